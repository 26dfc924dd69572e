"""Keelson output: a Zenoh subscriber on an isolated loopback session receives every subject under Keelson's
key space, the keelson package decodes every envelope and payload (the payload type each subject has in
keelson's own subjects.yaml) to the values dpgw published (in the subject's units), and sees one liveliness
token per source id."""

from __future__ import annotations

import math
import socket
import threading
from collections import defaultdict
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

keelson = pytest.importorskip("keelson")

from gateway.bus import isolated_config, open_session  # noqa: E402
from gateway.config import ConfigError, parse_config  # noqa: E402
from gateway.outputs import RawSentenceSink  # noqa: E402
from gateway.outputs.build import output_problems, sinks_from_config  # noqa: E402
from gateway.outputs.keelson import KeelsonSink  # noqa: E402
from gateway.pipeline import Output  # noqa: E402
from gateway.service import GatewayService  # noqa: E402
from tests.conftest import Recorder, free_port, wait_for  # noqa: E402
from wire.codecs import nmea_encode as enc  # noqa: E402
from wire.gst_covariance import ellipse_covariance_ne  # noqa: E402
from wire.messages import (  # noqa: E402
    Datum,
    Estimate,
    Measurement,
    Status,
    ThrusterCommand,
    ThrusterFeedback,
)

BASE = "keelson"
ENTITY = "test_ship"
LAT, LON, ALT, SEP = 59.4, 10.5, 20.0, 35.5
# the receiver's error ellipse: 0.5 m by 0.2 m, its major axis 30° east of north; σ lat / lon its marginals
SIGMA_MAJOR, SIGMA_MINOR, ORIENT_DEG = 0.5, 0.2, 30.0
SIGMA_LAT, SIGMA_LON, SIGMA_ALT = 0.444, 0.304, 0.9
C_NN, C_NE, C_EE = ellipse_covariance_ne(SIGMA_MAJOR, SIGMA_MINOR, math.radians(ORIENT_DEG))
ENU_COVARIANCE = [C_EE, C_NE, 0, C_NE, C_NN, 0, 0, 0, SIGMA_ALT**2]  # east, north, up; row-major
SUBJECTS = {
    "location_fix",
    "heading_true_north_deg",
    "course_over_ground_deg",
    "speed_over_ground_knots",
    "yaw_rate_degps",
    "surge_velocity_mps",
    "sway_velocity_mps",
    "force_newton",
    "moment_newton_meter",
    "raw_nmea0183",
    "log_message",
}
F32 = 1e-6  # keelson.TimestampedFloat is a 32-bit float: 24-bit mantissa, relative error < 6e-8


class Listener:
    """A Keelson consumer: subscribes to the entity's pubsub space and decodes with the keelson package."""

    def __init__(self, session: Any) -> None:
        self.lock = threading.Lock()
        # (subject, source_id) -> [(enclosed_at ns, payload message)]
        self.got: dict[tuple[str, str], list[tuple[int, Any]]] = defaultdict(list)
        self.sub = session.declare_subscriber(f"{BASE}/@v0/{ENTITY}/pubsub/**", self._on)

    def _on(self, sample: Any) -> None:
        key = keelson.parse_pubsub_key(str(sample.key_expr))
        assert key["base_path"] == BASE and key["entity_id"] == ENTITY and key["target_id"] is None
        subject = key["subject"]
        assert keelson.is_subject_well_known(subject), subject
        _, enclosed_at, payload = keelson.uncover(sample.payload.to_bytes())
        msg = keelson.decode_protobuf_payload_from_type_name(payload, keelson.get_subject_schema(subject))
        with self.lock:
            self.got[(subject, key["source_id"])].append((enclosed_at, msg))

    def of(self, subject: str, source_id: str) -> list[Any]:
        with self.lock:
            return [m for _, m in self.got[(subject, source_id)]]

    def by_stamp(self, subject: str, source_id: str) -> dict[int, Any]:
        return {m.timestamp.ToNanoseconds(): m for m in self.of(subject, source_id)}

    def subjects(self) -> set[str]:
        with self.lock:
            return {s for s, _ in self.got}


def tables(udp: int, zport: int, **keelson_keys: Any) -> dict[str, Any]:
    return {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": LAT, "lon_deg": LON},
        "sources": [
            {
                "name": "dgps1",
                "url": f"udp://127.0.0.1:{udp}",
                "protocol": "nmea",
                "roles": ["position", "heading"],
            }
        ],
        "observer": {"wave_period_s": 9.0},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"], "multicast_scouting": False, "prefix": "dp/k"},
        "status": {"rate_hz": 10.0},
        "log": {"path": ""},
        "commands": {"accept": ["mode"]},
        "keelson": {"enabled": True, "base_path": BASE, "entity_id": ENTITY, **keelson_keys},
    }


def sentences(k: int) -> list[str]:
    """One second of a DGPS with a gyro: GGA, GST, HDT (heading swinging a little so the yaw rate lives)."""
    t = datetime.now(UTC)
    return [
        enc.gga("GP", t, LAT + 2e-6 * math.sin(k / 5), LON, 2, 12, 0.8, ALT, SEP).rstrip("\r\n"),
        enc.gst(
            "GP", t, rms_m=0.5, sigma_major_m=SIGMA_MAJOR, sigma_minor_m=SIGMA_MINOR,
            orient_rad=math.radians(ORIENT_DEG),
            sigma_lat_m=SIGMA_LAT, sigma_lon_m=SIGMA_LON, sigma_alt_m=SIGMA_ALT,
        ).rstrip("\r\n"),
        enc.hdt("HE", 0.5 + 0.01 * math.sin(k / 3)).rstrip("\r\n"),
    ]  # fmt: skip


def test_a_keelson_consumer_receives_and_decodes_every_subject_with_the_right_values(tmp_path: Path) -> None:
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    config = parse_config(tables(udp, zport), base_dir=tmp_path)
    recorder = Recorder()
    sinks = sinks_from_config(config)
    assert len(sinks) == 1 and isinstance(sinks[0], KeelsonSink) and isinstance(sinks[0], RawSentenceSink)
    sink = sinks[0]
    service = GatewayService(config, sinks=[sink, recorder])
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{zport}"]))
    listener = Listener(client)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent: list[str] = []

    def send() -> None:
        lines = sentences(len(sent))
        sent.extend(lines)
        tx.sendto("".join(line + "\r\n" for line in lines).encode(), ("127.0.0.1", udp))

    def until(what: str, ok: Any) -> None:
        def step() -> bool:
            send()
            return bool(ok())

        wait_for(step, timeout=30.0, interval=0.05)

    def tokens() -> set[str]:
        replies = client.liveliness().get(f"{BASE}/@v0/{ENTITY}/pubsub/**")
        return {str(r.ok.key_expr) for r in replies if r.ok is not None}

    est, meas, sensor = "dpgw/estimate", "dpgw/measurement", "dpgw/sensor/dgps1"
    ran = False
    try:
        # presence: one token per source id, in keelson's liveliness key format
        expected = {keelson.construct_liveliness_key(BASE, ENTITY, sid) for sid in sink.source_ids()}
        wait_for(lambda: tokens() == expected)
        assert all("/pubsub/*/" in t for t in expected)
        assert {keelson.parse_liveliness_key(t)["source_id"] for t in tokens()} == {
            est, meas, sensor, "dpgw/control/demand", "dpgw/control/allocated",
            "dpgw/thrusters/feedback", "dpgw",
        }  # fmt: skip
        # The consumer's subscription must have reached the gateway's session before the first sentence is
        # sent: the tokens above travel the other way, and a put made before the gateway knows of the
        # subscriber is (rightly) sent to nobody. A probe publisher on the gateway's session says when.
        raw_key = keelson.construct_pubsub_key(BASE, ENTITY, "raw_nmea0183", sensor)
        probe = service._session.declare_publisher(raw_key)  # type: ignore[union-attr]
        try:
            wait_for(lambda: probe.matching_status.matching)
        finally:
            probe.undeclare()
        until("estimates", lambda: service.pipeline.estimates >= 5)
        service.submit("mode", "dp")  # a mode change (a log_message) and thruster commands (τ)
        until("τ demanded", lambda: listener.of("force_newton", "dpgw/control/demand"))
        until("a second fix of the receiver", lambda: len(listener.of("location_fix", sensor)) >= 2)
        until(
            "the mode change",
            lambda: any(
                m.message == "mode: standby -> dp (operator)" for m in listener.of("log_message", "dpgw")
            ),
        )
        ran = True
    finally:
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        sink.close()  # the tokens go with the sink, before the session closes
        gone = wait_for(lambda: tokens() == set(), timeout=10.0)
        service.close()
        if not ran:  # (an open session keeps the test process from exiting after the failure)
            client.close()
    tx.close()
    try:
        check_values(listener, recorder, sent)
    finally:
        client.close()
    # (the gateway's session is closed: its tokens are gone; checked from the client before it closed)
    assert gone
    assert not loop.is_alive()
    assert service.internal_errors == {}


def check_values(listener: Listener, recorder: Recorder, sent: list[str]) -> None:
    est, meas, sensor = "dpgw/estimate", "dpgw/measurement", "dpgw/sensor/dgps1"
    assert listener.subjects() >= SUBJECTS

    # the estimate: every subject of every estimate, in the subject's units
    estimates = recorder.of(Estimate, "/dp/estimate")
    assert estimates
    heading = listener.by_stamp("heading_true_north_deg", est)
    fixes = listener.by_stamp("location_fix", est)
    cog, sog = (
        listener.by_stamp("course_over_ground_deg", est),
        listener.by_stamp("speed_over_ground_knots", est),
    )
    rate = listener.by_stamp("yaw_rate_degps", est)
    surge, sway = listener.by_stamp("surge_velocity_mps", est), listener.by_stamp("sway_velocity_mps", est)
    force, moment = listener.by_stamp("force_newton", est), listener.by_stamp("moment_newton_meter", est)
    for e in estimates:
        t = e.stamp_ns
        u, v, r = e.nu
        assert heading[t].value == pytest.approx(e.heading_deg, rel=F32)
        assert math.degrees(e.eta[2]) % 360 == pytest.approx(heading[t].value, rel=F32)
        assert fixes[t].latitude == e.lat_deg and fixes[t].longitude == e.lon_deg  # doubles: exact
        assert fixes[t].frame_id == "estimate"
        assert rate[t].value == pytest.approx(r * 180 / math.pi, rel=F32, abs=1e-12)
        assert surge[t].value == pytest.approx(u, rel=F32, abs=1e-12)
        assert sway[t].value == pytest.approx(v, rel=F32, abs=1e-12)
        assert sog[t].value == pytest.approx(math.hypot(u, v) * 3600 / 1852, rel=F32, abs=1e-12)
        # course over ground: the direction of the NED velocity R(ψ)[u, v]
        vn = u * math.cos(e.eta[2]) - v * math.sin(e.eta[2])
        ve = u * math.sin(e.eta[2]) + v * math.cos(e.eta[2])
        if u == 0 and v == 0:  # at rest: no course, rather than a made-up one
            assert t not in cog
        else:
            assert math.cos(math.radians(cog[t].value) - math.atan2(ve, vn)) == pytest.approx(1.0, abs=1e-9)
            assert 0 <= cog[t].value < 360
        # the bias: earth-fixed [X, Y, N] as a force and a moment
        assert force[t].frame_id == "ned" and moment[t].frame_id == "ned"
        assert (force[t].vector.x, force[t].vector.y, force[t].vector.z) == (e.bias[0], e.bias[1], 0.0)
        assert (moment[t].vector.x, moment[t].vector.y, moment[t].vector.z) == (0.0, 0.0, e.bias[2])

    # the measurement: the gyro's heading, the fused position (a fixed antenna: where the GGA says)
    measurements = recorder.of(Measurement)
    m_heading = listener.by_stamp("heading_true_north_deg", meas)
    m_fix = listener.by_stamp("location_fix", meas)
    m_sigma = listener.by_stamp("location_fix_accuracy_horizontal_m", meas)
    for m in measurements:
        t = m.stamp_ns
        if m.valid[2]:
            assert m_heading[t].value == pytest.approx(math.degrees(m.eta[2]) % 360, rel=F32)
        if m.valid[0]:
            assert m_fix[t].latitude == pytest.approx(LAT, abs=3e-6) and m_fix[t].longitude == pytest.approx(
                LON, abs=1e-7
            )
        if m.sigma_m is not None:
            assert m_sigma[t].value == pytest.approx(m.sigma_m, rel=F32)
    assert m_heading and m_fix and m_sigma

    # the receiver's own fix: GGA's ellipsoidal height, GST's error ellipse as a full ENU covariance
    for f in listener.of("location_fix", sensor):
        assert f.frame_id == "dgps1"
        assert f.latitude == pytest.approx(LAT, abs=3e-6) and f.longitude == pytest.approx(LON, abs=1e-9)
        assert f.altitude == pytest.approx(ALT + SEP, abs=1e-9)
        assert f.position_covariance_type in (f.UNKNOWN, f.KNOWN)
        if f.position_covariance_type == f.KNOWN:
            assert list(f.position_covariance) == pytest.approx(ENU_COVARIANCE)
    assert any(f.position_covariance_type == f.KNOWN for f in listener.of("location_fix", sensor))
    assert C_NE > 0.09  # (the east-north term is there: the test would see it swapped or dropped)

    # raw sentences: every one sent, as sent, in order
    raw = [m.value for m in listener.of("raw_nmea0183", sensor)]
    assert raw == sent[: len(raw)] and len(raw) >= len(sent) - 30  # (the last few may still be in flight)

    # τ: the controller's demand and what was allocated, in the body frame
    commands = recorder.of(ThrusterCommand)
    assert commands
    for subject_source, attr in (
        ("dpgw/control/demand", "tau_demand"),
        ("dpgw/control/allocated", "tau_allocated"),
    ):
        f_by, m_by = (
            listener.by_stamp("force_newton", subject_source),
            listener.by_stamp("moment_newton_meter", subject_source),
        )
        for c in commands:
            x, y, n = getattr(c, attr)
            t = c.stamp_ns
            assert f_by[t].frame_id == "body" and (f_by[t].vector.x, f_by[t].vector.y) == (x, y)
            assert m_by[t].vector.z == n

    # log: the mode change
    logs = listener.of("log_message", "dpgw")
    said = [m for m in logs if m.message.startswith("mode: ")]
    assert [(m.message, m.level == m.INFO, m.name) for m in said] == [
        ("mode: standby -> dp (operator)", True, "dpgw")
    ]
    statuses = recorder.of(Status)
    assert statuses


def status(t: int, alarms: list[Any], events: list[str], mode: str = "dp") -> Output:
    """A `/dp/status` output at ``t`` with these alarms and reference state changes."""
    message = Status(
        stamp_ns=t, mode=mode, observer="passive", initialized=True, estimates=1, sources={},
        alarms=alarms, references={}, events=events,
    )  # fmt: skip
    return Output("/dp/status", message, t)


def test_feedback_alarms_and_state_changes_reach_keelson(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """What the NMEA-only service above does not produce: τ from the thrusters' feedback (a MAVLink link)
    and alarms (raised once, cleared once, as objects too) and reference state changes, as log messages."""
    zport, server, client = loopback_sessions
    config = parse_config(
        tables(free_port(socket.SOCK_DGRAM), zport, log_source_id="dpgw/log"), base_dir=tmp_path
    )
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, KeelsonSink)
    try:
        listener = Listener(client)
        sink.start(server)
        wait_for(lambda: len(list(client.liveliness().get(f"{BASE}/@v0/{ENTITY}/pubsub/*/dpgw/log"))) == 1)

        fb = ThrusterFeedback(stamp_ns=5, tau_allocated=[1000.5, -2000.25, 30000.125], thrusters=[])
        stale, sat = "dgps1: position stale", {"code": "sat", "message": "thrust saturated"}
        batches = [
            [Output("/dp/thrusters/feedback", fb, 5)],
            [status(10, [], [], mode="standby")],
            [status(20, [stale, sat], ["dgps1: stale"], mode="standby")],
            [status(30, [stale, sat], [], mode="standby")],
            [status(40, [stale], ["dgps1: ok again"], mode="manual")],
            # a mode change with its event (who made it): said once, the event's words
            [status(50, [stale], ["mode: manual -> dp (operator)"], mode="dp")],
        ]
        for batch in batches:
            sink.emit(batch, [o.message.encode() for o in batch])
        wait_for(lambda: len(listener.of("log_message", "dpgw/log")) >= 7)
        wait_for(lambda: listener.of("moment_newton_meter", "dpgw/thrusters/feedback"))
        force = listener.of("force_newton", "dpgw/thrusters/feedback")[0]
        moment = listener.of("moment_newton_meter", "dpgw/thrusters/feedback")[0]
        assert force.timestamp.ToNanoseconds() == 5 and force.frame_id == "body"
        assert (force.vector.x, force.vector.y, force.vector.z) == (1000.5, -2000.25, 0.0)
        assert (moment.vector.x, moment.vector.y, moment.vector.z) == (0.0, 0.0, 30000.125)
        logs = [
            (m.timestamp.ToNanoseconds(), m.level, m.message) for m in listener.of("log_message", "dpgw/log")
        ]
        Log = type(listener.of("log_message", "dpgw/log")[0])
        assert logs == [
            (20, Log.WARNING, "dgps1: stale"),
            (20, Log.WARNING, "alarm: dgps1: position stale"),
            (20, Log.WARNING, "alarm: sat: thrust saturated"),
            (40, Log.WARNING, "dgps1: ok again"),
            (40, Log.INFO, "alarm cleared: sat: thrust saturated (up 0.0 s)"),  # (20 ns to 40 ns)
            (40, Log.INFO, "mode: standby -> manual"),
            (50, Log.INFO, "mode: manual -> dp (operator)"),
        ]
    finally:
        sink.close()


def test_keelson_config_errors_name_the_key(tmp_path: Path) -> None:
    t = tables(1, 2, entity_id="")
    with pytest.raises(ConfigError, match=r"keelson\.entity_id: missing"):
        parse_config(t, base_dir=tmp_path)


def test_a_missing_keelson_package_stops_start_up_with_one_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util

    config = parse_config(tables(1, 2), base_dir=tmp_path)
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "keelson" else real(name, *a)
    )
    problems = output_problems(config)
    assert len(problems) == 1 and "keelson.enabled" in problems[0] and "dpgw[keelson]" in problems[0]
    from gateway.outputs.build import OutputError

    with pytest.raises(OutputError, match="keelson package is not installed"):
        sinks_from_config(config)
    from dpgw.cli_run import start_up_problems  # `dpgw run --check` says it too

    assert [p for p in start_up_problems(config) if "keelson" in p] == problems


def test_keelson_log_follows_alarm_identity_and_state_severity_and_fixes_carry_nine_covariances(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """What a Keelson log or map consumer relies on:
    - an alarm whose text carries a growing figure ("stale (3.1 s without data)" → "(4.1 s …)") is the same
      alarm still active: raised once, not cleared and raised again at every status;
    - a reference state change has the severity of its new state (INFO back to ok, WARNING stale or
      suspect, ERROR rejected), as on dpgw's own `/dp/log`;
    - every `foxglove.LocationFix` has the 9 covariance entries Foxglove's schema requires (the estimate's
      and the measurement's are UNKNOWN, all zero), so a consumer indexing it (a NavSatFix bridge) works."""
    zport, server, client = loopback_sessions
    config = parse_config(tables(free_port(socket.SOCK_DGRAM), zport), base_dir=tmp_path)
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, KeelsonSink)
    try:
        listener = Listener(client)
        sink.start(server)
        wait_for(lambda: len(list(client.liveliness().get(f"{BASE}/@v0/{ENTITY}/pubsub/*/dpgw"))) == 1)

        ref = "position reference dgps1"
        est = Estimate(
            stamp_ns=5, observer="passive", status="ok", eta=[1.0, 2.0, 0.3], nu=[0.0, 0.0, 0.0],
            bias=[0.0, 0.0, 0.0], eta_wf=[0.0, 0.0, 0.0], omega0=[0.8, 0.8, 0.8], lat_deg=LAT,
            lon_deg=LON, heading_deg=17.2, datum=Datum(lat_deg=LAT, lon_deg=LON),
        )  # fmt: skip
        meas = Measurement(
            stamp_ns=5, eta=[1.0, 2.0, 0.3], valid=[True, True, True], sources=["dgps1"], quality=2,
            sigma_m=0.5, tau=[0.0, 0.0, 0.0], tau_source="command",
        )  # fmt: skip
        batches = [
            [Output("/dp/measurement", meas, 5), Output("/dp/estimate", est, 5)],
            [status(10, ["source dgps1: stale (3.1 s without data)"], [f"{ref}: ok -> stale: no data"])],
            [status(20, ["source dgps1: stale (4.1 s without data)"], [])],
            [status(30, ["source dgps1: stale (5.1 s without data)"], [f"{ref}: stale -> rejected: jump"])],
            [status(40, [], [f"{ref}: rejected -> suspect", f"{ref}: suspect -> ok"])],
        ]
        for batch in batches:
            sink.emit(batch, [o.message.encode() for o in batch])
        wait_for(  # the last line: a log's lines arrive in order (one publisher)
            lambda: any(
                m.timestamp.ToNanoseconds() == 40 and m.message.startswith("alarm cleared")
                for m in listener.of("log_message", "dpgw")
            )
        )
        wait_for(lambda: listener.of("location_fix", "dpgw/measurement"))
        logs = [(m.timestamp.ToNanoseconds(), m.level, m.message) for m in listener.of("log_message", "dpgw")]
        Log = type(listener.of("log_message", "dpgw")[0])
        assert logs == [
            (10, Log.WARNING, f"{ref}: ok -> stale: no data"),
            (10, Log.WARNING, "alarm: source dgps1: stale (3.1 s without data)"),
            (30, Log.ERROR, f"{ref}: stale -> rejected: jump"),
            (40, Log.WARNING, f"{ref}: rejected -> suspect"),
            (40, Log.INFO, f"{ref}: suspect -> ok"),
            (40, Log.INFO, "alarm cleared: source dgps1: stale (5.1 s without data) (up 0.0 s)"),
        ]
        for sid in ("dpgw/estimate", "dpgw/measurement"):
            (fix,) = listener.of("location_fix", sid)
            assert list(fix.position_covariance) == [0.0] * 9
            assert fix.position_covariance_type == fix.UNKNOWN
    finally:
        sink.close()
