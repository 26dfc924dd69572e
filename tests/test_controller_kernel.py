"""The compiled DP control step (gateway/control/_controller_kernel.py) against the numpy reference.

`DPController(compiled=True)` (the default) runs the steps of dp mode after the first in one compiled
call; `compiled=False` runs the numpy code of `gateway.control.controller` and `gateway.control.reference`
throughout. Fed the same sequences — estimates near and far from the setpoint, setpoint moves that
saturate the reference model's speed and acceleration, headings across ±180°, saturated and unsaturated
allocation (back-calculation and frozen integrator), bias on and off, uneven and zero time steps, leaving
and re-entering dp — every field of every output agrees to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.control.controller import ControllerOutput, ControllerTuning, DPController
from observers.vessel import load_vessel

FIELDS = ("tau", "eta_error", "nu_error", "integral", "tau_p", "tau_i", "tau_d", "tau_ff")
REF_FIELDS = ("eta_d", "eta_dot_d", "eta_ddot_d", "nu_d", "nu_dot_d", "target")


def _close(a: ControllerOutput, b: ControllerOutput, scale: np.ndarray) -> None:
    assert a.mode == b.mode and a.valid == b.valid and a.t == b.t
    for f in FIELDS:
        x, y = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
        s = scale if f.startswith("tau") else 1.0
        np.testing.assert_allclose(x / s, y / s, rtol=1e-9, atol=1e-9, err_msg=f)
    for f in REF_FIELDS:
        np.testing.assert_allclose(getattr(a.reference, f), getattr(b.reference, f), rtol=1e-9, atol=1e-12)


def _run(vessel_name: str, seed: int, steps: int, tuning: ControllerTuning | None = None) -> int:
    vessel = load_vessel(vessel_name)
    fast, ref = DPController(vessel, tuning), DPController(vessel, tuning, compiled=False)
    scale = np.maximum(np.abs(np.diag(vessel.M)), 1.0)  # force scale per DOF, for the tolerances
    rng = np.random.default_rng(seed)
    t = 0.0
    eta = np.array([0.0, 0.0, math.pi - 0.05])
    nu = np.zeros(3)
    compiled_steps = 0
    for c in (fast, ref):
        c.set_mode("dp")
    for k in range(steps):
        t += float(rng.choice([0.1, 0.1, 0.1, 0.05, 0.5, 0.0, 3.0]))
        if k % 97 == 10:  # a setpoint move: tens of metres and through ±180°
            target = [rng.uniform(-40, 40), rng.uniform(-40, 40), rng.uniform(-math.pi, math.pi)]
            for c in (fast, ref):
                c.set_setpoint(target)
        if k % 331 == 200:  # leave and re-enter dp (bumpless entry runs in numpy on both)
            for c in (fast, ref):
                c.set_mode("standby")
        if k % 331 == 205:
            for c in (fast, ref):
                c.set_mode("dp")
        eta = eta + rng.normal(0.0, [0.3, 0.3, 0.02])
        eta[2] = (eta[2] + math.pi) % (2 * math.pi) - math.pi
        nu = 0.9 * nu + rng.normal(0.0, [0.05, 0.05, 0.002])
        bias = None if k % 7 == 3 else rng.normal(0.0, 1e4, 3)
        saturated = bool(rng.random() < 0.3)
        tau_alloc = None if k % 5 == 1 else rng.normal(0.0, 1e5, 3)
        kw = {"saturated": saturated, "tau_allocated": tau_alloc}
        a = fast.update(t, eta, nu, bias, **kw)
        b = ref.update(t, eta, nu, bias, **kw)
        _close(a, b, scale)
        compiled_steps += fast.mode == "dp"
    return compiled_steps


@pytest.mark.parametrize("name", ["mss_supply", "cybership2"])
def test_compiled_step_matches_numpy_along_a_sequence(name: str) -> None:
    assert _run(name, 1, 1500) > 1000


@settings(max_examples=25, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.booleans(),
    st.booleans(),
    st.sampled_from([None, 20.0, (5.0, 50.0, 500.0)]),  # tracking time: default, one, per DOF
)
def test_compiled_step_matches_numpy_for_any_tuning_switches(
    seed: int, feedforward: bool, bias_ff: bool, tracking: float | tuple[float, ...] | None
) -> None:
    tuning = ControllerTuning(feedforward=feedforward, bias_feedforward=bias_ff, tracking_time_s=tracking)
    _run("mss_supply", seed, 300, tuning)


def test_no_integral_action_keeps_z_zero_in_both() -> None:
    tuning = ControllerTuning(integral_ratio=(0.1, 0.0, 0.1))
    _run("mss_supply", 3, 400, tuning)
    c = DPController(load_vessel("mss_supply"), tuning)
    c.set_mode("dp")
    for k in range(50):
        c.update(
            0.1 * k, np.array([1.0, 2.0, 0.1]), np.zeros(3), None, saturated=True, tau_allocated=np.ones(3)
        )
    assert c.integral[1] == 0.0 and c.integral[0] != 0.0
