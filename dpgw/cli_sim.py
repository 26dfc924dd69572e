"""``dpgw sim``: the simulator as a sensor source on pty/UDP/TCP/serial, or to an MCAP file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from dpgw import cli_json, cli_sim_inputs
from dpgw.cli_paths import made_folder_problem, make_folder_for, mcap_path_problem
from dpgw.cli_progress import terminal_bar
from dpgw.cli_types import flags_given, positive_float, seed_int
from dpgw.cli_zenoh import ZENOH_FLAGS, add_endpoint_args, listen_endpoints
from dpgw.scenario_names import SCENARIO_NAMES

if TYPE_CHECKING:
    from simulator.faults import Fault

# Only the parser is built at import; the simulator (numpy, scipy, the MAVLink dialect) and Zenoh are
# imported by `run`, so `dpgw sim --help` answers at once.


RESYNC_LAG_S = 1.0
"""With --realtime: a lag behind the schedule beyond this (wall s) is not caught up (the clock re-anchors)."""

NAME = "sim"
HELP = "simulate a vessel at sea that speaks NMEA and MAVLink on real transports"
DESCRIPTION = (
    "Run a named scenario: a vessel at sea (LF dynamics, JONSWAP/PM waves through RAOs, slowly "
    "varying environment, thrusters) whose DGPS and gyro speak NMEA 0183 and whose thrusters report "
    "over MAVLink, on a pty (a virtual serial port), UDP, a TCP server, a serial port or a file. "
    "Ground truth and every byte sent go to MCAP; the MAVLink can also go to a tlog, timed as a ground "
    "station records it. Thruster commands may come back (dpgw dialect "
    "AZIMUTH_THRUSTER_COMMAND on the MAVLink link, or Zenoh <prefix>/thrusters/command) and close "
    "the loop."
)
EPILOG = (
    "examples:\n"
    "  dpgw sim --scenario torsetnes_2004 --duration 600 --out sim.mcap\n"
    "  dpgw sim --scenario torsetnes_2004 --nmea pty --realtime          # prints the device path\n"
    "  dpgw sim --scenario hassani --nmea dgps1=udp://127.0.0.1:10110 --nmea gyro1=pty --realtime\n"
    "  dpgw sim --scenario hajivand_2010 --mavlink tcp-listen://127.0.0.1:5760 --zenoh --realtime\n"
    "  dpgw sim --scenario hassani --nmea file:///tmp/trial.nmea --tlog trial.tlog\n"
    "  dpgw replay /tmp/trial.nmea trial.tlog --vessel cybership2   # a sea trial's logs, rehearsed\n"
    "  dpgw sim --vessel mss_osv --inputs trial.csv --csv states.csv --out trial.mcap   # open loop\n"
    f"scenarios: {', '.join(SCENARIO_NAMES)} (docs/simulator.md)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scenario", choices=SCENARIO_NAMES, metavar="NAME", help="scenario (the names are listed below)"
    )
    p.add_argument(
        "--duration", type=positive_float, metavar="S", help="sim seconds (default: the scenario's)"
    )
    p.add_argument("--seed", type=seed_int, default=0, help="random seed: same seed, same bytes (default 0)")
    p.add_argument(
        "--out",
        metavar="LOG.mcap",
        help="write ground truth and every frame sent to this MCAP (one that exists is kept: the run goes "
        "on in LOG_0001.mcap, the next free file of its set)",
    )
    p.add_argument(
        "--nmea",
        action="append",
        default=[],
        metavar="[SOURCE=]URL|pty",
        help="where NMEA goes (repeatable): pty, pty:///path/link, udp://H:P, tcp-listen://H:P (a server), "
        "serial:///dev/ttyX?baud=N, file:///path; a multicast group as a device of an IEC 61162-450 "
        "network: udp://239.192.0.4:60004?iface=lo&tag_source=GP0001. SOURCE= sends one sensor only "
        "(dgps1, gyro1; wind1, the "
        "anemometer, where the scenario has wind; mru1, the motion reference unit, where it has one: "
        "torsetnes_2004_mast)",
    )
    p.add_argument(
        "--mavlink",
        metavar="URL",
        help="where thruster MAVLink goes (and commands come back from); file:///PATH writes the frames "
        "alone, without times (not a tlog: see --tlog)",
    )
    p.add_argument(
        "--tlog",
        metavar="FILE.tlog",
        help="also record the thruster MAVLink as a tlog (as MAVProxy, Mission Planner and QGroundControl "
        "write: each frame after its 8-byte time), timed in the simulation's UTC like the NMEA sentences, "
        "so 'dpgw replay' merges it with an --nmea file:// text log; with or without --mavlink. One that "
        "exists is kept: the tlog goes in the next file of its set (FILE_0001.tlog), named on the console",
    )
    p.add_argument(
        "--signing-key-file",
        metavar="FILE",
        help="MAVLink 2 signing for the simulated thruster drives: FILE holds the key as the gateway "
        "config's signing_key (64 hexadecimal characters; keep it chmod 600). The drives then sign every "
        "frame they send and take only thruster commands signed with this key; unsigned or badly signed "
        "ones are counted (commands_rejected in the summary) and the first of each kind is logged. Not "
        "the key itself on the command line: other users see a command line in ps (docs/simulator.md)",
    )
    p.add_argument(
        "--held",
        action="store_true",
        help="the vessel held on its station by joystick until the first thruster command, as a crew holds "
        'it while a gateway started in DP ([control] initial_mode = "dp") waits for its observer to settle '
        "(145 s on torsetnes_2004): the thrusters deliver minus the slowly varying load from the start and "
        "answer the drift off station slowly, as dpgw demo holds it. Without it the scenario's own thrust "
        "(the known mean load only) leaves the vessel to drift (docs/gateway.md, 'Waiting for the observer')",
    )
    p.add_argument("--realtime", action="store_true", help="pace in real time (default: as fast as possible)")
    p.add_argument(
        "--speed",
        type=positive_float,
        default=1.0,
        metavar="X",
        help="with --realtime: sim seconds per wall second (default 1)",
    )
    p.add_argument(
        "--gnss-rate", type=float, metavar="HZ", help="DGPS rate 1-10 Hz (default: the scenario's)"
    )
    p.add_argument(
        "--gyro-rate", type=float, metavar="HZ", help="gyro rate up to 20 Hz (default: the scenario's)"
    )
    p.add_argument(
        "--faults",
        metavar="FILE.toml",
        help="schedule faults from a TOML file of [[faults]] tables (dropout, frozen, jump, noise_burst, "
        "bad_checksum, garbage, thruster_failure, drift, spoof, quality, bogus_feedback; see "
        "docs/sensors.md)",
    )
    p.add_argument(
        "--ardupilot",
        action="store_true",
        help="thrusters also report ArduPilot-style ESC_TELEMETRY (ESC n = n-th thruster, |rpm|) and "
        "SERVO_OUTPUT_RAW (outputs 1-16: azimuths; 17-32: reversible motor outputs, below 1500 µs astern: "
        "map them with esc_direction_servo = {n = 16 + n}; docs/sensors.md)",
    )
    p.add_argument(
        "--on-command-loss",
        choices=("hold", "stop"),
        help="what the drives do once their commands have stopped for 2 s: hold the last command (the "
        "default, as most DP drives do) or stop (zero thrust: a drive's fieldbus watchdog, an ArduPilot "
        "failsafe), to rehearse a gateway that goes silent",
    )
    p.add_argument(
        "--zenoh",
        action="store_true",
        help="a Zenoh session: with --realtime, publish the simulation time on <prefix>/sim/clock (for "
        "'dpgw run --clock sim'); without --mavlink, take thruster commands from Zenoh "
        "<prefix>/thrusters/command (with --mavlink the drives take them from their MAVLink link only: "
        "see --zenoh-commands)",
    )
    p.add_argument(
        "--zenoh-commands",
        action="store_true",
        help="with --mavlink: take thruster commands from Zenoh <prefix>/thrusters/command as well (a "
        "gateway that reads MAVLink feedback but commands over Zenoh). Off by default: the gateway "
        "publishes its commands there for consoles, and taking them would close the loop even when its "
        "MAVLink commands go nowhere or fail their signature",
    )
    p.add_argument("--prefix", help="Zenoh key prefix (default dp/<vessel>)")
    add_endpoint_args(p)
    p.add_argument(
        "--no-scouting",
        action="store_true",
        help="Zenoh multicast scouting off (off anyway when --zenoh-listen or --zenoh-connect names the "
        "endpoints: a simulator that scouts connects to every Zenoh peer it finds, other benches' gateways "
        "among them, and brings them its clock)",
    )
    p.add_argument("--zenoh-config", metavar="FILE", help="a Zenoh JSON5 config file (overrides the above)")
    p.add_argument("--json", action="store_true", help="print the run summary as JSON")
    cli_sim_inputs.add_arguments(p)
    p.set_defaults(func=run)


def load_faults(path: str) -> tuple[Fault, ...]:
    """The [[faults]] tables of a TOML file; errors name the file, the table and the field."""
    import tomllib

    from simulator.faults import FaultSchedule

    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the fault table ({exc.strerror})") from None
    # A misspelt table ([[fault]]) or a file of something else must not run a clean sea in its place.
    unknown = sorted(set(data) - {"faults"})
    if unknown:
        raise ValueError(
            f"{path}: unknown key '{unknown[0]}' (a fault file holds [[faults]] tables only; docs/sensors.md)"
        )
    if not data.get("faults"):
        raise ValueError(f"{path}: no [[faults]] table (docs/sensors.md)")
    try:
        return FaultSchedule.from_dicts(data["faults"]).faults
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _parse_route(spec: str, protocol: str) -> tuple[str, frozenset[str] | None]:
    if "=" in spec.split("://", 1)[0]:
        source, url = spec.split("=", 1)
        return url, frozenset({source})
    return spec, None


def run(args: argparse.Namespace) -> int:
    if (args.scenario is None) == (args.inputs is None):
        # (said as what was given: "(not both)" to one who gave neither read as a mistake not made)
        if args.scenario is not None:
            tail = ", not both"
        else:
            tail = " (open loop from recorded inputs)" + (
                ": --vessel goes with --inputs" if args.vessel else ""
            )
        print(f"dpgw sim: give --scenario NAME, or --vessel NAME --inputs INPUTS.csv{tail}", file=sys.stderr)
        return 2
    if args.inputs is not None:
        # A scenario's options do nothing open loop: refused rather than silently ignored.
        given = flags_given(
            ("--duration", args.duration),  # the inputs' times set the length
            ("--nmea", args.nmea),
            ("--mavlink", args.mavlink),
            ("--tlog", args.tlog),
            ("--realtime", args.realtime),
            ("--held", args.held),
            ("--speed", args.speed != 1.0),
            ("--gnss-rate", args.gnss_rate),
            ("--gyro-rate", args.gyro_rate),
            ("--faults", args.faults),
            ("--ardupilot", args.ardupilot),
            ("--on-command-loss", args.on_command_loss),
            ("--signing-key-file", args.signing_key_file),
            ("--zenoh", args.zenoh),
            *_session_options(args),
        )
        if given:
            print(
                f"dpgw sim: {', '.join(given)}: only with --scenario; open loop from --inputs takes "
                "--vessel, --csv, --out, --initial, --plant-option, --wind, --sea, --seed and --json",
                file=sys.stderr,
            )
            return 2
        return cli_sim_inputs.run(args)
    if args.vessel or args.csv or args.plant_option or args.wind or args.sea:
        print("dpgw sim: --vessel, --csv, --plant-option, --wind and --sea go with --inputs", file=sys.stderr)
        return 2
    if problem := mcap_path_problem("--out", args.out, made=True) or tlog_path_problem(args):
        print(f"dpgw sim: {problem}", file=sys.stderr)
        return 2
    if args.speed != 1.0 and not args.realtime:  # accepted and ignored before: the run went flat out
        print("dpgw sim: --speed X paces a --realtime run: add --realtime", file=sys.stderr)
        return 2
    if args.prefix is not None:
        from gateway.config.load import prefix_problem

        if problem := prefix_problem(args.prefix):
            print(f"dpgw sim: --prefix: {problem}", file=sys.stderr)
            return 2
    zenoh_only = flags_given(*_session_options(args))
    if zenoh_only and not args.zenoh:  # accepted and ignored before: no session was opened
        print(f"dpgw sim: {', '.join(zenoh_only)}: only with --zenoh", file=sys.stderr)
        return 2
    from dpgw.cli_stops import signals_noted

    # SIGINT and SIGTERM noted from before the sinks and the log open: a stop during start-up (Ctrl-C,
    # SIGTERM, or SIGHUP through `dpgw.cli.hangup_as_terminate`) then runs no sea and closes the log
    # complete, instead of meeting Python's defaults (a traceback, or a process killed with its log cut)
    with signals_noted() as stopped_by:
        return _run_scenario(args, stopped_by)


def tlog_path_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with --tlog PATH as a file to write (None when nothing)."""
    if args.tlog is None:
        return None
    path = Path(args.tlog)
    if path.is_dir():
        return f"--tlog {args.tlog}: a folder, not a file: give a file in it, e.g. {path / 'trial.tlog'}"
    if path.suffix == ".mcap" or (args.out and path.resolve() == Path(args.out).resolve()):
        return f"--tlog {args.tlog}: a tlog is not an MCAP log: give another name, e.g. {path.stem}.tlog"
    outputs = [("--nmea", _parse_route(spec, "nmea")[0]) for spec in args.nmea]
    for option, url in outputs + ([("--mavlink", args.mavlink)] if args.mavlink else []):
        written = _file_of(url)
        if written is not None and written.resolve() == path.resolve():
            return (
                f"--tlog {args.tlog}: {option} {url} writes to the same file: two writers would interleave "
                f"their bytes in it; give the tlog another name, e.g. {path.stem}-mavlink.tlog"
            )
    return made_folder_problem("--tlog", args.tlog)  # (its own folder is made when it opens)


def _file_of(url: str) -> Path | None:
    """The file a sink URL writes (``file:///PATH`` or a plain path, as `open_sink` reads it), else None
    (another transport, or a URL that does not parse: `open_sink` says why when it opens it)."""
    from wire.urls import SINK_OPTIONS, UrlError, parse_url

    try:
        ep = parse_url(url.strip(), options=SINK_OPTIONS, bare_path="file")
    except UrlError:
        return None
    return Path(ep.path) if ep.scheme == "file" else None


def _session_options(args: argparse.Namespace) -> tuple[tuple[str, object], ...]:
    """The options of the Zenoh session that --zenoh opens, as `flags_given` takes them."""
    return (
        ("--prefix", args.prefix),
        ("--zenoh-listen", args.zenoh_listen),
        ("--zenoh-connect", args.zenoh_connect),
        ("--no-scouting", args.no_scouting),
        ("--zenoh-config", args.zenoh_config),
        ("--zenoh-commands", args.zenoh_commands),
    )


def _run_scenario(args: argparse.Namespace, stopped_by: list[int]) -> int:
    """The scenario run; ``stopped_by`` holds the signal that asks it to stop (`signals_noted`)."""
    import signal
    from dataclasses import replace

    from gateway.bus import BusError, make_config, open_session
    from simulator.clock import Clock, RealtimeClock, VirtualClock
    from simulator.commands import MavlinkCommandInput, ZenohCommandInput
    from simulator.faults import COMMAND_KINDS
    from simulator.runner import CommandInput, Route, Simulation
    from simulator.scenarios import get_scenario
    from simulator.tlog_recorder import TlogRecorder
    from simulator.transports import Sink, TransportError, open_sink
    from wire.mcap.folder import make_log_folder
    from wire.mcap.rotation import free_path
    from wire.mcap.writer import McapLogWriter
    from wire.tlog import TlogWriter

    try:
        scenario = get_scenario(args.scenario)
        for flag, rates in (("--gnss-rate", (args.gnss_rate, None)), ("--gyro-rate", (None, args.gyro_rate))):
            try:
                scenario = scenario.with_sensor_rates(*rates)
            except ValueError as exc:  # (the sensor's own check names its class and field: name the option)
                raise ValueError(f"{flag}: {str(exc).split(': ', 1)[-1]}") from None
        for spec in args.nmea:
            picked = _parse_route(spec, "nmea")[1] or frozenset()
            if unknown := sorted(picked - set(scenario.nmea_sources())):
                raise ValueError(
                    f"--nmea {spec}: {args.scenario} has no NMEA talker '{unknown[0]}' (it has "
                    f"{', '.join(scenario.nmea_sources())}; without SOURCE= every one goes to the URL)"
                )
        if args.faults:
            added = load_faults(args.faults)
            problems = scenario.fault_problems(added)
            if problems:  # a fault that bites nothing would run a clean sea in its place
                more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
                raise ValueError(f"--faults {args.faults}: {problems[0]}{more}")
            scenario = replace(scenario, faults=scenario.faults + added)
            commands_in_file = sorted({f.kind for f in scenario.faults if f.kind in COMMAND_KINDS})
            if commands_in_file:
                print(
                    f"dpgw sim: {', '.join(commands_in_file)} in {args.faults} not sent: command faults are "
                    "inputs to the gateway, injected by the in-process closed loop (docs/simulator.md)",
                    file=sys.stderr,
                )
        if args.tlog and scenario.feedback is None:
            raise ValueError(
                f"--tlog {args.tlog}: {args.scenario} has no thrusters that report: it sends no MAVLink to "
                "record (the scenarios' sensors are listed in docs/simulator.md)"
            )
        signing_key = None
        if args.signing_key_file is not None:
            if scenario.feedback is None:
                raise ValueError(
                    f"--signing-key-file: {args.scenario} has no thrusters that report: it sends no MAVLink "
                    "to sign (the scenarios' sensors are listed in docs/simulator.md)"
                )
            from dpgw.signing_key import read_key_file

            signing_key, warning = read_key_file("--signing-key-file", args.signing_key_file)
            if warning:
                print(f"dpgw sim: warning: {warning}", file=sys.stderr)
        if args.ardupilot and scenario.feedback is not None:
            scenario = replace(
                scenario,
                feedback=replace(
                    scenario.feedback, ardupilot_esc=True, ardupilot_servo=True, ardupilot_motor=True
                ),
            )
        if args.on_command_loss and scenario.feedback is not None:
            scenario = replace(
                scenario, feedback=replace(scenario.feedback, on_command_loss=args.on_command_loss)
            )
    except (ValueError, OSError) as exc:
        print(f"dpgw sim: {exc}", file=sys.stderr)
        return 2
    sinks: list[Sink] = []
    routes: list[Route] = []
    commands: list[CommandInput] = []
    mav_commands: MavlinkCommandInput | None = None
    session = None
    log = None
    log_path = args.out  # (the file written: the next of its set when --out exists)
    tlog: TlogWriter | None = None
    try:
        for spec in args.nmea:
            url, sources = _parse_route(spec, "nmea")
            sink = open_sink(url)
            sinks.append(sink)
            routes.append(Route(sink, "nmea", sources))
            print(
                f"NMEA {'(' + ', '.join(sorted(sources)) + ') ' if sources else ''}-> {sink.describe()}",
                file=sys.stderr,
            )
        if args.mavlink:
            sink = open_sink(args.mavlink)
            sinks.append(sink)
            routes.append(Route(sink, "mavlink"))
            mav_commands = MavlinkCommandInput.for_drive(sink, scenario.feedback, signing_key=signing_key)
            commands.append(mav_commands)
            signed = " (signed; signed commands only)" if signing_key is not None else ""
            print(f"MAVLink -> {sink.describe()}{signed}", file=sys.stderr)
        if args.zenoh:
            prefix = args.prefix or f"dp/{scenario.vessel.name}"
            session = open_session(
                make_config(
                    connect=args.zenoh_connect,
                    listen=listen_endpoints(args.zenoh_listen),
                    # endpoints named: the bench is wired, and scouting would only find other benches
                    multicast_scouting=not (args.no_scouting or args.zenoh_connect or args.zenoh_listen),
                    config_file=args.zenoh_config,
                )
            )
            if args.mavlink and not args.zenoh_commands:
                # One command path, as a vessel's drives have: the gateway publishes every command on
                # <prefix>/thrusters/command for its consoles, and drives that took those too would
                # close the loop with its MAVLink commands lost, unsigned or refused for their signature
                print(
                    f"Zenoh: thruster commands from the MAVLink link only, not {prefix}/thrusters/command "
                    "(--zenoh-commands takes those too)",
                    file=sys.stderr,
                )
            else:
                commands.append(ZenohCommandInput(session, prefix))
                print(f"Zenoh: commands from {prefix}/thrusters/command", file=sys.stderr)
        if args.out:
            # Faster than real time, a chunk per second of log time is a chunk per few ms of work: tiny
            # chunks, each with its own compression call and indexes. Chunks then close by size (and
            # every second of wall time, which bounds the loss if the process dies).
            # (the simulation writes its own metadata: scenario, seed, vessel and datum)
            # An --out that exists is not overwritten: the run goes on in the next file of its set
            # (sim_0001.mcap), as the gateway's and the demo's logs do. A bench restarts the simulator
            # with the same command line under a running gateway, whose log of the run before stays;
            # overwriting lost the truth that log was to be scored against.
            try:
                if folder := make_log_folder(args.out):  # (its parent exists: `mcap_path_problem`)
                    print(f"dpgw sim: made the log's folder {folder} (it did not exist)", file=sys.stderr)
                log = McapLogWriter(
                    free_path(args.out), profile="dpgw-sim", flush_on_log_time=bool(args.realtime)
                )
            except OSError as exc:
                raise OSError(f"--out {args.out}: cannot write the log: {exc.strerror or exc}") from None
            if Path(log.path) != Path(args.out):
                print(f"log -> {log.path} ({args.out} exists: a log is never overwritten)", file=sys.stderr)
        if args.tlog:  # last: a tlog is made when opened, so not before another start-up step may fail
            # One that exists is kept, as --out's log is: the tlog goes in the next file of its set
            # (trial_0001.tlog). Overwriting it lost the feedback of the run before, which a bench
            # restarting the simulator with the same command line still scores its gateway log with.
            path = free_path(args.tlog)
            try:
                make_folder_for("dpgw sim", "--tlog", args.tlog)  # (its parent exists: `tlog_path_problem`)
                tlog = TlogWriter(path)
            except OSError as exc:
                raise OSError(f"--tlog {args.tlog}: cannot write the tlog: {exc.strerror or exc}") from None
            kept = "" if path == Path(args.tlog) else f" ({args.tlog} exists: a tlog is never overwritten)"
            print(f"MAVLink (tlog) -> {tlog.path}{kept}", file=sys.stderr)
    except (TransportError, BusError, OSError) as exc:
        message = exc.describe(ZENOH_FLAGS) if isinstance(exc, BusError) else str(exc)
        print(f"dpgw sim: {message}", file=sys.stderr)
        for s in sinks:
            s.close()
        if tlog is not None:
            tlog.close()
        return 2
    # A paced run stopped for longer than RESYNC_LAG_S (Ctrl-Z, a debugger, a suspended laptop, a stalled
    # machine) continues from where it was instead of catching the pause up in a burst of sea that no
    # gateway in the loop could follow; shorter lags are caught up, so the pace holds on average.
    clock: Clock = (
        RealtimeClock(speed=args.speed, resync_lag_s=RESYNC_LAG_S) if args.realtime else VirtualClock()
    )
    if args.held:  # the operator's joystick until the first command (`Simulation.held_tau`), as dpgw demo's
        from dpgw.station_hold import HOLD_PERIOD_S, froude_scale

        station, period = scenario.eta0, HOLD_PERIOD_S * froude_scale(scenario)
        scenario = replace(scenario, tau=lambda _: sim.held_tau(station, period))
    sim = Simulation(
        scenario, args.seed, routes=routes, log=log, clock=clock, commands=commands, signing_key=signing_key
    )
    if args.held:
        sim.start_held()
    recorder = None
    if tlog is not None:  # stamped with the simulation's own epoch: the NMEA sentences' UTC
        recorder = sim.on_emit = TlogRecorder(tlog, sim.epoch)
    if session is not None and args.realtime:  # a gateway on `clock = "sim"` stamps with this
        from simulator.sim_clock import SimClockPublisher

        sim.on_time = SimClockPublisher(session, prefix, sim.epoch, clock, period_s=sim.time_tick_s)
        print(f"Zenoh: simulation time on {sim.on_time.key}", file=sys.stderr)
    elif session is not None:  # (unpaced, the plant runs ahead of any gateway: there is no time to share)
        print(
            f"Zenoh: no simulation time on {prefix}/sim/clock without --realtime: a gateway on "
            'clock = "sim" holds what it receives until a tick comes; add --realtime (and --speed X)',
            file=sys.stderr,
        )

    duration = args.duration if args.duration is not None else scenario.duration_s
    bar = terminal_bar(duration, "sim s", json=args.json)
    try:
        step = 1.0 if args.realtime else 60.0
        while sim.t < duration - 1e-9 and not stopped_by:
            sim.run(min(step, duration - sim.t))
            if bar is not None:
                bar.n = round(sim.t)
                bar.refresh()
    finally:
        if bar is not None:
            bar.close()
        for s in sinks:
            s.close()
        if log is not None:
            log_path = str(log.path)
            log.close()
        if tlog is not None:
            tlog.close()
        if session is not None:
            session.close()
    summary = sim.summary.as_dict()
    summary["signed"] = signing_key is not None
    commands_rejected = dict(mav_commands.rejected) if mav_commands is not None else {}
    summary["commands_rejected"] = commands_rejected
    summary["interrupted"] = bool(stopped_by)
    summary["stopped_by"] = signal.Signals(stopped_by[0]).name if stopped_by else None
    if args.out:
        summary["log"] = log_path
    if recorder is not None:
        summary["tlog"] = {
            "path": args.tlog,
            "records": recorder.records,
            "not_recorded": recorder.not_recorded,
            "records_dropped": recorder.writer.records_dropped,
        }
    if args.json:
        print(cli_json.dumps(summary, indent=2))
    else:
        # stopped early, said as such: "1740 s simulated" alone read as a run that went its course
        from dpgw.cli_stops import stop_name

        by = f"stopped by {stop_name(stopped_by[0])} at " if stopped_by and sim.t < duration - 1e-9 else ""
        asked = f" of {duration:.0f} asked" if by else ""
        print(
            f"{scenario.name}: {by}{sim.t:.0f} s simulated{asked} in {sim.summary.wall_seconds:.1f} s "
            f"({sim.summary.speedup:.0f}x real time), seed {args.seed}"
        )
        for source, n in sorted(sim.summary.emissions.items()):
            line = f"  {source:12s} {n:8d} frames  {sim.summary.bytes_sent[source]:10d} bytes"
            if unsent := sim.summary.not_sent[source]:  # made (and logged), but no output took them
                what = "not sent" if unsent == n else f"{unsent} not sent"
                # (the tlog records the thrusters' frames though no link sends them: said so, not "not sent"
                # alone beside a tlog that holds them)
                kept = "; recorded in --tlog" if recorder is not None and source in recorder.sources else ""
                line += f"  ({what} on a link: no --nmea/--mavlink output takes them{kept})"
            print(line)
        if sim.summary.commands_applied:
            print(f"  thruster commands applied: {sim.summary.commands_applied}")
        if commands_rejected:
            rejected = ", ".join(f"{k} {v}" for k, v in sorted(commands_rejected.items()))
            print(f"  thruster command frames rejected: {rejected}")
        if signing_key is not None:
            print("  thruster MAVLink signed (MAVLink 2 signing, link id 0)")
        if args.out:
            print(f"  log: {log_path} ({sim.summary.truth_records} truth records)")
        if recorder is not None:
            skipped = (
                f", {recorder.not_recorded} corrupted frames not recorded (as a ground station would not)"
                if recorder.not_recorded
                else ""
            )
            dropped = (
                f", {recorder.writer.records_dropped} records lost ({recorder.writer.last_error})"
                if recorder.writer.records_dropped
                else ""
            )
            print(f"  tlog: {args.tlog} ({recorder.records} records{skipped}{dropped})")
    return 0
