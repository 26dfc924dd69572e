"""`dpgw demo` says what it will do and what it did: DP engaged only once the gateway itself calls the
estimate settled (no "before the observer settled" in a default demo), a duration too short to engage DP
said at the start, and Ctrl-C said in the summary and the exit status, stopped at once, its speed its own
and its estimate not scored on a few seconds.

Real demos (simulator, pty, UDP, Zenoh, MCAP) run in this process, as tests/test_demo_stop.py runs them, so
that the observer's settle time can be shortened (`PassiveObserver.settle_time_s`, ~145 s on the default
scenario: 9.95 s here, a fraction like the real one's, so that engaging at the rounded-up second comes
before the gateway's settle clock, which starts at the first estimate, has run out) and the demo stopped
by its own SIGINT handler."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from conftest import run_demo_beside, wait_for

from dpgw import cli_demo
from dpgw.cli import build_parser
from gateway.service import GatewayService
from observers.passive import PassiveObserver
from simulator.runner import Simulation
from wire.mcap.reader import is_complete, log_files, read_messages

ROOT = Path(__file__).resolve().parents[1]

SETTLE_S = 9.95
"""The observer's settle time in these tests (s)."""
CLOSE_S = 1.0
"""How long the gateway's close is made to take in the Ctrl-C test (s)."""
EARLY = "before the observer settled"
"""What the gateway says of a dp engaged on an estimate not yet settled (`Pipeline._mode_commanded`)."""


def run_demo(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    operator: Callable[[list[Simulation]], None] | None = None,
) -> tuple[int, dict[str, Any], str, Path]:
    """``dpgw demo ARGV --json`` in this process with the short settle time; ``operator`` runs in a thread
    beside it, given the demo's simulation once it exists. Returns the exit status, the JSON summary, what
    it said on stderr and its log."""
    monkeypatch.setattr(PassiveObserver, "settle_time_s", property(lambda _self: SETTLE_S))
    sims: list[Simulation] = []
    real_run = Simulation.run

    def watched_run(self: Simulation, *a: Any, **k: Any) -> Any:
        if not sims:
            sims.append(self)
        return real_run(self, *a, **k)

    monkeypatch.setattr(Simulation, "run", watched_run)
    out = tmp_path / "demo.mcap"
    args = build_parser().parse_args(
        ["demo", *argv, "--out", str(out), "--json", "--no-scouting", "--no-foxglove"]
    )
    code = run_demo_beside(args, (lambda: operator(sims)) if operator else None)
    captured = capsys.readouterr()
    return code, json.loads(captured.out) if captured.out else {}, captured.err, out


def said(out: Path, words: str) -> bool:
    """Whether any message of the log (status events, /dp/log lines) has ``words``."""
    return any(words in json.dumps(p) for _, _, _, p in read_messages(log_files(out)))


@pytest.mark.slow  # two demos of 14 s of sea at 10x, with start-up: ~15 s
def test_a_default_demo_engages_dp_once_the_gateway_calls_the_estimate_settled(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The gateway's settle clock starts at its first estimate (~0.3 s of sea); engaged at the settle
    time rounded up (10 s), it said "DP engaged by the operator before the observer settled" in every
    demo. Engaged when the gateway calls the estimate settled, it says nothing of the kind, and DP runs;
    an --engage-at before the settle time still gets the gateway's warning."""
    code, summary, err, out = run_demo(tmp_path, monkeypatch, capsys, ["--duration", "14", "--speed", "10"])
    assert code == 0, err
    assert EARLY not in caplog.text and not said(out, EARLY)
    assert "once the observer has settled, 10 s after its first estimate" in err
    # DP engaged: the operator's dp logged once, after the settle time, and the controller commanding
    assert [p["mode"] for _, _, _, p in read_messages(out, "/dp/mode")] == ["dp"]
    engaged = summary["engage_at_s"]
    assert SETTLE_S < engaged < SETTLE_S + 1.5 and summary["engage_at_given"] is False
    truth0 = next(p["stamp_ns"] for _, _, _, p in read_messages(out, "/truth/state"))
    commands = [(p["stamp_ns"] - truth0) / 1e9 for _, _, _, p in read_messages(out, "/dp/thrusters/command")]
    # at least half the control rate (10 Hz) over the DP stretch: a busy machine's gateway takes the sea
    # in batches and steps the controller less often (measured 33 alone, 20 in a loaded CI run)
    assert len(commands) >= 0.5 * 10 * (14 - engaged) and engaged <= commands[0] <= engaged + 1.0
    # and the gateway had called its estimate settled by then
    settled_at = next(
        (p["stamp_ns"] - truth0) / 1e9
        for _, _, _, p in read_messages(out, "/dp/estimate")
        if p.get("settled")
    )
    assert settled_at <= commands[0]

    caplog.clear()
    code, summary, err, out = run_demo(
        tmp_path / "early", monkeypatch, capsys, ["--duration", "8", "--speed", "10", "--engage-at", "5"]
    )
    assert code == 0, err
    assert said(out, EARLY)  # a real early engagement is still said
    assert summary["engage_at_s"] == pytest.approx(5.0, abs=0.05)
    assert summary["engage_at_given"] is True  # (the text: "at the time --engage-at gave", not "settled")


@pytest.mark.slow  # 5 s of sea at 10x, with start-up: ~5 s
def test_a_demo_too_short_to_engage_dp_says_so_at_the_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw demo --duration 120` announced "held on joystick until DP is engaged at 145 s"; only the end
    summary said DP never was. At the start now: one line that DP will not be engaged, station keeping
    will not be scored, and the duration that does both."""
    code, summary, err, out = run_demo(tmp_path, monkeypatch, capsys, ["--duration", "5", "--speed", "10"])
    assert code == 0, err
    lines = [line for line in err.splitlines() if "engaged" in line]
    assert len(lines) == 1, err
    assert lines[0].startswith("dpgw demo: with --duration 5, DP will not be engaged")
    need = cli_demo.needed_duration_s(SETTLE_S)
    assert "station keeping will not be scored" in lines[0] and f"give --duration {need} or more" in lines[0]
    assert list(read_messages(out, "/dp/mode")) == [] and summary["station_keeping"] is None


@pytest.mark.slow  # 64 s of sea at 10x and 4 s at 1x, with start-ups: ~20 s
def test_ctrl_c_is_said_exits_130_at_once_and_scores_only_enough_sea(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C during a demo: the summary and --json say it was stopped by Ctrl-C, at how much sea; the
    exit status is 130 (as `dpgw study`'s); the estimate, 4 s of it after the 60 s skip, is "not scored"
    rather than given a figure on those seconds."""
    stopped: list[float] = []

    def ctrl_c_at(sea_s: float) -> Callable[[list[Simulation]], None]:
        def operator(sims: list[Simulation]) -> None:
            try:
                wait_for(lambda: sims and sims[0].t >= sea_s, 300)
            finally:
                stopped.append(time.monotonic())
                os.kill(os.getpid(), signal.SIGINT)

        return operator

    code, summary, err, out = run_demo(
        tmp_path, monkeypatch, capsys, ["--duration", "360", "--speed", "10"], ctrl_c_at(64.0)
    )
    assert code == 130, err
    assert summary["interrupted"] is True and summary["stopped_by"] == "SIGINT"
    assert 64.0 <= summary["sim_seconds"] < 67.0
    assert summary.get("error_vs_truth") is None
    assert 0.0 < summary["estimate_scored_s"] < cli_demo.MIN_SCORED_S
    cli_demo.print_summary(summary)
    text = capsys.readouterr().out
    assert f"stopped by Ctrl-C at {summary['sim_seconds']:.0f} s of sea (of 360 asked)" in text
    assert "LF estimate vs truth: not scored (only " in text and "after the 60 s skip" in text
    assert out.exists()

    # At 1x the simulation is in the middle of its second of sea when Ctrl-C comes, and it paused there
    # for the gateway, which reads no more: the demo hung ~5 s, and counted them as run time. The close
    # made slow here (a second: a long log's index and footer) is not run time either.
    stopped.clear()
    close = GatewayService.close

    def slow_close(self: GatewayService) -> None:
        time.sleep(CLOSE_S)
        close(self)

    monkeypatch.setattr(GatewayService, "close", slow_close)
    t0 = time.monotonic()
    code, summary, err, out = run_demo(
        tmp_path / "slow", monkeypatch, capsys, ["--duration", "360", "--speed", "1"], ctrl_c_at(3.5)
    )
    took = time.monotonic() - stopped[0] - CLOSE_S
    assert code == 130, err
    assert took < 2.0, f"{took:.1f} s from Ctrl-C to the end (started {stopped[0] - t0:.1f} s in)"
    # at 1x a second of sea takes a second: the wall time is the simulation's, not the stop's
    sp = summary["speed"]
    assert abs(summary["wall_seconds"] - sp["paused_s"] - summary["sim_seconds"]) < CLOSE_S / 2, summary


@pytest.mark.slow  # a demo's start-up: ~3 s
def test_ctrl_c_during_start_up_stops_the_demo_with_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C while the gateway starts (its kernels compile for ~15 s on a first run) met Python's default:
    a KeyboardInterrupt traceback from inside the compiler. The demo takes it from its first instant:
    start-up finishes, nothing runs, one line says so, and the exit status is 130."""
    start = GatewayService.start

    def interrupted_start(self: GatewayService) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, as the gateway starts
        start(self)

    def not_the_demos(_signum: int, _frame: object) -> None:
        raise AssertionError("Ctrl-C during start-up met no handler of the demo's")

    monkeypatch.setattr(GatewayService, "start", interrupted_start)
    before = signal.signal(signal.SIGINT, not_the_demos)
    try:
        code, summary, err, _ = run_demo(tmp_path, monkeypatch, capsys, ["--duration", "60"])
    finally:
        signal.signal(signal.SIGINT, before)
    assert code == 130, err
    assert err.strip().splitlines()[-1] == "dpgw demo: stopped by Ctrl-C during start-up; nothing ran", err
    assert "Traceback" not in err and summary == {}


@pytest.mark.slow  # a gateway started, then the failure: a few seconds
def test_a_failure_between_the_gateways_start_and_the_simulation_closes_the_gateway(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Something going wrong after the gateway started but before the simulation runs (here the simulator's
    clock refusing to start) is raised as it was, with the gateway closed behind it: its sources' threads
    gone and its log complete. Left running, they kept the process from ending after the error."""
    from simulator.sim_clock import SimClockPublisher

    def refused(*_a: Any, **_k: Any) -> None:
        raise RuntimeError("the simulator's clock cannot start")

    monkeypatch.setattr(SimClockPublisher, "__init__", refused)
    before = {t for t in threading.enumerate() if t.name.startswith("dpgw-source-")}
    with pytest.raises(RuntimeError, match="clock cannot start"):
        run_demo(tmp_path, monkeypatch, capsys, ["--duration", "8"])
    left = [t for t in threading.enumerate() if t.name.startswith("dpgw-source-") and t not in before]
    assert wait_for(lambda: not any(t.is_alive() for t in left), 10), left
    logs = log_files(tmp_path / "demo.mcap")
    assert logs and all(is_complete(p) for p in logs)


@pytest.mark.slow  # 8 s of sea at 10x, with start-up: ~6 s
def test_dp_engaged_by_another_console_is_said_as_such(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A console on this computer sends dp to the demo's gateway before the demo's operator would (at the
    settle time, after this run's end): the summary said "the run ended at 8 s before DP was engaged". It
    says DP was engaged, and by whom."""
    import zenoh
    from conftest import free_port

    from gateway.bus import isolated_config, open_session

    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    console: list[zenoh.Session] = []

    def another_console(sims: list[Simulation]) -> None:
        wait_for(lambda: sims and sims[0].t >= 4.0, 120)
        session = open_session(isolated_config(connect=[endpoint]))
        console.append(session)
        session.put("dp/mss_supply/mode", json.dumps("dp"))

    code, summary, err, out = run_demo(
        tmp_path,
        monkeypatch,
        capsys,
        ["--duration", "8", "--speed", "10", "--zenoh-listen", endpoint],
        another_console,
    )
    for session in console:
        session.close()
    assert code == 0, err
    assert [p["mode"] for _, _, _, p in read_messages(out, "/dp/mode")] == ["dp"]
    assert summary["dp_engaged"] is True and summary["engaged_by"] == "another console"
    cli_demo.print_summary(summary)
    text = capsys.readouterr().out
    assert "before DP was engaged" not in text
    assert "DP was engaged by another console, not the demo's operator" in text


@pytest.mark.slow  # a demo process's start-up (its kernels compiled on a first run: ~15 s), then stopped
def test_sigterm_stops_a_demo_with_143_and_says_so(tmp_path: Path) -> None:
    """SIGTERM (`kill`, `timeout`) stopped `dpgw demo` short of its --duration with status 0, while Ctrl-C
    gave 130: a script could not tell a demo cut short from one that ran its course. 143 now (128 +
    SIGTERM, as a shell says it), with the summary naming the signal and the log complete. (`dpgw run`
    keeps 0 on SIGTERM, the service's normal stop: tests/test_run_signals.py.) A real process, stopped
    once it says it runs (the engagement line comes after the gateway has started)."""
    out = tmp_path / "demo.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "3600", "--speed", "1", "--out", str(out),
         "--json", "--no-scouting", "--no-foxglove"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    running = threading.Event()
    err: list[str] = []

    def read_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            err.append(line)
            if "held on joystick until DP is engaged" in line:
                running.set()

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        assert running.wait(180) or proc.poll() is not None, "".join(err)
        assert proc.poll() is None, "".join(err)
        proc.send_signal(signal.SIGTERM)
        stdout, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(10)
    assert proc.returncode == 143, "".join(err)
    summary = json.loads(stdout)
    assert summary["interrupted"] is True and summary["stopped_by"] == "SIGTERM"
    assert summary["sim_seconds"] < 3600 and "Traceback" not in "".join(err)
    assert all(is_complete(p) for p in summary["logs"])


@pytest.mark.slow  # 64 s of sea at 10x with start-up, and its replay with a report: ~15 s
def test_a_replay_of_a_demo_stopped_early_does_not_score_it_either(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A demo stopped by Ctrl-C 4 s after its 60 s skip says its estimate is "not scored" (fewer than
    `MIN_SCORED_S` seconds); `dpgw replay` of its log scored those seconds and printed, and reported, an RMS
    of them. The replay now scores on as much sea as the demo (the log records it), and says why not in
    the demo's words, on the console, in --json and in report.md."""
    from dpgw.cli import main

    def ctrl_c_at_64(sims: list[Simulation]) -> None:
        try:
            wait_for(lambda: sims and sims[0].t >= 64.0, 300)
        finally:
            os.kill(os.getpid(), signal.SIGINT)

    code, summary, err, _ = run_demo(
        tmp_path, monkeypatch, capsys, ["--duration", "360", "--speed", "10"], ctrl_c_at_64
    )
    assert code == 130, err
    assert 0.0 < summary["estimate_scored_s"] < cli_demo.MIN_SCORED_S and "error_vs_truth" not in summary
    report = tmp_path / "report"
    argv = ["replay", *summary["logs"], "--out", str(tmp_path / "again.mcap"), "--report", str(report)]
    assert main([*argv, "--json"]) == 0
    replayed = json.loads(capsys.readouterr().out)
    (label,) = replayed["estimates"]
    assert replayed["settle_s"] == cli_demo.SETTLE_S and replayed["min_scored_s"] == cli_demo.MIN_SCORED_S
    scored = replayed["estimate_scored_s"][label]
    assert 0.0 < scored < cli_demo.MIN_SCORED_S
    assert replayed["error_vs_truth"] == {}  # no figure on those seconds
    words = f"not scored (only {scored:.1f} s after the 60 s skip; at least 30 s are scored)"
    assert main([*argv, "--report", str(tmp_path / "text")]) == 0  # (the console's words)
    assert f"  {label} vs truth: {words}" in capsys.readouterr().out.splitlines()
    # the report counts its sea from its own t = 0, the first fused measurement, a fraction of a second
    # before the first estimate: its seconds are its own, its words the same
    metrics = json.loads((report / "metrics.json").read_text())
    assert metrics["min_scored_s"] == cli_demo.MIN_SCORED_S
    dof = metrics["observers"][label]
    assert scored <= dof["truth_scored_s"] < scored + 1.0
    words = f"not scored (only {dof['truth_scored_s']:.1f} s after the 60 s skip; at least 30 s are scored)"
    assert dof["truth_not_scored"] == words and dof["north"]["rms_error"] is None
    assert f"LF estimate vs truth: {words}." in (report / "report.md").read_text()


@pytest.mark.parametrize("engage_s", [100.0, 300.0])
def test_the_duration_asked_for_at_the_start_and_at_the_end_is_one_that_scores(
    engage_s: float, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--engage-at 100 --duration 160`: the start asked for 161 s, the end of that 160 s run (not scored:
    the stretch from 130 s to its last command was 29.9 s) asked for "160 or more", the duration given.
    Both now ask for the same figure, one past the run that fell short."""
    import argparse

    need = cli_demo.needed_duration_s(engage_s)
    assert need == engage_s + cli_demo.DP_SETTLE_S + cli_demo.MIN_SCORED_S + 1.0
    short = need - 1.0
    args = argparse.Namespace(duration=short, engage_at=engage_s)
    start = " ".join(cli_demo.engagement_lines(args, engage_s))
    assert f"give --duration {need} or more" in start, start
    cli_demo.print_summary(
        {
            "scenario": "torsetnes_2004", "sim_seconds": short, "wall_seconds": 5.0, "log": "d.mcap",
            "logs": ["d.mcap"], "sources": {}, "sent": {}, "estimates": 10, "alarms": [], "mode": "dp",
            "settle_s": cli_demo.SETTLE_S, "engage_at_s": engage_s, "dp_engaged": True,
            "error_vs_truth": {"samples": 0, "horizontal_rms_m": float("nan")}, "station_keeping": None,
        }
    )  # fmt: skip
    end = capsys.readouterr().out
    assert "station keeping: not scored" in end and f"give --duration {need} or more" in end, end
    # --json says why too, in the same words (a program saw only that the figures were missing)
    summary = {
        "sim_seconds": short, "mode": "dp", "engage_at_s": engage_s, "dp_engaged": True,
        "error_vs_truth": {"samples": 0, "horizontal_rms_m": float("nan")}, "station_keeping": None,
    }  # fmt: skip
    why = cli_demo.station_keeping_not_scored(summary)
    assert why is not None and f"  station keeping: {why}" in end
    assert f"  LF estimate vs truth: {cli_demo.estimate_not_scored(summary)}" in end
    assert cli_demo.station_keeping_not_scored({**summary, "station_keeping": {"p95": 1.0}}) is None
