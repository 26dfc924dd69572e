"""UDP sources (``udp://``, pymavlink ``udpin:``/``udp:``/``udpout:``): listening, multicast, send-first."""

from __future__ import annotations

import contextlib
import errno
import logging
import math
import re
import socket
import struct
import sys
import time
from typing import Any

from gateway.sources.base import POLL_S, READ_SIZE, Source, SourceError, log, strerror
from gateway.sources.sockets import bind_problem, fmt_addr

DEFAULT_RECEIVE_BUFFER = 4 * 1024 * 1024
"""Kernel receive buffer asked for a UDP source (``?rcvbuf=``). Linux's default (208 KiB) holds about
0.2 s of a busy NMEA multiplexer's datagrams; a burst (a logger replaying, a sensor restarting) then
overflows it and the kernel drops datagrams silently. 4 MiB holds tens of thousands."""

# Linux: SO_RXQ_OVFL makes every received datagram carry the socket's count of datagrams the kernel
# dropped (receive buffer full); SO_RCVBUFFORCE may exceed net.core.rmem_max (needs CAP_NET_ADMIN).
_SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40 if sys.platform.startswith("linux") else None)
_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33 if sys.platform.startswith("linux") else None)
# Linux: SO_TIMESTAMPNS makes every received datagram carry the instant the kernel took it in (a struct
# timespec of CLOCK_REALTIME). A datagram is stamped with that, not with the instant the reading thread got
# to it: on a busy machine the thread waits for a core and for the interpreter, and a stamp taken then is
# late by that wait (milliseconds; at a demo's 10x, a tenth of a second of simulation time).
_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35 if sys.platform.startswith("linux") else None)
_TIMESPEC = struct.Struct("@qq")
_CMSG_SPACE = socket.CMSG_SPACE(4) if hasattr(socket, "CMSG_SPACE") else 0
_CMSG_SPACE_STAMP = socket.CMSG_SPACE(_TIMESPEC.size) if hasattr(socket, "CMSG_SPACE") else 0
# Linux: IP_FREEBIND / IPV6_FREEBIND let a socket bind an address no interface has yet (systemd's FreeBind=).
_FREEBIND: dict[int, tuple[int, int]] = {
    socket.AF_INET: (socket.IPPROTO_IP, getattr(socket, "IP_FREEBIND", 15)),
    socket.AF_INET6: (socket.IPPROTO_IPV6, getattr(socket, "IPV6_FREEBIND", 78)),
}
ADDRESS_CHECK_S = 1.0
"""While the address listened on is not yet this computer's, how often it is looked for (s)."""


def _switch_on(sock: socket.socket, option: int | None) -> bool:
    """Turn the socket-level ``option`` on; False where this platform has no such option or refuses it
    (the source then goes without what it gives)."""
    if option is None:
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, option, 1)
    except OSError:
        return False
    return True


class UdpSource(Source):
    """A UDP socket: one chunk per datagram, from anyone; ``peer`` is the sender.

    Listening (``udp://HOST:PORT``, ``udpin:``): bound to HOST:PORT (port 0: any free one, see `port`).
    `write` answers the last peer, or ``target`` when one is configured (``?target=H:P``). A multicast HOST
    joins the group on ``iface`` (an address or an interface name; default: the system's choice).

    Sending first (``udpout:H:P``): bound to an ephemeral port, ``target`` is H:P; ``hello`` (a MAVLink
    HEARTBEAT by default) is sent at start and again every ``hello_interval_s`` while nothing comes back,
    so the far end learns where to send. `write` goes to the target.

    Nothing is dropped unseen: the socket asks for a ``receive_buffer`` of `DEFAULT_RECEIVE_BUFFER` bytes
    (``?rcvbuf=``; `granted_buffer` is what the kernel gave, logged when less), and on Linux every
    datagram carries the kernel's count of datagrams it dropped because the buffer was full
    (``SO_RXQ_OVFL``), kept in `dropped` (it is brought up to date by the next datagram that arrives).

    An interface slow to come up (DHCP, a link still negotiating) does not stop the gateway: a unicast
    address that is not yet this computer's is bound all the same (Linux ``IP_FREEBIND``), the source is
    not ``connected`` meanwhile (a ``/status`` alarm saying why), and datagrams are read as soon as the
    address appears (looked for every `ADDRESS_CHECK_S`). An address that never appears (a typing
    mistake) keeps the alarm up; ``dpgw run --check`` notes it (`listen_address_note`) but cannot refuse
    it, as the address may come later. An address that goes away while listening (the interface goes
    down, DHCP hands out another, someone removes it) is noticed the same way: after `ADDRESS_CHECK_S`
    with nothing received it is looked for, and when it is gone the source is not ``connected``, saying
    why, until it is back; otherwise the source would only look quiet.
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
        receive_buffer: int = DEFAULT_RECEIVE_BUFFER,
    ) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.receive_buffer = int(receive_buffer)
        self.granted_buffer = 0
        """Receive buffer the kernel granted (bytes, as `getsockopt` reports it: Linux counts its own
        bookkeeping in, so it is twice the size asked for when granted in full)."""
        self.dropped = 0
        """Datagrams the kernel dropped on this socket (receive buffer full); 0 where not reported."""
        self._ovfl = False
        self._kernel_stamps = False
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
        self.address_up = True
        """The address listened on is this computer's (False while waiting for an interface)."""
        self._local: tuple[int, tuple[Any, ...]] | None = None  # (family, address) of a specific unicast bind

    @property
    def shared(self) -> bool:
        return self.target is None  # listening: anyone may send; with a target, that is the far end

    @property
    def _one_address(self) -> bool:
        """Listening on one unicast address (not on every address, not on a multicast group): one that an
        interface still to come up may not have yet."""
        return bool(self.host) and self.host not in ("0.0.0.0", "::") and not self.multicast

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
            self._size_buffer(sock)
            if self.multicast:
                # many programs may listen to one group; a unicast port stays exclusive (in use = error)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            elif self._one_address and bind_family in _FREEBIND:
                self._local = (bind_family, local)
                with contextlib.suppress(OSError):  # (elsewhere: an address not up is refused as before)
                    sock.setsockopt(*_FREEBIND[bind_family], 1)
            try:
                sock.bind(local)
            except OSError as exc:
                raise SourceError(
                    self.name, self.url, *bind_problem(fmt_addr(local), exc, "UDP port")
                ) from exc
            if self.multicast:
                self._join(sock)
            sock.settimeout(POLL_S)
        except BaseException:
            sock.close()
            raise
        self._sock = sock
        self._port = int(sock.getsockname()[1])
        self.address_up = self._is_local()
        self.stats.connected = self.address_up
        if not self.address_up:
            self._error(
                "address not up",
                f"{fmt_addr(local)} is not an address of this computer yet: listening for when its "
                "interface comes up (if it never does, the address is wrong: ip -br addr)",
                always=True,
            )

    def listen_address_note(self) -> str | None:
        """Without opening anything: why the address listened on is not this computer's now (it may be an
        interface still to come up, or a typing mistake), or None. What ``dpgw run --check`` says."""
        if not self._one_address:
            return None
        try:
            family, local = self._resolve(self.host, 0, passive=True)
        except SourceError as exc:
            return exc.problem
        if not _address_is_local(family, local):
            return (
                f"{self.host} is not an address of this computer now: the gateway will wait for its "
                "interface to come up (if it never does, the address is wrong: ip -br addr)"
            )
        return None

    def _check_address(self) -> None:
        if self._local is not None and self._is_local():
            self.address_up = self.stats.connected = True
            log.warning("source %r: %s is up now; receiving", self.name, fmt_addr(self._local[1]))

    def _check_address_kept(self) -> None:
        """The address listened on went away (its interface went down, DHCP gave another, someone removed
        it): nothing can arrive on it, and without this the source would only look quiet. Not connected,
        saying why, until `_check_address` sees it back (the socket stays bound: it reads again then)."""
        if self._local is not None and not self._is_local():
            self.address_up = self.stats.connected = False
            self._error(
                "address gone",
                f"{fmt_addr(self._local[1])} is no longer an address of this computer (its interface went "
                "down or the address was removed): listening for when it comes back",
                always=True,
            )

    def _quiet(self, seconds: float) -> bool:
        """Nothing received for ``seconds`` (a datagram received proves the address is there)."""
        last_rx = self.stats.last_rx_mono_ns
        return last_rx is None or time.monotonic_ns() - last_rx >= seconds * 1e9

    def _is_local(self) -> bool:
        """The specific unicast address bound (if any) belongs to an interface of this computer now."""
        return self._local is None or _address_is_local(*self._local)

    def _size_buffer(self, sock: socket.socket) -> None:
        """Ask for `receive_buffer` (forced past net.core.rmem_max where permitted), note what was granted,
        and turn on the kernel's drop count."""
        for option in (_SO_RCVBUFFORCE, socket.SO_RCVBUF):
            if option is None:
                continue
            try:
                sock.setsockopt(socket.SOL_SOCKET, option, self.receive_buffer)
                break
            except OSError:
                continue  # not permitted (no CAP_NET_ADMIN): the capped request below
        self.granted_buffer = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        if self.granted_buffer < self.receive_buffer:
            log.warning(
                "source %r: the kernel granted a %d-byte receive buffer of the %d asked for; raise "
                "net.core.rmem_max (sysctl) or run with CAP_NET_ADMIN so bursts are not dropped",
                self.name, self.granted_buffer, self.receive_buffer,
            )  # fmt: skip
        self._ovfl = bool(_CMSG_SPACE) and _switch_on(sock, _SO_RXQ_OVFL)
        self._kernel_stamps = bool(_CMSG_SPACE_STAMP) and _switch_on(sock, _SO_TIMESTAMPNS)

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
            self._error("hello failed", f"cannot send to {fmt_addr(addr)}: {strerror(exc)}")

    def _run(self) -> None:
        sock = self._sock
        assert sock is not None
        last_hello = -math.inf
        next_check = time.monotonic() + ADDRESS_CHECK_S
        while not self._stop.is_set():
            if self._local is not None and time.monotonic() >= next_check:
                next_check = time.monotonic() + ADDRESS_CHECK_S
                if not self.address_up:
                    self._check_address()
                elif self._quiet(ADDRESS_CHECK_S):
                    self._check_address_kept()
            if self.hello and self._target_addr is not None:
                now = time.monotonic()
                last_rx = self.stats.last_rx_mono_ns
                quiet = last_rx is None or now - last_rx / 1e9 >= self.hello_interval_s
                if quiet and now - last_hello >= self.hello_interval_s:
                    last_hello = now
                    self._send_hello()
            try:
                kernel_ns = None
                if self._ovfl or self._kernel_stamps:
                    data, ancillary, _, addr = sock.recvmsg(READ_SIZE, _CMSG_SPACE + _CMSG_SPACE_STAMP)
                    for level, kind, value in ancillary:
                        if level != socket.SOL_SOCKET:
                            continue
                        if kind == _SO_RXQ_OVFL and len(value) >= 4:
                            self.dropped = struct.unpack("=I", value[:4])[0]
                        elif kind == _SO_TIMESTAMPNS and len(value) >= _TIMESPEC.size:
                            sec, nsec = _TIMESPEC.unpack_from(value)
                            kernel_ns = sec * 1_000_000_000 + nsec
                else:
                    data, addr = sock.recvfrom(READ_SIZE)
            except TimeoutError:
                continue
            except OSError as exc:  # ICMP errors reported on the socket; a closed socket at stop
                if self._stop.is_set():
                    return
                self._error("read error", f"receive failed: {strerror(exc)}", logging.DEBUG)
                self._sleep(0.05)
                continue
            if not self.address_up:  # (a datagram may come before the next look)
                self._check_address()
            self._last_peer = addr
            peer = fmt_addr(addr)
            if peer not in self._peers and len(self._peers) < 256:
                self._peers[peer] = addr
            self._emit(data, peer, kernel_ns)

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
            self._error("write failed", f"cannot send to {fmt_addr(addr)}: {strerror(exc)}")
            return False
        self.stats.add_sent(n)
        return n == len(data)

    def _close(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self.stats.connected = False


def _address_is_local(family: int, local: tuple[Any, ...]) -> bool:
    """Whether ``local`` (a socket address) belongs to an interface of this computer now: a probe socket
    binds it on any port (refused with EADDRNOTAVAIL when it does not)."""
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((local[0], 0, *local[2:]))
        except OSError as exc:
            return exc.errno != errno.EADDRNOTAVAIL
    return True
