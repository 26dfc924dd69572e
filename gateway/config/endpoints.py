"""Zenoh endpoints (``PROTO/HOST:PORT[?metadata][#config]``, e.g. ``tcp/192.168.1.10:7447``) taken apart.

One reading of an endpoint for everything that looks inside one: the start-up note on who may command
the vessel (is every endpoint on loopback?) and the bus's check that a ``connect`` endpoint is linked.
The config's own validation (`gateway.config.load`) checks the form and says what is wrong; these
functions take an endpoint as it is and never raise.
"""

from __future__ import annotations

import ipaddress

__all__ = ["endpoint_parts", "is_ip", "is_loopback"]


def endpoint_parts(endpoint: str) -> tuple[str, str, str]:
    """(protocol, host, port) of ``PROTO/HOST:PORT[?metadata][#config]``; an IPv6 host without its
    brackets; empty strings for what is not there."""
    proto, _, rest = endpoint.split("?", 1)[0].split("#", 1)[0].partition("/")
    host, _, port = rest.rpartition(":")
    return proto, host.strip("[]"), port


def is_ip(host: str) -> bool:
    """Whether ``host`` is an IP address (v4 or v6), not a name."""
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True


def is_loopback(endpoint: str) -> bool:
    """Whether ``endpoint`` is on a loopback address or ``localhost``: reachable from this computer only."""
    host = endpoint_parts(endpoint)[1]
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name other than localhost
