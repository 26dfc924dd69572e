"""The simulator end to end: real transports, independent parsers, seeds, truth, closed loop."""

from __future__ import annotations

import json
import math
import os
import select
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pymap3d
import pynmea2
import pytest
import serial
from conftest import wait_for

from dpgw.cli import main as cli_main
from simulator.faults import Fault
from simulator.runner import Route, Simulation
from simulator.scenarios import SCENARIOS, get_scenario
from simulator.sensors import DgpsConfig, ThrusterFeedbackConfig, antenna_ned
from simulator.transports import MemorySink
from wire.codecs.mavlink import AZIMUTH_THRUSTER_STATUS_ID, azimuth_command_frame, dialect, encoder
from wire.mcap.reader import read_messages, summary
from wire.mcap.writer import McapLogWriter


def run_to_memory(name: str, seed: int, duration: float, **changes):  # type: ignore[no-untyped-def]
    scenario = replace(get_scenario(name), **changes) if changes else get_scenario(name)
    nmea, mav = MemorySink(), MemorySink()
    sim = Simulation(scenario, seed, routes=[Route(nmea, "nmea"), Route(mav, "mavlink")])
    sim.run(duration)
    return sim, bytes(nmea.data), bytes(mav.data)


def nmea_lines(data: bytes) -> list[str]:
    return [line for line in data.decode("ascii").split("\r\n") if line]


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_everything_emitted_parses_with_independent_parsers(name: str) -> None:
    sim, nmea, mav = run_to_memory(name, seed=3, duration=30.0)
    lines = nmea_lines(nmea)
    assert len(lines) > 30
    kinds = set()
    for line in lines:
        msg = pynmea2.parse(line, check=True)  # raises on a bad checksum
        if isinstance(msg, pynmea2.ProprietarySentence):  # an MRU's PHTRO: manufacturer HTR, type O
            kinds.add(f"P{msg.manufacturer}{msg.data[0]}")
        else:
            kinds.add(msg.sentence_type)
    assert {"GGA", "HDT"} <= kinds or {"GNS", "HDT"} <= kinds
    if sim.scenario.mru:
        assert {"PHTRO"} <= kinds
    if sim.thrusters.n:
        mavlink = dialect().MAVLink(None)
        msgs = mavlink.parse_buffer(mav) or []
        assert not [m for m in msgs if m.get_type() == "BAD_DATA"]
        status = [m for m in msgs if m.get_msgId() == AZIMUTH_THRUSTER_STATUS_ID]
        assert {m.id for m in status} == set(sim.thrusters.ids)
        assert any(m.get_type() == "HEARTBEAT" for m in msgs)


def test_same_seed_same_bytes_different_seed_different_sea() -> None:
    _, a_nmea, a_mav = run_to_memory("torsetnes_2004", seed=11, duration=40.0)
    _, b_nmea, b_mav = run_to_memory("torsetnes_2004", seed=11, duration=40.0)
    _, c_nmea, _ = run_to_memory("torsetnes_2004", seed=12, duration=40.0)
    assert a_nmea == b_nmea and a_mav == b_mav
    assert a_nmea != c_nmea
    wa = get_wf("torsetnes_2004", 11)
    wc = get_wf("torsetnes_2004", 12)
    assert np.corrcoef(wa[:, 0], wc[:, 0])[0, 1] < 0.5  # a different sea, not just different noise


@pytest.mark.parametrize(
    ("name", "faults"),
    [
        ("fossen_strand_1999", ()),  # no thrusters: τ acts directly
        ("torsetnes_2004", ()),  # six thrusters; 120 s run through several 1024-draw blocks of the bias
        ("hajivand_2010", (Fault(kind="thruster_failure", source="2", t_start=10.0),)),
    ],
)
def test_compiled_plant_steps_equal_the_reference_bit_for_bit(name: str, faults: tuple[Fault, ...]) -> None:
    """`Simulation._advance_fused` (one compiled call for thrusters, bias and RK4) against the Python loop of
    `_advance_reference`: the same state and the same bytes, bit for bit."""
    runs = []
    for fused in (True, False):
        nmea, mav = MemorySink(), MemorySink()
        scenario = replace(get_scenario(name), faults=faults)
        sim = Simulation(scenario, 5, routes=[Route(nmea, "nmea"), Route(mav, "mavlink")])
        sim.fused_plant = fused
        sim.run(60.0)
        sim.run(60.0)  # (a second run: the state carries over)
        runs.append((sim, bytes(nmea.data), bytes(mav.data)))
    (a, a_nmea, a_mav), (b, b_nmea, b_mav) = runs
    assert a.dynamics.x.tobytes() == b.dynamics.x.tobytes()
    assert a.bias.b.tobytes() == b.bias.b.tobytes() and a.bias._k == b.bias._k
    assert a.thrusters.thrust.tobytes() == b.thrusters.thrust.tobytes()
    assert a.thrusters.angle.tobytes() == b.thrusters.angle.tobytes()
    assert a_nmea == b_nmea and a_mav == b_mav
    assert np.abs(a.dynamics.x[:2]).max() > 0.1  # the vessel moved: the test compares something


@pytest.mark.parametrize("name", ["mss_supply_storm", "mss_osv"])
def test_compiled_full_plant_steps_equal_the_reference_bit_for_bit(name: str) -> None:
    """`Simulation._advance_full` (one compiled call for thrusters, bias, wind force and the full plant's
    RK4, the current stepped in Python between calls) against the Python loop of `_advance_reference` /
    `_full_step`: the same state, environment and bytes, bit for bit, over 120 s (the current steps
    120 times, the wind force is recomputed 480 times, the bias crosses a 1024-draw block)."""
    runs = []
    for fused in (True, False):
        nmea, mav = MemorySink(), MemorySink()
        sim = Simulation(get_scenario(name), 5, routes=[Route(nmea, "nmea"), Route(mav, "mavlink")])
        sim.fused_plant = fused
        sim.run(60.0)
        sim.run(60.0)  # (a second run: the state carries over)
        runs.append((sim, bytes(nmea.data), bytes(mav.data)))
    (a, a_nmea, a_mav), (b, b_nmea, b_mav) = runs
    assert a.plant_env is not None and b.plant_env is not None
    assert a.plant_env.current is not None and b.plant_env.current is not None
    assert a.dynamics.x.tobytes() == b.dynamics.x.tobytes()
    assert len(a.dynamics.x) > 6 or name == "mss_osv"  # the supply vessel carries fluid-memory states
    assert a.bias.b.tobytes() == b.bias.b.tobytes() and a.bias._k == b.bias._k
    assert a.thrusters.thrust.tobytes() == b.thrusters.thrust.tobytes()
    assert a.thrusters.angle.tobytes() == b.thrusters.angle.tobytes()
    assert a.plant_env.wind_body.tobytes() == b.plant_env.wind_body.tobytes()
    assert a.plant_env.current.velocity_ned.tobytes() == b.plant_env.current.velocity_ned.tobytes()
    assert a.plant_env.due.tobytes() == b.plant_env.due.tobytes()
    assert a_nmea == b_nmea and a_mav == b_mav
    assert np.abs(a.plant_env.wind_body).max() > 0.0  # the wind pushes: the test compares something
    assert a.plant_env.current.speed != a.plant_env.current.model.speed_mps  # the current moved
    assert np.abs(a.dynamics.x[:2]).max() > 0.1  # the vessel moved


@pytest.mark.parametrize("name", ["mss_supply_storm", "mss_osv"])
def test_compiled_wind_force_equals_the_python_one_bit_for_bit(name: str) -> None:
    """The compiled wind force (the plant's advance, the feed-forward's mean wind) against
    `simulator.wind.wind_force`, the readable form: the same bits at any heading and velocity."""
    from simulator._full_advance_kernel import wind_force_into
    from simulator.wind import wind_force

    sim = Simulation(get_scenario(name), 1)
    env = sim.plant_env
    assert env is not None and env.wind is not None
    rng = np.random.default_rng(7)
    out = np.empty(3)
    x = np.zeros(6)
    for psi, u, v, t in zip(
        rng.uniform(-np.pi, np.pi, 3000),
        rng.normal(0, 2, 3000),
        rng.normal(0, 2, 3000),
        rng.uniform(0, 900, 3000),
        strict=True,
    ):
        mean = env.mean_wind_body(psi)
        assert mean.tobytes() == np.array(env.wind.mean_force_body(psi)).tobytes()
        env.due[1] = np.inf  # (the wind is due: its NED velocity is filled in)
        env.wind_parameters(t, 0.05)
        x[2:5] = psi, u, v
        wind_force_into(x, env.wind_p, out)
        speed = env.wind.speed(t)
        expected = wind_force(env.wind.area, env.wind.length_m, speed, env.wind.model.from_deg, psi, u, v)
        assert out.tobytes() == np.array(expected).tobytes()
    assert np.abs(out).max() > 0.0


def get_wf(name: str, seed: int) -> np.ndarray:
    sim = Simulation(get_scenario(name), seed)
    t = np.arange(0.0, 300.0, 0.5)
    return sim.waves.motion(t, sim.dynamics.x[2], 0.0, 0.0)


def test_truth_and_measurements_agree(tmp_path: Path) -> None:
    """Decoded GGA (pynmea2 + pymap3d) = the truth's antenna position (LF + WF + the lever arm turned by
    heading, roll and pitch), within the configured noise (tests/test_truth_vs_sensors.py has the
    statistics)."""
    lever = (10.0, -2.0, -20.0)
    scenario = replace(
        get_scenario("torsetnes_2004"),
        dgps=(DgpsConfig(rate_hz=1.0, sigma_m=0.05, lever_arm_m=lever, latency_s=0.2),),
    )
    path = tmp_path / "sim.mcap"
    with McapLogWriter(path) as log:
        Simulation(scenario, seed=5, log=log).run(120.0)
    truth = {m[3]["stamp_ns"]: m[3] for m in read_messages(path, "/truth/state")}
    datum = scenario.datum
    checked = 0
    for _topic, log_ns, pub_ns, payload in read_messages(path, "/raw/nmea/dgps1"):
        # one log message per burst: the sentences a sensor sent at one instant
        burst = [pynmea2.parse(line, check=True) for line in payload["text"].split("\r\n") if line]
        gga = [m for m in burst if m.sentence_type == "GGA"]
        if not gga:
            continue
        msg = gga[0]
        assert log_ns - pub_ns == pytest.approx(0.2e9, abs=1e6)  # latency: log time is when it was sent
        tr = truth.get(pub_ns)
        if tr is None:
            continue
        n, e, _ = pymap3d.geodetic2ned(msg.latitude, msg.longitude, 0.0, datum.lat_deg, datum.lon_deg, 0.0)
        eta = np.add(tr["eta_lf"], tr["eta_wf"])
        ant_n, ant_e, _ = antenna_ned(eta, lever, tr["wf_attitude"])
        assert abs(n - ant_n) < 0.3 and abs(e - ant_e) < 0.3
        assert tr["antennas"]["dgps1"][:2] == pytest.approx([ant_n, ant_e], abs=1e-9)
        checked += 1
    assert checked > 100
    s = summary(path)
    assert {"/truth/state", "/raw/nmea/dgps1", "/raw/nmea/gyro1", "/raw/mavlink/thrusters"} <= set(s.channels)
    wf = np.array([tr["eta_wf"] for tr in truth.values()])
    assert np.std(wf[:, 0]) > 0.1  # Hs 6 m moves the ship


def test_wave_motion_limits_of_fossen_strand() -> None:
    sim = Simulation(get_scenario("fossen_strand_1999"), seed=1)
    t = np.arange(0.0, 1200.0, 0.25)
    wf = sim.waves.motion(t, sim.dynamics.x[2], 0.0, 0.0)
    peaks = np.max(np.abs(wf), axis=0)
    np.testing.assert_allclose(peaks, [10.0, 10.0, math.radians(1.0)], rtol=0.05)


def test_thruster_failure_fault_is_reported() -> None:
    """A scheduled thruster failure: the unit's thrust decays to zero and its status carries FAULT."""
    from wire.codecs.mavlink import AzimuthThrusterFlags

    faults = (Fault(kind="thruster_failure", source="2", t_start=10.0),)
    sim, _, mav = run_to_memory("hajivand_2010", seed=1, duration=40.0, faults=faults)
    msgs = dialect().MAVLink(None).parse_buffer(mav) or []
    start_us = sim.epoch.stamp_ns(0.0) // 1000
    status = [m for m in msgs if m.get_msgId() == AZIMUTH_THRUSTER_STATUS_ID and m.id == 2]
    before = [m for m in status if m.time_usec - start_us < 9e6]
    after = [m for m in status if m.time_usec - start_us > 11e6]
    assert before and after
    assert not any(m.flags & AzimuthThrusterFlags.FAULT for m in before)
    assert all(m.flags & AzimuthThrusterFlags.FAULT for m in after)
    tc = sim.scenario.vessel.thrusters[1].thrust_time_constant_s
    assert abs(after[-1].thrust) <= 1e6 * math.exp(-(30.0 - 1.0) / tc) + 1.0
    assert sim.thrusters.failed[1]


def test_mavlink_commands_close_the_loop() -> None:
    """AZIMUTH_THRUSTER_COMMAND frames sent back on the link drive the thrusters (and the status shows it)."""
    from simulator.commands import MavlinkCommandInput

    scenario = replace(get_scenario("hajivand_2010"), feedback=ThrusterFeedbackConfig(rate_hz=2.0))
    mav = MemorySink()
    sim = Simulation(scenario, 0, routes=[Route(mav, "mavlink")], commands=[MavlinkCommandInput(mav)])
    sim.run(5.0)
    gcs = encoder(src_system=255, src_component=190)
    for tid, angle in ((1, 0.5), (2, -0.5), (3, 1.5)):
        mav.feed(azimuth_command_frame(gcs, 0, tid, 4e5, angle))
    sim.run(30.0)
    assert sim.external_control and sim.summary.commands_applied == 3
    np.testing.assert_allclose(sim.thrusters.thrust_setpoint, 4e5)
    np.testing.assert_allclose(sim.thrusters.angle, [0.5, -0.5, 1.5], atol=1e-9)


def test_the_simulated_drive_takes_only_commands_addressed_to_it() -> None:
    """The drive (system 1, component 1 by default) takes broadcast commands and its own; one addressed to
    another system or component is counted and not applied."""
    from simulator.commands import MavlinkCommandInput

    fb = ThrusterFeedbackConfig(rate_hz=2.0, system_id=4, component_id=9)
    scenario = replace(get_scenario("hajivand_2010"), feedback=fb)
    mav = MemorySink()
    inp = MavlinkCommandInput(mav, fb.system_id, fb.component_id)
    sim = Simulation(scenario, 0, routes=[Route(mav, "mavlink")], commands=[inp])
    sim.run(5.0)
    gw = encoder(src_system=1, src_component=191)
    for target in ((5, 9), (4, 8), (4, 0), (0, 0)):  # other system, other component, ours, broadcast
        mav.feed(
            azimuth_command_frame(gw, 0, 1, 4e5, 0.5, target_system=target[0], target_component=target[1])
        )
    sim.run(6.0)
    assert inp.received == 4 and inp.rejected == {"other target": 2}
    assert sim.summary.commands_applied == 2


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_zenoh_commands_close_the_loop() -> None:
    from gateway.bus import isolated_config, open_session
    from simulator.commands import ZenohCommandInput

    port = _free_port()
    sim_session = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    ctl_session = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    try:
        scenario = get_scenario("hajivand_2010")
        inp = ZenohCommandInput(sim_session, "dp/test")
        sim = Simulation(scenario, 0, commands=[inp])
        sim.run(2.0)
        cmd = {"stamp_ns": 0, "mode": "dp", "thrusters": [{"id": 1, "thrust_n": 3e5, "azimuth_rad": 1.0}]}

        def commanded() -> bool:  # resent until the two sessions have found each other
            ctl_session.put("dp/test/thrusters/command", json.dumps(cmd))
            sim.run(0.2)
            return sim.external_control

        assert wait_for(commanded, 30.0, interval=0.05), "the command never reached the simulator"
        ctl_session.put("dp/test/thrusters/command", b"not json")
        assert wait_for(lambda: inp.rejected, 10.0)  # the garbage was counted, not raised
        sim.run(20.0)
        assert sim.thrusters.thrust_setpoint[0] == pytest.approx(3e5)
        assert sim.thrusters.angle[0] == pytest.approx(1.0)
    finally:
        sim_session.close()
        ctl_session.close()


def _dpgw(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "dpgw", "sim", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.slow
def test_pyserial_reads_the_pty_of_dpgw_sim() -> None:
    proc = _dpgw("--scenario", "hassani", "--nmea", "pty", "--realtime", "--speed", "4", "--duration", "20")
    try:
        assert proc.stderr is not None
        device = None
        deadline = time.monotonic() + 20
        while device is None and time.monotonic() < deadline:
            ready, _, _ = select.select([proc.stderr], [], [], 1.0)
            if ready:
                line = proc.stderr.readline()
                if "/dev/pts/" in line:
                    device = line.split("->", 1)[1].split()[0]
        assert device and os.path.exists(device)
        with serial.Serial(device, baudrate=115200, timeout=2.0) as port:
            lines = []
            while len(lines) < 20:
                raw = port.readline()
                assert raw, "no data on the pty"
                if raw.startswith(b"$"):
                    lines.append(raw.decode("ascii"))
        parsed = [pynmea2.parse(s.strip(), check=True) for s in lines[1:]]
        assert {p.sentence_type for p in parsed} & {"GGA", "HDT", "ROT"}
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert proc.returncode == 0  # SIGTERM: a clean stop


def test_udp_listener_receives_dpgw_sim(tmp_path: Path) -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(10.0)
    port = rx.getsockname()[1]
    out = tmp_path / "run.mcap"
    proc = _dpgw(
        "--scenario", "torsetnes_2004", "--nmea", f"udp://127.0.0.1:{port}",
        "--duration", "30", "--out", str(out), "--json",
    )  # fmt: skip
    datagrams = []
    try:
        while len(datagrams) < 50:
            datagrams.append(rx.recv(65536))
    finally:
        stdout, _ = proc.communicate(timeout=60)
        rx.close()
    sentences = [pynmea2.parse(d.decode().strip(), check=True) for d in datagrams if d.startswith(b"$")]
    assert len(sentences) >= 40
    result = json.loads(stdout)
    assert result["sim_seconds"] == pytest.approx(30.0) and result["emissions"]["dgps1"] > 0
    assert summary(out).complete


def test_bad_arguments_give_one_clear_message() -> None:
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--nmea", "udp://nowhere"],
        capture_output=True,
        text=True,
    )
    assert p.returncode == 2 and "udp://nowhere" in p.stderr and "Traceback" not in p.stderr


def test_heading_of_turning_scenario_wraps_in_sentences() -> None:
    _, nmea, _ = run_to_memory("snijders_2005", seed=2, duration=20.0)
    hdt = [pynmea2.parse(s, check=True) for s in nmea_lines(nmea) if s[3:6] == "HDT"]
    assert all(0.0 <= float(m.heading) < 360.0 for m in hdt)


def test_faults_file_and_ardupilot_feedback_from_the_cli(tmp_path: Path) -> None:
    faults = tmp_path / "faults.toml"
    faults.write_text(
        '[[faults]]\nkind = "dropout"\nsource = "dgps1"\nt_start = 5.0\nt_end = 15.0\n'
        '[[faults]]\nkind = "bad_checksum"\nsource = "gyro1"\nt_start = 0.0\n'
    )
    out = tmp_path / "f.mcap"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "hajivand_2010", "--duration", "20",
         "--faults", str(faults), "--ardupilot", "--out", str(out), "--json"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert json.loads(p.stdout)["emissions"]["dgps1"] == 10 * 5  # 20 fixes at 1 Hz, 10 s of it silent
    gyro = [m[3]["text"] for m in read_messages(out, "/raw/nmea/gyro1")]
    for text in gyro:
        for line in text.split("\r\n"):
            with pytest.raises(pynmea2.ChecksumError):
                pynmea2.parse(line, check=True)
    frames = b"".join(
        __import__("base64").b64decode(m[3]["data"]) for m in read_messages(out, "/raw/mavlink/thrusters")
    )
    kinds = {m.get_type() for m in dialect().MAVLink(None).parse_buffer(frames) or []}
    assert {"ESC_TELEMETRY_1_TO_4", "SERVO_OUTPUT_RAW", "AZIMUTH_THRUSTER_STATUS"} <= kinds


def test_bad_fault_file_names_the_field(tmp_path: Path) -> None:
    faults = tmp_path / "faults.toml"
    faults.write_text('[[faults]]\nkind = "dropout"\nsource = "dgps1"\nt_start = 5.0\nt_end = 1.0\n')
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--faults", str(faults)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert p.returncode == 2 and "faults[0].t_end" in p.stderr and str(faults) in p.stderr


def test_sea_state_change_mid_run_shows_in_the_truth(tmp_path: Path) -> None:
    from simulator.spectra import SeaState

    sea = ((0.0, SeaState(3.0, 6.0)), (60.0, SeaState(3.0, 12.0)))
    scenario = replace(get_scenario("torsetnes_2004"), sea=sea)
    path = tmp_path / "sea.mcap"
    with McapLogWriter(path) as log:
        Simulation(scenario, 1, log=log).run(150.0)
    w0 = np.array([[m[2], m[3]["omega0"][0]] for m in read_messages(path, "/truth/state")])
    start = w0[0, 0]
    before = w0[(w0[:, 0] - start) < 80e9, 1]
    after = w0[(w0[:, 0] - start) > 100e9, 1]
    assert np.allclose(before, 2 * math.pi / 6.0) and np.allclose(after, 2 * math.pi / 12.0)


def test_a_run_in_chunks_is_one_run(tmp_path: Path) -> None:
    """The closed loop runs the simulator in 0.1 s chunks: that gives the same bytes on the wire and the
    same log (each truth record once, the drift force at 1 Hz) as one run of the same length."""
    sc = get_scenario("torsetnes_2004").with_sensor_rates(10.0, 10.0)
    out = []
    for chunk in (None, 0.1):
        nmea, mav = MemorySink(), MemorySink()
        path = tmp_path / f"{chunk}.mcap"
        with McapLogWriter(path) as log:
            sim = Simulation(sc, 2, log=log, routes=[Route(nmea, "nmea"), Route(mav, "mavlink")])
            if chunk is None:
                sim.run(20.0)
            while sim.t < 20.0 - 1e-9:
                sim.run(chunk)
        out.append((bytes(nmea.data), bytes(mav.data), list(read_messages(path))))
    assert out[0] == out[1]
    assert sum(1 for m in out[0][2] if m[0] == "/truth/state") == 201


def _gga_seconds(datagram: bytes) -> float | None:
    """Seconds of the day of a GGA (the fix time: the simulator's clock)."""
    text = datagram.decode("ascii", "replace")
    if not text.startswith("$GPGGA,"):
        return None
    hhmmss = text.split(",")[1]
    return int(hhmmss[:2]) * 3600 + int(hhmmss[2:4]) * 60 + float(hhmmss[4:])


@pytest.mark.slow  # ~10 s: a paced run stopped and continued
def test_a_paused_realtime_simulator_continues_where_it_was_not_in_a_burst() -> None:
    """A bench engineer stops `dpgw sim --realtime` (Ctrl-Z, a debugger, a suspended laptop) and continues
    it: the sea goes on from where it was, at its speed. Catching the pause up in a burst ran minutes of
    sea in a second of wall time: the gateway's commands, computed at wall speed, then act on a plant that
    moved on by hundreds of their own periods."""
    import signal

    speed = 4.0
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    port = rx.getsockname()[1]
    proc = _dpgw(
        "--scenario", "torsetnes_2004", "--nmea", f"dgps1=udp://127.0.0.1:{port}", "--gnss-rate", "10",
        "--realtime", "--speed", str(speed), "--duration", "600",
    )  # fmt: skip

    seen: list[float] = []

    def newest(until: float) -> float | None:
        """The newest fix time received until the wall instant ``until``."""
        while (left := until - time.monotonic()) > 0:
            rx.settimeout(left)
            try:
                s = _gga_seconds(rx.recv(4096))
            except TimeoutError:
                break
            if s is not None:
                seen.append(s)
        return seen[-1] if seen else None

    try:
        # running: a couple of seconds of fixes received
        assert wait_for(lambda: newest(time.monotonic() + 0.1) is not None and len(seen) > 20, 60.0)
        proc.send_signal(signal.SIGSTOP)
        before = newest(time.monotonic() + 0.5)  # (what was sent before the stop, drained)
        time.sleep(3.0)  # the pause is the stimulus: 3 s of wall, 12 s of sea at 4x
        proc.send_signal(signal.SIGCONT)
        resumed = time.monotonic()
        after = newest(resumed + 1.5)
        elapsed = time.monotonic() - resumed
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.terminate()
        proc.wait(timeout=30)
        rx.close()
    assert before is not None and after is not None
    advanced = after - before
    # from where it was, at its speed (a burst would add the 12 s of the pause)
    assert 0.0 < advanced <= speed * elapsed + 1.5, (advanced, elapsed)
    assert proc.returncode == 0


def test_sim_in_process_gives_back_the_signal_handlers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw sim` run in-process (a test, a notebook) catches SIGINT and SIGTERM to stop cleanly, and puts
    the caller's handlers back when it returns: Ctrl-C in the caller afterwards is the caller's again."""

    def mine(_signum: int, _frame: object) -> None:
        pass

    before = {sig: signal.signal(sig, mine) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        argv = ["sim", "--scenario", "hassani", "--duration", "2", "--seed", "1"]
        assert cli_main([*argv, "--out", str(tmp_path / "s.mcap"), "--json"]) == 0
        assert signal.getsignal(signal.SIGINT) is mine and signal.getsignal(signal.SIGTERM) is mine
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


def test_the_simulation_time_is_reported_to_the_ns() -> None:
    """The time is a sum of steps (199.99999999999292 after 200 s): reports (``dpgw sim --json``, the demo's
    JSON) give it to the ns, the resolution of every stamp, not with the sum's rounding error."""
    sim = Simulation(get_scenario("fossen_strand_1999"), 0)
    summary = sim.run(200.0)
    assert sim.t != 200.0  # (what the sum gives: why the report rounds it)
    assert sim.seconds == 200.0 and summary.as_dict()["sim_seconds"] == 200.0
