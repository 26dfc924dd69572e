"""A log's records are in log-time order in the file itself, the Foxglove log lines (`/dp/log`) of every
status included: a reader that streams the file (`mcap cat` on a pipe, Foxglove on an unindexed file, a
file cut short by a crash, read without its index) never sees time go back. Checked on what a live
gateway writes (real UDP input, a real log, a source going silent and back, so that periodic statuses
raise and clear alarms) and on a replay of that log, each read record by record with the `mcap` library's
stream reader, not through the index (which sorts)."""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace

import pytest
from conftest import free_port, stop_service, wait_for
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader

from gateway.config import parse_config
from gateway.foxglove_channels import FoxgloveChannels
from gateway.pipeline import RawEvent
from gateway.replay import build_pipeline, config_from_log, open_inputs, run_replay
from gateway.service import GatewayService
from tests.test_pipeline import T0, S, gga_at, nmea_src, pipeline
from tests.test_service import mux_tables
from wire.codecs import nmea_encode as enc
from wire.mcap.writer import McapLogWriter

HDT = enc.hdt("HE", 0.1).encode()


def file_order(path: Path) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of every message, in the order the file holds them (chunks decompressed by
    the stream reader, one record after another: no index, no sorting)."""
    topics: dict[int, str] = {}
    with path.open("rb") as f:
        for record in StreamReader(f, skip_magic=False).records:
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Message):
                yield topics[record.channel_id], record.log_time, record.data


def backward_steps(path: Path) -> list[tuple[str, int, str, int]]:
    """Every record whose log time is earlier than the record's before it: (topic before, its time, topic,
    time)."""
    steps, last = [], ("", 0)
    for topic, ns, _ in file_order(path):
        if ns < last[1]:
            steps.append((*last, topic, ns))
        last = (topic, ns)
    return steps


def log_lines_owed(path: Path) -> list[tuple[int, str, str]]:
    """(stamp, name, text) of every `/dp/log` line the log's statuses call for, in their order: each status
    read back and turned into lines by the same rule the gateway uses (`FoxgloveChannels.logs`)."""
    from observers.vessel import load_vessel

    channels = FoxgloveChannels(load_vessel("mss_supply"))
    owed = []
    for topic, _, data in file_order(path):
        if topic == "/dp/status":
            payload = json.loads(data)
            status = SimpleNamespace(
                stamp_ns=payload["stamp_ns"],
                events=payload.get("events", []),
                alarms=payload["alarms"],
                alarm_details=[SimpleNamespace(**d) for d in payload.get("alarm_details", [])],
            )
            for _, msg, ns in channels.logs(status):  # type: ignore[arg-type]
                owed.append((ns, msg.name, msg.message))  # type: ignore[attr-defined]
    return owed


def log_lines(path: Path) -> list[tuple[int, str, str]]:
    out = []
    for topic, ns, data in file_order(path):
        if topic == "/dp/log":
            line = json.loads(data)
            assert line["timestamp"]["sec"] * S + line["timestamp"]["nsec"] == ns
            out.append((ns, line["name"], line["message"]))
    return out


def burst() -> bytes:
    return (enc.gga("GP", datetime.now(UTC), 59.4, 10.5, 2, 12, 0.8, 20.0) + enc.hdt("HE", 0.5)).encode()


@pytest.fixture(scope="module")
def live_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A live gateway's log: data, a silence long enough for periodic statuses to raise the source's
    alarms while the gateway dead-reckons, data again (cleared), a second silence, and the stop."""
    tmp = tmp_path_factory.mktemp("order")
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    path = tmp / "live.mcap"
    tables = mux_tables(udp, zport, path, status_hz=10.0)
    tables["sources"][0]["timeout_s"] = 0.3
    service = GatewayService(parse_config(tables, base_dir=tmp), config_tables=tables)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    mux = service.pipeline.counters["mux"]

    def data_until(estimates: int) -> None:
        def sent() -> bool:
            tx.sendto(burst(), ("127.0.0.1", udp))
            return service.pipeline.estimates >= estimates

        assert wait_for(sent, 30.0), "estimates"

    def silent_for(s: float) -> None:
        # a periodic status made this long after the source's last chunk (so: with its alarms up)
        assert wait_for(lambda: service._status_ns - mux.last_rx_ns > s * S, 30.0), "a status in the silence"

    try:
        data_until(10)
        silent_for(1.0)
        data_until(service.pipeline.estimates + 10)
        silent_for(1.0)
    finally:
        tx.close()
        stop_service(service, loop)
    return path


def test_a_live_log_is_in_log_time_order_in_the_file(live_log: Path) -> None:
    assert backward_steps(live_log) == []


def test_a_live_log_holds_every_status_s_log_lines_once(live_log: Path) -> None:
    owed = log_lines_owed(live_log)
    names = {name for _, name, _ in owed}
    assert {"dpgw.alarm", "dpgw.reference"} <= names  # (the run did raise alarms and change states)
    assert any(text.startswith("alarm cleared: source mux: stale") for _, _, text in owed)
    assert log_lines(live_log) == owed  # none lost (the last status's too), none twice, each at its stamp


def assert_lines_follow_their_status(path: Path) -> None:
    records = list(file_order(path))
    for k, (topic, ns, _) in enumerate(records):
        if topic == "/dp/log":
            j = k - 1
            while records[j][0] == "/dp/log":
                j -= 1
            assert records[j][:2] == ("/dp/status", ns), (records[j][:2], ns)


def test_a_log_line_follows_its_status_at_once(live_log: Path) -> None:
    """Each status's lines are written right after it, so even a reader that stops at the status (a file cut
    there) has them, and nothing of a later time comes between."""
    assert_lines_follow_their_status(live_log)


def test_a_replay_writes_its_log_in_log_time_order(live_log: Path, tmp_path: Path) -> None:
    config = config_from_log(live_log)
    out_path = tmp_path / "replay.mcap"
    with McapLogWriter(str(out_path), profile="dpgw") as out:
        run_replay(open_inputs([live_log]), build_pipeline(config, []), out=out)
    assert backward_steps(out_path) == []
    owed = log_lines_owed(out_path)
    assert owed and log_lines(out_path) == owed
    assert_lines_follow_their_status(out_path)


# --- the pipeline directly ---------------------------------------------------------------------------------


def test_status_outputs_carry_the_status_s_log_lines_after_it() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=1.0)])
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + HDT))
    out = p.status_outputs(T0 + 3 * S)  # stale: the alarm raised by this status
    assert [o.topic for o in out] == ["/dp/status", "/dp/log"]
    assert {o.stamp_ns for o in out} == {T0 + 3 * S}
    assert out[1].payload["message"].startswith("alarm: source gps: stale")
    # nothing of it is left for later: the next tick (the state change to stale: its own status and lines)
    # says the alarm no more, and a status alone (`status`, for its content) makes no line
    # (the tick's dead-reckoned estimate raises an alarm of its own: `estimate dead reckoning …`)
    later = p.tick(T0 + 3 * S + 1)
    assert not any(
        o.topic == "/dp/log" and o.payload["name"] == "dpgw.alarm" and "source gps" in o.payload["message"]
        for o in later
    )
    assert p.status(T0 + 4 * S).topic == "/dp/status"
    assert [o.topic for o in p.tick(T0 + 4 * S + 1) if o.topic in ("/dp/status", "/dp/log")] == []


def test_the_last_status_of_a_run_brings_its_log_lines(tmp_path: Path) -> None:
    """What `drain` logs at the stop is the last status and its lines (`final_status_outputs`): nothing
    derives after it, so lines held for a later call were never written. Here the source went stale before
    the stop (the loop last ticked 3 s after its last chunk): the last status raises that alarm, and says
    so on `/dp/log`, at its stamp, which is not before the last tick's."""
    tables = mux_tables(free_port(socket.SOCK_DGRAM), free_port(), tmp_path / "never.mcap", status_hz=1.0)
    tables["sources"][0]["timeout_s"] = 1.0
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
    service.pipeline.feed(RawEvent(T0, "mux", gga_at(0.0, 0.0) + HDT))
    service._ticked_ns = T0 + 3 * S
    out = service.final_status_outputs()
    assert [o.topic for o in out] == ["/dp/status", "/dp/log"]
    assert {o.stamp_ns for o in out} == {T0 + 3 * S}
    assert out[1].payload["message"].startswith("alarm: source mux: stale")


def test_a_replay_of_a_simulator_log_writes_its_truth_between_the_events(tmp_path: Path) -> None:
    """A simulator log's truth went into the replay's output all first, then the events: a reader that
    streams the file saw time go back by the whole log (150 s on a demo's log). Now at its own times."""
    from simulator.runner import Simulation
    from simulator.scenarios import get_scenario

    sim_log, out = tmp_path / "sim.mcap", tmp_path / "replay.mcap"
    with McapLogWriter(sim_log) as w:
        Simulation(get_scenario("torsetnes_2004"), seed=1, log=w).run(20.0)
    from gateway.replay import build_config

    inputs = open_inputs([sim_log])
    with McapLogWriter(out, flush_on_log_time=False) as w:
        result = run_replay(inputs, build_pipeline(build_config(inputs), []), out=w)
    assert len(result.truth) > 100
    assert backward_steps(out) == []
    truth = [ns for topic, ns, _ in file_order(out) if topic == "/truth/state"]
    assert truth == sorted(int(r["stamp_ns"]) for r in result.truth)


def test_a_log_two_producers_write_into_is_in_order_within_its_window(tmp_path: Path) -> None:
    """`dpgw demo`'s simulator writes its truth into the gateway's log as the plant computes it, ~0.4 s
    before the gateway logs the inputs of that time, and some gateway records of a time come a few ms
    before its truth: the file went back in time at nearly every step (479 times in 150 s). With
    `hold_for_order` the file is in log-time order and holds every record, the held ones written at close."""
    from wire.messages import DeadReckoningTick

    path = tmp_path / "held.mcap"
    with McapLogWriter(path) as w:
        w.hold_for_order(2.0)
        for k in range(100):  # the plant at 10 Hz, 0.4 s ahead of the gateway's inputs, 5 ms behind its own
            w.write("/truth/state", DeadReckoningTick(silent_s=float(k)), T0 + k * S // 10)
            if k >= 4:
                w.write_raw_nmea("gps", HDT, T0 + (k - 4) * S // 10 + 5_000_000)
                w.write_many(
                    [("/dp/tick", DeadReckoningTick(silent_s=0.0).encode(), T0 + k * S // 10 + 1, None)]
                )
    assert backward_steps(path) == []
    topics = [t for t, _, _ in file_order(path)]
    assert topics.count("/truth/state") == 100 and topics.count("/raw/nmea/gps") == 96
    assert topics.count("/dp/tick") == 96
    # without it, as before: out of order
    plain = tmp_path / "plain.mcap"
    with McapLogWriter(plain) as w:
        for k in range(10):
            w.write("/truth/state", DeadReckoningTick(silent_s=float(k)), T0 + k * S // 10)
            if k >= 4:
                w.write_raw_nmea("gps", HDT, T0 + (k - 4) * S // 10 + 5_000_000)
    assert backward_steps(plain) != []


def test_a_held_log_rotated_writes_what_it_holds_to_the_file_it_finishes(tmp_path: Path) -> None:
    """A log that holds records for their order (`hold_for_order`: the demo's) and is rotated for a new run
    of the simulator (its time going back): what it held is the run before's, and goes to the file being
    finished, in order; the new file starts its order again. Before, the old run's last records waited in
    the heap and went into the new run's file."""
    from wire.messages import DeadReckoningTick

    path = tmp_path / "runs.mcap"
    tick = DeadReckoningTick(silent_s=0.0).encode()
    with McapLogWriter(path) as w:
        w.hold_for_order(2.0)
        for k in range(30):  # the first run: 3 s
            w.write_many([("/dp/tick", tick, T0 + k * S // 10, None)])
        second = w.rotate()
        for k in range(30):  # the second run starts again at T0
            w.write_many([("/dp/tick", tick, T0 + k * S // 10, None)])
    assert second != path
    for f in (path, second):
        times = [ns for _, ns, _ in file_order(f)]
        assert len(times) == 30 and times == sorted(times), f.name


def test_a_held_log_whose_file_is_removed_counts_the_loss_and_never_raises(tmp_path: Path) -> None:
    """The demo's held log with its file removed under it (a disk unmounted): the flush after the held
    records were written raised out of the writer, into the gateway's loop. It fails as an unheld log does:
    said, counted, a new file tried."""
    from wire.messages import DeadReckoningTick

    path = tmp_path / "held.mcap"
    tick = DeadReckoningTick(silent_s=0.0).encode()
    w = McapLogWriter(path, flush_interval_s=0.01, retry_s=3600.0)
    try:
        w.hold_for_order(0.5)
        for k in range(20):
            w.write_many([("/dp/tick", tick, T0 + k * S // 10, None)])
        path.unlink()
        t = [T0 + 2 * S]

        def one_more() -> bool:  # (a record a tenth of a second on: the held ones before it are written)
            t[0] += S // 10
            w.write_many([("/dp/tick", tick, t[0], None)])
            return w.error is not None

        assert wait_for(one_more, 30.0)
        assert w.lost > 0 and "removed" in (w.error or ""), (w.lost, w.error)
    finally:
        w.close()
