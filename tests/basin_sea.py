"""Measured position and heading of CyberShip II (the 1:70 model of a supply vessel) in a basin sea, for
the tests of the model-scale defaults (tests/test_gain_scheduled_model_scale.py,
tests/test_passive_model_scale.py).

The model at (0, 0), heading 0: its WF motion from a JONSWAP sea through its RAOs
(`simulator.waves.WaveField`), a slow LF motion from its LF dynamics under a weak station-keeping law
(the full-scale tests' 120 s loop and 100-600 s forcing, Froude-scaled by √70), and the `hassani`
scenario's sensor noise (1 cm RTK position, 0.1° gyro), sampled at `RATE`.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from observers.froude import froude_scale
from observers.kinematics import rotation, ssa
from observers.vessel import builtin_vessels, load_vessel
from simulator.spectra import SeaState
from simulator.vessel_dynamics import VesselDynamics
from simulator.waves import WaveField, WaveResponse

MODEL = load_vessel("cybership2")
RATE = 10.0
"""Hz: the `hassani` scenario's RTK and gyro rate."""
SCALE = math.sqrt(70.0)
"""Froude: the model's times are the ship's ÷ √70, its frequencies × √70."""
SHIPS = [name for name in builtin_vessels() if froude_scale(load_vessel(name)) == 1.0]
"""The built-in full-scale vessels: their defaults must stay exactly the unscaled ones."""
DEFAULT_SEA = SeaState(hs_m=0.05, tp_s=7.0 / SCALE, gamma=3.3, direction_rad=math.radians(150.0))
"""The ships' default 7 s sea, Froude-scaled to the model (0.84 s)."""


@lru_cache(maxsize=8)
def basin(sea: SeaState, duration_s: float, seed: int) -> tuple[np.ndarray, ...]:
    """(t, y, lf, wf): the measured position/heading y = lf + wf + noise at `RATE`, and its true LF and WF
    parts (the module docstring)."""
    rng = np.random.default_rng(seed)
    field = WaveField(schedule=[(0.0, sea)], response=WaveResponse.for_vessel(MODEL), seed=seed)
    n = int(duration_s * RATE)
    t = np.arange(n) / RATE
    dyn = VesselDynamics(MODEL)
    m = np.diag(MODEL.M)
    wn = 2 * math.pi / 120.0 * SCALE
    kp, kd = m * wn**2, m * 2 * 0.7 * wn
    periods = rng.uniform(100.0, 600.0, (3, 4)) / SCALE
    phases = rng.uniform(0, 2 * math.pi, (3, 4))
    amps = (m * np.array([0.02, 0.02, 0.02]))[:, None] * rng.uniform(0.5, 1.0, (3, 4))
    lf = np.empty((n, 3))
    for k in range(n):
        eta, nu = dyn.eta, dyn.nu
        lf[k] = eta
        err = eta.copy()
        err[2] = ssa(err[2])
        force = np.sum(amps * np.sin(2 * math.pi * t[k] / periods + phases), axis=1)
        dyn.step(1.0 / RATE, force - kp * (rotation(eta[2]).T @ err) - kd * nu)
    wf = field.motion(t, lf[:, 2], lf[:, 0], lf[:, 1])
    y = lf + wf + rng.standard_normal((n, 3)) * np.array([0.01, 0.01, math.radians(0.1)])
    y[:, 2] = ssa(y[:, 2])
    return t, y, lf, wf
