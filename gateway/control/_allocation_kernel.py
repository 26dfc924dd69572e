"""Compiled thrust allocation step: the fast twin of `QPAllocator`'s readable Python + DAQP path.

One call does what `QPAllocator.allocate` does in Python around DAQP — the previous state made
consistent (`_Layout.state`), the step's convex limits (`QPAllocator.limits`), the scaled QP
(`QPAllocator._qp`, its Hessian `_p_diag`), its solution, and the commands (`QPAllocator._commands`) —
line for line with those methods, so that the per-step cost is one compiled call instead of some two
hundred small numpy and Python operations (the QP itself is a few µs; the Python around it was most of
the ~100 µs).

The QP solver is the dual active-set method of Goldfarb & Idnani (1983), "A numerically stable dual
method for solving strictly convex quadratic programs", Math. Programming 27, 1–33 — the algorithm of
``quadprog`` (Turlach's qpgen2), which docs/allocation.md measured to agree with DAQP to 1e-9 on the
allocation's QPs. Written here for a **diagonal** Hessian H = diag(P) (the allocation's objective is
separable), which makes the start exact and cheap: G&I start at the unconstrained minimum x₀ = −H⁻¹q with
J₀ = L⁻ᵀ = diag(1/√P); here, one better, at the minimum over the simple bounds alone (x₀ clipped to them,
those bounds active, J₀'s columns permuted: `_bounded_start`). For constraints
nᵢᵀx ≥ bᵢ (equalities nᵢᵀx = bᵢ) it keeps J = L⁻ᵀQ and the upper triangular R of the active normals
(Jᵀ N_active = [R; 0]), and repeats (G&I Sec. 3, steps 1–3):

1. Pick the most violated constraint p (sᵢ = nᵢᵀx − bᵢ < −tol); none: x is optimal.
2. d = Jᵀn_p; primal direction z = J₂d₂ (J₂: the columns beyond the active set); dual direction
   r = R⁻¹d₁. Partial step t₁ = min uⱼ/rⱼ over active inequalities with rⱼ > 0; full step
   t₂ = −s_p / (zᵀn_p) (∞ when z = 0: n_p depends on the active normals).
3. t = min(t₁, t₂) (both ∞: infeasible). x += t z, u −= t r, u_p += t. If t = t₂: add p (Givens
   rotations zero d below position q+1, applied to J's columns); else drop the blocking constraint
   (Givens rotations restore R's triangle, applied to J) and go to 2 with the same p.

Equalities are added first after the start (a violated one's sign is chosen so that it is "violated") and
never dropped; their multipliers are free. Exact to round-off like any active-set method (the heavy slack
weight makes the QP ill-conditioned, 10⁶; first-order methods stop far from the optimum there). It starts
afresh every step (no state from the previous one): the bounded start holds the τ slacks and bias
shortfalls at zero from the outset, and the rest is ~13 iterations of O(n²) each on the benchmark's
sequence, ~6 µs. If it ever fails (iteration limit, infeasible to round-off, or a final primal violation
above tolerance), the caller falls back to the DAQP path for that step, so a wrong answer is never
returned silently.

``tests/test_allocation_kernel.py`` checks this against DAQP (the QP's solution, hypothesis) and against
the Python path (the whole step) on random feasible and infeasible cases.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.kinematics import ssa_jit

TWO_PI = 2.0 * math.pi
ANGLE_EPS = 1e-9  # as allocation._ANGLE_EPS
FEAS_TOL = 1e-11  # scaled units (forces / T_max, slack / τ_ref): a constraint violated by less is met
CHECK_TOL = 1e-8  # final check: a primal violation above this (scaled) is a failure → fallback

OK = 0
FAIL_ITER = 1
FAIL_INFEASIBLE = 2
FAIL_CHECK = 3


# --------------------------------------------------------------------------------------------------------
# Goldfarb–Idnani dual active-set QP, diagonal Hessian


@njit(cache=True)
def _givens(a: float, b: float) -> tuple[float, float, float]:
    h = math.hypot(a, b)
    if h == 0.0:
        return 1.0, 0.0, 0.0
    return a / h, b / h, h


@njit(cache=True)
def _dot_row(p, n_eq, Ceq, si, sv, v):
    """n_pᵀv for constraint p: a dense equality row, or an inequality with two nonzeros."""
    if p < n_eq:
        acc = 0.0
        for k in range(v.shape[0]):
            acc += Ceq[p, k] * v[k]
        return acc
    i = p - n_eq
    return sv[i, 0] * v[si[i, 0]] + sv[i, 1] * v[si[i, 1]]


@njit(cache=True)
def _bounded_start(Pd, q, n_eq, si, sv, sb, m_in, m_gen, x, active, u, Jt, R, mark):
    """The dual method's start: the minimum of ½xᵀHx + qᵀx over the simple bounds alone, with every bound
    it meets active. H is diagonal, so that minimum is the unconstrained x₀ = −H⁻¹q clipped to the bounds,
    and its active set is known without a single iteration: for the bound vₖxₖ ≥ b (v = ±1) that x₀
    violates, xₖ = v·b and its multiplier is uₖ = v(Pₖxₖ + qₖ) = v·Pₖ(xₖ − x₀ₖ) > 0 — dual feasible, as
    G&I's start must be. J = L⁻ᵀQ is the diagonal diag(1/√P) with its columns permuted (the clipped
    variables' first, in the order their bounds are active, signed by v) and R = diag(1/√Pₖ) of the
    clipped ones: Jᵀ N_active = [R; 0] holds exactly. Jt holds Jᵀ (as in `gi_solve`).

    Why: the shortfall variables (the τ slacks ŝ±, the bias shortfalls e) have q > 0 and bound 0, so x₀
    has every one of them negative; from x = x₀ the method adds them one at a time, and in the meantime
    the τ equalities, met through slacks that are not yet held at zero, move the forces onto bounds and
    faces that it must drop again (with the turn cost and the bias floor: ~42 iterations a step on the
    benchmark's sequence instead of ~12). The optimum is the same (the QP is strictly convex); only the
    path to it, and its round-off (~1e-11 scaled), differ. Returns the number active."""
    n = Pd.shape[0]
    nact = 0
    for k in range(n):
        x[k] = -q[k] / Pd[k]
        mark[k] = -1.0
        for j in range(n):
            Jt[k, j] = 0.0
            R[k, j] = 0.0
    for i in range(m_gen, m_in):
        k = si[i, 0]
        v = sv[i, 0]
        if mark[k] < 0.0 and v * x[k] - sb[i] < -FEAS_TOL:
            x[k] = v * sb[i]
            u[nact] = v * (Pd[k] * x[k] + q[k])
            active[nact] = i + n_eq
            mark[k] = nact
            nact += 1
    c = nact
    for k in range(n):
        h = 1.0 / math.sqrt(Pd[k])
        if mark[k] < 0.0:
            Jt[c, k] = h
            c += 1
        else:
            a = int(mark[k])
            Jt[a, k] = sv[active[a] - n_eq, 0] * h
            R[a, a] = h
    return nact


@njit(cache=True)
def gi_solve(Pd, q, Ceq, beq, si, sv, sb, m_in, m_gen, x, active, u, Jt, R, d, z, r, max_iter):
    """min ½xᵀdiag(Pd)x + qᵀx s.t. Ceq x = beq (dense rows) and, for i < m_in,
    sv[i,0]·x[si[i,0]] + sv[i,1]·x[si[i,1]] ≥ sb[i] (every inequality of the allocation's QP — bounds,
    polygon faces, cone edges — touches at most two variables, so a scan of all of them is O(m)).
    Rows i ≥ m_gen are simple bounds (sv[i,0] = ±1, sv[i,1] = 0; at most one violated per variable at
    the start, as `constraints_of` writes them): the start is their minimum (see `_bounded_start`).

    Work arrays Jt, R (n×n), d, z, r, u (n), active (int, n): the caller's (nothing is allocated per call).
    Jt holds Jᵀ (its row j is J's column j), so that the Givens rotations of J's columns and z = J₂d₂ run
    along contiguous memory (the arithmetic, and its order, is that of J itself).
    Constraint p is an equality for p < n_eq, inequality p − n_eq otherwise. Returns (status, iterations,
    number active); x holds the solution."""
    n = Pd.shape[0]
    n_eq = Ceq.shape[0]
    nact = _bounded_start(Pd, q, n_eq, si, sv, sb, m_in, m_gen, x, active, u, Jt, R, z)
    it = 0
    next_eq = 0
    while True:
        # ---- step 1: the constraint to add (equalities first, in order; then the most violated)
        p = -1
        sign_p = 1.0
        if next_eq < n_eq:
            p = next_eq
            next_eq += 1
            if _dot_row(p, n_eq, Ceq, si, sv, x) - beq[p] > 0.0:
                sign_p = -1.0
        else:
            worst = -FEAS_TOL
            for i in range(m_in):
                s = sv[i, 0] * x[si[i, 0]] + sv[i, 1] * x[si[i, 1]] - sb[i]
                if s < worst:
                    inact = True
                    for a in range(nact):
                        if active[a] == i + n_eq:
                            inact = False
                            break
                    if inact:
                        worst = s
                        p = i + n_eq
            if p < 0:
                break
        b_p = beq[p] if p < n_eq else sb[p - n_eq]
        u_p = 0.0
        # ---- steps 2–3 for constraint p (repeated after each drop)
        while True:
            it += 1
            if it > max_iter:
                return FAIL_ITER, it, nact
            s_p = sign_p * (_dot_row(p, n_eq, Ceq, si, sv, x) - b_p)
            # d = Jᵀ n_p
            if p < n_eq:  # each d[j] summed over k in order, the n sums side by side
                for j in range(n):
                    d[j] = 0.0
                for k in range(n):
                    ck = Ceq[p, k]
                    if ck != 0.0:
                        for j in range(n):
                            d[j] += Jt[j, k] * ck
                for j in range(n):
                    d[j] *= sign_p
            else:
                i0, i1 = si[p - n_eq, 0], si[p - n_eq, 1]
                v0, v1 = sv[p - n_eq, 0], sv[p - n_eq, 1]
                for j in range(n):
                    d[j] = v0 * Jt[j, i0] + v1 * Jt[j, i1]
            for k in range(n):  # z = J₂d₂, row by row of Jt (contiguous; each z[k] summed over j in order)
                z[k] = 0.0
            for j in range(nact, n):
                dj = d[j]
                for k in range(n):
                    z[k] += Jt[j, k] * dj
            zn = 0.0  # zᵀn_p = |d₂|² (J₂J₂ᵀ is the projector)
            dnorm = 0.0
            for j in range(n):
                dnorm += d[j] * d[j]
                if j >= nact:
                    zn += d[j] * d[j]
            for a in range(nact - 1, -1, -1):  # r = R⁻¹ d₁ (back substitution)
                acc = d[a]
                for j in range(a + 1, nact):
                    acc -= R[a, j] * r[j]
                r[a] = acc / R[a, a]
            t1 = math.inf
            drop = -1
            for a in range(nact):
                if active[a] >= n_eq and r[a] > 0.0:
                    ratio = u[a] / r[a]
                    if ratio < t1:
                        t1 = ratio
                        drop = a
            t2 = math.inf
            if zn > 1e-24 * max(dnorm, 1e-300):
                t2 = max(-s_p, 0.0) / zn  # ≥ 0 also if round-off met p during partial steps
            t = min(t1, t2)
            if t == math.inf:
                return FAIL_INFEASIBLE, it, nact
            if t2 < math.inf:
                for k in range(n):
                    x[k] += t * z[k]
            for a in range(nact):
                u[a] -= t * r[a]
            u_p += t
            if t2 <= t1:
                # add p: Givens rotations zero d[nact+1:], applied to J's columns
                for j in range(n - 1, nact, -1):
                    if d[j] == 0.0:  # nothing to zero (J is sparse after the start): no rotation
                        continue
                    c, sn, h = _givens(d[j - 1], d[j])
                    d[j - 1] = h
                    d[j] = 0.0
                    for k in range(n):
                        a1 = Jt[j - 1, k]
                        a2 = Jt[j, k]
                        Jt[j - 1, k] = c * a1 + sn * a2
                        Jt[j, k] = -sn * a1 + c * a2
                for a in range(nact + 1):
                    R[a, nact] = d[a]
                active[nact] = p
                u[nact] = u_p
                nact += 1
                break
            # drop the blocking constraint and restore R's triangle
            for a in range(drop, nact - 1):
                active[a] = active[a + 1]
                u[a] = u[a + 1]
                for k in range(nact):
                    R[k, a] = R[k, a + 1]
            for k in range(nact):
                R[k, nact - 1] = 0.0
            nact -= 1
            for a in range(drop, nact):
                if R[a + 1, a] == 0.0:
                    continue
                c, sn, h = _givens(R[a, a], R[a + 1, a])
                for j in range(a, nact):
                    a1 = R[a, j]
                    a2 = R[a + 1, j]
                    R[a, j] = c * a1 + sn * a2
                    R[a + 1, j] = -sn * a1 + c * a2
                R[a + 1, a] = 0.0
                for k in range(n):
                    a1 = Jt[a, k]
                    a2 = Jt[a + 1, k]
                    Jt[a, k] = c * a1 + sn * a2
                    Jt[a + 1, k] = -sn * a1 + c * a2
    # final check of the primal solution (what a wrong answer would show first)
    for p in range(n_eq):
        s = _dot_row(p, n_eq, Ceq, si, sv, x) - beq[p]
        if abs(s) > CHECK_TOL:
            return FAIL_CHECK, it, nact
    for i in range(m_in):
        if sv[i, 0] * x[si[i, 0]] + sv[i, 1] * x[si[i, 1]] - sb[i] < -CHECK_TOL:
            return FAIL_CHECK, it, nact
    return OK, it, nact


@njit(cache=True)
def constraints_of(A, ub_A, lb, ub, n_eq, si, sv, sb):
    """The inequalities of the QP of `allocation.QPData` (A[n_eq:]x ≤ ub_A, lb ≤ x ≤ ub) as rows
    sv[i,0]·x[si[i,0]] + sv[i,1]·x[si[i,1]] ≥ sb[i]: the finite general rows, then the finite bounds.
    Returns (row count, number of general rows), or (−1, −1) if a general row has more than two nonzeros
    (not this QP's structure)."""
    n = A.shape[1]
    m = 0
    for i in range(n_eq, A.shape[0]):
        if ub_A[i] < math.inf:
            cnt = 0
            si[m, 0], si[m, 1], sv[m, 0], sv[m, 1] = 0, 0, 0.0, 0.0
            for k in range(n):
                if A[i, k] != 0.0:
                    if cnt == 2:
                        return -1, -1
                    si[m, cnt] = k
                    sv[m, cnt] = -A[i, k]
                    cnt += 1
            sb[m] = -ub_A[i]
            m += 1
    m_gen = m
    for j in range(n):
        if lb[j] > -math.inf:
            si[m, 0], si[m, 1], sv[m, 0], sv[m, 1], sb[m] = j, j, 1.0, 0.0, lb[j]
            m += 1
        if ub[j] < math.inf:
            si[m, 0], si[m, 1], sv[m, 0], sv[m, 1], sb[m] = j, j, -1.0, 0.0, -ub[j]
            m += 1
    return m, m_gen


def solve_qp_data(P_diag, q, A, b_eq, ub_A, lb, ub, n_eq, bounded_start=True):
    """Solve one `allocation.QPData` (diagonal P given as its diagonal) with `gi_solve`: (x, status,
    iterations). For tests and the benchmark; the allocator's own step builds its QP inside the kernel.
    ``bounded_start=False``: G&I's own start at the unconstrained minimum (no bound active), the
    reference the bounded start (`_bounded_start`) is tested against."""
    n = A.shape[1]
    m_max = A.shape[0] + 2 * n
    si, sv, sb = np.empty((m_max, 2), dtype=np.int64), np.empty((m_max, 2)), np.empty(m_max)
    m, m_gen = constraints_of(np.ascontiguousarray(A, dtype=float), ub_A, lb, ub, n_eq, si, sv, sb)
    if m < 0:
        return np.full(n, np.nan), FAIL_CHECK, 0
    x = np.empty(n)
    w = (np.empty(n, dtype=np.int64), np.empty(n), np.empty((n, n)), np.empty((n, n)))
    status, it, _ = gi_solve(
        np.asarray(P_diag, dtype=float),
        np.asarray(q, dtype=float),
        np.ascontiguousarray(A[:n_eq], dtype=float),
        np.asarray(b_eq, dtype=float),
        si,
        sv,
        sb,
        m,
        m_gen if bounded_start else m,
        x,
        *w,
        np.empty(n),
        np.empty(n),
        np.empty(n),
        50 * (m + n),
    )
    return x, status, it


# --------------------------------------------------------------------------------------------------------
# The whole step: state → limits → QP → solve → commands (QPAllocator, line for line)


@njit(cache=True)
def _in_sector(i, angle, sec_start, sec_width, sec_count):
    for k in range(sec_count[i]):
        if ANGLE_EPS < (angle - sec_start[i, k]) % TWO_PI < sec_width[i, k] - ANGLE_EPS:
            return True
    return False


@njit(cache=True)
def _outside_sectors(i, target, sec_start, sec_width, sec_count):
    for k in range(sec_count[i]):
        start, width = sec_start[i, k], sec_width[i, k]
        p = (target - start) % TWO_PI
        if 0.0 < p < width:
            return start if p < width / 2 else start + width
    return target


@njit(cache=True)
def allocate_step(
    tau,
    prev_thrust,
    prev_angle,
    # layout (constant)
    is_az,
    first,
    xpos,
    ypos,
    cap,
    tmin,
    tmax,
    fixed_angle,
    tau_ref,
    dT,
    turn,
    idle,
    arc_lo0,
    arc_hi0,
    sec_start,
    sec_width,
    sec_count,
    has_sectors,
    pinv,
    idle_steering,
    turn_cw,
    turn_floor,
    bias_frac,
    # the QP's constant parts (Pd without the turn cost, which depends on the present thrust; A0 with the
    # bias rows' coefficients, their bounds set per step)
    Pd,
    q,
    A0,
    poly_scale,
    n_sides,
    # work arrays
    Pw,
    A,
    ub_A,
    lb,
    ub,
    si,
    sv,
    sb,
    xs,
    active,
    u,
    J,
    R,
    d,
    z,
    r,
    # outputs
    thrust_out,
    angle_out,
    tau_alloc,
    info,
):
    """One allocation step. Outputs: thrust_out, angle_out (n), tau_alloc (3), info = [status,
    iterations, objective, max scaled |slack| of the QP]. Returns the solver status (0 = OK)."""
    n = is_az.shape[0]
    n_ext = pinv.shape[0]
    nx = Pd.shape[0]
    # ---- _Layout.state: finite, azimuth thrust ≥ 0 (a negative one is the force turned by π), clipped
    thrust = np.empty(n)
    angle = np.empty(n)
    for i in range(n):
        t, a = prev_thrust[i], prev_angle[i]
        if not (math.isfinite(t) and math.isfinite(a)):
            if not math.isfinite(t):
                t = 0.0
            if not math.isfinite(a):
                a = fixed_angle[i]
        if is_az[i]:
            if t < 0.0:
                a = a + math.pi
                t = -t
            a = ssa_jit(a)
        else:
            a = fixed_angle[i]
        thrust[i] = min(max(t, tmin[i]), tmax[i])
        angle[i] = a
    # ---- QPAllocator.limits
    arc_lo = np.empty(n)
    arc_hi = np.empty(n)
    cone = np.zeros(n, dtype=np.bool_)
    blocked = np.zeros(n, dtype=np.bool_)
    along_min = np.empty(n)
    lower = np.empty(n)
    upper = np.empty(n)
    n_az_on = 0  # azimuths in service: thrust biasing needs two or more
    for i in range(n):
        if is_az[i] and tmax[i] > 0.0:
            n_az_on += 1
    for i in range(n):
        lo, hi = turn[i], turn[i]
        if has_sectors:
            a = angle[i]
            for k in range(sec_count[i]):
                start, width = sec_start[i, k], sec_width[i, k]
                p = (a - start) % TWO_PI
                if ANGLE_EPS < p < width - ANGLE_EPS:
                    blocked[i] = True
                    continue
                ahead = (start - a) % TWO_PI
                behind = (a - start - width) % TWO_PI
                hi = min(hi, 0.0 if ahead > TWO_PI - ANGLE_EPS else ahead)
                lo = min(lo, 0.0 if behind > TWO_PI - ANGLE_EPS else behind)
            # _convex_arc
            movable = is_az[i] and not blocked[i]
            total = lo + hi
            cone[i] = movable and total < TWO_PI
            if total > math.pi:
                lo2 = min(lo, math.pi / 2)
                hi2 = min(hi, math.pi - lo2)
                lo2 = min(lo, math.pi - hi2)
                lo, hi = lo2, hi2
            arc_lo[i] = lo if movable else 0.0
            arc_hi[i] = hi if movable else 0.0
            along_ok = not blocked[i]
        else:
            arc_lo[i], arc_hi[i] = arc_lo0[i], arc_hi0[i]
            cone[i] = is_az[i] and turn[i] + turn[i] < TWO_PI
            along_ok = is_az[i]
        down, up = thrust[i] - dT[i], thrust[i] + dT[i]
        upper[i] = min(tmax[i], up)
        along_min[i] = down if (along_ok and down > 0) else -math.inf
        lower[i] = max(tmin[i], down)
    # ---- QPAllocator._qp (and _p_diag: the turn cost over the present thrust)
    Pw[:] = Pd
    for i in range(n):
        if is_az[i]:
            t0 = max(thrust[i] / cap[i], turn_floor)
            Pw[first[i] + 1] += turn_cw[i] / (t0 * t0)
    A[:, :] = A0
    ub_A[:] = math.inf
    for k in range(n_ext):
        lb[k] = -math.inf
        ub[k] = math.inf
    for k in range(n_ext, nx):  # slack ŝ⁺, ŝ⁻ and the bias shortfalls e: non-negative
        lb[k] = 0.0
        ub[k] = math.inf
    sx, sy, sn = 1.0 / tau_ref[0], 1.0 / tau_ref[1], 1.0 / tau_ref[2]
    N = n_sides
    j = 0
    for i in range(n):
        k = first[i]
        if not is_az[i]:
            lb[k] = lower[i] / cap[i]
            ub[k] = upper[i] / cap[i]
            continue
        cp, x, y = cap[i], xpos[i], ypos[i]
        c, s = math.cos(angle[i]), math.sin(angle[i])
        A[0, k], A[1, k], A[2, k] = c * cp * sx, s * cp * sy, (x * s - y * c) * cp * sn
        A[0, k + 1], A[1, k + 1], A[2, k + 1] = -s * cp * sx, c * cp * sy, (x * c + y * s) * cp * sn
        rad = upper[i] / cp
        r0 = 3 + j * (N + 3)
        j += 1
        for m in range(N):
            ub_A[r0 + m] = rad * poly_scale
        if bias_frac > 0.0 and n_az_on >= 2 and not blocked[i]:
            # thrust biasing, soft: â + e ≥ min(β T_max, r) / T_cap, e ≥ 0 priced in the objective
            ub_A[r0 + N + 2] = -min(bias_frac * tmax[i], upper[i]) / cp
        if blocked[i]:
            lb[k] = 0.0
            ub[k] = 0.0
            lb[k + 1] = 0.0
            ub[k + 1] = 0.0
            continue
        lb[k], ub[k] = max(along_min[i] / cp, -rad), rad
        lb[k + 1], ub[k + 1] = -rad, rad
        if cone[i]:
            lo, hi = arc_lo[i], arc_hi[i]
            A[r0 + N, k], A[r0 + N, k + 1] = -math.sin(hi), math.cos(hi)
            ub_A[r0 + N] = 0.0
            if lo + hi < math.pi - 1e-9:
                A[r0 + N + 1, k], A[r0 + N + 1, k + 1] = -math.sin(lo), -math.cos(lo)
                ub_A[r0 + N + 1] = 0.0
    b_eq = np.empty(3)
    for i in range(3):
        b_eq[i] = tau[i] / tau_ref[i]
    # ---- solve
    m, m_gen = constraints_of(A, ub_A, lb, ub, 3, si, sv, sb)
    if m < 0:
        info[0] = FAIL_CHECK
        return FAIL_CHECK
    status, iters, _ = gi_solve(
        Pw, q, A[:3], b_eq, si, sv, sb, m, m_gen, xs, active, u, J, R, d, z, r, 50 * (m + nx)
    )
    info[0] = status
    info[1] = iters
    if status != OK:
        return status
    obj = 0.0
    for k in range(nx):
        obj += 0.5 * Pw[k] * xs[k] * xs[k] + q[k] * xs[k]
    info[2] = obj
    smax = 0.0
    for i in range(3):
        smax = max(smax, abs(xs[n_ext + i] - xs[n_ext + 3 + i]))
    info[3] = smax
    # ---- QPAllocator._solve's forces and _commands
    preferred_done = False
    pref = np.empty(n_ext)
    for i in range(n):
        k = first[i]
        if not is_az[i]:
            thrust_out[i] = min(max(xs[k] * cap[i], lower[i]), upper[i])
            angle_out[i] = fixed_angle[i]
            continue
        prev = angle[i]
        c, s = math.cos(prev), math.sin(prev)
        a, bb = xs[k] * cap[i], xs[k + 1] * cap[i]
        fx, fy = a * c - bb * s, a * s + bb * c
        mag = math.hypot(fx, fy)
        if mag >= idle[i] and not blocked[i]:
            rel = math.atan2(fy * c - fx * s, fx * c + fy * s)
            if cone[i]:
                rel = min(max(rel, -arc_lo[i]), arc_hi[i])
            angle_out[i] = prev + rel
            thrust_out[i] = min(mag, upper[i])
            continue
        new = prev
        off = blocked[i]
        if idle_steering:
            if not preferred_done:
                for kk in range(n_ext):
                    pref[kk] = pinv[kk, 0] * tau[0] + pinv[kk, 1] * tau[1] + pinv[kk, 2] * tau[2]
                preferred_done = True
            px, py = pref[k], pref[k + 1]
            if math.hypot(px, py) >= idle[i]:
                target = _outside_sectors(i, math.atan2(py, px), sec_start, sec_width, sec_count)
                step = turn[i]
                new = prev + min(max(ssa_jit(target - prev), -step), step)
                off = off or _in_sector(i, new, sec_start, sec_width, sec_count)
        along = max(fx * math.cos(new) + fy * math.sin(new), along_min[i], 0.0)
        angle_out[i] = new
        thrust_out[i] = 0.0 if off else min(along, upper[i])
    # ssa of every angle, then τ = B(α)T
    tx, ty, tn = 0.0, 0.0, 0.0
    for i in range(n):
        angle_out[i] = ssa_jit(angle_out[i])
        fx = thrust_out[i] * math.cos(angle_out[i])
        fy = thrust_out[i] * math.sin(angle_out[i])
        tx += fx
        ty += fy
        tn += xpos[i] * fy - ypos[i] * fx
    tau_alloc[0], tau_alloc[1], tau_alloc[2] = tx, ty, tn
    return OK
