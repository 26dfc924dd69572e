"""ROS 2 output: what docs/ros2.md says of the tokens the sink declares.

- docs/ros2.md's wire table (its node, publisher and subscription token examples) and its table of
  entity ids are read from the page and checked against the liveliness tokens a sink started on a real
  Zenoh session declares for the page's example config, as a ROS peer reads them: the page cannot go
  stale without this failing.
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
from gateway.outputs.build import output_problems, sinks_from_config
from gateway.outputs.ros2 import Ros2Sink
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
