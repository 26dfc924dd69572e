"""Run the simulator with two checkouts and check that every logged message is bit-identical.

A speed-up of the simulator must not change a byte it sends or a truth record it logs. This runs each
scenario with the same seed in the old tree and in this one (each with its own code on the import path),
logs everything to MCAP as `dpgw sim --out` does, and compares the messages read back (topic, log time,
publish time, payload) — not the files, whose chunk boundaries depend on wall time. A run of the
in-process closed loop (bytes path) is compared too, as a fingerprint of its estimates, commands and
true track; it is expected to differ when the plant or the loop's schedule changed on purpose.

    git worktree add /tmp/old <commit>        (or: git archive <commit> | tar -x -C /tmp/old)
    python bench/ab_sim_identity.py --base /tmp/old [--seconds 120] [--scenarios NAME ...]

By default the model-plant scenarios; name others (the full plant's: mss_supply_storm mss_osv) with
--scenarios.

Exit status 0 when the simulator's messages are identical; 1 with the scenarios that differ otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
SCENARIOS = ("fossen_strand_1999", "torsetnes_2004", "hassani", "hajivand_2010", "snijders_2005")

# Runs inside each tree: prints {scenario: sha256 of the messages, "closed_loop": sha256 of its outputs}.
_PROBE = r"""
import hashlib, inspect, json, os, sys, tempfile
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter
from dpgw.closed_loop import run_closed_loop
seconds = float(sys.argv[1])
out = {}
with tempfile.TemporaryDirectory() as folder:
    for name in sys.argv[2:]:
        path = os.path.join(folder, name + ".mcap")
        with McapLogWriter(path) as log:
            Simulation(get_scenario(name).with_sensor_rates(10.0, 10.0), seed=3, log=log).run(seconds)
        out[name] = hashlib.sha256(repr(list(read_messages(path))).encode()).hexdigest()
hold = [(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0})]
kw = {"wire": True} if "wire" in inspect.signature(run_closed_loop).parameters else {}
r = run_closed_loop(get_scenario("torsetnes_2004"), seconds, seed=1, events=hold, **kw)
blob = json.dumps([r.estimates, r.commands], default=str).encode() + r.eta_lf.tobytes()
out["closed_loop"] = hashlib.sha256(blob).hexdigest()
print(json.dumps(out))
"""


def probe(tree: Path, seconds: float, scenarios: list[str]) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-c", _PROBE, str(seconds), *scenarios]
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(
            f"ab_sim_identity: the run failed in {tree} (exit {proc.returncode}):\n{proc.stderr[-2000:]}"
        )
    result: dict[str, str] = json.loads(proc.stdout.strip().splitlines()[-1])
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, type=Path, help="the other checkout (the old code)")
    ap.add_argument("--new", type=Path, default=HERE, help="the checkout under test (default: this one)")
    ap.add_argument("--seconds", type=float, default=120.0, help="sim time per scenario (120)")
    ap.add_argument(
        "--scenarios",
        nargs="+",
        default=list(SCENARIOS),
        metavar="NAME",
        help=f"the scenarios to compare (default: {' '.join(SCENARIOS)}; the full plant's: "
        "mss_supply_storm mss_osv)",
    )
    a = ap.parse_args(argv)
    base, new = probe(a.base, a.seconds, a.scenarios), probe(a.new, a.seconds, a.scenarios)
    differ = [name for name in a.scenarios if base[name] != new[name]]
    for name in a.scenarios:
        print(f"  {name:20s} {'identical' if name not in differ else 'DIFFERENT'}")
    loop = "identical" if base["closed_loop"] == new["closed_loop"] else "different"
    print(f"  {'closed loop (bytes)':20s} {loop} (estimates, commands, true track)")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
