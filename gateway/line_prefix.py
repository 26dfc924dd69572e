"""NMEA text logs whose lines carry something before the sentence: a receive time stamped by the logger
(``2024-12-07T03:25:51.050Z $GPGGA,...``, ``2024-12-07 03:25:51.050,$GPGGA,...``) or an NMEA 4.10 / IEC
61162-450 TAG block (``\\s:GP0001,c:1733541951*47\\$GPGGA,...``, in a raw capture of a ship's network
after the datagram header ``UdPbC\\0``), as data loggers and ship networks write them. Replay reads the
sentences as they are without the prefix: the prefix is taken off each line that has one, and counted
(``line_prefix``), so that the log replays as its plain twin does.

A capture whose TAG blocks name several devices (two receivers and a gyro on one multicast group) is
not one source: two receivers' fixes taken as one receiver's jump between the antennas at every cycle.
Such a capture keeps its TAG blocks (`open_text_log` with ``keep_tags``; only the datagram headers and
a logger's stamps come off) and each cycle's lines are cut by device (`split_by_device`), so that replay
feeds each device to a source of its own that takes that device (``tag_source``), as the gateway does
live on the network: the pipeline reads the TAG blocks then, and counts the lines lost upstream from
their line counts. `capture_devices` finds the devices and what each sends.

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
from collections.abc import Iterator, Mapping
from typing import Any, BinaryIO, NamedTuple

from gateway.compressed import open_log
from gateway.pipeline import RawEvent
from wire.codecs.nmea_tag import SOURCE

PREFIX = re.compile(rb"(?m)^(?:(?:UdPbC\x00)?\\[^\\\r\n]*\\|[0-9][-0-9TZ:./+ ,;\t]*[ ,;\t])(?=[$!][A-Z]{2})")
"""A prefix before a sentence at a line's start (a TAG block, after the IEC 61162-450 datagram header
where a capture of a ship's network has it, or a written date and time and a separator)."""

DEVICE = re.compile(rb"(?m)^(?:UdPbC\x00)?\\(?:[^\\\r\n]*,)?s:([^,*\\\r\n]+)")
"""The device a line's TAG block names (``s:``)."""

KEPT_TAG_PREFIX = re.compile(
    rb"(?m)^(?:UdPbC\x00(?=\\)|[0-9][-0-9TZ:./+ ,;\t]*[ ,;\t](?=(?:\\[^\\\r\n]*\\)?[$!][A-Z]{2}))"
)
"""What `open_text_log` takes off a line with ``keep_tags``: the datagram header before a TAG block, or a
logger's written date and time before a TAG block or a sentence."""

DEVICE_SENTENCE = re.compile(
    rb"(?m)^(?:UdPbC\x00)?\\(?:[^\\\r\n]*,)?s:([^,*\\\r\n]+)[^\\\r\n]*\\[$!][A-Z]{2}([A-Z]{3})"
)
"""A line's device (``s:``) and its sentence's formatter (``GGA``)."""

UNTAGGED = re.compile(rb"(?m)^(?:[0-9][-0-9TZ:./+ ,;\t]*[ ,;\t])?[$!][A-Z]{2}")
"""A sentence without a TAG block at a line's start (after a logger's stamp, if any)."""

MAX_DEVICES = 64
"""Devices of a capture replayed as sources of their own (the live pipeline follows as many senders a
source): beyond them, a device's lines go to the capture's own source."""

BLOCK_BYTES = 1 << 20


class Unprefixed(io.RawIOBase):
    """The bytes of ``inner`` with each line's prefix (`PREFIX`; with ``keep_tags``, `KEPT_TAG_PREFIX`)
    taken off; ``stripped`` counts them, and ``devices`` the lines of each device the TAG blocks name."""

    def __init__(self, inner: BinaryIO, keep_tags: bool = False) -> None:
        self.inner = inner
        self.prefix = KEPT_TAG_PREFIX if keep_tags else PREFIX
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
            self._pending, n = self.prefix.subn(b"", block)
            self.stripped += n
        n = min(len(buffer), len(self._pending))
        buffer[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n

    def close(self) -> None:
        self.inner.close()
        super().close()


def open_text_log(path: Any, keep_tags: bool = False) -> BinaryIO:
    """An NMEA text log's bytes (decompressed, `gateway.compressed.open_log`), its lines' prefixes taken
    off when its first buffer holds any; with ``keep_tags``, its TAG blocks left on (`KEPT_TAG_PREFIX`)."""
    f = open_log(path)
    if PREFIX.search(f.peek(1 << 16)) is None:  # (what is buffered: 8 KiB, a hundred lines)
        return f
    return io.BufferedReader(Unprefixed(f, keep_tags), BLOCK_BYTES)


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


class CaptureDevices(NamedTuple):
    """What `capture_devices` found in a text log."""

    devices: dict[str, frozenset[str]]
    """Each device a TAG block names (``s:``), in the order they first appear, with the formatters of
    the sentences it sent."""
    others: int
    """Sentences that name no device (no TAG block), or one left out: not a device's name
    (`wire.codecs.nmea_tag.SOURCE`), or after the first `MAX_DEVICES`."""


def capture_devices(path: Any) -> CaptureDevices:
    """The devices a text log's TAG blocks name, and how many sentences are nobody's; nothing when the
    log's first buffer holds no TAG block naming a device (a plain log is not read through twice)."""
    found: dict[str, set[str]] = {}
    others = 0
    with open_log(path) as f:
        if DEVICE.search(f.peek(1 << 16)) is None:
            return CaptureDevices({}, 0)
        while block := f.read(BLOCK_BYTES):
            if not block.endswith(b"\n"):
                block += f.readline()  # (whole lines)
            others += len(UNTAGGED.findall(block))
            for device, formatter in DEVICE_SENTENCE.findall(block):
                name = device.decode("ascii", "replace")
                kinds = found.get(name)
                if kinds is None:
                    if len(found) >= MAX_DEVICES or not SOURCE.fullmatch(name):
                        others += 1
                        continue
                    kinds = found[name] = set()
                kinds.add(formatter.decode("ascii"))
    return CaptureDevices({name: frozenset(kinds) for name, kinds in found.items()}, others)


def line_device(line: bytes) -> str | None:
    """The device a line's TAG block names (``s:``), None without one."""
    m = DEVICE.match(line)
    return None if m is None else m[1].decode("ascii", "replace")


def split_by_device(events: Iterator[RawEvent], source_of: Mapping[str, str]) -> Iterator[RawEvent]:
    """Each cycle (or a stamped read, `gateway.stamped_log`) of a capture kept with its TAG blocks
    (`open_text_log` with ``keep_tags``) as one event per source, at the event's time: a line goes to the
    source of the device its TAG block names (``source_of``), else to the event's own source. A TAG block
    without ``s:`` (NMEA 4.10 lets the later lines of a group carry only ``g:``) goes with the line before
    it, as one datagram's lines. The sources come in the order their first line came."""
    for ev in events:
        if b"\\" not in ev.data:
            yield ev
            continue
        parts: dict[str, list[bytes]] = {}
        where = ev.source
        for line in ev.data.split(b"\r\n")[:-1]:  # (a cycle's lines, each ended by CR LF)
            if line[:1] == b"\\":
                device = line_device(line)
                where = source_of.get(device, ev.source) if device is not None else where
            else:
                where = ev.source
            parts.setdefault(where, []).append(line)
        for source, lines in parts.items():
            yield RawEvent(ev.rx_ns, source, b"\r\n".join(lines) + b"\r\n", cycle=ev.cycle)
