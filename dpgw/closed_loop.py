"""The HIL loop in one process: simulator → gateway pipeline → thruster commands → simulator.

What the simulator's sensors send is fed to the same pipeline the gateway runs, at the simulator's times (no
transports, no clocks): closed-loop station keeping for tests and studies, fast and reproducible. `dpgw demo`
runs the same loop over real UDP, a pty and MAVLink.

Two paths from the sensors to the pipeline (``wire``):

* **typed** (the default where it can be used): each sentence or frame reaches the pipeline as the record
  its decoder would return (`Emission.record` → `RawEvent.records`), unrounded; nothing is encoded, framed,
  checksummed or parsed. Same events, same order, same times, same random streams as the bytes: the
  estimates differ from the bytes path only by the wire format's rounding (1e-7 min of latitude, 0.01° of
  heading, float32 thrust), which tests/test_closed_loop.py bounds.
* **bytes**: the exact bytes the simulator would put on the wire, through the pipeline's framers and
  parsers — needed for a raw log, for the wire-side faults (bad checksum, garbage) and for ArduPilot
  feedback frames, and chosen for those automatically.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gateway.config import parse_config
from gateway.config.defaults import DEFAULTS
from gateway.pipeline import ControlEvent, Pipeline, PipelineSpec, RawEvent
from observers.factory import with_defaults
from simulator.commands import Command, TauCommand, ThrusterCommand
from simulator.faults import FaultSchedule
from simulator.runner import Route, Simulation
from simulator.scenarios import Scenario
from simulator.sensors import Emission
from simulator.transports import Sink
from wire import messages
from wire.mcap.writer import McapLogWriter
from wire.messages import Message, message_for_topic

Array = NDArray[np.float64]


class _TimedSink(Sink):
    """Keeps (sim time, bytes) of every write, for the pipeline to receive at the right time."""

    def __init__(self, sim_time: Any) -> None:
        super().__init__()
        self.sim_time = sim_time
        self.items: list[tuple[float, bytes]] = []

    def write(self, data: bytes) -> None:
        self.items.append((self.sim_time(), bytes(data)))
        self.bytes_written += len(data)

    def describe(self) -> str:
        return "in-process"


class _Commands:
    def __init__(self) -> None:
        self.pending: list[Command] = []

    def poll(self) -> list[Command]:
        out, self.pending = self.pending, []
        return out


@dataclass
class ClosedLoopRun:
    t: Array  # s, every chunk
    eta_lf: Array  # true LF motion [N, E, ψ]
    eta_wf: Array
    estimate_messages: list[messages.Estimate] = field(default_factory=list)  # typed; `estimates`: dicts
    nu: Array = field(default_factory=lambda: np.zeros((0, 3)))  # true LF velocity [u, v, r], body
    bias: Array = field(default_factory=lambda: np.zeros((0, 3)))  # true bias b (earth-fixed, `true_bias`)
    collected_messages: dict[str, list[Message]] = field(default_factory=dict)  # collect: topic -> messages
    command_messages: list[messages.ThrusterCommand] = field(default_factory=list)  # `commands`: dicts
    status: dict[str, Any] = field(default_factory=dict)
    statuses: list[dict[str, Any]] = field(default_factory=list)  # with status_every_s: /dp/status payloads

    # The payloads as dicts are made when first asked for: a study reads the typed measurements and no
    # estimate or command, and making dicts of them all cost the loop about as much as its bookkeeping.
    @cached_property
    def collected(self) -> dict[str, list[dict[str, Any]]]:
        """With ``collect``: topic -> payloads, in order."""
        return {topic: [m.to_dict() for m in ms] for topic, ms in self.collected_messages.items()}

    @cached_property
    def estimates(self) -> list[dict[str, Any]]:
        """/dp/estimate payloads, in order."""
        return [m.to_dict() for m in self.estimate_messages]

    @cached_property
    def commands(self) -> list[dict[str, Any]]:
        """/dp/thrusters/command payloads, in order."""
        return [m.to_dict() for m in self.command_messages]


def gateway_tables(scenario: Scenario, **control: Any) -> dict[str, Any]:
    """A gateway config for a scenario's sensors (what `dpgw demo` builds, without transports). Several
    DGPS or gyros become redundant sources, ranked in the scenario's order (priority 1, 2, …); the
    anemometers of a scenario with wind are ``wind`` sources (the controller's wind feed-forward; ``control``
    ``wind_feedforward_gain=0`` turns it off); its MRUs are ``attitude`` sources (the lever-arm
    compensation by roll and pitch). DP from the first estimate (``initial_mode = "dp"``,
    ``wait_for_observer = false``): no one holds the vessel here while a gateway waits for its observer
    (the scenario's own thrust answers the known mean load only), and the studies measure the control
    from the start; ``control`` ``wait_for_observer=True`` with `run_closed_loop`'s ``hold_on_joystick``
    runs the loop as `dpgw run` starts on a vessel held on joystick."""
    sources: list[dict[str, Any]] = [
        {"name": dgps.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position"],
         "lever_arm_m": list(dgps.lever_arm_m), "timeout_s": max(2.0, 3.0 / dgps.rate_hz), "priority": k + 1}
        for k, dgps in enumerate(scenario.dgps)
    ] + [
        {"name": gyro.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["heading"],
         "priority": k + 1}
        for k, gyro in enumerate(scenario.gyro)
    ] + [
        {"name": a.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["wind"],
         "timeout_s": max(2.0, 3.0 / a.rate_hz), "priority": k + 1}
        for k, a in enumerate(scenario.anemometers)
    ] + [
        {"name": m.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["attitude"],
         "timeout_s": max(0.5, 3.0 / m.rate_hz), "priority": k + 1}
        for k, m in enumerate(scenario.mru)
    ]  # fmt: skip
    if scenario.feedback is not None and scenario.vessel.thrusters:
        sources.append(
            {"name": "thrusters", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]}
        )
    return {
        "vessel": {"name": scenario.vessel.name},
        "datum": {"lat_deg": scenario.datum.lat_deg, "lon_deg": scenario.datum.lon_deg},
        "sources": sources,
        "observer": {"wave_period_s": scenario.sea[0][1].tp_s},
        "control": {"initial_mode": "dp", "wait_for_observer": False, **control},
        "commands": {"accept": ["mode", "setpoint", "tau"]},
        "log": {"path": ""},
    }


def with_scenario_observer(tables: dict[str, Any], scenario: Scenario) -> dict[str, Any]:
    """``tables`` (a gateway config) with the scenario's observer settings (`Scenario.observer_params`) for
    its ``[observer] type`` under the config's own ``params`` (`observers.factory.with_defaults`, the merge
    the study and the replay use): what the in-process loop and ``dpgw demo`` run, so that they run the
    observer a study of the same scenario runs. A new dict; applying it twice changes nothing."""
    observer = dict(tables.get("observer", {}))
    kind = observer.get("type", DEFAULTS["observer"]["type"])
    params = with_defaults(kind, scenario.observer_params.get(kind), observer.get("params", {}))
    if params:
        observer["params"] = params
    return {**tables, "observer": observer}


def _grouped(sim: Simulation, typed: list[tuple[float, int, str, Emission]], sources: Any) -> list[RawEvent]:
    """The typed emissions as pipeline events: one per sentence or frame as on the wire, except that what
    cannot step the observer joins the event before it from the same source at the same instant — the
    unused sentences (RMC, VTG, ZDA, ROT) and a burst's MAVLink frames (heartbeat, the thruster statuses).
    The observer steps, estimates and commands are the same (the pipeline steps once per event, after its
    records, and only for a fix or heading); fewer events and one thruster-feedback output per burst
    instead of one per frame make it cheaper."""
    out: list[RawEvent] = []
    records: list[Any] = []
    key: tuple[float, str] | None = None
    for t, _, name, e in typed:
        if name not in sources:
            continue
        joins = key == (t, name) and (e.protocol == "mavlink" or e.record is None)
        if not joins:
            if key is not None:
                out.append(RawEvent(sim.epoch.stamp_ns(key[0]), key[1], b"", records=tuple(records)))
            key, records = (t, name), []
        records.append(e.record)
    if key is not None:
        out.append(RawEvent(sim.epoch.stamp_ns(key[0]), key[1], b"", records=tuple(records)))
    return out


def true_bias(sim: Simulation) -> Array:
    """The bias an observer should find (earth-fixed [X, Y, N]): the slowly varying Markov force and the
    constant load, plus the mean wave drift (the plant takes it in the body frame) rotated to earth. Exact
    for the model plant; on the full plant current, wind and the nonlinear damping add loads no observer
    model separates, so the figure is NaN there."""
    if sim.scenario.plant != "model":
        return np.full(3, np.nan)
    psi = float(sim.dynamics.x[2])
    c, s = np.cos(psi), np.sin(psi)
    d = sim._drift_body
    return np.asarray(sim.bias.force, dtype=float) + np.array(
        [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]
    )


def is_foxglove_topic(topic: str) -> bool:
    """Whether ``topic`` is one of the Foxglove-native channels (`gateway.foxglove_channels`), which the
    pipeline makes only when asked to."""
    return (message_for_topic(topic).TITLE or "").startswith("foxglove.")


def needs_wire(scenario: Scenario, log: McapLogWriter | None = None) -> bool:
    """Whether the loop must feed the pipeline bytes: a raw log, a wire-side fault (bad checksum, garbage)
    or ArduPilot feedback frames (their meaning depends on the gateway's wiring config)."""
    feedback = scenario.feedback
    return (
        log is not None
        or any(f.kind in ("bad_checksum", "garbage") for f in scenario.faults)
        or (feedback is not None and feedback.ardupilot)
    )


def run_closed_loop(
    scenario: Scenario,
    duration_s: float,
    *,
    seed: int = 0,
    tables: dict[str, Any] | None = None,
    events: list[tuple[float, str, Any]] = (),  # type: ignore[assignment]
    chunk_s: float = 0.1,
    log: McapLogWriter | None = None,
    status_every_s: float | None = None,
    wire: bool | None = None,
    collect: tuple[str, ...] = (),
    hold_on_joystick: bool = False,
    tick: bool = True,
) -> ClosedLoopRun:
    """Run the scenario with the gateway pipeline commanding the thrusters. ``events``: (sim time, key,
    payload) Zenoh inputs such as ("setpoint", {...}) or ("mode", "standby"); the scenario's command faults
    (`FaultSchedule.command_events`) are added to them. With ``log``, every burst sent and the ground truth
    are logged as `dpgw sim --out` does (a log replay can score). With ``status_every_s``, the pipeline's
    /dp/status is kept that often (at the end of a chunk; at most once a chunk) in ``statuses``: what an
    operator station would see, to time alarms. ``wire``: True feeds the pipeline the bytes, False the typed
    records (module docstring); None (default) the records unless a log, a wire-side fault or ArduPilot
    feedback needs the bytes. ``tables`` (default `gateway_tables`) get the scenario's observer settings
    under their own (`with_scenario_observer`), as a study of the scenario does. ``collect``: pipeline
    topics (e.g. "/dp/measurement") whose payloads are kept in ``collected`` (the typed messages in
    ``collected_messages``), in order. ``hold_on_joystick``: until the gateway's first thruster command the
    vessel is held on its station by an operator on joystick, as `dpgw demo` holds it before DP is engaged
    (`Simulation.start_held`, `Simulation.held_tau`). ``tick``: the pipeline ticked once a chunk, as the
    service ticks it (False: never, as a gateway that did not dead-reckon through a silence; for
    `bench/dead_reckoning_control.py`'s comparison)."""
    if wire is None:
        wire = needs_wire(scenario, log)
    tables = with_scenario_observer(tables or gateway_tables(scenario), scenario)
    # the Foxglove-native channels mirror the outputs for a log or a viewer: made only if a caller collects
    # one of them (a study collects /dp/measurement, a JSON channel); the estimates and commands are the same
    # either way
    spec = PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd()))
    pipeline = Pipeline(replace(spec, foxglove_channels=any(map(is_foxglove_topic, collect))))
    commands = _Commands()
    sim: Simulation
    sinks: dict[str, _TimedSink] = {}

    def now() -> float:
        return sim.t

    names = (
        [d.source for d in scenario.dgps]
        + [g.source for g in scenario.gyro]
        + [a.source for a in scenario.anemometers]
        + [m.source for m in scenario.mru]
    )
    routes = []
    typed: list[tuple[float, int, str, Emission]] = []
    if wire:
        for name in names:
            sinks[name] = _TimedSink(now)
            routes.append(Route(sinks[name], "nmea", frozenset({name})))
        sinks["thrusters"] = _TimedSink(now)
        routes.append(Route(sinks["thrusters"], "mavlink"))
        on_emit = None
    else:
        # the bytes path's order: by time, then by sink (NMEA sources in the scenario's order, then MAVLink)
        rank = {name: k for k, name in enumerate(names)}

        def on_emit(e: Emission) -> None:
            typed.append((sim.t, rank.get(e.source, len(rank)), e.source, e))

    if hold_on_joystick:
        from dpgw.station_hold import HOLD_PERIOD_S, froude_scale

        station, period = scenario.eta0, HOLD_PERIOD_S * froude_scale(scenario)
        scenario = replace(scenario, tau=lambda _: sim.held_tau(station, period))
    sim = Simulation(scenario, seed, routes=routes, commands=[commands], log=log, wire=wire, on_emit=on_emit)
    if hold_on_joystick:
        sim.start_held()
    injected = FaultSchedule(scenario.faults).command_events(duration_s)
    pending_events = sorted([*events, *injected], key=lambda e: e[0])
    next_status = 0.0
    t_list, lf, wf = [], [], []
    run = ClosedLoopRun(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    run.collected_messages = {topic: [] for topic in collect}
    nu_list, bias_list = [], []
    while sim.t < duration_s - 1e-9:
        sim.run(chunk_s)
        while pending_events and pending_events[0][0] <= sim.t:
            t_ev, key, payload = pending_events.pop(0)
            pipeline.feed(ControlEvent(sim.epoch.stamp_ns(t_ev), key, payload))
        if wire:
            items = sorted(
                ((t, name, data) for name, s in sinks.items() for t, data in s.items), key=lambda x: x[0]
            )
            for s in sinks.values():
                s.items.clear()
            raw: list[RawEvent] = [
                RawEvent(sim.epoch.stamp_ns(t), name, data)
                for t, name, data in items
                if name in pipeline.sources
            ]
        else:
            typed.sort(key=lambda x: (x[0], x[1]))
            raw = _grouped(sim, typed, pipeline.sources)
            typed.clear()
        # the live service ticks its pipeline between inputs (`Pipeline.tick`): with every position and
        # heading source silent, it dead-reckons and commands on that; the loop ticks once a chunk, at its
        # end, after the chunk's inputs (a tick with data flowing does nothing but the state changes)
        fed = [pipeline.feed(event) for event in raw]
        if tick:
            fed.append(pipeline.tick(sim.epoch.stamp_ns(sim.t)))
        for outputs in fed:
            for o in outputs:
                if o.topic in run.collected_messages:
                    run.collected_messages[o.topic].append(o.message)
                if o.topic == "/dp/estimate":
                    assert isinstance(o.message, messages.Estimate)
                    run.estimate_messages.append(o.message)
                elif o.topic == "/dp/thrusters/command":
                    # (a vessel's thruster ids are integers; the message also allows other systems' names)
                    command = o.message
                    assert isinstance(command, messages.ThrusterCommand)
                    run.command_messages.append(command)
                    if command.thrusters:
                        commands.pending += [
                            ThrusterCommand(int(th.id), th.thrust_n, th.azimuth_rad)
                            for th in command.thrusters
                        ]
                    else:
                        tau = command.tau_allocated
                        commands.pending.append(TauCommand((tau[0], tau[1], tau[2])))
        if status_every_s is not None and sim.t >= next_status - 1e-9 and pipeline.last_ns:
            run.statuses.append(pipeline.status(pipeline.last_ns).payload)
            next_status = sim.t + status_every_s
        x = sim.dynamics.x
        t_list.append(sim.t)
        lf.append(x[0:3].copy())
        wf.append(sim._wf.motion(sim.t, x[0:3]).copy())
        nu_list.append(x[3:6].copy())
        bias_list.append(true_bias(sim))
    run.t = np.array(t_list)
    run.eta_lf = np.array(lf)
    run.eta_wf = np.array(wf)
    run.nu = np.array(nu_list)
    run.bias = np.array(bias_list)
    run.status = pipeline.status(pipeline.last_ns).payload
    return run
