"""Benchmark: the capability LP (`gateway.control.capability`) and the capability plot (`dpgw.capability`).

Per vessel, interleaved over the same random loads: one `CapabilityLP.scale` (constraints built once),
`attainable_scale` (built every call: the one-call form), and the same layout with a 60° barred sector on
two azimuths (four LPs per load: the convex pieces); median and p99 per call. Then one capability
plot at 30° (intact and every single failure), wall time.

    python bench/bench_capability_plot.py [--vessel mss_supply] [--loads 200] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from dpgw.capability import capability
from gateway.control.capability import CapabilityLP, attainable_scale
from observers.vessel import load_vessel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vessel", default="mss_supply")
    ap.add_argument("--loads", type=int, default=200)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    v = load_vessel(args.vessel)
    az = [i for i, t in enumerate(v.thrusters) if t.kind == "azimuth"][:2]
    barred = list(v.thrusters)
    for i in az:
        barred[i] = replace(barred[i], forbidden_sectors_deg=((150.0, 210.0),))
    built, built_barred = CapabilityLP(v.thrusters), CapabilityLP(barred)
    rng = np.random.default_rng(0)
    scale = np.array([1.0, 1.0, v.length_m / 4]) * max(t.max_thrust_n for t in v.thrusters)
    loads = rng.normal(size=(args.loads, 3)) * scale
    cases = {
        "CapabilityLP.scale": lambda tau: built.scale(tau),
        "attainable_scale (builds)": lambda tau: attainable_scale(v.thrusters, tau),
        f"2 barred sectors ({built_barred.lp_count} LPs)": lambda tau: built_barred.scale(tau),
    }
    times: dict[str, list[float]] = {k: [] for k in cases}
    for tau in loads:  # interleaved: load on the machine hits every case alike
        for name, fn in cases.items():
            t0 = time.perf_counter()
            fn(tau)
            times[name].append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    res = capability(v, step_deg=30.0, failures="each")
    plot_s = time.perf_counter() - t0
    out = {
        "vessel": v.name,
        "per_call_ms": {
            k: {"median": 1e3 * float(np.median(t)), "p99": 1e3 * float(np.percentile(t, 99))}
            for k, t in times.items()
        },
        "plot_30deg_each_failure_s": plot_s,
        "plot_cases": len(res.cases),
    }
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{v.name}: {args.loads} random loads, per call (ms)")
    for k, t in out["per_call_ms"].items():  # type: ignore[attr-defined]
        print(f"  {k:32s} median {t['median']:7.2f}   p99 {t['p99']:7.2f}")
    print(f"capability plot, 12 directions x {len(res.cases)} thruster conditions: {plot_s:.1f} s")


if __name__ == "__main__":
    main()
