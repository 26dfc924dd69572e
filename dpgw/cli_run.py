"""``dpgw run``: the live gateway from a TOML config (the onboard service)."""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import tomllib

from gateway.bus import BusError
from gateway.config import ConfigError, GatewayConfig, describe, format_problems, load_config
from gateway.service import GatewayService, zenoh_config
from gateway.sources import SourceError, open_source

NAME = "run"
HELP = "run the gateway: sensor streams in, observer, Zenoh and MCAP out"
DESCRIPTION = (
    "Run the live gateway described by a TOML config: read the DGPS/gyro NMEA and MAVLink thruster "
    "links, estimate the low-frequency motion with the wave-filtering observer, publish estimate, "
    "measurement and status on Zenoh (<prefix>/...) and log everything to MCAP. SIGINT or SIGTERM "
    "flush and close the log. A config mistake or a missing serial port stops start-up with one "
    "message naming what and where."
)
EPILOG = (
    "examples:\n"
    "  dpgw run --config /etc/dpgw/vessel.toml\n"
    "  dpgw run --config examples/nmea_udp_multiplexer.toml --log /tmp/trial.mcap\n"
    "  dpgw run --config vessel.toml --check        # validate the config and exit\n"
    "see examples/ for configs and a systemd unit; docs/config.md for every key"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", required=True, metavar="FILE", help="gateway config (TOML)")
    p.add_argument("--log", metavar="FILE.mcap", help="override [log] path")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (tests, trials)")
    p.add_argument(
        "--check",
        action="store_true",
        help="check the config and exit: a summary (status 0) or every problem (status 2); opens nothing",
    )
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
        problems = start_up_problems(config)
        if problems:
            print(format_problems(problems), file=sys.stderr)
            return 2
        print(describe(config))
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


def start_up_problems(config: GatewayConfig) -> list[str]:
    """What start-up would refuse beyond the config's own checks, found without opening anything: each
    source URL as the gateway's sources read it, and the Zenoh session's config."""
    where = str(config.path)
    problems: list[str] = []
    for sc in config.sources:
        try:
            open_source(sc.name, sc.url, timeout_s=sc.timeout_s)  # validates; opens nothing until start()
        except SourceError as exc:
            problems.append(
                f"{where}: sources.{sc.name}.url: {exc.problem}" + (f" ({exc.fix})" if exc.fix else "")
            )
    try:
        zenoh_config(config.zenoh)
    except BusError as exc:
        problems.append(f"{where}: zenoh: {exc}")
    return problems
