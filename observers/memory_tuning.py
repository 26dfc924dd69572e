"""The fluid-memory observer's model and gains in physical terms, and the checks that make them safe.

Hajivand & Mousavizadegan (2010), eqs (17)–(21), is the passive observer of Fossen & Strand (1999) with the
kinetics (20) written for the Cummins equation (2)/(8) instead of constant coefficients::

    [M_RB + A(∞)] ν̂' = -D_m ν̂ + Jᵀ b̂ + τ - μ̂ + Jᵀ K4 ỹ,   ξ̂_r' = A_r ξ̂_r + B_r ν̂,   μ̂ = C_r ξ̂_r + D_r ν̂

**The model.** A vessel file's M and D are the low-frequency model (M = M_RB + A(0), D the damping of slow
motion), the only numbers a DP vessel usually has. The radiation model (`observers.radiation`) says how
the added mass and damping change with frequency. The memory observer uses::

    M_m = M - [A(0) - A(∞)],        D_m = D - K(0)

with A(0) = A(∞) - C_r A_r⁻² B_r and K(0) = D_r - C_r A_r⁻¹ B_r of the radiation model, so that as ω → 0
the two observers see exactly the same ship (M_m + A(0) - A(∞) = M, D_m + K(0) = D), and they differ only
where the fluid memory acts. M_m is the vessel's M_RB + A(∞), which is what (20) asks for, and it must not
fall below M_RB (an A(∞) < 0: refused, `check_model`).

**The radiation model** (`default_radiation`) of the vessel's own hull (`observers.radiation.identify` on
its A(ω), B(ω); a built-in vessel's is stored beside it) is the right one. Without one, dpgw uses the
built-in model of MSS's supply vessel (the model stored beside the built-in vessel ``mss_supply``,
``observers/vessels/radiation/mss_supply.npz``) Froude-scaled to the vessel's displacement (length scale
λ = (m/m_supply)^⅓; `RadiationStateSpace.froude_scaled`): a hull of a similar form, with its memory time
scale. ``froude_scale`` overrides λ. Either is then fitted to a vessel file in the zero-frequency form
(`fit_scale`): per DOF its A(0) - A(∞) takes at most the share of the vessel's added mass M - M_RB that
memory has in the model's own hull, so that M_m ≥ M_RB + (1 - share)(M - M_RB). The vessel's M decides the
total because every observer, the controller and the plant without memory use it; the model decides the
time scale and the share. A file in the Cummins form (M_RB and A(∞) given, `observers.vessel`) took its
M from the Froude-scaled model, which is used as it is; its M_m is the file's M_RB + A(∞) exactly.

**Gains.** The passive observer's (`observers.passive_tuning`) from the same physical tuning: wave filter
from ω0, ζ, ζn, ωc, injections K4 = diag(M)·ωc·a and K3 = K4·ρ, then both injections multiplied per DOF by

    sᵢ = min(1, |jω0ᵢ M_m,ii + D_m,ii + K_ii(jω0ᵢ)| / |jω0ᵢ M_ii + D_ii|)          (`injection_scale`)

the ratio of the impedance the memory observer's velocity sees at the wave frequency to the passive
observer's, never above one. Why: ỹ carries the wave-frequency motion, and K4 ỹ drives ν̂ through that
impedance. Where the fluid memory has given back much of A(0) - A(∞) at ω0 (a short wave period, a large
hull: the ratio below one, 0.56-0.86 for Hajivand's vessel at 5-8 s), the memory observer's ν̂ with the
passive observer's K4 takes more wave motion than the passive observer's (measured, Hajivand's vessel
with slow manoeuvres: velocity errors 10-15 % above the passive observer's); scaled down by sᵢ it takes
less (velocity errors 9-22 % below). The price is a velocity-injection rate sᵢ·a instead of a at low
frequency (the slowest error pole of Hajivand's vessel -0.0206 s⁻¹ against -0.0226 s⁻¹), which
`slowest_error_rate` reports.

Where the ratio is above one (the supply vessel from 7-8 s periods on: 1.02-1.12) the memory observer
already takes less wave motion than the passive one, and raising its injections to "match" was measured
to cost: station keeping on the full plant (supply vessel, Hs 6 m, Tp 11.5 s, current and wind, four
seeds), surge-velocity errors 4.9-7.3 % above the passive observer's, with or without fluid memory in the
plant; capped at one, every DOF is within 1 % of the passive observer's (tests/test_memory_full_plant.py).
The impedance at the single frequency ω0 is a rule of thumb for a wave band, and it over-corrects either
way; only the direction that lowers the leakage is kept.

**Passivity of the extended error system.** Fossen & Strand's proof splits the error dynamics into the
position/wave/bias part (the SPR condition of Proposition 1, `check_spr`) and the velocity part, which must
be strictly passive from the injected force to ν̃. Here the velocity part is M_m ν̃' = -D_m ν̃ - μ̃ + u
with μ̃ = K(s) ν̃ (radiation states driven by ν̂ in the observer and by ν in the ship, so the error states
obey ξ̃_r' = A_r ξ̃_r + B_r ν̃): the map u → ν̃ is (M_m s + D_m + K(s))⁻¹, strictly passive when
Herm[D_m + K(jω)] > 0 at every ω, which holds when D_m + D_mᵀ > 0 and K is positive real (the
identification enforces the latter). `check_velocity_passivity` checks the Hermitian part numerically on a
grid spanning the radiation poles and the data band; `check_radiation_passivity` checks K alone;
`check_model` M_m > 0 and D_m + D_mᵀ > 0. The linearised extended error matrix (`error_dynamics_matrix`)
gives the rate the tuning promises (`slowest_error_rate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from observers.passive_tuning import (
    DOF,
    Check,
    PassiveGains,
    PassiveTuning,
    TuningError,
    check_spr,
    check_tuning_rule,
    injection_matrix,
    model_matrix,
    passive_gains,
)
from observers.radiation import RadiationStateSpace
from observers.radiation_builtin import (
    builtin_radiation,
    froude_scale_for_mass,
    memory_added_mass,
    stored_radiation,
)
from observers.state import ETA, N_STATE, NU, XI2
from observers.vessel import VesselModel, load_vessel, rigid_body_diagonal, rigid_body_matrix

Array = NDArray[np.float64]

PASSIVITY_TOLERANCE = 1e-9
"""Round-off allowance of the numerical passivity checks, relative to the largest damping on the grid."""


class MemoryModelError(TuningError):
    """A radiation model that cannot be combined with the vessel (the message says which matrix and why)."""


def froude_scale_for(vessel: VesselModel) -> float:
    """Length scale λ = (m_vessel / m_supply)^⅓ that carries the built-in model to ``vessel``'s mass."""
    return froude_scale_for_mass(vessel.mass_kg)


def own_radiation(vessel: VesselModel) -> RadiationStateSpace | None:
    """The model identified from the vessel's own A(ω), B(ω) when it is a built-in vessel that has one
    (``mss_supply``: the model the simulator's plant integrates for it), else None."""
    model = stored_radiation(vessel.name)
    if model is None:
        return None
    return model if vessel == load_vessel(vessel.name) else None


def memory_share(radiation: RadiationStateSpace) -> Array:
    """1 - A(∞)ᵢᵢ / A(0)ᵢᵢ per DOF: the share of the zero-frequency added mass that the fluid memory
    supplies in the model's own hull (the supply vessel: 0.595, 0.595, 0.471). Unchanged by Froude scaling
    and by `RadiationStateSpace.dof_scaled`: a property of the hull's form, not of its size."""
    a0 = np.diag(radiation.zero_frequency_added_mass())
    return np.asarray(1.0 - np.diag(radiation.A_inf) / a0)


def fit_scale(vessel: VesselModel, radiation: RadiationStateSpace) -> Array:
    """Per-DOF factors sᵢ ≤ 1 for `RadiationStateSpace.dof_scaled` so that the model's A(0) - A(∞) takes no
    more of the vessel's own added mass aᵢ = Mᵢᵢ - M_RB,ii than the model's hull gives to memory::

        sᵢ² = min(1, shareᵢ · aᵢ / [A(0) - A(∞)]ᵢᵢ)            (`memory_share`)

    so that the vessel's implied A(∞)ᵢᵢ = aᵢ - sᵢ² [A(0) - A(∞)]ᵢᵢ ≥ (1 - shareᵢ) aᵢ > 0 and M_m,ii ≥
    M_RB,ii. sᵢ = 1 where the DOF's M_RB is unknown (`rigid_body_diagonal`: yaw of a file without I_z)."""
    a = np.diag(vessel.M) - rigid_body_diagonal(vessel)
    mem = np.diag(memory_added_mass(radiation))
    share = memory_share(radiation)
    with np.errstate(invalid="ignore"):
        s2 = np.where(
            np.isfinite(a) & (mem > 0), np.minimum(1.0, share * a / np.where(mem > 0, mem, 1.0)), 1.0
        )
    return np.sqrt(np.maximum(s2, 1e-12))


def default_radiation(vessel: VesselModel, froude_scale: float | None = None) -> RadiationStateSpace:
    """The model of ``vessel``'s fluid memory that dpgw uses, in the observer and in a plant
    (docs/memory-observer.md, "Radiation model"):

    1. its own (`own_radiation`, unscaled: the hull its data describe), or the built-in model
       Froude-scaled to its displacement (`froude_scale_for`), or by ``froude_scale`` when given;
    2. for a vessel file in the zero-frequency form (M = M_RB + A(0)), scaled per DOF by `fit_scale`: the
       vessel's M is what every observer, the controller and the plant without memory use, so it sets
       the total added mass; the model sets the time scale and the share of it that is memory. A file in
       the Cummins form (``A_inf``) states A(∞) and took its A(0) from the Froude-scaled built-in model,
       which is left as it is;
    3. its A(∞) made the vessel's (`with_vessel_A_inf`), so that M_RB + A(∞) is the memory observer's M_m
       and a plant with this model has the vessel file's M as ω → 0."""
    own = own_radiation(vessel) if froude_scale is None else None
    if own is not None:
        radiation = own
    else:
        scale = froude_scale_for(vessel) if froude_scale is None else froude_scale
        radiation = builtin_radiation().froude_scaled(scale)
    if vessel.A_inf is None:
        s = fit_scale(vessel, radiation)
        if not np.all(s == 1.0):
            radiation = radiation.dof_scaled(s)
    return with_vessel_A_inf(vessel, radiation)


def with_vessel_A_inf(vessel: VesselModel, radiation: RadiationStateSpace) -> RadiationStateSpace:
    """``radiation`` with A(∞) = the vessel's: its file's ``A_inf`` (Cummins form), else M - M_RB - [A(0) -
    A(∞)] (so that the model's A(0) is the vessel's added mass M - M_RB), and ``M_RB`` the vessel's (the
    mass a plant puts A(∞) with). Unchanged if the vessel's full M_RB is unknown (no ``M_RB``, no
    ``[hull]``: such a vessel has no full plant, and the observer does not read A(∞))."""
    m_rb = rigid_body_matrix(vessel)
    if m_rb is None:
        return radiation
    a_inf = vessel.A_inf if vessel.A_inf is not None else vessel.M - m_rb - memory_added_mass(radiation)
    return replace(
        radiation,
        A_inf=0.5 * (a_inf + a_inf.T),
        M_RB=m_rb,
        source=f"{radiation.source}, A(∞) of {vessel.name}",
    )


@dataclass(frozen=True)
class MemoryModel:
    """What (20) integrates: M_m = M_RB + A(∞) (3×3), D_m (3×3) and the radiation state space."""

    M: Array
    D: Array
    radiation: RadiationStateSpace
    rigid_body: Array | None = None
    """Diagonal of the vessel's M_RB (`rigid_body_diagonal`, NaN where unknown): M_m,ii may not be less."""

    @property
    def Minv(self) -> Array:
        return np.asarray(np.linalg.inv(self.M))

    @property
    def memory_added_mass(self) -> Array:
        """A(0) - A(∞): the added mass that the fluid memory supplies to slow motion (kg, kg·m, kg·m²)."""
        return memory_added_mass(self.radiation)


def memory_model(
    vessel: VesselModel, radiation: RadiationStateSpace | None = None, froude_scale: float | None = None
) -> MemoryModel:
    """M_m = M - [A(0) - A(∞)] and D_m = D - K(0) for ``vessel`` with ``radiation`` (default:
    `default_radiation`, ``froude_scale`` its length scale). A model given is used as it is (Froude-scaled
    by ``froude_scale`` if given); every combination must leave M_m ≥ M_RB in each DOF whose M_RB is known
    and be a ship (`check_model`), else it is refused."""
    if radiation is None:
        radiation = default_radiation(vessel, froude_scale)
    elif froude_scale is not None:
        radiation = radiation.froude_scaled(froude_scale)
    ev = np.linalg.eigvals(radiation.Ar)
    if radiation.n_states == 0 or not np.all(ev.real < 0):
        raise MemoryModelError(
            f"radiation model: A_r must have every pole in the open left half-plane (largest real part "
            f"{ev.real.max() if len(ev) else float('nan'):.4g}); identify it with observers.radiation"
        )
    M = np.asarray(vessel.M - memory_added_mass(radiation))
    D = np.asarray(vessel.D - radiation.static_gain())
    model = MemoryModel(M, D, radiation, rigid_body_diagonal(vessel))
    check = check_model(model, vessel)
    if not check.ok:
        raise MemoryModelError(f"memory observer: {check.detail}")
    return model


@dataclass(frozen=True)
class MemoryGains:
    """The passive observer's gains (`PassiveGains`, the same physical tuning) and the memory model."""

    passive: PassiveGains
    model: MemoryModel

    @property
    def omega0(self) -> Array:
        return self.passive.omega0


def memory_gains(
    vessel: VesselModel,
    tuning: PassiveTuning | None = None,
    radiation: RadiationStateSpace | None = None,
    froude_scale: float | None = None,
) -> MemoryGains:
    """Gains for ``vessel`` from the physical ``tuning`` (the passive observer's, injections times
    `injection_scale`) and the memory model (`memory_model`)."""
    model = memory_model(vessel, radiation, froude_scale)
    pg = passive_gains(vessel, tuning)
    scale = np.diag(injection_scale(vessel, model, pg.omega0))
    return MemoryGains(replace(pg, K3=pg.K3 @ scale, K4=pg.K4 @ scale), model)


def injection_scale(vessel: VesselModel, model: MemoryModel, omega0: Array) -> Array:
    """sᵢ = min(1, |jω0 M_m,ii + D_m,ii + K_ii(jω0)| / |jω0 M_ii + D_ii|) per DOF (module docstring, Gains):
    the injections are lowered where the memory observer's velocity would take more wave motion than the
    passive observer's, never raised."""
    K = model.radiation.frequency_response(omega0)
    out = np.empty(3)
    for i in range(3):
        z_mem = 1j * omega0[i] * model.M[i, i] + model.D[i, i] + K[i, i, i]
        z_lf = 1j * omega0[i] * vessel.M[i, i] + vessel.D[i, i]
        out[i] = min(1.0, abs(z_mem) / abs(z_lf))
    return out


# --- checks ---------------------------------------------------------------------------------------------


def check_grid(radiation: RadiationStateSpace) -> Array:
    """Frequencies (rad/s) for the numerical checks: 10⁻³ of the slowest to 10³ × the fastest radiation
    pole, log-spaced, 60 points a decade (the Hermitian part varies on the scale of the poles)."""
    mag = np.abs(np.linalg.eigvals(radiation.Ar))
    lo, hi = math.log10(mag.min()) - 3.0, math.log10(mag.max()) + 3.0
    return np.logspace(lo, hi, int(60 * (hi - lo)) + 1)


def check_model(model: MemoryModel, vessel: VesselModel | None = None) -> Check:
    """M_m = M_RB + A(∞) symmetric positive definite (it is the inertia (20) inverts) and not below the
    rigid-body mass in any DOF where that is known (A(∞)ᵢᵢ ≥ 0), D_m + D_mᵀ > 0."""
    problems = []
    lam_m = float(np.linalg.eigvalsh(0.5 * (model.M + model.M.T)).min())
    if not lam_m > 0:
        hint = (
            f" (the vessel's M {np.diag(vessel.M).tolist()} is smaller than the radiation model's "
            f"A(0) - A(∞) {np.diag(model.memory_added_mass).tolist()}: a model of another hull? "
            "set froude_scale)"
            if vessel is not None
            else ""
        )
        problems.append(f"M_RB + A(∞) = M - [A(0) - A(∞)] is not positive definite (smallest eigenvalue "
                        f"{lam_m:.4g}){hint}")  # fmt: skip
    rb = np.full(3, np.nan) if model.rigid_body is None else model.rigid_body
    margin = np.diag(model.M) / rb - 1.0  # M_m,ii / M_RB,ii - 1 = A(∞)ᵢᵢ / M_RB,ii, NaN where unknown
    below = [DOF[i] for i in range(3) if margin[i] < 0]
    if below:
        problems.append(
            f"M_RB + A(∞) = M - [A(0) - A(∞)] is below the rigid-body mass in {', '.join(below)} "
            f"(M_m / M_RB - 1 = {np.round(margin, 4).tolist()}: an A(∞) < 0; the radiation model's "
            f"A(0) - A(∞) {np.diag(model.memory_added_mass).tolist()} exceeds the vessel's added mass: a "
            "model of another hull? set froude_scale, or leave the model to dpgw)"
        )
    lam_d = float(np.linalg.eigvalsh(model.D + model.D.T).min())
    if not lam_d > 0:
        problems.append(f"D - K(0) + (D - K(0))ᵀ is not positive definite (smallest eigenvalue {lam_d:.4g})")
    return Check(
        name="memory_model",
        inequality=(
            "M_RB + A(inf) = M - [A(0) - A(inf)] > 0, M_m,ii >= M_RB,ii and D - K(0) + (D - K(0))^T > 0"
        ),
        ok=not problems,
        detail="; ".join(problems) if problems else "inertia and damping positive definite",
        values={"min_eig_M": [lam_m], "min_eig_D_sym": [lam_d], "M_m_over_M_RB_minus_1": margin.tolist()},
    )


def _hermitian_min(K: NDArray[Any], extra: Array) -> tuple[NDArray[Any], float]:
    herm = 0.5 * (K + np.conj(K.transpose(0, 2, 1))) + 0.5 * (extra + extra.T)[None]
    lam = np.linalg.eigvalsh(herm)[:, 0]
    scale = float(np.max(np.real(np.diagonal(herm, axis1=1, axis2=2))))
    return lam, max(scale, 1e-300)


def check_radiation_passivity(radiation: RadiationStateSpace) -> Check:
    """K(jω) positive real: Herm K(jω) ⪰ 0 on `check_grid` (the fluid only takes energy from the hull)."""
    w = check_grid(radiation)
    lam, scale = _hermitian_min(radiation.frequency_response(w), np.zeros((3, 3)))
    k = int(np.argmin(lam))
    margin = float(lam[k] / scale)
    ok = margin >= -PASSIVITY_TOLERANCE
    return Check(
        name="radiation_passivity",
        inequality="Herm K(jw) >= 0 for all w (radiation subsystem passive)",
        ok=ok,
        detail=f"smallest eigenvalue of Herm K(jω) / peak damping = {margin:.3g} at ω = {w[k]:.4g} rad/s"
        + ("" if ok else ": the radiation model generates energy; identify it with passivity enforced"),
        values={"margin": [margin], "at_rad_s": [float(w[k])]},
    )


def check_velocity_passivity(model: MemoryModel) -> Check:
    """Herm[D_m + K(jω)] > 0 on `check_grid`: the velocity-error subsystem (M_m s + D_m + K(s))⁻¹ of the
    extended error system is strictly passive, as Fossen & Strand's proof needs of the velocity part."""
    w = np.concatenate([[0.0], check_grid(model.radiation)])
    lam, scale = _hermitian_min(model.radiation.frequency_response(w), model.D)
    k = int(np.argmin(lam))
    margin = float(lam[k] / scale)
    ok = margin > PASSIVITY_TOLERANCE
    return Check(
        name="velocity_passivity",
        inequality="Herm[D_m + K(jw)] > 0 for all w (velocity error subsystem strictly passive)",
        ok=ok,
        detail=f"smallest eigenvalue of Herm[D_m + K(jω)] / peak = {margin:.3g} at ω = {w[k]:.4g} rad/s"
        + ("" if ok else ": the extended error system is not passive (D - K(0) too small, or K not passive)"),
        values={"margin": [margin], "at_rad_s": [float(w[k])]},
    )


def check_gains(gains: MemoryGains) -> list[Check]:
    """Every check: rule (48), SPR (Proposition 1), the model, the radiation and velocity passivity."""
    return [
        check_tuning_rule(gains.passive),
        check_spr(gains.passive),
        check_model(gains.model),
        check_radiation_passivity(gains.model.radiation),
        check_velocity_passivity(gains.model),
    ]


def validate(gains: MemoryGains) -> None:
    """Raise `TuningError` naming the failed condition and the numbers."""
    for check in check_gains(gains):
        if not check.ok:
            raise TuningError(
                f"memory observer violates {check.inequality}: {check.detail}. "
                "Pass allow_unchecked=True (or --allow-unchecked) to run such gains for experiments."
            )


# --- linear analysis ------------------------------------------------------------------------------------


def n_state(model: MemoryModel) -> int:
    """Length of the state vector: the passive observer's 15 and the radiation states."""
    return N_STATE + model.radiation.n_states


def error_dynamics_matrix(gains: MemoryGains, psi: float = 0.0) -> Array:
    """Linearised extended error dynamics x̃' = (A - L C) x̃ at heading ψ, state [passive 15, ξ̃_r]."""
    model, pg = gains.model, gains.passive
    r = model.radiation
    n = n_state(model)
    vessel_like = _LowFrequency(model.M, model.D)
    A = np.zeros((n, n))
    A[:N_STATE, :N_STATE] = model_matrix(vessel_like, pg, psi)  # type: ignore[arg-type]
    Minv = model.Minv
    A[NU, NU] -= Minv @ r.Dr
    A[NU, N_STATE:] = -Minv @ r.Cr
    A[N_STATE:, NU] = r.Br
    A[N_STATE:, N_STATE:] = r.Ar
    L = np.zeros((n, 3))
    L[:N_STATE] = injection_matrix(vessel_like, pg, psi)  # type: ignore[arg-type]
    C = np.zeros((3, n))
    C[:, XI2] = np.eye(3)
    C[:, ETA] = np.eye(3)
    return A - L @ C


@dataclass(frozen=True)
class _LowFrequency:
    """Stand-in with the M, D (and Minv) the passive analysis functions read."""

    M: Array
    D: Array

    @property
    def Minv(self) -> Array:
        return np.asarray(np.linalg.inv(self.M))


def error_eigenvalues(gains: MemoryGains, psi: float = 0.0) -> NDArray[np.complex128]:
    ev = np.linalg.eigvals(error_dynamics_matrix(gains, psi)).astype(np.complex128)
    return ev[np.argsort(ev.real)[::-1]]


def slowest_error_rate(gains: MemoryGains, headings: int = 12) -> float:
    """Largest real part of the extended error eigenvalues over headings: the rate the tuning promises."""
    return max(
        float(error_eigenvalues(gains, psi)[0].real)
        for psi in np.linspace(-math.pi, math.pi, headings, endpoint=False)
    )


__all__ = [
    "DOF",
    "MemoryGains",
    "MemoryModel",
    "MemoryModelError",
    "builtin_radiation",
    "check_gains",
    "default_radiation",
    "error_dynamics_matrix",
    "fit_scale",
    "memory_gains",
    "memory_model",
    "memory_share",
    "own_radiation",
    "slowest_error_rate",
    "validate",
]
