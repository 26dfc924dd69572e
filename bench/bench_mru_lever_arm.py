"""The MRU's roll/pitch lever-arm compensation measured on `torsetnes_2004_mast` (a 25 m mast antenna):
the same closed-loop run with the gateway's config with and without the MRU source, side by side.

Figures printed (per seed, then the mean):

* the fused position measurement (each fix as the gateway compensated it) minus the truth's reference point
  (LF + WF) at the fix's measurement time: its RMS, and its power in the wave band (periods 4-25 s) with
  and without the MRU (the ratio in dB: the wave-frequency antenna motion the MRU takes out);
* the observer's LF position error (RMS of the horizontal distance between the estimate's η_LF and the true
  LF position, after the first 300 s).

Run: ``python bench/bench_mru_lever_arm.py [--duration 900] [--seeds 1 2 3] [--json]``
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from simulator.clock import SimEpoch
from simulator.scenarios import get_scenario

SCENARIO = "torsetnes_2004_mast"
WAVE_BAND_S = (4.0, 25.0)  # periods (s) counted as wave frequency
SETTLE_S = 300.0


def fix_errors(run: Any, scenario: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t_measured, [ΔN, ΔE]) of every position fix accepted: the fused measurement minus the true
    reference point (LF + WF) at the time the receiver measured it (received − its latency)."""
    epoch = SimEpoch(scenario.start_utc)
    latency = scenario.dgps[0].latency_s
    ts, errs = [], []
    last = None
    for m in run.collected_messages["/dp/measurement"]:
        if not m.valid[0] or m.eta[0] is None or m.stamp_ns == last:
            continue
        last = m.stamp_ns
        t = (m.stamp_ns - epoch.start_ns) / 1e9 - latency
        if t < SETTLE_S or t > run.t[-1]:
            continue
        truth = [np.interp(t, run.t, run.eta_lf[:, k] + run.eta_wf[:, k]) for k in (0, 1)]
        ts.append(t)
        errs.append([m.eta[0] - truth[0], m.eta[1] - truth[1]])
    return np.array(ts), np.array(errs)


def band_power(t: np.ndarray, e: np.ndarray) -> float:
    """Power (m²) of the error in the wave band, N and E summed: the periodogram of the error, resampled
    on its own mean fix interval, between the band's frequencies."""
    dt = float(np.median(np.diff(t)))
    grid = np.arange(t[0], t[-1], dt)
    total = 0.0
    for k in (0, 1):
        x = np.interp(grid, t, e[:, k])
        x = x - x.mean()
        spec = np.abs(np.fft.rfft(x)) ** 2 / len(x) ** 2 * 2.0
        f = np.fft.rfftfreq(len(x), dt)
        band = (f >= 1.0 / WAVE_BAND_S[1]) & (f <= 1.0 / WAVE_BAND_S[0])
        total += float(spec[band].sum())
    return total


def lf_rms(run: Any, scenario: Any) -> float:
    """RMS horizontal distance (m) of the estimate's η_LF from the true LF position at its time."""
    start_ns = SimEpoch(scenario.start_utc).start_ns
    t = np.array([(m.stamp_ns - start_ns) / 1e9 for m in run.estimate_messages])
    est = np.array([m.eta[:2] for m in run.estimate_messages], dtype=float)
    keep = (t >= SETTLE_S) & (t <= run.t[-1])
    truth = np.column_stack([np.interp(t[keep], run.t, run.eta_lf[:, k]) for k in (0, 1)])
    return float(math.sqrt(np.mean(np.sum((est[keep] - truth) ** 2, axis=1))))


def one(seed: int, duration: float, mru: bool) -> dict[str, float]:
    scenario = get_scenario(SCENARIO)
    tables = gateway_tables(scenario)
    if not mru:
        tables["sources"] = [s for s in tables["sources"] if "attitude" not in s["roles"]]
    run = run_closed_loop(scenario, duration, seed=seed, tables=tables, collect=("/dp/measurement",))
    t, e = fix_errors(run, scenario)
    return {
        "fix_rms_m": float(math.sqrt(np.mean(np.sum(e**2, axis=1)))),
        "wave_band_power_m2": band_power(t, e),
        "lf_rms_m": lf_rms(run, scenario),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=900.0, help="sim seconds per run (default 900)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3], help="seeds (default 1 2 3)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = ap.parse_args(argv)
    rows = []
    for seed in args.seeds:
        on, off = one(seed, args.duration, True), one(seed, args.duration, False)
        rows.append({"seed": seed, "mru": on, "heading_only": off,
                     "wave_band_reduction_db": 10 * math.log10(off["wave_band_power_m2"]
                                                               / on["wave_band_power_m2"])})  # fmt: skip
    if args.json:
        json.dump(rows, sys.stdout, indent=1)
        print()
        return 0
    print(f"{SCENARIO}, {args.duration:g} s per run, figures after {SETTLE_S:g} s")
    print("seed  fix RMS m (MRU / heading only)  wave-band dB less  LF RMS m (MRU / heading only)")
    for r in rows:
        on, off = r["mru"], r["heading_only"]
        fix = f"{on['fix_rms_m']:8.3f} / {off['fix_rms_m']:8.3f}"
        lf = f"{on['lf_rms_m']:7.3f} / {off['lf_rms_m']:7.3f}"
        print(f"{r['seed']:4d}  {fix}        {r['wave_band_reduction_db']:8.1f}          {lf}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
