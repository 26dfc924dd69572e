"""A person's mistakes in what ``dpgw run`` is to open, met when it starts: each stops start-up with status 2
and ONE line on stderr naming the config file, the key to edit (``sources.<name>.url``), the problem with
the URL, and what to do; no traceback. Real processes, a real pty held by another program, real sockets."""

from __future__ import annotations

import json
import os
import pty
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import serial
from conftest import free_port, one_source_config, wait_for

from gateway.bus import isolated_config, open_session
from simulator.transports import PtySink
from wire.codecs import nmea_encode as enc

ROOT = Path(__file__).resolve().parents[1]


def burst() -> bytes:
    gga = enc.gga("GP", datetime.now(UTC), 59.4, 10.5, 2, 12, 0.8, 20.0)
    return (gga + enc.hdt("HE", 0.5)).encode()


write_config = one_source_config


def start(cfg: Path, prefix: list[str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*(prefix or []), sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "5"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


def check(cfg: Path) -> subprocess.CompletedProcess[str]:
    """``dpgw run --config CFG --check`` in a fresh process."""
    return subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--check"],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def assert_one_clear_line(p: subprocess.CompletedProcess[str], cfg: Path, name: str, *what: str) -> None:
    assert p.returncode == 2, p.stderr
    lines = p.stderr.splitlines()
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr
    assert lines[0].startswith(f"dpgw run: {cfg}: sources.{name}.url: "), lines[0]
    for text in what:
        assert text in lines[0], lines[0]


def test_a_serial_port_that_does_not_exist(tmp_path: Path) -> None:
    cfg = write_config(tmp_path, "serial:///dev/ttyUSB_nope?baud=4800")
    assert_one_clear_line(
        start(cfg), cfg, "dgps1", "serial port /dev/ttyUSB_nope does not exist", "check the cable/udev name"
    )


def test_with_wait_for_ports_a_missing_serial_port_is_waited_for(tmp_path: Path) -> None:
    """The service's ``--wait-for-ports``: a serial port that is not there at start-up (a USB adapter late
    at boot) is a warning and a /status alarm, not a stop (systemd's restarts of a stopped gateway ran out
    after about a minute, and the port plugged in later was never read); it is read when it appears, and
    the estimates start. A port that is there but wrong still stops start-up (waiting would not mend it)."""
    link = tmp_path / "ttyUSB0"
    zport = free_port()
    cfg = write_config(tmp_path, f"serial://{link}?baud=115200", name="gps", datum=True)
    cfg.write_text(re.sub(r"tcp/127.0.0.1:\d+", f"tcp/127.0.0.1:{zport}", cfg.read_text()))
    p = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--wait-for-ports", "--json"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(p.stderr.readline, "")), daemon=True)  # type: ignore[union-attr]
    reader.start()
    client = None
    try:
        started = lambda: any(ln.startswith("dpgw run: vessel") for ln in lines)  # noqa: E731
        assert wait_for(lambda: started() or p.poll() is not None, 120.0) and started(), lines
        assert p.poll() is None, lines
        waiting = [ln for ln in lines if "waiting for it" in ln]
        assert len(waiting) == 1 and f"serial port {link} does not exist" in waiting[0], lines
        client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{zport}"]))

        def status() -> dict[str, Any]:
            replies = [r for r in client.get("dp/mss_supply/status", timeout=2.0) if r.ok is not None]
            return json.loads(replies[0].ok.payload.to_bytes()) if replies else {}

        assert wait_for(
            lambda: any(f"source gps: disconnected (serial port {link} does not exist" in a
                        for a in status().get("alarms", [])), 30.0
        ), status()  # fmt: skip
        with PtySink(str(link)) as sink:  # plugged in

            def sent_and_estimating() -> bool:
                sink.write(burst())
                time.sleep(0.02)  # (pacing the sender: 50 bursts a second)
                st = status()
                return st.get("estimates", 0) > 0 and not [a for a in st["alarms"] if "source gps" in a]

            assert wait_for(sent_and_estimating, 60.0), status()
            p.send_signal(signal.SIGTERM)
            out, _ = p.communicate(timeout=60)
    finally:
        if client is not None:
            client.close()
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, lines
    summary = json.loads(out)
    assert summary["estimates"] > 0 and summary["status"]["sources"]["gps"]["received"] > 0, summary
    assert any("is there now: reading" in ln for ln in lines), lines


def test_a_serial_port_another_program_holds(tmp_path: Path) -> None:
    master, slave = pty.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    try:
        with serial.Serial(device, exclusive=True):  # another program (gpsd, a terminal) has it
            cfg = write_config(tmp_path, f"serial://{device}?baud=4800", "gyro1")
            assert_one_clear_line(start(cfg), cfg, "gyro1", f"serial port {device} is in use", "stop it")
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("scheme", ["udp", "tcp-listen"])
def test_a_listening_port_in_use(tmp_path: Path, scheme: str) -> None:
    kind = socket.SOCK_DGRAM if scheme == "udp" else socket.SOCK_STREAM
    with socket.socket(socket.AF_INET, kind) as other:
        other.bind(("127.0.0.1", 0))
        if kind == socket.SOCK_STREAM:
            other.listen()
        port = other.getsockname()[1]
        cfg = write_config(tmp_path, f"{scheme}://127.0.0.1:{port}", "mux")
        assert_one_clear_line(
            start(cfg),
            cfg,
            "mux",
            f"cannot listen on 127.0.0.1:{port}: Address already in use",
            "choose another port",
        )


def _without_bind_privilege() -> list[str]:
    """A command prefix that starts the gateway without the privilege to bind ports below 1024: nothing
    when we lack it already; as root, ``setpriv`` dropping CAP_NET_BIND_SERVICE (root stays root, so the
    interpreter under /root stays reachable)."""
    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv to drop CAP_NET_BIND_SERVICE")
    return ["setpriv", "--bounding-set=-net_bind_service", "--inh-caps=-net_bind_service"]


@pytest.mark.parametrize("scheme", ["udp", "tcp-listen"])
def test_a_privileged_port_without_privileges(tmp_path: Path, scheme: str) -> None:
    cfg = write_config(tmp_path, f"{scheme}://0.0.0.0:555", "mux")
    p = start(cfg, prefix=_without_bind_privilege())
    if p.returncode != 2 and "Permission denied" not in p.stderr:
        pytest.skip(f"this system lets an unprivileged user bind port 555 (or cannot run as one): {p.stderr}")
    assert_one_clear_line(
        p, cfg, "mux", "cannot listen on 0.0.0.0:555: Permission denied", "choose a port of 1024 or above"
    )


def test_check_notes_a_serial_port_that_is_not_there_now(tmp_path: Path) -> None:
    """``--check`` opens nothing, so it cannot refuse a port that may yet come (a USB adapter, a simulator's
    pty link); it notes it. Before: ``ok`` with no word of it, then the service refused to start."""
    cfg = write_config(tmp_path, "serial:///dev/ttyUSB_nope?baud=4800")
    p = check(cfg)
    assert p.returncode == 0, p.stderr
    notes = [ln for ln in p.stdout.splitlines() if ln.startswith("note: sources.dgps1.url: ")]
    assert len(notes) == 1 and "serial port /dev/ttyUSB_nope does not exist now" in notes[0], p.stdout
    # a port that is there: no note
    master, slave = pty.openpty()
    try:
        cfg = write_config(tmp_path, f"serial://{os.ttyname(slave)}?baud=4800")
        p = subprocess.run(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--check", "--json"],
            cwd=ROOT, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    finally:
        os.close(master)
        os.close(slave)
    assert p.returncode == 0, p.stderr
    assert not [n for n in json.loads(p.stdout)["notes"] if "serial port" in n]


def test_check_notes_a_file_source_that_is_not_there_now(tmp_path: Path) -> None:
    """Before: ``--check`` said ``ok`` of a ``file:`` source whose file was not there, and the start then
    stopped on it. A note, as for a serial port (the file may be written by then); a file that is there
    gets none."""
    cfg = write_config(tmp_path, "file:nope.nmea")
    p = check(cfg)
    assert p.returncode == 0, p.stderr
    notes = [ln for ln in p.stdout.splitlines() if ln.startswith("note: sources.dgps1.url: ")]
    assert len(notes) == 1 and f"file {tmp_path / 'nope.nmea'} does not exist now" in notes[0], p.stdout
    (tmp_path / "nope.nmea").write_text("$GPGGA\r\n")
    p = check(cfg)
    assert p.returncode == 0 and "note: sources.dgps1.url: " not in p.stdout, p.stdout


def test_the_log_folder_note_of_a_user_without_a_passwd_entry(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A uid the password database does not know (a container run with ``--user 1234``): the note names
    the uid. Before, ``pwd.getpwuid`` raised KeyError and ``--check`` ended in a traceback."""
    import pwd

    from dpgw.cli_run import log_folder_note

    def unknown(uid: int) -> Any:
        raise KeyError(f"getpwuid(): uid not found: {uid}")

    monkeypatch.setattr(pwd, "getpwuid", unknown)
    # (as root, permissions cannot make the case: the check of what this user may write is stood in for;
    # a file in the way is a problem of its own, not this note)
    monkeypatch.setattr("dpgw.cli_run.writable", lambda path: False)
    note = log_folder_note(str(tmp_path / "logs" / "dpgw.mcap"))
    assert note is not None and f"for this user (uid {os.geteuid()})" in note, note
    assert f"the folder {tmp_path / 'logs'} does not exist and cannot be made" in note


def test_check_notes_a_log_folder_that_cannot_be_made(tmp_path: Path) -> None:
    """``sudo -u dpgw dpgw run --check`` is run to find what the service's user cannot do; a log folder it
    cannot write or make stopped the service's start-up after the check had said ``ok`` with no word of
    it. A folder this user cannot make is a note (not a problem: systemd's LogsDirectory may make it by
    then; `test_the_log_folder_note_of_a_user_without_a_passwd_entry`); a file in the folder's way, which
    nothing at start-up clears, is a problem (status 2), and the run itself stops on it with one line."""
    cfg = write_config(tmp_path, "udp://127.0.0.1:0")
    (tmp_path / "afile").write_bytes(b"")
    cfg.write_text(
        cfg.read_text().replace(str(tmp_path / "live.mcap"), str(tmp_path / "afile" / "dpgw.mcap"))
    )
    p = check(cfg)
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"log.path: cannot make the log's folder: {tmp_path / 'afile'} is a file, not a folder" in p.stderr
    assert "note: log.path" not in p.stdout
    run = start(cfg)
    assert run.returncode == 2 and "log.path: cannot make the log's folder" in run.stderr, run.stderr
    # a folder that can be made: no note
    cfg.write_text(cfg.read_text().replace(str(tmp_path / "afile"), str(tmp_path / "new")))
    p = check(cfg)
    assert p.returncode == 0 and "note: log.path" not in p.stdout, p.stdout
    # a folder whose parent is missing too is not made (a mistyped path): a note, and the run stops on it
    cfg.write_text(cfg.read_text().replace(str(tmp_path / "new"), str(tmp_path / "new" / "logs")))
    p = check(cfg)
    assert p.returncode == 0, p.stderr
    assert f"note: log.path: neither the folder {tmp_path / 'new' / 'logs'} nor its parent" in p.stdout
    run = start(cfg)
    assert run.returncode == 2, run.stderr
    assert f"log.path: neither the folder {tmp_path / 'new' / 'logs'} nor its parent" in run.stderr
    assert not (tmp_path / "new").exists()


def test_two_missing_serial_ports_are_named_in_one_message(tmp_path: Path) -> None:
    """Every serial port that is not there, with the key to edit, in one message: before, start-up named
    the first, and the engineer who fixed it met the second on the next try."""
    cfg = write_config(tmp_path, "serial:///dev/ttyUSB_nope1?baud=4800", name="gps")
    cfg.write_text(
        cfg.read_text().replace(
            "[zenoh]",
            '[[sources]]\nname = "gyro"\nurl = "serial:///dev/ttyUSB_nope2?baud=4800"\nprotocol = "nmea"\n'
            'roles = ["heading"]\npriority = 2\n[zenoh]',
        )
    )
    p = start(cfg)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    assert p.stderr.startswith(f"dpgw run: {cfg}: 2 serial ports do not exist:"), p.stderr
    said = "  sources.{0}.url: serial port /dev/ttyUSB_nope{1} does not exist (serial:///dev/ttyUSB_nope{1}?baud=4800)"
    assert said.format("gps", 1) in p.stderr.splitlines(), p.stderr
    assert said.format("gyro", 2) in p.stderr.splitlines(), p.stderr
    assert "--wait-for-ports" in p.stderr
    assert not (tmp_path / "live.mcap").exists()  # stopped before anything was opened


def with_missing_gyro(cfg: Path) -> Path:
    """``cfg`` with a second source, a gyro on a serial port that does not exist."""
    cfg.write_text(
        cfg.read_text().replace(
            "[zenoh]",
            '[[sources]]\nname = "gyro"\nurl = "serial:///dev/ttyUSB_nope2?baud=4800"\n'
            'protocol = "nmea"\nroles = ["heading"]\npriority = 2\n[zenoh]',
        )
    )
    return cfg


def test_a_missing_serial_port_and_a_port_in_use_are_named_in_one_message(tmp_path: Path) -> None:
    """A serial port that is not there and another source's UDP port held by another program: both in one
    message, each with its key and its fix (before, the second was met only after the first was fixed)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
        other.bind(("127.0.0.1", 0))
        port = other.getsockname()[1]
        cfg = with_missing_gyro(write_config(tmp_path, f"udp://127.0.0.1:{port}", name="mux"))
        p = start(cfg)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    lines = p.stderr.splitlines()
    assert lines[0] == f"dpgw run: {cfg}: 2 sources cannot open:", p.stderr
    assert lines[1] == (
        f"  sources.mux.url: cannot listen on 127.0.0.1:{port}: Address already in use "
        f"(udp://127.0.0.1:{port}) — another program uses this UDP port: stop it or choose another port"
    ), p.stderr
    assert lines[2] == (
        "  sources.gyro.url: serial port /dev/ttyUSB_nope2 does not exist (serial:///dev/ttyUSB_nope2?baud=4800)"
    ), p.stderr
    assert "--wait-for-ports" in lines[3], p.stderr
    assert not (tmp_path / "live.mcap").exists()  # stopped before anything was opened


def test_a_missing_serial_port_beside_a_tcp_server_that_is_down_is_one_message(tmp_path: Path) -> None:
    """A TCP source whose server is down and a gyro on a serial port that is not there: the start-up's one
    message names the port, and nothing else is said. Before, the TCP source's reader thread was started to
    try every source and said its first retry ("cannot connect ...; retrying with back-off") before it: two
    messages for one mistake, the first about something start-up does not stop on."""
    cfg = with_missing_gyro(write_config(tmp_path, f"tcp://127.0.0.1:{free_port()}", name="dgps1"))
    p = start(cfg)
    assert p.returncode == 2, p.stderr
    assert "cannot connect" not in p.stderr and "Traceback" not in p.stderr, p.stderr
    lines = p.stderr.splitlines()
    assert lines[0].startswith(
        f"dpgw run: {cfg}: sources.gyro.url: serial port /dev/ttyUSB_nope2 does not exist"
    )
    assert len(lines) == 1, p.stderr


def test_the_start_up_that_stops_starts_no_source(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same in the process, without the race: when a serial port is missing, every source is tried
    (opened and closed: `Source.probe`) so that one message names all that cannot open, and none is started,
    so no reader thread says anything of its own (the TCP client's retry warning above)."""
    from gateway.config import load_config
    from gateway.service import GatewayService
    from gateway.sources import Source, SourceError

    started: list[str] = []
    monkeypatch.setattr(Source, "start", lambda self, deliver: started.append(self.name))
    cfg = with_missing_gyro(write_config(tmp_path, f"tcp://127.0.0.1:{free_port()}", name="dgps1"))
    service = GatewayService(load_config(cfg))
    with pytest.raises(SourceError, match="ttyUSB_nope2"):
        service.start()
    service.close()
    assert started == []


def test_log_folder_one_level_is_made_and_said_more_is_refused(tmp_path: Path) -> None:
    """``--log`` in a folder that is not there: made, and said on stderr, when its parent exists; refused
    with one line, and nothing made, when more is missing (a mistyped path on a vessel PC, as root, made
    a tree of folders without a word)."""
    cfg = write_config(tmp_path, "udp://127.0.0.1:0")

    def run_with_log(path: Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "0.5",
             "--log", str(path)],
            cwd=ROOT, capture_output=True, text=True, timeout=120,
        )  # fmt: skip

    deep = tmp_path / "nonexistent" / "dir" / "x.mcap"
    p = run_with_log(deep)
    assert p.returncode == 2, p.stderr
    assert p.stderr.splitlines() == [
        f"dpgw run: --log {deep}: neither the folder {deep.parent} nor its parent {deep.parent.parent} "
        "exists: only the file's own folder is made, so that a mistyped path does not make folders; "
        f"check the path, or make it first (mkdir -p {deep.parent})"
    ], p.stderr
    assert not (tmp_path / "nonexistent").exists()
    one = tmp_path / "trials" / "x.mcap"
    p = run_with_log(one)
    assert p.returncode == 0, p.stderr
    assert [ln for ln in p.stderr.splitlines() if "made the log's folder" in ln] == [
        f"made the log's folder {one.parent} (it did not exist)"
    ], p.stderr
    assert one.exists()
    p = run_with_log(one)  # there now: nothing said
    assert p.returncode == 0 and "made the log's folder" not in p.stderr, p.stderr


def test_a_missing_serial_port_stops_start_up_before_the_kernels_compile(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The service compiles its numeric kernels (about 15 s on a first run) before the sources open, so a
    mistyped serial port was said only after that wait. Now the serial paths are looked at first, and
    every source that cannot open is still named together (a UDP port in use beside the missing port)."""
    import logging

    from gateway.config import load_config
    from gateway.service import GatewayService
    from gateway.sources import SeveralSourcesError

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
        other.bind(("127.0.0.1", 0))
        port = other.getsockname()[1]
        cfg = with_missing_gyro(write_config(tmp_path, f"udp://127.0.0.1:{port}", name="mux"))
        service = GatewayService(load_config(cfg))
        caplog.set_level(logging.INFO, logger="dpgw")
        with pytest.raises(SeveralSourcesError) as raised:
            service.start()
    assert [(e.name, e.missing_port) for e in raised.value.errors] == [("mux", False), ("gyro", True)]
    assert "Address already in use" in raised.value.errors[0].problem
    assert not [r for r in caplog.records if "compiled kernels ready" in r.getMessage()], caplog.text
    assert not service.opened and service._sources == []
    # with --wait-for-ports the port is waited for: the look does not stop start-up
    waiting = GatewayService(load_config(cfg), wait_for_ports=True)
    waiting._look_for_ports()


def test_check_names_the_config_as_given_for_every_problem(tmp_path: Path) -> None:
    """A source URL's problem found by the start-up checks was prefixed with the config's absolute path,
    every other problem with the name the user gave: one convention, the name as given."""
    write_config(tmp_path, "udp://127.0.0.1:0?rcvbuf=abc")
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", "vessel.toml", "--check"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 2
    assert "  vessel.toml: sources.dgps1.url: rcvbuf 'abc' is not a buffer size" in p.stderr, p.stderr
    assert str(tmp_path) not in p.stderr


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_the_check_notes_a_log_folder_where_no_file_can_be_made() -> None:
    """``log.path = "/proc/vessel.mcap"``: the folder's permissions say writable (to root), but the
    filesystem makes no file there: ``--check`` said ok without a word and ``dpgw run`` then stopped on it.
    The check now makes (and removes) a file there and notes why it could not."""
    from dpgw.cli_run import log_folder_note

    note = log_folder_note("/proc/vessel.mcap")
    assert note is not None and "/proc" in note, note
    if os.access("/proc", os.W_OK):  # (root: the permissions said yes)
        assert note.startswith("log.path: no file can be made in /proc ("), note
    assert not list(Path("/proc").glob(".dpgw-check-*"))


def test_the_check_leaves_no_file_in_a_log_folder_it_could_write(tmp_path: Path) -> None:
    from dpgw.cli_run import log_folder_note

    assert log_folder_note(str(tmp_path / "dpgw.mcap")) is None
    assert list(tmp_path.iterdir()) == []
