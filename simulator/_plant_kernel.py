"""Compiled RK4 of the full plant: the same equations as `simulator.plant_reference`, written out in loops.

Tested to agree with the reference to 1e-9 (tests/test_plant.py). Scalars travel in one array ``s``:
[m, x_g, X_u, X_|u|u, u_cross, cf_k, L, coriolis, surge, crossflow, C_A at ν instead of ν_r].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.kinematics import ssa_jit

S_M, S_XG, S_XU, S_XUU, S_UC, S_CFK, S_L, S_COR, S_SURGE, S_CF, S_CA_ABS = range(11)


@njit(cache=True)
def _derivative(x, tau, b_earth, vc_ned, s, Minv, D, MA, rA, rB, rC, rD, out):
    psi = x[2]
    c = math.cos(psi)
    sn = math.sin(psi)
    u, v, r = x[3], x[4], x[5]
    out[0] = c * u - sn * v
    out[1] = sn * u + c * v
    out[2] = r
    uc = c * vc_ned[0] + sn * vc_ned[1]
    vc = -sn * vc_ned[0] + c * vc_ned[1]
    ur = u - uc
    vr = v - vc
    f0 = tau[0] + c * b_earth[0] + sn * b_earth[1] - (D[0, 0] * ur + D[0, 1] * vr + D[0, 2] * r)
    f1 = tau[1] - sn * b_earth[0] + c * b_earth[1] - (D[1, 0] * ur + D[1, 1] * vr + D[1, 2] * r)
    f2 = tau[2] + b_earth[2] - (D[2, 0] * ur + D[2, 1] * vr + D[2, 2] * r)
    if s[S_COR] != 0.0:
        m = s[S_M]
        mxg = m * s[S_XG]
        ua, va = (u, v) if s[S_CA_ABS] != 0.0 else (ur, vr)
        a0 = MA[0, 0] * ua + MA[0, 1] * va + MA[0, 2] * r
        a1 = MA[1, 0] * ua + MA[1, 1] * va + MA[1, 2] * r
        f0 -= -m * r * vr - mxg * r * r - a1 * r
        f1 -= m * r * ur + a0 * r
        f2 -= mxg * r * ur + a1 * ur - a0 * vr
    if s[S_SURGE] != 0.0:
        sigma = 1.0 - math.tanh(abs(ur) / s[S_UC])
        f0 -= sigma * s[S_XU] * ur + (1.0 - sigma) * s[S_XUU] * abs(ur) * ur
    if s[S_CF] != 0.0:
        L = s[S_L]
        if abs(r) * L / 2.0 <= abs(vr):  # |w|w = sgn(v_r) w² along the whole hull
            sgn = 1.0 if vr >= 0.0 else -1.0
            i0 = sgn * (vr * vr * L + r * r * L * L * L / 12.0)
            i1 = sgn * vr * r * L * L * L / 6.0
        else:
            wp = vr + r * L / 2.0
            wm = vr - r * L / 2.0
            q2 = abs(wp) * wp * wp - abs(wm) * wm * wm
            q3 = abs(wp) * wp * wp * wp - abs(wm) * wm * wm * wm
            i0 = q2 / (3.0 * r)
            i1 = (q3 / 4.0 - vr * q2 / 3.0) / (r * r)
        f1 -= s[S_CFK] * i0
        f2 -= s[S_CFK] * i1
    nr = rA.shape[0]
    for i in range(nr):
        f0 -= rC[0, i] * x[6 + i]
        f1 -= rC[1, i] * x[6 + i]
        f2 -= rC[2, i] * x[6 + i]
        acc = rB[i, 0] * ur + rB[i, 1] * vr + rB[i, 2] * r
        for j in range(nr):
            acc += rA[i, j] * x[6 + j]
        out[6 + i] = acc
    if nr > 0:
        f0 -= rD[0, 0] * ur + rD[0, 1] * vr + rD[0, 2] * r
        f1 -= rD[1, 0] * ur + rD[1, 1] * vr + rD[1, 2] * r
        f2 -= rD[2, 0] * ur + rD[2, 1] * vr + rD[2, 2] * r
    out[3] = r * vc + Minv[0, 0] * f0 + Minv[0, 1] * f1 + Minv[0, 2] * f2
    out[4] = -r * uc + Minv[1, 0] * f0 + Minv[1, 1] * f1 + Minv[1, 2] * f2
    out[5] = Minv[2, 0] * f0 + Minv[2, 1] * f1 + Minv[2, 2] * f2


derivative_into = _derivative  # the state derivative alone (the plant's mean current load)


@njit(cache=True)
def rk4_steps(x, h, n, tau, b_earth, vc_ned, s, Minv, D, MA, rA, rB, rC, rD):
    """n RK4 steps of h seconds with the inputs held; ψ wrapped to [−π, π) after each."""
    dim = x.shape[0]
    k = np.empty((4, dim))
    xt = np.empty(dim)
    for _ in range(n):
        for stage in range(4):
            if stage == 0:
                for j in range(dim):
                    xt[j] = x[j]
            else:
                w = h if stage == 3 else 0.5 * h
                for j in range(dim):
                    xt[j] = x[j] + w * k[stage - 1, j]
            _derivative(xt, tau, b_earth, vc_ned, s, Minv, D, MA, rA, rB, rC, rD, k[stage])
        for j in range(dim):
            x[j] += h / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
        x[2] = ssa_jit(x[2])
