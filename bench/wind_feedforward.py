"""Station keeping with and without the wind feed-forward: same scenario, same seeds, side by side.

The gateway pipeline runs in the loop with the simulator (`dpgw.closed_loop`, the typed path); the only
difference between the two runs of a seed is ``[control] wind_feedforward_gain`` (1 and 0). Errors are of the
true LF position and heading from the setpoint (the start), after the first ``--settle`` seconds.

    python bench/wind_feedforward.py [--scenario mss_supply_wind] [--seeds 1 2 3 4] [--duration 1200]
                                     [--settle 300] [--wind 18] [--filter 2] [--json]

``--wind`` sets the mean wind of ``mss_supply_wind`` (3 m/s: a calm day). Prints per seed the p95 of the
horizontal position error (m) and of the heading error (deg), off and on, and their ratio on/off.

Losing the anemometer (``--loss T``): the anemometer drops out (`simulator.faults` ``dropout`` on every
anemometer) from T s to the end, and three runs per seed are compared: without feed-forward, with it
dropped at once when the wind is lost (``wind_loss_fade_s = 0``, the behaviour before the fade) and with the
default fade (or ``--fade`` s). Printed: the peak horizontal position and heading deviation from the
setpoint in the ``--window`` s after the loss (and, for scale, the peak in the same length before it).

    python bench/wind_feedforward.py --loss 600 --duration 1200 [--window 600] [--fade 286] [--back 700]

``--back T2``: the anemometer sends again from T2 (a return while the fade runs, or after it).
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from typing import Any

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from simulator.faults import Fault
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


def with_anemometer_loss(scenario: Scenario, t_loss: float, t_back: float = math.inf) -> Scenario:
    """The scenario with every anemometer silent from ``t_loss`` to ``t_back`` (a ``dropout`` fault)."""
    lost = tuple(Fault("dropout", a.source, t_loss, t_back) for a in scenario.anemometers)
    return replace(scenario, faults=(*scenario.faults, *lost))


def loss_deviation(
    scenario: Scenario,
    seed: int,
    duration_s: float,
    t_loss: float,
    window_s: float,
    settle_s: float = 300.0,
    t_back: float = math.inf,
    **control: Any,
) -> dict[str, float]:
    """Peak horizontal position (m) and heading (deg) deviation of the true LF pose from the setpoint in
    the ``window_s`` after the anemometer is lost at ``t_loss``, and before it (from ``settle_s``)."""
    sc = with_anemometer_loss(scenario, t_loss, t_back)
    run = run_closed_loop(sc, duration_s, seed=seed, tables=gateway_tables(sc, **control))
    pos = np.hypot(run.eta_lf[:, 0] - sc.eta0[0], run.eta_lf[:, 1] - sc.eta0[1])
    hdg = np.degrees(np.abs((run.eta_lf[:, 2] - sc.eta0[2] + math.pi) % (2 * math.pi) - math.pi))
    after = (run.t >= t_loss) & (run.t < t_loss + window_s)
    before = (run.t >= settle_s) & (run.t < t_loss)
    return {
        "pos_peak_m": float(pos[after].max()),
        "hdg_peak_deg": float(hdg[after].max()),
        "pos_peak_before_m": float(pos[before].max()),
        "hdg_peak_before_deg": float(hdg[before].max()),
    }


LOSS_CASES: dict[str, dict[str, Any]] = {
    "off": {"wind_feedforward_gain": 0.0},
    "drop": {"wind_feedforward_gain": 1.0, "wind_loss_fade_s": 0.0},
    "fade": {"wind_feedforward_gain": 1.0},
}
"""The runs of ``--loss``: no feed-forward, the feed-forward dropped at once, faded (default T_f)."""


def compare_loss(
    scenario: Scenario,
    seeds: list[int],
    duration_s: float,
    t_loss: float,
    window_s: float,
    settle_s: float,
    fade_s: float | None = None,
    t_back: float = math.inf,
) -> list[dict[str, Any]]:
    rows = []
    for seed in seeds:
        row: dict[str, Any] = {"seed": seed}
        for case, control in LOSS_CASES.items():
            if case == "fade" and fade_s is not None:
                control = {**control, "wind_loss_fade_s": fade_s}
            row[case] = loss_deviation(
                scenario, seed, duration_s, t_loss, window_s, settle_s, t_back, **control
            )
        rows.append(row)
    return rows


def print_loss(scenario: Scenario, rows: list[dict[str, Any]], a: argparse.Namespace) -> None:
    fade = "default" if a.fade is None else f"{a.fade:g} s"
    print(
        f"{scenario.name}: anemometer lost at {a.loss:g} s"
        + ("" if a.back is None else f", back at {a.back:g} s")
        + f"; peak deviation in the {a.window:g} s after "
        f"(before: from {a.settle:g} s to the loss); fade {fade}"
    )
    print(
        "seed  pos peak (m) off  drop  fade  fade/drop (before: off drop fade)"
        "   hdg peak (deg) off  drop  fade  fade/drop"
    )
    for r in rows:
        o, d, f = r["off"], r["drop"], r["fade"]
        print(
            f"{r['seed']:4d}  {o['pos_peak_m']:16.2f} {d['pos_peak_m']:5.2f} {f['pos_peak_m']:5.2f}"
            f" {f['pos_peak_m'] / d['pos_peak_m']:9.2f}"
            f"   ({o['pos_peak_before_m']:.2f} {d['pos_peak_before_m']:.2f} {f['pos_peak_before_m']:.2f})"
            f"  {o['hdg_peak_deg']:23.2f} {d['hdg_peak_deg']:5.2f} {f['hdg_peak_deg']:5.2f}"
            f" {f['hdg_peak_deg'] / d['hdg_peak_deg']:9.2f}"
        )
    for key in ("pos_peak_m", "hdg_peak_deg"):
        ratio = np.mean([r["fade"][key] / r["drop"][key] for r in rows])
        print(f"mean ratio fade/drop {key}: {ratio:.2f}")


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
    p.add_argument("--loss", type=float, default=None, help="lose the anemometer at this sim time (s)")
    p.add_argument("--window", type=float, default=600.0, help="--loss: seconds after the loss scored")
    p.add_argument("--back", type=float, default=None, help="--loss: the anemometer back at this time (s)")
    p.add_argument("--fade", type=float, default=None, help="--loss: wind_loss_fade_s (default: derived)")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    scenario = mss_supply_wind(a.wind) if a.wind is not None else get_scenario(a.scenario)
    if a.loss is not None:
        back = math.inf if a.back is None else a.back
        rows = compare_loss(scenario, a.seeds, a.duration, a.loss, a.window, a.settle, a.fade, back)
        if a.json:
            print(json.dumps({"scenario": scenario.name, "loss_s": a.loss, "rows": rows}))
        else:
            print_loss(scenario, rows, a)
        return
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
