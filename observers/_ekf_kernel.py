"""Compiled kernel of the DP extended Kalman filter (`observers.ekf`).

The fast twin of the readable reference in `observers.ekf` (`reference_predict`, `reference_update`);
tests/test_ekf.py checks that they agree to round-off. Keep the equations here line for line with it.

State ``x`` (15): η (0:3), ν (3:6), b (6:9), ξ1 (9:12), ξ2 = η_w (12:15); ``P`` (15×15) its covariance.
``W`` (2×3): rows ω0, ζ. ``Q`` (15×15): process noise intensity; ``r`` (3): measurement noise variances.

    predict:  x̂ ← RK4 of f(x̂, τ) over sub-steps h ≤ h_max;  P ← Φ P Φᵀ + Q h + ½(F Q + Q Fᵀ) h²,
              Φ = I + F h + (F h)²/2,  F = ∂f/∂x at the sub-step's start
    update:   one scalar update per measured DOF i (R is diagonal, so this equals the joint update):
              ỹᵢ = yᵢ − η̂ᵢ − η̂_w,i (ỹ₃ wrapped),  s = Hᵢ P Hᵢᵀ + rᵢ,  K = P Hᵢᵀ / s,
              x̂ ← x̂ + K ỹᵢ,  P ← P − K (P Hᵢᵀ)ᵀ,  Hᵢ = eᵢ + e₁₂₊ᵢ
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers._sdre_kernel import initialize as sdre_initialize
from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit

__all__ = ["STATUS_DEAD_RECKONING", "STATUS_INITIALIZING", "STATUS_OK", "run", "step"]


@njit(cache=True)
def derivative(x, tau, W, Minv, MinvD, out):
    """f(x, τ): η' = J(ψ)ν, ν' = −M⁻¹Dν + M⁻¹Jᵀ(ψ)b + M⁻¹τ, b' = 0, ξ1' = ξ2, ξ2' = −ω0²ξ1 − 2ζω0ξ2."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    u, v, r = x[3], x[4], x[5]
    out[0] = c * u - s * v
    out[1] = s * u + c * v
    out[2] = r
    f0 = c * x[6] + s * x[7] + tau[0]
    f1 = -s * x[6] + c * x[7] + tau[1]
    f2 = x[8] + tau[2]
    for i in range(3):
        out[3 + i] = (
            Minv[i, 0] * f0 + Minv[i, 1] * f1 + Minv[i, 2] * f2
            - (MinvD[i, 0] * u + MinvD[i, 1] * v + MinvD[i, 2] * r)
        )  # fmt: skip
        out[6 + i] = 0.0
        w = W[0, i]
        out[9 + i] = x[12 + i]
        out[12 + i] = -w * w * x[9 + i] - 2.0 * W[1, i] * w * x[12 + i]


@njit(cache=True)
def jacobian(x, W, Minv, MinvD, F):
    """F = ∂f/∂x at x: the model matrix A(ψ) plus the heading's column (∂(Jν)/∂ψ, ∂(M⁻¹Jᵀb)/∂ψ)."""
    for i in range(15):
        for j in range(15):
            F[i, j] = 0.0
    c = math.cos(x[2])
    s = math.sin(x[2])
    F[0, 3] = c
    F[0, 4] = -s
    F[1, 3] = s
    F[1, 4] = c
    F[2, 5] = 1.0
    F[0, 2] = -s * x[3] - c * x[4]
    F[1, 2] = c * x[3] - s * x[4]
    d0 = -s * x[6] + c * x[7]  # ∂(Jᵀb)/∂ψ
    d1 = -c * x[6] - s * x[7]
    for i in range(3):
        for j in range(3):
            F[3 + i, 3 + j] = -MinvD[i, j]
        # M⁻¹ Jᵀ: columns b0, b1, b2 (Jᵀ = [[c, s, 0], [−s, c, 0], [0, 0, 1]])
        F[3 + i, 6] = Minv[i, 0] * c - Minv[i, 1] * s
        F[3 + i, 7] = Minv[i, 0] * s + Minv[i, 1] * c
        F[3 + i, 8] = Minv[i, 2]
        F[3 + i, 2] = Minv[i, 0] * d0 + Minv[i, 1] * d1
        w = W[0, i]
        F[9 + i, 12 + i] = 1.0
        F[12 + i, 9 + i] = -w * w
        F[12 + i, 12 + i] = -2.0 * W[1, i] * w


@njit(cache=True)
def _rk4(x, h, tau, W, Minv, MinvD):
    k = np.empty((4, 15))
    xt = np.empty(15)
    for stage in range(4):
        if stage == 0:
            for j in range(15):
                xt[j] = x[j]
        else:
            w = h if stage == 3 else 0.5 * h
            for j in range(15):
                xt[j] = x[j] + w * k[stage - 1, j]
        derivative(xt, tau, W, Minv, MinvD, k[stage])
    for j in range(15):
        x[j] += h / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])


@njit(cache=True)
def predict(x, P, dt, tau, W, Q, Minv, MinvD, h_max):
    """Advance x̂ and P by dt with τ held (no measurement)."""
    n = max(1, math.ceil(dt / h_max - 1e-9))
    h = dt / n
    F = np.empty((15, 15))
    Phi = np.empty((15, 15))
    T = np.empty((15, 15))
    for _ in range(n):
        jacobian(x, W, Minv, MinvD, F)
        # Φ = I + F h + (F h)²/2
        FF = F @ F
        for i in range(15):
            for j in range(15):
                Phi[i, j] = F[i, j] * h + 0.5 * FF[i, j] * h * h
            Phi[i, i] += 1.0
        _rk4(x, h, tau, W, Minv, MinvD)
        T[:, :] = Phi @ P @ Phi.T
        FQ = F @ Q
        for i in range(15):
            for j in range(15):
                P[i, j] = T[i, j] + Q[i, j] * h + 0.5 * (FQ[i, j] + FQ[j, i]) * h * h
    x[2] = ssa_jit(x[2])


@njit(cache=True)
def update(x, P, y, r):
    """Scalar updates with each measured DOF; returns whether all three were measured."""
    complete = True
    PH = np.empty(15)
    for i in range(3):
        if math.isnan(y[i]):
            complete = False
            continue
        e = y[i] - x[i] - x[12 + i]
        if i == 2:
            e = ssa_jit(e)
        for j in range(15):
            PH[j] = P[j, i] + P[j, 12 + i]
        s = PH[i] + PH[12 + i] + r[i]
        for j in range(15):
            x[j] += PH[j] / s * e
        for j in range(15):
            kj = PH[j] / s
            for m in range(15):
                P[j, m] -= kj * PH[m]
        # keep P symmetric against round-off
        for j in range(15):
            for m in range(j + 1, 15):
                a = 0.5 * (P[j, m] + P[m, j])
                P[j, m] = a
                P[m, j] = a
    x[2] = ssa_jit(x[2])
    return complete


@njit(cache=True)
def initialize(x, P, P0, y, tau):
    """Start at rest for the first y and τ as the SDRE observer does (same 15 states): η̂ = y, ν̂ = 0, ξ̂ = 0,
    b̂ = −J(y₃)τ (Jᵀb̂ + τ = 0); P = P0."""
    sdre_initialize(x, y, tau)
    P[:, :] = P0


@njit(cache=True)
def step(x, P, clock, t, y, tau, W, Q, r, P0, Minv, MinvD, h_max):
    """One sample: predict to t with τ held since the last sample, then update with y. ``clock`` =
    [t_prev, initialized]. Returns the status code of this sample."""
    if clock[1] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, P, P0, y, tau)
        clock[0] = t
        clock[1] = 1.0
        return STATUS_OK
    dt = t - clock[0]
    if dt <= 0.0:
        # repeated or backward time: the sample is not used
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[0] = t
    tau_held = np.empty(3)
    for i in range(3):
        tau_held[i] = 0.0 if math.isnan(tau[i]) else tau[i]
    predict(x, P, dt, tau_held, W, Q, Minv, MinvD, h_max)
    complete = update(x, P, y, r)
    return STATUS_OK if complete else STATUS_DEAD_RECKONING


@njit(cache=True)
def run(x, P, clock, t, Y, TAU, W, Q, r, P0, Minv, MinvD, h_max, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    for k in range(n):
        code = step(x, P, clock, t[k], Y[k], TAU[k], W, Q, r, P0, Minv, MinvD, h_max)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(15):
                X_out[k, j] = np.nan
        else:
            for j in range(15):
                X_out[k, j] = x[j]
