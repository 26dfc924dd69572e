"""Noise-free data from the model the observer copies, Fossen & Strand (1999) eqs (14)–(18).

Used to test the observer's convergence: with data from its own model, the estimation error obeys the
error dynamics (30)–(32) exactly, so global exponential stability can be checked directly.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from observers.kinematics import rotation, ssa
from observers.passive_tuning import BIAS, ETA, NU, XI2, PassiveGains
from observers.vessel import VesselModel

TauFn = Callable[[float], np.ndarray]


def model_derivative(
    t: float, x: np.ndarray, vessel: VesselModel, gains: PassiveGains, tau: TauFn
) -> np.ndarray:
    """(14)–(17): ξ' = Ωξ, η' = J(y)ν, b' = -T⁻¹b, Mν' = -Dν + Jᵀ(y)b + τ, with y₃ = ψ + ψ_w (A4)."""
    xi1, xi2, eta, b, nu = x[0:3], x[XI2], x[ETA], x[BIAS], x[NU]
    J = rotation(eta[2] + xi2[2])
    w0, z = gains.omega0, gains.zeta
    d = np.empty(15)
    d[0:3] = xi2
    d[3:6] = -(w0**2) * xi1 - 2 * z * w0 * xi2
    d[ETA] = J @ nu
    d[BIAS] = -b / np.diag(gains.T)
    d[NU] = np.linalg.solve(vessel.M, -vessel.D @ nu + J.T @ b + tau(t))
    return d


def simulate_model(
    vessel: VesselModel, gains: PassiveGains, t: np.ndarray, x0: np.ndarray, tau: TauFn
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate (14)–(17) tightly and sample at t. Returns (states (n, 15), measurements y (n, 3))."""
    sol = solve_ivp(
        model_derivative,
        (t[0], t[-1]),
        x0,
        t_eval=t,
        args=(vessel, gains, tau),
        method="DOP853",
        rtol=1e-11,
        atol=1e-9,
        max_step=0.5,
    )
    assert sol.success, sol.message
    X = sol.y.T
    y = X[:, ETA] + X[:, XI2]  # (18)
    y[:, 2] = ssa(y[:, 2])
    return X, y
