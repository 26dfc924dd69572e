"""DP capability plot: the largest wind speed, with its current and waves, the thrusters can hold against.

For each direction β the environment comes from (degrees clockwise from the bow: 0 on the bow, 90 on
the starboard beam), intact and after each single thruster failure, the quasi-static balance

    τ_env(U, β) + τ_thr = 0,      τ_env = τ_wind(U, β) + τ_current(V_c, β) + τ_drift(Hs(U), Tp(U), β)

is asked of the thrusters through `gateway.control.capability` (k* = the largest multiple of −τ_env they
can give), and U_max(β) is the largest U such that k*(−τ_env(u, β)) ≥ 1 for every u ≤ U: the capability
plot of a DP vessel's documentation. The environment is co-linear (wind, waves and current from the same
β) and the vessel at rest at heading 0:

* wind: `observers.hull.relative_wind_force` (Fossen 2021 eqs (10.10)–(10.12), the simulator's and the
  wind feed-forward's own) for the vessel's ``[hull.wind]`` areas; U is the 1-hour mean at 10 m, brought
  to the areas' reference height by the NORSOK profile (`simulator.wind.norsok_mean`, as the simulator
  does with NORSOK gusts);
* current: `simulator.plant.FullPlant.current_load` — the full plant's hydrodynamic force on the hull
  held still in the current (surge resistance, cross-flow drag, the Munk moment of C_A(ν_r)ν_r), the
  same numbers the simulator applies; V_c fixed (``current_mps``), flowing towards β + 180°;
* waves: the mean drift 2∫S(ω)C(ω, β)dω of `simulator.waves.WaveResponse.mean_drift_force` (the
  ShipX supply vessel's coefficients, Froude-scaled for a vessel other than ``mss_supply``), in a fully
  developed Pierson–Moskowitz sea of the wind: Hs = 0.21 U₁₉.₅²/g, ω_p = 0.877 g/U₁₉.₅
  (Pierson & Moskowitz 1964; α = 0.0081, β = 0.74: Hs = 2√(α/β) g/ω₀², ω_p = (4β/5)^¼ ω₀,
  ω₀ = g/U₁₉.₅), U₁₉.₅ from U by the same NORSOK profile. A fully developed sea has the largest Hs
  the wind makes, but also the longest Tp, where a vessel of DP-vessel size drifts less per m² of Hs:
  not conservative for drift against a younger, fetch-limited sea (docs/capability.md).

Or, with ``Environment(sea="beaufort")``, the wind–sea–current relation of DNV-ST-0111 (Edition
December 2021) Table 2-1, the environment of its DP capability numbers: per Beaufort number 1–11 the
upper wind speed of that force, its Hs and Tp (a Pierson–Moskowitz spectrum, two-parameter form) and its
current (0.25, 0.50, then 0.75 m/s); between the rows Hs, Tp and the current are interpolated linearly in
U (the standard tabulates only the rows; the plot in m/s needs values between them). Each direction
then also gets its DP capability number: the highest Beaufort number whose row, and every row below it,
the thrusters hold (`dp_number`). The loads are still dpgw's (the vessel's own wind areas, full-plant
current load and drift coefficients), the drift long-crested (the standard's Level 1 spreads the waves by
cos²), and there is no thrust loss: the standard's *environment* and its dynamic factor, not its Level 1
load formulas, so the numbers are not a Level 1 assessment (docs/capability.md).

A missing ingredient (no ``[hull.wind]``: no wind load; no ``[hull]``: the current load from the linear
damping D alone) is left out with a warning in `CapabilityResult.warnings`, never silently.

Quasi-static: the mean loads, times ``Environment.dynamic_factor`` (1 by default: no dynamic allowance;
DNV-ST-0111's Level 1 multiplies the environmental loads by 1.25 for the gusts, the slowly varying drift
and the controller's reserve, the default with the Beaufort relation), no thrust loss beyond the barred
sectors. docs/capability.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gateway.control.capability import CapabilityLP
from gateway.control.consequence import failure_cases
from observers.hull import relative_wind, relative_wind_force
from observers.vessel import VesselModel
from simulator.plant import FullPlant
from simulator.plant_params import DEFAULT_OPTIONS, PlantOptions
from simulator.spectra import SeaState
from simulator.waves import G, WaveResponse
from simulator.wind import norsok_mean

Array = NDArray[np.float64]

DEFAULT_CURRENT_MPS = 0.75
"""1.5 kn: a moderate offshore surface current, the order used in published capability plots; give the
site's figure with ``current_mps``."""
PM_HS = 0.21
"""Hs = 0.21 U₁₉.₅²/g of a fully developed Pierson–Moskowitz sea."""
PM_PEAK = 0.877
"""ω_p = 0.877 g/U₁₉.₅ of a fully developed Pierson–Moskowitz sea."""
U_LIMIT_MPS = 40.0
"""The search stops here (beyond Beaufort 12, 32.7 m/s): a vessel that holds beyond it is reported as
holding at least this."""
U_GRID_MPS = 2.0
"""The scan step in U before the bisection: a loss of position between two grid speeds that is regained
at the next (k* not monotonic in U, possible when the yaw moments change sign) is missed only if it is
narrower than this."""
U_TOL_MPS = 0.02
"""Bisection tolerance on U_max (m/s)."""
CALM_U_MPS = 0.5
"""Below this wind speed the Pierson–Moskowitz sea is calm (Hs < 6 mm): no drift computed."""


@dataclass(frozen=True)
class BeaufortRow:
    """One row of DNV-ST-0111 Table 2-1: Beaufort number ``bf`` (the DP capability number), the upper
    1-hour mean wind speed at 10 m of that force, Hs, Tp and the current speed."""

    bf: int
    name: str
    wind_mps: float
    hs_m: float
    tp_s: float
    current_mps: float


BEAUFORT_TABLE = (
    BeaufortRow(0, "calm", 0.0, 0.0, math.nan, 0.0),  # (Tp not applicable: no sea)
    BeaufortRow(1, "light air", 1.5, 0.1, 3.5, 0.25),
    BeaufortRow(2, "light breeze", 3.4, 0.4, 4.5, 0.50),
    BeaufortRow(3, "gentle breeze", 5.4, 0.8, 5.5, 0.75),
    BeaufortRow(4, "moderate breeze", 7.9, 1.3, 6.5, 0.75),
    BeaufortRow(5, "fresh breeze", 10.7, 2.1, 7.5, 0.75),
    BeaufortRow(6, "strong breeze", 13.8, 3.1, 8.5, 0.75),
    BeaufortRow(7, "near gale", 17.1, 4.2, 9.0, 0.75),
    BeaufortRow(8, "gale", 20.7, 5.7, 10.0, 0.75),
    BeaufortRow(9, "strong gale", 24.4, 7.4, 10.5, 0.75),
    BeaufortRow(10, "storm", 28.4, 9.5, 11.5, 0.75),
    BeaufortRow(11, "violent storm", 32.6, 12.1, 12.0, 0.75),
)
"""DNV-ST-0111 (Edition December 2021) Table 2-1, the environment of the DP capability numbers 0–11
(Beaufort 12 has no capability number). Full scale."""
BEAUFORT_DYNAMIC_FACTOR = 1.25
"""DNV-ST-0111's Level 1 factor on the environmental loads (the dynamic allowance): the default with the
Beaufort relation."""
SEAS = ("pm", "beaufort")


def beaufort_sea(u10: float, scale: float = 1.0) -> tuple[float, float, float]:
    """(Hs m, Tp s, current m/s) of the Beaufort relation at wind speed ``u10`` (`BEAUFORT_TABLE`, linear
    in U between its rows, exactly a row's values at its wind speed; above Beaufort 11's wind, its row).
    ``scale``: a 1:λ model's λ (Froude: U, Tp and the current ÷ √λ, Hs ÷ λ). Tp is that of the next row
    up between calm and Beaufort 1, where Hs is below 0.1 m."""
    rows = BEAUFORT_TABLE
    root = math.sqrt(scale)
    u = u10 * root  # at full scale
    winds = [r.wind_mps for r in rows]
    hs = float(np.interp(u, winds, [r.hs_m for r in rows]))
    current = float(np.interp(u, winds, [r.current_mps for r in rows]))
    tp = float(np.interp(u, winds[1:], [r.tp_s for r in rows[1:]]))  # (clamped below Beaufort 1)
    return hs / scale, tp / root, current / root


def default_current(vessel: VesselModel) -> float:
    """`DEFAULT_CURRENT_MPS`, Froude-scaled (÷ √λ) for a 1:λ laboratory model (``vessel.model_scale``)."""
    return DEFAULT_CURRENT_MPS / math.sqrt(vessel.model_scale or 1.0)


def pm_sea(u10: float) -> tuple[float, float]:
    """(Hs m, Tp s) of the fully developed Pierson–Moskowitz sea of a 1-hour mean wind U₁₀ (module
    docstring): Hs = 0.21 U₁₉.₅²/g, Tp = 2π U₁₉.₅ / (0.877 g)."""
    u195 = norsok_mean(u10, 19.5)
    return PM_HS * u195**2 / G, 2.0 * math.pi * u195 / (PM_PEAK * G)


@dataclass(frozen=True)
class Environment:
    """The environment relation of the plot. ``current_mps`` the fixed current; ``wind``, ``current``,
    ``waves`` switch each load on or off (a wind-and-current-only plot, or a check against a simulation
    without waves)."""

    current_mps: float = DEFAULT_CURRENT_MPS
    wind: bool = True
    current: bool = True
    waves: bool = True
    sea: str = "pm"
    """"pm": a fully developed Pierson–Moskowitz sea of the wind and the fixed ``current_mps``;
    "beaufort": DNV-ST-0111 Table 2-1's sea and current for the wind (`beaufort_sea`; ``current_mps``
    unused)."""
    dynamic_factor: float = 1.0
    """The factor on the environmental loads (1: the mean loads; DNV-ST-0111 Level 1: 1.25)."""

    def __post_init__(self) -> None:
        if self.sea not in SEAS:
            raise ValueError(f"sea must be one of {SEAS}, got {self.sea!r}")
        if not (math.isfinite(self.dynamic_factor) and self.dynamic_factor > 0):
            raise ValueError(f"dynamic_factor must be a positive number, got {self.dynamic_factor!r}")

    def describe(self) -> str:
        parts = ["wind U" if self.wind else "no wind load"]
        if self.sea == "beaufort":
            if self.waves or self.current:
                kinds = [k for k, on in (("sea", self.waves), ("current", self.current)) if on]
                parts.append(f"DNV-ST-0111 Table 2-1 {' and '.join(kinds)} of U")
        else:
            if self.waves:
                parts.append("fully developed PM sea Hs = 0.21 U19.5²/g")
            if self.current:
                parts.append(f"current {self.current_mps:.3g} m/s")
        if self.dynamic_factor != 1.0:
            parts.append(f"loads × {self.dynamic_factor:g}")
        return ", ".join(parts) + ", co-linear" if len(parts) > 1 or self.wind else "no environment"


class EnvironmentLoads:
    """τ_env(U, β) on a vessel at rest (module docstring). ``warnings``: what is missing or estimated."""

    def __init__(self, vessel: VesselModel, environment: Environment = Environment()) -> None:
        self.vessel = vessel
        self.environment = environment
        self.warnings: list[str] = []
        hull = vessel.hull
        self.area = hull.wind if hull is not None else None
        if environment.wind and self.area is None:
            self.warnings.append(
                f"vessel '{vessel.name}' has no [hull.wind] areas: no wind load (the plot is for current and "
                "waves only)"
            )
            # what is computed, for the result to say: U still sets the sea (and the Beaufort current)
            self.environment = environment = replace(environment, wind=False)
        options = DEFAULT_OPTIONS
        if hull is None:
            options = PlantOptions(coriolis=False, surge_resistance=False, crossflow=False)
            if environment.current:
                self.warnings.append(
                    f"vessel '{vessel.name}' has no [hull] table: current load from the linear damping D "
                    "extrapolated to the current speed (no quadratic drag; D is fitted for slow motions: "
                    "read the current term with caution)"
                )
        if vessel.model_scale is not None:
            self.warnings.append(
                f"vessel '{vessel.name}' is a 1:{vessel.model_scale:g} model: U and the current are at the "
                f"model's scale (full scale: × {math.sqrt(vessel.model_scale):.3g}); the wind profile is not "
                "Froude-scaled"
            )
        self.plant = FullPlant(vessel, options=options)
        self.waves = WaveResponse.for_vessel(vessel) if environment.waves else None
        if self.waves is not None and vessel.name != "mss_supply":
            self.warnings.append(
                f"wave drift: the ShipX supply vessel's drift coefficients Froude-scaled to L = "
                f"{vessel.length_m:g} m (no data of this vessel's own)"
            )

    def components(self, u10: float, beta_rad: float) -> dict[str, Array]:
        """{"wind", "current", "waves"} loads [X, Y, N] (N, N, N·m, body frame) of wind speed ``u10`` with
        everything coming from β (rad, clockwise from the bow)."""
        env = self.environment
        zero = np.zeros(3)
        wind, current, waves = zero, zero, zero
        if env.wind and self.area is not None and u10 > 0:
            speed = norsok_mean(u10, self.area.height_m)
            urw, vrw = relative_wind(speed, math.degrees(beta_rad), 0.0, 0.0, 0.0)
            wind = np.array(relative_wind_force(self.area, self.vessel.length_m, urw, vrw))
        if env.sea == "beaufort":
            hs, tp, current_mps = beaufort_sea(u10, self.vessel.model_scale or 1.0)
            calm = hs <= 0.0
        else:
            current_mps, calm = env.current_mps, u10 < CALM_U_MPS
            hs, tp = pm_sea(u10) if not calm else (0.0, math.nan)
        if env.current and current_mps > 0:
            towards = beta_rad + math.pi
            vc = current_mps * np.array([math.cos(towards), math.sin(towards)])
            current = np.array(self.plant.current_load(vc), dtype=float)
        if self.waves is not None and not calm:
            sea = SeaState(hs_m=hs, tp_s=tp, kind="pm", direction_rad=beta_rad + math.pi)
            waves = np.asarray(self.waves.mean_drift_force(sea, 0.0), dtype=float)
        return {"wind": wind, "current": current, "waves": waves}

    def tau(self, u10: float, beta_rad: float) -> Array:
        """τ_env: the sum of the `components`, times the environment's ``dynamic_factor``."""
        c = self.components(u10, beta_rad)
        return np.asarray(
            self.environment.dynamic_factor * (c["wind"] + c["current"] + c["waves"]), dtype=float
        )


def limit_speed(
    scale_at: Callable[[float], float],
    *,
    u_limit: float = U_LIMIT_MPS,
    grid: float = U_GRID_MPS,
    tol: float = U_TOL_MPS,
) -> float:
    """U_max: the largest U ≤ ``u_limit`` with ``scale_at(u)`` ≥ 1 on [0, U] (scanned every ``grid``,
    then bisected to ``tol``); 0 when even U = 0 cannot be held, ``u_limit`` when nothing up to it fails.

    ``u_limit`` itself is always tried: where it is not a multiple of ``grid`` (the Beaufort scale's end,
    32.6 m/s) the scan would otherwise stop at the last multiple below it and call that limit held."""
    if scale_at(0.0) < 1.0:
        return 0.0
    lo = 0.0
    speeds = [float(u) for u in np.arange(grid, u_limit + 1e-9, grid)]
    if not speeds or speeds[-1] < u_limit - 1e-9:
        speeds.append(u_limit)
    for u in speeds:
        if scale_at(u) < 1.0:
            hi = u
            break
        lo = u
    else:
        return u_limit
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if scale_at(mid) >= 1.0:
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class CapabilityCase:
    """One thruster condition: ``label`` ("intact", "thruster 3 failed"), the ``failed`` ids and U_max
    per direction (m/s; the result's ``u_limit`` means at least that)."""

    label: str
    failed: tuple[int, ...]
    u_max: tuple[float, ...]
    dp_number: tuple[int, ...] | None = None
    """With the Beaufort relation, per direction the DP capability number (`dp_number`); else None."""


@dataclass(frozen=True)
class CapabilityResult:
    """A capability plot's numbers. ``worst``: per direction the smallest U_max over the single failures
    (None when failures were not analysed), ``worst_failed`` which thruster gives it; ``u_limit`` where
    the search stopped (a U_max equal to it means at least that)."""

    vessel: str
    directions_deg: tuple[float, ...]
    environment: Environment
    cases: tuple[CapabilityCase, ...]
    worst: tuple[float, ...] | None = None
    worst_failed: tuple[tuple[int, ...], ...] | None = None
    warnings: tuple[str, ...] = field(default=())
    u_limit: float = U_LIMIT_MPS
    worst_dp_number: tuple[int, ...] | None = None
    """With the Beaufort relation and failures analysed: per direction the least DP capability number
    over the failures."""

    @property
    def intact(self) -> CapabilityCase:
        return self.cases[0]

    def limiting_failures(self) -> tuple[tuple[int, ...], ...] | None:
        """Per direction the thrusters whose failure gives ``worst``; () where no failure lowers U_max below
        the intact vessel's own figure (nor the search's end): there is no failure to name, and naming the
        first of the equal ones would blame a thruster that is not the cause. None: failures not analysed."""
        if self.worst is None or self.worst_failed is None:
            return None
        return tuple(
            f if w < min(self.u_limit, u) else ()
            for w, u, f in zip(self.worst, self.intact.u_max, self.worst_failed, strict=True)
        )

    def to_dict(self) -> dict[str, Any]:
        env = self.environment
        beaufort = env.sea == "beaufort"
        environment: dict[str, Any] = {
            "relation": env.describe(),
            "sea": env.sea,
            "current_mps": (None if beaufort else env.current_mps) if env.current else 0.0,
            "wind": env.wind,  # (false where the vessel has no [hull.wind] areas: no wind load computed)
            "waves": env.waves,
            "wave_relation": "DNV-ST-0111 Table 2-1 (Hs, Tp and current per Beaufort number, linear in U "
            "between its rows; Pierson-Moskowitz spectrum)"
            if beaufort
            else "Pierson-Moskowitz fully developed: Hs = 0.21 U19.5^2/g, wp = 0.877 g/U19.5",
            "dynamic_factor": env.dynamic_factor,
        }
        if beaufort:
            environment["beaufort_table"] = [
                {
                    "bf": r.bf,
                    "wind_mps": r.wind_mps,
                    "hs_m": r.hs_m,
                    "tp_s": None if math.isnan(r.tp_s) else r.tp_s,
                    "current_mps": r.current_mps,
                }
                for r in BEAUFORT_TABLE
            ]
        cases = []
        for c in self.cases:
            case: dict[str, Any] = {"label": c.label, "failed": list(c.failed), "u_max_mps": list(c.u_max)}
            if c.dp_number is not None:
                case["dp_capability_number"] = list(c.dp_number)
            cases.append(case)
        worst: dict[str, Any] | None = None
        if self.worst is not None:
            worst = {
                "u_max_mps": list(self.worst),
                "failed": [list(f) for f in self.limiting_failures() or ()],
            }
            if self.worst_dp_number is not None:
                worst["dp_capability_number"] = list(self.worst_dp_number)
        return {
            "vessel": self.vessel,
            "environment": environment,
            "direction_convention": "environment coming from, degrees clockwise from the bow",
            "u_limit_mps": self.u_limit,
            "directions_deg": list(self.directions_deg),
            "cases": cases,
            "worst_failure": worst,
            "warnings": list(self.warnings),
        }


def capability(
    vessel: VesselModel,
    *,
    environment: Environment = Environment(),
    directions_deg: Sequence[float] | None = None,
    step_deg: float = 10.0,
    failures: str = "each",
    failure_groups: Sequence[Collection[int]] | None = None,
    u_limit: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CapabilityResult:
    """U_max per direction, intact and (``failures`` "each" or "worst") after each single failure;
    "none": intact only. "worst" keeps only the intact case and the per-direction minimum. A failure is
    one thruster, or with ``failure_groups`` each group of thrusters lost together (a switchboard, an
    engine room: the worst-case failure of the vessel's FMEA) and each thruster in no group alone
    (`gateway.control.consequence.failure_cases`, as the online consequence analysis tests them).
    The search (`limit_speed`) stops at ``u_limit`` (default `U_LIMIT_MPS`); its grid, tolerance and
    default limit are Froude-scaled (÷ √λ) for a 1:λ laboratory model. ``progress(done, total)``, when
    given, is called after each direction (a progress bar: a fine ``step_deg`` takes minutes)."""
    if failures not in ("none", "each", "worst"):
        raise ValueError(f"failures must be 'none', 'each' or 'worst', got {failures!r}")
    if not vessel.thrusters:
        raise ValueError(f"vessel '{vessel.name}' has no thrusters: nothing to hold position with")
    step_note = None
    if directions_deg is None:
        if not (0 < step_deg <= 180):
            raise ValueError(f"step_deg must be in (0, 180], got {step_deg!r}")
        n = max(1, round(360.0 / step_deg))
        directions_deg = [i * 360.0 / n for i in range(n)]
        if abs(n * step_deg - 360.0) > 1e-6:
            # the directions are spread evenly over the circle: a step that does not divide 360 is
            # rounded to one that does, and said (a plot at 7.06° steps for 7 was not)
            step_note = f"a step of {step_deg:g}° does not divide 360°: {n} directions {360.0 / n:.4g}° apart"
    dirs = tuple(float(d) for d in directions_deg)
    froude = math.sqrt(vessel.model_scale or 1.0)
    beaufort = environment.sea == "beaufort"
    # the Beaufort relation ends at Beaufort 11's wind: no capability number beyond it
    top = BEAUFORT_TABLE[-1].wind_mps if beaufort else U_LIMIT_MPS
    u_limit = top / froude if u_limit is None else float(u_limit)
    row_winds = [r.wind_mps / froude for r in BEAUFORT_TABLE[1:]]
    grid, tol = U_GRID_MPS / froude, U_TOL_MPS / froude
    loads = EnvironmentLoads(vessel, environment)
    conditions: list[tuple[str, tuple[int, ...]]] = [("intact", ())]
    if failures != "none":
        ids = {t.id for t in vessel.thrusters}
        # (the groups, then each thruster in no group alone: its own failure is a single failure too)
        groups = failure_cases([t.id for t in vessel.thrusters], [tuple(g) for g in failure_groups or ()])
        for group in groups:
            g = tuple(sorted(set(group)))
            if not g or set(g) - ids:
                raise ValueError(
                    f"failure group {list(group)}: give thruster ids of the vessel ({sorted(ids)})"
                )
            name = f"thruster {g[0]}" if len(g) == 1 else "thrusters " + "+".join(map(str, g))
            conditions.append((f"{name} failed", g))
    problems = [CapabilityLP(vessel.thrusters, failed=f) for _, f in conditions]
    per_case: list[list[float]] = [[] for _ in conditions]
    numbers: list[list[int]] = [[] for _ in conditions]
    for d in dirs:
        beta = math.radians(d)
        cache: dict[float, Array] = {}

        def demand(u: float, beta: float = beta, cache: dict[float, Array] = cache) -> Array:
            if u not in cache:
                cache[u] = -loads.tau(u, beta)
            return cache[u]

        for lp, out, number in zip(problems, per_case, numbers, strict=True):

            def scale_at(u: float, lp: CapabilityLP = lp) -> float:
                return lp.scale(demand(u))

            out.append(limit_speed(scale_at, u_limit=u_limit, grid=grid, tol=tol))
            if beaufort:
                number.append(dp_number(scale_at(u) for u in row_winds))
        if progress is not None:
            progress(len(per_case[0]), len(dirs))
    cases = tuple(
        CapabilityCase(label, failed, tuple(u), tuple(n) if beaufort else None)
        for (label, failed), u, n in zip(conditions, per_case, numbers, strict=True)
    )
    worst = worst_failed = worst_number = None
    if failures != "none":
        fail_cases = cases[1:]
        table = np.array([c.u_max for c in fail_cases])  # failures × directions
        idx = [int(j) for j in np.argmin(table, axis=0)]  # the first failure of the least U_max
        worst = tuple(fail_cases[j].u_max[i] for i, j in enumerate(idx))
        worst_failed = tuple(fail_cases[j].failed for j in idx)
        if beaufort:
            worst_number = tuple(min(n) for n in zip(*(c.dp_number or () for c in fail_cases), strict=True))
        if failures == "worst":
            cases = cases[:1]
    return CapabilityResult(
        vessel.name,
        dirs,
        loads.environment,  # (wind off where the vessel has no wind areas: what was computed)
        cases,
        worst,
        worst_failed,
        (*loads.warnings, *([step_note] if step_note else [])),
        u_limit,
        worst_number,
    )


def dp_number(scales: Iterable[float]) -> int:
    """The DP capability number from k* at the Beaufort rows 1, 2, … 11 in order: the highest number
    whose row and every row below it are held (k* ≥ 1); 0 when even Beaufort 1 is not (calm, Beaufort 0,
    has no load and is always held). Reads ``scales`` only up to the first row not held (a generator
    spares the LPs of the rows above it)."""
    held = 0
    for k in scales:
        if k < 1.0:
            break
        held += 1
    return held


def plot(result: CapabilityResult, path: str) -> None:
    """The classic polar capability plot: 0° = environment from ahead, clockwise, U_max radial (m/s),
    intact and worst single failure, written to ``path`` (PNG, SVG, PDF by its suffix)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.projections.polar import PolarAxes

    theta = np.radians(np.append(result.directions_deg, result.directions_deg[0]))
    fig = plt.figure(figsize=(7.0, 7.6))
    ax = fig.add_subplot(projection="polar")
    assert isinstance(ax, PolarAxes)
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    # with the Beaufort relation the plot is of the DP capability numbers, as the standard draws it
    numbers = result.intact.dp_number is not None

    def radial(case: CapabilityCase) -> Array:
        return np.array(case.dp_number if numbers and case.dp_number is not None else case.u_max, dtype=float)

    u = radial(result.intact)
    ax.plot(theta, np.append(u, u[0]), "-o", color="tab:blue", ms=3, label="intact")
    for k, case in enumerate(result.cases[1:]):
        v = radial(case)
        ax.plot(theta, np.append(v, v[0]), "-", color="0.7", lw=0.8, label="each failure" if k == 0 else None)
    worst = result.worst_dp_number if numbers else result.worst
    if worst is not None:
        w = np.array(worst, dtype=float)
        single = all(len(f) == 1 for f in result.worst_failed or ())
        label = "worst single failure" if single else "worst failure"
        ax.plot(theta, np.append(w, w[0]), "-s", color="tab:red", ms=3, label=label)
    ax.set_rlabel_position(112.5)  # between the angle labels (every 45°): the outer figure clear of "135°"
    if numbers:
        top = BEAUFORT_TABLE[-1].bf
        ax.set_rlim(0.0, top)
        ax.set_rticks(range(0, top + 1))
        caption = f"radial: DP capability number (Beaufort 0-{top}, DNV-ST-0111 Table 2-1 environment)"
    else:
        ax.set_rlim(0.0, result.u_limit)
        caption = f"radial: U_max (m/s, 1-hour mean wind at 10 m); {result.u_limit:.3g} = at least"
    ax.legend(loc="lower right", bbox_to_anchor=(1.1, -0.12), fontsize=8)
    fig.text(0.5, 0.05, caption, ha="center")
    env = result.environment.describe()
    fig.suptitle(
        f"DP capability: {result.vessel}\n{env}\n(environment from, clockwise from the bow)", fontsize=10
    )
    if result.warnings:
        fig.text(0.01, 0.005, "\n".join("note: " + w for w in result.warnings), fontsize=6, va="bottom")
    fig.savefig(path, dpi=120)
    plt.close(fig)
