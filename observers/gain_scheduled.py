"""Gain-scheduled wave filtering: Torsetnes, Jouffroy & Fossen (2004), Sec. III, on dpgw's passive observer.

Observer (29)–(34) — Fossen & Strand's (22)–(26) with the wave frequency ω̄0 as a parameter::

    ξ̂' = A_w(ω̄0) ξ̂ + K1(ω̄0) ỹ                                                     (29), (34)
    η̂' = R(ψ) ν̂ + K2(ω̄0) ỹ                                                        (30)
    b̂' = K3 ỹ                           random-walk bias: no 1/T term (ERRATA)     (31)
    M ν̂' + D ν̂ = τ + Rᵀ(ψ) b̂ + Rᵀ(ψ) K4 ỹ                                          (32)
    ŷ = η̂ + C_w ξ̂,  ỹ = y − ŷ (heading innovation wrapped, ERRATA of Fossen & Strand)  (33)

Gains (51)–(52) as corrected in ERRATA, with k = ωc/ω0 (`PassiveTuning.cutoff_ratio`)::

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
estimate (``ramp_time_constant_s``, 15 s), the gains recomputed in closed form at every sample (`gains_at`,
the arithmetic of `passive_gains`), and the speed limited by the contraction budget below. The compiled
loop (`run_scheduled`) runs the passive kernel (`observers._passive_kernel`) sample by sample with the
scheduled gains. The estimates depend on the measurements only, so batch `run` first takes the record
through the estimator (vectorised appends up to each update time) and then makes one compiled pass that
takes each new target at the sample where `step` would have: the same numbers as stepping.

**Checks at construction** over a geometric grid of ω0 in [ω_min, ω_max] (`contraction_check`):

1. tuning rule (53)/(48): 1/T ≪ λ/κ < ω0 < ωc and ζn > ζ > 0, at every grid point;
2. Proposition 1 of Fossen & Strand (SPR), numerically, at every grid point (with T = ∞ the bias
   integrator makes h(jω) only positive real as ω → 0, the margin there is nil; stability rests on 3.);
3. (50): a metric M(ω̄0) = Mᵀ > 0 with A(ω̄0)ᵀM + MA(ω̄0) < 0 — computed explicitly (a Lyapunov
   equation in time-scaled coordinates, `_metric`), with a decay margin: the slowest mode must decay
   faster than ``min_decay_rate`` (1e-3 s⁻¹) at every grid point and heading. (The paper's own (48),
   A + Aᵀ < 0, i.e. M = I, cannot hold: A has zero diagonal entries in the ξ rows.) The metric is
   computed per heading in body axes, as in (39)–(47): dpgw's K3, K4 are scaled by diag(M), which is not
   a multiple of I in surge/sway, so they do not commute with R(ψ) (the paper's A7 fails) and the
   body-axes error dynamics depend on ψ;
4. the time-varying part. Theorem 3 states (50) for frozen ω̄0: the paper drops dK/dt of its
   affine-quadratic-stability condition (7) by assumption A4 (ω̇0 = 0) and A5 (updates every T
   minutes). It gives no bound on how fast ω̄0 may move. dpgw keeps the term: with the metric
   M(ω̄0) of 3., the differential dynamics satisfy

       d/dt (δxᵀ M δx) ≤ (−2α(ω̄0) + κ(ω̄0)·|dω̄0/dt|) · δxᵀ M δx,

   α = the metric's decay rate, κ = the spectral radius of M^-½ (dM/dω̄0) M^-½. A scheduling budget
   β(t) ∈ [0, L0] makes the time-varying system contracting at every instant in the metric e^β·M
   (bounded between M and e^{L0}·M, so Definition 1 holds): β' = α − κ|dω̄0/dt|, capped at L0. The
   contraction rate during scheduling is then at least α/2, and a large move (the first adaptation,
   a new sea) only spends budget; when it is spent, |dω̄0/dt| ≤ α/κ (`ContractionCheck.sustained_rate`).
   L0 = 2 ln(``transient_gain``): the scheduling can amplify a transient error, measured in the metric, by
   at most that factor. The kernel enforces the budget at every sample; it is the certified version of the
   paper's "ω0 is slowly varying".

The tables are sampled on the grid; between grid points the kernel uses the smaller α and the larger κ
of the cell's end points (κ plus 10 %). A violation of 1–3 raises `ContractionError` naming the condition
(``allow_unchecked=True`` for experiments). Caveats: the metric is for frozen heading — the yaw rate r
adds r·∂M/∂ψ, which the paper's (47)–(48) and this check leave out (`ContractionCheck.yaw_rate_limit` is
the r the margin alone would absorb: ≈ 0.007 rad/s at ω0 = 0.55 for the supply vessel, well above DP yaw
rates); with ``per_dof=True`` the time-varying part uses the partial sensitivities on the diagonal
ω01 = ω02 = ω03, and the frozen check (50) covers a 5×5×5 grid of per-DOF ω0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
from numba import njit
from numpy.typing import ArrayLike, NDArray

from observers import _passive_kernel as kernel
from observers.kinematics import rotation
from observers.passive import (
    ZERO3,
    PassiveEstimate,
    PassiveObserver,
    PassiveRun,
    estimate_from_state,
    initial_state,
)
from observers.passive_tuning import (
    BIAS,
    ETA,
    NU,
    XI2,
    Check,
    PassiveGains,
    PassiveTuning,
    TuningError,
    check_spr,
    check_tuning_rule,
    error_dynamics_matrix,
    passive_gains,
)
from observers.vessel import VesselModel
from observers.wave_frequency import WaveFrequencyConfig, WaveFrequencyEstimator

Array = NDArray[np.float64]

DEFAULT_TUNING = PassiveTuning(bias_time_constant_s=math.inf)
"""Torsetnes (31): random-walk bias; everything else dpgw's passive defaults (relative to ω0)."""

SNAP = 1e-9
"""Within this relative distance of its target, the scheduled ω0 takes the target exactly (then rests)."""
_METRIC_SHIFT = 0.8  # M solves (Â + σI)ᵀP + P(Â + σI) = −I with σ = 0.8 × the spectral margin
_KAPPA_MARGIN = 1.1  # a grid cell's cost uses the larger end-point κ plus 10 %
_CENTER_POWER = 0.5  # state scaling powers of ω0 (−1, 0, 0, 2, 1) centred by −½ (see _scaling)


class ContractionError(TuningError):
    """The allowed ω0 range cannot be scheduled safely: names the condition that fails and where."""


# --- the checks -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ContractionCheck:
    """Result of `contraction_check` over ω0 in [omega_min, omega_max].

    omega (n,): grid (rad/s). alpha (n,): decay rate of the metric M(ω0), min over headings (1/s).
    kappa (k, n): metric sensitivity (per rad/s); k = 1 (shared ω0) or 3 (per-DOF partials).
    cost (k, n): cumulative budget cost from omega[0] (cell-wise conservative ∫κ dω).
    spectral_abscissa (n,): slowest error-dynamics eigenvalue's real part, max over headings (1/s).
    spr_margin_deg (n,): SPR phase margin below 10·ωc. yaw_rate_limit (n,): α/κ_ψ (rad/s), the yaw rate the
    metric's heading dependence could absorb on its own (not enforced; the paper's (47)–(48) leave it out).
    budget: L0. checks: named results (all grid points).
    """

    omega: Array
    alpha: Array
    kappa: Array
    cost: Array
    spectral_abscissa: Array
    spr_margin_deg: Array
    yaw_rate_limit: Array
    budget: float
    checks: tuple[Check, ...]
    per_dof: bool = False

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def sustained_rate(self) -> Array:
        """Largest |dω0/dt| (rad/s²) allowed with an empty budget, per grid point: α/Σκ."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray(self.alpha / self.kappa.sum(axis=0), dtype=float)

    def cost_between(self, w_from: float, w_to: float, dof: int = 0) -> float:
        """Budget spent moving ω0 (one DOF, or the shared one) from w_from to w_to."""
        K = self.cost[dof]
        return float(abs(np.interp(w_to, self.omega, K) - np.interp(w_from, self.omega, K)))

    def as_dict(self) -> dict[str, Any]:
        return {
            "omega": self.omega.tolist(),
            "alpha": self.alpha.tolist(),
            "kappa": self.kappa.tolist(),
            "sustained_rate": self.sustained_rate.tolist(),
            "spectral_abscissa": self.spectral_abscissa.tolist(),
            "spr_margin_deg": self.spr_margin_deg.tolist(),
            "yaw_rate_limit": self.yaw_rate_limit.tolist(),
            "budget": self.budget,
            "per_dof": self.per_dof,
            "checks": [c.as_dict() for c in self.checks],
        }


def _scaling(vessel: VesselModel, w: Array) -> Array:
    """Diagonal S(ω0) of dimensionless, time-scaled error coordinates x = S z.

    With the default (ratio) tuning, ξ1 ∝ 1/ω0, ξ2, η ∝ 1, b ∝ diag(M)·ω0², ν ∝ ω0 make S⁻¹AS/ω0 depend on
    ω0 only through D/(M ω0); the common factor ω0^-½ centres the powers. A constant-structure change of
    coordinates: any choice gives a valid metric, this one makes it vary little with ω0.
    """
    m = np.diag(vessel.M)
    c = w**-_CENTER_POWER
    return np.concatenate([c / w, c, c, m * w**2 * c, w * c])


def _rotate_to_body(A: Array, psi: float) -> Array:
    """T A Tᵀ with T = diag(Rᵀ, Rᵀ, Rᵀ, Rᵀ, I): ξ, η, b to the body axes (Torsetnes (39), (47))."""
    R = rotation(psi)
    T = sla.block_diag(R.T, R.T, R.T, R.T, np.eye(3))
    return np.asarray(T @ A @ T.T, dtype=float)


def _error_matrix(vessel: VesselModel, tuning: PassiveTuning, w: Array, psi: float = 0.0) -> Array:
    return error_dynamics_matrix(vessel, passive_gains(vessel, tuning.with_omega0(w)), psi)


def _metric(vessel: VesselModel, tuning: PassiveTuning, w: Array, psi: float) -> tuple[Array, Array]:
    """Metric M(ω0, ψ) of (50) in body axes, and the body-axes error matrix A it is made for.

    P solves (Â + σI)ᵀP + P(Â + σI) = −I for the scaled matrix Â = S⁻¹AS (σ = 0.8 × its spectral
    margin), so AᵀM + MA ≤ −2σM: M = S⁻ᵀPS⁻¹ contracts at least at rate σ.
    """
    s = _scaling(vessel, w)
    A = _rotate_to_body(_error_matrix(vessel, tuning, w, psi), psi)
    Ah = A * s[None, :] / s[:, None]
    sigma = _METRIC_SHIFT * max(-float(np.linalg.eigvals(Ah).real.max()), 0.0)
    P = sla.solve_continuous_lyapunov((Ah + sigma * np.eye(15)).T, -np.eye(15))
    P = 0.5 * (P + P.T)
    return P / s[:, None] / s[None, :], A


def _decay_rate(M: Array, A: Array) -> float:
    """Largest α with AᵀM + MA ≤ −2αM (negative if the metric does not contract)."""
    L = np.linalg.cholesky(M)
    Li = np.linalg.inv(L)
    F = Li @ (A.T @ M + M @ A) @ Li.T
    return float(-0.5 * np.linalg.eigvalsh(0.5 * (F + F.T)).max())


def _sensitivity(M: Array, dM: Array) -> float:
    Li = np.linalg.inv(np.linalg.cholesky(M))
    F = Li @ dM @ Li.T
    return float(np.abs(np.linalg.eigvalsh(0.5 * (F + F.T))).max())


_CHECK_CACHE: dict[tuple[Any, ...], ContractionCheck] = {}
_CHECK_CACHE_SIZE = 16


def contraction_check(
    vessel: VesselModel,
    tuning: PassiveTuning | None = None,
    omega_min: float = 0.3,
    omega_max: float = 1.6,
    *,
    per_dof: bool = False,
    n_grid: int = 25,
    headings: int = 4,
    min_decay_rate: float = 1e-3,
    transient_gain: float = 10.0,
) -> ContractionCheck:
    """Tuning rule (53), SPR, (50) with a margin, and the scheduling budget of (7) over [ω_min, ω_max].

    Returns the result; `validate_contraction` raises on failure. See the module docstring. Results are
    cached (a pure function of its arguments; the vessel by its M and D).
    """
    tuning = tuning or DEFAULT_TUNING
    key = (
        vessel.M.tobytes(),
        np.asarray(vessel.D, dtype=float).tobytes(),
        repr(tuning),
        float(omega_min),
        float(omega_max),
        per_dof,
        n_grid,
        headings,
        float(min_decay_rate),
        float(transient_gain),
    )
    hit = _CHECK_CACHE.get(key)
    if hit is not None:
        return hit
    result = _contraction_check(
        vessel, tuning, omega_min, omega_max, per_dof, n_grid, headings, min_decay_rate, transient_gain
    )
    if len(_CHECK_CACHE) >= _CHECK_CACHE_SIZE:
        _CHECK_CACHE.pop(next(iter(_CHECK_CACHE)))
    _CHECK_CACHE[key] = result
    return result


def _contraction_check(
    vessel: VesselModel,
    tuning: PassiveTuning,
    omega_min: float,
    omega_max: float,
    per_dof: bool,
    n_grid: int,
    headings: int,
    min_decay_rate: float,
    transient_gain: float,
) -> ContractionCheck:
    if not (0 < omega_min < omega_max and math.isfinite(omega_max)):
        raise ContractionError(
            f"assumption A6 needs 0 < omega_min < omega_max < ∞, got {omega_min}, {omega_max}"
        )
    if not transient_gain >= 1.0:
        raise ValueError(f"transient_gain must be ≥ 1, got {transient_gain!r}")
    grid = np.geomspace(omega_min, omega_max, n_grid)
    # the body-axes error dynamics depend on ψ through Rᵀ(ψ) K R(ψ): period π
    psis = np.linspace(0.0, math.pi, headings, endpoint=False)
    rule_bad: list[str] = []
    spr_bad: list[str] = []
    metric_bad: list[str] = []
    alpha = np.full(n_grid, np.nan)
    yaw_rate = np.full(n_grid, np.nan)
    abscissa = np.empty(n_grid)
    spr_margin = np.empty(n_grid)
    n_par = 3 if per_dof else 1
    kappa = np.zeros((n_par, n_grid))
    for j, w in enumerate(grid):
        w3 = np.full(3, w)
        try:
            gains = passive_gains(vessel, tuning.with_omega0(w3))
        except TuningError as exc:
            rule_bad.append(f"ω0 = {w:.4g}: {exc}")
            continue
        rule = check_tuning_rule(gains)
        if not rule.ok:
            rule_bad.append(f"ω0 = {w:.4g}: {rule.detail}")
        spr = check_spr(gains)
        spr_margin[j] = spr.values["margin_deg"][0]
        if not spr.ok:
            spr_bad.append(f"ω0 = {w:.4g}: {spr.detail}")
        abscissa[j] = max(
            float(np.linalg.eigvals(error_dynamics_matrix(vessel, gains, psi)).real.max()) for psi in psis
        )
        if not abscissa[j] <= -min_decay_rate:
            metric_bad.append(
                f"ω0 = {w:.4g}: slowest error mode {abscissa[j]:.3g} s⁻¹ is not below −{min_decay_rate:g} s⁻¹"
            )
            alpha[j] = math.nan
            continue
        # (50) per heading in body axes: the vessel-scaled K3, K4 (diag(M)) do not commute with R(ψ)
        # (Torsetnes' A7), so the body-axes error dynamics, and their metric, depend on ψ.
        h = 1e-4 * w
        dpsi = 1e-4
        a_min, y_min = math.inf, math.inf
        k_max = np.zeros(n_par)
        for psi in psis:
            M, A = _metric(vessel, tuning, w3, psi)
            a = _decay_rate(M, A)
            a_min = min(a_min, a)
            for i in range(n_par):
                d = np.ones(3) if not per_dof else np.eye(3)[i]
                dM = (
                    _metric(vessel, tuning, w3 + h * d, psi)[0] - _metric(vessel, tuning, w3 - h * d, psi)[0]
                ) / (2 * h)
                k_max[i] = max(k_max[i], _sensitivity(M, dM))
            dMy = (
                _metric(vessel, tuning, w3, psi + dpsi)[0] - _metric(vessel, tuning, w3, psi - dpsi)[0]
            ) / (2 * dpsi)
            y_min = min(y_min, a / max(_sensitivity(M, dMy), 1e-300))
        alpha[j] = a_min
        yaw_rate[j] = y_min
        kappa[:, j] = k_max
        if not a_min > 0:
            metric_bad.append(f"ω0 = {w:.4g}: no contracting metric found at some heading (α = {a_min:.3g})")
    checks = [
        Check(
            name="tuning_rule",
            inequality="(53)/(48): K3_i/K4_i = lambda_i/kappa_i < omega0_i < omega_c_i, "
            f"1/T_i << lambda_i/kappa_i, for every omega0 in [{omega_min:g}, {omega_max:g}] rad/s",
            ok=not rule_bad,
            detail=_failures(rule_bad, n_grid) if rule_bad else f"holds on {n_grid} points",
        ),
        Check(
            name="spr",
            inequality="Proposition 1 (Fossen & Strand): arg h_i(jw) > -90 deg, every omega0 in the range",
            ok=not spr_bad,
            detail=_failures(spr_bad, n_grid) if spr_bad else f"holds on {n_grid} points",
        ),
        Check(
            name="contraction_50",
            inequality="(50): A(w0)^T M(w0) + M(w0) A(w0) < 0 with M = M^T > 0, slowest mode < "
            f"-{min_decay_rate:g} 1/s, every omega0 in the range and every heading",
            ok=not metric_bad,
            detail=_failures(metric_bad, n_grid)
            if metric_bad
            else f"holds on {n_grid} points × {headings} headings",
        ),
    ]
    if per_dof and not metric_bad:
        checks.append(_frozen_3d(vessel, tuning, omega_min, omega_max, min_decay_rate))
    ok = all(c.ok for c in checks)
    cost = np.zeros((n_par, n_grid))
    if ok:
        kmax = np.maximum(kappa[:, 1:], kappa[:, :-1]) * _KAPPA_MARGIN
        cost[:, 1:] = np.cumsum(kmax * np.diff(grid)[None, :], axis=1)
    return ContractionCheck(
        omega=grid,
        alpha=alpha,
        kappa=kappa,
        cost=cost,
        spectral_abscissa=abscissa,
        spr_margin_deg=spr_margin,
        yaw_rate_limit=yaw_rate,
        budget=2.0 * math.log(transient_gain),
        checks=tuple(checks),
        per_dof=per_dof,
    )


def _failures(bad: list[str], n: int) -> str:
    return f"fails at {len(bad)} of {n} grid points; " + "; ".join(bad[:3]) + ("; …" if len(bad) > 3 else "")


def _frozen_3d(
    vessel: VesselModel, tuning: PassiveTuning, omega_min: float, omega_max: float, min_decay_rate: float
) -> Check:
    """(50) with different ω0 per DOF: spectral margin on a 5×5×5 grid (and 4 headings)."""
    g = np.geomspace(omega_min, omega_max, 5)
    worst = -math.inf
    where: tuple[float, ...] = ()
    for w1 in g:
        for w2 in g:
            for w3 in g:
                w = np.array([w1, w2, w3])
                for psi in (0.0, 0.5 * math.pi, math.pi / 4, -math.pi / 4):
                    a = float(np.linalg.eigvals(_error_matrix(vessel, tuning, w, psi)).real.max())
                    if a > worst:
                        worst, where = a, (w1, w2, w3)
    ok = worst <= -min_decay_rate
    return Check(
        name="contraction_50_per_dof",
        inequality=f"(50) per DOF: slowest mode < -{min_decay_rate:g} 1/s on a 5x5x5 grid of (w01, w02, w03)",
        ok=ok,
        detail=f"slowest mode {worst:.3g} 1/s at ω0 = {[round(x, 4) for x in where]}",
    )


def validate_contraction(check: ContractionCheck) -> None:
    for c in check.checks:
        if not c.ok:
            raise ContractionError(
                f"gain scheduling over [{check.omega[0]:g}, {check.omega[-1]:g}] rad/s violates "
                f"{c.inequality}: {c.detail}. Narrow the range (omega_min/omega_max) or change the tuning; "
                "allow_unchecked=True runs it anyway for experiments."
            )


# --- compiled scheduling loop -----------------------------------------------------------------------------
# Packed tuning P (10×3), one column per DOF: 0 ζ, 1 ζn, 2 ωc (ratio or rad/s), 3 ωc is a ratio,
# 4 a (ratio or 1/s), 5 a is a ratio, 6 ρ (ratio or rad/s), 7 ρ is a ratio, 8 M_ii, 9 1/T.
# Schedule state S (4): 0 t of the last sample, 1 started, 2 budget β, 3 enabled.


@njit(cache=True, inline="always")
def gains_at(omega, P, G):
    """Packed kernel gains G (8×3) at ω0 — the arithmetic of `passive_gains`, operation for operation."""
    for i in range(3):
        w0 = omega[i]
        z = P[0, i]
        zn = P[1, i]
        wc = w0 * P[2, i] if P[3, i] > 0.0 else P[2, i]
        a = w0 * P[4, i] if P[5, i] > 0.0 else P[4, i]
        rho = w0 * P[6, i] if P[7, i] > 0.0 else P[6, i]
        K4 = P[8, i] * wc * a
        G[0, i] = w0
        G[1, i] = z
        G[2, i] = -2.0 * (zn - z) * wc / w0
        G[3, i] = 2.0 * w0 * (zn - z)
        G[4, i] = wc
        G[5, i] = K4 * rho
        G[6, i] = K4
        G[7, i] = P[9, i]


@njit(cache=True, inline="always")
def _interp(x, xp, fp):
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = np.searchsorted(xp, x) - 1
    f = (x - xp[j]) / (xp[j + 1] - xp[j])
    return fp[j] + f * (fp[j + 1] - fp[j])


@njit(cache=True, inline="always")
def _cell_min(x, xp, fp):
    """min of fp over the grid cell holding x (a conservative piecewise-constant α)."""
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = np.searchsorted(xp, x) - 1
    return min(fp[j], fp[j + 1])


@njit(cache=True, inline="always")
def _cost(omega, new, s, grid, cost, shared):
    c = 0.0
    if shared:
        a = _interp(omega[0], grid, cost[0])
        b = _interp(omega[0] + s * (new[0] - omega[0]), grid, cost[0])
        return abs(b - a)
    for i in range(3):
        a = _interp(omega[i], grid, cost[i])
        b = _interp(omega[i] + s * (new[i] - omega[i]), grid, cost[i])
        c += abs(b - a)
    return c


@njit(cache=True, inline="always")
def advance_schedule(omega, target, S, dt, tau_r, grid, alpha, cost, budget, shared, new):
    """Move ω0 over dt towards target: first-order lag τ_r, within the contraction budget. True if moved.

    ``new`` is scratch space (3,). Within SNAP (relative) of the target, ω0 takes the target exactly.
    """
    moving = False
    near = True
    for i in range(3):
        if omega[i] != target[i]:
            moving = True
            if abs(target[i] - omega[i]) > SNAP * omega[i]:
                near = False
    if not moving and S[2] >= budget:
        return False  # at rest with a full budget: nothing to do
    w_min = omega[0]
    for i in range(1, 3):
        w_min = min(w_min, omega[i])
    beta = min(budget, S[2] + _cell_min(w_min, grid, alpha) * dt)
    if not moving:
        S[2] = beta
        return False
    f = 1.0 if near or tau_r <= 0.0 else 1.0 - math.exp(-dt / tau_r)
    for i in range(3):
        new[i] = omega[i] + (target[i] - omega[i]) * f
    c = _cost(omega, new, 1.0, grid, cost, shared)
    s = 1.0
    if c > beta:
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if _cost(omega, new, mid, grid, cost, shared) <= beta:
                lo = mid
            else:
                hi = mid
        s = lo
        c = _cost(omega, new, s, grid, cost, shared)
    for i in range(3):
        omega[i] = new[i] if s == 1.0 else omega[i] + s * (new[i] - omega[i])
    S[2] = max(0.0, beta - c)
    return s > 0.0


@njit(cache=True)
def run_scheduled(
    x,
    clock,
    S,
    omega,
    target,
    upd_index,
    upd_target,
    t,
    Y,
    TAU,
    P,
    G,
    Minv,
    D,
    h_max,
    max_hold,
    tau_r,
    grid,
    alpha,
    cost,
    budget,
    shared,
    X_out,
    status_out,
    W_out,
):
    """Per sample: take a new target if one arrives at sample k (upd_index, sorted; upd_target rows), advance
    the schedule to t_k (its gains held over the interval), then the passive step."""
    n = t.shape[0]
    p = 0
    scratch = np.empty(3)
    for k in range(n):
        while p < upd_index.shape[0] and upd_index[p] == k:
            for i in range(3):
                target[i] = upd_target[p, i]
            p += 1
        tk = t[k]
        if S[1] == 0.0:
            S[0] = tk
            S[1] = 1.0
        elif tk > S[0]:
            dt = tk - S[0]
            S[0] = tk
            if S[3] > 0.0 and advance_schedule(
                omega, target, S, dt, tau_r, grid, alpha, cost, budget, shared, scratch
            ):
                gains_at(omega, P, G)
        code = kernel.step(x, clock, tk, Y[k], TAU[k], G, Minv, D, h_max, max_hold)
        status_out[k] = code
        for i in range(3):
            W_out[k, i] = omega[i]
        if code == kernel.STATUS_INITIALIZING:
            for j in range(15):
                X_out[k, j] = np.nan
        else:
            for j in range(15):
                X_out[k, j] = x[j]


# --- the observer -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GainScheduledRun(PassiveRun):
    """`PassiveRun` plus the ω0 in use at each sample (n, 3) and the estimates made during the run."""

    omega0: Array = field(default_factory=lambda: np.empty((0, 3)))
    updates: tuple[tuple[float, tuple[float, float, float]], ...] = ()


def _pack_tuning(vessel: VesselModel, tuning: PassiveTuning) -> Array:
    g = passive_gains(vessel, tuning)  # validates the fields
    P = np.zeros((10, 3))
    P[0], P[1] = g.zeta, g.zeta_n

    def value(explicit: Any, ratio: Any) -> tuple[Array, Array]:
        if explicit is not None:
            return np.broadcast_to(np.asarray(explicit, dtype=float), (3,)), np.zeros(3)
        return np.broadcast_to(np.asarray(ratio, dtype=float), (3,)), np.ones(3)

    P[2], P[3] = value(tuning.omega_c, tuning.cutoff_ratio)
    P[4], P[5] = value(tuning.velocity_injection, tuning.velocity_injection_ratio)
    P[6], P[7] = value(tuning.bias_corner, tuning.bias_corner_ratio)
    P[8] = np.diag(vessel.M)
    P[9] = g.t_inv
    return np.ascontiguousarray(P)


class GainScheduledObserver:
    """Passive observer whose wave-filter gains follow an on-line estimate of ω0 (Torsetnes et al. 2004).

    ``step(t, y, tau)`` and ``run(t, y, tau)`` as `PassiveObserver` (same numbers either way); ``omega0`` is
    the wave frequency in use (3,), ``extra()`` the estimator's fields for the estimate message.

    estimator: `WaveFrequencyConfig` (window, update period T, ω range of A6, per-DOF or shared).
    omega0_initial: ω0 to start from (rad/s; one or per DOF), default the tuning's ω0.
    ramp_time_constant_s: time constant of the first-order move of ω0 towards each new estimate.
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
        h_max: float = 0.1,
        max_hold_s: float = 2.0,
        ramp_time_constant_s: float = 15.0,
        transient_gain: float = 10.0,
        schedule: bool = True,
    ) -> None:
        self.vessel = vessel
        self.tuning = tuning or DEFAULT_TUNING
        self.config = estimator or WaveFrequencyConfig()
        self.h_max = float(h_max)
        self.max_hold_s = float(max_hold_s)
        if not (self.h_max > 0 and self.max_hold_s > 0):
            raise ValueError("h_max and max_hold_s must be positive")
        if not (math.isfinite(ramp_time_constant_s) and ramp_time_constant_s >= 0):
            raise ValueError(f"ramp_time_constant_s must be ≥ 0, got {ramp_time_constant_s!r}")
        self.ramp_time_constant_s = float(ramp_time_constant_s)
        self.scheduling = bool(schedule)
        c = self.config
        w_init = np.broadcast_to(
            np.asarray(self.tuning.omega0 if omega0_initial is None else omega0_initial, dtype=float), (3,)
        ).copy()
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
        self._P = _pack_tuning(vessel, self.tuning)
        self._Minv = np.ascontiguousarray(vessel.Minv)
        self._D = np.ascontiguousarray(vessel.D, dtype=float)
        self.estimator = WaveFrequencyEstimator(self.config)
        self.reset()

    # -- state -------------------------------------------------------------------------------------------

    def reset(self) -> None:
        self.x = np.zeros(15)
        self._clock = np.zeros(2)
        self._omega = self.omega0_initial.copy()
        self._target = self.omega0_initial.copy()
        self._S = np.array([0.0, 0.0, self.check.budget, 1.0 if self.scheduling else 0.0])
        self._G = np.zeros((8, 3))
        gains_at(self._omega, self._P, self._G)
        self.estimator.reset()
        self._updates: list[tuple[float, tuple[float, float, float]]] = []

    @property
    def initialized(self) -> bool:
        return bool(self._clock[1])

    @property
    def t(self) -> float:
        return float(self._clock[0])

    @property
    def omega0(self) -> Array:
        """The wave frequency in use per DOF (rad/s)."""
        return self._omega.copy()

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
        return float(self._S[2])

    def initialize(
        self,
        t: float,
        eta: ArrayLike,
        nu: ArrayLike | None = None,
        bias: ArrayLike | None = None,
        eta_wf: ArrayLike | None = None,
    ) -> None:
        """Start from an explicit state (as `PassiveObserver.initialize`); ω0 and the estimator are kept."""
        self.x[:] = initial_state(eta, nu, bias, eta_wf)
        self._clock[:] = (float(t), 1.0)

    def extra(self) -> dict[str, Any]:
        e = self.estimator
        return {
            "omega0_estimate": None if e.latest is None else [float(v) for v in e.latest],
            "omega0_target": [float(v) for v in self._target],
            "omega0_updates": e.updates,
            "omega0_skipped": e.skipped,
            "omega0_last_skip": e.last_skip,
            "scheduling_budget": float(self._S[2]),
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
        run_scheduled(
            self.x,
            self._clock,
            self._S,
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

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> PassiveEstimate:
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
        X = np.empty((1, 15))
        status = np.empty(1, dtype=np.int8)
        W = np.empty((1, 3))
        self._run_kernel(np.array([tf]), Y, np.ascontiguousarray(TAU), X, status, W, upd_index, upd_target)
        return estimate_from_state(tf, self.x, int(status[0]))

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> GainScheduledRun:
        """`step` over every sample, with the same numbers.

        The estimates depend on the measurements only, not on the observer: the estimator first goes
        through the record (vectorised appends up to each update time, one spectrum per update), then one
        compiled pass runs the observer, taking each new target at the sample where `step` would have.
        """
        t_arr = np.ascontiguousarray(t, dtype=float)
        n = t_arr.shape[0]
        Y = np.ascontiguousarray(y, dtype=float).reshape(n, 3)
        TAU = np.zeros((n, 3)) if tau is None else np.ascontiguousarray(tau, dtype=float).reshape(n, 3)
        X = np.empty((n, 15))
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
        return GainScheduledRun(
            t_arr,
            X[:, ETA],
            X[:, NU],
            X[:, BIAS],
            X[:, XI2],
            status,
            omega0=W,
            updates=tuple(self._updates[first_update:]),
        )


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
    X = np.full((n, 15), np.nan)
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
                near = bool(np.all(np.abs(target - omega) <= SNAP * omega))
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
