"""The DP extended Kalman filter beside the passive and SDRE observers, in one run: live step time, batch
throughput, and LF error against the simulator's truth on the same measurements.

    python bench/bench_ekf.py [--duration 900] [--seeds 1 2 3] [--json]

Each scenario is simulated (open loop, the scenario's own force law) to a log with ground truth, then
replayed once with every observer side by side (`dpgw replay --observer ...`), so all see the very same
bytes. Times: the median of repeated passes over a 10 Hz record, all observers interleaved.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dpgw.cli import main as dpgw
from observers.factory import make_observer
from observers.vessel import load_vessel
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.mcap.writer import McapLogWriter

OBSERVERS = ("passive", "sdre", "ekf")
SCENARIOS = ("fossen_strand_1999", "torsetnes_2004", "snijders_2005")


def timing(rounds: int = 7) -> dict[str, dict[str, float]]:
    rng = np.random.default_rng(1)
    n = 6000
    t = np.arange(1, n + 1) / 10.0
    w = 2 * math.pi / 8.0
    y = np.c_[np.sin(w * t), np.cos(w * t), 0.3 + 0.01 * np.sin(w * t)] + rng.normal(
        0, [0.3, 0.3, 0.002], (n, 3)
    )
    vessel = load_vessel("mss_supply")
    obs = {k: make_observer(k, vessel) for k in OBSERVERS}
    for o in obs.values():  # compile and warm
        o.run(t[:50], y[:50])
        o.reset()
    batch: dict[str, list[float]] = {k: [] for k in OBSERVERS}
    live: dict[str, list[float]] = {k: [] for k in OBSERVERS}
    for _ in range(rounds):
        for k, o in obs.items():
            o.reset()
            t0 = time.perf_counter()
            o.run(t, y)
            batch[k].append(n / (time.perf_counter() - t0))
            o.reset()
            t0 = time.perf_counter()
            for i in range(2000):
                o.step(t[i], y[i])
            live[k].append((time.perf_counter() - t0) / 2000 * 1e6)
    return {
        k: {"batch_samples_per_s": statistics.median(batch[k]), "step_us": statistics.median(live[k])}
        for k in OBSERVERS
    }


def accuracy(duration: float, seeds: list[int], folder: Path) -> dict[str, dict[str, list[list[float]]]]:
    out: dict[str, dict[str, list[list[float]]]] = {}
    for name in SCENARIOS:
        scenario = get_scenario(name)
        out[name] = {k: [] for k in OBSERVERS}
        for seed in seeds:
            log = folder / f"{name}-{seed}.mcap"
            with McapLogWriter(log) as w:
                Simulation(scenario, seed=seed, log=w).run(duration)
            args = [
                "replay",
                str(log),
                "--vessel",
                scenario.vessel.name,
                "--out",
                str(folder / "r.mcap"),
                "--json",
            ]
            for k in OBSERVERS:
                args += ["--observer", f"{k}@{k}"]
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
                if dpgw(args) != 0:
                    raise SystemExit(f"replay of {log} failed")
            errors = json.loads(buf.getvalue())["error_vs_truth"]
            for k in OBSERVERS:
                e = errors[k]
                out[name][k].append([e["rms_north_m"], e["rms_east_m"], e["rms_heading_deg"]])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=900.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    times = timing()
    with tempfile.TemporaryDirectory() as d:
        acc = accuracy(args.duration, args.seeds, Path(d))
    if args.json:
        print(json.dumps({"timing": times, "rms": acc}, indent=2))
        return
    print("observer   live step (µs)   batch (samples/s)   [median of 7 interleaved passes, 10 Hz record]")
    for k, v in times.items():
        print(f"{k:10s} {v['step_us']:14.1f}   {v['batch_samples_per_s']:17,.0f}")
    print(
        f"\nLF RMS error vs truth, mean over seeds {args.seeds} "
        f"({args.duration:.0f} s, open loop, model plant)"
    )
    print("scenario             observer   N (m)    E (m)    ψ (deg)")
    for name, per in acc.items():
        for k, rows in per.items():
            m = np.mean(rows, axis=0)
            print(f"{name:20s} {k:9s} {m[0]:7.3f}  {m[1]:7.3f}  {m[2]:7.3f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
