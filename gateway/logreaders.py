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
- ``duplicate``: a line identical to the one before it (dropped);
- ``gzip_cut`` (``xz_cut``, ``bzip2_cut``, ``zstd_cut``): a compressed log (either kind is read
  compressed, `gateway.compressed`) whose stream ends before its end marker, a copy cut short: read up to
  the cut;
- ``heading_spread``: a cycle that held a heading sentence (HDT, THS, HDG) more than once from one talker
  (a 10 Hz gyro beside a 1 Hz receiver), cut into one cycle per heading, spread evenly in time up to the
  next cycle (`spread_headings`): each heading used at its own time, as live;
- ``line_prefix``: a line whose sentence came after a logger's time stamp or a TAG block, taken off
  (`gateway.line_prefix`); ``tag GP0001``: the lines whose TAG block named the device GP0001.

Truncated lines, garbage and checksum failures are counted by the pipeline's framer and decoder.

**tlogs** (QGroundControl, MAVProxy, pymavlink): each record is an 8-byte big-endian time stamp (µs since
1970) followed by one MAVLink v1 or v2 frame. A record that does not start a frame is counted (``bad_record``)
and the reader resynchronises on the next plausible record.
"""

from __future__ import annotations

import io
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from pathlib import Path
from typing import BinaryIO

import numpy as np

from gateway.compressed import open_log, was_cut
from gateway.line_prefix import inner_of, open_text_log, prefixes_stripped, tag_devices
from gateway.pipeline import RawEvent
from wire.codecs.nmea_encode import checksum
from wire.codecs.nmea_framing import DEFAULT_MAX_LENGTH
from wire.codecs.nmea_scan import (
    CLEAN,
    DIRTY,
    DUPLICATE,
    TIME_ASK,
    TIME_OK,
    LineScan,
    scan_lines,
    used_codes,
)
from wire.codecs.nmea_time import time_of_day_or_none
from wire.tlog import RECORD_TIME

NS = 1_000_000_000
DAY_NS = 86_400 * NS
MAX_TIME_NS = 2**63 - 1  # a signed 64-bit nanosecond count (until 2262): what every stamp must fit in
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
    if not line.startswith("$") or star < 0 or len(line) < star + 3 or not line.isascii():
        return None
    if checksum(line[1:star]) != line[star + 1 : star + 3].upper():
        return None
    return line[1:star].split(",")


def behind_tag(line: bytes) -> bytes:
    """A line without the TAG block it starts with, if any (a network capture's line kept whole:
    `gateway.line_prefix.open_text_log` with ``keep_tags``)."""
    return line if line[:1] != b"\\" else line[line.find(b"\\", 1) + 1 :]


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
    return time_of_day_or_none(line[k : line.find(b",", k)].decode("ascii", "replace"))


def _sentence_time(line: str) -> tuple[float | None, date | None]:
    kind = line[3:6] if len(line) > 6 else ""
    if kind not in TIMED:
        return None, None
    fields = _checked_fields(line.rstrip("\r\n"))
    if fields is None:
        return None, None
    tod = (
        time_of_day_or_none(fields[5 if kind == "GLL" else 1])
        if len(fields) > (5 if kind == "GLL" else 1)
        else None
    )
    return tod, _date(fields, kind)


def count_reading(f: BinaryIO, c: LogCounts) -> None:
    """Count ``<format>_cut`` (``gzip_cut``, ``xz_cut``, ...) in ``c`` if `open_log`'s file ``f`` (or
    `open_text_log`'s), read to its end, ended at a cut in its compressed stream; the lines whose
    prefix `open_text_log` took off (``line_prefix``); and the lines of each device a TAG block named
    (``tag GP0001``)."""
    if (compression := was_cut(inner_of(f))) is not None:
        c.counts[f"{compression.name}_cut"] += 1
    if stripped := prefixes_stripped(f):
        c.counts["line_prefix"] += stripped
    for device, n in tag_devices(f).items():
        c.counts[f"tag {device}"] += n


def _first_date(path: Path, limit: int = 2000) -> date | None:
    with io.TextIOWrapper(open_text_log(path), encoding="ascii", errors="replace", newline="") as f:
        for k, line in enumerate(f):
            if k >= limit:
                break
            _, d = _sentence_time(line.strip())
            if d is not None:
                return d
    return None


class _TimeKeeper:
    """Cycle times of a text log: the date and midnight rollover for each time of day, and the bad-time
    counts when a cycle starts (module docstring). Shared by both readers."""

    def __init__(self, day_ns: int, gap_s: float, counts: LogCounts) -> None:
        self.day_ns = day_ns
        self.gap_ns = gap_s * NS
        self.counts = counts
        self.last_tod: float | None = None
        self.latest_ns = -1
        self.seen: set[int] = set()

    def stamp(self, tod: float) -> int:
        """UTC ns of a time of day, the day moved on (or back) across midnight."""
        last = self.last_tod
        if last is not None and tod < last - 43_200:
            self.day_ns += DAY_NS  # midnight rollover
        elif last is not None and tod > last + 43_200:
            self.day_ns -= DAY_NS  # a late sentence from before midnight
        self.last_tod = tod
        return self.day_ns + round(tod * 1e9)

    def start_cycle(self, t_ns: int) -> None:
        """Count what is wrong with a new cycle's time: a gap, going backwards, a repeat."""
        c = self.counts.counts
        if self.latest_ns >= 0:
            if t_ns < self.latest_ns:
                c["repeated_time" if t_ns in self.seen else "time_backwards"] += 1
            elif t_ns - self.latest_ns > self.gap_ns:
                c["time_gap"] += 1
        self.latest_ns = max(self.latest_ns, t_ns)
        if len(self.seen) > 100_000:
            self.seen.clear()
        self.seen.add(t_ns)


def nmea_text_events_reference(
    path: str | Path,
    source: str = "nmea",
    *,
    base_date: date | None = None,
    gap_s: float = 5.0,
    counts: LogCounts | None = None,
    keep_tags: bool = False,
) -> Iterator[RawEvent]:
    """One `RawEvent` per cycle of a raw NMEA text log (see module docstring): the readable reference,
    line by line. `nmea_text_events` gives the same events and counts, faster.

    With ``keep_tags``, the lines keep their TAG blocks (`gateway.line_prefix.open_text_log`), and a
    sentence's time is read behind its block: a capture of a ship's network whose devices
    `gateway.line_prefix.split_by_device` tells apart afterwards."""
    path = Path(path)
    c = counts if counts is not None else LogCounts()
    day = _first_date(path) or base_date or DEFAULT_BASE_DATE
    day_ns = int(datetime(day.year, day.month, day.day, tzinfo=UTC).timestamp()) * NS
    lines: list[bytes] = []
    cycle_ns: int | None = None
    clock = _TimeKeeper(day_ns, gap_s, c)
    previous = b""
    with open_text_log(path, keep_tags) as f:
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
            body = behind_tag(line)
            if body[:1] == b"$" and body[3:6] in (b"GGA", b"GNS", b"RMC", b"ZDA", b"GLL"):
                # Most timed sentences repeat their cycle's time: only a new time needs the checksum
                # (a damaged time field must not start a cycle).
                quick = _unchecked_time(body)
                if quick is not None and quick == clock.last_tod:
                    tod = quick
                else:
                    tod, _ = _sentence_time(body.decode("ascii", "replace"))
            if tod is not None:
                t_ns = clock.stamp(tod)
                if t_ns != cycle_ns:
                    if lines and cycle_ns is not None:
                        yield RawEvent(cycle_ns, source, b"\r\n".join(lines) + b"\r\n", cycle=True)
                        c.cycles += 1
                        lines = []
                    clock.start_cycle(t_ns)
                    cycle_ns = t_ns
            lines.append(line)
        count_reading(f, c)
    if lines:
        if cycle_ns is None:
            c.counts["no_time"] += len(lines)  # a log with no timed sentence at all: nothing to replay
        else:
            yield RawEvent(cycle_ns, source, b"\r\n".join(lines) + b"\r\n", cycle=True)
            c.cycles += 1


_HEADINGS = (b"HDT", b"THS", b"HDG")
_HEADING_FIELDS = tuple(h + b"," for h in _HEADINGS)  # (the formatter and its comma: what a cycle holds)


def spread_headings(events: Iterator[RawEvent], counts: LogCounts) -> Iterator[RawEvent]:
    """The cycles of a text log reader, each cycle that holds a heading sentence more than once from one
    talker cut into one cycle per heading.

    A text log times untimed sentences by their cycle, from one fix's time to the next. A gyro sending at
    10 Hz beside a receiver at 1 Hz puts ten headings in each cycle, all at the fix's time: the observer
    would take the last, and the reference checks refuse the other nine as jumps at no time apart
    (measured on such a log: 5,843 of 6,000 headings refused ``test_jump``). The lines arrived in order
    between the fix and the next one, so each heading starts a cycle of its own (the first one stays with
    the fix), the ``m`` cycles spread evenly over the time to the next cycle: ``t + j (t_next - t) / m``.
    The last cycle of the log spreads over the span the cycle before it had (1 s with none). Counted
    (``heading_spread``: the cycles so made). A cycle the reader had checked (every line a clean sentence:
    `RawEvent.checked`) is cut with its checked texts; the others go on as they came.

    A capture cut by device (`gateway.line_prefix.split_by_device`) gives one event per source at each
    cycle's time: they are spread together, each over the time to the next cycle, and come out in time
    order."""
    held: RawEvent | None = None
    more: list[RawEvent] = []  # other sources' events at ``held``'s time (a capture cut by device)
    span = NS
    for ev in events:
        if held is not None:
            if (
                ev.rx_ns == held.rx_ns
                and ev.source != held.source
                and all(m.source != ev.source for m in more)
            ):
                more.append(ev)
                continue
            if ev.rx_ns > held.rx_ns:
                span = ev.rx_ns - held.rx_ns
            if more:
                yield from _spread_together([held, *more], span, counts)
                more = []
            else:
                yield from _spread(held, span, counts)
        held = ev
    if held is not None:
        yield from _spread_together([held, *more], span, counts)


def _spread_together(held: list[RawEvent], span: int, counts: LogCounts) -> Iterator[RawEvent]:
    """The events of one cycle's time, one per source, each spread (`_spread`), in time order."""
    parts = [part for ev in held for part in _spread(ev, span, counts)]
    parts.sort(key=lambda e: e.rx_ns)  # (stable: at one time, the order the lines came)
    yield from parts


def _spread(ev: RawEvent, span: int, counts: LogCounts) -> Iterator[RawEvent]:
    data = ev.data
    if sum(data.count(h) for h in _HEADING_FIELDS) < 2:  # (most cycles: at once)
        yield ev
        return
    lines = data.split(b"\r\n")[:-1]  # (a cycle's lines, each ended by CR LF)
    starts = [0]
    seen: set[bytes] = set()
    for i, line in enumerate(lines):
        line = behind_tag(line)
        if line[:1] == b"$" and line[3:6] in _HEADINGS:
            kind = line[1:6]  # talker and formatter
            if kind in seen:
                starts.append(i)
                seen.clear()
            seen.add(kind)
    if len(starts) == 1:
        yield ev
        return
    m = len(starts)
    counts.counts["heading_spread"] += m - 1
    starts.append(len(lines))
    texts = ev.checked[0] if ev.checked is not None else ()
    p = 0  # the next of the cycle's used texts (in line order)
    for j in range(m):
        part = lines[starts[j] : starts[j + 1]]
        checked: tuple[tuple[str, ...], int] | None = None
        if ev.checked is not None:  # (every line clean: the used ones among them, and how many others)
            used: list[str] = []
            for line in part:
                if p < len(texts) and line == texts[p].encode("ascii"):
                    used.append(texts[p])
                    p += 1
            checked = (tuple(used), len(part) - len(used))
        yield RawEvent(ev.rx_ns + span * j // m, ev.source, b"\r\n".join(part) + b"\r\n", checked, cycle=True)


BLOCK_BYTES = 4 << 20
"""Bytes read and scanned at a time by `nmea_text_events` (whole lines; a longer line grows the block)."""


class _Cycle:
    """The lines of the cycle being gathered (possibly over several blocks)."""

    __slots__ = ("count", "dirty", "lines", "others", "texts")

    def __init__(self) -> None:
        self.lines: list[bytes] = []  # lines, or runs of CR LF separated lines, to join with CR LF
        self.count = 0
        self.texts: list[str] = []
        self.others = 0
        self.dirty = False

    def event(self, rx_ns: int, source: str) -> RawEvent:
        checked = None if self.dirty else (tuple(self.texts), self.others)
        return RawEvent(rx_ns, source, b"\r\n".join(self.lines) + b"\r\n", checked, cycle=True)


def nmea_text_events(
    path: str | Path,
    source: str = "nmea",
    *,
    base_date: date | None = None,
    gap_s: float = 5.0,
    counts: LogCounts | None = None,
    only: frozenset[str] | None = None,
    block_bytes: int = BLOCK_BYTES,
) -> Iterator[RawEvent]:
    """One `RawEvent` per cycle of a raw NMEA text log (see module docstring) — the events and counts of
    `nmea_text_events_reference`, with the per-line work done block by block by the compiled scan
    (`wire.codecs.nmea_scan`); only the cycle boundaries are decided in Python.

    Events whose lines are all clean sentences carry ``checked`` (see `RawEvent`): the texts of the
    sentences whose formatter is in ``only`` (all, if None) and the count of the rest. Give as ``only``
    the pipeline's `USED_NMEA` (or a superset): the pipeline counts the rest without parsing them.
    """
    path = Path(path)
    c = counts if counts is not None else LogCounts()
    day = _first_date(path) or base_date or DEFAULT_BASE_DATE
    day_ns = int(datetime(day.year, day.month, day.day, tzinfo=UTC).timestamp()) * NS
    used = used_codes(only) if only is not None else None
    cycle = _Cycle()
    cycle_ns: int | None = None
    clock = _TimeKeeper(day_ns, gap_s, c)
    prev = b""
    with open_text_log(path) as f:
        tail = b""
        while True:
            chunk = f.read(block_bytes)
            data = tail + chunk
            if chunk:
                cut = data.rfind(b"\n") + 1
                if cut == 0:
                    tail = data
                    continue
                data, tail = data[:cut], data[cut:]
            elif not data:
                break
            buf = np.frombuffer(data, dtype=np.uint8)
            scan = scan_lines(buf, prev, used if used is not None else _ALL, DEFAULT_MAX_LENGTH)
            prev = scan.last.tobytes()
            block = _Block(data, scan, used is not None)
            c.lines += block.n
            duplicates = int(np.count_nonzero(scan.kind == DUPLICATE))
            if duplicates:
                c.counts["duplicate"] += duplicates
            # The lines where a new time may start a cycle; a clean timed line repeating the time of the
            # timed line just before it changes nothing in the reference and is skipped here.
            ts = scan.time_status
            idx = np.flatnonzero((ts == TIME_OK) | (ts == TIME_ASK))
            if len(idx) > 1:
                ok = ts[idx] == TIME_OK
                tods = scan.tod[idx]
                repeat = np.concatenate(([False], ok[1:] & ok[:-1] & (tods[1:] == tods[:-1])))
                idx = idx[~repeat]
            first = 0  # first line of the current cycle in this block
            time_ok = (ts[idx] == TIME_OK).tolist()
            tod_at = scan.tod[idx].tolist()
            for li, is_ok, tod_k in zip(idx.tolist(), time_ok, tod_at, strict=True):
                if is_ok:
                    tod: float | None = tod_k
                else:
                    line = block.line(li)
                    quick = _unchecked_time(line)
                    if quick is not None and quick == clock.last_tod:
                        tod = quick
                    else:
                        tod, _ = _sentence_time(line.decode("ascii", "replace"))
                if tod is None:
                    continue
                t_ns = clock.stamp(tod)
                if t_ns != cycle_ns:
                    if cycle_ns is not None:
                        block.add_to(cycle, first, li)
                        first = li
                        if cycle.lines:
                            yield cycle.event(cycle_ns, source)
                            c.cycles += 1
                            cycle = _Cycle()
                    clock.start_cycle(t_ns)
                    cycle_ns = t_ns
            block.add_to(cycle, first, block.n)
            if not chunk:
                break
        count_reading(f, c)
    if cycle.lines:
        if cycle_ns is None:
            c.counts["no_time"] += cycle.count
        else:
            yield cycle.event(cycle_ns, source)
            c.cycles += 1


_ALL = np.zeros(0, dtype=np.int64)  # no formatter list: every clean sentence counts as used


class _Block:
    """One scanned block of whole lines, handed out to cycles as runs of lines [a, b) in line order."""

    def __init__(self, data: bytes, scan: LineScan, only_given: bool) -> None:
        kind = scan.kind
        self.data = data
        self.n = len(kind)
        kept = kind >= CLEAN  # lines that belong to a cycle
        used = scan.used if only_given else kind == CLEAN
        # prefix counts, to judge a run of lines at once
        self.n_kept = _prefix(kept)
        self.n_dirty = _prefix(kind == DIRTY)
        self.n_plain = _prefix(kept & scan.crlf)  # kept and ending in exactly CR LF
        self.n_other = _prefix((kind == CLEAN) & ~used)
        self.start, self.end, self.kept = scan.start.tolist(), scan.end.tolist(), kept.tolist()
        self.used_at = [*np.flatnonzero(used).tolist(), self.n]  # (a sentinel at the end)
        self.up = 0  # next entry of used_at

    def line(self, k: int) -> bytes:
        return self.data[self.start[k] : self.end[k]]

    def add_to(self, cycle: _Cycle, a: int, b: int) -> None:
        """Add lines [a, b) to ``cycle`` (the runs come in line order)."""
        used_at = self.used_at
        while used_at[self.up] < a:
            self.up += 1
        if b <= a or self.n_kept[b] == self.n_kept[a]:
            return
        cycle.count += self.n_kept[b] - self.n_kept[a]
        if self.n_dirty[b] != self.n_dirty[a]:
            cycle.dirty = True
        cycle.others += self.n_other[b] - self.n_other[a]
        while used_at[self.up] < b:
            if not cycle.dirty:
                cycle.texts.append(self.line(used_at[self.up]).decode("ascii"))
            self.up += 1
        data, start, end = self.data, self.start, self.end
        if self.n_plain[b] - self.n_plain[a] == b - a:
            cycle.lines.append(data[start[a] : end[b - 1]])  # contiguous CR LF lines: one slice
        else:
            cycle.lines.extend(data[start[k] : end[k]] for k in range(a, b) if self.kept[k])


def _prefix(flags: np.ndarray) -> list[int]:
    """[0, f0, f0+f1, ...]: the number of true flags before each line index."""
    return [0, *np.cumsum(flags, dtype=np.int64).tolist()]


_V1, _V2 = 0xFE, 0xFD


def tlog_events(
    path: str | Path, source: str = "mavlink", counts: LogCounts | None = None
) -> Iterator[RawEvent]:
    """MAVLink frames of a tlog with their recorded times."""
    c = counts if counts is not None else LogCounts()
    with open_log(path) as f:
        data = f.read()
        count_reading(f, c)
    i, n = 0, len(data)
    while i + 9 <= n:
        (t_us,) = RECORD_TIME.unpack_from(data, i)
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
        if t_us * 1000 > MAX_TIME_NS:  # not a time (garbage, or not a tlog): no log could stamp it
            c.counts["bad_time"] += 1
        else:
            yield RawEvent(t_us * 1000, source, data[j : j + size])
        i = j + size
