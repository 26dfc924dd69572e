"""NMEA text logs timed by their logger alone: every line after a UTC receive time, no sentence with a time.

A data logger that writes one file per serial port stamps each line with the time it arrived
(``2024-12-07T03:25:51.050Z $HEHDT,45.9,T*2F``). A gyro's file then holds headings (HDT, THS, ROT) and no
sentence that carries a time of day, so the ordinary text reader (`gateway.logreaders`), which times a
log by its GGA/RMC/ZDA, has nothing to replay it by. Such a file is replayed by its stamps: each run of
lines with one stamp is one read at that time, as the live gateway received it (not a reader's cycle: the
pipeline cuts a read into cycles as it does a live one), so ``dpgw replay gps.nmea gyro.nmea`` merges
the two files by time.

Only stamps that say they are UTC are taken: ISO 8601 with ``Z`` or an offset (``+02:00``, turned into
UTC), and UNIX seconds (``1733541951.050``). A date and time without a zone may be the logger's local
time, hours off the receiver's UTC in a merge: such a file is read by its stamps only when the user says
which zone the logger wrote in (``dpgw replay --stamp-zone +02:00``, or ``UTC``); otherwise its
sentences' times are used where it has them, and without any, replay says why there is nothing to
replay. A file with sentence times is read the ordinary way whether or not it is stamped
(`gateway.line_prefix` takes the stamps off).

Counts (`LogCounts`): ``line_prefix`` the stamps taken off; ``no_stamp`` a line without one (it goes with
the read before it, as it arrived after it; before any stamp it is counted and left out);
``time_backwards`` a stamp earlier than the one before it (kept: the observer skips what is late);
``time_gap`` a step forward longer than ``gap_s``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta, timezone, tzinfo
from pathlib import Path

from gateway.compressed import open_log
from gateway.logreaders import TIMED, LogCounts, count_reading
from gateway.pipeline import RawEvent

NS = 1_000_000_000

STAMP = re.compile(
    rb"(?:(?P<iso>\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}:\d{2}(?:\.\d{1,9})?)(?P<zone>Z|[+-]\d{2}:?\d{2})?"
    rb"|(?P<unix>\d{9,10}(?:\.\d{1,9})?))[ ,;\t]+(?=[$!])"
)
"""A receive time at a line's start (ISO 8601 with or without a zone, or UNIX seconds), and its separator,
directly before a sentence."""

TIMED_SENTENCE = re.compile(rb"(?m)^[^$\r\n]*\$[A-Z]{2}(?:%s)," % "|".join(TIMED).encode("ascii"))
"""A sentence that carries a time of day (`gateway.logreaders.TIMED`: the ordinary reader times a log by
them)."""


def stamp_ns(m: re.Match[bytes], zone: tzinfo | None = None) -> int | None:
    """UTC ns of a `STAMP` match; None if it is no real time (a 13th month, ...) or names no zone and
    ``zone`` (the one the user says the logger wrote in: ``--stamp-zone``) is None."""
    try:
        if m["unix"] is not None:
            whole, _, frac = m["unix"].partition(b".")
            return int(whole) * NS + int((frac + b"000000000")[:9])
        if m["zone"] is None and zone is None:
            return None
        when = datetime.fromisoformat((m["iso"] + (m["zone"] or b"")).decode("ascii").replace(" ", "T"))
    except ValueError:
        return None
    if when.tzinfo is None:
        when = when.replace(tzinfo=zone)
    return int(when.timestamp()) * NS + when.microsecond * 1000


def parse_zone(text: str) -> tzinfo:
    """``UTC``, ``Z`` or an offset (``+02:00``, ``-0330``) as a zone; ValueError otherwise."""
    if text.strip().upper() in ("UTC", "Z"):
        return UTC
    m = re.fullmatch(r"([+-])(\d{2}):?(\d{2})", text.strip())
    if m is None or int(m[2]) > 14 or int(m[3]) >= 60:
        raise ValueError(f"{text!r} is not a zone (expected UTC or an offset such as +02:00 or -0330)")
    offset = timedelta(hours=int(m[2]), minutes=int(m[3]))
    return timezone(-offset if m[1] == "-" else offset)


def is_stamped_only(path: str | Path, zone: tzinfo | None = None, peek: int = 1 << 16) -> bool:
    """Whether a text log is to be replayed by its stamps: its first ``peek`` bytes (decompressed) hold
    a line that starts with a stamp that is a UTC time (given ``zone`` for one without a zone), and no
    sentence with a time of day."""
    with open_log(path) as f:
        head = f.read(peek)
    if TIMED_SENTENCE.search(head) is not None:
        return False
    return any((m := STAMP.match(line)) and stamp_ns(m, zone) is not None for line in head.splitlines()[:200])


def stamped_text_events(
    path: str | Path,
    source: str,
    *,
    counts: LogCounts | None = None,
    gap_s: float = 5.0,
    zone: tzinfo | None = None,
) -> Iterator[RawEvent]:
    """One `RawEvent` per run of lines with one stamp, at that stamp (module docstring)."""
    c = counts if counts is not None else LogCounts()
    lines: list[bytes] = []
    at: int | None = None
    latest = -1
    with open_log(path) as f:
        for raw in f:
            c.lines += 1
            line = raw.rstrip(b"\r\n")
            if not line:
                continue
            m = STAMP.match(line)
            t = stamp_ns(m, zone) if m is not None else None
            if m is None or t is None:
                c.counts["no_stamp"] += 1
                if at is not None:
                    lines.append(line)
                continue
            c.counts["line_prefix"] += 1
            if t != at:
                if lines and at is not None:
                    yield RawEvent(at, source, b"\r\n".join(lines) + b"\r\n")
                    c.cycles += 1
                    lines = []
                if latest >= 0 and t < latest:
                    c.counts["time_backwards"] += 1
                elif latest >= 0 and t - latest > gap_s * NS:
                    c.counts["time_gap"] += 1
                latest = max(latest, t)
                at = t
            lines.append(line[m.end() :])
        count_reading(f, c)
    if lines and at is not None:
        yield RawEvent(at, source, b"\r\n".join(lines) + b"\r\n")
        c.cycles += 1
