"""``dpgw demo``: the simulator on real loopback transports feeding the gateway, on this machine.

`DESCRIPTION` below says what it does (``dpgw demo --help`` prints it); `summarise` scores the estimate
against the simulator's ground truth and the station keeping from the log.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dpgw import cli_json
from dpgw.cli_foxglove import DEFAULT_HOST, DEFAULT_PORT, add_foxglove_arg, connect_lines, layout_path
from dpgw.cli_paths import mcap_path_problem
from dpgw.cli_stops import STOPPED_BY, set_from_handler, stop_name
from dpgw.cli_types import non_negative_float, positive_float, seed_int
from dpgw.cli_zenoh import ZENOH_FLAGS, add_endpoint_args, listen_endpoints
from dpgw.scenario_names import SCENARIO_NAMES
from dpgw.scored_stretch import DP_SETTLE_S, MIN_SCORED_S, SETTLE_S, dp_scored_from
from dpgw.station_hold import HOLD_PERIOD_S, froude_scale, hold_setpoint
from observers.settling import ENGAGE_TIME_CONSTANTS as SETTLING_TIME_CONSTANTS

if TYPE_CHECKING:
    from simulator.runner import Simulation

# Only the parser is built at import. The simulator and the gateway (numpy, numba, scipy, Zenoh) are
# imported by the functions that run the demo, so `dpgw demo --help` answers at once.

ENGAGE_TIME_CONSTANTS = SETTLING_TIME_CONSTANTS
"""When the demo's operator switches the gateway from standby to dp by default (``--engage-at``): once the
observer has settled, this many time constants of its slowest error mode (`Observer.settle_time_s`, the
one definition in `observers.settling` that the estimate's ``settled`` and `dpgw run`'s wait share: the
bias, ~96 s on the default scenario, so DP at 145 s). Until then the vessel is held on joystick: the
simulator's thrusters deliver minus the load it knows (`Simulation.start_held`), from the start, and
the drives report that thrust, so the observer starts at the load's equilibrium and its bias estimate
settles; DP then takes over bumplessly from the thrust the drives report, as a DP operator engages DP
once the estimate has settled. Engaged at the first sample instead (``--engage-at 0``), DP starts cold
into a full storm's load with a bias estimate of zero: on the default scenario (Hs 6 m) the vessel
drifts ~7 m and ~10 deg, and the integrator, which took the load while the bias estimate was still
growing, gives it back over ~200 s (the integral pole, 0.007 rad/s): p95 4-5 m over 60-360 s, which is
the start-up and not the station keeping. Engaged at 30 s (a third of a time constant), the hand-over
still cost p95 3.3 m / 2.6 deg; at 150 s, 0.75 m / 1.0 deg (in-process closed loop, seed 0)."""
LOG_ORDER_WINDOW_S = 2.0
"""The demo's log holds each record until it is this far (log time) behind the newest written, and
writes in log-time order (`McapLogWriter.hold_for_order`): the truth runs ~0.4 s ahead of the gateway's
inputs, more on a busy machine; a crash loses this much more of the log (0.2 s of wall time at 10x)."""
DEFAULT_DURATION_S = 360.0
LOWEST_SPEED = 1.0
"""The demo never slows itself below real time."""
MAX_LOOP_DELAY_S = 0.3
"""Sim seconds the loop may run late (the simulation behind its schedule, or data waiting for the gateway):
beyond it the simulation pauses until the gateway has caught up, and when it persists the demo slows
down. A few sensor samples: small beside a DP vessel's seconds-long dynamics, and still small for the
model-scale vessel of the `hassani` scenario."""
DEMO_OBSERVER = "passive"
"""The demo's observer type. Its settings for the scenario are the study's (`dpgw.closed_loop.
with_scenario_observer`): a scenario's `observer_params` for this type apply."""
SIM_CHUNK_S = 1.0
"""Sea simulated between two looks at whether the demo was stopped (s): at the demo's speeds a stop
takes effect within a fraction of a second of wall time."""
SETTLED_POLL_S = 0.1
"""Sea simulated between two looks at whether the gateway calls the estimate settled, once the demo's
operator waits for it to engage DP (`engage_time`): a sensor sample or so."""


NAME = "demo"
HELP = "simulator + gateway on this machine: NMEA over UDP and a pty, Zenoh, demo.mcap"
DEFAULT_SCENARIO = "torsetnes_2004"
# Plain text: argparse prints it as written (the module docstring's markup would show).
DESCRIPTION = (
    "The simulator on real loopback transports feeding the gateway, on this machine. The simulated DGPS "
    "speaks NMEA over UDP, the gyro over a pty (a virtual serial port), the thrusters MAVLink over UDP "
    "(signed both ways with a key made for the run, as a vessel's link should be); the gateway reads them "
    "exactly as it would on a vessel, runs the observer, publishes on Zenoh (peer mode: "
    "'dpgw listen' in another terminal sees it) and logs to demo.mcap: raw input, estimates and the "
    "simulator's ground truth in one file, so 'dpgw replay demo.mcap' can re-run and score it. The vessel "
    "runs --speed times faster than real time; the simulator publishes its time on Zenoh "
    "(<prefix>/sim/clock) and the gateway stamps what it receives with it, so the loop stays right on a "
    "busy machine. When the machine cannot keep up, the demo halves its speed (down to 1x) and says so. "
    "It serves everything live to the Foxglove app at ws://127.0.0.1:8765 (printed at start; another free "
    "port when 8765 is taken and no --foxglove was given). At the end it says how good the estimate was "
    "against the truth, how well the vessel kept station, and what wave filtering saved: the commanded "
    "thrust's wave band against the same controller fed the raw measurements (the log replayed once more)."
)
EPILOG = (
    "examples:\n"
    "  dpgw demo                                   # 6 minutes of sea in ~40 s\n"
    "  dpgw demo --scenario hassani --duration 300 --speed 5 --out hassani.mcap\n"
    "  dpgw demo --speed 1 --duration 600          # watch it in Foxglove in real time\n"
    "  dpgw demo --foxglove 0.0.0.0:8765           # Foxglove from another computer (no auth!)\n"
    "  dpgw listen 'dp/**'                         # in another terminal, while the demo runs"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scenario",
        choices=SCENARIO_NAMES,
        default=DEFAULT_SCENARIO,
        metavar="NAME",
        help=f"scenario: {', '.join(SCENARIO_NAMES)} (default {DEFAULT_SCENARIO}; docs/simulator.md)",
    )
    p.add_argument(
        "--duration",
        type=positive_float,
        default=DEFAULT_DURATION_S,
        metavar="S",
        help=f"sim seconds (default {DEFAULT_DURATION_S:.0f}; the estimate is scored after {SETTLE_S:.0f} s, "
        f"station keeping from {DP_SETTLE_S:.0f} s after DP is engaged and not before {SETTLE_S:.0f} s, each "
        f"on at least "
        f"{MIN_SCORED_S:.0f} s; too short a run is said at the start)",
    )
    p.add_argument(
        "--speed",
        type=positive_float,
        default=10.0,
        metavar="X",
        help="sim seconds per wall second (default 10); halved, down to 1, while the machine cannot keep up",
    )
    p.add_argument(
        "--seed",
        type=seed_int,
        default=0,
        help="random seed of waves, noise and faults: same seed, same sea (0)",
    )
    p.add_argument(
        "--mode",
        choices=("dp", "standby"),
        default="dp",
        help="dp: the gateway keeps the vessel on station (default), engaged at --engage-at; standby: "
        "estimation only, the scenario's own thrust",
    )
    p.add_argument(
        "--engage-at",
        type=non_negative_float,
        default=None,
        metavar="S",
        help=f"with --mode dp: the sim second the demo switches the gateway from standby to dp (default: "
        "once the gateway calls the estimate settled, "
        f"{ENGAGE_TIME_CONSTANTS:g} time constants of the observer's slowest mode after its first estimate, "
        "145 s on the default scenario; printed at start). Until then the vessel is held "
        "on joystick (the simulator's thrusters answer the load it knows) while the observer's bias "
        "estimate settles; then DP takes over from the thrust the drives report, as an operator engages "
        "DP. 0: dp from the first estimate, a cold start into the full load. Vessels without thruster "
        "feedback start in dp",
    )
    p.add_argument("--out", default="demo.mcap", metavar="FILE.mcap", help="the log (default demo.mcap)")
    add_endpoint_args(p)
    p.add_argument("--no-scouting", action="store_true", help="Zenoh multicast scouting off")
    add_foxglove_arg(p, what="the gateway's outputs", on_by_default=True)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def foxglove_server(args: argparse.Namespace) -> tuple[Any, str] | None:
    """The demo's Foxglove server sink (not started), and a note for the URL line; None with
    ``--no-foxglove``. Without ``--foxglove`` the demo asks for 127.0.0.1:8765 and, when that port is
    taken (another demo, a Foxglove bridge), for any free port: the default must not stop a demo.
    A port given with ``--foxglove`` is used or the demo stops with one message."""
    if args.no_foxglove:
        return None
    from gateway.outputs.foxglove_server import FoxgloveServerError, FoxgloveServerSink

    if args.foxglove is not None:
        return FoxgloveServerSink(*args.foxglove, port_given_by="--foxglove [HOST:]PORT"), ""
    sink = FoxgloveServerSink(DEFAULT_HOST, DEFAULT_PORT)
    try:
        sink.start()
        return sink, ""
    except FoxgloveServerError:
        sink = FoxgloveServerSink(DEFAULT_HOST, 0)
        return sink, f" ({DEFAULT_PORT} is in use)"


def demo_config(
    scenario: Any, pty_device: str, args: argparse.Namespace, signing_key: bytes | None = None
) -> dict[str, Any]:
    """The gateway's config tables for the demo. ``signing_key``: the thruster link's MAVLink 2 key (the
    demo's own, `run`); without one (a test of the other tables) the link is configured unsigned."""
    from dpgw.closed_loop import with_scenario_observer
    from gateway.config import default_config

    cfg = default_config(scenario.vessel.name)
    # the demo is a simulated vessel on this machine: it takes setpoints, modes and τ (still checked)
    cfg["commands"] = {"accept": ["mode", "setpoint", "tau"]}
    dgps = scenario.dgps[0]
    cfg["datum"] = {"lat_deg": scenario.datum.lat_deg, "lon_deg": scenario.datum.lon_deg}
    cfg["sources"] = [
        {
            "name": dgps.source,
            "url": "udp://127.0.0.1:0",
            "protocol": "nmea",
            "roles": ["position"],
            "lever_arm_m": list(dgps.lever_arm_m),
            "timeout_s": max(2.0, 3.0 / dgps.rate_hz),
        },
        {
            "name": scenario.gyro[0].source,
            "url": f"serial://{pty_device}?baud=115200",
            "protocol": "nmea",
            "roles": ["heading"],
            "timeout_s": 2.0,
        },
    ]
    for anemometer in scenario.anemometers:  # a scenario with wind: the controller's wind feed-forward
        cfg["sources"].append(
            {
                "name": anemometer.source,
                "url": "udp://127.0.0.1:0",
                "protocol": "nmea",
                "roles": ["wind"],
                "timeout_s": max(2.0, 3.0 / anemometer.rate_hz),
            }
        )
    for mru in scenario.mru:  # a motion reference unit: roll and pitch for the lever-arm compensation
        cfg["sources"].append(
            {
                "name": mru.source,
                "url": "udp://127.0.0.1:0",
                "protocol": "nmea",
                "roles": ["attitude"],
                "timeout_s": max(0.5, 3.0 / mru.rate_hz),
            }
        )
    if scenario.feedback is not None and scenario.vessel.thrusters:
        cfg["sources"].append(
            {
                "name": "thrusters",
                "url": "udp://127.0.0.1:0",
                "protocol": "mavlink",
                "roles": ["thrusters"],
                "commands": True,  # the dialect's AZIMUTH_THRUSTER_COMMAND back down the same link
                # signed, as a vessel's link should be: the demo's key for this run (`run`)
                **(
                    {"signing_key": signing_key.hex()}
                    if signing_key is not None
                    else {"allow_unsigned": True}
                ),
                # the simulated drive: only its frames are used, and the commands are addressed to it
                "system_id": scenario.feedback.system_id,
                "component_id": scenario.feedback.component_id,
            }
        )
    # The demo's operator engages DP (`engage_time`): a gateway started in dp (``--engage-at 0``, or a vessel
    # whose drives report no thrust) is in DP from the first estimate, as asked, not waiting for the observer
    cfg["control"] = {
        "initial_mode": "standby" if engages_later(args, scenario) else args.mode,
        "wait_for_observer": False,
    }
    tp = scenario.sea[0][1].tp_s
    cfg["observer"] = {"type": DEMO_OBSERVER, "wave_period_s": tp}
    cfg["zenoh"] = {
        "mode": "peer",
        "listen": listen_endpoints(args.zenoh_listen),
        "connect": list(args.zenoh_connect),
        "multicast_scouting": not args.no_scouting,
    }
    cfg["log"] = {"path": str(Path(args.out).resolve())}
    # the gateway lives on the simulator's time, whatever the load (docs/gateway.md, "Simulation time")
    cfg["time"] = {"clock": "sim"}
    # the scenario's observer settings as a study of it applies them (the hassani range, docs/simulator.md)
    return with_scenario_observer(cfg, scenario)


def engages_later(args: argparse.Namespace, scenario: Any) -> bool:
    """Whether the gateway starts in standby and the demo switches it to dp later (`engage_time`); if not,
    it starts in ``--mode``: standby; dp with ``--engage-at 0``, and dp on a vessel whose drives report
    no thrust (a bumpless take-over starts from the thrust they report: without it, it would be a step)."""
    if args.mode != "dp" or scenario.feedback is None or not scenario.vessel.thrusters:
        return False
    return args.engage_at is None or args.engage_at > 0


def engage_time(args: argparse.Namespace, observer: Any) -> float:
    """The sim second to engage DP: ``--engage-at``, or by default the earliest the estimate can have
    settled, the observer's settle time (`Observer.settle_time_s`: `observers.settling.
    ENGAGE_TIME_CONSTANTS` time constants of its slowest error mode). The gateway counts that from its
    first estimate, which comes with the first fix, a fraction of a second in: by default the demo's
    operator therefore waits from then on for the gateway itself to call the estimate settled
    (`waits_for_settled`), as an operator watches the console's "observer ready". (It engaged at this
    time rounded up to the second before, and when the first fix came later than the rounding left, the
    gateway said "DP engaged by the operator before the observer settled" in every default demo.)"""
    if args.engage_at is not None:
        return float(args.engage_at)
    return float(observer.settle_time_s)


def waits_for_settled(args: argparse.Namespace) -> bool:
    """Whether the demo's ``dp`` waits for the gateway to call the estimate settled (`Pipeline.settled`):
    by default; an ``--engage-at`` is the user's own time, kept even when early (then the gateway says so,
    as it says it to an operator who engages early)."""
    return args.engage_at is None


def needed_duration_s(engage_s: float | None) -> int:
    """The ``--duration`` that scores the station keeping with DP engaged at ``engage_s`` (None or 0: from
    the start; the estimate alone is scored from `SETTLE_S`, which is ``engage_s`` None's answer too):
    `MIN_SCORED_S` from `dp_scored_from`, and a second more. The scored stretch runs from its first sample
    to its last, a sample interval short of the run's end (a run of exactly 160 s with DP at 100 s scored
    29.9 s and was "not scored"), and an engagement still to come waits for a fix (`engage_time`). The
    same figure at the start and at the end of a run: before, the end asked for the duration just given."""
    return math.ceil(dp_scored_from(engage_s) + MIN_SCORED_S + 1.0)


def engagement_lines(args: argparse.Namespace, engage_s: float) -> list[str]:
    """What the demo says at start about when DP is engaged, for a run of ``args.duration``: when, or that
    this run ends before it (the vessel held on joystick throughout, station keeping not scored) and the
    duration it takes; and when the run ends after the engagement but too soon to score it, that too."""
    waits = waits_for_settled(args)
    when = (
        f"once the observer has settled, {engage_s:.0f} s after its first estimate"
        if waits
        else f"at {engage_s:g} s of sea"
    )
    need = needed_duration_s(engage_s)
    cold = needed_duration_s(0.0)
    todo = f"give --duration {need} or more (default {DEFAULT_DURATION_S:.0f})"
    if args.duration >= cold and engage_s > 0:
        todo += ", or --engage-at 0 for DP from the start"
    if args.duration <= engage_s + (1.0 if waits else 0.0):  # (the first estimate: within the first fix)
        return [
            f"with --duration {args.duration:g}, DP will not be engaged (it would be {when}) and station "
            f"keeping will not be scored: the vessel is held on joystick for the whole run; {todo}"
        ]
    lines = [f"the vessel is held on joystick until DP is engaged, {when} (--engage-at)"]
    if args.duration < need:
        lines.append(
            f"with --duration {args.duration:g}, station keeping will not be scored (it is scored from "
            f"{DP_SETTLE_S:.0f} s after DP is engaged and not before {SETTLE_S:.0f} s, on at least "
            f"{MIN_SCORED_S:.0f} s); {todo}"
        )
    return lines


def run(args: argparse.Namespace) -> int:
    import secrets
    import signal
    import threading
    from dataclasses import replace
    from datetime import UTC, datetime

    from dpgw.loop_lag import LoopLag, WatchedSink
    from gateway.bus import BusError
    from gateway.config import ConfigError, format_problems, parse_config
    from gateway.replay import DEMO_METADATA
    from gateway.service import GatewayService
    from gateway.sources import SourceError
    from simulator.clock import RealtimeClock, SimEpoch, SpeedGovernor
    from simulator.commands import MavlinkCommandInput, ZenohCommandInput
    from simulator.runner import Route, Simulation
    from simulator.scenarios import get_scenario
    from simulator.sim_clock import SimClockPublisher
    from simulator.transports import PtySink, UdpSink

    if problem := mcap_path_problem(
        "--out", args.out, made=True
    ):  # (before: said as the config key log.path)
        print(f"dpgw demo: {problem}", file=sys.stderr)
        return 2
    if args.mode == "standby" and args.engage_at is not None:  # (accepted and ignored before)
        print("dpgw demo: --engage-at switches to dp: it goes with --mode dp (the default)", file=sys.stderr)
        return 2
    # Ctrl-C or SIGTERM: the simulation ends its current second of sea before the gateway closes the
    # session and the log it writes to (it once went on into the closed session and the stop read as
    # "the simulator failed"); the summary covers what ran and says it was stopped, and by what. Taken
    # from here on, before the gateway starts: a Ctrl-C while its kernels compile (~15 s on a first run)
    # met Python's default, a traceback from inside the compiler.
    stop_sim = threading.Event()
    stopped_by: list[int] = []  # the signal that stopped the demo
    running: list[GatewayService] = []  # the gateway, once started

    def on_signal(signum: int, _frame: object) -> None:
        stopped_by.append(signum)
        set_from_handler(stop_sim, *(started.stop_event for started in running))

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    scenario = get_scenario(args.scenario)
    pty = PtySink()
    sinks: list[Any] = [pty]
    foxglove = None
    # The thruster link is MAVLink 2 signed with a key made for this run: the gateway signs its commands
    # and takes only signed feedback, the simulated drives sign theirs and take only signed commands. The
    # simulator runs in this process (a thread), so the key goes to it in memory: never on a command
    # line, in the environment or in a file; the log keeps the config without it (`GatewayService`).
    signing_key = secrets.token_bytes(32)
    try:
        tables = demo_config(scenario, pty.device, args, signing_key)
        config = parse_config(tables, base_dir=Path.cwd(), where="dpgw demo")
        foxglove = foxglove_server(args)
        outputs = [foxglove[0]] if foxglove is not None else []
        service = GatewayService(config, config_tables=tables, sinks=outputs)
        service.start()
        running.append(service)
    except ConfigError as exc:
        pty.close()
        print(format_problems(exc), file=sys.stderr)
        return 2
    except BusError as exc:
        pty.close()
        print(f"dpgw demo: {exc.describe(ZENOH_FLAGS)}", file=sys.stderr)
        return 2
    except (SourceError, OSError) as exc:
        pty.close()
        if foxglove is not None:
            foxglove[0].close()
        hint = " (or --no-foxglove)" if "foxglove" in str(exc) else ""
        print(f"dpgw demo: {exc}{hint}", file=sys.stderr)
        return 2
    if stopped_by:  # during start-up: nothing ran
        service.close()
        pty.close()
        print(
            f"dpgw demo: stopped by {stop_name(stopped_by[0])} during start-up; nothing ran", file=sys.stderr
        )
        return exit_status(stopped_by[0])
    # From here until the simulation runs, the gateway runs with nobody to stop it: whatever goes wrong
    # in between (a sink that cannot open, a scenario the simulator refuses) closes it, its sources and the
    # log before it is raised. Left running, its threads kept the process from ending after the error.
    try:
        if foxglove is not None:
            sink, note = foxglove
            for line in connect_lines(sink.url, sink.app_url(), note=note):
                print(f"dpgw demo: {line}", file=sys.stderr, flush=True)
        ports: dict[str, int] = {s.name: int(getattr(s, "port", 0)) for s in service._sources}
        start_utc = datetime.fromtimestamp(service._wall0_ns / 1e9, tz=UTC)
        counters = service.pipeline.counters
        # how far the gateway is behind what the simulator sent, in sim seconds (read in the simulator's
        # thread)
        loop_lag = LoopLag(
            SimEpoch(start_utc),
            lambda name: (
                (counters[name].last_rx_ns or None, counters[name].bytes) if name in counters else (None, 0)
            ),
            tolerance_s=Simulation.TIME_TICK_S,
        )

        def watched(sink: Any, source: str) -> WatchedSink:
            return WatchedSink(sink, source, loop_lag, lambda: sim.t)

        dgps_sink = UdpSink("127.0.0.1", ports[scenario.dgps[0].source])
        sinks.append(dgps_sink)
        routes = [
            Route(watched(dgps_sink, scenario.dgps[0].source), "nmea", frozenset({scenario.dgps[0].source})),
            Route(watched(pty, scenario.gyro[0].source), "nmea", frozenset({scenario.gyro[0].source})),
        ]
        for anemometer in scenario.anemometers:
            wind_sink = UdpSink("127.0.0.1", ports[anemometer.source])
            sinks.append(wind_sink)
            routes.append(
                Route(watched(wind_sink, anemometer.source), "nmea", frozenset({anemometer.source}))
            )
        for mru in scenario.mru:
            mru_sink = UdpSink("127.0.0.1", ports[mru.source])
            sinks.append(mru_sink)
            routes.append(Route(watched(mru_sink, mru.source), "nmea", frozenset({mru.source})))
        commands: list[Any] = []
        if "thrusters" in ports:
            mav_sink = UdpSink("127.0.0.1", ports["thrusters"])
            sinks.append(mav_sink)
            routes.append(Route(watched(mav_sink, "thrusters"), "mavlink"))
            # the loop closes over the MAVLink link (the thrusters port exists only with feedback)
            commands.append(
                MavlinkCommandInput.for_drive(mav_sink, scenario.feedback, signing_key=signing_key)
            )
        elif args.mode == "dp" and service._session is not None:
            commands.append(
                ZenohCommandInput(service._session, config.zenoh.prefix)
            )  # τ for layout-less ships
        clock = RealtimeClock(speed=args.speed)
        if args.mode == "dp":
            # Hold the scenario's station, not wherever the first (wave-moved, noisy) fix put the estimate.
            service.submit("setpoint", hold_setpoint(scenario))
        if service.log is not None:  # so that `dpgw replay` of this log scores the same stretch
            # (and scores it on as much sea: less than `MIN_SCORED_S` is said "not scored", there as here)
            service.log.add_metadata(
                DEMO_METADATA, {"settle_s": f"{SETTLE_S:g}", "min_scored_s": f"{MIN_SCORED_S:g}"}
            )
            # the simulator writes its truth into this log as the plant computes it, ahead of what the
            # gateway logs of the same time: held a window so that the file is in log-time order
            service.log.hold_for_order(LOG_ORDER_WINDOW_S)
        engage_s = engage_time(args, service.pipeline.observer) if engages_later(args, scenario) else None
        if engage_s is not None:
            for line in engagement_lines(args, engage_s):
                print(f"dpgw demo: {line}", file=sys.stderr, flush=True)
            # until DP is engaged, an operator holds the vessel by joystick on its station, against the load
            station, hold_period_s = scenario.eta0, HOLD_PERIOD_S * froude_scale(scenario)
            scenario = replace(scenario, tau=lambda _: sim.held_tau(station, hold_period_s))
        sim = Simulation(
            replace(scenario, start_utc=start_utc),
            args.seed,
            routes=routes,
            log=service.log,
            clock=clock,
            log_raw=False,  # the gateway logs what it received; the simulator adds the truth
            commands=commands,
            signing_key=signing_key,
        )

        def lowered(old: float, new: float, delay: float) -> None:
            if len(governor.changes) == 1:  # say it once; the summary gives the final speed
                print(
                    f"dpgw demo: this machine cannot keep up with {old:g}x (the loop ran {delay:.1f} s of "
                    f"sea late); running slower, {new:g}x (down to {LOWEST_SPEED:g}x if need be)",
                    file=sys.stderr,
                    flush=True,
                )

        governor = SpeedGovernor(
            clock, max_delay_s=MAX_LOOP_DELAY_S, floor=min(LOWEST_SPEED, args.speed), on_lower=lowered
        )
        assert service._session is not None
        sim.on_time = publisher = SimClockPublisher(
            service._session,
            config.zenoh.prefix,
            sim.epoch,
            clock,
            period_s=sim.time_tick_s,
            governor=governor,
            # as wall time at this speed; none once the demo stops: the gateway reads no more, and waiting for
            # it held the simulation (and so the stop) for up to `simulator.sim_clock.MAX_WAIT_S`
            downstream_delay_s=lambda: 0.0 if stop_sim.is_set() else loop_lag.lag_s(sim.t) / clock.speed,
            max_downstream_s=MAX_LOOP_DELAY_S,
        )
        if service.sim_time is not None:
            # the gateway knows its simulator: another simulator's clock on this key (another demo or bench
            # with this vessel's prefix, reached by scouting) is ignored and alarmed, never followed
            service.sim_time.pin(publisher.run)
        sim_error: list[BaseException] = []
        engaged_at: list[float] = []  # the sim second the demo's operator sent dp
        sim_ended: list[float] = []  # when the simulation stopped (monotonic): the run's own wall time ends

        if engage_s is not None:
            sim.start_held()
        pending_engage = math.inf if engage_s is None else engage_s
        wait_settled = waits_for_settled(args)

        def simulate() -> None:
            nonlocal pending_engage
            try:
                while sim.t < args.duration - 1e-9 and not stop_sim.is_set():
                    due = sim.t >= pending_engage - 1e-9
                    if due and (not wait_settled or service.pipeline.settled):
                        # the operator's "DP" button: an input on /dp/mode as any other, logged and replayed
                        service.submit("mode", "dp")
                        engaged_at.append(sim.t)
                        pending_engage, due = math.inf, False
                    step = SETTLED_POLL_S if due else max(pending_engage - sim.t, 1e-9)
                    sim.run(min(SIM_CHUNK_S, args.duration - sim.t, step))
                sim_ended.append(time.monotonic())
                if not stop_sim.is_set():
                    time.sleep(0.3)  # let the last bytes arrive
            except BaseException as exc:  # reported below, never a silent hang
                sim_error.append(exc)
            finally:
                service.stop_event.set()

        thread = threading.Thread(target=simulate, name="dpgw-demo-sim", daemon=True)
        wall0 = time.monotonic()
        thread.start()
    except BaseException:
        service.close()
        for s in sinks:
            s.close()
        raise
    try:
        service.run()
        service.drain()
    finally:
        stop_sim.set()  # (if the gateway stopped first, the simulation follows)
        thread.join(timeout=5)
        final_status = service.pipeline.status(service.pipeline.last_ns).payload
        # The files this run wrote: an --out that exists already is not overwritten, the run goes on in
        # the next file of its set (demo_0001.mcap, as a restarted gateway's log does), and a long run may
        # rotate; the summary scores and names these, not whatever --out held before. (Taken before
        # `close`, which lets the writer go; its list is complete once it is closed.)
        writer = service.log
        service.close()
        written = [str(p) for p in writer.paths] if writer is not None else []
        for s in sinks:
            s.close()
    if sim_error:
        print(f"dpgw demo: the simulator failed: {sim_error[0]!r}", file=sys.stderr)
        return 1
    # the speed is the simulation's own: the gateway's close and the log's footer come after it
    wall_s = (sim_ended[0] if sim_ended else time.monotonic()) - wall0
    # the engagement as it happened (by default once the gateway called the estimate settled); as planned
    # when the run ended before it
    engage_at = engaged_at[0] if engaged_at else engage_s
    summary = summarise(
        args, sim, final_status, wall_s, written or [args.out], engage_at, stopped=bool(stopped_by)
    )
    summary["dp_engaged"] = bool(engaged_at) if engage_s is not None else args.mode == "dp"
    if engage_s is not None and not engaged_at and final_status.get("mode") == "dp":
        # a console on this computer (the demo's gateway listens on no other) sent dp before the demo's
        # operator did: the run was in DP, not held on joystick, whatever the plan said
        summary["dp_engaged"] = True
        summary["engaged_by"] = "another console"
    summary["engage_at_given"] = args.engage_at is not None  # (else: once the gateway called it settled)
    summary["speed"] = {
        "requested": args.speed,
        "final": clock.speed,
        "lowered": [{"from": a, "to": b, "late_s": late} for a, b, late in governor.changes],
        "pauses": publisher.pauses,
        "paused_s": publisher.paused_s,
    }
    mav_commands = next((c for c in commands if isinstance(c, MavlinkCommandInput)), None)
    if mav_commands is not None:  # the drives' side of the signed link (the gateway's is in "sources")
        summary["thruster_link"] = {
            "signed": mav_commands.signed,
            "commands_rejected": dict(mav_commands.rejected),
        }
    summary["interrupted"] = bool(stopped_by)
    summary["stopped_by"] = signal.Signals(stopped_by[0]).name if stopped_by else None
    # why a figure is missing, in the console's words: a program read only its absence before
    summary["estimate_not_scored"] = estimate_not_scored(summary)
    summary["station_keeping_not_scored"] = station_keeping_not_scored(summary)
    if args.json:
        print(cli_json.dumps(summary, indent=2))
    else:
        print_summary(summary)
    return exit_status(stopped_by[0]) if stopped_by else 0


def exit_status(signum: int) -> int:
    """The demo's exit status when ``signum`` stopped it: 128 + the signal's number, as a shell says a
    command a signal ended (Ctrl-C 130, SIGTERM 143), and as `dpgw study` and `dpgw replay` do. The demo
    is a run with an end of its own (``--duration``): a script that stops one early (``timeout``, ``kill``)
    learns from the status that it did not run its course, whatever the log holds. `dpgw run` ends 0 on
    SIGTERM instead: there it is the service's normal stop (docs/cli.md, "Exit status on a signal")."""
    return 128 + int(signum)


def summarise(
    args: argparse.Namespace,
    sim: Simulation,
    status: dict[str, Any],
    wall_s: float,
    logs: list[str],
    engage_s: float | None = None,
    *,
    stopped: bool = False,
) -> dict[str, Any]:
    """The demo's summary from ``logs``, the files this run wrote (one unless it rotated); ``engage_s``: the
    sim second DP was to be engaged (None: the gateway started in its mode). ``stopped``: a signal ended
    the run, and whoever sent it wants out: the summary leaves out the one figure that replays the log
    again (what wave filtering saved), and says how to have it."""
    import numpy as np

    from dpgw.raw_feedback import thrust_wave_band
    from gateway.scoring import score
    from wire.mcap.reader import read_messages

    est = [(p["stamp_ns"], p["eta"]) for _, _, _, p in read_messages(logs, "/dp/estimate")]
    truth = [(p["stamp_ns"], p["eta_lf"]) for _, _, _, p in read_messages(logs, "/truth/state")]
    shown = " ".join(shlex.quote(p) for p in logs)
    result: dict[str, Any] = {
        "scenario": sim.scenario.name,
        "sim_seconds": sim.seconds,
        "duration_s": args.duration,
        "wall_seconds": wall_s,
        "log": logs[0],
        "logs": logs,
        "sent": dict(sim.summary.emissions),
        "commands_applied": sim.summary.commands_applied,  # thruster commands the simulated drives took
        "sources": status["sources"],
        "estimates": len(est),
        "alarms": status["alarms"],
        "mode": args.mode,
        "engage_at_s": engage_s,
    }
    commands = status.get("commands") or {}
    if engage_s is not None and any(k.startswith("mode:") for k in commands.get("refused", {})):
        # the operator's dp was refused (an unhealthy estimate): said why, in the gateway's words when the
        # last refusal was that one, else by its count's key ("mode: estimate not healthy")
        last = str(commands.get("last_refused") or "")
        result["dp_refused"] = (
            last if last.startswith("mode") else next(k for k in commands["refused"] if k.startswith("mode:"))
        )
    if est and truth:
        t0 = truth[0][0]
        te = (np.array([e[0] for e in est]) - t0) / 1e9
        tt = (np.array([t[0] for t in truth]) - t0) / 1e9
        s = score(te, np.array([e[1] for e in est]), tt, np.array([t[1] for t in truth]), settle_s=SETTLE_S)
        # the sea scored after the skip (`gateway.scoring.score` keeps it from the first estimate on):
        # less than `MIN_SCORED_S` is said, not scored
        result["estimate_scored_s"] = max(0.0, float(te[-1] - te[0]) - SETTLE_S)
        if result["estimate_scored_s"] >= MIN_SCORED_S:
            result["error_vs_truth"] = s.as_dict()
        result["settle_s"] = SETTLE_S
        result["station_keeping"] = station_keeping(
            logs, tt, np.array([t[1] for t in truth]), t0, thrust_wave_band(sim.scenario.vessel), not stopped
        )
    result["fix_stamp_lag_s"] = fix_stamp_lag_s(logs, sim.scenario.dgps[0].source)
    result["next"] = [
        f"look at it: open {shown} in Foxglove and import the layout {layout_path()} (map, 3D view "
        "with hull, thrusters and setpoint, measurement against estimate per DOF, alarm log); "
        "/dp/estimate.eta[0] against /truth/state.eta_lf[0] in a Plot panel shows the error",
        f"replay it in Foxglove, with play, pause and seek: dpgw replay {shown} --foxglove",
        f"replay it: dpgw replay {shown} --report {Path(logs[0]).stem}-report",
    ]
    return result


def station_keeping(
    log: list[str],
    t_truth: Any,
    eta_truth: Any,
    t0_ns: int,
    band: tuple[float, float],
    measure_wave_filtering: bool = True,
) -> dict[str, Any] | None:
    """How well the vessel kept station after the settle time: the true LF position's distance from, and
    heading's difference to, the controller's reference (the setpoint through the reference model), p95;
    the share of the commanded force's variance in ``band`` (rad/s), and what wave filtering kept out of
    the commanded τ there (`dpgw.raw_feedback`)."""
    import numpy as np

    from dpgw.raw_feedback import compare_with_raw_feedback
    from gateway.scoring import truth_at
    from observers.kinematics import ssa
    from wire.mcap.reader import read_messages

    cmds = [(p["stamp_ns"], p) for _, _, _, p in read_messages(log, "/dp/thrusters/command")]
    if not cmds:
        return None
    t_cmd = (np.array([c[0] for c in cmds]) - t0_ns) / 1e9
    ref = np.array([c[1]["reference"] for c in cmds], dtype=float)
    engaged = float(t_cmd[0])  # (its first command)
    keep = t_cmd >= dp_scored_from(engaged)
    if keep.sum() < 10 or t_cmd[keep][-1] - t_cmd[keep][0] < MIN_SCORED_S:
        return None
    true_at = truth_at(t_cmd[keep], t_truth, eta_truth)
    dist = np.hypot(true_at[:, 0] - ref[keep, 0], true_at[:, 1] - ref[keep, 1])
    signed = np.degrees(ssa(true_at[:, 2] - ref[keep, 2]))
    tau = np.array([c[1]["tau_demand"] for c in cmds], dtype=float)[keep]
    out = {
        "position_p95_m": float(np.nanpercentile(dist, 95)),
        "heading_p95_deg": float(np.nanpercentile(np.abs(signed), 95)),
        # the means say whether the integral action closes (a p95 alone cannot tell an offset from noise)
        "north_mean_m": float(np.nanmean(true_at[:, 0] - ref[keep, 0])),
        "east_mean_m": float(np.nanmean(true_at[:, 1] - ref[keep, 1])),
        "heading_mean_deg": float(np.nanmean(signed)),
        "reference": [float(ref[-1, 0]), float(ref[-1, 1]), math.degrees(float(ref[-1, 2]))],
        "dp_engaged_s": engaged,
        "scored_from_s": float(t_cmd[keep][0]),
    }
    dt = float(np.median(np.diff(t_cmd[keep])))
    if len(tau) >= 64 and dt > 0:
        spectrum = np.abs(np.fft.rfft(tau[:, :2] - tau[:, :2].mean(axis=0), axis=0)) ** 2
        omega = 2.0 * np.pi * np.fft.rfftfreq(len(tau), dt)
        wave = (omega >= band[0]) & (omega <= band[1])
        out["wave_band_force_share"] = float(spectrum[wave].sum() / max(spectrum[1:].sum(), 1e-30))
    # what wave filtering kept out of the commanded thrust (`dpgw.raw_feedback`), over the same stretch
    if measure_wave_filtering:
        print(
            "dpgw demo: measuring what wave filtering saved: the log replayed once more, the controller "
            "fed the raw measurements",
            file=sys.stderr,
        )
        out["wave_filtering"] = compare_with_raw_feedback(
            log, [c for _, c in cmds], band, cmds[int(np.argmax(keep))][0]
        ).figures
    else:
        shown = " ".join(shlex.quote(p) for p in log)
        out["wave_filtering"] = {
            "not_measured": f"the run was stopped; dpgw replay {shown} --report measures it"
        }
    return out


def fix_stamp_lag_s(log: list[str], source: str) -> dict[str, float] | None:
    """How much later the gateway stamped each DGPS fix than the fix's own time (the GGA time of day,
    which the simulator writes from its clock): per fix, received stamp − fix time. On one time base it
    is the receiver's latency (0.1 s in the scenarios) and nearly constant; a gateway clock drifting from
    the plant's shows as seconds. Median, 99th percentile and largest, in s."""
    import numpy as np

    from wire.mcap.reader import read_messages

    day_ns = 86_400 * 10**9
    lags = []
    for _, log_ns, _, p in read_messages(log, f"/raw/nmea/{source}"):
        for sentence in p["text"].split("\r\n"):
            fields = sentence.split(",")
            if len(fields) < 2 or not fields[0].endswith("GGA") or len(fields[1]) < 6:
                continue
            try:
                hh, mm, ss = int(fields[1][0:2]), int(fields[1][2:4]), float(fields[1][4:])
            except ValueError:
                continue
            tod_ns = round((hh * 3600 + mm * 60 + ss) * 1e9)
            fix_ns = log_ns - log_ns % day_ns + tod_ns
            fix_ns += day_ns * round((log_ns - fix_ns) / day_ns)  # the day nearest the receipt
            lags.append((log_ns - fix_ns) / 1e9)
    if not lags:
        return None
    a = np.array(lags)
    return {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "max": float(a.max())}


def _one_decimal(x: float) -> str:
    """``x`` to one decimal, never "-0.0" (a reference a hair west of the origin is at 0.0 m E)."""
    return f"{round(x, 1) + 0.0:.1f}"


def estimate_not_scored(r: dict[str, Any]) -> str | None:
    """Why the demo's summary ``r`` has no error of the LF estimate against the truth, in the console's
    words (and `--json`'s ``estimate_not_scored``); None when it has one."""
    e = r.get("error_vs_truth")
    if e is not None and (e["samples"] or math.isfinite(e.get("horizontal_rms_m", 0.0))):
        return None
    scored = r.get("estimate_scored_s") or 0.0
    todo = (
        ""
        if r.get("interrupted")
        else f"; give --duration {needed_duration_s(None)} or more, e.g. the default {DEFAULT_DURATION_S:.0f}"
    )
    from gateway.scoring import not_scored_note  # (the words `dpgw replay` says it in too)

    return f"{not_scored_note(scored, SETTLE_S, MIN_SCORED_S)}{todo}"


def station_keeping_not_scored(r: dict[str, Any]) -> str | None:
    """Why the demo's summary ``r`` has no station keeping, in the console's words (and `--json`'s
    ``station_keeping_not_scored``); None when it has it."""
    if r.get("station_keeping"):
        return None
    if r.get("dp_refused"):
        return f"not scored: the gateway refused dp ({r['dp_refused']})"
    how = "stopped" if r.get("interrupted") else "ended"
    if r.get("engaged_by"):
        return (
            f"not scored: DP was engaged by {r['engaged_by']}, not the demo's operator, and the run {how} at "
            f"{r['sim_seconds']:.0f} s, before {MIN_SCORED_S:.0f} s of DP after its {DP_SETTLE_S:.0f} s "
            "settle time"
        )
    if r.get("mode") == "standby":
        return "none in standby (the gateway commands no thrusters: the scenario's own thrust)"
    engage = r.get("engage_at_s")
    scored_from = dp_scored_from(engage)
    when = f"DP engaged at {engage:.0f} s" if engage is not None else "DP from the start"
    engaged = r.get("dp_engaged", engage is None or r["sim_seconds"] >= engage)
    ended = "" if engaged else "before DP was engaged"
    if not engaged and engage is not None and r["sim_seconds"] >= engage + 1.0:
        # the demo's operator waits for the gateway's "settled" (`waits_for_settled`): an observer that
        # restarted counts its settle time again
        ended += " (the gateway did not call the estimate settled)"
    need = needed_duration_s(engage)
    todo = f"give --duration {need} or more (default {DEFAULT_DURATION_S:.0f})"
    if engage is not None and r["sim_seconds"] >= needed_duration_s(0.0):
        todo += ", or --engage-at 0 for DP from the start"
    return (
        f"not scored: the run {how} at {r['sim_seconds']:.0f} s{' ' if ended else ''}{ended}; with {when} "
        f"it is scored from {scored_from:.0f} s, on at least {MIN_SCORED_S:.0f} s"
        + ("" if r.get("interrupted") else f"; {todo}")
    )


def print_summary(r: dict[str, Any]) -> None:
    if r.get("interrupted"):
        by = STOPPED_BY.get(str(r.get("stopped_by")), str(r.get("stopped_by") or "a signal"))
        of = f" (of {r['duration_s']:.0f} asked)" if r.get("duration_s") else ""
        ran = f"stopped by {by} at {r['sim_seconds']:.0f} s of sea{of}, after {r['wall_seconds']:.1f} s"
    else:
        ran = f"{r['sim_seconds']:.0f} s of sea in {r['wall_seconds']:.1f} s"
    print(f"dpgw demo: {r['scenario']}, {ran}; log {' '.join(r['logs'])}")
    print(f"  {'source':12s} {'sent':>8s} {'received':>9s}  rejected")
    for name, c in r["sources"].items():
        rej = ", ".join(f"{k} {v}" for k, v in c["rejected"].items()) or "none"
        if c.get("warnings"):  # used, with a caveat
            rej += "; warnings: " + ", ".join(f"{k} {v}" for k, v in c["warnings"].items())
        print(f"  {name:12s} {r['sent'].get(name, 0):8d} {c['received']:9d}  {rej}")
    link = r.get("thruster_link")
    if link is not None:
        rejected = ", ".join(f"{k} {v}" for k, v in sorted(link["commands_rejected"].items())) or "none"
        signed = "MAVLink 2 signed with a key made for this run" if link["signed"] else "unsigned"
        print(f"  thruster link: {signed}; command frames the drives rejected: {rejected}")
    print(f"  estimates published: {r['estimates']}")
    e = r.get("error_vs_truth")
    if e and e["samples"]:
        print(
            f"  LF estimate vs truth (after {r['settle_s']:.0f} s): "
            f"horizontal RMS {e['horizontal_rms_m']:.2f} m, p95 {e['horizontal_p95_m']:.2f} m; "
            f"heading RMS {e['rms_heading_deg']:.2f} deg"
        )
    elif (why := estimate_not_scored(r)) is not None:
        print(f"  LF estimate vs truth: {why}")
    k = r.get("station_keeping")
    if k:
        if r.get("engage_at_s") is not None:
            why = (
                "engaged by another console, not the demo's operator"
                if r.get("engaged_by")
                else "at the time --engage-at gave"
                if r.get("engage_at_given")
                else "while the observer's bias estimate settled"
            )
            print(f"  DP engaged at {k['dp_engaged_s']:.0f} s (held on joystick until then, {why})")
        print(
            f"  station keeping (true position vs the reference, after {k['scored_from_s']:.0f} s): p95 "
            f"{k['position_p95_m']:.2f} m, heading p95 {k['heading_p95_deg']:.2f} deg"
        )
        w = k.get("wave_filtering")
        if w:
            from dpgw.raw_feedback import wave_filtering_lines

            for text in wave_filtering_lines(w):
                print(f"  {text}")
        print(
            f"  mean offset from the reference ({_one_decimal(k['reference'][0])} m N, "
            f"{_one_decimal(k['reference'][1])} m E, {_one_decimal(k['reference'][2])} deg): "
            f"{k['north_mean_m']:+.2f} m N, {k['east_mean_m']:+.2f} m E, "
            f"heading {k['heading_mean_deg']:+.2f} deg"
        )
    elif (why := station_keeping_not_scored(r)) is not None:
        print(f"  station keeping: {why}")
    lag = r.get("fix_stamp_lag_s")
    if lag is not None:
        print(
            f"  time base: fixes stamped {1000 * lag['median']:.0f} ms after their own time (the median: "
            f"the receiver's latency; p99 {1000 * lag['p99']:.0f} ms, largest {1000 * lag['max']:.0f} ms: "
            "with the delivery on this machine)"
        )
    sp = r.get("speed")
    if sp and sp["final"] != sp["requested"]:
        print(f"  speed: {sp['requested']:g}x asked, {sp['final']:g}x at the end (this machine was busy)")
    if r["alarms"]:
        print(f"  alarms at the end: {'; '.join(r['alarms'])}")
    for step in r.get("next", []):
        print(f"  next: {step}")
