"""Kinematics of the 3-DOF horizontal-plane model: rotation J(ψ) and the smallest signed angle.

Fossen & Strand (1999), eq (2)::

    J(ψ) = [[cos ψ, -sin ψ, 0], [sin ψ, cos ψ, 0], [0, 0, 1]],    η' = J(ψ) ν              (1)

Every angle difference in dpgw goes through `ssa` (DESIGN.md, conventions), so that a heading crossing
±180° (0°/360° on the compass) never produces a 2π step (ERRATA: the heading innovation of eq (12)/(18)).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def ssa(angle: ArrayLike) -> NDArray[np.float64]:
    """Smallest signed angle: map any angle (rad) to [-π, π)."""
    a = np.asarray(angle, dtype=float)
    return np.mod(a + math.pi, 2.0 * math.pi) - math.pi


def ssa_scalar(angle: float) -> float:
    """`ssa` for one float, without numpy overhead."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def rotation(psi: float) -> NDArray[np.float64]:
    """J(ψ) of eq (2): body-frame velocity to earth-fixed (NED) rate of change."""
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
