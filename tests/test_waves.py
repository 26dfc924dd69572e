"""Wave spectra, RAO data conventions and WF motion synthesis (simulator.spectra, simulator.waves).

The synthesised records are checked against what they must be by construction of a linear random sea:
Hs = 4σ_ζ, the response spectrum |H(ω, β)|² S(ω) (peak and variance), and the physics that fixes the data's
conventions (long-wave particle motion, wave drift direction, full reflection of short waves).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad, trapezoid
from scipy.ndimage import uniform_filter1d
from scipy.signal import welch

from observers.vessel import load_vessel
from simulator.spectra import SeaState, jonswap, pierson_moskowitz
from simulator.waves import MSS_SUPPLY_LPP_M, G, WaveField, WaveResponse, frequency_range

SUPPLY = WaveResponse.mss_supply()
CS2_LENGTH_M = 1.255  # CyberShip II, a 1:70 model of a supply vessel
W_FINE = np.linspace(0.01, 40.0, 200_001)


def expected_response(response: WaveResponse, sea: SeaState, heading: float) -> tuple[np.ndarray, np.ndarray]:
    """Peak frequency (rad/s) and variance of each body DOF from the response spectrum |H|²S."""
    wp = sea.peak_frequency
    w = W_FINE[(0.3 * wp < W_FINE) & (8.0 * wp > W_FINE)]
    R = response.response_spectrum(w, sea, heading)
    return w[np.argmax(R, axis=0)], trapezoid(R, w, axis=0)


def welch_peak(x: np.ndarray, dt: float) -> np.ndarray:
    """Peak frequency (rad/s) of each column's Welch PSD, lightly smoothed (the sea is a sum of lines)."""
    f, P = welch(x.T, fs=1.0 / dt, nperseg=1024)
    P = uniform_filter1d(P, 3, axis=-1)
    return np.asarray(2.0 * math.pi * f[np.argmax(P, axis=-1)])


# -- spectra -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("hs", "tp", "gamma"), [(4.0, 10.0, 3.3), (2.5, 7.0, 1.0), (6.0, 12.0, 2.0), (0.05, 1.2, 5.0)]
)
def test_jonswap_integral_is_hs2_over_16(hs: float, tp: float, gamma: float) -> None:
    wp = 2 * math.pi / tp
    m0 = quad(lambda w: float(jonswap(w, hs, tp, gamma)), 0.0, 40 * wp, points=[wp], limit=400)[0]
    assert m0 == pytest.approx(hs**2 / 16, rel=0.01)
    w = np.linspace(0.5 * wp, 2 * wp, 30001)
    assert w[np.argmax(jonswap(w, hs, tp, gamma))] == pytest.approx(wp, rel=1e-3)


def test_pierson_moskowitz_and_gamma_one() -> None:
    m0 = quad(lambda w: float(pierson_moskowitz(w, 3.0, 9.0)), 0.0, np.inf, limit=400)[0]
    assert m0 == pytest.approx(9.0 / 16, rel=1e-6)
    w = np.linspace(0.0, 5.0, 501)
    np.testing.assert_allclose(jonswap(w, 3.0, 9.0, 1.0), pierson_moskowitz(w, 3.0, 9.0))
    assert pierson_moskowitz(w, 3.0, 9.0)[0] == 0.0  # S(0) = 0, no overflow
    pm = SeaState(3.0, 9.0, kind="pm")
    np.testing.assert_allclose(pm.spectrum(w), pierson_moskowitz(w, 3.0, 9.0))


def test_sea_state_fields_and_validation() -> None:
    sea = SeaState(4.0, 10.0, direction_rad=3 * math.pi / 2)
    assert sea.peak_frequency == pytest.approx(2 * math.pi / 10)
    assert sea.direction_rad == pytest.approx(-math.pi / 2)  # kept in [-π, π)
    assert np.all(SeaState(0.0, 8.0).spectrum(np.linspace(0.1, 3, 10)) == 0.0)  # calm sea is allowed
    for kwargs in (
        {"hs_m": -1.0, "tp_s": 8.0},
        {"hs_m": 2.0, "tp_s": 0.0},
        {"hs_m": float("nan"), "tp_s": 8.0},
        {"hs_m": 2.0, "tp_s": 8.0, "gamma": 0.5},
        {"hs_m": 2.0, "tp_s": 8.0, "gamma": 40.0},
        {"hs_m": 2.0, "tp_s": 8.0, "kind": "bretschneider"},
        {"hs_m": 2.0, "tp_s": 8.0, "direction_rad": float("inf")},
    ):
        with pytest.raises(ValueError):
            SeaState(**kwargs)  # type: ignore[arg-type]


# -- RAO data and its conventions ----------------------------------------------------------------------------


def test_mss_rao_conventions_from_long_wave_physics() -> None:
    """Long waves: the hull moves with the water particles, which lag the elevation by 90° along the travel
    direction (ζ = a cos θ, particle displacement a sin θ). So a lead-phase RAO has ∠H = −π/2 along the
    travel direction, +π/2 against it; |H| → 1 m/m."""
    w = 0.15
    follow, beam, head = (SUPPLY.rao_at(w, b) for b in (0.0, math.pi / 2, math.pi))
    assert abs(follow[0]) == pytest.approx(1.0, abs=0.02)
    assert np.angle(follow[0]) == pytest.approx(-math.pi / 2, abs=0.02)  # surge, following sea
    assert np.angle(head[0]) == pytest.approx(math.pi / 2, abs=0.02)  # surge, head sea
    assert abs(beam[1]) == pytest.approx(1.0, abs=0.02)
    assert np.angle(beam[1]) == pytest.approx(-math.pi / 2, abs=0.02)  # β = 90°: waves travel to starboard
    assert abs(beam[0]) < 1e-3 and abs(follow[1]) < 1e-3
    # Yaw is a rotation (rad/m): it vanishes with the wave slope k = ω²/g for long waves.
    assert abs(SUPPLY.rao_at(0.05, math.radians(130))[2]) < 2e-4


def test_rao_port_starboard_symmetry_and_wrap() -> None:
    w = np.linspace(0.2, 1.5, 40)
    for b in np.radians([10.0, 40.0, 95.0, 133.0, 170.0]):
        H, Hm = SUPPLY.rao_at(w, b), SUPPLY.rao_at(w, 2 * math.pi - b)
        np.testing.assert_allclose(Hm[:, 0], H[:, 0], atol=1e-9)  # surge symmetric
        np.testing.assert_allclose(Hm[:, 1:], -H[:, 1:], atol=1e-9)  # sway, yaw antisymmetric
        C, Cm = SUPPLY.drift_at(w, b), SUPPLY.drift_at(w, 2 * math.pi - b)
        np.testing.assert_allclose(Cm[:, 0], C[:, 0], rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(Cm[:, 1:], -C[:, 1:], rtol=1e-9, atol=1e-6)  # MSS yaw sign restored
    # β wraps: 355° interpolates between 350° and 0°, and −5° is the same direction.
    b350, b0 = SUPPLY.rao_at(w, math.radians(350)), SUPPLY.rao_at(w, 0.0)
    np.testing.assert_allclose(SUPPLY.rao_at(w, math.radians(355)), 0.5 * (b350 + b0), atol=1e-12)
    np.testing.assert_allclose(SUPPLY.rao_at(w, math.radians(-5)), SUPPLY.rao_at(w, math.radians(355)))


def test_rao_extrapolation() -> None:
    w_max = SUPPLY.omega[-1]
    assert np.all(SUPPLY.rao_at(1.5 * w_max + 0.01, np.linspace(0, 6, 7)) == 0)  # tapered to 0
    np.testing.assert_allclose(SUPPLY.rao_at(0.01, 1.0)[:2], SUPPLY.rao_at(SUPPLY.omega[0], 1.0)[:2])
    assert SUPPLY.drift_at(0.0, math.pi)[0] == 0.0
    np.testing.assert_allclose(SUPPLY.drift_at(10.0, 1.0), SUPPLY.drift_at(SUPPLY.drift_omega[-1], 1.0))


def test_drift_signs_and_short_wave_limit() -> None:
    """Mean drift pushes the ship along the wave travel direction; short beam waves are fully reflected:
    Y/ζa² → ½ρgL (Faltinsen 1990, ch. 5)."""
    sea = SeaState(4.0, 8.0)
    head = SUPPLY.mean_drift_force(sea, heading=math.pi)  # waves travel north, ship heads south
    assert head[0] < 0 and abs(head[1]) < 1e-3 * abs(head[0])
    from_port = SUPPLY.mean_drift_force(sea, heading=-math.pi / 2)  # β = +90°: waves travel to starboard
    from_stbd = SUPPLY.mean_drift_force(sea, heading=math.pi / 2)
    assert from_port[1] > 0 and from_stbd[1] < 0
    assert from_port[1] == pytest.approx(-from_stbd[1])
    assert 1e5 < from_port[1] < 1e6  # Hs 4 m on an 83 m hull: a few hundred kN
    # Waves from the port bow (β = 130°) turn the bow to starboard, towards beam-on; mirrored, to port.
    assert SUPPLY.mean_drift_force(sea, heading=-math.radians(130))[2] > 0
    assert SUPPLY.mean_drift_force(sea, heading=math.radians(130))[2] < 0
    half_rho_g_L = 0.5 * 1025.0 * G * MSS_SUPPLY_LPP_M
    assert SUPPLY.drift_at(SUPPLY.drift_omega[-1], math.pi / 2)[1] == pytest.approx(half_rho_g_L, rel=0.1)


# -- synthesis -----------------------------------------------------------------------------------------------


def test_elevation_hs_and_spectrum_peak() -> None:
    sea = SeaState(4.0, 10.0, direction_rad=0.7)
    field = WaveField(sea, SUPPLY, seed=11)
    dt = sea.tp_s / 20
    t = np.arange(0.0, 3600.0, dt)
    zeta = field.elevation(t)
    assert 4 * zeta.std() == pytest.approx(sea.hs_m, rel=0.05)
    assert welch_peak(zeta[:, None], dt)[0] == pytest.approx(sea.peak_frequency, rel=0.05)
    # The discrete sea carries the spectrum's energy, Σ a_k²/2 ≈ Hs²/16: a Riemann sum at random nodes, so
    # 2 % rather than the 1 % of the spectrum itself.
    c = field.components[0]
    assert np.sum(c.amplitude**2) / 2 == pytest.approx(sea.hs_m**2 / 16, rel=0.02)
    lo, hi = frequency_range(sea)
    assert len(c.omega) == 150 and lo <= c.omega.min() and c.omega.max() <= hi


@pytest.mark.parametrize(
    ("name", "length", "direction_deg", "dofs"),
    [
        ("beam", None, 90.0, (1, 2)),  # sway and yaw; surge is ~0 in a beam sea
        ("quartering", None, 45.0, (0, 1, 2)),
        ("bow quartering", None, 135.0, (0, 1, 2)),
        ("froude-scaled", CS2_LENGTH_M, 60.0, (0, 1, 2)),
    ],
)
def test_motion_has_the_response_spectrum(
    name: str, length: float | None, direction_deg: float, dofs: tuple[int, ...]
) -> None:
    response = SUPPLY if length is None else WaveResponse.froude_scaled(length)
    lam = response.length_m / MSS_SUPPLY_LPP_M
    sea = SeaState(4.0 * lam, 10.0 * math.sqrt(lam), direction_rad=math.radians(direction_deg))
    field = WaveField(sea, response, seed=5)
    dt = sea.tp_s / 20
    t = np.arange(0.0, 400 * sea.tp_s, dt)
    body = field.body_motion(t, 0.0)
    peak, var = expected_response(response, sea, 0.0)
    got_peak = welch_peak(body, dt)
    for j in dofs:
        assert got_peak[j] == pytest.approx(peak[j], rel=0.05), (name, j)
        assert body[:, j].var() == pytest.approx(var[j], rel=0.10), (name, j)
    # At heading 0 the NED motion is the body motion.
    np.testing.assert_allclose(field.motion(t[:500], 0.0), body[:500], atol=1e-12)


def test_froude_scaling() -> None:
    lam = CS2_LENGTH_M / MSS_SUPPLY_LPP_M
    model = WaveResponse.froude_scaled(CS2_LENGTH_M)
    assert model.length_m == pytest.approx(CS2_LENGTH_M)
    np.testing.assert_allclose(model.omega, SUPPLY.omega / math.sqrt(lam))
    w, b = np.linspace(0.1, 3.0, 50), math.radians(70)
    np.testing.assert_allclose(model.rao_at(w / math.sqrt(lam), b), SUPPLY.rao_at(w, b) * [1, 1, 1 / lam])
    np.testing.assert_allclose(
        model.drift_at(w / math.sqrt(lam), b), SUPPLY.drift_at(w, b) * [lam, lam, lam**2]
    )
    # The same sea at model scale: response peaks move by 1/√λ, translations scale by λ, angles not at all.
    full = SeaState(4.0, 10.0, direction_rad=b)
    small = SeaState(4.0 * lam, 10.0 * math.sqrt(lam), direction_rad=b)
    peak_full, var_full = expected_response(SUPPLY, full, 0.0)
    peak_small, var_small = expected_response(model, small, 0.0)
    np.testing.assert_allclose(peak_small, peak_full / math.sqrt(lam), rtol=1e-3)
    np.testing.assert_allclose(var_small, var_full * [lam**2, lam**2, 1.0], rtol=1e-3)
    # ... and so do the synthesised records.
    dt = 0.5
    t = np.arange(0.0, 4000.0, dt)
    rec_full = WaveField(full, SUPPLY, seed=3).body_motion(t, 0.0)
    rec_small = WaveField(small, model, seed=3).body_motion(t * math.sqrt(lam), 0.0)
    np.testing.assert_allclose(rec_small, rec_full * [lam, lam, 1.0], rtol=1e-9, atol=1e-12)
    assert welch_peak(rec_small[:, 1:2], dt * math.sqrt(lam))[0] == pytest.approx(
        welch_peak(rec_full[:, 1:2], dt)[0] / math.sqrt(lam), rel=1e-9
    )


def test_for_vessel_picks_data_or_scaling() -> None:
    assert WaveResponse.for_vessel(load_vessel("mss_supply")) is SUPPLY
    cs2 = WaveResponse.for_vessel(load_vessel("cybership2"))
    assert cs2.length_m == pytest.approx(CS2_LENGTH_M)
    assert WaveResponse.froude_scaled(MSS_SUPPLY_LPP_M).rao == pytest.approx(SUPPLY.rao)


def test_rotation_to_ned_and_motion_along_the_waves() -> None:
    """Body motion depends only on β = χ − ψ; NED motion is it rotated by ψ. In long waves the hull moves
    with the particles, so its velocity under a crest points where the waves travel."""
    chi, psi = 0.4, 2.0
    t = np.arange(0.0, 1200.0, 1.0)
    a = WaveField(SeaState(3.0, 9.0, direction_rad=chi), SUPPLY, seed=8).motion(t, psi)
    b = WaveField(SeaState(3.0, 9.0, direction_rad=chi - psi), SUPPLY, seed=8).motion(t, 0.0)
    c, s = math.cos(psi), math.sin(psi)
    np.testing.assert_allclose(a[:, 0], c * b[:, 0] - s * b[:, 1], atol=1e-12)
    np.testing.assert_allclose(a[:, 1], s * b[:, 0] + c * b[:, 1], atol=1e-12)
    np.testing.assert_allclose(a[:, 2], b[:, 2], atol=1e-15)

    swell = SeaState(2.0, 25.0, kind="pm", direction_rad=math.radians(-60))
    field = WaveField(swell, SUPPLY, seed=4)
    dt = 0.5
    t = np.arange(0.0, 3000.0, dt)
    zeta = field.elevation(t)
    for heading in (0.0, 1.0, math.pi, -2.5):
        eta = field.motion(t, heading)
        vel = np.gradient(eta[:, :2], dt, axis=0)
        along = vel @ [math.cos(swell.direction_rad), math.sin(swell.direction_rad)]
        assert np.corrcoef(along, zeta)[0, 1] > 0.95, heading


def test_wave_phase_travels_towards_direction() -> None:
    """One regular wave: the elevation at distance d along χ is the origin's delayed by d/c, c = g/ω."""
    sea = SeaState(2.0, 8.0, direction_rad=math.radians(200))
    field = WaveField(sea, SUPPLY, seed=2, n_components=1)
    w = float(field.components[0].omega[0])
    d = 37.0
    t = np.linspace(0.0, 60.0, 601)
    n, e = d * math.cos(sea.direction_rad), d * math.sin(sea.direction_rad)
    np.testing.assert_allclose(field.elevation(t, n, e), field.elevation(t - d / (G / w)), atol=1e-9)
    # Moving across the travel direction changes nothing.
    np.testing.assert_allclose(field.elevation(t, -e, n), field.elevation(t), atol=1e-9)
    np.testing.assert_allclose(field.motion(t, 0.3, -e, n), field.motion(t, 0.3), atol=1e-9)


def test_seed_reproducibility_and_time_varying_inputs() -> None:
    sea = SeaState(3.0, 9.0, direction_rad=1.0)
    t = np.arange(0.0, 600.0, 0.1)
    heading = 0.5 + 0.3 * np.sin(t / 100.0)  # slowly turning
    north, east = 0.2 * t, -0.1 * t  # slowly moving
    a = WaveField(sea, SUPPLY, seed=42).motion(t, heading, north, east)
    b = WaveField(sea, SUPPLY, seed=42).motion(t, heading, north, east)
    c = WaveField(sea, SUPPLY, seed=43).motion(t, heading, north, east)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c, atol=0.05 * np.abs(a).max())
    assert np.array_equal(
        WaveField(sea, SUPPLY, seed=7).elevation(t), WaveField(sea, SUPPLY, seed=7).elevation(t)
    )
    # The chunk size only bounds memory (results agree to rounding: BLAS blocks the sums differently).
    chunked = WaveField(sea, SUPPLY, seed=42, chunk_size=777).motion(t, heading, north, east)
    np.testing.assert_allclose(chunked, a, rtol=0, atol=1e-12)
    # Sample-by-sample evaluation agrees with the vectorised one (heading per sample, β interpolated).
    f = WaveField(sea, SUPPLY, seed=42)
    for i in (0, 1234, 5999):
        np.testing.assert_allclose(f.motion(t[i], heading[i], north[i], east[i]), a[i], atol=1e-12)
    assert f.motion(t[0], heading[0]).shape == (3,)
    assert f.motion(t.reshape(60, 100), 0.0).shape == (60, 100, 3)


def test_sea_state_change_mid_run() -> None:
    calm, rough = SeaState(1.5, 7.0, direction_rad=0.0), SeaState(5.0, 11.0, direction_rad=1.2)
    t_change, fade = 2400.0, 60.0
    field = WaveField([(0.0, calm), (t_change, rough)], SUPPLY, seed=9, fade_s=fade)
    dt = 0.25
    t = np.arange(0.0, 2 * t_change, dt)
    zeta = field.elevation(t)
    before, after = zeta[t < t_change], zeta[t >= t_change + fade]
    assert before.var() == pytest.approx(calm.hs_m**2 / 16, rel=0.10)
    assert after.var() == pytest.approx(rough.hs_m**2 / 16, rel=0.10)
    # Before the change the record is exactly the calm sea's: adding a sea state does not reshuffle the past.
    np.testing.assert_array_equal(before, WaveField(calm, SUPPLY, seed=9).elevation(t[t < t_change]))
    # No jump: the signal is continuous at both ends of the cross-fade, and no step exceeds the bound
    # dt · Σ (ω + |w'|) a of both fields.
    eps = 1e-7
    for tc in (t_change, t_change + fade):
        z = field.elevation(np.array([tc - eps, tc + eps]))
        assert abs(z[1] - z[0]) < 1e-5
        m = field.motion(np.array([tc - eps, tc + eps]), 0.3)
        assert np.max(np.abs(m[1] - m[0])) < 1e-5
    bound = dt * sum(np.sum((c.omega + math.pi / (2 * fade)) * c.amplitude) for c in field.components)
    assert np.max(np.abs(np.diff(zeta))) < bound
    assert field.peak_frequency(np.array([0.0, t_change + 10, t_change + 50])) == pytest.approx(
        [calm.peak_frequency, calm.peak_frequency, rough.peak_frequency]
    )
    assert field.sea_state_at(1e5) is rough and field.sea_state_at(-10.0) is calm
    # The mean drift follows the sea states with their power weights.
    drift = field.drift_force(np.array([10.0, t_change + fade + 1]), 0.0)
    np.testing.assert_allclose(drift[0], WaveField(calm, SUPPLY, seed=9).drift_force(0.0, 0.0))


def test_drift_force_mean_and_slowly_varying() -> None:
    sea = SeaState(4.0, 9.0, direction_rad=math.radians(100))
    field = WaveField(sea, SUPPLY, seed=21)
    mean = field.drift_force(0.0, 0.0)
    expected = SUPPLY.mean_drift_force(sea, 0.0)
    assert mean[0] == pytest.approx(expected[0], rel=0.05)
    assert mean[1] == pytest.approx(expected[1], rel=0.05)
    assert mean[1] > 0  # waves travel to starboard: pushed to starboard
    t = np.arange(0.0, 3 * 3600.0, 1.0)
    sv = field.drift_force(t, 0.0, slowly_varying=True)
    assert sv[:, 1].mean() == pytest.approx(mean[1], rel=0.15)
    assert sv[:, 1].std() > 0.2 * mean[1]  # it does vary, slowly
    f, P = welch(sv[:, 1], fs=1.0, nperseg=2048)
    assert 2 * math.pi * f[np.argmax(P[1:]) + 1] < 0.5 * sea.peak_frequency  # difference frequencies only


def test_motion_gain_limits() -> None:
    field = WaveField(SeaState(4.0, 10.0, direction_rad=2.0), SUPPLY, seed=1)
    t = np.arange(0.0, 1800.0, 0.5)
    limits = (10.0, 10.0, math.radians(1.0))
    gain = field.gain_for_limits(limits, t, 0.5)
    eta = field.with_motion_gain(gain).motion(t, 0.5)
    np.testing.assert_allclose(np.max(np.abs(eta), axis=0), limits, rtol=1e-9)
    np.testing.assert_allclose(field.motion(t[:10], 0.5) * gain, eta[:10])


def test_wave_field_validation() -> None:
    sea = SeaState(2.0, 8.0)
    for schedule in ([], [(0.0, sea), (30.0, sea)], [(10.0, sea), (0.0, sea)], [(0.0, "sea")]):
        with pytest.raises(ValueError):
            WaveField(schedule, SUPPLY, seed=1)  # type: ignore[arg-type]
    for kwargs in ({"n_components": 0}, {"fade_s": -1.0}, {"motion_gain": (1.0, 2.0)}, {"chunk_size": 0}):
        with pytest.raises(ValueError):
            WaveField(sea, SUPPLY, seed=1, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        WaveResponse.froude_scaled(-1.0)
    # A calm sea is a valid sea with no motion.
    calm = WaveField(SeaState(0.0, 8.0), SUPPLY, seed=1)
    assert np.all(calm.motion(np.arange(10.0), 0.0) == 0.0)


def test_attitude_raos_follow_the_long_wave_surface() -> None:
    """Heave, roll and pitch of the supply vessel in long waves move with the surface: heave −ζ (z down,
    phase π), pitch with the slope in a following sea (−π/2, bow up), roll with it in beam waves from port
    (+π/2, starboard down); Froude scaling divides the rotations by λ."""
    resp = WaveResponse.mss_supply()
    w = float(resp.omega[0])
    heave = resp.attitude_at(w, 0.0)[0]
    pitch = resp.attitude_at(w, 0.0)[2]
    roll = resp.attitude_at(w, math.pi / 2)[1]
    assert abs(heave) == pytest.approx(1.0, abs=0.05)
    assert abs(np.angle(heave * np.exp(-1j * math.pi))) < math.radians(10)
    assert abs(np.angle(pitch * np.exp(1j * math.pi / 2))) < math.radians(10)
    assert abs(np.angle(roll * np.exp(-1j * math.pi / 2))) < math.radians(10)
    scaled = resp.scaled(0.5)
    np.testing.assert_allclose(
        scaled.attitude_at(w / math.sqrt(0.5), 0.3), resp.attitude_at(w, 0.3) * [1, 2, 2]
    )


def test_motion_with_attitude_is_motion_and_attitude() -> None:
    sea = SeaState(hs_m=4.0, tp_s=10.0, direction_rad=math.radians(200.0))
    field = WaveField(sea, WaveResponse.mss_supply(), seed=3)
    t = np.arange(0.0, 120.0, 0.5)
    eta, att = field.motion_with_attitude(t, 2.0, 1.0, -2.0)
    np.testing.assert_allclose(eta, field.motion(t, 2.0, 1.0, -2.0), atol=1e-12)
    np.testing.assert_allclose(att, field.attitude(t, 2.0, 1.0, -2.0), atol=1e-12)
    assert np.std(att[:, 1]) > math.radians(0.5)  # beam waves: it rolls
    level = WaveField(sea, WaveResponse.froude_scaled(50.0), seed=3)
    assert np.std(level.attitude(t, 2.0)[:, 1]) > 0.0
    flat = replace(WaveResponse.mss_supply(), attitude=None)
    assert not np.any(WaveField(sea, flat, seed=3).attitude(t, 2.0))


# the compiled block synthesis against the numpy path it stands in for (the simulator's 2 s blocks)
_BLOCK_FIELDS = {
    "one sea, attitude, motion gain": WaveField(
        SeaState(hs_m=4.0, tp_s=10.0, direction_rad=math.radians(200.0)), SUPPLY, seed=3
    ).with_motion_gain((0.5, 2.0, 1.5)),
    "no attitude RAOs": WaveField(
        SeaState(hs_m=6.0, tp_s=11.5, direction_rad=math.radians(255.0)),
        replace(WaveResponse.mss_supply(), attitude=None),
        seed=5,
    ),
    "a sea change (cross-fade 100-140 s)": WaveField(
        [
            (0.0, SeaState(hs_m=2.0, tp_s=6.0, direction_rad=1.0)),
            (100.0, SeaState(hs_m=5.0, tp_s=12.0, direction_rad=-2.0)),
        ],
        WaveResponse.froude_scaled(70.0),
        seed=7,
        fade_s=40.0,
    ),
}


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(sorted(_BLOCK_FIELDS)),
    t0=st.one_of(st.floats(0.0, 3600.0), st.floats(90.0, 150.0)),  # (the fade, often)
    heading=st.floats(-4.0, 4.0),
    north=st.floats(-500.0, 500.0),
    east=st.floats(-500.0, 500.0),
)
def test_motion_block_is_motion_with_attitude_on_its_grid(
    name: str, t0: float, heading: float, north: float, east: float
) -> None:
    """`motion_block` (compiled carrier recurrence, β interpolated once) gives the numpy path's motion and
    attitude on the grid t0 + 0.05 s·k to round-off: 1e-9 of each quantity's amplitude in the block."""
    field = _BLOCK_FIELDS[name]
    n = 41
    grid = t0 + 0.05 * np.arange(n)
    eta, att = field.motion_with_attitude(grid, heading, north, east)
    expected = np.hstack([eta, att])
    got = field.motion_block(t0, 0.05, n, heading, north, east)
    scale = np.maximum(np.max(np.abs(expected), axis=0), 1e-12)
    assert np.all(np.abs(got - expected) <= 1e-9 * scale + 1e-15)
    if name == "no attitude RAOs":
        assert not np.any(got[:, 3:])
