"""Run one benchmark on two checkouts side by side and print the ratio of every figure.

These machines are shared and noisy: the same benchmark can give half its figures on another run. A change
is judged by running the old and the new code in the same session, interleaved (old, new, old, new …),
and comparing medians. Each tree runs its OWN copy of the benchmark script with its own code on the import
path (``PYTHONPATH`` = that tree), so a benchmark whose imports moved still runs on both.

    git worktree add /tmp/old <commit>
    python bench/ab_compare.py --base /tmp/old --rounds 3 bench/bench_replay.py --hours 0.5
    python bench/ab_compare.py --base /tmp/old bench/bench_gateway.py --quick --no-memory

The benchmark must accept ``--json`` and print one JSON document; every numeric leaf is compared
(``latency[0].p99_us`` …). ``--only REGEX`` keeps the figures whose path matches.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent.parent


def leaves(doc: Any, path: str = "") -> dict[str, float]:
    """Every numeric leaf of a JSON document by its path (``a.b[2].c``); booleans are not figures."""
    out: dict[str, float] = {}
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.update(leaves(v, f"{path}.{k}" if path else str(k)))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out.update(leaves(v, f"{path}[{i}]"))
    elif isinstance(doc, int | float) and not isinstance(doc, bool):
        out[path] = float(doc)
    return out


def run_once(tree: Path, script: str, args: list[str]) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    proc = subprocess.run(
        [sys.executable, str(tree / script), *args, "--json"],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        raise SystemExit(
            f"ab_compare: {script} failed in {tree} (exit {proc.returncode}):\n{proc.stderr[-2000:]}"
        )
    start = proc.stdout.find("{")
    return leaves(json.loads(proc.stdout[start:]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, type=Path, help="the other checkout (the old code)")
    ap.add_argument("--new", type=Path, default=HERE, help="the checkout under test (default: this one)")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved runs of each tree (3)")
    ap.add_argument("--only", help="compare only the figures whose path matches this regular expression")
    ap.add_argument("--json", action="store_true", help="print the medians and ratios as JSON")
    ap.add_argument("script", help="the benchmark, relative to each checkout (bench/bench_replay.py)")
    ap.add_argument("args", nargs=argparse.REMAINDER, help="arguments for the benchmark")
    a = ap.parse_args(argv)
    for tree in (a.base, a.new):
        if not (tree / a.script).is_file():
            ap.error(f"{tree / a.script}: no such benchmark in that checkout")
    runs: dict[str, list[dict[str, float]]] = {"base": [], "new": []}
    for k in range(a.rounds):
        for label, tree in (("base", a.base), ("new", a.new)):
            print(f"round {k + 1}/{a.rounds}: {label} ({tree}) ...", file=sys.stderr, flush=True)
            runs[label].append(run_once(tree, a.script, a.args))
    keys = sorted(set(runs["base"][0]) & set(runs["new"][0]))
    if a.only:
        keys = [k for k in keys if re.search(a.only, k)]
    rows = []
    for key in keys:
        old = statistics.median(r[key] for r in runs["base"] if key in r)
        new = statistics.median(r[key] for r in runs["new"] if key in r)
        rows.append({"figure": key, "base": old, "new": new, "ratio": new / old if old else None})
    if a.json:
        print(json.dumps({"script": a.script, "args": a.args, "rounds": a.rounds, "rows": rows}, indent=2))
        return 0
    print(f"{a.script} {' '.join(a.args)}: medians of {a.rounds} interleaved runs each")
    print(f"  {'figure':60s} {'base':>14s} {'new':>14s} {'new/base':>9s}")
    for r in rows:
        ratio = "" if r["ratio"] is None else f"{r['ratio']:9.3f}"
        print(f"  {r['figure'][:60]:60s} {r['base']:14.6g} {r['new']:14.6g} {ratio}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
