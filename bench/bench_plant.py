"""Benchmark: the cost of the full plant against the model plant, per 0.05 s plant step, side by side.

The plant alone (no sensors, no logging): `VesselDynamics` (M ν' + D ν = τ + Jᵀ b) against `FullPlant`
with its environment (current stepped once a second, wind force every 0.25 s), each stepped 0.05 s at a
time as the simulator's loop does, interleaved and best of several rounds (the machine is noisy).

    python bench/bench_plant.py [--seconds 600] [--rounds 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from observers.vessel import load_vessel
from simulator.current import CurrentModel
from simulator.plant import FullPlant
from simulator.plant_env import PlantEnvironment
from simulator.vessel_dynamics import VesselDynamics
from simulator.wind import WindModel


def model_run(seconds: float) -> float:
    dyn = VesselDynamics(load_vessel("mss_osv"))
    tau, b = np.array([1e5, 2e4, 1e6]), np.zeros(3)
    t0 = time.perf_counter()
    for _ in range(round(seconds / 0.05)):
        dyn.step(0.05, tau, b)
    return time.perf_counter() - t0


def full_run(seconds: float) -> float:
    vessel = load_vessel("mss_osv")
    plant = FullPlant(vessel)
    env = PlantEnvironment(
        vessel, CurrentModel(0.5, -140.0, 0.05, 5.0), WindModel(12.0, 210.0), np.random.SeedSequence(1)
    )
    tau, b = np.array([1e5, 2e4, 1e6]), np.zeros(3)
    t = 0.0
    t0 = time.perf_counter()
    for _ in range(round(seconds / 0.05)):
        env.step(0.05, t, plant.x)
        plant.step(0.05, tau + env.wind_body, b, env.current_ned)
        t += 0.05
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    model_run(1.0), full_run(1.0)  # compile / load the numba caches
    model, full = [], []
    for _ in range(args.rounds):
        model.append(model_run(args.seconds))
        full.append(full_run(args.seconds))
    steps = round(args.seconds / 0.05)
    m, f = min(model) / steps * 1e6, min(full) / steps * 1e6
    print(f"plant step (0.05 s), best of {args.rounds} x {steps} steps, interleaved:")
    print(f"  model plant  {m:6.2f} us/step  ({args.seconds / min(model):8.0f}x real time, plant alone)")
    print(f"  full plant   {f:6.2f} us/step  ({args.seconds / min(full):8.0f}x real time, plant alone)")
    print(f"  full / model {f / m:6.2f}")


if __name__ == "__main__":
    main()
