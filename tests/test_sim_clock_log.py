"""What a live gateway on the simulation clock writes to its log around the first tick, over real UDP and a
real Zenoh clock: input shed before the first tick, input held beyond the hold's bound, and the start-up
events of the status. Every file of the log is on one time base (the plant's, or, for what came before any
simulation time existed, this computer's: never both), in receive order, and nothing received is lost."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port, wait_for

from gateway import service as service_module
from gateway.bus import isolated_config, open_session
from gateway.config import parse_config
from gateway.service import GatewayService
from wire.mcap.reader import read_messages
from wire.messages import SimClock

S = 1_000_000_000
T0 = 1_600_000_000 * S
"""The scenario's epoch (2020-09-13): years from this computer's clock, as a bench's epoch can be."""
TICK_S = 0.05


def hdt(k: int) -> bytes:
    """The ``k``-th sentence of the test: a gyro heading of ``k % 360`` degrees, numbered by its text."""
    body = f"HEHDT,{k % 360}.{k // 360},T"
    checksum = 0
    for c in body.encode():
        checksum ^= c
    return f"${body}*{checksum:02X}\r\n".encode()


class Bench:
    """A gateway on ``clock = "sim"`` (or ``"wall"``) with one NMEA source on UDP, Zenoh on loopback and a
    log; a simulator's clock on a second Zenoh session (a tick every 50 ms at 1x from `T0`, once
    `start_clock` is called) and a UDP sender."""

    def __init__(self, tmp_path: Path, clock: str = "sim", control: dict[str, Any] | None = None) -> None:
        self.udp, self.zport = free_port(socket.SOCK_DGRAM), free_port()
        self.log_path = tmp_path / "hil.mcap"
        from tests.test_service import mux_tables

        tables = mux_tables(self.udp, self.zport, self.log_path, status_hz=10.0)
        tables["zenoh"]["prefix"] = "dp/t"
        tables["time"] = {"clock": clock}
        if control is not None:
            tables["control"] = control
        self.service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client: Any = None
        self.loop: threading.Thread | None = None
        self.ticker: threading.Thread | None = None
        self.ticking = threading.Event()
        self.ticks: list[int] = []  # the simulation times published
        self.statuses: list[dict[str, Any]] = []  # what a Zenoh subscriber of the status got
        self.paths: list[Path] = []
        self.wall_from = time.time_ns()
        self.wall_to = self.wall_from  # (set again at the stop)

    def start(self) -> None:
        self.service.start()
        self.client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{self.zport}"]))
        self.sub = self.client.declare_subscriber(
            "dp/t/status", lambda s: self.statuses.append(json.loads(s.payload.to_bytes()))
        )

    def run(self) -> None:
        self.loop = threading.Thread(target=self.service.run, name="consumer")
        self.loop.start()

    def send(self, ks: range) -> None:
        for k in ks:
            self.tx.sendto(hdt(k), ("127.0.0.1", self.udp))

    def start_clock(self) -> None:
        """The simulator's clock: a tick every 50 ms of wall time, 50 ms of simulation time each."""
        pub = self.client.declare_publisher("dp/t/sim/clock")
        self.ticking.set()

        def tick() -> None:
            k = 0
            while self.ticking.is_set():
                stamp = T0 + k * round(TICK_S * S)
                pub.put(SimClock(stamp_ns=stamp, period_s=TICK_S, speed=1.0).encode())
                self.ticks.append(stamp)
                k += 1
                time.sleep(TICK_S)  # (the simulator's pace, not a wait for an event)

        self.ticker = threading.Thread(target=tick, name="sim clock")
        self.ticker.start()

    def stop(self) -> None:
        self.ticking.clear()
        if self.ticker is not None:
            self.ticker.join(timeout=10)
        self.service.stop_event.set()
        if self.loop is not None:
            self.loop.join(timeout=30)
        self.service.drain()
        if self.service.log is not None:
            self.paths = list(self.service.log.paths)
        self.wall_to = time.time_ns()
        if self.client is not None:
            self.client.close()
        self.tx.close()
        self.service.close()

    def on_sim_time(self, ns: int) -> bool:
        """A log time on the plant's clock: between its epoch and a tick past the last one published."""
        return T0 <= ns <= (self.ticks[-1] if self.ticks else T0) + round(TICK_S * S)

    def on_wall_time(self, ns: int) -> bool:
        return self.wall_from <= ns <= self.wall_to


def raw_texts(paths: list[Path]) -> list[tuple[str, int, str]]:
    """(file, log time, text) of every raw sentence of ``mux`` in the log's files, in the order written."""
    raw = [(p, t, m) for p in paths for _, t, _, m in read_messages(p, "/raw/nmea/mux")]
    return [(p.name, t, m["text"].strip()) for p, t, m in raw]


def one_time_base(bench: Bench) -> None:
    """Every file of the log holds stamps of one clock only, and its raw input in receive order.

    (Only the raw channel's order is asserted: the Foxglove log lines of a status go out with the next
    derive, stamped with the status, and may follow a chunk received a fraction of a millisecond after it;
    a reader orders by log time through the file's index.)"""
    for path in bench.paths:
        times = [t for _, t, _, _ in read_messages(path)]
        assert times, f"{path.name}: empty"
        raw = [t for _, t, _, _ in read_messages(path, "/raw/nmea/mux")]
        assert raw == sorted(raw), f"{path.name}: raw input not in receive order"
        sim = [bench.on_sim_time(t) for t in times]
        wall = [bench.on_wall_time(t) for t in times]
        assert all(sim) or all(wall), (
            f"{path.name}: {sum(sim)} stamps on the simulation clock, {sum(wall)} on the wall clock, "
            f"{len(times) - sum(sim) - sum(wall)} on neither"
        )


@pytest.fixture
def bench(tmp_path: Path) -> Any:
    made: list[Bench] = []

    def make(**kwargs: Any) -> Bench:
        made.append(Bench(tmp_path, **kwargs))
        return made[-1]

    yield make
    for b in made:
        if b.paths == [] and b.service.opened:
            b.stop()


def test_input_shed_before_the_first_tick_is_logged_on_the_simulation_time_in_order(bench: Any) -> None:
    """An overloaded gateway (more than ``queue_max`` waiting) writes the oldest sensor data to the log
    without the pipeline. Before the first tick there is no simulation time to stamp it with: it waits in
    the hold with everything else received then, and reaches the log, in receive order, at the first
    tick's time; it is counted as shed, and the pipeline never sees it. Before, it was written at once,
    on this computer's clock, ahead of what was held: a log on two clocks."""
    b = bench()
    b.service.queue_max = 10
    b.start()
    b.send(range(30))  # 30 datagrams wait before the consumer turns: it sheds the 20 oldest
    assert wait_for(lambda: b.service._queue.qsize() == 30, 10.0), "the datagrams did not arrive"
    b.run()
    assert wait_for(lambda: sum(b.service.shed.values()) == 20 and not b.service._queue.qsize(), 10.0)
    assert b.service.pipeline.counters["mux"].received == 0  # no time yet: nothing handled
    b.start_clock()
    counters = b.service.pipeline.counters["mux"]
    assert wait_for(lambda: counters.received == 10, 20.0), counters.received  # the held, at the first tick
    b.send(range(30, 35))
    assert wait_for(lambda: counters.received == 15, 10.0), counters.received
    b.stop()
    assert b.service.shed == {"mux": 20} and counters.received == 15  # the shed ones: never handled
    one_time_base(b)
    raw = raw_texts(b.paths)
    assert [text for _, _, text in raw] == [hdt(k).decode().strip() for k in range(35)]  # all, in order
    first = raw[0][1]
    assert b.on_sim_time(first) and all(t == first for _, t, _ in raw[:30])  # at the first tick's time
    assert len(b.paths) == 1  # nothing on the wall clock: one file


def test_input_held_beyond_the_bound_before_the_first_tick_goes_to_a_file_of_its_own(
    bench: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """More than `HOLD_MAX` inputs before the first tick: the oldest are let go to keep memory bounded,
    written to the log unhandled on this computer's clock (there is no simulation time yet, and which one
    will come is not known), counted, and alarmed. The log then finishes that file at the first tick and
    goes on, on the plant's time, in the next file of its set: no file mixes the two clocks (a file that
    did put 2020 and 2026 side by side in one channel, and a replay or Foxglove's timeline took it as one
    run of six years). The pipeline handles what was held, at the first tick's time, and says where the
    log went."""
    monkeypatch.setattr(service_module, "HOLD_MAX", 5)
    b = bench()
    b.service._held = deque()
    b.start()
    b.run()
    b.send(range(8))
    assert wait_for(lambda: b.service.held_dropped == 3 and len(b.service._held) == 5, 10.0)
    (alarm,) = [a for a in b.service._alarms() if "while waiting for a tick" in a]
    assert "3 inputs logged without being handled" in alarm, alarm
    b.start_clock()
    counters = b.service.pipeline.counters["mux"]
    assert wait_for(lambda: counters.received == 5, 20.0), counters.received
    b.send(range(8, 10))
    assert wait_for(lambda: counters.received == 7, 10.0), counters.received
    b.stop()
    one_time_base(b)
    assert [p.name for p in b.paths] == ["hil.mcap", "hil_0001.mcap"]
    raw = raw_texts(b.paths)
    assert [text for _, _, text in raw] == [hdt(k).decode().strip() for k in range(10)]  # all, in order
    assert [name for name, _, _ in raw] == ["hil.mcap"] * 3 + ["hil_0001.mcap"] * 7
    assert all(b.on_wall_time(t) for _, t, _ in raw[:3])  # let go before any simulation time
    assert all(t == raw[3][1] for _, t, _ in raw[3:8]) and b.on_sim_time(raw[3][1])  # the first tick's
    events = [e for _, _, _, s in read_messages(b.paths[1], "/dp/status") for e in s.get("events", [])]
    assert any("log continues in hil_0001.mcap" in e and "3 inputs" in e for e in events), events
    last = [s for _, _, _, s in read_messages(b.paths[1], "/dp/status")][-1]
    assert any("3 inputs logged without being handled" in a and "in hil.mcap" in a for a in last["alarms"])
    assert counters.received == 7  # what the pipeline saw: what was held, and what came after the tick


@pytest.mark.parametrize("clock", ["sim", "wall"])
def test_the_start_up_events_reach_the_log_once(bench: Any, clock: str) -> None:
    """The start-up events (the start mode, the wind feed-forward off) go out once, in the first status
    that is logged, and so in the log's status channel and on Zenoh. Before, the status made at start-up
    for a query, and on the simulation clock the statuses published before the first tick, took them:
    neither is logged, and the log never held them."""
    b = bench(clock=clock, control={"initial_mode": "dp"})
    expected = list(b.service.pipeline._startup_events)
    assert any("initial mode dp" in e for e in expected), expected
    b.start()
    # (a query answered: the gateway knows the subscriber, declared before it, and gets every status)
    assert wait_for(lambda: any(r.ok is not None for r in b.client.get("dp/t/status", timeout=2.0)), 20.0)
    b.run()
    if clock == "sim":  # statuses without a time go out on Zenoh before the first tick
        assert wait_for(lambda: len(b.statuses) >= 3, 20.0), "no status on Zenoh"
        b.start_clock()
    counters = b.service.pipeline.counters["mux"]
    sent = [0]

    def send() -> None:
        b.send(range(sent[0], sent[0] + 1))
        sent[0] += 1

    assert wait_for(lambda: counters.received >= 3 or send(), 20.0)
    assert wait_for(lambda: any(s["sources"]["mux"].get("received", 0) >= 3 for s in b.statuses), 20.0)
    b.stop()
    logged = [s for _, _, _, s in read_messages(b.paths, "/dp/status")]
    said = [e for s in logged for e in s.get("events", [])]
    for event in expected:
        assert said.count(event) == 1, (event, said)
    on_zenoh = [e for s in b.statuses for e in s.get("events", [])]
    for event in expected:
        assert on_zenoh.count(event) == 1, (event, on_zenoh)


def test_input_shed_while_the_clock_is_silent_goes_to_the_run_a_tick_then_says(tmp_path: Path) -> None:
    """After a silence of the clock, what arrives is held until a tick says which run of the plant it is of
    (a paused simulator's, or a restarted one's whose data came before its ticks). Input shed meanwhile
    waits the same way: a restart's tick sends it, after what was held before it, to the new run's file at
    the new run's first tick. Before, it was written at once, on the old run's time, in the old run's
    file, ahead of the older input held."""
    from gateway.sources import Chunk
    from wire.mcap.writer import McapLogWriter

    b = Bench(tmp_path)
    service = b.service
    service.log = McapLogWriter(tmp_path / "gw.mcap", profile="dpgw", continue_set=True)
    st = service.sim_time
    assert st is not None
    now = time.monotonic_ns()
    for k in range(200):  # 10 s of a run whose last tick came 10 s ago
        st.on_tick(T0 + k * 50_000_000, 0.05, now - 20 * S + k * 50_000_000)
    service._take(Chunk("mux", hdt(0), rx_ns=1, rx_mono_ns=now - 15 * S))  # while it ticked: handled
    service._take(Chunk("mux", hdt(1), rx_ns=1, rx_mono_ns=now - 2 * S))  # after 8 s of silence: held
    service.queue_max = 0  # overloaded: the next is shed
    assert service._shed_oldest(Chunk("mux", hdt(2), rx_ns=1, rx_mono_ns=now - S)) is None
    assert service.shed == {"mux": 1}
    epoch2 = T0 - 3600 * S  # the simulator started again, from an epoch an hour before
    st.on_tick(epoch2, 0.05, now)
    service._release_held()
    assert not service._held and service.runs_followed == 1
    service.log.close()
    raw = raw_texts(list(service.log.paths))
    assert [(name, text) for name, _, text in raw] == [
        ("gw.mcap", hdt(0).decode().strip()),
        ("gw_0001.mcap", hdt(1).decode().strip()),
        ("gw_0001.mcap", hdt(2).decode().strip()),
    ]
    assert [t for _, t, _ in raw[1:]] == [epoch2, epoch2]  # the new run's first tick's time
    assert service.pipeline.counters["mux"].received == 2  # the shed one: never handled
    b.tx.close()
