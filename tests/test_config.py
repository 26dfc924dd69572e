"""`gateway.config`: the examples load, defaults fill in, paths resolve, and every mistake is reported.

A bad config raises one `ConfigError` that lists every problem as ``FILE: key.path: what (expected, got)``.
"""

from __future__ import annotations

import copy
import math
import shutil
import socket
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gateway.config import (
    ConfigError,
    GatewayConfig,
    default_config,
    format_problems,
    load_config,
    parse_config,
)
from gateway.config.defaults import DEFAULTS
from observers.passive_tuning import PassiveTuning

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

BASE_TOML = """
[vessel]
name = "mss_supply"

[[sources]]
name = "dgps1"
url = "serial:///dev/ttyUSB0?baud=4800"
protocol = "nmea"
roles = ["position"]
lever_arm_m = [10.0, -2.0, -20.0]

[[sources]]
name = "gyro1"
url = "serial:///dev/ttyUSB1?baud=4800"
protocol = "nmea"
roles = ["heading"]

[[sources]]
name = "thr"
url = "udpin:0.0.0.0:14550"
protocol = "mavlink"
roles = ["thrusters"]
"""

KEY = "ab" * 32  # a valid 64-hex-character signing key


def base() -> dict[str, Any]:
    return tomllib.loads(BASE_TOML)


def put(data: dict[str, Any], path: str, value: Any) -> None:
    """Set (or with value DELETE remove) a dotted path; integers index arrays: ``sources.0.url``."""
    *parents, last = path.split(".")
    node: Any = data
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    if isinstance(node, list):
        node[int(last)] = value
    elif value is DELETE:
        del node[last]
    else:
        node[last] = value


DELETE = object()


def parse(data: dict[str, Any], tmp_path: Path) -> GatewayConfig:
    return parse_config(data, base_dir=tmp_path, where="bad.toml")


def problems_of(data: dict[str, Any], tmp_path: Path) -> list[str]:
    with pytest.raises(ConfigError) as info:
        parse(data, tmp_path)
    return info.value.problems


# --- the examples -----------------------------------------------------------------------------------------


def example_files() -> list[Path]:
    return sorted(EXAMPLES.glob("*.toml"))


@pytest.mark.parametrize("path", example_files(), ids=lambda p: p.name)
def test_example_passes_the_check_command(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`dpgw run --config FILE --check`, as examples/README.md prints it, accepts every example: the
    command also checks what loading does not (the optional packages an enabled output needs)."""
    from dpgw.cli import main

    assert main(["run", "--config", str(path), "--check"]) == 0
    assert f"{path.name}: ok" in capsys.readouterr().out


def _doc_config_snippets() -> list[tuple[str, str]]:
    """The TOML blocks of docs/*.md that are gateway config tables (not vessel, fault or study files)."""
    import re

    sections = {"[zenoh]", "[commands]", "[ros2]", "[keelson]", "[foxglove]", "[integrity]", "[control]"}
    snippets = []
    for doc in sorted((ROOT / "docs").glob("*.md")):
        for block in re.findall(r"```toml\n(.*?)```", doc.read_text(encoding="utf-8"), re.S):
            first = next(line.strip() for line in block.splitlines() if line.strip())
            if first in sections:
                snippets.append((doc.name, block))
    return snippets


@pytest.mark.parametrize("snippet", _doc_config_snippets(), ids=lambda s: s[0])
def test_config_snippets_in_the_docs_are_valid(snippet: tuple[str, str], tmp_path: Path) -> None:
    """A config table the docs show, added to a working config, loads as printed (a users file it names
    is made, holding the users it names)."""
    data = base() | tomllib.loads(snippet[1])
    users = data.get("zenoh", {}).get("users_file")
    if users:
        names = [*data["zenoh"].get("commanders", []), "console"]
        (tmp_path / users).write_text("".join(f"{n}:secret-{n}\n" for n in names))
    parse(data, tmp_path)


def test_the_docs_have_config_snippets() -> None:
    assert {name for name, _ in _doc_config_snippets()} >= {"ros2.md", "security.md"}


def test_there_are_examples() -> None:
    names = {p.name for p in example_files()}
    assert {"two_serial_nmea_mavlink.toml", "nmea_udp_multiplexer.toml", "ardupilot_boat.toml"} <= names


@pytest.mark.parametrize("path", example_files(), ids=lambda p: p.name)
def test_example_loads_without_opening_anything(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Loading checks URLs for syntax only: no socket is made, no device opened (they need not exist)."""

    def no_socket(*args: object, **kwargs: object) -> None:
        raise AssertionError("loading a config must not open a socket")

    monkeypatch.setattr(socket, "socket", no_socket)
    config = load_config(path)
    assert config.path == path.resolve()
    assert config.sources_for("position") and config.sources_for("heading")
    assert config.observer.tuning is not None and not config.observer.failed_checks
    assert config.zenoh.prefix == f"dp/{config.vessel.name}"


def test_two_serial_example() -> None:
    c = load_config(EXAMPLES / "two_serial_nmea_mavlink.toml")
    assert c.vessel.name == "mss_supply" and c.vessel_source == "mss_supply"
    dgps, gyro, thr = c.sources
    assert (dgps.transport, dgps.url, dgps.roles) == (
        "serial",
        "serial:///dev/ttyUSB0?baud=4800",
        ("position",),
    )
    assert dgps.lever_arm_m == (10.0, -2.0, -20.0)
    assert (gyro.transport, gyro.roles, gyro.timeout_s) == ("serial", ("heading",), 1.0)
    assert (thr.protocol, thr.transport, thr.roles, thr.system_id) == (
        "mavlink",
        "pymavlink",
        ("thrusters",),
        1,
    )
    assert c.observer.tuning.omega0 == pytest.approx(2 * math.pi / 8.0)
    assert c.log.path == EXAMPLES / "logs" / "supply.mcap"
    assert c.datum.first_fix


def test_multiplexer_example() -> None:
    c = load_config(EXAMPLES / "nmea_udp_multiplexer.toml")
    (mux,) = c.sources
    assert mux.url == "udp://0.0.0.0:10110" and mux.transport == "udp"
    assert set(mux.roles) == {"position", "heading"}
    assert (c.datum.lat_deg, c.datum.lon_deg, c.datum.first_fix) == (59.4, 10.5, False)
    assert c.zenoh.mode == "client" and c.zenoh.connect == ("tcp/192.168.1.10:7447",)


def test_ardupilot_example() -> None:
    c = load_config(EXAMPLES / "ardupilot_boat.toml")
    (ap,) = c.sources
    assert set(ap.roles) == {"position", "heading", "thrusters"}
    assert ap.ardupilot is not None
    assert dict(ap.ardupilot.esc) == {1: 1, 2: 2, 3: 3}
    assert dict(ap.ardupilot.servo) == {1: 1, 3: 2}
    ids = {t.id for t in c.vessel.thrusters}
    assert set(ap.ardupilot.esc.values()) <= ids


def test_an_esc_on_a_thruster_that_reverses_is_noted(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """ESC telemetry rpm has no sign: the example names the bow tunnel's (id 3, reverses) motor output, so
    `--check` notes nothing; without that line, ESC 3 gets a note (and a warning at start-up) that says
    what to add; the azimuths on ESC 1 and 2 turn instead and never get one."""
    from dpgw.cli import main

    def notes(path: Path) -> list[str]:
        assert main(["run", "--config", str(path), "--check"]) == 0
        return [line for line in capsys.readouterr().out.splitlines() if line.startswith("note:")]

    assert notes(EXAMPLES / "ardupilot_boat.toml") == []
    text = (EXAMPLES / "ardupilot_boat.toml").read_text()
    lines = [line for line in text.splitlines() if not line.startswith("esc_direction_servo")]
    assert len(lines) == len(text.splitlines()) - 1
    bare = tmp_path / "boat.toml"
    bare.write_text("\n".join(lines) + "\n")
    assert notes(bare) == [
        "note: sources.ardupilot.ardupilot.esc: ESC 3 reports thruster 3, which reverses "
        "(min_thrust_n -1 N), but ESC telemetry rpm has no sign: its thrust is taken as ahead also when "
        "it runs astern (name its motor output in sources.ardupilot.ardupilot.esc_direction_servo, "
        "e.g. {3 = channel})"
    ]


def test_esc_direction_servo_forms_and_notes(tmp_path: Path) -> None:
    """`esc_direction_servo` takes a channel (neutral 1500 µs) or {servo, neutral_us}; the dead band is
    25 µs unless said. A reversing thruster's ESC is noted only while it has no direction source."""
    from gateway.config import config_notes

    d = base()
    put(d, "sources.2.ardupilot", {"esc": {"1": 4, "2": 5, "3": 1}, "esc_direction_servo": {"1": 9}})
    c = parse(d, tmp_path)
    ap = c.source("thr").ardupilot
    assert ap is not None and dict(ap.esc_direction_servo) == {1: (9, 1500.0)} and ap.esc_dead_band_us == 25.0
    reversing = sorted(t.id for t in c.vessel.thrusters if t.min_thrust_n < 0)
    assert 4 in reversing and 5 in reversing
    assert [n.split(":")[1].strip().split(" reports")[0] for n in config_notes(c)] == ["ESC 2"]
    put(
        d,
        "sources.2.ardupilot",
        {
            "esc": {"1": 4, "2": 5},
            "esc_direction_servo": {"1": 9, "2": {"servo": 10, "neutral_us": 1520}},
            "esc_dead_band_us": 40,
        },
    )
    c = parse(d, tmp_path)
    ap = c.source("thr").ardupilot
    assert ap is not None and dict(ap.esc_direction_servo) == {1: (9, 1500.0), 2: (10, 1520.0)}
    assert ap.esc_dead_band_us == 40.0 and config_notes(c) == []


def test_a_signing_key_in_a_config_everyone_may_read_is_noted(tmp_path: Path) -> None:
    """The install step put the config at mode 0644: the MAVLink signing key in it, which lets whoever
    reads it drive the thrusters, readable by every user. ``--check`` and start-up now say so."""
    import os

    from gateway.config import config_notes

    path = tmp_path / "vessel.toml"
    text = BASE_TOML.replace('name = "thr"', f'name = "thr"\nsigning_key = "{KEY}"', 1)
    assert text != BASE_TOML
    path.write_text(text)
    path.chmod(0o644)
    notes = [n for n in config_notes(load_config(path)) if "signing_key" in n]
    assert len(notes) == 1 and "sources.thr.signing_key" in notes[0] and "mode 0644" in notes[0], notes
    assert KEY not in notes[0]
    path.chmod(0o640)
    assert not [n for n in config_notes(load_config(path)) if "signing_key" in n]
    path.chmod(0o644)  # without a key, nothing to say
    path.write_text(BASE_TOML)
    assert os.stat(path).st_mode & 0o004 and config_notes(load_config(path)) == []


@pytest.mark.parametrize(
    ("zenoh", "reach"),
    [
        ({}, "any user or program on this computer"),
        ({"listen": ["tcp/127.0.0.1:7447", "tcp/[::1]:7448"]}, "any user or program on this computer"),
        ({"listen": ["tcp/192.168.10.5:7447"]}, "anyone on the network that reaches listen tcp/192.168.10.5"),
        ({"mode": "client", "connect": ["tcp/10.0.0.1:7447"]}, "reaches connect tcp/10.0.0.1:7447"),
        ({"connect": ["tcp/127.0.0.1:7447"]}, "any user or program on this computer"),  # the HIL bench's
    ],
)
def test_commands_anyone_may_give_are_noted(zenoh: dict[str, Any], reach: str, tmp_path: Path) -> None:
    """A HIL-bench trial set ``[commands] accept`` with no ``commanders``: every Zenoh peer that reaches
    the session may then engage DP or push the thrusters, and ``--check`` said nothing. It says so now,
    with who can reach the session; naming the commanders (or taking no commands) says nothing."""
    from gateway.config import config_notes
    from gateway.config.summary import open_commands_note

    base = {"vessel": {"name": "mss_supply"},
            "sources": [{"name": "gps", "url": "udp://127.0.0.1:10110", "protocol": "nmea",
                         "roles": ["position", "heading"]}]}  # fmt: skip
    open_ = parse_config({**base, "zenoh": zenoh, "commands": {"accept": ["mode", "tau"]}}, base_dir=tmp_path)
    note = open_commands_note(open_)
    assert note is not None and reach in note and "zenoh.commanders" in note, note
    assert "['mode', 'tau']" in note
    # start-up warns (config_notes) of a session the network reaches; --check of this computer's too
    network = "this computer" not in reach
    assert (note in config_notes(open_)) is network
    assert not [n for n in config_notes(parse_config({**base, "zenoh": zenoh}, base_dir=tmp_path))
                if n.startswith("commands")]  # fmt: skip
    (tmp_path / "users.txt").write_text("bridge:secret\n")
    (tmp_path / "users.txt").chmod(0o600)
    named = {**zenoh, "users_file": "users.txt", "commanders": ["bridge"]}
    closed = parse_config({**base, "zenoh": named, "commands": {"accept": ["mode"]}}, base_dir=tmp_path)
    assert not [n for n in config_notes(closed) if n.startswith("commands")]


def test_systemd_unit() -> None:
    unit = (EXAMPLES / "dpgw.service").read_text()
    for line in (
        "ExecStart=",
        "dpgw run --config /etc/dpgw/vessel.toml",
        "Restart=always",  # a clean exit on SIGHUP/SIGINT/kill is restarted too (examples/README.md)
        "RestartSec=",
        "User=dpgw",
        "SupplementaryGroups=dialout",
        "KillSignal=SIGTERM",
        "TimeoutStopSec=",
        "After=network-online.target",
        "Wants=network-online.target",
        "--wait-for-ports",  # a USB adapter late at boot must not stop the service (docs/sources.md)
        "Environment=NUMBA_CACHE_DIR=/var/cache/dpgw",  # the venv is read-only under ProtectSystem=strict
        "CacheDirectory=dpgw",
        "Type=notify",  # READY and the watchdog (dpgw.sd_notify)
        "WatchdogSec=",
    ):
        assert line in unit, line
    assert (EXAMPLES / "README.md").is_file()


def test_the_units_documentation_is_installed_with_the_package() -> None:
    """Each ``Documentation=`` of the unit is a file that ``pip install`` puts in the venv its ExecStart
    runs from: a path under that venv which pyproject's data-files fills from a file of this checkout.
    It pointed at /opt/dpgw/docs/, which no install makes: ``systemctl help dpgw`` found nothing."""
    unit = (EXAMPLES / "dpgw.service").read_text()
    exec_start = next(ln for ln in unit.splitlines() if ln.startswith("ExecStart="))
    venv = exec_start.removeprefix("ExecStart=").split()[0].removesuffix("/bin/dpgw")
    assert venv.startswith("/") and venv != exec_start, exec_start
    targets = [t for ln in unit.splitlines() if ln.startswith("Documentation=") for t in ln[14:].split()]
    assert targets, "no Documentation= in the unit"
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    data_files: dict[str, list[str]] = pyproject["tool"]["setuptools"]["data-files"]
    installed = {  # what setuptools installs, by its path in the venv (its globs, from the project root)
        f"{folder}/{source.name}": source
        for folder, patterns in data_files.items()
        for pattern in patterns
        for source in ROOT.glob(pattern)
        if source.is_file()
    }
    for target in targets:
        assert target.startswith(f"file://{venv}/"), (target, venv)
        in_venv = target.removeprefix(f"file://{venv}/")
        assert in_venv in installed, (target, sorted(installed))
        assert installed[in_venv].read_text().startswith("# "), installed[in_venv]


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze is not installed")
def test_systemd_unit_verifies(tmp_path: Path) -> None:
    """``systemd-analyze verify`` finds nothing wrong with the unit (directives, values, ExecStart), with
    ExecStart pointing at this installation's dpgw instead of /opt/dpgw/venv."""
    dpgw = Path(sys.executable).parent / "dpgw"
    if not dpgw.is_file():
        pytest.skip(f"no dpgw script beside {sys.executable}")
    unit = (EXAMPLES / "dpgw.service").read_text().replace("/opt/dpgw/venv/bin/dpgw", str(dpgw))
    (tmp_path / "dpgw.service").write_text(unit)
    r = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / "dpgw.service")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0 and not r.stderr.strip(), r.stderr


# --- defaults and paths -----------------------------------------------------------------------------------


def test_defaults_fill_in(tmp_path: Path) -> None:
    c = parse_config(base(), base_dir=tmp_path)
    d = default_config()
    assert c.reference_point_m == (0.0, 0.0)
    assert c.datum.first_fix and c.datum.lat_deg is None
    _, gyro, thr = c.sources
    assert gyro.lever_arm_m == (0.0, 0.0, 0.0)
    assert (gyro.timeout_s, gyro.priority, gyro.allow_missing_checksum) == (2.0, 1, False)
    assert (thr.system_id, thr.signing_key, thr.allow_unsigned, thr.ardupilot) == (None, None, False, None)
    o = c.observer
    assert (o.type, o.rate_hz, o.allow_unchecked) == ("passive", d["observer"]["rate_hz"], False)
    assert o.tuning.omega0 == pytest.approx(2 * math.pi / DEFAULTS["observer"]["wave_period_s"])
    assert o.tuning.omega0 == pytest.approx(PassiveTuning().omega0)
    for key in ("zeta", "zeta_n", "cutoff_ratio", "bias_time_constant_s", "velocity_injection_ratio"):
        assert getattr(o.tuning, key) == getattr(PassiveTuning(), key) == DEFAULTS["observer"][key]
    assert o.tuning.omega_c is None and o.tuning.bias_corner is None and o.tuning.velocity_injection is None
    assert [ch.ok for ch in o.checks] == [True, True]
    z = c.zenoh
    assert (z.mode, z.connect, z.config_file, z.multicast_scouting) == ("peer", (), None, True)
    assert z.listen == ("tcp/127.0.0.1:0",)  # loopback only unless the config says otherwise
    assert (z.users_file, z.user, z.password, z.commanders) == (None, "", "", ())
    assert c.commands.accept == frozenset() and c.commands.max_setpoint_distance_m == 50.0
    assert z.prefix == "dp/mss_supply"
    assert c.log.path == tmp_path.resolve() / "logs" / "dpgw.mcap"
    assert (c.log.rotate_mb, c.log.rotate_minutes, c.log.flush_interval_s, c.log.compression) == (
        1024,
        60,
        1.0,
        "zstd",
    )
    assert c.status.rate_hz == 1.0
    assert c.time.clock == "wall" and not c.time.sim  # at sea the computer's clock, always


def test_the_simulation_clock_is_chosen_in_the_time_table(tmp_path: Path) -> None:
    d = base()
    put(d, "time.clock", "sim")
    assert parse_config(d, base_dir=tmp_path).time.sim


def test_keelson_is_off_unless_enabled_and_takes_its_source_ids(tmp_path: Path) -> None:
    d = base()
    k = parse_config(d, base_dir=tmp_path).keelson
    assert not k.enabled and k.base_path == "keelson" and k.estimate_source_id == "dpgw/estimate"
    put(d, "keelson", {"enabled": True, "entity_id": "my_ship", "sensor_source_id": "gnss/{source}/0"})
    k = parse_config(d, base_dir=tmp_path).keelson
    assert k.enabled and k.entity_id == "my_ship" and k.sensor("dgps1") == "gnss/dgps1/0"


def test_default_config_is_the_parser_defaults(tmp_path: Path) -> None:
    """default_config() (what `dpgw demo` fills in) gives the same config as leaving every key out."""
    d = default_config()
    assert d["sources"] == [] and d["vessel"]["name"] == "mss_supply"
    d["sources"] = base()["sources"]
    from_defaults = parse_config(d, base_dir=tmp_path)
    implicit = parse_config(base(), base_dir=tmp_path)
    for name in ("reference_point_m", "datum", "sources", "observer", "zenoh", "log", "status"):
        assert getattr(from_defaults, name) == getattr(implicit, name), name
    assert default_config("cybership2")["vessel"]["name"] == "cybership2"
    # the tuning is left to the parser, which Froude-scales it for a model (as leaving it out does)
    model = default_config("cybership2")
    model["sources"] = base()["sources"]
    model["sources"][0]["lever_arm_m"] = [0.5, 0.0, -1.0]  # on the 2.5 m model
    assert "wave_period_s" not in model["observer"] and model["observer"]["type"] == "passive"
    implicit_model = {**base(), "vessel": {"name": "cybership2"}, "sources": model["sources"]}
    assert (
        parse_config(model, base_dir=tmp_path).observer
        == parse_config(implicit_model, base_dir=tmp_path).observer
    )
    assert parse_config(model, base_dir=tmp_path).observer.tuning.omega0 == pytest.approx(
        2 * math.pi / 7.0 * math.sqrt(70.0)
    )
    assert default_config("my_ship.toml")["vessel"] == {
        "file": "my_ship.toml",
        "reference_point_m": [0.0, 0.0],
    }
    with pytest.raises(ConfigError, match="sources: empty"):
        parse_config(default_config(), base_dir=tmp_path)


VESSEL_FILE = """
name = "test_boat"
length_m = 2.0
mass_kg = 30.0
M = [[30.0, 0.0, 0.0], [0.0, 40.0, 1.0], [0.0, 1.0, 3.0]]
D = [[2.0, 0.0, 0.0], [0.0, 7.0, 0.1], [0.0, 0.1, 0.5]]

[[thrusters]]
id = 7
kind = "azimuth"
x_m = -0.8
y_m = 0.0
max_thrust_n = 5.0
azimuth_rate_rad_s = 1.0
"""


def test_relative_paths_resolve_against_the_config_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "bench"
    (folder / "vessels").mkdir(parents=True)
    (folder / "vessels" / "boat.toml").write_text(VESSEL_FILE)
    (folder / "zenoh.json5").write_text('{ mode: "peer" }')
    config = folder / "dpgw.toml"
    config.write_text(
        """
[vessel]
file = "vessels/boat.toml"
reference_point_m = [0.1, 0.0]

[[sources]]
name = "replay"
url = "file:data/trial.nmea"
protocol = "nmea"
roles = ["position", "heading"]
lever_arm_m = [0.5, 0.0, -0.5]

[observer]
wave_period_s = 1.0

[zenoh]
config_file = "zenoh.json5"

[log]
path = "out/run.mcap"
"""
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    c = load_config(Path("..") / "bench" / "dpgw.toml")
    assert c.vessel.name == "test_boat" and [t.id for t in c.vessel.thrusters] == [7]
    assert c.vessel_source == str((folder / "vessels" / "boat.toml").resolve())
    assert c.reference_point_m == (0.1, 0.0)
    assert c.sources[0].url == "file://" + (folder / "data" / "trial.nmea").resolve().as_posix()
    assert c.sources[0].transport == "file"
    assert c.zenoh.config_file == (folder / "zenoh.json5").resolve()
    assert c.zenoh.prefix == "dp/test_boat"
    assert c.log.path == (folder / "out" / "run.mcap").resolve()
    assert c.path == config.resolve()


def test_logging_disabled_and_writer_options(tmp_path: Path) -> None:
    d = base()
    d["log"] = {"path": "", "rotate_mb": 0, "rotate_minutes": 0, "compression": "lz4"}
    c = parse(d, tmp_path)
    assert not c.log.enabled and c.log.path is None
    assert c.log.writer_options() == {
        "rotate_bytes": None,
        "rotate_seconds": None,
        "flush_interval_s": 1.0,
        "compression": "lz4",
    }
    d["log"] = {"rotate_mb": 2, "rotate_minutes": 1.5}
    opts = parse(d, tmp_path).log.writer_options()
    assert opts["rotate_bytes"] == 2 * 1024 * 1024 and opts["rotate_seconds"] == 90.0


def test_zenoh_make_builds_a_config_without_opening(tmp_path: Path) -> None:
    """The gateway builds the session's config from the typed values (the config itself imports no bus)."""
    import zenoh

    from gateway.service import zenoh_config

    d = base()
    d["zenoh"] = {"listen": ["tcp/127.0.0.1:0"], "multicast_scouting": False, "prefix": "bench/dp"}
    c = parse(d, tmp_path)
    assert c.zenoh.prefix == "bench/dp"
    assert isinstance(zenoh_config(c.zenoh), zenoh.Config)


def test_values_that_are_fine(tmp_path: Path) -> None:
    d = base()
    put(d, "datum", {"lat_deg": -33.9, "lon_deg": 151.2, "alt_m": 2.0})
    put(d, "sources.2.signing_key", KEY)
    put(d, "sources.2.allow_unsigned", True)
    put(d, "sources.2.url", "/dev/ttyACM0,57600")
    put(d, "sources.0.url", "tcp://192.168.1.20:2000")
    put(d, "sources.1.url", "tcp-listen://:10111")
    d["sources"] += [
        {
            "name": "sim",
            "url": "pty:///tmp/dpgw-gps",
            "protocol": "nmea",
            "roles": ["position"],
            "priority": 2,
        },
        {
            "name": "mux",
            "url": "udpin:0.0.0.0:10110",
            "protocol": "nmea",
            "roles": ["heading"],
            "priority": 3,
        },
        {"name": "usb", "url": "/dev/ttyUSB3,4800", "protocol": "nmea", "roles": ["heading"], "priority": 4},
        {
            "name": "mc",
            "url": "udp://239.1.2.3:10110?iface=eth0",
            "protocol": "nmea",
            "roles": ["heading"],
            "priority": 5,
        },
        {
            "name": "mc2",
            "url": "udp://239.1.2.4:10110",
            "protocol": "nmea",
            "roles": ["heading"],
            "priority": 6,
        },
        {
            "name": "replay",
            "url": "file:logs/trial.nmea?rate=fast",
            "protocol": "nmea",
            "roles": ["heading"],
            "priority": 7,
        },
    ]
    put(d, "sources.1.allow_missing_checksum", True)
    put(d, "sources.2.roles", ["thrusters", "heading"])
    put(d, "sources.2.priority", 2)
    put(d, "sources.2.ardupilot", {"esc": {"1": 1, "2": 2, "4": 4}, "servo": {"1": 1}})
    put(d, "observer", {"omega0": [0.8, 0.8, 0.7], "omega_c": 1.2, "bias_time_constant_s": math.inf})
    put(d, "vessel.reference_point_m", [-5, 0])
    c = parse(d, tmp_path)
    thr = c.source("thr")
    assert thr.signing_key == bytes.fromhex(KEY) and KEY not in repr(thr)
    assert thr.transport == "pymavlink" and thr.ardupilot is not None and thr.ardupilot.esc[4] == 4
    assert [s.name for s in c.sources_for("heading")][:3] == ["gyro1", "thr", "mux"]
    assert c.observer.tuning.omega0 == (0.8, 0.8, 0.7) and c.observer.tuning.omega_c == 1.2
    assert c.datum.fixed and c.datum.alt_m == 2.0
    assert c.sources[1].transport == "tcp-listen"
    assert [c.source(n).transport for n in ("sim", "mux", "usb", "mc", "replay")] == [
        "pty",
        "pymavlink",
        "pymavlink",
        "udp",
        "file",
    ]
    assert (
        c.source("replay").url
        == "file://" + (tmp_path / "logs" / "trial.nmea").resolve().as_posix() + "?rate=fast"
    )


def test_allow_unchecked_loads_a_failing_tuning(tmp_path: Path) -> None:
    d = base()
    d["observer"] = {"wave_period_s": 7, "bias_corner": 0.1, "allow_unchecked": True}
    c = parse(d, tmp_path)
    assert [ch.name for ch in c.observer.failed_checks] == ["spr"]


def test_injection_damping_ratio_zero_turns_the_floor_off(tmp_path: Path) -> None:
    """`injection_damping_ratio = 0` is what `PassiveTuning` and `dpgw tune --injection-damping-ratio 0` call
    "off"; the config refused it ("out of range ... positive"), so a tuning shown by dpgw tune could not be
    written in the config. Zero is taken; a negative value is still refused."""
    d = base()
    d["observer"] = {"wave_period_s": 9, "injection_damping_ratio": 0}
    assert parse(d, tmp_path).observer.tuning.injection_damping_ratio == 0.0
    d["observer"] = {"wave_period_s": 9, "injection_damping_ratio": [0.4, 0, 0.4]}
    assert parse(d, tmp_path).observer.tuning.injection_damping_ratio == (0.4, 0.0, 0.4)
    d["observer"] = {"wave_period_s": 9, "injection_damping_ratio": -0.1}
    (problem,) = problems_of(d, tmp_path)
    assert problem.startswith("bad.toml: observer.injection_damping_ratio: out of range (expected a zero or ")
    d["observer"] = {"wave_period_s": 9, "zeta": 0}  # the other ratios stay positive
    assert "observer.zeta: out of range" in problems_of(d, tmp_path)[0]


# --- bad configs ------------------------------------------------------------------------------------------

# (id, {dotted path: value}, key path reported, a fragment of the message)
BAD: list[tuple[str, dict[str, Any], str, str]] = [
    (
        "wrong type",
        {"observer.rate_hz": "fast"},
        "observer.rate_hz",
        'wrong type (expected a number from 1 to 50 Hz, got a string "fast")',
    ),
    ("bool is not a number", {"sources.0.timeout_s": True}, "sources.dgps1.timeout_s", "got a boolean true"),
    (
        "int expected",
        {"sources.0.priority": 1.5},
        "sources.dgps1.priority",
        "expected an integer >= 0, got a number 1.5",
    ),
    (
        "out of range",
        {"observer.rate_hz": 100},
        "observer.rate_hz",
        "out of range (expected a number from 1 to 50 Hz, got 100)",
    ),
    ("nan", {"sources.0.timeout_s": math.nan}, "sources.dgps1.timeout_s", "not a finite number"),
    (
        "timeout zero",
        {"sources.1.timeout_s": 0},
        "sources.gyro1.timeout_s",
        "expected a number > 0 and <= 600 s",
    ),
    (
        "latitude",
        {"datum": {"lat_deg": 95.0, "lon_deg": 10.0}},
        "datum.lat_deg",
        "from -90 to 90 degrees, got 95.0",
    ),
    ("lon missing", {"datum": {"lat_deg": 59.0}}, "datum.lon_deg", "missing (expected lat_deg and lon_deg"),
    ("empty datum", {"datum": {}}, "datum", "missing lat_deg and lon_deg"),
    (
        "datum both",
        {"datum": {"lat_deg": 59.0, "lon_deg": 10.0, "first_fix": True}},
        "datum",
        "first_fix = true and a fixed point",
    ),
    ("unknown section", {"sourcess": []}, "sourcess", "unknown key, did you mean 'sources'?"),
    (
        "unknown source key",
        {"sources.0.timout_s": 2.0},
        "sources.dgps1.timout_s",
        "did you mean 'timeout_s'?",
    ),
    (
        "unknown observer key",
        {"observer.wave_perod_s": 8.0},
        "observer.wave_perod_s",
        "did you mean 'wave_period_s'?",
    ),
    ("unknown log key", {"log.rotate_mib": 8}, "log.rotate_mib", "did you mean 'rotate_mb'?"),
    (
        "unknown key, no suggestion",
        {"zenoh.banana": 1},
        "zenoh.banana",
        "unknown key (expected one of: mode, connect",
    ),
    (
        "duplicate name",
        {"sources.1.name": "dgps1"},
        "sources[1].name",  # a duplicate is named by its index; the first keeps the name
        'source name "dgps1" is used twice, here and by sources.dgps1 (expected unique names',
    ),
    ("bad name", {"sources.0.name": "DGPS-1"}, "sources[0].name", "expected lowercase letters, digits and _"),
    (
        "no heading",
        {"sources.1.roles": ["position"], "sources.1.priority": 2},
        "sources",
        "no source has role 'heading' — add roles = [\"heading\"] to the gyro compass's [[sources]] entry",
    ),
    (
        "no position",
        {"sources.0.roles": ["heading"], "sources.0.priority": 2, "sources.0.lever_arm_m": DELETE},
        "sources",
        "no source has role 'position'",
    ),
    (
        "role typo",
        {"sources.1.roles": ["heding"]},
        "sources.gyro1.roles",
        'role "heding" is not available for protocol "nmea", did you mean "heading"?',
    ),
    (
        "thrusters over nmea",
        {"sources.1.roles": ["heading", "thrusters"]},
        "sources.gyro1.roles",
        'role "thrusters" is not available for protocol "nmea"',
    ),
    ("empty roles", {"sources.2.roles": []}, "sources.thr.roles", "empty (expected an array of roles"),
    (
        "repeated role",
        {"sources.1.roles": ["heading", "heading"]},
        "sources.gyro1.roles",
        "a role is repeated",
    ),
    (
        "protocol",
        {"sources.0.protocol": "nmea0183"},
        "sources.dgps1.protocol",
        'expected "nmea" or "mavlink", got "nmea0183"',
    ),
    ("missing url", {"sources.0.url": DELETE}, "sources.dgps1.url", "missing (expected a URL"),
    (
        "url scheme",
        {"sources.0.url": "serail:///dev/ttyUSB0"},
        "sources.dgps1.url",
        "unknown transport 'serail', did you mean serial://?",
    ),
    (
        "url two slashes",
        {"sources.0.url": "serial://dev/ttyUSB0"},
        "sources.dgps1.url",
        "three slashes: serial:///dev/ttyUSB0",
    ),
    (
        "url no slashes",
        {"sources.0.url": "tcp-listen:0.0.0.0:10110"},
        "sources.dgps1.url",
        "did you mean tcp-listen://0.0.0.0:10110?",
    ),
    (
        "no transport",
        {"sources.0.url": "192.168.1.5:10110"},
        "sources.dgps1.url",
        "expected udp://192.168.1.5",
    ),
    (
        "url option (gateway.sources)",
        {"sources.0.url": "serial:///dev/ttyUSB0?buad=4800"},
        "sources.dgps1.url",
        "buad",
    ),
    (
        "parity (gateway.sources)",
        {"sources.0.url": "serial:///dev/ttyUSB0?parity=X"},
        "sources.dgps1.url",
        "parity",
    ),
    (
        "pymavlink serial for nmea",
        {"sources.0.url": "serial:/dev/ttyUSB0"},
        "sources.dgps1.url",
        "opens at 115200 baud (expected serial:///dev/ttyUSB0?baud=4800 for NMEA 0183",
    ),
    (
        "bare device for nmea",
        {"sources.0.url": "/dev/ttyUSB0"},
        "sources.dgps1.url",
        "expected serial:///dev/ttyUSB0?baud=4800",
    ),
    (
        "baud",
        {"sources.0.url": "serial:///dev/ttyUSB0?baud=48000"},
        "sources.dgps1.url",
        "unsupported baud rate '48000'",
    ),
    ("port", {"sources.0.url": "udp://0.0.0.0:70000"}, "sources.dgps1.url", "port 70000 is out of range"),
    ("no port", {"sources.0.url": "udp://0.0.0.0"}, "sources.dgps1.url", "is not HOST:PORT"),
    ("tcp no host", {"sources.0.url": "tcp://:2000"}, "sources.dgps1.url", "no host to connect to"),
    ("pymavlink no host", {"sources.2.url": "udpout::14550"}, "sources.thr.url", "no host"),
    (
        "unknown pymavlink",
        {"sources.2.url": "udpbcast:1.2.3.4:14550"},
        "sources.thr.url",
        "unknown transport",
    ),
    ("not a url", {"sources.0.url": "gps.nmea"}, "sources.dgps1.url", "not a URL"),
    (
        "same device twice",
        {"sources.1.url": "serial:///dev/ttyUSB0?baud=4800"},
        "sources.gyro1.url",
        "same serial /dev/ttyUSB0 as sources.dgps1",
    ),
    (
        "same udp port twice",
        {"sources.0.url": "udp://0.0.0.0:14550"},
        "sources.thr.url",
        "same udp 14550 as sources.dgps1",
    ),
    (
        "lever arm short",
        {"sources.0.lever_arm_m": [10.0, -2.0]},
        "sources.dgps1.lever_arm_m",
        "expected an array of 3 numbers [x fwd, y stbd, z down]",
    ),
    (
        "lever arm string",
        {"sources.0.lever_arm_m": "10, -2, -20"},
        "sources.dgps1.lever_arm_m",
        'got a string "10, -2, -20"',
    ),
    (
        "lever arm in mm",
        {"sources.0.lever_arm_m": [10000.0, -2000.0, -20000.0]},
        "sources.dgps1.lever_arm_m",
        "farther from the reference point",
    ),
    (
        "lever arm on gyro",
        {"sources.1.lever_arm_m": [1.0, 0.0, 0.0]},
        "sources.gyro1.lever_arm_m",
        'only for sources with role "position"',
    ),
    (
        "signing key short",
        {"sources.2.signing_key": "abc123"},
        "sources.thr.signing_key",
        "expected 64 hexadecimal characters, got 6 characters",
    ),
    (
        "signing key not hex",
        {"sources.2.signing_key": "zz" * 32},
        "sources.thr.signing_key",
        "not all hexadecimal",
    ),
    (
        "signing key on nmea",
        {"sources.0.signing_key": KEY},
        "sources.dgps1.signing_key",
        'only for protocol "mavlink"',
    ),
    (
        "unsigned without key",
        {"sources.2.allow_unsigned": True},
        "sources.thr.allow_unsigned",
        "has no effect without a signing_key",
    ),
    (
        "system id",
        {"sources.2.system_id": 300},
        "sources.thr.system_id",
        "expected an integer from 1 to 255, got 300",
    ),
    (
        "checksum on mavlink",
        {"sources.2.allow_missing_checksum": True},
        "sources.thr.allow_missing_checksum",
        'only for protocol "nmea"',
    ),
    (
        "priority tie",
        {"sources.2.roles": ["thrusters", "heading"]},
        "sources.thr.priority",
        "sources 'gyro1' and 'thr' both have role 'heading' with priority 1",
    ),
    (
        "ardupilot thruster id",
        {"sources.2.ardupilot": {"esc": {"1": 9}}},
        "sources.thr.ardupilot.esc.1",
        "vessel 'mss_supply' has no thruster 9 (expected one of its thruster ids: 1, 2, 3, 4, 5, 6)",
    ),
    (
        "ardupilot servo to tunnel",
        {"sources.2.ardupilot": {"servo": {"1": 4}}},
        "sources.thr.ardupilot.servo.1",
        "thruster 4 is a tunnel thruster",
    ),
    (
        "ardupilot index",
        {"sources.2.ardupilot": {"esc": {"0": 1}}},
        "sources.thr.ardupilot.esc.0",
        "not a ESC index (expected 1 to 32",
    ),
    (
        "ardupilot twice",
        {"sources.2.ardupilot": {"esc": {"1": 1, "2": 1}}},
        "sources.thr.ardupilot.esc.2",
        "thruster 1 is also mapped from esc 1",
    ),
    (
        "esc direction channel out of range",
        {"sources.2.ardupilot": {"esc": {"1": 4}, "esc_direction_servo": {"1": 33}}},
        "sources.thr.ardupilot.esc_direction_servo.1",
        "not a servo output channel (expected 1 to 32, the SERVO_OUTPUT_RAW output of ESC 1's motor, got an "
        "integer 33)",
    ),
    (
        "esc direction from an azimuth servo",
        {
            "sources.2.ardupilot": {
                "esc": {"1": 4, "2": 1},
                "servo": {"3": 1},
                "esc_direction_servo": {"1": 3},
            }
        },
        "sources.thr.ardupilot.esc_direction_servo.1",
        "servo output 3 is the azimuth servo of thruster 1 in sources.thr.ardupilot.servo",
    ),
    (
        "esc direction of an ESC not mapped",
        {"sources.2.ardupilot": {"esc": {"1": 4}, "esc_direction_servo": {"2": 5}}},
        "sources.thr.ardupilot.esc_direction_servo.2",
        "ESC 2 is not mapped to a thruster (expected one of the ESCs in sources.thr.ardupilot.esc: 1)",
    ),
    (
        "esc direction table without servo",
        {"sources.2.ardupilot": {"esc": {"1": 4}, "esc_direction_servo": {"1": {"neutral_us": 1520}}}},
        "sources.thr.ardupilot.esc_direction_servo.1",
        "has no servo",
    ),
    (
        "esc direction neutral",
        {
            "sources.2.ardupilot": {
                "esc": {"1": 4},
                "esc_direction_servo": {"1": {"servo": 5, "neutral_us": 90}},
            }
        },
        "sources.thr.ardupilot.esc_direction_servo.1.neutral_us",
        "not a pulse width (expected 500 to 2500 µs, got 90)",
    ),
    (
        "esc direction key",
        {"sources.2.ardupilot": {"esc": {"1": 4}, "esc_direction_servo": {"1": {"channel": 5}}}},
        "sources.thr.ardupilot.esc_direction_servo.1.channel",
        "unknown key (expected one of: servo, neutral_us)",
    ),
    (
        "esc dead band",
        {"sources.2.ardupilot": {"esc": {"1": 4}, "esc_dead_band_us": -5}},
        "sources.thr.ardupilot.esc_dead_band_us",
        "not a pulse width (expected 0 to 400 µs, got -5)",
    ),
    ("ardupilot empty", {"sources.2.ardupilot": {}}, "sources.thr.ardupilot", "maps nothing"),
    (
        "ardupilot key",
        {"sources.2.ardupilot": {"escs": {"1": 1}}},
        "sources.thr.ardupilot.escs",
        "did you mean 'esc'?",
    ),
    (
        "ardupilot without thrusters role",
        {"sources.2.roles": ["heading"], "sources.2.priority": 2, "sources.2.ardupilot": {"esc": {"1": 1}}},
        "sources.thr.ardupilot",
        'expected "thrusters" in roles',
    ),
    (
        "spr",
        {"observer.wave_period_s": 7, "observer.bias_corner": 0.1},
        "observer",
        "tuning fails Proposition 1",
    ),
    (
        "tuning rule",
        {"observer.wave_period_s": 7, "observer.bias_corner": 2.0},
        "observer",
        "tuning fails (48)",
    ),
    (
        "tuning per dof",
        {"observer.wave_period_s": [7.0, 8.0]},
        "observer.wave_period_s",
        "or an array of 3 [surge, sway, yaw]",
    ),
    ("tuning negative", {"observer.zeta": -0.1}, "observer.zeta", "out of range (expected a positive number"),
    (
        "wave period and omega0",
        {"observer.wave_period_s": 7, "observer.omega0": 0.9},
        "observer",
        "both wave_period_s and omega0",
    ),
    (
        "omega_c and ratio",
        {"observer.omega_c": 1.1, "observer.cutoff_ratio": 1.2},
        "observer",
        "both omega_c and cutoff_ratio",
    ),
    ("observer type", {"observer.type": "kalman"}, "observer.type", 'got "kalman"'),
    (
        "observer params",
        {"observer.type": "gain_scheduled", "observer.params": {"omega_mni": 0.3}},
        "observer.params",
        "unknown parameter(s) ['omega_mni']",
    ),
    (
        "allow_unchecked type",
        {"observer.allow_unchecked": "yes"},
        "observer.allow_unchecked",
        "expected true or false",
    ),
    (
        "unknown vessel",
        {"vessel.name": "mss_suply"},
        "vessel.name",
        'not a built-in vessel, did you mean "mss_supply"?',
    ),
    ("vessel missing", {"vessel": DELETE}, "vessel", "missing (expected a [vessel] table)"),
    ("vessel name and file", {"vessel.file": "x.toml"}, "vessel", "both name and file given"),
    ("vessel file missing", {"vessel": {"file": "nope.toml"}}, "vessel.file", "no such file"),
    (
        "vessel as string",
        {"vessel": "mss_supply"},
        "vessel",
        'expected a [vessel] table, got a string "mss_supply"',
    ),
    (
        "reference point",
        {"vessel.reference_point_m": [0.0, 0.0, 0.0]},
        "vessel.reference_point_m",
        "expected an array of 2 numbers",
    ),
    (
        "reference point far",
        {"vessel.reference_point_m": [500.0, 0.0]},
        "vessel.reference_point_m",
        "outside the vessel",
    ),
    ("sources table", {"sources": {"name": "x"}}, "sources", "written [[sources]], got a table [sources]"),
    ("no sources", {"sources": []}, "sources", "empty (expected at least one [[sources]]"),
    ("zenoh mode", {"zenoh.mode": "router"}, "zenoh.mode", 'expected "peer" or "client", got "router"'),
    ("zenoh endpoint", {"zenoh.connect": ["192.168.1.10:7447"]}, "zenoh.connect[0]", "not a Zenoh endpoint"),
    (
        "zenoh protocol",
        {"zenoh.connect": ["tpc/192.168.1.10:7447"]},
        "zenoh.connect[0]",
        "unknown Zenoh protocol 'tpc'",
    ),
    (
        "zenoh listen type",
        {"zenoh.listen": "tcp/0.0.0.0:7447"},
        "zenoh.listen",
        "expected an array of endpoints",
    ),
    ("zenoh config missing", {"zenoh.config_file": "nope.json5"}, "zenoh.config_file", "no such file"),
    ("zenoh prefix", {"zenoh.prefix": "dp/*"}, "zenoh.prefix", "'*' not allowed"),
    ("zenoh prefix slash", {"zenoh.prefix": "/dp/ship"}, "zenoh.prefix", "no leading or trailing '/'"),
    (
        "log compression",
        {"log.compression": "gzip"},
        "log.compression",
        'expected one of "zstd", "lz4", "none", got "gzip"',
    ),
    ("log suffix", {"log.path": "logs/run.log"}, "log.path", "expected a path ending in .mcap"),
    ("rotate negative", {"log.rotate_mb": -1}, "log.rotate_mb", "out of range"),
    ("rotate tiny", {"log.rotate_mb": 0.5}, "log.rotate_mb", "too small"),
    ("flush", {"log.flush_interval_s": 0}, "log.flush_interval_s", "expected a number > 0 and <= 60 s"),
    ("status rate", {"status.rate_hz": 0}, "status.rate_hz", "from 0.1 to 10 Hz, got 0"),
    ("section type", {"log": "logs/x.mcap"}, "log", "expected a [log] table"),
    ("clock typo", {"time.clock": "simulation"}, "time.clock", 'expected "wall" or "sim", got "simulation"'),
    ("clock key typo", {"time.clok": "sim"}, "time.clok", "did you mean 'clock'"),
    (
        "keelson without entity",
        {"keelson.enabled": True},
        "keelson.entity_id",
        "missing (expected one key chunk in snake_case",
    ),
    ("keelson entity", {"keelson.entity_id": "My Ship"}, "keelson.entity_id", 'got "My Ship"'),
    ("keelson enabled type", {"keelson.enabled": "yes"}, "keelson.enabled", "expected true or false"),
    ("keelson base wildcard", {"keelson.base_path": "keelson/*"}, "keelson.base_path", "not a Keelson key"),
    ("keelson verbatim", {"keelson.estimate_source_id": "@x"}, "keelson.estimate_source_id", "snake_case"),
    ("keelson sensor", {"keelson.sensor_source_id": "gnss"}, "keelson.sensor_source_id", 'no "{source}"'),
    (
        "keelson same id",
        {"keelson.log_source_id": "dpgw/estimate"},
        "keelson.log_source_id",
        "the same as keelson.estimate_source_id",
    ),
    ("keelson key typo", {"keelson.entity": "x"}, "keelson.entity", "did you mean 'entity_id'"),
]


@pytest.mark.parametrize(("changes", "key", "fragment"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_config(changes: dict[str, Any], key: str, fragment: str, tmp_path: Path) -> None:
    d = base()
    for path, value in changes.items():
        put(d, path, value)
    problems = problems_of(d, tmp_path)
    matching = [p for p in problems if p.startswith(f"bad.toml: {key}: ")]
    assert matching, problems
    assert any(fragment in p for p in matching), matching


def test_a_port_used_twice_is_listed_with_the_entries_own_problems(tmp_path: Path) -> None:
    """Two DGPS receivers on one UDP port, the second entry with a misspelt key and a wrong type: all three
    problems in one pass (the port clash does not wait for the entry's own problems to be fixed), and the
    clash's advice is a port each (two receivers are not one source with several roles)."""
    d = base()
    put(d, "sources.0.url", "udp://0.0.0.0:41101")
    d["sources"].insert(
        1,
        {
            "name": "dgps2",
            "url": "udp://0.0.0.0:41101",
            "protocol": "nmea",
            "roles": ["position"],
            "priority": 1,
            "timout_s": 2,
            "lever_arm_m": "1, 2, 3",
        },
    )
    problems = problems_of(d, tmp_path)
    mine = [p for p in problems if p.startswith("bad.toml: sources.dgps2.")]
    assert len(mine) == 3, problems
    assert any(p.startswith("bad.toml: sources.dgps2.timout_s: ") for p in mine), mine
    assert any(p.startswith("bad.toml: sources.dgps2.lever_arm_m: ") for p in mine), mine
    (clash,) = [p for p in mine if p.startswith("bad.toml: sources.dgps2.url: ")]
    assert "same udp 41101 as sources.dgps1" in clash, clash
    advice = "two sources cannot listen on the same port: give each its own port (or, if it is one device"
    assert advice in clash, clash


def test_every_problem_is_listed_with_file_and_key(tmp_path: Path) -> None:
    path = tmp_path / "ship.toml"
    path.write_text(
        """
[vessel]
name = "mss_suply"

[[sources]]
name = "dgps1"
url = "serail:///dev/ttyUSB0"
protocol = "nmea"
roles = ["position"]
lever_arm_m = [1.0, 2.0]
timout_s = 2

[[sources]]
name = "dgps1"
url = "udpin:0.0.0.0:14550"
protocol = "mavlink"
roles = ["thrusters"]
signing_key = "not-a-key"

[observer]
wave_period_s = 7
bias_corner = 0.1
rate_hz = "fast"

[log]
compression = "gzip"
"""
    )
    with pytest.raises(ConfigError) as info:
        load_config(path)
    problems = info.value.problems
    expected_keys = [
        "vessel.name",
        "sources.dgps1.timout_s",
        "sources.dgps1.url",
        "sources.dgps1.lever_arm_m",
        "sources[1].signing_key",  # a second "dgps1": named by its index
        "sources[1].name",
        "sources",  # no heading
        "observer.rate_hz",
        "observer",  # SPR: checked with a stand-in vessel although vessel.name is wrong
        "log.compression",
    ]
    assert [p.split(": ")[1] for p in problems] == expected_keys, problems
    assert all(p.startswith(f"{path}: ") for p in problems)
    message = str(info.value)
    assert message.startswith(f"invalid configuration ({len(problems)} problems):")
    assert all(p in message for p in problems)
    assert "not-a-key" not in message  # a secret is never echoed


def test_invalid_toml_names_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text('[vessel]\nname = "mss_supply"\nreference_point_m = [0.0, 0.0\n\n[datum]\n')
    with pytest.raises(ConfigError) as info:
        load_config(path)
    (problem,) = info.value.problems
    assert problem.startswith(f"{path}: not valid TOML: ")
    assert "(at line 5, column 1)" in problem


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "absent.toml")


def test_vessel_error_is_wrapped(tmp_path: Path) -> None:
    (tmp_path / "bad_vessel.toml").write_text(VESSEL_FILE.replace("[0.0, 1.0, 3.0]", "[0.0, 1.0, -3.0]"))
    d = base()
    d["vessel"] = {"file": "bad_vessel.toml"}
    problems = problems_of(d, tmp_path)
    assert any(p.startswith("bad.toml: vessel.file: ") and "field 'M'" in p for p in problems), problems


def test_zenoh_keys_that_a_config_file_would_override(tmp_path: Path) -> None:
    (tmp_path / "z.json5").write_text("{}")
    d = base()
    d["zenoh"] = {"config_file": "z.json5", "connect": ["tcp/10.0.0.1:7447"], "mode": "peer"}
    problems = problems_of(d, tmp_path)
    assert problems == [
        "bad.toml: zenoh.connect: has no effect when zenoh.config_file is set (expected it in z.json5, or no "
        "config_file)"
    ]


def test_format_problems_for_the_cli(tmp_path: Path) -> None:
    d = base()
    d["observer"] = {"rate_hz": 0}
    with pytest.raises(ConfigError) as info:
        parse(d, tmp_path)
    text = format_problems(info.value)
    lines = text.splitlines()
    assert lines[0] == "dpgw: the configuration has 1 problem; nothing was started:"
    assert lines[1].startswith("  bad.toml: observer.rate_hz: out of range")
    assert format_problems(["a", "b"]).splitlines()[0].endswith("2 problems; nothing was started:")


def test_a_source_name_used_twice_is_one_problem_naming_the_name(tmp_path: Path) -> None:
    """Two DGPS both named "dgps1" (the second copied from the first): one problem, the name used twice.
    Before, a second one followed: "sources 'dgps1' and 'dgps1' both have role 'position' with priority
    1", a person's puzzle (the priorities were never the mistake)."""
    d = base()
    d["sources"].insert(1, {**d["sources"][0], "url": "udp://127.0.0.1:10110"})
    assert problems_of(d, tmp_path) == [
        'bad.toml: sources[1].name: source name "dgps1" is used twice, here and by sources.dgps1 (expected '
        "unique names: a source's name keys its status, its log channels and its alarms)"
    ]


def test_a_config_file_that_cannot_be_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A missing file: no key of it is in question, so no pointer to the keys' page; ``--check`` starts
    nothing anyway, so it does not say that nothing was started (the run itself does)."""
    from dpgw.cli import main

    missing = tmp_path / "vesel.toml"
    assert main(["run", "--config", str(missing), "--check"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "dpgw: the configuration has 1 problem:",
        f"  {missing}: cannot read: no such file",
    ]
    assert main(["run", "--config", str(missing)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "dpgw: the configuration has 1 problem; nothing was started:",
        f"  {missing}: cannot read: no such file",
    ]
    bad = tmp_path / "bad.toml"
    bad.write_text("[observer]\nrate_hz = 0\n")
    assert main(["run", "--config", str(bad), "--check"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].endswith("problems:") and "nothing was started" not in err[0], err
    assert err[-1].startswith("Every key is described in docs/config.md"), err


def test_check_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`dpgw run --config FILE --check`: the one check command; a summary, or every problem (status 2)."""
    from dpgw.cli import main

    assert main(["run", "--config", str(EXAMPLES / "nmea_udp_multiplexer.toml"), "--check"]) == 0
    assert "nmea_udp_multiplexer.toml: ok" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text(BASE_TOML.replace('roles = ["heading"]', 'roles = ["heading"]\nbaud = 4800'))
    assert main(["run", "--config", str(bad), "--check"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: sources.gyro1.baud: unknown key" in err


def test_check_command_in_a_subprocess(tmp_path: Path) -> None:
    """`dpgw run --config FILE --check` in a process: one message on stderr, nothing on stdout, status 2."""
    bad = tmp_path / "bad.toml"
    bad.write_text(BASE_TOML.replace('"mss_supply"', '"titanic"'))
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(bad), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert p.returncode == 2
    assert p.stdout == ""
    assert f"{bad}: vessel.name: not a built-in vessel" in p.stderr
    assert p.stderr.startswith("dpgw: the configuration has 1 problem:\n")  # (--check starts nothing anyway)


def test_the_old_check_module_is_gone() -> None:
    """One check command: `python -m gateway.config` no longer runs (it is a package without __main__)."""
    p = subprocess.run(
        [sys.executable, "-m", "gateway.config", "x.toml"], capture_output=True, text=True, cwd=ROOT
    )
    assert p.returncode != 0


def test_parse_config_does_not_modify_its_input(tmp_path: Path) -> None:
    d = base()
    before = copy.deepcopy(d)
    parse(d, tmp_path)
    assert d == before


def test_ardupilot_servo_calibration_defaults_and_limits(tmp_path: Path) -> None:
    """The servo calibration of an ArduPilot source: 1500 µs ahead and 400 µs a half turn unless said; a
    half turn near 0 µs (every pulse one angle), a pulse width outside 500–2500 µs or a non-number is
    refused with its key."""
    d = base()
    put(d, "sources.2.ardupilot", {"servo": {"1": 1}})
    ap = parse(d, tmp_path).source("thr").ardupilot
    assert ap is not None and (ap.servo_neutral_us, ap.servo_half_turn_us) == (1500.0, 400.0)
    put(d, "sources.2.ardupilot", {"servo": {"1": 1}, "servo_neutral_us": 1520, "servo_half_turn_us": -380.5})
    ap = parse(d, tmp_path).source("thr").ardupilot
    assert ap is not None and (ap.servo_neutral_us, ap.servo_half_turn_us) == (1520.0, -380.5)
    put(d, "sources.2.ardupilot", {"servo": {"1": 1}, "servo_neutral_us": 3000, "servo_half_turn_us": 0.5})
    got = problems_of(d, tmp_path)
    assert any("sources.thr.ardupilot.servo_neutral_us: not a pulse width" in p for p in got), got
    assert any(
        "sources.thr.ardupilot.servo_half_turn_us: maps every pulse width to one angle" in p for p in got
    )
    put(d, "sources.2.ardupilot", {"servo": {"1": 1}, "servo_neutral_us": True})
    assert any("servo_neutral_us: not a pulse width" in p for p in problems_of(d, tmp_path))


def test_integrity_config_mistakes_name_the_key() -> None:
    tables = {
        "vessel": {"name": "mss_supply"},
        "sources": [{"name": "g", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position"]}],
        "observer": {},
        "integrity": {"gga_quality": [1, 8, 12], "median_m": 0},
    }
    with pytest.raises(ConfigError) as e:
        parse_config(tables, base_dir=Path.cwd())
    assert "integrity.median_m: out of range" in str(e.value)
    assert "integrity.gga_quality: not GGA quality codes" in str(e.value)


# --- who may command: [commands], Zenoh users and commanders, unsigned MAVLink commands ------------------


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"commands.accept": ["mode", "sepoint"]}, 'commands.accept[1]: not a command input, did you mean "setpoint"?'),  # noqa: E501
        ({"commands.accept": ["tau", "tau"]}, "commands.accept: an input is repeated"),
        ({"commands.max_setpoint_distance_m": 0}, "commands.max_setpoint_distance_m: out of range"),
        ({"commands.manual_tau_hold_s": 0}, "commands.manual_tau_hold_s: out of range (expected a number > 0 s, or inf, got 0)"),  # noqa: E501
        ({"commands.manual_tau_hold_s": -2.0}, "commands.manual_tau_hold_s: out of range"),
        ({"commands.manual_tau_hold_s": math.nan}, "commands.manual_tau_hold_s: out of range"),
        ({"commands.manual_tau_hold_s": -math.inf}, "commands.manual_tau_hold_s: out of range"),
        ({"commands.manual_tau_hold_s": "2 s"}, 'commands.manual_tau_hold_s: wrong type (expected a number > 0 s, or inf, got a string "2 s")'),  # noqa: E501
        ({"commands.manual_tau_hold_s": True}, "commands.manual_tau_hold_s: wrong type"),
        ({"commands.enabled": True}, "commands.enabled: unknown key"),
        ({"zenoh.commanders": ["captain"]}, "zenoh.commanders: needs zenoh.users_file"),
        ({"zenoh.users_file": "users.txt", "zenoh.commanders": ["captian"]}, "zenoh.commanders[0]: not a user of"),  # noqa: E501
        ({"zenoh.users_file": "nothing.txt"}, "zenoh.users_file: cannot read"),
        ({"zenoh.users_file": "bad_users.txt"}, "zenoh.users_file: bad_users.txt line 2 is not user:password"),  # noqa: E501
        ({"zenoh.user": "gw"}, "zenoh.user: given without zenoh.password_file"),
        ({"zenoh.config_file": "z.json5", "zenoh.users_file": "users.txt"}, "zenoh.users_file: has no effect when zenoh.config_file is set"),  # noqa: E501
        ({"sources.2.commands": True}, "sources.thr.commands: thruster commands would go out unsigned (expected a signing_key, or allow_unsigned = true"),  # noqa: E501
        ({"sources.2.allow_unsigned": True}, "sources.thr.allow_unsigned: has no effect without a signing_key or commands = true"),  # noqa: E501
        ({"sources.2.component_id": 0}, "sources.thr.component_id: out of range (expected an integer from 1 to 255"),  # noqa: E501
        ({"sources.0.component_id": 1}, 'sources.dgps1.component_id: only for protocol "mavlink"'),
    ],
)  # fmt: skip
def test_command_access_mistakes_stop_start_up(
    changes: dict[str, Any], expected: str, tmp_path: Path
) -> None:
    (tmp_path / "users.txt").write_text("captain:secret\nwatch:other\n")
    (tmp_path / "bad_users.txt").write_text("captain:secret\nno password here\n")
    (tmp_path / "z.json5").write_text("{}")
    data = base()
    for path, value in changes.items():
        put(data, path, value)
    found = problems_of(data, tmp_path)
    assert any(expected in line for line in found), found
    assert not any("secret" in line for line in found), found  # a password is never echoed


def test_manual_tau_hold_in_a_file(tmp_path: Path) -> None:
    """2 s unless set; TOML's ``inf`` holds a τ until the next one; 0 stops start-up with the file and the
    key named."""
    assert parse(base(), tmp_path).commands.manual_tau_hold_s == 2.0
    path = tmp_path / "gw.toml"
    path.write_text(BASE_TOML + '\n[commands]\naccept = ["mode", "tau"]\nmanual_tau_hold_s = inf\n')
    assert load_config(path).commands.manual_tau_hold_s == math.inf
    path.write_text(BASE_TOML + "\n[commands]\nmanual_tau_hold_s = 0.0\n")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert "gw.toml" in str(info.value) and "commands.manual_tau_hold_s: out of range" in str(info.value)


def test_command_access_that_is_fine(tmp_path: Path) -> None:
    (tmp_path / "users.txt").write_text("captain:secret\nwatch:other\n")
    (tmp_path / "gw.password").write_text("gateway-secret\n")
    data = base()
    put(data, "zenoh.users_file", "users.txt")
    put(data, "zenoh.commanders", ["captain"])
    put(data, "zenoh.user", "gw")
    put(data, "zenoh.password_file", "gw.password")
    put(data, "commands.accept", ["setpoint", "mode"])
    put(data, "commands.max_setpoint_distance_m", 25)
    put(data, "sources.2.commands", True)
    put(data, "sources.2.allow_unsigned", True)
    put(data, "sources.2.system_id", 1)
    put(data, "sources.2.component_id", 7)
    c = parse(data, tmp_path)
    assert c.zenoh.users_file == tmp_path / "users.txt" and c.zenoh.commanders == ("captain",)
    assert (c.zenoh.user, c.zenoh.password) == ("gw", "gateway-secret")
    assert "gateway-secret" not in repr(c.zenoh)
    assert c.commands.accept == frozenset({"setpoint", "mode"}) and c.commands.max_setpoint_distance_m == 25
    thr = c.source("thr")
    assert (thr.commands, thr.allow_unsigned, thr.signing_key, thr.system_id, thr.component_id) == (
        True, True, None, 1, 7,
    )  # fmt: skip
    put(data, "sources.2.allow_unsigned", DELETE)
    put(data, "sources.2.signing_key", KEY)
    assert parse(data, tmp_path).source("thr").signing_key == bytes.fromhex(KEY)


@pytest.mark.parametrize(
    ("observer", "refused"),
    [
        ({"type": "ekf", "zeta": 0.1, "bias_time_constant_s": 500.0}, ["bias_time_constant_s"]),
        (
            {"type": "sdre", "wave_period_s": 8.0, "zeta_n": 1.0, "cutoff_ratio": 1.1},
            ["zeta_n", "cutoff_ratio"],
        ),
        ({"type": "mmae", "wave_period_s": 8.0}, ["wave_period_s"]),
        ({"type": "mmae", "zeta": 0.1}, ["zeta"]),  # the bank's own ζ goes in [observer.params]
        ({"type": "sdre", "wave_period_s": 8.0, "zeta": 0.1}, []),
        ({"type": "passive", "zeta_n": 1.0, "bias_time_constant_s": 500.0}, []),
        ({"type": "memory", "zeta_n": 1.0}, []),
        ({"type": "mmae", "params": {"zeta": 0.1}}, []),
    ],
)
def test_a_tuning_key_the_observer_does_not_use_is_refused(
    observer: dict[str, Any], refused: list[str], tmp_path: Path
) -> None:
    """Silently ignored, `[observer] type = "ekf"` with `bias_time_constant_s` looked like a tuning that
    took effect: each such key is a problem naming the key and what the observer does use."""
    data = base()
    data["observer"] = observer
    try:
        parse(data, tmp_path)
        problems: list[str] = []
    except ConfigError as exc:
        problems = exc.problems
    found = [line for line in problems if "not used by" in line]
    assert len(found) == len(refused), found
    for key, line in zip(refused, found, strict=True):
        assert f"observer.{key}" in line and f'"{observer["type"]}"' in line and "[observer.params]" in line


def test_the_check_command_notes_a_udp_address_this_computer_does_not_have(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A UDP source on an address no interface has is waited for at start-up (an interface slow to come
    up at boot), so `--check` cannot refuse it; it says so, because a typing mistake looks the same.
    (198.51.100.0/24 is TEST-NET-2: documentation only, never a real interface.)"""
    from dpgw.cli import main

    for host, noted in (("198.51.100.7", True), ("127.0.0.1", False), ("0.0.0.0", False)):
        path = tmp_path / "vessel.toml"
        path.write_text(
            f'[vessel]\nname = "mss_supply"\n[log]\npath = ""\n[[sources]]\nname = "gps"\n'
            f'url = "udp://{host}:10110"\nprotocol = "nmea"\nroles = ["position", "heading"]\n'
        )
        assert main(["run", "--config", str(path), "--check"]) == 0
        out = capsys.readouterr().out
        assert ("note: sources.gps.url: 198.51.100.7 is not an address of this computer now" in out) == noted


def test_control_return_speed_is_checked_against_the_vessels_reference_speed(tmp_path: Path) -> None:
    """`[control] return_speed_mps` reaches the controller; above the reference model's Froude-scaled speed
    limit (0.5 m/s for the 76.2 m mss_supply), zero or negative, start-up stops naming the key."""
    from gateway.control.controller import ControllerTuning, DPController

    d = base()  # mss_supply
    d["control"] = {"return_speed_mps": 0.3}
    cfg = parse(d, tmp_path)
    assert cfg.control is not None and cfg.control.return_speed_mps == 0.3
    ctl = DPController(cfg.vessel, ControllerTuning(return_speed_mps=cfg.control.return_speed_mps))
    assert ctl.return_speed_mps == 0.3
    d["control"] = {}
    assert parse(d, tmp_path).control.return_speed_mps is None  # type: ignore[union-attr]
    d["control"] = {"return_speed_mps": 0.8}
    (problem,) = problems_of(d, tmp_path)
    assert problem.startswith("bad.toml: control.return_speed_mps: above the reference model's speed limit")
    assert "at most 0.5 m/s" in problem and "got 0.8" in problem
    d["control"] = {"return_speed_mps": 0}
    (problem,) = problems_of(d, tmp_path)
    assert problem.startswith("bad.toml: control.return_speed_mps: out of range")


def test_the_observer_is_held_no_slower_than_the_dp_loop_it_feeds(tmp_path: Path) -> None:
    """The config gives the observer's tuning the controller's bandwidth (its Froude-scaled default, or
    ``[control] bandwidth_rad_s``) as ``loop_bandwidth``, so that a ratio-set velocity injection decays no
    slower than the DP loop (docs/passive-observer.md). CyberShip II in the `hassani` sea (6.76 s): the
    velocity error then decays at the loop's 0.545/0.545/0.779 rad/s instead of 0.19-0.32 s⁻¹. A controller
    fed the raw measurement (`feedback = "measurement"`) is not fed the estimate: no floor. An explicit
    ``velocity_injection`` is the user's and is kept."""
    from dpgw.closed_loop import gateway_tables
    from observers.passive_tuning import passive_gains
    from simulator.scenarios import get_scenario

    def injection(c: GatewayConfig) -> Any:
        g = passive_gains(c.vessel, c.observer.tuning)
        return np.diag(g.K4) / np.diag(c.vessel.M) / g.omega_c

    d = gateway_tables(get_scenario("hassani"))
    c = parse(d, tmp_path)
    damping = np.diag(c.vessel.D) / np.diag(c.vessel.M)
    np.testing.assert_allclose(c.observer.tuning.loop_bandwidth, (0.5454, 0.5454, 0.7792), atol=1e-4)
    np.testing.assert_allclose(damping + injection(c), c.observer.tuning.loop_bandwidth, rtol=1e-12)
    put(d, "control.bandwidth_rad_s", [0.6, 0.6, 0.9])
    assert parse(d, tmp_path).observer.tuning.loop_bandwidth == (0.6, 0.6, 0.9)
    put(d, "control.feedback", "measurement")
    raw = parse(d, tmp_path)
    assert raw.observer.tuning.loop_bandwidth is None
    np.testing.assert_allclose(injection(raw), 0.12 * 2 * math.pi / d["observer"]["wave_period_s"])
    put(d, "control.feedback", "estimate")
    put(d, "observer.velocity_injection", 0.2)
    np.testing.assert_allclose(injection(parse(d, tmp_path)), 0.2, rtol=1e-12)


@pytest.mark.parametrize("name", ["ltp", "vessel", "vessel_measured"])
def test_a_position_source_may_not_take_the_name_of_a_frame(name: str, tmp_path: Path) -> None:
    """A position source's fixes are in its antenna's frame, named after it: named like one of the frames
    the gateway draws in, its antenna would replace that frame in a viewer's transform tree."""
    data = base()
    position = next(k for k, s in enumerate(data["sources"]) if "position" in s["roles"])
    put(data, f"sources.{position}.name", name)
    (problem,) = [p for p in problems_of(data, tmp_path) if f"sources[{position}].name" in p or ".name" in p]
    assert f'"{name}" is the name of one of the frames the gateway draws in' in problem, problem
    assert "ltp, vessel, vessel_measured" in problem


def test_the_check_summary_has_a_line_for_each_output_and_access_that_is_on(tmp_path: Path) -> None:
    """``dpgw run --check``'s summary (`describe`): one short line each for Foxglove, Keelson, ROS 2, Zenoh
    authentication with its commanders and the log's rotation when on; none of them when off."""
    from gateway.config import describe

    (tmp_path / "users.txt").write_text("captain:secret\nwatch:other\n")
    data = base()
    put(data, "zenoh.users_file", "users.txt")
    put(data, "zenoh.commanders", ["captain"])
    put(data, "foxglove.enabled", True)
    put(data, "keelson.enabled", True)
    put(data, "keelson.entity_id", "my_ship")
    put(data, "ros2.enabled", True)
    put(data, "log.rotate_mb", 256)
    put(data, "log.rotate_minutes", 0)
    lines = describe(parse(data, tmp_path)).splitlines()
    assert "  foxglove live server on 127.0.0.1:8765" in lines, lines
    assert "  keelson under keelson/@v0/my_ship/pubsub/…" in lines, lines
    assert "  ros2 (rmw_zenoh) domain 0, node /dpgw/dpgw" in lines, lines
    users = tmp_path / "users.txt"
    assert f"  zenoh authentication: users of {users}; commands only from captain" in lines, lines
    assert "  log rotated at 256 MB" in lines, lines
    assert not any("secret" in line for line in lines)
    off = base()
    put(off, "log.rotate_mb", 0)
    put(off, "log.rotate_minutes", 0)
    quiet = describe(parse(off, tmp_path))
    for word in ("foxglove", "keelson", "ros2", "authentication", "rotated"):
        assert word not in quiet, quiet
