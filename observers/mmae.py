"""Multiple-model adaptive wave filter (MMAE) of Hassani, Pascoal, Aguiar & Athans, eqs (6)–(18).

The paper's printed (9), (13) and (14) have misprints; the forms below are the corrected ones (each checked
against (7)–(10)). The model, in vessel-parallel coordinates
η_p = Rᵀ(ψ) η (6), for one candidate peak frequency ω0 (the same ω0 in all three DOFs, as the paper)::

    ξ' = A_w(ω0) ξ + E_w w1,     A_w = [[0, I], [-Ω, -Λ]],  Ω = ω0² I,  Λ = 2ζω0 I,  E_w = [0; I]   (7)
    η_p' = ν                                                                                        (8)
    M ν' + D ν = τ + b_p + w2                                       ((9) as corrected)              (9)
    b_p' = w3                                                                                       (10)
    η_w = C_w ξ,  C_w = [0, I];      y = η_p + η_w + v                                        (11)–(12)

State x = [ξ1, ξ2 = η_w, η_p, b_p, ν] ∈ R¹⁵ (13), w = [w1; w2; w3] ∈ R⁹ (the print repeats w2)::

    A(ω0) = [[A_w, 0, 0, 0], [0, 0, 0, I], [0, 0, 0, 0], [0, 0, M⁻¹, -M⁻¹D]]   (sign lost in print)   (14)
    B = [0; 0; 0; M⁻¹],   G = [[E_w, 0, 0], [0, 0, 0], [0, 0, I], [0, M⁻¹, 0]],   C = [C_w, I, 0, 0]   (14)

Q = diag(Q1, Q2, Q3) in the order of w (G is not printed; it follows from (7)–(10)); defaults (A.2)
for CyberShip II, scaled for other vessels by `hassani_noise`. Q is a continuous-time intensity
(E{w(t)wᵀ(s)} = Q δ(t − s), Sec. 3); R is the covariance of one sample of v (σ² of the sensors: (A.2)'s
1e-4 m² is a 1 cm RTK fix; as a continuous intensity that is R·dt).

Bank of steady-state Kalman filters (17), one per candidate ω0ⁱ, in discrete time: zero-order hold of
A, B at the nominal interval ``dt``, Q_d by Van Loan's method, the discrete algebraic Riccati equation
solved once per candidate for the prior covariance Pᵢ, gain Kᵢ = Pᵢ Cᵀ Sᵢ⁻¹, innovation covariance
Sᵢ = C Pᵢ Cᵀ + R (the paper leaves S_i of (18) open; the innovation covariance is the natural choice).

Dynamic weights: the discrete-time equivalent of (18) with m_i = ½ rᵢᵀ Sᵢ⁻¹ rᵢ and β_i = 1/√det Sᵢ,
i.e. Bayes' rule pᵢ(k) ∝ βᵢ exp(−mᵢ) pᵢ(k−1), computed in the log domain, then projected onto
{Σ pᵢ = 1, pᵢ ≥ floor} so that a filter that lost can win again when the sea changes (the floor is dpgw's:
the paper's (18) has none; `WEIGHT_FLOOR`). Each sample is new information: the gateway gives this
observer each measurement once (`new_samples_only`), not a held fix again at every step. Blended estimate
(16) x̂ = Σ pᵢ x̂ᵢ and blended ω0 = Σ pᵢ ω0ⁱ. By default every measured DOF votes (the paper); with
``heading_in_weights=False`` only the position innovations do (their marginal likelihood): first-order
yaw is a poor witness of the sea's peak (its RAO grows as the wave slope, ∝ ω², in long waves), see
docs/mmae.md. The heading is filtered by every filter either way.

Vessel-parallel frame. The filters run in a frame whose axes are those of NED rotated by ψ_f, the
blended heading estimate of the previous sample. At each sample, before the prediction, the frame is
turned to the newest heading: the N/E parts of η_p and b_p of every filter are re-expressed exactly,
η_p ← Rᵀ(Δψ) η_p, b_p ← Rᵀ(Δψ) b_p (this is the ψ' S η_p term that (8) neglects); ν, and the wave
states ξ (first-order wave motion is a body-frame response), are body-frame quantities and are not
turned. The measurement enters as y_p = Rᵀ(ψ_f) y (N, E; heading as is) and leaves as
η̂ = R(ψ_f) η̂_p, b̂ = R(ψ_f) b̂_p (earth-fixed, like the passive observer's b), η̂_w = R(ψ_f) ξ̂2 (the
heading components are not rotated). Heading innovations are wrapped (ssa); the blended heading is
ψ_f + Σ pᵢ ssa(ψ̂ᵢ − ψ_f), so filters either side of ±π blend correctly.

Missing data and time. A position fix is N and E together (one NaN makes both missing). With a DOF
missing, the update uses the one-step optimal gain for the DOFs present from the same steady-state
prior Pᵢ (Kᵢ,v = Pᵢ C_vᵀ S_vv⁻¹, S_vv the sub-block of Sᵢ), and the weights use the marginal likelihood
of those DOFs; with nothing measured the filters only predict and the weights stay. An interval dt is
predicted by n = round(dt / dt_nom) exact steps of the nominal transition and the remainder
δ = dt − n·dt_nom (|δ| ≤ dt_nom/2) by a second-order Taylor step of the continuous model; the gains stay
those of dt_nom (set dt to the sensors' rate). A gap longer than ``max_gap_s`` restarts the filters
(weights kept) from the next complete measurement. Repeated or backward time: the sample is not used.

``observers._mmae_kernel`` is the compiled twin of the readable numpy reference at the end of this
module (`reference_run`); tests/test_mmae.py checks they agree to round-off. The LF output stage that dpgw
adds (the estimate given out with an identified LF process noise) is `observers.mmae_lf`. Full notes:
docs/mmae.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_discrete_are

from observers import _mmae_kernel as kernel
from observers import mmae_lf
from observers.base import (
    STATUS_DEAD_RECKONING,
    STATUS_INITIALIZING,
    STATUS_NAMES,
    STATUS_OK,
    ZERO3,
    Estimate,
    InitialState,
    ObserverBase,
    Run,
    batch_inputs,
)
from observers.kinematics import ssa_scalar
from observers.mmae_model import MASKS, continuous_model, discretize, filter_tables
from observers.settling import settle_time_from_time_constant
from observers.state import BIAS, ETA, I_PSI, N_STATE, NU, XI2, StateView
from observers.vessel import VesselModel
from observers.wave_frequency import WaveFrequencyConfig, WaveFrequencyEstimator

Array = NDArray[np.float64]

HASSANI_CANDIDATES = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)
"""The paper's eight candidate peak frequencies (rad/s), Sec. 4."""

Q1_CYBERSHIP2 = np.diag([0.09, 0.09, 1e-4])
"""(A.2) Q1: intensity of w1, the wave-model noise (m²/s, m²/s, rad²/s)."""
Q2_CYBERSHIP2 = np.diag([1e-3, 1e-3, 1e-4])
"""(A.2) Q2: intensity of w2, the force noise of (9) (N²·s, N²·s, (N·m)²·s)."""
Q3_CYBERSHIP2 = np.diag([1e-3, 1e-3, 1e-4])
"""(A.2) Q3: intensity of w3, the bias random walk of (10) (N²/s, N²/s, (N·m)²/s)."""
R_CYBERSHIP2 = np.diag([1e-4, 1e-4, 1e-8])
"""(A.2) R: measurement noise (m², m², rad²), used as the covariance of one sample."""
CYBERSHIP2_LENGTH_M = 1.255
CYBERSHIP2_M_DIAG = np.array([25.8, 33.8, 2.76])
"""diag M of (A.1): the inertia that (A.2)'s force noises Q2, Q3 belong to."""

WEIGHT_FLOOR = 1e-8
"""Least weight of any filter (dpgw's; the paper's weights (18) have none). A filter that lost needs
ln(0.9/floor) ≈ 18 nats of evidence to win again: enough that a few wave periods of chance do not move the
bank off the right filter (1e-3, 7 nats, let the weights leave it every minute or two), few enough that a
changed sea wins within minutes (docs/mmae.md)."""

WAVE_STD_FACTOR = 0.7
"""Identified wave-model σ = this × the measured wave-band σ: the variance the likelihood itself prefers for
a second-order model of a JONSWAP motion spectrum (docs/mmae.md, "Tuning for identification")."""
IDENTIFICATION_MEDIAN_OF = 5
"""The σ's the bank is designed with are the median of the last five windows' (each DOF on its own)."""
REDESIGN_RATIO = 1.3
"""The bank is designed again when an identified σ moves outside [1/1.3, 1.3] × the one it was made with."""


def identification_config(candidates: Sequence[float]) -> WaveFrequencyConfig:
    """The spectral window for noise identification, in periods of the slowest candidate (T = 2π/ω_min):
    Welch segments of 3 T over a 6 T window, every T, the first after one T; the band the candidates
    span, widened by 1.5 either side. Segments of 3 T put bins every ω_min/3, so the band's lower edge
    (ω_min/1.5) lies two bins up, past the Hann main lobe of what the quadratic detrend leaves of the LF
    motion; with 2 T it lay 1.3 bins up, inside it, and a sea at the slowest candidates could not be told
    from the LF motion (`observers.wave_frequency.wave_band_power`)."""
    c = np.asarray(candidates, dtype=float)
    period = 2.0 * math.pi / float(c.min())
    return WaveFrequencyConfig(
        window_s=6.0 * period,
        update_period_s=period,
        omega_min=float(c.min()) / 1.5,
        omega_max=float(c.max()) * 1.5,
        segment_s=3.0 * period,
        min_span_s=period,
        min_snr=0.0,
        median_of=1,
    )


@dataclass(frozen=True)
class NoiseIdentification:
    """What the measurements said at time t: sensor noise σ and wave-motion σ per DOF (NaN: not seen)."""

    t: float
    measurement_sigma: tuple[float, float, float]
    wave_sigma: tuple[float, float, float]
    redesigned: bool


def hassani_noise(vessel: VesselModel) -> tuple[Array, Array]:
    """(Q, R) of (A.2) for CyberShip II, scaled to ``vessel`` (9×9 intensity, 3×3 per-sample covariance).

    Froude scaling with the length ratio λ = L / 1.255 m (time ∝ √λ) and, for the force noises, the
    vessel's own inertia per DOF (rᵢ = Mᵢᵢ / Mᵢᵢ of (A.1)), so that w2/M and w3/M — the accelerations
    and jerks the noise stands for — scale like Froude accelerations (∝ λ⁰; angular ∝ λ⁻¹) whatever the
    hull's fullness::

        Q1 (m²/s; rad²/s)              × λ^1.5;            yaw × λ^-0.5
        Q2 (N²·s; (N·m)²·s)            × r² λ^0.5;         yaw × r² λ^-1.5
        Q3 (N²/s; (N·m)²/s)            × r² λ^-0.5;        yaw × r² λ^-2.5
        R  (m²; rad²) per sample       × λ²;               heading × 1

    For a geometrically similar hull (r = λ³ in surge and sway, λ⁵ in yaw) this is plain Froude
    scaling. CyberShip II itself gets (A.2) exactly. Note that Q1 is a sea state, not a vessel
    property: (A.2)'s Q1 = 0.09 m²/s is a wave motion of σ = 0.5 m at ω0 = 0.9 rad/s and ζ = 0.1
    (0.32 m at the default ζ = 0.25); see `wave_std` of
    `MMAEObserver` to set it from the expected wave motion instead.
    """
    lam = vessel.length_m / CYBERSHIP2_LENGTH_M
    r2 = (np.diag(vessel.M) / CYBERSHIP2_M_DIAG) ** 2
    q1 = np.diag(Q1_CYBERSHIP2) * np.array([lam**1.5, lam**1.5, lam**-0.5])
    q2 = np.diag(Q2_CYBERSHIP2) * r2 * np.array([lam**0.5, lam**0.5, lam**-1.5])
    q3 = np.diag(Q3_CYBERSHIP2) * r2 * np.array([lam**-0.5, lam**-0.5, lam**-2.5])
    R = R_CYBERSHIP2 * np.diag([lam**2, lam**2, 1.0])
    return np.diag(np.concatenate([q1, q2, q3])), np.asarray(R, dtype=float)


@dataclass(frozen=True, eq=False)
class MMAEBank:
    """The designed bank: one steady-state Kalman filter per candidate ω0 (arrays the kernel reads).

    ``A`` (N, 15, 15), ``B`` (15, 3): continuous model; ``Phi`` (N, 15, 15), ``Gam`` (15, 3): ZOH at
    ``dt``; ``Q`` (9, 9) intensity of w, ``R`` (3, 3) per-sample covariance; ``P`` (N, 15, 15)
    steady-state prior covariance; ``S`` (N, 3, 3) innovation covariance; per mask m (see `MASKS`):
    ``K`` (N, 4, 15, 3) gains, ``Sinv`` (N, 4, 3, 3) inverse of the measured sub-block of S (zeros
    elsewhere) and ``logdet`` (N, 4) its log-determinant.
    """

    candidates: Array
    zeta: float
    dt: float
    Q: Array
    R: Array
    A: Array
    B: Array
    C: Array
    Phi: Array
    Gam: Array
    P: Array
    S: Array
    K: Array
    Sinv: Array
    logdet: Array

    @property
    def n(self) -> int:
        return int(self.candidates.size)


def reference_frequency(candidates: ArrayLike) -> float:
    """ω̄, the geometric mean of the candidates (rad/s): where `wave_std` sets the wave-model variance."""
    return float(np.exp(np.mean(np.log(np.asarray(candidates, dtype=float)))))


def _matrix(value: ArrayLike, n: int, name: str) -> Array:
    a = np.asarray(value, dtype=float)
    if a.shape == (n,):
        a = np.diag(a)
    if a.shape != (n, n) or not np.all(np.isfinite(a)):
        raise ValueError(
            f"{name} must be a finite {n}×{n} matrix or {n} diagonal values, got shape {a.shape}"
        )
    if not np.allclose(a, a.T, rtol=1e-12, atol=0.0):
        raise ValueError(f"{name} must be symmetric")
    return a


def design_bank(
    vessel: VesselModel,
    candidates: Sequence[float] = HASSANI_CANDIDATES,
    zeta: float = 0.25,
    Q: ArrayLike | None = None,
    R: ArrayLike | None = None,
    dt: float = 0.1,
    wave_std: ArrayLike | None = None,
) -> MMAEBank:
    """Discretise (14) per candidate, solve the DARE, and tabulate gains and likelihood terms.

    ``zeta``: ζ of the wave model (7); 0.25 by default. Hassani et al. leave ζ a symbol (Λ = diag 2ζᵢω0ᵢ);
    the usual 0.1 (Fossen & Strand (1999) Sec. 6; Torsetnes et al. (2004) for JONSWAP) puts the bank's
    likelihood peak 5 % above a JONSWAP sea's peak (docs/mmae.md).

    ``Q``: 9×9 (or 9 diagonal values) intensity of w = [w1; w2; w3]; default `hassani_noise`.
    ``R``: 3×3 (or 3 diagonal values) covariance of one measurement sample; default `hassani_noise`.
    ``wave_std``: expected standard deviation σ of the wave motion [N m, E m, ψ rad] (e.g. from the
    forecast sea state through the vessel's RAOs). If given, it replaces Q1 by 4ζω̄ diag(σ²), ω̄ the
    geometric mean of the candidates: one Q1 for the whole bank, as in the paper, such that the wave
    model (7) at ω̄ has the stationary variance σ² (Var ξ2 = Q1/(4ζω0)); candidate i expects σ² ω̄/ω0ⁱ.
    (Giving every candidate the same variance σ² instead makes the identification fragile: with σ 40 %
    too high the bank settles two candidates low; see docs/mmae.md.)
    """
    cand = np.asarray(candidates, dtype=float).ravel()
    if cand.size < 1 or not np.all(np.isfinite(cand)) or np.any(cand <= 0):
        raise ValueError(f"candidates must be positive finite frequencies (rad/s), got {candidates!r}")
    if np.unique(cand).size != cand.size:
        raise ValueError(f"candidates must be distinct, got {candidates!r}")
    if not (math.isfinite(zeta) and zeta > 0):
        raise ValueError(f"zeta must be a positive number, got {zeta!r}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    Q0, R0 = hassani_noise(vessel)
    Qm = Q0 if Q is None else _matrix(Q, 9, "Q")
    Rm = R0 if R is None else _matrix(R, 3, "R")
    if np.linalg.eigvalsh(Qm).min() < -1e-12 * max(1.0, float(np.abs(Qm).max())):
        raise ValueError("Q must be positive semi-definite")
    if np.linalg.eigvalsh(Rm).min() <= 0:
        raise ValueError("R must be positive definite")
    if wave_std is not None:
        sigma = np.broadcast_to(np.asarray(wave_std, dtype=float), (3,))
        if not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
            raise ValueError(f"wave_std must be three positive numbers (m, m, rad), got {wave_std!r}")
        Qm = Qm.copy()
        Qm[:3, :3] = np.diag(4.0 * zeta * reference_frequency(cand) * sigma**2)
    n = cand.size
    A_all = np.empty((n, N_STATE, N_STATE))
    Phi_all = np.empty((n, N_STATE, N_STATE))
    P_all = np.empty((n, N_STATE, N_STATE))
    S_all = np.empty((n, 3, 3))
    K_all = np.zeros((n, 4, N_STATE, 3))
    Sinv_all = np.zeros((n, 4, 3, 3))
    logdet_all = np.zeros((n, 4))
    B = Gam = C = np.zeros(0)
    for i, w0 in enumerate(cand):
        A, B, G, C = continuous_model(vessel, float(w0), zeta)
        Phi, Gam_i, Qd = discretize(A, B, G, Qm, dt)
        # A is block-diagonal in (ξ) and (η_p, b_p, ν); so is Φ (the kernel multiplies the blocks only)
        assert np.abs(Phi[:6, 6:]).max() <= 1e-12 and np.abs(Phi[6:, :6]).max() <= 1e-12
        Phi[:6, 6:] = 0.0
        Phi[6:, :6] = 0.0
        P = solve_discrete_are(Phi.T, C.T, Qd, Rm)
        P, S = filter_tables(P, C, Rm, K_all[i], Sinv_all[i], logdet_all[i])
        A_all[i], Phi_all[i], P_all[i], S_all[i] = A, Phi, P, S
        if i == 0:
            Gam = Gam_i
        elif not np.allclose(Gam_i, Gam, rtol=1e-12, atol=0.0):  # B acts on the LF states only
            raise AssertionError("Γ must not depend on ω0")
    return MMAEBank(
        candidates=cand,
        zeta=float(zeta),
        dt=float(dt),
        Q=Qm,
        R=Rm,
        A=np.ascontiguousarray(A_all),
        B=np.ascontiguousarray(B),
        C=C,
        Phi=np.ascontiguousarray(Phi_all),
        Gam=np.ascontiguousarray(Gam),
        P=P_all,
        S=S_all,
        K=np.ascontiguousarray(K_all),
        Sinv=np.ascontiguousarray(Sinv_all),
        logdet=np.ascontiguousarray(logdet_all),
    )


def _new_only(Y: Array, last: Array) -> Array:
    """Rows of Y (n, 3) with a value repeated exactly from the row before (the first row: from ``last``)
    set to NaN — the position N, E as a pair, the heading alone — for the noise identification: a
    gateway holds a 2 Hz fix between the 10 Hz headings, and held values would read as a noise-free
    sensor. (The filters still get every sample as given: they initialise on the first complete one.)"""
    prev = np.vstack([last.reshape(1, 3), Y[:-1]])
    out = Y.copy()
    pos = (Y[:, 0] == prev[:, 0]) & (Y[:, 1] == prev[:, 1])
    out[pos, 0:2] = np.nan
    out[Y[:, 2] == prev[:, 2], 2] = np.nan
    return out


def _new_only_one(y: Array, last: Array) -> Array:
    """`_new_only` for one sample (per-sample use in `step`: plain comparisons, no array building; the
    step-vs-run agreement test checks both give the same)."""
    out = y.copy()
    if y[0] == last[0] and y[1] == last[1]:
        out[0] = out[1] = math.nan
    if y[2] == last[2]:
        out[2] = math.nan
    return out


def _median_finite(rows: list[Array]) -> Array:
    """Per DOF, the median of the finite values of ``rows`` (NaN where there is none)."""
    out = np.full(3, math.nan)
    for i in range(3):
        v = sorted(float(r[i]) for r in rows if math.isfinite(r[i]))
        m = len(v)
        if m:
            out[i] = v[m // 2] if m % 2 else 0.5 * (v[m // 2 - 1] + v[m // 2])
    return out


def _f3(v: Array) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def _clean3(v: tuple[float, float, float]) -> list[float | None]:
    return [x if math.isfinite(x) else None for x in v]


class MMAEObserver(ObserverBase):
    """Hassani et al.'s MMAE wave filter for any `VesselModel`; the observer interface of `observers`.

    Model, per candidate ω0ⁱ (the module docstring has it in full): the wave model (7) driving η_w, and
    η_p' = ν, M ν' + D ν = τ + b_p + w2, b_p' = w3 in vessel-parallel axes; y = η_p + η_w + v (11)–(12).
    State per filter x = [ξ1, ξ2 = η_w, η_p, b_p, ν] (`observers.state`), in the frame of heading
    `frame_heading`; ``state`` is the blended one (16). `predict` runs the filters' prediction alone (the
    weights stay); `step` predicts, then updates every filter and the weights (17)–(18) with y.

    ``step(t, y, tau)`` for live use, ``run(t, y, tau)`` over arrays: the same compiled kernel, the same
    numbers. y = [N, E, ψ] (m, m, rad; NaN = missing), τ = [X, Y, N] (N, N, N·m, body frame) held since
    the previous sample. Output η̂, ν̂, b̂ (earth-fixed), η̂_w of the blended estimate (16).
    `Run.extras`: ``"weights"`` (n, N), the weights after each sample.

    ``candidates`` ω0ⁱ (rad/s), ``zeta`` of the wave model (7), ``Q``/``R``/``wave_std`` see
    `design_bank`, ``dt`` the nominal sample interval (s), ``weight_floor`` the least weight of any
    filter (0 ≤ floor < 1/N), ``warmup_s`` how long after the first measurement the weights stay
    uniform (default 0: measured to delay identification), ``max_gap_s`` the longest gap bridged by
    prediction, ``heading_in_weights`` whether the heading innovation votes in the weights.

    ``identify_noise`` (default: whenever R or the wave model is not given): the sensor noise σ (robust
    spread of second differences) and the wave-motion σ (Welch power above the noise floor, from the end of
    the LF motion's tail: `observers.wave_frequency.wave_band_power`) are measured over a sliding window of
    six periods of the slowest candidate (segments of three), every period; the bank is designed again
    with the median of the last five windows, R = σ_n², wave_std = 0.7·σ_wave, when either moves by more
    than 30 % (filter states and weights kept). The weights start moving at the first identification,
    about one slowest period after the first sample. Hassani's (A.2) Q and R, the fallback before that, do not
    identify real seas (docs/mmae.md). The default ζ is 0.25, not the usual 0.1 (Hassani et al. give no
    value), for the same reason.

    ``lf_output`` (default True; it applies when the noise is identified and Q is not given): the LF
    output stage, `observers.mmae_lf` — the bank keeps (A.2)'s LF noise Q2, Q3 and identifies ω0 as above;
    the estimate given out comes, per DOF where the data show slow LF motion, from one filter of the
    winning wave model with Q2, Q3 scaled down (chosen from the LF residual), while the winner holds ≥ 0.9
    of the weight. With (A.2)'s LF noise beside a calm identified sea the blend does not notch (its yaw
    estimate is the gyro's signal). ``lf_output=False`` gives the paper's blend (16). `state` and
    `filter_states` stay the bank's.
    """

    new_samples_only = True
    """Each measurement once: every sample updates the filters and the weights as new information (a held
    fix given again at the step rate would count one measurement several times; `ObserverBase`)."""

    def __init__(
        self,
        vessel: VesselModel,
        *,
        candidates: Sequence[float] = HASSANI_CANDIDATES,
        zeta: float = 0.25,
        Q: ArrayLike | None = None,
        R: ArrayLike | None = None,
        dt: float = 0.1,
        weight_floor: float = WEIGHT_FLOOR,
        wave_std: ArrayLike | None = None,
        warmup_s: float = 0.0,
        max_gap_s: float = 60.0,
        heading_in_weights: bool = True,
        identify_noise: bool | None = None,
        lf_output: bool = True,
    ) -> None:
        self.vessel = vessel
        self.bank = self._initial_bank = design_bank(vessel, candidates, zeta, Q, R, dt, wave_std)
        self._design_args = (tuple(float(c) for c in candidates), float(zeta), Q, R, float(dt), wave_std)
        # Identify what was not given: R unless R is given, the wave model unless Q or wave_std is.
        self._fixed_R = R is not None
        self._fixed_Q1 = Q is not None or wave_std is not None
        self.identify_noise = (
            not (self._fixed_R and self._fixed_Q1) if identify_noise is None else bool(identify_noise)
        )
        self.identified: NoiseIdentification | None = None
        self._design_sigma: tuple[Array, Array] | None = None  # (measurement σ, wave σ) of the bank in use
        # the LF output stage: Q2, Q3 identified for the estimate given out (`observers.mmae_lf`), unless
        # switched off, whenever the noise is identified and Q is not given
        self.lf_output = bool(lf_output) and self.identify_noise and Q is None
        self.lf = mmae_lf.LFOutputStage(vessel, hassani_noise(vessel)[0])
        self.noise_estimator = WaveFrequencyEstimator(identification_config(candidates))
        n = self.bank.n
        self.weight_floor = float(weight_floor)
        if not (0.0 <= self.weight_floor < 1.0 / n):
            raise ValueError(f"weight_floor must be within [0, 1/{n}), got {weight_floor!r}")
        self.warmup_s = float(warmup_s)
        self.max_gap_s = float(max_gap_s)
        if not (math.isfinite(self.warmup_s) and self.warmup_s >= 0):
            raise ValueError(f"warmup_s must be ≥ 0 s, got {warmup_s!r}")
        if not (self.max_gap_s > 0):
            raise ValueError(f"max_gap_s must be positive, got {max_gap_s!r}")
        self.heading_in_weights = bool(heading_in_weights)
        self._settle_s: float | None = None  # `settle_time_s`, once asked for
        self._params = np.zeros(kernel.N_PARAMS)
        self._params[kernel.PARAM_DT] = self.bank.dt
        self._params[kernel.PARAM_WEIGHT_FLOOR] = self.weight_floor
        self._params[kernel.PARAM_WARMUP_S] = self.warmup_s
        self._params[kernel.PARAM_MAX_GAP_S] = self.max_gap_s
        self._params[kernel.PARAM_HEADING_VOTES] = float(self.heading_in_weights)
        self.reset()  # (when identifying, the weights wait for the first identification: warm-up ∞)

    @classmethod
    def from_params(
        cls,
        vessel: VesselModel,
        tuning: Any,
        params: dict[str, Any],
        *,
        allow_unchecked: bool = False,
    ) -> MMAEObserver:
        """The observer `observers.factory` builds by name. The passive tuning and ``allow_unchecked`` do not
        apply: the bank is designed from its own noise settings. ``measurement_sigma`` (m, m, rad per sample;
        one or per DOF) sets R = diag(σ²): Hassani's (A.2) R is far from real gyros."""
        params = dict(params)
        if "candidates" in params:
            params["candidates"] = tuple(float(c) for c in params["candidates"])
        if "measurement_sigma" in params:
            sigma = np.broadcast_to(np.asarray(params.pop("measurement_sigma"), dtype=float), (3,))
            params["R"] = np.diag(sigma**2)
        return cls(vessel, **params)

    def reset(self) -> None:
        """Back to uninitialised, uniform weights (and, when identifying, the initial bank and no noise
        estimate)."""
        if self.identify_noise:
            self.bank = self._initial_bank
            self.noise_estimator.reset()
            self.identified = None
            self._design_sigma = None
            self._history: list[tuple[Array, Array]] = []
            self._params[kernel.PARAM_WARMUP_S] = math.inf
        self._last_y = np.full(3, np.nan)  # the previous sample as given (see `_new_only`)
        # samples (t, y, τ chunks) taken before the first identification, to run again through its bank
        self._prefix: list[tuple[Array, Array, Array]] = []
        # an explicit start (`initialize`): blended state, time, frame heading, weights; kept for that rerun
        self._start: tuple[Array, float, float, Array] | None = None
        self.lf.reset()
        self._reset_filters()

    def _reset_filters(self) -> None:
        """Filters uninitialised, weights uniform."""
        n = self.bank.n
        self._X = np.zeros((n, N_STATE))
        self._p = np.full(n, 1.0 / n)
        self._xb = np.zeros(N_STATE)
        self._clock = np.zeros(kernel.N_CLOCK)

    def _begin(self, t: float, start: InitialState) -> None:
        """Start every filter from an explicit state (weights kept, as at a restart after a long gap); η,
        b and η_w in NED as the estimates give them, omitted parts zero. Without this, the first complete
        measurement initialises the filters (ξ = 0, ν = 0, b_p = −τ)."""
        psi_f = ssa_scalar(float(start.eta[2]))
        x = StateView.zeros()
        x.eta[:] = _turn(start.eta, psi_f)
        x.x[I_PSI] = psi_f
        if start.nu is not None:
            x.nu[:] = start.nu
        if start.bias is not None:
            x.bias[:] = _turn(start.bias, psi_f)
        if start.eta_wf is not None:
            x.eta_wf[:] = _turn(start.eta_wf, psi_f)
        self._xb[:] = x.x
        kernel.start_at(self._X, self._xb, self._clock, t, psi_f)
        self._start = (x.x.copy(), t, psi_f, self._p.copy())
        self._prefix = []  # samples before an explicit start are not run again
        self.lf.reset()

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`, from the bank the observer starts with. Each filter is a steady-state
        Kalman filter whose start-up error decays with its slowest closed-loop mode, τᵢ = −dt / ln ρᵢ, ρᵢ
        the spectral radius of (I − KᵢC)Φᵢ (docs/mmae.md: 3.6-13.8 s across the default bank); the bank
        settles with its slowest filter, `ENGAGE_TIME_CONSTANTS` × max τᵢ. That is not all: the blend is
        only as good as the weights, and when the noise is identified (the default) the weights wait for
        the first identification and the bank is designed again from it — the evidence of one whole
        identification window (six periods of the slowest candidate, `identification_config`) is what
        the weights then rest on. So the larger of the two. The LF output stage's stiffer filters
        (`observers.mmae_lf`) are chosen from the data as they come: nothing about them can be derived
        in advance, and they start from the winner's state, so they are not counted."""
        if self._settle_s is None:
            b = self._initial_bank
            eye = np.eye(N_STATE)  # (the last mask: every DOF measured)
            radius = max(
                float(np.max(np.abs(np.linalg.eigvals((eye - b.K[i, len(MASKS) - 1] @ b.C) @ b.Phi[i]))))
                for i in range(b.n)
            )
            tau = -b.dt / math.log(radius) if 0.0 < radius < 1.0 else math.inf
            settle = settle_time_from_time_constant(tau)
            if self.identify_noise:
                settle = max(settle, identification_config(self._design_args[0]).window_s)
            self._settle_s = settle
        return self._settle_s

    @property
    def state(self) -> StateView:
        """The blended state (16) by name, in the vessel-parallel frame of `frame_heading` (a view)."""
        return StateView(self._xb)

    @property
    def candidates(self) -> Array:
        return self.bank.candidates.copy()

    @property
    def weights(self) -> Array:
        """pᵢ, one per candidate (sum 1, each ≥ weight_floor)."""
        return self._p.copy()

    @property
    def omega0(self) -> Array:
        """Blended ω0 = Σ pᵢ ω0ⁱ (rad/s), the same for N, E and ψ (one ω0 for all DOFs, as the paper)."""
        return np.full(3, kernel.blended_omega(self._p, self.bank.candidates))

    @property
    def filter_states(self) -> Array:
        """States of the filters (N, 15) in the vessel-parallel frame of heading `frame_heading`."""
        return self._X.copy()

    @property
    def frame_heading(self) -> float:
        return float(self._clock[kernel.CLOCK_PSI_F])

    def extra(self) -> dict[str, Any]:
        """Fields for the estimate message."""
        out: dict[str, Any] = {
            "weights": self._p.tolist(),
            "candidates": self.bank.candidates.tolist(),
            "omega0_blended": self.omega0.tolist(),
        }
        if self.identified is not None:
            out["measurement_sigma"] = _clean3(self.identified.measurement_sigma)
            out["wave_sigma"] = _clean3(self.identified.wave_sigma)
        if self.lf_output:
            out["lf_noise_scale"] = list(self.lf.scale)
            out["lf_output"] = self.lf.active
        return out

    def _identify(self, t: float) -> None:
        """An update of the noise estimator is due at t: measure σ's, design the bank again if they moved."""
        est = self.noise_estimator
        est.estimate(t)  # the spectrum of the window (its ω0 is not used here: the bank identifies ω0)
        info = est.last_info
        if info is None or info.t != t:
            return
        cfg = est.config
        sig_n = est.noise_sigma(t, cfg.update_period_s)  # since the last update: ~200 differences at 10 Hz
        if not np.all(np.isfinite(sig_n)):
            # A short update period at a low rate (a bank of fast candidates on a 5 Hz log: 3.1 s, 15
            # samples) holds too few differences for the robust spread; without this the bank was never
            # designed and the weights stayed uniform for the whole record. The whole window then.
            sig_n = np.where(np.isfinite(sig_n), sig_n, est.noise_sigma(t, cfg.window_s))
        sig_w = np.sqrt(np.array(info.wave_power))  # the wave motion alone: above the LF tail and the noise
        # the median of the last few windows: one window of a few wave periods scatters by ±30 % and more,
        # and every redesign moves the likelihoods the weights are made of
        self._history.append((np.where(sig_n > 0, sig_n, np.nan), np.where(sig_w > 0, sig_w, np.nan)))
        del self._history[:-IDENTIFICATION_MEDIAN_OF]
        med_n = _median_finite([h[0] for h in self._history])
        med_w = _median_finite([h[1] for h in self._history])
        prev = self._design_sigma
        meas = np.where(np.isfinite(med_n), med_n, np.nan if prev is None else prev[0])
        wave = np.where(np.isfinite(med_w), med_w, np.nan if prev is None else prev[1])
        redesign = False
        if np.all(np.isfinite(meas)) and np.all(np.isfinite(wave)):
            if prev is None:
                redesign = True
            else:
                ratios = np.concatenate([meas / prev[0], wave / prev[1]])
                redesign = bool(np.any((ratios > REDESIGN_RATIO) | (ratios < 1.0 / REDESIGN_RATIO)))
        if redesign:
            cand, zeta, Q, R, dt, wave_std = self._design_args
            self.bank = design_bank(
                self.vessel,
                cand,
                zeta,
                Q,
                R if self._fixed_R else np.diag(meas**2),
                dt,
                wave_std if self._fixed_Q1 else WAVE_STD_FACTOR * wave,
            )
            first = self._design_sigma is None
            self._design_sigma = (meas, wave)
            self._params[kernel.PARAM_WARMUP_S] = self.warmup_s  # the weights may move from now on
            if first and self._prefix:
                self._restart_on_prefix()
        if self.lf_output and self._design_sigma is not None:
            self.lf.identify(t, self.bank, self._X, self._p, self._clock, self._params)
        self.identified = NoiseIdentification(t, _f3(meas), _f3(wave), redesign)

    def _restart_on_prefix(self) -> None:
        """The first identified bank starts where the record started: the filters and weights are set back
        and run again over the samples taken so far (their outputs were already given, by the fallback
        bank with the weights held), so that the bank's state is what it would be had it been designed
        at the first sample. Costs one pass over one slowest period of data, once."""
        t = np.concatenate([c[0] for c in self._prefix])
        Y = np.ascontiguousarray(np.concatenate([c[1] for c in self._prefix]))
        TAU = np.ascontiguousarray(np.concatenate([c[2] for c in self._prefix]))
        self._prefix = []
        self._reset_filters()
        if self._start is not None:  # the filters started from an explicit state: so they do again
            x0, t0, psi0, p0 = self._start
            self._xb[:] = x0
            self._p[:] = p0
            kernel.start_at(self._X, self._xb, self._clock, t0, psi0)
        n, m = self.bank.n, t.shape[0]
        kernel.run(
            self._X, self._p, self._xb, self._clock, t, Y, TAU, *self._kernel_args(),
            np.empty((m, 4, 3)), np.empty((m, n)), np.empty(m, dtype=np.int8),
        )  # fmt: skip

    def _kernel_args(self) -> tuple[Array, Array, Array, Array, Array, Array, Array, Array]:
        b = self.bank
        return (b.Phi, b.Gam, b.A, b.B, b.K, b.Sinv, b.logdet, self._params)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t (s) with measurement y and generalised force τ held since the last sample."""
        y_arr = np.asarray(y, dtype=float).reshape(3)
        fresh = _new_only_one(y_arr, self._last_y)
        self._last_y = y_arr.copy()
        tau_arr = ZERO3 if tau is None else np.asarray(tau, dtype=float).reshape(3)
        if self.identify_noise:
            est = self.noise_estimator
            est.add(float(t), fresh)
            if est.due(float(t)):
                self._identify(float(t))
        out = np.empty((kernel.N_OUT, 3))
        code = kernel.step(
            self._X, self._p, self._xb, self._clock, float(t), y_arr, tau_arr, *self._kernel_args()
        )
        if self.identify_noise and self._design_sigma is None:
            self._prefix.append(
                (np.array([float(t)]), y_arr.reshape(1, 3).copy(), tau_arr.reshape(1, 3).copy())
            )
        if self.lf_output and self.lf.running:
            self.lf.record_one(float(t), y_arr, tau_arr)
            self.lf.step(float(t), y_arr, tau_arr)
        if code == STATUS_INITIALIZING:
            return Estimate.initializing(float(t))
        kernel.outputs(self._xb, self._clock[kernel.CLOCK_PSI_F], out)
        if self.lf.active:
            lf = np.empty((1, kernel.N_OUT, 3))
            self.lf.outputs(lf[0])
            mmae_lf.mix_outputs(out.reshape(1, kernel.N_OUT, 3), lf, self.lf.scale)
        return Estimate(
            float(t),
            out[kernel.OUT_ETA],
            out[kernel.OUT_NU],
            out[kernel.OUT_BIAS],
            out[kernel.OUT_ETA_WF],
            STATUS_NAMES[code],
        )

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample: t (n,), y (n, 3) with NaN for missing, τ (n, 3) or None for zero."""
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        n = t_arr.shape[0]
        fresh = _new_only(Y, self._last_y)
        if n:
            self._last_y = Y[-1].copy()
        OUT = np.empty((n, kernel.N_OUT, 3))
        W = np.empty((n, self.bank.n))
        status = np.empty(n, dtype=np.int8)
        OUT_LF = np.empty((n, kernel.N_OUT, 3)) if self.lf_output else OUT
        a = 0  # the kernel has run samples [0, a)

        def kernel_to(b: int) -> None:
            nonlocal a
            if b <= a:
                return
            kernel.run(
                self._X, self._p, self._xb, self._clock, t_arr[a:b], Y[a:b], TAU[a:b],
                *self._kernel_args(), OUT[a:b], W[a:b], status[a:b],
            )  # fmt: skip
            if self.identify_noise and self._design_sigma is None:
                # copies (as `step` keeps them): the caller may reuse its arrays before the restart reads them
                self._prefix.append((t_arr[a:b].copy(), Y[a:b].copy(), TAU[a:b].copy()))
            if self.lf_output and self.lf.running:
                self.lf.record(t_arr[a:b], Y[a:b], TAU[a:b])
                self.lf.run(t_arr[a:b], Y[a:b], TAU[a:b], OUT_LF[a:b])
                if self.lf.active:  # (in place: OUT[a:b] is a view)
                    mmae_lf.mix_outputs(OUT[a:b], OUT_LF[a:b], self.lf.scale)
            a = b

        if self.identify_noise:
            # Identifications depend on the measurements only: walk the estimator through the record to
            # each update, run the kernel up to it, identify (perhaps designing the bank again), go on.
            # `step` does the same at the same samples, so both give the same numbers.
            for j in self.noise_estimator.add_until_updates(t_arr, fresh):
                kernel_to(j)
                self._identify(float(t_arr[j]))
        kernel_to(n)
        om = np.empty(n)
        kernel.blended_omegas(W, self.bank.candidates, om)
        omega = np.repeat(om[:, None], 3, axis=1)
        return Run(
            t_arr,
            OUT[:, kernel.OUT_ETA],
            OUT[:, kernel.OUT_NU],
            OUT[:, kernel.OUT_BIAS],
            OUT[:, kernel.OUT_ETA_WF],
            status,
            omega,
            {"weights": W},
        )


# --- readable reference ----------------------------------------------------------------------------------
# The same algorithm with the bank's matrices in numpy, one sample at a time. Slow; used to check the
# kernel (tests/test_mmae.py) and as the baseline of bench/bench_mmae.py.


def _turn(v: Array, angle: float) -> Array:
    """Rᵀ(angle) applied to the horizontal part of a 3-vector (re-expressed in axes turned by angle)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]])


def project_weights(q: Array, floor: float) -> Array:
    """The floor: weights below it are raised to it and the others scaled down in proportion, repeated
    until none is below (Σ = 1 is kept, the order of the weights too)."""
    p = q.copy()
    low = np.zeros(p.size, dtype=bool)
    while True:
        new = (p < floor) & ~low
        if not new.any():
            return p
        low |= new
        p[low] = floor
        p[~low] *= (1.0 - floor * np.count_nonzero(low)) / p[~low].sum()


def reference_run(
    bank: MMAEBank,
    t: Array,
    y: Array,
    tau: Array | None = None,
    weight_floor: float = WEIGHT_FLOOR,
    warmup_s: float = 0.0,
    max_gap_s: float = 60.0,
    heading_in_weights: bool = True,
) -> tuple[Array, Array, NDArray[np.int8]]:
    """Reference batch run. Returns outputs (n, 4, 3) = [η̂, ν̂, b̂, η̂_w] (NaN while initialising),
    weights (n, N) and status codes (n,)."""
    N, n = bank.n, len(t)
    tau = np.zeros((n, 3)) if tau is None else np.nan_to_num(np.asarray(tau, dtype=float))
    OUT = np.full((n, kernel.N_OUT, 3), np.nan)
    W = np.empty((n, N))
    status = np.zeros(n, dtype=np.int8)
    X = np.zeros((N, N_STATE))
    p = np.full(N, 1.0 / N)
    xb = np.zeros(N_STATE)
    psi_f = t_prev = t_init = 0.0
    initialized = False

    def start(k: int) -> None:
        nonlocal psi_f, t_prev, t_init, initialized, xb
        psi_f = ssa_scalar(float(y[k, 2]))
        x0 = np.zeros(N_STATE)
        x0[ETA] = _turn(y[k], psi_f)
        x0[I_PSI] = psi_f
        x0[BIAS] = -tau[k]  # equilibrium of (9) at rest: b_p = −τ
        X[:] = x0
        xb = x0.copy()
        t_prev = t_init = float(t[k])
        initialized = True

    for k in range(n):
        complete = bool(np.all(np.isfinite(y[k])))
        dt = t[k] - t_prev
        if initialized and dt > max_gap_s:
            initialized = False  # restart from this sample if it is complete (weights kept)
        if not initialized:
            if complete:
                start(k)
                status[k] = STATUS_OK
        elif dt <= 0:
            status[k] = STATUS_OK if complete else STATUS_DEAD_RECKONING
        else:
            t_prev = float(t[k])
            # 1. turn the vessel-parallel frame to the latest blended heading
            d = ssa_scalar(xb[I_PSI] - psi_f)
            for i in range(N):
                X[i, ETA] = _turn(X[i, ETA], d)
                X[i, BIAS] = _turn(X[i, BIAS], d)
            psi_f = float(xb[I_PSI])
            # 2. predict: n nominal ZOH steps, then a 2nd-order Taylor step for the remainder
            steps = math.floor(dt / bank.dt + 0.5)
            delta = dt - steps * bank.dt
            for i in range(N):
                x = X[i]
                for _ in range(steps):
                    x = bank.Phi[i] @ x + bank.Gam @ tau[k]
                if abs(delta) > 1e-9 * bank.dt:
                    f = bank.A[i] @ x + bank.B @ tau[k]
                    x = x + delta * f + 0.5 * delta**2 * (bank.A[i] @ f)
                X[i] = x
            # 3. update and weights (18)
            pos = bool(np.isfinite(y[k, 0]) and np.isfinite(y[k, 1]))
            head = bool(np.isfinite(y[k, 2]))
            m = int(pos) + 2 * int(head)
            if m:
                yk = np.nan_to_num(y[k])
                yp = _turn(yk, psi_f)
                mw = m if heading_in_weights else m & 1  # the DOFs that inform the weights
                ll = np.empty(N)
                for i in range(N):
                    y_hat = bank.C @ X[i]
                    r = np.where(MASKS[m], yp - y_hat, 0.0)
                    r[2] = ssa_scalar(yp[2] - y_hat[2]) if head else 0.0
                    ll[i] = -0.5 * r @ bank.Sinv[i, mw] @ r - 0.5 * bank.logdet[i, mw]
                    X[i] = X[i] + bank.K[i, m] @ r
                    X[i, I_PSI] = ssa_scalar(X[i, I_PSI])
                if mw and t[k] - t_init >= warmup_s:
                    lp = np.log(p) + ll
                    q = np.exp(lp - lp.max())
                    p = project_weights(q / q.sum(), weight_floor)
            # 4. blend (16)
            xb = p @ X
            xb[I_PSI] = ssa_scalar(psi_f + sum(p[i] * ssa_scalar(X[i, I_PSI] - psi_f) for i in range(N)))
            status[k] = STATUS_OK if m == 3 else STATUS_DEAD_RECKONING
        W[k] = p
        if initialized and status[k] != STATUS_INITIALIZING:
            OUT[k, kernel.OUT_ETA] = _turn(xb[ETA], -psi_f)
            OUT[k, kernel.OUT_NU] = xb[NU]
            OUT[k, kernel.OUT_BIAS] = _turn(xb[BIAS], -psi_f)
            OUT[k, kernel.OUT_ETA_WF] = _turn(xb[XI2], -psi_f)
    return OUT, W, status
