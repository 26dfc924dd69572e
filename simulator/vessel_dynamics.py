"""Low-frequency 3-DOF vessel dynamics for the simulator (the plant, not the observer's model).

    η' = J(ψ) ν                                                   Fossen & Strand (1999) eq (1)
    M ν' + D ν = τ_thrusters + Jᵀ(ψ) b + τ_drift                  eq (3), plus mean wave drift (body frame)

integrated by classical RK4 with a fixed internal step (≤ 0.05 s), the forces held over each
step. ψ is kept in [-π, π). The wave-frequency motion is added on top by the sensors' caller
(`simulator.waves`), never fed back: the LF/WF superposition of the paper's Sec. 2.4.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import ssa_jit, ssa_scalar
from observers.vessel import VesselModel

Array = NDArray[np.float64]
MAX_STEP_S = 0.05


@njit(cache=True)
def _derivative(x, force_body, Minv, D, out):
    psi = x[2]
    c = math.cos(psi)
    s = math.sin(psi)
    u, v, r = x[3], x[4], x[5]
    out[0] = c * u - s * v
    out[1] = s * u + c * v
    out[2] = r
    f0 = force_body[0] - (D[0, 0] * u + D[0, 1] * v + D[0, 2] * r)
    f1 = force_body[1] - (D[1, 0] * u + D[1, 1] * v + D[1, 2] * r)
    f2 = force_body[2] - (D[2, 0] * u + D[2, 1] * v + D[2, 2] * r)
    for i in range(3):
        out[3 + i] = Minv[i, 0] * f0 + Minv[i, 1] * f1 + Minv[i, 2] * f2


@njit(cache=True)
def _rk4(x, h, tau_body, b_earth, Minv, D):
    """One RK4 step. The earth-fixed bias is rotated into the body frame at each stage (it is Jᵀ(ψ) b)."""
    k = np.empty((4, 6))
    xt = np.empty(6)
    f = np.empty(3)
    for stage in range(4):
        if stage == 0:
            for j in range(6):
                xt[j] = x[j]
        else:
            w = h if stage == 3 else 0.5 * h
            for j in range(6):
                xt[j] = x[j] + w * k[stage - 1, j]
        c = math.cos(xt[2])
        s = math.sin(xt[2])
        f[0] = tau_body[0] + c * b_earth[0] + s * b_earth[1]
        f[1] = tau_body[1] - s * b_earth[0] + c * b_earth[1]
        f[2] = tau_body[2] + b_earth[2]
        _derivative(xt, f, Minv, D, k[stage])
    for j in range(6):
        x[j] += h / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
    x[2] = ssa_jit(x[2])


class VesselDynamics:
    """State x = [N, E, ψ, u, v, r] of the low-frequency motion."""

    def __init__(
        self, vessel: VesselModel, eta0: ArrayLike = (0.0, 0.0, 0.0), nu0: ArrayLike = (0.0, 0.0, 0.0)
    ):
        self.vessel = vessel
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._D = np.ascontiguousarray(vessel.D, dtype=float)
        self.x = np.zeros(6)
        self.x[0:3] = np.asarray(eta0, dtype=float)
        self.x[3:6] = np.asarray(nu0, dtype=float)
        self.x[2] = ssa_scalar(self.x[2])

    @property
    def eta(self) -> Array:
        return self.x[0:3].copy()

    @property
    def nu(self) -> Array:
        return self.x[3:6].copy()

    def step(self, h: float, tau_body: ArrayLike, bias_earth: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Advance by h seconds (split into RK4 steps of at most 0.05 s) with the forces held."""
        n = max(1, math.ceil(h / MAX_STEP_S - 1e-9))
        tau = np.asarray(tau_body, dtype=float)
        b = np.asarray(bias_earth, dtype=float)
        for _ in range(n):
            _rk4(self.x, h / n, tau, b, self._Minv, self._D)
