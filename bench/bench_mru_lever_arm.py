"""The MRU's roll/pitch lever-arm compensation measured on `torsetnes_2004_mast` (a 25 m mast antenna):
the same closed-loop run with the gateway's config with and without the MRU source, side by side.

Figures printed (per seed, then the mean):

* the fused position measurement (each fix as the gateway compensated it) minus the truth's reference point
  (LF + WF) at the fix's measurement time: its RMS, and its power in the wave band (periods 4-25 s) with
  and without the MRU (the ratio in dB: the wave-frequency antenna motion the MRU takes out);
* the observer's LF position error (RMS of the horizontal distance between the estimate's η_LF and the true
  LF position, after the first 300 s).

With ``--pairing LATENCY_S …``: how much of the antenna's wave-frequency motion stays in the fixes when the
MRU's attitude is paired with each fix by receive time and by the sentences' own UTC times (a PASHR MRU, a
noise-free DGPS with that latency), in % of the heading-only motion (`pairing`).

Run: ``python bench/bench_mru_lever_arm.py [--duration 900] [--seeds 1 2 3] [--json] [--pairing 0.1 0.15]``
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from simulator.clock import SimEpoch
from simulator.faults import Fault
from simulator.scenarios import get_scenario

SCENARIO = "torsetnes_2004_mast"
WAVE_BAND_S = (4.0, 25.0)  # periods (s) counted as wave frequency
SETTLE_S = 300.0


def fix_errors(run: Any, scenario: Any, new_fixes_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(t_measured, [ΔN, ΔE]) of every position fix accepted: the fused measurement minus the true
    reference point (LF + WF) at the time the receiver measured it (received − its latency).
    ``new_fixes_only``: only the measurements whose position changed, i.e. published for a new fix (a
    measurement published for a heading holds the last fix, which that time − latency does not date:
    what it adds is the motion since the fix, not a lever-arm error)."""
    epoch = SimEpoch(scenario.start_utc)
    latency = scenario.dgps[0].latency_s
    ts, errs = [], []
    last = None
    last_ne = None
    for m in run.collected_messages["/dp/measurement"]:
        if not m.valid[0] or m.eta[0] is None or m.stamp_ns == last:
            continue
        last = m.stamp_ns
        if new_fixes_only:
            if (m.eta[0], m.eta[1]) == last_ne:
                continue
            last_ne = (m.eta[0], m.eta[1])
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


def lf_rms(run: Any, scenario: Any, worst: bool = False) -> float:
    """RMS horizontal distance (m) of the estimate's η_LF from the true LF position at its time (``worst``:
    the largest distance instead)."""
    start_ns = SimEpoch(scenario.start_utc).start_ns
    t = np.array([(m.stamp_ns - start_ns) / 1e9 for m in run.estimate_messages])
    est = np.array([m.eta[:2] for m in run.estimate_messages], dtype=float)
    keep = (t >= SETTLE_S) & (t <= run.t[-1])
    truth = np.column_stack([np.interp(t[keep], run.t, run.eta_lf[:, k]) for k in (0, 1)])
    d2 = np.sum((est[keep] - truth) ** 2, axis=1)
    return float(math.sqrt(np.max(d2) if worst else np.mean(d2)))


def position_error(run: Any, sp: tuple[float, float] = (0.0, 0.0)) -> tuple[float, float]:
    """(RMS, largest) horizontal distance (m) of the true LF position from the setpoint after
    `SETTLE_S`: how well the vessel kept station."""
    keep = run.t >= SETTLE_S
    d = np.hypot(run.eta_lf[keep, 0] - sp[0], run.eta_lf[keep, 1] - sp[1])
    return float(np.sqrt(np.mean(d**2))), float(np.max(d))


def one(
    seed: int,
    duration: float,
    mru: bool,
    *,
    sentence: str | None = None,
    attitude_time: str = "sensor",
    gnss_sigma_m: float | None = None,
    gnss_latency_s: float | None = None,
    faults: tuple[Fault, ...] = (),
    new_fixes_only: bool = False,
    integrity: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """One closed-loop run's figures. ``sentence``: the MRU's sentence instead of the scenario's (PASHR
    carries its UTC time, PHTRO none); ``attitude_time``: the gateway's ``[integrity] attitude_time``
    (pairing by sensor or receive time); ``gnss_sigma_m``: the DGPS's noise instead of the scenario's (0
    shows the lever-arm residual alone); ``gnss_latency_s``: the DGPS's latency instead of the scenario's
    (0.1 s); ``faults``: added to the scenario's; ``integrity``: keys of the gateway's ``[integrity]``.
    Also returns the MRU source's rejects by test (``mru_rejected``) from the last status, and how far
    the vessel was from its setpoint (``station_rms_m``, ``station_max_m``)."""
    scenario = get_scenario(SCENARIO)
    if sentence is not None:
        scenario = replace(scenario, mru=tuple(replace(m, sentence=sentence) for m in scenario.mru))
    if gnss_sigma_m is not None:
        scenario = replace(scenario, dgps=tuple(replace(d, sigma_m=gnss_sigma_m) for d in scenario.dgps))
    if gnss_latency_s is not None:
        scenario = replace(scenario, dgps=tuple(replace(d, latency_s=gnss_latency_s) for d in scenario.dgps))
    if faults:
        scenario = replace(scenario, faults=(*scenario.faults, *faults))
    tables = gateway_tables(scenario)
    tables["integrity"] = {**tables.get("integrity", {}), **(integrity or {}), "attitude_time": attitude_time}
    if not mru:
        tables["sources"] = [s for s in tables["sources"] if "attitude" not in s["roles"]]
    run = run_closed_loop(
        scenario, duration, seed=seed, tables=tables, collect=("/dp/measurement",), status_every_s=10.0
    )
    t, e = fix_errors(run, scenario, new_fixes_only)
    last = run.statuses[-1] if run.statuses else None
    mru_name = scenario.mru[0].source if scenario.mru else ""
    sources = last["sources"] if last else {}
    rejected = dict(sources[mru_name]["rejected"]) if mru and mru_name in sources else {}
    return {
        "fix_rms_m": float(math.sqrt(np.mean(np.sum(e**2, axis=1)))),
        "wave_band_power_m2": band_power(t, e),
        "lf_rms_m": lf_rms(run, scenario),
        "lf_max_m": lf_rms(run, scenario, worst=True),
        "station_rms_m": position_error(run)[0],
        "station_max_m": position_error(run)[1],
        "mru_rejected": rejected,
    }


def pairing(seed: int, duration: float, gnss_latency_s: float | None = None) -> dict[str, float]:
    """How much of the antenna's wave-frequency motion stays in the fixes (noise-free DGPS, PASHR MRU):
    the wave-band power of the fix error with the attitude paired by receive time and by sensor time, as a
    fraction (amplitude, %) of the heading-only error, and the sensor-time pairing's gain in dB."""
    kw: dict[str, Any] = {
        "sentence": "PASHR",
        "gnss_sigma_m": 0.0,
        "gnss_latency_s": gnss_latency_s,
        "new_fixes_only": True,
    }
    off = one(seed, duration, False, **kw)["wave_band_power_m2"]
    rx = one(seed, duration, True, attitude_time="receive", **kw)
    utc = one(seed, duration, True, attitude_time="sensor", **kw)
    p_rx, p_utc = rx["wave_band_power_m2"], utc["wave_band_power_m2"]
    return {
        "residual_receive_pct": 100.0 * math.sqrt(p_rx / off),
        "residual_sensor_pct": 100.0 * math.sqrt(p_utc / off),
        "sensor_vs_receive_db": 10.0 * math.log10(p_rx / p_utc),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=900.0, help="sim seconds per run (default 900)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3], help="seeds (default 1 2 3)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument(
        "--pairing",
        type=float,
        nargs="+",
        metavar="LATENCY_S",
        help="instead: pairing by sensor vs receive time (PASHR, noise-free DGPS) at these DGPS latencies",
    )
    args = ap.parse_args(argv)
    if args.pairing:
        prows = [
            {"seed": seed, "gnss_latency_s": lat, **pairing(seed, args.duration, lat)}
            for lat in args.pairing
            for seed in args.seeds
        ]
        if args.json:
            json.dump(prows, sys.stdout, indent=1)
            print()
            return 0
        print(f"{SCENARIO} with a PASHR MRU and a noise-free DGPS, {args.duration:g} s per run")
        print("DGPS latency s  seed  wave motion left in the fixes: receive time %  sensor time %  dB")
        for r in prows:
            print(f"{r['gnss_latency_s']:14.3f}  {r['seed']:4d}  {r['residual_receive_pct']:44.2f}"
                  f"  {r['residual_sensor_pct']:13.2f}  {r['sensor_vs_receive_db']:4.1f}")  # fmt: skip
        return 0
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
