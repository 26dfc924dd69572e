"""Words of the command line a user trial found odd: the thruster feedback's state changes, log lines
without the program's name, and the simulator's thruster frames counted as if sent. Real processes."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

from conftest import free_port

from gateway.references.state import StateChange

ROOT = Path(__file__).resolve().parents[1]


def test_a_thruster_links_state_change_reads_like_a_reference_line() -> None:
    """Its role and usual source name are both "thrusters": "thrusters reference thrusters: stale -> ok"
    read as a slip."""
    change = StateChange(0, "thrusters", "thrusters", "stale", "ok", "")
    assert change.text == "reference thrusters (thruster feedback): stale -> ok"
    assert StateChange(0, "dgps1", "position", "ok", "rejected", "jump").text == (
        "position reference dgps1: ok -> rejected: jump"
    )


def run_python(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)


def test_a_commands_log_lines_carry_its_name() -> None:
    """``dpgw demo`` (and every command that sets no logging of its own) printed the gateway's warnings
    bare amid its own ``dpgw demo: ...`` lines; ``dpgw run``'s own setting replaces the default, one line
    per record (not two)."""
    p = run_python(
        "import logging; from dpgw import journal; journal.default_logging('demo'); "
        "logging.getLogger('dpgw').warning('heading reference gyro1: stale -> ok')"
    )
    assert p.stderr == "dpgw demo: heading reference gyro1: stale -> ok\n", p.stderr
    p = run_python(
        "import logging; from dpgw import journal; journal.default_logging('run'); "
        "journal.configure_logging(logging.WARNING); logging.getLogger('dpgw').warning('x')"
    )
    assert p.stderr == "x\n", p.stderr


def test_a_demos_stderr_lines_all_carry_its_name(tmp_path: Path) -> None:
    """A short demo, its log in a folder to be made: every stderr line starts ``dpgw demo: ``, the thruster
    link's state change among them in the words of the other references, and the folder made is said."""
    out = tmp_path / "trials" / "demo.mcap"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "10", "--no-foxglove", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    lines = p.stderr.splitlines()
    assert lines and all(line.startswith("dpgw demo: ") for line in lines), p.stderr
    assert "dpgw demo: reference thrusters (thruster feedback): stale -> ok" in lines, p.stderr
    assert "dpgw demo: position reference dgps1: stale -> ok" in lines, p.stderr
    assert f"dpgw demo: made the log's folder {out.parent} (it did not exist)" in lines, p.stderr


def test_sim_says_which_frames_no_output_took() -> None:
    """``dpgw sim --nmea ...`` without ``--mavlink``: the thrusters' MAVLink frames are made but go nowhere;
    the summary counted them like the sent ones."""
    port = free_port(socket.SOCK_DGRAM)  # (nobody listens: UDP sends regardless)
    argv = [sys.executable, "-m", "dpgw", "sim", "--scenario", "mss_supply_wind", "--duration", "20",
            "--nmea", f"udp://127.0.0.1:{port}"]  # fmt: skip
    p = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    lines = {ln.split()[0]: ln for ln in p.stdout.splitlines() if ln.startswith("  ") and "frames" in ln}
    assert lines["thrusters"].endswith("(not sent on a link: no --nmea/--mavlink output takes them)"), (
        p.stdout
    )
    assert "not sent" not in lines["dgps1"] and "not sent" not in lines["gyro1"], p.stdout
    result = json.loads(subprocess.run([*argv, "--json"], cwd=ROOT, capture_output=True, text=True).stdout)
    assert result["not_sent"] == {"thrusters": result["emissions"]["thrusters"]}, result


def test_sim_says_the_tlog_holds_the_frames_no_link_sent(tmp_path: Path) -> None:
    """``--tlog`` alone: the thrusters' frames went to no link but into the tlog, and the summary said
    "not sent" beside "tlog: ... (317 records)"; it says where they are."""
    argv = [sys.executable, "-m", "dpgw", "sim", "--scenario", "torsetnes_2004", "--duration", "10",
            "--tlog", str(tmp_path / "t.tlog")]  # fmt: skip
    p = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    lines = {ln.split()[0]: ln for ln in p.stdout.splitlines() if ln.startswith("  ") and "frames" in ln}
    assert lines["thrusters"].endswith("output takes them; recorded in --tlog)"), p.stdout
    assert "recorded in --tlog" not in lines["dgps1"], p.stdout
