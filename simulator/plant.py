"""The full low-frequency plant: a 3-DOF nonlinear manoeuvring model, not the observers' model.

    η' = R(ψ) ν
    M ν_r' + C_RB(ν_r) ν_r + C_A(ν_r) ν_r + D ν_r + d(ν_r) + μ = τ_thrusters + τ_wind + τ_drift + Rᵀ(ψ) b

with ν_r = ν − ν_c the velocity relative to the current, M = M_RB + M_A (M_RB + A∞ with fluid memory),
d(ν_r) the blended surge resistance and the cross-flow drag, μ the radiation force of a fluid-memory state
space (optional). The equations, each term's source and its switch are in `simulator.plant_reference`
(the readable numpy form) and docs/simulator.md; `simulator._plant_kernel` is the compiled RK4 the
simulator runs, tested equal to the reference.

Same interface as `simulator.vessel_dynamics.VesselDynamics` (``x``, ``eta``, ``nu``, ``step``) plus the
current (NED velocity, held over a step) and the radiation states (``x[6:]``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import ssa_scalar
from observers.vessel import VesselModel
from simulator._plant_kernel import derivative_into, rk4_steps
from simulator.plant_params import DEFAULT_OPTIONS, PlantOptions, PlantParams

Array = NDArray[np.float64]
MAX_STEP_S = 0.05


class FullPlant:
    """State x = [N, E, ψ, u, v, r, x_r…]: the low-frequency motion and the radiation states."""

    def __init__(
        self,
        vessel: VesselModel,
        eta0: ArrayLike = (0.0, 0.0, 0.0),
        nu0: ArrayLike = (0.0, 0.0, 0.0),
        options: PlantOptions = DEFAULT_OPTIONS,
    ) -> None:
        self.vessel = vessel
        self.options = options
        self.params = p = PlantParams.build(vessel, options)
        self.x = np.zeros(6 + p.n_radiation)
        self.x[0:3] = np.asarray(eta0, dtype=float)
        self.x[3:6] = np.asarray(nu0, dtype=float)
        self.x[2] = ssa_scalar(self.x[2])
        flags = (p.coriolis, p.surge, p.crossflow, p.ca_absolute)
        self._s = np.array([p.m, p.x_g, p.Xu, p.Xuu, p.u_cross, p.cf_k, p.length, *(float(f) for f in flags)])
        c = np.ascontiguousarray
        self._arrays = (c(p.Minv), c(p.D), c(p.MA), c(p.rA), c(p.rB), c(p.rC), c(p.rD))
        self._zero_current = np.zeros(2)
        self._load_buffers = (np.empty_like(self.x), np.empty_like(self.x), np.zeros(3))

    @property
    def eta(self) -> Array:
        return self.x[0:3].copy()

    @property
    def nu(self) -> Array:
        return self.x[3:6].copy()

    def step(
        self,
        h: float,
        tau_body: ArrayLike,
        bias_earth: ArrayLike = (0.0, 0.0, 0.0),
        current_ned: ArrayLike | None = None,
    ) -> None:
        """Advance by h seconds (RK4 steps of at most 0.05 s) with the forces and the current held."""
        n = max(1, math.ceil(h / MAX_STEP_S - 1e-9))
        tau = np.asarray(tau_body, dtype=float)
        b = np.asarray(bias_earth, dtype=float)
        vc = self._zero_current if current_ned is None else np.asarray(current_ned, dtype=float)
        rk4_steps(self.x, h / n, n, tau, b, vc, self._s, *self._arrays)

    def current_load(self, current_ned: ArrayLike) -> Array:
        """The hydrodynamic force [X, Y, N] (body frame) on the vessel held still at its heading in the
        current: what a feed-forward of the mean current load must cancel."""
        xt, out, zero = self._load_buffers  # (no allocation per control tick: it runs at 10 Hz)
        xt[:] = self.x
        xt[3:] = 0.0
        vc = current_ned if isinstance(current_ned, np.ndarray) else np.asarray(current_ned, dtype=float)
        derivative_into(xt, zero, zero, vc, self._s, *self._arrays, out)
        return np.asarray(self.params.M @ out[3:6])
