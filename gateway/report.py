"""The replay report: metrics and PNG plots in the style of the papers' figures.

After a sea trial the estimators are re-run on the recorded data (`dpgw replay`); this module turns the
result into what the papers show (Fossen & Strand 1999, Figs. 9-14; Torsetnes et al. 2004, Figs. 3-8):
measurement against the LF and WF estimates per DOF, velocities, bias, the wave frequency in use, and the
power spectra that show the wave filter at work. `docs/report.md` gives every formula and choice.

`compute_metrics` is pure numerics (arrays in, a JSON-able dict out); only `write_report` writes files.
matplotlib is optional (`pip install dpgw[plot]`): without it the report has the metrics and the table.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.fft import next_fast_len

from gateway.scoring import Score, score
from observers.kinematics import ssa

Array = NDArray[np.float64]

DOF = ("north", "east", "heading")
DOF_SYMBOL = ("N", "E", "ψ")
# The wave band searched for the spectral peak at full scale (rad/s: periods 3.1 s to 31 s).
FULL_SCALE_WAVE_BAND = (0.2, 2.0)
# Vessels shorter than this are laboratory models: the band is Froude-scaled from a prototype of
# PROTOTYPE_LENGTH_M (wave frequencies scale with 1/sqrt(length)).
MODEL_MAX_LENGTH_M = 10.0
PROTOTYPE_LENGTH_M = 80.0
# Default settle time: the first SETTLE_FRACTION of the replay, at most SETTLE_MAX_S seconds.
SETTLE_FRACTION = 0.1
SETTLE_MAX_S = 60.0
# Welch segments span WELCH_PERIODS periods of the band's lowest frequency (bin spacing ω_lo/8).
WELCH_PERIODS = 8
# Up to this many sample intervals between two valid samples are bridged by linear interpolation.
MAX_GAP_SAMPLES = 4.0
MAX_PLOT_POINTS = 20_000


# --------------------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class ObserverTrace:
    """One observer's estimates; arrays (n,) or (n, 3), SI units and radians."""

    label: str  # e.g. "passive", "passive_T9"
    t: NDArray[Any]  # seconds since the replay's start
    eta: NDArray[Any]  # LF estimate [N, E, ψ]
    nu: NDArray[Any]  # [u, v, r]
    bias: NDArray[Any]  # earth-fixed bias [X, Y, N] (N, N, N·m)
    eta_wf: NDArray[Any]  # WF estimate [N, E, ψ]
    omega0: NDArray[Any]  # wave frequency in use per DOF (rad/s); constant for a fixed-gain observer


@dataclass(frozen=True)
class ReplayData:
    """Everything a replay report shows."""

    title: str  # e.g. log file name(s)
    vessel: str
    t_meas: NDArray[Any]  # (m,) measurement times, s
    y: NDArray[Any]  # (m, 3) measurements [N, E, ψ], NaN where missing
    traces: tuple[ObserverTrace, ...]
    truth_t: NDArray[Any] | None = None  # simulator logs: /truth/state
    truth_eta_lf: NDArray[Any] | None = None
    truth_eta_wf: NDArray[Any] | None = None
    # per source {"received": n, "<reject reason>": n, ...};
    # per input log {"truncated": n, "time_gap": n, "time_backwards": n, ...}
    counts: Mapping[str, Mapping[str, int]] = field(default_factory=dict)


# ------------------------------------------------------------------------------------------- helpers
def _col3(a: NDArray[Any] | None, n: int) -> Array:
    """An (n, 3) float array from (n, 3) or (n,) (broadcast to the three DOFs); NaN if missing."""
    if a is None:
        return np.full((n, 3), np.nan)
    x = np.asarray(a, dtype=float)
    if x.ndim == 1:
        x = np.repeat(x[:, None], 3, axis=1)
    if x.shape != (n, 3):
        raise ValueError(f"expected an array of shape ({n}, 3) or ({n},), got {x.shape}")
    return x


def _interp(t_query: Array, t: Array, x: Array, angle: bool = False) -> Array:
    """Linear interpolation over the finite samples of x; an angle through its unwrapped value, then ssa.

    NaN outside the span of the finite samples."""
    ok = np.isfinite(x) & np.isfinite(t)
    if np.count_nonzero(ok) < 2:
        return np.full(len(t_query), np.nan)
    tv, xv = t[ok], x[ok]
    if angle:
        xv = np.unwrap(xv)
    out = np.interp(t_query, tv, xv, left=np.nan, right=np.nan)
    return ssa(out) if angle else out


def _interp3(t_query: Array, t: Array, eta: Array) -> Array:
    return np.column_stack([_interp(t_query, t, eta[:, k], angle=(k == 2)) for k in range(3)])


def _valid(t: Array, x: Array) -> NDArray[np.bool_]:
    """Finite samples at finite times (t sorted); of samples with the same time only the first."""
    ok = np.isfinite(x) & np.isfinite(t)
    idx = np.flatnonzero(ok)
    if len(idx) > 1:
        ok[idx[1:][np.diff(t[idx]) <= 0]] = False
    return ok


def _nominal_dt(t: Array) -> float:
    d = np.diff(t)
    d = d[d > 0]
    return float(np.median(d)) if len(d) else float("nan")


def wave_band_for_length(length_m: float | None) -> tuple[float, float]:
    """The wave band (rad/s) searched for the spectral peak: 0.2-2.0 rad/s at full scale; for a model
    shorter than 10 m, Froude-scaled from an 80 m prototype (ω ∝ 1/sqrt(L))."""
    lo, hi = FULL_SCALE_WAVE_BAND
    if length_m is None or not math.isfinite(length_m) or length_m <= 0 or length_m >= MODEL_MAX_LENGTH_M:
        return lo, hi
    k = math.sqrt(PROTOTYPE_LENGTH_M / length_m)
    return lo * k, hi * k


@lru_cache(maxsize=32)
def _vessel_length(vessel: str) -> float | None:
    """Length of a built-in vessel (or a vessel TOML path); None if unknown. Reads package data only."""
    if not vessel:
        return None
    try:
        from observers.vessel import load_vessel

        return float(load_vessel(vessel).length_m)
    except Exception:
        return None


def _stretches(t: Array, max_gap: float) -> list[tuple[int, int]]:
    """Index ranges [i0, i1) of t (times of valid samples) with no step longer than max_gap."""
    if len(t) == 0:
        return []
    breaks = np.flatnonzero(np.diff(t) > max_gap) + 1
    edges = np.concatenate(([0], breaks, [len(t)]))
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]


def _resample(t: Array, x: Array, dt: float, max_gap: float) -> list[Array]:
    """Valid samples (t increasing, x (n, c) finite) onto uniform grids of step dt, one per stretch.

    Gaps up to max_gap are bridged by linear interpolation; longer gaps split the record."""
    out = []
    for i0, i1 in _stretches(t, max_gap):
        ts, xs = t[i0:i1], x[i0:i1]
        n = math.floor((ts[-1] - ts[0]) / dt + 1e-9) + 1
        grid = ts[0] + dt * np.arange(n)
        out.append(np.column_stack([np.interp(grid, ts, xs[:, c]) for c in range(x.shape[1])]))
    return out


@dataclass(frozen=True)
class _Psd:
    omega: Array  # rad/s
    psd: Array  # one-sided, per rad/s
    segments: int


def _periodograms(x: Array, fs: float, nper: int) -> tuple[Array, Array, int]:
    """Welch's method on one record, vectorised: Hann window, 50 % overlap, linear detrend per segment,
    one-sided density (as `scipy.signal.welch`). Returns frequencies (Hz), the sum of the segments'
    periodograms and their number."""
    step = nper - nper // 2
    segs = np.lib.stride_tricks.sliding_window_view(x, nper)[::step]
    r = np.arange(nper) - (nper - 1) / 2.0
    segs = segs - segs.mean(axis=1, keepdims=True)
    segs = segs - np.outer(segs @ r / (r @ r), r)
    win = signal.windows.hann(nper, sym=False)
    spec = np.abs(np.fft.rfft(segs * win, axis=1)) ** 2 / (fs * np.sum(win**2))
    spec[:, 1 : nper // 2 + (nper % 2)] *= 2.0  # one-sided: all but DC (and Nyquist for even nper)
    freq = np.asarray(np.fft.rfftfreq(nper, 1.0 / fs), dtype=np.float64)
    total: Array = spec.sum(axis=0)
    return freq, total, len(segs)


def _welch(pieces: Sequence[Array], dt: float, seg_s: float, highpass: float | None) -> _Psd | None:
    """Welch PSD (Hann, 50 % overlap, linear detrend per segment) averaged over record pieces, each
    weighted by its number of segments. `highpass` (rad/s): a zero-phase 4th-order Butterworth high-pass
    first (the LF trend removal). Pieces shorter than a segment are skipped; if all are, the longest one
    is a single (shorter) segment."""
    fs = 1.0 / dt
    lengths = [len(p) for p in pieces]
    if not lengths or max(lengths) < 16:
        return None
    nper = next_fast_len(round(seg_s / dt), real=True)  # a segment a little longer, a fast FFT size
    if max(lengths) < nper:
        nper = max(lengths)
        pieces = [pieces[int(np.argmax(lengths))]]
    sos = None
    padlen = 0
    if highpass is not None:
        # odd extension over about three time constants of the filter keeps the edges quiet
        padlen = int(3.0 / (highpass * dt)) + 1
        wn = highpass / (math.pi * fs)  # (ω/2π) / (fs/2)
        if 0.0 < wn < 1.0:
            sos = signal.butter(4, wn, btype="highpass", output="sos")
    total: Array | None = None
    freq: Array | None = None
    nseg_total = 0
    for p in pieces:
        if len(p) < nper:
            continue
        x = p - np.mean(p)
        if sos is not None:
            x = signal.sosfiltfilt(sos, x, padlen=min(len(x) - 1, padlen))
        f, pxx_sum, nseg = _periodograms(x, fs, nper)
        total = pxx_sum if total is None else total + pxx_sum
        freq = f
        nseg_total += nseg
    if total is None or freq is None:
        return None
    return _Psd(omega=2.0 * math.pi * freq, psd=total / nseg_total / (2.0 * math.pi), segments=nseg_total)


def _peak(p: _Psd, band: tuple[float, float]) -> tuple[float, bool]:
    """Frequency (rad/s) of the largest PSD value in the band, refined by a parabola through the log-PSD
    of the three bins around it; and whether it sits on the band's edge (no wave peak found)."""
    idx = np.flatnonzero((p.omega >= band[0]) & (p.omega <= band[1]) & (p.psd > 0))
    if len(idx) == 0:
        return float("nan"), False
    k = int(idx[np.argmax(p.psd[idx])])
    at_edge = k in (idx[0], idx[-1])
    if 0 < k < len(p.psd) - 1 and np.all(p.psd[k - 1 : k + 2] > 0):
        a, b, c = np.log(p.psd[k - 1 : k + 2])
        den = a - 2.0 * b + c
        delta = 0.5 * (a - c) / den if den < 0 else 0.0
        dw = p.omega[1] - p.omega[0]
        return float(p.omega[k] + float(np.clip(delta, -0.5, 0.5)) * dw), bool(at_edge)
    return float(p.omega[k]), bool(at_edge)


def _band_power(p: _Psd, omega: float) -> float:
    """PSD summed over the three bins around omega."""
    k = int(np.argmin(np.abs(p.omega - omega)))
    return float(np.sum(p.psd[max(k - 1, 0) : k + 2]))


def _neighbours(t: Array, dt: float) -> NDArray[np.bool_]:
    """Consecutive valid samples that are true neighbours (no missing sample between them)."""
    return np.diff(t) <= 1.5 * dt


def _f(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


# ------------------------------------------------------------------------------------------ analysis
@dataclass
class _Analysis:
    prep: _Prepared
    metrics: dict[str, Any]
    band: tuple[float, float]
    settle_t: float
    meas_peak: list[float]  # dominant frequency per DOF (rad/s)
    meas_psd: list[_Psd | None]  # measurement PSD per DOF (plot: no high-pass)
    est_psd: dict[int, list[_Psd | None]]  # per trace index, per DOF: LF estimate PSD (plot)
    attenuation: dict[int, list[float]]


@dataclass(frozen=True)
class _Trace:
    label: str
    t: Array
    eta: Array
    nu: Array
    bias: Array
    eta_wf: Array
    omega0: Array


@dataclass(frozen=True)
class _Prepared:
    """The report's inputs as float arrays of checked shapes, sorted by time."""

    t_meas: Array
    y: Array
    traces: list[_Trace]
    truth: tuple[Array, Array, Array | None] | None  # t, η_LF, η_WF


def _prepare(data: ReplayData) -> _Prepared:
    t_meas = np.asarray(data.t_meas, dtype=float).reshape(-1)
    o = np.argsort(t_meas, kind="stable")
    y = _col3(data.y, len(t_meas))[o]
    traces = []
    for tr in data.traces:
        t = np.asarray(tr.t, dtype=float).reshape(-1)
        n = len(t)
        oo = np.argsort(t, kind="stable")
        arrays = [_col3(a, n)[oo] for a in (tr.eta, tr.nu, tr.bias, tr.eta_wf, tr.omega0)]
        traces.append(_Trace(str(tr.label), t[oo], *arrays))
    truth = None
    if data.truth_t is not None and data.truth_eta_lf is not None and len(data.truth_t) > 1:
        tt = np.asarray(data.truth_t, dtype=float).reshape(-1)
        to = np.argsort(tt, kind="stable")
        wf = _col3(data.truth_eta_wf, len(tt))[to] if data.truth_eta_wf is not None else None
        truth = (tt[to], _col3(data.truth_eta_lf, len(tt))[to], wf)
    return _Prepared(t_meas[o], y, traces, truth)


def _analyse(data: ReplayData, wave_band: tuple[float, float] | None, settle_s: float | None) -> _Analysis:
    prep = _prepare(data)
    t_meas, y, traces = prep.t_meas, prep.y, prep.traces
    starts = [t_meas[0]] if len(t_meas) else []
    ends = [t_meas[-1]] if len(t_meas) else []
    for tr_ in traces:
        if len(tr_.t):
            starts.append(tr_.t[0])
            ends.append(tr_.t[-1])
    t0 = float(min(starts)) if starts else 0.0
    t1 = float(max(ends)) if ends else 0.0
    duration = t1 - t0
    if settle_s is None:
        settle_s = min(SETTLE_MAX_S, SETTLE_FRACTION * duration)
    settle_t = t0 + settle_s

    if wave_band is None:
        length = _vessel_length(data.vessel)
        band = wave_band_for_length(length)
        if length is None:
            basis = f"full scale (vessel '{data.vessel}' not found: length unknown)"
        elif length < MODEL_MAX_LENGTH_M:
            basis = f"Froude-scaled: model of L = {length:g} m, prototype {PROTOTYPE_LENGTH_M:g} m"
        else:
            basis = f"full scale (L = {length:g} m)"
    else:
        band = (float(wave_band[0]), float(wave_band[1]))
        basis = "given"
    seg_s = WELCH_PERIODS * 2.0 * math.pi / band[0]
    hp = band[0] / 3.0

    has_truth = prep.truth is not None
    metrics: dict[str, Any] = {
        "title": data.title,
        "vessel": data.vessel,
        "units": {
            "north": "m",
            "east": "m",
            "heading": "rad",
            "time": "s",
            "frequency": "rad/s",
            "attenuation": "dB",
            "psd": "unit²·s/rad",
        },
        "span_s": [_f(t0), _f(t1)],
        "duration_s": _f(duration),
        "settle_s": _f(settle_s),
        "wave_band_rad_s": [band[0], band[1]],
        "wave_band_basis": basis,
        "truth": bool(has_truth),
    }

    # ---- measurement: dominant wave frequency per DOF (whole record)
    meas_info = []  # per DOF: (valid mask, dt, max_gap, band clipped to Nyquist)
    meas_peak: list[float] = []
    meas_psd: list[_Psd | None] = []
    mdict: dict[str, Any] = {"samples": len(t_meas)}
    for k in range(3):
        valid = _valid(t_meas, y[:, k])
        tv = t_meas[valid]
        dt = _nominal_dt(tv)
        max_gap = MAX_GAP_SAMPLES * dt
        band_k = (band[0], min(band[1], 0.8 * math.pi / dt)) if math.isfinite(dt) else band
        xv = y[valid, k]
        if k == 2:
            xv = np.unwrap(xv)
        pieces = [p[:, 0] for p in _resample(tv, xv[:, None], dt, max_gap)] if math.isfinite(dt) else []
        psd_hp = _welch(pieces, dt, seg_s, hp) if pieces else None
        psd_raw = _welch(pieces, dt, seg_s, None) if pieces else None
        w_peak, at_edge = _peak(psd_hp, band_k) if psd_hp is not None else (float("nan"), False)
        meas_info.append((valid, dt, max_gap, band_k))
        meas_peak.append(w_peak)
        meas_psd.append(psd_raw)
        mdict[DOF[k]] = {
            "valid": int(np.count_nonzero(valid)),
            "sample_interval_s": _f(dt),
            "psd_segments": psd_hp.segments if psd_hp is not None else 0,
            "dominant_frequency_rad_s": _f(w_peak),
            "dominant_period_s": _f(2.0 * math.pi / w_peak) if w_peak > 0 else None,
            "peak_at_band_edge": at_edge,
        }
    metrics["measurement"] = mdict

    # ---- per observer
    observers: dict[str, Any] = {}
    est_psd: dict[int, list[_Psd | None]] = {}
    attenuation: dict[int, list[float]] = {}
    for i, trace in enumerate(traces):
        label, t, eta, eta_wf, omega0 = trace.label, trace.t, trace.eta, trace.eta_wf, trace.omega0
        key = label if label not in observers else f"{label}#{i + 1}"
        odict: dict[str, Any] = {"samples": len(t), "span_s": [_f(t[0]), _f(t[-1])] if len(t) else None}
        est_psd[i] = []
        attenuation[i] = []
        s_lf: Score | None = None
        s_wf: Score | None = None
        if prep.truth is not None and len(t):
            tt, t_lf, t_wf = prep.truth
            settle_rel = max(0.0, settle_t - float(t[0]))
            s_lf = score(t, eta, tt, t_lf, settle_s=settle_rel)
            s_wf = score(t, eta_wf, tt, t_wf, settle_s=settle_rel) if t_wf is not None else None
        total = eta + eta_wf
        total[:, 2] = ssa(total[:, 2])
        for k in range(3):
            valid, dt, max_gap, _band_k = meas_info[k]
            ang = k == 2
            sel = valid & (t_meas >= settle_t)
            if len(t):
                sel &= (t_meas >= t[0]) & (t_meas <= t[-1])
            tq = t_meas[sel]
            yq = y[sel, k]
            lfq = _interp(tq, t, eta[:, k], angle=ang) if len(t) else np.full(len(tq), np.nan)
            totq = _interp(tq, t, total[:, k], angle=ang) if len(t) else np.full(len(tq), np.nan)
            ok = np.isfinite(lfq) & np.isfinite(totq)
            tq, yq, lfq, totq = tq[ok], yq[ok], lfq[ok], totq[ok]

            # innovation ỹ = y − (η̂ + η̂_w)
            inn = _y_minus(yq, totq, ang)
            nb = _neighbours(tq, dt) if len(tq) > 1 else np.zeros(0, dtype=bool)
            if len(inn):
                mu = float(np.mean(inn))
                sd = float(np.std(inn))
                rms = float(np.sqrt(np.mean(inn**2)))
                c = inn - mu
                var = float(np.mean(c**2))
                # a (numerically) constant residual has no autocorrelation
                r1 = (
                    float(np.mean(c[:-1][nb] * c[1:][nb])) / var
                    if np.any(nb) and var > 1e-18 * max(rms * rms, 1e-300)
                    else float("nan")
                )
            else:
                mu = sd = rms = r1 = float("nan")

            # smoothness: first differences of neighbouring samples on the measurement time grid
            if np.any(nb):
                dy = np.diff(yq)[nb]
                de = np.diff(lfq)[nb]
                if ang:
                    dy, de = ssa(dy), ssa(de)
                sdy, sde = float(np.std(dy)), float(np.std(de))
            else:
                sdy = sde = float("nan")

            # attenuation at the measurement's wave peak: the same samples of y and η̂ through the same
            # resampling, high-pass and Welch estimate
            att = float("nan")
            p_est_raw: _Psd | None = None
            segs = 0
            if len(tq) > 1 and math.isfinite(dt):
                pair = np.column_stack([np.unwrap(yq), np.unwrap(lfq)] if ang else [yq, lfq])
                pieces = _resample(tq, pair, dt, max_gap)
                pm = _welch([p[:, 0] for p in pieces], dt, seg_s, hp)
                pe = _welch([p[:, 1] for p in pieces], dt, seg_s, hp)
                p_est_raw = _welch([p[:, 1] for p in pieces], dt, seg_s, None)
                if pm is not None and pe is not None and math.isfinite(meas_peak[k]):
                    segs = pm.segments
                    den = _band_power(pm, meas_peak[k])
                    num = _band_power(pe, meas_peak[k])
                    if den > 0 and num > 0:
                        att = 10.0 * math.log10(num / den)
            est_psd[i].append(p_est_raw)
            attenuation[i].append(att)

            w0 = omega0[:, k][(t >= settle_t) & np.isfinite(omega0[:, k])] if len(t) else np.zeros(0)
            dof: dict[str, Any] = {
                "omega0_median_rad_s": _f(float(np.median(w0))) if len(w0) else None,
                "attenuation_db": _f(att),
                "psd_segments": segs,
                "innovation": {
                    "samples": len(inn),
                    "mean": _f(mu),
                    "std": _f(sd),
                    "rms": _f(rms),
                    "lag1_autocorrelation": _f(r1),
                },
                "smoothness": {
                    "std_diff_estimate": _f(sde),
                    "std_diff_measurement": _f(sdy),
                    "ratio": _f(sde / sdy) if sdy > 0 else None,
                },
                "truth_samples": s_lf.samples if s_lf is not None else None,
                "rms_error": _f(s_lf.rms[k]) if s_lf is not None else None,
                "mean_square_error": _f(s_lf.mean_square[k]) if s_lf is not None else None,
                "rms_error_wf": _f(s_wf.rms[k]) if s_wf is not None else None,
            }
            odict[DOF[k]] = dof
        observers[key] = odict
    metrics["observers"] = observers
    metrics["counts"] = {str(src): {str(r): int(n) for r, n in c.items()} for src, c in data.counts.items()}
    return _Analysis(prep, metrics, band, settle_t, meas_peak, meas_psd, est_psd, attenuation)


def _y_minus(y: Array, est: Array, angle: bool) -> Array:
    """y − est; for an angle the smallest signed angle of the difference, in [-π, π)."""
    d = y - est
    return ssa(d) if angle else d


def compute_metrics(
    data: ReplayData,
    *,
    wave_band: tuple[float, float] | None = None,
    settle_s: float | None = None,
) -> dict[str, Any]:
    """The report's numbers as a JSON-able dict (NaN → None); see docs/report.md for each key.

    `wave_band` (rad/s) overrides the band searched for the measurement's wave peak (default: from the
    vessel's length, `wave_band_for_length`); `settle_s` the time excluded at the start (default: the first
    10 % of the replay, at most 60 s)."""
    return _analyse(data, wave_band, settle_s).metrics


# --------------------------------------------------------------------------------------------- plots
_COLOURS = ("black", "tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange", "tab:brown", "tab:cyan")
_MEAS: dict[str, Any] = {"color": "0.70", "lw": 0.8}
_TRUTH: dict[str, Any] = {"color": "0.35", "lw": 1.0, "ls": "--", "zorder": 50}


def decimate(t: NDArray[Any], x: NDArray[Any], max_points: int = MAX_PLOT_POINTS) -> tuple[Array, Array]:
    """At most `max_points` points of a line that keep its envelope: the min and max of each bucket, in
    time order. NaN (gaps) survive where a whole bucket is NaN, so lines still break there."""
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = len(t)
    if n <= max_points:
        return t, x
    b = math.ceil(n / (max_points // 2))
    m = math.ceil(n / b)
    pad = m * b - n
    xp = np.concatenate([x, np.full(pad, np.nan)]).reshape(m, b)
    finite = np.isfinite(xp)
    any_f = finite.any(axis=1)
    imin = np.argmin(np.where(finite, xp, np.inf), axis=1)
    imax = np.argmax(np.where(finite, xp, -np.inf), axis=1)
    lo = np.minimum(imin, imax) + b * np.arange(m)
    hi = np.maximum(imin, imax) + b * np.arange(m)
    idx = np.column_stack([lo, hi]).reshape(-1)
    idx = np.minimum(idx, n - 1)
    xs = x[idx].copy()
    xs[np.repeat(~any_f, 2)] = np.nan
    return t[idx], xs


def _heading_deg(t: Array, psi: Array, centre: float) -> tuple[Array, Array]:
    """Heading in degrees within ±180° of `centre` (rad), with a break (NaN) where it wraps."""
    d = np.degrees(centre + ssa(psi - centre))
    jumps = np.flatnonzero(np.abs(np.diff(d)) > 180.0) + 1
    if len(jumps):
        d = np.insert(d, jumps, np.nan)
        t = np.insert(t, jumps, np.nan)
    return t, d


def _time_scale(duration: float) -> tuple[float, str]:
    if duration > 10 * 3600:
        return 3600.0, "time (h)"
    if duration > 600:
        return 60.0, "time (min)"
    return 1.0, "time (s)"


def _load_figure() -> Any:
    """matplotlib's Figure class, or None if matplotlib is not installed. No pyplot: no global state,
    safe in threads; PNGs are drawn by the Agg canvas."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return None
    return Figure


def _plots(data: ReplayData, an: _Analysis, folder: Path, Figure: Any) -> list[Path]:
    prep = an.prep
    t_meas, y, traces, truth = prep.t_meas, prep.y, prep.traces, prep.truth
    span = an.metrics["span_s"]
    scale, tlabel = _time_scale((span[1] or 0.0) - (span[0] or 0.0))
    # heading plotted around the circular mean of the measured (else estimated) heading
    psi_ref = y[:, 2][np.isfinite(y[:, 2])]
    if len(psi_ref) == 0 and traces and len(traces[0].t):
        psi_ref = traces[0].eta[:, 2][np.isfinite(traces[0].eta[:, 2])]
    centre = float(np.arctan2(np.mean(np.sin(psi_ref)), np.mean(np.cos(psi_ref)))) if len(psi_ref) else 0.0
    suptitle = f"{data.title} — {data.vessel}" if data.vessel else data.title

    # zoom window (Torsetnes et al. Figs. 7-8): the last 20 wave periods of the record, at least 60 s
    peaks = [w for w in an.meas_peak if math.isfinite(w) and w > 0]
    t_end = span[1] or 0.0
    t_beg = span[0] or 0.0
    zoom_len = 20.0 * 2.0 * math.pi / float(np.median(peaks)) if peaks else 0.05 * (t_end - t_beg)
    zoom = (max(t_beg, t_end - max(zoom_len, 60.0)), t_end)
    use_zoom = zoom[0] > t_beg + 0.05 * (t_end - t_beg)

    def figure(name: str, rows: int = 1) -> tuple[Any, Any]:
        fig = Figure(figsize=(15.0, 0.6 + 3.6 * rows), layout="constrained")
        axes = fig.subplots(rows, 3, squeeze=False, sharex="row" if name != "psd" else False)
        fig.suptitle(f"{suptitle}: {name}", fontsize=11)
        for ax in axes.flat:
            ax.grid(True, color="0.9", lw=0.6)
            ax.tick_params(labelsize=8)
        return fig, axes

    def line(
        ax: Any,
        t: Array,
        x: Array,
        *,
        deg: bool = False,
        wrap: bool = False,
        window: tuple[float, float] | None = None,
        **kw: Any,
    ) -> None:
        if window is not None:
            m = (t >= window[0]) & (t <= window[1])
            t, x = t[m], x[m]
        if len(t) == 0:
            return
        if wrap:
            t, x = _heading_deg(t, x, centre)
        elif deg:
            x = np.degrees(x)
        td, xd = decimate(t, x)
        ax.plot(td / scale, xd, **kw)

    def colour(i: int) -> str:
        return _COLOURS[i % len(_COLOURS)]

    def z(i: int) -> float:
        """The first observer (black) is drawn on top of the others, as in the papers."""
        return 40.0 - i * 30.0 / max(len(traces), 1)

    def save(fig: Any, axes: Any, name: str) -> Path:
        for ax in axes[-1]:
            ax.set_xlabel(tlabel if name != "psd" else "frequency ω (rad/s)", fontsize=9)
        handles, labels = axes[0][0].get_legend_handles_labels()
        if handles:
            fig.legend(handles, labels, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
        path = folder / f"{name}.png"
        fig.savefig(path, dpi=100)
        return path

    def mark_zoom(axes: Any) -> None:
        for ax in axes[0]:
            ax.axvspan(zoom[0] / scale, zoom[1] / scale, color="tab:olive", alpha=0.12, lw=0, zorder=0)
        for ax in axes[1]:
            ax.set_title(f"zoom: last {zoom[1] - zoom[0]:.0f} s", fontsize=8, loc="right")

    written = []
    rows = 2 if use_zoom else 1
    windows: list[tuple[float, float] | None] = [None, zoom] if use_zoom else [None]

    # 1. position: measurement, LF estimates, true LF motion (Fossen & Strand Figs. 13-14)
    pos_units = ("north (m)", "east (m)", "heading ψ (deg)")
    fig, axes = figure("position", rows)
    for r, win in enumerate(windows):
        for k, ax in enumerate(axes[r]):
            line(ax, t_meas, y[:, k], wrap=k == 2, window=win, label="measurement y", **_MEAS)
            if truth is not None:
                line(ax, truth[0], truth[1][:, k], wrap=k == 2, window=win, label="true LF η", **_TRUTH)
            for i, tr_ in enumerate(traces):
                lab = f"η̂ {tr_.label}"
                kw: dict[str, Any] = {"color": colour(i), "lw": 1.0, "zorder": z(i), "label": lab}
                line(ax, tr_.t, tr_.eta[:, k], wrap=k == 2, window=win, **kw)
            ax.set_ylabel(pos_units[k], fontsize=9)
            if r == 0:
                ax.set_title(f"{DOF_SYMBOL[k]}: measurement and LF estimate", fontsize=9)
    if use_zoom:
        mark_zoom(axes)
    written.append(save(fig, axes, "position"))

    # 2. wave: WF estimates on the true WF motion (grey, as in Fossen & Strand Figs. 9-11)
    wf_units = ("north η_w (m)", "east η_w (m)", "heading ψ_w (deg)")
    fig, axes = figure("wave", rows)
    for r, win in enumerate(windows):
        for k, ax in enumerate(axes[r]):
            if truth is not None and truth[2] is not None:
                kw_t: dict[str, Any] = {"color": "0.6", "lw": 1.2, "zorder": 1, "label": "true WF η_w"}
                line(ax, truth[0], truth[2][:, k], deg=k == 2, window=win, **kw_t)
            for i, tr_ in enumerate(traces):
                kw_w: dict[str, Any] = {
                    "color": colour(i),
                    "lw": 0.8,
                    "zorder": z(i),
                    "label": f"η̂_w {tr_.label}",
                }
                line(ax, tr_.t, tr_.eta_wf[:, k], deg=k == 2, window=win, **kw_w)
            ax.set_ylabel(wf_units[k], fontsize=9)
            if r == 0:
                ax.set_title(f"{DOF_SYMBOL[k]}: WF estimate", fontsize=9)
    if use_zoom:
        mark_zoom(axes)
    written.append(save(fig, axes, "wave"))

    # 3. velocity
    fig, axes = figure("velocity")
    vel_units = ("surge u (m/s)", "sway v (m/s)", "yaw rate r (deg/s)")
    for k, ax in enumerate(axes[0]):
        for i, tr_ in enumerate(traces):
            line(
                ax,
                tr_.t,
                tr_.nu[:, k],
                deg=k == 2,
                color=colour(i),
                lw=1.0,
                zorder=z(i),
                label=f"ν̂ {tr_.label}",
            )
        ax.set_ylabel(vel_units[k], fontsize=9)
        ax.set_title(("u", "v", "r")[k] + ": velocity estimate", fontsize=9)
    written.append(save(fig, axes, "velocity"))

    # 4. bias (kN / MN when large)
    fig, axes = figure("bias")
    for k, ax in enumerate(axes[0]):
        big = max((float(np.nanmax(np.abs(tr_.bias[:, k]), initial=0.0)) for tr_ in traces), default=0.0)
        div, prefix = (1e6, "M") if big >= 1e7 else (1e3, "k") if big >= 1e4 else (1.0, "")
        for i, tr_ in enumerate(traces):
            td, xd = decimate(tr_.t, tr_.bias[:, k] / div)
            ax.plot(td / scale, xd, color=colour(i), lw=1.0, zorder=z(i), label=f"b̂ {tr_.label}")
        unit = f"{prefix}N·m" if k == 2 else f"{prefix}N"
        ax.set_ylabel(f"{('X', 'Y', 'N')[k]} ({unit})", fontsize=9)
        ax.set_title(f"{('X', 'Y', 'N')[k]}: bias estimate (earth-fixed)", fontsize=9)
    written.append(save(fig, axes, "bias"))

    # 5. omega0: wave frequency in use, and the measurement's spectral peak
    fig, axes = figure("omega0")
    for k, ax in enumerate(axes[0]):
        for i, tr_ in enumerate(traces):
            td, xd = decimate(tr_.t, tr_.omega0[:, k])
            ax.plot(td / scale, xd, color=colour(i), lw=1.2, zorder=z(i), label=f"ω₀ {tr_.label}")
        if math.isfinite(an.meas_peak[k]):
            ax.axhline(an.meas_peak[k], color="0.5", ls="--", lw=1.0, label="PSD peak of y")
        ax.set_ylabel("ω₀ (rad/s)", fontsize=9)
        ax.set_title(f"{DOF_SYMBOL[k]}: wave frequency in use", fontsize=9)
    written.append(save(fig, axes, "omega0"))

    # 6. psd: measurement vs LF estimate, wave band shaded, attenuation annotated
    fig, axes = figure("psd")
    psd_units = ("PSD north (m²·s/rad)", "PSD east (m²·s/rad)", "PSD heading (deg²·s/rad)")
    for k, ax in enumerate(axes[0]):
        conv = math.degrees(1.0) ** 2 if k == 2 else 1.0
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axvspan(an.band[0], an.band[1], color="0.93", zorder=0, label="wave band searched")
        drawn = False
        pm = an.meas_psd[k]
        if pm is not None:
            m = pm.omega > 0
            ax.plot(pm.omega[m], pm.psd[m] * conv, label="measurement y", **_MEAS, zorder=45)
            drawn = True
        notes = []
        for i, tr_ in enumerate(traces):
            pe = an.est_psd[i][k]
            if pe is not None:
                m = pe.omega > 0
                ax.plot(
                    pe.omega[m],
                    pe.psd[m] * conv,
                    color=colour(i),
                    lw=1.0,
                    zorder=z(i),
                    label=f"η̂ {tr_.label}",
                )
                drawn = True
            a = an.attenuation[i][k]
            notes.append(f"{tr_.label}: {a:+.1f} dB" if math.isfinite(a) else f"{tr_.label}: –")
        wp = an.meas_peak[k]
        if math.isfinite(wp):
            ax.axvline(wp, color="0.4", ls=":", lw=1.0)
            notes.insert(0, f"peak ω = {wp:.3g} rad/s (T = {2 * math.pi / wp:.3g} s)")
        if notes:
            ax.text(
                0.02,
                0.03,
                "\n".join(notes),
                transform=ax.transAxes,
                ha="left",
                va="bottom",
                fontsize=8,
                zorder=100,
                bbox={"facecolor": "white", "edgecolor": "0.8", "alpha": 0.85},
            )
        if not drawn:
            ax.set_xlim(an.band[0] / 10.0, an.band[1] * 2.0)
        ax.set_ylabel(psd_units[k], fontsize=9)
        ax.set_title(f"{DOF_SYMBOL[k]}: PSD, attenuation at the wave peak", fontsize=9)
    written.append(save(fig, axes, "psd"))
    return written


# --------------------------------------------------------------------------------------------- files
def _json_clean(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _json_clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_clean(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _fmt(x: Any, digits: int = 3, scale: float = 1.0) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{float(x) * scale:.{digits}g}"


def _report_md(data: ReplayData, m: dict[str, Any], plot_note: str, pngs: Sequence[Path]) -> str:
    deg = math.degrees(1.0)
    lines = [f"# Replay report: {data.title}", ""]
    lines += [
        f"- vessel: {data.vessel or '–'}",
        f"- span: {_fmt(m['span_s'][0], 6)} s to {_fmt(m['span_s'][1], 6)} s ({_fmt(m['duration_s'], 4)} s)",
        f"- measurements: {m['measurement']['samples']} samples; metrics after a settle time of "
        f"{_fmt(m['settle_s'], 4)} s",
        f"- wave band searched: {m['wave_band_rad_s'][0]:.3g}–{m['wave_band_rad_s'][1]:.3g} rad/s "
        f"— {m['wave_band_basis']}",
        f"- ground truth: {'yes (simulator log)' if m['truth'] else 'no'}",
        "",
        "## Measurement: dominant wave frequency",
        "",
        "| DOF | valid samples | sample interval (s) | peak ω (rad/s) | peak period (s) | Welch segments |",
        "|---|---|---|---|---|---|",
    ]
    for k, d in enumerate(DOF):
        md = m["measurement"][d]
        edge = " (band edge: no clear wave peak)" if md["peak_at_band_edge"] else ""
        lines.append(
            f"| {DOF_SYMBOL[k]} | {md['valid']} | {_fmt(md['sample_interval_s'])} | "
            f"{_fmt(md['dominant_frequency_rad_s'])}{edge} | {_fmt(md['dominant_period_s'])} | "
            f"{md['psd_segments']} |"
        )
    units = ("N (m)", "E (m)", "ψ (deg)")
    for label, od in m["observers"].items():
        lines += ["", f"## Observer `{label}`", ""]
        head = (
            "| DOF | ω₀ in use (rad/s) | attenuation at peak (dB) | innovation mean | innovation std | "
            "innovation RMS | lag-1 autocorr. | smoothness ratio |"
        )
        sep = "|---|---|---|---|---|---|---|---|"
        if m["truth"]:
            head += " RMS error LF | mean square error LF | RMS error WF |"
            sep += "---|---|---|"
        lines += [head, sep]
        for k, d in enumerate(DOF):
            dd = od[d]
            s = deg if k == 2 else 1.0
            inn = dd["innovation"]
            row = (
                f"| {units[k]} | {_fmt(dd['omega0_median_rad_s'])} | {_fmt(dd['attenuation_db'])} | "
                f"{_fmt(inn['mean'], 3, s)} | {_fmt(inn['std'], 3, s)} | {_fmt(inn['rms'], 3, s)} | "
                f"{_fmt(inn['lag1_autocorrelation'], 2)} | {_fmt(dd['smoothness']['ratio'], 2)} |"
            )
            if m["truth"]:
                row += (
                    f" {_fmt(dd['rms_error'], 3, s)} | {_fmt(dd['mean_square_error'], 3, s * s)} | "
                    f"{_fmt(dd['rms_error_wf'], 3, s)} |"
                )
            lines.append(row)
        lines.append("")
        lines.append(
            f"{od['samples']} estimates. Heading rows in degrees (mean square in deg²). Smoothness ratio = "
            "std of the LF estimate's first difference / that of the measurement (< 1: smoother)."
        )
    lines += ["", "## Bad input", ""]
    if m["counts"]:
        lines += ["| source / log | counter | count |", "|---|---|---|"]
        for src, c in m["counts"].items():
            for reason, n in c.items():
                lines.append(f"| {src} | {reason} | {n} |")
    else:
        lines.append("No counts were passed to the report.")
    lines += ["", "## Plots", ""]
    if pngs:
        for p in pngs:
            lines += [f"![{p.stem}]({p.name})", ""]
    else:
        lines.append(plot_note)
    lines += ["", "Numbers: `metrics.json` (SI units, radians). Definitions: dpgw `docs/report.md`.", ""]
    return "\n".join(lines)


def write_report(
    data: ReplayData,
    folder: str | Path,
    *,
    plots: bool = True,
    wave_band: tuple[float, float] | None = None,
    settle_s: float | None = None,
) -> list[Path]:
    """Write metrics.json, report.md and (with matplotlib, if `plots`) the six PNGs into `folder`
    (created if needed). Returns the files written."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    an = _analyse(data, wave_band, settle_s)
    pngs: list[Path] = []
    if not plots:
        note = "Plots were not requested (`plots=False`)."
    else:
        Figure = _load_figure()
        if Figure is None:
            note = (
                "Plots were not drawn: matplotlib is not installed. Install it with `pip install dpgw[plot]`."
            )
        else:
            note = ""
            pngs = _plots(data, an, out, Figure)
    metrics_path = out / "metrics.json"
    metrics_path.write_text(json.dumps(_json_clean(an.metrics), indent=2, ensure_ascii=False) + "\n")
    report_path = out / "report.md"
    report_path.write_text(_report_md(data, an.metrics, note, pngs), encoding="utf-8")
    return [metrics_path, report_path, *pngs]
