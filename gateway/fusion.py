"""Fusion: decoded sentences and frames → the observer's measurement y and input τ.

Pure numerics (no I/O, no clocks: times come with the data), shared by the live service and replay.

- **Datum and NED.** Positions are converted to the local NED plane of a fixed datum, or of the first
  valid fix (DESIGN.md conventions), with `wire.geodesy.LocalFrame` (exact WGS-84).
- **Lever arms.** An antenna at body-frame (x, y) from the reference point measures
  p_ref = p_antenna − J(ψ)[x, y] (DESIGN.md). ψ is the heading of the same cycle: the heading received
  closest in time to the fix (an epoch), from a short history. With a fresh attitude from a motion
  reference unit (role ``attitude``: roll φ, pitch θ), the whole arm (x, y, z) is turned by
  R_zyx(φ, θ, ψ) (Fossen 2021, eq. 2.18; `observers.kinematics.lever_arm_ned`, the simulator's antenna
  rotation): p_ref = p_antenna − [R_zyx(φ, θ, ψ)(x, y, z)]_NE, which takes out the wave-frequency motion a
  high antenna makes as the vessel rolls and pitches. The attitude is paired with the fix like the
  heading (the sample received closest in time, within its source's timeout); with none, heading only.
  **Sensor time.** When both the fix (GGA/GNS) and the MRU's sentence (PASHR) carry their own UTC time of
  day, the attitude is instead taken at the fix's own time, linearly interpolated between the two MRU
  samples around it (`_at_sensor_time`; ``pair_by_sensor_time``): a receiver's fix leaves it ~0.1 s after
  its epoch while an MRU's sample leaves within ~0.01 s, and pairing by receive time leaves that
  difference × the roll rate in every fix (docs/gateway.md, "Pairing by sensor time"). Both clocks must
  be GNSS time (an MRU aided by the same receiver, as a DP MRU is). Without a time on either side, or
  without two MRU samples within `ATTITUDE_INTERP_GAP_S` around the fix's time: receive time as above.
- **Held measurements.** The observer runs on the latest measurement of each DOF, held until it is older
  than its source's timeout; then that DOF is missing (dead reckoning). Holding matters: the passive
  observer is a continuous-time filter, and seeing a 1 Hz fix only at the instant it arrives would cut the
  position injection in proportion to the step rate.
- **Source priority.** Of several sources with the same role, the one with the lowest ``priority`` that is
  fresh is used (failover); a fix from a lower-ranked source is ignored while a better one is fresh.
- **Position covariance.** A GST's horizontal covariance (north/east, from its error ellipse when it has
  one: `wire.gst_covariance`) belongs to the fixes of its own source and holds, like a measurement, until
  it is older than that source's timeout: receivers send GST after (not with) each GGA, often at a lower
  rate, so a fix must not clear it. Its shape (not its size) shapes the source's pooling weight
  (`Fusion._shaped_mean`).
- **τ** for the observer: Σ B(αᵢ) Tᵢ over the thrusters' reported thrust and azimuth (the configuration
  matrix, `VesselModel.configuration_matrix`); without feedback, the demand (set by the controller or a
  manual τ). A thrust is fresh for its source's ``timeout_s`` (the time after which `/status` calls that
  source stale; ``feedback_timeout_ns`` where none is given) after the report that carried it (thrust or
  shaft speed); an azimuth-only report (a servo output) moves the angle but does not make an old thrust
  fresh again. While some thrusters' feedback is fresh and others' is not (a unit without a feedback
  link, one whose reports stopped), those count with their commanded thrust and azimuth (from the last
  allocation; none in standby or without one: then with no thrust). Shaft speed becomes thrust by the
  thruster's own propeller law (`Thruster.thrust_at_rpm`), also for a dialect status whose thrust is NaN
  (a drive that measures speed but does not estimate thrust).

- **Wind.** An anemometer's latest valid MWV (role ``wind``), held like a measurement until it is older than
  its source's timeout; of several, the best-ranked fresh one. Stored as body-frame components, u = V cos β,
  v = V sin β (β from the bow), with its reference: ``R`` is the relative wind the controller's feed-forward
  uses as it is; ``T`` (true wind) needs the vessel's velocity added (`gateway.pipeline`).

Fusion owns its state: the pipeline reports what arrived through the ``add_*`` / ``set_*`` methods and reads
through read-only properties and methods; nothing outside writes its fields.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, NamedTuple

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray

from observers.hull import apparent_wind_body
from observers.kinematics import lever_arm_ned, ssa_scalar
from observers.vessel import Thruster, VesselModel
from wire.codecs.nmea_time import utc_step_s
from wire.geodesy import LocalFrame
from wire.gst_covariance import unit_shape

Array = NDArray[np.float64]
NS = 1_000_000_000
HEADING_HISTORY_NS = 5 * NS
HEADING_HISTORY_MAX = 512  # and at most this many (a 50 Hz gyro fills 250 in 5 s; replay feeds far faster)
ATTITUDE_HISTORY_NS = 5 * NS
ATTITUDE_HISTORY_MAX = 512  # an MRU at 100 Hz fills 500 in 5 s
ATTITUDE_INTERP_GAP_S = 0.5
"""Pairing by sensor time interpolates between two MRU samples at most this far apart (s): an MRU sends at
5-100 Hz, so a wider gap is a dropout, across which the roll is not a straight line."""
SENSOR_TIME_MAX_SKEW_NS = NS // 2
"""Pairing by sensor time takes an MRU sample only if it was received within this of the fix (0.5 s): a
latency difference is tens to hundreds of ms; a larger gap between the sample the clocks pair and the
one received with the fix means the clocks are not the same time, and receive time is used instead."""
FEEDBACK_TIMEOUT_NS = 2 * NS
"""Thruster feedback older than this is not used for τ (the demand is, as without feedback)."""


class Held(NamedTuple):
    """A held measurement: value, when it was received, which source, and how long it stays valid.
    (A NamedTuple: several are made per fix, and a frozen dataclass costs 3-4x as much to build.)"""

    value: float = math.nan
    rx_ns: int = 0
    source: str = ""
    priority: int = 0
    valid_ns: int = 0

    def fresh(self, now_ns: int) -> bool:
        return self.source != "" and now_ns - self.rx_ns <= self.valid_ns


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class PositionFix:
    north: float
    east: float
    quality: int


class ThrusterFeedback(NamedTuple):
    """The latest feedback of one thruster: thrust (N), azimuth (rad), receive time of the thrust (ns)."""

    thrust_n: float
    azimuth_rad: float
    rx_ns: int


def _read_only(a: ArrayLike) -> Array:
    out = np.array(a, dtype=float).reshape(3)
    out.setflags(write=False)
    return out


def rms_sigma_m(cov_ne: tuple[float, float, float] | None) -> float | None:
    """One horizontal 1σ of a covariance (C_NN, C_NE, C_EE; m²): √((C_NN + C_EE) / 2), the RMS of the north
    and east σ (None for None)."""
    return None if cov_ne is None else math.sqrt((cov_ne[0] + cov_ne[2]) / 2.0)


class Fusion:
    def __init__(
        self,
        vessel: VesselModel,
        datum: LocalFrame | None = None,
        reference_point_m: tuple[float, float] = (0.0, 0.0),
        feedback_timeout_ns: int = FEEDBACK_TIMEOUT_NS,
        pooling: str = "weighted",
    ) -> None:
        self.vessel = vessel
        self.reference_point_m = reference_point_m
        self.feedback_timeout_ns = feedback_timeout_ns
        self._datum = datum
        self._north = Held()
        self._east = Held()
        self._heading = Held()
        self.pooling = pooling  # "weighted" (inverse variance) or "priority" (best-ranked fresh source)
        # source -> (north, east, quality, weight, east as a Held)
        self._pos: dict[str, tuple[Held, float, int, float, Held]] = {}
        self._hdg: dict[str, tuple[Held, float]] = {}  # source -> (heading, weight)
        # Pooling is a function of what is held, the time and the mode: the last pooling's inputs, so that
        # the observer step right after a fix or heading (same time, nothing new) does not pool again.
        self._pos_changes = self._hdg_changes = 0  # counts of changes to _pos / _hdg
        self._pos_pooled: tuple[int, int, str] | None = None
        self._hdg_pooled: tuple[int, int, str] | None = None
        self._position_sources: tuple[str, ...] = ()
        self._heading_sources: tuple[str, ...] = ()
        self._feedback_ok = True
        self._quality = 0
        self._headings: deque[tuple[int, float]] = deque(maxlen=HEADING_HISTORY_MAX)
        # source -> (its latest GST covariance (C_NN, C_NE, C_EE; m²), valid until ns): like a measurement
        self._cov: dict[str, tuple[tuple[float, float, float], int]] = {}
        self._thrust: dict[int, ThrusterFeedback] = {}
        self._thrust_timeout: dict[int, int] = {}  # thruster id -> the timeout of the source that reported it
        # τ from feedback is a function of what is held and which of it is fresh: the last one, keyed by
        # (changes to _thrust, the fresh ids), so that the steps between feedback bursts do not recompute it
        self._thrust_changes = 0
        self._tau_cached: tuple[tuple[int, tuple[int, ...]], Array] | None = None
        # the last τ made while every held thrust was fresh: (changes to _thrust, the time until which all
        # of them stay fresh, τ); until then and with no new feedback it stands without the freshness pass
        self._tau_all_fresh: tuple[int, int, Array] | None = None
        self._azimuth: dict[int, float] = {}  # last reported azimuth, also before any thrust was reported
        self._thrusters: dict[int, Thruster] = {t.id: t for t in vessel.thrusters}
        self._tau_demand = _read_only(np.zeros(3))
        self._thrust_demand: tuple[list[float], list[float]] | None = None  # (thrust, azimuth) per thruster
        self._wind: dict[str, tuple[Held, float, str]] = {}  # source -> (u as a Held, v, reference R/T)
        # MRU attitude: source -> (priority, valid_ns, history of (rx_ns, roll, pitch, UTC s of day or None))
        self._attitude: dict[str, tuple[int, int, deque[tuple[int, float, float, float | None]]]] = {}
        self.pair_by_sensor_time = True
        """Pair a fix and an attitude by their own UTC times where both have one (`attitude_at`); False:
        by receive time always (``[integrity] attitude_time = "receive"``)."""
        self.last_compensation = ""
        """How the last fix's lever arm was compensated: ``"attitude"`` (R_zyx(φ, θ, ψ), the MRU source in
        `attitude_source`), ``"heading"`` (J(ψ) only) or ``""`` (none yet, or that fix's antenna is at the
        reference point: nothing to compensate)."""
        self.attitude_source = ""

    # --- read-only views ----------------------------------------------------------------------------------

    @property
    def datum(self) -> LocalFrame | None:
        """The local NED frame's origin: configured, or set by the first valid fix."""
        return self._datum

    @property
    def north(self) -> Held:
        return self._north

    @property
    def east(self) -> Held:
        return self._east

    @property
    def heading(self) -> Held:
        return self._heading

    @property
    def quality(self) -> int:
        """Quality indicator of the latest fix used (GGA's; 1 for sentences and frames without one)."""
        return self._quality

    @property
    def thrust(self) -> Mapping[int, ThrusterFeedback]:
        """Thruster id → its latest feedback (thrusters that reported a thrust or shaft speed)."""
        return MappingProxyType(self._thrust)

    def fresh_thrust(self, now_ns: int) -> dict[int, ThrusterFeedback]:
        """Thruster id → its feedback, for the thrusters whose feedback is fresh at ``now_ns`` (within its
        source's timeout) and usable (`set_feedback_usable`)."""
        return self._fresh_thrust(now_ns) if self._feedback_ok else {}

    def _fresh_thrust(self, now_ns: int) -> dict[int, ThrusterFeedback]:
        """Thruster id → its feedback, for the thrusters whose feedback is within its source's timeout."""
        timeout = self._thrust_timeout
        return {tid: v for tid, v in self._thrust.items() if now_ns - v.rx_ns <= timeout[tid]}

    @property
    def tau_demand(self) -> Array:
        """The demanded τ [X, Y, N] (read-only array; change it with `set_tau_demand`)."""
        return self._tau_demand

    # --- heading ------------------------------------------------------------------------------------------

    def add_heading(
        self, rx_ns: int, psi: float, source: str, priority: int, valid_ns: int, weight: float = 1.0
    ) -> bool:
        """A heading measurement (rad) that passed its source's tests. Returns True if it is in use (always
        when pooling by weight; by priority, when no better-ranked source is fresh)."""
        self._hdg[source] = (Held(ssa_scalar(psi), rx_ns, source, priority, valid_ns), weight)
        self._hdg_changes += 1
        self._heading = self._pool_heading(rx_ns)
        self._headings.append((rx_ns, self._heading.value))
        while self._headings and rx_ns - self._headings[0][0] > HEADING_HISTORY_NS:
            self._headings.popleft()
        return source in self._heading_sources

    def drop_heading(self, source: str) -> None:
        """A heading source's data may not be used (it failed a test): forget what it sent."""
        if self._hdg.pop(source, None) is not None:
            self._hdg_changes += 1

    def heading_at(self, t_ns: int) -> float:
        """The heading received closest in time to t (the same cycle as a fix); NaN if none is recent."""
        found = _nearest_in_time(self._headings, t_ns)
        if found is None or found[0] > self._heading.valid_ns:
            return math.nan
        return float(found[1][1])

    # --- attitude (MRU) ----------------------------------------------------------------------------------

    def add_attitude(
        self,
        rx_ns: int,
        roll_rad: float,
        pitch_rad: float,
        source: str,
        priority: int,
        valid_ns: int,
        utc_s: float | None = None,
    ) -> None:
        """A motion reference unit's roll φ (starboard down +) and pitch θ (bow up +), rad, that passed its
        source's tests; ``utc_s``: the sentence's own UTC time of day (PASHR), None without one."""
        entry = self._attitude.get(source)
        if entry is None:
            entry = self._attitude[source] = (priority, valid_ns, deque(maxlen=ATTITUDE_HISTORY_MAX))
        history = entry[2]
        history.append((rx_ns, roll_rad, pitch_rad, utc_s))
        while history and rx_ns - history[0][0] > ATTITUDE_HISTORY_NS:
            history.popleft()

    def drop_attitude(self, source: str) -> None:
        """An attitude source's data may not be used: forget what it sent."""
        self._attitude.pop(source, None)

    def attitude_at(self, t_ns: int, utc_s: float | None = None) -> tuple[float, float, str] | None:
        """(roll, pitch, source) received closest in time to t (the same cycle as a fix) from the
        best-ranked attitude source that has one within its timeout of t; None if none has. With the fix's
        own UTC time of day ``utc_s`` (and `pair_by_sensor_time`), the chosen source's attitude at that
        time (`_at_sensor_time`) where its samples carry times around it."""
        best: tuple[int, float, float, float, str] | None = None  # (priority, |dt|, roll, pitch, source)
        for source, (priority, valid_ns, history) in self._attitude.items():
            if best is not None and priority > best[0]:
                continue
            found = _nearest_in_time(history, t_ns)
            if found is None or found[0] > valid_ns:
                continue
            found_dt, (_, roll, pitch, _) = found
            if best is None or (priority, found_dt) < best[:2]:
                best = (priority, found_dt, roll, pitch, source)
        if best is None:
            return None
        if utc_s is not None and self.pair_by_sensor_time:
            at = _at_sensor_time(self._attitude[best[4]][2], utc_s, t_ns)
            if at is not None:
                return at[0], at[1], best[4]
        return best[2], best[3], best[4]

    # --- position -----------------------------------------------------------------------------------------

    def reference_position(
        self,
        rx_ns: int,
        lat_deg: float,
        lon_deg: float,
        lever_arm_m: tuple[float, float, float],
        utc_s: float | None = None,
    ) -> tuple[float, float] | None:
        """A GNSS fix of an antenna as the reference point's NED position (the datum is set by the first
        fix if none); None when a lever arm has no heading of the same cycle to be compensated with.

        p_ref = p_antenna − [R_zyx(φ, θ, ψ)(x, y, z)]_NE with a fresh MRU attitude (`attitude_at`), else
        p_ref = p_antenna − J(ψ)[x, y]; (x, y, z) is the lever arm from the reference point (whose z is the
        reference point's own, 0). ``utc_s``: the fix's own UTC time of day (GGA, GNS), for pairing it
        with the MRU by sensor time."""
        if self._datum is None:
            self._datum = LocalFrame(lat_deg, lon_deg, 0.0)
        north, east, _ = self._datum.to_ned(lat_deg, lon_deg, 0.0)
        x = lever_arm_m[0] - self.reference_point_m[0]
        y = lever_arm_m[1] - self.reference_point_m[1]
        z = lever_arm_m[2]
        self.last_compensation = ""  # (this fix's way, never the previous fix's: an antenna at the point)
        attitude = self.attitude_at(rx_ns, utc_s) if self._attitude and (x or y or z) else None
        if attitude is not None:
            psi = self.heading_at(rx_ns)
            if math.isnan(psi):
                return None
            dn, de, _ = lever_arm_ned(psi, attitude[0], attitude[1], x, y, z)
            self.last_compensation, self.attitude_source = "attitude", attitude[2]
            return north - dn, east - de
        if x or y:
            psi = self.heading_at(rx_ns)
            if math.isnan(psi):
                return None
            c, s = math.cos(psi), math.sin(psi)
            north -= c * x - s * y
            east -= s * x + c * y
            self.last_compensation = "heading"
        elif z:
            self.last_compensation = "heading"  # (a vertical arm: nothing to take out without an attitude)
        return north, east

    def use_position(
        self,
        rx_ns: int,
        north: float,
        east: float,
        source: str,
        priority: int,
        valid_ns: int,
        quality: int = 1,
        weight: float = 1.0,
    ) -> bool:
        """A reference-point fix (local NED) that passed its source's tests; ``weight`` its pooling weight
        (inverse variance). Returns True if it is in use."""
        held = Held(north, rx_ns, source, priority, valid_ns)
        self._pos[source] = (held, east, quality, weight, Held(east, rx_ns, source, priority, valid_ns))
        self._pos_changes += 1
        self._pool_position(rx_ns)
        return source in self._position_sources

    def drop_position(self, source: str) -> None:
        """A position source's data may not be used (it failed a test): forget what it sent."""
        if self._pos.pop(source, None) is not None:
            self._pos_changes += 1

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
    ) -> PositionFix | None:
        """A GNSS fix of an antenna, used untested. Returns the reference point's NED position if used."""
        ned = self.reference_position(rx_ns, lat_deg, lon_deg, lever_arm_m)
        if ned is None or not self.use_position(rx_ns, *ned, source, priority, valid_ns, quality):
            return None
        return PositionFix(ned[0], ned[1], quality)

    # --- pooling ------------------------------------------------------------------------------------------

    def _fresh(self, held: Mapping[str, tuple[Held, ...]] | dict, now_ns: int) -> list:
        return [v for v in held.values() if v[0].fresh(now_ns)]

    def _pick(self, fresh: list) -> list:
        """The entries to pool: all (by weight), or the best-ranked (by priority; the newest on a tie)."""
        if self.pooling == "priority" or len(fresh) < 2:
            best = min(fresh, key=lambda v: (v[0].priority, -v[0].rx_ns))
            return [best]
        return fresh

    def _pool_position(self, now_ns: int) -> None:
        key = (now_ns, self._pos_changes, self.pooling)
        if key == self._pos_pooled:
            return  # pooled already with these inputs: the same result stands
        self._pos_pooled = key
        if len(self._pos) == 1:  # one source (the common case): its numbers, as the general path gives
            (entry,) = self._pos.values()
            held = entry[0]
            if held.fresh(now_ns):
                self._position_sources = (held.source,)
                self._north, self._east, self._quality = held, entry[4], entry[2]
                return
        fresh = self._fresh(self._pos, now_ns)
        if not fresh:
            self._position_sources = ()
            self._north = self._east = Held()
            return
        use = self._pick(fresh)
        self._position_sources = tuple(sorted(v[0].source for v in use))
        newest = max(use, key=lambda v: v[0].rx_ns)[0]
        lead = max(use, key=lambda v: (v[3], -v[0].priority))[0]
        if len(use) == 1:  # one source: its numbers exactly (a weighted mean of one is not bit-exact)
            north, east = newest.value, use[0][1]
        else:
            shaped = self._shaped_mean(use, now_ns) if self._cov else None
            if shaped is not None:
                north, east = shaped
            else:
                w = sum(v[3] for v in use)
                north = sum(v[3] * v[0].value for v in use) / w
                east = sum(v[3] * v[1] for v in use) / w
        self._north = Held(north, newest.rx_ns, lead.source, lead.priority, newest.valid_ns)
        self._east = Held(east, newest.rx_ns, lead.source, lead.priority, newest.valid_ns)
        self._quality = min(v[2] for v in use) if len(use) > 1 else use[0][2]

    def _shaped_mean(self, use: list, now_ns: int) -> tuple[float, float] | None:
        """The weighted mean of the pooled fixes with each source's GST error ellipse as the shape of its
        weight; None when no pooled source has a fresh GST covariance (the scalar mean then).

        Source i counts with the information matrix Wᵢ = wᵢ Sᵢ⁻¹: wᵢ its pooling weight (the inverse
        measured variance, as without GST) and Sᵢ the shape of its covariance Cᵢ — scaled to a unit RMS
        σ, Ĉ = Cᵢ / (tr Cᵢ / 2), with a floor added to both axes (Sᵢ = (Ĉ + f I) / (1 + f),
        `wire.gst_covariance.unit_shape`) so that no source takes all the weight across a needle-thin
        ellipse's narrow axis; S = I for a source without GST or with a zero covariance, and for a circle.
        The pooled position is x = (Σ Wᵢ)⁻¹ Σ Wᵢ xᵢ, the information-weighted mean. So the measured
        spread still says how much a source counts and the receiver's ellipse only in which direction:
        two receivers with crossed ellipses each supply their good axis; with circles it is the scalar
        mean."""
        cov = self._cov
        if not any(v[0].source in cov and now_ns <= cov[v[0].source][1] for v in use):
            return None
        a = b = c = hn = he = 0.0  # Σ W = [[a, b], [b, c]], Σ W x = (hn, he)
        for v in use:
            w, n, e = v[3], v[0].value, v[1]
            held = cov.get(v[0].source)
            shape = unit_shape(held[0]) if held is not None and now_ns <= held[1] else None
            if shape is not None:  # W = w S⁻¹
                snn, sne, see = shape
                k = w / (snn * see - sne * sne)
                wnn, wne, wee = see * k, -sne * k, snn * k
            else:
                wnn, wne, wee = w, 0.0, w
            a += wnn
            b += wne
            c += wee
            hn += wnn * n + wne * e
            he += wne * n + wee * e
        det = a * c - b * b
        return (c * hn - b * he) / det, (a * he - b * hn) / det

    def _pool_heading(self, now_ns: int) -> Held:
        key = (now_ns, self._hdg_changes, self.pooling)
        if key == self._hdg_pooled:
            return self._heading  # pooled already with these inputs (every caller keeps the result there)
        self._hdg_pooled = key
        if len(self._hdg) == 1:  # one source (the common case): its heading, as the general path gives
            (entry,) = self._hdg.values()
            held = entry[0]
            if held.fresh(now_ns):
                self._heading_sources = (held.source,)
                return held
        fresh = self._fresh(self._hdg, now_ns)
        if not fresh:
            self._heading_sources = ()
            return Held()
        use = self._pick(fresh)
        self._heading_sources = tuple(sorted(v[0].source for v in use))
        newest = max(use, key=lambda v: v[0].rx_ns)[0]
        lead = max(use, key=lambda v: (v[1], -v[0].priority))[0]
        if len(use) == 1:
            psi = newest.value
        else:
            psi = math.atan2(
                sum(v[1] * math.sin(v[0].value) for v in use), sum(v[1] * math.cos(v[0].value) for v in use)
            )
        return Held(psi, newest.rx_ns, lead.source, lead.priority, newest.valid_ns)

    @property
    def position_sources(self) -> tuple[str, ...]:
        """The sources pooled into the latest position."""
        return self._position_sources

    @property
    def heading_sources(self) -> tuple[str, ...]:
        """The sources pooled into the latest heading."""
        return self._heading_sources

    def add_position_covariance(
        self, rx_ns: int, cov_ne: tuple[float, float, float], source: str, valid_ns: int
    ) -> None:
        """A source's horizontal position covariance (C_NN, C_NE, C_EE; m², from GST), valid for
        ``valid_ns`` after ``rx_ns``. One that is no covariance (a negative or non-finite variance, a
        correlation beyond ±1) is not kept. The correlation is checked with a margin of rounding, relative
        and absolute (1e-12 of the trace): a needle-thin ellipse along an axis has C_NN·C_EE underflow to 0
        while C_NE² does not quite (θ = 1e-163 gave C_NE² = 6e-324 against 0), and is still one."""
        nn, ne, ee = cov_ne
        slack = 1e-12 * (nn + ee)
        if (
            nn >= 0.0
            and ee >= 0.0
            and ne * ne <= nn * ee * (1.0 + 1e-9) + slack * slack
            and math.isfinite(nn + ne + ee)
        ):
            self._cov[source] = (cov_ne, rx_ns + valid_ns)

    def position_covariance_ne(self, now_ns: int) -> tuple[float, float, float] | None:
        """The horizontal covariance (C_NN, C_NE, C_EE; m²) of the position in use: its source's GST
        covariance while both are fresh, else None."""
        pos = self._north
        held = self._cov.get(pos.source)  # (no GST from this source: the common case, asked every step)
        if held is None or now_ns > held[1] or not pos.fresh(now_ns):
            return None
        return held[0]

    def position_sigma_m(self, now_ns: int) -> float | None:
        """The 1σ error of the position in use, √((C_NN + C_EE) / 2) of `position_covariance_ne` (the RMS
        of the north and east σ), else None."""
        return rms_sigma_m(self.position_covariance_ne(now_ns))

    # --- wind ---------------------------------------------------------------------------------------------

    def add_wind(
        self, rx_ns: int, speed_mps: float, angle_rad: float, reference: str, source: str, priority: int,
        valid_ns: int,
    ) -> None:  # fmt: skip
        """An anemometer's wind (MWV): ``speed_mps`` from ``angle_rad`` clockwise from the bow, reference
        ``R`` (relative) or ``T`` (true), valid for ``valid_ns`` after ``rx_ns``."""
        if not (math.isfinite(speed_mps) and math.isfinite(angle_rad)) or speed_mps < 0:
            return
        u, v = apparent_wind_body(speed_mps, angle_rad)  # (reference T: the same polar-to-body step)
        self._wind[source] = (Held(u, rx_ns, source, priority, valid_ns), v, reference)

    def wind(self, now_ns: int) -> tuple[float, float, str, str] | None:
        """(u, v, reference, source) of the best-ranked fresh wind (body frame, m/s; module docstring), or
        None when no wind source is fresh."""
        best: tuple[Held, float, str] | None = None
        for held, v, ref in self._wind.values():
            if held.fresh(now_ns) and (best is None or held.priority < best[0].priority):
                best = (held, v, ref)
        if best is None:
            return None
        return best[0].value, best[1], best[2], best[0].source

    # --- what the observer gets ----------------------------------------------------------------------------

    def measurement(self, now_ns: int) -> tuple[Array, list[bool]]:
        """y = [N, E, ψ] with NaN for any DOF whose held value is stale."""
        self._pool_position(now_ns)
        n, e = self._north, self._east
        h = self._heading = self._pool_heading(now_ns)
        # (`Held.fresh` of each, inline: this runs for every observer step)
        valid = [
            n.source != "" and now_ns - n.rx_ns <= n.valid_ns,
            e.source != "" and now_ns - e.rx_ns <= e.valid_ns,
            h.source != "" and now_ns - h.rx_ns <= h.valid_ns,
        ]
        y = np.array(
            [
                n.value if valid[0] else math.nan,
                e.value if valid[1] else math.nan,
                h.value if valid[2] else math.nan,
            ]
        )
        return y, valid

    def measurement_received_ns(self) -> tuple[int, int, int]:
        """When the measurement of each DOF [N, E, ψ] now held was received (ns; 0 before any): a DOF's
        measurement is new to an observer when this is later than the one it was last given."""
        return self._north.rx_ns, self._east.rx_ns, self._heading.rx_ns

    # --- thrusters and τ ------------------------------------------------------------------------------------

    def add_thruster(
        self,
        rx_ns: int,
        thruster_id: int,
        thrust_n: float,
        azimuth_rad: float | None,
        timeout_ns: int | None = None,
    ) -> None:
        """Feedback of a thruster's thrust (N) and, if known, its azimuth (rad); a non-finite thrust is
        ignored, an unknown azimuth keeps the last one reported. ``timeout_ns``: how long it stays fresh
        (the reporting source's timeout; default ``feedback_timeout_ns``)."""
        if not math.isfinite(thrust_n):
            return
        self._thrust_timeout[thruster_id] = self.feedback_timeout_ns if timeout_ns is None else timeout_ns
        if azimuth_rad is not None and math.isfinite(azimuth_rad):
            self._azimuth[thruster_id] = azimuth_rad
        self._thrust[thruster_id] = ThrusterFeedback(thrust_n, self._azimuth.get(thruster_id, 0.0), rx_ns)
        self._thrust_changes += 1

    def add_thruster_rpm(
        self,
        rx_ns: int,
        thruster_id: int,
        rpm: float,
        azimuth_rad: float | None = None,
        timeout_ns: int | None = None,
    ) -> None:
        """Feedback of a thruster's shaft speed (rpm) and, if known, its azimuth (rad): thrust by the
        thruster's propeller law. A thruster the vessel does not have is ignored (the config check refuses
        such a mapping)."""
        th = self._thrusters.get(thruster_id)
        if th is not None:
            self.add_thruster(rx_ns, thruster_id, th.thrust_at_rpm(rpm), azimuth_rad, timeout_ns)

    def add_thruster_azimuth(self, rx_ns: int, thruster_id: int, azimuth_rad: float) -> None:
        """Feedback of an azimuth alone (a servo output): moves the angle, leaves the thrust's time alone."""
        if not math.isfinite(azimuth_rad):
            return
        self._azimuth[thruster_id] = azimuth_rad
        old = self._thrust.get(thruster_id)
        if old is not None:
            self._thrust[thruster_id] = old._replace(azimuth_rad=azimuth_rad)
            self._thrust_changes += 1

    def set_tau_demand(
        self, tau: ArrayLike, thrust_n: ArrayLike | None = None, azimuth_rad: ArrayLike | None = None
    ) -> None:
        """The τ [X, Y, N] demanded of the thrusters (controller, manual input, or zero in standby) and,
        where an allocation made it, each thruster's commanded thrust (N) and azimuth (rad), in layout
        order: what τ counts for a thruster whose feedback is not fresh while others' is."""
        self._tau_demand = _read_only(tau)
        if thrust_n is None or azimuth_rad is None:
            self._thrust_demand = None
        else:
            self._thrust_demand = (
                np.asarray(thrust_n, dtype=float).tolist(),
                np.asarray(azimuth_rad, dtype=float).tolist(),
            )

    def set_feedback_usable(self, usable: bool) -> None:
        """Whether thruster feedback may be used for τ (a source sending out-of-range reports is not
        trusted: τ comes from the demand until it has been clean for a while)."""
        self._feedback_ok = usable

    def tau(self, now_ns: int) -> tuple[Array, str]:
        """τ from fresh thruster feedback through the configuration matrix, else the demand."""
        layout = self.vessel.thrusters
        if not layout or not self._thrust or not self._feedback_ok:
            return self._tau_demand.copy(), "demand"
        held = self._tau_all_fresh  # (a thrust fresh at a time is fresh at every earlier one too)
        if held is not None and held[0] == self._thrust_changes and now_ns <= held[1]:
            return held[2].copy(), "feedback"
        fresh = self._fresh_thrust(now_ns)
        if not fresh:
            return self._tau_demand.copy(), "demand"
        if len(fresh) < len(layout):
            # some thrusters fresh, others not: those count with their command (not cached: it changes
            # with every control step)
            return self._tau_of(fresh, self._thrust_demand), "feedback"
        key = (self._thrust_changes, tuple(fresh))
        if self._tau_cached is not None and self._tau_cached[0] == key:
            tau = self._tau_cached[1]
        else:
            tau = self._tau_of(fresh, None)
            self._tau_cached = (key, tau)
        if len(fresh) == len(self._thrust):  # (here every thruster of the layout is fresh)
            until = min(v.rx_ns + self._thrust_timeout[tid] for tid, v in fresh.items())
            self._tau_all_fresh = (self._thrust_changes, until, tau)
        return tau.copy(), "feedback"

    def _tau_of(
        self, fresh: dict[int, ThrusterFeedback], demand: tuple[list[float], list[float]] | None
    ) -> Array:
        """τ = Σ B(αᵢ) Tᵢ with each thruster's fresh feedback, else its command from ``demand`` (thrust and
        azimuth in layout order), else no thrust at its fixed angle (standby, or no allocation)."""
        layout = self.vessel.thrusters
        thrust = [
            fresh[t.id].thrust_n if t.id in fresh else demand[0][i] if demand else 0.0
            for i, t in enumerate(layout)
        ]
        angle = [
            fresh[t.id].azimuth_rad if t.id in fresh else demand[1][i] if demand else t.angle_rad
            for i, t in enumerate(layout)
        ]
        return self.vessel.generalized_force(thrust, angle)


def _nearest_in_time(history: Sequence[tuple[Any, ...]], t_ns: int) -> tuple[int, tuple[Any, ...]] | None:
    """(|Δt|, entry) of the entry of a time-ordered history of (t_ns, ...) received closest to t_ns; None
    when it is empty. A fix pairs with recent samples (its cycle's heading, attitude): walk back from the
    newest until the gap starts to grow, with no copy of the history per fix."""
    best: tuple[int, tuple[Any, ...]] | None = None
    for entry in reversed(history):
        dt = abs(entry[0] - t_ns)
        if best is not None and dt > best[0]:
            break
        best = (dt, entry)
    return best


def _at_sensor_time(
    history: Sequence[tuple[int, float, float, float | None]], utc_s: float, t_ns: int
) -> tuple[float, float] | None:
    """(roll, pitch) at the UTC time of day ``utc_s``, linearly interpolated between the two samples of a
    time-ordered MRU history whose own times (the 4th item) lie on either side of it, at most
    `ATTITUDE_INTERP_GAP_S` apart (a sample at exactly that time is taken as it is); None when there are
    none such (no times, the fix's time past the newest sample, a gap). Steps between times of day are
    taken modulo a day (`utc_step_s`), so midnight is no gap. Walks back from the newest sample."""
    after: tuple[float, float, float] | None = None  # (step from the fix's time ≥ 0, roll, pitch)
    for rx_ns, roll, pitch, t in reversed(history):
        if t is None:
            return None
        step = utc_step_s(utc_s, t)
        if step >= 0.0:
            after = (step, roll, pitch)
            if step == 0.0:
                return (roll, pitch) if abs(rx_ns - t_ns) <= SENSOR_TIME_MAX_SKEW_NS else None
            continue
        if after is None or after[0] - step > ATTITUDE_INTERP_GAP_S:
            return None
        if abs(rx_ns - t_ns) > SENSOR_TIME_MAX_SKEW_NS:
            # the two clocks disagree by more than any latency: the MRU's is not GNSS time (set by hand,
            # free running), and its "same time" is another moment; receive time is then the better guess
            return None
        w = -step / (after[0] - step)  # the weight of the later sample
        return roll + w * (after[1] - roll), pitch + w * (after[2] - pitch)
    return None
