"""Ocean current: speed and direction as first-order Gauss–Markov processes with limits.

    V_c' = −V_c/T + w,      β_c' = −β_c/T + w                       Fossen (2021) Sec. 10.3 (eq (10.63))

each about its mean, simulated exactly in discrete time (Ornstein–Uhlenbeck: over a step h,
x ← e^{−h/T} x + σ √(1 − e^{−2h/T}) ν) and held inside its limits (a saturating integrator: the process
stops at a limit and leaves it only inwards), as Fossen's current model keeps V_min ≤ V_c ≤ V_max.
The direction is where the current flows *towards*, clockwise from north; the current is irrotational and
uniform, its NED velocity held over each plant step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CurrentModel:
    speed_mps: float = 0.0
    direction_deg: float = 0.0  # flows towards, from north
    speed_sigma_mps: float = 0.0  # stationary std of the slowly varying part
    direction_sigma_deg: float = 0.0
    time_constant_s: float = 900.0
    speed_limits_mps: tuple[float, float] = (0.0, math.inf)
    direction_limits_deg: tuple[float, float] = (-math.inf, math.inf)  # absolute, not about the mean

    def __post_init__(self) -> None:
        checks = {
            "speed_mps": self.speed_mps >= 0,
            "speed_sigma_mps": self.speed_sigma_mps >= 0,
            "direction_sigma_deg": self.direction_sigma_deg >= 0,
            "time_constant_s": self.time_constant_s > 0,
            "speed_limits_mps": 0 <= self.speed_limits_mps[0] <= self.speed_mps <= self.speed_limits_mps[1],
            "direction_limits_deg": self.direction_limits_deg[0]
            <= self.direction_deg
            <= self.direction_limits_deg[1],
        }
        for key, ok in checks.items():
            if not ok:
                raise ValueError(f"current: field '{key}' out of range ({getattr(self, key)!r})")


class Current:
    """The current's state: speed and direction now. ``velocity_ned`` is [V_N, V_E] (m/s)."""

    def __init__(self, model: CurrentModel, rng: np.random.Generator) -> None:
        self.model = model
        self.rng = rng
        self.speed = model.speed_mps
        self.direction_deg = model.direction_deg
        self._h = math.nan
        self._decay = 1.0
        self._velocity = np.zeros(2)
        self._update_velocity()
        self._normals: list[list[float]] = []  # drawn in blocks: one generator call per 1024 steps
        self._k = 0

    def _update_velocity(self) -> None:
        b = math.radians(self.direction_deg)
        self._velocity = np.array([self.speed * math.cos(b), self.speed * math.sin(b)])

    def step(self, h: float) -> None:
        m = self.model
        if m.speed_sigma_mps == 0.0 and m.direction_sigma_deg == 0.0:
            return
        if h != self._h:
            self._h = h
            self._decay = math.exp(-h / m.time_constant_s)
            self._kick = math.sqrt(1.0 - self._decay**2)
        if self._k == len(self._normals):
            self._normals = self.rng.standard_normal((1024, 2)).tolist()
            self._k = 0
        w = self._normals[self._k]
        self._k += 1
        speed = m.speed_mps + self._decay * (self.speed - m.speed_mps) + m.speed_sigma_mps * self._kick * w[0]
        direction = (
            m.direction_deg
            + self._decay * (self.direction_deg - m.direction_deg)
            + m.direction_sigma_deg * self._kick * w[1]
        )
        self.speed = min(max(speed, m.speed_limits_mps[0]), m.speed_limits_mps[1])
        self.direction_deg = min(max(direction, m.direction_limits_deg[0]), m.direction_limits_deg[1])
        self._update_velocity()

    def set(self, speed_mps: float, direction_deg: float) -> None:
        """Impose the current (recorded inputs)."""
        self.speed, self.direction_deg = speed_mps, direction_deg
        self._update_velocity()

    @property
    def velocity_ned(self) -> Array:
        return self._velocity
