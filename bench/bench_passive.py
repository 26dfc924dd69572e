"""Benchmark: passive observer per-sample `step` and batch `run` on 24 h of 10 Hz data.

Targets: batch >= 1,000,000 samples/s, step <= 20 µs. Side by side in the same run with the
straightforward numpy implementation of the same equations (`observers.passive.reference_run`), which is
timed on a slice (a full day would take minutes) and reported as samples/s and as a ratio.

    python bench/bench_passive.py [--hours 24] [--rate 10] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from _timing import best_of, step_latency

from observers.kinematics import ssa
from observers.passive import PassiveObserver, reference_run
from observers.passive_tuning import passive_gains
from observers.vessel import load_vessel


def make_input(hours: float, rate: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * rate)
    t = np.arange(n) / rate
    w = 2 * math.pi / 8.0
    y = np.c_[
        2 * np.sin(w * t) + 0.5 * rng.standard_normal(n),
        2 * np.cos(0.9 * w * t) + 0.5 * rng.standard_normal(n),
        ssa(0.3 + 0.02 * np.sin(w * t) + 0.002 * rng.standard_normal(n)),
    ]
    y[rng.random(n) < 0.001, :2] = np.nan  # occasional lost fixes
    tau = np.tile([1e5, -5e4, 2e6], (n, 1)) + rng.normal(0, 1e4, (n, 3))
    return t, y, tau


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--rate", type=float, default=10.0, help="sample rate (Hz)")
    ap.add_argument("--reference-samples", type=int, default=20_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    vessel = load_vessel("mss_supply")
    gains = passive_gains(vessel)
    t, y, tau = make_input(args.hours, args.rate)
    n = len(t)

    PassiveObserver(vessel).run(t[:100], y[:100], tau[:100])  # compile (cached on disk after the first run)

    best = best_of(3, lambda: PassiveObserver(vessel).run(t, y, tau))
    batch_rate = n / best
    step_median, step_p99 = step_latency(PassiveObserver(vessel), t, y, tau, 200_000)

    r = args.reference_samples
    t0 = time.perf_counter()
    reference_run(vessel, gains, t[:r], y[:r], tau[:r])
    ref_rate = r / (time.perf_counter() - t0)

    result = {
        "samples": n,
        "hours": args.hours,
        "rate_hz": args.rate,
        "batch_samples_per_s": batch_rate,
        "batch_seconds": best,
        "step_median_us": step_median * 1e6,
        "step_p99_us": step_p99 * 1e6,
        "numpy_reference_samples_per_s": ref_rate,
        "batch_speedup_vs_numpy": batch_rate / ref_rate,
        "step_speedup_vs_numpy": (1 / step_median) / ref_rate,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"passive observer, mss_supply, {args.hours:g} h at {args.rate:g} Hz = {n:,} samples")
    print(f"  batch run (numba kernel):  {batch_rate:12,.0f} samples/s  ({best:.2f} s; target >= 1e6)")
    print(
        f"  step (per sample):   median {step_median * 1e6:6.2f} µs, p99 {step_p99 * 1e6:6.2f} µs (target 20)"
    )
    print(f"  numpy reference (same eqs):{ref_rate:12,.0f} samples/s  (timed on {r:,} samples)")
    print(f"  ratio batch / numpy:       {batch_rate / ref_rate:12,.0f} x")
    print(f"  ratio step / numpy:        {(1 / step_median) / ref_rate:12,.1f} x")


if __name__ == "__main__":
    main()
