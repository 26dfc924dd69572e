"""Benchmark: the capability LP's two solvers side by side, and what the online consequence analysis costs
the closed loop.

1. `gateway.control.capability.CapabilityLP.scale` with DAQP (the default) and HiGHS (the reference) on
   the same random loads, per built-in vessel: µs a load by CPU time, the ratio, and the largest relative
   difference of k* between them.
2. The closed loop as the studies run it (`dpgw.closed_loop.run_closed_loop`, typed records), with the
   consequence analysis on and off, rounds interleaved: CPU ms per sim second and the ratio, and the LPs
   it solved.

    python bench/bench_capability.py [--loads 200] [--scenario torsetnes_2004] [--seconds 300]
                                     [--rounds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from typing import Any

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from gateway.control import capability
from observers.vessel import load_vessel
from simulator.scenarios import get_scenario

VESSELS = ("mss_supply", "mss_osv", "hajivand_vessel", "cybership2")


def solvers(loads: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    rng = np.random.default_rng(0)
    for name in VESSELS:
        v = load_vessel(name)
        scale = np.array([1.0, 1.0, v.length_m / 2]) * max(t.max_thrust_n for t in v.thrusters)
        taus = [rng.normal(size=3) * scale for _ in range(loads)]
        row: dict[str, float] = {}
        ks: dict[str, list[float]] = {}
        for solver in capability.SOLVERS:
            lp = capability.CapabilityLP(v.thrusters, solver=solver)
            t0 = time.process_time()
            ks[solver] = [lp.scale(t) for t in taus]
            row[f"{solver}_us"] = (time.process_time() - t0) / loads * 1e6
        row["highs_over_daqp"] = row["highs_us"] / row["daqp_us"]
        row["max_rel_diff"] = max(abs(a - b) / b for a, b in zip(ks["daqp"], ks["highs"], strict=True))
        out[name] = row
    return out


def loop(scenario: str, seconds: float, rounds: int) -> dict[str, Any]:
    sc = get_scenario(scenario)
    times: dict[bool, list[float]] = {False: [], True: []}
    lps = 0
    orig = capability.CapabilityLP.scale

    def counted(self: capability.CapabilityLP, tau: Any) -> float:
        nonlocal lps
        lps += 1
        return orig(self, tau)

    # one untimed run first: the first closed loop of a process pays the one-off costs (imports, the
    # allocation kernel's compilation, caches), ~20 times a run's own, which an even number of rounds
    # would put in one side's median
    run_closed_loop(sc, min(seconds, 10.0), seed=1, tables=gateway_tables(sc))
    capability.CapabilityLP.scale = counted  # type: ignore[method-assign]
    try:
        for r in range(rounds):
            for on in (False, True) if r % 2 == 0 else (True, False):  # (each first in turn)
                tables = gateway_tables(sc)
                tables["consequence"] = {"enabled": on}
                t0 = time.process_time()
                run_closed_loop(sc, seconds, seed=1, tables=tables)
                times[on].append((time.process_time() - t0) / seconds * 1e3)
    finally:
        capability.CapabilityLP.scale = orig  # type: ignore[method-assign]
    off, on = statistics.median(times[False]), statistics.median(times[True])
    return {
        "scenario": scenario,
        "sim_seconds": seconds,
        "off_ms_per_sim_s": off,
        "on_ms_per_sim_s": on,
        "on_over_off": on / off,
        "lps_per_run": lps / rounds,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--loads", type=int, default=200, help="random loads per vessel (200)")
    ap.add_argument("--scenario", default="torsetnes_2004", help="closed-loop scenario (torsetnes_2004)")
    ap.add_argument("--seconds", type=float, default=300.0, help="sim seconds per closed-loop run (300)")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds of the closed loop (3)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    a = ap.parse_args()
    result = {"solvers": solvers(a.loads), "closed_loop": loop(a.scenario, a.seconds, a.rounds)}
    if a.json:
        print(json.dumps(result, indent=2))
        return
    print("capability LP, µs a load (CPU)      DAQP     HiGHS   HiGHS/DAQP   max |Δk*|/k*")
    for name, r in result["solvers"].items():
        print(
            f"  {name:28s} {r['daqp_us']:8.0f} {r['highs_us']:9.0f} {r['highs_over_daqp']:10.1f}x"
            f"   {r['max_rel_diff']:.1e}"
        )
    c = result["closed_loop"]
    print(
        f"closed loop {c['scenario']}, {c['sim_seconds']:.0f} s, median of {a.rounds} interleaved rounds"
        " (CPU):"
        f" off {c['off_ms_per_sim_s']:.2f}, on {c['on_ms_per_sim_s']:.2f} ms per sim second"
        f" ({c['on_over_off']:.3f}x), {c['lps_per_run']:.0f} LPs a run"
    )


if __name__ == "__main__":
    main()
