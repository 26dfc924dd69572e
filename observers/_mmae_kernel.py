"""Compiled kernel of the MMAE wave filter, Hassani et al. eqs (13)–(18) (see `observers.mmae`).

The fast twin of `observers.mmae.reference_run`; tests/test_mmae.py checks that the two agree to
round-off. It exists because batch replay must run eight 15-state filters at ≥ 100,000 samples a second
(bench/bench_mmae.py). Keep the steps here line for line with the reference.

Arrays (N filters): ``X`` (N, 15) filter states in the vessel-parallel frame, ``p`` (N,) weights,
``xb`` (15,) blended state, ``clock`` (``CLOCK_*`` below: last sample's time, initialised flag, frame
heading ψ_f, time of initialisation); bank: ``Phi`` (N, 15, 15), ``Gam`` (15, 3), ``A`` (N, 15, 15),
``B`` (15, 3), ``K`` (N, 4, 15, 3), ``Sinv`` (N, 4, 3, 3), ``logdet`` (N, 4); ``params`` (``PARAM_*``:
nominal interval, weight floor, warm-up, longest gap, whether the heading votes in the weights).

State order: `observers.state` (ξ1, ξ2 = η_w, η_p, b_p, ν). A(ω0) is block-diagonal in (ξ) and
(η_p, b_p, ν), so the prediction multiplies the 6×6 and 9×9 blocks only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.base import STATUS_DEAD_RECKONING, STATUS_INITIALIZING, STATUS_OK
from observers.kinematics import ssa_jit
from observers.state import I_BIAS, I_ETA, I_NU, I_PSI, I_XI2, N_STATE

# the clock
CLOCK_T = 0  # time of the last sample used
CLOCK_STARTED = 1  # 1.0 once initialised
CLOCK_PSI_F = 2  # ψ_f, heading of the vessel-parallel frame (rad)
CLOCK_T_INIT = 3  # time of initialisation (the warm-up counts from it)
N_CLOCK = 4

# the parameters
PARAM_DT = 0  # nominal sample interval the bank is discretised at (s)
PARAM_WEIGHT_FLOOR = 1  # least weight of any filter
PARAM_WARMUP_S = 2  # the weights stay put this long after initialisation (s)
PARAM_MAX_GAP_S = 3  # a longer gap restarts the filters (s)
PARAM_HEADING_VOTES = 4  # 1.0: the heading innovation informs the weights; 0.0: position only
N_PARAMS = 5

# rows of the outputs (4, 3)
OUT_ETA = 0
OUT_NU = 1
OUT_BIAS = 2
OUT_ETA_WF = 3
N_OUT = 4


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
    for j in range(N_STATE):
        xb[j] = 0.0
    xb[I_ETA] = c * y[0] + s * y[1]
    xb[I_ETA + 1] = -s * y[0] + c * y[1]
    xb[I_PSI] = psi
    for j in range(3):
        xb[I_BIAS + j] = -(0.0 if math.isnan(tau[j]) else tau[j])
    start_at(X, xb, clock, t, psi)


@njit(cache=True)
def start_at(X, xb, clock, t, psi_f):
    """Every filter at the blended state xb (in the frame of heading psi_f); the clock started at t."""
    for i in range(X.shape[0]):
        for j in range(N_STATE):
            X[i, j] = xb[j]
    clock[CLOCK_T] = t
    clock[CLOCK_STARTED] = 1.0
    clock[CLOCK_PSI_F] = psi_f
    clock[CLOCK_T_INIT] = t


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
    return _step(X, p, xb, clock, t, y, tau, Phi, Gam, A, B, K, Sinv, logdet, params, _scratch(X.shape[0]))


@njit(cache=True)
def _scratch(n):
    """Work arrays of one step (allocated once per `run`, not per sample: at one filter the allocations
    cost as much as the filter)."""
    return (np.empty(3), np.empty(N_STATE), np.empty(N_STATE), np.empty(N_STATE), np.empty(n), np.empty(3))


@njit(cache=True)
def _step(X, p, xb, clock, t, y, tau, Phi, Gam, A, B, K, Sinv, logdet, params, scratch):
    """`step` with its work arrays given."""
    u, g, xn, f, ll, res = scratch
    N = X.shape[0]
    complete = not (math.isnan(y[0]) or math.isnan(y[1]) or math.isnan(y[2]))
    dt = t - clock[CLOCK_T]
    if clock[CLOCK_STARTED] != 0.0 and dt > params[PARAM_MAX_GAP_S]:
        clock[CLOCK_STARTED] = 0.0  # gap longer than max_gap_s: restart from this sample if complete
    if clock[CLOCK_STARTED] == 0.0:
        if not complete:
            return STATUS_INITIALIZING
        start(X, p, xb, clock, t, y, tau)
        return STATUS_OK
    if dt <= 0.0:
        return STATUS_OK if complete else STATUS_DEAD_RECKONING
    clock[CLOCK_T] = t
    for j in range(3):
        u[j] = 0.0 if math.isnan(tau[j]) else tau[j]

    # 1. turn the vessel-parallel frame to the latest blended heading
    psi_f = clock[CLOCK_PSI_F]
    d = ssa_jit(xb[I_PSI] - psi_f)
    if d != 0.0:
        c = math.cos(d)
        s = math.sin(d)
        for i in range(N):
            _turn(X[i], I_ETA, c, s)
            _turn(X[i], I_BIAS, c, s)
    psi_f = xb[I_PSI]
    clock[CLOCK_PSI_F] = psi_f

    # 2. predict: n nominal ZOH steps, then a 2nd-order Taylor step for the remainder
    dt_nom = params[PARAM_DT]
    n_steps = math.floor(dt / dt_nom + 0.5)
    delta = dt - n_steps * dt_nom
    for r in range(N_STATE):
        g[r] = Gam[r, 0] * u[0] + Gam[r, 1] * u[1] + Gam[r, 2] * u[2]
    for i in range(N):
        x = X[i]
        Ph = Phi[i]
        for _ in range(n_steps):
            for r in range(I_ETA):  # the wave block (ξ1, ξ2)
                acc = g[r]
                for q in range(I_ETA):
                    acc += Ph[r, q] * x[q]
                xn[r] = acc
            for r in range(I_ETA, N_STATE):  # the LF block (η_p, b_p, ν)
                acc = g[r]
                for q in range(I_ETA, N_STATE):
                    acc += Ph[r, q] * x[q]
                xn[r] = acc
            for r in range(N_STATE):
                x[r] = xn[r]
        if abs(delta) > 1e-9 * dt_nom:
            Ai = A[i]
            for r in range(N_STATE):
                acc = B[r, 0] * u[0] + B[r, 1] * u[1] + B[r, 2] * u[2]
                for q in range(N_STATE):
                    acc += Ai[r, q] * x[q]
                f[r] = acc
            for r in range(N_STATE):
                acc = 0.0
                for q in range(N_STATE):
                    acc += Ai[r, q] * f[q]
                xn[r] = x[r] + delta * f[r] + 0.5 * delta * delta * acc
            for r in range(N_STATE):
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
        # the DOFs that inform the weights: all measured, or the position only (PARAM_HEADING_VOTES 0)
        mw = m if params[PARAM_HEADING_VOTES] != 0.0 else (m & 1)
        for i in range(N):
            x = X[i]
            res[0] = yp0 - (x[I_ETA] + x[I_XI2]) if pos else 0.0
            res[1] = yp1 - (x[I_ETA + 1] + x[I_XI2 + 1]) if pos else 0.0
            res[2] = ssa_jit(y[2] - (x[I_PSI] + x[I_XI2 + 2])) if head else 0.0
            Si = Sinv[i, mw]
            quad = 0.0
            for a in range(3):
                acc = 0.0
                for b in range(3):
                    acc += Si[a, b] * res[b]
                quad += res[a] * acc
            ll[i] = -0.5 * quad - 0.5 * logdet[i, mw]
            Ki = K[i, m]
            for r in range(N_STATE):
                x[r] += Ki[r, 0] * res[0] + Ki[r, 1] * res[1] + Ki[r, 2] * res[2]
            x[I_PSI] = ssa_jit(x[I_PSI])
        if mw != 0 and t - clock[CLOCK_T_INIT] >= params[PARAM_WARMUP_S]:
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
            _project(p, params[PARAM_WEIGHT_FLOOR])

    # 4. blend (16); the heading as ψ_f + Σ pᵢ ssa(ψᵢ − ψ_f)
    for j in range(N_STATE):
        acc = 0.0
        for i in range(N):
            acc += p[i] * X[i, j]
        xb[j] = acc
    acc = 0.0
    for i in range(N):
        acc += p[i] * ssa_jit(X[i, I_PSI] - psi_f)
    xb[I_PSI] = ssa_jit(psi_f + acc)
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
    for row, off in ((OUT_ETA, I_ETA), (OUT_BIAS, I_BIAS), (OUT_ETA_WF, I_XI2)):
        out[row, 0] = c * xb[off] - s * xb[off + 1]
        out[row, 1] = s * xb[off] + c * xb[off + 1]
        out[row, 2] = xb[off + 2]
    for j in range(3):
        out[OUT_NU, j] = xb[I_NU + j]


@njit(cache=True)
def run(X, p, xb, clock, t, Y, TAU, Phi, Gam, A, B, K, Sinv, logdet, params, OUT, W, status):
    """`step` over arrays; OUT[k] = outputs after sample k (NaN while initialising), W[k] the weights."""
    n = t.shape[0]
    scratch = _scratch(X.shape[0])
    for k in range(n):
        code = _step(X, p, xb, clock, t[k], Y[k], TAU[k], Phi, Gam, A, B, K, Sinv, logdet, params, scratch)
        status[k] = code
        if code == STATUS_INITIALIZING:
            for a in range(4):
                for b in range(3):
                    OUT[k, a, b] = np.nan
        else:
            outputs(xb, clock[CLOCK_PSI_F], OUT[k])
        for i in range(p.shape[0]):
            W[k, i] = p[i]


@njit(cache=True)
def run_single(X, xb, clock, t, Y, TAU, Phi, Gam, A, B, K, Sinv, logdet, params, RES):
    """k independent single filters (each a bank of one, with its own state, frame and clock: X, xb (k, 15),
    clock (k, N_CLOCK); its own matrices Phi[i], A[i], K[i], Sinv[i], logdet[i]) over the same samples;
    RES[i, j] = y_j − (η̂ + η̂_w) of filter i after sample j (NED, heading wrapped; NaN where y is or while
    initialising). The LF output stage's trial filters (`observers.mmae_lf`)."""
    k = X.shape[0]
    n = t.shape[0]
    scratch = _scratch(1)
    one = np.ones(1)
    out = np.empty((N_OUT, 3))
    for j in range(n):
        for i in range(k):
            one[0] = 1.0
            code = _step(
                X[i : i + 1], one, xb[i], clock[i], t[j], Y[j], TAU[j], Phi[i : i + 1], Gam, A[i : i + 1], B,
                K[i : i + 1], Sinv[i : i + 1], logdet[i : i + 1], params, scratch,
            )  # fmt: skip
            if code == STATUS_INITIALIZING:
                for d in range(3):
                    RES[i, j, d] = np.nan
                continue
            outputs(xb[i], clock[i, CLOCK_PSI_F], out)
            for d in range(2):
                RES[i, j, d] = Y[j, d] - out[OUT_ETA, d] - out[OUT_ETA_WF, d]
            RES[i, j, 2] = ssa_jit(Y[j, 2] - out[OUT_ETA, 2] - out[OUT_ETA_WF, 2])


@njit(cache=True)
def mix_outputs(blend, lf, stiff):
    """In place into ``blend`` (m, 4, 3): per DOF d with stiff[d] the LF output filter's estimate ``lf``,
    the blend's elsewhere, in the vessel-parallel axes of the blend's heading estimate (η̂, b̂, η̂_w turned
    there, chosen, turned back; ν̂ is body-frame already). See `observers.mmae_lf.mix_outputs`."""
    for k in range(blend.shape[0]):
        if stiff[0] and stiff[1] and stiff[2]:
            for a in range(N_OUT):
                for d in range(3):
                    blend[k, a, d] = lf[k, a, d]
            continue
        psi = blend[k, OUT_ETA, 2]
        c = math.cos(psi)
        s = math.sin(psi)
        for row in (OUT_ETA, OUT_BIAS, OUT_ETA_WF):
            bx = c * blend[k, row, 0] + s * blend[k, row, 1]
            by = -s * blend[k, row, 0] + c * blend[k, row, 1]
            lx = c * lf[k, row, 0] + s * lf[k, row, 1]
            ly = -s * lf[k, row, 0] + c * lf[k, row, 1]
            x = lx if stiff[0] else bx
            y = ly if stiff[1] else by
            blend[k, row, 0] = c * x - s * y
            blend[k, row, 1] = s * x + c * y
            if stiff[2]:
                blend[k, row, 2] = lf[k, row, 2]
        for d in range(3):
            if stiff[d]:
                blend[k, OUT_NU, d] = lf[k, OUT_NU, d]
