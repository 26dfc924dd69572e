"""The passive observer, Fossen & Strand (1999) eqs (22)–(26): convergence, accuracy, wave filtering,
dropouts, and agreement between the compiled kernel, the numpy reference, `step` and `run`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from model_data import simulate_model
from scipy.integrate import solve_ivp

from observers.froude import froude_scale
from observers.kinematics import rotation, ssa
from observers.passive import PassiveObserver, reference_derivative, reference_run
from observers.passive_tuning import PassiveTuning, lf_response, notch_depth_db, passive_gains
from observers.state import BIAS, ETA, I_ETA, I_PSI, N_STATE, NU, XI2
from observers.vessel import builtin_vessels, load_vessel

VESSELS = builtin_vessels()


def cruise(vessel_name: str) -> np.ndarray:
    """A steady velocity [u, v, r] that turns the vessel through ±180° within the test."""
    return np.array([0.1, 0.05, 0.02]) if vessel_name == "cybership2" else np.array([0.5, 0.2, 0.01])


@pytest.mark.parametrize("name", builtin_vessels())
def test_global_exponential_convergence_from_far_off(name: str) -> None:
    """Noise-free data from the model (14)–(18); observer started 50 m, 170°, velocity and bias wrong.

    The vessel turns continuously, so the heading crosses ±180° several times. The error must shrink at
    least as fast as exp(-0.01 t) down to the floor set by sampling at 10 Hz (speed × half a sample).
    A model's default tuning is Froude-scaled (`PassiveTuning.for_vessel`: ω0 × √λ), so its data are
    sampled Froude-scaled too, at 10·√λ Hz (84 Hz for CyberShip II, a basin's motion capture rate): the
    same sampling relative to its dynamics as a ship's at 10 Hz. At 10 Hz its scaled gains (ωc 9.2 rad/s)
    leave a velocity error of 1.3 mm/s from the sample-and-hold and the 0.1 s integration step.
    """
    vessel = load_vessel(name)
    dt = 0.1 / math.sqrt(froude_scale(vessel))
    gains = passive_gains(vessel)
    nu_cruise = cruise(name)
    tau_c = vessel.D @ nu_cruise

    def tau(t: float) -> np.ndarray:
        return tau_c * (1 + 0.2 * math.sin(0.01 * t))

    x0 = np.zeros(N_STATE)
    x0[XI2] = [1.0, 1.0, math.radians(1.0)]  # WF motion
    x0[ETA] = [100.0, -20.0, math.radians(175.0)]
    x0[BIAS] = vessel.D @ np.array([0.05, -0.05, 0.001])  # bias
    x0[NU] = nu_cruise
    t = np.arange(0.0, 1200.0, dt)
    X, y = simulate_model(vessel, gains, t, x0, tau)
    assert np.sum(np.abs(np.diff(y[:, 2])) > math.pi) >= 2, "heading must cross ±180° in this test"

    obs = PassiveObserver(vessel)
    obs.initialize(
        0.0,
        X[0, ETA] + [50.0, 50.0, math.radians(170.0)],
        nu=X[0, NU] + [1.0, -1.0, 0.02],
        bias=-2.0 * X[0, BIAS],
    )
    r = obs.run(t[1:], y[1:], np.array([tau(s) for s in t[1:]]))
    e_pos = np.linalg.norm(r.eta[:, :2] - X[1:, I_ETA:I_PSI], axis=1)
    e_psi = np.abs(ssa(r.eta[:, 2] - X[1:, I_PSI]))
    speed = np.linalg.norm(nu_cruise[:2]) * 1.2
    floor_pos = 2 * speed * dt / 2 + 1e-3
    floor_psi = 2 * nu_cruise[2] * 1.2 * dt / 2 + 1e-4
    for T in (200, 400, 600, 900, 1199):
        k = int(T / dt) - 1
        envelope = math.exp(-0.01 * T)
        assert e_pos[k] <= 50 * math.sqrt(2) * envelope + floor_pos, (T, e_pos[k])
        assert e_psi[k] <= math.radians(170) * envelope + floor_psi, (T, e_psi[k])
    # at the end: velocity and bias are estimated, not just position
    scale = np.abs(tau_c)
    assert np.all(np.abs(r.nu[-1] - X[-1, NU]) <= 1e-3 * np.maximum(np.abs(nu_cruise), 1e-2))
    assert np.all(np.abs(r.bias[-1] - X[-1, BIAS]) <= 1e-2 * scale)


def reference_derivative_t(_t, x, y, valid, tau, vessel, gains):  # type: ignore[no-untyped-def]
    return reference_derivative(x, y, valid, tau, vessel, gains)


def _continuous_reference(vessel, gains, t, y, tau, x0):  # type: ignore[no-untyped-def]
    """(22)–(26) integrated by DOP853 at tight tolerance, y and τ held over each interval (as dpgw).

    The first trial step is the interval itself (at most 0.1 s) instead of solve_ivp's own guess, which
    costs two derivative calls and starts small enough to need a second step on most 20 ms intervals; the
    error control at rtol = atol = 1e-12 still accepts or shrinks every step, so the result is the same to
    ~1e-14 (and 42 % fewer derivative calls at 50 Hz)."""
    X = [x0]
    x = x0.copy()
    for k in range(1, len(t)):
        valid = ~np.isnan(y[k])
        yk = np.where(valid, y[k], 0.0)
        sol = solve_ivp(
            reference_derivative_t,
            (t[k - 1], t[k]),
            x,
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
            first_step=min(t[k] - t[k - 1], 0.1),
            args=(yk, valid, tau[k], vessel, gains),
        )
        x = sol.y[:, -1].copy()
        x[8] = ssa(x[8])
        X.append(x)
    return np.array(X)


@pytest.mark.slow
@pytest.mark.parametrize("rate_hz", [1.0, 10.0, 50.0])
def test_discrete_observer_matches_continuous_time(rate_hz: float) -> None:
    """Discrete observer (RK4 sub-steps) against a tight-tolerance integration of (22)–(26).

    Reached with the default h_max = 0.1 s over 300 s of wave motion, 0.3 m noise, a dropout and a jittered
    (variable) sample interval: position < 3e-5 m, heading < 2e-7 rad, velocity < 5e-6 m/s, bias < 1e-5
    relative, at 1, 10 and 50 Hz. Halving h_max divides the error by ~16 (RK4 is 4th order).
    """
    vessel = load_vessel("mss_supply")
    gains = passive_gains(vessel, PassiveTuning.from_wave_period(8.0))
    rng = np.random.default_rng(7)
    dt = 1.0 / rate_hz
    t = np.cumsum(np.r_[0.0, dt * (1 + 0.2 * rng.uniform(-1, 1, int(300 * rate_hz)))])
    w = 2 * math.pi / 8.0
    y = np.c_[
        3 * np.sin(w * t) + 0.02 * t + 0.3 * rng.standard_normal(len(t)),
        2 * np.cos(w * t) - 0.01 * t + 0.3 * rng.standard_normal(len(t)),
        ssa(math.radians(179.0) + math.radians(2) * np.sin(w * t) + 0.001 * t),
    ]
    y[len(t) // 2 : len(t) // 2 + int(5 * rate_hz), :2] = np.nan  # a dropout inside the comparison
    tau = np.tile([2e5, -1e5, 3e6], (len(t), 1))
    x0 = None
    errors = []
    for h_max in (0.1, 0.05):
        obs = PassiveObserver(vessel, gains=gains, h_max=h_max)
        obs.initialize(t[0], y[0], nu=[0.1, 0.0, 0.0], bias=[1e5, 0, 0])
        x0 = obs.x.copy()
        run = obs.run(t[1:], y[1:], tau[1:])
        if h_max == 0.1:
            ref = _continuous_reference(vessel, gains, t, y, tau, x0)[1:]
            assert np.max(np.abs(ssa(run.eta[:, 2] - ref[:, I_PSI]))) < 2e-7
            assert np.max(np.abs(run.nu - ref[:, NU])) < 5e-6
            assert np.max(np.abs(run.bias - ref[:, BIAS]) / np.abs(tau[0])) < 1e-5
        errors.append(np.max(np.abs(run.eta[:, :2] - ref[:, I_ETA:I_PSI])))
    assert errors[0] < 3e-5
    assert errors[1] < errors[0] / 8 or errors[0] < 1e-7  # 4th order (1e-7: round-off floor at 50 Hz)


def test_kernel_agrees_with_numpy_reference() -> None:
    vessel = load_vessel("northern_clipper")
    gains = passive_gains(vessel)
    rng = np.random.default_rng(3)
    n = 1500
    t = np.cumsum(rng.uniform(0.02, 1.5, n))
    y = np.c_[rng.normal(0, 5, n), rng.normal(0, 5, n), ssa(rng.uniform(-4, 4, n))]
    y[rng.random((n, 3)) < 0.1] = np.nan
    t[rng.random(n) < 0.01] -= 0.5  # backward time steps are skipped by both
    tau = rng.normal(0, 1e5, (n, 3))
    X = reference_run(vessel, gains, t, y, tau)
    r = PassiveObserver(vessel, gains=gains).run(t, y, tau)
    ok = r.initialized
    np.testing.assert_allclose(r.eta[ok], X[ok, ETA], rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(r.nu[ok], X[ok, NU], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(r.bias[ok], X[ok, BIAS], rtol=1e-10, atol=1e-6)


def test_step_and_run_give_the_same_numbers() -> None:
    vessel = load_vessel("cybership2")
    rng = np.random.default_rng(11)
    n = 800
    t = np.cumsum(rng.uniform(0.05, 0.3, n))
    y = np.c_[rng.normal(0, 0.5, n), rng.normal(0, 0.5, n), ssa(rng.uniform(-4, 4, n))]
    y[:5] = np.nan  # initialising: nothing until the first complete measurement
    y[100:140, :2] = np.nan
    tau = rng.normal(0, 1, (n, 3))
    run = PassiveObserver(vessel).run(t, y, tau)
    obs = PassiveObserver(vessel)
    steps = [obs.step(t[k], y[k], tau[k]) for k in range(n)]
    assert [s.status for s in steps[:5]] == ["initializing"] * 5
    assert steps[120].status == "dead_reckoning" and steps[200].status == "ok"
    np.testing.assert_array_equal(np.array([s.eta for s in steps]), run.eta)
    np.testing.assert_array_equal(np.array([s.nu for s in steps]), run.nu)
    np.testing.assert_array_equal(np.array([s.bias for s in steps]), run.bias)
    np.testing.assert_array_equal(np.array([s.eta_wf for s in steps]), run.eta_wf)


@pytest.mark.parametrize("bias_time", [1000.0, math.inf])
def test_initialisation_from_first_measurement_has_no_transient(bias_time: float) -> None:
    """Constant y and τ from the first sample on: the estimate does not move at all.

    With a finite bias time constant the observer's equilibrium has a small steady innovation (the
    "limited integral effect" of (24)); with T = ∞ the LF estimate equals the measurement exactly.
    """
    vessel = load_vessel("mss_supply")
    obs = PassiveObserver(vessel, PassiveTuning(bias_time_constant_s=bias_time))
    y = [12.0, -7.0, math.radians(-135.0)]
    tau = [3e5, -2e5, 4e6]  # thrusters balance a steady environmental force
    t = np.arange(0, 600, 0.5)
    r = obs.run(t, np.tile(y, (len(t), 1)), np.tile(tau, (len(t), 1)))
    np.testing.assert_allclose(r.eta, np.tile(r.eta[0], (len(t), 1)), atol=1e-9)
    np.testing.assert_allclose(r.nu, np.tile(r.nu[0], (len(t), 1)), atol=1e-12)
    np.testing.assert_allclose(r.bias, np.tile(r.bias[0], (len(t), 1)), rtol=1e-9)
    offset = np.abs(r.eta[0] - y)
    if math.isinf(bias_time):
        assert np.all(offset < 1e-9)
        np.testing.assert_allclose(r.bias[0][:2], -(rotation(y[2]) @ tau)[:2], rtol=1e-9)
    else:
        assert np.all(offset[:2] < 0.05) and offset[2] < math.radians(0.1)


@pytest.mark.parametrize("dof", [0, 1, 2])
def test_wave_motion_at_omega0_is_attenuated_20_db(dof: int) -> None:
    """Sinusoidal WF motion at ω0 reaches the LF estimate attenuated by ≥ 20 dB (and as predicted)."""
    vessel = load_vessel("mss_supply")
    gains = passive_gains(vessel, PassiveTuning.from_wave_period(9.0))
    w0 = gains.omega0[dof]
    amplitude = [5.0, 5.0, math.radians(2.0)][dof]
    t = np.arange(0.0, 1500.0, 0.1)
    y = np.zeros((len(t), 3))
    y[:, 2] = math.radians(30.0)
    y[:, dof] += amplitude * np.sin(w0 * t)
    r = PassiveObserver(vessel, gains=gains).run(t, y)
    tail = t > 900.0
    lf = r.eta[tail, dof] - (math.radians(30.0) if dof == 2 else 0.0)
    # amplitude of the ω0 component of the LF estimate (lock-in over whole periods)
    c = 2 * np.mean(lf * np.exp(-1j * w0 * t[tail]))
    attenuation_db = 20 * math.log10(abs(c) / amplitude)
    assert attenuation_db <= -20.0
    assert attenuation_db == pytest.approx(notch_depth_db(vessel, gains)[dof], abs=1.0)


def test_lf_motion_passes_the_filter() -> None:
    """Slow motion (well below ω0) passes to the LF estimate essentially unchanged."""
    vessel = load_vessel("mss_supply")
    gains = passive_gains(vessel)
    gain = lf_response(vessel, gains, [0.002])
    np.testing.assert_allclose(gain[:, 0], 1.0, atol=0.02)


def test_position_dropout_dead_reckons_and_recovers_without_jump() -> None:
    """30 s without position (heading present): dead reckoning, then recovery with no jump beyond the
    drift accumulated while dead reckoning."""
    vessel = load_vessel("mss_supply")
    gains = passive_gains(vessel)
    nu_c = np.array([0.4, 0.1, 0.002])
    tau_c = vessel.D @ nu_c
    x0 = np.zeros(N_STATE)
    x0[XI2] = [1.5, 1.0, math.radians(1.0)]
    x0[8] = 0.3
    x0[NU] = nu_c
    t = np.arange(0.0, 900.0, 0.1)
    X, y = simulate_model(vessel, gains, t, x0, lambda s: tau_c * (1 + 0.3 * math.sin(0.02 * s)))
    tau = np.array([tau_c * (1 + 0.3 * math.sin(0.02 * s)) for s in t])
    y_meas = y.copy()
    lost = (t >= 600.0) & (t < 630.0)
    y_meas[lost, :2] = np.nan
    r = PassiveObserver(vessel, gains=gains).run(t, y_meas, tau)
    assert np.all(r.status[lost] == 2)  # dead_reckoning
    err = np.linalg.norm(r.eta[:, :2] - X[:, I_ETA:I_PSI], axis=1)
    drift = err[np.flatnonzero(lost)[-1]]
    # per-sample change of the estimate, minus the true LF motion over the same sample
    step_err = np.linalg.norm(np.diff(r.eta[:, :2], axis=0) - np.diff(X[:, I_ETA:I_PSI], axis=0), axis=1)
    after = (t[1:] >= 630.0) & (t[1:] < 700.0)
    before = (t[1:] >= 500.0) & (t[1:] < 600.0)
    assert step_err[after].max() <= drift + step_err[before].max() + 1e-6
    assert err[t >= 800.0].max() <= err[(t > 500) & (t < 600)].max() + 0.01  # back to pre-dropout error


def test_late_measurement_after_silence_is_not_held_over_the_gap() -> None:
    """Live: all sources silent for 30 s, then one sample. Only the last max_hold_s use it."""
    vessel = load_vessel("mss_supply")
    obs = PassiveObserver(vessel, max_hold_s=1.0)
    obs.step(0.0, [0.0, 0.0, 0.0])
    for k in range(1, 11):
        obs.step(k * 0.1, [0.0, 0.0, 0.0])
    e = obs.step(31.0, [10.0, 0.0, 0.0])  # the vessel really did move 10 m during the silence
    assert 0.0 < e.eta[0] < 10.0 * (1 - math.exp(-1.2 * 1.0)) + 0.5


def test_heading_crossing_north_leaves_no_step() -> None:
    vessel = load_vessel("northern_clipper")
    t = np.arange(0.0, 400.0, 0.1)
    psi = ssa(math.radians(170.0) + 0.005 * t)  # crosses ±180° at t ≈ 35 s
    y = np.c_[np.zeros_like(t), np.zeros_like(t), psi]
    r = PassiveObserver(vessel).run(t, y)
    assert np.max(np.abs(ssa(np.diff(r.eta[:, 2])))) < 0.005 * 0.1 * 3
    assert np.all(r.eta[:, 2] >= -math.pi) and np.all(r.eta[:, 2] < math.pi)
