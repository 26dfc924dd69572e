"""The MMAE wave filter of Hassani et al. (observers/mmae.py): identification of the wave peak in the
`hassani` sea, re-adaptation when the sea changes, LF tracking, weight invariants, missing data and
variable dt, and agreement between the compiled kernel, the numpy reference, `step` and `run`.

Test data: y = η_LF + η_WF + noise at 10 Hz, made directly (no transports): η_LF from the simulator's
vessel dynamics under the `hassani` scenario's 10 m step (a τ that balances a constant earth-fixed
bias), η_WF from `simulator.waves.WaveField`, sensor noise of the scenario (DGPS 1 cm, gyro 0.1°).

Tuning used for identification (docs/mmae.md, "Tuning for identification"): R = the sensors' noise;
ζ = 0.25; wave_std = 0.7 × the forecast wave-motion σ (the sea's spectrum through the vessel's RAOs).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are

from observers.base import Estimate
from observers.kinematics import ssa
from observers.mmae import (
    HASSANI_CANDIDATES,
    N_STATE,
    Q1_CYBERSHIP2,
    R_CYBERSHIP2,
    MMAEObserver,
    continuous_model,
    design_bank,
    discretize,
    hassani_noise,
    identification_config,
    reference_run,
)
from observers.vessel import VesselModel, builtin_vessels, load_vessel
from observers.wave_frequency import WaveFrequencyEstimator, wave_band_power
from simulator.scenarios import ShipNow, get_scenario, trajectory_law
from simulator.spectra import SeaState
from simulator.vessel_dynamics import VesselDynamics
from simulator.waves import WaveField, WaveResponse

SENSOR_R = (0.01**2, 0.01**2, math.radians(0.1) ** 2)  # the hassani scenario's DGPS and gyro
ZETA = 0.25
ML_STD_FACTOR = 0.7
PERIOD_CANDIDATES = tuple(2 * math.pi / T for T in (4.0, 5.0, 6.0, 7.0, 8.0, 10.0, 12.0, 14.0))


@dataclass
class Record:
    vessel: VesselModel
    t: np.ndarray
    y: np.ndarray
    tau: np.ndarray  # τ held over (t_{k-1}, t_k], as `step` expects
    eta: np.ndarray  # true LF motion
    wf: np.ndarray  # true WF motion


def make_record(
    duration_s: float, schedule: list[tuple[float, SeaState]] | None = None, seed: int = 0
) -> Record:
    sc = get_scenario("hassani")
    vessel = sc.vessel
    field = WaveField(schedule or list(sc.sea), WaveResponse.for_vessel(vessel), seed=seed)
    law = trajectory_law(vessel, sc.extra["legs"])
    dyn = VesselDynamics(vessel)
    n = round(duration_s * 10.0)
    t = np.arange(n) / 10.0
    b = np.array([0.3, -0.2, 0.02])  # earth-fixed environmental force (N, N, N·m)
    eta = np.empty((n, 3))
    tau = np.empty((n, 3))
    for k in range(n):
        eta[k] = dyn.eta
        c, s = math.cos(eta[k, 2]), math.sin(eta[k, 2])
        tau[k] = law(
            ShipNow(t[k], eta[k], dyn.nu, np.array([c * b[0] + s * b[1], -s * b[0] + c * b[1], b[2]]))
        )
        dyn.step(0.1, tau[k], b)
    wf = field.motion(t, eta[:, 2], eta[:, 0], eta[:, 1])
    rng = np.random.default_rng(1000 + seed)
    y = eta + wf + rng.standard_normal((n, 3)) * np.sqrt(SENSOR_R)
    return Record(vessel, t, y, np.vstack([tau[:1], tau[:-1]]), eta, wf)


def forecast_wave_std(vessel: VesselModel, sea: SeaState, heading: float = 0.0) -> np.ndarray:
    """σ of the WF motion [surge, sway, yaw] expected from a sea state through the vessel's RAOs."""
    w = np.linspace(0.02, 40.0, 40_000)
    spectrum = WaveResponse.for_vessel(vessel).response_spectrum(w, sea, heading)
    return np.sqrt(np.trapezoid(spectrum, w, axis=0))


def identifying_observer(vessel: VesselModel, sea: SeaState, **kw: object) -> MMAEObserver:
    wave_std = ML_STD_FACTOR * forecast_wave_std(vessel, sea)
    return MMAEObserver(vessel, zeta=ZETA, R=SENSOR_R, wave_std=wave_std, **kw)  # type: ignore[arg-type]


def first_time(t: np.ndarray, cond: np.ndarray) -> float:
    idx = np.flatnonzero(cond)
    return float(t[idx[0]]) if idx.size else math.inf


# --- identification --------------------------------------------------------------------------------------


@pytest.mark.slow
def test_hassani_sea_selects_the_0_9_filter_within_a_minute() -> None:
    """True peak 0.93 rad/s (JONSWAP γ 3.3, Hs 0.08 m), CyberShip II, 10 Hz, the 10 m step at 40–80 s.
    Hassani et al. Sec. 4: the fifth filter (0.9 rad/s) "is selected in about one minute".

    Measured (seed 0): the weight of the 0.9 rad/s filter first exceeds 0.9 at t = 42.2 s and is 0.991
    at 90 s. Initialisation: the filters start at the first measurement (ξ = 0, ν = 0, b_p = −τ) and the
    weights move from the first sample (no warm-up). The start-up transient of a filter decays with its
    slowest closed-loop mode: 5.2 s for the 0.9 rad/s filter (so ~16 s for 3τ), 13.8 s for the 0.3 rad/s
    one; the rest of the 42 s is the likelihood ratio accumulating.
    """
    rec = make_record(150.0, seed=0)
    obs = identifying_observer(rec.vessel, get_scenario("hassani").sea[0][1])
    r = obs.run(rec.t, rec.y, rec.tau)
    i09 = HASSANI_CANDIDATES.index(0.9)
    t_first = first_time(rec.t, r.extras["weights"][:, i09] > 0.9)
    assert t_first <= 60.0, t_first
    assert r.extras["weights"][900, i09] > 0.9
    # the start-up transient: slowest closed-loop mode of each filter of the bank
    b = obs.bank
    tau_slow = [
        -b.dt / np.log(np.max(np.abs(np.linalg.eigvals((np.eye(N_STATE) - b.K[i, 3] @ b.C) @ b.Phi[i]))))
        for i in range(b.n)
    ]
    assert tau_slow[i09] < 6.0 and max(tau_slow) < 15.0, tau_slow


@pytest.mark.slow
def test_hassani_sea_over_seeds() -> None:
    """The same over 12 seas (seeds 0–11). Measured: 11 of 12 reach weight > 0.9 for 0.9 rad/s within 90 s
    and 10 of 12 within the paper's "about one minute" (first crossings 14–73 s, median 35 s; seed 5 at
    93 s); the blended ω0 averaged over 90–150 s is 0.900–0.921 rad/s
    (mean over the seeds 0.903): the bank settles on the candidate nearest the peak (0.9, 3 % below 0.93)
    and stays there (the weight floor of 1e-8; with 1e-3 the weight moved between 0.9 and 1.05 and the
    blended ω0 averaged 0.890–1.045)."""
    i09 = HASSANI_CANDIDATES.index(0.9)
    sea = get_scenario("hassani").sea[0][1]
    reached = 0
    firsts = []
    blended = []
    for seed in range(12):
        rec = make_record(150.0, seed=seed)
        r = identifying_observer(rec.vessel, sea).run(rec.t, rec.y, rec.tau)
        firsts.append(first_time(rec.t, r.extras["weights"][:, i09] > 0.9))
        reached += firsts[-1] <= 90.0
        blended.append(np.mean(r.omega0[900:, 0]))
    assert reached >= 11
    assert sum(f <= 60.0 for f in firsts) >= 10 and np.median(firsts) <= 60.0, firsts
    assert np.all(np.abs(np.array(blended) / 0.93 - 1) < 0.04), blended


def test_the_weight_floor_holds_the_winner() -> None:
    """Seed 4 of the `hassani` sea, forecast tuning, 200 s. With the default floor (1e-8) the 0.9 rad/s filter
    keeps its weight from 90 s on (least 0.989 measured) and the blended ω0 stays within 10 % of 0.93; with
    the old floor of 1e-3 a filter that lost needed only ln(0.9/1e-3) ≈ 7 nats to win again and a few wave
    periods of chance gave them: the weight of 0.9 fell to the floor and the blended ω0 was within 10 % for
    52 % of the time."""
    rec = make_record(200.0, seed=4)
    sea = get_scenario("hassani").sea[0][1]
    obs = identifying_observer(rec.vessel, sea)
    assert obs.weight_floor == 1e-8
    r = obs.run(rec.t, rec.y, rec.tau)
    late = rec.t >= 90.0
    assert r.extras["weights"][late, HASSANI_CANDIDATES.index(0.9)].min() > 0.9
    assert np.all(np.abs(r.omega0[late, 0] / 0.93 - 1) <= 0.1)
    old = identifying_observer(rec.vessel, sea, weight_floor=1e-3).run(rec.t, rec.y, rec.tau)
    assert np.mean(np.abs(old.omega0[late, 0] / 0.93 - 1) <= 0.1) < 0.8  # what the floor fixed


def test_wave_band_power_starts_after_the_lf_tail() -> None:
    """`wave_band_power`: a spectrum falling from the band's lower edge is the LF motion's tail; the wave
    power is summed from the trough after it. Rising from the edge: the whole band. Falling with no peak
    after the first minimum: not measured (NaN)."""
    d = 0.1
    tail_and_sea = np.array([179.0, 10.0, 0.01, 0.4, 0.8, 1.2, 0.9, 0.3, 0.1, 0.1])
    assert wave_band_power(tail_and_sea, d, 0.1) == pytest.approx((tail_and_sea[2:].sum() - 8 * 0.1) * d)
    sea = np.array([0.05, 0.3, 0.9, 1.2, 0.6, 0.2, 0.1])
    assert wave_band_power(sea, d, 0.05) == pytest.approx((sea.sum() - 7 * 0.05) * d)
    assert math.isnan(wave_band_power(np.array([8.0, 7.0, 2.3, 0.8, 0.34, 0.19, 0.12, 0.13]), d, 0.1))
    assert math.isnan(wave_band_power(np.array([0.1, 0.1, 0.1]), d, 0.2))  # nothing above the noise


def test_identified_wave_sigma_ignores_lf_motion() -> None:
    """The noise identification's window on a vessel that drifts and turns (LF motion of 2 m at 0.12 rad/s and
    0.3 m at 0.2 rad/s, a 10 m minimum-jerk step in 40 s) with waves of σ 1.7 cm around 0.93 rad/s and 1 cm
    noise: the wave σ it measures (`SpectrumInfo.wave_power`) is within 30 % of the waves' (measured
    0.74–1.09 ×). The band power above the noise from ω_min — what the bank was designed with before — was
    6.5–10.5 ×: the 0.3 rad/s filter, which expects the most motion, then won in the `hassani` scenario
    through the CLI."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 300.0, 0.1)
    w = rng.uniform(0.75, 1.15, 40)
    a = np.full(40, 0.017 * math.sqrt(2.0 / 40))
    waves = (a[:, None] * np.sin(w[:, None] * t + rng.uniform(0, 2 * math.pi, 40)[:, None])).sum(axis=0)
    s = np.clip((t - 120.0) / 40.0, 0.0, 1.0)
    lf = 2.0 * np.sin(0.12 * t) + 0.3 * np.sin(0.2 * t + 1.0) + 10.0 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    y = np.zeros((t.size, 3))
    y[:, 0] = lf + waves + 0.01 * rng.standard_normal(t.size)
    y[:, 1] = 0.5 * lf + 0.01 * rng.standard_normal(t.size)
    y[:, 2] = 0.001 * rng.standard_normal(t.size)
    est = WaveFrequencyEstimator(identification_config(HASSANI_CANDIDATES))
    cfg = est.config
    checked = 0
    for j in est.add_until_updates(t, y):
        est.estimate(float(t[j]))
        info = est.last_info
        if info is None or info.t != t[j] or t[j] < cfg.window_s:
            continue
        sigma = math.sqrt(info.wave_power[0])
        assert abs(sigma / np.std(waves) - 1) < 0.3, (t[j], sigma)
        old = info.band_power[0] - info.noise_psd[0] * (cfg.omega_max - cfg.omega_min)
        assert math.sqrt(old) > 5 * np.std(waves)  # the old measure: the LF motion counted as waves
        checked += 1
    assert checked >= 4


@pytest.mark.parametrize("seed", [0, 3])
def test_sea_change_readapts_within_5_minutes(seed: int) -> None:
    """Tp 6 s → 12 s at t = 300 s (60 s cross-fade), the literal periods: at CyberShip II's scale both are
    long waves inside the paper's frequency range, and the candidates are the periods 4, 5, 6, 7, 8, 10,
    12, 14 s, so that 6 s and 12 s are candidates (with the paper's set 2π/12 = 0.524 rad/s sits midway
    between 0.45 and 0.6). The bank keeps the Tp 6 s tuning (wave_std from the first sea's forecast).

    Measured over seeds 0–7, times after the change: the 12 s filter passes 0.9 at +71 … +212 s, the
    blended ω0 stays within 10 % of 2π/12 from +38 … +196 s on, and at the end within −0.4 … 0 %. Seed 0:
    +71 s and +66 s; seed 3: +166 s and +132 s."""
    s6 = SeaState(0.08, 6.0, 3.3, direction_rad=math.radians(150.0))
    s12 = SeaState(0.08, 12.0, 3.3, direction_rad=math.radians(150.0))
    tc = 300.0
    rec = make_record(tc + 300.0, schedule=[(0.0, s6), (tc, s12)], seed=seed)
    obs = identifying_observer(rec.vessel, s6, candidates=PERIOD_CANDIDATES)
    r = obs.run(rec.t, rec.y, rec.tau)
    i6, i12 = 2, 6
    before, after = rec.t < tc, rec.t >= tc
    assert first_time(rec.t, before & (r.extras["weights"][:, i6] > 0.9)) < 100.0
    k_change = int(np.searchsorted(rec.t, tc))
    assert abs(r.omega0[k_change, 0] / PERIOD_CANDIDATES[i6] - 1) < 0.1  # adapted to the first sea
    t12 = first_time(rec.t, after & (r.extras["weights"][:, i12] > 0.9)) - tc
    assert t12 <= 300.0, t12  # the 12 s filter wins within 5 minutes of the change
    w_ok = np.abs(r.omega0[:, 0] / PERIOD_CANDIDATES[i12] - 1) < 0.1
    assert first_time(rec.t, after & w_ok) - tc <= 150.0
    assert w_ok[-1]  # blended ω0 within 10 % at the end
    W = r.extras["weights"]
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-12)
    assert W.min() >= obs.weight_floor * (1 - 1e-12)


# --- estimation ------------------------------------------------------------------------------------------


def test_blended_lf_estimate_tracks_and_weights_stay_a_distribution() -> None:
    """LF error after the first 30 s (seed 0, including the 10 m move): measured RMS 1.10 cm N, 0.72 cm E,
    0.112° heading (seeds 0–11: 0.92–1.13 cm, 0.58–0.72 cm, 0.104–0.117°), against WF motion of σ 1.7 cm
    / 1.0 cm and 1 cm sensor noise: 0.48 × the error of taking y as the LF position. Bounds: 1.2 cm,
    0.8 cm, 0.15°, 0.6 × raw; the WF estimate removes at least half of the WF motion's variance in N."""
    rec = make_record(150.0, seed=0)
    obs = identifying_observer(rec.vessel, get_scenario("hassani").sea[0][1])
    r = obs.run(rec.t, rec.y, rec.tau)
    k = rec.t >= 30.0
    err = r.eta[k] - rec.eta[k]
    err[:, 2] = ssa(err[:, 2])
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 0.012 and rms[1] < 0.008 and rms[2] < math.radians(0.15), rms
    raw = np.sqrt(np.mean((rec.y[k, :2] - rec.eta[k, :2]) ** 2, axis=0))
    assert np.all(rms[:2] < 0.6 * raw)  # better than the raw measurement as an LF estimate
    wf_err = np.mean((r.eta_wf[k, 0] - rec.wf[k, 0]) ** 2)
    assert wf_err < 0.5 * np.var(rec.wf[k, 0])
    W = r.extras["weights"]
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-12)
    assert W.min() >= obs.weight_floor * (1 - 1e-12)
    assert np.all(r.status == 1)


def test_a_turning_vessel_far_from_the_origin() -> None:
    """The vessel-parallel frame follows the heading: 100 m off the origin, turning at 0.03 rad/s through
    ±180° five times in 10 minutes, the LF error stays at the level of a vessel holding still."""
    vessel = load_vessel("cybership2")
    n = 6000
    t = np.arange(n) / 10.0
    dyn = VesselDynamics(vessel, eta0=(100.0, -50.0, math.radians(170.0)))
    nu_c = np.array([0.1, 0.02, 0.03])
    dyn.x[3:6] = nu_c
    b = np.array([0.1, -0.1, 0.01])
    eta = np.empty((n, 3))
    tau = np.empty((n, 3))
    for k in range(n):
        eta[k] = dyn.eta
        c, s = math.cos(eta[k, 2]), math.sin(eta[k, 2])
        tau[k] = vessel.D @ nu_c - np.array([c * b[0] + s * b[1], -s * b[0] + c * b[1], b[2]])
        dyn.step(0.1, tau[k], b)
    sea = SeaState(0.08, 2 * math.pi / 0.93, 3.3, direction_rad=math.radians(150.0))
    wf = WaveField(sea, WaveResponse.for_vessel(vessel), seed=1).motion(t, eta[:, 2], eta[:, 0], eta[:, 1])
    y = eta + wf + np.random.default_rng(2).standard_normal((n, 3)) * np.sqrt(SENSOR_R)
    y[:, 2] = ssa(y[:, 2])
    assert np.sum(np.abs(np.diff(y[:, 2])) > math.pi) >= 4
    r = identifying_observer(vessel, sea).run(t, y, np.vstack([tau[:1], tau[:-1]]))
    err = r.eta[600:] - eta[600:]
    err[:, 2] = ssa(err[:, 2])
    rms = np.sqrt(np.mean(err**2, axis=0))
    assert rms[0] < 0.012 and rms[1] < 0.010 and rms[2] < math.radians(0.2), rms
    assert np.sqrt(np.mean((r.nu[600:] - nu_c) ** 2)) < 0.006
    np.testing.assert_allclose(r.bias[-1], b, atol=0.06)  # earth-fixed bias, N and N·m


# --- the design ------------------------------------------------------------------------------------------


def test_default_bank_is_the_papers_eight_candidates() -> None:
    """Hassani et al. Sec. 4: eight candidates {0.3, 0.45, …, 1.35} rad/s covering peaks in [0.25, 1.4] rad/s;
    the true 0.93 rad/s is not among them, and 0.9 rad/s (the fifth) is the one the paper sees win."""
    printed = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)
    assert printed == HASSANI_CANDIDATES
    bank = design_bank(load_vessel("cybership2"))
    np.testing.assert_array_equal(bank.candidates, printed)
    assert 0.93 not in printed and int(np.argmin(np.abs(bank.candidates - 0.93))) == 4


def test_default_noise_is_appendix_a_for_cybership2_and_froude_scales() -> None:
    cs2 = load_vessel("cybership2")
    Q, R = hassani_noise(cs2)
    np.testing.assert_array_equal(np.diag(Q)[:3], np.diag(Q1_CYBERSHIP2))
    np.testing.assert_array_equal(np.diag(Q)[3:], [1e-3, 1e-3, 1e-4, 1e-3, 1e-3, 1e-4])
    np.testing.assert_array_equal(R, R_CYBERSHIP2)
    # a geometrically similar hull λ = 70 times larger: plain Froude scaling of every intensity
    lam = 70.0
    big = VesselModel(
        "big", cs2.M * np.diag([1, 1, lam]) * lam**3 @ np.diag([1, 1, lam]), cs2.D, cs2.length_m * lam, 1.0
    )
    Qb, Rb = hassani_noise(big)
    expected = np.diag(Q) * np.array(
        [lam**1.5, lam**1.5, lam**-0.5, lam**6.5, lam**6.5, lam**8.5, lam**5.5, lam**5.5, lam**7.5]
    )
    np.testing.assert_allclose(np.diag(Qb), expected, rtol=1e-12)
    np.testing.assert_allclose(np.diag(Rb), np.diag(R) * [lam**2, lam**2, 1.0], rtol=1e-12)
    # the same wave motion in units of the ship: σ of (7) at ω0 ∝ 1/√λ grows as λ
    var_small = Q[0, 0] / (4 * 0.1 * 0.9)
    var_big = Qb[0, 0] / (4 * 0.1 * 0.9 / math.sqrt(lam))
    assert var_big / var_small == pytest.approx(lam**2)


def test_model_discretisation_and_riccati() -> None:
    """(14) as corrected: ν row [0, 0, M⁻¹, −M⁻¹D], C = [C_w, I, 0, 0], B = [0; 0; 0; M⁻¹]; G from (7)–(10)
    (w1 through E_w, w2 through M⁻¹ on ν, w3 on b_p); ZOH and Van Loan against a fine quadrature; the stored
    P solves the DARE; every filter is stable; S = C P Cᵀ + R."""
    vessel = load_vessel("cybership2")
    A, B, G, C = continuous_model(vessel, 0.9, 0.1)
    Minv = np.linalg.inv(vessel.M)
    expected_A = np.zeros((N_STATE, N_STATE))
    expected_A[0:3, 3:6] = np.eye(3)  # A_w = [[0, I], [−Ω, −Λ]], Ω = ω0² I, Λ = 2ζω0 I  (7)
    expected_A[3:6, 0:3] = -0.81 * np.eye(3)
    expected_A[3:6, 3:6] = -2 * 0.1 * 0.9 * np.eye(3)
    expected_A[6:9, 12:15] = np.eye(3)  # η_p' = ν  (8)
    expected_A[12:15, 9:12] = Minv  # M ν' + D ν = τ + b_p + w2  (9); b_p' = w3 (10): a zero row
    expected_A[12:15, 12:15] = -Minv @ vessel.D
    np.testing.assert_allclose(A, expected_A, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(B[:12], 0.0)
    np.testing.assert_allclose(B[12:15], Minv, rtol=1e-15)
    expected_G = np.zeros((N_STATE, 9))
    expected_G[3:6, 0:3] = np.eye(3)  # E_w w1
    expected_G[12:15, 3:6] = Minv  # M⁻¹ w2
    expected_G[9:12, 6:9] = np.eye(3)  # w3
    np.testing.assert_allclose(G, expected_G, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(C, np.hstack([np.zeros((3, 3)), np.eye(3), np.eye(3), np.zeros((3, 6))]))
    Q, _ = hassani_noise(vessel)
    Phi, Gam, Qd = discretize(A, B, G, Q, 0.1)
    np.testing.assert_allclose(Phi, expm(A * 0.1), rtol=1e-12, atol=1e-15)
    s = np.linspace(0.0, 0.1, 2001)
    integrand = np.array([expm(A * si) @ G @ Q @ G.T @ expm(A.T * si) for si in s])
    np.testing.assert_allclose(Qd, np.trapezoid(integrand, s, axis=0), rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(Gam, np.trapezoid([expm(A * si) @ B for si in s], s, axis=0), rtol=1e-6)
    bank = design_bank(vessel, dt=0.1, R=SENSOR_R)
    for i in range(bank.n):
        P = solve_discrete_are(bank.Phi[i].T, bank.C.T, discretize(bank.A[i], bank.B, G, Q, 0.1)[2], bank.R)
        np.testing.assert_allclose(bank.P[i], P, rtol=1e-8, atol=1e-14)
        np.testing.assert_allclose(bank.S[i], bank.C @ P @ bank.C.T + bank.R, rtol=1e-10)
        closed = (np.eye(N_STATE) - bank.K[i, 3] @ bank.C) @ bank.Phi[i]
        assert np.max(np.abs(np.linalg.eigvals(closed))) < 1.0


@pytest.mark.parametrize("name", builtin_vessels())
def test_every_builtin_vessel_gets_a_stable_bank(name: str) -> None:
    """Default (A.2, Froude-scaled) noise for every built-in vessel: the DARE solves and every filter of
    the bank is stable (spectral radius of (I − KC)Φ below 1)."""
    bank = MMAEObserver(load_vessel(name)).bank
    for i in range(bank.n):
        closed = (np.eye(N_STATE) - bank.K[i, 3] @ bank.C) @ bank.Phi[i]
        assert np.max(np.abs(np.linalg.eigvals(closed))) < 1.0
        assert np.all(np.linalg.eigvalsh(bank.S[i]) > 0)


def test_bad_settings_are_refused() -> None:
    vessel = load_vessel("cybership2")
    with pytest.raises(ValueError, match="weight_floor"):
        MMAEObserver(vessel, weight_floor=0.2)
    with pytest.raises(ValueError, match="candidates"):
        MMAEObserver(vessel, candidates=(0.5, -1.0))
    with pytest.raises(ValueError, match="R must be positive definite"):
        MMAEObserver(vessel, R=[1e-4, 0.0, 1e-6])
    with pytest.raises(ValueError, match="dt"):
        MMAEObserver(vessel, dt=0.0)


# --- interface, missing data, time -----------------------------------------------------------------------


def test_observer_interface() -> None:
    vessel = load_vessel("cybership2")
    obs = MMAEObserver(vessel)
    assert not obs.initialized
    est = obs.step(0.0, [np.nan, 0.0, 0.0])
    assert est.status == "initializing" and np.all(np.isnan(est.eta))
    est = obs.step(0.1, [1.0, 2.0, 0.3], [0.1, 0.0, 0.0])
    assert isinstance(est, Estimate) and est.status == "ok" and obs.initialized
    np.testing.assert_allclose(est.eta, [1.0, 2.0, 0.3], atol=1e-12)  # starts at the measurement
    np.testing.assert_allclose(est.bias[2], -0.0, atol=1e-15)
    assert obs.weights.shape == (8,) and obs.omega0.shape == (3,)
    assert obs.omega0[0] == pytest.approx(np.mean(HASSANI_CANDIDATES))
    extra = json.loads(json.dumps(obs.extra()))
    assert set(extra) == {"weights", "candidates", "omega0_blended", "lf_noise_scale", "lf_output"}
    assert extra["lf_noise_scale"] == [1.0, 1.0, 1.0] and extra["lf_output"] is False
    assert set(MMAEObserver(vessel, lf_output=False).extra()) == {"weights", "candidates", "omega0_blended"}
    assert extra["candidates"] == list(HASSANI_CANDIDATES) and len(extra["omega0_blended"]) == 3
    from observers.factory import make_observer

    made = make_observer("mmae", vessel, params={"candidates": [0.5, 1.0], "weight_floor": 0.01, "zeta": 0.2})
    assert made.step(0.0, [0.0, 0.0, 0.0]).status == "ok" and made.extra()["candidates"] == [0.5, 1.0]
    # the LF output stage is on by default and switched off by name, as `--observer mmae:lf_output=false`
    from gateway.replay import parse_observer_spec

    assert made.lf_output
    spec = parse_observer_spec("mmae:lf_output=false")
    assert not make_observer("mmae", vessel, params=spec.params).lf_output


def test_missing_dofs_and_gaps() -> None:
    rec = make_record(120.0, seed=1)
    y = rec.y.copy()
    y[400:450, 0] = np.nan  # one coordinate missing = the fix is missing
    y[600:620, 2] = np.nan  # heading lost
    y[800:850] = np.nan  # everything lost for 5 s
    sea = get_scenario("hassani").sea[0][1]
    r = identifying_observer(rec.vessel, sea).run(rec.t, y, rec.tau)
    W = r.extras["weights"]
    assert np.all(r.status[400:450] == 2) and np.all(r.status[600:620] == 2) and r.status[700] == 1
    # nothing measured: the weights stay
    assert np.all(W[800:850] == W[799])
    # one kind lost: the other still votes
    assert np.any(W[449] != W[400]) and np.any(W[619] != W[600])
    # only the position votes: the weights stay while the fix is lost
    r_pos = identifying_observer(rec.vessel, sea, heading_in_weights=False).run(rec.t, y, rec.tau)
    W_pos = r_pos.extras["weights"]
    assert np.all(W_pos[400:450] == W_pos[399])
    assert np.any(W_pos[619] != W_pos[600])
    # dead reckoning over the 5 s gap (just after the 10 m move): measured 1.8 cm growing to 6.9 cm;
    # the estimate does not jump at recovery
    err = np.linalg.norm(r.eta[800:851, :2] - rec.eta[800:851, :2], axis=1)
    assert err.max() < 0.08
    assert np.linalg.norm(r.eta[851, :2] - r.eta[850, :2]) < 0.02
    # a gap longer than max_gap_s restarts the filters at the next complete sample, weights kept
    obs2 = MMAEObserver(rec.vessel, max_gap_s=10.0)
    obs2.run(rec.t[:100], rec.y[:100], rec.tau[:100])
    w = obs2.weights
    est = obs2.step(rec.t[99] + 30.0, [5.0, 6.0, 0.1])
    assert est.status == "ok"
    np.testing.assert_allclose(est.eta, [5.0, 6.0, 0.1], atol=1e-12)
    np.testing.assert_array_equal(obs2.weights, w)


def test_variable_dt_prediction_matches_the_exact_transition() -> None:
    """Prediction over dt = 0.13 s, 0.27 s and 0.05 s (nominal 0.1 s): n ZOH steps plus a 2nd-order Taylor
    step for the remainder δ (|δ| ≤ dt/2), against expm(A dt). The Taylor error is ≈ (ω0 δ)³/6 of the
    wave states; measured, as the worst relative error of any state block (ξ, η_p, b_p, ν) of any filter:
    8.4e-6 (0.13 s), 8.9e-6 (0.27 s), 3.9e-5 (0.05 s)."""
    vessel = load_vessel("cybership2")
    bank = design_bank(vessel, dt=0.1)
    tau = np.array([0.4, -0.2, 0.05])
    for dt, tol in ((0.13, 2e-5), (0.27, 2e-5), (0.05, 1e-4)):
        obs = MMAEObserver(vessel, weight_floor=0.0)
        obs.step(0.0, [1.0, 2.0, 0.3], tau)
        obs.step(0.1, [1.05, 1.98, 0.31], tau)  # a real update, so the filters' states differ
        X0, p0, psi0 = obs.filter_states, obs.weights, obs.frame_heading
        obs.predict(0.1 + dt, tau)
        X1 = obs.filter_states
        # the frame turned to the new blended heading before the prediction: η_p, b_p re-expressed
        d = obs.frame_heading - psi0
        turn = np.array([[math.cos(d), math.sin(d)], [-math.sin(d), math.cos(d)]])
        X0[:, 6:8] = X0[:, 6:8] @ turn.T
        X0[:, 9:11] = X0[:, 9:11] @ turn.T
        for i in range(bank.n):
            aug = np.zeros((N_STATE + 3, N_STATE + 3))
            aug[:N_STATE, :N_STATE] = bank.A[i]
            aug[:N_STATE, N_STATE:] = bank.B
            E = expm(aug * dt)
            exact = E[:N_STATE, :N_STATE] @ X0[i] + E[:N_STATE, N_STATE:] @ tau
            # error per block (ξ, η_p, b_p, ν) relative to the block's size
            err = max(
                np.linalg.norm(X1[i, sl] - exact[sl]) / np.linalg.norm(exact[sl])
                for sl in (slice(0, 6), slice(6, 9), slice(9, 12), slice(12, 15))
            )
            assert err < tol, (dt, i)
        np.testing.assert_array_equal(obs.weights, p0)


def _jittered_inputs(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = 2500
    t = np.cumsum(rng.choice([0.1, 0.1, 0.1, 0.08, 0.13, 0.2, 0.35], n))
    w = 0.9
    y = np.c_[
        20 + 0.02 * np.sin(w * t) + 0.01 * rng.standard_normal(n),
        -5 + 0.01 * np.cos(w * t) + 0.01 * rng.standard_normal(n),
        ssa(math.pi - 0.05 + 0.002 * t + 0.002 * rng.standard_normal(n)),  # crosses ±π
    ]
    y[:4] = np.nan
    y[rng.random(n) < 0.05, 0] = np.nan
    y[rng.random(n) < 0.05, 2] = np.nan
    y[1000:1010] = np.nan
    t[rng.random(n) < 0.005] -= 0.05  # repeated/backward times are skipped by both
    t[2000:] += 70.0  # a gap > max_gap_s: restart
    tau = rng.normal(0, 0.3, (n, 3))
    return t, y, tau


@pytest.mark.parametrize("heading_in_weights", [True, False])
def test_kernel_agrees_with_numpy_reference(heading_in_weights: bool) -> None:
    vessel = load_vessel("cybership2")
    t, y, tau = _jittered_inputs(5)
    kw = dict(weight_floor=1e-3, warmup_s=5.0, max_gap_s=60.0, heading_in_weights=heading_in_weights)
    obs = MMAEObserver(vessel, R=SENSOR_R, wave_std=(0.01, 0.01, 0.001), **kw)  # type: ignore[arg-type]
    r = obs.run(t, y, tau)
    OUT, W, status = reference_run(obs.bank, t, y, tau, **kw)  # type: ignore[arg-type]
    np.testing.assert_array_equal(r.status, status)
    ok = r.initialized
    assert ok.sum() > 2000
    np.testing.assert_allclose(r.eta[ok], OUT[ok, 0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(r.nu[ok], OUT[ok, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.bias[ok], OUT[ok, 2], rtol=0, atol=1e-10)
    np.testing.assert_allclose(r.eta_wf[ok], OUT[ok, 3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.extras["weights"], W, rtol=0, atol=1e-10)
    assert np.ptp(W[-200:], axis=0).max() > 0  # the weights did move


@pytest.mark.slow
def test_step_and_run_give_the_same_numbers() -> None:
    vessel = load_vessel("cybership2")
    t, y, tau = _jittered_inputs(8)
    run = MMAEObserver(vessel, R=SENSOR_R).run(t, y, tau)
    obs = MMAEObserver(vessel, R=SENSOR_R)
    weights, omega = [], []
    steps = []
    for k in range(len(t)):
        steps.append(obs.step(t[k], y[k], tau[k]))
        weights.append(obs.weights)
        omega.append(obs.omega0)
    assert [s.status for s in steps[:4]] == ["initializing"] * 4
    for field in ("eta", "nu", "bias", "eta_wf"):
        np.testing.assert_array_equal(np.array([getattr(s, field) for s in steps]), getattr(run, field))
    np.testing.assert_array_equal(np.array(weights), run.extras["weights"])
    np.testing.assert_array_equal(np.array(omega), run.omega0)


# --- defaults: noise and wave motion identified from the measurements -------------------------------------


@pytest.mark.slow
def test_defaults_identify_the_hassani_sea() -> None:
    """No tuning at all (`MMAEObserver(vessel)`): R and the wave model are identified from the data (docs/
    mmae.md, "Noise identification"), the bank restarted on the first identification. Measured, seeds 0–11:
    the 0.9 rad/s filter passes 0.9 within 90 s in 11 of 12 (22–73 s; seed 5 at 99 s), as with the forecast
    tuning above; blended ω0 over 90–150 s 0.900–0.922, 0.903 on average; sensor σ identified within 15 %
    (1 cm, 1 cm, 0.1°)."""
    i09 = HASSANI_CANDIDATES.index(0.9)
    reached, blended = 0, []
    for seed in range(12):
        rec = make_record(150.0, seed=seed)
        obs = MMAEObserver(rec.vessel)
        assert obs.identify_noise
        r = obs.run(rec.t, rec.y, rec.tau)
        reached += first_time(rec.t, r.extras["weights"][:, i09] > 0.9) <= 90.0
        blended.append(np.mean(r.omega0[900:, 0]))
        assert obs.identified is not None
        np.testing.assert_allclose(obs.identified.measurement_sigma, np.sqrt(SENSOR_R), rtol=0.15)
    assert reached >= 11
    assert np.all(np.abs(np.array(blended) / 0.93 - 1) < 0.04), blended


@pytest.mark.parametrize("seed", [2, 5])
def test_defaults_readapt_when_the_sea_changes(seed: int) -> None:
    """The Tp 6 s → 12 s change with no tuning (bank redesigned as the identified wave motion moves).
    Measured over seeds 0–7: the 12 s filter passes 0.9 at +71 … +208 s after the change, the blended ω0
    stays within 10 % from +38 … +202 s on and for 98–100 % of the last 100 s. Seeds 2 and 5 failed with
    identification segments of two slowest periods (the 12 s sea merged with the LF tail in the band's
    lowest bins and the identified wave σ collapsed: docs/mmae.md)."""
    s6 = SeaState(0.08, 6.0, 3.3, direction_rad=math.radians(150.0))
    s12 = SeaState(0.08, 12.0, 3.3, direction_rad=math.radians(150.0))
    tc = 300.0
    rec = make_record(tc + 300.0, schedule=[(0.0, s6), (tc, s12)], seed=seed)
    r = MMAEObserver(rec.vessel, candidates=PERIOD_CANDIDATES).run(rec.t, rec.y, rec.tau)
    after = rec.t >= tc
    assert first_time(rec.t, after & (r.extras["weights"][:, 6] > 0.9)) - tc <= 300.0
    w_ok = np.abs(r.omega0[:, 0] / PERIOD_CANDIDATES[6] - 1) < 0.1
    assert np.mean(w_ok[-1000:]) >= 0.9


def test_identification_step_and_run_agree() -> None:
    """With identification (redesigns and the restart on the first one), `step` and `run` give the same
    numbers, and the restart happens once."""
    rec = make_record(120.0, seed=4)
    a, b = MMAEObserver(rec.vessel), MMAEObserver(rec.vessel)
    run = a.run(rec.t, rec.y, rec.tau)
    steps = [b.step(t, y, tau) for t, y, tau in zip(rec.t, rec.y, rec.tau, strict=True)]
    eta = np.array([s.eta for s in steps])
    np.testing.assert_array_equal(eta, run.eta)
    np.testing.assert_array_equal(b.weights, a.weights)
    assert a.identified == b.identified and a.identified is not None
    assert not a._prefix and not b._prefix  # (the restart consumed the samples kept for it)
    # in pieces, the first ending before the first identification: its samples are kept for the restart
    c = MMAEObserver(rec.vessel)
    first = c.run(rec.t[:100], rec.y[:100], rec.tau[:100])
    assert c.identified is None
    rest = c.run(rec.t[100:], rec.y[100:], rec.tau[100:])
    np.testing.assert_array_equal(np.r_[first.eta, rest.eta], run.eta)
    np.testing.assert_array_equal(c.weights, a.weights)


def _lf_record(
    lf_amplitude_m: float, heading_rate: float, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """10 Hz for 300 s: waves of σ 1.7 cm / 1 cm / 0.05° around 0.93 rad/s and the `hassani` sensors' noise,
    on LF motion of ``lf_amplitude_m`` at 0.12 and 0.2 rad/s in N and E and a heading turning at
    ``heading_rate`` rad/s with 0.1 rad of 0.08 rad/s; none of it explained by τ (= 0). Returns t, y and the
    LF motion alone."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 300.0, 0.1)
    y = np.empty((t.size, 3))
    lf_true = np.zeros((t.size, 3))
    for d, (wave_sigma, lf) in enumerate(((0.017, 1.0), (0.010, 0.6), (math.radians(0.05), 0.0))):
        w = rng.uniform(0.75, 1.15, 40)
        a = np.full(40, wave_sigma * math.sqrt(2.0 / 40))
        waves = (a[:, None] * np.sin(w[:, None] * t + rng.uniform(0, 2 * math.pi, 40)[:, None])).sum(axis=0)
        lf_true[:, d] = lf * lf_amplitude_m * (np.sin(0.12 * t) + 0.3 * np.sin(0.2 * t + 1.0))
        y[:, d] = lf_true[:, d] + waves + rng.standard_normal(t.size) * math.sqrt(SENSOR_R[d])
    if heading_rate:
        lf_true[:, 2] += heading_rate * t + 0.1 * np.sin(0.08 * t)
        y[:, 2] += lf_true[:, 2]
    return t, y, lf_true


def _lf_rms(eta: np.ndarray, lf_true: np.ndarray, t: np.ndarray) -> np.ndarray:
    late = t >= 200.0
    err = eta[late] - lf_true[late]
    err[:, 2] = ssa(err[:, 2])
    return np.sqrt(np.mean(err**2, axis=0))


@pytest.mark.parametrize("seed", [0, 1])
def test_lf_output_is_stiff_at_a_constant_load_and_loose_when_the_vessel_moves(seed: int) -> None:
    """The LF output stage (`observers.mmae_lf`). On a vessel at rest under a constant load (the motion:
    waves and noise only) the LF noise becomes stiff (s ≤ 1e-3 of (A.2) in every DOF), the stage gives the
    estimate, and the LF estimate carries far less wave motion than the bank's blend (16) with (A.2)'s
    Q2, Q3: RMS error at most a third of it in N, E and ψ (≥ 9.5 dB; measured 4-9×). On a vessel that
    drifts 2 m and turns a stiff model would lag: s stays ≥ 0.1 and the error is within 5 % of the blend's
    (measured: equal; the stage is not used). Given Q, nothing of it is identified."""
    vessel = get_scenario("hassani").vessel
    tau = np.zeros((3000, 3))
    t, y, lf_true = _lf_record(0.0, 0.0, seed)
    still = MMAEObserver(vessel, lf_output=True)
    run = still.run(t, y, tau)
    blend = MMAEObserver(vessel, lf_output=False).run(t, y, tau)
    assert max(still.lf.scale) <= 1e-3 and still.lf.active, still.lf.scale
    assert np.all(_lf_rms(run.eta, lf_true, t) <= _lf_rms(blend.eta, lf_true, t) / 3.0)
    np.testing.assert_array_equal(run.extras["weights"], blend.extras["weights"])  # the bank is the same
    t, y, lf_true = _lf_record(2.0, 0.05, seed)
    moving = MMAEObserver(vessel, lf_output=True)
    run = moving.run(t, y, tau)
    blend = MMAEObserver(vessel, lf_output=False).run(t, y, tau)
    assert min(moving.lf.scale) >= 0.1, moving.lf.scale
    assert np.all(_lf_rms(run.eta, lf_true, t) <= 1.05 * _lf_rms(blend.eta, lf_true, t))
    fixed = MMAEObserver(vessel, Q=hassani_noise(vessel)[0], lf_output=True)
    fixed.run(t, y, tau)
    assert fixed.lf.scale == (1.0, 1.0, 1.0) and not fixed.lf.running


def test_lf_output_step_and_run_agree() -> None:
    """With the LF output stage giving the estimate, `step` and `run` give the same numbers."""
    vessel = get_scenario("hassani").vessel
    t, y, _ = _lf_record(0.0, 0.0, 0)
    tau = np.zeros((t.size, 3))
    a, b = MMAEObserver(vessel, lf_output=True), MMAEObserver(vessel, lf_output=True)
    run = a.run(t, y, tau)
    steps = [b.step(tk, yk, uk) for tk, yk, uk in zip(t, y, tau, strict=True)]
    assert a.lf.active and b.lf.active and a.lf.scale == b.lf.scale
    for name in ("eta", "nu", "bias", "eta_wf"):
        stepped = np.array([getattr(s, name) for s in steps])
        np.testing.assert_array_equal(stepped, getattr(run, name), err_msg=name)


@pytest.mark.parametrize("omega0", [0.3, 0.9, 1.35])
def test_lf_stage_designs_are_the_banks(omega0: float) -> None:
    """The LF output stage's fast designs (Q_d from unit intensities, the DARE by doubling) against
    `design_bank` for the same candidate, Q and R (scipy's DARE): gains and log det agree to 1e-8 of
    their size, S⁻¹ to 1e-7 (measured 3e-8), for the paper's LF noise and for LF noise 1e-2 … 1e-6 of it."""
    from observers.mmae_lf import _Designer, scaled_lf_noise

    vessel = get_scenario("hassani").vessel
    designer = _Designer(vessel)
    Q = hassani_noise(vessel)[0].copy()
    Q[:3, :3] = np.diag([3e-6, 1e-6, 2e-10])  # an identified calm sea's Q1
    R = np.diag(SENSOR_R)
    for s in (1.0, 1e-2, 1e-4, 1e-6):
        Qs = scaled_lf_noise(Q, hassani_noise(vessel)[0], (s, s, s))
        bank = design_bank(vessel, (omega0,), 0.25, Qs, R, 0.1)
        Phi, Gam, A, B, K, Sinv, logdet = designer.design(omega0, 0.25, 0.1, Qs, R)
        np.testing.assert_allclose(Phi, bank.Phi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(A, bank.A, rtol=0, atol=0)
        np.testing.assert_allclose(B, bank.B, rtol=0, atol=0)
        np.testing.assert_allclose(Gam, bank.Gam, rtol=0, atol=1e-12 * abs(bank.Gam).max())
        np.testing.assert_allclose(K, bank.K, rtol=0, atol=1e-8 * abs(bank.K).max())
        np.testing.assert_allclose(Sinv, bank.Sinv, rtol=0, atol=1e-7 * abs(bank.Sinv).max())
        np.testing.assert_allclose(logdet, bank.logdet, rtol=0, atol=1e-8)


def test_doubling_dare_solves_the_riccati_equation() -> None:
    """`solve_dare_doubling` against scipy on random stabilisable systems (including a random walk with
    little noise, the slow case): the residual of the equation is at round-off and X is scipy's."""
    from scipy.linalg import solve_discrete_are

    from observers.doubling_dare import solve_dare_doubling

    rng = np.random.default_rng(3)
    for n, m in ((2, 1), (6, 3), (15, 3)):
        for _ in range(5):
            a = rng.standard_normal((n, n))
            a *= rng.uniform(0.5, 1.02) / max(abs(np.linalg.eigvals(a)))
            a[0, :] = 0.0
            a[0, 0] = 1.0  # a random walk
            b = rng.standard_normal((n, m))
            g = rng.standard_normal((n, n))
            q = g @ g.T * 1e-3
            q[0, 0] += 1e-9
            r = np.eye(m) * rng.uniform(0.1, 2.0)
            x = solve_dare_doubling(a, b, q, r)
            ref = solve_discrete_are(a, b, q, r)
            resid = a.T @ x @ a - a.T @ x @ b @ np.linalg.solve(r + b.T @ x @ b, b.T @ x @ a) + q - x
            assert abs(resid).max() <= 1e-9 * abs(x).max()
            np.testing.assert_allclose(x, ref, rtol=0, atol=1e-7 * abs(ref).max())


def test_lf_stage_trials_in_one_call_equal_each_filter_run_alone() -> None:
    """`_mmae_kernel.run_single` (the trial filters in one compiled call, no weight updates) against each
    filter run alone through the bank kernel (`run`, a bank of one): the same residuals to the bit."""
    from observers import _mmae_kernel as kernel
    from observers.mmae_lf import LF_NOISE_SCALES, _Designer, _no_weights, _Trials, scaled_lf_noise

    vessel = get_scenario("hassani").vessel
    t, y, _ = _lf_record(0.5, 0.01, 2)
    t, y = t[:1200], np.ascontiguousarray(y[:1200])
    y[300:320, 2] = np.nan  # heading lost for 2 s
    tau = np.zeros((t.size, 3))
    designer = _Designer(vessel)
    Q = hassani_noise(vessel)[0].copy()
    Q[:3, :3] = np.diag([3e-6, 1e-6, 2e-10])
    R = np.diag(SENSOR_R)
    each = [designer.design(0.9, 0.25, 0.1, scaled_lf_noise(Q, hassani_noise(vessel)[0], (s,) * 3), R)
            for s in LF_NOISE_SCALES]  # fmt: skip
    params = np.zeros(kernel.N_PARAMS)
    params[kernel.PARAM_DT] = 0.1
    params[kernel.PARAM_MAX_GAP_S] = 60.0
    params[kernel.PARAM_WEIGHT_FLOOR] = 1e-8
    params = _no_weights(params)
    trials = _Trials(np.zeros(15), np.zeros(kernel.N_CLOCK), len(LF_NOISE_SCALES))  # (not started)
    trials.set(each)
    res = trials.residuals(t, y, tau, params)
    for i, m in enumerate(each):
        Xi, pi, xbi, ci = np.zeros((1, 15)), np.ones(1), np.zeros(15), np.zeros(kernel.N_CLOCK)
        out = np.empty((t.size, kernel.N_OUT, 3))
        kernel.run(
            Xi, pi, xbi, ci, t, y, tau, *m, params, out, np.empty((t.size, 1)), np.empty(t.size, np.int8)
        )
        r = y - out[:, kernel.OUT_ETA] - out[:, kernel.OUT_ETA_WF]
        r[:, 2] = ssa(r[:, 2])
        np.testing.assert_array_equal(res[i], r)
        np.testing.assert_array_equal(trials.X[i], Xi[0])


def test_lf_stage_mix_takes_the_stiff_dofs_in_vessel_axes() -> None:
    """`mix_outputs`: with the heading at 90° the vessel's x axis is east: a stiff surge takes E (and ν_u)
    from the output filter and keeps N (sway, loose) from the blend; all stiff copies everything; none
    stiff changes nothing; the heading's DOF is taken as is."""
    from observers.mmae_lf import mix_outputs

    blend = np.zeros((1, 4, 3))
    blend[0, 0] = [10.0, 20.0, math.pi / 2]
    blend[0, 1] = [1.0, 2.0, 3.0]
    lf = np.zeros((1, 4, 3))
    lf[0, 0] = [11.0, 21.0, math.pi / 2 + 0.1]
    lf[0, 1] = [4.0, 5.0, 6.0]
    m = blend.copy()
    mix_outputs(m, lf, (0.01, 1.0, 1.0))
    np.testing.assert_allclose(m[0, 0], [10.0, 21.0, math.pi / 2], atol=1e-12)
    np.testing.assert_array_equal(m[0, 1], [4.0, 2.0, 3.0])
    m = blend.copy()
    mix_outputs(m, lf, (1.0, 1.0, 1e-3))
    np.testing.assert_allclose(m[0, 0], [10.0, 20.0, math.pi / 2 + 0.1], atol=1e-12)
    np.testing.assert_array_equal(m[0, 1], [1.0, 2.0, 6.0])
    m = blend.copy()
    mix_outputs(m, lf, (1e-6, 1e-6, 1e-6))
    np.testing.assert_array_equal(m, lf)
    m = blend.copy()
    mix_outputs(m, lf, (1.0, 1.0, 1.0))
    np.testing.assert_array_equal(m, blend)


def test_run_in_pieces_from_a_reused_buffer_equals_one_run() -> None:
    """`run` keeps copies of the samples it defers (the samples before the first identification, the LF
    stage's samples until its next identification): a caller that feeds pieces from one buffer it refills
    gets exactly the numbers of one run over the whole record."""
    vessel = get_scenario("hassani").vessel
    t, y, _ = _lf_record(0.0, 0.0, 1)
    tau = np.zeros((t.size, 3))
    whole = MMAEObserver(vessel).run(t, y, tau)
    assert whole is not None
    obs = MMAEObserver(vessel)
    piece = 250  # not a multiple of the identification period: every piece leaves samples deferred
    bt, by, btau = np.empty(piece), np.empty((piece, 3)), np.zeros((piece, 3))
    eta = []
    for a in range(0, t.size, piece):
        m = min(piece, t.size - a)
        bt[:m], by[:m] = t[a : a + m], y[a : a + m]
        eta.append(obs.run(bt[:m], by[:m], btau[:m]).eta)
        bt[:], by[:] = np.nan, np.nan  # the caller reuses its buffer
    assert obs.lf.active
    np.testing.assert_array_equal(np.concatenate(eta), whole.eta)


def test_a_bank_of_fast_candidates_identifies_at_5_hz() -> None:
    """A 1:70 model's sea (3.9 rad/s) logged at 5 Hz, the bank around it (1.96-7.84 rad/s): one period of
    the slowest candidate is 3.2 s, 16 samples, too few differences for the noise σ since the last
    update. Before, the noise was then never measured, the bank never designed and the weights stayed
    uniform for the whole record (ω0 the mean of the bank, 4.9 rad/s); the noise is now measured over the
    identification window, and the filter nearest the sea wins."""
    rng = np.random.default_rng(3)
    dt, sea = 0.2, 3.9
    t = np.arange(0.0, 300.0, dt)
    y = np.zeros((len(t), 3))
    for k, (amp, noise) in enumerate([(0.02, 0.004), (0.02, 0.004), (0.004, 0.002)]):
        for w in sea * np.linspace(0.92, 1.08, 15):  # a narrow sea of 15 components, random phases
            y[:, k] += amp / math.sqrt(15) * math.sqrt(2) * np.sin(w * t + rng.uniform(0, 2 * math.pi))
        y[:, k] += 0.05 * np.sin(0.02 * t + k) + noise * rng.standard_normal(len(t))  # slow LF drift
    bank = (1.96, 2.79, 3.63, 4.46, 5.29, 6.13, 6.96, 7.84)
    obs = MMAEObserver(load_vessel("cybership2"), candidates=bank)
    r = obs.run(t, y, np.zeros((len(t), 3)))
    assert obs.identified is not None
    # measured (within 2x: at 5 Hz a 3.9 rad/s sea, ω·dt = 0.8, is not smooth on the sampling scale and
    # adds to the second differences: 6, 5.5 and 2.3 mm here)
    sigma = np.asarray(obs.identified.measurement_sigma)
    assert np.all((sigma > (0.004, 0.004, 0.002)) & (sigma < (0.008, 0.008, 0.004))), sigma
    w = r.extras["weights"]
    assert np.ptp(w) > 0.5  # the weights moved
    last = t >= 200.0
    winner = np.asarray(bank)[np.argmax(w[last], axis=1)]
    assert np.mean(np.isin(winner, (3.63, 4.46))) > 0.9, np.unique(winner, return_counts=True)
