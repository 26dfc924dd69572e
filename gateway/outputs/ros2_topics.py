"""Every ROS 2 topic the ROS 2 sink (`gateway.outputs.ros2`) publishes or subscribes, and the start-up check
that no two of them are one topic.

One list for both: the sink declares exactly the topics `sink_topics` gives, and `topic_clashes` checks
those same topics, so a topic added to the sink is checked without anyone remembering to. Two of dpgw's
topics on one name would put two message types on one ROS topic (every node reading it fails on one of
them), or feed the setpoint subscription dpgw's own poses. Imports nothing beyond the config, so
``dpgw run --check`` says a clash without the ``ros2`` extra installed.
"""

from __future__ import annotations

from collections.abc import Sequence

from gateway.config import GatewayConfig, Ros2Config
from gateway.config.problems import show
from wire.rmw_zenoh import dds_type_name, fully_qualified

CLOCK_TOPIC = "/clock"
DIAGNOSTICS_TOPIC = "/diagnostics"
"""Where diagnostic_updater publishes and diagnostic_aggregator / rqt_robot_monitor read: absolute."""
TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"

FIXED_TOPICS = {
    "clock": (CLOCK_TOPIC, "ROS's simulation clock (dpgw's with [time] clock = \"sim\")"),
    "diagnostics": (DIAGNOSTICS_TOPIC, "ROS's diagnostics (dpgw's estimate settling)"),
    "tf_static": (TF_STATIC_TOPIC, "ROS's static transforms (dpgw's antenna frames)"),
    "tf": (TF_TOPIC, "ROS's moving transforms (dpgw's vessel frame, unless ros2.publish_tf = false)"),
}
"""The absolute topics whose names ROS fixes, by the sink's name for them: (topic, what it is). Each is
kept from every configured topic whether or not this config publishes it (``publish_tf = false``, no
simulation clock): another message type on ``/tf`` or ``/clock`` breaks every ROS node that reads it,
dpgw's publisher or not."""

CONFIGURED = {"odom": "odom_topic", "pose": "pose_topic", "setpoint": "setpoint_topic"}
"""The sink's topics named by one ``[ros2]`` key each, by the sink's name for them."""


def sink_topics(cfg: Ros2Config, fix_sources: Sequence[str], sim_clock: bool) -> dict[str, str]:
    """Every topic the sink declares, fully qualified, by the sink's name for it (``odom``, ``pose``,
    ``setpoint``, ``fix/<source>`` for each GNSS source, ``clock`` with a simulation clock,
    ``diagnostics``, ``tf_static`` when there is a GNSS source, ``tf`` unless ``publish_tf = false``)."""
    ns = cfg.namespace
    topics = {name: fully_qualified(ns, getattr(cfg, key)) for name, key in CONFIGURED.items()}
    topics.update({f"fix/{s}": fully_qualified(ns, f"{cfg.fix_topic}/{s}") for s in fix_sources})
    if sim_clock:
        topics["clock"] = CLOCK_TOPIC
    topics["diagnostics"] = DIAGNOSTICS_TOPIC
    if fix_sources:
        topics["tf_static"] = TF_STATIC_TOPIC
    if cfg.publish_tf:
        topics["tf"] = TF_TOPIC
    return topics


def topic_clashes(config: GatewayConfig) -> list[str]:
    """A ``FILE: key: problem`` line for each topic of the sink (`sink_topics` of this config, with every
    one of `FIXED_TOPICS`) that is another's too, naming the key that made it and the topic it meets."""
    cfg = config.ros2
    sources = [s.name for s in config.sources_for("position")]
    topics = sink_topics(cfg, sources, config.time.sim)
    owner: dict[str, str] = {topic: f"{topic}, {what}" for topic, what in FIXED_TOPICS.values()}
    problems = []
    # the fixed topics first, then the configured ones, then each source's: a clash is blamed on the later
    for name, key in CONFIGURED.items():
        value, topic = getattr(cfg, key), topics[name]
        if topic in owner:
            problems.append(
                f"{config.path}: ros2.{key}: the same topic as {owner[topic]} (expected a topic of its own, "
                f"got {_named(value, topic, cfg.namespace)})"
            )
        owner.setdefault(topic, f"ros2.{key}")
    for source in sources:
        topic = topics[f"fix/{source}"]
        if topic in owner:
            problems.append(
                f"{config.path}: sources: {source}: its NavSatFix topic ros2.fix_topic/{source} is {topic}, "
                f"the same topic as {owner[topic]} (expected another source name, or another "
                f"{owner[topic] if owner[topic].startswith('ros2.') else 'ros2.fix_topic'})"
            )
        owner.setdefault(topic, f"ros2.fix_topic/{source}")
    return problems


ROS_DOMAIN_IDS = range(233)
"""The domain ids ROS 2 allows (0-232); rmw_zenoh writes one as its decimal number, the first chunk of
every key of that domain."""
ROS_LIVELINESS = "@ros2_lv"
"""rmw_zenoh's liveliness key space (``@ros2_lv/<domain>/...``): its graph of nodes, topics and services."""


def prefix_in_domain(config: GatewayConfig) -> list[str]:
    """A ``FILE: zenoh.prefix: problem`` line when dpgw's own Zenoh keys (``<prefix>/estimate``, ...) lie in
    a key space of ROS 2 over Zenoh: rmw_zenoh puts every topic of domain D at ``D/<topic>/<type>/<hash>``
    (docs/ros2.md), so a prefix whose first chunk is a domain's number (``0/dp/ship``) shares that
    domain's; its graph's liveliness tokens are under ``@ros2_lv``. A ROS peer's ``D/**`` (a bridge, a
    recorder, ``ros2 topic list``'s discovery) then meets dpgw's JSON among the CDR of the ROS topics, and
    a prefix that is a topic's path (``0/dpgw`` with namespace ``/dpgw``) puts dpgw's keys under that
    topic's. Any domain, not only ``ros2.domain_id``'s: the ROS peers on the same Zenoh may use another
    (``ROS_DOMAIN_ID``)."""
    cfg, prefix = config.ros2, config.zenoh.prefix
    first = prefix.split("/", 1)[0]
    if first == ROS_LIVELINESS:
        return [
            f"{config.path}: zenoh.prefix: {show(prefix)} starts with {ROS_LIVELINESS}/, rmw_zenoh's "
            f"liveliness key space, where ROS 2 nodes announce themselves: dpgw's key {prefix}/estimate "
            "would sit among them (expected a prefix such as the default dp/<vessel name>)"
        ]
    if not first.isdecimal() or str(int(first)) != first or int(first) not in ROS_DOMAIN_IDS:
        return []
    odom = fully_qualified(cfg.namespace, cfg.odom_topic).strip("/")
    ros_key = f"{first}/{odom}/{dds_type_name('nav_msgs/msg/Odometry')}/RIHS01_…"
    whose = (
        f"{first} (ros2.domain_id), where rmw_zenoh puts every ROS topic: dpgw's key {prefix}/estimate would "
        f"sit beside the ROS key {ros_key}"
        if first == str(cfg.domain_id)
        else f"{first}, where rmw_zenoh puts every ROS topic of that domain (ROS_DOMAIN_ID={first}): dpgw's "
        f"key {prefix}/estimate would sit among them"
    )
    return [
        f"{config.path}: zenoh.prefix: {show(prefix)} starts with {first}/, the key space of ROS 2 domain "
        f"{whose} (expected a prefix whose first chunk is not a ROS domain number, 0-232, e.g. the default "
        f"dp/<vessel name>{', or another ros2.domain_id' if first == str(cfg.domain_id) else ''})"
    ]


def _named(value: str, topic: str, namespace: str) -> str:
    """A configured topic name as given, and the topic it is when that differs (a relative name)."""
    return show(value) if value == topic else f"{show(value)}, {topic} in namespace {show(namespace)}"
