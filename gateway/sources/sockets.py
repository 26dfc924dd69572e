"""Socket helpers shared by the UDP and TCP sources: address text, whole sends, bind errors, stream tuning."""

from __future__ import annotations

import contextlib
import errno
import select
import socket
import time
from typing import Any

from gateway.sources.base import POLL_S, strerror


def fmt_addr(addr: tuple[Any, ...]) -> str:
    """A socket address as ``host:port`` (``[v6]:port``): the form of `Chunk.peer` and of messages."""
    host, port = addr[0], addr[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def send_all(sock: socket.socket, data: bytes, timeout_s: float) -> str | None:
    """Send all of ``data`` on a non-blocking stream socket within ``timeout_s``; the error text, or None."""
    view = memoryview(data)
    deadline = time.monotonic() + timeout_s
    while view:
        try:
            n = sock.send(view, socket.MSG_NOSIGNAL)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            return strerror(exc)
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


def bind_problem(address: str, exc: OSError, what: str) -> tuple[str, str]:
    """The problem and the fix of a failed bind, for `SourceError`."""
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
    return f"cannot listen on {address}: {strerror(exc)}", fix


def tune_stream(sock: socket.socket) -> None:
    """No Nagle delay (commands are small and time-critical); keepalive finds a dead peer in ~11 s."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE, 5)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL, 2)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT, 3)
