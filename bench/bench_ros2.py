"""Benchmark: what the ROS 2 output costs, beside the Keelson output, side by side in one run.

1. **Per message**, in this process: one `OutputSink.emit` of one estimate and of one GNSS fix, for
   the ``[ros2]`` sink (an estimate: an Odometry, a PoseStamped and its /tf TFMessage, CDR by rosbags,
   rmw_zenoh attachment; a fix: a NavSatFix) and the ``[keelson]`` sink (an estimate: up to 10 protobuf
   envelopes; a fix: one), each on a real Zenoh session with a subscriber of everything it publishes in a
   second session on loopback (so every put goes out on a link, as with a ROS 2 peer). Rounds interleave
   the sinks; the median µs per emit and per sample over ``--n`` emits, best round of ``--repeat``.
2. **Live path**: ``dpgw run`` subprocesses (`bench.bench_gateway`'s: UDP NMEA in, Zenoh on loopback, MCAP
   log on) at 10 Hz, with no extra output, with ``[ros2]`` and with ``[keelson]`` (each with a subscriber
   of its keys in this process), interleaved ``--rounds`` times: latency datagram → ``<prefix>/estimate``
   at the subscriber (p50, p99) and the gateway's CPU (% of one core).

    python bench/bench_ros2.py [--n 2000] [--repeat 5] [--seconds 20] [--rounds 2] [--json]
    python bench/bench_ros2.py --no-live      # part 1 only (a few seconds)
"""

from __future__ import annotations

import argparse
import json
import math
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.bench_gateway import Child, config_text, free_port, latency_run
from gateway.bus import isolated_config, open_session
from gateway.config import parse_config
from gateway.outputs.build import sinks_from_config
from gateway.pipeline import Output
from wire.foxglove import location_fix
from wire.gst_covariance import ELLIPSE, GstCovariance, ellipse_covariance_ne
from wire.messages import Datum, Estimate

VARIANTS = ("off", "ros2", "keelson")


def estimate(k: int) -> Output:
    t = 1_780_000_000_000_000_000 + k * 100_000_000
    e = Estimate(
        stamp_ns=t, observer="passive", status="ok", eta=[1.5 + 1e-3 * k, -2.25, 0.5], nu=[0.1, -0.05, 0.002],
        bias=[1e4, -2e3, 5e4], eta_wf=[0.1, 0.05, 0.001], omega0=[0.7, 0.7, 0.7], lat_deg=59.40001,
        lon_deg=10.49996, heading_deg=28.6, datum=Datum(lat_deg=59.4, lon_deg=10.5),
    )  # fmt: skip
    return Output("/dp/estimate", e, t)


FIX_COVARIANCE = GstCovariance(*ellipse_covariance_ne(0.5, 0.2, math.radians(30.0)), 0.81, ELLIPSE)


def fix(k: int) -> Output:
    t = 1_780_000_000_000_000_000 + k * 100_000_000
    return Output(
        "/gnss/dgps1/fix", location_fix(t, "dgps1", 59.40001, 10.49996, 55.5, FIX_COVARIANCE), t, zenoh=False
    )


def tables(port: int, which: str) -> dict[str, Any]:
    t: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {
                "name": "dgps1",
                "url": "udp://127.0.0.1:1",
                "protocol": "nmea",
                "roles": ["position", "heading"],
            }
        ],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"], "multicast_scouting": False},
        "log": {"path": ""},
    }
    t[which] = {"enabled": True} if which == "ros2" else {"enabled": True, "entity_id": "bench_ship"}
    return t


def per_message(n: int, repeat: int) -> dict[str, Any]:
    """Median µs per emit (estimate, fix) for each sink, best round of `repeat`, rounds interleaved."""
    port = free_port(socket.SOCK_STREAM)
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    received = {"ros2": 0, "keelson": 0}

    def counter(name: str) -> Any:
        def on(_sample: Any) -> None:
            received[name] += 1

        return on

    subs = [
        client.declare_subscriber("0/**", counter("ros2")),
        client.declare_subscriber("keelson/@v0/**", counter("keelson")),
    ]
    sinks = {}
    for which in ("ros2", "keelson"):
        (sink,) = sinks_from_config(parse_config(tables(port, which), base_dir=Path(".")))
        sink.start(server)
        sinks[which] = sink
    est = [estimate(k) for k in range(n)]
    fixes = [fix(k) for k in range(n)]
    enc_est = [o.message.encode() for o in est]
    enc_fix = [o.message.encode() for o in fixes]
    time.sleep(0.5)  # the subscriptions reach the server (a benchmark may wait; a test may not)
    best: dict[str, dict[str, float]] = {}
    samples: dict[str, dict[str, float]] = {}
    for _ in range(repeat):
        for which, sink in sinks.items():
            for kind, outs, encs in (("estimate", est, enc_est), ("fix", fixes, enc_fix)):
                before = received[which]
                times = []
                for o, b in zip(outs, encs, strict=True):
                    t0 = time.perf_counter_ns()
                    sink.emit([o], [b])
                    times.append(time.perf_counter_ns() - t0)
                med = statistics.median(times) / 1e3
                slot = best.setdefault(which, {})
                slot[kind] = min(slot.get(kind, float("inf")), med)
                time.sleep(0.2)  # the last samples arrive
                samples.setdefault(which, {})[kind] = (received[which] - before) / len(outs)
    for sink in sinks.values():
        sink.close()
    for s in subs:
        s.undeclare()
    client.close()
    server.close()
    return {
        which: {f"{kind}_us_per_emit": best[which][kind] for kind in ("estimate", "fix")}
        | {f"{kind}_samples_per_emit": samples[which][kind] for kind in ("estimate", "fix")}
        for which in best
    }


class GatewayWith(Child):
    """`bench.bench_gateway`'s live gateway with one extra output table and a subscriber of its keys."""

    what = "dpgw run"

    def __init__(self, folder: Path, name: str, extra: str, extra_key: str | None) -> None:
        from bench.bench_gateway import PREFIX

        udp, zport = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
        config = folder / f"{name}.toml"
        config.write_text(config_text(udp, zport, folder / f"{name}.mcap") + extra)
        argv = [sys.executable, "-m", "dpgw", "run", "--config", str(config), "--json"]
        super().__init__(folder, name, argv, f"{PREFIX}/estimate", udp, zport)
        self.extra_key = extra_key
        self.extra_samples = 0
        self._extra_sub: Any = None

    def connect(self, timeout_s: float = 30.0) -> None:
        super().connect(timeout_s)
        if self.extra_key is not None:
            self._extra_sub = self.session.declare_subscriber(self.extra_key, self._count)

    def _count(self, _sample: Any) -> None:
        self.extra_samples += 1

    def stop(self) -> None:
        if self._extra_sub is not None:
            self._extra_sub.undeclare()
            self._extra_sub = None
        super().stop()


EXTRA = {
    "off": ("", None),
    "ros2": ("[ros2]\nenabled = true\n", "0/**"),
    "keelson": ('[keelson]\nenabled = true\nentity_id = "bench_ship"\n', "keelson/@v0/**"),
}


def live(seconds: float, warmup: float, rounds: int) -> dict[str, Any]:
    out: dict[str, list[dict[str, Any]]] = {v: [] for v in VARIANTS}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for r in range(rounds):
            for v in VARIANTS:
                extra, key = EXTRA[v]
                gw = GatewayWith(folder, f"{v}_{r}", extra, key)
                res = latency_run(gw, 10.0, 10.0, warmup, seconds)
                out[v].append(
                    {
                        "p50_ms": res["latency"]["p50_ms"],
                        "p99_ms": res["latency"]["p99_ms"],
                        "cpu_pct": res["cpu"]["gateway_pct"],
                        "other_pct": res["cpu"]["other_processes_pct"],
                        "lost": res["lost"],
                        "extra_samples": gw.extra_samples,
                    }
                )
                print(f"  round {r + 1} {v:8s} {_row(out[v][-1])}", file=sys.stderr, flush=True)
    return out


def _row(x: dict[str, Any]) -> str:
    return (
        f"p50 {x['p50_ms']:.3f} ms  p99 {x['p99_ms']:.3f} ms  CPU {x['cpu_pct']:.1f} %  "
        f"(others {x['other_pct']:.0f} %, lost {x['lost']}, extra samples {x['extra_samples']})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000, help="emits per sink, kind and round (2000)")
    ap.add_argument("--repeat", type=int, default=5, help="interleaved rounds of part 1; the best counts (5)")
    ap.add_argument("--seconds", type=float, default=20.0, help="measured seconds per live run (20)")
    ap.add_argument("--warmup", type=float, default=3.0, help="seconds discarded per live run (3)")
    ap.add_argument("--rounds", type=int, default=2, help="interleaved live rounds of every variant (2)")
    ap.add_argument("--no-live", action="store_true", help="part 1 only")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    res: dict[str, Any] = {"per_message": per_message(args.n, args.repeat)}
    if not args.no_live:
        res["live"] = live(args.seconds, args.warmup, args.rounds)
    if args.json:
        print(json.dumps(res, indent=2))
        return
    pm = res["per_message"]
    print("per emit, median µs (best of rounds)      ros2     keelson   ros2/keelson")
    for kind, what in (("estimate", "estimate (Odometry + Pose + TF | 9 subjects)"), ("fix", "GNSS fix")):
        r, k = pm["ros2"][f"{kind}_us_per_emit"], pm["keelson"][f"{kind}_us_per_emit"]
        print(f"  {what:38s} {r:8.1f} {k:11.1f} {r / k:12.2f}")
    for kind in ("estimate", "fix"):
        r, k = pm["ros2"][f"{kind}_samples_per_emit"], pm["keelson"][f"{kind}_samples_per_emit"]
        print(f"  samples received per {kind:12s}         {r:8.1f} {k:11.1f}")
    if "live" in res:
        print("live gateway at 10 Hz (best round: lowest p99)")
        for v in VARIANTS:
            b = min(res["live"][v], key=lambda x: x["p99_ms"])
            print(f"  {v:8s} {_row(b)}")


if __name__ == "__main__":
    main()
