"""The HIL loop in one process: simulator bytes → gateway pipeline → thruster commands → simulator.

The same bytes the simulator would put on the wire are fed to the same pipeline the gateway runs, at the
simulator's times (no transports, no clocks): closed-loop station keeping for tests and studies, fast
and reproducible. `dpgw demo` runs the same loop over real UDP, a pty and MAVLink.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gateway.config import parse_config
from gateway.pipeline import ControlEvent, Pipeline, PipelineSpec, RawEvent
from simulator.commands import Command, TauCommand, ThrusterCommand
from simulator.faults import FaultSchedule
from simulator.runner import Route, Simulation
from simulator.scenarios import Scenario
from simulator.transports import Sink
from wire.mcap.writer import McapLogWriter

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
    estimates: list[dict[str, Any]] = field(default_factory=list)
    commands: list[dict[str, Any]] = field(default_factory=list)
    status: dict[str, Any] = field(default_factory=dict)
    statuses: list[dict[str, Any]] = field(default_factory=list)  # with status_every_s: /dp/status payloads


def gateway_tables(scenario: Scenario, **control: Any) -> dict[str, Any]:
    """A gateway config for a scenario's sensors (what `dpgw demo` builds, without transports). Several
    DGPS or gyros become redundant sources, ranked in the scenario's order (priority 1, 2, …)."""
    sources: list[dict[str, Any]] = [
        {"name": dgps.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position"],
         "lever_arm_m": list(dgps.lever_arm_m), "timeout_s": max(2.0, 3.0 / dgps.rate_hz), "priority": k + 1}
        for k, dgps in enumerate(scenario.dgps)
    ] + [
        {"name": gyro.source, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["heading"],
         "priority": k + 1}
        for k, gyro in enumerate(scenario.gyro)
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
        "control": {"initial_mode": "dp", **control},
        "commands": {"accept": ["mode", "setpoint", "tau"]},
        "log": {"path": ""},
    }


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
) -> ClosedLoopRun:
    """Run the scenario with the gateway pipeline commanding the thrusters. ``events``: (sim time, key,
    payload) Zenoh inputs such as ("setpoint", {...}) or ("mode", "standby"); the scenario's command faults
    (`FaultSchedule.command_events`) are added to them. With ``log``, every burst sent and the ground truth
    are logged as `dpgw sim --out` does (a log replay can score). With ``status_every_s``, the pipeline's
    /dp/status is kept that often (at the end of a chunk; at most once a chunk) in ``statuses``: what an
    operator station would see, to time alarms."""
    tables = tables or gateway_tables(scenario)
    pipeline = Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))
    commands = _Commands()
    sim: Simulation
    sinks: dict[str, _TimedSink] = {}

    def now() -> float:
        return sim.t

    routes = []
    for name in [d.source for d in scenario.dgps] + [g.source for g in scenario.gyro]:
        sinks[name] = _TimedSink(now)
        routes.append(Route(sinks[name], "nmea", frozenset({name})))
    sinks["thrusters"] = _TimedSink(now)
    routes.append(Route(sinks["thrusters"], "mavlink"))
    sim = Simulation(scenario, seed, routes=routes, commands=[commands], log=log)
    injected = FaultSchedule(scenario.faults).command_events(duration_s)
    pending_events = sorted([*events, *injected], key=lambda e: e[0])
    next_status = 0.0
    t_list, lf, wf = [], [], []
    run = ClosedLoopRun(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    while sim.t < duration_s - 1e-9:
        sim.run(chunk_s)
        while pending_events and pending_events[0][0] <= sim.t:
            t_ev, key, payload = pending_events.pop(0)
            pipeline.feed(ControlEvent(sim.epoch.stamp_ns(t_ev), key, payload))
        items = sorted(
            ((t, name, data) for name, s in sinks.items() for t, data in s.items), key=lambda x: x[0]
        )
        for s in sinks.values():
            s.items.clear()
        for t, name, data in items:
            if name not in pipeline.sources:
                continue
            for o in pipeline.feed(RawEvent(sim.epoch.stamp_ns(t), name, data)):
                if o.topic == "/dp/estimate":
                    run.estimates.append(o.payload)
                elif o.topic == "/dp/thrusters/command":
                    run.commands.append(o.payload)
                    if o.payload["thrusters"]:
                        commands.pending += [
                            ThrusterCommand(th["id"], th["thrust_n"], th["azimuth_rad"])
                            for th in o.payload["thrusters"]
                        ]
                    else:
                        tau = o.payload["tau_allocated"]
                        commands.pending.append(TauCommand((tau[0], tau[1], tau[2])))
        if status_every_s is not None and sim.t >= next_status - 1e-9 and pipeline.last_ns:
            run.statuses.append(pipeline.status(pipeline.last_ns).payload)
            next_status = sim.t + status_every_s
        x = sim.dynamics.x
        t_list.append(sim.t)
        lf.append(x[0:3].copy())
        wf.append(sim._wf.motion(sim.t, x[0:3]).copy())
    run.t = np.array(t_list)
    run.eta_lf = np.array(lf)
    run.eta_wf = np.array(wf)
    run.status = pipeline.status(pipeline.last_ns).payload
    return run
