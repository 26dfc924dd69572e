"""Compiled kernel of the passive observer, Fossen & Strand (1999) eqs (22)–(26).

This is the fast twin of the readable reference in `observers.passive` (`reference_derivative`,
`reference_propagate`); ``tests/test_passive_observer.py`` checks that the two agree to round-off.
It exists because the batch replay of days of 10 Hz data has to run at millions of samples a second
(``bench/bench_passive.py``). Keep the equations here line for line with the reference.

Packed gains ``G`` (8×3), one column per DOF, rows::

    0 ω0   1 ζ   2 k1   3 k2   4 k3   5 λ (diag K3 = Λ)   6 κ (diag K4 = 𝒦)   7 1/T

State ``x`` (15): ξ1 (0:3), ξ2 = η_w (3:6), η (6:9), b (9:12), ν (12:15).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.kinematics import ssa_jit

STATUS_INITIALIZING = 0
STATUS_OK = 1
STATUS_DEAD_RECKONING = 2


@njit(cache=True)
def derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, out):
    """x' of (22)–(25) with y, τ held. mask[i] = 0 removes DOF i's injection (no measurement)."""
    yt0 = (y[0] - (x[6] + x[3])) * mask[0]
    yt1 = (y[1] - (x[7] + x[4])) * mask[1]
    yt2 = ssa_jit(y[2] - (x[8] + x[5])) * mask[2]
    psi = psi_meas if use_meas_psi else x[8] + x[5]
    c = math.cos(psi)
    s = math.sin(psi)
    yt = (yt0, yt1, yt2)
    for i in range(3):
        w0 = G[0, i]
        # (22): ξ̂' = Ω ξ̂ + K1 ỹ, Ω of (11)
        out[i] = x[3 + i] + G[2, i] * yt[i]
        out[3 + i] = -w0 * w0 * x[i] - 2.0 * G[1, i] * w0 * x[3 + i] + G[3, i] * yt[i]
        # (24): b̂' = -T⁻¹ b̂ + Λ ỹ
        out[9 + i] = -G[7, i] * x[9 + i] + G[5, i] * yt[i]
    # (23): η̂' = J(y) ν̂ + K2 ỹ
    u, v, r = x[12], x[13], x[14]
    out[6] = c * u - s * v + G[4, 0] * yt0
    out[7] = s * u + c * v + G[4, 1] * yt1
    out[8] = r + G[4, 2] * yt2
    # (25): M ν̂' = -D ν̂ + Jᵀ(y) (b̂ + 𝒦 ỹ) + τ
    q0 = x[9] + G[6, 0] * yt0
    q1 = x[10] + G[6, 1] * yt1
    q2 = x[11] + G[6, 2] * yt2
    f0 = c * q0 + s * q1 + tau[0] - (D[0, 0] * u + D[0, 1] * v + D[0, 2] * r)
    f1 = -s * q0 + c * q1 + tau[1] - (D[1, 0] * u + D[1, 1] * v + D[1, 2] * r)
    f2 = q2 + tau[2] - (D[2, 0] * u + D[2, 1] * v + D[2, 2] * r)
    for i in range(3):
        out[12 + i] = Minv[i, 0] * f0 + Minv[i, 1] * f1 + Minv[i, 2] * f2


@njit(cache=True)
def _integrate(x, span, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, h_max):
    """Classical RK4 over ``span`` seconds in equal sub-steps no longer than ``h_max``."""
    if span <= 0.0:
        return
    n = max(1, math.ceil(span / h_max - 1e-9))
    h = span / n
    k1 = np.empty(15)
    k2 = np.empty(15)
    k3 = np.empty(15)
    k4 = np.empty(15)
    xt = np.empty(15)
    for _ in range(n):
        derivative(x, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k1)
        for j in range(15):
            xt[j] = x[j] + 0.5 * h * k1[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k2)
        for j in range(15):
            xt[j] = x[j] + 0.5 * h * k2[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k3)
        for j in range(15):
            xt[j] = x[j] + h * k3[j]
        derivative(xt, y, mask, tau, psi_meas, use_meas_psi, G, Minv, D, k4)
        for j in range(15):
            x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


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
    complete = True
    for i in range(3):
        ok = not math.isnan(y[i])
        mask[i] = 1.0 if ok else 0.0
        ys[i] = y[i] if ok else 0.0
        ts[i] = 0.0 if math.isnan(tau[i]) else tau[i]
        complete = complete and ok
    use_meas_psi = mask[2] > 0.0
    psi_meas = ys[2]
    dead = dt - max_hold if dt > max_hold else 0.0
    if dead > 0.0:
        none = np.zeros(3)
        _integrate(x, dead, ys, none, ts, 0.0, False, G, Minv, D, h_max)
    _integrate(x, dt - dead, ys, mask, ts, psi_meas, use_meas_psi, G, Minv, D, h_max)
    x[8] = ssa_jit(x[8])
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
        A[i, i] = -G[5, i]
        A[i, 3 + i] = G[7, i]
        rhs[3 + i] = -(0.0 if math.isnan(tau[i]) else tau[i])
        for j in range(3):
            # (D Jᵀ K2 + Jᵀ 𝒦)[i, j] and Jᵀ[i, j]
            dj = 0.0
            for m in range(3):
                dj += D[i, m] * Jt[m, j]
            A[3 + i, j] = dj * G[4, j] + Jt[i, j] * G[6, j]
            A[3 + i, 3 + j] = Jt[i, j]
    sol = np.linalg.solve(A, rhs)
    for j in range(15):
        x[j] = 0.0
    for i in range(3):
        yt = sol[i]
        w0 = G[0, i]
        x[3 + i] = -G[2, i] * yt
        x[i] = (2.0 * G[1, i] * w0 * G[2, i] + G[3, i]) * yt / (w0 * w0)
        x[6 + i] = y[i] - yt - x[3 + i]
        x[9 + i] = sol[3 + i]
        # ν̂ = -Jᵀ K2 ỹ
        x[12 + i] = -(Jt[i, 0] * G[4, 0] * sol[0] + Jt[i, 1] * G[4, 1] * sol[1] + Jt[i, 2] * G[4, 2] * sol[2])
    x[8] = ssa_jit(x[8])


@njit(cache=True)
def step(x, clock, t, y, tau, G, Minv, D, h_max, max_hold):
    """One sample. ``clock`` = [t_prev, initialized]. Returns the status code of this sample."""
    if clock[1] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, y, tau, G, D)
        clock[0] = t
        clock[1] = 1.0
        return STATUS_OK
    dt = t - clock[0]
    if dt <= 0.0:
        # repeated or backward time: nothing to integrate; the sample is not used
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[0] = t
    return propagate(x, dt, y, tau, G, Minv, D, h_max, max_hold)


@njit(cache=True)
def run(x, clock, t, Y, TAU, G, Minv, D, h_max, max_hold, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    for k in range(n):
        code = step(x, clock, t[k], Y[k], TAU[k], G, Minv, D, h_max, max_hold)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(15):
                X_out[k, j] = np.nan
        else:
            for j in range(15):
                X_out[k, j] = x[j]
