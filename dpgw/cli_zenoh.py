"""The Zenoh options the commands share: one help text each, and how a bus error names them.

Light on purpose (standard library only): every command's parser is built at start-up, also for
``--help``, so nothing here may import Zenoh.
"""

from __future__ import annotations

from typing import Any

# What a `gateway.bus.BusError` key is called on each command line (``dpgw listen`` has the short names).
ZENOH_FLAGS = {"listen": "--zenoh-listen", "connect": "--zenoh-connect", "config_file": "--zenoh-config"}
LISTEN_FLAGS = {"listen": "--listen", "connect": "--connect", "config_file": "--zenoh-config"}


def add_endpoint_args(p: Any, *, listen: str = "--zenoh-listen", connect: str = "--zenoh-connect") -> None:
    p.add_argument(
        listen,
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable; default: Zenoh picks a free "
        "port and finds local peers by multicast scouting)",
    )
    p.add_argument(
        connect,
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh router or peer to connect to, e.g. tcp/192.168.1.10:7447 (repeatable)",
    )
