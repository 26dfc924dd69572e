"""What the full plant adds around the scenario's loads: the current it moves in and the wind force.

One object per run so the time loop (`simulator.runner`) only asks two things each plant step: the
current's NED velocity and the wind's body-frame force. Each has its own random stream, drawn from the
run's seed after the existing ones, so adding them changes none of the other streams.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from observers.hull import AIR_DENSITY
from observers.vessel import VesselModel
from simulator._full_advance_kernel import wind_force_into
from simulator.current import Current, CurrentModel
from simulator.wind import Wind, WindModel

Array = NDArray[np.float64]
CURRENT_STEP_S = 1.0
WIND_STEP_S = 0.25


class PlantEnvironment:
    def __init__(
        self,
        vessel: VesselModel,
        current: CurrentModel | None,
        wind: WindModel | None,
        seed: np.random.SeedSequence,
    ) -> None:
        current_seq, wind_seq = seed.spawn(2)
        self.current = Current(current, np.random.default_rng(current_seq)) if current is not None else None
        self.wind: Wind | None = None
        if wind is not None:
            if vessel.hull is None or vessel.hull.wind is None:
                raise ValueError(
                    f"vessel '{vessel.name}': wind needs the vessel's wind areas, field 'hull.wind' "
                    "(docs/vessels.md)"
                )
            self.wind = Wind(wind, vessel.hull.wind, vessel.length_m, np.random.default_rng(wind_seq))
        self.wind_body = np.zeros(3)
        self._no_current = np.zeros(2)
        # [time since the current was last advanced, time since the wind force was last computed]
        self.due = np.array([0.0, math.inf])
        # for the compiled advance (`simulator._full_advance_kernel`): the thresholds `step` compares with,
        # and the wind's constants and NED velocity (`wind_parameters`)
        self.due_thresholds = np.array([CURRENT_STEP_S - 1e-9, WIND_STEP_S - 1e-9])
        self.wind_p = np.zeros(9)
        self._mean_wind_p = self.wind_p.copy()
        self._mean_wind_x = np.zeros(5)
        if self.wind is not None:
            towards = math.radians(self.wind.model.from_deg + 180.0)  # as `simulator.wind.wind_force`
            self._towards_cos, self._towards_sin = math.cos(towards), math.sin(towards)
            a = self.wind.area
            self.wind_p[:7] = (0.5 * AIR_DENSITY, a.cx, a.cy, a.cn, a.frontal_area_m2, a.lateral_area_m2,
                               self.wind.length_m)  # fmt: skip
            mean = self.wind.mean
            self._mean_wind_p[:] = self.wind_p
            self._mean_wind_p[7:] = (mean * self._towards_cos, mean * self._towards_sin)

    def step(self, h: float, t: float, x: Array) -> None:
        """Advance by h from time t with the vessel in state x.

        The current moves once a second (exactly, over the elapsed time: its time constant is minutes) and the
        wind force is recomputed every 0.25 s (the gust series' grid; it has nothing above 0.2 Hz), held in
        between: per plant step both would cost more than the plant itself for no difference in the motion.
        """
        due = self.due
        if self.current is not None:
            due[0] += h
            if due[0] >= CURRENT_STEP_S - 1e-9:
                self.step_current()
        if self.wind is not None:
            due[1] += h
            if due[1] >= WIND_STEP_S - 1e-9:
                self.wind_body[:] = self.wind.force_body(t, float(x[2]), float(x[3]), float(x[4]))
                due[1] = 0.0

    def step_current(self) -> None:
        """Move the current over the time accumulated since it last moved."""
        assert self.current is not None
        self.current.step(float(self.due[0]))
        self.due[0] = 0.0

    def wind_parameters(self, t: float, until_due: float) -> None:
        """Fill ``wind_p`` = [½ρ_a, c_x, c_y, c_n, A_F, A_L, L, wn, we] for the wind at time t, for the
        compiled advance: the constants of `simulator.wind.wind_force` and the wind's NED velocity (wn, we),
        computed as it computes them. Nothing without wind, nor when the force cannot fall due within
        ``until_due`` s (a margin of 1e-7 s over the rounding of the substeps' sum: wn, we go unread)."""
        wind = self.wind
        if wind is None or self.due[1] + until_due < WIND_STEP_S - 1e-7:
            return
        speed = wind.speed(t)
        self.wind_p[7] = speed * self._towards_cos
        self.wind_p[8] = speed * self._towards_sin

    @property
    def current_ned(self) -> Array:
        return self.current.velocity_ned if self.current is not None else self._no_current

    def mean_wind_body(self, psi: float) -> Array:
        """The mean wind's force on the vessel at rest (body frame); zero without wind.

        `Wind.mean_force_body` through the compiled wind force of the plant's advance: the same bits
        (tests/test_simulator.py), half the time, at every control tick."""
        if self.wind is None:
            return np.zeros(3)
        x = self._mean_wind_x
        x[2] = psi
        out = np.empty(3)
        wind_force_into(x, self._mean_wind_p, out)
        return out
