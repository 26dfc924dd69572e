"""The simulator's plant steps in one compiled call: thrusters, Markov bias and RK4 for n substeps.

The runner advances the low-frequency plant (`simulator.vessel_dynamics.VesselDynamics`) between two events
in substeps of at most 0.05 s; per substep it steps the thrusters (`simulator.thrusters`), takes their
force τ = B(α) u, steps the bias (`simulator.environment.MarkovBias`, eq (7) of Fossen & Strand 1999) and
integrates eq (1), (3) by RK4 with

    τ_body = τ + τ_drift,    b_earth = b + b_constant.

The readable reference is `Simulation._advance_reference` (simulator/runner.py), one Python call per model
per substep; this kernel does the same arithmetic in the same order (the same compiled functions for the
thrusters and RK4, and the bias update b ← e^{-h/T} b + σ√(1 − e^{-2h/T}) ν element by element, as numpy
does it), so both give the same bits (tests/test_simulator.py checks a run of each). The bias' decay and
kick factors and its block of normal draws come from `MarkovBias` (numpy's exp, its own generator): the
kernel only reads them, so the random stream is drawn exactly as before.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from simulator._thruster_kernel import thruster_step, thruster_tau
from simulator.vessel_dynamics import _rk4


@njit(cache=True)
def thrust_and_bias(
    h, thrusters, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate, tx, ty,
    tau_direct, b, decay, kick, normals, k,
):  # fmt: skip
    """One substep's thrusters (their force τ, or ``tau_direct`` without them) and Markov bias, shared by
    both plants' advances: returns τ; updates thrust, angle and b in place and reads normals row ``k``."""
    if thrusters:
        thruster_step(h, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate)
        tau = thruster_tau(thrust, angle, tx, ty)
    else:
        tau = tau_direct
    for j in range(3):
        b[j] = decay[j] * b[j] + kick[j] * normals[k, j]
    return tau


@njit(cache=True)
def advance(
    n, h, m, x, Minv, D,
    thrusters, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate, tx, ty,
    tau_direct, drift, b, b_constant, decay, kick, normals, k,
):  # fmt: skip
    """``n`` substeps of ``h`` s, each integrated as ``m`` RK4 steps of h/m (as `VesselDynamics.step`
    splits it). ``thrusters`` False: τ = ``tau_direct``. Reads the bias normals from row ``k`` on (the
    caller makes sure n rows are left) and returns the next row. Updates x, thrust, angle and b in place."""
    tau_body = np.empty(3)
    b_earth = np.empty(3)
    hm = h / m
    for _ in range(n):
        tau = thrust_and_bias(
            h, thrusters, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate,
            tx, ty, tau_direct, b, decay, kick, normals, k,
        )  # fmt: skip
        k += 1
        for j in range(3):
            tau_body[j] = tau[j] + drift[j]
            b_earth[j] = b[j] + b_constant[j]
        for _i in range(m):
            _rk4(x, hm, tau_body, b_earth, Minv, D)
    return k
