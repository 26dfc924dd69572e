"""Benchmark: what the Foxglove-native channels cost a replay, side by side in one process.

The same generated log as `bench/bench_replay.py` (torsetnes_2004, 10 Hz DGPS and gyro, 1 h by default)
is replayed end to end with MCAP output, interleaved, in three variants:

- ``off``: the JSON channels and the GNSS LocationFix at most 1 Hz, the channels before the Foxglove
  scene (`FoxgloveChannels.derive` replaced by one that returns nothing; the estimate's LocationFix, 1 Hz
  before, goes with it: 0.1 output a cycle);
- ``on_fix_1hz``: every Foxglove channel, the GNSS LocationFix at most 1 Hz per source;
- ``on``: every Foxglove channel and a LocationFix for every GNSS fix (`FIX_PERIOD_NS` = 0), as shipped.

CPU time of the process (less disturbed than wall time by the other work on a shared machine), best of
``--repeat``; µs per cycle, and each variant's ratio to ``off``.

    python bench/bench_foxglove.py [--hours 0.5] [--repeat 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from typing import Any

import gateway.pipeline as pipeline_module
from bench.bench_replay import make_log
from gateway.replay import ObserverSpec, build_config, build_pipeline, open_inputs, run_replay
from wire.mcap.writer import McapLogWriter

VARIANTS = ("off", "on_fix_1hz", "on")


def _run(inputs: Any, config: Any, variant: str, path: str) -> tuple[float, int, int]:
    pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
    if variant == "off":
        pipeline.foxglove.derive = lambda outputs: []  # type: ignore[method-assign]
    pipeline_module.FIX_PERIOD_NS = 0 if variant == "on" else 1_000_000_000
    c0 = time.process_time()
    with McapLogWriter(path, flush_on_log_time=False) as out:
        result = run_replay(inputs, pipeline, out=out)
    cpu = time.process_time() - c0
    return cpu, result.events, result.outputs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=3, help="interleaved runs of each variant; the best counts")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    fix_period = pipeline_module.FIX_PERIOD_NS
    with tempfile.TemporaryDirectory() as folder:
        log = os.path.join(folder, "trial.nmea")
        make_log(log, args.hours)
        inputs = open_inputs([log])
        inputs[0].fast_scan = True
        config = build_config(inputs, vessel="mss_supply")
        _run(inputs, config, "on", os.path.join(folder, "warm.mcap"))  # compile and warm outside the timing
        cpu = dict.fromkeys(VARIANTS, math.inf)
        events: dict[str, int] = {}
        outputs: dict[str, int] = {}
        sizes: dict[str, int] = {}
        for _ in range(args.repeat):
            for v in VARIANTS:
                path = os.path.join(folder, f"{v}.mcap")
                c, events[v], outputs[v] = _run(inputs, config, v, path)
                cpu[v] = min(cpu[v], c)
                sizes[v] = os.path.getsize(path)
    pipeline_module.FIX_PERIOD_NS = fix_period
    r = {
        v: {
            "us_per_cycle": 1e6 * cpu[v] / events[v],
            "ratio_to_off": cpu[v] / cpu["off"],
            "outputs_per_cycle": outputs[v] / events[v],
            "mcap_bytes_ratio_to_off": sizes[v] / sizes["off"],
        }
        for v in VARIANTS
    }
    if args.json:
        print(json.dumps({"hours": args.hours, **r}, indent=2))
        return
    print(f"replay of {args.hours:g} h, {events['off']:,} cycles; CPU, best of {args.repeat} interleaved")
    for v, f in r.items():
        print(
            f"  {v:14s} {f['us_per_cycle']:7.1f} µs/cycle  x{f['ratio_to_off']:.2f}  "
            f"{f['outputs_per_cycle']:.2f} outputs/cycle  MCAP x{f['mcap_bytes_ratio_to_off']:.2f}"
        )


if __name__ == "__main__":
    main()
