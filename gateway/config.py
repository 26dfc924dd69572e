"""The gateway's TOML configuration (``dpgw run --config FILE``): read, check, and turn into typed values.

One file per vessel or bench (``docs/config.md`` lists every key; ``examples/`` has working files).
Loading either returns a complete, validated, frozen `GatewayConfig` or raises one `ConfigError` whose
message lists **every** problem found, each as ``FILE: key.path: what is wrong (expected …, got …)``.
Unknown keys are errors with a "did you mean" suggestion, so a typo is never silently ignored.

Loading reads the config file, a vessel file and a Zenoh config file if named; it opens no device, port,
socket or log: source URLs are checked for syntax (here, then by `gateway.sources.open_source`, which
validates without opening), and are opened by the sources at start-up.
Relative paths (``vessel.file``, ``log.path``, ``zenoh.config_file``, ``file:`` source URLs) are resolved
against the folder of the config file.

``python -m gateway.config FILE`` checks a file and prints a summary or the problems (exit status 1).
"""

from __future__ import annotations

import difflib
import json
import math
import re
import sys
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl, quote, unquote, urlsplit

from observers.factory import OBSERVER_TYPES as _OBSERVER_TYPES
from observers.factory import ObserverSpecError, check_params
from observers.passive_tuning import (
    Check,
    PassiveTuning,
    TuningError,
    check_gains,
    passive_gains,
)
from observers.vessel import VesselError, VesselModel, builtin_vessels, load_vessel

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "BAUD_RATES",
    "COMPRESSIONS",
    "OBSERVER_TYPES",
    "PROTOCOLS",
    "ROLES",
    "ArdupilotMap",
    "ConfigError",
    "DatumConfig",
    "GatewayConfig",
    "LogConfig",
    "ObserverConfig",
    "SourceConfig",
    "StatusConfig",
    "ZenohConfig",
    "default_config",
    "describe",
    "format_problems",
    "load_config",
    "main",
    "parse_config",
]

PROTOCOLS = ("nmea", "mavlink")
ROLES: dict[str, tuple[str, ...]] = {
    "nmea": ("position", "heading"),
    "mavlink": ("thrusters", "position", "heading"),
}
"""The roles a source of each protocol can have."""
OBSERVER_TYPES = _OBSERVER_TYPES  # passive, gain_scheduled, mmae (observers.factory)
COMPRESSIONS = ("zstd", "lz4", "none")
ZENOH_MODES = ("peer", "client")
URL_SCHEMES = ("serial", "pty", "udp", "tcp", "tcp-listen", "file")
"""Transports of the gateway's own URLs (``scheme://...``, `gateway.sources`)."""
PYMAVLINK_PREFIXES = ("udpin", "udpout", "udp", "tcp", "tcpin")
"""pymavlink strings ``prefix:HOST:PORT``; serial ``/dev/ttyX[,BAUD]`` or ``serial:/dev/ttyX[:BAUD]``."""
BAUD_RATES = (
    300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000,
    921600, 1000000, 1152000, 1500000, 2000000, 2500000, 3000000, 3500000, 4000000,
)  # fmt: skip
ZENOH_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial", "vsock")
SOURCE_NAME = re.compile(r"[a-z0-9_]+")
SIGNING_KEY = re.compile(r"[0-9a-fA-F]{64}")
MAX_ARDUPILOT_INDEX = 32
"""ESC indices (ESC_TELEMETRY_1_TO_4 … 29_TO_32) and servo output channels (SERVO_OUTPUT_RAW) are 1–32."""
MIB = 1024 * 1024

# --- the embedded defaults (one place: the parser and default_config() both read it) -------------------

_DEFAULT_TUNING = PassiveTuning()
_DEFAULTS: dict[str, dict[str, Any]] = {
    "vessel": {"reference_point_m": [0.0, 0.0]},
    "datum": {"alt_m": 0.0, "first_fix": False},
    "source": {
        "lever_arm_m": [0.0, 0.0, 0.0],
        "timeout_s": 2.0,
        "allow_missing_checksum": False,
        "priority": 1,
        "allow_unsigned": False,
    },
    "observer": {
        "type": "passive",
        "wave_period_s": 7.0,
        "zeta": _DEFAULT_TUNING.zeta,
        "zeta_n": _DEFAULT_TUNING.zeta_n,
        "cutoff_ratio": _DEFAULT_TUNING.cutoff_ratio,
        "bias_time_constant_s": _DEFAULT_TUNING.bias_time_constant_s,
        "velocity_injection_ratio": _DEFAULT_TUNING.velocity_injection_ratio,
        "bias_corner_ratio": _DEFAULT_TUNING.bias_corner_ratio,
        "allow_unchecked": False,
        "rate_hz": 10.0,
    },
    "zenoh": {
        "mode": "peer",
        "connect": [],
        "listen": [],
        "config_file": "",
        "prefix": "",
        "multicast_scouting": True,
    },
    "log": {
        "path": "logs/dpgw.mcap",
        "rotate_mb": 1024,
        "rotate_minutes": 60,
        "flush_interval_s": 1.0,
        "compression": "zstd",
    },
    "status": {"rate_hz": 1.0},
    "control": {
        "rate_hz": 10.0,
        "initial_mode": "standby",
        "allocator": "qp",
        "damping": 1.0,
        "feedback": "estimate",
    },
}

_TOP_KEYS = ("vessel", "datum", "sources", "observer", "zenoh", "log", "status", "control")
_VESSEL_KEYS = ("name", "file", "reference_point_m")
_DATUM_KEYS = ("lat_deg", "lon_deg", "alt_m", "first_fix")
_SOURCE_KEYS = (
    "name",
    "url",
    "protocol",
    "roles",
    "lever_arm_m",
    "timeout_s",
    "allow_missing_checksum",
    "priority",
    "system_id",
    "signing_key",
    "allow_unsigned",
    "ardupilot",
    "commands",
)
_MAVLINK_ONLY = ("system_id", "signing_key", "allow_unsigned", "ardupilot", "commands")
_TUNING_KEYS = (
    "zeta",
    "zeta_n",
    "cutoff_ratio",
    "omega_c",
    "bias_time_constant_s",
    "velocity_injection",
    "velocity_injection_ratio",
    "bias_corner_ratio",
    "bias_corner",
)
_OBSERVER_KEYS = ("type", "wave_period_s", "omega0", *_TUNING_KEYS, "allow_unchecked", "rate_hz", "params")
_ZENOH_KEYS = tuple(_DEFAULTS["zenoh"])
_LOG_KEYS = tuple(_DEFAULTS["log"])
_STATUS_KEYS = tuple(_DEFAULTS["status"])
_CONTROL_KEYS = (*_DEFAULTS["control"], "bandwidth_rad_s")
CONTROL_MODES = ("standby", "dp", "manual")
ALLOCATORS = ("qp", "pseudo_inverse")
FEEDBACKS = ("estimate", "measurement")


def default_config(vessel: str = "mss_supply") -> dict[str, Any]:
    """The embedded defaults as a config dict (what `dpgw demo` starts from); ``sources`` is left empty.

    ``vessel`` is a built-in vessel name or a vessel file path. Fill in ``sources`` and pass the dict to
    `parse_config`.
    """
    vessel_table: dict[str, Any] = {"name": vessel} if vessel in builtin_vessels() else {"file": vessel}
    vessel_table.update(_copy(_DEFAULTS["vessel"]))
    return {
        "vessel": vessel_table,
        "datum": {"first_fix": True},
        "sources": [],
        "observer": _copy(_DEFAULTS["observer"]),
        "zenoh": _copy(_DEFAULTS["zenoh"]),
        "log": _copy(_DEFAULTS["log"]),
        "status": _copy(_DEFAULTS["status"]),
    }


def _copy(table: dict[str, Any]) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, list) else v for k, v in table.items()}


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
    """ArduPilot feedback → thrusters: ESC index → thruster id (rpm), servo channel → thruster (azimuth)."""

    esc: Mapping[int, int] = field(default_factory=dict)
    servo: Mapping[int, int] = field(default_factory=dict)


@dataclass(frozen=True)
class SourceConfig:
    """One ``[[sources]]`` entry.

    ``transport`` is the kind of link the URL names: ``serial``, ``udp``, ``tcp``, ``tcp-listen``, ``file``
    (the gateway's URLs) or ``pymavlink`` (a pymavlink connection string, MAVLink only). ``url`` is as
    written, except that a relative ``file:`` path is made absolute (``file:///...``).
    ``system_id`` None accepts any MAVLink system. ``signing_key`` is the 32-byte MAVLink 2 signing secret.
    """

    name: str
    url: str
    protocol: str
    roles: tuple[str, ...]
    transport: str
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    timeout_s: float = 2.0
    allow_missing_checksum: bool = False
    priority: int = 1
    system_id: int | None = None
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
    """The Zenoh session; ``prefix`` is resolved (default ``dp/<vessel name>``)."""

    prefix: str
    mode: str = "peer"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    config_file: Path | None = None
    multicast_scouting: bool = True

    def make(self) -> zenoh.Config:
        """The `zenoh.Config` for this session (`gateway.bus.make_config`); opens nothing."""
        from gateway.bus import make_config

        return make_config(
            mode=self.mode,
            connect=self.connect,
            listen=self.listen,
            multicast_scouting=self.multicast_scouting,
            config_file=self.config_file,
        )


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
    """The DP controller and thrust allocation (issue 5): control rate on the event clock (Hz), the mode at
    start, the allocator, and the controller's closed-loop bandwidth (rad/s; None = the vessel's
    Froude-scaled default) and damping."""

    rate_hz: float = 10.0
    initial_mode: str = "standby"
    allocator: str = "qp"
    bandwidth_rad_s: float | tuple[float, float, float] | None = None
    damping: float = 1.0
    feedback: str = "estimate"
    """What the controller's position/heading term sees: the observer's LF estimate (always, at sea), or
    the raw measurement — only to demonstrate what wave filtering buys (the same controller, same ν̂)."""


@dataclass(frozen=True)
class StatusConfig:
    """How often ``<prefix>/status`` is published (Hz)."""

    rate_hz: float = 1.0


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

    def sources_for(self, role: str) -> tuple[SourceConfig, ...]:
        """The sources with ``role``, in failover order (lowest priority first)."""
        return tuple(sorted((s for s in self.sources if role in s.roles), key=lambda s: s.priority))

    def source(self, name: str) -> SourceConfig:
        for s in self.sources:
            if s.name == name:
                return s
        raise KeyError(name)


# --- errors ---------------------------------------------------------------------------------------------


class ConfigError(ValueError):
    """A configuration that cannot be used. ``problems``: every problem found, one line each."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems: list[str] = list(problems)
        n = len(self.problems)
        head = "invalid configuration" + (f" ({n} problems)" if n != 1 else "")
        super().__init__(head + ":\n" + "\n".join(f"  {p}" for p in self.problems))


def format_problems(error: ConfigError | Sequence[str]) -> str:
    """One message for a person: every problem on its own line, and that nothing was started."""
    problems = error.problems if isinstance(error, ConfigError) else list(error)
    n = len(problems)
    lines = [f"dpgw: the configuration has {n} problem{'s' if n != 1 else ''}; nothing was started:"]
    lines += [f"  {p}" for p in problems]
    lines.append("Every key is described in docs/config.md; examples/ has working files.")
    return "\n".join(lines)


# --- reading values -------------------------------------------------------------------------------------

_MISSING: Any = object()


def _show(value: Any) -> str:
    """A value as it is written in TOML (what the user wrote), for "got …"."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value == math.inf else repr(value))
    if isinstance(value, dict):
        return "a table" if not value else "a table {" + ", ".join(list(value)[:4]) + "}"
    if isinstance(value, list):
        text = "[" + ", ".join(_show(v) for v in value[:6]) + (", …]" if len(value) > 6 else "]")
        return text
    return str(value)


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


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


class _Reader:
    """Collects problems (``FILE: key.path: message``) while reading typed values out of tables."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.problems: list[str] = []

    def problem(self, key: str, message: str) -> None:
        self.problems.append(f"{self.where}: {key}: {message}")

    # tables

    def table(self, data: Mapping[str, Any], key: str, path: str, *, required: bool = False) -> dict | None:
        value = data.get(key, _MISSING)
        if value is _MISSING:
            if required:
                self.problem(path, f"missing (expected a [{path}] table)")
            return None
        if not isinstance(value, dict):
            self.problem(path, f"wrong type (expected a [{path}] table, got {_kind(value)} {_show(value)})")
            return None
        return value

    def known(self, table: Mapping[str, Any], path: str, known: Sequence[str]) -> None:
        for key in table:
            if key in known:
                continue
            close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
            hint = f", did you mean '{close[0]}'?" if close else ""
            prefix = f"{path}." if path else ""
            self.problem(f"{prefix}{key}", f"unknown key{hint} (expected one of: {', '.join(known)})")

    # scalars

    def number(
        self,
        table: Mapping[str, Any],
        key: str,
        path: str,
        default: Any = _MISSING,
        *,
        lo: float | None = None,
        hi: float | None = None,
        lo_open: bool = False,
        hi_open: bool = False,
        unit: str = "",
        allow_inf: bool = False,
        what: str = "a number",
    ) -> float | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        range_text = _range_text(lo, hi, lo_open, hi_open)
        expected = what + (f" {range_text}" if range_text else "") + (f" {unit}" if unit else "")
        if value is _MISSING:
            self.problem(name, f"missing (expected {expected})")
            return None
        if value is None:
            return None
        if not _is_number(value):
            self.problem(name, f"wrong type (expected {expected}, got {_kind(value)} {_show(value)})")
            return None
        x = float(value)
        if math.isnan(x) or (math.isinf(x) and not (allow_inf and x > 0)):
            self.problem(name, f"not a finite number (expected {expected}, got {_show(value)})")
            return None
        bad = (
            (lo is not None and (x <= lo if lo_open else x < lo))
            or (hi is not None and (x >= hi if hi_open else x > hi))
        )  # fmt: skip
        if bad:
            self.problem(name, f"out of range (expected {expected}, got {_show(value)})")
            return None
        return x

    def integer(
        self,
        table: Mapping[str, Any],
        key: str,
        path: str,
        default: Any = _MISSING,
        *,
        lo: int | None = None,
        hi: int | None = None,
    ) -> int | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        range_text = _range_text(lo, hi, False, False)
        expected = "an integer" + (f" {range_text}" if range_text else "")
        if value is _MISSING:
            self.problem(name, f"missing (expected {expected})")
            return None
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            self.problem(name, f"wrong type (expected {expected}, got {_kind(value)} {_show(value)})")
            return None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            self.problem(name, f"out of range (expected {expected}, got {value})")
            return None
        return value

    def boolean(self, table: Mapping[str, Any], key: str, path: str, default: Any = _MISSING) -> bool | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        if value is _MISSING:
            self.problem(name, "missing (expected true or false)")
            return None
        if not isinstance(value, bool):
            self.problem(name, f"wrong type (expected true or false, got {_kind(value)} {_show(value)})")
            return None
        return value

    def string(
        self, table: Mapping[str, Any], key: str, path: str, default: Any = _MISSING, *, expected: str = ""
    ) -> str | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        exp = expected or "a string"
        if value is _MISSING:
            self.problem(name, f"missing (expected {exp})")
            return None
        if value is None:
            return None
        if not isinstance(value, str):
            self.problem(name, f"wrong type (expected {exp}, got {_kind(value)} {_show(value)})")
            return None
        return value

    def choice(
        self, table: Mapping[str, Any], key: str, path: str, choices: Sequence[str], default: Any = _MISSING
    ) -> str | None:
        options = " or ".join(f'"{c}"' for c in choices) if len(choices) <= 2 else None
        exp = options or "one of " + ", ".join(f'"{c}"' for c in choices)
        value = self.string(table, key, path, default, expected=exp)
        if value is None:
            return None
        if value not in choices:
            close = difflib.get_close_matches(value, choices, n=1, cutoff=0.6)
            hint = f', did you mean "{close[0]}"?' if close else ""
            self.problem(f"{path}.{key}", f"not a known value{hint} (expected {exp}, got {_show(value)})")
            return None
        return value

    def vector(
        self,
        table: Mapping[str, Any],
        key: str,
        path: str,
        n: int,
        default: Any = _MISSING,
        *,
        unit: str = "",
        names: str = "",
    ) -> tuple[float, ...] | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        exp = f"an array of {n} numbers" + (f" {names}" if names else "") + (f" in {unit}" if unit else "")
        if value is _MISSING:
            self.problem(name, f"missing (expected {exp})")
            return None
        if not isinstance(value, list) or len(value) != n or not all(_is_number(v) for v in value):
            self.problem(name, f"wrong type (expected {exp}, got {_kind(value)} {_show(value)})")
            return None
        if not all(math.isfinite(v) for v in value):
            self.problem(name, f"not finite (expected {exp}, got {_show(value)})")
            return None
        return tuple(float(v) for v in value)

    def per_dof(
        self, table: Mapping[str, Any], key: str, path: str, *, unit: str = "", allow_inf: bool = False
    ) -> float | tuple[float, float, float] | None:
        """A positive number for all three DOF, or an array [surge, sway, yaw]."""
        value = table[key]
        name = f"{path}.{key}"
        limit = "positive" + (" (inf allowed)" if allow_inf else "")
        exp = f"a {limit} number{' ' + unit if unit else ''}, or an array of 3 [surge, sway, yaw]"
        items = value if isinstance(value, list) else [value]
        ok_type = (not isinstance(value, list) or len(value) == 3) and all(_is_number(v) for v in items)
        if not ok_type:
            self.problem(name, f"wrong type (expected {exp}, got {_kind(value)} {_show(value)})")
            return None
        xs = [float(v) for v in items]
        if not all((math.isfinite(x) or (allow_inf and x == math.inf)) and x > 0 for x in xs):
            self.problem(name, f"out of range (expected {exp}, got {_show(value)})")
            return None
        if isinstance(value, list):
            return (xs[0], xs[1], xs[2])
        return xs[0]

    def string_list(
        self,
        table: Mapping[str, Any],
        key: str,
        path: str,
        default: Any = _MISSING,
        *,
        expected: str = "an array of strings",
    ) -> list[str] | None:
        value = table.get(key, default)
        name = f"{path}.{key}"
        if value is _MISSING:
            self.problem(name, f"missing (expected {expected})")
            return None
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            self.problem(name, f"wrong type (expected {expected}, got {_kind(value)} {_show(value)})")
            return None
        return list(value)


# --- URLs -----------------------------------------------------------------------------------------------


def _split_host_port(netloc: str, *, any_port: bool = False) -> tuple[str, int] | str:
    """``HOST:PORT``, ``[v6]:PORT`` or ``:PORT`` → (host, port), or the problem as a string.

    ``any_port``: port 0 (any free port) is allowed, as for a Zenoh listen endpoint.
    """
    m = re.fullmatch(r"\[([0-9A-Fa-f:.]+)\]:(\d+)|([^:\[\]/@]*):(\d+)", netloc)
    if not m:
        return f"{netloc!r} is not HOST:PORT"
    host = m.group(1) if m.group(1) is not None else m.group(3)
    port = int(m.group(2) or m.group(4))
    if not (0 if any_port else 1) <= port <= 65535:
        return f"port {port} is out of range ({0 if any_port else 1}-65535)"
    return host, port


_URL_FORMS = (
    "serial:///dev/ttyUSB0?baud=4800, pty:///PATH, udp://0.0.0.0:10110, tcp://HOST:PORT, "
    "tcp-listen://0.0.0.0:PORT, file:///path/log.nmea, file:relative/log.nmea, or pymavlink's "
    "udpin:0.0.0.0:14550, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, /dev/ttyACM0,57600"
)


def _check_baud(baud: str) -> str | None:
    if baud.isdigit() and int(baud) in BAUD_RATES:
        return None
    return f"unsupported baud rate {baud!r} (expected one of {', '.join(map(str, BAUD_RATES))})"


def _listening(kind: str, host: str, port: int) -> str | None:
    """The resource a listening socket takes: None for port 0 (any free port) and multicast groups."""
    multicast = re.fullmatch(r"(22[4-9]|23\d)\.\d+\.\d+\.\d+", host) is not None
    return None if port == 0 or multicast else f"{kind}:{port}"


def _check_url(url: str, protocol: str, base_dir: Path) -> tuple[str, str, str | None] | str:
    """(transport, url, resource) for a source URL, or the problem (syntax only: nothing is opened).

    ``resource`` names what the URL occupies on this machine (a serial device, a listening port), so two
    sources that would fight over it are caught; None for links that occupy nothing exclusively.
    `gateway.sources.open_source` has the last word on options (`_check_with_sources`).
    """
    text = url.strip()
    if not text:
        return f"empty (expected a URL: {_URL_FORMS})"
    if "://" not in text:
        serial = re.fullmatch(r"(/[^,]*)(?:,(.*))?|serial:(/.*?)(?::(\d+))?", text, flags=re.IGNORECASE)
        if serial:  # pymavlink serial devices: /dev/ttyACM0[,57600], serial:/dev/ttyACM0[:57600]
            device = serial.group(1) or serial.group(3)
            baud = serial.group(2) if serial.group(1) else serial.group(4)
            if not baud and protocol == "nmea":
                return (
                    "a pymavlink device string without a baud rate opens at 115200 baud (expected "
                    f"serial://{device}?baud=4800 for NMEA 0183, got {_show(url)})"
                )
            if baud:
                problem = _check_baud(baud)
                if problem:
                    return problem
            return "pymavlink", text, f"serial:{device}"
        m = re.fullmatch(r"([A-Za-z][A-Za-z0-9+.-]*):(.*)", text)
        if not m:
            if re.fullmatch(r"[^:/]*:\d+", text):
                return f"no transport given (expected udp://{text} or tcp://{text}, got {_show(url)})"
            return f"not a URL (expected one of {_URL_FORMS}, got {_show(url)})"
        prefix, rest = m.group(1).lower(), m.group(2)
        if prefix == "file":  # file:relative/path.nmea[?rate=...], relative to the config file
            rel, _, query = rest.partition("?")
            if not rel:
                return "no path given (expected file:PATH or file:///ABSOLUTE/PATH)"
            path = (base_dir / unquote(rel)).resolve()
            return "file", "file://" + quote(path.as_posix()) + (f"?{query}" if query else ""), None
        if prefix in PYMAVLINK_PREFIXES:
            listening = prefix in ("udpin", "udp", "tcpin")
            hp = _split_host_port(rest, any_port=listening)
            if isinstance(hp, str):
                return f"{hp} (expected {prefix}:HOST:PORT, e.g. udpin:0.0.0.0:14550, got {_show(url)})"
            host, port = hp
            if not host and not listening:
                return f"no host (expected {prefix}:HOST:PORT, got {_show(url)})"
            kind = "tcp" if prefix.startswith("tcp") else "udp"
            return "pymavlink", text, _listening(kind, host, port) if listening else None
        if prefix in URL_SCHEMES:
            return f"not a URL I understand, did you mean {prefix}://{rest.lstrip('/')}? (got {_show(url)})"
        close = difflib.get_close_matches(prefix, URL_SCHEMES + PYMAVLINK_PREFIXES, n=1, cutoff=0.6)
        hint = f", did you mean {close[0]}:?" if close else ""
        return f"unknown transport '{prefix}'{hint} (expected one of {_URL_FORMS}, got {_show(url)})"
    try:
        parts = urlsplit(text)
    except ValueError as exc:
        return f"malformed URL: {exc} (expected one of {_URL_FORMS}, got {_show(url)})"
    scheme = parts.scheme.lower()
    if scheme not in URL_SCHEMES:
        close = difflib.get_close_matches(scheme, URL_SCHEMES, n=1, cutoff=0.6)
        hint = f", did you mean {close[0]}://?" if close else ""
        return f"unknown transport '{parts.scheme}'{hint} (expected one of {_URL_FORMS}, got {_show(url)})"
    if parts.fragment:
        return f"unexpected '#{parts.fragment}' (expected no fragment, got {_show(url)})"
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    if scheme in ("serial", "pty", "file"):
        if parts.netloc not in ("", "localhost"):
            return (
                f"{parts.netloc!r} is read as a host name (expected an absolute path with three slashes: "
                f"{scheme}:///{parts.netloc}{parts.path}, got {_show(url)})"
            )
        path_text = unquote(parts.path)
        if not path_text:
            example = {"serial": "serial:///dev/ttyUSB0", "pty": "pty:///tmp/dpgw-gps"}.get(
                scheme, "file:///x.nmea"
            )
            return f"no path given (expected e.g. {example}, got {_show(url)})"
        if scheme == "file":
            return "file", text, None
        if "baud" in options:
            problem = _check_baud(options["baud"])
            if problem:
                return problem
        return scheme, text, f"serial:{path_text}"
    if parts.path not in ("", "/"):
        return f"unexpected path {parts.path!r} (expected {scheme}://HOST:PORT, got {_show(url)})"
    listening = scheme != "tcp"
    hp = _split_host_port(parts.netloc, any_port=listening)
    if isinstance(hp, str):
        return f"{hp} (expected {scheme}://HOST:PORT, got {_show(url)})"
    host, port = hp
    if scheme == "tcp":
        if not host:
            return f"no host to connect to (expected tcp://HOST:PORT, got {_show(url)})"
        return "tcp", text, None
    return scheme, text, _listening("udp" if scheme == "udp" else "tcp", host, port)


def _check_with_sources(name: str, url: str, timeout_s: float) -> str | None:
    """What `gateway.sources.open_source` says of the URL (it validates options; it opens nothing)."""
    from gateway.sources import SourceError, open_source

    try:
        open_source(name, url, timeout_s=timeout_s)
    except SourceError as exc:
        return str(exc)
    return None


def _check_zenoh_endpoint(endpoint: str, *, listen: bool = False) -> str | None:
    m = re.fullmatch(r"([a-z][a-z0-9-]*)/([^?#]+)([?#].*)?", endpoint)
    if not m:
        return (
            "not a Zenoh endpoint (expected <protocol>/<address>, e.g. tcp/192.168.1.10:7447, "
            f"got {_show(endpoint)})"
        )
    proto, address = m.group(1), m.group(2)
    if proto not in ZENOH_PROTOCOLS:
        known = ", ".join(ZENOH_PROTOCOLS)
        return f"unknown Zenoh protocol '{proto}' (expected one of {known}, got {_show(endpoint)})"
    if proto in ("tcp", "udp", "tls", "quic"):
        hp = _split_host_port(address, any_port=listen)
        if isinstance(hp, str):
            return f"{hp} (expected {proto}/HOST:PORT, e.g. {proto}/192.168.1.10:7447, got {_show(endpoint)})"
        if not hp[0]:
            return (
                f"no host (expected {proto}/HOST:PORT, e.g. {proto}/0.0.0.0:{hp[1]}, got {_show(endpoint)})"
            )
    return None


def _check_key_expr(prefix: str) -> str | None:
    if prefix.startswith("/") or prefix.endswith("/") or "//" in prefix:
        return (
            "empty chunk in the key expression (expected chunks separated by single '/', no leading or "
            f"trailing '/', e.g. dp/my_ship, got {_show(prefix)})"
        )
    bad = "".join(sorted(set(prefix) & set("*$?#")))
    if not bad and any(c.isspace() for c in prefix):
        bad = "whitespace"
    if bad:
        return (
            f"'{bad}' not allowed in a key expression prefix (expected plain chunks such as dp/my_ship, "
            f"got {_show(prefix)})"
        )
    return None


# --- parsing --------------------------------------------------------------------------------------------


def load_config(path: str | Path) -> GatewayConfig:
    """Read, check and return the configuration in ``path``; raise `ConfigError` listing every problem."""
    where = str(path)
    file = Path(path)
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        raise ConfigError([f"{where}: cannot read: no such file"]) from None
    except OSError as exc:
        raise ConfigError([f"{where}: cannot read: {exc.strerror or exc}"]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError([f"{where}: not UTF-8 text (byte {exc.start}): save the file as UTF-8"]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{where}: not valid TOML: {exc}"]) from None
    resolved = file.resolve()
    return _parse(data, base_dir=resolved.parent, where=where, path=resolved)


def parse_config(data: dict[str, Any], *, base_dir: Path, where: str = "<config>") -> GatewayConfig:
    """Check a parsed config (a dict as from `tomllib`); relative paths are resolved against ``base_dir``.

    ``where`` names the config in messages. Raises `ConfigError` listing every problem.
    """
    base = Path(base_dir).resolve()
    return _parse(data, base_dir=base, where=where, path=base / where)


def _parse(data: dict[str, Any], *, base_dir: Path, where: str, path: Path) -> GatewayConfig:
    r = _Reader(where)
    if not isinstance(data, dict):
        raise ConfigError(
            [f"{where}: (top level): wrong type (expected a table of sections, got {_kind(data)})"]
        )
    r.known(data, "", _TOP_KEYS)

    vessel, vessel_source, reference_point = _parse_vessel(r, data, base_dir)
    datum = _parse_datum(r, data)
    sources = _parse_sources(r, data, base_dir, vessel)
    observer = _parse_observer(r, data, vessel)
    zenoh_config = _parse_zenoh(r, data, base_dir, vessel)
    log = _parse_log(r, data, base_dir)
    status = _parse_status(r, data)
    control = _parse_control(r, data)

    if r.problems:
        raise ConfigError(r.problems)
    assert vessel is not None and vessel_source is not None and reference_point is not None
    assert datum is not None and sources is not None and observer is not None
    assert zenoh_config is not None and log is not None and status is not None and control is not None
    return GatewayConfig(
        vessel=vessel,
        vessel_source=vessel_source,
        reference_point_m=reference_point,
        datum=datum,
        sources=sources,
        observer=observer,
        zenoh=zenoh_config,
        log=log,
        status=status,
        path=path,
        control=control,
    )


def _parse_vessel(
    r: _Reader, data: Mapping[str, Any], base_dir: Path
) -> tuple[VesselModel | None, str | None, tuple[float, float] | None]:
    t = r.table(data, "vessel", "vessel", required=True)
    if t is None:
        return None, None, None
    r.known(t, "vessel", _VESSEL_KEYS)
    builtins = builtin_vessels()
    vessel: VesselModel | None = None
    source: str | None = None
    if "name" in t and "file" in t:
        r.problem(
            "vessel", "both name and file given (expected one: a built-in vessel name or a vessel file)"
        )
    elif "name" in t:
        name = r.string(t, "name", "vessel", expected=f"a built-in vessel name ({', '.join(builtins)})")
        if name is not None:
            if name not in builtins:
                close = difflib.get_close_matches(name, builtins, n=1, cutoff=0.6)
                hint = f', did you mean "{close[0]}"?' if close else ""
                r.problem(
                    "vessel.name",
                    f"not a built-in vessel{hint} (expected one of {', '.join(builtins)}, or give "
                    f'file = "my_ship.toml" for a vessel file; got {_show(name)})',
                )
            else:
                try:
                    vessel, source = load_vessel(name), name
                except VesselError as exc:
                    r.problem("vessel.name", str(exc))
    elif "file" in t:
        file = r.string(t, "file", "vessel", expected="a vessel TOML file path (relative to the config file)")
        if file is not None:
            vessel_path = (base_dir / file).resolve()
            if not file:
                r.problem("vessel.file", "empty (expected a vessel TOML file path)")
            elif not vessel_path.is_file():
                r.problem(
                    "vessel.file",
                    f"no such file {vessel_path} (expected a vessel TOML file; relative paths are relative "
                    f"to the config file's folder; got {_show(file)})",
                )
            else:
                try:
                    vessel, source = load_vessel(vessel_path), str(vessel_path)
                except VesselError as exc:
                    r.problem("vessel.file", str(exc))
    else:
        r.problem(
            "vessel",
            f'missing name or file (expected name = one of {", ".join(builtins)}, or file = "my_ship.toml")',
        )
    ref = r.vector(
        t,
        "reference_point_m",
        "vessel",
        2,
        _DEFAULTS["vessel"]["reference_point_m"],
        unit="m",
        names="[x, y]",
    )
    reference: tuple[float, float] | None = None
    if ref is not None:
        reference = (ref[0], ref[1])
        if vessel is not None and max(abs(ref[0]), abs(ref[1])) > vessel.length_m:
            r.problem(
                "vessel.reference_point_m",
                f"outside the vessel (expected |x|, |y| <= the vessel length {vessel.length_m:g} m, got "
                f"{_show(t['reference_point_m'])})",
            )
            reference = None
    return vessel, source, reference


def _parse_datum(r: _Reader, data: Mapping[str, Any]) -> DatumConfig | None:
    if "datum" not in data:
        return DatumConfig(first_fix=True)
    t = r.table(data, "datum", "datum")
    if t is None:
        return None
    r.known(t, "datum", _DATUM_KEYS)
    d = _DEFAULTS["datum"]
    first_fix = r.boolean(t, "first_fix", "datum", d["first_fix"])
    alt = r.number(t, "alt_m", "datum", d["alt_m"], lo=-1000.0, hi=10000.0, unit="m")
    has_lat, has_lon = "lat_deg" in t, "lon_deg" in t
    lat = r.number(t, "lat_deg", "datum", None, lo=-90.0, hi=90.0, unit="degrees")
    lon = r.number(t, "lon_deg", "datum", None, lo=-180.0, hi=180.0, unit="degrees")
    if first_fix is None or alt is None:
        return None
    if first_fix:
        if has_lat or has_lon or "alt_m" in t:
            r.problem(
                "datum",
                "first_fix = true and a fixed point given (expected either lat_deg, lon_deg [, alt_m] or "
                "first_fix = true)",
            )
            return None
        return DatumConfig(first_fix=True)
    if not has_lat or not has_lon:
        missing = " and ".join(k for k, has in (("lat_deg", has_lat), ("lon_deg", has_lon)) if not has)
        both = not has_lat and not has_lon
        r.problem(
            "datum" if both else f"datum.{missing}",
            f"missing{' ' + missing if both else ''} (expected lat_deg and lon_deg of the local NED origin, "
            "or first_fix = true)",
        )
        return None
    if lat is None or lon is None:
        return None
    return DatumConfig(lat_deg=lat, lon_deg=lon, alt_m=alt, first_fix=False)


def _parse_sources(
    r: _Reader, data: Mapping[str, Any], base_dir: Path, vessel: VesselModel | None
) -> tuple[SourceConfig, ...] | None:
    value = data.get("sources", _MISSING)
    example = '[[sources]] name = "dgps1", url = "serial:///dev/ttyUSB0?baud=4800", protocol = "nmea", ...'
    if value is _MISSING:
        r.problem("sources", f"missing (expected at least one {example})")
        return None
    if isinstance(value, dict):
        r.problem(
            "sources", "wrong type (expected an array of tables, written [[sources]], got a table [sources])"
        )
        return None
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        r.problem("sources", f"wrong type (expected an array of tables [[sources]], got {_kind(value)})")
        return None
    if not value:
        r.problem("sources", f"empty (expected at least one {example})")
        return None
    ok = True
    out: list[SourceConfig] = []
    resources: dict[str, int] = {}
    for i, entry in enumerate(value):
        path = f"sources[{i}]"
        src = _parse_source(r, entry, path, base_dir, vessel)
        if src is None:
            ok = False
            continue
        source, resource = src
        if resource is not None:
            if resource in resources:
                j = resources[resource]
                kind, _, what = resource.partition(":")
                r.problem(
                    f"{path}.url",
                    f"same {kind} {what} as sources[{j}] ({_show(value[j].get('name'))}) (expected each "
                    "device or listening port used by one source; give that source several roles instead)",
                )
                ok = False
            else:
                resources[resource] = i
        out.append(source)
    # Checks across entries run on what was written, also when an entry has problems of its own.
    names: dict[str, int] = {}
    for i, entry in enumerate(value):
        name = entry.get("name")
        if not isinstance(name, str):
            continue
        if name in names:
            r.problem(
                f"sources[{i}].name",
                f"duplicate source name (expected unique names; sources[{names[name]}] is also "
                f"{_show(name)})",
            )
            ok = False
        else:
            names[name] = i
    written_roles = {
        role for entry in value if isinstance(entry.get("roles"), list) for role in entry["roles"]
    }
    for role, device in (("position", "DGPS"), ("heading", "gyro compass")):
        if role not in written_roles:
            r.problem(
                "sources",
                f"no source has role '{role}' — add roles = [\"{role}\"] to the {device}'s [[sources]] entry "
                "(expected a source of position and one of heading: the observer needs both)",
            )
            ok = False
    for role in ("position", "heading", "thrusters"):
        by_priority: dict[int, str] = {}
        for sc in out:
            if role not in sc.roles:
                continue
            if sc.priority in by_priority:
                r.problem(
                    f"sources[{names.get(sc.name, '?')}].priority",
                    f"sources '{by_priority[sc.priority]}' and '{sc.name}' both have role '{role}' with "
                    f"priority {sc.priority} (expected different priorities: the lower wins, the other is "
                    "its failover)",
                )
                ok = False
            else:
                by_priority[sc.priority] = sc.name
    return tuple(out) if ok else None


def _parse_source(
    r: _Reader, t: Mapping[str, Any], path: str, base_dir: Path, vessel: VesselModel | None
) -> tuple[SourceConfig, str | None] | None:
    n0 = len(r.problems)
    r.known(t, path, _SOURCE_KEYS)
    d = _DEFAULTS["source"]
    name = r.string(t, "name", path, expected='a name of lowercase letters, digits and _ (e.g. "dgps1")')
    if name is not None and not SOURCE_NAME.fullmatch(name):
        r.problem(
            f"{path}.name", f"not a valid name (expected lowercase letters, digits and _, got {_show(name)})"
        )
    protocol = r.choice(t, "protocol", path, PROTOCOLS)
    allowed = ROLES.get(protocol or "", ())
    roles_exp = (
        "an array of roles from " + ", ".join(f'"{x}"' for x in allowed) + f' (protocol "{protocol}")'
        if protocol
        else "an array of roles: nmea: position, heading; mavlink: thrusters, position, heading"
    )
    roles = r.string_list(t, "roles", path, expected=roles_exp)
    if roles is not None:
        if not roles:
            r.problem(f"{path}.roles", f"empty (expected {roles_exp})")
        if len(set(roles)) != len(roles):
            r.problem(f"{path}.roles", f"a role is repeated (expected each role once, got {_show(roles)})")
        if protocol is not None:
            for role in roles:
                if role not in allowed:
                    close = difflib.get_close_matches(role, allowed, n=1, cutoff=0.6)
                    hint = f', did you mean "{close[0]}"?' if close else ""
                    r.problem(
                        f"{path}.roles",
                        f'role {_show(role)} is not available for protocol "{protocol}"{hint} '
                        f"(expected {roles_exp})",
                    )
    url_value = r.string(t, "url", path, expected="a URL, e.g. serial:///dev/ttyUSB0?baud=4800")
    transport: str | None = None
    url: str | None = None
    resource: str | None = None
    if url_value is not None:
        # with protocol unknown (reported above), check the syntax as permissively as for MAVLink
        checked = _check_url(url_value, protocol or "mavlink", base_dir)
        if isinstance(checked, str):
            r.problem(f"{path}.url", checked)
        else:
            transport, url, resource = checked
            problem = _check_with_sources(name if name else "source", url, 2.0)
            if problem:
                r.problem(f"{path}.url", problem)
    lever = r.vector(
        t, "lever_arm_m", path, 3, d["lever_arm_m"], unit="m", names="[x fwd, y stbd, z down] of the antenna"
    )
    if "lever_arm_m" in t and roles is not None and "position" not in roles:
        r.problem(
            f"{path}.lever_arm_m",
            'only for sources with role "position" (expected no lever_arm_m, or add "position" to roles)',
        )
    if lever is not None and vessel is not None and math.dist(lever, (0, 0, 0)) > 2 * vessel.length_m:
        r.problem(
            f"{path}.lever_arm_m",
            f"farther from the reference point than twice the vessel length (expected metres within "
            f"{2 * vessel.length_m:g} m, got {_show(t['lever_arm_m'])})",
        )
    timeout = r.number(t, "timeout_s", path, d["timeout_s"], lo=0.0, hi=600.0, lo_open=True, unit="s")
    priority = r.integer(t, "priority", path, d["priority"], lo=0)
    allow_missing = r.boolean(t, "allow_missing_checksum", path, d["allow_missing_checksum"])
    if "allow_missing_checksum" in t and protocol == "mavlink":
        r.problem(f"{path}.allow_missing_checksum", 'only for protocol "nmea" (expected no such key here)')
    if protocol == "nmea":
        for key in _MAVLINK_ONLY:
            if key in t:
                r.problem(f"{path}.{key}", 'only for protocol "mavlink" (expected no such key for "nmea")')
    system_id = r.integer(t, "system_id", path, None, lo=1, hi=255)
    signing_key: bytes | None = None
    key_text = r.string(t, "signing_key", path, None, expected="64 hexadecimal characters (32 bytes)")
    if key_text is not None:
        if SIGNING_KEY.fullmatch(key_text):
            signing_key = bytes.fromhex(key_text)
        else:
            # never echo a secret back into a log: only its length
            r.problem(
                f"{path}.signing_key",
                f"not a signing key (expected 64 hexadecimal characters, got {len(key_text)} characters"
                + (", not all hexadecimal" if re.search(r"[^0-9a-fA-F]", key_text) else "")
                + ")",
            )
    allow_unsigned = r.boolean(t, "allow_unsigned", path, d["allow_unsigned"])
    if allow_unsigned and "signing_key" not in t and protocol == "mavlink":
        r.problem(
            f"{path}.allow_unsigned",
            "has no effect without a signing_key (expected a signing_key, or no allow_unsigned)",
        )
    commands = r.boolean(t, "commands", path, False)
    if commands and roles is not None and "thrusters" not in roles:
        r.problem(f"{path}.commands", 'sends thruster commands (expected "thrusters" in roles)')
    ardupilot: ArdupilotMap | None = None
    if "ardupilot" in t and protocol == "mavlink":
        if roles is not None and "thrusters" not in roles:
            r.problem(f"{path}.ardupilot", 'maps thruster feedback (expected "thrusters" in roles)')
        ardupilot = _parse_ardupilot(r, t, f"{path}.ardupilot", vessel)
    if len(r.problems) != n0:
        return None
    assert name is not None and protocol is not None and roles is not None and url is not None
    assert transport is not None and lever is not None and timeout is not None and priority is not None
    assert allow_missing is not None and allow_unsigned is not None
    source = SourceConfig(
        name=name,
        url=url,
        protocol=protocol,
        roles=tuple(roles),
        transport=transport,
        lever_arm_m=(lever[0], lever[1], lever[2]),
        timeout_s=timeout,
        allow_missing_checksum=allow_missing,
        priority=priority,
        system_id=system_id,
        signing_key=signing_key,
        allow_unsigned=allow_unsigned,
        ardupilot=ardupilot,
        commands=bool(commands),
    )
    return source, resource


def _parse_ardupilot(
    r: _Reader, parent: Mapping[str, Any], path: str, vessel: VesselModel | None
) -> ArdupilotMap | None:
    t = r.table(parent, "ardupilot", path)
    if t is None:
        return None
    r.known(t, path, ("esc", "servo"))
    if not t.get("esc") and not t.get("servo"):
        r.problem(path, "maps nothing (expected esc = {1 = 1, ...} and/or servo = {1 = 1, ...})")
    thrusters = {th.id: th for th in vessel.thrusters} if vessel is not None else None
    maps: dict[str, dict[int, int]] = {}
    for key, what in (("esc", "ESC index"), ("servo", "servo output channel")):
        m = r.table(t, key, f"{path}.{key}")
        maps[key] = {}
        if m is None:
            continue
        used: dict[int, int] = {}
        for k, v in m.items():
            name = f"{path}.{key}.{k}"
            if not k.isdigit() or not 1 <= int(k) <= MAX_ARDUPILOT_INDEX:
                r.problem(name, f"not a {what} (expected 1 to {MAX_ARDUPILOT_INDEX}, got {_show(k)})")
                continue
            if isinstance(v, bool) or not isinstance(v, int):
                r.problem(name, f"wrong type (expected a thruster id, an integer, got {_kind(v)} {_show(v)})")
                continue
            if thrusters is not None and v not in thrusters:
                ids = ", ".join(str(i) for i in sorted(thrusters)) or "none"
                r.problem(
                    name,
                    f"vessel '{vessel.name if vessel else ''}' has no thruster {v} (expected one of its "
                    f"thruster ids: {ids})",
                )
                continue
            if key == "servo" and thrusters is not None and thrusters[v].kind != "azimuth":
                r.problem(
                    name,
                    f"thruster {v} is a {thrusters[v].kind} thruster (expected an azimuth thruster: a servo "
                    "channel gives the azimuth angle)",
                )
                continue
            if v in used:
                r.problem(
                    name,
                    f"thruster {v} is also mapped from {key} {used[v]} (expected one {what} per thruster)",
                )
                continue
            used[v] = int(k)
            maps[key][int(k)] = v
    return ArdupilotMap(esc=maps["esc"], servo=maps["servo"])


def _parse_observer(r: _Reader, data: Mapping[str, Any], vessel: VesselModel | None) -> ObserverConfig | None:
    t = r.table(data, "observer", "observer")
    if t is None:
        if "observer" in data:
            return None
        t = {}
    n0 = len(r.problems)
    r.known(t, "observer", _OBSERVER_KEYS)
    d = _DEFAULTS["observer"]
    kind = r.choice(t, "type", "observer", OBSERVER_TYPES, d["type"])
    allow_unchecked = r.boolean(t, "allow_unchecked", "observer", d["allow_unchecked"])
    rate = r.number(t, "rate_hz", "observer", d["rate_hz"], lo=1.0, hi=50.0, unit="Hz")
    n_tuning = len(r.problems)
    values: dict[str, Any] = {}
    if "wave_period_s" in t and "omega0" in t:
        r.problem(
            "observer", "both wave_period_s and omega0 given (expected one: the wave period or ω0 = 2π/Tp)"
        )
    elif "omega0" in t:
        values["omega0"] = r.per_dof(t, "omega0", "observer", unit="rad/s")
    else:
        with_default = {"wave_period_s": d["wave_period_s"], **t}
        period = r.per_dof(with_default, "wave_period_s", "observer", unit="s")
        if period is not None:
            values["omega0"] = (
                2 * math.pi / period if isinstance(period, float) else tuple(2 * math.pi / p for p in period)
            )
    for explicit, ratio in (
        ("omega_c", "cutoff_ratio"),
        ("bias_corner", "bias_corner_ratio"),
        ("velocity_injection", "velocity_injection_ratio"),
    ):
        if explicit in t and ratio in t:
            r.problem(
                "observer", f"both {explicit} and {ratio} given (expected one: {explicit} overrides {ratio})"
            )
    for key in _TUNING_KEYS:
        if key in t:
            values[key] = r.per_dof(t, key, "observer", allow_inf=key == "bias_time_constant_s")
        elif (
            key in d
            and not (key == "cutoff_ratio" and "omega_c" in t)
            and not (key == "bias_corner_ratio" and "bias_corner" in t)
            and not (key == "velocity_injection_ratio" and "velocity_injection" in t)
        ):
            values[key] = d[key]
    if len(r.problems) != n_tuning or any(v is None for v in values.values()):
        return None
    # The tuning is complete: check it for this vessel even if other observer keys have problems.
    tuning = PassiveTuning(**values)
    # The checks depend on gain ratios only (the vessel's M scales K3 and K4 alike), so a tuning is still
    # checked, with a stand-in vessel, when the configured vessel has problems of its own.
    try:
        checks = tuple(check_gains(passive_gains(vessel or load_vessel("mss_supply"), tuning)))
    except TuningError as exc:
        r.problem("observer", str(exc))
        return None
    for check in checks:
        if not check.ok and not allow_unchecked:
            r.problem(
                "observer",
                f"tuning fails {check.inequality}: {check.detail} (expected a tuning that passes, or "
                "observer.allow_unchecked = true to run such gains for experiments)",
            )
    params: dict[str, Any] = {}
    if "params" in t:
        ptab = t["params"]
        if not isinstance(ptab, dict):
            r.problem("observer.params", f"wrong type (expected a table, got {_kind(ptab)})")
        elif kind is not None:
            try:
                check_params(kind, ptab)
            except ObserverSpecError as exc:
                r.problem("observer.params", str(exc))
            for key, value in ptab.items():
                items = value if isinstance(value, list) else [value]
                if not all(_is_number(v) or isinstance(v, bool) for v in items):
                    r.problem(f"observer.params.{key}", f"wrong type (expected numbers, got {_show(value)})")
                else:
                    params[key] = tuple(value) if isinstance(value, list) else value
            if kind == "passive" and ptab:
                r.problem(
                    "observer.params", 'the passive observer takes no params (expected none for "passive")'
                )
    if len(r.problems) != n0:
        return None
    assert kind is not None and allow_unchecked is not None and rate is not None
    return ObserverConfig(
        type=kind, tuning=tuning, allow_unchecked=allow_unchecked, rate_hz=rate, checks=checks, params=params
    )


def _parse_zenoh(
    r: _Reader, data: Mapping[str, Any], base_dir: Path, vessel: VesselModel | None
) -> ZenohConfig | None:
    t = r.table(data, "zenoh", "zenoh")
    if t is None:
        if "zenoh" in data:
            return None
        t = {}
    n0 = len(r.problems)
    r.known(t, "zenoh", _ZENOH_KEYS)
    d = _DEFAULTS["zenoh"]
    mode = r.choice(t, "mode", "zenoh", ZENOH_MODES, d["mode"])
    endpoints: dict[str, list[str]] = {}
    for key in ("connect", "listen"):
        values = r.string_list(
            t, key, "zenoh", d[key], expected='an array of endpoints like "tcp/192.168.1.10:7447"'
        )
        endpoints[key] = values or []
        for i, endpoint in enumerate(values or []):
            problem = _check_zenoh_endpoint(endpoint, listen=key == "listen")
            if problem:
                r.problem(f"zenoh.{key}[{i}]", problem)
    scouting = r.boolean(t, "multicast_scouting", "zenoh", d["multicast_scouting"])
    config_text = r.string(
        t, "config_file", "zenoh", d["config_file"], expected="a Zenoh JSON5 config file path"
    )
    config_file: Path | None = None
    if config_text:
        config_file = (base_dir / config_text).resolve()
        for key in ("mode", "connect", "listen", "multicast_scouting"):
            if key in t and t[key] != d[key]:
                r.problem(
                    f"zenoh.{key}",
                    f"has no effect when zenoh.config_file is set (expected it in {config_file.name}, or no "
                    "config_file)",
                )
        if not config_file.is_file():
            r.problem("zenoh.config_file", f"no such file {config_file} (expected a Zenoh JSON5 config file)")
        else:
            import zenoh

            try:
                zenoh.Config.from_file(str(config_file))
            except Exception as exc:  # zenoh raises its own ZError
                r.problem("zenoh.config_file", f"not a valid Zenoh config: {exc}")
    prefix = r.string(t, "prefix", "zenoh", d["prefix"], expected='a key expression such as "dp/my_ship"')
    if prefix == "" and vessel is not None:
        prefix = f"dp/{vessel.name}"
    if prefix:
        problem = _check_key_expr(prefix)
        if problem:
            r.problem("zenoh.prefix", problem)
    if len(r.problems) != n0 or prefix is None or mode is None or scouting is None:
        return None
    return ZenohConfig(
        prefix=prefix,
        mode=mode,
        connect=tuple(endpoints["connect"]),
        listen=tuple(endpoints["listen"]),
        config_file=config_file,
        multicast_scouting=scouting,
    )


def _parse_log(r: _Reader, data: Mapping[str, Any], base_dir: Path) -> LogConfig | None:
    t = r.table(data, "log", "log")
    if t is None:
        if "log" in data:
            return None
        t = {}
    n0 = len(r.problems)
    r.known(t, "log", _LOG_KEYS)
    d = _DEFAULTS["log"]
    text = r.string(t, "path", "log", d["path"], expected='an .mcap file path, or "" to disable logging')
    path: Path | None = None
    if text:
        path = (base_dir / text).resolve()
        if path.suffix != ".mcap":
            r.problem(
                "log.path", f"not an MCAP file name (expected a path ending in .mcap, got {_show(text)})"
            )
    rotate_mb = r.number(t, "rotate_mb", "log", d["rotate_mb"], lo=0.0, unit="MiB (0 = never)")
    if rotate_mb is not None and 0 < rotate_mb < 1:
        r.problem("log.rotate_mb", f"too small (expected 0 (never) or >= 1 MiB, got {_show(t['rotate_mb'])})")
    rotate_min = r.number(t, "rotate_minutes", "log", d["rotate_minutes"], lo=0.0, unit="minutes (0 = never)")
    if rotate_min is not None and 0 < rotate_min < 1:
        r.problem(
            "log.rotate_minutes",
            f"too small (expected 0 (never) or >= 1 minute, got {_show(t['rotate_minutes'])})",
        )
    flush = r.number(
        t, "flush_interval_s", "log", d["flush_interval_s"], lo=0.0, hi=60.0, lo_open=True, unit="s"
    )
    compression = r.choice(t, "compression", "log", COMPRESSIONS, d["compression"])
    if len(r.problems) != n0:
        return None
    assert rotate_mb is not None and rotate_min is not None and flush is not None and compression is not None
    return LogConfig(
        path=path,
        rotate_mb=rotate_mb,
        rotate_minutes=rotate_min,
        flush_interval_s=flush,
        compression=compression,
    )


def _parse_status(r: _Reader, data: Mapping[str, Any]) -> StatusConfig | None:
    t = r.table(data, "status", "status")
    if t is None:
        if "status" in data:
            return None
        t = {}
    r.known(t, "status", _STATUS_KEYS)
    rate = r.number(t, "rate_hz", "status", _DEFAULTS["status"]["rate_hz"], lo=0.1, hi=10.0, unit="Hz")
    return None if rate is None else StatusConfig(rate_hz=rate)


def _parse_control(r: _Reader, data: Mapping[str, Any]) -> ControlConfig | None:
    t = r.table(data, "control", "control")
    if t is None:
        if "control" in data:
            return None
        t = {}
    r.known(t, "control", _CONTROL_KEYS)
    d = _DEFAULTS["control"]
    n0 = len(r.problems)
    rate = r.number(t, "rate_hz", "control", d["rate_hz"], lo=1.0, hi=50.0, unit="Hz")
    mode = r.choice(t, "initial_mode", "control", CONTROL_MODES, d["initial_mode"])
    allocator = r.choice(t, "allocator", "control", ALLOCATORS, d["allocator"])
    bandwidth = r.per_dof(t, "bandwidth_rad_s", "control", unit="rad/s") if "bandwidth_rad_s" in t else None
    damping = r.number(t, "damping", "control", d["damping"], lo=0.3, hi=3.0)
    feedback = r.choice(t, "feedback", "control", FEEDBACKS, d["feedback"])
    if len(r.problems) != n0:
        return None
    assert rate is not None and mode is not None and allocator is not None and damping is not None
    assert feedback is not None
    return ControlConfig(rate, mode, allocator, bandwidth, damping, feedback)


# --- a command-line check -------------------------------------------------------------------------------


def describe(config: GatewayConfig) -> str:
    """A short human summary of a loaded configuration."""
    lines = [
        f"config {config.path}: ok",
        f"  vessel {config.vessel.name} ({config.vessel_source}), "
        f"reference point {list(config.reference_point_m)} m",
        "  datum: first valid fix"
        if config.datum.first_fix
        else f"  datum: {config.datum.lat_deg:.6f}°, {config.datum.lon_deg:.6f}°, {config.datum.alt_m:g} m",
    ]
    for s in config.sources:
        lines.append(f"  source {s.name}: {s.protocol} {'/'.join(s.roles)} priority {s.priority} <- {s.url}")
    obs = config.observer
    lines.append(
        f"  observer {obs.type} at {obs.rate_hz:g} Hz, ω0 = {_show_dof(obs.tuning.omega0)} rad/s"
        + ("" if not config.observer.failed_checks else " (UNCHECKED: tuning checks fail)")
    )
    z = config.zenoh
    lines.append(
        f"  zenoh {z.mode} prefix {z.prefix}"
        + (f", config file {z.config_file}" if z.config_file else "")
        + (f", connect {list(z.connect)}" if z.connect else "")
        + (f", listen {list(z.listen)}" if z.listen else "")
    )
    lines.append(f"  log {config.log.path}" if config.log.enabled else "  log disabled")
    return "\n".join(lines)


def _show_dof(value: Any) -> str:
    if isinstance(value, tuple | list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"


def main(argv: Sequence[str] | None = None, *, out: Callable[[str], None] = print) -> int:
    """``python -m gateway.config FILE...``: check config files; 0 when all load, 1 otherwise."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or any(a in ("-h", "--help") for a in args):
        out("usage: python -m gateway.config FILE [FILE ...]  — check dpgw config files (docs/config.md)")
        return 0 if args else 2
    status = 0
    for arg in args:
        try:
            out(describe(load_config(arg)))
        except ConfigError as exc:
            print(format_problems(exc), file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
