"""SDRE observer of Snijders, van der Woude & Westhuis (2005), Sec. 2.5 and 3.2.

The paper's printed state order, C and Ω2 are garbled; dpgw reads them as below (state order as the
matrices require, Ω = diag(ω0ᵢ) of frequencies, not their squares). Model (1)–(2), T = 0 (random-walk bias)::

    η' = J(ψ) ν,   M ν' = −D ν + Jᵀ(ψ) b + τ,   b' = 0 (+ noise),   ξ' = Ω2 ξ (+ noise),   y = η + Γ2 ξ
    x = [η, ν, b, ξ] (15),  x' = A(x) x + B τ,  y = C x,   C = [I 0 0 Γ2],  Γ2 = [0 I],  B = [0; M⁻¹; 0; 0]
    Ω2 = [[0, I], [−Ω², −2ZΩ]],  Ω = diag(ω0ᵢ),  A12 = J(ψ),  A22 = −M⁻¹D,  A23 = M⁻¹Jᵀ(ψ),  A33 = 0

Observer (Sec. 3.2, written there for the autonomous system; with thrust the prediction is A(x̂)x̂ + Bτ)::

    x̂' = A(x̂) x̂ + B τ + K(x̂) ỹ,   ỹ = y − C x̂ (ỹ₃ wrapped to [−π, π) by ssa),   K = P Cᵀ R⁻¹
    0 = A(x̂) P + P Aᵀ(x̂) − P Cᵀ R⁻¹ C P + Q

A(x̂) depends on x̂ only through the LF heading estimate ψ̂ = η̂₃, and with N and E tuned alike the
Riccati solution turns with the heading: P(ψ) = S P(0) Sᵀ, K(ψ) = S K(0) Jᵀ(ψ), S = blockdiag(J, I, J,
J, J). So one Riccati solution per ω0 is exact for every heading (no linearisation about a set of yaw
angles, the drawback of the classical Kalman filters the paper names); otherwise the de-rotated gain is
tabulated over ψ (`observers.sdre_tuning`). Q and R come from physical tuning (`SdreTuning`): the
paper's Q, R in SI leave the bias practically unestimated (bias error poles near −1e-7 s⁻¹).

Discrete time: the same scheme as the passive observer (`observers._passive_kernel`): each sample's y
and τ are held over the interval that ends at its stamp, RK4 in sub-steps of at most ``h_max``, a DOF
whose measurement is missing (NaN) gets no innovation, and a gap longer than ``max_hold_s`` is dead
reckoning except for its last ``max_hold_s``. The gain is continuous over each interval, so there is
no separate discrete update: `predict` advances without a measurement (dead reckoning), `step` with one.

``observers._sdre_kernel`` is the compiled twin of the readable numpy reference at the end of this
module; tests/test_sdre.py checks they agree. Notes and measurements: docs/sdre.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers import _sdre_kernel as kernel
from observers.base import (
    STATUS_NAMES,
    Estimate,
    InitialState,
    ObserverBase,
    Run,
    batch_inputs,
    step_inputs,
)
from observers.kinematics import rotation, ssa_scalar
from observers.passive_tuning import PassiveTuning
from observers.reference import reference_loop, rk4_held
from observers.sdre_tuning import (
    BIAS,
    ETA,
    NU,
    TABLE_SIZE,
    XI2,
    SdreTuning,
    SdreWeights,
    gain_table,
    input_matrix,
    output_matrix,
    paper_weights,
    sdre_weights,
    slowest_error_rate,
    system_matrix,
    table_gain,
    with_wave_frequency,
)
from observers.settling import settle_time_from_rate
from observers.vessel import VesselModel
from observers.wave_frequency import ESTIMATOR_KEYS, estimator_config

Array = NDArray[np.float64]


def initial_state(start: InitialState) -> Array:
    """The 15-state vector [η, ν, b, ξ1, ξ2 = η_w] for an explicit start (ψ wrapped; omitted parts zero)."""
    x = np.zeros(15)
    x[ETA] = start.eta
    x[2] = ssa_scalar(x[2])
    for part, value in ((NU, start.nu), (BIAS, start.bias), (XI2, start.eta_wf)):
        if value is not None:
            x[part] = value
    return x


def estimate_from_state(t: float, x: Array, code: int) -> Estimate:
    """The estimate a kernel status ``code`` and state ``x`` stand for (copies; NaN while initialising)."""
    if code == kernel.STATUS_INITIALIZING:
        return Estimate.initializing(t)
    return Estimate(t, x[ETA].copy(), x[NU].copy(), x[BIAS].copy(), x[XI2].copy(), STATUS_NAMES[code])


class SdreObserver(ObserverBase):
    """Snijders et al. (2005) SDRE observer for any `VesselModel`.

    ``step(t, y, tau)`` for live use, ``run(t, y, tau)`` over arrays: the same kernel, the same numbers.
    y = [N, E, ψ] (m, m, rad; NaN = missing), τ = [X, Y, N] (N, N, N·m). ``weights`` (Q, R) replace the
    physical tuning, e.g. `observers.sdre_tuning.paper_weights` to reproduce the paper literally.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: SdreTuning | None = None,
        *,
        weights: SdreWeights | None = None,
        h_max: float = 0.1,
        max_hold_s: float = 2.0,
        table_size: int = TABLE_SIZE,
    ) -> None:
        self.vessel = vessel
        self.h_max = float(h_max)
        self.max_hold_s = float(max_hold_s)
        if not (self.h_max > 0 and self.max_hold_s > 0):
            raise ValueError("h_max and max_hold_s must be positive")
        self.table_size = int(table_size)
        self.tuning = tuning or SdreTuning()
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._MinvD = np.ascontiguousarray(vessel.Minv @ vessel.D)
        # Weights given as numbers stay those numbers when ω0 changes (`set_omega0`); only the physical
        # tuning's weights are functions of ω0.
        self._given_weights = weights is not None
        self.set_weights(weights if weights is not None else sdre_weights(vessel, self.tuning))
        self.reset()

    @classmethod
    def from_params(
        cls, vessel: VesselModel, tuning: PassiveTuning | None, params: dict[str, Any], *,
        allow_unchecked: bool = False,
    ) -> SdreObserver:  # fmt: skip
        """The observer `observers.factory` builds by name: ω0 and ζ from the common ``tuning`` (as every
        observer's), the rest from ``params``: the fields of `SdreTuning`; ``paper_weights = true`` to run
        the paper's Q, R literally, for comparison; ``adaptive = true`` with the wave-frequency estimator's
        settings for ω0 scheduled from the measurements (`observers.sdre_adaptive`). ``allow_unchecked``
        has nothing to relax here: a tuning that cannot give a stable filter is refused by
        `sdre_weights` itself."""
        params = dict(params)
        literal = bool(params.pop("paper_weights", False))
        adaptive = bool(params.pop("adaptive", False))
        from observers.sdre_adaptive import AdaptiveSdreObserver  # (it builds on this one)

        est = {k: params.pop(k) for k in ESTIMATOR_KEYS if k in params}
        if est and not adaptive:
            raise ValueError(
                f"{', '.join(est)}: settings of the wave-frequency estimator (expected adaptive = true)"
            )
        common = tuning or PassiveTuning.for_vessel(vessel)  # a model's default is Froude-scaled
        sdre_tuning = SdreTuning(omega0=common.omega0, zeta=common.zeta, **params)
        weights = paper_weights(sdre_tuning.omega0, sdre_tuning.zeta) if literal else None
        if adaptive:
            # the vessel's Froude-scaled defaults where not given; ω0 searched above the DP loop's band
            config = estimator_config(vessel, est).held_by(common.loop_bandwidth)
            return AdaptiveSdreObserver(vessel, sdre_tuning, estimator=config, weights=weights)
        return cls(vessel, sdre_tuning, weights=weights)

    def set_weights(self, weights: SdreWeights) -> None:
        """Solve the Riccati equation for new weights (state kept: no jump in the estimates)."""
        table = gain_table(self.vessel, weights, self.table_size)
        self.weights = weights
        self.table = np.ascontiguousarray(table)
        self._W = np.ascontiguousarray(np.stack([weights.omega0, weights.zeta]))
        self._settle_s: float | None = None  # `settle_time_s` of these weights, once asked for

    def set_omega0(self, omega0: ArrayLike) -> None:
        """Re-tune to a new wave frequency (rad/s, per DOF or one for all): one new Riccati solution. With
        ``weights`` given to the constructor (the paper's Q, R) those Q and R are kept; otherwise they
        follow the physical tuning at the new ω0."""
        self.tuning = self.tuning.with_omega0(omega0)
        if self._given_weights:
            self.set_weights(with_wave_frequency(self.weights, omega0))
        else:
            self.set_weights(sdre_weights(self.vessel, self.tuning))

    def reset(self) -> None:
        self.x = np.zeros(15)
        self._clock = np.zeros(2)  # [t of the last sample, initialised flag]

    @property
    def omega0(self) -> Array:
        """The wave frequency the filter is tuned to, per DOF (rad/s)."""
        return self.weights.omega0.copy()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: `ENGAGE_TIME_CONSTANTS` time constants of the slowest eigenvalue of
        A(ψ) − K(ψ)C over a grid of headings (`sdre_tuning.slowest_error_rate`): the bias pole, −0.056 s⁻¹
        for snijders_ship and −0.052 s⁻¹ for mss_supply at ω0 = 2π/12 s (docs/sdre.md), so ~27-29 s.
        Computed for the weights in use (new weights, a new figure)."""
        if self._settle_s is None:
            self._settle_s = settle_time_from_rate(slowest_error_rate(self.vessel, self.weights))
        return self._settle_s

    def _begin(self, t: float, start: InitialState) -> None:
        """`initialize`: ψ wrapped. Without it, the first complete measurement initialises the observer at
        its equilibrium for that sample (η̂ = y, ν̂ = 0, b̂ = −J(ψ)τ, ξ̂ = 0). No extras: the gain follows
        from ω0 and ψ̂."""
        self.x[:] = initial_state(start)
        self._set_clock(t)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t (s) with measurement y and generalised force τ held since the last sample."""
        y_arr, tau_arr = step_inputs(y, tau)
        code = kernel.step(
            self.x, self._clock, float(t), y_arr, tau_arr, self._W, self.table, self._Minv, self._MinvD,
            self.h_max, self.max_hold_s
        )  # fmt: skip
        return estimate_from_state(float(t), self.x, code)

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample: t (n,), y (n, 3) with NaN for missing, τ (n, 3) or None for zero."""
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        X = np.empty((n, 15))
        status = np.empty(n, dtype=np.int8)
        kernel.run(
            self.x, self._clock, t_arr, Y, TAU, self._W, self.table, self._Minv, self._MinvD, self.h_max,
            self.max_hold_s, X, status
        )  # fmt: skip
        # ω0 is fixed over a run (it changes only by `set_omega0` between calls)
        omega0 = np.broadcast_to(self.weights.omega0, (n, 3)).copy()
        return Run(t_arr, X[:, ETA], X[:, NU], X[:, BIAS], X[:, XI2], status, omega0)


# --- readable reference ----------------------------------------------------------------------------------
# The same equations written with the paper's matrices, in numpy. Slow; used to check the kernel and as
# the baseline of bench/bench_sdre.py.


def reference_derivative(
    x: Array, y: Array, valid: NDArray[np.bool_], tau: Array, vessel: VesselModel, weights: SdreWeights,
    table: Array,
) -> Array:  # fmt: skip
    """x̂' = A(ψ̂) x̂ + B τ + K(ψ̂) ỹ with y and τ held; DOFs with valid[i] False get no innovation."""
    psi = x[2]
    y_tilde = np.where(valid, y - output_matrix() @ x, 0.0)
    y_tilde[2] = ssa_scalar(y[2] - (x[2] + x[14])) if valid[2] else 0.0
    A = system_matrix(vessel, weights.omega0, weights.zeta, psi)
    K = table_gain(table, psi)  # = P(ψ̂) Cᵀ R⁻¹ (sdre_tuning)
    return np.asarray(A @ x + input_matrix(vessel) @ tau + K @ y_tilde)


def reference_equilibrium(y: Array, tau: Array) -> Array:
    """The state where x̂' = 0 for constant y, τ (twin of the kernel's `initialize`)."""
    x = np.zeros(15)
    x[ETA] = y
    x[2] = ssa_scalar(y[2])
    x[BIAS] = -rotation(y[2]) @ tau  # Jᵀ b̂ + τ = 0
    return x


def reference_propagate(
    x: Array, dt: float, y: Array, tau: Array, vessel: VesselModel, weights: SdreWeights, table: Array,
    h_max: float = 0.1, max_hold_s: float = 2.0,
) -> Array:  # fmt: skip
    """Reference twin of `observers._sdre_kernel.propagate` (returns the new state)."""
    valid = ~np.isnan(y)
    y = np.where(valid, y, 0.0)
    tau = np.nan_to_num(tau)

    def f(x: Array, valid: NDArray[np.bool_]) -> Array:
        return reference_derivative(x, y, valid, tau, vessel, weights, table)

    x = rk4_held(f, x, dt, valid, h_max, max_hold_s)
    x[2] = ssa_scalar(x[2])
    return x


def reference_run(
    vessel: VesselModel,
    weights: SdreWeights,
    table: Array,
    t: Array,
    y: Array,
    tau: Array | None = None,
    h_max: float = 0.1,
    max_hold_s: float = 2.0,
) -> Array:
    """Reference batch run: states (n, 15), NaN before initialisation (`observers.reference`)."""
    return reference_loop(
        t, y, tau,
        lambda y0, tau0: reference_equilibrium(y0, tau0),
        lambda x, dt, yk, tauk: reference_propagate(
            x, dt, yk, tauk, vessel, weights, table, h_max, max_hold_s
        ),
    )  # fmt: skip
