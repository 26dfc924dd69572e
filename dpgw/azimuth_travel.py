"""Azimuth travel in closed-loop station keeping: how far the commanded azimuths turn, in °/min.

A DP engineer reads an azimuth that keeps slewing while the vessel holds station as wear (slewing gear,
seals) and as thrust lost while turning. This measures it on the gateway's own closed loop
(`dpgw.closed_loop.run_closed_loop`, holding the scenario's start position and heading): the sum of the
commanded azimuth changes |ssa(αₖ₊₁ − αₖ)| over a window, per minute, with the station-keeping figures
of the same run (true LF position and heading error, p95) beside it.

    python -m dpgw.azimuth_travel --scenario torsetnes_2004 --json
    python -m dpgw.azimuth_travel --before      # also the allocation as it was, side by side

``--before`` runs the same loop with the allocation's earlier tuning (`BEFORE`: the turn cost on the
cross force, c = 1, no thrust biasing, ρ₁ = √ρ₂), to compare in one run.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import math
import sys
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

import gateway.pipeline
from dpgw.cli_types import seed_int
from dpgw.closed_loop import ClosedLoopRun, run_closed_loop
from dpgw.station_hold import hold_setpoint
from gateway.control.allocation import QPAllocator
from simulator.clock import SimEpoch
from simulator.scenarios import get_scenario

BEFORE: dict[str, Any] = {
    "turn_weight": 1.0,
    "turn_thrust_floor": 1.0,  # the cost on the cross force itself, not over the present thrust
    "bias_fraction": 0.0,
    "slack_l1_weight": 1e3,
}
"""The allocation's options before the azimuths were stopped from hunting (`docs/allocation.md`)."""


@contextlib.contextmanager
def _allocator_options(options: dict[str, Any] | None) -> Any:
    """The gateway pipeline's QP allocator made with ``options`` while the block runs (None: as is)."""
    if not options:
        yield
        return
    saved = gateway.pipeline.QPAllocator
    gateway.pipeline.QPAllocator = functools.partial(QPAllocator, **options)  # type: ignore[misc,assignment]
    try:
        yield
    finally:
        gateway.pipeline.QPAllocator = saved  # type: ignore[misc]


@dataclass(frozen=True)
class TravelFigures:
    scenario: str
    allocation: str  # "default" or "before"
    seed: int
    window_s: tuple[float, float]
    travel_deg_per_min: dict[str, float]  # thruster id -> commanded azimuth travel, °/min
    slew_deg_per_min: dict[str, float]  # thruster id -> its rated slew rate, °/min
    thrust_median_fraction: dict[str, float]  # thruster id -> median commanded thrust / T_max
    saturated_fraction: float  # of the window's allocation steps reported saturated
    position_p95_m: float  # true LF horizontal distance from the station
    heading_p95_deg: float  # true LF |heading error|


def _ssa(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def travel_of(
    run: ClosedLoopRun, scenario: Any, t0: float, t1: float, seed: int = 0, allocation: str = "default"
) -> TravelFigures:
    """The figures of a run over [t0, t1] s (sim time)."""
    vessel = scenario.vessel
    az = [th for th in vessel.thrusters if th.kind == "azimuth"]
    times, angles, thrusts, saturated = [], [], [], []
    for m in run.command_messages:
        if not m.thrusters:
            continue
        saturated.append(bool(m.saturated))
        by_id = {str(th.id): th for th in m.thrusters}
        times.append(m.stamp_ns)
        angles.append([by_id[str(th.id)].azimuth_rad for th in az])
        thrusts.append([by_id[str(th.id)].thrust_n for th in az])
    # sim time of a command: its stamp less the scenario's epoch (sim time 0)
    epoch_ns = SimEpoch(scenario.start_utc).stamp_ns(0.0)
    t = (np.array(times, dtype=np.int64) - epoch_ns) * 1e-9
    sel = (t >= t0) & (t <= t1)
    a = np.asarray(angles, dtype=float)[sel]
    f = np.asarray(thrusts, dtype=float)[sel]
    minutes = (t1 - t0) / 60.0
    step = np.abs(_ssa(np.diff(a, axis=0)))
    keep = (run.t >= t0) & (run.t <= t1)
    north, east, psi = scenario.eta0
    pos = np.hypot(run.eta_lf[keep, 0] - north, run.eta_lf[keep, 1] - east)
    head = np.degrees(np.abs(_ssa(run.eta_lf[keep, 2] - psi)))
    return TravelFigures(
        scenario=scenario.name,
        allocation=allocation,
        seed=seed,
        window_s=(t0, t1),
        travel_deg_per_min={
            str(th.id): float(np.degrees(step[:, k].sum()) / minutes) for k, th in enumerate(az)
        },
        slew_deg_per_min={str(th.id): math.degrees(th.azimuth_rate_rad_s) * 60.0 for th in az},
        thrust_median_fraction={
            str(th.id): float(np.median(f[:, k]) / th.max_thrust_n) for k, th in enumerate(az)
        },
        saturated_fraction=float(np.mean(np.asarray(saturated)[sel])),
        position_p95_m=float(np.percentile(pos, 95)),
        heading_p95_deg=float(np.percentile(head, 95)),
    )


def measure(
    scenario_name: str,
    *,
    seed: int = 1,
    settle_s: float = 200.0,
    window_s: float = 400.0,
    allocator_options: dict[str, Any] | None = None,
) -> TravelFigures:
    """Hold the scenario's start station for ``settle_s + window_s`` and measure over the window.
    ``allocator_options``: `QPAllocator` options for the gateway's allocation (e.g. `BEFORE`)."""
    sc = get_scenario(scenario_name)
    events = [(0.0, "setpoint", hold_setpoint(sc))]
    with _allocator_options(allocator_options):
        run = run_closed_loop(sc, settle_s + window_s, seed=seed, events=events)
    label = "before" if allocator_options == BEFORE else ("options" if allocator_options else "default")
    return travel_of(run, sc, settle_s, settle_s + window_s, seed, label)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m dpgw.azimuth_travel",
        description="Measure how far the commanded azimuths turn (°/min) while the gateway keeps station "
        "in a simulated scenario (its start position and heading), with the station-keeping p95 errors of "
        "the same run. A DP engineer expects a small fraction of the slew rate, not continuous slewing.",
    )
    p.add_argument(
        "--scenario", action="append", help="scenario name (repeatable; default torsetnes_2004 and hassani)"
    )
    p.add_argument("--seed", type=seed_int, default=1)
    p.add_argument("--settle", type=float, default=200.0, help="s held before the window (default 200)")
    p.add_argument("--window", type=float, default=400.0, help="s measured (default 400)")
    p.add_argument("--json", action="store_true", help="one JSON object per scenario, for programs")
    p.add_argument(
        "--before",
        action="store_true",
        help="also run the allocation's earlier tuning (BEFORE), side by side",
    )
    args = p.parse_args(argv)
    runs = [None, BEFORE] if args.before else [None]
    for name in args.scenario or ["torsetnes_2004", "hassani"]:
        for options in runs:
            fig = measure(
                name, seed=args.seed, settle_s=args.settle, window_s=args.window, allocator_options=options
            )
            if args.json:
                print(json.dumps(asdict(fig)))
            else:
                print(
                    f"{fig.scenario}, allocation {fig.allocation} "
                    f"(seed {fig.seed}, {fig.window_s[0]:.0f}-{fig.window_s[1]:.0f} s):"
                )
                for k, v in fig.travel_deg_per_min.items():
                    print(
                        f"  azimuth {k}: {v:7.1f} °/min  (slew {fig.slew_deg_per_min[k]:.0f} °/min, "
                        f"median thrust {100 * fig.thrust_median_fraction[k]:.1f} % of T_max)"
                    )
                print(
                    f"  position p95 {fig.position_p95_m:.3f} m, heading p95 {fig.heading_p95_deg:.3f}°, "
                    f"saturated {100 * fig.saturated_fraction:.1f} % of the steps"
                )
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
