"""The replay's wave-tuning check: a sea far from the observer's ω0 is found and said, with a command
that works as printed; no sea, no warning."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from dpgw.cli import main
from gateway.replay import parse_observer_spec
from gateway.report.data import DOF
from gateway.report.findings import amplification_warnings
from gateway.report.wave_check import CLEAR_PEAK_DB, check_wave_tuning, retune_spec
from observers.factory import OBSERVER_TYPES
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.mcap.writer import McapLogWriter

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
BAND = (0.2, 2.0)


def vessel_under_way(seed: int, wave_omega: float | None, duration: float = 900.0, dt: float = 0.1):  # type: ignore[no-untyped-def]
    """Position/heading as a DP log sees them: LF motion of metres over minutes (integrated noise through a
    slow first-order lag), a narrow-band sea at `wave_omega` (none if None), 0.3 m / 0.2° white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, dt)
    n = len(t)
    y = np.empty((n, 3))
    b, a = signal.butter(1, 0.02 / (math.pi / dt))  # 0.02 rad/s lag: minutes
    for k, (lf_scale, wf_amp, noise) in enumerate([(3.0, 0.3, 0.3), (3.0, 0.3, 0.3), (0.05, 0.003, 0.0035)]):
        lf = signal.lfilter(b, a, np.cumsum(rng.standard_normal(n))) * lf_scale * dt
        wf = np.zeros(n)
        if wave_omega is not None:
            # a sea of 20 components over ±10 % of the peak, random phases
            for w in wave_omega * np.linspace(0.9, 1.1, 20):
                wf += wf_amp / math.sqrt(20) * math.sqrt(2) * np.sin(w * t + rng.uniform(0, 2 * math.pi))
        y[:, k] = lf + wf + noise * rng.standard_normal(n)
    return t, y


@pytest.mark.parametrize("seed", range(3))
def test_a_sea_far_from_omega0_is_found_and_the_advice_gives_its_period(seed: int) -> None:
    t, y = vessel_under_way(seed, wave_omega=0.55)
    wc = check_wave_tuning(
        t, y, BAND, {"passive": np.full((len(t), 3), 0.8976)}, {"passive": ("passive", False)}
    )
    assert wc.measured is not None and abs(wc.measured / 0.55 - 1.0) < 0.05
    assert all(p.clear and p.above_trend_db >= CLEAR_PEAK_DB for p in wc.peaks.values())
    (warning,) = wc.warnings()
    m = re.search(r"--observer passive:wave_period_s=([0-9.]+), or", warning)
    assert m is not None, warning
    assert abs(float(m.group(1)) / (2 * math.pi / 0.55) - 1.0) < 0.06
    assert wc.notes() == []  # a clear peak: the check was made
    # tuned to the sea: silent
    tuned = check_wave_tuning(t, y, BAND, {"passive": np.full(len(t), 0.55)})
    assert tuned.warnings() == [] and tuned.notes() == [] and tuned.observers[0].ratio is not None


@pytest.mark.parametrize("seed", range(12))
def test_no_sea_no_warning(seed: int) -> None:
    """LF motion and white noise only: the spectrum falls through the band; its maximum is no wave peak."""
    t, y = vessel_under_way(seed, wave_omega=None)
    wc = check_wave_tuning(t, y, BAND, {"passive": np.full(len(t), 0.8976)})
    assert wc.measured is None
    assert wc.warnings() == []
    # no verdict, but said: the check could not be made, and why in each DOF
    (note,) = wc.notes()
    assert note.startswith("no clear wave peak in the log (") and note.endswith(
        "the wave frequency the observers used ('passive' 0.90 rad/s) could not be checked against the sea"
    )
    assert all(d in note for d in ("north", "east", "heading")), note


def test_an_observer_that_schedules_omega0_is_told_to_widen_its_range() -> None:
    t, y = vessel_under_way(1, wave_omega=0.35)
    w0 = np.clip(np.linspace(0.9, 0.3, len(t)), 0.6, None)  # moved, but stuck at its bound 0.6
    wc = check_wave_tuning(t, y, BAND, {"gs": w0}, {"gs": ("gain_scheduled", True)})
    (warning,) = wc.warnings()
    assert "range does not reach" in warning
    m = re.search(
        r"--observer gain_scheduled:wave_period_s=([0-9.]+),omega_min=([0-9.]+),omega_max=([0-9.]+)$", warning
    )
    assert m is not None, warning
    period, lo, hi = (float(g) for g in m.groups())
    assert lo < 2 * math.pi / period < hi and abs(2 * math.pi / period / 0.35 - 1) < 0.06


@pytest.mark.parametrize("scale", [1.0, 70.0])
def test_a_peak_slower_than_any_sea_is_not_advised_as_the_wave_period(scale: float) -> None:
    """The band reaches 31 s (its low edge), past the longest swell (25 s, ÷ √λ for a model): a clear
    peak there, e.g. a DP oscillation, is said to be more likely the vessel's own motion, and retuning the
    wave filter to it is not given as the fix (a filter there would take out the motion DP must act on)."""
    root = math.sqrt(scale)
    t, y = vessel_under_way(2, wave_omega=0.235, duration=1800.0)
    t = t / root  # the same record at the model's scale: times ÷ √λ, frequencies × √λ
    band = (BAND[0] * root, BAND[1] * root)
    wc = check_wave_tuning(
        t,
        y,
        band,
        {"passive": np.full(len(t), 0.8976 * root)},
        {"passive": ("passive", False)},
        froude_scale=scale,
    )
    assert wc.measured is not None and abs(wc.measured / (0.235 * root) - 1.0) < 0.06
    assert wc.longest_sea_s == pytest.approx(25.0 / root)
    (warning,) = wc.warnings()
    assert f"longer than any sea's ({25.0 / root:.3g} s at most" in warning, warning
    assert "more likely the vessel's own slow motion" in warning
    assert "Re-run with" not in warning and "gain_scheduled" not in warning, warning
    # a sea inside the periods a sea has keeps its advice (the test above at full scale)
    t2, y2 = vessel_under_way(2, wave_omega=0.3, duration=1800.0)
    inside = check_wave_tuning(t2, y2, BAND, {"passive": np.full(len(t2), 0.8976)})
    (advice,) = inside.warnings()
    assert "Re-run with --observer passive:wave_period_s=" in advice and "longer than any sea's" not in advice


def _advised_spec(stderr: str) -> str:
    m = re.search(r"Re-run with --observer (\S+), or|re-run with --observer (\S+)$", stderr.strip(), re.M)
    assert m is not None, stderr
    return m.group(1) or m.group(2)


def test_replay_warns_with_a_command_that_works_as_printed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Snijders' sea (JONSWAP Tp 12 s) replayed with the default 7 s tuning: a warning naming the period;
    the command it prints runs and is silent."""
    log = tmp_path / "sea.mcap"
    with McapLogWriter(log) as out:
        Simulation(get_scenario("snijders_2005"), seed=3, log=out).run(900.0)
    args = ["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "a.mcap"), "--json"]
    assert main(args) == 0
    cap = capsys.readouterr()
    summary = json.loads(cap.out)
    wc = summary["wave_check"]
    assert 0.45 < wc["measured_peak_rad_s"] < 0.6  # Tp 12 s is 0.52 rad/s
    assert wc["observers"]["passive"]["mistuned"] is True
    assert "warning: the measured wave peak" in cap.err
    err_first = cap.err.splitlines()
    spec = _advised_spec(cap.err)
    assert spec.startswith("passive:wave_period_s=1")
    args = [
        "replay",
        str(log),
        "--vessel",
        "mss_supply",
        "--observer",
        spec,
        "--out",
        str(tmp_path / "b.mcap"),
    ]
    assert main([*args, "--json"]) == 0
    cap = capsys.readouterr()
    assert "warning" not in cap.err
    again = json.loads(cap.out)
    assert not any(o["mistuned"] for o in again["wave_check"]["observers"].values())
    # A simulator's log has its truth: the advice was tried on it, and its score is what running it gives
    # (the same pipeline); the note says better or worse by what the numbers say
    tried = wc["advice_on_truth"]["passive"]
    assert tried["advised"] == spec and tried["as_run"] == summary["error_vs_truth"]["passive"]
    (as_printed,) = again["error_vs_truth"].values()
    assert tried["error_vs_truth"] == as_printed
    (note,) = [line for line in err_first if "tried on this log's truth" in line]
    keys = ("rms_north_m", "rms_east_m", "rms_heading_deg")
    better = [tried["error_vs_truth"][k] < tried["as_run"][k] for k in keys]
    verdict = (
        "better in every DOF" if all(better) else "worse in every DOF" if not any(better) else "better in "
    )
    assert verdict in note, note


def test_replay_of_a_sea_the_tuning_fits_is_silent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "sea.mcap"
    with McapLogWriter(log) as out:
        Simulation(get_scenario("fossen_strand_1999"), seed=3, log=out).run(900.0)
    assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "a.mcap")]) == 0
    assert "warning" not in capsys.readouterr().err


def test_real_usv_log_in_a_short_sea_is_called_mistuned(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = DATA / "usv-nmea" / "202412061745.txt"
    if not log.exists():
        pytest.skip(f"{log} not present (../shared/data beside the clone)")
    args = ["replay", str(log), "--vessel", "cybership2", "--out", str(tmp_path / "a.mcap"), "--json"]
    assert main(args) == 0
    cap = capsys.readouterr()
    wc = json.loads(cap.out)["wave_check"]
    assert 3.5 < wc["measured_peak_rad_s"] < 4.5
    spec = _advised_spec(cap.err)
    assert (
        main(
            [
                "replay",
                str(log),
                "--vessel",
                "cybership2",
                "--observer",
                spec,
                "--out",
                str(tmp_path / "b.mcap"),
            ]
        )
        == 0
    )
    assert "warning" not in capsys.readouterr().err


def test_report_without_matplotlib_says_so_on_the_console(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import gateway.report.plots as plots
    import gateway.report.writer as writer

    monkeypatch.setattr(plots, "load_figure", lambda: None)
    monkeypatch.setattr(writer, "load_figure", lambda: None)
    log = tmp_path / "sea.mcap"
    with McapLogWriter(log) as out:
        Simulation(get_scenario("fossen_strand_1999"), seed=1, log=out).run(200.0)
    args = ["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "a.mcap")]
    assert main([*args, "--report", str(tmp_path / "rep")]) == 0
    err = capsys.readouterr().err
    assert "matplotlib is not installed" in err and "pip install matplotlib" in err
    assert not list((tmp_path / "rep").glob("*.png"))


def test_replay_checks_only_received_samples_as_the_report_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 10 Hz gyro beside a 10 Hz DGPS 20 ms later (hassani): the pipeline steps on both, holding the
    other DOF, and the held heading is a staircase with a line of its own (read as a 15.7 rad/s sea that
    the tuning 'missed'). The check takes only what was received, as the report's measurement does: per
    DOF the same peak as the report, and no warning for a sea the log does not have."""
    log = tmp_path / "sea.mcap"
    with McapLogWriter(log) as out:
        Simulation(get_scenario("hassani"), seed=0, log=out).run(300.0)
    report = tmp_path / "report"
    args = ["replay", str(log), "--out", str(tmp_path / "a.mcap"), "--report", str(report), "--json"]
    assert main(args) == 0
    cap = capsys.readouterr()
    per_dof = json.loads(cap.out)["wave_check"]["per_dof"]
    measured = json.loads((report / "metrics.json").read_text())["measurement"]
    for dof in ("north", "east", "heading"):
        assert per_dof[dof]["peak_rad_s"] == pytest.approx(measured[dof]["dominant_frequency_rad_s"]), dof
    assert "warning: the measured wave peak" not in cap.err


def test_an_mmae_bank_that_misses_the_sea_is_advised_a_bank_the_replay_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The MMAE's default bank is Hassani's full-scale one (0.3-1.35 rad/s) on every vessel, so on the
    1:70 USV log (a 3.9 rad/s sea) it settles at 0.75 rad/s and is warned. Before, the advice was
    `mmae:wave_period_s=...,omega_min=...,omega_max=...`, keys the MMAE refuses (it has a bank, not a
    range): the printed command stopped with an error. Now it advises a bank around the sea, which runs
    as printed.

    On this log that bank is not the end: the USV's LF motion, without a clear wave peak in east and
    heading, is explained as waves by the slowest filter, which wins (docs/mmae.md: the filter that expects
    the most motion explains LF motion as waves). (Before, the bank's noise was never identified at 5 Hz,
    its weights stayed uniform and their mean, 4.9 rad/s, passed for a fit.) The warning then does not
    advise the same bank again, a circle, but a fixed ω0 at the measured peak, which runs as printed and
    is silent."""
    log = DATA / "usv-nmea" / "202412061745.txt"
    if not log.exists():
        pytest.skip(f"{log} not present (../shared/data beside the clone)")
    base = ["replay", str(log), "--vessel", "cybership2", "--observer"]
    assert main([*base, "mmae", "--out", str(tmp_path / "a.mcap")]) == 0
    err = capsys.readouterr().err
    m = re.search(r"--observer (mmae:candidates=[0-9./]+)", err)
    assert m is not None, err
    bank = [float(x) for x in m.group(1).split("=")[1].split("/")]
    assert len(bank) == 8 and min(bank) < 3.92 < max(bank)  # around the measured peak
    assert main([*base, m.group(1), "--out", str(tmp_path / "b.mcap"), "--json"]) == 0
    cap = capsys.readouterr()
    (tuning,) = json.loads(cap.out)["wave_check"]["observers"].values()
    assert tuning["omega0_rad_s"] == pytest.approx(min(bank), rel=0.05)  # the weights moved, to the slowest
    again = re.search(r"--observer (mmae:candidates=[0-9./]+)", cap.err)
    assert again is None, cap.err  # not the same bank again
    m = re.search(
        r"spans the sea's, .*led by the motion without a clear wave peak \(east and heading\).*"
        r"--observer (passive:wave_period_s=[0-9.]+)\.",
        cap.err,
    )
    assert m is not None, cap.err
    assert main([*base, m.group(1), "--out", str(tmp_path / "c.mcap"), "--json"]) == 0
    cap = capsys.readouterr()
    assert "warning" not in cap.err
    (tuning,) = json.loads(cap.out)["wave_check"]["observers"].values()
    assert tuning["mistuned"] is False and abs(tuning["omega0_rad_s"] / 3.92 - 1.0) < 0.05


def _usv_like_log(path: Path, seed: int = 0, duration: float = 300.0) -> tuple[str, str]:
    """An NMEA log of a model at 5 Hz (GGA, RMC, HDT) moving with LF motion and noise only, no sea (as the
    calm USV trial): its first cycle has no fix (GGA quality 0, RMC void), so the log's first time is a
    cycle before its first measurement. Returns the UTC of both, as hh:mm:ss.s."""
    from datetime import UTC, datetime, timedelta

    from wire.codecs import nmea_encode as enc

    dt = 0.2
    rng = np.random.default_rng(seed)
    n = round(duration / dt)
    # a random walk (its spectrum falls as 1/ω² through the band: no peak) under RTK noise of millimetres;
    # the heading's walk of 0.3° a step, its noise 0.05°
    steps = rng.standard_normal((n, 3)) * [0.01, 0.01, math.radians(0.3)]
    y = np.cumsum(steps, axis=0) + rng.standard_normal((n, 3)) * [0.002, 0.002, math.radians(0.05)]
    lat0, lon0 = 22.567, 114.532
    t0 = datetime(2024, 12, 5, 13, 37, 23, 500000, tzinfo=UTC)
    lines = []
    for k in range(n):
        when = t0 + timedelta(seconds=k * dt)
        lat = lat0 + y[k, 0] / 111_320.0
        lon = lon0 + y[k, 1] / (111_320.0 * math.cos(math.radians(lat0)))
        fix = k > 0
        lines += [
            enc.gga("GP", when, lat, lon, 4 if fix else 0, 19, 0.9, 3.4, decimals=9),
            enc.rmc("GP", when, lat, lon, 0.05, 1.0, fix, decimals=9),
        ]
        if fix:
            lines.append(enc.hdt("GN", 4.0 + y[k, 2]))
    path.write_text("".join(lines))
    return "13:37:23.5", "13:37:23.7"


def test_a_calm_log_says_the_check_was_not_made_and_the_report_that_the_filter_amplifies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A model's log without a sea (a calm trial: LF motion and noise), replayed as cybership2 with the
    default ω0 7.51 rad/s. Every DOF's maximum is the band's edge: no verdict, but the console now says
    that the ω0 check could not be made (before: nothing). The passive filter's LF response is above 1
    below its notch (+1.8 dB at 1.68 rad/s, `lf_response`), so the report's attenuation at that maximum
    is positive: the report and the console now both warn of it (before: +1.2 to +2.6 dB in a table,
    nothing said). Each line on the console is in report.md's Warnings as said."""
    log = tmp_path / "calm.txt"
    first_time, first_fix = _usv_like_log(log)
    report = tmp_path / "rep"
    args = ["replay", str(log), "--vessel", "cybership2", "--out", str(tmp_path / "a.mcap")]
    assert main([*args, "--report", str(report), "--json"]) == 0
    cap = capsys.readouterr()
    summary = json.loads(cap.out)
    assert summary["wave_check"]["measured_peak_rad_s"] is None
    assert all(d["at_band_edge"] for d in summary["wave_check"]["per_dof"].values())
    (note,) = summary["wave_check"]["notes"]
    assert "could not be checked against the sea" in note and "'passive' 7.51 rad/s" in note
    metrics = json.loads((report / "metrics.json").read_text())
    attenuation = [metrics["observers"]["passive"][d]["attenuation_db"] for d in ("north", "east", "heading")]
    assert all(a > 0.0 for a in attenuation), attenuation
    (amplifies,) = summary["report_warnings"]
    assert amplifies == metrics["warnings"][0]
    assert amplifies.startswith("observer 'passive' amplifies the measured motion at the measurement's")
    assert "no clear wave peak" in amplifies and "(ω0 in use 7.51 rad/s)" in amplifies
    # the observer's own name in its advice, a spec that runs as printed (was "--observer NAME:...")
    assert "(--observer passive:wave_period_s=" in amplifies and "NAME" not in amplifies, amplifies
    err = cap.err.splitlines()
    assert f"dpgw replay: note: {note}" in err
    assert f"dpgw replay: warning: report: {amplifies}" in err
    md = (report / "report.md").read_text()
    warnings = md.split("## Warnings\n\n", 1)[1].split("\n\n", 1)[0].splitlines()
    # (and that an NMEA log alone has no thrust: the observers ran with τ = 0)
    (no_thrust,) = [line for line in err if "no thruster feedback in the log" in line]
    no_thrust = no_thrust.removeprefix("dpgw replay: note: ")
    assert summary["measurements"]["tau_from_feedback"] == summary["measurements"]["tau_from_demand"] == 0
    assert warnings == [f"- note: {note}", f"- note: {no_thrust}", f"- warning: {amplifies}"]
    # the start: the console's log line counts from the first sentence with a time (a cycle without a
    # fix), the report's t = 0 from the first fused measurement; the report gives both, each labelled
    (log_line,) = [line for line in _plain_summary(args).splitlines() if line.startswith("  log calm.txt:")]
    span = log_line.split("; ", 1)[1]
    assert span.startswith(f"2024-12-05 {first_time} to ")
    assert f"\n- log calm.txt: {span} — its first to last sentence or record with a time\n" in md
    assert "- span: 0.0 s to " in md and f", 2024-12-05 {first_fix} to " in md
    assert " — from the first fused measurement (t = 0 s in the tables and plots)" in md


def _plain_summary(args: list[str]) -> str:
    """The console summary of the replay ``args`` (again, to another file)."""
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        assert main(args) == 0
    return buf.getvalue()


def test_real_calm_usv_log_says_so_on_the_console_as_the_report_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The user's trial: 202412051037 replayed as cybership2 with --report showed +1.21/+2.26/+2.64 dB and
    "band edge: no clear wave peak" in report.md, and the console said nothing of either."""
    log = DATA / "usv-nmea" / "202412051037.txt"
    if not log.exists():
        pytest.skip(f"{log} not present (../shared/data beside the clone)")
    report = tmp_path / "rep"
    args = ["replay", str(log), "--vessel", "cybership2", "--out", str(tmp_path / "a.mcap")]
    assert main([*args, "--report", str(report)]) == 0
    err = capsys.readouterr().err
    assert (
        "dpgw replay: note: no clear wave peak in the log (north, east and heading: maximum 1.68 rad/s" in err
    )
    assert "dpgw replay: warning: report: observer 'passive' amplifies the measured motion" in err
    assert "+1.21 dB in N, +2.26 dB in E, +2.64 dB in ψ at 1.68 rad/s" in err
    md = (report / "report.md").read_text()
    assert "## Warnings" in md and "+1.21 dB in N, +2.26 dB in E, +2.64 dB in ψ at 1.68 rad/s" in md


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(OBSERVER_TYPES), omega=st.floats(0.2, 12.0))
def test_every_retuning_advised_is_a_spec_replay_takes(kind: str, omega: float) -> None:
    """The advice names the observer's own keys: ``wave_period_s`` where it uses ω0, a bank for the MMAE.
    Before, the amplification warning advised ``mmae:wave_period_s=...``, which replay refused."""
    spec = parse_observer_spec(retune_spec(kind, omega))
    assert spec.name == kind
    if kind == "mmae":
        bank = spec.params["candidates"]
        assert min(bank) < omega < max(bank)
    else:
        assert 2 * math.pi / spec.params["wave_period_s"] == pytest.approx(omega, rel=0.06)


def test_the_amplification_warning_advises_each_observer_in_its_own_keys() -> None:
    """`amplification_warnings` on a report's metrics where the MMAE and the SDRE both lift the motion at a
    2.88 rad/s peak: each is advised a spec of its own keys, the period as the wave check writes it."""
    dof = {"attenuation_db": 4.57, "omega0_median_rad_s": 2.88}
    measured = {d: {"dominant_frequency_rad_s": 2.88, "peak_at_band_edge": False} for d in DOF}
    metrics = {
        "measurement": measured,
        "observers": {name: {"observer": name, **{d: dict(dof) for d in DOF}} for name in ("mmae", "sdre")},
    }
    mmae, sdre = amplification_warnings(metrics)
    m = re.search(r"--observer (mmae:candidates=[0-9./]+)\)", mmae)
    assert m is not None and parse_observer_spec(m.group(1)).name == "mmae", mmae
    assert "(--observer sdre:wave_period_s=2.2)" in sdre, sdre


def test_every_advice_of_the_wave_check_runs_as_printed() -> None:
    """Each mistuned observer is advised a spec replay takes, and the warning prints that spec: an adaptive
    SDRE's range with ``adaptive=true`` again (a fixed SDRE refuses a range: before, the advice was
    refused), the MMAE a bank, a fixed observer its own wave period."""
    t, y = vessel_under_way(1, wave_omega=0.35)
    w0 = np.full(len(t), 0.9)
    kinds = {
        "gs": ("gain_scheduled", True),
        "sd": ("sdre", True),
        "mm": ("mmae", True),
        "p": ("passive", False),
    }
    wc = check_wave_tuning(t, y, BAND, dict.fromkeys(kinds, w0), kinds)
    advised = wc.advised()
    assert set(advised) == set(kinds)
    for label, spec in advised.items():
        parsed = parse_observer_spec(spec)
        assert parsed.name == kinds[label][0]
        assert any(f"--observer {spec}" in w for w in wc.warnings()), (spec, wc.warnings())
    assert parse_observer_spec(advised["sd"]).params["adaptive"]
