"""ROS 2 output: the estimate's settling on ``/diagnostics``, the GNSS antenna frames on ``/tf_static`` and
the moving vessel frame on ``/tf``.

- A real pipeline's estimates (GGA + HDT fed with their receive times, the observer's real settle clock)
  go through the sink onto a loopback Zenoh session; an rmw_zenoh peer without ROS decodes every
  ``diagnostic_msgs/DiagnosticArray`` with rosbags and finds the estimate's ``settled`` and
  ``settle_s_left``: False and counting down from the settle time first, True and 0 from the first
  settled estimate on, sent at once when it flips and once a second between.
- ``/tf_static`` reaches a node that subscribes only after the sink has published it (transient local: a
  zenoh-ext advanced subscriber with history, as rmw_zenoh's transient-local subscription), with the
  antenna at (10, 2, −15) m in dpgw's body axes as (10, −2, 15) in REP 103's, parent = the odometry's
  ``child_frame_id``.
- ``/tf`` carries, with every odometry, one transform ``frame_id`` → ``child_frame_id`` that is exactly the
  odometry's pose and stamp (a real pipeline's estimates while the vessel turns through north), with a
  publisher token of tf2_ros's broadcaster QoS; with ``publish_tf = false`` there is neither token nor
  sample.
"""

from __future__ import annotations

import itertools
import math
import socket
import threading
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rosbags")
pytest.importorskip("xxhash")

import zenoh.ext as zext
from zenoh.ext import Int64, z_deserialize

from gateway.config import parse_config
from gateway.outputs.build import output_problems, sinks_from_config
from gateway.outputs.ros2 import DIAGNOSTIC_ARRAY, ODOMETRY, TF_MESSAGE, Ros2Sink, ros_typestore
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from tests.conftest import QUICK_SETTLING_OBSERVER, free_port, gga_hdt_chunk, settling_bench, wait_for
from tests.test_ros2 import DOMAIN, LAT, LON, RosListener, stamp_ns, tables
from wire import rmw_zenoh as rz
from wire.codecs import nmea_encode as enc
from wire.messages import Estimate

S = 1_000_000_000
T0 = 1_780_000_000 * S
LEVER_ARM = (10.0, 2.0, -15.0)  # x forward, y starboard, z down (dpgw's body axes): above the deck


def config_tables(zport: int, **ros2: Any) -> dict[str, Any]:
    t = tables(free_port(socket.SOCK_DGRAM), zport, **ros2)
    t["sources"][0]["lever_arm_m"] = list(LEVER_ARM)
    t["sources"].append(
        {"name": "dgps2", "url": f"udp://127.0.0.1:{free_port(socket.SOCK_DGRAM)}", "protocol": "nmea",
         "roles": ["position"], "priority": 2}
    )  # fmt: skip
    t["observer"] = dict(QUICK_SETTLING_OBSERVER)
    return t


def turning_chunk(k: int) -> bytes:
    """A tenth of a second of a DGPS with a gyro while the vessel drifts north-east and turns at 10°/s
    through north (from 300°): GGA and HDT."""
    t = datetime.now(UTC)
    gga = enc.gga("GP", t, LAT + 2e-7 * k, LON + 3e-7 * k, 2, 12, 0.8, 20.0, 35.5)
    return (gga + enc.hdt("HE", math.radians((300.0 + 1.0 * k) % 360.0))).encode()


def key_of(topic: str, ros_type: str) -> str:
    return rz.topic_key(DOMAIN, topic, ros_type, ros_typestore().hash_rihs01(ros_type))


def test_diagnostics_say_whether_the_estimate_has_settled(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    zport, server, client = loopback_sessions
    _, pipeline, sink, settle_s = settling_bench(config_tables(zport), tmp_path)
    assert isinstance(sink, Ros2Sink)
    store = ros_typestore()
    key = key_of("/diagnostics", DIAGNOSTIC_ARRAY)
    listener = RosListener(client, store)
    try:
        sink.start(server)
        diag = sink._pubs["diagnostics"].pub
        assert wait_for(lambda: diag.matching_status.matching)  # the listener's subscription has arrived
        estimates: list[Estimate] = []
        for k in range(int((settle_s + 4.0) * 10)):  # until 4 s past the settle time, at 10 Hz
            rx = T0 + k * S // 10
            out = pipeline.feed(RawEvent(rx, "dgps1", gga_hdt_chunk(k, LAT, LON)))
            estimates += [o.message for o in out if o.topic == "/dp/estimate"]  # type: ignore[misc]
            sink.emit(out, [])
        assert len(estimates) > 10 * settle_s
        sent = sink.published["diagnostics"]
        assert wait_for(lambda: len(listener.of(key)) >= sent, 10.0), (len(listener.of(key)), sent)
        samples = listener.of(key)
    finally:
        sink.close()
    assert listener.bad == []
    by_stamp = {e.stamp_ns: e for e in estimates}
    flip = next(e for e in estimates if e.settled)
    first = estimates[0]
    assert first.settled is False and first.settle_s_left == pytest.approx(settle_s, abs=1e-6)
    got: list[tuple[int, bool, float]] = []
    for _, _, _, msg in samples:
        assert msg.header.frame_id == ""
        (status,) = msg.status
        values = {kv.key: kv.value for kv in status.values}
        assert set(values) == {"settled", "settle_s_left", "observer"}
        assert status.name == "dpgw: estimate settled" and status.hardware_id == "mss_supply"
        assert values["observer"] == "passive"
        settled = {"True": True, "False": False}[values["settled"]]
        left = float(values["settle_s_left"])
        e = by_stamp[stamp_ns(msg.header)]  # every status is an estimate's, with its values
        assert settled == e.settled and left == pytest.approx(e.settle_s_left, abs=1e-3)
        if settled:
            assert status.level == status.OK and status.message == "settled" and left == 0.0
        else:
            assert status.level == status.WARN and left > 0.0
            assert status.message == f"settling: {left:.1f} s left"
        got.append((stamp_ns(msg.header), settled, left))
    stamps = [g[0] for g in got]
    assert stamps == sorted(stamps) and stamps[0] == first.stamp_ns  # the first estimate says it at once
    # settling, counting down; then settled from the first settled estimate on, said at once
    early = [g for g in got if not g[1]]
    assert early and all(g[2] > 0.0 for g in early)
    assert [g[2] for g in early] == sorted((g[2] for g in early), reverse=True)
    assert early[0][2] == pytest.approx(settle_s, abs=1e-3)
    late = [g for g in got if g[1]]
    assert late[0][0] == flip.stamp_ns and all(g[2] == 0.0 for g in late)
    assert all(g[0] < flip.stamp_ns for g in early)
    # once a second between (diagnostic_updater's period), not at every estimate
    gaps = [(b - a) / S for a, b in itertools.pairwise(stamps)]
    assert all(gap <= 1.1 for gap in gaps)
    assert len(got) <= settle_s + 4.0 + 3
    assert sent == len(got)
    assert got[-1][0] >= estimates[-1].stamp_ns - S  # the last second's too


def test_tf_static_gives_each_antenna_frame_at_its_lever_arm_to_a_late_joiner(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    zport, server, client = loopback_sessions
    config = parse_config(config_tables(zport, child_frame_id="base_link"), base_dir=tmp_path)
    assert output_problems(config) == []
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    store = ros_typestore()
    key = key_of("/tf_static", TF_MESSAGE)
    got: list[tuple[tuple[int, int, bytes], Any]] = []
    lock = threading.Lock()

    def on_sample(sample: Any) -> None:
        attachment = z_deserialize(tuple[Int64, Int64, bytes], sample.attachment)
        msg = store.deserialize_cdr(sample.payload.to_bytes(), TF_MESSAGE)
        with lock:
            got.append((attachment, msg))

    try:
        sink.start(server)  # published now, before anyone subscribes
        assert sink.published["tf_static"] == 1
        # a node that subscribes afterwards, as rmw_zenoh's transient-local subscription does
        late = zext.declare_advanced_subscriber(
            client,
            key,
            on_sample,
            history=zext.HistoryConfig(detect_late_publishers=True, max_samples=1),
        )
        try:
            assert wait_for(lambda: len(got) >= 1, 10.0), "the static transforms never reached a late joiner"
        finally:
            late.undeclare()
        tokens = list(sink.tokens)
    finally:
        sink.close()
    assert len(got) == 1
    (seq, _, gid), msg = got[0]
    token = next(t for t in tokens if "%tf_static/" in t)
    assert seq == 1 and gid == rz.entity_gid(token)
    parsed = rz.parse_token(token)
    assert parsed.topic == "/tf_static" and parsed.kind == rz.PUBLISHER
    assert parsed.qos == ":1:,1:,:,:,,"  # reliable, transient local, keep-last 1 (StaticBroadcasterQoS)
    frames = {t.child_frame_id: t for t in msg.transforms}
    assert set(frames) == {"dgps1", "dgps2"}  # the NavSatFix frame_ids
    for t in msg.transforms:
        assert t.header.frame_id == "base_link"  # the odometry's child_frame_id
        q = t.transform.rotation
        assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    v = frames["dgps1"].transform.translation
    assert (v.x, v.y, v.z) == (10.0, -2.0, 15.0)  # x forward, y left, z up (REP 103)
    v = frames["dgps2"].transform.translation
    assert (v.x, v.y, v.z) == (0.0, 0.0, 0.0)  # no lever arm given: at the reference point


def test_an_antenna_frame_named_like_the_odometry_frames_stops_start_up(tmp_path: Path) -> None:
    """A position source named as ``frame_id`` or ``child_frame_id`` would make its antenna frame that
    frame's child of itself on ``/tf_static``: refused, naming the source and the key."""
    t = config_tables(free_port(), child_frame_id="dgps2")
    problems = output_problems(parse_config(t, base_dir=tmp_path))
    assert len(problems) == 1
    assert "sources: dgps2:" in problems[0] and "ros2.child_frame_id" in problems[0]


def run_estimates(sink: Ros2Sink, config: Any, steps: int) -> list[Estimate]:
    """A real pipeline's main estimates of ``steps`` tenths of a second of `turning_chunk`, via ``sink``."""
    pipeline = Pipeline(PipelineSpec.from_config(config))
    estimates: list[Estimate] = []
    for k in range(steps):
        out = pipeline.feed(RawEvent(T0 + k * S // 10, "dgps1", turning_chunk(k)))
        estimates += [o.message for o in out if o.topic == "/dp/estimate"]  # type: ignore[misc]
        sink.emit(out, [])
    return estimates


def test_tf_broadcasts_the_odometrys_pose_as_the_vessel_frame(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """RViz / Foxglove with the fixed frame ``frame_id`` draw the vessel (and its antennas, children of
    ``child_frame_id`` on /tf_static) only if a transform ``frame_id`` → ``child_frame_id`` is on ``/tf``:
    one per odometry, its pose and stamp, as robot_localization broadcasts it."""
    zport, server, client = loopback_sessions
    config = parse_config(config_tables(zport, frame_id="map", child_frame_id="base_link"), base_dir=tmp_path)
    assert config.ros2.publish_tf  # the default, as robot_localization's
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    store = ros_typestore()
    tf_key, odom_key = key_of("/tf", TF_MESSAGE), key_of("/dpgw/odom", ODOMETRY)
    listener = RosListener(client, store)
    try:
        sink.start(server)
        assert wait_for(lambda: sink._pubs["tf"].pub.matching_status.matching)  # the listener has subscribed
        estimates = run_estimates(sink, config, 120)
        sent = sink.published["tf"]
        assert sent == sink.published["odom"] >= 100
        assert wait_for(lambda: len(listener.of(tf_key)) >= sent and len(listener.of(odom_key)) >= sent, 10.0)
        tokens = list(sink.tokens)
    finally:
        sink.close()
    assert listener.bad == []
    tfs, odoms = listener.of(tf_key), listener.of(odom_key)
    assert len(tfs) == len(odoms) == sent
    # the publisher: rmw_zenoh's token for /tf with tf2_ros's TransformBroadcaster QoS, its GID, its count
    (token,) = (t for t in tokens if "/MP/" in t and "%tf/" in t)
    parsed = rz.parse_token(token)
    assert parsed.topic == "/tf" and parsed.dds_type == rz.dds_type_name(TF_MESSAGE)
    assert parsed.qos == "::,100:,:,:,,"  # reliable, volatile, keep-last 100 (DynamicBroadcasterQoS)
    assert [seq for seq, _, _, _ in tfs] == list(range(1, sent + 1))
    assert {gid for _, _, gid, _ in tfs} == {rz.entity_gid(token)}
    by_stamp = {e.stamp_ns: e for e in estimates}
    headings = []
    for (_, _, _, tf), (_, _, _, odom) in zip(tfs, odoms, strict=True):
        (t,) = tf.transforms
        assert t.header.frame_id == "map" and t.child_frame_id == "base_link"  # the configured frames
        assert (t.header.stamp.sec, t.header.stamp.nanosec) == (
            odom.header.stamp.sec,
            odom.header.stamp.nanosec,
        )
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        v, r = t.transform.translation, t.transform.rotation
        assert (v.x, v.y, v.z) == (p.x, p.y, p.z)
        assert (r.x, r.y, r.z, r.w) == (q.x, q.y, q.z, q.w)
        # and that pose is the estimate's: (x, y) = (E, N), yaw = π/2 − ψ
        e = by_stamp[stamp_ns(t.header)]
        north, east, _ = e.eta
        assert (v.x, v.y) == (east, north)
        heading = math.degrees(math.pi / 2 - 2 * math.atan2(r.z, r.w)) % 360.0
        assert math.cos(math.radians(heading - e.heading_deg)) == pytest.approx(1.0, abs=1e-12)
        headings.append(e.heading_deg)
    # (several poses, not one: the vessel moved and turned through north while they went out)
    assert min(headings) < 10.0 and max(headings) > 350.0
    assert (
        len(
            {
                (m.transforms[0].transform.translation.x, m.transforms[0].transform.translation.y)
                for *_, m in tfs
            }
        )
        > 50
    )


def test_with_publish_tf_false_nothing_goes_on_tf(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """A vessel whose ROS side already broadcasts ``frame_id`` → ``child_frame_id`` (its own localisation
    node) turns dpgw's off: no /tf publisher token and no sample, the odometry as before."""
    zport, server, client = loopback_sessions
    config = parse_config(config_tables(zport, publish_tf=False), base_dir=tmp_path)
    assert output_problems(config) == [] and not config.ros2.publish_tf
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    store = ros_typestore()
    tf_key, odom_key = key_of("/tf", TF_MESSAGE), key_of("/dpgw/odom", ODOMETRY)
    listener = RosListener(client, store)

    def live() -> set[str]:  # the tokens on the graph, as a ROS node's graph cache reads them
        return {str(r.ok.key_expr) for r in client.liveliness().get("@ros2_lv/**") if r.ok is not None}

    try:
        sink.start(server)
        assert wait_for(lambda: sink._pubs["odom"].pub.matching_status.matching)
        run_estimates(sink, config, 30)
        sent = sink.published["odom"]
        assert sent >= 20
        assert wait_for(lambda: len(listener.of(odom_key)) >= sent, 10.0)
        graph = wait_for(lambda: (g := live()) >= set(sink.tokens) and g)
        assert graph
    finally:
        sink.close()
    assert listener.bad == []
    assert listener.of(tf_key) == []  # (subscribed to the whole domain before the first estimate)
    topics = {rz.parse_token(t).topic for t in graph if "/NN/" not in t}
    assert "/tf" not in topics and {"/dpgw/odom", "/tf_static"} <= topics  # the antennas' frames still go out
    assert "tf" not in sink.topics and "tf" not in sink.published
