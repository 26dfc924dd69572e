"""Compiled kernel of the fluid-memory observer, Hajivand & Mousavizadegan (2010) eqs (17)–(21).

The fast twin of the readable reference in `observers.memory` (`reference_derivative`,
`reference_propagate`); ``tests/test_memory_observer.py`` checks that the two agree to round-off. Keep the
equations here line for line with the reference.

State ``x`` (15 + n): the passive observer's layout (`observers.state`: ξ1, ξ2 = η_w, η, b, ν), then the
n radiation states ξ_r. Eqs (17)–(19), (21) are the passive observer's (22)–(24), (26) and are computed
by `observers._passive_kernel.derivative` itself; (20) differs only by the radiation force, so it is that
derivative with τ - μ̂ in place of τ (same M⁻¹, Jᵀ, injection), with M = M_RB + A(∞) and D = D_m.

The radiation matrices are block diagonal (one block per identified element), so they are passed as
their non-zero entries, all in one pair of arrays ``RI`` (k, 2) (row, column, both indices into x) and
``RV`` (k,): the first ``n_dyn`` entries are ξ_r' = A_r ξ_r + B_r ν̂ (rows and columns are x indices), the
next ``n_mu`` are μ̂ = C_r ξ_r + D_r ν̂ (rows 0-2 are μ's), the rest S = -A_r⁻¹ B_r, the radiation states
at rest for a constant ν̂ (to start in equilibrium). Two arrays, not eight: every array passed to a
compiled function costs a reference count in and out on each call, and these calls run four times a
sub-step (a small cost beside the call layers, see `_passive_derivative`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers import _passive_kernel as pk
from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit
from observers.state import I_PSI, N_STATE

CLOCK_T = 0
CLOCK_STARTED = 1

# The passive observer's derivative, the same Python function, inlined here at numba's IR level: called
# as a separate compiled function from this module it ran at half the speed (measured, bench_memory.py).
_passive_derivative = njit(cache=True, inline="always")(pk.derivative.py_func)


@njit(cache=True, inline="always")
def derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, out):
    """x' of (17)–(21) with y, τ held."""
    # (7): μ̂ = C_r ξ̂_r + D_r ν̂
    mu0 = 0.0
    mu1 = 0.0
    mu2 = 0.0
    for k in range(n_dyn, n_dyn + n_mu):
        v = RV[k] * x[RI[k, 1]]
        row = RI[k, 0]
        if row == 0:
            mu0 += v
        elif row == 1:
            mu1 += v
        else:
            mu2 += v
    # (20): [M_RB + A(∞)] ν̂' = -D ν̂ + Jᵀ b̂ + τ - μ̂ + Jᵀ K4 ỹ. The sign of μ̂ is that of (8),
    # [M + A] ν' + μ = f_ext (the radiation force opposes the motion); the printed (20) has +μ, which
    # would feed energy into the velocity estimate.
    tau_eff = (tau[0] - mu0, tau[1] - mu1, tau[2] - mu2)
    _passive_derivative(x, y, mask, tau_eff, psi_meas, use_meas_psi, G, Minv, D, out)
    # (7): ξ̂_r' = A_r ξ̂_r + B_r ν̂, driven by the velocity estimate
    for j in range(N_STATE, x.shape[0]):
        out[j] = 0.0
    for k in range(n_dyn):
        out[RI[k, 0]] += RV[k] * x[RI[k, 1]]


@njit(cache=True)
def _integrate(x, span, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, h_max):
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
    for _ in range(n):
        derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, k1)
        for j in range(m):
            xt[j] = x[j] + 0.5 * h * k1[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, k2)
        for j in range(m):
            xt[j] = x[j] + 0.5 * h * k2[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, k3)
        for j in range(m):
            xt[j] = x[j] + h * k3[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, k4)
        for j in range(m):
            x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def propagate(x, dt, y, tau, G, Minv, D, RI, RV, n_dyn, n_mu, h_max, max_hold):
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
        _integrate(x, dead, ys, none, ts, 0.0, False, G, Minv, D, RI, RV, n_dyn, n_mu, h_max)
    _integrate(x, dt - dead, ys, mask, ts, psi_meas, use_meas_psi, G, Minv, D, RI, RV, n_dyn, n_mu, h_max)
    x[I_PSI] = ssa_jit(x[I_PSI])
    return STATUS_OK if complete else STATUS_DEAD_RECKONING


@njit(cache=True)
def initialize(x, y, tau, G, D_lf, RI, RV, n_dyn, n_mu):
    """Equilibrium for the first y and τ: the passive observer's (with D_lf = D_m + K(0), the damping a
    constant ν̂ meets), and the radiation states at rest for that ν̂, ξ̂_r = -A_r⁻¹ B_r ν̂ (so μ̂ = K(0) ν̂)."""
    pk.initialize(x, y, tau, G, D_lf)
    for j in range(N_STATE, x.shape[0]):
        x[j] = 0.0
    for k in range(n_dyn + n_mu, RV.shape[0]):
        x[RI[k, 0]] += RV[k] * x[RI[k, 1]]


@njit(cache=True)
def step(x, clock, t, y, tau, G, Minv, D, D_lf, RI, RV, n_dyn, n_mu, h_max, max_hold):
    """One sample. ``clock`` = [t of the last sample, initialised]. Returns the status code of this sample."""
    if clock[CLOCK_STARTED] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, y, tau, G, D_lf, RI, RV, n_dyn, n_mu)
        clock[CLOCK_T] = t
        clock[CLOCK_STARTED] = 1.0
        return STATUS_OK
    dt = t - clock[CLOCK_T]
    if dt <= 0.0:
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[CLOCK_T] = t
    return propagate(x, dt, y, tau, G, Minv, D, RI, RV, n_dyn, n_mu, h_max, max_hold)


@njit(cache=True)
def run(x, clock, t, Y, TAU, G, Minv, D, D_lf, RI, RV, n_dyn, n_mu, h_max, max_hold, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    m = x.shape[0]
    for k in range(n):
        code = step(x, clock, t[k], Y[k], TAU[k], G, Minv, D, D_lf, RI, RV, n_dyn, n_mu, h_max, max_hold)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(m):
                X_out[k, j] = np.nan
        else:
            for j in range(m):
                X_out[k, j] = x[j]
