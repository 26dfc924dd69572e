"""Compiled wave-frequency synthesis on an evenly spaced time grid: the fast twin of
`simulator.waves.WaveField.motion_with_attitude` for the simulator's blocks.

The first-order wave motion of one sea state is the real part of a sum over its K regular components,

    x_d(t_s) = w_s · Re Σ_k e^{iθ_k(t_s)} T_kd(β),    θ_k(t) = ω_k t − k_k (N cos χ + E sin χ) + ε_k,

with T(β) the components' amplitude-weighted RAO table interpolated linearly at the wave's direction
relative to the heading (`WaveField._at_beta`). Over one of the simulator's 2 s blocks the heading and the
position are held (the runner evaluates a block at its start), so β and the position term are constant,
and on the grid t_s = t₀ + s·Δt the carriers follow the recurrence

    e^{iθ_k(t_{s+1})} = e^{iθ_k(t_s)} · e^{iω_k Δt}:

one complex multiplication per component and sample instead of a cosine and a sine, and the table
interpolated in β once per block instead of once per sample. The carriers start exact at every block (a
cosine and a sine each at t₀), so the recurrence's round-off (an ulp or so a step) never accumulates past
one block. ``tests/test_waves.py`` checks this against the readable numpy path.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def synthesize(omega, phase, wavenumber, along, t0, dt, tab_re, tab_im, j, f, weights, out):
    """out[s, d] += weights[s] · Re Σ_k e^{iθ_k(t₀ + s·dt)} T_kd for s = 0 … n−1.

    omega, phase, wavenumber: (K,); along: the position along the waves' direction (m);
    tab_re, tab_im: (K, B+1, D), the table on the closed β grid; T = (1 − f) tab[:, j] + f tab[:, j+1];
    weights: (n,); out: (n, D).
    """
    n, n_d = out.shape
    n_k = omega.shape[0]
    z_re = np.empty(n_k)
    z_im = np.empty(n_k)
    r_re = np.empty(n_k)
    r_im = np.empty(n_k)
    t_re = np.empty((n_k, n_d))
    t_im = np.empty((n_k, n_d))
    g = 1.0 - f
    for k in range(n_k):
        theta = omega[k] * t0 + phase[k] - wavenumber[k] * along
        z_re[k], z_im[k] = math.cos(theta), math.sin(theta)
        r_re[k], r_im[k] = math.cos(omega[k] * dt), math.sin(omega[k] * dt)
        for d in range(n_d):
            t_re[k, d] = g * tab_re[k, j, d] + f * tab_re[k, j + 1, d]
            t_im[k, d] = g * tab_im[k, j, d] + f * tab_im[k, j + 1, d]
    acc = np.empty(n_d)
    for s in range(n):
        for d in range(n_d):
            acc[d] = 0.0
        for k in range(n_k):
            zr, zi = z_re[k], z_im[k]
            for d in range(n_d):
                acc[d] += zr * t_re[k, d] - zi * t_im[k, d]
            z_re[k] = zr * r_re[k] - zi * r_im[k]
            z_im[k] = zr * r_im[k] + zi * r_re[k]
        w = weights[s]
        for d in range(n_d):
            out[s, d] += w * acc[d]
