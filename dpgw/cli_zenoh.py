"""The Zenoh options the commands share: one help text each, and how a bus error names them.

Light on purpose (standard library only): every command's parser is built at start-up, also for
``--help``, so nothing here may import Zenoh.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

# What a `gateway.bus.BusError` key is called on each command line (``dpgw listen`` has the short names).
ZENOH_FLAGS = {"listen": "--zenoh-listen", "connect": "--zenoh-connect", "config_file": "--zenoh-config"}
LISTEN_FLAGS = {"listen": "--listen", "connect": "--connect", "config_file": "--zenoh-config"}

LOOPBACK_LISTEN = "tcp/127.0.0.1:0"
"""Where a command's Zenoh session listens when no endpoint is given: a free port on this computer only,
as the gateway's ``[zenoh] listen`` default. Zenoh's own peer default (every interface) would let any
machine on the network reach the session — a demo's gateway takes mode, setpoint and τ from its peers."""


def listen_endpoints(given: Sequence[str]) -> list[str]:
    """The endpoints to listen on: those given (``--zenoh-listen``), else `LOOPBACK_LISTEN`. Local tools
    still find the session by multicast scouting; another computer needs a listener opened on purpose."""
    return list(given) or [LOOPBACK_LISTEN]


def add_endpoint_args(p: Any, *, listen: str = "--zenoh-listen", connect: str = "--zenoh-connect") -> None:
    p.add_argument(
        listen,
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, e.g. tcp/192.168.10.5:7447 to be reached from that network "
        "(repeatable; default: a free port on this computer only, tcp/127.0.0.1:0; local peers are found by "
        "multicast scouting)",
    )
    p.add_argument(
        connect,
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh router or peer to connect to, e.g. tcp/192.168.1.10:7447 (repeatable)",
    )
