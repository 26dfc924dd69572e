"""Benchmark: the fluid-memory observer's batch `run` and live `step`, beside the passive observer's in the
same run (the machine is shared and noisy: compare the ratios, not the absolute numbers).

Targets: memory batch >= 500,000 samples/s, memory step <= 30 µs. Input: ``bench_passive.make_input``
(10 Hz positions with waves, noise and lost fixes), the supply vessel, the default tuning, the built-in
radiation model (17 states). The numpy reference of the same equations is timed on a slice.

    python bench/bench_memory.py [--hours 4] [--rate 10] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

from _timing import best_of, step_latency
from bench_passive import make_input

from observers.memory import MemoryObserver, reference_run
from observers.passive import PassiveObserver
from observers.vessel import load_vessel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=4.0)
    ap.add_argument("--rate", type=float, default=10.0, help="sample rate (Hz)")
    ap.add_argument("--step-samples", type=int, default=100_000)
    ap.add_argument("--reference-samples", type=int, default=3_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    vessel = load_vessel("mss_supply")
    t, y, tau = make_input(args.hours, args.rate)
    n = len(t)
    makers = {"memory": lambda: MemoryObserver(vessel), "passive": lambda: PassiveObserver(vessel)}
    for make in makers.values():
        make().run(t[:100], y[:100], tau[:100])  # compile (cached on disk after the first run)

    result: dict[str, float | int] = {"samples": n, "hours": args.hours, "rate_hz": args.rate}
    # interleaved, best of 3 each: both see the same machine load
    best = {name: float("inf") for name in makers}
    for _ in range(3):
        for name, make in makers.items():
            best[name] = min(best[name], best_of(1, lambda make=make: make().run(t, y, tau)))
    for name, make in makers.items():
        med, p99 = step_latency(make(), t, y, tau, args.step_samples)
        result[f"{name}_batch_samples_per_s"] = n / best[name]
        result[f"{name}_step_median_us"] = med * 1e6
        result[f"{name}_step_p99_us"] = p99 * 1e6
    r = args.reference_samples
    gains = MemoryObserver(vessel).gains
    t0 = time.perf_counter()
    reference_run(gains, t[:r], y[:r], tau[:r])
    result["memory_numpy_reference_samples_per_s"] = r / (time.perf_counter() - t0)
    result["batch_ratio_memory_to_passive"] = best["passive"] / best["memory"]
    result["step_ratio_memory_to_passive"] = (
        result["memory_step_median_us"] / result["passive_step_median_us"]
    )
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(
        f"mss_supply, {args.hours:g} h at {args.rate:g} Hz = {n:,} samples; memory model 17 radiation states"
    )
    for name in makers:
        print(
            f"  {name:8s} batch {result[f'{name}_batch_samples_per_s']:12,.0f} samples/s   step median "
            f"{result[f'{name}_step_median_us']:6.2f} µs, p99 {result[f'{name}_step_p99_us']:6.2f} µs"
        )
    print(f"  memory / passive: batch speed {result['batch_ratio_memory_to_passive']:.2f}x, "
          f"step time {result['step_ratio_memory_to_passive']:.2f}x")  # fmt: skip
    print(f"  memory numpy reference: {result['memory_numpy_reference_samples_per_s']:,.0f} samples/s")
    print("  targets: memory batch >= 500,000 samples/s, memory step <= 30 µs")


if __name__ == "__main__":
    main()
