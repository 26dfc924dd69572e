"""Quasi-static thrust capability: how large a multiple of a generalised force the thrusters can hold.

For a load τ = [X, Y, N] (N, N, N·m, body frame at the reference point) the attainable scale is

    k*(τ) = max k   s.t.   B f = k τ,   fᵢ ∈ Fᵢ for every thruster i in service,   k ≥ 0,

with B the extended thrust configuration of `gateway.control.allocation` (Hajivand & Mousavizadegan
2010, eq (22), signs restored: an azimuth contributes a free force (F_x, F_y), a tunnel or main
propeller its signed thrust u along its fixed direction α) and Fᵢ the set of forces thruster i can give:

* tunnel / main: u ∈ [min(min_thrust_n, 0), max_thrust_n] (an interval: exact);
* azimuth: |F| ≤ T_max, the direction outside its forbidden sectors. The disc is replaced by a regular
  polygon with n sides inscribed in it (n = ``polygon_sides``, default 64): every force the polygon
  allows is achievable, and the polygon holds the disc shrunk by cos(π/n), so k* is underestimated by at
  most a factor cos(π/n) (0.12 % for n = 64) — conservative. A barred sector (a wedge) cut out of the
  disc leaves a set that is not convex when the wedge is narrower than 180°; it is split exactly into
  convex pieces: each allowed arc of directions wider than 180° is cut into equal arcs of at most
  180°, and each arc of width w ≤ π gives the convex piece "direction in the arc, inside the polygon
  inscribed in the arc's sector" (chords of at most 2π/n, the same cos(π/n) bound). The force set is
  the union of its pieces, so k* is the largest over every choice of one piece per azimuth of the
  LP with those pieces: exact (up to the polygon), not the optimistic convex hull. The number of LPs is
  the product of the pieces' counts (2 per azimuth with one narrow sector): fine for the handful of
  azimuths of a DP vessel.

k* ≥ 1: τ can be held, with 1/k* the utilisation of the thrust system in the direction of τ;
k* < 1: it cannot, and k* τ is the largest load in that direction that can. k*(c τ) = k*(τ)/c for
c > 0. τ = 0 gives inf. A τ the thrusters cannot push in at all (a tunnel-only layout asked for surge)
gives 0.

This is the load-side half of the DP capability analysis (``docs/capability.md``); the loads come from
``dpgw.capability``. No thrust loss (thruster-hull and thruster-thruster interaction, current inflow) is
modelled beyond the barred sectors: a thruster gives its rated thrust in any allowed direction.

Solved in scaled units (forces / T_max, rows of τ / τ_ref), so the LP is well conditioned for a 2 N model
ship and a 2 MN azimuth alike, by DAQP (the dual active-set solver the allocation already uses; an LP by
its proximal-point iterations) — ~30-100 times faster than HiGHS on these small LPs, which matters to the
online consequence analysis that solves one per failure case inside the control loop
(`bench/bench_capability.py`) — with HiGHS (`scipy.optimize.linprog`, ``solver="highs"``) kept as the
reference the tests compare it with, and as the fallback for an LP DAQP does not report solved. Pure
numerics.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Collection, Sequence
from ctypes import c_int
from dataclasses import dataclass

import daqp
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linprog

from gateway.control.allocation import thruster_configuration_matrix
from observers.vessel import Thruster

Array = NDArray[np.float64]

DEFAULT_POLYGON_SIDES = 64
"""Sides of the polygon inscribed in each azimuth's thrust disc: k* at most cos(π/64) ≈ 0.9988 low."""

TWO_PI = 2.0 * math.pi

SOLVERS = ("daqp", "highs")
"""The LP solvers: DAQP (the default, fast), HiGHS (the reference, and DAQP's fallback)."""

_BIG = 1e30  # (DAQP's "no bound")
_IMMUTABLE = 5  # DAQP constraint sense: ACTIVE + IMMUTABLE, an equality

__all__ = [
    "DEFAULT_POLYGON_SIDES",
    "SOLVERS",
    "CapabilityLP",
    "CapabilitySolution",
    "allowed_arcs",
    "attainable_scale",
]


def attainable_scale(
    thrusters: Sequence[Thruster],
    tau: ArrayLike,
    *,
    failed: Collection[int] = (),
    polygon_sides: int = DEFAULT_POLYGON_SIDES,
    solver: str = "daqp",
) -> float:
    """The largest k >= 0 such that the thrusters (those whose id is not in `failed`) can produce k·tau
    (tau = [X, Y, N] in N, N, N·m, body frame, at the vessel's reference point), within each thruster's
    limits. k >= 1: tau can be held; k < 1: it can not (1/k is the utilisation). inf for tau = 0.

    Conservative by at most a factor cos(π/``polygon_sides``) (module docstring). For many loads on the
    same layout build one `CapabilityLP` and call its `scale`: the constraints are built once."""
    return CapabilityLP(thrusters, failed=failed, polygon_sides=polygon_sides, solver=solver).scale(tau)


DIRECTION_EPS = 1e-6
"""A load's component smaller than this fraction of its largest one is taken as 0 (`CapabilityLP.solve`)."""


@dataclass(frozen=True)
class CapabilitySolution:
    """The optimum of one capability LP: ``scale`` = k*, and the thrusters' forces that give k*·τ
    (layout order of the thrusters passed in; a failed thruster has zero): ``thrust`` (N, ≥ 0 for
    azimuths, signed for fixed units) and ``azimuth`` (rad, force direction clockwise from the bow)."""

    scale: float
    thrust: Array
    azimuth: Array


def allowed_arcs(sectors_deg: Sequence[tuple[float, float]]) -> list[tuple[float, float]] | None:
    """The directions an azimuth may push in, as arcs (start_rad, width_rad) each of width ≤ π (a convex
    wedge), from its forbidden sectors ``(start, end)`` in degrees, each from start clockwise to end.
    None: no sector, every direction allowed; []: every direction barred."""
    if not sectors_deg:
        return None
    # barred intervals on [0, 360), split where they wrap
    barred: list[tuple[float, float]] = []
    for start, end in sectors_deg:
        s = float(start) % 360.0
        w = (float(end) - float(start)) % 360.0
        if w == 0.0:
            continue
        if s + w <= 360.0:
            barred.append((s, s + w))
        else:
            barred += [(s, 360.0), (0.0, s + w - 360.0)]
    barred.sort()
    merged: list[list[float]] = []
    for a, b in barred:
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    if not merged:
        return None
    free: list[tuple[float, float]] = []  # (start, end) in degrees, end may exceed 360 (wrap)
    for (_, b0), (a1, _) in itertools.pairwise(merged):
        if a1 > b0:
            free.append((b0, a1))
    last_end, first_start = merged[-1][1], merged[0][0]
    if last_end - first_start < 360.0:  # the gap across 0°
        free.append((last_end, first_start + 360.0))
    arcs: list[tuple[float, float]] = []
    for a, b in free:
        width = math.radians(b - a)
        pieces = max(1, math.ceil(width / math.pi - 1e-12))
        for j in range(pieces):
            arcs.append((math.radians(a) + j * width / pieces, width / pieces))
    return arcs


def _disc_rows(n: int) -> tuple[Array, Array]:
    """Half-planes of the regular n-gon inscribed in the unit circle, one vertex on direction 0."""
    phi = TWO_PI * (np.arange(n) + 0.5) / n
    return np.column_stack([np.cos(phi), np.sin(phi)]), np.full(n, math.cos(math.pi / n))


def _wedge_rows(start: float, width: float, n: int) -> tuple[Array, Array]:
    """Half-planes of the convex polygon inscribed in the unit-circle sector of directions
    [start, start + width] (width ≤ π): the two radial edges and chords of at most 2π/n."""
    m = max(1, math.ceil(width / (TWO_PI / n) - 1e-12))
    half = width / (2 * m)
    mids = start + half * (2 * np.arange(m) + 1)
    rows = [np.column_stack([np.cos(mids), np.sin(mids)])]
    bounds = [np.full(m, math.cos(half))]
    end = start + width
    # direction ≥ start: cos(start) F_y − sin(start) F_x ≥ 0; direction ≤ end: cos(end) F_y − sin(end) F_x ≤ 0
    rows.append(np.array([[math.sin(start), -math.cos(start)], [-math.sin(end), math.cos(end)]]))
    bounds.append(np.zeros(2))
    return np.vstack(rows), np.concatenate(bounds)


class CapabilityLP:
    """The capability LP of one thruster layout with some thrusters failed, built once, solved for any τ
    (`scale`, `solve`). ``failed``: ids out of service (unknown ids are refused: a typo would otherwise
    silently give the intact figure)."""

    def __init__(
        self,
        thrusters: Sequence[Thruster],
        *,
        failed: Collection[int] = (),
        polygon_sides: int = DEFAULT_POLYGON_SIDES,
        solver: str = "daqp",
    ) -> None:
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        self.solver = solver
        self.fallbacks = 0
        """LPs DAQP did not report solved, handed to HiGHS (a diagnostic: none in the tests' layouts)."""
        if polygon_sides < 6:
            raise ValueError(f"polygon_sides must be at least 6, got {polygon_sides}")
        self.thrusters = tuple(thrusters)
        ids = [t.id for t in self.thrusters]
        unknown = set(failed) - set(ids)
        if unknown:
            raise ValueError(f"failed: unknown thruster ids {sorted(unknown)}; the layout has {ids}")
        self.failed = frozenset(failed)
        self.polygon_sides = int(polygon_sides)
        B = thruster_configuration_matrix(self.thrusters)
        is_az = [t.kind == "azimuth" for t in self.thrusters]
        owner = np.repeat(np.arange(len(ids)), [2 if a else 1 for a in is_az]).astype(int)
        cap = np.array([max(t.max_thrust_n, -min(t.min_thrust_n, 0.0)) for t in self.thrusters], dtype=float)
        self._owner = owner
        self._is_az = np.array(is_az, dtype=bool)
        # τ scale per DOF: what all thrusters together give in that DOF at full thrust (as allocation does)
        contrib = np.abs(B) * cap[owner][None, :]
        tau_ref = contrib.sum(axis=1) if contrib.size else np.zeros(3)
        self._tau_ref = np.maximum(tau_ref, max(float(tau_ref.max(initial=0.0)), 1.0) * 1e-6)
        self._cap_ext = cap[owner] if owner.size else np.zeros(0)
        self._B_hat = B * self._cap_ext[None, :] / self._tau_ref[:, None]  # scaled forces → scaled τ
        n_ext = B.shape[1]
        # bounds of the scaled variables: azimuth components in [-1, 1], fixed units in [tmin, tmax]/cap
        bounds: list[tuple[float, float]] = []
        for i in owner.tolist():
            t = self.thrusters[i]
            if t.id in self.failed:
                bounds.append((0.0, 0.0))
            elif is_az[i]:
                bounds.append((-1.0, 1.0))
            else:
                bounds.append((min(t.min_thrust_n, 0.0) / cap[i], t.max_thrust_n / cap[i]))
        self._bounds = [*bounds, (0.0, None)]
        # the convex pieces of each azimuth in service: a list of (rows, rhs) in its two variables
        disc = _disc_rows(self.polygon_sides)
        firsts = np.concatenate([[0], np.cumsum([2 if a else 1 for a in is_az])[:-1]]).astype(int)
        piece_sets: list[list[tuple[int, Array, Array]]] = []
        for i, t in enumerate(self.thrusters):
            if not is_az[i] or t.id in self.failed:
                continue
            arcs = allowed_arcs(t.forbidden_sectors_deg)
            if arcs is None:
                pieces = [disc]
            elif not arcs:  # every direction barred: no force
                pieces = [(np.vstack([np.eye(2), -np.eye(2)]), np.zeros(4))]
            else:
                pieces = [_wedge_rows(a, w, self.polygon_sides) for a, w in arcs]
            piece_sets.append([(int(firsts[i]), rows, rhs) for rows, rhs in pieces])
        # one inequality system per choice of one piece per azimuth
        self._systems: list[tuple[Array, Array]] = []
        for choice in itertools.product(*piece_sets) if piece_sets else [()]:
            blocks, rhs_parts = [], []
            for first, rows, rhs in choice:
                block = np.zeros((rows.shape[0], n_ext + 1))
                block[:, first : first + 2] = rows
                blocks.append(block)
                rhs_parts.append(rhs)
            if blocks:
                self._systems.append((np.vstack(blocks), np.concatenate(rhs_parts)))
            else:
                self._systems.append((np.zeros((0, n_ext + 1)), np.zeros(0)))
        self._c = np.zeros(n_ext + 1)
        self._c[-1] = -1.0  # maximise k̂
        # DAQP's form of each system: simple bounds on every variable (a failed thruster's pinned at 0,
        # immutable), then the three rows of B̂ f − k̂ t̂ = 0 (filled in per load), then the pieces' rows
        lo = np.array([b[0] for b in self._bounds], dtype=float)
        hi = np.array([_BIG if b[1] is None else b[1] for b in self._bounds], dtype=float)
        pinned = np.where(lo == hi, _IMMUTABLE, 0)
        self._daqp = [
            (
                np.vstack([np.zeros((3, n_ext + 1)), A_ub]),
                np.concatenate([hi, np.zeros(3), b_ub]),
                np.concatenate([lo, np.zeros(3), np.full(b_ub.size, -_BIG)]),
                np.concatenate([pinned, np.full(3, _IMMUTABLE), np.zeros(b_ub.size)]).astype(c_int),
            )
            for A_ub, b_ub in self._systems
        ]

    @property
    def lp_count(self) -> int:
        """LPs solved per load: the product over azimuths of their convex pieces (1 without sectors)."""
        return len(self._systems)

    def scale(self, tau: ArrayLike) -> float:
        """k*(τ) (module docstring): inf for τ = 0."""
        return self.solve(tau).scale

    @property
    def tau_ref(self) -> Array:
        """τ's scale per DOF (N, N, N·m): what all thrusters together give in it at full thrust. The LP is
        solved on τ / tau_ref, and `DIRECTION_EPS` is of its largest component in these units."""
        return self._tau_ref.copy()

    def solve(self, tau: ArrayLike) -> CapabilitySolution:
        """k*(τ) and the thrusters' forces that give k*·τ (τ's components below `DIRECTION_EPS` of its
        largest, in `tau_ref` units, taken as 0)."""
        t = np.asarray(tau, dtype=float).reshape(3)
        if not np.all(np.isfinite(t)):
            raise ValueError(f"tau must be finite, got {t.tolist()}")
        n = len(self.thrusters)
        if not np.any(t):
            return CapabilitySolution(
                math.inf, np.zeros(n), np.array([th.angle_rad for th in self.thrusters])
            )
        t_hat = t / self._tau_ref
        # the direction of t̂ as a unit vector, by its largest component first: ‖t̂‖ squares the
        # components, which underflows to 0 for a load below ~1e-150 (a load decaying towards zero) and
        # overflows for one above ~1e150; k* = k̂ / ‖t̂‖ is then formed as (k̂ / ‖u‖) / max|t̂|
        big = float(np.max(np.abs(t_hat)))
        if big == 0.0:  # (a load so small that dividing by τ_ref made it zero: held, however weak)
            return CapabilitySolution(
                math.inf, np.zeros(n), np.array([th.angle_rad for th in self.thrusters])
            )
        u = t_hat / big
        # A component below DIRECTION_EPS of the largest is taken as 0. At such a direction the answer
        # jumps: a yaw-only load that the layout answers only with surge of one sign has k* > 0, the same
        # load with 1e-7 of the other sign k* = 0, and the solvers decide it by their tolerances (DAQP
        # 0.73, HiGHS 0 on cybership2 with a sector barred and thruster 2 lost). No thruster resolves a
        # millionth of the largest demand, so the component is noise, and both solvers see the same LP.
        u[np.abs(u) < DIRECTION_EPS] = 0.0
        norm_u = float(np.linalg.norm(u))
        A_eq = np.column_stack([self._B_hat, -u / norm_u])
        best_k, best_x = -1.0, np.zeros(self._c.size)
        for j, (A_ub, b_ub) in enumerate(self._systems):
            if self.solver == "daqp":
                A, bu, bl, sense = self._daqp[j]
                A[:3] = A_eq
                x, fval, flag, _ = daqp.solve(None, self._c, A, bu, bl, sense)
                if flag == 1:  # (EXIT_OPTIMAL; anything else: HiGHS decides)
                    if -fval > best_k:
                        best_k, best_x = -float(fval), np.asarray(x, dtype=float)
                    continue
                self.fallbacks += 1
            res = linprog(
                self._c,
                A_ub=A_ub if A_ub.size else None,
                b_ub=b_ub if b_ub.size else None,
                A_eq=A_eq,
                b_eq=np.zeros(3),
                bounds=self._bounds,
                method="highs",
            )
            if res.status != 0:  # k = 0, f = 0 is always feasible and k is bounded: a solver failure
                raise RuntimeError(f"capability LP: HiGHS status {res.status}: {res.message}")
            if -res.fun > best_k:
                best_k, best_x = -float(res.fun), np.asarray(res.x, dtype=float)
        forces = best_x[:-1] * self._cap_ext
        thrust = np.zeros(n)
        azimuth = np.array([th.angle_rad for th in self.thrusters], dtype=float)
        k = 0
        for i in range(n):
            if self._is_az[i]:
                fx, fy = forces[k], forces[k + 1]
                thrust[i], azimuth[i] = math.hypot(fx, fy), math.atan2(fy, fx)
                k += 2
            else:
                thrust[i] = forces[k]
                k += 1
        with np.errstate(over="ignore"):  # (k* beyond the float range of a vanishing load: inf)
            scale = float(np.float64(max(best_k, 0.0) / norm_u) / big)
        return CapabilitySolution(scale, thrust, azimuth)
