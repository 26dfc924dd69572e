"""The study's figures of one observer on one case: estimates against the simulator's truth.

Pure numerics, arrays in and a flat dict of floats out (one row of the results table). The LF position
and heading errors are `gateway.scoring.score` and the wave-band attenuation is `gateway.report`'s
(`compute_metrics`), the same figures a replay report gives; what is added here needs the truth a log
does not carry (velocity, bias) or is a study's own (ω0 error, convergence time). docs/study.md defines
every column.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from gateway.scoring import score

Array = NDArray[np.float64]

# Convergence: the moving RMS of the horizontal LF position error over CONVERGENCE_WINDOW_S must stay below
# CONVERGENCE_FACTOR times its RMS over the last half of the case. The window is long against the wave
# periods (the error's wave-band leakage averages out) and short against the case; the factor 3 keeps the
# slow wander of a converged estimate (LF errors of DP are slow, bursty) from counting as a transient.
CONVERGENCE_WINDOW_S = 20.0
CONVERGENCE_FACTOR = 3.0


def _interp3(t_query: Array, t: Array, x: Array) -> Array:
    return np.column_stack(
        [np.interp(t_query, t, x[:, k], left=np.nan, right=np.nan) for k in range(x.shape[1])]
    )


def _rms(x: Array) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if len(x) else float("nan")


def convergence_time(t: Array, err: Array) -> float:
    """Time (s, from the first estimate) after which the moving RMS of ``err`` stays below
    CONVERGENCE_FACTOR × its RMS over the last half: 0 when it never rises above; an episode late in the
    case (an estimate thrown off after converging) shows as a late time. NaN with fewer than 3 samples.
    ``err`` ≥ 0, finite, at times ``t`` (increasing)."""
    if len(t) < 3:
        return float("nan")
    t_mid = t[0] + 0.5 * (t[-1] - t[0])
    final = _rms(err[t >= t_mid])
    if not math.isfinite(final):
        return float("nan")
    sq = np.concatenate([[0.0], np.cumsum(err * err)])
    lo = np.searchsorted(t, t - CONVERGENCE_WINDOW_S, side="left")
    idx = np.arange(len(t))
    mov = np.sqrt((sq[idx + 1] - sq[lo]) / (idx + 1 - lo))
    above = np.nonzero(mov > CONVERGENCE_FACTOR * final)[0]
    if len(above) == 0:
        return 0.0
    return float(t[above[-1]] - t[0])


def score_run(
    t: Array,
    eta: Array,
    nu: Array,
    bias: Array,
    omega0: Array,
    truth_t: Array,
    truth_eta: Array,
    truth_nu: Array,
    truth_bias: Array,
    settle_s: float,
    omega_p: float,
) -> dict[str, float]:
    """The columns of one observer's row, but the attenuation (needs every trace: `case`). ``t`` sim time
    (s) of the initialised estimates; scored from ``settle_s`` (sim time) on."""
    out: dict[str, float] = {}
    keep = t >= settle_s
    s = score(t[keep], eta[keep], truth_t, truth_eta) if np.any(keep) else None
    out["rms_north_m"] = s.rms[0] if s else math.nan
    out["rms_east_m"] = s.rms[1] if s else math.nan
    out["rms_horizontal_m"] = s.horizontal_rms_m if s else math.nan
    out["rms_heading_deg"] = math.degrees(s.rms[2]) if s else math.nan

    nu_err = nu[keep] - _interp3(t[keep], truth_t, truth_nu)
    out["rms_surge_mps"] = _rms(nu_err[:, 0])
    out["rms_sway_mps"] = _rms(nu_err[:, 1])
    out["rms_yaw_rate_degps"] = math.degrees(_rms(nu_err[:, 2]))

    b_err = bias[keep] - _interp3(t[keep], truth_t, truth_bias)
    out["bias_rms_x_n"] = _rms(b_err[:, 0])
    out["bias_rms_y_n"] = _rms(b_err[:, 1])
    out["bias_rms_n_nm"] = _rms(b_err[:, 2])

    w0 = omega0[keep]
    w0 = w0[np.all(np.isfinite(w0), axis=1)]
    if len(w0) and omega_p > 0:
        out["omega0_median_rad_s"] = float(np.median(np.mean(w0, axis=1)))
        out["omega0_error_pct"] = float(100.0 * np.median(np.mean(np.abs(w0 - omega_p), axis=1)) / omega_p)
    else:
        out["omega0_median_rad_s"] = out["omega0_error_pct"] = math.nan

    ref = np.column_stack(
        [np.interp(t, truth_t, truth_eta[:, k], left=np.nan, right=np.nan) for k in range(2)]
    )
    horiz = np.hypot(eta[:, 0] - ref[:, 0], eta[:, 1] - ref[:, 1])
    ok = np.isfinite(horiz)
    out["convergence_s"] = convergence_time(t[ok], horiz[ok])
    return out
