"""The sign of ArduPilot ESC rpm from the ESC's reversible motor output (``esc_direction_servo``): real
MAVLink frames from the project's encoders, through the real parser, wiring and pipeline."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gateway.config import parse_config
from gateway.esc_direction import EscDirections
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from wire.codecs import mavlink as mv

S = 1_000_000_000
T0 = 1_780_000_000 * S
TIMEOUT_S = 1.0
TUNNEL_ESC, TUNNEL_OUT = 3, 5  # cybership2's bow tunnel (id 3, at +π/2, reverses) on ESC 3, output 5


def boat(**ardupilot: object) -> Pipeline:
    """cybership2 with an ArduPilot link: ESC 1-3 -> thrusters 1-3, the tunnel's direction from output 5."""
    wiring = {"esc": {"1": 1, "2": 2, "3": 3}, "servo": {"1": 1, "3": 2}, "esc_direction_servo": {"3": 5}}
    tables = {
        "vessel": {"name": "cybership2"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
            {
                "name": "ap",
                "url": "udpin:127.0.0.1:0",
                "protocol": "mavlink",
                "roles": ["thrusters"],
                "timeout_s": TIMEOUT_S,
                "ardupilot": {**wiring, **ardupilot},
            },
        ],
        "observer": {"wave_period_s": 8.0},
        "log": {"path": ""},
    }
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


MAV = mv.encoder(1, 1)


def outputs(tunnel_us: int) -> bytes:
    """SERVO_OUTPUT_RAW: azimuth servos 1 and 3 ahead (1500 µs), the tunnel's motor on output 5."""
    return mv.servo_output_raw_frame(MAV, 0, [1500, 0, 1500, 0, tunnel_us])


def esc(tunnel_rpm: float) -> bytes:
    """ESC_TELEMETRY_1_TO_4: the azimuths stopped, the tunnel at |rpm| (the field has no sign)."""
    return mv.esc_telemetry_frame(MAV, [0.0, 0.0, abs(tunnel_rpm)])


def tunnel_thrust(p: Pipeline, rpm: float) -> float:
    return p.spec.vessel.thrusters[2].thrust_at_rpm(rpm)


# --- the wire: what the frames say ----------------------------------------------------------------------


def test_servo_output_raw_gives_the_direction_of_each_named_esc() -> None:
    """Above the neutral by more than the dead band: ahead; below: astern; inside: 0; 0 µs (output not in
    use): no report. A channel on port 1 (17-32) and a per-ESC neutral are read as configured."""
    wiring = mv.ArduPilotWiring(
        esc={3: 3, 4: 4}, esc_direction={3: (5, 1500.0), 4: (18, 1520.0)}, esc_dead_band_us=25.0
    )

    def directions(frame: bytes) -> list[tuple[int, int, int]]:
        (msg,) = mv.parse_frames(frame)
        return [(r.esc, r.direction, r.pwm_us) for r in mv.reports(msg, wiring)]

    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 0, 0, 0, 1300])) == [(3, -1, 1300)]
    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 0, 0, 0, 1526])) == [(3, 1, 1526)]
    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 0, 0, 0, 1475])) == [(3, 0, 1475)]
    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 0, 0, 0, 0])) == []
    # port 1 carries outputs 17-32: output 18 is its second; neutral 1520 -> 1500 is inside the band
    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 1500], port=1)) == [(4, 0, 1500)]
    assert directions(mv.servo_output_raw_frame(MAV, 0, [0, 1490], port=1)) == [(4, -1, 1490)]
    # ESC telemetry names its ESC, so the gateway knows the rpm is unsigned
    (msg,) = mv.parse_frames(mv.esc_telemetry_frame(MAV, [0.0, 0.0, 150.0, 10.0]))
    assert [(r.thruster_id, r.rpm, r.esc) for r in mv.reports(msg, wiring)] == [(3, 150.0, 3), (4, 10.0, 4)]


@given(pwm=st.integers(1, 2500), neutral=st.integers(900, 2100), band=st.integers(0, 400))
def test_direction_is_the_side_of_the_neutral_outside_the_dead_band(
    pwm: int, neutral: int, band: int
) -> None:
    wiring = mv.ArduPilotWiring(esc={1: 1}, esc_direction={1: (1, float(neutral))}, esc_dead_band_us=band)
    (msg,) = mv.parse_frames(mv.servo_output_raw_frame(MAV, 0, [pwm]))
    (r,) = mv.reports(msg, wiring)
    assert isinstance(r, mv.EscDirectionReport) and r.pwm_us == pwm
    assert r.direction == (0 if abs(pwm - neutral) <= band else int(math.copysign(1, pwm - neutral)))


# --- the pipeline: signed thrust and τ ------------------------------------------------------------------


def test_a_tunnel_running_astern_gives_negative_thrust_and_tau_to_port() -> None:
    """The bow tunnel pushes to starboard ahead (+π/2): astern (output below its trim) its feedback thrust
    is negative and τ's sway force and yaw moment point to port, as the propeller law gives for −rpm."""
    p = boat()
    p.feed(RawEvent(T0, "ap", outputs(1300)))
    p.feed(RawEvent(T0 + S // 10, "ap", esc(150.0)))
    thrust = p.fusion.thrust[3][0]
    assert thrust == pytest.approx(tunnel_thrust(p, -150.0)) and thrust < 0
    tau, source = p.fusion.tau(T0 + S // 5)
    assert source == "feedback"
    np.testing.assert_allclose(
        tau, p.spec.vessel.generalized_force([0.0, 0.0, thrust], [0.0, 0.0, math.pi / 2]), atol=1e-12
    )
    assert tau[1] < 0 and tau[2] < 0  # to port; bow to port (the tunnel is forward of the reference point)
    # ahead: the same rpm, the other sign
    p.feed(RawEvent(T0 + 3 * S // 10, "ap", outputs(1700)))
    p.feed(RawEvent(T0 + 4 * S // 10, "ap", esc(150.0)))
    assert p.fusion.thrust[3][0] == pytest.approx(-thrust)
    assert p.fusion.tau(T0 + S // 2)[0][1] > 0
    assert not p.counters["ap"].rejected


def test_inside_the_dead_band_the_last_driven_direction_holds() -> None:
    """Back to neutral after astern: the ESC is no longer driven and the propeller coasts down astern, so
    its rpm keeps the astern sign; with nothing driven since start the direction is unknown (not thrust),
    except at 0 rpm, which is no thrust either way."""
    p = boat()
    p.feed(RawEvent(T0, "ap", outputs(1300)))
    p.feed(RawEvent(T0 + S // 10, "ap", outputs(1490)))  # inside ±25 µs of 1500
    p.feed(RawEvent(T0 + S // 5, "ap", esc(40.0)))
    assert p.fusion.thrust[3][0] == pytest.approx(tunnel_thrust(p, -40.0)) and p.fusion.thrust[3][0] < 0

    fresh = boat()
    fresh.feed(RawEvent(T0, "ap", outputs(1510)))
    fresh.feed(RawEvent(T0 + S // 10, "ap", esc(40.0)))
    assert 3 not in fresh.fusion.thrust
    assert fresh.counters["ap"].rejected["esc_direction_unknown"] == 1
    fresh.feed(RawEvent(T0 + S // 5, "ap", esc(0.0)))
    assert fresh.fusion.thrust[3][0] == 0.0

    wide = boat(esc_dead_band_us=250)  # a wider band: 1300 µs is now "not driven"
    wide.feed(RawEvent(T0, "ap", outputs(1300)))
    wide.feed(RawEvent(T0 + S // 10, "ap", esc(40.0)))
    assert 3 not in wide.fusion.thrust


def test_without_fresh_motor_outputs_the_rpm_is_not_thrust_and_tau_counts_the_command() -> None:
    """No SERVO_OUTPUT_RAW yet, or the last older than the source's timeout: the tunnel's rpm has no sign
    and is not used; its old feedback ages out and τ counts the tunnel with its commanded thrust (the
    azimuths' feedback is fresh). A direction held in the dead band is forgotten across such a gap."""
    p = boat()
    p.feed(RawEvent(T0, "ap", esc(150.0)))  # no motor output seen yet
    assert 3 not in p.fusion.thrust and p.fusion.thrust[1][0] == 0.0
    assert p.counters["ap"].rejected["esc_direction_unknown"] == 1

    p.feed(RawEvent(T0 + S // 10, "ap", outputs(1300)))
    p.feed(RawEvent(T0 + S // 5, "ap", esc(150.0)))
    astern = p.fusion.thrust[3][0]
    assert astern < 0
    # the outputs stop; ESC telemetry goes on past the timeout
    late = T0 + S // 10 + int(TIMEOUT_S * S) + S // 10
    p.feed(RawEvent(late, "ap", esc(150.0)))
    assert p.fusion.thrust[3][2] == T0 + S // 5  # not updated
    assert p.counters["ap"].rejected["esc_direction_unknown"] == 2
    command = [0.3, -0.2, 0.6]
    angles = [0.1, -0.1, math.pi / 2]
    p.fusion.set_tau_demand(np.zeros(3), command, angles)
    p.feed(RawEvent(late + int(TIMEOUT_S * S), "ap", esc(150.0)))  # the azimuths fresh, the tunnel not
    tau, source = p.fusion.tau(late + int(TIMEOUT_S * S))
    assert source == "feedback"
    np.testing.assert_allclose(tau, p.spec.vessel.generalized_force([0.0, 0.0, 0.6], [0.0, 0.0, math.pi / 2]))
    # the outputs resume inside the dead band: the astern from before the gap is not trusted
    p.feed(RawEvent(late + 2 * S, "ap", outputs(1500)))
    p.feed(RawEvent(late + 2 * S + 1, "ap", esc(20.0)))
    assert p.counters["ap"].rejected["esc_direction_unknown"] == 4


def test_esc_directions_keep_sources_apart() -> None:
    d = EscDirections()
    d.add("a", 1, -1, T0, S)
    assert (d.sign("a", 1, T0 + S), d.sign("a", 1, T0 + S + 1), d.sign("b", 1, T0)) == (-1, 0, 0)


# --- the simulator -> the gateway -----------------------------------------------------------------------


def sim_thruster_frames() -> list[tuple[float, bytes]]:
    """The simulator's ArduPilot thruster link (ESC telemetry and motor outputs, as `dpgw sim --ardupilot`
    sends them) while cybership2's bow tunnel is commanded ahead, astern, stopped and astern again."""
    from dataclasses import replace

    from simulator.runner import Simulation
    from simulator.scenarios import get_scenario
    from simulator.sensors import ThrusterFeedbackConfig

    feedback = ThrusterFeedbackConfig(ardupilot_esc=True, ardupilot_servo=True, ardupilot_motor=True)
    emitted: list[tuple[float, bytes]] = []
    sim = Simulation(
        replace(get_scenario("hassani"), feedback=feedback),
        seed=1,
        on_emit=lambda e: emitted.append((e.t_emit, e.data)) if e.source == "thrusters" else None,
    )
    sim.external_control = True  # the tunnel's thrust as commanded here, the azimuths idle
    for thrust_n, seconds in ((0.6, 3.0), (-0.8, 3.0), (0.0, 2.0), (-0.5, 3.0)):
        sim.thrusters.command_one(3, thrust_n)
        sim.run(seconds)
    return emitted


def test_the_simulators_motor_outputs_give_the_gateway_the_tunnels_sign() -> None:
    """Sim -> gateway through the bytes: with the tunnel's motor output (the sim's output 16 + 3) named in
    `esc_direction_servo`, the thrust the gateway derives from the ESC's unsigned rpm has the sign and size
    of the tunnel's true thrust (its own status frame of the same instant) wherever it pushes more than
    0.05 N; without it, every astern sample is taken as ahead."""
    frames = sim_thruster_frames()
    signed = boat(esc_direction_servo={"3": 19})
    unsigned = boat(esc_direction_servo={})
    parser = mv.FrameParser()
    truth: float | None = None
    compared = []
    for t_emit, data in frames:
        (msg,) = parser.feed(data)
        kind = msg.get_type()
        if kind == "AZIMUTH_THRUSTER_STATUS":
            if msg.id == 3:
                truth = float(msg.thrust)  # the drive's own thrust (the dialect's status): the truth
            continue
        rx_ns = T0 + round(t_emit * S)
        for p in (signed, unsigned):
            p.feed(RawEvent(rx_ns, "ap", data))
        fed = signed.fusion.thrust.get(3)
        if kind == "ESC_TELEMETRY_1_TO_4" and truth is not None and fed is not None and fed[2] == rx_ns:
            compared.append((truth, fed[0], unsigned.fusion.thrust[3][0]))
    pushing = [(t, s, u) for t, s, u in compared if abs(t) > 0.05]
    astern = [(t, s, u) for t, s, u in pushing if t < 0]
    assert len(astern) >= 20 and len(pushing) - len(astern) >= 10  # 5 Hz: ~6 s astern, ~3 s ahead
    for t, s, _ in pushing:
        assert s == pytest.approx(t, abs=0.01)  # the ESC's whole rpm is the only rounding
    assert all(u > 0 for _, _, u in astern)
    assert not signed.counters["ap"].rejected


def test_motor_pwm_is_the_shaft_speed_fraction_either_side_of_the_trim() -> None:
    from simulator.sensors import motor_pwm

    assert motor_pwm(0.0, -1.0, 1.0) == 1500
    assert (motor_pwm(1.0, -1.0, 1.0), motor_pwm(-1.0, -1.0, 1.0)) == (1900, 1100)
    assert motor_pwm(-0.8, -1.0, 1.0) == round(1500 - 400 * math.sqrt(0.8))  # 1142: astern
    assert motor_pwm(0.5, -0.5, 2.0) == 1700  # a quarter of full thrust: half speed ahead
    assert motor_pwm(-0.5, 0.0, 2.0) == 1500  # a thruster that does not reverse has no astern side
