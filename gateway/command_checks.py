"""Whether a command from Zenoh may be carried out: setpoints near the vessel, τ within the thrusters'
reach, DP only on a healthy estimate. Every refusal has a reason a person reads.

A DP gateway acts on its inputs; an input that would move the vessel somewhere absurd (a setpoint 50 km
away), ask for more force than the thrusters have (τ = 1e12), or put it in DP on an estimate nobody
trusts, is refused, counted and said, never half-obeyed. Access control (who may send commands at all)
is Zenoh's, configured in ``[zenoh]``; this module judges what an admitted command asks for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from observers.vessel import VesselModel

DEFAULT_MAX_SETPOINT_DISTANCE_M = 50.0
"""How far from the vessel's estimated position a new setpoint may be (``[control]
max_setpoint_distance_m``). DP moves a vessel metres to tens of metres at a time; a setpoint further away
is a typo, a wrong datum or an attack, and pursuing it would drive the vessel off its work."""

MODES = ("standby", "dp", "manual")
HEALTHY = ("ok", "degraded")  # estimate statuses DP may be engaged on


def force_capacity(vessel: VesselModel) -> NDArray[np.float64] | None:
    """The largest |X|, |Y|, |N| the thrusters can make, each alone (N, N, N·m); None without a layout.

    An azimuth points its whole thrust anywhere: it adds its rating to X and Y and its rating times its
    distance from the origin to N. A fixed unit adds its rating (or reverse rating) along its direction."""
    if not vessel.thrusters:
        return None
    cap = np.zeros(3)
    for th in vessel.thrusters:
        t = max(abs(th.max_thrust_n), abs(th.min_thrust_n))
        if th.kind == "azimuth":
            cap += t * np.array([1.0, 1.0, math.hypot(th.x_m, th.y_m)])
        else:
            a = th.angle_rad
            cap += t * np.abs([math.cos(a), math.sin(a), th.x_m * math.sin(a) - th.y_m * math.cos(a)])
    return cap


def check_mode(mode: Any, estimate_status: str | None) -> str | None:
    """Why a mode request is refused, or None."""
    if mode not in MODES:
        return f"mode {mode!r} is not one of {', '.join(MODES)}"
    if mode == "dp" and estimate_status not in HEALTHY:
        return (
            f"mode dp refused: the estimate is {estimate_status or 'not there yet'} (DP needs an estimate "
            "that is ok or degraded)"
        )
    return None


def check_setpoint(
    target_ned: NDArray[np.float64] | None,
    position_ned: NDArray[np.float64] | None,
    max_distance_m: float,
) -> str | None:
    """Why a setpoint (already in local NED: N, E, ψ) is refused, or None."""
    if target_ned is None or not np.all(np.isfinite(target_ned)):
        return "setpoint refused: expected finite north_m/east_m or lat_deg/lon_deg, and heading_deg"
    if position_ned is None or not np.all(np.isfinite(position_ned[:2])):
        return "setpoint refused: no position estimate yet to judge its distance by"
    distance = math.hypot(target_ned[0] - position_ned[0], target_ned[1] - position_ned[1])
    if distance > max_distance_m:
        return (
            f"setpoint refused: {distance:,.0f} m from the vessel's estimated position (at most "
            f"{max_distance_m:g} m: [control] max_setpoint_distance_m)"
        )
    return None


def check_tau(
    payload: Any, capacity: NDArray[np.float64] | None
) -> tuple[NDArray[np.float64] | None, str | None]:
    """τ = [X, Y, N] from a manual-τ input, or the reason it is refused."""
    if not isinstance(payload, Mapping):
        return None, "tau refused: expected {X, Y, N} in N, N, N·m"
    try:
        tau = np.array([float(payload[k]) for k in ("X", "Y", "N")])
    except (KeyError, TypeError, ValueError):
        return None, "tau refused: expected {X, Y, N} in N, N, N·m"
    if not np.all(np.isfinite(tau)):
        return None, "tau refused: not finite"
    if capacity is not None and np.any(np.abs(tau) > capacity):
        over = ", ".join(
            f"{k} {abs(v):.3g} > {c:.3g}" for k, v, c in zip("XYN", tau, capacity, strict=True) if abs(v) > c
        )
        return None, f"tau refused: beyond what the thrusters can make ({over})"
    return tau, None
