"""The full plant's steps in one compiled call: thrusters, Markov bias, wind force and RK4 for n substeps.

The runner advances the full plant (`simulator.plant.FullPlant`) between two events in substeps of at
most 0.05 s; per substep the readable reference (`Simulation._advance_reference` → `_full_step`, in
simulator/runner.py) steps the thrusters (`simulator.thrusters`), takes their force τ = B(α) u, steps the
bias (`simulator.environment.MarkovBias`, Fossen & Strand 1999 eq (7)), lets the environment
(`simulator.plant_env.PlantEnvironment`) move the current once a second and recompute the wind force every
0.25 s, and integrates the plant by RK4 (`simulator._plant_kernel.rk4_steps`) with

    τ_body = (τ + τ_drift) + τ_wind,    b_earth = b + b_constant,    ν_c the current's NED velocity.

This kernel does the same arithmetic in the same order, so both give the same bits (tests/test_simulator.py
runs both full-plant scenarios each way and compares state and bytes):

- thrusters and RK4: the same compiled functions (`simulator._thruster_kernel` through
  `_advance_kernel.thrust_and_bias`, which the model plant's advance uses too, and `rk4_steps`);
- bias: b ← e^{-h/T} b + σ√(1 − e^{-2h/T}) ν element by element with `MarkovBias`' own factors and its
  block of normal draws (read, never drawn here: the random stream is the same);
- wind: Fossen (2021) eqs (10.10)–(10.12) on the relative wind, `simulator.wind.wind_force` written out
  with the same operations in the same order. The wind's speed and its NED velocity (wn, we) are computed
  by the caller: the reference asks the gust series at the event's start time for every substep of it, so
  they are constant over one call. numba's cos, sin and atan2 are the C library's, as CPython's math
  module's are (tests/test_simulator.py checks the force against `wind_force` bit for bit);
- current: not stepped here. Its Gauss–Markov step draws from its own generator once a second, so the
  kernel stops *before* the substep at which it falls due (returning how many substeps it did), the
  caller steps `Current` in Python with the accumulated time, and calls again with ``current_stepped``
  True for that substep (its time is already counted).

``due`` = [time since the current moved, time since the wind force was computed], carried between calls.
``wind_p`` = [½ρ_a, c_x, c_y, c_n, A_F, A_L, L, wn, we]; ``steps`` = [current step − 1e-9, wind step −
1e-9] (the thresholds `PlantEnvironment.step` compares with). The arguments from ``x`` to ``steps`` are
the same objects for a whole run (arrays updated in place, or constants): the runner gathers them once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from simulator._advance_kernel import thrust_and_bias
from simulator._plant_kernel import rk4_steps


@njit(cache=True)
def _wind_force(x, p, out):
    """`simulator.wind.wind_force` on the state x = [N, E, ψ, u, v, r, …]: the same operations, in order."""
    u = x[3]
    v = x[4]
    wn = p[7]
    we = p[8]
    c = math.cos(x[2])
    s = math.sin(x[2])
    urw = u - (c * wn + s * we)
    vrw = v - (-s * wn + c * we)
    q = p[0] * (urw * urw + vrw * vrw)
    gamma = -math.atan2(vrw, urw)
    out[0] = -q * p[1] * math.cos(gamma) * p[4]
    out[1] = q * p[2] * math.sin(gamma) * p[5]
    out[2] = q * p[3] * math.sin(2.0 * gamma) * p[5] * p[6]


wind_force_into = _wind_force
"""The wind force alone: the feed-forward's mean wind (`PlantEnvironment.mean_wind_body`)."""


@njit(cache=True)
def advance_full(
    n, h, m,
    x, s, Minv, D, MA, rA, rB, rC, rD,
    thrusters, thrust, angle, failed, is_azimuth, time_constant, rate, tx, ty,
    b_constant, has_current, has_wind, wind_p, wind_body, due, steps,
    thrust_sp, angle_sp, tau_direct, drift, b, decay, kick, normals, k, current_stepped, vc,
):  # fmt: skip
    """Up to ``n`` substeps of ``h`` s, each integrated as ``m`` RK4 steps of h/m (as `FullPlant.step`
    splits it). Reads the bias normals from row ``k`` on (the caller makes sure n rows are left). Updates
    x, thrust, angle, b, wind_body and due in place. Returns (the next normals row, the substeps done):
    fewer than n when the current fell due before the next one (its accumulated time is in due[0])."""
    tau_body = np.empty(3)
    b_earth = np.empty(3)
    hm = h / m
    for i in range(n):
        if has_current:
            if current_stepped and i == 0:
                pass  # the caller has just stepped the current for this substep
            else:
                cd = due[0] + h
                due[0] = cd
                if cd >= steps[0]:
                    return k, i
        tau = thrust_and_bias(
            h, thrusters, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate,
            tx, ty, tau_direct, b, decay, kick, normals, k,
        )  # fmt: skip
        k += 1
        if has_wind:
            wd = due[1] + h
            if wd >= steps[1]:
                _wind_force(x, wind_p, wind_body)
                due[1] = 0.0
            else:
                due[1] = wd
        for j in range(3):
            tau_body[j] = tau[j] + drift[j] + wind_body[j]
            b_earth[j] = b[j] + b_constant[j]
        rk4_steps(x, hm, m, tau_body, b_earth, vc, s, Minv, D, MA, rA, rB, rC, rD)
    return k, n
