"""The TOML file's shape: one pydantic model per table, each key with its type, range and unit.

pydantic (v2, strict: no "3" for 3, no true for 1) checks types and ranges and says where; this module
turns its findings into the config's own messages (``key.path: what is wrong (expected …, got …)``), with
the "expected" text each field declares, the value as the user wrote it, and "did you mean" for unknown
keys and values. A table is always read whole: a key with a problem becomes None and its problem is
listed, so the checks across keys (`gateway.config.load`) still run on the rest and every problem is
reported at once.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    ValidationError,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    field_validator,
)
from pydantic_core import PydanticCustomError

from gateway.config.defaults import DEFAULTS
from gateway.config.model import (
    ALLOCATORS,
    ATTITUDE_TIMES,
    CLOCKS,
    COMPRESSIONS,
    CONTROL_MODES,
    FEEDBACKS,
    OBSERVER_TYPES,
    POOLINGS,
    PROTOCOLS,
    ZENOH_MODES,
)
from gateway.config.problems import Problems, did_you_mean, kind, show
from observers.vessel import builtin_vessels

__all__ = [
    "MISSING",
    "CommandsTable",
    "ControlTable",
    "DatumTable",
    "FoxgloveTable",
    "IntegrityTable",
    "KeelsonTable",
    "LogTable",
    "ObserverTable",
    "Ros2Table",
    "SourceTable",
    "StatusTable",
    "TimeTable",
    "VesselTable",
    "ZenohTable",
    "read_table",
]


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


MISSING: Any = _Missing()
"""The default of a required key: validating it reports "missing (expected …)"."""


# --- field declarations: type, range, and the "expected …" text of every message ----------------------


def _fmt(x: float) -> str:
    return f"{x:g}"


def _range_text(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    if lo is not None and hi is not None and not lo_open and not hi_open:
        return f"from {_fmt(lo)} to {_fmt(hi)}"
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {_fmt(lo)}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {_fmt(hi)}")
    return " and ".join(parts)


def number(
    default: Any = MISSING,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
) -> Any:
    """A finite number (an integer is a number) in a range, with its unit in the message."""
    span = _range_text(lo, hi, lo_open, hi_open)
    expected = "a number" + (f" {span}" if span else "") + (f" {unit}" if unit else "")
    return Field(
        default,
        ge=None if lo_open else lo,
        gt=lo if lo_open else None,
        le=None if hi_open else hi,
        lt=hi if hi_open else None,
        allow_inf_nan=False,
        json_schema_extra={"expected": expected},
    )


def integer(default: Any = MISSING, *, lo: int | None = None, hi: int | None = None) -> Any:
    span = _range_text(lo, hi, False, False)
    return Field(
        default, ge=lo, le=hi, json_schema_extra={"expected": "an integer" + (f" {span}" if span else "")}
    )


def boolean(default: Any = MISSING) -> Any:
    return Field(default, json_schema_extra={"expected": "true or false"})


def text(default: Any = MISSING, expected: str = "a string") -> Any:
    return Field(default, json_schema_extra={"expected": expected})


def choice(default: Any, choices: Sequence[str]) -> Any:
    """One of a few strings; a near miss gets "did you mean"."""
    options = " or ".join(f'"{c}"' for c in choices) if len(choices) <= 2 else None
    expected = options or "one of " + ", ".join(f'"{c}"' for c in choices)
    return Field(default, json_schema_extra={"expected": expected, "choices": list(choices)})


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _vector(n: int) -> Callable[[Any], tuple[float, ...]]:
    def check(value: Any) -> tuple[float, ...]:
        if not isinstance(value, list | tuple) or len(value) != n or not all(_is_number(v) for v in value):
            raise PydanticCustomError("wrong_type", "wrong type")
        if not all(math.isfinite(v) for v in value):
            raise PydanticCustomError("not_finite", "not finite")
        return tuple(float(v) for v in value)

    return check


def vector(n: int, default: Any = MISSING, *, unit: str = "", names: str = "") -> Any:
    expected = f"an array of {n} numbers" + (f" {names}" if names else "") + (f" in {unit}" if unit else "")
    return Field(default, json_schema_extra={"expected": expected})


def _per_dof(
    allow_inf: bool, allow_zero: bool = False
) -> Callable[[Any], float | tuple[float, float, float]]:
    def check(value: Any) -> float | tuple[float, float, float]:
        items = value if isinstance(value, list) else [value]
        if (isinstance(value, list) and len(value) != 3) or not all(_is_number(v) for v in items):
            raise PydanticCustomError("wrong_type", "wrong type")
        xs = [float(v) for v in items]
        if not all(
            (math.isfinite(x) or (allow_inf and x == math.inf)) and (x > 0 or (allow_zero and x == 0))
            for x in xs
        ):
            raise PydanticCustomError("out_of_range", "out of range")
        return (xs[0], xs[1], xs[2]) if isinstance(value, list) else xs[0]

    return check


def per_dof(*, unit: str = "", allow_inf: bool = False, zero: str = "") -> Any:
    """A positive number for all three degrees of freedom, or an array [surge, sway, yaw]; ``zero`` (what 0
    means) allows 0 too."""
    limit = ("zero or positive" if zero else "positive") + (" (inf allowed)" if allow_inf else "")
    limit += f" ({zero})" if zero else ""
    expected = f"a {limit} number{' ' + unit if unit else ''}, or an array of 3 [surge, sway, yaw]"
    return Field(None, json_schema_extra={"expected": expected})


def _positive_or_inf(value: Any) -> float:
    if not _is_number(value):
        raise PydanticCustomError("wrong_type", "wrong type")
    x = float(value)
    if not x > 0:  # (NaN too)
        raise PydanticCustomError("out_of_range", "out of range")
    return x


def positive_or_inf(default: Any = MISSING, *, unit: str = "") -> Any:
    """A number > 0, or ``inf`` (meaning "never": say what in the key's docs)."""
    return Field(default, json_schema_extra={"expected": f"a number > 0{' ' + unit if unit else ''}, or inf"})


def _zero_positive_or_inf(value: Any) -> float | None:
    if value is None:  # (the default, derived from the tuning)
        return None
    if not _is_number(value):
        raise PydanticCustomError("wrong_type", "wrong type")
    x = float(value)
    if not x >= 0:  # (NaN too)
        raise PydanticCustomError("out_of_range", "out of range")
    return x


def zero_positive_or_inf(*, unit: str = "", zero: str, inf: str) -> Any:
    """A number ≥ 0 or ``inf``, default None (the key's derived default); ``zero`` and ``inf`` say what
    those mean."""
    expected = f"a number >= 0{' ' + unit if unit else ''} (0: {zero}), or inf ({inf})"
    return Field(None, json_schema_extra={"expected": expected})


Vector2 = Annotated[tuple[float, float], PlainValidator(_vector(2))]
Vector3 = Annotated[tuple[float, float, float], PlainValidator(_vector(3))]
PerDof = Annotated[float | tuple[float, float, float], PlainValidator(_per_dof(False))]
PerDofOrInf = Annotated[float | tuple[float, float, float], PlainValidator(_per_dof(True))]
PerDofOrZero = Annotated[float | tuple[float, float, float], PlainValidator(_per_dof(False, True))]
PositiveOrInf = Annotated[float, PlainValidator(_positive_or_inf)]
ZeroPositiveOrInfOrNone = Annotated[float | None, PlainValidator(_zero_positive_or_inf)]


def _table(value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise PydanticCustomError("wrong_type", "wrong type")
    return value


Table = Annotated[dict[str, Any], PlainValidator(_table)]


# --- reading a table -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Issue:
    key: str
    type: str
    value: Any


class _Section(BaseModel):
    """A config table: every key validated on its own; a key with a problem becomes None (`read_table`)."""

    model_config = ConfigDict(strict=True, extra="ignore", validate_default=True, frozen=True)
    section: ClassVar[str] = ""

    @field_validator("*", mode="wrap")
    @classmethod
    def _collect(cls, value: Any, handler: ValidatorFunctionWrapHandler, info: ValidationInfo) -> Any:
        issues: list[_Issue] = info.context["issues"] if info.context else []
        name = info.field_name or ""
        if value is MISSING:
            issues.append(_Issue(name, "missing", value))
            return None
        if value is None:  # an optional key not given
            return None
        try:
            result = handler(value)
        except ValidationError as exc:
            errors = exc.errors()
            at_key = [e for e in errors if not e["loc"]]
            first = (at_key or errors)[0]
            kind_ = first["type"]
            if kind_ == "finite_number" and first["loc"]:
                kind_ = "not_finite"  # an element of an array
            issues.append(_Issue(name, kind_, value))
            return None
        extra = cls.model_fields[name].json_schema_extra
        choices = extra.get("choices") if isinstance(extra, dict) else None
        if isinstance(choices, list) and result not in choices:
            issues.append(_Issue(name, "not_known", value))
            return None
        return result


_WRONG_RANGE = {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "out_of_range"}


def _message(issue: _Issue, expected: str, choices: Sequence[str] | None) -> str:
    v = issue.value
    if issue.type == "missing":
        return f"missing (expected {expected})"
    if issue.type in _WRONG_RANGE:
        return f"out of range (expected {expected}, got {show(v)})"
    if issue.type == "finite_number":
        return f"not a finite number (expected {expected}, got {show(v)})"
    if issue.type == "not_finite":
        return f"not finite (expected {expected}, got {show(v)})"
    if issue.type == "not_known" and isinstance(v, str):
        hint = did_you_mean(v, choices or (), quote='"')
        return f"not a known value{hint} (expected {expected}, got {show(v)})"
    return f"wrong type (expected {expected}, got {kind(v)} {show(v)})"


def read_table(
    model: type[_Section],
    table: Mapping[str, Any],
    path: str,
    problems: Problems,
    *,
    expected: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """Every key of ``model`` read from ``table`` (defaults filled in); a key with a problem is None.

    Problems go to ``problems`` as ``path.key: …``: unknown keys first (with "did you mean"), then each
    key's in the order the model declares them. ``expected`` overrides a key's "expected …" text where
    it depends on other keys (the roles a protocol allows).
    """
    known = list(model.model_fields)
    problems.unknown_keys(table, path, known)
    issues: list[_Issue] = []
    values = {k: table[k] for k in known if k in table}
    instance = model.model_validate(values, context={"issues": issues})
    for issue in issues:
        extra = model.model_fields[issue.key].json_schema_extra
        info = extra if isinstance(extra, dict) else {}
        exp = (expected or {}).get(issue.key) or str(info.get("expected", "a value"))
        written = info.get("choices")
        choices = [str(c) for c in written] if isinstance(written, list) else None
        problems.add(f"{path}.{issue.key}", _message(issue, exp, choices))
    return {k: getattr(instance, k) for k in known}


# --- the tables ------------------------------------------------------------------------------------------

_BUILTINS = ", ".join(builtin_vessels())


class VesselTable(_Section):
    """``[vessel]``: a built-in vessel or a vessel file, and the reference point of the estimates."""

    name: str = text(None, f"a built-in vessel name ({_BUILTINS})")
    file: str = text(None, "a vessel TOML file path (relative to the config file)")
    reference_point_m: Vector2 = vector(2, DEFAULTS["vessel"]["reference_point_m"], unit="m", names="[x, y]")


class DatumTable(_Section):
    """``[datum]``: the local NED origin, fixed or the first valid fix."""

    lat_deg: float = number(None, lo=-90.0, hi=90.0, unit="degrees")
    lon_deg: float = number(None, lo=-180.0, hi=180.0, unit="degrees")
    alt_m: float = number(DEFAULTS["datum"]["alt_m"], lo=-1000.0, hi=10000.0, unit="m")
    first_fix: bool = boolean(DEFAULTS["datum"]["first_fix"])


_SRC = DEFAULTS["source"]


class SourceTable(_Section):
    """One ``[[sources]]`` entry."""

    name: str = text(expected='a name of lowercase letters, digits and _ (e.g. "dgps1")')
    url: str = text(expected="a URL, e.g. serial:///dev/ttyUSB0?baud=4800")
    protocol: str = choice(MISSING, PROTOCOLS)
    roles: list[str] = text(expected="an array of roles")
    lever_arm_m: Vector3 = vector(
        3, _SRC["lever_arm_m"], unit="m", names="[x fwd, y stbd, z down] of the antenna"
    )
    timeout_s: float = number(_SRC["timeout_s"], lo=0.0, hi=600.0, lo_open=True, unit="s")
    allow_missing_checksum: bool = boolean(_SRC["allow_missing_checksum"])
    tag_source: str = text(None, 'the sending device a TAG block names (s:), e.g. "GP0001"')
    priority: int = integer(_SRC["priority"], lo=0)
    system_id: int = integer(None, lo=1, hi=255)
    component_id: int = integer(None, lo=1, hi=255)
    signing_key: str = text(None, "64 hexadecimal characters (32 bytes)")
    allow_unsigned: bool = boolean(_SRC["allow_unsigned"])
    ardupilot: Table = text(None, "an [ardupilot] table")
    commands: bool = boolean(False)


_OBS = DEFAULTS["observer"]
TUNING_KEYS = (
    "zeta",
    "zeta_n",
    "cutoff_ratio",
    "omega_c",
    "bias_time_constant_s",
    "velocity_injection",
    "velocity_injection_ratio",
    "injection_damping_ratio",
    "bias_corner_ratio",
    "bias_corner",
)


class ObserverTable(_Section):
    """``[observer]``: type, the passive tuning in physical terms (wave period, ratios), rate, params."""

    type: str = choice(_OBS["type"], OBSERVER_TYPES)
    wave_period_s: PerDof = per_dof(unit="s")
    omega0: PerDof = per_dof(unit="rad/s")
    zeta: PerDof = per_dof()
    zeta_n: PerDof = per_dof()
    cutoff_ratio: PerDof = per_dof()
    omega_c: PerDof = per_dof()
    bias_time_constant_s: PerDofOrInf = per_dof(allow_inf=True)
    velocity_injection: PerDof = per_dof()
    velocity_injection_ratio: PerDof = per_dof()
    # 0 turns the damping floor off, as in `PassiveTuning` and `dpgw tune --injection-damping-ratio 0`
    injection_damping_ratio: PerDofOrZero = per_dof(zero="0 = no floor")
    bias_corner_ratio: PerDof = per_dof()
    bias_corner: PerDof = per_dof()
    allow_unchecked: bool = boolean(_OBS["allow_unchecked"])
    rate_hz: float = number(_OBS["rate_hz"], lo=1.0, hi=50.0, unit="Hz")
    params: Table = text(None, "a table")


_Z = DEFAULTS["zenoh"]
_ENDPOINTS = 'an array of endpoints like "tcp/192.168.1.10:7447"'


class ZenohTable(_Section):
    """``[zenoh]``: the session (peer or client, endpoints or a Zenoh config file) and the key prefix."""

    mode: str = choice(_Z["mode"], ZENOH_MODES)
    connect: list[str] = text(_Z["connect"], _ENDPOINTS)
    listen: list[str] = text(_Z["listen"], _ENDPOINTS)
    config_file: str = text(_Z["config_file"], "a Zenoh JSON5 config file path")
    prefix: str = text(_Z["prefix"], 'a key expression such as "dp/my_ship"')
    multicast_scouting: bool = boolean(_Z["multicast_scouting"])
    users_file: str = text(_Z["users_file"], "a Zenoh user:password dictionary file path")
    user: str = text(_Z["user"], "a Zenoh user name")
    password_file: str = text(_Z["password_file"], "a file holding this session's Zenoh password")
    commanders: list[str] = text(_Z["commanders"], 'an array of user names, e.g. ["bridge"]')


_L = DEFAULTS["log"]


class LogTable(_Section):
    """``[log]``: the MCAP file, its rotation, flushing and compression."""

    path: str = text(_L["path"], 'an .mcap file path, or "" to disable logging')
    rotate_mb: float = number(_L["rotate_mb"], lo=0.0, unit="MiB (0 = never)")
    rotate_minutes: float = number(_L["rotate_minutes"], lo=0.0, unit="minutes (0 = never)")
    flush_interval_s: float = number(_L["flush_interval_s"], lo=0.0, hi=60.0, lo_open=True, unit="s")
    compression: str = choice(_L["compression"], COMPRESSIONS)


class StatusTable(_Section):
    """``[status]``: how often the status is published."""

    rate_hz: float = number(DEFAULTS["status"]["rate_hz"], lo=0.1, hi=10.0, unit="Hz")


class TimeTable(_Section):
    """``[time]``: the clock received data is stamped with (wall, or a simulator's on Zenoh)."""

    clock: str = choice(DEFAULTS["time"]["clock"], CLOCKS)


_C = DEFAULTS["control"]


class ControlTable(_Section):
    """``[control]``: the DP controller and thrust allocation."""

    rate_hz: float = number(_C["rate_hz"], lo=1.0, hi=50.0, unit="Hz")
    initial_mode: str = choice(_C["initial_mode"], CONTROL_MODES)
    wait_for_observer: bool = boolean(_C["wait_for_observer"])
    allocator: str = choice(_C["allocator"], ALLOCATORS)
    bandwidth_rad_s: PerDof = per_dof(unit="rad/s")
    damping: float = number(_C["damping"], lo=0.3, hi=3.0)
    feedback: str = choice(_C["feedback"], FEEDBACKS)
    return_speed_mps: float | None = number(None, lo=0.0, lo_open=True, unit="m/s")
    wind_feedforward_gain: float = number(_C["wind_feedforward_gain"], lo=0.0, hi=1.0)
    wind_filter_s: float = number(_C["wind_filter_s"], lo=0.0, hi=120.0, lo_open=True, unit="s")
    wind_loss_fade_s: float | None = number(None, lo=0.0, hi=3600.0, unit="s (0 = drop at once)")
    takeover_fade_s: ZeroPositiveOrInfOrNone = zero_positive_or_inf(
        unit="s",
        zero="at once",
        inf="never: the integrator keeps the τ held before, the rule before the fade",
    )


_Q = DEFAULTS["consequence"]


class ConsequenceTable(_Section):
    """``[consequence]``: the online consequence analysis (worst-case failure) in DP."""

    enabled: bool = boolean(_Q["enabled"])
    failure_groups: list[list[int]] = Field(
        _Q["failure_groups"],
        json_schema_extra={
            "expected": "an array of arrays of thruster ids lost together, e.g. [[1, 2], [3, 4]] "
            "([]: each thruster alone)"
        },
    )
    filter_s: float = number(_Q["filter_s"], lo=1.0, hi=600.0, unit="s")


_I = DEFAULTS["integrity"]


def _positive(key: str, unit: str, hi: float | None = None) -> Any:
    return number(_I[key], lo=0.0, hi=hi, lo_open=True, unit=unit)


class IntegrityTable(_Section):
    """``[integrity]``: the reference and feedback tests (docs/integrity.md)."""

    gga_quality: list[int] = Field(
        _I["gga_quality"], json_schema_extra={"expected": "an array of GGA quality codes from 1 to 9"}
    )
    pooling: str = choice(_I["pooling"], POOLINGS)
    readmit_s: float = number(_I["readmit_s"], lo=0.0, hi=3600.0, unit="s")
    max_speed_m_s: float = _positive("max_speed_m_s", "m/s")
    jump_m: float = _positive("jump_m", "m")
    max_rate_deg_s: float = _positive("max_rate_deg_s", "deg/s")
    heading_jump_deg: float = _positive("heading_jump_deg", "deg", 180.0)
    freeze_s: float = _positive("freeze_s", "s")
    heading_freeze_s: float = _positive("heading_freeze_s", "s")
    heading_freeze_min_s: float = _positive("heading_freeze_min_s", "s")
    max_sigma_m: float = _positive("max_sigma_m", "m")
    prediction_gate_m: float = _positive("prediction_gate_m", "m")
    prediction_gate_deg: float = _positive("prediction_gate_deg", "deg", 180.0)
    prediction_max_age_s: float = number(
        _I["prediction_max_age_s"], lo=0.0, unit="s (0 = no prediction test)"
    )
    median_m: float = _positive("median_m", "m")
    divergence_m: float = _positive("divergence_m", "m")
    heading_median_deg: float = _positive("heading_median_deg", "deg", 180.0)
    heading_divergence_deg: float = _positive("heading_divergence_deg", "deg", 180.0)
    smoothing_s: float = _positive("smoothing_s", "s", 600.0)
    min_sigma_m: float = _positive("min_sigma_m", "m")
    lost_after_s: float = _positive("lost_after_s", "s")
    restart_confirm_s: float = number(_I["restart_confirm_s"], lo=0.0, hi=600.0, unit="s")
    dead_reckoning_rate_hz: float = number(_I["dead_reckoning_rate_hz"], lo=0.1, hi=100.0, unit="Hz")
    thrust_margin: float = number(_I["thrust_margin"], lo=1.0, hi=10.0)
    feedback_rejects: int = integer(_I["feedback_rejects"], lo=1)
    attitude_max_deg: float = _positive("attitude_max_deg", "deg", 90.0)
    attitude_max_rate_deg_s: float = _positive("attitude_max_rate_deg_s", "deg/s")
    attitude_jump_deg: float = _positive("attitude_jump_deg", "deg", 180.0)
    attitude_freeze_s: float = _positive("attitude_freeze_s", "s")
    attitude_freeze_max_s: float = _positive("attitude_freeze_max_s", "s")
    attitude_max_sigma_deg: float = _positive("attitude_max_sigma_deg", "deg", 90.0)
    attitude_rejects: int = integer(_I["attitude_rejects"], lo=1)
    attitude_time: str = choice(_I["attitude_time"], ATTITUDE_TIMES)


_CMD = DEFAULTS["commands"]


class CommandsTable(_Section):
    """``[commands]``: which Zenoh command inputs are taken, the setpoint's distance limit, and the manual
    τ's hold time."""

    accept: list[str] = text(_CMD["accept"], 'an array of inputs from "mode", "setpoint", "tau"')
    max_setpoint_distance_m: float = number(
        _CMD["max_setpoint_distance_m"], lo=0.0, hi=10000.0, lo_open=True, unit="m"
    )
    manual_tau_hold_s: PositiveOrInf = positive_or_inf(_CMD["manual_tau_hold_s"], unit="s")


_K = DEFAULTS["keelson"]
_SOURCE_ID = 'key chunks in snake_case joined by "/", e.g. "dpgw/estimate"'


class KeelsonTable(_Section):
    """``[keelson]``: Keelson's key space on the gateway's Zenoh session (docs/keelson.md)."""

    enabled: bool = boolean(_K["enabled"])
    base_path: str = text(_K["base_path"], 'key chunks in snake_case joined by "/", e.g. "keelson"')
    entity_id: str = text(_K["entity_id"], 'one key chunk in snake_case naming the vessel, e.g. "my_ship"')
    estimate_source_id: str = text(_K["estimate_source_id"], _SOURCE_ID)
    measurement_source_id: str = text(_K["measurement_source_id"], _SOURCE_ID)
    sensor_source_id: str = text(
        _K["sensor_source_id"],
        'key chunks in snake_case joined by "/" holding "{source}", e.g. "dpgw/sensor/{source}"',
    )
    demand_source_id: str = text(_K["demand_source_id"], _SOURCE_ID)
    allocated_source_id: str = text(_K["allocated_source_id"], _SOURCE_ID)
    feedback_source_id: str = text(_K["feedback_source_id"], _SOURCE_ID)
    log_source_id: str = text(_K["log_source_id"], _SOURCE_ID)


_R = DEFAULTS["ros2"]
_TOPIC = 'a ROS 2 topic name, relative to the namespace (e.g. "odom") or absolute (e.g. "/odom")'
_FRAME = 'a frame id: letters, digits, "_", "/" (e.g. "map")'


class Ros2Table(_Section):
    """``[ros2]``: ROS 2 topics in rmw_zenoh's format on the gateway's Zenoh session (docs/ros2.md)."""

    enabled: bool = boolean(_R["enabled"])
    domain_id: int = integer(_R["domain_id"], lo=0, hi=232)
    namespace: str = text(_R["namespace"], 'an absolute ROS 2 namespace, e.g. "/dpgw" (or "/")')
    node_name: str = text(_R["node_name"], 'a ROS 2 node name: letters, digits, "_", e.g. "dpgw"')
    frame_id: str = text(_R["frame_id"], _FRAME)
    child_frame_id: str = text(_R["child_frame_id"], _FRAME)
    publish_tf: bool = boolean(_R["publish_tf"])
    odom_topic: str = text(_R["odom_topic"], _TOPIC)
    pose_topic: str = text(_R["pose_topic"], _TOPIC)
    fix_topic: str = text(_R["fix_topic"], _TOPIC)
    setpoint_topic: str = text(_R["setpoint_topic"], _TOPIC)


_F = DEFAULTS["foxglove"]


class FoxgloveTable(_Section):
    """``[foxglove]``: the live Foxglove WebSocket server (docs/foxglove.md)."""

    enabled: bool = boolean(_F["enabled"])
    host: str = text(
        _F["host"],
        'an IP address or host name to listen on, e.g. "127.0.0.1" (this computer only) or "0.0.0.0" '
        "(every interface)",
    )
    port: int = integer(_F["port"], lo=0, hi=65535)
