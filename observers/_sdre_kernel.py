"""Compiled kernel of the SDRE observer, Snijders, van der Woude & Westhuis (2005) Sec. 3.2.

The fast twin of the readable reference in `observers.sdre` (`reference_derivative`,
`reference_propagate`); tests/test_sdre.py checks that they agree to round-off. Keep the equations here
line for line with the reference. It exists for the same reason as the passive observer's kernel: batch
replay of long logs, and a live step of a few microseconds (bench/bench_sdre.py).

    x̂' = A(ψ̂) x̂ + B τ + K(ψ̂) ỹ,    ỹ = y − C x̂ (ỹ₃ wrapped),    K(ψ) = S(ψ) K̄(ψ) Jᵀ(ψ)

State ``x`` (15): η (0:3), ν (3:6), b (6:9), ξ1 (9:12), ξ2 = η_w (12:15). ``W`` (2×3): rows ω0, ζ.
``table`` (n, 15, 3): the de-rotated gain K̄ at ψₖ = kπ/n (n = 1: the same for every heading).
The integration scheme is the passive observer's: y and τ held over the interval that ends at the
sample, classical RK4 in sub-steps no longer than ``h_max``, a gap longer than ``max_hold`` dead
reckoning except for its last ``max_hold`` seconds, a missing DOF without injection.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers._passive_kernel import held_sample
from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit

__all__ = ["STATUS_DEAD_RECKONING", "STATUS_INITIALIZING", "STATUS_OK", "run", "step"]


@njit(cache=True)
def derivative(x, y, mask, tau, W, table, Minv, MinvD, out):
    """x̂' with y, τ held; mask[i] = 0 removes DOF i's innovation (no measurement)."""
    psi = x[2]
    c = math.cos(psi)
    s = math.sin(psi)
    yt0 = (y[0] - (x[0] + x[12])) * mask[0]
    yt1 = (y[1] - (x[1] + x[13])) * mask[1]
    yt2 = ssa_jit(y[2] - (x[2] + x[14])) * mask[2]
    # Jᵀ(ψ) ỹ: the innovation in the frame in which K̄ was solved
    z0 = c * yt0 + s * yt1
    z1 = -s * yt0 + c * yt1
    z2 = yt2
    n = table.shape[0]
    g = np.empty(15)
    if n == 1:
        for j in range(15):
            g[j] = table[0, j, 0] * z0 + table[0, j, 1] * z1 + table[0, j, 2] * z2
    else:
        u = (psi % math.pi) / math.pi * n
        i0 = min(int(u), n - 1)
        f = u - i0
        i1 = (i0 + 1) % n
        for j in range(15):
            k0 = (1.0 - f) * table[i0, j, 0] + f * table[i1, j, 0]
            k1 = (1.0 - f) * table[i0, j, 1] + f * table[i1, j, 1]
            k2 = (1.0 - f) * table[i0, j, 2] + f * table[i1, j, 2]
            g[j] = k0 * z0 + k1 * z1 + k2 * z2
    # S(ψ) g: η, b, ξ1, ξ2 turn with the heading, ν does not
    for b0 in (0, 6, 9, 12):
        a0 = g[b0]
        a1 = g[b0 + 1]
        g[b0] = c * a0 - s * a1
        g[b0 + 1] = s * a0 + c * a1
    u_, v_, r_ = x[3], x[4], x[5]
    # η' = J(ψ̂) ν̂
    out[0] = c * u_ - s * v_ + g[0]
    out[1] = s * u_ + c * v_ + g[1]
    out[2] = r_ + g[2]
    # ν' = −M⁻¹D ν̂ + M⁻¹ (Jᵀ(ψ̂) b̂ + τ)
    f0 = c * x[6] + s * x[7] + tau[0]
    f1 = -s * x[6] + c * x[7] + tau[1]
    f2 = x[8] + tau[2]
    for i in range(3):
        out[3 + i] = (
            Minv[i, 0] * f0
            + Minv[i, 1] * f1
            + Minv[i, 2] * f2
            - (MinvD[i, 0] * u_ + MinvD[i, 1] * v_ + MinvD[i, 2] * r_)
            + g[3 + i]
        )
    for i in range(3):
        w0 = W[0, i]
        # b' = 0 (random walk, T = 0)
        out[6 + i] = g[6 + i]
        # ξ' = Ω2 ξ
        out[9 + i] = x[12 + i] + g[9 + i]
        out[12 + i] = -w0 * w0 * x[9 + i] - 2.0 * W[1, i] * w0 * x[12 + i] + g[12 + i]


@njit(cache=True)
def _integrate(x, span, y, mask, tau, W, table, Minv, MinvD, h_max):
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
        derivative(x, y, mask, tau, W, table, Minv, MinvD, k1)
        for j in range(15):
            xt[j] = x[j] + 0.5 * h * k1[j]
        derivative(xt, y, mask, tau, W, table, Minv, MinvD, k2)
        for j in range(15):
            xt[j] = x[j] + 0.5 * h * k2[j]
        derivative(xt, y, mask, tau, W, table, Minv, MinvD, k3)
        for j in range(15):
            xt[j] = x[j] + h * k3[j]
        derivative(xt, y, mask, tau, W, table, Minv, MinvD, k4)
        for j in range(15):
            x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def propagate(x, dt, y, tau, W, table, Minv, MinvD, h_max, max_hold):
    """Advance x by dt with measurement y (NaN = missing DOF) and τ held; returns the step's status."""
    mask = np.empty(3)
    ys = np.empty(3)
    ts = np.empty(3)
    complete = held_sample(y, tau, mask, ys, ts)
    dead = dt - max_hold if dt > max_hold else 0.0
    if dead > 0.0:
        none = np.zeros(3)
        _integrate(x, dead, ys, none, ts, W, table, Minv, MinvD, h_max)
    _integrate(x, dt - dead, ys, mask, ts, W, table, Minv, MinvD, h_max)
    x[2] = ssa_jit(x[2])
    return STATUS_OK if complete else STATUS_DEAD_RECKONING


@njit(cache=True)
def initialize(x, y, tau):
    """Start at the observer's equilibrium for the first y and τ: ỹ = 0, ν̂ = 0, ξ̂ = 0, b̂ = −J(y₃) τ.

    With a random-walk bias, x̂' = 0 needs ỹ = 0 (b̂' = K_b ỹ); then ξ̂ = 0 (Ω2 is invertible), ν̂ = 0
    (η̂' = J ν̂) and Jᵀ b̂ + τ = 0.
    """
    c = math.cos(y[2])
    s = math.sin(y[2])
    t0 = 0.0 if math.isnan(tau[0]) else tau[0]
    t1 = 0.0 if math.isnan(tau[1]) else tau[1]
    t2 = 0.0 if math.isnan(tau[2]) else tau[2]
    for j in range(15):
        x[j] = 0.0
    x[0] = y[0]
    x[1] = y[1]
    x[2] = ssa_jit(y[2])
    x[6] = -(c * t0 - s * t1)
    x[7] = -(s * t0 + c * t1)
    x[8] = -t2


@njit(cache=True)
def step(x, clock, t, y, tau, W, table, Minv, MinvD, h_max, max_hold):
    """One sample. ``clock`` = [t_prev, initialized]. Returns the status code of this sample."""
    if clock[1] == 0.0:
        if math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]):
            return STATUS_INITIALIZING
        initialize(x, y, tau)
        clock[0] = t
        clock[1] = 1.0
        return STATUS_OK
    dt = t - clock[0]
    if dt <= 0.0:
        # repeated or backward time: nothing to integrate; the sample is not used
        complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[0] = t
    return propagate(x, dt, y, tau, W, table, Minv, MinvD, h_max, max_hold)


@njit(cache=True)
def run(x, clock, t, Y, TAU, W, table, Minv, MinvD, h_max, max_hold, X_out, status_out):
    """`step` over arrays; X_out[k] is the state after sample k (NaN while initialising)."""
    n = t.shape[0]
    for k in range(n):
        code = step(x, clock, t[k], Y[k], TAU[k], W, table, Minv, MinvD, h_max, max_hold)
        status_out[k] = code
        if code == STATUS_INITIALIZING:
            for j in range(15):
                X_out[k, j] = np.nan
        else:
            for j in range(15):
                X_out[k, j] = x[j]
