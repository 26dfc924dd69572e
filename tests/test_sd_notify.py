"""`dpgw run` speaks systemd's notification protocol (`dpgw.sd_notify`) for the unit's ``Type=notify`` and
``WatchdogSec=``: READY once open, WATCHDOG from the consumer loop, STOPPING at a stop. Real processes and
a real unix datagram socket standing in for systemd's; the watchdog is shown to stop when the loop does."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

from conftest import free_port, one_source_config, wait_for
from test_service_faults import Live, SlowSink, burst

ROOT = Path(__file__).resolve().parents[1]


class FakeSystemd:
    """The notification socket: collects every datagram sent to it."""

    def __init__(self, path: Path) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.sock.settimeout(0.2)
        self.messages: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                self.messages.append(self.sock.recv(65536).decode())
            except TimeoutError:
                continue

    def with_line(self, start: str) -> list[str]:
        return [m for m in list(self.messages) for ln in m.splitlines() if ln.startswith(start)]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


def test_ready_watchdog_and_stopping(tmp_path: Path) -> None:
    cfg = one_source_config(tmp_path, f"udp://127.0.0.1:{free_port(socket.SOCK_DGRAM)}", "mux")
    systemd = FakeSystemd(tmp_path / "notify")
    env = dict(os.environ, NOTIFY_SOCKET=str(tmp_path / "notify"), WATCHDOG_USEC="400000")
    env.pop("WATCHDOG_PID", None)
    p = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg)],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert wait_for(lambda: systemd.with_line("READY=1") or p.poll() is not None, 120.0), p.poll()
        ready = systemd.with_line("READY=1")
        assert len(ready) == 1 and "STATUS=dpgw run: vessel mss_supply" in ready[0], ready
        # twice per 0.4 s period: a few of them in a moment
        assert wait_for(lambda: len(systemd.with_line("WATCHDOG=1")) >= 5, 30.0), systemd.messages
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
        assert p.returncode == 0, err
        assert systemd.with_line("STOPPING=1"), systemd.messages
        first_ping = next(k for k, m in enumerate(systemd.messages) if "WATCHDOG=1" in m)
        assert first_ping > systemd.messages.index(ready[0])  # fed once up, from the loop
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        systemd.close()


def test_the_watchdog_stops_when_the_consumer_loop_does(tmp_path: Path) -> None:
    """A loop stuck in an output that never returns must starve systemd's watchdog (so that systemd
    restarts the gateway), although its reader threads still take data in."""
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    turns = [0]
    stuck = threading.Event()
    release = threading.Event()

    class StuckSink(SlowSink):
        def emit(self, outputs: list[object], encoded: list[bytes]) -> None:
            if self.slow.is_set():
                stuck.set()
                release.wait(60)  # (blocked, as an output that hangs)

    sink = StuckSink(0.0)
    try:
        with Live(tmp_path, f"udp://127.0.0.1:{udp}", sinks=[sink]) as live:
            live.service.heartbeat = lambda: turns.__setitem__(0, turns[0] + 1)
            assert wait_for(lambda: turns[0] > 10, 30.0)
            sink.slow.set()
            assert wait_for(lambda: tx.sendto(burst(0), ("127.0.0.1", udp)) and stuck.is_set(), 30.0)
            at_stuck = turns[0]
            src = live.service._sources[0]
            got = src.stats.chunks
            assert wait_for(lambda: tx.sendto(burst(1), ("127.0.0.1", udp)) and src.stats.chunks >= got + 20)
            assert turns[0] <= at_stuck + 1, (at_stuck, turns[0])  # no turn while stuck
            sink.slow.clear()
            release.set()
            assert wait_for(lambda: turns[0] > at_stuck + 10, 30.0)
    finally:
        release.set()
        tx.close()


def test_a_failing_watchdog_notification_is_counted_and_the_loop_goes_on(tmp_path: Path) -> None:
    """The notification runs in the consumer loop: one that raises (a status line that cannot be made, a
    socket gone) is an internal error, counted and logged, and the gateway carries on handling input."""
    udp = free_port(socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    calls = [0]

    def failing() -> None:
        calls[0] += 1
        raise OSError("the notify socket is gone")

    try:
        with Live(tmp_path, f"udp://127.0.0.1:{udp}") as live:
            live.service.heartbeat = failing
            src = live.service._sources[0]
            assert wait_for(lambda: tx.sendto(burst(0), ("127.0.0.1", udp)) and src.stats.chunks >= 20, 30.0)
            assert wait_for(lambda: live.service.pipeline.estimates >= 5, 30.0)
            assert live.service.internal_errors["watchdog"] >= 2 and calls[0] >= 2
            assert live.loop.is_alive()
    finally:
        tx.close()
