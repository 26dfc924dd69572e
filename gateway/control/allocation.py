"""Thrust allocation: generalised force demand τ = [X, Y, N] → thrust and azimuth per thruster.

Implements the extended thrust configuration of Hajivand & Mousavizadegan (2010), eq (22), with the
signs the printed equation lost restored: an azimuth i at (xᵢ, yᵢ) contributes a free force
(F_x,i, F_y,i) with the columns [1, 0, −yᵢ]ᵀ and [0, 1, xᵢ]ᵀ (yaw moment = x·F_y − y·F_x); a tunnel or
main propeller contributes its signed thrust uᵢ along its fixed direction αᵢ, column
[cos αᵢ, sin αᵢ, xᵢ sin αᵢ − yᵢ cos αᵢ]ᵀ.
Then τ = B f with B constant, and an azimuth's thrust is |Fᵢ|, its angle atan2(F_y,i, F_x,i).

* `PseudoInverseAllocator` — the paper's "T⁻¹(α) τ": the weighted minimum-norm solution
  f = W⁻¹Bᵀ(BW⁻¹Bᵀ)⁻¹τ, no limits; a demand beyond capacity is scaled down as a whole (reported).
* `QPAllocator` — the default: a convex QP solved every step — by default in one compiled call
  (`gateway.control._allocation_kernel`: the same limits, QP and commands, a Goldfarb–Idnani dual
  active-set solver), with this module's Python path around DAQP (dual active set, warm-started) as its
  tested reference and fallback (``solver="daqp"``)::

      min  ½ Σᵢ wᵢ (p |f̂ᵢ|² + c (f̂ᵢ·nᵢ / max(T̂₀,ᵢ, θ))²)  +  Σⱼ ρ₁,ⱼ |ŝⱼ| + ½ ρ₂,ⱼ ŝⱼ²
      s.t. B f + s = τ,  f in the per-thruster convex sets of this step (docs/allocation.md)

  in scaled units f̂ᵢ = fᵢ / T_max,i, ŝⱼ = sⱼ / τ_ref,j: a quadratic power proxy (p = ``power_weight``), a
  cost on each azimuth's turn (c = ``turn_weight``): the force across its current direction nᵢ divided by
  its present thrust T̂₀,ᵢ (floored at θ = ``turn_thrust_floor``) is the angle turned, so a turn costs
  the same at low thrust as at high, and an exact (ℓ₁) plus heavy quadratic (ℓ₂) penalty on the slack s,
  so that a feasible τ is met exactly and an infeasible one gives the closest achievable τ with
  ``saturated=True``. With two or more azimuths in service each is asked to keep ``bias_fraction`` of its
  T_max along its present direction (thrust biasing: they push against each other, and the resultant
  turns by changing magnitudes instead of slewing the azimuths) — a soft floor: its shortfall eᵢ ≥ 0 is
  priced (``bias_l1_weight`` eᵢ + ½ ``bias_weight`` eᵢ²) far below the slack, so the bias gives way
  whenever it and τ cannot both be had, and never makes a reachable τ unreachable.

The convex sets, their approximations (inscribed polygon for |F| ≤ T_max, rate cone around the previous
azimuth clipped by forbidden sectors, half-plane lower thrust bound) and the scaling are documented in
``docs/allocation.md``. Angles: radians, direction of the force on the hull, clockwise from the bow,
[-π, π). Thrusts: N (signed for tunnels and main propellers, ≥ 0 for azimuths).

Pure numerics (DESIGN rule 2). The one exception is ``AllocationResult.solve_time_s``, a diagnostic read
from ``time.perf_counter``; no output depends on it.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import daqp
import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray

from gateway.control import _allocation_kernel as _kernel
from observers.kinematics import ssa, ssa_scalar
from observers.vessel import Thruster, VesselModel

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

TWO_PI = 2.0 * math.pi
_ANGLE_EPS = 1e-9  # rad: an azimuth this close to a forbidden sector's edge is on the edge, not inside
_SAT_TOL = 1e-6  # scaled slack (fraction of τ_ref) above which the allocation reports saturation
DEMAND_CLIP = 100.0
"""A demand larger than this many times τ_ref in some DOF is allocated as the same direction at that size
(`QPAllocator.allocate`): a hundred times what all thrusters together could give in that DOF, so the
achieved τ is the same for any practical purpose, and the QP stays well scaled."""

__all__ = [
    "AllocationResult",
    "PseudoInverseAllocator",
    "QPAllocator",
    "QPData",
    "QPSolution",
    "StepLimits",
    "ThrusterCommand",
    "extended_configuration_matrix",
    "reference_solve_cvxpy",
    "thruster_configuration_matrix",
]


# --------------------------------------------------------------------------------------------------------
# Results


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ThrusterCommand:
    """Thrust (N) and azimuth (rad, force direction, clockwise from the bow, [-π, π)) per thruster, in
    layout order. Tunnels and main propellers: signed thrust, azimuth = their fixed ``angle_rad``.
    Passed back into the next `QPAllocator.allocate` as the current state (or the thrusters' feedback)."""

    thrust: Array
    azimuth: Array

    @classmethod
    def at_rest(cls, vessel: VesselModel) -> ThrusterCommand:
        """Every thruster at zero thrust, pointing at its configured ``angle_rad``."""
        n = len(vessel.thrusters)
        return cls(np.zeros(n), ssa(np.array([t.angle_rad for t in vessel.thrusters], dtype=float)))


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class AllocationResult:
    """One allocation. ``tau_allocated`` = B(azimuth)·thrust of the returned command (N, N, N·m);
    ``slack`` = ``tau_demand − tau_allocated``; ``saturated`` when the demand could not be met;
    ``alarms`` are messages for a person; ``status`` is ``"optimal"``, ``"scaled"`` (pseudo-inverse
    saturation), ``"invalid_input"`` or ``"solver_failed: …"`` (then the previous command is held)."""

    thrust: Array
    azimuth: Array
    tau_allocated: Array
    tau_demand: Array
    slack: Array
    saturated: bool
    alarms: tuple[str, ...]
    solve_time_s: float
    status: str

    @property
    def command(self) -> ThrusterCommand:
        """The result as the state to pass to the next step."""
        return ThrusterCommand(self.thrust, self.azimuth)


# --------------------------------------------------------------------------------------------------------
# Layout: the extended configuration (Hajivand eq (22), the signs restored)


def extended_configuration_matrix(vessel: VesselModel) -> Array:
    """B (3 × n_ext) of τ = B f: two columns [1, 0, −y]ᵀ, [0, 1, x]ᵀ per azimuth (F_x, F_y), one column
    [cos α, sin α, x sin α − y cos α]ᵀ per tunnel or main propeller (signed thrust), in layout order."""
    return thruster_configuration_matrix(vessel.thrusters)


def thruster_configuration_matrix(thrusters: Sequence[Thruster]) -> Array:
    """`extended_configuration_matrix` of a list of thrusters (layout order)."""
    cols: list[list[float]] = []
    for t in thrusters:
        if t.kind == "azimuth":
            cols += [[1.0, 0.0, -t.y_m], [0.0, 1.0, t.x_m]]
        else:
            c, s = math.cos(t.angle_rad), math.sin(t.angle_rad)
            cols.append([c, s, t.x_m * s - t.y_m * c])
    return np.array(cols, dtype=float).reshape(-1, 3).T


class _Layout:
    """Per-thruster numbers of a vessel, as arrays, and the scaling of the allocation problem."""

    def __init__(self, vessel: VesselModel, weights: Mapping[int, float] | Sequence[float] | None) -> None:
        th = vessel.thrusters
        if not th:
            raise ValueError(f"vessel '{vessel.name}': no thrusters to allocate to")
        self.vessel = vessel
        self.n = len(th)
        self.ids = [t.id for t in th]
        self.is_az = np.array([t.kind == "azimuth" for t in th], dtype=bool)
        self.x = np.array([t.x_m for t in th], dtype=float)
        self.y = np.array([t.y_m for t in th], dtype=float)
        self.tmax = np.array([t.max_thrust_n for t in th], dtype=float)
        self.tmin = np.where(self.is_az, 0.0, np.array([min(t.min_thrust_n, 0.0) for t in th], dtype=float))
        # the configured limits; ``tmax``/``tmin`` are zero for a thruster out of service (`set_available`)
        self.tmax_rated, self.tmin_rated = self.tmax.copy(), self.tmin.copy()
        self.available = np.ones(self.n, dtype=bool)
        # scale of each thruster's force: its largest thrust magnitude
        self.cap = np.maximum(self.tmax, -self.tmin)
        self.rate = np.array([t.azimuth_rate_rad_s for t in th], dtype=float)
        self.time_constant = np.array([t.thrust_time_constant_s for t in th], dtype=float)
        self.fixed_angle = ssa(np.array([t.angle_rad for t in th], dtype=float))
        self.weights = _per_thruster(weights, self.ids, "weights", default=1.0)
        if np.any(self.weights <= 0) or not np.all(np.isfinite(self.weights)):
            raise ValueError(f"weights must be positive and finite, got {self.weights.tolist()}")
        # extended variables: 2 per azimuth, 1 per fixed thruster
        self.first = np.zeros(self.n, dtype=int)  # index of thruster i's first variable
        k = 0
        for i in range(self.n):
            self.first[i] = k
            k += 2 if self.is_az[i] else 1
        self.n_ext = k
        self.B = extended_configuration_matrix(vessel)
        self.owner = np.repeat(np.arange(self.n), np.where(self.is_az, 2, 1))  # thruster of each variable
        # τ scale per DOF: the sum over thrusters of what each can contribute to that DOF at full thrust
        lever = np.where(self.is_az, np.hypot(self.x, self.y), 0.0)
        c, s = np.cos(self.fixed_angle), np.sin(self.fixed_angle)
        contrib = np.vstack(
            [
                np.where(self.is_az, 1.0, np.abs(c)),
                np.where(self.is_az, 1.0, np.abs(s)),
                np.where(self.is_az, lever, np.abs(self.x * s - self.y * c)),
            ]
        )
        tau_ref = contrib @ self.cap
        floor = max(float(tau_ref.max()), 1.0) * 1e-3
        self.tau_ref = np.maximum(tau_ref, floor)

    def availability(self, available: Mapping[int, bool] | Sequence[bool]) -> Array:
        """The availability mask in layout order from {id: available} (ids not named keep their state) or
        one bool per thruster."""
        mask = self.available.copy()
        if isinstance(available, Mapping):
            unknown = set(available) - set(self.ids)
            if unknown:
                raise ValueError(f"available: unknown thruster ids {sorted(unknown)}; layout has {self.ids}")
            for tid, ok in available.items():
                mask[self.ids.index(tid)] = bool(ok)
        else:
            values = [bool(v) for v in available]
            if len(values) != self.n:
                raise ValueError(f"available: {len(values)} values for {self.n} thrusters")
            mask[:] = values
        return mask

    def weighted_pinv(self) -> Array:
        """The weighted pseudo-inverse of B (weights wᵢ / T_max,i² per force variable) over the available
        thrusters: the columns of those out of service are zero, so they get no force."""
        keep = self.available[self.owner]
        return _weighted_pinv(self.B * keep[None, :], (self.weights / self.cap**2)[self.owner])

    def tau_of(self, thrust: Array, azimuth: Array) -> Array:
        """τ = B(α) T (N, N, N·m): same as ``VesselModel.generalized_force``."""
        fx, fy = thrust * np.cos(azimuth), thrust * np.sin(azimuth)
        return np.array([fx.sum(), fy.sum(), float(self.x @ fy - self.y @ fx)])

    def state(self, previous: ThrusterCommand | None) -> tuple[Array, Array]:
        """Previous (thrust, azimuth) made consistent: finite, azimuths ≥ 0 thrust (a negative azimuth
        thrust is the same force turned by π), everything within [min, max] thrust, fixed angles fixed."""
        if previous is None:
            return np.zeros(self.n), self.fixed_angle.copy()
        thrust = np.asarray(previous.thrust, dtype=float).reshape(self.n)
        angle = np.asarray(previous.azimuth, dtype=float).reshape(self.n)
        if not (np.isfinite(thrust).all() and np.isfinite(angle).all()):
            thrust = np.where(np.isfinite(thrust), thrust, 0.0)
            angle = np.where(np.isfinite(angle), angle, self.fixed_angle)
        flip = self.is_az & (thrust < 0)
        if flip.any():
            angle = np.where(flip, angle + math.pi, angle)
            thrust = np.where(flip, -thrust, thrust)
        angle = np.where(self.is_az, ssa(angle), self.fixed_angle)
        return np.minimum(np.maximum(thrust, self.tmin), self.tmax), angle


def _per_thruster(
    value: Mapping[int, float] | Sequence[float] | float | None, ids: list[int], name: str, default: float
) -> Array:
    """A per-thruster number given as {id: value}, a sequence in layout order, one value, or None."""
    if value is None:
        return np.full(len(ids), default)
    if isinstance(value, Mapping):
        unknown = set(value) - set(ids)
        if unknown:
            raise ValueError(f"{name}: unknown thruster ids {sorted(unknown)}; layout has {ids}")
        return np.array([float(value.get(i, default)) for i in ids], dtype=float)
    arr = np.broadcast_to(np.asarray(value, dtype=float), (len(ids),)).copy()
    return arr


def _weighted_pinv(B: Array, w_ext: Array) -> Array:
    """W⁻¹Bᵀ(BW⁻¹Bᵀ)⁻¹ with W = diag(w_ext), via the SVD pseudo-inverse of B W^{-1/2} (rank-safe)."""
    r = 1.0 / np.sqrt(w_ext)
    return np.asarray(r[:, None] * np.linalg.pinv(B * r[None, :]), dtype=float)


# --------------------------------------------------------------------------------------------------------
# Baseline: weighted pseudo-inverse


class PseudoInverseAllocator:
    """Weighted minimum-norm allocation, the paper's T⁻¹(α)τ (Hajivand eq (22), signs restored):
    unconstrained.

    Minimises Σᵢ wᵢ |fᵢ / T_max,i|² subject to B f = τ (same power proxy and weights as `QPAllocator`).
    When some thruster would exceed its thrust limits, the whole f is scaled down by the largest factor
    that fits (τ keeps its direction, is not met: ``saturated=True``, status ``"scaled"``, an alarm). No
    rate limits and no forbidden sectors. An azimuth with (near) zero thrust keeps its previous angle.
    """

    def __init__(
        self,
        vessel: VesselModel,
        weights: Mapping[int, float] | Sequence[float] | None = None,
        *,
        idle_thrust_fraction: float = 1e-3,
    ) -> None:
        self.layout = L = _Layout(vessel, weights)
        self.pinv = L.weighted_pinv()
        self.idle_thrust = idle_thrust_fraction * L.cap

    @property
    def available(self) -> Array:
        """Which thrusters the allocation may use (layout order; all, unless `set_available` said not)."""
        return self.layout.available.copy()

    def set_available(self, available: Mapping[int, bool] | Sequence[bool]) -> None:
        """Take thrusters out of the allocation (a tripped drive, local control, an emergency stop) or put
        them back: {id: bool} or one bool per thruster. An unavailable thruster is commanded zero thrust and
        the others share τ."""
        L = self.layout
        L.available = L.availability(available)
        self.pinv = L.weighted_pinv()

    def allocate(self, tau_demand: ArrayLike, previous: ThrusterCommand | None = None) -> AllocationResult:
        t0 = time.perf_counter()
        L = self.layout
        tau = np.array(tau_demand, dtype=float).reshape(3)
        _, prev_angle = L.state(previous)
        if not np.all(np.isfinite(tau)):
            return _hold(L, tau, previous, "invalid_input", "thrust allocation: non-finite τ demand", t0)
        f = self.pinv @ tau
        thrust, angle = _split(L, f, prev_angle, self.idle_thrust)
        # a fixed thruster that cannot reverse is clipped at zero; then all is scaled down to fit as a whole
        clip = (thrust < 0) & (L.tmin == 0)
        thrust = np.where(clip, 0.0, thrust)
        usage = np.where(thrust >= 0, thrust / L.tmax, thrust / np.minimum(L.tmin, -1e-300))
        k = 1.0 / max(1.0, float(usage.max()))
        alarms: tuple[str, ...] = ()
        status = "scaled" if k < 1.0 or clip.any() else "optimal"
        thrust = thrust * k
        tau_alloc = L.tau_of(thrust, angle)
        slack = tau - tau_alloc
        saturated = bool(np.max(np.abs(slack) / L.tau_ref) > _SAT_TOL)
        if saturated:
            alarms = (_saturation_alarm(tau, slack),)
        return AllocationResult(
            thrust, angle, tau_alloc, tau, slack, saturated, alarms, time.perf_counter() - t0, status
        )


def _split(L: _Layout, f: Array, prev_angle: Array, idle: Array) -> tuple[Array, Array]:
    """Extended fixed-frame forces → (thrust, azimuth); idle azimuths keep ``prev_angle``."""
    thrust = np.zeros(L.n)
    angle = prev_angle.copy()
    for i in range(L.n):
        k = L.first[i]
        if L.is_az[i]:
            fx, fy = f[k], f[k + 1]
            thrust[i] = math.hypot(fx, fy)
            if thrust[i] >= idle[i]:
                angle[i] = math.atan2(fy, fx)
            else:  # keep the angle; the thrust is the part of f along it
                thrust[i] = max(0.0, fx * math.cos(angle[i]) + fy * math.sin(angle[i]))
        else:
            thrust[i] = f[k]
            angle[i] = L.fixed_angle[i]
    return thrust, ssa(angle)


def _saturation_alarm(tau: Array, slack: Array) -> str:
    return (
        "thrust allocation saturated: demand τ = [{:.4g} N, {:.4g} N, {:.4g} N·m] not achievable, "
        "shortfall [{:.4g} N, {:.4g} N, {:.4g} N·m]".format(*tau, *slack)
    )


def _hold(
    L: _Layout, tau: Array, previous: ThrusterCommand | None, status: str, alarm: str, t0: float
) -> AllocationResult:
    """Keep the previous command (it satisfies every rate limit); used when no new one can be computed."""
    thrust, angle = L.state(previous)
    tau_alloc = L.tau_of(thrust, angle)
    slack = np.where(np.isfinite(tau), tau - tau_alloc, 0.0)
    return AllocationResult(
        thrust, angle, tau_alloc, tau, slack, True, (alarm,), time.perf_counter() - t0, status
    )


# --------------------------------------------------------------------------------------------------------
# Constrained QP


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class StepLimits:
    """What each thruster can deliver in the coming step, around its previous state (layout order).

    Azimuths: ``angle`` is the previous azimuth; the new force direction must lie in
    [angle − arc_lo, angle + arc_hi] (``cone`` True; arc_lo + arc_hi ≤ π so the sector is convex) or is
    free (``cone`` False); |F| ≤ ``radius`` (N) through the inscribed polygon; the component along
    ``angle`` ≥ ``along_min`` (N, −inf for none) and, at a price (thrust biasing), ≥ ``bias_floor`` (N,
    −inf for none); ``blocked`` (previous azimuth inside a forbidden sector):
    F = 0. Tunnels and main propellers: ``lower`` ≤ u ≤ ``upper`` (N, signed). ``thrust`` is the previous
    thrust. Fields that belong to the other kind of thruster are not used.
    """

    angle: Array
    thrust: Array
    arc_lo: Array
    arc_hi: Array
    cone: BoolArray
    radius: Array
    along_min: Array
    bias_floor: Array
    blocked: BoolArray
    lower: Array
    upper: Array


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class QPData:
    """The QP of one step in scaled variables x = [f̂ (rotated frame), ŝ⁺ (3), ŝ⁻ (3), e (one per azimuth)]::

        min ½ xᵀPx + qᵀx   s.t.   lb ≤ x ≤ ub,   A[:n_eq] x = b_eq,   A[n_eq:] x ≤ ub_A

    ``A`` rows: the n_eq = 3 equality rows B̂ f̂ + ŝ⁺ − ŝ⁻ = τ̂, then per azimuth its polygon rows and two
    cone rows and its bias-floor row −â − e ≤ −floor (unused: ub_A = inf; ub_A[:n_eq] is unused).
    Absent bounds are ±inf. Used by the solver here and by the solver comparison in ``bench/``.
    """

    P: Array
    q: Array
    A: Array
    b_eq: Array
    ub_A: Array
    lb: Array
    ub: Array
    n_eq: int


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class QPSolution:
    """Optimum of the QP: ``forces`` in the fixed frame of eq (22) (N; F_x, F_y per azimuth, u per fixed
    thruster, layout order), ``slack`` = τ − B·forces (N, N, N·m), ``objective`` in scaled units,
    ``status`` ``"optimal"`` or ``"solver_failed: exitflag n"``."""

    forces: Array
    slack: Array
    objective: float
    status: str
    iterations: int


class QPAllocator:
    """Constrained thrust allocation, one convex QP per step (module docstring; ``docs/allocation.md``).

    Parameters (physical units; weights are relative, the problem is scaled so units do not matter):

    ``dt`` (s) — the allocation period; the rate limits allow what the thrusters can do in ``dt``.
    ``weights`` — per thruster ({id: w} or layout order), relative cost of its scaled force |F/T_max|².
    ``power_weight`` — p, weight of the power proxy Σ wᵢ |F/T_max|².
    ``turn_weight`` — c, weight of an azimuth's turn: of (force across its current direction / its present
    thrust)², the angle turned in rad², the thrust floored at ``turn_thrust_floor`` × T_max.
    ``bias_fraction`` — β: with two or more azimuths in service, each is to keep this fraction of its
    T_max along its present direction (thrust biasing; 0: none), a soft floor â + e ≥ β with the
    shortfall e ≥ 0 priced ``bias_l1_weight`` · e + ½ ``bias_weight`` · e² (scaled units): above the
    power and turn costs' gradients, so that it holds when it can, and 10⁴ times below the slack's ρ₁, so
    that τ always wins over it.
    ``slack_weight`` — ρ₂ (one value or [X, Y, N]), quadratic weight of the scaled slack s/τ_ref.
    ``slack_l1_weight`` — ρ₁, the exact (ℓ₁) penalty weight; default ρ₂/10 (above the multipliers the
    turn cost can make, so that a feasible demand is met exactly).
    ``forbidden_sectors`` — {azimuth id: [(start_rad, end_rad), …]}: force directions (the same convention
    as the output azimuth) that must not be used, from start clockwise to end. None (default): the
    vessel's own (`Thruster.forbidden_sectors_deg`); given, it replaces them.
    ``thrust_rate`` — {id: N/s} maximum thrust change rate; default T_max / thrust_time_constant_s.
    ``polygon_sides`` — sides of the regular polygon inscribed in |F| ≤ T_max.
    ``idle_thrust_fraction`` — an azimuth below this fraction of its T_max is idle: its angle does not
    follow the (noisy) direction of its tiny force.
    ``idle_steering`` — idle azimuths turn (at their rate limit) towards the direction the unconstrained
    allocation wants them in, so a thruster that points the wrong way is not stuck there.
    ``solver`` — ``"compiled"`` (default): the whole step in one compiled call
    (`gateway.control._allocation_kernel`: the same limits, QP and commands, solved by a Goldfarb–Idnani
    dual active-set method), falling back to DAQP for a step it cannot solve; ``"daqp"``: the readable
    Python path around DAQP, the reference the compiled step is tested against.
    """

    def __init__(
        self,
        vessel: VesselModel,
        *,
        dt: float = 0.1,
        weights: Mapping[int, float] | Sequence[float] | None = None,
        power_weight: float = 1.0,
        turn_weight: float = 100.0,
        turn_thrust_floor: float = 0.1,
        bias_fraction: float = 0.1,
        bias_weight: float = 1e3,
        bias_l1_weight: float = 10.0,
        slack_weight: float | Sequence[float] = 1e6,
        slack_l1_weight: float | Sequence[float] | None = None,
        forbidden_sectors: Mapping[int, Sequence[tuple[float, float]]] | None = None,
        thrust_rate: Mapping[int, float] | None = None,
        polygon_sides: int = 16,
        idle_thrust_fraction: float = 1e-3,
        idle_steering: bool = True,
        solver: str = "compiled",
    ) -> None:
        if solver not in ("compiled", "daqp"):
            raise ValueError(f"solver must be 'compiled' or 'daqp', got {solver!r}")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        if polygon_sides < 6:
            raise ValueError(f"polygon_sides must be at least 6, got {polygon_sides}")
        if not (power_weight > 0 and turn_weight >= 0):
            raise ValueError("power_weight must be positive and turn_weight non-negative")
        if not (0 < turn_thrust_floor <= 1 and 0 <= bias_fraction < 1):
            raise ValueError("turn_thrust_floor must be in (0, 1] and bias_fraction in [0, 1)")
        self.layout = L = _Layout(vessel, weights)
        self.dt = float(dt)
        self.power_weight = float(power_weight)
        self.turn_weight = float(turn_weight)
        self.turn_thrust_floor = float(turn_thrust_floor)
        self.bias_fraction = float(bias_fraction)
        self.bias_weight, self.bias_l1_weight = float(bias_weight), float(bias_l1_weight)
        if not (self.bias_weight > 0 and self.bias_l1_weight >= 0):
            raise ValueError("bias_weight must be positive and bias_l1_weight non-negative")
        self.rho2 = np.broadcast_to(np.asarray(slack_weight, dtype=float), (3,)).copy()
        rho1 = 0.1 * self.rho2 if slack_l1_weight is None else slack_l1_weight
        self.rho1 = np.broadcast_to(np.asarray(rho1, dtype=float), (3,)).copy()
        if not (np.all(self.rho2 > 0) and np.all(self.rho1 >= 0)):
            raise ValueError("slack_weight must be positive and slack_l1_weight non-negative")
        self.polygon_sides = int(polygon_sides)
        self.idle_thrust = float(idle_thrust_fraction) * L.cap
        self.idle_steering = bool(idle_steering)
        if forbidden_sectors is None:  # the barred zones of the vessel's layout
            forbidden_sectors = {
                t.id: [(math.radians(a), math.radians(b)) for a, b in t.forbidden_sectors_deg]
                for t in vessel.thrusters
                if t.forbidden_sectors_deg
            }
        self.forbidden = _forbidden(forbidden_sectors, L)
        default_rate = np.where(L.time_constant > 0, L.cap / np.maximum(L.time_constant, 1e-300), np.inf)
        rate = _per_thruster(thrust_rate, L.ids, "thrust_rate", default=math.nan)
        self.thrust_rate = np.where(np.isnan(rate), default_rate, rate)
        if not np.all(self.thrust_rate > 0):
            raise ValueError("thrust_rate must be positive")
        self._dT = self.thrust_rate * self.dt  # N per step
        # The longest a shortfall from the rate limits alone can last: a thruster's thrust across its whole
        # range, an azimuth's half turn (`_shortfall_alarms`).
        turns = L.is_az & (L.rate > 0)  # (an azimuth that cannot turn has no turn to wait for)
        half_turn = np.zeros(L.n)
        half_turn[turns] = math.pi / L.rate[turns]
        ramp = np.concatenate([(L.tmax_rated - L.tmin_rated) / self.thrust_rate, half_turn])
        ramp = ramp[np.isfinite(ramp)]
        self.ramp_s = float(ramp.max()) if ramp.size else 0.0
        """The longest ramp of the layout (s): a shortfall that the rate limits explain is no alarm for as
        long, then it is one."""
        self._ramping_s = 0.0  # how long the present rate-limited shortfall has lasted (s)
        self._turn = np.where(L.is_az, L.rate * self.dt, 0.0)  # rad per step
        # the arc of directions reachable in one step when no forbidden sector is near
        self._blocked0 = np.zeros(L.n, dtype=bool)
        self._arc_lo0, self._arc_hi0, self._cone0 = _convex_arc(self._turn, self._turn, L.is_az)
        for arr in (self._blocked0, self._arc_lo0, self._arc_hi0, self._cone0):
            arr.setflags(write=False)
        # unconstrained direction each azimuth would take (idle steering): same weights, no limits
        self._pinv = L.weighted_pinv()
        self._build_structure()
        self._model: Any = None  # DAQP workspace, set up on the first solve and updated after
        self.solver = solver
        self.fallbacks = 0  # steps where the compiled solver gave up and DAQP solved (diagnostic)
        self._kernel_args = self._build_kernel_args() if solver == "compiled" else ()

    @property
    def available(self) -> Array:
        """Which thrusters the allocation may use (layout order; all, unless `set_available` said not)."""
        return self.layout.available.copy()

    def set_available(self, available: Mapping[int, bool] | Sequence[bool]) -> None:
        """Take thrusters out of the allocation (a tripped drive, local control, an emergency stop) or put
        them back: {id: bool} or one bool per thruster, from the next step on.

        An unavailable thruster's thrust limits become [0, 0]: its previous thrust is read as zero (a tripped
        drive delivers nothing, so the others' rate limits start from what is really there), it is
        commanded zero, and the QP shares τ among the others, each within its own rate limits. Back in
        service it starts from zero and ramps up at its thrust rate. Its azimuth is left where it was
        (no idle steering: a dead drive does not turn, and one in local control is not ours to turn).
        The scaling (τ_ref, the force scales) keeps the rated figures, so the weights do not change."""
        L = self.layout
        L.available = L.availability(available)
        # in place: the compiled step holds these arrays
        L.tmax[:] = np.where(L.available, L.tmax_rated, 0.0)
        L.tmin[:] = np.where(L.available, L.tmin_rated, 0.0)
        self._pinv[:] = L.weighted_pinv()

    # ---- problem structure (constant) ------------------------------------------------------------------

    def _build_structure(self) -> None:
        L = self.layout
        N = self.polygon_sides
        self._az = np.flatnonzero(L.is_az)
        self._fixed = np.flatnonzero(~L.is_az)
        self._ka = L.first[self._az]  # variable â (along) of each azimuth; b̂ (across) is the next one
        self._kf = L.first[self._fixed]
        n_az = len(self._az)
        self.n_x = L.n_ext + 6 + n_az  # forces, ŝ⁺, ŝ⁻, the azimuths' bias shortfalls e
        self.n_rows = 3 + n_az * (N + 3)  # τ; per azimuth: polygon, two cone edges, the bias floor
        P = np.zeros(self.n_x)
        P[L.first] = self.power_weight * L.weights
        P[self._ka + 1] = self.power_weight * L.weights[self._az]
        P[L.n_ext : L.n_ext + 6] = np.r_[self.rho2, self.rho2]
        P[L.n_ext + 6 :] = self.bias_weight
        self._P_diag = P  # without the turn cost, which depends on the present thrust (`_p_diag`)
        self._turn_cw = self.turn_weight * L.weights[self._az]
        self.q = np.r_[np.zeros(L.n_ext), self.rho1, self.rho1, np.full(n_az, self.bias_l1_weight)]
        # polygon: vertex k at 2πk/N from the previous azimuth, face normals half-way between vertices
        theta = TWO_PI * (np.arange(N) + 0.5) / N
        self._poly_scale = math.cos(math.pi / N)
        A = np.zeros((self.n_rows, self.n_x))
        A[0:3, L.n_ext : L.n_ext + 6] = np.c_[np.eye(3), -np.eye(3)]
        for j, k in enumerate(self._ka):
            r0 = 3 + j * (N + 3)
            A[r0 : r0 + N, k] = np.cos(theta)
            A[r0 : r0 + N, k + 1] = np.sin(theta)
            A[r0 + N + 2, k] = A[r0 + N + 2, L.n_ext + 6 + j] = -1.0  # −â − e ≤ −floor (bound per step)
        A[0:3, self._kf] = L.B[:, self._kf] * L.cap[self._fixed] / L.tau_ref[:, None]
        self._A = A
        self._ubA0 = np.full(self.n_rows, np.inf)
        self._az_list = self._az.tolist()
        self._ka_list = self._ka.tolist()
        self._cap_list, self._x_list, self._y_list = L.cap.tolist(), L.x.tolist(), L.y.tolist()
        self._idle_list, self._turn_list = self.idle_thrust.tolist(), self._turn.tolist()
        self._lb0 = np.r_[np.full(L.n_ext, -np.inf), np.zeros(6 + n_az)]
        self._ub0 = np.full(self.n_x, np.inf)
        self._blower_rows = np.full(self.n_rows - 3, -np.inf)
        self._rest_thrust = np.zeros(L.n)

    def _build_kernel_args(self) -> tuple[Any, ...]:
        """Constant arrays and work arrays of the compiled step (`_allocation_kernel.allocate_step`)."""
        L = self.layout
        k_max = max((len(v) for v in self.forbidden.values()), default=0)
        sec_start = np.zeros((L.n, max(k_max, 1)))
        sec_width = np.zeros((L.n, max(k_max, 1)))
        sec_count = np.zeros(L.n, dtype=np.int64)
        for i, sectors in self.forbidden.items():
            for k, (start, width) in enumerate(sectors):
                sec_start[i, k], sec_width[i, k] = start, width
            sec_count[i] = len(sectors)
        n_x, n_rows = self.n_x, self.n_rows
        m_max = n_rows + 2 * n_x
        turn_cw = np.zeros(L.n)
        turn_cw[self._az] = self._turn_cw
        self._k_out = (np.empty(L.n), np.empty(L.n), np.empty(3), np.zeros(4))
        self._k_x = np.empty(n_x)
        f = np.ascontiguousarray
        return (
            L.is_az,
            L.first.astype(np.int64),
            L.x,
            L.y,
            L.cap,
            L.tmin,
            L.tmax,
            L.fixed_angle,
            L.tau_ref,
            f(self._dT, dtype=float),
            f(self._turn, dtype=float),
            f(self.idle_thrust, dtype=float),
            f(self._arc_lo0, dtype=float),
            f(self._arc_hi0, dtype=float),
            sec_start,
            sec_width,
            sec_count,
            bool(self.forbidden),
            f(self._pinv),
            self.idle_steering,
            turn_cw,
            self.turn_thrust_floor,
            self.bias_fraction,
            self._P_diag,
            self.q,
            self._A,
            self._poly_scale,
            self.polygon_sides,
            np.empty(n_x),  # work: the step's Hessian diagonal, A, ub_A, lb, ub
            np.empty((n_rows, n_x)),
            np.empty(n_rows),
            np.empty(n_x),
            np.empty(n_x),
            np.empty((m_max, 2), dtype=np.int64),  # work: inequality rows (two nonzeros each)
            np.empty((m_max, 2)),
            np.empty(m_max),
            self._k_x,  # work: solution, active set, multipliers, J, R, d, z, r
            np.empty(n_x, dtype=np.int64),
            np.empty(n_x),
            np.empty((n_x, n_x)),
            np.empty((n_x, n_x)),
            np.empty(n_x),
            np.empty(n_x),
            np.empty(n_x),
            *self._k_out,
        )

    # ---- the step's limits -----------------------------------------------------------------------------

    def limits(self, previous: ThrusterCommand | None) -> StepLimits:
        """The convex limits of one step around ``previous`` (None: every thruster at rest at its
        configured ``angle_rad``)."""
        L = self.layout
        thrust, angle = L.state(previous)
        if self.forbidden:
            arc_lo, arc_hi = self._turn.copy(), self._turn.copy()
            blocked = np.zeros(L.n, dtype=bool)
            for i, sectors in self.forbidden.items():
                a = float(angle[i])
                for start, width in sectors:
                    p = (a - start) % TWO_PI  # how far clockwise of the sector's start
                    if _ANGLE_EPS < p < width - _ANGLE_EPS:
                        blocked[i] = True
                        continue
                    ahead = (start - a) % TWO_PI  # clockwise distance to the sector
                    behind = (a - start - width) % TWO_PI  # anticlockwise distance to its end
                    arc_hi[i] = min(arc_hi[i], 0.0 if ahead > TWO_PI - _ANGLE_EPS else ahead)
                    arc_lo[i] = min(arc_lo[i], 0.0 if behind > TWO_PI - _ANGLE_EPS else behind)
            arc_lo, arc_hi, cone = _convex_arc(arc_lo, arc_hi, L.is_az & ~blocked)
            along_ok = ~blocked  # in a forbidden sector, the sector wins over the thrust rate
        else:
            arc_lo, arc_hi, cone, blocked = self._arc_lo0, self._arc_hi0, self._cone0, self._blocked0
            along_ok = L.is_az
        down, up = thrust - self._dT, thrust + self._dT
        upper = np.minimum(L.tmax, up)
        along_min = np.where(along_ok & (down > 0), down, -np.inf)
        bias_floor = np.full(L.n, -np.inf)
        if self.bias_fraction > 0 and np.count_nonzero(L.is_az & (L.tmax > 0)) >= 2:
            # thrust biasing: β·T_max along the present direction (up to what this step can reach there,
            # so it ramps up at the thrust rate from below), a soft floor: see `_qp`
            biased = L.is_az & ~blocked
            bias_floor[biased] = np.minimum(self.bias_fraction * L.tmax, upper)[biased]
        return StepLimits(
            angle=angle,
            thrust=thrust,
            arc_lo=arc_lo,
            arc_hi=arc_hi,
            cone=cone,
            radius=upper,
            along_min=along_min,
            bias_floor=bias_floor,
            blocked=blocked,
            lower=np.maximum(L.tmin, down),
            upper=upper,
        )

    def qp_data(self, tau_demand: ArrayLike, previous: ThrusterCommand | None) -> QPData:
        """The scaled QP of one step (see `QPData`)."""
        return self._qp(np.array(tau_demand, dtype=float).reshape(3), self.limits(previous))

    def _qp(self, tau: Array, lim: StepLimits) -> QPData:
        # a loop over the azimuths with scalar maths: for a handful of thrusters this is several times
        # faster than numpy's per-call overhead on arrays of three
        L = self.layout
        N = self.polygon_sides
        A = self._A.copy()
        ub_A = self._ubA0.copy()
        lb, ub = self._lb0.copy(), self._ub0.copy()
        sx, sy, sn = (float(v) for v in 1.0 / L.tau_ref)
        angle, radius, along_min = lim.angle.tolist(), lim.radius.tolist(), lim.along_min.tolist()
        bias_floor = lim.bias_floor.tolist()
        arc_lo, arc_hi, cone, blocked = lim.arc_lo.tolist(), lim.arc_hi.tolist(), lim.cone, lim.blocked
        for j, i in enumerate(self._az_list):
            k = self._ka_list[j]
            cap, x, y = self._cap_list[i], self._x_list[i], self._y_list[i]
            c, s = math.cos(angle[i]), math.sin(angle[i])
            # B̂ in the rotated frame: â along the previous azimuth, b̂ 90° clockwise of it
            A[0, k], A[1, k], A[2, k] = c * cap * sx, s * cap * sy, (x * s - y * c) * cap * sn
            A[0, k + 1], A[1, k + 1], A[2, k + 1] = -s * cap * sx, c * cap * sy, (x * c + y * s) * cap * sn
            rad = radius[i] / cap
            r0 = 3 + j * (N + 3)
            ub_A[r0 : r0 + N] = rad * self._poly_scale
            if bias_floor[i] > -math.inf:  # â + e ≥ floor, e ≥ 0 priced: the soft bias floor
                ub_A[r0 + N + 2] = -bias_floor[i] / cap
            if blocked[i]:
                lb[k] = ub[k] = lb[k + 1] = ub[k + 1] = 0.0
                continue
            lb[k], ub[k] = max(along_min[i] / cap, -rad), rad
            lb[k + 1], ub[k + 1] = -rad, rad
            if cone[i]:  # two half-planes through the origin; at exactly π both edges are one line
                lo, hi = arc_lo[i], arc_hi[i]
                A[r0 + N, k], A[r0 + N, k + 1] = -math.sin(hi), math.cos(hi)
                ub_A[r0 + N] = 0.0
                if lo + hi < math.pi - 1e-9:
                    A[r0 + N + 1, k], A[r0 + N + 1, k + 1] = -math.sin(lo), -math.cos(lo)
                    ub_A[r0 + N + 1] = 0.0
        kf, fixed = self._kf, self._fixed
        lb[kf] = lim.lower[fixed] / L.cap[fixed]
        ub[kf] = lim.upper[fixed] / L.cap[fixed]
        return QPData(np.diag(self._p_diag(lim)), self.q, A, tau / L.tau_ref, ub_A, lb, ub, 3)

    def _p_diag(self, lim: StepLimits) -> Array:
        """The Hessian's diagonal for this step: the power proxy, the slack weights and the turn cost
        c·wᵢ / max(T̂₀,ᵢ, θ)² on each azimuth's across component b̂ (b̂ / T̂₀ is the angle turned)."""
        P = self._P_diag.copy()
        az = self._az
        t0 = np.maximum(lim.thrust[az] / self.layout.cap[az], self.turn_thrust_floor)
        P[self._ka + 1] += self._turn_cw / (t0 * t0)
        return P

    # ---- solve -----------------------------------------------------------------------------------------

    def solve_qp(self, tau_demand: ArrayLike, previous: ThrusterCommand | None) -> QPSolution:
        """Solve the QP of one step (no post-processing: see `allocate`) with this allocator's solver
        (the compiled one falls back to DAQP where it gives up, as `allocate` does)."""
        tau, lim = np.array(tau_demand, dtype=float).reshape(3), self.limits(previous)
        if self.solver == "compiled":
            d = self._qp(tau, lim)
            x, status, iterations = _kernel.solve_qp_data(
                np.ascontiguousarray(np.diag(d.P)), d.q, d.A, d.b_eq, d.ub_A, d.lb, d.ub, 3
            )
            if status == _kernel.OK:
                return self._solution(x, lim, d, iterations)
            self.fallbacks += 1
        return self._solve(tau, lim)

    def _solve(self, tau: Array, lim: StepLimits) -> QPSolution:
        L = self.layout
        d = self._qp(tau, lim)
        bupper = np.concatenate((d.ub, d.b_eq, d.ub_A[3:]))
        blower = np.concatenate((d.lb, d.b_eq, self._blower_rows))
        if self._model is None:
            sense = np.zeros(self.n_x + self.n_rows, dtype=np.int32)
            sense[self.n_x : self.n_x + 3] = 5  # equality rows
            self._model = daqp.Model()
            self._model.setup(d.P, d.q, d.A, bupper, blower, sense)
            # feasibility to 1e-9, not DAQP's 1e-6: the bias shortfall's linear price would otherwise buy
            # a violation of a cone edge by 1e-6 (the compiled solver is exact there)
            self._model.settings = {**self._model.settings, "primal_tol": 1e-9}
        else:  # same structure: new values, the previous active set is the warm start
            self._model.update(H=d.P, A=d.A, bupper=bupper, blower=blower)
        x, _fval, exitflag, info = self._model.solve()
        if exitflag < 1 or not np.all(np.isfinite(x)):
            self._model = None  # start afresh next time
            return QPSolution(
                np.zeros(L.n_ext), tau.copy(), math.nan, f"solver_failed: exitflag {exitflag}", 0
            )
        return self._solution(np.asarray(x, dtype=float), lim, d, int(info["iterations"]))

    def _solution(self, x: Array, lim: StepLimits, d: QPData, iterations: int) -> QPSolution:
        """The QP's scaled solution x as forces in the fixed frame of eq (22), slack (N) and objective."""
        L = self.layout
        ka, kf = self._ka, self._kf
        ang = lim.angle[self._az]
        c, s = np.cos(ang), np.sin(ang)
        a, b = x[ka] * L.cap[self._az], x[ka + 1] * L.cap[self._az]
        forces = np.empty(L.n_ext)
        forces[ka], forces[ka + 1] = a * c - b * s, a * s + b * c
        forces[kf] = x[kf] * L.cap[self._fixed]
        slack = (x[L.n_ext : L.n_ext + 3] - x[L.n_ext + 3 : L.n_ext + 6]) * L.tau_ref
        objective = float(0.5 * np.dot(np.diag(d.P) * x, x) + np.dot(d.q, x))
        return QPSolution(forces, slack, objective, "optimal", iterations)

    def allocate(self, tau_demand: ArrayLike, previous: ThrusterCommand | None = None) -> AllocationResult:
        """Thrust and azimuth per thruster for the demand ``tau_demand`` = [X, Y, N] (N, N, N·m) given the
        current state ``previous`` (the last command or the thrusters' feedback; None: at rest)."""
        t0 = time.perf_counter()
        L = self.layout
        tau = np.array(tau_demand, dtype=float).reshape(3)
        x, y, n = tau.tolist()  # three floats: cheaper than numpy's isfinite and all on an array of three
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(n)):
            return _hold(L, tau, previous, "invalid_input", "thrust allocation: non-finite τ demand", t0)
        # a demand far beyond capacity is solved as the same direction at DEMAND_CLIP × τ_ref (the result
        # and its shortfall still name the demand as given): in scaled units of 10⁸ and more the slack's
        # weight swamps the QP's other terms and the solvers fail
        tau_qp = tau
        over = max(abs(x) / L.tau_ref[0], abs(y) / L.tau_ref[1], abs(n) / L.tau_ref[2])
        if over > DEMAND_CLIP:
            tau_qp = tau * (DEMAND_CLIP / over)
        if self._kernel_args:
            res = self._allocate_compiled(tau_qp, previous, t0, tau)
            if res is not None:
                return res
            self.fallbacks += 1  # the compiled solver gave up on this QP: DAQP solves it
        lim = self.limits(previous)
        sol = self._solve(tau_qp, lim)
        if sol.status != "optimal":
            return _hold(L, tau, previous, sol.status, f"thrust allocation: QP {sol.status}", t0)
        thrust, angle = self._commands(tau_qp, sol.forces, lim)
        tau_alloc = L.tau_of(thrust, angle)
        slack = tau - tau_alloc
        saturated = tau_qp is not tau or bool(np.max(np.abs(sol.slack) / L.tau_ref) > _SAT_TOL)
        alarms = self._shortfall_alarms(tau, saturated and tau_qp is tau, saturated, slack)
        return AllocationResult(
            thrust, angle, tau_alloc, tau, slack, saturated, alarms, time.perf_counter() - t0, "optimal"
        )

    def _allocate_compiled(
        self, tau_qp: Array, previous: ThrusterCommand | None, t0: float, tau: Array
    ) -> AllocationResult | None:
        """`allocate` in one compiled call for the demand ``tau_qp`` (``tau`` as given, for the result);
        None if its solver gave up (the caller then uses DAQP)."""
        L = self.layout
        if previous is None:
            prev_thrust, prev_angle = self._rest_thrust, L.fixed_angle
        else:
            prev_thrust = np.asarray(previous.thrust, dtype=float).reshape(L.n)
            prev_angle = np.asarray(previous.azimuth, dtype=float).reshape(L.n)
        if _kernel.allocate_step(tau_qp, prev_thrust, prev_angle, *self._kernel_args) != _kernel.OK:
            return None
        thrust_o, angle_o, tau_o, info = self._k_out
        thrust, angle, tau_alloc = thrust_o.copy(), angle_o.copy(), tau_o.copy()
        slack = tau - tau_alloc
        saturated = tau_qp is not tau or bool(info[3] > _SAT_TOL)
        alarms = self._shortfall_alarms(tau, saturated and tau_qp is tau, saturated, slack)
        return AllocationResult(
            thrust, angle, tau_alloc, tau, slack, saturated, alarms, time.perf_counter() - t0, "optimal"
        )

    def _shortfall_alarms(
        self, tau: Array, maybe_ramping: bool, saturated: bool, slack: Array
    ) -> tuple[str, ...]:
        """The alarm of a step that did not meet the demand: none while the thrusters are only ramping to
        it. A demand the thrusters in service can give at rest (`reachable`: a zero demand always) that one
        step does not meet is their rate limits at work: the thrust moving at its thrust rate, an azimuth
        turning, as on entering manual (τ to zero) or after a setpoint step. That is no alarm for as long
        as a ramp of the layout can take (`ramp_s`); a shortfall that lasts longer, or a demand beyond what
        the thrusters can give, is saturation, alarmed at once. ``saturated`` stays as it is either way
        (the controller's anti-windup must know the demand was not met)."""
        if not saturated:
            self._ramping_s = 0.0
            return ()
        if maybe_ramping and self.reachable(tau):
            self._ramping_s += self.dt
            if self._ramping_s <= self.ramp_s + self.dt:
                return ()
        else:
            self._ramping_s = 0.0
        return (_saturation_alarm(tau, slack),)

    def reachable(self, tau: ArrayLike) -> bool:
        """Whether the thrusters in service can give ``tau`` at rest, rate limits aside: its weighted
        pseudo-inverse allocation within every thruster's thrust limits (a sufficient test, not a
        necessary one: a demand it finds out of reach may still be reachable by another share, and is then
        alarmed as saturation; forbidden sectors are not looked at, the ramp's time bound catches them)."""
        L = self.layout
        f = self._pinv @ np.asarray(tau, dtype=float).reshape(3)
        thrust = np.empty(L.n)
        for i in range(L.n):
            k = L.first[i]
            thrust[i] = math.hypot(f[k], f[k + 1]) if L.is_az[i] else f[k]
        margin = 1e-6 * L.cap
        return bool(np.all(thrust <= L.tmax + margin) and np.all(thrust >= L.tmin - margin))

    def _commands(self, tau: Array, forces: Array, lim: StepLimits) -> tuple[Array, Array]:
        """QP forces → (thrust, azimuth). The angle is kept inside the step's allowed arc (solver
        round-off); an idle azimuth (force below the idle threshold) does not follow its force's direction:
        it holds its angle, or with idle steering turns at its rate limit towards the direction the
        unconstrained allocation wants; its thrust is the part of the force along the commanded angle."""
        L = self.layout
        thrust = np.minimum(np.maximum(forces[L.first], lim.lower), lim.upper)  # fixed thrusters
        angle = L.fixed_angle.copy()
        f = forces.tolist()
        prev_angle, radius = lim.angle.tolist(), lim.radius.tolist()
        preferred: list[float] | None = None
        for j, i in enumerate(self._az_list):
            k = self._ka_list[j]
            fx, fy, prev = f[k], f[k + 1], prev_angle[i]
            mag = math.hypot(fx, fy)
            if mag >= self._idle_list[i] and not lim.blocked[i]:
                c, s = math.cos(prev), math.sin(prev)
                rel = math.atan2(fy * c - fx * s, fx * c + fy * s)  # direction relative to prev
                if lim.cone[i]:
                    rel = min(max(rel, -float(lim.arc_lo[i])), float(lim.arc_hi[i]))
                angle[i], thrust[i] = prev + rel, min(mag, radius[i])
                continue
            new, off = prev, bool(lim.blocked[i])  # off: no thrust (in a forbidden sector)
            if self.idle_steering:
                if preferred is None:
                    preferred = (self._pinv @ tau).tolist()
                px, py = preferred[k], preferred[k + 1]
                if math.hypot(px, py) >= self._idle_list[i]:
                    target = self._outside_sectors(i, math.atan2(py, px))
                    step = self._turn_list[i]
                    new = prev + min(max(ssa_scalar(target - prev), -step), step)
                    off = off or self._in_sector(i, new)  # turning through a sector at zero thrust
            # the part of the force along the commanded angle, kept within the thrust-rate limits
            along = max(fx * math.cos(new) + fy * math.sin(new), float(lim.along_min[i]), 0.0)
            angle[i], thrust[i] = new, 0.0 if off else min(along, radius[i])
        return thrust, ssa(angle)

    def _in_sector(self, i: int, angle: float) -> bool:
        """Whether ``angle`` is strictly inside a forbidden sector of thruster i."""
        for start, width in self.forbidden.get(i, ()):
            if _ANGLE_EPS < (angle - start) % TWO_PI < width - _ANGLE_EPS:
                return True
        return False

    def _outside_sectors(self, i: int, target: float) -> float:
        """``target`` moved to the nearer edge of a forbidden sector of thruster i that contains it."""
        for start, width in self.forbidden.get(i, ()):
            p = (target - start) % TWO_PI
            if 0.0 < p < width:
                return start if p < width / 2 else start + width
        return target


def _convex_arc(arc_lo: Array, arc_hi: Array, movable: BoolArray) -> tuple[Array, Array, BoolArray]:
    """The allowed directions [−arc_lo, +arc_hi] around the previous azimuth as a convex set: a sector
    of at most π. Wider than π (not convex) it becomes the widest sector of π inside it, centred on the
    previous azimuth where the arc allows; a full turn or more (2π) is no direction limit (``cone``
    False)."""
    total = arc_lo + arc_hi
    cone = movable & (total < TWO_PI)
    wide = total > math.pi
    if wide.any():
        lo = np.minimum(arc_lo, math.pi / 2)
        hi = np.minimum(arc_hi, math.pi - lo)
        lo = np.minimum(arc_lo, math.pi - hi)
        arc_lo, arc_hi = np.where(wide, lo, arc_lo), np.where(wide, hi, arc_hi)
    return np.where(movable, arc_lo, 0.0), np.where(movable, arc_hi, 0.0), cone


def _forbidden(
    sectors: Mapping[int, Sequence[tuple[float, float]]] | None, L: _Layout
) -> dict[int, list[tuple[float, float]]]:
    """{layout index: [(start, width)]} with start in [-π, π) and width in (0, 2π)."""
    out: dict[int, list[tuple[float, float]]] = {}
    for tid, lst in (sectors or {}).items():
        if tid not in L.ids:
            raise ValueError(f"forbidden_sectors: unknown thruster id {tid}; layout has {L.ids}")
        i = L.ids.index(tid)
        if not L.is_az[i]:
            raise ValueError(f"forbidden_sectors: thruster {tid} is not an azimuth")
        for start, end in lst:
            if not (math.isfinite(start) and math.isfinite(end)):
                raise ValueError(f"forbidden_sectors: thruster {tid}: non-finite sector ({start}, {end})")
            width = (end - start) % TWO_PI
            if width <= 0.0:
                raise ValueError(f"forbidden_sectors: thruster {tid}: empty or full sector ({start}, {end})")
            out.setdefault(i, []).append((ssa_scalar(start), width))
    return out


# --------------------------------------------------------------------------------------------------------
# Independent reference formulation (tests and benchmark only: needs cvxpy)


def reference_solve_cvxpy(
    allocator: QPAllocator, tau_demand: ArrayLike, previous: ThrusterCommand | None, **solver_options: Any
) -> QPSolution:
    """The same problem as `QPAllocator`, written independently with cvxpy in the fixed frame of eq (22):
    variables F_x, F_y per azimuth and u per fixed thruster, slack s = τ − B f, each in the problem's
    scaled units (force / T_max, slack / τ_ref; cvxpy and its solver need no help with units then).
    Readable and slow (ms): the reference the QP is tested against. Not used at run time (cvxpy is a
    test and benchmark dependency)."""
    import cvxpy as cp

    A = allocator
    L = A.layout
    lim = A.limits(previous)
    tau = np.array(tau_demand, dtype=float).reshape(3)
    N = A.polygon_sides
    f = cp.Variable(L.n_ext)  # scaled forces, fixed frame
    g = np.sqrt(A.rho2)
    s = cp.Variable(3)  # slack scaled so that its quadratic weight is 1: s = √ρ₂ (τ − B f) / τ_ref
    force_scale = L.cap[L.owner]
    cost: list[Any] = [(A.rho1 / g) @ cp.abs(s), 0.5 * cp.sum_squares(s)]
    cons: list[Any] = [cp.multiply(g / L.tau_ref, (L.B * force_scale) @ f) + s == g * tau / L.tau_ref]
    for i in range(L.n):
        k, w = L.first[i], L.weights[i]
        if not L.is_az[i]:
            cost.append(0.5 * A.power_weight * w * cp.square(f[k]))
            cons += [f[k] * L.cap[i] >= lim.lower[i], f[k] * L.cap[i] <= lim.upper[i]]
            continue
        F = f[k : k + 2]
        a = lim.angle[i]  # previous azimuth
        along = np.array([math.cos(a), math.sin(a)])
        across = np.array([-math.sin(a), math.cos(a)])  # 90° clockwise of it
        cost.append(0.5 * A.power_weight * w * cp.sum_squares(F))
        # the turn: the force across the previous azimuth over the previous thrust (floored), in rad
        t0 = max(lim.thrust[i] / L.cap[i], A.turn_thrust_floor)
        cost.append(0.5 * A.turn_weight * w * cp.square(across @ F / t0))
        if lim.blocked[i]:  # previous azimuth inside a forbidden sector
            cons.append(F == 0)
            continue
        r = lim.radius[i] / L.cap[i]
        for m in range(N):  # regular polygon inscribed in |F| ≤ r, one vertex on the previous azimuth
            normal = a + TWO_PI * (m + 0.5) / N
            cons.append(math.cos(normal) * F[0] + math.sin(normal) * F[1] <= r * math.cos(math.pi / N))
        if lim.cone[i]:  # direction between a − arc_lo and a + arc_hi: cross product with each edge
            e_hi, e_lo = a + lim.arc_hi[i], a - lim.arc_lo[i]
            cons.append(math.cos(e_hi) * F[1] - math.sin(e_hi) * F[0] <= 0)
            cons.append(math.cos(e_lo) * F[1] - math.sin(e_lo) * F[0] >= 0)
        if np.isfinite(lim.along_min[i]):  # thrust-rate limit downwards
            cons.append(along @ F >= lim.along_min[i] / L.cap[i])
        if np.isfinite(lim.bias_floor[i]):  # thrust biasing: a floor along it, its shortfall priced
            e = cp.Variable(nonneg=True)
            cons.append(along @ F + e >= lim.bias_floor[i] / L.cap[i])
            cost += [A.bias_l1_weight * e, 0.5 * A.bias_weight * cp.square(e)]
    prob = cp.Problem(cp.Minimize(cp.sum(cp.hstack(cost))), cons)
    # Clarabel, tight: when saturated the objective is large, so the relative gap alone would stop early;
    # if it cannot certify that, once or twice more with a little more room (feasibility, then the gap)
    attempts: list[dict[str, Any]] = (
        [dict(solver_options)]
        if solver_options
        else [
            {"solver": cp.CLARABEL, "tol_gap_abs": 1e-10, "tol_gap_rel": 1e-13, "tol_feas": 1e-10},
            {"solver": cp.CLARABEL, "tol_gap_abs": 1e-10, "tol_gap_rel": 1e-13, "tol_feas": 1e-9},
            {"solver": cp.CLARABEL, "tol_gap_abs": 1e-9, "tol_gap_rel": 1e-10, "tol_feas": 1e-8},
        ]
    )
    for options in attempts:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "solution may be inaccurate": see the status
            prob.solve(**options)
        if prob.status == cp.OPTIMAL and f.value is not None:
            forces = np.asarray(f.value, dtype=float) * force_scale
            return QPSolution(forces, tau - L.B @ forces, float(prob.value), "optimal", 0)
    return QPSolution(np.zeros(L.n_ext), tau.copy(), math.nan, f"reference: {prob.status}", 0)
