"""Compiled kernel of the MMAE wave filter, Hassani et al. eqs (13)–(18) (see `observers.mmae`).

The fast twin of `observers.mmae.reference_run`; tests/test_mmae.py checks that the two agree to
round-off. It exists because batch replay must run eight 15-state filters at ≥ 100,000 samples a second
(bench/bench_mmae.py). Keep the steps here line for line with the reference.

Arrays (N filters): ``X`` (N, 15) filter states in the vessel-parallel frame, ``p`` (N,) weights,
``xb`` (15,) blended state, ``clock`` = [t_prev, initialised, ψ_f (frame heading), t_init];
bank: ``Phi`` (N, 15, 15), ``Gam`` (15, 3), ``A`` (N, 15, 15), ``B`` (15, 3), ``K`` (N, 4, 15, 3),
``Sinv`` (N, 4, 3, 3), ``logdet`` (N, 4);
``params`` = [dt_nom, weight floor, warm-up s, max gap s, heading in weights (1/0)].

State order: ξ1 (0:3), ξ2 = η_w (3:6), η_p (6:9), b_p (9:12), ν (12:15). A(ω0) is block-diagonal in
(ξ) and (η_p, b_p, ν), so the prediction multiplies the 6×6 and 9×9 blocks only.
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
def _turn(x, i, c, s):
    """Re-express x[i], x[i+1] (N, E components) in axes turned by the angle of (c, s): Rᵀ x."""
    a = x[i]
    b = x[i + 1]
    x[i] = c * a + s * b
    x[i + 1] = -s * a + c * b


@njit(cache=True)
def start(X, p, xb, clock, t, y, tau):
    """Initialise every filter at y: ξ = 0, η_p = Rᵀ(ψ)y, b_p = −τ (rest of (9)), ν = 0. Weights kept."""
    psi = ssa_jit(y[2])
    c = math.cos(psi)
    s = math.sin(psi)
    for j in range(15):
        xb[j] = 0.0
    xb[6] = c * y[0] + s * y[1]
    xb[7] = -s * y[0] + c * y[1]
    xb[8] = psi
    for j in range(3):
        xb[9 + j] = -(0.0 if math.isnan(tau[j]) else tau[j])
    for i in range(X.shape[0]):
        for j in range(15):
            X[i, j] = xb[j]
    clock[0] = t
    clock[1] = 1.0
    clock[2] = psi
    clock[3] = t


@njit(cache=True)
def _project(p, floor):
    """Raise weights below the floor to it and scale the rest down, until none is below (Σ p = 1)."""
    n = p.shape[0]
    low = np.zeros(n, dtype=np.bool_)
    for _ in range(n + 1):
        changed = False
        for i in range(n):
            if not low[i] and p[i] < floor:
                low[i] = True
                changed = True
        if not changed:
            return
        n_low = 0
        rest = 0.0
        for i in range(n):
            if low[i]:
                n_low += 1
            else:
                rest += p[i]
        scale = (1.0 - floor * n_low) / rest
        for i in range(n):
            p[i] = floor if low[i] else p[i] * scale


@njit(cache=True)
def step(X, p, xb, clock, t, y, tau, Phi, Gam, A, B, K, Sinv, logdet, params):
    """One sample; returns its status code (see `observers.mmae.reference_run` for the steps)."""
    N = X.shape[0]
    complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
    dt = t - clock[0]
    if clock[1] != 0.0 and dt > params[3]:
        clock[1] = 0.0  # gap longer than max_gap_s: restart from this sample if complete
    if clock[1] == 0.0:
        if not complete:
            return STATUS_INITIALIZING
        start(X, p, xb, clock, t, y, tau)
        return STATUS_OK
    if dt <= 0.0:
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[0] = t
    u = np.empty(3)
    for j in range(3):
        u[j] = 0.0 if math.isnan(tau[j]) else tau[j]

    # 1. turn the vessel-parallel frame to the latest blended heading
    psi_f = clock[2]
    d = ssa_jit(xb[8] - psi_f)
    if d != 0.0:
        c = math.cos(d)
        s = math.sin(d)
        for i in range(N):
            _turn(X[i], 6, c, s)
            _turn(X[i], 9, c, s)
    psi_f = xb[8]
    clock[2] = psi_f

    # 2. predict: n nominal ZOH steps, then a 2nd-order Taylor step for the remainder
    dt_nom = params[0]
    n_steps = math.floor(dt / dt_nom + 0.5)
    delta = dt - n_steps * dt_nom
    g = np.empty(15)
    for r in range(15):
        g[r] = Gam[r, 0] * u[0] + Gam[r, 1] * u[1] + Gam[r, 2] * u[2]
    xn = np.empty(15)
    f = np.empty(15)
    for i in range(N):
        x = X[i]
        Ph = Phi[i]
        for _ in range(n_steps):
            for r in range(6):
                acc = g[r]
                for q in range(6):
                    acc += Ph[r, q] * x[q]
                xn[r] = acc
            for r in range(6, 15):
                acc = g[r]
                for q in range(6, 15):
                    acc += Ph[r, q] * x[q]
                xn[r] = acc
            for r in range(15):
                x[r] = xn[r]
        if abs(delta) > 1e-9 * dt_nom:
            Ai = A[i]
            for r in range(15):
                acc = B[r, 0] * u[0] + B[r, 1] * u[1] + B[r, 2] * u[2]
                for q in range(15):
                    acc += Ai[r, q] * x[q]
                f[r] = acc
            for r in range(15):
                acc = 0.0
                for q in range(15):
                    acc += Ai[r, q] * f[q]
                xn[r] = x[r] + delta * f[r] + 0.5 * delta * delta * acc
            for r in range(15):
                x[r] = xn[r]

    # 3. update and weights (18)
    pos = not (math.isnan(y[0]) or math.isnan(y[1]))
    head = not math.isnan(y[2])
    m = (1 if pos else 0) + (2 if head else 0)
    if m != 0:
        c = math.cos(psi_f)
        s = math.sin(psi_f)
        yp0 = c * y[0] + s * y[1] if pos else 0.0
        yp1 = -s * y[0] + c * y[1] if pos else 0.0
        # the DOFs that inform the weights: all measured, or the position only (params[4] = 0)
        mw = m if params[4] != 0.0 else (m & 1)
        ll = np.empty(N)
        res = np.empty(3)
        for i in range(N):
            x = X[i]
            res[0] = yp0 - (x[6] + x[3]) if pos else 0.0
            res[1] = yp1 - (x[7] + x[4]) if pos else 0.0
            res[2] = ssa_jit(y[2] - (x[8] + x[5])) if head else 0.0
            Si = Sinv[i, mw]
            quad = 0.0
            for a in range(3):
                acc = 0.0
                for b in range(3):
                    acc += Si[a, b] * res[b]
                quad += res[a] * acc
            ll[i] = -0.5 * quad - 0.5 * logdet[i, mw]
            Ki = K[i, m]
            for r in range(15):
                x[r] += Ki[r, 0] * res[0] + Ki[r, 1] * res[1] + Ki[r, 2] * res[2]
            x[8] = ssa_jit(x[8])
        if mw != 0 and t - clock[3] >= params[2]:
            top = -math.inf
            for i in range(N):
                ll[i] += math.log(p[i])
                if ll[i] > top:
                    top = ll[i]
            total = 0.0
            for i in range(N):
                ll[i] = math.exp(ll[i] - top)
                total += ll[i]
            for i in range(N):
                p[i] = ll[i] / total
            _project(p, params[1])

    # 4. blend (16); the heading as ψ_f + Σ pᵢ ssa(ψᵢ − ψ_f)
    for j in range(15):
        acc = 0.0
        for i in range(N):
            acc += p[i] * X[i, j]
        xb[j] = acc
    acc = 0.0
    for i in range(N):
        acc += p[i] * ssa_jit(X[i, 8] - psi_f)
    xb[8] = ssa_jit(psi_f + acc)
    return STATUS_OK if m == 3 else STATUS_DEAD_RECKONING


@njit(cache=True)
def blended_omega(p, candidates):
    """Σ pᵢ ω0ⁱ (the same loop for `step` and `run`, so both give the same bits)."""
    acc = 0.0
    for i in range(p.shape[0]):
        acc += p[i] * candidates[i]
    return acc


@njit(cache=True)
def blended_omegas(W, candidates, out):
    for k in range(W.shape[0]):
        out[k] = blended_omega(W[k], candidates)


@njit(cache=True)
def outputs(xb, psi_f, out):
    """NED outputs of the blended state: out = [η̂, ν̂, b̂ (earth-fixed), η̂_w] (R(ψ_f) on N, E)."""
    c = math.cos(psi_f)
    s = math.sin(psi_f)
    for row, off in ((0, 6), (2, 9), (3, 3)):
        out[row, 0] = c * xb[off] - s * xb[off + 1]
        out[row, 1] = s * xb[off] + c * xb[off + 1]
        out[row, 2] = xb[off + 2]
    for j in range(3):
        out[1, j] = xb[12 + j]


@njit(cache=True)
def run(X, p, xb, clock, t, Y, TAU, Phi, Gam, A, B, K, Sinv, logdet, params, OUT, W, status):
    """`step` over arrays; OUT[k] = outputs after sample k (NaN while initialising), W[k] the weights."""
    n = t.shape[0]
    for k in range(n):
        code = step(X, p, xb, clock, t[k], Y[k], TAU[k], Phi, Gam, A, B, K, Sinv, logdet, params)
        status[k] = code
        if code == STATUS_INITIALIZING:
            for a in range(4):
                for b in range(3):
                    OUT[k, a, b] = np.nan
        else:
            outputs(xb, clock[2], OUT[k])
        for i in range(p.shape[0]):
            W[k, i] = p[i]
