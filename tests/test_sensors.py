"""Simulated sensors and faults, checked on the wire with parsers that are not ours: pynmea2 for NMEA and
pymavlink's generated ``MAVLink.parse_buffer`` for MAVLink; positions go back to NED with pymap3d."""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import pynmea2
import pytest

from simulator.clock import SimEpoch
from simulator.faults import Fault, FaultSchedule
from simulator.sensors import (
    Anemometer,
    AnemometerConfig,
    Datum,
    Dgps,
    DgpsConfig,
    Emission,
    Gyro,
    GyroConfig,
    Sensor,
    ShipState,
    ThrusterFeedback,
    ThrusterFeedbackConfig,
    ThrusterReading,
    azimuth_to_pwm,
    pwm_to_azimuth,
)
from wire.codecs import mavlink as mv

REPO = Path(__file__).resolve().parent.parent
EPOCH = SimEpoch(datetime(2024, 6, 1, 12, 0, 0, tzinfo=UTC))
DATUM = Datum(63.44, 10.40, 42.0)
KNOT = 1852.0 / 3600.0
QUIET: dict[str, Any] = {"sigma_m": 0.0, "sigma_velocity_mps": 0.0}  # a noise-free DGPS
QUIET_GYRO: dict[str, Any] = {"sigma_rad": 0.0, "sigma_rot_rad_s": 0.0}

if "THS" not in pynmea2.TalkerSentence.sentence_types:
    # pynmea2 1.19 has no THS; registering a layout is pynmea2's own extension mechanism (as in
    # test_codecs_encode.py). The checksum and field splitting are still pynmea2's.
    class THS(pynmea2.TalkerSentence):
        fields = (("Heading, degrees true", "heading", float), ("Mode indicator", "mode"))


# ---------------------------------------------------------------------------------------------- helpers


def parse(em: Emission) -> Any:
    text = em.data.decode("ascii")
    assert text.startswith("$") and text.endswith("\r\n") and text.count("\r\n") == 1
    return pynmea2.parse(text.strip(), check=True)


def mav_decode(data: bytes) -> list[Any]:
    """pymavlink's own parser (not wire.codecs.mavlink.FrameParser)."""
    msgs = mv.dialect().MAVLink(None).parse_buffer(data)
    return list(msgs or [])


def cruise(t: float) -> ShipState:
    """A vessel moving north-east and turning to starboard, its heading crossing north (0°/360°)."""
    psi = (-0.4 + 0.02 * t + math.pi) % (2 * math.pi) - math.pi
    return ShipState(t, np.array([5.0 + 0.8 * t, -3.0 + 0.3 * t, psi]), np.array([0.7, 0.1, 0.02]))


def run(
    sensor: Dgps | Gyro | ThrusterFeedback | Anemometer,
    state: Callable[[float], ShipState],
    t_end: float,
    wire_seed: int = 99,
) -> list[Emission]:
    """What the runner does: sample at next_time() until t_end (exclusive) and put the wire-side faults on
    the bytes with a generator of its own."""
    wire = np.random.default_rng(wire_seed)
    out: list[Emission] = []
    while sensor.next_time() < t_end:
        out += sensor.faults.apply_to_emissions(sensor.sample(state(sensor.next_time())), wire)
    return out


def dgps(seed: int = 0, faults: Sequence[Fault] = (), **config: Any) -> Dgps:
    return Dgps(DgpsConfig(**config), DATUM, EPOCH, np.random.default_rng(seed), FaultSchedule(faults))


def gyro(seed: int = 0, faults: Sequence[Fault] = (), **config: Any) -> Gyro:
    return Gyro(GyroConfig(**config), EPOCH, np.random.default_rng(seed), FaultSchedule(faults))


def antenna_truth(state: ShipState, lever: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Antenna NED position and velocity, written out independently of simulator.sensors."""
    n, e, psi = state.eta
    u, v, r = state.nu
    R = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
    arm = np.array(lever[:2])
    pos = np.array([n, e]) + R @ arm
    vel = R @ (np.array([u, v]) + r * np.array([-arm[1], arm[0]]))
    return pos, vel


def gga_ned(msgs: list[Any]) -> np.ndarray:
    lat = np.array([m.latitude for m in msgs])
    lon = np.array([m.longitude for m in msgs])
    n, e, _ = pymap3d.geodetic2ned(lat, lon, DATUM.alt_m, DATUM.lat_deg, DATUM.lon_deg, DATUM.alt_m)
    return np.column_stack([n, e])


def of_kind(emissions: list[Emission], kind: str) -> list[Emission]:
    return [em for em in emissions if em.data[3:6] == kind.encode()]


def angle_diff_deg(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


def feedback(seed: int = 0, faults: Sequence[Fault] = (), **config: Any) -> ThrusterFeedback:
    return ThrusterFeedback(
        ThrusterFeedbackConfig(**config), EPOCH, np.random.default_rng(seed), FaultSchedule(faults)
    )


def thrusters(t: float) -> ShipState:
    readings = (
        ThrusterReading(
            1,
            "tunnel",
            2.0e4 * math.sin(t),
            math.pi / 2,
            300.0 * math.sin(t),
            2.1e4,
            math.pi / 2,
            False,
            1.0e5,
        ),
        ThrusterReading(2, "azimuth", 8.0e4, 0.1 * t - 1.0, 180.0, 8.2e4, 0.1 * t - 0.9, False),
        ThrusterReading(3, "azimuth", 5.0e4, -2.0, -150.0, 5.0e4, -2.0, False, 3.0e5),
    )
    return ShipState(t, np.zeros(3), np.zeros(3), readings)


# ---------------------------------------------------------------------------------------------- DGPS


def test_dgps_noise_free_burst_decodes_to_the_antenna_position_and_velocity() -> None:
    lever = (12.0, -4.0, -25.0)
    sensor = dgps(rate_hz=2.0, lever_arm_m=lever, **QUIET)
    emissions = run(sensor, cruise, 30.0)
    kinds = [em.data[3:6].decode() for em in emissions]
    # one realistic burst per fix: position and velocity at 2 Hz, statistics and date once a second
    bursts: dict[float, list[str]] = {}
    for em, kind in zip(emissions, kinds, strict=True):
        bursts.setdefault(em.t_measured, []).append(kind)
    assert len(bursts) == 60
    for t, burst in bursts.items():
        whole = EPOCH.utc(t).microsecond == 0
        assert burst == (["GGA", "RMC", "VTG", "GST", "ZDA"] if whole else ["GGA", "RMC", "VTG"]), t
    every = run(dgps(rate_hz=2.0, slow_rate_hz=2.0, **QUIET), cruise, 5.0)
    assert [em.data[3:6].decode() for em in every] == ["GGA", "RMC", "VTG", "GST", "ZDA"] * 10
    for em in emissions:
        msg = parse(em)
        state = cruise(em.t_measured)
        pos, vel = antenna_truth(state, lever)
        utc = EPOCH.utc(em.t_measured)
        if hasattr(msg, "timestamp"):
            assert msg.timestamp == utc.time().replace(tzinfo=msg.timestamp.tzinfo)
        speed, course = math.hypot(*vel), math.degrees(math.atan2(vel[1], vel[0]))
        if isinstance(msg, pynmea2.GGA):
            assert np.abs(gga_ned([msg])[0] - pos).max() < 0.01
            assert msg.gps_qual == 2 and msg.num_sats == "12" and msg.horizontal_dil == "0.80"
            assert msg.altitude == pytest.approx(20.0 + 25.0, abs=1e-3) and msg.altitude_units == "M"
            assert msg.age_gps_data == "2.0" and msg.ref_station_id == "0001"
        elif isinstance(msg, pynmea2.RMC):
            assert msg.status == "A" and msg.mode_indicator == "D"
            assert msg.datestamp == utc.date()
            assert np.abs(gga_ned([msg])[0] - pos).max() < 0.01
            assert msg.spd_over_grnd * KNOT == pytest.approx(speed, abs=0.0005 * KNOT + 1e-9)
            assert abs(angle_diff_deg(msg.true_course, course)) <= 0.005 + 1e-9
        elif isinstance(msg, pynmea2.VTG):
            assert float(msg.spd_over_grnd_kts) * KNOT == pytest.approx(speed, abs=0.0005 * KNOT + 1e-9)
            assert msg.spd_over_grnd_kmph / 3.6 == pytest.approx(speed, abs=0.0005 / 3.6 + 1e-9)
            assert abs(angle_diff_deg(msg.true_track, course)) <= 0.005 + 1e-9
            assert msg.faa_mode == "D"
        elif isinstance(msg, pynmea2.GST):
            assert msg.std_dev_latitude == msg.std_dev_longitude == msg.rms == 0.0
        else:
            assert isinstance(msg, pynmea2.ZDA)
            assert (msg.day, msg.month, msg.year) == (1, 6, 2024)


def test_dgps_gns_rtk_and_autonomous_fixes() -> None:
    rtk = run(dgps(position_sentence="GNS", extra=("RMC",), quality=4, talker="GN", **QUIET), cruise, 3.0)
    gns, rmc = parse(rtk[0]), parse(rtk[1])
    assert rtk[0].data.startswith(b"$GNGNS,") and gns.mode_indicator == "RR"
    assert gns.num_sats == "12" and gns.age_gps_data == "2.0" and gns.diferential == "0001"
    assert np.abs(gga_ned([gns])[0] - antenna_truth(cruise(0.0), (0.0, 0.0, -20.0))[0]).max() < 0.01
    assert rmc.mode_indicator == "R"
    sps = parse(run(dgps(quality=1, extra=(), **QUIET), cruise, 1.0)[0])
    assert sps.gps_qual == 1 and sps.age_gps_data == "" and sps.ref_station_id == ""


def test_lever_arm_traces_a_circle_when_turning_on_the_spot() -> None:
    r = 2 * math.pi / 60.0  # one turn a minute
    lever = (10.0, 5.0, -20.0)

    def spin(t: float) -> ShipState:
        return ShipState(
            t, np.array([0.0, 0.0, (r * t + math.pi) % (2 * math.pi) - math.pi]), np.array([0, 0, r])
        )

    emissions = run(dgps(rate_hz=5.0, extra=("VTG",), lever_arm_m=lever, **QUIET), spin, 60.0)
    fixes = gga_ned([parse(em) for em in of_kind(emissions, "GGA")])
    radius = math.hypot(10.0, 5.0)
    assert np.abs(np.hypot(fixes[:, 0], fixes[:, 1]) - radius).max() < 0.01
    bearings = np.degrees(np.arctan2(fixes[:, 1], fixes[:, 0]))
    assert np.histogram(bearings, bins=12, range=(-180, 180))[0].min() > 0  # all the way round
    for em, bearing in zip(of_kind(emissions, "VTG"), bearings, strict=True):
        vtg = parse(em)
        assert float(vtg.spd_over_grnd_kts) * KNOT == pytest.approx(r * radius, abs=0.001)
        assert abs(angle_diff_deg(vtg.true_track, bearing + 90.0)) < 0.02  # turning clockwise


def test_rates_latency_and_the_utc_grid() -> None:
    emissions = run(dgps(rate_hz=5.0, latency_s=0.15), cruise, 20.0)
    measured = sorted({em.t_measured for em in emissions})
    assert len(measured) == 100 and len(emissions) == 3 * 100 + 2 * 20  # GST, ZDA once a second
    assert np.allclose(np.diff(measured), 0.2)
    assert all(em.t_emit - em.t_measured == pytest.approx(0.15) for em in emissions)
    assert {em.protocol for em in emissions} == {"nmea"} and {em.source for em in emissions} == {"dgps1"}

    gyro_out = run(gyro(rate_hz=10.0, latency_s=0.02), cruise, 20.0)
    assert len({em.t_measured for em in gyro_out}) == 200 and len(gyro_out) == 400
    assert all(em.t_emit - em.t_measured == pytest.approx(0.02) for em in gyro_out)

    # an epoch that does not start on a whole second: fixes still fall on whole UTC seconds (GPS time)
    epoch = SimEpoch(datetime(2024, 6, 1, 12, 0, 0, 250000, tzinfo=UTC))
    sensor = Dgps(DgpsConfig(rate_hz=2.0), DATUM, epoch, np.random.default_rng(0))
    assert sensor.next_time() == pytest.approx(0.25)
    first = run(sensor, cruise, 1.0)
    assert parse(first[0]).timestamp.microsecond == 500000


def test_sampling_late_skips_and_early_gives_nothing() -> None:
    sensor = dgps(rate_hz=10.0)
    assert sensor.sample(cruise(-0.05)) == []
    assert sensor.next_time() == 0.0
    assert len(sensor.sample(cruise(0.0))) == 5 and sensor.next_time() == pytest.approx(0.1)
    assert len(sensor.sample(cruise(3.33))) == 3  # late: one burst (no GST/ZDA off the second), no catch-up
    assert sensor.next_time() == pytest.approx(3.4)


def positions_and_errors(emissions: list[Emission], lever: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    ggas = of_kind(emissions, "GGA")
    truth = np.array([antenna_truth(cruise(em.t_measured), lever)[0] for em in ggas])
    return np.array([em.t_measured for em in ggas]), gga_ned([parse(em) for em in ggas]) - truth


def lag1(x: np.ndarray) -> float:
    x = x - x.mean()
    return float(np.dot(x[:-1], x[1:]) / np.dot(x, x))


@pytest.mark.parametrize("tau", [0.0, 2.0])
def test_position_noise_has_the_configured_sigma_and_correlation(tau: float) -> None:
    sigma = 0.5
    emissions = run(
        dgps(seed=7, rate_hz=1.0, extra=("GST",), sigma_m=sigma, noise_correlation_s=tau), cruise, 3000.0
    )
    _, err = positions_and_errors(emissions, (0.0, 0.0, -20.0))
    assert len(err) == 3000
    for axis in (0, 1):
        assert np.std(err[:, axis]) == pytest.approx(sigma, rel=0.1)
        assert abs(np.mean(err[:, axis])) < 0.1
        assert lag1(err[:, axis]) == pytest.approx(math.exp(-1.0 / tau) if tau else 0.0, abs=0.07)
    assert np.corrcoef(err[:, 0], err[:, 1])[0, 1] == pytest.approx(0.0, abs=0.07)
    gst = parse(of_kind(emissions, "GST")[0])
    assert gst.std_dev_latitude == gst.std_dev_longitude == sigma


def test_heading_noise_has_the_configured_sigma() -> None:
    sigma = math.radians(0.5)
    emissions = run(gyro(seed=3, rate_hz=20.0, sentences=("THS",), sigma_rad=sigma), cruise, 150.0)
    err = [
        angle_diff_deg(float(parse(em).heading), math.degrees(cruise(em.t_measured).eta[2]))
        for em in emissions
    ]
    assert len(err) == 3000
    assert np.std(err) == pytest.approx(math.degrees(sigma), rel=0.1)


# ---------------------------------------------------------------------------------------------- gyro


def test_gyro_sentences_decode_to_heading_and_rate_of_turn() -> None:
    variation = math.radians(3.0)
    sensor = gyro(sentences=("HDT", "THS", "ROT", "HDG"), variation_rad=variation, **QUIET_GYRO)
    emissions = run(sensor, cruise, 40.0)  # heading goes from -23° through north to +23°
    assert [em.data[3:6] for em in emissions[:4]] == [b"HDT", b"THS", b"ROT", b"HDG"]
    headings = []
    for em in emissions:
        msg, state = parse(em), cruise(em.t_measured)
        truth = math.degrees(state.eta[2])
        assert em.data[1:3] == b"HE"
        if isinstance(msg, pynmea2.HDT):
            assert msg.hdg_true == "T" and 0.0 <= float(msg.heading) < 360.0
            assert abs(angle_diff_deg(float(msg.heading), truth)) <= 0.005 + 1e-9
            headings.append(float(msg.heading))
        elif isinstance(msg, pynmea2.ROT):
            assert msg.status == "A"
            assert float(msg.rate_of_turn) == pytest.approx(math.degrees(state.nu[2]) * 60.0, abs=0.05 + 1e-9)
        elif isinstance(msg, pynmea2.HDG):
            sign = {"E": 1.0, "W": -1.0}
            true = (
                float(msg.heading)
                + sign[msg.dev_dir] * float(msg.deviation)
                + sign[msg.var_dir] * float(msg.variation)
            )
            assert float(msg.variation) == 3.0 and msg.var_dir == "E"
            assert abs(angle_diff_deg(true, truth)) <= 0.1 + 1e-9
        else:
            assert msg.mode == "A" and abs(angle_diff_deg(msg.heading, truth)) <= 0.005 + 1e-9
    assert min(headings) < 1.0 and max(headings) > 359.0  # crossed north without a 360.00


# ---------------------------------------------------------------------------------------------- thrusters


def test_thruster_feedback_frames_decode_with_pymavlink() -> None:
    sensor = feedback(ardupilot_esc=True, ardupilot_servo=True, system_id=7, component_id=33)
    emissions = run(sensor, thrusters, 10.0)
    assert {em.protocol for em in emissions} == {"mavlink"}
    msgs = [mav_decode(em.data) for em in emissions]
    assert all(len(m) == 1 for m in msgs)  # one frame per emission
    msgs_flat = [m[0] for m in msgs]
    stream = mav_decode(b"".join(em.data for em in emissions))  # the frames back to back, as on a wire
    assert [m.get_msgbuf() for m in stream] == [em.data for em in emissions]
    seqs = [m.get_seq() for m in msgs_flat]
    assert seqs == [i % 256 for i in range(len(seqs))]  # one encoder: a real link's sequence
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in msgs_flat} == {(7, 33)}
    types = [m.get_type() for m in msgs_flat]
    assert types.count("HEARTBEAT") == 10
    assert types.count("AZIMUTH_THRUSTER_STATUS") == 3 * 50
    assert types.count("ESC_TELEMETRY_1_TO_4") == 50 and types.count("SERVO_OUTPUT_RAW") == 50
    d = mv.dialect()
    flags_ok = (
        mv.AzimuthThrusterFlags.READY
        | mv.AzimuthThrusterFlags.RUNNING
        | mv.AzimuthThrusterFlags.REMOTE_CONTROL
    )
    esc_counts = []
    for em, msg in zip(emissions, msgs_flat, strict=True):
        state = thrusters(em.t_measured)
        if msg.get_type() == "HEARTBEAT":
            assert msg.type == d.MAV_TYPE_SURFACE_BOAT and msg.autopilot == d.MAV_AUTOPILOT_ARDUPILOTMEGA
        elif msg.get_type() == "AZIMUTH_THRUSTER_STATUS":
            truth = next(r for r in state.thrusters if r.id == msg.id)
            assert msg.time_usec == EPOCH.stamp_ns(em.t_measured) // 1000
            assert msg.thrust == pytest.approx(truth.thrust_n, rel=1e-6)
            assert msg.rpm == pytest.approx(truth.rpm, rel=1e-6)
            assert angle_diff_deg(
                math.degrees(msg.azimuth), math.degrees(truth.azimuth_rad)
            ) == pytest.approx(0, abs=1e-4)
            assert msg.thrust_setpoint == pytest.approx(truth.thrust_setpoint_n, rel=1e-6)
            assert msg.flags == flags_ok and msg.fault_code == 0
            if math.isnan(truth.power_w):
                assert math.isnan(msg.power)
            else:
                assert msg.power == pytest.approx(truth.power_w, rel=1e-6)
        elif msg.get_type() == "ESC_TELEMETRY_1_TO_4":
            assert msg.rpm[:3] == [round(abs(r.rpm)) for r in state.thrusters] and msg.rpm[3] == 0
            esc_counts.append(msg.count[0])
        else:
            pwm = [msg.servo1_raw, msg.servo2_raw, msg.servo3_raw]
            assert pwm == [azimuth_to_pwm(r.azimuth_rad) for r in state.thrusters] and msg.servo4_raw == 0
            for value, r in zip(pwm, state.thrusters, strict=True):
                assert (
                    abs(angle_diff_deg(math.degrees(pwm_to_azimuth(value)), math.degrees(r.azimuth_rad)))
                    < 0.5
                )
            assert msg.time_usec == round(em.t_measured * 1e6)
    assert esc_counts == list(range(1, 51))


def test_azimuth_pwm_mapping() -> None:
    assert [azimuth_to_pwm(a) for a in (0.0, math.pi / 2, -math.pi / 2, -math.pi, math.pi)] == [
        1500,
        1700,
        1300,
        1100,
        1100,
    ]
    assert pwm_to_azimuth(1700) == pytest.approx(math.pi / 2)


def test_thruster_feedback_heartbeat_only_instants_and_no_heartbeat() -> None:
    sensor = feedback(rate_hz=2.0, heartbeat_hz=1.0)
    types = [mav_decode(em.data)[0].get_type() for em in run(sensor, thrusters, 4.0)]
    assert types.count("HEARTBEAT") == 4 and types.count("AZIMUTH_THRUSTER_STATUS") == 3 * 8
    assert types[:4] == ["HEARTBEAT", *["AZIMUTH_THRUSTER_STATUS"] * 3]  # heartbeat first in an instant
    silent = [mav_decode(em.data)[0].get_type() for em in run(feedback(heartbeat_hz=0.0), thrusters, 4.0)]
    assert "HEARTBEAT" not in silent and mv.dialect().MAV_AUTOPILOT_INVALID == 8


# ---------------------------------------------------------------------------------------------- faults


def test_dropout_silences_the_source_in_the_window() -> None:
    faults = [Fault("dropout", "dgps1", 10.0, 20.0), Fault("dropout", "*", 30.0, 35.0)]
    out = run(dgps(faults=faults), cruise, 40.0)
    times = sorted({em.t_measured for em in out})
    assert times == [t for t in range(40) if not (10 <= t < 20 or 30 <= t < 35)]
    g = run(gyro(faults=faults, rate_hz=1.0), cruise, 40.0)
    assert {em.t_measured for em in g} == {float(t) for t in range(40) if not 30 <= t < 35}
    th = run(feedback(faults=[Fault("dropout", "thrusters", 2.0, 3.0)]), thrusters, 4.0)
    assert (
        not [em for em in th if 2.0 <= em.t_measured < 3.0] and len(th) == 3 * 15 + 3
    )  # status + heartbeats at 0, 1, 3 s


def test_frozen_repeats_the_value_measured_at_the_start_while_time_moves_on() -> None:
    lever = (3.0, 1.0, -20.0)
    faults = [Fault("frozen", "dgps1", 10.0, 20.0)]
    out = run(dgps(faults=faults, lever_arm_m=lever, **QUIET), cruise, 25.0)
    ggas = [parse(em) for em in of_kind(out, "GGA")]
    inside = [g for g, em in zip(ggas, of_kind(out, "GGA"), strict=True) if 10 <= em.t_measured < 20]
    assert len(inside) == 10 and len({(g.lat, g.lon, g.altitude) for g in inside}) == 1
    assert len({g.timestamp for g in inside}) == 10  # sentences keep flowing with fresh times
    assert np.abs(gga_ned(inside[:1])[0] - antenna_truth(cruise(10.0), lever)[0]).max() < 0.01
    after = ggas[20:]
    assert np.abs(gga_ned(after) - [antenna_truth(cruise(t), lever)[0] for t in range(20, 25)]).max() < 0.01
    speeds = {parse(em).spd_over_grnd for em in of_kind(out, "RMC") if 10 <= em.t_measured < 20}
    assert len(speeds) == 1

    g = run(gyro(faults=[Fault("frozen", "*", 1.0, 2.0)], sentences=("HDT",)), cruise, 3.0)
    frozen = {em.data for em in g if 1.0 <= em.t_measured < 2.0}
    assert len(frozen) == 1 and len({em.data for em in g}) > 10

    th = run(feedback(faults=[Fault("frozen", "thrusters", 1.0, 3.0)]), thrusters, 4.0)
    tunnel = [(em.t_measured, mav_decode(em.data)[0]) for em in th]
    tunnel = [(t, m) for t, m in tunnel if m.get_type() == "AZIMUTH_THRUSTER_STATUS" and m.id == 1]
    inside_th = [m for t, m in tunnel if 1.0 <= t < 3.0]
    assert len({m.thrust for m in inside_th}) == 1 and len({m.time_usec for m in inside_th}) == 10
    assert len({m.thrust for t, m in tunnel if t >= 3.0}) == 5


def test_jump_offsets_the_reported_position_and_heading() -> None:
    faults = [Fault("jump", "dgps1", 10.0, 20.0, {"north_m": 5.0, "east_m": -3.0})]
    times, err = positions_and_errors(run(dgps(faults=faults, **QUIET), cruise, 30.0), (0.0, 0.0, -20.0))
    inside = (times >= 10) & (times < 20)
    assert np.abs(err[inside] - [5.0, -3.0]).max() < 0.01
    assert np.abs(err[~inside]).max() < 0.01

    g = run(gyro(faults=[Fault("jump", "gyro1", 1.0, 2.0, {"heading_rad": 0.1})], **QUIET_GYRO), cruise, 3.0)
    for em in of_kind(g, "HDT"):
        jump = 5.7296 if 1.0 <= em.t_measured < 2.0 else 0.0
        got = angle_diff_deg(float(parse(em).heading), math.degrees(cruise(em.t_measured).eta[2]))
        assert got == pytest.approx(jump, abs=0.006)


def test_noise_burst_adds_noise_in_the_window_only() -> None:
    faults = [Fault("noise_burst", "dgps1", 500.0, 1500.0, {"sigma_m": 3.0})]
    times, err = positions_and_errors(
        run(dgps(seed=5, faults=faults, extra=(), sigma_m=0.1), cruise, 2000.0), (0.0, 0.0, -20.0)
    )
    inside = (times >= 500) & (times < 1500)
    assert np.std(err[inside]) == pytest.approx(math.hypot(3.0, 0.1), rel=0.1)
    assert np.std(err[~inside]) == pytest.approx(0.1, rel=0.1)

    burst = [Fault("noise_burst", "gyro1", 0.0, 100.0, {"sigma_rad": math.radians(2.0)})]
    g = run(gyro(seed=5, faults=burst, sentences=("HDT",), sigma_rad=0.0), cruise, 100.0)
    err_deg = [
        angle_diff_deg(float(parse(em).heading), math.degrees(cruise(em.t_measured).eta[2])) for em in g
    ]
    assert np.std(err_deg) == pytest.approx(2.0, rel=0.1)


def test_bad_checksum_fails_the_independent_checks() -> None:
    faults = [
        Fault("bad_checksum", "*", 10.0, 20.0),
        Fault("bad_checksum", "*", 30.0, 40.0, {"probability": 0.5}),
    ]
    out = run(dgps(faults=faults), cruise, 40.0)
    bad = 0
    for em in out:
        text = em.data.decode("ascii").strip()
        if 10.0 <= em.t_emit < 20.0:
            with pytest.raises(pynmea2.ChecksumError):
                pynmea2.parse(text, check=True)
        elif em.t_emit < 30.0:
            pynmea2.parse(text, check=True)
        else:
            try:
                pynmea2.parse(text, check=True)
            except pynmea2.ChecksumError:
                bad += 1
    assert 10 <= bad <= 40  # 50 sentences at p = 0.5

    th = run(feedback(faults=[Fault("bad_checksum", "thrusters", 1.0, 2.0)]), thrusters, 3.0)
    corrupted = 0
    for em in th:
        rx = mv.dialect().MAVLink(None)
        rx.robust_parsing = True  # report a bad frame as BAD_DATA instead of raising
        types = [m.get_type() for m in rx.parse_buffer(em.data) or []]
        assert len(types) == 1
        if 1.0 <= em.t_emit < 2.0:
            assert types == ["BAD_DATA"]
            corrupted += 1
        else:
            assert types[0] in {"HEARTBEAT", "AZIMUTH_THRUSTER_STATUS"}
    assert corrupted == 3 * 5 + 1


def is_valid_sentence(line: bytes) -> bool:
    try:
        pynmea2.parse(line.decode("ascii"), check=True)
    except (pynmea2.ParseError, pynmea2.ChecksumError, UnicodeDecodeError, ValueError, AttributeError):
        return False
    return True


def test_garbage_inserts_junk_that_is_never_a_valid_sentence_or_frame() -> None:
    faults = [Fault("garbage", "dgps1", 0.0, 200.0, {"probability": 0.5, "max_bytes": 60})]
    clean = run(dgps(seed=1), cruise, 200.0)
    dirty = run(dgps(seed=1, faults=faults), cruise, 200.0)  # line noise leaves the sensor's noise alone
    good = {em.data for em in clean}
    junk = [em for em in dirty if em.data not in good]
    assert [em for em in dirty if em.data in good] == clean  # every good sentence intact, in order
    assert 350 <= len(junk) <= 650  # 1000 sentences at p = 0.5
    for em in junk:
        assert 1 <= len(em.data) <= 60 and em.t_measured == em.t_emit and em.source == "dgps1"
        assert not any(is_valid_sentence(line) for line in re.split(rb"[\r\n$]", em.data) if line)
        assert not any(is_valid_sentence(b"$" + line) for line in re.split(rb"[\r\n$]", em.data) if line)
    blobs = b"".join(em.data for em in junk)
    assert b"$" in blobs and b"\r\n" in blobs and any(b > 127 for b in blobs)
    assert any(em.data.startswith(b"$GP") for em in junk)  # partial sentences

    th_faults = [Fault("garbage", "thrusters", 0.0, 10.0, {"max_bytes": 30})]
    th_clean = run(feedback(), thrusters, 10.0)
    th_dirty = run(feedback(faults=th_faults), thrusters, 10.0)
    frames = {em.data for em in th_clean}
    assert [em for em in th_dirty if em.data in frames] == th_clean
    th_junk = [em for em in th_dirty if em.data not in frames]
    assert len(th_junk) == len(th_clean)  # probability 1 by default
    assert not any(mv.parse_frames(em.data) for em in th_junk)
    assert any(em.data[:1] == b"\xfd" for em in th_junk)  # truncated frames among the junk


def test_sensors_leave_wire_faults_to_the_schedule() -> None:
    wire_faults = [Fault("bad_checksum", "*", 0.0), Fault("garbage", "*", 0.0)]
    for make in (dgps, gyro, feedback):
        plain, faulty = make(seed=4), make(seed=4, faults=wire_faults)
        state = ShipState(0.0, cruise(0.0).eta, cruise(0.0).nu, thrusters(0.0).thrusters)
        sampled = faulty.sample(state)
        assert sampled == plain.sample(state)
        on_wire = faulty.faults.apply_to_emissions(sampled, np.random.default_rng(0))
        assert len(on_wire) == 2 * len(sampled) and not set(on_wire) & set(sampled)


def test_thruster_failure_is_reported_as_fault() -> None:
    schedule = FaultSchedule([Fault("thruster_failure", "2", 1.0, 2.0)])
    assert schedule.active("thruster_failure", "2", 1.5) is not None
    assert schedule.active("thruster_failure", "2", 2.0) is None
    assert schedule.active("thruster_failure", "1", 1.5) is None
    sensor = ThrusterFeedback(ThrusterFeedbackConfig(), EPOCH, np.random.default_rng(0), schedule)
    for em in run(sensor, thrusters, 3.0):
        msg = mav_decode(em.data)[0]
        if msg.get_type() != "AZIMUTH_THRUSTER_STATUS":
            continue
        failed = msg.id == 2 and 1.0 <= em.t_measured < 2.0
        flags = mv.AzimuthThrusterFlags(msg.flags)
        assert bool(flags & mv.AzimuthThrusterFlags.FAULT) == failed
        assert bool(flags & mv.AzimuthThrusterFlags.RUNNING) == (not failed)
        assert msg.fault_code == (1 if failed else 0)
    # the thruster model's own failed flag is reported as well
    state = thrusters(0.0)
    failed_state = ShipState(0.0, state.eta, state.nu, (ThrusterReading(4, "main", 0, 0, 0, 1e4, 0, True),))
    msg = mav_decode(feedback(heartbeat_hz=0.0).sample(failed_state)[0].data)[0]
    assert msg.flags & mv.AzimuthThrusterFlags.FAULT and not msg.flags & mv.AzimuthThrusterFlags.READY


def test_fault_schedule_lookup() -> None:
    a = Fault("dropout", "*", 0.0, 1.0)
    b = Fault("dropout", "gyro1", 5.0)
    schedule = FaultSchedule([a, b])
    assert schedule.active("dropout", "dgps1", 0.5) is a
    assert schedule.active("dropout", "dgps1", 1.0) is None
    assert schedule.active("dropout", "gyro1", 1e9) is b
    assert schedule.active("frozen", "gyro1", 6.0) is None and len(schedule) == 2
    with pytest.raises(ValueError, match="unknown fault kind"):
        schedule.active("dropot", "gyro1", 0.0)
    assert Fault("bad_checksum", "x", 0.0).params["probability"] == 1.0
    assert dict(Fault("garbage", "x", 0.0).params) == {"probability": 1.0, "max_bytes": 40.0}


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ({"kind": "dropot", "source": "a", "t_start": 0}, r"faults\[0\]\.kind: unknown fault kind 'dropot'"),
        ({"source": "a", "t_start": 0}, r"faults\[0\]\.kind: missing"),
        ({"kind": "dropout", "t_start": 0}, r"faults\[0\]\.source: missing"),
        ({"kind": "dropout", "source": "a"}, r"faults\[0\]\.t_start: missing"),
        ({"kind": "dropout", "source": "", "t_start": 0}, r"faults\[0\]\.source: must be a non-empty"),
        ({"kind": "dropout", "source": "a", "t_start": "10"}, r"faults\[0\]\.t_start: must be a number"),
        (
            {"kind": "dropout", "source": "a", "t_start": 20, "t_end": 10},
            r"faults\[0\]\.t_end: must be later",
        ),
        ({"kind": "jump", "source": "a", "t_start": 0}, r"faults\[0\]\.params: a jump fault needs"),
        ({"kind": "jump", "source": "a", "t_start": 0, "north": 1}, r"faults\[0\]\.north: not a parameter"),
        (
            {"kind": "jump", "source": "a", "t_start": 0, "north_m": "x"},
            r"faults\[0\]\.north_m: must be a number",
        ),
        (
            {"kind": "noise_burst", "source": "a", "t_start": 0, "sigma_m": -1},
            r"faults\[0\]\.sigma_m: must be >= 0",
        ),
        (
            {"kind": "garbage", "source": "a", "t_start": 0, "probability": 2},
            r"faults\[0\]\.probability: must be",
        ),
        (
            {"kind": "garbage", "source": "a", "t_start": 0, "max_bytes": 0.5},
            r"faults\[0\]\.max_bytes: must be",
        ),
        (
            {"kind": "dropout", "source": "a", "t_start": 0, "params": {"x": 1}},
            r"faults\[0\]\.x: not a parameter",
        ),
        (
            {"kind": "jump", "source": "a", "t_start": 0, "north_m": 1, "params": {"north_m": 2}},
            r"faults\[0\]\.north_m: given both",
        ),
    ],
)
def test_fault_tables_are_validated_with_the_field_named(item: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        FaultSchedule.from_dicts([item])


def test_fault_tables_from_toml_and_the_documented_example() -> None:
    schedule = FaultSchedule.from_dicts(
        [
            {"kind": "dropout", "source": "dgps1", "t_start": 1, "t_end": 2},
            {"kind": "thruster_failure", "source": 3, "t_start": 5},
            {"kind": "noise_burst", "source": "gyro1", "t_start": 0, "params": {"sigma_rad": 0.01}},
        ]
    )
    assert schedule.active("thruster_failure", "3", 100.0) is not None
    assert schedule.faults[2].params["sigma_rad"] == 0.01 and schedule.faults[1].t_end == math.inf
    doc = (REPO / "docs" / "sensors.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", doc, re.S)
    tables = [tomllib.loads(b) for b in blocks if "[[faults]]" in b]
    assert tables
    for table in tables:
        documented = FaultSchedule.from_dicts(table["faults"])
        assert {f.kind for f in documented.faults} >= {"dropout", "jump", "bad_checksum", "garbage"}


# ---------------------------------------------------------------------------------------------- determinism


def everything(seed: int) -> bytes:
    faults = [
        Fault("noise_burst", "dgps1", 5.0, 10.0, {"sigma_m": 2.0}),
        Fault("garbage", "*", 0.0, 30.0, {"probability": 0.3}),
        Fault("bad_checksum", "*", 0.0, 30.0, {"probability": 0.2}),
    ]
    rng = np.random.SeedSequence(seed).spawn(3)
    sensors: list[Dgps | Gyro | ThrusterFeedback] = [
        Dgps(
            DgpsConfig(noise_correlation_s=3.0),
            DATUM,
            EPOCH,
            np.random.default_rng(rng[0]),
            FaultSchedule(faults),
        ),
        Gyro(GyroConfig(), EPOCH, np.random.default_rng(rng[1]), FaultSchedule(faults)),
        ThrusterFeedback(
            ThrusterFeedbackConfig(ardupilot_esc=True),
            EPOCH,
            np.random.default_rng(rng[2]),
            FaultSchedule(faults),
        ),
    ]
    out: list[Emission] = []
    for sensor in sensors:
        out += run(
            sensor, lambda t: ShipState(t, cruise(t).eta, cruise(t).nu, thrusters(t).thrusters), 30.0, seed
        )
    out.sort(key=lambda em: em.t_emit)
    return b"".join(em.data for em in out)


def test_same_seed_same_bytes_other_seed_other_bytes() -> None:
    first = everything(42)
    assert first == everything(42)
    assert first != everything(43)


# ---------------------------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: DgpsConfig(rate_hz=20.0), r"DgpsConfig\.rate_hz: must be in 1\.\.10 Hz, got 20\.0"),
        (lambda: DgpsConfig(rate_hz=0.5), r"DgpsConfig\.rate_hz"),
        (lambda: DgpsConfig(rate_hz=math.nan), r"DgpsConfig\.rate_hz"),
        (lambda: DgpsConfig(position_sentence="RMC"), r"DgpsConfig\.position_sentence"),
        (lambda: DgpsConfig(extra=("RMC", "GSV")), r"DgpsConfig\.extra: must be some of"),
        (lambda: DgpsConfig(extra=("RMC", "RMC")), r"DgpsConfig\.extra: repeats"),
        (lambda: DgpsConfig(extra=("GGA",)), r"DgpsConfig\.extra: repeats"),
        (lambda: DgpsConfig(quality=3), r"DgpsConfig\.quality: must be one of \[1, 2, 4, 5\]"),
        (lambda: DgpsConfig(sigma_m=-0.1), r"DgpsConfig\.sigma_m"),
        (lambda: DgpsConfig(sigma_m=math.inf), r"DgpsConfig\.sigma_m"),
        (lambda: DgpsConfig(lever_arm_m=(1.0, 2.0)), r"DgpsConfig\.lever_arm_m"),  # type: ignore[arg-type]
        (lambda: DgpsConfig(talker="gp"), r"DgpsConfig\.talker"),
        (lambda: DgpsConfig(source=""), r"DgpsConfig\.source"),
        (lambda: DgpsConfig(n_sats=3), r"DgpsConfig\.n_sats"),
        (lambda: DgpsConfig(station_id=1024), r"DgpsConfig\.station_id"),
        (lambda: DgpsConfig(latency_s=-0.1), r"DgpsConfig\.latency_s"),
        (lambda: DgpsConfig(noise_correlation_s=-1.0), r"DgpsConfig\.noise_correlation_s"),
        (lambda: GyroConfig(rate_hz=25.0), r"GyroConfig\.rate_hz: must be in \(0, 20\] Hz"),
        (lambda: GyroConfig(sentences=("HDT", "HDM")), r"GyroConfig\.sentences"),
        (lambda: GyroConfig(sentences=()), r"GyroConfig\.sentences"),
        (lambda: GyroConfig(sigma_rad=-1.0), r"GyroConfig\.sigma_rad"),
        (lambda: ThrusterFeedbackConfig(rate_hz=0.0), r"ThrusterFeedbackConfig\.rate_hz"),
        (lambda: ThrusterFeedbackConfig(system_id=0), r"ThrusterFeedbackConfig\.system_id"),
        (lambda: ThrusterFeedbackConfig(heartbeat_hz=-1.0), r"ThrusterFeedbackConfig\.heartbeat_hz"),
        (lambda: Datum(95.0, 0.0), r"Datum\.lat_deg"),
        (lambda: ShipState(0.0, np.zeros(2), np.zeros(3)), r"ShipState\.eta"),
        (lambda: ThrusterReading(1, "bow", 0, 0, 0, 0, 0, False), r"ThrusterReading\.kind"),
        (lambda: ThrusterReading(300, "main", 0, 0, 0, 0, 0, False), r"ThrusterReading\.id"),
    ],
)
def test_config_errors_name_the_field(make: Callable[[], object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_datum_is_vectorised_and_inverts() -> None:
    north, east = np.array([0.0, 100.0, -2500.0]), np.array([0.0, -40.0, 3000.0])
    lat, lon, alt = DATUM.to_geodetic(north, east)
    assert (
        lat.shape == (3,) and lat[0] == pytest.approx(DATUM.lat_deg) and alt[0] == pytest.approx(DATUM.alt_m)
    )
    n, e, _ = DATUM.to_ned(lat, lon, alt)
    assert np.allclose(n, north, atol=1e-6) and np.allclose(e, east, atol=1e-6)
    scalar = DATUM.to_geodetic(10.0, 20.0)
    assert all(isinstance(x, float) for x in scalar)


def test_sensors_satisfy_the_runner_protocol() -> None:
    for sensor in (dgps(), gyro(), feedback()):
        assert isinstance(sensor, Sensor) and sensor.next_time() == 0.0
    assert dgps().source == "dgps1" and gyro().source == "gyro1" and feedback().source == "thrusters"


def test_the_simulators_unchecked_constructors_make_the_same_objects() -> None:
    """`ShipState.trusted` and `ThrusterReading.trusted` (the runner's, without the checks) give what the
    checked constructors give for valid input."""
    values = (3, "azimuth", 1.5e4, -0.3, 120.0, 2e4, -0.2, False, 5e3)
    assert ThrusterReading.trusted(*values) == ThrusterReading(*values)
    eta, nu = np.array([1.0, 2.0, 0.5]), np.array([0.1, 0.0, 0.01])
    reading = ThrusterReading(*values)
    made, checked = ShipState.trusted(4.0, eta, nu, (reading,)), ShipState(4.0, eta, nu, (reading,))
    assert made.t == checked.t and made.thrusters == checked.thrusters
    assert np.array_equal(made.eta, checked.eta) and np.array_equal(made.nu, checked.nu)
    for args in ((1.5, "dgps1", "nmea", b"$GPZDA*00\r\n", 1.4), (2.0, "thrusters", "mavlink", b"", 2.0, ())):
        fast, slow = Emission.trusted(*args), Emission(*args)
        assert fast == slow and vars(fast) == vars(slow) and hash(fast) == hash(slow)


# ---------------------------------------------------------------------------------------------- anemometer


def apparent_wind_truth(speed: float, from_deg: float, state: ShipState) -> tuple[float, float]:
    """(speed, angle from the bow in degrees [0, 360)) of the wind felt on board, written out from the
    vectors: air velocity over ground minus the ship's velocity over ground, seen from the bow."""
    to = math.radians(from_deg) + math.pi
    air_ne = speed * np.array([math.cos(to), math.sin(to)])
    psi = float(state.eta[2])
    R = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
    ship_ne = R @ state.nu[:2]
    rel_body = R.T @ (air_ne - ship_ne)  # the air's velocity relative to the ship, body frame
    # the wind comes from the opposite of where the air goes
    return float(np.hypot(*rel_body)), math.degrees(math.atan2(-rel_body[1], -rel_body[0])) % 360.0


def anemometer(seed: int = 0, faults: Sequence[Fault] = (), wind: tuple[float, float] = (15.0, 85.0),
               **config: Any) -> Anemometer:  # fmt: skip
    return Anemometer(
        AnemometerConfig(**config), lambda t: wind, np.random.default_rng(seed), FaultSchedule(faults)
    )


def test_anemometer_reads_the_apparent_wind_in_mwv() -> None:
    sensor = anemometer(sigma_speed_mps=0.0, sigma_angle_rad=0.0, rate_hz=4.0)
    emissions = run(sensor, cruise, 30.0)
    assert len(emissions) == 120  # 4 Hz
    for em in emissions:
        msg = parse(em)
        assert isinstance(msg, pynmea2.MWV) and em.data[1:3] == b"WI"
        assert msg.reference == "R" and msg.wind_speed_units == "M" and msg.status == "A"
        speed, angle = apparent_wind_truth(15.0, 85.0, cruise(em.t_measured))
        assert float(msg.wind_speed) == pytest.approx(speed, abs=0.05 + 1e-9)
        assert abs(angle_diff_deg(float(msg.wind_angle), angle)) <= 0.05 + 1e-9
        assert em.t_emit == pytest.approx(em.t_measured + 0.05)


def test_anemometer_ship_moving_in_still_air_feels_a_head_wind() -> None:
    def ahead(t: float) -> ShipState:
        return ShipState(t, np.array([0.0, 0.0, 1.0]), np.array([5.0, 0.0, 0.0]))

    msg = parse(run(anemometer(wind=(0.0, 0.0), sigma_speed_mps=0.0, sigma_angle_rad=0.0), ahead, 1.0)[0])
    assert float(msg.wind_speed) == pytest.approx(5.0) and float(msg.wind_angle) in (0.0, 360.0)


def test_anemometer_noise_has_the_configured_spread() -> None:
    def still(t: float) -> ShipState:
        return ShipState(t, np.array([0.0, 0.0, 0.3]), np.zeros(3))

    sensor = anemometer(seed=4, rate_hz=10.0, unit="N")
    speeds, angles = [], []
    for em in run(sensor, still, 400.0):
        msg = parse(em)
        assert msg.wind_speed_units == "N"
        speeds.append(float(msg.wind_speed) * KNOT)
        angles.append(float(msg.wind_angle))
    speed, angle = apparent_wind_truth(15.0, 85.0, still(0.0))
    assert np.mean(speeds) == pytest.approx(speed, abs=0.03)
    assert np.std(speeds) == pytest.approx(0.3, rel=0.1)
    diffs = [angle_diff_deg(a, angle) for a in angles]
    assert abs(np.mean(diffs)) < 0.2 and np.std(diffs) == pytest.approx(2.0, rel=0.1)


def test_anemometer_dropout_and_bad_config() -> None:
    sensor = anemometer(faults=[Fault("dropout", "wind1", 10.0, 20.0)])
    times = [em.t_measured for em in run(sensor, cruise, 30.0)]
    assert times and not any(10.0 <= t < 20.0 for t in times)
    with pytest.raises(ValueError, match=r"AnemometerConfig.rate_hz"):
        AnemometerConfig(rate_hz=0.0)
    with pytest.raises(ValueError, match=r"AnemometerConfig.unit"):
        AnemometerConfig(unit="F")


def test_scenarios_with_wind_have_an_anemometer_that_sees_the_plant_wind() -> None:
    from observers.hull import relative_wind
    from simulator.runner import Simulation
    from simulator.scenarios import get_scenario

    scenario = get_scenario("mss_supply_storm")
    assert [a.source for a in scenario.anemometers] == ["wind1"]
    assert get_scenario("torsetnes_2004").anemometers == ()
    got: list[Emission] = []
    sim = Simulation(scenario, 3, wire=False, on_emit=got.append)
    sim.run(20.0)
    mwv = [e for e in got if e.source == "wind1"]
    assert len(mwv) == pytest.approx(40, abs=1)
    env = sim.plant_env
    assert env is not None and env.wind is not None
    gusty = [env.wind.speed(e.t_measured) for e in mwv]
    assert max(gusty) - min(gusty) > 0.5  # the plant's gusts reach the reading
    errors = []
    for e in mwv:
        rec = e.record
        assert rec.valid and rec.reference == "R"
        # the vessel barely moves in 20 s of station keeping: its velocity changes the wind by < 0.5 m/s
        u, v = relative_wind(
            env.wind.speed(e.t_measured), env.wind.model.from_deg, scenario.eta0[2], 0.0, 0.0
        )
        errors.append(rec.speed_mps - math.hypot(u, v))
    assert abs(np.mean(errors)) < 0.5 and np.std(errors) < 0.6
