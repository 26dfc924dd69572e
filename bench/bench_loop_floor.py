"""Benchmark: the floor under the studies' closed loop: what its numerics cost with no Python around them.

The in-process closed loop (`dpgw.closed_loop`, torsetnes_2004 with 10 Hz sensors and six thrusters, as
`bench/bench_simulator.py` runs it) has a target of 3,000x real time: 333 µs of CPU per second of sim
time for everything. This benchmark asks whether a loop compiled as a whole could meet it. It times the
loop's compiled kernels called **from compiled code** (a numba loop around each: no dispatch, no result
objects, no Python between them), on the state and arguments a real run of the loop gave them:

- the QP thrust allocation (`gateway.control._allocation_kernel.allocate_step`), once per control step;
- the passive observer's step (`observers._passive_kernel.step`), once per step;
- the DP controller's step (`gateway.control._controller_kernel.dp_step`), once per control step;
- the plant's advance over 0.1 s (`simulator._advance_kernel`: thruster dynamics, Markov bias, two RK4
  sub-steps), called from Python once per tick as the runner does;
- the wave-frequency motion and attitude of one 2 s block on the 0.05 s grid, per second of sim time:
  the compiled carrier recurrence the simulator uses (`simulator.waves.WaveField.motion_block`) and,
  beside it, its numpy reference (`motion_with_attitude`).

Their sum at 10 Hz is a **lower bound** for a compiled loop: it leaves out the sensors (noise, geodesy),
the reference checks, fusion, the records and the bookkeeping, which a compiled loop would also pay
for. Beside it, in the same run, the Python-orchestrated typed loop as the studies run it, and the ratio.

    python bench/bench_loop_floor.py [--seconds 300] [--calls 20000] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

from dpgw.cli import single_threaded_blas

single_threaded_blas()  # before numpy loads: CPU time is the loop's, not BLAS's spinning

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from dpgw.closed_loop import run_closed_loop  # noqa: E402
from gateway.control import _allocation_kernel as alloc_kernel  # noqa: E402
from gateway.control import _controller_kernel as ctl_kernel  # noqa: E402
from gateway.pipeline import Pipeline  # noqa: E402
from observers import _passive_kernel as obs_kernel  # noqa: E402
from simulator.runner import WF_BLOCK_S, Simulation  # noqa: E402
from simulator.scenarios import get_scenario  # noqa: E402
from simulator.vessel_dynamics import MAX_STEP_S  # noqa: E402

HOLD = [(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0})]
TARGET = 3000.0
RATE_HZ = 10.0  # sensors, observer and control, as bench_simulator.py's closed loop


@njit
def _allocations(n, tau, thrust, angle, args):  # type: ignore[no-untyped-def]
    """n allocation steps with τ wandering a little (the solver's active set changes as in the loop)."""
    ok = 0
    tau0 = tau.copy()
    for i in range(n):
        tau[0] = tau0[0] * (1.0 + 0.05 * math.sin(0.1 * i))
        tau[1] = tau0[1] * (1.0 + 0.05 * math.cos(0.13 * i))
        tau[2] = tau0[2] * (1.0 + 0.05 * math.sin(0.07 * i))
        ok += alloc_kernel.allocate_step(tau, thrust, angle, *args) == alloc_kernel.OK
    return ok


@njit
def _observer_steps(n, x, clock, t0, y, tau, G, Minv, D, h_max, max_hold):  # type: ignore[no-untyped-def]
    y0 = y.copy()
    for i in range(n):
        y[0] = y0[0] + 0.3 * math.sin(0.7 * i)
        y[1] = y0[1] + 0.3 * math.cos(0.5 * i)
        obs_kernel.step(x, clock, t0 + (i + 1) / 10.0, y, tau, G, Minv, D, h_max, max_hold)
    return x[0]


@njit
def _controller_steps(n, rs, rp, inp, dt, use_b, use_ta, saturated, feedforward, mats, dof):  # type: ignore[no-untyped-def]
    total = 0.0
    for _ in range(n):
        total += ctl_kernel.dp_step(rs, rp, inp, dt, use_b, use_ta, saturated, feedforward, mats, dof)[0]
    return total


def _per_call(fn: Any, *args: Any, calls: int) -> float:
    """µs per call of a compiled loop (compiled and warmed by a first call of one)."""
    fn(1, *args)
    t0 = time.process_time()
    fn(calls, *args)
    return 1e6 * (time.process_time() - t0) / calls


def _pipeline_after(seconds: float, scenario: Any) -> Pipeline:
    """The pipeline of a closed-loop run of ``seconds``, holding station: its objects' real state."""
    made: list[Pipeline] = []
    original = Pipeline.__init__

    def keep(self: Pipeline, *a: Any, **k: Any) -> None:
        original(self, *a, **k)
        made.append(self)

    Pipeline.__init__ = keep  # type: ignore[method-assign]
    try:
        run_closed_loop(scenario, seconds, seed=0, events=HOLD)
    finally:
        Pipeline.__init__ = original  # type: ignore[method-assign]
    return made[-1]


def measure(seconds: float, calls: int) -> dict[str, Any]:
    scenario = get_scenario("torsetnes_2004").with_sensor_rates(RATE_HZ, RATE_HZ)
    pipe = _pipeline_after(30.0, scenario)
    allocator, controller, observer = pipe.allocator, pipe.controller, pipe.observer
    assert allocator is not None and controller is not None
    args = allocator._kernel_args  # type: ignore[union-attr]
    # the allocation: from the last command the run gave, against the controller's last τ
    tau = np.asarray(controller._tau, dtype=float).copy()
    thrust = np.asarray(allocator._k_out[0], dtype=float).copy()  # type: ignore[union-attr]
    angle = np.asarray(allocator._k_out[1], dtype=float).copy()  # type: ignore[union-attr]
    us_alloc = _per_call(_allocations, tau, thrust, angle, args, calls=calls)
    t0 = time.process_time()
    for _ in range(calls // 4):
        alloc_kernel.allocate_step(tau, thrust, angle, *args)
    us_alloc_python = 1e6 * (time.process_time() - t0) / (calls // 4)

    x, clock = observer.x.copy(), observer._clock.copy()  # type: ignore[attr-defined]
    y = x[6:9].copy()  # η̂ as the measurement: the observer stays where the run left it
    us_obs = _per_call(
        _observer_steps, x, clock, float(clock[0]), y, np.zeros(3), observer._G, observer._Minv,  # type: ignore[attr-defined]
        observer._D, observer.h_max, observer.max_hold_s, calls=calls,  # type: ignore[attr-defined]
    )  # fmt: skip

    rs, rp = controller.reference.packed()
    inp = np.concatenate(
        (
            x[6:9],
            x[12:15],
            x[9:12],
            controller._tau,
            controller._tau,
            controller._z,
            controller.reference.target,
        )
    )
    us_ctl = _per_call(
        _controller_steps, rs.copy(), rp, inp, 1.0 / RATE_HZ, True, True, False,
        controller.tuning.feedforward, controller._mats, controller._dof, calls=calls,
    )  # fmt: skip

    sim = Simulation(scenario, 1)
    sim.run(5.0)
    ticks = max(100, calls // 10)
    t0 = time.process_time()
    for _ in range(ticks):
        sim._advance_fused(2, MAX_STEP_S)  # 0.1 s: two sub-steps of at most 0.05 s, as the runner splits it
    us_plant = 1e6 * (time.process_time() - t0) / ticks

    field = sim._wf.field
    blocks = max(20, calls // 100)
    n_grid = round(WF_BLOCK_S / MAX_STEP_S) + 1  # the runner's block grid (`simulator.runner._WaveCache`)
    grid = MAX_STEP_S * np.arange(n_grid)
    heading = math.radians(45.0)
    t0 = time.process_time()
    for k in range(blocks):
        field.motion_with_attitude(grid + WF_BLOCK_S * k, heading, 0.0, 0.0)
    us_waves_numpy = 1e6 * (time.process_time() - t0) / blocks / WF_BLOCK_S
    t0 = time.process_time()
    for k in range(blocks):
        field.motion_block(WF_BLOCK_S * k, MAX_STEP_S, n_grid, heading, 0.0, 0.0)
    us_waves = 1e6 * (time.process_time() - t0) / blocks / WF_BLOCK_S

    per_second = {
        "allocation": RATE_HZ * us_alloc,
        "observer": RATE_HZ * us_obs,
        "controller": RATE_HZ * us_ctl,
        "plant": RATE_HZ * us_plant,
        "waves": us_waves,
    }
    floor = sum(per_second.values())

    t0 = time.process_time()
    run_closed_loop(scenario, seconds, seed=1, events=HOLD)
    loop_us = 1e6 * (time.process_time() - t0) / seconds
    return {
        "per_call_us": {
            "allocation": us_alloc,
            "allocation_called_from_python": us_alloc_python,
            "observer": us_obs,
            "controller": us_ctl,
            "plant_per_tick": us_plant,
        },
        "waves_numpy_reference_us_per_sim_second": us_waves_numpy,
        "per_sim_second_us": per_second,
        "floor_us_per_sim_second": floor,
        "floor_speedup": 1e6 / floor,
        "python_loop_us_per_sim_second": loop_us,
        "python_loop_speedup": 1e6 / loop_us,
        "loop_over_floor": loop_us / floor,
        "budget_us_per_sim_second": 1e6 / TARGET,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=300.0, help="sim time of the Python loop's run (300)")
    ap.add_argument("--calls", type=int, default=20000, help="calls of each compiled kernel (20000)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    r = measure(args.seconds, args.calls)
    if args.json:
        print(json.dumps(r, indent=2))
        return
    c, s = r["per_call_us"], r["per_sim_second_us"]
    print("the closed loop's numerics called from compiled code (CPU time), torsetnes_2004 at 10 Hz")
    print(f"  {'part':34s} {'us/call':>8s} {'us per sim s':>13s}")
    print(f"  {'QP allocation':34s} {c['allocation']:8.2f} {s['allocation']:13.1f}")
    print(f"  {'  (the same, called from Python)':34s} {c['allocation_called_from_python']:8.2f}")
    print(f"  {'passive observer step':34s} {c['observer']:8.2f} {s['observer']:13.1f}")
    print(f"  {'DP controller step':34s} {c['controller']:8.2f} {s['controller']:13.1f}")
    print(f"  {'plant advance, 0.1 s (from Python)':34s} {c['plant_per_tick']:8.2f} {s['plant']:13.1f}")
    print(f"  {'wave motion (compiled, 2 s blocks)':34s} {'':8s} {s['waves']:13.1f}")
    print(f"  {'  (the numpy reference)':34s} {'':8s} {r['waves_numpy_reference_us_per_sim_second']:13.1f}")
    print(
        f"  {'floor (sum; no sensors, checks, records)':42s} {r['floor_us_per_sim_second']:5.0f}"
        f"  -> at most {r['floor_speedup']:,.0f}x"
    )
    print(
        f"  {'the Python-orchestrated typed loop':42s} {r['python_loop_us_per_sim_second']:5.0f}"
        f"  -> {r['python_loop_speedup']:,.0f}x  ({r['loop_over_floor']:.1f} times the floor)"
    )
    print(f"  budget at {TARGET:,.0f}x: {r['budget_us_per_sim_second']:.0f} us per sim second")


if __name__ == "__main__":
    main()
