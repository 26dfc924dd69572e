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
which is what the feed-forward is for.

Losing the wind (the anemometer stale or invalid: ``update(dt, None)``) does not drop the term: that would
step the thrust demand by the whole wind load, and the vessel would drift off until the integral term and
the bias estimate b̂ had taken it. The filter holds the last wind and its force is faded out linearly to
zero over T_f (``fade_s``, `[control] wind_loss_fade_s`) by a weight w::

    τ_wind = −k_w w τ̂_w(ū_rw, v̄_rw),   w ← max(0, w − dt/T_f) while lost,  min(1, w + dt/T_f) while measured

The held wind is the air's motion relative to the vessel, in body axes: it stays true of the earth only
while the heading does. A vessel that turns while its anemometer is out (the operator's heading change,
a weathervaning setpoint) would carry a body-frame wind round with it — after a 180° turn pushing with
the wind instead of against it. So while the wind is lost and the heading ψ is given (``update(...,
psi=)``), the held (ū_rw, v̄_rw) is turned by the heading change since the last step, as the relative
wind of a vessel holding station (ν ≈ 0: u_rw = −V_w cos(β_w − ψ), v_rw = −V_w sin(β_w − ψ) for a true
wind V_w going towards β_w) turns::

    ū_rw ← cos Δψ ū_rw + sin Δψ v̄_rw,   v̄_rw ← −sin Δψ ū_rw + cos Δψ v̄_rw

(the vessel's own velocity, part of the measured relative wind, is turned with it: negligible at
station-keeping speeds). Without ψ the wind is held as it was.

The observer is given τ − τ_wind (`gateway.pipeline`), so whatever force is held it treats as known and
b̂ takes the difference to the true load; as w falls, the faded part shows in the observer's velocity
error and moves into b̂ at the pace it is taken off, which the bias feed-forward −Jᵀb̂ and the integrator
answer: the load changes hands instead of dropping. Linear, not exponential: a loop that takes a load
over with time constant T (b̂, the integrator) lags a ramp of duration T_f by ≈ F·T/T_f; an exponential
e^(−t/T_f) starts at the same rate and needs ≈ 3 T_f to be gone, so for the same end the linear fade
leaves a third of the unanswered force, and it ends at a time the operator can be told.

The wind back: the filter continues from the held wind toward the new measurement (T_w), and w climbs
back to 1 at the same pace, from wherever the fade had got to — the force continues from its present,
faded value, never from zero. After a complete fade b̂ holds the whole wind, and the force then comes
back over T_f rather than the filter's ≈ 3 T_w: handed back as fast as b̂ can let it go (measured: the
filter's ramp made the return as large an excursion as the loss, docs/controller.md). The first wind since
the start (or `reset`) has no load to take from b̂ and is fed forward in full through the filter's ramp,
as before. T_f = 0 drops the term at once and restarts the filter from zero on return. Default T_f:
`default_fade_s`, from the times in which the controller's integral term and the observer's bias estimate
take a load over.
"""

from __future__ import annotations

import math

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import NDArray

from observers.hull import WindArea, relative_wind_force
from observers.settling import ENGAGE_TIME_CONSTANTS, UNKNOWN_SETTLE_S

Array = NDArray[np.float64]

FADE_PER_TAKEOVER = 2.0
"""Default fade time T_f as a multiple of the slower takeover time (`default_fade_s`): a ramp over twice the
time constant of the loop that takes the load leaves it at most about half the force unanswered at a time,
a fraction that measured (docs/controller.md, "Losing the wind") well below the drop at once, without
holding an old wind for much longer than the loop needs."""


WEIGHT_DONE = 1e-9
"""A fade whose remaining weight w is this small has ended."""


def default_fade_s(integral_time_s: float, bias_time_s: float | None = None) -> float:
    """T_f = `FADE_PER_TAKEOVER` × max(T_i, T_b): T_i = 1/a, the slowest integral pole of the controller
    (a = ρ ωn, `gateway.control.controller`), T_b the time constant of the observer's slowest error mode,
    its bias mode (`observer_bias_time_s`; None: not known, T_i alone). Infinite or
    non-positive times are left out; with neither known, 0 (the term drops at once)."""
    times = [x for x in (integral_time_s, bias_time_s) if x is not None and math.isfinite(x) and x > 0]
    return FADE_PER_TAKEOVER * max(times) if times else 0.0


def observer_bias_time_s(observer: object) -> float | None:
    """T_b, the time constant of the feeding observer's slowest error mode: the one behind its settle
    time, `Observer.settle_time_s` / `ENGAGE_TIME_CONSTANTS` (each observer's from its own model,
    observers.settling; for fixed passive gains −1/(the slowest error eigenvalue over all headings), the
    bias mode ≈ aρ/(d + a) per DOF, docs/passive-observer.md). None when the observer derives no figure
    (`UNKNOWN_SETTLE_S`, or none at all): the integral time alone then sets the default fade."""
    settle_s = getattr(observer, "settle_time_s", None)
    if not isinstance(settle_s, float) or settle_s == UNKNOWN_SETTLE_S:
        return None
    if not (math.isfinite(settle_s) and settle_s > 0.0):
        return None
    return settle_s / ENGAGE_TIME_CONSTANTS


@mypyc_attr(native_class=False)
class WindFeedForward:
    """τ_wind = −k_w w τ̂_w of the low-passed relative wind; w fades out when the wind is lost and back in
    when it returns (module docstring)."""

    def __init__(
        self, area: WindArea, length_m: float, filter_s: float, gain: float, fade_s: float = 0.0
    ) -> None:
        if not (math.isfinite(filter_s) and filter_s > 0):
            raise ValueError(f"wind feed-forward: filter time constant must be > 0 s, got {filter_s!r}")
        if not (math.isfinite(gain) and 0.0 <= gain <= 1.0):
            raise ValueError(f"wind feed-forward: gain must be in [0, 1], got {gain!r}")
        if not (math.isfinite(fade_s) and fade_s >= 0):
            raise ValueError(f"wind feed-forward: loss fade time must be >= 0 s, got {fade_s!r}")
        self.area = area
        self.length_m = float(length_m)
        self.filter_s = float(filter_s)
        self.gain = float(gain)
        self.fade_s = float(fade_s)
        """T_f: w moves between 0 and 1 over this time after the wind is lost or back (0: at once)."""
        self.u = 0.0
        self.v = 0.0
        self.active = False
        """Whether the last `update` had a measurement."""
        self.weight = 0.0
        """w ∈ [0, 1]: the fraction of the filtered wind's force fed forward."""
        self._seen = False  # a wind measured since the start (or `reset`)
        self._psi: float | None = None  # heading (rad) the filtered wind's body axes are at; None: unknown
        self.tau = np.zeros(3)
        """The last output τ_wind, body frame [X, Y, N] (nonzero also while a lost wind fades)."""

    @property
    def fading(self) -> bool:
        """The wind is lost and its held force is not yet faded out."""
        return not self.active and self.weight > 0.0

    @property
    def fading_in(self) -> bool:
        """The wind is back after a loss and its force is not yet fed forward in full."""
        return self.active and self.weight < 1.0

    def reset(self) -> None:
        """As at the start: no wind, filter at zero; the next wind comes in through the filter alone."""
        self.u = self.v = 0.0
        self.active = False
        self.weight = 0.0
        self._seen = False
        self._psi = None
        self.tau = np.zeros(3)

    def update(self, dt: float, relative_wind: tuple[float, float] | None, psi: float | None = None) -> Array:
        """One step of dt seconds with the relative wind (u_rw, v_rw) measured now (body frame, m/s), or
        None (or non-finite): no usable measurement, the held force fades (module docstring). ``psi``: the
        heading now (rad; None or non-finite: not known), by which a held wind is turned with the vessel.
        Returns τ_wind."""
        dt = dt if math.isfinite(dt) and dt > 0 else 0.0
        psi = psi if psi is not None and math.isfinite(psi) else None
        u = v = math.nan
        if relative_wind is not None:
            u, v = relative_wind
        if not (math.isfinite(u) and math.isfinite(v)):
            self._turn_held(psi)
            return self._lost(dt)
        self._psi = psi
        if not self._seen or self.fade_s <= 0.0:
            self.weight = 1.0  # the first wind since the start: in through the filter's ramp alone
        else:
            self.weight += dt / self.fade_s
            if self.weight >= 1.0 - WEIGHT_DONE:  # (dt/T_f summed in floating point: done at T_f)
                self.weight = 1.0
        alpha = 1.0 - math.exp(-dt / self.filter_s) if dt > 0 else 0.0
        self.u += alpha * (u - self.u)
        self.v += alpha * (v - self.v)
        self.active = True
        self._seen = True
        return self._force()

    def _turn_held(self, psi: float | None) -> None:
        """The held wind into the body axes of heading ``psi`` (module docstring); kept as it is when either
        heading is not known."""
        if psi is not None and self._psi is not None and psi != self._psi:
            d = psi - self._psi
            c, s = math.cos(d), math.sin(d)
            self.u, self.v = c * self.u + s * self.v, -s * self.u + c * self.v
        if psi is not None:
            self._psi = psi

    def _lost(self, dt: float) -> Array:
        self.active = False
        if self.fade_s <= 0.0:
            self.reset()
            return self.tau
        self.weight -= dt / self.fade_s
        if self.weight <= WEIGHT_DONE:
            self.weight = 0.0
        return self._force()

    def _force(self) -> Array:
        if self.weight == 0.0:
            self.tau = np.zeros(3)
            return self.tau
        x, y, n = relative_wind_force(self.area, self.length_m, self.u, self.v)
        k = -self.gain * self.weight
        self.tau = np.array([k * x, k * y, k * n])
        return self.tau

    @property
    def filtered(self) -> tuple[float, float]:
        """(ū_rw, v̄_rw), m/s: the filter's state (held while the wind is lost)."""
        return self.u, self.v
