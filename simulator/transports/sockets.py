"""Socket helpers shared by the UDP and TCP sinks: name resolution, address text, bind errors."""

from __future__ import annotations

import errno
import socket

from simulator.transports.base import TransportError


def resolve(url: str, host: str, port: int, kind: int, *, passive: bool = False) -> tuple[int, tuple]:
    try:
        infos = socket.getaddrinfo(host, port, type=kind, flags=socket.AI_PASSIVE if passive else 0)
    except (OSError, UnicodeError) as exc:
        raise TransportError(
            url, f"cannot resolve host {host!r}: {exc}", "check the host name or address"
        ) from exc
    family, _, _, _, sockaddr = infos[0]
    return family, sockaddr


def fmt_addr(addr: tuple) -> str:
    host, port = addr[0], addr[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def bind_error(url: str, address: str, exc: OSError, what: str = "port") -> TransportError:
    if exc.errno == errno.EADDRINUSE:
        fix = f"another program uses this {what}: stop it or choose another port (0 picks a free one)"
    elif exc.errno == errno.EACCES:
        fix = "ports below 1024 need privileges: choose a port of 1024 or above"
    elif exc.errno == errno.EADDRNOTAVAIL:
        fix = "the host is not an address of this machine: use 127.0.0.1, 0.0.0.0 or one of its addresses"
    else:
        fix = ""
    return TransportError(url, f"cannot bind {address}: {exc.strerror or exc}", fix)
