"""On-line estimate of the dominating wave frequency ω0 from position and heading measurements.

Torsetnes, Jouffroy & Fossen (2004), Sec. III-B and assumptions A5, A6, A8: the wave peak frequencies
ω0ᵢ (surge, sway, yaw) are present in the measured position and heading (A8: the measured motion is the
sum of the LF and WF motion), so they "can be estimated on-line from position and heading measurements
using spectral analysis"; ω̄0 is updated every T (A5: "every T minutes"), within
0 < ω̄0,min ≤ ω̄0 ≤ ω̄0,max < ∞ (A6). The paper names no method; dpgw's choices, in order:

1. **Sliding window.** Samples (t, y) are kept for the last ``window_s`` seconds (300 s: 26 periods of an
   11.5 s sea, and one sea state is stationary for much longer). NaN marks a missing DOF.
2. **Welch segments.** The window is covered by segments of ``segment_s`` (120 s) at 50 % overlap, laid
   on the resampling grid from the first sample (segment k starts k·⌊n_seg/2⌋ grid points after it). The
   periodogram of a segment is computed once, when its last sample is in, and kept while the segment
   lies inside the window: an update only does the segments completed since the last one (one, with the
   defaults), and the window's spectrum is the mean of its segments' — Welch's estimate over the window.
   Before the first segment is complete, the data so far form one shorter segment if they span at least
   ``min_span_s`` (default two periods of ω_min, 42 s, at most ``segment_s``), so the first update comes
   after one period T.
3. **Uniform grid, dropouts.** A segment's samples are put on a uniform grid at ``resample_hz`` (default:
   Nyquist at 3·ω_max, 1.53 Hz for ω_max = 1.6 rad/s): each grid cell with samples gives the mean of its
   samples at their mean time (a box anti-alias filter: faster sampling averages white noise down
   instead of folding it into the band), and these points, with the nearest samples outside the segment,
   are interpolated linearly at the cell centres (slower sampling, short dropouts). So irregular sampling
   costs nothing. A DOF whose samples leave a gap longer than ``max_gap_s`` in a segment is left out of
   that segment (it keeps the segments that are clean: its clean stretches, cut into segments). The
   heading is unwrapped first (a heading crossing ±180° would otherwise be a 2π step).
4. **LF motion removed.** The LF motion of a DP vessel is large (metres) and slow (periods of minutes):
   each segment loses its least-squares quadratic before it is windowed, which takes the bulk of it; the
   periodogram is then weighted by the power gain of a zero-phase (filtfilt) 4th-order Butterworth
   high-pass, (r⁸/(1 + r⁸))², r = ω/ω_hp, corner ω_hp = ``highpass_cutoff_ratio``·ω_min (0.15 rad/s by
   default; −0.03 dB at ω_min). Applied after the window rather than before it, the high-pass cannot
   remove window leakage, but after the quadratic there is little left to leak: Hann sidelobes put what
   remains ≥ 50 dB below it five bins away, and the band starts six bins up.
5. **Periodogram.** Hann window, FFT of the next power of two (the same bins for every DOF, segment and
   update), one-sided PSD per rad/s.
6. **Combining DOFs** (``per_dof=False``, the default, as Torsetnes' case study uses one ω0 for surge,
   sway and yaw). Power in m² and rad² cannot be added, so each DOF's spectrum is normalised to unit
   power in the wave band [ω_min, ω_max] and weighted by its wave-band signal-to-noise ratio
   snr/(1 + snr), snr = (band power − noise power in the band)/noise power in the band, the noise level
   being the median PSD above 1.5·ω_max (white measurement noise is flat there; waves are not). So a DOF
   counts by how clearly it sees the waves, whatever its unit. A DOF with snr < ``min_snr`` is left out.
   With ``per_dof=True`` each DOF gets its own peak; a DOF that cannot (too little data, no peak above
   noise) takes the combined estimate.
7. **Peak.** The spectrum of the wave model (18) (Fossen & Strand's (10)) fitted to the bins around the
   maximum in [ω_min, ω_max] (`_peak`: a linear least-squares fit, whose peak ω0 is the estimate; a
   parabola through the log PSD at the maximum bin and its neighbours is the fallback). A maximum on the
   band edge is not a peak: the update is skipped.
8. **Smoothing.** The estimate is the median of the last ``median_of`` (3) peaks: one odd window (a
   cross-fade between two seas, a burst of noise) does not move ω0, a real change does at the second
   update that sees it.

**Above the DP loop's band** (``loop_bandwidth``). The paper's A8 takes the measured motion to be LF plus
WF motion and the LF motion to lie below the waves (the high-pass of step 4 removes it below 0.5·ω_min).
Under DP the LF motion is the closed loop's: it has power up to the loop's natural frequency ωn (the
controller's bandwidth), and falls steeply above it (the disturbance's spectrum times the loop's second-
order roll-off). On a ship ωn is far below ω_min (0.07-0.1 rad/s against 0.3) and nothing changes. Where
the loop is fast against the sea the two overlap: the `hassani` case runs a full-scale 6.8 s sea
(0.93 rad/s) on the 1:70 CyberShip II, whose Froude-scaled loop has ωn = 0.55 / 0.55 / 0.78 rad/s. There
the closed-loop motion at ω_min = 0.3 rad/s is as strong as the wave peak in north and east and 20 dB
above it in heading (which has the strongest wave-band snr, so full weight), the combined spectrum's
maximum sits on ω_min, and the estimator either skipped every update (ω0 stayed at its start) or took a
bump of the loop's motion just above ω_min for a peak (0.32-0.40 rad/s, the gain-scheduled observer's
notch then on the loop's motion: 2.2-3.1° heading error against 0.7° for the fixed observer). So where the
DP loop is known the peak is searched above ωn only: each DOF's bins below max(ω_min, ωn) are left out of
its band power, its snr and the peak (one band for all DOFs with a shared ω0: the highest loop's ωn, as
the DOFs are added; ``per_dof=True``: each its own). The wave filter could not separate waves from the
loop's motion inside the loop's band anyway: there the vessel is meant to follow what it measures. The
paper is silent on this (its case study's PID has ωn = 0.8 rad/s beside a 0.546 rad/s sea, which this
rule would not find: a DP loop is normally set below the wave band, and dpgw's is, at full scale).

**Skipped updates** (`WaveFrequencyEstimator.last_skip` says why): too little clean data (no clean
segment and less than ``min_span_s`` so far); no DOF's wave band rises ``min_snr`` above the noise (calm
sea, or dead sensors); the maximum lies on an edge of [ω_min, ω_max]. The estimate in use is then kept.

**Cost.** `add` appends arrays (amortised O(1) per sample, vectorised in batch use); an update is O(T)
for its new segments plus O(window/segment) to average them, numpy/scipy only, whatever the sample rate.

**Model ships.** Froude scaling to a 1:λ model (λ = L_ship/L_model) changes frequencies by √λ and times
by 1/√λ: ``WaveFrequencyConfig().for_model(λ)`` (e.g. CyberShip II, 1:70: ω in [2.5, 13.4] rad/s,
window 36 s, update every 7.2 s; ``scaled(L_model/L_ship)`` is the same with the length ratio). The
observers' default is the vessel's own (`for_vessel`, with the scale of `observers.froude`): a ship keeps
the settings above exactly, a model gets them Froude-scaled.
`estimator_config` reads a config's keys on top: set neither ``omega_min`` nor ``omega_max`` and the
whole default follows the vessel; set either and the range is yours — the other bound is the vessel's,
the time settings (window, update period, segment …) stay the full-scale ones, valid for any range above
0.3 rad/s (a model's shorter ones could not resolve a full-scale sea).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.froude import froude_scale, froude_scaled
from observers.kinematics import ssa
from observers.vessel import VesselModel

Array = NDArray[np.float64]

_NOISE_BAND = (1.5, 0.9)  # noise level: median PSD from 1.5·ω_max to 0.9·ω_Nyquist
_FFT_OVERSAMPLE = 1  # FFT length: the next power of two ≥ the segment length
_FIT_LEVEL = 0.1  # the peak fit uses the bins around the maximum above 10 % of it
TROUGH_RISE = 2.0
"""`wave_band_power`: the spectrum must rise this much above the trough after the LF tail for a sea."""


@dataclass(frozen=True)
class WaveFrequencyConfig:
    """Settings of `WaveFrequencyEstimator` (see the module docstring for what each step does).

    window_s:              sliding window (s).
    update_period_s:       T of assumption A5: a new estimate every T seconds (s).
    omega_min, omega_max:  bounds of assumption A6 (rad/s); the peak is searched in between.
    per_dof:               one ω0 per DOF instead of one shared by surge, sway and yaw.
    highpass_cutoff_ratio: corner of the high-pass that removes the LF motion, as a fraction of ω_min.
    segment_s:             Welch segment length (s); segments overlap by half.
    resample_hz:           uniform grid rate (Hz); None: Nyquist at 3·ω_max.
    max_gap_s:             gaps up to this are interpolated; a longer gap drops the DOF from the segment (s).
    min_span_s:            least data for the first, short segment (s); None: two periods of ω_min (at
                           most segment_s).
    min_snr:               wave-band power above noise, relative to the noise power in the band.
    median_of:             the estimate is the median of the last ``median_of`` spectral peaks (1: none).
    loop_bandwidth:        natural frequency ωn (rad/s, one or per DOF) of the DP loop that moves the
                           vessel, where known (`GainScheduledObserver` passes its tuning's, which a gateway
                           config sets from ``[control]``); the peak is searched above it (module docstring,
                           "Above the DP loop's band"). None: no loop known, the whole [ω_min, ω_max].
    """

    window_s: float = 300.0
    # A5's example is T = 15 min. dpgw updates every minute: the first estimate then replaces a badly tuned
    # start within a minute or two instead of a quarter of an hour. Frequent updates cost no jumps: the
    # estimate is the median of the last peaks (`median_of`), the gain-scheduled observer ramps towards it
    # within its contraction budget (`observers.gain_scheduled_analysis`), and the adaptive SDRE keeps its
    # state across a new ω0.
    update_period_s: float = 60.0
    omega_min: float = 0.3
    omega_max: float = 1.6
    per_dof: bool = False
    highpass_cutoff_ratio: float = 0.5
    segment_s: float = 120.0
    resample_hz: float | None = None
    max_gap_s: float = 2.0
    min_span_s: float | None = None
    min_snr: float = 3.0
    median_of: int = 3
    loop_bandwidth: Any = None

    def __post_init__(self) -> None:
        positive = {
            "window_s": self.window_s,
            "update_period_s": self.update_period_s,
            "omega_min": self.omega_min,
            "omega_max": self.omega_max,
            "highpass_cutoff_ratio": self.highpass_cutoff_ratio,
            "segment_s": self.segment_s,
            "max_gap_s": self.max_gap_s,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"WaveFrequencyConfig.{name} must be a positive number, got {value!r}")
        if not self.omega_max > self.omega_min:
            raise ValueError(
                f"WaveFrequencyConfig: omega_max = {self.omega_max} must exceed omega_min = {self.omega_min}"
            )
        if not self.highpass_cutoff_ratio < 1.0:
            raise ValueError("WaveFrequencyConfig.highpass_cutoff_ratio must be < 1 (corner below ω_min)")
        if self.resample_hz is not None and not (
            math.isfinite(self.resample_hz) and self.resample_hz * math.pi > _NOISE_BAND[0] * self.omega_max
        ):
            raise ValueError(
                f"WaveFrequencyConfig.resample_hz = {self.resample_hz!r}: its Nyquist frequency must lie "
                f"above {_NOISE_BAND[0]}·omega_max (the noise reference band)"
            )
        if self.min_span_s is not None and not (math.isfinite(self.min_span_s) and self.min_span_s > 0):
            raise ValueError(f"WaveFrequencyConfig.min_span_s must be positive, got {self.min_span_s!r}")
        if int(self.median_of) != self.median_of or self.median_of < 1:
            raise ValueError(f"WaveFrequencyConfig.median_of must be an integer ≥ 1, got {self.median_of!r}")
        if not (math.isfinite(self.min_snr) and self.min_snr >= 0):
            raise ValueError(f"WaveFrequencyConfig.min_snr must be ≥ 0, got {self.min_snr!r}")
        if self.loop_bandwidth is not None:
            wn = np.asarray(self.loop_bandwidth, dtype=float)
            if wn.ndim > 1 or wn.size not in (1, 3) or not bool(np.all(np.isfinite(wn) & (wn > 0))):
                raise ValueError(
                    "WaveFrequencyConfig.loop_bandwidth must be a positive number or three (per DOF), got "
                    f"{self.loop_bandwidth!r}"
                )
            # kept as a tuple of three floats: the config stays hashable and comparable
            three = np.broadcast_to(wn, (3,))
            object.__setattr__(self, "loop_bandwidth", (float(three[0]), float(three[1]), float(three[2])))
            if not max(self.search_floor) < self.omega_max:
                raise ValueError(
                    f"WaveFrequencyConfig: the DP loop's bandwidth {list(self.loop_bandwidth)} rad/s reaches "
                    f"omega_max = {self.omega_max}: no wave band is left above the loop to search"
                )
        if not self.min_span_effective_s <= self.segment_s <= self.window_s:
            raise ValueError(
                "WaveFrequencyConfig: need min_span_s ≤ segment_s ≤ window_s, got "
                f"{self.min_span_effective_s:.4g}, {self.segment_s:.4g}, {self.window_s:.4g} s"
            )

    @property
    def resample_hz_effective(self) -> float:
        return self.resample_hz if self.resample_hz is not None else 3.0 * self.omega_max / math.pi

    @property
    def search_floor(self) -> tuple[float, float, float]:
        """Lowest frequency searched per DOF (rad/s): ω_min, raised to the DP loop's natural frequency where
        that lies above it (module docstring, "Above the DP loop's band"). With one ω0 for all DOFs
        (``per_dof=False``) one band for all: the highest loop's."""
        if self.loop_bandwidth is None:
            return (self.omega_min, self.omega_min, self.omega_min)
        wn = np.asarray(self.loop_bandwidth)  # (three floats: `__post_init__`)
        floor = np.maximum(self.omega_min, wn if self.per_dof else np.full(3, wn.max()))
        return (float(floor[0]), float(floor[1]), float(floor[2]))

    @property
    def min_span_effective_s(self) -> float:
        if self.min_span_s is not None:
            return self.min_span_s
        return min(2.0 * (2.0 * math.pi / self.omega_min), self.segment_s)

    def for_model(self, scale: float) -> WaveFrequencyConfig:
        """These settings as a 1:``scale`` model sees them (λ = L_full/L_model, `observers.froude`):
        frequencies × √λ, times ÷ √λ (`observers.froude.froude_scaled`); λ = 1 returns them exactly."""
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"Froude scale must be a positive number, got {scale!r}")

        def w(value: float) -> float:
            return froude_scaled(value, scale, "frequency")

        def t(value: float) -> float:
            return froude_scaled(value, scale, "time")

        return replace(
            self,
            window_s=t(self.window_s),
            update_period_s=t(self.update_period_s),
            omega_min=w(self.omega_min),
            omega_max=w(self.omega_max),
            segment_s=t(self.segment_s),
            resample_hz=None if self.resample_hz is None else w(self.resample_hz),
            max_gap_s=t(self.max_gap_s),
            min_span_s=None if self.min_span_s is None else t(self.min_span_s),
            loop_bandwidth=None
            if self.loop_bandwidth is None
            else tuple(w(float(v)) for v in self.loop_bandwidth),
        )

    def scaled(self, length_ratio: float) -> WaveFrequencyConfig:
        """Froude-scaled copy for a vessel ``length_ratio`` times as long: ω × 1/√ratio, times × √ratio
        (`for_model` with λ = 1/``length_ratio``)."""
        if not (math.isfinite(length_ratio) and length_ratio > 0):
            raise ValueError(f"length ratio must be a positive number, got {length_ratio!r}")
        return self.for_model(1.0 / length_ratio)

    def held_by(self, loop_bandwidth: Any) -> WaveFrequencyConfig:
        """This config searching above the DP loop's band ``loop_bandwidth`` (a tuning's: None, unknown)
        where it has no band of its own ("Above the DP loop's band"): how an observer that schedules ω0
        takes the loop its estimate feeds."""
        if self.loop_bandwidth is not None or loop_bandwidth is None:
            return self
        return replace(self, loop_bandwidth=loop_bandwidth)

    @classmethod
    def for_vessel(cls, vessel: VesselModel) -> WaveFrequencyConfig:
        """The default settings Froude-scaled to ``vessel`` (λ = `observers.froude.froude_scale`): a ship
        (λ = 1) gets the defaults exactly, a 1:λ model ω × √λ and times ÷ √λ (`for_model`)."""
        return cls().for_model(froude_scale(vessel))


ESTIMATOR_KEYS = ("window_s", "update_period_s", "omega_min", "omega_max", "per_dof")
"""The estimator's settings a config or observer spec may set (the rest keep their defaults)."""


def estimator_config(vessel: VesselModel, params: dict[str, Any]) -> WaveFrequencyConfig:
    """The estimator of a config's ``params`` (keys of `ESTIMATOR_KEYS`) for ``vessel``.

    Neither ``omega_min`` nor ``omega_max`` given: `WaveFrequencyConfig.for_vessel`, Froude-scaled as a
    whole. Either given: the full-scale defaults with the given bound(s), the missing one the vessel's
    (module docstring, "Model ships"). Given window and period settings apply on top in both cases."""
    given = {k: params[k] for k in ESTIMATOR_KEYS if k in params}
    if "per_dof" in given:
        given["per_dof"] = bool(given["per_dof"])
    scaled = WaveFrequencyConfig.for_vessel(vessel)
    if "omega_min" not in given and "omega_max" not in given:
        return replace(scaled, **given)
    given.setdefault("omega_min", scaled.omega_min)
    given.setdefault("omega_max", scaled.omega_max)
    return WaveFrequencyConfig(**given)


@dataclass(frozen=True)
class SpectrumInfo:
    """What one update saw, per DOF: used, clean segments averaged, wave-band snr, own peak (rad/s, NaN if
    none); the combined peak."""

    t: float
    used: tuple[bool, bool, bool]
    segments: tuple[int, int, int]
    snr: tuple[float, float, float]
    peak: tuple[float, float, float]
    combined_peak: float
    band_power: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    """Mean power of the clean segments in [ω_min, ω_max] per DOF (m², rad²; noise included)."""
    noise_psd: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    """Mean noise level per DOF (one-sided PSD per rad/s, from the noise reference band)."""
    wave_power: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    """Power of the wave motion per DOF (m², rad²): the window's mean spectrum from the end of the LF
    motion's tail to ω_max, less the noise there (`wave_band_power`; NaN where not positive)."""

    def as_dict(self) -> dict[str, Any]:
        def clean(values: tuple[float, ...]) -> list[float | None]:
            return [float(v) if math.isfinite(v) else None for v in values]

        return {
            "t": self.t,
            "used": list(self.used),
            "segments": list(self.segments),
            "snr": clean(self.snr),
            "peak": clean(self.peak),
            "combined_peak": self.combined_peak if math.isfinite(self.combined_peak) else None,
        }


class WaveFrequencyEstimator:
    """Sliding-window spectral estimate of ω0 (rad/s, per DOF), updated every ``update_period_s``.

    ``add(t, y)`` takes one sample (t float, y (3,)) or many (t (n,), y (n, 3)); NaN = missing DOF; samples
    not later than the last one kept are ignored (time must increase). ``estimate(t)`` returns a new
    estimate (3,) when an update is due at t (t ≥ `next_update_t`) and the data allow one, else None.
    Updates fall on the grid t_first + k·T (t_first: the first sample's time); a silence longer than T
    skips the updates it covers instead of bunching them.
    """

    def __init__(self, config: WaveFrequencyConfig | None = None) -> None:
        self.config = config or WaveFrequencyConfig()
        self.reset()

    def reset(self) -> None:
        self._t = np.empty(1024)
        self._y = np.empty((3, 1024))  # one contiguous row per DOF
        self._n = 0
        self._t0: float | None = None
        self._next: float | None = None
        # k → segment k's wave-band PSD (3, band bins), clean DOFs, band power and noise level per DOF
        self._segments: dict[int, _Segment] = {}
        self.latest: Array | None = None
        self._raw: list[Array] = []
        self.updates = 0
        self.skipped = 0
        self.last_skip: str | None = None
        self.last_info: SpectrumInfo | None = None

    # -- data in ---------------------------------------------------------------------------------------------

    @property
    def next_update_t(self) -> float | None:
        """Time of the next update (None before the first sample)."""
        return self._next

    @property
    def last_t(self) -> float:
        return float(self._t[self._n - 1]) if self._n else -math.inf

    def add(self, t: ArrayLike, y: ArrayLike) -> None:
        """Samples in, appended to the window's buffer (amortised O(1) per sample). Only appended: what an
        estimate computes does not depend on how the samples were handed in."""
        t_arr = np.atleast_1d(np.asarray(t, dtype=float))
        y_arr = np.asarray(y, dtype=float).reshape(t_arr.shape[0], 3)
        m = t_arr.size
        if m == 0:
            return
        last = self.last_t
        if m == 1:
            if not float(t_arr[0]) > last:
                return
        elif not (t_arr[0] > last and bool((t_arr[1:] > t_arr[:-1]).all())):
            running = np.maximum.accumulate(np.concatenate([[last], t_arr]))
            keep = t_arr > running[:-1]
            t_arr, y_arr = t_arr[keep], y_arr[keep]
            m = t_arr.size
            if m == 0:
                return
        if self._next is None:
            self._t0 = float(t_arr[0])
            self._next = self._t0 + self.config.update_period_s
        if self._n + m > self._t.size:
            self._compact(m)
        self._t[self._n : self._n + m] = t_arr
        self._y[:, self._n : self._n + m] = y_arr.T
        self._n += m

    def add_until_updates(self, t: Array, y: Array) -> Iterator[int]:
        """`add` a record (t (n,), y (n, 3)) and stop at each sample where an update falls due: yields
        its index j, with samples 0 … j added, so that the caller can `estimate(t[j])` (and do its own
        work up to j) exactly where sample-by-sample use would; the rest is added at the end. What an
        update sees does not depend on how the samples are handed in, so batch and `step` agree."""
        n = t.shape[0]
        if n == 0:
            return
        k = 0
        if self._next is None:
            self.add(t[:1], y[:1])
            k = 1
        t_max = np.maximum.accumulate(t)  # an update happens at the first sample with t ≥ its time
        while k < n:
            assert self._next is not None
            j = int(np.searchsorted(t_max, self._next, side="left"))
            if j >= n:
                self.add(t[k:], y[k:])
                return
            self.add(t[k : j + 1], y[k : j + 1])
            k = j + 1
            yield j

    def _compact(self, incoming: int) -> None:
        """Drop samples no estimate can use any more (older than the window, a segment and a period), grow
        the buffer if needed."""
        c = self.config
        keep_from = self.last_t - (c.window_s + c.segment_s + c.update_period_s + 2.0 * c.max_gap_s)
        i0 = int(np.searchsorted(self._t[: self._n], keep_from, side="right"))
        kept = self._n - i0
        size = self._t.size
        while kept + incoming > size // 2:
            size *= 2
        if size != self._t.size:
            t_new, y_new = np.empty(size), np.empty((3, size))
        else:
            t_new, y_new = self._t, self._y
        t_new[:kept] = self._t[i0 : self._n]
        y_new[:, :kept] = self._y[:, i0 : self._n]
        self._t, self._y, self._n = t_new, y_new, kept

    def noise_sigma(self, t: float, span_s: float) -> Array:
        """σ of the sensor noise per DOF from the samples in (t − span_s, t]: the robust spread of the
        second differences y[k+1] − 2y[k] + y[k−1], 1.4826·MAD/√6 (heading differences wrapped). White
        noise has 6σ² of variance there, while motion smooth on the sampling scale hardly appears: a
        speed or a ramp not at all, waves at 1 rad/s sampled at 10 Hz with (ω·dt)⁴ ≈ 1e-4 of their
        variance. Each DOF uses its own samples (NaN = not measured). NaN for a DOF with fewer than 20
        usable differences."""
        i0 = int(np.searchsorted(self._t[: self._n], t - span_s, side="right"))
        i1 = int(np.searchsorted(self._t[: self._n], t, side="right"))
        out = np.full(3, math.nan)
        for i in range(3):
            y = self._y[i, i0:i1]
            have = np.isfinite(y)
            if int(have.sum()) < 22:
                continue
            tt, y = self._t[i0:i1][have], y[have]  # each DOF at its own samples (a fix every 0.5 s …)
            dt = np.diff(tt)
            ok = dt <= 1.5 * float(np.median(dt))  # differences across a dropout are not noise
            regular = ok[1:] & ok[:-1] & (np.abs(dt[1:] - dt[:-1]) <= 0.25 * dt[:-1])
            d = np.diff(y)
            if i == 2:
                d = ssa(d)
            d2 = np.diff(d)[regular]
            if d2.size >= 20:
                out[i] = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
        return out

    # -- estimate --------------------------------------------------------------------------------------------

    def due(self, t: float) -> bool:
        return self._next is not None and t >= self._next

    def estimate(self, t: float) -> Array | None:
        """A new ω0 estimate (rad/s, shape (3,)) if an update is due at t and succeeds, else None."""
        if not self.due(t):
            return None
        assert self._next is not None
        T = self.config.update_period_s
        self._next += T * max(1, math.floor((t - self._next) / T) + 1)
        result = self._compute(float(t))
        if result is None:
            self.skipped += 1
            return None
        self._raw.append(result)
        del self._raw[: -self.config.median_of]
        m = len(self._raw)
        if m > 1:
            med = []
            for i in range(3):
                ordered = sorted(float(r[i]) for r in self._raw)
                med.append(ordered[m // 2] if m % 2 else 0.5 * (ordered[m // 2 - 1] + ordered[m // 2]))
            result = np.array(med)
        self.latest = result
        self.updates += 1
        self.last_skip = None
        return result.copy()

    @cached_property
    def _design(self) -> tuple[float, int, int, Array, slice, slice, Array]:
        """fs, segment length (grid points), FFT length, ω bins (rad/s), the wave band and the noise
        reference band (slices of the bins), Hann window."""
        c = self.config
        fs = c.resample_hz_effective
        nseg = max(8, round(c.segment_s * fs))
        nfft = 1 << math.ceil(math.log2(_FFT_OVERSAMPLE * nseg))
        omega = np.asarray(2.0 * math.pi * np.fft.rfftfreq(nfft, 1.0 / fs), dtype=float)
        band = np.flatnonzero((omega >= c.omega_min) & (omega <= c.omega_max))
        noise = np.flatnonzero(
            (omega >= _NOISE_BAND[0] * c.omega_max) & (omega <= _NOISE_BAND[1] * math.pi * fs)
        )
        if band.size < 5 or noise.size < 5:
            raise ValueError(
                "WaveFrequencyConfig: segment_s is too short to resolve [omega_min, omega_max] "
                f"({band.size} frequency bins) or the noise band ({noise.size})"
            )
        return (
            fs,
            nseg,
            nfft,
            omega,
            slice(int(band[0]), int(band[-1]) + 1),
            slice(int(noise[0]), int(noise[-1]) + 1),
            np.hanning(nseg + 2)[1:-1],
        )

    @cached_property
    def _highpass(self) -> Array:
        """Power gain of the zero-phase high-pass on the bins, with DC and Nyquist halved (one-sided)."""
        c = self.config
        omega = self._design[3]
        r8 = (omega / (c.highpass_cutoff_ratio * c.omega_min)) ** 8
        g = (r8 / (1.0 + r8)) ** 2
        g[0] *= 0.5
        g[-1] *= 0.5
        return np.asarray(g, dtype=float)

    @cached_property
    def _band_start(self) -> NDArray[np.int64]:
        """Per DOF, the first wave-band bin searched: 0, or the first at or above the DP loop's natural
        frequency (`WaveFrequencyConfig.search_floor`)."""
        _, _, _, omega, band, _, _ = self._design
        w_band = omega[band]
        return np.array([int(np.searchsorted(w_band, f)) for f in self.config.search_floor], dtype=np.int64)

    @cached_property
    def _band_mask(self) -> Array:
        """(3, band bins): 1 from `_band_start` on, 0 below (the DP loop's band)."""
        n = self._design[4].stop - self._design[4].start
        return np.asarray(np.arange(n)[None, :] >= self._band_start[:, None], dtype=float)

    @cached_property
    def _lf_operators(self) -> dict[int, tuple[Array, Array]]:
        return {}

    def _detrend(self, x: Array) -> Array:
        """Rows of x less their least-squares quadratic: the bulk of the LF motion over one segment."""
        L = x.shape[1]
        ops = self._lf_operators.get(L)
        if ops is None:
            s = np.linspace(-1.0, 1.0, L)
            basis = np.stack([np.ones(L), s, 1.5 * s * s - 0.5])
            ops = (basis, np.linalg.pinv(basis))
            self._lf_operators[L] = ops
        basis, pinv = ops
        return np.asarray(x - (x @ pinv) @ basis, dtype=float)

    def _skip(self, t: float, reason: str, info: SpectrumInfo | None = None) -> None:
        self.last_skip = reason
        nan3 = (math.nan, math.nan, math.nan)
        self.last_info = info or SpectrumInfo(t, (False, False, False), (0, 0, 0), nan3, nan3, math.nan)

    def _segment(self, a: int, npts: int) -> _Segment:
        """Periodogram of the grid t0 + j/fs, j = a … a + npts − 1, per DOF: its wave band, whether the DOF
        is clean, its wave-band power and its noise level (median PSD in the noise reference band)."""
        c = self.config
        fs, _, nfft, omega, band, noise_mask, hann = self._design
        assert self._t0 is not None
        cell = 1.0 / fs
        centers: Array = self._t0 + np.arange(a, a + npts, dtype=float) * cell
        edges: Array = self._t0 + (np.arange(a, a + npts + 1, dtype=float) - 0.5) * cell
        n = self._n
        i0, i1 = np.searchsorted(self._t[:n], (edges[0] - c.max_gap_s, edges[-1] + c.max_gap_s))
        ts, ys = self._t[i0:i1], self._y[:, i0:i1]
        psd = np.zeros((3, omega.size))
        valid = np.zeros(3, dtype=bool)
        rows, x = _resample(edges, centers, ts, ys, c.max_gap_s)
        if rows:
            x = self._detrend(x)
            w = hann if npts == hann.size else np.hanning(npts + 2)[1:-1]
            X = np.fft.rfft(x * w, n=nfft, axis=1)
            # one-sided PSD per rad/s, 2|X|²/(Σw² · 2π fs) (DC and Nyquist once), through the high-pass
            psd[rows] = (X.real**2 + X.imag**2) * (self._highpass / (np.sum(w**2) * math.pi * fs))
            valid[rows] = True
        noise = psd[:, noise_mask]
        half_n = noise.shape[1] // 2
        part = np.partition(noise, [half_n - 1, half_n], axis=1)
        level = part[:, half_n] if noise.shape[1] % 2 else 0.5 * (part[:, half_n - 1] + part[:, half_n])
        in_band = psd[:, band]
        if self._band_start.any():  # a DP loop's band inside [ω_min, ω_max]: not searched
            in_band = in_band * self._band_mask
        power = in_band.sum(axis=1) * (omega[1] - omega[0])
        return _Segment(in_band, tuple(bool(v) for v in valid), power.tolist(), level.tolist())

    def _compute(self, t: float) -> Array | None:
        c = self.config
        fs, nseg, _, omega, band, _, _ = self._design
        assert self._t0 is not None
        hop = nseg // 2
        j_now = math.floor((t - self._t0) * fs + 0.5)
        j_last = math.floor((self.last_t - self._t0) * fs + 0.5)
        first = j_now - math.floor(c.window_s * fs)  # the window's first cell
        # segments inside the window and complete (the cell after them has begun): cached, or computed now
        k_lo = max(0, -(-first // hop))
        k_hi = (j_last - nseg) // hop
        for k in [k for k in self._segments if k < k_lo]:
            del self._segments[k]
        for k in range(k_lo, k_hi + 1):
            if k not in self._segments:
                self._segments[k] = self._segment(k * hop, nseg)
        stack = [self._segments[k] for k in range(k_lo, k_hi + 1)]
        if not any(any(seg.valid) for seg in stack):
            # no clean full segment yet: the data so far as one shorter segment (the first update)
            a = max(0, first)
            npts = j_last - a + 1
            if npts < 8 or (npts - 1) / fs < c.min_span_effective_s:
                self._skip(t, f"too little clean data: less than min_span_s = {c.min_span_effective_s:.1f} s")
                return None
            stack = [self._segment(a, npts)]
        # 6. per-DOF wave-band snr, weights; the window's spectrum is the mean over its clean segments
        count = [0, 0, 0]
        band_power = [0.0, 0.0, 0.0]
        noise_level = [0.0, 0.0, 0.0]
        psd = np.zeros_like(stack[0].psd)
        for seg in stack:
            psd += seg.psd  # a DOF's row is zero where it is not clean
            for i in range(3):
                if seg.valid[i]:
                    count[i] += 1
                    band_power[i] += seg.power[i]
                    noise_level[i] += seg.noise[i]
        snr = [math.nan, math.nan, math.nan]
        weight = [0.0, 0.0, 0.0]
        used = [False, False, False]
        floor = c.search_floor
        for i in range(3):
            if not count[i]:
                continue
            band_power[i] /= count[i]
            noise_power = noise_level[i] / count[i] * (c.omega_max - floor[i])
            snr[i] = (band_power[i] - noise_power) / noise_power if noise_power > 0 else math.inf
            if snr[i] >= c.min_snr and band_power[i] > 0:
                used[i] = True
                w = snr[i] / (1.0 + snr[i]) if math.isfinite(snr[i]) else 1.0
                # normalised to unit band power (the mean PSD is psd / count), weighted by snr
                weight[i] = w / (band_power[i] * count[i])
        nan3 = (math.nan, math.nan, math.nan)
        segs = (count[0], count[1], count[2])
        powers = _f3([band_power[i] if count[i] else math.nan for i in range(3)])
        noises = _f3([noise_level[i] / count[i] if count[i] else math.nan for i in range(3)])
        d_omega = float(omega[1] - omega[0])
        starts = self._band_start.tolist()
        waves = _f3(
            [
                wave_band_power(psd[i, starts[i] :] / count[i], d_omega, noises[i]) if count[i] else math.nan
                for i in range(3)
            ]
        )
        if not any(used):
            reason = (
                "too little clean data: no DOF has a segment without a gap > max_gap_s"
                if not any(count)
                else f"no wave peak above the noise (wave-band snr < min_snr = {c.min_snr:g} in every DOF)"
            )
            self._skip(
                t,
                reason,
                SpectrumInfo(
                    t, (used[0], used[1], used[2]), segs, _f3(snr), nan3, math.nan, powers, noises, waves
                ),
            )
            return None
        w_band = omega[band]
        lo = min(starts[i] for i in range(3) if used[i])  # (all the same with one ω0 for all DOFs)
        shared = _peak(np.dot(weight, psd)[lo:], w_band[lo:])
        peaks = [
            _peak(psd[i, starts[i] :], w_band[starts[i] :]) if c.per_dof and used[i] else math.nan
            for i in range(3)
        ]
        info = SpectrumInfo(
            t, (used[0], used[1], used[2]), segs, _f3(snr), _f3(peaks), shared, powers, noises, waves
        )
        if not math.isfinite(shared):
            self._skip(
                t,
                "the spectral maximum lies on an edge of [omega_min, omega_max] (above the DP loop's band, "
                "where known): no peak inside",
                info,
            )
            return None
        self.last_info = info
        if not c.per_dof:
            return np.full(3, shared)
        return np.array([p if math.isfinite(p) else shared for p in peaks])


@dataclass(frozen=True)
class _Segment:
    psd: Array  # (3, band bins), zero rows for DOFs that are not clean
    valid: tuple[bool, ...]
    power: list[float]  # wave-band power per DOF
    noise: list[float]  # noise level (PSD) per DOF


def _f3(v: list[float]) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def wave_band_power(psd: Array, d_omega: float, noise_psd: float) -> float:
    """Power of the wave motion in one DOF's spectrum over the wave band (``psd``: one-sided PSD per rad/s
    on the band's bins, ω_min … ω_max, spacing ``d_omega``), less the white noise at ``noise_psd``.

    The sum runs from the end of the LF motion's tail, not from ω_min: a band reaching down to a few
    bins above zero frequency (a bank's slowest candidate in a short segment) holds the LF motion that
    the quadratic and the window leave — a drifting, turning or manoeuvring vessel's, which a window of
    two short periods cannot separate from ω_min (the Hann main lobe is four bins wide). That tail falls
    from the lower edge; a sea has almost no energy below ~0.7 of its peak (PM: e^{−1.25(ωp/ω)⁴}). So when
    the spectrum falls from the lower edge, the sum starts at its first minimum (the trough between the
    LF tail and the wave peak), provided the spectrum rises again after it by `TROUGH_RISE` (a wave peak);
    when it rises from the edge, at ω_min. NaN (not measured) if it falls without a peak after, or if what
    is left is not positive."""
    p = np.asarray(psd, dtype=float)
    n = p.size
    start = 0
    while start + 1 < n and p[start + 1] < p[start]:
        start += 1
    if start and not p[start:].max() >= TROUGH_RISE * p[start]:
        # no hump after the first minimum (a chance dip of the noise): the LF tail runs into the sea, or a
        # sea peaks in the band's lowest bins, which this window cannot tell apart — not measured
        return math.nan
    power = float(p[start:].sum() - noise_psd * (n - start)) * d_omega
    return power if power > 0 else math.nan


def _resample(edges: Array, centers: Array, tv: Array, yv: Array, max_gap: float) -> tuple[list[int], Array]:
    """The DOFs (rows of yv, samples at times tv, NaN = missing) that can be put on the grid ``centers``
    (cells [edges[j], edges[j+1])), and their values there (len(dofs), len(centers)).

    Each cell with samples gives one point per DOF, the mean of its samples at their mean time (a box
    anti-alias filter: sampled faster than the grid, white noise is averaged down instead of folding into
    the band); the points are interpolated linearly at the cell centres (sampled slower than the grid,
    or across a short dropout). A DOF is left out if its samples leave a gap longer than ``max_gap``, or do
    not reach both ends of the grid (to within one cell). The heading (row 2) is unwrapped first.
    """
    idx = np.searchsorted(tv, edges)
    k = int(idx[-1])
    nd = yv.shape[0]
    if k - int(idx[0]) < 2:
        return [], np.empty((0, centers.size))
    finite = np.isfinite(yv[:, :k])
    every = bool(finite.all())
    count = idx[1:] - idx[:-1]
    cell = edges[1] - edges[0]
    if every and bool(count.all()):  # the usual case: every cell has samples, none missing
        rows = yv[:, :k]
        if nd == 3:
            psi = _unwrap(rows[2])
            if psi is not rows[2]:
                rows = np.vstack([rows[:2], psi])
        starts = idx[:-1]
        tj = np.add.reduceat(tv[:k], starts) / count
        # samples in every cell: no gap is longer than two cells, and both ends are reached
        if 2.0 * cell > max_gap and not _covers(tv, centers, cell, max_gap):
            return [], np.empty((0, centers.size))
        yj = np.add.reduceat(rows, starts, axis=1) / count
        return list(range(nd)), np.array([np.interp(centers, tj, row) for row in yj])
    # the general case (missing values, empty cells): one reduceat for the sums [t·f (3), y·f (3), f (3)],
    # f = 1 where a DOF has a value; each DOF then gets its own points, plus its nearest samples outside
    # the grid (fetched up to max_gap beyond it) so that empty cells at the ends are bridged too
    fin = np.isfinite(yv)
    if nd == 3 and fin[2].any():
        yv = yv.copy()
        yv[2] = _unwrap_finite(yv[2], fin[2])
    finite = fin[:, :k]
    padded = np.zeros((3 * nd, k + 1))
    padded[2 * nd :, :k] = finite
    padded[:nd, :k] = tv[:k] * finite
    padded[nd : 2 * nd, :k] = np.where(finite, yv[:, :k], 0.0)
    sums = np.add.reduceat(padded, idx[:-1], axis=1)
    if not count.all():
        sums[:, count == 0] = 0.0  # reduceat gives an empty cell the next sample, not zero
    counts = sums[2 * nd :]
    if 2.0 * cell <= max_gap and bool((counts > 0).all()):  # a few values missing, none for a whole cell
        tj = sums[:nd] / counts
        yj = sums[nd : 2 * nd] / counts
        return list(range(nd)), np.array([np.interp(centers, tj[i], yj[i]) for i in range(nd)])
    i0 = int(idx[0])
    dofs: list[int] = []
    out: list[Array] = []
    for i in range(nd):
        full = counts[i] > 0
        t_i = sums[i, full] / counts[i, full]
        v_i = sums[nd + i, full] / counts[i, full]
        before = np.flatnonzero(fin[i, :i0])
        after = np.flatnonzero(fin[i, k:])
        if before.size or after.size:
            lo = [before[-1]] if before.size else []
            hi = [k + after[0]] if after.size else []
            t_i = np.concatenate([tv[lo], t_i, tv[hi]])
            v_i = np.concatenate([yv[i, lo], v_i, yv[i, hi]])
        if t_i.size < 2 or not _covers(tv[fin[i]], centers, cell, max_gap):
            continue
        dofs.append(i)
        out.append(np.interp(centers, t_i, v_i))
    return dofs, np.array(out) if out else np.empty((0, centers.size))


def _covers(ts: Array, centers: Array, cell: float, max_gap: float) -> bool:
    """Samples at ts (increasing, fetched to max_gap beyond the grid) reach both ends of the grid to
    within a cell and leave no gap longer than max_gap."""
    return bool(
        ts.size >= 2
        and ts[0] <= centers[0] + cell
        and ts[-1] >= centers[-1] - cell
        and (ts[1:] - ts[:-1]).max() <= max_gap
    )


def _unwrap_finite(a: Array, finite: NDArray[np.bool_] | None) -> Array:
    """Heading unwrapped over its finite values (the others stay 0: they are masked out of the sums)."""
    if finite is None:
        return _unwrap(a)
    out = a.copy()
    out[finite] = _unwrap(a[finite])
    return out


def _unwrap(a: Array) -> Array:
    """np.unwrap for angles (rad), cheaper: subtract the 2π multiples that make every step < π."""
    if a.size < 2 or a.max() - a.min() < math.pi:
        return a
    d = a[1:] - a[:-1]
    if not (np.abs(d) > math.pi).any():
        return a
    return np.asarray(a - 2.0 * math.pi * np.concatenate([[0.0], np.cumsum(np.round(d / (2.0 * math.pi)))]))


def _peak(p: Array, w_band: Array, level: float = _FIT_LEVEL) -> float:
    """Peak of the wave model (18) (Fossen & Strand's (10)) fitted to the spectrum ``p`` on the wave band's
    bins ``w_band`` (rad/s).

    The PSD of the 2nd-order wave model, S(ω) = A ω² / ((ω0² − ω²)² + (2ζω0ω)²), has its maximum at ω0,
    and 1/S = (ω0⁴/A)/ω² + ω²/A + (4ζ² − 2)ω0²/A is linear in (1/ω², ω², 1): a weighted linear
    least-squares fit (weights S², i.e. relative error) over the contiguous bins around the maximum that
    stay above ``level`` × the maximum gives ω0 = (a/b)^¼. It uses the whole peak, not three bins, so it
    scatters less than a three-point parabola on a window of a random sea (docs/gain-scheduled.md). NaN if
    the maximum lies on an edge of the band (no peak inside).
    """
    v = p.tolist()  # ~50 bins: plain floats are cheaper than numpy calls here
    if len(v) < 3:
        return math.nan
    pos = max(range(len(v)), key=v.__getitem__)
    if pos == 0 or pos == len(v) - 1:
        return math.nan
    floor = level * v[pos]
    lo = pos
    while lo > 0 and v[lo - 1] >= floor:
        lo -= 1
    hi = pos + 1
    while hi < len(v) and v[hi] >= floor:
        hi += 1
    if hi - lo >= 3:
        # normal equations of the weighted fit in u = ω/ω_k (well scaled): rows x = S·(1/u², u², 1) → 1
        wk = float(w_band[pos])
        w = w_band[lo:hi].tolist()
        a11 = a12 = a13 = a22 = a23 = a33 = b1 = b2 = b3 = 0.0
        for wi, si in zip(w, v[lo:hi], strict=True):
            u2 = (wi / wk) ** 2
            x1, x2, x3 = si / u2, si * u2, si
            a11 += x1 * x1
            a12 += x1 * x2
            a13 += x1 * x3
            a22 += x2 * x2
            a23 += x2 * x3
            a33 += x3 * x3
            b1 += x1
            b2 += x2
            b3 += x3
        # Cramer's rule for the symmetric 3×3 system (only a and b are needed)
        c11 = a22 * a33 - a23 * a23
        c12 = a13 * a23 - a12 * a33
        c13 = a12 * a23 - a13 * a22
        det = a11 * c11 + a12 * c12 + a13 * c13
        if det > 1e-12 * a11 * a22 * a33:
            a = (b1 * c11 + b2 * c12 + b3 * c13) / det
            b = (b1 * c12 + b2 * (a11 * a33 - a13 * a13) + b3 * (a12 * a13 - a11 * a23)) / det
            if a > 0 and b > 0:
                w0 = wk * (a / b) ** 0.25
                if w[0] <= w0 <= w[-1]:
                    return w0
    # fallback: parabola through log PSD at the maximum and its neighbours
    y0, y1, y2 = (math.log(max(x, 1e-300)) for x in v[pos - 1 : pos + 2])
    den = y0 - 2.0 * y1 + y2
    delta = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    return float(w_band[pos] + max(-0.5, min(0.5, delta)) * (w_band[1] - w_band[0]))
