"""Benchmark: SDRE observer batch `run` and per-sample `step`, beside the passive observer in the same run.

Targets: batch >= 200,000 samples/s, step <= 30 µs. The input is bench_passive's (10 Hz, waves, noise,
occasional lost fixes, mss_supply). Also timed: the numpy reference of the same equations (on a slice),
and the Riccati solutions (one per ω0 when N and E are tuned alike; a 1° table otherwise).

    python bench/bench_sdre.py [--hours 2] [--rate 10] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

from _timing import best_of, step_latency
from bench_passive import make_input

from observers.passive import PassiveObserver
from observers.sdre import SdreObserver, reference_run
from observers.sdre_tuning import SdreTuning, error_eigenvalues, paper_weights, sdre_weights
from observers.vessel import load_vessel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=2.0)
    ap.add_argument("--rate", type=float, default=10.0, help="sample rate (Hz)")
    ap.add_argument("--reference-samples", type=int, default=5_000)
    ap.add_argument("--step-samples", type=int, default=100_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    vessel = load_vessel("mss_supply")
    t, y, tau = make_input(args.hours, args.rate)
    n = len(t)

    # compile both kernels (cached on disk after the first run)
    SdreObserver(vessel).run(t[:100], y[:100], tau[:100])
    PassiveObserver(vessel).run(t[:100], y[:100], tau[:100])

    sdre_batch = best_of(3, lambda: SdreObserver(vessel).run(t, y, tau))
    passive_batch = best_of(3, lambda: PassiveObserver(vessel).run(t, y, tau))
    sdre_step, sdre_p99 = step_latency(SdreObserver(vessel), t, y, tau, args.step_samples)
    passive_step, passive_p99 = step_latency(PassiveObserver(vessel), t, y, tau, args.step_samples)

    solve_one = best_of(3, lambda: SdreObserver(vessel))
    solve_table = best_of(1, lambda: SdreObserver(vessel, SdreTuning(omega0=(0.8, 0.9, 0.85))))

    obs = SdreObserver(vessel)
    r = args.reference_samples
    t0 = time.perf_counter()
    reference_run(vessel, obs.weights, obs.table, t[:r], y[:r], tau[:r])
    ref_rate = r / (time.perf_counter() - t0)

    result = {
        "samples": n,
        "sdre_batch_samples_per_s": n / sdre_batch,
        "passive_batch_samples_per_s": n / passive_batch,
        "sdre_step_median_us": sdre_step * 1e6,
        "sdre_step_p99_us": sdre_p99 * 1e6,
        "passive_step_median_us": passive_step * 1e6,
        "passive_step_p99_us": passive_p99 * 1e6,
        "batch_ratio_sdre_over_passive": passive_batch / sdre_batch,
        "step_ratio_sdre_over_passive": sdre_step / passive_step,
        "sdre_numpy_reference_samples_per_s": ref_rate,
        "riccati_one_solution_s": solve_one,
        "riccati_table_180_s": solve_table,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"mss_supply, {args.hours:g} h at {args.rate:g} Hz = {n:,} samples")
    print(f"                          {'sdre':>14s} {'passive':>14s}   ratio sdre/passive")
    print(
        f"  batch (samples/s)       {n / sdre_batch:14,.0f} {n / passive_batch:14,.0f}"
        f"   {(n / sdre_batch) / (n / passive_batch):6.2f}   (target sdre >= 200,000)"
    )
    print(
        f"  step median (µs)        {sdre_step * 1e6:14.2f} {passive_step * 1e6:14.2f}"
        f"   {sdre_step / passive_step:6.2f}   (target sdre <= 30)"
    )
    print(f"  step p99 (µs)           {sdre_p99 * 1e6:14.2f} {passive_p99 * 1e6:14.2f}")
    print(
        f"  sdre numpy reference    {ref_rate:14,.0f} samples/s (batch is {n / sdre_batch / ref_rate:,.0f}x)"
    )
    print(
        f"  Riccati: one solution (N, E alike) {solve_one * 1e3:.1f} ms; 180-point table {solve_table:.2f} s"
    )
    print_error_poles()


def print_error_poles() -> None:
    """Eigenvalues of A − KC (any heading: they do not depend on it) for the defaults and the paper's Q, R."""
    w0 = 2 * math.pi / 12.0
    for name in ("snijders_ship", "mss_supply", "cybership2"):
        vessel = load_vessel(name)
        for label, weights in (
            ("dpgw defaults", sdre_weights(vessel, SdreTuning(omega0=w0))),
            ("paper Q, R in SI", paper_weights(w0)),
        ):
            ev = error_eigenvalues(vessel, weights)
            poles = ", ".join(
                f"{z.real:.3g}{z.imag:+.3g}j" if z.imag > 0 else f"{z.real:.3g}" for z in ev if z.imag >= 0
            )
            print(f"  error poles, {name}, {label} (ω0 = 2π/12 s): {poles}")


if __name__ == "__main__":
    main()
