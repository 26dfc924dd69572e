"""`dpgw --help` must answer at once: building the parsers imports nothing heavy.

The property tested is which modules a help page loads, not how long it takes (a timing test fails on a
busy machine and passes on a fast one; `bench/bench_cli_startup.py` measures the time).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap

from dpgw.cli import SUBCOMMANDS

# Each of these costs from tens of milliseconds to seconds at import (numba and scipy the most), or pulls
# in packages that do. None is needed to print a help page.
HEAVY = (
    "numpy",
    "numba",
    "scipy",
    "zenoh",
    "pydantic",
    "mcap",
    "matplotlib",
    "tqdm",
    "gateway",
    "wire",
    "dask",
    "distributed",
)
HEAVY_MODULES = (
    "simulator.scenarios",
    "simulator.runner",
    "observers.vessel",
    "observers.passive_tuning",
    "observers.radiation",
)

COMMANDS = [p.__name__.removeprefix("dpgw.cli_") for p in SUBCOMMANDS]


def _loaded_after_help() -> list[str]:
    """The modules loaded in a fresh interpreter after printing `dpgw --help` and every `dpgw X --help`."""
    script = textwrap.dedent(
        f"""
        import contextlib, io, json, sys
        from dpgw.cli import main
        for argv in ([], *[[c] for c in {COMMANDS!r}]):
            with contextlib.redirect_stdout(io.StringIO()):
                try:
                    main([*argv, "--help"])
                except SystemExit:
                    pass
        print(json.dumps(sorted(sys.modules)))
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    loaded: list[str] = json.loads(out.stdout)
    return loaded


def test_help_pages_import_nothing_heavy() -> None:
    loaded = _loaded_after_help()
    heavy = sorted(
        {
            m if m in HEAVY_MODULES else m.split(".")[0]
            for m in loaded
            if m.split(".")[0] in HEAVY or m in HEAVY_MODULES
        }
    )
    assert not heavy, f"--help imported {heavy}: move these imports into the command's run()"
    assert "dpgw.cli_demo" in loaded and "dpgw.cli_tune" in loaded  # the parsers were built


def test_every_command_is_covered() -> None:
    assert sorted(COMMANDS) == [
        "capability",
        "demo",
        "listen",
        "radiation",
        "replay",
        "run",
        "sim",
        "study",
        "tune",
    ]


def test_scenario_names_match_the_scenarios() -> None:
    from dpgw.scenario_names import SCENARIO_NAMES
    from simulator.scenarios import SCENARIOS

    assert tuple(SCENARIOS) == SCENARIO_NAMES


def test_builtin_vessels_listed_without_numerics() -> None:
    from observers import vessel, vessel_files

    names = vessel_files.builtin_vessels()
    assert "mss_supply" in names and names == vessel.builtin_vessels()
    for name in names:
        assert vessel.load_vessel(name).name  # each listed name loads


def test_radiation_defaults_match_the_fit() -> None:
    from dpgw import cli_radiation
    from observers import radiation

    assert (cli_radiation.MIN_ORDER, cli_radiation.MAX_ORDER, cli_radiation.R2_TARGET) == (
        radiation.MIN_ORDER,
        radiation.MAX_ORDER,
        radiation.R2_TARGET,
    )


def test_capability_defaults_match_the_analysis() -> None:
    from dpgw import capability, cli_capability

    assert cli_capability.DEFAULT_CURRENT_MPS == capability.DEFAULT_CURRENT_MPS
    assert cli_capability.U_LIMIT_MPS == capability.U_LIMIT_MPS
    assert cli_capability.BEAUFORT_DYNAMIC_FACTOR == capability.BEAUFORT_DYNAMIC_FACTOR


def test_replay_help_lists_every_spec_tuning_key() -> None:
    """`dpgw replay --help` lists the keys an observer spec takes for the tuning: all that
    `parse_observer_spec` takes (it left out velocity_injection_ratio and injection_damping_ratio)."""
    from dpgw import cli_replay
    from gateway.replay import TUNING_KEYS

    assert set(cli_replay.SPEC_TUNING_KEYS) == TUNING_KEYS
    assert len(cli_replay.SPEC_TUNING_KEYS) == len(TUNING_KEYS)
    listed = set(re.findall(r"[a-z0-9_]+", cli_replay.EPILOG.split("examples:")[0]))
    for key in TUNING_KEYS:
        assert key in listed, key


def test_dpgw_runs_blas_single_threaded_unless_told_otherwise() -> None:
    """OpenBLAS's extra threads spin-wait after every small product (twice the CPU for the same wall time,
    measured in bench/bench_simulator.py): every dpgw command sets one thread before numpy loads, and a
    value the user set stays."""
    code = textwrap.dedent(
        """
        import os, sys
        from dpgw.cli import main
        try:
            main(["sim", "--help"])
        except SystemExit:
            pass
        import numpy  # loads OpenBLAS with the variables as they are now
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            print(os.environ[name])
        print(len(os.listdir("/proc/self/task")))  # OpenBLAS starts its threads when it loads
        """
    )
    clean = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], env=clean, capture_output=True, text=True, check=True)
    assert out.stdout.split()[-4:] == ["1", "1", "1", "1"]  # and no BLAS thread beside the main one
    mine = {**clean, "OPENBLAS_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", code], env=mine, capture_output=True, text=True, check=True)
    assert out.stdout.split()[-4:-1] == ["2", "1", "1"]
