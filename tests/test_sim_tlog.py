"""`dpgw sim --tlog`: a real tlog of the thruster MAVLink, timed on the simulation's clock, that pymavlink
and `dpgw replay` read, and that replays with the simulator's NMEA text as the simulator's own log does."""

from __future__ import annotations

import base64
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpgw.cli import main
from gateway.logreaders import LogCounts, tlog_events
from simulator.faults import Fault
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from simulator.tlog_recorder import TlogRecorder
from wire.codecs import mavlink as mv
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter
from wire.tlog import RECORD_TIME, TlogWriter


def _simulate(
    tmp_path: Path, seconds: float, faults: tuple[Fault, ...] = (), latency_s: float = 0.0
) -> tuple[Path, Path, Any]:
    """hassani (thrusters at 5 Hz, sending ``latency_s`` after they measure) for ``seconds``: its MCAP log
    and its tlog."""
    scenario = get_scenario("hassani")
    assert scenario.feedback is not None
    feedback = replace(scenario.feedback, latency_s=latency_s)
    scenario = replace(scenario, faults=scenario.faults + faults, feedback=feedback)
    log, tlog = tmp_path / "sim.mcap", tmp_path / "sim.tlog"
    with McapLogWriter(log) as w, TlogWriter(tlog) as t:
        sim = Simulation(scenario, seed=2, log=w)
        recorder = sim.on_emit = TlogRecorder(t, sim.epoch)
        sim.run(seconds)
    return log, tlog, recorder


def _sent(log: Path) -> list[tuple[int, bytes]]:
    """(µs since 1970, frame) of every valid MAVLink frame the simulator's MCAP log says it sent."""
    out = []
    for _, log_ns, _, payload in read_messages(log, "/raw/mavlink/thrusters"):
        data = base64.b64decode(payload["data"])
        out += [(log_ns // 1000, bytes(m.get_msgbuf())) for m in mv.parse_frames(data)]
    return out


def _pymavlink_records(path: Path) -> list[tuple[float, Any]]:
    """The messages pymavlink's own tlog reader gives, with their `_timestamp`, in the project's dialect."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(path))  # a .tlog file: mavmmaplog, a mavlogfile
    assert isinstance(conn, mavutil.mavlogfile)
    # in the dpgw dialect (ardupilotmega + the azimuth thruster messages), as mavfile itself switches dialects
    conn.mav = mv.dialect().MAVLink(conn)
    conn.mav.robust_parsing = True
    conn.rewind()
    out = []
    while (m := conn.recv_msg()) is not None:
        out.append((m._timestamp, m))
    conn.close()
    return out


def test_pymavlink_reads_the_tlog_with_the_simulations_send_times(tmp_path: Path) -> None:
    log, tlog, recorder = _simulate(tmp_path, 10.0, latency_s=0.03)
    sent = _sent(log)
    got = _pymavlink_records(tlog)
    assert [m.get_type() for _, m in got].count(
        "AZIMUTH_THRUSTER_STATUS"
    ) == 3 * 50  # 3 drives, 5 Hz, sent 0.03..9.83 s
    assert "BAD_DATA" not in {m.get_type() for _, m in got}
    assert len(got) == len(sent) == recorder.records
    times = np.array([t for t, _ in got])
    assert np.all(np.diff(times) >= 0.0)
    # each frame at the time the simulator sent it (measured + 30 ms): the MCAP log's time of its burst, on
    # the simulation's epoch (the NMEA sentences' UTC)
    start = Simulation(get_scenario("hassani")).epoch.stamp_ns(0.0) / 1e9
    assert times[0] == pytest.approx(start + 0.03, abs=1e-6) and times[-1] <= start + 10.0
    assert np.allclose(times, [t_us * 1e-6 for t_us, _ in sent], rtol=0.0, atol=1e-6)
    assert [bytes(m.get_msgbuf()) for _, m in got] == [frame for _, frame in sent]


def test_the_gateways_tlog_reader_reads_it_exactly(tmp_path: Path) -> None:
    log, tlog, _ = _simulate(tmp_path, 10.0)
    counts = LogCounts()
    events = list(tlog_events(tlog, "thrusters", counts))
    assert [(e.rx_ns // 1000, e.data) for e in events] == _sent(log)
    assert all(e.rx_ns % 1000 == 0 for e in events) and not counts.counts
    # one record per frame: an 8-byte time, then the frame
    assert tlog.stat().st_size == sum(RECORD_TIME.size + len(e.data) for e in events)


def test_corrupted_frames_are_left_out_as_a_ground_station_would(tmp_path: Path) -> None:
    """Garbage and bad CRCs on the link (faults) are not frames a ground station logs: the tlog stays one
    whole frame per record (pymavlink sees no BAD_DATA); every good frame is still in it."""
    faults = (
        Fault("garbage", "thrusters", 1.0, 3.0),
        Fault("bad_checksum", "thrusters", 4.0, 5.0, {"probability": 0.5}),
    )
    log, tlog, recorder = _simulate(tmp_path, 8.0, faults)
    assert recorder.not_recorded > 5
    got = _pymavlink_records(tlog)
    assert "BAD_DATA" not in {m.get_type() for _, m in got}
    assert len(got) == len(_sent(log))
    counts = LogCounts()
    assert len(list(tlog_events(tlog, "thrusters", counts))) == len(got) and not counts.counts


def _feedback(path: Path) -> dict[int, dict[str, Any]]:
    """The replay's /dp/thrusters/feedback, the last at each time (a tlog's frames of one instant are one
    event each; the simulator's log keeps them as one burst)."""
    return {m["stamp_ns"]: m for _, _, _, m in read_messages(path, "/dp/thrusters/feedback")}


def test_dpgw_sim_nmea_text_and_tlog_replay_as_the_sims_own_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A sea trial rehearsed: `dpgw sim` writes the NMEA text and a tlog (and its MCAP log); `dpgw replay` of
    the two files together gives the thruster feedback at the drives' 5 Hz with the values a replay of the
    simulator's own log gives, and an estimate that follows the truth."""
    nmea, tlog, log = tmp_path / "trial.nmea", tmp_path / "trial.tlog", tmp_path / "sim.mcap"
    seconds = 60.0  # hassani's 10 m step starts at 40 s: the thrusters work
    argv = ["sim", "--scenario", "hassani", "--duration", str(seconds), "--seed", "3"]
    assert main([*argv, "--nmea", f"file://{nmea}", "--tlog", str(tlog), "--out", str(log), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["tlog"]["records"] == summary["emissions"]["thrusters"] > 0
    assert (
        main(["replay", str(nmea), str(tlog), "--vessel", "cybership2", "--out", str(tmp_path / "a.mcap")])
        == 0
    )
    assert main(["replay", str(log), "--out", str(tmp_path / "b.mcap")]) == 0
    capsys.readouterr()

    fed, own = _feedback(tmp_path / "a.mcap"), _feedback(tmp_path / "b.mcap")
    stamps = np.array(sorted(fed))
    assert len(stamps) == 5 * seconds + 1 and np.allclose(np.diff(stamps), 0.2e9, rtol=0, atol=1e3)
    assert sorted(own) == sorted(fed)
    assert [fed[k]["thrusters"] for k in stamps] == [own[k]["thrusters"] for k in stamps]
    assert max(abs(fed[k]["tau_allocated"][0]) for k in stamps) > 1.0  # the step was driven: real values

    truth = [(m["stamp_ns"], *m["eta_lf"][:2]) for _, _, _, m in read_messages(log, "/truth/state")]
    t_truth, n_truth, e_truth = (np.array(c, dtype=float) for c in zip(*truth, strict=True))
    est = [
        (m["stamp_ns"], *m["eta"][:2]) for _, _, _, m in read_messages(tmp_path / "a.mcap", "/dp/estimate")
    ]
    assert len(est) >= 10 * (seconds - 1)  # one per NMEA cycle (RTK and gyro at 10 Hz)
    t_est, n_est, e_est = (np.array(c, dtype=float) for c in zip(*est, strict=True))
    settled = t_est >= t_est[0] + 5e9
    error = np.hypot(n_est - np.interp(t_est, t_truth, n_truth), e_est - np.interp(t_est, t_truth, e_truth))
    assert float(np.sqrt(np.mean(error[settled] ** 2))) < 0.1  # m, through a 10 m step


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--scenario", "fossen_strand_1999", "--tlog", "{d}/x.tlog"], "has no thrusters that report"),
        (["--scenario", "hassani", "--tlog", "{d}/nope/deeper/x.tlog"], "neither the folder"),
        (["--scenario", "hassani", "--tlog", "{d}"], "a folder, not a file"),
        (["--scenario", "hassani", "--tlog", "{d}/x.mcap"], "a tlog is not an MCAP log"),
        (
            ["--scenario", "hassani", "--nmea", "file://{d}/x.tlog", "--tlog", "{d}/x.tlog"],
            "--nmea file://",
        ),
        (
            ["--scenario", "hassani", "--nmea", "gyro1=file://{d}/x.tlog", "--tlog", "{d}/x.tlog"],
            "writes to the same file",
        ),
        (["--scenario", "hassani", "--mavlink", "file://{d}/x.tlog", "--tlog", "{d}/x.tlog"], "--mavlink"),
        (
            ["--scenario", "hassani", "--nmea", "{d}/x.tlog", "--tlog", "{d}/x.tlog"],
            "writes to the same file",
        ),
        (
            ["--vessel", "mss_osv", "--inputs", "{d}/in.csv", "--tlog", "{d}/x.tlog"],
            "--tlog: only with --scenario",
        ),
    ],
)
def test_a_tlog_that_cannot_be_written_stops_at_once_saying_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], says: str
) -> None:
    argv = ["sim", "--duration", "1", *(a.format(d=tmp_path) for a in args)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("dpgw sim: ") and says in err and "\n" not in err, err
    assert not (tmp_path / "x.tlog").exists()


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, 2**53),  # µs since 1970
            st.integers(1, 8),  # thruster id
            st.floats(-1e6, 1e6, allow_nan=False),  # thrust, N
        ),
        max_size=20,
    )
)
def test_tlog_records_read_back_as_written(tmp_path_factory: pytest.TempPathFactory, rows: list) -> None:
    """Whatever the times and frames, `tlog_events` gives back each record's time and frame as written."""
    path = tmp_path_factory.mktemp("tlog") / "x.tlog"
    mav = mv.encoder(1, 1)
    written = [
        (t_us, mv.azimuth_status_frame(mav, t_us, tid, thrust, 0.0, 0.0, 0)) for t_us, tid, thrust in rows
    ]
    with TlogWriter(path) as w:
        for t_us, frame in written:
            w.write(t_us, [frame])
    counts = LogCounts()
    assert [(e.rx_ns // 1000, e.data) for e in tlog_events(path, "x", counts)] == written
    assert not counts.counts and w.records == len(written)


def test_an_existing_tlog_is_left_as_it_was_when_start_up_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tlog is made when opened, so it is opened last: a run that stops at start-up (here Zenoh cannot
    listen on an address this machine does not have) leaves yesterday's tlog of that name whole."""
    old = tmp_path / "trial.tlog"
    old.write_bytes(b"yesterday's sea trial")
    argv = ["sim", "--scenario", "hassani", "--duration", "1", "--tlog", str(old), "--zenoh",
            "--zenoh-listen", "tcp/192.0.2.1:7447", "--no-scouting"]  # fmt: skip
    assert main(argv) == 2
    assert "cannot listen on tcp/192.0.2.1:7447" in capsys.readouterr().err
    assert old.read_bytes() == b"yesterday's sea trial"


def test_a_tlog_that_exists_is_kept_and_the_run_goes_on_in_the_next_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bench restarting the simulator with the same command line wrote over the tlog of the run before
    (the MCAP log was kept already): now the tlog goes on in the next file of its set, said on the console."""
    old = tmp_path / "trial.tlog"
    old.write_bytes(b"yesterday's sea trial")
    argv = ["sim", "--scenario", "hassani", "--duration", "2", "--tlog", str(old), "--json"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    said = f"MAVLink (tlog) -> {tmp_path / 'trial_0001.tlog'} ({old} exists: a tlog is never overwritten)"
    assert said in err, err
    assert old.read_bytes() == b"yesterday's sea trial"
    assert (tmp_path / "trial_0001.tlog").stat().st_size > 0
    assert main(argv) == 0 and (tmp_path / "trial_0002.tlog").exists()
