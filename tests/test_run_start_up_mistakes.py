"""A person's mistakes in what ``dpgw run`` is to open, met when it starts: each stops start-up with status 2
and ONE line on stderr naming the config file, the key to edit (``sources.<name>.url``), the problem with
the URL, and what to do; no traceback. Real processes, a real pty held by another program, real sockets."""

from __future__ import annotations

import json
import os
import pty
import shutil
import socket
import subprocess
import sys
import tty
from pathlib import Path

import pytest
import serial
from conftest import free_port

ROOT = Path(__file__).resolve().parents[1]


def write_config(tmp: Path, url: str, name: str = "dgps1") -> Path:
    cfg = tmp / "vessel.toml"
    cfg.write_text(f"""
[vessel]
name = "mss_supply"
[[sources]]
name = "{name}"
url = "{url}"
protocol = "nmea"
roles = ["position", "heading"]
[zenoh]
listen = ["tcp/127.0.0.1:{free_port()}"]
multicast_scouting = false
[log]
path = "{tmp / "live.mcap"}"
""")
    return cfg


def start(cfg: Path, prefix: list[str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*(prefix or []), sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "5"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


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
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--check"],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
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
