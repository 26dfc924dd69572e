"""Passive nonlinear observer of Fossen & Strand (1999), eqs (22)–(26).

Model (14)–(18), ψ in J taken from the measured heading (assumption A4)::

    ξ' = Ω ξ,   η' = J(y) ν,   b' = -T⁻¹ b,   M ν' = -D ν + Jᵀ(y) b + τ,   y = η + Γ ξ     (14)–(18)

Observer::

    ξ̂' = Ω ξ̂ + K1 ỹ                                                               (22)
    η̂' = J(y) ν̂ + K2 ỹ                                                             (23)
    b̂' = -T⁻¹ b̂ + Λ ỹ                         (Λ = K3; γ = 1, see passive_tuning)   (24)
    M ν̂' = -D ν̂ + Jᵀ(y) b̂ + τ + Jᵀ(y) 𝒦 ỹ      (𝒦 = K4)                             (25)
    ŷ = η̂ + Γ ξ̂,   ỹ = y − ŷ,  ỹ₃ wrapped to [-π, π) (else a 0°/360° crossing jumps 2π)  (26)

State x = [ξ1, ξ2 = η̂_w, η̂, b̂, ν̂] (15). Gains: `observers.passive_tuning`.

Discrete time. The paper's observer is continuous; measurements arrive at 1–50 Hz, at variable
intervals. Each sample's y and τ are held over the interval that ends at its time stamp (so the estimate
at t_k has already used y_k: no added sample of delay), and the ODE is integrated exactly enough by RK4 in
sub-steps of at most ``h_max`` (0.1 s by default: error poles reach -1.3 s⁻¹, and forward Euler at 1 Hz
is not accurate). A DOF whose measurement is missing (NaN) gets no injection: it is dead
reckoning, and J uses the estimated heading ŷ₃ when the heading itself is missing. A gap longer than
``max_hold_s`` is dead reckoning except for its last ``max_hold_s``. ``tests/test_passive_observer.py``
states the agreement reached with a tight-tolerance continuous-time integration.

The observer is not split into a predict and an update: its injection is continuous over each interval
(there is no discrete correction to separate out). `predict` advances without measurement (pure dead
reckoning); `step` advances with one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers import _passive_kernel as kernel
from observers.base import (
    STATUS_INITIALIZING,
    STATUS_NAMES,
    ZERO3,
    Estimate,
    InitialState,
    ObserverBase,
    Run,
    batch_inputs,
)
from observers.kinematics import rotation, ssa_scalar
from observers.passive_tuning import PassiveGains, PassiveTuning, passive_gains, slowest_error_rate, validate
from observers.reference import reference_loop, rk4_held
from observers.settling import settle_time_from_rate
from observers.state import BIAS, ETA, I_PSI, N_STATE, NU, XI, XI2, StateView
from observers.vessel import VesselModel

Array = NDArray[np.float64]


def pack_gains(gains: PassiveGains) -> Array:
    """The (8, 3) array the kernel reads, one row per quantity (`observers._passive_kernel`, ``G_*``)."""
    for name in ("K2", "K3", "K4", "T"):
        M = getattr(gains, name)
        if np.count_nonzero(M[~np.eye(3, dtype=bool)]):
            raise ValueError(f"gain {name} must be diagonal (structure of Proposition 1, (40)–(41))")
    G = np.empty((kernel.N_GAIN_ROWS, 3))
    G[kernel.G_OMEGA0] = gains.omega0
    G[kernel.G_ZETA] = gains.zeta
    G[kernel.G_K1] = gains.k1
    G[kernel.G_K2] = gains.k2
    G[kernel.G_K3] = gains.k3
    G[kernel.G_LAMBDA] = np.diag(gains.K3)
    G[kernel.G_KAPPA] = np.diag(gains.K4)
    G[kernel.G_T_INV] = gains.t_inv
    return G


def initial_state(start: InitialState) -> Array:
    """The 15-state vector (`observers.state`) for an explicit start (ψ wrapped; omitted parts zero)."""
    state = StateView.zeros()
    state.eta[:] = start.eta
    state.x[I_PSI] = ssa_scalar(state.x[I_PSI])
    for part, value in ((state.nu, start.nu), (state.bias, start.bias), (state.eta_wf, start.eta_wf)):
        if value is not None:
            part[:] = value
    return state.x


def estimate_from_state(t: float, x: Array, code: int) -> Estimate:
    """The estimate a kernel status ``code`` and state ``x`` stand for (copies; NaN while initialising)."""
    if code == STATUS_INITIALIZING:
        return Estimate.initializing(t)
    return Estimate(t, x[ETA].copy(), x[NU].copy(), x[BIAS].copy(), x[XI2].copy(), STATUS_NAMES[code])


class PassiveObserver(ObserverBase):
    """Fossen & Strand (1999) passive observer for any `VesselModel` (the module docstring has the details).

    Model, (14)–(18), with ψ in J taken from the measured heading (assumption A4)::

        ξ' = Ω ξ,   η' = J(y) ν,   b' = -T⁻¹ b,   M ν' = -D ν + Jᵀ(y) b + τ,   y = η + Γ ξ

    State x = [ξ1, ξ2 = η̂_w, η̂, b̂, ν̂] (`observers.state`; ``state`` names its parts). Gains from a
    physical `PassiveTuning` (`observers.passive_tuning`). `predict` is dead reckoning (no injection);
    `step` integrates (22)–(26) over the interval with the sample's y and τ held. ``step`` for live use,
    ``run`` over arrays: both use the same kernel and give the same numbers. `Run.extras`: none.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: PassiveTuning | None = None,
        *,
        gains: PassiveGains | None = None,
        allow_unchecked: bool = False,
        h_max: float = 0.1,
        max_hold_s: float = 2.0,
    ) -> None:
        self.vessel = vessel
        self.h_max = float(h_max)
        self.max_hold_s = float(max_hold_s)
        if not (self.h_max > 0 and self.max_hold_s > 0):
            raise ValueError("h_max and max_hold_s must be positive")
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._D = np.ascontiguousarray(vessel.D, dtype=float)
        self.set_gains(gains if gains is not None else passive_gains(vessel, tuning), allow_unchecked)
        self.reset()

    def set_gains(self, gains: PassiveGains, allow_unchecked: bool = False) -> None:
        """Use new gains from now on (the state is kept: no jump in the estimates)."""
        if not allow_unchecked:
            validate(gains)
        self.gains = gains
        self._G = pack_gains(gains)
        self._settle_s: float | None = None  # `settle_time_s` of these gains, once asked for

    def reset(self) -> None:
        self.x = np.zeros(N_STATE)
        self._clock = np.zeros(2)  # kernel.CLOCK_T, kernel.CLOCK_STARTED

    @property
    def state(self) -> StateView:
        """The state by name (a view: writing to it changes the observer)."""
        return StateView(self.x)

    @property
    def omega0(self) -> Array:
        """The wave frequency the filter is tuned to, per DOF (rad/s) — fixed for this observer."""
        return self.gains.omega0.copy()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: `ENGAGE_TIME_CONSTANTS` time constants of the slowest eigenvalue of
        the error dynamics (30)–(32) over all headings (`passive_tuning.slowest_error_rate`): the bias
        mode, ≈ aρ/(d + a) per DOF (docs/passive-observer.md); 145 s on the default scenario."""
        if self._settle_s is None:
            self._settle_s = settle_time_from_rate(slowest_error_rate(self.vessel, self.gains))
        return self._settle_s

    def _begin(self, t: float, start: InitialState) -> None:
        """`initialize`; without it the first complete measurement starts the observer in equilibrium."""
        self.x[:] = initial_state(start)
        self._set_clock(t)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t (s) with measurement y and generalised force τ held since the last sample."""
        # inline (not `step_inputs`): the live path; a call costs 0.5 µs a sample here
        y_arr = np.asarray(y, dtype=float)
        tau_arr = ZERO3 if tau is None else np.asarray(tau, dtype=float)
        code = kernel.step(
            self.x, self._clock, float(t), y_arr, tau_arr, self._G, self._Minv, self._D, self.h_max,
            self.max_hold_s
        )  # fmt: skip
        return estimate_from_state(float(t), self.x, code)

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample: t (n,), y (n, 3) with NaN for missing, τ (n, 3) or None for zero."""
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        X = np.empty((n, N_STATE))
        status = np.empty(n, dtype=np.int8)
        kernel.run(
            self.x, self._clock, t_arr, Y, TAU, self._G, self._Minv, self._D, self.h_max, self.max_hold_s,
            X, status
        )  # fmt: skip
        omega0 = np.broadcast_to(self.gains.omega0, (n, 3))  # fixed gains: one row, repeated (a view)
        return Run(t_arr, X[:, ETA], X[:, NU], X[:, BIAS], X[:, XI2], status, omega0)


# --- readable reference ----------------------------------------------------------------------------------
# The same equations written with the paper's matrices, in numpy. Slow; used to check the kernel and as
# the baseline of bench/bench_passive.py.


def reference_derivative(
    x: Array, y: Array, valid: NDArray[np.bool_], tau: Array, vessel: VesselModel, gains: PassiveGains
) -> Array:
    """x' of (22)–(25) with y and τ held; DOFs with valid[i] False get no injection."""
    xi, eta_w, eta, b, nu = x[XI], x[XI2], x[ETA], x[BIAS], x[NU]
    y_hat = eta + eta_w  # (26), Γ = [0 I]
    y_tilde = np.where(valid, y - y_hat, 0.0)
    y_tilde[2] = ssa_scalar(y[2] - y_hat[2]) if valid[2] else 0.0
    J = rotation(y[2] if valid[2] else y_hat[2])  # J(y), assumption A4
    Omega = np.block(
        [[np.zeros((3, 3)), np.eye(3)], [-np.diag(gains.omega0**2), -np.diag(2 * gains.zeta * gains.omega0)]]
    )
    xi_dot = Omega @ xi + gains.K1 @ y_tilde  # (22)
    eta_dot = J @ nu + gains.K2 @ y_tilde  # (23)
    b_dot = -gains.t_inv * b + gains.K3 @ y_tilde  # (24); T⁻¹ written per DOF so T = ∞ works
    nu_dot = np.linalg.solve(vessel.M, -vessel.D @ nu + J.T @ b + tau + J.T @ gains.K4 @ y_tilde)  # (25)
    return np.concatenate([xi_dot, eta_dot, b_dot, nu_dot])


def reference_equilibrium(y: Array, tau: Array, vessel: VesselModel, gains: PassiveGains) -> Array:
    """The state where (22)–(25) are all zero for constant y, τ (twin of the kernel's `initialize`)."""
    J = rotation(y[2])
    # unknowns [ỹ, b̂]:  T⁻¹ b̂ - Λ ỹ = 0,   (D Jᵀ K2 + Jᵀ 𝒦) ỹ + Jᵀ b̂ = -τ
    A = np.block([[-gains.K3, np.diag(gains.t_inv)], [vessel.D @ J.T @ gains.K2 + J.T @ gains.K4, J.T]])
    sol = np.linalg.solve(A, np.r_[np.zeros(3), -tau])
    y_tilde, b = sol[:3], sol[3:]
    Omega = np.block(
        [[np.zeros((3, 3)), np.eye(3)], [-np.diag(gains.omega0**2), -np.diag(2 * gains.zeta * gains.omega0)]]
    )
    xi = -np.linalg.solve(Omega, gains.K1 @ y_tilde)  # (22) at rest
    x = np.zeros(N_STATE)
    x[XI] = xi
    x[ETA] = y - y_tilde - xi[3:6]
    x[I_PSI] = ssa_scalar(x[I_PSI])
    x[BIAS] = b
    x[NU] = -J.T @ gains.K2 @ y_tilde  # (23) at rest
    return x


def reference_propagate(
    x: Array, dt: float, y: Array, tau: Array, vessel: VesselModel, gains: PassiveGains,
    h_max: float = 0.1, max_hold_s: float = 2.0,
) -> Array:  # fmt: skip
    """Reference twin of `observers._passive_kernel.propagate` (returns the new state)."""
    valid = ~np.isnan(y)
    y, tau = np.where(valid, y, 0.0), np.nan_to_num(tau)

    def f(x: Array, valid: NDArray[np.bool_]) -> Array:
        return reference_derivative(x, y, valid, tau, vessel, gains)

    x = rk4_held(f, x, dt, valid, h_max, max_hold_s)
    x[I_PSI] = ssa_scalar(x[I_PSI])
    return x


def reference_run(
    vessel: VesselModel,
    gains: PassiveGains,
    t: Array,
    y: Array,
    tau: Array | None = None,
    h_max: float = 0.1,
    max_hold_s: float = 2.0,
) -> Array:
    """Reference batch run: states (n, 15), NaN before initialisation (`observers.reference`)."""
    return reference_loop(
        t, y, tau,
        lambda y0, tau0: reference_equilibrium(y0, tau0, vessel, gains),
        lambda x, dt, yk, tauk: reference_propagate(x, dt, yk, tauk, vessel, gains, h_max, max_hold_s),
        N_STATE,
    )  # fmt: skip
