"""The pipeline: a deterministic function from time-ordered input events to outputs (DESIGN.md rule 1).

    raw chunk (source, rx time, bytes) → framing → decoding → fusion → observer → outputs

Live, events come from the sources stamped by the clock (`gateway.service`); in replay they come from a
log as fast as the CPU allows (`gateway.replay`). Same code, same events, same numbers. Nothing here reads
a clock, opens a socket or writes a file: outputs are returned to the caller, who publishes and logs them.

Bad input never stops it (rule 4): a sentence or frame that cannot be used is counted per source and
reason, and the caller has already logged the raw bytes.

**When the observer steps.** Once per input chunk that brought a new measurement, at that chunk's receive
time, with every DOF's latest measurement held (`gateway.fusion`). A chunk usually carries one sentence,
a datagram may carry a burst; one step per chunk avoids zero-length steps. The estimate is published at
once (latency), and stepping is driven only by the events (determinism).
"""

from __future__ import annotations

import copy
import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Final

import numpy as np
from mypy_extensions import mypyc_attr

from gateway.alarms import alarm_key, alarm_level
from gateway.commands import HEALTHY_FOR_DP, CommandGate
from gateway.config import (
    ArdupilotMap,
    CommandsConfig,
    ConsequenceConfig,
    ControlConfig,
    GatewayConfig,
    IntegrityConfig,
    wind_feedforward_off,
)
from gateway.control.allocation import AllocationResult, PseudoInverseAllocator, QPAllocator, ThrusterCommand
from gateway.control.consequence import ConsequenceAnalysis, FailureCase
from gateway.control.controller import ControllerTuning, DPController
from gateway.control.wind_feedforward import observer_bias_time_s
from gateway.esc_direction import EscDirections
from gateway.foxglove_channels import FoxgloveChannels
from gateway.fusion import NS, Fusion, rms_sigma_m
from gateway.references import ReferenceMonitor
from gateway.references.monitor import Prediction
from gateway.references.state import reference_name
from observers.base import (
    STATUS_DEAD_RECKONING,
    STATUS_INITIALIZING,
    STATUS_NAMES,
    STATUS_OK,
    Estimate,
    Observer,
)
from observers.factory import make_observer
from observers.kinematics import ssa_scalar
from observers.vessel import VesselModel
from wire.codecs import mavlink as mv
from wire.codecs import nmea as nmea_codec
from wire.codecs.nmea_framing import AIS, COMMENT, IEC_61162_450, TAG_BLOCK, Frame, NmeaFramer
from wire.codecs.nmea_tag import OTHER_TAG_SOURCE, TagBlock, TagReject, decode_tag, next_line
from wire.codecs.nmea_time import utc_step_s
from wire.foxglove import antenna_frame, ellipsoidal_height_m, location_fix
from wire.geodesy import LocalFrame
from wire.gst_covariance import INCONSISTENT, GstCovariance, gst_covariance, unit_shape
from wire.messages import (
    AlarmDetail,
    CommandStatus,
    ConsequenceStatus,
    Datum,
    FailureCaseStatus,
    Measurement,
    Message,
    ReferenceStatus,
    SetpointStatus,
    SigningRejection,
    SourceStatus,
    Status,
    Thruster,
    ThrusterFeedback,
)
from wire.messages import Estimate as EstimateMessage
from wire.messages import ThrusterCommand as CommandMessage

MAX_LINE_GAP: Final = 100
"""Most lines a device's TAG line count may skip and be taken for lines lost (`Pipeline._tag_seen`): 10 s of a
10 Hz device sending one sentence a cycle; a larger jump is a restart, not a loss."""
USED_NMEA = frozenset({"GGA", "GNS", "HDT", "THS", "HDG", "GST", "MWV", "VWR"})
_CYCLE_KINDS: Final = frozenset({"GGA", "GNS", "HDT", "THS", "HDG"})
"""The sentences that are a cycle's measurement (a fix, a heading): one of them again from the same talker
in one read starts the source's next cycle (`Pipeline._cycles`). Not GST, wind or attitude sentences, which
ride with a cycle; nor a receiver's several GSV, never used."""
"""Sentences the fusion uses; others (RMC, VTG, ZDA, ROT ...) are checked and counted, not parsed."""
RAW_VELOCITY_FILTER_S = 1.0
WIND_ON_CONFIRM_S = 10.0
"""After the wind feed-forward was announced off, how long the wind must be fresh without a break before
it is announced on again (`Pipeline._relative_wind`): an anemometer that loses most of its sentences
(corrupt, invalid) goes stale and fresh again every few seconds, and an operator told "off", "on", "off"
… at that rate stops reading the events. Longer than the gaps of such a flapping source (a timeout of a
few seconds) and than the feed-forward's filter ramp (≈ 3 T_w = 6 s at the default filter). After a loss
the force comes back at the pace it faded (`WindFeedForward`), and "on" says how long that still takes.
The feed-forward itself uses every fresh wind at once."""
"""Dirty-derivative filter of the measurement-fed comparison controller (no wave filter)."""
_INITIALIZING = STATUS_NAMES[STATUS_INITIALIZING]
FIX_PERIOD_NS = 0
"""Least time between two `foxglove.LocationFix` of one GNSS source: 0, every fix (the map shows each
receiver's own scatter; what it costs a replay is measured in docs/foxglove.md). `bench/bench_foxglove.py`
sets it to compare."""
TICK_KEY = "tick"
"""The `ControlEvent` key of a live tick that dead-reckoned (`Pipeline.tick`), logged on `TICK_TOPIC`."""
TICK_TOPIC = f"/dp/{TICK_KEY}"
"""The log's topic of those ticks: the service writes them there, a replay feeds them back from there."""


@mypyc_attr(native_class=False)
@dataclass(frozen=True, init=False)
class RawEvent:
    """A chunk of bytes as received: UTC receive time (ns), source name, bytes.

    ``peer``: the sender, where one source hears several (UDP). Every sender has its own framer, so two
    senders' partial sentences never splice into one.

    ``checked`` (NMEA only, set by replay's log reader): the chunk is whole lines, each a clean sentence
    whose framing and checksum the reader has already verified (`wire.codecs.nmea_scan`); it holds the
    texts of the sentences the pipeline uses (`USED_NMEA`, proprietary ones too), in order, and the count
    of the other good sentences. The pipeline then skips the framer and counts the others unparsed — the
    outputs are the same as from ``data`` (tests/test_replay.py compares both).
    """

    rx_ns: int
    source: str
    data: bytes
    checked: tuple[tuple[str, ...], int] | None = None
    peer: str = ""
    """Who sent it on a shared link (a UDP sender's ``host:port``); each sender is framed on its own."""
    records: tuple[Any, ...] | None = None
    """In place of ``data`` (the in-process closed loop, where nothing crosses a wire): one item per
    sentence or frame, as the codecs decode it — an NMEA sentence (`wire.codecs.nmea`; None for one the
    pipeline does not use) or a MAVLink frame's tuple of `wire.codecs.mavlink` reports. The pipeline skips
    framing and decoding and does the rest exactly as for bytes; a record carries no MAVLink system or
    component id, so a source's ``system_id`` / ``component_id`` filter does not apply to it."""
    cycle: bool = False
    """The chunk is one cycle of its source by construction (a text log's reader cuts the log by the
    sentences' own times): it is not cut again as a read that holds several cycles is (`Pipeline._cycles`)."""

    def __init__(
        self,
        rx_ns: int,
        source: str,
        data: bytes,
        checked: tuple[tuple[str, ...], int] | None = None,
        peer: str = "",
        records: tuple[Any, ...] | None = None,
        cycle: bool = False,
    ) -> None:
        # Frozen like the generated __init__ makes it, but filled in directly: that one sets each field
        # through object.__setattr__, 1.5 µs an event against 0.3 (replay makes one per cycle).
        d = self.__dict__
        d["rx_ns"], d["source"], d["data"], d["checked"], d["peer"] = rx_ns, source, data, checked, peer
        d["records"], d["cycle"] = records, cycle


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ControlEvent:
    """An input from Zenoh (setpoint, mode, manual τ), logged so replay sees it too."""

    rx_ns: int
    key: str  # "setpoint" | "mode" | "tau"
    payload: Any


@mypyc_attr(native_class=False)
@dataclass(frozen=True, init=False)
class Output:
    """Something to publish and/or log: MCAP topic (the Zenoh key is the prefix + the part after /dp) and
    the typed message (`wire.messages`: it encodes itself, once, for Zenoh and the log)."""

    topic: str
    message: Message
    stamp_ns: int
    zenoh: bool = True

    def __init__(self, topic: str, message: Message, stamp_ns: int, zenoh: bool = True) -> None:
        # (filled in directly, as `RawEvent` is: three or four outputs per observer step)
        d = self.__dict__
        d["topic"], d["message"], d["stamp_ns"], d["zenoh"] = topic, message, stamp_ns, zenoh

    @cached_property
    def payload(self) -> dict[str, Any]:
        """The message as a plain dict, for consumers that index it by field name (made on first use)."""
        return self.message.to_dict()


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class SourceSpec:
    """What the pipeline needs to know of a source (built from the config)."""

    name: str
    protocol: str  # "nmea" | "mavlink"
    roles: frozenset[str]
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    timeout_s: float = 2.0
    allow_missing_checksum: bool = False
    tag_source: str | None = None  # only the sentences whose TAG block names this device (`_take_frames`)
    priority: int = 1
    signing_key: bytes | None = None
    allow_unsigned: bool = True
    ardupilot: mv.ArduPilotWiring | None = None  # ArduPilot ESC / servo outputs -> the vessel's thrusters
    system_id: int | None = None  # MAVLink: frames from another system are rejected (None: any)
    component_id: int | None = None  # MAVLink: frames from another component are rejected (None: any)
    signatures_from_a_log: bool = False
    """MAVLink signing checked on logged frames (replay): a stream's first timestamp is taken whatever its
    age, then each frame's must grow as live. Live (False), a new stream more than a minute behind this
    host's clock is a replay and rejected, which is every stream of a log recorded more than a minute
    ago."""
    logged_verdicts: Mapping[tuple[str, int], tuple[mv.LoggedVerdict, ...]] | None = field(
        default=None, compare=False
    )
    """A replay of a signed link whose log holds no key but the live gateway's verdicts
    (`/raw/mavlink_rejected/<source>`): (peer, chunk receive time ns) → the frames of that chunk the live
    gateway refused for signing. Those frames are refused for the logged reason, the others taken
    unchecked (`Pipeline.unmatched_verdicts`: those that found no frame). None: signatures are checked
    with ``signing_key``, or not at all without one."""

    @cached_property
    def timeout_ns(self) -> int:
        """How long a measurement from this source stays valid (ns; computed once, used per sentence)."""
        return int(self.timeout_s * NS)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class PipelineSpec:
    vessel: VesselModel
    sources: tuple[SourceSpec, ...]
    observer: Observer
    observer_name: str = "passive"
    datum: tuple[float, float, float] | None = None  # (lat, lon, alt); None = first fix
    reference_point_m: tuple[float, float] = (0.0, 0.0)
    extra_observers: tuple[tuple[str, Observer], ...] = ()
    """More observers fed the same y and τ (replay: side by side), published on /dp/estimates/<label>."""
    control: ControlConfig | None = None
    """DP controller and allocation; None: estimation only."""
    integrity: IntegrityConfig = field(default_factory=IntegrityConfig)
    """Reference and feedback tests (`gateway.references`)."""
    commands: CommandsConfig = field(default_factory=CommandsConfig)
    """Which command inputs are taken (none by default) and their limits (`gateway.commands`)."""
    consequence: ConsequenceConfig = field(default_factory=ConsequenceConfig)
    """The online consequence analysis in DP (`gateway.control.consequence`)."""
    foxglove_channels: bool = True
    """Make the Foxglove-native channels (`gateway.foxglove_channels`, and each GNSS fix's
    `foxglove.LocationFix`). On by default, so every log opens in Foxglove as it is; `dpgw replay
    --no-foxglove-channels` turns them off where only the JSON channels are wanted (a faster replay:
    on a 5 Hz log they are half of the messages written)."""

    @classmethod
    def from_config(cls, config: GatewayConfig) -> PipelineSpec:
        sources = tuple(
            SourceSpec(
                name=sc.name,
                protocol=sc.protocol,
                roles=frozenset(sc.roles),
                lever_arm_m=sc.lever_arm_m,
                timeout_s=sc.timeout_s,
                allow_missing_checksum=sc.allow_missing_checksum,
                tag_source=sc.tag_source,
                priority=sc.priority,
                signing_key=sc.signing_key,
                allow_unsigned=sc.allow_unsigned,
                ardupilot=_wiring(sc.ardupilot),
                system_id=sc.system_id,
                component_id=sc.component_id,
            )
            for sc in config.sources
        )
        observer = make_observer(
            config.observer.type,
            config.vessel,
            config.observer.tuning,
            params=config.observer.params,
            allow_unchecked=config.observer.allow_unchecked,
        )
        d = config.datum
        datum = (
            None if d.first_fix or d.lat_deg is None or d.lon_deg is None else (d.lat_deg, d.lon_deg, d.alt_m)
        )
        return cls(
            vessel=config.vessel,
            sources=sources,
            observer=observer,
            observer_name=config.observer.type,
            datum=datum,
            reference_point_m=config.reference_point_m,
            control=config.control,
            integrity=config.integrity,
            commands=config.commands,
            consequence=config.consequence,
        )


def _wiring(ardupilot: ArdupilotMap | None) -> mv.ArduPilotWiring | None:
    if ardupilot is None:
        return None
    return mv.ArduPilotWiring(
        esc=dict(ardupilot.esc),
        servo=dict(ardupilot.servo),
        servo_neutral_us=ardupilot.servo_neutral_us,
        servo_half_turn_us=ardupilot.servo_half_turn_us,
        esc_direction=dict(ardupilot.esc_direction_servo),
        esc_dead_band_us=ardupilot.esc_dead_band_us,
    )


NOT_BAD_INPUT = frozenset((AIS, COMMENT, TAG_BLOCK, IEC_61162_450, OTHER_TAG_SOURCE))
"""Reject reasons that are not bad input (counted, not used, not wrong): they say nothing of a source's
health, and a source's good input may come with them on every line (a TAG block, a datagram header)."""


def reasons_text(counts: Counter[str]) -> str:
    """``bad_checksum 80, no_checksum 3``: the three commonest reasons with their counts."""
    return ", ".join(f"{reason} {n}" for reason, n in counts.most_common(3))


@dataclass
class SourceCounters:
    received: int = 0  # sentences/frames decoded and used or understood
    rejected: Counter[str] = field(default_factory=Counter)
    warnings: Counter[str] = field(default_factory=Counter)  # used, with a caveat (not rejected)
    bytes: int = 0
    last_rx_ns: int = 0
    dropped: int = 0  # lost before the gateway read them (the kernel's count; the service sets it)
    skipped_bytes: int = 0  # MAVLink: bytes outside any valid frame (the frame parsers' count)
    lost_lines: int = 0  # NMEA over IEC 61162-450: lines the TAG blocks' line counts skipped (`_tag_seen`)
    # the link's: times it came back after it was lost, and when (UTC ns) and why it was last lost (the
    # transport counts them where the link is lost and comes back; the service copies them for a status)
    reconnects: int = 0
    last_disconnect: tuple[int, str] | None = None
    # What the statuses saw of the good input (`bad_input_alarm`): the count received, the receive time by
    # which it had last grown (while nothing was good yet: the first read a status saw; 0: no read yet)
    # and the rejects then. A source whose bytes keep coming while nothing in them is good (a wrong baud
    # rate, a corrupting link: every checksum bad) is not silent, and must not read as "no data" or as
    # fresh: it is alarmed by what is wrong with it.
    good_seen: int = 0
    last_good_ns: int = 0
    rejected_at_good: Counter[str] = field(default_factory=Counter)

    def bad_input_alarm(self, name: str, now_ns: int, timeout_s: float) -> str | None:
        """Note the good input since the last status; then ``source NAME: no valid data for 8.0 s (80
        rejected: bad_checksum 80)`` when reads have kept coming with nothing good in them for longer than
        ``timeout_s``: what was rejected since the last good input, most first, not-bad reasons left out."""
        if self.received != self.good_seen:  # good input since the last status: up to its latest read
            self.good_seen, self.last_good_ns = self.received, self.last_rx_ns
            self.rejected_at_good = Counter(self.rejected)
        elif not self.last_good_ns:
            self.last_good_ns = self.last_rx_ns  # nothing good yet: counted from the first read
        since = self.last_good_ns
        if not since or (now_ns - since) / NS <= timeout_s:
            return None
        grown = self.rejected_since_good()
        if not grown:
            return None  # (bytes that are not even rejects: the framers hold them; the stale rule says it)
        return (
            f"source {name}: no valid data for {(now_ns - since) / NS:.1f} s "
            f"({sum(grown.values())} rejected: {reasons_text(grown)})"
        )

    def rejected_since_good(self) -> Counter[str]:
        """The rejects since the good input the last status saw, not-bad reasons (`NOT_BAD_INPUT`) left
        out: what is wrong with a source whose reads keep coming with nothing good in them."""
        return Counter(
            {r: n for r, n in (self.rejected - self.rejected_at_good).items() if r not in NOT_BAD_INPUT}
        )

    def as_message(self, now_ns: int) -> SourceStatus:
        age = (now_ns - self.last_rx_ns) / NS if self.last_rx_ns else None
        return SourceStatus(
            age_s=age,
            received=self.received,
            rejected=dict(self.rejected),
            warnings=dict(self.warnings),
            bytes=self.bytes,
            dropped=self.dropped,
            skipped_bytes=self.skipped_bytes,
            lost_lines=self.lost_lines,
            reconnects=self.reconnects,
            last_disconnect=None if self.last_disconnect is None else self.last_disconnect[1],
            last_disconnect_ns=None if self.last_disconnect is None else self.last_disconnect[0],
        )


class Pipeline:
    def __init__(self, spec: PipelineSpec) -> None:
        self.spec = spec
        self.observer = spec.observer
        datum = LocalFrame(*spec.datum) if spec.datum is not None else None
        ip = spec.integrity
        self.fusion = Fusion(
            spec.vessel, datum=datum, reference_point_m=spec.reference_point_m, pooling=ip.pooling
        )
        self.esc_directions = EscDirections()  # the sign of ArduPilot ESC rpm, from the motor outputs

        def by_role(role: str) -> dict[str, int]:
            return {s.name: s.timeout_ns for s in spec.sources if role in s.roles}

        self.monitor = ReferenceMonitor(
            ip,
            by_role("position"),
            by_role("heading"),
            by_role("thrusters"),
            {t.id: t for t in spec.vessel.thrusters},
            by_role("attitude"),
        )
        self.fusion.pair_by_sensor_time = ip.attitude_time == "sensor"
        self._events: list[str] = []  # reference state changes not yet in a status
        self._startup_events: list[str] = []  # said once, in the first status
        self.thrusters_out: dict[int, str] = {}  # thruster id -> why its drive does not take DP commands
        self._caller_alarms: list[str] = []  # the alarms the caller (the service) gave the last status
        self._alarm_since: dict[str, int] = {}  # alarm key -> stamp of the first status with it
        self._last_est: Estimate | None = None
        self._extra_last: dict[str, Estimate] = {}  # each extra observer's last estimate (by label)
        # the last estimate as floats for `_prediction`: (estimate, eta, nu, eta_wf, cos ψ, sin ψ)
        self._pred_base: tuple[Estimate, list[float], list[float], list[float], float, float] | None = None
        self._last_est_ns = 0
        self._measured_ns = [0, 0, 0]  # when each DOF last went into the observer with a measurement
        # observers that want each measurement once (id → receive time of the one each DOF last gave it)
        self._given_ns: dict[int, list[int]] = {}
        self._last_step_ns = 0
        self._step_deferred = False  # a step owed, left to the next event at the same time (`_owed_step`)
        # (source, sentence kind, talker) -> the time its measuring sentence last arrived, and the period
        self._cycle_ns: dict[tuple[str, str, str], tuple[int, int]] = {}
        self._last_dr_ns = 0
        self._ghost: Observer | None = None  # the dead-reckoning copy of a silence (`tick`)
        self.dead_reckoned = False  # the last `tick` dead-reckoned (the service logs it, `TICK_KEY`)
        self._dr_period_ns = int(NS / ip.dead_reckoning_rate_hz)
        # Every source is silent once nothing has stepped the observer for the longest reference timeout
        # (any fix or heading steps it, accepted or not); only then do ticks publish.
        self._silent_ns = max(
            (s.timeout_ns for s in spec.sources if s.roles & {"position", "heading"}), default=2 * NS
        )
        self._lost_ns = int(ip.lost_after_s * NS)
        # The longest gap between two steps every observer bridges (`Observer.max_gap_s`; the MMAE bank
        # starts again after a longer one): a longer silence is a restart the pipeline makes and announces
        # itself (`_reacquire`), so that the settle clock, the restart count and the events see it.
        self._bridged_ns = self._lost_ns
        for obs in [spec.observer, *(o for _, o in spec.extra_observers)]:
            if math.isfinite(obs.max_gap_s):
                self._bridged_ns = min(self._bridged_ns, int(obs.max_gap_s * NS))
        # Re-acquisition of a DOF whose references return outside the prediction gate (`_reacquire`): per
        # DOF [N, E, ψ], when its present unbroken run of measurements began, 0 while not re-acquiring, -1
        # while re-acquiring but broken off.
        self._reacq_ns = [0, 0, 0]
        self._prediction_test = ip.prediction_max_age_s > 0
        self._prediction_max_age_s = ip.prediction_max_age_s
        self._confirm_ns = int(ip.restart_confirm_s * NS)
        self.restarts = 0  # observer restarts from a returning reference (`_reacquire`)
        self._datum_for_message: LocalFrame | None = None
        self._datum_msg = Datum(lat_deg=0.0, lon_deg=0.0)
        self.sources = {s.name: s for s in spec.sources}
        self.counters = {s.name: SourceCounters() for s in spec.sources}
        # One framer (NMEA) or frame parser (MAVLink) per source and sender, made on the sender's first
        # chunk; key (source, peer), peer "" for links with one sender.
        self._framers: dict[tuple[str, str], NmeaFramer] = {}
        self._tag_named: dict[tuple[str, str], str] = {}  # a sender's TAG block awaiting its sentence
        # a sender's last group of lines (``g:``) whose first line named its device: (group id, device)
        self._tag_group: dict[tuple[str, str], tuple[str, str]] = {}
        self._tag_lines: dict[tuple[str, str], int] = {}  # (source, device) -> its last line count (n:)
        self._tag_devices: Counter[str] = Counter()  # source -> devices in `_tag_lines`
        self.sentence_tap: Callable[[str, int, str, str], None] | None = None
        """Called with (source, receive time ns, sentence text, peer) for every NMEA sentence the framer
        cuts from received bytes, before it is decoded (valid or not): an output that republishes raw
        sentences (Keelson's ``raw_nmea0183``) gets them without framing the bytes a second time. Not
        called for chunks that arrive already framed (replay's checked lines) or decoded (records)."""
        self._parsers: dict[tuple[str, str], mv.FrameParser] = {}
        self._verifiers: dict[str, mv.MAVLink] = {}  # signed MAVLink source -> its senders' one verifier
        self._parser_seen: dict[tuple[str, str], Counter[str]] = {}
        self._parser_rejects: dict[tuple[str, str], int] = {}  # sum of _parser_seen, the fast check
        self._parser_skipped: dict[tuple[str, str], int] = {}  # its skipped_bytes already counted
        self._sender_rx: dict[tuple[str, str], int] = {}  # (source, peer) -> its last chunk's time
        self._logged_verdicts_left: dict[tuple[str, str, int], list[mv.LoggedVerdict]] = {}
        """Replay of a signed link without its key: (source, peer, chunk time) → its logged verdicts not
        applied yet (`_verdicts_left`)."""
        self.mavlink_peer: dict[str, str] = {}
        """MAVLink source → the sender of the last frame it accepted (signature, system and component
        checked): where the service sends the thruster commands. Not whoever sent the last datagram: one
        stray or forged datagram on a shared link must not take the commands away from the drive."""
        self.t0_ns: int | None = None
        self.last_ns = 0
        self.mode = "standby"
        self.setpoint: dict[str, Any] | None = None
        self._dp_target: tuple[float, float, float] | None = None  # (N, E, ψ) of the last dp step
        self.manual_tau = np.zeros(3)
        # The dead-man on the manual τ (`_manual_tau_hold`): the hold time, the receive time of the τ in
        # force (None: none taken in this manual spell, τ = 0 since entering it), and whether it expired.
        self._manual_hold_s = float(spec.commands.manual_tau_hold_s)
        self._manual_hold_ns = round(self._manual_hold_s * NS) if math.isfinite(self._manual_hold_s) else None
        self._manual_tau_ns: int | None = None
        self.manual_tau_expired = False
        """In manual, no new τ for longer than ``[commands] manual_tau_hold_s``: the demand is zero, an
        alarm is up (`_command_alarms`) until a fresh τ or another mode."""
        self.estimates = 0
        self.commands = CommandGate(spec.commands.accept, spec.commands.max_setpoint_distance_m, spec.vessel)
        self.estimate_status: str | None = None  # of the last published estimate (the DP-mode check)
        # (status, health) of the last published estimate of the primary observer, a dead-reckoned one of
        # `tick` too: the estimate's alarm (`_estimate_alarms`)
        self._published_health: tuple[str, list[str]] | None = None
        self._last_fix_ns: dict[str, int] = {}
        # per source, the last GGA height and GST covariance, carried on its LocationFix
        self._fix_alt_m: dict[str, float] = {}
        self._fix_time: dict[str, tuple[float, int]] = {}  # source -> (UTC s of day, rx ns) of its last fix
        # (GST fresh until, covariance, its unit shape): a GST older than the source's timeout no longer
        # describes its fixes
        self._fix_cov: dict[str, tuple[int, GstCovariance, tuple[float, float, float] | None]] = {}
        self.foxglove = FoxgloveChannels(
            spec.vessel,
            antennas={name: src.lever_arm_m for name, src in self.sources.items() if "position" in src.roles},
        )
        self._foxglove_on = spec.foxglove_channels
        cc = spec.control
        self.controller: DPController | None = None
        self.allocator: QPAllocator | PseudoInverseAllocator | None = None
        self.command: ThrusterCommand | None = None
        self.allocation: AllocationResult | None = None
        self.control_alarms: list[str] = []
        self._pending_setpoint: dict[str, Any] | None = None
        # Whether the observer's estimate has settled (`Observer.settle_time_s` after its start: its first
        # estimate, or the first after a restart), and what DP does about it (docs/gateway.md, "Waiting
        # for the observer").
        self.settled = False
        self._settle_ns = round(float(spec.observer.settle_time_s) * NS)  # read again at each start
        self._settle_from_ns: int | None = None  # the observer's start; None until its first estimate
        self.waiting_for_observer = False
        """``initial_mode = "dp"`` with ``wait_for_observer``: standby until the estimate has settled, then
        DP by itself; ended by the engagement or by an operator's mode command."""
        self._unsettled_dp = ""  # in DP on an estimate not yet settled: why ("operator", "restart", "start")
        self._returns_seen = 0  # the controller's governed returns already announced
        self._raw: tuple[float, np.ndarray, np.ndarray] | None = None
        self._last_control_ns = 0
        self._next_control_ns = 0
        self._control_period_ns = NS // 10
        if cc is not None:
            self.mode = cc.initial_mode
            if cc.initial_mode == "dp" and cc.wait_for_observer:
                self.mode, self.waiting_for_observer = "standby", True
                self._startup_events.append(
                    f"initial mode dp: standby until the observer has settled ({self._settle_ns / NS:.0f} s "
                    "after its first estimate), then DP engages by itself (control.wait_for_observer)"
                )
            elif cc.initial_mode == "dp":
                self._unsettled_dp = "start"
            self._control_period_ns = int(NS / cc.rate_hz)
            self.controller = DPController(
                spec.vessel,
                ControllerTuning(
                    bandwidth_rad_s=cc.bandwidth_rad_s,
                    damping=cc.damping,
                    return_speed_mps=cc.return_speed_mps,
                    wind_feedforward_gain=cc.wind_feedforward_gain,
                    wind_filter_s=cc.wind_filter_s,
                    wind_loss_fade_s=cc.wind_loss_fade_s,
                    takeover_fade_s=cc.takeover_fade_s,
                ),
                observer_bias_time_s=(
                    observer_bias_time_s(spec.observer) if cc.feedback == "estimate" else None
                ),
            )
            if spec.vessel.thrusters:
                self.allocator = (
                    QPAllocator(spec.vessel, dt=1.0 / cc.rate_hz)
                    if cc.allocator == "qp"
                    else PseudoInverseAllocator(spec.vessel)
                )
                self.command = ThrusterCommand.at_rest(spec.vessel)
        q = spec.consequence
        self.consequence: ConsequenceAnalysis | None = None
        self._consequence_ns = 0  # when its failure cases were last tested
        if self.allocator is not None and q.enabled and len(spec.vessel.thrusters) > 1:
            self.consequence = ConsequenceAnalysis(
                spec.vessel.thrusters, failure_groups=q.failure_groups, filter_s=q.filter_s
            )
        self._best_priority = {
            role: min(s.priority for s in spec.sources if role in s.roles)
            for role in ("position", "heading")
            if any(role in s.roles for s in spec.sources)
        }
        # sources that are a backup (not the best-ranked) for position / for heading
        self._backup = {
            role: {s.name for s in spec.sources if s.priority > best}
            for role, best in self._best_priority.items()
        }
        # a backup source matters only when the best-ranked one is preferred (pooling by weight uses all)
        self._backup_used = self._backup if spec.integrity.pooling == "priority" else {}
        # roles with more than one source: only there does a source's pooling weight (`monitor.weight`)
        # matter; the fusion uses one source's numbers as they are (the common case: not asked per fix)
        self._pooled = {
            role for role in ("position", "heading") if sum(role in s.roles for s in spec.sources) > 1
        }
        self._thruster_ids = [th.id for th in spec.vessel.thrusters]
        self._wind_sources = tuple(s.name for s in spec.sources if "wind" in s.roles)
        self._attitude_sources = tuple(s.name for s in spec.sources if "attitude" in s.roles)
        self.lever_arm_compensation: Counter[str] = Counter()
        """Fixes by how their lever arm was compensated, with an attitude source configured: ``attitude``
        (R_zyx(φ, θ, ψ)) or ``heading`` (no fresh attitude: J(ψ) alone)."""
        self._compensation_said = ""
        self.wind_feedforward: str | None = None
        """Why the controller's wind feed-forward is off, as announced ("" while it is on; None without a
        controller): after an "off", "on" only once the wind has held for `WIND_ON_CONFIRM_S`."""
        self._wind_fresh_since_ns: int | None = None  # start of the present unbroken run of fresh wind
        self._wind_used = False  # a controller with wind feed-forward and a wind source to feed it
        if self.controller is not None and cc is not None:
            why = wind_feedforward_off(cc, spec.vessel, (s.roles for s in spec.sources))
            self._wind_used = not why and self.controller.wind is not None
            self.wind_feedforward = why or "no wind measured yet"
            if why:  # said once, in the first status (which it does not hasten)
                self._startup_events.append(f"wind feed-forward off: {why}")

    def start_over(self, spec: PipelineSpec, event: str) -> Pipeline:
        """A pipeline as at start-up for another run of the plant (a simulator started again under the
        live gateway, `gateway.service`), built from ``spec`` (a fresh one: new observers), that keeps
        what counts over the gateway's life: the sources' counters (the same objects, in the same dict)
        but not their freshness (no data yet from the new run), the estimates published, the observer
        restarts, the command counters, the raw-sentence tap. Everything else starts over: observers,
        fusion (a datum from the first fix, if so configured), reference tests, controller and allocation,
        the mode from ``control.initial_mode`` and no setpoint (one still waiting to be applied is refused
        as ``setpoint: dropped at restart``, with an event), the framers and MAVLink parsers, the drives'
        flags. ``event`` goes out, once, in its first status."""
        new = Pipeline(spec)
        for c in self.counters.values():
            c.last_rx_ns = c.last_good_ns = 0
        new.counters = self.counters
        new.estimates = self.estimates
        new.restarts = self.restarts
        new.commands.counters = self.commands.counters
        new.sentence_tap = self.sentence_tap
        new._caller_alarms = list(self._caller_alarms)
        new._alarm_since = dict(self._alarm_since)
        new._events.append(event)
        if self._pending_setpoint is not None:
            # a setpoint taken but not applied yet is of the old run's sea, as the one in force is: dropped,
            # but said and counted, or a console would believe it on its way
            text = (
                f"setpoint {_show_setpoint(self._pending_setpoint)} dropped unapplied: the plant started "
                "again (a new run); send it again for this run"
            )
            new.commands.refuse("setpoint", "dropped at restart", text)
            new._events.append(text)
        return new

    @property
    def startup_events(self) -> tuple[str, ...]:
        """The start-up events not yet said (the start mode, the wind feed-forward off): the first status
        that is logged carries them."""
        return tuple(self._startup_events)

    def say(self, event: str) -> None:
        """An event of the caller's (the live service's: where its log went), said once in the next status
        with the pipeline's own."""
        self._events.append(event)

    def _mavlink_parser(self, s: SourceSpec) -> mv.FrameParser:
        """A frame parser for a new sender on ``s``. A signed link's senders share one verifier (one
        signing state: the newest timestamp seen per link, system and component), so a frame is taken
        once, whoever sends it: with a verifier per sender, a genuine frame recorded on the network and
        re-sent from another address within the replay window was taken again — and the thruster
        commands would then go to that address (`mavlink_peer`)."""
        if s.signing_key is None:
            return mv.FrameParser(keep_signing_rejects=s.logged_verdicts is not None)
        mav = self._verifiers.get(s.name)
        if mav is None:
            mav = self._verifiers[s.name] = mv.encoder(src_system=255, src_component=190)
            mv.setup_signing(
                mav,
                s.signing_key,
                sign_outgoing=False,
                allow_unsigned=s.allow_unsigned,
                initial_timestamp=0 if s.signatures_from_a_log else None,  # None: this host's clock
            )
        return mv.FrameParser(mav, keep_signing_rejects=True)

    # --- events in ------------------------------------------------------------------------------------------

    def compile_kernels(self) -> None:
        """Call the compiled kernels this pipeline steps live once, on throwaway twins, so that numba
        compiles them (the first run after an install or an upgrade: ~8 s for the allocation alone) or
        loads them from its cache (~0.3 s) now, before the first sample, instead of stalling the loop that
        long at the first estimate or the first DP step. Nothing of this pipeline's state changes: the
        observers and the controller are deep copies, the allocator a new one of the same kind."""
        y, zero = np.array([0.0, 0.0, 0.1]), np.zeros(3)
        for obs in [self.spec.observer, *(o for _, o in self.spec.extra_observers)]:
            twin = copy.deepcopy(obs)
            for k in range(3):
                twin.step(0.1 * k, y, zero)
        if self.controller is not None:
            controller = copy.deepcopy(self.controller)
            controller.set_mode("dp")
            controller.set_setpoint(y)
            for k in range(3):  # the first dp step enters bumplessly; the compiled law runs after it
                controller.update(100.0 + 0.1 * k, zero, zero, zero)
        if isinstance(self.allocator, QPAllocator):
            allocator = QPAllocator(self.spec.vessel, dt=self.allocator.dt, solver=self.allocator.solver)
            previous = allocator.allocate(np.array([1.0, 1.0, 1.0]))
            allocator.allocate(np.array([2.0, -1.0, 0.5]), previous.command)

    def feed(self, event: RawEvent | ControlEvent, defer_step: bool = False) -> list[Output]:
        """The outputs of one event: its measurements used and, when it brought one, an observer step.

        ``defer_step``: another source's event at the same time comes next, and the step waits for it,
        so the instant is stepped once with both. A replay of a text log says so where its cycle feeds
        several sources (a source per role of a user's config, a network capture's devices, logs merged
        by time): each would otherwise step the observer at the same time again, with a dt of zero and a
        second estimate of the same stamp. No live feeder defers; two live inputs at one time (the
        simulation's clock interpolates its stamps) step once all the same (`_owed_step`)."""
        if isinstance(event, ControlEvent):
            if event.key == TICK_KEY:  # a live tick that dead-reckoned, from its log (`tick`)
                return self.tick(event.rx_ns)
            self._control(event)
            return []
        spec = self.sources.get(event.source)
        if spec is None:
            return self._owed_step(event.rx_ns, event.source, defer_step)
        if not event.data and event.records is None and event.checked is None:
            # the end of a sender's stream (`gateway.sources.Chunk`: a TCP connection closed): what its
            # framer holds of an unfinished sentence is counted now (a shared framer is left alone)
            out_of_stream = self._owed_step(event.rx_ns, event.source, defer_step)
            if event.peer:
                key = (spec.name, event.peer)
                self._forget_sender(key, self.counters[event.source], event.rx_ns, out_of_stream)
            return out_of_stream
        rx_ns = event.rx_ns
        if self.t0_ns is None:
            self.t0_ns = rx_ns
        if rx_ns > self.last_ns:
            self.last_ns = rx_ns
        if self._manual_tau_ns is not None:
            self._manual_tau_hold(rx_ns)
        c = self.counters[event.source]
        c.bytes += len(event.data)
        if spec.tag_source is None or event.records is not None:
            # (a source that takes one device of a group is fresh only when that device's sentences come:
            # `_nmea`; the group's other devices keep its socket busy, not the source alive)
            c.last_rx_ns = rx_ns
        out: list[Output] = []
        if event.records is not None:
            updated = self._records(spec, c, event, out)
        elif spec.protocol == "nmea":
            updated = self._nmea(spec, c, event, out)
        else:
            updated = self._mavlink(spec, c, event, out)
        if updated:
            self._step_deferred = True  # (owed: taken now, unless the next event at this time takes it)
        out += self._owed_step(rx_ns, event.source, defer_step)
        changes = self._state_changes(rx_ns)
        if changes:
            out += changes
        self._with_foxglove(out)
        return out

    def _owed_step(self, rx_ns: int, source: str, defer_step: bool) -> list[Output]:
        """The observer step an event called for (`feed`), or one an event before it at the same time
        left to it, unless this one leaves it to the next in turn: a step owed is taken by the next event
        whatever that brings (nothing, a source the pipeline does not have, the end of a stream)."""
        if defer_step or not self._step_deferred:
            return []
        if rx_ns == self._last_step_ns and self.observer.initialized:
            # The observer stepped at this very time already: a step of dt 0 changes nothing of its state
            # and published the same estimate again (a second /dp/estimate of one stamp: live on the
            # simulation's clock, whose interpolated stamps can coincide, a gyro and a GGA read at one
            # tick). The measurement is held, and the step stays owed to the next event.
            return []
        self._step_deferred = False
        return self._step(rx_ns, source)

    def _with_foxglove(self, out: list[Output]) -> None:
        """Add the Foxglove-native channels that mirror ``out`` (`gateway.foxglove_channels`)."""
        if self._foxglove_on:
            out += [Output(topic, message, ns, False) for topic, message, ns in self.foxglove.derive(out)]

    def tick(self, now_ns: int) -> list[Output]:
        """Called by the live service between events (any rate). Once nothing has stepped the observer
        for the longest source timeout (every source silent): a dead-reckoned estimate at
        ``integrity.dead_reckoning_rate_hz``, and the control step on it at the control rate (DP holds the
        setpoint on the dead-reckoned estimate, as it does while one DOF is measured; a manual τ goes on
        being commanded, and its dead-man timed); and the reference state changes (sources going stale).
        The dead reckoning runs on a copy of the observer, so the observer's own state stays a function of
        the events alone. The controller's and the allocation's state do move on at a tick that
        dead-reckoned (``dead_reckoned`` is then True): the service logs such a tick (`TICK_KEY`), and a
        replay, fed it as a `ControlEvent`, ticks there too and so reproduces the commands after it.

        Why control goes on: with nothing measured, no step used to run, so no command went out; drives
        that time out their command then stopped pushing against the current and wind the last
        commands held, and drives that do not held a command that nothing corrected. A DP system
        dead-reckons on its model for exactly this (the bias estimate carries the mean loads), with an
        alarm until the operator takes over or a reference comes back."""
        self.dead_reckoned = False
        if self.t0_ns is None or now_ns <= self.last_ns:
            return []
        out: list[Output] = []
        if (
            self.observer.initialized
            and now_ns - self._last_step_ns > self._silent_ns
            and now_ns - max(self._last_step_ns, self._last_dr_ns) >= self._dr_period_ns
        ):
            self._last_dr_ns = now_ns
            # One copy per silence, moved on from tick to tick: predicting a fresh copy over the whole
            # silence at every tick cost time in proportion to it (9 ms a tick after an hour for the
            # passive observer, 90 % of a core at 10 Hz after ten; more for the heavier observers).
            ghost = self._ghost
            if ghost is None:
                ghost = self._ghost = copy.deepcopy(self.observer)
            tau, _ = self.fusion.tau(now_ns)
            est = ghost.predict(self._t(now_ns), self._with_wind_load(tau))
            self.dead_reckoned = True
            if est.status != STATUS_NAMES[0]:
                dead_reckoned = self._estimate(self.spec.observer_name, ghost, est, now_ns, [False] * 3)
                self._published_health = (dead_reckoned.status, list(dead_reckoned.health))
                out.append(Output("/dp/estimate", dead_reckoned, now_ns))
                if self.controller is not None and now_ns >= self._next_control_ns:
                    if self._manual_tau_ns is not None:
                        self._manual_tau_hold(now_ns)
                    self._next_control_ns = now_ns + self._control_period_ns
                    out.extend(self._control_step(self._t(now_ns), est, now_ns))
        out.extend(self._state_changes(now_ns))
        self._with_foxglove(out)
        return out

    def _refused_reads(self, source: str, now_ns: int, timeout_ns: int) -> str | None:
        """What ``source``'s reads within ``timeout_ns`` were refused for by its decoder (``no_checksum 3``,
        most first, not-bad reasons left out), when it has been read within that time and nothing good
        has come from it since the last status; else None (silent, or talking with good input for
        another role). For `ReferenceMonitor.refresh`: such a source talks and is refused, not silent."""
        c = self.counters.get(source)
        if c is None or not c.last_rx_ns or now_ns - c.last_rx_ns > timeout_ns or c.received != c.good_seen:
            return None
        grown = c.rejected_since_good()
        # (none: bytes that are not even rejects, which the framers hold: silence to the tests)
        return reasons_text(grown) if grown else None

    def silence_s(self, now_ns: int) -> float:
        """How long nothing has stepped the observer at ``now_ns`` (0 before the first step)."""
        return (now_ns - self._last_step_ns) / NS if self._last_step_ns else 0.0

    def _state_changes(self, now_ns: int) -> list[Output]:
        """Reference state changes since the last call, and observer restarts (`_reacquire`): to the next
        status, and a status at once."""
        self.monitor.refresh(now_ns, self._refused_reads)
        changes = self.monitor.drain()
        if changes:
            self._events.extend(c.text for c in changes)
        elif not self._events:
            return []
        return self.status_outputs(now_ns)

    def count_internal_error(self, source: str) -> None:
        """The caller could not finish handling a chunk of ``source`` (an exception inside `feed`): count it
        with the source's rejects (reason ``internal_error``), so `/status` shows it."""
        c = self.counters.get(source)
        if c is not None:
            c.rejected["internal_error"] += 1

    def _nmea(self, spec: SourceSpec, c: SourceCounters, ev: RawEvent, out: list[Output]) -> bool:
        texts: Sequence[str]
        if ev.checked is not None:  # framed and checksummed already (replay's line scan)
            texts, others = ev.checked
            c.received += others
            verified = True
        else:
            framed: list[str] = []
            texts = framed
            key, framer = self._framer(spec, c, ev.peer, ev.rx_ns)
            self._take_frames(spec.tag_source, key, framer.feed(ev.data), c, framed)
            verified = False
            tap = self.sentence_tap
            if tap is not None:
                for text in framed:
                    tap(spec.name, ev.rx_ns, text, ev.peer)
        if texts and spec.tag_source is not None:  # its device spoke (`feed`)
            c.last_rx_ns = ev.rx_ns
        decode, reject, unused = nmea_codec.decode, nmea_codec.Reject, nmea_codec.UNUSED
        require = not spec.allow_missing_checksum
        used: list[Any] = []
        for text in texts:
            s = decode(text, require_checksum=require, only=USED_NMEA, verified=verified)
            if type(s) is reject:
                c.rejected[s.reason] += 1  # (a Reject)
                continue
            c.received += 1
            if s is not unused:
                used.append(s)
        # (a text log's reader has cut the log into cycles by the sentences' own times already)
        cycles = [] if verified or ev.cycle else self._cycles(spec.name, used, ev.rx_ns)
        if len(cycles) > 1:  # the read held several cycles: each but the last is stepped at its own time
            *earlier, (_, used) = cycles
            for stamp, sentences in earlier:
                if self._use_sentences(spec, stamp, sentences, out):
                    out += self._step(stamp, spec.name)
                out += self._state_changes(stamp)
        return self._use_sentences(spec, ev.rx_ns, used, out)  # (the last: stepped by `feed`)

    def _use_sentences(self, spec: SourceSpec, rx_ns: int, sentences: list[Any], out: list[Output]) -> bool:
        """`_use_nmea` for each sentence of one cycle, all of them; whether any calls for an observer step."""
        updated = False
        for s in sentences:
            updated |= self._use_nmea(spec, rx_ns, s, out)
        return updated

    def _cycles(self, source: str, sentences: list[Any], rx_ns: int) -> list[tuple[int, list[Any]]]:
        """The source's cycles in one read, each with the time it is taken to have arrived at.

        A byte stream (serial, a pty, TCP) hands over what arrived since the last read, all at the read's
        time: on a busy machine, or with a reader held up, one read holds several cycles of a gyro
        (measured in the demo on a loaded machine: up to 5 a read). Used as one, every cycle but the last
        was overwritten unstepped at the last one's time: 13 % of the observer's steps lost, and its
        station keeping 0.79 -> 1.18 m p95. So a read is cut into cycles where a measuring sentence (a
        fix, a heading: `_CYCLE_KINDS`) comes again from the same talker, and each earlier cycle is given
        the time it most likely arrived at: spread evenly back from the read's time over the time since
        that sentence's previous arrival, at most its last period apart (a burst after a silence came
        back to back, not spread over the silence). A cycle that would fall at or before the observer's
        last step (another source stepped it since) goes with the next one, as every cycle did before.
        The rule is a function of the logged reads alone, so a replay of the log cuts and times them the
        same. NMEA gives no better time: a heading sentence has no time field, and a fix's time of day is
        the receiver's, not its arrival's."""
        cuts: list[int] = []
        seen: set[tuple[str, str]] = set()
        first: tuple[str, str] | None = None  # the sentence whose repeat made the first cut
        for k, s in enumerate(sentences):
            if s.kind in _CYCLE_KINDS:
                key = (s.kind, s.talker)
                if key in seen:
                    cuts.append(k)
                    seen = set()
                    if first is None:
                        first = key
                seen.add(key)
        cycles: list[tuple[int, list[Any]]] = []
        gap = 0
        if first is not None:
            prev, period = self._cycle_ns.get((source, first[0], first[1]), (0, 0))
            n = len(cuts) + 1
            gap = (rx_ns - prev) // n if prev else 0  # (its first arrival: no time to spread back over)
            if period:
                gap = min(gap, period)
        if gap <= 0:
            cycles.append((rx_ns, sentences))
        else:
            floor = max(prev, self._last_step_ns)
            bounds = [0, *cuts, len(sentences)]
            carried: list[Any] = []
            for i in range(n):
                part = carried + sentences[bounds[i] : bounds[i + 1]]
                stamp = rx_ns - (n - 1 - i) * gap
                if stamp <= floor and i < n - 1:
                    carried = part  # no time of its own after the last step: used with the next cycle
                    continue
                cycles.append((stamp, part))
                carried = []
        arrivals = self._cycle_ns
        for stamp, part in cycles:
            for s in part:
                if s.kind in _CYCLE_KINDS:
                    arrival = (source, s.kind, s.talker)
                    last = arrivals.get(arrival)
                    if last is None:
                        arrivals[arrival] = (stamp, 0)
                    elif stamp > last[0]:
                        arrivals[arrival] = (stamp, stamp - last[0])
        return cycles

    def _use_nmea(self, spec: SourceSpec, rx_ns: int, s: Any, out: list[Output]) -> bool:
        kind = type(s)  # (the codec's sentence classes have no subclasses: `is`, not isinstance chains)
        if kind is nmea_codec.Gga or kind is nmea_codec.Gns:
            if "position" not in spec.roles:
                return False
            if not s.valid or s.lat_deg is None or s.lon_deg is None:
                # the receiver says it has no fix (quality 0, empty fields): received, then refused and
                # counted a second time like a fix the quality test refuses (test_*), so a log of 753
                # sentences and 21 fixes says why
                self.counters[spec.name].rejected["test_no_fix"] += 1
                return False
            if s.time_s is not None and self._fix_time_backwards(spec, rx_ns, s.time_s):
                self.counters[spec.name].rejected["test_time"] += 1
                return False
            if s.alt_m is not None and self._foxglove_on:  # (the height goes only on the LocationFix)
                self._fix_alt_m[spec.name] = ellipsoidal_height_m(s.alt_m, s.geoid_sep_m)
            quality = s.quality if kind is nmea_codec.Gga else None
            return self._use_position(spec, rx_ns, s.lat_deg, s.lon_deg, quality, out, s.time_s)
        if kind is nmea_codec.Heading:
            if "heading" not in spec.roles:
                return False
            if s.valid and s.heading_rad is not None:
                return self._use_heading(spec, rx_ns, s.heading_rad)
            self.counters[spec.name].rejected["test_no_heading"] += 1  # an empty HDT, THS mode V, ...
            return False
        if kind is nmea_codec.Attitude:
            if "attitude" in spec.roles:
                if s.valid:
                    self._use_attitude(spec, rx_ns, s)
                else:  # an empty roll or pitch: the MRU says it has no measurement
                    self.counters[spec.name].rejected["attitude_invalid"] += 1
            return False
        if kind is nmea_codec.Mwv:
            if "wind" in spec.roles:
                if s.valid:
                    self.fusion.add_wind(
                        rx_ns,
                        s.speed_mps,
                        s.angle_rad,
                        s.reference,
                        spec.name,
                        spec.priority,
                        spec.timeout_ns,
                    )
                else:  # status V or an empty field: the anemometer says it has no measurement
                    self.counters[spec.name].rejected["wind_invalid"] += 1
            return False
        if kind is nmea_codec.Gst and "position" in spec.roles:
            cov = gst_covariance(s)  # the error ellipse in full when it has one (`wire.gst_covariance`)
            if cov is None:
                return False
            if cov.origin == INCONSISTENT:  # its ellipse disagrees with its own σ lat / lon: those are used
                self.counters[spec.name].warnings["gst_ellipse_inconsistent"] += 1
            ne = (cov.nn, cov.ne, cov.ee)
            self.fusion.add_position_covariance(rx_ns, ne, spec.name, spec.timeout_ns)
            self._fix_cov[spec.name] = (rx_ns + spec.timeout_ns, cov, unit_shape(ne))
        return False

    def _fix_time_backwards(self, spec: SourceSpec, rx_ns: int, time_s: float) -> bool:
        """True for a fix whose UTC time is earlier than the last fix of its source, while that one is
        fresh (received within the source's timeout): an old fix delivered late (a datagram overtaken
        on the network, a receiver's buffer replayed, a spoofer repeating recorded sentences) must not
        reach the observer as a measurement of now. The step is taken modulo a day, so midnight
        (86399.9 s -> 0.1 s) is a step forward; a fix at the same time (GGA and GNS of one epoch) is not
        older. A receiver whose clock really stepped back is locked out for at most its timeout: once the
        last fix is older than that, the next one starts the time afresh (and the jump test judges its
        position)."""
        last = self._fix_time.get(spec.name)
        if last is not None and rx_ns - last[1] <= spec.timeout_ns and utc_step_s(last[0], time_s) < 0.0:
            return True
        self._fix_time[spec.name] = (time_s, rx_ns)
        return False

    def _framer(
        self, spec: SourceSpec, c: SourceCounters, peer: str, rx_ns: int
    ) -> tuple[tuple[str, str], NmeaFramer]:
        key = (spec.name, peer)
        framer = self._framers.get(key)
        if framer is None:
            self._forget_idle_senders(spec, c, rx_ns)
            key = (spec.name, _sender_key(peer, self._framers, spec.name))
            framer = self._framers.setdefault(key, NmeaFramer())
        self._sender_rx[key] = rx_ns
        return key, framer

    def _tag_seen(self, source: str, device: str | None, tag: TagBlock, c: SourceCounters) -> None:
        """A device's line count (``n:``) that skips: the lines between were lost on the network (a switch's
        buffer, a multicast route), which the kernel's count (``dropped``) cannot see. Counted per source
        (``lost_lines``) from the device's previous line, for each device apart, for the first
        `MAX_SENDERS` devices a source hears. A count that goes back, repeats, or jumps by more than
        `MAX_LINE_GAP` is a device restarting or datagrams arriving out of order, not counted."""
        n_text = tag.params.get("n")
        if device is None or n_text is None or not n_text.isdigit():
            return
        n = int(n_text)
        last = self._tag_lines.get((source, device))
        if last is None and self._tag_devices[source] >= MAX_SENDERS:
            return  # (a flood of made-up device names must not grow memory: the first ones are followed)
        if last is None:
            self._tag_devices[source] += 1
        self._tag_lines[(source, device)] = n
        if last is not None:
            missing = (n - next_line(last)) % 999  # (the count runs 1-999, then 1 again)
            if 0 < missing <= MAX_LINE_GAP:
                c.lost_lines += missing

    def _take_frames(
        self,
        want: str | None,
        key: tuple[str, str],
        frames: list[Frame],
        c: SourceCounters,
        framed: list[str],
    ) -> None:
        """The candidate sentences of a sender's ``frames`` into ``framed``, the other frames counted by
        reason. A TAG block is read (a damaged one counted ``tag_checksum`` or ``tag_malformed``; a good
        one's line count checked, `_tag_seen`). With ``want``, a source's ``tag_source``, only the
        sentences whose TAG block names that device (``s:``) are taken and the others counted
        ``other_tag_source``: on an IEC 61162-450 network several devices send to one multicast group, and
        a source takes one of them. A TAG block belongs to the sentence right after it, which may arrive in
        the sender's next read (the device it named is held per sender). A group's later line whose block
        carries only ``g:`` (NMEA 4.10: the device is named on the group's first line) is that device's. A
        sentence without a readable TAG block is not taken then (whose it is cannot be told)."""
        named = self._tag_named.get(key) if want is not None else None
        for frame in frames:
            text = frame.text
            if text is not None:
                if want is None or named == want:
                    framed.append(text)
                else:
                    c.rejected[OTHER_TAG_SOURCE] += 1
                named = None
                continue
            reason = frame.reason or "garbage"
            if reason == TAG_BLOCK:
                tag = decode_tag(frame.raw)
                if isinstance(tag, TagReject):
                    reason = tag.reason
                    named = None
                else:
                    named = tag.source
                    group = tag.group
                    if group is not None:
                        held = self._tag_group.get(key)
                        if named is not None:
                            self._tag_group[key] = (group[1], named)
                        elif group[0] > 1 and held is not None and held[0] == group[1]:
                            named = held[1]  # (a group's later line: its first line's device)
                    self._tag_seen(key[0], named, tag, c)
            elif reason != IEC_61162_450:  # (the header comes before a TAG block: it keeps no name)
                named = None
            c.rejected[reason] += 1
        if want is None:
            return
        if named is None:
            self._tag_named.pop(key, None)
        else:
            self._tag_named[key] = named

    def _parser(
        self, spec: SourceSpec, c: SourceCounters, peer: str, rx_ns: int, out: list[Output]
    ) -> tuple[tuple[str, str], mv.FrameParser]:
        key = (spec.name, peer)
        parser = self._parsers.get(key)
        if parser is None:
            self._forget_idle_senders(spec, c, rx_ns, out)
            key = (spec.name, _sender_key(peer, self._parsers, spec.name))
            parser = self._parsers.get(key)
            if parser is None:
                parser = self._parsers[key] = self._mavlink_parser(spec)
                self._parser_seen[key] = Counter()
                self._parser_rejects[key] = 0
                self._parser_skipped[key] = 0
        self._sender_rx[key] = rx_ns
        return key, parser

    def _forget_idle_senders(
        self, spec: SourceSpec, c: SourceCounters, rx_ns: int, out: list[Output] | None = None
    ) -> None:
        """A new sender on a source: first forget the source's senders silent for longer than its
        timeout (a TCP client that disconnected and came back from another port, a receiver that moved
        address). What each held back of an unfinished sentence or frame is counted now
        (`NmeaFramer.flush`, `FrameParser.flush`: ``truncated``, ``garbage``, …) and its state freed: the
        half sentence a dropped client left is counted by the time the next client after its timeout
        connects, and a link whose clients reconnect all day keeps one framer per live sender instead of
        filling `MAX_SENDERS` with dead ones and putting every newcomer on the shared framer, where two
        clients' sentences would splice. Senders still talking are kept: a flood of new addresses shares
        one framer and cannot push out the receiver that was there first. Only event times are used, so
        a replay forgets the same senders."""
        name = spec.name
        table: Mapping[tuple[str, str], object] = self._framers if spec.protocol == "nmea" else self._parsers
        idle = [
            key
            for key in table
            if key[0] == name and rx_ns - self._sender_rx.get(key, rx_ns) > spec.timeout_ns
        ]
        for key in idle:
            self._forget_sender(key, c, rx_ns, out)

    def _forget_sender(
        self, key: tuple[str, str], c: SourceCounters, rx_ns: int = 0, out: list[Output] | None = None
    ) -> None:
        """Count what the framer or frame parser of ``key`` (source, peer) holds back, and free it. A
        signed link's frames refused for signing then are recorded in ``out`` as a chunk's are, stamped
        ``rx_ns`` (the event that forgot the sender) with the sender's peer, and a replay without the key
        applies those verdicts at the same event: a refused frame held behind a false start completes only
        here (a forged one was counted ``bad_signature`` live but left no record, and the replay took it)."""
        self._sender_rx.pop(key, None)
        self._tag_named.pop(key, None)
        self._tag_group.pop(key, None)
        framer = self._framers.pop(key, None)
        if framer is not None:
            for frame in framer.flush():
                c.rejected[frame.reason or "garbage"] += 1
        parser = self._parsers.get(key)
        if parser is not None:
            logged = self.sources[key[0]].logged_verdicts
            if logged is not None:
                parser.verdicts = self._verdicts_left(key[0], logged, key[1], rx_ns)
            # a valid frame held behind a false start completes only now: counted, not used (the sender
            # is gone or silent beyond its timeout)
            late = len(parser.flush())
            parser.verdicts = None
            if late:
                c.rejected["sender gone"] += late
            if self._count_parser_rejects(key, c) and parser.signing_rejects and out is not None:
                out.extend(_signing_rejections(key[0], rx_ns, key[1], parser.signing_rejects))
            del self._parsers[key], self._parser_seen[key], self._parser_rejects[key]
            del self._parser_skipped[key]

    def _use_position(
        self,
        spec: SourceSpec,
        rx_ns: int,
        lat: float,
        lon: float,
        quality: int | None,
        out: list[Output],
        utc_s: float | None = None,
    ) -> bool:
        """A fix through the source's tests (`gateway.references`), then into the fusion if it passes. True
        when the observer should step (also for a rejected fix: the estimate goes on at the source's rate).
        ``utc_s``: the fix's own UTC time of day (GGA, GNS), which pairs it with the MRU by sensor time."""
        ned = self.fusion.reference_position(rx_ns, lat, lon, spec.lever_arm_m, utc_s)
        if ned is None:
            return False  # a lever arm without a heading of the same cycle cannot be compensated
        if self._attitude_sources:
            self._note_compensation(spec.name)
        if self._foxglove_on:
            self._location_fix(spec.name, rx_ns, lat, lon, out)
        pred = self._prediction(rx_ns, 0)
        held = self._fix_cov.get(spec.name)  # its GST's shape while fresh (`wire.gst_covariance.unit_shape`)
        shape = held[2] if held is not None and rx_ns <= held[0] else None
        if self.monitor.position(spec.name, rx_ns, ned[0], ned[1], quality, pred, shape):
            if not self.monitor.usable("position", spec.name):  # readmitting: passes, not yet in use
                self.fusion.drop_position(spec.name)
                return True
            weight = self.monitor.weight("position", spec.name) if "position" in self._pooled else 1.0
            q = 1 if quality is None else quality
            self.fusion.use_position(rx_ns, *ned, spec.name, spec.priority, spec.timeout_ns, q, weight)
        else:
            self._count_test_reject(spec.name, self.monitor.reason("position", spec.name))
            self.fusion.drop_position(spec.name)
        return True

    def _use_attitude(self, spec: SourceSpec, rx_ns: int, s: nmea_codec.Attitude) -> None:
        """An MRU's roll and pitch through its tests (`ReferenceMonitor.attitude`): into the fusion if they
        may be used. A failing sample is counted by test (``test_attitude_jump``, …) and not used; while
        the MRU is rejected or readmitting its attitude is forgotten (the lever arm falls back to heading
        only, as when the MRU is stale)."""
        roll, pitch = s.roll_rad, s.pitch_rad
        assert roll is not None and pitch is not None  # (``valid``)
        sigmas = (s.roll_sigma_rad, s.pitch_sigma_rad)
        if self.monitor.attitude(spec.name, rx_ns, roll, pitch, s.time_s, sigmas):
            self.fusion.add_attitude(rx_ns, roll, pitch, spec.name, spec.priority, spec.timeout_ns, s.time_s)
            return
        why = self.monitor.attitude_problem(spec.name)  # ("" for a passing sample while readmitting)
        if why:
            self._count_test_reject(spec.name, why, "test_attitude_")
        if not self.monitor.attitude_usable(spec.name):
            self.fusion.drop_attitude(spec.name)  # (else one sample dropped: the good ones around it stay)

    def _note_compensation(self, source: str) -> None:
        """Count how a fix's lever arm was compensated (`Fusion.reference_position`: ``attitude`` with the
        MRU's roll and pitch, ``heading`` alone while no attitude is fresh) and say in the status when
        that changes: once on, once off, not per fix."""
        how = self.fusion.last_compensation
        if not how:
            return
        self.lever_arm_compensation[how] += 1
        if how == "heading":  # the fix is used, by J(ψ) alone: a caveat, not a reject
            self.counters[source].warnings["lever_arm_heading_only"] += 1
        if how != self._compensation_said:
            if how == "attitude":
                text = f"lever-arm compensation: roll and pitch from {self.fusion.attitude_source} (MRU) on"
            else:
                names = ", ".join(self._attitude_sources)
                why = "; ".join(
                    f"{n} {st.state}: {st.reason}"
                    for n in self._attitude_sources
                    for st in self.monitor.states().get(n, ())
                    if st.role == "attitude" and st.state in ("rejected", "suspect")
                )
                text = f"lever-arm compensation: heading only (no fresh attitude from {names})"
                if why:
                    text = f"lever-arm compensation: heading only (attitude not trusted: {why})"
            self._events.append(text)
            self._compensation_said = how

    def _use_heading(self, spec: SourceSpec, rx_ns: int, psi: float) -> bool:
        if self.monitor.heading(spec.name, rx_ns, psi, self._prediction(rx_ns, 2)):
            if not self.monitor.usable("heading", spec.name):  # readmitting: passes, not yet in use
                self.fusion.drop_heading(spec.name)
                return True
            weight = self.monitor.weight("heading", spec.name) if "heading" in self._pooled else 1.0
            self.fusion.add_heading(rx_ns, psi, spec.name, spec.priority, spec.timeout_ns, weight)
        else:
            self._count_test_reject(spec.name, self.monitor.reason("heading", spec.name))
            self.fusion.drop_heading(spec.name)
        return True

    def _count_test_reject(self, source: str, reason: str, prefix: str = "test_") -> None:
        """A sentence or frame that failed a reference test, counted by test (``test_jump``, …: the first
        word of the test's ``reason``; an MRU's as ``test_attitude_jump``, …)."""
        word = reason.split(":")[0].split(" ")[0].lower() or "failed"
        self.counters[source].rejected[f"{prefix}{word}"] += 1

    def _prediction(self, now_ns: int, dof: int) -> Prediction | None:
        """Where the estimate expects a position (dof 0) or heading (dof 2) now: the last estimate moved on
        by its velocity (the observer itself is not advanced), plus its wave motion; None before one, and
        while the DOF is being re-acquired (`_reacquire`: the estimate is then what is in question)."""
        if self._reacq_ns[dof]:
            return None
        return self._predicted(now_ns, dof)

    def _predicted(self, now_ns: int, dof: int) -> Prediction | None:
        """`_prediction` whether or not the DOF is being re-acquired."""
        est = self._last_est
        measured = self._measured_ns[dof]
        if est is None or not measured:
            return None
        base = self._pred_base
        if base is None or base[0] is not est:  # (made by `_step` for every published estimate)
            if not est.initialized:
                return None
            # the estimate as plain floats, once per estimate (NaN wave motion counts as none): this runs
            # for every fix and heading, and numpy's per-element arithmetic cost more than the test itself
            wf = [x if x == x else 0.0 for x in est.eta_wf.tolist()]
            eta = est.eta.tolist()
            base = self._pred_base = (est, eta, est.nu.tolist(), wf, math.cos(eta[2]), math.sin(eta[2]))
        _, eta, nu, wf, c, s = base
        dt = (now_ns - self._last_est_ns) / NS
        age = (now_ns - measured) / NS
        # Past the age limit the prediction test ends, so that an old prediction never locks out a reference
        # back from a silence. Not in DP when the DOF's references were refused while their data kept
        # coming (a DGPS that jumped 30 m and stayed there): ended by time alone, the test let the offset
        # in after the age limit, the observer restarted on it, and DP drove the vessel 30 m off its
        # station while the alarms said it was returning to it. So DP keeps testing them (`held`).
        held = (
            self._prediction_test
            and age > self._prediction_max_age_s
            and self.mode == "dp"
            and self.controller is not None
            and self.monitor.refused_while_talking("heading" if dof == 2 else "position")
        )
        if dof == 2:
            return Prediction((ssa_scalar(eta[2] + wf[2] + nu[2] * dt),), age, nu[2], held)
        u, v = nu[0], nu[1]
        n = eta[0] + wf[0] + (c * u - s * v) * dt
        e = eta[1] + wf[1] + (s * u + c * v) * dt
        return Prediction((n, e), age, 0.0, held)

    def _mavlink(self, spec: SourceSpec, c: SourceCounters, ev: RawEvent, out: list[Output]) -> bool:
        key, parser = self._parser(spec, c, ev.peer, ev.rx_ns, out)
        logged = spec.logged_verdicts
        if logged is None:
            msgs = parser.feed(ev.data)
        else:  # a replay without the key: the live gateway's verdicts on this chunk's frames
            parser.verdicts = self._verdicts_left(spec.name, logged, ev.peer, ev.rx_ns)
            msgs = parser.feed(ev.data)
            parser.verdicts = None
        if self._count_parser_rejects(key, c) and parser.signing_rejects:
            out.extend(_signing_rejections(spec.name, ev.rx_ns, ev.peer, parser.signing_rejects))
            parser.signing_rejects.clear()
        frames: list[Sequence[mv.Report]] = []
        for msg in msgs:
            if spec.system_id is not None and msg.get_srcSystem() != spec.system_id:
                c.rejected["other system"] += 1  # a second vehicle or a forger on the link
                continue
            if spec.component_id is not None and msg.get_srcComponent() != spec.component_id:
                c.rejected["other component"] += 1
                continue
            self.mavlink_peer[spec.name] = ev.peer
            frames.append(mv.reports(msg, spec.ardupilot))
        return self._use_reports(spec, c, ev.rx_ns, frames, out)

    def _verdicts_left(
        self,
        source: str,
        logged: Mapping[tuple[str, int], tuple[mv.LoggedVerdict, ...]],
        peer: str,
        rx_ns: int,
    ) -> list[mv.LoggedVerdict] | None:
        """The logged verdicts on the chunks of ``source`` from ``peer`` at ``rx_ns`` not applied yet (one
        list for every chunk of that sender and time: two chunks may share a receive time), or None."""
        key = (source, peer, rx_ns)
        left = self._logged_verdicts_left.get(key)
        if left is None:
            verdicts = logged.get((peer, rx_ns))
            if not verdicts:
                return None
            left = self._logged_verdicts_left[key] = list(verdicts)
        return left or None

    def unmatched_verdicts(self) -> dict[str, int]:
        """Per source replayed with logged verdicts (`SourceSpec.logged_verdicts`), those that refused no
        frame so far: no frame at their place with their digest (a log edited or merged with another), or
        their chunk not replayed (yet)."""
        out: dict[str, int] = {}
        for spec in self.spec.sources:
            if spec.logged_verdicts is None:
                continue
            total = sum(len(v) for v in spec.logged_verdicts.values())
            applied = sum(
                len(spec.logged_verdicts[(peer, rx_ns)]) - len(left)
                for (source, peer, rx_ns), left in self._logged_verdicts_left.items()
                if source == spec.name
            )
            out[spec.name] = total - applied
        return out

    def _records(self, spec: SourceSpec, c: SourceCounters, ev: RawEvent, out: list[Output]) -> bool:
        """A chunk already decoded (`RawEvent.records`): each item counted as received, then used."""
        assert ev.records is not None
        if spec.protocol != "nmea":
            return self._use_reports(spec, c, ev.rx_ns, ev.records, out)
        updated = False
        for s in ev.records:
            c.received += 1
            if s is not None:
                updated |= self._use_nmea(spec, ev.rx_ns, s, out)
        return updated

    def _use_reports(
        self, spec: SourceSpec, c: SourceCounters, rx_ns: int, frames: Sequence[Sequence[mv.Report]],
        out: list[Output],
    ) -> bool:  # fmt: skip
        """The reports of MAVLink frames from an accepted sender, one sequence per frame."""
        roles = spec.roles
        updated = False
        feedback = False
        for reports in frames:
            c.received += 1
            for r in reports:
                if isinstance(r, mv.ThrusterReport):
                    if "thrusters" not in roles:
                        continue
                    if r.flags is not None:
                        self._thruster_flags(r.thruster_id, r.flags)
                    if (
                        r.esc is not None
                        and r.rpm
                        and spec.ardupilot
                        and r.esc in spec.ardupilot.esc_direction
                    ):
                        sign = self.esc_directions.sign(spec.name, r.esc, rx_ns)
                        if not sign:  # rpm without a sign: not thrust (τ counts the command instead)
                            c.rejected["esc_direction_unknown"] += 1
                            continue
                        r = replace(r, rpm=sign * r.rpm)
                    problem = self.monitor.feedback(
                        spec.name, rx_ns, r.thruster_id, r.thrust_n, r.azimuth_rad, r.rpm
                    )
                    if problem:
                        c.rejected["out_of_range"] += 1
                        continue
                    # a drive that does not know its thrust sends NaN: then its shaft speed gives it
                    if r.thrust_n is not None and not math.isnan(r.thrust_n):
                        self.fusion.add_thruster(
                            rx_ns, r.thruster_id, r.thrust_n, r.azimuth_rad, spec.timeout_ns
                        )
                        feedback = True
                    elif r.rpm is not None and not math.isnan(r.rpm):
                        self.fusion.add_thruster_rpm(
                            rx_ns, r.thruster_id, r.rpm, r.azimuth_rad, spec.timeout_ns
                        )
                        feedback = True
                    elif r.azimuth_rad is not None:  # a servo: the angle goes out with the next thrust
                        self.fusion.add_thruster_azimuth(rx_ns, r.thruster_id, r.azimuth_rad)
                elif isinstance(r, mv.PositionReport):
                    if "position" not in roles or not r.valid:
                        continue
                    if not (-90.0 <= r.lat_deg <= 90.0 and -180.0 <= r.lon_deg <= 180.0):
                        # an int32 field of 1e-7 degrees holds up to ±214.7°: no position (the NMEA
                        # decoder rejects such a field as bad_field); counted, and never fused or drawn
                        c.rejected["position_out_of_range"] += 1
                        continue
                    updated |= self._use_position(spec, rx_ns, r.lat_deg, r.lon_deg, None, out)
                elif isinstance(r, mv.EscDirectionReport):
                    if "thrusters" in roles:
                        self.esc_directions.add(spec.name, r.esc, r.direction, rx_ns, spec.timeout_ns)
                elif "heading" in roles:
                    updated |= self._use_heading(spec, rx_ns, r.heading_rad)
        if "thrusters" in roles:
            self.fusion.set_feedback_usable(self.monitor.feedback_usable(spec.name))
        if feedback:
            out.append(self._feedback_output(rx_ns))
        return updated

    def _count_parser_rejects(self, key: tuple[str, str], c: SourceCounters) -> bool:
        """Add what a frame parser rejected and skipped since last time to its source's counters (which
        also hold the pipeline's own reasons, so they are added to, never overwritten); True if it
        rejected something new."""
        parser = self._parsers[key]
        skipped = parser.skipped_bytes
        if skipped != self._parser_skipped[key]:
            c.skipped_bytes += skipped - self._parser_skipped[key]
            self._parser_skipped[key] = skipped
        total = sum(parser.rejected.values())
        if total == self._parser_rejects[key]:
            return False
        seen = self._parser_seen[key]
        for reason, n in parser.rejected.items():
            if n != seen[reason]:
                c.rejected[reason] += n - seen[reason]
                seen[reason] = n
        self._parser_rejects[key] = total
        return True

    def _control(self, ev: ControlEvent) -> None:
        """A command input, taken only if `gateway.commands` finds nothing wrong (refusals are counted
        there, with the reason, for `/status` and the caller's log)."""
        gate = self.commands
        if gate.admit(ev.key, ev.payload) is not None:
            return
        if ev.key == "mode":
            unstepped_ns = ev.rx_ns - self._last_step_ns
            silent_s = unstepped_ns / NS if self._last_step_ns and unstepped_ns > self._silent_ns else None
            if gate.check_mode(ev.payload, self.observer.initialized, self.estimate_status, silent_s) is None:
                if ev.payload != self.mode:  # (said first: the notices of `_mode_commanded` follow it)
                    self._events.append(f"mode: {self.mode} -> {ev.payload} (operator)")
                self._mode_commanded(ev.payload, ev.rx_ns)
                if ev.payload != "manual" or self.mode != "manual":
                    # manual starts from no thrust until the operator's next τ (as the controller's
                    # manual does): a τ of an earlier manual spell is not what the operator means now;
                    # and the dead-man has nothing to time until that τ (`_manual_tau_hold`)
                    self.manual_tau = np.zeros(3)
                    self._manual_tau_ns = None
                    self.manual_tau_expired = False
                self.mode = ev.payload
                gate.accepted("mode")
        elif ev.key == "setpoint":
            # the distance from the present position is checked when it is applied (`_control_step`):
            # a setpoint may arrive before the first estimate
            if gate.check_setpoint_shape(ev.payload) is None:
                if self._pending_setpoint is not None:
                    self._setpoint_superseded(self._pending_setpoint)
                self._pending_setpoint = ev.payload
        elif ev.key == "tau":
            tau = gate.check_tau(ev.payload)
            if isinstance(tau, np.ndarray) and gate.check_tau_mode(self.mode) is None:
                gate.accepted("tau")
                self.manual_tau = tau
                self._manual_tau_ns = ev.rx_ns
                self.manual_tau_expired = False  # (its alarm clears with the next status)
                if self.controller is None:
                    self.fusion.set_tau_demand(tau)

    def _setpoint_superseded(self, old: dict[str, Any]) -> None:
        """A setpoint taken but not applied yet, replaced by a newer one: counted (`CommandCounters.
        superseded`) and said once, so the operator sees that it was dropped and why it had not been
        applied."""
        self.commands.superseded("setpoint")
        if self.controller is None:
            why = "no DP controller is configured to apply it"
        elif self.estimate_status not in HEALTHY_FOR_DP:
            status = self.estimate_status or "not there yet"
            why = f"it waited for an estimate healthy enough for dp (the estimate is {status})"
        else:
            why = "it waited for the next control step"
        self._events.append(
            f"setpoint superseded: {_show_setpoint(old)} dropped unapplied, replaced by a newer one; {why}"
        )

    def _manual_tau_hold(self, now_ns: int) -> None:
        """The dead-man on the manual τ: in manual, once no new τ has been taken for longer than
        ``[commands] manual_tau_hold_s`` (on the pipeline's clock: the receive times of the events, so a
        replay expires it where the live run did), the demand goes to zero and the mode stays manual.
        Said once as an event, alarmed until a fresh τ (`_command_alarms`), counted (`CommandCounters.
        expired`). A joystick or console streams its τ at several Hz; one that stops (crashed, cable out,
        link lost) must not leave the thrusters pushing. ``inf``: held until the next one."""
        held_ns = self._manual_hold_ns
        since = self._manual_tau_ns
        if held_ns is None or since is None or self.manual_tau_expired or self.mode != "manual":
            return
        if now_ns - since <= held_ns:
            return
        self.manual_tau_expired = True
        self.manual_tau = np.zeros(3)
        if self.controller is None:
            self.fusion.set_tau_demand(self.manual_tau)
        self.commands.expired("tau")
        self._events.append(
            f"manual τ expired: no new τ for {_seconds(self._manual_hold_s)} s; thrust demand set to zero"
        )

    def _command_alarms(self) -> list[str]:
        """The command inputs' alarm: a manual τ expired (`_manual_tau_hold`), up until a fresh τ."""
        if not self.manual_tau_expired:
            return []
        return [
            "manual τ expired: thrust demand zero until a new τ "
            f"(commands.manual_tau_hold_s = {self._manual_hold_s:g} s)"
        ]

    def _mode_commanded(self, mode: str, now_ns: int) -> None:
        """An operator's mode command, accepted: the operator decides, as on a DP console. It ends a wait
        for the observer (`waiting_for_observer`) whatever the mode; a ``dp`` before the estimate has
        settled is honoured, said once and alarmed until the estimate has settled."""
        if self.waiting_for_observer:
            self.waiting_for_observer = False
            if mode != "dp":
                self._events.append(f"DP no longer waits for the observer: the operator chose {mode}")
        if mode == "dp" and self.mode != "dp" and not self.settled and self.controller is not None:
            self._unsettled_dp = "operator"
            self._events.append(
                "DP engaged by the operator before the observer settled "
                f"({self.settle_left_s(now_ns):.0f} s left): the bias estimate is still growing"
            )

    def settle_left_s(self, now_ns: int) -> float:
        """Seconds until the observer's estimate is taken as settled (0 once it is; its whole settle time
        before its first estimate). The settle time is time the observer is stepped on measurements: while
        nothing steps it (every source silent) the count stands where the last step left it, and goes on
        from there at the next (`_settle_clock`), as a dead-reckoning observer's bias estimate does not
        converge."""
        if self.settled:
            return 0.0
        start = self._settle_from_ns
        if start is None:
            return self._settle_ns / NS
        last = self._last_step_ns
        if last and now_ns - last > self._silent_ns:
            now_ns = last  # (silent: counted up to the last step)
        return max(0.0, (start + self._settle_ns - now_ns) / NS)

    def _settle_clock(self, now_ns: int, before_ns: int = 0) -> None:
        """At an estimate of the (primary) observer: start its settle clock at its first estimate, and
        mark it settled once `Observer.settle_time_s` of stepping has passed since. ``before_ns``: the
        step before this one; a silence since (longer than every source's timeout, `settle_left_s`) is
        not counted: the clock's start moves on by it."""
        start = self._settle_from_ns
        if start is None:
            self._settle_from_ns = start = now_ns
            self._settle_ns = round(float(self.observer.settle_time_s) * NS)
        elif before_ns and now_ns - before_ns > self._silent_ns:
            self._settle_from_ns = start = start + (now_ns - before_ns)
        if not self.settled and now_ns - start >= self._settle_ns:
            self.settled = True
            self._unsettled_dp = ""

    def _engage_when_settled(self) -> None:
        """While waiting for the observer: DP once the estimate has settled and is healthy enough for DP
        (the check an operator's ``dp`` passes, `gateway.commands`); the control step then takes over
        from what the thrusters deliver (`_take_over`), bumplessly."""
        if self.settled and self.estimate_status in HEALTHY_FOR_DP:
            self.waiting_for_observer = False
            self.mode = "dp"
            self._events.append(
                "mode: standby -> dp (by the gateway, control.wait_for_observer): "
                "observer settled: DP engaged"
            )

    def _settling_alarms(self, now_ns: int) -> list[str]:
        """The notice while the estimate has not settled and it matters: DP waiting for it, or DP running
        on it. An alarm of the status's list, cleared when the estimate has settled (numbers masked, one
        alarm while its seconds count down: `gateway.foxglove_channels.alarm_key`)."""
        if self.waiting_for_observer:
            if not self.settled:
                left = self.settle_left_s(now_ns)
                return [f"DP waits for the observer to settle: {left:.0f} s left (control.wait_for_observer)"]
            return [f"DP waits for a healthy estimate: it is {self.estimate_status or 'not there'}"]
        if self.mode != "dp" or self.settled or self.controller is None:
            return []
        left = self.settle_left_s(now_ns)
        why = {
            "operator": "DP engaged before the observer settled",
            "restart": "observer restarted in DP",
        }.get(self._unsettled_dp, "DP from the first estimate (control.wait_for_observer = false)")
        return [f"{why}: estimate settling, {left:.0f} s left"]

    def _estimate_alarms(self, now_ns: int) -> list[str]:
        """The alarm of an estimate that is not measured: its last published status (a dead-reckoned
        estimate of `tick` too) `dead_reckoning` or `lost`, with which DOFs have had no usable reference for
        how long (since it last went into the observer: the source's timeout after its last datum; `lost`
        past ``integrity.lost_after_s``, as `_health` says it), and, in DP, what DP does
        on it: the controller is not told (it steps on the dead-reckoned estimate as on any other, at every
        step a measurement of another DOF makes, or with nothing measured at all at every control period of
        the gateway's clock, `tick`). Cleared by the first estimate measured again."""
        pub = self._published_health
        if pub is None or pub[0] not in ("dead_reckoning", "lost"):
            return []
        status, health = pub
        unmeasured = [k for k, word in enumerate(health) if word in ("dead_reckoning", "lost")]
        ages = [now_ns - self._measured_ns[k] for k in unmeasured if self._measured_ns[k]]
        age_s = max(ages) / NS if ages else 0.0
        what = " and ".join(
            name
            for name, dofs in (("position", (0, 1)), ("heading", (2,)))
            if any(k in unmeasured for k in dofs)
        )
        lost_s = self._lost_ns / NS
        unused = f"no usable {what} reference" if what else "no usable reference"
        if status == "lost" or age_s > lost_s:
            text = f"estimate lost: dead reckoning for {age_s:.0f} s, {unused}"
        else:
            text = (
                f"estimate dead reckoning for {age_s:.0f} s: {unused} "
                f"(lost after integrity.lost_after_s = {lost_s:g} s)"
            )
        if self.mode == "dp" and self.controller is not None:
            text += "; in DP: the controller holds the setpoint on the dead-reckoned estimate"
            if self._last_step_ns and now_ns - self._last_step_ns > self._silent_ns:
                text += " (nothing measured: stepped on the gateway's clock)"
        return [text]

    def _thruster_flags(self, thruster_id: int, flags: int) -> None:
        """A drive's status flags: a thruster whose drive says it will not deliver DP commands (`OUT_FLAGS`:
        a shutdown-class fault, an emergency stop, local control) is taken out of the thrust allocation at
        once and alarmed while it is out; when its flags clear it is put back. Flags 0 (a sender that does
        not report them) say nothing against the thruster. Announced as status events on each change."""
        if thruster_id not in self._thruster_ids:
            return
        # (plain ints: an IntFlag's `&` runs in Python, and every drive report passes here)
        bits = int(flags)
        why = ", ".join(name for bit, name in OUT_FLAGS if bits & bit) if bits else ""
        old = self.thrusters_out.get(thruster_id, "")
        if why == old:
            return
        if why:
            self.thrusters_out[thruster_id] = why
            self._events.append(f"thruster {thruster_id} out of DP ({why}): removed from thrust allocation")
        else:
            del self.thrusters_out[thruster_id]
            self._events.append(
                f"thruster {thruster_id} back in DP ({old} cleared): in thrust allocation again"
            )
        if self.allocator is not None:
            self.allocator.set_available({thruster_id: not why})

    # --- observer and outputs -------------------------------------------------------------------------------

    def _t(self, ns: int) -> float:
        assert self.t0_ns is not None
        return (ns - self.t0_ns) / 1e9

    def _step(self, now_ns: int, trigger: str) -> list[Output]:
        fusion = self.fusion
        y, valid = fusion.measurement(now_ns)
        tau, tau_source = fusion.tau(now_ns)
        tau_obs = self._with_wind_load(tau)
        t = (now_ns - self.t0_ns) / 1e9 if self.t0_ns is not None else 0.0  # (`_t`; feed set t0_ns)
        measured = self._measured_ns
        y_obs = y
        reacq, before = self._reacq_ns, self._last_step_ns
        returning = (
            reacq[0]
            or reacq[2]
            or (valid[0] and measured[0] and measured[0] != before)  # back: not measured at the last step
            or (valid[2] and measured[2] and measured[2] != before)
            # no step at all for longer than lost_after_s (a replay's gap between two logs, hours or
            # years, has no events to step on): the references are back after being lost, not held; or
            # for longer than an observer bridges (`_bridged_ns`)
            or (before and now_ns - before > self._bridged_ns)
        )
        # (an observer not yet initialised has no state to restart: its first complete measurement starts
        # it, as it would have without the outage)
        if returning and self._last_est is not None and self.observer.initialized:
            y_obs = self._reacquire(now_ns, y, valid)
        est = self._observe(self.observer, t, y_obs, tau_obs, valid)
        self._last_est, self._last_est_ns, self._last_step_ns = est, now_ns, now_ns
        self._ghost = None  # a silence ends with a step
        if valid[0]:
            measured[0] = now_ns
        if valid[1]:
            measured[1] = now_ns
        if valid[2]:
            measured[2] = now_ns
        names = (fusion.position_sources if valid[0] else ()) + (fusion.heading_sources if valid[2] else ())
        cov = fusion.position_covariance_ne(now_ns)  # (its GST's; sigma_m is its RMS σ)
        out = [
            Output(
                "/dp/measurement",
                Measurement(
                    stamp_ns=now_ns,
                    eta=[None if v != v else v for v in y.tolist()],  # NaN (stale) -> null
                    valid=valid,
                    sources=_source_names(names),
                    quality=fusion.quality,
                    sigma_m=rms_sigma_m(cov),
                    tau=tau.tolist(),
                    tau_source=tau_source,
                    covariance_ne_m2=None if cov is None else list(cov),
                ),
                now_ns,
            )
        ]
        if est.status != _INITIALIZING:
            self.estimates += 1
            if not self.settled:
                self._settle_clock(now_ns, before)
            estimate = self._estimate(self.spec.observer_name, self.observer, est, now_ns, valid)
            self.estimate_status = estimate.status
            self._published_health = (estimate.status, list(estimate.health))
            if self.waiting_for_observer:
                self._engage_when_settled()
            # `_prediction`'s floats from the message's lists (the same numbers: ``est`` as lists)
            eta, wf = estimate.eta, estimate.eta_wf
            self._pred_base = (
                est,
                eta,
                estimate.nu,
                [x if x == x else 0.0 for x in wf],
                math.cos(eta[2]),
                math.sin(eta[2]),
            )
            out.append(
                Output("/dp/estimate", estimate, now_ns)
            )  # (its LocationFix: gateway.foxglove_channels)
            if self.controller is not None and now_ns >= self._next_control_ns:
                self._next_control_ns = now_ns + self._control_period_ns
                out.extend(self._control_step(t, est, now_ns))
        for label, obs in self.spec.extra_observers:
            e = self._observe(obs, t, y_obs, tau_obs, valid)
            self._extra_last[label] = e
            if e.status != STATUS_NAMES[0]:
                out.append(Output(f"/dp/estimates/{label}", self._estimate(label, obs, e, now_ns), now_ns))
        return out

    def _reacquire(self, now_ns: int, y: np.ndarray, valid: list[bool]) -> np.ndarray:
        """Restart the observers when a DOF's references return and the estimate cannot be right; returns
        the y to step them with (``y`` itself unless they restart).

        While a DOF has no usable reference the observer dead-reckons on its model, and the estimate
        drifts (a current or wind it has not learnt, a tow, hours between two logs). When the references
        return, stepping the observer with them would pull the estimate over slowly (its injection gains
        act over tens of seconds), and meanwhile the prediction test would reject every fix that lands
        outside its gate: measured, a 20 m drift over a 60 s outage gave 17 m of error 5 s after the
        return and 40 % of the returning fixes rejected for a minute. So, per DOF (position, heading):

        - back after ``lost_after_s`` (the estimate was reported lost), or the first step after no step
          for that long (a replay's gap between merged logs, which has no event to step on): the
          observers restart from the measurement at once, as at start-up, integrating nothing across it;
        - back after any break (measured now, not at the last step) and inside the prediction gate of
          the dead-reckoned prediction (``prediction_gate_m`` grown by the 3σ ellipse of the position's
          GST covariance when known; ``prediction_gate_deg``; without its growth with age): the dead
          reckoning held, and the observers carry on with the measurement as before the outage;
        - back outside that gate (after a short break, a fix the prediction test let through only
          because its gate grows with the age; after ``prediction_max_age_s``, any): the DOF is
          re-acquired. Until it has been measured for ``restart_confirm_s`` without a break its
          references are not tested against the prediction (the other tests still apply) and do not
          reach the observers, which keep dead-reckoning that DOF (a fed observer would take the step
          into its wave estimate within a second or two, and a wild fix would reach it). Then, if the
          measurement is still outside the gate, the observers restart from it; if not (the first fix
          back was the wild one), they carry on with it. A break in the measurement starts the
          re-acquisition again. One wild fix on return therefore restarts nothing: it would have to hold
          up for the confirmation time, and the good fixes after it meet the source's own jump test
          against it.

        The gate and its words are the reference monitor's (`ReferenceMonitor.beyond_prediction_gate`),
        with the pooled position's GST covariance when known.

        Nothing stepped for longer than an observer bridges (`Observer.max_gap_s`, shorter than
        ``lost_after_s``) restarts everything too: that observer would start again by itself, unseen.

        A restart is `Observer.reset` and the step with y, which initialises the observer as its first
        measurement does (a DOF with no fresh value then takes the prediction's). Announced as a status
        event and counted (`restarts`).

        A re-acquisition of one DOF while the other is measured and in the observers restarts that DOF
        only (`_restart_dof`): the other keeps its state — position, velocity, bias and wave motion.
        Restarting everything from one measurement put the heading's wave motion into its LF estimate and
        zeroed its bias: a 30 s frozen DGPS, re-acquired 3 m off the dead-reckoned position, gave the
        heading estimate a 2° transient though the gyro never failed. The same holds for a DOF back after
        ``lost_after_s`` (the first rule) while the other was measured throughout: its state is as good
        as its measurements, however long the first was away (the same frozen DGPS, rejected 5 s in and
        held out 5 s after it moved again, came back after 30 s, lost by a hair, and the full restart
        put the heading's 2° of wave motion into its LF estimate). Both DOFs back at once, or nothing
        stepped for ``lost_after_s`` (which leaves both unmeasured), restart everything: then no part of
        the state has been kept up by a measurement.
        """
        measured, reacq, lost_ns = self._measured_ns, self._reacq_ns, self._lost_ns
        why = ""
        silent_ns = now_ns - self._last_step_ns if self._last_step_ns else 0
        whole = self._bridged_ns < silent_ns <= self._lost_ns  # (longer: both DOFs are lost, below)
        if whole:
            why = (
                f"nothing stepped the observer for {silent_ns / NS:.0f} s "
                f"(it bridges at most {self._bridged_ns / NS:g} s: max_gap_s)"
            )
        lost = False
        confirmed: list[int] = []  # DOFs re-acquired outside the gate: the ones a restart is for
        lost_dofs: list[int] = []  # DOFs back after lost_after_s
        for dof in (0, 2):
            if not valid[dof]:
                if reacq[dof]:
                    reacq[dof] = -1
                continue
            last = measured[dof]
            gap_ns = now_ns - last
            what = "position" if dof == 0 else "heading"
            if last and gap_ns > lost_ns:
                why = why or f"{what} back after {gap_ns / NS:.0f} s (lost after {lost_ns / NS:g} s)"
                lost = True
                lost_dofs.append(dof)
                continue
            # back: measured now, not at the last step (or again after a break in a re-acquisition);
            # without the prediction test (prediction_max_age_s = 0) only the lost rule above applies
            back = reacq[dof] == -1 or (last and last != self._last_step_ns and self._prediction_test)
            if not (back or reacq[dof]):
                continue
            off = self._off_gate(now_ns, dof, y)
            if back:
                # back (or back again after a break): inside the gate it simply carries on, outside it is
                # held back while it confirms itself
                reacq[dof] = now_ns if off else 0
            elif now_ns - reacq[dof] >= self._confirm_ns:
                reacq[dof] = 0
                if off:
                    why = why or f"{what} {off}"
                    confirmed.append(dof)
        # one DOF back (confirmed outside the gate, or lost) while the other was measured at the last
        # step and is now: that DOF alone restarts. The other's state is as good as its measurements,
        # however long the first was away (nothing stepped for lost_after_s is both DOFs lost at once).
        single = lost_dofs if lost else confirmed  # (a DOF lost beside one confirmed: both are back)
        if why and len(single) == 1 and not (lost and confirmed) and not whole:
            other = 2 - single[0]  # (0 position, 2 heading)
            steady = valid[other] and not reacq[other] and measured[other] == self._last_step_ns
            if steady and self._restart_dof(single[0], y):
                self._given_ns.clear()
                self.restarts += 1
                kept = "heading" if other == 2 else "position"
                self._events.append(f"observer restarted from the measurement: {why} ({kept} kept)")
                return y
        if not why:
            if not (reacq[0] or reacq[2]):
                return y
            y_obs = y.copy()  # a DOF being re-acquired does not reach the observers yet
            if reacq[0]:
                y_obs[0] = y_obs[1] = math.nan
            if reacq[2]:
                y_obs[2] = math.nan
            return y_obs
        y_obs = y.copy()
        # a DOF not measured now starts from the dead-reckoned prediction, moved on by the estimated
        # velocity for at most lost_after_s: beyond that the velocity says nothing (between two logs a
        # day apart, 0.15 m/s carried on for 17 h put the restarted position 9.8 km from the vessel)
        at_ns = min(now_ns, self._last_est_ns + self._lost_ns)
        for dof in (0, 2):
            if not valid[dof]:
                pred = self._predicted(at_ns, dof)
                if pred is not None:
                    y_obs[dof : dof + len(pred.value)] = pred.value
        self.observer.reset()
        for _, obs in self.spec.extra_observers:
            obs.reset()
        self._given_ns.clear()
        reacq[:] = (0, 0, 0)
        self.restarts += 1
        self._events.append(f"observer restarted from the measurement: {why}")
        # Its estimate starts again (bias from zero): not settled until its settle time has passed again.
        # DP is kept, as a DP system keeps DP through a filter reset: dropping to standby would leave the
        # thrusters to no one; the controller's integrator holds the load the bias estimate lost while it
        # grows back, and an alarm says so until it has settled (docs/gateway.md, "Waiting for the
        # observer").
        self._settle_from_ns, self.settled = None, False
        if self.mode == "dp" and self.controller is not None:
            self._unsettled_dp = "restart"
            self._events.append(
                "DP kept on the restarted observer: its estimate settles again in "
                f"{self._settle_ns / NS:.0f} s"
            )
        return y_obs

    def _restart_dof(self, dof: int, y: np.ndarray) -> bool:
        """Restart DOF ``dof`` (0: north and east, 2: heading) of every observer from the measurement y and
        keep the rest of its state: each observer starts again (`Observer.initialize`) at the time of its
        last estimate from that estimate, with the DOF's LF position set to y and its wave motion to zero,
        as a first measurement starts it; the step that follows takes y. False, and nothing changed, when
        an observer has no estimate to keep (the caller then restarts everything)."""
        observers = [
            (self.observer, self._last_est),
            *((o, self._extra_last.get(k)) for k, o in self.spec.extra_observers),
        ]
        if any(e is None or not e.initialized for _, e in observers):
            return False
        for obs, e in observers:
            assert e is not None
            eta, eta_wf = e.eta.copy(), np.nan_to_num(e.eta_wf)
            k = slice(0, 2) if dof == 0 else slice(2, 3)
            eta[k], eta_wf[k] = y[k], 0.0
            obs.initialize(e.t, eta, nu=e.nu.copy(), bias=e.bias.copy(), eta_wf=eta_wf)
        return True

    def _off_gate(self, now_ns: int, dof: int, y: np.ndarray) -> str:
        """How far y lies from the dead-reckoned prediction of DOF ``dof`` (0 position, 2 heading) when
        that is outside the prediction gate, in words for the restart event; "" when inside (or no
        prediction yet)."""
        pred = self._predicted(now_ns, dof)
        if pred is None:
            return ""
        if dof == 0:
            value = (float(y[0]), float(y[1]))
            cov = self.fusion.position_covariance_ne(now_ns)
            return self.monitor.beyond_prediction_gate("position", value, pred.value, cov_ne=cov)
        return self.monitor.beyond_prediction_gate("heading", (float(y[2]),), pred.value)

    def _observe(
        self, obs: Observer, t: float, y: np.ndarray, tau: np.ndarray, valid: list[bool]
    ) -> Estimate:
        """Step one observer with the held measurement y, or — for an observer that wants each measurement
        once (``new_samples_only``, `observers.base.ObserverBase`) — with the DOFs whose measurement it has
        not been given yet (the others NaN; all of them until it is initialised). Such an observer reports
        a step that brought only some DOFs as dead reckoning; while every DOF's measurement is valid (held
        within its source's timeout) the estimate is reported "ok", as for the others."""
        if not getattr(obs, "new_samples_only", False):
            return obs.step(t, y, tau)
        received = self.fusion.measurement_received_ns()
        given = self._given_ns.setdefault(id(obs), [-1, -1, -1])
        if obs.initialized:
            y = np.array([v if given[k] < received[k] else math.nan for k, v in enumerate(y.tolist())])
        for k in range(3):
            if y[k] == y[k]:
                given[k] = received[k]
        est = obs.step(t, y, tau)
        if est.status == STATUS_NAMES[STATUS_DEAD_RECKONING] and all(valid):
            est = replace(est, status=STATUS_NAMES[STATUS_OK])
        return est

    def _setpoint_ned(self, sp: dict[str, Any]) -> np.ndarray | None:
        """A setpoint {north_m, east_m, heading_deg} or {lat_deg, lon_deg, heading_deg} in local NED."""
        try:
            psi = math.radians(float(sp["heading_deg"]))
            if "north_m" in sp:
                target = np.array([float(sp["north_m"]), float(sp["east_m"]), psi])
            elif self.fusion.datum is not None:
                n, e, _ = self.fusion.datum.to_ned(float(sp["lat_deg"]), float(sp["lon_deg"]), 0.0)
                target = np.array([n, e, psi])
            else:
                return None  # a lat/lon setpoint waits for the datum
        except (KeyError, TypeError, ValueError):
            self._pending_setpoint = None
            self.control_alarms = [
                "setpoint ignored: expected north_m/east_m or lat_deg/lon_deg, heading_deg"
            ]
            return None
        return target if np.all(np.isfinite(target)) else None

    def _deviation_alarms(self, eta_error: np.ndarray, of: str = "the DP reference") -> list[str]:
        """In dp: the position's distance from the DP reference against the watch circles drawn around
        the setpoint (warning, alarm; `FoxgloveChannels.watch_circles_m`), and the heading's difference
        against `HEADING_LIMITS_DEG`. The reference, not the target: during a setpoint move the vessel
        follows the reference, and only a vessel that cannot (a drive-off, a load beyond capability, a
        thruster lost) is off it. During a governed return (`DPController.returning`) the reference
        restarted at the vessel, so the caller gives the distance from the setpoint instead: the vessel
        stays alarmed until it is back inside the circles."""
        out = []
        d = math.hypot(float(eta_error[0]), float(eta_error[1]))
        circles = self.foxglove.watch_circles_m
        for radius, word in sorted(zip(circles, ("warning", "alarm"), strict=False), reverse=True):
            if d > radius:
                out.append(f"position {d:.1f} m off {of}: beyond the {word} circle ({radius:g} m)")
                break
        dpsi = abs(math.degrees(float(eta_error[2])))
        for limit, word in sorted(zip(HEADING_LIMITS_DEG, ("warning", "alarm"), strict=True), reverse=True):
            if dpsi > limit:
                out.append(f"heading {dpsi:.1f}° off {of}: beyond the {word} limit ({limit:g}°)")
                break
        return out

    def _take_over(self, now_ns: int) -> np.ndarray:
        """Leaving standby, the thrusters are someone else's until now (a lever, a joystick, another
        system) and may be carrying the load: start from what they deliver. The allocation's state becomes
        each thruster's fresh feedback (thrust, azimuth), so the first command's rate limits are counted
        from where the thrusters are, not from the last command before standby; and the τ to continue from
        (the controller's bumpless start) is the τ of that feedback. Without fresh feedback: the last
        command and τ = 0, as before."""
        tau, source = self.fusion.tau(now_ns)
        if self.allocator is not None and self.command is not None:
            thrust, azimuth = self.command.thrust.copy(), self.command.azimuth.copy()
            fresh = self.fusion.fresh_thrust(now_ns)
            for i, tid in enumerate(self._thruster_ids):
                fb = fresh.get(tid)
                if fb is not None:
                    thrust[i], azimuth[i] = fb.thrust_n, fb.azimuth_rad
            self.command = ThrusterCommand(thrust, azimuth)
        return tau if source == "feedback" else np.zeros(3)

    def _raw_feedback(self, t: float, est: Estimate) -> tuple[np.ndarray, np.ndarray]:
        """η and ν for a DP system without a wave filter (``[control] feedback = "measurement"``, only to
        show what wave filtering buys): the raw measurement, and a dirty derivative of it (first-order
        filter, time constant RAW_VELOCITY_FILTER_S) rotated into the body frame."""
        y, _ = self.fusion.measurement(self._last_control_ns)
        y = np.where(np.isnan(y), est.eta, y)
        if self._raw is None:
            self._raw = (t, y, np.zeros(3))
        t0, y0, v = self._raw
        dt = t - t0
        if dt > 0:
            dy = y - y0
            dy[2] = ssa_scalar(dy[2])
            v = v + dt / (RAW_VELOCITY_FILTER_S + dt) * (dy / dt - v)
            self._raw = (t, y, v)
        c, s = math.cos(y[2]), math.sin(y[2])
        nu = np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]])
        return y, nu

    def _control_step(self, t: float, est: Estimate, now_ns: int) -> list[Output]:
        """DP controller on the LF estimate (never the raw measurement), then thrust allocation."""
        ctl = self.controller
        assert ctl is not None
        self._last_control_ns = now_ns
        if ctl.mode != self.mode:
            tau_now = self.fusion.tau_demand
            if ctl.mode == "standby":
                tau_now = self._take_over(now_ns)
            # a setpoint taken outside dp was checked against the estimate of then: the vessel may have
            # been moved far since (in standby or manual), so again against the estimate now
            held = ctl.setpoint
            if (
                self.mode == "dp"
                and held is not None
                and self.commands.check_setpoint_distance(held, est.eta, entering_dp=True) is not None
            ):
                ctl.forget_setpoint()
                self.setpoint = None
            ctl.set_mode(self.mode, tau_now=tau_now)
        pending = self._pending_setpoint
        # (a setpoint waits, as one before the first estimate does, while the estimate is not healthy
        # enough for dp: a dead-reckoned or lost position is nothing to check its distance against)
        if pending is not None and self.estimate_status in HEALTHY_FOR_DP:
            target = self._setpoint_ned(pending)
            if target is not None:
                self._pending_setpoint = None
                if self.commands.check_setpoint_distance(target, est.eta) is None:
                    ctl.set_setpoint(target)
                    self.setpoint = pending
                    self.commands.accepted("setpoint")
        prev = self.allocation
        eta_in, nu_in = est.eta, est.nu
        bias_in: np.ndarray | None = est.bias
        if self.spec.control is not None and self.spec.control.feedback == "measurement":
            eta_in, nu_in = self._raw_feedback(t, est)
            bias_in = None  # without an observer there is no bias estimate to feed forward
        o = ctl.update(
            t,
            eta_in,
            nu_in,
            bias_in,
            saturated=bool(prev is not None and prev.saturated),
            tau_allocated=None if prev is None else prev.tau_allocated,
            tau_manual=self.manual_tau,
            relative_wind=self._relative_wind(now_ns, est) if self._wind_used else None,
        )
        if ctl.returns != self._returns_seen:  # a governed return began: announced once, as an event
            self._returns_seen = ctl.returns
            if ctl.last_return is not None:
                self._events.append(ctl.last_return)
        scene: list[Output] = []
        target = o.reference.target if self.mode == "dp" else None
        # the target in force, for the status (`CommandStatus.setpoint`: what a console reads back)
        self._dp_target = None if target is None else (float(target[0]), float(target[1]), float(target[2]))
        if self._foxglove_on:  # (the setpoint scene is made only for the Foxglove channels)
            scene = [
                Output(topic, message, ns, zenoh=False)
                for topic, message, ns in self.foxglove.setpoint(
                    None if target is None else (float(target[0]), float(target[1]), float(target[2])),
                    now_ns,
                )
            ]
        if self.mode == "standby":
            self.fusion.set_tau_demand(np.zeros(3))
            self.control_alarms = []
            if self.consequence is not None:
                self.consequence.reset()
            return scene  # standby commands nothing: the thrusters are someone else's
        deviation: list[str] = []
        if self.mode == "dp" and o.valid:
            if ctl.returning:  # off the station not by the operator's choice: measured from the setpoint
                off = np.asarray(eta_in, dtype=float) - o.reference.target
                off[2] = ssa_scalar(float(off[2]))
                deviation = self._deviation_alarms(off, "the DP setpoint (returning)")
            else:
                deviation = self._deviation_alarms(o.eta_error)
        thrusters: list[Thruster] = []
        saturated = False
        if self.allocator is not None:
            res = self.allocator.allocate(o.tau, self.command)
            self.allocation, self.command = res, res.command
            tau_allocated = res.tau_allocated
            self.fusion.set_tau_demand(tau_allocated, res.thrust, res.azimuth)
            saturated = res.saturated
            self.control_alarms = list(res.alarms) + deviation
            self._consequence_step(t, now_ns, o.tau, float(eta_in[2]))
            thrusters = [
                Thruster(id=tid, thrust_n=f, azimuth_rad=a)
                for tid, f, a in zip(
                    self._thruster_ids, res.thrust.tolist(), res.azimuth.tolist(), strict=True
                )
            ]
        else:
            tau_allocated = o.tau  # no thruster layout: τ is the command (simulated vessels of the papers)
            self.control_alarms = deviation
            self.fusion.set_tau_demand(tau_allocated)
        return [
            Output(
                "/dp/thrusters/command",
                CommandMessage(
                    stamp_ns=now_ns,
                    mode=self.mode,  # type: ignore[arg-type]  # one of MODES: set only from them
                    tau_demand=o.tau.tolist(),
                    tau_allocated=np.asarray(tau_allocated, dtype=float).tolist(),
                    saturated=saturated,
                    thrusters=thrusters,
                    reference=o.reference.eta_d.tolist(),
                ),
                now_ns,
            ),
            *scene,
        ]

    def _consequence_step(self, t: float, now_ns: int, tau_demand: np.ndarray, psi: float) -> None:
        """The consequence analysis on the demanded τ — what is required of the thrusters, which a
        saturated allocation does not give — in DP only (in manual the operator holds the position, and
        the analysis forgets the load); its alarm joins the controller's. It is a monitor: should it fail,
        it says so in an alarm and the control step goes on."""
        ca = self.consequence
        if ca is None:
            return
        if self.mode != "dp":
            ca.reset()
            return
        try:
            if ca.update(t, tau_demand, self.thrusters_out.keys(), psi) is not None:
                self._consequence_ns = now_ns
        except Exception as exc:  # (a solver's failure must not stop the thrusters' commands)
            ca.record_failure(exc)  # (retried a second on, not at every step: its alarm up meanwhile)
        text = ca.alarm_text()
        if text is not None:
            self.control_alarms.append(text)

    def _consequence_status(self) -> ConsequenceStatus | None:
        """What the last consequence analysis found, for the status; None outside DP or before the first."""
        ca = self.consequence
        v = None if ca is None or self.mode != "dp" else ca.verdict
        if v is None:
            return None

        def case(c: FailureCase) -> FailureCaseStatus:
            return FailureCaseStatus(lost=list(c.lost), utilisation=_finite_or_none(c.utilisation))

        worst = v.worst
        return ConsequenceStatus(
            stamp_ns=self._consequence_ns,
            load=list(v.load),
            utilisation=_finite_or_none(v.intact),
            worst=None if worst is None else case(worst),
            cases=[case(c) for c in v.cases],
        )

    def _with_wind_load(self, tau: np.ndarray) -> np.ndarray:
        """τ for the observer: the thrusters' τ plus the wind force the controller's feed-forward answers
        (−τ_wind = k_w τ̂_w, with a fresh wind and while a lost one fades), a known force of the observer's
        model M ν' + D ν = τ + Jᵀ b. Without it b̂ would hold the wind too and the bias feed-forward −Jᵀ b̂
        would cancel the wind a second time (the integrator taking the excess back, slowly); with it b̂ is
        the rest of the load, and (1 − k_w) of the wind; as a lost wind's force fades, b̂ takes it over."""
        if not self._wind_used:
            return tau
        wind = self.controller.wind if self.controller is not None else None
        if wind is None or not (wind.active or wind.fading):
            return tau
        return tau - wind.tau

    def _relative_wind(self, now_ns: int, est: Estimate) -> tuple[float, float] | None:
        """The wind for the controller's feed-forward: the best fresh anemometer's relative wind (u_rw, v_rw),
        body frame (a true wind, MWV reference T, plus the estimated velocity ν̂: u_rw = u + V_t cos β_t),
        or None. Says in the status events when the feed-forward goes off (at once) and when it is back (the
        first wind at once; after an "off", once the wind has been fresh without a break for
        `WIND_ON_CONFIRM_S`, so that a flapping anemometer gives one "off", not one per lost sentence)."""
        w = self.fusion.wind(now_ns)
        source = ""
        announced = self.wind_feedforward
        if w is None:
            wind = None
            self._wind_fresh_since_ns = None
            why = (
                "no wind measured yet"
                if announced == "no wind measured yet"
                else f"no valid wind from {', '.join(self._wind_sources)} within the source timeout"
            )
        else:
            u, v, reference, source = w
            if self._wind_fresh_since_ns is None:
                self._wind_fresh_since_ns = now_ns
            why = ""
            if (
                announced
                and announced != "no wind measured yet"
                and now_ns - self._wind_fresh_since_ns < WIND_ON_CONFIRM_S * NS
            ):
                why = announced  # announced off: back "on" only once it has held (`WIND_ON_CONFIRM_S`)
            if reference == "T":
                nu = est.nu
                u, v = u + float(nu[0]), v + float(nu[1])
            wind = (u, v)
        if why != self.wind_feedforward:
            ff = self.controller.wind if self.controller is not None else None
            if why and self.wind_feedforward == "":
                if ff is not None and ff.fade_s > 0 and ff.weight > 0:  # held, fading (`WindFeedForward`)
                    # from where it is (w < 1 when lost again while still fading in): w T_f to go
                    rest = ff.weight * ff.fade_s
                    self._events.append(f"wind feed-forward fading out over {rest:.0f} s: {why}")
                else:
                    self._events.append(f"wind feed-forward off: {why}")
            elif not why:
                rest = 0.0 if ff is None or not ff.fading_in else (1.0 - ff.weight) * ff.fade_s
                more = f", fading in over {rest:.0f} s" if rest >= 0.5 else ""
                self._events.append(f"wind feed-forward on: wind from {source}{more}")
            self.wind_feedforward = why
        return wind

    def _estimate(
        self, label: str, obs: Observer, est: Estimate, now_ns: int, valid: list[bool] | None = None
    ) -> EstimateMessage:
        datum = self.fusion.datum
        eta = est.eta.tolist()
        lat = lon = None
        if datum is not None:
            lat, lon = datum.to_lat_lon(eta[0], eta[1])
        health: list[str] = [] if valid is None else self._health(now_ns, valid)
        status = est.status
        backup = self._backup_used
        if "lost" in health:
            status = "lost"
        elif status == "ok" and (
            "degraded" in health
            or (  # (no backup sources: nothing to look up, the common case)
                bool(backup)
                and (
                    self.fusion.north.source in backup.get("position", ())
                    or self.fusion.heading.source in backup.get("heading", ())
                )
            )
        ):
            status = "degraded"  # running on a subset of the references, or on a backup source
        return EstimateMessage(
            stamp_ns=now_ns,
            observer=label,
            status=status,  # type: ignore[arg-type]  # the observer's STATUS_NAMES, or "degraded"
            eta=eta,
            nu=est.nu.tolist(),
            bias=est.bias.tolist(),
            eta_wf=est.eta_wf.tolist(),
            omega0=obs.omega0.tolist(),  # the protocol's omega0: a float array (3,)
            lat_deg=lat,
            lon_deg=lon,
            heading_deg=math.degrees(eta[2]) % 360.0,
            datum=None
            if datum is None
            else (self._datum_msg if datum is self._datum_for_message else self._datum_message(datum)),
            extra=obs.extra(),
            health=health,  # type: ignore[arg-type]  # DofHealth words only
            # (the primary observer's: an extra observer's settle clock is not kept)
            settled=None if valid is None else self.settled,
            settle_s_left=None if valid is None else self.settle_left_s(now_ns),
        )

    def _datum_message(self, datum: LocalFrame) -> Datum:
        """The estimate's datum object, made once per datum (it is the same for every estimate)."""
        if self._datum_for_message is not datum:
            self._datum_for_message = datum
            self._datum_msg = Datum(lat_deg=datum.lat_deg, lon_deg=datum.lon_deg)
        return self._datum_msg

    def _health(self, now_ns: int, valid: list[bool]) -> list[str]:
        """Per DOF: ok / degraded (some references usable, not all ok) / dead_reckoning / lost."""
        if valid[0] and valid[1] and valid[2]:  # (every DOF measured: the common case, every estimate)
            health = self.monitor.health
            word = "ok" if health("position") == "ok" else "degraded"
            return [word, word, "ok" if health("heading") == "ok" else "degraded"]
        out = []
        position: str | None = None  # (asked once for both position DOFs)
        for k in range(3):
            if not valid[k]:
                measured = self._measured_ns[k]
                out.append("lost" if measured and now_ns - measured > self._lost_ns else "dead_reckoning")
            elif k < 2:
                if position is None:
                    position = "ok" if self.monitor.health("position") == "ok" else "degraded"
                out.append(position)
            else:
                out.append("ok" if self.monitor.health("heading") == "ok" else "degraded")
        return out

    def _fresh_cov(self, source: str, rx_ns: int) -> GstCovariance | None:
        held = self._fix_cov.get(source)
        return held[1] if held is not None and rx_ns <= held[0] else None

    def _location_fix(self, source: str, rx_ns: int, lat: float, lon: float, out: list[Output]) -> None:
        """The fix's `foxglove.LocationFix`, onto ``out`` (called with the Foxglove channels on)."""
        period = FIX_PERIOD_NS  # (a module global: the benchmark sets it)
        if period and rx_ns - self._last_fix_ns.get(source, -period) < period:
            return
        self._last_fix_ns[source] = rx_ns
        out.append(
            Output(
                f"/gnss/{source}/fix",
                location_fix(
                    rx_ns,
                    antenna_frame(source),
                    lat,
                    lon,
                    self._fix_alt_m.get(source, 0.0),
                    self._fresh_cov(source, rx_ns),
                ),
                rx_ns,
                zenoh=False,
            )
        )

    def _feedback_output(self, now_ns: int) -> Output:
        tau, _ = self.fusion.tau(now_ns)
        return Output(
            "/dp/thrusters/feedback",
            ThrusterFeedback(
                stamp_ns=now_ns,
                mode=self.mode,  # type: ignore[arg-type]  # one of MODES: set only from them
                tau_demand=self.fusion.tau_demand.tolist(),
                tau_allocated=tau.tolist(),
                thrusters=[
                    Thruster(id=tid, thrust_n=t, azimuth_rad=a)
                    for tid, (t, a, _) in sorted(self.fusion.thrust.items())
                ],
            ),
            now_ns,
        )

    def status_outputs(self, now_ns: int, alarms: list[str] | None = None) -> list[Output]:
        """The status (`status_message`; the caller decides when: the service's periodic one, its last one,
        or one made at once for a reference state change) and, with the Foxglove channels on, its log
        lines (`/dp/log`: `FoxgloveChannels.logs`) right after it, at its stamp: what is logged of a
        status. The lines go out with their status, never later: held for the next event or tick, they
        were written after outputs of later times (a dead-reckoned estimate, the next input), and a file
        read in its own order (streamed, or cut short and read without its index) went back in time; the
        service's last status had none at all."""
        message = self.status_message(now_ns, alarms)
        out = [Output("/dp/status", message, now_ns)]
        if self._foxglove_on:
            out += [Output(topic, line, ns, False) for topic, line, ns in self.foxglove.logs(message)]
        return out

    def status(self, now_ns: int, alarms: list[str] | None = None) -> Output:
        """The status alone, for what reads its content (a summary, a query, a test): no log lines are made
        of it, and the alarms it raises or clears are those the next `status_outputs` logs (its events,
        taken by this one, are in it and not on `/dp/log`). What is logged comes from `status_outputs`."""
        return Output("/dp/status", self.status_message(now_ns, alarms), now_ns)

    def _alarm_details(self, now_ns: int, alarms: list[str], remember: bool) -> list[AlarmDetail]:
        """Each alarm's stable key, level and since when (`gateway.alarms`); ``remember``: this status is
        logged, and what it clears is forgotten (a status for Zenoh alone changes nothing)."""
        keys = [alarm_key(a) for a in alarms]
        since = {k: self._alarm_since.get(k, now_ns) for k in keys}
        if remember:
            self._alarm_since = since
        mode = self.mode
        return [
            AlarmDetail(key=k, level=alarm_level(a, mode), since_ns=since[k])  # type: ignore[arg-type]
            for a, k in zip(alarms, keys, strict=True)
        ]

    def _setpoint_status(self) -> SetpointStatus | None:
        """The DP target of the last control step (`_dp_target`) as the status says it, with its latitude
        and longitude once the datum is set; None before DP's first step."""
        if self._dp_target is None:
            return None
        north, east, psi = self._dp_target
        lat = lon = None
        datum = self.fusion.datum
        if datum is not None:
            lat, lon = datum.to_lat_lon(north, east)
        return SetpointStatus(
            north_m=north, east_m=east, heading_deg=math.degrees(psi) % 360.0, lat_deg=lat, lon_deg=lon
        )

    def status_message(
        self, now_ns: int, alarms: list[str] | None = None, *, remember: bool = True
    ) -> Status:
        """Per-source age, counts, rejects by reason, and the alarms: the caller's, the controller's, one
        per thruster out of DP, and one per source that sent nothing yet or went stale. Without ``alarms``
        (a status made at once for a reference state change) the caller's last ones: the service's alarms
        (clock, Zenoh, a device) are still up, and a status without them would clear them on /status and in
        the alarm log.
        ``remember=False``: a status for Zenoh only (before the pipeline has a time), whose alarms are not
        carried into the next, and which says no event: the events (the start-up ones first) wait for the
        first status that is logged, so that the log has them as well as Zenoh (taken by a status that only
        Zenoh saw, they never reached the log)."""
        if alarms is None:
            alarms = self._caller_alarms
        elif remember:
            self._caller_alarms = list(alarms)
        alarms = (
            list(alarms)
            + self._estimate_alarms(now_ns)
            + self._settling_alarms(now_ns)
            + self.control_alarms
            + self._command_alarms()
        )
        alarms += [f"thruster {tid} out of DP ({why})" for tid, why in sorted(self.thrusters_out.items())]
        references: dict[str, list[ReferenceStatus]] = {}
        for name, states in self.monitor.states().items():
            references[name] = [
                ReferenceStatus(
                    role=st.role,
                    state=st.state,  # type: ignore[arg-type]  # one of the STATES
                    reason=st.reason,
                    sigma_m=self.monitor.sigma_m(name) if st.role == "position" else None,
                )
                for st in states
            ]
            alarms += [
                f"{reference_name(st.role, name)}: {st.state} ({st.reason})"
                for st in states
                if st.state in ("rejected", "suspect")
            ]
        events: list[str] = []
        if remember:
            events, self._events = self._startup_events + self._events, []
            self._startup_events = []
        for name, c in self.counters.items():
            spec = self.sources[name]
            bad = c.bad_input_alarm(name, now_ns, spec.timeout_s)  # (notes the good input: every status)
            if c.last_rx_ns == 0:
                alarms.append(f"source {name}: no data yet")
            elif (now_ns - c.last_rx_ns) / NS > spec.timeout_s:
                alarms.append(f"source {name}: stale ({(now_ns - c.last_rx_ns) / NS:.1f} s without data)")
            elif bad is not None:
                alarms.append(bad)
        return Status(
            stamp_ns=now_ns,
            mode=self.mode,  # type: ignore[arg-type]  # one of MODES: set only from them
            observer=self.spec.observer_name,
            initialized=self.observer.initialized,
            estimates=self.estimates,
            sources={name: c.as_message(now_ns) for name, c in self.counters.items()},
            alarms=list(alarms),
            alarm_details=self._alarm_details(now_ns, alarms, remember),
            references=references,
            events=events,
            commands=CommandStatus(
                accepted=dict(self.commands.counters.accepted),
                refused=dict(self.commands.counters.refused),
                last_refused=self.commands.counters.last_refused,
                superseded=dict(self.commands.counters.superseded),
                expired=dict(self.commands.counters.expired),
                setpoint=self._setpoint_status() if self.mode == "dp" else None,
                setpoint_waiting=None if self._pending_setpoint is None else dict(self._pending_setpoint),
            ),
            consequence=self._consequence_status(),
        )


def _seconds(x: float) -> str:
    """A time in seconds as an operator reads it: one decimal (2.0), or as many as it has (0.25)."""
    return f"{x:.1f}" if round(x, 1) == x else f"{x:g}"


def _show_setpoint(sp: Mapping[str, Any]) -> str:
    """A setpoint as an operator reads it: north/east or lat/lon, and heading."""
    if "north_m" in sp:
        where = f"north {float(sp['north_m']):.1f} m, east {float(sp['east_m']):.1f} m"
    else:
        where = f"lat {float(sp['lat_deg']):.6f}°, lon {float(sp['lon_deg']):.6f}°"
    return f"({where}, heading {float(sp['heading_deg']):.1f}°)"


SIGNING_REJECTED_TOPIC = "/raw/mavlink_rejected/"
"""`/raw/mavlink_rejected/<source>`: the frames of a signed link refused for signing (`SigningRejection`)."""


def _signing_rejections(
    source: str, rx_ns: int, peer: str, rejects: Sequence[mv.SigningReject]
) -> list[Output]:
    """The log's record of each frame of a chunk of ``peer`` received at ``rx_ns`` refused for signing:
    log only (not Zenoh), at the chunk's receive time, so that a replay without the key refuses the same
    frames (`SourceSpec.logged_verdicts`). Made only for refused frames."""
    out = []
    for r in rejects:
        ids = mv.frame_ids(r.frame)
        message = SigningRejection(
            stamp_ns=rx_ns,
            source=source,
            reason=r.reason,  # type: ignore[arg-type]  # (one of mv.SIGNING_REASONS)
            offset=r.offset,
            digest=mv.frame_digest(r.frame),
            system_id=ids.system_id,
            component_id=ids.component_id,
            seq=ids.seq,
            msg_id=ids.msg_id,
            link_id=ids.link_id,
            signature_timestamp=ids.signature_timestamp,
            peer=peer,
        )
        out.append(Output(SIGNING_REJECTED_TOPIC + source, message, rx_ns, False))
    return out


def _finite_or_none(x: float) -> float | None:
    return x if math.isfinite(x) else None


HEADING_LIMITS_DEG = (3.0, 5.0)
"""Heading deviation from the DP reference (warning, alarm), degrees: the usual DP console defaults."""

OUT_FLAGS = (
    (int(mv.AzimuthThrusterFlags.FAULT), "fault"),
    (int(mv.AzimuthThrusterFlags.EMERGENCY_STOP), "emergency stop"),
    (int(mv.AzimuthThrusterFlags.LOCAL_CONTROL), "local control"),
)
"""Drive flags under which a thruster does not deliver DP commands, with the words of its alarm. The others
(WARNING, THRUST_LIMITED, …) leave it in the allocation: it still delivers, perhaps less."""

MAX_SENDERS = 64
"""Senders per source that get a framer of their own; more (a scan, a flood of spoofed addresses) share
one, so memory stays bounded whoever sends. A newcomer first makes room by forgetting the senders silent
for longer than the source's timeout (`Pipeline._forget_idle_senders`)."""


def _sender_key(peer: str, per_sender: Mapping[tuple[str, str], object], source: str) -> str:
    """``peer`` while the source has fewer than `MAX_SENDERS` senders, else the shared key ``"*"``."""
    if sum(1 for name, _ in per_sender if name == source) < MAX_SENDERS:
        return peer
    return "*"


def _source_names(names: tuple[str, ...]) -> list[str]:
    """The distinct names, sorted (one or two of them, usually the same: the cheap cases first)."""
    if len(names) < 2:
        return list(names)
    if len(names) == 2 and names[0] == names[1]:
        return [names[0]]
    return sorted(set(names))
