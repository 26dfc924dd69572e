"""Fluid memory of the plant: the radiation convolution of the Cummins equation as a state space.

Cummins (1962); Perez & Fossen (2008); Hajivand & Mousavizadegan (2010) eqs (2)-(7). In the body frame
(surge, sway, yaw; ν = [u, v, r] in m/s and rad/s, forces [X, Y, N] in N and N m) the radiation force is

    τ_rad = -A(∞) ν' - μ,        μ(t) = ∫₀ᵗ K(t - τ) ν(τ) dτ,
    K(t) = (2/π) ∫₀^∞ B(ω) cos(ωt) dω                                          (Perez & Fossen eq (5))

and the convolution is replaced by the identified state space (`observers.radiation.identify`):

    x_r' = A_r x_r + B_r ν,      μ = C_r x_r + D_r ν                           (eq (7))

so that the plant reads (M_RB + A(∞)) ν' + ... + μ = τ + ...; the memory is driven by the velocity
relative to the water (radiation is the wave field the hull makes by moving through the water, so a
current that carries hull and water together makes none). A plant integrates x_r in its own RK4 state
(`simulator._fluid_memory_kernel.memory_derivative`, `memory_force`) or steps it alone with
`CumminsMemory`, which is exact for ν linear over a step.

`RadiationStateSpace` (`observers.radiation`: one object for the plant and the fluid-memory observer) is
what a plant takes; `simulator.fluid_memory_cache` loads it for a vessel
(identified once and stored, never at a simulator's start); `simulator.fluid_memory_energy` holds the
checks that it only dissipates.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.radiation import RadiationStateSpace, RadiationStateSpaceError
from simulator._fluid_memory_kernel import memory_step

__all__ = ["CumminsMemory", "FluidMemoryError", "RadiationStateSpace"]

Array = NDArray[np.floating[Any]]


FluidMemoryError = RadiationStateSpaceError
"""A fluid-memory model that cannot be used — its matrices (checked by `RadiationStateSpace` itself) or its
file (`simulator.fluid_memory_cache`): one error, whose message names where the model came from and why."""


class CumminsMemory:
    """The memory states of one vessel stepped on their own: x_r' = A_r x_r + B_r ν, μ = C_r x_r + D_r ν.

    `step` advances exactly for ν linear over the step (constant if ``nu1`` is not given) with a compiled
    kernel; the discretisation is computed once per step size."""

    def __init__(self, model: RadiationStateSpace, x0: ArrayLike | None = None) -> None:
        self.model = model
        self._C = np.ascontiguousarray(model.Cr)
        self._D = np.ascontiguousarray(model.Dr)
        self.x = np.zeros(model.n_states) if x0 is None else np.array(x0, dtype=float)
        if self.x.shape != (model.n_states,):
            raise FluidMemoryError(f"x0 has shape {self.x.shape}, expected ({model.n_states},)")
        self._next = np.empty_like(self.x)

    def reset(self) -> None:
        self.x[:] = 0.0

    def force(self, nu: ArrayLike) -> Array:
        """μ = C_r x_r + D_r ν for the current state (N, N, N m); the plant applies -μ."""
        return self._C @ self.x + self._D @ np.asarray(nu, dtype=float)

    def derivative(self, x: ArrayLike, nu: ArrayLike) -> Array:
        """A_r x + B_r ν (numpy; a compiled plant calls `memory_derivative` instead)."""
        return self.model.Ar @ np.asarray(x, dtype=float) + self.model.Br @ np.asarray(nu, dtype=float)

    def step(self, h: float, nu0: ArrayLike, nu1: ArrayLike | None = None) -> Array:
        """Advance by h s with ν going linearly from ``nu0`` to ``nu1`` (held at ``nu0`` if None); return μ
        at the end of the step."""
        phi, g0, g1 = self.model.discretise(h)
        a = np.ascontiguousarray(nu0, dtype=float)
        b = a if nu1 is None else np.ascontiguousarray(nu1, dtype=float)
        memory_step(self.x, a, b, phi, g0, g1, self._next)
        self.x, self._next = self._next, self.x
        return self.force(b)

    def run(self, h: float, nu: ArrayLike) -> Array:
        """μ at every sample of ν (N, 3) sampled every h s, ν linear between samples, from the current state
        (μ[0] is the current force). Returns (N, 3)."""
        nu = np.asarray(nu, dtype=float)
        out = np.empty_like(nu)
        out[0] = self.force(nu[0])
        for k in range(1, len(nu)):
            out[k] = self.step(h, nu[k - 1], nu[k])
        return out
