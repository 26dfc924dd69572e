"""NMEA text logs whose lines carry something before the sentence: a receive time stamped by the logger
(``2024-12-07T03:25:51.050Z $GPGGA,...``, ``2024-12-07 03:25:51.050,$GPGGA,...``) or an NMEA 4.10 / IEC
61162-450 TAG block (``\\s:GP0001,c:1733541951*47\\$GPGGA,...``, in a raw capture of a ship's network
after the datagram header ``UdPbC\\0``), as data loggers and ship networks write them. Replay reads the
sentences as they are without the prefix: the prefix is taken off each line that has one, and counted
(``line_prefix``), so that the log replays as its plain twin does. A TAG block's device is not told apart
here: a text log is one source (a ship network's devices are told apart live, by a source's
``tag_source``, and a gateway's MCAP log replays them so).

What is taken off is only a TAG block (between two backslashes) or a run of the characters of a written
date and time (digits, ``-:./+TZ``, spaces, ``,;`` and tabs) starting with a digit and ending in a
separator, and only directly before a ``$`` or ``!``: a gpsd comment (``# ... $GPGGA``) and garbage stay as
they are, for the framer to count. The time in a prefix is not used: a text log's times come from its
sentences (`gateway.logreaders`), prefixed or not, so that both replay alike.

Interpreted on purpose, as `gateway.compressed` (a class deriving from `io.RawIOBase`); a log is looked at
once when it is opened (its first buffer), and one without prefixes is read as it was, at no cost.
"""

from __future__ import annotations

import io
import re
from collections import Counter
from typing import Any, BinaryIO

from gateway.compressed import open_log

PREFIX = re.compile(rb"(?m)^(?:(?:UdPbC\x00)?\\[^\\\r\n]*\\|[0-9][-0-9TZ:./+ ,;\t]*[ ,;\t])(?=[$!][A-Z]{2})")
"""A prefix before a sentence at a line's start (a TAG block, after the IEC 61162-450 datagram header
where a capture of a ship's network has it, or a written date and time and a separator)."""

DEVICE = re.compile(rb"(?m)^(?:UdPbC\x00)?\\(?:[^\\\r\n]*,)?s:([^,*\\\r\n]+)")
"""The device a line's TAG block names (``s:``)."""

BLOCK_BYTES = 1 << 20


class Unprefixed(io.RawIOBase):
    """The bytes of ``inner`` with each line's prefix (`PREFIX`) taken off; ``stripped`` counts them, and
    ``devices`` the lines of each device the TAG blocks name."""

    def __init__(self, inner: BinaryIO) -> None:
        self.inner = inner
        self.stripped = 0
        self.devices: Counter[str] = Counter()
        self._pending = b""

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        while not self._pending:
            block = self.inner.read(BLOCK_BYTES)
            if not block:
                return 0
            if not block.endswith(b"\n"):
                block += self.inner.readline()  # (whole lines: a prefix is never split)
            if b"\\" in block:
                self.devices.update(d.decode("ascii", "replace") for d in DEVICE.findall(block))
            self._pending, n = PREFIX.subn(b"", block)
            self.stripped += n
        n = min(len(buffer), len(self._pending))
        buffer[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n

    def close(self) -> None:
        self.inner.close()
        super().close()


def open_text_log(path: Any) -> BinaryIO:
    """An NMEA text log's bytes (decompressed, `gateway.compressed.open_log`), its lines' prefixes taken
    off when its first buffer holds any."""
    f = open_log(path)
    if PREFIX.search(f.peek(1 << 16)) is None:  # (what is buffered: 8 KiB, a hundred lines)
        return f
    return io.BufferedReader(Unprefixed(f), BLOCK_BYTES)


def inner_of(f: BinaryIO) -> BinaryIO:
    """The log file under `open_text_log`'s prefix stripping (``f`` itself when there is none)."""
    raw = getattr(f, "raw", None)
    return raw.inner if isinstance(raw, Unprefixed) else f


def prefixes_stripped(f: BinaryIO) -> int:
    """How many lines of `open_text_log`'s file ``f`` had their prefix taken off so far."""
    raw = getattr(f, "raw", None)
    return raw.stripped if isinstance(raw, Unprefixed) else 0


def tag_devices(f: BinaryIO) -> Counter[str]:
    """How many lines of `open_text_log`'s file ``f`` each device named in a TAG block sent, so far."""
    raw = getattr(f, "raw", None)
    return raw.devices if isinstance(raw, Unprefixed) else Counter()
