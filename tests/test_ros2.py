"""ROS 2 through rmw_zenoh: what dpgw puts on Zenoh is what an rmw_zenoh node would, checked without ROS.

- The formats against rmw_zenoh's own examples (its docs/design.md gives keys and liveliness tokens of
  the demo nodes verbatim) and against the published RIHS01 hashes of the ROS 2 Jazzy types.
- The attachment against Zenoh's own deserializer (`zenoh.ext.z_deserialize`), not our parser.
- A live gateway on loopback: a Zenoh subscriber on ``<domain>/**`` and a liveliness query on
  ``@ros2_lv/**`` see every key, attachment and token in that format, rosbags decodes every payload to the
  pipeline's values, and a PoseStamped published from here arrives as the same dpgw setpoint (one in a
  wrong frame is refused and counted).
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections import defaultdict
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rosbags")
pytest.importorskip("xxhash")

import xxhash
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st
from zenoh.ext import Int64, z_deserialize, z_serialize

from gateway.bus import isolated_config, open_session
from gateway.config import ConfigError, parse_config
from gateway.outputs import InputSink, RawSentenceSink
from gateway.outputs.build import output_problems, sinks_from_config
from gateway.outputs.ros2 import Ros2Sink, navsat_status, ros_typestore, setpoint_payload
from gateway.pipeline import Output
from gateway.service import GatewayService
from tests.conftest import Recorder, free_port, wait_for
from wire import rmw_zenoh as rz
from wire.codecs import nmea_encode as enc
from wire.gst_covariance import ellipse_covariance_ne
from wire.messages import Estimate, LocationFix, Time

# RIHS01 hashes as ROS 2 Jazzy publishes them (rosidl's generated type descriptions; std_msgs/String is
# also the one rmw_zenoh's design document shows in its keys)
PUBLISHED_HASHES = {
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "nav_msgs/msg/Odometry": "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    "sensor_msgs/msg/NavSatFix": "RIHS01_62223ab3fe210a15976021da7afddc9e200dc9ec75231c1b6a557fc598a65404",
    "geometry_msgs/msg/PoseStamped": (
        "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"
    ),
    # (TFMessage's as `ros2 topic info -v /tf` shows it on Jazzy; DiagnosticArray's as other ROS 2
    # implementations of Jazzy's interfaces hard-code it)
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "diagnostic_msgs/msg/DiagnosticArray": (
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e"
    ),
}
STRING_HASH = PUBLISHED_HASHES["std_msgs/msg/String"]
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"

LAT, LON, ALT, SEP = 59.4, 10.5, 20.0, 35.5
# the receiver's error ellipse: 0.5 m by 0.2 m, its major axis 30° east of north; σ lat / lon its marginals
SIGMA_MAJOR, SIGMA_MINOR, ORIENT_DEG = 0.5, 0.2, 30.0
SIGMA_LAT, SIGMA_LON, SIGMA_ALT = 0.444, 0.304, 0.9
C_NN, C_NE, C_EE = ellipse_covariance_ne(SIGMA_MAJOR, SIGMA_MINOR, math.radians(ORIENT_DEG))
ENU_COVARIANCE = [C_EE, C_NE, 0, C_NE, C_NN, 0, 0, 0, SIGMA_ALT**2]  # east, north, up; row-major
DOMAIN = 7
ODOM_KEY = f"{DOMAIN}/dpgw/odom/nav_msgs::msg::dds_::Odometry_/{PUBLISHED_HASHES['nav_msgs/msg/Odometry']}"
POSE_KEY = (
    f"{DOMAIN}/dpgw/pose/geometry_msgs::msg::dds_::PoseStamped_/"
    + PUBLISHED_HASHES["geometry_msgs/msg/PoseStamped"]
)
FIX_KEY = (
    f"{DOMAIN}/dpgw/fix/dgps1/sensor_msgs::msg::dds_::NavSatFix_/"
    + PUBLISHED_HASHES["sensor_msgs/msg/NavSatFix"]
)
DIAGNOSTICS_KEY = (
    f"{DOMAIN}/diagnostics/diagnostic_msgs::msg::dds_::DiagnosticArray_/"
    + PUBLISHED_HASHES["diagnostic_msgs/msg/DiagnosticArray"]
)
TF_KEY = f"{DOMAIN}/tf/tf2_msgs::msg::dds_::TFMessage_/" + PUBLISHED_HASHES["tf2_msgs/msg/TFMessage"]
TF_STATIC_KEY = (
    f"{DOMAIN}/tf_static/tf2_msgs::msg::dds_::TFMessage_/" + PUBLISHED_HASHES["tf2_msgs/msg/TFMessage"]
)
SETPOINT_KEY = (
    f"{DOMAIN}/dpgw/setpoint/geometry_msgs::msg::dds_::PoseStamped_/"
    + PUBLISHED_HASHES["geometry_msgs/msg/PoseStamped"]
)


# --- the formats, against rmw_zenoh's documented examples ------------------------------------------------


def test_rosbags_gives_the_published_rihs01_hashes() -> None:
    store = ros_typestore()
    for ros_type, published in PUBLISHED_HASHES.items():
        assert store.hash_rihs01(ros_type) == published, ros_type


def test_topic_keys_are_rmw_zenohs() -> None:
    # docs/design.md, "Topic and Service name mapping to Zenoh key expressions"
    assert (
        rz.topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH)
        == "0/chatter/std_msgs::msg::dds_::String_/" + STRING_HASH
    )
    assert (
        rz.topic_key(0, rz.fully_qualified("/robot1", "chatter"), "std_msgs/msg/String", STRING_HASH)
        == "0/robot1/chatter/std_msgs::msg::dds_::String_/" + STRING_HASH
    )
    assert (
        rz.topic_key(2, "/add_two_ints", "example_interfaces/srv/AddTwoInts", ADD_TWO_INTS_HASH)
        == "2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/" + ADD_TWO_INTS_HASH
    )
    assert rz.ros_type_name("nav_msgs::msg::dds_::Odometry_") == "nav_msgs/msg/Odometry"
    assert rz.fully_qualified("/dpgw", "/abs") == "/abs" and rz.fully_qualified("/", "odom") == "/odom"


def test_liveliness_tokens_are_rmw_zenohs() -> None:
    # docs/design.md, "Graph Cache": the demo nodes' tokens, verbatim
    assert (
        rz.node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "/", "listener")
        == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    )
    listener = rz.entity_token(
        2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, 10, rz.SUBSCRIPTION, "/", "listener", "/chatter",
        "std_msgs/msg/String", STRING_HASH, rz.Qos(depth=10),
    )  # fmt: skip
    assert listener == (
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::"
        f"String_/{STRING_HASH}/::,10:,:,:,,"
    )
    talker = rz.entity_token(
        2, "8b20917502ee955ac4476e0266340d5c", 0, 10, rz.PUBLISHER, "/", "talker", "/chatter",
        "std_msgs/msg/String", STRING_HASH, rz.Qos(depth=7),
    )  # fmt: skip
    assert talker == (
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::"
        f"String_/{STRING_HASH}/::,7:,:,:,,"
    )
    t = rz.parse_token(talker)
    assert (t.domain_id, t.kind, t.namespace, t.node, t.topic, t.qos) == (
        2, "MP", "/", "talker", "/chatter", "::,7:,:,:,,",
    )  # fmt: skip
    # non-default QoS fields are the rmw enum numbers: best effort 2, transient local 1, keep all 2
    assert rz.Qos(rz.BEST_EFFORT, rz.TRANSIENT_LOCAL, rz.KEEP_ALL, 42).keyexpr() == "2:1:2,:,:,:,,"
    for bad in ("@ros2_lv/0/z/0/0/XX/%/%/n", "@other/0/z/0/0/NN/%/%/n", "@ros2_lv/0/z/0/0/MP/%/%/n"):
        with pytest.raises(ValueError):
            rz.parse_token(bad)


@settings(max_examples=200, deadline=None)
@given(
    seq=st.integers(-(2**63), 2**63 - 1),
    stamp=st.integers(-(2**63), 2**63 - 1),
    gid=st.binary(min_size=16, max_size=16),
)
def test_the_attachment_is_zenohs_serialization(seq: int, stamp: int, gid: bytes) -> None:
    data = rz.attachment(seq, stamp, gid)
    assert len(data) == 33  # docs/design.md: 8 + 8 + 1 (the GID's length) + 16
    assert data == z_serialize((Int64(seq), Int64(stamp), gid)).to_bytes()
    assert z_deserialize(tuple[Int64, Int64, bytes], zenoh.ZBytes(data)) == (seq, stamp, gid)
    assert rz.parse_attachment(data) == (seq, stamp, gid)
    with pytest.raises(ValueError):
        rz.parse_attachment(data[:-1])


def test_the_gid_is_xxh3_128_of_the_token_low_half_first() -> None:
    token = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MP/%/%/talker/%chatter/x/y/::,7:,:,:,,"
    h = xxhash.xxh3_128(token.encode())
    low, high = h.intdigest() & (2**64 - 1), h.intdigest() >> 64
    assert rz.entity_gid(token) == low.to_bytes(8, "little") + high.to_bytes(8, "little")
    assert rz.entity_gid(token) == h.digest()[::-1]  # (the canonical digest is big-endian)


@settings(max_examples=300, deadline=None)
@given(
    north=st.floats(-1e4, 1e4),
    east=st.floats(-1e4, 1e4),
    heading=st.floats(0.0, 359.999),
    scale=st.floats(0.1, 10.0),
)
def test_a_pose_stamped_in_enu_is_the_same_ned_setpoint(
    north: float, east: float, heading: float, scale: float
) -> None:
    """(x, y) = (E, N) and yaw = π/2 − ψ, for any quaternion scale (an unnormalised one is a rotation)."""
    store = ros_typestore()
    msg = pose_stamped(store, "ltp", east, north, heading, scale)
    sp = setpoint_payload(store.deserialize_cdr(store.serialize_cdr(msg, rz_pose()), rz_pose()), "ltp")
    assert isinstance(sp, dict)
    assert sp["north_m"] == north and sp["east_m"] == east
    assert math.cos(math.radians(sp["heading_deg"] - heading)) == pytest.approx(1.0, abs=1e-12)
    assert 0.0 <= sp["heading_deg"] < 360.0
    assert isinstance(setpoint_payload(msg, "map"), str)


def test_setpoints_that_are_none_are_refused_with_their_reason() -> None:
    store = ros_typestore()
    assert str(setpoint_payload(pose_stamped(store, "map", 1, 2, 3), "ltp")).startswith("wrong frame: ")
    zero = pose_stamped(store, "ltp", 1, 2, 3, scale=0.0)
    assert str(setpoint_payload(zero, "ltp")).startswith("invalid orientation: ")


# --- a live gateway ------------------------------------------------------------------------------------


def rz_pose() -> str:
    return "geometry_msgs/msg/PoseStamped"


def pose_stamped(
    store: Any, frame: str, east: float, north: float, heading_deg: float, scale: float = 1.0
) -> Any:
    t = store.types
    yaw = math.pi / 2 - math.radians(heading_deg)
    return t[rz_pose()](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=1, nanosec=2), frame_id=frame
        ),
        pose=t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=east, y=north, z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=scale * math.sin(yaw / 2), w=scale * math.cos(yaw / 2)
            ),
        ),
    )


class RosListener:
    """An rmw_zenoh peer without ROS: every sample on the domain, its attachment decoded by Zenoh's own
    deserializer, its payload by rosbags."""

    def __init__(self, session: Any, store: Any) -> None:
        self.store = store
        self.lock = threading.Lock()
        self.got: dict[str, list[tuple[int, int, bytes, Any]]] = defaultdict(list)
        self.bad: list[str] = []
        self.sub = session.declare_subscriber(f"{DOMAIN}/**", self._on)

    def _on(self, sample: Any) -> None:
        key = str(sample.key_expr)
        try:
            ros_type = rz.ros_type_name(key.split("/")[-2])
            assert sample.attachment is not None, "no attachment"
            seq, stamp, gid = z_deserialize(tuple[Int64, Int64, bytes], sample.attachment)
            msg = self.store.deserialize_cdr(sample.payload.to_bytes(), ros_type)
        except Exception as exc:  # (a callback's exception would be lost: keep it for the test)
            with self.lock:
                self.bad.append(f"{key}: {exc!r}")
            return
        with self.lock:
            self.got[key].append((seq, stamp, gid, msg))

    def of(self, key: str) -> list[tuple[int, int, bytes, Any]]:
        with self.lock:
            return list(self.got[key])


def tables(udp: int, zport: int, **ros2: Any) -> dict[str, Any]:
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
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"], "multicast_scouting": False, "prefix": "dp/r"},
        "status": {"rate_hz": 10.0},
        "log": {"path": ""},
        "commands": {"accept": ["mode", "setpoint"]},
        "ros2": {"enabled": True, "domain_id": DOMAIN, **ros2},
    }


def sentences(k: int) -> list[str]:
    """One second of a DGPS (quality 2) with a gyro: GGA, GST, HDT; the heading swings so ν lives."""
    t = datetime.now(UTC)
    return [
        enc.gga("GP", t, LAT + 2e-6 * math.sin(k / 5), LON, 2, 12, 0.8, ALT, SEP).rstrip("\r\n"),
        enc.gst(
            "GP", t, rms_m=0.5, sigma_major_m=SIGMA_MAJOR, sigma_minor_m=SIGMA_MINOR,
            orient_rad=math.radians(ORIENT_DEG),
            sigma_lat_m=SIGMA_LAT, sigma_lon_m=SIGMA_LON, sigma_alt_m=SIGMA_ALT,
        ).rstrip("\r\n"),
        enc.hdt("HE", 30.0 + 0.02 * math.sin(k / 3)).rstrip("\r\n"),
    ]  # fmt: skip


def test_a_ros2_peer_sees_rmw_zenoh_keys_attachments_tokens_and_the_pipelines_values(
    tmp_path: Path,
) -> None:
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    config = parse_config(tables(udp, zport), base_dir=tmp_path)
    sinks = sinks_from_config(config)
    assert len(sinks) == 1 and isinstance(sinks[0], Ros2Sink)
    sink = sinks[0]
    assert isinstance(sink, RawSentenceSink) and isinstance(sink, InputSink)
    recorder = Recorder()
    service = GatewayService(config, sinks=[sink, recorder])
    t_start = time.time_ns()
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{zport}"]))
    store = ros_typestore()
    listener = RosListener(client, store)
    live: list[str] = []
    lv_sub = client.liveliness().declare_subscriber(
        "@ros2_lv/**", lambda s: live.append(str(s.key_expr)), history=True
    )
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = [0]

    def send() -> None:
        lines = sentences(sent[0])
        sent[0] += 1
        tx.sendto("".join(line + "\r\n" for line in lines).encode(), ("127.0.0.1", udp))

    def until(ok: Any, timeout: float = 30.0) -> Any:
        def step() -> Any:
            send()
            return ok()

        return wait_for(step, timeout=timeout, interval=0.05)

    def tokens() -> set[str]:
        return {str(r.ok.key_expr) for r in client.liveliness().get("@ros2_lv/**") if r.ok is not None}

    zid = sink.zid
    assert zid == str(client.info.peers_zid()[0])  # the gateway's session, as Zenoh names it
    ran = False
    try:
        # the ROS graph: a node, six publishers, one subscription, in rmw_zenoh's token format
        assert wait_for(lambda: len(tokens()) == 8), tokens()
        found = tokens()
        assert found == set(sink.tokens)
        parsed = {rz.parse_token(k).kind + rz.parse_token(k).topic: rz.parse_token(k) for k in found}
        assert set(parsed) == {
            "NN", "MP/dpgw/odom", "MP/dpgw/pose", "MP/dpgw/fix/dgps1", "MS/dpgw/setpoint", "MP/diagnostics",
            "MP/tf_static", "MP/tf",
        }  # fmt: skip
        node = parsed["NN"]
        assert f"@ros2_lv/{DOMAIN}/{zid}/0/0/NN/%/%dpgw/dpgw" in found
        assert (node.domain_id, node.zid, node.namespace, node.node, node.enclave) == (
            DOMAIN, zid, "/dpgw", "dpgw", "/",
        )  # fmt: skip
        for name, ros_type in (
            ("MP/dpgw/odom", "nav_msgs/msg/Odometry"),
            ("MP/dpgw/pose", "geometry_msgs/msg/PoseStamped"),
            ("MP/dpgw/fix/dgps1", "sensor_msgs/msg/NavSatFix"),
            ("MS/dpgw/setpoint", "geometry_msgs/msg/PoseStamped"),
            ("MP/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
            ("MP/tf_static", "tf2_msgs/msg/TFMessage"),
            ("MP/tf", "tf2_msgs/msg/TFMessage"),
        ):
            t = parsed[name]
            assert (t.domain_id, t.zid, t.node_id, t.namespace, t.node) == (DOMAIN, zid, "0", "/dpgw", "dpgw")
            assert t.dds_type == rz.dds_type_name(ros_type) and t.type_hash == PUBLISHED_HASHES[ros_type]
            if name == "MP/tf_static":
                assert t.qos == ":1:,1:,:,:,,"  # reliable, transient local, keep last 1
            elif name == "MP/tf":
                assert t.qos == "::,100:,:,:,,"  # reliable, volatile, keep last 100 (TransformBroadcaster)
            else:
                assert t.qos == "::,10:,:,:,,"  # reliable, volatile, keep last 10
        assert len({t.entity_id for t in parsed.values() if t.kind != "NN"}) == 7
        assert wait_for(lambda: set(live) >= found)  # a liveliness subscriber sees them too

        until(lambda: len(listener.of(ODOM_KEY)) >= 5 and len(listener.of(FIX_KEY)) >= 3)

        # a setpoint from ROS: one in the wrong frame is refused here, counted; the right one is taken
        service.submit("mode", "dp")
        gid = rz.entity_gid("@ros2_lv/test/setpoint/publisher")
        # a put sent before this session knows of the gateway's subscription goes to nobody: wait for it
        probe = client.declare_publisher(SETPOINT_KEY)
        try:
            assert wait_for(lambda: probe.matching_status.matching)
        finally:
            probe.undeclare()
        wrong = store.serialize_cdr(pose_stamped(store, "map", 3.0, 4.0, 45.0), rz_pose())
        client.put(SETPOINT_KEY, bytes(wrong), attachment=rz.attachment(1, time.time_ns(), gid))
        assert wait_for(lambda: sink.refused["wrong frame"] == 1)
        client.put(
            SETPOINT_KEY, b"\x00\x01\x00\x00not a pose", attachment=rz.attachment(2, time.time_ns(), gid)
        )
        assert wait_for(lambda: sink.refused["undecodable"] == 1)
        good = store.serialize_cdr(pose_stamped(store, "ltp", 3.0, 4.0, 45.0), rz_pose())
        client.put(SETPOINT_KEY, bytes(good), attachment=rz.attachment(3, time.time_ns(), gid))
        assert until(lambda: service.pipeline.setpoint is not None)
        sp = service.pipeline.setpoint
        assert sp is not None and sp["north_m"] == 4.0 and sp["east_m"] == 3.0
        assert sp["heading_deg"] == pytest.approx(45.0, abs=1e-9)
        assert service.pipeline.commands.counters.accepted["setpoint"] == 1
        assert sink.setpoints == 1 and sum(sink.refused.values()) == 2
        assert service.pipeline.controller is not None
        assert list(service.pipeline.controller._setpoint) == pytest.approx([4.0, 3.0, math.radians(45)])
        ran = True
    finally:
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        sink.close()  # the tokens go with the sink, before the session closes
        gone = wait_for(lambda: tokens() == set(), timeout=10.0)
        service.close()
        tx.close()
        lv_sub.undeclare()
        if not ran:  # (an open session keeps the test process from exiting after the failure)
            client.close()
    try:
        check_samples(listener, recorder, sink, found, t_start, time.time_ns())
    finally:
        client.close()
    assert gone
    assert not loop.is_alive()
    assert service.internal_errors == {}


def check_samples(
    listener: RosListener, recorder: Recorder, sink: Ros2Sink, tokens: set[str], t0: int, t1: int
) -> None:
    # (this session's own setpoints, delivered locally; the undecodable one is in `bad`)
    assert len(listener.got.pop(SETPOINT_KEY)) == 2
    assert len(listener.bad) == 1 and listener.bad[0].startswith(SETPOINT_KEY)
    listener.bad.clear()
    assert listener.bad == []
    # (the static transforms went out at start, likely before this listener subscribed: a late joiner
    # gets them in tests/test_ros2_settling_and_frames.py)
    assert len(listener.got.pop(TF_STATIC_KEY, [])) <= 1
    assert set(listener.got) == {ODOM_KEY, POSE_KEY, FIX_KEY, DIAGNOSTICS_KEY, TF_KEY}
    gid_of = {
        DIAGNOSTICS_KEY: rz.entity_gid(next(k for k in tokens if "/MP/" in k and "%diagnostics/" in k)),
        ODOM_KEY: rz.entity_gid(next(k for k in tokens if "/MP/" in k and "%odom/" in k)),
        POSE_KEY: rz.entity_gid(next(k for k in tokens if "/MP/" in k and "%pose/" in k)),
        FIX_KEY: rz.entity_gid(next(k for k in tokens if "/MP/" in k and "%fix%dgps1/" in k)),
        TF_KEY: rz.entity_gid(next(k for k in tokens if "/MP/" in k and "%tf/" in k)),
    }
    assert len(set(gid_of.values())) == 5
    for key, samples in listener.got.items():
        # the attachment: sequence numbers 1, 2, 3, ... per publisher, this computer's time at publishing,
        # the publisher's GID (the one rmw_zenoh derives from its token)
        assert [s[0] for s in samples] == list(range(1, len(samples) + 1)), key
        stamps = [s[1] for s in samples]
        assert all(t0 <= t <= t1 for t in stamps) and stamps == sorted(stamps)
        assert {s[2] for s in samples} == {gid_of[key]}

    # Odometry and PoseStamped: the main observer's every estimate, ENU/FLU
    estimates = {e.stamp_ns: e for e in recorder.of(Estimate, "/dp/estimate")}
    odoms = [s[3] for s in listener.of(ODOM_KEY)]
    poses = {stamp_ns(s[3].header): s[3] for s in listener.of(POSE_KEY)}
    assert len(odoms) == len(estimates) == len(poses) >= 5
    for o in odoms:
        e = estimates[stamp_ns(o.header)]
        north, east, _ = e.eta
        u, v, r = e.nu
        assert o.header.frame_id == "ltp" and o.child_frame_id == "vessel"
        p = o.pose.pose
        assert (p.position.x, p.position.y, p.position.z) == (east, north, 0.0)
        q = p.orientation
        assert (q.x, q.y) == (0.0, 0.0) and q.z**2 + q.w**2 == pytest.approx(1.0, abs=1e-12)
        heading = math.degrees(math.pi / 2 - 2 * math.atan2(q.z, q.w)) % 360
        assert math.cos(math.radians(heading - e.heading_deg)) == pytest.approx(1.0, abs=1e-12)
        tw = o.twist.twist
        assert (tw.linear.x, tw.linear.y, tw.linear.z) == (u, -v, 0.0)
        assert (tw.angular.x, tw.angular.y, tw.angular.z) == (0.0, 0.0, -r)
        assert not o.pose.covariance.any() and not o.twist.covariance.any()  # unknown
        assert o.pose.covariance.shape == (36,)
        ps = poses[stamp_ns(o.header)]
        assert ps.header.frame_id == "ltp" and ps.pose == p
    assert any(o.twist.twist.angular.z != 0.0 for o in odoms)
    # /tf: with each odometry, ltp → vessel at its pose and stamp (tests/test_ros2_settling_and_frames.py
    # turns the vessel through north)
    tfs = [s[3] for s in listener.of(TF_KEY)]
    assert len(tfs) == len(odoms)
    for o, m in zip(odoms, tfs, strict=True):
        (t,) = m.transforms
        assert (t.header.frame_id, t.child_frame_id, t.header.stamp) == ("ltp", "vessel", o.header.stamp)
        p = o.pose.pose
        v = t.transform.translation
        assert (v.x, v.y, v.z) == (p.position.x, p.position.y, p.position.z)
        assert t.transform.rotation == p.orientation

    # NavSatFix: every receiver fix, GGA's ellipsoidal height, GST's ellipse as a full ENU covariance (the
    # east-north term where east-north is, east first), DGPS status, GPS service
    fixes = {
        f.timestamp.sec * 1_000_000_000 + f.timestamp.nsec: f
        for f in recorder.of(LocationFix, "/gnss/dgps1/fix")
    }
    navsat = [s[3] for s in listener.of(FIX_KEY)]
    assert len(navsat) == len(fixes) >= 3
    for n in navsat:
        f = fixes[stamp_ns(n.header)]
        assert n.header.frame_id == "dgps1"
        assert (n.latitude, n.longitude, n.altitude) == (f.latitude, f.longitude, f.altitude)
        assert n.altitude == pytest.approx(ALT + SEP, abs=1e-9)
        assert n.status.status == n.status.STATUS_SBAS_FIX and n.status.service == n.status.SERVICE_GPS
        assert list(n.position_covariance) == list(f.position_covariance)
        assert n.position_covariance_type == f.position_covariance_type
    assert any(
        n.position_covariance_type == n.COVARIANCE_TYPE_KNOWN
        and list(n.position_covariance) == pytest.approx(ENU_COVARIANCE)
        for n in navsat
    )
    assert C_NE > 0.09 and C_EE < C_NN  # (east and north not interchangeable, the cross term not zero)
    assert sink.published["odom"] == len(odoms) and sink.published["fix/dgps1"] == len(navsat)


def stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def test_ros2_config_errors_name_the_key(tmp_path: Path) -> None:
    t = tables(1, 2, namespace="dpgw", frame_id="/map", pose_topic="odom", domain_id=233, publish_tf="yes")
    with pytest.raises(ConfigError) as err:
        parse_config(t, base_dir=tmp_path)
    text = str(err.value)
    for key in ("ros2.namespace", "ros2.frame_id", "ros2.pose_topic", "ros2.domain_id", "ros2.publish_tf"):
        assert key in text
    assert "the same topic as ros2.odom_topic" in text


def test_missing_packages_and_bad_topic_names_stop_start_up(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util

    t = tables(1, 2)
    t["sources"][0]["name"] = "1gps"
    config = parse_config(t, base_dir=tmp_path)
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "rosbags" else real(name, *a)
    )
    problems = output_problems(config)
    assert len(problems) == 2
    assert "ros2.enabled" in problems[0] and "dpgw[ros2]" in problems[0] and "rosbags is" in problems[0]
    assert "1gps: not a ROS 2 name token" in problems[1]
    from dpgw.cli_run import start_up_problems  # `dpgw run --check` says them too

    assert [p for p in start_up_problems(config) if "ros2" in p or "1gps" in p] == problems


def test_gga_quality_maps_to_navsat_status_as_nmea_navsat_driver_does() -> None:
    """ROS's NMEA driver (nmea_navsat_driver, whose NavSatFix most ROS nodes are written against) gives
    GGA quality 1 STATUS_FIX, 2 SBAS, 4/5/9 GBAS, and every other quality (0 invalid, 3 PPS, 6 dead
    reckoning, 7 manual, 8 simulator) STATUS_NO_FIX: a dead-reckoned or simulated position must not reach
    a ROS consumer (navsat_transform, a map) as a satellite fix. The service bits are the talker's."""
    s = ros_typestore().types["sensor_msgs/msg/NavSatStatus"]
    expected = {1: s.STATUS_FIX, 2: s.STATUS_SBAS_FIX, 4: s.STATUS_GBAS_FIX, 5: s.STATUS_GBAS_FIX}
    expected[9] = s.STATUS_GBAS_FIX
    for quality in range(10):
        want = expected.get(quality, s.STATUS_NO_FIX)
        assert navsat_status(quality, "GP") == (want, s.SERVICE_GPS), quality
    assert navsat_status(1, "GL")[1] == s.SERVICE_GLONASS
    assert navsat_status(1, "GA")[1] == s.SERVICE_GALILEO
    assert navsat_status(1, "GB")[1] == navsat_status(1, "BD")[1] == s.SERVICE_COMPASS
    assert navsat_status(1, "GN")[1] == 0  # several constellations: the talker does not say which


def test_navsat_fix_altitude_is_nan_until_the_receiver_gave_a_height(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """sensor_msgs/NavSatFix: "altitude … (quiet NaN if no altitude is available)". A receiver that has
    not given a height (a GGA with its altitude field empty, a MAVLink position: dpgw's LocationFix then
    says 0) must not reach ROS as a fix on the ellipsoid, tens of metres off; once it has, the height is
    GGA's, ellipsoidal."""
    zport, server, client = loopback_sessions
    config = parse_config(tables(free_port(socket.SOCK_DGRAM), zport), base_dir=tmp_path)
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    try:
        listener = RosListener(client, ros_typestore())
        sink.start(server)
        probe = LocationFix(
            timestamp=Time(sec=0, nsec=1), frame_id="dgps1", latitude=LAT, longitude=LON, altitude=0.0,
            position_covariance=[0.0] * 9, position_covariance_type=0,
        )  # fmt: skip
        # the listener's subscription reaches the sink's session: a fix is delivered
        wait_for(lambda: sink.emit([Output("/gnss/dgps1/fix", probe, 1)], []) or listener.of(FIX_KEY))
        t = datetime.now(UTC)
        no_fix = enc.gga("GP", t, LAT, LON, 0, 0, None, ALT, SEP).rstrip("\r\n")  # quality 0: no height
        no_height = enc.gga("GP", t, LAT, LON, 1, 9, 0.9, None, None).rstrip("\r\n")
        with_height = enc.gga("GP", t, LAT, LON, 1, 9, 0.9, ALT, SEP).rstrip("\r\n")
        steps = [([no_fix, no_height], 0.0), ([with_height], ALT + SEP)]
        for k, (texts, altitude) in enumerate(steps, start=1):
            for text in texts:
                sink.raw_nmea("dgps1", k * 1000, text, "test")
            fix = LocationFix(
                timestamp=Time(sec=k, nsec=0), frame_id="dgps1", latitude=LAT, longitude=LON,
                altitude=altitude, position_covariance=[0.0] * 9, position_covariance_type=0,
            )  # fmt: skip
            sink.emit([Output("/gnss/dgps1/fix", fix, k * 1_000_000_000)], [])
        assert wait_for(lambda: {s[3].header.stamp.sec for s in listener.of(FIX_KEY)} >= {1, 2})
        by_sec = {s[3].header.stamp.sec: s[3] for s in listener.of(FIX_KEY)}
        assert math.isnan(by_sec[0].altitude)  # the probe: no GGA at all yet
        assert math.isnan(by_sec[1].altitude)
        assert by_sec[2].altitude == pytest.approx(ALT + SEP, abs=1e-9)
        assert listener.bad == []
    finally:
        sink.close()


def test_with_sim_time_the_simulators_ticks_go_out_on_clock(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """``[time] clock = "sim"``: the other topics' stamps are the plant's time, so ROS nodes run with
    ``use_sim_time`` need that time on ``/clock`` (rosgraph_msgs/Clock), as a simulator gives it to ROS.
    The sink forwards every tick of ``<prefix>/sim/clock`` there, with rmw_zenoh's key, attachment and a
    publisher token with rclcpp's ClockQoS (best effort, depth 1); a tick that does not decode is counted
    and dropped. Without ``clock = "sim"`` there is no /clock."""
    import msgspec

    from wire.messages import SIM_CLOCK_KEY, SimClock

    zport, server, client = loopback_sessions
    sim_tables = {**tables(free_port(socket.SOCK_DGRAM), zport), "time": {"clock": "sim"}}
    config = parse_config(sim_tables, base_dir=tmp_path)
    wall = parse_config(tables(free_port(socket.SOCK_DGRAM), zport), base_dir=tmp_path)
    assert "clock" not in sinks_from_config(wall)[0].topics  # type: ignore[attr-defined]
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    store = ros_typestore()
    key = rz.topic_key(
        DOMAIN, "/clock", "rosgraph_msgs/msg/Clock", store.hash_rihs01("rosgraph_msgs/msg/Clock")
    )
    ticks = client.declare_publisher(
        f"dp/r/{SIM_CLOCK_KEY}", congestion_control=zenoh.CongestionControl.BLOCK
    )
    try:
        listener = RosListener(client, store)
        sink.start(server)
        t0 = 1_780_000_000_123_456_789  # a simulated instant, months from this computer's clock

        def tick(k: int) -> int:
            stamp = t0 + k * 50_000_000
            ticks.put(msgspec.json.encode(SimClock(stamp_ns=stamp, period_s=0.05, speed=1.0)))
            return stamp

        # the tick publisher reaches the sink's subscriber and the listener the sink's /clock: one gets out
        assert wait_for(lambda: tick(0) and listener.of(key), 30.0), "no /clock sample"
        ticks.put(b"not a tick")
        stamps = [tick(k) for k in range(1, 21)]

        def forwarded() -> list[int]:  # (the probe's ticks, all at t0, may still be arriving: left out)
            got = (m.clock.sec * 1_000_000_000 + m.clock.nanosec for _, _, _, m in listener.of(key))
            return [stamp for stamp in got if stamp > t0]

        assert wait_for(lambda: len(forwarded()) >= 20, 30.0)
        assert forwarded() == stamps
        seqs = [seq for seq, _, _, _ in listener.of(key)]
        assert seqs == list(range(1, len(seqs) + 1))  # rmw_zenoh's attachment: the publisher's own count
        assert wait_for(lambda: sink.refused["clock tick"] == 1)
        assert listener.bad == []
        clock_tokens = [t for t in sink.tokens if "%clock/" in t]
        assert len(clock_tokens) == 1
        parsed = rz.parse_token(clock_tokens[0])
        assert (
            parsed.topic == "/clock" and parsed.qos == rz.Qos(reliability=rz.BEST_EFFORT, depth=1).keyexpr()
        )
    finally:
        sink.close()
        ticks.undeclare()
