"""ROS 2 output: the topics the sink declares, and what docs/ros2.md says of them.

- docs/ros2.md's wire table (its node, publisher and subscription token examples) and its table of
  entity ids are read from the page and checked against the liveliness tokens a sink started on a real
  Zenoh session declares for the page's example config, as a ROS peer reads them: the page cannot go
  stale without this failing.
- The sink declares a topic only from `sink_topics`, the list the start-up check reads.
- Start-up refuses, with one message naming the key and the topic it meets, a configured topic that is
  one of the fixed ROS topics (``/clock``, ``/diagnostics``, ``/tf``, ``/tf_static``: even where this
  config does not publish it) and a source whose ``fix/<source>`` is a configured topic; a normal
  config, and names that only look alike (``tf`` in ``/dpgw``), pass.
"""

from __future__ import annotations

import re
import socket
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rosbags")
pytest.importorskip("xxhash")

from gateway.config import parse_config
from gateway.outputs.build import OutputError, output_problems, sinks_from_config
from gateway.outputs.ros2 import Ros2Sink
from gateway.outputs.ros2_topics import FIXED_TOPICS, sink_topics
from tests.conftest import free_port, wait_for
from tests.test_ros2 import tables
from wire import rmw_zenoh as rz

DOCS = Path(__file__).resolve().parents[1] / "docs" / "ros2.md"


def docs_token_examples() -> dict[str, str]:
    """The example column of the wire table's token rows, by row name."""
    rows = {}
    for line in DOCS.read_text(encoding="utf-8").splitlines():
        m = re.match(r"\| (node token|publisher token|subscription token) \|.*\| `([^`]+)` \|$", line)
        if m:
            rows[m[1]] = m[2]
    return rows


def docs_entity_ids() -> dict[int, tuple[str, str]]:
    """The table of entity ids: id → (kind, topic; the node's namespace and name for the node)."""
    ids = {}
    for line in DOCS.read_text(encoding="utf-8").splitlines():
        m = re.match(r"\| (\d+) \| `(NN|MP|MS)` \| `([^`]+)`", line)
        if m:
            assert int(m[1]) not in ids, line
            ids[int(m[1])] = (m[2], m[3])
    return ids


def docs_config(zport: int, **ros2: Any) -> dict[str, Any]:
    """The page's example: domain 0, namespace /dpgw, one position source dgps1, no simulation clock."""
    return tables(free_port(socket.SOCK_DGRAM), zport, domain_id=0, namespace="/dpgw", **ros2)


def live_tokens(client: Any) -> set[str]:
    """The ROS graph as a ROS peer's graph cache reads it: every liveliness token on the session."""
    return {str(r.ok.key_expr) for r in client.liveliness().get("@ros2_lv/**") if r.ok is not None}


def test_the_docs_token_examples_and_entity_ids_are_what_a_running_sink_declares(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    zport, server, client = loopback_sessions
    config = parse_config(docs_config(zport), base_dir=tmp_path)
    assert output_problems(config) == []
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    examples, ids = docs_token_examples(), docs_entity_ids()
    assert set(examples) == {"node token", "publisher token", "subscription token"}
    try:
        sink.start(server)
        graph = wait_for(lambda: (g := live_tokens(client)) == set(sink.tokens) and g, 10.0)
    finally:
        sink.close()
    assert graph, "the sink's tokens never reached the other session"
    parsed = {rz.parse_token(t).entity_id: rz.parse_token(t) for t in graph}
    # the table of ids: every entity, no other
    declared = {
        int(i): (t.kind, t.topic if t.kind != rz.NODE else f"{t.namespace}/{t.node}")
        for i, t in parsed.items()
    }
    assert declared == ids
    # each example ("…" any text, <zid> the session id) names exactly one of those tokens, of its row's kind
    for row, example in examples.items():
        pattern = re.escape(example).replace("…", ".+").replace(re.escape("<zid>"), re.escape(sink.zid))
        matching = [t for t in graph if re.fullmatch(pattern, t)]
        assert len(matching) == 1, (row, example, sorted(graph))
        t = rz.parse_token(matching[0])
        assert t.kind == {"node token": "NN", "publisher token": "MP", "subscription token": "MS"}[row]


def test_the_sink_declares_only_the_topics_the_start_up_check_reads(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    """With every optional topic on (two sources, the simulation clock, /tf): the topics in the sink's
    tokens are `sink_topics`' for its config, one token each."""
    zport, server, _ = loopback_sessions
    t = docs_config(zport)
    udp2 = free_port(socket.SOCK_DGRAM)
    t["sources"].append(
        {
            "name": "dgps2",
            "url": f"udp://127.0.0.1:{udp2}",
            "protocol": "nmea",
            "roles": ["position"],
            "priority": 2,
        }
    )
    t["time"] = {"clock": "sim"}
    config = parse_config(t, base_dir=tmp_path)
    assert output_problems(config) == []
    sink = sinks_from_config(config)[0]
    assert isinstance(sink, Ros2Sink)
    try:
        sink.start(server)
        tokens = list(sink.tokens)
    finally:
        sink.close()
    declared = [rz.parse_token(k).topic for k in tokens if rz.parse_token(k).kind != rz.NODE]
    expected = sink_topics(config.ros2, ["dgps1", "dgps2"], sim_clock=True)
    assert sorted(declared) == sorted(expected.values())
    assert set(FIXED_TOPICS) <= set(expected)  # every fixed topic is in use in this config


def problems_of(tmp_path: Path, ros2: dict[str, Any], **config: Any) -> list[str]:
    t = tables(1, 2, **ros2)
    t.update(config)
    return output_problems(parse_config(t, base_dir=tmp_path))


@pytest.mark.parametrize(
    ("key", "value", "meets"),
    [
        ("odom_topic", "/tf", "/tf, ROS's moving transforms"),
        ("pose_topic", "/tf_static", "/tf_static, ROS's static transforms"),
        ("pose_topic", "/diagnostics", "/diagnostics, ROS's diagnostics"),
        ("setpoint_topic", "/tf", "/tf, ROS's moving transforms"),
        ("odom_topic", "/clock", "/clock, ROS's simulation clock"),  # (no simulation clock in this config)
    ],
)
def test_a_configured_topic_on_a_fixed_ros_topic_stops_start_up(
    tmp_path: Path, key: str, value: str, meets: str
) -> None:
    problems = problems_of(tmp_path, {key: value})
    assert len(problems) == 1, problems
    assert f": ros2.{key}: the same topic as {meets}" in problems[0]
    assert f'got "{value}"' in problems[0]
    with pytest.raises(OutputError) as err:  # what `dpgw run` stops on, before anything opens
        sinks_from_config(parse_config(tables(1, 2, **{key: value}), base_dir=tmp_path))
    assert str(err.value) == problems[0]


def test_a_relative_name_in_the_root_namespace_is_the_fixed_topic(tmp_path: Path) -> None:
    problems = problems_of(tmp_path, {"namespace": "/", "pose_topic": "diagnostics"})
    assert len(problems) == 1, problems
    assert ": ros2.pose_topic: the same topic as /diagnostics, ROS's diagnostics" in problems[0]
    assert '"diagnostics", /diagnostics in namespace "/"' in problems[0]


def test_the_fixed_topics_are_kept_free_where_this_config_does_not_publish_them(tmp_path: Path) -> None:
    """``publish_tf = false`` leaves /tf to another ROS node: an Odometry on it would break that node's
    readers all the same."""
    problems = problems_of(tmp_path, {"publish_tf": False, "odom_topic": "/tf"})
    assert (
        len(problems) == 1
        and ": ros2.odom_topic: the same topic as /tf, ROS's moving transforms" in problems[0]
    )


def test_with_sim_time_the_clock_clashes_too(tmp_path: Path) -> None:
    problems = problems_of(tmp_path, {"setpoint_topic": "/clock"}, time={"clock": "sim"})
    assert (
        len(problems) == 1
        and ": ros2.setpoint_topic: the same topic as /clock, ROS's simulation clock" in problems[0]
    )


@pytest.mark.parametrize("key", ["odom_topic", "pose_topic", "setpoint_topic"])
def test_a_source_whose_fix_topic_is_a_configured_topic_stops_start_up(tmp_path: Path, key: str) -> None:
    problems = problems_of(tmp_path, {key: "fix/dgps1"})
    assert len(problems) == 1, problems
    assert ": sources: dgps1: its NavSatFix topic ros2.fix_topic/dgps1 is /dpgw/fix/dgps1" in problems[0]
    assert (
        f"the same topic as ros2.{key} (expected another source name, or another ros2.{key})" in problems[0]
    )


def test_a_source_clash_through_an_absolute_fix_topic(tmp_path: Path) -> None:
    problems = problems_of(tmp_path, {"fix_topic": "/gnss", "odom_topic": "/gnss/dgps1"})
    assert (
        len(problems) == 1
        and "sources: dgps1: its NavSatFix topic ros2.fix_topic/dgps1 is /gnss/dgps1" in (problems[0])
    )


@pytest.mark.parametrize(
    "ros2",
    [
        {},
        {"publish_tf": False},
        {"odom_topic": "tf", "pose_topic": "clock", "setpoint_topic": "diagnostics"},  # /dpgw/tf, …: not /tf
        {
            "odom_topic": "fix",
            "fix_topic": "gnss",
        },  # /dpgw/fix is no fix topic: those are /dpgw/gnss/<source>
        {"namespace": "/", "odom_topic": "tf_static_not", "fix_topic": "fix"},
    ],
)
def test_a_config_without_a_clash_is_accepted(tmp_path: Path, ros2: dict[str, Any]) -> None:
    assert problems_of(tmp_path, ros2) == []
    assert problems_of(tmp_path, ros2, time={"clock": "sim"}) == []


def test_dpgw_run_check_says_the_clash(tmp_path: Path) -> None:
    from dpgw.cli_run import start_up_problems

    config = parse_config(tables(1, 2, odom_topic="/tf"), base_dir=tmp_path)
    clashes = [p for p in start_up_problems(config) if "ros2.odom_topic" in p]
    assert len(clashes) == 1 and "the same topic as /tf, ROS's moving transforms" in clashes[0]


def test_dpgw_run_says_the_clash_as_check_does(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`dpgw run` stops on a clash before anything opens, with the message `dpgw run --check` gives (its
    heading, one line a problem, where the keys are described). Before, the lines came bare."""
    from dpgw.cli import main

    good = Path(__file__).resolve().parents[1] / "examples" / "nmea_udp_multiplexer.toml"
    config = tmp_path / "clash.toml"
    config.write_text(good.read_text() + '\n[ros2]\nenabled = true\nodom_topic = "/tf"\n')
    assert main(["run", "--config", str(config), "--log", str(tmp_path / "never.mcap")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "dpgw: the configuration has 1 problem; nothing was started:", err
    assert err[1].startswith(f"  {config}: ros2.odom_topic: the same topic as /tf"), err
    assert "docs/config.md" in err[-1], err
    assert not (tmp_path / "never.mcap").exists()


def with_prefix(prefix: str, **ros2: Any) -> dict[str, Any]:
    t = tables(1, 2, **ros2)
    t["zenoh"] = {**t["zenoh"], "prefix": prefix}
    return t


def test_a_zenoh_prefix_in_the_ros_domain_key_space_stops_start_up(tmp_path: Path) -> None:
    """rmw_zenoh keys every topic of domain D as ``D/<topic>/...``: a ``[zenoh] prefix`` starting with D
    (``0/dpgw`` with domain 0) put dpgw's JSON keys in the ROS topics' key space, unchecked. Refused now
    at start-up and by ``dpgw run --check``, one line naming both keys and what to change; only with the
    ROS 2 output on; any domain's number (0-232) and rmw_zenoh's ``@ros2_lv`` liveliness space."""
    from dpgw.cli_run import start_up_problems

    config = parse_config(with_prefix("0/dpgw", domain_id=0), base_dir=tmp_path)
    problems = output_problems(config)
    assert len(problems) == 1, problems
    (line,) = problems
    assert line.startswith(
        f'{config.path}: zenoh.prefix: "0/dpgw" starts with 0/, the key space of ROS 2 domain 0'
    )
    assert "dpgw's key 0/dpgw/estimate" in line
    assert "the ROS key 0/dpgw/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_" in line
    assert "expected a prefix whose first chunk is not a ROS domain number" in line
    assert "or another ros2.domain_id" in line
    assert [p for p in start_up_problems(config) if "zenoh.prefix" in p] == problems  # `dpgw run --check`
    with pytest.raises(OutputError) as err:  # `dpgw run`, before anything opens
        sinks_from_config(config)
    assert str(err.value) == line
    assert "ROS 2 domain 7" in problems_of(tmp_path, {}, zenoh={"prefix": "7"})[0]  # (the tables' domain 7)
    # another domain's number (ROS peers on the same Zenoh in ROS_DOMAIN_ID=0), and rmw_zenoh's liveliness
    # space: refused too
    (other,) = output_problems(parse_config(with_prefix("0/dpgw", domain_id=1), base_dir=tmp_path))
    assert 'zenoh.prefix: "0/dpgw" starts with 0/, the key space of ROS 2 domain 0, where rmw_zenoh' in other
    assert "(ROS_DOMAIN_ID=0)" in other and "another ros2.domain_id" not in other
    assert "232" in problems_of(tmp_path, {}, zenoh={"prefix": "232/x"})[0]
    (lv,) = output_problems(parse_config(with_prefix("@ros2_lv/dp", domain_id=0), base_dir=tmp_path))
    assert "rmw_zenoh's liveliness key space" in lv
    # not a domain's number as rmw_zenoh writes it (07, 233), a number further in, or the ROS 2 output
    # off: no problem
    for tables_ in (
        with_prefix("233/dpgw", domain_id=1),
        with_prefix("dp/0", domain_id=0),
        with_prefix("07/dpgw", domain_id=7),
        {**with_prefix("0/dpgw", domain_id=0), "ros2": {"enabled": False, "domain_id": 0}},
    ):
        assert output_problems(parse_config(tables_, base_dir=tmp_path)) == [], tables_
