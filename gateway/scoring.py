"""Estimates against ground truth: the numbers `dpgw demo` prints and replay reports.

Pure numerics: arrays in, numbers out. Truth (the simulator's `/truth/state`, 10 Hz) is interpolated
linearly to each estimate's time (heading through its unwrapped angle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from observers.kinematics import ssa

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Score:
    samples: int
    rms: tuple[float, float, float]  # N (m), E (m), ψ (rad)
    horizontal_rms_m: float
    horizontal_p95_m: float
    heading_p95_rad: float
    mean_square: tuple[float, float, float]  # (1/n) Σ (η̂ − η)², Snijders et al. (2005)'s table

    def as_dict(self) -> dict[str, object]:
        return {
            "samples": self.samples,
            "rms_north_m": self.rms[0],
            "rms_east_m": self.rms[1],
            "rms_heading_deg": float(np.degrees(self.rms[2])),
            "horizontal_rms_m": self.horizontal_rms_m,
            "horizontal_p95_m": self.horizontal_p95_m,
            "heading_p95_deg": float(np.degrees(self.heading_p95_rad)),
            "mean_square": list(self.mean_square),
        }


def not_scored_note(scored_s: float, settle_s: float, min_scored_s: float) -> str:
    """Why an estimate was not scored against the truth, in the words `dpgw demo` and `dpgw replay` (its
    console and report.md) share: ``scored_s`` of sea after the ``settle_s`` skip, fewer than the
    ``min_scored_s`` a figure needs (`dpgw.scored_stretch.MIN_SCORED_S` says why: a few seconds' RMS is one
    sample of errors that vary over tens of seconds)."""
    if scored_s > 0.0:
        return (
            f"not scored (only {scored_s:.{1 if scored_s < 10 else 0}f} s after the {settle_s:g} s skip; "
            f"at least {min_scored_s:g} s are scored)"
        )
    return (
        f"not scored: the first {settle_s:g} s are left out while the observer settles, and at least "
        f"{min_scored_s:g} s after them are scored"
    )


def truth_at(t_est: Array, t_truth: Array, eta_truth: Array) -> Array:
    """Truth η at the estimate times (linear; heading unwrapped first). NaN outside the truth's span."""
    out = np.empty((len(t_est), 3))
    for k in range(2):
        out[:, k] = np.interp(t_est, t_truth, eta_truth[:, k], left=np.nan, right=np.nan)
    out[:, 2] = ssa(np.interp(t_est, t_truth, np.unwrap(eta_truth[:, 2]), left=np.nan, right=np.nan))
    return out


def score(t_est: Array, eta_est: Array, t_truth: Array, eta_truth: Array, settle_s: float = 0.0) -> Score:
    """Errors of estimates (times in s, any common origin) against the truth after ``settle_s``."""
    t_est = np.asarray(t_est, dtype=float)
    ref = truth_at(t_est, np.asarray(t_truth, dtype=float), np.asarray(eta_truth, dtype=float))
    err = np.asarray(eta_est, dtype=float) - ref
    err[:, 2] = ssa(err[:, 2])
    keep = (t_est >= t_est[0] + settle_s) & np.all(np.isfinite(err), axis=1) if len(t_est) else t_est > 0
    e = err[keep]
    if len(e) == 0:
        nan3 = (float("nan"),) * 3
        return Score(0, nan3, float("nan"), float("nan"), float("nan"), nan3)
    horiz = np.hypot(e[:, 0], e[:, 1])
    ms = np.mean(e**2, axis=0)
    return Score(
        samples=len(e),
        rms=tuple(float(v) for v in np.sqrt(ms)),  # type: ignore[arg-type]
        horizontal_rms_m=float(np.sqrt(np.mean(horiz**2))),
        horizontal_p95_m=float(np.percentile(horiz, 95)),
        heading_p95_rad=float(np.percentile(np.abs(e[:, 2]), 95)),
        mean_square=tuple(float(v) for v in ms),  # type: ignore[arg-type]
    )
