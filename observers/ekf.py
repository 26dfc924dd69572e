"""The DP extended Kalman filter: the industry's baseline wave filter (Balchen, Jenssen, Mathisen & Sælid
1980; Sælid, Jenssen & Balchen 1983), in the textbook form of Fossen (2021), *Handbook of Marine Craft
Hydrodynamics and Motion Control*, 2nd ed., Sec. 13.4 (the DP EKF).

Model — the same one the passive and SDRE observers use, written with x = [η, ν, b, ξ1, ξ2 = η_w]::

    η' = J(ψ) ν + w_η
    M ν' = −D ν + Jᵀ(ψ) b + τ + M w_ν
    b' = w_b                                   (random walk: the commercial choice; T = ∞)
    ξ1' = ξ2,  ξ2' = −ω0² ξ1 − 2ζω0 ξ2 + w_ξ     (2nd-order wave model per DOF)
    y = η + ξ2 + v

with white process noise of intensity Q (15×15) and measurement noise of variance r per sample. The
filter linearises f about x̂ at every step (F = ∂f/∂x, whose only nonlinear entries are the heading's
column: ∂(J(ψ)ν)/∂ψ and ∂(M⁻¹Jᵀ(ψ)b)/∂ψ) — the "linearised about ψ̂" of the textbook, whose drawback
the SDRE paper names (the linearisation holds near the present heading only).

**Discrete time.** Continuous-discrete EKF: between samples, x̂ follows the nonlinear model (RK4 in
sub-steps of at most ``h_max``, τ held) and P ← Φ P Φᵀ + Q h + ½(F Q + Q Fᵀ) h² with
Φ = I + F h + (F h)²/2: the transition and the discretised noise ∫ e^{Fs} Q e^{Fᵀs} ds both to second
order in h (at h = 0.1 s and ω0 ≈ 1 rad/s the neglected terms are ~2e-4 of a step); at each
sample the measured DOFs update x̂ and P. R is diagonal, so the update is done one DOF at a time (scalar
divisions, no matrix inverse; equal to the joint update, which the reference does — tests/test_ekf.py).
Unlike the passive and SDRE observers, the correction is discrete: `predict` is the time update alone,
`step` the time update followed by the measurement update.

**Tuning in physical terms** — the SDRE observer's (`observers.sdre_tuning.SdreTuning`, the same Q): the
process noise intensities follow from the sensors' noise, the expected wave motion and an LF bandwidth
relative to ω0; so one set of numbers serves a 1:70 model and a 200 m ship. The measurement noise is
the sensors' per-sample variance (``position_sigma_m``, ``heading_sigma_rad``).

**Start.** At the first complete measurement: η̂ = y, ν̂ = 0, ξ̂ = 0, b̂ = −J(ψ)τ (the equilibrium), and
P0 = the diagonal of the stationary continuous filter's covariance (the SDRE Riccati solution at ψ = 0,
whose diagonal does not depend on the heading when N and E are tuned alike): the filter starts as sure
of itself as it will be in steady state, neither sluggish nor jumpy.

``observers._ekf_kernel`` is the compiled twin of the readable reference at the end of this module.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers import _ekf_kernel as kernel
from observers.base import Estimate, InitialState, ObserverBase, Run, batch_inputs, step_inputs
from observers.kinematics import rotation, ssa_scalar
from observers.passive_tuning import PassiveTuning
from observers.sdre import estimate_from_state, initial_state
from observers.sdre_tuning import (
    BIAS,
    ETA,
    NU,
    XI2,
    SdreTuning,
    SdreWeights,
    input_matrix,
    output_matrix,
    sdre_weights,
    slowest_error_rate,
    solve_riccati,
    system_matrix,
)
from observers.settling import settle_time_from_rate
from observers.vessel import VesselModel

Array = NDArray[np.float64]

N_STATES = 15


def measurement_variance(tuning: SdreTuning) -> Array:
    """r: the variance of one sample's noise per DOF [N, E, ψ] (m², m², rad²)."""
    return np.array([tuning.position_sigma_m**2, tuning.position_sigma_m**2, tuning.heading_sigma_rad**2])


def initial_covariance(vessel: VesselModel, weights: SdreWeights) -> Array:
    """P0: the diagonal of the stationary continuous filter's covariance (module docstring)."""
    return np.diag(np.diag(solve_riccati(vessel, weights, 0.0)))


class EkfObserver(ObserverBase):
    """The DP extended Kalman filter for any `VesselModel` (the module docstring states the model).

    ``step(t, y, tau)`` for live use, ``run(t, y, tau)`` over arrays: the same kernel, the same numbers.
    ``covariance`` is P after the last sample; `extra` publishes its position and heading 1σ.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: SdreTuning | None = None,
        *,
        h_max: float = 0.1,
    ) -> None:
        self.vessel = vessel
        self.h_max = float(h_max)
        if not self.h_max > 0:
            raise ValueError("h_max must be positive")
        self.tuning = tuning or SdreTuning()
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._MinvD = np.ascontiguousarray(vessel.Minv @ vessel.D)
        self.r = measurement_variance(self.tuning)
        if not np.all(np.isfinite(self.r) & (self.r > 0)):
            raise ValueError("ekf: position_sigma_m and heading_sigma_rad must be positive")
        self.set_weights(sdre_weights(vessel, self.tuning))
        self.reset()

    @classmethod
    def from_params(
        cls, vessel: VesselModel, tuning: PassiveTuning | None, params: dict[str, Any], *,
        allow_unchecked: bool = False,
    ) -> EkfObserver:  # fmt: skip
        """Built by name (`observers.factory`): ω0 and ζ from the common ``tuning``, the rest the fields of
        `SdreTuning` (sensor noise, wave motion, LF bandwidth). ``allow_unchecked`` relaxes nothing: a
        tuning that cannot give a stable filter is refused by `sdre_weights`."""
        common = tuning or PassiveTuning.for_vessel(vessel)  # a model's default is Froude-scaled
        return cls(vessel, SdreTuning(omega0=common.omega0, zeta=common.zeta, **params))

    def set_weights(self, weights: SdreWeights) -> None:
        self.weights = weights
        self._W = np.ascontiguousarray(np.stack([weights.omega0, weights.zeta]))
        self._Q = np.ascontiguousarray(weights.Q)
        self._P0 = np.ascontiguousarray(initial_covariance(self.vessel, weights))
        self._settle_s: float | None = None  # `settle_time_s` of these weights, once asked for

    def reset(self) -> None:
        self.x = np.zeros(N_STATES)
        self.covariance = np.zeros((N_STATES, N_STATES))
        self._clock = np.zeros(2)

    @property
    def omega0(self) -> Array:
        return self.weights.omega0.copy()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: `ENGAGE_TIME_CONSTANTS` time constants of the slowest error mode of
        the SDRE observer with the same weights (`sdre_tuning.slowest_error_rate`). Why that one: the EKF
        has the same model and Q, and the SDRE's R is the per-sample variance r this filter uses times the
        tuning's sample period (R = σ² dt, `sdre_weights`), the continuous intensity of the same noise; it
        starts from P0 = that Riccati solution at ψ = 0, so its gain is the steady Kalman gain from the
        first sample and its error decays with the same poles — the bias pole the slowest (docs/sdre.md).
        An approximation where the sensors' rate differs from ``sample_period_s`` (the gain then differs
        as the information per second does) or the vessel turns fast (the SDRE freezes ψ)."""
        if self._settle_s is None:
            self._settle_s = settle_time_from_rate(slowest_error_rate(self.vessel, self.weights))
        return self._settle_s

    def _begin(self, t: float, start: InitialState) -> None:
        """`initialize`: the given state, with the start covariance P0."""
        self.x[:] = initial_state(start)
        self.covariance[:] = self._P0
        self._set_clock(t)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        y_arr, tau_arr = step_inputs(y, tau)
        code = kernel.step(
            self.x, self.covariance, self._clock, float(t), y_arr, tau_arr, self._W, self._Q, self.r,
            self._P0, self._Minv, self._MinvD, self.h_max
        )  # fmt: skip
        return estimate_from_state(float(t), self.x, code)

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        X = np.empty((n, N_STATES))
        status = np.empty(n, dtype=np.int8)
        kernel.run(
            self.x, self.covariance, self._clock, t_arr, Y, TAU, self._W, self._Q, self.r, self._P0,
            self._Minv, self._MinvD, self.h_max, X, status
        )  # fmt: skip
        omega0 = np.broadcast_to(self.weights.omega0, (n, 3)).copy()
        return Run(t_arr, X[:, ETA], X[:, NU], X[:, BIAS], X[:, XI2], status, omega0)

    def extra(self) -> dict[str, Any]:
        """The filter's own 1σ of the LF position and heading (m, m, rad) — what it believes of itself."""
        if not self.initialized:
            return {}
        return {"eta_sigma": [math.sqrt(max(self.covariance[i, i], 0.0)) for i in range(3)]}


# --- readable reference ----------------------------------------------------------------------------------
# The same filter with the model's matrices in numpy, and the joint (not sequential) measurement update.


def reference_derivative(x: Array, tau: Array, vessel: VesselModel, weights: SdreWeights) -> Array:
    """f(x, τ) = A(ψ) x + B τ: the model written with the SDRE paper's matrices (it is the same model)."""
    A = system_matrix(vessel, weights.omega0, weights.zeta, float(x[2]))
    return A @ x + input_matrix(vessel) @ tau


def reference_jacobian(x: Array, vessel: VesselModel, weights: SdreWeights) -> Array:
    """∂f/∂x: A(ψ) plus the heading's column."""
    psi = float(x[2])
    F = system_matrix(vessel, weights.omega0, weights.zeta, psi)
    dJ = np.array([[-math.sin(psi), -math.cos(psi), 0.0], [math.cos(psi), -math.sin(psi), 0.0], [0, 0, 0]])
    F[ETA, 2] += dJ @ x[NU]
    F[NU, 2] += vessel.Minv @ dJ.T @ x[BIAS]
    return F


def reference_predict(
    x: Array, P: Array, dt: float, tau: Array, vessel: VesselModel, weights: SdreWeights, h_max: float = 0.1
) -> tuple[Array, Array]:
    n = max(1, math.ceil(dt / h_max - 1e-9))
    h = dt / n
    x, P = x.copy(), P.copy()
    for _ in range(n):
        F = reference_jacobian(x, vessel, weights)
        Phi = np.eye(N_STATES) + F * h + 0.5 * (F @ F) * h * h
        k1 = reference_derivative(x, tau, vessel, weights)
        k2 = reference_derivative(x + 0.5 * h * k1, tau, vessel, weights)
        k3 = reference_derivative(x + 0.5 * h * k2, tau, vessel, weights)
        k4 = reference_derivative(x + h * k3, tau, vessel, weights)
        x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        FQ = F @ weights.Q
        P = Phi @ P @ Phi.T + weights.Q * h + 0.5 * (FQ + FQ.T) * h * h
    x[2] = ssa_scalar(x[2])
    return x, P


def reference_update(x: Array, P: Array, y: Array, r: Array) -> tuple[Array, Array]:
    """The joint Kalman update with the measured DOFs (rows of C = [I 0 0 0 I])."""
    valid = ~np.isnan(y)
    if not valid.any():
        return x, P
    H = output_matrix()[valid]
    e = y[valid] - H @ x
    if valid[2]:
        e[-1] = ssa_scalar(e[-1])
    S = H @ P @ H.T + np.diag(r[valid])
    K = P @ H.T @ np.linalg.inv(S)
    x = x + K @ e
    x[2] = ssa_scalar(x[2])
    P = P - K @ H @ P
    return x, 0.5 * (P + P.T)


def reference_run(
    vessel: VesselModel, tuning: SdreTuning, t: Array, y: Array, tau: Array | None = None, h_max: float = 0.1
) -> Array:
    """Reference batch run: states (n, 15), NaN before the first complete measurement."""
    weights = sdre_weights(vessel, tuning)
    r = measurement_variance(tuning)
    P0 = initial_covariance(vessel, weights)
    tau = np.zeros((len(t), 3)) if tau is None else tau
    out = np.full((len(t), N_STATES), np.nan)
    x: Array | None = None
    P = P0
    t_prev = 0.0
    for k in range(len(t)):
        if x is None:
            if np.isnan(y[k]).any():
                continue
            x = np.zeros(N_STATES)
            x[ETA] = y[k]
            x[2] = ssa_scalar(x[2])
            x[BIAS] = -rotation(y[k][2]) @ tau[k]
            P, t_prev = P0.copy(), t[k]
        elif t[k] > t_prev:
            x, P = reference_predict(x, P, t[k] - t_prev, tau[k], vessel, weights, h_max)
            x, P = reference_update(x, P, y[k], r)
            t_prev = t[k]
        out[k] = x
    return out
