"""Reading recorded logs as pipeline events: raw NMEA text logs and MAVLink telemetry logs (tlogs).

(The gateway's own MCAP logs are read by `gateway.replay.mcap_events`.)

**NMEA text logs** carry no receive times: time comes from the sentences. GGA, GNS, RMC and ZDA carry the
UTC time of day (RMC and ZDA also the date); sentences without time (HDT, ROT, VTG, GST …) take the time
of their *cycle*, as gpsd groups a cycle: a cycle is every line from one new time stamp to the next. Each
cycle becomes one `RawEvent` (its lines, in order) at the cycle's time, so the observer steps once per
cycle. The date comes from the first RMC/ZDA in the file (else ``base_date``); a time of day that falls
by more than 12 h is a midnight rollover. Bad time is counted and never fatal:

- ``time_gap``: a step forward longer than ``gap_s`` — a dropout, not a jump (the observer dead-reckons);
- ``time_backwards``: a cycle earlier than the previous one (kept, the observer skips it);
- ``repeated_time``: a cycle with the time of an earlier, finished cycle;
- ``duplicate``: a line identical to the one before it (dropped).

Truncated lines, garbage and checksum failures are counted by the pipeline's framer and decoder.

**tlogs** (QGroundControl, MAVProxy, pymavlink): each record is an 8-byte big-endian time stamp (µs since
1970) followed by one MAVLink v1 or v2 frame. A record that does not start a frame is counted (``bad_record``)
and the reader resynchronises on the next plausible record.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from pathlib import Path

from gateway.codecs.nmea_encode import checksum
from gateway.pipeline import RawEvent

NS = 1_000_000_000
DAY_NS = 86_400 * NS
TIMED = ("GGA", "GNS", "RMC", "ZDA", "GLL")
DEFAULT_BASE_DATE = date(2000, 1, 1)


@dataclass
class LogCounts:
    lines: int = 0
    cycles: int = 0
    counts: Counter[str] = field(default_factory=Counter)


def _checked_fields(line: str) -> list[str] | None:
    """Fields of a sentence whose checksum is right (time must not come from a damaged line)."""
    star = line.rfind("*")
    if not line.startswith("$") or star < 0 or len(line) < star + 3:
        return None
    if checksum(line[1:star]) != line[star + 1 : star + 3].upper():
        return None
    return line[1:star].split(",")


def _time_of_day(text: str) -> float | None:
    if len(text) < 6 or not text[:6].isdigit():
        return None
    try:
        h, m, s = int(text[0:2]), int(text[2:4]), float(text[4:])
    except ValueError:
        return None
    if h > 23 or m > 59 or s >= 61:
        return None
    return h * 3600 + m * 60 + s


def _date(fields: list[str], kind: str) -> date | None:
    try:
        if kind == "RMC" and len(fields) > 9 and len(fields[9]) == 6:
            d = fields[9]
            return date(2000 + int(d[4:6]), int(d[2:4]), int(d[0:2]))
        if kind == "ZDA" and len(fields) > 4 and fields[2] and fields[3] and fields[4]:
            return date(int(fields[4]), int(fields[3]), int(fields[2]))
    except ValueError:
        return None
    return None


def _unchecked_time(line: bytes) -> float | None:
    """Time of day of a timed sentence without checking its checksum (cheap; see `nmea_text_events`)."""
    k = 7 if line[3:6] != b"GLL" else -1
    if k < 0:
        return None
    return _time_of_day(line[k : line.find(b",", k)].decode("ascii", "replace"))


def _sentence_time(line: str) -> tuple[float | None, date | None]:
    kind = line[3:6] if len(line) > 6 else ""
    if kind not in TIMED:
        return None, None
    fields = _checked_fields(line.rstrip("\r\n"))
    if fields is None:
        return None, None
    tod = (
        _time_of_day(fields[5 if kind == "GLL" else 1]) if len(fields) > (5 if kind == "GLL" else 1) else None
    )
    return tod, _date(fields, kind)


def _first_date(path: Path, limit: int = 2000) -> date | None:
    with open(path, encoding="ascii", errors="replace", newline="") as f:
        for k, line in enumerate(f):
            if k >= limit:
                break
            _, d = _sentence_time(line.strip())
            if d is not None:
                return d
    return None


def nmea_text_events(
    path: str | Path,
    source: str = "nmea",
    *,
    base_date: date | None = None,
    gap_s: float = 5.0,
    counts: LogCounts | None = None,
) -> Iterator[RawEvent]:
    """One `RawEvent` per cycle of a raw NMEA text log (see module docstring)."""
    path = Path(path)
    c = counts if counts is not None else LogCounts()
    day = _first_date(path) or base_date or DEFAULT_BASE_DATE
    day_ns = int(datetime(day.year, day.month, day.day, tzinfo=UTC).timestamp()) * NS
    lines: list[bytes] = []
    cycle_ns: int | None = None
    last_tod: float | None = None
    latest_ns = -1
    seen: set[int] = set()
    previous = b""
    with open(path, "rb") as f:
        for raw in f:
            c.lines += 1
            line = raw.rstrip(b"\r\n")
            if not line:
                continue
            if line == previous:
                c.counts["duplicate"] += 1
                continue
            previous = line
            tod: float | None = None
            if line[:1] == b"$" and line[3:6] in (b"GGA", b"GNS", b"RMC", b"ZDA", b"GLL"):
                # Most timed sentences repeat their cycle's time: only a new time needs the checksum
                # (a damaged time field must not start a cycle).
                quick = _unchecked_time(line)
                if quick is not None and quick == last_tod:
                    tod = quick
                else:
                    tod, _ = _sentence_time(line.decode("ascii", "replace"))
            if tod is not None:
                if last_tod is not None and tod < last_tod - 43_200:
                    day_ns += DAY_NS  # midnight rollover
                elif last_tod is not None and tod > last_tod + 43_200:
                    day_ns -= DAY_NS  # a late sentence from before midnight
                last_tod = tod
                t_ns = day_ns + round(tod * 1e9)
                if t_ns != cycle_ns:
                    if lines and cycle_ns is not None:
                        yield RawEvent(cycle_ns, source, b"\r\n".join(lines) + b"\r\n")
                        c.cycles += 1
                        lines = []
                    if latest_ns >= 0:
                        if t_ns < latest_ns:
                            c.counts["repeated_time" if t_ns in seen else "time_backwards"] += 1
                        elif t_ns - latest_ns > gap_s * NS:
                            c.counts["time_gap"] += 1
                    latest_ns = max(latest_ns, t_ns)
                    if len(seen) > 100_000:
                        seen.clear()
                    seen.add(t_ns)
                    cycle_ns = t_ns
            lines.append(line)
    if lines:
        if cycle_ns is None:
            c.counts["no_time"] += len(lines)  # a log with no timed sentence at all: nothing to replay
        else:
            yield RawEvent(cycle_ns, source, b"\r\n".join(lines) + b"\r\n")
            c.cycles += 1


_V1, _V2 = 0xFE, 0xFD


def tlog_events(
    path: str | Path, source: str = "mavlink", counts: LogCounts | None = None
) -> Iterator[RawEvent]:
    """MAVLink frames of a tlog with their recorded times."""
    c = counts if counts is not None else LogCounts()
    data = Path(path).read_bytes()
    i, n = 0, len(data)
    while i + 9 <= n:
        (t_us,) = struct.unpack_from(">Q", data, i)
        j = i + 8
        marker = data[j]
        if marker == _V1 and j + 1 < n:
            size = 6 + data[j + 1] + 2
        elif marker == _V2 and j + 2 < n:
            signed = j + 2 < n and data[j + 2] & 0x01
            size = 10 + data[j + 1] + 2 + (13 if signed else 0)
        else:
            c.counts["bad_record"] += 1
            i += 1  # resynchronise byte by byte on the next plausible record
            while i + 9 <= n and data[i + 8] not in (_V1, _V2):
                i += 1
            continue
        if j + size > n:
            c.counts["truncated"] += 1
            break
        c.lines += 1
        yield RawEvent(t_us * 1000, source, data[j : j + size])
        i = j + size
