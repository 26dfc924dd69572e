"""Zenoh: opening a session the way DESIGN.md prescribes.

Default: peer mode on the local machine, no router needed (multicast scouting finds local peers).
``connect`` / ``listen`` endpoints (e.g. ``tcp/192.168.1.10:7447``) join an existing Zenoh network or
router; a Zenoh JSON5 config file overrides everything. Tests use ``isolated_config`` (loopback only,
scouting off) so parallel tests and other programs never see each other.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import zenoh


class BusError(RuntimeError):
    """A Zenoh configuration a person must fix (bad endpoint, unreadable config file)."""


def make_config(
    *,
    mode: str = "peer",
    connect: Sequence[str] = (),
    listen: Sequence[str] = (),
    multicast_scouting: bool = True,
    config_file: str | Path | None = None,
) -> zenoh.Config:
    if config_file is not None:
        path = Path(config_file)
        if not path.is_file():
            raise BusError(f"zenoh config file '{path}' does not exist")
        try:
            return zenoh.Config.from_file(str(path))
        except Exception as exc:  # zenoh raises its own ZError
            raise BusError(f"zenoh config file '{path}': {exc}") from None
    if mode not in ("peer", "client"):
        raise BusError(f"zenoh mode '{mode}': expected 'peer' or 'client'")
    conf: dict[str, Any] = {"mode": mode, "scouting": {"multicast": {"enabled": multicast_scouting}}}
    if connect:
        conf["connect"] = {"endpoints": list(connect)}
    if listen:
        conf["listen"] = {"endpoints": list(listen)}
    try:
        return zenoh.Config.from_json5(json.dumps(conf))
    except Exception as exc:
        raise BusError(f"zenoh endpoints {list(connect) + list(listen)}: {exc}") from None


def isolated_config(listen: Sequence[str] = (), connect: Sequence[str] = ()) -> zenoh.Config:
    """Loopback-only session with multicast scouting off (tests, demo)."""
    return make_config(listen=listen, connect=connect, multicast_scouting=False)


def open_session(config: zenoh.Config) -> zenoh.Session:
    try:
        return zenoh.open(config)
    except Exception as exc:
        raise BusError(f"cannot open a zenoh session: {exc}") from None
