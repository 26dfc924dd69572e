"""Thruster dynamics: what the thrusters actually deliver, and the generalised force it makes.

Per thruster: thrust follows its setpoint with a first-order lag (time constant), clipped to
[min_thrust_n, max_thrust_n]; an azimuth turns towards its setpoint at most at its slew rate, by the
shorter way round. The generalised force is τ = B_u(α) u through the configuration matrix
(`VesselModel.configuration_matrix`). A failed thruster delivers no thrust and holds its angle.
RPM is reported from the propeller law T = K n|n| with K set so max thrust is reached at each thruster's
``max_rpm`` (the vessel file's, the law the gateway reads the feedback with).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import ssa, ssa_scalar
from observers.vessel import VesselModel
from simulator._thruster_kernel import thruster_step, thruster_tau

Array = NDArray[np.float64]
DEFAULT_MAX_RPM = 200.0


class ThrusterBank:
    def __init__(self, vessel: VesselModel, max_rpm: float | None = None) -> None:
        self.vessel = vessel
        th = vessel.thrusters
        self.ids = [t.id for t in th]
        self.n = len(th)
        self.is_azimuth = np.array([t.kind == "azimuth" for t in th], dtype=bool)
        self._azimuth = self.is_azimuth.tolist()  # (lists: one element of an array costs more to read)
        self.max_thrust = np.array([t.max_thrust_n for t in th], dtype=float)
        self.min_thrust = np.array([t.min_thrust_n for t in th], dtype=float)
        self._min_thrust, self._max_thrust = self.min_thrust.tolist(), self.max_thrust.tolist()
        self.rate = np.array([t.azimuth_rate_rad_s for t in th], dtype=float)
        self.time_constant = np.array([max(t.thrust_time_constant_s, 1e-6) for t in th], dtype=float)
        self.fixed_angle = np.array([t.angle_rad for t in th], dtype=float)
        # each thruster's own propeller law, as the gateway reads it (a single 200 rpm for all would report
        # a 140 rpm tunnel at 200 rpm and have its feedback rejected as out of range)
        rpm_max = np.array([t.max_rpm if max_rpm is None else max_rpm for t in th], dtype=float)
        self.k_prop = self.max_thrust / rpm_max**2
        self.x = np.array([t.x_m for t in th], dtype=float)
        self.y = np.array([t.y_m for t in th], dtype=float)
        self.thrust = np.zeros(self.n)
        self.angle = self.fixed_angle.copy()
        self.thrust_setpoint = np.zeros(self.n)
        self.angle_setpoint = self.fixed_angle.copy()
        self.failed = np.zeros(self.n, dtype=bool)

    def index(self, thruster_id: int) -> int:
        return self.ids.index(thruster_id)

    def command(self, thrust_n: ArrayLike, angle_rad: ArrayLike | None = None) -> None:
        """Set every thruster's setpoint (layout order). Angles of fixed thrusters are ignored."""
        self.thrust_setpoint = np.clip(np.asarray(thrust_n, dtype=float), self.min_thrust, self.max_thrust)
        if angle_rad is not None:
            a = np.asarray(angle_rad, dtype=float)
            if a.shape == self.fixed_angle.shape:  # (ssa_scalar is ssa bit for bit, cheaper for a few)
                fixed = self.fixed_angle.tolist()
                self.angle_setpoint = np.array(
                    [
                        ssa_scalar(v) if az else f
                        for v, az, f in zip(a.tolist(), self._azimuth, fixed, strict=True)
                    ]
                )
            else:
                self.angle_setpoint = np.where(self.is_azimuth, ssa(a), self.fixed_angle)

    def command_one(self, thruster_id: int, thrust_n: float, angle_rad: float | None = None) -> None:
        i = self.index(thruster_id)
        self.thrust_setpoint[i] = min(max(thrust_n, self._min_thrust[i]), self._max_thrust[i])
        if angle_rad is not None and self._azimuth[i]:
            self.angle_setpoint[i] = ssa_scalar(float(angle_rad))  # (= ssa, bit for bit; no array)

    def step(self, h: float) -> None:
        thruster_step(h, self.thrust, self.angle, self.thrust_setpoint, self.angle_setpoint, self.failed,
              self.is_azimuth, self.time_constant, self.rate)  # fmt: skip

    @property
    def tau(self) -> Array:
        """Generalised force [X, Y, N] in the body frame from the actual thrusts and angles.

        Same as ``vessel.generalized_force(thrust, angle)`` (the configuration matrix, tested equal),
        written out because it runs at every plant step.
        """
        return thruster_tau(self.thrust, self.angle, self.x, self.y)

    @property
    def rpm(self) -> Array:
        return np.sign(self.thrust) * np.sqrt(np.abs(self.thrust) / self.k_prop)

    @property
    def power_w(self) -> Array:
        """Rough shaft power, P ∝ |T|^1.5 (momentum theory), scaled to 1 kW per 10 kN^1.5 at max."""
        return 1e3 * (np.abs(self.thrust) / 1e4) ** 1.5


class PrescribedAllocation:
    """Thrust and angle per thruster that produce τ, for scenarios with a prescribed τ.

    The minimum-norm solution of the extended configuration (an azimuth contributes free F_x and F_y,
    a tunnel F_y, a main propeller F_x); azimuth angle = atan2(F_y, F_x), thrust = norm. This is the
    scenario's stand-in for a DP system's allocation until the gateway commands the thrusters; it
    ignores limits on purpose (the thruster model enforces them). The extended matrix does not depend on
    the angles, so its pseudo-inverse is computed once.
    """

    def __init__(self, vessel: VesselModel) -> None:
        self.vessel = vessel
        cols: list[Array] = []
        self.owner: list[tuple[int, int]] = []
        for i, t in enumerate(vessel.thrusters):
            if t.kind == "azimuth":
                cols += [np.array([1.0, 0.0, -t.y_m]), np.array([0.0, 1.0, t.x_m])]
                self.owner += [(i, 0), (i, 1)]
            else:
                c, s = math.cos(t.angle_rad), math.sin(t.angle_rad)
                cols.append(np.array([c, s, t.x_m * s - t.y_m * c]))
                self.owner.append((i, 2))
        self.pinv = np.linalg.pinv(np.array(cols).T)
        self.is_azimuth = [t.kind == "azimuth" for t in vessel.thrusters]
        self.fixed_angle = np.array([t.angle_rad for t in vessel.thrusters], dtype=float)

    def __call__(self, tau: ArrayLike) -> tuple[Array, Array]:
        f = (self.pinv @ np.asarray(tau, dtype=float)).tolist()  # (Python floats: the same doubles)
        n = len(self.is_azimuth)
        fx, fy, thrust = [0.0] * n, [0.0] * n, [0.0] * n
        for value, (i, kind) in zip(f, self.owner, strict=True):
            if kind == 0:
                fx[i] = value
            elif kind == 1:
                fy[i] = value
            else:
                thrust[i] = value
        angle = self.fixed_angle.tolist()
        for i, az in enumerate(self.is_azimuth):
            if az:
                thrust[i] = math.hypot(fx[i], fy[i])
                angle[i] = math.atan2(fy[i], fx[i])
        return np.array(thrust), np.array(angle)


def least_squares_commands(vessel: VesselModel, tau: ArrayLike) -> tuple[Array, Array]:
    """One-off `PrescribedAllocation` (tests, scripts)."""
    return PrescribedAllocation(vessel)(tau)
