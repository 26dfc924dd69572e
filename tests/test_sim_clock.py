"""The simulation clock on the bus: the simulator publishes its time before everything it sends and at least
every tick; the gateway on ``clock = "sim"`` holds what comes before the first tick and stamps everything
with the simulation time; the demo's speed governor halves the speed only when the loop stays late."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import pytest

from gateway.config import parse_config
from gateway.service import GatewayService
from gateway.sources import Chunk
from simulator.clock import RealtimeClock, SimEpoch, SpeedGovernor, VirtualClock
from simulator.runner import Route, Simulation
from simulator.scenarios import get_scenario
from simulator.sim_clock import SimClockPublisher
from simulator.transports import Sink
from wire.messages import SimClock

# --- the simulator's side ---------------------------------------------------------------------------------


class FakeSession:
    """What `SimClockPublisher` needs of a Zenoh session: publishers whose puts are kept."""

    def __init__(self) -> None:
        self.puts: list[tuple[str, bytes]] = []

    def declare_publisher(self, key: str, encoding: str | None = None) -> Any:
        session = self

        class Pub:
            def put(self, body: bytes) -> None:
                session.puts.append((key, body))

            def undeclare(self) -> None:
                pass

        return Pub()


class TickAwareSink(Sink):
    """Records, for every write, the newest tick published before it."""

    def __init__(self, session: FakeSession) -> None:
        super().__init__()
        self.session = session
        self.writes: list[int] = []

    def write(self, data: bytes) -> None:
        self.writes.append(json.loads(self.session.puts[-1][1])["stamp_ns"])

    def describe(self) -> str:
        return "test"


def test_ticks_go_out_on_zenoh_as_json_like_every_dpgw_payload() -> None:
    """A real Zenoh subscriber gets the tick with the encoding every dpgw payload has, `application/json`
    (docs/interfaces.md), and the tick decodes as a `dpgw.SimClock`."""
    from datetime import UTC, datetime

    from gateway.bus import isolated_config, open_session
    from tests.conftest import free_port, wait_for

    port = free_port()
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    got: list[tuple[str, bytes]] = []
    try:
        sub = client.declare_subscriber(
            "dp/t/sim/clock", lambda s: got.append((str(s.encoding), s.payload.to_bytes()))
        )
        epoch = SimEpoch(datetime(2026, 3, 1, tzinfo=UTC))
        pub = SimClockPublisher(server, "dp/t", epoch, VirtualClock(), period_s=0.05)
        t = 0.0
        while not got and t < 10.0:  # until the subscription has reached the publisher's side
            t += 0.05
            pub(t)
            wait_for(lambda: got, timeout=0.2)
        encoding, body = got[0]
        assert encoding == "application/json"
        assert SimClock(**json.loads(body)).stamp_ns >= epoch.stamp_ns(0.05)
        sub.undeclare()
    finally:
        client.close()
        server.close()


def test_ticks_come_before_every_burst_and_at_least_every_period() -> None:
    sc = get_scenario("torsetnes_2004")
    session = FakeSession()
    sink = TickAwareSink(session)
    sim = Simulation(sc, 1, routes=[Route(sink, "nmea"), Route(sink, "mavlink")], clock=VirtualClock())
    pub = SimClockPublisher(session, "dp/t", sim.epoch, sim.clock, period_s=sim.time_tick_s)
    sim.on_time = pub
    emitted: list[int] = []
    # every emission as it leaves, after the sink has it (the runner's `on_emit`)
    sim.on_emit = lambda e: emitted.append(sim.epoch.stamp_ns(e.t_emit))
    sim.run(20.0)
    ticks = [SimClock(**json.loads(body)).stamp_ns for _, body in session.puts]
    assert {key for key, _ in session.puts} == {"dp/t/sim/clock"}
    assert ticks == sorted(set(ticks))  # strictly increasing
    gaps = [(b - a) / 1e9 for a, b in itertools.pairwise(ticks)]
    assert max(gaps) <= sim.time_tick_s + 1e-6  # at least every period (20 Hz of sim time)
    assert ticks[-1] == sim.epoch.stamp_ns(20.0)
    # every write left after the tick of its own instant: a gateway can never stamp it ahead of the plant
    assert len(sink.writes) == len(emitted) > 100
    assert all(tick == t for tick, t in zip(sink.writes, emitted, strict=True))


def test_set_speed_continues_from_where_the_simulation_is() -> None:
    wall = [100.0]
    clock = RealtimeClock(10.0, monotonic=lambda: wall[0], sleep=lambda s: wall.__setitem__(0, wall[0] + s))
    clock.sleep_until(10.0)  # 1 s of wall
    wall[0] += 3.0  # the machine stalls: 3 s late
    assert clock.sleep_until(11.0) == pytest.approx(2.9)
    clock.set_speed(5.0)  # from here at 5x, the lag dropped, not caught up
    assert clock.deadline(16.0) == pytest.approx(wall[0] + 1.0)


def test_the_governor_halves_the_speed_only_when_the_loop_stays_late() -> None:
    wall = [0.0]
    clock = RealtimeClock(10.0, monotonic=lambda: wall[0], sleep=lambda s: None)
    said: list[tuple[float, float, float]] = []
    gov = SpeedGovernor(
        clock, max_delay_s=0.3, persist_s=2.0, on_lower=lambda *a: said.append(a), monotonic=lambda: wall[0]
    )

    def run(seconds: float, late_wall_s: float) -> None:
        for _ in range(round(seconds / 0.01)):
            wall[0] += 0.01
            gov.observe(late_wall_s)

    run(5.0, 0.001)  # 10 ms x 10 = 0.1 s of sim late: fine
    run(0.3, 0.5)  # one stall: smoothed away
    run(5.0, 0.001)
    assert clock.speed == 10.0 and not said
    run(4.0, 0.1)  # 0.1 s of wall late, 1 s of sim at 10x, for seconds: halve
    assert clock.speed == 5.0 and len(said) == 1 and said[0][:2] == (10.0, 5.0)
    run(60.0, 0.5)  # stays late: down to the floor, never below
    assert clock.speed == 1.0
    assert [c[1] for c in gov.changes] == [5.0, 2.5, 1.25, 1.0]


def test_the_publisher_paces_a_realtime_clock_and_reports_its_speed() -> None:
    wall = [0.0]
    slept: list[float] = []

    def sleep(s: float) -> None:
        slept.append(s)
        wall[0] += s

    clock = RealtimeClock(4.0, monotonic=lambda: wall[0], sleep=sleep)
    session = FakeSession()
    epoch = SimEpoch.from_wall_clock()
    pub = SimClockPublisher(session, "dp/t", epoch, clock, period_s=0.05)
    pub(0.0)
    pub(1.0)
    pub(1.0)  # the same instant again: nothing new
    assert wall[0] == pytest.approx(0.25)  # 1 s of sim at 4x
    ticks = [SimClock(**json.loads(b)) for _, b in session.puts]
    assert [t.stamp_ns for t in ticks] == [epoch.stamp_ns(0.0), epoch.stamp_ns(1.0)]
    assert ticks[0].speed == 4.0 and ticks[0].period_s == 0.05


# --- the gateway's side -----------------------------------------------------------------------------------


class Sample:
    def __init__(self, body: bytes) -> None:
        self.payload = self
        self.body = body

    def to_bytes(self) -> bytes:
        return self.body


def sim_service(
    tmp_path: Path,
    clock: str = "sim",
    status_hz: float = 1.0,
    commands: list[str] | None = None,
    zenoh: dict[str, Any] | None = None,
) -> GatewayService:
    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "mux", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "log": {"path": ""},
        "status": {"rate_hz": status_hz},
        "time": {"clock": clock},
    }
    if commands:
        tables["commands"] = {"accept": commands}
    if zenoh:
        tables["zenoh"] = zenoh
    return GatewayService(parse_config(tables, base_dir=tmp_path))


def chunk(rx_mono_ns: int) -> Chunk:
    return Chunk("mux", b"$HEHDT,45.0,T*1D\r\n", rx_ns=1, rx_mono_ns=rx_mono_ns)


def test_the_gateway_holds_data_until_the_first_tick_then_stamps_with_simulation_time(tmp_path: Path) -> None:
    import time

    service = sim_service(tmp_path)
    assert service.sim_time is not None and service._now() is None
    service._take(chunk(1_000))
    service._take(chunk(2_000))
    assert service.pipeline.counters["mux"].bytes == 0 and len(service._held) == 2  # held: no time yet
    t0 = 1_800_000_000 * 10**9
    service._on_clock(Sample(SimClock(stamp_ns=t0, period_s=0.05, speed=10.0).encode()))
    service._on_clock(Sample(b"not a tick"))
    assert service.clock_rejected == 1
    service._take(chunk(time.monotonic_ns()))  # after the tick (a receive instant later than any tick so far)
    c = service.pipeline.counters["mux"]
    assert not service._held and c.bytes == 3 * len(chunk(0).data)
    # the held chunks at the first tick's time; the later one at most one tick ahead of it
    assert t0 <= c.last_rx_ns <= t0 + 50_000_000
    assert service.pipeline.t0_ns == t0


def test_the_wall_clock_stays_the_default(tmp_path: Path) -> None:
    service = sim_service(tmp_path, clock="wall")
    assert service.sim_time is None
    service._take(chunk(5))
    assert service.pipeline.counters["mux"].last_rx_ns == 1  # the chunk's own receive time


def test_nothing_is_stamped_before_there_is_a_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """While items wait and none has been handled yet, there is no pipeline time: the status then goes out
    unlogged rather than stamped 0 (a message at 1970 in the log would make the writer rotate the file)."""
    from gateway.service import _Input

    service = sim_service(tmp_path, clock="wall", status_hz=10.0)
    logged: list[int] = []
    monkeypatch.setattr(service, "_log_outputs", lambda outs, enc: logged.extend(o.stamp_ns for o in outs))
    service._queue.put(_Input("mode", "dp", 1_000, 1_000))  # an input: sets no pipeline time
    for k in range(3):
        service._queue.put(Chunk("mux", b"$HEHDT,45.0,T*1D\r\n", rx_ns=10**18 + k, rx_mono_ns=k))
    service.run(duration_s=0.5)
    assert logged and min(logged) > 0  # the statuses once a chunk was handled, none before


# --- the demo's measure of how far the gateway is behind ----------------------------------------------------


def test_loop_lag_is_the_age_of_the_oldest_burst_not_yet_handled() -> None:
    from dpgw.loop_lag import LoopLag

    epoch = SimEpoch.from_wall_clock()
    handled: dict[str, tuple[int | None, int]] = {"gyro1": (None, 0), "dgps1": (None, 0)}
    lag = LoopLag(epoch, lambda s: handled[s], tolerance_s=0.05)
    assert lag.lag_s(0.0) == 0.0
    lag.sent("gyro1", 1.0, 20)
    lag.sent("gyro1", 1.0, 20)  # the same burst, a second sentence
    lag.sent("gyro1", 1.1, 20)
    lag.sent("dgps1", 1.05, 70)
    assert lag.lag_s(1.5) == pytest.approx(0.5)
    handled["gyro1"] = (None, 40)  # the first burst's bytes are in (stamps aside)
    assert lag.lag_s(1.5) == pytest.approx(0.45)  # dgps1's burst at 1.05 is the oldest now
    handled["dgps1"] = (epoch.stamp_ns(1.02), 60)  # stamped a little early, within a tick: handled
    assert lag.lag_s(1.5) == pytest.approx(0.4)  # gyro1's second burst
    handled["gyro1"] = (epoch.stamp_ns(1.1), 60)
    assert lag.lag_s(1.5) == 0.0  # nothing waits; a quiet source adds nothing
    assert lag.lag_s(100.0) == 0.0


def test_a_missing_or_silent_simulation_clock_is_an_alarm(tmp_path: Path) -> None:
    import time

    service = sim_service(tmp_path)
    service._wall0_ns = time.time_ns() - 10**10  # started 10 s ago
    service._take(chunk(1))
    assert any("no simulation time on dp/mss_supply/sim/clock yet" in a and "1 inputs held" in a
               and "dpgw sim --zenoh --realtime" in a  # (unpaced, the simulator publishes no clock)
               for a in service._alarms())  # fmt: skip
    assert service.sim_time is not None
    service.sim_time.on_tick(10**18, 0.05, time.monotonic_ns() - 6 * 10**9)  # one tick, 6 s ago
    assert any("no simulation clock tick on dp/mss_supply/sim/clock for 6 s" in a for a in service._alarms())


def test_an_unpaced_simulator_on_zenoh_says_it_publishes_no_clock() -> None:
    """`dpgw sim --zenoh` without `--realtime` publishes no simulation time (it would run ahead of any
    gateway): it says so, naming the key and the flag, instead of leaving a gateway on `clock = "sim"` to
    hold everything in silence; with `--realtime` it names the key it publishes on."""
    import subprocess
    import sys

    def stderr_of(*extra: str) -> str:
        done = subprocess.run(
            [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--duration", "1", "--zenoh",
             "--no-scouting", "--zenoh-listen", "tcp/127.0.0.1:0", "--prefix", "bench/x", *extra],
            capture_output=True, text=True, timeout=120, check=True,
        )  # fmt: skip
        return done.stderr

    unpaced = stderr_of()
    assert "no simulation time on bench/x/sim/clock without --realtime" in unpaced, unpaced
    paced = stderr_of("--realtime", "--speed", "20")
    assert "Zenoh: simulation time on bench/x/sim/clock" in paced and "without --realtime" not in paced


# --- a HIL bench in two processes: what the log and the alarms say ------------------------------------------


def _log_times(path: Path) -> list[tuple[str, int]]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [(ch.topic, m.log_time) for _, ch, m in make_reader(f).iter_messages(log_time_order=False)]


def test_a_log_on_simulation_time_holds_no_wall_clock_stamp(tmp_path: Path) -> None:
    """The statuses made while no tick has come (at start-up, while the simulator is not up yet) go out on
    Zenoh stamped with the wall clock, but nothing of them may reach the log: a log line at the wall clock
    in a log on the plant's time (months apart) stretches its timeline and rotates the file."""
    import time

    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path, status_hz=10.0)
    service.log = McapLogWriter(tmp_path / "gw.mcap", profile="dpgw")
    service._wall0_ns = time.time_ns() - 10**10  # started 10 s ago: the "no time yet" alarm is up
    service.run(duration_s=0.3)  # statuses without a time: published, not logged
    t0 = 1_600_000_000 * 10**9  # the plant's time: years from the wall clock
    service._on_clock(Sample(SimClock(stamp_ns=t0, period_s=0.05, speed=1.0).encode()))
    service._queue.put(chunk(time.monotonic_ns()))
    service.run(duration_s=0.3)
    service.log.close()
    times = _log_times(tmp_path / "gw.mcap")
    assert any(topic == "/dp/status" for topic, _ in times)  # the statuses from the first tick on
    late = [(topic, ns) for topic, ns in times if not t0 <= ns <= t0 + 10**9]
    assert not late, f"stamped off the simulation time: {late[:5]}"


S = 1_000_000_000
TICK_NS = 50_000_000


def fix(north: float, east: float, psi_deg: float, t_ns: int) -> bytes:
    """A DGPS fix (UTC time ``t_ns``) and a gyro heading, as one chunk of the `mux` source."""
    import math
    from datetime import UTC, datetime

    from wire.codecs import nmea_encode as enc
    from wire.geodesy import LocalFrame

    lat, lon, _ = LocalFrame(59.4, 10.5).to_geodetic(north, east, 0.0)
    gga = enc.gga("GP", datetime.fromtimestamp(t_ns / S, UTC), lat, lon, 2, 12, 0.8, 20.0)
    return (gga + enc.hdt("HE", math.radians(psi_deg))).encode()


def run_of_the_plant(
    service: GatewayService, t0: int, mono0: int, at: tuple[float, float, float], seconds: float = 10.0
) -> None:
    """A run of the simulator as the gateway sees it: a tick every 50 ms at 1x from ``t0`` (received from
    monotonic ``mono0`` on) and, 1 ms after every other tick, a fix and a heading of a vessel at ``at``
    (with a little noise: a value that never changes is a frozen sensor)."""
    import math

    assert service.sim_time is not None
    n, e, psi = at
    for k in range(round(seconds / 0.05)):
        t, mono = t0 + k * TICK_NS, mono0 + k * TICK_NS
        service.sim_time.on_tick(t, 0.05, mono)
        if k % 2 == 0:
            data = fix(n + 0.2 * math.sin(k), e + 0.2 * math.cos(k), psi + 0.05 * math.sin(k), t)
            service._take(Chunk("mux", data, rx_ns=1, rx_mono_ns=mono + 10**6))


def _messages(path: Path) -> list[tuple[str, int, dict[str, Any]]]:
    """(topic, log time, payload) of every message of one file, in the order written."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [
            (ch.topic, m.log_time, json.loads(m.data))
            for _, ch, m in make_reader(f).iter_messages(log_time_order=False)
        ]


def test_a_restarted_simulator_is_followed_in_a_file_of_its_own(tmp_path: Path) -> None:
    """A simulator restarted under a running gateway starts its time again (from its epoch): its ticks go
    back more than a second. The gateway follows the new run as a gateway started with it would: what it
    still had of the old run goes to the old run; the log goes on in the next file of its set; the pipeline
    starts over (a fresh observer: the new run's first estimate is where the new vessel is, not a blend
    with the old one; the mode back to the configured one); the counts go on; and the status says so once."""
    import math
    import time

    from gateway.service import _Input
    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path, status_hz=10.0, commands=["mode"])
    service.log = McapLogWriter(tmp_path / "gw.mcap", profile="dpgw", continue_set=True)
    st = service.sim_time
    assert st is not None
    t0, mono0 = 1_600_000_000 * S, time.monotonic_ns() - 60 * S
    run_of_the_plant(service, t0, mono0, (100.0, 0.0, 45.0))  # the first run: 10 s at (100 m N, 45°)
    service._take(_Input("mode", "manual", 1, mono0 + 10 * S))
    first = service.pipeline
    assert first.mode == "manual" and first.estimates > 0
    received = first.counters["mux"].received
    # the consumer is behind: a chunk of the old run (0.2 s after its last tick) and one of the new run (1.5 s
    # after the old run's last tick, before the new run's first: its UDP was up before its Zenoh) wait while
    # the new run's first tick comes, at its epoch again
    late = Chunk("mux", fix(100.0, 0.0, 45.0, t0 + 10 * S), rx_ns=1, rx_mono_ns=mono0 + 10_200_000_000)
    early = Chunk("mux", fix(-50.0, 30.0, 200.0, t0), rx_ns=1, rx_mono_ns=mono0 + 11_500_000_000)
    st.on_tick(t0, 0.05, mono0 + 12 * S)
    assert st.went_back == (t0 + 199 * TICK_NS, t0) and service.pipeline is first  # not followed yet
    service._take(late)  # the old run's: handled in it, on its time
    assert service.pipeline is first and first.counters["mux"].received == received + 2
    assert first.last_ns >= t0 + 199 * TICK_NS
    service._take(early)  # the new run's: followed
    second = service.pipeline
    assert second is not first and st.went_back is None and service.runs_followed == 1
    assert second.mode == "standby"  # as at start-up, not the old run's manual
    assert second.last_ns == t0  # stamped with the new run's first tick's time
    run_of_the_plant(service, t0 + TICK_NS, mono0 + 12 * S + TICK_NS, (-50.0, 30.0, 200.0))
    assert second.counters["mux"].received == received + 2 + 2 + 200  # the counts go on
    service.run(duration_s=0.3)  # statuses
    service.log.close()
    files = [tmp_path / "gw.mcap", tmp_path / "gw_0001.mcap"]
    assert service.log.paths == files
    said = []
    for path in files:
        messages = _messages(path)
        times = [t for _, t, _ in messages]
        assert times == sorted(times), f"{path.name}: log times not in order"
        assert t0 <= times[0] and times[-1] <= t0 + 11 * S, path.name  # one run's time
        statuses = [p for topic, _, p in messages if topic == "/dp/status"]
        said += [(path.name, e) for p in statuses for e in p.get("events", [])]
    followed = [(name, e) for name, e in said if "following the new run" in e]
    assert len(followed) == 1 and followed[0][0] == "gw_0001.mcap", said
    assert "went back 9.9 s" in followed[0][1] and "log continues in gw_0001.mcap" in followed[0][1]
    # the new run's first estimate: where the new vessel is (a fresh observer), not the old one's
    est = [p for topic, _, p in _messages(files[1]) if topic == "/dp/estimate"]
    n, e, psi = est[0]["eta"]
    assert math.hypot(n + 50.0, e - 30.0) < 1.0 and abs(math.degrees(psi) % 360.0 - 200.0) < 1.0, est[0]
    # a tick swapped by two Zenoh threads (one period back) is not a restart
    other = sim_service(tmp_path)
    assert other.sim_time is not None
    other.sim_time.on_tick(t0 + 100_000_000, 0.05, 1)
    other.sim_time.on_tick(t0 + 50_000_000, 0.05, 2)
    assert other.sim_time.went_back is None and other.sim_time.ignored == 1


def test_data_before_a_restarted_simulators_first_tick_goes_to_the_run_its_tick_says(tmp_path: Path) -> None:
    """The new run's first data can come before its first tick does (UDP and the pty are up at once, the
    Zenoh session to the new simulator takes seconds): received while the clock has been silent, it is
    held until a tick says which run it belongs to. A tick going back: the new run's, handled in it at its
    first tick's time; a tick going on (a paused simulator continued): this run's, handled in it."""
    import time

    t0 = 1_600_000_000 * 10**9
    now = time.monotonic_ns()
    for restarted in (True, False):
        service = sim_service(tmp_path)
        assert service.sim_time is not None
        for k in range(200):  # 10 s of a run whose last tick came 10 s ago
            service.sim_time.on_tick(t0 + k * 50_000_000, 0.05, now - 20 * 10**9 + k * 50_000_000)
        service._take(chunk(now - 15 * 10**9))  # while the ticks came: handled at once
        first = service.pipeline
        handled = first.counters["mux"].bytes
        assert handled > 0
        service._take(chunk(now))  # after 10 s of silence: held until a tick says whose it is
        assert first.counters["mux"].bytes == handled and len(service._held) == 1
        back = t0 if restarted else t0 + 200 * 50_000_000
        service._on_clock(Sample(SimClock(stamp_ns=back, period_s=0.05, speed=1.0).encode()))
        service._release_held()
        assert not service._held
        assert service.pipeline.counters["mux"].bytes == 2 * handled  # handled, in one run or the other
        assert service.pipeline.counters["mux"].last_rx_ns == back  # at the time of the tick after it
        assert (service.pipeline is not first) == restarted and service.runs_followed == int(restarted)


def test_what_is_held_for_want_of_a_tick_reaches_the_log(tmp_path: Path) -> None:
    """Nothing received is lost under the simulation clock: inputs held for a first tick that never comes
    (a simulator publishing its clock under another prefix) are written to the log, unhandled, when the
    gateway stops; beyond the hold's bound the oldest go to the log as they are let go."""
    from collections import deque

    from mcap.reader import make_reader

    from gateway import service as service_module
    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path)
    service.log = McapLogWriter(tmp_path / "held.mcap")
    bound = 5
    held = [Chunk("mux", f"$HEHDT,{k}.0,T*00\r\n".encode(), rx_ns=10**18 + k, rx_mono_ns=k) for k in range(8)]
    original = service_module.HOLD_MAX
    try:
        service_module.HOLD_MAX = bound
        service._held = deque(maxlen=None)
        for c in held:
            service._take(c)
    finally:
        service_module.HOLD_MAX = original
    assert len(service._held) == bound and service.held_dropped == 3
    said = "3 inputs logged without being handled while waiting for a tick"
    assert any(said in a for a in service._alarms())
    service.drain()
    service.log.close()
    assert service.pipeline.counters["mux"].bytes == 0  # never handled: no time to handle them at
    with open(tmp_path / "held.mcap", "rb") as f:
        raw = [m for _, ch, m in make_reader(f).iter_messages() if ch.topic == "/raw/nmea/mux"]
    assert [json.loads(m.data)["text"] for m in raw] == [c.data.decode().rstrip() for c in held]  # in order
    assert [m.log_time for m in raw] == [c.rx_ns for c in held]  # at their receive times: no sim time yet
    assert service.logged_unhandled == 8
    # a gateway without a log says they are dropped, not logged
    service.log = None
    (alarm,) = [a for a in service._alarms() if "while waiting for a tick" in a]
    assert "3 inputs dropped (no log to keep them)" in alarm, alarm


def test_the_last_status_of_a_run_is_the_last_in_its_log(tmp_path: Path) -> None:
    """The periodic status goes out at the clock's present, ahead of the last input handled; the status
    `drain` writes at the end (every count of the run) must not be stamped before it, or the last
    status by log time, what a replay or a viewer takes as the run's, is an older one."""
    import time

    from mcap.reader import make_reader

    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path, clock="wall", status_hz=10.0)
    service.log = McapLogWriter(tmp_path / "run.mcap")
    t = time.time_ns() - 5 * 10**9  # received 5 s ago: handled at that time, the status at now
    service._take(Chunk("mux", b"$HEHDT,45.0,T*1D\r\n", rx_ns=t, rx_mono_ns=time.monotonic_ns()))
    service.run(duration_s=0.3)
    service.drain()
    service.log.close()
    with open(tmp_path / "run.mcap", "rb") as f:
        statuses = [(m.log_time, json.loads(m.data)) for _, ch, m in make_reader(f).iter_messages(
                    log_time_order=False) if ch.topic == "/dp/status"]  # (in the order written)  # fmt: skip
    assert any(ns > t + 4 * 10**9 for ns, _ in statuses)  # periodic ones at the present
    assert statuses[-1][0] == max(ns for ns, _ in statuses)  # the one written last is the last by time


def test_a_second_simulator_on_the_same_key_is_ignored_and_alarmed(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two benches on one network sharing a prefix: a second simulator's clock reaches the gateway (here
    both publish through real Zenoh sessions to the gateway's listener), its time an hour ahead. Before,
    each of its ticks looked like a restart of the gateway's own simulator and the gateway followed one
    then the other, a new log file each time; now the gateway keeps to its own run, ignores the other's
    ticks and says so, once in its log and in its status."""
    import logging
    import time
    from datetime import UTC, datetime, timedelta

    from gateway.bus import isolated_config, open_session
    from tests.conftest import free_port, wait_for

    port = free_port()
    zenoh = {"listen": [f"tcp/127.0.0.1:{port}"], "multicast_scouting": False, "prefix": "dp/t"}
    service = sim_service(tmp_path, zenoh=zenoh)
    ours = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    theirs = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    epoch = SimEpoch(datetime(2026, 3, 1, tzinfo=UTC))
    own = SimClockPublisher(ours, "dp/t", epoch, VirtualClock(), period_s=0.05)
    other = SimClockPublisher(theirs, "dp/t", SimEpoch(epoch.start_utc + timedelta(hours=1)), VirtualClock())
    caplog.set_level(logging.WARNING, logger="gateway.service")
    service.start()
    try:
        st = service.sim_time
        assert st is not None
        t = 0.0
        # our simulator first (the gateway follows it), then both, interleaved
        while not wait_for(lambda: st.started, timeout=0.05) and t < 10.0:
            t += 0.05
            own(t)
        assert st.run_id == own.run
        for _ in range(100):
            t += 0.05
            own(t)
            other(t)
            if wait_for(lambda: st.foreign >= 20, timeout=0.01):
                break
        assert st.foreign >= 20 and st.foreign_run == other.run
        assert st.went_back is None and st.runs == 1 and st.run_id == own.run
        alarms = [a for a in service._alarms() if "another simulator's clock on dp/t/sim/clock" in a]
        assert alarms and f"run {other.run}" in alarms[0] and "prefix" in alarms[0], service._alarms()
        now = st.now(time.monotonic_ns())
        assert now is not None and abs(now - epoch.stamp_ns(t)) < 10**9  # on our run's time
        said = [r for r in caplog.records if "another simulator's clock" in r.getMessage()]
        assert len(said) == 1
        # the other bench's simulator stops: once it has been silent for FOREIGN_ALARM_S the alarm clears
        # (said in the log; the count is kept), while ours ticks on
        import gateway.service as gs

        monkeypatch.setattr(gs, "FOREIGN_ALARM_S", 0.3)

        def foreign_alarm() -> bool:
            return any("another simulator's clock" in a for a in service._alarms())

        def cleared() -> bool:
            nonlocal t
            t += 0.05
            own(t)
            return not foreign_alarm()

        assert wait_for(cleared, timeout=20.0, interval=0.05)
        assert any("alarm cleared" in r.getMessage() for r in caplog.records)
        counted = st.foreign
        # ... and it comes back: the alarm again, and said again
        for _ in range(200):
            t += 0.05
            own(t)
            other(t)
            if wait_for(lambda: st.foreign > counted, timeout=0.01):
                break
        assert st.foreign > counted and foreign_alarm()
        said = [r for r in caplog.records if "another simulator's clock on" in r.getMessage()]
        assert len(said) == 2
    finally:
        service.close()
        ours.close()
        theirs.close()


def test_a_demo_pinned_after_hearing_another_simulator_stamps_on_its_own(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """`dpgw demo` starts its gateway (subscribed to the clock) before it pins its own simulator's run: a
    tick of another simulator heard in between is dropped at the pin, the demo's data is stamped on its
    own simulator's time, and the other simulator is said once in the log."""
    import logging
    import time

    caplog.set_level(logging.WARNING, logger="gateway.service")
    service = sim_service(tmp_path)
    st = service.sim_time
    assert st is not None
    ours, theirs = 1_600_000_000 * S, 1_600_000_000 * S + 3600 * S
    service._on_clock(Sample(SimClock(stamp_ns=theirs, period_s=0.05, speed=1.0, run=22).encode()))
    st.pin(11)
    service._on_clock(Sample(SimClock(stamp_ns=ours, period_s=0.05, speed=1.0, run=11).encode()))
    service._on_clock(Sample(SimClock(stamp_ns=theirs + TICK_NS, period_s=0.05, speed=1.0, run=22).encode()))
    service._take(chunk(time.monotonic_ns()))
    assert ours <= service.pipeline.counters["mux"].last_rx_ns <= ours + TICK_NS
    said = [r for r in caplog.records if "another simulator's clock" in r.getMessage()]
    assert len(said) == 1 and "run 22" in said[0].getMessage()


def test_the_last_status_after_a_restart_is_on_the_new_runs_time(tmp_path: Path) -> None:
    """The last status `drain` writes is never stamped before the periodic one logged last, but that one
    is of the run before a restart when the gateway stops right after following a new run: the last status
    goes into the new run's file at the new run's time, not an hour ahead at the old run's."""
    import time

    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path, status_hz=10.0)
    service.log = McapLogWriter(tmp_path / "gw.mcap", profile="dpgw", continue_set=True)
    st = service.sim_time
    assert st is not None
    t0, mono0 = 1_600_000_000 * S, time.monotonic_ns() - 60 * S
    run_of_the_plant(service, t0 + 3600 * S, mono0, (100.0, 0.0, 45.0))  # the old run, an hour ahead
    service.run(duration_s=0.15)  # its periodic status
    st.on_tick(t0, 0.05, mono0 + 12 * S)  # the restarted simulator's first tick
    service._take(Chunk("mux", fix(-50.0, 30.0, 200.0, t0), rx_ns=1, rx_mono_ns=mono0 + 12 * S + 10**6))
    assert service.runs_followed == 1
    service.drain()
    service.log.close()
    new_file = _messages(tmp_path / "gw_0001.mcap")
    late = [(topic, t) for topic, t, _ in new_file if not t0 <= t <= t0 + S]
    assert not late, f"stamped off the new run's time: {late}"


def test_the_status_keeps_its_rate_in_the_simulations_time(tmp_path: Path) -> None:
    """Before, the status went out on the wall clock: a simulator at 10x gave the log one status per 10 s
    of its time (29 over a 240 s demo at 1 Hz). On ``clock = "sim"`` it keeps its rate in the simulation's
    time, as everything else the gateway logs does: ~10 s of simulation at 10x, ~10 statuses at 1 Hz."""
    import threading
    import time

    from wire.mcap.writer import McapLogWriter

    service = sim_service(tmp_path, status_hz=1.0)
    service.log = McapLogWriter(tmp_path / "gw.mcap", profile="dpgw")
    t0, speed, wall_s = 1_800_000_000 * S, 10.0, 1.2
    mono0 = time.monotonic_ns()
    service._on_clock(Sample(SimClock(stamp_ns=t0, period_s=0.05, speed=speed).encode()))
    runner = threading.Thread(target=service.run, kwargs={"duration_s": wall_s})
    runner.start()
    while runner.is_alive():  # ticks at 10x the wall, as a simulator's clock publisher sends them
        elapsed = time.monotonic_ns() - mono0
        service._on_clock(
            Sample(SimClock(stamp_ns=t0 + int(speed * elapsed), period_s=0.05, speed=speed).encode())
        )
        time.sleep(0.005)
    runner.join()
    service.log.close()
    stamps = [ns for topic, ns in _log_times(tmp_path / "gw.mcap") if topic == "/dp/status"]
    covered = (max(stamps) - t0) / S
    assert covered > 5.0, covered  # (the simulation ran at least 5 s in the 1.2 s of wall)
    assert len(stamps) >= 0.7 * covered, (len(stamps), covered)
    gaps = [(b - a) / S for a, b in itertools.pairwise(stamps)]
    assert max(gaps) < 2.5, gaps  # about a second of simulation apart (a busy machine: a late one)


def test_the_next_status_time_holds_the_rate_and_follows_a_clock_that_jumps() -> None:
    """A period after the last due time while the clock runs on; from now where the clock jumped forward
    past it or went back (a simulation started over; the schedule of the old run would otherwise stay far
    ahead, and every pass of the loop would find a status due)."""
    from gateway.service import next_due

    assert next_due(None, 10 * S, S) == 11 * S
    assert next_due(11 * S, 11 * S + 30_000_000, S) == 12 * S  # a late pass: the rate holds
    assert next_due(12 * S, 20 * S, S) == 21 * S  # jumped forward
    assert next_due(500 * S, 3 * S, S) == 4 * S  # went back
