"""Fluid-memory observer of Hajivand & Mousavizadegan (2010), eqs (17)–(21).

The passive observer of Fossen & Strand (1999) (`observers.passive`) with the kinetics of the Cummins
equation (2)/(8): frequency-dependent added mass and damping as A(∞) plus a convolution of past velocities,
replaced by the state space (7) identified from A(ω), B(ω) (`observers.radiation`). The paper prints
tildes where the observer's states (hats) are meant; written with hats::

    ξ̂' = Ω ξ̂ + K1 ỹ                                                                 (17)
    η̂' = J(y) ν̂ + K2 ỹ                                                               (18)
    b̂' = -T⁻¹ b̂ + Λ ỹ                                             (γ = 1, as the paper's)   (19)
    [M_RB + A(∞)] ν̂' = -D_m ν̂ + Jᵀ(y) b̂ + τ - μ̂ + Jᵀ(y) K4 ỹ                          (20)
    ξ̂_r' = A_r ξ̂_r + B_r ν̂,    μ̂ = C_r ξ̂_r + D_r ν̂                                    (7)
    ỹ = y - η̂ - Γ ξ̂,   ỹ₃ wrapped to [-π, π)                                          (21)

**Sign of μ̂.** The printed (20) has +μ̃. Eq (8), [M + A] η'' + μ(ν, t) = f_ext, puts μ on the side of
the inertia: the radiation force on the hull is -μ (eq (3): f_rad = -A∞ η'' - ∫K ν), a force that takes
energy out of the motion (K positive real). With +μ the observer's ship would be fed energy by its own
radiation; dpgw uses -μ̂. ``tests/test_memory_observer.py`` shows the printed sign failing.

**What drives the radiation states: ν̂.** The paper does not say. The true radiation force is driven by
the true velocity ν, which a DP vessel does not measure (positions and heading only). ν̂ is the observer's
copy of it, used exactly as D ν of the model becomes D ν̂ in the observer: then the radiation error
states obey ξ̃_r' = A_r ξ̃_r + B_r ν̃, the same passive system driven by the velocity error, and the
extended error system is a passive radiation block in feedback with the strictly passive velocity block
(`observers.memory_tuning`). The alternatives are worse: a velocity differentiated from y carries the
wave-frequency motion and the noise the wave filter exists to remove (and the fluid memory of the
wave-frequency motion is already in the measured η_w); the LF velocity from η̂' adds the K2 ỹ injection.

M_RB + A(∞), D_m and the gains: `observers.memory_tuning` (the same physical tuning as the passive
observer; M_m and D_m chosen so that both observers see the same ship as ω → 0).

Discrete time exactly as the passive observer (`observers.reference`): y and τ held over the interval
ending at the sample, RK4 sub-steps ≤ ``h_max``, dead reckoning beyond ``max_hold_s`` of a gap, a start in
equilibrium at the first complete measurement.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers import _memory_kernel as kernel
from observers.base import ZERO3, Estimate, InitialState, ObserverBase, Run, batch_inputs
from observers.kinematics import rotation, ssa_scalar
from observers.memory_tuning import MemoryGains, memory_gains, n_state, slowest_error_rate, validate
from observers.passive import estimate_from_state, initial_state, pack_gains
from observers.passive import reference_equilibrium as passive_equilibrium
from observers.passive_tuning import PassiveTuning
from observers.radiation import RadiationStateSpace
from observers.reference import reference_loop, rk4_held
from observers.settling import settle_time_from_rate
from observers.state import BIAS, ETA, I_NU, I_PSI, N_STATE, NU, XI, XI2
from observers.vessel import VesselModel

Array = NDArray[np.float64]

MU_SIGN = -1.0
"""The radiation force enters (20) as -μ̂ (eq (8)); the reference takes the sign as an argument only so
that a test can show the printed +μ failing."""


def pack_radiation(gains: MemoryGains) -> tuple[NDArray[np.int64], Array, int, int]:
    """(RI, RV, n_dyn, n_mu), the radiation model as the kernel reads it (`observers._memory_kernel`): the
    non-zero entries of [A_r B_r] (ξ_r'), then of [C_r D_r] (μ̂), then of S = -A_r⁻¹ B_r (ξ_r at rest), each
    as (row, x index) and value."""
    r = gains.model.radiation
    n = r.n_states
    S = -np.linalg.solve(r.Ar, r.Br)
    parts = []
    # (matrix, row offset, column offset into x)
    for M, row0, col0 in (
        (r.Ar, N_STATE, N_STATE), (r.Br, N_STATE, I_NU),
        (r.Cr, 0, N_STATE), (r.Dr, 0, I_NU),
        (S, N_STATE, I_NU),
    ):  # fmt: skip
        idx = np.argwhere(M != 0.0)
        parts.append((idx + np.array([row0, col0]), M[M != 0.0]))
    RI = np.ascontiguousarray(np.vstack([p[0] for p in parts]), dtype=np.int64)
    RV = np.ascontiguousarray(np.concatenate([p[1] for p in parts]), dtype=float)
    n_dyn = len(parts[0][1]) + len(parts[1][1])
    n_mu = len(parts[2][1]) + len(parts[3][1])
    assert RI[:, 1].max(initial=0) < N_STATE + n
    return RI, RV, n_dyn, n_mu


class MemoryObserver(ObserverBase):
    """Hajivand & Mousavizadegan (2010) fluid-memory observer (the module docstring has the details).

    Model: the passive observer's (Fossen & Strand (14)–(18)) with the Cummins kinetics
    [M_RB + A(∞)] ν' = -D_m ν + Jᵀ b + τ - μ, μ = K(s) ν as the state space (7).

    State x = [ξ1, ξ2 = η̂_w, η̂, b̂, ν̂] (`observers.state`) followed by the radiation states ξ̂_r. Gains
    and model from a physical `PassiveTuning` and a radiation model (`observers.memory_tuning`; default:
    the built-in supply-vessel model Froude-scaled to the vessel). ``step`` for live use, ``run`` over
    arrays: the same kernel, the same numbers. `Run.extras`: ``"radiation_force"`` (n, 3), μ̂ after each
    sample (N, N, N·m; NaN while initialising).
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: PassiveTuning | None = None,
        *,
        radiation: RadiationStateSpace | None = None,
        froude_scale: float | None = None,
        gains: MemoryGains | None = None,
        allow_unchecked: bool = False,
        h_max: float = 0.1,
        max_hold_s: float = 2.0,
    ) -> None:
        self.vessel = vessel
        self.h_max = float(h_max)
        self.max_hold_s = float(max_hold_s)
        if not (self.h_max > 0 and self.max_hold_s > 0):
            raise ValueError("h_max and max_hold_s must be positive")
        if gains is None:
            gains = memory_gains(vessel, tuning, radiation, froude_scale)
        if not allow_unchecked:
            validate(gains)
        self.gains = gains
        self._settle_s: float | None = None  # `settle_time_s`, once asked for
        model = gains.model
        self._G = pack_gains(gains.passive)
        self._Minv = np.ascontiguousarray(model.Minv)
        self._D = np.ascontiguousarray(model.D, dtype=float)
        self._D_lf = np.ascontiguousarray(model.D + model.radiation.static_gain(), dtype=float)
        self._RI, self._RV, self._n_dyn, self._n_mu = pack_radiation(gains)
        self._S = -np.linalg.solve(model.radiation.Ar, model.radiation.Br)
        self._n = n_state(model)
        self.reset()

    @classmethod
    def from_params(
        cls, vessel: VesselModel, tuning: Any, params: dict[str, Any], *, allow_unchecked: bool = False
    ) -> MemoryObserver:
        """`observers.factory`: params ``froude_scale`` (optional, the built-in model's length scale)."""
        scale = params.get("froude_scale")
        return cls(
            vessel,
            tuning,
            froude_scale=None if scale is None else float(scale),
            allow_unchecked=allow_unchecked,
        )

    def reset(self) -> None:
        self.x = np.zeros(self._n)
        self._clock = np.zeros(2)

    @property
    def omega0(self) -> Array:
        """The wave frequency the filter is tuned to, per DOF (rad/s) — fixed for this observer."""
        return self.gains.omega0.copy()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: `ENGAGE_TIME_CONSTANTS` time constants of the slowest eigenvalue of
        the extended error system (the passive observer's with the radiation states) over headings
        (`memory_tuning.slowest_error_rate`, the rate the tuning promises; −0.023 s⁻¹ for the supply
        vessel, docs/memory-observer.md). The gains are fixed: computed once."""
        if self._settle_s is None:
            self._settle_s = settle_time_from_rate(slowest_error_rate(self.gains))
        return self._settle_s

    @property
    def radiation_force(self) -> Array:
        """μ̂ = C_r ξ̂_r + D_r ν̂ now (N, N, N·m)."""
        r = self.gains.model.radiation
        return np.asarray(r.Cr @ self.x[N_STATE:] + r.Dr @ self.x[NU])

    def _begin(self, t: float, start: InitialState) -> None:
        """`initialize`: the given state, radiation states at rest for the given ν̂ (μ̂ = K(0) ν̂)."""
        self.x[:N_STATE] = initial_state(start)
        self.x[N_STATE:] = self._S @ self.x[NU]
        self._set_clock(t)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t (s) with measurement y and generalised force τ held since the last sample."""
        y_arr = np.asarray(y, dtype=float)
        tau_arr = ZERO3 if tau is None else np.asarray(tau, dtype=float)
        code = kernel.step(
            self.x, self._clock, float(t), y_arr, tau_arr, self._G, self._Minv, self._D, self._D_lf,
            self._RI, self._RV, self._n_dyn, self._n_mu, self.h_max, self.max_hold_s
        )  # fmt: skip
        return estimate_from_state(float(t), self.x, code)

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample: t (n,), y (n, 3) with NaN for missing, τ (n, 3) or None for zero."""
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        X = np.empty((n, self._n))
        status = np.empty(n, dtype=np.int8)
        kernel.run(
            self.x, self._clock, t_arr, Y, TAU, self._G, self._Minv, self._D, self._D_lf, self._RI,
            self._RV, self._n_dyn, self._n_mu, self.h_max, self.max_hold_s, X, status
        )  # fmt: skip
        r = self.gains.model.radiation
        mu = X[:, N_STATE:] @ r.Cr.T + X[:, NU] @ r.Dr.T
        omega0 = np.broadcast_to(self.gains.omega0, (n, 3))
        return Run(t_arr, X[:, ETA], X[:, NU], X[:, BIAS], X[:, XI2], status, omega0, {"radiation_force": mu})


# --- readable reference ----------------------------------------------------------------------------------
# The same equations with the paper's matrices, in numpy. Slow; used to check the kernel and as the
# baseline of bench/bench_memory.py.


def reference_derivative(
    x: Array, y: Array, valid: NDArray[np.bool_], tau: Array, gains: MemoryGains, mu_sign: float = MU_SIGN
) -> Array:
    """x' of (17)–(21) and (7) with y and τ held; DOFs with valid[i] False get no injection."""
    pg, model = gains.passive, gains.model
    r = model.radiation
    xi, eta_w, eta, b, nu, xr = x[XI], x[XI2], x[ETA], x[BIAS], x[NU], x[N_STATE:]
    y_hat = eta + eta_w  # (21), Γ = [0 I]
    y_tilde = np.where(valid, y - y_hat, 0.0)
    y_tilde[2] = ssa_scalar(y[2] - y_hat[2]) if valid[2] else 0.0
    J = rotation(y[2] if valid[2] else y_hat[2])
    Omega = np.block(
        [[np.zeros((3, 3)), np.eye(3)], [-np.diag(pg.omega0**2), -np.diag(2 * pg.zeta * pg.omega0)]]
    )
    mu = r.Cr @ xr + r.Dr @ nu  # (7)
    xi_dot = Omega @ xi + pg.K1 @ y_tilde  # (17)
    eta_dot = J @ nu + pg.K2 @ y_tilde  # (18)
    b_dot = -pg.t_inv * b + pg.K3 @ y_tilde  # (19)
    nu_dot = np.linalg.solve(
        model.M, -model.D @ nu + J.T @ b + tau + mu_sign * mu + J.T @ pg.K4 @ y_tilde
    )  # (20)
    xr_dot = r.Ar @ xr + r.Br @ nu  # (7), driven by ν̂
    return np.concatenate([xi_dot, eta_dot, b_dot, nu_dot, xr_dot])


def reference_equilibrium(y: Array, tau: Array, gains: MemoryGains) -> Array:
    """The state where (17)–(21) and (7) are all zero for constant y, τ (twin of the kernel's)."""
    model = gains.model
    r = model.radiation

    class _LF:  # what a constant ν̂ meets: D_m + K(0)
        M = model.M
        D = model.D + r.static_gain()

    x15 = passive_equilibrium(y, tau, _LF, gains.passive)  # type: ignore[arg-type]
    return np.concatenate([x15, -np.linalg.solve(r.Ar, r.Br @ x15[NU])])


def reference_propagate(
    x: Array, dt: float, y: Array, tau: Array, gains: MemoryGains, h_max: float = 0.1,
    max_hold_s: float = 2.0, mu_sign: float = MU_SIGN,
) -> Array:  # fmt: skip
    """Reference twin of `observers._memory_kernel.propagate` (returns the new state)."""
    valid = ~np.isnan(y)
    y, tau = np.where(valid, y, 0.0), np.nan_to_num(tau)

    def f(x: Array, valid: NDArray[np.bool_]) -> Array:
        return reference_derivative(x, y, valid, tau, gains, mu_sign)

    x = rk4_held(f, x, dt, valid, h_max, max_hold_s)
    x[I_PSI] = ssa_scalar(x[I_PSI])
    return x


def reference_run(
    gains: MemoryGains,
    t: Array,
    y: Array,
    tau: Array | None = None,
    h_max: float = 0.1,
    max_hold_s: float = 2.0,
    mu_sign: float = MU_SIGN,
) -> Array:
    """Reference batch run: states (n, 15 + n_r), NaN before initialisation (`observers.reference`)."""
    return reference_loop(
        t, y, tau,
        lambda y0, tau0: reference_equilibrium(y0, tau0, gains),
        lambda x, dt, yk, tauk: reference_propagate(x, dt, yk, tauk, gains, h_max, max_hold_s, mu_sign),
        n_state(gains.model),
    )  # fmt: skip
