"""Cross-flow drag by strip theory with Hoerner's 2-D drag coefficient (Fossen 2021, Sec. 6.7.1).

    Y_cf = −½ ρ T ∫ C_d(x) |v_r + x r| (v_r + x r) dx,     N_cf = −½ ρ T ∫ x C_d(x) |v_r + x r| (v_r + x r) dx

over the hull's length, with the 2-D coefficient of a ship section C_d = C_d^{2D}(B/2T) taken from
Hoerner (1965), *Fluid-Dynamic Drag*, the curve MSS (Hoerner.m) digitised. The integral is a midpoint sum
over ``strips`` equal strips of [−L/2, L/2] about the reference point: 20 strips are within 0.1 % of the
integral for any v_r, r (tests/test_plant.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# Hoerner's 2-D cross-flow drag coefficient of a ship section against B/(2T) (Hoerner 1965, the points MSS
# digitised): data, the published curve.
_HOERNER_B_2T = np.array([0.0108623, 0.176606, 0.353025, 0.451863, 0.472838, 0.492877, 0.493252, 0.558473,
                          0.646401, 0.833589, 0.988002, 1.30807, 1.63918, 1.85998, 2.31288, 2.59998, 3.00877,
                          3.45075, 3.7379, 4.00309])  # fmt: skip
_HOERNER_CD = np.array([1.96608, 1.96573, 1.89756, 1.78718, 1.58374, 1.27862, 1.21082, 1.08356, 0.998631,
                        0.87959, 0.828415, 0.759941, 0.691442, 0.657076, 0.630693, 0.596186, 0.586846,
                        0.585909, 0.559877, 0.559315])  # fmt: skip


def hoerner_cd(beam_m: float, draft_m: float) -> float:
    """Hoerner's 2-D cross-flow drag coefficient at B/(2T); beyond the curve's end, its last value."""
    ratio = beam_m / (2.0 * draft_m)
    return float(np.interp(ratio, _HOERNER_B_2T, _HOERNER_CD))


def strips(length_m: float, n: int) -> tuple[Array, float]:
    """Midpoints of n equal strips over [−L/2, L/2] and their width."""
    dx = length_m / n
    return -0.5 * length_m + dx * (np.arange(n) + 0.5), dx


def crossflow_force(v_r: float, r: float, k: float, xs: Array, dx: float) -> tuple[float, float]:
    """(Y, N) of the cross-flow drag, k = ½ ρ T C_d; the readable form of the kernel's loop."""
    w = v_r + xs * r
    q = np.abs(w) * w * dx
    return float(-k * q.sum()), float(-k * (xs * q).sum())
