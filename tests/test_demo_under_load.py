"""`dpgw demo` on a machine that is busy: the loop stays right, only its speed suffers.

The simulator publishes its time on Zenoh, the gateway stamps with it, and the demo pauses or slows the
simulation while the gateway is behind (docs/gateway.md, "Simulation time"). Run quietly and with two
CPU-bound processes hogging both cores, the gateway and the plant share one time base (each DGPS fix is
stamped the receiver's latency after the fix's own time, 99 % of them within one sample period more), the
LF estimate error is within 25 % of the quiet run's (plus the quiet run's own spread), and station keeping
holds (p95 ≤ 0.5 m).

The scenario is `hassani` (Cybership II, model scale, 10 Hz RTK and gyro): its fast dynamics make it the
one most sensitive to loop delay (without the simulation clock and pacing it lost its heading under this
load: p95 30-40 m), and its controller settles within the run. DP is engaged from the first estimate
(`--engage-at 0`): the demo's default waits for the observer's slowest mode (61 s here), half this test's
run; loop delay matters the same either way. The default `torsetnes_2004` engaged cold needs
longer than a short demo to settle from its start (p95 about 5 m over 60-180 s), so it cannot show the
bound in a test of this length; engaged as the demo does by default, tests/test_demo_engage.py.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import wait_for

SCENARIO = "hassani"
DURATION_S = "120"
FIX_PERIOD_S = 0.1  # the scenario's RTK receiver at 10 Hz: one sample
FIX_LATENCY_S = 0.1  # and its latency (simulator.sensors.DgpsConfig)
STATION_P95_M = 0.5  # station keeping p95 bound, five times what it holds
QUIET_SPREAD_M = 0.005  # the quiet run's LF RMS from run to run (0.025-0.030 m measured)


def demo(out: Path) -> dict[str, Any]:
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "demo", "--scenario", SCENARIO, "--duration", DURATION_S,
         "--out", str(out), "--json", "--no-scouting", "--engage-at", "0"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary: dict[str, Any] = json.loads(proc.stdout)
    return summary


def figures(s: dict[str, Any]) -> str:
    k, e, lag = s["station_keeping"], s["error_vs_truth"], s["fix_stamp_lag_s"]
    return (
        f"LF RMS {e['horizontal_rms_m']:.3f} m, "
        f"p95 {k['position_p95_m']:.2f} m / {k['heading_p95_deg']:.2f}°, "
        f"fix stamp - fix time median {1000 * lag['median']:.0f} ms, p99 {1000 * lag['p99']:.0f} ms, "
        f"max {1000 * lag['max']:.0f} ms; speed {s['speed']['final']:g}x "
        f"(pauses {s['speed']['pauses']}, {s['speed']['paused_s']:.1f} s), wall {s['wall_seconds']:.1f} s"
    )


@pytest.mark.slow  # two demos of 120 s of sea: about a minute
@pytest.mark.alone  # its bounds are for two hogs, not for another test's simulation beside them
def test_the_demo_under_two_cpu_hogs_keeps_one_time_base_and_station(tmp_path: Path) -> None:
    quiet = demo(tmp_path / "quiet.mcap")
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        loaded = demo(tmp_path / "loaded.mcap")
    finally:
        for h in hogs:
            h.kill()
        for h in hogs:
            h.wait()
    print(f"\nquiet:  {figures(quiet)}\nloaded: {figures(loaded)}")
    for run in (quiet, loaded):
        # one time base: a fix is stamped its latency after its own time, within one sample period
        lag = run["fix_stamp_lag_s"]
        assert abs(lag["median"] - FIX_LATENCY_S) <= 0.02
        assert lag["p99"] <= FIX_LATENCY_S + FIX_PERIOD_S
        # (0.10 m in every run, quiet or loaded, since the observer keeps up with the loop; it lost its
        # heading before the simulation clock: p95 30-40 m)
        assert run["station_keeping"]["position_p95_m"] <= STATION_P95_M
        assert run["estimates"] > 1000
    rms_quiet = quiet["error_vs_truth"]["horizontal_rms_m"]
    # within 25 % of the quiet run's, plus the quiet run's own spread from run to run (its timing differs:
    # 0.025-0.030 m measured in five quiet runs since the observer keeps up with the loop; at that size a
    # quarter is 6 mm, and the quiet run alone moves by 4)
    assert loaded["error_vs_truth"]["horizontal_rms_m"] <= 1.25 * rms_quiet + QUIET_SPREAD_M


@pytest.mark.slow  # a demo started and stopped: a few seconds
def test_a_demo_stopped_with_ctrl_c_ends_cleanly_and_says_it_was_interrupted(tmp_path: Path) -> None:
    """Ctrl-C during `dpgw demo`: the simulation ends its current second of sea before the gateway
    closes the Zenoh session and the log, so the stop is not reported as a failure of the simulator (it
    was: the simulation went on into the closed session), the exit status is 130 (as `dpgw study`'s: it
    was 0), the JSON summary covers what ran and says it was interrupted, by Ctrl-C, and the log is
    complete (its summary section readable)."""
    from mcap.reader import make_reader

    out = tmp_path / "stopped.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "3600", "--out", str(out), "--json",
         "--no-scouting"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        # running: the log has its first chunk of data (the writer closes a chunk each wall second)
        assert wait_for(
            lambda: proc.poll() is not None or (out.exists() and out.stat().st_size > 20_000), 120
        )
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, stderr
    assert "failed" not in stderr, stderr
    summary = json.loads(stdout)
    assert summary["interrupted"] is True and summary["stopped_by"] == "SIGINT"
    assert 0 < summary["sim_seconds"] < 3600
    with out.open("rb") as f:
        stats = make_reader(f).get_summary()
    assert stats is not None and stats.statistics is not None and stats.statistics.message_count > 0
