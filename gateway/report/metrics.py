"""The report's numbers: dominant wave frequency, attenuation at the wave peak, innovation statistics,
smoothness and errors against the truth, per observer and DOF.

Pure numerics: arrays in, a JSON-able dict out (`compute_metrics`). The attenuation compares the power
spectra of measurement and LF estimate at the measurement's wave peak, the notch of the wave filter seen
in the data (Fossen & Strand 1999, Figs. 9-14; Torsetnes et al. 2004, Fig. 3).
`docs/report.md` gives every formula and choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gateway.report.data import DOF, Array, Prepared, ReplayData, prepare, utc_text
from gateway.report.findings import amplification_warnings
from gateway.report.spectra import Psd, band_power, nominal_dt, peak, resample, valid_samples, welch
from gateway.scoring import Score, not_scored_note, score
from observers.froude import MODEL_MAX_LENGTH_M, PROTOTYPE_LENGTH_M, froude_scale_of, scaled_frequencies
from observers.kinematics import ssa

# The wave band searched for the spectral peak at full scale (rad/s: periods 3.1 s to 31 s). A model's
# band is Froude-scaled by its scale λ (`observers.froude`, the rule the observers' default ω0 ranges use):
# its model_scale, or for a vessel shorter than MODEL_MAX_LENGTH_M a PROTOTYPE_LENGTH_M prototype (wave
# frequencies scale with 1/sqrt(length)).
FULL_SCALE_WAVE_BAND = (0.2, 2.0)
# Default settle time: the first SETTLE_FRACTION of the replay, at most SETTLE_MAX_S seconds.
SETTLE_FRACTION = 0.1
SETTLE_MAX_S = 60.0
# Welch segments span WELCH_PERIODS periods of the band's lowest frequency (bin spacing ω_lo/8).
WELCH_PERIODS = 8
# Up to this many sample intervals between two valid samples are bridged by linear interpolation.
MAX_GAP_SAMPLES = 4.0


def default_settle_s(duration_s: float) -> float:
    """The start left out of the metrics when no settle time is given: SETTLE_FRACTION of the span, at most
    SETTLE_MAX_S, to 0.1 s (a 299.9 s span, its last sample one interval short of 300 s, settles after
    30.0 s, not a spurious-looking 29.99 s)."""
    return round(min(SETTLE_MAX_S, SETTLE_FRACTION * duration_s), 1)


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


def wave_band_for_length(length_m: float | None, model_scale: float | None = None) -> tuple[float, float]:
    """The wave band (rad/s) searched for the spectral peak: 0.2-2.0 rad/s at full scale; for a 1:λ model
    × √λ (`observers.froude.froude_scale_of`: λ = ``model_scale``, or for a vessel shorter than 10 m the
    ratio to an 80 m prototype)."""
    lo, hi = scaled_frequencies(FULL_SCALE_WAVE_BAND, froude_scale_of(length_m, model_scale))
    return lo, hi


@lru_cache(maxsize=32)
def vessel_scale(vessel: str) -> tuple[float | None, float | None]:
    """Length and model scale of a built-in vessel (or a vessel TOML path); None if it cannot be loaded
    (`vessel_scale_why` says why). Reads package data only."""
    length, model_scale, _ = vessel_scale_why(vessel)
    return length, model_scale


def vessel_scale_why(vessel: str) -> tuple[float | None, float | None, str | None]:
    """`vessel_scale`, and why the vessel could not be loaded (the vessel file's own error: not a built-in
    nor a file, a misspelt key, a matrix that is not positive definite), else None. Only the vessel's
    errors are taken: anything else is a fault of the code and is raised, not turned into full scale."""
    if not vessel:
        return None, None, None
    from observers.vessel import VesselError, load_vessel

    try:
        v = load_vessel(vessel)
    except (VesselError, OSError) as exc:
        return None, None, str(exc)
    return float(v.length_m), v.model_scale, None


def _neighbours(t: Array, dt: float) -> NDArray[np.bool_]:
    """Consecutive valid samples that are true neighbours (no missing sample between them)."""
    return np.diff(t) <= 1.5 * dt


def _f(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass
class Analysis:
    """The metrics and what the plots draw beside them (spectra, peaks, attenuation)."""

    prep: Prepared
    metrics: dict[str, Any]
    band: tuple[float, float]
    settle_t: float
    meas_peak: list[float]  # dominant frequency per DOF (rad/s)
    meas_psd: list[Psd | None]  # measurement PSD per DOF (plot: no high-pass)
    est_psd: dict[int, list[Psd | None]]  # per trace index, per DOF: LF estimate PSD (plot)
    attenuation: dict[int, list[float]]


def analyse(data: ReplayData, wave_band: tuple[float, float] | None, settle_s: float | None) -> Analysis:
    prep = prepare(data)
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
        settle_s = default_settle_s(duration)
    settle_t = t0 + settle_s

    if wave_band is None:
        length, model_scale, why = (
            vessel_scale_why(data.vessel)
            if data.vessel_length_m is None
            else (data.vessel_length_m, data.vessel_model_scale, None)
        )
        band = wave_band_for_length(length, model_scale)
        if length is None:
            basis = f"full scale (length unknown: {why or 'no vessel named'})"
        elif model_scale is not None:
            basis = f"Froude-scaled: 1:{model_scale:g} model (L = {length:g} m)"
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
        "span_utc": None
        if data.start_ns is None
        else [utc_text(data.start_ns, t0), utc_text(data.start_ns, t1)],
        "duration_s": _f(duration),
        "settle_s": _f(settle_s),
        "wave_band_rad_s": [band[0], band[1]],
        "wave_band_basis": basis,
        "truth": bool(has_truth),
        "min_scored_s": data.min_scored_s,
    }

    # ---- measurement: dominant wave frequency per DOF (whole record)
    meas_info = []  # per DOF: (valid mask, dt, max_gap, band clipped to Nyquist)
    meas_peak: list[float] = []
    meas_psd: list[Psd | None] = []
    mdict: dict[str, Any] = {"samples": len(t_meas)}
    for k in range(3):
        valid = valid_samples(t_meas, y[:, k])
        tv = t_meas[valid]
        dt = nominal_dt(tv)
        max_gap = MAX_GAP_SAMPLES * dt
        band_k = (band[0], min(band[1], 0.8 * math.pi / dt)) if math.isfinite(dt) else band
        xv = y[valid, k]
        if k == 2:
            xv = np.unwrap(xv)
        pieces = [p[:, 0] for p in resample(tv, xv[:, None], dt, max_gap)] if math.isfinite(dt) else []
        psd_hp = welch(pieces, dt, seg_s, hp) if pieces else None
        psd_raw = welch(pieces, dt, seg_s, None) if pieces else None
        w_peak, at_edge = peak(psd_hp, band_k) if psd_hp is not None else (float("nan"), False)
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
    est_psd: dict[int, list[Psd | None]] = {}
    attenuation: dict[int, list[float]] = {}
    for i, trace in enumerate(traces):
        label, t, eta, eta_wf, omega0 = trace.label, trace.t, trace.eta, trace.eta_wf, trace.omega0
        key = label if label not in observers else f"{label}#{i + 1}"
        odict: dict[str, Any] = {"samples": len(t), "span_s": [_f(t[0]), _f(t[-1])] if len(t) else None}
        if trace.observer:
            odict["observer"] = trace.observer
        est_psd[i] = []
        attenuation[i] = []
        s_lf: Score | None = None
        s_wf: Score | None = None
        if prep.truth is not None and len(t):
            tt, t_lf, t_wf = prep.truth
            settle_rel = max(0.0, settle_t - float(t[0]))
            # the sea scored after the skip, from the first estimate on (as `dpgw demo` counts it): fewer
            # than `ReplayData.min_scored_s` seconds are said "not scored", never given a figure
            scored_s = max(0.0, float(t[-1] - t[0]) - settle_rel)
            odict["truth_scored_s"] = _f(scored_s)
            if data.min_scored_s is not None and scored_s < data.min_scored_s:
                odict["truth_not_scored"] = not_scored_note(scored_s, settle_s, data.min_scored_s)
            else:
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
            p_est_raw: Psd | None = None
            segs = 0
            if len(tq) > 1 and math.isfinite(dt):
                pair = np.column_stack([np.unwrap(yq), np.unwrap(lfq)] if ang else [yq, lfq])
                pieces = resample(tq, pair, dt, max_gap)
                pm = welch([p[:, 0] for p in pieces], dt, seg_s, hp)
                pe = welch([p[:, 1] for p in pieces], dt, seg_s, hp)
                p_est_raw = welch([p[:, 1] for p in pieces], dt, seg_s, None)
                if pm is not None and pe is not None and math.isfinite(meas_peak[k]):
                    segs = pm.segments
                    den = band_power(pm, meas_peak[k])
                    num = band_power(pe, meas_peak[k])
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
    # what the replay's console says besides (the wave check's lines; `dpgw replay` passes them), then what
    # the report finds itself: an observer lifting the motion it should filter
    metrics["checks"] = list(data.checks)
    metrics["warnings"] = amplification_warnings(metrics)
    metrics["log_spans"] = dict(data.log_spans)
    if data.dp_performance is not None:
        metrics["dp_performance"] = dict(data.dp_performance)
    return Analysis(prep, metrics, band, settle_t, meas_peak, meas_psd, est_psd, attenuation)


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
    return analyse(data, wave_band, settle_s).metrics
