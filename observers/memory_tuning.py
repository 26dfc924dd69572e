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
where the fluid memory acts. This also makes M_m = M_RB + A(∞) when the vessel file and the hydrodynamic
data agree, which is what (20) asks for.

**The radiation model** of the vessel's own hull (`observers.radiation.identify` on its A(ω), B(ω)) is
the right one. Without one, dpgw uses the built-in model of MSS's supply vessel (the model stored beside the
built-in vessel ``mss_supply``, ``observers/vessels/radiation/mss_supply.npz``, which the simulator's plant
reads too) Froude-scaled to the vessel's displacement (length scale λ = (m/m_supply)^⅓;
`RadiationStateSpace.froude_scaled`): a hull of a similar form, with its memory time scale and its
A(0) - A(∞) in proportion. ``froude_scale`` overrides λ.

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

import json
import math
from dataclasses import dataclass, replace
from functools import lru_cache
from importlib import resources
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
from observers.state import ETA, N_STATE, NU, XI2
from observers.vessel import VesselModel

Array = NDArray[np.float64]

PASSIVITY_TOLERANCE = 1e-9
"""Round-off allowance of the numerical passivity checks, relative to the largest damping on the grid."""


class MemoryModelError(TuningError):
    """A radiation model that cannot be combined with the vessel (the message says which matrix and why)."""


BUILTIN_RADIATION = "vessels/radiation/mss_supply.npz"
"""The built-in model, in the package: the one `dpgw radiation` identified for mss_supply (with its fit
report beside it, ``mss_supply.toml``), read by the plant and by this observer alike."""


@lru_cache(maxsize=1)
def builtin_radiation() -> RadiationStateSpace:
    """MSS's supply vessel, identified by dpgw from its ShipX data (17 states, passive): the 82.8 m,
    6362 t hull of the ShipX/VERES A(ω), B(ω), whose rigid-body mass the file records (``M_RB``)."""
    with (
        resources.as_file(resources.files("observers") / BUILTIN_RADIATION) as path,
        np.load(path, allow_pickle=False) as data,
    ):
        meta = json.loads(str(data["meta"]))
        m_rb = np.array(meta["M_RB"], dtype=float)
        return RadiationStateSpace(
            data["Ar"],
            data["Br"],
            data["Cr"],
            data["Dr"],
            data["A_inf"],
            source=f"MSS supply vessel ({m_rb[0, 0] / 1e3:.0f} t), ShipX A(ω), B(ω)",
            hydro_sha256=str(meta.get("hydro_sha256", "")),
            M_RB=m_rb,
        )


def froude_scale_for(vessel: VesselModel) -> float:
    """Length scale λ = (m_vessel / m_supply)^⅓ that carries the built-in model to ``vessel``'s mass."""
    m_rb = builtin_radiation().M_RB
    assert m_rb is not None  # the built-in file records it
    return float((vessel.mass_kg / m_rb[0, 0]) ** (1.0 / 3.0))


@dataclass(frozen=True)
class MemoryModel:
    """What (20) integrates: M_m = M_RB + A(∞) (3×3), D_m (3×3) and the radiation state space."""

    M: Array
    D: Array
    radiation: RadiationStateSpace

    @property
    def Minv(self) -> Array:
        return np.asarray(np.linalg.inv(self.M))

    @property
    def memory_added_mass(self) -> Array:
        """A(0) - A(∞): the added mass that the fluid memory supplies to slow motion (kg, kg·m, kg·m²)."""
        return self.radiation.zero_frequency_added_mass() - self.radiation.A_inf


def memory_model(
    vessel: VesselModel, radiation: RadiationStateSpace | None = None, froude_scale: float | None = None
) -> MemoryModel:
    """M_m = M - [A(0) - A(∞)] and D_m = D - K(0) for ``vessel`` with ``radiation`` (default: the built-in
    model Froude-scaled to the vessel, or by ``froude_scale``); refuses a combination that is not a ship."""
    if radiation is None:
        radiation = builtin_radiation().froude_scaled(
            froude_scale if froude_scale is not None else froude_scale_for(vessel)
        )
    elif froude_scale is not None:
        radiation = radiation.froude_scaled(froude_scale)
    ev = np.linalg.eigvals(radiation.Ar)
    if radiation.n_states == 0 or not np.all(ev.real < 0):
        raise MemoryModelError(
            f"radiation model: A_r must have every pole in the open left half-plane (largest real part "
            f"{ev.real.max() if len(ev) else float('nan'):.4g}); identify it with observers.radiation"
        )
    A_mem = radiation.zero_frequency_added_mass() - radiation.A_inf
    M = np.asarray(vessel.M - 0.5 * (A_mem + A_mem.T))
    D = np.asarray(vessel.D - radiation.static_gain())
    model = MemoryModel(M, D, radiation)
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
    """M_m = M_RB + A(∞) symmetric positive definite (it is the inertia (20) inverts), D_m + D_mᵀ > 0."""
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
    lam_d = float(np.linalg.eigvalsh(model.D + model.D.T).min())
    if not lam_d > 0:
        problems.append(f"D - K(0) + (D - K(0))ᵀ is not positive definite (smallest eigenvalue {lam_d:.4g})")
    return Check(
        name="memory_model",
        inequality="M_RB + A(inf) = M - [A(0) - A(inf)] > 0 and D - K(0) + (D - K(0))^T > 0",
        ok=not problems,
        detail="; ".join(problems) if problems else "inertia and damping positive definite",
        values={"min_eig_M": [lam_m], "min_eig_D_sym": [lam_d]},
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
    "error_dynamics_matrix",
    "memory_gains",
    "memory_model",
    "slowest_error_rate",
    "validate",
]
