"""Wind feed-forward (`gateway.control.wind_feedforward`, `DPController(..., relative_wind=...)`): the
force it cancels is the plant's wind force for the same relative wind, the filter is the first-order
low-pass it says, the gain and filter are checked at start-up, and the compiled controller step adds it as
the reference does."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gateway.control.controller import ControllerError, ControllerTuning, DPController
from gateway.control.wind_feedforward import WindFeedForward
from observers.hull import apparent_wind_body, relative_wind, relative_wind_force
from observers.vessel import load_vessel
from simulator.wind import Wind, WindModel, wind_force


@pytest.fixture(scope="module")
def supply():  # type: ignore[no-untyped-def]
    return load_vessel("mss_supply")


@pytest.mark.parametrize("from_deg", [0.0, 37.0, 85.0, 133.0, 180.0, 251.0, 315.0])
@pytest.mark.parametrize(("psi", "u", "v"), [(0.0, 0.0, 0.0), (0.8, 0.4, -0.2), (-2.5, -1.0, 0.5)])
def test_feedforward_cancels_the_plants_wind_force(
    supply, from_deg: float, psi: float, u: float, v: float
) -> None:  # type: ignore[no-untyped-def]
    """The feed-forward of a steady measured wind is exactly minus the plant's force: the anemometer's speed
    and angle from the bow, back to components, through the one force function."""
    area = supply.hull.wind
    plant = Wind(WindModel(15.0, from_deg, gust="none"), area, supply.length_m, np.random.default_rng(0))
    force = plant.force_body(0.0, psi, u, v)
    urw, vrw = relative_wind(plant.mean, from_deg, psi, u, v)
    speed, angle = math.hypot(urw, vrw), math.atan2(vrw, urw)  # what MWV (reference R) carries
    ff = WindFeedForward(area, supply.length_m, filter_s=2.0, gain=1.0)
    for _ in range(400):  # 40 s at 10 Hz: 20 time constants, the filter has converged (e^-20)
        tau = ff.update(0.1, apparent_wind_body(speed, angle))
    scale = max(abs(f) for f in force) + 1.0
    np.testing.assert_allclose(tau, -np.array(force), rtol=0, atol=1e-6 * scale)
    assert wind_force(area, supply.length_m, plant.mean, from_deg, psi, u, v) == force
    assert relative_wind_force(area, supply.length_m, urw, vrw) == force


def test_a_head_wind_pushes_aft_and_a_beam_wind_to_lee(supply) -> None:  # type: ignore[no-untyped-def]
    area, length = supply.hull.wind, supply.length_m
    x, y, _ = relative_wind_force(area, length, *apparent_wind_body(15.0, 0.0))
    assert x < 0 and abs(y) < 1e-6 * abs(x)
    x, y, _ = relative_wind_force(area, length, *apparent_wind_body(15.0, math.pi / 2))  # from starboard
    assert y < 0 and abs(x) < 1e-6 * abs(y)


def test_the_filter_is_a_first_order_low_pass_at_any_rate(supply) -> None:  # type: ignore[no-untyped-def]
    area, length = supply.hull.wind, supply.length_m
    out = {}
    for dt in (0.1, 0.5, 1.0):
        ff = WindFeedForward(area, length, filter_s=4.0, gain=1.0)
        ff.update(0.0, (0.0, 0.0))
        for _ in range(round(4.0 / dt)):
            ff.update(dt, (10.0, -5.0))
        out[dt] = ff.filtered
    for u, v in out.values():
        assert u == pytest.approx(10.0 * (1 - math.exp(-1)), rel=1e-12)
        assert v == pytest.approx(-5.0 * (1 - math.exp(-1)), rel=1e-12)


def test_stale_wind_turns_it_off_and_it_ramps_back(supply) -> None:  # type: ignore[no-untyped-def]
    ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=1.0)
    for _ in range(200):
        ff.update(0.1, (15.0, 3.0))
    full = ff.tau.copy()
    assert ff.active and np.all(np.abs(full) > 0)
    assert np.all(ff.update(0.1, None) == 0) and not ff.active
    assert np.all(ff.update(0.1, (math.nan, 1.0)) == 0) and not ff.active
    back = ff.update(0.1, (15.0, 3.0))
    assert ff.active and 0 < abs(back[0]) < 0.01 * abs(full[0])  # from zero, not a step


def test_gain_scales_and_bad_tuning_stops_start_up(supply) -> None:  # type: ignore[no-untyped-def]
    half = WindFeedForward(supply.hull.wind, supply.length_m, 2.0, 0.5)
    full = WindFeedForward(supply.hull.wind, supply.length_m, 2.0, 1.0)
    for _ in range(50):
        a, b = half.update(0.1, (12.0, 4.0)), full.update(0.1, (12.0, 4.0))
    np.testing.assert_allclose(a, 0.5 * b, rtol=1e-12)
    for bad in (-0.1, 1.5, math.nan, True):
        with pytest.raises(ControllerError, match="wind_feedforward_gain"):
            DPController(supply, ControllerTuning(wind_feedforward_gain=bad))
    for bad_s in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ControllerError, match="wind_filter_s"):
            DPController(supply, ControllerTuning(wind_filter_s=bad_s))
    assert DPController(supply, ControllerTuning(wind_feedforward_gain=0.0)).wind is None
    assert DPController(load_vessel("cybership2")).wind is None  # no [hull.wind]
    assert DPController(supply).wind is not None


@pytest.mark.parametrize("compiled", [False, True])
def test_controller_adds_the_wind_term_to_tau(supply, compiled: bool) -> None:  # type: ignore[no-untyped-def]
    """Two controllers on the same estimates, one with a measured wind: τ differs by exactly τ_wind (the
    integrator sees the same errors), compiled and readable step alike; in standby nothing is commanded."""
    with_wind = DPController(supply, compiled=compiled)
    without = DPController(supply, compiled=compiled)
    rng = np.random.default_rng(1)
    for ctl in (with_wind, without):
        ctl.set_mode("dp")
    wind = (14.0, 6.0)
    for k in range(300):
        eta = np.array([0.5, -0.3, 0.2]) + 0.1 * rng.standard_normal(3)
        nu = 0.01 * rng.standard_normal(3)
        t = 0.1 * k
        a = with_wind.update(t, eta, nu, None, relative_wind=wind)
        b = without.update(t, eta, nu, None, relative_wind=wind if k < 0 else None)
        np.testing.assert_allclose(a.tau - b.tau, a.tau_wind, rtol=0, atol=1e-6 * (1 + np.abs(a.tau).max()))
        np.testing.assert_allclose(
            a.tau_ff - b.tau_ff, a.tau_wind, rtol=0, atol=1e-9 * (1 + np.abs(a.tau).max())
        )
    force = relative_wind_force(supply.hull.wind, supply.length_m, *wind)
    np.testing.assert_allclose(a.tau_wind, -np.array(force), rtol=1e-6)
    assert np.all(b.tau_wind == 0)
    with_wind.set_mode("standby")
    o = with_wind.update(30.0, eta, nu, None, relative_wind=wind)
    assert np.all(o.tau == 0) and np.all(o.tau_wind == 0)


def test_compiled_and_readable_agree_with_wind_and_saturation(supply) -> None:  # type: ignore[no-untyped-def]
    fast, ref = DPController(supply, compiled=True), DPController(supply, compiled=False)
    rng = np.random.default_rng(7)
    for ctl in (fast, ref):
        ctl.set_mode("dp")
    for k in range(400):
        eta = np.array([1.0, 0.5, 0.1]) + 0.2 * rng.standard_normal(3)
        nu = 0.02 * rng.standard_normal(3)
        wind = None if 150 <= k < 170 else (10.0 + rng.standard_normal(), 5.0 + rng.standard_normal())
        sat = k % 7 == 0
        alloc = fast.tau * 0.8 if sat else None
        a = fast.update(0.1 * k, eta, nu, None, saturated=sat, tau_allocated=alloc, relative_wind=wind)
        b = ref.update(0.1 * k, eta, nu, None, saturated=sat, tau_allocated=alloc, relative_wind=wind)
        scale = 1.0 + np.abs(b.tau).max()
        np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(a.tau_wind, b.tau_wind, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(a.integral, b.integral, rtol=1e-9, atol=1e-9)
