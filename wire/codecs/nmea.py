"""NMEA 0183 sentence decoding: one sentence's text in, a typed sentence in SI units (or a reject) out.

The decoding half of the NMEA codec; :mod:`wire.codecs.nmea_framing` finds the sentences in the byte
stream, :func:`decode` reads one. Units change here and only here (DESIGN.md rule 3): ``ddmm.mmmm``
latitude/longitude become signed decimal degrees, knots become m/s, degrees of heading and course become
radians in [-π, π), degrees per minute become rad/s, ``hhmmss.ss`` becomes seconds of the UTC day. Bad input
is never raised (rule 4): :func:`decode` returns a :class:`Reject` with a stable ``reason`` that the caller
counts per source, and a ``detail`` for the log.

Reject reasons (:data:`REJECT_REASONS`):

=============== ================================================================================
``no_checksum``  no ``*HH`` (only with ``require_checksum=True``, the default)
``bad_checksum`` the checksum does not match, or ``*`` is not followed by exactly two hex digits
``bad_format``   not a sentence: no ``$``/``!``, non-ASCII text, a malformed address field, or fewer
                 fields than the sentence type needs
``unsupported``  a well-formed sentence of a type dpgw does not use (GSA, GSV, GLL, proprietary
                 ``$P...`` other than PASHR/PHTRO, AIS ``!AIVDM``, ...): counted, not an error
``bad_field``    a field of a supported sentence does not parse or is out of range; ``detail`` names it
=============== ================================================================================

A field a receiver leaves empty is not an error: it decodes as ``None``, and a sentence without a usable
measurement comes back with ``valid=False`` (GGA quality 0, RMC status V, THS mode V, an empty HDT).

Supported sentence types, any talker (``GP``, ``GN``, ``GL``, ``GA``, ``GB``, ``BD``, ``HE``, ``HC``, ``IN``,
``II``, ``WI``, ...): GGA, GNS, RMC, VTG, GST, ZDA (:class:`Gga`, :class:`Gns`, :class:`Rmc`, :class:`Vtg`,
:class:`Gst`, :class:`Zda`), HDT, THS, HDG (:class:`Heading`), ROT (:class:`Rot`), MWV and VWR (:class:`Mwv`,
wind speed and angle: knots, km/h and statute mph become m/s); and two proprietary motion reference unit
(MRU) sentences, ``$PASHR`` and ``$PHTRO`` (:class:`Attitude`: roll and pitch in dpgw's signs, starboard
down and bow up positive). The layouts are the
ones :mod:`wire.codecs.nmea_encode` writes (NMEA 0183 v4.10), read leniently: missing trailing fields
are empty, extra trailing fields (newer NMEA versions) are ignored. ``docs/nmea.md`` has the details.

Speed matters (replay runs at 100,000 sentences/s): one ``split(',')`` per sentence, no regular
expressions, a checksum folded on a big integer instead of a byte loop, and the fast constructors below.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from datetime import UTC, date, datetime, timedelta
from typing import Any, Final, Literal, TypeAlias, TypeVar

from mypy_extensions import mypyc_attr

from observers.kinematics import ssa_scalar
from wire.codecs.nmea_encode import checksum
from wire.codecs.nmea_time import parse_time_of_day

NO_CHECKSUM: Final = "no_checksum"
BAD_CHECKSUM: Final = "bad_checksum"
BAD_FORMAT: Final = "bad_format"
UNSUPPORTED: Final = "unsupported"
BAD_FIELD: Final = "bad_field"
REJECT_REASONS: Final = (NO_CHECKSUM, BAD_CHECKSUM, BAD_FORMAT, UNSUPPORTED, BAD_FIELD)
"""Every :attr:`Reject.reason`: stable strings, counted per source in ``<prefix>/status``."""

MPS_PER_KNOT: Final = 1852.0 / 3600.0
"""1 knot in m/s (1 international nautical mile = 1852 m)."""

_RAD: Final = math.pi / 180.0
_PI: Final = math.pi
_TWO_PI: Final = 2.0 * math.pi
_INF: Final = math.inf
_RAD_S_PER_DEG_MIN: Final = math.pi / 180.0 / 60.0


# ---------------------------------------------------------------------------------------------- results


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class Reject:
    """A sentence :func:`decode` could not use: ``reason`` is one of :data:`REJECT_REASONS`, ``detail`` a
    short human-readable explanation for the log (not stable: do not parse it)."""

    reason: str
    detail: str


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Gga:
    """GGA, GNSS fix data. ``valid``: quality ≥ 1 and a position; quality 0 or an empty position is a
    sentence without a measurement (``valid=False``), not a reject."""

    kind: Literal["GGA"] = field(default="GGA", init=False)
    talker: str
    time_s: float | None
    """UTC time of the fix, seconds of the UTC day."""
    lat_deg: float | None
    """Latitude, degrees, north positive (WGS-84)."""
    lon_deg: float | None
    """Longitude, degrees, east positive."""
    quality: int
    """GPS quality indicator (``nmea_encode.GGA_QUALITY``): 0 no fix, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK
    float, 6 dead reckoning, ... An empty field reads as 0."""
    n_sats: int | None
    hdop: float | None
    alt_m: float | None
    """Antenna altitude above mean sea level (the geoid), m."""
    geoid_sep_m: float | None
    """Geoid above the WGS-84 ellipsoid, m."""
    age_s: float | None
    """Age of the differential corrections, s."""
    station_id: int | None
    valid: bool


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Gns:
    """GNS, GNSS fix data with one mode character per constellation. ``valid``: a position and at least
    one mode character other than ``N``."""

    kind: Literal["GNS"] = field(default="GNS", init=False)
    talker: str
    time_s: float | None
    lat_deg: float | None
    lon_deg: float | None
    mode: str
    """Mode indicators, GPS, GLONASS, Galileo, BDS, QZSS, NavIC order (``N`` no fix, ``A``, ``D``, ``R`` RTK
    fixed, ``F`` RTK float, ``E``, ...); may be empty."""
    n_sats: int | None
    hdop: float | None
    alt_m: float | None
    geoid_sep_m: float | None
    age_s: float | None
    station_id: int | None
    nav_status: str | None
    """NMEA 4.10 navigational status (``S``, ``C``, ``U``, ``V``) or ``None``."""
    valid: bool


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Rmc:
    """RMC, recommended minimum GNSS data. ``valid``: status ``A``, a position, and a mode (if sent) other
    than ``N``; status ``V`` gives ``valid=False``. ``nav_status`` is reported, not used for ``valid``."""

    kind: Literal["RMC"] = field(default="RMC", init=False)
    talker: str
    time_s: float | None
    date: date | None
    """UTC date; two-digit years are 1980-2079."""
    valid: bool
    lat_deg: float | None
    lon_deg: float | None
    sog_mps: float | None
    """Speed over ground, m/s."""
    cog_rad: float | None
    """Course over ground, true, rad in [-π, π) (clockwise from true north)."""
    mode: str | None
    """Mode indicator (NMEA 2.3+), ``None`` when the receiver sends none."""
    mag_var_rad: float | None
    """Magnetic variation, rad, east positive."""
    nav_status: str | None


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Vtg:
    """VTG, course and speed over ground. ``valid``: a speed and a mode (if sent) other than ``N``; the
    course may be ``None`` while valid (receivers leave it empty at rest)."""

    kind: Literal["VTG"] = field(default="VTG", init=False)
    talker: str
    cog_rad: float | None
    """Course over ground, true, rad in [-π, π)."""
    sog_mps: float | None
    """Speed over ground, m/s (from the knots field, or km/h when knots are empty)."""
    mode: str | None
    valid: bool


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Gst:
    """GST, GNSS pseudorange error statistics (1σ, metres). Empty fields are ``None``."""

    kind: Literal["GST"] = field(default="GST", init=False)
    talker: str
    time_s: float | None
    rms_m: float | None
    sigma_major_m: float | None
    sigma_minor_m: float | None
    orient_rad: float | None
    """Orientation of the semi-major axis, clockwise from true north, rad in [0, π)."""
    sigma_lat_m: float | None
    sigma_lon_m: float | None
    sigma_alt_m: float | None


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Zda:
    """ZDA, UTC time and date. The local zone fields are ignored (dpgw runs on UTC)."""

    kind: Literal["ZDA"] = field(default="ZDA", init=False)
    talker: str
    time_s: float | None
    date: date | None
    utc: datetime | None
    """Time and date as an aware UTC datetime (``None`` if either is empty)."""


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Heading:
    """HDT, THS (true heading) or HDG (magnetic compass).

    ``heading_rad`` is clockwise from north in [-π, π). For HDT and THS it is true heading. For HDG it is
    sensor heading + deviation (the magnetic heading, ``magnetic=True``), plus the variation when the
    sentence gives it (then true heading, ``magnetic=False``). ``valid`` is False for an empty heading and
    for THS mode ``V``; ``mode`` is THS's mode indicator (``A``, ``E``, ``M``, ``S``, ``V``), ``None`` for
    HDT and HDG."""

    kind: Literal["HDT", "THS", "HDG"]
    talker: str
    heading_rad: float | None
    valid: bool
    mode: str | None
    magnetic: bool = False


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Mwv:
    """MWV, wind speed and angle (an anemometer). ``angle_rad`` is the direction the wind comes *from*,
    clockwise from the bow, in [-π, π) (0: on the bow, +π/2: from starboard); ``speed_mps`` in m/s whatever
    unit was sent (K km/h, M m/s, N knots, S statute miles per hour). ``reference`` is ``R`` (relative: the
    apparent wind the vessel feels, its own velocity included) or ``T`` (theoretical: the true wind,
    still given relative to the bow). ``valid``: status ``A`` with an angle, a reference and a speed;
    status ``V`` or an empty field gives ``valid=False``.

    The older VWR (relative wind, the angle 0-180° with ``L``/``R`` for the side) decodes to the same class
    with ``kind`` ``"VWR"``, ``reference`` ``"R"``, and ``valid`` for an angle, a side and a speed (VWR has
    no status field)."""

    kind: Literal["MWV", "VWR"] = field(default="MWV", init=False)
    talker: str
    angle_rad: float | None
    reference: str | None
    speed_mps: float | None
    valid: bool


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Rot:
    """ROT, rate of turn in rad/s (positive: bow to starboard). ``valid``: a rate and status ``A``."""

    kind: Literal["ROT"] = field(default="ROT", init=False)
    talker: str
    rate_rad_s: float | None
    valid: bool


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Attitude:
    """A motion reference unit's (MRU's) attitude: proprietary ``$PASHR`` (Applanix POS MV, Hemisphere,
    OxTS, Trimble: time, true heading, roll, pitch, heave, their 1σ, aiding and IMU status) or ``$PHTRO``
    (iXblue Octans / Phins: pitch and roll as magnitudes with side letters).

    dpgw's signs, whatever the sentence: ``roll_rad`` positive starboard down (port up), ``pitch_rad``
    positive bow up (Fossen's φ and θ of the NED/body frames); ``heave_up_m`` positive up, as PASHR sends
    it. PASHR's signs are these already (roll + port up, pitch + bow up, heave + up); PHTRO's letters map
    ``M`` (bow up) → +pitch, ``P`` (bow down) → −pitch, ``T`` (port up, starboard down) → +roll, ``B``
    (port down) → −roll. ``valid``: roll and pitch both present. ``talker`` is ``""`` (a proprietary
    sentence has none: its address is ``P``, the manufacturer and the type)."""

    kind: Literal["PASHR", "PHTRO"]
    talker: str
    time_s: float | None
    """UTC time of the measurement, seconds of the UTC day (PASHR; None for PHTRO, which carries none)."""
    roll_rad: float | None
    pitch_rad: float | None
    heading_rad: float | None
    """True heading in [-π, π) (PASHR, when its field 3 is ``T``); None for PHTRO."""
    heave_up_m: float | None
    roll_sigma_rad: float | None
    pitch_sigma_rad: float | None
    heading_sigma_rad: float | None
    aiding: int | None
    """PASHR field 10, GNSS aiding status (0 none, 1 GNSS, 2 GNSS and heading aiding): reported, not used."""
    imu: int | None
    """PASHR field 11, the IMU status flag: reported, not used (vendors give it opposite meanings)."""
    valid: bool


Sentence: TypeAlias = Gga | Gns | Rmc | Vtg | Gst | Zda | Heading | Rot | Mwv | Attitude
"""What :func:`decode` returns for a sentence it uses; ``kind`` tells them apart."""

SENTENCE_TYPES: Final = ("GGA", "GNS", "RMC", "VTG", "GST", "ZDA", "HDT", "THS", "HDG", "ROT", "MWV", "VWR")
"""The sentence formatters :func:`decode` decodes; every other well-formed sentence is ``unsupported``."""

PROPRIETARY_TYPES: Final = ("PASHR", "PHTRO")
"""The proprietary sentences (whole address fields) :func:`decode` decodes: MRU attitude (`Attitude`);
every other proprietary sentence is ``unsupported``."""


# ---------------------------------------------------------------------------------------------- construction

_T = TypeVar("_T")


def _fast_new(cls: type[_T]) -> Callable[..., _T]:
    """A constructor for the frozen dataclass ``cls`` taking all its fields positionally, in declaration
    order (``kind`` included), that sets the instance dict in one step instead of one
    ``object.__setattr__`` per field as a frozen dataclass's ``__init__`` does: ~2x faster for GGA. The
    result is an ordinary instance, equal to and hashing as one made with ``cls(...)`` (tested). Generated
    source, as ``dataclasses`` itself generates ``__init__``."""
    names = [f.name for f in fields(cls)]  # type: ignore[arg-type]
    items = ", ".join(f"{name!r}: {name}" for name in names)
    source = (
        f"def make({', '.join(names)}):\n"
        f"    obj = new(cls)\n"
        f"    set_dict(obj, '__dict__', {{{items}}})\n"
        f"    return obj\n"
    )
    namespace: dict[str, Any] = {"new": object.__new__, "set_dict": object.__setattr__, "cls": cls}
    exec(source, namespace)
    make: Callable[..., _T] = namespace["make"]
    return make


# ---------------------------------------------------------------------------------------------- decode


class _Unused:
    """A good sentence (format and checksum checked) of a type the caller did not ask for."""

    def __repr__(self) -> str:
        return "UNUSED"


UNUSED: Final = _Unused()


def decode(
    text: str,
    *,
    require_checksum: bool = True,
    only: frozenset[str] | None = None,
    verified: bool = False,
) -> Sentence | Reject | _Unused:
    """Decode one sentence, ``$`` to checksum (a :class:`Frame`'s ``text``; a trailing CR/LF is ignored).

    Returns a typed sentence (:data:`Sentence`) or a :class:`Reject`; never raises. With
    ``require_checksum=False`` a sentence without ``*HH`` is accepted (some gyros send none); a checksum
    that is present is always checked. With ``only`` (sentence formatters such as ``{"GGA", "HDT"}``), a
    good sentence of another type is not parsed field by field: `UNUSED` is returned (replay skips the
    work for sentences the pipeline does not use; checksum failures are still rejects). ``verified=True``:
    the caller has already checked the checksum (replay's compiled line scan) and it is not recomputed.
    """
    try:
        if len(text) < 2 or text[0] not in "$!" or not text.isascii():
            return Reject(BAD_FORMAT, f"not an NMEA sentence: {text[:40]!r}")
        star = text.find("*")
        if star < 0:
            if text.endswith(_EOL):  # (off the hot path)
                return decode(text.rstrip("\r\n"), require_checksum=require_checksum)
            if require_checksum:
                return Reject(NO_CHECKSUM, f"no checksum: {text[:40]!r}")
            body = text[1:]
        else:
            body = text[1:star]
            given = _HEX.get(text[star + 1 :])
            if given is None:
                if text.endswith(_EOL):
                    return decode(text.rstrip("\r\n"), require_checksum=require_checksum)
                return Reject(BAD_CHECKSUM, f"checksum field {text[star + 1 :][:8]!r} is not two hex digits")
            if not verified and _xor(body) != given:
                return Reject(BAD_CHECKSUM, f"checksum {text[star + 1 :]}, computed {checksum(body)}")
        if only is not None and body[2:5] not in only and body[:1] != "P":
            return UNUSED
        parts = body.split(",")
        entry = _ADDRESSES.get(parts[0])
        if entry is None:
            entry = _address(parts[0])
        if isinstance(entry, Reject):
            return entry
        talker, decoder = entry
        return decoder(talker, parts)
    except Exception as exc:  # pragma: no cover - a bug must not stop the gateway (DESIGN.md rule 4)
        return Reject(BAD_FORMAT, f"decoder error {exc!r} on {text[:40]!r}")


def _hex_table() -> dict[str, int]:
    digits = "0123456789abcdefABCDEF"
    return {a + b: int(a + b, 16) for a in digits for b in digits}


_HEX: Final = _hex_table()
_EOL: Final = ("\r", "\n")


def _xor(body: str) -> int:
    """XOR of the bytes of ``body`` (ASCII): the NMEA checksum as an int, = ``int(checksum(body), 16)``.

    Folds the bytes as one big integer (a handful of C-level shifts) instead of a Python loop per byte."""
    x = int.from_bytes(body.encode("ascii"), "little")
    n = len(body)
    if n <= 128:
        if n > 64:
            x ^= x >> 512
        if n > 32:
            x ^= x >> 256
        if n > 16:
            x ^= x >> 128
        x ^= x >> 64
        x ^= x >> 32
        x ^= x >> 16
        x ^= x >> 8
        return x & 0xFF
    value = 0
    for byte in body.encode("ascii"):
        value ^= byte
    return value


_Decoder: TypeAlias = Callable[[str, list[str]], Sentence | Reject]
_ADDRESSES: dict[str, tuple[str, _Decoder] | Reject] = {}
_ADDRESS_CACHE_MAX = 4096


def _address(address: str) -> tuple[str, _Decoder] | Reject:
    """Classify an address field: ``(talker, decoder)`` or a :class:`Reject` (cached)."""
    entry: tuple[str, _Decoder] | Reject
    if len(address) == 5 and address.isalnum() and address.isupper() and address[0] != "P":
        talker, kind = address[:2], address[2:]
        decoder = _DECODERS.get(kind)
        if not talker[0].isalpha() or not kind.isalpha():
            entry = Reject(BAD_FORMAT, f"bad address field {address!r}")
        elif decoder is None:
            entry = Reject(UNSUPPORTED, kind)
        else:
            entry = (talker, decoder)
    elif address in _PROPRIETARY:
        entry = ("", _PROPRIETARY[address])  # (a proprietary sentence has no talker id)
    elif address[:1] == "P" and address.isalnum() and address.isupper() and len(address) >= 2:
        entry = Reject(UNSUPPORTED, f"proprietary {address}")
    else:
        entry = Reject(BAD_FORMAT, f"bad address field {address[:12]!r}")
    if len(_ADDRESSES) < _ADDRESS_CACHE_MAX:
        _ADDRESSES[address] = entry
    return entry


def _too_few(kind: str, parts: list[str], needed: int) -> Reject:
    return Reject(BAD_FORMAT, f"{kind} has {len(parts) - 1} fields, needs at least {needed}")


def _bad_field(kind: str, names: dict[int, str], i: int, parts: list[str]) -> Reject:
    """``bad_field``, naming field ``i`` (and the fields that go with it: a hemisphere, a date)."""
    name = names.get(i, "field")
    value = ",".join(parts[i : i + _WIDTH.get(name, 1)])
    return Reject(BAD_FIELD, f"{kind} {name} (field {i}): {value[:40]!r}")


_WIDTH: Final = {
    "latitude": 2,
    "longitude": 2,
    "magnetic variation": 2,
    "deviation": 2,
    "variation": 2,
    "day,month,year": 3,
    "wind speed": 2,
    "wind angle and side": 2,
    "pitch and side": 2,
    "roll and side": 2,
}
_PAD: Final = [""] * 16

_Field = tuple[int, str, Callable[..., Any], int | None]
"""One field of a sentence layout: its index, its name (for rejects), its parser, and the index of the
field that goes with it (a hemisphere, a direction) or None."""


def _fields(kind: str, p: list[str], least: int, full: int, layout: tuple[_Field, ...]) -> list[Any] | Reject:
    """The values of ``layout``'s fields of sentence ``p`` (address first), or a reject: ``too few`` below
    ``least`` parts; missing trailing fields up to ``full`` parts are empty; a parser's ValueError (or
    KeyError, for lookups) is a ``bad_field`` naming the field."""
    n = len(p)
    if n < least:
        return _too_few(kind, p, least - 1)
    if n < full:
        p += _PAD[: full - n]
    values = []
    i = 0
    try:
        for i, _, parse, j in layout:
            values.append(parse(p[i]) if j is None else parse(p[i], p[j]))
    except (ValueError, KeyError):
        return _bad_field(kind, {f[0]: f[1] for f in layout}, i, p)
    return values


# ---------------------------------------------------------------------------------------------- fields
# Each parser takes the field text and returns the value or None (empty field); anything else raises
# ValueError, which the sentence decoders turn into a bad_field reject naming the field.


def _float(s: str) -> float | None:
    """Optional finite float."""
    if not s:
        return None
    x = float(s)
    if x - x:  # NaN or infinity
        raise ValueError(s)
    return x


def _nonneg(s: str) -> float | None:
    """Optional finite float ≥ 0."""
    if not s:
        return None
    x = float(s)
    if not 0.0 <= x < _INF:
        raise ValueError(s)
    return x


def _count(s: str) -> int | None:
    """Optional non-negative integer (digits only)."""
    if not s:
        return None
    if not s.isdigit():
        raise ValueError(s)
    return int(s)


def _degrees_minutes(s: str, hemisphere: str, limit: float, plus: str, minus: str) -> float | None:
    """``d…dmm.mmmm`` + hemisphere → signed degrees within ±limit (full precision: the whole field is one
    float)."""
    if not s:
        return None
    v = float(s)
    degrees = v // 100.0
    minutes = v - 100.0 * degrees
    if not (v >= 0.0 and minutes < 60.0):
        raise ValueError(s)
    angle = degrees + minutes / 60.0
    if angle > limit:
        raise ValueError(s)
    if hemisphere == plus:
        return angle
    if hemisphere == minus:
        return -angle
    raise ValueError(hemisphere)


def _lat(s: str, hemisphere: str) -> float | None:
    """``ddmm.mmmm`` + ``N``/``S`` → degrees."""
    return _degrees_minutes(s, hemisphere, 90.0, "N", "S")


def _lon(s: str, hemisphere: str) -> float | None:
    """``dddmm.mmmm`` + ``E``/``W`` → degrees."""
    return _degrees_minutes(s, hemisphere, 180.0, "E", "W")


def _bearing(s: str) -> float | None:
    """Degrees in [0, 360] → rad in [-π, π)."""
    if not s:
        return None
    v = float(s)
    if not 0.0 <= v <= 360.0:
        raise ValueError(s)
    angle = v * _RAD
    if angle >= _PI:
        angle -= _TWO_PI
    return angle


def _east_west(s: str, direction: str) -> float | None:
    """Magnitude in degrees (≤ 180) + ``E``/``W`` → degrees, east positive."""
    if not s:
        return None
    v = float(s)
    if not 0.0 <= v <= 180.0:
        raise ValueError(s)
    if direction == "E":
        return v
    if direction == "W":
        return -v
    raise ValueError(direction)


def _letter(s: str) -> str | None:
    """Optional single upper-case letter (mode indicators, status)."""
    if not s:
        return None
    if s not in _LETTERS:
        raise ValueError(s)
    return s


_LETTERS: Final = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZ")


_DATES: dict[str, date] = {}


def _ddmmyy(s: str) -> date | None:
    """``ddmmyy`` → date; two-digit years are 1980-2079."""
    if not s:
        return None
    d = _DATES.get(s)
    if d is None:
        if len(s) != 6 or not s.isdigit():
            raise ValueError(s)
        yy = int(s[4:])
        d = date(2000 + yy if yy < 80 else 1900 + yy, int(s[2:4]), int(s[:2]))
        if len(_DATES) < 4096:
            _DATES[s] = d
    return d


# ---------------------------------------------------------------------------------------------- sentences

_new_gga = _fast_new(Gga)
_new_gns = _fast_new(Gns)
_new_rmc = _fast_new(Rmc)
_new_vtg = _fast_new(Vtg)
_new_heading = _fast_new(Heading)

_QUALITY: Final = {str(q): q for q in range(10)} | {"": 0}


_GGA_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "time", parse_time_of_day, None),
    (2, "latitude", _lat, 3),
    (4, "longitude", _lon, 5),
    (6, "quality", _QUALITY.__getitem__, None),  # KeyError for anything but one digit or empty
    (7, "satellites", _count, None),
    (8, "hdop", _nonneg, None),
    (9, "altitude", _float, None),
    (11, "geoid separation", _float, None),
    (13, "age", _nonneg, None),
    (14, "station id", _count, None),
)


def _gga_reference(talker: str, p: list[str]) -> Gga | Reject:
    """``$--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,x,xx,x.x,x.x,M,x.x,M,x.x,xxxx`` by the generic layout walk:
    the readable form of `_gga` (tests/test_nmea_decode.py checks that both agree)."""
    v = _fields("GGA", p, 7, 15, _GGA_LAYOUT)
    if isinstance(v, Reject):
        return v
    _, lat, lon, quality = v[:4]
    return _new_gga("GGA", talker, *v, quality >= 1 and lat is not None and lon is not None)


_GGA_NAMES: Final = {f[0]: f[1] for f in _GGA_LAYOUT}


def _gga(talker: str, p: list[str]) -> Gga | Reject:
    """``$--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,x,xx,x.x,x.x,M,x.x,M,x.x,xxxx``: `_GGA_LAYOUT` unrolled.

    Every cycle of a DGPS has a GGA, and walking the layout (a tuple unpacked, a test and an append per
    field) cost as much as parsing the fields; this does the same parsers in the same order, with the same
    reject naming the first bad field."""
    n = len(p)
    if n < 7:
        return _too_few("GGA", p, 6)
    if n < 15:
        p += _PAD[: 15 - n]
    i = 1
    try:
        time_s = parse_time_of_day(p[1])
        i = 2
        lat = _degrees_minutes(p[2], p[3], 90.0, "N", "S")  # (`_lat`)
        i = 4
        lon = _degrees_minutes(p[4], p[5], 180.0, "E", "W")  # (`_lon`)
        i = 6
        quality = _QUALITY[p[6]]  # KeyError for anything but one digit or empty
        i = 7
        n_sats = _count(p[7])
        i = 8
        hdop = _nonneg(p[8])
        i = 9
        alt_m = _float(p[9])
        i = 11
        geoid_sep_m = _float(p[11])
        i = 13
        age_s = _nonneg(p[13])
        i = 14
        station = _count(p[14])
    except (ValueError, KeyError):
        return _bad_field("GGA", _GGA_NAMES, i, p)
    valid = quality >= 1 and lat is not None and lon is not None
    return _new_gga(
        "GGA", talker, time_s, lat, lon, quality, n_sats, hdop, alt_m, geoid_sep_m, age_s, station, valid
    )


def _gns_mode(s: str) -> str:
    """The GNS mode indicator: upper-case letters, one per constellation (may be empty)."""
    if s and not (s.isalpha() and s.isupper()):
        raise ValueError(s)
    return s


_GNS_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "time", parse_time_of_day, None),
    (2, "latitude", _lat, 3),
    (4, "longitude", _lon, 5),
    (6, "mode", _gns_mode, None),
    (7, "satellites", _count, None),
    (8, "hdop", _nonneg, None),
    (9, "altitude", _float, None),
    (10, "geoid separation", _float, None),
    (11, "age", _nonneg, None),
    (12, "station id", _count, None),
    (13, "navigational status", _letter, None),
)


def _gns(talker: str, p: list[str]) -> Gns | Reject:
    """``$--GNS,hhmmss.ss,llll.ll,a,yyyyy.yy,a,c--c,xx,x.x,x.x,x.x,x.x,x.x,a``"""
    v = _fields("GNS", p, 7, 14, _GNS_LAYOUT)
    if isinstance(v, Reject):
        return v
    _, lat, lon, mode = v[:4]
    return _new_gns("GNS", talker, *v, lat is not None and lon is not None and mode.strip("N") != "")


def _status(s: str) -> str:
    """An A (valid) / V (void) status field, or empty."""
    if s != "A" and s != "V" and s:
        raise ValueError(s)
    return s


_RMC_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "time", parse_time_of_day, None),
    (2, "status", _status, None),
    (3, "latitude", _lat, 4),
    (5, "longitude", _lon, 6),
    (7, "speed", _nonneg, None),
    (8, "course", _bearing, None),
    (9, "date", _ddmmyy, None),
    (10, "magnetic variation", _east_west, 11),
    (12, "mode", _letter, None),
    (13, "navigational status", _letter, None),
)


def _rmc(talker: str, p: list[str]) -> Rmc | Reject:
    """``$--RMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,x.x,a,a,a``"""
    v = _fields("RMC", p, 3, 14, _RMC_LAYOUT)
    if isinstance(v, Reject):
        return v
    time_s, status, lat, lon, sog, cog, day, var, mode, nav_status = v
    valid = status == "A" and lat is not None and lon is not None and mode != "N"
    return _new_rmc(
        "RMC",
        talker,
        time_s,
        day,
        valid,
        lat,
        lon,
        None if sog is None else sog * MPS_PER_KNOT,
        cog,
        mode,
        None if var is None else var * _RAD,
        nav_status,
    )


_VTG_NAMES = {1: "course true", 3: "course magnetic", 5: "speed knots", 7: "speed km/h", 9: "mode"}
_VTG_OLD_NAMES = {1: "course true", 2: "course magnetic", 3: "speed knots", 4: "speed km/h"}


def _vtg(talker: str, p: list[str]) -> Vtg | Reject:
    """``$--VTG,x.x,T,x.x,M,x.x,N,x.x,K,a`` (also the NMEA 1.5 layout ``$--VTG,x.x,x.x,x.x,x.x``)."""
    n = len(p)
    if n >= 9 or (n > 2 and p[2] == "T"):
        if n < 10:
            p += _PAD[: 10 - n]
        names = _VTG_NAMES
        knots, kmh, mode_field = 5, 7, 9
    elif n == 5:
        names = _VTG_OLD_NAMES
        knots, kmh, mode_field = 3, 4, 0
    else:
        return _too_few("VTG", p, 8)
    i = 1
    try:
        cog = _bearing(p[1])
        i = knots
        sog = _nonneg(p[knots])
        if sog is not None:
            sog *= MPS_PER_KNOT
        else:
            i = kmh
            sog = _nonneg(p[kmh])
            if sog is not None:
                sog /= 3.6
        i = mode_field
        mode = _letter(p[9]) if mode_field else None
    except ValueError:
        return _bad_field("VTG", names, i, p)
    valid = sog is not None and mode != "N"
    return _new_vtg("VTG", talker, cog, sog, mode, valid)


_GST_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "time", parse_time_of_day, None),
    (2, "rms", _nonneg, None),
    (3, "sigma major", _nonneg, None),
    (4, "sigma minor", _nonneg, None),
    (5, "orientation", _float, None),
    (6, "sigma latitude", _nonneg, None),
    (7, "sigma longitude", _nonneg, None),
    (8, "sigma altitude", _nonneg, None),
)


def _gst(talker: str, p: list[str]) -> Gst | Reject:
    """``$--GST,hhmmss.ss,x.x,x.x,x.x,x.x,x.x,x.x,x.x``"""
    v = _fields("GST", p, 9, 9, _GST_LAYOUT)
    if isinstance(v, Reject):
        return v
    time_s, rms, major, minor, orient, sigma_lat, sigma_lon, sigma_alt = v
    if orient is not None:
        orient = (orient * _RAD) % _PI
        if orient >= _PI:  # rounding of a tiny negative angle
            orient = 0.0
    return Gst(talker, time_s, rms, major, minor, orient, sigma_lat, sigma_lon, sigma_alt)


_ZDA_NAMES = {1: "time", 2: "day,month,year"}


def _zda(talker: str, p: list[str]) -> Zda | Reject:
    """``$--ZDA,hhmmss.ss,xx,xx,xxxx,xx,xx``"""
    if len(p) < 5:
        return _too_few("ZDA", p, 4)
    i = 1
    try:
        time_s = parse_time_of_day(p[1])
        i = 2
        day = _count(p[2])
        month = _count(p[3])
        year = _count(p[4])
        when = None
        if day is not None and month is not None and year is not None:
            when = date(year, month, day)
    except ValueError:
        return _bad_field("ZDA", _ZDA_NAMES, i, p)
    utc = None
    if when is not None and time_s is not None:
        try:
            utc = datetime(when.year, when.month, when.day, tzinfo=UTC) + timedelta(seconds=time_s)
        except OverflowError:  # 9999-12-31 plus a day's seconds
            return _bad_field("ZDA", _ZDA_NAMES, 2, p)
    return Zda(talker, time_s, when, utc)


def _hdt(talker: str, p: list[str]) -> Heading | Reject:
    """``$--HDT,x.x,T``"""
    if len(p) < 2:
        return _too_few("HDT", p, 1)
    try:
        heading = _bearing(p[1])
    except ValueError:
        return _bad_field("HDT", _HEADING_NAMES, 1, p)
    return _new_heading("HDT", talker, heading, heading is not None, None, False)


_HEADING_NAMES = {1: "heading", 2: "mode"}
_THS_MODES: Final = frozenset("AEMSV")


def _ths_mode(s: str) -> str:
    if s not in _THS_MODES:
        raise ValueError(s)
    return s


_THS_LAYOUT: Final[tuple[_Field, ...]] = ((1, "heading", _bearing, None), (2, "mode", _ths_mode, None))


def _ths(talker: str, p: list[str]) -> Heading | Reject:
    """``$--THS,x.x,a``"""
    v = _fields("THS", p, 3, 3, _THS_LAYOUT)
    if isinstance(v, Reject):
        return v
    heading, mode = v
    return _new_heading("THS", talker, heading, heading is not None and mode != "V", mode, False)


def _sensor_heading(s: str) -> float | None:
    """The magnetic sensor heading of HDG, degrees within [0, 360]."""
    value = _float(s)
    if value is not None and not 0.0 <= value <= 360.0:
        raise ValueError(s)
    return value


_HDG_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "heading", _sensor_heading, None),
    (2, "deviation", _east_west, 3),
    (4, "variation", _east_west, 5),
)


def _hdg(talker: str, p: list[str]) -> Heading | Reject:
    """``$--HDG,x.x,x.x,a,x.x,a``"""
    v = _fields("HDG", p, 2, 6, _HDG_LAYOUT)
    if isinstance(v, Reject):
        return v
    sensor, deviation, variation = v
    heading = None
    if sensor is not None:
        heading = ssa_scalar((sensor + (deviation or 0.0) + (variation or 0.0)) * _RAD)
    return Heading("HDG", talker, heading, heading is not None, None, variation is None)


_ROT_LAYOUT: Final[tuple[_Field, ...]] = ((1, "rate of turn", _float, None), (2, "status", _status, None))


def _rot(talker: str, p: list[str]) -> Rot | Reject:
    """``$--ROT,x.x,A``"""
    v = _fields("ROT", p, 2, 3, _ROT_LAYOUT)
    if isinstance(v, Reject):
        return v
    rate, status = v
    if rate is not None:
        rate *= _RAD_S_PER_DEG_MIN
    return Rot(talker, rate, rate is not None and status == "A")


MPS_PER_UNIT: Final = {"M": 1.0, "K": 1.0 / 3.6, "N": MPS_PER_KNOT, "S": 1609.344 / 3600.0}
"""MWV's speed units in m/s: M m/s, K km/h, N knots, S statute miles per hour."""
_WIND_REFERENCES: Final = frozenset("RT")


def _wind_speed(s: str, unit: str) -> float | None:
    """A speed ≥ 0 and its unit letter → m/s (a speed without a known unit is a bad field)."""
    v = _nonneg(s)
    if v is None:
        return None
    return v * MPS_PER_UNIT[unit]  # KeyError: no or an unknown unit


def _wind_reference(s: str) -> str | None:
    if not s:
        return None
    if s not in _WIND_REFERENCES:
        raise ValueError(s)
    return s


_MWV_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "wind angle", _bearing, None),
    (2, "reference", _wind_reference, None),
    (3, "wind speed", _wind_speed, 4),
    (5, "status", _status, None),
)


def _mwv(talker: str, p: list[str]) -> Mwv | Reject:
    """``$--MWV,x.x,a,x.x,a,A``: angle (degrees from the bow, clockwise, 0-360), reference R/T, speed,
    unit K/M/N/S, status A/V. A missing status field reads as empty (not valid)."""
    v = _fields("MWV", p, 5, 6, _MWV_LAYOUT)
    if isinstance(v, Reject):
        return v
    angle, reference, speed, status = v
    valid = status == "A" and angle is not None and reference is not None and speed is not None
    return Mwv(talker, angle, reference, speed, valid)


def _side_angle(s: str, side: str) -> float | None:
    """VWR's angle: degrees [0, 180] off the bow and ``L`` (port, negative) or ``R`` (starboard) → rad."""
    if not s:
        return None
    v = float(s)
    if not 0.0 <= v <= 180.0:
        raise ValueError(s)
    if side == "R":
        return ssa_scalar(v * _RAD)
    if side == "L":
        return ssa_scalar(-v * _RAD)
    raise ValueError(side)


_VWR_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "wind angle and side", _side_angle, 2),
    (3, "speed knots", _nonneg, None),
    (5, "speed m/s", _nonneg, None),
    (7, "speed km/h", _nonneg, None),
)


def _vwr(talker: str, p: list[str]) -> Mwv | Reject:
    """``$--VWR,x.x,a,x.x,N,x.x,M,x.x,K``: relative wind angle 0-180° and side L/R, speed in knots, m/s and
    km/h (the first of m/s, knots, km/h that is given is used); decoded as an `Mwv` of kind VWR."""
    v = _fields("VWR", p, 3, 9, _VWR_LAYOUT)
    if isinstance(v, Reject):
        return v
    angle, knots, mps, kmh = v
    speed = mps if mps is not None else knots * MPS_PER_KNOT if knots is not None else None
    if speed is None and kmh is not None:
        speed = kmh / 3.6
    out = Mwv(talker, angle, "R", speed, angle is not None and speed is not None)
    object.__setattr__(out, "kind", "VWR")  # (kind is not an __init__ field)
    return out


_DECODERS: Final[dict[str, _Decoder]] = {
    "GGA": _gga,
    "GNS": _gns,
    "RMC": _rmc,
    "VTG": _vtg,
    "GST": _gst,
    "ZDA": _zda,
    "HDT": _hdt,
    "THS": _ths,
    "HDG": _hdg,
    "ROT": _rot,
    "MWV": _mwv,
    "VWR": _vwr,
}


# ---------------------------------------------------------------------------------------------- proprietary
# MRU attitude. Signs are turned into dpgw's here (roll + starboard down, pitch + bow up): the rest of dpgw
# never sees a vendor's convention.


def _signed_degrees(s: str, limit: float) -> float | None:
    """Optional signed degrees within ±limit (a leading ``+`` allowed, as POS MV sends) → rad."""
    if not s:
        return None
    v = float(s)
    if not -limit <= v <= limit:  # (NaN fails too)
        raise ValueError(s)
    return v * _RAD


def _sigma_degrees(s: str) -> float | None:
    """Optional 1σ in degrees ≥ 0 → rad."""
    v = _nonneg(s)
    return None if v is None else v * _RAD


def _true_flag(s: str) -> str:
    """PASHR field 3: ``T`` (true heading) or empty."""
    if s and s != "T":
        raise ValueError(s)
    return s


def _flag(s: str) -> int | None:
    """A single-digit status flag, or empty."""
    if not s:
        return None
    if len(s) != 1 or not s.isdigit():
        raise ValueError(s)
    return int(s)


_PASHR_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "time", parse_time_of_day, None),
    (2, "heading", _bearing, None),
    (3, "true flag", _true_flag, None),
    (4, "roll", lambda s: _signed_degrees(s, 180.0), None),
    (5, "pitch", lambda s: _signed_degrees(s, 90.0), None),
    (6, "heave", _float, None),
    (7, "roll sigma", _sigma_degrees, None),
    (8, "pitch sigma", _sigma_degrees, None),
    (9, "heading sigma", _sigma_degrees, None),
    (10, "aiding status", _flag, None),
    (11, "IMU status", _flag, None),
)


def _pashr(talker: str, p: list[str]) -> Attitude | Reject:
    """``$PASHR,hhmmss.sss,HHH.HH,T,RRR.RR,PPP.PP,heave,rr.rrr,pp.ppp,hh.hhh,a,b``: time, true heading,
    roll (+ port up), pitch (+ bow up), heave (m, + up), 1σ of roll, pitch and heading (degrees), GNSS
    aiding and IMU status. Ashtech receivers use the same address for their command replies
    (``$PASHR,POS,...``, a letter in field 1): those are ``unsupported``, not bad fields."""
    if len(p) > 1 and p[1][:1].isalpha():
        return Reject(UNSUPPORTED, f"proprietary PASHR,{p[1][:8]}")
    v = _fields("PASHR", p, 6, 12, _PASHR_LAYOUT)
    if isinstance(v, Reject):
        return v
    time_s, heading, flag, roll, pitch, heave, s_roll, s_pitch, s_heading, aiding, imu = v
    if flag != "T":
        heading = None  # a heading not marked true is not one dpgw can use
    valid = roll is not None and pitch is not None
    return Attitude(
        "PASHR", talker, time_s, roll, pitch, heading, heave, s_roll, s_pitch, s_heading, aiding, imu, valid
    )


def _side_degrees(s: str, side: str, limit: float, plus: str, minus: str) -> float | None:
    """A magnitude in degrees within [0, limit] and its side letter → signed rad."""
    if not s:
        return None
    v = float(s)
    if not 0.0 <= v <= limit:
        raise ValueError(s)
    if side == plus:
        return v * _RAD
    if side == minus:
        return -v * _RAD
    raise ValueError(side)


_PHTRO_LAYOUT: Final[tuple[_Field, ...]] = (
    (1, "pitch and side", lambda s, side: _side_degrees(s, side, 90.0, "M", "P"), 2),
    (3, "roll and side", lambda s, side: _side_degrees(s, side, 180.0, "T", "B"), 4),
)


def _phtro(talker: str, p: list[str]) -> Attitude | Reject:
    """``$PHTRO,x.xx,a,y.yy,b``: pitch magnitude, ``M`` bow up / ``P`` bow down; roll magnitude, ``B`` port
    down / ``T`` port up (iXblue's letters: French *monte*/*plonge*, *bâbord*/*tribord*)."""
    v = _fields("PHTRO", p, 5, 5, _PHTRO_LAYOUT)
    if isinstance(v, Reject):
        return v
    pitch, roll = v
    valid = roll is not None and pitch is not None
    return Attitude("PHTRO", talker, None, roll, pitch, None, None, None, None, None, None, None, valid)


_PROPRIETARY: Final[dict[str, _Decoder]] = {"PASHR": _pashr, "PHTRO": _phtro}
