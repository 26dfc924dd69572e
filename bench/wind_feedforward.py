"""Station keeping with and without the wind feed-forward: same scenario, same seeds, side by side.

The gateway pipeline runs in the loop with the simulator (`dpgw.closed_loop`, the typed path); the only
difference between the two runs of a seed is ``[control] wind_feedforward_gain`` (1 and 0). Errors are of the
true LF position and heading from the setpoint (the start), after the first ``--settle`` seconds.

    python bench/wind_feedforward.py [--scenario mss_supply_wind] [--seeds 1 2 3 4] [--duration 1200]
                                     [--settle 300] [--wind 18] [--filter 2] [--json]

``--wind`` sets the mean wind of ``mss_supply_wind`` (3 m/s: a calm day). Prints per seed the p95 of the
horizontal position error (m) and of the heading error (deg), off and on, and their ratio on/off.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from simulator.scenarios import Scenario, get_scenario, mss_supply_wind


def station_errors(
    scenario: Scenario, seed: int, duration_s: float, settle_s: float, **control: Any
) -> dict[str, float]:
    run = run_closed_loop(scenario, duration_s, seed=seed, tables=gateway_tables(scenario, **control))
    k = run.t >= settle_s
    pos = np.hypot(run.eta_lf[k, 0] - scenario.eta0[0], run.eta_lf[k, 1] - scenario.eta0[1])
    hdg = np.abs((run.eta_lf[k, 2] - scenario.eta0[2] + math.pi) % (2 * math.pi) - math.pi)
    return {
        "pos_p95_m": float(np.percentile(pos, 95)),
        "pos_max_m": float(pos.max()),
        "hdg_p95_deg": float(np.degrees(np.percentile(hdg, 95))),
    }


def compare(
    scenario: Scenario, seeds: list[int], duration_s: float, settle_s: float, filter_s: float
) -> list[dict[str, Any]]:
    rows = []
    for seed in seeds:
        off = station_errors(scenario, seed, duration_s, settle_s, wind_feedforward_gain=0.0)
        on = station_errors(
            scenario, seed, duration_s, settle_s, wind_feedforward_gain=1.0, wind_filter_s=filter_s
        )
        rows.append({"seed": seed, "off": off, "on": on})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="mss_supply_wind")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4])
    p.add_argument("--duration", type=float, default=1200.0, help="sim seconds per run")
    p.add_argument("--settle", type=float, default=300.0, help="seconds left out at the start")
    p.add_argument("--wind", type=float, default=None, help="mean wind of mss_supply_wind (m/s)")
    p.add_argument("--filter", type=float, default=2.0, help="wind_filter_s of the 'on' runs")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    scenario = mss_supply_wind(a.wind) if a.wind is not None else get_scenario(a.scenario)
    rows = compare(scenario, a.seeds, a.duration, a.settle, a.filter)
    if a.json:
        print(json.dumps({"scenario": scenario.name, "rows": rows}))
        return
    print(
        f"{scenario.name}: {scenario.description}; {a.duration:g} s, from {a.settle:g} s; "
        f"filter {a.filter:g} s"
    )
    print("seed  pos p95 off   on   on/off   hdg p95 off   on   on/off")
    for r in rows:
        off, on = r["off"], r["on"]
        pos = (off["pos_p95_m"], on["pos_p95_m"], on["pos_p95_m"] / off["pos_p95_m"])
        hdg = (off["hdg_p95_deg"], on["hdg_p95_deg"], on["hdg_p95_deg"] / off["hdg_p95_deg"])
        print(
            f"{r['seed']:4d}  {pos[0]:8.2f} {pos[1]:6.2f} {pos[2]:7.2f}"
            f"   {hdg[0]:8.2f} {hdg[1]:6.2f} {hdg[2]:7.2f}"
        )
    for key in ("pos_p95_m", "hdg_p95_deg"):
        ratio = np.mean([r["on"][key] / r["off"][key] for r in rows])
        print(f"mean ratio on/off {key}: {ratio:.2f}")


if __name__ == "__main__":
    main()
