"""Timing helpers shared by the observer benchmarks (imported as a sibling: run benches as scripts)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np


def best_of(runs: int, fn: Callable[[], object]) -> float:
    """Fastest wall time (s) of ``runs`` calls: the least disturbed by other load on a shared machine."""
    best = math.inf
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def step_latency(
    obs: Any, t: np.ndarray, y: np.ndarray, tau: np.ndarray, samples: int
) -> tuple[float, float]:
    """(median, p99) seconds of ``obs.step`` over the first ``samples`` rows, the first 100 (warm-up) dropped.

    Rows are sliced beforehand so the timing holds the step alone, as a live caller would call it.
    """
    m = min(len(t), samples)
    rows_y = [y[k] for k in range(m)]
    rows_tau = [tau[k] for k in range(m)]
    times = np.empty(m)
    for k in range(m):
        t0 = time.perf_counter()
        obs.step(t[k], rows_y[k], rows_tau[k])
        times[k] = time.perf_counter() - t0
    return float(np.median(times[100:])), float(np.percentile(times[100:], 99))
