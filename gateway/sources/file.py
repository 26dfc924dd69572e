"""A file read as a stream (``file://``), as fast as possible, at a line rate, or paced by the NMEA time."""

from __future__ import annotations

import logging
import os
import re
import threading
import time
from typing import IO

from gateway.sources.base import READ_SIZE, Source, SourceError, strerror
from wire.codecs.nmea_time import time_of_day_or_none

log = logging.getLogger(__name__)

_NMEA_TIME = re.compile(rb"^[$!][A-Z]{2}(GGA|RMC|ZDA|GNS|GST|GBS|GRS|GLL),")


def nmea_time_of_day(line: bytes) -> float | None:
    """UTC seconds of day of an NMEA sentence that carries one (GGA, RMC, ZDA, GNS, GST, GBS, GRS, GLL)."""
    m = _NMEA_TIME.match(line)
    if m is None:
        return None
    fields = line.rstrip(b"\r\n").split(b"*", 1)[0].split(b",")
    index = 5 if m.group(1) == b"GLL" else 1
    if len(fields) <= index:
        return None
    return time_of_day_or_none(fields[index].decode("ascii", "replace"))


class FileSource(Source):
    """A file read as a stream, for tests and demos (log replay proper is a separate module).

    ``rate``:

    * ``"fast"`` — as fast as ``deliver`` takes it, in chunks of whole lines (up to 64 KiB);
    * ``"realtime"`` — line by line, paced by the UTC time of day in the NMEA sentences that carry one
      (GGA, RMC, ZDA, GNS, GST, GBS, GRS, GLL); lines without a time follow the timed line before them at
      once; a step back in time or forward by more than `MAX_GAP_S` is not waited for (midnight wraps are).
      A file without timed sentences (MAVLink, gyro only) is delivered at once: give a rate in Hz;
    * a number — that many lines per second.

    At the end of the file the source stops delivering, ``finished`` becomes True and ``stats.connected``
    False. `write` returns False.
    """

    kind = "file"
    MAX_GAP_S = 60.0

    def __init__(
        self, name: str, url: str, path: str, rate: str | float = "realtime", *, timeout_s: float = 2.0
    ) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.path = path
        self.rate = rate
        self._file: IO[bytes] | None = None
        self._finished = threading.Event()

    @property
    def finished(self) -> bool:
        """The whole file was delivered."""
        return self._finished.is_set()

    def _open(self) -> None:
        path = self.path
        if not os.path.exists(path):
            raise SourceError(self.name, self.url, f"file {path} does not exist", "check the path")
        if os.path.isdir(path):
            raise SourceError(self.name, self.url, f"{path} is a directory", "give a file")
        try:
            self._file = open(path, "rb")  # noqa: SIM115 — owned by the source, closed in _close
        except OSError as exc:
            raise SourceError(
                self.name, self.url, f"cannot read {path}: {strerror(exc)}", "check permissions"
            ) from exc
        self.stats.connected = True

    def _run(self) -> None:
        f = self._file
        assert f is not None
        done = self._run_fast(f) if self.rate == "fast" else self._run_paced(f)
        if done:
            self._finished.set()
            log.info("source %r: end of file %s", self.name, self.path)
        self.stats.connected = False

    def _run_fast(self, f: IO[bytes]) -> bool:
        rest = b""
        while not self._stop.is_set():
            block = f.read(READ_SIZE)
            if not block:
                if rest:
                    self._emit(rest)
                return True
            data = rest + block
            cut = data.rfind(b"\n") + 1
            if cut == 0 and len(data) < READ_SIZE:
                rest = data  # no line end yet: read on
                continue
            if cut == 0:
                cut = len(data)  # a long line or binary data: deliver as is
            rest = data[cut:]
            self._emit(data[:cut])
        return False

    def _run_paced(self, f: IO[bytes]) -> bool:
        hz = None if self.rate == "realtime" else float(self.rate)
        start = time.monotonic()
        n = 0
        anchor: float | None = None  # monotonic s of file time `elapsed` = 0
        elapsed = 0.0
        previous: float | None = None
        warned = False
        while not self._stop.is_set():
            line = f.readline(READ_SIZE)
            if not line:
                return True
            if hz is not None:
                due = start + n / hz
            else:
                t = nmea_time_of_day(line)
                due = time.monotonic()
                if t is not None:
                    if previous is not None:
                        step = t - previous
                        if step < -43200.0:
                            step += 86400.0  # past midnight
                        if 0.0 <= step <= self.MAX_GAP_S:
                            elapsed += step
                    previous = t
                    if anchor is None:
                        anchor = time.monotonic() - elapsed
                    due = anchor + elapsed
                elif anchor is None and not warned and n >= 1000:
                    warned = True
                    log.warning(
                        "source %r: no timed NMEA sentence in the first %d lines of %s; delivering at once "
                        "(give ?rate=HZ to pace it)",
                        self.name,
                        n,
                        self.path,
                    )
            n += 1
            if self._sleep(due - time.monotonic()):
                return False
            self._emit(line)
        return False

    def _close(self) -> None:
        f, self._file = self._file, None
        if f is not None:
            f.close()
        self.stats.connected = False
