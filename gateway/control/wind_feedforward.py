"""Wind feed-forward: the force of the measured wind, taken off the thrust demand before the hull feels
it drift.

Pure numerics (DESIGN.md rule 2): the relative wind in, a body-frame force out; time only through ``dt``.

The anemometer measures the apparent (relative) wind, speed V and angle β from the bow (NMEA MWV, reference
R), i.e. the vessel's velocity relative to the air in body axes (`observers.hull.apparent_wind_body`)::

    u_rw = V cos β,   v_rw = V sin β

Low-pass, first order with time constant T_w (``wind_filter_s``), per component, exactly discretised for
the step dt (so the same T_w holds at any control rate)::

    x̄ ← x̄ + (1 − e^(−dt/T_w)) (x − x̄),    x = (u_rw, v_rw)

Components, not speed and angle, are filtered: a wind near dead astern has an angle that jumps between
±180°, and the filtered angle of such a wind would swing through the bow. Then the wind force of the
hull's wind areas, the plant's own function (`observers.hull.relative_wind_force`, Fossen (2021) eqs
(10.10)–(10.12)), and the feed-forward with gain k_w ∈ [0, 1] (``wind_feedforward_gain``)::

    τ_wind = − k_w τ̂_w(ū_rw, v̄_rw)

The filter keeps the anemometer's noise (±0.3 m/s, ±2° white, several samples a second) and the mast's
wave-frequency sway out of the thrust demand; T_w of a few seconds still passes the gusts that move a DP
vessel (the NORSOK gust spectrum's energy sits below 0.05 Hz; the position loop's bandwidth is ≈ 0.01 Hz),
which is what the feed-forward is for. Without a measurement (the anemometer stale or invalid) the output is
zero and the filter restarts from zero when the wind returns, so the feed-forward ramps back in over ≈ 3 T_w
instead of stepping the thrusters; the integral term carries the load in between, as without feed-forward.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from observers.hull import WindArea, relative_wind_force

Array = NDArray[np.float64]


class WindFeedForward:
    """τ_wind = −k_w τ̂_w of the low-passed relative wind (module docstring)."""

    def __init__(self, area: WindArea, length_m: float, filter_s: float, gain: float) -> None:
        if not (math.isfinite(filter_s) and filter_s > 0):
            raise ValueError(f"wind feed-forward: filter time constant must be > 0 s, got {filter_s!r}")
        if not (math.isfinite(gain) and 0.0 <= gain <= 1.0):
            raise ValueError(f"wind feed-forward: gain must be in [0, 1], got {gain!r}")
        self.area = area
        self.length_m = float(length_m)
        self.filter_s = float(filter_s)
        self.gain = float(gain)
        self.u = 0.0
        self.v = 0.0
        self.active = False
        """Whether the last `update` had a measurement (the feed-forward is on)."""
        self.tau = np.zeros(3)
        """The last output τ_wind, body frame [X, Y, N]."""

    def reset(self) -> None:
        self.u = self.v = 0.0
        self.active = False
        self.tau = np.zeros(3)

    def update(self, dt: float, relative_wind: tuple[float, float] | None) -> Array:
        """One step of dt seconds with the relative wind (u_rw, v_rw) measured now (body frame, m/s), or
        None: no usable measurement (feed-forward off, filter reset). Returns τ_wind."""
        if relative_wind is None:
            self.reset()
            return self.tau
        u, v = relative_wind
        if not (math.isfinite(u) and math.isfinite(v)):
            self.reset()
            return self.tau
        alpha = 1.0 - math.exp(-dt / self.filter_s) if dt > 0 else 0.0
        self.u += alpha * (u - self.u)
        self.v += alpha * (v - self.v)
        self.active = True
        x, y, n = relative_wind_force(self.area, self.length_m, self.u, self.v)
        k = -self.gain
        self.tau = np.array([k * x, k * y, k * n])
        return self.tau

    @property
    def filtered(self) -> tuple[float, float]:
        """(ū_rw, v̄_rw), m/s."""
        return self.u, self.v
