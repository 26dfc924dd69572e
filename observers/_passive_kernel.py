"""Compiled kernel of the passive observer, Fossen & Strand (1999) eqs (22)–(26).

This is the fast twin of the readable reference in `observers.passive` (`reference_derivative`,
`reference_propagate`); ``tests/test_passive_observer.py`` checks that the two agree to round-off.
It exists because the batch replay of days of 10 Hz data has to run at millions of samples a second
(``bench/bench_passive.py``). Keep the equations here line for line with the reference.

State ``x`` (15): the layout of `observers.state` (ξ1, ξ2 = η_w, η, b, ν), indexed by its block starts.

Packed gains ``G`` (8×3), one column per DOF, one row per quantity (the ``G_*`` row names below;
`observers.passive.pack_gains` fills them)::

    ω0   ζ   k1   k2   k3   λ (diag K3 = Λ)   κ (diag K4 = 𝒦)   1/T

``clock`` (2): [t of the last sample, initialised flag] (``CLOCK_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit
from observers.state import I_BIAS, I_ETA, I_NU, I_PSI, I_XI1, I_XI2, N_STATE

# rows of the packed gains G
G_OMEGA0 = 0  # ω0, wave model (11)
G_ZETA = 1  # ζ, wave model (11)
G_K1 = 2  # k1 of (45): ξ1 injection (top rows of K1)
G_K2 = 3  # k2 of (46): ξ2 injection (bottom rows of K1)
G_K3 = 4  # k3 of (47): η injection (diag K2)
G_LAMBDA = 5  # λ: bias injection (diag K3 = Λ)
G_KAPPA = 6  # κ: velocity injection (diag K4 = 𝒦)
G_T_INV = 7  # 1/T: bias time constant (0 for a random walk)
N_GAIN_ROWS = 8

# the clock
CLOCK_T = 0  # time of the last sample used
CLOCK_STARTED = 1  # 1.0 once initialised


@njit(cache=True)
def derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, out):
    """x' of (22)–(25) with y, τ held. mask[i] = 0 removes DOF i's injection (no measurement)."""
    # (26): ŷ = η̂ + η̂_w, ỹ = y − ŷ (heading wrapped)
    yt0 = (y[0] - (x[I_ETA] + x[I_XI2])) * mask[0]
    yt1 = (y[1] - (x[I_ETA + 1] + x[I_XI2 + 1])) * mask[1]
    yt2 = ssa_jit(y[2] - (x[I_PSI] + x[I_XI2 + 2])) * mask[2]
    psi = psi_meas if use_meas_psi else x[I_PSI] + x[I_XI2 + 2]
    c = math.cos(psi)
    s = math.sin(psi)
    yt = (yt0, yt1, yt2)
    for i in range(3):
        w0 = G[G_OMEGA0, i]
        # (22): ξ̂' = Ω ξ̂ + K1 ỹ, Ω of (11)
        out[I_XI1 + i] = x[I_XI2 + i] + G[G_K1, i] * yt[i]
        out[I_XI2 + i] = -w0 * w0 * x[I_XI1 + i] - 2.0 * G[G_ZETA, i] * w0 * x[I_XI2 + i] + G[G_K2, i] * yt[i]
        # (24): b̂' = -T⁻¹ b̂ + Λ ỹ
        out[I_BIAS + i] = -G[G_T_INV, i] * x[I_BIAS + i] + G[G_LAMBDA, i] * yt[i]
    # (23): η̂' = J(y) ν̂ + K2 ỹ
    u, v, r = x[I_NU], x[I_NU + 1], x[I_NU + 2]
    out[I_ETA] = c * u - s * v + G[G_K3, 0] * yt0
    out[I_ETA + 1] = s * u + c * v + G[G_K3, 1] * yt1
    out[I_ETA + 2] = r + G[G_K3, 2] * yt2
    # (25): M ν̂' = -D ν̂ + Jᵀ(y) (b̂ + 𝒦 ỹ) + τ
    q0 = x[I_BIAS] + G[G_KAPPA, 0] * yt0
    q1 = x[I_BIAS + 1] + G[G_KAPPA, 1] * yt1
    q2 = x[I_BIAS + 2] + G[G_KAPPA, 2] * yt2
    f0 = c * q0 + s * q1 + tau[0] - (D[0, 0] * u + D[0, 1] * v + D[0, 2] * r)
    f1 = -s * q0 + c * q1 + tau[1] - (D[1, 0] * u + D[1, 1] * v + D[1, 2] * r)
    f2 = q2 + tau[2] - (D[2, 0] * u + D[2, 1] * v + D[2, 2] * r)
    for i in range(3):
        out[I_NU + i] = Minv[i, 0] * f0 + Minv[i, 1] * f1 + Minv[i, 2] * f2


@njit(cache=True)
def _integrate(x, span, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, h_max):
    """Classical RK4 over ``span`` seconds in equal sub-steps no longer than ``h_max``."""
    if span <= 0.0:
        return
    n = max(1, math.ceil(span / h_max - 1e-9))
    h = span / n
    k1 = np.empty(N_STATE)
    k2 = np.empty(N_STATE)
    k3 = np.empty(N_STATE)
    k4 = np.empty(N_STATE)
    xt = np.empty(N_STATE)
    for _ in range(n):
        derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k1)
        for j in range(N_STATE):
            xt[j] = x[j] + 0.5 * h * k1[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k2)
        for j in range(N_STATE):
            xt[j] = x[j] + 0.5 * h * k2[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k3)
        for j in range(N_STATE):
            xt[j] = x[j] + h * k3[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k4)
        for j in range(N_STATE):
            x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def held_sample(y, tau, mask, ys, ts):
    """Unpack one sample for the integration (shared with the SDRE kernel): mask[i] 1 where y[i] was
    measured, ys = y with missing DOFs 0, ts = τ with NaN as 0. Returns whether every DOF was measured."""
    complete = True
    for i in range(3):
        ok = not math.isnan(y[i])
        mask[i] = 1.0 if ok else 0.0
        ys[i] = y[i] if ok else 0.0
        ts[i] = 0.0 if math.isnan(tau[i]) else tau[i]
        complete = complete and ok
    return complete


@njit(cache=True)
def propagate(x, dt, y, tau, G, Minv, D, h_max, max_hold):
    """Advance x by dt with measurement y (NaN = missing DOF) and τ held; returns the step's status.

    The measurement acts over the last ``max_hold`` seconds of the interval at most; any older part of a
    long gap is dead reckoning (no injection), so a late measurement is not treated as if it had been
    seen all along.
    """
    mask = np.empty(3)
    ys = np.empty(3)
    ts = np.empty(3)
    complete = held_sample(y, tau, mask, ys, ts)
    use_meas_psi = mask[2] > 0.0
    psi_meas = ys[2]
    dead = dt - max_hold if dt > max_hold else 0.0
    if dead > 0.0:
        none = np.zeros(3)
        _integrate(x, dead, ys, none, ts, 0.0, False, G, Minv, D, h_max)
    _integrate(x, dt - dead, ys, mask, ts, psi_meas, use_meas_psi, G, Minv, D, h_max)
    x[I_PSI] = ssa_jit(x[I_PSI])
    return STATUS_OK if complete else STATUS_DEAD_RECKONING


@njit(cache=True)
def initialize(x, y, tau, G, D):
    """Start at the observer's equilibrium for the first measurement y and force τ (no transient).

    With y and τ constant, every derivative of (22)–(25) is zero when ν̂ = -Jᵀ K2 ỹ (23) and (24)–(25)::

        T⁻¹ b̂ = Λ ỹ,        D Jᵀ K2 ỹ + Jᵀ b̂ + Jᵀ 𝒦 ỹ = -τ

    (a 6×6 linear system in ỹ, b̂; with T = ∞ it gives ỹ = 0, b̂ = -J τ). The leaky bias model leaves a
    small steady innovation ỹ; ξ̂ follows from (22): ξ̂2 = -k1 ỹ, ξ̂1 = (2ζω0 k1 + k2) ỹ / ω0².
    """
    c = math.cos(y[2])
    s = math.sin(y[2])
    Jt = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    A = np.zeros((6, 6))
    rhs = np.zeros(6)
    for i in range(3):
        A[i, i] = -G[G_LAMBDA, i]
        A[i, 3 + i] = G[G_T_INV, i]
        rhs[3 + i] = -(0.0 if math.isnan(tau[i]) else tau[i])
        for j in range(3):
            # (D Jᵀ K2 + Jᵀ 𝒦)[i, j] and Jᵀ[i, j]
            dj = 0.0
            for m in range(3):
                dj += D[i, m] * Jt[m, j]
            A[3 + i, j] = dj * G[G_K3, j] + Jt[i, j] * G[G_KAPPA, j]
            A[3 + i, 3 + j] = Jt[i, j]
    sol = np.linalg.solve(A, rhs)  # [ỹ, b̂]
    for j in range(N_STATE):
        x[j] = 0.0
    for i in range(3):
        yt = sol[i]
        w0 = G[G_OMEGA0, i]
        x[I_XI2 + i] = -G[G_K1, i] * yt
        x[I_XI1 + i] = (2.0 * G[G_ZETA, i] * w0 * G[G_K1, i] + G[G_K2, i]) * yt / (w0 * w0)
        x[I_ETA + i] = y[i] - yt - x[I_XI2 + i]
        x[I_BIAS + i] = sol[3 + i]
        # ν̂ = -Jᵀ K2 ỹ
        x[I_NU + i] = -(
            Jt[i, 0] * G[G_K3, 0] * sol[0] + Jt[i, 1] * G[G_K3, 1] * sol[1] + Jt[i, 2] * G[G_K3, 2] * sol[2]
        )
    x[I_PSI] = ssa_jit(x[I_PSI])


@njit(cache=True)
def step(x, clock, t, y, tau, G, Minv, D, h_max, max_hold):
    """One sample. ``clock`` = [t of the last sample, initialised]. Returns the status code of this sample."""
    if clock[CLOCK_STARTED] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, y, tau, G, D)
        clock[CLOCK_T] = t
        clock[CLOCK_STARTED] = 1.0
        return STATUS_OK
    dt = t - clock[CLOCK_T]
    if dt <= 0.0:
        # repeated or backward time: nothing to integrate; the sample is not used
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[CLOCK_T] = t
    return propagate(x, dt, y, tau, G, Minv, D, h_max, max_hold)


@njit(cache=True)
def run(x, clock, t, Y, TAU, G, Minv, D, h_max, max_hold, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    for k in range(n):
        code = step(x, clock, t[k], Y[k], TAU[k], G, Minv, D, h_max, max_hold)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(N_STATE):
                X_out[k, j] = np.nan
        else:
            for j in range(N_STATE):
                X_out[k, j] = x[j]
