"""Benchmark: the MMAE wave filter (eight 15-state Kalman filters) in batch replay, per-sample `step`, and
the passive observer's batch rate on the same data as a reference ratio.

Target: MMAE batch >= 100,000 samples/s with eight filters, as it runs by default (noise identification and
the LF output stage, `observers.mmae_lf`). Side by side in the same run: the paper's blend alone
(``lf_output=False``: what the LF output stage costs),
`PassiveObserver(...).run` on the same input (the reference ratio), and the straightforward numpy
implementation of the same MMAE (`observers.mmae.reference_run`), timed on a slice.

    python bench/bench_mmae.py [--hours 6] [--rate 10] [--vessel cybership2] [--json]
"""

from __future__ import annotations

import argparse
import json
import math

from dpgw.cli import single_threaded_blas

single_threaded_blas()  # as `dpgw run` and `dpgw replay` run (before numpy loads): one BLAS thread

import numpy as np  # noqa: E402
from _timing import best_of, step_latency  # noqa: E402

from observers.kinematics import ssa  # noqa: E402
from observers.mmae import MMAEObserver, reference_run  # noqa: E402
from observers.passive import PassiveObserver  # noqa: E402
from observers.vessel import load_vessel  # noqa: E402


def make_input(hours: float, rate: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CyberShip II-sized motion: a slow drift, 0.93 rad/s wave motion, 1 cm / 0.1° noise, lost fixes."""
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * rate)
    t = np.arange(n) / rate
    w = 0.93
    y = np.c_[
        0.5 * np.sin(2e-3 * t) + 0.02 * np.sin(w * t) + 0.01 * rng.standard_normal(n),
        0.3 * np.cos(1e-3 * t) + 0.01 * np.cos(0.9 * w * t) + 0.01 * rng.standard_normal(n),
        ssa(0.3 + 0.002 * np.sin(w * t) + math.radians(0.1) * rng.standard_normal(n)),
    ]
    y[rng.random(n) < 0.001, :2] = np.nan  # occasional lost fixes
    tau = np.tile([0.3, -0.2, 0.02], (n, 1)) + rng.normal(0, 0.05, (n, 3))
    return t, y, tau


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=6.0)
    ap.add_argument("--rate", type=float, default=10.0, help="sample rate (Hz)")
    ap.add_argument("--vessel", default="cybership2")
    ap.add_argument("--reference-samples", type=int, default=5_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    vessel = load_vessel(args.vessel)
    t, y, tau = make_input(args.hours, args.rate)
    n = len(t)
    settings = dict(dt=1.0 / args.rate, R=[1e-4, 1e-4, math.radians(0.1) ** 2])

    # compile (cached on disk after the first run)
    MMAEObserver(vessel, **settings).run(t[:100], y[:100], tau[:100])
    PassiveObserver(vessel).run(t[:100], y[:100], tau[:100])

    mmae_s = best_of(3, lambda: MMAEObserver(vessel, **settings).run(t, y, tau))
    paper_s = best_of(3, lambda: MMAEObserver(vessel, **settings, lf_output=False).run(t, y, tau))
    passive_s = best_of(3, lambda: PassiveObserver(vessel).run(t, y, tau))
    mmae_rate, passive_rate = n / mmae_s, n / passive_s

    step_median, step_p99 = step_latency(MMAEObserver(vessel, **settings), t, y, tau, 100_000)

    r = args.reference_samples
    bank = MMAEObserver(vessel, **settings).bank
    ref_s = best_of(1, lambda: reference_run(bank, t[:r], y[:r], tau[:r]))
    ref_rate = r / ref_s

    result = {
        "vessel": args.vessel,
        "filters": bank.n,
        "samples": n,
        "hours": args.hours,
        "rate_hz": args.rate,
        "mmae_batch_samples_per_s": mmae_rate,
        "mmae_batch_seconds": mmae_s,
        "mmae_paper_blend_batch_samples_per_s": n / paper_s,
        "lf_output_cost_ratio": mmae_s / paper_s,
        "passive_batch_samples_per_s": passive_rate,
        "passive_over_mmae": passive_rate / mmae_rate,
        "mmae_step_median_us": step_median * 1e6,
        "mmae_step_p99_us": step_p99 * 1e6,
        "numpy_reference_samples_per_s": ref_rate,
        "batch_speedup_vs_numpy": mmae_rate / ref_rate,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"MMAE, {bank.n} filters, {args.vessel}, {args.hours:g} h at {args.rate:g} Hz = {n:,} samples")
    print(f"  MMAE batch run (numba):     {mmae_rate:12,.0f} samples/s  ({mmae_s:.2f} s; target >= 100,000)")
    print(f"  MMAE, the paper's blend:    {n / paper_s:12,.0f} samples/s  (lf_output=False; the LF output")
    print(f"    stage costs {mmae_s / paper_s:.2f} x)")
    print(f"  passive batch run (numba):  {passive_rate:12,.0f} samples/s  ({passive_s:.2f} s)")
    print(f"  ratio passive / MMAE:       {passive_rate / mmae_rate:12.2f} x")
    print(f"  MMAE step (per sample):     median {step_median * 1e6:6.2f} µs, p99 {step_p99 * 1e6:6.2f} µs")
    print(f"  MMAE numpy reference:       {ref_rate:12,.0f} samples/s  (timed on {r:,} samples)")
    print(f"  ratio batch / numpy:        {mmae_rate / ref_rate:12,.0f} x")


if __name__ == "__main__":
    main()
