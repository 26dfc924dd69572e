"""Where the simulator's bytes go: a pty, UDP, a TCP server, a serial port or a file — one interface.

The simulator is a vessel at sea that behaves like real hardware on the wire. Its NMEA sentences and
MAVLink frames are written to a `Sink`; thruster commands (MAVLink) that peers send back are read from the
same sink with `Sink.read_available`. `open_sink` turns a URL into a sink::

    pty                          PtySink: a new pseudo-terminal; any serial program opens .device
    pty:///tmp/dpgw-gps          ... with a stable symlink to it (removed on close)
    udp://HOST:PORT              UdpSink: one datagram per write to HOST:PORT; replies are read back
    udp://HOST:PORT?bind=H:P     ... sending from (and listening on) H:P
    tcp-listen://HOST:PORT       TcpServerSink: a TCP server; every write goes to every client
    serial:///dev/ttyUSB0?baud=4800   SerialSink: a real serial port, raw 8N1, no flow control
    file:///path/to/file, PATH   FileSink: appended, handed to the OS on every write

Behaviour every sink shares (``docs/transports.md`` has the details and how to connect programs):

* ``write`` never blocks the simulation for long and never raises because a peer is slow, absent or gone.
  A write is delivered whole or dropped whole — never cut in the middle of a sentence — and a drop is
  counted (``writes_dropped``, ``bytes_dropped``, ``last_error``).
* Errors a person must fix (a malformed URL, a port in use, an unwritable path) raise one
  `TransportError` when the sink is opened, naming the URL and what to do.
* Sinks are not thread-safe: one simulation thread writes and reads. There are no background threads;
  work on peers (accepting TCP clients, sending what a busy peer could not take yet) is done in each
  ``write``, ``read_available`` and ``poll``.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import logging
import math
import os
import socket
import struct
import termios
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self

from wire.urls import SINK_OPTIONS, Endpoint, UrlError, parse_url, serial_settings, split_host_port

__all__ = [
    "FileSink",
    "MemorySink",
    "PtySink",
    "SerialSink",
    "Sink",
    "TcpServerSink",
    "TransportError",
    "UdpSink",
    "open_sink",
]

log = logging.getLogger(__name__)

#: The URL forms `open_sink` understands, for error messages.
URL_FORMS = (
    "pty, pty:///PATH/TO/LINK, udp://HOST:PORT[?bind=HOST:PORT], tcp-listen://HOST:PORT, "
    "serial:///dev/DEVICE[?baud=4800], file:///PATH or a plain file path"
)

_READ_CHUNK = 65536
_MAX_READS_PER_PEER = 16  # per read call: bounds the time spent on a flooding peer


class TransportError(Exception):
    """A transport that cannot work as configured: the message names the URL and what to do."""

    def __init__(self, url: str, problem: str, fix: str = "") -> None:
        self.url = url
        self.problem = problem
        self.fix = fix
        super().__init__(f"{url}: {problem}" + (f" — {fix}" if fix else ""))


class Sink(ABC):
    """Where simulated hardware writes its bytes, and where bytes from its peers come back.

    Counters (plain ints, reset never):

    * ``bytes_written`` — bytes the operating system accepted (for a TCP server: summed over clients).
    * ``writes_dropped`` — writes not delivered, counted per peer (a TCP write that two clients could not
      take counts 2). A write with nobody to deliver it to (a TCP server with no client) is not a drop.
    * ``bytes_dropped`` — bytes of those writes, plus data discarded later (a pty's stale input, the
      backlog of a TCP client that is disconnected for being too slow).
    * ``last_error`` — the last OS error that caused a drop, as text (``None`` if there was none).
    """

    def __init__(self) -> None:
        self.bytes_written = 0
        self.writes_dropped = 0
        self.bytes_dropped = 0
        self.last_error: str | None = None
        self._closed = False

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Send ``data`` (one sentence, one frame or one burst) to the peers; never blocks for long."""

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        """Bytes that came back from peers since the last call, as ``(peer, bytes)`` items; non-blocking.

        UDP: one item per datagram; TCP: one item per client that sent something; pty and serial: one item.
        Keep peers apart when several may send at once (a MAVLink frame must not be spliced from two).
        """
        return []

    def read_available(self) -> bytes:
        """All bytes that came back from peers since the last call, concatenated; ``b""`` if none."""
        return b"".join(chunk for _, chunk in self.read_from_peers())

    def poll(self) -> None:  # noqa: B027 — optional hook, deliberately empty by default
        """Service peers without writing: accept waiting TCP clients, send what a busy peer could not take."""

    @abstractmethod
    def describe(self) -> str:
        """A one-line description a person can act on, e.g. the pty device to open."""

    def close(self) -> None:
        """Release the transport. Idempotent."""
        self._closed = True

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def bytes_pending(self) -> int:
        """Bytes taken by ``write`` that wait in user space for a busy peer (neither written nor dropped)."""
        return 0

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"I/O on a closed sink ({self.describe()})")

    def _drop(self, nbytes: int, error: str | None = None) -> None:
        self.writes_dropped += 1
        self.bytes_dropped += nbytes
        if error is not None:
            self.last_error = error

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return (
            f"<{type(self).__name__} {self.describe()} {state} bytes_written={self.bytes_written} "
            f"writes_dropped={self.writes_dropped}>"
        )


# --------------------------------------------------------------------------------------------- in memory


class MemorySink(Sink):
    """Keeps everything written in ``data``; ``feed`` queues bytes for `read_available`. For tests."""

    def __init__(self) -> None:
        super().__init__()
        self.data = bytearray()
        self._incoming: list[bytes] = []

    def write(self, data: bytes) -> None:
        self._check_open()
        self.data += data
        self.bytes_written += len(data)

    def feed(self, data: bytes) -> None:
        """Queue ``data`` as if a peer had sent it."""
        self._incoming.append(bytes(data))

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        items, self._incoming = self._incoming, []
        return [("memory", chunk) for chunk in items]

    def describe(self) -> str:
        return "memory"


# ------------------------------------------------------------------------------- fd-based: pty and serial


def _make_raw(fd: int) -> None:
    """cfmakeraw(3): bytes pass unchanged — no echo, no CR/LF translation, no signals, no flow control."""
    attrs = termios.tcgetattr(fd)
    iflag, oflag, cflag, lflag = attrs[0], attrs[1], attrs[2], attrs[3]
    iflag &= ~(
        termios.IGNBRK
        | termios.BRKINT
        | termios.PARMRK
        | termios.ISTRIP
        | termios.INLCR
        | termios.IGNCR
        | termios.ICRNL
        | termios.IXON
        | termios.IXOFF
        | termios.INPCK
    )
    oflag &= ~termios.OPOST
    lflag &= ~(termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN)
    cflag &= ~(termios.CSIZE | termios.PARENB)
    cflag |= termios.CS8
    attrs[0], attrs[1], attrs[2], attrs[3] = iflag, oflag, cflag, lflag
    cc = attrs[6]
    cc[termios.VMIN] = 1
    cc[termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def _queued(fd: int, request: int) -> int:
    """Bytes in a tty's input (TIOCINQ) or output (TIOCOUTQ) queue; 0 if the driver cannot tell."""
    try:
        raw = fcntl.ioctl(fd, request, b"\0\0\0\0")
    except OSError:
        return 0
    return int(struct.unpack("i", raw)[0])


class _FdSink(Sink):
    """A non-blocking file descriptor (pty master, serial port) written whole-or-dropped.

    A write the kernel takes only in part keeps its tail in ``_pending``, sent before anything else; while
    a tail is pending, new writes are dropped whole. So the stream is never cut inside a write, and at
    most one write's worth of bytes waits in user space.
    """

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd
        self._pending = bytearray()

    @property
    def bytes_pending(self) -> int:
        return len(self._pending)

    def _flush_pending(self) -> bool:
        """Send the pending tail; True when nothing is pending any more."""
        while self._pending:
            try:
                n = os.write(self._fd, self._pending)
            except BlockingIOError:
                return False
            except OSError as exc:
                # the tail of a write cannot follow: give it up (its head is already out)
                self.bytes_dropped += len(self._pending)
                self.last_error = f"{self.describe()}: {exc.strerror or exc}"
                self._pending.clear()
                return True
            if n <= 0:
                return False
            self.bytes_written += n
            del self._pending[:n]
        return True

    def _before_write(self) -> None:
        """Hook run before each write (the pty discards stale input here)."""

    def write(self, data: bytes) -> None:
        self._check_open()
        if not data:
            return
        self._before_write()
        if not self._flush_pending():
            self._drop(len(data), f"{self.describe()}: buffer full (the reader is slow or absent)")
            return
        try:
            n = os.write(self._fd, data)
        except BlockingIOError:
            self._drop(len(data), f"{self.describe()}: buffer full (the reader is slow or absent)")
            return
        except OSError as exc:
            self._drop(len(data), f"{self.describe()}: {exc.strerror or exc}")
            return
        self.bytes_written += n
        if n < len(data):
            self._pending += data[n:]

    def poll(self) -> None:
        if not self._closed:
            self._flush_pending()

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        self._check_open()
        chunks: list[bytes] = []
        for _ in range(_MAX_READS_PER_PEER):
            try:
                chunk = os.read(self._fd, _READ_CHUNK)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:  # EIO: no one at the other end
                if exc.errno != errno.EIO:
                    self.last_error = f"{self.describe()}: read: {exc.strerror or exc}"
                break
            if not chunk:
                break
            chunks.append(chunk)
        return [(self.describe(), b"".join(chunks))] if chunks else []


class PtySink(_FdSink):
    """A pseudo-terminal: the simulator holds the master; a serial program opens ``device`` (the slave).

    The slave is put in raw mode so bytes pass unchanged. The sink keeps its own descriptor on the slave so
    the pty lives on while readers come and go (without it the master gets EIO once the last reader
    closes). With ``link``, a symlink ``link -> device`` is made (an existing symlink there is replaced;
    any other file is an error) and removed on close if it still points at this pty.

    When no reader drains the pty the kernel's buffer (some tens of KiB) fills and writes are dropped
    whole. When the pty's input has not once been empty for ``stale_s`` seconds (checked at each write),
    it is discarded (counted in ``bytes_dropped`` and ``stale_flushes``), so a reader that opens the pty
    late gets current sentences, as from a sensor on a serial line, not a backlog of old ones. A reader
    that keeps up empties the input within milliseconds and is never affected. ``stale_s=None`` keeps
    everything.
    """

    def __init__(
        self, link: str | None = None, *, stale_s: float | None = 2.0, url: str | None = None
    ) -> None:
        self.url = url or ("pty" if link is None else f"pty://{link}")
        if stale_s is not None and not (math.isfinite(stale_s) and stale_s > 0):
            raise TransportError(self.url, f"stale_s must be a positive number of seconds, got {stale_s!r}")
        master, slave = os.openpty()
        try:
            _make_raw(slave)
            os.set_blocking(master, False)
            self.device = os.ttyname(slave)
        except OSError as exc:
            os.close(master)
            os.close(slave)
            raise TransportError(self.url, f"cannot set up the pty: {exc.strerror or exc}") from exc
        super().__init__(master)
        self._slave = slave
        self.stale_s = stale_s
        #: times stale input was discarded
        self.stale_flushes = 0
        self._last_drained = time.monotonic()
        self.link: str | None = None
        if link is not None:
            try:
                self.link = _make_symlink(link, self.device, self.url)
            except BaseException:
                os.close(master)
                os.close(slave)
                raise

    def _before_write(self) -> None:
        if self.stale_s is None:
            return
        now = time.monotonic()
        waiting = _queued(self._slave, termios.TIOCINQ)
        if waiting == 0:
            self._last_drained = now
        elif now - self._last_drained > self.stale_s:
            # Nobody has emptied the input for stale_s: discard it (and the tail of a write whose head
            # went with it), as a serial line loses what is sent while nobody listens.
            termios.tcflush(self._slave, termios.TCIFLUSH)
            self.bytes_dropped += waiting + len(self._pending)
            self._pending.clear()
            self.stale_flushes += 1
            self._last_drained = now

    def describe(self) -> str:
        return f"{self.link} -> {self.device}" if self.link else self.device

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        if self.link is not None:
            with contextlib.suppress(OSError):
                if os.readlink(self.link) == self.device:
                    os.unlink(self.link)
        for fd in (self._fd, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def _make_symlink(link: str, target: str, url: str) -> str:
    path = os.path.abspath(link)
    if os.path.lexists(path) and not os.path.islink(path):
        raise TransportError(
            url, f"{path} exists and is not a symlink", "remove it or choose another link path"
        )
    if not os.path.isdir(os.path.dirname(path)):
        raise TransportError(url, f"directory {os.path.dirname(path)} does not exist", "create it first")
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.symlink(target, tmp)
        os.replace(tmp, path)  # atomic: a reader never sees the link missing or half-made
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise TransportError(
            url, f"cannot create symlink {path}: {exc.strerror or exc}", "choose a writable directory"
        ) from exc
    return path


def _baud_constant(baud: int) -> int | None:
    value = getattr(termios, f"B{baud}", None)
    return value if isinstance(value, int) else None


class SerialSink(_FdSink):
    """A real serial port (or any tty): raw 8N1 at ``baud``, no flow control, modem lines ignored.

    Writes are non-blocking: when the simulator produces faster than the line's baud rate carries, the
    driver's buffer fills and writes are dropped whole, as on an overloaded NMEA talker.
    """

    def __init__(self, device: str, baud: int = 4800, *, url: str | None = None) -> None:
        self.device = device
        self.baud = baud
        self.url = url or f"serial://{device}?baud={baud}"
        speed = _baud_constant(baud)
        if speed is None:
            rates = [
                b
                for b in (4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
                if _baud_constant(b)
            ]
            raise TransportError(
                self.url, f"unsupported baud rate {baud}", f"use one of {', '.join(map(str, rates))}"
            )
        try:
            fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            fix = {
                errno.ENOENT: "check the device name (ls /dev/serial/by-id/)",
                errno.EACCES: "join the group owning the device (often 'dialout') and log in again",
                errno.EBUSY: "another program has the port open",
            }.get(exc.errno or 0, "")
            raise TransportError(self.url, f"cannot open {device}: {exc.strerror or exc}", fix) from exc
        try:
            if not os.isatty(fd):
                raise TransportError(
                    self.url, f"{device} is not a serial device", "use file://PATH for a file"
                )
            _make_raw(fd)
            attrs = termios.tcgetattr(fd)
            attrs[2] &= ~(termios.CSTOPB | termios.CRTSCTS | termios.HUPCL)
            attrs[2] |= termios.CLOCAL | termios.CREAD
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except OSError as exc:
            os.close(fd)
            raise TransportError(self.url, f"cannot configure {device}: {exc.strerror or exc}") from exc
        except BaseException:
            os.close(fd)
            raise
        super().__init__(fd)

    def describe(self) -> str:
        return f"serial://{self.device}?baud={self.baud}"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        with contextlib.suppress(OSError):
            os.close(self._fd)


# ---------------------------------------------------------------------------------------------------- UDP


def _resolve(url: str, host: str, port: int, kind: int, *, passive: bool = False) -> tuple[int, tuple]:
    try:
        infos = socket.getaddrinfo(host, port, type=kind, flags=socket.AI_PASSIVE if passive else 0)
    except (OSError, UnicodeError) as exc:
        raise TransportError(
            url, f"cannot resolve host {host!r}: {exc}", "check the host name or address"
        ) from exc
    family, _, _, _, sockaddr = infos[0]
    return family, sockaddr


def _fmt_addr(addr: tuple) -> str:
    host, port = addr[0], addr[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def _bind_error(url: str, address: str, exc: OSError, what: str = "port") -> TransportError:
    if exc.errno == errno.EADDRINUSE:
        fix = f"another program uses this {what}: stop it or choose another port (0 picks a free one)"
    elif exc.errno == errno.EACCES:
        fix = "ports below 1024 need privileges: choose a port of 1024 or above"
    elif exc.errno == errno.EADDRNOTAVAIL:
        fix = "the host is not an address of this machine: use 127.0.0.1, 0.0.0.0 or one of its addresses"
    else:
        fix = ""
    return TransportError(url, f"cannot bind {address}: {exc.strerror or exc}", fix)


class UdpSink(Sink):
    """Datagrams to ``host:port``, one per write (NMEA multiplexers send one per sentence or burst).

    The socket is bound to ``bind`` (default: any address, an ephemeral port: see ``local_address``) and
    datagrams sent to it — a ground station's MAVLink commands, a listener's replies — are read back with
    `read_available`. Broadcast destinations are allowed. A datagram the OS refuses (send buffer full,
    too large, network unreachable) is dropped and counted.
    """

    def __init__(
        self, host: str, port: int, *, bind: tuple[str, int] | None = None, url: str | None = None
    ) -> None:
        super().__init__()
        self.url = url or f"udp://{host}:{port}"
        if not 0 < port < 65536:
            raise TransportError(self.url, f"port {port} is out of range", "use a destination port 1–65535")
        family, self.destination = _resolve(self.url, host, port, socket.SOCK_DGRAM)
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            if bind is None:
                local: tuple = ("::" if family == socket.AF_INET6 else "0.0.0.0", 0)
            else:
                bind_family, local = _resolve(self.url, bind[0], bind[1], socket.SOCK_DGRAM, passive=True)
                if bind_family != family:
                    raise TransportError(
                        self.url, "bind address and destination are of different IP versions", "use one kind"
                    )
            try:
                sock.bind(local)
            except OSError as exc:
                raise _bind_error(self.url, _fmt_addr(local), exc, "UDP port") from exc
            sock.setblocking(False)
        except BaseException:
            sock.close()
            raise
        self._sock = sock
        self.local_address: tuple = sock.getsockname()

    @property
    def port(self) -> int:
        """The local port replies come to."""
        return int(self.local_address[1])

    def write(self, data: bytes) -> None:
        self._check_open()
        if not data:
            return
        try:
            n = self._sock.sendto(data, self.destination)
        except OSError as exc:  # BlockingIOError (buffer full), EMSGSIZE, ENETUNREACH, ECONNREFUSED ...
            self._drop(len(data), f"{self.describe()}: {exc.strerror or exc}")
            return
        self.bytes_written += n

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        self._check_open()
        items: list[tuple[str, bytes]] = []
        for _ in range(_MAX_READS_PER_PEER * 16):
            try:
                data, addr = self._sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error reported on the socket; nothing to read
                continue
            items.append((_fmt_addr(addr), data))
        return items

    def describe(self) -> str:
        return f"udp://{_fmt_addr(self.destination)} (from {_fmt_addr(self.local_address)})"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        self._sock.close()


# ---------------------------------------------------------------------------------------------- TCP server


@dataclass(eq=False)
class _Client:
    sock: socket.socket
    peer: str
    backlog: bytearray = field(default_factory=bytearray)
    eof: bool = False  # the client closed its sending side (it may still read)


class TcpServerSink(Sink):
    """A TCP server: every write goes to every connected client; what clients send is read back.

    Clients are accepted without a thread: the listening socket is non-blocking and polled in each
    ``write``, ``read_available`` and ``poll``. The kernel completes the handshake on the listen backlog, so
    a client is connected at once; it is taken into the list — and starts receiving — at the next write.
    No thread means no locks, no shared state with the simulation loop, and a close that cannot race.

    A client that cannot take a write now (its kernel send buffer is full) keeps the rest in a per-client
    backlog; once the backlog would exceed ``max_backlog`` bytes the client is disconnected (counted in
    ``clients_dropped``) — a slow client never stalls the simulation nor the other clients, and is never
    sent a stream with holes in it. A client that disconnects is forgotten at the next write that fails.
    A client that only half-closes (shuts down its sending side) keeps receiving.
    """

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, *, max_backlog: int = 262_144, url: str | None = None
    ) -> None:
        super().__init__()
        self.url = url or f"tcp://{host}:{port}"
        if not 0 <= port < 65536:
            raise TransportError(
                self.url, f"port {port} is out of range", "use a port 1–65535, or 0 for any free one"
            )
        if max_backlog < 0:
            raise TransportError(self.url, f"max_backlog must be >= 0, got {max_backlog}")
        self.max_backlog = max_backlog
        family, address = _resolve(self.url, host or "0.0.0.0", port, socket.SOCK_STREAM, passive=True)
        sock = socket.socket(family, socket.SOCK_STREAM)
        try:
            # SO_REUSEADDR: a restarted simulator may reuse the port at once (connections in TIME_WAIT); on
            # Linux it does not let two servers listen on one port, so a port in use is still an error.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(address)
                sock.listen(socket.SOMAXCONN)
            except OSError as exc:
                raise _bind_error(self.url, _fmt_addr(address), exc, "TCP port") from exc
            sock.setblocking(False)
        except BaseException:
            sock.close()
            raise
        self._listener = sock
        self.address: tuple = sock.getsockname()
        self._clients: list[_Client] = []
        #: clients accepted so far
        self.clients_accepted = 0
        #: clients disconnected by the sink (gone, or too slow)
        self.clients_dropped = 0

    @property
    def host(self) -> str:
        return str(self.address[0])

    @property
    def port(self) -> int:
        """The listening port (the ephemeral one chosen when the URL said port 0)."""
        return int(self.address[1])

    @property
    def bytes_pending(self) -> int:
        return sum(len(c.backlog) for c in self._clients)

    @property
    def clients(self) -> int:
        """Clients connected now (as far as the sink knows: a departure is noticed at the next write)."""
        return len(self._clients)

    def _accept(self) -> None:
        for _ in range(64):
            try:
                conn, addr = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # ECONNABORTED, EMFILE ...: try again at the next poll
                self.last_error = f"{self.describe()}: accept: {exc.strerror or exc}"
                return
            conn.setblocking(False)
            with contextlib.suppress(OSError):
                # sentences are small and time-critical: no Nagle delay
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._clients.append(_Client(conn, _fmt_addr(addr)))
            self.clients_accepted += 1
            log.info("tcp://%s: client %s connected", _fmt_addr(self.address), _fmt_addr(addr))

    def _disconnect(self, client: _Client, reason: str) -> None:
        self._clients.remove(client)
        self.clients_dropped += 1
        self.bytes_dropped += len(client.backlog)
        where = f"tcp://{_fmt_addr(self.address)}"
        self.last_error = f"{where}: client {client.peer}: {reason}"
        log.info("%s: client %s dropped: %s", where, client.peer, reason)
        with contextlib.suppress(OSError):
            client.sock.close()

    def _send(self, client: _Client, data: bytes | bytearray) -> int:
        """Send as much as the kernel takes now; raise OSError if the client is gone."""
        try:
            return client.sock.send(data, socket.MSG_NOSIGNAL)
        except (BlockingIOError, InterruptedError):
            return 0

    def _flush_backlog(self, client: _Client) -> bool:
        """Send a client's backlog; False if the client is gone (and was disconnected)."""
        while client.backlog:
            try:
                n = self._send(client, client.backlog)
            except OSError as exc:
                self._disconnect(client, exc.strerror or str(exc))
                return False
            if n <= 0:
                break
            self.bytes_written += n
            del client.backlog[:n]
        return True

    def poll(self) -> None:
        if self._closed:
            return
        self._accept()
        for client in list(self._clients):
            self._flush_backlog(client)

    def write(self, data: bytes) -> None:
        self._check_open()
        self._accept()
        if not data:
            return
        for client in list(self._clients):
            if not self._flush_backlog(client):
                self._drop(len(data))
                continue
            if client.backlog:
                n = 0
            else:
                try:
                    n = self._send(client, data)
                except OSError as exc:
                    self._disconnect(client, exc.strerror or str(exc))
                    self._drop(len(data))
                    continue
                self.bytes_written += n
            rest = len(data) - n
            if rest and len(client.backlog) + rest > self.max_backlog:
                self._disconnect(client, f"too slow: more than {self.max_backlog} bytes behind")
                self._drop(rest)
                continue
            client.backlog += data[n:]

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        self._check_open()
        self._accept()
        items: list[tuple[str, bytes]] = []
        for client in list(self._clients):
            if client.eof:
                continue
            chunks: list[bytes] = []
            for _ in range(_MAX_READS_PER_PEER):
                try:
                    chunk = client.sock.recv(_READ_CHUNK)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError as exc:  # ECONNRESET
                    self._disconnect(client, exc.strerror or str(exc))
                    break
                if not chunk:
                    client.eof = True
                    break
                chunks.append(chunk)
            if chunks:
                items.append((client.peer, b"".join(chunks)))
        return items

    def describe(self) -> str:
        n = len(self._clients)
        return f"tcp://{_fmt_addr(self.address)} ({n} client{'s' if n != 1 else ''})"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        for client in self._clients:
            with contextlib.suppress(OSError):
                client.sock.close()
        self._clients.clear()
        self._listener.close()


# --------------------------------------------------------------------------------------------------- file


class FileSink(Sink):
    """Bytes appended to a file, handed to the OS on every write (no user-space buffering).

    A failed write (disk full) is dropped and counted. A path that is a FIFO or a device is opened as a
    file: writes may then block while the reader does not read — use ``pty`` or ``serial://`` instead.
    """

    def __init__(self, path: str, *, url: str | None = None) -> None:
        super().__init__()
        self.path = os.path.abspath(path)
        self.url = url or path
        try:
            self._file = open(self.path, "ab", buffering=0)  # noqa: SIM115 — owned by the sink, closed in close()
        except OSError as exc:
            fix = {
                errno.ENOENT: f"create the directory {os.path.dirname(self.path)} or choose another path",
                errno.EACCES: "choose a path you may write to",
                errno.EISDIR: "give a file name, not a directory",
                errno.EROFS: "choose a path on a writable file system",
            }.get(exc.errno or 0, "choose another path")
            raise TransportError(
                self.url, f"cannot open {self.path} for writing: {exc.strerror or exc}", fix
            ) from exc

    def write(self, data: bytes) -> None:
        self._check_open()
        view = memoryview(data)
        while view:
            try:
                n = self._file.write(view)
            except OSError as exc:
                self._drop(len(view), f"{self.describe()}: {exc.strerror or exc}")
                return
            if not n:  # a non-blocking device or FIFO that is full
                self._drop(len(view), f"{self.describe()}: would block")
                return
            self.bytes_written += n
            view = view[n:]

    def describe(self) -> str:
        return f"file://{self.path}"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        self._file.close()


# ------------------------------------------------------------------------------------------------- the URL


def _number(url: str, key: str, value: str) -> float:
    try:
        x = float(value)
    except ValueError:
        x = math.nan
    if not (math.isfinite(x) and x > 0):
        raise TransportError(url, f"option {key}={value!r} is not a positive number")
    return x


def open_sink(url: str) -> Sink:
    """Open the sink a URL names (see the module docstring and ``docs/transports.md``).

    Raises `TransportError` (message: the URL, the problem, what to do) when it cannot work.
    """
    text = url.strip()
    if not text:
        raise TransportError(repr(url), "empty transport", f"give one of: {URL_FORMS}")
    try:
        ep = parse_url(text, options=SINK_OPTIONS, bare_path="file")
        return _sink_for(url, ep)
    except UrlError as exc:
        raise TransportError(url, exc.problem, f"expected {exc.expected}" if exc.expected else "") from None


def _sink_for(url: str, ep: Endpoint) -> Sink:
    """The sink for a parsed URL (`wire.urls`: the one URL grammar); option values checked here."""
    if ep.scheme == "pty":
        stale: float | None = 2.0
        raw = ep.option("stale_s")
        if raw is not None:
            stale = None if raw.lower() in ("none", "off", "inf") else _number(url, "stale_s", raw)
        return PtySink(ep.path or None, stale_s=stale, url=url)
    if ep.scheme == "file":
        return FileSink(ep.path, url=url)
    if ep.scheme == "serial":
        return SerialSink(ep.path, serial_settings(ep).baud, url=url)
    port = ep.port or 0
    if ep.scheme == "udp":
        if not ep.host:
            raise TransportError(url, "no destination host", "e.g. udp://127.0.0.1:10110")
        bind_text = ep.option("bind")
        bind = split_host_port(bind_text, need_host=False, allow_zero=True) if bind_text else None
        if bind is not None and not bind[0]:
            bind = ("0.0.0.0", bind[1])
        return UdpSink(ep.host, port, bind=bind, url=url)
    max_backlog = 262_144
    backlog_text = ep.option("max_backlog")
    if backlog_text is not None:
        if not backlog_text.isdigit():
            raise TransportError(url, f"max_backlog {backlog_text!r} is not a whole number of bytes")
        max_backlog = int(backlog_text)
    return TcpServerSink(ep.host or "0.0.0.0", port, max_backlog=max_backlog, url=url)
