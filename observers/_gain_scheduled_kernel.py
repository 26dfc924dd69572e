"""Compiled scheduling loop of the gain-scheduled observer, Torsetnes, Jouffroy & Fossen (2004) Sec. III.

The fast twin of `observers.gain_scheduled.reference_run`; ``tests/test_gain_scheduled.py`` checks that the
two agree. Per sample: take a new ω0 target, move the scheduled ω0 towards it (a first-order lag, within the
contraction budget of `observers.gain_scheduled_analysis`), recompute the gains (51)–(52) in closed form,
then one step of the passive kernel (`observers._passive_kernel`) with them.

Packed tuning ``P`` (10×3), one column per DOF, one row per quantity (``P_*`` below; filled by
`observers.gain_scheduled.pack_tuning`). A quantity given as a ratio to ω0 (the default tuning) scales
with the scheduled ω0; one given in absolute units stays::

    ζ   ζn   ωc (ratio or rad/s)   ωc-is-ratio   a (ratio or 1/s)   a-is-ratio   ρ (ratio or rad/s)
    ρ-is-ratio   M_ii   1/T

Schedule state ``S`` (4): time of the last sample, started flag, budget β, scheduling enabled (``S_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers import _passive_kernel as kernel
from observers._passive_kernel import (
    G_K1,
    G_K2,
    G_K3,
    G_KAPPA,
    G_LAMBDA,
    G_OMEGA0,
    G_T_INV,
    G_ZETA,
)
from observers.base import STATUS_INITIALIZING
from observers.state import N_STATE

SNAP = 1e-9
"""Within this relative distance of its target, the scheduled ω0 takes the target exactly (then rests)."""

# rows of the packed tuning P
P_ZETA = 0  # ζ of the wave model
P_ZETA_N = 1  # ζn of the notch (44)
P_OMEGA_C = 2  # ωc: ratio ωc/ω0, or rad/s
P_OMEGA_C_IS_RATIO = 3  # 1.0 if the row above is a ratio to ω0
P_INJECTION = 4  # a, the velocity-injection rate: ratio a/ω0, or 1/s
P_INJECTION_IS_RATIO = 5
P_BIAS_CORNER = 6  # ρ = λ/κ: ratio ρ/ω0, or rad/s
P_BIAS_CORNER_IS_RATIO = 7
P_MASS = 8  # M_ii, the vessel-scaled injection's inertia
P_T_INV = 9  # 1/T of the bias model
P_INJECTION_FLOOR = 10  # the least ratio-set a, 1/s (passive_tuning.injection_floor)
N_TUNING_ROWS = 11

# the schedule state S
S_T = 0  # time of the last sample
S_STARTED = 1  # 1.0 after the first sample
S_BUDGET = 2  # β, the contraction budget left
S_ENABLED = 3  # 1.0: ω0 follows its target; 0.0: held (the fixed observer)
N_SCHEDULE = 4


@njit(cache=True, inline="always")
def gains_at(omega, P, G):
    """Packed kernel gains G (8×3) at ω0 — the arithmetic of `passive_gains`, operation for operation."""
    for i in range(3):
        w0 = omega[i]
        z = P[P_ZETA, i]
        zn = P[P_ZETA_N, i]
        wc = w0 * P[P_OMEGA_C, i] if P[P_OMEGA_C_IS_RATIO, i] > 0.0 else P[P_OMEGA_C, i]
        a = (
            max(w0 * P[P_INJECTION, i], P[P_INJECTION_FLOOR, i])
            if P[P_INJECTION_IS_RATIO, i] > 0.0
            else P[P_INJECTION, i]
        )
        rho = w0 * P[P_BIAS_CORNER, i] if P[P_BIAS_CORNER_IS_RATIO, i] > 0.0 else P[P_BIAS_CORNER, i]
        K4 = P[P_MASS, i] * wc * a
        G[G_OMEGA0, i] = w0
        G[G_ZETA, i] = z
        G[G_K1, i] = -2.0 * (zn - z) * wc / w0  # (45), Torsetnes (51)
        G[G_K2, i] = 2.0 * w0 * (zn - z)  # (46), (51)
        G[G_K3, i] = wc  # (47), (52)
        G[G_LAMBDA, i] = K4 * rho
        G[G_KAPPA, i] = K4
        G[G_T_INV, i] = P[P_T_INV, i]


@njit(cache=True, inline="always")
def _interp(x, xp, fp):
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = np.searchsorted(xp, x) - 1
    f = (x - xp[j]) / (xp[j + 1] - xp[j])
    return fp[j] + f * (fp[j + 1] - fp[j])


@njit(cache=True, inline="always")
def _cell_min(x, xp, fp):
    """min of fp over the grid cell holding x (a conservative piecewise-constant α)."""
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = np.searchsorted(xp, x) - 1
    return min(fp[j], fp[j + 1])


@njit(cache=True, inline="always")
def _cost(omega, new, s, grid, cost, shared):
    c = 0.0
    if shared:
        a = _interp(omega[0], grid, cost[0])
        b = _interp(omega[0] + s * (new[0] - omega[0]), grid, cost[0])
        return abs(b - a)
    for i in range(3):
        a = _interp(omega[i], grid, cost[i])
        b = _interp(omega[i] + s * (new[i] - omega[i]), grid, cost[i])
        c += abs(b - a)
    return c


@njit(cache=True, inline="always")
def advance_schedule(omega, target, S, dt, tau_r, grid, alpha, cost, budget, shared, new):
    """Move ω0 over dt towards target: first-order lag τ_r, within the contraction budget. True if moved.

    ``new`` is scratch space (3,). Within SNAP (relative) of the target, ω0 takes the target exactly.
    """
    moving = False
    near = True
    for i in range(3):
        if omega[i] != target[i]:
            moving = True
            if abs(target[i] - omega[i]) > SNAP * omega[i]:
                near = False
    if not moving and S[S_BUDGET] >= budget:
        return False  # at rest with a full budget: nothing to do
    w_min = omega[0]
    for i in range(1, 3):
        w_min = min(w_min, omega[i])
    beta = min(budget, S[S_BUDGET] + _cell_min(w_min, grid, alpha) * dt)
    if not moving:
        S[S_BUDGET] = beta
        return False
    f = 1.0 if near or tau_r <= 0.0 else 1.0 - math.exp(-dt / tau_r)
    for i in range(3):
        new[i] = omega[i] + (target[i] - omega[i]) * f
    c = _cost(omega, new, 1.0, grid, cost, shared)
    s = 1.0
    if c > beta:
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if _cost(omega, new, mid, grid, cost, shared) <= beta:
                lo = mid
            else:
                hi = mid
        s = lo
        c = _cost(omega, new, s, grid, cost, shared)
    for i in range(3):
        omega[i] = new[i] if s == 1.0 else omega[i] + s * (new[i] - omega[i])
    S[S_BUDGET] = max(0.0, beta - c)
    return s > 0.0


@njit(cache=True)
def run_scheduled(
    x,
    clock,
    S,
    omega,
    target,
    upd_index,
    upd_target,
    t,
    Y,
    TAU,
    P,
    G,
    Minv,
    D,
    h_max,
    max_hold,
    tau_r,
    grid,
    alpha,
    cost,
    budget,
    shared,
    X_out,
    status_out,
    W_out,
):
    """Per sample: take a new target if one arrives at sample k (upd_index, sorted; upd_target rows), advance
    the schedule to t_k (its gains held over the interval), then the passive step."""
    n = t.shape[0]
    p = 0
    scratch = np.empty(3)
    for k in range(n):
        while p < upd_index.shape[0] and upd_index[p] == k:
            for i in range(3):
                target[i] = upd_target[p, i]
            p += 1
        tk = t[k]
        if S[S_STARTED] == 0.0:
            S[S_T] = tk
            S[S_STARTED] = 1.0
        elif tk > S[S_T]:
            dt = tk - S[S_T]
            S[S_T] = tk
            if S[S_ENABLED] > 0.0 and advance_schedule(
                omega, target, S, dt, tau_r, grid, alpha, cost, budget, shared, scratch
            ):
                gains_at(omega, P, G)
        code = kernel.step(x, clock, tk, Y[k], TAU[k], G, Minv, D, h_max, max_hold)
        status_out[k] = code
        for i in range(3):
            W_out[k, i] = omega[i]
        if code == STATUS_INITIALIZING:
            for j in range(N_STATE):
                X_out[k, j] = np.nan
        else:
            for j in range(N_STATE):
                X_out[k, j] = x[j]
