"""Benchmark: end-to-end replay throughput on an NMEA text log.

Target: >= 100,000 sentences/s (passive observer, MCAP output), so a day of 10 Hz data replays in well
under a minute. The log is made by the simulator (torsetnes_2004, 10 Hz DGPS: GGA, RMC, VTG, GST/ZDA at
1 Hz; 10 Hz gyro: HDT, ROT). Side by side in the same run, on the same bytes:

- end to end as `dpgw replay` runs it (MCAP output through `McapLogWriter`);
- the pipeline without any output (what the MCAP writing costs);
- framing + decoding alone with the line-by-line framer and decoder (what every sentence cost before the
  compiled line scan, `wire.codecs.nmea_scan`).

    python bench/bench_replay.py [--hours 1] [--repeat 2] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time

from gateway.replay import (
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
        config = build_config(inputs, vessel="mss_supply")
        warm = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
        warm.observer.step(0.0, [0.0, 0.0, 0.0])  # compile outside the timed run
        list(inputs[0].events())  # (and the line scan)
        walls: dict[str, float] = {}
        result = None
        for _ in range(args.repeat):
            for mode in ("replay", "no_output"):
                pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
                path = os.path.join(folder, f"out_{mode}.mcap")
                t0 = time.perf_counter()
                if mode == "no_output":
                    result = run_replay(inputs, pipeline)
                else:
                    with McapLogWriter(path, flush_on_log_time=False) as out:
                        result = run_replay(inputs, pipeline, out=out)
                walls[mode] = min(walls.get(mode, math.inf), time.perf_counter() - t0)
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
        "decode_only_sentences_per_second": decode_rate,
        "no_output_sentences_per_second": result.sentences / walls["no_output"],
        "end_to_end_over_decode": rate / decode_rate,
        "day_at_10_hz_seconds": 24 * result.sentences / args.hours / rate,
    }
    if args.json:
        print(json.dumps(r, indent=2))
        return
    print(
        f"replay of {args.hours:g} h of 10 Hz NMEA ({result.sentences:,} sentences, {result.events:,} cycles)"
    )
    rows = [
        ("end to end as dpgw replay runs it", rate, "  (target >= 100,000)"),
        ("pipeline without output", r["no_output_sentences_per_second"], ""),
        ("line-by-line framing + decoding alone", decode_rate, ""),
    ]
    for label, value, note in rows:
        print(f"  {label + ':':42s} {value:10,.0f} sentences/s{note}")
    print(f"  a day of this 10 Hz data would take {r['day_at_10_hz_seconds']:.0f} s")


if __name__ == "__main__":
    main()
