"""``dpgw listen``: print what arrives on Zenoh (estimates, status, commands ...).

Zenoh is imported by `run`, not here: building the parser (``--help``) must stay instant.
"""

from __future__ import annotations

import argparse
import base64
import json
import sys
import time
from typing import Any

from dpgw import cli_json
from dpgw.cli_types import positive_float, positive_int
from dpgw.cli_zenoh import LISTEN_FLAGS, add_endpoint_args, listen_endpoints

NAME = "listen"
DEFAULT_KEY = "dp/**"
HELP = "print what arrives on Zenoh"
DESCRIPTION = (
    "Subscribe to a Zenoh key expression (default dp/**, without the simulator's clock) and print every "
    "sample: one line each, "
    '\'KEY: PAYLOAD\', or with --json one JSON object {"key": KEY, "payload": PAYLOAD} (the payload '
    "as published: docs/interfaces.md lists the fields)."
)
EPILOG = (
    "examples:\n"
    "  dpgw listen                              # everything under dp/\n"
    "  dpgw listen 'dp/mss_supply/estimate' --json | jq -c .payload.eta\n"
    "  dpgw listen --connect tcp/192.168.1.10:7447 'dp/*/status'"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "key",
        nargs="?",
        help="Zenoh key expression (default dp/**, leaving out the simulator's clock <prefix>/sim/clock, "
        "which is a third of what a demo publishes: name it, or give --all, to see it)",
    )
    p.add_argument("--all", action="store_true", help="with the default key, the simulator's clock too")
    p.add_argument("--json", action="store_true", help="one JSON object per line: {key, payload}")
    p.add_argument("--count", type=positive_int, metavar="N", help="exit after N samples")
    p.add_argument(
        "--duration",
        type=positive_float,
        metavar="S",
        help="exit after S seconds (status 1, saying so, if nothing arrived)",
    )
    add_endpoint_args(p, listen="--listen", connect="--connect")
    p.add_argument("--no-scouting", action="store_true", help="multicast scouting off (use --connect)")
    p.add_argument(
        "--zenoh-config", metavar="FILE", help="a Zenoh JSON5 config file (replaces the options above)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import queue
    import signal

    from gateway.bus import BusError, key_expr_problem, make_config, open_session
    from wire.messages import SIM_CLOCK_KEY

    # the simulator's clock (10 ticks a second) is left out of the default view, not out of a key asked for
    hide_clock = args.key is None and not args.all
    args.key = args.key or DEFAULT_KEY
    if problem := key_expr_problem(args.key):
        print(f"dpgw listen: {problem}", file=sys.stderr)
        return 2
    try:
        session = open_session(
            make_config(
                connect=args.connect,
                listen=listen_endpoints(args.listen),
                multicast_scouting=not args.no_scouting,
                config_file=args.zenoh_config,
            )
        )
    except BusError as exc:
        print(f"dpgw listen: {exc.describe(LISTEN_FLAGS)}", file=sys.stderr)
        return 2
    samples: queue.Queue[tuple[str, bytes]] = queue.Queue()
    sub = session.declare_subscriber(args.key, lambda s: samples.put((str(s.key_expr), s.payload.to_bytes())))
    stop = {"now": False}
    signal.signal(signal.SIGINT, lambda *_: stop.update(now=True))
    signal.signal(signal.SIGTERM, lambda *_: stop.update(now=True))
    if hint := key_hint(args.key):
        # known from the key alone, so said at once (once Ctrl-C is handled): it was said only when a
        # --duration ended with nothing heard, and a listener stopped with Ctrl-C (how most stop it) never
        # learnt why it heard nothing
        print(f"dpgw listen: {args.key}: {hint.removeprefix('; ')}", file=sys.stderr, flush=True)
    deadline = None if args.duration is None else time.monotonic() + args.duration
    n = clock_seen = 0
    clock_suffix = "/" + SIM_CLOCK_KEY
    interrupted = False
    reached = 0
    try:
        while not stop["now"] and (args.count is None or n < args.count):
            if deadline is not None and time.monotonic() > deadline:
                break
            try:
                key, body = samples.get(timeout=0.1)
            except queue.Empty:
                continue
            if hide_clock and key.endswith(clock_suffix):
                clock_seen += 1
                continue
            n += 1
            print(sample_line(key, body, as_json=args.json), flush=True)
        interrupted = stop["now"]
        if n == 0:
            reached = len(list(session.info.peers_zid())) + len(list(session.info.routers_zid()))
    finally:
        sub.undeclare()
        session.close()
    if n == 0 and not interrupted:
        if clock_seen:
            print(
                f"dpgw listen: only the simulator's clock on {args.key} ({clock_seen} ticks, left out: "
                "give --all, or its key, to see them): no gateway publishing there yet",
                file=sys.stderr,
            )
            return 1
        print(f"dpgw listen: {nothing_heard(args, reached)}", file=sys.stderr)
        return 1
    return 0


BINARY_SHOWN = 16
"""Bytes of a binary payload shown, in hex, on a line of text (the rest is counted)."""


def decode_payload(body: bytes) -> tuple[str, Any]:
    """(encoding, payload): ``json`` (the value), ``text`` (a str: UTF-8 without control characters but
    tab and line breaks), or ``base64`` (the bytes in base64: ROS 2's CDR, Keelson's protobuf)."""
    try:
        return "json", json.loads(body)
    except ValueError:
        pass
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError:
        text = None
    if text is not None and all(c.isprintable() or c in "\t\r\n" for c in text):
        return "text", text
    return "base64", base64.b64encode(body).decode("ascii")


def sample_line(key: str, body: bytes, *, as_json: bool) -> str:
    """One sample as printed: ``KEY: PAYLOAD``; a binary payload as its length and first bytes in hex
    (printed raw, CDR or protobuf wrote control bytes to the terminal); with ``as_json`` one object
    ``{"key", "payload"}`` for JSON (every dpgw payload: what programs read stays as it was), and for
    another payload ``encoding`` too (`decode_payload`'s; base64 with ``bytes``, its length)."""
    encoding, payload = decode_payload(body)
    if as_json:
        out: dict[str, Any] = {"key": key, "payload": payload}
        if encoding != "json":
            out["encoding"] = encoding
        if encoding == "base64":
            out["bytes"] = len(body)
        return cli_json.dumps(out)
    if encoding == "json":
        return f"{key}: {json.dumps(payload)}"
    if encoding == "text":
        return f"{key}: {payload}"
    more = "…" if len(body) > BINARY_SHOWN else ""
    return f"{key}: <{len(body)} bytes, binary (not JSON nor text): {body[:BINARY_SHOWN].hex(' ')}{more}>"


def key_hint(key: str) -> str:
    """What a key misses of Keelson's (""): its keys have an ``@v0`` chunk, and Zenoh's wildcards never
    match a chunk that starts with ``@`` (docs/keelson.md), so ``keelson/**`` and ``**`` hear none."""
    chunks = key.split("/")
    if any(c.startswith("@") for c in chunks):
        return ""
    if chunks[0] == "keelson":
        rest = "/".join(chunks[1:]) or "**"
        said = "; Keelson's keys have an @v0 chunk, which no wildcard matches in Zenoh"
        return f"{said}: try 'keelson/@v0/{rest}'"
    if key == "**":
        return "; '**' matches no chunk that starts with '@': name it, as in Keelson's 'keelson/@v0/**'"
    return ""


def nothing_heard(args: argparse.Namespace, reached: int) -> str:
    """What to check when --duration passed without a sample: a silent exit would look like an empty bus.

    ``reached``: the Zenoh peers and routers this session was connected to at the end.
    """
    said = f"nothing on {args.key} in {args.duration:g} s"
    unknown = [e for e in args.connect or () if not _resolves(e)]
    if reached == 0 and unknown:
        hosts = ", ".join(repr(_host(e)) for e in unknown)
        return (
            f"{said}: {hosts} is not a name this computer can resolve (--connect {', '.join(unknown)}): "
            "a typo, or a name only another network knows? Give its IP address"
        )
    if reached == 0 and args.connect:
        return (
            f"{said}: nothing answered at {', '.join(args.connect)} (--connect): is a Zenoh router or a "
            "gateway listening there? ('dpgw run' listens where [zenoh] listen says)"
        )
    if reached == 0:
        return (
            f"{said}: no Zenoh peer found{' (scouting is off: give --connect)' if args.no_scouting else ''}: "
            "is a gateway running (dpgw run, dpgw demo)? On another computer: --connect tcp/HOST:7447"
        )
    return (
        f"{said}, though {reached} Zenoh peer{'s' if reached > 1 else ''} answered: is the key right? "
        "'dp/**' shows everything a gateway publishes"
        + ("; and see the note on the key above" if key_hint(args.key) else "")
    )


def _host(endpoint: str) -> str:
    """The host of a Zenoh endpoint ``proto/host:port`` (an IPv6 address in brackets, unbracketed)."""
    addr = endpoint.split("/", 1)[-1].split("#", 1)[0]
    host = addr.rsplit(":", 1)[0] if ":" in addr else addr
    return host.strip("[]")


def _resolves(endpoint: str) -> bool:
    """Whether the host of a tcp/udp/tls/quic endpoint resolves (others, such as serial, are not asked)."""
    import socket

    if endpoint.split("/", 1)[0] not in ("tcp", "udp", "tls", "quic", "ws"):
        return True
    try:
        socket.getaddrinfo(_host(endpoint), None)
    except (socket.gaierror, UnicodeError):
        return False
    return True
