"""Sensor and thruster faults for the simulator: what goes wrong, on which stream, and when.

A `Fault` is one kind of failure on one source (a sensor's stream name, ``"*"`` for every source, or a
thruster id as a string for ``thruster_failure``) over a window of sim time ``[t_start, t_end)``. A
`FaultSchedule` holds the faults of a scenario; the sensors of `simulator.sensors` consult it at every
sample, and the thruster model asks it about ``thruster_failure``.

Kinds and their parameters (``params``; all SI):

==================== ============================================ ============================================
kind                 effect                                        params
==================== ============================================ ============================================
``dropout``          the source sends nothing in the window        –
``frozen``           the value measured at the first sample in     –
                     the window repeats; sentences keep flowing
                     with advancing times
``jump``             a step added to the reported value for the    ``north_m``, ``east_m`` (GNSS);
                     whole window (a window of one sample is a     ``heading_rad`` (gyro); ``roll_rad``,
                     spike, a long one an offset)                  ``pitch_rad`` (MRU); at least one
``noise_burst``      extra white noise on top of the normal noise  ``sigma_m`` (GNSS, per axis),
                                                                   ``sigma_rad`` (gyro); at least one
``bad_checksum``     sentences go out with a wrong NMEA checksum   ``probability`` per emission (default 1)
                     / MAVLink frames with a wrong CRC
``garbage``          extra random bytes on the line: line noise,   ``probability`` per emission (default 1),
                     ``$`` and CR/LF, partial sentences or frames  ``max_bytes`` (default 40)
``thruster_failure`` the thruster stops (applied by the thruster   –
                     model; the feedback reports FAULT)
``drift``            an offset growing at a constant rate from     ``north_mps``, ``east_mps`` (GNSS);
                     ``t_start`` (rate × (t − t_start)): a slowly  ``heading_rad_s`` (gyro); at least one
                     walking reference; back to normal at t_end
``spoof``            the receiver reports this latitude and/or     ``lat_deg``, ``lon_deg``; at least one
                     longitude instead of the measured one (a far
                     fix, a spoofer's position)
``quality``          GGA reports this quality indicator (GNS, RMC  ``quality`` (0..8; 6 dead reckoning,
                     and VTG the matching mode letter)              7 manual input, 8 simulator)
``bogus_feedback``   the thruster's status frames claim these      ``thrust_n``, ``rpm``, ``azimuth_rad``;
                     values (source: thruster id or ``"*"``)        at least one
``command_setpoint`` a setpoint sent to the gateway at t_start     ``north_m``, ``east_m``, ``heading_deg``
                     (and every 1/rate_hz s in the window when      (default 0), ``rate_hz`` (default 0:
                     ``rate_hz`` > 0); source: the sender's label   once)
``command_tau``      a manual τ sent to the gateway, as above      ``surge_n``, ``sway_n``, ``yaw_nm``
                                                                   (at least one), ``rate_hz``
``command_mode``     a mode change sent to the gateway, as above   ``mode`` (text, required), ``rate_hz``
==================== ============================================ ============================================

Sample-side faults (``dropout``, ``frozen``, ``jump``, ``noise_burst``, ``thruster_failure``, ``drift``,
``spoof``, ``quality``, ``bogus_feedback``) are active when the *measurement* time is in the window; the
sensors (and the thruster model) apply them. Wire-side
faults (``bad_checksum``, ``garbage``) are active when the bytes leave the sensor (``Emission.t_emit``); the
simulator runner applies them to every sensor's emissions with `FaultSchedule.apply_to_emissions` and a
random generator of its own. Command faults (``command_*``) are not the sensors' business: they are inputs a
peer sends to the gateway's command keys (a hostile or mistaken operator station). `FaultSchedule.
command_events` lists them as ``(sim time, key, payload)`` with the payloads of the gateway's command
inputs (docs/interfaces.md); the in-process closed loop (`dpgw.closed_loop`) feeds them to the pipeline.
See docs/sensors.md and docs/simulator.md.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from mypy_extensions import mypyc_attr

from wire.codecs.mavlink import parse_frames
from wire.codecs.nmea_encode import checksum, corrupt_checksum

if TYPE_CHECKING:
    from simulator.sensors import Emission

__all__ = ["COMMAND_KINDS", "FAULT_KINDS", "QUALITY_MODES", "Fault", "FaultSchedule"]

FAULT_KINDS = (
    "dropout",
    "frozen",
    "jump",
    "noise_burst",
    "bad_checksum",
    "garbage",
    "thruster_failure",
    "drift",
    "spoof",
    "quality",
    "bogus_feedback",
    "command_setpoint",
    "command_tau",
    "command_mode",
)
"""Every fault kind a `Fault` may have."""

TIME_TOLERANCE_S = 1e-6
"""Sim times this close count as the same instant (as the sensors' sample schedule does)."""

COMMAND_KINDS = ("command_setpoint", "command_tau", "command_mode")
"""Fault kinds that are commands sent to the gateway, not something a sensor does."""

QUALITY_MODES = {0: "N", 1: "A", 2: "D", 3: "P", 4: "R", 5: "F", 6: "E", 7: "M", 8: "S"}
"""GGA quality indicator → the mode letter GNS, RMC and VTG carry for it (NMEA 0183 4.x)."""

_PARAMS: dict[str, dict[str, float | None]] = {
    # name -> default (None: optional, no default)
    "dropout": {},
    "frozen": {},
    "jump": {"north_m": None, "east_m": None, "heading_rad": None, "roll_rad": None, "pitch_rad": None},
    "noise_burst": {"sigma_m": None, "sigma_rad": None},
    "bad_checksum": {"probability": 1.0},
    "garbage": {"probability": 1.0, "max_bytes": 40.0},
    "thruster_failure": {},
    "drift": {"north_mps": None, "east_mps": None, "heading_rad_s": None},
    "spoof": {"lat_deg": None, "lon_deg": None},
    "quality": {"quality": None},
    "bogus_feedback": {"thrust_n": None, "rpm": None, "azimuth_rad": None},
    "command_setpoint": {"north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0, "rate_hz": 0.0},
    "command_tau": {"surge_n": None, "sway_n": None, "yaw_nm": None, "rate_hz": 0.0},
    "command_mode": {"mode": None, "rate_hz": 0.0},
}
# kinds that need at least one of their parameters without a default
_NEEDS_ONE = {
    "jump",
    "noise_burst",
    "drift",
    "spoof",
    "quality",
    "bogus_feedback",
    "command_tau",
    "command_mode",
}
_TEXT = {"mode"}  # parameters that are text, not numbers
_NON_NEGATIVE = {"sigma_m", "sigma_rad", "rate_hz"}
_PROBABILITY = {"probability"}
_FIELDS = ("kind", "source", "t_start", "t_end", "params")
_SENTENCE_RE = re.compile(rb"\$([^$*\r\n]*)\*([0-9A-Fa-f]{2})")


@mypyc_attr(native_class=False)  # (mypyc: its checks set fields through `object.__setattr__`)
@dataclass(frozen=True)
class Fault:
    """One fault on one source over ``[t_start, t_end)`` (sim seconds). Validated on construction: a
    `ValueError` names the field that is wrong. ``params`` is stored read-only with the defaults of its
    kind filled in (``bad_checksum``/``garbage``: ``probability`` 1.0; ``garbage``: ``max_bytes`` 40)."""

    kind: str
    source: str
    t_start: float
    t_end: float = math.inf
    params: Mapping[str, float | str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # The values as given, not through the fields' types: compiled (setup.py), reading a str or float
        # field fails on a value of another type before these checks could say what is wrong.
        given: dict[str, Any] = vars(self)
        kind, source = given["kind"], given["source"]
        if kind not in FAULT_KINDS:
            raise ValueError(f"kind: unknown fault kind {kind!r}; expected one of {', '.join(FAULT_KINDS)}")
        if not isinstance(source, str) or not source:
            raise ValueError(f"source: must be a non-empty string (a stream name or '*'), got {source!r}")
        t_start = _number("t_start", given["t_start"])
        if not math.isfinite(t_start):
            raise ValueError(f"t_start: must be a finite time in seconds, got {given['t_start']!r}")
        t_end = _number("t_end", given["t_end"])
        if math.isnan(t_end) or t_end <= t_start:
            raise ValueError(f"t_end: must be later than t_start ({t_start} s), got {given['t_end']!r}")
        object.__setattr__(self, "t_start", t_start)
        object.__setattr__(self, "t_end", t_end)
        object.__setattr__(self, "params", MappingProxyType(_check_params(kind, given["params"])))

    def covers(self, t: float) -> bool:
        """True when ``t_start <= t < t_end``, both ends taken `TIME_TOLERANCE_S` early: the runner's sim time
        is a sum of steps (119.99999999999682 for 120 s), and a sample due at a fault's start must see it."""
        return self.t_start - TIME_TOLERANCE_S <= t < self.t_end - TIME_TOLERANCE_S

    def applies_to(self, source: str) -> bool:
        """True for this fault's source, or any source when it is ``"*"``."""
        return self.source == "*" or self.source == source

    def param(self, name: str, default: float = 0.0) -> float:
        """A numeric parameter, or ``default`` when it is not set."""
        value = self.params.get(name)
        return default if value is None else float(value)

    def has(self, name: str) -> bool:
        """True when the parameter is set (given, or defaulted by its kind)."""
        return name in self.params


class FaultSchedule:
    """The faults of a scenario. `active` answers "is a fault of this kind on this source at time t";
    `apply_to_emissions` puts the wire-side faults (``bad_checksum``, ``garbage``) on a sensor's bytes."""

    def __init__(self, faults: Iterable[Fault] = ()) -> None:
        self.faults: tuple[Fault, ...] = tuple(faults)
        for i, fault in enumerate(self.faults):
            if not isinstance(fault, Fault):
                raise TypeError(f"faults[{i}]: expected a Fault, got {type(fault).__name__}")
        self._by_kind: dict[str, tuple[Fault, ...]] = {
            kind: tuple(f for f in self.faults if f.kind == kind) for kind in FAULT_KINDS
        }

    def __len__(self) -> int:
        return len(self.faults)

    def __repr__(self) -> str:
        return f"FaultSchedule({list(self.faults)!r})"

    @classmethod
    def from_dicts(cls, items: Iterable[Mapping[str, Any]]) -> FaultSchedule:
        """From scenario tables (e.g. TOML ``[[faults]]``). Each item has ``kind``, ``source``, ``t_start``,
        optional ``t_end`` (default: until the end), and its parameters either as further keys of the item or
        in a ``params`` table. A thruster id may be given as an integer. Errors name the item and the field:
        ``faults[2].t_end: must be later than t_start (120.0 s), got 100.0``."""
        faults = []
        for i, item in enumerate(items):
            where = f"faults[{i}]"
            if not isinstance(item, Mapping):
                raise ValueError(f"{where}: expected a table of fault fields, got {type(item).__name__}")
            for key in ("kind", "source", "t_start"):
                if key not in item:
                    raise ValueError(f"{where}.{key}: missing (a fault needs kind, source and t_start)")
            params: dict[str, Any] = {}
            nested = item.get("params", {})
            if not isinstance(nested, Mapping):
                raise ValueError(f"{where}.params: expected a table of parameters, got {nested!r}")
            params.update(nested)
            for key, value in item.items():
                if key in _FIELDS:
                    continue
                if key in params:
                    raise ValueError(f"{where}.{key}: given both as a key and in params")
                params[key] = value
            source = item["source"]
            if isinstance(source, int) and not isinstance(source, bool):
                source = str(source)
            try:
                faults.append(
                    Fault(
                        kind=item["kind"],
                        source=source,
                        t_start=item["t_start"],
                        t_end=item.get("t_end", math.inf),
                        params=params,
                    )
                )
            except ValueError as exc:
                raise ValueError(f"{where}.{exc}") from None
        return cls(faults)

    def active(self, kind: str, source: str, t: float) -> Fault | None:
        """The first fault of ``kind`` on ``source`` (or on ``"*"``) covering time ``t``, else None."""
        try:
            candidates = self._by_kind[kind]
        except KeyError:
            raise ValueError(
                f"unknown fault kind {kind!r}; expected one of {', '.join(FAULT_KINDS)}"
            ) from None
        for fault in candidates:
            if fault.applies_to(source) and fault.covers(t):
                return fault
        return None

    def command_events(self, until_s: float) -> list[tuple[float, str, Any]]:
        """The command faults as gateway inputs before ``until_s``: ``(sim time, key, payload)`` with key
        ``setpoint`` ({north_m, east_m, heading_deg}), ``tau`` ({X, Y, N}) or ``mode`` (text), sorted by
        time. Each is sent at ``t_start``, and again every ``1/rate_hz`` s in its window when ``rate_hz`` > 0
        (a peer that keeps sending)."""
        out: list[tuple[float, str, Any]] = []
        for fault in self.faults:
            if fault.kind not in COMMAND_KINDS:
                continue
            key, payload = _command(fault)
            rate = fault.param("rate_hz")
            end = min(fault.t_end, until_s)
            k = 0
            while (t := fault.t_start + (k / rate if rate > 0 else 0.0)) < end:
                out.append((t, key, payload))
                if rate <= 0:
                    break
                k += 1
        return sorted(out, key=lambda e: e[0])

    def apply_to_emissions(self, emissions: list[Emission], rng: np.random.Generator) -> list[Emission]:
        """The emissions as they go on the wire, in order, with ``bad_checksum`` and ``garbage`` applied at
        each emission's ``t_emit``: a corrupted emission replaces the good one (NMEA: every bit of the
        checksum inverted; MAVLink: the CRC inverted); garbage is a separate emission just before or after
        it, with the same ``t_emit`` and ``t_measured = t_emit`` (nothing was measured). ``rng`` is only
        drawn from while such a fault is active, so a schedule without them leaves the sensors' random
        streams untouched."""
        if not self._by_kind["bad_checksum"] and not self._by_kind["garbage"]:
            return list(emissions)
        out: list[Emission] = []
        for em in emissions:
            bad = self.active("bad_checksum", em.source, em.t_emit)
            if bad is not None and rng.random() < bad.param("probability", 1.0):
                em = _replace_data(em, _corrupt(em.protocol, em.data))
            junk = self.active("garbage", em.source, em.t_emit)
            if junk is not None and rng.random() < junk.param("probability", 1.0):
                blob = _garbage(em, int(junk.param("max_bytes", 40.0)), rng)
                noise = _replace_data(em, blob, t_measured=em.t_emit)
                if rng.random() < 0.5:
                    out += [noise, em]
                else:
                    out += [em, noise]
            else:
                out.append(em)
        return out


# ---------------------------------------------------------------------------------------------- helpers


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name}: must be a number, got {value!r}")
    return float(value)


def _command(fault: Fault) -> tuple[str, Any]:
    """A command fault as the gateway's command input: its key and payload."""
    p = fault.param
    if fault.kind == "command_setpoint":
        return "setpoint", {"north_m": p("north_m"), "east_m": p("east_m"), "heading_deg": p("heading_deg")}
    if fault.kind == "command_tau":
        return "tau", {"X": p("surge_n"), "Y": p("sway_n"), "N": p("yaw_nm")}
    return "mode", str(fault.params["mode"])


def _check_params(kind: str, params: Mapping[str, Any]) -> dict[str, float | str]:
    if not isinstance(params, Mapping):
        raise ValueError(f"params: expected a mapping of parameter names to numbers, got {params!r}")
    allowed = _PARAMS[kind]
    out: dict[str, float | str] = {}
    for name, value in params.items():
        if name not in allowed:
            expected = ", ".join(allowed) if allowed else "none"
            raise ValueError(f"{name}: not a parameter of a {kind} fault (expected: {expected})")
        if name in _TEXT:
            if not isinstance(value, str) or not value:
                raise ValueError(f"{name}: must be non-empty text, got {value!r}")
            out[name] = value
            continue
        number = _number(name, value)
        if not math.isfinite(number):
            raise ValueError(f"{name}: must be finite, got {value!r}")
        if name in _NON_NEGATIVE and number < 0.0:
            raise ValueError(f"{name}: must be >= 0, got {value!r}")
        if name in _PROBABILITY and not 0.0 <= number <= 1.0:
            raise ValueError(f"{name}: must be a probability in [0, 1], got {value!r}")
        if name == "max_bytes" and (number != int(number) or not 1 <= number <= 4096):
            raise ValueError(f"max_bytes: must be a whole number of bytes in 1..4096, got {value!r}")
        if name == "quality" and number not in QUALITY_MODES:
            raise ValueError(f"quality: must be a GGA quality indicator 0..8, got {value!r}")
        if name == "lat_deg" and not -90.0 <= number <= 90.0:
            raise ValueError(f"lat_deg: must be in -90..90, got {value!r}")
        if name == "lon_deg" and not -180.0 <= number <= 180.0:
            raise ValueError(f"lon_deg: must be in -180..180, got {value!r}")
        out[name] = number
    needed = [name for name, default in allowed.items() if default is None]
    if kind in _NEEDS_ONE and not any(name in out for name in needed):
        raise ValueError(f"params: a {kind} fault needs at least one of {', '.join(needed)}")
    for name, default in allowed.items():
        if default is not None:
            out.setdefault(name, default)
    return out


def _replace_data(em: Emission, data: bytes, *, t_measured: float | None = None) -> Emission:
    return dataclasses.replace(em, data=data, t_measured=em.t_measured if t_measured is None else t_measured)


def _corrupt(protocol: str, data: bytes) -> bytes:
    """The same bytes with a wrong checksum (NMEA) or CRC (MAVLink); other bytes are left as they are."""
    if protocol == "nmea":
        try:
            return corrupt_checksum(data.decode("ascii")).encode("ascii")
        except (UnicodeDecodeError, ValueError):
            return data
    if protocol == "mavlink" and len(data) >= 8:
        if data[0] == 0xFD:
            crc_at = 10 + data[1]
        elif data[0] == 0xFE:
            crc_at = 6 + data[1]
        else:
            return data
        if len(data) < crc_at + 2:
            return data
        out = bytearray(data)
        out[crc_at] ^= 0xFF
        out[crc_at + 1] ^= 0xFF
        return bytes(out)
    return data


def _garbage(em: Emission, max_bytes: int, rng: np.random.Generator) -> bytes:
    """1..max_bytes of junk of one of three sorts: line noise (any byte value, as at a wrong baud rate),
    printable text with NMEA's framing characters (``$``, ``,``, ``*``, CR/LF) mixed in, or the beginning of
    the emission's own sentence/frame cut off before its end. Never a complete valid sentence or frame."""
    n = int(rng.integers(1, max_bytes + 1))
    sort = int(rng.integers(3))
    if sort == 0:
        blob = rng.integers(0, 256, size=n, dtype=np.uint8).tobytes()
    elif sort == 1:
        alphabet = np.frombuffer(b"$$,,**\r\n0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ.-", dtype=np.uint8)
        blob = alphabet[rng.integers(0, len(alphabet), size=n)].tobytes()
    else:
        # a partial sentence: cut before the checksum (NMEA) or before the CRC (MAVLink) of the real thing
        end = em.data.find(b"*") if em.protocol == "nmea" else len(em.data) - 2
        if end <= 1:
            end = len(em.data) - 1
        cut = int(rng.integers(1, max(2, min(end, n) + 1)))
        blob = em.data[:cut]
        if em.protocol == "nmea" and rng.random() < 0.5:
            blob += b"\r\n"
    return _defuse(em.protocol, blob)


def _defuse(protocol: str, blob: bytes) -> bytes:
    """Make sure random junk does not happen to contain a valid sentence or frame."""
    if protocol == "mavlink":
        while parse_frames(blob):
            blob = blob.replace(b"\xfd", b"\x00", 1).replace(b"\xfe", b"\x00", 1)
        return blob
    for match in _SENTENCE_RE.finditer(blob):
        body = match.group(1)
        if body.isascii() and checksum(body.decode("ascii")) == match.group(2).decode("ascii").upper():
            return _defuse(protocol, blob[: match.start()] + b"#" + blob[match.start() + 1 :])
    return blob
