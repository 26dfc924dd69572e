"""The discrete algebraic Riccati equation by the structure-preserving doubling algorithm (SDA).

Solves, for the stabilising X = Xᵀ ⪰ 0 (the same equation and argument order as
`scipy.linalg.solve_discrete_are(a, b, q, r)`)::

    X = aᵀ X a − aᵀ X b (r + bᵀ X b)⁻¹ bᵀ X a + q

Chu, Fan, Lin & Wang, "Structure-preserving algorithms for periodic discrete-time algebraic Riccati
equations", Int. J. Control 77 (2004); the doubling iteration for the DARE, with G = b r⁻¹ bᵀ, H = q::

    W_k = I + G_k H_k
    A_{k+1} = A_k W_k⁻¹ A_k
    G_{k+1} = G_k + A_k W_k⁻¹ G_k A_kᵀ
    H_{k+1} = H_k + A_kᵀ H_k W_k⁻¹ A_k          H_k → X

converging quadratically: the error falls as ρ(closed loop)^(2^k), so a closed-loop mode of 0.9999 per step
needs about 17 doublings. Why it exists beside scipy: the MMAE's LF output stage designs a 15-state filter
many times a run, and scipy's QZ-based solver spends most of its ~5 ms in set-up for a matrix this small; the
doubling iteration is a few dozen 15×15 products (bench/bench_mmae.py). scipy stays the reference
(tests/test_mmae.py checks they agree) and the fallback when the iteration does not converge.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import solve_discrete_are

Array = NDArray[np.float64]


def solve_dare_doubling(
    a: Array, b: Array, q: Array, r: Array, *, rtol: float = 1e-13, max_iter: int = 64
) -> Array:
    """X of the DARE above by doubling; `scipy.linalg.solve_discrete_are` if it has not converged (relative
    change of H below ``rtol``) within ``max_iter`` doublings or met a singular W."""
    n = a.shape[0]
    eye = np.eye(n)
    A = np.array(a, dtype=float)
    G = b @ np.linalg.solve(r, b.T)
    G = 0.5 * (G + G.T)
    H = np.array(q, dtype=float)
    try:
        for _ in range(max_iter):
            W = eye + G @ H
            WiA = np.linalg.solve(W, A)  # W⁻¹ A
            WiG = np.linalg.solve(W, G)  # W⁻¹ G
            H_next = H + A.T @ H @ WiA
            G = G + A @ WiG @ A.T
            A = A @ WiA
            G = 0.5 * (G + G.T)
            H_next = 0.5 * (H_next + H_next.T)
            change = np.abs(H_next - H).max()
            H = H_next
            if change <= rtol * np.abs(H).max():
                return H
    except np.linalg.LinAlgError:
        pass
    return np.asarray(solve_discrete_are(a, b, q, r))
