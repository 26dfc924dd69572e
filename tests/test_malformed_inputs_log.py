"""Zenoh inputs in the log: every record on `/dp/mode`, `/dp/setpoint` and `/dp/tau` validates against its
channel's embedded schema, and one that would not (a mode "DP", a setpoint without its heading, a τ of
strings, bytes that were no JSON) goes as text to `/dp/input/malformed`; a replay feeds both to the
pipeline exactly as received, so it refuses what the live gateway refused. Before, the malformed ones
were logged on the typed channels (`{"mode": {"invalid": "not json"}}`, `{"setpoint": [1, 2, 3]}`),
breaking those channels' schemas for Foxglove and every reader that checks."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
from jsonschema import Draft202012Validator
from mcap.reader import make_reader

from gateway.pipeline import ControlEvent
from gateway.replay import mcap_events
from wire.mcap.writer import McapLogWriter
from wire.messages import MALFORMED_INPUT_TOPIC, input_from_log, logged_input

T0 = 1_780_000_000_000_000_000

SENT: list[tuple[str, Any]] = [
    ("mode", "dp"),
    ("mode", "DP"),
    ("mode", {"invalid": "not json{"}),
    ("mode", {"mode": "dp"}),
    ("tau", {"X": 1.0, "Y": 2, "N": -3.5}),
    ("tau", {"X": "big", "Y": 0, "N": 0}),
    ("setpoint", {"north_m": 1.0, "east_m": 2.0, "heading_deg": 30.0}),
    ("setpoint", {"lat_deg": 63.4, "lon_deg": 10.4, "heading_deg": 0.0}),
    ("setpoint", [1, 2, 3]),
    ("setpoint", {"north_m": 1.0}),
    ("setpoint", None),
]


def _records(path: Path) -> list[tuple[str, dict[str, Any], dict[str, Any]]]:
    """(topic, record, its channel's embedded JSON schema) of every message in the file."""
    out = []
    with path.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema is not None and schema.encoding == "jsonschema"
            out.append((channel.topic, json.loads(message.data), json.loads(schema.data)))
    return out


def test_every_input_record_fits_its_channel_and_replays_as_received(tmp_path: Path) -> None:
    path = tmp_path / "inputs.mcap"
    with McapLogWriter(path) as w:
        for k, (key, payload) in enumerate(SENT):
            w.write(*logged_input(key, payload), T0 + k, T0 + k)
    records = _records(path)
    for topic, record, schema in records:
        errors = [e.message for e in Draft202012Validator(schema).iter_errors(record)]
        assert not errors, (topic, record, errors)
    topics = [t for t, _, _ in records]
    assert topics.count(MALFORMED_INPUT_TOPIC) == 7 and topics.count("/dp/mode") == 1, topics
    replayed = [(e.key, e.payload) for e in mcap_events(path) if isinstance(e, ControlEvent)]
    assert replayed == SENT


_json = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**53), 2**53)
    | st.floats(allow_nan=False)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=8,
)


@settings(max_examples=300, deadline=None)
@given(key=st.sampled_from(["mode", "setpoint", "tau"]), payload=_json)
def test_any_json_input_is_logged_on_a_channel_it_fits_and_read_back_as_received(
    key: str, payload: Any
) -> None:
    """The codec pair `logged_input` / `input_from_log` through JSON, as the log stores it: any JSON value
    on any key comes back as it was sent, and a record on an input's own channel is one its message type
    takes."""
    import msgspec

    from wire.messages import ManualTau, ModeRequest, Setpoint

    topic, record = logged_input(key, payload)
    stored = json.loads(json.dumps(record))
    assert input_from_log(topic, stored) == (key, payload)
    if topic != MALFORMED_INPUT_TOPIC:
        msgspec.convert(stored, {"mode": ModeRequest, "setpoint": Setpoint, "tau": ManualTau}[key])
