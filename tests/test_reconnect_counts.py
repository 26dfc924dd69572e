"""A link that drops and comes back is counted per source: ``reconnects`` and the last disconnect (why and
when) in ``/dp/status``, in ``dpgw run -v``'s periodic line and in the run's final summary. A real TCP
server the test starts, kills and starts again on the same port (a GNSS multiplexer restarting), the
gateway's real TCP client source; every wait is for an event, with a deadline."""

from __future__ import annotations

import contextlib
import queue
import re
import signal
import socket
import threading
import time
from datetime import UTC, datetime
from pathlib import Path

from conftest import free_port, one_source_config, wait_for
from test_run_signals import Gateway
from test_service_faults import Live

from dpgw import cli_run
from wire.codecs import nmea_encode as enc


class RestartingServer:
    """A TCP server on one port sending GGA + HDT at 10 Hz to the client it accepted. `kill` closes the
    listener and the connection (the server process gone); `start` listens again on the same port."""

    def __init__(self) -> None:
        self.port = free_port()
        self.accepted = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        listener = socket.socket()
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", self.port))
        listener.listen()
        listener.settimeout(0.05)
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, args=(listener,), daemon=True)
        self._thread.start()

    def _serve(self, listener: socket.socket) -> None:
        conn = None
        try:
            while conn is None and not self._stop.is_set():
                with contextlib.suppress(TimeoutError):
                    conn, _ = listener.accept()
            if conn is None:
                return
            self.accepted += 1
            k = 0
            while not self._stop.wait(0.1):  # a receiver's 10 Hz: pacing, not a wait for an event
                gga = enc.gga("GP", datetime.now(UTC), 59.4 + 1e-7 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
                try:
                    conn.sendall((gga + enc.hdt("HE", 0.5 + 0.01 * (k % 5))).encode())
                except OSError:
                    return
                k += 1
        finally:
            if conn is not None:
                conn.close()
            listener.close()

    def kill(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
            assert not self._thread.is_alive()


def source_status(live: Live) -> dict:  # type: ignore[type-arg]
    return live.status().get("sources", {}).get("gps", {})


def test_a_tcp_server_that_drops_twice_shows_two_reconnects_and_the_last_disconnect(tmp_path: Path) -> None:
    """The status says nothing of reconnects while the link never dropped (left out while 0); after the
    server is killed and started again, ``reconnects`` is 1 and ``last_disconnect`` says why and when;
    after a second time, 2. ``dpgw run -v``'s line from that status says so too."""
    server = RestartingServer()
    server.start()
    try:
        with Live(tmp_path, f"tcp://127.0.0.1:{server.port}") as live:
            src = live.service._sources[0]
            assert wait_for(lambda: server.accepted == 1, 30.0), "the gateway never connected"
            assert wait_for(lambda: source_status(live).get("received", 0) > 0, 30.0), source_status(live)
            first = source_status(live)
            assert "reconnects" not in first and "last_disconnect" not in first, first
            for n in (1, 2):
                before_ns = time.time_ns()
                server.kill()
                assert wait_for(lambda: not src.stats.connected, 30.0), "the drop was not seen"
                server.start()
                assert wait_for(lambda n=n: server.accepted == n + 1, 30.0), "the gateway did not reconnect"
                status = wait_for(
                    lambda n=n: source_status(live).get("reconnects") == n and live.status(), 30.0
                )
                assert status, source_status(live)
                gps = status["sources"]["gps"]
                assert (
                    gps["last_disconnect"]
                    == f"connection to 127.0.0.1:{server.port} lost: closed by the server"
                )
                assert before_ns <= gps["last_disconnect_ns"] <= time.time_ns()
            line = cli_run.status_line(status, 10.0)
            lost = f"connection to 127.0.0.1:{server.port} lost: closed by the server"
            assert re.search(
                rf"gps \d+ rx [0-9.]+ s ago \(2 reconnects, last lost \d+ s ago: {re.escape(lost)}\)", line
            ), line
    finally:
        server.kill()


def test_a_client_of_a_tcp_listen_source_that_comes_back_is_a_reconnect(tmp_path: Path) -> None:
    """``tcp-listen``: a sensor that connects, hangs up and connects again (from a new port) is one
    reconnect, and the status says which client went and why."""
    port = free_port()
    with Live(tmp_path, f"tcp-listen://127.0.0.1:{port}") as live:
        src = live.service._sources[0]
        peers = []
        for n in (0, 1):
            with socket.create_connection(("127.0.0.1", port), timeout=5) as client:
                host, cport = client.getsockname()
                peers.append(f"{host}:{cport}")
                assert wait_for(lambda: src.stats.connected, 30.0), "the client was not accepted"
                client.sendall(enc.hdt("HE", 0.5).encode())
                assert wait_for(lambda n=n: source_status(live).get("received", 0) > n, 30.0), source_status(
                    live
                )
            assert wait_for(lambda: not src.stats.connected, 30.0), "the hang-up was not seen"
        status = wait_for(
            lambda: (
                source_status(live).get("last_disconnect") == f"client {peers[1]} gone: closed by the client"
                and source_status(live)
            ),
            30.0,
        )
        assert status and status["reconnects"] == 1, source_status(live)


def line_within(gw: Gateway, text: str, seconds: float) -> str | None:
    """The first line the gateway prints containing ``text`` within ``seconds`` from now (None if none:
    `Gateway.wait_line`'s timeout is per line, and a gateway with ``-v`` prints one every 5 s)."""
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = gw.lines.get(timeout=left)
        except queue.Empty:
            return None
        if text in line:
            return line
    return None


def write_config(tmp: Path, port: int) -> Path:
    return one_source_config(tmp, f"tcp://127.0.0.1:{port}", "gps", datum=True, log=False)


def test_dpgw_run_says_the_reconnects_in_its_periodic_line_and_its_final_summary(tmp_path: Path) -> None:
    """``dpgw run -v`` against a server killed and started again twice: a periodic line says ``2
    reconnects`` with the last disconnect, and so does the final summary, a line for the source."""
    server = RestartingServer()
    server.start()
    gw = Gateway(write_config(tmp_path, server.port), options=("-v",))
    try:
        gw.wait_line("dpgw run: vessel")
        assert wait_for(lambda: server.accepted == 1, 60.0), "the gateway never connected"
        for n in (1, 2):
            server.kill()
            server.start()
            assert wait_for(lambda n=n: server.accepted == n + 1, 60.0), "the gateway did not reconnect"
        assert line_within(gw, "(2 reconnects, last lost ", 60.0), "".join(gw.err)  # (a line every 5 s)
        gw.proc.send_signal(signal.SIGINT)
        assert gw.proc.stdout is not None
        out = gw.proc.stdout.read()
        code = gw.proc.wait(timeout=60)
    finally:
        if gw.proc.poll() is None:  # (a failed assertion: the gateway must not outlive the test)
            gw.proc.kill()
            gw.proc.wait(timeout=60)
        server.kill()
    assert code == 0, "".join(gw.err)
    lost = f"connection to 127.0.0.1:{server.port} lost: closed by the server"
    summary = out.splitlines()
    assert summary[0].startswith("dpgw run: stopped: "), out
    assert re.fullmatch(
        rf"dpgw run: source gps: 2 reconnects, last lost \d+ s ago: {re.escape(lost)}", summary[1]
    ), out
