"""The pipeline's fusion rules: lever arms, failover, staleness, MAVLink sources and signing."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from gateway.bus import isolated_config, open_session
from gateway.commands import tau_capacity
from gateway.config import parse_config
from gateway.pipeline import ControlEvent, Pipeline, PipelineSpec, RawEvent
from wire.codecs import mavlink as mv
from wire.codecs import nmea_encode as enc
from wire.geodesy import LocalFrame

S = 1_000_000_000
T0 = 1_780_000_000 * S
DATUM = (59.4, 10.5)
KEY = bytes(range(32))


ALL_INPUTS = {"accept": ["mode", "setpoint", "tau"]}


def pipeline(
    sources: list[dict], vessel: str = "mss_supply", commands: dict = ALL_INPUTS, **more: dict
) -> Pipeline:  # type: ignore[type-arg]
    # The fixes here are noiseless and repeat for seconds, which the freeze test would rightly call frozen;
    # these tests are about the fusion rules, so the freeze test waits longer than any of them runs.
    more.setdefault("integrity", {})
    more["integrity"] = {"freeze_s": 600.0, "heading_freeze_s": 600.0, **more["integrity"]}
    tables = {
        **more,
        "vessel": {"name": vessel},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": sources,
        "observer": {"wave_period_s": 8.0},
        "log": {"path": ""},
        "commands": commands,
    }
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


def nmea_src(name: str, roles: list[str], **kw) -> dict:  # type: ignore[no-untyped-def, type-arg]
    return {"name": name, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": roles, **kw}


def gga_at(north: float, east: float) -> bytes:
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(north, east, 0.0)
    return enc.gga("GP", datetime(2026, 6, 1, tzinfo=UTC), lat, lon, 2, 12, 0.8, 20.0).encode()


def test_lever_arm_is_compensated_with_the_heading_of_the_same_cycle() -> None:
    """Antenna 30 m forward and 5 m to starboard, heading east: the reference point is where the antenna
    is minus J(ψ)·lever arm."""
    p = pipeline(
        [nmea_src("gps", ["position"], lever_arm_m=[30.0, 5.0, -20.0]), nmea_src("gyro", ["heading"])]
    )
    psi = math.radians(90.0)
    antenna = np.array([100.0, 50.0]) + np.array(
        [math.cos(psi) * 30 - math.sin(psi) * 5, math.sin(psi) * 30 + math.cos(psi) * 5]
    )
    out = []
    for k in range(5):
        t = T0 + k * S // 10
        out += p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
        out += p.feed(RawEvent(t + 1000, "gps", gga_at(*antenna)))
    meas = [o.payload for o in out if o.topic == "/dp/measurement"][-1]
    np.testing.assert_allclose(meas["eta"][:2], [100.0, 50.0], atol=0.005)  # GGA prints 1e-6 minute (2 mm)
    est = [o.payload for o in out if o.topic == "/dp/estimate"][-1]
    np.testing.assert_allclose(est["eta"][:2], [100.0, 50.0], atol=0.05)
    assert est["lat_deg"] == pytest.approx(LocalFrame(*DATUM).to_geodetic(100.0, 50.0)[0], abs=1e-6)


def test_fix_without_heading_of_its_cycle_is_not_used() -> None:
    p = pipeline([nmea_src("gps", ["position"], lever_arm_m=[30.0, 0.0, 0.0]), nmea_src("gyro", ["heading"])])
    out = p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0)))
    assert not out  # no heading yet: the lever arm cannot be compensated
    assert p.counters["gps"].received == 1


def test_failover_to_the_backup_and_back() -> None:
    """With ``pooling = "priority"`` the backup is hot standby (by default references are pooled)."""
    p = pipeline(
        [
            nmea_src("gps1", ["position"], priority=1, timeout_s=1.0),
            nmea_src("gps2", ["position"], priority=2, timeout_s=1.0),
            nmea_src("gyro", ["heading"]),
        ],
        integrity={"pooling": "priority"},
    )

    def cycle(t: int, with1: bool) -> list:  # type: ignore[type-arg]
        out = p.feed(RawEvent(t, "gyro", enc.hdt("HE", 0.0).encode()))
        if with1:
            out += p.feed(RawEvent(t + 1, "gps1", gga_at(10.0, 0.0)))
        out += p.feed(RawEvent(t + 2, "gps2", gga_at(12.0, 0.0)))
        return out

    for k in range(10):
        cycle(T0 + k * S // 2, True)
    assert p.fusion.north.source == "gps1" and p.fusion.north.value == pytest.approx(10.0, abs=0.01)
    out = []
    for k in range(10, 20):  # gps1 silent: after its 1 s timeout gps2 takes over
        out += cycle(T0 + k * S // 2, False)
    assert p.fusion.north.source == "gps2"
    statuses = [o.payload["status"] for o in out if o.topic == "/dp/estimate"]
    assert statuses[-1] == "degraded"
    for k in range(20, 24):
        cycle(T0 + k * S // 2, True)
    assert p.fusion.north.source == "gps1"


def test_silent_source_is_stale_and_estimate_dead_reckons() -> None:
    p = pipeline([nmea_src("gps", ["position"], timeout_s=1.0), nmea_src("gyro", ["heading"], timeout_s=1.0)])
    for k in range(20):
        t = T0 + k * S // 5
        p.feed(RawEvent(t, "gyro", enc.hdt("HE", 0.2).encode()))
        p.feed(RawEvent(t + 1, "gps", gga_at(0.0, 0.0)))
    out = []
    for k in range(20, 40):  # position lost, heading continues
        out += p.feed(RawEvent(T0 + k * S // 5, "gyro", enc.hdt("HE", 0.2).encode()))
    est = [o.payload for o in out if o.topic == "/dp/estimate"]
    assert est[0]["status"] == "ok" or est[0]["status"] == "dead_reckoning"
    assert est[-1]["status"] == "dead_reckoning"
    status = p.status(T0 + 40 * S // 5).payload
    assert any("gps: stale" in a for a in status["alarms"])
    assert not any("gyro" in a for a in status["alarms"])


def mav_src(name: str, roles: list[str], **kw) -> dict:  # type: ignore[no-untyped-def, type-arg]
    return {"name": name, "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": roles, **kw}


def test_mavlink_position_and_heading_sources() -> None:
    """GLOBAL_POSITION_INT / GPS_RAW_INT and ATTITUDE as an alternative position/heading source."""
    p = pipeline([mav_src("ap", ["position", "heading"])], vessel="cybership2")
    d = mv.dialect()
    mav = mv.encoder(1, 1)
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(3.0, -2.0, 0.0)
    out = []
    for k in range(10):
        t = T0 + k * S // 10
        frames = mv.pack(mav, d.MAVLink_attitude_message(k * 100, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
        frames += mv.pack(
            mav,
            d.MAVLink_gps_raw_int_message(k, 3, round(lat * 1e7), round(lon * 1e7), 0, 100, 100, 0, 0, 12),
        )
        out += p.feed(RawEvent(t, "ap", frames))
    est = [o.payload for o in out if o.topic == "/dp/estimate"][-1]
    np.testing.assert_allclose(est["eta"], [3.0, -2.0, 0.5], atol=0.05)
    hdg = mv.pack(
        mav, d.MAVLink_global_position_int_message(0, round(lat * 1e7), round(lon * 1e7), 0, 0, 0, 0, 0, 9000)
    )
    p.feed(RawEvent(T0 + 20 * S, "ap", hdg))  # after a gap: a 61° turn in 1 s would fail the rate test
    assert p.fusion.heading.value == pytest.approx(math.pi / 2)


def test_dialect_and_ardupilot_thruster_feedback_give_tau() -> None:
    p = pipeline(
        [
            nmea_src("gps", ["position", "heading"]),
            mav_src("thr", ["thrusters"], ardupilot={"esc": {"1": 1, "2": 2}, "servo": {"1": 1, "2": 2}}),
        ],
        vessel="cybership2",
    )
    mav = mv.encoder(1, 1)
    out = p.feed(RawEvent(T0, "thr", mv.azimuth_status_frame(mav, 0, 3, 0.5, 100.0, math.pi / 2, 0)))
    fb = [o.payload for o in out if o.topic == "/dp/thrusters/feedback"]
    assert fb and fb[0]["thrusters"] == [
        {"id": 3, "thrust_n": 0.5, "azimuth_rad": pytest.approx(math.pi / 2)}
    ]
    # ArduPilot: rpm -> thrust by the propeller law, servo PWM -> azimuth
    p.feed(RawEvent(T0 + 1, "thr", mv.esc_telemetry_frame(mav, [200.0, 100.0])))
    p.feed(RawEvent(T0 + 2, "thr", mv.servo_output_raw_frame(mav, 0, [1700, 1500])))
    t1, a1, _ = p.fusion.thrust[1]
    t2, a2, _ = p.fusion.thrust[2]
    assert t1 == pytest.approx(2.0) and a1 == pytest.approx(math.pi / 2)  # max thrust at max rpm; 1700 µs
    assert t2 == pytest.approx(0.5) and a2 == pytest.approx(0.0)
    tau, source = p.fusion.tau(T0 + 3)
    assert source == "feedback"
    v = p.spec.vessel
    np.testing.assert_allclose(tau, v.generalized_force([2.0, 0.5, 0.5], [math.pi / 2, 0.0, math.pi / 2]))


def test_a_drive_that_does_not_know_its_thrust_gives_it_by_its_shaft_speed() -> None:
    """The dialect sends an unknown value as NaN. A drive that measures shaft speed but does not estimate
    thrust: the thrust is the thruster's propeller law at that speed, at the azimuth of the same frame."""
    p = pipeline(
        [nmea_src("gps", ["position", "heading"]), mav_src("thr", ["thrusters"])], vessel="cybership2"
    )
    mav = mv.encoder(1, 1)
    out = p.feed(RawEvent(T0, "thr", mv.azimuth_status_frame(mav, 0, 1, math.nan, 100.0, 0.5, 0)))
    thrust, azimuth, _ = p.fusion.thrust[1]
    assert thrust == pytest.approx(p.spec.vessel.thrusters[0].thrust_at_rpm(100.0)) and thrust > 0
    assert azimuth == pytest.approx(0.5)
    assert [o.topic for o in out].count("/dp/thrusters/feedback") == 1
    # nothing known but the azimuth: the angle moves, the thrust keeps its time
    p.feed(RawEvent(T0 + S, "thr", mv.azimuth_status_frame(mav, 0, 1, math.nan, math.nan, -0.5, 0)))
    assert p.fusion.thrust[1] == (thrust, pytest.approx(-0.5), T0)
    assert not p.counters["thr"].rejected


@pytest.mark.parametrize("azimuth", [45.0, -90.0, 1e30])
def test_an_azimuth_beyond_a_full_turn_is_out_of_range(azimuth: float) -> None:
    """Radians in [-π, π) on the wire; [0, 2π) is taken too, beyond ±2π the number is no angle (degrees
    most likely): counted out of range, τ unchanged."""
    p = pipeline(
        [nmea_src("gps", ["position", "heading"]), mav_src("thr", ["thrusters"])], vessel="cybership2"
    )
    mav, d = mv.encoder(1, 1), mv.dialect()
    p.feed(RawEvent(T0, "thr", mv.azimuth_status_frame(mav, 0, 1, 1.0, 100.0, 0.5, 0)))
    tau0, _ = p.fusion.tau(T0)
    nan = math.nan
    raw = d.MAVLink_azimuth_thruster_status_message(0, 1, 1.5, 100.0, azimuth, 0, nan, nan, nan, nan, 0)
    p.feed(RawEvent(T0 + 1, "thr", mv.pack(mav, raw)))  # (the encode helper would wrap it)
    assert p.counters["thr"].rejected["out_of_range"] == 1
    assert p.fusion.thrust[1][:2] == (1.0, pytest.approx(0.5))
    np.testing.assert_array_equal(p.fusion.tau(T0 + 1)[0], tau0)
    in_range = d.MAVLink_azimuth_thruster_status_message(0, 1, 1.5, 100.0, 5.5, 0, nan, nan, nan, nan, 0)
    p.feed(RawEvent(T0 + 2, "thr", mv.pack(mav, in_range)))  # a [0, 2π) drive
    assert p.fusion.thrust[1][:2] == (1.5, pytest.approx(5.5))


@pytest.mark.parametrize("timeout_s", [0.5, 5.0])
def test_thruster_feedback_is_fresh_for_its_sources_timeout_as_status_says(timeout_s: float) -> None:
    """A link that reports every 3 s with ``timeout_s = 5`` keeps τ on the feedback throughout; one with
    ``timeout_s = 0.5`` is stale in `/status` 1 s after a report, and τ is then the demand, not the held
    feedback (it was held a fixed 2 s whatever the source's timeout said)."""
    p = pipeline(
        [nmea_src("gps", ["position", "heading"]), mav_src("thr", ["thrusters"], timeout_s=timeout_s)],
        vessel="cybership2",
    )
    mav = mv.encoder(1, 1)
    for k in range(3):
        p.feed(RawEvent(T0 + 3 * k * S, "thr", mv.azimuth_status_frame(mav, 0, 1, 1.0, 100.0, 0.0, 0)))
        now = T0 + 3 * k * S + S
        stale = any("thr: stale" in a for a in p.status(now).payload["alarms"])
        assert p.fusion.tau(now)[1] == ("demand" if timeout_s < 1 else "feedback")
        assert stale == (timeout_s < 1)
        assert p.fusion.tau(now + 2 * S)[1] == ("demand" if timeout_s < 1 else "feedback")


def test_a_thruster_without_feedback_counts_in_tau_with_its_command() -> None:
    """Feedback from the two azimuths only (the bow tunnel has no feedback link): τ for the observer is B(α)
    of their reported thrusts and the tunnel's commanded thrust, not of zero for the tunnel."""
    p = pipeline(
        [nmea_src("gps", ["position", "heading"]), mav_src("thr", ["thrusters"])],
        vessel="cybership2",
        control={"initial_mode": "manual"},
    )
    p.feed(ControlEvent(T0, "tau", {"X": 0.0, "Y": 0.3, "N": 0.2}))
    mav = mv.encoder(1, 1)
    for k in range(10):
        t = T0 + k * S // 5
        p.feed(RawEvent(t, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
        for tid in (1, 2):
            p.feed(RawEvent(t + 1, "thr", mv.azimuth_status_frame(mav, 0, tid, 0.4, 90.0, 1.0, 0)))
    cmd = p.allocation
    assert cmd is not None and abs(cmd.thrust[2]) > 0.05  # the tunnel is commanded
    tau, source = p.fusion.tau(t + 2)
    assert source == "feedback"
    expected = p.spec.vessel.generalized_force([0.4, 0.4, cmd.thrust[2]], [1.0, 1.0, cmd.azimuth[2]])
    np.testing.assert_allclose(tau, expected, rtol=1e-6)  # (float32 on the wire)
    # in standby the thrusters are someone else's: the unknown one counts with no thrust
    p.feed(ControlEvent(t + 3, "mode", "standby"))
    p.feed(RawEvent(t + S, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
    tau, _ = p.fusion.tau(t + S)
    np.testing.assert_allclose(
        tau, p.spec.vessel.generalized_force([0.4, 0.4, 0.0], [1.0, 1.0, 0.0]), rtol=1e-6
    )


def test_frames_of_another_mavlink_system_or_component_are_rejected_and_counted() -> None:
    p = pipeline(
        [
            nmea_src("gps", ["position", "heading"]),
            mav_src("thr", ["thrusters"], system_id=1, component_id=7),
        ],
        vessel="cybership2",
    )
    intruder, other_part, drive = mv.encoder(2, 7), mv.encoder(1, 8), mv.encoder(1, 7)
    p.feed(RawEvent(T0, "thr", mv.azimuth_status_frame(intruder, 0, 1, 9.0, 10.0, 0.0, 0)))
    p.feed(RawEvent(T0 + 1, "thr", mv.azimuth_status_frame(other_part, 0, 1, 9.0, 10.0, 0.0, 0)))
    assert 1 not in p.fusion.thrust
    p.feed(RawEvent(T0 + 2, "thr", mv.azimuth_status_frame(drive, 0, 1, 1.5, 10.0, 0.0, 0)))
    assert p.fusion.thrust[1][0] == 1.5
    c = p.counters["thr"]
    assert dict(c.rejected) == {"other system": 1, "other component": 1} and c.received == 1


def test_bytes_outside_mavlink_frames_are_counted_and_shown() -> None:
    """An NMEA talker wired to a MAVLink port (or any noise on it): no frame, so nothing received or
    rejected, but every byte outside a valid frame is counted in the status (`skipped_bytes`), beside the
    frames that are valid."""
    p = pipeline([
        nmea_src("gps", ["position", "heading"]),
        {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]},
    ])  # fmt: skip
    mav = mv.encoder(1, 1)
    frame = bytes(mav.heartbeat_encode(0, 0, 0, 0, 0).pack(mav))
    noise = (enc.hdt("HE", 1.0) + enc.rot("HE", 0.1)).encode()
    for k in range(10):
        p.feed(RawEvent(T0 + k, "thr", noise + frame if k % 2 else noise))
    c = p.counters["thr"]
    assert c.received == 5 and not c.rejected
    assert c.skipped_bytes == 10 * len(noise)
    status = json.loads(p.status(T0 + 10).message.encode())
    assert status["sources"]["thr"]["skipped_bytes"] == 10 * len(noise)
    assert "skipped_bytes" not in status["sources"]["gps"]  # (left out while 0)


def test_signed_mavlink_link_rejects_unsigned_and_forged_frames() -> None:
    p = pipeline(
        [nmea_src("gps", ["position", "heading"]), mav_src("thr", ["thrusters"], signing_key=KEY.hex())],
        vessel="cybership2",
    )
    good = mv.encoder(1, 1)
    mv.setup_signing(good, KEY, link_id=1)
    forged = mv.encoder(1, 1)
    mv.setup_signing(forged, bytes(32), link_id=1)
    plain = mv.encoder(1, 1)
    p.feed(RawEvent(T0, "thr", mv.azimuth_status_frame(plain, 0, 1, 1.0, 10.0, 0.0, 0)))
    p.feed(RawEvent(T0 + 1, "thr", mv.azimuth_status_frame(forged, 0, 1, 1.0, 10.0, 0.0, 0)))
    assert 1 not in p.fusion.thrust
    p.feed(RawEvent(T0 + 2, "thr", mv.azimuth_status_frame(good, 0, 1, 1.5, 10.0, 0.0, 0)))
    assert p.fusion.thrust[1][0] == 1.5
    rejected = p.counters["thr"].rejected
    assert sum(rejected.values()) >= 2, rejected


def test_manual_tau_is_allocated_and_is_the_observers_input() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    p.feed(ControlEvent(T0, "mode", "manual"))
    p.feed(ControlEvent(T0, "tau", {"X": 1e4, "Y": -2e3, "N": 5e4}))
    out = []
    for k in range(5):
        burst = gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()
        out += p.feed(RawEvent(T0 + k * S // 5, "gps", burst))
    cmd = [o.payload for o in out if o.topic == "/dp/thrusters/command"][-1]
    assert cmd["mode"] == "manual" and not cmd["saturated"]
    np.testing.assert_allclose(cmd["tau_allocated"], [1e4, -2e3, 5e4], rtol=1e-6, atol=1e-3)
    tau, source = p.fusion.tau(T0 + S)
    assert source == "demand"
    np.testing.assert_allclose(tau, [1e4, -2e3, 5e4], rtol=1e-6, atol=1e-3)
    p.feed(ControlEvent(T0, "tau", {"X": "lots"}))  # bad input: refused, counted, never raised
    p.feed(ControlEvent(T0, "mode", "warp"))
    assert p.mode == "manual"


def test_demand_beyond_capacity_gives_closest_tau_an_alarm_and_no_nan() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    p.feed(ControlEvent(T0, "mode", "manual"))
    # each DOF within what the thrusters give alone (gateway.commands.tau_capacity), but not all together
    cap = tau_capacity(p.spec.vessel)
    assert cap is not None
    out = []
    for k in range(30):  # the τ streamed as a joystick does (one given once expires after 2 s)
        p.feed(ControlEvent(T0 + k * S // 5, "tau", dict(zip("XYN", (0.9 * cap).tolist(), strict=True))))
        out += p.feed(RawEvent(T0 + k * S // 5, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
    cmd = [o.payload for o in out if o.topic == "/dp/thrusters/command"][-1]
    assert cmd["saturated"]
    assert all(math.isfinite(v) for v in cmd["tau_allocated"])
    for th, t in zip(cmd["thrusters"], p.spec.vessel.thrusters, strict=True):
        assert abs(th["thrust_n"]) <= t.max_thrust_n * 1.0001 and math.isfinite(th["azimuth_rad"])
    status = p.status(T0 + 6 * S).payload
    assert any("satur" in a for a in status["alarms"]), status["alarms"]
    est = [o.payload for o in out if o.topic == "/dp/estimate"][-1]
    assert all(math.isfinite(v) for v in est["eta"])


def test_standby_commands_nothing() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    out = []
    for k in range(10):
        out += p.feed(RawEvent(T0 + k * S // 5, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
    assert p.mode == "standby" and not [o for o in out if o.topic == "/dp/thrusters/command"]


@pytest.mark.slow
def test_dpgw_listen_prints_what_arrives(tmp_path: Path) -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    pub = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "dpgw", "listen", "dp/x/**", "--json", "--count", "3", "--no-scouting",
             "--connect", f"tcp/127.0.0.1:{port}", "--duration", "20"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        deadline = time.monotonic() + 20
        while proc.poll() is None and time.monotonic() < deadline:
            pub.put("dp/x/estimate", json.dumps({"eta": [1, 2, 3]}))
            time.sleep(0.2)
        out, err = proc.communicate(timeout=10)
    finally:
        pub.close()
    lines = [json.loads(line) for line in out.splitlines()]
    assert len(lines) == 3 and lines[0] == {"key": "dp/x/estimate", "payload": {"eta": [1, 2, 3]}}, err


def gst(sigma_lat: float, sigma_lon: float) -> bytes:
    return enc.gst(
        "GP", datetime(2026, 6, 1, tzinfo=UTC), rms_m=0.5, sigma_major_m=None, sigma_minor_m=None,
        orient_rad=None, sigma_lat_m=sigma_lat, sigma_lon_m=sigma_lon, sigma_alt_m=1.0,
    ).encode()  # fmt: skip


def test_gst_sigma_holds_across_fixes_while_fresh_then_is_null() -> None:
    """A receiver sends GST after its GGA, often less often: every fix while the GST is fresh carries its
    sigma in /dp/measurement; once the GST is older than the source's timeout, sigma_m is null."""
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=1.0)])
    sigma = math.hypot(0.3, 0.4) / math.sqrt(2)  # one horizontal 1σ: RMS of the two

    def sigmas(t0: int, n: int, gst_every: int) -> list[float | None]:
        out = []
        for k in range(n):
            t = t0 + k * S // 5
            out += p.feed(RawEvent(t, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
            if gst_every and k % gst_every == 0:
                out += p.feed(RawEvent(t + S // 100, "gps", gst(0.3, 0.4)))  # after the fix, own chunk
        return [o.payload["sigma_m"] for o in out if o.topic == "/dp/measurement"]

    assert sigmas(T0, 1, 0) == [None]  # no GST yet
    got = sigmas(T0 + S, 20, 4)  # a GST every 0.8 s, fixes at 5 Hz
    assert got[0] is None and got[1:] == [pytest.approx(sigma)] * 19
    got = sigmas(T0 + 5 * S, 10, 0)  # GSTs stop; the last one (at T0 + 4.21 s) is stale after 1 s
    assert got[:2] == [pytest.approx(sigma)] * 2 and got[2:] == [None] * 8  # fixes at 5.0, 5.2 | 5.4 ...
    # a GST from another source is not this fix's sigma
    p2 = pipeline([nmea_src("gps", ["position", "heading"]), nmea_src("gps2", ["position"], priority=2)])
    p2.feed(RawEvent(T0, "gps2", gst(0.3, 0.4)))
    out = p2.feed(RawEvent(T0 + 1, "gps", gga_at(0.0, 0.0) + enc.hdt("HE", 0.3).encode()))
    assert [o.payload["sigma_m"] for o in out if o.topic == "/dp/measurement"] == [None]


def test_two_senders_on_one_udp_source_never_splice_their_sentences() -> None:
    """Each sender has its own framer: two senders' partial sentences, interleaved chunk by chunk on one
    source, all decode (one framer per socket would splice them into garbage); a sender's stream split
    anywhere gives the same sentences."""
    p = pipeline([nmea_src("mux", ["position", "heading"])])
    a = (enc.hdt("HE", 10.0) + enc.hdt("HE", 11.0)).encode() * 50
    b = (enc.hdt("HC", 20.0) + enc.hdt("HC", 21.0)).encode() * 50
    cuts_a = [*list(range(0, len(a), 7)), len(a)]
    cuts_b = [*list(range(0, len(b), 11)), len(b)]
    pieces_a = [a[i:j] for i, j in itertools.pairwise(cuts_a)]
    pieces_b = [b[i:j] for i, j in itertools.pairwise(cuts_b)]
    t = T0
    for k in range(max(len(pieces_a), len(pieces_b))):
        for peer, pieces in (("10.0.0.1:4000", pieces_a), ("10.0.0.2:4000", pieces_b)):
            if k < len(pieces):
                t += 1000
                p.feed(RawEvent(t, "mux", pieces[k], peer=peer))
    c = p.counters["mux"]
    # every sentence framed and checksummed whole (a splice would be garbage or a bad checksum); the
    # reference tests may still refuse the two senders' differing headings, which is their job
    framing = {k: n for k, n in c.rejected.items() if not k.startswith("test_")}
    assert c.received == 200 and not framing, (c.received, dict(c.rejected))


def test_senders_beyond_the_cap_share_one_framer() -> None:
    """A flood of sender addresses cannot grow memory without bound: past MAX_SENDERS they share a framer."""
    from gateway.pipeline import MAX_SENDERS

    p = pipeline([nmea_src("mux", ["position", "heading"])])
    for k in range(MAX_SENDERS + 50):
        p.feed(RawEvent(T0 + k, "mux", enc.hdt("HE", 1.0).encode(), peer=f"10.0.{k // 250}.{k % 250}:1"))
    assert len(p._framers) == MAX_SENDERS + 1
    assert p.counters["mux"].received == MAX_SENDERS + 50


def test_clients_that_reconnect_all_day_keep_a_framer_each_and_their_leftovers_are_counted() -> None:
    """A TCP client that drops and reconnects comes back from a new port each time, leaving a half sentence
    in the framer of the old one. When a new sender comes, the senders silent for longer than the source's
    timeout are forgotten, their leftovers counted: the framers stay bounded, every leftover is counted
    (nothing received goes uncounted), and two clients talking at once after hundreds of reconnects still
    get a framer each (before, every newcomer past MAX_SENDERS shared one, and their sentences spliced,
    while the leftovers of the first MAX_SENDERS were never counted)."""
    from gateway.pipeline import MAX_SENDERS

    p = pipeline([nmea_src("mux", ["position", "heading"], url="tcp-listen://127.0.0.1:0", timeout_s=2.0)])
    c = p.counters["mux"]
    t = T0
    reconnects = 3 * MAX_SENDERS
    for k in range(reconnects):  # one connection every 0.5 s, each ending half-way through a sentence
        t += S // 2
        p.feed(RawEvent(t, "mux", enc.hdt("HE", 1.0).encode() + b"$HEHDT,1.0", peer=f"10.0.0.9:{40000 + k}"))
        assert len(p._framers) <= MAX_SENDERS + 1
    a = enc.hdt("HE", 10.0).encode() * 20
    b = enc.hdt("HE", 10.0).encode() * 20
    for i in range(0, len(a), 7):  # two clients at once, their bytes interleaved in 7-byte reads
        t += 1000
        p.feed(RawEvent(t, "mux", a[i : i + 7], peer="10.0.0.1:50001"))
        p.feed(RawEvent(t + 1, "mux", b[i : i + 7], peer="10.0.0.2:50002"))
    assert ("mux", "*") not in p._framers  # nobody was put on the shared framer
    assert c.received == reconnects + 40
    # the leftovers of the forgotten connections, counted when they were forgotten; the rest are held by
    # the framers of the connections not yet forgotten (at most MAX_SENDERS), never lost from the count
    held = sum(f.pending for (source, _), f in p._framers.items() if source == "mux")
    forgotten = c.rejected["truncated"]
    assert forgotten >= reconnects - 5  # all but those of the last timeout (2 s: 4 connections, and one)
    assert forgotten * len(b"$HEHDT,1.0") + held == reconnects * len(b"$HEHDT,1.0")
    assert {k for k in c.rejected if not k.startswith("test_")} == {"truncated"}


def test_the_end_of_a_senders_stream_counts_what_it_left_unfinished() -> None:
    """An empty chunk from a peer is the end of its stream (a TCP connection closed): the half sentence it
    left is counted at once, its framer freed; another sender's framer is untouched."""
    p = pipeline([nmea_src("mux", ["position", "heading"], url="tcp-listen://127.0.0.1:0")])
    c = p.counters["mux"]
    p.feed(RawEvent(T0, "mux", enc.hdt("HE", 1.0).encode() + b"$HEHDT,1.0", peer="10.0.0.9:40000"))
    other = enc.hdt("HE", 2.0).encode()
    p.feed(RawEvent(T0 + 1, "mux", other[:9], peer="10.0.0.8:40000"))
    assert c.received == 1 and not c.rejected  # (the half sentences are held, waiting for their ends)
    p.feed(RawEvent(T0 + 2, "mux", b"", peer="10.0.0.9:40000"))
    assert dict(c.rejected) == {"truncated": 1} and ("mux", "10.0.0.9:40000") not in p._framers
    p.feed(RawEvent(T0 + 3, "mux", other[9:], peer="10.0.0.8:40000"))
    assert c.received == 2  # the other client's sentence, completed in its own framer


def test_a_flood_of_new_senders_never_pushes_out_the_one_talking() -> None:
    """Senders still talking are kept: a flood of new addresses, all within the timeout, shares the one
    spare framer, and the receiver's sentences split across its datagrams still decode whole."""
    from gateway.pipeline import MAX_SENDERS

    p = pipeline([nmea_src("mux", ["position", "heading"])])
    c = p.counters["mux"]
    good = enc.hdt("HE", 1.0).encode()
    t = T0
    for k in range(4 * MAX_SENDERS):
        t += S // 100
        p.feed(RawEvent(t, "mux", good[: k % len(good)], peer="10.0.0.1:4001"))  # the receiver, split
        p.feed(RawEvent(t + 1, "mux", good[k % len(good) :], peer="10.0.0.1:4001"))
        p.feed(RawEvent(t + 2, "mux", b"$XX", peer=f"10.9.{k // 250}.{k % 250}:1"))  # the flood
    assert c.received == 4 * MAX_SENDERS
    assert len(p._framers) <= MAX_SENDERS + 1 and ("mux", "10.0.0.1:4001") in p._framers


def test_mavlink_clients_that_reconnect_keep_a_parser_each_and_their_leftovers_are_counted() -> None:
    from gateway.pipeline import MAX_SENDERS

    p = pipeline([
        nmea_src("gps", ["position", "heading"]),
        {"name": "thr", "url": "tcp-listen://127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]},
    ])  # fmt: skip
    c = p.counters["thr"]
    mav = mv.encoder(1, 1)
    frame = bytes(mav.heartbeat_encode(0, 0, 0, 0, 0).pack(mav))
    t = T0
    reconnects = 3 * MAX_SENDERS
    for k in range(reconnects):
        t += S // 2
        p.feed(RawEvent(t, "thr", frame + frame[:5], peer=f"10.0.0.9:{40000 + k}"))
        assert len(p._parsers) <= MAX_SENDERS + 1
    assert ("thr", "*") not in p._parsers
    assert c.received == reconnects
    held = sum(parser.pending for (source, _), parser in p._parsers.items() if source == "thr")
    assert c.rejected["truncated"] >= reconnects - MAX_SENDERS
    assert held + 5 * c.rejected["truncated"] == 5 * reconnects


def test_an_observer_that_wants_new_samples_gets_each_measurement_once() -> None:
    """GGA and HDT at 10 Hz, 20 ms apart: the observer steps 20 times a second, each time with one new
    measurement and the other held. The MMAE (``new_samples_only``) is given each fix and each heading once
    (held DOFs as NaN), except the held values that complete its first sample; its estimates say "ok" while
    both sources are alive. An observer that wants held values (the passive one, side by side) gets every
    DOF at every step, as before."""
    tables = {
        "vessel": {"name": "cybership2"},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": [
            nmea_src("gps", ["position"], timeout_s=1.0),
            nmea_src("gyro", ["heading"], timeout_s=1.0),
        ],
        "observer": {"type": "mmae"},
        "integrity": {"freeze_s": 600.0, "heading_freeze_s": 600.0},
        "log": {"path": ""},
    }
    config = parse_config(tables, base_dir=Path.cwd())
    from observers.factory import make_observer

    passive = make_observer("passive", config.vessel, config.observer.tuning)
    spec = PipelineSpec.from_config(config)
    p = Pipeline(
        PipelineSpec(
            vessel=spec.vessel,
            sources=spec.sources,
            observer=spec.observer,
            observer_name="mmae",
            datum=spec.datum,
            extra_observers=(("passive", passive),),
        )
    )
    given: dict[str, list[np.ndarray]] = {"mmae": [], "passive": []}
    for label, obs in (("mmae", p.observer), ("passive", passive)):
        step = obs.step

        def recording(t, y, tau=None, _step=step, _label=label):  # type: ignore[no-untyped-def]
            given[_label].append(np.array(y, dtype=float))
            return _step(t, y, tau)

        obs.step = recording  # type: ignore[method-assign]
    rng = np.random.default_rng(3)
    out = []
    n = 100
    for k in range(n):
        t = T0 + k * S // 10
        out += p.feed(RawEvent(t, "gps", gga_at(0.01 * rng.standard_normal(), 0.01 * rng.standard_normal())))
        out += p.feed(
            RawEvent(t + S // 50, "gyro", enc.hdt("HE", 0.2 + 0.002 * rng.standard_normal()).encode())
        )
    mmae = np.array(given["mmae"])
    first = int(np.flatnonzero(np.isfinite(mmae).all(axis=1))[0])
    assert first == 1  # the first heading, with the held first fix: the MMAE starts there
    after = mmae[first + 1 :]
    # one fix per step at the fix times, one heading per step at the heading times: each given once
    assert int(np.isfinite(after[:, 0]).sum()) == n - 1
    assert int(np.isfinite(after[:, 2]).sum()) == n - 1
    assert not (np.isfinite(after[:, 0]) & np.isfinite(after[:, 2])).any()
    np.testing.assert_array_equal(np.isfinite(after[:, 0]), np.isfinite(after[:, 1]))  # N and E together
    assert np.isfinite(np.array(given["passive"])[1:]).all()  # held values for the passive observer
    est = [o.payload for o in out if o.topic == "/dp/estimate"]
    assert len(est) == 2 * n - 1 and {e["status"] for e in est[1:]} == {"ok"}


def test_compile_kernels_leaves_the_pipelines_state_alone() -> None:
    """The live service calls `compile_kernels` before its sources open (so numba's compile or cache
    load does not stall the loop at the first sample or DP step): afterwards the pipeline gives exactly
    what a pipeline that never called it gives, in dp mode with a setpoint move."""
    src = [nmea_src("gps", ["position", "heading"])]
    warmed, plain = pipeline(src), pipeline(src)
    warmed.compile_kernels()
    outs = []
    for p in (warmed, plain):
        out = []
        for k in range(60):
            if k == 5:  # dp once there is an estimate
                out += p.feed(ControlEvent(T0 + k * S // 5, "mode", "dp"))
            if k == 20:
                out += p.feed(ControlEvent(T0 + k * S // 5, "setpoint", {"north_m": 3.0, "east_m": 1.0}))
            burst = gga_at(0.01 * k, 0.0) + enc.hdt("HE", 0.3 + 0.001 * k).encode()
            out += p.feed(RawEvent(T0 + k * S // 5, "gps", burst))
        outs.append([o.message.encode() for o in out])
    assert outs[0] == outs[1]
    assert sum(o.topic == "/dp/thrusters/command" for o in out) > 20


def test_fusion_tau_held_while_all_fresh_equals_a_fresh_pass() -> None:
    """`Fusion.tau` keeps the τ made while every thrust was fresh until the first one goes stale; at every
    time (before, at and after each thrust's timeout, and back in time) it equals what a fusion fed the
    same reports and asked only then gives, to the bit."""
    from gateway.fusion import NS, Fusion
    from observers.vessel import load_vessel

    vessel = load_vessel("mss_supply")
    ids = [t.id for t in vessel.thrusters]
    # (receive time, thruster, thrust, azimuth): one report per thruster, 0.1 s apart
    reports = [(k * NS // 10, tid, 1000.0 * (k + 1), 0.1 * k) for k, tid in enumerate(ids)]
    held = Fusion(vessel)
    for rx, tid, f, a in reports:
        held.add_thruster(rx, tid, f, a)
    first, last = reports[0][0], reports[-1][0]
    timeout = held.feedback_timeout_ns
    times = [last, last + 1, first + timeout - 1, first + timeout, first + timeout + 1, last + timeout,
             last + timeout + 1, last + 2, first + timeout]  # fmt: skip
    for t in times:
        once = Fusion(vessel)
        for rx, tid, f, a in reports:
            once.add_thruster(rx, tid, f, a)
        tau, how = held.tau(t)
        tau_once, how_once = once.tau(t)
        assert how == how_once
        assert tau.tolist() == tau_once.tolist(), t
    # a new report after the held τ was made is used at once
    held.add_thruster(last + 5, ids[0], -5000.0, 0.3)
    once = Fusion(vessel)
    for rx, tid, f, a in [*reports, (last + 5, ids[0], -5000.0, 0.3)]:
        once.add_thruster(rx, tid, f, a)
    assert held.tau(last + 6)[0].tolist() == once.tau(last + 6)[0].tolist()


def test_a_reference_state_change_keeps_the_services_alarms() -> None:
    """The service's own alarms (the clock, Zenoh, a disconnected device) come with its periodic status; a
    status the pipeline makes at once for a reference state change must carry them too. Without them it
    says on /status that they are gone, and the alarm log (/dp/log) writes "alarm cleared" at every state
    change and raises the alarm again a second later."""
    p = pipeline([nmea_src("gps", ["position"], timeout_s=1.0), nmea_src("gyro", ["heading"], timeout_s=1.0)])
    service_alarm = "clock: no simulation clock tick on dp/mss_supply/sim/clock for 7 s"
    p.status(T0, [service_alarm])
    out = []
    for k in range(1, 20):  # the gyro comes up (stale -> ok): a state change, and its status at once
        out += p.feed(RawEvent(T0 + k * S // 5, "gyro", enc.hdt("HE", 0.2).encode()))
    statuses = [o.payload for o in out if o.topic == "/dp/status"]
    assert statuses and any(s["events"] for s in statuses)
    assert all(service_alarm in s["alarms"] for s in statuses)
    lines = [json.loads(o.message.encode())["message"] for o in out if o.topic == "/dp/log"]
    assert not [x for x in lines if "cleared: clock" in x], lines


def test_two_inputs_at_one_time_step_the_observer_once() -> None:
    """On the simulation's clock a gyro's read and a GGA's can be stamped at one time (its stamps are
    interpolated between ticks): the second stepped the observer again with a dt of zero and published a
    byte-identical second estimate of the same stamp (9 in a 150 s demo). One step an instant: the second
    input's measurement is held and goes into the next step."""
    p = pipeline([nmea_src("gps", ["position"]), nmea_src("gyro", ["heading"])])
    hdt = enc.hdt("HE", 30.0).encode()
    stamps: list[int] = []
    positions = []
    for k in range(20):
        t = T0 + k * S // 10
        outs = p.feed(RawEvent(t, "gyro", hdt))
        if k % 10 == 0:  # a 1 Hz fix at the gyro's time
            outs += p.feed(RawEvent(t, "gps", gga_at(2.0 * (k // 10), 0.0)))
        for o in outs:
            if o.topic == "/dp/estimate":
                stamps.append(o.stamp_ns)
            if o.topic == "/dp/measurement":
                positions.append((o.stamp_ns, o.message.eta[0]))
    assert len(stamps) == len(set(stamps)), [s for s in stamps if stamps.count(s) > 1][:3]
    # the fix of t = 1 s (2 m north), read after that instant's gyro step, is in the step after it
    after = [n for ns, n in positions if ns == T0 + 11 * S // 10]
    assert after == [pytest.approx(2.0, abs=1e-3)], positions[-10:]
