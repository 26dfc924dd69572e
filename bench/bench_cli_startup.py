"""Benchmark: how long `dpgw --help` and every `dpgw COMMAND --help` take, beside `import zenoh`.

Each measurement is a fresh ``python -m dpgw ... --help`` process (what a person typing the command waits
for), wall time from spawn to exit. The commands run interleaved, round after round, so a burst of load on a
shared machine hits all of them alike; the median over the rounds is reported. ``python -c "import zenoh"``
and ``python -c pass`` run in the same rounds: the first is what a command pays when it opens the bus, the
second the interpreter's own start-up, the floor no command can beat. Target: every --help under 0.5 s.

    python bench/bench_cli_startup.py                 # 7 rounds, a few seconds
    python bench/bench_cli_startup.py --rounds 15 --json
    python bench/bench_cli_startup.py --against ../main  # another checkout's dpgw in the same rounds
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

COMMANDS = ("run", "demo", "sim", "replay", "tune", "listen", "radiation")
TARGET_S = 0.5


def cases(roots: dict[str, str]) -> dict[str, tuple[list[str], dict[str, str]]]:
    """name -> (argv, environment): each checkout's dpgw (labelled), then the two references."""
    py = sys.executable
    out: dict[str, tuple[list[str], dict[str, str]]] = {}
    for label, root in roots.items():
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)
        tag = f" [{label}]" if len(roots) > 1 else ""
        out[f"dpgw --help{tag}"] = ([py, "-m", "dpgw", "--help"], env)
        for c in COMMANDS:
            out[f"dpgw {c} --help{tag}"] = ([py, "-m", "dpgw", c, "--help"], env)
    env = dict(os.environ)
    out['python -c "import zenoh"'] = ([py, "-c", "import zenoh"], env)
    out["python -c pass"] = ([py, "-c", "pass"], env)
    return out


def wall_time(argv: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    # cwd: `python -m` puts the working directory first on sys.path, before PYTHONPATH
    cwd = env.get("PYTHONPATH", "").split(os.pathsep)[0] or None
    done = subprocess.run(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd=cwd, check=False
    )
    elapsed = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}): {done.stderr.decode()[-500:]}")
    return elapsed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=7, help="interleaved rounds; the median is reported (7)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument(
        "--against", metavar="DIR", help="also time the dpgw of this checkout (e.g. main), in the same rounds"
    )
    args = ap.parse_args()
    # this checkout's dpgw, not an installed one
    roots = {"this": str(Path(__file__).resolve().parent.parent)}
    if args.against:
        roots[Path(args.against).resolve().name] = str(Path(args.against).resolve())
    todo = cases(roots)
    times: dict[str, list[float]] = {name: [] for name in todo}
    for argv, env in todo.values():  # warm the OS file cache (and .pyc files) before measuring
        wall_time(argv, env)
    for _ in range(args.rounds):
        for name, (argv, env) in todo.items():
            times[name].append(wall_time(argv, env))
    result = {
        "rounds": args.rounds,
        "target_s": TARGET_S,
        "median_s": {name: statistics.median(ts) for name, ts in times.items()},
        "max_s": {name: max(ts) for name, ts in times.items()},
    }
    result["all_help_under_target"] = all(  # this checkout's; --against is for comparison
        v < TARGET_S
        for k, v in result["median_s"].items()
        if (k.startswith("dpgw") and "[" not in k) or "[this]" in k
    )
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"wall time of a fresh process, median (max) of {args.rounds} interleaved rounds:")
    for name in todo:
        med, worst = result["median_s"][name], result["max_s"][name]
        flag = "" if not name.startswith("dpgw") or med < TARGET_S else f"   over {TARGET_S} s"
        print(f"  {name:36s} {med:6.3f} s  ({worst:.3f}){flag}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
