"""Compiled DP control step: the fast twin of `DPController._update_dp` (steady dp mode) and
`ReferenceModel.step`.

The readable reference is the numpy code in `gateway.control.controller` (Torsetnes, Jouffroy & Fossen
(2004) eqs (57)–(59), (67)–(70), with the reference feed-forward, bias feed-forward and back-calculation
anti-windup documented there) and `gateway.control.reference` (Fossen (2011) eq. (12.12) with the velocity
and acceleration limits). This kernel does the same operations on scalars in one call, so that a control
step costs one compiled call instead of some seventy numpy calls on arrays of three. It covers the step of
dp mode after the first one (the bumpless entry, standby and manual stay in numpy: once per mode change).
The two differ only by round-off (numpy's 3×3 products go through BLAS, which fuses multiply-adds);
``tests/test_controller_kernel.py`` checks that they agree along closed-loop-like sequences.

Packed arrays (indices below): the reference model's state ``rs``, its constants ``rp``, the inputs ``inp``,
the matrices ``mats`` = [M, D, M⁻¹, Kp, Ki, Kd] and the per-DOF ``dof`` = [k, has integral, tracking rate].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.kinematics import ssa_jit

# rs: the reference model's state
RS_P0, RS_P1, RS_V0, RS_V1, RS_F0, RS_F1, RS_PSI, RS_R, RS_FPSI = range(9)
# rp: its constants
RP_WT, RP_WY, RP_HMAX, RP_VMAX, RP_AMAX, RP_RMAX, RP_RAMAX, RP_MAXSUB = range(8)
# inp: η̂, ν̂, b̂, τ_allocated, the previous τ, z (3 each), then the target r (3)
IN_ETA, IN_NU, IN_B, IN_TA, IN_TAU, IN_Z, IN_TARGET = 0, 3, 6, 9, 12, 15, 18
# out: τ, z, η̃, ν̃, τ_p, τ_i, τ_d, τ_ff, η_d, η_d', η_d'', ν_d, ν̇_d (3 each)
N_OUT = 39


@njit(cache=True)
def _accel(rs, rp):
    """`ReferenceModel._accel` on the packed state: (a_N, a_E, a_ψ)."""
    hw = 0.5 * rp[RP_WT]
    c0, c1 = hw * (rs[RS_F0] - rs[RS_P0]), hw * (rs[RS_F1] - rs[RS_P1])
    n = math.hypot(c0, c1)
    if n > rp[RP_VMAX]:
        k = rp[RP_VMAX] / n
        c0, c1 = c0 * k, c1 * k
    tw = 2.0 * rp[RP_WT]
    a0, a1 = tw * (c0 - rs[RS_V0]), tw * (c1 - rs[RS_V1])
    n = math.hypot(a0, a1)
    if n > rp[RP_AMAX]:
        k = rp[RP_AMAX] / n
        a0, a1 = a0 * k, a1 * k
    wy = rp[RP_WY]
    r_c = 0.5 * wy * ssa_jit(rs[RS_FPSI] - rs[RS_PSI])
    r_c = max(-rp[RP_RMAX], min(rp[RP_RMAX], r_c))
    ar = 2.0 * wy * (r_c - rs[RS_R])
    ar = max(-rp[RP_RAMAX], min(rp[RP_RAMAX], ar))
    return a0, a1, ar


@njit(cache=True)
def reference_step(rs, rp, target, dt):
    """`ReferenceModel.step(dt)` on the packed state (in place)."""
    if not (math.isfinite(dt) and dt > 0):
        return
    n = int(min(rp[RP_MAXSUB], max(1.0, math.ceil(dt / rp[RP_HMAX] - 1e-9))))
    h = dt / n
    gf_t = 1.0 - math.exp(-rp[RP_WT] * h)
    gf_y = 1.0 - math.exp(-rp[RP_WY] * h)
    for _ in range(n):
        a0, a1, ar = _accel(rs, rp)
        rs[RS_F0] = rs[RS_F0] + gf_t * (target[0] - rs[RS_F0])
        rs[RS_F1] = rs[RS_F1] + gf_t * (target[1] - rs[RS_F1])
        rs[RS_FPSI] = ssa_jit(rs[RS_FPSI] + gf_y * ssa_jit(target[2] - rs[RS_FPSI]))
        rs[RS_P0] = rs[RS_P0] + h * rs[RS_V0] + 0.5 * h * h * a0
        rs[RS_P1] = rs[RS_P1] + h * rs[RS_V1] + 0.5 * h * h * a1
        rs[RS_V0] = rs[RS_V0] + h * a0
        rs[RS_V1] = rs[RS_V1] + h * a1
        rs[RS_PSI] = ssa_jit(rs[RS_PSI] + h * rs[RS_R] + 0.5 * h * h * ar)
        rs[RS_R] = rs[RS_R] + h * ar


@njit(cache=True)
def _mv(mats, m, x0, x1, x2, out, o, sign):
    """out[o:o+3] = sign · mats[m] @ x."""
    for i in range(3):
        out[o + i] = sign * (mats[m, i, 0] * x0 + mats[m, i, 1] * x1 + mats[m, i, 2] * x2)


@njit(cache=True)
def dp_step(rs, rp, inp, dt, use_b, use_ta, saturated, feedforward, mats, dof):
    """One dp-mode step after the first: the reference model advanced by dt, then the control law.
    Returns ``out`` (N_OUT: see the module docstring); ``rs`` is advanced in place."""
    out = np.zeros(N_OUT)
    reference_step(rs, rp, inp[IN_TARGET : IN_TARGET + 3], dt)
    # the reference state (ReferenceModel.state)
    a0, a1, ar = _accel(rs, rp)
    psi_d, r_d = rs[RS_PSI], rs[RS_R]
    cd, sd = math.cos(psi_d), math.sin(psi_d)
    ed0, ed1, ed2 = rs[RS_V0], rs[RS_V1], r_d  # η_d'
    nud0, nud1, nud2 = cd * ed0 + sd * ed1, -sd * ed0 + cd * ed1, ed2  # ν_d = Jᵀ(ψ_d) η_d'
    nudot0 = cd * a0 + sd * a1 + r_d * nud1  # ν̇_d = Jᵀ(ψ_d) η_d'' + r_d [v_d, −u_d, 0]
    nudot1 = -sd * a0 + cd * a1 - r_d * nud0
    nudot2 = ar
    out[24], out[25], out[26] = rs[RS_P0], rs[RS_P1], psi_d
    out[27], out[28], out[29] = ed0, ed1, ed2
    out[30], out[31], out[32] = a0, a1, ar
    out[33], out[34], out[35] = nud0, nud1, nud2
    out[36], out[37], out[38] = nudot0, nudot1, nudot2
    # the control law (DPController._update_dp)
    psi = inp[IN_ETA + 2]
    c, s = math.cos(psi), math.sin(psi)
    e0, e1 = inp[IN_ETA] - rs[RS_P0], inp[IN_ETA + 1] - rs[RS_P1]
    e2 = ssa_jit(inp[IN_ETA + 2] - psi_d)
    # ν̃ = ν̂ − Jᵀ(ψ̂) η_d'
    ne0 = inp[IN_NU] - (c * ed0 + s * ed1)
    ne1 = inp[IN_NU + 1] - (-s * ed0 + c * ed1)
    ne2 = inp[IN_NU + 2] - ed2
    ff = np.zeros(3)
    if feedforward:
        for i in range(3):
            ff[i] = (mats[0, i, 0] * nudot0 + mats[0, i, 1] * nudot1 + mats[0, i, 2] * nudot2) + (
                mats[1, i, 0] * nud0 + mats[1, i, 1] * nud1 + mats[1, i, 2] * nud2
            )
    if use_b:
        b0, b1, b2 = inp[IN_B], inp[IN_B + 1], inp[IN_B + 2]
        ff[0] -= c * b0 + s * b1
        ff[1] -= -s * b0 + c * b1
        ff[2] -= b2
    # τ_p = −Kp Jᵀ(ψ̂) η̃,  τ_d = −Kd ν̃
    _mv(mats, 3, c * e0 + s * e1, -s * e0 + c * e1, e2, out, 12, -1.0)
    _mv(mats, 5, ne0, ne1, ne2, out, 18, -1.0)
    z0, z1, z2 = inp[IN_Z], inp[IN_Z + 1], inp[IN_Z + 2]
    if dt > 0:
        if saturated and use_ta:
            # back-calculation: dw = M⁻¹ (min(dt/Tt, 1) (τ − τ_allocated)), per DOF with integral action
            x = np.empty(3)
            for i in range(3):
                frac = min(dt * dof[2, i], 1.0)
                x[i] = frac * (inp[IN_TAU + i] - inp[IN_TA + i])
            dw = np.empty(3)
            for i in range(3):
                v = mats[2, i, 0] * x[0] + mats[2, i, 1] * x[1] + mats[2, i, 2] * x[2]
                dw[i] = v / dof[0, i] if dof[1, i] > 0 else 0.0
            z0 = z0 + e0 * dt + (c * dw[0] - s * dw[1])
            z1 = z1 + e1 * dt + (s * dw[0] + c * dw[1])
            z2 = z2 + e2 * dt + dw[2]
        elif not saturated:
            z0, z1, z2 = z0 + e0 * dt, z1 + e1 * dt, z2 + e2 * dt
    if dof[1, 0] == 0:
        z0 = 0.0
    if dof[1, 1] == 0:
        z1 = 0.0
    if dof[1, 2] == 0:
        z2 = 0.0
    # τ_i = −Ki Jᵀ(ψ̂) z
    _mv(mats, 4, c * z0 + s * z1, -s * z0 + c * z1, z2, out, 15, -1.0)
    for i in range(3):
        out[21 + i] = ff[i]
        out[i] = out[12 + i] + out[15 + i] + out[18 + i] + ff[i]
    out[3], out[4], out[5] = z0, z1, z2
    out[6], out[7], out[8] = e0, e1, e2
    out[9], out[10], out[11] = ne0, ne1, ne2
    return out
