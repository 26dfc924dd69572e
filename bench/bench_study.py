"""`dpgw study` on Dask: cases per minute serially, on 1 and on 2 local workers, and Dask's own cost per case.

All in one run, side by side (the machine is shared and noisy: compare the ratios, not the absolute
figures across runs):

* **scaling**: the same real cases (a closed loop + every registered observer + scoring each) serially in
  this process, then on a fresh LocalCluster of 1 and of 2 worker processes (cluster start-up included:
  it is what a user waits for). Ideal 2-worker speed-up is 2.0 on two free cores.
* **overhead**: a trivial case (returns one row at once) N times serially and on 2 workers; Dask's cost per
  case = (time on Dask for N − time for 1) / (N − 1) − the serial time per case, so the cluster's start-up is
  left out. Also reported: the cluster's start-up (1 trivial case).

    python bench/bench_study.py [--cases 8] [--duration 120] [--trivial 400] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from dpgw.study.runner import run_study
from dpgw.study.spec import StudySpec


def trivial_case(case: dict[str, Any]) -> list[dict[str, Any]]:
    return [{"seed": case["seed"], "value": 1.0}]


def timed(cases: list[Any], workers: int, fn: Any = None) -> float:
    t0 = time.perf_counter()
    run_study(cases, workers=workers, case_fn=fn)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=8, help="real cases per configuration")
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds per real case")
    ap.add_argument("--scenario", default="torsetnes_2004")
    ap.add_argument("--trivial", type=int, default=400, help="trivial cases for the overhead")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    spec = StudySpec(scenarios=(args.scenario,), seeds=tuple(range(args.cases)), duration_s=args.duration)
    cases = spec.cases()
    run_study(cases[:1], workers=0)  # numba's cache loaded and the modules imported here, as on a worker
    t_serial = timed(cases, 0)
    t_one = timed(cases, 1)
    t_two = timed(cases, 2)

    trivial = StudySpec(
        scenarios=("hassani",), seeds=tuple(range(args.trivial)), observers=("passive",)
    ).cases()
    s_n = timed(trivial, 0, trivial_case)
    d_1 = timed(trivial[:1], 2, trivial_case)
    d_n = timed(trivial, 2, trivial_case)
    per_case_ms = 1e3 * ((d_n - d_1) / (len(trivial) - 1) - s_n / len(trivial))

    def cpm(t: float) -> float:
        return 60.0 * len(cases) / t

    out = {
        "cases": len(cases),
        "case": f"{args.scenario}, {args.duration:g} s, {len(spec.observer_specs())} observers",
        "cases_per_minute": {"serial": cpm(t_serial), "dask_1": cpm(t_one), "dask_2": cpm(t_two)},
        "speedup_2_over_1": t_one / t_two,
        "dask_1_over_serial": t_serial / t_one,
        "dask_overhead_per_case_ms": per_case_ms,
        "trivial_serial_per_case_ms": 1e3 * s_n / len(trivial),
        "cluster_startup_s": d_1,
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"real cases: {out['case']}, {len(cases)} per configuration")
    print(f"{'':24s}{'serial':>10s}{'dask 1 w':>10s}{'dask 2 w':>10s}")
    c = out["cases_per_minute"]
    print(f"{'cases per minute':24s}{c['serial']:10.1f}{c['dask_1']:10.1f}{c['dask_2']:10.1f}")
    print(f"{'wall (s)':24s}{t_serial:10.1f}{t_one:10.1f}{t_two:10.1f}")
    print(
        f"speed-up 2 workers / 1 worker: {out['speedup_2_over_1']:.2f}  "
        f"(1 worker / serial: {out['dask_1_over_serial']:.2f})"
    )
    print(
        f"Dask overhead per case: {per_case_ms:.2f} ms ({len(trivial)} trivial cases, 2 workers; serial "
        f"{out['trivial_serial_per_case_ms']:.3f} ms each); LocalCluster start-up + 1 case: {d_1:.1f} s"
    )


if __name__ == "__main__":
    main()
