"""``dpgw run``: the live gateway from a TOML config (the onboard service)."""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import tomllib
from typing import Any

from gateway.bus import BusError
from gateway.config import ConfigError, format_problems, load_config
from gateway.service import GatewayService
from gateway.sources import SourceError


def register(sub: Any) -> None:
    p = sub.add_parser(
        "run",
        help="run the gateway: sensor streams in, observer, Zenoh and MCAP out",
        description=(
            "Run the live gateway described by a TOML config: read the DGPS/gyro NMEA and MAVLink thruster "
            "links, estimate the low-frequency motion with the wave-filtering observer, publish estimate, "
            "measurement and status on Zenoh (<prefix>/...) and log everything to MCAP. SIGINT or SIGTERM "
            "flush and close the log. A config mistake or a missing serial port stops start-up with one "
            "message naming what and where."
        ),
        epilog=(
            "examples:\n"
            "  dpgw run --config /etc/dpgw/vessel.toml\n"
            "  dpgw run --config examples/nmea_udp_multiplexer.toml --log /tmp/trial.mcap\n"
            "  dpgw run --config vessel.toml --check        # validate the config and exit\n"
            "see examples/ for configs and a systemd unit; docs/config.md for every key"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", required=True, metavar="FILE", help="gateway config (TOML)")
    p.add_argument("--log", metavar="FILE.mcap", help="override [log] path")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (tests, trials)")
    p.add_argument("--check", action="store_true", help="validate the config and exit (0 when it is good)")
    p.add_argument("--json", action="store_true", help="print the exit summary as JSON")
    p.add_argument("-v", "--verbose", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    try:
        config = load_config(args.config)
    except ConfigError as exc:
        print(format_problems(exc), file=sys.stderr)
        return 2
    if args.check:
        print(f"{args.config}: OK ({len(config.sources)} sources, vessel {config.vessel.name})")
        return 0
    with open(args.config, "rb") as f:
        tables = tomllib.load(f)
    service = GatewayService(config, log_path=args.log, config_tables=tables)
    try:
        service.start()
    except (SourceError, BusError, OSError) as exc:
        print(f"dpgw run: {exc}", file=sys.stderr)
        return 2

    def on_signal(signum: int, _frame: object) -> None:
        service.stop_event.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        service.run(args.duration)
        service.drain()
    finally:
        status = service.pipeline.status(service.pipeline.last_ns).payload
        service.close()
    summary = {"estimates": service.pipeline.estimates, "published": service.published, "status": status}
    if args.json:
        print(json.dumps(summary, indent=2, default=str))
    else:
        print(
            f"dpgw run: stopped; {service.pipeline.estimates} estimates, "
            f"{service.published} messages published"
        )
    return 0
