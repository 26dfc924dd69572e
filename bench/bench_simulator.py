"""Benchmark: the simulator's speed, in times real time, beside its targets, side by side in one run.

1. **Wire + MCAP** (target >= 360x): one hour of sim time with 10 Hz sensors, every byte encoded and
   logged to MCAP (zstd, chunks closed by size and wall time) with the ground truth at 10 Hz, as
   `dpgw sim --out` does.
   - fossen_strand_1999: DGPS 10 Hz (GGA, RMC, VTG at 10 Hz; GST, ZDA at 1 Hz), gyro 10 Hz (HDT, ROT);
     no thruster layout (τ acts directly).
   - torsetnes_2004: the same sensors plus six thrusters with their dynamics, reporting
     AZIMUTH_THRUSTER_STATUS at 5 Hz each and a heartbeat over MAVLink.
   - mss_supply_storm: the same sensors and thruster feedback on the full plant (Coriolis, nonlinear and
     cross-flow drag, fluid memory, a varying current and a gusting wind): what the full plant costs.
2. **In-process closed loop** (target >= 3,000x), as the studies run it (`dpgw.closed_loop`):
   torsetnes_2004 with the same 10 Hz sensors and six thrusters, the gateway pipeline (reference checks,
   fusion, passive observer, DP controller at 10 Hz, QP allocation) commanding the thrusters, holding
   station. Once with the typed records (no wire encoding, the default) and once with the bytes.

Each figure is sim time / wall time. The machine is shared: beside it, sim time / CPU time of this process
(`time.process_time`), which moves much less when other work competes for the cores; `--rounds N` takes
the best of N interleaved rounds. The closed loop's CPU time is split by phase (the simulator, the
pipeline's observer step, its control step — and inside it the allocation and the DP controller — the rest
of the pipeline) so it is clear where the time goes. The split inside the pipeline times methods by
patching them, which a compiled pipeline (mypyc) does not see: it calls them directly. There the pipeline
is one figure; ``DPGW_PURE_PYTHON=1`` splits the interpreted pipeline instead (slower, but in proportion).

    python bench/bench_simulator.py [--hours 1] [--loop-hours H] [--rounds 1] [--json]
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import tempfile
import time
from collections.abc import Callable
from typing import Any

from dpgw.cli import single_threaded_blas

single_threaded_blas()  # as `dpgw sim` runs (before numpy loads): CPU time is the loop's, not BLAS's spinning

import gateway.pipeline  # noqa: E402
from dpgw.closed_loop import run_closed_loop  # noqa: E402
from gateway.control.allocation import QPAllocator  # noqa: E402
from gateway.control.controller import DPController  # noqa: E402
from gateway.pipeline import Pipeline  # noqa: E402
from simulator.runner import Simulation  # noqa: E402
from simulator.scenarios import get_scenario  # noqa: E402
from wire.compiled import is_compiled  # noqa: E402
from wire.mcap.writer import McapLogWriter  # noqa: E402

TARGET_WIRE = 360.0
WIRE_CASES = ("fossen_strand_1999", "torsetnes_2004")
FULL_PLANT_CASE = "mss_supply_storm"  # listed last, so earlier figures keep their place for ab_compare.py
TARGET_LOOP = 3000.0
HOLD = [(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0})]


def run_case(name: str, hours: float, folder: str) -> dict[str, Any]:
    scenario = get_scenario(name).with_sensor_rates(10.0, 10.0)
    path = os.path.join(folder, f"{name}.mcap")
    t0, c0 = time.perf_counter(), time.process_time()
    with McapLogWriter(path, flush_on_log_time=False) as log:  # as `dpgw sim --out` (virtual clock)
        sim = Simulation(scenario, seed=1, log=log)
        sim.run(hours * 3600.0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "case": f"wire+mcap {name}" + (" (full plant)" if scenario.plant == "full" else ""),
        "sim_seconds": sim.t,
        "wall_seconds": wall,
        "speedup": sim.t / wall,
        "speedup_cpu": sim.t / cpu,
        "target": TARGET_WIRE,
        "frames": sum(sim.summary.emissions.values()),
        "mcap_bytes": os.path.getsize(path),
        "thrusters": sim.thrusters.n,
    }


class _PhaseTimer:
    """CPU time of this thread spent inside some methods, patched for one run and restored. CPU time, not
    wall time: on a shared machine the split should show the code's cost, not the waits for a core."""

    def __init__(self, targets: dict[str, tuple[type, str]]) -> None:
        self.targets = targets
        self.seconds = dict.fromkeys(targets, 0.0)
        self._saved: list[tuple[type, str, Callable[..., Any]]] = []

    def __enter__(self) -> _PhaseTimer:
        for label, (cls, name) in self.targets.items():
            original = getattr(cls, name)
            self._saved.append((cls, name, original))
            setattr(cls, name, self._timed(label, original))
        return self

    def _timed(self, label: str, f: Callable[..., Any]) -> Callable[..., Any]:
        seconds = self.seconds

        def timed(*a: Any, **k: Any) -> Any:
            t0 = time.thread_time()
            try:
                return f(*a, **k)
            finally:
                seconds[label] += time.thread_time() - t0

        return timed

    def __exit__(self, *exc: object) -> None:
        for cls, name, original in self._saved:
            setattr(cls, name, original)


def run_loop(hours: float, wire: bool, phases: bool) -> dict[str, Any]:
    scenario = get_scenario("torsetnes_2004").with_sensor_rates(10.0, 10.0)
    duration = hours * 3600.0
    # the compiled pipeline calls its own steps (and the controller's and allocator's) directly: patched
    # timers would read 0 there, so only its whole `feed` is timed
    inside = not is_compiled(gateway.pipeline)
    targets: dict[str, tuple[type, str]] = {"simulator": (Simulation, "run"), "pipeline": (Pipeline, "feed")}
    if inside:
        targets |= {
            "observer_step": (Pipeline, "_step"),
            "control_step": (Pipeline, "_control_step"),
            "allocation": (QPAllocator, "allocate"),
            "controller": (DPController, "update"),
        }
    timer = _PhaseTimer(targets if phases else {})
    # An older checkout (bench/ab_compare.py --base) has only the bytes path: its default is then that.
    typed = "wire" in inspect.signature(run_closed_loop).parameters
    kwargs = {"wire": wire} if typed else {}
    with timer:
        t0, c0 = time.perf_counter(), time.process_time()
        r = run_closed_loop(scenario, duration, seed=1, events=HOLD, **kwargs)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out: dict[str, Any] = {
        "case": f"closed loop torsetnes_2004, {'bytes' if wire or not typed else 'typed records'}",
        "sim_seconds": duration,
        "wall_seconds": wall,
        "speedup": duration / wall,
        "speedup_cpu": duration / cpu,
        "target": TARGET_LOOP,
        "estimates": len(r.estimates),
        "commands": len(r.commands),
    }
    if phases:
        s = timer.seconds
        # the control step runs inside the observer step, which runs inside feed: split them apart
        split = (
            {
                "simulator": s["simulator"],
                "pipeline_observer_step": s["observer_step"] - s["control_step"],
                "pipeline_control_step": s["control_step"],
                # of which (inside the control step): the allocation and the DP controller
                "control_allocation": s["allocation"],
                "control_controller": s["controller"],
                "pipeline_other": s["pipeline"] - s["observer_step"],
            }
            if inside
            else {"simulator": s["simulator"], "pipeline_compiled_whole": s["pipeline"]}
        )
        split["loop_other"] = cpu - sum(v for k, v in split.items() if not k.startswith("control_"))
        out["us_per_sim_second"] = {k: 1e6 * v / duration for k, v in split.items()}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=1.0, help="sim time of the wire+MCAP cases (1)")
    ap.add_argument(
        "--loop-hours", type=float, help="sim time of the closed-loop cases (default: --hours / 4)"
    )
    ap.add_argument("--rounds", type=int, default=1, help="interleaved rounds; the best of each is kept (1)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    loop_hours = args.loop_hours if args.loop_hours is not None else args.hours / 4
    # warm-up: compile the numba kernels (cached on disk) and import everything outside the timed runs
    Simulation(get_scenario("torsetnes_2004"), 0).run(2.0)
    run_closed_loop(get_scenario("torsetnes_2004"), 2.0, seed=0, events=HOLD)
    best: dict[str, dict[str, Any]] = {}
    for k in range(args.rounds):
        with tempfile.TemporaryDirectory() as folder:
            rows = [run_case(n, args.hours, folder) for n in WIRE_CASES]
        # the phase timers cost a little: the typed loop is timed once without them, once with
        rows.append(run_loop(loop_hours, wire=False, phases=False))
        rows.append(run_loop(loop_hours, wire=True, phases=False))
        if k == 0:
            phased = run_loop(loop_hours, wire=False, phases=True)
        with tempfile.TemporaryDirectory() as folder:
            rows.append(run_case(FULL_PLANT_CASE, args.hours, folder))
        for i, row in enumerate(rows):
            if str(i) not in best or row["speedup"] > best[str(i)]["speedup"]:
                best[str(i)] = row
    results = [*best.values()]
    results[len(WIRE_CASES)]["us_per_sim_second"] = phased["us_per_sim_second"]  # the studies' default path
    if args.json:
        print(
            json.dumps({"cases": results}, indent=2)
        )  # an object: bench/ab_compare.py reads from the first "{"
        return
    print(
        f"simulator speed, times real time (sim time / wall time; / CPU time beside it), "
        f"best of {args.rounds}"
    )
    print(f"  {'case':46s} {'wall':>8s} {'speedup':>8s} {'(CPU)':>8s} {'target':>7s}")
    for r in results:
        met = "met" if r["speedup"] >= r["target"] else "NOT met"
        print(
            f"  {r['case']:46s} {r['wall_seconds']:7.1f}s {r['speedup']:7.0f}x {r['speedup_cpu']:7.0f}x "
            f"{r['target']:6.0f}x {met}"
        )
    print(f"  wire+mcap: {args.hours:g} h of sim time each; closed loop: {loop_hours:g} h")
    typed = results[len(WIRE_CASES)]
    print(f"  {typed['case']}, CPU time per second of sim time:")
    for k, v in typed["us_per_sim_second"].items():
        print(f"    {k:26s} {v:8.0f} us")
    print(f"    {'budget at the target':26s} {1e6 / TARGET_LOOP:8.0f} us")


if __name__ == "__main__":
    main()
