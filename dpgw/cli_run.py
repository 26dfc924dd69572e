"""``dpgw run``: the live gateway from a TOML config (the onboard service).

Only the parser is built at import: the gateway (numpy, numba, Zenoh, pydantic) is imported by `run`, so
``dpgw run --help`` answers at once.
"""

from __future__ import annotations

import argparse
import re
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

from dpgw import cli_json
from dpgw.cli_foxglove import FROM_CONFIG, add_foxglove_arg, connect_lines
from dpgw.cli_paths import mcap_path_problem, writable
from dpgw.cli_types import positive_float
from dpgw.sd_notify import Notifier

if TYPE_CHECKING:
    from gateway.config import GatewayConfig
    from gateway.service import GatewayService
    from gateway.sources import SourceError

# With -v, one status line this often (wall seconds).
STATUS_EVERY_S = 5.0


NAME = "run"
HELP = "run the gateway: sensor streams in, observer, Zenoh and MCAP out"
DESCRIPTION = (
    "Run the live gateway described by a TOML config: read the DGPS/gyro NMEA and MAVLink thruster "
    "links, estimate the low-frequency motion with the wave-filtering observer, publish estimate, "
    "measurement and status on Zenoh (<prefix>/...) and log everything to MCAP. SIGINT (Ctrl-C), "
    "SIGTERM and SIGHUP (the terminal or SSH session closing) stop it, also during start-up: the log is "
    "flushed and closed complete. A config mistake or a missing serial port stops start-up with one "
    "message naming what and where."
)
EPILOG = (
    "examples:\n"
    "  dpgw run --config /etc/dpgw/vessel.toml\n"
    "  dpgw run --config /etc/dpgw/vessel.toml --wait-for-ports   # as the systemd unit runs it\n"
    "  dpgw run --config examples/nmea_udp_multiplexer.toml --log /tmp/trial.mcap\n"
    "  dpgw run --config vessel.toml --check        # validate the config and exit\n"
    "  dpgw run --config vessel.toml --foxglove     # and serve it to Foxglove at ws://127.0.0.1:8765\n"
    "see examples/ for configs and a systemd unit; docs/config.md for every key"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", required=True, metavar="FILE", help="gateway config (TOML)")
    p.add_argument("--log", metavar="FILE.mcap", help="override [log] path")
    p.add_argument(
        "--duration", type=positive_float, metavar="S", help="stop after S seconds (tests, trials)"
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="check the config and exit: a summary (status 0) or every problem (status 2); opens nothing",
    )
    p.add_argument(
        "--wait-for-ports",
        action="store_true",
        help="a serial port that does not exist at start-up is waited for (an alarm in /status, opened when "
        "it appears) instead of stopping start-up; the other sources run meanwhile. For a service (the "
        "systemd unit in examples/ uses it): a USB adapter late at boot or unplugged then does not stop "
        "the gateway, nor make systemd give up on it after its restarts",
    )
    p.add_argument(
        "--clock",
        choices=("wall", "sim"),
        help="what received data is stamped with: this computer's clock (wall), or the simulation time a "
        "simulator publishes on <prefix>/sim/clock (sim: a HIL bench, e.g. with 'dpgw sim --zenoh "
        "--realtime'); overrides [time] clock (default wall)",
    )
    add_foxglove_arg(
        p,
        what="every output (overrides [foxglove]; without a value: the config's host and port, or "
        "127.0.0.1:8765)",
        bare=FROM_CONFIG,
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print the exit summary as JSON; with --check, the check as JSON on stdout: {config, ok, "
        "problems, summary, notes}",
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help=f"log what the gateway does, and print a one-line status every {STATUS_EVERY_S:g} s (stderr)",
    )
    p.set_defaults(func=run)


class StopSignals:
    """SIGINT, SIGTERM and SIGHUP stop ``dpgw run`` cleanly, from the moment `run` starts.

    Installed before the config is read and the kernels compile (seconds on a first run): a signal during
    start-up used to meet Python's defaults, so Ctrl-C printed a KeyboardInterrupt traceback and SIGTERM
    (``systemctl stop`` or ``restart`` of a unit still starting) killed the process with its MCAP log
    opened but without its summary. SIGHUP (the terminal or SSH session it runs in closing) killed it at
    any time, the log likewise cut. Now each only sets `requested` (and the service's ``stop_event``, once
    there is a service): start-up finishes what it is doing, opens nothing more, and the gateway closes
    as after any stop. SIGHUP comes here through `dpgw.cli.hangup_as_terminate`, which hands it to the
    SIGTERM handler (with SIGHUP's number) unless ``nohup`` ignores it."""

    def __init__(self) -> None:
        import signal

        self.requested = threading.Event()
        self.signum: int | None = None
        self._service: GatewayService | None = None
        self._before = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM)}

    def restore(self) -> None:
        """The handlers as they were before: `run` returns to its caller (a test, a program calling
        `dpgw.cli.main`) with Ctrl-C its caller's again. Left installed, a Ctrl-C after ``dpgw run
        --check`` in the same process only set this object's flag, and a replay run next never stopped."""
        import signal

        for signum, handler in self._before.items():
            signal.signal(signum, handler)

    def _on_signal(self, signum: int, _frame: object) -> None:
        from dpgw.cli_stops import set_from_handler

        self.signum = self.signum or signum
        service = self._service
        set_from_handler(self.requested, *([service.stop_event] if service is not None else []))

    def attach(self, service: GatewayService) -> None:
        """From now on a signal also stops ``service`` (and one already received does at once)."""
        self._service = service
        if self.signum is not None:  # (set in the handler itself; `requested` a moment later)
            service.stop_event.set()

    @property
    def name(self) -> str:
        import signal

        return signal.Signals(self.signum).name if self.signum is not None else "a signal"


def run(args: argparse.Namespace) -> int:
    stop = StopSignals()  # first: a signal during the imports and start-up below stops cleanly too
    try:
        return _run(args, stop)
    finally:
        stop.restore()


def _run(args: argparse.Namespace, stop: StopSignals) -> int:
    import logging
    import tomllib
    from dataclasses import replace

    from dpgw.journal import configure_logging, start_up_error
    from gateway.bus import BusError
    from gateway.config import (
        ConfigError,
        FoxgloveConfig,
        TimeConfig,
        describe,
        enabled_lines,
        format_problems,
        load_config,
    )
    from gateway.outputs.build import OutputError, sinks_from_config
    from gateway.service import GatewayService, LogPathError
    from gateway.sources import SourceError

    configure_logging(logging.INFO if args.verbose else logging.WARNING)
    try:
        config = load_config(args.config)
    except ConfigError as exc:
        if args.check and args.json:
            return _check_json(args.config, exc.problems)
        start_up_error(format_problems(exc, started=not args.check))
        return 2
    if args.clock is not None:
        config = replace(config, time=TimeConfig(clock=args.clock))
    if args.foxglove is not None:
        fc = config.foxglove
        host, port = (fc.host, fc.port) if args.foxglove is FROM_CONFIG else args.foxglove
        config = replace(config, foxglove=FoxgloveConfig(enabled=True, host=host, port=port))
    if args.check:
        problems = start_up_problems(config, where=args.config)
        if args.json:
            return _check_json(args.config, problems, describe(config), start_up_notes(config))
        if problems:
            start_up_error(format_problems(problems, started=False))
            return 2
        print(describe(config))
        for note in start_up_notes(config):
            print(f"note: {note}")
        return 0
    if problem := mcap_path_problem("--log", args.log, made=True):
        start_up_error(f"dpgw run: {problem}")
        return 2
    with open(args.config, "rb") as f:
        tables = tomllib.load(f)
    if args.clock is not None:  # the log's copy of the config says what ran
        tables["time"] = {**tables.get("time", {}), "clock": args.clock}
    try:
        sinks = sinks_from_config(config)
    except OutputError as exc:  # said as `--check` says it: the same problems, the same heading
        start_up_error(format_problems(exc.problems))
        return 2
    if stop.signum is not None:  # before anything opens: nothing to close
        print(f"dpgw run: stopped by {stop.name} during start-up; nothing was opened", file=sys.stderr)
        return 0
    service = GatewayService(
        config, log_path=args.log, config_tables=tables, sinks=sinks, wait_for_ports=args.wait_for_ports
    )
    stop.attach(service)
    try:
        service.start()
    except BusError as exc:
        start_up_error(f"dpgw run: {config.path}: {exc}")
        return 2
    except LogPathError as exc:
        where = "--log" if args.log else f"{config.path}: log.path"
        start_up_error(f"dpgw run: {where}: {exc.problem}")
        return 2
    except SourceError as exc:  # the file and key to edit, as for a mistake in the config itself
        start_up_error(source_errors_message(config, exc))
        return 2
    except OSError as exc:
        start_up_error(f"dpgw run: {exc}")
        return 2
    if not service.opened:  # stopped while the kernels compiled: nothing was opened
        service.close()
        print(f"dpgw run: stopped by {stop.name} during start-up; nothing was opened", file=sys.stderr)
        return 0
    line = start_up_line(config, service, args.log)
    print(line, file=sys.stderr, flush=True)
    for extra in enabled_lines(config, foxglove=False):  # (the Foxglove server says its address below)
        print(f"dpgw run: {extra}", file=sys.stderr, flush=True)
    notifier = Notifier()  # systemd (Type=notify, WatchdogSec): ready now, the loop feeds the watchdog
    if notifier.enabled:
        t0 = time.monotonic()
        service.heartbeat = lambda: notifier.heartbeat(
            lambda: status_line(service.last_status(), time.monotonic() - t0)
        )
        notifier.ready(line)
    for sink in sinks:
        if sink.name == "foxglove":
            for line in connect_lines(sink.url, sink.app_url()):  # type: ignore[attr-defined]
                print(f"dpgw run: {line}", file=sys.stderr, flush=True)
    if stop.signum is not None:
        print(f"dpgw run: stopped by {stop.name} during start-up", file=sys.stderr, flush=True)
    reporter = None
    if args.verbose:
        reporter = threading.Thread(target=report_status, args=(service,), name="dpgw-status", daemon=True)
        reporter.start()
    try:
        service.run(args.duration)
        notifier.stopping()
        service.drain()  # bounded: gateway.service.DRAIN_S, the rest logged as received
    finally:
        service.stop_event.set()  # also ends the status reporter
        status = service.final_status().payload
        log_files = [str(p) for p in service.log.paths] if service.log is not None else []
        # (over the whole run: a status says it only while writing fails, the alarm clears when it works)
        not_logged = service.log.lost if service.log is not None else 0
        failures = service.log.failures if service.log is not None else 0
        service.close()
        notifier.close()
    why = stop_reason(stop.signum, args.duration)
    summary = {
        "estimates": service.pipeline.estimates,
        "published": service.published,
        "stopped_by": stop.name if stop.signum is not None else None,  # as `dpgw demo --json` has it
        "status": status,
        "log_files": log_files,
        "log_not_logged": not_logged,
    }
    if args.json:
        print(cli_json.dumps(summary, indent=2))
    else:
        from wire.json_payload import to_jsonable

        plain = to_jsonable(status)  # (the message as /dp/status carries it)
        print(f"dpgw run: stopped: {why}; {service.pipeline.estimates} estimates, {service.published} "
              "messages published")  # fmt: skip
        if log_files:
            print(f"dpgw run: log: {', '.join(log_files)}")
        if not_logged or failures:
            print(
                f"dpgw run: log: {not_logged} messages were not logged: writing failed {failures} "
                f"time{'s' if failures != 1 else ''} during the run (the gateway's log says when and why)"
            )
        for name, source in plain.get("sources", {}).items():
            if source.get("reconnects"):
                print(f"dpgw run: source {name}: {reconnects_text(source, time.time_ns())}")
        for line in alarm_lines(plain.get("alarms") or [], service.pipeline.estimates):
            print(f"dpgw run: {line}")
    return 0


ALARMS_SHOWN = 8
"""At most this many alarms in the text summary of a stop, one line each; ``--json`` has them all."""


def stop_reason(signum: int | None, duration_s: float | None) -> str:
    """Why ``dpgw run`` stopped, for its summary: the signal it was sent (Ctrl-C is SIGINT), else the end of
    ``--duration``, else the gateway ending by itself."""
    import signal

    if signum is not None:
        return {
            signal.SIGINT: "Ctrl-C (SIGINT)",
            signal.SIGTERM: "SIGTERM (systemctl stop, kill)",
            getattr(signal, "SIGHUP", -1): "SIGHUP (the terminal or SSH session closed)",
        }.get(signum, signal.Signals(signum).name)
    if duration_s is not None:
        return f"--duration {duration_s:g} s reached"
    return "the gateway ended"


def alarm_lines(alarms: list[str], estimates: int) -> list[str]:
    """The alarms up at the stop, one line each (``alarm: source ardupilot: no data yet``), at most
    `ALARMS_SHOWN` and a line saying how many more; none when the run made estimates and no alarm was up.
    A run that made no estimate says so even without an alarm: the alarms are why, and were only in
    ``--json`` (and /status), so a trial that received nothing ended on a summary that looked fine."""
    lines = [f"alarm: {a}" for a in alarms[:ALARMS_SHOWN]]
    if len(alarms) > ALARMS_SHOWN:
        lines.append(f"... and {len(alarms) - ALARMS_SHOWN} more alarms (all of them: --json)")
    if not estimates and not alarms:
        lines.append("no estimate and no alarm: check that the sources' data reach this computer (-v)")
    return lines


# A URL that asks for any free port: ``:0`` at the end of its address (``udp://127.0.0.1:0``,
# ``udpin:0.0.0.0:0?...``), not the ``:0`` of ``udpin:0.0.0.0:555`` or of an IPv6 address.
ASKS_ANY_PORT = re.compile(r":0(?![0-9.:\]])")
# A Zenoh endpoint on any free port: ``tcp/127.0.0.1:0`` (before its ``?metadata`` or ``#config``).
ZENOH_ANY_PORT = re.compile(r":0(?:$|[?#])")


def start_up_line(config: GatewayConfig, service: GatewayService, log_override: str | None) -> str:
    """What the gateway opened: each source (with the port it bound, when it chose one), Zenoh, the log."""
    sources = []
    for src in service._sources:
        port = getattr(src, "port", None)
        bound = f", port {port}" if isinstance(port, int) and ASKS_ANY_PORT.search(src.url) else ""
        sources.append(f"{src.name} {src.url}{bound}")
    z = config.zenoh
    zenoh = f"zenoh {z.mode} prefix {z.prefix}"
    if z.config_file:
        zenoh += f" config {z.config_file}"
    zenoh += f", listen {' '.join(z.listen) if z.listen else '(Zenoh default)'}"
    if any(ZENOH_ANY_PORT.search(e) for e in z.listen):
        # Zenoh does not say which port it bound (only its admin space does, which dpgw leaves off: it
        # would tell any peer this session's locators and links), so say what port 0 means instead
        zenoh += (
            " (port 0: a free port, which Zenoh does not report; peers on this computer find it by "
            "scouting"
            + ("" if z.multicast_scouting else ", which is off: nobody can connect to it")
            + "; give a port, e.g. tcp/127.0.0.1:7447, to connect to it by address)"
        )
    zenoh += f", connect {' '.join(z.connect)}" if z.connect else ""
    zenoh += "" if z.multicast_scouting else ", scouting off"
    log_path = log_override or (str(config.log.path) if config.log.path else None)
    if service.log is not None:  # the file it writes: a restarted gateway continues the set
        log_path = str(service.log.path)
        if service.log.error is not None:
            log_path += f" (NOT WRITTEN: {service.log.error}; retrying every {service.log.retry_s:g} s)"
    clock = f"; clock: simulation time from {z.prefix}/sim/clock" if config.time.sim else ""
    return (
        f"dpgw run: vessel {config.vessel.name}; sources {', '.join(sources) or 'none'}; {zenoh}; "
        f"log {log_path or 'off'}{clock}"
    )


def report_status(service: GatewayService, every_s: float = STATUS_EVERY_S) -> None:
    """Every ``every_s`` until the service stops: one line from the status the gateway last published."""
    t0 = time.monotonic()
    while not service.stop_event.wait(every_s):
        print(status_line(service.last_status(), time.monotonic() - t0), file=sys.stderr, flush=True)


# Reasons in a source's ``rejected`` that are no fault of the link: well-formed sentences of types dpgw
# does not use (GSV, GSA, proprietary $P...: `wire.codecs.nmea.UNSUPPORTED`), AIS
# (`wire.codecs.nmea_framing.AIS`), `#` comment lines (`wire.codecs.nmea_framing.COMMENT`), an IEC
# 61162-450 network's framing (TAG blocks, datagram headers) and, on a source with a ``tag_source``, the
# sentences of the other devices sharing its multicast group (`wire.codecs.nmea_tag.OTHER_TAG_SOURCE`).
NOT_USED = ("unsupported", "ais", "comment", "tag_block", "iec_61162_450", "other_tag_source")


def reconnects_text(source: dict[str, Any], now_ns: int) -> str:
    """``2 reconnects, last lost 12 s ago: connection to 10.0.0.5:4001 lost: closed by the server``: a
    source's reconnects (`SourceStatus`) and its last disconnect, how long before ``now_ns``: the wall
    clock, as the disconnect's time is (not the status's stamp, which is the simulation's time under
    ``--clock sim``)."""
    n = source.get("reconnects", 0)
    text = f"{n} reconnect{'s' * (n != 1)}"
    why, when = source.get("last_disconnect"), source.get("last_disconnect_ns")
    if why:
        ago = f" {max(0.0, (now_ns - when) / 1e9):.0f} s ago" if when else ""
        text += f", last lost{ago}: {why}"
    return text


def status_line(status: dict[str, Any], elapsed_s: float) -> str:
    """``dpgw run: 35 s, dp, 340 estimates; dgps1 35 rx 0.1 s ago (2 rejected, 40 not used), gyro1 ...;
    alarms: ...``. Sentences dpgw does not use (`NOT_USED`) are counted apart from the rejected: a receiver
    sending GSV and GSA four times a second showed hundreds "rejected" in a healthy stream. A link that
    was lost and came back says how often, and why it was last lost (`reconnects_text`)."""
    if not status:
        return f"dpgw run: {elapsed_s:.0f} s, no status yet"
    parts = []
    for name, c in status.get("sources", {}).items():
        age = c.get("age_s")
        reasons = c.get("rejected", {})
        not_used = sum(n for r, n in reasons.items() if r in NOT_USED)
        rejected = sum(reasons.values()) - not_used
        counts = [f"{rejected} rejected"] * bool(rejected) + [f"{not_used} not used"] * bool(not_used)
        counts += [f"{c['lost_lines']} lost on the network"] if c.get("lost_lines") else []
        counts += [reconnects_text(c, time.time_ns())] if c.get("reconnects") else []
        parts.append(
            f"{name} {c.get('received', 0)} rx"
            + (f" {age:.1f} s ago" if age is not None else " none yet")
            + (f" ({', '.join(counts)})" if counts else "")
        )
    alarms = status.get("alarms") or []
    return (
        f"dpgw run: {elapsed_s:.0f} s, {status.get('mode', '?')}, {status.get('estimates', 0)} estimates; "
        + ", ".join(parts)
        + (f"; alarms: {'; '.join(alarms)}" if alarms else "")
    )


def _check_json(path: str, problems: list[str], summary: str = "", notes: list[str] | None = None) -> int:
    """``--check --json``: the check for a program (CI over a fleet's configs), status 0 or 2 as without."""
    out = {
        "config": str(path),
        "ok": not problems,
        "problems": problems,
        "summary": summary.splitlines() if not problems else [],
        "notes": (notes or []) if not problems else [],
    }
    print(cli_json.dumps(out, indent=2))
    return 2 if problems else 0


def start_up_notes(config: GatewayConfig) -> list[str]:
    """What start-up would not refuse but an engineer should know: a UDP source listening on an address
    that is not this computer's now (start-up waits for it, as for an interface still coming up at boot;
    a typing mistake looks the same); a serial port that is not there now (start-up would stop on it,
    but it may come: a USB adapter plugged in, the simulator's pty link made when it starts; ``--check``
    said ``ok`` and the gateway then refused to start); the config's own notes
    (`gateway.config.config_notes`)."""
    import os

    from gateway.config import config_notes
    from gateway.config.summary import open_commands_note
    from gateway.sources import FileSource, SerialSource, SourceError, open_source
    from gateway.sources.udp import UdpSource

    notes: list[str] = config_notes(config)
    if (note := open_commands_note(config)) and note not in notes:  # (also one reached from here only)
        notes.append(note)
    if config.log.path and (note := log_folder_note(str(config.log.path))):
        notes.append(note)
    for sc in config.sources:
        try:
            source = open_source(sc.name, sc.url, timeout_s=sc.timeout_s)
        except SourceError:
            continue  # (a problem start_up_problems reports)
        if isinstance(source, UdpSource) and (note := source.listen_address_note()):
            notes.append(f"sources.{sc.name}.url: {note}")
        if isinstance(source, SerialSource) and not os.path.exists(source.device):
            notes.append(
                f"sources.{sc.name}.url: serial port {source.device} does not exist now: start-up stops on "
                "it unless it is there by then, or waits for it with --wait-for-ports (the service unit) "
                "(check the cable/udev name: ls /dev/serial/by-id/; a simulator's pty link is made when "
                "the simulator starts)"
            )
        if isinstance(source, FileSource) and not os.path.isfile(source.path):
            what = "is a folder" if os.path.isdir(source.path) else "does not exist now"
            notes.append(
                f"sources.{sc.name}.url: file {source.path} {what}: start-up stops on it unless the file is "
                "there by then (check the path; a relative one is from the config's folder)"
            )
    return notes


def log_folder_note(path: str) -> str | None:
    """``log.path`` whose folder this user cannot write in, or make, now (or whose folder's parent is
    missing too: `wire.mcap.folder`): start-up would stop on it. A
    note, not a problem: the folder may be made by then (systemd's ``LogsDirectory`` makes /var/log/dpgw
    for the service's user when the service starts), but ``sudo -u dpgw dpgw run --check``, run to find
    what the service's user cannot do, said ``ok`` and the service then stopped on it."""
    import os

    from dpgw.cli_paths import cannot_create_in, user_name
    from wire.mcap.folder import log_folder_blocked, log_folder_problem

    folder = os.path.dirname(os.path.abspath(path))
    if log_folder_blocked(path):
        return None  # (a problem: `start_up_problems`)
    if problem := log_folder_problem(path):  # (only the log's own folder is made)
        return f"log.path: {problem}: start-up stops on it unless that changes by then"
    if writable(folder):
        if os.path.isdir(folder) and (why := cannot_create_in(folder)):
            return f"log.path: no file can be made in {folder} ({why}): start-up stops on it"
        return None
    what = "is not writable" if os.path.isdir(folder) else "does not exist and cannot be made"
    return (
        f"log.path: the folder {folder} {what} for this user ({user_name()}) now: start-up stops on it "
        "unless that changes by then (a service: give a path in its LogsDirectory, /var/log/dpgw, which "
        "systemd makes for the service's user when it starts)"
    )


def start_up_problems(config: GatewayConfig, where: str | None = None) -> list[str]:
    """What start-up would refuse beyond the config's own checks, found without opening anything: each
    source URL as the gateway's sources read it, and the Zenoh session's config. Each is prefixed with
    ``where``, the config as the user named it (as the config's own problems are: `load_config`), or its
    absolute path."""
    from gateway.bus import BusError
    from gateway.outputs.build import output_problems
    from gateway.service import zenoh_config
    from gateway.sources import SourceError, open_source
    from wire.mcap.folder import log_folder_blocked

    where = where or str(config.path)
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
        problems.append(f"{where}: {exc}")
    if config.log.path and (blocked := log_folder_blocked(str(config.log.path))):
        problems.append(
            f"{where}: log.path: cannot make the log's folder: {blocked} is a file, not a folder (a file is "
            "in the way): choose a folder the gateway may write to (a service: its LogsDirectory, "
            "/var/log/dpgw)"
        )
    return problems + output_problems(config, where)


def source_errors_message(config: GatewayConfig, exc: SourceError) -> str:
    """The start-up stop for sources that cannot open, each with the key to edit: one line for one; for
    several (`SeveralSourcesError`: the service tries every source first), a heading and a line each, so
    that the engineer who plugs in one serial port and frees another's UDP port does not meet them one per
    try."""
    from gateway.sources import SeveralSourcesError

    def said(e: SourceError) -> str:
        return f"sources.{e.name}.url: {e.problem} ({e.url})"

    if not isinstance(exc, SeveralSourcesError):
        return f"dpgw run: {config.path}: {said(exc)}" + (f" — {exc.fix}" if exc.fix else "")
    errors = exc.errors
    missing = [e for e in errors if e.missing_port]
    if len(missing) == len(errors):
        heading = f"{len(errors)} serial ports do not exist"
    else:
        heading = f"{len(errors)} sources cannot open"
    lines = [f"dpgw run: {config.path}: {heading}:"]
    for e in errors:
        lines.append(f"  {said(e)}" + (f" — {e.fix}" if e.fix and e not in missing else ""))
    if missing:
        lines.append(
            "serial ports: check the cables/udev names (ls /dev/serial/by-id/; for the simulator: the pty it "
            "printed), or start with --wait-for-ports to run without them until they appear"
        )
    return "\n".join(lines)
