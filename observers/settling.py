"""When an observer's estimate is taken as settled: `Observer.settle_time_s`, one rule for every observer.

A wave-filtering observer starts (its first complete measurement, or a restart) with its bias estimate at
zero or at the load's equilibrium guess, and the error decays with the observer's slowest error mode: for
the passive observer of Fossen & Strand (1999) the bias mode, ≈ aρ/(d + a) per DOF (docs/passive-observer.md),
~96 s on the default scenario. A DP controller engaged on that estimate fights a bias error that is still
going away: its integrator takes the load the bias estimate does not yet carry, and gives it back as the
estimate grows. A DP operator engages once the position reference and the observer are ready; the gateway
says when that is (the estimate's ``settled``) and, with ``[control] wait_for_observer``, waits for it.

The rule: `ENGAGE_TIME_CONSTANTS` time constants of the slowest error mode, T_s = 1.5 / |λ_slowest|. The
papers give no such figure (they state convergence, not when to trust it); the factor is dpgw's, measured
in the closed loop on the default scenario (docs/gateway.md, "How the demo engages DP"): DP engaged at the
first estimate gave p95 4.3 m / 5.8° over the first minutes, at a third of a time constant p95 3.3 m /
2.6°, at 1.5 time constants 0.75 m / 1.0°. After 1.5 time constants an initial error is down to e^−1.5 ≈
22 % — the load it leaves is one the controller's integrator answers without a transient of note.

Numerics only (no I/O): the observers call these with their own slowest rate.
"""

from __future__ import annotations

import math

ENGAGE_TIME_CONSTANTS = 1.5
"""The estimate is taken as settled this many time constants of the observer's slowest error mode after
its start (module docstring: the measured reason)."""

UNKNOWN_SETTLE_S = 300.0
"""The settle time of an observer whose error dynamics give no figure (an observer of another family that
does not derive its own, or a tuning whose slowest mode is not stable): five minutes, twice the passive
observer's on the default scenario (145 s) — a conservative wait, as an operator waits for a filter they
cannot judge; dpgw's choice, stated where it is used (the estimate's ``settle_s_left``)."""


def settle_time_from_rate(rate: float) -> float:
    """T_s = `ENGAGE_TIME_CONSTANTS` / −λ for the slowest error eigenvalue's real part λ (1/s, negative);
    `UNKNOWN_SETTLE_S` for a λ that is not a finite negative number (no stable slowest mode to go by)."""
    if not (math.isfinite(rate) and rate < 0.0):
        return UNKNOWN_SETTLE_S
    return ENGAGE_TIME_CONSTANTS / -rate


def settle_time_from_time_constant(time_constant_s: float) -> float:
    """T_s = `ENGAGE_TIME_CONSTANTS` × τ for the slowest mode's time constant τ (s, positive);
    `UNKNOWN_SETTLE_S` for a τ that is not a finite positive number."""
    if not (math.isfinite(time_constant_s) and time_constant_s > 0.0):
        return UNKNOWN_SETTLE_S
    return ENGAGE_TIME_CONSTANTS * time_constant_s


__all__ = [
    "ENGAGE_TIME_CONSTANTS",
    "UNKNOWN_SETTLE_S",
    "settle_time_from_rate",
    "settle_time_from_time_constant",
]
