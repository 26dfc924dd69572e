"""A UDP sink (``udp://HOST:PORT[?bind=H:P&iface=I&tag_source=S]``): one datagram per write; replies are
read back. To a multicast group it can send as a device on an IEC 61162-450 network does."""

from __future__ import annotations

import re
import socket
import struct

from simulator.transports.base import MAX_READS_PER_PEER, Sink, TransportError
from simulator.transports.sockets import bind_error, fmt_addr, resolve
from wire.codecs.nmea_tag import SOURCE, SOURCE_EXPECTED, iec_450_datagram


class UdpSink(Sink):
    """Datagrams to ``host:port``, one per write (NMEA multiplexers send one per sentence or burst).

    The socket is bound to ``bind`` (default: any address, an ephemeral port: see ``local_address``) and
    datagrams sent to it — a ground station's MAVLink commands, a listener's replies — are read back with
    `read_available`. Broadcast destinations are allowed. A datagram the OS refuses (send buffer full,
    too large, network unreachable) is dropped and counted.

    To a multicast group, ``iface`` (an IPv4 address or an interface name) is the interface the datagrams
    leave by (default: the system's choice, which on a machine without a default route is none). With
    ``tag_source`` each write goes out as an IEC 61162-450 sentence datagram of that device (the header
    ``UdPbC\\0``, each sentence after a TAG block naming it and counting it, ``n:`` 1-999:
    `wire.codecs.nmea_tag.iec_450_datagram`), so that a bench can stand in for the devices of a ship's
    network.
    """

    def __init__(
        self,
        host: str,
        port: int,
        *,
        bind: tuple[str, int] | None = None,
        iface: str | None = None,
        tag_source: str | None = None,
        url: str | None = None,
    ) -> None:
        super().__init__()
        self.url = url or f"udp://{host}:{port}"
        if not 0 < port < 65536:
            raise TransportError(self.url, f"port {port} is out of range", "use a destination port 1–65535")
        if tag_source is not None and not SOURCE.fullmatch(tag_source):
            raise TransportError(
                self.url, f"tag_source {tag_source!r} is not a TAG block source", SOURCE_EXPECTED
            )
        self.tag_source = tag_source
        self._line = 1  # the device's line count (TAG blocks' n:) of its next sentence
        family, self.destination = resolve(self.url, host, port, socket.SOCK_DGRAM)
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            if iface is not None:
                _send_by(sock, self.url, iface)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            if bind is None:
                local: tuple = ("::" if family == socket.AF_INET6 else "0.0.0.0", 0)
            else:
                bind_family, local = resolve(self.url, bind[0], bind[1], socket.SOCK_DGRAM, passive=True)
                if bind_family != family:
                    raise TransportError(
                        self.url, "bind address and destination are of different IP versions", "use one kind"
                    )
            try:
                sock.bind(local)
            except OSError as exc:
                raise bind_error(self.url, fmt_addr(local), exc, "UDP port") from exc
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
        if self.tag_source is not None:
            data, self._line = iec_450_datagram(data, self.tag_source, self._line)
        try:
            n = self._sock.sendto(data, self.destination)
        except OSError as exc:  # BlockingIOError (buffer full), EMSGSIZE, ENETUNREACH, ECONNREFUSED ...
            self._drop(len(data), f"{self.describe()}: {exc.strerror or exc}")
            return
        self.bytes_written += n

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        self._check_open()
        items: list[tuple[str, bytes]] = []
        for _ in range(MAX_READS_PER_PEER * 16):
            try:
                data, addr = self._sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error reported on the socket; nothing to read
                continue
            items.append((fmt_addr(addr), data))
        return items

    def describe(self) -> str:
        device = f", as the device {self.tag_source} of an IEC 61162-450 network" if self.tag_source else ""
        return f"udp://{fmt_addr(self.destination)} (from {fmt_addr(self.local_address)}{device})"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        self._sock.close()


def _send_by(sock: socket.socket, url: str, iface: str) -> None:
    """Multicast leaves by the interface ``iface`` (an IPv4 address or an interface name; that the
    destination is a multicast group, the URL's grammar has checked: `wire.urls`)."""
    try:
        if re.fullmatch(r"\d+\.\d+\.\d+\.\d+", iface):
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(iface))
        else:  # struct ip_mreqn: the interface by its index
            mreqn = struct.pack("4s4si", bytes(4), bytes(4), socket.if_nametoindex(iface))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, mreqn)
    except OSError as exc:
        raise TransportError(
            url,
            f"cannot send by interface {iface}: {exc.strerror or exc}",
            "give ?iface= an address or name of an interface that is up (ip -br addr)",
        ) from exc
