"""Replay one log with two checkouts and check that the estimates are bit-identical.

A refactor must not change a number. This replays the same log (a `dpgw demo` log, a sea trial) with the
old code and with this tree, each through its own `dpgw replay`, and compares every estimate message of
the outputs field by field: floats must be equal to the bit (``repr``), not merely close.

    git worktree add /tmp/old <commit>
    python bench/ab_replay_identity.py --base /tmp/old demo.mcap [--vessel mss_supply]

``--every-topic`` also compares every message of every topic as bytes (topic, log time, publish time,
payload), in file order per topic: what a change to the writing or the Foxglove channels must keep.

Exit status 0 when identical; 1 with the first differences listed otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

HERE = Path(__file__).resolve().parent.parent
COMPARED = ("/dp/estimate", "/dp/measurement")


def replay(tree: Path, log: Path, out: Path, extra: list[str]) -> None:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    module = "dpgw" if (tree / "dpgw" / "__main__.py").exists() else "gateway"  # older trees
    cmd = [sys.executable, "-m", module, "replay", str(log), "--out", str(out), *extra]
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"replay failed in {tree} (exit {proc.returncode}):\n{proc.stderr[-2000:]}")


def messages(path: Path) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {t: [] for t in COMPARED}
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=list(COMPARED)):
            out[channel.topic].append(json.loads(message.data))
    return out


def raw_messages(path: Path) -> dict[str, list[tuple[int, int, bytes]]]:
    """Every message of every topic as (log time, publish time, payload bytes), in file order per topic."""
    out: dict[str, list[tuple[int, int, bytes]]] = {}
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            out.setdefault(channel.topic, []).append((message.log_time, message.publish_time, message.data))
    return out


def every_topic(old: Path, new: Path) -> int:
    """Compare two logs message by message, byte for byte; print a line per topic; 1 if any differs."""
    a, b = raw_messages(old), raw_messages(new)
    bad = 0
    for topic in sorted(set(a) | set(b)):
        x, y = a.get(topic, []), b.get(topic, [])
        first = next((k for k, (m, n) in enumerate(zip(x, y, strict=False)) if m != n), None)
        if len(x) != len(y) or first is not None:
            bad = 1
            where = f"first at message {first}" if first is not None else "counts differ"
            print(f"{topic}: {len(x)} / {len(y)} messages, DIFFERENT ({where})")
        else:
            print(f"{topic}: {len(y)} messages, byte-identical")
    return bad


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    """Where two decoded JSON values differ; floats by their exact repr."""
    if isinstance(a, dict) and isinstance(b, dict):
        diffs = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                continue  # a field added or removed is an interface change, not a numeric one
            diffs += differences(a[k], b[k], f"{path}.{k}")
        return diffs
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        return [
            d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in differences(x, y, f"{path}[{i}]")
        ]
    return [] if repr(a) == repr(b) else [f"{path}: {a!r} != {b!r}"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, type=Path, help="the other checkout (the old code)")
    ap.add_argument("--new", type=Path, default=HERE, help="the checkout under test (default: this one)")
    ap.add_argument(
        "--expect-changed",
        action="append",
        default=[],
        metavar="TOPIC.FIELD",
        help="a field a deliberate fix changes (e.g. /dp/measurement.sigma_m); its differences are counted "
        "and shown but do not fail the comparison; every other field must still be bit-identical",
    )
    ap.add_argument(
        "--every-topic",
        action="store_true",
        help="also compare every message of every topic byte for byte (times and payload)",
    )
    ap.add_argument("log", type=Path, help="the log to replay")
    ap.add_argument("replay_args", nargs=argparse.REMAINDER, help="more `dpgw replay` arguments")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="dpgw-ab-") as tmp:
        outs = {}
        for label, tree in (("base", a.base), ("new", a.new)):
            outs[label] = Path(tmp) / f"{label}.mcap"
            replay(tree.resolve(), a.log.resolve(), outs[label], a.replay_args)
        old, new = messages(outs["base"]), messages(outs["new"])
        bad = every_topic(outs["base"], outs["new"]) if a.every_topic else 0
    for topic in COMPARED:
        n_old, n_new = len(old[topic]), len(new[topic])
        diffs = [] if n_old == n_new else [f"{n_old} messages != {n_new}"]
        expected: Counter[str] = Counter()
        for k, (x, y) in enumerate(zip(old[topic], new[topic], strict=False)):
            for d in differences(x, y):
                field = d.split(":", 1)[0].split("[", 1)[0]  # ".sigma_m" of ".sigma_m: None != 0.3"
                if f"{topic}{field}" in a.expect_changed:
                    expected[field] += 1
                else:
                    diffs.append(f"message {k}{d}")
        verdict = "bit-identical" if not diffs else f"{len(diffs)} differences"
        if expected:
            changed = ", ".join(f"{f.lstrip('.')} in {n}" for f, n in sorted(expected.items()))
            verdict += f" apart from the expected changes ({changed} messages)"
        print(f"{topic}: {n_new} messages, {verdict}")
        for d in diffs[:10]:
            print(f"  {d}")
        bad += bool(diffs)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
