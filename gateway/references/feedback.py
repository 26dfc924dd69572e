"""Thruster feedback range checks: a report is a number about a physical machine, so it must be one the
machine can produce. Thrust within the thruster's capacity × margin (either direction: some thrusters
reverse), finite azimuth and shaft speed, shaft speed within max rpm × margin, azimuth within ±2π.

The dialect sends azimuths in [-π, π); ±2π also admits a drive that reports [0, 2π). Beyond that the
number is no angle in radians: most likely degrees (a drive configured for them), which read as radians
would turn the thrust to an arbitrary direction in τ."""

from __future__ import annotations

import math

from observers.vessel import Thruster

AZIMUTH_LIMIT_RAD = 2.0 * math.pi
"""A reported azimuth beyond ± this is out of range."""


def feedback_problem(
    thruster: Thruster | None,
    thrust_n: float | None,
    azimuth_rad: float | None,
    rpm: float | None,
    margin: float,
) -> str:
    """Why a thruster report is out of range ("" if it is not)."""
    if thruster is None:
        return "unknown thruster"
    if thrust_n is not None:
        cap = max(abs(thruster.max_thrust_n), abs(thruster.min_thrust_n)) * margin
        if abs(thrust_n) > cap:  # NaN (the sender does not know) is no thrust, not a bad one
            return f"thrust {thrust_n:.4g} N beyond capacity {cap:.4g} N"
    if azimuth_rad is not None and math.isinf(azimuth_rad):
        return "azimuth not finite"
    if azimuth_rad is not None and abs(azimuth_rad) > AZIMUTH_LIMIT_RAD:
        return f"azimuth {azimuth_rad:.4g} rad beyond ±2π (degrees sent as radians?)"
    if rpm is not None and abs(rpm) > thruster.max_rpm * margin:
        return f"shaft speed {rpm:.4g} rpm beyond {thruster.max_rpm * margin:.4g} rpm"
    return ""
