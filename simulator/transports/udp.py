"""A UDP sink (``udp://HOST:PORT[?bind=H:P]``): one datagram per write; replies are read back."""

from __future__ import annotations

import socket

from simulator.transports.base import MAX_READS_PER_PEER, Sink, TransportError
from simulator.transports.sockets import bind_error, fmt_addr, resolve


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
        family, self.destination = resolve(self.url, host, port, socket.SOCK_DGRAM)
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
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
        return f"udp://{fmt_addr(self.destination)} (from {fmt_addr(self.local_address)})"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        self._sock.close()
