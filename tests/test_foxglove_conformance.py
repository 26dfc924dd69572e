"""dpgw's MCAP logs against Foxglove's and MCAP's own published definitions, not against our reading of them.

Real logs made here (a `dpgw demo`, its `dpgw replay`, and a demo killed with SIGKILL mid-run) are opened
with the `mcap` library's readers, and every message of every Foxglove-schema channel is validated twice:
against the JSON Schema embedded in the file, and against a schema built from `OFFICIAL`, the field table
below, written from Foxglove's published definitions. The embedded schemas are checked against the same
table field by field (names, kinds, enum values, bounds, what is required). Then what the schemas cannot
say: Foxglove's documented conventions (unit quaternions, colours in 0-1, unique metadata keys, frames that
exist in the transform tree, LocationFix's ENU covariance and its type, deletions stamped after what they
delete) and the MCAP file's structure that lets Foxglove seek (summary, statistics, chunk indexes,
message indexes, CRCs).

Sources of the facts (read, not copied):
- foxglove/foxglove-sdk, `schemas/jsonschema/<Name>.json` (the JSON Schemas Foxglove publishes for JSON
  channels) and `schemas/proto/foxglove/<Name>.proto` (the same messages, with their field comments);
- foxglove/mcap, `website/docs/spec/index.md` (the format) and `website/docs/spec/registry.md` (well-known
  message encodings, schema encodings and profiles).
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import zlib
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import wait_for
from hypothesis import given, settings
from hypothesis import strategies as st
from jsonschema import Draft202012Validator
from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, MessageIndex, Schema, SummaryOffset
from mcap.stream_reader import StreamReader, breakup_chunk

from gateway.foxglove_channels import FoxgloveChannels
from gateway.pipeline import RawEvent
from tests.test_foxglove_channels import HDT
from tests.test_pipeline import DATUM, T0, S, gga_at, mav_src, nmea_src, pipeline
from wire import foxglove as fx
from wire.codecs import mavlink as mv
from wire.geodesy import LocalFrame
from wire.gst_covariance import AXES, ELLIPSE, GstCovariance
from wire.message_schema import json_schema
from wire.messages import MESSAGES, FrameTransforms

REPO = Path(__file__).resolve().parents[1]

# --- Foxglove's definitions, as a table ---------------------------------------------------------------------
# Every Foxglove schema dpgw writes, and every type nested in one, from foxglove/foxglove-sdk
# `schemas/jsonschema/<Name>.json` (LocationFix, PoseInFrame, FrameTransforms, Log, SceneUpdate; the nested
# types are spelled out inside those files under the titles used here). A field's kind:
#   "number", "string", "boolean"; "integer>=0"; "nsec" (an integer 0..999999999); "base64" (a string,
#   contentEncoding base64); the title of another type of this table (an object); "[K]" an array of K,
#   "[K]*9" of exactly 9; "enum <title>" (one of ENUMS[<title>], by value).
# Each entry: (fields, optional): the fields not in `optional` are in the schema's "required" list.
# `time` and `duration` are untitled-by-Foxglove sub-objects titled "time" / "duration" with no "required".

OFFICIAL: dict[str, tuple[dict[str, str], frozenset[str]]] = {
    "time": ({"sec": "integer>=0", "nsec": "nsec"}, frozenset({"sec", "nsec"})),
    "duration": ({"sec": "integer", "nsec": "nsec"}, frozenset({"sec", "nsec"})),
    "foxglove.Vector3": ({"x": "number", "y": "number", "z": "number"}, frozenset()),
    "foxglove.Point3": ({"x": "number", "y": "number", "z": "number"}, frozenset()),
    "foxglove.Quaternion": ({"x": "number", "y": "number", "z": "number", "w": "number"}, frozenset()),
    "foxglove.Pose": ({"position": "foxglove.Vector3", "orientation": "foxglove.Quaternion"}, frozenset()),
    "foxglove.Color": ({"r": "number", "g": "number", "b": "number", "a": "number"}, frozenset()),
    "foxglove.KeyValuePair": ({"key": "string", "value": "string"}, frozenset()),
    # LocationFix.json; LocationFix.proto: heading "in radians, measured clockwise from north", velocity
    # "in local East-North-Up (ENU) frame in m/s", covariance "East, North, and Up (ENU), in row-major order"
    "foxglove.LocationFix": (
        {
            "timestamp": "time",
            "frame_id": "string",
            "latitude": "number",
            "longitude": "number",
            "altitude": "number",
            "position_covariance": "[number]*9",
            "position_covariance_type": "enum foxglove.PositionCovarianceType",
            "heading": "number",
            "velocity": "foxglove.Vector3",
            "color": "foxglove.Color",
            "metadata": "[foxglove.KeyValuePair]",
        },
        frozenset({"heading", "velocity", "color", "metadata"}),
    ),
    # PoseInFrame.json
    "foxglove.PoseInFrame": (
        {"timestamp": "time", "frame_id": "string", "pose": "foxglove.Pose"},
        frozenset(),
    ),
    # FrameTransforms.json (FrameTransform.json for the items): translation is "the position of the child
    # frame's origin in the parent frame", rotation "the orientation of the child frame in the parent frame"
    "foxglove.FrameTransform": (
        {
            "timestamp": "time",
            "parent_frame_id": "string",
            "child_frame_id": "string",
            "translation": "foxglove.Vector3",
            "rotation": "foxglove.Quaternion",
        },
        frozenset(),
    ),
    "foxglove.FrameTransforms": ({"transforms": "[foxglove.FrameTransform]"}, frozenset()),
    # Log.json
    "foxglove.Log": (
        {
            "timestamp": "time",
            "level": "enum foxglove.LogLevel",
            "message": "string",
            "name": "string",
            "file": "string",
            "line": "integer>=0",
        },
        frozenset(),
    ),
    # SceneUpdate.json, with SceneEntityDeletion, SceneEntity and the primitives spelled out inside it
    "foxglove.SceneUpdate": (
        {"deletions": "[foxglove.SceneEntityDeletion]", "entities": "[foxglove.SceneEntity]"},
        frozenset(),
    ),
    "foxglove.SceneEntityDeletion": (
        {"timestamp": "time", "type": "enum foxglove.SceneEntityDeletionType", "id": "string"},
        frozenset(),
    ),
    "foxglove.SceneEntity": (
        {
            "timestamp": "time",
            "frame_id": "string",
            "id": "string",
            "lifetime": "duration",
            "frame_locked": "boolean",
            "metadata": "[foxglove.KeyValuePair]",
            "arrows": "[foxglove.ArrowPrimitive]",
            "cubes": "[foxglove.CubePrimitive]",
            "spheres": "[foxglove.SpherePrimitive]",
            "cylinders": "[foxglove.CylinderPrimitive]",
            "lines": "[foxglove.LinePrimitive]",
            "triangles": "[foxglove.TriangleListPrimitive]",
            "texts": "[foxglove.TextPrimitive]",
            "models": "[foxglove.ModelPrimitive]",
        },
        frozenset(),
    ),
    "foxglove.ArrowPrimitive": (
        {
            "pose": "foxglove.Pose",
            "shaft_length": "number",
            "shaft_diameter": "number",
            "head_length": "number",
            "head_diameter": "number",
            "color": "foxglove.Color",
        },
        frozenset(),
    ),
    "foxglove.CubePrimitive": (
        {"pose": "foxglove.Pose", "size": "foxglove.Vector3", "color": "foxglove.Color"},
        frozenset(),
    ),
    "foxglove.SpherePrimitive": (
        {"pose": "foxglove.Pose", "size": "foxglove.Vector3", "color": "foxglove.Color"},
        frozenset(),
    ),
    "foxglove.CylinderPrimitive": (
        {
            "pose": "foxglove.Pose",
            "size": "foxglove.Vector3",
            "bottom_scale": "number",
            "top_scale": "number",
            "color": "foxglove.Color",
        },
        frozenset(),
    ),
    "foxglove.LinePrimitive": (
        {
            "type": "enum foxglove.LineType",
            "pose": "foxglove.Pose",
            "thickness": "number",
            "scale_invariant": "boolean",
            "points": "[foxglove.Point3]",
            "color": "foxglove.Color",
            "colors": "[foxglove.Color]",
            "indices": "[integer>=0]",
        },
        frozenset(),
    ),
    "foxglove.TriangleListPrimitive": (
        {
            "pose": "foxglove.Pose",
            "points": "[foxglove.Point3]",
            "color": "foxglove.Color",
            "colors": "[foxglove.Color]",
            "indices": "[integer>=0]",
        },
        frozenset(),
    ),
    "foxglove.TextPrimitive": (
        {
            "pose": "foxglove.Pose",
            "billboard": "boolean",
            "font_size": "number",
            "scale_invariant": "boolean",
            "color": "foxglove.Color",
            "text": "string",
        },
        frozenset(),
    ),
    "foxglove.ModelPrimitive": (
        {
            "pose": "foxglove.Pose",
            "scale": "foxglove.Vector3",
            "color": "foxglove.Color",
            "override_color": "boolean",
            "url": "string",
            "media_type": "string",
            "data": "base64",
        },
        frozenset(),
    ),
}

# Enum values as the JSON Schemas give them ("oneOf" of titled "const"s; the .proto enums agree).
ENUMS: dict[str, dict[str, int]] = {
    "foxglove.PositionCovarianceType": {"UNKNOWN": 0, "APPROXIMATED": 1, "DIAGONAL_KNOWN": 2, "KNOWN": 3},
    "foxglove.LogLevel": {"UNKNOWN": 0, "DEBUG": 1, "INFO": 2, "WARNING": 3, "ERROR": 4, "FATAL": 5},
    "foxglove.SceneEntityDeletionType": {"MATCHING_ID": 0, "ALL": 1},
    "foxglove.LineType": {"LINE_STRIP": 0, "LINE_LOOP": 1, "LINE_LIST": 2},
}

TOP_LEVEL = ("foxglove.LocationFix", "foxglove.PoseInFrame", "foxglove.FrameTransforms", "foxglove.Log",
             "foxglove.SceneUpdate")  # fmt: skip
"""The Foxglove schemas dpgw gives a channel (docs/foxglove.md's table)."""

# MCAP (foxglove/mcap, website/docs/spec/registry.md): JSON messages are message encoding `json`, their
# JSON Schema is schema encoding `jsonschema`; the well-known profiles are `ros1` and `ros2` only (each
# demands ROS encodings), and a profile may also name a framework that is not one of those.
ROS_PROFILES = {"ros1", "ros2"}


def _kind_schema(kind: str) -> dict[str, Any]:
    if kind.startswith("["):
        inner, _, count = kind[1:].partition("]")
        out: dict[str, Any] = {"type": "array", "items": _kind_schema(inner)}
        if count:
            out["minItems"] = out["maxItems"] = int(count.removeprefix("*"))
        return out
    if kind.startswith("enum "):
        title = kind.removeprefix("enum ")
        return {"title": title, "oneOf": [{"title": n, "const": v} for n, v in ENUMS[title].items()]}
    if kind in OFFICIAL:
        return official_schema(kind)
    return {
        "number": {"type": "number"},
        "string": {"type": "string"},
        "boolean": {"type": "boolean"},
        "integer": {"type": "integer"},
        "integer>=0": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
        "base64": {"type": "string", "contentEncoding": "base64"},
    }[kind]


def official_schema(title: str) -> dict[str, Any]:
    """A JSON Schema of type ``title`` built from `OFFICIAL` alone (what Foxglove publishes)."""
    fields, optional = OFFICIAL[title]
    return {
        "title": title,
        "type": "object",
        "properties": {name: _kind_schema(kind) for name, kind in fields.items()},
        "required": [name for name in fields if name not in optional],
    }


def embedded_differences(title: str, schema: dict[str, Any], path: str = "") -> list[str]:
    """Where the JSON Schema a channel carries for ``title`` departs from Foxglove's, field by field.

    Allowed: leaving out an optional field, requiring a field Foxglove leaves optional (dpgw always writes
    it), other descriptions. Everything else (a field Foxglove does not have, another kind, other enum
    values or bounds, a required field not required) is a difference."""
    out: list[str] = []
    fields, optional = OFFICIAL[title]
    where = path or title
    if schema.get("title") != title or schema.get("type") != "object":
        out.append(f"{where}: title {schema.get('title')!r}, type {schema.get('type')!r}")
    props = schema.get("properties", {})
    out += [f"{where}.{n}: not a field of {title}" for n in props.keys() - fields.keys()]
    required = set(schema.get("required", ()))
    out += [f"{where}.{n}: required by Foxglove" for n in fields if n not in optional and n not in required]
    out += [f"{where}.{n}: missing" for n in fields if n not in optional and n not in props]
    for name, kind in fields.items():
        if name in props:
            out += _kind_differences(kind, props[name], f"{where}.{name}")
    return out


def _kind_differences(kind: str, s: dict[str, Any], where: str) -> list[str]:
    if kind in OFFICIAL:
        return embedded_differences(kind, s, where)
    if kind.startswith("["):
        inner, _, count = kind[1:].partition("]")
        out = [] if s.get("type") == "array" else [f"{where}: {s.get('type')!r}, not an array"]
        n = int(count.removeprefix("*")) if count else None
        if (s.get("minItems"), s.get("maxItems")) != (n, n):
            out.append(f"{where}: items {s.get('minItems')}..{s.get('maxItems')}, Foxglove's {n}")
        return out + _kind_differences(inner, s.get("items", {}), f"{where}[]")
    if kind.startswith("enum "):
        title = kind.removeprefix("enum ")
        got = {o.get("title"): o.get("const") for o in s.get("oneOf", ())}
        return [] if got == ENUMS[title] else [f"{where}: enum {got}, Foxglove's {ENUMS[title]}"]
    want = _kind_schema(kind)
    got = {k: s.get(k) for k in ("type", "minimum", "maximum", "contentEncoding") if k in s or k in want}
    return [] if got == want else [f"{where}: {got}, Foxglove's {want}"]


# --- reading with the mcap library only ---------------------------------------------------------------------


def read_prefix(path: Path) -> tuple[list[tuple[Schema, Channel, Message]], bool]:
    """Every message of ``path`` with its schema and channel, in file order, as a streaming reader (what
    Foxglove uses for a file without an index) gets them: records up to the first partial one, chunk CRCs
    checked. Also whether the file ended cleanly (footer and magic)."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    out: list[tuple[Schema, Channel, Message]] = []
    complete = False
    with path.open("rb") as f:
        try:
            for rec in StreamReader(f, validate_crcs=True).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message):
                    # a channel and its schema come before its first message, or no reader can decode it
                    ch = channels[rec.channel_id]
                    out.append((schemas[ch.schema_id], ch, rec))
                elif isinstance(rec, Footer):
                    complete = True
        except EndOfFile:
            pass
    return out, complete


def foxglove_messages(
    msgs: list[tuple[Schema, Channel, Message]],
) -> Iterator[tuple[str, str, Message, dict[str, Any]]]:
    for schema, channel, m in msgs:
        if schema.name.startswith("foxglove."):
            yield channel.topic, schema.name, m, json.loads(m.data)


def check_every_foxglove_message(msgs: list[tuple[Schema, Channel, Message]]) -> Counter[str]:
    """Validate every Foxglove-schema message against its embedded schema and Foxglove's; check the
    embedded schemas field by field, the channels' encodings, and Foxglove's conventions. The count of
    messages checked per topic."""
    counts: Counter[str] = Counter()
    validators: dict[int, tuple[Draft202012Validator, Draft202012Validator]] = {}
    conventions = Conventions()
    for schema, channel, m in msgs:
        assert channel.message_encoding == "json", channel.topic
        assert schema.encoding == "jsonschema", schema.name
        if not schema.name.startswith("foxglove."):
            continue
        assert schema.name in TOP_LEVEL, f"{channel.topic}: {schema.name} is not in the table of this test"
        if schema.id not in validators:
            embedded = json.loads(schema.data)
            assert embedded_differences(schema.name, embedded) == [], schema.name
            validators[schema.id] = (
                Draft202012Validator(embedded),
                Draft202012Validator(official_schema(schema.name)),
            )
        payload = json.loads(m.data)
        for v in validators[schema.id]:
            errors = [e.message for e in v.iter_errors(payload)]
            assert not errors, (channel.topic, m.log_time, errors[:3])
        conventions.check(channel.topic, schema.name, m, payload)
        counts[channel.topic] += 1
    conventions.check_frames()
    return counts


def _ns(t: dict[str, int]) -> int:
    return t["sec"] * 1_000_000_000 + t["nsec"]


class Conventions:
    """What Foxglove's definitions say in words, which a JSON Schema cannot: checked message by message."""

    def __init__(self) -> None:
        self.frames: set[str] = set()  # every frame of /dp/tf
        self.parent_of: dict[str, str] = {}  # child frame -> its parent
        self.tf_stamps: set[int] = set()
        self.used_frames: Counter[str] = Counter()
        self.pose_stamps: list[int] = []
        self.entity_stamp: dict[tuple[str, str], int] = {}  # (topic, id) -> stamp of the last entity

    def check(self, topic: str, name: str, m: Message, p: dict[str, Any]) -> None:
        # the message's own stamp is its log time (Foxglove plays by log time and looks up transforms by
        # the stamp: the two must agree for a frame to be found when its message is shown)
        stamps = [
            x["timestamp"]
            for x in [p, *p.get("transforms", ()), *p.get("entities", ()), *p.get("deletions", ())]
            if "timestamp" in x
        ]
        assert stamps and all(_ns(t) == m.log_time for t in stamps), (topic, stamps, m.log_time)
        for q in _all(p, "orientation") + _all(p, "rotation"):
            # Foxglove.Quaternion: a rotation, so of unit norm (x, y, z, w)
            assert math.hypot(q["x"], q["y"], q["z"], q["w"]) == pytest.approx(1.0, abs=1e-9), (topic, q)
        for c in _all(p, "color") + [c for cs in _all(p, "colors") for c in cs]:
            assert all(0.0 <= c[k] <= 1.0 for k in "rgba"), (topic, c)  # "value between 0 and 1"
        for meta in _all(p, "metadata"):
            keys = [kv["key"] for kv in meta]
            assert len(keys) == len(set(keys)), (topic, keys)  # "Keys must be unique"
        if name == "foxglove.LocationFix":
            self._location_fix(topic, p)
        elif name == "foxglove.FrameTransforms":
            for t in p["transforms"]:
                parent, child = t["parent_frame_id"], t["child_frame_id"]
                assert parent != child
                # a tree: a frame has one parent for the whole log
                assert self.parent_of.setdefault(child, parent) == parent, (child, parent, self.parent_of)
                self.frames |= {parent, child}
            self.tf_stamps.add(m.log_time)
        elif name == "foxglove.PoseInFrame":
            self.used_frames[p["frame_id"]] += 1
            self.pose_stamps.append(m.log_time)
        elif name == "foxglove.SceneUpdate":
            self._scene(topic, p)

    def _location_fix(self, topic: str, p: dict[str, Any]) -> None:
        assert -90.0 <= p["latitude"] <= 90.0 and -180.0 <= p["longitude"] <= 180.0, p
        self.used_frames[p["frame_id"]] += 1  # (the receiver's antenna, or the vessel for the estimate)
        # heading: radians clockwise from north (a number when present; dpgw's is the estimate's ψ)
        assert "heading" not in p or math.isfinite(p["heading"])
        cov = np.array(p["position_covariance"]).reshape(3, 3)
        kind = p["position_covariance_type"]
        assert np.array_equal(cov, cov.T), (topic, p["position_covariance"])  # a covariance is symmetric
        if kind == ENUMS["foxglove.PositionCovarianceType"]["UNKNOWN"]:
            assert not cov.any(), (topic, p)  # dpgw: nothing claimed when nothing is known
            return
        assert np.linalg.eigvalsh(cov).min() >= -1e-12 * max(1.0, cov.max()), (topic, cov)  # PSD
        assert (np.diag(cov) >= 0).all(), (topic, cov)  # (0: a receiver's σ of 0.0, as it printed it)
        if kind == ENUMS["foxglove.PositionCovarianceType"]["DIAGONAL_KNOWN"]:
            assert not (cov - np.diag(np.diag(cov))).any(), (topic, cov)  # "put it along the diagonal"
        # the up axis (ENU: the third) is never correlated with the horizontal in dpgw's fixes
        assert cov[2, 0] == cov[2, 1] == cov[0, 2] == cov[1, 2] == 0.0

    def _scene(self, topic: str, p: dict[str, Any]) -> None:
        ids = [e["id"] for e in p["entities"]]
        assert len(ids) == len(set(ids)), (topic, ids)  # an id replaces: two in one update is ambiguous
        for d in p["deletions"]:
            if d["type"] == ENUMS["foxglove.SceneEntityDeletionType"]["MATCHING_ID"]:
                # "Only matching entities earlier than this timestamp will be deleted."
                made = self.entity_stamp.get((topic, d["id"]))
                assert made is not None, (topic, d)  # deleting what was never drawn
                assert _ns(d["timestamp"]) > made, (topic, d, made)
        for e in p["entities"]:
            self.entity_stamp[(topic, e["id"])] = _ns(e["timestamp"])
            self.used_frames[e["frame_id"]] += 1
            lifetime = e["lifetime"]
            assert lifetime["sec"] >= 0  # 0: until replaced or deleted; never negative
            for a in e["arrows"]:
                assert min(a["shaft_length"], a["shaft_diameter"], a["head_length"], a["head_diameter"]) >= 0
            for line in e["lines"]:
                n = len(line["points"])
                assert line["thickness"] > 0
                assert not line["colors"] or len(line["colors"]) == n  # "same length as points"
                assert all(i < n for i in line["indices"])
                if line["type"] == ENUMS["foxglove.LineType"]["LINE_LOOP"]:
                    assert n >= 3, (topic, e["id"])  # a loop of fewer points draws no area

    def check_frames(self) -> None:
        """Every frame a pose, an entity or a fix is in is in the transform tree, whose only root is the
        world frame; every pose has the transforms of its own stamp (Foxglove looks them up by it)."""
        if not self.frames:
            return
        roots = self.frames - set(self.parent_of)
        assert roots == {fx.WORLD_FRAME}, (roots, self.parent_of)
        for frame in self.parent_of:  # every frame reaches the root (no cycle)
            seen = {frame}
            while frame != fx.WORLD_FRAME:
                frame = self.parent_of[frame]
                assert frame not in seen, (frame, self.parent_of)
                seen.add(frame)
        assert set(self.used_frames) <= self.frames, (set(self.used_frames), self.frames)
        assert all(s in self.tf_stamps for s in self.pose_stamps)


def _all(node: Any, key: str) -> list[Any]:
    """Every value under ``key`` anywhere in a decoded message."""
    out: list[Any] = []
    if isinstance(node, dict):
        for k, v in node.items():
            if k == key:
                out.append(v)
            out += _all(v, key)
    elif isinstance(node, list):
        for v in node:
            out += _all(v, key)
    return out


# --- the logs ----------------------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _demo_args(out: Path, duration_s: int, speed: float) -> list[str]:
    return [sys.executable, "-m", "dpgw", "demo", "--duration", str(duration_s), "--speed", str(speed),
            "--out", str(out), "--engage-at", "5", "--json", "--no-scouting", "--no-foxglove",
            "--zenoh-listen", f"tcp/127.0.0.1:{_free_port()}"]  # fmt: skip


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(REPO)}


@pytest.fixture(scope="module")
def demo_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fxconf") / "demo.mcap"
    proc = subprocess.run(_demo_args(out, 30, 10), capture_output=True, text=True, timeout=300, env=_env(),
                          cwd=REPO)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def replay_log(demo_log: Path) -> Path:
    out = demo_log.with_name("replayed.mcap")
    args = [sys.executable, "-m", "dpgw", "replay", str(demo_log), "--out", str(out), "--json"]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=300, env=_env(), cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    return out


FOXGLOVE_TOPICS = {"/gnss/dgps1/fix", "/dp/estimate/fix", "/dp/estimate/pose", "/dp/measurement/pose",
                   "/dp/tf", "/dp/scene/hull", "/dp/scene/thrusters", "/dp/scene/setpoint",
                   "/dp/log"}  # fmt: skip


@pytest.mark.slow  # a 30 s demo at 10x and its replay
@pytest.mark.parametrize("which", ["demo_log", "replay_log"])
def test_every_foxglove_message_conforms_to_foxglove_s_schemas(
    which: str, request: pytest.FixtureRequest
) -> None:
    path: Path = request.getfixturevalue(which)
    msgs, complete = read_prefix(path)
    assert complete
    counts = check_every_foxglove_message(msgs)
    assert set(counts) == FOXGLOVE_TOPICS, set(counts) ^ FOXGLOVE_TOPICS
    assert counts["/dp/tf"] >= 50 and counts["/gnss/dgps1/fix"] >= 20  # a 30 s log at ~5 Hz and 2 Hz


@pytest.mark.slow
def test_mcap_structure_lets_foxglove_seek(demo_log: Path) -> None:
    data = demo_log.read_bytes()
    with demo_log.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        header = reader.get_header()
        info = reader.get_summary()
        assert info is not None
        everything = list(reader.iter_messages(log_time_order=False))
        # seeking by time on the index gives exactly the messages from then on
        times = sorted(m.log_time for _, _, m in everything)
        mid = times[len(times) // 2]
        seek = [(c.topic, m.log_time) for _, c, m in reader.iter_messages(topics=["/dp/tf"], starting_at=mid)]
        assert seek == sorted((c.topic, m.log_time) for _, c, m in everything if c.topic == "/dp/tf" and
                              m.log_time >= mid)  # fmt: skip
    # the header: a profile that is not one of the ROS profiles (their encodings are not JSON); the
    # library with the releases that wrote it, e.g. "dpgw 0.1.0 (mcap 1.6.0)"
    assert header.profile not in ROS_PROFILES
    assert re.fullmatch(r"dpgw \S+ \(mcap \d+\.\d+\S*\)", header.library), header.library
    # schemas and channels: a JSON Schema for every channel, json messages
    for ch in info.channels.values():
        assert ch.message_encoding == "json" and ch.schema_id in info.schemas, ch.topic
        assert all(isinstance(k, str) and isinstance(v, str) for k, v in ch.metadata.items())
    for s in info.schemas.values():
        assert s.encoding == "jsonschema" and isinstance(json.loads(s.data), dict), s.name
    # statistics: what the file holds
    stats = info.statistics
    assert stats is not None
    per_channel = Counter(m.channel_id for _, _, m in everything)
    assert stats.message_count == len(everything)
    assert stats.channel_message_counts == dict(per_channel)
    assert (stats.message_start_time, stats.message_end_time) == (times[0], times[-1])
    assert (stats.channel_count, stats.schema_count) == (len(info.channels), len(info.schemas))
    # chunk indexes: one per chunk, each with the message index of every channel in its chunk
    chunks = [r for r in StreamReader(io.BytesIO(data), emit_chunks=True).records if isinstance(r, Chunk)]
    assert stats.chunk_count == len(chunks) == len(info.chunk_indexes) > 1
    for ci in info.chunk_indexes:
        opcode, length = struct.unpack_from("<BQ", data, ci.chunk_start_offset)
        assert opcode == 0x06 and ci.chunk_length == 9 + length
        chunk = Chunk.read(
            ReadDataStream(io.BytesIO(data[ci.chunk_start_offset + 9 : ci.chunk_start_offset + 9 + length]))
        )
        records = chunk_records(chunk)
        in_chunk = {off: r for off, r in records if isinstance(r, Message)}
        assert {r.channel_id for r in in_chunk.values()} == set(ci.message_index_offsets)
        assert ci.message_start_time == min(r.log_time for r in in_chunk.values())
        assert ci.message_end_time == max(r.log_time for r in in_chunk.values())
        indexed = 0
        for channel_id, offset in ci.message_index_offsets.items():
            opcode, length = struct.unpack_from("<BQ", data, offset)
            assert opcode == 0x07
            mi = MessageIndex.read(ReadDataStream(io.BytesIO(data[offset + 9 : offset + 9 + length])))
            assert mi.channel_id == channel_id
            for log_time, at in mi.records:
                r = in_chunk[at]  # the offset of a Message record in the chunk's uncompressed records
                assert (r.channel_id, r.log_time) == (channel_id, log_time)
            indexed += len(mi.records)
        assert indexed == len(in_chunk)
        assert ci.message_index_length == sum(9 + struct.unpack_from("<Q", data, o + 1)[0]
                                              for o in ci.message_index_offsets.values())  # fmt: skip
    # the data section's and the summary's CRCs, where given (0 says "not available")
    footer = Footer.read(ReadDataStream(io.BytesIO(data[-8 - 20 : -8])))
    data_end_at = footer.summary_start - (9 + 4)
    assert data[data_end_at] == 0x0F
    data_end = DataEnd.read(ReadDataStream(io.BytesIO(data[data_end_at + 9 : footer.summary_start])))
    assert data_end.data_section_crc in (0, zlib.crc32(data[:data_end_at]))
    assert footer.summary_crc in (0, zlib.crc32(data[footer.summary_start : len(data) - 8 - 4]))
    # the summary offset section lists each group of summary records
    offsets = [r for r in StreamReader(io.BytesIO(data)).records if isinstance(r, SummaryOffset)]
    assert {o.group_opcode for o in offsets} >= {
        0x03,
        0x04,
        0x08,
        0x0B,
    }  # schemas, channels, chunk index, stats
    assert isinstance(next(iter(StreamReader(io.BytesIO(data)).records)), Header)


def chunk_records(chunk: Chunk) -> list[tuple[int, Any]]:
    """(offset in the uncompressed records, record) of a chunk, as the message index counts offsets."""
    stream = ReadDataStream(io.BytesIO(_uncompressed(chunk)))
    records = breakup_chunk(chunk)
    out: list[tuple[int, Any]] = []
    for r in records:
        out.append((stream.count, r))
        _, length = struct.unpack("<BQ", stream.read(9))
        stream.read(length)
    return out


def _uncompressed(chunk: Chunk) -> bytes:
    if chunk.compression == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    if chunk.compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(chunk.data))
    return chunk.data


@pytest.mark.slow  # a demo run at 2x, killed once it has written a few chunks
def test_a_killed_demo_s_log_is_readable_up_to_its_last_flushed_chunk(tmp_path: Path) -> None:
    out = tmp_path / "killed.mcap"
    proc = subprocess.Popen(_demo_args(out, 600, 2), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=_env(), cwd=REPO, start_new_session=True)  # fmt: skip
    try:

        def enough() -> list[tuple[Schema, Channel, Message]] | None:
            if not out.exists():
                return None
            msgs, _ = read_prefix(out)
            topics = {c.topic for _, c, _ in msgs}
            chunks = sum(1 for _ in _chunks(out))
            return msgs if chunks >= 4 and {"/dp/tf", "/dp/scene/hull", "/gnss/dgps1/fix"} <= topics else None

        before = wait_for(enough, 240.0, interval=0.25)
        assert before, "the demo wrote no Foxglove channels in 4 minutes"
        assert proc.poll() is None, "the demo ended before it was killed"
        os.killpg(proc.pid, signal.SIGKILL)  # the demo and anything it started, at once, mid-run
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    after, complete = read_prefix(out)
    assert not complete  # killed: no summary, no footer (Foxglove reads it without an index)
    assert [(c.topic, m.log_time) for _, c, m in after[: len(before)]] == [
        (c.topic, m.log_time) for _, c, m in before
    ]  # what was readable before the kill is still there
    counts = check_every_foxglove_message(after)
    assert counts["/dp/tf"] > 0 and counts["/dp/scene/hull"] > 0
    # what is lost is the part of the file after the last whole record: less than one chunk
    size = out.stat().st_size
    whole = _chunks(out)
    last_end = max(end for end in whole)
    assert size - last_end < 256 * 1024 + 1024, (size, last_end)


def _chunks(path: Path) -> list[int]:
    """End offsets of the whole Chunk records of a (possibly cut) file."""
    data = path.read_bytes()
    ends, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        end = pos + 9 + length
        if end > len(data):
            break
        if opcode == 0x06:
            ends.append(end)
        pos = end
    return ends


# --- what the demo does not make: every other kind of Foxglove message dpgw writes -------------------------


def test_messages_the_demo_does_not_make_conform_too() -> None:
    """Fixes with each covariance type, a setpoint drawn then deleted, alarm and state-change log lines
    (a source going stale and back, through the pipeline): each validated against Foxglove's table, its
    class's own schema, and the conventions."""
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=1.0)])
    made: list[tuple[str, Any]] = []
    for k, cov in enumerate(
        [
            None,
            GstCovariance(nn=4.0, ne=0.0, ee=1.0, uu=9.0, origin=AXES),
            GstCovariance(nn=4.0, ne=1.5, ee=1.0, uu=9.0, origin=ELLIPSE),
            GstCovariance(nn=4.0, ne=1.5, ee=1.0, uu=20.0, origin=ELLIPSE, up_known=False),
        ]
    ):
        made.append(("/gnss/gps/fix", fx.location_fix(T0 + k, "gps", 63.4, 10.4, 55.0, cov)))
    ch = FoxgloveChannels(p.spec.vessel)
    made += [(t, m) for t, m, _ in ch.setpoint((10.0, -5.0, 0.3), T0 + S)]
    made += [(t, m) for t, m, _ in ch.setpoint(None, T0 + 2 * S)]
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + HDT))
    for k in range(2, 5):  # stale from 1 s on: a state change (WARNING) and an alarm raised
        made += [(o.topic, o.message) for o in p.status_outputs(T0 + k * S) if o.topic == "/dp/log"]
        made += [(o.topic, o.message) for o in p.tick(T0 + k * S + 1) if o.topic == "/dp/log"]
    made += [(o.topic, o.message) for o in p.feed(RawEvent(T0 + 6 * S, "gps", gga_at(0.0, 0.0) + HDT))
             if o.topic == "/dp/log"]  # fmt: skip
    conventions = Conventions()
    kinds: Counter[str] = Counter()
    for topic, msg in made:
        cls = type(msg)
        assert cls.TITLE in TOP_LEVEL and embedded_differences(cls.TITLE, json_schema(cls)) == []
        payload = json.loads(msg.encode())
        for schema in (json_schema(cls), official_schema(cls.TITLE)):
            errors = [e.message for e in Draft202012Validator(schema).iter_errors(payload)]
            assert not errors, (topic, errors[:3])
        stamp = payload.get("timestamp") or (payload["entities"] or payload["deletions"])[0]["timestamp"]
        conventions.check(topic, cls.TITLE, _at(_ns(stamp)), payload)
        kinds[cls.TITLE] += 1
    assert [m.position_covariance_type for _, m in made[:4]] == [0, 2, 3, 1]
    assert kinds["foxglove.LocationFix"] == 4 and kinds["foxglove.SceneUpdate"] == 2
    assert {m.level for _, m in made if type(m).__name__ == "Log"} >= {2, 3}  # INFO and WARNING lines


def test_every_foxglove_class_s_schema_is_foxglove_s() -> None:
    """The schema of every message class titled foxglove.* (what the log and the live server carry)."""
    classes = [cls for cls in MESSAGES if (cls.TITLE or "").startswith("foxglove.")]
    assert {cls.TITLE for cls in classes} == set(TOP_LEVEL)
    for cls in classes:
        assert embedded_differences(cls.TITLE, json_schema(cls)) == [], cls.TITLE


def test_the_table_finds_a_departure() -> None:
    """The comparison is not blind: a schema with a renamed field, another enum, or an optional field
    missing from "required" where Foxglove requires it is reported."""
    good = official_schema("foxglove.Log")
    assert embedded_differences("foxglove.Log", good) == []
    renamed = json.loads(json.dumps(good))
    renamed["properties"]["severity"] = renamed["properties"].pop("level")
    assert embedded_differences("foxglove.Log", renamed)
    levels = json.loads(json.dumps(good))
    levels["properties"]["level"]["oneOf"][0]["const"] = 7
    assert embedded_differences("foxglove.Log", levels)
    unrequired = json.loads(json.dumps(good))
    unrequired["required"].remove("file")
    assert embedded_differences("foxglove.Log", unrequired) == ["foxglove.Log.file: required by Foxglove"]


def _at(ns: int) -> Message:
    return Message(channel_id=0, sequence=0, log_time=ns, publish_time=ns, data=b"")


def _nmea(body: str) -> bytes:
    checksum = 0
    for byte in body.encode():
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode()


GGA_FAR = "GPGGA,000000.00,5924.0000,N,01030.0000,E,2,12,0.8,1e308,M,1e308,M,,"
"""A GGA whose height and geoid separation are finite but whose sum (the ellipsoidal height) is not."""


@pytest.mark.parametrize(
    ("gst", "kind"),
    [
        ("GPGST,000000.00,1.0,1e200,1e200,0.0,1e200,1e200,1e200", 0),  # every σ² overflows: no covariance
        ("GPGST,000000.00,1.0,2.0,1.0,30.0,1.9,1.1,1e200", 1),  # σ_alt² overflows: up approximated
        ("GPGST,000000.00,1.0,1e170,1.0,30.0,1.9,1.1,2.0", 2),  # a² overflows: σ lat / lon, diagonal
    ],
)
def test_a_fix_from_sentences_whose_squares_overflow_is_still_foxglove_s(gst: str, kind: int) -> None:
    """A receiver's σ or heights so large that squaring or adding them overflows a float: the fix on
    `/gnss/<source>/fix` must still be Foxglove's LocationFix (numbers, not the `null` JSON gives an
    infinity), with the covariance type of the figures that were usable."""
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    outs = p.feed(RawEvent(T0, "gps", _nmea(gst) + _nmea(GGA_FAR) + HDT))
    (fix,) = [o.message for o in outs if o.topic == "/gnss/gps/fix"]
    payload = json.loads(fix.encode())
    for schema in (json_schema(type(fix)), official_schema("foxglove.LocationFix")):
        errors = [e.message for e in Draft202012Validator(schema).iter_errors(payload)]
        assert not errors, errors[:3]
    Conventions().check("/gnss/gps/fix", "foxglove.LocationFix", _at(T0), payload)
    assert payload["position_covariance_type"] == kind
    assert payload["altitude"] == 0.0  # an ellipsoidal height that is not a number is not known


def test_the_conventions_find_a_departure() -> None:
    """The convention checks are not blind either: each departure below is caught."""
    pose = json.loads(fx.pose_in_frame(T0, 1.0, 2.0, 0.3).encode())
    fix = json.loads(
        fx.location_fix(T0, "gps", 63.4, 10.4, 0.0, GstCovariance(4.0, 1.0, 1.0, 9.0, AXES)).encode()
    )
    tf = json.loads(FrameTransforms(transforms=[fx.frame_transform(T0, fx.VESSEL_FRAME, 0, 0, 0)]).encode())
    hull = json.loads(
        FoxgloveChannels(pipeline([nmea_src("gps", ["position", "heading"])]).spec.vessel)._hull(T0).encode()
    )

    def bad(name: str, payload: dict[str, Any], change: Any, log_ns: int = T0) -> None:
        changed = json.loads(json.dumps(payload))
        change(changed)
        with pytest.raises(AssertionError):
            c = Conventions()
            c.check("/dp/tf", "foxglove.FrameTransforms", _at(T0), tf)
            c.check("/x", name, _at(log_ns), changed)
            c.check_frames()

    bad("foxglove.PoseInFrame", pose, lambda p: p["pose"]["orientation"].update(w=2.0))  # not a rotation
    bad("foxglove.PoseInFrame", pose, lambda p: p.update(frame_id="nowhere"))  # a frame not in the tree
    bad("foxglove.PoseInFrame", pose, lambda p: None, log_ns=T0 + 1)  # stamp is not the log time
    bad("foxglove.LocationFix", fix, lambda p: p.update(position_covariance_type=2))  # diagonal, it is not
    bad("foxglove.LocationFix", fix, lambda p: p["position_covariance"].__setitem__(1, 0.5))  # not symmetric
    bad("foxglove.LocationFix", fix, lambda p: p.update(latitude=91.0))
    bad("foxglove.SceneUpdate", hull, lambda p: p["entities"][0]["arrows"][0]["color"].update(r=1.5))
    bad(
        "foxglove.SceneUpdate",
        hull,
        lambda p: p["entities"][0]["metadata"].append(dict(key="vessel", value="x")),
    )
    deletion = {"deletions": [{"timestamp": hull["entities"][0]["timestamp"], "type": 0, "id": "hull"}],
                "entities": []}  # fmt: skip
    with pytest.raises(AssertionError):  # a deletion no later than the entity it deletes deletes nothing
        c = Conventions()
        c.check("/dp/scene/hull", "foxglove.SceneUpdate", _at(T0), hull)
        c.check("/dp/scene/hull", "foxglove.SceneUpdate", _at(T0), deletion)


@pytest.mark.parametrize(("lat", "lon"), [(120.0, 10.5), (59.4, 200.0), (-214.7483647, -214.7483647)])
def test_a_mavlink_position_out_of_range_is_counted_never_fused_nor_drawn(lat: float, lon: float) -> None:
    """GPS_RAW_INT's latitude and longitude are int32 in 1e-7 degrees, which holds ±214.7°: such a fix is
    no WGS-84 position (Foxglove's LocationFix has latitude and longitude in degrees). It is counted, not
    written as a LocationFix, and not fused: the next real fix is used (before, the first such fix moved
    the estimate thousands of kilometres and the real fixes after it were rejected as jumps)."""
    p = pipeline([mav_src("ap", ["position", "heading"])], vessel="cybership2")
    d, mav = mv.dialect(), mv.encoder(1, 1)
    real_lat, real_lon, _ = LocalFrame(*DATUM).to_geodetic(3.0, -2.0, 0.0)
    outs = []
    for k, (la, lo) in enumerate([(lat, lon), (real_lat, real_lon)]):
        frames = mv.pack(mav, d.MAVLink_attitude_message(k, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
        fix = d.MAVLink_gps_raw_int_message(k, 3, round(la * 1e7), round(lo * 1e7), 0, 100, 100, 0, 0, 12)
        outs += p.feed(RawEvent(T0 + k * S, "ap", frames + mv.pack(mav, fix)))
    fixes = [o.message for o in outs if o.topic == "/gnss/ap/fix"]
    assert [(f.latitude, f.longitude) for f in fixes] == [
        (round(real_lat * 1e7) / 1e7, round(real_lon * 1e7) / 1e7)
    ]
    assert p.counters["ap"].rejected == {"position_out_of_range": 1}
    est = [o.message for o in outs if o.topic == "/dp/estimate"][-1]
    np.testing.assert_allclose(est.eta[:2], [3.0, -2.0], atol=0.5)


_SIGMA = st.one_of(
    st.just(""), st.floats(0.0, 1e308).map(repr), st.floats(0.0, 50.0).map(lambda x: f"{x:.3f}")
)
_HEIGHT = st.one_of(
    st.just(""), st.floats(-1e308, 1e308).map(repr), st.floats(-100.0, 100.0).map(lambda x: f"{x:.1f}")
)


@settings(max_examples=150, deadline=None)
@given(
    sigmas=st.tuples(_SIGMA, _SIGMA, st.floats(0.0, 179.9).map(lambda x: f"{x:.1f}"), _SIGMA, _SIGMA, _SIGMA),
    alt=_HEIGHT,
    sep=_HEIGHT,
)
def test_every_gnss_fix_a_receiver_can_send_is_foxglove_s(
    sigmas: tuple[str, ...], alt: str, sep: str
) -> None:
    """Whatever σ, orientation, height and geoid separation a GST and a GGA carry (any finite figure the
    decoder takes, up to the float's limit, or none), the fix on `/gnss/<source>/fix` is Foxglove's
    LocationFix: it validates and keeps Foxglove's covariance conventions."""
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    gst = _nmea("GPGST,000000.00,1.0," + ",".join(sigmas))
    gga = _nmea(f"GPGGA,000000.00,5924.0000,N,01030.0000,E,2,12,0.8,{alt},M,{sep},M,,")
    outs = p.feed(RawEvent(T0, "gps", gst + gga + HDT))
    for o in outs:
        if o.topic == "/gnss/gps/fix":
            payload = json.loads(o.message.encode())
            errors = [e.message for e in _OFFICIAL_FIX.iter_errors(payload)]
            assert not errors, errors[:3]
            Conventions().check(o.topic, "foxglove.LocationFix", _at(T0), payload)
    assert any(o.topic == "/gnss/gps/fix" for o in outs) or p.counters["gps"].rejected


_OFFICIAL_FIX = Draft202012Validator(official_schema("foxglove.LocationFix"))
