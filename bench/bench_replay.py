"""Benchmark: end-to-end replay throughput on an NMEA text log.

Target: >= 100,000 sentences/s (passive observer, MCAP output), so a day of 10 Hz data replays in well
under a minute. The log is made by the simulator (torsetnes_2004, 10 Hz DGPS: GGA, RMC, VTG, GST/ZDA at
1 Hz; 10 Hz gyro: HDT, ROT). Side by side in the same run, on the same bytes:

- end to end as `dpgw replay` runs it (MCAP output through `McapLogWriter`);
- the pipeline without any output (what the MCAP writing costs);
- framing + decoding alone with the line-by-line framer and decoder (what every sentence cost before the
  compiled line scan, `wire.codecs.nmea_scan`).

The generated log always goes through the compiled scan (the path `dpgw replay` takes for logs from
`gateway.replay.FAST_SCAN_MIN_BYTES` on), so figures compare across versions. Then the real sea-trial logs
(a USV's GGA/RMC/VTG/HDT at 5 Hz, ``shared/data/usv-nmea`` in the folder that holds the checkout; skipped
without them), each end to end with MCAP output by the path `dpgw replay` picks for its size and by the
line-by-line reader, beside pynmea2 merely parsing the same lines (``pynmea2.parse`` per line: the
target ratio is >= 1).

Why the real logs run at fewer sentences per second than the generated one: not the sentences but the
cycles. Replay's cost is per cycle (one event, one observer step, ~3.4 outputs written), and a real
USV cycle is 4 sentences (GGA, RMC, VTG, HDT: both the fix and the heading used in every cycle) against
5.2 in the generated log (GGA, RMC, VTG, HDT, ROT, and GST/ZDA once a second), so the same ~60 µs a
cycle is 67,000 sentences/s there and 87,000 here; each log's µs per cycle is printed beside it. The
line-by-line reader leaves framing and checksums to the pipeline: ~25 µs more a cycle, which is why logs
from 64 KiB on now take the compiled scan (its first call costs 6-8 ms beyond numba's start-up; it used
to cost ~0.3 s, and logs under 8 MiB were read line by line). A process also pays a fixed ~0.25 s the
first time it calls any numba kernel, which on a 13,000-line log was most of the run from the command
line; the figures here are warm (a first round is run and not counted).

    python bench/bench_replay.py [--hours 1] [--repeat 2] [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import tempfile
import time
from pathlib import Path

import pynmea2

from gateway.replay import (
    FAST_SCAN_MIN_BYTES,
    ObserverSpec,
    build_config,
    build_pipeline,
    open_inputs,
    run_replay,
)
from simulator.runner import Route, Simulation
from simulator.scenarios import get_scenario
from simulator.transports import FileSink
from wire.codecs.nmea import decode
from wire.codecs.nmea_framing import NmeaFramer
from wire.mcap.writer import McapLogWriter


def make_log(path: str, hours: float) -> None:
    scenario = get_scenario("torsetnes_2004").with_sensor_rates(10.0, 10.0)
    sink = FileSink(path)
    Simulation(scenario, seed=1, routes=[Route(sink, "nmea")]).run(hours * 3600.0)
    sink.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2, help="runs of each variant; the best is reported (2)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--real-logs",
        type=Path,
        default=REAL_LOGS,
        help="folder of real NMEA text logs (*.txt) (default: shared/data/usv-nmea beside the checkout)",
    )
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        log = os.path.join(folder, "trial.nmea")
        make_log(log, args.hours)
        with open(log, "rb") as f:
            data = f.read()
        # decoding floor
        t0 = time.perf_counter()
        framer = NmeaFramer()
        n = 0
        for k in range(0, len(data), 4096):
            for frame in framer.feed(data[k : k + 4096]):
                if frame.text is not None:
                    decode(frame.text)
                    n += 1
        decode_rate = n / (time.perf_counter() - t0)
        # end to end and without output, alternating (best of `repeat`: the machine is shared)
        inputs = open_inputs([log])
        inputs[0].fast_scan = True  # the compiled scan, as for every log from FAST_SCAN_MIN_BYTES on
        config = build_config(inputs, vessel="mss_supply")
        warm = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
        warm.observer.step(0.0, [0.0, 0.0, 0.0])  # compile outside the timed run
        list(inputs[0].events())  # (and the line scan)
        walls: dict[str, float] = {}
        cpus: dict[str, float] = {}  # CPU time of the process: less disturbed by other work on the machine
        result = None
        for _ in range(args.repeat):
            for mode in ("replay", "no_output"):
                pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
                path = os.path.join(folder, f"out_{mode}.mcap")
                t0, c0 = time.perf_counter(), time.process_time()
                if mode == "no_output":
                    result = run_replay(inputs, pipeline)
                else:
                    with McapLogWriter(path, flush_on_log_time=False) as out:
                        result = run_replay(inputs, pipeline, out=out)
                walls[mode] = min(walls.get(mode, math.inf), time.perf_counter() - t0)
                cpus[mode] = min(cpus.get(mode, math.inf), time.process_time() - c0)
        assert result is not None
        wall = walls["replay"]
    rate = result.sentences / wall
    r = {
        "hours": args.hours,
        "sentences": result.sentences,
        "cycles": result.events,
        "estimates": sum(result.estimates.values()),
        "wall_seconds": wall,
        "sentences_per_second": rate,
        "us_per_cycle": 1e6 * wall / result.events,
        "decode_only_sentences_per_second": decode_rate,
        "no_output_sentences_per_second": result.sentences / walls["no_output"],
        "cpu_sentences_per_second": result.sentences / cpus["replay"],
        "end_to_end_over_decode": rate / decode_rate,
        "day_at_10_hz_seconds": 24 * result.sentences / args.hours / rate,
    }
    r["real_logs"] = real_logs(args.repeat, args.real_logs)
    if args.json:
        print(json.dumps(r, indent=2))
        return
    print(
        f"replay of {args.hours:g} h of 10 Hz NMEA ({result.sentences:,} sentences, {result.events:,} "
        f"cycles, {result.sentences / result.events:.1f} a cycle; "
        f"{r['us_per_cycle']:.1f} µs a cycle end to end)"
    )
    rows = [
        ("end to end as dpgw replay runs it", rate, "  (target >= 100,000)"),
        ("the same by CPU time", r["cpu_sentences_per_second"], ""),
        ("pipeline without output", r["no_output_sentences_per_second"], ""),
        ("line-by-line framing + decoding alone", decode_rate, ""),
    ]
    for label, value, note in rows:
        print(f"  {label + ':':42s} {value:10,.0f} sentences/s{note}")
    print(f"  a day of this 10 Hz data would take {r['day_at_10_hz_seconds']:.0f} s")
    if not r["real_logs"]:
        print("real logs: none found (shared/data/usv-nmea beside the checkout's folder)")
    for name, x in r["real_logs"].items():
        print(
            f"real log {name} ({x['sentences']:,} sentences, {x['sentences'] / x['cycles']:.1f} a cycle, "
            f"{x['path_used']}): end to end {x['sentences_per_second']:,.0f} sentences/s "
            f"({x['us_per_cycle']:.1f} µs a cycle); pynmea2 parsing alone "
            f"{x['pynmea2_per_second']:,.0f}/s; ratio {x['ratio_to_pynmea2']:.2f} (target >= 1); by CPU time "
            f"{x['cpu_sentences_per_second']:,.0f}/s, ratio {x['cpu_ratio_to_pynmea2']:.2f}"
        )


REAL_LOGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "usv-nmea"


def real_logs(repeat: int, folder: Path = REAL_LOGS) -> dict[str, dict[str, float | int | str]]:
    """Each real log end to end (MCAP output, the path `dpgw replay` picks) beside pynmea2 parsing the
    same lines; best of ``repeat`` after one warm-up run (the fixed start-up cost is in the docstring)."""
    out: dict[str, dict[str, float | int | str]] = {}
    for path, scan in [
        (p, scan)
        for p in (sorted(folder.glob("*.txt")) if folder.is_dir() else [])
        for scan in (None, False)  # the path `dpgw replay` picks by size, and the line reader
    ]:
        inputs = open_inputs([path])
        inputs[0].fast_scan = scan
        config = build_config(inputs, vessel="mss_supply")
        lines = [line for line in path.read_text(encoding="ascii", errors="replace").splitlines() if line]
        walls = {k: math.inf for k in ("replay", "pynmea2", "cpu_replay", "cpu_pynmea2")}
        result = None
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(repeat + 1):  # the first round warms up (numba, caches) and is not counted
                pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
                t0, c0 = time.perf_counter(), time.process_time()
                with McapLogWriter(os.path.join(tmp, "out.mcap"), flush_on_log_time=False) as w:
                    result = run_replay(inputs, pipeline, out=w)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                t0, c0 = time.perf_counter(), time.process_time()
                for line in lines:
                    with contextlib.suppress(pynmea2.ParseError):
                        pynmea2.parse(line, check=True)
                wall_p, cpu_p = time.perf_counter() - t0, time.process_time() - c0
                if k:
                    walls["replay"] = min(walls["replay"], wall)
                    walls["pynmea2"] = min(walls["pynmea2"], wall_p)
                    walls["cpu_replay"] = min(walls["cpu_replay"], cpu)
                    walls["cpu_pynmea2"] = min(walls["cpu_pynmea2"], cpu_p)
        assert result is not None
        rate = result.sentences / walls["replay"]
        rate_p = len(lines) / walls["pynmea2"]
        scan = scan if scan is not None else path.stat().st_size >= FAST_SCAN_MIN_BYTES
        out[path.name + (" (compiled scan)" if scan else "")] = {
            "sentences": result.sentences,
            "cycles": result.events,
            "path_used": "compiled scan" if scan else "line reader",
            "sentences_per_second": rate,
            "us_per_cycle": 1e6 * walls["replay"] / result.events,
            "pynmea2_per_second": rate_p,
            "ratio_to_pynmea2": rate / rate_p,
            # the same by the process's CPU time (steadier when other work shares the machine)
            "cpu_sentences_per_second": result.sentences / walls["cpu_replay"],
            "cpu_ratio_to_pynmea2": walls["cpu_pynmea2"]
            / walls["cpu_replay"]
            * result.sentences
            / len(lines),
        }
    return out


if __name__ == "__main__":
    main()
