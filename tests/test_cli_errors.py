"""A new user's first mistakes: each stops with one line naming what, where and what to do (never a
traceback), and what the help pages and --json print can be used as printed."""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import free_port
from hypothesis import given, settings
from hypothesis import strategies as st

from dpgw import cli_json
from dpgw.cli import build_parser, main, subparser

REPO = Path(__file__).resolve().parents[1]


def _one_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


# --- dpgw replay on something that is not a log ----------------------------------------------------------


def test_replay_of_an_empty_file_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "trial.mcap"
    log.write_bytes(b"")
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 2
    assert _one_line(capsys.readouterr().err) == f"dpgw replay: {log}: empty file: nothing to replay"


def test_replay_of_a_non_mcap_file_named_mcap_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "trial.mcap"
    log.write_bytes(random.Random(1).randbytes(4000))
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw replay: {log}: not an MCAP file"), line
    assert not (tmp_path / "trial-replay.mcap").exists()


def test_replay_of_binary_data_finds_nothing_and_says_what_to_give(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "capture.dat"
    log.write_bytes(random.Random(2).randbytes(5000))
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw replay: nothing to replay in {log}: no NMEA sentence with a time"), line
    assert "no_time" in line  # what the reader found in it
    assert "an NMEA 0183 text log or a MAVLink tlog" in line
    assert not (tmp_path / "capture-replay.mcap").exists()  # no empty output left behind


def test_replay_of_a_folder_says_it_is_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "logs"
    folder.mkdir()
    assert main(["replay", str(folder), "--vessel", "mss_supply"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert (
        line == f"dpgw replay: {folder}: a folder, not a log file: give the logs in it (e.g. {folder}/*.mcap)"
    )


def test_replay_without_a_vessel_says_which_log_names_none(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = tmp_path / "trial.txt"
    text.write_text("$GPGGA,120000.00,5924.0,N,01030.0,E,2,08,0.9,10.0,M,40.0,M,,*4C\r\n")
    assert main(["replay", str(text)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line == (
        f"dpgw replay: {text}: names no vessel (an NMEA text log or a tlog does not): give --vessel "
        "NAME|FILE or --config FILE"
    )
    mcap = tmp_path / "other.mcap"
    mcap.write_bytes(b"\x89MCAP0\r\n" + bytes(12))  # an MCAP file cut just after its magic
    assert main(["replay", str(mcap)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw replay: {mcap}: carries no configuration"), line
    assert line.endswith("give --vessel NAME|FILE or --config FILE"), line


def test_replay_of_a_raw_mavlink_stream_says_it_is_no_tlog(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw sim --mavlink file://x.tlog` writes frames without record times; before, replay read them as
    tlog records (bad_record, bad_time) and ran on without the thrusters, or found 'nothing to replay'."""
    raw = tmp_path / "thrusters.tlog"
    assert main(["sim", "--scenario", "hassani", "--duration", "2", "--mavlink", f"file://{raw}"]) == 0
    capsys.readouterr()
    assert raw.stat().st_size > 0
    assert main(["replay", str(raw), "--vessel", "cybership2"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw replay: {raw}: a raw MAVLink byte stream (frames without record times"), (
        line
    )
    assert not (tmp_path / "thrusters-replay.mcap").exists()


def _tlog_record(t_us: int) -> bytes:
    """A tlog record: the time (µs, big-endian) and an (empty, unchecked) MAVLink 2 frame of 12 bytes."""
    return struct.pack(">Q", t_us) + b"\xfd\x00" + bytes(10)


def test_a_tlog_time_no_log_can_hold_is_counted_not_fatal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from gateway.logreaders import LogCounts, tlog_events

    log = tmp_path / "link.tlog"
    log.write_bytes(_tlog_record(2**64 - 1) + _tlog_record(1_700_000_000_000_000))
    counts = LogCounts()
    events = list(tlog_events(log, "mav", counts))
    assert [e.rx_ns for e in events] == [1_700_000_000_000_000_000]
    assert counts.counts["bad_time"] == 1
    log.write_bytes(_tlog_record(2**64 - 1))
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 2  # before: struct.error from the writer
    assert "bad_time 1" in _one_line(capsys.readouterr().err)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600))
def test_tlog_reader_yields_only_times_a_log_can_hold(data: bytes) -> None:
    import tempfile

    from gateway.logreaders import MAX_TIME_NS, tlog_events

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "x.tlog"
        path.write_bytes(data)
        assert all(0 <= e.rx_ns <= MAX_TIME_NS for e in tlog_events(path))


# --- dpgw listen with nobody there -----------------------------------------------------------------------


def test_listen_with_nothing_at_connect_says_so_and_fails() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--connect", endpoint, "--duration", "0.5"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert p.returncode == 1 and p.stdout == ""
    line = _one_line(p.stderr)
    assert line.startswith(f"dpgw listen: nothing on dp/** in 0.5 s: nothing answered at {endpoint}"), line


# --- argparse --------------------------------------------------------------------------------------------


def test_an_unknown_option_shows_the_commands_usage(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["run", "--config", "vessel.toml", "--observer", "ekf"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: dpgw run ") and "--config FILE" in err
    assert err.strip().endswith("dpgw run: error: unrecognized arguments: --observer ekf")


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: subparser(parser, name) for name in sub.choices}


@pytest.mark.parametrize("command", sorted(_subparsers()))
def test_examples_are_whole_commands_on_an_80_column_terminal(
    command: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each example command is on one line as written (its comment may move above it): copied, it runs."""
    monkeypatch.setenv("COLUMNS", "80")
    parser = _subparsers()[command]
    shown = [line.strip() for line in parser.format_help().splitlines()]
    for line in (parser.epilog or "").splitlines():
        stripped = line.strip()
        if not line.startswith(" ") or not stripped.startswith(("dpgw ", "--")):
            continue
        command_part, _, comment = stripped.partition("  #")
        assert command_part.strip() in shown or stripped in shown, f"broken example: {stripped}"
        if comment:
            assert any(comment.strip() in s for s in shown)


@pytest.mark.parametrize("command", sorted(_subparsers()))
def test_example_files_exist(command: str) -> None:
    text = _subparsers()[command].format_help()
    for path in re.findall(r"\bexamples/[\w./-]+", text) + re.findall(r"--file ([\w/-]+/[\w./-]+)", text):
        assert (REPO / path.rstrip(".")).exists(), f"dpgw {command} --help names {path}, which is not there"


def test_observer_names_are_the_registered_ones() -> None:
    from observers.factory import OBSERVER_TYPES
    from observers.observer_names import OBSERVER_NAMES

    assert OBSERVER_NAMES == OBSERVER_TYPES


# --- --json: standard JSON -------------------------------------------------------------------------------


def test_json_output_has_no_nan_or_infinity() -> None:
    text = cli_json.dumps({"rms": math.nan, "T": [[math.inf, 0.0], [0.0, -math.inf]], "n": 3, "ok": 0.5})
    assert json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in {text}")) == {
        "rms": None, "T": [[None, 0.0], [0.0, None]], "n": 3, "ok": 0.5,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("key", "says"),
    [
        ("/dp/estimate", "— did you mean 'dp/*/estimate'?"),  # an MCAP topic given as a key: <prefix>/X
        ("dp//x", "— did you mean 'dp/x'?"),
        ("dp/#", "(`#` and `?` are forbidden characters)."),
        ("dp/**/**", "`**/**` must be replaced by `**`"),
    ],
)
def test_listen_to_a_key_that_is_not_one_says_what_to_write(
    key: str, says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: a Zenoh traceback (ZError ... at /root/.cargo/...borrowed.rs:777)."""
    assert main(["listen", key, "--duration", "1", "--no-scouting"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw listen: '{key}' is not a Zenoh key expression ("), line
    assert says in line and ".rs:" not in line
    assert "with no leading or trailing '/'" in line


@pytest.mark.parametrize(
    "argv",
    [
        ["sim", "--scenario", "hassani", "--duration", "1", "--zenoh", "--prefix", "/dp/x"],
        ["replay", "x.mcap", "--speed", "100", "--prefix", "/dp/x"],
    ],
)
def test_a_prefix_that_is_no_key_is_refused_before_anything_starts(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: a Zenoh traceback at the first put (the replay after reading its logs)."""
    assert main(argv) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw {argv[0]}: --prefix: empty chunk in the key expression"), line
    assert 'e.g. dp/my_ship, got "/dp/x"' in line


def test_run_check_json_is_the_check_for_a_program(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, --check ignored --json: a program checking a fleet's configs had to parse the text."""
    good = REPO / "examples" / "nmea_udp_multiplexer.toml"
    assert main(["run", "--config", str(good), "--check", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is True and out["problems"] == [] and out["config"] == str(good)
    assert out["summary"][0] == f"config {good}: ok"
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace("[observer]", "[observer]\nwave_perod_s = 9.0", 1))
    assert main(["run", "--config", str(bad), "--check", "--json"]) == 2
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is False and out["summary"] == []
    assert any("observer.wave_perod_s: unknown key" in p for p in out["problems"]), out
    assert main(["run", "--config", str(tmp_path / "nope.toml"), "--check", "--json"]) == 2
    assert json.loads(capsys.readouterr().out)["problems"] == [
        f"{tmp_path / 'nope.toml'}: cannot read: no such file"
    ]


def test_run_gives_its_caller_back_its_signal_handlers(capsys: pytest.CaptureFixture[str]) -> None:
    """`dpgw run` takes SIGINT and SIGTERM from its first line; called in a process that goes on (a test, a
    program calling `main`), it left them installed: a Ctrl-C afterwards only set its finished run's flag,
    and a replay run next in the same process never stopped."""
    import signal

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    good = REPO / "examples" / "nmea_udp_multiplexer.toml"
    assert main(["run", "--config", str(good), "--check", "--json"]) == 0
    capsys.readouterr()
    assert {s: signal.getsignal(s) for s in before} == before


def test_output_to_a_reader_that_has_gone_stops_quietly(tmp_path: Path) -> None:
    """`dpgw tune --json | head -1`: the reader stops reading; before, a BrokenPipeError traceback. The
    pipe's read end is closed before the command starts, so its first write fails, whatever the timing."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "dpgw", "tune", "--vessel", "mss_supply", "--wave-period", "9", "--json"],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert proc.stderr == "", proc.stderr
    assert proc.returncode == 128 + 13


def test_replay_vessel_mistakes_name_the_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Before, --vessel was reported as the config key it becomes: 'dpgw: the configuration has 1 problem ...
    vessel.name: ... or give file = "my_ship.toml" ... Every key is described in docs/config.md'."""
    log = tmp_path / "trial.txt"
    log.write_text("$HEHDT,45.0,T*2E\r\n")
    assert main(["replay", str(log), "--vessel", "mss_suply"]) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        "dpgw replay: --vessel: vessel 'mss_suply': not a built-in vessel, did you mean \"mss_supply\"? ("
    )
    gateway_config = REPO / "examples" / "hil_bench.toml"
    assert main(["replay", str(log), "--vessel", str(gateway_config)]) == 2
    assert _one_line(capsys.readouterr().err) == (
        f"dpgw replay: --vessel: {gateway_config}: a gateway configuration ([vessel], [[sources]]), not a "
        "vessel file (its [vessel] table names the vessel; a vessel file has name, mass and the matrices: "
        "docs/vessels.md)"
    )


def test_study_stopped_with_ctrl_c_says_what_is_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before: a KeyboardInterrupt traceback from wherever the study was (a case, Dask, matplotlib); then
    what was kept, but not how many cases. (A real Ctrl-C, SIGTERM, SIGHUP: tests/test_study_process.py.)"""
    import dpgw.study.runner

    def interrupted(*_args: object, **_kwargs: object) -> None:
        stop = dpgw.study.runner.StudyInterrupted()
        stop.done, stop.total = 3, 8
        raise stop

    monkeypatch.setattr(dpgw.study.runner, "run_study", interrupted)
    # (scored after every observer settled: the MMAE's bank, ~126 s, the latest; no warning before the run)
    argv = ["study", "--scenario", "hassani", "--seeds", "0", "--settle", "130", "--serial", "--out",
            str(tmp_path / "s")]  # fmt: skip
    assert main(argv) == 130
    assert _one_line(capsys.readouterr().err) == (
        f"dpgw study: stopped (Ctrl-C); 3 of 8 cases done and cached in {tmp_path / 's' / 'cache'}: the "
        "same command resumes from them"
    )


def test_an_mcap_output_that_is_a_folder_or_not_mcap_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `dpgw run --log logs` (an existing folder) wrote logs_0001, a file without .mcap, beside it;
    `--log trial.txt` and `dpgw sim/replay --out x.txt` wrote MCAP files named .txt that replay then read
    as NMEA text; `dpgw replay --out DIR` said '[Errno 21] Is a directory'."""
    folder = tmp_path / "logs"
    folder.mkdir()
    text = tmp_path / "trial.txt"
    config = REPO / "examples" / "nmea_udp_multiplexer.toml"
    cases = [
        # (--duration: a regression runs briefly and fails, instead of running on)
        (
            ["run", "--config", str(config), "--log", str(folder), "--duration", "2"],
            "dpgw run: --log",
            "a folder",
        ),
        (
            ["run", "--config", str(config), "--log", str(text), "--duration", "2"],
            "dpgw run: --log",
            "not an MCAP",
        ),
        (
            ["sim", "--scenario", "hassani", "--duration", "1", "--out", str(text)],
            "dpgw sim: --out",
            "not an MCAP",
        ),
        (
            ["replay", str(REPO / "README.md"), "--out", str(folder)],
            "dpgw replay: --out",
            "a folder, not a file",
        ),
        (["demo", "--out", str(text), "--duration", "2", "--no-foxglove"], "dpgw demo: --out", "not an MCAP"),
    ]
    for argv, head, words in cases:
        assert main(argv) == 2, argv
        line = _one_line(capsys.readouterr().err)
        assert line.startswith(head) and words in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs"]  # nothing written
    assert list(folder.iterdir()) == []


def test_tune_refuses_an_infinite_wave_period(capsys: pytest.CaptureFixture[str]) -> None:
    """Before: 'tuning 'omega0': must be positive (per DOF or one for all), got [0.0, 0.0, 0.0]'."""
    assert main(["tune", "--vessel", "mss_supply", "--wave-period", "inf"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        "dpgw tune: --wave-period must be a positive, finite number of seconds"
    )


def test_tune_json_is_standard_json() -> None:
    """The default random-walk bias has T = inf: printed as null, not Infinity (which most parsers reject)."""
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "tune", "--vessel", "mss_supply", "--wave-period", "9", "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout, parse_constant=lambda c: pytest.fail(f"{c} in dpgw tune --json"))
    assert doc["T"][0][0] is None and doc["K1"]


# --- dpgw demo's summary ---------------------------------------------------------------------------------


def test_demo_too_short_to_score_says_how_long_to_run(capsys: pytest.CaptureFixture[str]) -> None:
    from dpgw.cli_demo import SETTLE_S, needed_duration_s, print_summary

    nan = math.nan
    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 50.0, "wall_seconds": 5.0, "log": "d.mcap",
            "logs": ["d.mcap"],
            "sources": {}, "sent": {}, "estimates": 10, "alarms": [], "settle_s": SETTLE_S,
            "error_vs_truth": {"samples": 0, "horizontal_rms_m": nan},
            "station_keeping": {
                "position_p95_m": 1.0, "heading_p95_deg": 1.0, "reference": [0.0, -0.0001, 45.0],
                "north_mean_m": 0.1, "east_mean_m": -0.1, "heading_mean_deg": 0.5,
                "dp_engaged_s": 1.0, "scored_from_s": 60.0,
            },
        }
    )  # fmt: skip
    out = capsys.readouterr().out
    assert f"give --duration {needed_duration_s(None)} or more" in out
    assert "-0.0" not in out and "(0.0 m N, 0.0 m E, 45.0 deg)" in out


def test_demo_ended_before_dp_was_engaged_says_what_to_do(capsys: pytest.CaptureFixture[str]) -> None:
    """A demo shorter than its engage time (150 s, then 30 s before scoring, on at least 30 s) has no
    station keeping to score: the summary says why and how to get one, instead of leaving the line out."""
    from dpgw.cli_demo import print_summary

    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 120.0, "wall_seconds": 12.0, "log": "d.mcap",
            "logs": ["d.mcap"], "sources": {}, "sent": {}, "estimates": 500, "alarms": [],
            "settle_s": 60.0, "engage_at_s": 150.0,
            "error_vs_truth": {"samples": 100, "horizontal_rms_m": 0.3, "horizontal_p95_m": 0.5,
                               "rms_heading_deg": 0.3},
            "station_keeping": None,
        }
    )  # fmt: skip
    out = capsys.readouterr().out
    assert "station keeping: not scored: the run ended at 120 s before DP was engaged" in out
    assert "scored from 180 s, on at least 30 s; give --duration 211 or more" in out
    assert "--engage-at 0" in out


def test_demo_of_60_s_advises_only_what_would_score(capsys: pytest.CaptureFixture[str]) -> None:
    """`dpgw demo --duration 60`: nothing is scored; the advice names a duration that scores, and not
    --engage-at 0 (DP from the start is scored from 60 s too, which a 60 s run never reaches); the
    estimate's 'not scored' is said where its figures would be, before the station keeping."""
    from dpgw.cli_demo import print_summary

    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 60.0, "wall_seconds": 6.0, "log": "d.mcap",
            "logs": ["d.mcap"], "sources": {}, "sent": {}, "estimates": 700, "alarms": [],
            "settle_s": 60.0, "engage_at_s": 150.0, "mode": "dp",
            "error_vs_truth": {"samples": 0, "horizontal_rms_m": math.nan, "horizontal_p95_m": math.nan,
                               "rms_heading_deg": math.nan},
            "station_keeping": None,
        }
    )  # fmt: skip
    out = capsys.readouterr().out
    assert "--engage-at 0" not in out and "give --duration 211 or more" in out
    assert out.index("LF estimate vs truth: not scored") < out.index("station keeping: not scored")


def test_demo_in_standby_says_it_kept_no_station(capsys: pytest.CaptureFixture[str]) -> None:
    from dpgw.cli_demo import print_summary

    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 360.0, "wall_seconds": 36.0, "log": "d.mcap",
            "logs": ["d.mcap"], "sources": {}, "sent": {}, "estimates": 4300, "alarms": [],
            "settle_s": 60.0, "engage_at_s": None, "mode": "standby",
            "error_vs_truth": {"samples": 100, "horizontal_rms_m": 0.9, "horizontal_p95_m": 1.5,
                               "rms_heading_deg": 0.4},
            "station_keeping": None,
        }
    )  # fmt: skip
    assert "station keeping: none in standby" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["demo", "--duration", "-5"], "argument --duration: must be a positive number (got -5)"),
        (["demo", "--speed", "0"], "argument --speed: must be a positive number (got 0)"),
        (
            ["sim", "--scenario", "hassani", "--duration", "nan"],
            "argument --duration: must be a finite number",
        ),
        (["replay", "x.mcap", "--settle", "-1"], "argument --settle: must be a number >= 0 (got -1)"),
        (["replay", "x.mcap", "--speed", "-1"], "argument --speed: must be a positive number (got -1)"),
        (["listen", "--count", "0"], "argument --count: must be 1 or more (got 0)"),
        (
            ["run", "--config", "x.toml", "--duration", "abc"],
            "argument --duration: must be a number (got abc)",
        ),
        # before: "invalid _seeds value: 'x'" (the function's name) and "'seeds' is empty"
        (["study", "--seeds", "x"], "argument --seeds: 'x': expected whole numbers and ranges, e.g. 0-7,9"),
        (["study", "--seeds", "0-3,7-5"], "argument --seeds: '7-5': an empty range (write 5-7)"),
        (["study", "--hs", "2,four"], "argument --hs: '2,four': expected numbers separated by commas"),
    ],
)
def test_a_duration_speed_or_count_that_cannot_be_is_refused(
    argv: list[str], words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, `dpgw demo --duration -5` ran, wrote an empty demo.mcap and exited 0."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: dpgw {argv[0]} ") and f"dpgw {argv[0]}: error: {words}" in err


# --- commands as the README prints them ------------------------------------------------------------------


def test_run_foxglove_without_a_value_serves_on_the_configs_port(tmp_path: Path) -> None:
    """`dpgw run --config FILE --foxglove` (README, dpgw run --help) stopped with "'config' is not
    [HOST:]PORT": argparse passed the bare option's string marker through the address check."""
    from dpgw.cli_foxglove import FROM_CONFIG

    args = build_parser().parse_args(["run", "--config", "vessel.toml", "--foxglove"])
    assert args.foxglove is FROM_CONFIG
    port = free_port()
    cfg = tmp_path / "vessel.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\nwave_period_s = 9.0\n'
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{free_port()}"]\nmulticast_scouting = false\n[log]\npath = ""\n'
        f"[foxglove]\nport = {port}\n"
    )
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--foxglove", "--duration", "0.5"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert f"ws://127.0.0.1:{port}" in p.stderr


def _example_commands() -> list[str]:
    """Every example command of every help page, continuation lines joined, comments and pipes cut."""
    commands = []
    for parser in _subparsers().values():
        pending = ""
        for line in (parser.epilog or "").splitlines():
            text = pending + " " + line.strip() if pending else line.strip()
            if text.endswith("\\"):
                pending = text[:-1].strip()
                continue
            pending = ""
            if text.startswith("dpgw "):
                commands.append(text.split("  #")[0].split(" | ")[0].strip())
    return commands


DOCS = [REPO / "README.md", REPO / "examples" / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def _doc_commands() -> list[str]:
    """Every `dpgw …` command in a code block of README.md, examples/README.md and docs/*.md, as a reader
    copies it: continuation lines joined, a path before `dpgw` (`.venv/bin/dpgw`), `sudo`, comments and
    pipes cut, `&&`-chains split."""
    commands = []
    for doc in DOCS:
        for block in re.findall(r"```[a-z]*\n(.*?)```", doc.read_text(encoding="utf-8"), re.S):
            pending = ""
            for line in block.splitlines():
                text = pending + " " + line.strip() if pending else line.strip()
                if text.endswith("\\"):
                    pending = text[:-1].strip()
                    continue
                pending = ""
                for part in re.split(r" && | ; ", text):
                    part = re.sub(r"^(sudo (-u \w+ )?)?\S*?(?=\bdpgw )", "", part.strip())
                    if part.startswith("dpgw "):
                        commands.append(part.split("  #")[0].split(" | ")[0].strip())
    return commands


def test_the_docs_have_commands_to_check() -> None:
    commands = _doc_commands()
    assert "dpgw demo" in commands  # README's `.venv/bin/dpgw demo`
    assert "dpgw run --config examples/two_serial_nmea_mavlink.toml --check" in commands


@pytest.mark.parametrize("command", _doc_commands())
def test_every_command_in_the_docs_parses(command: str) -> None:
    """What README.md and docs/ print, the parser takes (files they name may be placeholders; the example
    configs and study files they name are loaded by tests/test_config.py and tests/test_study.py)."""
    import shlex

    build_parser().parse_args(shlex.split(command)[1:])


def test_every_option_the_docs_name_exists() -> None:
    """Every `--option` the docs write after `dpgw COMMAND` (whole commands, usage lines and mentions such
    as `dpgw replay --settle S`) is an option of that command: a renamed or removed option shows here."""
    parsers = _subparsers()
    wrong, seen = [], 0
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        mentions = re.findall(r"`(dpgw [^`]+)`", text) + re.findall(r"(?m)^\s*(?:\S*/)?(dpgw \w+ .*)$", text)
        for mention in mentions:
            words = mention.split()
            if words[1] not in parsers:
                continue
            known = {o for action in parsers[words[1]]._actions for o in action.option_strings}
            for word in words[2:]:
                for option in re.findall(r"(?:^|[\[/])(--[a-z][\w-]*)", word):
                    seen += 1
                    if option not in known:
                        wrong.append(f"{doc.name}: {mention!r}: {option}")
    assert seen > 100  # the docs name options, and they were found
    assert not wrong, wrong


@pytest.mark.parametrize("command", _example_commands())
def test_every_help_example_parses(command: str) -> None:
    """What an example asks for, the parser takes (the files it names are placeholders)."""
    import shlex

    build_parser().parse_args(shlex.split(command)[1:])  # SystemExit on an option the command refuses


def test_replay_runs_the_configs_observer_by_default(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without --observer a replay runs the observer its config names (a gateway log: what ran live), not
    always the passive one."""
    log = tmp_path / "gps.txt"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--duration", "20",
         "--nmea", f"file://{log}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    cfg = tmp_path / "ekf.toml"
    cfg.write_text(
        '[vessel]\nname = "cybership2"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\ntype = "ekf"\nwave_period_s = 6.0\n'
        '[log]\npath = ""\n'
    )
    out = tmp_path / "again.mcap"
    assert main(["replay", str(log), "--config", str(cfg), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert list(summary["estimates"]) == ["ekf"] and summary["estimates"]["ekf"] > 0


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('[[fault]]\nkind = "dropout"\nsource = "dgps1"\nt_start = 1.0\n', "unknown key 'fault'"),
        ("# nothing yet\n", "no [[faults]] table"),
    ],
)
def test_a_fault_file_without_faults_is_refused(
    text: str, words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, a misspelt [[fault]] table ran the scenario without its faults and exited 0."""
    faults = tmp_path / "faults.toml"
    faults.write_text(text)
    assert main(["sim", "--scenario", "hassani", "--faults", str(faults), "--duration", "1"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"dpgw sim: {faults}: {words}"), line


def test_replay_with_an_unknown_vessel_name_lists_the_built_in_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: "vessel.file: no such file .../nope": a misspelt name was taken for a file."""
    log = tmp_path / "gps.txt"
    log.write_text("$GPGGA,100000.00,5924.000000,N,01029.999988,E,4,12,0.80,20.259,M,,,2.0,0001*11\r\n")
    assert main(["replay", str(log), "--vessel", "mss_suply"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    line = _one_line(err)
    assert line.startswith("dpgw replay: --vessel: vessel 'mss_suply': not a built-in vessel"), line
    assert "cybership2, hajivand_vessel, mss_osv, mss_supply" in line


# --- the analyst's commands: what they cannot do is said before the work, and --json is JSON ------------

OSV_INPUTS = REPO / "tests" / "data" / "mss-osv" / "steps_inputs.csv"


def test_sim_open_loop_refuses_scenario_options_and_prints_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, --duration, --realtime, --nmea ... were accepted with --inputs and ignored, and --json
    printed the plain-text line."""
    argv = ["sim", "--vessel", "mss_osv", "--inputs", str(OSV_INPUTS), "--csv", str(tmp_path / "s.csv")]
    assert main([*argv, "--duration", "100", "--realtime"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith("dpgw sim: --duration, --realtime: only with --scenario;"), line
    # before, a traceback (FileNotFoundError) after the whole run; a deeper missing folder than the file's
    # own is refused before the run, as a log's is (`wire.mcap.folder`; the own folder: test_log_folder.py)
    nowhere = tmp_path / "nope" / "s.csv"
    deeper = nowhere.parent / "deeper" / "s.csv"
    assert main([*argv[:-1], str(deeper)]) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        f"dpgw sim: --csv {deeper}: neither the folder {deeper.parent} nor its parent {nowhere.parent} exists"
    )
    assert not nowhere.parent.exists()
    deep = tmp_path / "nope" / "deeper" / "s.mcap"  # (only the file's own folder is made)
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--out", str(deep)]) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        f"dpgw sim: --out {deep}: neither the folder {deep.parent} nor its parent {nowhere.parent} exists"
    )
    assert not (tmp_path / "s.csv").exists()
    assert main([*argv, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    last = (tmp_path / "s.csv").read_text().strip().splitlines()[-1].split(",")
    assert summary["vessel"] == "mss_osv" and summary["rows"] == len(OSV_INPUTS.read_text().splitlines()) - 1
    assert [summary["end"][k] for k in ("t", "north", "east", "psi_deg")] == pytest.approx(
        [float(x) for x in last[:4]], rel=1e-8
    )


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--max-order", "1"], "argument --max-order: must be 2 or more"),
        (["--max-order", "0"], "argument --max-order: must be 2 or more: K(s) needs"),
        (["--r2", "0"], "argument --r2: must be above 0 and at most 1 (got 0)"),
        (["--r2", "1.5"], "argument --r2: must be above 0 and at most 1 (got 1.5)"),
    ],
)
def test_radiation_refuses_a_fit_setting_it_cannot_use(
    extra: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, --max-order 1 ended in a ValueError traceback and --r2 1.5 fitted every element to the cap."""
    with pytest.raises(SystemExit) as exit_:
        main(["radiation", str(tmp_path / "hydro.npz"), *extra])
    assert exit_.value.code == 2
    assert f"dpgw radiation: error: {words}" in capsys.readouterr().err


def test_radiation_and_replay_check_where_they_write_before_working(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, a stem in a missing folder was a FileNotFoundError traceback after the whole fit, and a
    --report that is a file a FileExistsError traceback after the whole replay."""
    hydro = tmp_path / "hydro.npz"
    hydro.write_bytes(b"not read: the check comes first")
    assert main(["radiation", str(hydro), "--out", str(tmp_path / "nope" / "fit")]) == 2
    assert _one_line(capsys.readouterr().err) == (
        f"dpgw radiation: --out {tmp_path}/nope/fit: no folder {tmp_path}/nope: "
        "create it or give another path"
    )
    # a misspelt vessel name was taken for a file stem: nope_radiation.npz written in the current folder
    assert main(["radiation", str(hydro), "--vessel", "nope"]) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        "dpgw radiation: --vessel: vessel 'nope': not a built-in vessel (cybership2,"
    )
    assert not list(Path.cwd().glob("nope_radiation.*"))
    log = tmp_path / "gps.txt"
    log.write_text("$GPGGA,100000.00,5924.000000,N,01029.999988,E,4,12,0.80,20.259,M,,,2.0,0001*11\r\n")
    (tmp_path / "afile").write_text("")
    assert main(["replay", str(log), "--vessel", "cybership2", "--report", str(tmp_path / "afile")]) == 2
    assert _one_line(capsys.readouterr().err).endswith(
        "afile: a file, not a folder: give a folder (it is created)"
    )
    assert (
        main(["replay", str(log), "--vessel", "cybership2", "--out", str(tmp_path / "nope" / "x.mcap")]) == 2
    )
    assert _one_line(capsys.readouterr().err).endswith(": create it or give another path")
    assert not (tmp_path / "gps-replay.mcap").exists()


def test_replay_says_why_an_observer_made_no_estimate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, a log without heading (gpsd's nmea-rtk.log) replayed with status 0, no observer line on the
    console and `"estimates": {}` in --json: the observer asked for was not even named."""
    from datetime import UTC, datetime, timedelta

    from wire.codecs.nmea_encode import gga

    t0 = datetime(2026, 5, 1, 10, 0, tzinfo=UTC)
    fixes = [
        gga("GP", t0 + timedelta(seconds=0.5 * k), 59.4 + 1e-6 * k, 10.5, 4, 12, 0.8, 20.0) for k in range(40)
    ]
    log = tmp_path / "gps.txt"
    log.write_bytes(b"".join(f if isinstance(f, bytes) else f.encode() for f in fixes))
    assert (
        main(
            [
                "replay",
                str(log),
                "--vessel",
                "mss_supply",
                "--observer",
                "passive",
                "--observer",
                "ekf",
                "--json",
            ]
        )
        == 0
    )
    out, err = capsys.readouterr()
    s = json.loads(out)
    assert s["estimates"] == {"passive": 0, "ekf": 0}
    m = s["measurements"]
    assert m["samples"] == 40 and m["position"] >= 35 and m["heading"] == 0
    assert _one_line(err).startswith(
        "dpgw replay: warning: observers 'passive', 'ekf' made no estimate: an observer needs position and "
        f"heading, and of the 40 fused measurements {m['position']} had a position and 0 a heading."
    )


def test_replay_with_a_settle_time_past_the_end_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `passive vs truth (after 1000 s): RMS N nan m, E nan m, heading nan deg`."""
    log = tmp_path / "sim.mcap"
    assert main(["sim", "--scenario", "fossen_strand_1999", "--duration", "20", "--out", str(log)]) == 0
    capsys.readouterr()
    assert main(["replay", str(log), "--settle", "1000"]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out
    assert (
        "  passive vs truth: no estimate after the settle time 1000 s to score (give a shorter --settle)"
        in out
    )


def test_replay_refuses_an_observer_label_given_twice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, `--observer passive --observer passive` printed one observer with twice the estimates, and
    `passive@a --observer ekf@a` counted and published both under one label."""
    log = tmp_path / "gps.txt"
    log.write_text("$GPGGA,100000.00,5924.000000,N,01029.999988,E,4,12,0.80,20.259,M,,,2.0,0001*11\r\n")
    for specs in (["passive", "passive"], ["passive@a", "ekf@a"]):
        argv = ["replay", str(log), "--vessel", "mss_supply"] + [f"--observer={s}" for s in specs]
        assert main(argv) == 2
        label = specs[0].partition("@")[2] or "passive"
        assert _one_line(capsys.readouterr().err) == (
            f"dpgw replay: --observer: label '{label}' given twice (name each: SPEC@label)"
        )


def test_replay_report_counts_each_measurement_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The pipeline steps on every chunk with each DOF's latest measurement held, so a 1 Hz fix among
    10 Hz headings was in the report ten times: sample interval 0.1 s for north, innovation statistics
    over held copies. The report counts a DOF only when the fusion received it anew."""
    log = tmp_path / "sim.mcap"
    argv = [
        "sim",
        "--scenario",
        "fossen_strand_1999",
        "--duration",
        "60",
        "--gnss-rate",
        "1",
        "--gyro-rate",
        "10",
    ]
    assert main([*argv, "--out", str(log)]) == 0
    assert main(["replay", str(log), "--report", str(tmp_path / "rep"), "--json"]) == 0
    capsys.readouterr()
    m = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    meas = m["measurement"]
    assert meas["north"]["sample_interval_s"] == pytest.approx(1.0, rel=0.02)
    assert meas["heading"]["sample_interval_s"] == pytest.approx(0.1, rel=0.02)
    # (every fix: this sea moves the antenna up to 14 m between 1 Hz fixes, which the jump test allows
    # for by the source's own steps; before, 36 of 60 were used, the rest rejected or readmitting)
    assert 58 <= meas["north"]["valid"] <= 61 and 500 <= meas["heading"]["valid"] <= 601
    assert m["observers"]["passive"]["north"]["innovation"]["samples"] <= meas["north"]["valid"]


def test_no_estimate_with_both_sensors_is_not_blamed_on_a_missing_sensor() -> None:
    from dpgw.cli_replay import _no_estimates

    s = {"estimates": {"a": 0, "b": 3}, "measurements": {"samples": 10, "position": 9, "heading": 8}}
    assert _no_estimates(s) == [
        "observer 'a' made no estimate, although of the 10 fused measurements 9 had a position and 8 a "
        "heading: the events in /dp/status of the output say why"
    ]
    assert _no_estimates({**s, "estimates": {"a": 1}}) == []


def test_replay_zenoh_options_without_pacing_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, --zenoh-connect, --prefix ... were accepted and ignored: an unpaced replay opens no session."""
    log = tmp_path / "gps.txt"
    log.write_text("$GPGGA,100000.00,5924.000000,N,01029.999988,E,4,12,0.80,20.259,M,,,2.0,0001*11\r\n")
    argv = [
        "replay",
        str(log),
        "--vessel",
        "mss_supply",
        "--zenoh-connect",
        "tcp/127.0.0.1:7447",
        "--prefix",
        "x",
    ]
    assert main(argv) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        "dpgw replay: --prefix, --zenoh-connect: a replay publishes on Zenoh only when paced: add --speed X"
    )
    assert not (tmp_path / "gps-replay.mcap").exists()


def test_sim_names_its_own_options_in_what_it_refuses(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: --nmea gps9=pty (no such talker) ran and sent nothing to the pty, silently; --gnss-rate 50
    said 'DgpsConfig.rate_hz: ...'; --out on a path that cannot be written printed a bare errno."""
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--nmea", "gps9=pty"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        "dpgw sim: --nmea gps9=pty: hassani has no NMEA talker 'gps9' (it has dgps1, gyro1; without SOURCE= "
        "every one goes to the URL)"
    )
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--gnss-rate", "50"]) == 2
    assert _one_line(capsys.readouterr().err) == "dpgw sim: --gnss-rate: must be in 1..10 Hz, got 50.0"
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--gyro-rate", "50"]) == 2
    assert _one_line(capsys.readouterr().err).startswith("dpgw sim: --gyro-rate: must be in")
    folder = tmp_path / "a-folder.mcap"
    folder.mkdir()
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--out", str(folder)]) == 2
    assert _one_line(capsys.readouterr().err).startswith(f"dpgw sim: --out {folder}: a folder, not a file")
    if Path("/proc/self").is_dir():  # Linux: a folder where no file can be made, even by root
        nowhere = "/proc/dpgw-test.mcap"
        assert main(["sim", "--scenario", "hassani", "--duration", "1", "--out", nowhere]) == 2
        assert _one_line(capsys.readouterr().err).startswith(
            f"dpgw sim: --out {nowhere}: cannot write the log: "
        )


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--speed", "5"], "dpgw sim: --speed X paces a --realtime run: add --realtime"),
        (
            ["--prefix", "x", "--zenoh-listen", "tcp/127.0.0.1:0"],
            "dpgw sim: --prefix, --zenoh-listen: only with --zenoh",
        ),
        # --no-scouting, as demo, replay and listen take it (before: "unrecognized arguments")
        (["--no-scouting"], "dpgw sim: --no-scouting: only with --zenoh"),
        (["--zenoh-commands"], "dpgw sim: --zenoh-commands: only with --zenoh"),
    ],
)
def test_sim_options_that_need_another_are_refused(
    extra: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, each was accepted and ignored: the run went as fast as possible, no Zenoh session opened."""
    assert (
        main(["sim", "--scenario", "hassani", "--duration", "1", "--out", str(tmp_path / "s.mcap"), *extra])
        == 2
    )
    assert _one_line(capsys.readouterr().err) == words
    assert not (tmp_path / "s.mcap").exists()


def _run_with_log(tmp_path: Path, log_path: str, *more: str) -> subprocess.CompletedProcess[str]:
    cfg = tmp_path / "vessel.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\nwave_period_s = 9.0\n'
        "[zenoh]\nmulticast_scouting = false\n"  # (listening on a port the system picks)
        + (f'[log]\npath = "{log_path}"\n' if log_path else "")
    )
    return subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "0.5", *more],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_run_makes_the_folder_of_its_log(tmp_path: Path) -> None:
    """The default log path (`logs/dpgw.mcap`) and every example's (`logs/...`) is in a folder beside the
    config: `dpgw run --config examples/hil_bench.toml`, as printed, stopped with "[Errno 2] No such file or
    directory" when that folder was not there yet."""
    p = _run_with_log(tmp_path, "")  # the default
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "logs" / "dpgw.mcap").stat().st_size > 0
    assert "made the log's folder" in p.stderr, p.stderr  # (said: one line)
    p = _run_with_log(tmp_path, "trials/bench.mcap")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "trials" / "bench.mcap").stat().st_size > 0
    # a folder whose parent is missing too is not made (a mistyped path must not scatter folders)
    p = _run_with_log(tmp_path, "sea/2026/bench.mcap")
    assert p.returncode == 2 and "log.path: neither the folder" in p.stderr, p.stderr
    assert not (tmp_path / "sea").exists()


def test_a_log_folder_that_cannot_be_made_stops_start_up_with_one_message(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("not a folder")
    p = _run_with_log(tmp_path, "afile/dpgw.mcap")
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "log.path" in lines[0] and str(tmp_path / "afile") in lines[0], p.stderr
    assert "Errno" not in lines[0] and "choose" in lines[0]
    p = _run_with_log(tmp_path, "", "--log", str(tmp_path / "afile" / "x.mcap"))
    assert p.returncode == 2 and "--log" in p.stderr, p.stderr
    # --check says it too, as a problem (status 2): it said "ok" with a note blaming the user's rights
    # ("does not exist and cannot be made for this user"), and the gateway then stopped on it
    p = _run_with_log(tmp_path, "afile/dpgw.mcap", "--check")
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"{tmp_path / 'afile'} is a file, not a folder (a file is in the way)" in p.stderr, p.stderr
    assert "for this user" not in p.stdout + p.stderr


def test_run_json_summary_without_any_data_is_stamped_now_not_1970(tmp_path: Path) -> None:
    """A gateway that received nothing has no time of its own; its closing status used to be stamped 0
    (1970) with every source stale for 56 years."""
    import json
    import time

    p = _run_with_log(tmp_path, "", "--json")
    assert p.returncode == 0, p.stderr
    status = json.loads(p.stdout)["status"]
    assert abs(status["stamp_ns"] - time.time_ns()) < 600 * 10**9
    assert not any("stale" in str(a) for a in status["alarms"]), status["alarms"]


def test_listen_leaves_the_simulators_clock_out_of_its_default_view() -> None:
    """During a demo a third of what arrives on dp/** was <prefix>/sim/clock, ten ticks a second: the
    default view leaves it out; --all or its own key shows it."""
    import json
    import threading

    from gateway.bus import isolated_config, open_session

    port = free_port()
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    stop = threading.Event()

    def publish() -> None:
        k = 0
        while not stop.is_set():
            server.put("dp/x/sim/clock", json.dumps({"stamp_ns": k}))
            if k % 5 == 0:
                server.put("dp/x/estimate", json.dumps({"stamp_ns": k}))
            k += 1
            stop.wait(0.01)

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    base = [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--connect", f"tcp/127.0.0.1:{port}"]
    try:
        keys = {}
        for extra in ([], ["--all"], ["dp/*/sim/clock"]):
            p = subprocess.run(
                [*base, *extra, "--count", "20", "--json"], capture_output=True, text=True, timeout=60
            )
            assert p.returncode == 0, p.stderr
            keys[" ".join(extra)] = {json.loads(line)["key"] for line in p.stdout.splitlines()}
        assert keys[""] == {"dp/x/estimate"}
        assert "dp/x/sim/clock" in keys["--all"]
        assert keys["dp/*/sim/clock"] == {"dp/x/sim/clock"}
    finally:
        stop.set()
        thread.join(5)
        server.close()


def test_listen_that_heard_only_the_clock_says_so() -> None:
    import json
    import threading

    from gateway.bus import isolated_config, open_session

    port = free_port()
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    stop = threading.Event()

    def tick() -> None:
        while not stop.is_set():
            server.put("dp/x/sim/clock", json.dumps({"stamp_ns": 0}))
            stop.wait(0.01)

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        p = subprocess.run(
            [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--connect", f"tcp/127.0.0.1:{port}",
             "--duration", "4"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    finally:
        stop.set()
        thread.join(5)
        server.close()
    assert p.returncode == 1 and p.stdout == ""
    line = _one_line(p.stderr)
    assert line.startswith("dpgw listen: only the simulator's clock on dp/** ("), line
    assert "no gateway publishing there yet" in line


def test_listen_to_a_host_that_does_not_resolve_says_so() -> None:
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--connect", "tcp/nohost.invalid:7447",
         "--duration", "0.5"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert p.returncode == 1 and p.stdout == ""
    line = _one_line(p.stderr)
    assert "'nohost.invalid' is not a name this computer can resolve" in line, line


def test_demo_whose_dp_was_refused_says_why(capsys: pytest.CaptureFixture[str]) -> None:
    """The operator's dp refused by the gateway (an estimate not healthy at the engage time): no station
    keeping to score, and the summary says the gateway's reason instead of leaving the line out."""
    from dpgw.cli_demo import print_summary

    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 360.0, "wall_seconds": 36.0, "log": "d.mcap",
            "logs": ["d.mcap"], "sources": {}, "sent": {}, "estimates": 500, "alarms": [],
            "settle_s": 60.0, "engage_at_s": 145.0, "station_keeping": None,
            "dp_refused": "mode dp refused: the estimate is dead reckoning",
        }
    )  # fmt: skip
    out = capsys.readouterr().out
    assert "station keeping: not scored: the gateway refused dp (mode dp refused: the estimate is dead" in out


def test_demo_engage_at_with_standby_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """`--engage-at` switches the gateway to dp: with `--mode standby` it was accepted and ignored."""
    assert main(["demo", "--mode", "standby", "--engage-at", "60", "--no-foxglove"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "dpgw demo: --engage-at switches to dp: it goes with --mode dp (the default)"


def test_a_bare_replay_report_goes_beside_the_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw replay LOG --report` (no folder, as a user types it first) writes the report beside the
    output, in <out>-report; it was an argparse error."""
    log = tmp_path / "sim.mcap"
    assert main(["sim", "--scenario", "fossen_strand_1999", "--duration", "30", "--out", str(log)]) == 0
    assert main(["replay", str(log), "--json", "--report"]) == 0
    capsys.readouterr()
    assert (tmp_path / "sim-replay-report" / "metrics.json").is_file()
    assert (tmp_path / "sim-replay.mcap").is_file()
    out = tmp_path / "other.mcap"
    assert main(["replay", str(log), "--out", str(out), "--report"]) == 0
    assert (tmp_path / "other-report" / "report.md").is_file()


def test_a_replay_report_folder_that_holds_a_report_is_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--report DIR` naming a folder that held a report wrote over it silently (the earlier replay's
    report.md and plots gone, or mixed with the new), while an --out that exists is kept. The same rule
    now for both, given or derived from --out: the next free folder of its set, said on stderr and named
    in the summary; the earlier report untouched."""
    log = tmp_path / "sim.mcap"
    assert main(["sim", "--scenario", "fossen_strand_1999", "--duration", "30", "--out", str(log)]) == 0
    report = tmp_path / "rep"
    assert main(["replay", str(log), "--out", str(tmp_path / "a.mcap"), "--report", str(report)]) == 0
    capsys.readouterr()
    first = {p.name: p.read_bytes() for p in report.iterdir()}
    assert "report.md" in first
    assert (
        main(["replay", str(log), "--out", str(tmp_path / "b.mcap"), "--report", str(report), "--json"]) == 0
    )
    captured = capsys.readouterr()
    again = tmp_path / "rep_0001"
    assert f"dpgw replay: report -> {again} ({report} holds a report: a report is never overwritten)" in (
        captured.err.splitlines()
    ), captured.err
    assert str(again / "report.md") in json.loads(captured.out)["report"]
    assert {p.name: p.read_bytes() for p in report.iterdir()} == first
    # a bare --report, beside --out: its folder (c-report) held a report whose log has since gone
    (tmp_path / "c-report").mkdir()
    (tmp_path / "c-report" / "report.md").write_text("an earlier replay's\n")
    assert main(["replay", str(log), "--out", str(tmp_path / "c.mcap"), "--report"]) == 0
    err = capsys.readouterr().err
    assert f"report -> {tmp_path / 'c-report_0001'} ({tmp_path / 'c-report'} holds a report" in err, err
    assert (tmp_path / "c-report" / "report.md").read_text() == "an earlier replay's\n"
    assert (tmp_path / "c-report_0001" / "metrics.json").is_file()


def test_replay_argument_mistakes_say_what_was_meant(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--report LOG` with no LOG after it: --report takes an optional folder, so it took the log, and
    argparse said only that LOG is required. A misspelt observer or key of an observer spec got the list of
    names but no "did you mean", which a config's misspelt key gets."""
    log = tmp_path / "usv.txt"
    log.write_text("$GPGGA,100000.00,5924.000000,N,01029.999988,E,4,12,0.80,20.259,M,,,2.0,0001*11\r\n")
    with pytest.raises(SystemExit) as exit_:
        main(["replay", "--report", str(log), "--vessel", "cybership2"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines()[-1] == (
        "dpgw replay: error: the following arguments are required: LOG "
        f"(--report took {log} as the report's folder: its folder is optional, so put a bare --report after "
        f"the logs, 'dpgw replay {log} ... --report', or give it one: --report DIR)"
    )
    # a --report folder that is no file, with LOG missing: argparse's own message, no guess about it
    with pytest.raises(SystemExit):
        main(["replay", "--report", str(tmp_path / "new"), "--vessel", "cybership2"])
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "dpgw replay: error: the following arguments are required: LOG"
    )
    args = ["replay", str(log), "--vessel", "cybership2", "--out", str(tmp_path / "x.mcap")]
    assert main([*args, "--observer", "pasive"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        "dpgw replay: observer spec 'pasive': unknown observer 'pasive', did you mean 'passive'? "
        "(known: passive, gain_scheduled, mmae, sdre, ekf, memory)"
    )
    assert main([*args, "--observer", "passive:wave_perod=2"]) == 2
    assert _one_line(capsys.readouterr().err).startswith(
        "dpgw replay: observer spec 'passive:wave_perod=2': unknown key 'wave_perod', did you mean "
        "'wave_period_s'? (passive takes bias_corner, "
    )
    assert main([*args, "--observer", "sdre:adaptiv=true"]) == 2
    assert "unknown key 'adaptiv', did you mean 'adaptive'? (sdre takes " in _one_line(
        capsys.readouterr().err
    )
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize(
    ("args", "said"),
    [
        ("--hs -1", "argument --hs: a significant wave height must be ≥ 0 m (got -1)"),
        ("--hs 2,-0.5", "argument --hs: a significant wave height must be ≥ 0 m (got -0.5 in 2,-0.5)"),
        ("--tp 0", "argument --tp: a peak period must be > 0 s (got 0)"),
        ("--current -1", "argument --current: a current speed must be ≥ 0 m/s (got -1)"),
        ("--direction 1,inf", "argument --direction: '1,inf': every value must be a finite number"),
        ("--duration -5", "argument --duration: must be a positive number (got -5)"),
    ],
)
def test_study_sea_values_out_of_range_name_the_option(
    args: str, said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `--hs -1` stopped with `'seas'[0]: 'hs_m' out of range (-1.0)`, the study file's key for a
    value the user gave as --hs, and no range."""
    with pytest.raises(SystemExit) as exit_:
        main(["study", "--scenario", "hassani", *args.split(), "--serial"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"dpgw study: error: {said}"


def test_study_settle_past_the_end_names_the_flags(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["study", "--scenario", "hassani", "--duration", "10", "--settle", "20", "--serial"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        "dpgw study: --settle 20: scoring must start before the case ends: give less than the duration, "
        "10 s (or a longer --duration)"
    )


def test_sim_wind_spectrum_mistake_names_the_option_and_the_spectra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `--wind 10,90,norsk` stopped with `wind: field 'gust': one of ('norsok', 'harris', 'none'),
    got 'norsk'`, a key of no file the user wrote."""
    argv = ["sim", "--vessel", "mss_osv", "--inputs", str(OSV_INPUTS), "--csv", str(tmp_path / "s.csv")]
    assert main([*argv, "--wind", "10,90,norsk"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        "dpgw sim: --wind 10,90,norsk: no gust spectrum 'norsk': did you mean norsok? SPECTRUM is one of "
        "norsok, harris, none (none: a steady wind)"
    )
    assert not (tmp_path / "s.csv").exists()


def test_listen_hints_at_keelsons_at_chunk_and_summarises_binary_payloads() -> None:
    """A peer publishes Keelson's binary payloads (protobuf: bytes that are not UTF-8) on keelson/@v0/…,
    text and JSON beside them. ``keelson/**`` hears nothing (no wildcard matches an ``@`` chunk) and says
    to name ``@v0``; ``keelson/@v0/**`` hears them, a binary payload printed as its length and first bytes
    in hex, never raw, and with --json carried in base64 with an ``encoding`` that says so."""
    import base64
    import json
    import threading

    from dpgw.cli_listen import key_hint
    from gateway.bus import isolated_config, open_session

    blob = bytes([0x0A, 0x0C, 0x08, 0x96, 0x01, 0x1B, 0x07, 0xFF, 0x00, 0x9C]) * 3  # a protobuf-like body
    port = free_port()
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    stop = threading.Event()

    def publish() -> None:
        while not stop.is_set():
            server.put("keelson/@v0/sv1/pubsub/heading_true_north_deg/dpgw", blob)
            server.put("keelson/@v0/sv1/pubsub/note/dpgw", "plain text")
            server.put("keelson/@v0/sv1/pubsub/json/dpgw", json.dumps({"a": 1}))
            stop.wait(0.01)

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    base = [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--connect", f"tcp/127.0.0.1:{port}"]
    try:
        missed = subprocess.run(
            [*base, "keelson/**", "--duration", "3"], capture_output=True, text=True, timeout=60
        )
        text = subprocess.run(
            [*base, "keelson/@v0/**", "--count", "9"], capture_output=True, text=True, timeout=60
        )
        as_json = subprocess.run(
            [*base, "keelson/@v0/**", "--count", "9", "--json"], capture_output=True, text=True, timeout=60
        )
    finally:
        stop.set()
        thread.join(5)
        server.close()
    assert missed.returncode == 1 and missed.stdout == "", missed.stderr
    note, line = missed.stderr.splitlines()  # the note on the key at once, then what was (not) heard
    assert note == (
        "dpgw listen: keelson/**: Keelson's keys have an @v0 chunk, which no wildcard matches in Zenoh: "
        "try 'keelson/@v0/**'"
    )
    assert line.startswith("dpgw listen: nothing on keelson/** in 3 s, though 1 Zenoh peer answered"), line
    assert line.endswith("; and see the note on the key above")
    assert text.returncode == 0, text.stderr
    by_key = {ln.split(": ", 1)[0]: ln.split(": ", 1)[1] for ln in text.stdout.splitlines()}
    assert by_key["keelson/@v0/sv1/pubsub/heading_true_north_deg/dpgw"] == (
        f"<30 bytes, binary (not JSON nor text): {blob[:16].hex(' ')}…>"
    )
    assert by_key["keelson/@v0/sv1/pubsub/note/dpgw"] == "plain text"
    assert by_key["keelson/@v0/sv1/pubsub/json/dpgw"] == '{"a": 1}'
    assert "\x00" not in text.stdout and "\x1b" not in text.stdout  # nothing raw reached the terminal
    assert as_json.returncode == 0, as_json.stderr
    objects = {o["key"]: o for o in map(json.loads, as_json.stdout.splitlines())}
    binary = objects["keelson/@v0/sv1/pubsub/heading_true_north_deg/dpgw"]
    assert binary["encoding"] == "base64" and binary["bytes"] == 30
    assert base64.b64decode(binary["payload"]) == blob
    assert objects["keelson/@v0/sv1/pubsub/json/dpgw"] == {
        "key": "keelson/@v0/sv1/pubsub/json/dpgw",
        "payload": {"a": 1},
    }
    assert objects["keelson/@v0/sv1/pubsub/note/dpgw"]["encoding"] == "text"
    # the other keys without an @ chunk
    assert key_hint("**").startswith("; '**' matches no chunk that starts with '@'")
    assert "try 'keelson/@v0/*/pubsub/**'" in key_hint("keelson/*/pubsub/**")
    assert key_hint("keelson/@v0/**") == key_hint("dp/**") == ""


def test_run_says_its_log_rotation_at_start_and_the_files_it_wrote_at_the_stop(tmp_path: Path) -> None:
    """The start-up says the log's rotation (one line; Keelson, ROS 2, authentication would have theirs:
    `describe`'s test), and the stop summary names the log files written, which exist; ``--json`` has them
    as ``log_files``."""
    import json

    p = _run_with_log(tmp_path, "trials/bench.mcap")
    assert p.returncode == 0, p.stderr
    assert "dpgw run: log rotated at 1024 MB or 60 min, whichever first" in p.stderr.splitlines(), p.stderr
    said = [ln for ln in p.stdout.splitlines() if ln.startswith("dpgw run: log: ")]
    assert len(said) == 1, p.stdout
    files = said[0].removeprefix("dpgw run: log: ").split(", ")
    assert files and all(Path(f).parent == tmp_path / "trials" and Path(f).stat().st_size > 0 for f in files)
    q = _run_with_log(tmp_path, "trials/bench.mcap", "--json")
    assert q.returncode == 0, q.stderr
    written = json.loads(q.stdout)["log_files"]
    assert len(written) == 1 and written[0] not in files and Path(written[0]).stat().st_size > 0, written


def test_listen_says_the_keelson_note_at_once_for_a_listener_stopped_by_ctrl_c() -> None:
    """Most stop ``dpgw listen`` with Ctrl-C, not a --duration: the note on a key that can hear none of
    Keelson's keys came only when a duration ended, so they never saw it. It depends on the key alone and
    comes first."""
    import signal

    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--listen", f"tcp/127.0.0.1:{port}",
         "keelson/**"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stderr is not None
        first = proc.stderr.readline()  # (blocks until the note: no sleep)
        assert first.startswith("dpgw listen: keelson/**: Keelson's keys have an @v0 chunk"), first
        assert proc.poll() is None  # said while listening, before any stop
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("command", ["demo", "sim"])
def test_a_negative_seed_is_a_usage_error_and_writes_nothing(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--seed -1` ended in numpy's traceback (`expected non-negative integer`) after the demo had made its
    log (a stub demo_0001.mcap per try); now argparse's usage error, status 2, before anything is made."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main([command, "--seed", "-1", "--duration", "10"])
    assert stop.value.code == 2
    assert "argument --seed: must be 0 or more" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_run_says_at_its_stop_how_many_messages_were_not_logged(tmp_path: Path) -> None:
    """The log file removed under a running gateway (a disk unmounted) and the next file of the set on a
    full disk (/dev/full): while it fails the status alarms, but the alarm clears when writing works again,
    and the stop summary said nothing of the gap. It now gives the run's count, on the console and in
    ``--json`` (``log_not_logged``)."""
    from conftest import wait_for

    cfg = tmp_path / "vessel.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\nwave_period_s = 9.0\n'
        '[zenoh]\nmulticast_scouting = false\n[log]\npath = "gw.mcap"\n[status]\nrate_hz = 10.0\n'
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "4", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert wait_for(lambda: (tmp_path / "gw.mcap").exists() or proc.poll() is not None, 60.0)
        (tmp_path / "gw_0001.mcap").symlink_to("/dev/full")  # where the writer tries next
        (tmp_path / "gw.mcap").unlink()
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    summary = json.loads(out)
    assert summary["log_not_logged"] > 0, summary
    assert summary["log_files"][0].endswith("gw.mcap")
