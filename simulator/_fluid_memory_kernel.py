"""Compiled kernels of the fluid-memory states, each beside the readable numpy reference it must equal.

The state space is x_r' = A x_r + B ν, μ = C x_r + D ν (`simulator.fluid_memory`). A plant either steps it
on its own with the exact first-order-hold discretisation (`memory_step`), or carries x_r in its own RK4
state and calls `memory_derivative` / `memory_force` from inside its compiled stage function (numba can
call one njit function from another; a Python call per stage would cost more than the arithmetic).

The loops are written out because the matrices are small (17 states for the supply vessel): numba's
explicit loops beat a BLAS call's set-up at this size, and they allocate nothing.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.floating[Any]]


@njit(cache=True)
def memory_step(x, nu0, nu1, phi, g0, g1, out):
    """out = Φ x + Γ₀ ν₀ + Γ₁ ν₁: one exact step with ν linear from ν₀ to ν₁ (out may not alias x)."""
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += phi[i, j] * x[j]
        for j in range(3):
            acc += g0[i, j] * nu0[j] + g1[i, j] * nu1[j]
        out[i] = acc


@njit(cache=True)
def memory_derivative(x, nu, a, b, out):
    """out = A x + B ν (an RK4 stage of a plant carrying x_r in its state)."""
    n = x.shape[0]
    for i in range(n):
        acc = b[i, 0] * nu[0] + b[i, 1] * nu[1] + b[i, 2] * nu[2]
        for j in range(n):
            acc += a[i, j] * x[j]
        out[i] = acc


@njit(cache=True)
def memory_force(x, nu, c, d, out):
    """out = μ = C x + D ν, the memory part of the radiation force (the plant applies -μ)."""
    n = x.shape[0]
    for i in range(3):
        acc = d[i, 0] * nu[0] + d[i, 1] * nu[1] + d[i, 2] * nu[2]
        for j in range(n):
            acc += c[i, j] * x[j]
        out[i] = acc


def memory_step_reference(x: Array, nu0: Array, nu1: Array, phi: Array, g0: Array, g1: Array) -> Array:
    return phi @ x + g0 @ nu0 + g1 @ nu1


def memory_derivative_reference(x: Array, nu: Array, a: Array, b: Array) -> Array:
    return a @ x + b @ nu


def memory_force_reference(x: Array, nu: Array, c: Array, d: Array) -> Array:
    return c @ x + d @ nu
