"""The simulator's plant: LF dynamics, thrusters, environment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from observers.kinematics import rotation, ssa
from observers.vessel import builtin_vessels, load_vessel
from simulator.environment import BiasModel, MarkovBias
from simulator.thrusters import ThrusterBank, least_squares_commands
from simulator.vessel_dynamics import VesselDynamics


@pytest.mark.parametrize("name", builtin_vessels())
def test_constant_tau_gives_steady_velocity_D_inv_tau(name: str) -> None:
    vessel = load_vessel(name)
    nu_ss = np.array([0.3, 0.1, 0.0])
    tau = vessel.D @ nu_ss + np.array([0.0, 0.0, 0.0])
    dyn = VesselDynamics(vessel)
    slowest = min(np.linalg.eigvals(vessel.Minv @ vessel.D).real)
    for _ in range(int(12 / slowest)):
        dyn.step(1.0, tau)
    np.testing.assert_allclose(dyn.nu, np.linalg.solve(vessel.D, tau), rtol=1e-4, atol=1e-6)


def test_turn_keeps_kinematics_consistent_and_wraps_heading() -> None:
    """A steady turn: the track is a circle of radius U/r, ψ stays in [-π, π), η' = J(ψ)ν throughout."""
    vessel = load_vessel("mss_supply")
    nu_ss = np.array([2.0, 0.0, 0.02])
    tau = vessel.D @ nu_ss
    dyn = VesselDynamics(vessel, nu0=nu_ss)
    track = []
    for _ in range(int(2 * 2 * math.pi / 0.02 / 0.5)):  # two full turns at 0.5 s steps
        dyn.step(0.5, tau)
        track.append(dyn.eta)
    track_arr = np.array(track)
    assert np.all(track_arr[:, 2] >= -math.pi) and np.all(track_arr[:, 2] < math.pi)
    assert np.sum(np.abs(np.diff(track_arr[:, 2])) > math.pi) >= 2  # crossed ±180° twice
    centre = track_arr[:, :2].mean(axis=0)
    radius = np.linalg.norm(track_arr[:, :2] - centre, axis=1)
    np.testing.assert_allclose(radius, 2.0 / 0.02, rtol=1e-3)
    # heading tangent to the track: the velocity direction is ψ (no sway)
    v = np.diff(track_arr[:, :2], axis=0)
    course = np.arctan2(v[:, 1], v[:, 0])
    mid_psi = track_arr[:-1, 2] + 0.5 * ssa(np.diff(track_arr[:, 2]))
    assert np.max(np.abs(ssa(course - mid_psi))) < 1e-3


def test_rk4_step_size_does_not_change_the_answer() -> None:
    vessel = load_vessel("cybership2")
    tau = np.array([1.0, 0.5, 0.1])
    a, b = VesselDynamics(vessel), VesselDynamics(vessel)
    for _ in range(200):
        a.step(0.05, tau, [0.2, -0.1, 0.0])
    b.step(10.0, tau, [0.2, -0.1, 0.0])  # split internally into 0.05 s steps
    np.testing.assert_allclose(a.x, b.x, rtol=1e-12, atol=1e-12)


def test_azimuth_slews_at_its_rate_limit_and_thrust_lags() -> None:
    vessel = load_vessel("mss_supply")
    bank = ThrusterBank(vessel)
    thrust = np.zeros(bank.n)
    thrust[0] = 2e5
    angle = np.zeros(bank.n)
    angle[0] = math.radians(170.0)
    bank.command(thrust, angle)
    for _ in range(20):
        bank.step(0.05)  # 1 s
    rate = vessel.thrusters[0].azimuth_rate_rad_s
    assert bank.angle[0] == pytest.approx(rate * 1.0, rel=1e-9)
    tc = vessel.thrusters[0].thrust_time_constant_s
    assert bank.thrust[0] == pytest.approx(2e5 * (1 - math.exp(-1.0 / tc)), rel=1e-9)
    # the short way round: from +12°, -150° is 162° to port (198° to starboard)
    angle[0] = math.radians(-150.0)
    bank.command(thrust, angle)
    before = bank.angle[0]
    bank.step(0.05)
    assert bank.angle[0] < before


def test_generalised_force_through_the_configuration_matrix() -> None:
    vessel = load_vessel("hajivand_vessel")
    bank = ThrusterBank(vessel)
    bank.thrust[:] = [1e5, 2e5, 3e5]
    bank.angle[:] = [0.0, math.pi / 2, -math.pi / 2]
    x = [t.x_m for t in vessel.thrusters]
    y = [t.y_m for t in vessel.thrusters]
    expected = np.array(
        [
            1e5,
            2e5 - 3e5,
            -y[0] * 1e5 + x[1] * 2e5 - x[2] * 3e5,  # N = x F_y − y F_x
        ]
    )
    np.testing.assert_allclose(bank.tau, expected, rtol=1e-12, atol=1e-6)


def test_failed_thruster_delivers_nothing() -> None:
    bank = ThrusterBank(load_vessel("mss_supply"))
    bank.command(np.full(bank.n, 1e5), np.zeros(bank.n))
    bank.failed[1] = True
    for _ in range(400):
        bank.step(0.05)
    assert bank.thrust[1] == pytest.approx(0.0, abs=1.0) and bank.thrust[0] > 9e4


@pytest.mark.parametrize("name", ["mss_supply", "hajivand_vessel", "cybership2"])
def test_prescribed_tau_commands_reproduce_tau(name: str) -> None:
    vessel = load_vessel(name)
    rng = np.random.default_rng(0)
    for _ in range(20):
        tau = rng.normal(0, 1, 3) * np.array([1e5, 1e5, 3e6]) * (vessel.mass_kg / 6e6)
        thrust, angle = least_squares_commands(vessel, tau)
        np.testing.assert_allclose(vessel.generalized_force(thrust, angle), tau, rtol=1e-9, atol=1e-6)


def test_markov_bias_statistics() -> None:
    """Eq (7) simulated exactly: stationary std σ and correlation time T."""
    model = BiasModel(sigma=(1e4, 2e4, 3e5), time_constant_s=(100.0, 100.0, 100.0), constant=(5.0, 0.0, 0.0))
    bias = MarkovBias(model, np.random.default_rng(1))
    samples = []
    for _ in range(200_000):
        bias.step(1.0)
        samples.append(bias.b.copy())
    b = np.array(samples)
    np.testing.assert_allclose(b.std(axis=0), model.sigma, rtol=0.05)
    lag = 100
    rho = np.mean(b[:-lag, 0] * b[lag:, 0]) / b[:, 0].var()
    assert rho == pytest.approx(math.exp(-1.0), abs=0.05)
    assert bias.force[0] == pytest.approx(bias.b[0] + 5.0)


def test_bias_acts_in_earth_axes() -> None:
    """The bias enters as Jᵀ(ψ) b: an earth-fixed force accelerates the vessel as M⁻¹ Jᵀ(ψ) b at any
    heading."""
    vessel = load_vessel("mss_supply")
    b = np.array([5e3, -2e3, 1e5])
    for psi in (0.0, 1.0, -2.5):
        dyn = VesselDynamics(vessel, eta0=(0, 0, psi))
        dyn.step(1e-3, [0, 0, 0], b)
        np.testing.assert_allclose(dyn.nu / 1e-3, vessel.Minv @ rotation(psi).T @ b, rtol=1e-4)


def test_fast_tau_equals_configuration_matrix() -> None:
    vessel = load_vessel("mss_supply")
    bank = ThrusterBank(vessel)
    rng = np.random.default_rng(4)
    bank.thrust[:] = rng.normal(0, 1e5, bank.n)
    bank.angle[:] = rng.uniform(-math.pi, math.pi, bank.n)
    bank.angle[~bank.is_azimuth] = bank.fixed_angle[~bank.is_azimuth]
    np.testing.assert_allclose(bank.tau, vessel.generalized_force(bank.thrust, bank.angle), rtol=1e-12)
