"""Every registered observer keeps every promise of `observers.base.Observer`.

Parametrised over the registry (`observers.factory.OBSERVERS`), so an observer registered later is checked
with no change here. Each observer is built by name with its defaults, as the gateway builds it.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from observers.base import STATUS_NAMES, Estimate, Observer, Run
from observers.factory import OBSERVER_PARAMS, OBSERVERS, ObserverSpecError, make_observer
from observers.kinematics import ssa
from observers.vessel import load_vessel

VESSEL = load_vessel("mss_supply")
NAMES = sorted(OBSERVERS)
FIELDS = ("eta", "nu", "bias", "eta_wf")


def record(seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """90 s at about 10 Hz of wave motion on a drift, with what real data has: noise, irregular intervals,
    a repeated time stamp, lost fixes, a 3 s outage of everything, a heading crossing ±180°."""
    rng = np.random.default_rng(seed)
    n = 900
    t = np.arange(n) / 10.0 + rng.uniform(0.0, 0.02, n)
    t[400] = t[399]  # a repeated time stamp: the sample is not used
    w = 2 * math.pi / 9.0
    y = np.c_[
        2.0 * np.sin(w * t) + 0.02 * t + 0.3 * rng.standard_normal(n),
        1.5 * np.cos(0.9 * w * t) - 0.01 * t + 0.3 * rng.standard_normal(n),
        ssa(3.0 + 0.03 * np.sin(w * t) + 0.002 * t + 0.002 * rng.standard_normal(n)),
    ]
    y[:3, :2] = np.nan  # no position yet: the observer waits
    y[rng.random(n) < 0.03, :2] = np.nan
    y[500:530] = np.nan
    tau = np.array([1e5, -5e4, 2e6]) + rng.normal(0.0, 1e4, (n, 3))
    return t, y, tau


def build(name: str) -> Observer:
    return make_observer(name, VESSEL)


def assert_same_estimate(a: Estimate, b: Estimate) -> None:
    """Bit for bit (NaN where NaN)."""
    assert (a.t, a.status) == (b.t, b.status)
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


@pytest.mark.parametrize("name", NAMES)
def test_built_by_name_it_implements_the_protocol(name: str) -> None:
    obs = build(name)
    assert isinstance(obs, Observer)
    for member in ("initialize", "step", "run", "predict", "reset", "extra"):
        assert callable(getattr(obs, member)), member
    assert obs.initialized is False and obs.t == 0.0
    assert OBSERVERS[name].params == OBSERVER_PARAMS[name]
    with pytest.raises(ObserverSpecError, match="no_such_setting"):
        make_observer(name, VESSEL, params={"no_such_setting": 1})


@pytest.mark.parametrize("name", NAMES)
def test_step_returns_the_base_estimate(name: str) -> None:
    obs = build(name)
    first = obs.step(0.0, [np.nan, np.nan, 0.5])
    assert isinstance(first, Estimate) and first.status == "initializing" and not first.initialized
    assert all(np.all(np.isnan(getattr(first, f))) for f in FIELDS)
    assert not obs.initialized
    est = obs.step(0.1, [10.0, -4.0, 0.5], [1e5, 0.0, 0.0])
    assert isinstance(est, Estimate) and est.status == "ok" and est.initialized and est.t == 0.1
    assert obs.initialized and obs.t == 0.1
    for f in FIELDS:
        v = getattr(est, f)
        assert v.shape == (3,) and np.all(np.isfinite(v)), f
    np.testing.assert_allclose(est.eta + est.eta_wf, [10.0, -4.0, 0.5], atol=0.05)  # starts near y
    assert obs.step(0.2, [10.0, np.nan, 0.5]).status == "dead_reckoning"


@pytest.mark.parametrize("name", NAMES)
def test_run_equals_stepping_sample_by_sample(name: str) -> None:
    t, y, tau = record()
    batch, stepped = build(name), build(name)
    run = batch.run(t, y, tau)
    assert isinstance(run, Run) and len(run) == t.size
    assert run.omega0.shape == (t.size, 3)
    assert set(STATUS_NAMES[int(c)] for c in run.status) == {"initializing", "ok", "dead_reckoning"}
    for k in range(t.size):
        est = stepped.step(t[k], y[k], tau[k])
        assert_same_estimate(est, run.estimate(k))
        np.testing.assert_array_equal(stepped.omega0, run.omega0[k])
    assert stepped.t == batch.t and stepped.initialized == batch.initialized
    assert stepped.extra() == batch.extra()
    # in two pieces: the same again (a record may be replayed in chunks)
    pieces = build(name)
    half = t.size // 2
    r1, r2 = pieces.run(t[:half], y[:half], tau[:half]), pieces.run(t[half:], y[half:], tau[half:])
    for f in (*FIELDS, "status", "omega0"):
        np.testing.assert_array_equal(np.r_[getattr(r1, f), getattr(r2, f)], getattr(run, f), err_msg=f)
    assert pieces.extra() == batch.extra()


@pytest.mark.parametrize("name", NAMES)
def test_predict_advances_time_without_a_measurement(name: str) -> None:
    t, y, tau = (a[:300] for a in record())
    obs = build(name)
    obs.run(t, y, tau)
    twin = copy.deepcopy(obs)
    t_next = obs.t + 0.7
    est = obs.predict(t_next, tau[-1])
    assert isinstance(est, Estimate) and est.status == "dead_reckoning" and est.t == t_next
    assert obs.t == t_next
    assert_same_estimate(est, twin.step(t_next, [np.nan] * 3, tau[-1]))  # predict = step without y
    later = obs.predict(t_next + 1.0)  # τ omitted: zero
    assert obs.t == t_next + 1.0 and later.status == "dead_reckoning"
    assert not np.array_equal(later.eta, est.eta)  # it moved: the state was advanced, not held
    assert obs.predict(t_next).t == t_next and obs.t == t_next + 1.0  # backward: nothing is undone


@pytest.mark.parametrize("name", NAMES)
def test_reset_returns_to_the_uninitialised_state(name: str) -> None:
    t, y, tau = (a[:600] for a in record())
    fresh = build(name)
    expected = fresh.run(t, y, tau)
    extra = fresh.extra()
    obs = build(name)
    obs.run(t[::-1] + 100.0, y[::-1], tau)  # any history at all
    obs.reset()
    assert not obs.initialized and obs.t == 0.0
    assert obs.step(0.0, [np.nan] * 3).status == "initializing"
    obs.reset()
    again = obs.run(t, y, tau)
    for f in (*FIELDS, "status", "omega0"):
        np.testing.assert_array_equal(getattr(again, f), getattr(expected, f), err_msg=f)
    assert obs.extra() == extra


@pytest.mark.parametrize("name", NAMES)
def test_initialize_sets_the_state(name: str) -> None:
    obs = build(name)
    eta = np.array([120.0, -45.0, 3.1 + 2 * math.pi])  # heading given unwrapped
    nu = np.array([0.4, -0.1, 0.003])
    bias = np.array([2e4, -3e4, 1e6])
    eta_wf = np.array([0.6, -0.2, 0.004])
    obs.initialize(50.0, eta, nu=nu, bias=bias, eta_wf=eta_wf)
    assert obs.initialized and obs.t == 50.0
    now = obs.predict(50.0)  # no time passes: the state as set
    np.testing.assert_allclose(now.eta, [120.0, -45.0, 3.1], rtol=1e-12)
    np.testing.assert_allclose(now.nu, nu, rtol=1e-12)
    np.testing.assert_allclose(now.bias, bias, rtol=1e-12)
    np.testing.assert_allclose(now.eta_wf, eta_wf, rtol=1e-12, atol=1e-15)
    assert obs.t == 50.0
    # omitted parts are zero; the observer goes on from the explicit start, not from the next measurement
    obs.initialize(0.0, [1.0, 2.0, -0.5])
    start = obs.predict(0.0)
    np.testing.assert_allclose(start.eta, [1.0, 2.0, -0.5], rtol=1e-12)
    assert np.all(start.nu == 0.0) and np.all(start.bias == 0.0) and np.all(start.eta_wf == 0.0)
    est = obs.step(0.1, [30.0, 2.0, -0.5])
    assert est.status == "ok" and est.eta[0] < 15.0


@pytest.mark.parametrize("name", NAMES)
def test_omega0_and_extra(name: str) -> None:
    obs = build(name)
    t, y, tau = record()

    def check() -> None:
        w = obs.omega0
        assert isinstance(w, np.ndarray) and w.shape == (3,) and np.all(np.isfinite(w) & (w > 0))
        extra = obs.extra()
        assert isinstance(extra, dict)
        assert json.loads(json.dumps(extra, allow_nan=False)) == json.loads(json.dumps(extra))

    check()
    obs.run(t[:450], y[:450], tau[:450])
    check()
    for k in range(450, t.size):
        obs.step(t[k], y[k], tau[k])
    check()
    w = obs.omega0
    w[:] = -1.0  # a copy: writing to it changes nothing
    assert np.all(obs.omega0 > 0)
