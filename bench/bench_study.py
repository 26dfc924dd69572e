"""`dpgw study` on Dask: cases per minute serially, on 1 and on 2 local workers, and Dask's own cost per case.

All in one run, side by side (the machine is shared and noisy: compare the ratios, not the absolute
figures across runs):

* **scaling**: the same real cases (a closed loop + every registered observer + scoring each) serially in
  this process, then on a LocalCluster of 1 and of 2 worker processes (one thread each), each cluster
  warmed first with one other case per worker (imports and numba's cached kernels: the start-up, reported
  on its own). Ideal 2-worker speed-up is 2.0 on two free cores.
* **overhead**: a trivial case (returns one row at once) N times serially and on the warm 2-worker
  cluster: Dask's cost per case = (time on Dask − serial time) / N.

    python bench/bench_study.py [--cases 8] [--duration 300] [--trivial 400] [--json]
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from typing import Any

from dpgw.study.runner import run_study
from dpgw.study.spec import StudySpec


def trivial_case(case: dict[str, Any]) -> list[dict[str, Any]]:
    return [{"seed": case["seed"], "value": 1.0}]


def timed(cases: list[Any], workers: int = 0, fn: Any = None, scheduler: str | None = None) -> float:
    t0 = time.perf_counter()
    run_study(cases, workers=workers, case_fn=fn, scheduler=scheduler)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=8, help="real cases per configuration")
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds per real case")
    ap.add_argument("--scenario", default="torsetnes_2004")
    ap.add_argument("--trivial", type=int, default=400, help="trivial cases for the overhead")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    from distributed import Client, LocalCluster

    from dpgw.study.case import run_case

    spec = StudySpec(scenarios=(args.scenario,), seeds=tuple(range(args.cases)), duration_s=args.duration)
    cases = spec.cases()
    trivial = StudySpec(
        scenarios=("hassani",), seeds=tuple(range(args.trivial)), observers=("passive",)
    ).cases()
    run_study(cases[:1], workers=0)  # numba's cache loaded and the modules imported here, as on a worker
    t_serial = timed(cases)
    s_n = timed(trivial, fn=trivial_case)
    wall: dict[int, float] = {}
    startup: dict[int, float] = {}
    d_n = 0.0
    for n in (1, 2):
        with LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster:
            address = cluster.scheduler_address
            # every worker runs one short case first (client.run: on each worker)
            warm = StudySpec(scenarios=(args.scenario,), seeds=(1000,), duration_s=10.0).cases()[0].as_dict()
            t0 = time.perf_counter()
            with Client(address) as client:
                client.run(run_case, warm)
            startup[n] = time.perf_counter() - t0
            wall[n] = timed(cases, scheduler=address)
            if n == 2:
                d_n = timed(trivial, fn=trivial_case, scheduler=address)
    per_case_ms = 1e3 * (d_n - s_n) / len(trivial)
    t_one, t_two = wall[1], wall[2]

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
        "worker_warmup_s": startup,
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
        f"Dask overhead per case: {per_case_ms:.2f} ms ({len(trivial)} trivial cases, 2 warm workers; serial "
        f"{out['trivial_serial_per_case_ms']:.3f} ms each)"
    )
    print(
        f"a short first case on every worker (imports, numba cache): {startup[1]:.1f} s on 1 worker, "
        f"{startup[2]:.1f} s on 2"
    )


if __name__ == "__main__":
    main()
