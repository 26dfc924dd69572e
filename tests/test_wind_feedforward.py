"""Wind feed-forward (`gateway.control.wind_feedforward`, `DPController(..., relative_wind=...)`): the
force it cancels is the plant's wind force for the same relative wind, the filter is the first-order
low-pass it says, the gain and filter are checked at start-up, and the compiled controller step adds it as
the reference does."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gateway.control.controller import ControllerError, ControllerTuning, DPController
from gateway.control.wind_feedforward import Array, WindFeedForward, default_fade_s
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


# -- losing the wind: hold and fade ---------------------------------------------------------------------
def _steady(ff: WindFeedForward, wind: tuple[float, float], seconds: float = 30.0, dt: float = 0.1) -> Array:
    for _ in range(round(seconds / dt)):
        ff.update(dt, wind)
    return ff.tau.copy()


@pytest.mark.parametrize("dt", [0.1, 0.25, 1.0])
def test_a_lost_wind_is_held_and_faded_out_linearly(supply, dt: float) -> None:  # type: ignore[no-untyped-def]
    """After the loss τ_wind = (1 − t/T_f) τ_held in every component (direction kept), at any control step,
    zero from T_f on; the first step after the loss is no step in the thrust demand."""
    fade = 40.0
    ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=0.8, fade_s=fade)
    held = _steady(ff, (14.0, -6.0))
    held_wind = ff.filtered
    assert np.all(np.abs(held) > 1e3)
    n_fade = round(fade / dt)
    for k in range(1, n_fade + 5):
        tau = ff.update(dt, None)
        w = max(0.0, 1.0 - k * dt / fade)
        np.testing.assert_allclose(tau, w * held, rtol=1e-9, atol=1e-9 * np.abs(held).max())
        assert ff.fading == (w > 0) and not ff.active
    assert np.all(ff.tau == 0) and ff.weight == 0.0
    assert ff.filtered == held_wind  # the filter holds the lost wind


def test_a_lost_wind_turns_with_the_vessel_it_is_held_for(supply) -> None:  # type: ignore[no-untyped-def]
    """The held wind is relative, in body axes. A vessel that turns while the anemometer is out must keep
    the wind where it is on the earth: 15 m/s from the north, the vessel heading north then turned to
    south (half a minute into a 300 s fade), the held feed-forward must push north-going (+X at heading 0,
    then −X at heading π: still against the wind, which now comes from astern) — held in body axes it
    would push the vessel ahead, i.e. southward, with the wind, doubling the load it was there to cancel.
    Checked against the plant's force for the same true wind at the new heading."""
    area, length = supply.hull.wind, supply.length_m
    ff = WindFeedForward(area, length, filter_s=2.0, gain=1.0, fade_s=300.0)
    for _ in range(400):
        ff.update(0.1, relative_wind(15.0, 0.0, 0.0, 0.0, 0.0), psi=0.0)
    assert ff.tau[0] > 0  # a head wind pushes aft; the feed-forward ahead
    for k in range(1, 301):  # 30 s without wind, turning 180° at 6°/s
        psi = math.pi * k / 300
        tau = ff.update(0.1, None, psi=psi)
    w = ff.weight
    plant = np.array(wind_force(area, length, 15.0, 0.0, math.pi, 0.0, 0.0))  # the north wind, from astern
    np.testing.assert_allclose(tau, -w * plant, rtol=1e-9, atol=1e-6 * np.abs(plant).max())
    assert tau[0] < 0
    # without a heading the held wind stays as it was
    ff2 = WindFeedForward(area, length, filter_s=2.0, gain=1.0, fade_s=300.0)
    _steady(ff2, (14.0, -6.0))
    held = ff2.filtered
    ff2.update(0.1, None)
    assert ff2.filtered == held
    # the controller hands it the estimated heading: a lost wind held through a half turn pushes against it
    ctl = DPController(supply)
    ctl.set_mode("dp")
    nu = np.zeros(3)
    for k in range(300):
        ctl.update(0.1 * k, np.zeros(3), nu, None, relative_wind=relative_wind(15.0, 0.0, 0.0, 0.0, 0.0))
    o = ctl.update(30.1, np.array([0.0, 0.0, math.pi]), nu, None, relative_wind=None)
    assert ctl.wind is not None and ctl.wind.fading and o.tau_wind[0] < 0


def test_invalid_wind_fades_like_a_missing_one(supply) -> None:  # type: ignore[no-untyped-def]
    a = WindFeedForward(supply.hull.wind, supply.length_m, 2.0, 1.0, fade_s=20.0)
    b = WindFeedForward(supply.hull.wind, supply.length_m, 2.0, 1.0, fade_s=20.0)
    _steady(a, (12.0, 5.0)), _steady(b, (12.0, 5.0))
    bad: list[tuple[float, float] | None] = [(math.nan, 1.0), (1.0, math.inf), (-math.inf, math.nan)]
    for k in range(60):
        np.testing.assert_array_equal(a.update(0.1, None), b.update(0.1, bad[k % 3]))
    assert a.fading and b.fading and 0.65 < b.weight < 0.75
    # a non-finite or negative step does not move the fade (nor the filter)
    w = b.weight
    for dt in (math.nan, -1.0, math.inf, 0.0):
        b.update(dt, None)
        assert b.weight == w and np.all(np.isfinite(b.tau))


def test_wind_back_while_fading_continues_from_the_faded_force(supply) -> None:  # type: ignore[no-untyped-def]
    """Lost for 10 s of a 40 s fade (w = 0.75), then back: the first τ is w (+ one step of the fade in) times
    the force of the held filter state moved one filter step toward the new measurement — continuous, not
    from zero — and w climbs back to 1 at the fade's pace (10 s), the filter following the new wind."""
    ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=1.0, fade_s=40.0)
    held = _steady(ff, (15.0, 3.0))
    u0, v0 = ff.filtered
    for _ in range(100):
        faded = ff.update(0.1, None)
    np.testing.assert_allclose(faded, 0.75 * held, rtol=1e-9)
    assert ff.filtered == (u0, v0)
    new_wind = (13.0, 5.0)  # the wind changed meanwhile
    back = ff.update(0.1, new_wind)
    assert ff.active and ff.fading_in and not ff.fading
    alpha = 1.0 - math.exp(-0.1 / 2.0)
    uv = (u0 + alpha * (new_wind[0] - u0), v0 + alpha * (new_wind[1] - v0))
    np.testing.assert_allclose(ff.filtered, uv, rtol=1e-12)
    x, y, n = relative_wind_force(supply.hull.wind, supply.length_m, *uv)
    np.testing.assert_allclose(back, -(0.75 + 0.1 / 40.0) * np.array([x, y, n]), rtol=1e-9)
    assert np.all(np.abs(back - faded) < 0.05 * np.abs(held))  # no step
    full = -np.array(relative_wind_force(supply.hull.wind, supply.length_m, *new_wind))
    for k in range(2, 101):
        ff.update(0.1, new_wind)
        w = min(1.0, 0.75 + k * 0.1 / 40.0)
        assert ff.weight == pytest.approx(w, abs=1e-12)
    assert ff.weight == 1.0 and not ff.fading_in
    np.testing.assert_allclose(_steady(ff, new_wind, 20.0), full, rtol=1e-6)  # and the filter converged


def test_wind_back_after_a_complete_fade_fades_in_over_the_fade_time(supply) -> None:  # type: ignore[no-untyped-def]
    """After a complete fade b̂ holds the whole wind; the returning wind's force comes back as it went,
    linearly over T_f (the observer hands the load back at that pace), not in the filter's few seconds."""
    ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=1.0, fade_s=5.0)
    full = _steady(ff, (15.0, 3.0))
    for _ in range(60):
        ff.update(0.1, None)
    assert not ff.fading and np.all(ff.tau == 0)
    for k in range(1, 51):
        tau = ff.update(0.1, (15.0, 3.0))
        np.testing.assert_allclose(tau, min(1.0, k * 0.1 / 5.0) * full, rtol=1e-6)
    assert ff.weight == 1.0 and not ff.fading_in


def test_the_first_wind_comes_in_through_the_filter_alone(supply) -> None:  # type: ignore[no-untyped-def]
    """At the start (and after `reset`) there is no load for b̂ to hand back: the first wind is fed forward in
    full through the filter's ramp (≈ 3 T_w), as without a fade."""
    for fade in (0.0, 286.0):
        ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=1.0, fade_s=fade)
        ff.update(0.0, (15.0, 3.0))
        assert ff.weight == 1.0 and not ff.fading_in
        tau = _steady(ff, (15.0, 3.0), seconds=6.0)
        full = -np.array(relative_wind_force(supply.hull.wind, supply.length_m, 15.0, 3.0))
        assert np.all(np.abs(tau) > 0.9 * np.abs(full))
        ff.reset()
        assert ff.weight == 0.0 and ff.filtered == (0.0, 0.0) and np.all(ff.tau == 0)


def test_a_loss_during_the_fade_in_restarts_the_fade_from_the_present_force(supply) -> None:  # type: ignore[no-untyped-def]
    """Lost, back briefly, lost again (a flapping anemometer): every loss holds the present force, so the
    output is continuous through every change and never exceeds the last measured force."""
    ff = WindFeedForward(supply.hull.wind, supply.length_m, filter_s=2.0, gain=1.0, fade_s=60.0)
    full = _steady(ff, (12.0, -4.0))
    prev = full
    rng = np.random.default_rng(3)
    for _ in range(600):
        wind = (12.0, -4.0) if rng.random() < 0.3 else None
        tau = ff.update(0.1, wind)
        assert np.all(np.abs(tau - prev) <= 0.06 * np.abs(full))  # ≤ one filter step (1 − e^−0.05 ≈ 5 %)
        assert np.all(np.abs(tau) <= np.abs(full) * (1 + 1e-6))  # (30 s of filter: converged to e^-15)
        prev = tau


def test_fade_time_default_and_checks(supply) -> None:  # type: ignore[no-untyped-def]
    """Default T_f = 2 max(T_i, T_b); [control] wind_loss_fade_s = 0 drops at once; a bad value stops
    start-up naming the field."""
    assert default_fade_s(143.0, 96.0) == 2 * 143.0
    assert default_fade_s(100.0, 250.0) == 2 * 250.0
    assert default_fade_s(math.inf, 50.0) == 100.0 and default_fade_s(80.0, None) == 160.0
    assert default_fade_s(math.inf, None) == 0.0
    ctl = DPController(supply)
    a = ctl.gains.integral_pole
    assert ctl.wind is not None and ctl.wind.fade_s == pytest.approx(2.0 / a.min())  # 286 s at 76.2 m
    slow_observer = DPController(supply, observer_bias_time_s=400.0)
    assert slow_observer.wind is not None and slow_observer.wind.fade_s == 800.0
    at_once = DPController(supply, ControllerTuning(wind_loss_fade_s=0.0))
    assert at_once.wind is not None and at_once.wind.fade_s == 0.0
    for bad in (-1.0, math.nan, math.inf, True, "slow"):
        with pytest.raises(ControllerError, match="wind_loss_fade_s"):
            DPController(supply, ControllerTuning(wind_loss_fade_s=bad))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="fade"):
        WindFeedForward(supply.hull.wind, supply.length_m, 2.0, 1.0, fade_s=-1.0)
    from gateway.control.wind_feedforward import observer_bias_time_s
    from observers.factory import make_observer

    t_b = observer_bias_time_s(make_observer("passive", supply))
    assert t_b is not None and 10.0 < t_b < 1000.0
    assert observer_bias_time_s(object()) is None
    # another observer: the time constant behind its own settle time (the SDRE's slowest A − KC pole)
    from observers.settling import ENGAGE_TIME_CONSTANTS, UNKNOWN_SETTLE_S

    sdre = make_observer("sdre", supply)
    assert observer_bias_time_s(sdre) == pytest.approx(sdre.settle_time_s / ENGAGE_TIME_CONSTANTS)
    assert 1.0 < sdre.settle_time_s < UNKNOWN_SETTLE_S

    class Unknowable:
        settle_time_s = UNKNOWN_SETTLE_S

    assert observer_bias_time_s(Unknowable()) is None
