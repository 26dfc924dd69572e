"""The thruster model's per-substep arithmetic, compiled by numba: the first-order thrust lag and azimuth
slew (`thruster_step`) and the generalised force τ = B(α) u (`thruster_tau`). `ThrusterBank` calls them,
and so do the plant kernels (`simulator._advance_kernel`, `simulator._full_advance_kernel`) from compiled
code. A module of their own: `simulator.thrusters` is compiled by mypyc (setup.py), and numba compiles
Python bytecode, which a mypyc-compiled module no longer has.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from observers.kinematics import ssa_jit


@njit(cache=True)
def thruster_step(h, thrust, angle, thrust_sp, angle_sp, failed, is_azimuth, time_constant, rate):
    """First-order thrust lag towards the setpoint (zero when failed); azimuth slew at most rate·h."""
    for i in range(thrust.shape[0]):
        target = 0.0 if failed[i] else thrust_sp[i]
        thrust[i] = target + (thrust[i] - target) * math.exp(-h / time_constant[i])
        if is_azimuth[i] and not failed[i]:
            err = ssa_jit(angle_sp[i] - angle[i])
            lim = rate[i] * h
            move = min(max(err, -lim), lim)
            angle[i] = ssa_jit(angle[i] + move)


@njit(cache=True)
def thruster_tau(thrust, angle, x, y):
    out = np.zeros(3)
    for i in range(thrust.shape[0]):
        fx = thrust[i] * math.cos(angle[i])
        fy = thrust[i] * math.sin(angle[i])
        out[0] += fx
        out[1] += fy
        out[2] += x[i] * fy - y[i] * fx
    return out
