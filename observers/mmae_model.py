"""The model of one MMAE filter, its discretisation and its steady-state tables (Hassani et al. (7)–(14),
as corrected in `observers.mmae`'s docstring): shared by the bank (`observers.mmae.design_bank`) and the
LF output stage (`observers.mmae_lf`), which designs single filters of the same model."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from observers.state import BIAS, ETA, N_STATE, NU, XI1, XI2
from observers.vessel import VesselModel

Array = NDArray[np.float64]

MASKS = ((False, False, False), (True, True, False), (False, False, True), (True, True, True))
"""Measured DOFs [N, E, ψ] for mask index m = (position present) + 2·(heading present)."""


def continuous_model(vessel: VesselModel, omega0: float, zeta: float) -> tuple[Array, Array, Array, Array]:
    """A(ω0), B, G, C of (13)–(14) with the misprints corrected (`observers.mmae`'s docstring)."""
    Minv = vessel.Minv
    A = np.zeros((N_STATE, N_STATE))
    A[XI1, XI2] = np.eye(3)
    A[XI2, XI1] = -(omega0**2) * np.eye(3)  # -Ω
    A[XI2, XI2] = -2.0 * zeta * omega0 * np.eye(3)  # -Λ
    A[ETA, NU] = np.eye(3)  # (8)
    A[NU, BIAS] = Minv  # (9): ν' = M⁻¹ b_p − M⁻¹ D ν + M⁻¹ τ + M⁻¹ w2
    A[NU, NU] = -Minv @ vessel.D
    B = np.zeros((N_STATE, 3))
    B[NU] = Minv
    G = np.zeros((N_STATE, 9))
    G[XI2, 0:3] = np.eye(3)  # E_w w1
    G[NU, 3:6] = Minv  # M⁻¹ w2
    G[BIAS, 6:9] = np.eye(3)  # w3
    C = np.zeros((3, N_STATE))
    C[:, XI2] = np.eye(3)  # C_w
    C[:, ETA] = np.eye(3)
    return A, B, G, C


def discretize(A: Array, B: Array, G: Array, Q: Array, dt: float) -> tuple[Array, Array, Array]:
    """Zero-order hold (Φ, Γ) and Van Loan's Q_d = ∫₀^dt e^{As} G Q Gᵀ e^{Aᵀs} ds."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    E = expm(aug * dt)
    Phi, Gam = E[:n, :n], E[:n, n:]
    V = np.zeros((2 * n, 2 * n))
    V[:n, :n] = -A
    V[:n, n:] = G @ Q @ G.T
    V[n:, n:] = A.T
    F = expm(V * dt)
    Qd = F[n:, n:].T @ F[:n, n:]
    return Phi, Gam, 0.5 * (Qd + Qd.T)


def filter_tables(P: Array, C: Array, R: Array, K: Array, Sinv: Array, logdet: Array) -> tuple[Array, Array]:
    """From the steady-state prior P: the innovation covariance S = C P Cᵀ + R and, per mask m (`MASKS`),
    the one-step gain K[m] = P C_vᵀ S_vv⁻¹, S_vv⁻¹ (Sinv[m]) and log det S_vv (logdet[m]) of the DOFs
    measured (K (4, 15, 3), Sinv (4, 3, 3), logdet (4,) filled in place, zero for DOFs not measured).
    Returns P and S, symmetrised."""
    P = 0.5 * (P + P.T)
    S = C @ P @ C.T + R
    S = 0.5 * (S + S.T)
    for m, mask in enumerate(MASKS):
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            continue
        Svv = S[np.ix_(idx, idx)]
        Svv_inv = np.linalg.inv(Svv)
        K[m][:, idx] = P @ C[idx].T @ Svv_inv
        Sinv[m][np.ix_(idx, idx)] = Svv_inv
        logdet[m] = np.linalg.slogdet(Svv)[1]
    return P, S
