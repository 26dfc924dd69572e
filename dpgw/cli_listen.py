"""``dpgw listen``: print what arrives on Zenoh (estimates, status, commands ...).

Zenoh is imported by `run`, not here: building the parser (``--help``) must stay instant.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from dpgw.cli_zenoh import LISTEN_FLAGS, add_endpoint_args

NAME = "listen"
HELP = "print what arrives on Zenoh"
DESCRIPTION = (
    "Subscribe to a Zenoh key expression (default dp/**) and print every sample: one line each, "
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
    p.add_argument("key", nargs="?", default="dp/**", help="Zenoh key expression (default dp/**)")
    p.add_argument("--json", action="store_true", help="one JSON object per line: {key, payload}")
    p.add_argument("--count", type=int, metavar="N", help="exit after N samples")
    p.add_argument("--duration", type=float, metavar="S", help="exit after S seconds")
    add_endpoint_args(p, listen="--listen", connect="--connect")
    p.add_argument("--no-scouting", action="store_true", help="multicast scouting off (use --connect)")
    p.add_argument(
        "--zenoh-config", metavar="FILE", help="a Zenoh JSON5 config file (replaces the options above)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import queue
    import signal

    from gateway.bus import BusError, make_config, open_session

    try:
        session = open_session(
            make_config(
                connect=args.connect,
                listen=args.listen,
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
    deadline = None if args.duration is None else time.monotonic() + args.duration
    n = 0
    try:
        while not stop["now"] and (args.count is None or n < args.count):
            if deadline is not None and time.monotonic() > deadline:
                break
            try:
                key, body = samples.get(timeout=0.1)
            except queue.Empty:
                continue
            n += 1
            try:
                payload: Any = json.loads(body)
            except ValueError:
                payload = body.decode("utf-8", "replace")
            if args.json:
                print(json.dumps({"key": key, "payload": payload}), flush=True)
            else:
                print(
                    f"{key}: {json.dumps(payload) if not isinstance(payload, str) else payload}", flush=True
                )
    finally:
        sub.undeclare()
        session.close()
    return 0
