"""Kinematics of the 3-DOF horizontal-plane model: rotation J(ψ) and the smallest signed angle.

Fossen & Strand (1999), eq (2)::

    J(ψ) = [[cos ψ, -sin ψ, 0], [sin ψ, cos ψ, 0], [0, 0, 1]],    η' = J(ψ) ν              (1)

Every angle difference in dpgw goes through the smallest signed angle defined here, so that a heading
crossing ±180° (0°/360° on the compass) never produces a 2π step (Fossen & Strand's heading innovation of
eqs (12)/(18) must be wrapped). There is one definition, `ssa_scalar`, in three forms: `ssa_scalar` for
one float, `ssa` for arrays (the same arithmetic, element-wise) and `ssa_jit`, the same Python function
compiled by numba for the compiled kernels. All three give the same bits for the same input.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray


def ssa_scalar(angle: float) -> float:
    """Smallest signed angle of one float: map any angle (rad) to [-π, π)."""
    a = (angle + math.pi) % (2.0 * math.pi) - math.pi
    # For an angle a hair below -π (or below -π - 2kπ), angle + π is a tiny negative number and its
    # remainder rounds up to 2π itself, which would give +π: fold that one value back to -π.
    return a - 2.0 * math.pi if a >= math.pi else a


def ssa(angle: ArrayLike) -> NDArray[np.float64]:
    """`ssa_scalar` element-wise for arrays (numpy's ``mod`` is Python's float ``%``, bit for bit)."""
    a = np.mod(np.asarray(angle, dtype=float) + math.pi, 2.0 * math.pi) - math.pi
    return a - 2.0 * math.pi * (a >= math.pi)  # subtracting 0.0 leaves every other value's bits alone


ssa_jit = njit(cache=True)(ssa_scalar)
"""`ssa_scalar` compiled for numba kernels (call it from ``@njit`` code; numba's float ``%`` is Python's)."""


def rotation(psi: float) -> NDArray[np.float64]:
    """J(ψ) of eq (2): body-frame velocity to earth-fixed (NED) rate of change."""
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def lever_arm_ned(
    psi: float, phi: float, theta: float, x: float, y: float, z: float
) -> tuple[float, float, float]:
    """A body-frame lever arm [x, y, z] (x forward, y starboard, z down) turned into NED by the zyx Euler
    angles: R_zyx(φ, θ, ψ)·[x, y, z] (Fossen 2021, eq. 2.18), with φ roll (starboard down positive), θ
    pitch (bow up positive), ψ heading::

        R_zyx = R_z(ψ) R_y(θ) R_x(φ)

    computed as the three plane rotations in turn (roll, then pitch, then heading) on plain floats. With
    φ = θ = 0 it is J(ψ)[x, y] of eq (1) and z unchanged. The one definition: the simulator's antenna
    (`simulator.sensors.antenna_ned`) and the gateway's lever-arm compensation (`gateway.fusion`) both
    call it, so that compensating a simulated fix with the true attitude gives the reference point back
    to rounding."""
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    y1, z1 = cf * y - sf * z, sf * y + cf * z  # R_x(φ)
    x2, z2 = ct * x + st * z1, -st * x + ct * z1  # R_y(θ)
    c, s = math.cos(psi), math.sin(psi)  # R_z(ψ)
    return c * x2 - s * y1, s * x2 + c * y1, z2
