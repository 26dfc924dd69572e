"""Simulated sensors that look like real hardware on the wire: a DGPS receiver, a gyro compass and a
thruster controller's MAVLink feedback.

Each sensor samples the simulated vessel (`ShipState`) on its own schedule and returns `Emission` s: the
exact bytes it sends (a whole NMEA sentence with ``\\r\\n``, or one MAVLink frame), the sim time they leave
the sensor (measurement time + latency) and the time the value was measured. The simulator runner asks each
sensor for `Sensor.next_time`, computes the ship state at that time, calls `Sensor.sample` and writes the
bytes to the sensor's transport at ``t_emit``.

Models (docs/sensors.md has the full description):

* `Dgps` — antenna position = reference point + R(φ, θ, ψ)·lever arm: the vessel's heading and its
  wave-frequency roll and pitch turn the lever arm (a mast 20 m high moves 0.35 m per degree of roll),
  heave and the turned arm's height go into the altitude; noise white or first-order Gauss-Markov with
  standard deviation σ per axis; NED → WGS-84 latitude/longitude at a `Datum` with pymap3d. Speed and
  course over ground from the antenna's low-frequency NED velocity J(ψ)(ν + r × lever arm) plus white
  velocity noise. Fixes on the UTC grid of the output rate (like a receiver locked to GPS time); one burst
  per fix: GGA or GNS, then RMC, VTG, GST, ZDA as configured.
* `Gyro` — heading ψ + white noise, wrapped; rate of turn r + white noise: HDT, THS, ROT, HDG.
* `Anemometer` — the relative (apparent) wind at the mast: the plant's wind (mean + gust, at the vessel's
  wind reference height) minus the vessel's own LF velocity, as speed and angle from the bow, plus white
  noise on each: NMEA MWV, reference R.
* `Mru` — a motion reference unit: the reference point's wave-frequency roll φ and pitch θ (the RAOs'
  attitude the `Dgps` antenna is turned by) + white noise, as proprietary ``$PHTRO`` (iXblue) or ``$PASHR``
  (POS MV-style, with heading and heave): what a DP system's lever-arm compensation needs.
* `ThrusterFeedback` — per thruster one ``AZIMUTH_THRUSTER_STATUS``, a ``HEARTBEAT`` (surface boat), and
  optionally ArduPilot-style ``ESC_TELEMETRY_x_TO_y`` (rpm) and ``SERVO_OUTPUT_RAW`` (azimuth as PWM), all
  through one MAVLink encoder so sequence numbers run like on a real link; with a signing key
  (`ThrusterFeedback.sign_with`) every frame is MAVLink 2 signed.

All randomness comes from the ``rng`` given to a sensor: the same seed gives the same bytes. Faults come from
a `simulator.faults.FaultSchedule`. A sensor applies the sample-side faults itself (dropout, frozen, jump,
noise burst, drift, spoof, quality, bogus feedback, thruster failure); the wire-side faults (bad checksum,
garbage) are applied by whoever puts the bytes on the wire, with
``FaultSchedule.apply_to_emissions(emissions, rng)`` and a generator of its own, so
that line noise never changes the sensors' random streams.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, ClassVar, Generic, Literal, NamedTuple, Protocol, TypeVar

import numpy as np
import pymap3d
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray
from pydantic import AfterValidator, ConfigDict, Field, TypeAdapter, ValidationError

from observers.hull import relative_wind
from observers.kinematics import lever_arm_ned, ssa_scalar
from observers.vessel import THRUSTER_KINDS
from simulator.clock import SimEpoch
from simulator.faults import QUALITY_MODES, Fault, FaultSchedule
from simulator.sensor_protocol import Sensor
from wire.codecs import mavlink as mv
from wire.codecs import nmea as nmea_codec
from wire.codecs import nmea_encode as nmea
from wire.geodesy import LocalFrame

__all__ = [
    "DGPS_EXTRA_SENTENCES",
    "DGPS_POSITION_SENTENCES",
    "DGPS_QUALITIES",
    "FAULT_CODE_TRIP",
    "GYRO_SENTENCES",
    "MRU_SENTENCES",
    "SERVO_PWM_CENTER_US",
    "SERVO_PWM_HALF_RANGE_US",
    "THRUSTER_KINDS",
    "VERTICAL_SIGMA_FACTOR",
    "Anemometer",
    "AnemometerConfig",
    "Datum",
    "Dgps",
    "DgpsConfig",
    "Emission",
    "Gyro",
    "GyroConfig",
    "Mru",
    "MruConfig",
    "Sensor",
    "ShipState",
    "ThrusterFeedback",
    "ThrusterFeedbackConfig",
    "ThrusterReading",
    "antenna_ned",
    "antenna_ned_floats",
    "antenna_position",
    "antenna_velocity",
    "azimuth_to_pwm",
    "pwm_to_azimuth",
]

DGPS_POSITION_SENTENCES = ("GGA", "GNS")
DGPS_EXTRA_SENTENCES = ("GGA", "GNS", "RMC", "VTG", "GST", "ZDA")
DGPS_QUALITIES = {1: "A", 2: "D", 4: "R", 5: "F"}
"""GGA quality → mode indicator of GNS (per constellation), RMC and VTG: 1 autonomous (SPS), 2 differential,
4 RTK fixed, 5 RTK float."""
GYRO_SENTENCES = ("HDT", "THS", "ROT", "HDG")
MRU_SENTENCES = ("PHTRO", "PASHR")
VERTICAL_SIGMA_FACTOR = 1.5
"""Vertical GNSS noise = this × the horizontal σ (satellite geometry makes height worse than position)."""
SERVO_PWM_CENTER_US = 1500
SERVO_PWM_HALF_RANGE_US = 400
"""SERVO_OUTPUT_RAW azimuth mapping: pwm = 1500 + 400·azimuth/π µs, azimuth in [-π, π) → [1100, 1900)."""
FAULT_CODE_TRIP = 1
"""``AZIMUTH_THRUSTER_STATUS.fault_code`` of a failed thruster (the simulator's one "drive tripped" code)."""

_DUE_TOL_S = 1e-6
_new = object.__new__
_ID_TEXT = [str(i) for i in range(256)]  # a thruster id (0..255) as a fault's source names it
_GNS_CONSTELLATIONS = 2  # GNS mode field: one character for GPS and one for GLONASS
_FLAGS_OK = (
    mv.AzimuthThrusterFlags.READY | mv.AzimuthThrusterFlags.RUNNING | mv.AzimuthThrusterFlags.REMOTE_CONTROL
)
_FLAGS_FAILED = mv.AzimuthThrusterFlags.REMOTE_CONTROL | mv.AzimuthThrusterFlags.FAULT


# ---------------------------------------------------------------------------------------------- data

# This module is compiled by mypyc (setup.py). Its dataclasses stay Python classes
# (``native_class=False``): the samples are made without their checks through ``object.__new__`` and
# ``__dict__`` (`Emission.trusted`, …), `Datum` keeps its frame in a field it does not declare, and the
# configs are checked by pydantic as written (a compiled float field would turn an int into a float first).


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Datum:
    """The origin of the local NED frame on the WGS-84 ellipsoid (degrees, ellipsoidal height in m)."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        _validate(self, _DATUM_RULES)
        object.__setattr__(self, "_frame", LocalFrame(self.lat_deg, self.lon_deg, self.alt_m))

    def to_geodetic(self, north: ArrayLike, east: ArrayLike, down: ArrayLike = 0.0) -> tuple[Any, Any, Any]:
        """Latitude (deg), longitude (deg) and ellipsoidal height (m) of local NED points (m). Scalars give
        floats, arrays give arrays (broadcast). Scalars go through `wire.geodesy` (the same exact
        conversion as pymap3d, ~60x faster: one call per fix at 10 Hz adds up)."""
        frame: LocalFrame = self._frame  # type: ignore[attr-defined]
        if isinstance(north, float) and isinstance(east, float) and isinstance(down, float | int):
            return frame.to_geodetic(float(north), float(east), float(down))  # (np.float64 is a float)
        if np.ndim(north) == 0 and np.ndim(east) == 0 and np.ndim(down) == 0:
            return frame.to_geodetic(float(north), float(east), float(down))  # type: ignore[arg-type]
        lat, lon, alt = pymap3d.ned2geodetic(north, east, down, self.lat_deg, self.lon_deg, self.alt_m)
        return _maybe_float(lat), _maybe_float(lon), _maybe_float(alt)

    def to_ned(
        self, lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike | None = None
    ) -> tuple[Any, Any, Any]:
        """Local NED (m) of geodetic points; the inverse of `to_geodetic`. ``alt_m`` defaults to the datum's
        height (points on the tangent plane's level)."""
        height = self.alt_m if alt_m is None else alt_m
        n, e, d = pymap3d.geodetic2ned(lat_deg, lon_deg, height, self.lat_deg, self.lon_deg, self.alt_m)
        return _maybe_float(n), _maybe_float(e), _maybe_float(d)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Emission:
    """One frame on the wire: a whole NMEA sentence (with ``\\r\\n``), one MAVLink frame, or junk bytes."""

    t_emit: float
    """Sim time the bytes leave the sensor (measurement time + latency)."""
    source: str
    """Stream name (``dgps1``, ``gyro1``, ``thrusters``)."""
    protocol: str
    """``"nmea"`` or ``"mavlink"``."""
    data: bytes
    """The exact bytes."""
    t_measured: float
    """Sim time the value was sampled (garbage: ``t_emit``)."""
    record: Any = None
    """Only from a sensor with ``encode = False`` (then ``data`` is empty): what a receiver decodes from the
    frame, as the wire codecs return it, at full precision. NMEA: the `wire.codecs.nmea` sentence (`Gga`,
    `Gns`, `Gst`, `Heading`) or None for one a DP gateway does not use (RMC, VTG, ZDA, ROT); MAVLink: the
    tuple of `wire.codecs.mavlink` reports (empty for a heartbeat)."""

    @classmethod
    def trusted(
        cls, t_emit: float, source: str, protocol: str, data: bytes, t_measured: float, record: Any = None
    ) -> Emission:
        """For the sensors' own samples: the same object without the frozen dataclass' per-field
        ``object.__setattr__`` (a sensor makes ~80 a second)."""
        e = _new(cls)
        d = e.__dict__
        d["t_emit"] = t_emit
        d["source"] = source
        d["protocol"] = protocol
        d["data"] = data
        d["t_measured"] = t_measured
        d["record"] = record
        return e

    @property
    def text(self) -> str:
        """The bytes as text (NMEA); undecodable bytes show as U+FFFD."""
        return self.data.decode("ascii", errors="replace")


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ThrusterReading:
    """What one thruster's drive measures (given by the thruster model): SI units, azimuth clockwise from
    the bow (direction of the thrust force), ``rpm`` negative astern, ``power_w`` NaN if unknown."""

    id: int
    kind: str
    thrust_n: float
    azimuth_rad: float
    rpm: float
    thrust_setpoint_n: float
    azimuth_setpoint_rad: float
    failed: bool
    power_w: float = math.nan

    def __post_init__(self) -> None:
        # a value made every sample (not a config): two plain comparisons, no schema; on the values as given
        # (`_given`)
        given = _given(self)
        tid, kind = given["id"], given["kind"]
        if isinstance(tid, bool) or not (isinstance(tid, int | np.integer) and 0 <= tid <= 255):
            raise ValueError(f"ThrusterReading.id: must be in 0..255, got {tid!r}")
        if kind not in THRUSTER_KINDS:
            raise ValueError(f"ThrusterReading.kind: must be one of {THRUSTER_KINDS}, got {kind!r}")

    @classmethod
    def trusted(
        cls, id: int, kind: str, thrust_n: float, azimuth_rad: float, rpm: float, thrust_setpoint_n: float,
        azimuth_setpoint_rad: float, failed: bool, power_w: float,
    ) -> ThrusterReading:  # fmt: skip
        """For the simulator's own loop, whose ids and kinds come from a checked vessel: the same object
        without the checks (six of them at every feedback sample)."""
        reading = _new(cls)
        d = reading.__dict__
        d["id"] = id
        d["kind"] = kind
        d["thrust_n"] = thrust_n
        d["azimuth_rad"] = azimuth_rad
        d["rpm"] = rpm
        d["thrust_setpoint_n"] = thrust_setpoint_n
        d["azimuth_setpoint_rad"] = azimuth_setpoint_rad
        d["failed"] = failed
        d["power_w"] = power_w
        return reading


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ShipState:
    """What the sensors sample at time ``t``: ``eta`` = [N, E, ψ] of the reference point (total motion, LF +
    WF), ``nu`` = [u, v, r] in the body frame, the thrusters' readings, and ``attitude`` = [z (m, down), φ,
    θ (rad)]: the reference point's wave-frequency heave, roll (starboard down) and pitch (bow up)."""

    t: float
    eta: NDArray[np.float64]
    nu: NDArray[np.float64]
    thrusters: tuple[ThrusterReading, ...] = ()
    attitude: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ("eta", "nu", "attitude"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,):
                raise ValueError(f"ShipState.{name}: must have 3 elements, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "thrusters", tuple(_given(self)["thrusters"]))

    @classmethod
    def trusted(
        cls,
        t: float,
        eta: NDArray[np.float64],
        nu: NDArray[np.float64],
        thrusters: tuple[ThrusterReading, ...],
        attitude: NDArray[np.float64] | None = None,
    ) -> ShipState:
        """For the simulator's own loop, whose arrays are float64 of 3 and readings a tuple already: the
        same object without the checks (it is made at every sample instant)."""
        state = _new(cls)
        d = state.__dict__
        d["t"] = t
        d["eta"] = eta
        d["nu"] = nu
        d["thrusters"] = thrusters
        d["attitude"] = np.zeros(3) if attitude is None else attitude
        return state


# ---------------------------------------------------------------------------------------------- configs


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class DgpsConfig:
    """A DGPS / RTK receiver. σ in m per horizontal axis (1σ); lever arm (x fwd, y stbd, z down) in m from
    the reference point to the antenna; latency and correlation time in s.

    ``alt_m`` is the altitude above mean sea level of the *reference point*: GGA/GNS report
    ``alt_m - lever_arm_m[2]`` (the antenna is higher when z is negative). ``sigma_velocity_mps`` is the white
    noise per NED axis of the Doppler velocity behind RMC/VTG. With ``noise_correlation_s`` > 0 the position
    noise is a first-order Gauss-Markov process with that time constant (same σ).
    """

    source: str = "dgps1"
    talker: str = "GP"
    rate_hz: float = 1.0
    position_sentence: str = "GGA"
    extra: tuple[str, ...] = ("RMC", "VTG", "GST", "ZDA")
    slow_sentences: tuple[str, ...] = ("GST", "ZDA")
    """Sentences sent at ``slow_rate_hz`` only (on the fixes that fall on that grid), as real receivers are
    configured: statistics and date once a second, position and velocity at the fix rate."""
    slow_rate_hz: float = 1.0
    quality: int = 2
    sigma_m: float = 0.5
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, -20.0)
    latency_s: float = 0.1
    n_sats: int = 12
    hdop: float = 0.8
    alt_m: float = 20.0
    age_s: float | None = 2.0
    station_id: int | None = 1
    noise_correlation_s: float = 0.0
    sigma_velocity_mps: float = 0.02

    def __post_init__(self) -> None:
        given = _given(self)
        object.__setattr__(self, "extra", tuple(given["extra"]))
        object.__setattr__(self, "slow_sentences", tuple(given["slow_sentences"]))
        object.__setattr__(self, "lever_arm_m", tuple(float(x) for x in given["lever_arm_m"]))
        burst = (given["position_sentence"], *given["extra"])
        _validate(self, _DGPS_RULES)
        if len(set(burst)) != len(burst):
            raise ValueError(
                f"DgpsConfig.extra: repeats a sentence or the position sentence, got {self.extra!r}"
            )

    @property
    def lever_arm_xyz(self) -> tuple[float, float, float]:
        """The lever arm as (x, y, z), z = 0 when only (x, y) is given."""
        arm = self.lever_arm_m
        return arm[0], arm[1], arm[2] if len(arm) > 2 else 0.0

    @property
    def sentences(self) -> tuple[str, ...]:
        """The sentences of one burst, in the order they are sent."""
        return (self.position_sentence, *self.extra)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class GyroConfig:
    """A gyro compass. ``sigma_rad`` is the white heading noise (1σ), ``sigma_rot_rad_s`` the white noise on
    the rate of turn. ``variation_rad`` (east positive) is only used by HDG, which reports a magnetic sensor
    heading = true heading − variation with deviation 0 and that variation."""

    source: str = "gyro1"
    talker: str = "HE"
    rate_hz: float = 10.0
    sentences: tuple[str, ...] = ("HDT", "ROT")
    sigma_rad: float = math.radians(0.05)
    latency_s: float = 0.02
    sigma_rot_rad_s: float = math.radians(0.5) / 60.0
    variation_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "sentences", tuple(_given(self)["sentences"]))
        _validate(self, _GYRO_RULES)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class AnemometerConfig:
    """An ultrasonic anemometer on the mast, sending MWV (relative wind) at ``rate_hz``.

    ``sigma_speed_mps`` and ``sigma_angle_rad`` are the white noise (1σ) on the apparent speed and angle:
    the defaults are a marine ultrasonic sensor's stated accuracy (±0.3 m/s, ±2°, e.g. Gill WindObserver,
    Vaisala WMT700 class), at 2 Hz (such sensors output 1-4 Hz, up to 10). ``unit`` is MWV's speed unit
    (M m/s, N knots, K km/h, S mph). The sensor is taken to stand at the vessel's wind reference height
    (``[hull.wind] height_m``), so it sees the speed the plant's wind force is computed with; the mast's
    wave-frequency roll is not in its reading."""

    source: str = "wind1"
    talker: str = "WI"
    rate_hz: float = 2.0
    sigma_speed_mps: float = 0.3
    sigma_angle_rad: float = math.radians(2.0)
    latency_s: float = 0.05
    unit: str = "M"

    def __post_init__(self) -> None:
        _validate(self, _ANEMOMETER_RULES)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class MruConfig:
    """A motion reference unit (MRU) at the reference point, sending roll and pitch at ``rate_hz``.

    ``sentence``: ``PHTRO`` (iXblue Octans: pitch and roll only) or ``PASHR`` (POS MV-style: also time,
    true heading, heave and the 1σ of each). ``sigma_rad`` is the white noise on roll and pitch (1σ): 0.02°
    is a DP-class MRU's stated accuracy (Kongsberg MRU 5, iXblue Octans: 0.01°); ``sigma_heading_rad`` the
    noise on PASHR's heading. Latency 10 ms (an MRU outputs within a few ms of its sample)."""

    source: str = "mru1"
    sentence: str = "PHTRO"
    rate_hz: float = 10.0
    sigma_rad: float = math.radians(0.02)
    sigma_heading_rad: float = math.radians(0.05)
    latency_s: float = 0.01

    def __post_init__(self) -> None:
        _validate(self, _MRU_RULES)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ThrusterFeedbackConfig:
    """A thruster controller reporting over MAVLink as system ``system_id``, component ``component_id``.
    ``heartbeat_hz`` 0 turns the heartbeat off (to test a gateway's link-loss alarm). ``on_command_loss``:
    what the drives do once no command has come for `simulator.runner.COMMAND_TIMEOUT_S`: ``hold`` their
    last command (the default), or ``stop`` (thrust to zero, the azimuths where they are: a drive's
    fieldbus watchdog, an ArduPilot failsafe)."""

    source: str = "thrusters"
    rate_hz: float = 5.0
    system_id: int = 1
    component_id: int = 1
    heartbeat_hz: float = 1.0
    ardupilot_esc: bool = False
    ardupilot_servo: bool = False
    ardupilot_motor: bool = False
    latency_s: float = 0.0
    on_command_loss: str = "hold"

    def __post_init__(self) -> None:
        _validate(self, _FEEDBACK_RULES)

    @property
    def ardupilot(self) -> bool:
        """Whether any ArduPilot frame is sent (their meaning depends on the receiver's wiring)."""
        return self.ardupilot_esc or self.ardupilot_servo or self.ardupilot_motor


# ---------------------------------------------------------------------------------------------- sensors


def antenna_position(
    eta: ArrayLike, lever_arm_m: Sequence[float], attitude: ArrayLike | None = None
) -> NDArray[np.float64]:
    """NED [N, E] of an antenna at body-frame ``lever_arm_m`` (x, y[, z]) from the reference point at η.

    With ``attitude`` = [z, φ, θ] (heave, roll, pitch) the lever arm is turned by R_zyx(φ, θ, ψ) (Fossen
    2021, eq. 2.18), so roll and pitch move a high antenna sideways and fore-aft; without, by ψ alone."""
    return antenna_ned(eta, lever_arm_m, attitude)[:2]


def antenna_ned(
    eta: ArrayLike, lever_arm_m: Sequence[float], attitude: ArrayLike | None = None
) -> NDArray[np.float64]:
    """NED [N, E, D] of an antenna (see `antenna_position`); D includes heave and the turned arm's z."""
    north, east, psi = np.asarray(eta, dtype=float).tolist()
    x, y = float(lever_arm_m[0]), float(lever_arm_m[1])
    z = float(lever_arm_m[2]) if len(lever_arm_m) > 2 else 0.0
    heave, phi, theta = (0.0, 0.0, 0.0) if attitude is None else np.asarray(attitude, dtype=float).tolist()
    return np.array(antenna_ned_floats(north, east, psi, x, y, z, heave, phi, theta))


def antenna_ned_floats(
    north: float, east: float, psi: float, x: float, y: float, z: float,
    heave: float, phi: float, theta: float,
) -> tuple[float, float, float]:  # fmt: skip
    """`antenna_ned` on plain floats (the simulator's loop: no arrays in or out): the reference point plus
    the lever arm turned by `observers.kinematics.lever_arm_ned` (R_zyx(φ, θ, ψ)), the rotation the
    gateway's MRU compensation inverts."""
    dn, de, dd = lever_arm_ned(psi, phi, theta, x, y, z)
    return north + dn, east + de, heave + dd


def antenna_velocity(eta: ArrayLike, nu: ArrayLike, lever_arm_m: Sequence[float]) -> NDArray[np.float64]:
    """NED velocity [v_N, v_E] of the antenna: J(ψ)·(ν + r × lever arm) = J(ψ)·[u − r·y, v + r·x]."""
    psi = float(np.asarray(eta, dtype=float)[2])
    u, v, r = np.asarray(nu, dtype=float)
    x, y = float(lever_arm_m[0]), float(lever_arm_m[1])
    bu, bv = u - r * y, v + r * x
    c, s = math.cos(psi), math.sin(psi)
    return np.array([c * bu - s * bv, s * bu + c * bv])


def azimuth_to_pwm(azimuth_rad: float) -> int:
    """SERVO_OUTPUT_RAW pulse width (µs) of an azimuth: 1500 + 400·ssa(azimuth)/π; ahead (0) is 1500 µs,
    starboard (π/2) 1700 µs, port (−π/2) 1300 µs, astern 1100 µs (−π; +π wraps to −π)."""
    return round(SERVO_PWM_CENTER_US + SERVO_PWM_HALF_RANGE_US * ssa_scalar(azimuth_rad) / math.pi)


def motor_pwm(thrust_n: float, min_thrust_n: float, max_thrust_n: float) -> int:
    """A reversible motor output's pulse width (µs) for a thrust command, as ArduPilot drives a reversible
    throttle (trim 1500 µs, range 1100-1900 µs): 1500 + 400·throttle, with the throttle the shaft speed
    as a fraction of full speed on that side, sqrt(T / T_max) ahead and −sqrt(T / T_min) astern (the
    quadratic propeller law T ∝ n|n|). A thruster that does not reverse (T_min ≥ 0) has no astern side."""
    if thrust_n >= 0:
        throttle = math.sqrt(min(thrust_n / max_thrust_n, 1.0)) if max_thrust_n > 0 else 0.0
    else:
        throttle = -math.sqrt(min(thrust_n / min_thrust_n, 1.0)) if min_thrust_n < 0 else 0.0
    return round(SERVO_PWM_CENTER_US + SERVO_PWM_HALF_RANGE_US * throttle)


def pwm_to_azimuth(pwm_us: float) -> float:
    """Inverse of `azimuth_to_pwm` (rad; 1 µs ≈ 0.45°)."""
    return (pwm_us - SERVO_PWM_CENTER_US) / SERVO_PWM_HALF_RANGE_US * math.pi


class _Schedule:
    """Sample instants ``t0 + k / rate``, computed from k (never summed up, so they do not drift)."""

    def __init__(self, rate_hz: float, t0: float) -> None:
        self.period = 1.0 / rate_hz if rate_hz > 0 else math.inf
        self.t0 = t0
        self.k = 0

    @property
    def k(self) -> int:
        """The index of the next sample."""
        return self._k

    @k.setter
    def k(self, k: int) -> None:
        self._k = k
        # the runner asks for the next instant several times per step: kept, not recomputed
        self._next = self.t0 + k * self.period if math.isfinite(self.period) else math.inf

    def next(self) -> float:
        return self._next

    def due(self, t: float) -> bool:
        return t >= self._next - _DUE_TOL_S

    def advance_past(self, t: float) -> None:
        if math.isfinite(self.period):
            self.k = max(self._k + 1, math.floor((t + _DUE_TOL_S - self.t0) / self.period) + 1)


class _Freezer:
    """Holds the value measured at the first sample of a ``frozen`` fault and repeats it in its window."""

    def __init__(self) -> None:
        self._fault: Fault | None = None
        self._value: Any = None

    def __call__(self, fault: Fault | None, value: Any) -> Any:
        if fault is None:
            self._fault = None
            return value
        if fault is not self._fault:
            self._fault, self._value = fault, value
        return self._value


class _SourceConfig(Protocol):
    @property
    def source(self) -> str: ...


_C = TypeVar("_C", bound=_SourceConfig)
_M = TypeVar("_M")


class _Sampled(Generic[_C, _M]):
    """What the NMEA sensors share (`Dgps`, `Gyro`, `Anemometer`): their config and random stream, a
    sample schedule, the faults applied at the sample (``dropout``: nothing sent; ``frozen``: the window's
    first measurement repeated, the random stream drawn all the same) and the ``encode`` switch. A sensor
    gives `_measure`, and its `sample` turns what `_sampled` returns into emissions."""

    def __init__(
        self, config: _C, rng: np.random.Generator, faults: FaultSchedule | None, schedule: _Schedule
    ) -> None:
        self.config = config
        self.source = config.source
        self.rng = rng
        self.faults = faults if faults is not None else FaultSchedule()
        self._schedule = schedule
        self._freeze = _Freezer()
        self.encode = True
        """False: emissions carry typed records instead of bytes (see `Emission.record`)."""

    def next_time(self) -> float:
        return self._schedule.next()

    def _sampled(self, state: ShipState) -> tuple[float, _M] | None:
        """(t, the measurement at t, frozen while a ``frozen`` fault is on) when a sample is due at
        ``state.t`` and no ``dropout`` is on; the schedule advances past t whenever one was due."""
        t = float(state.t)
        if not self._schedule.due(t):
            return None
        self._schedule.advance_past(t)
        if self.faults.active("dropout", self.source, t):
            return None
        return t, self._freeze(self.faults.active("frozen", self.source, t), self._measure(state, t))

    def _measure(self, state: ShipState, t: float) -> _M:
        raise NotImplementedError


class _Burst(NamedTuple):
    kinds: tuple[str, ...]
    utc: Any  # datetime
    seconds: float  # of the UTC day
    quality: int
    mode: str
    age: float | None
    station: int | None


class _Fix(NamedTuple):
    lat_deg: float
    lon_deg: float
    alt_m: float
    sog_mps: float
    cog_rad: float


class Dgps(_Sampled[DgpsConfig, _Fix]):
    """A DGPS/RTK receiver (see `DgpsConfig`). Fixes fall on the UTC grid of the output rate (whole seconds
    at 1 Hz, .0/.2/.4… at 5 Hz), the first at or after ``start``; every sentence of a burst carries the fix
    time and leaves at fix time + latency."""

    def __init__(
        self,
        config: DgpsConfig,
        datum: Datum,
        epoch: SimEpoch,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        *,
        start: float = 0.0,
    ) -> None:
        period = 1.0 / config.rate_hz
        past_second = (epoch.stamp_ns(start) % 1_000_000_000) / 1e9
        super().__init__(config, rng, faults, _Schedule(config.rate_hz, start + (-past_second) % period))
        self.datum = datum
        self.epoch = epoch
        self._sigma = np.array([1.0, 1.0, VERTICAL_SIGMA_FACTOR]) * config.sigma_m
        self._noise: NDArray[np.float64] | None = None
        self._t_noise = 0.0
        self._mode = DGPS_QUALITIES[config.quality]
        self._kinds_all = config.sentences
        self._kinds_fast = tuple(k for k in config.sentences if k not in config.slow_sentences)
        self._lever_arm = config.lever_arm_xyz

    def sample(self, state: ShipState) -> list[Emission]:
        sampled = self._sampled(state)
        if sampled is None:
            return []
        t, fix = sampled
        t_emit = t + self.config.latency_s
        if not self.encode:
            return [Emission.trusted(t_emit, self.source, "nmea", b"", t, r) for r in self._records(fix, t)]
        return [
            Emission.trusted(t_emit, self.source, "nmea", text.encode("ascii"), t)
            for text in self._sentences(fix, t)
        ]

    def _position_noise(self, t: float) -> NDArray[np.float64]:
        """[N, E, Down-up] noise (m): white, or Gauss-Markov x⁺ = φx + √(1−φ²)σw with φ = exp(−Δt/T)."""
        w = self.rng.standard_normal(3)
        tau = self.config.noise_correlation_s
        if tau <= 0.0 or self._noise is None:
            self._noise = self._sigma * w
        else:
            phi = math.exp(-max(t - self._t_noise, 0.0) / tau)
            self._noise = phi * self._noise + math.sqrt(1.0 - phi * phi) * self._sigma * w
        self._t_noise = t
        return self._noise

    def _measure(self, state: ShipState, t: float) -> _Fix:
        """The fix at t. Plain floats throughout (the same IEEE arithmetic as the arrays of
        `antenna_velocity` and `antenna_ned`, element by element, without making them)."""
        cfg = self.config
        noise = self._position_noise(t).copy()
        north, east, psi = state.eta.tolist()
        u, v, r = state.nu.tolist()
        x, y, z = self._lever_arm
        bu, bv = u - r * y, v + r * x  # antenna_velocity
        c, s = math.cos(psi), math.sin(psi)
        w = self.rng.standard_normal(2).tolist()
        vn = c * bu - s * bv + cfg.sigma_velocity_mps * w[0]
        ve = s * bu + c * bv + cfg.sigma_velocity_mps * w[1]
        burst = self.faults.active("noise_burst", self.source, t)
        if burst is not None:
            sigma = burst.param("sigma_m")
            noise += np.array([sigma, sigma, VERTICAL_SIGMA_FACTOR * sigma]) * self.rng.standard_normal(3)
        heave, phi, theta = state.attitude.tolist()
        ant_n, ant_e, ant_d = antenna_ned_floats(north, east, psi, x, y, z, heave, phi, theta)
        n0, n1, n2 = noise.tolist()
        north, east = ant_n + n0, ant_e + n1
        jump = self.faults.active("jump", self.source, t)
        if jump is not None:
            north += jump.param("north_m")
            east += jump.param("east_m")
        drift = self.faults.active("drift", self.source, t)
        if drift is not None:
            north += drift.param("north_mps") * (t - drift.t_start)
            east += drift.param("east_mps") * (t - drift.t_start)
        lat, lon, _ = self.datum.to_geodetic(north, east, 0.0)
        spoof = self.faults.active("spoof", self.source, t)
        if spoof is not None:
            lat = spoof.param("lat_deg", float(lat))
            lon = spoof.param("lon_deg", float(lon))
        return _Fix(float(lat), float(lon), cfg.alt_m - ant_d + n2, math.hypot(vn, ve), math.atan2(ve, vn))

    def _burst(self, t: float) -> _Burst:
        """What the sentences of the fix at ``t`` share: which are sent, the UTC time, quality and mode."""
        cfg = self.config
        utc = self.epoch.utc(t)
        quality, mode = cfg.quality, self._mode
        bad = self.faults.active("quality", self.source, t)
        if bad is not None:
            quality = int(bad.param("quality"))
            mode = QUALITY_MODES[quality]
        differential = quality in (2, 3, 4, 5)  # corrections in use: the age and station fields are filled
        seconds = utc.hour * 3600 + utc.minute * 60 + utc.second + utc.microsecond * 1e-6
        slow_due = (seconds % (1.0 / min(cfg.slow_rate_hz, cfg.rate_hz))) < 0.5 / cfg.rate_hz
        kinds = self._kinds_all if slow_due else self._kinds_fast
        age = cfg.age_s if differential else None
        station = cfg.station_id if differential else None
        return _Burst(kinds, utc, seconds, quality, mode, age, station)

    def _records(self, fix: _Fix, t: float) -> list[Any]:
        """The sentences of `_sentences` as a receiver decodes them (`Emission.record`), unrounded."""
        cfg = self.config
        b = self._burst(t)
        sigma = cfg.sigma_m
        out: list[Any] = []
        for kind in b.kinds:
            if kind == "GGA":
                out.append(
                    nmea_codec.Gga(
                        cfg.talker, b.seconds, fix.lat_deg, fix.lon_deg, b.quality, cfg.n_sats, cfg.hdop,
                        fix.alt_m, None, b.age, b.station, b.quality >= 1,
                    )
                )  # fmt: skip
            elif kind == "GNS":
                mode = b.mode * _GNS_CONSTELLATIONS
                out.append(
                    nmea_codec.Gns(
                        cfg.talker, b.seconds, fix.lat_deg, fix.lon_deg, mode, cfg.n_sats, cfg.hdop,
                        fix.alt_m, None, b.age, b.station, None, mode.strip("N") != "",
                    )
                )  # fmt: skip
            elif kind == "GST":
                out.append(
                    nmea_codec.Gst(
                        cfg.talker, b.seconds, sigma, sigma, sigma, 0.0, sigma, sigma,
                        VERTICAL_SIGMA_FACTOR * sigma,
                    )
                )  # fmt: skip
            else:
                out.append(None)  # RMC, VTG, ZDA: counted by a gateway, not used
        return out

    def _sentences(self, fix: _Fix, t: float) -> list[str]:
        cfg = self.config
        b = self._burst(t)
        utc, quality, mode, age, station = b.utc, b.quality, b.mode, b.age, b.station
        sigma = cfg.sigma_m
        out = []
        for kind in b.kinds:
            if kind == "GGA":
                text = nmea.gga(
                    cfg.talker,
                    utc,
                    fix.lat_deg,
                    fix.lon_deg,
                    quality,
                    cfg.n_sats,
                    cfg.hdop,
                    fix.alt_m,
                    None,
                    age,
                    station,
                )
            elif kind == "GNS":
                text = nmea.gns(
                    cfg.talker,
                    utc,
                    fix.lat_deg,
                    fix.lon_deg,
                    mode * _GNS_CONSTELLATIONS,
                    cfg.n_sats,
                    cfg.hdop,
                    fix.alt_m,
                    None,
                    age,
                    station,
                )
            elif kind == "RMC":
                text = nmea.rmc(
                    cfg.talker, utc, fix.lat_deg, fix.lon_deg, fix.sog_mps, fix.cog_rad, True, mode
                )
            elif kind == "VTG":
                text = nmea.vtg(cfg.talker, fix.cog_rad, fix.sog_mps, mode)
            elif kind == "GST":
                text = nmea.gst(
                    cfg.talker,
                    utc,
                    rms_m=sigma,
                    sigma_major_m=sigma,
                    sigma_minor_m=sigma,
                    orient_rad=0.0,
                    sigma_lat_m=sigma,
                    sigma_lon_m=sigma,
                    sigma_alt_m=VERTICAL_SIGMA_FACTOR * sigma,
                )
            else:
                text = nmea.zda(cfg.talker, utc)
            out.append(text)
        return out


class Gyro(_Sampled[GyroConfig, tuple[float, float]]):
    """A gyro compass (see `GyroConfig`), free-running at ``start + k / rate_hz``."""

    def __init__(
        self,
        config: GyroConfig,
        epoch: SimEpoch,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        *,
        start: float = 0.0,
    ) -> None:
        super().__init__(config, rng, faults, _Schedule(config.rate_hz, start))
        self.epoch = epoch

    def sample(self, state: ShipState) -> list[Emission]:
        sampled = self._sampled(state)
        if sampled is None:
            return []
        t, (heading, rate) = sampled
        cfg = self.config
        t_emit = t + cfg.latency_s
        if not self.encode:
            return [
                Emission.trusted(
                    t_emit, self.source, "nmea", b"", t, _heading_record(kind, cfg.talker, heading)
                )
                for kind in cfg.sentences
            ]
        out = []
        for kind in cfg.sentences:
            if kind == "HDT":
                text = nmea.hdt(cfg.talker, heading)
            elif kind == "THS":
                text = nmea.ths(cfg.talker, heading, "A")
            elif kind == "ROT":
                text = nmea.rot(cfg.talker, rate, True)
            else:
                text = nmea.hdg(cfg.talker, heading - cfg.variation_rad, 0.0, cfg.variation_rad)
            out.append(Emission.trusted(t_emit, self.source, "nmea", text.encode("ascii"), t))
        return out

    def _measure(self, state: ShipState, t: float) -> tuple[float, float]:
        w = self.rng.standard_normal(2)
        heading = float(state.eta[2]) + self.config.sigma_rad * w[0]
        rate = float(state.nu[2]) + self.config.sigma_rot_rad_s * w[1]
        burst = self.faults.active("noise_burst", self.source, t)
        if burst is not None:
            heading += burst.param("sigma_rad") * float(self.rng.standard_normal())
        jump = self.faults.active("jump", self.source, t)
        if jump is not None:
            heading += jump.param("heading_rad")
        drift = self.faults.active("drift", self.source, t)
        if drift is not None:
            heading += drift.param("heading_rad_s") * (t - drift.t_start)
        return ssa_scalar(heading), rate


WindAt = Callable[[float], tuple[float, float]]
"""The true wind at sim time t: (speed m/s at the vessel's wind reference height, from degrees)."""


class Anemometer(_Sampled[AnemometerConfig, tuple[float, float]]):
    """An anemometer (see `AnemometerConfig`), free-running at ``start + k / rate_hz``. ``wind`` gives the
    true wind at a time (`simulator.wind.Wind`: mean + gust); the reading is the apparent wind
    `observers.hull.relative_wind` of the vessel's LF velocity, the same function the plant's wind force
    and the gateway's feed-forward start from."""

    def __init__(
        self,
        config: AnemometerConfig,
        wind: WindAt,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        *,
        start: float = 0.0,
    ) -> None:
        super().__init__(config, rng, faults, _Schedule(config.rate_hz, start))
        self.wind = wind

    def sample(self, state: ShipState) -> list[Emission]:
        sampled = self._sampled(state)
        if sampled is None:
            return []
        t, (angle, speed) = sampled
        cfg = self.config
        t_emit = t + cfg.latency_s
        if not self.encode:
            record = nmea_codec.Mwv(cfg.talker, angle, "R", speed, True)
            return [Emission.trusted(t_emit, self.source, "nmea", b"", t, record)]
        text = nmea.mwv(cfg.talker, angle, speed, "R", cfg.unit)
        return [Emission.trusted(t_emit, self.source, "nmea", text.encode("ascii"), t)]

    def _measure(self, state: ShipState, t: float) -> tuple[float, float]:
        """(angle from the bow in [-π, π), speed ≥ 0) of the apparent wind at t, noise included."""
        speed, from_deg = self.wind(t)
        u, v, _ = state.nu.tolist()
        urw, vrw = relative_wind(speed, from_deg, float(state.eta[2]), u, v)
        w = self.rng.standard_normal(2).tolist()
        cfg = self.config
        angle = ssa_scalar(math.atan2(vrw, urw) + cfg.sigma_angle_rad * w[0])
        return angle, max(math.hypot(urw, vrw) + cfg.sigma_speed_mps * w[1], 0.0)


class Mru(_Sampled[MruConfig, tuple[float, float, float, float]]):
    """A motion reference unit (see `MruConfig`), free-running at ``start + k / rate_hz``: the state's
    wave-frequency roll and pitch (``ShipState.attitude``, dpgw's signs: starboard down, bow up) plus white
    noise, as PHTRO or PASHR (the sentence carries the signs its maker uses: `wire.codecs.nmea_encode`).
    Faults: ``dropout`` and ``frozen`` (`_Sampled`), the ones a stale or stuck MRU shows, and ``jump``
    (``roll_rad``, ``pitch_rad`` added in its window: a spike for one sample, an offset for longer)."""

    def __init__(
        self,
        config: MruConfig,
        epoch: SimEpoch,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        *,
        start: float = 0.0,
    ) -> None:
        super().__init__(config, rng, faults, _Schedule(config.rate_hz, start))
        self.epoch = epoch

    def sample(self, state: ShipState) -> list[Emission]:
        sampled = self._sampled(state)
        if sampled is None:
            return []
        t, (roll, pitch, heading, heave_down) = sampled
        cfg = self.config
        t_emit = t + cfg.latency_s
        pashr = cfg.sentence == "PASHR"
        if not self.encode:
            record = nmea_codec.Attitude(
                "PASHR" if pashr else "PHTRO",
                "",
                self._seconds(t) if pashr else None,
                roll,
                pitch,
                heading if pashr else None,
                -heave_down if pashr else None,
                cfg.sigma_rad if pashr else None,
                cfg.sigma_rad if pashr else None,
                cfg.sigma_heading_rad if pashr else None,
                1 if pashr else None,
                1 if pashr else None,
                True,
            )
            return [Emission.trusted(t_emit, self.source, "nmea", b"", t, record)]
        if pashr:
            text = nmea.pashr(
                self.epoch.utc(t),
                roll,
                pitch,
                heading_rad=heading,
                heave_up_m=-heave_down,
                roll_sigma_rad=cfg.sigma_rad,
                pitch_sigma_rad=cfg.sigma_rad,
                heading_sigma_rad=cfg.sigma_heading_rad,
            )
        else:
            text = nmea.phtro(roll, pitch)
        return [Emission.trusted(t_emit, self.source, "nmea", text.encode("ascii"), t)]

    def _seconds(self, t: float) -> float:
        utc = self.epoch.utc(t)
        return utc.hour * 3600 + utc.minute * 60 + utc.second + utc.microsecond * 1e-6

    def _measure(self, state: ShipState, t: float) -> tuple[float, float, float, float]:
        """(roll, pitch, heading, heave down) at t, noise included."""
        heave, phi, theta = state.attitude.tolist()
        w = self.rng.standard_normal(3).tolist()
        cfg = self.config
        roll = phi + cfg.sigma_rad * w[0]
        pitch = theta + cfg.sigma_rad * w[1]
        jump = self.faults.active("jump", self.source, t)
        if jump is not None:
            roll += jump.param("roll_rad")
            pitch += jump.param("pitch_rad")
        heading = ssa_scalar(float(state.eta[2]) + cfg.sigma_heading_rad * w[2])
        return roll, pitch, heading, heave


def _heading_record(kind: str, talker: str, heading: float) -> nmea_codec.Heading | None:
    """A gyro sentence as a receiver decodes it: HDT, THS (mode A) and HDG (its variation added back:
    true heading) carry the heading; ROT is not used by a DP gateway."""
    if kind == "ROT":
        return None
    return nmea_codec.Heading(kind, talker, heading, True, "A" if kind == "THS" else None, False)  # type: ignore[arg-type]


class ThrusterFeedback:
    """A thruster controller's MAVLink link (see `ThrusterFeedbackConfig`): per thruster an
    ``AZIMUTH_THRUSTER_STATUS`` at ``rate_hz``, a ``HEARTBEAT`` at ``heartbeat_hz`` (both from ``start``), and
    with ``ardupilot_esc`` / ``ardupilot_servo`` an ``ESC_TELEMETRY_1_TO_4`` per four thrusters (ESC n is the
    n-th thruster of ``ShipState.thrusters``; up to 32) / a ``SERVO_OUTPUT_RAW`` per 16 thrusters (port 0, 1;
    output n = n-th thruster's azimuth, `azimuth_to_pwm`); with ``ardupilot_motor`` a ``SERVO_OUTPUT_RAW``
    on port 1 with each thruster's reversible motor output (output 16 + n = n-th thruster's, up to 16,
    `motor_pwm` of its thrust setpoint within ``thrust_limits_n``). All frames of one instant: heartbeat
    first, then the status frames in thruster order, motor outputs, ESC telemetry, servo outputs."""

    def __init__(
        self,
        config: ThrusterFeedbackConfig,
        epoch: SimEpoch,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        *,
        start: float = 0.0,
        thrust_limits_n: Mapping[int, tuple[float, float]] | None = None,
    ) -> None:
        self.config = config
        self.thrust_limits_n = dict(thrust_limits_n or {})
        """Thruster id → (min, max) thrust (N): the scale of its motor output (`motor_pwm`)."""
        self.source = config.source
        self.epoch = epoch
        self.rng = rng  # unused today: the drives' feedback is exact (kept for the common signature)
        self.faults = faults if faults is not None else FaultSchedule()
        self.start = start
        self.mav = mv.encoder(config.system_id, config.component_id)
        self._wall_clock: Callable[[], float] = time.time
        self._status = _Schedule(config.rate_hz, start)
        self._heartbeat = _Schedule(config.heartbeat_hz, start)
        self._freeze = _Freezer()
        self.encode = True
        """False: emissions carry typed records instead of bytes (see `Emission.record`); not with the
        ArduPilot frames, whose meaning depends on the receiver's wiring."""
        self._esc_count = [0] * 32
        ardupilot = config.ardupilot
        d = mv.dialect()
        self._autopilot = d.MAV_AUTOPILOT_ARDUPILOTMEGA if ardupilot else d.MAV_AUTOPILOT_INVALID
        # an ArduPilot Rover/boat in GUIDED (custom mode 15), armed, takes commands from a companion computer
        armed = d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | d.MAV_MODE_FLAG_SAFETY_ARMED
        self._base_mode = armed if ardupilot else 0
        self._custom_mode = 15 if ardupilot else 0

    SIGNING_LINK_ID: ClassVar[int] = 0  # (ClassVar: compiled, a plain name would be an instance field)
    """The MAVLink 2 signing link id of the drive's frames (the gateway signs its commands as link 1)."""

    def sign_with(self, key: bytes, wall_clock: Callable[[], float] = time.time) -> None:
        """Sign every frame from now on with this 32-byte MAVLink 2 key (link `SIGNING_LINK_ID`).

        The signature's timestamp follows ``wall_clock`` (UNIX s), not the simulation's time: a receiver
        takes a new signed stream only if its timestamp is at most a minute behind its own clock
        (pymavlink's check), and a simulation runs faster or slower than the wall and may start on any
        date. Between two readings of the clock the timestamp goes up by one per frame, as the protocol
        requires. So signed frames are not the same bytes from run to run (the payloads are)."""
        mv.setup_signing(self.mav, key, link_id=self.SIGNING_LINK_ID)
        self._wall_clock = wall_clock

    def next_time(self) -> float:
        return min(self._status.next(), self._heartbeat.next())

    def sample(self, state: ShipState) -> list[Emission]:
        t = float(state.t)
        heartbeat, status = self._heartbeat.due(t), self._status.due(t)
        if not (heartbeat or status):
            return []
        if heartbeat:
            self._heartbeat.advance_past(t)
        if status:
            self._status.advance_past(t)
        if self.faults.active("dropout", self.source, t):
            return []
        if not self.encode:
            return self._records(state, t, heartbeat, status)
        frames: list[bytes] = []
        if self.mav.signing.sign_outgoing:  # never behind the wall clock (`sign_with`)
            mv.keep_signing_time(self.mav, self._wall_clock())
        if heartbeat:
            frames.append(
                mv.heartbeat_frame(
                    self.mav,
                    autopilot=self._autopilot,
                    base_mode=self._base_mode,
                    custom_mode=self._custom_mode,
                )
            )
        if status:
            readings = self._freeze(self.faults.active("frozen", self.source, t), state.thrusters)
            frames += self._status_frames(readings, t)
        t_emit = t + self.config.latency_s
        return [Emission.trusted(t_emit, self.source, "mavlink", frame, t) for frame in frames]

    def _records(self, state: ShipState, t: float, heartbeat: bool, status: bool) -> list[Emission]:
        """The frames of `sample` as a receiver decodes them (`Emission.record`): a heartbeat carries no
        report, a status one `ThrusterReport` with thrust, azimuth and rpm unrounded (float32 on the wire) and
        the drive's flags."""
        if self.config.ardupilot:
            raise ValueError(
                "ThrusterFeedback: typed records need the dpgw dialect only (no ArduPilot frames)"
            )
        t_emit = t + self.config.latency_s
        out = [Emission.trusted(t_emit, self.source, "mavlink", b"", t, ())] if heartbeat else []
        if status:
            readings = self._freeze(self.faults.active("frozen", self.source, t), state.thrusters)
            for reading in readings:
                thrust, rpm, azimuth = reading.thrust_n, reading.rpm, reading.azimuth_rad
                bogus = self.faults.active("bogus_feedback", str(reading.id), t)
                if bogus is not None:
                    thrust = bogus.param("thrust_n", thrust)
                    rpm = bogus.param("rpm", rpm)
                    azimuth = bogus.param("azimuth_rad", azimuth)
                key = _ID_TEXT[reading.id]
                failed = reading.failed or self.faults.active("thruster_failure", key, t) is not None
                flags = int(_FLAGS_FAILED if failed else _FLAGS_OK)
                report = mv.ThrusterReport(reading.id, float(thrust), float(azimuth), float(rpm), flags=flags)
                out.append(Emission.trusted(t_emit, self.source, "mavlink", b"", t, (report,)))
        return out

    def _status_frames(self, readings: tuple[ThrusterReading, ...], t: float) -> list[bytes]:
        time_usec = self.epoch.stamp_ns(t) // 1000
        frames = []
        for reading in readings:
            key = _ID_TEXT[reading.id]
            failed = reading.failed or self.faults.active("thruster_failure", key, t) is not None
            thrust, rpm, azimuth = reading.thrust_n, reading.rpm, reading.azimuth_rad
            bogus = self.faults.active("bogus_feedback", key, t)
            if bogus is not None:  # the drive claims what the fault says (a bad scaling, a broken sensor)
                thrust = bogus.param("thrust_n", thrust)
                rpm = bogus.param("rpm", rpm)
                azimuth = bogus.param("azimuth_rad", azimuth)
            frames.append(
                mv.azimuth_status_frame(
                    self.mav,
                    time_usec,
                    reading.id,
                    thrust,
                    rpm,
                    azimuth,
                    _FLAGS_FAILED if failed else _FLAGS_OK,
                    thrust_setpoint_n=reading.thrust_setpoint_n,
                    azimuth_setpoint_rad=reading.azimuth_setpoint_rad,
                    power_w=reading.power_w,
                    fault_code=FAULT_CODE_TRIP if failed else 0,
                )
            )
        if self.config.ardupilot_motor and readings:  # (before the ESC telemetry: the command that drove it)
            if len(readings) > 16:
                raise ValueError(
                    f"ThrusterFeedback: ardupilot_motor puts the motor outputs on outputs 17-32 (port 1): at "
                    f"most 16 thrusters, got {len(readings)}"
                )
            since_boot_us = round((t - self.start) * 1e6)
            limits = self.thrust_limits_n
            pwm = [motor_pwm(r.thrust_setpoint_n, *limits.get(r.id, (-1.0, 1.0))) for r in readings]
            frames.append(mv.servo_output_raw_frame(self.mav, since_boot_us, pwm, port=1))
        if self.config.ardupilot_esc:
            for block, first in enumerate(mv.ESC_TELEMETRY_BLOCKS):
                group = readings[4 * block : 4 * block + 4]
                if not group:
                    break
                for i in range(4 * block, 4 * block + len(group)):
                    self._esc_count[i] += 1
                frames.append(
                    mv.esc_telemetry_frame(
                        self.mav,
                        [r.rpm for r in group],
                        count=self._esc_count[4 * block : 4 * block + len(group)],
                        first_esc=first,
                    )
                )
        if self.config.ardupilot_servo and readings:
            since_boot_us = round((t - self.start) * 1e6)
            for port in range(math.ceil(len(readings) / 16)):
                pwm = [azimuth_to_pwm(r.azimuth_rad) for r in readings[16 * port : 16 * port + 16]]
                frames.append(mv.servo_output_raw_frame(self.mav, since_boot_us, pwm, port))
        return frames


# ---------------------------------------------------------------------------------------------- helpers


# The configs' rules: each field's type and limits as a pydantic type (strict: no "5" for 5, no True for
# 1; floats finite), and what the message says when it fails. One library validates the gateway's config
# file and these; the message names the class and field: ``DgpsConfig.rate_hz: must be in 1..10 Hz, got 20``.

Rule = tuple[TypeAdapter[Any], str]
_STRICT = ConfigDict(strict=True)


def _rule(tp: Any, what: str) -> Rule:
    return TypeAdapter(tp, config=_STRICT), what


def _number(
    *, ge: float | None = None, le: float | None = None, gt: float | None = None, lt: float | None = None
) -> Any:
    return Annotated[float, Field(ge=ge, le=le, gt=gt, lt=lt, allow_inf_nan=False)]


def _integer(ge: int, le: int) -> Any:
    return Annotated[int, Field(ge=ge, le=le)]


def _one_of(choices: tuple[Any, ...]) -> Any:
    """One of ``choices``, compared as written (no conversion: 2.0 is not the quality 2)."""
    return Literal.__getitem__(choices)


def _tuple(*items: Any) -> Any:
    """``tuple[items]`` built at run time (the items are pydantic types made by the helpers above)."""
    return tuple.__class_getitem__(items)


def _stream_name(v: str) -> str:
    if v == "" or v.strip() != v or v == "*":
        raise ValueError("not a stream name")
    return v


def _distinct(v: tuple[str, ...]) -> tuple[str, ...]:
    if not v or len(set(v)) != len(v):
        raise ValueError("empty or repeated")
    return v


_StreamName = Annotated[str, AfterValidator(_stream_name)]
_Talker = Annotated[str, Field(pattern=r"^[A-Z][A-Z0-9]$")]
_SOURCE_RULE = _rule(_StreamName, "must be a non-empty stream name without surrounding spaces (not '*')")
_TALKER_RULE = _rule(_Talker, "must be a 2-character NMEA talker id such as 'GP', 'GN' or 'HE'")
_BOOLEAN_RULE = _rule(bool, "must be true or false")
_LATENCY_RULE = _rule(_number(ge=0.0, le=10.0), "must be in 0..10 s")
_DgpsExtra = _tuple(_one_of(DGPS_EXTRA_SENTENCES), ...)

_DATUM_RULES: dict[str, Rule] = {
    "lat_deg": _rule(_number(ge=-90.0, le=90.0), "must be in [-90, 90] degrees"),
    "lon_deg": _rule(_number(ge=-180.0, le=180.0), "must be in [-180, 180] degrees"),
    "alt_m": _rule(_number(), "must be finite"),
}
_DGPS_RULES: dict[str, Rule] = {
    "source": _SOURCE_RULE,
    "talker": _TALKER_RULE,
    "rate_hz": _rule(_number(ge=1.0, le=10.0), "must be in 1..10 Hz"),
    "position_sentence": _rule(_one_of(DGPS_POSITION_SENTENCES), f"must be one of {DGPS_POSITION_SENTENCES}"),
    "extra": _rule(_DgpsExtra, f"must be some of {DGPS_EXTRA_SENTENCES}"),
    "slow_sentences": _rule(
        _DgpsExtra, f"must be some of {DGPS_EXTRA_SENTENCES} (the position sentence always runs at rate_hz)"
    ),
    "slow_rate_hz": _rule(_number(gt=0.0, le=10.0), "must be in (0, 10] Hz"),
    "quality": _rule(_one_of(tuple(DGPS_QUALITIES)), f"must be one of {sorted(DGPS_QUALITIES)}"),
    "sigma_m": _rule(_number(ge=0.0), "must be >= 0 m"),
    "lever_arm_m": _rule(
        _tuple(_number(), _number(), _number()), "must be 3 finite numbers (x fwd, y stbd, z down) in m"
    ),
    "latency_s": _LATENCY_RULE,
    "n_sats": _rule(_integer(4, 99), "must be in 4..99 (a fix needs four satellites)"),
    "hdop": _rule(_number(gt=0.0, le=99.0), "must be in (0, 99]"),
    "alt_m": _rule(_number(), "must be finite"),
    "age_s": _rule(_number(ge=0.0, le=999.0) | None, "must be None or in 0..999 s"),
    "station_id": _rule(_integer(0, 1023) | None, "must be None or in 0..1023"),
    "noise_correlation_s": _rule(_number(ge=0.0), "must be >= 0 s (0 = white noise)"),
    "sigma_velocity_mps": _rule(_number(ge=0.0), "must be >= 0 m/s"),
}
_GYRO_RULES: dict[str, Rule] = {
    "source": _SOURCE_RULE,
    "talker": _TALKER_RULE,
    "rate_hz": _rule(_number(gt=0.0, le=20.0), "must be in (0, 20] Hz"),
    "sentences": _rule(
        Annotated[_tuple(_one_of(GYRO_SENTENCES), ...), AfterValidator(_distinct)],
        f"must be distinct names out of {GYRO_SENTENCES}",
    ),
    "sigma_rad": _rule(_number(ge=0.0), "must be >= 0 rad"),
    "latency_s": _LATENCY_RULE,
    "sigma_rot_rad_s": _rule(_number(ge=0.0), "must be >= 0 rad/s"),
    "variation_rad": _rule(_number(ge=-math.pi, le=math.pi), "must be in [-π, π] rad"),
}
_ANEMOMETER_RULES: dict[str, Rule] = {
    "source": _SOURCE_RULE,
    "talker": _TALKER_RULE,
    "rate_hz": _rule(_number(gt=0.0, le=20.0), "must be in (0, 20] Hz"),
    "sigma_speed_mps": _rule(_number(ge=0.0), "must be >= 0 m/s"),
    "sigma_angle_rad": _rule(_number(ge=0.0, le=math.pi), "must be in [0, π] rad"),
    "latency_s": _LATENCY_RULE,
    "unit": _rule(
        _one_of(("M", "N", "K", "S")), "must be one of 'M' (m/s), 'N' (knots), 'K' (km/h), 'S' (mph)"
    ),
}
_MRU_RULES: dict[str, Rule] = {
    "source": _SOURCE_RULE,
    "sentence": _rule(_one_of(MRU_SENTENCES), f"must be one of {MRU_SENTENCES}"),
    "rate_hz": _rule(_number(gt=0.0, le=100.0), "must be in (0, 100] Hz"),
    "sigma_rad": _rule(_number(ge=0.0, le=0.1), "must be in [0, 0.1] rad"),
    "sigma_heading_rad": _rule(_number(ge=0.0, le=0.1), "must be in [0, 0.1] rad"),
    "latency_s": _LATENCY_RULE,
}
COMMAND_LOSS_ACTIONS = ("hold", "stop")
"""What simulated drives do when their commands stop (`ThrusterFeedbackConfig.on_command_loss`)."""
_FEEDBACK_RULES: dict[str, Rule] = {
    "source": _SOURCE_RULE,
    "rate_hz": _rule(_number(gt=0.0, le=50.0), "must be in (0, 50] Hz"),
    "system_id": _rule(_integer(1, 255), "must be in 1..255"),
    "component_id": _rule(_integer(1, 255), "must be in 1..255"),
    "heartbeat_hz": _rule(_number(ge=0.0, le=10.0), "must be in 0..10 Hz (0 = no heartbeat)"),
    "ardupilot_esc": _BOOLEAN_RULE,
    "ardupilot_servo": _BOOLEAN_RULE,
    "ardupilot_motor": _BOOLEAN_RULE,
    "latency_s": _LATENCY_RULE,
    "on_command_loss": _rule(_one_of(COMMAND_LOSS_ACTIONS), "must be 'hold' or 'stop'"),
}


def _validate(obj: object, rules: dict[str, Rule]) -> None:
    """Check the fields of a config dataclass against its rules (pydantic): ``ValueError("<Class>.<field>:
    <what>, got <value>")`` for the first field that fails."""
    for name, (adapter, what) in rules.items():
        value = getattr(obj, name)
        try:
            adapter.validate_python(value)
        except ValidationError:
            raise ValueError(f"{type(obj).__name__}.{name}: {what}, got {value!r}") from None


def _given(obj: object) -> dict[str, Any]:
    """A dataclass' fields as given, for its checks: this module is compiled (setup.py), and reading a field
    through its declared type there fails on a value of another type (a list for a tuple, a string for a
    float) before the check could say what is wrong, or turns an int into a float."""
    return vars(obj)


def _maybe_float(x: Any) -> Any:
    arr = np.asarray(x)
    return float(arr) if arr.ndim == 0 else arr
