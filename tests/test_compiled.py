"""The compiled hot path (setup.py, `wire.compiled`) against its readable reference, the same sources run
interpreted (``DPGW_PURE_PYTHON=1``): every message of a replay byte-identical, every topic, on a closed-loop
demo log (control, MAVLink thrusters, allocation), on a simulated log full of sensor faults, and on the real
USV sea-trial logs; the simulator's own output (every message it logs, with faults, an MRU, the full plant
and an anemometer) and the in-process closed loop's (typed and bytes) identical too. Plus: the install did
compile it, and an edited source is never shadowed by its stale compiled form."""

from __future__ import annotations

import ast
import hashlib
import json
import os
import socket
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
from mcap.reader import make_reader

import wire
from wire import compiled

ROOT = Path(wire.__file__).resolve().parent.parent
REAL_LOGS = ROOT.parent / "shared" / "data" / "usv-nmea"
PURE = {**os.environ, compiled.PURE_ENV: "1"}
COMPILED = {k: v for k, v in os.environ.items() if k != compiled.PURE_ENV}

FAULTS = """
[[faults]]
kind = "dropout"
source = "dgps1"
t_start = 40.0
t_end = 75.0

[[faults]]
kind = "jump"
source = "dgps1"
t_start = 100.0
t_end = 130.0
north_m = 6.0
east_m = -4.0

[[faults]]
kind = "frozen"
source = "gyro1"
t_start = 150.0
t_end = 170.0

[[faults]]
kind = "bad_checksum"
source = "*"
t_start = 0.0
probability = 0.05

[[faults]]
kind = "garbage"
source = "*"
t_start = 180.0
t_end = 200.0
probability = 0.2
max_bytes = 60

[[faults]]
kind = "thruster_failure"
source = 2
t_start = 210.0
"""

needs_compiled = pytest.mark.skipif(
    not compiled.status().modules, reason="this install compiled none of the hot path (setup.py)"
)


def test_the_install_compiled_the_hot_path_and_it_is_the_one_running() -> None:
    """CI installs with a C compiler: the hot path must run compiled there, or the speed figures of
    docs/performance.md are not this install's."""
    if os.environ.get(compiled.PURE_ENV, "") not in ("", "0"):
        pytest.skip(f"{compiled.PURE_ENV} is set: the interpreted sources run on purpose")
    status = compiled.status()
    assert status.compiled, f"the hot path runs {status.describe()}"
    import gateway.pipeline
    import wire.codecs.nmea

    assert compiled.is_compiled(gateway.pipeline) and compiled.is_compiled(wire.codecs.nmea)
    said = subprocess.run(
        [sys.executable, "-m", "dpgw", "--version"], capture_output=True, text=True, check=True
    )
    assert f"hot path: compiled (mypyc, {len(status.modules)} modules)" in said.stdout


# Bases a compiled (mypyc native) class may have besides another compiled class. A native class derived from
# any other class compiles, but may not import: `io.RawIOBase` under Python 3.12+ raised "type ... has the
# Py_TPFLAGS_MANAGED_DICT flag but tp_dictoffset is set" at import, so `dpgw replay` failed there and not
# on 3.11. Such a class must be a Python class (``@mypyc_attr(native_class=False)``).
NATIVE_SAFE_BASES = frozenset(
    {"object", "Exception", "ValueError", "RuntimeError", "Protocol", "NamedTuple", "Generic", "ABC"}
    | {"Enum", "IntEnum", "IntFlag", "Flag", "StrEnum"}
)


def _base_name(node: ast.expr) -> str:
    """A class base as written, without its type arguments (``_Sampled[...]`` -> ``_Sampled``)."""
    if isinstance(node, ast.Subscript):
        node = node.value
    return ast.unparse(node)


def _python_class(cls: ast.ClassDef) -> bool:
    """Whether a class is marked ``@mypyc_attr(native_class=False)`` (compiled modules keep it a Python
    class)."""
    return any(
        isinstance(d, ast.Call)
        and ast.unparse(d.func).endswith("mypyc_attr")
        and any(k.arg == "native_class" and isinstance(k.value, ast.Constant) and k.value.value is False
                for k in d.keywords)
        for d in cls.decorator_list
    )  # fmt: skip


def test_every_compiled_class_derives_only_from_what_mypyc_supports_on_every_python() -> None:
    """The compiled modules' native classes derive only from other compiled classes or from the bases
    mypyc supports (`NATIVE_SAFE_BASES`); any other base needs ``@mypyc_attr(native_class=False)``. Read
    from the sources, so it holds on the Python this runs on for the ones it does not (3.12, 3.13)."""
    manifest = json.loads((ROOT / "wire" / "_compiled.json").read_text())
    trees = {
        name: ast.parse((ROOT / (name.replace(".", "/") + ".py")).read_text()) for name in manifest["modules"]
    }
    classes = [c for tree in trees.values() for c in ast.walk(tree) if isinstance(c, ast.ClassDef)]
    native = {c.name for c in classes if not _python_class(c)}
    unsupported = [
        f"{module}: class {c.name}({_base_name(b)})"
        for module, tree in trees.items()
        for c in ast.walk(tree)
        if isinstance(c, ast.ClassDef) and not _python_class(c)
        for b in c.bases
        if _base_name(b) not in NATIVE_SAFE_BASES and _base_name(b) not in native
    ]
    assert classes and not unsupported, unsupported


Messages = dict[str, list[tuple[int, int, bytes]]]  # topic -> (log time, publish time, payload)


def test_an_empty_bytes_slice_is_empty_not_an_error() -> None:
    """mypyc's runtime raised SystemError on a bytes slice that ends before it begins (setup.py builds a
    fixed copy): a sentence cut after its address field is such a slice in the log reader's time scan."""
    from gateway.logreaders import _unchecked_time

    assert _unchecked_time(b"$GPGGA,") is None  # line[7:-1] of a 7-byte line: b""
    assert _unchecked_time(b"$GPGGA,123519.00,4807.038,N") == 12 * 3600 + 35 * 60 + 19.0


def _messages(path: Path) -> Messages:
    out: Messages = {}
    with path.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            out.setdefault(channel.topic, []).append((message.log_time, message.publish_time, message.data))
    return out


def _replay(
    log: Path, out: Path, env: dict[str, str], *extra: str
) -> dict[str, list[tuple[int, int, bytes]]]:
    cmd = [sys.executable, "-m", "dpgw", "replay", str(log), "--out", str(out), *extra]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return _messages(out)


def _assert_same(log: Path, tmp_path: Path, *extra: str) -> int:
    pure = _replay(log, tmp_path / "pure.mcap", PURE, *extra)
    fast = _replay(log, tmp_path / "compiled.mcap", COMPILED, *extra)
    assert sorted(pure) == sorted(fast)
    for topic in pure:
        assert len(pure[topic]) == len(fast[topic]), topic
        for k, (a, b) in enumerate(zip(pure[topic], fast[topic], strict=True)):
            assert a == b, f"{topic} message {k} differs:\n  interpreted {a!r:.400}\n  compiled    {b!r:.400}"
    assert pure["/dp/estimate"], "nothing estimated: the comparison proves nothing"
    return sum(len(v) for v in pure.values())


@pytest.mark.slow
@needs_compiled
def test_a_closed_loop_demo_replays_byte_identical_compiled_and_interpreted(tmp_path: Path) -> None:
    log = tmp_path / "demo.mcap"
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "demo", "--scenario", "hassani_sea_change", "--duration", "120",
         "--speed", "20", "--out", str(log), "--engage-at", "5", "--json", "--no-scouting",
         "--zenoh-listen", f"tcp/127.0.0.1:{port}"],
        capture_output=True, text=True, timeout=300, env=COMPILED, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    n = _assert_same(log, tmp_path)
    commands = _messages(tmp_path / "compiled.mcap").get("/dp/thrusters/command", [])
    assert n > 1000 and commands, (n, len(commands))


@pytest.mark.slow
@needs_compiled
def test_a_faulty_sensor_log_replays_byte_identical_compiled_and_interpreted(tmp_path: Path) -> None:
    """Dropout, jump, frozen gyro, bad checksums, garbage and a thruster trip: the reference checks,
    votes, restarts and rejects all take their rarer paths."""
    faults = tmp_path / "faults.toml"
    faults.write_text(FAULTS)
    log = tmp_path / "sim.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "torsetnes_2004", "--duration", "240",
         "--seed", "4", "--faults", str(faults), "--out", str(log), "--json"],
        capture_output=True, text=True, timeout=300, env=COMPILED, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    _assert_same(log, tmp_path)
    status = [json.loads(data) for _, _, data in _messages(tmp_path / "pure.mcap")["/dp/status"]]
    rejected = status[-1]["sources"]
    assert any(sum(s.get("rejected", {}).values()) for s in rejected.values()), rejected


@pytest.mark.slow
@needs_compiled
@pytest.mark.parametrize("name", ["202412061745.txt"])
def test_a_real_sea_trial_replays_byte_identical_compiled_and_interpreted(name: str, tmp_path: Path) -> None:
    log = REAL_LOGS / name
    if not log.exists():
        pytest.skip(f"real USV log not found ({log})")
    _assert_same(log, tmp_path, "--vessel", "mss_supply")


# Runs in a fresh interpreter (compiled or not is decided at its first import of `wire`): prints whether the
# simulator ran compiled and a sha256 of everything each run produced, with the counts behind them.
_SIM_PROBE = r"""
import dataclasses, hashlib, json, sys, tempfile, tomllib
from pathlib import Path
from dpgw.closed_loop import run_closed_loop
from simulator import runner
from simulator.faults import FaultSchedule
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire import compiled
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter

faults = FaultSchedule.from_dicts(tomllib.loads(sys.argv[1])["faults"]).faults
out = {"compiled": compiled.is_compiled(runner)}
with tempfile.TemporaryDirectory() as folder:
    for name, with_faults in (("torsetnes_2004_mast", True), ("mss_supply_storm", False)):
        scenario = get_scenario(name).with_sensor_rates(10.0, 10.0)
        if with_faults:
            scenario = dataclasses.replace(scenario, faults=faults)
        path = Path(folder) / (name + ".mcap")
        with McapLogWriter(path) as log:
            summary = Simulation(scenario, seed=3, log=log).run(240.0)
        messages = list(read_messages(path))
        digest = hashlib.sha256(repr(messages).encode()).hexdigest()
        out[name] = [digest, len(messages), dict(summary.emissions)]
hold = [(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0})]
for wire in (False, True):
    r = run_closed_loop(get_scenario("torsetnes_2004"), 60.0, seed=1, events=hold, wire=wire,
                        collect=("/dp/measurement",), status_every_s=5.0)
    blob = json.dumps([r.estimates, r.commands, r.collected, r.statuses, r.status], default=str).encode()
    blob += r.t.tobytes() + r.eta_lf.tobytes() + r.eta_wf.tobytes() + r.nu.tobytes() + r.bias.tobytes()
    out["closed_loop_bytes" if wire else "closed_loop_typed"] = [
        hashlib.sha256(blob).hexdigest(), len(r.estimates), len(r.commands)
    ]
print(json.dumps(out))
"""


def _sim_probe(env: dict[str, str]) -> dict[str, object]:
    proc = subprocess.run(
        [sys.executable, "-c", _SIM_PROBE, FAULTS], env=env, capture_output=True, text=True, timeout=600,
        check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    return dict(json.loads(proc.stdout))


@pytest.mark.slow
@needs_compiled
def test_the_simulator_and_the_closed_loop_give_identical_results_compiled_and_interpreted() -> None:
    """The simulator's side of the loop is compiled too (its time loop, sensors, thrusters, faults): four
    minutes of sensors with every kind of sample and wire fault, an MRU and the full plant with an
    anemometer, logged message for message; and a minute of the in-process closed loop, typed and bytes:
    estimates, commands, measurements, statuses and the true track to the last bit."""
    pure, fast = _sim_probe(PURE), _sim_probe(COMPILED)
    assert pure.pop("compiled") is False and fast.pop("compiled") is True
    for key in pure:
        assert pure[key] == fast[key], f"{key}:\n  interpreted {pure[key]}\n  compiled    {fast[key]}"
    assert all(entry[1] > 100 for entry in pure.values()), pure  # (something was compared)


@needs_compiled
def test_an_edited_source_runs_interpreted_not_its_stale_compiled_form(tmp_path: Path) -> None:
    """The manifest says what was compiled from which source; one changed source sends every compiled
    module back to its source (they call each other directly), with a warning that says how to compile
    again. Checked on a copy of the packages, so the install is not touched."""
    for package in ("wire", "gateway", "observers", "simulator", "dpgw"):
        subprocess.run(["cp", "-a", str(ROOT / package), str(tmp_path / package)], check=True)
    manifest = tmp_path / "wire" / "_compiled.json"
    names = ["wire.geodesy", "gateway.fusion"]
    digests = {}
    for name in names:
        source = tmp_path.joinpath(*name.split(".")).with_suffix(".py")
        digests[name] = hashlib.sha256(source.read_bytes()).hexdigest()
    manifest.write_text(json.dumps({"compiled": True, "reason": "", "modules": digests}))
    probe = (
        "import warnings, sys; warnings.simplefilter('always')\n"
        "from wire import compiled\n"
        "import wire.geodesy, gateway.fusion\n"
        "s = compiled.status()\n"
        "print(s.compiled, wire.geodesy.__file__.endswith('.py'), gateway.fusion.__file__.endswith('.py'))\n"
    )
    # -S: no site processing, so an editable install's import hook cannot send `wire` back to the checkout;
    # the installed libraries stay reachable through PYTHONPATH
    env = {**COMPILED, "PYTHONPATH": os.pathsep.join([str(tmp_path), sysconfig.get_paths()["purelib"]])}
    cmd = [sys.executable, "-S", "-c", probe]
    run = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, check=True)
    clean = run.stdout.split()
    edited = tmp_path / "gateway" / "fusion.py"
    edited.write_text(edited.read_text() + "\n# an edit\n")
    run2 = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, check=True)
    # untouched: the manifest's sources match, and the compiled forms load
    assert clean == ["True", "False", "False"], clean
    # edited: interpreted, both modules from their sources, and the warning names the change
    assert run2.stdout.split() == ["False", "True", "True"], run2.stdout
    assert "gateway.fusion changed since the install compiled it" in run2.stderr
    assert "pip install -e ." in run2.stderr
