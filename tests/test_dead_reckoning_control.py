"""DP through a total silence: with every position and heading source silent, the live gateway goes on
commanding the thrusters on its dead-reckoned estimate at the control rate (before, no control step ran
and no command went out), logs the ticks at which it did so on ``/dp/tick``, and a replay of its log ticks
there too, so that it commands what the live run commanded, through the silence and after it.

A real gateway: UDP input, its consumer loop and clock, a real MCAP log, then `run_replay` on that log; and
the in-process closed loop of the studies, which ticks its pipeline as the service does."""

from __future__ import annotations

import contextlib
import io
import json
import socket
import threading
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import free_port, stop_service, wait_for

from dpgw.cli import main
from dpgw.closed_loop import run_closed_loop
from gateway.config import parse_config
from gateway.replay import build_pipeline, config_from_log, open_inputs, run_replay
from gateway.service import GatewayService
from simulator.clock import SimEpoch
from simulator.faults import Fault
from simulator.scenarios import get_scenario
from tests.test_service import mux_tables
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter

S = 1_000_000_000


def burst() -> bytes:
    return (enc.gga("GP", datetime.now(UTC), 59.4, 10.5, 2, 12, 0.8, 20.0) + enc.hdt("HE", 0.5)).encode()


def commands(path: Path) -> list[tuple[int, dict[str, Any]]]:
    return [(ns, p) for _, ns, _, p in read_messages(path, "/dp/thrusters/command")]


def test_dp_commands_through_a_total_silence_and_a_replay_commands_the_same(tmp_path: Path) -> None:
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    path = tmp_path / "live.mcap"
    tables = mux_tables(udp, zport, path, status_hz=2.0)
    tables["sources"][0]["timeout_s"] = 0.3
    tables["control"] = {"initial_mode": "dp", "wait_for_observer": False}
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    p, mux = service.pipeline, service.pipeline.counters["mux"]

    def data_until(estimates: int) -> None:
        def sent() -> bool:
            tx.sendto(burst(), ("127.0.0.1", udp))
            return p.estimates >= estimates

        assert wait_for(sent, 30.0), "estimates"

    try:
        data_until(30)
        # silent: the gateway's clock steps the control, 1.5 s of it past the source's timeout
        assert wait_for(lambda: p._last_control_ns - mux.last_rx_ns > 1.8 * S, 30.0), "control in the silence"
        silence = (mux.last_rx_ns, p._last_control_ns)
        data_until(p.estimates + 20)
    finally:
        tx.close()
        stop_service(service, loop)

    live = commands(path)
    in_silence = [(ns, c) for ns, c in live if silence[0] + 0.3 * S < ns <= silence[1]]
    # ~15 at 10 Hz in 1.5 s (a busy machine ticks late, never more often)
    assert len(in_silence) >= 5, [ns - silence[0] for ns, _ in live[-30:]]
    assert all(c["mode"] == "dp" and len(c["thrusters"]) == 6 for _, c in in_silence)
    ticks = [ns for _, ns, _, _ in read_messages(path, "/dp/tick")]
    assert {ns for ns, _ in in_silence} <= set(ticks)
    assert all(silence[0] < ns for ns in ticks)
    # the silence's estimates were dead-reckoned (the alarm's words: docs/gateway.md)
    statuses = [e["status"] for _, ns, _, e in read_messages(path, "/dp/estimate") if ns in set(ticks)]
    assert statuses and set(statuses) <= {"dead_reckoning", "lost"}

    out_path = tmp_path / "replay.mcap"
    with McapLogWriter(str(out_path), profile="dpgw") as out:
        run_replay(open_inputs([path]), build_pipeline(config_from_log(path), [], controller=True), out=out)
    replayed = commands(out_path)
    # every command, through the silence and after it (the controller and the allocation moved on at the
    # ticks), as the live gateway sent it
    assert len(replayed) == len(live)
    assert replayed == live
    # the replay's log holds the ticks too, so it replays as the live log does (before, it held no
    # /dp/tick, and a replay of it sent no command through the silence)
    assert [ns for _, ns, _, _ in read_messages(out_path, "/dp/tick")] == ticks
    again = tmp_path / "again.mcap"
    with McapLogWriter(str(again), profile="dpgw") as out:
        run_replay(
            open_inputs([out_path]), build_pipeline(config_from_log(path), [], controller=True), out=out
        )
    assert commands(again) == live

    # how DP did, from the live log, in the replay's summary and report (`gateway.report.station_keeping`)
    report = tmp_path / "report"
    cli_out = tmp_path / "cli.mcap"
    argv = ["replay", str(path), "--out", str(cli_out), "--json", "--report", str(report)]
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        assert main(argv) == 0
    dp = json.loads(printed.getvalue())["dp_performance"]
    assert dp["modes"]["from"] == "statuses" and dp["modes"]["time_s"]["dp"] > 2.0, dp["modes"]
    sk = dp["station_keeping"]
    assert sk["commands"] >= len(live) - 5 and sk["position_error_m"]["max"] >= sk["position_error_m"]["p95"]
    # a few seconds in dp: too short for a wave-band figure (less than one period of the band's lower edge)
    assert dp["wave_filtering"] is None
    dr = dp["dead_reckoning"]
    assert dr["spells"] >= 1 and dr["longest_s"] >= 1.0 and dr["in_dp_s"] >= 1.0, dr
    spell = max(dr["list"], key=lambda x: x["to_s"] - x["from_s"])
    assert spell["mode"] == "dp"
    levels = {a["key"].split(" for ")[0]: a["level"] for a in dp["alarms"]}
    assert levels.get("estimate dead reckoning") == "critical", dp["alarms"]
    md = (report / "report.md").read_text()
    assert "## DP performance (the live gateway's log)" in md and "| critical | estimate dead reckoning" in md


def test_the_closed_loop_keeps_commanding_through_a_total_silence_and_keeps_station() -> None:
    """Every sensor of torsetnes_2004 drops out for 20 s at 200 s (settled, in DP). The loop ticks its
    pipeline once a chunk as the service ticks it: the estimates go on, dead-reckoned, and the commands at
    10 Hz (before, none went out for those 20 s and the simulated drives held their last command). Station
    keeping over the silence and the 20 s after stays within the 40 s before it (measured, seeds 0-5: at
    most 1.01x; holding the last command gave the same within the seeds' spread: this simulator's drives
    hold their command, where real drives that time theirs out would have stopped)."""
    scenario = get_scenario("torsetnes_2004")
    silent = replace(scenario, faults=(*scenario.faults, Fault("dropout", "*", 200.0, 220.0)))
    run = run_closed_loop(silent, 240.0, seed=3)
    epoch = SimEpoch(scenario.start_utc).stamp_ns(0.0)
    in_silence = [c for c in run.commands if 202.5 * S < c["stamp_ns"] - epoch < 220 * S]
    assert len(in_silence) >= 170, len(in_silence)  # 10 Hz from the sources' timeout on
    statuses = {e["status"] for e in run.estimates if 202.5 * S < e["stamp_ns"] - epoch < 220 * S}
    assert statuses and statuses <= {"dead_reckoning", "lost"}, statuses
    off = np.hypot(run.eta_lf[:, 0] - scenario.eta0[0], run.eta_lf[:, 1] - scenario.eta0[1])
    before = off[(run.t >= 160) & (run.t < 200)].max()
    during = off[(run.t >= 200) & (run.t < 240)].max()
    assert during <= 1.25 * before, (during, before)


def test_in_manual_the_joystick_is_commanded_through_a_total_silence_and_its_dead_man_expires() -> None:
    """An operator takes manual because the references failed: the joystick's τ must still reach the
    thrusters (before, with nothing stepping, no command went out at all), and the dead-man must still
    expire a τ that stopped coming, on the ticks' time."""
    from gateway.pipeline import ControlEvent, RawEvent
    from tests.test_commands import ALL, T0, moving_fix, pipeline

    rng = np.random.default_rng(7)
    p = pipeline({"accept": ALL, "manual_tau_hold_s": 2.0}, initial_mode="manual")
    t = 0.0
    while t < 5.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    out: list[Any] = []
    # silent from 5 s on; the joystick streams 1 MN ahead at 5 Hz from 8 s to 10 s, then stops
    for k in range(1, 151):  # ticks at 10 Hz up to 20 s
        now = T0 + round((t + k / 10) * S)
        if 8.0 <= t + k / 10 <= 10.0 and k % 2 == 0:
            p.feed(ControlEvent(now - S // 20, "tau", {"X": 1e6, "Y": 0.0, "N": 0.0}))
        out += p.tick(now)
    demands = [(o.stamp_ns, o.payload["tau_demand"][0]) for o in out if o.topic == "/dp/thrusters/command"]
    when = {ns: x for ns, x in demands}
    joystick = [x for ns, x in demands if T0 + 8.2 * S <= ns <= T0 + 10 * S]
    assert joystick and all(x == 1e6 for x in joystick), demands
    # no τ for longer than the hold (2 s after the last, at 9.95 s): zero from 12 s on, the mode still manual
    late = [x for ns, x in when.items() if ns >= T0 + 12.1 * S]
    assert late and all(x == 0.0 for x in late), late
    assert p.mode == "manual" and p.commands.counters.expired == {"tau": 1}


def test_simulated_drives_hold_or_stop_when_their_commands_stop() -> None:
    """The simulator's drives on command loss (`ThrusterFeedbackConfig.on_command_loss`): ``hold`` keeps the
    last command (as most DP drives do), ``stop`` goes to zero thrust 2 s after the last command, the
    azimuths where they were (a fieldbus watchdog, an ArduPilot failsafe)."""
    from dpgw.closed_loop import _Commands
    from simulator.commands import ThrusterCommand
    from simulator.runner import COMMAND_TIMEOUT_S, Simulation

    scenario = get_scenario("torsetnes_2004")
    assert scenario.feedback is not None
    for action, after in (("hold", 50e3), ("stop", 0.0)):
        drives = replace(scenario, feedback=replace(scenario.feedback, on_command_loss=action))
        commands = _Commands()
        sim = Simulation(drives, 0, commands=[commands])
        ids = list(sim.thrusters.ids)
        for _ in range(10):  # 1 s of commands: 50 kN at 30°
            commands.pending += [ThrusterCommand(i, 50e3, 0.5) for i in ids]
            sim.run(0.1)
        assert sim.thrusters.thrust_setpoint.tolist() == [50e3] * len(ids)
        sim.run(COMMAND_TIMEOUT_S - 0.3)  # not yet timed out: held either way
        assert sim.thrusters.thrust_setpoint.tolist() == [50e3] * len(ids), action
        sim.run(0.5)
        assert sim.thrusters.thrust_setpoint.tolist() == [after] * len(ids), action
        azimuths = sim.thrusters.angle_setpoint[sim.thrusters.is_azimuth].tolist()
        assert azimuths and all(abs(a - 0.5) < 1e-12 for a in azimuths), action
    with pytest.raises(ValueError, match="on_command_loss"):
        replace(scenario.feedback, on_command_loss="coast")
