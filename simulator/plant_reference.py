"""The full plant's equations written plainly in numpy: the reference the compiled kernel is tested against.

State x = [N, E, ψ, u, v, r, x_r…] (x_r the radiation states, if any). With ν_r = ν − ν_c, the current
ν_c = Rᵀ(ψ) V_c (V_c constant in NED over a step) and Fossen (2021) eqs (6.111)–(6.116), 3 DOF:

    η' = R(ψ) ν
    M ν_r' + C_RB(ν_r) ν_r + C_A(ν_r) ν_r + D ν_r + d(ν_r) + μ = τ + Rᵀ(ψ) b
    ν' = ν_c' + ν_r',      ν_c' = −S(ω) ν_c = [r v_c, −r u_c, 0]

C_RB in its linear-velocity-independent form (Fossen 2021 eq (3.63), 3 DOF, y_g = 0) — the form for which
M_RB ν' + C_RB(ν) ν = M_RB ν_r' + C_RB(ν_r) ν_r holds for an irrotational current (Property 10.1):

    C_RB ν_r = [−m r v_r − m x_g r², m r u_r, m x_g r u_r]

C_A(ν_r) the skew form of eq (6.51) from M_A (a = M_A ν_r; a = M_A ν with the option that reproduces osv.m):

    C_A ν_r = [−a₂ r, a₁ r, a₂ u_r − a₁ v_r]

d(ν_r): the blended surge resistance X = −σ X_u u_r − (1 − σ) X_|u|u |u_r| u_r, σ = 1 − tanh(|u_r|/u_c)
(Fossen 2021 eq (6.98)–(6.99)) and the cross-flow drag (`simulator.crossflow`). μ = C x_r + D_r ν_r and
x_r' = A x_r + B ν_r: the radiation force of the Cummins equation in state space, when given.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from simulator.crossflow import crossflow
from simulator.plant_params import PlantParams

Array = NDArray[np.float64]


def derivative(x: Array, tau_body: Array, bias_earth: Array, current_ned: Array, p: PlantParams) -> Array:
    psi = x[2]
    c, s = math.cos(psi), math.sin(psi)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    nu = x[3:6]
    r = nu[2]
    nu_c = R.T @ np.array([current_ned[0], current_ned[1], 0.0])
    nu_c_dot = np.array([r * nu_c[1], -r * nu_c[0], 0.0])
    nu_r = nu - nu_c
    u_r, v_r = nu_r[0], nu_r[1]

    force = tau_body + R.T @ bias_earth - p.D @ nu_r
    if p.coriolis:
        crb = np.array([-p.m * r * v_r - p.m * p.x_g * r * r, p.m * r * u_r, p.m * p.x_g * r * u_r])
        a = p.MA @ (nu if p.ca_absolute else nu_r)
        ca = np.array([-a[1] * r, a[0] * r, a[1] * u_r - a[0] * v_r])
        force -= crb + ca
    if p.surge:
        sigma = 1.0 - math.tanh(abs(u_r) / p.u_cross)
        force[0] -= sigma * p.Xu * u_r + (1.0 - sigma) * p.Xuu * abs(u_r) * u_r
    if p.crossflow:
        Y, N = crossflow(v_r, r, p.cf_k, p.length)
        force[1] += Y
        force[2] += N
    xr = x[6:]
    out = np.empty_like(x)
    if p.n_radiation:
        force -= p.rC @ xr + p.rD @ nu_r
        out[6:] = p.rA @ xr + p.rB @ nu_r
    out[0:3] = R @ nu
    out[3:6] = nu_c_dot + p.Minv @ force
    return out


def rk4_step(
    x: Array, h: float, tau_body: Array, bias_earth: Array, current_ned: Array, p: PlantParams
) -> Array:
    """One classical RK4 step with the inputs held; ψ wrapped to [−π, π) afterwards."""
    k1 = derivative(x, tau_body, bias_earth, current_ned, p)
    k2 = derivative(x + 0.5 * h * k1, tau_body, bias_earth, current_ned, p)
    k3 = derivative(x + 0.5 * h * k2, tau_body, bias_earth, current_ned, p)
    k4 = derivative(x + h * k3, tau_body, bias_earth, current_ned, p)
    out = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    out[2] = (out[2] + math.pi) % (2 * math.pi) - math.pi
    return out
