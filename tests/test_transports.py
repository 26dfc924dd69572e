"""The simulator's transports (pty, UDP, TCP server, serial, file) and clocks, against real clients.

Everything is on this machine: ptys, and sockets on 127.0.0.1 with ephemeral ports. Every read has a
timeout and every loop a bound, so a broken transport fails a test instead of hanging it.
"""

from __future__ import annotations

import os
import select
import socket
import sys
import threading
import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import pytest
import serial
from conftest import free_port, wait_for

from simulator.clock import RealtimeClock, SimEpoch, VirtualClock
from simulator.transports import (
    FileSink,
    MemorySink,
    PtySink,
    SerialSink,
    Sink,
    TcpServerSink,
    TransportError,
    UdpSink,
    open_sink,
)

GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
HDT = b"$HEHDT,274.07,T*03\r\n"
# line endings and bytes a careless tty would translate: bare CR, LF-CR, NUL, XON/XOFF, ^C, 0xFF
AWKWARD = b"$GPZDA,201530.00,04,07,2002,00,00*60\r\n\r\n\n\r\x00\x11\x13\x03\xff\xfe MAVLink\xfd\x09\r\n"


def read_exactly(port: serial.Serial, n: int, timeout: float = 3.0) -> bytes:
    out = b""
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        out += port.read(n - len(out))
    return out


def recv_exactly(sock: socket.socket, n: int, timeout: float = 3.0) -> bytes:
    sock.settimeout(timeout)
    out = b""
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        try:
            chunk = sock.recv(n - len(out))
        except TimeoutError:
            break
        if not chunk:
            break
        out += chunk
    return out


def read_until(sink: Sink, n: int, timeout: float = 3.0) -> bytes:
    out = b""
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        out += sink.read_available()
        time.sleep(0.005)
    return out


@pytest.fixture
def pty_sink() -> Iterator[PtySink]:
    sink = open_sink("pty")
    assert isinstance(sink, PtySink)
    yield sink
    sink.close()


# -------------------------------------------------------------------------------------------------- pty


def test_pty_pyserial_reads_the_exact_bytes(pty_sink: PtySink) -> None:
    assert pty_sink.device.startswith("/dev/")
    assert pty_sink.describe() == pty_sink.device
    with serial.Serial(pty_sink.device, baudrate=4800, timeout=0.5) as port:
        chunks = [GGA, HDT, AWKWARD, GGA]
        for chunk in chunks:
            pty_sink.write(chunk)
        expected = b"".join(chunks)
        assert read_exactly(port, len(expected)) == expected
        port.timeout = 0.1
        assert port.read(100) == b""  # nothing echoed, nothing added
    assert pty_sink.bytes_written == len(expected)
    assert pty_sink.writes_dropped == 0


def test_pty_bytes_from_the_reader_come_back(pty_sink: PtySink) -> None:
    command = b"\xfd\x21\x00\x00\x01\xff\xbe\x4c\x00\x00\r\n\x00"  # MAVLink-like bytes with CR, LF, NUL
    with serial.Serial(pty_sink.device, baudrate=57600, timeout=0.5) as port:
        port.write(command)
        port.flush()
        assert read_until(pty_sink, len(command)) == command
        assert pty_sink.read_available() == b""
    # and the sink's own output is not echoed back to it
    pty_sink.write(GGA)
    time.sleep(0.05)  # an absence has no event to poll for: a bounded look (load can only hide an echo)
    assert pty_sink.read_available() == b""


def test_pty_survives_a_reader_closing_and_reopening(pty_sink: PtySink) -> None:
    with serial.Serial(pty_sink.device, baudrate=4800, timeout=0.5) as port:
        pty_sink.write(GGA)
        assert read_exactly(port, len(GGA)) == GGA
    pty_sink.write(HDT)  # nobody reading: no EIO, no exception
    assert pty_sink.read_available() == b""
    with serial.Serial(pty_sink.device, baudrate=4800, timeout=0.5) as port:
        pty_sink.write(GGA)
        assert read_exactly(port, len(GGA)) == GGA  # pyserial discards what was sent while it was away


def test_pty_symlink_is_made_and_removed(tmp_path: Path) -> None:
    link = tmp_path / "dpgw-gps"
    sink = open_sink(f"pty://{link}")
    assert isinstance(sink, PtySink)
    try:
        assert link.is_symlink()
        assert os.readlink(link) == sink.device
        assert sink.link == str(link)
        assert str(link) in sink.describe() and sink.device in sink.describe()
        with serial.Serial(str(link), baudrate=4800, timeout=0.5) as port:
            sink.write(HDT)
            assert read_exactly(port, len(HDT)) == HDT
    finally:
        sink.close()
    assert not os.path.lexists(link)
    sink.close()  # idempotent


def test_pty_symlink_replaces_a_stale_link_but_not_a_file(tmp_path: Path) -> None:
    link = tmp_path / "gyro"
    link.symlink_to("/dev/pts/does-not-exist")
    with open_sink(f"pty://{link}") as sink:
        assert isinstance(sink, PtySink)
        assert os.readlink(link) == sink.device
    assert not os.path.lexists(link)
    regular = tmp_path / "precious.txt"
    regular.write_text("keep me")
    with pytest.raises(TransportError, match="not a symlink") as info:
        open_sink(f"pty://{regular}")
    assert str(regular) in str(info.value)
    assert regular.read_text() == "keep me"


@pytest.mark.slow  # two simulator processes
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the claim is a Linux abstract socket")
def test_a_second_simulator_on_a_running_benchs_pty_link_is_refused(tmp_path: Path) -> None:
    """`dpgw sim` started again (another terminal) with the link of a simulator that is running: refused,
    naming the link, and the running one's link is left as it was. It was replaced, and removed when the
    second stopped (here on its Zenoh port, taken by the first): the running bench lost its gyro link."""
    import subprocess

    link, zport = tmp_path / "gyro", free_port()
    argv = [sys.executable, "-m", "dpgw", "sim", "--scenario", "hassani", "--nmea", f"gyro1=pty://{link}",
            "--realtime", "--zenoh", "--no-scouting", "--zenoh-listen", f"tcp/127.0.0.1:{zport}"]  # fmt: skip
    first = subprocess.Popen([*argv, "--duration", "600"], stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(link.is_symlink, 60.0), "the first simulator made no link"
        served = os.readlink(link)
        second = subprocess.run([*argv, "--duration", "1"], capture_output=True, text=True, timeout=120)
        assert second.returncode == 2, second.stderr
        assert f"{link} is the link of a pty another program is serving now" in second.stderr, second.stderr
        assert os.readlink(link) == served and os.path.exists(served)  # the bench's link, untouched
        with serial.Serial(str(link), timeout=5) as port:  # ... and it still reads the first simulator
            assert port.read_until(b"\n").startswith(b"$")
    finally:
        first.terminate()
        first.wait(timeout=60)
    assert not os.path.lexists(link)  # removed by its owner on the way out
    with open_sink(f"pty://{link}") as sink:  # the link is free again once its simulator has ended
        assert os.readlink(link) == sink.device


def test_pty_without_reader_never_blocks(pty_sink: PtySink) -> None:
    total = 0
    n_writes = 0
    t0 = time.monotonic()
    while total < 1_000_000:
        pty_sink.write(GGA)
        total += len(GGA)
        n_writes += 1
    elapsed = time.monotonic() - t0
    assert elapsed < 3.0  # ~0.1 s on a laptop; the point is that it returns at all
    assert pty_sink.writes_dropped > 0
    # every byte is accounted for: written to the kernel, dropped, or the tail of one write still pending
    assert pty_sink.bytes_written + pty_sink.bytes_dropped + pty_sink.bytes_pending == total
    assert pty_sink.bytes_pending < len(GGA)
    assert pty_sink.last_error is not None and pty_sink.device in pty_sink.last_error
    t0 = time.monotonic()
    pty_sink.write(b"x" * 1_000_000)  # one huge write
    assert time.monotonic() - t0 < 1.0


def test_pty_write_is_whole_or_dropped_once_a_reader_appears(pty_sink: PtySink) -> None:
    """Fill the pty with no reader, then read: the stream holds whole sentences only."""
    line = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
    fd = os.open(pty_sink.device, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        for _ in range(5000):
            pty_sink.write(line)
        assert pty_sink.writes_dropped > 0
        data = b""
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            pty_sink.poll()  # lets a pending tail follow once there is room
            ready, _, _ = select.select([fd], [], [], 0.05)
            if ready:
                data += os.read(fd, 65536)
            elif pty_sink.bytes_pending == 0:
                break
        assert len(data) == pty_sink.bytes_written
        assert len(data) % len(line) == 0 and data == line * (len(data) // len(line))
    finally:
        os.close(fd)


def test_pty_discards_input_nobody_reads(tmp_path: Path) -> None:
    """A reader that opens late gets current sentences, not a backlog (stale_s); stale_s=none keeps all."""
    for url, expect_old in (("pty?stale_s=0.2", False), ("pty:?stale_s=none", True)):
        with open_sink(url) as sink:
            assert isinstance(sink, PtySink)
            sink.write(b"$OLD*00\r\n")
            time.sleep(0.4)  # what is tested: $OLD ages past stale_s (longer on a loaded machine: still past)
            sink.write(b"$NEW*00\r\n")
            # read without pyserial, which would flush the input on open
            fd = os.open(sink.device, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                data = b""
                deadline = time.monotonic() + 2.0
                while not data.endswith(b"$NEW*00\r\n") and time.monotonic() < deadline:
                    if select.select([fd], [], [], 0.05)[0]:
                        data += os.read(fd, 4096)
            finally:
                os.close(fd)
            if expect_old:
                assert data == b"$OLD*00\r\n$NEW*00\r\n"
                assert sink.stale_flushes == 0
            else:
                assert data == b"$NEW*00\r\n"
                assert sink.stale_flushes == 1
                assert sink.bytes_dropped == len(b"$OLD*00\r\n")


# -------------------------------------------------------------------------------------------------- UDP


@pytest.fixture
def udp_listener() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(3.0)
    yield sock
    sock.close()


def test_udp_one_datagram_per_write_and_replies_come_back(udp_listener: socket.socket) -> None:
    port = udp_listener.getsockname()[1]
    with open_sink(f"udp://127.0.0.1:{port}") as sink:
        assert isinstance(sink, UdpSink)
        assert f"127.0.0.1:{port}" in sink.describe()
        burst = GGA + HDT
        for chunk in (GGA, HDT, burst, AWKWARD):
            sink.write(chunk)
        received = []
        sender = None
        for _ in range(4):
            data, sender = udp_listener.recvfrom(65536)
            received.append(data)
        assert received == [GGA, HDT, burst, AWKWARD]
        assert sink.bytes_written == len(GGA + HDT + burst + AWKWARD)
        assert sender is not None and sender[1] == sink.port

        assert sink.read_available() == b""
        udp_listener.sendto(b"reply-1", sender)
        udp_listener.sendto(b"reply-2", sender)
        deadline = time.monotonic() + 3.0
        items: list[tuple[str, bytes]] = []
        while len(items) < 2 and time.monotonic() < deadline:
            items += sink.read_from_peers()
            time.sleep(0.005)
        assert [chunk for _, chunk in items] == [b"reply-1", b"reply-2"]  # datagram boundaries kept
        assert items[0][0] == f"127.0.0.1:{port}"


def test_udp_bind_option_and_replies_via_read_available(udp_listener: socket.socket) -> None:
    port = udp_listener.getsockname()[1]
    with open_sink(f"udp://127.0.0.1:{port}?bind=127.0.0.1:0") as sink:
        assert isinstance(sink, UdpSink)
        assert sink.local_address[0] == "127.0.0.1"
        sink.write(HDT)
        data, sender = udp_listener.recvfrom(65536)
        assert data == HDT and sender == sink.local_address
        udp_listener.sendto(b"\xfd\x09command", sender)
        assert read_until(sink, 9) == b"\xfd\x09command"


def test_udp_absent_peer_and_oversize_datagram_do_not_raise() -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nobody listens there now: the kernel answers with ICMP port unreachable
    with open_sink(f"udp://127.0.0.1:{port}") as sink:
        for _ in range(20):
            sink.write(GGA)
        sink.read_available()
        sink.write(b"x" * 70_000)  # larger than any UDP datagram
        assert sink.writes_dropped >= 1
        assert sink.last_error is not None


# -------------------------------------------------------------------------------------------------- TCP


def connect(port: int) -> socket.socket:
    return socket.create_connection(("127.0.0.1", port), timeout=3.0)


def wait_clients(sink: TcpServerSink, n: int, timeout: float = 3.0) -> None:
    deadline = time.monotonic() + timeout
    while sink.clients != n and time.monotonic() < deadline:
        sink.poll()
        time.sleep(0.005)
    assert sink.clients == n


def test_tcp_server_sends_to_every_client_and_reads_them() -> None:
    with open_sink("tcp-listen://127.0.0.1:0") as sink:
        assert isinstance(sink, TcpServerSink)
        assert sink.port > 0 and sink.host == "127.0.0.1"
        sink.write(GGA)  # no client: goes nowhere, not a drop
        assert sink.writes_dropped == 0
        a = connect(sink.port)
        wait_clients(sink, 1)
        sink.write(GGA)
        b = connect(sink.port)
        wait_clients(sink, 2)
        sink.write(HDT)
        sink.write(AWKWARD)
        assert recv_exactly(a, len(GGA + HDT + AWKWARD)) == GGA + HDT + AWKWARD
        assert recv_exactly(b, len(HDT + AWKWARD)) == HDT + AWKWARD
        assert sink.clients_accepted == 2

        a.sendall(b"\xfd\x01from-a")
        b.sendall(b"\xfd\x01from-b")
        deadline = time.monotonic() + 3.0
        got: dict[str, bytes] = {}
        while len(got) < 2 and time.monotonic() < deadline:
            for peer, chunk in sink.read_from_peers():
                got[peer] = got.get(peer, b"") + chunk
            time.sleep(0.005)
        assert sorted(got.values()) == [b"\xfd\x01from-a", b"\xfd\x01from-b"]
        assert f"127.0.0.1:{a.getsockname()[1]}" in got

        # a client that goes away does not make writes raise; it is forgotten, the other keeps receiving
        a.close()
        for _ in range(50):
            sink.write(GGA)
            if sink.clients == 1:
                break
            time.sleep(0.01)
        assert sink.clients == 1 and sink.clients_dropped == 1
        sink.write(HDT)
        stream = recv_exactly(b, 10_000, timeout=0.3)
        assert stream.endswith(HDT) and stream.replace(GGA, b"") == HDT
        b.close()


def test_tcp_client_bytes_via_read_available_and_half_close() -> None:
    with TcpServerSink("127.0.0.1", 0) as sink:
        c = connect(sink.port)
        c.sendall(b"COMMAND")
        assert read_until(sink, 7) == b"COMMAND"
        c.shutdown(socket.SHUT_WR)  # done sending, still reading (nc, some loggers)
        assert read_until(sink, 1, timeout=0.2) == b""
        sink.write(GGA)
        assert recv_exactly(c, len(GGA)) == GGA
        assert sink.clients == 1
        c.close()


def test_tcp_slow_client_is_dropped_not_waited_for() -> None:
    with open_sink("tcp-listen://127.0.0.1:0?max_backlog=65536") as sink:
        assert isinstance(sink, TcpServerSink)
        slow = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        slow.connect(("127.0.0.1", sink.port))
        fast = connect(sink.port)
        fast_bytes = 0
        stop = threading.Event()

        def drain() -> None:
            nonlocal fast_bytes
            fast.settimeout(0.1)
            while not stop.is_set():
                try:
                    chunk = fast.recv(65536)
                except TimeoutError:
                    continue
                if not chunk:
                    break
                fast_bytes += len(chunk)

        reader = threading.Thread(target=drain, daemon=True)
        reader.start()
        try:
            wait_clients(sink, 2)
            block = b"y" * 1000
            t0 = time.monotonic()
            writes = 0
            while sink.clients_dropped == 0 and writes < 50_000:
                sink.write(block)
                writes += 1
            assert time.monotonic() - t0 < 5.0
            assert sink.clients_dropped == 1 and sink.clients == 1
            assert sink.writes_dropped >= 1 and "too slow" in (sink.last_error or "")
            for _ in range(10):
                sink.write(block)
            deadline = time.monotonic() + 3.0
            while fast_bytes < (writes + 10) * 1000 and time.monotonic() < deadline:
                sink.poll()
                time.sleep(0.01)
            assert fast_bytes == (writes + 10) * 1000  # the fast client lost nothing
        finally:
            stop.set()
            reader.join(timeout=2.0)
            slow.close()
            fast.close()


def test_tcp_port_in_use_is_a_transport_error() -> None:
    with TcpServerSink("127.0.0.1", 0) as first:
        url = f"tcp-listen://127.0.0.1:{first.port}"
        with pytest.raises(TransportError, match="in use") as info:
            open_sink(url)
        assert url in str(info.value)


def test_udp_bind_port_in_use_is_a_transport_error() -> None:
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.1", 0))
    try:
        url = f"udp://127.0.0.1:10110?bind=127.0.0.1:{holder.getsockname()[1]}"
        with pytest.raises(TransportError, match="in use") as info:
            open_sink(url)
        assert url in str(info.value)
    finally:
        holder.close()


# ---------------------------------------------------------------------------------------- serial, file


def test_serial_sink_on_a_tty() -> None:
    """A real serial port is a tty: a pty's slave stands in for one; the test reads the master."""
    master, slave = os.openpty()
    try:
        device = os.ttyname(slave)
        with open_sink(f"serial://{device}?baud=38400") as sink:
            assert isinstance(sink, SerialSink)
            assert sink.describe() == f"serial://{device}?baud=38400"
            sink.write(AWKWARD)
            data = b""
            deadline = time.monotonic() + 3.0
            while len(data) < len(AWKWARD) and time.monotonic() < deadline:
                if select.select([master], [], [], 0.05)[0]:
                    data += os.read(master, 4096)
            assert data == AWKWARD
            os.write(master, b"back")
            assert read_until(sink, 4) == b"back"
    finally:
        os.close(master)
        os.close(slave)


def test_file_sink_appends_exact_bytes(tmp_path: Path) -> None:
    path = tmp_path / "out.nmea"
    with open_sink(f"file://{path}") as sink:
        assert isinstance(sink, FileSink)
        sink.write(GGA)
        sink.write(AWKWARD)
        assert path.read_bytes() == GGA + AWKWARD  # on disk at once, no close needed
    with open_sink(str(path)) as sink:  # a plain path appends
        sink.write(HDT)
        assert sink.describe() == f"file://{path}"
    assert path.read_bytes() == GGA + AWKWARD + HDT


def test_memory_sink_and_closed_sink() -> None:
    sink = MemorySink()
    sink.write(GGA)
    sink.feed(b"cmd")
    assert bytes(sink.data) == GGA and sink.read_available() == b"cmd" and sink.read_available() == b""
    sink.close()
    assert sink.closed
    with pytest.raises(ValueError, match="closed"):
        sink.write(GGA)


# ------------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    "url",
    [
        "udp://127.0.0.1",
        "udp://:10110",
        "udp://127.0.0.1:0",
        "udp://127.0.0.1:99999",
        "udp://127.0.0.1:10110?bind=nonsense",
        "udp:127.0.0.1:10110",
        "tcp-listen://127.0.0.1:abc",
        "tcp-listen://127.0.0.1:0?bogus=1",
        "tcp-listen://127.0.0.1:0/path",
        "tcp-listen://192.0.2.1:0",
        "tcp://127.0.0.1:10110",  # the old server spelling: now a client, which the simulator has not
        "ftp://example.org/file",
        "pty://tmp/dpgw-gps",
        "pty?stale_s=-1",
        "serial:///dev/dpgw-no-such-port",
        "serial:///dev/null",
        "serial:///dev/ptmx?baud=12345",
        "file:///dpgw-no-such-dir/out.nmea",
        "/dpgw-no-such-dir/out.nmea",
        "file:///",
    ],
)
def test_bad_urls_raise_transport_error_naming_the_url(url: str) -> None:
    with pytest.raises(TransportError) as info:
        open_sink(url)
    assert url in str(info.value)
    assert info.value.url == url


def test_unwritable_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(TransportError, match="directory"):
        open_sink(str(tmp_path))
    if os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(TransportError, match="Permission denied"):
            open_sink(f"file://{locked}/out.nmea")


# ------------------------------------------------------------------------------------------------ clocks


def test_virtual_clock_does_not_sleep() -> None:
    clock = VirtualClock()
    t0 = time.monotonic()
    for k in range(1, 10_001):
        assert clock.sleep_until(k * 100.0) == 0.0
    assert time.monotonic() - t0 < 0.5
    assert clock.now() == 1_000_000.0
    clock.sleep_until(5.0)  # never goes back
    assert clock.now() == 1_000_000.0


@pytest.mark.parametrize("speed", [1.0, 4.0])
def test_realtime_clock_paces_against_the_wall(speed: float) -> None:
    """Against the real clock: never early, on time as a rule, sim time = speed × wall time. A loaded
    machine may wake any one step late by tens of ms, so single steps are not bounded here; the exact
    schedule (no drift, lag, resync) is tested on a fake clock below."""
    clock = RealtimeClock(speed=speed)
    dt = 0.05 * speed  # 10 steps, 0.5 s of wall time at any speed
    before = time.monotonic()
    clock.anchor()
    start = time.monotonic()  # the anchor's wall instant is between `before` and `start`
    late = []
    for k in range(1, 11):
        lag = clock.sleep_until(k * dt)
        woke = time.monotonic()
        assert woke - (before + k * 0.05) > -0.002  # never early (beyond rounding)
        late.append(woke - (start + k * 0.05))
        assert lag <= late[-1] + (start - before) + 1e-6  # the lag the clock reports is no more than real
    assert sorted(late)[len(late) // 2] < 0.02, late  # the median step is on time
    w0 = time.monotonic()
    now = clock.now()
    w1 = time.monotonic()
    assert (w0 - start) * speed - 1e-9 <= now <= (w1 - before) * speed + 1e-9  # speed × wall since the anchor
    assert now >= 10 * dt


class FakeTime:
    """A monotonic clock and sleep that oversleeps, for exact tests of the schedule."""

    def __init__(self, oversleep: float = 0.0) -> None:
        self.t = 1000.0
        self.oversleep = oversleep
        self.sleeps: list[float] = []

    def monotonic(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.sleeps.append(s)
        self.t += s + self.oversleep


def test_realtime_clock_does_not_accumulate_drift() -> None:
    fake = FakeTime(oversleep=0.003)  # every sleep 3 ms long
    clock = RealtimeClock(speed=2.0, monotonic=fake.monotonic, sleep=fake.sleep)
    clock.anchor()
    for k in range(1, 10_001):
        clock.sleep_until(k * 0.1)
    # 1000 sim s at speed 2 = 500 wall s: off by one oversleep, not 10 000 of them
    assert fake.t - 1000.0 == pytest.approx(500.0, abs=0.004)
    assert clock.late_count == 0


def test_realtime_clock_reports_lag_and_can_resync(caplog: pytest.LogCaptureFixture) -> None:
    fake = FakeTime()
    clock = RealtimeClock(monotonic=fake.monotonic, sleep=fake.sleep, warn_lag_s=0.5)
    clock.sleep_until(0.0)  # anchors here
    fake.t += 2.0  # a step that took 2 s
    with caplog.at_level("WARNING", logger="simulator.clock"):
        lag = clock.sleep_until(1.0)
    assert lag == pytest.approx(1.0)
    assert clock.lag_s == pytest.approx(1.0) and clock.max_lag_s == pytest.approx(1.0)
    assert clock.late_count == 1
    assert "behind real time" in caplog.text
    assert clock.sleep_until(2.0) == 0.0  # caught up: the next deadline is still in the future
    assert fake.t == pytest.approx(1002.0)

    resync = RealtimeClock(monotonic=fake.monotonic, sleep=fake.sleep, resync_lag_s=5.0)
    resync.sleep_until(0.0)
    fake.t += 60.0  # suspended for a minute
    assert resync.sleep_until(1.0) == pytest.approx(59.0)
    assert resync.resync_count == 1
    before = fake.t
    assert resync.sleep_until(2.0) == 0.0  # sim time continues from the late step, no burst
    assert fake.t - before == pytest.approx(1.0)


def test_realtime_clock_rejects_bad_speed() -> None:
    for speed in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="speed"):
            RealtimeClock(speed=speed)


def test_sim_epoch_maps_sim_time_to_utc() -> None:
    epoch = SimEpoch(datetime(2024, 6, 1, 12, 0, 0, tzinfo=UTC))
    assert epoch.utc(0.0) == datetime(2024, 6, 1, 12, 0, 0, tzinfo=UTC)
    assert epoch.utc(3661.25) == datetime(2024, 6, 1, 13, 1, 1, 250_000, tzinfo=UTC)
    assert epoch.stamp_ns(0.0) == 1_717_243_200_000_000_000
    assert epoch.stamp_ns(1.5) == 1_717_243_201_500_000_000
    assert epoch.sim_time(datetime(2024, 6, 1, 12, 0, 10, tzinfo=UTC)) == 10.0
    # another zone is converted; the day rolls over
    oslo = SimEpoch(datetime(2024, 6, 1, 23, 59, 59, tzinfo=timezone(timedelta(hours=2))))
    assert oslo.start_utc == datetime(2024, 6, 1, 21, 59, 59, tzinfo=UTC)
    assert oslo.utc(7201.0).date() == datetime(2024, 6, 2, tzinfo=UTC).date()
    with pytest.raises(ValueError, match="timezone-aware"):
        SimEpoch(datetime(2024, 6, 1))
    now = SimEpoch.from_wall_clock()
    assert abs((now.utc(0.0) - datetime.now(UTC)).total_seconds()) < 2.0
