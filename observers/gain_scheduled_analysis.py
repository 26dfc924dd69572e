"""Contraction analysis for gain scheduling: Torsetnes, Jouffroy & Fossen (2004), Sec. III-C, eqs (7), (50),
with Fossen & Strand (1999) Proposition 1 and tuning rule (48) (Torsetnes' (53)).

What range of wave frequencies ω0 may `observers.gain_scheduled.GainScheduledObserver` schedule over, and
how fast may ω0 move there? The observer's error dynamics at a frozen ω̄0 are those of the passive observer
with the gains ``passive_gains(vessel, tuning.with_omega0(ω̄0))`` (`observers.passive_tuning`).

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
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from observers.kinematics import rotation
from observers.passive_tuning import (
    Check,
    PassiveTuning,
    TuningError,
    check_spr,
    check_tuning_rule,
    error_dynamics_matrix,
    passive_gains,
)
from observers.state import N_STATE
from observers.vessel import VesselModel

Array = NDArray[np.float64]

DEFAULT_TUNING = PassiveTuning(bias_time_constant_s=math.inf)
"""Torsetnes (31): random-walk bias; everything else dpgw's passive defaults (relative to ω0)."""

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
    P = sla.solve_continuous_lyapunov((Ah + sigma * np.eye(N_STATE)).T, -np.eye(N_STATE))
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
