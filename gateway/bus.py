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
import re
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import zenoh

from gateway.config.endpoints import endpoint_parts, is_ip


class BusError(RuntimeError):
    """A Zenoh configuration a person must fix (bad endpoint, port in use, unreadable config file).

    ``key`` is the session setting at fault (``listen``, ``connect``, ``config_file`` or None), ``problem``
    says what went wrong naming the endpoint, ``fix`` what to do. `describe` names the setting the way the
    person wrote it (``zenoh.listen`` in a config file, ``--listen`` on a command line); ``str()`` uses the
    config keys. Zenoh's own messages end in Rust source locations: those are dropped, they mean nothing
    to the person who must fix the endpoint.
    """

    def __init__(self, problem: str, *, key: str | None = None, fix: str = "") -> None:
        self.problem = problem
        self.key = key
        self.fix = fix
        super().__init__(self.describe())

    def describe(self, names: Mapping[str, str] | None = None) -> str:
        name = (names or {}).get(self.key or "", f"zenoh.{self.key}" if self.key else "zenoh")
        return f"{name}: {self.problem}" + (f" — {self.fix}" if self.fix else "")

    def __str__(self) -> str:
        return self.describe()


class UnreachableError(BusError):
    """Nothing answers at the ``connect`` endpoints (a client found no router): the configuration may be
    right, the router not up yet. `Dialler` waits for it."""


JSON = zenoh.Encoding.APPLICATION_JSON
"""The encoding every dpgw payload is put with (docs/interfaces.md): the gateway's, and a paced replay's."""

_RUST_LOCATION = re.compile(r"\s*\bat /\S+\.rs:\d+\.?")
_ENDPOINT_FORM = "PROTOCOL/HOST:PORT, e.g. tcp/0.0.0.0:7447"


def _clean(text: str) -> str:
    """A Zenoh error without its Rust source locations."""
    return _RUST_LOCATION.sub("", text).strip()


def key_expr_problem(key: str) -> str | None:
    """Why ``key`` is not a Zenoh key expression (None when it is one), in words that say what to write.

    The common slip is an MCAP topic (``/dp/estimate``) given as a key: Zenoh keys have no leading '/'.
    """
    try:
        zenoh.KeyExpr(key)
    except zenoh.ZError as exc:
        reason = _clean(str(exc)).split(": ", 1)[-1]
        fixed = "/".join(c for c in key.split("/") if c)
        if key.startswith("/dp/") and fixed.count("/") == 1:
            # the log's topic /dp/X is the key <prefix>/X, and the prefix is dp/<vessel> by default
            fixed = "dp/*/" + fixed.split("/", 1)[1]
        end = f" — did you mean '{fixed}'?" if fixed and fixed != key and _is_key(fixed) else "."
        return (
            f"'{key}' is not a Zenoh key expression ({reason}){end} Keys are chunks separated by single '/', "
            "with no leading or trailing '/' (the log's topic /dp/estimate is the key dp/<vessel>/estimate); "
            "* matches one chunk, ** any number"
        )
    return None


def _is_key(key: str) -> bool:
    try:
        zenoh.KeyExpr(key)
    except zenoh.ZError:
        return False
    return True


def _explain(exc: Exception, listen: Sequence[str], connect: Sequence[str]) -> BusError:
    """One `BusError` naming the setting and the endpoint, from Zenoh's message about opening a session."""
    text = _clean(str(exc))
    low = text.lower()
    configured = [("listen", e) for e in listen] + [("connect", e) for e in connect]
    named = [(k, e) for k, e in configured if e in text]

    def pick(key: str | None, test: Any = None) -> tuple[str | None, str]:
        hits = named or [
            (k, e) for k, e in configured if (key is None or k == key) and (test is None or test(e))
        ]
        if not hits:
            hits = [(k, e) for k, e in configured if key is None or k == key]
        keys = {k for k, _ in hits}
        return (keys.pop() if len(keys) == 1 else key), ", ".join(e for _, e in hits) or "?"

    if "address already in use" in low or "os error 98" in low:
        key, ep = pick("listen")
        return BusError(
            f"cannot listen on {ep}: address in use",
            key=key,
            fix="another zenohd or dpgw is listening there; choose another port",
        )
    if "cannot assign requested address" in low or "os error 99" in low:
        key, ep = pick("listen")
        return BusError(
            f"cannot listen on {ep}: not an address of this machine",
            key=key,
            fix="use one of this machine's addresses, or 0.0.0.0 for all of them",
        )
    if "permission denied" in low or "os error 13" in low:
        key, ep = pick("listen")
        return BusError(
            f"cannot listen on {ep}: permission denied", key=key, fix="ports below 1024 need root; use 7447"
        )
    if "endpoints must be of the form" in low:
        key, ep = pick(None, lambda e: "/" not in e)
        return BusError(f"'{ep}' is not an endpoint", key=key, fix=f"write {_ENDPOINT_FORM}")
    if "invalid port" in low:
        key, ep = pick(None, lambda e: not _valid_port(e))
        return BusError(
            f"{ep}: invalid port", key=key, fix=f"a port is a number up to 65535: {_ENDPOINT_FORM}"
        )
    m = re.search(r"not supported for (\S+) protocol", text)
    if m:
        proto = m.group(1)
        key, ep = pick(None, lambda e: e.startswith(f"{proto}/"))
        return BusError(f"{ep}: unknown protocol '{proto}'", key=key, fix=f"write {_ENDPOINT_FORM}")
    if "failed to lookup address" in low or "name or service not known" in low:
        key, ep = pick(None)
        return BusError(f"{ep}: unknown host name", key=key, fix="check the name, or write the IP address")
    if "unable to connect" in low:
        key, ep = pick("connect")
        return UnreachableError(
            f"cannot connect to {ep}",
            key=key,
            fix="is a Zenoh router or peer running there? check the address and the port",
        )
    return BusError(f"cannot open a session: {text}", key=None)


def _valid_port(endpoint: str) -> bool:
    port = endpoint.split("?", 1)[0].split("#", 1)[0].rsplit(":", 1)[-1]
    return port.isdigit() and 0 <= int(port) <= 65535


def _endpoints(config: zenoh.Config, key: str) -> list[str]:
    try:
        value = json.loads(config.get_json(f"{key}/endpoints"))
    except Exception:  # a shape this version of Zenoh does not give: name no endpoint
        return []
    if isinstance(value, dict):  # per-mode endpoints ({"peer": [...], "router": [...]})
        return [str(e) for v in value.values() for e in (v if isinstance(v, list) else [v])]
    return [str(e) for e in value] if isinstance(value, list) else []


def unlinked(connect: Sequence[str], session: zenoh.Session) -> list[str]:
    """The ``connect`` endpoints ``session`` has no link to now, as written.

    A link the session dialled has the endpoint's address as its ``dst`` (Zenoh gives it resolved: a host
    name comes back as its IP address). An endpoint with an IP address is matched on protocol, address and
    port; one with a host name on protocol and port only (resolving the name here would wait on DNS in the
    status loop; two ``connect`` endpoints on one port of different named hosts are rare enough). Zenoh
    dials a ``connect`` endpoint even when the peer there has dialled this session's listener too (the two
    keep a link each), so a peer reached only the other way is not taken for a dead endpoint."""
    linked = {endpoint_parts(str(link.dst)) for link in session.info.links()}
    named = {(proto, port) for proto, _, port in linked}
    down = []
    for endpoint in connect:
        proto, host, port = endpoint_parts(endpoint)
        ok = (proto, host, port) in linked if is_ip(host) else (proto, port) in named
        if not ok:
            down.append(endpoint)
    return down


REDIAL_S = 0.5
"""How often a session dials a ``connect`` endpoint (a router, a console) that is not up yet or lost (s):
one TCP connect attempt, well under a millisecond of work when nobody answers."""


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
            raise BusError(f"'{path}' does not exist", key="config_file")
        try:
            return zenoh.Config.from_file(str(path))
        except Exception as exc:  # zenoh raises its own ZError
            raise BusError(f"'{path}': {_clean(str(exc))}", key="config_file") from None
    if mode not in ("peer", "client"):
        raise BusError(f"'{mode}': expected 'peer' or 'client'", key="mode")
    conf: dict[str, Any] = {"mode": mode, "scouting": {"multicast": {"enabled": multicast_scouting}}}
    if connect:
        conf["connect"] = {"endpoints": list(connect)}
    if mode == "client" or connect:
        # A router or console that is not up yet or lost is redialled every REDIAL_S (Zenoh's default
        # backs off from 1 s to 4 s): a peer's endpoints in the background from the start, a client's once
        # it has connected (until then `Dialler` dials it). One TCP connect per period to a dead endpoint
        # costs nothing; a DP gateway's outputs are back within a period of the router's return. The open
        # itself keeps Zenoh's defaults (a client: one dial, fail at once).
        period_ms = round(REDIAL_S * 1000)
        retry = {"period_init_ms": period_ms, "period_max_ms": period_ms, "period_increase_factor": 1}
        conf.setdefault("connect", {})["retry"] = retry
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
        raise _explain(exc, listen, connect) from None


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
    """Loopback-only session with multicast scouting off (tests, benches): listening on ``listen``, else on a
    free port of this computer only (Zenoh's own default would be every interface)."""
    return make_config(listen=list(listen) or ["tcp/127.0.0.1:0"], connect=connect, multicast_scouting=False)


def open_session(config: zenoh.Config) -> zenoh.Session:
    try:
        return zenoh.open(config)
    except Exception as exc:
        raise _explain(exc, _endpoints(config, "listen"), _endpoints(config, "connect")) from None


class Dialler:
    """A client session opened as soon as its router answers, in a thread of its own.

    Zenoh 1.x opens a client session only once it has reached a router: ``zenoh.open`` either fails at
    once (a client's default, ``connect.exit_on_failure``) or, with ``connect.timeout_ms = -1``, blocks
    until the router comes, in a call no one can cancel. A gateway on a vessel must start whatever the
    order the services come up in, and must stop when told. So the thread dials again every ``period_s``
    with the fail-fast open (cancelled by `close` between two dials); once connected, a lost router is
    Zenoh's business (it redials it by itself). ``config`` builds a fresh `zenoh.Config` for each dial.
    Another failure than `UnreachableError` (a listener's port taken meanwhile by another program) is kept
    in `error` for the status to say, and the dialling goes on: the port may be freed.
    """

    def __init__(self, config: Callable[[], zenoh.Config], period_s: float = REDIAL_S) -> None:
        self._config = config
        self._period_s = period_s
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._session: zenoh.Session | None = None
        self.error: BusError | None = None
        self.dials = 0
        self._thread = threading.Thread(target=self._run, name="zenoh-dialler", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._period_s):
            self.dials += 1
            try:
                session = open_session(self._config())
            except UnreachableError:
                self.error = None
                continue
            except BusError as exc:
                self.error = exc
                continue
            self.error = None
            with self._lock:
                if self._stop.is_set():  # closed while this dial succeeded
                    session.close()
                else:
                    self._session = session
            return

    def take(self) -> zenoh.Session | None:
        """The open session once it has connected (once: the caller owns it then), else None."""
        with self._lock:
            session, self._session = self._session, None
        return session

    def close(self) -> None:
        """Stop dialling; a session opened and never taken is closed."""
        self._stop.set()
        self._thread.join()
        session = self.take()
        if session is not None:
            session.close()
