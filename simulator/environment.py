"""Slowly varying environmental force: the bias of Fossen & Strand (1999) eq (7), plus steady forces.

    b' = -T⁻¹ b + Ψ n                                              (7), earth-fixed, n white, unit intensity

simulated exactly in discrete time (an Ornstein–Uhlenbeck process): over a step h,
b ← e^{-h/T} b + σ √(1 − e^{-2h/T}) ν,  ν ~ N(0, I), where σ = Ψ √(T/2) is the stationary standard
deviation. A constant earth-fixed current/wind force is added on top; wave drift comes from
`simulator.waves` (body frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import NDArray

Array = NDArray[np.float64]


@mypyc_attr(native_class=False)  # (mypyc: a scenario's value, read once; kept a Python class)
@dataclass(frozen=True)
class BiasModel:
    """Markov bias: stationary std σ per DOF (N, N, N·m), time constants T (s), a constant force (NED)."""

    sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)
    time_constant_s: tuple[float, float, float] = (1000.0, 1000.0, 1000.0)
    constant: tuple[float, float, float] = (0.0, 0.0, 0.0)


class MarkovBias:
    def __init__(self, model: BiasModel, rng: np.random.Generator, start_stationary: bool = True) -> None:
        self.model = model
        self.rng = rng
        self.sigma = np.asarray(model.sigma, dtype=float)
        self.T = np.asarray(model.time_constant_s, dtype=float)
        if np.any(self.sigma < 0) or np.any(self.T <= 0):
            raise ValueError("bias: sigma must be >= 0 and time constants > 0")
        self.b = self.sigma * rng.standard_normal(3) if start_stationary else np.zeros(3)
        self._factors: dict[float, tuple[Array, Array]] = {}
        self._normals = np.empty((0, 3))  # drawn in blocks: one generator call per 1024 steps, not per step
        self._k = 0
        self.constant = np.asarray(model.constant, dtype=float)

    def step(self, h: float) -> None:
        decay, kick = self.factors(h)
        normals, k = self.draws()
        self.b = decay * self.b + kick * normals[k]
        self._k = k + 1

    def factors(self, h: float) -> tuple[Array, Array]:
        """e^{-h/T} and σ√(1 − e^{-2h/T}) for a step h. The runner's substeps take a few dozen distinct
        values (event times minus sums of steps): each one's factors are computed once."""
        known = self._factors.get(h)
        if known is None:
            if len(self._factors) > 256:
                self._factors.clear()
            decay = np.exp(-h / self.T)
            known = self._factors[h] = (decay, self.sigma * np.sqrt(1.0 - decay**2))
        return known

    def refill(self) -> None:
        """The next block of normal draws (one generator call per 1024 steps); `step` reads row k of it."""
        self._normals = self.rng.standard_normal((1024, 3))
        self._k = 0

    def draws(self) -> tuple[Array, int]:
        """(the block of normal draws, the next row to use), refilled first when used up: for a compiled
        caller (`simulator._advance_kernel`) that steps b itself; it reports the rows it took with
        `took`. The draws are the ones `step` would have used, in the same order."""
        if self._k == len(self._normals):
            self.refill()
        return self._normals, self._k

    def took(self, k: int) -> None:
        """The caller of `draws` has used the rows up to (not including) k."""
        self._k = k

    @property
    def force(self) -> Array:
        """Total slowly varying earth-fixed force: Markov part plus the constant current/wind force."""
        return self.b + self.constant
