"""Gain-scheduled wave filtering: Torsetnes, Jouffroy & Fossen (2004), Sec. III, on dpgw's passive observer.

Observer (29)–(34) — Fossen & Strand's (22)–(26) with the wave frequency ω̄0 as a parameter::

    ξ̂' = A_w(ω̄0) ξ̂ + K1(ω̄0) ỹ                                                     (29), (34)
    η̂' = R(ψ) ν̂ + K2(ω̄0) ỹ                                                        (30)
    b̂' = K3 ỹ                           random-walk bias: no 1/T term              (31)
    M ν̂' + D ν̂ = τ + Rᵀ(ψ) b̂ + Rᵀ(ψ) K4 ỹ                                          (32)
    ŷ = η̂ + C_w ξ̂,  ỹ = y − ŷ (heading innovation wrapped to [-π, π))              (33)

Gains (51)–(52), read as below (the printed (51) is garbled), with k = ωc/ω0
(`PassiveTuning.cutoff_ratio`)::

    K1(ω̄0) = [ −2(ζd − ζ)·k·I ;  2(ζd − ζ)·ω̄0·I ],      K2(ω̄0) = k·ω̄0·I          (51), (52)

which is Fossen & Strand (45)–(47) with ωc = k·ω0 — so the gains at any ω̄0 are exactly
``passive_gains(vessel, tuning.with_omega0(ω̄0))``. K3 = Λ and K4 = 𝒦 follow rule (53) (Fossen & Strand
(48)) with dpgw's vessel-scaled injection (`observers.passive_tuning`): K4 = diag(M)·ωc·a,
K3 = K4·ρ. With the default tuning a = 0.12·ω0 and ρ = λ/κ = 0.04·ω0 scale with ω̄0 too (the ratios that
make the tuning rule and SPR hold at every ω0, docs/passive-observer.md); a tuning with explicit
``velocity_injection``/``bias_corner`` keeps a and λ/κ = K3/K4 fixed, closer to the paper's constant K3, K4
(K4 still follows ωc), and then (53) can fail at the low end of the range (checked).

Default bias model: the paper's random walk (31), T = ∞ (``PassiveTuning(bias_time_constant_s=inf)``).

**Estimate of ω0**: `observers.wave_frequency` (Sec. III-B, A5, A6, A8), one value for all DOFs by default.

**Scheduling without jumps.** The observer state is never touched by a gain change (it is the state of
(29)–(33) for whatever ω̄0), and ω̄0 itself moves continuously: a first-order lag towards each new
estimate (``ramp_time_constant_s``, 15 s on a ship, ÷ √λ on a 1:λ model), the gains recomputed in closed
form at every sample (`gains_at`, the arithmetic of `passive_gains`), and the speed limited by a contraction
budget. The compiled loop
(`observers._gain_scheduled_kernel`) runs the passive kernel (`observers._passive_kernel`) sample by sample
with the scheduled gains. The estimates depend on the measurements only, so batch `run` first takes the record
through the estimator (vectorised appends up to each update time) and then makes one compiled pass that
takes each new target at the sample where `step` would have: the same numbers as stepping.

**Checks at construction** (`observers.gain_scheduled_analysis`): over a grid of ω0 in [ω_min, ω_max], the
tuning rule (53)/(48), Proposition 1 (SPR) of Fossen & Strand, and (50) with a decay margin; and the
scheduling budget that bounds how fast ω0 may move (the time-varying part that (7) keeps and Theorem 3
drops). A violation raises `ContractionError` naming the condition (``allow_unchecked=True`` for
experiments).

Three modules, one concept each: this one (the observer and its readable reference),
`observers.gain_scheduled_analysis` (the contraction analysis) and `observers._gain_scheduled_kernel` (the
compiled loop).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers import _gain_scheduled_kernel as sk
from observers import _passive_kernel as pk
from observers.base import ZERO3, Estimate, InitialState, ObserverBase, Run, batch_inputs
from observers.froude import froude_scale, froude_scaled
from observers.gain_scheduled_analysis import (
    DEFAULT_TUNING,
    ContractionCheck,
    ContractionError,
    contraction_check,
    validate_contraction,
)
from observers.passive import PassiveObserver, estimate_from_state, initial_state
from observers.passive_tuning import (
    PassiveGains,
    PassiveTuning,
    injection_floor,
    passive_gains,
    slowest_error_rate,
)
from observers.settling import settle_time_from_rate
from observers.state import BIAS, ETA, N_STATE, NU, XI2, StateView
from observers.vessel import VesselModel
from observers.wave_frequency import (
    ESTIMATOR_KEYS,
    WaveFrequencyConfig,
    WaveFrequencyEstimator,
    estimator_config,
)

Array = NDArray[np.float64]

__all__ = [
    "DEFAULT_TUNING",
    "ContractionCheck",
    "ContractionError",
    "GainScheduledObserver",
    "contraction_check",
    "pack_tuning",
    "reference_run",
]


# --- the observer -----------------------------------------------------------------------------------------

H_MAX_S = 0.1
"""A ship's RK4 sub-step (s): the fastest error pole over its ω0 range (0.3-1.6 rad/s) is −2.4 s⁻¹, so
|λ|·h ≤ 0.24. A 1:λ model's poles are √λ faster (−20 s⁻¹ at CyberShip II's 13.4 rad/s, |λ|·h = 2.0 at
0.1 s, near RK4's stability edge): its default is H_MAX_S ÷ √λ (`observers.froude.froude_scaled`)."""
RAMP_TIME_CONSTANT_S = 15.0
"""A ship's ω0 ramp (s), a quarter of its estimator's 60 s update period: ω0 settles before the next
estimate. A time, so ÷ √λ on a 1:λ model (1.8 s for CyberShip II, whose updates come every 7.2 s)."""


def _initial_for_range(w: Array, config: WaveFrequencyConfig, scale: float) -> Array:
    """Where ω0 starts when ``omega0_initial`` is not given: the tuning's ω0; on a 1:λ model whose range
    does not hold it, the same sea in the range's scale (`observers.froude`), if the range holds that:
    ω0·√λ where the tuning's ω0 is a full-scale sea (``DEFAULT_TUNING``'s 2π/7 s) and the range the
    model's, ω0/√λ where the tuning's is the model's default (`PassiveTuning.for_vessel`, what a config
    without a wave period gives) and the range a full-scale one (Hassani's case). Otherwise the tuning's
    ω0, refused below."""

    def holds(x: Array) -> bool:
        return bool(np.all((x >= config.omega_min) & (x <= config.omega_max)))

    if holds(w) or scale == 1.0:
        return w
    up, down = froude_scaled(w, scale, "frequency"), froude_scaled(w, scale, "time")  # ω0·√λ, ω0/√λ
    return next((x for x in (up, down) if holds(x)), w)


def pack_tuning(vessel: VesselModel, tuning: PassiveTuning) -> Array:
    """The packed tuning the compiled loop reads (`observers._gain_scheduled_kernel`, rows ``P_*``)."""
    g = passive_gains(vessel, tuning)  # validates the fields
    P = np.zeros((sk.N_TUNING_ROWS, 3))
    P[sk.P_ZETA], P[sk.P_ZETA_N] = g.zeta, g.zeta_n

    def value(explicit: Any, ratio: Any) -> tuple[Array, Array]:
        if explicit is not None:
            return np.broadcast_to(np.asarray(explicit, dtype=float), (3,)), np.zeros(3)
        return np.broadcast_to(np.asarray(ratio, dtype=float), (3,)), np.ones(3)

    P[sk.P_OMEGA_C], P[sk.P_OMEGA_C_IS_RATIO] = value(tuning.omega_c, tuning.cutoff_ratio)
    P[sk.P_INJECTION], P[sk.P_INJECTION_IS_RATIO] = value(
        tuning.velocity_injection, tuning.velocity_injection_ratio
    )
    P[sk.P_BIAS_CORNER], P[sk.P_BIAS_CORNER_IS_RATIO] = value(tuning.bias_corner, tuning.bias_corner_ratio)
    P[sk.P_MASS] = np.diag(vessel.M)
    P[sk.P_T_INV] = g.t_inv
    P[sk.P_INJECTION_FLOOR] = injection_floor(vessel, tuning)
    return np.ascontiguousarray(P)


class GainScheduledObserver(ObserverBase):
    """Passive observer whose wave-filter gains follow an on-line estimate of ω0 (Torsetnes et al. 2004).

    Model: `PassiveObserver`'s, (29)–(33), with the wave frequency ω̄0 a slowly varying parameter and a
    random-walk bias (31). State x = [ξ1, ξ2 = η̂_w, η̂, b̂, ν̂] (`observers.state`; ``state`` names its
    parts), plus the schedule: ω0 in use, its target, the contraction budget. `predict` is dead reckoning
    with the gains held; `step` feeds the ω0 estimator, moves ω0 towards its target, then integrates
    (29)–(33) over the interval. ``step`` and ``run`` give the same numbers; ``omega0`` is the wave
    frequency in use (3,), ``extra()`` the estimator's fields for the estimate message.
    `Run.extras`: ``"updates"``, the ω0 estimates made during the run, as (t, (ω0 per DOF)).

    estimator: `WaveFrequencyConfig` (window, update period T, ω range of A6, per-DOF or shared); default
               the vessel's, `WaveFrequencyConfig.for_vessel` (0.3-1.6 rad/s for a ship, × √λ for a 1:λ
               model: `observers.froude`).
    tuning: the LF tuning (ratios to ω0, ζ, ζn, bias model); default the vessel's,
            `PassiveTuning.for_vessel` (as every observer's: Froude-scaled on a model).
    omega0_initial: ω0 to start from (rad/s; one or per DOF), default the tuning's ω0 (Froude-scaled,
                    ω0·√λ or ω0/√λ, on a model whose range does not hold it: `_initial_for_range`).
    h_max: RK4 sub-step (s); default `H_MAX_S` (0.1 s) on a ship, ÷ √λ on a 1:λ model.
    ramp_time_constant_s: time constant of the first-order move of ω0 towards each new estimate; default
                          `RAMP_TIME_CONSTANT_S` (15 s) on a ship, ÷ √λ on a 1:λ model.
    max_hold_s: a gap longer than this is dead reckoning except for its last ``max_hold_s`` (2 s, not
                scaled: a sensor-dropout setting, the same as the passive observer's).
    transient_gain: L0 = 2 ln(transient_gain) is the scheduling budget (module docstring).
    schedule: False keeps ω0 fixed (the estimator still runs and reports): the fixed observer.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: PassiveTuning | None = None,
        *,
        estimator: WaveFrequencyConfig | None = None,
        omega0_initial: ArrayLike | None = None,
        allow_unchecked: bool = False,
        h_max: float | None = None,
        max_hold_s: float = 2.0,
        ramp_time_constant_s: float | None = None,
        transient_gain: float = 10.0,
        schedule: bool = True,
    ) -> None:
        self.vessel = vessel
        scale = froude_scale(vessel)
        self.tuning = tuning or PassiveTuning.for_vessel(vessel)
        # ω0 searched above the band of the DP loop this observer's vessel is held by
        self.config = (estimator or WaveFrequencyConfig.for_vessel(vessel)).held_by(
            self.tuning.loop_bandwidth
        )
        self.h_max = float(froude_scaled(H_MAX_S, scale, "time") if h_max is None else h_max)
        self.max_hold_s = float(max_hold_s)
        if not (self.h_max > 0 and self.max_hold_s > 0):
            raise ValueError("h_max and max_hold_s must be positive")
        if ramp_time_constant_s is None:
            ramp_time_constant_s = froude_scaled(RAMP_TIME_CONSTANT_S, scale, "time")
        if not (math.isfinite(ramp_time_constant_s) and ramp_time_constant_s >= 0):
            raise ValueError(f"ramp_time_constant_s must be ≥ 0, got {ramp_time_constant_s!r}")
        self.ramp_time_constant_s = float(ramp_time_constant_s)
        self._scheduling = bool(schedule)
        c = self.config
        w_init = np.broadcast_to(
            np.asarray(self.tuning.omega0 if omega0_initial is None else omega0_initial, dtype=float), (3,)
        ).copy()
        if omega0_initial is None:
            w_init = _initial_for_range(w_init, c, scale)
        if not np.all((w_init >= c.omega_min) & (w_init <= c.omega_max)):
            raise ContractionError(
                f"omega0_initial {w_init.tolist()} lies outside [omega_min, omega_max] = "
                f"[{c.omega_min:g}, {c.omega_max:g}] rad/s (assumption A6)"
            )
        if not c.per_dof and not np.all(w_init == w_init[0]):
            raise ValueError("a shared ω0 (per_dof=False) needs one omega0_initial for all DOFs")
        self.omega0_initial = w_init
        self.check = contraction_check(
            vessel,
            self.tuning,
            c.omega_min,
            c.omega_max,
            per_dof=c.per_dof,
            transient_gain=transient_gain,
        )
        if not allow_unchecked:
            validate_contraction(self.check)
        if not self.check.ok:
            # unchecked experiments: no certified budget — schedule with the first-order lag alone
            self._cost = np.zeros_like(self.check.cost)
            self._alpha = np.ones_like(self.check.alpha)
        else:
            self._cost = np.ascontiguousarray(self.check.cost)
            self._alpha = np.ascontiguousarray(self.check.alpha)
        self._grid = np.ascontiguousarray(self.check.omega)
        self._P = pack_tuning(vessel, self.tuning)
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._D = np.ascontiguousarray(vessel.D, dtype=float)
        self.estimator = WaveFrequencyEstimator(self.config)
        self._settle_at_omega: tuple[tuple[float, ...], float] | None = None  # (ω0, `settle_time_s` there)
        self.reset()

    @classmethod
    def from_params(
        cls, vessel: VesselModel, tuning: PassiveTuning | None, params: dict[str, Any], *,
        allow_unchecked: bool = False,
    ) -> GainScheduledObserver:  # fmt: skip
        """The observer `observers.factory` builds by name: the estimator's settings (window_s,
        update_period_s, omega_min, omega_max, per_dof; the vessel's Froude-scaled defaults for those not
        given, `observers.wave_frequency.estimator_config`) and the observer's own (e.g. omega0_initial)."""
        params = dict(params)
        est = {k: params.pop(k) for k in ESTIMATOR_KEYS if k in params}
        return cls(
            vessel, tuning, estimator=estimator_config(vessel, est), allow_unchecked=allow_unchecked, **params
        )

    # -- state -------------------------------------------------------------------------------------------

    def reset(self) -> None:
        """Back to uninitialised: ω0 at ``omega0_initial``, a full budget, the estimator emptied."""
        self.x = np.zeros(N_STATE)
        self._clock = np.zeros(2)  # the passive kernel's CLOCK_T, CLOCK_STARTED
        self._omega = self.omega0_initial.copy()
        self._target = self.omega0_initial.copy()
        self._schedule = np.zeros(sk.N_SCHEDULE)
        self._schedule[sk.S_BUDGET] = self.check.budget
        self._schedule[sk.S_ENABLED] = 1.0 if self._scheduling else 0.0
        self._G = np.zeros((pk.N_GAIN_ROWS, 3))
        sk.gains_at(self._omega, self._P, self._G)
        self.estimator.reset()
        self._updates: list[tuple[float, tuple[float, float, float]]] = []

    @property
    def state(self) -> StateView:
        """The observer state by name (a view: writing to it changes the observer)."""
        return StateView(self.x)

    @property
    def scheduling(self) -> bool:
        """Whether ω0 follows its target (False: held where it is; the estimator still runs)."""
        return bool(self._schedule[sk.S_ENABLED])

    @scheduling.setter
    def scheduling(self, on: bool) -> None:
        self._scheduling = bool(on)
        self._schedule[sk.S_ENABLED] = 1.0 if on else 0.0

    @property
    def omega0(self) -> Array:
        """The wave frequency in use per DOF (rad/s)."""
        return self._omega.copy()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: `ENGAGE_TIME_CONSTANTS` time constants of the slowest error mode of the
        passive gains at the ω0 in use (`passive_tuning.slowest_error_rate`, the bias mode) — at the start
        (when the gateway asks) the initial ω0, the configured sea's (``wave_period_s``). The bias mode
        scales with ω0 (the tuning's corners are ratios of it: −0.0037 s⁻¹ at 0.3 rad/s to −0.056 s⁻¹ at
        1.6 rad/s on mss_supply), so a sea much longer than the configured one settles later than this
        says; the slowest over the whole scheduling range (405 s on mss_supply's default range, its
        0.3 rad/s end) would hold the estimate unsettled for a sea that is rarely there."""
        omega = tuple(self._omega.tolist())
        if self._settle_at_omega is None or self._settle_at_omega[0] != omega:
            self._settle_at_omega = (
                omega,
                settle_time_from_rate(slowest_error_rate(self.vessel, self.gains)),
            )
        return self._settle_at_omega[1]

    @property
    def omega0_target(self) -> Array:
        return self._target.copy()

    @property
    def gains(self) -> PassiveGains:
        """The gains in use (== `passive_gains(vessel, tuning.with_omega0(omega0))`)."""
        return passive_gains(self.vessel, self.tuning.with_omega0(self._omega.copy()))

    @property
    def budget(self) -> float:
        """Scheduling budget left, β ∈ [0, L0]."""
        return float(self._schedule[sk.S_BUDGET])

    def _begin(self, t: float, start: InitialState) -> None:
        """`initialize` (as the passive observer's); ω0 and the estimator are kept."""
        self.x[:] = initial_state(start)
        self._set_clock(t)

    def extra(self) -> dict[str, Any]:
        e = self.estimator
        return {
            "omega0_estimate": None if e.latest is None else [float(v) for v in e.latest],
            "omega0_target": [float(v) for v in self._target],
            "omega0_updates": e.updates,
            "omega0_skipped": e.skipped,
            "omega0_last_skip": e.last_skip,
            "scheduling_budget": self.budget,
        }

    # -- estimates in ------------------------------------------------------------------------------------

    def _new_target(self, t: float, est: Array) -> Array:
        """Record an estimate; the target it gives (clipped to [ω_min, ω_max], A6)."""
        c = self.config
        self._updates.append((float(t), (float(est[0]), float(est[1]), float(est[2]))))
        return np.clip(est, c.omega_min, c.omega_max)

    def _run_kernel(
        self,
        t: Array,
        Y: Array,
        TAU: Array,
        X: Array,
        status: NDArray[np.int8],
        W: Array,
        upd_index: NDArray[np.int64],
        upd_target: Array,
    ) -> None:
        sk.run_scheduled(
            self.x,
            self._clock,
            self._schedule,
            self._omega,
            self._target,
            upd_index,
            upd_target,
            t,
            Y,
            TAU,
            self._P,
            self._G,
            self._Minv,
            self._D,
            self.h_max,
            self.max_hold_s,
            self.ramp_time_constant_s,
            self._grid,
            self._alpha,
            self._cost,
            self.check.budget,
            not self.config.per_dof,
            X,
            status,
            W,
        )

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t (s) with measurement y (NaN = missing) and force τ held since the last sample."""
        tf = float(t)
        Y = np.asarray(y, dtype=float).reshape(1, 3)
        TAU = ZERO3.reshape(1, 3) if tau is None else np.asarray(tau, dtype=float).reshape(1, 3)
        self.estimator.add(tf, Y[0])
        est = self.estimator.estimate(tf)
        if est is None:
            upd_index, upd_target = _NO_INDEX, _NO_TARGET
        else:
            upd_index, upd_target = _ZERO_INDEX, self._new_target(tf, est).reshape(1, 3)
        X = np.empty((1, N_STATE))
        status = np.empty(1, dtype=np.int8)
        W = np.empty((1, 3))
        self._run_kernel(np.array([tf]), Y, np.ascontiguousarray(TAU), X, status, W, upd_index, upd_target)
        return estimate_from_state(tf, self.x, int(status[0]))

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample, with the same numbers.

        The estimates depend on the measurements only, not on the observer: the estimator first goes
        through the record (vectorised appends up to each update time, one spectrum per update), then one
        compiled pass runs the observer, taking each new target at the sample where `step` would have.
        """
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        X = np.empty((n, N_STATE))
        status = np.empty(n, dtype=np.int8)
        W = np.empty((n, 3))
        est = self.estimator
        first_update = len(self._updates)
        index: list[int] = []
        targets: list[Array] = []
        for j in est.add_until_updates(t_arr, Y):
            update = est.estimate(float(t_arr[j]))
            if update is not None:
                index.append(j)
                targets.append(self._new_target(float(t_arr[j]), update))
        upd_index = np.array(index, dtype=np.int64)
        upd_target = np.array(targets, dtype=float).reshape(-1, 3)
        self._run_kernel(t_arr, Y, TAU, X, status, W, upd_index, upd_target)
        updates = tuple(self._updates[first_update:])
        return Run(t_arr, X[:, ETA], X[:, NU], X[:, BIAS], X[:, XI2], status, W, {"updates": updates})


_NO_INDEX = np.zeros(0, dtype=np.int64)
_NO_TARGET = np.zeros((0, 3))
_ZERO_INDEX = np.zeros(1, dtype=np.int64)


# --- readable reference -----------------------------------------------------------------------------------


def reference_run(
    vessel: VesselModel,
    tuning: PassiveTuning,
    check: ContractionCheck,
    config: WaveFrequencyConfig,
    omega0_initial: Sequence[float],
    t: Array,
    y: Array,
    tau: Array | None = None,
    *,
    ramp_time_constant_s: float = 15.0,
    h_max: float = 0.1,
    max_hold_s: float = 2.0,
) -> tuple[Array, Array]:
    """The same algorithm written plainly: `PassiveObserver.step` with `set_gains` every sample and the
    schedule in Python. Returns (states (n, 15), ω0 (n, 3)). Slow; for the agreement test."""
    n = len(t)
    tau_a = np.zeros((n, 3)) if tau is None else np.asarray(tau, dtype=float)
    obs = PassiveObserver(
        vessel, tuning.with_omega0(np.asarray(omega0_initial, dtype=float)), allow_unchecked=True
    )
    est = WaveFrequencyEstimator(config)
    omega = np.array(omega0_initial, dtype=float)
    target = omega.copy()
    beta = check.budget
    shared = not config.per_dof
    t_prev: float | None = None
    X = np.full((n, N_STATE), np.nan)
    W = np.empty((n, 3))

    def cost_to(new: Array) -> float:
        if shared:
            return check.cost_between(omega[0], new[0])
        return sum(check.cost_between(omega[i], new[i], i) for i in range(3))

    for k in range(n):
        tk = float(t[k])
        est.add(tk, y[k])
        e = est.estimate(tk)
        if e is not None:
            target = np.clip(e, config.omega_min, config.omega_max)
        if t_prev is None:
            t_prev = tk
        elif tk > t_prev:
            dt = tk - t_prev
            t_prev = tk
            a_lo = check.alpha
            wmin = float(omega.min())
            jj = int(np.clip(np.searchsorted(check.omega, wmin) - 1, 0, len(check.omega) - 2))
            rate = (
                a_lo[0]
                if wmin <= check.omega[0]
                else a_lo[-1]
                if wmin >= check.omega[-1]
                else min(a_lo[jj], a_lo[jj + 1])
            )
            beta = min(check.budget, beta + rate * dt)
            if np.any(omega != target):
                near = bool(np.all(np.abs(target - omega) <= sk.SNAP * omega))
                f = 1.0 if near or ramp_time_constant_s <= 0 else 1.0 - math.exp(-dt / ramp_time_constant_s)
                new = omega + (target - omega) * f
                c = cost_to(new)
                if c > beta:  # the largest fraction of the step the budget allows
                    lo, hi = 0.0, 1.0
                    for _ in range(40):
                        mid = 0.5 * (lo + hi)
                        if cost_to(omega + mid * (new - omega)) <= beta:
                            lo = mid
                        else:
                            hi = mid
                    new = omega + lo * (new - omega)
                    c = cost_to(new)
                beta = max(0.0, beta - c)
                omega = new
                obs.set_gains(passive_gains(vessel, tuning.with_omega0(omega.copy())), allow_unchecked=True)
        r = obs.step(tk, y[k], tau_a[k])
        if r.status != "initializing":
            X[k] = obs.x
        W[k] = omega
    return X, W
