"""A running gateway and a thruster drive on a real MAVLink UDP link: what goes out, to whom, and what
the feedback does to τ. The drive's side is pymavlink's generated code for the dpgw dialect."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port, wait_for

from gateway.config import parse_config
from gateway.service import GatewayService
from wire.codecs import mavlink as mv
from wire.codecs import nmea_encode as enc

KEY = bytes(range(32))
DRIVE = (1, 1)  # the thruster controller's system and component id


class Link:
    """A gateway (GPS on UDP, thruster link on UDP with commands on) and the sockets of the other end."""

    def __init__(self, tmp: Path, thr_url: str | None = None, **thr: Any) -> None:
        self.gps_port, self.thr_port = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
        tables: dict[str, Any] = {
            "vessel": {"name": "cybership2"},
            "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
            "sources": [
                {"name": "gps", "url": f"udp://127.0.0.1:{self.gps_port}", "protocol": "nmea",
                 "roles": ["position", "heading"]},
                {"name": "thr", "url": thr_url or f"udp://127.0.0.1:{self.thr_port}", "protocol": "mavlink",
                 "roles": ["thrusters"], "commands": True, **thr},
            ],
            "control": {"initial_mode": "manual"},
            "observer": {"wave_period_s": 9.0},
            "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"], "multicast_scouting": False},
            "log": {"path": ""},
        }  # fmt: skip
        self.service = GatewayService(parse_config(tables, base_dir=tmp), config_tables=tables)
        self.sockets: list[socket.socket] = []
        self.service.start()
        self.loop = threading.Thread(target=self.service.run, name="consumer")
        self.loop.start()

    def udp(self) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        s.setblocking(False)
        self.sockets.append(s)
        return s

    def gps(self, s: socket.socket) -> None:
        gga = enc.gga("GP", datetime.now(UTC), 59.4, 10.5, 2, 12, 0.8, 20.0)
        s.sendto((gga + enc.hdt("HE", 0.5)).encode(), ("127.0.0.1", self.gps_port))

    def stop(self) -> None:
        self.service.stop_event.set()
        self.loop.join(timeout=30)
        self.service.close()
        for s in self.sockets:
            s.close()


def drained(s: socket.socket) -> bytes:
    out = b""
    while True:
        try:
            out += s.recv(65536)
        except BlockingIOError:
            return out


@pytest.fixture
def signed_link(tmp_path: Path) -> Iterator[Link]:
    link = Link(tmp_path, signing_key=KEY.hex(), system_id=DRIVE[0], component_id=DRIVE[1])
    try:
        yield link
    finally:
        link.stop()


def test_commands_go_signed_to_the_configured_drive_not_to_the_last_datagram(signed_link: Link) -> None:
    """Another vehicle (system 2, unsigned) talks on the port first, then the drive (system 1, component
    1, signing) reports too, the other vehicle after every report. The commands wait for the drive, are
    addressed to system 1 / component 1 (not broadcast, which the other vehicle's controller would take),
    are signed with the link's key, and go to the drive's address: the other sender, though the last one
    heard, receives nothing."""
    link = signed_link
    gps, drive, other = link.udp(), link.udp(), link.udp()
    tx = mv.encoder(*DRIVE)
    mv.setup_signing(tx, KEY, link_id=3)
    intruder = mv.encoder(2, 1)
    rx = mv.encoder(0, 0)  # pymavlink's parser on the drive's side, checking the signatures
    mv.setup_signing(rx, KEY, sign_outgoing=False)
    got: list[Any] = []
    to_other = bytearray()
    thr = next(s for s in link.service._sources if s.name == "thr")

    def before_the_drive() -> bool:
        """The other vehicle is the only sender: commands are made but go nowhere."""
        link.gps(gps)
        other.sendto(mv.heartbeat_frame(intruder), ("127.0.0.1", link.thr_port))
        to_other.extend(drained(other))
        return bool(to_other) or thr.stats.errors["command not sent"] >= 5

    assert wait_for(before_the_drive, 60.0, 0.05), "the gateway made no commands"
    assert not to_other, f"{len(to_other)} bytes of thruster commands went to the other vehicle"

    def exchange() -> bool:
        link.gps(gps)
        drive.sendto(mv.heartbeat_frame(tx), ("127.0.0.1", link.thr_port))
        drive.sendto(mv.azimuth_status_frame(tx, 0, 1, 0.1, 20.0, 0.0, 0), ("127.0.0.1", link.thr_port))
        other.sendto(mv.heartbeat_frame(intruder), ("127.0.0.1", link.thr_port))
        to_other.extend(drained(other))
        got.extend(m for m in rx.parse_buffer(drained(drive)) or [] if m.get_type() != "BAD_DATA")
        return sum(m.get_type() == "AZIMUTH_THRUSTER_COMMAND" for m in got) >= 30

    assert wait_for(exchange, 60.0, 0.05), f"the drive received {len(got)} frames"
    commands = [m for m in got if m.get_type() == "AZIMUTH_THRUSTER_COMMAND"]
    assert {(m.target_system, m.target_component) for m in commands} == {DRIVE}
    assert {m.id for m in commands} == {1, 2, 3}  # cybership2's thrusters
    assert all(m.get_signed() for m in commands)
    # from an onboard computer (as the udpout hello), not a ground station's system 255
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in commands} == {(1, 191)}
    assert not to_other, f"{len(to_other)} bytes of thruster commands went to the other vehicle"
    c = link.service.pipeline.counters["thr"]
    assert c.rejected["other system"] + c.rejected["unsigned"] > 0  # the other vehicle: counted, not used

    # The drive goes (its socket closed): UDP cannot tell, the commands still go out, and the alarm is its
    # feedback going stale in /status; the gateway carries on.
    drive.close()
    link.sockets.remove(drive)
    sent0 = thr.stats.bytes_sent

    def stale() -> bool:
        link.gps(gps)
        return any("thr: stale" in a for a in link.service.last_status().get("alarms", []))

    assert wait_for(stale, 60.0, 0.05), link.service.last_status()
    assert thr.stats.bytes_sent > sent0 and link.loop.is_alive()
    assert link.service.pipeline.fusion.tau(link.service.pipeline.last_ns)[1] == "demand"


def test_a_drive_that_reboots_takes_the_gateways_signed_commands(signed_link: Link) -> None:
    """The gateway has signed commands for a while; the drive then reboots and meets the command stream
    new. pymavlink's receiver takes a new stream only if its first timestamp is at most a minute behind
    its own clock: the gateway's timestamps must follow the wall clock, not merely grow by one a frame
    from start-up (which, sending ten frames a second, falls a minute behind after a minute)."""
    link = signed_link
    gps, drive = link.udp(), link.udp()
    tx = mv.encoder(*DRIVE)
    mv.setup_signing(tx, KEY, link_id=3)
    # as if the gateway had been running for ten minutes, its timestamp grown by one per frame only
    mav = link.service._command_links["thr"]
    mav.signing.timestamp -= 10 * 60 * 100_000
    rebooted = mv.encoder(0, 0)  # the drive's parser, started now: its own clock is now
    mv.setup_signing(rebooted, KEY, sign_outgoing=False)
    got: list[Any] = []

    def exchange() -> bool:
        link.gps(gps)
        drive.sendto(mv.heartbeat_frame(tx), ("127.0.0.1", link.thr_port))
        drive.sendto(mv.azimuth_status_frame(tx, 0, 1, 0.1, 20.0, 0.0, 0), ("127.0.0.1", link.thr_port))
        got.extend(rebooted.parse_buffer(drained(drive)) or [])
        return sum(m.get_type() == "AZIMUTH_THRUSTER_COMMAND" for m in got) >= 6

    assert wait_for(exchange, 60.0, 0.05), (
        f"the rebooted drive took {sum(m.get_type() == 'AZIMUTH_THRUSTER_COMMAND' for m in got)} commands "
        f"of {len(got)} frames ({sum(m.get_type() == 'BAD_DATA' for m in got)} refused)"
    )


def test_a_genuine_frame_resent_from_another_address_is_refused_as_a_replay(signed_link: Link) -> None:
    """Someone on the network records the drive's signed frames and sends each again from another address
    once the gateway has it. Each sender had its own verifier, whose replay check started empty: every
    copy was taken (as new frames of a known stream), and the thruster commands went to the last sender of
    an accepted frame, the copier. The senders of a source now share one verifier: the copies are refused
    as replays (``bad_signature``), counted, and the copier gets no command."""
    link = signed_link
    gps, drive, copier = link.udp(), link.udp(), link.udp()
    tx = mv.encoder(*DRIVE)
    mv.setup_signing(tx, KEY, link_id=3)
    rx = mv.encoder(0, 0)
    mv.setup_signing(rx, KEY, sign_outgoing=False)
    counters = link.service.pipeline.counters["thr"]
    got: list[Any] = []
    to_copier = bytearray()
    copies = 0

    def exchange() -> bool:
        nonlocal copies
        link.gps(gps)
        frame = mv.azimuth_status_frame(tx, 0, 1, 0.1, 20.0, 0.0, 0)
        before = counters.received
        drive.sendto(frame, ("127.0.0.1", link.thr_port))
        if wait_for(lambda: counters.received > before, 10.0, 0.002):  # the gateway has the original
            copier.sendto(frame, ("127.0.0.1", link.thr_port))
            copies += 1
        got.extend(rx.parse_buffer(drained(drive)) or [])
        to_copier.extend(drained(copier))
        return sum(m.get_type() == "AZIMUTH_THRUSTER_COMMAND" for m in got) >= 30 and copies >= 20

    assert wait_for(exchange, 60.0, 0.05), f"the drive received {len(got)} frames, {copies} copies sent"
    assert wait_for(lambda: counters.rejected["bad_signature"] >= copies, 10.0, 0.01), dict(counters.rejected)
    assert counters.rejected["bad_signature"] == copies  # each copy refused, no original
    assert not to_copier, f"{len(to_copier)} bytes of thruster commands went to the copier"


def test_feedback_over_udp_is_used_or_counted_frame_by_frame(tmp_path: Path) -> None:
    """A drive's feedback on a real UDP port, with what a shared, noisy link carries: a MAVLink 1 heartbeat,
    another system's and another component's status, a thruster the vessel does not have, an infinite
    thrust, a NaN thrust with a shaft speed, a signed frame on a link without a key, line noise. Each frame
    is used or counted under the reason the docs give, and τ is B(α) of the good reports alone."""
    from pymavlink.dialects.v10 import ardupilotmega as v1

    link = Link(
        tmp_path, commands=False, system_id=DRIVE[0], component_id=DRIVE[1], ardupilot={"esc": {"1": 3}}
    )
    try:
        drive, signed, other_system, other_part = (
            mv.encoder(*DRIVE),
            mv.encoder(*DRIVE),
            mv.encoder(2, 1),
            mv.encoder(1, 7),
        )
        mv.setup_signing(signed, bytes(32))  # a key the gateway does not have: accepted unchecked
        mav1 = v1.MAVLink(None, srcSystem=DRIVE[0], srcComponent=DRIVE[1])
        nan, inf = float("nan"), float("inf")
        frames = [
            bytes(v1.MAVLink_heartbeat_message(11, 8, 0, 0, 4, 3).pack(mav1)),  # MAVLink 1: received
            mv.azimuth_status_frame(drive, 0, 1, 1.5, 150.0, 0.5, 0),  # used
            mv.azimuth_status_frame(other_system, 0, 1, 2.0, 200.0, 0.0, 0),  # other system
            mv.azimuth_status_frame(other_part, 0, 1, 2.0, 200.0, 0.0, 0),  # other component
            mv.azimuth_status_frame(drive, 0, 9, 1.0, 100.0, 0.0, 0),  # out_of_range: unknown thruster
            mv.azimuth_status_frame(drive, 0, 2, inf, 100.0, 0.0, 0),  # out_of_range: not finite
            mv.azimuth_status_frame(signed, 0, 2, nan, 100.0, -0.5, 0),  # used: thrust by the rpm
            mv.esc_telemetry_frame(drive, [100.0]),  # ESC 1 -> tunnel thruster 3: used
            b"$HEHDT,12.3,T*00\r\n" + mv.heartbeat_frame(drive)[:-1] + b"\x00",  # noise, bad CRC
        ]
        tx = link.udp()
        for f in frames:
            tx.sendto(f, ("127.0.0.1", link.thr_port))
        p = link.service.pipeline
        c = p.counters["thr"]
        # one sender's frames are handled in order: the last one counted means all are
        assert wait_for(lambda: c.rejected["bad_crc"], 30.0), c
        # frames from the drive are received (an out-of-range one is received and rejected, like a fix
        # that fails a test); another system's or component's are not
        assert c.received == 6
        assert dict(c.rejected) == {
            "other system": 1, "other component": 1, "out_of_range": 2, "bad_crc": 1
        }, c.rejected  # fmt: skip
        assert c.skipped_bytes > 0
        v = p.spec.vessel
        t2, t3 = v.thrusters[1].thrust_at_rpm(100.0), v.thrusters[2].thrust_at_rpm(100.0)
        assert {tid: fb[:2] for tid, fb in p.fusion.thrust.items()} == {
            1: (1.5, pytest.approx(0.5)), 2: (t2, pytest.approx(-0.5)), 3: (t3, 0.0)
        }  # fmt: skip
        tau, source = p.fusion.tau(max(fb.rx_ns for fb in p.fusion.thrust.values()))
        assert source == "feedback"
        expected = v.generalized_force([1.5, t2, t3], [0.5, -0.5, 0.0])
        assert tau == pytest.approx(expected)
    finally:
        link.stop()


def test_signed_feedback_over_a_serial_pty_in_pieces(tmp_path: Path) -> None:
    """A signed drive on a serial line (a pty at 115200 Bd), its frames arriving in 7-byte pieces as a slow
    UART hands them over: every frame is reassembled and its signature checked; a replayed frame (same
    signing timestamp) is rejected, and τ is the last good report's."""
    from simulator.transports import PtySink

    with PtySink(stale_s=None) as pty:
        link = Link(tmp_path, f"serial://{pty.device}?baud=115200", commands=False, signing_key=KEY.hex())
        try:
            tx = mv.encoder(*DRIVE)
            mv.setup_signing(tx, KEY, link_id=2)
            frames = [mv.azimuth_status_frame(tx, 0, 1, 0.05 * k, 5.0 * k, 0.01 * k, 0) for k in range(1, 41)]
            blob = b"".join(frames) + frames[-2]  # the last but one again: a replay
            for i in range(0, len(blob), 7):
                pty.write(blob[i : i + 7])
            c = link.service.pipeline.counters["thr"]
            assert wait_for(lambda: c.received + sum(c.rejected.values()) >= 41, 30.0), c
            assert c.received == 40 and dict(c.rejected) == {"bad_signature": 1}
            assert c.skipped_bytes == 0
            fb = link.service.pipeline.fusion.thrust[1]
            assert (fb.thrust_n, fb.azimuth_rad) == (pytest.approx(2.0), pytest.approx(0.4))
        finally:
            link.stop()
