"""Benchmark: what the extra outputs cost on the live path (latency and CPU), side by side.

The same gateway run as `bench_gateway` (a real ``dpgw run`` subprocess, UDP NMEA in at a fixed rate, the
estimate received over Zenoh in this process, MCAP logging on), once per output case:

- ``off``: no extra output (the reference every ratio is against);
- ``foxglove``: ``[foxglove]`` on, with a client connected that subscribes to every channel it is
  offered (a helper process speaking Foxglove's WebSocket protocol), so every message is framed and sent;
- ``keelson``: ``[keelson]`` on, with a Zenoh subscriber on ``keelson/@v0/**`` in this process, so every
  envelope is routed to a peer.

Each case is a fresh gateway; the cases are interleaved, ``--rounds`` times, so a change in the machine's
load spreads over all of them rather than landing on one. Latency: datagram written → estimate received
(`bench_gateway.latency_run`: the same pairing, warm-up and quantiles), pooled over the rounds; CPU: the
gateway process's utime + stime over the measured window, in % of one core, the median of the rounds.

A case is one entry of `CASES`: the config section it adds, and optionally a client that consumes what it
sends. An output whose optional packages are not installed (ROS 2 needs ``dpgw[ros2]``) is skipped and said
so; adding one is adding an entry.

    python bench/bench_outputs.py                                 # 10 Hz, 3 rounds of 20 s: ~4 minutes
    python bench/bench_outputs.py --rates 10 50 --rounds 2 --json

Linux only (``/proc``). Results in docs/performance.md.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import socket
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_gateway import (
    PREFIX,
    REPO,
    Child,
    config_text,
    free_port,
    latency_run,
    progress,
)

_FOXGLOVE_CLIENT = """
import asyncio, json, signal, sys
import websockets
stop = asyncio.Event()
async def main():
    port = int(sys.argv[1])
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGTERM, stop.set)
    loop.add_signal_handler(signal.SIGINT, stop.set)
    for _ in range(300):
        try:
            ws = await websockets.connect(
                f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], max_size=None
            )
            break
        except OSError:
            await asyncio.sleep(0.1)
    else:
        sys.exit("no server")
    n = nbytes = 0
    next_id = 1
    async def reader():
        nonlocal n, nbytes, next_id
        async for frame in ws:
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "advertise":
                    subs = []
                    for ch in msg["channels"]:
                        subs.append({"id": next_id, "channelId": ch["id"]})
                        next_id += 1
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif frame[0] == 1:
                n += 1
                nbytes += len(frame)
    task = asyncio.create_task(reader())
    await stop.wait()
    task.cancel()
    await ws.close()
    print(json.dumps({"messages": n, "bytes": nbytes, "channels": next_id - 1}))
asyncio.run(main())
"""


class FoxgloveClient:
    """A helper process subscribed to every channel the server offers; counts what it receives."""

    def __init__(self, port: int) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _FOXGLOVE_CLIENT, str(port)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )

    def stop(self) -> dict[str, Any]:
        if self.proc.poll() is None:
            self.proc.terminate()
        out, err = self.proc.communicate(timeout=30)
        try:
            return dict(json.loads(out))
        except ValueError:
            return {"error": err[-500:]}


class ZenohSubscriber:
    """A Zenoh subscriber on the bench's session to the gateway, counting what the output puts: Keelson's
    ``keelson/@v0/**`` (``@v0`` is a verbatim chunk: ``**`` does not cross it), ROS 2's ``<domain>/**``."""

    def __init__(self, session: Any, key: str) -> None:
        self.n = 0
        self.sub = session.declare_subscriber(key, self._count)

    def _count(self, _sample: Any) -> None:
        self.n += 1

    def stop(self) -> dict[str, Any]:
        with contextlib.suppress(Exception):
            self.sub.undeclare()
        return {"messages": self.n}


@dataclass(frozen=True)
class Case:
    """One output configuration: the TOML it adds (``{port}``: a free TCP port for a server), whether it can
    run here, and the consumer started once the gateway is up."""

    section: str
    module: str | None = None
    """The module the output needs (skipped when it is not installed)."""
    consumer: Callable[[Any, int], Any] | None = None
    """(the gateway `Child`, the port) -> an object with ``stop() -> dict``."""

    def available(self) -> bool:
        return self.module is None or importlib.util.find_spec(self.module) is not None


CASES: dict[str, Case] = {
    "off": Case(""),
    "foxglove": Case(
        '[foxglove]\nenabled = true\nhost = "127.0.0.1"\nport = {port}\n',
        "foxglove",
        lambda _gw, port: FoxgloveClient(port),
    ),
    "keelson": Case(
        '[keelson]\nenabled = true\nentity_id = "bench_ship"\n',
        "keelson",
        lambda gw, _port: ZenohSubscriber(gw.session, "keelson/@v0/**"),
    ),
    "ros2": Case(
        "[ros2]\nenabled = true\ndomain_id = 0\n",
        "rosbags",
        lambda gw, _port: ZenohSubscriber(gw.session, "0/**"),
    ),
}


class OutputGateway(Child):
    """`bench_gateway.Gateway` with one output case's config section, and its consumer."""

    what = "dpgw run"

    def __init__(self, folder: Path, name: str, case: Case) -> None:
        udp, zport, self.port = (
            free_port(socket.SOCK_DGRAM),
            free_port(socket.SOCK_STREAM),
            free_port(socket.SOCK_STREAM),
        )
        config = folder / f"{name}.toml"
        text = config_text(udp, zport, folder / f"{name}.mcap") + case.section.format(port=self.port)
        config.write_text(text)
        argv = [sys.executable, "-m", "dpgw", "run", "--config", str(config), "--json"]
        super().__init__(folder, name, argv, f"{PREFIX}/estimate", udp, zport)
        self.case = case
        self.consumer: Any = None
        self.consumed: dict[str, Any] = {}

    def connect(self, timeout_s: float = 30.0) -> None:
        super().connect(timeout_s)
        if self.case.consumer is not None:
            self.consumer = self.case.consumer(self, self.port)

    def stop(self) -> None:
        if self.consumer is not None:
            self.consumed = self.consumer.stop()
        super().stop()


def run_case(
    folder: Path, name: str, case: Case, rate: float, warmup: float, seconds: float
) -> dict[str, Any]:
    gw = OutputGateway(folder, name, case)
    r = latency_run(gw, rate, 10.0, warmup, seconds)
    samples = r.pop("_samples")
    return {
        "latency_ns": [recv - sent for _, sent, _, recv in samples],
        "cpu_pct": r["cpu"]["gateway_pct"],
        "other_pct": r["cpu"]["other_processes_pct"],
        "lost": r["lost"],
        "consumed": gw.consumed,
    }


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    lat = np.concatenate([np.asarray(r["latency_ns"], dtype=float) for r in runs]) / 1e6
    p50, p99 = np.percentile(lat, [50, 99]) if lat.size else (float("nan"), float("nan"))
    return {
        "p50_ms": float(p50),
        "p99_ms": float(p99),
        "n": int(lat.size),
        "cpu_pct": statistics.median(r["cpu_pct"] for r in runs),
        "cpu_pct_rounds": [r["cpu_pct"] for r in runs],
        "other_processes_pct": statistics.median(r["other_pct"] for r in runs),
        "lost": sum(r["lost"] for r in runs),
        "consumed": [r["consumed"] for r in runs],
    }


@contextlib.contextmanager
def scratch() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="dpgw-bench-outputs-") as d:
        yield Path(d)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rates", type=float, nargs="+", default=[10.0], metavar="HZ")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0, help="measured seconds per case and round")
    ap.add_argument("--warmup", type=float, default=3.0)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    cases = {name: CASES[name] for name in args.cases if CASES[name].available()}
    skipped = [name for name in args.cases if name not in cases]
    for name in skipped:
        progress(f"skipped {name}: {CASES[name].module} is not installed")
    results: dict[str, Any] = {
        "rates": {},
        "skipped": skipped,
        "rounds": args.rounds,
        "seconds": args.seconds,
    }
    with scratch() as folder:
        for rate in args.rates:
            runs: dict[str, list[dict[str, Any]]] = {name: [] for name in cases}
            for k in range(args.rounds):
                for name, case in cases.items():
                    progress(f"{rate:g} Hz, round {k + 1}/{args.rounds}: {name}")
                    runs[name].append(
                        run_case(folder, f"{name}_{rate:g}_{k}", case, rate, args.warmup, args.seconds)
                    )
            table = {name: summarise(r) for name, r in runs.items()}
            off = table.get("off")
            for row in table.values():
                if off is not None:
                    row["p99_ratio"] = row["p99_ms"] / off["p99_ms"]
                    row["p50_ratio"] = row["p50_ms"] / off["p50_ms"]
                    row["cpu_ratio"] = row["cpu_pct"] / off["cpu_pct"] if off["cpu_pct"] > 0 else None
            results["rates"][f"{rate:g}"] = table
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    for rate, table in results["rates"].items():
        print(
            f"\n{rate} Hz in, {args.rounds} rounds x {args.seconds:g} s per case (interleaved), MCAP log on"
        )
        print(
            f"  {'output':10s} {'p50 ms':>7s} {'p99 ms':>7s} {'CPU %':>6s}  "
            f"{'p50 x':>6s} {'p99 x':>6s} {'CPU x':>6s}  consumed (messages per round)"
        )
        for name, row in table.items():
            got = ", ".join(str(c.get("messages", c.get("error", "?"))) for c in row["consumed"] if c) or "-"
            cpu_x = row.get("cpu_ratio")
            print(
                f"  {name:10s} {row['p50_ms']:7.2f} {row['p99_ms']:7.2f} {row['cpu_pct']:6.1f}  "
                f"{row.get('p50_ratio', float('nan')):6.2f} {row.get('p99_ratio', float('nan')):6.2f} "
                f"{cpu_x if cpu_x is not None else float('nan'):6.2f}  {got}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
