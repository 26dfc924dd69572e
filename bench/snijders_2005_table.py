"""Snijders, van der Woude & Westhuis (2005), Sec. 5: the table of mean-square LF estimation errors,
(1/n) Σ ‖η̂ − η‖² per DOF, for the passive observer in the paper's tracking case, closed loop.

    python bench/snijders_2005_table.py [--seed N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from test_station_keeping import format_snijders_table, snijders_table, snijders_track

from dpgw.closed_loop import run_closed_loop
from simulator.scenarios import get_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    r = run_closed_loop(get_scenario("snijders_2005"), 1800.0, seed=args.seed, events=snijders_track())
    print(f"snijders_2005, JONSWAP Hs 5 m Tp 12 s, 1800 s, seed {args.seed}")
    print(format_snijders_table(snijders_table(r)))


if __name__ == "__main__":
    main()
