"""UDP sources (``udp://``, pymavlink ``udpin:``/``udp:``/``udpout:``): listening, multicast, send-first."""

from __future__ import annotations

import logging
import math
import re
import socket
import struct
import time
from typing import Any

from gateway.sources.base import POLL_S, READ_SIZE, Source, SourceError, strerror
from gateway.sources.sockets import bind_problem, fmt_addr


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
            self._error("hello failed", f"cannot send to {fmt_addr(addr)}: {strerror(exc)}")

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
                data, addr = sock.recvfrom(READ_SIZE)
            except TimeoutError:
                continue
            except OSError as exc:  # ICMP errors reported on the socket; a closed socket at stop
                if self._stop.is_set():
                    return
                self._error("read error", f"receive failed: {strerror(exc)}", logging.DEBUG)
                self._sleep(0.05)
                continue
            self._last_peer = addr
            peer = fmt_addr(addr)
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
            self._error("write failed", f"cannot send to {fmt_addr(addr)}: {strerror(exc)}")
            return False
        self.stats.add_sent(n)
        return n == len(data)

    def _close(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self.stats.connected = False
