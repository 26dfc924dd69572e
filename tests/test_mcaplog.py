"""MCAP log: schema contract, chunk bound, crash safety (kill -9 / SIGTERM), rotation, JSON edge cases.

Payloads are checked with the `jsonschema` package against the schema embedded in each channel."""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import wait_for
from hypothesis import given, settings
from hypothesis import strategies as st
from jsonschema import Draft202012Validator
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from wire.json_payload import encode_json, to_jsonable
from wire.mcap.fast import FastWriter
from wire.mcap.reader import log_files, read_messages, read_metadata, summary
from wire.mcap.rotation import rotated_path
from wire.mcap.writer import McapLogWriter
from wire.message_schema import json_schema
from wire.messages import Estimate, LocationFix, message_for_topic

REPO = Path(__file__).resolve().parents[1]
T0 = 1_750_000_000_000_000_000  # a UTC time in ns
KIB = 1024


def sample_payloads(stamp: int) -> dict[str, dict[str, Any]]:
    """One valid payload per schema'd topic, as the pipeline would hand them over (numpy inside)."""
    v = np.array([1.5, -2.0, 0.25])
    return {
        "/dp/estimate": {
            "stamp_ns": stamp,
            "observer": "passive",
            "status": "ok",
            "eta": v,
            "nu": v * 0.1,
            "bias": np.array([1e3, -2e3, 5e4]),
            "eta_wf": np.zeros(3),
            "omega0": np.full(3, 0.8),
            "lat_deg": 63.43,
            "lon_deg": 10.39,
            "heading_deg": np.float64(14.3),
            "datum": {"lat_deg": 63.43, "lon_deg": 10.39},
            "weights": [0.2, 0.8],  # an extra field (MMAE) must be accepted
        },
        "/dp/measurement": {
            "stamp_ns": stamp,
            "eta": [1.0, float("nan"), 0.1],
            "valid": [True, False, True],
            "sources": ["dgps1", "gyro1"],
            "quality": {"dgps1": {"fix_quality": 2, "hdop": 0.9}},
            "sigma_m": None,
            "tau": v,
            "tau_source": "demand",
        },
        "/dp/thrusters/command": {
            "stamp_ns": stamp,
            "mode": "dp",
            "tau_demand": v,
            "tau_allocated": v,
            "saturated": False,
            "thrusters": [{"id": i, "thrust_n": 1e4 * i, "azimuth_rad": 0.1 * i} for i in range(3)],
            "reference": v,
        },
        "/dp/thrusters/feedback": {
            "stamp_ns": stamp,
            "thrusters": [{"id": "bow", "thrust_n": np.float32(5e3), "azimuth_rad": 1.57, "rpm": 300}],
        },
        "/dp/status": {
            "stamp_ns": stamp,
            "mode": "dp",
            "observer": "passive",
            "initialized": True,
            "estimates": 99,
            "sources": {
                "dgps1": {"age_s": 0.1, "received": 100, "rejected": {"checksum": 2}, "bytes": 7000},
                "gyro1": {"age_s": None, "received": 0, "rejected": {}, "bytes": 0},
            },
            "alarms": ["dgps1 stale", {"code": "E1", "message": "x"}],
        },
        "/dp/setpoint": {"north_m": 1.0, "east_m": 2.0, "heading_deg": 90.0},
        "/dp/mode": {"mode": "manual"},
        "/dp/tau": {"X": 1.0, "Y": 0.0, "N": -3.0},
        "/truth/state": {
            "stamp_ns": stamp,
            "eta_lf": v,
            "nu": v,
            "bias": v,
            "eta_wf": v,
            "omega0": v,
        },
    }


def write_all_topics(path: Path, n: int = 20) -> None:
    with McapLogWriter(path) as w:
        for i in range(n):
            t = T0 + i * 100_000_000
            for topic, payload in sample_payloads(t).items():
                w.write(topic, payload, t + 1000, t)
            w.write_raw_nmea("dgps1", f"$GPGGA,{i}*00\r\n", t)
            w.write_raw_nmea("dgps1", b"$GPGGA,\xff\x00*00", t)  # garbage is logged too
            w.write_raw_mavlink("thr", bytes(range(i, i + 20)), t)
            assert w.write_location_fix("dgps1", 63.43, 10.39, t, heading_rad=0.2)
            w.write_location_fix("est", 63.43, 10.39, t, position_covariance=np.eye(3), covariance_type=2)
            w.write("/something/else", {"x": i}, t)


# --- the schema contract ------------------------------------------------------------------------------------


def test_file_opens_with_mcap_reader_and_messages_validate(tmp_path: Path) -> None:
    path = tmp_path / "all.mcap"
    write_all_topics(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        s = reader.get_summary()
        assert s is not None
        topics = {ch.topic for ch in s.channels.values()}
        assert set(sample_payloads(0)) <= topics
        assert {"/raw/nmea/dgps1", "/raw/mavlink/thr", "/gnss/dgps1/fix", "/gnss/est/fix"} <= topics
        for ch in s.channels.values():
            assert ch.message_encoding == "json"
            assert s.schemas[ch.schema_id].encoding == "jsonschema"
        count = 0
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            payload = json.loads(message.data)
            errors = [e.message for e in Draft202012Validator(json.loads(schema.data)).iter_errors(payload)]
            assert not errors, (channel.topic, errors)
            assert schema.name == message_for_topic(channel.topic).TITLE
            count += 1
        assert count == 20 * 15


def test_location_fix_has_foxglove_fields(tmp_path: Path) -> None:
    path = tmp_path / "fix.mcap"
    write_all_topics(path, n=2)
    fixes = list(read_messages(path, topics="/gnss/est/fix"))
    assert len(fixes) == 2
    topic, _, publish_time, fix = fixes[0]
    assert set(fix) == {
        "timestamp",
        "frame_id",
        "latitude",
        "longitude",
        "altitude",
        "position_covariance",
        "position_covariance_type",
    }
    assert fix["timestamp"] == {"sec": publish_time // 10**9, "nsec": publish_time % 10**9}
    assert fix["position_covariance"] == np.eye(3).ravel().tolist()
    assert summary(path).channels[topic].schema_name == "foxglove.LocationFix"


def test_non_finite_fix_is_not_logged(tmp_path: Path) -> None:
    with McapLogWriter(tmp_path / "nan_fix.mcap") as w:
        assert not w.write_location_fix("gps", math.nan, 10.0, T0)
        assert w.write_location_fix(
            "gps", 63.0, 10.0, T0, position_covariance=[math.nan] * 9, covariance_type=3
        )
    ((_, _, _, fix),) = read_messages(tmp_path / "nan_fix.mcap")
    assert fix["position_covariance"] == [0.0] * 9 and fix["position_covariance_type"] == 0


def test_schemas_reject_contract_violations() -> None:
    estimate = Draft202012Validator(json_schema(Estimate))
    good = to_jsonable(sample_payloads(T0)["/dp/estimate"])
    assert estimate.is_valid(good)  # an extra field (MMAE `weights`) included
    assert not estimate.is_valid({**good, "status": "fine"})
    assert not estimate.is_valid({**good, "eta": [1.0, 2.0]})
    assert not estimate.is_valid({k: v for k, v in good.items() if k != "nu"})
    assert not estimate.is_valid({**good, "stamp_ns": 1.5})
    assert estimate.is_valid({**good, "datum": None})
    assert estimate.is_valid({**good, "lat_deg": None, "eta": [None, 1.0, 2.0]})  # NaN is logged as null
    fix = Draft202012Validator(json_schema(LocationFix))
    assert any(e.validator == "oneOf" for e in fix.iter_errors({"position_covariance_type": 4}))
    assert not fix.is_valid({**to_jsonable(_a_fix()), "latitude": None})  # Foxglove's numbers: no null


def _a_fix() -> dict[str, Any]:
    return {
        "timestamp": {"sec": 1, "nsec": 2},
        "frame_id": "gps",
        "latitude": 63.0,
        "longitude": 10.0,
        "altitude": 0.0,
        "position_covariance": [0.0] * 9,
        "position_covariance_type": 0,
    }


def test_topic_lookup() -> None:
    assert message_for_topic("/raw/nmea/gyro1").TITLE == "dpgw.RawNmea"
    assert message_for_topic("/raw/mavlink/thr").TITLE == "dpgw.RawMavlink"
    assert message_for_topic("/dp/estimate/fix").TITLE == "foxglove.LocationFix"
    assert message_for_topic("/dp/estimates/T9").TITLE == "dpgw.Estimate"
    assert message_for_topic("/gnss/dgps1/fix").TITLE == "foxglove.LocationFix"
    assert message_for_topic("/raw/nmea/").TITLE == "dpgw.Any"
    assert message_for_topic("/unknown").TITLE == "dpgw.Any"


# --- chunks -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("compression", ["zstd", "none"])
def test_chunks_stay_within_256_kib(tmp_path: Path, compression: str) -> None:
    path = tmp_path / "big.mcap"
    rng = np.random.default_rng(1)
    with McapLogWriter(
        path, flush_interval_s=1e6, background_flush=False, compression=compression, fsync=False
    ) as w:
        for i in range(3000):  # ~1.5 MB of JSON, messages of very different sizes
            w.write(f"/t{i % 7}", {"i": i, "blob": "x" * int(rng.integers(0, 1500))}, T0 + i)
    with open(path, "rb") as f:
        s = make_reader(f).get_summary()
        assert s is not None
        sizes = [c.uncompressed_size for c in s.chunk_indexes]
        assert len(sizes) >= 6
        assert max(sizes) <= 256 * KIB
        assert max(sizes) > 240 * KIB  # the bound, not the flush timer, closed the chunks
        assert max(c.chunk_length for c in s.chunk_indexes) <= 256 * KIB
        f.seek(0)
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
        assert [c.uncompressed_size for c in chunks] == sizes
    assert [p[3]["i"] for p in read_messages(path)] == list(range(3000))


def test_oversize_message_gets_its_own_chunk(tmp_path: Path) -> None:
    path = tmp_path / "huge.mcap"
    with McapLogWriter(path, chunk_size=4 * KIB, background_flush=False, fsync=False) as w:
        for i in range(5):
            w.write("/t", {"i": i, "blob": "y" * (10 * KIB if i == 2 else 10)}, T0 + i)
    assert [p[3]["i"] for p in read_messages(path)] == list(range(5))
    assert summary(path).chunk_count == 3


# --- crash safety -------------------------------------------------------------------------------------------

WRITER_SCRIPT = textwrap.dedent(
    """
    import signal, sys, time
    from wire.mcap.writer import McapLogWriter

    stop = False

    def on_term(signum, frame):
        global stop
        stop = True  # never close() inside a handler: the interrupted frame may be mid-write

    signal.signal(signal.SIGTERM, on_term)
    w = McapLogWriter(sys.argv[1])
    print("ready", flush=True)
    i, next_t = 0, time.monotonic()
    while not stop:
        t = time.time_ns()
        w.write("/dp/tick", {"i": i, "stamp_ns": t}, t, t)
        w.write_raw_nmea("gyro", "$HEHDT,123.4,T*2B", t, t)
        print("wrote", i, t, flush=True)  # what the writer had accepted when it was killed
        i += 1
        next_t += 0.02  # 50 Hz
        time.sleep(max(0.0, next_t - time.monotonic()))  # pacing, so the file grows at a known rate
    w.close()
    print("closed", i, flush=True)
    """
)


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def start_writer(path: Path) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER_SCRIPT, str(path)],
        stdout=subprocess.PIPE,
        text=True,
        env=_env(),
        cwd=REPO,
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "ready"
    return proc


def ticks(path: Path) -> list[tuple[int, int]]:
    return [(payload["i"], log_time) for _, log_time, _, payload in read_messages(path, topics=["/dp/tick"])]


@pytest.mark.slow
def test_kill_9_loses_at_most_about_one_second(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    proc = start_writer(path)
    try:
        # kill once the file holds more than 1.5 s of ticks (so flushes have happened while writing)
        assert wait_for(lambda: len(ticks(path)) > 50 * 1.5, 60.0), "the writer saved nothing for 60 s"
        kill_ns = time.time_ns()
        proc.send_signal(signal.SIGKILL)
        out, _ = proc.communicate(timeout=10)
    finally:
        proc.kill()
    accepted = [line.split() for line in out.splitlines() if line.startswith("wrote")]
    last_accepted_ns = int(accepted[-1][2])
    saved = ticks(path)
    assert [i for i, _ in saved] == list(range(len(saved)))  # a clean prefix: nothing lost before the cut
    lost_s = (last_accepted_ns - saved[-1][1]) / 1e9
    assert lost_s <= 1.0 + 0.1, f"lost {lost_s:.2f} s of accepted messages"
    assert (kill_ns - saved[-1][1]) / 1e9 < 2.0  # the same seen from outside, with room for a slow machine
    assert len(saved) > 50 * 1.5
    info = summary(path)
    assert not info.complete
    assert info.channels["/dp/tick"].message_count == len(saved)
    assert info.channels["/raw/nmea/gyro"].schema_name == "dpgw.RawNmea"


def test_sigterm_closes_the_file_cleanly(tmp_path: Path) -> None:
    path = tmp_path / "terminated.mcap"
    proc = start_writer(path)
    try:
        # terminate a writer that has messages both on disk and in its open chunk
        assert wait_for(lambda: len(ticks(path)) >= 10, 60.0), "the writer saved nothing for 60 s"
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0
    written = int(out.split()[-1])  # "closed <n>"
    with open(path, "rb") as f:
        s = make_reader(f).get_summary()
    assert s is not None and s.statistics is not None
    assert s.statistics.message_count == 2 * written
    assert [i for i, _ in ticks(path)] == list(range(written))
    assert summary(path).complete


def test_exit_without_close_still_finishes_the_file(tmp_path: Path) -> None:
    path = tmp_path / "forgot.mcap"
    code = "import sys; from wire.mcap.writer import McapLogWriter; w = McapLogWriter(sys.argv[1]); "
    code += "w.write('/t', {'i': 1}, 1); raise SystemExit(3)"
    proc = subprocess.run([sys.executable, "-c", code, str(path)], cwd=REPO, env=_env(), timeout=30)
    assert proc.returncode == 3
    assert summary(path).complete and summary(path).message_count == 1


def test_wall_clock_flush_without_further_writes(tmp_path: Path) -> None:
    path = tmp_path / "idle.mcap"
    w = McapLogWriter(path, flush_interval_s=0.5)
    try:
        for i in range(3):
            w.write("/t", {"i": i}, T0)
        assert list(read_messages(path)) == []  # still in the open chunk
        # no more writes: the background thread must hand the chunk over on its own
        assert wait_for(lambda: [p[3]["i"] for p in read_messages(path)] == [0, 1, 2], 10.0)
    finally:
        w.close()


def test_log_time_flush(tmp_path: Path) -> None:
    """Replay writes 5 s of log time in far less wall time: still at most ~1 s of log time unsaved."""
    path = tmp_path / "replay.mcap"
    w = McapLogWriter(path, background_flush=False, fsync=False)
    try:
        for i in range(500):
            w.write("/t", {"i": i}, T0 + i * 10_000_000)
        last = list(read_messages(path))[-1]
        assert (T0 + 499 * 10_000_000 - last[1]) / 1e9 <= 1.0
    finally:
        w.close()


def test_chunk_closing_works_without_writer_flush(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """mcap < 1.6 has no Writer.flush(); the private fallback must close chunks the same way."""
    monkeypatch.delattr(Writer, "flush")
    path = tmp_path / "old_mcap.mcap"
    w = McapLogWriter(path, background_flush=False, fsync=False)
    try:
        for i in range(300):
            w.write("/t", {"i": i}, T0 + i * 10_000_000)
        saved = [p[3]["i"] for p in read_messages(path)]
        assert 200 <= len(saved) < 300 and saved == list(range(len(saved)))
    finally:
        w.close()
    assert [p[3]["i"] for p in read_messages(path)] == list(range(300))


def test_truncated_at_any_byte_reads_a_prefix(tmp_path: Path) -> None:
    path = tmp_path / "full.mcap"
    with McapLogWriter(path, chunk_size=2 * KIB, background_flush=False, fsync=False) as w:
        for i in range(300):
            w.write(f"/t{i % 3}", {"i": i, "v": [i, i * 0.5]}, T0 + i)
    full = [p[3]["i"] for p in read_messages(path)]
    assert full == list(range(300))
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    seen = set()
    for n in range(0, len(data), max(1, len(data) // 300)):
        cut.write_bytes(data[:n])
        got = [p[3]["i"] for p in read_messages(cut)]
        assert got == full[: len(got)]
        seen.add(len(got))
        info = summary(cut)
        assert info.message_count == len(got)
        assert sum(c.message_count for c in info.channels.values()) == len(got)
    assert len(seen) >= 8 and max(seen) == 300  # the cuts fell all over the data section and summary


def test_metadata_is_read_from_a_cut_file(tmp_path: Path) -> None:
    """The configuration a log carries (a Metadata record right after the header) is found in a file cut
    by kill -9 or power loss, which has no metadata index: replay runs such a log on its own config."""
    path = tmp_path / "full.mcap"
    meta = {"json": json.dumps({"vessel": {"name": "mss_supply"}}), "prefix": "dp/x"}
    with McapLogWriter(path, chunk_size=2 * KIB, background_flush=False, fsync=False) as w:
        w.add_metadata("dpgw.config", meta)
        for i in range(300):
            w.write("/t", {"i": i}, T0 + i)
    assert read_metadata(path) == [("dpgw.config", meta)]
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    after_metadata = len(data) // 2  # well past the header and the Metadata record, inside the chunks
    assert 0 < data.find(b"dpgw.config") < after_metadata
    for n in range(after_metadata, len(data), max(1, len(data) // 50)):
        cut.write_bytes(data[:n])
        assert read_metadata(cut) == [("dpgw.config", meta)], n
    for n in (0, 4, 8, 20):  # cut before the record is complete: none, and no error
        cut.write_bytes(data[:n])
        assert read_metadata(cut) == []


# --- rotation -----------------------------------------------------------------------------------------------


def test_rotation_by_size(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with McapLogWriter(
        path,
        chunk_size=4 * KIB,
        rotate_bytes=16 * KIB,
        background_flush=False,
        compression="none",
        fsync=False,
    ) as w:
        for i in range(2000):
            w.write("/dp/tick", {"i": i, "pad": "z" * 20}, T0 + i * 1000)
            w.write_raw_nmea("gps", f"$GPGGA,{i}", T0 + i * 1000)
    files = log_files(path)
    assert files == w.paths
    assert [f.name for f in files[:3]] == ["run.mcap", "run_0001.mcap", "run_0002.mcap"]
    assert len(files) >= 5
    for f in files[:-1]:
        info = summary(f)
        assert info.complete
        assert set(info.channels) == {"/dp/tick", "/raw/nmea/gps"}  # every file self-contained
        assert 16 * KIB <= f.stat().st_size <= 16 * KIB + 4 * KIB + 8 * KIB  # + one chunk + summary
    got = [p[3]["i"] for p in read_messages(files, topics="/dp/tick")]
    assert got == list(range(2000))  # nothing lost, nothing duplicated, in order
    assert sum(1 for _ in read_messages(files, topics="/raw/nmea/gps")) == 2000


def test_rotation_by_log_time(tmp_path: Path) -> None:
    path = tmp_path / "trial.mcap"
    with McapLogWriter(path, rotate_seconds=1.0, background_flush=False, fsync=False) as w:
        for i in range(46):  # 10 Hz for 4.5 s
            w.write("/dp/tick", {"i": i}, T0 + i * 100_000_000)
    files = log_files(path)
    assert files == [rotated_path(path, k) for k in range(5)]
    per_file = [[p[3]["i"] for p in read_messages(f)] for f in files]
    assert per_file == [list(range(k * 10, min(k * 10 + 10, 46))) for k in range(5)]
    for f in files:
        info = summary(f)
        assert info.complete and info.start_ns is not None and info.end_ns is not None
        assert info.end_ns - info.start_ns < 1_000_000_000


# --- JSON ---------------------------------------------------------------------------------------------------


def test_numpy_and_non_finite_values(tmp_path: Path) -> None:
    path = tmp_path / "nan.mcap"
    payload = {
        "a": np.array([1.0, np.nan, np.inf, -np.inf]),
        "m": np.arange(4.0).reshape(2, 2),
        "f32": np.float32(0.5),
        "f64": np.float64("nan"),
        "i": np.int64(2**40),
        "b": np.bool_(True),
        "nested": {"x": [float("nan"), (1, np.int32(2))]},
        "ints": np.array([1, 2], dtype=np.uint8),
    }
    with McapLogWriter(path) as w:
        w.write("/x", payload, T0)
    ((_, _, _, got),) = read_messages(path)
    assert got == {
        "a": [1.0, None, None, None],
        "m": [[0.0, 1.0], [2.0, 3.0]],
        "f32": 0.5,
        "f64": None,
        "i": 2**40,
        "b": True,
        "nested": {"x": [None, [1, 2]]},
        "ints": [1, 2],
    }
    raw = path.read_bytes()
    assert b"NaN" not in raw and b"Infinity" not in raw
    with pytest.raises(TypeError):
        encode_json({"c": 1j})


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner, max_size=4),
    max_leaves=20,
)


def _expected(v: Any) -> Any:
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, list):
        return [_expected(x) for x in v]
    if isinstance(v, dict):
        return {k: _expected(x) for k, x in v.items()}
    return v


@settings(max_examples=100, deadline=None)
@given(json_values)
def test_encode_json_round_trips_with_null_for_non_finite(value: Any) -> None:
    assert json.loads(encode_json(value)) == _expected(value)


# --- threads, lifecycle -------------------------------------------------------------------------------------


def test_many_threads_writing(tmp_path: Path) -> None:
    path = tmp_path / "threads.mcap"
    n_threads, n_each = 8, 400
    with McapLogWriter(
        path, chunk_size=8 * KIB, flush_interval_s=0.01, rotate_bytes=64 * KIB, fsync=False
    ) as w:

        def work(k: int) -> None:
            for i in range(n_each):
                t = time.time_ns()
                w.write(f"/thread/{k % 3}", {"k": k, "i": i, "v": np.full(3, i * 0.1)}, t)

        threads = [threading.Thread(target=work, args=(k,)) for k in range(n_threads)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    files = log_files(path)
    assert len(files) > 1
    got = sorted((p[3]["k"], p[3]["i"]) for p in read_messages(files))
    assert got == sorted((k, i) for k in range(n_threads) for i in range(n_each))
    assert all(summary(f).complete for f in files)


def test_close_is_idempotent_and_later_writes_are_dropped(tmp_path: Path) -> None:
    path = tmp_path / "closed.mcap"
    w = McapLogWriter(path)
    w.add_metadata("config", {"vessel": "supply"})
    w.write("/t", {"i": 0}, T0)
    w.close()
    w.close()
    assert w.closed
    w.write("/t", {"i": 1}, T0 + 1)
    assert [p[3] for p in read_messages(path)] == [{"i": 0}]
    with open(path, "rb") as f:
        assert [m.metadata for m in make_reader(f).iter_metadata()] == [{"vessel": "supply"}]


def test_bad_path_fails_at_start_up(tmp_path: Path) -> None:
    with pytest.raises(OSError):
        McapLogWriter(tmp_path / "no" / "such" / "dir" / "x.mcap")
    with pytest.raises(ValueError):
        McapLogWriter(tmp_path / "x.mcap", compression="brotli")


# --- FastWriter: the library's Writer with a one-pack add_message -------------------------------------------

_messages = st.lists(
    st.tuples(
        st.integers(0, 2),  # channel
        st.integers(0, 2**63 - 1),  # log time
        st.binary(max_size=300),
        st.integers(0, 2**32 - 1),  # sequence
        st.booleans(),  # flush (close the chunk) before this message
    ),
    max_size=60,
)


def _write_with(
    cls: type[Writer],
    messages: list[tuple[int, int, bytes, int, bool]],
    fast: bool,
    compression: CompressionType = CompressionType.NONE,
) -> bytes:
    import io

    buf = io.BytesIO()
    w = cls(buf, chunk_size=700, compression=compression)
    if not fast:
        w.fast = False  # type: ignore[attr-defined]
        w._zstd = None  # type: ignore[attr-defined]
    w.start(profile="", library="dpgw")
    sid = w.register_schema("s", "jsonschema", b"{}")
    ids = [w.register_channel(f"/c{k}", "json", sid) for k in range(3)]
    for ch, log_ns, data, seq, flush in messages:
        if flush:
            w.flush()
        w.add_message(ids[ch], log_ns, data, log_ns // 2, seq)
    w.finish()
    return buf.getvalue()


@settings(max_examples=150, deadline=None)
@given(_messages)
def test_fast_writer_writes_the_same_bytes_as_the_library(messages: list[Any]) -> None:
    """FastWriter's add_message must be indistinguishable from mcap.Writer's: same file, byte for byte
    (statistics, chunk times, message indexes, chunk boundaries)."""
    reference = _write_with(Writer, messages, fast=True)
    fast = _write_with(FastWriter, messages, fast=True)
    assert FastWriter(__import__("io").BytesIO()).fast  # the installed mcap has what the fast path needs
    assert fast == reference
    assert _write_with(FastWriter, messages, fast=False) == reference  # the fallback path too


@settings(max_examples=80, deadline=None)
@given(_messages)
def test_fast_writer_compresses_zstd_chunks_as_the_library_does(messages: list[Any]) -> None:
    """FastWriter closes zstd chunks with one compressor for its life (the library makes one per chunk):
    same file, byte for byte, and the fallback (the library's own chunk closing) too."""
    reference = _write_with(Writer, messages, fast=True, compression=CompressionType.ZSTD)
    assert FastWriter(__import__("io").BytesIO())._zstd is not None  # the installed mcap has what it needs
    assert _write_with(FastWriter, messages, fast=True, compression=CompressionType.ZSTD) == reference
    assert _write_with(FastWriter, messages, fast=False, compression=CompressionType.ZSTD) == reference


# --- write_many: a cycle's messages in one call ---------------------------------------------------------


@pytest.mark.parametrize("rotate_bytes", [None, 6 * KIB])
def test_write_many_writes_what_write_encoded_writes(tmp_path: Path, rotate_bytes: int | None) -> None:
    """Replay hands each cycle's raw input and outputs to `write_many`: the files (and where they split on
    rotation by size) must be those of one `write_encoded` call per message, byte for byte."""
    from wire.mcap.writer import raw_nmea_record
    from wire.messages import RawNmea

    rng = np.random.default_rng(3)
    cycles = []
    for k in range(400):
        t = T0 + k * 100_000_000
        topic, raw = raw_nmea_record("gps", f"$GPHDT,{rng.uniform(0, 360):.3f},T*00\r\n".encode())
        est = Estimate(
            stamp_ns=t, observer="passive", status="ok", eta=rng.normal(size=3).tolist(), nu=[0.0] * 3,
            bias=[0.0] * 3, eta_wf=[0.0] * 3, omega0=[0.8] * 3, lat_deg=None, lon_deg=None,
            heading_deg=1.0, datum=None,
        )  # fmt: skip
        cycles.append([(topic, raw, t, RawNmea), ("/dp/estimate", est.encode(), t, Estimate)])
    files = {}
    for mode in ("one_by_one", "many"):
        path = tmp_path / mode / "log.mcap"
        path.parent.mkdir()
        opts = {"flush_on_log_time": False, "background_flush": False, "flush_interval_s": 3600.0}
        with McapLogWriter(path, chunk_size=4 * KIB, rotate_bytes=rotate_bytes, **opts) as w:
            for records in cycles:
                if mode == "many":
                    w.write_many(records)
                else:
                    for topic, data, t, schema in records:
                        w.write_encoded(topic, data, t, t, schema=schema)
        files[mode] = [p.read_bytes() for p in w.paths]  # (finished files: after close)
    assert len(files["many"]) == (1 if rotate_bytes is None else len(files["one_by_one"]))
    assert rotate_bytes is None or len(files["many"]) > 1  # (the rotation case does rotate)
    assert files["many"] == files["one_by_one"]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.lists(
            st.tuples(st.integers(0, 4), st.integers(0, 3 * KIB), st.integers(-2, 2)),  # topic, size, Δt
            min_size=1,
            max_size=8,
        ),
        max_size=40,
    )
)
def test_write_many_fast_path_matches_write_encoded(cycles: list[list[tuple[int, int, int]]]) -> None:
    """`write_many` without rotation takes an inlined loop (`_write_many_fast`): channels appearing
    mid-cycle, chunks closing mid-cycle, records larger than a chunk, times going backwards — the file
    must be that of one `write_encoded` call per message, byte for byte."""
    import tempfile

    from wire.messages import RawNmea

    files = {}
    with tempfile.TemporaryDirectory() as folder:
        for mode in ("one_by_one", "many"):
            path = Path(folder) / f"{mode}.mcap"
            opts = {"flush_on_log_time": False, "background_flush": False, "flush_interval_s": 3600.0}
            with McapLogWriter(path, chunk_size=2 * KIB, fsync=False, **opts) as w:
                t = T0
                for cycle in cycles:
                    records = []
                    for topic, size, dt in cycle:
                        t += dt * 1_000_000
                        records.append((f"/raw/nmea/s{topic}", b"x" * size, t, RawNmea))
                    if mode == "many":
                        w.write_many(records)
                    else:
                        for topic_name, data, ns, schema in records:
                            w.write_encoded(topic_name, data, ns, ns, schema=schema)
            files[mode] = path.read_bytes()
    assert files["many"] == files["one_by_one"]


# --- raw_nmea_record: the common chunk from a cached head -------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(
    st.text(st.characters(codec="utf-8"), max_size=12),  # source
    st.one_of(
        st.binary(max_size=120),
        st.binary(max_size=80).map(lambda b: b + b"\r\n"),
        st.text(st.characters(codec="ascii"), max_size=80).map(lambda s: (s + "\r\n").encode()),
        st.text(max_size=40),
        st.text(max_size=40).map(lambda s: s + "\n"),
    ),
    st.sampled_from(["", "10.0.0.2:4001"]),
)
def test_raw_nmea_record_matches_the_message(source: str, text: str | bytes, peer: str) -> None:
    """`raw_nmea_record` writes the common chunk (ASCII bytes, terminated, one sender) from a cached head:
    the same topic and payload bytes as the `RawNmea` message gives, for every chunk."""
    from wire.mcap.writer import raw_nmea_record, raw_nmea_record_reference

    assert raw_nmea_record(source, text, peer) == raw_nmea_record_reference(source, text, peer)
    assert raw_nmea_record(source, text, peer) == raw_nmea_record_reference(source, text, peer)  # (cached)


def test_raw_nmea_record_of_a_replay_chunk_is_the_message() -> None:
    """A USV cycle as replay hands it over: the fast form, and it reads back as the message."""
    from wire.mcap import writer
    from wire.mcap.writer import raw_nmea_record
    from wire.messages import RawNmea

    chunk = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n$GPHDT,274.07,T*03\r\n"
    topic, data = raw_nmea_record("log_2024", chunk)
    assert topic == "/raw/nmea/log_2024"
    assert data == RawNmea(source="log_2024", text=chunk.decode().rstrip("\r\n")).encode()
    assert json.loads(data) == {"source": "log_2024", "text": chunk.decode().rstrip("\r\n")}
    assert "log_2024" in writer._RAW_NMEA_HEADS  # (it took the cached head)


@settings(max_examples=300, deadline=None)
@given(
    st.one_of(
        st.binary(max_size=120),
        st.lists(st.sampled_from([b"$GPHDT,1.0,T*00", b"\r", b"\n", b"\r\n", b"\n\r", b"\x00", b"\xff"])).map(
            b"".join
        ),
    ),
    st.sampled_from(["", "10.0.0.2:4001"]),
)
def test_a_raw_nmea_chunk_reads_back_byte_for_byte(chunk: bytes, peer: str) -> None:
    """Whatever line terminator a chunk ends with (a bare LF, a CR, LF CR, blank lines, a CR LF split across
    two reads, none), the chunk replay rebuilds from the logged record is exactly the bytes received."""
    import base64

    from wire.mcap.writer import raw_nmea_record

    _, data = raw_nmea_record("gps", chunk, peer)
    p = json.loads(data)
    body = base64.b64decode(p["data"]) if "data" in p else p["text"].encode("ascii")
    end = b"" if p.get("unterminated") else p.get("eol", "\r\n").encode("ascii")
    assert body + end == chunk


# --- the disk fails while logging ---------------------------------------------------------------------------


def _ticks(path: Path) -> list[int]:
    return [p[3]["i"] for p in read_messages(log_files(path), topics="/dp/tick")]


def test_a_full_disk_never_raises_is_reported_once_and_writing_resumes(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The second file of the set is /dev/full (the kernel's own ENOSPC): writes never raise, the failure is
    one ERROR line, messages are dropped and counted, and writing resumes once the disk has room (here: the
    link removed)."""
    path = tmp_path / "run.mcap"
    full = rotated_path(path, 1)
    full.symlink_to("/dev/full")
    caplog.set_level(logging.DEBUG, logger="wire.mcap.writer")
    w = McapLogWriter(
        path, chunk_size=4 * KIB, rotate_bytes=16 * KIB, compression="none", fsync=False,
        background_flush=False, retry_s=0.0,
    )  # fmt: skip
    failed_at = None
    for i in range(3000):
        w.write("/dp/tick", {"i": i, "pad": "z" * 20}, T0 + i * 1000)
        if w.error is not None and failed_at is None:
            failed_at = i
            assert "No space left on device" in w.error and str(full) in w.error
        if failed_at is not None and i == failed_at + 100:
            full.unlink()  # room again
    w.close()
    assert failed_at is not None and w.error is None and w.failures == 1
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 1, [r.getMessage() for r in errors]  # once, not once per message
    resumed = [r.getMessage() for r in caplog.records if "writing again" in r.getMessage()]
    assert len(resumed) == 1 and "101 messages were not logged" in resumed[0]
    got = _ticks(path)
    assert got == sorted(got) and set(range(3000)) - set(got) == set(range(failed_at, failed_at + 101))
    assert w.lost == 101
    assert all(summary(f).complete for f in log_files(path))


def test_a_full_disk_at_start_up_starts_failed_and_a_bad_path_still_stops(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    path.symlink_to("/dev/full")
    w = McapLogWriter(path, background_flush=False, fsync=False, retry_s=3600.0)
    w.write("/dp/tick", {"i": 0}, T0)  # dropped, counted, no exception
    assert w.error is not None and "No space left on device" in w.error and w.lost == 1
    w.close()
    with pytest.raises(FileNotFoundError):
        McapLogWriter(tmp_path / "no" / "such" / "dir.mcap", background_flush=False)


def test_write_many_on_a_full_disk_counts_every_message_lost(tmp_path: Path) -> None:
    """Replay's `write_many` on a failed log drops the whole cycle and counts each of its messages, as
    one `write_encoded` per message would."""
    from wire.messages import RawNmea

    path = tmp_path / "run.mcap"
    path.symlink_to("/dev/full")
    w = McapLogWriter(path, background_flush=False, fsync=False, retry_s=3600.0)
    records = [(f"/raw/nmea/s{k}", b"$GPHDT,1.0,T*00", T0 + k, RawNmea) for k in range(3)]
    w.write_many(records)
    w.write_many(records[:2])
    assert w.error is not None and w.lost == 5
    w.close()


def test_the_log_directory_gone_at_a_rotation_then_back(tmp_path: Path) -> None:
    """The directory moved away (a disk unmounted, a careless rm) before a rotation: the new file cannot be
    opened; when it is back, writing goes on in the next file of the set."""
    logs = tmp_path / "logs"
    logs.mkdir()
    path = logs / "trial.mcap"
    w = McapLogWriter(path, rotate_seconds=1.0, background_flush=False, fsync=False, retry_s=0.0)
    for i in range(9):
        w.write("/dp/tick", {"i": i}, T0 + i * 100_000_000)
    logs.rename(tmp_path / "away")  # the open file goes with it (same inode): written on
    for i in range(9, 15):
        w.write("/dp/tick", {"i": i}, T0 + i * 100_000_000)  # 10: the rotation, and the failure
    assert w.error is not None and "No such file or directory" in w.error and str(path.parent) in w.error
    (tmp_path / "away").rename(logs)
    for i in range(15, 20):
        w.write("/dp/tick", {"i": i}, T0 + i * 100_000_000)
    w.close()
    assert w.error is None and w.lost == 5  # 10 .. 14
    assert _ticks(path) == [*range(10), *range(15, 20)]


def test_a_log_file_removed_while_written_is_noticed(tmp_path: Path) -> None:
    """Deleted under the writer, a file takes writes that nobody can ever read: the flush thread notices
    (within the flush interval) and writing goes on in the next file of the set."""
    path = tmp_path / "run.mcap"
    w = McapLogWriter(path, flush_interval_s=0.05, fsync=False, retry_s=0.0)
    try:
        w.write("/dp/tick", {"i": 0}, T0)
        path.unlink()
        assert wait_for(lambda: w.error is not None, 10.0), "the removal was not noticed"
        assert "removed" in (w.error or "")
        w.write("/dp/tick", {"i": 1}, T0 + 1000)
    finally:
        w.close()
    assert w.error is None and w.paths[-1] == rotated_path(path, 1)
    assert _ticks(path) == [1]


def test_a_restarted_writer_continues_the_set_and_overwrites_nothing(tmp_path: Path) -> None:
    path = tmp_path / "dpgw.mcap"
    with McapLogWriter(path, rotate_seconds=1.0, background_flush=False, fsync=False) as w:
        for i in range(25):
            w.write("/dp/tick", {"i": i}, T0 + i * 100_000_000)
    before = {f: f.read_bytes() for f in log_files(path)}
    assert len(before) == 3
    with McapLogWriter(path, continue_set=True, background_flush=False, fsync=False) as w2:
        w2.write("/dp/tick", {"i": 25}, T0 + 10**10)
    assert w2.paths == [rotated_path(path, 3)]
    assert {f: f.read_bytes() for f in before} == before
    assert _ticks(path) == list(range(26))


def test_rotate_starts_the_next_file_now_and_keeps_a_file_without_messages(tmp_path: Path) -> None:
    """`rotate` (a simulator started again under the gateway): the file is finished and the next of the set
    takes what follows, earlier log times included; a file with nothing in it yet is kept, not left empty."""
    from wire.mcap.reader import read_messages

    w = McapLogWriter(tmp_path / "run.mcap", background_flush=False, fsync=False)
    assert w.rotate() == tmp_path / "run.mcap"  # nothing written yet: the same file
    w.write("/dp/mode", {"mode": "dp"}, 100 * 10**9, 100 * 10**9)
    assert w.rotate() == tmp_path / "run_0001.mcap"
    w.write("/dp/mode", {"mode": "standby"}, 10 * 10**9, 10 * 10**9)  # the new run's time: earlier
    w.close()
    assert w.paths == [tmp_path / "run.mcap", tmp_path / "run_0001.mcap"]
    first = [(t, p) for _, t, _, p in read_messages(tmp_path / "run.mcap", "/dp/mode")]
    second = [(t, p) for _, t, _, p in read_messages(tmp_path / "run_0001.mcap", "/dp/mode")]
    assert [p["mode"] for _, p in first] == ["dp"] and [p["mode"] for _, p in second] == ["standby"]


def test_a_schema_is_made_once_per_message_class() -> None:
    """The writer looks a message's schema up at every write: it must be made once (a lost cache doubled
    replay's writing time, ~11 → ~25 µs a real-log cycle, with every file still correct)."""
    from wire.mcap.writer import _schema_bytes
    from wire.messages import Estimate

    assert _schema_bytes(Estimate) is _schema_bytes(Estimate)
