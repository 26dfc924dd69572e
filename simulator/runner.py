"""The simulator's time loop: plant, sea, sensors, faults, transports, ground truth.

Events in sim time, in order: plant steps (≤ 0.05 s, RK4), control ticks (prescribed τ or commands that
came back), sensor samples, emissions leaving the sensors after their latency, truth records. On a
`VirtualClock` it runs as fast as the CPU allows; on a `RealtimeClock` every emission is written at its
wall time. Every byte sent is also logged to MCAP (`/raw/nmea/<source>`, `/raw/mavlink/<source>`) with the
ground truth (`/truth/state`, DESIGN.md) so a run can be replayed and scored.

The wave-frequency motion (RAO × spectrum, `simulator.waves`) is added to the low-frequency motion for the
sensors only — it is never fed back into the plant (the LF/WF superposition of Fossen & Strand Sec. 2.4).
It is evaluated in 2 s blocks on the 0.05 s grid with the heading and position at the block's start, and
interpolated linearly to the sample times (error ~0.1 % for wave periods above 3 s): one compiled call
per block (`WaveField.motion_block`, a carrier recurrence; numpy's `motion_with_attitude` is its readable
reference) instead of one per sample. The same call gives the WF heave, roll and pitch: the sensors see the
vessel's six-degree-of-freedom WF motion (a DGPS antenna on a mast swings with roll and pitch), and the
truth logs exactly what they see — η_WF and the attitude of the reference point, and each antenna's true
position — so measurement − truth is the sensor's noise and nothing else.
"""

from __future__ import annotations

import heapq
import json
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import rotation, ssa_scalar
from simulator._advance_kernel import advance as advance_kernel
from simulator._full_advance_kernel import advance_full as advance_full_kernel
from simulator.clock import Clock, SimEpoch, VirtualClock
from simulator.commands import Command, TauCommand
from simulator.environment import MarkovBias
from simulator.faults import FaultSchedule
from simulator.plant import FullPlant
from simulator.plant_env import PlantEnvironment
from simulator.scenarios import Scenario, ShipNow
from simulator.sensors import (
    Anemometer,
    Dgps,
    Emission,
    Gyro,
    Mru,
    ShipState,
    ThrusterFeedback,
    ThrusterReading,
    antenna_ned_floats,
)
from simulator.spectra import SeaState
from simulator.thrusters import PrescribedAllocation, ThrusterBank
from simulator.transports import Sink
from simulator.vessel_dynamics import MAX_STEP_S, VesselDynamics
from simulator.waves import WaveField, WaveResponse
from wire.mcap.writer import McapLogWriter
from wire.messages import SIM_METADATA, TruthState

Array = NDArray[np.float64]

WF_BLOCK_S = 2.0
COMMAND_TIMEOUT_S = 2.0


class CommandInput(Protocol):
    def poll(self) -> list[Command]: ...


@mypyc_attr(native_class=False)
@dataclass
class Route:
    """Where emissions go: a sink for some sources (None = every source of that protocol)."""

    sink: Sink
    protocol: str  # "nmea" | "mavlink"
    sources: frozenset[str] | None = None

    def wants(self, e: Emission) -> bool:
        return e.protocol == self.protocol and (self.sources is None or e.source in self.sources)


@mypyc_attr(native_class=False)
@dataclass
class SimSummary:
    scenario: str
    seed: int
    sim_seconds: float
    wall_seconds: float
    emissions: Counter[str] = field(default_factory=Counter)
    bytes_sent: Counter[str] = field(default_factory=Counter)
    not_sent: Counter[str] = field(default_factory=Counter)
    """Per source: emissions no route took (``dpgw sim --nmea pty`` without ``--mavlink``: the thrusters'
    frames are made, and logged, but go nowhere)."""
    commands_applied: int = 0
    truth_records: int = 0

    @property
    def speedup(self) -> float:
        return self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else math.inf

    def as_dict(self) -> dict[str, object]:
        return {
            "scenario": self.scenario,
            "seed": self.seed,
            "sim_seconds": self.sim_seconds,  # (`Simulation.seconds`: to the ns)
            "wall_seconds": self.wall_seconds,
            "speedup": self.speedup,
            "emissions": dict(self.emissions),
            "bytes_sent": dict(self.bytes_sent),
            "not_sent": dict(self.not_sent),
            "commands_applied": self.commands_applied,
            "truth_records": self.truth_records,
        }


class _WaveCache:
    """WF motion on the plant grid, one 2 s block at a time (see module docstring)."""

    def __init__(self, field: WaveField) -> None:
        self.field = field
        self.t0 = math.inf
        self.values = np.zeros((1, 6))
        self._last: tuple[float, Array] = (math.nan, np.zeros(6))

    def motion(self, t: float, eta_lf: Array) -> Array:
        """η_WF = [N, E, ψ] at t."""
        return self.motion6(t, eta_lf)[:3]

    def attitude(self, t: float, eta_lf: Array) -> Array:
        """WF [heave (down), roll, pitch] of the reference point at t."""
        return self.motion6(t, eta_lf)[3:]

    def motion6(self, t: float, eta_lf: Array) -> Array:
        """[N, E, ψ, z, φ, θ] at t (sensors and truth ask for the same instant: the last answer is kept)."""
        if t == self._last[0]:
            return self._last[1]
        if not (self.t0 <= t <= self.t0 + WF_BLOCK_S):
            self.t0 = t
            n = round(WF_BLOCK_S / MAX_STEP_S) + 1  # the block's grid t, t + 0.05, …, t + 2 s
            x0, x1, x2 = eta_lf.tolist()
            self.values = self.field.motion_block(t, MAX_STEP_S, n, x2, x0, x1)
        x = (t - self.t0) / MAX_STEP_S
        i = min(int(x), len(self.values) - 2)
        w = x - i
        value = (1 - w) * self.values[i] + w * self.values[i + 1]
        self._last = (t, value)
        return value


class Simulation:
    """One run of a scenario. ``routes`` send emissions to transports; ``log`` gets everything."""

    TIME_TICK_S: ClassVar[float] = 0.05  # (ClassVar: compiled, a plain name would be an instance field)
    """The longest sim time between two `on_time` calls (20 Hz of sim time)."""

    def __init__(
        self,
        scenario: Scenario,
        seed: int = 0,
        *,
        routes: Sequence[Route] = (),
        log: McapLogWriter | None = None,
        clock: Clock | None = None,
        commands: Sequence[CommandInput] = (),
        log_raw: bool = True,
        wire: bool = True,
        on_emit: Callable[[Emission], None] | None = None,
        signing_key: bytes | None = None,
    ) -> None:
        """``signing_key``: the simulated thruster drives sign every MAVLink frame they send with this
        32-byte MAVLink 2 key (`ThrusterFeedback.sign_with`; give the same key to their
        `simulator.commands.MavlinkCommandInput`, which then takes signed commands only).

        ``wire=False``: the sensors send typed records (`Emission.record`) instead of bytes, for an
        in-process receiver that hands them to ``on_emit`` (called for every emission as it leaves, after
        the routes); there are then no bytes to route, log or corrupt, so it refuses routes, a raw log,
        the wire-side faults and ArduPilot feedback (whose meaning depends on the receiver's wiring)."""
        if not wire:
            wire_faults = sorted({f.kind for f in scenario.faults if f.kind in ("bad_checksum", "garbage")})
            feedback = scenario.feedback
            ardupilot = feedback is not None and feedback.ardupilot
            problem = (
                "routes" if routes else
                "a raw log (log_raw=True)" if log is not None and log_raw else
                f"{', '.join(wire_faults)} faults" if wire_faults else
                "ArduPilot feedback frames" if ardupilot else
                "signed feedback (signing_key)" if signing_key is not None else None
            )  # fmt: skip
            if problem:
                raise ValueError(f"Simulation(wire=False): {problem} need the bytes; use wire=True")
        self.wire = wire
        self.on_emit = on_emit
        self.scenario = scenario
        self.log_raw = log_raw
        self.seed = seed
        self.routes = list(routes)
        self.log = log
        if log is not None:
            # what a replay needs to score this log: the frame the truth is in, and what made it
            d = scenario.datum
            log.add_metadata(
                SIM_METADATA,
                {
                    "scenario": scenario.name,
                    "seed": str(seed),
                    "vessel": scenario.vessel.name,
                    "datum": json.dumps({"lat_deg": d.lat_deg, "lon_deg": d.lon_deg, "alt_m": d.alt_m}),
                },
            )
        self.clock = clock or VirtualClock()
        self.commands = list(commands)
        self.epoch = SimEpoch(scenario.start_utc)
        ss = np.random.SeedSequence(seed)
        wave_seq, bias_seq, sensor_seq, fault_seq = ss.spawn(4)
        vessel = scenario.vessel

        self.waves = WaveField(
            list(scenario.sea),
            WaveResponse.for_vessel(vessel),
            seed=int(wave_seq.generate_state(1)[0]),
        )
        if scenario.wave_motion_limits is not None:
            t_grid = np.arange(0.0, min(scenario.duration_s, 1800.0), 0.5)
            gain = self.waves.gain_for_limits(scenario.wave_motion_limits, t_grid, scenario.eta0[2])
            self.waves = self.waves.with_motion_gain(gain)
        self._wf = _WaveCache(self.waves)

        self.dynamics: VesselDynamics | FullPlant
        self.plant_env: PlantEnvironment | None = None
        if scenario.plant == "full":  # its own streams, spawned after the others: those stay as they were
            self.dynamics = FullPlant(vessel, scenario.eta0, scenario.nu0, scenario.plant_options)
            self.plant_env = PlantEnvironment(vessel, scenario.current, scenario.wind, ss.spawn(1)[0])
        else:
            self.dynamics = VesselDynamics(vessel, scenario.eta0, scenario.nu0)
        self.bias = MarkovBias(scenario.bias, np.random.default_rng(bias_seq))
        self.thrusters = ThrusterBank(vessel)
        self.allocate = PrescribedAllocation(vessel) if self.thrusters.n else None
        self.direct_tau = self.thrusters.n == 0  # a vessel without a layout: τ acts directly (papers' sims)
        self.tau_direct = np.zeros(3)
        self.fused_plant = True
        """False: the plant steps in Python (`_advance_reference`), for tests that compare the two."""
        self._full_args: tuple[object, ...] = ()
        self._thruster_kinds = [t.kind for t in vessel.thrusters]
        self._lever_arms = [(d.source, *d.lever_arm_xyz) for d in scenario.dgps]
        """(source, x, y, z) of each DGPS antenna, for the truth."""

        self.faults = FaultSchedule(scenario.faults)
        self._failure_faults = any(f.kind == "thruster_failure" for f in scenario.faults)
        self.fault_rng = np.random.default_rng(fault_seq)
        sensor_rngs = [np.random.default_rng(s) for s in sensor_seq.spawn(8)]
        self.sensors: list[Dgps | Gyro | ThrusterFeedback | Anemometer | Mru] = []
        for k, cfg in enumerate(scenario.dgps):
            self.sensors.append(Dgps(cfg, scenario.datum, self.epoch, sensor_rngs[k], self.faults))
        for k, gcfg in enumerate(scenario.gyro):
            self.sensors.append(Gyro(gcfg, self.epoch, sensor_rngs[4 + k], self.faults))
        if scenario.feedback is not None and self.thrusters.n:
            limits = {t.id: (t.min_thrust_n, t.max_thrust_n) for t in vessel.thrusters}
            drive = ThrusterFeedback(
                scenario.feedback, self.epoch, sensor_rngs[7], self.faults, thrust_limits_n=limits
            )
            if signing_key is not None:
                drive.sign_with(signing_key)
            self.sensors.append(drive)
        if self.plant_env is not None and self.plant_env.wind is not None:
            wind = self.plant_env.wind
            model = wind.model

            def wind_at(t: float) -> tuple[float, float]:
                return wind.speed(t), model.from_deg

            # their own streams, spawned after all others (adding an anemometer changes no other stream)
            for acfg, aseq in zip(scenario.anemometers, ss.spawn(len(scenario.anemometers)), strict=True):
                self.sensors.append(Anemometer(acfg, wind_at, np.random.default_rng(aseq), self.faults))
        # MRUs: their own streams, spawned after all others (adding one changes no other stream)
        for mcfg, mseq in zip(scenario.mru, ss.spawn(len(scenario.mru)), strict=True):
            self.sensors.append(Mru(mcfg, self.epoch, np.random.default_rng(mseq), self.faults))
        for sensor in self.sensors:
            sensor.encode = wire

        self._sensors_seen: list[Dgps | Gyro | ThrusterFeedback | Anemometer | Mru] = []
        self._sensor_kinds: list[tuple[Dgps | Gyro | ThrusterFeedback | Anemometer | Mru, bool]] = []
        self.t = 0.0
        self._sea_valid = (math.inf, -math.inf)
        self._sea_cached = scenario.sea[0][1]
        self._drift_body = np.zeros(3)
        self._pending: list[tuple[float, int, Emission]] = []
        self._seq = 0
        self._last_command_t = -math.inf
        self._next_truth: float | None = None
        self._next_drift: float | None = None
        self.external_control = False
        feedback = scenario.feedback
        self._stops_on_command_loss = feedback is not None and feedback.on_command_loss == "stop"
        self.summary = SimSummary(scenario.name, seed, 0.0, 0.0)
        self.on_time: Callable[[float], None] | None = None
        """Called with the sim time after every advance, before what is due then is sampled or sent, and
        at least every `time_tick_s` of sim time: a simulation clock on a bus (`simulator.sim_clock`)."""
        self.time_tick_s = self.TIME_TICK_S

    # --- plant --------------------------------------------------------------------------------------

    def _advance(self, h: float) -> None:
        n = max(1, math.ceil(h / MAX_STEP_S - 1e-9))
        hs = h / n
        if not self.fused_plant:
            self._advance_reference(n, hs)
        elif self.plant_env is not None:
            self._advance_full(n, hs)
        else:
            self._advance_fused(n, hs)
        self.t += h

    def _advance_fused(self, n: int, hs: float) -> None:
        """`_advance_reference` for the low-frequency plant, in one compiled call per block of bias draws
        (`simulator._advance_kernel`; the same bits)."""
        bias, th, dyn = self.bias, self.thrusters, self.dynamics
        assert isinstance(dyn, VesselDynamics)
        decay, kick = bias.factors(hs)
        m = max(1, math.ceil(hs / MAX_STEP_S - 1e-9))  # VesselDynamics.step's own split (always 1 here)
        while n > 0:
            normals, k = bias.draws()
            chunk = min(n, len(normals) - k)
            k = advance_kernel(
                chunk, hs, m, dyn.x, dyn._Minv, dyn._D,
                not self.direct_tau, th.thrust, th.angle, th.thrust_setpoint, th.angle_setpoint, th.failed,
                th.is_azimuth, th.time_constant, th.rate, th.x, th.y,
                self.tau_direct, self._drift_body, bias.b, bias.constant, decay, kick, normals, k,
            )  # fmt: skip
            bias.took(k)
            n -= chunk

    def _advance_full(self, n: int, hs: float) -> None:
        """`_advance_reference` for the full plant, in one compiled call per block of bias draws and per
        step of the current (`simulator._full_advance_kernel`; the same bits). The current steps in Python
        (`Current.step`, once a second): the kernel stops before the substep at which it falls due."""
        env, bias, th = self.plant_env, self.bias, self.thrusters
        assert env is not None
        decay, kick = bias.factors(hs)
        m = max(1, math.ceil(hs / MAX_STEP_S - 1e-9))  # FullPlant.step's own split (always 1 here)
        env.wind_parameters(self.t, n * hs)  # the reference asks the wind at self.t for every substep
        fixed = self._full_args or self._full_fixed_args()
        kernel: Callable[..., tuple[int, int]] = advance_full_kernel  # (a numba dispatcher: untyped)
        stepped = False
        while n > 0:
            normals, k = bias.draws()
            chunk = min(n, len(normals) - k)
            k, done = kernel(
                chunk, hs, m, *fixed, th.thrust_setpoint, th.angle_setpoint, self.tau_direct,
                self._drift_body, bias.b, decay, kick, normals, k, stepped, env.current_ned,
            )  # fmt: skip
            bias.took(k)
            n -= done
            stepped = False
            if done < chunk:  # the current fell due before substep `done`: step it, then go on from there
                env.step_current()
                stepped = True

    def _full_fixed_args(self) -> tuple[object, ...]:
        """The compiled full-plant advance's arguments that stay the same objects for the whole run (the
        arrays it updates in place and the constants), gathered once."""
        env, th, dyn = self.plant_env, self.thrusters, self.dynamics
        assert env is not None and isinstance(dyn, FullPlant)
        self._full_args = (
            dyn.x, dyn._s, *dyn._arrays,
            not self.direct_tau, th.thrust, th.angle, th.failed, th.is_azimuth, th.time_constant, th.rate,
            th.x, th.y,
            self.bias.constant, env.current is not None, env.wind is not None, env.wind_p, env.wind_body,
            env.due, env.due_thresholds,
        )  # fmt: skip
        return self._full_args

    def _advance_reference(self, n: int, hs: float) -> None:
        """n plant substeps of hs: thrusters, bias, dynamics, one Python call each (the readable form)."""
        for _ in range(n):
            if self.direct_tau:
                tau = self.tau_direct
            else:
                self.thrusters.step(hs)
                tau = self.thrusters.tau
            self.bias.step(hs)
            if self.plant_env is None:
                self.dynamics.step(hs, tau + self._drift_body, self.bias.force)
            else:
                self._full_step(hs, tau)

    def _full_step(self, h: float, tau: Array) -> None:
        env = self.plant_env
        assert env is not None and isinstance(self.dynamics, FullPlant)
        env.step(h, self.t, self.dynamics.x)
        self.dynamics.step(h, tau + self._drift_body + env.wind_body, self.bias.force, env.current_ned)

    def _mean_load_body(self) -> Array:
        return self._load_body(self.bias.constant)

    def held_load_body(self) -> Array:
        """The slowly varying load on the vessel now, body frame: the whole bias (its Markov part too), the
        mean wave drift and, on the full plant, the mean wind and the current's load. What an operator
        holding the vessel by joystick answers, and a thrust of minus it holds the vessel still but for
        the waves and gusts for a while, but it has no spring: what it leaves drifts the vessel off
        (`held_tau` adds the operator's correction; `dpgw demo` holds the vessel so until DP is engaged)."""
        return self._load_body(self.bias.force)

    def held_tau(self, station: ArrayLike, period_s: float) -> Array:
        """τ of an operator holding the vessel by joystick on ``station`` [N, E, ψ]: minus the slowly varying
        load (`held_load_body`), and the operator's slow correction of the LF position and heading off the
        station, critically damped with the natural period ``period_s`` (τ = −load − M(ω²Rᵀe + 2ων)). Without
        the correction a hold has no spring: on the full plant with its current a residual of ~1 % of the
        load (the gusts' mean over a minute or two, the thrusters' lag behind the load) moved the vessel
        off at a steady 0.1 m/s, 16 m in 150 s on `mss_supply_storm`. (A model of no paper: an operator who
        watches the vessel and answers its drift slowly, not a DP controller.)"""
        w = 2.0 * math.pi / period_s
        x = self.dynamics.x
        e = x[0:3] - np.asarray(station, dtype=float)
        e[2] = ssa_scalar(float(e[2]))
        off_body = rotation(float(x[2])).T @ e
        correction = self.scenario.vessel.M @ (w * w * off_body + 2.0 * w * x[3:6])
        return np.asarray(-self.held_load_body() - correction)

    def start_held(self) -> None:
        """Start with the vessel held against its load, as a vessel on joystick is before DP is engaged:
        the thrusters (or τ, without a layout) already deliver minus `held_load_body`, at their setpoints,
        instead of starting at rest in the full load. Before the first `run`."""
        tau = -self.held_load_body()
        if self.allocate is None:
            self.tau_direct = tau
            return
        thrust, angle = self.allocate(tau)
        self.thrusters.command(thrust, angle)
        self.thrusters.thrust[:] = self.thrusters.thrust_setpoint
        self.thrusters.angle[:] = self.thrusters.angle_setpoint

    def _load_body(self, bias_earth: Array) -> Array:
        psi = self.dynamics.x[2]
        load = rotation(psi).T @ bias_earth + self._drift_body
        if self.plant_env is not None and isinstance(self.dynamics, FullPlant):
            load = (
                load
                + self.plant_env.mean_wind_body(psi)
                + self.dynamics.current_load(self.plant_env.current_ned)
            )
        return load

    def _control_tick(self) -> None:
        if self._failure_faults:
            for i, tid in enumerate(self.thrusters.ids):
                self.thrusters.failed[i] = (
                    self.faults.active("thruster_failure", str(tid), self.t) is not None
                )
        for source in self.commands:
            for cmd in source.poll():
                if isinstance(cmd, TauCommand):
                    if self.direct_tau:  # a vessel without thrusters takes τ itself
                        self.tau_direct = np.asarray(cmd.tau, dtype=float)
                        self.summary.commands_applied += 1
                        self._last_command_t = self.t
                        self.external_control = True
                    continue
                if cmd.id in self.thrusters.ids:
                    self.thrusters.command_one(cmd.id, cmd.thrust_n, cmd.azimuth_rad)
                    self.summary.commands_applied += 1
                    self._last_command_t = self.t
                    self.external_control = True
        if self.external_control:
            # Commands stopped for COMMAND_TIMEOUT_S: most DP drives hold their last command; drives whose
            # comms-loss action is to stop (a fieldbus watchdog, an ArduPilot failsafe) go to zero thrust,
            # the azimuths where they are (`ThrusterFeedbackConfig.on_command_loss`).
            if self._stops_on_command_loss and self.command_timed_out:
                self.thrusters.command(np.zeros(self.thrusters.n), self.thrusters.angle_setpoint)
            return
        tau = self.scenario.tau(ShipNow(self.t, self.dynamics.eta, self.dynamics.nu, self._mean_load_body()))
        if self.allocate is None:
            self.tau_direct = np.asarray(tau, dtype=float)
        else:
            thrust, angle = self.allocate(tau)
            self.thrusters.command(thrust, angle)

    @property
    def command_timed_out(self) -> bool:
        return self.external_control and self.t - self._last_command_t > COMMAND_TIMEOUT_S

    # --- sensing --------------------------------------------------------------------------------------

    def ship_state(self, with_thrusters: bool = True) -> ShipState:
        eta_lf = self.dynamics.x[0:3]
        wf6 = self._wf.motion6(self.t, eta_lf)
        eta = eta_lf + wf6[:3]
        eta[2] = ssa_scalar(eta[2])
        readings: tuple[ThrusterReading, ...] = ()
        if with_thrusters and self.thrusters.n:
            # each array once, as Python floats (rpm and power are computed properties)
            th = self.thrusters
            kinds = self._thruster_kinds
            readings = tuple(
                map(
                    ThrusterReading.trusted,
                    th.ids,
                    kinds,
                    th.thrust.tolist(),
                    th.angle.tolist(),
                    th.rpm.tolist(),
                    th.thrust_setpoint.tolist(),
                    th.angle_setpoint.tolist(),
                    th.failed.tolist(),
                    th.power_w.tolist(),
                )
            )  # fmt: skip  (every list has one element per thruster)
        return ShipState.trusted(self.t, eta, self.dynamics.x[3:6].copy(), readings, wf6[3:].copy())

    def _sea_state(self) -> SeaState:
        """The current sea state; it changes only at the schedule's switch times (mid-fade), so cache it."""
        if not (self._sea_valid[0] <= self.t < self._sea_valid[1]):
            sea = self.waves.sea_state_at(self.t)
            starts = [t0 for t0, _ in self.scenario.sea]
            mids = [t0 + self.waves.fade_s / 2 for t0 in starts[1:]]
            lo = max([m for m in mids if m <= self.t], default=-math.inf)
            hi = min([m for m in mids if m > self.t], default=math.inf)
            self._sea_cached, self._sea_valid = sea, (lo, hi)
        return self._sea_cached

    def _truth(self) -> None:
        if self.log is None:
            return
        x = self.dynamics.x
        wf6 = self._wf.motion6(self.t, x[0:3])
        xs = x.tolist()  # plain floats (the same doubles as the arrays' elements, cheaper arithmetic)
        wf, attitude = wf6[:3].tolist(), wf6[3:].tolist()
        north, east, psi = xs[0] + wf[0], xs[1] + wf[1], xs[2] + wf[2]
        antennas = {
            source: list(antenna_ned_floats(north, east, psi, ax, ay, az, *attitude))
            for source, ax, ay, az in self._lever_arms
        }
        c, s = math.cos(xs[2]), math.sin(xs[2])
        d = self._drift_body if self.plant_env is None else self._drift_body + self.plant_env.wind_body
        d0, d1, d2 = d.tolist()
        b0, b1, b2 = self.bias.force.tolist()
        bias_total = [b0 + c * d0 - s * d1, b1 + s * d0 + c * d1, b2 + d2]
        sea = self._sea_state()
        w0 = sea.peak_frequency
        tau = self.tau_direct if self.direct_tau else self.thrusters.tau
        stamp = self.epoch.stamp_ns(self.t)
        truth = TruthState(
            stamp_ns=stamp,
            eta_lf=[xs[0], xs[1], ssa_scalar(xs[2])],
            nu=xs[3:6],
            bias=bias_total,
            eta_wf=wf,
            wf_attitude=attitude,
            antennas=antennas,
            omega0=[w0, w0, w0],
            tau=tau.tolist(),
            hs_m=sea.hs_m,
        )
        self.log.write("/truth/state", truth, stamp, stamp)
        self.summary.truth_records += 1

    def _emit_due(self) -> None:
        """Send every emission that is due. The log gets one message per burst (a sensor's frames of one
        instant, like a multiplexer's datagram); the transports get each sentence or frame on its own."""
        burst: list[Emission] = []
        first: Emission | None = None
        paced = not isinstance(self.clock, VirtualClock)  # a virtual clock never waits
        pending, routes, on_emit, limit = self._pending, self.routes, self.on_emit, self.t + 1e-9
        while pending and pending[0][0] <= limit:
            e = heapq.heappop(pending)[2]
            if first is not None and (
                e.source != first.source or e.t_emit != first.t_emit or e.protocol != first.protocol
            ):
                self._end_burst(burst)
                burst = []
                first = None
            if paced:
                self.clock.sleep_until(e.t_emit)
            sent = False
            for route in routes:
                if route.wants(e):
                    route.sink.write(e.data)
                    sent = True
            if not sent:
                self.summary.not_sent[e.source] += 1
            if on_emit is not None:
                on_emit(e)
            burst.append(e)
            if first is None:
                first = e
        if burst:
            self._end_burst(burst)

    def _end_burst(self, burst: list[Emission]) -> None:
        first = burst[0]
        data = b"".join([e.data for e in burst])
        self.summary.emissions[first.source] += len(burst)
        self.summary.bytes_sent[first.source] += len(data)
        if self.log is None or not self.log_raw:
            return
        log_ns = self.epoch.stamp_ns(first.t_emit)
        pub_ns = self.epoch.stamp_ns(first.t_measured)
        if first.protocol == "nmea":
            self.log.write_raw_nmea(first.source, data, log_ns, pub_ns)
        else:
            self.log.write_raw_mavlink(first.source, data, log_ns, pub_ns)

    # --- the loop ---------------------------------------------------------------------------------------

    @property
    def seconds(self) -> float:
        """The simulation time as reports give it, to the nanosecond (the resolution of every stamp):
        `t` is a sum of steps, 199.99999999999042 after 200 s of 0.05 s steps."""
        return round(self.t, 9)

    def run(
        self, duration_s: float | None = None, progress: Callable[[float], None] | None = None
    ) -> SimSummary:
        end = self.t + (duration_s if duration_s is not None else self.scenario.duration_s)
        truth_dt = 1.0 / self.scenario.truth_rate_hz
        ctrl_dt = 1.0 / self.scenario.control_rate_hz
        # The truth and the drift force keep their schedules from one run() to the next, so a run in
        # chunks (the closed loop's 0.1 s) logs each truth record once and updates the drift force at
        # 1 Hz like one long run. Every run() starts with a control tick: commands that came in between
        # chunks act at once.
        next_truth = self.t if self._next_truth is None else self._next_truth
        next_drift = self.t if self._next_drift is None else self._next_drift
        next_ctrl = self.t
        next_progress = self.t
        next_time = self.t
        wall0 = time.perf_counter()
        eps = 1e-9
        if self._sensors_seen != self.sensors:  # (an isinstance on a Protocol's subclass is slow: once)
            self._sensors_seen = list(self.sensors)
            self._sensor_kinds = [(s, isinstance(s, ThrusterFeedback)) for s in self.sensors]
        sensors = self._sensor_kinds
        next_times = [s.next_time for s in self.sensors]
        pending = self._pending
        apply_faults, fault_rng = self.faults.apply_to_emissions, self.fault_rng
        while True:
            # the sensors' next instants: nothing but their own samples moves them, so the values found
            # here also say which are due after the advance
            times = [f() for f in next_times]
            t_next = min(next_truth, next_ctrl, next_drift, end, *times)
            if self.on_time is not None and next_time < t_next:
                t_next = next_time
            if pending and pending[0][0] < t_next:
                t_next = pending[0][0]
            if t_next > self.t:
                self._advance(t_next - self.t)
            if self.on_time is not None:
                self.on_time(self.t)
                while next_time <= self.t + eps:
                    next_time += self.time_tick_s
            if self.t >= next_drift - eps:
                eta = self.dynamics.x
                self._drift_body = self.waves.drift_force(np.array([self.t]), eta[2], eta[0], eta[1])[0]
                next_drift += 1.0
            if self.t >= next_ctrl - eps:
                self._control_tick()
                next_ctrl += ctrl_dt
            state: ShipState | None = None  # built once per instant; thruster readings only for feedback
            due = self.t + eps
            for (sensor, feedback), t_sensor in zip(sensors, times, strict=True):
                if t_sensor > due:
                    continue
                while True:
                    if feedback:
                        emissions = sensor.sample(self.ship_state(with_thrusters=True))
                    else:
                        if state is None:
                            state = self.ship_state(with_thrusters=False)
                        emissions = sensor.sample(state)
                    for e in apply_faults(emissions, fault_rng):
                        heapq.heappush(pending, (e.t_emit, self._seq, e))
                        self._seq += 1
                    if sensor.next_time() > due:
                        break
            if pending and pending[0][0] <= due:
                self._emit_due()
            if self.t >= next_truth - eps:
                self._truth()
                next_truth += truth_dt
            if progress is not None and self.t >= next_progress:
                progress(self.t)
                next_progress += 10.0
            if self.t >= end - eps:
                break
        self._next_truth, self._next_drift = next_truth, next_drift
        self.summary.sim_seconds = self.seconds
        self.summary.wall_seconds += time.perf_counter() - wall0
        return self.summary
