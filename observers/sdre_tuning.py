"""Weights Q, R of the SDRE observer from physical tuning, the Riccati solution, and error-pole analysis.

Snijders, van der Woude & Westhuis (2005), Sec. 2.5 and 3.2, with the garbled printed matrices read as
the model requires (state order x = [η, ν, b, ξ], C = [I 0 0 Γ2], Γ2 = [0 I], Ω2 = [[0, I], [−Ω², −2ZΩ]],
Ω = diag(ω0ᵢ) of frequencies, not their squares, T = 0: random-walk bias)::

    A(ψ) = [[0, J(ψ), 0, 0], [0, −M⁻¹D, M⁻¹Jᵀ(ψ), 0], [0, 0, 0, 0], [0, 0, 0, Ω2]],  B = [0; M⁻¹; 0; 0]
    0 = A P + P Aᵀ − P Cᵀ R⁻¹ C P + Q,      K = P Cᵀ R⁻¹                                  (Sec. 3.2)

**Why the paper's weights are not used as numbers.** The paper's Q = blockdiag(1e-5·I9, I6), R = I3 are
intensities in SI units. For its ship (M₃₃ = 3.2e9 kg·m²) they make the bias error poles about
−1e-7 s⁻¹ (surge) and slower (yaw): the bias is practically never estimated — the same unit trap as
Fossen & Strand's injection gains. ``paper_weights`` keeps them for comparison; dpgw tunes in physical
terms instead, so that the same numbers work on a 1:70 model and on a 200 m ship:

* Measurement noise, R: ``position_sigma_m`` (N and E alike) and ``heading_sigma_rad``, the 1σ noise of
  one sample, turned into a continuous-time intensity by the sample period: Rᵢ = σᵢ² · ``sample_period_s``.
* Wave model, Q for ξ: the paper's model (Sec. 2.3) drives only ξ2 (Σ2 = [0; Σ]); its weight makes the
  stationary standard deviation of η_w equal ``wave_sigma_m`` (N, E) and ``wave_sigma_rad`` (heading):
  Q_ξ2,i = 4 ζᵢ ω0ᵢ σ_w,i², Q_ξ1 = 0.
* Low-frequency model, Q for η, ν, b: neglecting damping, one DOF is the chain b' = w_b, ν' = b/m + w_ν,
  η' = ν + w_η measured as y = η + v. Its steady Kalman error poles are the stable roots of
  (spectral factorisation)::

      −r s⁶ + q_η s⁴ − q_ν s² + q_b/m² = 0

  With s = ω_b p this is r ω_b⁶ (−p⁶ + α p⁴ − β p² + 1) for q_b = m² r ω_b⁶, q_ν = β r ω_b⁴, q_η = α r ω_b²:
  the pole pattern is set by the dimensionless α, β alone and scaled by the LF bandwidth ω_b (rad/s), for
  any vessel and any unit system (α = β = 0: a third-order Butterworth pattern at ω_b). ω_b is set
  relative to the wave frequency (``lf_bandwidth_ratio`` = ω_b/ω0; a wave filter needs ω_b well below
  ω0, and a DP controller needs it above its own bandwidth) or explicitly (``lf_bandwidth``). m is M₃₃
  for yaw and √(M₁₁M₂₂) for north and east: the bias is earth-fixed (it enters as Jᵀ(ψ)b), so its
  weight must be the same in N and E for the filter not to prefer a compass direction.

  The r in these weights is a reference, not the gyro's noise: the position noise for N and E, and for
  yaw the position noise seen at a lever ℓ (``yaw_lever_m``, default half the vessel's length),
  r_ψ = r_N/ℓ², so that yaw and sway uncertainty are weighed alike (a heading error δψ moves the bow by
  ℓ δψ). Taken from a good gyro instead, the yaw model looks nearly perfect, and through the sway–yaw
  coupling of M and D the filter then reads sway motion out of heading innovations: on the
  snijders_2005 case (seed 1) a 0.05° gyro raised the sway error from 2.1e-2 to 1.7e-1 m² that way
  (docs/sdre.md). R itself is the sensors' noise.

**One Riccati solution for every heading.** A depends on x̂ only through ψ̂. With S(ψ) =
blockdiag(J, I, J, J, J) (η, b, ξ1, ξ2 turn with the heading; ν is body-fixed), A(ψ) = S A(0) Sᵀ and
C Sᵀ = Jᵀ C whenever ω0, ζ, the wave weight, R and the bias/position weights are equal in N and E
(Ω commutes with J then). Then P(ψ) = S P(0) Sᵀ solves the Riccati equation at ψ, and K(ψ) = S K(0) Jᵀ(ψ):
one solution per ω0 serves every heading. Otherwise (unequal ω0 in surge and sway, say) the de-rotated
gain K̄(ψ) = Sᵀ(ψ) K(ψ) J(ψ) is tabulated over ψ ∈ [0, π) (turning by π is the diagonal J(π) = diag(−1,
−1, 1), which commutes with Ω, so K̄ has period π) and interpolated linearly; the error of that
interpolation is measured in tests/test_sdre.py and stated in docs/sdre.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_continuous_are

from observers.kinematics import rotation
from observers.vessel import VesselModel

Array = NDArray[np.float64]

# State order of Snijders et al.: x = [η, ν, b, ξ1, ξ2], ξ2 = η_w (the order A, B and C require).
ETA, NU, BIAS, XI1, XI2 = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)
N_STATES = 15

TABLE_SIZE = 180
"""Headings in [0, π) at which the de-rotated gain is tabulated when one solution cannot serve all (1°)."""


class SdreTuningError(ValueError):
    """A tuning that cannot give a stable observer; the message names the field and the reason."""


def _vec3(value: ArrayLike, name: str, allow_zero: bool = False) -> Array:
    a = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    bad = ~np.isfinite(a) | (a < 0 if allow_zero else a <= 0)
    if np.any(bad):
        need = "non-negative" if allow_zero else "positive"
        raise SdreTuningError(f"SDRE tuning '{name}': must be finite and {need} per DOF, got {a.tolist()}")
    return a


@dataclass(frozen=True)
class SdreTuning:
    """SDRE observer tuning in physical terms, per DOF (surge/north, sway/east, yaw) or one for all.

    omega0, zeta:        wave model Ω2 (rad/s, −); from the sea state like the passive observer's.
    position_sigma_m:    1σ noise of one position sample (N and E).
    heading_sigma_rad:   1σ noise of one heading sample.
    sample_period_s:     the measurement interval that turns σ² into an intensity (R = σ² Δt).
    wave_sigma_m:        expected standard deviation of the wave-frequency motion in N and E (m).
    wave_sigma_rad:      expected standard deviation of the wave-frequency heading motion (rad).
    lf_bandwidth_ratio:  ω_b/ω0, the bandwidth of the low-frequency estimate relative to the wave frequency.
    lf_bandwidth:        explicit ω_b (rad/s), overrides lf_bandwidth_ratio.
    velocity_weight:     β of the pole pattern (module docstring): velocity process noise q_ν = β r ω_b⁴.
    position_weight:     α: position process noise q_η = α r ω_b².
    yaw_lever_m:         ℓ of the yaw LF weights' reference r_ψ = r_position/ℓ² (default half the vessel's
                         length; module docstring).
    """

    omega0: Any = 2 * math.pi / 7.0
    zeta: Any = 0.1
    position_sigma_m: float = 0.5
    heading_sigma_rad: float = math.radians(0.2)
    sample_period_s: float = 1.0
    wave_sigma_m: float = 1.0
    wave_sigma_rad: float = math.radians(1.0)
    lf_bandwidth_ratio: Any = 0.2
    lf_bandwidth: Any = None
    velocity_weight: Any = 2.0
    position_weight: Any = 0.0
    yaw_lever_m: float | None = None

    def with_omega0(self, omega0: ArrayLike) -> SdreTuning:
        return replace(self, omega0=omega0)


@dataclass(frozen=True)
class SdreWeights:
    """Q (15×15) and R (3×3) of the Riccati equation, intensities in SI units, with the wave model."""

    omega0: Array
    zeta: Array
    Q: Array
    R: Array


def sdre_weights(vessel: VesselModel, tuning: SdreTuning | None = None) -> SdreWeights:
    """Q and R for ``vessel`` from the physical ``tuning`` (module docstring)."""
    tuning = tuning or SdreTuning()
    w0 = _vec3(tuning.omega0, "omega0")
    zeta = _vec3(tuning.zeta, "zeta")
    sig = _vec3(
        [tuning.position_sigma_m, tuning.position_sigma_m, tuning.heading_sigma_rad],
        "position_sigma_m, heading_sigma_rad",
    )
    dt = _vec3(tuning.sample_period_s, "sample_period_s")
    r = sig**2 * dt
    wave = _vec3(
        [tuning.wave_sigma_m, tuning.wave_sigma_m, tuning.wave_sigma_rad], "wave_sigma_m, wave_sigma_rad"
    )
    wb = (
        _vec3(tuning.lf_bandwidth, "lf_bandwidth")
        if tuning.lf_bandwidth is not None
        else w0 * _vec3(tuning.lf_bandwidth_ratio, "lf_bandwidth_ratio")
    )
    if np.any(wb >= w0):
        raise SdreTuningError(
            f"SDRE tuning 'lf_bandwidth': ω_b = {wb.tolist()} rad/s must stay below ω0 = {w0.tolist()} "
            "rad/s (a wave filter passes the low frequencies only)"
        )
    lever = vessel.length_m / 2 if tuning.yaw_lever_m is None else float(tuning.yaw_lever_m)
    if not (math.isfinite(lever) and lever > 0):
        raise SdreTuningError(f"SDRE tuning 'yaw_lever_m': must be a positive length, got {lever!r}")
    r_lf = r[0] * np.array([1.0, 1.0, 1.0 / lever**2])  # the LF weights' reference (module docstring)
    beta = _vec3(tuning.velocity_weight, "velocity_weight", allow_zero=True)
    alpha = _vec3(tuning.position_weight, "position_weight", allow_zero=True)
    M = vessel.M
    m = np.array([math.sqrt(M[0, 0] * M[1, 1])] * 2 + [M[2, 2]])
    Q = np.zeros((N_STATES, N_STATES))
    Q[ETA, ETA] = np.diag(alpha * r_lf * wb**2)
    Q[NU, NU] = np.diag(beta * r_lf * wb**4)
    Q[BIAS, BIAS] = np.diag(m**2 * r_lf * wb**6)
    Q[XI2, XI2] = np.diag(4 * zeta * w0 * wave**2)
    return SdreWeights(omega0=w0, zeta=zeta, Q=Q, R=np.diag(r))


def with_wave_frequency(weights: SdreWeights, omega0: ArrayLike) -> SdreWeights:
    """``weights`` for a new wave frequency ω0 with their Q and R kept: weights given as numbers (the
    paper's, say) are not functions of ω0, so a re-tune moves only the wave model Ω2."""
    return replace(weights, omega0=_vec3(omega0, "omega0"))


def paper_weights(omega0: ArrayLike, zeta: ArrayLike = 0.1) -> SdreWeights:
    """The paper's Q = blockdiag(1e-5·I9, I6), R = I3 (Sec. 4), taken as SI intensities."""
    Q = np.diag(np.r_[np.full(9, 1e-5), np.ones(6)])
    return SdreWeights(_vec3(omega0, "omega0"), _vec3(zeta, "zeta"), Q, np.eye(3))


# --- model matrices ---------------------------------------------------------------------------------------


def rotation_blocks(psi: float) -> Array:
    """S(ψ) = blockdiag(J, I, J, J, J): the heading turns η, b, ξ1, ξ2 (earth-fixed); ν is body-fixed."""
    J = rotation(psi)
    S = np.zeros((N_STATES, N_STATES))
    for block in (ETA, BIAS, XI1, XI2):
        S[block, block] = J
    S[NU, NU] = np.eye(3)
    return S


def wave_matrix(omega0: Array, zeta: Array) -> Array:
    """Ω2 = [[0, I], [−Ω², −2ZΩ]] with Ω = diag(ω0ᵢ): frequencies, not their squares."""
    return np.block([[np.zeros((3, 3)), np.eye(3)], [-np.diag(omega0**2), -np.diag(2 * zeta * omega0)]])


def system_matrix(vessel: VesselModel, omega0: Array, zeta: Array, psi: float) -> Array:
    """A(x̂) of (1), which depends on x̂ only through the heading ψ̂ (T = 0: random-walk bias)."""
    A = np.zeros((N_STATES, N_STATES))
    J = rotation(psi)
    Minv = vessel.Minv
    A[ETA, NU] = J
    A[NU, NU] = -Minv @ vessel.D
    A[NU, BIAS] = Minv @ J.T
    A[9:15, 9:15] = wave_matrix(omega0, zeta)
    return A


def input_matrix(vessel: VesselModel) -> Array:
    """B = [0; M⁻¹; 0; 0] of (1)."""
    B = np.zeros((N_STATES, 3))
    B[NU] = vessel.Minv
    return B


def output_matrix() -> Array:
    """C = [I 0 0 Γ2], Γ2 = [0 I]: y = η + η_w (the measured motion is LF plus wave)."""
    C = np.zeros((3, N_STATES))
    C[:, ETA] = np.eye(3)
    C[:, XI2] = np.eye(3)
    return C


# --- the Riccati equation ---------------------------------------------------------------------------------


def _scaling(weights: SdreWeights) -> Array:
    """Per-state scale T (x = T z) under which Q and R are of order one.

    In SI the states span ten orders of magnitude (metres against newton-metres); the solver's balancing
    and any residual check are honest only in scaled coordinates. ν and ξ1 may carry no weight: they are
    scaled as the states they feed (ν → η, ξ1 ↔ ξ2 through ω0).
    """
    d = np.sqrt(np.maximum(np.diag(weights.Q), 0.0))
    scale = np.where(d > 0, d, 1.0)
    for k in range(3):
        if d[3 + k] == 0:
            scale[3 + k] = math.sqrt(weights.R[k, k])
        if d[9 + k] == 0:
            scale[9 + k] = scale[12 + k] / weights.omega0[k]
    return np.asarray(scale)


def solve_riccati(vessel: VesselModel, weights: SdreWeights, psi: float) -> Array:
    """P of 0 = A P + P Aᵀ − P Cᵀ R⁻¹ C P + Q at heading ψ (the filter Riccati equation of Sec. 3.2).

    Solved as the control Riccati equation of the dual system (Aᵀ, Cᵀ) in scaled coordinates
    (`_scaling`), P = T P_z T.
    """
    A = system_matrix(vessel, weights.omega0, weights.zeta, psi)
    C = output_matrix()
    scale = _scaling(weights)
    Ti = 1.0 / scale
    Az = Ti[:, None] * A * scale[None, :]
    Cz = C * scale[None, :]
    Qz = Ti[:, None] * weights.Q * Ti[None, :]
    Pz = solve_continuous_are(Az.T, Cz.T, Qz, weights.R)
    P = scale[:, None] * Pz * scale[None, :]
    return np.asarray(0.5 * (P + P.T))


def riccati_residual(vessel: VesselModel, weights: SdreWeights, psi: float, P: Array) -> float:
    """‖A P + P Aᵀ − P Cᵀ R⁻¹ C P + Q‖ / (‖A P‖ + ‖P Aᵀ‖ + ‖P Cᵀ R⁻¹ C P‖ + ‖Q‖), Frobenius norms, in the
    scaled coordinates of `_scaling` (in SI the bias block alone would decide the norms)."""
    Ti = 1.0 / _scaling(weights)
    A = system_matrix(vessel, weights.omega0, weights.zeta, psi)
    C = output_matrix()
    Rinv = np.linalg.inv(weights.R)
    terms = [A @ P, P @ A.T, -P @ C.T @ Rinv @ C @ P, weights.Q]
    terms = [Ti[:, None] * t * Ti[None, :] for t in terms]
    res = np.linalg.norm(sum(terms))
    return float(res / sum(np.linalg.norm(t) for t in terms))


def direct_gain(vessel: VesselModel, weights: SdreWeights, psi: float) -> Array:
    """K(ψ) = P(ψ) Cᵀ R⁻¹ from a Riccati solution at ψ itself (slow: the definition, for checks)."""
    P = solve_riccati(vessel, weights, psi)
    return np.asarray(P @ output_matrix().T @ np.linalg.inv(weights.R))


def heading_invariant(weights: SdreWeights) -> bool:
    """True when one Riccati solution serves every heading (N and E alike in Ω2, Q and R)."""
    d = np.diag(weights.Q)
    same = [weights.omega0[:2], weights.zeta[:2], np.diag(weights.R)[:2]]
    same += [d[block][:2] for block in (ETA, BIAS, XI1, XI2)]
    offdiag = weights.Q - np.diag(d)
    return all(v[0] == v[1] for v in same) and not np.any(offdiag)


def gain_table(vessel: VesselModel, weights: SdreWeights, size: int = TABLE_SIZE) -> Array:
    """De-rotated gains K̄(ψₖ) = Sᵀ K(ψₖ) J(ψₖ), ψₖ = kπ/n, shape (n, 15, 3); n = 1 when invariant."""
    n = 1 if heading_invariant(weights) else size
    table = np.empty((n, N_STATES, 3))
    for k in range(n):
        psi = k * math.pi / n
        table[k] = rotation_blocks(psi).T @ direct_gain(vessel, weights, psi) @ rotation(psi)
    return table


def table_gain(table: Array, psi: float) -> Array:
    """K(ψ) = S(ψ) K̄(ψ) Jᵀ(ψ), K̄ interpolated linearly in the table of period π."""
    n = table.shape[0]
    if n == 1:
        Kbar = table[0]
    else:
        u = (psi % math.pi) / math.pi * n
        i0 = min(int(u), n - 1)
        f = u - i0
        Kbar = (1.0 - f) * table[i0] + f * table[(i0 + 1) % n]
    return np.asarray(rotation_blocks(psi) @ Kbar @ rotation(psi).T)


# --- error dynamics ---------------------------------------------------------------------------------------


def error_eigenvalues(
    vessel: VesselModel, weights: SdreWeights, psi: float = 0.0, table: Array | None = None
) -> NDArray[np.complex128]:
    """Eigenvalues of A(ψ) − K(ψ) C, the estimation-error dynamics frozen at ψ, slowest first."""
    K = direct_gain(vessel, weights, psi) if table is None else table_gain(table, psi)
    Acl = system_matrix(vessel, weights.omega0, weights.zeta, psi) - K @ output_matrix()
    ev = np.linalg.eigvals(Acl).astype(np.complex128)
    return ev[np.argsort(ev.real)[::-1]]


def slowest_error_rate(vessel: VesselModel, weights: SdreWeights, headings: int = 36) -> float:
    """Largest real part of the error eigenvalues over a grid of headings (the slowest convergence)."""
    table = gain_table(vessel, weights)
    return max(
        float(error_eigenvalues(vessel, weights, psi, table)[0].real)
        for psi in np.linspace(-math.pi, math.pi, headings, endpoint=False)
    )
