"""A new user's first mistakes: each stops with one line naming what, where and what to do (never a
traceback), and what the help pages and --json print can be used as printed."""

from __future__ import annotations

import argparse
import json
import math
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
    from dpgw.cli_demo import SETTLE_S, print_summary

    nan = math.nan
    print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": 50.0, "wall_seconds": 5.0, "log": "d.mcap",
            "sources": {}, "sent": {}, "estimates": 10, "alarms": [], "settle_s": SETTLE_S,
            "error_vs_truth": {"samples": 0, "horizontal_rms_m": nan},
            "station_keeping": {
                "position_p95_m": 1.0, "heading_p95_deg": 1.0, "reference": [0.0, -0.0001, 45.0],
                "north_mean_m": 0.1, "east_mean_m": -0.1, "heading_mean_deg": 0.5,
            },
        }
    )  # fmt: skip
    out = capsys.readouterr().out
    assert f"give a --duration longer than {SETTLE_S:.0f}" in out
    assert "-0.0" not in out and "(0.0 m N, 0.0 m E, 45.0 deg)" in out


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
    assert "vessel.name: not a built-in vessel" in err and "mss_supply" in err and 'got "mss_suply"' in err
