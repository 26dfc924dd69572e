"""Fusion: decoded sentences and frames → the observer's measurement y and input τ.

Pure numerics (no I/O, no clocks: times come with the data), shared by the live service and replay.

- **Datum and NED.** Positions are converted to the local NED plane of a fixed datum, or of the first
  valid fix (DESIGN.md conventions), with `wire.geodesy.LocalFrame` (exact WGS-84).
- **Lever arms.** An antenna at body-frame (x, y) from the reference point measures
  p_ref = p_antenna − J(ψ)[x, y] (DESIGN.md). ψ is the heading of the same cycle: the heading received
  closest in time to the fix (an epoch), from a short history.
- **Held measurements.** The observer runs on the latest measurement of each DOF, held until it is older
  than its source's timeout; then that DOF is missing (dead reckoning). Holding matters: the passive
  observer is a continuous-time filter, and seeing a 1 Hz fix only at the instant it arrives would cut the
  position injection in proportion to the step rate.
- **Source priority.** Of several sources with the same role, the one with the lowest ``priority`` that is
  fresh is used (failover); a fix from a lower-ranked source is ignored while a better one is fresh.
- **τ** for the observer: Σ B(αᵢ) Tᵢ over the thrusters' reported thrust and azimuth (the configuration
  matrix, `VesselModel.configuration_matrix`); without feedback, the demand (set by the controller or a
  manual τ).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from observers.kinematics import ssa_scalar
from observers.vessel import VesselModel
from wire.geodesy import LocalFrame

Array = NDArray[np.float64]
NS = 1_000_000_000
HEADING_HISTORY_NS = 5 * NS
HEADING_HISTORY_MAX = 512  # and at most this many (a 50 Hz gyro fills 250 in 5 s; replay feeds far faster)


@dataclass
class Held:
    """A held measurement: value, when it was received, which source, and how long it stays valid."""

    value: float = math.nan
    rx_ns: int = 0
    source: str = ""
    priority: int = 0
    valid_ns: int = 0

    def fresh(self, now_ns: int) -> bool:
        return self.source != "" and now_ns - self.rx_ns <= self.valid_ns


@dataclass
class PositionFix:
    north: float
    east: float
    quality: int
    sigma_m: float | None = None


@dataclass
class Fusion:
    vessel: VesselModel
    datum: LocalFrame | None = None
    reference_point_m: tuple[float, float] = (0.0, 0.0)
    north: Held = field(default_factory=Held)
    east: Held = field(default_factory=Held)
    heading: Held = field(default_factory=Held)
    quality: int = 0
    position_sigma_m: float | None = None
    _headings: deque[tuple[int, float]] = field(default_factory=lambda: deque(maxlen=HEADING_HISTORY_MAX))
    thrust: dict[int, tuple[float, float, int]] = field(default_factory=dict)  # id -> (thrust N, azimuth, rx)
    tau_demand: Array = field(default_factory=lambda: np.zeros(3))
    feedback_timeout_ns: int = 2 * NS

    # --- heading ------------------------------------------------------------------------------------------

    def add_heading(self, rx_ns: int, psi: float, source: str, priority: int, valid_ns: int) -> bool:
        """A heading measurement (rad). Returns True if it was used (fresh and best-ranked)."""
        h = self.heading
        if h.fresh(rx_ns) and priority > h.priority and h.source != source:
            return False
        self.heading = Held(ssa_scalar(psi), rx_ns, source, priority, valid_ns)
        self._headings.append((rx_ns, self.heading.value))
        while self._headings and rx_ns - self._headings[0][0] > HEADING_HISTORY_NS:
            self._headings.popleft()
        return True

    def heading_at(self, t_ns: int) -> float:
        """The heading received closest in time to t (the same cycle as a fix); NaN if none is recent."""
        if not self._headings:
            return math.nan
        # Fixes pair with recent headings: walk back from the newest until the gap starts to grow
        # (no copy of the history per fix).
        best_dt, best = None, math.nan
        for t, psi in reversed(self._headings):
            dt = abs(t - t_ns)
            if best_dt is not None and dt > best_dt:
                break
            best_dt, best = dt, psi
        if best_dt is None or best_dt > self.heading.valid_ns:
            return math.nan
        return best

    # --- position -----------------------------------------------------------------------------------------

    def add_position(
        self,
        rx_ns: int,
        lat_deg: float,
        lon_deg: float,
        lever_arm_m: tuple[float, float, float],
        source: str,
        priority: int,
        valid_ns: int,
        quality: int = 1,
        sigma_m: float | None = None,
    ) -> PositionFix | None:
        """A GNSS fix of an antenna. Returns the reference point's NED position if it was used."""
        n = self.north
        if n.fresh(rx_ns) and priority > n.priority and n.source != source:
            return None
        if self.datum is None:
            self.datum = LocalFrame(lat_deg, lon_deg, 0.0)
        north, east, _ = self.datum.to_ned(lat_deg, lon_deg, 0.0)
        x = lever_arm_m[0] - self.reference_point_m[0]
        y = lever_arm_m[1] - self.reference_point_m[1]
        if x or y:
            psi = self.heading_at(rx_ns)
            if math.isnan(psi):
                return None  # a lever arm without a heading of the same cycle cannot be compensated
            c, s = math.cos(psi), math.sin(psi)
            north -= c * x - s * y
            east -= s * x + c * y
        self.north = Held(north, rx_ns, source, priority, valid_ns)
        self.east = Held(east, rx_ns, source, priority, valid_ns)
        self.quality = quality
        self.position_sigma_m = sigma_m
        return PositionFix(north, east, quality, sigma_m)

    # --- what the observer gets ----------------------------------------------------------------------------

    def measurement(self, now_ns: int) -> tuple[Array, list[bool]]:
        """y = [N, E, ψ] with NaN for any DOF whose held value is stale."""
        valid = [self.north.fresh(now_ns), self.east.fresh(now_ns), self.heading.fresh(now_ns)]
        y = np.array(
            [
                self.north.value if valid[0] else math.nan,
                self.east.value if valid[1] else math.nan,
                self.heading.value if valid[2] else math.nan,
            ]
        )
        return y, valid

    def add_thruster(self, rx_ns: int, thruster_id: int, thrust_n: float, azimuth_rad: float | None) -> None:
        if not math.isfinite(thrust_n):
            return
        old = self.thrust.get(thruster_id)
        az = (
            azimuth_rad
            if azimuth_rad is not None and math.isfinite(azimuth_rad)
            else (old[1] if old else 0.0)
        )
        self.thrust[thruster_id] = (thrust_n, az, rx_ns)

    def tau(self, now_ns: int) -> tuple[Array, str]:
        """τ from fresh thruster feedback through the configuration matrix, else the demand."""
        layout = self.vessel.thrusters
        if not layout or not self.thrust:
            return self.tau_demand.copy(), "demand"
        fresh = {tid: v for tid, v in self.thrust.items() if now_ns - v[2] <= self.feedback_timeout_ns}
        if not fresh:
            return self.tau_demand.copy(), "demand"
        thrust = np.array([fresh.get(t.id, (0.0, 0.0, 0))[0] for t in layout])
        angle = np.array([fresh.get(t.id, (0.0, t.angle_rad, 0))[1] for t in layout])
        return self.vessel.generalized_force(thrust, angle), "feedback"
