"""Every message dpgw publishes on Zenoh and logs to MCAP, defined once.

Each class below is the contract of one stream (DESIGN.md, "Interfaces other programs rely on"). From it
come, with nothing written twice:
- the JSON payload: `Message.encode()` (field names and order as declared; non-finite floats as `null`);
- the JSON Schema (draft 2020-12) embedded in each MCAP channel: `wire.message_schema.json_schema`;
- the field tables of `docs/interfaces.md`: `tools/gen_interfaces.py` (a test fails when they drift).
Extend them (new optional fields, new topics); do not rename or remove a field.

**Why msgspec Structs.** The estimate, measurement and command are built and encoded on the live path at
every observer step. `bench/bench_messages.py` builds and encodes them with each candidate side by side
(µs per message, ratio to the dict literal + orjson the pipeline used before; best of 7 interleaved
rounds, 2-core shared machine): msgspec Struct 1.20 / 0.64 / 1.93 µs (0.90 / 0.63 / 0.70 of before);
dict + orjson 1.33 / 1.02 / 2.74; dataclass(slots) + orjson 2.17 / 1.26 / 3.85 (1.2-1.6x); pydantic
4.55 / 2.83 / 6.96 validated (2.5-3.4x), slower still with `model_construct`. The JSON is the same bytes
as before, except that a float of magnitude >= 1e16 is spelled `1e16` rather than `1e+16` (the same
number to every JSON reader; no dpgw field comes near it).

Conventions shared by every message:
- SI units and radians; local NED at the datum (η = [N, E, ψ]), body frame ν = [u, v, r], τ = [X, Y, N].
- Every float may be `null` in the JSON: JSON has no NaN or ±inf, so a non-finite float is encoded as
  `null`; hence dpgw's schemas type floats as `["number", "null"]`. `foxglove.LocationFix` is the
  exception (Foxglove's schema; its writers never put a non-finite number in it).
- Objects accept extra fields (no `additionalProperties: false`) so payloads can grow. The estimate's
  observer-specific fields (`Observer.extra()`: MMAE weights, scheduled ω0 ...) travel in `Estimate.extra`
  and appear at the top level of the JSON, after the declared fields; a declared field always wins over an
  extra of the same name.
- A field with a default is optional: it is left out of the JSON while it holds its default (`None`, or
  an empty `extra`), and the schema does not require it. Every other field is always present.
- Fields are keyword-only, so a call site names what it fills in.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

import msgspec
import numpy as np

from wire.json_payload import encode_json, to_jsonable

__all__ = [
    "ANY",
    "MESSAGES",
    "SIM_CLOCK_KEY",
    "TOPICS",
    "AnyObject",
    "CommandStatus",
    "ConsequenceStatus",
    "Datum",
    "DeadReckoningTick",
    "Estimate",
    "FailureCaseStatus",
    "FrameTransform",
    "FrameTransforms",
    "LocationFix",
    "Log",
    "ManualTau",
    "Measurement",
    "Message",
    "ModeRequest",
    "PoseInFrame",
    "RawMavlink",
    "RawNmea",
    "Record",
    "ReferenceStatus",
    "SceneEntity",
    "SceneUpdate",
    "Setpoint",
    "SigningRejection",
    "SimClock",
    "SourceStatus",
    "Status",
    "Thruster",
    "ThrusterCommand",
    "ThrusterFeedback",
    "Time",
    "Topic",
    "TruthState",
    "encoder_of",
    "message_for_topic",
]


def doc(description: str, unit: str = "", schema: dict[str, Any] | None = None) -> msgspec.Meta:
    """A field's meaning and unit (the schema's `description`; the doc table's `meaning` and `unit`).
    `schema` replaces the generated JSON Schema of the field (for Foxglove's own definitions)."""
    extra: dict[str, Any] = {}
    if unit:
        extra["unit"] = unit
    if schema is not None:
        extra["schema"] = schema
    return msgspec.Meta(description=description, extra=extra or None)


Vec3 = Annotated[list[float], msgspec.Meta(min_length=3, max_length=3)]
"""Three numbers ([N, E, ψ] or [X, Y, N] as the field says); each may be null (NaN)."""

ETA = "η = [N, E, ψ]: north, east, heading (clockwise from true north, in [-π, π))."
NU = "ν = [u, v, r]: surge (forward), sway (starboard), yaw rate."
TAU = "[X, Y, N]: surge force, sway force, yaw moment, in the body frame."
STAMP = (
    "Event time, UTC nanoseconds since the Unix epoch: when the input that produced it was received, on "
    'the gateway\'s clock (the simulation time with `[time] clock = "sim"`; in a replay of an NMEA text '
    "log, the sentences' own time). JavaScript readers parse it as a double (~256 ns resolution)."
)
TRUTH_STAMP = (
    "Simulation time of the sample, UTC nanoseconds since the Unix epoch. JavaScript readers parse it as "
    "a double (~256 ns resolution)."
)

EstimateStatus = Literal["initializing", "ok", "dead_reckoning", "degraded", "lost"]
DofHealth = Literal["ok", "degraded", "dead_reckoning", "lost"]
Mode = Literal["standby", "dp", "manual"]


# --- encoding -----------------------------------------------------------------------------------------


def _enc_hook(obj: Any) -> Any:
    """What msgspec cannot encode itself: numpy scalars and arrays (an observer's extras, a numpy float
    handed over unconverted), bytes-likes, dataclasses, enums (through `to_jsonable`)."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return to_jsonable(obj)  # raises TypeError for what JSON cannot hold, as encode_json does


_ENCODER = msgspec.json.Encoder(enc_hook=_enc_hook)


class Record(msgspec.Struct, kw_only=True, omit_defaults=True, gc=False):
    """An object inside a message (or a message itself). `gc=False`: records hold only plain values and
    containers, never a cycle, so the garbage collector need not track the hundreds of thousands a replay
    makes. `TITLE`: the schema's `title` (None: no title, as for dpgw's nested objects)."""

    TITLE: ClassVar[str | None] = None
    FLATTEN: ClassVar[tuple[str, ...]] = ()
    """Mapping fields whose items are written at the top level of the JSON, not as a nested object."""


class Message(Record, kw_only=True):
    """A top-level message: one Zenoh payload / one MCAP message. The class docstring is its schema's
    description; `TITLE` its schema name (the MCAP schema record's name)."""

    TITLE: ClassVar[str | None] = "dpgw.Message"
    FOXGLOVE: ClassVar[bool] = False
    """A schema Foxglove defines: no `$schema` key, and numbers are plain `number` (never null)."""

    def encode(self) -> bytes:
        """The JSON payload: compact UTF-8, declared fields in order, non-finite floats as null, floats in
        their shortest round-trip form. The bytes are those the dict payloads (`wire.json_payload`, orjson)
        gave, except that a magnitude of 1e16 or more is spelled ``1e16`` rather than ``1e+16``: the same
        number to any JSON reader."""
        return _ENCODER.encode(self)

    def to_dict(self) -> dict[str, Any]:
        """The payload as plain Python (what `json.loads(self.encode())` gives, except that a non-finite
        float stays a float): for consumers that index payloads by field name."""
        out: dict[str, Any] = msgspec.to_builtins(self, enc_hook=_enc_hook)
        return out


def encoder_of(cls: type[Message]) -> Callable[[Any], bytes]:
    """A function giving ``msg.encode()`` for a message of class `cls`: the msgspec encoder's own
    `encode` (called from C, no Python frame: ~0.1 µs a message less) where the class encodes as `Message`
    does, else the class's `encode`. For loops that encode hundreds of thousands of messages (replay)."""
    return _ENCODER.encode if cls.encode is Message.encode else cls.encode


# --- the gateway's outputs ----------------------------------------------------------------------------


class Datum(Record, kw_only=True):
    lat_deg: Annotated[float, doc("Datum latitude (WGS-84).", "deg")]
    lon_deg: Annotated[float, doc("Datum longitude (WGS-84).", "deg")]


class Estimate(Message, kw_only=True):
    """Observer state estimate of the vessel's reference point (Zenoh `<prefix>/estimate`)."""

    TITLE = "dpgw.Estimate"
    FLATTEN = ("extra",)

    stamp_ns: Annotated[int, doc(STAMP, "ns (UTC)")]
    observer: Annotated[str, doc("Observer name (or replay label), e.g. `passive`, `mmae`.")]
    status: Annotated[
        EstimateStatus,
        doc(
            "initializing: not yet converged or no datum; ok: every reference fresh and passing its "
            "tests; dead_reckoning: a DOF has no usable reference, predicting from the model; degraded: "
            "running on a subset of the references (one rejected, suspect or stale) or on a backup "
            "source; lost: no usable position reference for longer than `integrity.lost_after_s`."
        ),
    ]
    eta: Annotated[
        Vec3, doc("Low-frequency position and heading of the reference point, " + ETA, "m, m, rad")
    ]
    nu: Annotated[Vec3, doc("Low-frequency velocity " + NU, "m/s, m/s, rad/s")]
    bias: Annotated[Vec3, doc("Slowly varying environmental force [X, Y, N], earth-fixed axes.", "N, N, N·m")]
    eta_wf: Annotated[
        Vec3,
        doc(
            "Wave-frequency motion [N, E, ψ]: the estimate of the observer's wave model.",
            "m, m, rad",
        ),
    ]
    omega0: Annotated[
        Vec3,
        doc(
            "Wave peak frequency in use by the wave model per DOF [N, E, ψ] (scheduled by "
            "`gain_scheduled`, blended by `mmae`).",
            "rad/s",
        ),
    ]
    lat_deg: Annotated[
        float | None, doc("Latitude of eta (WGS-84, north positive); null before a datum.", "deg")
    ]
    lon_deg: Annotated[
        float | None, doc("Longitude of eta (WGS-84, east positive); null before a datum.", "deg")
    ]
    heading_deg: Annotated[float, doc("Heading ψ in [0, 360), clockwise from true north.", "deg")]
    datum: Annotated[Datum | None, doc("Origin of the local NED frame; null before the first valid fix.")]
    health: Annotated[
        list[DofHealth],
        doc(
            "Per DOF [N, E, ψ]: ok (every reference passes), degraded (some usable, not all), "
            "dead_reckoning (none usable), lost (dead reckoning past `integrity.lost_after_s`); "
            "left out when not known (an extra observer's estimate)."
        ),
    ] = []
    settled: Annotated[
        bool | None,
        doc(
            "The observer's estimate has settled: its start (first estimate, or a restart) lies at least "
            "the observer's settle time behind (1.5 time constants of its slowest error mode, "
            'docs/gateway.md, "Waiting for the observer"). Until then the bias estimate is still '
            "growing and DP engaged on it starts with a transient. Independent of `status`; absent when "
            "not known (an extra observer's estimate)."
        ),
    ] = None
    settle_s_left: Annotated[
        float | None,
        doc("Seconds until `settled` (0 once settled); absent when not known.", "s"),
    ] = None
    extra: Annotated[
        dict[str, Any],
        doc(
            "Observer-specific fields (`Observer.extra()`), written at the top level of the JSON after "
            "the fields above, e.g. `weights` (MMAE)."
        ),
    ] = {}

    def encode(self) -> bytes:
        if not self.extra:  # the fixed-gain observer: `extra` is left out (omit_defaults)
            return _ENCODER.encode(self)
        return encode_json(self.to_dict())

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = msgspec.to_builtins(self, enc_hook=_enc_hook)
        for key, value in out.pop("extra", {}).items():
            out.setdefault(key, value)  # a declared field wins over an extra of the same name
        return out


class Measurement(Message, kw_only=True):
    """Fused position/heading measurement y fed to the observer, and the τ it got (Zenoh
    `<prefix>/measurement`)."""

    TITLE = "dpgw.Measurement"

    stamp_ns: Annotated[int, doc(STAMP, "ns (UTC)")]
    eta: Annotated[
        list[float | None],
        msgspec.Meta(min_length=3, max_length=3),
        doc("Measured " + ETA + " Lever arms compensated; null where not measured.", "m, m, rad"),
    ]
    valid: Annotated[
        list[bool],
        msgspec.Meta(min_length=3, max_length=3),
        doc(
            "Per component of eta [N, E, ψ]: a measurement in use at this step, new or held from its "
            "source's last accepted one (within its `timeout_s`: the observer steps on every input with each "
            "DOF's latest measurement)."
        ),
    ]
    sources: Annotated[list[str], doc("Names (from the config) of the sources that contributed.")]
    quality: Annotated[
        Any,
        doc(
            "Source quality indicator, free form; the gateway gives the GGA fix quality of the "
            "position in use (an integer)."
        ),
    ]
    sigma_m: Annotated[
        float | None,
        doc(
            "Horizontal 1σ of the position in use from its receiver's GST: √((C_NN + C_EE)/2), the RMS of "
            "the north and east σ; null if none.",
            "m",
        ),
    ]
    tau: Annotated[Vec3, doc("Generalised force the observer was given " + TAU, "N, N, N·m")]
    tau_source: Annotated[
        str,
        doc(
            "Where tau came from: `feedback` (the thrusters' reported thrust) or `demand` (the last command)."
        ),
    ]
    covariance_ne_m2: Annotated[
        Vec3 | None,
        doc(
            "Horizontal covariance of the position in use, [C_NN, C_NE, C_EE] in north/east, from its "
            "receiver's GST (the full error ellipse when the sentence has one: docs/nmea.md); left out "
            "without a fresh GST.",
            "m², m², m²",
        ),
    ] = None


class Thruster(Record, kw_only=True):
    id: Annotated[int | str, doc("Thruster id as in the vessel model.")]
    thrust_n: Annotated[float, doc("Thrust magnitude; negative for reversed thrust.", "N")]
    azimuth_rad: Annotated[float, doc("Azimuth of the thrust, body frame, from the bow, clockwise.", "rad")]


class ThrusterCommand(Message, kw_only=True):
    """Thrust allocation output (Zenoh `<prefix>/thrusters/command`). Not published in standby."""

    TITLE = "dpgw.ThrusterCommand"

    stamp_ns: Annotated[int, doc(STAMP, "ns (UTC)")]
    mode: Annotated[Mode, doc("Gateway mode when the command was made.")]
    tau_demand: Annotated[
        Vec3, doc("Generalised force demanded by the DP controller or manual input " + TAU, "N, N, N·m")
    ]
    tau_allocated: Annotated[
        Vec3,
        doc("Generalised force the allocation achieves (the demand without a thruster layout).", "N, N, N·m"),
    ]
    saturated: Annotated[
        bool, doc("The thrusters cannot deliver tau_demand; tau_allocated is the closest they can.")
    ]
    thrusters: Annotated[list[Thruster], doc("One entry per thruster; empty without a thruster layout.")]
    reference: Annotated[Vec3, doc("The reference model's η_d the controller tracks [N, E, ψ].", "m, m, rad")]


class ThrusterFeedback(Message, kw_only=True):
    """Thruster feedback decoded from MAVLink (Zenoh `<prefix>/thrusters/feedback`): the fields of the
    command, of which only stamp_ns and thrusters are always present."""

    TITLE = "dpgw.ThrusterFeedback"

    stamp_ns: Annotated[int, doc(STAMP, "ns (UTC)")]
    mode: Annotated[Mode | None, doc("Gateway mode when the feedback arrived.")] = None
    tau_demand: Annotated[Vec3 | None, doc("Generalised force last demanded " + TAU, "N, N, N·m")] = None
    tau_allocated: Annotated[
        Vec3 | None, doc("Generalised force the thrusters report delivering " + TAU, "N, N, N·m")
    ] = None
    thrusters: Annotated[list[Thruster], doc("One entry per thruster that reported.")]


class SourceStatus(Record, kw_only=True):
    age_s: Annotated[float | None, doc("Time since the last message; null if none yet.", "s")]
    received: Annotated[int, doc("Sentences/frames decoded and used or understood (count).")]
    rejected: Annotated[
        dict[str, int],
        doc(
            'Rejected by reason (count), e.g. {"bad_checksum": 2}; the reasons are listed in '
            'docs/gateway.md ("Bad input").'
        ),
    ]
    warnings: Annotated[
        dict[str, int],
        doc(
            'Used, with a caveat, by reason (count), e.g. {"lever_arm_heading_only": 12}: the sentence was '
            "not rejected, but something about it is worth an operator's eye; the reasons are listed in "
            'docs/gateway.md ("Bad input"). Left out while empty.'
        ),
    ] = msgspec.field(default_factory=dict)
    bytes: Annotated[int, doc("Bytes received (count).")]
    dropped: Annotated[
        int,
        doc(
            "Datagrams the kernel dropped before the gateway could read them (UDP receive buffer full; "
            "count). Left out while 0."
        ),
    ] = 0
    skipped_bytes: Annotated[
        int,
        doc(
            "MAVLink links: bytes outside any valid frame (noise, another protocol on the link, the bytes of "
            "rejected frames; count), so a link that carries something else shows it. NMEA links count "
            "their noise as `garbage` lines in `rejected` instead. Left out while 0."
        ),
    ] = 0
    lost_lines: Annotated[
        int,
        doc(
            "NMEA over an IEC 61162-450 network: sentences its devices sent that never arrived, seen where "
            "the line count (`n:`) of a device's TAG blocks skips (count). Lost on the network (a switch, "
            "a multicast route), where `dropped` cannot see. Left out while 0."
        ),
    ] = 0
    reconnects: Annotated[
        int,
        doc(
            "Times the link came back after it was lost: a TCP client connected again, a serial port "
            "reopened, a `tcp-listen` server's clients accepted after the first (count). A UDP socket has "
            "no link to lose. Left out while 0."
        ),
    ] = 0
    last_disconnect: Annotated[
        str | None,
        doc(
            "Why the link was last lost, as the transport saw it (`connection to 10.0.0.5:4001 lost: "
            "closed by the server`, `serial port /dev/ttyUSB0 failed: ...`, `client 10.0.0.7:50122 gone: "
            "closed by the client`). Left out while it never was."
        ),
    ] = None
    last_disconnect_ns: Annotated[
        int | None,
        doc("When the link was last lost (the wall clock). Left out while it never was.", "ns (UTC)"),
    ] = None


class AlarmDetail(Record, kw_only=True):
    key: Annotated[
        str,
        doc(
            "The alarm's identity: its text with the figures that are values as `#` (\"source dgps1: "
            'stale (# s without data)"). The same while the alarm stays up as its figures change; what '
            "a console tells alarms apart by, raised and cleared."
        ),
    ]
    level: Annotated[
        Literal["warning", "critical"],
        doc(
            "critical: DP cannot be trusted to hold the vessel now (the estimate lost; in DP, dead "
            "reckoning on no position or heading reference; beyond the alarm circle or heading limit); "
            "warning: the rest."
        ),
    ]
    since_ns: Annotated[
        int, doc("When this alarm (this key) was raised: the stamp of the first status with it.", "ns (UTC)")
    ]


class ReferenceStatus(Record, kw_only=True):
    role: Annotated[
        str, doc("What the source is tested as: `position`, `heading`, `thrusters` or `attitude` (an MRU).")
    ]
    state: Annotated[
        Literal["ok", "suspect", "rejected", "stale"],
        doc(
            "ok: passes every test, in use; suspect: in use with a soft alarm (two references diverge) "
            "or passing again after a rejection and not yet readmitted (not in use); rejected: failed a "
            "test, not in use; stale: no data within its timeout."
        ),
    ]
    reason: Annotated[str, doc("Why it is not ok, for a person (empty when ok).")]
    sigma_m: Annotated[
        float | None, doc("Measured 1σ noise of a position reference; left out when not measured yet.", "m")
    ] = None


class SetpointStatus(Record, kw_only=True):
    north_m: Annotated[float, doc("North of the local frame's origin (the datum).", "m")]
    east_m: Annotated[float, doc("East of the local frame's origin (the datum).", "m")]
    heading_deg: Annotated[float, doc("Heading, clockwise from north.", "deg")]
    lat_deg: Annotated[float | None, doc("Latitude (WGS-84); left out before a datum.", "deg")] = None
    lon_deg: Annotated[float | None, doc("Longitude (WGS-84); left out before a datum.", "deg")] = None


class CommandStatus(Record, kw_only=True):
    accepted: Annotated[dict[str, int], doc('Command inputs taken, by key (count), e.g. {"mode": 2}.')]
    refused: Annotated[
        dict[str, int],
        doc('Command inputs refused, by "key: reason" (count), e.g. {"setpoint: too far": 1}.'),
    ]
    last_refused: Annotated[str | None, doc("Why the last refused input was refused; absent if none.")] = None
    superseded: Annotated[
        dict[str, int],
        doc(
            "Command inputs taken but dropped unapplied because a newer one of the same key replaced them, "
            'by key (count), e.g. {"setpoint": 1}: a setpoint waiting for the next control step or for a '
            "healthy estimate. Left out while empty."
        ),
    ] = msgspec.field(default_factory=dict)
    expired: Annotated[
        dict[str, int],
        doc(
            'Command inputs held past their hold time, by key (count), e.g. {"tau": 1}: a manual τ not '
            "renewed within commands.manual_tau_hold_s, the thrust demand then set to zero. Left out while "
            "empty."
        ),
    ] = msgspec.field(default_factory=dict)
    setpoint: Annotated[
        SetpointStatus | None,
        doc(
            "The DP setpoint in force: the controller's target (the operator's setpoint once applied, or the "
            "position and heading held when DP was engaged without one), as of the last control step; "
            "left out outside DP. What a console reads back to show the station being kept."
        ),
    ] = None
    setpoint_waiting: Annotated[
        dict[str, Any] | None,
        doc(
            "A setpoint taken but not applied yet, as it was sent (it waits for the next control step, for "
            "an estimate healthy enough for DP); left out when none waits."
        ),
    ] = None


class FailureCaseStatus(Record, kw_only=True):
    lost: Annotated[list[int], doc("Thruster ids lost together in this failure case.")]
    utilisation: Annotated[
        float | None,
        doc(
            "Share of the remaining thrusters' capacity the present load would take after the failure "
            "(1 = all of it; over 1: position lost); null: the rest cannot push against it at all, or no "
            "thruster is left."
        ),
    ]


class ConsequenceStatus(Record, kw_only=True):
    stamp_ns: Annotated[int, doc("When the failure cases were last tested.", "ns (UTC)")]
    load: Annotated[
        list[float],
        msgspec.Meta(min_length=3, max_length=3),
        doc("The mean load tested, the demanded τ low-passed, body frame [X, Y, N].", "N, N, N·m"),
    ]
    utilisation: Annotated[
        float | None,
        doc("Share of the capacity of the thrusters in service the load takes now; null: unreachable."),
    ]
    worst: Annotated[
        FailureCaseStatus | None,
        doc("The failure case of the highest utilisation; left out if none to test."),
    ] = None
    cases: Annotated[
        list[FailureCaseStatus],
        doc("Every failure case tested: the configured groups in order, then each thruster in no group."),
    ] = []


class Status(Message, kw_only=True):
    """Gateway health (Zenoh `<prefix>/status`, also the answer to a query on that key)."""

    TITLE = "dpgw.Status"

    stamp_ns: Annotated[int, doc(STAMP, "ns (UTC)")]
    mode: Annotated[Mode, doc("Current gateway mode.")]
    observer: Annotated[str, doc("Name of the observer publishing on `<prefix>/estimate`.")]
    initialized: Annotated[bool, doc("The observer has been initialised (has a first measurement).")]
    estimates: Annotated[
        int,
        doc(
            "The observer's estimates published so far, made on measurements (count); the dead-reckoned "
            "estimates published while every source is silent are not counted."
        ),
    ]
    sources: Annotated[dict[str, SourceStatus], doc("Per input source, keyed by source name.")]
    alarms: Annotated[
        list[str | dict[str, Any]],
        doc("Active alarms: short strings, or objects with at least `code` and `message`."),
    ]
    alarm_details: Annotated[
        list[AlarmDetail],
        doc(
            "One entry per alarm of `alarms`, in the same order: its stable key, level and since when. "
            "Left out while there is no alarm."
        ),
    ] = []
    references: Annotated[
        dict[str, list[ReferenceStatus]],
        doc("Per source, its state in each role it is tested in (reference and feedback integrity)."),
    ] = {}
    events: Annotated[
        list[str],
        doc(
            "Reference state changes since the previous status, for a person; a status is published at "
            "once when one happens."
        ),
    ] = []
    commands: Annotated[
        CommandStatus | None, doc("The command inputs (mode, setpoint, τ): taken, refused and why.")
    ] = None
    consequence: Annotated[
        ConsequenceStatus | None,
        doc(
            "The online consequence analysis in DP: would the thrusters left after the worst-case failure "
            "hold the present load (docs/controller.md); left out outside DP or without a thruster layout."
        ),
    ] = None


class Time(Record, kw_only=True):
    TITLE = "time"

    sec: Annotated[int, msgspec.Meta(ge=0), doc("Whole seconds since the Unix epoch (UTC).", "s")]
    nsec: Annotated[int, msgspec.Meta(ge=0, le=999_999_999), doc("Nanoseconds within the second.", "ns")]


class LocationFix(Message, kw_only=True):
    """GNSS position fix (WGS-84), for Foxglove's Map panel."""

    # Field names, types and constraints of Foxglove's published JSON schema (same title, so Foxglove
    # recognises the channel and shows the log on its map); descriptions are ours.
    TITLE = "foxglove.LocationFix"
    FOXGLOVE = True

    timestamp: Annotated[Time, doc("Time of the fix (UTC): seconds and nanoseconds since the Unix epoch.")]
    frame_id: Annotated[
        str,
        doc(
            "The frame the fix is of: the source (antenna) for a GNSS fix, `vessel` for the estimate on "
            "`/dp/estimate/fix` (its pose's frame; Keelson's `dpgw/estimate` keeps `estimate`)."
        ),
    ]
    latitude: Annotated[float, doc("Latitude (WGS-84, north positive).", "deg")]
    longitude: Annotated[float, doc("Longitude (WGS-84, east positive).", "deg")]
    altitude: Annotated[float, doc("Altitude; 0 when not known.", "m")]
    position_covariance: Annotated[
        list[float],
        msgspec.Meta(min_length=9, max_length=9),
        doc(
            "3x3 position covariance, row-major, axes East, North, Up (ENU, Foxglove's convention; not "
            "NED) in the tangent plane at the fix.",
            "m²",
        ),
    ]
    position_covariance_type: Annotated[
        int,
        doc(
            "How position_covariance is known: 0 unknown, 1 approximated, 2 diagonal known, 3 known.",
            schema={
                "title": "foxglove.PositionCovarianceType",
                "oneOf": [
                    {"title": "UNKNOWN", "const": 0},
                    {"title": "APPROXIMATED", "const": 1},
                    {"title": "DIAGONAL_KNOWN", "const": 2},
                    {"title": "KNOWN", "const": 3},
                ],
            },
        ),
    ]
    heading: Annotated[float | None, doc("Heading, clockwise from true north; optional.", "rad")] = None


# --- Foxglove's own schemas -----------------------------------------------------------------------------
# Field names, types, nesting and constraints are Foxglove's published JSON schemas (foxglove-sdk,
# `schemas/jsonschema/`), under the same titles, so Foxglove Studio recognises each channel and draws it;
# the descriptions are ours. Every array field Foxglove requires is required here too (an empty list when
# unused): Foxglove's JSON decoder does not fill in missing fields.


def _enum(title: str, *names: str) -> dict[str, Any]:
    """A Foxglove enum field's schema: its values as titled constants, as Foxglove writes them."""
    return {"title": title, "oneOf": [{"title": n, "const": k} for k, n in enumerate(names)]}


class Duration(Record, kw_only=True):
    TITLE = "duration"

    sec: Annotated[int, doc("Whole seconds.", "s")]
    nsec: Annotated[int, msgspec.Meta(ge=0, le=999_999_999), doc("Nanoseconds within the second.", "ns")]


class Vector3(Record, kw_only=True):
    TITLE = "foxglove.Vector3"

    x: Annotated[float, doc("x component.")]
    y: Annotated[float, doc("y component.")]
    z: Annotated[float, doc("z component.")]


class Point3(Record, kw_only=True):
    TITLE = "foxglove.Point3"

    x: Annotated[float, doc("x coordinate position.", "m")]
    y: Annotated[float, doc("y coordinate position.", "m")]
    z: Annotated[float, doc("z coordinate position.", "m")]


class Quaternion(Record, kw_only=True):
    TITLE = "foxglove.Quaternion"

    x: Annotated[float, doc("x value.")]
    y: Annotated[float, doc("y value.")]
    z: Annotated[float, doc("z value.")]
    w: Annotated[float, doc("w value.")]


class Pose(Record, kw_only=True):
    TITLE = "foxglove.Pose"

    position: Annotated[Vector3, doc("Position in the frame (ENU or FLU: docs/foxglove.md).", "m")]
    orientation: Annotated[Quaternion, doc("Orientation in the frame (a yaw about +z for dpgw).")]


class Color(Record, kw_only=True):
    TITLE = "foxglove.Color"

    r: Annotated[float, doc("Red value between 0 and 1.")]
    g: Annotated[float, doc("Green value between 0 and 1.")]
    b: Annotated[float, doc("Blue value between 0 and 1.")]
    a: Annotated[float, doc("Alpha value between 0 and 1.")]


class FrameTransform(Record, kw_only=True):
    TITLE = "foxglove.FrameTransform"

    timestamp: Annotated[Time, doc("Time of the transform (UTC).")]
    parent_frame_id: Annotated[str, doc("Parent frame: `ltp` (local tangent plane at the datum, ENU).")]
    child_frame_id: Annotated[str, doc("Child frame: `vessel` (estimate) or `vessel_measured`, FLU.")]
    translation: Annotated[Vector3, doc("The child's origin in the parent frame: [east, north, 0].", "m")]
    rotation: Annotated[Quaternion, doc("The child's orientation in the parent frame: yaw π/2 − ψ about up.")]


class FrameTransforms(Message, kw_only=True):
    """Transforms from the datum's local tangent plane to the vessel frames (for Foxglove's 3D panel)."""

    TITLE = "foxglove.FrameTransforms"
    FOXGLOVE = True

    transforms: Annotated[list[FrameTransform], doc("The estimate's frame, then the measurement's.")]


class PoseInFrame(Message, kw_only=True):
    """A timestamped pose of the vessel's reference point in the datum's local tangent plane."""

    TITLE = "foxglove.PoseInFrame"
    FOXGLOVE = True

    timestamp: Annotated[Time, doc("Time of the pose (UTC).")]
    frame_id: Annotated[str, doc("Frame of the pose: `ltp` (local tangent plane at the datum, ENU).")]
    pose: Annotated[Pose, doc("[east, north, 0] and the yaw π/2 − ψ about up.")]


class KeyValuePair(Record, kw_only=True):
    TITLE = "foxglove.KeyValuePair"

    key: Annotated[str, doc("Key.")]
    value: Annotated[str, doc("Value.")]


class ArrowPrimitive(Record, kw_only=True):
    TITLE = "foxglove.ArrowPrimitive"

    pose: Annotated[Pose, doc("Position of the arrow's tail and orientation of the arrow (along +x).")]
    shaft_length: Annotated[float, doc("Length of the arrow shaft.", "m")]
    shaft_diameter: Annotated[float, doc("Diameter of the arrow shaft.", "m")]
    head_length: Annotated[float, doc("Length of the arrow head.", "m")]
    head_diameter: Annotated[float, doc("Diameter of the arrow head.", "m")]
    color: Annotated[Color, doc("Color of the arrow.")]


class CubePrimitive(Record, kw_only=True):
    TITLE = "foxglove.CubePrimitive"

    pose: Annotated[Pose, doc("Position of the center of the cube and orientation of the cube.")]
    size: Annotated[Vector3, doc("Size of the cube along each axis.", "m")]
    color: Annotated[Color, doc("Color of the cube.")]


class SpherePrimitive(Record, kw_only=True):
    TITLE = "foxglove.SpherePrimitive"

    pose: Annotated[Pose, doc("Position of the center of the sphere and orientation of the sphere.")]
    size: Annotated[Vector3, doc("Size (diameter) of the sphere along each axis.", "m")]
    color: Annotated[Color, doc("Color of the sphere.")]


class CylinderPrimitive(Record, kw_only=True):
    TITLE = "foxglove.CylinderPrimitive"

    pose: Annotated[Pose, doc("Position of the center of the cylinder and orientation of the cylinder.")]
    size: Annotated[Vector3, doc("Size of the cylinder's bounding box.", "m")]
    bottom_scale: Annotated[float, doc("0-1, ratio of the diameter of the bottom face to size.x/size.y.")]
    top_scale: Annotated[float, doc("0-1, ratio of the diameter of the top face to size.x/size.y.")]
    color: Annotated[Color, doc("Color of the cylinder.")]


class LinePrimitive(Record, kw_only=True):
    TITLE = "foxglove.LinePrimitive"

    type: Annotated[
        int, doc("Drawing primitive: 0 line strip, 1 line loop, 2 line list.", schema=_enum(
            "foxglove.LineType", "LINE_STRIP", "LINE_LOOP", "LINE_LIST"
        ))
    ]  # fmt: skip
    pose: Annotated[Pose, doc("Origin of the lines relative to the reference frame.")]
    thickness: Annotated[float, doc("Line thickness (m, or pixels when scale_invariant).")]
    scale_invariant: Annotated[bool, doc("Thickness in pixels (true) or in metres (false).")]
    points: Annotated[list[Point3], doc("Points along the line.")]
    color: Annotated[Color, doc("Solid color of the whole line (used when colors is empty).")]
    colors: Annotated[list[Color], doc("Per-point colors (empty: color for every point).")]
    indices: Annotated[
        list[Annotated[int, msgspec.Meta(ge=0)]], doc("Indices into points (empty: in order).")
    ]


class TriangleListPrimitive(Record, kw_only=True):
    TITLE = "foxglove.TriangleListPrimitive"

    pose: Annotated[Pose, doc("Origin of the triangles relative to the reference frame.")]
    points: Annotated[list[Point3], doc("Vertices, three per triangle.")]
    color: Annotated[Color, doc("Solid color of the whole shape.")]
    colors: Annotated[list[Color], doc("Per-vertex colors.")]
    indices: Annotated[list[Annotated[int, msgspec.Meta(ge=0)]], doc("Indices into points.")]


class TextPrimitive(Record, kw_only=True):
    TITLE = "foxglove.TextPrimitive"

    pose: Annotated[Pose, doc("Position of the center of the text box and orientation of the text.")]
    billboard: Annotated[bool, doc("Always face the camera.")]
    font_size: Annotated[float, doc("Font size (height of one line of text).")]
    scale_invariant: Annotated[bool, doc("font_size in pixels (true) or in metres (false).")]
    color: Annotated[Color, doc("Color of the text.")]
    text: Annotated[str, doc("Text.")]


class ModelPrimitive(Record, kw_only=True):
    TITLE = "foxglove.ModelPrimitive"

    pose: Annotated[Pose, doc("Origin of the model relative to the reference frame.")]
    scale: Annotated[Vector3, doc("Scale factor to apply to the model along each axis.")]
    color: Annotated[Color, doc("Solid color of the model, if override_color.")]
    override_color: Annotated[bool, doc("Draw in color rather than the model's own.")]
    url: Annotated[str, doc("URL of the model file.")]
    media_type: Annotated[str, doc("Media type of the embedded model (e.g. model/gltf-binary).")]
    data: Annotated[bytes, doc("Embedded model (base64); empty when url is given.")]


class SceneEntity(Record, kw_only=True):
    TITLE = "foxglove.SceneEntity"

    timestamp: Annotated[Time, doc("Time of the entity (UTC).")]
    frame_id: Annotated[str, doc("Frame the entity is drawn in: `vessel` (hull, thrusters) or `ltp`.")]
    id: Annotated[str, doc("Entity id: a later entity with the same id replaces this one.")]
    lifetime: Annotated[Duration, doc("How long the entity shows; 0: until replaced or deleted.")]
    frame_locked: Annotated[bool, doc("Moves with its frame as the frame moves (true for the hull).")]
    metadata: Annotated[list[KeyValuePair], doc("Key/value pairs shown when the entity is selected.")]
    arrows: Annotated[list[ArrowPrimitive], doc("Arrows.")]
    cubes: Annotated[list[CubePrimitive], doc("Cubes.")]
    spheres: Annotated[list[SpherePrimitive], doc("Spheres.")]
    cylinders: Annotated[list[CylinderPrimitive], doc("Cylinders.")]
    lines: Annotated[list[LinePrimitive], doc("Lines.")]
    triangles: Annotated[list[TriangleListPrimitive], doc("Triangle lists.")]
    texts: Annotated[list[TextPrimitive], doc("Texts.")]
    models: Annotated[list[ModelPrimitive], doc("Models.")]


class SceneEntityDeletion(Record, kw_only=True):
    TITLE = "foxglove.SceneEntityDeletion"

    timestamp: Annotated[Time, doc("Entities created before this time are deleted.")]
    type: Annotated[
        int,
        doc("0: the entity with this id; 1: every entity.", schema=_enum(
            "foxglove.SceneEntityDeletionType", "MATCHING_ID", "ALL"
        )),
    ]  # fmt: skip
    id: Annotated[str, doc("Id of the entity to delete (type 0).")]


class SceneUpdate(Message, kw_only=True):
    """3D scene entities to add, replace or delete (Foxglove's 3D panel): hull, thrusters, setpoint."""

    TITLE = "foxglove.SceneUpdate"
    FOXGLOVE = True

    deletions: Annotated[list[SceneEntityDeletion], doc("Entities to delete.")]
    entities: Annotated[list[SceneEntity], doc("Entities to add or replace.")]


class Log(Message, kw_only=True):
    """A log line: an alarm raised or cleared, a reference's state change (Foxglove's Log panel)."""

    TITLE = "foxglove.Log"
    FOXGLOVE = True

    timestamp: Annotated[Time, doc("Time of the event (UTC).")]
    level: Annotated[
        int,
        doc("Severity: 0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal.", schema=_enum(
            "foxglove.LogLevel", "UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"
        )),
    ]  # fmt: skip
    message: Annotated[str, doc("The event, for a person.")]
    name: Annotated[str, doc("What raised it: `dpgw.alarm` or `dpgw.reference`.")]
    file: Annotated[str, doc("Always empty (a gateway event has no source file).")]
    line: Annotated[int, msgspec.Meta(ge=0), doc("Always 0.")]


class TruthState(Message, kw_only=True):
    """Simulator ground truth (MCAP `/truth/state`, simulator logs only)."""

    TITLE = "dpgw.TruthState"

    stamp_ns: Annotated[int, doc(TRUTH_STAMP, "ns (UTC)")]
    eta_lf: Annotated[Vec3, doc("True low-frequency " + ETA, "m, m, rad")]
    nu: Annotated[Vec3, doc("True low-frequency velocity " + NU, "m/s, m/s, rad/s")]
    bias: Annotated[Vec3, doc("True environmental force [X, Y, N], earth-fixed axes.", "N, N, N·m")]
    eta_wf: Annotated[
        Vec3,
        doc(
            "True wave-frequency motion [N, E, ψ] of the reference point (what the gyro sees; added to "
            "eta_lf, not subtracted).",
            "m, m, rad",
        ),
    ]
    omega0: Annotated[Vec3, doc("True wave peak frequency per DOF [N, E, ψ].", "rad/s")]
    tau: Annotated[Vec3 | None, doc("Generalised force acting from the thrusters " + TAU, "N, N, N·m")] = None
    hs_m: Annotated[float | None, doc("Significant wave height of the sea state.", "m")] = None
    wf_attitude: Annotated[
        Vec3 | None,
        doc(
            "True wave-frequency heave (down), roll (starboard down) and pitch (bow up) of the reference "
            "point: with eta_wf the vessel's six-degree-of-freedom wave motion.",
            "m, rad, rad",
        ),
    ] = None
    antennas: Annotated[
        dict[str, Vec3] | None,
        doc(
            "True NED position [N, E, D] of each position sensor's antenna, by source name: the reference "
            "point's LF + WF motion plus the lever arm turned by heading, roll and pitch (what the receiver "
            "measures, without its noise). D is down from the reference point's still-water height.",
            "m",
        ),
    ] = None


SIM_METADATA = "dpgw.sim"
"""MCAP metadata record a simulator writes into its log: ``scenario``, ``seed``, ``vessel`` and ``datum``
(JSON {lat_deg, lon_deg, alt_m}: the origin of the NED frame `/truth/state` is in, so that a replay of the
log puts its estimates in the same frame as the truth)."""

SIM_CLOCK_KEY = "sim/clock"
"""Under the Zenoh prefix: where a simulator publishes its time (`SimClock`)."""


class SimClock(Message, kw_only=True):
    """The simulator's time (Zenoh `<prefix>/sim/clock`; the ROS `/clock` convention): published before
    every burst of sensor data and at least every `period_s` of simulation time. A gateway with
    `[time] clock = "sim"` stamps what it receives with this time instead of its own clock."""

    TITLE = "dpgw.SimClock"

    stamp_ns: Annotated[int, doc("Simulation time now, as UTC nanoseconds since the Unix epoch.", "ns (UTC)")]
    period_s: Annotated[
        float, doc("Longest simulation time between two ticks (the next tick comes at most this later).", "s")
    ]
    speed: Annotated[
        float | None,
        doc(
            "Simulation seconds per wall second the simulator is paced at (left out: as fast as possible).",
            "",
        ),
    ] = None
    run: Annotated[
        int,
        doc(
            "This run of the plant: a random number from 1 to 2^53 - 1 drawn when the simulator starts "
            "(0: a simulator that does not say). A gateway follows one run: another run's ticks while its "
            "own still come are another simulator's clock on the same key, ignored and alarmed.",
            "",
        ),
    ] = 0


# --- raw inputs, logged exactly as received ---------------------------------------------------------


class RawNmea(Message, kw_only=True):
    """One NMEA 0183 sentence (or chunk of them) exactly as received, valid or not (MCAP
    `/raw/nmea/<source>`)."""

    TITLE = "dpgw.RawNmea"

    source: Annotated[str, doc("Source name from the configuration.")]
    text: Annotated[
        str,
        doc(
            "The sentence without its final CR LF. Non-ASCII bytes are shown as backslash escapes, and "
            "then `data` holds the exact bytes."
        ),
    ]
    data: Annotated[
        bytes | None,
        doc("Exact bytes (base64); only when they are not ASCII."),
    ] = None
    peer: Annotated[
        str,
        doc(
            "The sender (`host:port`) where one source hears several (UDP); each sender is framed on its "
            "own. Left out for a link with one sender."
        ),
    ] = ""
    unterminated: Annotated[
        bool,
        doc(
            "The chunk did not end with a line terminator (a sentence split across reads, as TCP and "
            "serial links deliver them); `text` is then exactly what came, and a replay frames it so. "
            "Left out (false) for a chunk of whole lines."
        ),
    ] = False
    eol: Annotated[
        str,
        doc(
            "The line terminator bytes that ended the chunk (stripped from `text` and `data`) when they were "
            "not exactly CR LF: a bare LF or CR, LF CR, several blank lines, a CR LF split across reads. "
            "Left out for CR LF and for an unterminated chunk, so `text` (or `data`) + `eol` (CR LF when "
            "left out, nothing when `unterminated`) is exactly the bytes received."
        ),
    ] = ""


class RawMavlink(Message, kw_only=True):
    """One MAVLink frame exactly as received, valid or not (MCAP `/raw/mavlink/<source>`)."""

    TITLE = "dpgw.RawMavlink"

    data: Annotated[bytes, doc("Frame bytes (base64).")]
    source: Annotated[str, doc("Source name from the configuration.")]

    # --- Zenoh inputs, logged so a replay sees them ---------------------------------------------------------
    peer: Annotated[
        str,
        doc("The sender (`host:port`) where one source hears several (UDP); left out otherwise."),
    ] = ""


class SigningRejection(Message, kw_only=True):
    """A MAVLink frame the gateway refused for its signature, on a source with a signing key (MCAP
    `/raw/mavlink_rejected/<source>`): the gateway's verdict, which a replay without the key (a log never
    holds it) applies to the same frame. Logged only for refused frames; accepted frames leave nothing."""

    TITLE = "dpgw.SigningRejection"

    stamp_ns: Annotated[
        int,
        doc(
            "Receive time of the chunk whose bytes completed the frame: the log time of that chunk's "
            "`/raw/mavlink/<source>` record. A frame held behind a false start completes only when its "
            "sender is forgotten (silent past the source's timeout, or its connection closed): then the "
            "time of the chunk or end of stream that forgot it, with that frame's own sender as `peer`.",
            "ns (UTC)",
        ),
    ]
    source: Annotated[str, doc("Source name from the configuration.")]
    reason: Annotated[
        Literal["bad_signature", "unsigned"],
        doc(
            "`bad_signature`: signed with another key, or a timestamp not newer than the stream's last (a "
            "replayed frame); `unsigned`: no signature on a link that requires one. Counted under the same "
            "reason in the source's `rejected`."
        ),
    ]
    offset: Annotated[
        int,
        doc(
            "Where the frame's first byte is in that chunk (bytes); negative when it began in an earlier "
            "chunk of the same sender (a frame split across reads; counted back from the end of what was "
            "held for a frame completed when its sender was forgotten)."
        ),
    ]
    digest: Annotated[
        str,
        doc("First 8 bytes of the frame's SHA-256 (16 hex digits): a replay checks it is the same frame."),
    ]
    system_id: Annotated[int, doc("The frame's system id (header).")]
    component_id: Annotated[int, doc("The frame's component id (header).")]
    seq: Annotated[int, doc("The frame's sequence number (header).")]
    msg_id: Annotated[int, doc("The frame's message id.")]
    link_id: Annotated[int | None, doc("Signing link id; left out for an unsigned frame.")] = None
    signature_timestamp: Annotated[
        int | None,
        doc("Signing timestamp, 10 µs units since 2015-01-01 UTC; left out for an unsigned frame."),
    ] = None
    peer: Annotated[
        str,
        doc("The sender (`host:port`) where one source hears several (UDP); left out otherwise."),
    ] = ""


class Setpoint(Message, kw_only=True):
    """Position/heading setpoint as received on Zenoh `<prefix>/setpoint` (logged so replay sees it):
    either north_m/east_m (local NED) or lat_deg/lon_deg, with heading_deg."""

    TITLE = "dpgw.Setpoint"

    north_m: Annotated[float | None, doc("North in the local NED frame.", "m")] = None
    east_m: Annotated[float | None, doc("East in the local NED frame.", "m")] = None
    lat_deg: Annotated[float | None, doc("Latitude (WGS-84).", "deg")] = None
    lon_deg: Annotated[float | None, doc("Longitude (WGS-84).", "deg")] = None
    heading_deg: Annotated[float, doc("Heading, clockwise from true north.", "deg")]


class ModeRequest(Message, kw_only=True):
    """Mode request as received on Zenoh `<prefix>/mode` (a bare JSON string there), wrapped as an
    object when logged."""

    TITLE = "dpgw.ModeRequest"

    mode: Annotated[Mode, doc("Requested mode.")]


class ManualTau(Message, kw_only=True):
    """Manual generalised force as received on Zenoh `<prefix>/tau` (body frame)."""

    TITLE = "dpgw.ManualTau"

    X: Annotated[float, doc("Surge force.", "N")]
    Y: Annotated[float, doc("Sway force.", "N")]
    N: Annotated[float, doc("Yaw moment.", "N·m")]


MALFORMED_INPUT_TOPIC = "/dp/input/malformed"


class MalformedInput(Message, kw_only=True):
    """A Zenoh input whose payload does not fit its own channel's schema (a mode "DP", a setpoint without
    its heading, a τ of strings, bytes that are no JSON), logged here as text so that every record on
    `/dp/mode`, `/dp/setpoint` and `/dp/tau` validates against its schema; a replay feeds it to the
    pipeline as the live gateway did, and it is refused the same way (`logged_input`)."""

    TITLE = "dpgw.MalformedInput"

    key: Annotated[str, doc("The input's key under the prefix: setpoint, mode or tau.")]
    payload: Annotated[
        str,
        doc('What was received, as JSON text (bytes that were no JSON: `{"invalid": "<the text>"}`).'),
    ]


class DeadReckoningTick(Message, kw_only=True):
    """A tick of the live gateway's clock at which it dead-reckoned: every position and heading source
    silent, the estimate predicted and, at the control rate, the thrusters commanded on it. Logged so that
    a replay ticks at the same times and reproduces what the live run commanded after it."""

    TITLE = "dpgw.DeadReckoningTick"

    silent_s: Annotated[float, doc("How long nothing had stepped the observer.", "s")]


class AnyObject(Message, kw_only=True):
    """Free-form JSON object (no schema registered for this topic)."""

    TITLE = "dpgw.Any"


# --- where each message goes ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Topic:
    """An MCAP topic (a pattern ending in `/` matches every topic under it) and the message on it.
    `zenoh`: the key under the prefix and its direction (`out`/`in`), when it is also on Zenoh."""

    pattern: str
    message: type[Message]
    content: str
    zenoh: tuple[str, str] | None = None


TOPICS: tuple[Topic, ...] = (
    Topic("/dp/estimate", Estimate, "the primary observer's estimate", ("estimate", "out")),
    Topic("/dp/measurement", Measurement, "the measurement the observer was given", ("measurement", "out")),
    Topic("/dp/thrusters/command", ThrusterCommand, "the allocation's command", ("thrusters/command", "out")),
    Topic(
        "/dp/thrusters/feedback",
        ThrusterFeedback,
        "thruster feedback (MAVLink)",
        ("thrusters/feedback", "out"),
    ),
    Topic("/dp/status", Status, "gateway health, at `status.rate_hz`", ("status", "out")),
    Topic(
        "/dp/setpoint", Setpoint, "the input as received (one that fits no schema: below)", ("setpoint", "in")
    ),
    Topic(
        "/dp/mode",
        ModeRequest,
        "the input, wrapped as `{mode}` (a bare JSON string on Zenoh)",
        ("mode", "in"),
    ),
    Topic("/dp/tau", ManualTau, "the input as received (one that fits no schema: below)", ("tau", "in")),
    Topic(
        MALFORMED_INPUT_TOPIC,
        MalformedInput,
        "an input whose payload does not fit its channel's schema, as text (a replay feeds it, refused as "
        "live)",
    ),
    Topic(
        "/dp/tick",
        DeadReckoningTick,
        "live only: a tick at which the gateway dead-reckoned (every position and heading source silent); "
        "a replay ticks there too",
    ),
    Topic(
        "/dp/estimates/",
        Estimate,
        "replay only: `/dp/estimates/<label>`, further observers run side by side (`--observer SPEC@label`); "
        "a paced replay (`--speed`) publishes them on Zenoh too, as `<prefix>/estimates/<label>`",
        ("estimates/<label>", "out"),
    ),
    Topic("/dp/estimate/fix", LocationFix, "the estimated position and heading, for the map (≤ ~5 Hz)"),
    Topic("/gnss/", LocationFix, "`/gnss/<source>/fix`: every GNSS fix, for the map"),
    Topic(
        "/dp/tf",
        FrameTransforms,
        "frames `ltp` (the datum's tangent plane, ENU) → `vessel` (LF estimate) and `vessel_measured`, "
        "with the estimate's pose",
    ),
    Topic(
        "/dp/estimate/pose",
        PoseInFrame,
        "the LF estimate's pose in `ltp`, at the estimate's rate up to ~5 Hz",
    ),
    Topic(
        "/dp/measurement/pose",
        PoseInFrame,
        "the measurement's pose in `ltp` with the estimate's, when N, E, ψ are all measured",
    ),
    Topic(
        "/dp/scene/",
        SceneUpdate,
        "`/dp/scene/hull` (every 10 s), `/dp/scene/thrusters` (commanded and fed-back arrows, ≤ 10 Hz), "
        "`/dp/scene/setpoint` (setpoint and watch circles, on change and every 10 s), for the 3D panel",
    ),
    Topic("/dp/log", Log, "alarms raised and cleared, reference state changes, for the Log panel"),
    Topic("/truth/state", TruthState, "simulator logs only: the ground truth"),
    Topic(
        "/sim/clock",
        SimClock,
        "the simulator's time, for gateways on `clock = \"sim\"` (Zenoh only: the chunks' stamps carry it)",
        (SIM_CLOCK_KEY, "in"),
    ),
    Topic("/raw/nmea/", RawNmea, "`/raw/nmea/<source>`: every NMEA chunk as received, valid or not"),
    Topic(
        "/raw/mavlink/", RawMavlink, "`/raw/mavlink/<source>`: every MAVLink frame as received, valid or not"
    ),
    Topic(
        "/raw/mavlink_rejected/",
        SigningRejection,
        "`/raw/mavlink_rejected/<source>`: each frame of a signed link refused for its signature (none for "
        "accepted frames), so that a replay without the key refuses the same ones",
    ),
)

MESSAGES: tuple[type[Message], ...] = tuple(dict.fromkeys(t.message for t in TOPICS))
"""Every message class on some topic, in the order of `TOPICS`, each once."""

ANY: type[Message] = AnyObject
"""The message of a topic nobody registered: any JSON object."""

_EXACT = {t.pattern: t.message for t in TOPICS if not t.pattern.endswith("/")}
_PREFIXES = sorted((t for t in TOPICS if t.pattern.endswith("/")), key=lambda t: -len(t.pattern))


_INPUT_MESSAGES: dict[str, type[Message]] = {"setpoint": Setpoint, "mode": ModeRequest, "tau": ManualTau}


def logged_input(key: str, payload: Any) -> tuple[str, dict[str, Any]]:
    """The channel and record a Zenoh input ``key`` with ``payload`` (as received: a JSON value, or the
    service's ``{"invalid": text}`` for bytes that were no JSON) is logged as: ``/dp/<key>`` as received
    (a mode wrapped as ``{mode}``; anything else that is no object too, or a replay, which unwraps
    ``{mode}``, would take ``{"mode": "dp"}`` that the live refused) when that fits the channel's schema,
    else `MALFORMED_INPUT_TOPIC` with the payload as JSON text. Before, a refused ``{"X": "big"}`` or
    ``{"setpoint": [1, 2, 3]}`` went on the typed channel and broke its schema for every reader that checks
    (Foxglove among them)."""
    wrap = key == "mode" or not isinstance(payload, dict)
    body = {key: payload} if wrap else payload
    message = _INPUT_MESSAGES.get(key)
    if message is None:  # (another /dp/ input: a dead-reckoning tick, logged by the gateway itself)
        return f"/dp/{key}", body
    try:
        json.dumps(body, allow_nan=False)  # (a non-finite number: JSON has none, the log would write null)
        msgspec.convert(body, message)
    except (msgspec.ValidationError, TypeError, ValueError):
        # Python's JSON text (Infinity, NaN: what json.loads took them from), read back as it was
        text = json.dumps(payload, ensure_ascii=False, default=repr)
        return MALFORMED_INPUT_TOPIC, {"key": key, "payload": text}
    return f"/dp/{key}", body


def input_from_log(topic: str, record: dict[str, Any]) -> tuple[str, Any]:
    """The key and payload of an input as `logged_input` logged it (the inverse): what a replay feeds."""
    if topic == MALFORMED_INPUT_TOPIC:
        return str(record["key"]), json.loads(record["payload"])
    key = topic[len("/dp/") :]
    return key, (record.get(key, record) if key == "mode" else record)


def message_for_topic(topic: str) -> type[Message]:
    """The message class of `topic`: exact match, else the longest matching prefix, else `ANY`."""
    exact = _EXACT.get(topic)
    if exact is not None:
        return exact
    for t in _PREFIXES:
        if topic.startswith(t.pattern) and len(topic) > len(t.pattern):
            return t.message
    return ANY
