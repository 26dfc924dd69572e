"""DP engaged on a cold observer against DP that waited for it (docs/gateway.md, "Waiting for the observer").

In the in-process closed loop (`dpgw.closed_loop`) on torsetnes_2004 (mss_supply, Hs 6 m), three starts:
DP from the first estimate on a vessel nobody held (a HIL bench without a joystick), DP from the first
estimate on a vessel held on joystick, and a gateway with ``initial_mode = "dp"`` waiting for its observer
(the default) while the vessel is held. Per seed: when DP engaged, the p95 and the largest of the true LF
position's distance and heading difference from the DP reference over the ``--window`` seconds after, and
the share of saturated commands in the first minute.

    python bench/bench_settling.py --seeds 4
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from dpgw.closed_loop import gateway_tables, run_closed_loop
from simulator.clock import SimEpoch
from simulator.scenarios import get_scenario

STARTS = (("cold, not held", False, False), ("cold, held", False, True), ("waited, held", True, True))


def after_engagement(wait: bool, held: bool, seed: int, window_s: float) -> tuple[float, ...]:
    """(engaged s, position p95, max (m), heading p95, max (deg), saturated % of the first minute)."""
    scenario = get_scenario("torsetnes_2004")
    epoch = SimEpoch(scenario.start_utc).stamp_ns(0.0)
    lead = 150.0 if wait else 0.0
    run = run_closed_loop(
        scenario,
        lead + window_s + 5.0,
        seed=seed,
        tables=gateway_tables(scenario, wait_for_observer=wait),
        hold_on_joystick=held,
    )
    cmds = run.command_messages
    tc = np.array([(c.stamp_ns - epoch) / 1e9 for c in cmds])
    ref = np.array([c.reference for c in cmds])
    k = (run.t >= tc[0]) & (run.t <= tc[0] + window_s)
    e = run.eta_lf[k] - np.column_stack([np.interp(run.t[k], tc, ref[:, i]) for i in range(3)])
    pos = np.hypot(e[:, 0], e[:, 1])
    hdg = np.degrees(np.abs((e[:, 2] + math.pi) % (2 * math.pi) - math.pi))
    saturated = np.mean([c.saturated for c in cmds if (c.stamp_ns - cmds[0].stamp_ns) / 1e9 <= 60.0])
    return (
        float(tc[0]),
        float(np.percentile(pos, 95)),
        float(pos.max()),
        float(np.percentile(hdg, 95)),
        float(hdg.max()),
        100.0 * float(saturated),
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=1, help="seeds 0..N-1 (default 1)")
    p.add_argument("--window", type=float, default=180.0, help="seconds scored after engagement (180)")
    args = p.parse_args()
    for label, wait, held in STARTS:
        rows = np.array([after_engagement(wait, held, s, args.window) for s in range(args.seeds)])
        for s, r in enumerate(rows):
            print(
                f"{label:15s} seed {s}: engaged {r[0]:5.1f} s; position p95 {r[1]:.2f} m (max {r[2]:.2f}), "
                f"heading p95 {r[3]:.2f} deg (max {r[4]:.2f}); saturated in the first minute {r[5]:.1f} %"
            )
        print(
            f"{label:15s} mean: position p95 {rows[:, 1].mean():.2f} m, heading p95 {rows[:, 3].mean():.2f} "
            f"deg, saturated {rows[:, 5].mean():.1f} %"
        )


if __name__ == "__main__":
    main()
