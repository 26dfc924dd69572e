"""NMEA text logs timed by their logger alone: every line after a UTC receive time, no sentence with a time.

A data logger that writes one file per serial port stamps each line with the time it arrived
(``2024-12-07T03:25:51.050Z $HEHDT,45.9,T*2F``). A gyro's file then holds headings (HDT, THS, ROT) and no
sentence that carries a time of day, so the ordinary text reader (`gateway.logreaders`), which times a
log by its GGA/RMC/ZDA, has nothing to replay it by. Such a file is replayed by its stamps: each run of
lines with one stamp is one read at that time, as the live gateway received it (not a reader's cycle: the
pipeline cuts a read into cycles as it does a live one), so ``dpgw replay gps.nmea gyro.nmea`` merges
the two files by time.

A capture of a ship's network may carry the time in each line's TAG block instead: ``c:``, the UNIX time
the sender gave the sentence (NMEA 4.10; ``\\s:HE0001,n:12,c:1733541951*hh\\$HEHDT,...``). A gyro's group
alone has no other time, so a file whose TAG blocks carry ``c:`` and that holds no sentence with a time
is read by those times the same way. ``c:`` is seconds (9 or 10 digits, a fraction allowed) or, with 12 or
13 digits and no fraction, milliseconds, as AIS and IEC 61162-450 loggers write it; only a TAG block whose
checksum is right gives a time (one that is damaged goes with the read before it, as a line without a
stamp, and the pipeline counts the damage where the block is kept). Where the capture's blocks name
several devices, the blocks stay on the lines and the replay splits them by device
(`gateway.line_prefix.split_by_device`); otherwise the block comes off, as a logger's stamp does.

Only stamps that say they are UTC are taken: ISO 8601 with ``Z`` or an offset (``+02:00``, turned into
UTC), and UNIX seconds (``1733541951.050``). A date and time without a zone may be the logger's local
time, hours off the receiver's UTC in a merge: such a file is read by its stamps only when the user says
which zone the logger wrote in (``dpgw replay --stamp-zone +02:00``, or ``UTC``); otherwise its
sentences' times are used where it has them, and without any, replay says why there is nothing to
replay. A file with sentence times is read the ordinary way whether or not it is stamped
(`gateway.line_prefix` takes the stamps off).

Counts (`LogCounts`): ``line_prefix`` the stamps taken off; ``tag_time`` the lines timed by ``c:``;
``no_stamp`` a line without one (it goes with the read before it, as it arrived after it; before any stamp it
is counted and left out); ``time_backwards`` a stamp earlier than the one before it (kept: the observer skips
what is late); ``time_gap`` a step forward longer than ``gap_s``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta, timezone, tzinfo
from pathlib import Path

from gateway.compressed import open_log
from gateway.logreaders import TIMED, LogCounts, count_reading
from gateway.pipeline import RawEvent
from wire.codecs.nmea_tag import TagBlock, decode_tag

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


TAG_PREFIX = re.compile(rb"(?:UdPbC\x00)?(\\[^\\\r\n]*\\)(?=[$!])")
"""A TAG block at a line's start (after the IEC 61162-450 datagram header, where a capture has it),
directly before a sentence: group 1 the block with its two backslashes."""


def tag_time_ns(value: str) -> int | None:
    """UTC ns of a TAG block's ``c:`` value: UNIX seconds (9 or 10 digits, a fraction allowed) or
    milliseconds (12 or 13 digits, no fraction); None for anything else.

    >>> tag_time_ns("1733541951.05"), tag_time_ns("1733541951050")
    (1733541951050000000, 1733541951050000000)
    """
    whole, dot, frac = value.partition(".")
    if not (whole.isascii() and whole.isdigit()) or (dot and not (frac.isascii() and frac.isdigit())):
        return None
    if 12 <= len(whole) <= 13 and not dot:
        return int(whole) * 1_000_000
    if not 9 <= len(whole) <= 10 or len(frac) > 9:
        return None
    return int(whole) * NS + int((frac + "000000000")[:9])


def line_tag_time(line: bytes) -> tuple[int, re.Match[bytes]] | None:
    """A line's time from its TAG block's ``c:`` (`tag_time_ns`) and the block's match (`TAG_PREFIX`);
    None without a block, with a damaged one, or without a readable ``c:``."""
    m = TAG_PREFIX.match(line)
    if m is None or b"c:" not in m[1]:
        return None
    tag = decode_tag(m[1])
    if type(tag) is not TagBlock or (c := tag.params.get("c")) is None:
        return None
    t = tag_time_ns(c)
    return None if t is None else (t, m)


def _behind(line: bytes, block: re.Match[bytes], keep_tags: bool) -> bytes:
    """``line`` behind its datagram header and, unless ``keep_tags``, its TAG block (`TAG_PREFIX`)."""
    return line[block.start(1) :] if keep_tags else line[block.end() :]


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
    a line that starts with a stamp that is a UTC time (given ``zone`` for one without a zone) or with a
    TAG block whose ``c:`` is one, and no sentence with a time of day."""
    with open_log(path) as f:
        head = f.read(peek)
    if TIMED_SENTENCE.search(head) is not None:
        return False
    return any(
        ((m := STAMP.match(line)) and stamp_ns(m, zone) is not None) or line_tag_time(line) is not None
        for line in head.splitlines()[:200]
    )


def stamped_text_events(
    path: str | Path,
    source: str,
    *,
    counts: LogCounts | None = None,
    gap_s: float = 5.0,
    zone: tzinfo | None = None,
    keep_tags: bool = False,
) -> Iterator[RawEvent]:
    """One `RawEvent` per run of lines with one stamp, at that stamp (module docstring). ``keep_tags``: a
    line timed by its TAG block keeps the block (a capture to be split by device), else it comes off."""
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
            if m is not None and t is not None:
                c.counts["line_prefix"] += 1
                body = line[m.end() :]
            elif (tagged := line_tag_time(line)) is not None:
                c.counts["tag_time"] += 1
                t, block = tagged
                body = _behind(line, block, keep_tags)
            else:
                c.counts["no_stamp"] += 1
                if at is not None:  # (a TAG block here: a group's later line, g: alone, or a damaged one)
                    tag = TAG_PREFIX.match(line)
                    lines.append(line if tag is None else _behind(line, tag, keep_tags))
                continue
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
            lines.append(body)
        count_reading(f, c)
    if lines and at is not None:
        yield RawEvent(at, source, b"\r\n".join(lines) + b"\r\n")
        c.cycles += 1
