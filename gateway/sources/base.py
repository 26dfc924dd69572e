"""What every gateway source shares: the `Source` interface and its reader thread, the `Chunk` it
delivers, `SourceError` for mistakes a person must fix, the counters (`SourceStats`) and the reconnect
back-off. The transports live in their own modules (`serial`, `udp`, `tcp`, `file`); `url` turns a URL into
one of them.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import ClassVar, Self

log = logging.getLogger(__name__)

#: Reconnect back-off (TCP client, serial port that went away): first wait, doubling up to the cap.
BACKOFF_FIRST_S = 0.5
BACKOFF_MAX_S = 10.0
#: Longest a reader thread blocks in one read, so `Source.stop` is prompt.
POLL_S = 0.2
#: How long `Source.stop` waits for the reader thread.
STOP_JOIN_S = 1.0
KERNEL_STAMP_SLACK_NS = 60_000_000_000
"""A kernel receive stamp further than this before the clock when read, or after it, is not believed: a
platform whose constant or layout differs, or a clock stepped in between. The data are then stamped when
read, as without one."""
READ_SIZE = 65536


# -------------------------------------------------------------------------------------------- the values


@dataclass(frozen=True)
class Chunk:
    """Bytes as one read returned them, with the time they were received."""

    source: str
    """Source name from the config."""
    data: bytes
    """Bytes as read: a UDP datagram, a serial read, a TCP segment, whole lines of a file."""
    rx_ns: int
    """Receive time, UTC ns since 1970 (``time.time_ns()``), taken right after the read returned."""
    rx_mono_ns: int
    """Receive time on the monotonic clock (``time.monotonic_ns()``): for ages and rates."""
    peer: str = ""
    """UDP/TCP peer ``host:port`` (``[v6]:port``) that sent it, for `Source.write` ``peer=``; else ``""``.

    Empty ``data`` from a TCP source marks the end of that peer's stream (its connection closed), so what
    the gateway holds of an unfinished sentence from it is counted then (`Source._end_of_stream`); a
    UDP datagram of no bytes reads the same way."""


class SourceError(Exception):
    """A source that cannot work as configured; a person must fix it.

    The message names the source, the problem, the URL and what to do, e.g. ``source 'gyro1': serial port
    /dev/ttyUSB9 does not exist (serial:///dev/ttyUSB9?baud=4800) — check the cable/udev name``.
    """

    def __init__(
        self, name: str, url: str, problem: str, fix: str = "", *, missing_port: bool = False
    ) -> None:
        self.name = name
        self.url = url
        self.problem = problem
        self.fix = fix
        self.missing_port = missing_port
        """The problem is a serial device that does not exist (a cable, a udev name, a simulator not started:
        ``--wait-for-ports`` runs without it); the start-up message groups these."""
        super().__init__(f"source {name!r}: {problem} ({url})" + (f" — {fix}" if fix else ""))


class SeveralSourcesError(SourceError):
    """Several sources that cannot open at start-up (a serial port missing, another's UDP port in use): all
    of them, so that a person fixes every one before the next try. Its own fields are the first's."""

    def __init__(self, errors: list[SourceError]) -> None:
        first = errors[0]
        super().__init__(first.name, first.url, first.problem, first.fix, missing_port=first.missing_port)
        self.errors = list(errors)
        self.args = ("; ".join(str(e) for e in errors),)

    def __str__(self) -> str:
        return str(self.args[0])


@dataclass
class SourceStats:
    """Counters of one source. Written by its reader thread (and `Source.write`); read by anyone.

    Plain attributes are safe to read at any time; use `snapshot` for a consistent copy (``errors`` may
    change while it is iterated).
    """

    bytes_received: int = 0
    chunks: int = 0
    last_rx_mono_ns: int | None = None
    """Monotonic ns of the last chunk; None before the first."""
    connected: bool = False
    """The link is up: serial port open, TCP connected, UDP socket bound, a client connected (tcp-listen),
    file being read."""
    reconnects: int = 0
    """Times the link came back after it was lost (TCP client reconnected, serial port reopened) or, for
    ``tcp-listen``, clients accepted after the first. Counted where the link comes back, never per read.
    UDP has no link to lose: 0."""
    last_disconnect: tuple[int, str] | None = None
    """When (UTC ns since 1970, ``time.time_ns()``) and why the link was last lost, in words (``connection
    to 127.0.0.1:4001 lost: closed by the server``); None while it never was. One tuple, set at once, so
    a reader never sees one loss's time with another's reason."""
    errors: Counter[str] = field(default_factory=Counter)
    """Problems by short, stable reason: ``"connect failed"``, ``"disconnected"``, ``"deliver raised"`` ..."""
    bytes_sent: int = 0
    last_error: str | None = None
    """The last problem in full (what the OS said), for a person."""
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False, compare=False)

    def count_error(self, reason: str, detail: str | None = None) -> None:
        with self._lock:
            self.errors[reason] += 1
            self.last_error = detail or reason

    def note_disconnect(self, why: str) -> None:
        """The link was lost (now), and why (`last_disconnect`): called where a link is lost, not per read."""
        self.last_disconnect = (time.time_ns(), why)

    def add_sent(self, n: int) -> None:
        with self._lock:
            self.bytes_sent += n

    def snapshot(self) -> SourceStats:
        """A copy that no thread changes."""
        with self._lock:
            return SourceStats(
                bytes_received=self.bytes_received,
                chunks=self.chunks,
                last_rx_mono_ns=self.last_rx_mono_ns,
                connected=self.connected,
                reconnects=self.reconnects,
                last_disconnect=self.last_disconnect,
                errors=Counter(self.errors),
                bytes_sent=self.bytes_sent,
                last_error=self.last_error,
            )


class Backoff:
    """Waits of BACKOFF_FIRST_S, doubling to BACKOFF_MAX_S; `reset` after a success."""

    def __init__(self, first: float = BACKOFF_FIRST_S, cap: float = BACKOFF_MAX_S) -> None:
        self.first = first
        self.cap = cap
        self.delay = first

    def next(self) -> float:
        delay = self.delay
        self.delay = min(self.delay * 2.0, self.cap)
        return delay

    def reset(self) -> None:
        self.delay = self.first


# ------------------------------------------------------------------------------------------- the base


class Source(ABC):
    """One input stream of the gateway. Create with `open_source`; `start` once, `stop` when done.

    Threading: `start` opens the transport in the calling thread (so a `SourceError` reaches the caller)
    and starts one daemon reader thread, which calls ``deliver`` for every chunk. An exception in
    ``deliver`` is counted (``errors["deliver raised"]``) and logged; reading goes on. `write` may be
    called from any thread.
    """

    kind: ClassVar[str] = ""

    def __init__(self, name: str, url: str, *, timeout_s: float = 2.0) -> None:
        self.name = name
        self.url = url
        self.timeout_s = timeout_s
        """How long a TCP connect attempt or a blocked write may take; the default of `is_stale`."""
        self.stats = SourceStats()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._deliver: Callable[[Chunk], None] | None = None
        self._started = False
        self._io_lock = threading.Lock()  # a write, and closing what a write uses
        self._logged: set[str] = set()

    # ---------------------------------------------------------------- public

    def start(self, deliver: Callable[[Chunk], None]) -> None:
        """Open the transport and start the reader thread. Raises `SourceError` if it cannot be opened.

        A source is started once; open a new one with `open_source` to start again.
        """
        if self._started or self._stop.is_set():
            raise RuntimeError(f"source {self.name!r} was already started or stopped: open a new one")
        self._open()
        self._deliver = deliver
        self._started = True
        thread = threading.Thread(target=self._main, name=f"dpgw-source-{self.name}", daemon=True)
        self._thread = thread
        thread.start()

    def probe(self) -> None:
        """Open the transport and close it again, without a reader thread: whether the source can open, for
        a start-up that stops and names every source that cannot. Raises `SourceError` as `start` does. A
        TCP client, which connects in its reader thread, opens nothing here (and says nothing: started, its
        thread's first retry warning came out before the start-up's one message)."""
        try:
            self._open()
        finally:
            self._close()

    def stop(self) -> None:
        """Stop reading and close the transport; waits up to ~1 s for the reader thread. Idempotent."""
        self._stop.set()
        self._interrupt()
        thread = self._thread
        if thread is None:
            self._close()  # never started (or start failed): release what _open may have made
            return
        if thread is not threading.current_thread():
            thread.join(STOP_JOIN_S)
            if thread.is_alive():
                log.warning(
                    "source %r: reader thread still busy after %.1f s (is deliver blocked?); it ends on "
                    "its own when deliver returns",
                    self.name,
                    STOP_JOIN_S,
                )

    @property
    def finished(self) -> bool:
        """The stream has ended for good (a file read to its end); never for a live link."""
        return False

    @property
    def running(self) -> bool:
        """The reader thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def write(self, data: bytes, peer: str | None = None) -> bool:
        """Send ``data`` back on the link; False if it cannot right now (not connected, no peer, timeout).

        ``peer`` (a `Chunk.peer`) picks the UDP peer or ``tcp-listen`` client; sources with one peer
        ignore it. Never raises for I/O problems; they are counted in ``stats.errors``.
        """
        return False

    @property
    def shared(self) -> bool:
        """Whether any number of senders can reach this link and `write` without a ``peer`` answers
        whoever spoke last (a listening UDP port) or everyone (a TCP server): what must reach one device
        (thruster commands) then needs its ``peer``. False for a link with one far end."""
        return False

    def age_s(self, now_mono_ns: int | None = None) -> float:
        """Seconds since the last chunk (``inf`` if none yet)."""
        last = self.stats.last_rx_mono_ns
        if last is None:
            return math.inf
        now = time.monotonic_ns() if now_mono_ns is None else now_mono_ns
        return max(0.0, (now - last) / 1e9)

    def is_stale(self, timeout_s: float | None = None, now_mono_ns: int | None = None) -> bool:
        """Nothing received for more than ``timeout_s`` (default: the source's ``timeout_s``), or ever."""
        limit = self.timeout_s if timeout_s is None else timeout_s
        return self.age_s(now_mono_ns) > limit

    def describe(self) -> str:
        return f"{self.name} ({self.url})"

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped" if self._started else "not started"
        return f"<{type(self).__name__} {self.name!r} {self.url} {state}>"

    # ---------------------------------------------------------------- for subclasses

    @abstractmethod
    def _open(self) -> None:
        """Open the transport in the caller's thread; raise `SourceError` on a problem a person must fix."""

    @abstractmethod
    def _run(self) -> None:
        """The reader loop; returns when ``self._stop`` is set (or the stream ended)."""

    def _close(self) -> None:  # noqa: B027 — optional hook
        """Release the transport (called by the reader thread on its way out). Idempotent."""

    def _interrupt(self) -> None:  # noqa: B027 — optional hook
        """Wake a blocked read at once (called by `stop` from another thread)."""

    def _main(self) -> None:
        try:
            self._run()
        except Exception as exc:  # a bug: say so, but do not take the process down
            log.exception("source %r: reader thread failed", self.name)
            self.stats.count_error("reader failed", f"reader thread failed: {exc!r}")
        finally:
            self._close()
            self.stats.connected = False

    def _error(self, reason: str, detail: str, level: int = logging.WARNING, *, always: bool = False) -> None:
        """Count a problem; log it at ``level`` the first time a reason occurs (every time with ``always``:
        state changes such as a lost link), at DEBUG after."""
        self.stats.count_error(reason, detail)
        if reason in self._logged and not always:
            level = logging.DEBUG
        self._logged.add(reason)
        log.log(level, "source %r (%s): %s", self.name, self.url, detail)

    def _emit(self, data: bytes, peer: str = "", kernel_ns: int | None = None) -> None:
        """Stamp ``data`` (call right after the read returned) and hand it to ``deliver``. ``kernel_ns``:
        when the kernel took the data in (UTC ns), where the transport says; the stamp is then that
        instant, and its monotonic twin is now less the wait since (never later than now)."""
        rx_ns = time.time_ns()
        rx_mono_ns = time.monotonic_ns()
        if kernel_ns is not None:
            waited = rx_ns - kernel_ns
            if 0 <= waited <= KERNEL_STAMP_SLACK_NS:
                rx_ns = kernel_ns
                rx_mono_ns -= waited
        stats = self.stats
        stats.bytes_received += len(data)
        stats.chunks += 1
        stats.last_rx_mono_ns = rx_mono_ns
        self._hand_over(Chunk(self.name, bytes(data), rx_ns, rx_mono_ns, peer))

    def _end_of_stream(self, peer: str) -> None:
        """Hand over the end of ``peer``'s stream (an empty `Chunk`); not counted as data received."""
        if peer:
            self._hand_over(Chunk(self.name, b"", time.time_ns(), time.monotonic_ns(), peer))

    def _hand_over(self, chunk: Chunk) -> None:
        """Give ``chunk`` to ``deliver``; what it raises is counted (logged the first time), never raised
        into the reading thread."""
        deliver = self._deliver
        if deliver is None:
            return
        try:
            deliver(chunk)
        except Exception as exc:
            self.stats.count_error("deliver raised", f"deliver raised {type(exc).__name__}: {exc}")
            if "deliver raised" not in self._logged:
                self._logged.add("deliver raised")
                log.exception("source %r: deliver raised (counted; reading goes on)", self.name)

    def _sleep(self, seconds: float) -> bool:
        """Wait ``seconds`` unless stopped; True if stopped."""
        return self._stop.wait(max(0.0, seconds))


def strerror(exc: OSError) -> str:
    """What the OS said, for a message (``exc.strerror`` without the errno, or whatever there is)."""
    return exc.strerror or str(exc) or type(exc).__name__
