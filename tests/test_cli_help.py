"""What a new user reads: every help page, its examples, and the one-line errors of a Zenoh endpoint."""

from __future__ import annotations

import argparse
import itertools
import json
import re
import shlex
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port

from dpgw import cli_run
from dpgw.cli import build_parser
from gateway.bus import BusError, isolated_config, make_config, open_session


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


# --- help pages ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", sorted(_subparsers()))
def test_every_option_has_help(command: str) -> None:
    parser = _subparsers()[command]
    missing = [a.option_strings or a.dest for a in parser._actions if not a.help]
    assert not missing, f"dpgw {command}: options without help: {missing}"


@pytest.mark.parametrize("command", ["", *sorted(_subparsers())])
def test_help_is_plain_text(command: str) -> None:
    """Help pages are printed as written: no reST or Markdown markup (``x``, :class:`x`, `x`)."""
    parser = _subparsers()[command] if command else build_parser()
    text = parser.format_help()
    assert "``" not in text and not re.search(r":\w+:`", text) and "`" not in text, text


def test_descriptions_wrap_and_examples_keep_their_layout() -> None:
    text = _subparsers()["replay"].format_help()
    width = max(len(line) for line in text.splitlines())
    assert width <= 120  # argparse's width: $COLUMNS or 80 less 2, never one line per paragraph
    assert "       --observer passive:wave_period_s=2.5@long" in text  # a continuation line, as written


@pytest.mark.parametrize("columns", ["80", "200"])
def test_a_continued_example_is_never_cut_by_its_comment(
    columns: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An example too wide for the terminal gets its comment on a line of its own above it. For the second
    line of a command continued with "\\" the comment went between the two lines: pasted, the command
    ended at the comment and its `--out trial.mcap` ran as a command of its own. Every page, two widths."""
    monkeypatch.setenv("COLUMNS", columns)
    for name, parser in _subparsers().items():
        lines = parser.format_help().splitlines()
        for above, below in itertools.pairwise(lines):
            if above.rstrip().endswith("\\"):
                assert below.strip().startswith("--"), (name, above, below)


def test_demo_help_lists_the_scenarios() -> None:
    from dpgw.scenario_names import SCENARIO_NAMES

    text = " ".join(_subparsers()["demo"].format_help().split())
    for name in SCENARIO_NAMES:
        assert name in text


def test_replay_settle_default_is_the_one_used() -> None:
    """No settle time on the command line: the summary and the report both use the report's rule."""
    from dpgw.cli_replay import default_settle_s
    from gateway.report.metrics import SETTLE_FRACTION, SETTLE_MAX_S

    args = build_parser().parse_args(["replay", "x.mcap", "--out", "y.mcap"])
    assert args.settle is None
    help_text = next(a.help for a in _subparsers()["replay"]._actions if a.dest == "settle")
    assert help_text is not None
    assert f"{SETTLE_FRACTION:.0%}".replace("%", " %") in help_text.replace("%%", "%")
    assert f"{SETTLE_MAX_S:.0f} s" in help_text
    assert default_settle_s(100.0) == pytest.approx(10.0) and default_settle_s(3600.0) == SETTLE_MAX_S
    # a 10 Hz span of 300 s ends one interval short: its settle time reads 30 s, not 29.99 s
    assert default_settle_s(299.9) == 30.0


@pytest.mark.skipif(shutil.which("jq") is None, reason="jq not installed")
def test_listen_jq_example_works_as_printed() -> None:
    """The epilog's `dpgw listen ... --json | jq ...` prints the estimate's eta, not null."""
    epilog = _subparsers()["listen"].epilog or ""
    line = next(ln for ln in epilog.splitlines() if "| jq" in ln)
    listen_part, jq_part = line.split("|", 1)
    key = shlex.split(listen_part)[2]
    port = free_port()
    pub = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "dpgw", *shlex.split(listen_part)[1:], "--count", "1", "--no-scouting",
             "--connect", f"tcp/127.0.0.1:{port}", "--duration", "20"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        deadline = time.monotonic() + 20
        while proc.poll() is None and time.monotonic() < deadline:
            pub.put(key, json.dumps({"stamp_ns": 1, "eta": [1.5, -2.0, 0.25]}))
            time.sleep(0.2)
        out, err = proc.communicate(timeout=10)
    finally:
        pub.close()
    assert proc.returncode == 0, err
    jq = subprocess.run(shlex.split(jq_part.split("#")[0]), input=out, capture_output=True, text=True)
    assert jq.returncode == 0, jq.stderr
    assert json.loads(jq.stdout) == [1.5, -2.0, 0.25]


# --- Zenoh errors: the flag or config key, the endpoint, what to do; never Rust internals ----------------


def _assert_one_clear_line(stderr: str) -> None:
    assert "Traceback" not in stderr and ".rs:" not in stderr and ".cargo" not in stderr, stderr
    assert len(stderr.strip().splitlines()) == 1, stderr


def test_listen_on_a_port_in_use_names_flag_endpoint_and_fix() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        endpoint = f"tcp/127.0.0.1:{taken.getsockname()[1]}"
        p = subprocess.run(
            [sys.executable, "-m", "dpgw", "listen", "--no-scouting", "--listen", endpoint,
             "--duration", "5"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert p.returncode == 2
    _assert_one_clear_line(p.stderr)
    assert p.stderr.startswith(f"dpgw listen: --listen: cannot listen on {endpoint}: address in use")
    assert "choose another port" in p.stderr


def test_run_on_a_port_in_use_names_config_key(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        endpoint = f"tcp/127.0.0.1:{taken.getsockname()[1]}"
        cfg = tmp_path / "vessel.toml"
        cfg.write_text(
            '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
            'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\nwave_period_s = 9.0\n'
            f'[zenoh]\nlisten = ["{endpoint}"]\nmulticast_scouting = false\n[log]\npath = ""\n'
        )
        p = subprocess.run(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "5"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert p.returncode == 2
    _assert_one_clear_line(p.stderr)
    assert f"{cfg}: zenoh.listen: cannot listen on {endpoint}: address in use" in p.stderr


@pytest.mark.parametrize(
    ("kwargs", "key", "words"),
    [
        ({"listen": ["127.0.0.1:7447"]}, "listen", ["'127.0.0.1:7447' is not an endpoint", "tcp/"]),
        ({"listen": ["tcp/127.0.0.1:99999"]}, "listen", ["tcp/127.0.0.1:99999: invalid port", "65535"]),
        ({"connect": ["foo/127.0.0.1:1"]}, "connect", ["foo/127.0.0.1:1: unknown protocol 'foo'"]),
        ({"listen": ["tcp/192.0.2.1:7447"]}, "listen", ["tcp/192.0.2.1:7447: not an address of this"]),
        (
            {"mode": "client", "connect": ["tcp/127.0.0.1:1"]},
            "connect",
            ["cannot connect to tcp/127.0.0.1:1"],
        ),
    ],
)
def test_bus_errors_name_the_setting_and_endpoint(kwargs: dict[str, Any], key: str, words: list[str]) -> None:
    with pytest.raises(BusError) as info:
        session = open_session(make_config(multicast_scouting=False, **kwargs))
        session.close()
    exc = info.value
    assert exc.key == key and exc.fix
    for w in words:
        assert w in str(exc)
    assert str(exc).startswith(f"zenoh.{key}: ")
    assert exc.describe({key: f"--{key}"}).startswith(f"--{key}: ")
    assert ".rs:" not in str(exc) and ".cargo" not in str(exc)


# --- dpgw run: the start-up line and the -v status -------------------------------------------------------


def test_run_prints_a_start_up_line(tmp_path: Path) -> None:
    zport = free_port()
    log = tmp_path / "trial.mcap"
    cfg = tmp_path / "vessel.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:0"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n[observer]\nwave_period_s = 9.0\n'
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{zport}"]\nmulticast_scouting = false\n[log]\npath = "{log}"\n'
    )

    def start_up_line() -> str:
        """Run the gateway for half a second; its start-up line."""
        p = subprocess.run(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), "--duration", "0.5"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert p.returncode == 0, p.stderr
        return next(ln for ln in p.stderr.splitlines() if ln.startswith("dpgw run: vessel"))

    line = start_up_line()
    assert re.search(r"sources gps udp://127\.0\.0\.1:0, port \d+;", line), line
    assert f"listen tcp/127.0.0.1:{zport}" in line and "prefix dp/mss_supply" in line
    assert f"log {log}" in line
    # restarted (systemd, a reboot): the log goes on in the next file of the set; the first is kept
    first = log.read_bytes()
    line = start_up_line()
    assert f"log {tmp_path / 'trial_0001.mcap'}" in line, line
    assert log.read_bytes() == first


@pytest.mark.parametrize(
    ("url", "asks"),
    [("udp://127.0.0.1:0", True), ("udpin:0.0.0.0:0", True), ("tcp-listen://[::]:0?max=1", True),
     ("udpin:0.0.0.0:555", False), ("udp://0.0.0.0:10110", False), ("udp://[fe80::0:1]:14550", False),
     ("tcp-listen://[::0]:5760", False), ("serial:///dev/ttyUSB0", False)],
)  # fmt: skip
def test_the_start_up_line_gives_the_bound_port_only_where_the_url_asked_for_any(
    url: str, asks: bool
) -> None:
    """Before: any ':0' in the URL, so 'thrusters udpin:0.0.0.0:555, port 555' (docs/cli.md: the port it
    bound when the URL asked for port 0)."""
    from types import SimpleNamespace

    from gateway.config import parse_config

    tables = {"vessel": {"name": "mss_supply"},
              "sources": [{"name": "gps", "url": "udp://127.0.0.1:10110", "protocol": "nmea",
                           "roles": ["position", "heading"]}]}  # fmt: skip
    config = parse_config(tables, base_dir=Path("."))
    service = SimpleNamespace(_sources=[SimpleNamespace(name="mav", url=url, port=40123)], log=None)
    line = cli_run.start_up_line(config, service, None)  # type: ignore[arg-type]
    assert (f"mav {url}, port 40123;" in line) is asks and (f"mav {url};" in line) is not asks, line


@pytest.mark.parametrize("scouting", [True, False])
def test_the_start_up_line_says_what_a_zenoh_port_0_means(scouting: bool) -> None:
    """A HIL-bench trial read "listen tcp/127.0.0.1:0" and had no port to connect a console to: Zenoh
    does not report the port it bound, so the line says how peers find the session, and how to pin it."""
    from types import SimpleNamespace

    from gateway.config import parse_config

    def line(listen: str) -> str:
        tables = {"vessel": {"name": "mss_supply"},
                  "sources": [{"name": "gps", "url": "udp://127.0.0.1:10110", "protocol": "nmea",
                               "roles": ["position", "heading"]}],
                  "zenoh": {"listen": [listen], "multicast_scouting": scouting}}  # fmt: skip
        config = parse_config(tables, base_dir=Path("."))
        service = SimpleNamespace(_sources=[], log=None)
        return cli_run.start_up_line(config, service, None)  # type: ignore[arg-type]

    said = line("tcp/127.0.0.1:0")
    assert "listen tcp/127.0.0.1:0 (port 0: a free port" in said and "tcp/127.0.0.1:7447" in said, said
    assert ("nobody can connect to it" in said) is not scouting, said
    assert "port 0" not in line("tcp/127.0.0.1:7450") and "port 0" not in line("tcp/[::]:10")


class _FakeService:
    def __init__(self, status: dict[str, Any]) -> None:
        self.stop_event = threading.Event()
        self.status = status

    def last_status(self) -> dict[str, Any]:
        return self.status


def test_verbose_status_line_counts_sentences_not_used_apart_from_the_rejected() -> None:
    """saab-r4.log's receiver over TCP: AIS and $PFEC/GLL/DTM, well-formed but not used. Before: '(63
    rejected)' for a healthy stream, as if its sentences were bad."""
    from wire.codecs.nmea import UNSUPPORTED
    from wire.codecs.nmea_framing import AIS, COMMENT, IEC_61162_450, TAG_BLOCK
    from wire.codecs.nmea_tag import OTHER_TAG_SOURCE

    assert set(cli_run.NOT_USED) == {UNSUPPORTED, AIS, COMMENT, TAG_BLOCK, IEC_61162_450, OTHER_TAG_SOURCE}
    sources = {
        "gyro": {"age_s": 0.0, "received": 154, "rejected": {"ais": 24, "unsupported": 20, "test_jump": 19}},
        "gps": {"age_s": 0.2, "received": 90, "rejected": {"unsupported": 40}},
        "mux": {"age_s": 0.1, "received": 90, "rejected": {"bad_checksum": 2}},
    }
    line = cli_run.status_line({"mode": "standby", "estimates": 5, "sources": sources}, 10.0)
    assert "gyro 154 rx 0.0 s ago (19 rejected, 44 not used)" in line
    assert "gps 90 rx 0.2 s ago (40 not used)" in line
    assert "mux 90 rx 0.1 s ago (2 rejected)" in line


def test_verbose_status_line_times_the_last_disconnect_by_the_wall_clock_not_the_status_stamp() -> None:
    """A link lost 12 s ago (the wall clock, as the transport stamps it) under ``--clock sim``, whose
    status is stamped with a simulation time of 2020: the line says 12 s, not 200 million."""
    lost_ns = time.time_ns() - 12 * 10**9
    sources = {
        "mux": {
            "age_s": 0.1,
            "received": 90,
            "reconnects": 1,
            "last_disconnect": "connection to 10.0.0.5:4001 lost: closed by the server",
            "last_disconnect_ns": lost_ns,
        },
        "gps": {"age_s": 0.2, "received": 90},
    }
    status = {"stamp_ns": 1_577_836_800 * 10**9, "mode": "dp", "estimates": 5, "sources": sources}
    line = cli_run.status_line(status, 10.0)
    assert (
        "mux 90 rx 0.1 s ago (1 reconnect, last lost 12 s ago: connection to 10.0.0.5:4001 lost: closed by "
        "the server), gps 90 rx 0.2 s ago;" in line + ";"
    ), line


def test_verbose_status_line_every_period(capsys: pytest.CaptureFixture[str]) -> None:
    status = {
        "mode": "dp",
        "estimates": 340,
        "sources": {"gps": {"age_s": 0.1, "received": 35, "rejected": {"checksum": 2}}},
        "alarms": ["source gyro: stale (3.0 s without data)"],
    }
    service = _FakeService(status)
    thread = threading.Thread(target=cli_run.report_status, args=(service, 0.02))
    thread.start()
    deadline = time.monotonic() + 10
    lines: list[str] = []
    while len(lines) < 2 and time.monotonic() < deadline:
        lines += capsys.readouterr().err.splitlines()
        time.sleep(0.01)
    service.stop_event.set()
    thread.join(timeout=5)
    assert not thread.is_alive()
    assert len(lines) >= 2
    assert lines[0].startswith("dpgw run: ") and "\n" not in lines[0]
    for part in ("dp", "340 estimates", "gps 35 rx 0.1 s ago (2 rejected)", "alarms: source gyro: stale"):
        assert part in lines[0]
