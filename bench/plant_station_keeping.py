"""Station keeping on the observers' model plant and on the full plant, side by side: the HIL loop in one
process (`dpgw.closed_loop`), passive observer, DP controller and allocation, 30 minutes after a 5-minute
settle, p95 and mean of the true LF position and heading error from the setpoint.

Cases: `torsetnes_2004` as the paper has it (model plant); the same on the full plant (Coriolis, surge
resistance, cross-flow drag; no current or wind: the papers' environment); the same with fluid memory;
and `mss_supply_storm` (full plant, fluid memory, 1 m/s current, 15 m/s wind, Hs 6 m).

    python bench/plant_station_keeping.py [--seeds 1 2] [--duration 2100] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace

import numpy as np

from dpgw.closed_loop import run_closed_loop
from observers.kinematics import ssa
from observers.memory_tuning import default_radiation
from simulator.plant_params import PlantOptions
from simulator.scenarios import Scenario, get_scenario

SETTLE_S = 300.0


def cases() -> list[tuple[str, Scenario]]:
    tors = get_scenario("torsetnes_2004")
    return [
        ("torsetnes_2004, model plant", tors),
        ("torsetnes_2004, full plant", replace(tors, plant="full")),
        (
            "torsetnes_2004, full plant + memory",
            replace(tors, plant="full", plant_options=PlantOptions(radiation=default_radiation(tors.vessel))),
        ),
        ("mss_supply_storm (full, memory, current, wind)", get_scenario("mss_supply_storm")),
    ]


def keep_station(scenario: Scenario, duration: float, seed: int) -> dict[str, float]:
    n0, e0, psi0 = scenario.eta0
    events = [(0.0, "setpoint", {"north_m": n0, "east_m": e0, "heading_deg": math.degrees(psi0)})]
    t0 = time.perf_counter()
    r = run_closed_loop(scenario, duration, seed=seed, events=events)
    wall = time.perf_counter() - t0
    keep = r.t >= SETTLE_S
    pos = np.hypot(r.eta_lf[keep, 0] - n0, r.eta_lf[keep, 1] - e0)
    hdg = np.degrees(ssa(r.eta_lf[keep, 2] - psi0))
    est = np.array([e["eta"] for e in r.estimates if e.get("eta") is not None], dtype=float)
    return {
        "p95_position_m": float(np.percentile(pos, 95)),
        "p95_heading_deg": float(np.percentile(np.abs(hdg), 95)),
        "mean_heading_deg": float(hdg.mean()),
        "mean_north_m": float((r.eta_lf[keep, 0] - n0).mean()),
        "mean_east_m": float((r.eta_lf[keep, 1] - e0).mean()),
        "estimates": float(len(est)),
        "speedup": duration / wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--duration", type=float, default=2100.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = []
    for label, scenario in cases():
        per_seed = [keep_station(scenario, args.duration, s) for s in args.seeds]
        mean = {k: float(np.mean([p[k] for p in per_seed])) for k in per_seed[0]}
        spread = {k: float(np.ptp([p[k] for p in per_seed])) for k in per_seed[0]}
        rows.append({"case": label, "mean": mean, "spread": spread, "per_seed": per_seed})
        if not args.json:
            print(
                f"{label:48s} p95 {mean['p95_position_m']:5.2f} m (±{spread['p95_position_m'] / 2:.2f}) "
                f"{mean['p95_heading_deg']:5.2f}° (±{spread['p95_heading_deg'] / 2:.2f})  mean ψ "
                f"{mean['mean_heading_deg']:+.3f}°  N {mean['mean_north_m']:+.2f} "
                f"E {mean['mean_east_m']:+.2f} m"
                f"  [{mean['speedup']:.0f}x real time]",
                flush=True,
            )
    if args.json:
        print(json.dumps({"seeds": args.seeds, "duration_s": args.duration, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
