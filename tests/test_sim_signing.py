"""The simulated thruster drives on a MAVLink 2 signed link: what they send is signed, what they take is
only what is signed with their key (`dpgw sim --signing-key-file`, `dpgw demo`), and the config a log
keeps never holds the key."""

from __future__ import annotations

import json
import logging
import os
import re
import socket
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import wait_for

from gateway.config import parse_config
from gateway.config.defaults import default_config
from gateway.config.logged import KEY_NOT_LOGGED, for_log, unlogged_key_sources, without_unlogged_keys
from simulator.commands import MavlinkCommandInput
from simulator.runner import Route, Simulation
from simulator.scenarios import get_scenario
from simulator.sensors import ThrusterFeedbackConfig
from simulator.transports import UdpSink
from wire.codecs import mavlink as mv

KEY = bytes(range(100, 132))
OTHER_KEY = bytes(range(32))
DRIVE = (4, 9)


def _verifier(key: bytes) -> mv.FrameParser:
    rx = mv.encoder(0, 0)
    mv.setup_signing(rx, key, sign_outgoing=False)
    return mv.FrameParser(rx)


class _SignedDrive:
    """The hajivand_2010 vessel (three azimuths) whose drives sign with `KEY`, over real UDP loopback to a
    socket that stands for the gateway."""

    def __init__(self) -> None:
        self.gateway = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.gateway.bind(("127.0.0.1", 0))
        self.gateway.setblocking(False)
        fb = ThrusterFeedbackConfig(rate_hz=5.0, system_id=DRIVE[0], component_id=DRIVE[1])
        self.sink = UdpSink("127.0.0.1", self.gateway.getsockname()[1])
        self.commands = MavlinkCommandInput.for_drive(self.sink, fb, signing_key=KEY)
        scenario = replace(get_scenario("hajivand_2010"), feedback=fb)
        self.sim = Simulation(
            scenario, 0, routes=[Route(self.sink, "mavlink")], commands=[self.commands], signing_key=KEY
        )
        self.received = b""
        self.sim_address: tuple[str, int] | None = None

    def feedback(self) -> bytes:
        """Run a little sea; return the datagrams the gateway's socket holds (learning the sim's address)."""
        self.sim.run(0.5)
        out = b""
        while True:
            try:
                data, self.sim_address = self.gateway.recvfrom(65536)
            except BlockingIOError:
                return out
            out += data

    def rejected_now(self) -> dict[str, int]:
        """Run a little sea (the drive reads its link at each control tick); what it has rejected."""
        self.sim.run(0.1)
        return dict(self.commands.rejected)

    def applied(self) -> int:
        self.sim.run(0.1)
        return self.sim.summary.commands_applied

    def close(self) -> None:
        self.sink.close()
        self.gateway.close()


@pytest.fixture
def drive() -> Iterator[_SignedDrive]:
    d = _SignedDrive()
    try:
        yield d
    finally:
        d.close()


def test_a_signed_drive_signs_its_feedback_and_takes_only_commands_signed_with_its_key(
    drive: _SignedDrive, caplog: pytest.LogCaptureFixture
) -> None:
    """Feedback: every frame signed, and with the drive's key (a parser with another key rejects them all).
    Commands over UDP loopback: an unsigned one and one signed with another key are counted and not
    applied; one signed with the key is; the same signed frame sent again, from the same or another
    address, is a replay (its timestamp is not newer) and is rejected."""
    caplog.set_level(logging.WARNING, logger="simulator.commands")
    data = wait_for(drive.feedback, 30.0)
    assert data and drive.sim_address is not None
    good = _verifier(KEY)
    frames = good.feed(data) + good.flush()
    assert len(frames) >= 4 and not good.rejected  # heartbeat + three status frames at least
    assert all(f.get_signed() and f.get_link_id() == 0 for f in frames)
    assert {f.get_type() for f in frames} >= {"HEARTBEAT", "AZIMUTH_THRUSTER_STATUS"}
    wrong = _verifier(OTHER_KEY)
    assert wrong.feed(data) + wrong.flush() == []
    assert wrong.rejected["bad_signature"] == len(frames)

    plain = mv.encoder(1, 191)
    forger = mv.encoder(1, 191)
    mv.setup_signing(forger, OTHER_KEY, link_id=1)
    gateway = mv.encoder(1, 191)
    mv.setup_signing(gateway, KEY, link_id=1)
    drive.gateway.sendto(mv.azimuth_command_frame(plain, 0, 1, 3e5, 0.5), drive.sim_address)
    drive.gateway.sendto(mv.azimuth_command_frame(forger, 0, 1, 3e5, 0.5), drive.sim_address)

    rejected = drive.rejected_now
    assert wait_for(lambda: rejected() == {"unsigned": 1, "bad_signature": 1}, 30.0), f"rejected {rejected()}"
    assert drive.sim.summary.commands_applied == 0 and not drive.sim.external_control
    signed = mv.azimuth_command_frame(gateway, 0, 2, 2e5, -0.7)
    drive.gateway.sendto(signed, drive.sim_address)

    assert wait_for(lambda: drive.applied() >= 1, 30.0), f"rejected {rejected()}"
    i = drive.sim.thrusters.ids.index(2)
    assert drive.sim.thrusters.thrust_setpoint[i] == pytest.approx(2e5)
    assert drive.sim.thrusters.angle_setpoint[i] == pytest.approx(-0.7, abs=1e-6)

    # the captured signed frame, sent again: from the gateway's address, then from another one
    replayer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        drive.gateway.sendto(signed, drive.sim_address)
        replayer.sendto(signed, drive.sim_address)
        assert wait_for(lambda: rejected()["bad_signature"] == 3, 30.0), f"rejected {rejected()}"
    finally:
        replayer.close()
    assert drive.sim.summary.commands_applied == 1
    assert drive.commands.received == 1
    # the first of each kind per peer is logged, with its bytes; the key never
    messages = [r.getMessage() for r in caplog.records]
    assert sum("not signed" in m for m in messages) == 1
    assert sum("bad signature" in m for m in messages) == 2  # the gateway's address, the replayer's
    assert not any(KEY.hex() in m or OTHER_KEY.hex() in m for m in messages)


def test_without_a_key_the_drive_sends_unsigned_and_takes_unsigned_commands() -> None:
    """No key: as before (unsigned frames out, an unsigned command taken), and the same bytes as before
    for the same seed."""
    from simulator.transports import MemorySink

    fb = ThrusterFeedbackConfig(rate_hz=2.0)
    scenario = replace(get_scenario("hajivand_2010"), feedback=fb)
    mav = MemorySink()
    inp = MavlinkCommandInput.for_drive(mav, fb)
    sim = Simulation(scenario, 0, routes=[Route(mav, "mavlink")], commands=[inp])
    sim.run(3.0)
    frames = mv.parse_frames(bytes(mav.data))
    assert frames and not any(f.get_signed() for f in frames)
    mav.feed(mv.azimuth_command_frame(mv.encoder(1, 191), 0, 1, 1e5, 0.2))
    sim.run(1.0)
    assert sim.summary.commands_applied == 1 and not inp.rejected


def test_signing_needs_the_bytes() -> None:
    with pytest.raises(ValueError, match="signed feedback"):
        Simulation(get_scenario("hajivand_2010"), 0, wire=False, signing_key=KEY)


# --- the config a log keeps ------------------------------------------------------------------------------


def _tables_with_key() -> dict:  # type: ignore[type-arg]
    cfg = default_config("cybership2")
    cfg["sources"] = [
        {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
        {
            "name": "thr",
            "url": "udp://127.0.0.1:0",
            "protocol": "mavlink",
            "roles": ["thrusters"],
            "commands": True,
            "signing_key": KEY.hex(),
            "allow_unsigned": True,
        },
    ]
    return cfg


def test_the_logged_config_holds_no_key_and_replays_without_one() -> None:
    tables = _tables_with_key()
    parse_config(tables, base_dir=Path.cwd(), where="test")  # a valid config, with its key
    logged = for_log(tables)
    text = json.dumps(logged)
    assert KEY.hex() not in text and KEY.hex().upper() not in text
    assert not re.search(r"[0-9a-fA-F]{64}", text)
    assert tables["sources"][-1]["signing_key"] == KEY.hex()  # the caller's tables untouched
    assert unlogged_key_sources(logged) == ["thr"]
    again = without_unlogged_keys(logged)
    thr = again["sources"][-1]
    assert thr["name"] == "thr" and not {"signing_key", "allow_unsigned", "commands"} & set(thr)
    config = parse_config({**again, "log": {"path": ""}}, base_dir=Path.cwd(), where="test")
    assert next(s for s in config.sources if s.name == "thr").signing_key is None
    # (no sources: nothing to hide; the command rules are written out, tests/test_replay.py)
    assert for_log({"vessel": {"name": "x"}})["vessel"] == {"name": "x"}


def test_a_logged_key_marker_is_not_taken_for_a_key() -> None:
    """The marker is not 64 hexadecimal characters: a logged config given to the gateway as it is stops
    with the config's own message rather than running with some key."""
    from gateway.config import ConfigError

    assert not re.fullmatch(r"[0-9a-fA-F]{64}", KEY_NOT_LOGGED)
    with pytest.raises(ConfigError, match=r"sources\.thr\.signing_key: not a signing key"):
        parse_config(for_log(_tables_with_key()), base_dir=Path.cwd(), where="test")


# --- dpgw sim --signing-key-file -------------------------------------------------------------------------


def _sim(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", *args], capture_output=True, text=True, timeout=120
    )


def _key_file(path: Path, text: str, mode: int = 0o600) -> Path:
    path.write_text(text)
    os.chmod(path, mode)
    return path


def test_dpgw_sim_signs_with_the_key_in_the_file(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "drive.key", KEY.hex() + "\n")
    frames_file = tmp_path / "frames.bin"
    run = _sim(
        "--scenario", "hajivand_2010", "--duration", "5", "--mavlink", f"file://{frames_file}",
        "--signing-key-file", str(key), "--json",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["signed"] is True and summary["commands_rejected"] == {}
    assert KEY.hex() not in run.stdout + run.stderr and "warning" not in run.stderr
    parser = _verifier(KEY)
    frames = parser.feed(frames_file.read_bytes()) + parser.flush()
    assert len(frames) == summary["emissions"]["thrusters"] > 20 and not parser.rejected
    assert all(f.get_signed() for f in frames)


@pytest.mark.parametrize(
    ("text", "mode", "expected"),
    [
        (KEY.hex()[:-2], 0o600, "not a signing key (expected 64 hexadecimal characters, got 62 characters)"),
        ("z" * 64, 0o600, "got 64 characters, not all hexadecimal"),
        (None, 0o600, "no such file"),
    ],
)
def test_dpgw_sim_refuses_a_bad_key_file_without_echoing_it(
    tmp_path: Path, text: str | None, mode: int, expected: str
) -> None:
    path = tmp_path / "drive.key"
    if text is not None:
        _key_file(path, text, mode)
    run = _sim("--scenario", "hajivand_2010", "--duration", "1", "--signing-key-file", str(path))
    assert run.returncode == 2
    assert run.stderr.startswith(f"dpgw sim: --signing-key-file {path}: ") and expected in run.stderr
    if text is not None:
        assert text not in run.stderr


def test_dpgw_sim_warns_of_a_key_file_others_may_read(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "drive.key", KEY.hex(), 0o644)
    run = _sim("--scenario", "hajivand_2010", "--duration", "1", "--signing-key-file", str(key), "--json")
    assert run.returncode == 0, run.stderr
    assert f"other users of this machine may read the key (chmod 600 {key})" in run.stderr
    assert KEY.hex() not in run.stderr


def test_dpgw_sim_signing_needs_thrusters_that_report() -> None:
    """A scenario without thruster feedback (a paper's ship without a layout) has nothing to sign:
    refused, not ignored."""
    assert get_scenario("fossen_strand_1999").feedback is None
    run = _sim("--scenario", "fossen_strand_1999", "--duration", "1", "--signing-key-file", "/nonexistent")
    assert run.returncode == 2 and "has no thrusters that report" in run.stderr


def test_rejections_are_counted_per_reason() -> None:
    """The input's `rejected` sums its parsers' counts with its own (other target, non finite)."""
    from simulator.transports import MemorySink

    mem = MemorySink()
    inp = MavlinkCommandInput(mem, 1, 1, signing_key=KEY)
    mem.feed(mv.azimuth_command_frame(mv.encoder(1, 191), 0, 1, 1e5, 0.2))
    mem.feed(b"\xfd\x00garbage")
    assert inp.poll() == []
    assert inp.rejected["unsigned"] == 1 and inp.received == 0
    assert Counter(inp.rejected) == inp.rejected
