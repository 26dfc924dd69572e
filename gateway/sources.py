"""How the live gateway reads the vessel's streams: serial ports, ptys, UDP, TCP and files — one interface.

A `Source` is opened from a URL by `open_source` and started with a ``deliver`` callback. A daemon reader
thread reads the transport and calls ``deliver`` with one `Chunk` per read (a UDP datagram, a serial read,
a TCP segment, whole lines of a file), stamped with the UTC and monotonic receive times. The consumer (the
pipeline) puts chunks on a queue; decoding is not done here. ``write`` sends bytes back (MAVLink commands)::

    serial:///dev/ttyUSB0?baud=4800[&bytesize=8&parity=N&stopbits=1]   a serial port (pyserial)
    pty:///tmp/dpgw-gps                   the same, on a pty path (e.g. the simulator's link)
    udp://0.0.0.0:10110[?target=H:P]      listen for datagrams; write() answers the last peer (or target)
    udp://239.1.2.3:10110?iface=eth0      ... joining a multicast group (iface: address or interface name)
    tcp://HOST:PORT                       a TCP client that reconnects with exponential back-off
    tcp-listen://0.0.0.0:PORT             a TCP server; any number of clients
    file:///path/log.nmea?rate=fast|realtime|HZ   a file read as a stream (tests, demos)
    udpin:H:P  udp:H:P  udpout:H:P  tcp:H:P  tcpin:H:P  /dev/ttyUSB0,57600  serial:/dev/ttyUSB0:57600
                                          pymavlink connection strings, mapped onto the above

Errors a person must fix (a malformed URL, a serial port that does not exist or is in use, a UDP port
taken) raise one `SourceError` naming the source, the URL and what to do — from `open_source` (the URL)
or from `Source.start` (opening it). Everything that can heal by itself is counted and retried, never
raised: a TCP server that is down (or goes down), a USB serial adapter unplugged while running. See
``docs/sources.md``.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import math
import os
import re
import select
import socket
import stat
import struct
import threading
import time
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import IO, Any, ClassVar, Self
from urllib.parse import parse_qs, unquote, urlsplit

from wire.codecs.nmea_time import time_of_day_or_none

__all__ = [
    "BACKOFF_FIRST_S",
    "BACKOFF_MAX_S",
    "Chunk",
    "FileSource",
    "SerialSource",
    "Source",
    "SourceError",
    "SourceStats",
    "TcpClientSource",
    "TcpListenSource",
    "UdpSource",
    "nmea_time_of_day",
    "open_source",
]

log = logging.getLogger(__name__)

#: Reconnect back-off (TCP client, serial port that went away): first wait, doubling up to the cap.
BACKOFF_FIRST_S = 0.5
BACKOFF_MAX_S = 10.0
#: Longest a reader thread blocks in one read, so `Source.stop` is prompt.
POLL_S = 0.2
_SERIAL_POLL_S = 0.1
#: How long `Source.stop` waits for the reader thread.
STOP_JOIN_S = 1.0
_READ_SIZE = 65536
#: pymavlink's default baud rate, used for MAVLink device strings without one (``/dev/ttyUSB0``).
MAVLINK_DEFAULT_BAUD = 115200
#: NMEA 0183 / IEC 61162-1 default, used for ``serial://`` URLs without ``baud``.
NMEA_DEFAULT_BAUD = 4800

URL_FORMS = (
    "serial:///dev/DEVICE?baud=4800, pty:///PATH, udp://HOST:PORT, tcp://HOST:PORT, "
    "tcp-listen://HOST:PORT, file:///PATH?rate=fast|realtime|HZ, or pymavlink's udpin:H:P, udpout:H:P, "
    "tcp:H:P, tcpin:H:P, /dev/DEVICE,BAUD, serial:/dev/DEVICE:BAUD"
)


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
    """UDP/TCP peer ``host:port`` (``[v6]:port``) that sent it, for `Source.write` ``peer=``; else ``""``."""


class SourceError(Exception):
    """A source that cannot work as configured; a person must fix it.

    The message names the source, the problem, the URL and what to do, e.g. ``source 'gyro1': serial port
    /dev/ttyUSB9 does not exist (serial:///dev/ttyUSB9?baud=4800) — check the cable/udev name``.
    """

    def __init__(self, name: str, url: str, problem: str, fix: str = "") -> None:
        self.name = name
        self.url = url
        self.problem = problem
        self.fix = fix
        super().__init__(f"source {name!r}: {problem} ({url})" + (f" — {fix}" if fix else ""))


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
    ``tcp-listen``, clients accepted after the first."""
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
                errors=Counter(self.errors),
                bytes_sent=self.bytes_sent,
                last_error=self.last_error,
            )


class _Backoff:
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

    def _emit(self, data: bytes, peer: str = "") -> None:
        """Stamp ``data`` (call right after the read returned) and hand it to ``deliver``."""
        rx_ns = time.time_ns()
        rx_mono_ns = time.monotonic_ns()
        stats = self.stats
        stats.bytes_received += len(data)
        stats.chunks += 1
        stats.last_rx_mono_ns = rx_mono_ns
        deliver = self._deliver
        if deliver is None:
            return
        try:
            deliver(Chunk(self.name, bytes(data), rx_ns, rx_mono_ns, peer))
        except Exception as exc:
            self.stats.count_error("deliver raised", f"deliver raised {type(exc).__name__}: {exc}")
            if "deliver raised" not in self._logged:
                self._logged.add("deliver raised")
                log.exception("source %r: deliver raised (counted; reading goes on)", self.name)

    def _sleep(self, seconds: float) -> bool:
        """Wait ``seconds`` unless stopped; True if stopped."""
        return self._stop.wait(max(0.0, seconds))


# -------------------------------------------------------------------------------------------- serial


class SerialSource(Source):
    """A serial port or a pty, via pyserial; raw bytes, no flow control, exclusive (``flock``).

    The device must exist at `start` (else `SourceError`). When it fails while running (a USB adapter
    unplugged, the simulator's pty closed), the error is counted, ``stats.connected`` goes False and the
    port is reopened with back-off (0.5 s doubling to 10 s) until it is back; ``stats.reconnects`` counts
    the reopenings. A pty has no baud rate: the setting is accepted and ignored.
    """

    kind = "serial"

    def __init__(
        self,
        name: str,
        url: str,
        device: str,
        baud: int = NMEA_DEFAULT_BAUD,
        *,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        timeout_s: float = 2.0,
    ) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.device = device
        self.baud = baud
        self.bytesize = bytesize
        self.parity = parity
        self.stopbits = stopbits
        self._ser: Any = None  # serial.Serial while open

    def _open_port(self) -> Any:
        try:
            import serial  # pyserial is needed only by serial sources
        except ImportError as exc:
            raise SourceError(
                self.name, self.url, "pyserial is not installed", "pip install pyserial"
            ) from exc
        if not os.path.exists(self.device):
            raise SourceError(
                self.name,
                self.url,
                f"serial port {self.device} does not exist",
                "check the cable/udev name (ls /dev/serial/by-id/; for the simulator: the pty it printed)",
            )
        with contextlib.suppress(OSError):
            if not stat.S_ISCHR(os.stat(self.device).st_mode):
                raise SourceError(
                    self.name,
                    self.url,
                    f"{self.device} is not a serial device",
                    f"for a file write file://{os.path.abspath(self.device)}",
                )
        ser = serial.Serial()
        ser.port = self.device
        ser.baudrate = self.baud
        ser.bytesize = self.bytesize
        ser.parity = self.parity
        ser.stopbits = self.stopbits
        ser.timeout = _SERIAL_POLL_S
        ser.write_timeout = self.timeout_s
        ser.exclusive = True
        try:
            ser.open()
        except (serial.SerialException, OSError, ValueError) as exc:
            code = getattr(exc, "errno", None)
            text = str(exc)
            if code == errno.EAGAIN or "exclusively lock" in text:
                problem, fix = f"serial port {self.device} is in use", "another program has it open: stop it"
            elif code == errno.EACCES:
                problem = f"no permission to open serial port {self.device}"
                fix = "join the group owning the device (often 'dialout') and log in again"
            elif code == errno.ENOENT:
                problem, fix = f"serial port {self.device} does not exist", "check the cable/udev name"
            elif code == errno.EBUSY:
                problem, fix = f"serial port {self.device} is busy", "another program has it open: stop it"
            else:
                problem, fix = (
                    f"cannot open serial port {self.device}: {text}",
                    "check the device and settings",
                )
            raise SourceError(self.name, self.url, problem, fix) from exc
        return ser

    def _open(self) -> None:
        self._ser = self._open_port()
        self.stats.connected = True

    def _run(self) -> None:
        import serial

        backoff = _Backoff()
        while not self._stop.is_set():
            ser = self._ser
            if ser is None:
                if self._sleep(backoff.next()):
                    return
                try:
                    ser = self._open_port()
                except SourceError as exc:
                    self._error("reopen failed", str(exc), logging.DEBUG)
                    continue
                with self._io_lock:
                    self._ser = ser
                self.stats.connected = True
                self.stats.reconnects += 1
                backoff.reset()
                log.info("source %r: serial port %s open again", self.name, self.device)
            data = b""
            try:
                data = ser.read(1)
                if data:
                    waiting = ser.in_waiting
                    if waiting:
                        data += ser.read(waiting)
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                if self._stop.is_set():
                    return
                if data:
                    self._emit(data)
                self._error(
                    "disconnected", f"serial port {self.device} failed: {exc}; reopening", always=True
                )
                self.stats.connected = False
                with self._io_lock:
                    self._ser = None
                    with contextlib.suppress(Exception):
                        ser.close()
                continue
            if data:
                self._emit(data)

    def write(self, data: bytes, peer: str | None = None) -> bool:
        import serial

        with self._io_lock:
            ser = self._ser
            if ser is None or self._stop.is_set():
                return False
            try:
                n = ser.write(data) or 0
            except serial.SerialTimeoutException:
                self._error("write timeout", f"write to {self.device} timed out after {self.timeout_s} s")
                return False
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                self._error("write failed", f"write to {self.device} failed: {exc}")
                return False
        self.stats.add_sent(n)
        return n == len(data)

    def _interrupt(self) -> None:
        ser = self._ser
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.cancel_read()

    def _close(self) -> None:
        with self._io_lock:
            ser, self._ser = self._ser, None
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.close()
        self.stats.connected = False


# ------------------------------------------------------------------------------------------- sockets


def _fmt_addr(addr: tuple[Any, ...]) -> str:
    host, port = addr[0], addr[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def _strerror(exc: OSError) -> str:
    return exc.strerror or str(exc) or type(exc).__name__


def _send_all(sock: socket.socket, data: bytes, timeout_s: float) -> str | None:
    """Send all of ``data`` on a non-blocking stream socket within ``timeout_s``; the error text, or None."""
    view = memoryview(data)
    deadline = time.monotonic() + timeout_s
    while view:
        try:
            n = sock.send(view, socket.MSG_NOSIGNAL)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            return _strerror(exc)
        view = view[n:]
        if view:
            left = deadline - time.monotonic()
            if left <= 0:
                return f"timed out after {timeout_s} s ({len(view)} of {len(data)} bytes not sent)"
            try:
                select.select([], [sock], [], min(left, POLL_S))
            except (OSError, ValueError) as exc:
                return str(exc)
    return None


def _bind_problem(address: str, exc: OSError, what: str) -> tuple[str, str]:
    if exc.errno == errno.EADDRINUSE:
        fix = f"another program uses this {what}: stop it or choose another port"
    elif exc.errno == errno.EACCES:
        fix = "ports below 1024 need privileges: choose a port of 1024 or above"
    elif exc.errno == errno.EADDRNOTAVAIL:
        fix = (
            "the host is not an address of this machine: listen on 0.0.0.0 (every interface) or one of its "
            "addresses"
        )
    else:
        fix = ""
    return f"cannot listen on {address}: {_strerror(exc)}", fix


class UdpSource(Source):
    """A UDP socket: one chunk per datagram, from anyone; ``peer`` is the sender.

    Listening (``udp://HOST:PORT``, ``udpin:``): bound to HOST:PORT (port 0: any free one, see `port`).
    `write` answers the last peer, or ``target`` when one is configured (``?target=H:P``). A multicast HOST
    joins the group on ``iface`` (an address or an interface name; default: the system's choice).

    Sending first (``udpout:H:P``): bound to an ephemeral port, ``target`` is H:P; ``hello`` (a MAVLink
    HEARTBEAT by default) is sent at start and again every ``hello_interval_s`` while nothing comes back,
    so the far end learns where to send. `write` goes to the target.
    """

    kind = "udp"

    def __init__(
        self,
        name: str,
        url: str,
        host: str,
        port: int,
        *,
        target: tuple[str, int] | None = None,
        iface: str | None = None,
        hello: bytes | None = None,
        hello_interval_s: float = 1.0,
        timeout_s: float = 2.0,
    ) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.host = host
        self._port = port
        self.target = target
        self.iface = iface
        self.hello = hello
        self.hello_interval_s = hello_interval_s
        self._sock: socket.socket | None = None
        self._target_addr: tuple[Any, ...] | None = None
        self._last_peer: tuple[Any, ...] | None = None
        self._peers: dict[str, tuple[Any, ...]] = {}

    @property
    def multicast(self) -> bool:
        try:
            return socket.inet_aton(self.host)[0] & 0xF0 == 0xE0 and self.host.count(".") == 3
        except OSError:
            return False

    @property
    def port(self) -> int:
        """The local port (after `start`, the one chosen for port 0)."""
        return self._port

    def _resolve(self, host: str, port: int, passive: bool) -> tuple[int, tuple[Any, ...]]:
        try:
            infos = socket.getaddrinfo(
                host or None, port, type=socket.SOCK_DGRAM, flags=socket.AI_PASSIVE if passive else 0
            )
        except (OSError, UnicodeError) as exc:
            raise SourceError(
                self.name, self.url, f"cannot resolve host {host!r}: {exc}", "check the host name or address"
            ) from exc
        family, _, _, _, sockaddr = infos[0]
        return family, sockaddr

    def _open(self) -> None:
        family: int = socket.AF_INET
        if self.target is not None:
            family, self._target_addr = self._resolve(self.target[0], self.target[1], passive=False)
        host = self.host or ("::" if family == socket.AF_INET6 else "0.0.0.0")
        bind_family, local = self._resolve(host, self._port, passive=True)
        if self._target_addr is not None and bind_family != family:
            raise SourceError(
                self.name, self.url, "the listen address and target are of different IP versions", "use one"
            )
        sock = socket.socket(bind_family, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            if self.multicast:
                # many programs may listen to one group; a unicast port stays exclusive (in use = error)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(local)
            except OSError as exc:
                raise SourceError(
                    self.name, self.url, *_bind_problem(_fmt_addr(local), exc, "UDP port")
                ) from exc
            if self.multicast:
                self._join(sock)
            sock.settimeout(POLL_S)
        except BaseException:
            sock.close()
            raise
        self._sock = sock
        self._port = int(sock.getsockname()[1])
        self.stats.connected = True

    def _join(self, sock: socket.socket) -> None:
        group = socket.inet_aton(self.host)
        iface = self.iface or ""
        try:
            if not iface:
                mreq = group + socket.inet_aton("0.0.0.0")
            elif re.fullmatch(r"\d+\.\d+\.\d+\.\d+", iface):
                mreq = group + socket.inet_aton(iface)
            else:  # an interface name: struct ip_mreqn
                mreq = group + socket.inet_aton("0.0.0.0") + struct.pack("i", socket.if_nametoindex(iface))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        except OSError as exc:
            raise SourceError(
                self.name,
                self.url,
                f"cannot join multicast group {self.host} on {iface or 'the default interface'}: {exc}",
                "give ?iface= an address or name of an interface that is up (ip -br addr)",
            ) from exc

    def _send_hello(self) -> None:
        sock, addr = self._sock, self._target_addr
        if sock is None or addr is None or not self.hello:
            return
        try:
            sock.sendto(self.hello, addr)
        except OSError as exc:
            self._error("hello failed", f"cannot send to {_fmt_addr(addr)}: {_strerror(exc)}")

    def _run(self) -> None:
        sock = self._sock
        assert sock is not None
        last_hello = -math.inf
        while not self._stop.is_set():
            if self.hello and self._target_addr is not None:
                now = time.monotonic()
                last_rx = self.stats.last_rx_mono_ns
                quiet = last_rx is None or now - last_rx / 1e9 >= self.hello_interval_s
                if quiet and now - last_hello >= self.hello_interval_s:
                    last_hello = now
                    self._send_hello()
            try:
                data, addr = sock.recvfrom(_READ_SIZE)
            except TimeoutError:
                continue
            except OSError as exc:  # ICMP errors reported on the socket; a closed socket at stop
                if self._stop.is_set():
                    return
                self._error("read error", f"receive failed: {_strerror(exc)}", logging.DEBUG)
                self._sleep(0.05)
                continue
            self._last_peer = addr
            peer = _fmt_addr(addr)
            if peer not in self._peers and len(self._peers) < 256:
                self._peers[peer] = addr
            self._emit(data, peer)

    def write(self, data: bytes, peer: str | None = None) -> bool:
        sock = self._sock
        if sock is None or self._stop.is_set():
            return False
        if peer:
            addr = self._peers.get(peer)
            if addr is None:
                return False
        else:
            addr = self._target_addr or self._last_peer
            if addr is None:
                return False  # nobody to answer yet
        try:
            n = sock.sendto(data, addr)
        except OSError as exc:
            self._error("write failed", f"cannot send to {_fmt_addr(addr)}: {_strerror(exc)}")
            return False
        self.stats.add_sent(n)
        return n == len(data)

    def _close(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self.stats.connected = False


def _tune_stream(sock: socket.socket) -> None:
    """No Nagle delay (commands are small and time-critical); keepalive finds a dead peer in ~11 s."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE, 5)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL, 2)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT, 3)


class TcpClientSource(Source):
    """A TCP client that keeps its connection up: ``tcp://HOST:PORT`` (pymavlink ``tcp:H:P``).

    `start` never raises because the server is down — a server that is down is not a config mistake, the
    link may come up later. Connection attempts (each up to ``timeout_s``) are retried after 0.5 s, 1 s,
    2 s ... up to 10 s; the wait is reset by a successful connection. When the server closes the
    connection or it fails, the client reconnects the same way; ``stats.reconnects`` counts the times the
    link came back, ``stats.errors`` the failed attempts (``"connect failed"``) and lost links
    (``"disconnected"``). `write` sends to the server while connected.
    """

    kind = "tcp"

    def __init__(self, name: str, url: str, host: str, port: int, *, timeout_s: float = 2.0) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.host = host
        self.port = port
        self._sock: socket.socket | None = None
        self._peer = ""

    def _open(self) -> None:
        pass  # connecting is the reader thread's job: it retries

    def _connect(self) -> socket.socket | None:
        try:
            infos = socket.getaddrinfo(self.host, self.port, type=socket.SOCK_STREAM)
        except (OSError, UnicodeError) as exc:
            self._error("connect failed", f"cannot resolve {self.host!r}: {exc}; retrying")
            return None
        problem = "no address"
        for family, kind, proto, _, addr in infos:
            sock = socket.socket(family, kind, proto)
            sock.setblocking(False)
            err = sock.connect_ex(addr)
            deadline = time.monotonic() + self.timeout_s
            while err in (errno.EINPROGRESS, errno.EAGAIN, errno.EALREADY):
                if self._stop.is_set():
                    sock.close()
                    return None
                left = deadline - time.monotonic()
                if left <= 0:
                    err = errno.ETIMEDOUT
                    break
                _, writable, _ = select.select([], [sock], [], min(left, POLL_S))
                if writable:
                    err = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if err == 0:
                _tune_stream(sock)
                return sock
            sock.close()
            problem = f"{_fmt_addr(addr)}: {os.strerror(err)}"
        self._error("connect failed", f"cannot connect to {problem}; retrying with back-off")
        return None

    def _run(self) -> None:
        backoff = _Backoff()
        ever_connected = False
        while not self._stop.is_set():
            sock = self._connect()
            if sock is None:
                if self._sleep(backoff.next()):
                    return
                continue
            backoff.reset()
            peer = _fmt_addr(sock.getpeername())
            with self._io_lock:
                self._sock, self._peer = sock, peer
            self.stats.connected = True
            if ever_connected:
                self.stats.reconnects += 1
            ever_connected = True
            log.info("source %r: connected to %s", self.name, peer)
            reason = self._read(sock, peer)
            with self._io_lock:
                self._sock = None
                sock.close()
            self.stats.connected = False
            if reason is None:  # stopped
                return
            self._error("disconnected", f"connection to {peer} lost: {reason}; reconnecting", always=True)
            if self._sleep(backoff.next()):
                return

    def _read(self, sock: socket.socket, peer: str) -> str | None:
        """Read until the link fails (returns why) or the source is stopped (None)."""
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([sock], [], [], POLL_S)
            except (OSError, ValueError) as exc:
                return str(exc)
            if not readable:
                continue
            try:
                data = sock.recv(_READ_SIZE)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError as exc:
                return _strerror(exc)
            if not data:
                return "closed by the server"
            self._emit(data, peer)
        return None

    def write(self, data: bytes, peer: str | None = None) -> bool:
        with self._io_lock:
            sock = self._sock
            if sock is None or self._stop.is_set():
                return False
            problem = _send_all(sock, data, self.timeout_s)
        if problem is not None:
            self._error("write failed", f"write to {self._peer} failed: {problem}")
            return False
        self.stats.add_sent(len(data))
        return True

    def _close(self) -> None:
        with self._io_lock:
            sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self.stats.connected = False


class TcpListenSource(Source):
    """A TCP server (``tcp-listen://HOST:PORT``, pymavlink ``tcpin:H:P``) taking any number of clients.

    The port is bound at `start` (port in use: `SourceError`; port 0: any free one, see `port`). Each
    client's bytes arrive as chunks with its ``peer``; ``stats.connected`` is True while at least one
    client is connected. `write` sends to every client, or to the one named by ``peer``.
    """

    kind = "tcp-listen"
    MAX_CLIENTS = 64

    def __init__(self, name: str, url: str, host: str, port: int, *, timeout_s: float = 2.0) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.host = host
        self._port = port
        self._listener: socket.socket | None = None
        self._clients: dict[socket.socket, str] = {}
        self._accepted = 0

    @property
    def port(self) -> int:
        """The listening port (after `start`, the one chosen for port 0)."""
        return self._port

    @property
    def clients(self) -> list[str]:
        with self._io_lock:
            return list(self._clients.values())

    def _open(self) -> None:
        try:
            infos = socket.getaddrinfo(
                self.host or None, self._port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
            )
        except (OSError, UnicodeError) as exc:
            raise SourceError(
                self.name, self.url, f"cannot resolve host {self.host!r}: {exc}", "check the address"
            ) from exc
        family, kind, proto, _, address = infos[0]
        sock = socket.socket(family, kind, proto)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # restart at once; no sharing on Linux
            try:
                sock.bind(address)
                sock.listen(16)
            except OSError as exc:
                raise SourceError(
                    self.name, self.url, *_bind_problem(_fmt_addr(address), exc, "TCP port")
                ) from exc
            sock.setblocking(False)
        except BaseException:
            sock.close()
            raise
        self._listener = sock
        self._port = int(sock.getsockname()[1])

    def _drop(self, sock: socket.socket, reason: str) -> None:
        with self._io_lock:
            peer = self._clients.pop(sock, "?")
            sock.close()
            self.stats.connected = bool(self._clients)
        log.info("source %r: client %s gone: %s", self.name, peer, reason)

    def _accept(self, listener: socket.socket) -> None:
        try:
            conn, addr = listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:  # ECONNABORTED, EMFILE ...
            self._error("accept failed", f"accept failed: {_strerror(exc)}")
            self._sleep(0.05)
            return
        if len(self._clients) >= self.MAX_CLIENTS:
            self._error("too many clients", f"refused client {_fmt_addr(addr)}: {self.MAX_CLIENTS} connected")
            conn.close()
            return
        conn.setblocking(False)
        _tune_stream(conn)
        peer = _fmt_addr(addr)
        with self._io_lock:
            self._clients[conn] = peer
        if self._accepted:
            self.stats.reconnects += 1
        self._accepted += 1
        self.stats.connected = True
        log.info("source %r: client %s connected", self.name, peer)

    def _run(self) -> None:
        listener = self._listener
        assert listener is not None
        while not self._stop.is_set():
            with self._io_lock:
                peers = dict(self._clients)
            try:
                readable, _, _ = select.select([listener, *peers], [], [], POLL_S)
            except (OSError, ValueError):  # a client closed under us: look again
                self._sleep(0.01)
                continue
            for sock in readable:
                if sock is listener:
                    self._accept(listener)
                    continue
                peer = peers.get(sock, "")
                try:
                    data = sock.recv(_READ_SIZE)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError as exc:
                    self._error("disconnected", f"client {peer}: {_strerror(exc)}", logging.INFO)
                    self._drop(sock, _strerror(exc))
                    continue
                if not data:
                    self._drop(sock, "closed by the client")
                    continue
                self._emit(data, peer)

    def write(self, data: bytes, peer: str | None = None) -> bool:
        with self._io_lock:
            targets = [(s, p) for s, p in self._clients.items() if not peer or p == peer]
            if not targets or self._stop.is_set():
                return False
            ok = True
            for sock, name in targets:
                problem = _send_all(sock, data, self.timeout_s)
                if problem is None:
                    self.stats.add_sent(len(data))
                else:
                    ok = False
                    self.stats.count_error("write failed", f"write to client {name} failed: {problem}")
        return ok

    def _close(self) -> None:
        with self._io_lock:
            for sock in self._clients:
                sock.close()
            self._clients.clear()
            listener, self._listener = self._listener, None
        if listener is not None:
            listener.close()
        self.stats.connected = False


# ---------------------------------------------------------------------------------------------- file

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
                self.name, self.url, f"cannot read {path}: {_strerror(exc)}", "check permissions"
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
            block = f.read(_READ_SIZE)
            if not block:
                if rest:
                    self._emit(rest)
                return True
            data = rest + block
            cut = data.rfind(b"\n") + 1
            if cut == 0 and len(data) < _READ_SIZE:
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
            line = f.readline(_READ_SIZE)
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


# ------------------------------------------------------------------------------------------- the URL

_OPTIONS: dict[str, tuple[str, ...]] = {
    "serial": ("baud", "bytesize", "parity", "stopbits"),
    "pty": ("baud", "bytesize", "parity", "stopbits"),
    "udp": ("target", "iface"),
    "tcp": (),
    "tcp-listen": (),
    "file": ("rate",),
}
_PYMAVLINK = ("udpin", "udp", "udpout", "tcp", "tcpin", "serial")
_PARITY = {
    **{k: k.upper() for k in "neoms"},
    **{"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"},
}


def _options(name: str, url: str, scheme: str, query: str) -> dict[str, str]:
    try:
        parsed = parse_qs(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError as exc:
        raise SourceError(
            name, url, f"malformed options {query!r}", "write them as ?name=value&name=value"
        ) from exc
    allowed = _OPTIONS[scheme]
    out: dict[str, str] = {}
    for key, values in parsed.items():
        if key not in allowed:
            raise SourceError(
                name,
                url,
                f"unknown option {key!r} for {scheme}",
                f"options for {scheme}: {', '.join(allowed) if allowed else 'none'}",
            )
        if len(values) != 1:
            raise SourceError(name, url, f"option {key!r} given {len(values)} times", "give it once")
        out[key] = values[0].strip()
    return out


def _host_port(name: str, url: str, text: str, *, need_host: bool, allow_zero: bool) -> tuple[str, int]:
    """``HOST:PORT`` or ``[V6]:PORT`` (``:PORT`` when the host may be empty) → (host, port)."""
    m = re.fullmatch(r"\[([^\]]+)\]:(\d{1,5})|([^:\[\]/@?#\s]*):(\d{1,5})", text)
    if not m:
        raise SourceError(name, url, f"{text!r} is not HOST:PORT", "e.g. 127.0.0.1:10110 or [::1]:10110")
    host = m.group(1) if m.group(1) is not None else m.group(3)
    port = int(m.group(2) or m.group(4))
    if need_host and not host:
        raise SourceError(name, url, "no host given", "e.g. 127.0.0.1:5760")
    low = 0 if allow_zero else 1
    if not low <= port <= 65535:
        raise SourceError(
            name,
            url,
            f"port {port} is out of range",
            f"use {low}–65535" + (" (0: any free port)" if low == 0 else ""),
        )
    return host, port


def _serial_source(
    name: str, url: str, device: str, opts: dict[str, str], default_baud: int, timeout_s: float
) -> SerialSource:
    if not device:
        raise SourceError(name, url, "no device given", "e.g. serial:///dev/ttyUSB0?baud=4800")
    baud_text = opts.get("baud", str(default_baud))
    if not baud_text.isdigit() or not 0 < int(baud_text) <= 20_000_000:
        raise SourceError(
            name, url, f"baud {baud_text!r} is not a baud rate", "e.g. baud=4800, 38400 or 115200"
        )
    bytesize_text = opts.get("bytesize", "8")
    if bytesize_text not in ("5", "6", "7", "8"):
        raise SourceError(
            name, url, f"bytesize {bytesize_text!r} is not 5, 6, 7 or 8", "NMEA and MAVLink use 8"
        )
    parity = _PARITY.get(opts.get("parity", "N").lower())
    if parity is None:
        raise SourceError(name, url, f"parity {opts['parity']!r} is not one of N, E, O, M, S", "NMEA uses N")
    stop_text = opts.get("stopbits", "1")
    if stop_text not in ("1", "1.5", "2"):
        raise SourceError(name, url, f"stopbits {stop_text!r} is not 1, 1.5 or 2", "NMEA uses 1")
    return SerialSource(
        name,
        url,
        device,
        int(baud_text),
        bytesize=int(bytesize_text),
        parity=parity,
        stopbits=float(stop_text) if stop_text == "1.5" else int(stop_text),
        timeout_s=timeout_s,
    )


def _default_hello() -> bytes:
    """A MAVLink 2 HEARTBEAT of an onboard computer (system 1, component 191), not a ground station: a
    GCS heartbeat (system 255) that stops later could trigger an autopilot's GCS failsafe."""
    from wire.codecs import mavlink  # only udpout needs the (large) dialect

    d = mavlink.dialect()
    mav = mavlink.encoder(1, d.MAV_COMP_ID_ONBOARD_COMPUTER)
    return mavlink.heartbeat_frame(mav, mav_type=d.MAV_TYPE_ONBOARD_CONTROLLER)


def _pymavlink_source(name: str, url: str, text: str, timeout_s: float, hello: bytes | None) -> Source | None:
    """pymavlink connection strings; None if ``text`` is not one."""
    m = re.fullmatch(r"([a-z]+):(.*)", text, flags=re.IGNORECASE)
    if m is None or "://" in text:
        if text.startswith("/") and "://" not in text:  # /dev/ttyUSB0[,57600]
            device, _, baud = text.partition(",")
            return _serial_source(
                name, url, device, {"baud": baud} if baud else {}, MAVLINK_DEFAULT_BAUD, timeout_s
            )
        return None
    scheme, rest = m.group(1).lower(), m.group(2)
    if scheme not in _PYMAVLINK:
        return None
    if scheme == "serial":  # serial:/dev/ttyUSB0[:57600]
        device, baud = rest, ""
        tail = re.fullmatch(r"(.*):(\d+)", rest)
        if tail:
            device, baud = tail.group(1), tail.group(2)
        return _serial_source(
            name, url, device, {"baud": baud} if baud else {}, MAVLINK_DEFAULT_BAUD, timeout_s
        )
    if scheme in ("udpin", "udp"):
        host, port = _host_port(name, url, rest, need_host=False, allow_zero=True)
        return UdpSource(name, url, host, port, timeout_s=timeout_s)
    if scheme == "udpout":
        host, port = _host_port(name, url, rest, need_host=True, allow_zero=False)
        return UdpSource(
            name,
            url,
            "",
            0,
            target=(host, port),
            hello=_default_hello() if hello is None else hello,
            timeout_s=timeout_s,
        )
    if scheme == "tcp":
        host, port = _host_port(name, url, rest, need_host=True, allow_zero=False)
        return TcpClientSource(name, url, host, port, timeout_s=timeout_s)
    host, port = _host_port(name, url, rest, need_host=False, allow_zero=True)  # tcpin
    return TcpListenSource(name, url, host, port, timeout_s=timeout_s)


def open_source(name: str, url: str, *, timeout_s: float = 2.0, hello: bytes | None = None) -> Source:
    """The source a URL names (module docstring, ``docs/sources.md``); validated, not opened yet.

    ``timeout_s``: how long one TCP connect attempt or a blocked write may take, and the default of
    `Source.is_stale`. ``hello``: for ``udpout:``, the datagram that announces the gateway to the far end
    (default: a MAVLink HEARTBEAT, see `_default_hello`); ``b""`` sends none.

    Raises `SourceError` for a URL that cannot work, with the URL and what to do in the message.
    """
    if not isinstance(name, str) or not name.strip():
        raise SourceError(str(name), str(url), "a source needs a name", "name it in the config")
    text = url.strip() if isinstance(url, str) else ""
    if not text:
        raise SourceError(name, str(url), "empty URL", f"give one of: {URL_FORMS}")
    if not (isinstance(timeout_s, int | float) and math.isfinite(timeout_s) and timeout_s > 0):
        raise SourceError(name, url, f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
    if any(c.isspace() or not c.isprintable() for c in text):
        raise SourceError(name, url, "the URL contains spaces or control characters", "remove them")

    if re.fullmatch(r"pty:?/*", text, flags=re.IGNORECASE):
        raise SourceError(
            name, url, "no pty path given", "give the path the simulator printed, e.g. pty:///tmp/dpgw-gps"
        )
    mav = _pymavlink_source(name, url, text, timeout_s, hello)
    if mav is not None:
        return mav
    if "://" not in text:
        m = re.match(r"([A-Za-z][A-Za-z0-9+.-]*):", text)
        if m and m.group(1).lower() in _OPTIONS:
            raise SourceError(
                name,
                url,
                "not a URL I understand",
                f"did you mean {m.group(1)}://{text[m.end() :].lstrip('/')}?",
            )
        if re.fullmatch(r"[^:/]*:\d+", text):
            raise SourceError(name, url, "no transport given", f"write udp://{text} or tcp://{text}")
        raise SourceError(name, url, "not a URL I understand", f"give one of: {URL_FORMS}")
    try:
        parts = urlsplit(text)
    except ValueError as exc:
        raise SourceError(name, url, f"malformed URL: {exc}", f"give one of: {URL_FORMS}") from exc
    scheme = parts.scheme.lower()
    if scheme not in _OPTIONS:
        raise SourceError(name, url, f"unknown transport {parts.scheme!r}", f"give one of: {URL_FORMS}")
    if parts.fragment:
        raise SourceError(name, url, f"unexpected '#{parts.fragment}'", "remove it")
    opts = _options(name, url, scheme, parts.query)

    if scheme in ("serial", "pty", "file"):
        if parts.netloc not in ("", "localhost"):
            raise SourceError(
                name,
                url,
                f"{parts.netloc!r} is read as a host name",
                f"write an absolute path with three slashes: {scheme}:///{parts.netloc}{parts.path}",
            )
        path = unquote(parts.path)
        if scheme == "file":
            if not path:
                raise SourceError(name, url, "no file given", "e.g. file:///data/run1.nmea?rate=fast")
            raw_rate = opts.get("rate", "realtime").lower()
            rate: str | float = raw_rate
            if raw_rate not in ("fast", "realtime"):
                try:
                    rate = float(raw_rate)
                except ValueError:
                    rate = math.nan
                if not (math.isfinite(rate) and rate > 0):
                    raise SourceError(
                        name,
                        url,
                        f"rate {opts['rate']!r} is not fast, realtime or lines per second",
                        "e.g. rate=10",
                    )
            return FileSource(name, url, path, rate, timeout_s=timeout_s)
        if scheme == "pty" and not path:
            raise SourceError(
                name,
                url,
                "no pty path given",
                "give the path the simulator printed, e.g. pty:///tmp/dpgw-gps",
            )
        return _serial_source(name, url, path, opts, NMEA_DEFAULT_BAUD, timeout_s)

    if parts.path not in ("", "/"):
        raise SourceError(name, url, f"unexpected path {parts.path!r}", f"write {scheme}://HOST:PORT")
    if scheme == "tcp":
        host, port = _host_port(name, url, parts.netloc, need_host=True, allow_zero=False)
        return TcpClientSource(name, url, host, port, timeout_s=timeout_s)
    if scheme == "tcp-listen":
        host, port = _host_port(name, url, parts.netloc, need_host=False, allow_zero=True)
        return TcpListenSource(name, url, host, port, timeout_s=timeout_s)
    host, port = _host_port(name, url, parts.netloc, need_host=False, allow_zero=True)
    target = None
    if "target" in opts:
        target = _host_port(name, url, opts["target"], need_host=True, allow_zero=False)
    source = UdpSource(
        name, url, host, port, target=target, iface=opts.get("iface") or None, timeout_s=timeout_s
    )
    if opts.get("iface") and not source.multicast:
        raise SourceError(name, url, "iface is for multicast groups (224.0.0.0–239.255.255.255)", "remove it")
    return source
