"""Write the open-loop input sequences for the `mss_osv` vessel that the plant is checked against osv.m on.

    python tools/osv_inputs.py tests/data/mss-osv

Four 10-minute sequences, one input row per second (held between rows), columns as `dpgw sim --inputs`
reads them: t, current_speed, current_dir_deg, n_1 … n_4 (rpm; 1, 2 bow tunnels, 3, 4 stern azimuths),
alpha_3, alpha_4 (deg). Each exercises a different part of the model:

- steps: surge steps ahead on both azimuths, then a sway step on all four units (surge resistance,
  linear + cross-flow drag in sway, the sway–yaw coupling of M and C);
- turn: the azimuths angled to port with the tunnels pushing the bow to starboard (yaw, the Munk moment,
  cross-flow drag along the hull);
- current: no thrust for two minutes, then low thrust, under a 0.6 m/s current that turns through 90°
  (relative velocity, the current's body-frame rotation);
- azimuth_sweep: both azimuths swept through ±90° at different rates and speeds (the thrust law and
  configuration, large sideslip).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

DURATION_S = 600.0
COLUMNS = ("t", "current_speed", "current_dir_deg", "n_1", "n_2", "n_3", "n_4", "alpha_3", "alpha_4")


def _steps(t: np.ndarray) -> dict[str, np.ndarray]:
    n_az = np.where(t >= 10, 90.0, 0.0) + np.where(t >= 200, 40.0, 0.0) - np.where(t >= 400, 130.0, 0.0)
    tunnel = np.where((t >= 400) & (t < 520), 110.0, 0.0)
    side = np.where((t >= 400) & (t < 520), 90.0, 0.0)
    return {
        "n_1": tunnel,
        "n_2": tunnel,
        "n_3": n_az + np.where(side > 0, 100.0, 0.0),
        "n_4": n_az + np.where(side > 0, 130.0, 0.0),
        "alpha_3": side,
        "alpha_4": side,
    }


def _turn(t: np.ndarray) -> dict[str, np.ndarray]:
    on = (t >= 5).astype(float)
    return {
        "n_1": 120.0 * on,
        "n_2": 120.0 * on,
        "n_3": 110.0 * on,
        "n_4": 150.0 * on,
        "alpha_3": -35.0 * on,
        "alpha_4": -35.0 * on,
    }


def _current(t: np.ndarray) -> dict[str, np.ndarray]:
    late = (t >= 120).astype(float)
    return {
        "current_speed": np.full_like(t, 0.6),
        "current_dir_deg": 30.0 + 90.0 * np.clip(t / 500.0, 0, 1),
        "n_1": 40.0 * late,
        "n_2": 40.0 * late,
        "n_3": 60.0 * late,
        "n_4": 60.0 * late,
        "alpha_3": np.zeros_like(t),
        "alpha_4": np.zeros_like(t),
    }


def _azimuth_sweep(t: np.ndarray) -> dict[str, np.ndarray]:
    return {
        "current_speed": np.full_like(t, 0.2),
        "current_dir_deg": np.full_like(t, 200.0),
        "n_1": np.zeros_like(t),
        "n_2": np.zeros_like(t),
        "n_3": np.full_like(t, 100.0),
        "n_4": 120.0 * np.minimum(t / 60.0, 1.0),
        "alpha_3": 90.0 * np.sin(2 * math.pi * t / 300.0),
        "alpha_4": 90.0 * np.sin(2 * math.pi * t / 220.0),
    }


SEQUENCES = {"steps": _steps, "turn": _turn, "current": _current, "azimuth_sweep": _azimuth_sweep}


def write(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(0.0, DURATION_S + 0.5, 1.0)
    paths = []
    for name, make in SEQUENCES.items():
        cols = {c: np.zeros_like(t) for c in COLUMNS}
        cols["t"] = t
        cols.update(make(t))
        path = folder / f"{name}_inputs.csv"
        with path.open("w") as f:
            f.write(",".join(COLUMNS) + "\n")
            for row in zip(*(cols[c] for c in COLUMNS), strict=True):
                f.write(",".join(f"{v:.6g}" for v in row) + "\n")
        paths.append(path)
    return paths


if __name__ == "__main__":
    for p in write(Path(sys.argv[1] if len(sys.argv) > 1 else "tests/data/mss-osv")):
        print(p)
