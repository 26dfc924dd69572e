"""`dpgw replay GATEWAY.mcap --truth SIM.mcap`: a HIL bench's gateway log scored against the simulator's
truth, the truth moved into the gateway's frame; and both logs given as LOG (every sentence fed twice) is
refused with the command that scores them. The two-process bench itself is in test_hil_bench."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import simulator_log

from dpgw.replay_truth import fed_twice, to_replay_frame, truth_log_problem
from gateway.replay import logged_datum, open_inputs, truth_records
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.geodesy import LocalFrame
from wire.mcap.writer import McapLogWriter


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulator_log(tmp_path_factory.mktemp("truth") / "sim.mcap", "torsetnes_2004", 2, 30.0)


def gateway_like(path: Path) -> Path:
    """A log with a gateway's configuration record and no simulator description (what `dpgw run` writes
    at its start; `fed_twice` reads only that)."""
    with McapLogWriter(path) as w:
        w.add_metadata("dpgw.config", {"json": json.dumps({"vessel": {"name": "mss_supply"}})})
    return path


def test_the_truth_is_moved_into_the_replays_frame(sim_log: Path) -> None:
    datum = logged_datum(sim_log)
    assert datum is not None
    sim = LocalFrame(datum["lat_deg"], datum["lon_deg"], datum["alt_m"])
    # the gateway's datum (its first fix, or its config) 800 m south and 300 m west of the simulator's
    lat, lon, h = sim.to_geodetic(-800.0, -300.0, 0.0)
    gateway = LocalFrame(lat, lon, h)
    moved = to_replay_frame(sim_log, gateway)
    original = truth_records(sim_log)
    assert len(moved) == len(original) > 100
    for a, b in zip(original[::50], moved[::50], strict=True):
        # the same place on the earth: through the two frames to latitude and longitude
        la, lo, _ = sim.to_geodetic(a["eta_lf"][0], a["eta_lf"][1], 0.0)
        lb, lob, _ = gateway.to_geodetic(b["eta_lf"][0], b["eta_lf"][1], 0.0)
        assert abs(la - lb) < 1e-9 and abs(lo - lob) < 1e-9
        assert b["eta_lf"][0] - a["eta_lf"][0] == pytest.approx(800.0, abs=0.1)
        assert b["eta_lf"][1] - a["eta_lf"][1] == pytest.approx(300.0, abs=0.1)
        assert b["eta_lf"][2] == a["eta_lf"][2] and b["eta_wf"] == a["eta_wf"]
    assert to_replay_frame(sim_log, sim)[7] == original[7]  # the same datum: untouched


def test_a_gateway_log_and_its_simulators_log_together_are_refused(sim_log: Path, tmp_path: Path) -> None:
    gw = gateway_like(tmp_path / "hil.mcap")
    why = fed_twice(open_inputs([gw, sim_log]))
    assert why is not None and f"dpgw replay {gw} --truth {sim_log}" in why
    assert fed_twice(open_inputs([sim_log])) is None and fed_twice(open_inputs([gw])) is None
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(gw), str(sim_log), "--out", str(tmp_path / "o.mcap")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "feeds every sentence twice" in proc.stderr, proc.stderr
    assert "--truth" in proc.stderr and not (tmp_path / "o.mcap").exists()


def test_a_truth_log_must_be_a_simulators(sim_log: Path, tmp_path: Path) -> None:
    assert truth_log_problem(sim_log) is None
    assert "no such file" in (truth_log_problem(tmp_path / "none.mcap") or "")
    assert "not a simulator log" in (truth_log_problem(gateway_like(tmp_path / "gw.mcap")) or "")
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(sim_log), "--truth", str(sim_log)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "its own truth" in proc.stderr, proc.stderr


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two 90 s runs of one scenario, seeds 0 and 1: each one's simulator log (s0.mcap, s1.mcap) and its
    sentences as a text log (s0.nmea, s1.nmea)."""
    from simulator.runner import Route
    from simulator.transports import FileSink

    folder = tmp_path_factory.mktemp("runs")
    for seed in (0, 1):
        sink = FileSink(str(folder / f"s{seed}.nmea"))
        with McapLogWriter(folder / f"s{seed}.mcap") as w:
            Simulation(get_scenario("torsetnes_2004"), seed=seed, log=w, routes=[Route(sink, "nmea")]).run(
                90.0
            )
        sink.close()
    return folder


def replay_json(log: Path, *args: str) -> tuple[dict, str]:  # type: ignore[type-arg]
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(log), "--vessel", "mss_supply", *args, "--json"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(p.stdout), p.stderr


def test_the_truth_of_another_run_is_said_not_to_be_this_logs(two_runs: Path, tmp_path: Path) -> None:
    """Before: a text log of seed 1 scored against seed 0's truth (same scenario, same times) printed RMS
    errors of tens of metres as the observer's own, without a word. The truth's motion is compared with
    the log's own measurements; another run's is said not to be this log's (stderr, `truth_mismatch` in
    the JSON), the run's own truth says nothing."""
    wrong, right = two_runs / "s0.mcap", two_runs / "s1.mcap"
    doc, err = replay_json(two_runs / "s1.nmea", "--truth", str(wrong), "--out", str(tmp_path / "a.mcap"))
    far = doc["truth_mismatch"]
    assert far["median_position_m"] > 10.0 or far["median_heading_deg"] > 10.0
    assert f"--truth: {wrong} is not this log's" in err and "another run's truth" in err
    doc, err = replay_json(two_runs / "s1.nmea", "--truth", str(right), "--out", str(tmp_path / "b.mcap"))
    assert "truth_mismatch" not in doc and "not this log's" not in err
    assert doc["error_vs_truth"]["passive"]["rms_north_m"] < 2.0


def test_a_wrong_lever_arm_is_said_as_an_offset_not_another_runs_truth(
    two_runs: Path, tmp_path: Path
) -> None:
    """The run's own truth, replayed on a config whose DGPS lever arm is 10 m forward and 2 m to port of
    the simulator's antenna: the measured reference point sits a steady 10.2 m off the truth. Before,
    "not this log's ... give the simulator log of the run that made this log", which it was; now the
    offset in the vessel's frame, as the antenna's place relative to the config's arm."""
    cfg = tmp_path / "vessel.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n'
        '[[sources]]\nname = "dgps1"\nurl = "udp://127.0.0.1:0"\nprotocol = "nmea"\nroles = ["position"]\n'
        "lever_arm_m = [10.0, -2.0, 0.0]\n"
        '[[sources]]\nname = "gyro1"\nurl = "udp://127.0.0.1:0"\nprotocol = "nmea"\nroles = ["heading"]\n'
    )
    log, truth = two_runs / "s1.nmea", two_runs / "s1.mcap"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(log), "--config", str(cfg), "--source", f"dgps1={log}",
         "--source", f"gyro1={log}", "--truth", str(truth), "--out", str(tmp_path / "o.mcap"), "--json"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    far = json.loads(p.stdout)["truth_mismatch"]
    forward, starboard = far["steady_offset_body_m"]
    assert forward == pytest.approx(-10.0, abs=0.5) and starboard == pytest.approx(2.0, abs=0.5), far
    said = f"{forward:+.1f} m forward and {starboard:+.1f} m to starboard of where the config's lever arm"
    assert "sit a steady 10." in p.stderr and said in p.stderr, p.stderr
    assert "not this log's" not in p.stderr


def test_the_summary_and_the_report_leave_out_the_same_start(two_runs: Path, tmp_path: Path) -> None:
    """A gateway joins a simulation already running and stops before it (a HIL bench): the truth spans
    more than the log. Before, the summary's errors left out 10 % of the truth's span and the report 10 %
    of the log's (35.5 s against 29.2 s on a bench run), so the two printed different RMS errors of one
    replay. Both now take the log's own span."""
    lines = (two_runs / "s1.nmea").read_text().splitlines(keepends=True)
    half = tmp_path / "second_half.nmea"
    half.write_text("".join(lines[len(lines) // 2 :]))
    doc, _ = replay_json(half, "--truth", str(two_runs / "s1.mcap"), "--out", str(tmp_path / "h.mcap"),
                         "--report", str(tmp_path / "report"))  # fmt: skip
    metrics = json.loads((tmp_path / "report" / "metrics.json").read_text())
    assert doc["settle_s"] == metrics["settle_s"] == pytest.approx(0.1 * metrics["duration_s"], abs=0.1)
    e, r = doc["error_vs_truth"]["passive"], metrics["observers"]["passive"]
    assert e["samples"] == r["north"]["truth_samples"]
    assert e["rms_north_m"] == pytest.approx(r["north"]["rms_error"], rel=1e-9)
    assert e["rms_east_m"] == pytest.approx(r["east"]["rms_error"], rel=1e-9)
