"""Benchmark: what Python's cyclic garbage collector costs a replay, side by side in one run.

The same NMEA log replayed end to end (passive observer, every output written to MCAP, as `dpgw replay`
does) with the collector as it is, with ``gc.freeze()`` once the pipeline is built (the objects made at
start-up are never scanned again), with the generation-0 threshold raised to 100,000, and with the
collector off. Rounds interleaved, best of ``--repeat`` after a warm-up round, CPU time of the process per
cycle (one event, one observer step, its outputs): a ratio near 1 says the collector is not worth tuning.

    python bench/bench_replay_gc.py [LOG] [--repeat 4] [--json]

LOG defaults to the largest real USV log (``shared/data/usv-nmea`` in the folder that holds the checkout).
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import tempfile
import time
from pathlib import Path

from gateway.replay import ObserverSpec, build_config, build_pipeline, open_inputs, run_replay
from wire.mcap.writer import McapLogWriter

REAL_LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "usv-nmea" / "202412051037.txt"
MODES = ("as is", "frozen", "threshold 100k", "off")


def replay_us_per_cycle(log: Path, mode: str, folder: str) -> float:
    """CPU µs a cycle of one end-to-end replay of ``log`` with the collector in ``mode``."""
    inputs = open_inputs([log])
    inputs[0].fast_scan = True
    config = build_config(inputs, vessel="mss_supply")
    pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
    threshold = gc.get_threshold()
    if mode == "frozen":
        gc.freeze()
    elif mode == "threshold 100k":
        gc.set_threshold(100_000, threshold[1], threshold[2])
    elif mode == "off":
        gc.disable()
    try:
        c0 = time.process_time()
        with McapLogWriter(Path(folder) / "out.mcap", flush_on_log_time=False) as out:
            result = run_replay(inputs, pipeline, out=out)
        cpu = time.process_time() - c0
    finally:
        gc.enable()
        gc.unfreeze()
        gc.set_threshold(*threshold)
    return 1e6 * cpu / max(result.events, 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", nargs="?", type=Path, default=REAL_LOG, help="an NMEA text log (a real USV log)")
    ap.add_argument("--repeat", type=int, default=4, help="rounds; the best of each is reported (4)")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON document")
    args = ap.parse_args()
    if not args.log.is_file():
        raise SystemExit(f"bench_replay_gc: {args.log}: no such log (give an NMEA text log)")
    best = dict.fromkeys(MODES, math.inf)
    with tempfile.TemporaryDirectory() as folder:
        replay_us_per_cycle(args.log, "as is", folder)  # warm-up: kernels, caches
        for _ in range(args.repeat):
            for mode in MODES:
                best[mode] = min(best[mode], replay_us_per_cycle(args.log, mode, folder))
    ratios = {mode: best["as is"] / us for mode, us in best.items()}
    if args.json:
        print(json.dumps({"log": str(args.log), "us_per_cycle": best, "speed_up": ratios}, indent=2))
        return
    print(f"{args.log.name}: CPU µs a cycle, best of {args.repeat} interleaved rounds")
    for mode in MODES:
        print(f"  collector {mode:15s} {best[mode]:7.1f} µs   x{ratios[mode]:.2f}")


if __name__ == "__main__":
    main()
