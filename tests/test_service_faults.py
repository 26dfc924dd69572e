"""The live service through the faults of weeks at sea: the log's disk fails, a USB serial adapter is
unplugged and plugged in again. Real sockets, a real pty, a real Zenoh session and real MCAP files; every
wait is for an event, with a deadline.

What must hold each time: the DP outputs (estimates on Zenoh) go on, the fault is a `/status` alarm while it
lasts, and the gateway takes up what came back without a restart."""

from __future__ import annotations

import base64
import contextlib
import gc
import json
import logging
import os
import re
import socket
import subprocess
import sys
import threading
import time
import tracemalloc
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh
from conftest import Recorder, free_port, wait_for

import wire.mcap.writer as mcap_writer
from gateway.bus import BusError, Dialler, UnreachableError, isolated_config, make_config, open_session
from gateway.config import parse_config
from gateway.service import GatewayService
from simulator.transports import PtySink
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import log_files, read_messages, summary
from wire.mcap.rotation import rotated_path
from wire.messages import Estimate


def burst(k: int) -> bytes:
    gga = enc.gga("GP", datetime.now(UTC), 59.4 + 1e-6 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
    return (gga + enc.hdt("HE", 0.5)).encode()


class Live:
    """A running `GatewayService` (consumer loop in a thread) and a Zenoh client counting its estimates."""

    def __init__(
        self,
        tmp_path: Path,
        url: str,
        connect: list[str] | None = None,
        mode: str = "peer",
        sinks: Sequence[Any] = (),
    ) -> None:
        self.zport = free_port()
        self.log_path = tmp_path / "dpgw.mcap"
        self.tables = {
            "vessel": {"name": "mss_supply"},
            "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
            "sources": [{"name": "gps", "url": url, "protocol": "nmea", "roles": ["position", "heading"]}],
            "observer": {"wave_period_s": 9.0},
            "zenoh": {
                "mode": mode,
                "listen": [f"tcp/127.0.0.1:{self.zport}"] if mode == "peer" else [],
                "connect": connect or [],
                "multicast_scouting": False,
                "prefix": "dp/f",
            },
            "status": {"rate_hz": 10.0},
            "log": {"path": str(self.log_path), "flush_interval_s": 0.1},
        }
        self.service = GatewayService(
            parse_config(self.tables, base_dir=tmp_path), config_tables=self.tables, sinks=sinks
        )
        self.estimates = 0
        self._lock = threading.Lock()

    def __enter__(self) -> Live:
        self.service.start()
        self.loop = threading.Thread(target=self.service.run, name="consumer")
        self.loop.start()
        self.client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{self.zport}"]))
        self._sub = self.client.declare_subscriber("dp/f/estimate", self._on_estimate)
        return self

    def __exit__(self, *exc: object) -> None:
        self.service.stop_event.set()
        self.loop.join(timeout=30)
        self.service.drain()
        self.client.close()
        self.service.close()
        assert not self.loop.is_alive()

    def _on_estimate(self, _sample: zenoh.Sample) -> None:
        with self._lock:
            self.estimates += 1

    def status(self) -> dict[str, Any]:
        replies = [r for r in self.client.get("dp/f/status", timeout=2.0) if r.ok is not None]
        return json.loads(replies[0].ok.payload.to_bytes()) if replies else {}

    def alarms(self, word: str) -> list[str]:
        return [a for a in self.status().get("alarms", []) if word in a]

    def estimates_go_on(self, send: Callable[[], None], n: int = 5) -> None:
        """At least ``n`` more estimates arrive on Zenoh (sending while waiting)."""
        start = self.estimates
        assert wait_for(lambda: send() or self.estimates >= start + n, 30.0), "no estimates on Zenoh"


@pytest.fixture
def quick_retry(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setattr(mcap_writer, "RETRY_S", 0.2, raising=False)  # the log's retry, not 10 s
    yield


def test_the_log_disk_failing_is_an_alarm_and_outputs_go_on(
    tmp_path: Path, quick_retry: None, caplog: pytest.LogCaptureFixture
) -> None:
    """The log file removed under the gateway (a disk unmounted) and the next file on a full disk
    (/dev/full: the kernel's ENOSPC): estimates keep coming on Zenoh, /status says what is wrong, the
    gateway's log says it once; when there is room again, logging resumes in the next file of the set."""
    udp = free_port(socket.SOCK_DGRAM)
    caplog.set_level(logging.WARNING, logger="wire.mcap.writer")
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = [0]

    def send() -> None:
        tx.sendto(burst(sent[0]), ("127.0.0.1", udp))
        sent[0] += 1
        time.sleep(0.02)  # (pacing the sender: 50 bursts a second, a busy multiplexer)

    full = rotated_path(tmp_path / "dpgw.mcap", 1)
    try:
        with Live(tmp_path, f"udp://127.0.0.1:{udp}") as live:
            live.estimates_go_on(send)
            full.symlink_to("/dev/full")  # where the next file of the set will go
            live.log_path.unlink()  # the disk is gone from under the open file
            assert wait_for(lambda: send() or live.alarms("log:"), 30.0), "no /status alarm for the log"
            alarm = live.alarms("log:")[0]
            assert "not logged" in alarm and ("removed" in alarm or "No space left" in alarm), alarm
            live.estimates_go_on(send, 20)  # ~2 s of DP outputs while the log fails
            assert wait_for(lambda: send() or "No space left" in " ".join(live.alarms("log:")), 30.0)
            full.unlink()  # room again
            assert wait_for(lambda: send() or not live.alarms("log:"), 30.0), live.alarms("log:")
            resumed_at = sent[0]
            live.estimates_go_on(send, 20)
            lost = live.service.log.lost if live.service.log else 0
    finally:
        tx.close()
    assert lost > 0
    errors = [
        r.getMessage()
        for r in caplog.records
        if r.levelno >= logging.ERROR and r.name == mcap_writer.__name__
    ]
    assert len(errors) == 1, errors  # one line for the failure, not one per message or retry
    assert "the file was removed while being written" in errors[0], errors
    assert any("writing again, to " + str(full) in r.getMessage() for r in caplog.records)
    # logging resumed: the file that replaced /dev/full holds raw input and estimates after the return
    assert log_files(live.log_path) == [full]
    raw = list(read_messages(full, "/raw/nmea/gps"))
    assert len(raw) >= 2 * 10 and len(list(read_messages(full, "/dp/estimate"))) >= 10
    assert resumed_at > 0


def test_a_usb_serial_adapter_unplugged_and_back(tmp_path: Path) -> None:
    """The pty behind the configured name closes (the adapter unplugged): /status says the source is
    disconnected and then stale; a new pty behind the same name (plugged in again) is read again, estimates
    resume and the alarm clears, without restarting the gateway."""
    link = tmp_path / "ttyUSB0"
    sink = PtySink(str(link))
    k = [0]

    def send_on(s: PtySink) -> Callable[[], None]:
        def send() -> None:
            s.write(burst(k[0]))
            k[0] += 1
            time.sleep(0.02)

        return send

    with Live(tmp_path, f"serial://{link}?baud=115200") as live:
        try:
            live.estimates_go_on(send_on(sink))
        finally:
            sink.close()  # unplugged
        assert wait_for(lambda: live.alarms("source gps: disconnected"), 30.0), live.status().get("alarms")
        # once a reopen has failed: the problem, once, not the start-up message with the source's name and
        # URL again inside the alarm that names them
        gone = f"source gps: disconnected (serial port {link} does not exist; reopening)"
        assert wait_for(lambda: live.alarms(gone), 30.0), live.status().get("alarms")
        src = live.service._sources[0]
        assert src.stats.errors["disconnected"] == 1 and src.running
        with PtySink(str(link)) as sink2:  # plugged in again, as a new device behind the same name
            send2 = send_on(sink2)
            assert wait_for(lambda: src.stats.connected, 30.0), "the port was not reopened"
            live.estimates_go_on(send2, 10)
            assert wait_for(lambda: send2() or not live.alarms("source gps"), 30.0), live.alarms("source gps")
            # the status counts the reconnect and says why the port was lost
            gps = wait_for(lambda: live.status()["sources"]["gps"], 30.0)
            assert gps["reconnects"] == 1, gps
            assert gps["last_disconnect"].startswith(f"serial port {link} failed: "), gps
        assert src.stats.reconnects == 1


_ROUTER = """
import json, sys, time, zenoh
listen = {"endpoints": [sys.argv[1]]}
conf = {"mode": "router", "listen": listen, "scouting": {"multicast": {"enabled": False}}}
session = zenoh.open(zenoh.Config.from_json5(json.dumps(conf)))
print("up", time.time(), flush=True)  # (when it listens: zenoh.open has bound its listener)
sys.stdin.read()  # until the test closes stdin or kills it
"""


def start_router(endpoint: str, listened: list[float] | None = None) -> subprocess.Popen[str]:
    """A Zenoh router (what zenohd is) in a process of its own; returns once it listens (the time it
    began to, wall clock, appended to ``listened``)."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _ROUTER, endpoint], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    word, at = proc.stdout.readline().split()
    assert word == "up"
    if listened is not None:
        listened.append(float(at))
    return proc


def bursts_to(tx: socket.socket, port: int) -> Callable[[], None]:
    """A function that sends the next burst (`burst`) to 127.0.0.1:``port``, paced at 50 a second: called
    from inside `wait_for`, the stream goes on while a test waits for what it does."""
    k = [0]

    def send() -> None:
        tx.sendto(burst(k[0]), ("127.0.0.1", port))
        k[0] += 1
        time.sleep(0.02)

    return send


def zenoh_alarms(live: Live) -> list[str]:
    """The Zenoh link's alarms in the gateway's last status."""
    return [a for a in live.service.last_status().get("alarms", []) if a.startswith("zenoh:")]


def test_a_peer_started_before_the_endpoint_it_connects_to(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A bench's gateway (a peer, ``connect`` to the simulator's endpoint) started before the simulator: it
    says the endpoint is not reached *yet*, then that it is connected, never "lost" nor "connected again"
    (it had lost nothing: an integrator read "lost" as the simulator having died)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    send = bursts_to(tx, udp)
    caplog.set_level(logging.WARNING, logger="dpgw")
    proc: subprocess.Popen[str] | None = None
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}", connect=[endpoint])
    live.service.start()
    live.loop = threading.Thread(target=live.service.run, name="consumer")
    live.loop.start()
    try:
        assert wait_for(lambda: send() or zenoh_alarms(live), 30.0), "no alarm with the endpoint not up"
        proc = start_router(endpoint)  # the simulator's session comes up
        assert wait_for(lambda: send() or not zenoh_alarms(live), 30.0), zenoh_alarms(live)
    finally:
        live.service.stop_event.set()
        live.loop.join(timeout=30)
        live.service.drain()
        live.service.close()
        tx.close()
        if proc is not None:
            proc.kill()
            proc.wait()
    said = [r.getMessage() for r in caplog.records if r.getMessage().startswith("zenoh:")]
    assert len(said) == 2, said
    assert said[0].startswith(f"zenoh: {endpoint} (connect) not reached yet") and "lost" not in said[0], said
    assert said[1] == f"zenoh: connected to {endpoint}; outputs go out", said


def test_a_down_connect_endpoint_is_named_and_a_console_on_the_listener_still_hears(tmp_path: Path) -> None:
    """A peer gateway listening for consoles and dialling a simulator's endpoint that is down: the alarm
    names that endpoint ("(connect)"); it says outputs go nowhere only while the session has nobody at all.
    A console on the gateway's own listener receives the status, whose alarm then no longer claims that
    outputs go nowhere; the simulator's endpoint coming up clears the alarm."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    send = bursts_to(tx, udp)
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}", connect=[endpoint])
    live.service.start()
    live.loop = threading.Thread(target=live.service.run, name="consumer")
    live.loop.start()
    sim: zenoh.Session | None = None
    try:
        assert wait_for(lambda: send() or zenoh_alarms(live), 30.0), "no alarm with the endpoint down"
        alone = zenoh_alarms(live)[0]
        assert alone.startswith(f"zenoh: not connected to {endpoint} (connect; ") and "go nowhere" in alone
        live.client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{live.zport}"]))
        live._sub = live.client.declare_subscriber("dp/f/estimate", live._on_estimate)
        live.estimates_go_on(send)  # the console on the listener hears the gateway
        heard = wait_for(lambda: send() or [a for a in live.alarms("zenoh:") if "go nowhere" not in a], 30.0)
        assert heard == [f"zenoh: not connected to {endpoint} (connect; Zenoh redials it)"], heard
        sim = open_session(make_config(listen=[endpoint], multicast_scouting=False))  # the simulator is up
        assert wait_for(lambda: send() or not zenoh_alarms(live), 30.0), zenoh_alarms(live)
    finally:
        tx.close()
        if hasattr(live, "client"):
            live.__exit__()
        else:
            live.service.stop_event.set()
            live.loop.join(timeout=30)
            live.service.drain()
            live.service.close()
        if sim is not None:
            sim.close()


def test_the_zenoh_router_restarting(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The gateway connects to a router (zenoh.connect); a console reaches it through the router. The router
    is killed: /status (in the log, on Foxglove, on -v) says Zenoh is not connected; the router is started
    again: estimates reach the console again, the alarm clears, without restarting the gateway."""
    router = f"tcp/127.0.0.1:{free_port()}"
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    send = bursts_to(tx, udp)

    proc = start_router(router)
    caplog.set_level(logging.WARNING, logger="dpgw")
    try:
        live = Live(tmp_path, f"udp://127.0.0.1:{udp}", connect=[router])
        live.service.start()
        live.loop = threading.Thread(target=live.service.run, name="consumer")
        live.loop.start()
        live.client = open_session(make_config(mode="client", connect=[router], multicast_scouting=False))
        live._sub = live.client.declare_subscriber("dp/f/estimate", live._on_estimate)
        try:
            live.estimates_go_on(send)
            assert not zenoh_alarms(live)
            proc.kill()
            proc.wait()
            assert wait_for(lambda: send() or zenoh_alarms(live), 30.0), "no alarm with the router gone"
            assert router in zenoh_alarms(live)[0]
            before = live.service.pipeline.estimates
            assert wait_for(lambda: send() or live.service.pipeline.estimates >= before + 10, 30.0)
            proc = start_router(router)  # the router is back
            live.estimates_go_on(send, 10)  # ... and so are the estimates at the console
            assert wait_for(lambda: send() or not zenoh_alarms(live), 30.0), zenoh_alarms(live)
        finally:
            live.__exit__()
    finally:
        tx.close()
        proc.kill()
        proc.wait()
    said = [r.getMessage() for r in caplog.records if r.getMessage().startswith("zenoh:")]
    assert len(said) == 2 and "lost" in said[0] and "connected again" in said[1], said
    statuses = [m for _, _, _, m in read_messages(log_files(live.log_path), "/dp/status")]
    assert any(any(a.startswith("zenoh: not connected") for a in s.get("alarms", [])) for s in statuses)


def test_a_client_gateway_starts_before_its_router(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """``mode = "client"``: the router in zenoh.connect is not up when the gateway starts (services start in
    any order). The gateway starts all the same, runs its pipeline, and says Zenoh is not connected; the
    router comes: a console behind it receives the estimates, the alarm clears. The router restarts: the
    estimates reach the console again, without restarting the gateway."""
    router = f"tcp/127.0.0.1:{free_port()}"
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    send = bursts_to(tx, udp)

    class Local(Recorder):  # a sink that needs no Zenoh (as the Foxglove server)
        needs_zenoh = False

    local, behind = Local(), Recorder()
    caplog.set_level(logging.WARNING, logger="dpgw")
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}", connect=[router], mode="client", sinks=[local, behind])
    live.service.start()  # nobody at the router's endpoint: it starts all the same
    live.loop = threading.Thread(target=live.service.run, name="consumer")
    live.loop.start()
    proc = None
    listened: list[float] = []
    try:
        before = live.service.pipeline.estimates
        assert wait_for(lambda: send() or live.service.pipeline.estimates >= before + 10, 30.0)
        assert wait_for(lambda: send() or zenoh_alarms(live), 30.0), "no alarm without the router"
        said = f"zenoh: not connected to {router} (connect; dialled every 0.5 s)"
        assert zenoh_alarms(live)[0].startswith(said)
        assert local.of(Estimate) and not behind.outputs  # (a Zenoh sink starts with the session)
        proc = start_router(router, listened)
        assert wait_for(lambda: send() or not zenoh_alarms(live), 30.0), zenoh_alarms(live)
        live.client = open_session(make_config(mode="client", connect=[router], multicast_scouting=False))
        live._sub = live.client.declare_subscriber("dp/f/estimate", live._on_estimate)
        live.estimates_go_on(send, 10)  # the console behind the router has the estimates
        assert behind.of(Estimate)
        proc.kill()  # the router restarts
        proc.wait()
        assert wait_for(lambda: send() or zenoh_alarms(live), 30.0), "no alarm with the router gone"
        proc = start_router(router, listened)
        assert wait_for(lambda: send() or not zenoh_alarms(live), 30.0), zenoh_alarms(live)
        live.estimates_go_on(send, 10)
    finally:
        tx.close()
        if hasattr(live, "client"):
            live.__exit__()
        else:
            live.service.stop_event.set()
            live.loop.join(timeout=30)
            live.service.close()
        if proc is not None:
            proc.kill()
            proc.wait()
    records = [r for r in caplog.records if r.getMessage().startswith("zenoh:")]
    said = [r.getMessage() for r in records]
    assert said[0].startswith(f"zenoh: cannot connect to {router}") and "dials it" in said[0], said
    assert said[1] == f"zenoh: connected to {router}; outputs go out", said
    assert "lost" in said[2] and "connected again" in said[3], said
    # (the connection's delay after the router comes: bench/zenoh_redial.py; here it is the router's own
    # start-up that takes longer than a dial period)
    assert records[1].created < listened[0] + 10.0 and records[3].created < listened[1] + 10.0


def test_a_client_with_a_zenoh_config_file_keeps_what_the_file_says(tmp_path: Path) -> None:
    """A Zenoh config file is the user's own: a client whose file says nothing of ``exit_on_failure`` fails
    to start without its router, as Zenoh's default for clients is."""
    router = f"tcp/127.0.0.1:{free_port()}"
    conf = {
        "mode": "client",
        "connect": {"endpoints": [router]},
        "scouting": {"multicast": {"enabled": False}},
    }
    (tmp_path / "zenoh.json5").write_text(json.dumps(conf))
    live = Live(tmp_path, "udp://127.0.0.1:0", connect=[router], mode="client")
    live.tables["zenoh"] = {"config_file": str(tmp_path / "zenoh.json5"), "prefix": "dp/f"}
    live.service = GatewayService(parse_config(live.tables, base_dir=tmp_path), config_tables=live.tables)
    with pytest.raises(UnreachableError, match=f"cannot connect to {router}"):
        live.service.start()


def test_a_client_gateway_without_its_router_still_stops_on_a_port_in_use(tmp_path: Path) -> None:
    """Waiting for the router is for a router not up yet, not for a configuration mistake: a listener's
    port in use stops start-up with the message naming zenoh.listen, as in peer mode."""
    router = f"tcp/127.0.0.1:{free_port()}"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        endpoint = f"tcp/127.0.0.1:{taken.getsockname()[1]}"
        live = Live(tmp_path, "udp://127.0.0.1:0", connect=[router], mode="client")
        live.tables["zenoh"]["listen"] = [endpoint]
        live.service = GatewayService(parse_config(live.tables, base_dir=tmp_path), config_tables=live.tables)
        with pytest.raises(BusError) as info:
            live.service.start()
    assert not isinstance(info.value, UnreachableError)
    assert str(info.value).startswith(f"zenoh.listen: cannot listen on {endpoint}: address in use")


def test_a_dialler_dials_until_closed() -> None:
    """The gateway's dialler (a client's router not up yet) dials again and again; another failure than
    nobody answering (its listener's port taken meanwhile) is kept for the status and it dials on; it
    stops when closed: a gateway told to stop while its router is away stops, leaving no thread behind."""
    router = f"tcp/127.0.0.1:{free_port()}"
    listen: list[str] = []
    dialler = Dialler(
        lambda: make_config(mode="client", connect=[router], listen=listen, multicast_scouting=False), 0.05
    )
    with socket.socket() as taken:
        try:
            assert wait_for(lambda: dialler.dials >= 3, 30.0), "it does not dial again"
            assert dialler.error is None
            taken.bind(("127.0.0.1", 0))
            taken.listen()
            listen.append(f"tcp/127.0.0.1:{taken.getsockname()[1]}")
            assert wait_for(lambda: dialler.error is not None, 30.0), "the port in use is not kept"
            assert dialler.error is not None and dialler.error.key == "listen"
            assert "address in use" in str(dialler.error)
            dials = dialler.dials
            assert wait_for(lambda: dialler.dials >= dials + 3, 30.0), "it stopped dialling"
        finally:
            dialler.close()
    assert dialler.take() is None
    assert not [t for t in threading.enumerate() if t.name == "zenoh-dialler"]


def _open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.mark.slow
@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="counts descriptors in /proc")
def test_nothing_grows_with_time(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """~25 s of a busy gateway: NMEA at ~200 bursts a second on UDP, a TCP source whose server drops the
    link every 0.5 s (a reconnect each time), the log rotating every ~50 kB, status at 10 Hz. Between the
    end of a warm-up and the end, the open descriptors, the threads and the memory Python holds
    (tracemalloc) must not grow with the time run: rotation closes its files, reconnects close their
    sockets, histories are bounded."""
    # pytest keeps every log record of a test (a reconnect is one, by design): not the gateway's memory
    caplog.set_level(logging.ERROR)
    udp = free_port(socket.SOCK_DGRAM)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    server.settimeout(0.05)
    tcp_port = server.getsockname()[1]
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}")
    tcp = {"name": "mux2", "url": f"tcp://127.0.0.1:{tcp_port}", "protocol": "nmea", "roles": ["heading"]}
    tables = {**live.tables, "sources": [*live.tables["sources"], {**tcp, "priority": 2}]}
    config = parse_config(tables, base_dir=tmp_path)
    config = replace(config, log=replace(config.log, rotate_mb=0.05))  # (below what a config may say)
    live.service = GatewayService(config, config_tables=tables)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    k = [0]
    accepted = [0]
    conn: list[socket.socket] = []

    def serve() -> None:
        """Send to the TCP source, and drop its connection every 0.5 s."""
        if conn and time.monotonic() - conn[1] > 0.5:  # type: ignore[operator]
            conn[0].close()
            conn.clear()
        if not conn:
            try:
                c, _ = server.accept()
            except TimeoutError:
                return
            accepted[0] += 1
            conn[:] = [c, time.monotonic()]  # type: ignore[list-item]
        with contextlib.suppress(OSError):
            conn[0].sendall(enc.hdt("HE", 0.5 + 1e-3 * (k[0] % 5)).encode())

    def send() -> None:
        tx.sendto(burst(k[0]), ("127.0.0.1", udp))
        k[0] += 1
        if k[0] % 10 == 0:
            serve()
        time.sleep(0.005)

    def measure() -> tuple[int, int, int]:
        # what the consumer has not taken yet is a busy machine's backlog, not growth: wait until it is in
        assert wait_for(lambda: live.service._queue.empty(), 30.0), "the consumer never caught up"
        gc.collect()  # (a finished file's writer is a reference cycle: what the collector will free)
        return _open_fds(), threading.active_count(), tracemalloc.get_traced_memory()[0]

    try:
        with live:
            deadline = time.monotonic() + 5.0  # warm-up: caches, first files, every channel registered
            while time.monotonic() < deadline:
                send()
            tracemalloc.start()
            first = measure()
            files0, reconnects0 = len(live.service.log.paths), live.service._sources[1].stats.reconnects  # type: ignore[union-attr]
            points = [first]
            for _ in range(2):  # 2 x 10 s
                deadline = time.monotonic() + 10.0
                while time.monotonic() < deadline:
                    send()
                points.append(measure())
            mid, last = points[1:]
            files = len(live.service.log.paths) - files0  # type: ignore[union-attr]
            reconnects = live.service._sources[1].stats.reconnects - reconnects0
            estimates = live.service.pipeline.estimates
    finally:
        tracemalloc.stop()
        tx.close()
        server.close()
        for c in conn[:1]:
            c.close()  # type: ignore[attr-defined]
    print(
        f"(descriptors, threads, bytes traced): after warm-up {first}, 10 s later {mid}, 20 s later {last}; "
        f"{files} files, {reconnects} reconnects, {estimates} estimates"
    )
    assert files >= 10 and reconnects >= 10  # the test did rotate and reconnect, many times
    # descriptors: no file or socket left open (~20 of each made); a reconnect in progress, the fsync's
    # duplicate, a file being opened come and go
    assert last[0] - first[0] <= 4, (first, mid, last)
    assert last[1] <= first[1], (first, mid, last)  # threads: none left behind (another test's may end)
    # memory held: bounded (what the first 10 s took: the log's open chunk, up to 256 KiB, ...), not
    # growing with time (the second 10 s add a few kB: the writer's list of the files it wrote)
    assert last[2] - first[2] < 2 * 2**20 and last[2] - mid[2] < 64 * 2**10, (first, mid, last)


class SlowSink:
    """An output that takes ``delay_s`` per batch while ``slow`` is set: a consumer that cannot keep up."""

    name = "slow"
    needs_zenoh = False

    def __init__(self, delay_s: float) -> None:
        self.delay_s = delay_s
        self.slow = threading.Event()

    def start(self, session: Any) -> None:
        pass

    def emit(self, outputs: list[Any], encoded: list[bytes]) -> None:
        if self.slow.is_set():
            time.sleep(self.delay_s)  # (the work of a slow output, not a wait of the test)

    def close(self) -> None:
        pass


def test_a_gateway_that_falls_behind_says_so(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A consumer that cannot keep up (here a slow output) lets inputs wait, and its estimates and
    commands are as late: /status says how late while it lasts, the gateway's log says so once when it
    starts and once when it is back. Before: not a word (measured: minutes behind, a simulated vessel
    700 m off station under commands that late)."""
    udp = free_port(socket.SOCK_DGRAM)
    caplog.set_level(logging.WARNING, logger="dpgw")
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = [0]

    def send() -> None:
        tx.sendto(burst(sent[0]), ("127.0.0.1", udp))
        sent[0] += 1
        time.sleep(0.02)  # (pacing the sender: 50 bursts a second)

    sink = SlowSink(0.1)
    try:
        with Live(tmp_path, f"udp://127.0.0.1:{udp}", sinks=[sink]) as live:
            live.estimates_go_on(send)
            assert not live.alarms("behind")
            sink.slow.set()  # 10 batches a second at most, 50 bursts a second in
            assert wait_for(lambda: send() or live.alarms("gateway behind"), 60.0), live.status()
            alarm = live.alarms("gateway behind")[0]
            assert "s ago" in alarm and "waiting" in alarm, alarm
            assert live.service.behind_ns > 1e9
            sink.slow.clear()
            assert wait_for(lambda: send() or not live.alarms("gateway behind"), 60.0), live.status()
            live.estimates_go_on(send)
    finally:
        tx.close()
    said = [r.getMessage() for r in caplog.records if "gateway behind" in r.getMessage()]
    back = [r.getMessage() for r in caplog.records if "gateway caught up" in r.getMessage()]
    assert len(said) == 1 and len(back) == 1, (said, back)


def test_a_stop_far_behind_ends_in_time_with_every_byte_logged(tmp_path: Path) -> None:
    """Stopped while far behind (minutes of input queued), the gateway handled all of it first, for
    minutes, and systemd killed it after TimeoutStopSec: the log cut, the queue lost. Now the drain handles
    for a bounded time and writes the rest to the log as received: the stop ends in time, the log is
    complete and holds every byte the source received."""
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink = SlowSink(0.2)
    try:
        with Live(tmp_path, f"udp://127.0.0.1:{udp}", sinks=[sink]) as live:
            live.estimates_go_on(lambda: tx.sendto(burst(0), ("127.0.0.1", udp)) and time.sleep(0.02))
            src = live.service._sources[0]
            sink.slow.set()  # 5 batches a second at most: what comes now waits in the queue
            before = src.stats.chunks
            for k in range(300):  # a minute of handling at that pace
                tx.sendto(burst(k), ("127.0.0.1", udp))
            assert wait_for(lambda: src.stats.chunks >= before + 300, 30.0), src.stats.chunks - before
            live.service.stop_event.set()
            live.loop.join(timeout=30)
            t0 = time.monotonic()
            live.service.drain(within_s=1.0)
            took = time.monotonic() - t0
            received = src.stats.bytes_received
            logged_only = live.service.logged_unhandled
            live.service.close()
    finally:
        tx.close()
    assert took < 5.0, took  # 1 s of handling (one slow batch past it) and the writes
    assert logged_only > 200, logged_only
    assert summary(live.log_path).complete
    logged = 0
    for _, _, _, p in read_messages(live.log_path, "/raw/nmea/gps"):
        body = base64.b64decode(p["data"]) if "data" in p else p["text"].encode("ascii")
        logged += len(body) + (0 if p.get("unterminated") else len(p.get("eol", "\r\n")))
    assert logged == received


class BlockedSink(SlowSink):
    """An output that, while ``slow`` is set, does not return until ``free`` is: a consumer stopped."""

    def __init__(self) -> None:
        super().__init__(0.0)
        self.free = threading.Event()

    def emit(self, outputs: list[Any], encoded: list[bytes]) -> None:
        if self.slow.is_set():
            self.free.wait(60)


def logged_raw_bytes(path: Path) -> int:
    """The bytes of the source ``gps`` that the log holds as received."""
    logged = 0
    for _, _, _, p in read_messages(log_files(path), "/raw/nmea/gps"):
        body = base64.b64decode(p["data"]) if "data" in p else p["text"].encode("ascii")
        logged += len(body) + (0 if p.get("unterminated") else len(p.get("eol", "\r\n")))
    return logged


def test_an_overloaded_gateway_bounds_its_queue_and_logs_every_input(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Inputs arriving 25 times faster than the gateway handles them: its queue grew without bound (memory
    with it; only "gateway behind" said so). Now more than ``queue_max`` waiting sends the oldest to the log
    as received, unhandled and counted, and the alarm says how many: the queue stays within its bound (and
    one turn's arrivals), nothing is lost (every byte received is in the log) and the gateway says it once."""
    udp = free_port(socket.SOCK_DGRAM)
    caplog.set_level(logging.WARNING, logger="dpgw")
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink = SlowSink(0.02)
    n, bound = 2000, 100
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}", sinks=[sink])
    live.service.queue_max = bound
    try:
        with live:
            live.estimates_go_on(lambda: tx.sendto(burst(0), ("127.0.0.1", udp)) and time.sleep(0.02))
            src = live.service._sources[0]
            sink.slow.set()  # 20 ms a batch: some 20 inputs a second handled
            before = src.stats.chunks
            for k in range(n):
                tx.sendto(burst(k), ("127.0.0.1", udp))
                time.sleep(0.002)  # (pacing the sender: 500 a second)
            assert wait_for(lambda: src.stats.chunks >= before + n, 30), src.stats.chunks - before
            assert wait_for(lambda: live.alarms("without being handled"), 30), live.status()
            alarm = live.alarms("without being handled")[0]
            sink.slow.clear()
            live.service.stop_event.set()
            live.loop.join(timeout=30)
            live.service.drain()
            shed, lost, peak = (
                sum(live.service.shed.values()),
                dict(live.service.lost),
                live.service.queue_peak,
            )
            received = src.stats.bytes_received
            live.service.close()
    finally:
        tx.close()
    assert peak <= 2 * bound, peak  # the bound, and what arrives during one turn of the loop
    assert shed > n // 2, shed
    assert not lost, lost
    counted = re.search(r"(\d+) inputs written to the log without being handled \(gps (\d+);", alarm)
    assert counted and 0 < int(counted[1]) == int(counted[2]) <= shed, alarm  # (read while it counted)
    assert summary(live.log_path).complete
    assert logged_raw_bytes(live.log_path) == received
    said = [r.getMessage() for r in caplog.records if "gateway overloaded" in r.getMessage()]
    assert len(said) == 1, said


def test_a_stopped_gateway_counts_what_it_cannot_queue(tmp_path: Path) -> None:
    """A consumer that has stopped turning (an output that never returns; systemd's watchdog ends it)
    cannot log what it sheds: past ``4 * queue_max`` waiting, what arrives is counted as lost, not
    queued. Memory stays bounded and the count of what was neither handled nor logged is in /status."""
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink = BlockedSink()
    n, bound = 1000, 100
    live = Live(tmp_path, f"udp://127.0.0.1:{udp}", sinks=[sink])
    live.service.queue_max = bound
    try:
        with live:
            live.estimates_go_on(lambda: tx.sendto(burst(0), ("127.0.0.1", udp)) and time.sleep(0.02))
            src = live.service._sources[0]
            sink.slow.set()  # the next batch never returns
            before = src.stats.chunks
            for k in range(n):
                tx.sendto(burst(k), ("127.0.0.1", udp))
            assert wait_for(lambda: src.stats.chunks >= before + n, 30), src.stats.chunks - before
            waiting = live.service._queue.qsize()
            lost = sum(live.service.lost.values())
            shed = sum(live.service.shed.values())
            sink.free.set()  # the output comes back: the gateway goes on and says what it lost
            assert wait_for(lambda: live.alarms("lost, neither handled nor logged"), 30), live.status()
            alarm = live.alarms("lost, neither handled nor logged")[0]
    finally:
        sink.free.set()
        tx.close()
    assert waiting <= 4 * bound and live.service.queue_peak <= 4 * bound, (waiting, live.service.queue_peak)
    # What was not queued was shed into the log (while the consumer still turned: how much depends on how
    # fast the burst came, slower on a busy machine) or, once it had stopped, counted lost; a few were
    # handled before the output blocked.
    assert lost > 0 and lost + shed >= n - 4 * bound - 5, (lost, shed)
    assert f"{lost} inputs lost" in alarm and f"gps {lost}" in alarm, alarm
