"""Zenoh: opening a session the way DESIGN.md prescribes.

Default: peer mode on the local machine, no router needed (multicast scouting finds local peers).
``connect`` / ``listen`` endpoints (e.g. ``tcp/192.168.1.10:7447``) join an existing Zenoh network or
router; a Zenoh JSON5 config file overrides everything. Tests use ``isolated_config`` (loopback only,
scouting off) so parallel tests and other programs never see each other.

Who may talk to a session is Zenoh's own business (docs/security.md): ``users_file`` makes every peer
authenticate with a user name and password (Zenoh's ``usrpwd``), and ``command_acl`` builds the access
control that lets only the named users put on the command keys. ``dial_scouted = False`` (the gateway's
session) stops the session from connecting out to the peers it discovers: then only those that can
reach its listeners (loopback by default) get in, which multicast scouting alone would not ensure.
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
    dial_scouted: bool = True,
    users_file: str | Path | None = None,
    user: str = "",
    password: str = "",
    access_control: dict[str, Any] | None = None,
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
    if not dial_scouted:
        nobody: dict[str, list[str]] = {"router": [], "peer": []}
        conf["scouting"]["multicast"]["autoconnect"] = nobody
        conf["scouting"]["gossip"] = {"autoconnect": nobody}
    usrpwd: dict[str, str] = {}
    if users_file is not None:
        usrpwd["dictionary_file"] = str(users_file)
    if user:
        usrpwd.update(user=user, password=password)
    if usrpwd:
        conf["transport"] = {"auth": {"usrpwd": usrpwd}}
    if access_control is not None:
        conf["access_control"] = access_control
    try:
        return zenoh.Config.from_json5(json.dumps(conf))
    except Exception as exc:
        raise BusError(f"zenoh endpoints {list(connect) + list(listen)}: {exc}") from None


ALL_MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
)
"""The message kinds of Zenoh's access control."""


def command_acl(command_keys: Sequence[str], commanders: Sequence[str]) -> dict[str, Any]:
    """Access control in which only ``commanders`` (authenticated user names) may put on ``command_keys``.

    Zenoh applies only the rules whose permission differs from the default, so the default is ``deny``
    and everything else is allowed explicitly: all outgoing messages, and every incoming one except puts
    and deletes (a gateway subscribes to nothing but its command keys, so the only puts it receives are
    commands). Queries on the status, subscriptions to the estimate and the rest go on for every peer.
    """
    reading = [m for m in ALL_MESSAGES if m not in ("put", "delete")]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {
                "id": "out",
                "permission": "allow",
                "flows": ["egress"],
                "messages": list(ALL_MESSAGES),
                "key_exprs": ["**"],
            },
            {
                "id": "in",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": reading,
                "key_exprs": ["**"],
            },
            {
                "id": "command",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                "key_exprs": list(command_keys),
            },
        ],
        "subjects": [{"id": "anyone"}, {"id": "commanders", "usernames": list(commanders)}],
        "policies": [
            {"id": "everyone", "rules": ["out", "in"], "subjects": ["anyone"]},
            {"id": "commanding", "rules": ["command"], "subjects": ["commanders"]},
        ],
    }


def isolated_config(listen: Sequence[str] = (), connect: Sequence[str] = ()) -> zenoh.Config:
    """Loopback-only session with multicast scouting off (tests, demo)."""
    return make_config(listen=listen, connect=connect, multicast_scouting=False)


def open_session(config: zenoh.Config) -> zenoh.Session:
    try:
        return zenoh.open(config)
    except Exception as exc:
        raise BusError(f"cannot open a zenoh session: {exc}") from None
