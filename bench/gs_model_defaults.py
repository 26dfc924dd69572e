"""The gain-scheduled observer's defaults on a 1:70 model (CyberShip II) in basin seas, side by side.

Columns: the defaults as they were (the ship's ``DEFAULT_TUNING``, ``h_max`` 0.1 s, ``ramp_time_constant_s``
15 s: only the ω0 range and start Froude-scaled), the vessel's tuning (`PassiveTuning.for_vessel`) with the
old step and ramp, and today's defaults (the vessel's tuning, step and ramp ÷ √70). Data: the shared basin
sea of the model-scale tests (tests/basin_sea.py: the model's LF motion under a weak station-keeping law,
its WF motion through its RAOs, 1 cm / 0.1° noise, 10 Hz), 300 s; errors are RMS from 150 s on against the
true LF motion. Prints figures; asserts nothing.

    python bench/gs_model_defaults.py [--seeds 4]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from basin_sea import MODEL, RATE, basin

from observers.gain_scheduled import DEFAULT_TUNING, GainScheduledObserver
from observers.kinematics import ssa
from simulator.spectra import SeaState

SETTLE_S = 150.0
SEAS = {
    "3.8 rad/s (Tp 1.65 s)": SeaState(
        hs_m=0.06, tp_s=2 * math.pi / 3.8, gamma=3.3, direction_rad=math.radians(150)
    ),
    "7.5 rad/s (Tp 0.84 s)": SeaState(
        hs_m=0.05, tp_s=7.0 / math.sqrt(70), gamma=3.3, direction_rad=math.radians(150)
    ),
}
OLD_STEP = {"h_max": 0.1, "ramp_time_constant_s": 15.0}
VARIANTS = {
    "before (ship tuning, h 0.1, ramp 15)": {"tuning": DEFAULT_TUNING, **OLD_STEP},
    "for_vessel tuning, h 0.1, ramp 15": OLD_STEP,
    "after (for_vessel, h, ramp / sqrt 70)": {},
}


def errors(sea: SeaState, seed: int, kw: dict) -> tuple[float, float, float]:
    t, y, lf, _ = basin(sea, 300.0, seed)
    obs = GainScheduledObserver(MODEL, **kw)
    r = obs.run(t, y)
    k = int(SETTLE_S * RATE)
    e = r.eta[k:] - lf[k:]
    e[:, 2] = ssa(e[:, 2])
    pos = float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2)))
    psi = float(np.degrees(np.sqrt(np.mean(e[:, 2] ** 2))))
    omega_err = float(np.median(np.abs(r.omega0[k:, 0] / sea.peak_frequency - 1.0)))
    return pos, psi, omega_err


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=4)
    args = ap.parse_args()
    for sea_name, sea in SEAS.items():
        print(f"\nbasin sea {sea_name}, Hs {sea.hs_m * 100:.0f} cm, seeds 0-{args.seeds - 1}")
        print(f"{'variant':40s} {'LF pos cm':>10s} {'LF psi deg':>11s} {'|w0/wp-1|':>10s}   per seed pos cm")
        for name, kw in VARIANTS.items():
            rows = [errors(sea, s, kw) for s in range(args.seeds)]
            pos, psi, om = (float(np.mean(c)) for c in zip(*rows, strict=True))
            per = " ".join(f"{r[0] * 100:.3f}" for r in rows)
            print(f"{name:40s} {pos * 100:10.3f} {psi:11.4f} {om:10.3f}   {per}")


if __name__ == "__main__":
    main()
