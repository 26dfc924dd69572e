"""The NMEA 0183 UTC time-of-day field, ``hhmmss`` or ``hhmmss.s…``, as seconds of the UTC day.

The one parser every Python reader of that field uses: the sentence decoders (GGA, GNS, RMC, GST, ZDA),
the log readers' cycle clock and the file source's pacing. The compiled line scan of replay
(`wire.codecs.nmea_scan`) keeps its own copy as the fast kernel; a test holds it to this one, value for
value.

The grammar is strict because a time that is wrong by a digit moves every later event of a log: exactly
two digits each of hours (00-23), minutes (00-59) and seconds (00-60, a leap second included), then
optionally a point and any number of decimal digits (``hhmmss.`` as some receivers send it counts as
``hhmmss``). ASCII digits only; no sign, exponent, blank or underscore that ``float()`` would let in.

The value is ``h*3600 + m*60 + s`` with ``s`` = ``float("ss.sss")``, the correctly rounded seconds: the
exact time of day to within one rounding of the sum (sub-nanosecond), whatever the number of decimals.
"""

from __future__ import annotations

# Seconds may reach 60.999…: a positive leap second is the 61st second of its minute.
_SECONDS_LIMIT = 61.0


_TWO_DIGITS = frozenset(f"{i:02d}" for i in range(100))
_HOUR_S = {f"{i:02d}": i * 3600 for i in range(24)}
_MINUTE_S = {f"{i:02d}": i * 60 for i in range(60)}


def parse_time_of_day(field: str) -> float | None:
    """Seconds of the UTC day of an NMEA time field; None for an empty field (no time sent).

    Raises ValueError, naming the field, for anything that is not a time of day (the sentence decoders
    count it as a bad field)."""
    if not field:
        return None
    # Table lookups, not a regular expression: this runs for every GGA, RMC, GST and ZDA of a replay, and
    # the match cost 0.25 µs a sentence more (measured). The tables hold ASCII digits only ("²" and "٣"
    # are digits to `str.isdigit`, not here); `isascii` guards the fraction for the same reason.
    hour_s = _HOUR_S.get(field[:2])
    minute_s = _MINUTE_S.get(field[2:4])
    rest = field[4:]  # ss or ss.s…
    n = len(rest)
    if (
        hour_s is None
        or minute_s is None
        or rest[:2] not in _TWO_DIGITS
        or (n > 2 and (rest[2] != "." or (n > 3 and not (rest.isascii() and rest[3:].isdigit()))))
    ):
        raise ValueError(f"time of day {field!r} is not hhmmss[.s…] with hours 0-23 and minutes 0-59")
    seconds = float(rest)
    if seconds >= _SECONDS_LIMIT:
        raise ValueError(f"time of day {field!r} is out of range (seconds < 61)")
    return hour_s + minute_s + seconds


def time_of_day_or_none(field: str) -> float | None:
    """`parse_time_of_day`, with None for an empty or bad field: for readers that only order or pace
    lines by their time and count bad times elsewhere."""
    try:
        return parse_time_of_day(field)
    except ValueError:
        return None


HALF_DAY_S = 43_200.0


def utc_step_s(from_s: float, to_s: float) -> float:
    """The signed step (s) from one UTC time of day to another, taken modulo a day into [−12 h, 12 h):
    23:59:59.9 → 00:00:00.1 is +0.2 s, not −86399.8 s. Two times of day of sentences received within
    hours of each other (a fix and the one before it, a fix and an MRU sample) are ordered and spaced by
    this without a date: the one comparison of NMEA times the gateway makes (the fix time-order test,
    pairing an MRU sample with a fix by their own times)."""
    return (to_s - from_s + HALF_DAY_S) % 86_400.0 - HALF_DAY_S
