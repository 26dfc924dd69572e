"""The typed gateway configuration: what `load_config` returns (frozen values, SI units, radians).

These are the values the rest of the gateway uses; the TOML file's shape and its checks live in
`gateway.config.schema` and `gateway.config.load`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from observers.factory import OBSERVER_TYPES as _OBSERVER_TYPES
from observers.passive_tuning import Check, PassiveTuning
from observers.vessel import VesselModel

PROTOCOLS = ("nmea", "mavlink")
ROLES: dict[str, tuple[str, ...]] = {
    "nmea": ("position", "heading", "wind", "attitude"),
    "mavlink": ("thrusters", "position", "heading"),
}
"""The roles a source of each protocol can have. ``wind``: an anemometer's MWV, for the controller's wind
feed-forward (docs/controller.md). ``attitude``: a motion reference unit's roll and pitch (PASHR, PHTRO),
for the lever-arm compensation of the position sources (docs/gateway.md)."""
OBSERVER_TYPES = _OBSERVER_TYPES  # every observer registered in observers.factory, by name
COMPRESSIONS = ("zstd", "lz4", "none")
ZENOH_MODES = ("peer", "client")
CONTROL_MODES = ("standby", "dp", "manual")
COMMAND_INPUTS = ("mode", "setpoint", "tau")
ALLOCATORS = ("qp", "pseudo_inverse")
POOLINGS = ("weighted", "priority")
ATTITUDE_TIMES = ("sensor", "receive")
FEEDBACKS = ("estimate", "measurement")
CLOCKS = ("wall", "sim")
BAUD_RATES = (
    300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000,
    921600, 1000000, 1152000, 1500000, 2000000, 2500000, 3000000, 3500000, 4000000,
)  # fmt: skip
"""Baud rates a serial source may use (a typo such as 48000 is caught, not tried on the port)."""
ZENOH_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial", "vsock")
SOURCE_NAME = re.compile(r"[a-z0-9_]+")
SIGNING_KEY = re.compile(r"[0-9a-fA-F]{64}")
MAX_ARDUPILOT_INDEX = 32
"""ESC indices (ESC_TELEMETRY_1_TO_4 … 29_TO_32) and servo output channels (SERVO_OUTPUT_RAW) are 1–32."""
MIB = 1024 * 1024


# --- the typed result -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class DatumConfig:
    """Origin of the local NED frame: a fixed point (``lat_deg``, ``lon_deg``, ``alt_m``) or the first fix."""

    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float = 0.0
    first_fix: bool = True

    @property
    def fixed(self) -> bool:
        return not self.first_fix


@dataclass(frozen=True)
class ArdupilotMap:
    """ArduPilot feedback → thrusters: ESC index → thruster id (rpm), servo channel → thruster (azimuth), and
    the servo calibration: azimuth = π (pwm − servo_neutral_us) / servo_half_turn_us; ESC index → (servo
    channel of its reversible motor output, that output's neutral µs): the direction of its rpm, with the
    dead band ± esc_dead_band_us around the neutral."""

    esc: Mapping[int, int] = field(default_factory=dict)
    servo: Mapping[int, int] = field(default_factory=dict)
    servo_neutral_us: float = 1500.0
    servo_half_turn_us: float = 400.0
    esc_direction_servo: Mapping[int, tuple[int, float]] = field(default_factory=dict)
    esc_dead_band_us: float = 25.0


@dataclass(frozen=True)
class SourceConfig:
    """One ``[[sources]]`` entry.

    ``transport`` is the kind of link the URL names: ``serial``, ``udp``, ``tcp``, ``tcp-listen``, ``file``
    (the gateway's URLs) or ``pymavlink`` (a pymavlink connection string, MAVLink only). ``url`` is as
    written, except that a relative ``file:`` path is made absolute (``file:///...``).
    ``system_id`` / ``component_id`` None accept any MAVLink system / component. ``signing_key`` is the
    32-byte MAVLink 2 signing secret. ``allow_unsigned``: with a key, also accept unsigned frames; without
    one, on a link with ``commands``, send the thruster commands unsigned (the operator's written choice).
    """

    name: str
    url: str
    protocol: str
    roles: tuple[str, ...]
    transport: str
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    timeout_s: float = 2.0
    allow_missing_checksum: bool = False
    tag_source: str | None = None  # NMEA: only the sentences whose TAG block names this device (s:)
    priority: int = 1
    system_id: int | None = None
    component_id: int | None = None
    signing_key: bytes | None = field(default=None, repr=False)
    allow_unsigned: bool = False
    ardupilot: ArdupilotMap | None = None
    commands: bool = False  # MAVLink thrusters: send the dialect's AZIMUTH_THRUSTER_COMMAND on this link

    def has_role(self, role: str) -> bool:
        return role in self.roles


@dataclass(frozen=True)
class ObserverConfig:
    """The observer: its type, tuning, whether failed checks are allowed, and its update rate (epochs/s).

    ``checks`` are the results of the tuning rule (48) and the SPR check of Proposition 1 for the vessel
    (all ok unless ``allow_unchecked``).
    """

    type: str
    tuning: PassiveTuning
    allow_unchecked: bool = False
    rate_hz: float = 10.0
    checks: tuple[Check, ...] = ()
    params: Mapping[str, Any] = field(default_factory=dict)
    """Settings of the adaptive observers beyond the passive tuning (`observers.factory.OBSERVER_PARAMS`)."""

    @property
    def failed_checks(self) -> tuple[Check, ...]:
        return tuple(c for c in self.checks if not c.ok)


@dataclass(frozen=True)
class ZenohConfig:
    """The Zenoh session; ``prefix`` is resolved (default ``dp/<vessel name>``).

    Turned into a `zenoh.Config` by the gateway (`gateway.bus.make_config`), not here: the config sits
    below the bus and opens nothing."""

    prefix: str
    mode: str = "peer"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    config_file: Path | None = None
    multicast_scouting: bool = True
    users_file: Path | None = None
    """Zenoh user/password dictionary (``user:password`` lines): every peer must authenticate as one."""
    user: str = ""
    password: str = field(default="", repr=False)
    """This session's own credentials, for a router or peer that requires them (read from a file)."""
    commanders: tuple[str, ...] = ()
    """Users (of ``users_file``) whose puts on the command keys are let through; empty: no access
    control (every peer that may connect may command, if ``[commands]`` accepts the input)."""


@dataclass(frozen=True)
class LogConfig:
    """The MCAP log. ``path`` None: logging disabled. Limits of 0 (rotation) mean never."""

    path: Path | None
    rotate_mb: float = 1024
    rotate_minutes: float = 60
    flush_interval_s: float = 1.0
    compression: str = "zstd"

    @property
    def enabled(self) -> bool:
        return self.path is not None

    def writer_options(self) -> dict[str, Any]:
        """Keyword arguments of `wire.mcap.writer.McapLogWriter` (besides the path)."""
        return {
            "rotate_bytes": int(self.rotate_mb * MIB) if self.rotate_mb > 0 else None,
            "rotate_seconds": self.rotate_minutes * 60.0 if self.rotate_minutes > 0 else None,
            "flush_interval_s": self.flush_interval_s,
            "compression": self.compression,
        }


@dataclass(frozen=True)
class ControlConfig:
    """The DP controller and thrust allocation : control rate on the event clock (Hz), the mode at
    start, the allocator, and the controller's closed-loop bandwidth (rad/s; None = the vessel's
    Froude-scaled default) and damping."""

    rate_hz: float = 10.0
    initial_mode: str = "standby"
    wait_for_observer: bool = True
    """With ``initial_mode = "dp"``: hold standby until the observer's estimate has settled
    (`Observer.settle_time_s` after its first estimate), then engage DP by itself, as an operator engages
    once the observer is ready; False: DP from the first estimate."""
    allocator: str = "qp"
    bandwidth_rad_s: float | tuple[float, float, float] | None = None
    damping: float = 1.0
    feedback: str = "estimate"
    """What the controller's position/heading term sees: the observer's LF estimate (always, at sea), or
    the raw measurement — only to demonstrate what wave filtering buys (the same controller, same ν̂)."""
    return_speed_mps: float | None = None
    """Speed limit of a governed return to the station after the vessel was far off its reference
    (docs/controller.md); None: the reference model's speed limit (0.5 m/s at 76.2 m, Froude-scaled)."""
    wind_feedforward_gain: float = 1.0
    """k_w ∈ [0, 1] of the wind feed-forward from a ``wind`` source (0: off)."""
    wind_filter_s: float = 2.0
    """Time constant (s) of the low-pass on the measured wind before the feed-forward."""
    wind_loss_fade_s: float | None = None
    """After the wind is lost, its last force fades linearly to zero over this time (s; 0: drops at
    once); None: twice the slower of the controller's integral time and the observer's bias mode
    (docs/controller.md)."""
    takeover_fade_s: float | None = None
    """After a bumpless entry into DP, the τ held before entry fades into the control law's own (the
    load the bias estimate knows) over this time (s; 0: at once); None: 1/ωn of the slowest DOF
    (docs/controller.md, "Modes and bumpless transfer")."""


@dataclass(frozen=True)
class ConsequenceConfig:
    """The online consequence analysis (docs/controller.md, "Consequence analysis"): whether it runs (in
    DP, with a thruster layout), the worst-case failures it tests (groups of thruster ids lost together;
    empty: each thruster alone) and the time constant (s) of the mean load it tests them against."""

    enabled: bool = True
    failure_groups: tuple[tuple[int, ...], ...] = ()
    filter_s: float = 30.0


@dataclass(frozen=True)
class CommandsConfig:
    """Which Zenoh command inputs the pipeline takes (none unless listed), the setpoint's largest
    distance from the present position (m), and how long a manual τ is held without a new one (s; inf:
    until the next one) before the thrust demand goes to zero (the dead-man, docs/config.md)."""

    accept: frozenset[str] = frozenset()
    max_setpoint_distance_m: float = 50.0
    manual_tau_hold_s: float = 2.0


@dataclass(frozen=True)
class StatusConfig:
    """How often ``<prefix>/status`` is published (Hz)."""

    rate_hz: float = 1.0


@dataclass(frozen=True)
class TimeConfig:
    """``[time]``: what the gateway stamps received data with. ``wall``: this computer's clock (at sea,
    always). ``sim``: the simulation time a simulator publishes on ``<prefix>/sim/clock``
    (`gateway.sim_time`), so the observer, controller and log live on the plant's time however far a busy
    simulator falls behind the wall."""

    clock: str = "wall"

    @property
    def sim(self) -> bool:
        return self.clock == "sim"


@dataclass(frozen=True)
class KeelsonConfig:
    """``[keelson]``: publish under Keelson's key space on the gateway's Zenoh session
    (`gateway.outputs.keelson`, docs/keelson.md). Each ``*_source_id`` is the last part of the keys of one
    stream; ``sensor_source_id`` holds ``{source}``, replaced by each input source's name."""

    enabled: bool = False
    base_path: str = "keelson"
    entity_id: str = ""
    estimate_source_id: str = "dpgw/estimate"
    measurement_source_id: str = "dpgw/measurement"
    sensor_source_id: str = "dpgw/sensor/{source}"
    demand_source_id: str = "dpgw/control/demand"
    allocated_source_id: str = "dpgw/control/allocated"
    feedback_source_id: str = "dpgw/thrusters/feedback"
    log_source_id: str = "dpgw"

    def sensor(self, source: str) -> str:
        """The source id of one input source (its raw sentences and its fixes)."""
        return self.sensor_source_id.replace("{source}", source)


@dataclass(frozen=True)
class Ros2Config:
    """``[ros2]``: ROS 2 topics in rmw_zenoh's format on the gateway's Zenoh session
    (`gateway.outputs.ros2`, docs/ros2.md). Topic names are relative to ``namespace`` unless they start
    with ``/``; each GNSS receiver's fixes go out on ``<fix_topic>/<source name>``."""

    enabled: bool = False
    domain_id: int = 0
    namespace: str = "/dpgw"
    node_name: str = "dpgw"
    frame_id: str = "ltp"
    """The world frame (ENU at the datum) of the odometry and poses, and the only frame a setpoint may
    be given in."""
    child_frame_id: str = "vessel"
    """The vessel frame (FLU at the reference point) the odometry's twist is in."""
    publish_tf: bool = True
    """Broadcast the odometry's pose as the moving transform ``frame_id`` → ``child_frame_id`` on ``/tf``
    (as robot_localization does by default); off where another ROS node already broadcasts it (two
    broadcasters of one transform fight)."""
    odom_topic: str = "odom"
    pose_topic: str = "pose"
    fix_topic: str = "fix"
    setpoint_topic: str = "setpoint"

    def topics(self) -> dict[str, str]:
        """The topic names by config key."""
        return {
            "odom_topic": self.odom_topic,
            "pose_topic": self.pose_topic,
            "fix_topic": self.fix_topic,
            "setpoint_topic": self.setpoint_topic,
        }


@dataclass(frozen=True)
class FoxgloveConfig:
    """``[foxglove]``: the live Foxglove WebSocket server (`gateway.outputs.foxglove_server`,
    docs/foxglove.md "Live"). Off by default: a vessel's gateway serves no one it was not told to. The
    server has no authentication, so it binds to this computer only (127.0.0.1) unless ``host`` says
    otherwise. ``port`` 0: any free port (the one bound is printed at start)."""

    enabled: bool = False
    host: str = "127.0.0.1"
    port: int = 8765


@dataclass(frozen=True)
class IntegrityConfig:
    """``[integrity]``: thresholds of the reference tests (defaults for DGPS-class references and a gyro;
    `gateway.references` applies them, docs/integrity.md explains them)."""

    gga_quality: tuple[int, ...] = (1, 2, 4, 5)
    """GGA fix qualities accepted: GPS, DGPS, RTK fixed, RTK float. 3 (PPS), 6 (dead reckoning), 7 (manual)
    and 8 (simulator) are not measurements of where the antenna is."""
    pooling: str = "weighted"
    """How usable sources of one role combine: ``weighted`` (inverse measured variance) or ``priority``
    (the lowest ``priority`` that is usable, the others are hot standby)."""
    readmit_s: float = 5.0
    """A rejected source is used again only after it has passed every test for this long (not used while
    readmitting). A heading rejected by a jump that comes back on its track of before the jump (a spike)
    is used again on its second sample; past this long the ordinary readmission applies."""
    max_speed_m_s: float = 5.0
    """Fastest plausible speed over ground: bounds how far a fix may move from the source's last good one."""
    jump_m: float = 5.0
    """Jump allowance on top of speed × time (noise and multipath of a good fix)."""
    max_rate_deg_s: float = 10.0
    """Fastest plausible rate of turn (a DP vessel turns a few °/s)."""
    heading_jump_deg: float = 2.0
    """Heading jump allowance on top of rate × time. A gyro or GNSS compass is good to 0.1-0.3°, so 2° is
    over six times the worst; a USV's GNSS compass at sea gave one-sample spikes of 6-7° that the former
    5° let through at 5 Hz (a 7° limit), each moving the LF heading estimate up to 1.7°."""
    freeze_s: float = 5.0
    """A position repeated bit for bit this long is frozen (a live receiver's last digits always move)."""
    heading_freeze_s: float = 20.0
    """The longest time a heading may repeat the same value bit for bit before it is frozen, however
    rarely its last digit changes (a gyro on a steady heading in calm water repeats a 0.1° value for
    seconds): the bound on how long a frozen gyro is believed."""
    heading_freeze_min_s: float = 2.0
    """The shortest such time: the hold when the heading's last digit changes from nearly every sample to
    the next (yaw in any sea way). Between the two, each heading source is held by how often its own
    values repeat, learned as it passes (docs/integrity.md, "Freeze"). At or above ``heading_freeze_s`` the
    hold is ``heading_freeze_s`` whatever the source's activity (the fixed hold of earlier versions)."""
    max_sigma_m: float = 3.0
    """A source whose measured 1σ noise exceeds this is rejected (variance test)."""
    prediction_gate_m: float = 5.0
    """Largest innovation (fix − the observer's prediction) accepted, plus 3σ of the source's noise."""
    prediction_gate_deg: float = 10.0
    """Largest heading innovation accepted."""
    prediction_max_age_s: float = 10.0
    """The prediction test is only applied while the estimate had a measurement this recently (an old
    prediction must not lock out the only reference back from a silence); its gate grows with the age at
    max_speed/10. In DP, references refused while their data kept coming stay tested past it, the gate
    held at its width here: time alone never lets a reference that jumped take the vessel."""
    median_m: float = 0.75
    """With three or more position references: a reference whose smoothed position is farther than this
    from the median of all is rejected (catches slow drift: 1 m/min is out within a minute)."""
    divergence_m: float = 1.0
    """With two position references: smoothed positions farther apart than this raise an alarm."""
    heading_median_deg: float = 1.0
    """The median test for three or more gyros."""
    heading_divergence_deg: float = 2.0
    """The divergence alarm for two gyros."""
    smoothing_s: float = 5.0
    """Time constant of the smoothed track the median and divergence tests compare (averages the noise)."""
    min_sigma_m: float = 0.1
    """Floor of a source's measured 1σ in the variance weighting (one very quiet source must not take all
    the weight)."""
    lost_after_s: float = 30.0
    """Dead reckoning longer than this (no usable position reference) is reported as ``lost``; a reference
    that returns after that restarts the observer from its measurement, as at start-up."""
    restart_confirm_s: float = 2.0
    """A DOF whose references return after a break (not yet ``lost``) outside the prediction gate of the
    dead-reckoned estimate is held back from the observer and not tested against the prediction while it
    confirms itself: once it has been measured this long without a break, the observer restarts from the
    measurement if it still lies outside the gate (the dead-reckoned estimate drifted; feeding the
    returning reference slowly would let the prediction test reject every other fix for a minute), and
    carries on with it if not. A return inside the gate carries on at once."""
    dead_reckoning_rate_hz: float = 10.0
    """While no measurement steps the observer, a dead-reckoned estimate is published at this rate."""
    thrust_margin: float = 1.2
    """Feedback thrust beyond the thruster's capacity × this is out of range (a report, not a thrust)."""
    feedback_rejects: int = 3
    """This many out-of-range feedback frames within ``readmit_s`` reject a feedback source in use: τ for
    the observer comes from the demand until it has been clean for ``readmit_s``. One rejects a source
    not in use (stale, not heard from yet, readmitting): there are no good reports around it to keep."""
    attitude_max_deg: float = 30.0
    """An MRU's |roll| or |pitch| beyond this is out of range. A vessel rolling 30° is far past any DP
    operation's limit and near capsize for most hulls; a sentence saying so is a fault (an MRU mounted or
    configured wrongly, a unit still aligning)."""
    attitude_max_rate_deg_s: float = 20.0
    """Fastest plausible roll or pitch rate: roll φ = φₐ sin(2πt/T) turns at most φₐ 2π/T, and ±20° at a
    6 s period (a stiff small vessel in a beam sea, far past DP limits) is 21°/s. At 10 Hz, 2° a sample."""
    attitude_jump_deg: float = 1.0
    """Allowance on top of rate × time between consecutive MRU samples (a DP MRU is good to 0.01-0.05°,
    a sentence rounds to 0.01°): with the rate, 3° between samples at 10 Hz."""
    attitude_freeze_s: float = 2.0
    """The shortest time an MRU may repeat the same roll and pitch exactly (the decoded values, bit for
    bit) before it is frozen: the hold when its last digit changes from nearly every sample to the next
    (any sea way). A quieter MRU is held longer, by how often its own last digit changes (up to
    ``attitude_freeze_max_s``; `gateway.references.attitude`)."""
    attitude_freeze_max_s: float = 30.0
    """The longest time an MRU may repeat the same roll and pitch exactly before it is frozen, however
    rarely its last digit changes (flat calm, an MRU much quieter than its sentence's 0.01°): the bound on
    how long a frozen MRU is believed. 30 s: a frozen MRU in flat calm is wrong by the little the hull
    moves in that time, and an MRU whose noise is a quarter of its resolution (0.0025° at 0.01°) is held
    22.5 s, which it repeats by chance less than once in 10⁹ run starts (docs/integrity.md). At or
    below ``attitude_freeze_s`` the hold is ``attitude_freeze_s`` whatever the MRU's activity (the fixed
    hold of earlier versions)."""
    attitude_max_sigma_deg: float = 0.5
    """An MRU reporting its own roll or pitch 1σ (PASHR fields 7-8) above this is not trusted: a DP MRU
    reports 0.01-0.05°; an INS still aligning or unaided reports degrees. 0.5° on a 25 m mast is 0.2 m."""
    attitude_rejects: int = 3
    """An MRU sample that fails a test is never used; this many within ``readmit_s`` reject the MRU (heading
    only until it has passed for ``readmit_s``). One spike (one failing sample) is dropped while the
    samples around it go on compensating; a frozen, offset or out-of-range MRU is out on its third. One
    rejects an MRU not in use (stale, not heard from yet, readmitting)."""
    attitude_time: str = "sensor"
    """How an attitude is paired with a fix: ``sensor`` (by both sentences' own UTC times where both have
    one: PASHR and GGA/GNS; else by receive time) or ``receive`` (by receive time always: for an MRU whose
    clock is not GNSS time)."""


@dataclass(frozen=True)
class GatewayConfig:
    """A complete, validated gateway configuration.

    ``vessel_source`` is the built-in vessel's name or the vessel file's absolute path.
    ``reference_point_m`` is the body-frame point (x forward, y starboard, m) the estimates refer to.
    ``path`` is the config file (for a dict given to `parse_config`: ``base_dir / where``).
    """

    vessel: VesselModel
    vessel_source: str
    reference_point_m: tuple[float, float]
    datum: DatumConfig
    sources: tuple[SourceConfig, ...]
    observer: ObserverConfig
    zenoh: ZenohConfig
    log: LogConfig
    status: StatusConfig
    path: Path
    control: ControlConfig = field(default_factory=ControlConfig)
    consequence: ConsequenceConfig = field(default_factory=ConsequenceConfig)
    integrity: IntegrityConfig = field(default_factory=IntegrityConfig)
    commands: CommandsConfig = field(default_factory=CommandsConfig)
    time: TimeConfig = field(default_factory=TimeConfig)
    keelson: KeelsonConfig = field(default_factory=KeelsonConfig)
    ros2: Ros2Config = field(default_factory=Ros2Config)
    foxglove: FoxgloveConfig = field(default_factory=FoxgloveConfig)

    def sources_for(self, role: str) -> tuple[SourceConfig, ...]:
        """The sources with ``role``, in failover order (lowest priority first)."""
        return tuple(sorted((s for s in self.sources if role in s.roles), key=lambda s: s.priority))

    def source(self, name: str) -> SourceConfig:
        for s in self.sources:
            if s.name == name:
                return s
        raise KeyError(name)
