"""Who may command the vessel: a real gateway session with Zenoh user/password authentication and access
control on the command keys; sessions without credentials, with wrong ones, or of a user who may only
watch cannot change the mode, setpoint or τ; the commander can. The default session listens on loopback
only."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh
from conftest import free_port, wait_for

from gateway.bus import open_session
from gateway.config import parse_config
from gateway.service import GatewayService, zenoh_config

PREFIX = "dp/acl"


def tables(zenoh_table: dict[str, Any]) -> dict[str, Any]:
    return {
        "vessel": {"name": "mss_supply"},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "zenoh": {"multicast_scouting": False, "prefix": PREFIX, **zenoh_table},
        "commands": {"accept": ["mode", "setpoint", "tau"]},
        "log": {"path": ""},
    }


def client(port: int, user: str | None = None, password: str | None = None) -> zenoh.Session:
    conf: dict[str, Any] = {
        "mode": "peer",
        "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"]},
        "scouting": {"multicast": {"enabled": False}},
    }
    if user is not None:
        conf["transport"] = {"auth": {"usrpwd": {"user": user, "password": password}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(conf)))


def status(session: zenoh.Session) -> dict[str, Any] | None:
    replies = [r for r in session.get(f"{PREFIX}/status", timeout=2.0) if r.ok is not None]
    return json.loads(replies[0].ok.payload.to_bytes()) if replies else None


@pytest.fixture
def gateway(tmp_path: Path) -> Iterator[tuple[GatewayService, int]]:
    (tmp_path / "users.txt").write_text("captain:aye-aye\nwatch:look-only\n")
    port = free_port()
    t = tables({"listen": [f"tcp/127.0.0.1:{port}"], "users_file": "users.txt", "commanders": ["captain"]})
    service = GatewayService(parse_config(t, base_dir=tmp_path))
    service.start()  # opens its own session from the config: auth and ACL are the gateway's, not the test's
    loop = threading.Thread(target=service.run)
    loop.start()
    try:
        yield service, port
    finally:
        service.stop_event.set()
        loop.join()
        service.close()


def test_an_unauthenticated_session_cannot_even_connect(gateway: tuple[GatewayService, int]) -> None:
    service, port = gateway
    for user, password in ((None, None), ("captain", "wrong"), ("stranger", "aye-aye")):
        s = client(port, user, password)
        try:
            assert list(s.info.peers_zid()) == [], f"{user} got in"
            s.put(f"{PREFIX}/mode", json.dumps("manual"))
            assert status(s) is None
        finally:
            s.close()
    assert service.pipeline.mode == "standby"


def test_only_the_commander_changes_mode_setpoint_or_tau(gateway: tuple[GatewayService, int]) -> None:
    service, port = gateway
    watch = client(port, "watch", "look-only")
    captain = client(port, "captain", "aye-aye")
    try:
        first = wait_for(lambda: status(watch), 10.0)
        assert first is not None, "an authenticated user may read the status"
        assert first["mode"] == "standby"
        # the watch tries everything first, on its own (ordered) link...
        watch.put(f"{PREFIX}/mode", json.dumps("manual"))
        watch.put(f"{PREFIX}/tau", json.dumps({"X": 1e4, "Y": 0.0, "N": 0.0}))
        watch.put(f"{PREFIX}/setpoint", json.dumps({"north_m": 5.0, "east_m": 0.0, "heading_deg": 0.0}))
        # ...then the captain commands manual and a τ (a τ is taken in manual only): once that is taken,
        # the watch's puts would have been too
        captain.put(f"{PREFIX}/mode", json.dumps("manual"))
        assert wait_for(lambda: (s := status(captain)) is not None and s["mode"] == "manual", 10.0)
        captain.put(f"{PREFIX}/tau", json.dumps({"X": 2e4, "Y": 0.0, "N": 0.0}))
        taken = wait_for(
            lambda: (s := status(watch)) is not None and s["commands"]["accepted"].get("tau") == 1 and s, 10.0
        )
        assert taken, "the commander's τ was not taken"
        assert service.pipeline.manual_tau.tolist() == [2e4, 0.0, 0.0]
        assert taken["commands"]["accepted"] == {"mode": 1, "tau": 1}
        assert not taken["commands"].get("refused")
        assert service.pipeline._pending_setpoint is None and service.pipeline.setpoint is None
    finally:
        watch.close()
        captain.close()


def _listening_addresses(pid: str = "self") -> set[tuple[str, str]]:
    """(socket inode, local address) of a process's listening TCP sockets (from /proc)."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = set()
    for table, width in ((f"/proc/{pid}/net/tcp", 8), (f"/proc/{pid}/net/tcp6", 32)):
        with open(table) as f:
            for line in f.readlines()[1:]:
                cols = line.split()
                if cols[3] == "0A" and cols[9] in inodes:  # LISTEN
                    found.add((cols[9], cols[1].split(":")[0][:width]))
    return found


LOOPBACK = {"0100007F", "00000000000000000000000001000000"}  # 127.0.0.1, ::1 as /proc writes them


@pytest.mark.skipif(not Path("/proc/self/net/tcp").exists(), reason="needs Linux /proc")
def test_the_default_session_listens_on_loopback_only(tmp_path: Path) -> None:
    config = parse_config(tables({}), base_dir=tmp_path)
    assert config.zenoh.listen == ("tcp/127.0.0.1:0",)
    before = _listening_addresses()
    session = open_session(zenoh_config(config.zenoh))
    try:
        opened = {address for _, address in _listening_addresses() - before}
        assert opened, "the session listens somewhere"
        assert opened <= LOOPBACK, f"listening beyond loopback: {opened}"
    finally:
        session.close()


def test_the_commands_sessions_listen_on_this_computer_only_unless_told(tmp_path: Path) -> None:
    """`dpgw demo`'s gateway takes mode, setpoint and τ from its peers: left to Zenoh's own default it
    listened on every interface, and a machine on the LAN could engage DP. Every command's session listens
    where the gateway's default does, unless ``--zenoh-listen`` says otherwise."""
    import argparse

    from dpgw import cli_demo
    from dpgw.cli_zenoh import LOOPBACK_LISTEN, listen_endpoints
    from gateway.config.defaults import DEFAULTS
    from simulator.scenarios import get_scenario

    assert DEFAULTS["zenoh"]["listen"] == [LOOPBACK_LISTEN]
    assert listen_endpoints([]) == [LOOPBACK_LISTEN]  # dpgw sim --zenoh, paced dpgw replay, dpgw listen
    assert listen_endpoints(["tcp/192.168.10.5:7447"]) == ["tcp/192.168.10.5:7447"]
    p = argparse.ArgumentParser()
    cli_demo.add_arguments(p)
    scenario = get_scenario("fossen_strand_1999")
    demo = cli_demo.demo_config(scenario, "/dev/null", p.parse_args(["--out", "x.mcap"]))
    assert demo["zenoh"]["listen"] == [LOOPBACK_LISTEN]
    asked = cli_demo.demo_config(
        scenario, "/dev/null", p.parse_args(["--out", "x.mcap", "--zenoh-listen", "tcp/0.0.0.0:0"])
    )
    assert asked["zenoh"]["listen"] == ["tcp/0.0.0.0:0"]


@pytest.mark.skipif(not Path("/proc/self/net/tcp").exists(), reason="needs Linux /proc")
def test_dpgw_listen_opens_no_port_beyond_loopback() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "listen", "--duration", "60", "--no-scouting"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        opened = wait_for(lambda: {address for _, address in _listening_addresses(str(proc.pid))}, 60.0)
        assert opened, "dpgw listen opened no listening socket"
        assert opened <= LOOPBACK, f"listening beyond loopback: {opened}"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_unsigned_mavlink_commands_warn_at_start_up(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    t = tables({})
    t["sources"].append(
        {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"],
         "commands": True, "allow_unsigned": True}
    )  # fmt: skip
    with caplog.at_level("WARNING", logger="dpgw"):
        GatewayService(parse_config(t, base_dir=tmp_path))
    assert any("thr: thruster commands go out UNSIGNED" in r.getMessage() for r in caplog.records)
