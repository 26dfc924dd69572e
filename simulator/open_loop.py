"""Open-loop runs of the plant from recorded inputs: how a vessel model is checked against a sea trial or
against another simulator (`dpgw sim --vessel NAME --inputs INPUTS.csv`).

INPUTS.csv: a header row, then one row per time. Columns ``t`` (s, increasing), ``current_speed`` (m/s),
``current_dir_deg`` (the direction the current flows *towards*, clockwise from north), and per thruster
k = 1…N in the vessel file's order ``n_<k>`` (shaft speed, rpm, negative astern) and, for azimuths,
``alpha_<k>`` (deg, the thrust's direction clockwise from the bow). Optional: ``wind_speed`` (m/s, at the
vessel's wind reference height) and ``wind_from_deg`` (the direction it blows from), as an anemometer
records them — then the wind force on the vessel's ``[hull.wind]`` areas acts too. Every input is held from
its row to the next. Thrust is the vessel's propeller law, T = T_max (n/n_max)|n/n_max|
(`Thruster.thrust_at_rpm`), at once: a recording of shaft speeds already contains the drives' dynamics.
Nothing is clipped — a recording is what happened.

The states (STATES.csv: ``t, north, east, psi_deg, u, v, r_degps``) are the low-frequency state at every
input row, before that row's inputs act. The run starts at rest at the origin, heading 0, unless given an
initial state (a sea-trial record rarely starts at rest).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.spelling import closest
from observers.vessel import VesselModel
from simulator.plant import MAX_STEP_S, FullPlant
from simulator.plant_params import DEFAULT_OPTIONS, PlantOptions
from simulator.wind import wind_force

Array = NDArray[np.float64]

STATE_COLUMNS = ("t", "north", "east", "psi_deg", "u", "v", "r_degps")


class InputsError(ValueError):
    """An INPUTS.csv that cannot be run; the message names the file, the row and the column."""


@dataclass(frozen=True)
class Inputs:
    t: Array  # (rows,)
    current_speed: Array
    current_dir_deg: Array
    rpm: Array  # (rows, N)
    alpha_deg: Array  # (rows, N); the fixed direction for tunnels and main propellers
    wind_speed: Array | None = None
    wind_from_deg: Array | None = None


def input_columns(vessel: VesselModel) -> list[str]:
    cols = ["t", "current_speed", "current_dir_deg"]
    cols += [f"n_{k}" for k in range(1, len(vessel.thrusters) + 1)]
    cols += [f"alpha_{k}" for k, th in enumerate(vessel.thrusters, 1) if th.kind == "azimuth"]
    return cols


WIND_COLUMNS = ("wind_speed", "wind_from_deg")


def read_inputs(path: str | Path, vessel: VesselModel) -> Inputs:
    """Read and check INPUTS.csv for this vessel. Every error names the row (file line) and the column.

    As a spreadsheet saves it: a UTF-8 byte-order mark (Excel's "CSV UTF-8") is skipped, and so are blank
    lines (a trailing empty line, a row of empty cells). The separator is ``,``; a file that uses ``;``
    (a spreadsheet in a decimal-comma locale) is refused with that said."""
    where = str(path)
    expected = input_columns(vessel)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            rows = [(reader.line_num, row) for row in reader if any(cell.strip() for cell in row)]
    except OSError as exc:
        raise InputsError(f"{where}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise InputsError(f"{where}: not a text CSV file") from None
    except csv.Error as exc:
        raise InputsError(f"{where}: not a CSV file ({exc})") from None
    if not rows:
        raise InputsError(f"{where}: empty; expected a header row with the columns {', '.join(expected)}")
    header_line, first = rows[0]
    header = [h.strip() for h in first]
    _check_header(header, header_line, expected, vessel, where)
    wind_cols = [c for c in WIND_COLUMNS if c in header]
    if len(wind_cols) == 1:
        other = next(c for c in WIND_COLUMNS if c not in header)
        raise InputsError(f"{where}: column {wind_cols[0]} without {other} (recorded wind needs both)")
    if wind_cols and (vessel.hull is None or vessel.hull.wind is None):
        raise InputsError(
            f"{where}: columns wind_speed, wind_from_deg: vessel '{vessel.name}' has no wind areas "
            "(field 'hull.wind', docs/vessels.md)"
        )
    data = np.empty((len(rows) - 1, len(header)))
    lines = [line for line, _ in rows[1:]]
    for i, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputsError(f"{where}: line {line}: {len(row)} fields, the header has {len(header)}")
        for j, text in enumerate(row):
            try:
                value = float(text)
            except ValueError:
                raise InputsError(
                    f"{where}: line {line}, column '{header[j]}': not a number: {text!r}"
                ) from None
            if not math.isfinite(value):
                raise InputsError(f"{where}: line {line}, column '{header[j]}': not finite: {text!r}")
            data[i, j] = value
    if len(data) < 2:
        raise InputsError(f"{where}: needs at least two rows after the header (a start and an end time)")
    col = {name: data[:, header.index(name)] for name in header}
    t = col["t"]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        line = lines[int(bad[0]) + 1]
        raise InputsError(
            f"{where}: line {line}, column 't': times must increase ({t[bad[0] + 1]} after {t[bad[0]]})"
        )
    for name in ("current_speed", "wind_speed"):
        neg = np.flatnonzero(col[name] < 0) if name in col else np.zeros(0, dtype=int)
        if neg.size:
            raise InputsError(f"{where}: line {lines[int(neg[0])]}, column '{name}': must be ≥ 0")
    n = len(vessel.thrusters)
    rpm = np.column_stack([col[f"n_{k}"] for k in range(1, n + 1)]) if n else np.zeros((len(t), 0))
    alpha = np.tile(np.degrees([th.angle_rad for th in vessel.thrusters]), (len(t), 1))
    for k, th in enumerate(vessel.thrusters, 1):
        if th.kind == "azimuth":
            alpha[:, k - 1] = col[f"alpha_{k}"]
    return Inputs(
        t,
        col["current_speed"],
        col["current_dir_deg"],
        rpm,
        alpha,
        col.get("wind_speed"),
        col.get("wind_from_deg"),
    )


def _check_header(header: list[str], line: int, expected: list[str], vessel: VesselModel, where: str) -> None:
    """The header names every column this vessel needs and no other; a near miss gets a "did you mean"."""
    layout = f"{vessel.name} has {len(vessel.thrusters)} thrusters: columns {', '.join(expected)}"
    known = [*expected, *WIND_COLUMNS]
    missing = [c for c in expected if c not in header]
    unknown = [c for c in header if c not in known]
    if missing and len(header) == 1:
        for sep, name in ((";", "';'"), ("\t", "tabs")):
            if sep in header[0]:
                raise InputsError(
                    f"{where}: line {line}: the separator is ',' but the file seems to use {name}: "
                    f"save it as CSV with commas ({layout})"
                )
    for column in unknown:
        if problem := _thruster_column_problem(column, vessel):
            raise InputsError(f"{where}: line {line}, column '{column}': {problem} ({layout})")
        meant = closest(column, known)
        if meant is not None and meant not in header:
            raise InputsError(
                f"{where}: line {line}, column '{column}': unknown, did you mean '{meant}'? ({layout})"
            )
    if missing:
        raise InputsError(
            f"{where}: missing column{'s' if len(missing) > 1 else ''} {', '.join(missing)} ({layout})"
        )
    if unknown:
        raise InputsError(
            f"{where}: unknown column{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} ({layout})"
        )


def _thruster_column_problem(column: str, vessel: VesselModel) -> str | None:
    """Why ``n_<k>`` or ``alpha_<k>`` is not a column of this vessel (k beyond its thrusters, an angle of a
    fixed-direction thruster), or None if the column is not of that form."""
    prefix, _, number = column.partition("_")
    if prefix not in ("n", "alpha") or not number.isdigit():
        return None
    k = int(number)
    n = len(vessel.thrusters)
    if not 1 <= k <= n:
        return f"no thruster {k}: {vessel.name} has {n}" + (f", numbered 1 to {n}" if n else "")
    th = vessel.thrusters[k - 1]
    if prefix == "alpha" and th.kind != "azimuth":
        return (
            f"thruster {k} is a {th.kind} (a fixed direction, {math.degrees(th.angle_rad):g}°: no angle to "
            "record): drop the column"
        )
    return None


def overspeed_warnings(inputs: Inputs, vessel: VesselModel, where: str) -> list[str]:
    """One line per thruster whose recorded |n| exceeds its ``max_rpm``: the likely sign of a unit mistake
    (rad/s, rps or percent for rpm). Only said: a recording is what happened, so the run is not clipped,
    and the thrust at n is T_max (n/n_max)|n/n_max|, beyond T_max."""
    out = []
    for k, th in enumerate(vessel.thrusters, 1):
        rpm = np.abs(inputs.rpm[:, k - 1])
        over = np.flatnonzero(rpm > th.max_rpm)
        if over.size:
            worst = float(rpm.max())
            out.append(
                f"{where}: column 'n_{k}': |n| up to {worst:g} rpm (first at t = {inputs.t[over[0]]:g} s), "
                f"beyond thruster {k}'s max_rpm {th.max_rpm:g}: a unit mistake (rps, rad/s, %)? Run "
                f"unclipped, at up to {(worst / th.max_rpm) ** 2:.3g}× its max_thrust_n"
            )
    return out


ExtraForce = Callable[[float, Array], Array]
"""An added body-frame force at (t, state): wind, wave drift."""


def run_open_loop(
    vessel: VesselModel,
    inputs: Inputs,
    options: PlantOptions = DEFAULT_OPTIONS,
    extra_force: ExtraForce | None = None,
    extra_step_s: float = 0.25,
    eta0: ArrayLike = (0.0, 0.0, 0.0),
    nu0: ArrayLike = (0.0, 0.0, 0.0),
    go_on: Callable[[int], bool] | None = None,
) -> Array:
    """Integrate the full plant through the inputs; the state rows (STATE_COLUMNS) at every input time.

    Without ``extra_force`` or recorded wind each interval is one call of the compiled RK4 (steps of at
    most 0.05 s); with them, the forces are re-evaluated every ``extra_step_s`` and held in between.
    ``go_on(i)``, when given, is asked before row i is integrated on to row i + 1 (a progress bar, a
    stop): when it says no, the rows up to i are returned, each exactly as in the whole run.
    """
    plant = FullPlant(vessel, eta0, nu0, options=options)
    area = vessel.hull.wind if vessel.hull is not None else None
    recorded_wind = inputs.wind_speed is not None and inputs.wind_from_deg is not None and area is not None
    out = np.empty((len(inputs.t), len(STATE_COLUMNS)))
    zero_bias = np.zeros(3)
    for i, t in enumerate(inputs.t):
        x = plant.x
        out[i] = (t, x[0], x[1], math.degrees(x[2]), x[3], x[4], math.degrees(x[5]))
        if i == len(inputs.t) - 1:
            break
        if go_on is not None and not go_on(i):
            return out[: i + 1]
        thrust = [th.thrust_at_rpm(n) for th, n in zip(vessel.thrusters, inputs.rpm[i], strict=True)]
        tau = vessel.generalized_force(thrust, np.radians(inputs.alpha_deg[i])) if thrust else np.zeros(3)
        b = math.radians(inputs.current_dir_deg[i])
        vc = inputs.current_speed[i] * np.array([math.cos(b), math.sin(b)])
        dt = inputs.t[i + 1] - t
        if extra_force is None and not recorded_wind:
            plant.step(dt, tau, zero_bias, vc)
            continue
        chunks = max(1, math.ceil(dt / extra_step_s - 1e-9))
        for c in range(chunks):
            tc = t + c * dt / chunks
            force = tau.copy()
            if extra_force is not None:
                force += extra_force(tc, plant.x)
            if recorded_wind:
                assert area is not None and inputs.wind_speed is not None and inputs.wind_from_deg is not None
                x = plant.x
                force += wind_force(
                    area, vessel.length_m, inputs.wind_speed[i], inputs.wind_from_deg[i], x[2], x[3], x[4]
                )
            plant.step(dt / chunks, force, zero_bias, vc)
    return out


def write_states(path: str | Path, states: Array) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        f.write(",".join(STATE_COLUMNS) + "\n")
        for row in states:
            f.write(f"{row[0]:.3f}," + ",".join(f"{v:.9g}" for v in row[1:]) + "\n")


__all__ = [
    "MAX_STEP_S",
    "STATE_COLUMNS",
    "Inputs",
    "InputsError",
    "overspeed_warnings",
    "read_inputs",
    "run_open_loop",
    "write_states",
]
