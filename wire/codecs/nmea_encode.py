"""NMEA 0183 sentence encoders: SI units, radians and UTC in, one complete sentence out.

What the simulator's GNSS receivers and gyro compasses emit, and what fault injection starts from. Every
function is pure and returns ``$<talker><type>,<fields>*<HH>\\r\\n``; the talker id is a parameter (``GP``,
``GN`` GNSS, ``HE`` gyro, ``HC`` magnetic compass, ``IN`` integrated navigation, ...). Units change here and
only here (DESIGN.md rule 3): latitude/longitude in signed decimal degrees become ``ddmm.mmmmmm,N``/
``dddmm.mmmmmm,E``, speeds in m/s become knots (and km/h), angles in radians become degrees, rates of turn
in rad/s become degrees per minute.

Layouts follow NMEA 0183 v4.10 (field numbers in the docstrings are 1-based after the address field).
Formatting decisions:

* Latitude and longitude carry ``decimals`` decimals of minutes, default 6 (1e-6 min ≈ 1.9 mm, enough for
  RTK). Degrees and minutes are derived from one rounded integer, so rounding carries correctly
  (59.9999996' prints as the next whole degree, never as ``60.000000``).
* Times are ``hhmmss.ss`` (``time_decimals``, default 2), rounded to the nearest unit; the date printed by
  RMC and ZDA comes from the same rounded instant, so 23:59:59.996 becomes 00:00:00.00 of the next day.
  A naive ``datetime`` is taken as UTC; an aware one is converted to UTC.
* Headings and courses are in [0, 360) at their resolution: 359.996° prints as ``0.00``, never ``360.00``.
* A ``None`` value gives a null (empty) field, as receivers send when they have no data.
* High-precision sentences can exceed the standard's 82-character limit, as RTK receivers' sentences do in
  practice; no limit is enforced.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from datetime import UTC, datetime, timedelta

KNOTS_PER_MPS = 3600.0 / 1852.0
"""1 m/s in knots (1 international nautical mile = 1852 m)."""
KMH_PER_MPS = 3.6

LATLON_DECIMALS = 6
TIME_DECIMALS = 2

GGA_QUALITY = {
    0: "fix not available",
    1: "GPS fix (SPS)",
    2: "differential GPS fix",
    3: "PPS fix",
    4: "RTK fixed",
    5: "RTK float",
    6: "estimated (dead reckoning)",
    7: "manual input",
    8: "simulation",
}
"""GGA field 6, the GPS quality indicator."""

POSITION_MODES = "NADPRFEMS"
"""Mode indicator characters (RMC, VTG, GNS): N no fix, A autonomous, D differential, P precise, R RTK
fixed, F RTK float, E estimated (dead reckoning), M manual input, S simulator."""

HEADING_MODES = "AEMSV"
"""THS mode indicator: A autonomous, E estimated (dead reckoning), M manual input, S simulator,
V not valid."""

NAV_STATUS = "SCUV"
"""Navigational status (RMC/GNS, NMEA 4.10): S safe, C caution, U unsafe, V not valid."""

_TALKER_RE = re.compile(r"[A-Z][A-Z0-9]")
_KIND_RE = re.compile(r"[A-Z]{3}")
_RESERVED = frozenset("$*,!\\^~\r\n")

Field = str | None


# ---------------------------------------------------------------------------------------------- framing


def checksum(body: str) -> str:
    """NMEA checksum of ``body`` (the characters between ``$`` and ``*``): two upper-case hex digits of the
    XOR of all its bytes.

    The bytes are read as one integer and folded in halves (x ^= x >> 8w for w = 2^k bytes, largest first):
    after the fold by w, byte i < w holds the XOR of bytes i, i + w, i + 2w, ... of the region below 2w, so
    the last fold leaves the XOR of all in byte 0. ~log2(n) big-integer operations in C instead of n Python
    ones (a sentence is ~70 bytes); `checksum_reference` is the byte loop, tested equal."""
    data = body.encode("ascii")
    x = int.from_bytes(data, "little")
    if len(data) <= 128:  # every sentence in practice: the seven folds written out
        x ^= x >> 512
        x ^= x >> 256
        x ^= x >> 128
        x ^= x >> 64
        x ^= x >> 32
        x ^= x >> 16
        x ^= x >> 8
        return _HEX2[x & 0xFF]
    width = 1 << (len(data) - 1).bit_length()
    while width > 1:
        width >>= 1
        x ^= x >> (width << 3)
    return _HEX2[x & 0xFF]


def checksum_reference(body: str) -> str:
    """`checksum` as the standard states it: the XOR of every byte, one at a time."""
    value = 0
    for ch in body.encode("ascii"):
        value ^= ch
    return f"{value:02X}"


_HEX2 = tuple(f"{v:02X}" for v in range(256))


def sentence(talker: str, kind: str, fields: Iterable[Field]) -> str:
    """``$<talker><kind>,<f1>,<f2>,...*HH\\r\\n``. ``talker`` is two characters (``GP``), ``kind`` three
    (``GGA``); a ``None`` field is null (empty). Fields must be ASCII without NMEA's reserved characters."""
    if not _TALKER_RE.fullmatch(talker):
        raise ValueError(f"talker id must be 2 upper-case characters, got {talker!r}")
    if not _KIND_RE.fullmatch(kind):
        raise ValueError(f"sentence formatter must be 3 upper-case letters, got {kind!r}")
    texts = ["" if f is None else f for f in fields]
    for text in texts:
        if not text.isascii() or _RESERVED.intersection(text):
            raise ValueError(f"NMEA field {text!r} contains a reserved or non-ASCII character")
    body = ",".join([talker + kind, *texts])
    return f"${body}*{checksum(body)}\r\n"


_CHECKED_HEADS: dict[tuple[str, str], str] = {}


def _build(talker: str, kind: str, fields: Iterable[Field]) -> str:
    """`sentence` for fields this module formatted itself (numbers, validated letters): the talker and
    formatter are checked once per pair, the fields are not re-scanned. ~2x faster on the simulator's
    10 Hz bursts (bench/bench_simulator.py)."""
    head = _CHECKED_HEADS.get((talker, kind))
    if head is None:
        sentence(talker, kind, ())  # validates, raises on a bad talker or formatter
        head = _CHECKED_HEADS[(talker, kind)] = talker + kind
    body = ",".join([head, *[f or "" for f in fields]])  # (a field is text or None; "" stays "")
    return f"${body}*{checksum(body)}\r\n"


def corrupt_checksum(text: str) -> str:
    """The same sentence with a wrong checksum (every bit of it inverted), for fault injection."""
    star = text.rfind("*")
    if star < 0 or len(text) < star + 3:
        raise ValueError(f"not an NMEA sentence with a checksum: {text!r}")
    good = int(text[star + 1 : star + 3], 16)
    return f"{text[: star + 1]}{good ^ 0xFF:02X}{text[star + 3 :]}"


# ---------------------------------------------------------------------------------------------- position


def gga(
    talker: str,
    t_utc: datetime,
    lat_deg: float | None,
    lon_deg: float | None,
    quality: int,
    n_sats: int,
    hdop: float | None,
    alt_m: float | None,
    geoid_sep_m: float | None = None,
    age_s: float | None = None,
    station_id: int | None = None,
    *,
    decimals: int = LATLON_DECIMALS,
    time_decimals: int = TIME_DECIMALS,
) -> str:
    """GGA, Global Positioning System fix data::

        $--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,x,xx,x.x,x.x,M,x.x,M,x.x,xxxx*hh
               1         2       3 4        5 6 7  8   9   10 11 12 13  14

    1 UTC time of fix, 2-3 latitude N/S, 4-5 longitude E/W, 6 quality (:data:`GGA_QUALITY`), 7 satellites
    in use (00-99), 8 HDOP, 9-10 antenna altitude above mean sea level (geoid), m, 11-12 geoidal separation
    (geoid above WGS-84 ellipsoid), m, 13 age of differential corrections, s, 14 differential reference
    station id (0000-1023). Altitude 3 decimals (mm), HDOP 2, age 1.
    """
    if quality not in GGA_QUALITY:
        raise ValueError(f"GGA quality must be one of {sorted(GGA_QUALITY)}, got {quality}")
    lat, ns = _lat(lat_deg, decimals)
    lon, ew = _lon(lon_deg, decimals)
    fields = [
        _time(_rounded(t_utc, time_decimals), time_decimals),
        lat,
        ns,
        lon,
        ew,
        str(quality),
        _count(n_sats),
        _fixed(hdop, 2),
        _fixed(alt_m, 3),
        None if alt_m is None else "M",
        _fixed(geoid_sep_m, 3),
        None if geoid_sep_m is None else "M",
        _fixed(age_s, 1),
        _station(station_id),
    ]
    return _build(talker, "GGA", fields)


def gns(
    talker: str,
    t_utc: datetime,
    lat_deg: float | None,
    lon_deg: float | None,
    mode: str,
    n_sats: int,
    hdop: float | None,
    alt_m: float | None,
    geoid_sep_m: float | None = None,
    age_s: float | None = None,
    station_id: int | None = None,
    nav_status: str | None = None,
    *,
    decimals: int = LATLON_DECIMALS,
    time_decimals: int = TIME_DECIMALS,
) -> str:
    """GNS, GNSS fix data::

        $--GNS,hhmmss.ss,llll.ll,a,yyyyy.yy,a,c--c,xx,x.x,x.x,x.x,x.x,x.x,a*hh
               1         2       3 4        5 6    7  8   9   10  11  12  13

    1 UTC time, 2-5 position, 6 mode indicator, one character per constellation in the order GPS, GLONASS,
    Galileo, BDS, QZSS, NavIC (e.g. ``DD``, ``RR``; :data:`POSITION_MODES`), 7 satellites in use, 8 HDOP,
    9 orthometric height, m, 10 geoidal separation, m, 11 age of differential data, s, 12 reference station
    id, 13 navigational status (NMEA 4.10, :data:`NAV_STATUS`; omitted when ``None``).
    """
    if not mode or any(c not in POSITION_MODES for c in mode):
        raise ValueError(f"GNS mode must be characters of {POSITION_MODES!r}, got {mode!r}")
    lat, ns = _lat(lat_deg, decimals)
    lon, ew = _lon(lon_deg, decimals)
    fields = [
        _time(_rounded(t_utc, time_decimals), time_decimals),
        lat,
        ns,
        lon,
        ew,
        mode,
        _count(n_sats),
        _fixed(hdop, 2),
        _fixed(alt_m, 3),
        _fixed(geoid_sep_m, 3),
        _fixed(age_s, 1),
        _station(station_id),
    ]
    if nav_status is not None:
        fields.append(_one_of("GNS navigational status", nav_status, NAV_STATUS))
    return _build(talker, "GNS", fields)


def rmc(
    talker: str,
    t_utc: datetime,
    lat_deg: float | None,
    lon_deg: float | None,
    sog_mps: float | None,
    cog_rad: float | None,
    valid: bool,
    mode: str = "D",
    *,
    mag_var_rad: float | None = None,
    decimals: int = LATLON_DECIMALS,
    time_decimals: int = TIME_DECIMALS,
    speed_decimals: int = 3,
    course_decimals: int = 2,
) -> str:
    """RMC, recommended minimum specific GNSS data (NMEA 2.3 layout with mode indicator)::

        $--RMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,x.x,a,a*hh
               1         2 3       4 5        6 7   8   9      10  11 12

    1 UTC time, 2 status A valid / V warning, 3-6 position, 7 speed over ground, knots, 8 course over
    ground, degrees true, 9 date, 10-11 magnetic variation, degrees E/W (east positive in
    ``mag_var_rad``), 12 mode indicator (:data:`POSITION_MODES`).
    """
    rounded = _rounded(t_utc, time_decimals)
    lat, ns = _lat(lat_deg, decimals)
    lon, ew = _lon(lon_deg, decimals)
    var, var_dir = _east_west(mag_var_rad, 1)
    fields = [
        _time(rounded, time_decimals),
        "A" if valid else "V",
        lat,
        ns,
        lon,
        ew,
        _speed(sog_mps, KNOTS_PER_MPS, speed_decimals),
        _deg360(cog_rad, course_decimals),
        f"{rounded.day:02d}{rounded.month:02d}{rounded.year % 100:02d}",
        var,
        var_dir,
        _one_of("RMC mode", mode, POSITION_MODES),
    ]
    return _build(talker, "RMC", fields)


def vtg(
    talker: str,
    cog_rad: float | None,
    sog_mps: float | None,
    mode: str = "D",
    *,
    mag_var_rad: float | None = None,
    speed_decimals: int = 3,
    course_decimals: int = 2,
) -> str:
    """VTG, course over ground and ground speed::

        $--VTG,x.x,T,x.x,M,x.x,N,x.x,K,a*hh
               1   2 3   4 5   6 7   8 9

    1 course over ground, degrees true, 3 course over ground, degrees magnetic (true minus
    ``mag_var_rad``, east positive; null if the variation is not given), 5 speed, knots, 7 speed, km/h,
    9 mode indicator (:data:`POSITION_MODES`).
    """
    magnetic = None if cog_rad is None or mag_var_rad is None else cog_rad - mag_var_rad
    fields = [
        _deg360(cog_rad, course_decimals),
        "T",
        _deg360(magnetic, course_decimals),
        "M",
        _speed(sog_mps, KNOTS_PER_MPS, speed_decimals),
        "N",
        _speed(sog_mps, KMH_PER_MPS, speed_decimals),
        "K",
        _one_of("VTG mode", mode, POSITION_MODES),
    ]
    return _build(talker, "VTG", fields)


def gst(
    talker: str,
    t_utc: datetime,
    *,
    rms_m: float | None,
    sigma_major_m: float | None,
    sigma_minor_m: float | None,
    orient_rad: float | None,
    sigma_lat_m: float | None,
    sigma_lon_m: float | None,
    sigma_alt_m: float | None,
    time_decimals: int = TIME_DECIMALS,
) -> str:
    """GST, GNSS pseudorange error statistics::

        $--GST,hhmmss.ss,x.x,x.x,x.x,x.x,x.x,x.x,x.x*hh
               1         2   3   4   5   6   7   8

    1 UTC time of the associated GGA/GNS fix, 2 RMS of the pseudorange residuals, m, 3-4 standard deviation
    of the semi-major / semi-minor axis of the error ellipse, m, 5 orientation of the semi-major axis,
    degrees from true north, 6-8 standard deviation of latitude, longitude and altitude error, m.
    The orientation of an axis is defined modulo 180°: it is printed in [0, 180). Metres with 3 decimals.
    Keyword-only: seven numbers of the same kind are too easy to pass in the wrong order.
    """
    orient = None
    if orient_rad is not None:
        scaled = round(math.degrees(_finite("orient_rad", orient_rad)) * 10) % 1800
        orient = f"{scaled // 10}.{scaled % 10}"
    fields = [
        _time(_rounded(t_utc, time_decimals), time_decimals),
        _fixed(rms_m, 3),
        _fixed(sigma_major_m, 3),
        _fixed(sigma_minor_m, 3),
        orient,
        _fixed(sigma_lat_m, 3),
        _fixed(sigma_lon_m, 3),
        _fixed(sigma_alt_m, 3),
    ]
    return _build(talker, "GST", fields)


def zda(talker: str, t_utc: datetime, *, time_decimals: int = TIME_DECIMALS) -> str:
    """ZDA, time and date::

        $--ZDA,hhmmss.ss,xx,xx,xxxx,xx,xx*hh
               1         2  3  4    5  6

    1 UTC time, 2 day, 3 month, 4 year (four digits), 5-6 local zone hours and minutes (always ``00,00``:
    dpgw speaks UTC).
    """
    rounded = _rounded(t_utc, time_decimals)
    fields = [
        _time(rounded, time_decimals),
        f"{rounded.day:02d}",
        f"{rounded.month:02d}",
        f"{rounded.year:04d}",
        "00",
        "00",
    ]
    return _build(talker, "ZDA", fields)


# ---------------------------------------------------------------------------------------------- heading


def hdt(talker: str, heading_rad: float | None, *, decimals: int = 2) -> str:
    """HDT, heading true::

        $--HDT,x.x,T*hh

    1 heading, degrees true, in [0, 360) with ``decimals`` decimals (default 0.01°).
    """
    return _build(talker, "HDT", [_deg360(heading_rad, decimals), "T"])


def ths(talker: str, heading_rad: float | None, mode: str = "A", *, decimals: int = 2) -> str:
    """THS, true heading and status (replaces HDT in NMEA 3.0+ gyros and INS)::

        $--THS,x.x,a*hh

    1 heading, degrees true, [0, 360), 2 mode indicator (:data:`HEADING_MODES`: A autonomous, E estimated,
    M manual, S simulator, V data not valid).
    """
    return _build(talker, "THS", [_deg360(heading_rad, decimals), _one_of("THS mode", mode, HEADING_MODES)])


def rot(talker: str, rate_rad_s: float | None, valid: bool = True, *, decimals: int = 1) -> str:
    """ROT, rate of turn::

        $--ROT,x.x,A*hh

    1 rate of turn, degrees per minute, negative when the bow turns to port (``rate_rad_s`` is the yaw
    rate r, positive clockwise seen from above), 2 status A valid / V invalid.
    """
    rate = None if rate_rad_s is None else math.degrees(_finite("rate_rad_s", rate_rad_s)) * 60.0
    return _build(talker, "ROT", [_fixed(rate, decimals), "A" if valid else "V"])


MWV_UNITS = {"M": 1.0, "K": 3.6, "N": 3600.0 / 1852.0, "S": 3600.0 / 1609.344}
"""MWV's speed units per m/s: M m/s, K km/h, N knots, S statute miles per hour."""


def mwv(
    talker: str,
    angle_rad: float | None,
    speed_mps: float | None,
    reference: str = "R",
    unit: str = "M",
    valid: bool = True,
    *,
    decimals: int = 1,
) -> str:
    """MWV, wind speed and angle (an anemometer)::

        $--MWV,x.x,a,x.x,a,A*hh
               1   2 3   4 5

    1 wind angle, degrees [0, 360) clockwise from the bow, the direction the wind comes from, 2 reference
    R relative (apparent) / T theoretical (true), 3 wind speed, 4 its unit K km/h, M m/s, N knots, S statute
    mph, 5 status A valid / V invalid.
    """
    _one_of("reference", reference, "RT")
    _one_of("unit", unit, "KMNS")
    speed = _speed(speed_mps, MWV_UNITS[unit], decimals, "wind speed")
    status = "A" if valid else "V"
    return _build(talker, "MWV", [_deg360(angle_rad, decimals), reference, speed, unit, status])


def hdg(
    talker: str,
    heading_mag_rad: float | None,
    deviation_rad: float | None = None,
    variation_rad: float | None = None,
    *,
    decimals: int = 1,
) -> str:
    """HDG, heading, deviation and variation (magnetic compass)::

        $--HDG,x.x,x.x,a,x.x,a*hh
               1   2   3 4   5

    1 magnetic sensor heading, degrees [0, 360), 2-3 magnetic deviation, degrees E/W, 4-5 magnetic
    variation, degrees E/W. East is positive in the arguments: magnetic heading = sensor heading +
    deviation, true heading = magnetic heading + variation. Null fields when not given.
    """
    dev, dev_dir = _east_west(deviation_rad, decimals)
    var, var_dir = _east_west(variation_rad, decimals)
    return _build(talker, "HDG", [_deg360(heading_mag_rad, decimals), dev, dev_dir, var, var_dir])


# ---------------------------------------------------------------------------------------------- fields


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _check_decimals(decimals: int, low: int, high: int) -> None:
    if not low <= decimals <= high:
        raise ValueError(f"decimals must be in {low}..{high}, got {decimals}")


def _utc(t: datetime) -> datetime:
    return t.replace(tzinfo=UTC) if t.tzinfo is None else t.astimezone(UTC)


def _rounded(t: datetime, decimals: int) -> datetime:
    """``t`` in UTC rounded to the nearest 10**-decimals s (half up), carrying into the date. The last
    answer is kept: a receiver's burst (GGA, RMC, GST, ZDA) asks for the same instant several times."""
    global _LAST_ROUNDED
    last = _LAST_ROUNDED
    if t is last[0] and decimals == last[1]:
        return last[2]
    _check_decimals(decimals, 0, 6)
    u = _utc(t)
    quantum = 10 ** (6 - decimals)
    micro = (u.microsecond + quantum // 2) // quantum * quantum
    rounded = u.replace(microsecond=0) + timedelta(microseconds=micro)
    _LAST_ROUNDED = (t, decimals, rounded)  # (one tuple: a reader in another thread sees all)
    return rounded


# The last answers of `_rounded`, `_time`, `_lat` and `_lon`, one tuple each, kept by hand: functools'
# lru_cache(maxsize=1) gives the same answers but made a receiver's burst of four sentences 7-20 % slower
# (hashing a datetime per call).
_LAST_ROUNDED: tuple[object, int, datetime] = (None, -1, datetime.min)
_LAST_TIME: tuple[object, int, str] = (None, -1, "")


def _time(t: datetime, decimals: int) -> str:
    """``hhmmss.ss`` of an already rounded UTC time (the last answer is kept, as in `_rounded`)."""
    global _LAST_TIME
    last = _LAST_TIME
    if t is last[0] and decimals == last[1]:
        return last[2]
    text = f"{t.hour:02d}{t.minute:02d}{t.second:02d}"  # (strftime costs ~5x more, at every sentence)
    if decimals:
        text += f".{t.microsecond // 10 ** (6 - decimals):0{decimals}d}"
    _LAST_TIME = (t, decimals, text)
    return text


def _dm(abs_deg: float, deg_digits: int, decimals: int) -> str:
    """Degrees and decimal minutes from one rounded integer (no 60-minute carry error)."""
    scale = 10**decimals
    units = round(abs_deg * 60 * scale)
    degrees, rest = divmod(units, 60 * scale)
    minutes, fraction = divmod(rest, scale)
    return _DM_FORMAT[deg_digits][decimals] % (degrees, minutes, fraction)


# "%0<d>d%02d.%0<n>d" per degree digits (2 latitude, 3 longitude) and decimals: built once, not per call
_DM_FORMAT = {d: [f"%0{d}d%02d.%0{n}d" for n in range(10)] for d in (2, 3)}


def _lat(lat_deg: float | None, decimals: int) -> tuple[Field, Field]:
    if not 1 <= decimals <= 9:
        _check_decimals(decimals, 1, 9)
    if lat_deg is None:
        return None, None
    lat = float(lat_deg)
    global _LAST_LAT
    last = _LAST_LAT  # GGA/GNS and RMC of one fix print the same latitude: the last answer is kept
    if lat == last[0] and decimals == last[1]:  # (±0 print alike; NaN never matches and is refused below)
        return last[2]
    if not math.isfinite(lat):
        _finite("lat_deg", lat)
    if not -90.0 <= lat <= 90.0:
        raise ValueError(f"latitude must be in [-90, 90] degrees, got {lat}")
    text = _dm(abs(lat), 2, decimals)
    south = lat < 0 and text.strip("0.") != ""
    out: tuple[Field, Field] = (text, "S" if south else "N")
    _LAST_LAT = (lat, decimals, out)
    return out


def _lon(lon_deg: float | None, decimals: int) -> tuple[Field, Field]:
    if not 1 <= decimals <= 9:
        _check_decimals(decimals, 1, 9)
    if lon_deg is None:
        return None, None
    lon = float(lon_deg)
    global _LAST_LON
    last = _LAST_LON  # (as in `_lat`)
    if lon == last[0] and decimals == last[1]:
        return last[2]
    key = lon
    if not math.isfinite(lon):
        _finite("lon_deg", lon)
    if not -180.0 <= lon <= 180.0:
        lon = (lon + 180.0) % 360.0 - 180.0
    text = _dm(abs(lon), 3, decimals)
    west = lon < 0 and text.strip("0.") != ""
    out: tuple[Field, Field] = (text, "W" if west else "E")
    _LAST_LON = (key, decimals, out)
    return out


_LAST_LAT: tuple[float, int, tuple[Field, Field]] = (math.nan, -1, (None, None))
_LAST_LON: tuple[float, int, tuple[Field, Field]] = (math.nan, -1, (None, None))


def _fixed(value: float | None, decimals: int) -> Field:
    """Fixed-point text, never ``-0.00``."""
    if value is None:
        return None
    v = float(value)
    if not math.isfinite(v):
        _finite("value", v)
    text = _FIXED_FORMAT[decimals] % v if 0 <= decimals < 10 else f"{v:.{decimals}f}"
    if text[0] == "-" and text.strip("-0.") == "":
        text = text[1:]
    return text


_FIXED_FORMAT = [f"%.{n}f" for n in range(10)]  # (printf-style %.nf is Python's f"{v:.nf}", digit for digit)


def _deg360(angle_rad: float | None, decimals: int) -> Field:
    """An angle as degrees in [0, 360) at ``decimals`` resolution (360.00 wraps to 0.00)."""
    if angle_rad is None:
        return None
    if not 0 <= decimals <= 9:
        _check_decimals(decimals, 0, 9)
    a = float(angle_rad)
    if not math.isfinite(a):
        _finite("angle", a)
    scale = 10**decimals
    units = round(math.degrees(a) * scale) % (360 * scale)
    whole, fraction = divmod(units, scale)
    return _DEG_FORMAT[decimals] % (whole, fraction) if decimals else str(whole)


_DEG_FORMAT = [f"%d.%0{n}d" for n in range(10)]


def _east_west(angle_rad: float | None, decimals: int) -> tuple[Field, Field]:
    """Magnitude in degrees and E/W (east positive) for deviation and variation."""
    if angle_rad is None:
        return None, None
    degrees = math.degrees(_finite("angle", angle_rad))
    text = _fixed(abs(degrees), decimals)
    assert text is not None
    west = degrees < 0 and text.strip("0.") != ""
    return text, "W" if west else "E"


def _speed(speed_mps: float | None, factor: float, decimals: int, what: str = "speed over ground") -> Field:
    if speed_mps is None:
        return None
    speed = _finite(what, speed_mps)
    if speed < 0:
        raise ValueError(f"{what} cannot be negative, got {speed} m/s")
    return _fixed(speed * factor, decimals)


def _count(n: int) -> str:
    if not 0 <= n <= 99:
        raise ValueError(f"number of satellites must be in 0..99, got {n}")
    return f"{n:02d}"


def _station(station_id: int | None) -> Field:
    if station_id is None:
        return None
    if not 0 <= station_id <= 1023:
        raise ValueError(f"differential reference station id must be in 0..1023, got {station_id}")
    return f"{station_id:04d}"


def _one_of(name: str, value: str, allowed: str) -> str:
    if len(value) != 1 or value not in allowed:
        raise ValueError(f"{name} must be one of {list(allowed)}, got {value!r}")
    return value


# ---------------------------------------------------------------------------------------------- MRU attitude


def _build_proprietary(address: str, fields: Iterable[Field]) -> str:
    """``$<address>,<fields>*HH\\r\\n`` for a proprietary sentence (``P`` + manufacturer + type: the
    address is not a talker and a formatter). Fields formatted by this module."""
    body = ",".join([address, *[f or "" for f in fields]])
    return f"${body}*{checksum(body)}\r\n"


def _signed(value: float | None, decimals: int) -> Field:
    """Fixed-point text with an explicit sign (``+00.39``, ``-01.20``), as MRUs print attitude."""
    text = _fixed(value, decimals)
    if text is None or text[0] == "-":
        return text
    return "+" + text


def pashr(
    t_utc: datetime,
    roll_rad: float | None,
    pitch_rad: float | None,
    *,
    heading_rad: float | None = None,
    heave_up_m: float | None = None,
    roll_sigma_rad: float | None = None,
    pitch_sigma_rad: float | None = None,
    heading_sigma_rad: float | None = None,
    aiding: int | None = 1,
    imu: int | None = 1,
    time_decimals: int = 3,
    decimals: int = 2,
) -> str:
    """PASHR, attitude of a motion reference unit (Applanix POS MV, Hemisphere, OxTS, Trimble)::

        $PASHR,hhmmss.sss,HHH.HH,T,RRR.RR,PPP.PP,x.xx,r.rrr,p.ppp,h.hhh,a,b*hh
               1          2      3 4      5      6    7     8     9     10 11

    1 UTC time, 2 true heading, degrees [0, 360), 3 ``T`` (true; empty without a heading), 4 roll,
    degrees, + port up (starboard down, dpgw's φ), 5 pitch, degrees, + bow up (dpgw's θ), 6 heave, m,
    + up, 7-9 1σ of roll, pitch and heading, degrees, 10 GNSS aiding status (0 none, 1 GNSS, 2 GNSS and
    heading), 11 IMU status flag. Angles with ``decimals`` decimals and an explicit sign, as POS MV prints.
    """
    for name, flag in (("aiding", aiding), ("imu", imu)):
        if flag is not None and not 0 <= flag <= 9:
            raise ValueError(f"PASHR {name} status must be one digit, got {flag}")
    sigma = [None if v is None else math.degrees(_finite("sigma", v)) for v in
             (roll_sigma_rad, pitch_sigma_rad, heading_sigma_rad)]  # fmt: skip
    roll = None if roll_rad is None else math.degrees(_finite("roll_rad", roll_rad))
    pitch = None if pitch_rad is None else math.degrees(_finite("pitch_rad", pitch_rad))
    if roll is not None and not -180.0 <= roll <= 180.0:
        raise ValueError(f"roll must be within ±180°, got {roll}°")
    if pitch is not None and not -90.0 <= pitch <= 90.0:
        raise ValueError(f"pitch must be within ±90°, got {pitch}°")
    fields = [
        _time(_rounded(t_utc, time_decimals), time_decimals),
        _deg360(heading_rad, decimals),
        None if heading_rad is None else "T",
        _signed(roll, decimals),
        _signed(pitch, decimals),
        _signed(heave_up_m, 2),
        *[_fixed(v, 3) for v in sigma],
        None if aiding is None else str(aiding),
        None if imu is None else str(imu),
    ]
    return _build_proprietary("PASHR", fields)


def phtro(roll_rad: float | None, pitch_rad: float | None, *, decimals: int = 2) -> str:
    """PHTRO, pitch and roll of an iXblue MRU/INS (Octans, Phins, Hydrins)::

        $PHTRO,x.xx,a,y.yy,b*hh
               1    2 3    4

    1 pitch, degrees, magnitude, 2 ``M`` bow up / ``P`` bow down, 3 roll, degrees, magnitude, 4 ``T`` port
    up (starboard down: dpgw's positive φ) / ``B`` port down. A zero angle is sent with ``M`` / ``T``.
    """
    fields: list[Field] = []
    for value, limit, plus, minus in ((pitch_rad, 90.0, "M", "P"), (roll_rad, 180.0, "T", "B")):
        if value is None:
            fields += [None, None]
            continue
        degrees = math.degrees(_finite("angle", value))
        if not -limit <= degrees <= limit:
            raise ValueError(f"PHTRO angle must be within ±{limit:g}°, got {degrees}°")
        text = _fixed(abs(degrees), decimals)
        assert text is not None
        fields += [text, minus if degrees < 0 and text.strip("0.") != "" else plus]
    return _build_proprietary("PHTRO", fields)
