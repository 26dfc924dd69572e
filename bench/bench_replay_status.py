"""Benchmark: what `dpgw replay`'s periodic `/dp/status` costs, side by side in one run.

The same NMEA log replayed end to end (passive observer, every output written to MCAP), once as library
callers replay it (`run_replay` without a status period: a status only at a reference state change) and
once as `dpgw replay` does (a status, with its Foxglove log lines, a second of log time, as the live
gateway logs them). Rounds interleaved after a warm-up round, CPU time of the process; the median of
``--repeat`` rounds per side and their ratio (with / without).

    python bench/bench_replay_status.py [LOG] [--vessel NAME] [--repeat 5] [--json]

LOG defaults to the largest real USV log (``shared/data/usv-nmea`` in the folder that holds the checkout),
replayed as CyberShip II (a 1:70 model: the USV's scale).
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from gateway.replay import ObserverSpec, build_config, build_pipeline, open_inputs, run_replay
from wire.mcap.writer import McapLogWriter

REAL_LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "usv-nmea" / "202412051037.txt"
SIDES = {"without": None, "with 1 Hz status": 1_000_000_000}


def sentences_per_cpu_second(log: Path, vessel: str, period_ns: int | None, folder: str) -> float:
    """Sentences a CPU second of one end-to-end replay of ``log`` with the status period ``period_ns``."""
    inputs = open_inputs([log])
    pipeline = build_pipeline(build_config(inputs, vessel=vessel), [ObserverSpec("passive", "passive", {})])
    c0 = time.process_time()
    with McapLogWriter(Path(folder) / "out.mcap", flush_on_log_time=False) as out:
        result = run_replay(inputs, pipeline, out=out, status_period_ns=period_ns)
    return result.sentences / (time.process_time() - c0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", nargs="?", type=Path, default=REAL_LOG, help="an NMEA text log (a real USV log)")
    ap.add_argument("--vessel", default="cybership2", help="the vessel to replay it as (cybership2)")
    ap.add_argument("--repeat", type=int, default=5, help="interleaved rounds; the median is reported (5)")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON document")
    args = ap.parse_args()
    if not args.log.is_file():
        raise SystemExit(f"bench_replay_status: {args.log}: no such log (give an NMEA text log)")
    runs: dict[str, list[float]] = {side: [] for side in SIDES}
    with tempfile.TemporaryDirectory() as folder:
        sentences_per_cpu_second(args.log, args.vessel, None, folder)  # warm-up: kernels, caches
        for _ in range(args.repeat):
            for side, period in SIDES.items():
                runs[side].append(sentences_per_cpu_second(args.log, args.vessel, period, folder))
    median = {side: statistics.median(v) for side, v in runs.items()}
    ratio = median["with 1 Hz status"] / median["without"]
    if args.json:
        print(
            json.dumps({"log": str(args.log), "sentences_per_cpu_second": median, "ratio": ratio}, indent=2)
        )
        return
    print(f"{args.log.name}: sentences a CPU second, median of {args.repeat} interleaved rounds")
    for side in SIDES:
        print(f"  {side:17s} {median[side]:9,.0f}")
    print(f"  with / without    {ratio:9.2f}")


if __name__ == "__main__":
    main()
