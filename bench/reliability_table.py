"""The reliability table: each fault a DP system must survive, injected into the in-process closed loop
(simulator bytes → gateway pipeline → thruster commands → simulator), and what the gateway made of it.

mss_supply holds (0, 0) at 45° in the torsetnes_2004 sea (JONSWAP Hs 6 m), DGPS and gyro at 10 Hz, the
gateway's DP controller and allocation commanding the six thrusters. Every case settles for ``--settle``
seconds, then its faults start (simulator/faults.py; hostile commands as command inputs), and the run goes
on for the fault's window plus ``--after`` seconds. Per case, over [fault start, end of run]:

* **detected**: seconds from the fault's start to the first /dp/status alarm that names the faulted source
  (or, for commands, the command), or the first change of that source's ``state`` when the status carries
  one, that was not there just before the fault; "not detected" when none came;
* **est. error**: the largest horizontal distance and heading difference between the gateway's estimate
  (/dp/estimate, LF) and the simulator's true LF motion;
* **off station**: the largest true distance of the vessel from its setpoint;
* **max thrust**: the largest thrust any thruster was commanded, and in % of that thruster's capacity;
  **saturated**: seconds of commands the allocation flagged as saturated;
* **rejected**: inputs of the faulted source the gateway rejected in the window (all reasons).

The baseline row is the same run without a fault, scored over the window of the single-sample cases.

    python bench/reliability_table.py [--json] [--out docs/reliability.md] [--seed 1]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dpgw.closed_loop import ClosedLoopRun, gateway_tables, run_closed_loop
from observers.kinematics import ssa
from simulator.clock import SimEpoch
from simulator.faults import Fault
from simulator.scenarios import Scenario, get_scenario

STATION = {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0}
COMMAND_WORDS = ("setpoint", "command", "refused", "mode")
"""What an alarm about a command says. Not "τ": the controller's saturation alarm quotes the τ it demands,
a consequence of a command, not its detection."""


Spec = tuple[str, str, float, dict[str, Any]]
"""One fault of a case: kind, source, duration (s), parameters."""


@dataclass(frozen=True)
class Case:
    name: str
    faults: tuple[Spec, ...]
    dgps: int = 1  # how many DGPS the vessel has (the first is the primary)
    watch: tuple[str, ...] = ()  # what an alarm must name to count as detecting this fault
    window_s: float = 0.0  # how long the fault lasts (for the run length)
    offsets: tuple[float, ...] = field(default=())  # start of each fault after the settle (default 0)


def cases() -> list[Case]:
    def on(
        source: str, kind: str, duration_s: float, **params: Any
    ) -> tuple[str, str, float, dict[str, Any]]:
        return kind, source, duration_s, params

    def gps(name: str, *faults: Spec, dgps: int = 1) -> Case:
        return Case(name, faults, dgps=dgps, watch=("dgps1",))

    def feedback(name: str, thrust_n: float) -> Case:  # one frame: the feedback comes at 5 Hz
        return Case(name, (on("1", "bogus_feedback", 0.1, thrust_n=thrust_n),), watch=("thruster",))

    def command(
        name: str, *faults: tuple[str, str, float, dict[str, Any]], offsets: tuple[float, ...] = ()
    ) -> Case:
        return Case(name, faults, watch=COMMAND_WORDS, offsets=offsets)

    drift = on("dgps1", "drift", 300.0, north_mps=1.0 / 60.0)
    return [
        Case("baseline (no fault)", ()),
        gps("position jump 50 m for 1 s", on("dgps1", "jump", 1.0, north_m=50.0)),
        Case("heading flip 180° for 1 s", (on("gyro1", "jump", 1.0, heading_rad=math.pi),), watch=("gyro1",)),
        gps("frozen position 30 s", on("dgps1", "frozen", 30.0)),
        gps("primary of 3 DGPS drifts 1 m/min, 5 min", drift, dgps=3),
        gps("primary of 2 DGPS drifts 1 m/min, 5 min", drift, dgps=2),
        gps("GGA quality 6 (dead reckoning) 10 s", on("dgps1", "quality", 10.0, quality=6)),
        gps("GGA quality 7 (manual input) 10 s", on("dgps1", "quality", 10.0, quality=7)),
        gps("GGA quality 8 (simulator) 10 s", on("dgps1", "quality", 10.0, quality=8)),
        gps("one GGA at 91° E", on("dgps1", "spoof", 0.05, lon_deg=91.0)),  # one fix at 10 Hz
        gps("DGPS dropout 10 s (the only DGPS)", on("dgps1", "dropout", 10.0)),
        gps("DGPS dropout 20 s (the only DGPS)", on("dgps1", "dropout", 20.0)),
        gps("DGPS dropout 60 s (the only DGPS)", on("dgps1", "dropout", 60.0)),
        gps("primary of 3 DGPS silent 10 s", on("dgps1", "dropout", 10.0), dgps=3),
        feedback("one status frame: 4e7 N", 4e7),
        feedback("one status frame: 1e30 N", 1e30),
        command(
            "setpoint 50 km away", on("intruder", "command_setpoint", 1.0, north_m=50_000.0, heading_deg=45.0)
        ),
        command(
            "manual mode, τ = 1e12 N for 10 s",
            on("intruder", "command_mode", 1.0, mode="manual"),
            on("intruder", "command_tau", 10.0, surge_n=1e12, rate_hz=1.0),
            offsets=(0.0, 0.1),
        ),
        command("mode switched to standby", on("intruder", "command_mode", 1.0, mode="standby")),
    ]


def scenario(n_dgps: int) -> Scenario:
    """torsetnes_2004 with DGPS and gyro at 10 Hz and ``n_dgps`` receivers (dgps1, dgps2, ...)."""
    sc = get_scenario("torsetnes_2004").with_sensor_rates(10.0, 10.0)
    base = sc.dgps[0]
    return replace(sc, dgps=tuple(replace(base, source=f"dgps{k + 1}") for k in range(n_dgps)))


def run_case(case: Case, settle_s: float, after_s: float, seed: int) -> dict[str, Any]:
    sc = scenario(case.dgps)
    t_fault = settle_s
    faults = []
    window = 0.0
    for k, (kind, source, duration, params) in enumerate(case.faults):
        start = t_fault + (case.offsets[k] if case.offsets else 0.0)
        faults.append(Fault(kind, source, start, start + duration, params))
        window = max(window, start + duration - t_fault)
    sc = replace(sc, faults=tuple(faults))
    duration = t_fault + max(window, 1.0) + after_s
    wall = time.perf_counter()
    r = run_closed_loop(
        sc,
        duration,
        seed=seed,
        tables=gateway_tables(sc),
        events=[(0.0, "setpoint", STATION)],
        status_every_s=0.1,
    )
    row = score(r, sc, t_fault, case)
    row["wall_s"] = round(time.perf_counter() - wall, 1)
    return row


def score(r: ClosedLoopRun, sc: Scenario, t_fault: float, case: Case) -> dict[str, Any]:
    t0_ns = SimEpoch(sc.start_utc).stamp_ns(0.0)

    def sim_t(stamp_ns: int) -> float:
        return (stamp_ns - t0_ns) / 1e9

    # estimate error against the truth, over the window
    te = np.array([sim_t(e["stamp_ns"]) for e in r.estimates])
    est = np.array([e["eta"] for e in r.estimates], dtype=float)
    keep = te >= t_fault
    te, est = te[keep], est[keep]
    truth = np.column_stack([np.interp(te, r.t, r.eta_lf[:, i]) for i in range(2)])
    psi = np.interp(te, r.t, np.unwrap(r.eta_lf[:, 2]))
    pos_err = np.hypot(*(est[:, :2] - truth).T)
    hdg_err = np.degrees(np.abs(ssa(est[:, 2] - psi)))
    after = r.t >= t_fault
    off = np.hypot(r.eta_lf[after, 0], r.eta_lf[after, 1])
    # commands over the window
    capacity = {th.id: th.max_thrust_n for th in sc.vessel.thrusters}
    biggest, biggest_pct, saturated = 0.0, 0.0, 0
    commands = [c for c in r.commands if sim_t(c["stamp_ns"]) >= t_fault]
    for c in commands:
        saturated += bool(c["saturated"])
        for th in c["thrusters"]:
            thrust = abs(float(th["thrust_n"]))
            if thrust > biggest:
                biggest, biggest_pct = thrust, 100.0 * thrust / capacity[th["id"]]
    period = 1.0 / sc.control_rate_hz
    detected, alarm, rejected = detection(r.statuses, sim_t, t_fault, case.watch)
    return {
        "case": case.name,
        "faults": [{"kind": k, "source": s, "duration_s": d, **p} for k, s, d, p in case.faults],
        "detected_s": detected,
        "alarm": alarm,
        "rejected": rejected,
        "max_position_error_m": float(pos_err.max()) if len(pos_err) else math.nan,
        "max_heading_error_deg": float(hdg_err.max()) if len(hdg_err) else math.nan,
        "max_off_station_m": float(off.max()),
        "max_thrust_n": biggest,
        "max_thrust_pct": biggest_pct,
        "saturated_s": saturated * period,
        "window_s": float(r.t[-1] - t_fault),
    }


def detection(
    statuses: list[dict[str, Any]], sim_t: Any, t_fault: float, watch: tuple[str, ...]
) -> tuple[float | None, str, int]:
    """(seconds to the first new alarm or source-state change naming a watched word, its text, rejects of
    the watched sources in the window)."""
    before = [s for s in statuses if sim_t(s["stamp_ns"]) < t_fault]
    during = [s for s in statuses if sim_t(s["stamp_ns"]) >= t_fault]
    if not before or not during or not watch:
        return None, "", 0
    old_alarms = set(before[-1]["alarms"])
    old_states = {name: src.get("state") for name, src in before[-1]["sources"].items()}

    def named(text: str) -> bool:
        return any(w in text for w in watch)

    def rejects(status: dict[str, Any]) -> int:
        return sum(
            sum(src.get("rejected", {}).values()) for name, src in status["sources"].items() if named(name)
        )

    def refused(status: dict[str, Any]) -> int:  # commands the gateway refused (Status.commands)
        return sum((status.get("commands") or {}).get("refused", {}).values())

    old_refused = refused(before[-1])
    found: tuple[float | None, str] = (None, "")
    for s in during:
        new = [a for a in s["alarms"] if a not in old_alarms and named(a)]
        if watch == COMMAND_WORDS and refused(s) > old_refused:
            new.append(f"command refused: {(s.get('commands') or {}).get('last_refused', '')}")
        changed = [
            f"{name}: {src.get('state')}" + (f" ({src['reason']})" if src.get("reason") else "")
            for name, src in s["sources"].items()
            if named(name) and src.get("state") != old_states.get(name)
        ]
        if new or changed:
            found = (sim_t(s["stamp_ns"]) - t_fault, (changed + new)[0])
            break
    return found[0], found[1], rejects(during[-1]) - rejects(before[-1])


def markdown(rows: list[dict[str, Any]], header: str) -> str:
    out = [
        header,
        "",
        "| fault | detected | est. error max | off station max | max thrust commanded | saturated "
        "| rejected |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        detected = "—" if row["case"].startswith("baseline") else "not detected"
        if row["detected_s"] is not None:
            detected = f"{row['detected_s']:.1f} s: {row['alarm'][:70]}"
        out.append(
            f"| {row['case']} | {detected} | {metres(row['max_position_error_m'])}, "
            f"{row['max_heading_error_deg']:.1f}° | {metres(row['max_off_station_m'])} | "
            f"{row['max_thrust_n'] / 1e3:.0f} kN ({row['max_thrust_pct']:.0f} %) | "
            f"{row['saturated_s']:.1f} s | {row['rejected']} |"
        )
    return "\n".join(out)


def metres(x: float) -> str:
    """0.49 m, 15.8 m, 308 km, 1.2e+23 m: readable across the range a fault can cause."""
    if x < 10.0:
        return f"{x:.2f} m"
    if x < 1e4:
        return f"{x:.1f} m"
    if x < 1e7:
        return f"{x / 1e3:.0f} km"
    return f"{x:.1e} m"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    ap.add_argument("--out", type=Path, help="also write the table as Markdown to this file")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--settle", type=float, default=120.0, help="seconds on station before the fault")
    ap.add_argument("--after", type=float, default=60.0, help="seconds scored after the fault's window")
    ap.add_argument("--only", nargs="+", metavar="WORD", help="only the cases whose name holds a word")
    args = ap.parse_args()
    selected = [c for c in cases() if not args.only or any(w in c.name for w in args.only)]
    wall = time.perf_counter()
    rows = []
    for case in selected:
        rows.append(run_case(case, args.settle, args.after, args.seed))
        print(f"  {case.name}: {rows[-1]['wall_s']} s", file=sys.stderr)
    total = time.perf_counter() - wall
    command = " ".join(["python bench/reliability_table.py", *(a for a in sys.argv[1:] if a != "--json")])
    if args.json:
        print(
            json.dumps(
                {"seed": args.seed, "settle_s": args.settle, "after_s": args.after, "rows": rows}, indent=1
            )
        )
    header = (
        f"mss_supply on station (torsetnes_2004 sea, Hs 6 m; DGPS and gyro 10 Hz), seed {args.seed}; "
        f"each fault after {args.settle:.0f} s on station, scored from its start to {args.after:.0f} s "
        "after its end. "
        f"{len(rows)} runs in {total:.0f} s. `{command}`"
    )
    table = markdown(rows, header)
    if not args.json:
        print(table)
    if args.out:
        write_doc(args.out, table)


def write_doc(path: Path, table: str) -> None:
    """Replace the table between the markers of ``path`` (the rest of the page is prose kept by hand)."""
    begin, end = "<!-- reliability-table -->", "<!-- /reliability-table -->"
    text = path.read_text() if path.exists() else f"# Reliability\n\n{begin}\n{end}\n"
    if begin not in text or end not in text:
        text += f"\n{begin}\n{end}\n"
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    path.write_text(f"{head}{begin}\n{table}\n{end}{tail}")


if __name__ == "__main__":
    main()
