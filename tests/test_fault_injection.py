"""The simulator's faults for testing a gateway's defences: a slowly drifting reference, a far fix, bad GGA
quality, bogus thruster feedback and hostile commands; checked on the wire with parsers that are not ours
(pynmea2, pymavlink), positions back to NED with pymap3d."""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import pynmea2
import pytest

from simulator.clock import SimEpoch
from simulator.faults import COMMAND_KINDS, Fault, FaultSchedule
from simulator.sensors import (
    Datum,
    Dgps,
    DgpsConfig,
    Emission,
    Gyro,
    GyroConfig,
    ShipState,
    ThrusterFeedback,
    ThrusterFeedbackConfig,
    ThrusterReading,
)
from wire.codecs import mavlink as mv

REPO = Path(__file__).resolve().parent.parent
EPOCH = SimEpoch(datetime(2024, 6, 1, 12, 0, 0, tzinfo=UTC))
DATUM = Datum(63.44, 10.40, 0.0)
STILL = ShipState(0.0, np.array([0.0, 0.0, math.radians(30.0)]), np.zeros(3))
QUIET_GPS: dict[str, Any] = {"sigma_m": 0.0, "sigma_velocity_mps": 0.0, "rate_hz": 1.0}


def at(t: float) -> ShipState:
    return ShipState(t, STILL.eta, STILL.nu, STILL.thrusters)


def sample_until(sensor: Dgps | Gyro | ThrusterFeedback, t_end: float) -> list[Emission]:
    out: list[Emission] = []
    while sensor.next_time() < t_end:
        out += sensor.sample(at(sensor.next_time()))
    return out


def gga(emissions: list[Emission]) -> list[tuple[float, Any]]:
    return [
        (em.t_measured, pynmea2.parse(em.data.decode().strip(), check=True))
        for em in emissions
        if b"GGA" in em.data[:6]
    ]


def ned(msg: Any) -> tuple[float, float]:
    n, e, _ = pymap3d.geodetic2ned(msg.latitude, msg.longitude, 0.0, DATUM.lat_deg, DATUM.lon_deg, 0.0)
    return float(n), float(e)


def dgps(faults: list[Fault], **config: Any) -> Dgps:
    return Dgps(
        DgpsConfig(**{**QUIET_GPS, **config}), DATUM, EPOCH, np.random.default_rng(0), FaultSchedule(faults)
    )


def test_drift_walks_one_metre_a_minute_and_stops_at_the_end() -> None:
    fault = Fault("drift", "dgps1", 60.0, 360.0, {"north_mps": 1.0 / 60.0})
    fixes = gga(sample_until(dgps([fault]), 400.0))
    for t, msg in fixes:
        n, e = ned(msg)
        expected = (t - 60.0) / 60.0 if 60.0 <= t < 360.0 else 0.0
        assert n == pytest.approx(expected, abs=0.01) and abs(e) < 0.01
    assert max(ned(m)[0] for _, m in fixes) == pytest.approx(299.0 / 60.0, abs=0.01)  # 5 m after 5 min


def test_gyro_drift_and_a_heading_flip() -> None:
    faults = [
        Fault("drift", "gyro1", 10.0, 20.0, {"heading_rad_s": math.radians(0.5)}),
        Fault("jump", "gyro1", 30.0, 31.0, {"heading_rad": math.pi}),
    ]
    gyro = Gyro(
        GyroConfig(sigma_rad=0.0, sigma_rot_rad_s=0.0, rate_hz=10.0),
        EPOCH,
        np.random.default_rng(0),
        FaultSchedule(faults),
    )
    for em in sample_until(gyro, 40.0):
        msg = pynmea2.parse(em.data.decode().strip(), check=True)
        if msg.sentence_type != "HDT":
            continue
        t = em.t_measured
        expected = (
            30.0 + (0.5 * (t - 10.0) if 10.0 <= t < 20.0 else 0.0) + (180.0 if 30.0 <= t < 31.0 else 0.0)
        )
        assert (float(msg.heading) - expected + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=0.011)


def test_spoof_reports_a_far_fix_for_one_sample_only() -> None:
    fault = Fault("spoof", "dgps1", 5.0, 5.5, {"lon_deg": 91.0})
    fixes = gga(sample_until(dgps([fault]), 10.0))
    far = [(t, m) for t, m in fixes if abs(m.longitude - DATUM.lon_deg) > 1.0]
    assert [t for t, _ in far] == [5.0]
    assert far[0][1].longitude == pytest.approx(91.0, abs=1e-6)
    assert far[0][1].latitude == pytest.approx(DATUM.lat_deg, abs=1e-6)  # latitude not spoofed


@pytest.mark.parametrize("quality", [0, 6, 7, 8])
def test_bad_quality_in_gga_and_the_matching_mode_letters(quality: int) -> None:
    fault = Fault("quality", "dgps1", 2.0, 4.0, {"quality": quality})
    letter = "NADPRFEMS"[quality]
    emissions = sample_until(dgps([fault], extra=("RMC", "VTG")), 6.0)
    emissions += sample_until(dgps([fault], position_sentence="GNS", extra=()), 6.0)
    for em in emissions:
        msg = pynmea2.parse(em.data.decode().strip(), check=True)
        bad = 2.0 <= em.t_measured < 4.0
        if msg.sentence_type == "GGA":
            assert msg.gps_qual == (quality if bad else 2)
            if bad:  # no differential corrections claimed for a fix that is not differential
                assert msg.age_gps_data == "" and msg.ref_station_id == ""
        elif msg.sentence_type == "GNS":
            assert msg.mode_indicator == (letter * 2 if bad else "DD")
        else:
            assert msg.data[-1] == (letter if bad else "D")


def thrusters(t: float) -> ShipState:
    readings = tuple(
        ThrusterReading(i, "azimuth", 1e4 * i, 0.1 * i, 100.0 * i, 1e4 * i, 0.1 * i, False) for i in (1, 2)
    )
    return ShipState(t, STILL.eta, STILL.nu, readings)


@pytest.mark.parametrize("claim", [4e7, 1e30])
def test_bogus_feedback_claims_the_thrust_on_one_thruster(claim: float) -> None:
    fault = Fault("bogus_feedback", "2", 1.0, 1.2, {"thrust_n": claim})
    sensor = ThrusterFeedback(
        ThrusterFeedbackConfig(rate_hz=10.0), EPOCH, np.random.default_rng(0), FaultSchedule([fault])
    )
    seen = []
    while sensor.next_time() < 3.0:
        t = sensor.next_time()
        for em in sensor.sample(thrusters(t)):
            for msg in mv.dialect().MAVLink(None).parse_buffer(em.data) or []:
                if msg.get_type() == "AZIMUTH_THRUSTER_STATUS":
                    seen.append((t, msg.id, msg.thrust, msg.azimuth))
    bogus = [(t, i) for t, i, thrust, _ in seen if thrust == pytest.approx(claim, rel=1e-6)]
    assert bogus == [(1.0, 2), (pytest.approx(1.1), 2)]
    assert all(thrust == pytest.approx(1e4 * i) for t, i, thrust, _ in seen if (t, i) not in bogus)
    assert all(az == pytest.approx(0.1 * i) for _, i, _, az in seen)  # only the thrust was faked


def test_a_sample_a_rounding_error_before_the_fault_start_sees_the_fault() -> None:
    """The runner's sim time is a sum of steps: the fix due at 120 s is sampled at 119.99999999999682 s, and a
    one-sample fault scheduled at 120 s must still hit it."""
    fault = Fault("spoof", "dgps1", 120.0, 120.05, {"lon_deg": 91.0})
    assert fault.covers(119.99999999999682) and not fault.covers(120.05 - 1e-9)
    sensor = dgps([fault], rate_hz=10.0)
    sensor._schedule.k = 1200  # the next fix is due at 120 s
    em = sensor.sample(at(119.99999999999682))[0]
    assert pynmea2.parse(em.data.decode().strip()).longitude == pytest.approx(91.0)


def test_command_faults_become_gateway_inputs() -> None:
    schedule = FaultSchedule.from_dicts(
        [
            {"kind": "command_setpoint", "source": "intruder", "t_start": 10, "north_m": 50_000.0},
            {
                "kind": "command_tau",
                "source": "intruder",
                "t_start": 20,
                "t_end": 21,
                "surge_n": 1e12,
                "rate_hz": 4,
            },
            {"kind": "command_mode", "source": "intruder", "t_start": 5, "mode": "manual"},
            {"kind": "dropout", "source": "dgps1", "t_start": 0, "t_end": 1},
        ]
    )
    events = schedule.command_events(until_s=100.0)
    assert events[0] == (5.0, "mode", "manual")
    assert events[1] == (10.0, "setpoint", {"north_m": 50_000.0, "east_m": 0.0, "heading_deg": 0.0})
    taus = [e for e in events if e[1] == "tau"]
    assert [t for t, _, _ in taus] == [20.0, 20.25, 20.5, 20.75]
    assert taus[0][2] == {"X": 1e12, "Y": 0.0, "N": 0.0}
    assert schedule.command_events(until_s=20.3)[-1][0] == 20.25
    assert set(COMMAND_KINDS) == {"command_setpoint", "command_tau", "command_mode"}


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ({"kind": "drift", "source": "a", "t_start": 0}, r"needs at least one of north_mps, east_mps"),
        ({"kind": "spoof", "source": "a", "t_start": 0, "lon_deg": 191}, r"lon_deg: must be in -180..180"),
        ({"kind": "spoof", "source": "a", "t_start": 0, "lat_deg": -91}, r"lat_deg: must be in -90..90"),
        ({"kind": "quality", "source": "a", "t_start": 0, "quality": 9}, r"quality: must be a GGA quality"),
        ({"kind": "quality", "source": "a", "t_start": 0}, r"needs at least one of quality"),
        (
            {"kind": "bogus_feedback", "source": 1, "t_start": 0, "thrust_n": math.inf},
            r"thrust_n: must be finite",
        ),
        ({"kind": "command_mode", "source": "x", "t_start": 0, "mode": 3}, r"mode: must be non-empty text"),
        ({"kind": "command_mode", "source": "x", "t_start": 0, "rate_hz": 1}, r"needs at least one of mode"),
        (
            {"kind": "command_tau", "source": "x", "t_start": 0, "rate_hz": -1, "surge_n": 1},
            r"rate_hz: must be >= 0",
        ),
    ],
)
def test_new_fault_tables_are_validated_with_the_field_named(item: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        FaultSchedule.from_dicts([item])


def test_the_documented_fault_file_loads() -> None:
    """docs/simulator.md's fault file for the defences covers every kind it lists."""
    import re
    import tomllib

    doc = (REPO / "docs" / "simulator.md").read_text()
    blocks = [tomllib.loads(b) for b in re.findall(r"```toml\n(.*?)```", doc, re.S) if "[[faults]]" in b]
    assert blocks
    kinds = {f.kind for b in blocks for f in FaultSchedule.from_dicts(b["faults"]).faults}
    assert kinds >= {
        "jump",
        "frozen",
        "drift",
        "quality",
        "spoof",
        "dropout",
        "bogus_feedback",
        *COMMAND_KINDS,
    }
    # and it runs as `dpgw sim --faults FILE` on a built-in scenario: before, its drift fault named dgps2,
    # which no built-in scenario has, and every scenario refused the file
    from simulator.scenarios import get_scenario

    for b in blocks:
        sc = get_scenario("torsetnes_2004")
        assert sc.fault_problems(FaultSchedule.from_dicts(b["faults"]).faults) == []


# --- faults that would bite nothing ----------------------------------------------------------------------


def test_the_built_in_scenarios_own_faults_all_bite() -> None:
    from dpgw.scenario_names import SCENARIO_NAMES
    from simulator.scenarios import get_scenario

    for name in SCENARIO_NAMES:
        sc = get_scenario(name)
        assert sc.fault_problems(sc.faults) == [], name


@pytest.mark.parametrize(
    ("fault", "says"),
    [
        (
            Fault("jump", "gps9", 10.0, 20.0, {"north_m": 5.0}),
            "has no source 'gps9' (its sources: dgps1, gyro1",
        ),
        (Fault("jump", "gyro1", 1.0, 2.0, {"north_m": 5.0}), "(north_m) acts on the gyro 'gyro1'"),
        (Fault("noise_burst", "dgps1", 1.0, 2.0, {"sigma_rad": 0.1}), "acts on the GNSS 'dgps1'"),
        (Fault("spoof", "gyro1", 1.0, 2.0, {"lat_deg": 60.0}), "a spoof fault acts on a GNSS receiver"),
        (
            Fault("thruster_failure", "9", 1.0, 2.0),
            "no thruster '9' on mss_supply (its ids: 1, 2, 3, 4, 5, 6)",
        ),
    ],
)
def test_a_fault_that_would_bite_nothing_is_named(fault: Fault, says: str) -> None:
    from simulator.scenarios import get_scenario

    problems = get_scenario("torsetnes_2004").fault_problems([fault])
    assert len(problems) == 1 and says in problems[0], problems


def test_faults_that_bite_pass_and_wildcards_and_commands_are_left_alone() -> None:
    from simulator.scenarios import get_scenario

    ok = [
        Fault("jump", "dgps1", 1.0, 2.0, {"north_m": 5.0}),
        Fault("jump", "gyro1", 1.0, 2.0, {"heading_rad": 0.1}),
        Fault("drift", "dgps1", 1.0, 2.0, {"north_mps": 0.1}),
        Fault("dropout", "*", 1.0, 2.0),
        Fault("garbage", "thrusters", 1.0, 2.0),
        Fault("thruster_failure", "3", 1.0, 2.0),
        Fault("command_mode", "station", 1.0, 2.0, {"mode": "dp"}),
    ]
    assert get_scenario("torsetnes_2004").fault_problems(ok) == []


def test_dpgw_sim_refuses_a_fault_file_that_would_bite_nothing(tmp_path: Path) -> None:
    import subprocess
    import sys

    f = tmp_path / "faults.toml"
    f.write_text('[[faults]]\nkind = "jump"\nsource = "gps9"\nt_start = 10.0\nnorth_m = 5.0\n')
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "torsetnes_2004", "--duration", "5", "--faults",
         str(f), "--out", str(tmp_path / "x.mcap")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip().splitlines() == [
        f"dpgw sim: --faults {f}: jump fault on 'gps9' at 10 s: torsetnes_2004 has no source 'gps9' "
        "(its sources: dgps1, gyro1, thrusters)"
    ]
    assert not (tmp_path / "x.mcap").exists()
