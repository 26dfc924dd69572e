"""TCP sources: a client that reconnects with back-off (``tcp://``, pymavlink ``tcp:``) and a server that
takes any number of clients (``tcp-listen://``, pymavlink ``tcpin:``)."""

from __future__ import annotations

import errno
import logging
import os
import select
import socket
import time

from gateway.sources.base import BACKOFF_MAX_S, POLL_S, READ_SIZE, Backoff, Source, SourceError, strerror
from gateway.sources.sockets import bind_problem, fmt_addr, send_all, tune_stream

STABLE_CONNECTION_S = BACKOFF_MAX_S
"""A connection that lasted this long (s), or brought `WORKING_CONNECTION_BYTES`, was a success: the
back-off starts again from its first wait. Any other counts as a failed attempt. Reset at every connect, a
server that accepts and closes at once (a port forward to nothing, a device rebooting in a loop) was
reconnected every 0.5 s for days, two journal lines each time (~300,000 a day) pushing the useful history
out; now the waits grow to `BACKOFF_MAX_S`. A link that brings data and drops is a link that works, badly:
it is reconnected at once, as before (its data is the vessel's)."""
WORKING_CONNECTION_BYTES = 64
"""Bytes a connection must bring to count as working: a sentence or a few MAVLink frames, more than the
fragment a server that closes at once may send."""

log = logging.getLogger(__name__)


class TcpClientSource(Source):
    """A TCP client that keeps its connection up: ``tcp://HOST:PORT`` (pymavlink ``tcp:H:P``).

    `start` never raises because the server is down — a server that is down is not a config mistake, the
    link may come up later. Connection attempts (each up to ``timeout_s``) are retried after 0.5 s, 1 s,
    2 s ... up to 10 s; the wait is reset by a successful connection. When the server closes the
    connection or it fails, the client reconnects the same way; ``stats.reconnects`` counts the times the
    link came back, ``stats.last_disconnect`` says when and why it was last lost, ``stats.errors`` counts
    the failed attempts (``"connect failed"``) and lost links (``"disconnected"``). `write` sends to the
    server while connected.
    """

    kind = "tcp"

    def __init__(self, name: str, url: str, host: str, port: int, *, timeout_s: float = 2.0) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.host = host
        self.port = port
        self._sock: socket.socket | None = None
        self._peer = ""
        self._conn_bytes = 0  # brought by the connection in use (`WORKING_CONNECTION_BYTES`)

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
                tune_stream(sock)
                return sock
            sock.close()
            problem = f"{fmt_addr(addr)}: {os.strerror(err)}"
        self._error("connect failed", f"cannot connect to {problem}; retrying with back-off")
        return None

    def _run(self) -> None:
        backoff = Backoff()
        ever_connected = False
        while not self._stop.is_set():
            sock = self._connect()
            if sock is None:
                if self._sleep(backoff.next()):
                    return
                continue
            connected_at, self._conn_bytes = time.monotonic(), 0
            peer = fmt_addr(sock.getpeername())
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
            self._end_of_stream(peer)
            if reason is None:  # stopped
                return
            if (
                self._conn_bytes >= WORKING_CONNECTION_BYTES
                or time.monotonic() - connected_at >= STABLE_CONNECTION_S
            ):
                backoff.reset()  # (a server that accepts and closes at once is retried ever more slowly)
            self.stats.note_disconnect(f"connection to {peer} lost: {reason}")
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
                data = sock.recv(READ_SIZE)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError as exc:
                return strerror(exc)
            if not data:
                return "closed by the server"
            self._conn_bytes += len(data)
            self._emit(data, peer)
        return None

    def write(self, data: bytes, peer: str | None = None) -> bool:
        with self._io_lock:
            sock = self._sock
            if sock is None or self._stop.is_set():
                return False
            problem = send_all(sock, data, self.timeout_s)
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
    client is connected, ``stats.reconnects`` counts the clients accepted after the first and
    ``stats.last_disconnect`` says when and why a client last went. `write` sends to every client, or to
    the one named by ``peer``.
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
    def shared(self) -> bool:
        return True

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
                # a backlog as deep as the client limit: a burst of peers (sensors redialling after a switch
                # restart) waits in the queue; a full queue drops SYNs, which the peer resends after 1 s
                sock.listen(self.MAX_CLIENTS)
            except OSError as exc:
                raise SourceError(
                    self.name, self.url, *bind_problem(fmt_addr(address), exc, "TCP port")
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
        self.stats.note_disconnect(f"client {peer} gone: {reason}")
        log.info("source %r: client %s gone: %s", self.name, peer, reason)
        self._end_of_stream(peer)

    def _accept(self, listener: socket.socket) -> None:
        try:
            conn, addr = listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:  # ECONNABORTED, EMFILE ...
            self._error("accept failed", f"accept failed: {strerror(exc)}")
            self._sleep(0.05)
            return
        if len(self._clients) >= self.MAX_CLIENTS:
            self._error("too many clients", f"refused client {fmt_addr(addr)}: {self.MAX_CLIENTS} connected")
            conn.close()
            return
        conn.setblocking(False)
        tune_stream(conn)
        peer = fmt_addr(addr)
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
                    data = sock.recv(READ_SIZE)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError as exc:
                    self._error("disconnected", f"client {peer}: {strerror(exc)}", logging.INFO)
                    self._drop(sock, strerror(exc))
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
                problem = send_all(sock, data, self.timeout_s)
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
