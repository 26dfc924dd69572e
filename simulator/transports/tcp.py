"""A TCP server sink (``tcp-listen://HOST:PORT``): every write to every client; a slow client never stalls
it."""

from __future__ import annotations

import contextlib
import logging
import socket
from dataclasses import dataclass, field

from simulator.transports.base import MAX_READS_PER_PEER, READ_CHUNK, Sink, TransportError
from simulator.transports.sockets import bind_error, fmt_addr, resolve

log = logging.getLogger(__name__)


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
        self.url = url or f"tcp-listen://{host}:{port}"
        if not 0 <= port < 65536:
            raise TransportError(
                self.url, f"port {port} is out of range", "use a port 1–65535, or 0 for any free one"
            )
        if max_backlog < 0:
            raise TransportError(self.url, f"max_backlog must be >= 0, got {max_backlog}")
        self.max_backlog = max_backlog
        family, address = resolve(self.url, host or "0.0.0.0", port, socket.SOCK_STREAM, passive=True)
        sock = socket.socket(family, socket.SOCK_STREAM)
        try:
            # SO_REUSEADDR: a restarted simulator may reuse the port at once (connections in TIME_WAIT); on
            # Linux it does not let two servers listen on one port, so a port in use is still an error.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(address)
                sock.listen(socket.SOMAXCONN)
            except OSError as exc:
                raise bind_error(self.url, fmt_addr(address), exc, "TCP port") from exc
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
            self._clients.append(_Client(conn, fmt_addr(addr)))
            self.clients_accepted += 1
            log.info("tcp-listen://%s: client %s connected", fmt_addr(self.address), fmt_addr(addr))

    def _disconnect(self, client: _Client, reason: str) -> None:
        self._clients.remove(client)
        self.clients_dropped += 1
        self.bytes_dropped += len(client.backlog)
        where = f"tcp-listen://{fmt_addr(self.address)}"
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
            for _ in range(MAX_READS_PER_PEER):
                try:
                    chunk = client.sock.recv(READ_CHUNK)
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
        return f"tcp-listen://{fmt_addr(self.address)} ({n} client{'s' if n != 1 else ''})"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        for client in self._clients:
            with contextlib.suppress(OSError):
                client.sock.close()
        self._clients.clear()
        self._listener.close()
