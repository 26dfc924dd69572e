"""The readable reference loop of the state observers: what their compiled kernels are checked against.

Each observer states its own continuous-time model as a numpy derivative x' = f(x, valid) (`valid`: which
DOFs of the held measurement inject); the way that model is sampled is the same for all of them and is
written once here:

* between samples, y and τ are held; the interval is integrated by classical RK4 in equal sub-steps of
  at most ``h_max`` seconds;
* when a sample comes after a silence longer than ``max_hold_s``, all but the last ``max_hold_s`` of the
  interval is dead reckoning (no injection): a measurement is not treated as if seen all along;
* the first sample with every DOF measured starts the observer at the equilibrium for that sample;
  repeated or backward times are not integrated.

Slow, plain numpy; used by the tests and as the baselines of the observer benchmarks.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
Derivative = Callable[[Array, NDArray[np.bool_]], Array]


def rk4_held(
    f: Derivative, x: Array, dt: float, valid: NDArray[np.bool_], h_max: float, max_hold_s: float
) -> Array:
    """x after an interval dt with the sample held: dead reckoning for what exceeds ``max_hold_s``, then
    the sample's own ``valid`` DOFs injecting (RK4, sub-steps ≤ ``h_max``)."""

    def integrate(x: Array, span: float, valid: NDArray[np.bool_]) -> Array:
        if span <= 0:
            return x
        n = max(1, math.ceil(span / h_max - 1e-9))
        h = span / n
        for _ in range(n):
            k1 = f(x, valid)
            k2 = f(x + 0.5 * h * k1, valid)
            k3 = f(x + 0.5 * h * k2, valid)
            k4 = f(x + h * k3, valid)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x

    dead = max(dt - max_hold_s, 0.0)
    x = integrate(x, dead, np.zeros(3, dtype=bool))
    return integrate(x, dt - dead, valid)


def reference_loop(
    t: Array,
    y: Array,
    tau: Array | None,
    equilibrium: Callable[[Array, Array], Array],
    propagate: Callable[[Array, float, Array, Array], Array],
    n_state: int = 15,
) -> Array:
    """States (n, ``n_state``) after each sample, NaN before the observer starts: ``equilibrium(y, τ)`` at
    the first complete sample, then ``propagate(x, dt, y, τ)`` for every later time."""
    n = len(t)
    tau = np.zeros((n, 3)) if tau is None else np.asarray(tau, dtype=float)
    X = np.full((n, n_state), np.nan)
    x: Array | None = None
    t_prev = 0.0
    for k in range(n):
        if x is None:
            if np.all(np.isfinite(y[k])):
                x = equilibrium(y[k], np.nan_to_num(tau[k]))
                t_prev = t[k]
                X[k] = x
            continue
        if t[k] > t_prev:
            x = propagate(x, t[k] - t_prev, y[k], tau[k])
            t_prev = t[k]
        X[k] = x
    return X
