"""``dpgw sim --vessel NAME --inputs INPUTS.csv``: the full plant open loop from recorded inputs.

What an engineer runs to check a vessel model against a sea trial or another simulator: the recorded
shaft speeds, azimuth angles and current in, the low-frequency states out (STATES.csv) and the truth to
MCAP. No waves and no wind unless asked (``--wind``, ``--sea``: their slowly varying forces only; the
states are low-frequency). ``--plant-option`` switches the plant's effects (docs/simulator.md).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
from dataclasses import fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dpgw.cli_paths import made_folder_problem, make_folder_for, mcap_path_problem
from dpgw.cli_progress import terminal_bar
from dpgw.cli_stops import signals_noted, stop_name

if TYPE_CHECKING:
    from simulator.plant_params import PlantOptions

PLANT_OPTION_KEYS = ("coriolis", "surge_resistance", "crossflow", "added_mass_coriolis")


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("open loop from recorded inputs (instead of --scenario)")
    g.add_argument("--vessel", metavar="NAME|FILE.toml", help="the vessel (built-in name or a vessel file)")
    g.add_argument(
        "--inputs",
        metavar="INPUTS.csv",
        help="recorded inputs: t, current_speed, current_dir_deg (towards, from north), n_<k> (rpm) per "
        "thruster and alpha_<k> (deg) per azimuth, k in the vessel's thruster order; held between rows",
    )
    g.add_argument(
        "--csv", metavar="STATES.csv", help="write t, north, east, psi_deg, u, v, r_degps per input row"
    )
    g.add_argument(
        "--plant-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="coriolis|surge_resistance|crossflow=on|off, added_mass_coriolis=relative|absolute (repeatable)",
    )
    g.add_argument(
        "--initial",
        metavar="N,E,PSI_DEG[,U,V,R_DEGPS]",
        help="the state at the first row (default: at rest at the origin, heading 0)",
    )
    g.add_argument(
        "--wind",
        metavar="SPEED,FROM_DEG[,SPECTRUM]",
        help="add wind: 1-hour mean at 10 m (m/s), the direction it blows from, gusts norsok|harris|none",
    )
    g.add_argument(
        "--sea",
        metavar="HS,TP,TOWARDS_DEG",
        help="add the mean wave drift of a JONSWAP sea (m, s, the direction the waves travel towards)",
    )


def wind_spectrum(option: str, name: str) -> str:
    """The gust spectrum of ``--wind SPEED,FROM_DEG,SPECTRUM``, checked here so that a wrong one is named as
    the option's (the wind model's own check said ``wind: field 'gust'``, a key of no file the user
    wrote)."""
    import difflib

    from simulator.wind import GUST_SPECTRA

    gust = name.strip().lower()
    if gust not in GUST_SPECTRA:
        close = difflib.get_close_matches(gust, GUST_SPECTRA, n=1)
        hint = f"did you mean {close[0]}? " if close else ""
        raise ValueError(
            f"--wind {option}: no gust spectrum {name.strip()!r}: {hint}SPECTRUM is one of "
            f"{', '.join(GUST_SPECTRA)} (none: a steady wind)"
        )
    return gust


def plant_options(specs: list[str]) -> PlantOptions:
    """PlantOptions from KEY=VALUE strings; a bad one is a ValueError naming it."""
    from simulator.plant_params import PlantOptions

    values: dict[str, Any] = {}
    known = {f.name for f in fields(PlantOptions)}
    for spec in specs:
        key, sep, value = spec.partition("=")
        key, value = key.strip(), value.strip().lower()
        if not sep or key not in PLANT_OPTION_KEYS or key not in known:
            raise ValueError(
                f"--plant-option {spec!r}: expected KEY=VALUE with KEY one of {', '.join(PLANT_OPTION_KEYS)}"
            )
        if key == "added_mass_coriolis":
            values[key] = value
        elif value in ("on", "true", "1", "yes"):
            values[key] = True
        elif value in ("off", "false", "0", "no"):
            values[key] = False
        else:
            raise ValueError(f"--plant-option {spec!r}: {key} takes on or off")
    return replace(PlantOptions(), **values)


def _hull_problem(vessel: Any, options: PlantOptions, given: str) -> str | None:
    """A vessel without ``[hull]`` runs only the linear plant: the error gives the exact flags that switch
    off the effects still on, to copy, or None if nothing needs the hull."""
    if vessel.hull is not None:
        return None
    on = [key for key in ("coriolis", "surge_resistance", "crossflow") if getattr(options, key)]
    if not on:
        return None
    flags = " ".join(f"--plant-option {key}=off" for key in on)
    return (
        f"vessel '{vessel.name}' ({given}) has no [hull] table, which the full plant's {', '.join(on)} "
        f"need: add one (M_A, x_g, beam, draught, surge resistance; docs/vessels.md), or run M and D alone "
        f"with {flags}"
    )


def _floats(text: str, flag: str, n: int, extra: tuple[str, ...] = ()) -> tuple[list[float], list[str]]:
    parts = [p.strip() for p in text.split(",")]
    if not (n <= len(parts) <= n + len(extra)):
        raise ValueError(
            f"{flag} {text!r}: expected {n} numbers" + (f" and optionally {extra[0]}" if extra else "")
        )
    try:
        nums = [float(p) for p in parts[:n]]
    except ValueError:
        raise ValueError(f"{flag} {text!r}: not numbers") from None
    if not all(math.isfinite(x) for x in nums):
        raise ValueError(f"{flag} {text!r}: not finite")
    return nums, parts[n:]


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from observers.vessel import VesselError, load_vessel
    from simulator.open_loop import (
        InputsError,
        overspeed_warnings,
        read_inputs,
    )
    from simulator.plant_params import PlantError, PlantParams

    try:
        if not args.vessel:
            raise ValueError("--inputs needs --vessel NAME|FILE.toml")
        if not (args.csv or args.out):
            raise ValueError(
                "--inputs needs --csv STATES.csv and/or --out LOG.mcap (somewhere to write the states)"
            )
        # the outputs' folders as every log's (`wire.mcap.folder`): their own is made, a deeper one refused
        out_problem = mcap_path_problem("--out", args.out, made=True)
        if problem := made_folder_problem("--csv", args.csv) or out_problem:
            raise ValueError(problem)
        if problem := inputs_problem(args.inputs):
            raise ValueError(problem)
        vessel = load_vessel(args.vessel)
        options = plant_options(args.plant_option)
        if problem := _hull_problem(vessel, options, args.vessel):
            raise ValueError(problem)
        PlantParams.build(vessel, options)  # a vessel the plant cannot run is said before the inputs are read
        inputs = read_inputs(args.inputs, vessel)
        for warning in overspeed_warnings(inputs, vessel, str(args.inputs)):
            print(f"dpgw sim: warning: {warning}", file=sys.stderr)
        eta0, nu0 = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        if args.initial:
            (n0, e0, psi0), more = _floats(args.initial, "--initial", 3, ("U,V,R_DEGPS",) * 3)
            eta0 = (n0, e0, math.radians(psi0))
            if more:
                if len(more) != 3:
                    raise ValueError(f"--initial {args.initial!r}: give 3 or 6 numbers")
                (u0, v0, r0), _ = _floats(",".join(more), "--initial", 3)
                nu0 = (u0, v0, math.radians(r0))
        if args.wind and inputs.wind_speed is not None:
            raise ValueError(
                f"--wind: {args.inputs} has recorded wind columns already; give one or the other"
            )
        forces = []
        if args.wind:
            from simulator.wind import Wind, WindModel

            (speed, from_deg), rest = _floats(args.wind, "--wind", 2, ("SPECTRUM",))
            gust = wind_spectrum(args.wind, rest[0] if rest else "norsok")
            if vessel.hull is None or vessel.hull.wind is None:
                raise ValueError(
                    f"--wind: vessel '{vessel.name}' has no wind areas (field 'hull.wind', docs/vessels.md)"
                )
            wind = Wind(
                WindModel(speed, from_deg, gust=gust),
                vessel.hull.wind,
                vessel.length_m,
                np.random.default_rng(args.seed),
            )
            forces.append(lambda t, x: np.array(wind.force_body(t, float(x[2]), float(x[3]), float(x[4]))))
        if args.sea:
            from simulator.spectra import SeaState
            from simulator.waves import WaveField, WaveResponse

            (hs, tp, towards), _ = _floats(args.sea, "--sea", 3)
            waves = WaveField(
                SeaState(hs_m=hs, tp_s=tp, direction_rad=math.radians(towards)),
                WaveResponse.for_vessel(vessel),
                seed=args.seed,
            )
            forces.append(lambda t, x: waves.drift_force(np.array([t]), x[2], x[0], x[1])[0])
    except (ValueError, OSError, VesselError, InputsError, PlantError) as exc:
        print(f"dpgw sim: {exc}", file=sys.stderr)
        return 2

    def extra(t: float, x: Any) -> Any:
        return sum((f(t, x) for f in forces), np.zeros(3))

    # Ctrl-C or SIGTERM (SIGHUP through `dpgw.cli.hangup_as_terminate`) ends the run at the row it has
    # reached, and what ran is written as a whole run's would be (the states up to there, the log
    # complete), said, with the exit status of a command a signal stopped (128 + its number): an open-loop
    # run goes to the end of its inputs, as a replay to the end of its logs. Python's defaults gave a
    # traceback and nothing written, or, during the writing, a file cut short.
    with signals_noted() as stopped_by:
        return _run_and_write(args, vessel, inputs, options, extra if forces else None, eta0, nu0, stopped_by)


def _run_and_write(
    args: argparse.Namespace,
    vessel: Any,
    inputs: Any,
    options: Any,
    extra: Any,
    eta0: Any,
    nu0: Any,
    stopped_by: list[int],
) -> int:
    """The open-loop run until its last row or a signal (``stopped_by``, `signals_noted`), what ran
    written, the summary; the exit status."""
    from simulator.open_loop import STATE_COLUMNS, run_open_loop, write_states

    bar = terminal_bar(len(inputs.t) - 1, "row", json=args.json)

    def go_on(i: int) -> bool:
        if bar is not None and (i % 100 == 0 or i == len(inputs.t) - 2):
            bar.n = i
            bar.refresh()
        return not stopped_by

    try:
        states = run_open_loop(vessel, inputs, options, extra, eta0=eta0, nu0=nu0, go_on=go_on)
        if bar is not None:
            bar.close()
        ran = len(states)
        if stopped_by:  # (a signal during the writing below is taken when the files are complete)
            print(
                f"dpgw sim: stopped by {stop_name(stopped_by[0])} at row {ran} of {len(inputs.t)} "
                f"({states[-1][0] - states[0][0]:.0f} s of {inputs.t[-1] - inputs.t[0]:.0f} s); the states "
                "up to there are written",
                file=sys.stderr,
            )
        if args.csv:
            make_folder_for("dpgw sim", "--csv", args.csv)
            write_states(args.csv, states)
        if args.out:
            make_folder_for("dpgw sim", "--out", args.out)
            args.out = _write_log(args, vessel.name, inputs, states)
    except OSError as exc:
        print(f"dpgw sim: {exc}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
    interrupted = ran < len(inputs.t)
    status = 128 + stopped_by[0] if interrupted else 0
    end = states[-1]
    if args.json:
        from dpgw import cli_json

        summary = {
            "vessel": vessel.name,
            "inputs": str(args.inputs),
            "rows": len(states),
            "seconds": float(end[0] - states[0][0]),
            "end": dict(zip(STATE_COLUMNS, (float(x) for x in end), strict=True)),
            "csv": args.csv,
            "out": args.out,
            "interrupted": interrupted,
            "stopped_by": signal.Signals(stopped_by[0]).name if interrupted else None,
        }
        print(cli_json.dumps(summary, indent=2))
        return status
    of = f" of {len(inputs.t)}" if interrupted else ""
    print(
        f"{vessel.name}: {len(states)}{of} input rows, {end[0] - states[0][0]:.0f} s open loop; end at "
        f"N {end[1]:.1f} m, E {end[2]:.1f} m, heading {end[3]:.1f}°"
        + (f"; states: {args.csv}" if args.csv else "")
        + (f"; log: {args.out}" if args.out else "")
    )
    return status


def inputs_problem(path: str) -> str | None:
    """What is wrong with --inputs PATH, the file read (None when nothing): it must be there; unlike an
    output's, its folder is never made."""
    p = Path(path)
    if p.is_dir():
        return f"--inputs {path}: a folder, not a file: give the recorded inputs' CSV file"
    if not p.exists():
        where = "" if p.resolve().parent.is_dir() else f" (nor its folder {p.parent})"
        return f"--inputs {path}: no such file{where}: give the recorded inputs' CSV file (docs/simulator.md)"
    return None


def _write_log(args: argparse.Namespace, vessel: str, inputs: Any, states: Any) -> str:
    """The states as /truth/state records (as a scenario's truth), stamped from the scenario epoch; the
    file written: ``--out`` itself, or the next free file of its set when it exists (a log is never
    overwritten, as with ``--scenario``), said on stderr."""
    import math as m

    from simulator.clock import SimEpoch
    from simulator.scenarios import Scenario
    from wire.mcap.rotation import free_path
    from wire.mcap.writer import McapLogWriter
    from wire.messages import TruthState

    epoch = SimEpoch(Scenario.__dataclass_fields__["start_utc"].default)  # type: ignore[arg-type]
    with McapLogWriter(free_path(args.out), profile="dpgw-sim") as log:
        if Path(log.path) != Path(args.out):
            print(f"log -> {log.path} ({args.out} exists: a log is never overwritten)", file=sys.stderr)
        log.add_metadata("dpgw.sim", {"vessel": vessel, "inputs": str(args.inputs), "mode": "open loop"})
        for row in states:
            stamp = epoch.stamp_ns(float(row[0]))
            log.write(
                "/truth/state",
                TruthState(
                    stamp_ns=stamp,
                    eta_lf=[float(row[1]), float(row[2]), m.radians(float(row[3]))],
                    nu=[float(row[4]), float(row[5]), m.radians(float(row[6]))],
                    bias=[0.0, 0.0, 0.0],
                    eta_wf=[0.0, 0.0, 0.0],
                    omega0=[0.0, 0.0, 0.0],
                ),
                stamp,
                stamp,
            )
        return str(log.path)
