"""The replay's vessel-scale check: a log with motion faster than the given vessel makes (a small craft
replayed as a ship) gets one line of advice naming the vessels that fit; a log replayed with its own
vessel gets none."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_wave_check import vessel_under_way

from dpgw.cli import main
from gateway.report.vessel_check import builtin_scales, check_vessel_scale
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.codecs import nmea_encode as enc
from wire.mcap.writer import McapLogWriter

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SHIP = ("mss_supply", 76.2, None)


def check(t: np.ndarray, y: np.ndarray, vessel: tuple[str, float, float | None] = SHIP):  # type: ignore[no-untyped-def]
    return check_vessel_scale(t, y, vessel[0], vessel[1], vessel[2], builtin_scales())


@pytest.mark.parametrize("seed", range(3))
def test_a_short_sea_a_ship_does_not_ride_is_advised_and_a_ship_s_sea_is_not(seed: int) -> None:
    """A sea at 4 rad/s (1.6 s) in the motion, above a ship's wave band (0.2-2 rad/s): advice naming the
    model-scale vessel, whose band reaches it. A ship's sea (0.55 rad/s), or none at all: nothing."""
    t, y = vessel_under_way(seed, wave_omega=4.0)
    short = check(t, y)
    assert short.fastest is not None and abs(short.fastest / 4.0 - 1.0) < 0.05
    assert short.suitable == ("cybership2",)
    assert "--vessel cybership2" in short.advice() and "smaller vessel" in short.advice()
    assert check(t, y, ("cybership2", 1.255, 70.0)).advice() == ""  # inside the model's band
    for omega in (0.55, None):
        t, y = vessel_under_way(seed, wave_omega=omega)
        assert check(t, y).advice() == "", omega


Capture = pytest.CaptureFixture[str]


def replay_json(log: Path, tmp_path: Path, capsys: Capture, *extra: str) -> dict[str, Any]:
    assert main(["replay", str(log), *extra, "--out", str(tmp_path / "r.mcap"), "--json"]) == 0
    out: dict[str, Any] = json.loads(capsys.readouterr().out)
    return out


MATCHED = [
    "torsetnes_2004",  # the demo's scenario
    "hassani",  # CyberShip II, a 1:70 model
    "mss_supply_storm",
    "mss_osv",
    "hajivand_2010",
    "snijders_2005",
    "fossen_strand_1999",
]


@pytest.mark.parametrize("scenario", MATCHED)
def test_a_generated_log_replayed_with_its_own_vessel_gets_no_advice(
    scenario: str, tmp_path: Path, capsys: Capture
) -> None:
    log = tmp_path / "sim.mcap"
    with McapLogWriter(log) as out:
        Simulation(get_scenario(scenario), seed=1, log=out).run(300.0)
    check = replay_json(log, tmp_path, capsys)["vessel_check"]
    assert check["advice"] is None, check
    assert not any(d["clear"] for d in check["above_band"].values())


def small_craft_log(path: Path, seconds: float = 600.0, seed: int = 1) -> None:
    """A 5 Hz NMEA log (GGA + HDT) of a small craft riding a short sea: 0.1 m and 1° of motion in a
    narrow band around 4 rad/s (1.6 s), slow drift, RTK noise (1 cm, 0.1°)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.2)
    motion = np.zeros((len(t), 3))
    for k, amp in enumerate((0.1, 0.1, math.radians(1.0))):
        for w in 4.0 * np.linspace(0.9, 1.1, 20):
            motion[:, k] += amp / math.sqrt(10) * np.sin(w * t + rng.uniform(0, 2 * math.pi))
    motion[:, 0] += 0.002 * t
    noise = rng.normal(0.0, 1.0, (len(t), 3)) * (0.01, 0.01, math.radians(0.1))
    y = motion + noise
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    lines = []
    for k, tk in enumerate(t):
        lat = 59.4 + y[k, 0] / 111_320.0
        lon = 10.5 + y[k, 1] / (111_320.0 * math.cos(math.radians(59.4)))
        lines.append(enc.gga("GP", t0 + timedelta(seconds=float(tk)), lat, lon, 4, 14, 0.7, 3.0))
        lines.append(enc.hdt("GN", 1.0 + y[k, 2]))
    path.write_text("".join(lines))


def test_a_small_craft_s_log_replayed_as_a_supply_vessel_is_advised_a_smaller_one(
    tmp_path: Path, capsys: Capture
) -> None:
    """A small craft in a short sea (1.6 s) replayed as the 6,000 t mss_supply: advice on the summary's
    own line and in --json, naming --vessel cybership2, whose band reaches the sea; replayed so, none."""
    log = tmp_path / "craft.nmea"
    small_craft_log(log)
    check = replay_json(log, tmp_path, capsys, "--vessel", "mss_supply")["vessel_check"]
    assert check["advice"] is not None and "--vessel cybership2" in check["advice"], check
    assert check["suitable"] == ["cybership2"]
    assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "s.mcap")]) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("advice:")]
    assert len(lines) == 1 and "vessel 'mss_supply' does not fit this log" in lines[0]
    assert replay_json(log, tmp_path, capsys, "--vessel", "cybership2")["vessel_check"]["advice"] is None


def test_the_usv_log_replayed_as_a_supply_vessel_is_advised_a_smaller_one(
    tmp_path: Path, capsys: Capture
) -> None:
    """The real USV log in a short sea (202412061745: peaks at 3.9 and 4.1 rad/s, 1.5-1.6 s) replayed as
    the 6,000 t mss_supply: advice to re-run with --vessel cybership2; re-run so, no advice. Before, the
    summary said nothing about the vessel."""
    path = DATA / "usv-nmea" / "202412061745.txt"
    if not path.exists():
        pytest.skip(f"{path} not present (../shared/data beside the clone)")
    advice = replay_json(path, tmp_path, capsys, "--vessel", "mss_supply")["vessel_check"]["advice"]
    assert advice is not None
    m = re.search(r"re-run with --vessel (\S+) ", advice)
    assert m is not None and m.group(1) == "cybership2", advice
    periods = [float(x) for x in re.findall(r"periods down to ([0-9.]+) s", advice)]
    assert periods and 1.3 < periods[0] < 1.8
    assert replay_json(path, tmp_path, capsys, "--vessel", m.group(1))["vessel_check"]["advice"] is None


@pytest.mark.slow  # 240 s of sea at 10x: ~30 s
def test_the_demo_s_own_log_gets_no_advice(tmp_path: Path, capsys: Capture) -> None:
    out = tmp_path / "demo.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "240", "--out", str(out), "--json",
         "--no-scouting", "--no-foxglove"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert replay_json(out, tmp_path, capsys)["vessel_check"]["advice"] is None
    assert math.isfinite(json.loads(proc.stdout)["station_keeping"]["position_p95_m"])
