"""Gains of the passive observer from physical tuning, and the checks that make them safe.

Fossen & Strand (1999), Sec. 5, with two of the paper's misprints corrected (said where they apply):

* Wave-filter gains, eqs (45)–(47) (the printed (45) is garbled; this form gives the paper's own (59))::

      k1i = -2 (ζni - ζi) ωci / ω0i,     k2i = 2 ω0i (ζni - ζi),     k3i = ωci

  K1 (6×3) = [diag(k1); diag(k2)], K2 = diag(k3). These shape the position-error transfer function
  h0ᵢ(s) of eq (42) into the notch filter h0dᵢ(s) of eq (44).
* Injection gains 𝒦 (K4, velocity, eq (25)) and Λ (K3, bias, eq (24)). The paper's values (60) are not in
  SI units for the M of (56): used literally they leave the velocity and bias loops open. dpgw
  therefore tunes them in physical terms and scales them with the vessel::

      K4ᵢᵢ = Mᵢᵢ · ωcᵢ · aᵢ        (aᵢ: velocity-injection rate, 1/s)
      K3ᵢᵢ = K4ᵢᵢ · ρᵢ              (ρᵢ = λᵢ/κᵢ: bias corner frequency, rad/s)

  Below ωc the position-error loop is ỹ ≈ J ν̃ / (s + ωc), so the injection adds K4/ωc = M·a of
  damping to the velocity-error dynamics: a velocity error decays at about Dᵢᵢ/Mᵢᵢ + aᵢ whatever the
  unit system or the size of the ship. γ of (24)–(25) is redundant with K3, K4 and is fixed at 1.
* Tuning rule (48) (Torsetnes' (53)): ``1/Tᵢ ≪ λᵢ/κᵢ < ω0ᵢ < ωcᵢ``; "≪" is checked as a factor of 10.
* Proposition 1 (SPR): hᵢ(s) = h_Bᵢ(s)·h0ᵢ(s), eqs (42)–(43), must have phase above −90° at all
  frequencies. **The paper says (48) suffices; it does not.** With the paper's own numbers (ζn = 1,
  ζ = 0.1, ωc = 1.1, ω0 = 0.8976, λ/κ = 0.1, T = 1000) the phase of hᵢ(jω) falls to −94.8° at
  0.69 rad/s: the lag of h_B (a PI-like corner at λ/κ) adds to the lag of the notch just below ω0. The
  phase depends only on the ratios to ω0; with the paper's ωc/ω0 it holds for λ/κ ≲ 0.045 ω0, so
  dpgw's default corner is ρ = 0.04 ω0, and the SPR check is done numerically, not inferred from (48).
* Velocity injection a = 0.12 ω0 by default: wave motion leaks into ν̂ roughly as a/ω0, and a DP
  controller's damping term passes ν̂ to the thrusters; 0.12 ω0 keeps the commanded thrust's wave-band
  content ≥ 20 dB below a controller fed the raw measurements (tests/test_station_keeping.py) while every
  built-in vessel's slowest error pole stays faster than −0.01 s⁻¹.
* **No slower than the loop it feeds** (``loop_bandwidth``). A ratio to ω0 ties the observer's LF speed to
  the sea's time scale, while a DP controller's bandwidth ωn is set in the vessel's (Froude-scaled with
  its length). Where the sea is long against the vessel the two part: the `hassani` case runs the paper's
  6.8 s sea on the 1:70 CyberShip II (18.9 in Froude time √(g/L)·Tp, against 4.1 for torsetnes_2004's
  11.5 s on the 76.2 m supply vessel), so a = 0.12 ω0 = 0.11 s⁻¹ leaves the velocity error decaying at
  0.19-0.32 s⁻¹ under a 0.55-0.78 rad/s loop: the controller acts on an estimate slower than itself (the
  separation a cascade of estimator and controller assumes). Fed by it, the model held its heading to a
  p95 of 5.5-6.6°, nearly all of it the estimate's error. So where a DP loop is known (the gateway's
  ``[control]``, `gateway.config`), a ratio-set a is held at ≥ ωnᵢ − Dᵢᵢ/Mᵢᵢ: the velocity error decays
  no slower than the loop's natural frequency. On every full-scale built-in scenario with its own sea
  the floor lies below 0.12 ω0 except snijders_2005's yaw (0.83 ωn: a 0.063 → 0.080 s⁻¹);
  docs/passive-observer.md has the figures.
* **The default follows the vessel** (`PassiveTuning.for_vessel`). The defaults above are a ship's: ω0 =
  2π/7 s, a North Sea DP day. A 1:λ model (`observers.froude`: CyberShip II is 1:70) sails in that sea
  made small by Froude's law, times ÷ √λ and frequencies × √λ, and its own LF dynamics (Dᵢᵢ/Mᵢᵢ) are
  √λ faster too. So a model's default is the ship's Froude-scaled field by field::

      ω0, ωc, a, ρ  (rad/s, 1/s)  →  × √λ          T (s)  →  ÷ √λ          ζ, ζn and the ratios: kept

  (for CyberShip II ω0 = 0.8976·√70 = 7.51 rad/s, a 0.84 s basin sea). With λ = 1 (every vessel of
  10 m or more without a ``model_scale``) the tuning is `PassiveTuning()` exactly. The ship's default on
  the model puts the notch (0.90 rad/s) and cut-off (1.1 rad/s) inside the model's LF band: measured on
  CyberShip II (tests/test_passive_model_scale.py), its LF estimate follows the model's slow motion
  (−5 dB at 0.5 rad/s, −19 dB at 1 rad/s), the rest goes to the WF estimate, and the slowest error
  pole is −0.011 s⁻¹ against −0.34 s⁻¹ scaled.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.froude import froude_scale, froude_scaled
from observers.kinematics import rotation
from observers.state import BIAS, ETA, N_STATE, NU, XI, XI1, XI2
from observers.vessel import VesselModel

Array = NDArray[np.float64]

PAPER_CUTOFF_RATIO = 1.1 / 0.8976
"""ωc/ω0 of Fossen & Strand (1999) Sec. 6: ωc = 1.1 rad/s for ω0 = 0.8976 rad/s (a 7.0 s wave period)."""

FREQUENCY_FIELDS = ("omega0", "omega_c", "velocity_injection", "bias_corner")
"""The `PassiveTuning` fields that are frequencies or rates (rad/s, 1/s): × √λ on a 1:λ model."""
TIME_FIELDS = ("bias_time_constant_s",)
"""The `PassiveTuning` fields that are times (s): ÷ √λ on a 1:λ model. The rest are ratios (kept)."""

TUNING_RULE_MARGIN = 10.0
"""How much larger λ/κ must be than 1/T for "1/T ≪ λ/κ" of rule (48)."""


class TuningError(ValueError):
    """Gains that violate the tuning rule (48) or the SPR condition of Proposition 1."""


def _vec3(value: ArrayLike, name: str) -> Array:
    a = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(a) | (np.isinf(a) & (a > 0))) or np.any(a <= 0):
        raise TuningError(f"tuning '{name}': must be positive (per DOF or one for all), got {a.tolist()}")
    return a


@dataclass(frozen=True)
class PassiveTuning:
    """Observer tuning in physical terms, per DOF (surge/north, sway/east, yaw) or one value for all.

    omega0:               dominating wave frequency ω0 (rad/s); see `from_wave_period`.
    zeta:                 relative damping ζ of the wave model (10).
    zeta_n:               notch damping ζn > ζ of the desired filter (44); ζ/ζn sets the notch depth.
    cutoff_ratio:         ωc/ω0 of the filter cut-off (44); default the paper's 1.1/0.8976.
    omega_c:              explicit ωc (rad/s), overrides cutoff_ratio.
    bias_time_constant_s: T of the bias model (7), (24); ``inf`` (the default) makes the bias a random
                          walk: no steady LF offset (see the field's comment).
    velocity_injection_ratio: a/ω0, where a (1/s) is the extra decay rate of the velocity error from 𝒦
                          (module docstring). Relative to ω0 because wave motion leaks into ν̂ — and
                          through a DP controller's damping into the thrust — in proportion to a/ω0.
    velocity_injection:   explicit a (1/s), overrides velocity_injection_ratio (and its damping floor).
    injection_damping_ratio: floor of the ratio-set a as a fraction of the vessel's own damping rate
                          Dᵢᵢ/Mᵢᵢ (a ≥ this · Dᵢᵢ/Mᵢᵢ); see the field's comment.
    bias_corner_ratio:    ρ/ω0, where ρ = λ/κ is the bias corner frequency (48).
    bias_corner:          explicit ρ = λ/κ (rad/s), overrides bias_corner_ratio.
    loop_bandwidth:       natural frequency ωn (rad/s) of the DP loop this observer's estimate feeds; a
                          ratio-set a is held at ≥ ωn − Dᵢᵢ/Mᵢᵢ (module docstring, "No slower than the
                          loop it feeds"). None (the default): no loop, no floor. The gateway's config
                          sets it from ``[control]``.
    """

    omega0: Any = 2 * math.pi / 7.0
    zeta: Any = 0.1
    zeta_n: Any = 1.0
    cutoff_ratio: Any = PAPER_CUTOFF_RATIO
    omega_c: Any = None
    # T = ∞ (a random-walk bias, as Torsetnes (31) and Hassani (10)), not (58)'s 1000 s: with a finite T
    # the bias estimate leaks, and holding it against the leak takes a steady innovation ỹ = b̂/(K3 T),
    # which the wave-filter states carry into a constant LF offset of about (1 + 2ζ(ζn − ζ)…) ỹ. Measured
    # (`hassani`, CyberShip II): LF heading error 0.27° with T = 1000 s, 0.029° with T = ∞; 0.83 → 0.32 cm
    # north. docs/passive-observer.md. (58) stays available: PassiveTuning(bias_time_constant_s=1000).
    bias_time_constant_s: Any = math.inf
    velocity_injection_ratio: Any = 0.12
    velocity_injection: Any = None
    # Below ωc the bias and velocity errors obey s² + (d + a)s + aρ = 0 per DOF (d = Dᵢᵢ/Mᵢᵢ), whose slow
    # root is ≈ aρ/(d + a): the bias is seen only through the velocity error it causes, b/D. Where the
    # vessel's own damping dwarfs a — osv.m's yaw, D66 = M66/1 s, against a = 0.11/s — the bias mode
    # slows to aρ/d (280 s), and ρ cannot rise past the SPR limit. Holding a ≥ 0.4 d keeps that root at
    # ≥ 0.29ρ (94 s on mss_osv, notch −20.4 dB); for every other built-in vessel at its default ω0 the
    # floor is below 0.12 ω0 and the gains are unchanged. docs/passive-observer.md.
    injection_damping_ratio: Any = 0.4
    bias_corner_ratio: Any = 0.04
    bias_corner: Any = None
    loop_bandwidth: Any = None

    @classmethod
    def from_wave_period(cls, period_s: ArrayLike, **kwargs: Any) -> PassiveTuning:
        """Tuning for a dominating (peak) wave period in seconds: ω0 = 2π/Tp."""
        return cls(omega0=2 * math.pi / np.asarray(period_s, dtype=float), **kwargs)

    def with_omega0(self, omega0: ArrayLike) -> PassiveTuning:
        return replace(self, omega0=omega0)

    @classmethod
    def for_vessel(cls, vessel: VesselModel, **given: Any) -> PassiveTuning:
        """The default tuning for ``vessel`` (module docstring, "The default follows the vessel"): the
        fields in ``given`` as given, every other field's default Froude-scaled to the vessel's λ
        (`observers.froude.froude_scale`). For a full-scale vessel (λ = 1) this is ``cls(**given)``."""
        defaults = {k: v for k, v in cls().__dict__.items() if k not in given}
        return cls(**froude_scaled_fields(defaults, froude_scale(vessel)), **given)


def froude_scaled_fields(values: Mapping[str, Any], scale: float) -> dict[str, Any]:
    """``values`` (some `PassiveTuning` fields) for a 1:``scale`` model: `FREQUENCY_FIELDS` × √λ,
    `TIME_FIELDS` ÷ √λ (∞ stays ∞), None and the dimensionless fields as they are. λ = 1 returns them
    untouched (the same objects: a ship's tuning is today's exactly)."""
    if scale == 1.0:
        return dict(values)
    out = dict(values)
    for key, value in values.items():
        if value is None or (key not in FREQUENCY_FIELDS and key not in TIME_FIELDS):
            continue
        scaled = np.asarray(
            froude_scaled(
                np.asarray(value, dtype=float), scale, "frequency" if key in FREQUENCY_FIELDS else "time"
            )
        )
        out[key] = float(scaled) if scaled.ndim == 0 else tuple(float(x) for x in scaled)
    return out


@dataclass(frozen=True)
class PassiveGains:
    """Numbers the observer (22)–(26) runs with, in SI units for one vessel.

    K1 (6×3): wave-state injection (22); K2 (3×3): position injection (23); K3 = Λ (3×3): bias injection
    (24); K4 = 𝒦 (3×3): velocity injection (25); T (3×3): bias time constants. omega0, zeta define Ω (11).
    Also kept: the physical values they came from (omega_c, zeta_n) for the checks.
    """

    omega0: Array
    zeta: Array
    zeta_n: Array
    omega_c: Array
    K1: Array
    K2: Array
    K3: Array
    K4: Array
    T: Array
    tuning: PassiveTuning = field(default_factory=PassiveTuning)

    @property
    def k1(self) -> Array:
        return np.diag(self.K1[:3])

    @property
    def k2(self) -> Array:
        return np.diag(self.K1[3:])

    @property
    def k3(self) -> Array:
        return np.diag(self.K2)

    @property
    def t_inv(self) -> Array:
        return 1.0 / np.diag(self.T)

    @property
    def bias_corner(self) -> Array:
        """λᵢ/κᵢ (rad/s)."""
        return np.diag(self.K3) / np.diag(self.K4)


def filter_gains(omega0: ArrayLike, zeta: ArrayLike, zeta_n: ArrayLike, omega_c: ArrayLike) -> Array:
    """k1, k2, k3 of eqs (45)–(47) ((45) corrected, module docstring), as a (3, n) array."""
    w0, z, zn, wc = (np.asarray(v, dtype=float) for v in (omega0, zeta, zeta_n, omega_c))
    k1 = -2.0 * (zn - z) * wc / w0
    k2 = 2.0 * w0 * (zn - z)
    k3 = wc * np.ones_like(k1)
    return np.stack([k1, k2, k3])


def injection_floor(vessel: VesselModel, tuning: PassiveTuning) -> Array:
    """The least ratio-set injection rate a (1/s) per DOF: b · Dᵢᵢ/Mᵢᵢ (``injection_damping_ratio`` b) and,
    with a ``loop_bandwidth`` ωn, ωnᵢ − Dᵢᵢ/Mᵢᵢ (the velocity error no slower than the loop)."""
    b = np.broadcast_to(np.asarray(tuning.injection_damping_ratio, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(b)) or np.any(b < 0):
        raise TuningError(
            "tuning 'injection_damping_ratio': must be zero or positive (per DOF or one for all), "
            f"got {b.tolist()}"
        )
    d = np.diag(vessel.D) / np.diag(vessel.M)
    floor = b * d
    if tuning.loop_bandwidth is not None:
        floor = np.maximum(floor, _vec3(tuning.loop_bandwidth, "loop_bandwidth") - d)
    return floor


def passive_gains(vessel: VesselModel, tuning: PassiveTuning | None = None) -> PassiveGains:
    """Gains of eqs (45)–(47) and the vessel-scaled injection gains for ``vessel``; without a ``tuning``
    the vessel's default (`PassiveTuning.for_vessel`: Froude-scaled on a model)."""
    tuning = tuning or PassiveTuning.for_vessel(vessel)
    w0 = _vec3(tuning.omega0, "omega0")
    zeta = _vec3(tuning.zeta, "zeta")
    zeta_n = _vec3(tuning.zeta_n, "zeta_n")
    wc = (
        _vec3(tuning.omega_c, "omega_c")
        if tuning.omega_c is not None
        else w0 * _vec3(tuning.cutoff_ratio, "cutoff_ratio")
    )
    T = _vec3(tuning.bias_time_constant_s, "bias_time_constant_s")
    a = (
        _vec3(tuning.velocity_injection, "velocity_injection")
        if tuning.velocity_injection is not None
        else np.maximum(
            w0 * _vec3(tuning.velocity_injection_ratio, "velocity_injection_ratio"),
            injection_floor(vessel, tuning),
        )
    )
    rho = (
        _vec3(tuning.bias_corner, "bias_corner")
        if tuning.bias_corner is not None
        else w0 * _vec3(tuning.bias_corner_ratio, "bias_corner_ratio")
    )
    k1, k2, k3 = filter_gains(w0, zeta, zeta_n, wc)
    K4 = np.diag(np.diag(vessel.M) * wc * a)
    K3 = K4 * rho
    return PassiveGains(
        omega0=w0,
        zeta=zeta,
        zeta_n=zeta_n,
        omega_c=wc,
        K1=np.vstack([np.diag(k1), np.diag(k2)]),
        K2=np.diag(k3),
        K3=K3,
        K4=K4,
        T=np.diag(T),
        tuning=tuning,
    )


# --- checks ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Check:
    """Result of one check: which inequality, per DOF, whether it holds, and the numbers."""

    name: str
    inequality: str
    ok: bool
    detail: str
    values: dict[str, list[float]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "inequality": self.inequality,
            "ok": self.ok,
            "detail": self.detail,
            "values": self.values,
        }


DOF = ("surge", "sway", "yaw")


def h_transfer(gains: PassiveGains, omega: Array) -> Array:
    """hᵢ(jω) = h_Bᵢ(jω)·h0ᵢ(jω) of Proposition 1, eqs (42)–(43), shape (3, len(omega)).

    Computed from the gains actually in use (eq (42)), not from the design target (44).
    """
    s = 1j * np.asarray(omega)[None, :]
    w0, z = gains.omega0[:, None], gains.zeta[:, None]
    k1, k2, k3 = gains.k1[:, None], gains.k2[:, None], gains.k3[:, None]
    num0 = s**2 + 2 * z * w0 * s + w0**2
    den0 = s**3 + (k2 + k3 + 2 * z * w0) * s**2 + (w0**2 + 2 * z * w0 * k3 - k1 * w0**2) * s + w0**2 * k3
    kappa = np.diag(gains.K4)[:, None]
    lam = np.diag(gains.K3)[:, None]
    tinv = gains.t_inv[:, None]
    hB = kappa + lam / (s + tinv)
    return hB * num0 / den0


def check_tuning_rule(gains: PassiveGains) -> Check:
    """Rule (48): 1/Tᵢ ≪ λᵢ/κᵢ < ω0ᵢ < ωcᵢ, with ζnᵢ > ζᵢ > 0 for the notch (44)."""
    rho, tinv, w0, wc = gains.bias_corner, gains.t_inv, gains.omega0, gains.omega_c
    failures = []
    for i, dof in enumerate(DOF):
        if not TUNING_RULE_MARGIN * tinv[i] <= rho[i]:
            failures.append(f"{dof}: 1/T = {tinv[i]:.4g} is not ≪ λ/κ = {rho[i]:.4g} (need a factor 10)")
        if not rho[i] < w0[i]:
            failures.append(f"{dof}: λ/κ = {rho[i]:.4g} is not < ω0 = {w0[i]:.4g}")
        if not w0[i] < wc[i]:
            failures.append(f"{dof}: ω0 = {w0[i]:.4g} is not < ωc = {wc[i]:.4g}")
        if not gains.zeta_n[i] > gains.zeta[i] > 0:
            failures.append(f"{dof}: ζn = {gains.zeta_n[i]:.4g} must exceed ζ = {gains.zeta[i]:.4g} > 0")
    return Check(
        name="tuning_rule",
        inequality="(48): 1/T_i << lambda_i/kappa_i < omega0_i < omega_c_i  (and zeta_n_i > zeta_i, (44))",
        ok=not failures,
        detail="; ".join(failures) if failures else "holds in every DOF",
        values={
            "1/T": tinv.tolist(),
            "lambda/kappa": rho.tolist(),
            "omega0": w0.tolist(),
            "omega_c": wc.tolist(),
        },
    )


def check_spr(gains: PassiveGains, points_per_decade: int = 400) -> Check:
    """Proposition 1: arg hᵢ(jω) > −90° for all ω (checked on 1e-6…1e4 rad/s, log-spaced, widened to a
    decade beyond the tuning's own corners: a wave period of years or of milliseconds, which no sea has,
    still gets its answer instead of an empty band)."""
    corners = np.concatenate([np.diag(gains.T) ** -1, gains.omega0, gains.omega_c])
    corners = corners[np.isfinite(corners) & (corners > 0)]
    lo = min(-6.0, math.floor(math.log10(corners.min())) - 1) if corners.size else -6.0
    hi = max(4.0, math.ceil(math.log10(corners.max())) + 2) if corners.size else 4.0
    omega = np.logspace(lo, hi, round(hi - lo) * points_per_decade + 1)
    phase = np.degrees(np.unwrap(np.angle(h_transfer(gains, omega)), axis=1))
    i_min = np.argmin(phase, axis=1)
    min_phase = phase[np.arange(3), i_min]
    at = omega[i_min]
    # h is strictly proper (relative degree 1), so its phase tends to -90° as ω → ∞ in any SPR tuning, and
    # with a random-walk bias (1/T = 0, the default) h_B's integrator takes it to -90° as ω → 0 as well: a
    # margin taken over all ω would read 0° for every tuning. The margin worth reporting is the one in the
    # band where the bias corner and the notch act, from λ/κ to 10·ωc.
    band = (omega >= gains.bias_corner.min()) & (omega <= 10 * gains.omega_c.max())
    if not band.any():
        band = omega <= 10 * gains.omega_c.max()
    in_band = phase[:, band]
    margin = float(in_band.min() + 90.0)
    margin_at = float(omega[band][np.unravel_index(np.argmin(in_band), in_band.shape)[1]])
    bad = [
        f"{dof}: phase of h(jω) = {min_phase[i]:.2f}° at ω = {at[i]:.4g} rad/s"
        for i, dof in enumerate(DOF)
        if not min_phase[i] > -90.0
    ]
    return Check(
        name="spr",
        inequality="Proposition 1: arg h_i(jw) > -90 deg for all w, h_i = h_B,i * h_0,i (42)-(43)",
        ok=not bad,
        detail="; ".join(bad) + " (lower λ/κ or raise ωc/ω0)"
        if bad
        else f"phase above -90° everywhere; margin {margin:.2f}° from λ/κ to 10·ωc "
        f"(at {margin_at:.4g} rad/s)",
        values={
            "min_phase_deg": min_phase.tolist(),
            "at_rad_s": at.tolist(),
            "margin_deg": [margin],
            "margin_at_rad_s": [margin_at],
        },
    )


def check_gains(gains: PassiveGains) -> list[Check]:
    return [check_tuning_rule(gains), check_spr(gains)]


def validate(gains: PassiveGains) -> None:
    """Raise `TuningError` naming the inequality if the tuning rule or the SPR condition fails."""
    for check in check_gains(gains):
        if not check.ok:
            raise TuningError(
                f"observer tuning violates {check.inequality}: {check.detail}. "
                "Pass allow_unchecked=True (or --allow-unchecked) to run such gains for experiments."
            )


# --- linear analysis ------------------------------------------------------------------------------------

# State order: `observers.state`, x = [ξ1 (3), ξ2 = η_w (3), η (3), b (3), ν (3)].


def _output_matrix() -> Array:
    """C0 of (21) in dpgw's state order: y = η + η_w."""
    C = np.zeros((3, N_STATE))
    C[:, XI2] = np.eye(3)
    C[:, ETA] = np.eye(3)
    return C


def model_matrix(vessel: VesselModel, gains: PassiveGains, psi: float) -> Array:
    """Matrix of the model (14)–(17) with ψ (J(y)) frozen: x' = A x + B τ, y = C0 x."""
    A = np.zeros((N_STATE, N_STATE))
    J = rotation(psi)
    Minv = vessel.Minv
    A[XI1, XI2] = np.eye(3)
    A[XI2, XI1] = -np.diag(gains.omega0**2)
    A[XI2, XI2] = -np.diag(2 * gains.zeta * gains.omega0)
    A[ETA, NU] = J
    A[BIAS, BIAS] = -np.diag(gains.t_inv)
    A[NU, NU] = -Minv @ vessel.D
    A[NU, BIAS] = Minv @ J.T
    return A


def injection_matrix(vessel: VesselModel, gains: PassiveGains, psi: float) -> Array:
    """L (15×3) of the observer x̂' = A x̂ + B τ + L ỹ, eqs (22)–(25) with γ = 1."""
    L = np.zeros((N_STATE, 3))
    L[XI] = gains.K1
    L[ETA] = gains.K2
    L[BIAS] = gains.K3
    L[NU] = vessel.Minv @ rotation(psi).T @ gains.K4
    return L


def error_dynamics_matrix(vessel: VesselModel, gains: PassiveGains, psi: float = 0.0) -> Array:
    """Linearised estimation-error dynamics (30)–(32): x̃' = (A − L C0) x̃ at heading ψ."""
    return model_matrix(vessel, gains, psi) - injection_matrix(vessel, gains, psi) @ _output_matrix()


def error_eigenvalues(vessel: VesselModel, gains: PassiveGains, psi: float = 0.0) -> NDArray[np.complex128]:
    ev = np.linalg.eigvals(error_dynamics_matrix(vessel, gains, psi)).astype(np.complex128)
    return ev[np.argsort(ev.real)[::-1]]


def slowest_error_mode(vessel: VesselModel, gains: PassiveGains, headings: int = 36) -> tuple[float, float]:
    """(rate, heading): the largest real part of the error eigenvalues over all headings (the slowest
    convergence; > 0: a mode that grows) and the heading ψ (rad) where it is."""
    return max(
        (float(error_eigenvalues(vessel, gains, psi)[0].real), float(psi))
        for psi in np.linspace(-math.pi, math.pi, headings, endpoint=False)
    )


def slowest_error_rate(vessel: VesselModel, gains: PassiveGains, headings: int = 36) -> float:
    """Largest real part of the error eigenvalues over all headings (the slowest convergence)."""
    return slowest_error_mode(vessel, gains, headings)[0]


def velocity_injection_rate(vessel: VesselModel, gains: PassiveGains) -> Array:
    """a per DOF (1/s): the velocity error's decay rate from the injection, 𝒦 = diag(M) ωc a
    (`passive_gains`)."""
    return np.asarray(np.diag(gains.K4) / (np.diag(vessel.M) * gains.omega_c), dtype=float)


def lf_response(vessel: VesselModel, gains: PassiveGains, omega: ArrayLike, psi: float = 0.0) -> Array:
    """|η̂ᵢ/yᵢ|(jω): gain from measured motion to the LF estimate, per DOF, shape (3, n)."""
    A = error_dynamics_matrix(vessel, gains, psi)
    L = injection_matrix(vessel, gains, psi)
    out = []
    for w in np.atleast_1d(np.asarray(omega, dtype=float)):
        H = np.linalg.solve(1j * w * np.eye(N_STATE) - A, L)[ETA]
        out.append(np.abs(np.diag(H)))
    return np.array(out).T


def check_stability(vessel: VesselModel, gains: PassiveGains, headings: int = 36) -> Check:
    """The linearised error dynamics (30)–(32) decay at every heading: max Re λ(A − L C0)(ψ) < 0.

    The paper proves this for a tuning that meets rule (48) and Proposition 1; a tuning that breaks them
    (allowed for experiments) can have a mode that grows. Such a mode must be called what it is, not shown
    as a slow one with a negative time constant."""
    worst, at = slowest_error_mode(vessel, gains, headings)
    return Check(
        name="stability",
        inequality="(30)-(32) linearised: max Re lambda(A - L C0)(psi) < 0 at every heading psi",
        ok=worst < 0.0,
        detail=(
            f"every error mode decays; the slowest with time constant {-1 / worst:.1f} s"
            if worst < 0.0
            else f"an error mode grows: Re λ = {worst:+.5f} 1/s at ψ = {math.degrees(at):.0f}° (the error "
            f"doubles every {math.log(2) / worst:.0f} s): the estimate diverges"
            if worst > 0.0
            else "an error mode does not decay (Re λ = 0): the estimate does not converge"
        ),
        values={"max_real_part_per_s": [worst], "at_heading_deg": [math.degrees(at)]},
    )


SLOW_MODE_S = 100.0
"""An error mode slower than this (time constant, s) gets advice: a DP observer that takes minutes to
forget an initial error is not ready when the vessel goes on DP."""

WEAK_NOTCH_DB = -10.0
"""A notch shallower than this at ω0 (the LF estimate keeping more than a third of the wave motion) gets a
note: the observer then hardly filters the waves, whatever its checks say."""


def tuning_advice(vessel: VesselModel, gains: PassiveGains) -> list[str]:
    """What to change in a tuning whose slowest error mode is slower than `SLOW_MODE_S` or whose notch is
    shallower than `WEAK_NOTCH_DB`, found by trying it, not by a rule of thumb: the slowest mode is not
    monotonic in the velocity injection a (raising a speeds up the velocity error but, past a point, slows
    the mode the bias and the notch share), so the advice names the a that was tried and what it gave.
    Candidates below the DP loop's floor (``loop_bandwidth``) are not offered. Empty: nothing to say (an
    unstable tuning is `check_stability`'s to report)."""
    notes: list[str] = []
    tuning = gains.tuning
    slowest = slowest_error_rate(vessel, gains)
    a = velocity_injection_rate(vessel, gains)
    if -1.0 / SLOW_MODE_S < slowest < 0.0:
        tried = [
            (slowest_error_rate(vessel, g), candidate)
            for candidate, g in _other_injections(vessel, tuning, a, (0.25, 0.5, 2.0, 4.0))
        ]
        better = [t for t in tried if t[0] < slowest * 1.1]
        if better:
            rate, best = min(better, key=lambda t: t[0])
            way = "lower" if best < a.max() else "higher"
            notes.append(
                f"slowest error mode {-1 / slowest:.0f} s (slower than {SLOW_MODE_S:.0f} s): a {way} "
                f"velocity injection, --velocity-injection {best:g}, gives {-1 / rate:.0f} s"
            )
        else:
            notes.append(
                f"slowest error mode {-1 / slowest:.0f} s (slower than {SLOW_MODE_S:.0f} s), and neither a "
                f"higher nor a lower velocity injection shortens it (tried ×0.25 to ×4): a higher "
                "--bias-corner-ratio or a shorter --bias-time would"
            )
    notch = notch_depth_db(vessel, gains)
    if notch.max() > WEAK_NOTCH_DB:
        verb = "amplifies" if notch.max() > 0.0 else "keeps"
        weak = (
            f"weak wave filtering: the LF estimate {verb} the wave motion at ω0 ({notch.max():+.1f} dB; "
            f"{WEAK_NOTCH_DB:.0f} dB or deeper filters it)"
        )
        notes.append(f"{weak}: {_weak_notch_cause(vessel, gains, a)}")
    return notes


def _other_injections(
    vessel: VesselModel, tuning: PassiveTuning, a: Array, factors: tuple[float, ...]
) -> Iterator[tuple[float, PassiveGains]]:
    """The tuning with the velocity injection a (one for all DOFs, as --velocity-injection takes it) at
    each of ``factors`` × its largest, to two figures, and the gains it gives: those whose gains pass
    `check_gains`, none below the DP loop's floor (``loop_bandwidth``: the injection replaces it)."""
    floor = float(injection_floor(vessel, tuning).max()) if tuning.loop_bandwidth is not None else 0.0
    for factor in factors:
        candidate = float(f"{factor * a.max():.2g}")
        if candidate < floor:
            continue
        try:
            g = passive_gains(vessel, replace(tuning, velocity_injection=candidate))
        except TuningError:
            continue
        if all(c.ok for c in check_gains(g)):
            yield candidate, g


def _weak_notch_cause(vessel: VesselModel, gains: PassiveGains, a: Array) -> str:
    """Why the notch of ``gains`` is shallow and what deepens it, found in this order: the ratio ζ/ζn,
    which sets the notch's depth (about 20·log10(ζ/ζn) dB; none, or a peak, at ζn ≤ ζ, which tuning rule
    (48) forbids); then the velocity injection a, tried lower (×0.5 down to ×0.02, the largest that
    filters is named; an a near or above ω0 fills the notch); else the ratio again. Before, the note
    always named a, also for ζn ≤ ζ with a at 1 % of ω0."""
    zeta, zeta_n = float(gains.zeta.max()), float(gains.zeta_n.min())
    ratio = f"ζ = {zeta:.3g}, ζn = {zeta_n:.3g} (depth about 20·log10(ζ/ζn) dB)"
    if zeta_n <= zeta:
        return f"ζn must be above ζ for a notch, and {ratio}: raise --zeta-n (default 1.0) or lower --zeta"
    for candidate, g in _other_injections(vessel, gains.tuning, a, (0.5, 0.25, 0.1, 0.05, 0.02)):
        depth = notch_depth_db(vessel, g).max()
        if depth <= WEAK_NOTCH_DB:
            return (
                f"the velocity injection a = {_per_dof(a)} 1/s fills the notch (ω0 = "
                f"{gains.omega0.max():.3g} rad/s): --velocity-injection {candidate:g} gives {depth:+.1f} dB "
                "(or lower the --loop-bandwidth that sets it)"
            )
    return f"{ratio}: a larger ζn or a smaller ζ deepens it"


def _per_dof(values: Array) -> str:
    """One number where the three DOFs agree, else surge,sway,yaw (as the CLI takes them)."""
    if np.allclose(values, values[0]):
        return f"{values[0]:.3g}"
    return ",".join(f"{v:.3g}" for v in values)


def notch_depth_db(vessel: VesselModel, gains: PassiveGains) -> Array:
    """Response of the LF estimate to wave-frequency motion at ω0, per DOF, in dB (negative = attenuated)."""
    depth = [20 * math.log10(lf_response(vessel, gains, [gains.omega0[i]])[i, 0]) for i in range(3)]
    return np.array(depth)
