"""The gateway's sources (serial/pty, UDP, TCP client and server, file) against the simulator's sinks.

Everything runs on this machine: ptys, and sockets on 127.0.0.1 with ephemeral ports. Every wait has a
deadline, so a broken source fails a test instead of hanging it; no test leaves a reader thread behind.
"""

from __future__ import annotations

import itertools
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.sources import (
    BACKOFF_FIRST_S,
    Chunk,
    FileSource,
    SerialSource,
    Source,
    SourceError,
    TcpClientSource,
    TcpListenSource,
    UdpSource,
    open_source,
)
from gateway.sources import nmea_time_of_day as tod
from simulator.transports import PtySink, TcpServerSink, UdpSink

GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
S = TypeVar("S", bound=Source)

HDT = b"$HEHDT,274.07,T*03\r\n"
# bytes a careless tty would translate or swallow: bare CR, LF-CR, NUL, XON/XOFF, ^C, 0xFF, a MAVLink marker
AWKWARD = b"$GPZDA,201530.00,04,07,2002,00,00*60\r\n\r\n\n\r\x00\x11\x13\x03\xff\xfe MAVLink\xfd\x09\r\n"


class Collector:
    """A ``deliver`` callback that keeps chunks; `wait` polls a condition with a deadline."""

    def __init__(self) -> None:
        self.chunks: list[Chunk] = []
        self._lock = threading.Lock()

    def __call__(self, chunk: Chunk) -> None:
        with self._lock:
            self.chunks.append(chunk)

    @property
    def data(self) -> bytes:
        with self._lock:
            return b"".join(c.data for c in self.chunks)

    def wait(
        self, condition: Callable[[], bool], timeout: float = 5.0, poll: Callable[[], object] | None = None
    ) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if poll is not None:
                poll()
            if condition():
                return True
            time.sleep(0.01)
        return condition()

    def wait_bytes(self, n: int, timeout: float = 5.0, poll: Callable[[], object] | None = None) -> bytes:
        self.wait(lambda: len(self.data) >= n, timeout, poll)
        return self.data


def wait_until(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


def read_until(sink: UdpSink | TcpServerSink | PtySink, wanted: bytes, timeout: float = 3.0) -> bytes:
    received = b""
    deadline = time.monotonic() + timeout
    while wanted not in received and time.monotonic() < deadline:
        received += sink.read_available()
        time.sleep(0.01)
    return received


def source_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("dpgw-source-") and t.is_alive()]


@pytest.fixture
def opened() -> Iterator[list[Source]]:
    """Sources to stop at the end of the test; then no reader thread may be left."""
    before = set(source_threads())  # threads of other tests' sources are not ours to judge
    sources: list[Source] = []
    yield sources
    for src in sources:
        src.stop()
    assert wait_until(lambda: not set(source_threads()) - before, 2.0), source_threads()


def start(
    opened: list[Source], name: str, url: str, cls: type[S], *, timeout_s: float = 2.0
) -> tuple[S, Collector]:
    """Open ``url`` (it must give a ``cls``), start it with a `Collector`; stopped at the end of the test."""
    src = open_source(name, url, timeout_s=timeout_s)
    assert isinstance(src, cls), src
    got = Collector()
    opened.append(src)
    src.start(got)
    return src, got


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# -------------------------------------------------------------------------------------------- serial


def test_serial_pty_bytes_arrive_in_order_unchanged(opened: list[Source]) -> None:
    with PtySink() as sink:
        before_ns = time.time_ns()
        src, got = start(opened, "gps", f"serial://{sink.device}?baud=115200", SerialSource)
        assert isinstance(src, SerialSource) and src.baud == 115200
        assert src.stats.connected
        sent = b""
        for i in range(50):
            piece = (GGA, HDT, AWKWARD)[i % 3]
            sink.write(piece)
            sent += piece
            if i % 10 == 0:
                time.sleep(0.01)  # pacing: the reader sees the stream in several reads, not one
        assert got.wait_bytes(len(sent)) == sent
        chunks = list(got.chunks)
        assert all(c.source == "gps" and c.peer == "" for c in chunks)
        assert all(before_ns <= c.rx_ns <= time.time_ns() for c in chunks)
        monos = [c.rx_mono_ns for c in chunks]
        assert monos == sorted(monos)
        assert src.stats.bytes_received == len(sent) and src.stats.chunks == len(chunks)


def test_serial_pty_link_and_write_back(opened: list[Source], tmp_path: Path) -> None:
    link = tmp_path / "dpgw-gps"
    with PtySink(str(link)) as sink:
        src, got = start(
            opened, "gps", f"pty://{link}?baud=4800&bytesize=8&parity=N&stopbits=1", SerialSource
        )
        sink.write(GGA)
        assert got.wait_bytes(len(GGA)) == GGA
        assert src.write(b"\xfd\x09command\r\n")
        assert read_until(sink, b"command\r\n") == b"\xfd\x09command\r\n"
        assert src.stats.bytes_sent == 11


def test_serial_missing_device_names_source_url_and_device(opened: list[Source]) -> None:
    src = open_source("gyro_nope", "serial:///dev/ttyUSB_nope?baud=4800")  # parsing does not open
    with pytest.raises(SourceError) as info:
        src.start(Collector())
    text = str(info.value)
    assert "'gyro_nope'" in text and "serial:///dev/ttyUSB_nope?baud=4800" in text
    assert "/dev/ttyUSB_nope does not exist" in text and "check the cable/udev name" in text
    assert not src.running and "dpgw-source-gyro_nope" not in {t.name for t in source_threads()}
    src.stop()  # harmless after a failed start


def test_a_file_named_as_a_serial_port_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "log.nmea"
    path.write_bytes(GGA)
    with pytest.raises(SourceError, match=r"log.nmea is not a serial device .* — for a file write file://"):
        open_source("gps", str(path)).start(Collector())  # a bare path is pymavlink's serial device


def test_a_folder_named_as_a_serial_port_is_refused_without_a_file_hint(tmp_path: Path) -> None:
    """Before: '... is not a serial device — for a file write file:///tmp/...', a folder no file:// reads."""
    with pytest.raises(SourceError) as info:
        open_source("gps", f"serial://{tmp_path}?baud=4800").start(Collector())
    assert info.value.problem == f"{tmp_path} is a folder, not a serial device"
    assert "file://" not in str(info.value) and "ls /dev/serial/by-id/" in info.value.fix


def test_a_device_that_is_not_a_terminal_is_refused_as_not_a_serial_port() -> None:
    """/dev/null (a character device, no tty). Before: 'cannot open serial port /dev/null: Could not
    configure port: (25, 'Inappropriate ioctl for device') — check the device and settings'."""
    with pytest.raises(SourceError) as info:
        open_source("gps", "serial:///dev/null?baud=4800").start(Collector())
    assert info.value.problem == "/dev/null is not a serial port (a device, but not a terminal)"
    assert "ls /dev/serial/by-id/" in info.value.fix


def test_serial_port_in_use_is_refused(opened: list[Source]) -> None:
    with PtySink() as sink:
        start(opened, "gps", f"serial://{sink.device}", SerialSource)
        second = open_source("gps2", f"serial://{sink.device}")
        with pytest.raises(SourceError, match=r"source 'gps2': serial port .* is in use"):
            second.start(Collector())


def _read_then_unplug(
    opened: list[Source], name: str, link: Path, first: bytes
) -> tuple[SerialSource, Collector]:
    """A serial source on a pty behind ``link`` that has read ``first``, then the pty gone (the link too)
    and the source seen disconnected."""
    sink = PtySink(str(link))
    try:
        src, got = start(opened, name, f"pty://{link}", SerialSource)
        sink.write(first)
        assert got.wait_bytes(len(first)) == first
    finally:
        sink.close()
    assert wait_until(lambda: not src.stats.connected, 3.0)
    return src, got


def test_serial_unplugged_while_running_reopens(opened: list[Source], tmp_path: Path) -> None:
    """The pty vanishing is a USB adapter unplugged: counted, marked, reopened with back-off, never raised."""
    link = tmp_path / "usb"
    src, got = _read_then_unplug(opened, "gps", link, GGA)
    assert src.stats.errors["disconnected"] == 1 and src.running
    with PtySink(str(link)) as sink2:  # plugged in again (a new pty behind the same name)
        assert wait_until(lambda: src.stats.connected, 5.0)
        assert src.stats.reconnects == 1
        sink2.write(HDT)
        assert got.wait_bytes(len(GGA + HDT)) == GGA + HDT


@pytest.mark.slow
def test_a_pty_made_again_after_a_long_absence_is_read_at_once(opened: list[Source], tmp_path: Path) -> None:
    """A simulator restarted under the gateway makes its pty again after seconds: read within 1 s of it.

    With the back-off alone (0.5, 1, 2, 4, 8 s between opens) a pty away for 4 s was opened again only at
    the next attempt, 7.5 s after it went: 3.5 s more with no heading (14 s of sea at 4x). A port that
    is not there is looked for, cheaply, every `ABSENT_POLL_S` instead.
    """
    link = tmp_path / "gyro"
    src, got = _read_then_unplug(opened, "gyro1", link, HDT)  # the simulator stopped: its pty is gone
    # the scenario's input, not a wait for an event: the simulator takes seconds to start again, and in
    # that time the back-off would have grown past three failed opens (0.5 + 1 + 2 s)
    time.sleep(4.0)
    assert not src.stats.connected
    with PtySink(str(link)) as sink2:  # the restarted simulator's pty, behind the same link
        appeared = time.monotonic()
        assert wait_until(lambda: src.stats.connected, 5.0)
        reopened_after = time.monotonic() - appeared
        assert reopened_after < 1.0, f"read {reopened_after:.2f} s after the pty appeared"
        sink2.write(HDT)
        assert got.wait_bytes(2 * len(HDT)) == HDT + HDT
    assert src.stats.reconnects == 1


# ----------------------------------------------------------------------------------------------- UDP


def test_udp_listen_receives_datagrams_and_replies_to_last_peer(opened: list[Source]) -> None:
    src, got = start(opened, "dgps", "udp://127.0.0.1:0", UdpSource)
    assert isinstance(src, UdpSource) and src.port > 0 and src.stats.connected
    assert not src.write(b"nobody yet")  # no peer and no target: cannot answer
    with UdpSink("127.0.0.1", src.port) as sink:
        for sentence in (GGA, HDT, GGA):
            sink.write(sentence)
        got.wait(lambda: len(got.chunks) >= 3)
        assert [c.data for c in got.chunks] == [GGA, HDT, GGA]  # one chunk per datagram
        assert got.chunks[0].peer == f"127.0.0.1:{sink.port}"
        assert src.write(b"reply")
        assert read_until(sink, b"reply") == b"reply"


def test_udp_write_to_a_target_and_to_a_named_peer(opened: list[Source]) -> None:
    with UdpSink("127.0.0.1", 9, bind=("127.0.0.1", 0)) as target:
        src, got = start(opened, "mav", f"udp://127.0.0.1:0?target=127.0.0.1:{target.port}", UdpSource)
        assert src.write(b"to target")  # a configured target: writable before anyone spoke
        assert read_until(target, b"to target") == b"to target"
        with UdpSink("127.0.0.1", src.port) as other:  # a second talker on the same port
            other.write(b"x")
            assert got.wait(lambda: bool(got.chunks))
            assert src.write(b"to peer", peer=got.chunks[0].peer)
            assert not src.write(b"?", peer="127.0.0.1:1")  # a peer never heard of
            assert read_until(other, b"to peer") == b"to peer"
            assert src.write(b"again")  # without peer=: the target, not the last peer
            assert read_until(target, b"again") == b"again"


def test_a_datagram_is_stamped_when_the_kernel_took_it_in_not_when_the_reader_got_to_it(
    opened: list[Source],
) -> None:
    """A reading thread kept from reading (here by a slow ``deliver``; on a busy machine by the scheduler)
    stamps the datagram waiting in the kernel with its arrival, not with the end of the wait: the receive
    instant the observer's delay compensation and the simulation clock rely on. Linux (SO_TIMESTAMPNS)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("kernel receive stamps are read on Linux")
    held, release = threading.Event(), threading.Event()
    chunks: list[Chunk] = []

    def deliver(chunk: Chunk) -> None:
        chunks.append(chunk)
        if len(chunks) == 1:
            held.set()
            release.wait(10.0)  # the reader is kept here while the second datagram arrives

    src = open_source("dgps", "udp://127.0.0.1:0")
    assert isinstance(src, UdpSource)
    opened.append(src)
    src.start(deliver)
    with UdpSink("127.0.0.1", src.port) as sink:
        sink.write(GGA)
        assert held.wait(5.0)
        sent_mono, sent_wall = time.monotonic_ns(), time.time_ns()
        sink.write(HDT)
        while time.monotonic_ns() - sent_mono < 200_000_000:  # the reader kept from it for 0.2 s
            time.sleep(0.01)
        released_mono = time.monotonic_ns()
        release.set()
        assert wait_until(lambda: len(chunks) >= 2)
    late = chunks[1]
    assert late.data == HDT
    # stamped at its arrival (within 50 ms of the send), not at the release 0.2 s later
    assert sent_mono - 1_000_000 <= late.rx_mono_ns < sent_mono + 50_000_000 < released_mono
    assert abs(late.rx_ns - sent_wall) < 50_000_000


def test_udp_port_in_use_is_refused(opened: list[Source]) -> None:
    first, _ = start(opened, "a", "udp://127.0.0.1:0", UdpSource)
    second = open_source("b", f"udp://127.0.0.1:{first.port}")
    with pytest.raises(
        SourceError, match=r"source 'b': cannot listen on 127.0.0.1:\d+: Address already in use"
    ):
        second.start(Collector())


def test_udpout_announces_itself_with_a_heartbeat_and_reads_replies(opened: list[Source]) -> None:
    from wire.codecs.mavlink import parse_frames

    far = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    far.bind(("127.0.0.1", 0))
    far.settimeout(3.0)
    try:
        src, got = start(opened, "thrusters", f"udpout:127.0.0.1:{far.getsockname()[1]}", UdpSource)
        assert isinstance(src, UdpSource) and src.target == ("127.0.0.1", far.getsockname()[1])
        hello, addr = far.recvfrom(1024)
        (msg,) = parse_frames(hello)
        assert msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 191
        far.sendto(b"\xfdfeedback", addr)
        assert got.wait_bytes(9) == b"\xfdfeedback"
        assert src.write(b"command")
        assert far.recvfrom(1024)[0] == b"command"
    finally:
        far.close()


def test_udp_multicast_group(opened: list[Source]) -> None:
    group = "239.255.77.13"
    try:
        src, got = start(opened, "mc", f"udp://{group}:0?iface=127.0.0.1", UdpSource)
    except SourceError as exc:  # pragma: no cover — a machine without multicast on loopback
        pytest.skip(str(exc))
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sender.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
        sender.sendto(GGA, (group, src.port))
        if not got.wait(lambda: bool(got.chunks), 2.0):  # pragma: no cover
            pytest.skip("multicast is not routed on loopback here")
        assert got.chunks[0].data == GGA
    finally:
        sender.close()


# ----------------------------------------------------------------------------------------------- TCP


def test_tcp_client_receives_and_reconnects_after_the_server_restarts(opened: list[Source]) -> None:
    server = TcpServerSink("127.0.0.1", 0)
    port = server.port
    try:
        src, got = start(opened, "dgps", f"tcp://127.0.0.1:{port}", TcpClientSource)
        assert isinstance(src, TcpClientSource)
        assert got.wait(lambda: b"$GPGGA" in got.data, 5.0, poll=lambda: server.write(GGA))
        assert src.stats.connected and src.stats.reconnects == 0
        assert got.chunks[0].peer == f"127.0.0.1:{port}"
        assert src.write(b"cmd")
        assert wait_until(lambda: b"cmd" in server.read_available(), 3.0)
    finally:
        server.close()
    assert wait_until(lambda: not src.stats.connected, 3.0)
    assert src.stats.errors["disconnected"] == 1
    # the end of the stream from the server is handed over: an empty chunk with its peer
    assert got.wait(lambda: got.chunks[-1].data == b"" and got.chunks[-1].peer == f"127.0.0.1:{port}", 3.0)
    assert not src.write(b"lost")  # not connected: cannot write now
    with TcpServerSink("127.0.0.1", port) as server2:  # the same port, a new server
        assert got.wait(lambda: HDT in got.data, 8.0, poll=lambda: server2.write(HDT))
        assert src.stats.reconnects >= 1 and src.stats.connected


def test_tcp_client_backs_off_from_a_server_that_accepts_and_closes_at_once(opened: list[Source]) -> None:
    """A server that accepts and closes at once (a port forward to nothing, a device rebooting in a loop):
    each connect reset the back-off, so the gateway reconnected every 0.5 s for as long as it lasted, two
    journal lines each time. A connection shorter than `STABLE_CONNECTION_S` now counts as a failed
    attempt: the waits between connects grow (0.5, 1, 2 s; a busy machine makes them longer, never
    shorter)."""
    from gateway.sources.tcp import STABLE_CONNECTION_S

    assert STABLE_CONNECTION_S >= 2.0
    server = socket.create_server(("127.0.0.1", 0))
    accepted: list[float] = []

    def accept_and_close() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:  # (closed: the test is over)
                return
            accepted.append(time.monotonic())
            conn.close()

    threading.Thread(target=accept_and_close, daemon=True).start()
    try:
        start(opened, "flap", f"tcp://127.0.0.1:{server.getsockname()[1]}", TcpClientSource)
        assert wait_until(lambda: len(accepted) >= 4, 30.0), accepted
    finally:
        server.close()
    waits = [b - a for a, b in itertools.pairwise(accepted[:4])]
    assert waits[0] >= BACKOFF_FIRST_S * 0.9 and waits[1] >= 1.8 * BACKOFF_FIRST_S, waits
    assert waits[2] >= 3.6 * BACKOFF_FIRST_S, waits


@pytest.mark.slow
def test_tcp_client_without_a_server_keeps_retrying_with_back_off(opened: list[Source]) -> None:
    port = free_tcp_port()
    t0 = time.monotonic()
    src, got = start(
        opened, "dgps", f"tcp://127.0.0.1:{port}", TcpClientSource
    )  # does not raise: the server may come later
    # attempts at 0, 0.5, 1.5, 3.5 s (waits of 0.5, 1, 2 … s): the n-th never before the sum of the waits
    # (a loaded machine may make it later, never sooner), and the source keeps trying
    too_soon: list[tuple[int, float]] = []

    def third_attempt() -> bool:
        n, elapsed = src.stats.errors["connect failed"], time.monotonic() - t0
        if n and elapsed < BACKOFF_FIRST_S * (2 ** (n - 1) - 1):
            too_soon.append((n, elapsed))
        return n >= 3

    assert wait_until(third_attempt, 20.0), src.stats.errors
    assert not too_soon, f"attempts came without back-off (attempt, seconds): {too_soon}"
    assert not src.stats.connected and src.running and not got.chunks
    assert "Connection refused" in (src.stats.last_error or "")
    with TcpServerSink("127.0.0.1", port) as server:  # the link comes up later
        assert got.wait(lambda: GGA in got.data, 8.0, poll=lambda: server.write(GGA))
    assert time.monotonic() - t0 < 12


def test_tcp_listen_takes_several_clients(opened: list[Source]) -> None:
    src, got = start(opened, "mav", "tcp-listen://127.0.0.1:0", TcpListenSource)
    assert isinstance(src, TcpListenSource) and src.port > 0 and not src.stats.connected
    a = socket.create_connection(("127.0.0.1", src.port), timeout=3)
    b = socket.create_connection(("127.0.0.1", src.port), timeout=3)
    try:
        assert wait_until(lambda: len(src.clients) == 2, 3.0) and src.stats.connected
        a.sendall(b"from a")
        b.sendall(b"from b")
        got.wait(lambda: len(got.data) >= 12)
        peers = {c.data: c.peer for c in got.chunks}
        assert peers[b"from a"] == f"127.0.0.1:{a.getsockname()[1]}"
        assert peers[b"from b"] == f"127.0.0.1:{b.getsockname()[1]}"
        assert src.write(b"all")
        assert a.recv(16) == b"all" and b.recv(16) == b"all"
        assert src.write(b"only b", peer=peers[b"from b"])
        assert b.recv(16) == b"only b"
        a.close()
        assert wait_until(lambda: len(src.clients) == 1, 3.0)
        # a's end of stream: an empty chunk with its peer, after its bytes, not counted as data
        a_peer = peers[b"from a"]
        assert got.wait(lambda: any(c.data == b"" for c in got.chunks), 3.0)
        ends = [k for k, c in enumerate(got.chunks) if c.data == b""]
        assert [got.chunks[k].peer for k in ends] == [a_peer]
        assert ends[0] > next(k for k, c in enumerate(got.chunks) if c.peer == a_peer and c.data)
        assert src.stats.chunks == len(got.chunks) - 1
    finally:
        a.close()
        b.close()


def test_tcp_listen_port_in_use_is_refused(opened: list[Source]) -> None:
    first, _ = start(opened, "a", "tcpin:127.0.0.1:0", TcpListenSource)
    second = open_source("b", f"tcp-listen://127.0.0.1:{first.port}")
    with pytest.raises(SourceError, match=r"source 'b': cannot listen on .*Address already in use"):
        second.start(Collector())


# ---------------------------------------------------------------------------------------------- file


def test_file_fast_delivers_the_whole_file_in_whole_lines(opened: list[Source], tmp_path: Path) -> None:
    path = tmp_path / "log.nmea"
    content = b"".join((GGA, HDT)[i % 2] for i in range(5000)) + b"$GPHDT,1.0,T"  # last line unterminated
    path.write_bytes(content)
    src, got = start(opened, "log", f"file://{path}?rate=fast", FileSource)
    assert isinstance(src, FileSource)
    assert wait_until(lambda: src.finished, 5.0)
    assert got.data == content
    assert all(c.data.endswith(b"\n") for c in got.chunks[:-1])
    assert not src.stats.connected and not src.write(b"x")
    assert wait_until(lambda: not src.running, 2.0)


def _gga(hhmmss: str) -> bytes:
    return f"$GPGGA,{hhmmss},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*00\r\n".encode()


def test_file_realtime_is_paced_by_the_sentence_times(opened: list[Source], tmp_path: Path) -> None:
    path = tmp_path / "log.nmea"
    # 1.5 s of sentences across midnight; HDT has no time and follows the GGA before it at once
    lines = [_gga("235959.00"), HDT, _gga("235959.50"), HDT, _gga("000000.00"), _gga("000000.50")]
    path.write_bytes(b"".join(lines))
    src, got = start(opened, "log", f"file://{path}", FileSource)  # realtime is the default
    assert wait_until(lambda: src.finished, 6.0)
    chunks = got.chunks
    assert [c.data for c in chunks] == lines
    t = [(c.rx_mono_ns - chunks[0].rx_mono_ns) / 1e9 for c in chunks]
    assert 1.35 <= t[-1] <= 3.0, t
    assert 0.35 <= t[2] <= 1.5 and t[1] < 0.3, t


def test_file_rate_in_lines_per_second(opened: list[Source], tmp_path: Path) -> None:
    path = tmp_path / "log.nmea"
    path.write_bytes(HDT * 10)
    src, got = start(opened, "log", f"file://{path}?rate=20", FileSource)
    assert wait_until(lambda: src.finished, 5.0)
    span = (got.chunks[-1].rx_mono_ns - got.chunks[0].rx_mono_ns) / 1e9
    assert len(got.chunks) == 10 and 0.4 <= span <= 1.5, span


def test_file_missing_is_refused(tmp_path: Path) -> None:
    src = open_source("log", f"file://{tmp_path}/nope.nmea")
    with pytest.raises(SourceError, match=r"source 'log': file .*nope.nmea does not exist"):
        src.start(Collector())


def test_nmea_time_of_day() -> None:
    assert tod(_gga("123519.25")) == pytest.approx(12 * 3600 + 35 * 60 + 19.25)
    assert tod(b"$GPGLL,4916.45,N,12311.12,W,225444,A*1D\r\n") == 22 * 3600 + 54 * 60 + 44
    assert tod(b"$GPZDA,201530.00,04,07,2002,00,00*60\r\n") == 20 * 3600 + 15 * 60 + 30
    assert tod(HDT) is None and tod(b"$GPGGA,,,,*00") is None and tod(b"garbage") is None


# ----------------------------------------------------------------------------------------- staleness


def test_stale_after_the_sender_goes_quiet(opened: list[Source]) -> None:
    src, got = start(opened, "gyro", "udp://127.0.0.1:0", UdpSource)
    assert src.is_stale(0.3) and src.age_s() == float("inf")  # nothing yet: stale
    with UdpSink("127.0.0.1", src.port) as sink:
        sink.write(HDT)
        assert got.wait(lambda: bool(got.chunks))
        assert not src.is_stale(0.3) and src.age_s() < 0.3
        assert wait_until(lambda: src.is_stale(0.3), 2.0)
        assert src.age_s() > 0.3
        last = src.stats.last_rx_mono_ns
        assert last is not None and src.age_s(last + 250_000_000) == pytest.approx(0.25)
        sink.write(HDT)
        assert got.wait(lambda: len(got.chunks) >= 2)
        assert not src.is_stale(0.3)


def test_an_exception_in_deliver_is_counted_and_reading_goes_on(opened: list[Source]) -> None:
    seen: list[bytes] = []

    def deliver(chunk: Chunk) -> None:
        seen.append(chunk.data)
        if chunk.data == b"bad":
            raise ValueError("consumer bug")

    src = open_source("u", "udp://127.0.0.1:0")
    assert isinstance(src, UdpSource)
    opened.append(src)
    src.start(deliver)
    with UdpSink("127.0.0.1", src.port) as sink:
        for d in (b"bad", b"good", b"bad", b"good"):
            sink.write(d)
        assert wait_until(lambda: len(seen) == 4)
    assert src.stats.errors["deliver raised"] == 2 and src.running


# ------------------------------------------------------------------------------------------ the URLs


@pytest.mark.parametrize(
    ("url", "cls", "attrs"),
    [
        ("udpin:0.0.0.0:14550", UdpSource, {"host": "0.0.0.0", "port": 14550, "target": None}),
        ("udp:127.0.0.1:14550", UdpSource, {"host": "127.0.0.1", "port": 14550, "target": None}),
        ("udpout:10.0.0.2:14550", UdpSource, {"host": "", "port": 0, "target": ("10.0.0.2", 14550)}),
        ("tcp:127.0.0.1:5760", TcpClientSource, {"host": "127.0.0.1", "port": 5760}),
        ("tcpin:0.0.0.0:5760", TcpListenSource, {"host": "0.0.0.0", "port": 5760}),
        ("/dev/ttyUSB0,57600", SerialSource, {"device": "/dev/ttyUSB0", "baud": 57600}),
        ("/dev/ttyACM0", SerialSource, {"device": "/dev/ttyACM0", "baud": 115200}),
        ("serial:/dev/ttyUSB0:57600", SerialSource, {"device": "/dev/ttyUSB0", "baud": 57600}),
        ("serial:///dev/ttyUSB0", SerialSource, {"device": "/dev/ttyUSB0", "baud": 4800}),
        (
            "serial:///dev/ttyS1?baud=38400&bytesize=7&parity=E&stopbits=2",
            SerialSource,
            {"baud": 38400, "bytesize": 7, "parity": "E", "stopbits": 2},
        ),
        ("pty:///tmp/dpgw-gps", SerialSource, {"device": "/tmp/dpgw-gps"}),
        ("udp://0.0.0.0:10110", UdpSource, {"host": "0.0.0.0", "port": 10110, "target": None}),
        ("udp://[::1]:10110", UdpSource, {"host": "::1", "port": 10110}),
        ("udp://:0?target=127.0.0.1:9", UdpSource, {"port": 0, "target": ("127.0.0.1", 9)}),
        ("udp://239.1.2.3:10110?iface=eth0", UdpSource, {"multicast": True, "iface": "eth0"}),
        ("tcp://gps.local:10110", TcpClientSource, {"host": "gps.local", "port": 10110}),
        ("tcp-listen://0.0.0.0:0", TcpListenSource, {"port": 0}),
        ("file:///data/run1.nmea?rate=fast", FileSource, {"path": "/data/run1.nmea", "rate": "fast"}),
        ("file:///data/run1.nmea", FileSource, {"rate": "realtime"}),
        ("file:///data/run1.nmea?rate=12.5", FileSource, {"rate": 12.5}),
    ],
)
def test_urls_parse_to_the_right_kind(url: str, cls: type[Source], attrs: dict[str, object]) -> None:
    src = open_source("s", url, hello=b"hi")  # parse only: nothing is opened
    assert type(src) is cls and src.url == url and src.name == "s"
    assert (
        src.kind
        == {
            UdpSource: "udp",
            TcpClientSource: "tcp",
            TcpListenSource: "tcp-listen",
            SerialSource: "serial",
            FileSource: "file",
        }[cls]
    )
    for key, value in attrs.items():
        assert getattr(src, key) == value, key
    assert not src.running and not src.stats.connected


@pytest.mark.parametrize(
    "url",
    [
        "",
        "bogus://x",
        "udp://127.0.0.1",
        "udp://127.0.0.1:70000",
        "udp://127.0.0.1:10110?bogus=1",
        "udp://127.0.0.1:10110?iface=eth0",
        "udp://127.0.0.1:10110?target=nowhere",
        "tcp://:10110",
        "tcp://127.0.0.1:0",
        "tcp://127.0.0.1:10110/path",
        "tcp:127.0.0.1",
        "udpout:0.0.0.0",
        "serial://dev/ttyUSB0",
        "serial:///dev/ttyUSB0?baud=fast",
        "serial:///dev/ttyUSB0?parity=X",
        "serial:///dev/ttyUSB0?bytesize=9",
        "serial:///dev/ttyUSB0?stopbits=3",
        "serial:///dev/ttyUSB0?baud=4800&baud=9600",
        "pty",
        "file://log.nmea",
        "file:///x?rate=slow",
        "file:///x?rate=0",
        "127.0.0.1:10110",
        "udp:/",
        "tcp-listen://host",
        "udp://1.2.3.4:5 6",
        "udp://1.2.3.4:5#frag",
    ],
)
def test_bad_urls_are_refused_naming_the_url(url: str) -> None:
    with pytest.raises(SourceError) as info:
        open_source("dgps1", url)
    assert str(info.value).startswith("source 'dgps1': ")
    assert f"({url})" in str(info.value)


@settings(max_examples=300, deadline=None)
@given(
    st.text(max_size=60)
    | st.from_regex(r"(udp|tcp|serial|file|pty|udpin|tcpin|udpout):/{0,3}[\w.:?=&/\[\]-]{0,30}")
)
def test_any_text_gives_a_source_or_a_source_error(url: str) -> None:
    try:
        src = open_source("x", url, hello=b"")
    except SourceError as exc:
        assert "source 'x'" in str(exc)
    else:
        assert isinstance(src, Source) and not src.running


def test_timeout_must_be_positive() -> None:
    with pytest.raises(SourceError, match="timeout_s"):
        open_source("x", "udp://0.0.0.0:0", timeout_s=0)


def test_start_twice_is_a_programming_error(opened: list[Source]) -> None:
    src, _ = start(opened, "u", "udp://127.0.0.1:0", UdpSource)
    with pytest.raises(RuntimeError):
        src.start(Collector())
    src.stop()
    src.stop()  # idempotent
    with pytest.raises(RuntimeError):
        src.start(Collector())  # a stopped source is not restarted: open a new one
    open_source("never", "udp://127.0.0.1:0").stop()  # stop before start is harmless


# ----------------------------------------------------------------------------------- stop is prompt


def _serial(tmp: Path, keep: list[object]) -> str:
    sink = PtySink()
    keep.append(sink)
    return f"serial://{sink.device}"


def _tcp_connected(tmp: Path, keep: list[object]) -> str:
    server = TcpServerSink("127.0.0.1", 0)
    keep.append(server)
    return f"tcp://127.0.0.1:{server.port}"


def _tcp_no_server(tmp: Path, keep: list[object]) -> str:
    return f"tcp://127.0.0.1:{free_tcp_port()}"


def _tcp_listen(tmp: Path, keep: list[object]) -> str:
    return "tcp-listen://127.0.0.1:0"


def _file_waiting(tmp: Path, keep: list[object]) -> str:
    (tmp / "slow.nmea").write_bytes(HDT * 5)
    return f"file://{tmp}/slow.nmea?rate=0.2"


@pytest.mark.parametrize(
    "make",
    [
        _serial,
        lambda tmp, keep: "udp://127.0.0.1:0",
        lambda tmp, keep: "udpout:127.0.0.1:9",
        _tcp_connected,
        _tcp_no_server,
        _tcp_listen,
        _file_waiting,
    ],
    ids=["serial", "udp", "udpout", "tcp-connected", "tcp-retrying", "tcp-listen", "file-paced"],
)
def test_stop_is_prompt_and_leaves_no_thread(
    make: Callable[[Path, list[object]], str], tmp_path: Path, opened: list[Source]
) -> None:
    keep: list[object] = []
    try:
        src = open_source("s", make(tmp_path, keep))
        opened.append(src)
        src.start(Collector())
        if isinstance(src, TcpListenSource):
            keep.append(socket.create_connection(("127.0.0.1", src.port), timeout=3))
        if isinstance(src, TcpClientSource) and keep:
            server = keep[0]
            assert isinstance(server, TcpServerSink)

            def accepted() -> bool:
                server.poll()  # the sink accepts clients when polled
                return src.stats.connected

            assert wait_until(accepted, 3.0)
        # not a wait for an event (there is none to see): time for the reader to enter its blocking read or
        # back-off wait, where a stop is hardest. A loaded machine can make this check weaker, never fail it
        time.sleep(0.3)
        assert src.running
        t0 = time.monotonic()
        src.stop()
        assert time.monotonic() - t0 < 1.5
        assert not src.running and "dpgw-source-s" not in {t.name for t in threading.enumerate()}
        assert not src.stats.connected
    finally:
        for thing in keep:
            thing.close()  # type: ignore[attr-defined]


@pytest.mark.slow  # 30,000 datagrams twice, and a tiny buffer that drops most of them: ~15 s
@pytest.mark.parametrize("rcvbuf", ["4k", None])
def test_udp_burst_nothing_dropped_unseen(opened: list[Source], rcvbuf: str | None) -> None:
    """30,000 datagrams as fast as the sender can: every one is either received or counted as dropped by
    the kernel (SO_RXQ_OVFL), with a tiny buffer that must drop and with the default one."""
    got: list[int] = []
    url = "udp://127.0.0.1:0" + (f"?rcvbuf={rcvbuf}" if rcvbuf else "")
    src = open_source("burst", url)
    assert isinstance(src, UdpSource)
    src.start(lambda chunk: got.append(len(chunk.data)))
    opened.append(src)
    assert src.granted_buffer >= (4096 if rcvbuf else 4 * 1024 * 1024) or src.granted_buffer > 0
    payload = b"$HEHDT,123.4,T*2B\r\n"
    sent = 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for _ in range(30_000):
            tx.sendto(payload, ("127.0.0.1", src.port))
            sent += 1

        def settled() -> bool:
            # the kernel's count arrives with the next datagram that gets through: while the books do not
            # balance, send one more, and look again at the next poll (looking right after sending raced
            # the receiving thread on a busy machine: the probe just sent was always still in flight)
            nonlocal sent
            if len(got) + src.dropped == sent:
                return True
            tx.sendto(payload, ("127.0.0.1", src.port))
            sent += 1
            return False

        assert wait_until(settled, 20.0), (len(got), src.dropped, sent)
    if rcvbuf == "4k":
        assert src.dropped > 0  # the small buffer did overflow, and it was seen


def test_udp_on_an_address_not_up_yet_waits_for_it_instead_of_refusing(opened: list[Source]) -> None:
    """An interface slow to come up at boot: the source starts (not connected, saying why) instead of
    stopping the gateway, which systemd would restart until it gives up (StartLimitBurst)."""
    src, _ = start(opened, "dgps", "udp://192.0.2.10:0", UdpSource)  # TEST-NET-1: on no interface here
    assert src.running and not src.stats.connected and not src.address_up
    assert "192.0.2.10" in (src.stats.last_error or "") and "not an address of this computer yet" in (
        src.stats.last_error or ""
    )


_COMES_UP = """
import json, socket, subprocess, sys, time
from gateway.sources import open_source
subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
got = []
src = open_source("dgps", "udp://10.9.8.7:10110")
src.start(got.append)
before = (src.stats.connected, src.address_up)
subprocess.run(["ip", "addr", "add", "10.9.8.7/32", "dev", "lo"], check=True)  # the interface comes up
deadline = time.monotonic() + 20
tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
while not got and time.monotonic() < deadline:
    tx.sendto(b"$GPHDT,1.0,T*00\\r\\n", ("10.9.8.7", 10110))
    time.sleep(0.05)
print(json.dumps({"before": before, "after": [src.stats.connected, src.address_up], "got": len(got)}))
src.stop()
"""


_GOES_AWAY = """
import json, socket, subprocess, sys, time
from gateway.sources import open_source
subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
subprocess.run(["ip", "addr", "add", "10.9.8.7/32", "dev", "lo"], check=True)
got = []
src = open_source("dgps", "udp://10.9.8.7:10110")
src.start(got.append)
tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

def until(done, what):
    deadline = time.monotonic() + 20
    while not done():
        if time.monotonic() > deadline:
            sys.exit(f"timed out waiting for {what}")
        time.sleep(0.05)

def receives():
    n = len(got)
    def more():
        tx.sendto(b"$GPHDT,1.0,T*00\\r\\n", ("10.9.8.7", 10110))
        return len(got) > n
    until(more, "a datagram")

receives()
up = [src.stats.connected, src.address_up]
subprocess.run(["ip", "addr", "del", "10.9.8.7/32", "dev", "lo"], check=True)  # the interface goes down
until(lambda: not src.address_up, "the address to be missed")
gone = [src.stats.connected, src.address_up, src.stats.last_error]
subprocess.run(["ip", "addr", "add", "10.9.8.7/32", "dev", "lo"], check=True)  # and comes back
receives()
back = [src.stats.connected, src.address_up]
print(json.dumps({"up": up, "gone": gone, "back": back}))
src.stop()
"""


def _in_network_namespace(script: str) -> dict[str, object]:
    """Run ``script`` (python) in a network namespace of its own (no root needed, nothing on this machine's
    network changed); its last line of output, as JSON."""
    import json
    import os
    import shutil
    import subprocess
    import sys

    if shutil.which("unshare") is None or shutil.which("ip") is None:  # pragma: no cover
        pytest.skip("needs unshare and ip (util-linux, iproute2)")
    probe = subprocess.run(["unshare", "-rn", "true"], capture_output=True)
    if probe.returncode != 0:  # pragma: no cover — no user namespaces here
        pytest.skip(f"unshare -rn not permitted: {probe.stderr.decode().strip()}")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    run = subprocess.run(
        ["unshare", "-rn", sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=90
    )
    assert run.returncode == 0, run.stderr
    result: dict[str, object] = json.loads(run.stdout.strip().splitlines()[-1])
    return result


def test_udp_says_when_its_address_goes_away_and_reads_again_when_it_is_back() -> None:
    """An interface that goes down under a listening source: not connected, saying why (else it would
    only look quiet), and reading again once the address is back, on the same socket."""
    result = _in_network_namespace(_GOES_AWAY)
    assert result["up"] == [True, True]
    connected, address_up, why = result["gone"]  # type: ignore[misc]
    assert (connected, address_up) == (False, False)
    assert "10.9.8.7:10110 is no longer an address of this computer" in why, why
    assert result["back"] == [True, True]


def test_udp_reads_once_its_address_comes_up() -> None:
    """In a network namespace of its own (no root needed, nothing on this machine's network changed): the
    source is started on an address no interface has, then the address is added; datagrams arrive."""
    result = _in_network_namespace(_COMES_UP)
    assert result["before"] == [False, False]
    assert result["after"] == [True, True] and result["got"] >= 1
