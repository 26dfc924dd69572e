"""ROS 2 output (and setpoint input) through rmw_zenoh: dpgw as a ROS 2 node, with no ROS install.

rmw_zenoh (ROS 2's Zenoh middleware, ``RMW_IMPLEMENTATION=rmw_zenoh_cpp``) maps a topic to one Zenoh key
and a ROS message to its CDR bytes; a node, publisher or subscription exists for ``ros2 node list`` /
``ros2 topic list`` through a liveliness token. So dpgw's own Zenoh session can be a ROS 2 node: this
sink declares the tokens, publishes CDR samples with rmw_zenoh's attachment on rmw_zenoh's keys, and
takes a setpoint from a ROS 2 publisher. The formats are `wire.rmw_zenoh`'s (its docstring names the
rmw_zenoh sources they follow); the CDR serialisation and the RIHS01 type hashes are the `rosbags`
package's (ROS 2 Jazzy message definitions).

Topics (``[ros2]``; names relative to ``namespace``, ``/dpgw`` by default):

- ``odom`` — ``nav_msgs/msg/Odometry`` of the main observer's LF estimate (``/dp/estimate``): pose in
  ``frame_id`` (``ltp``: ENU at the datum, x east, y north, z up), twist in ``child_frame_id``
  (``vessel``: FLU, x forward, y port, z up). The estimate carries no covariance: both covariances are
  all zeros, which ROS messages read as "unknown" (sensor_msgs/Imu's stated convention).
- ``pose`` — ``geometry_msgs/msg/PoseStamped``: the same pose.
- ``fix/<source>`` — ``sensor_msgs/msg/NavSatFix`` of each GNSS fix a receiver gives (``/gnss/<source>/
  fix``): ellipsoidal height (NaN until the receiver gave one), GST's covariance in ENU (full from its
  error ellipse, else diagonal; approximated without σ_alt; else unknown: docs/ros2.md), the status
  from GGA's quality as nmea_navsat_driver maps it (1 fix, 2 SBAS, 4/5/9 GBAS, any other no fix), the
  service from the talker.
- ``/clock`` — ``rosgraph_msgs/msg/Clock``, only with ``[time] clock = "sim"``: the simulator's ticks
  (``<prefix>/sim/clock``) as ROS's simulation clock, best effort, keep-last 1 (rclcpp's ``ClockQoS``).
  The stamps of the other topics are then the plant's time; a ROS node run with ``use_sim_time`` reads
  the same time from ``/clock`` (without it the node's own clock is the wall clock, months from the
  stamps). An absolute topic, as ROS has it, whatever ``namespace``.
- ``/diagnostics`` — ``diagnostic_msgs/msg/DiagnosticArray`` with one ``DiagnosticStatus``, "<node>:
  estimate settled": whether the main observer's estimate has settled (``settled``, ``settle_s_left`` of
  ``/dp/estimate`` as key-values, WARN while settling, OK once settled), at most once a second of estimate
  time and at once when it settles or starts settling again. The topic diagnostic_updater publishes on.
- ``/tf`` — ``tf2_msgs/msg/TFMessage``, unless ``publish_tf = false``: with each odometry, one
  ``TransformStamped`` ``frame_id`` → ``child_frame_id``, the odometry's pose and stamp, as a ROS state
  estimator (robot_localization's ``publish_tf``) broadcasts it; reliable, volatile, keep-last 100 (tf2_ros's
  ``DynamicBroadcasterQoS``). It joins the vessel and its antenna frames to the world frame in RViz.
- ``/tf_static`` — ``tf2_msgs/msg/TFMessage``: each GNSS antenna's frame (the source's name, the
  NavSatFix's ``frame_id``) as a child of ``child_frame_id`` at its lever arm, in REP 103's body axes
  (x forward, y left, z up: dpgw's (x, y, z) is (x, −y, −z)), published once at start, reliable,
  transient local, keep-last 1 (tf2_ros's static broadcaster QoS) through a Zenoh advanced publisher with
  a cache, as rmw_zenoh makes a transient-local publisher: a node that joins later gets it.
- ``setpoint`` (subscribed) — ``geometry_msgs/msg/PoseStamped`` in ``frame_id`` only: (x, y) = (E, N) at
  the datum and the yaw about +z = π/2 − ψ become dpgw's ``{north_m, east_m, heading_deg}``, handed to the
  gateway's input path (`InputSink`): logged, checked and counted by `gateway.commands` exactly like a
  setpoint on ``<prefix>/setpoint``, and taken only when ``[commands] accept`` lists ``setpoint``. A pose
  in another frame, an undecodable sample or an orientation that is no rotation is refused here,
  counted by reason (`Ros2Sink.refused`) and logged with its bytes.

The frames are those of dpgw's Foxglove channels (`wire.foxglove`: the ENU/FLU turn at the edge).
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np
from rosbags.typesys import Stores, get_typestore

from gateway.config import GatewayConfig, Ros2Config
from gateway.outputs.base import SettlingChanges, Submit
from gateway.outputs.ros2_topics import sink_topics
from wire import rmw_zenoh as rz
from wire.foxglove import antenna_frame, heading_yaw
from wire.messages import SIM_CLOCK_KEY, Estimate, LocationFix, SimClock

if TYPE_CHECKING:
    import zenoh

    from gateway.pipeline import Output

log = logging.getLogger(__name__)

ODOMETRY = "nav_msgs/msg/Odometry"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
CLOCK = "rosgraph_msgs/msg/Clock"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
DIAGNOSTICS_PERIOD_NS = 1_000_000_000
"""diagnostic_updater's default period (1 s); a change of ``settled`` goes out at once."""
TF_QOS = rz.Qos(depth=100)
"""tf2_ros's ``DynamicBroadcasterQoS`` (a ``TransformBroadcaster``'s): reliable, volatile, keep-last 100."""
TF_STATIC_QOS = rz.Qos(durability=rz.TRANSIENT_LOCAL, depth=1)
"""tf2_ros's ``StaticBroadcasterQoS``: reliable, transient local, keep-last 1 (one message with every
static frame, kept for nodes that join later)."""
SAMPLE_MISS_HEARTBEAT_S = 0.5
"""rmw_zenoh's sporadic heartbeat of a reliable transient-local publisher (its
``SAMPLE_MISS_DETECTION_HEARTBEAT_PERIOD``, 500 ms), so a subscriber can ask for a sample it missed."""
CLOCK_QOS = rz.Qos(reliability=rz.BEST_EFFORT, depth=1)
"""rclcpp's ``ClockQoS``: the sensor-data profile (best effort) at depth 1; a late tick is worth nothing."""
ESTIMATE_TOPIC = "/dp/estimate"
"""Only the main observer's estimate: the comparison observers are for the log and for tuning."""
FIX_TOPIC_PREFIX = "/gnss/"
QOS = rz.Qos()
"""Reliable, volatile, keep-last 10: ROS 2's default profile (rclcpp's and ``ros2 topic pub``'s)."""
NS = 1_000_000_000
REFUSALS_LOGGED = 20
"""Refused setpoints logged one by one; after that every 1000th (all are counted)."""

# GGA fix quality → sensor_msgs/NavSatStatus.status, as nmea_navsat_driver maps it (the ROS driver whose
# output most ROS nodes expect): autonomous → FIX, DGPS → SBAS, RTK fixed/float and WAAS → GBAS, and any
# other quality (0 invalid, 3 PPS, 6 dead reckoning, 7 manual input, 8 simulator) → NO_FIX.
STATUS_NO_FIX, STATUS_FIX, STATUS_SBAS_FIX, STATUS_GBAS_FIX = -1, 0, 1, 2
GGA_STATUS = {1: STATUS_FIX, 2: STATUS_SBAS_FIX, 4: STATUS_GBAS_FIX, 5: STATUS_GBAS_FIX, 9: STATUS_GBAS_FIX}
# NMEA talker → NavSatStatus.service (a bitmask; GN, "several constellations", does not say which)
TALKER_SERVICE = {"GP": 1, "GL": 2, "GB": 4, "BD": 4, "GA": 8}


def navsat_status(gga_quality: int, talker: str) -> tuple[int, int]:
    """(NavSatStatus.status, NavSatStatus.service) of a GGA's fix quality and talker. A quality that is no
    satellite fix (dead reckoning, manual, simulator, PPS, invalid) is STATUS_NO_FIX, as nmea_navsat_driver
    has it: a ROS node that takes any status ≥ STATUS_FIX as a satellite fix must not be given one."""
    return GGA_STATUS.get(gga_quality, STATUS_NO_FIX), TALKER_SERVICE.get(talker, 0)


def ros_typestore() -> Any:
    """rosbags' ROS 2 Jazzy message definitions (the types and RIHS01 hashes rmw_zenoh keys on)."""
    return get_typestore(Stores.ROS2_JAZZY)


class Ros2Sink:
    """An `OutputSink`, `RawSentenceSink` and `InputSink` speaking rmw_zenoh; built by `ros2_sink`."""

    name = "ros2"

    def __init__(
        self,
        cfg: Ros2Config,
        fix_sources: Sequence[str],
        sim_clock_key: str | None = None,
        lever_arms: Mapping[str, Sequence[float]] | None = None,
        hardware_id: str = "",
    ) -> None:
        """``sim_clock_key``: the Zenoh key of the simulator's ticks (`wire.messages.SimClock`), with
        ``[time] clock = "sim"``: they go out on ``/clock``. ``lever_arms``: each GNSS source's antenna
        (m, x forward, y starboard, z down from the reference point; a source not in it is at the
        reference point), for ``/tf_static``. ``hardware_id``: the diagnostics' (the vessel's name)."""
        self.cfg = cfg
        self.fix_sources = tuple(fix_sources)
        arms = lever_arms or {}
        self.lever_arms = {s: tuple(float(v) for v in arms.get(s, (0.0, 0.0, 0.0))) for s in self.fix_sources}
        self.hardware_id = hardware_id
        self.sim_clock_key = sim_clock_key
        self.store = ros_typestore()
        t = self.store.types
        self._Time, self._Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self._Point, self._Quaternion = t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Quaternion"]
        self._Vector3, self._Pose = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Pose"]
        self._Twist = t["geometry_msgs/msg/Twist"]
        self._PoseCov = t["geometry_msgs/msg/PoseWithCovariance"]
        self._TwistCov = t["geometry_msgs/msg/TwistWithCovariance"]
        self._Odometry, self._PoseStamped = t[ODOMETRY], t[POSE_STAMPED]
        self._NavSatFix, self._NavSatStatus = t[NAV_SAT_FIX], t["sensor_msgs/msg/NavSatStatus"]
        self._Clock = t[CLOCK]
        self._DiagnosticArray = t[DIAGNOSTIC_ARRAY]
        self._DiagnosticStatus, self._KeyValue = (
            t["diagnostic_msgs/msg/DiagnosticStatus"],
            t["diagnostic_msgs/msg/KeyValue"],
        )
        self._TFMessage, self._TransformStamped = t[TF_MESSAGE], t["geometry_msgs/msg/TransformStamped"]
        self._Transform = t["geometry_msgs/msg/Transform"]
        self._unknown36 = np.zeros(36)  # shared: never written
        self.hashes = {
            ty: self.store.hash_rihs01(ty)
            for ty in (ODOMETRY, NAV_SAT_FIX, POSE_STAMPED, CLOCK, DIAGNOSTIC_ARRAY, TF_MESSAGE)
        }
        self.topics = sink_topics(cfg, self.fix_sources, sim_clock_key is not None)
        """Every topic declared, fully qualified, by name (``odom``, ``fix/<source>``, ``tf``, ...)."""
        self.published: Counter[str] = Counter()
        """Samples put, by topic."""
        self.refused: Counter[str] = Counter()
        """Setpoints refused here, by reason (what passes goes on to `gateway.commands`), and simulator ticks
        that do not decode ("clock tick")."""
        self.setpoints = 0
        """Setpoints handed to the gateway's input path."""
        self.tokens: list[str] = []
        """Every liveliness token declared (node first), as key text."""
        self.zid = ""
        """The Zenoh session id in the tokens (set by `start`)."""
        self._submit: Submit | None = None
        self._session: zenoh.Session | None = None
        self._pubs: dict[str, _Publisher] = {}
        self._declared: list[Any] = []
        self._quality: dict[str, tuple[int, int]] = {}  # source → (status, service) of its last GGA
        self._has_height: set[str] = set()  # sources that have given a height (GGA/GNS altitude field)
        # what the estimates last said of their settling, and when the next /diagnostics is due
        self._settling = SettlingChanges()
        self._next_diagnostics_ns = 0

    # --- OutputSink / InputSink -------------------------------------------------------------------------

    def bind_inputs(self, submit: Submit) -> None:
        self._submit = submit

    def start(self, session: zenoh.Session) -> None:
        import zenoh

        self._session = session
        c = self.cfg
        zid = self.zid = str(session.info.zid())
        node_id = 0
        entity_ids = iter(range(1, 1 << 31))  # unique within this session, as rmw_zenoh's counter

        def token(key: str) -> None:
            self._declared.append(session.liveliness().declare_token(key))
            self.tokens.append(key)

        token(rz.node_token(c.domain_id, zid, node_id, c.namespace, c.node_name))
        outputs = [("odom", ODOMETRY, QOS), ("pose", POSE_STAMPED, QOS)]
        outputs += [(f"fix/{s}", NAV_SAT_FIX, QOS) for s in self.fix_sources]
        if self.sim_clock_key is not None:
            outputs.append(("clock", CLOCK, CLOCK_QOS))
        outputs.append(("diagnostics", DIAGNOSTIC_ARRAY, QOS))
        if self.fix_sources:
            outputs.append(("tf_static", TF_MESSAGE, TF_STATIC_QOS))
        if c.publish_tf:
            outputs.append(("tf", TF_MESSAGE, TF_QOS))
        for name, ros_type, qos in outputs:
            topic, type_hash = self.topics[name], self.hashes[ros_type]
            key = rz.entity_token(
                c.domain_id, zid, node_id, next(entity_ids), rz.PUBLISHER, c.namespace, c.node_name,
                topic, ros_type, type_hash, qos,
            )  # fmt: skip
            reliable = qos.reliability == rz.RELIABLE
            options: dict[str, Any] = {
                "reliability": zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT,
                "congestion_control": zenoh.CongestionControl.DROP,  # keep-last: a slow reader loses samples
            }
            zkey = rz.topic_key(c.domain_id, topic, ros_type, type_hash)
            if qos.durability == rz.TRANSIENT_LOCAL:
                pub = transient_local_publisher(session, zkey, qos, options)
            else:
                pub = session.declare_publisher(zkey, **options)
            self._pubs[name] = _Publisher(pub, rz.entity_gid(key))
            token(key)
        if self.sim_clock_key is not None:
            self._declared.append(session.declare_subscriber(self.sim_clock_key, self._on_sim_clock))
        topic, type_hash = self.topics["setpoint"], self.hashes[POSE_STAMPED]
        self._declared.append(
            session.declare_subscriber(
                rz.topic_key(c.domain_id, topic, POSE_STAMPED, type_hash), self._on_setpoint
            )
        )
        token(
            rz.entity_token(
                c.domain_id, zid, node_id, next(entity_ids), rz.SUBSCRIPTION, c.namespace, c.node_name,
                topic, POSE_STAMPED, type_hash, QOS,
            )
        )  # fmt: skip
        if self.fix_sources:
            self._put("tf_static", self.antenna_transforms(time.time_ns()), TF_MESSAGE)

    def emit(self, outputs: list[Output], encoded: list[bytes]) -> None:
        for o in outputs:
            m = o.message
            if type(m) is Estimate:
                if o.topic == ESTIMATE_TOPIC:
                    self._estimate(m)
                    self._diagnostics(m)
            elif type(m) is LocationFix and o.topic.startswith(FIX_TOPIC_PREFIX):
                self._fix(m)

    def raw_nmea(self, source: str, rx_ns: int, text: str, peer: str) -> None:
        """Keeps each receiver's GGA quality and talker for its NavSatFix status, and whether it has given
        a height (the fix that follows in the same chunk's outputs comes from this sentence); a sentence
        failing its checksum is skipped, as the pipeline skips it."""
        kind = text[3:7]
        if (kind != "GGA," and kind != "GNS,") or source not in self.fix_sources:
            return
        star = text.rfind("*")
        if star > 0:
            x = 0
            for ch in text[1:star].encode("ascii", "replace"):
                x ^= ch
            if text[star + 1 : star + 3].upper() != f"{x:02X}":
                return
        fields = text[: star if star > 0 else None].split(",")
        # field 9 is the altitude in GGA and in GNS; a sentence without a fix (GGA quality 0, GNS mode all
        # N) gives the pipeline no height, so none here either. The pipeline keeps a height: so does this.
        if len(fields) > 9 and fields[9] and fields[6].strip("0N"):
            self._has_height.add(source)
        if kind == "GGA," and len(fields) > 6 and fields[6].isdigit():
            self._quality[source] = navsat_status(int(fields[6]), text[1:3])

    def close(self) -> None:
        for d in [*self._declared, *(p.pub for p in self._pubs.values())]:
            with contextlib.suppress(Exception):  # already gone with the session
                d.undeclare()
        self._declared.clear()
        self._pubs.clear()
        self._session = None

    # --- publishing ------------------------------------------------------------------------------------

    def _put(self, name: str, msg: Any, ros_type: str) -> None:
        p = self._pubs.get(name)
        if p is None:
            return  # not started, or closed
        p.seq += 1  # a publisher's first sample is number 1 (rmw_zenoh)
        p.pub.put(
            bytes(self.store.serialize_cdr(msg, ros_type)),
            attachment=rz.attachment(p.seq, time.time_ns(), p.gid),
        )
        self.published[name] += 1

    def _header(self, stamp_ns: int, frame_id: str) -> Any:
        return self._Header(stamp=self._Time(sec=stamp_ns // NS, nanosec=stamp_ns % NS), frame_id=frame_id)

    def _pose(self, north: float, east: float, psi: float) -> Any:
        """The pose in the ENU world frame of the reference point at (N, E) heading ψ."""
        h = 0.5 * heading_yaw(psi)
        return self._Pose(
            position=self._Point(x=east, y=north, z=0.0),
            orientation=self._Quaternion(x=0.0, y=0.0, z=math.sin(h), w=math.cos(h)),
        )

    def _estimate(self, e: Estimate) -> None:
        north, east, psi = e.eta
        if not all(v is not None and math.isfinite(v) for v in (north, east, psi)):
            return
        header = self._header(e.stamp_ns, self.cfg.frame_id)
        pose = self._pose(north, east, psi)
        self._put("pose", self._PoseStamped(header=header, pose=pose), POSE_STAMPED)
        u, v, r = e.nu
        if not all(x is not None and math.isfinite(x) for x in (u, v, r)):
            return
        # body (x forward, y starboard, z down) → FLU: (u, −v), yaw rate −r
        twist = self._Twist(linear=self._Vector3(x=u, y=-v, z=0.0), angular=self._Vector3(x=0.0, y=0.0, z=-r))
        odom = self._Odometry(
            header=header,
            child_frame_id=self.cfg.child_frame_id,
            pose=self._PoseCov(pose=pose, covariance=self._unknown36),
            twist=self._TwistCov(twist=twist, covariance=self._unknown36),
        )
        self._put("odom", odom, ODOMETRY)
        if "tf" in self._pubs:
            self._put("tf", self.vessel_transform(header, pose), TF_MESSAGE)

    def vessel_transform(self, header: Any, pose: Any) -> Any:
        """The ``TFMessage`` of ``/tf``: one transform ``frame_id`` → ``child_frame_id`` that is the
        odometry's pose (translation its position, rotation its orientation) with its header (stamp and
        parent frame), as robot_localization's ekf_node broadcasts its odometry (``publish_tf``)."""
        p = pose.position
        transform = self._Transform(translation=self._Vector3(x=p.x, y=p.y, z=p.z), rotation=pose.orientation)
        return self._TFMessage(
            transforms=[
                self._TransformStamped(
                    header=header, child_frame_id=self.cfg.child_frame_id, transform=transform
                )
            ]
        )

    def _diagnostics(self, e: Estimate) -> None:
        """``/diagnostics``: whether the estimate has settled, once a second of estimate time and at once
        when that changes (it settles, or starts settling again: its settle time left grows, a restart).
        Nothing for an estimate that does not say (``settled`` absent)."""
        settled, left = e.settled, e.settle_s_left
        if settled is None or left is None or "diagnostics" not in self._pubs:
            return
        if not self._settling.update(settled, left) and e.stamp_ns < self._next_diagnostics_ns:
            return
        self._next_diagnostics_ns = e.stamp_ns + DIAGNOSTICS_PERIOD_NS
        self._put(
            "diagnostics", self.settling_diagnostics(e.stamp_ns, settled, left, e.observer), DIAGNOSTIC_ARRAY
        )

    def settling_diagnostics(self, stamp_ns: int, settled: bool, left_s: float, observer: str) -> Any:
        """The ``DiagnosticArray`` of the estimate's settling: one status, "<node>: estimate settled", WARN
        while settling (DP does not engage by itself on it; an operator's DP is alarmed), OK once settled;
        key-values as diagnostic_updater writes them (a bool ``True`` / ``False``)."""
        s = self._DiagnosticStatus
        status = s(
            level=np.uint8(s.OK if settled else s.WARN),
            name=f"{self.cfg.node_name}: estimate settled",
            message="settled" if settled else f"settling: {left_s:.1f} s left",
            hardware_id=self.hardware_id,
            values=[
                self._KeyValue(key="settled", value="True" if settled else "False"),
                self._KeyValue(key="settle_s_left", value=f"{left_s:.3f}"),
                self._KeyValue(key="observer", value=observer),
            ],
        )
        return self._DiagnosticArray(header=self._header(stamp_ns, ""), status=[status])

    def antenna_transforms(self, stamp_ns: int) -> Any:
        """The ``TFMessage`` of ``/tf_static``: ``child_frame_id`` → each GNSS source's antenna frame (its
        name: the NavSatFix's ``frame_id``) at its lever arm, not rotated. The lever arm is in dpgw's body
        axes (x forward, y starboard, z down); REP 103's body frame is x forward, y left, z up, so it is
        (x, −y, −z) here, as on the Foxglove ``/dp/tf`` (`wire.foxglove.antenna_transform`)."""
        header = self._header(stamp_ns, self.cfg.child_frame_id)
        identity = self._Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        transforms = []
        for source in self.fix_sources:
            x, y, z = self.lever_arms[source]
            transforms.append(
                self._TransformStamped(
                    header=header,
                    child_frame_id=antenna_frame(source),
                    transform=self._Transform(translation=self._Vector3(x=x, y=-y, z=-z), rotation=identity),
                )
            )
        return self._TFMessage(transforms=transforms)

    def _fix(self, f: LocationFix) -> None:
        name = f"fix/{f.frame_id}"
        if name not in self._pubs:
            return
        status, service = self._quality.get(f.frame_id, (STATUS_FIX, 0))
        # NavSatFix's "quiet NaN if no altitude is available": the LocationFix says 0 for a source that
        # has given no height (a MAVLink position, a GGA with the field empty), not a height on the ellipsoid
        altitude = f.altitude if f.frame_id in self._has_height else math.nan
        msg = self._NavSatFix(
            header=self._header(f.timestamp.sec * NS + f.timestamp.nsec, f.frame_id),
            status=self._NavSatStatus(status=status, service=service),
            latitude=f.latitude,
            longitude=f.longitude,
            altitude=altitude,
            position_covariance=np.asarray(f.position_covariance, dtype=np.float64),
            position_covariance_type=f.position_covariance_type,
        )
        self._put(name, msg, NAV_SAT_FIX)

    # --- the setpoint (a Zenoh thread) --------------------------------------------------------------------

    def _on_sim_clock(self, sample: zenoh.Sample) -> None:
        """A simulator tick → ``/clock``; one that does not decode is counted (`refused`) and dropped (the
        gateway's own clock subscriber counts and alarms it too)."""
        try:
            tick = msgspec.json.decode(sample.payload.to_bytes(), type=SimClock)
        except (msgspec.DecodeError, msgspec.ValidationError):
            self.refused["clock tick"] += 1
            return
        stamp = tick.stamp_ns
        self._put("clock", self._Clock(clock=self._Time(sec=stamp // NS, nanosec=stamp % NS)), CLOCK)

    def _on_setpoint(self, sample: zenoh.Sample) -> None:
        raw = sample.payload.to_bytes()
        try:
            msg = self.store.deserialize_cdr(raw, POSE_STAMPED)
        except Exception:
            self._refuse("undecodable", f"not a CDR geometry_msgs/msg/PoseStamped: {raw[:96].hex()}")
            return
        payload = setpoint_payload(msg, self.cfg.frame_id)
        if isinstance(payload, str):
            reason, _, text = payload.partition(": ")
            self._refuse(reason, f"{text} (bytes {raw[:96].hex()})")
            return
        if self._submit is None:
            self._refuse("no input path", "the sink is not bound to a gateway")
            return
        self.setpoints += 1
        self._submit("setpoint", payload)

    def _refuse(self, reason: str, text: str) -> None:
        self.refused[reason] += 1
        n = sum(self.refused.values())
        if n <= REFUSALS_LOGGED or n % 1000 == 0:
            log.warning("ROS 2 setpoint refused (#%d, %s): %s", n, reason, text)


class _Publisher:
    """A Zenoh publisher with its rmw_zenoh identity: the GID and the sequence number of its last sample."""

    __slots__ = ("gid", "pub", "seq")

    def __init__(self, pub: Any, gid: bytes) -> None:
        self.pub, self.gid, self.seq = pub, gid, 0


def transient_local_publisher(session: zenoh.Session, key: str, qos: rz.Qos, options: dict[str, Any]) -> Any:
    """A transient-local publisher as rmw_zenoh declares one: a zenoh-ext advanced publisher that keeps its
    last ``depth`` samples for subscribers that join later (they query them: an advanced subscriber with
    history, as rmw_zenoh's transient-local subscription), is detectable by them (publisher detection),
    and, reliable, sends a sporadic heartbeat so a subscriber can fetch a sample it missed."""
    import zenoh.ext as zext

    miss = (
        zext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=SAMPLE_MISS_HEARTBEAT_S)
        if qos.reliability == rz.RELIABLE
        else None
    )
    return zext.declare_advanced_publisher(
        session,
        key,
        cache=zext.CacheConfig(max_samples=qos.depth),
        sample_miss_detection=miss,
        publisher_detection=True,
        **options,
    )


def setpoint_payload(msg: Any, frame_id: str) -> dict[str, float] | str:
    """dpgw's setpoint ``{north_m, east_m, heading_deg}`` of a ``geometry_msgs/PoseStamped`` in the ENU
    world frame ``frame_id``, or ``"<reason>: <text>"`` when it is none.

    The heading is the yaw ϕ of the orientation quaternion q = (x, y, z, w) about +z,
    ϕ = atan2(2(wz + xy), 1 − 2(y² + z²)) (the z-y-x Euler yaw; roll and pitch are ignored), turned to a
    heading clockwise from north, ψ = π/2 − ϕ, in [0, 360) degrees. Position (x, y) = (E, N); z is ignored
    (a vessel holds no depth). Finiteness and range are `gateway.commands`'s to check; a quaternion of
    norm 0 (no rotation at all: an unset orientation) is refused here."""
    got = msg.header.frame_id
    if got != frame_id:
        return f"wrong frame: frame_id {got!r}, expected {frame_id!r} (ENU at the datum)"
    q = msg.pose.orientation
    norm2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w
    if not norm2 > 1e-12:  # (also NaN)
        return f"invalid orientation: quaternion ({q.x}, {q.y}, {q.z}, {q.w}) is not a rotation"
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), norm2 - 2.0 * (q.y * q.y + q.z * q.z))
    heading = math.degrees(0.5 * math.pi - yaw) % 360.0
    p = msg.pose.position
    return {"north_m": float(p.y), "east_m": float(p.x), "heading_deg": heading}


def ros2_sink(config: GatewayConfig) -> Ros2Sink:
    """The sink ``[ros2]`` describes: a NavSatFix topic and a static antenna frame for every source with
    the ``position`` role, and ``/clock`` with ``[time] clock = "sim"``."""
    clock_key = f"{config.zenoh.prefix}/{SIM_CLOCK_KEY}" if config.time.sim else None
    positions = config.sources_for("position")
    return Ros2Sink(
        config.ros2,
        [s.name for s in positions],
        clock_key,
        lever_arms={s.name: s.lever_arm_m for s in positions},
        hardware_id=config.vessel.name,
    )
