"""Where the mean-square LF error of the Snijders et al. (2005) tracking case comes from, per observer:
the error η̂ − η split by frequency (Welch PSD integrated over bands), so that a ranking of observers can
be explained by a measurement rather than a guess.

Bands, relative to the sea's peak frequency ωp (Tp 12 s: 0.52 rad/s):
  slow  < 0.2 ωp      tracking lag and bias error (the LF model's bandwidth decides it)
  mid   0.2–0.6 ωp    between the LF bandwidth and the waves
  wave  0.6–2 ωp      wave motion leaking into the LF estimate (the wave filter decides it)
  high  > 2 ωp        measurement noise passed through

    python bench/snijders_2005_bands.py [--seed 1] [--observers sdre passive] [--plant model|full|...]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import welch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from test_station_keeping import SNIJDERS_PLANTS, snijders_scenario, snijders_track

from dpgw.closed_loop import gateway_tables, run_closed_loop
from gateway.scoring import truth_at
from observers.kinematics import ssa

BANDS = (("slow", 0.0, 0.2), ("mid", 0.2, 0.6), ("wave", 0.6, 2.0), ("high", 2.0, math.inf))


def error_bands(
    observer: str, seed: int, params: dict[str, Any] | None = None, plant: str = "model"
) -> np.ndarray:
    """Rows surge, sway, yaw; columns: mean square, then its part in each of `BANDS` (PSD integral)."""
    sc = snijders_scenario(plant)
    tables = gateway_tables(sc)
    tables["observer"]["type"] = observer
    if params:
        tables["observer"]["params"] = params
    r = run_closed_loop(sc, 1800.0, seed=seed, events=snijders_track(), tables=tables)
    est = np.array([e["eta"] for e in r.estimates])
    t_est = (np.array([e["stamp_ns"] for e in r.estimates]) - r.estimates[0]["stamp_ns"]) / 1e9
    truth = truth_at(t_est, r.t - r.t[0], r.eta_lf)
    ok = np.all(np.isfinite(truth), axis=1) & np.all(np.isfinite(est), axis=1)
    err = est[ok] - truth[ok]
    err[:, 2] = ssa(err[:, 2])
    # on a uniform grid (the estimates come at the measurement rate, nearly uniform)
    fs = 2.0
    grid = np.arange(t_est[ok][0], t_est[ok][-1], 1.0 / fs)
    e = np.c_[[np.interp(grid, t_est[ok], err[:, k]) for k in range(3)]].T
    w_p = sc.sea[0][1].peak_frequency
    f, pxx = welch(e, fs=fs, nperseg=1024, axis=0, detrend=False, scaling="density")
    w = 2 * math.pi * f
    df = f[1] - f[0]
    rows = []
    for k in range(3):
        parts = [float(np.sum(pxx[(w >= lo * w_p) & (w < hi * w_p), k]) * df) for _, lo, hi in BANDS]
        rows.append([float(np.mean(e[:, k] ** 2)), *parts])
    return np.array(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--observers", nargs="+", default=["sdre", "passive"])
    ap.add_argument("--plant", choices=SNIJDERS_PLANTS, default="model", help="the plant (default model)")
    ap.add_argument(
        "--sdre-ratio", type=float, default=None, help="sdre's lf_bandwidth_ratio ω_b/ω0 (default its own)"
    )
    args = ap.parse_args()
    print(
        f"snijders_2005 on the {args.plant} plant, seed {args.seed}: mean-square error and its parts by band "
        "(ωp = 2π/12 s)"
    )
    print(f"  {'observer':8s} {'DOF':5s} {'mean sq':>10s}" + "".join(f" {b[0]:>10s}" for b in BANDS))
    for name in args.observers:
        params = {"lf_bandwidth_ratio": args.sdre_ratio} if name == "sdre" and args.sdre_ratio else None
        rows = error_bands(name, args.seed, params, plant=args.plant)
        for dof, row in zip(("surge", "sway", "yaw"), rows, strict=True):
            print(f"  {name:8s} {dof:5s} " + " ".join(f"{v:10.3e}" for v in row))
    print("  (bands in units of ωp: " + ", ".join(f"{n} {lo:g}–{hi:g}" for n, lo, hi in BANDS) + ")")


if __name__ == "__main__":
    main()
