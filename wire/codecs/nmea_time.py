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

import re

_HHMMSS = re.compile(r"([0-9]{2})([0-9]{2})([0-9]{2}(?:\.[0-9]*)?)")
# Seconds may reach 60.999…: a positive leap second is the 61st second of its minute.
_SECONDS_LIMIT = 61.0


def parse_time_of_day(field: str) -> float | None:
    """Seconds of the UTC day of an NMEA time field; None for an empty field (no time sent).

    Raises ValueError, naming the field, for anything that is not a time of day (the sentence decoders
    count it as a bad field)."""
    if not field:
        return None
    m = _HHMMSS.fullmatch(field)
    if m is None:
        raise ValueError(f"time of day {field!r} is not hhmmss[.s…]")
    hours, minutes, seconds = int(m.group(1)), int(m.group(2)), float(m.group(3))
    if hours > 23 or minutes > 59 or seconds >= _SECONDS_LIMIT:
        raise ValueError(f"time of day {field!r} is out of range (hours 0-23, minutes 0-59, seconds < 61)")
    return hours * 3600 + minutes * 60 + seconds


def time_of_day_or_none(field: str) -> float | None:
    """`parse_time_of_day`, with None for an empty or bad field: for readers that only order or pace
    lines by their time and count bad times elsewhere."""
    try:
        return parse_time_of_day(field)
    except ValueError:
        return None
