"""Compiled kernel of the fluid-memory observer, Hajivand & Mousavizadegan (2010) eqs (17)–(21).

The fast twin of the readable reference in `observers.memory` (`reference_derivative`,
`reference_propagate`); ``tests/test_memory_observer.py`` checks that the two agree to round-off. Keep the
equations here line for line with the reference.

State ``x`` (15 + n): the passive observer's layout (`observers.state`: ξ1, ξ2 = η_w, η, b, ν), then the
n radiation states ξ_r. Eqs (17)–(19), (21) are the passive observer's (22)–(24), (26) and are computed
by `observers._passive_kernel.derivative` itself; (20) differs only by the radiation force, so it is that
derivative with τ - μ̂ in place of τ (same M⁻¹, Jᵀ, injection), with M = M_RB + A(∞) and D = D_m.

The radiation matrices are block diagonal (one block per identified element), so they are passed as
their non-zero entries (``idx`` rows/columns, ``val``): a dense 17×17 product per RK stage would cost more
than the rest of the observer. ``rad`` = (ar_idx, ar_val, br_idx, br_val, cr_idx, cr_val, Dr, S) with
S = -A_r⁻¹ B_r (the radiation states at rest for a constant ν̂, used to start in equilibrium).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers import _passive_kernel as pk
from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit
from observers.state import I_NU, I_PSI, N_STATE

CLOCK_T = 0
CLOCK_STARTED = 1


@njit(cache=True)
def radiation_force(x, rad, mu):
    """μ̂ = C_r ξ̂_r + D_r ν̂ (7), into mu (3)."""
    cr_idx, cr_val, Dr = rad[4], rad[5], rad[6]
    for i in range(3):
        mu[i] = Dr[i, 0] * x[I_NU] + Dr[i, 1] * x[I_NU + 1] + Dr[i, 2] * x[I_NU + 2]
    for k in range(cr_val.shape[0]):
        mu[cr_idx[k, 0]] += cr_val[k] * x[N_STATE + cr_idx[k, 1]]


@njit(cache=True)
def derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, work, out):
    """x' of (17)–(21) with y, τ held; ``work`` (6) is scratch for μ̂ and τ - μ̂."""
    mu = work[0:3]
    tau_eff = work[3:6]
    radiation_force(x, rad, mu)
    # (20): [M_RB + A(∞)] ν̂' = -D ν̂ + Jᵀ b̂ + τ - μ̂ + Jᵀ K4 ỹ. The sign of μ̂ is that of (8),
    # [M + A] ν' + μ = f_ext (the radiation force opposes the motion); the printed (20) has +μ, which
    # would feed energy into the velocity estimate.
    for i in range(3):
        tau_eff[i] = tau[i] - mu[i]
    pk.derivative(x, y, mask, tau_eff, psi_meas, use_meas_psi, G, Minv, D, out)
    # ξ̂_r' = A_r ξ̂_r + B_r ν̂ (7), driven by the velocity estimate
    ar_idx, ar_val, br_idx, br_val = rad[0], rad[1], rad[2], rad[3]
    for j in range(N_STATE, x.shape[0]):
        out[j] = 0.0
    for k in range(ar_val.shape[0]):
        out[N_STATE + ar_idx[k, 0]] += ar_val[k] * x[N_STATE + ar_idx[k, 1]]
    for k in range(br_val.shape[0]):
        out[N_STATE + br_idx[k, 0]] += br_val[k] * x[I_NU + br_idx[k, 1]]


@njit(cache=True)
def _integrate(x, span, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, h_max):
    """Classical RK4 over ``span`` seconds in equal sub-steps no longer than ``h_max``."""
    if span <= 0.0:
        return
    n = max(1, math.ceil(span / h_max - 1e-9))
    h = span / n
    m = x.shape[0]
    k1 = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    xt = np.empty(m)
    work = np.empty(6)
    for _ in range(n):
        derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, work, k1)
        for j in range(m):
            xt[j] = x[j] + 0.5 * h * k1[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, work, k2)
        for j in range(m):
            xt[j] = x[j] + 0.5 * h * k2[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, work, k3)
        for j in range(m):
            xt[j] = x[j] + h * k3[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, rad, work, k4)
        for j in range(m):
            x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def propagate(x, dt, y, tau, G, Minv, D, rad, h_max, max_hold):
    """Advance x by dt with y (NaN = missing DOF) and τ held; the last ``max_hold`` s inject at most."""
    mask = np.empty(3)
    ys = np.empty(3)
    ts = np.empty(3)
    complete = pk.held_sample(y, tau, mask, ys, ts)
    use_meas_psi = mask[2] > 0.0
    psi_meas = ys[2]
    dead = dt - max_hold if dt > max_hold else 0.0
    if dead > 0.0:
        none = np.zeros(3)
        _integrate(x, dead, ys, none, ts, 0.0, False, G, Minv, D, rad, h_max)
    _integrate(x, dt - dead, ys, mask, ts, psi_meas, use_meas_psi, G, Minv, D, rad, h_max)
    x[I_PSI] = ssa_jit(x[I_PSI])
    return STATUS_OK if complete else STATUS_DEAD_RECKONING


@njit(cache=True)
def initialize(x, y, tau, G, D_lf, rad):
    """Equilibrium for the first y and τ: the passive observer's (with D_lf = D_m + K(0), the damping a
    constant ν̂ meets), and the radiation states at rest for that ν̂, ξ̂_r = -A_r⁻¹ B_r ν̂ (so μ̂ = K(0) ν̂)."""
    pk.initialize(x, y, tau, G, D_lf)
    S = rad[7]
    for j in range(S.shape[0]):
        x[N_STATE + j] = S[j, 0] * x[I_NU] + S[j, 1] * x[I_NU + 1] + S[j, 2] * x[I_NU + 2]


@njit(cache=True)
def step(x, clock, t, y, tau, G, Minv, D, D_lf, rad, h_max, max_hold):
    """One sample. ``clock`` = [t of the last sample, initialised]. Returns the status code of this sample."""
    if clock[CLOCK_STARTED] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, y, tau, G, D_lf, rad)
        clock[CLOCK_T] = t
        clock[CLOCK_STARTED] = 1.0
        return STATUS_OK
    dt = t - clock[CLOCK_T]
    if dt <= 0.0:
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[CLOCK_T] = t
    return propagate(x, dt, y, tau, G, Minv, D, rad, h_max, max_hold)


@njit(cache=True)
def run(x, clock, t, Y, TAU, G, Minv, D, D_lf, rad, h_max, max_hold, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    m = x.shape[0]
    for k in range(n):
        code = step(x, clock, t[k], Y[k], TAU[k], G, Minv, D, D_lf, rad, h_max, max_hold)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(m):
                X_out[k, j] = np.nan
        else:
            for j in range(m):
                X_out[k, j] = x[j]
