"""Benchmark: the replay report on a long log — `compute_metrics` and `write_report` (with the six PNGs), and
the share of the Welch spectra in the metrics.

Synthetic data: 10 Hz fixes of slow drift plus a 0.6 rad/s wave, two observers at 10 Hz (one leaving 5 %
of the wave in its LF estimate, one 50 %), `mss_supply`. The report's spectra are `scipy.signal.welch`;
this prints how much of the metrics' time they take, the figure that decides whether a faster hand-made
Welch would be worth keeping.

    python bench/bench_report.py [--hours 24] [--rate 10] [--no-plots] [--json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from typing import Any

import numpy as np
from _timing import best_of

import gateway.report.metrics as metrics_module
from gateway.report import ObserverTrace, ReplayData, compute_metrics, write_report
from gateway.report.spectra import welch
from observers.kinematics import ssa

W_WAVE = 0.6  # rad/s


def make_data(hours: float, rate: float, seed: int = 1) -> ReplayData:
    t = np.arange(0.0, hours * 3600.0, 1.0 / rate)
    n = len(t)
    lf = np.column_stack([3.0 * np.sin(1e-3 * t), -2.0 * np.cos(1.3e-3 * t), 3.1 + 0.02 * np.sin(2e-3 * t)])
    wf = np.column_stack([np.sin(W_WAVE * t), 0.7 * np.sin(W_WAVE * t + 0.5), 0.01 * np.sin(W_WAVE * t + 1)])
    rng = np.random.default_rng(seed)
    y = lf + wf + rng.normal(0.0, [0.02, 0.02, 0.0005], (n, 3))
    y[:, 2] = ssa(y[:, 2])

    def trace(label: str, left: float) -> ObserverTrace:
        eta = lf + left * wf
        eta[:, 2] = ssa(eta[:, 2])
        z = np.zeros((n, 3))
        return ObserverTrace(label, t, eta, z, z, (1.0 - left) * wf, np.full((n, 3), W_WAVE))

    return ReplayData("bench", "mss_supply", t, y, (trace("passive", 0.05), trace("half", 0.5)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--rate", type=float, default=10.0, help="Hz, fixes and estimates")
    ap.add_argument("--no-plots", action="store_true", help="time write_report without the PNGs")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    data = make_data(args.hours, args.rate)

    welch_s = [0.0]

    def timed_welch(*a: Any, **kw: Any) -> Any:
        t0 = time.perf_counter()
        out = welch(*a, **kw)
        welch_s[0] += time.perf_counter() - t0
        return out

    metrics_module.welch = timed_welch  # type: ignore[assignment]  # count the spectra's share
    metrics_s = best_of(3, lambda: compute_metrics(data))
    welch_s[0] = 0.0
    compute_metrics(data)
    welch_share_s = welch_s[0]
    metrics_module.welch = welch  # type: ignore[assignment]
    with tempfile.TemporaryDirectory() as folder:
        report_s = best_of(1, lambda: write_report(data, folder, plots=not args.no_plots))

    result = {
        "samples": len(data.t_meas),
        "observers": len(data.traces),
        "compute_metrics_s": round(metrics_s, 3),
        "welch_s": round(welch_share_s, 3),
        "write_report_s": round(report_s, 3),
        "plots": not args.no_plots,
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"{result['samples']} fixes, {result['observers']} observers at {args.rate:g} Hz")
    print(f"compute_metrics: {metrics_s:.2f} s (Welch spectra with high-pass: {welch_share_s:.2f} s)")
    print(f"write_report ({'with' if not args.no_plots else 'without'} plots): {report_s:.2f} s")


if __name__ == "__main__":
    main()
