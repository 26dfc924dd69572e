"""Gain-scheduled wave filtering, Torsetnes, Jouffroy & Fossen (2004): the ω0 estimator, the scheduled
observer, the contraction check, and the measurements behind the adaptive observers on simulated
supply-vessel data.

Data: the `torsetnes_2004` scenario's MSS supply vessel at (0, 0), heading 45°, in a JONSWAP sea through the
vessel's RAOs (`simulator.waves.WaveField`), plus a low-frequency motion from the vessel's LF dynamics
(`simulator.vessel_dynamics`) under slowly varying forces and a weak station-keeping law, plus DGPS-like
(0.3 m) and gyro-like (0.05°) white noise, at 10 Hz. Deterministic seeds.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
from functools import lru_cache

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import cumulative_trapezoid

from observers.gain_scheduled import GainScheduledObserver, reference_run
from observers.gain_scheduled_analysis import DEFAULT_TUNING, ContractionError, contraction_check
from observers.kinematics import rotation, ssa
from observers.passive import PassiveObserver, pack_gains
from observers.passive_tuning import PassiveTuning, passive_gains
from observers.state import BIAS, I_ETA, I_PSI, NU, XI2
from observers.vessel import load_vessel
from observers.wave_frequency import WaveFrequencyConfig, WaveFrequencyEstimator, _peak
from simulator.scenarios import get_scenario
from simulator.spectra import SeaState
from simulator.vessel_dynamics import VesselDynamics
from simulator.waves import WaveField, WaveResponse

SCENARIO = get_scenario("torsetnes_2004")
VESSEL = SCENARIO.vessel
SEA = SCENARIO.sea[0][1]  # JONSWAP Hs 6 m, Tp 11.5 s, waves 30° off the bow
HEADING = SCENARIO.eta0[2]
RATE = 10.0
BADLY_TUNED = 0.83  # Torsetnes Sec. V: the initial ω0, right for Hs = 1 m
T_UPDATE = WaveFrequencyConfig().update_period_s


def motion_spectrum(sea: SeaState, omega: np.ndarray) -> np.ndarray:
    """Spectra of the WF motion [N, E, ψ] (NED) at heading 45°: |H(ω, β)|² S(ω), H rotated to NED."""
    H = WaveResponse.for_vessel(VESSEL).rao_at(omega, ssa(sea.direction_rad - HEADING))
    c, s = math.cos(HEADING), math.sin(HEADING)
    Hn = np.stack([c * H[:, 0] - s * H[:, 1], s * H[:, 0] + c * H[:, 1], H[:, 2]], axis=1)
    return np.asarray(np.abs(Hn) ** 2 * sea.spectrum(omega)[:, None])


def true_peak(sea: SeaState) -> float:
    """The peak the WF motion actually has through the RAOs: each DOF's spectrum normalised to unit power
    in [0.3, 1.6] rad/s and summed (what the shared estimate looks at), its maximum."""
    w = np.linspace(0.3, 1.6, 13001)
    S = motion_spectrum(sea, w)
    return float(w[np.argmax((S / S.sum(axis=0)).sum(axis=1))])


@lru_cache(maxsize=8)
def simulate(
    duration_s: float, seed: int, schedule: tuple[tuple[float, SeaState], ...] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, y, η_LF): measured position/heading at 10 Hz = LF motion + WF motion + noise."""
    rng = np.random.default_rng(seed)
    field = WaveField(
        schedule=list(schedule or SCENARIO.sea), response=WaveResponse.for_vessel(VESSEL), seed=seed
    )
    n = int(duration_s * RATE)
    t = np.arange(n) / RATE
    dyn = VesselDynamics(VESSEL, eta0=SCENARIO.eta0)
    m = np.diag(VESSEL.M)
    wn = 2 * math.pi / 120.0  # a slow station-keeping loop: LF excursions of metres, periods of minutes
    kp, kd = m * wn**2, m * 2 * 0.7 * wn
    periods = rng.uniform(100.0, 600.0, (3, 4))
    phases = rng.uniform(0, 2 * math.pi, (3, 4))
    amps = np.array([2e4, 3e4, 1e6])[:, None] * rng.uniform(0.5, 1.0, (3, 4))
    eta0 = np.asarray(SCENARIO.eta0)
    lf = np.empty((n, 3))
    for k in range(n):
        eta, nu = dyn.eta, dyn.nu
        lf[k] = eta
        err = eta - eta0
        err[2] = ssa(err[2])
        force = np.sum(amps * np.sin(2 * math.pi * t[k] / periods + phases), axis=1)
        dyn.step(1.0 / RATE, force - kp * (rotation(eta[2]).T @ err) - kd * nu)
    wf = field.motion(t, lf[:, 2], lf[:, 0], lf[:, 1])
    y = lf + wf + rng.standard_normal((n, 3)) * np.array([0.3, 0.3, math.radians(0.05)])
    y[:, 2] = ssa(y[:, 2])
    return t, y, lf


def band_power(x: np.ndarray, lo: float, hi: float) -> float:
    """Power of the rows of x (n, k), summed, in [lo, hi] rad/s (Welch, 205 s segments, detrended)."""
    f, P = signal.welch(x, fs=RATE, nperseg=2048, detrend="linear", axis=0)
    w = 2 * math.pi * f
    band = (w >= lo) & (w <= hi)
    return float(P[band].sum() * (f[1] - f[0]))


# --- the sea the tests use --------------------------------------------------------------------------------


def test_true_peak_through_the_raos() -> None:
    """Tp 11.5 s is ωp = 0.546 rad/s; through the supply vessel's RAOs at 30° off the bow the WF motion peaks
    there too (N 0.546, E 0.543, ψ 0.553): the RAOs are flat near the peak. That combined peak is "the true
    peak" of the tests. (For Tp 6 s the RAOs do move it: 1.047 becomes 0.85 in N and E, 1.02 in yaw.)"""
    peak = true_peak(SEA)
    assert SEA.peak_frequency == pytest.approx(0.5464, abs=1e-4)
    assert peak == pytest.approx(SEA.peak_frequency, rel=0.01)
    w = np.linspace(0.3, 1.6, 13001)
    per_dof = w[np.argmax(motion_spectrum(SEA, w), axis=0)]
    np.testing.assert_allclose(per_dof, [0.546, 0.543, 0.553], atol=0.002)
    short = SeaState(2.0, 6.0, 3.3, direction_rad=SEA.direction_rad)
    assert w[np.argmax(motion_spectrum(short, w)[:, 0])] == pytest.approx(0.85, abs=0.01)


# --- the estimator ----------------------------------------------------------------------------------------


def test_estimator_through_dropouts_irregular_sampling_and_heading_wrap() -> None:
    """2 Hz position with jittered time stamps and lost fixes (5 % at random, one 20 s outage), heading at
    10 Hz near 180° so it wraps through ±π all the time: the estimate still finds the peak."""
    t, y, _ = simulate(1200.0, 3)
    rng = np.random.default_rng(11)
    t_j = t + rng.uniform(-0.02, 0.02, t.size)  # jittered stamps (still increasing: 0.1 s apart)
    y = y.copy()
    y[:, 2] = ssa(y[:, 2] + math.pi - HEADING)  # heading ≈ 180°: the measured heading jumps ±2π
    assert np.sum(np.abs(np.diff(y[:, 2])) > math.pi) > 50
    pos = np.full(t.size, False)
    pos[::5] = True  # 2 Hz fixes
    pos[rng.random(t.size) < 0.05] = False
    pos[(t > 500) & (t < 520)] = False
    y[~pos, :2] = np.nan
    est = WaveFrequencyEstimator()
    out = []
    infos = {}
    for k in range(t.size):
        est.add(t_j[k], y[k])
        e = est.estimate(t_j[k])
        if e is not None:
            out.append(e[0])
            infos[round(t_j[k])] = est.last_info
    peak = true_peak(SEA)
    assert est.updates >= 18
    assert est.skipped == 0
    assert np.median(np.abs(np.array(out[2:]) / peak - 1)) < 0.05
    assert np.all(np.abs(np.array(out[2:]) / peak - 1) < 0.15)
    # the 20 s outage: the segments that overlap it lose N and E, the heading keeps them
    during = infos[600]
    assert during is not None and during.segments[0] == during.segments[1] < during.segments[2] == 3
    assert all(infos[1140].used)


def test_peak_fit_recovers_the_wave_model_peak() -> None:
    """`_peak` fits the 2nd-order wave model's spectrum; on that spectrum it returns ω0 exactly."""
    w = np.linspace(0.3, 1.6, 50)
    for w0 in (0.4, 0.55, 0.9, 1.4):
        for zeta in (0.05, 0.1, 0.3):
            S = w**2 / ((w0**2 - w**2) ** 2 + (2 * zeta * w0 * w) ** 2)
            assert _peak(S, w) == pytest.approx(w0, rel=1e-9)
    assert math.isnan(_peak(np.linspace(1.0, 0.1, 50), w))  # maximum on the band edge: no peak


def test_estimator_ignores_large_lf_motion() -> None:
    """A DP vessel's LF motion dwarfs its WF motion: 50 m of extra LF motion (100 s period, 2° in yaw) leaves
    the estimates within 3 % of those without it."""

    def estimates(y: np.ndarray) -> np.ndarray:
        est = WaveFrequencyEstimator()
        out = []
        for k in range(0, t.size, 600):
            est.add(t[k : k + 600], y[k : k + 600])
            e = est.estimate(t[min(k + 599, t.size - 1)])
            if e is not None:
                out.append(e[0])
        return np.array(out)

    t, y, _ = simulate(1200.0, 1)
    extra = y.copy()
    extra[:, 0] += 50 * np.sin(2 * math.pi * t / 100)
    extra[:, 1] += 50 * np.cos(2 * math.pi * t / 130)
    extra[:, 2] = ssa(extra[:, 2] + math.radians(2) * np.sin(2 * math.pi * t / 100))
    plain, disturbed = estimates(y), estimates(extra)
    assert plain.size == disturbed.size >= 18
    np.testing.assert_allclose(disturbed, plain, rtol=0.03)


def test_estimator_skips_with_a_reason() -> None:
    est = WaveFrequencyEstimator()
    rng = np.random.default_rng(0)
    t = np.arange(0, 400, 0.1)
    calm = rng.standard_normal((t.size, 3)) * [0.3, 0.3, 1e-3]  # noise only
    got = []
    for k in range(t.size):
        est.add(t[k], calm[k])
        got.append(est.estimate(t[k]))
    assert all(g is None for g in got)
    assert est.updates == 0 and est.skipped == 6
    assert est.last_skip is not None and "no wave peak above the noise" in est.last_skip
    est = WaveFrequencyEstimator(WaveFrequencyConfig(update_period_s=30.0))
    est.add(np.arange(0, 31, 0.1), np.ones((310, 3)))
    assert est.estimate(30.0) is None
    assert est.last_skip is not None and "too little clean data" in est.last_skip


def test_estimator_config_and_model_ship_scaling() -> None:
    cfg = WaveFrequencyConfig().scaled(1 / 70)  # CyberShip II, a 1:70 model
    assert cfg.omega_min == pytest.approx(0.3 * math.sqrt(70))
    assert cfg.update_period_s == pytest.approx(60 / math.sqrt(70))
    with pytest.raises(ValueError, match="omega_max"):
        WaveFrequencyConfig(omega_min=1.0, omega_max=0.5)
    with pytest.raises(ValueError, match="segment_s"):
        WaveFrequencyConfig(segment_s=500.0)
    # the model ship's whole range passes the contraction check with the scaled estimator
    obs = GainScheduledObserver(load_vessel("cybership2"), estimator=cfg, omega0_initial=5.0)
    assert obs.check.ok


# --- gains and checks -------------------------------------------------------------------------------------


@pytest.mark.slow  # ~10 s
def test_scheduled_gains_are_torsetnes_51_52_and_the_passive_rule() -> None:
    """Gains at any ω̄0 are (51)–(52) in the corrected form, bit for bit those of `passive_gains`."""
    obs = GainScheduledObserver(VESSEL, omega0_initial=0.7)
    g = obs.gains
    tun = DEFAULT_TUNING
    k = tun.cutoff_ratio
    zd, z = tun.zeta_n, tun.zeta
    # Sec. III-A: ζd "typically 1.0", ζ "recommended 0.1 for JONSWAP"; k > 1 is left open (Fossen & Strand's
    # 1.1/0.8976 here)
    assert (zd, z) == (1.0, 0.1) and k == pytest.approx(1.1 / 0.8976, rel=1e-12)
    np.testing.assert_allclose(g.K1[:3], -2 * (zd - z) * k * np.eye(3), rtol=1e-14)
    np.testing.assert_allclose(g.K1[3:], 2 * (zd - z) * 0.7 * np.eye(3), rtol=1e-14)
    np.testing.assert_allclose(g.K2, k * 0.7 * np.eye(3), rtol=1e-14)
    assert np.all(g.t_inv == 0.0)  # Torsetnes (31): random-walk bias
    assert np.array_equal(obs._G, pack_gains(passive_gains(VESSEL, tun.with_omega0(np.full(3, 0.7)))))
    # after a run, the kernel's closed-form gains at the ω0 it ended with are still passive_gains'
    t, y, _ = simulate(400.0, 1)
    obs.run(t, y)
    assert not np.allclose(obs.omega0, 0.7)
    assert np.array_equal(obs._G, pack_gains(obs.gains))


def test_contraction_check_over_the_default_range() -> None:
    chk = contraction_check(VESSEL, DEFAULT_TUNING, 0.3, 1.6)
    assert chk.ok, [c.detail for c in chk.checks if not c.ok]
    assert [c.name for c in chk.checks] == ["tuning_rule", "spr", "contraction_50"]
    assert np.all(chk.alpha > 0) and np.all(chk.spectral_abscissa < -1e-3)
    assert np.all(chk.alpha < -chk.spectral_abscissa)  # a metric cannot beat the slowest mode
    assert np.all(chk.sustained_rate > 1e-4)
    assert chk.budget == pytest.approx(2 * math.log(10))
    # the first adaptation of the Torsetnes case fits in the budget
    assert chk.cost_between(BADLY_TUNED, true_peak(SEA)) < chk.budget
    json.dumps(chk.as_dict())


def test_contraction_check_refuses_an_impossible_range() -> None:
    """Fixed injection (as in the paper: λ/κ = K3/K4 = 0.05 rad/s) and ω_min below it violate (53)."""
    fixed = PassiveTuning(bias_time_constant_s=math.inf, bias_corner=0.05, velocity_injection=0.05)
    with pytest.raises(ContractionError, match=r"\(53\)/\(48\)") as err:
        GainScheduledObserver(
            VESSEL, fixed, estimator=WaveFrequencyConfig(omega_min=0.04, omega_max=1.6), omega0_initial=0.8
        )
    assert "λ/κ = 0.05 is not < ω0 = 0.04" in str(err.value)
    # with the ratios of the default tuning (53) holds everywhere, but so low a range leaves the bias
    # loop practically open: (50) with its decay margin fails
    with pytest.raises(ContractionError, match=r"\(50\)"):
        GainScheduledObserver(VESSEL, estimator=WaveFrequencyConfig(omega_min=0.02, omega_max=1.6))
    obs = GainScheduledObserver(
        VESSEL,
        estimator=WaveFrequencyConfig(omega_min=0.02, omega_max=1.6),
        omega0_initial=0.8,
        allow_unchecked=True,
    )
    assert not obs.check.ok
    with pytest.raises(ContractionError, match="A6"):
        GainScheduledObserver(VESSEL, omega0_initial=2.0)


# --- the measurements behind the adaptive observers -----------------------------------------------------


def test_adapts_from_the_badly_tuned_start() -> None:
    """Torsetnes' case: ω0 starts at 0.83 rad/s in the Hs 6 m, Tp 11.5 s sea. After two update periods
    (120 s: one estimate, from 60 s of data, applied) ω0 is within 10 % of the true peak, and stays there.

    Eight sea realisations. The first estimate sees five wave periods, and the peak of a random sea over
    60 s scatters: the same estimator on the noise-free WF motion alone scatters the same way
    (docs/gain-scheduled.md). Required, and measured: 7 of 8 within 10 % at 120 s and at every sample from
    then on (seed 5 is the exception: its first minute of sea peaks at 0.64 rad/s, +18 %), median 5 %.
    """
    peak = true_peak(SEA)
    at_2T, after = [], []
    for seed in range(8):
        t, y, _ = simulate(1200.0, seed)
        run = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED).run(t, y)
        err = run.omega0[:, 0] / peak - 1
        k = int(2 * T_UPDATE * RATE)
        at_2T.append(err[k])
        after.append(np.abs(err[k:]).max())
    at_2T_abs = np.abs(at_2T)
    assert np.sum(at_2T_abs <= 0.10) >= 7, np.round(at_2T, 3)
    assert np.median(at_2T_abs) <= 0.06, np.round(at_2T, 3)
    assert np.sum(np.array(after) <= 0.10) >= 7, np.round(after, 3)


def test_wave_band_power_10db_below_the_badly_tuned_filter() -> None:
    """After adaptation (t ≥ 300 s) the LF position estimate carries ≥ 10 dB less wave-band power than the
    fixed observer at 0.83 rad/s (same tuning, scheduling off), in the band holding 90 % of the WF position
    energy (0.80–1.34 × peak). In the wider 0.5–2 × peak band the gain is ≈ 9.5 dB: at a notch depth
    ζ/ζn = 0.1 the filter, even exactly at the peak, leaves the band's skirts (linear theory: 9.7 dB)."""
    peak = true_peak(SEA)
    t, y, _ = simulate(1500.0, 1)
    adaptive = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED).run(t, y)
    fixed = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED, schedule=False).run(t, y)
    assert np.all(fixed.omega0 == BADLY_TUNED)
    k = int(300 * RATE)
    w = np.linspace(0.1, 3.0, 20001)
    S = motion_spectrum(SEA, w)[:, :2].sum(axis=1)
    cum = cumulative_trapezoid(S, w, initial=0.0) / np.trapezoid(S, w)
    lo, hi = w[np.searchsorted(cum, 0.05)], w[np.searchsorted(cum, 0.95)]
    assert lo / peak == pytest.approx(0.80, abs=0.01) and hi / peak == pytest.approx(1.34, abs=0.01)
    db90 = 10 * math.log10(band_power(fixed.eta[k:, :2], lo, hi) / band_power(adaptive.eta[k:, :2], lo, hi))
    db_wide = 10 * math.log10(
        band_power(fixed.eta[k:, :2], 0.5 * peak, 2 * peak)
        / band_power(adaptive.eta[k:, :2], 0.5 * peak, 2 * peak)
    )
    assert db90 >= 10.0, db90
    assert db_wide >= 8.5, db_wide


def test_readapts_when_the_sea_changes() -> None:
    """Tp 6 s (Hs 2 m) for 900 s, then Tp 12 s (Hs 6 m; a 60 s cross-fade): ω0 is within 10 % of the new
    peak within 5 minutes of the change (measured: 190–250 s in six realisations), and within 12 % after."""
    d = SEA.direction_rad
    schedule = (
        (0.0, SeaState(2.0, 6.0, 3.3, direction_rad=d)),
        (900.0, SeaState(6.0, 12.0, 3.3, direction_rad=d)),
    )
    peak = true_peak(schedule[1][1])
    for seed in (0, 1, 2, 3):
        t, y, _ = simulate(1500.0, seed, schedule)
        run = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED).run(t, y)
        before = run.omega0[int(890 * RATE), 0]
        assert before > 1.5 * peak  # adapted to the short sea first
        err = np.abs(run.omega0[int(900 * RATE) :, 0] / peak - 1)
        first_in = np.argmax(err <= 0.10) / RATE
        assert 0 < first_in <= 300.0, (seed, first_in)
        assert err[int(first_in * RATE) :].max() <= 0.12, seed


@pytest.mark.slow  # ~7 s
def test_no_jump_at_gain_updates() -> None:
    """Around every update that moves ω0, the LF estimate's largest per-sample change is no larger than
    elsewhere in the surrounding minute — as in the run with scheduling off. And the jump itself: the same
    state stepped over the update sample with the new gains and with the old ones differs by < 1 % of a
    typical per-sample change (the state is never touched; the gains only change its derivative)."""
    t, y, _ = simulate(1200.0, 2)
    sched = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED).run(t, y)
    fixed = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED, schedule=False).run(t, y)
    moves = [
        round(tu * RATE)
        for tu, _ in sched.extras["updates"]
        if np.ptp(sched.omega0[round(tu * RATE) : round((tu + 20) * RATE), 0]) > 0.005
    ]
    assert len(moves) >= 4
    for run in (sched, fixed):
        step = np.r_[0.0, np.linalg.norm(np.diff(run.eta[:, :2], axis=0), axis=1)]
        for k in moves:
            near = step[k : k + 10]  # the update sample and the next second: the steepest part of the ramp
            around = np.r_[step[k - 300 : k], step[k + 10 : k + 300]]
            assert near.max() <= around.max(), (run is sched, t[k])
    step = np.linalg.norm(np.diff(sched.eta[:, :2], axis=0), axis=1)
    for k in moves[:3]:
        obs = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
        obs.run(t[:k], y[:k])
        frozen = copy.deepcopy(obs)
        frozen.scheduling = False  # for this one sample: old gains
        moved, kept = obs.step(t[k], y[k]), frozen.step(t[k], y[k])
        assert not np.array_equal(obs.omega0, frozen.omega0)
        assert np.linalg.norm(moved.eta[:2] - kept.eta[:2]) < 0.01 * np.median(step)


def test_run_and_step_give_the_same_numbers() -> None:
    t, y, _ = simulate(400.0, 4)
    rng = np.random.default_rng(3)
    t = t + rng.uniform(0, 0.05, t.size)  # irregular intervals
    y = y.copy()
    y[rng.random(t.size) < 0.02, :2] = np.nan
    y[(t > 100) & (t < 104), :] = np.nan  # a short outage: dead reckoning
    tau = rng.normal(0, 1e4, (t.size, 3))
    a = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    b = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    run = a.run(t, y, tau)
    for k in range(t.size):
        est = b.step(t[k], y[k], tau[k])
        assert np.array_equal(b.omega0, run.omega0[k])
        if k % 97 == 0 or k == t.size - 1:
            assert est.status == {0: "initializing", 1: "ok", 2: "dead_reckoning"}[int(run.status[k])]
            assert np.array_equal(est.eta, run.eta[k], equal_nan=True)
            assert np.array_equal(est.nu, run.nu[k], equal_nan=True)
            assert np.array_equal(est.bias, run.bias[k], equal_nan=True)
            assert np.array_equal(est.eta_wf, run.eta_wf[k], equal_nan=True)
    assert a.extra() == b.extra()
    assert np.array_equal(a.x, b.x)
    assert len(run.extras["updates"]) == a.estimator.updates >= 4
    # run in two pieces = run at once
    c = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    half = t.size // 2
    r1, r2 = c.run(t[:half], y[:half], tau[:half]), c.run(t[half:], y[half:], tau[half:])
    assert np.array_equal(np.r_[r1.eta, r2.eta], run.eta, equal_nan=True)
    assert np.array_equal(np.r_[r1.omega0, r2.omega0], run.omega0)


def test_compiled_loop_matches_the_readable_reference() -> None:
    """Every state, not only η̂ and ν̂: the heading, the bias (31) and the wave states (29) carry the scheduled
    gains K3 = Λ and K1, so a fault in them would leave the position and velocity nearly unchanged for the
    250 s compared. Measured: identical to the bit."""
    t, y, _ = simulate(400.0, 5)
    obs = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    run = obs.run(t[:2500], y[:2500])
    X, W = reference_run(VESSEL, obs.tuning, obs.check, obs.config, [BADLY_TUNED] * 3, t[:2500], y[:2500])
    assert W[-1, 0] < 0.9 * BADLY_TUNED  # ω0 moved, so the gains were scheduled
    np.testing.assert_allclose(W, run.omega0, rtol=1e-12)
    np.testing.assert_allclose(X[:, I_ETA:I_PSI], run.eta[:, :2], atol=1e-8)
    np.testing.assert_allclose(ssa(X[:, I_PSI] - run.eta[:, 2]), 0.0, atol=1e-10)
    np.testing.assert_allclose(X[:, NU], run.nu, atol=1e-9)
    np.testing.assert_allclose(X[:, BIAS], run.bias, rtol=1e-10, atol=1e-6)  # N, N, N·m of 1e4–1e5
    np.testing.assert_allclose(X[:, XI2], run.eta_wf, atol=1e-8)
    np.testing.assert_allclose(X[-1], obs.x, rtol=1e-10, atol=1e-8)  # ξ1 too


def test_schedule_stays_within_the_contraction_budget() -> None:
    """A target far away: ω0 moves fast while the budget lasts, then no faster than α/κ; the budget spent
    never exceeds what (7) allows (L0 plus the refill ∫α dt)."""
    obs = GainScheduledObserver(VESSEL, omega0_initial=1.5, ramp_time_constant_s=5.0)
    t = np.arange(0.0, 600.0, 0.1)
    y = np.tile([0.0, 0.0, HEADING], (t.size, 1))
    obs.step(0.0, y[0])
    obs._target[:] = 0.3  # as if an estimate had arrived
    w = [obs.omega0[0]]
    for k in range(1, t.size):
        obs.step(t[k], y[k])
        w.append(obs.omega0[0])
    w_arr = np.array(w)
    chk = obs.check
    spent = sum(chk.cost_between(a, b) for a, b in itertools.pairwise(w_arr))
    refill = float(np.sum(np.interp(w_arr[:-1], chk.omega, chk.alpha))) * 0.1
    assert spent <= chk.budget + refill + 1e-6
    assert w_arr[-1] < 0.5  # it does get there, at the sustained rate
    rate = np.abs(np.diff(w_arr)) / 0.1
    late = w_arr[1:] < 0.45
    assert np.all(rate[late] <= 1.05 * np.interp(w_arr[1:][late], chk.omega, chk.sustained_rate))


def test_two_observers_contract_while_omega0_moves() -> None:
    """Contraction in action: two observers with the same data and schedule, started 20 m, 10° and a wrong
    bias apart, converge while ω0 adapts."""
    t, y, _ = simulate(1200.0, 6)
    a = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    b = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED)
    b.initialize(0.0, y[0] + [20.0, -20.0, math.radians(10)], bias=[1e5, -1e5, 1e6])
    a.initialize(0.0, y[0])
    ra, rb = a.run(t[1:], y[1:]), b.run(t[1:], y[1:])
    assert np.array_equal(ra.omega0, rb.omega0)
    d = np.linalg.norm(ra.eta[:, :2] - rb.eta[:, :2], axis=1)
    assert d[int(600 * RATE)] < 0.05 * d[0] and d[-1] < 0.01 * d[0]


def test_per_dof_estimates_and_the_interface() -> None:
    t, y, _ = simulate(600.0, 7)
    obs = GainScheduledObserver(
        VESSEL, estimator=WaveFrequencyConfig(per_dof=True), omega0_initial=[0.8, 0.83, 0.9]
    )
    assert obs.check.per_dof and [c.name for c in obs.check.checks][-1] == "contraction_50_per_dof"
    assert not obs.initialized
    for k in range(t.size):
        est = obs.step(t[k], y[k])
    assert obs.initialized and est.status == "ok"
    assert obs.omega0.shape == (3,)
    np.testing.assert_allclose(obs.omega0, true_peak(SEA), rtol=0.12)
    extra = obs.extra()
    assert set(extra) >= {"omega0_estimate", "omega0_updates"}
    json.dumps(extra)
    with pytest.raises(ValueError, match="one omega0_initial"):
        GainScheduledObserver(VESSEL, omega0_initial=[0.8, 0.83, 0.9])


def test_scheduling_off_is_the_fixed_passive_observer() -> None:
    t, y, _ = simulate(400.0, 1)
    fixed = GainScheduledObserver(VESSEL, omega0_initial=BADLY_TUNED, schedule=False).run(t, y)
    ref = PassiveObserver(VESSEL, DEFAULT_TUNING.with_omega0(BADLY_TUNED)).run(t, y)
    assert np.array_equal(fixed.eta, ref.eta, equal_nan=True)
    assert np.array_equal(fixed.bias, ref.bias, equal_nan=True)


@pytest.mark.parametrize("vessel_name", ["mss_osv", "cybership2", "mss_supply"])
def test_compiled_gains_equal_passive_gains_with_and_without_the_damping_floor(vessel_name: str) -> None:
    """The compiled schedule's gains at each ω0 are `passive_gains`' to the bit, also where the velocity
    injection's damping floor (a ≥ b·D/M) sets a instead of the ratio (mss_osv's yaw; any DOF at low ω0),
    and where the DP loop's floor (a ≥ ωn − D/M, ``loop_bandwidth``) does (CyberShip II's Froude-scaled
    loop)."""
    from observers import _gain_scheduled_kernel as sk
    from observers.gain_scheduled import pack_tuning

    vessel = load_vessel(vessel_name)
    floored = 0
    tunings = (
        PassiveTuning(),
        PassiveTuning(injection_damping_ratio=1e-9),
        PassiveTuning(loop_bandwidth=(0.545, 0.545, 0.779)),
    )
    for tuning in tunings:
        P = pack_tuning(vessel, tuning)
        for w0 in (0.3, 0.55, 0.8976, 1.5, 4.0):
            omega = np.array([w0, 0.9 * w0, 1.1 * w0])
            G = np.zeros((8, 3))
            sk.gains_at(omega, P, G)
            ref = passive_gains(vessel, tuning.with_omega0(omega))
            assert np.array_equal(G[sk.G_KAPPA], np.diag(ref.K4))
            assert np.array_equal(G[sk.G_LAMBDA], np.diag(ref.K3))
            ratio_only = np.diag(vessel.M) * ref.omega_c * omega * tuning.velocity_injection_ratio
            floored += int(np.sum(np.diag(ref.K4) > ratio_only * (1 + 1e-12)))
    if vessel_name in ("mss_osv", "cybership2"):
        assert floored > 0  # the floor is exercised
