"""Foxglove-native channels in a demo log, channel by channel: each decodes with the JSON schema it
carries, and holds what the JSON channels hold (GGA's altitude, GST's covariance, the estimate's heading
and pose, the measurement's pose, the commanded thrust, the status events). Plus the frame conventions,
the alarm log and the setpoint scene on the pipeline directly, and the field layout against Foxglove's own
schema definitions (from the foxglove-sdk package, when installed)."""

from __future__ import annotations

import itertools
import json
import math
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from jsonschema import Draft202012Validator

from gateway.foxglove_channels import POSE_PERIOD_NS, AlarmChanges, FoxgloveChannels, alarm_key
from gateway.pipeline import RawEvent
from gateway.replay import config_from_log
from tests.test_pipeline import T0, S, gga_at, nmea_src, pipeline
from wire import foxglove as fx
from wire.codecs import nmea
from wire.codecs import nmea_encode as enc
from wire.gst_covariance import ellipse_covariance_ne
from wire.mcap.reader import read_messages, summary
from wire.message_schema import json_schema
from wire.messages import ANY, MESSAGES, message_for_topic

HDT = enc.hdt("HE", 0.1).encode()

FOXGLOVE_TOPICS = {
    "/dp/estimate/fix": "foxglove.LocationFix",
    "/gnss/dgps1/fix": "foxglove.LocationFix",
    "/dp/tf": "foxglove.FrameTransforms",
    "/dp/estimate/pose": "foxglove.PoseInFrame",
    "/dp/measurement/pose": "foxglove.PoseInFrame",
    "/dp/scene/hull": "foxglove.SceneUpdate",
    "/dp/scene/thrusters": "foxglove.SceneUpdate",
    "/dp/scene/setpoint": "foxglove.SceneUpdate",
    "/dp/log": "foxglove.Log",
}


@pytest.fixture(scope="module")
def demo_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fxdemo") / "demo.mcap"
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "40", "--speed", "10", "--out", str(out),
         "--engage-at", "5", "--json", "--no-scouting", "--zenoh-listen", f"tcp/127.0.0.1:{port}"],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return out


def _by_topic(path: Path) -> dict[str, list[tuple[int, dict[str, Any]]]]:
    out: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    for topic, log_ns, _, payload in read_messages(path):
        out.setdefault(topic, []).append((log_ns, payload))
    return out


def _ns(t: dict[str, int]) -> int:
    return t["sec"] * S + t["nsec"]


def _yaw(q: dict[str, float]) -> float:
    assert q["x"] == 0.0 and q["y"] == 0.0  # a yaw about +z only
    return 2.0 * math.atan2(q["z"], q["w"])


def _same_angle(a: float, b: float) -> bool:
    return abs(math.remainder(a - b, 2 * math.pi)) < 1e-9


@pytest.mark.slow  # a 40 s demo at 10x, ~10 s
def test_every_foxglove_channel_decodes_with_the_schema_it_carries(demo_log: Path) -> None:
    info = summary(demo_log)
    msgs = _by_topic(demo_log)
    for topic, schema_name in FOXGLOVE_TOPICS.items():
        channel = info.channels[topic]
        assert channel.schema_name == schema_name and channel.message_encoding == "json"
        assert channel.message_count > 0, topic
        validator = Draft202012Validator(info.schemas[schema_name])
        for _, payload in msgs[topic]:
            errors = list(validator.iter_errors(payload))
            assert not errors, (topic, errors[0].message)


@pytest.mark.slow
def test_gnss_fixes_hold_gga_altitude_and_gst_covariance(demo_log: Path) -> None:
    timeout_ns = int(config_from_log(demo_log).sources[0].timeout_s * S)
    # what each GGA's fix must hold, from the raw sentences in the order the gateway took them
    expected: dict[int, tuple[float, list[float], int]] = {}
    gst: tuple[int, nmea.Gst] | None = None
    for _, log_ns, _, raw in read_messages(demo_log, "/raw/nmea/dgps1"):
        for text in raw["text"].splitlines():
            s = nmea.decode(text)
            if isinstance(s, nmea.Gst):
                gst = (log_ns, s)
            elif isinstance(s, nmea.Gga) and s.valid and log_ns not in expected:
                cov, kind = [0.0] * 9, 0
                if gst is not None and log_ns - gst[0] <= timeout_ns:
                    g = gst[1]
                    # the simulator's receiver draws a circle: its ellipse, a known covariance (type 3)
                    # with no east-north term, and the marginals its σ lat / lon
                    nn, ne, ee = ellipse_covariance_ne(g.sigma_major_m, g.sigma_minor_m, g.orient_rad)
                    assert (nn, ee) == pytest.approx((g.sigma_lat_m**2, g.sigma_lon_m**2), rel=1e-2)
                    assert g.sigma_alt_m is not None  # (else the up variance is approximated, type 1)
                    cov, kind = [ee, ne, 0, ne, nn, 0, 0, 0, g.sigma_alt_m**2], 3
                alt = (s.alt_m or 0.0) + (s.geoid_sep_m or 0.0)
                expected[log_ns] = (alt, cov, kind)
    fixes = list(read_messages(demo_log, "/gnss/dgps1/fix"))
    gga_stamps = sorted(expected)
    # every fix: one for each GGA the gateway took (those after the datum was set)
    assert [_ns(f["timestamp"]) for _, _, _, f in fixes] == gga_stamps[len(gga_stamps) - len(fixes) :]
    assert len(fixes) >= 60  # a 40 s demo, DGPS at 2 Hz
    with_cov = 0
    for _, log_ns, _, fix in fixes:
        alt, cov, kind = expected[_ns(fix["timestamp"])]
        assert log_ns == _ns(fix["timestamp"])
        assert fix["altitude"] == pytest.approx(alt, abs=1e-9) and alt > 1.0  # the demo's antenna height
        assert fix["position_covariance"] == pytest.approx(cov)
        assert fix["position_covariance_type"] == kind
        assert "heading" not in fix  # a GNSS fix has no heading of its own
        assert fix["frame_id"] == "dgps1"  # the receiver's antenna
        with_cov += fix["position_covariance_type"] == 3
    assert with_cov >= len(fixes) - 2  # every fix after the first GST
    # the antenna's frame: vessel -> dgps1 at the configured lever arm, x forward, y port, z up (FLU)
    arm = config_from_log(demo_log).sources[0].lever_arm_m
    antennas = [
        t
        for _, _, _, tf in read_messages(demo_log, "/dp/tf")
        for t in tf["transforms"]
        if t["child_frame_id"] == "dgps1"
    ]
    assert len(antennas) >= 4  # with the first estimate, then every 10 s: 40 s
    for t in antennas:
        assert t["parent_frame_id"] == "vessel"
        assert (t["translation"]["x"], t["translation"]["y"], t["translation"]["z"]) == (
            arm[0],
            -arm[1],
            -arm[2],
        )
        assert t["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert any(arm)  # (the demo's antenna is off the reference point; the signs: tests/test_foxglove.py)


@pytest.mark.slow
def test_estimate_fix_pose_and_frame_are_the_estimate(demo_log: Path) -> None:
    # A feed's outputs are logged in order: the measurements and estimates, then what mirrors them; so each
    # Foxglove message is checked against the JSON estimate and measurement of its own stamp logged before
    # it. (Not simply the last one: a chunk that held two gyro cycles, on a busy machine, steps twice, and
    # the first step's mirror follows the second step's estimate.)
    est: dict[int, dict[str, Any]] = {}
    meas: dict[int, dict[str, Any]] = {}
    est_stamps: list[int] = []
    pose_stamps: list[int] = []
    fix_stamps: list[int] = []
    for topic, _, _, p in read_messages(demo_log):
        if topic == "/dp/estimate":
            est[p["stamp_ns"]] = p
            est_stamps.append(p["stamp_ns"])
        elif topic == "/dp/measurement":
            meas[p["stamp_ns"]] = p
        elif topic == "/dp/estimate/fix":
            e_ = est[_ns(p["timestamp"])]
            assert (p["latitude"], p["longitude"]) == (e_["lat_deg"], e_["lon_deg"])
            assert p["heading"] == e_["eta"][2]
            fix_stamps.append(e_["stamp_ns"])
        elif topic == "/dp/estimate/pose":
            e_ = est[_ns(p["timestamp"])]
            n, e, psi = e_["eta"]
            pose = p["pose"]
            assert p["frame_id"] == "ltp"
            assert (pose["position"]["x"], pose["position"]["y"], pose["position"]["z"]) == (e, n, 0.0)  # ENU
            assert _same_angle(_yaw(pose["orientation"]), math.pi / 2 - psi)
            pose_stamps.append(e_["stamp_ns"])
        elif topic == "/dp/measurement/pose":
            n, e, psi = meas[_ns(p["timestamp"])]["eta"]
            pose = p["pose"]
            assert (pose["position"]["x"], pose["position"]["y"]) == (e, n)
            assert _same_angle(_yaw(pose["orientation"]), math.pi / 2 - psi)
        elif topic == "/dp/tf":
            if all(t["parent_frame_id"] == "vessel" for t in p["transforms"]):
                continue  # (the antennas' frames, with the hull: test_gnss_fixes_hold_...)
            first, *measured = p["transforms"]
            assert (first["parent_frame_id"], first["child_frame_id"]) == ("ltp", "vessel")
            n, e, psi = est[_ns(first["timestamp"])]["eta"]
            assert (first["translation"]["x"], first["translation"]["y"]) == (e, n)
            assert _same_angle(_yaw(first["rotation"]), math.pi / 2 - psi)
            for t in measured:
                m = meas[_ns(t["timestamp"])]
                assert t["child_frame_id"] == "vessel_measured"
                assert (t["translation"]["x"], t["translation"]["y"]) == (m["eta"][1], m["eta"][0])
    assert len(pose_stamps) > 150 and fix_stamps == pose_stamps  # the map and the 3D panel: the same
    gaps = [b - a for a, b in itertools.pairwise(pose_stamps)]
    assert min(gaps) >= POSE_PERIOD_NS  # at most ~5 Hz ...
    # ... and no estimate left out for longer than that, but by the estimate's own gaps
    assert max(gaps) <= POSE_PERIOD_NS + max(b - a for a, b in itertools.pairwise(est_stamps))


@pytest.mark.slow
def test_scene_holds_hull_commanded_thrust_and_setpoint(demo_log: Path) -> None:
    msgs = _by_topic(demo_log)
    config = config_from_log(demo_log)
    commands = {p["stamp_ns"]: p for _, p in msgs["/dp/thrusters/command"]}
    arrows = [u["entities"][0] for _, u in msgs["/dp/scene/thrusters"]]
    commanded = [a for a in arrows if a["id"] == "thrusters/command"]
    assert len(commanded) == len(commands)  # one scene per command
    assert any(a["id"] == "thrusters/feedback" for a in arrows)
    for ent in commanded:
        cmd = commands[_ns(ent["timestamp"])]
        assert ent["frame_id"] == "vessel" and len(ent["arrows"]) == len(cmd["thrusters"])
        for arrow, th in zip(ent["arrows"], cmd["thrusters"], strict=True):
            yaw = _yaw(arrow["pose"]["orientation"])
            want = -th["azimuth_rad"] + (math.pi if th["thrust_n"] < 0 else 0.0)
            if th["thrust_n"] != 0.0:
                assert _same_angle(yaw, want)
    (hull, *_) = [u["entities"][0] for _, u in msgs["/dp/scene/hull"]]
    assert hull["frame_id"] == "vessel" and hull["frame_locked"]
    xs = [p["x"] for p in hull["lines"][0]["points"]]
    assert max(xs) - min(xs) == pytest.approx(config.vessel.length_m)
    # the demo holds its station: the setpoint it sent, with the watch circles around it
    (sent,) = [p for _, p in msgs["/dp/setpoint"]]
    scene = msgs["/dp/scene/setpoint"][-1][1]["entities"][0]
    tip = scene["arrows"][0]["pose"]["position"]
    if "north_m" in sent:
        assert (tip["x"], tip["y"]) == pytest.approx((sent["east_m"], sent["north_m"]), abs=0.5)
    radii = sorted(
        math.hypot(ln["points"][0]["x"] - tip["x"], ln["points"][0]["y"] - tip["y"]) for ln in scene["lines"]
    )
    assert radii == pytest.approx([5.0, 10.0])


@pytest.mark.slow
def test_log_holds_every_status_event(demo_log: Path) -> None:
    msgs = _by_topic(demo_log)
    events = [e for _, s in msgs["/dp/status"] for e in s.get("events", [])]
    logged = [p["message"] for _, p in msgs["/dp/log"] if p["name"] == "dpgw.reference"]
    assert events and logged == events


# --- the pipeline directly ---------------------------------------------------------------------------------


def test_frames_are_enu_and_flu() -> None:
    # heading east (ψ = 90°): the ENU yaw is 0, the vessel's x axis points along the world's x (east)
    t = fx.frame_transform(T0, "vessel", 10.0, 20.0, math.pi / 2)
    assert (t.translation.x, t.translation.y, t.translation.z) == (20.0, 10.0, 0.0)
    assert _same_angle(2 * math.atan2(t.rotation.z, t.rotation.w), 0.0)
    # a thruster on the starboard side (y stbd 3 m) pushing to starboard (α = 90°): at y = -3 in FLU,
    # pointing at -y (yaw -90°); reversed thrust points the other way
    a = fx.thrust_arrow(5.0, 3.0, 1000.0, math.pi / 2, 2000.0, 10.0, fx.color(1, 1, 1))
    assert (a.pose.position.x, a.pose.position.y) == (5.0, -3.0)
    assert _same_angle(2 * math.atan2(a.pose.orientation.z, a.pose.orientation.w), -math.pi / 2)
    assert a.shaft_length + a.head_length == pytest.approx(5.0)  # half thrust: half the scale
    r = fx.thrust_arrow(5.0, 3.0, -1000.0, math.pi / 2, 2000.0, 10.0, fx.color(1, 1, 1))
    assert _same_angle(2 * math.atan2(r.pose.orientation.z, r.pose.orientation.w), math.pi / 2)


def test_alarm_logged_once_when_raised_and_once_when_cleared() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=1.0)])
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + HDT))
    logs: list[dict[str, Any]] = []
    for k in range(2, 6):  # the source is stale from 1 s on; its age grows, the alarm stays the same
        logs += [o.payload for o in p.status_outputs(T0 + k * S) if o.topic == "/dp/log"]
        logs += [o.payload for o in p.tick(T0 + k * S + 1) if o.topic == "/dp/log"]
    # back: the state change's status (made inside the feed) carries the cleared alarm and the event
    logs += [
        o.payload for o in p.feed(RawEvent(T0 + 6 * S, "gps", gga_at(0.0, 0.0) + HDT)) if o.topic == "/dp/log"
    ]
    logs += [o.payload for o in p.status_outputs(T0 + 6 * S) if o.topic == "/dp/log"]
    logs += [o.payload for o in p.tick(T0 + 6 * S + 1) if o.topic == "/dp/log"]
    # (the source's alarm: the estimate's own, dead reckoning while the source is silent, is another)
    alarms = [x for x in logs if x["name"] == "dpgw.alarm" and "source gps" in x["message"]]
    assert [x["level"] for x in alarms] == [3, 2]  # WARNING raised, INFO cleared
    assert alarms[0]["message"].startswith("alarm: source gps: stale")
    assert alarms[1]["message"].startswith("alarm cleared: source gps: stale")
    events = [(x["level"], x["message"]) for x in logs if x["name"] == "dpgw.reference"]
    assert [lvl for lvl, _ in events] == [3, 3, 2, 2]  # stale: WARNING; back to ok: INFO
    assert events[0][1] == "position reference gps: ok -> stale: no data for 2.0 s"


def test_alarms_of_sources_named_apart_by_digits_are_two_alarms() -> None:
    """The digits of a name are no value to mask: two sources stale are two alarms raised, and one of them
    cleared is that one cleared; a value changing is still the same alarm."""
    log = AlarmChanges()
    raised, cleared = log.update(
        ["source dgps1: stale (3.1 s without data)", "source dgps2: stale (2.9 s without data)"]
    )
    assert raised == ["source dgps1: stale (3.1 s without data)", "source dgps2: stale (2.9 s without data)"]
    assert cleared == []
    # a second on: the same two alarms, nothing raised or cleared
    assert log.update(
        ["source dgps1: stale (4.1 s without data)", "source dgps2: stale (3.9 s without data)"]
    ) == ([], [])
    # dgps1 back: dgps1's alarm cleared (with its last text), dgps2's still up
    assert log.update(["source dgps2: stale (4.9 s without data)"]) == (
        [],
        ["source dgps1: stale (4.1 s without data)"],
    )


def test_start_up_clears_only_the_no_data_alarms_that_were_raised() -> None:
    log = AlarmChanges()
    raised, _ = log.update(["source dgps1: no data yet", "source dgps2: no data yet"])
    assert raised == ["source dgps1: no data yet", "source dgps2: no data yet"]
    assert log.update(["source dgps1: no data yet"]) == ([], ["source dgps2: no data yet"])
    assert log.update([]) == ([], ["source dgps1: no data yet"])


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("thruster 1 out of DP (drive fault)", "thruster 2 out of DP (drive fault)"),
        ("heading reference gyro1: suspect (jump)", "heading reference gyro2: suspect (jump)"),
        ("source gps_2: stale (3.0 s without data)", "source gps_3: stale (3.0 s without data)"),
        ("device /dev/ttyUSB0: disconnected", "device /dev/ttyUSB1: disconnected"),
        (
            "consequence analysis: after losing thrusters 1, 2 the rest would need 90 % of their thrust",
            "consequence analysis: after losing thrusters 1, 3 the rest would need 90 % of their thrust",
        ),
    ],
)
def test_names_with_digits_are_different_alarms(a: str, b: str) -> None:
    assert alarm_key(a) != alarm_key(b)


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("source dgps1: stale (3.1 s without data)", "source dgps1: stale (4.1 s without data)"),
        ("DP waits for the observer to settle: 88 s left", "DP waits for the observer to settle: 87 s left"),
        (
            "thrust allocation saturated: demand τ = [1.2e+05 N, 0 N, -3 N·m] not achievable, shortfall "
            "[-3.82e+04 N, 0 N, 0 N·m]",
            "thrust allocation saturated: demand τ = [1.3e+05 N, 0 N, -4 N·m] not achievable, shortfall "
            "[-2.1e+04 N, 1 N, 0 N·m]",
        ),
        ("position 6.2 m off the DP reference", "position 16 m off the DP reference"),
    ],
)
def test_values_changing_are_the_same_alarm(a: str, b: str) -> None:
    assert alarm_key(a) == alarm_key(b)


def test_two_stale_sources_both_alarmed_on_dp_log() -> None:
    """On the pipeline: dgps1 and dgps2 both stale, /status lists both and /dp/log raises both; neither
    is said cleared before it was raised."""
    p = pipeline(
        [
            nmea_src("dgps1", ["position", "heading"], timeout_s=1.0),
            nmea_src("dgps2", ["position"], timeout_s=1.0, priority=2),
        ]
    )
    logs: list[str] = []
    for name in ("dgps1", "dgps2"):
        p.feed(RawEvent(T0, name, gga_at(0.0, 0.0) + HDT))
    for k in range(2, 5):
        logs += [o.payload["message"] for o in p.status_outputs(T0 + k * S) if o.topic == "/dp/log"]
    alarms = [m for m in logs if m.startswith("alarm")]
    assert sorted(m.split(": stale")[0] for m in alarms) == ["alarm: source dgps1", "alarm: source dgps2"]


def test_setpoint_scene_follows_dp_and_is_deleted_outside_it() -> None:
    ch = FoxgloveChannels(
        pipeline([nmea_src("gps", ["position", "heading"])]).spec.vessel, watch_circles_m=(3.0, 6.0)
    )
    (first,) = ch.setpoint((10.0, -5.0, 0.0), T0)
    assert first[0] == "/dp/scene/setpoint" and len(first[1].entities[0].lines) == 2  # type: ignore[attr-defined]
    assert ch.setpoint((10.0, -5.0, 0.0), T0 + S) == []  # unchanged: not repeated before its period
    assert len(ch.setpoint((10.0, -5.0, 0.0), T0 + 11 * S)) == 1  # repeated for a player that seeks
    (gone,) = ch.setpoint(None, T0 + 12 * S)
    assert gone[1].deletions[0].id == "setpoint"  # type: ignore[attr-defined]
    assert ch.setpoint(None, T0 + 13 * S) == []


# --- the field layout against Foxglove's own definitions -----------------------------------------------


def _proto_fields(name: str) -> dict[str, Any]:
    """Foxglove's definition of message ``name`` (e.g. foxglove.SceneUpdate): field name → nested fields
    (a dict) or None, from the protobuf descriptors the foxglove-sdk package ships."""
    messages = pytest.importorskip("foxglove.messages")
    descriptor_pb2 = pytest.importorskip("google.protobuf.descriptor_pb2")
    cls = getattr(messages, name.removeprefix("foxglove."))
    fds = descriptor_pb2.FileDescriptorSet.FromString(cls.get_schema().data)
    types = {f"{fd.package}.{m.name}": m for fd in fds.file for m in fd.message_type}

    def fields(type_name: str) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for f in types[type_name].field:
            nested = f.type_name.lstrip(".")
            out[f.name] = fields(nested) if nested in types and nested.startswith("foxglove.") else None
        return out

    return fields(name)


def _schema_fields(schema: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, sub in schema.get("properties", {}).items():
        sub = sub.get("items", sub)
        nested = sub.get("properties")
        is_time = sub.get("title") in ("time", "duration")  # Foxglove's JSON time; a Timestamp in protobuf
        out[name] = _schema_fields(sub) if nested is not None and not is_time else None
    return out


OPTIONAL_LEFT_OUT = {"foxglove.LocationFix": {"color", "metadata", "velocity"}}
"""Optional fields of newer Foxglove versions that dpgw leaves out (docs/foxglove.md)."""


@pytest.mark.parametrize("cls", [m for m in MESSAGES if m.FOXGLOVE], ids=lambda m: m.TITLE)
def test_field_layout_is_foxglove_s(cls: Any) -> None:
    ours, theirs = _schema_fields(json_schema(cls)), _proto_fields(cls.TITLE)
    for name in OPTIONAL_LEFT_OUT.get(cls.TITLE, set()):
        theirs.pop(name, None)
    assert ours == theirs


# --- the layout file ---------------------------------------------------------------------------------------

LAYOUT = Path(__file__).resolve().parents[1] / "dpgw" / "foxglove-layout.json"


def test_the_demo_points_at_the_layout_the_package_ships() -> None:
    from dpgw.cli_foxglove import layout_path

    assert Path(layout_path()) == LAYOUT and LAYOUT.is_file()


def test_layout_names_only_channels_and_fields_dpgw_writes() -> None:
    layout = json.loads(LAYOUT.read_text())
    panels = layout["configById"]
    assert {k.split("!")[0] for k in panels} == {"3D", "map", "Plot", "RosOut"}
    topics: set[str] = set(panels["3D!dpgw"]["topics"]) | set(panels["map!dpgw"]["topicColors"])
    topics.add(panels["RosOut!dpgw"]["topicToRender"])
    for key, panel in panels.items():
        if key.startswith("Plot!"):
            for p in panel["paths"]:
                topic, _, path = p["value"].partition(".")
                field = path.split("[")[0].split(".")[0]
                assert field in json_schema(message_for_topic(topic))["properties"], p["value"]
                topics.add(topic)
    for topic in topics:
        assert message_for_topic(topic) is not ANY, topic
    assert panels["3D!dpgw"]["followTf"] == fx.VESSEL_FRAME
