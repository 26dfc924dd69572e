"""The HIL bench as docs/cli.md and examples/hil_bench.toml print it: `dpgw sim` and `dpgw run` in two
processes, NMEA over UDP and a pty, MAVLink feedback and commands over UDP, the simulation time on Zenoh.
The loop closes, the estimate tracks the truth, the gateway's log is on the plant's time, and Ctrl-C / SIGTERM
stop both with complete logs."""

from __future__ import annotations

import itertools
import json
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import free_port, wait_for
from mcap.reader import make_reader

from gateway.scoring import score
from observers.kinematics import ssa
from wire.mcap.reader import read_messages

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "hil_bench.toml"


def dpgw(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "dpgw", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def lines_of(stream: object, into: list[str]) -> threading.Thread:
    """Collect a process's stderr lines as they come (its -v status lines are the test's events)."""

    def read() -> None:
        for line in stream:  # type: ignore[attr-defined]
            into.append(line)

    t = threading.Thread(target=read, daemon=True)
    t.start()
    return t


def estimates_said(lines: list[str]) -> int:
    """The estimates count of the newest `dpgw run -v` line ("dpgw run: 10 s, dp, 116 estimates; ...")."""
    for line in reversed(lines):
        if line.startswith("dpgw run: ") and " estimates" in line:
            return int(line.split(" estimates")[0].rsplit(" ", 1)[-1])
    return 0


def complete(path: Path) -> tuple[int, int]:
    """(messages, chunks) from the MCAP summary section (the footer a clean stop writes)."""
    with open(path, "rb") as f:
        s = make_reader(f).get_summary()
    assert s is not None and s.statistics is not None, f"{path}: no summary: the writer was not closed"
    return s.statistics.message_count, len(s.chunk_indexes)


def bench(tmp_path: Path) -> tuple[Path, list[str]]:
    """The example as printed, on this test's free ports and paths: (the gateway's config, the `dpgw sim`
    arguments without ``--out``)."""
    nmea, mav, zport = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM), free_port()
    gyro, log = tmp_path / "gyro", tmp_path / "hil.mcap"
    text = EXAMPLE.read_text()
    for old, new in [
        ("udp://127.0.0.1:10110", f"udp://127.0.0.1:{nmea}"),
        ("pty:///tmp/dpgw-gyro", f"pty://{gyro}"),
        ("udp://127.0.0.1:14550", f"udp://127.0.0.1:{mav}"),
        ("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{zport}"),
        ('path = "logs/hil.mcap"', f'path = "{log}"'),
    ]:
        assert old in text, old
        text = text.replace(old, new)
    cfg = tmp_path / "hil_bench.toml"
    cfg.write_text(text)
    sim_args = [
        "sim", "--scenario", "torsetnes_2004", "--nmea", f"dgps1=udp://127.0.0.1:{nmea}",
        "--nmea", f"gyro1=pty://{gyro}", "--mavlink", f"udp://127.0.0.1:{mav}", "--held", "--realtime",
        "--speed", "4", "--zenoh", "--zenoh-listen", f"tcp/127.0.0.1:{zport}", "--json",
    ]  # fmt: skip
    return cfg, sim_args


@pytest.mark.slow  # ~60 s: two processes, 200 s of sea at 4x
def test_the_documented_two_process_bench_closes_the_loop_and_stops_cleanly(tmp_path: Path) -> None:
    cfg, sim_args = bench(tmp_path)
    gyro, log, truth_log = tmp_path / "gyro", tmp_path / "hil.mcap", tmp_path / "sim.mcap"
    sim = dpgw(*sim_args, "--out", str(truth_log))
    gw: subprocess.Popen[str] | None = None
    try:
        assert wait_for(gyro.exists, 60.0), "the simulator made no pty"
        gw = dpgw("run", "--config", str(cfg), "-v")
        said: list[str] = []
        lines_of(gw.stderr, said)
        # 200 s of sea at the observer's 10 Hz, seen in the gateway's own status line: DP engaged by the
        # gateway itself once its observer settled (145 s), and a minute of station keeping
        assert wait_for(lambda: estimates_said(said) >= 2000 or gw.poll() is not None, 240.0), "".join(said)
        gw.send_signal(signal.SIGINT)  # Ctrl-C
        assert gw.wait(timeout=60) == 0, "".join(said)
        assert gw.stdout is not None and gw.stdout.read().startswith("dpgw run: stopped: ")
        sim.send_signal(signal.SIGTERM)
        out, err = sim.communicate(timeout=60)
        assert sim.returncode == 0, err
    finally:
        for p in (gw, sim):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
    run = json.loads(out)
    assert run["interrupted"] is True
    assert run["commands_applied"] > 0, run  # the gateway's commands reached the simulated drives
    # one log file: a line stamped with the wall clock in a log on the plant's time made the writer rotate
    assert not sorted(tmp_path.glob("hil_*.mcap")), "the gateway's log was split"
    # both logs complete: the summary section is there
    assert complete(log)[0] > 0 and complete(truth_log)[0] > 0
    truth = [p for _, _, _, p in read_messages(truth_log, "/truth/state")]
    t_truth = np.array([p["stamp_ns"] for p in truth]) / 1e9
    eta_truth = np.array([p["eta_lf"] for p in truth])
    est = [p for _, _, _, p in read_messages(log, "/dp/estimate")]
    t_est = np.array([p["stamp_ns"] for p in est]) / 1e9
    eta_est = np.array([p["eta"] for p in est])
    # the gateway's log is on the plant's time: nothing stamped outside the simulated span
    with open(log, "rb") as f:
        stamps = [m.log_time / 1e9 for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert t_truth[0] - 1.0 <= min(stamps) and max(stamps) <= t_truth[-1] + 1.0
    # one time base: the gyro's headings, stamped by the gateway, against the heading the simulator gave it
    # (LF + WF, swinging 1° at the wave period: half a second off would show as 0.3°; the gyro's σ is 0.05°)
    meas = [p for _, _, _, p in read_messages(log, "/dp/measurement")]
    t_meas = np.array([p["stamp_ns"] for p in meas]) / 1e9
    psi = np.array([np.nan if p["eta"][2] is None else p["eta"][2] for p in meas], dtype=float)
    total = np.array([p["eta_lf"][2] + p["eta_wf"][2] for p in truth])
    ok = np.isfinite(psi)
    miss = ssa(psi[ok] - np.interp(t_meas[ok], t_truth, np.unwrap(total)))
    assert ok.sum() > 500 and np.degrees(np.sqrt(np.mean(miss**2))) < 0.25
    # the LF estimate against the true LF motion (measured: 0.72 m and 1.4° RMS, the heading while the
    # observer's bias takes up the scenario's mean yaw moment after the gateway joins a running sea)
    s = score(t_est, eta_est, t_truth, eta_truth, settle_s=30.0)
    assert s.samples > 500
    assert s.horizontal_rms_m < 1.5 and np.degrees(s.rms[2]) < 3.0, s.as_dict()
    # the gateway waited for its observer (the crew holding the vessel meanwhile: --held), then engaged
    engaged = [
        p["stamp_ns"] / 1e9
        for _, _, _, p in read_messages(log, "/dp/status")
        for e in p.get("events", [])
        if "observer settled: DP engaged" in e
    ]
    assert len(engaged) == 1 and 140.0 < engaged[0] - t_est[0] < 150.0, engaged
    # said once in the gateway's log
    assert "".join(said).count("standby, DP by itself once the observer has settled") == 1
    # station keeping in the closed loop: the vessel stays near its setpoint (where it started)
    drift = np.hypot(*(eta_truth[t_truth >= t_truth[0] + 30.0, :2] - eta_truth[0, :2]).T)
    assert drift.max() < 10.0, drift.max()
    # the bench's two logs scored from the command line: the gateway's replayed, the simulator's truth
    # (in the simulator's datum; the gateway's is its first fix) moved into the replay's frame
    scored = subprocess.run(
        [
            sys.executable,
            "-m",
            "dpgw",
            "replay",
            str(log),
            "--truth",
            str(truth_log),
            "--json",
            "--out",
            str(tmp_path / "scored.mcap"),
            "--settle",
            "30",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert scored.returncode == 0, scored.stderr
    err = json.loads(scored.stdout)["error_vs_truth"]
    (label,) = err
    assert err[label]["horizontal_rms_m"] < 1.5, err  # as the live estimate's (above)
    assert abs(err[label]["horizontal_rms_m"] - s.horizontal_rms_m) < 0.3, (err, s.as_dict())
    assert any(True for _ in read_messages(tmp_path / "scored.mcap", "/truth/state"))  # replays scored too


def log_times(path: Path) -> list[tuple[str, int]]:
    """(topic, log time) of one file's messages, in the order written."""
    with open(path, "rb") as f:
        return [(ch.topic, m.log_time) for _, ch, m in make_reader(f).iter_messages(log_time_order=False)]


def lf_truth(path: Path) -> tuple[np.ndarray, np.ndarray]:
    truth = [p for _, _, _, p in read_messages(path, "/truth/state")]
    return np.array([p["stamp_ns"] for p in truth]) / 1e9, np.array([p["eta_lf"] for p in truth])


def estimates(path: Path) -> tuple[np.ndarray, np.ndarray]:
    est = [p for _, _, _, p in read_messages(path, "/dp/estimate")]
    return np.array([p["stamp_ns"] for p in est]) / 1e9, np.array([p["eta"] for p in est], dtype=float)


@pytest.mark.slow  # ~60 s: three processes, 40 + 80 s of sea at 4x
def test_a_simulator_restarted_under_the_gateway_is_followed(tmp_path: Path) -> None:
    """The bench stops `dpgw sim` and starts it again (another seed: another sea) under a running `dpgw
    run`: its time starts again from its epoch. The gateway follows the new run: its log goes on in the
    next file of the set, each file one run on its own (times in order, within that run's span) that
    replays alone to the same estimates; the estimate converges onto the new run's truth; and the gateway
    says so once (its log and its status)."""
    cfg, sim_args = bench(tmp_path)
    gyro, log, log2 = tmp_path / "gyro", tmp_path / "hil.mcap", tmp_path / "hil_0001.mcap"
    truth1, truth2 = tmp_path / "sim1.mcap", tmp_path / "sim2.mcap"
    procs: list[subprocess.Popen[str]] = []
    try:
        procs.append(sim := dpgw(*sim_args, "--out", str(truth1)))
        assert wait_for(gyro.exists, 60.0), "the simulator made no pty"
        procs.append(gw := dpgw("run", "--config", str(cfg), "-v"))
        said: list[str] = []
        lines_of(gw.stderr, said)
        assert wait_for(lambda: estimates_said(said) >= 400 or gw.poll() is not None, 180.0), "".join(said)
        sim.send_signal(signal.SIGTERM)  # the bench stops the simulator ...
        assert sim.wait(timeout=60) == 0
        before = estimates_said(said)
        procs.append(sim := dpgw(*sim_args, "--out", str(truth2), "--seed", "7"))  # ... and starts it again
        assert wait_for(lambda: any("following the new run" in line for line in said), 120.0), "".join(said)
        assert wait_for(lambda: estimates_said(said) >= before + 800 or gw.poll() is not None, 180.0), (
            "".join(said)
        )
        gw.send_signal(signal.SIGINT)
        assert gw.wait(timeout=60) == 0, "".join(said)
        sim.send_signal(signal.SIGTERM)
        assert sim.wait(timeout=60) == 0
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    # said once in the gateway's log, naming the file the log goes on in
    followed = [line for line in said if "following the new run" in line]
    assert len(followed) == 1 and "log continues in hil_0001.mcap" in followed[0], followed
    assert "went back" in followed[0] and "restart dpgw run" not in "".join(said)
    # the restarted simulator (a new run identity, its clock up within the old one's 2 s of silence) is
    # not taken for a second bench on the prefix (before: the alarm, for the rest of the run)
    assert not [line for line in said if "another simulator" in line]
    # two files, one a run, each complete and on its own run's time, in order
    assert sorted(tmp_path.glob("hil*.mcap")) == [log, log2]
    for path, truth in ((log, truth1), (log2, truth2)):
        assert complete(path)[0] > 0
        written = log_times(path)
        for topic in {topic for topic, _ in written}:  # each channel in order: no second run's time in it
            on = [t for name, t in written if name == topic]
            assert on == sorted(on), f"{path.name} {topic}: log times out of order"
        # across channels, less than a second back (another run's time would be tens of seconds back):
        # the Foxglove log lines of a status come up to ~0.1 s behind the outputs written before them
        times = [t for _, t in written]
        assert min(b - a for a, b in itertools.pairwise(times)) > -1_000_000_000, path.name
        times.sort()
        t_truth, _ = lf_truth(truth)
        assert t_truth[0] - 1.0 <= times[0] / 1e9 and times[-1] / 1e9 <= t_truth[-1] + 1.0, path.name
    # said once in the status: the new file's, not the old one's
    events = [
        (path.name, e)
        for path in (log, log2)
        for _, _, _, p in read_messages(path, "/dp/status")
        for e in p.get("events", [])
        if "following the new run" in e
    ]
    assert [name for name, _ in events] == ["hil_0001.mcap"], events
    # the estimate converges onto the new run's truth (the gateway joins it from its first second)
    t_truth, eta_truth = lf_truth(truth2)
    t_est, eta_est = estimates(log2)
    s = score(t_est, eta_est, t_truth, eta_truth, settle_s=30.0)
    assert s.samples > 400
    assert s.horizontal_rms_m < 1.5 and np.degrees(s.rms[2]) < 3.0, s.as_dict()
    # the new run's file replays alone, to the estimates the live gateway published
    out = tmp_path / "replay2.mcap"
    done = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(log2), "--out", str(out), "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    t_rep, eta_rep = estimates(out)
    assert len(t_rep) == len(t_est) and np.array_equal(t_rep, t_est)
    assert np.max(np.abs(eta_rep - eta_est)) < 1e-6


def sim_taking_zenoh_commands(*extra: str) -> tuple[dict[str, object], str]:
    """`dpgw sim` with its thrusters on MAVLink (a UDP port nobody commands from) and a Zenoh session,
    while a console publishes thruster commands on ``<prefix>/thrusters/command`` (what the gateway
    publishes there for consoles), from the first clock tick it hears (the link is up) to the end of the
    run: (the run's JSON summary, its stderr)."""
    import zenoh

    from gateway.bus import isolated_config, open_session

    mav, zport = free_port(socket.SOCK_DGRAM), free_port()
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # the MAVLink peer: hears, never commands
    sink.bind(("127.0.0.1", mav))
    sim = dpgw(
        "sim", "--scenario", "torsetnes_2004", "--duration", "8", "--realtime", "--speed", "2",
        "--mavlink", f"udp://127.0.0.1:{mav}", "--zenoh", "--zenoh-listen", f"tcp/127.0.0.1:{zport}",
        "--no-scouting", "--prefix", "bench/x", "--json", *extra,
    )  # fmt: skip
    ticks: list[int] = []
    console = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{zport}"]))
    try:
        console.declare_subscriber("bench/x/sim/clock", lambda s: ticks.append(1))
        command = json.dumps(
            {"mode": "dp", "thrusters": [{"id": i, "thrust_n": 1e4, "azimuth_rad": 0.0} for i in range(1, 7)]}
        ).encode()
        pub = console.declare_publisher("bench/x/thrusters/command", encoding=zenoh.Encoding.APPLICATION_JSON)
        assert wait_for(lambda: bool(ticks) or sim.poll() is not None, 60.0), "no clock tick from the sim"
        while sim.poll() is None:
            pub.put(command)
            wait_for(lambda: sim.poll() is not None, 0.05)  # (the console's pace: 20 commands a second)
        out, err = sim.communicate(timeout=60)
    finally:
        console.close()
        sink.close()
        if sim.poll() is None:
            sim.kill()
            sim.wait()
    assert sim.returncode == 0, err
    return json.loads(out), err


@pytest.mark.slow  # two 4 s runs
def test_drives_on_mavlink_do_not_take_the_gateways_zenoh_commands(tmp_path: Path) -> None:
    """With --mavlink the simulated drives take commands from their MAVLink link only. They took the
    gateway's Zenoh output `<prefix>/thrusters/command` as well (the clock needs --zenoh, which also
    subscribed it), so a bench closed the loop with the gateway's MAVLink commands going nowhere, or
    refused for their signature: `commands_applied` > 0 said the link worked when it did not."""
    taken, said = sim_taking_zenoh_commands("--zenoh-commands")  # asked for: the console reaches the drives
    assert int(taken["commands_applied"]) > 0, said  # type: ignore[call-overload]
    assert "Zenoh: commands from bench/x/thrusters/command" in said
    run, said = sim_taking_zenoh_commands()
    assert run["commands_applied"] == 0, (run, said)
    assert "thruster commands from the MAVLink link only, not bench/x/thrusters/command" in said, said


def test_a_simulator_restarted_with_the_same_out_keeps_the_runs_truth(tmp_path: Path) -> None:
    """A bench restarts `dpgw sim` with the same command line (`--out sim.mcap`) under a running gateway,
    whose log of the first run stays: the first run's truth must stay too, to score that log against. It
    was overwritten; now the second run goes on in sim_0001.mcap, as the gateway's own log does, and the
    summary names the file written."""
    out = tmp_path / "sim.mcap"

    def run(seed: str) -> dict[str, object]:
        done = subprocess.run(
            [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--duration", "3", "--seed", seed,
             "--out", str(out), "--json"],
            capture_output=True, text=True, timeout=120, check=True,
        )  # fmt: skip
        summary: dict[str, object] = json.loads(done.stdout)
        return summary

    assert run("1")["log"] == str(out)
    first = out.read_bytes()
    second = run("2")
    assert second["log"] == str(tmp_path / "sim_0001.mcap"), second
    assert out.read_bytes() == first  # the first run's truth, as it was
    seeds = []
    for path in (out, tmp_path / "sim_0001.mcap"):
        with open(path, "rb") as f:
            seeds += [m.metadata["seed"] for m in make_reader(f).iter_metadata() if m.name == "dpgw.sim"]
        assert any(True for _ in read_messages(path, "/truth/state"))
    assert seeds == ["1", "2"]  # each run's own truth, in its own file
