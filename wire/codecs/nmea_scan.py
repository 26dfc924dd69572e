"""Batch line scan of NMEA text (replay's fast path): one compiled pass over a buffer of whole lines.

Replay must take a raw NMEA log at >= 100,000 sentences/s. Per line, Python pays ~2 µs just to
iterate, frame and checksum a sentence, before any decoding. This kernel does, for every line of a block
at once, the checks that decide whether the ordinary path (framer → decoder) would see the line as one
clean, checksum-verified sentence:

* ``CLEAN``: starts with ``$``; every other byte printable ASCII other than ``$``/``!`` (the framer's
  sentence bytes); at most ``max_length`` long; the first ``*`` three from the end, followed by two hex
  digits equal to the XOR of the bytes between ``$`` and ``*`` — exactly what `NmeaFramer.feed` frames
  as one ``Frame(text=line)`` and `nmea.decode` accepts as checksummed. ``used`` says whether ``decode``
  with ``only=`` would parse it (its formatter is in ``only``, or it is proprietary, ``$P…``).
* ``DIRTY``: anything else (truncated, garbage, bad checksum, AIS, non-ASCII …): the caller sends such
  lines down the ordinary path, which counts them with their reasons. Nothing is decided here.
* ``BLANK`` and ``DUPLICATE`` (identical to the previous non-blank line), as `logreaders` counts them.

and, for the timed sentences GGA/GNS/RMC/ZDA (field 1 = hhmmss[.s…]), the time of day in seconds: the
compiled copy of the one readable parser `wire.codecs.nmea_time.parse_time_of_day`, ``h*3600 + m*60 + s``
with ``s`` parsed exactly (at most 11 significant digits divided by a power of ten is the correctly
rounded float, the value ``float()`` gives). tests/test_nmea_scan.py holds the two to the same value on
generated fields (hypothesis). Lines whose time the kernel does not decide — GLL (time in field 5), a
dirty timed line, an unusual time format — are marked ``TIME_ASK`` for the reader to evaluate with the
readable parser.

The readable reference is the ordinary path itself: tests/test_replay.py checks that the fast reader
gives the same events, counts and pipeline outputs as `logreaders.nmea_text_events_reference` on the
real logs and on generated logs full of damage.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numba import njit
from numpy.typing import NDArray

BLANK, DUPLICATE, CLEAN, DIRTY = 0, 1, 2, 3
TIME_NONE, TIME_OK, TIME_ASK = 0, 1, 2


def formatter_code(formatter: str) -> int:
    """A three-letter sentence formatter (``"GGA"``) as the int the kernel compares."""
    b = formatter.encode("ascii")
    return b[0] << 16 | b[1] << 8 | b[2]


TIMED_CODES = np.array([formatter_code(f) for f in ("GGA", "GNS", "RMC", "ZDA")], dtype=np.int64)
GLL_CODE = formatter_code("GLL")


def used_codes(only: Iterable[str]) -> NDArray[np.int64]:
    return np.array([formatter_code(f) for f in only if len(f) == 3], dtype=np.int64)


@njit(cache=True)
def _hex(c: int) -> int:
    if 48 <= c <= 57:
        return c - 48
    if 65 <= c <= 70:
        return c - 55
    if 97 <= c <= 102:
        return c - 87
    return -1


@njit(cache=True)
def _same(buf, a0, a1, prev) -> bool:  # type: ignore[no-untyped-def]
    n = a1 - a0
    if n != prev.shape[0]:
        return False
    for k in range(n):  # noqa: SIM110 - numba compiles a loop, not all() over a generator
        if buf[a0 + k] != prev[k]:
            return False
    return True


@njit(cache=True)
def _time_field(buf, a, b):
    """Time of day (s) of buf[a:b] = hhmmss[.f{1,9}]: (status, seconds). The fast kernel of
    `nmea_time.parse_time_of_day`: TIME_OK with its value, TIME_NONE where it gives None or refuses the
    range, TIME_ASK for any other form (it decides those)."""
    n = b - a
    if n == 0:
        return TIME_NONE, 0.0
    if n < 6:
        return TIME_ASK, 0.0
    for k in range(6):
        if not (48 <= buf[a + k] <= 57):
            return TIME_ASK, 0.0
    h = (buf[a] - 48) * 10 + (buf[a + 1] - 48)
    m = (buf[a + 2] - 48) * 10 + (buf[a + 3] - 48)
    digits = (buf[a + 4] - 48) * 10 + (buf[a + 5] - 48)
    scale = 1
    if n > 6:
        if buf[a + 6] != 46 or n == 7 or n > 16:  # '.', then 1..9 digits
            return TIME_ASK, 0.0
        for k in range(a + 7, b):
            c = buf[k]
            if not (48 <= c <= 57):
                return TIME_ASK, 0.0
            digits = digits * 10 + (c - 48)
            scale *= 10
    s = float(digits) / float(scale)  # both exact: the quotient is float()'s correctly rounded value
    if h > 23 or m > 59 or s >= 61.0:
        return TIME_NONE, 0.0
    return TIME_OK, float(h * 3600 + m * 60) + s


@njit(cache=True)
def scan_kernel(buf, prev, used, max_length):
    """Scan buf (uint8, whole lines; the last may lack its line end) — see the module docstring.

    Returns per line: start, end (line terminators excluded), kind, used, crlf (ends in exactly CR LF),
    time status and time of day; and the last non-blank line (for the next block's duplicate check)."""
    n = buf.shape[0]
    lines = 0
    for i in range(n):
        if buf[i] == 10:
            lines += 1
    if n > 0 and buf[n - 1] != 10:
        lines += 1
    start = np.empty(lines, np.int64)
    end = np.empty(lines, np.int64)
    kind = np.empty(lines, np.int8)
    is_used = np.zeros(lines, np.bool_)
    crlf = np.zeros(lines, np.bool_)
    tstat = np.zeros(lines, np.int8)
    tod = np.zeros(lines, np.float64)
    p0 = -1  # previous non-blank line in this block: buf[p0:p1]
    p1 = -1
    i = 0
    for li in range(lines):
        a = i
        j = a
        while j < n and buf[j] != 10:
            j += 1
        nxt = j + 1
        b = j
        while b > a and (buf[b - 1] == 13 or buf[b - 1] == 10):
            b -= 1
        start[li] = a
        end[li] = b
        crlf[li] = j < n and b == j - 1 and buf[b] == 13
        i = nxt
        if b == a:
            kind[li] = BLANK
            continue
        if p0 >= 0:
            dup = b - a == p1 - p0
            if dup:
                for k in range(b - a):
                    if buf[a + k] != buf[p0 + k]:
                        dup = False
                        break
        else:
            dup = _same(buf, a, b, prev)
        if dup:
            kind[li] = DUPLICATE
            continue
        p0 = a
        p1 = b
        length = b - a
        clean = buf[a] == 36 and 6 <= length <= max_length
        if clean:
            x = 0
            star = -1
            for k in range(a + 1, b):
                c = buf[k]
                if c < 32 or c > 126 or c == 33 or c == 36:
                    clean = False
                    break
                if c == 42 and star < 0:
                    star = k
                elif star < 0:
                    x ^= c
            if clean:
                if star != b - 3:
                    clean = False
                else:
                    hi = _hex(buf[b - 2])
                    lo = _hex(buf[b - 1])
                    clean = hi >= 0 and lo >= 0 and hi * 16 + lo == x
        kind[li] = CLEAN if clean else DIRTY
        code = -1
        if length >= 6:
            code = int(buf[a + 3]) << 16 | int(buf[a + 4]) << 8 | int(buf[a + 5])
        if clean:
            if star - a < 6:
                kind[li] = DIRTY  # a body too short to hold a formatter: let the decoder say why
                clean = False
            else:
                u = buf[a + 1] == 80  # 'P': proprietary sentences are always decoded
                for k in range(used.shape[0]):
                    if used[k] == code:
                        u = True
                is_used[li] = u
        if buf[a] == 36 and code >= 0:
            timed = code == GLL_CODE
            for k in range(TIMED_CODES.shape[0]):
                if TIMED_CODES[k] == code:
                    timed = True
            if timed:
                if not clean or code == GLL_CODE or length < 8 or buf[a + 6] != 44:
                    tstat[li] = TIME_ASK
                else:
                    f = a + 7
                    g = f
                    while g < b and buf[g] != 44:
                        g += 1
                    if g >= b - 3:  # no comma after the time: the reference reads such a field two ways
                        tstat[li] = TIME_ASK
                    else:
                        st, sec = _time_field(buf, f, g)
                        tstat[li] = st
                        tod[li] = sec
    last = buf[p0:p1].copy() if p0 >= 0 else prev.copy()
    return start, end, kind, is_used, crlf, tstat, tod, last


class LineScan:
    """The arrays `scan_kernel` returns, by name."""

    __slots__ = ("crlf", "end", "kind", "last", "start", "time_status", "tod", "used")

    def __init__(self, result: tuple[NDArray, ...]) -> None:
        (self.start, self.end, self.kind, self.used, self.crlf, self.time_status, self.tod, self.last) = (
            result
        )


def scan_lines(buf: NDArray[np.uint8], prev: bytes, used: NDArray[np.int64], max_length: int) -> LineScan:
    """`scan_kernel` on a block (``buf``: uint8 view of whole lines); ``prev``: the last non-blank line of
    the previous block (b"" at the start)."""
    return LineScan(scan_kernel(buf, np.frombuffer(prev, dtype=np.uint8), used, max_length))
