"""What the gateway's dead-reckoning control does through a total sensor silence, in the closed loop.

Every sensor of a scenario drops out for ``--silence`` seconds at ``--at`` (a `dropout` fault on every
source); the simulated drives either hold their last command or stop 2 s after it (``--drives``). Side by
side, per seed: the gateway ticking its pipeline as the live service does (dead-reckoned estimates and the
control step on them: `gateway.pipeline.Pipeline.tick`), the same loop never ticked (no command at all
through the silence, as the gateway did before), and the run without the fault. Position and heading
RMS off the scenario's initial station over the silence and the ``--after`` seconds that follow.

    python bench/dead_reckoning_control.py [--scenario mss_supply_storm] [--seeds 0-1] [--drives stop]
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from dpgw.closed_loop import ClosedLoopRun, run_closed_loop
from simulator.faults import Fault
from simulator.scenarios import get_scenario


def rms_off_station(
    run: ClosedLoopRun, eta0: tuple[float, float, float], t0: float, t1: float
) -> tuple[float, float]:
    """RMS of the true LF position's distance and heading's difference (deg) from ``eta0`` over [t0, t1)."""
    t, eta = run.t, run.eta_lf
    m = (t >= t0) & (t < t1)
    pos = np.hypot(eta[m, 0] - eta0[0], eta[m, 1] - eta0[1])
    psi = np.degrees(np.abs(np.angle(np.exp(1j * (eta[m, 2] - eta0[2])))))
    return float(np.sqrt(np.mean(pos**2))), float(np.sqrt(np.mean(psi**2)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--scenario",
        action="append",
        help="scenario (repeatable; default mss_supply_storm and torsetnes_2004)",
    )
    p.add_argument("--seeds", default="0-1", help="seeds, A-B (default 0-1)")
    p.add_argument("--drives", choices=("hold", "stop"), default="stop", help="the drives on command loss")
    p.add_argument("--at", type=float, default=200.0, help="when the silence starts (s)")
    p.add_argument("--silence", type=float, default=20.0, help="how long every sensor is silent (s)")
    p.add_argument("--after", type=float, default=30.0, help="seconds after the silence scored (s)")
    args = p.parse_args()
    a, _, b = args.seeds.partition("-")
    seeds = range(int(a), int(b or a) + 1)
    end = args.at + args.silence + args.after
    print(
        f"every sensor silent {args.silence:g} s at {args.at:g} s, drives that {args.drives} on command "
        f"loss; RMS off station over {args.at:g}-{end:g} s (position m / heading deg)"
    )
    print(f"  {'scenario':<20} {'seed':>4}  {'DR control':>16}  {'no control step':>16}  {'no fault':>16}")
    for name in args.scenario or ["mss_supply_storm", "torsetnes_2004"]:
        base = get_scenario(name)
        if base.feedback is not None:
            base = replace(base, feedback=replace(base.feedback, on_command_loss=args.drives))
        silent = replace(base, faults=(*base.faults, Fault("dropout", "*", args.at, args.at + args.silence)))
        for seed in seeds:
            cells = []
            for scenario, tick in ((silent, True), (silent, False), (base, True)):
                run = run_closed_loop(scenario, end, seed=seed, tick=tick)
                pos, psi = rms_off_station(run, base.eta0, args.at, end)
                cells.append(f"{pos:6.2f} / {psi:5.2f}" if math.isfinite(pos) else "-")
            print(f"  {name:<20} {seed:>4}  {cells[0]:>16}  {cells[1]:>16}  {cells[2]:>16}", flush=True)


if __name__ == "__main__":
    main()
