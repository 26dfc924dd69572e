"""``dpgw capability``: the DP capability plot of a vessel, intact and after single thruster failures."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from dpgw import cli_json
from dpgw.cli_paths import missing_folder
from dpgw.cli_progress import terminal_bar
from dpgw.cli_types import finite_float, non_negative_float
from observers.vessel_files import builtin_vessels

# dpgw.capability's DEFAULT_CURRENT_MPS and U_LIMIT_MPS, written here so that `dpgw capability --help` needs
# no numpy or scipy (the analysis is imported by `run`); a test holds them equal.
DEFAULT_CURRENT_MPS = 0.75
U_LIMIT_MPS = 40.0
BEAUFORT_DYNAMIC_FACTOR = 1.25
PLOT_SUFFIXES = (".png", ".svg", ".pdf")

NAME = "capability"
HELP = "DP capability plot: the largest wind (with its current and waves) the thrusters hold against"
DESCRIPTION = (
    "For each direction the environment comes from (0° = on the bow, clockwise), find the largest wind "
    "speed U (1-hour mean at 10 m) at which the thrusters can still balance the mean loads and hold position "
    "and heading: wind on the vessel's [hull.wind] areas, a fixed current (--current-mps) and the mean wave "
    "drift of a fully developed Pierson-Moskowitz sea of that wind (Hs = 0.21 U19.5²/g), all from the same "
    "direction. Quasi-static: the mean loads against the thrusters' limits (their barred sectors "
    f"respected), no dynamic allowance. Intact, and after each single thruster failure. U_max = "
    f"{U_LIMIT_MPS:g} means at least {U_LIMIT_MPS:g} m/s (a laboratory model: Froude-scaled); 0 means "
    "even the current alone is too much. "
    "With --sea beaufort the sea and current come from DNV-ST-0111's Table 2-1 (the environment of its "
    "DP capability numbers, Beaufort 1-11), the loads are multiplied by its dynamic factor 1.25, and each "
    "direction also gets its DP capability number: the highest Beaufort number held with every one "
    "below it (dpgw's own load models, not the standard's Level 1 formulas). "
    "Method and assumptions: docs/capability.md."
)
EPILOG = (
    "examples:\n"
    "  dpgw capability --vessel mss_supply                  # intact and worst failure\n"
    "  dpgw capability --vessel mss_supply --plot cap.png   # and the polar plot\n"
    "  dpgw capability --vessel mss_osv --failures each --json   # every failure\n"
    "  dpgw capability --vessel my_ship.toml --current-mps 1.0 --step-deg 15\n"
    "  dpgw capability --vessel mss_supply --failure-group 1,4 --failure-group 2,5,6   # switchboards\n"
    "  dpgw capability --config examples/hil_bench.toml     # its vessel and failure groups\n"
    "  dpgw capability --vessel mss_supply --sea beaufort --plot bf.png   # DP capability numbers\n"
    f"built-in vessels: {', '.join(builtin_vessels())}"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--vessel", metavar="NAME|FILE", help="built-in vessel name or a vessel TOML file")
    source.add_argument(
        "--config",
        metavar="FILE",
        help="a gateway config: its vessel, and its [consequence] failure_groups as the failures analysed "
        "(the switchboards the online consequence analysis tests)",
    )
    p.add_argument(
        "--current-mps",
        type=non_negative_float,
        default=None,
        metavar="MPS",
        help=f"current speed (m/s), from the same direction as the wind (default {DEFAULT_CURRENT_MPS:g}, "
        "1.5 kn, Froude-scaled for a laboratory model; 0: wind and waves only)",
    )
    p.add_argument(
        "--step-deg",
        type=_step,
        default=10.0,
        metavar="DEG",
        help="direction step (degrees, dividing 360 into whole steps is best; default 10)",
    )
    p.add_argument(
        "--failures",
        choices=("none", "each", "worst"),
        default="worst",
        help="none: intact only; each: intact and every single thruster failure; worst (default): intact "
        "and, per direction, the worst single failure",
    )
    p.add_argument(
        "--failure-group",
        action="append",
        type=_group,
        metavar="IDS",
        help="thruster ids lost together, comma-separated (a switchboard: --failure-group 1,4); repeat for "
        "each group; given, the groups are the failures analysed instead of single thrusters (a thruster "
        "in no group is still lost alone)",
    )
    p.add_argument(
        "--sea",
        choices=("pm", "beaufort"),
        default="pm",
        help="the sea and current of a wind speed. pm (default): a fully developed Pierson-Moskowitz sea "
        "of the wind and the fixed --current-mps; beaufort: DNV-ST-0111 Table 2-1's Hs, Tp and current "
        "per Beaufort number (linear in the wind between its rows), and per direction the DP capability "
        "number",
    )
    p.add_argument(
        "--dynamic-factor",
        type=_factor,
        default=None,
        metavar="F",
        help=f"multiply the environmental loads by F, an allowance for the gusts, the slowly varying drift "
        f"and the controller's reserve (default 1 with --sea pm: the mean loads; {BEAUFORT_DYNAMIC_FACTOR:g} "
        "with --sea beaufort, the standard's Level 1 factor)",
    )
    p.add_argument("--no-waves", action="store_true", help="leave the wave drift out (wind and current only)")
    p.add_argument("--plot", type=Path, metavar="FILE", help="write the polar plot (.png, .svg or .pdf)")
    p.add_argument("--json", action="store_true", help="print the result as JSON instead of a table")
    p.set_defaults(func=run)


def _group(text: str) -> tuple[int, ...]:
    try:
        ids = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be thruster ids separated by commas, e.g. 1,4 (got {text})"
        ) from None
    if not ids:
        raise argparse.ArgumentTypeError(f"must name at least one thruster id (got {text!r})")
    return ids


def _factor(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < 100.0:  # (nan fails too) one message for every wrong value, zero and negatives alike
        raise argparse.ArgumentTypeError(f"must be a positive factor below 100, e.g. 1.25 (got {text})")
    return value


def _step(text: str) -> float:
    value = finite_float(text)  # (one message for every value out of range: -10 was "must be >= 0", 0 not)
    if not 0.0 < value <= 180.0:
        raise argparse.ArgumentTypeError(f"must be above 0 and at most 180 degrees (got {text})")
    return value


def run(args: argparse.Namespace) -> int:
    from observers.vessel import VesselError, VesselModel, load_vessel

    vessel: VesselModel
    if args.failure_group and args.failures == "none":
        print(
            "dpgw capability: --failure-group with --failures none: no failure would be analysed; give "
            "--failures worst or each with the groups, or leave the groups out",
            file=sys.stderr,
        )
        return 2
    if args.sea == "beaufort" and args.current_mps is not None:
        print(
            "dpgw capability: --current-mps with --sea beaufort: the Beaufort table gives the current for "
            "each wind (0.25 m/s at Beaufort 1, 0.50 at 2, 0.75 from 3); leave --current-mps out, or use "
            "--sea pm for a fixed current",
            file=sys.stderr,
        )
        return 2
    if args.config is not None:
        from gateway.config import ConfigError, format_problems, load_config

        try:
            config = load_config(args.config)
        except ConfigError as exc:
            print(format_problems(exc), file=sys.stderr)
            return 2
        vessel = config.vessel
        if not args.failure_group and config.consequence.failure_groups:
            args.failure_group = [tuple(g) for g in config.consequence.failure_groups]
    else:
        try:
            vessel = load_vessel(args.vessel)
        except VesselError as exc:
            print(f"dpgw capability: --vessel: {exc}", file=sys.stderr)
            return 2
    if not vessel.thrusters:
        print(
            f"dpgw capability: vessel '{vessel.name}' has no thrusters: give a vessel with a [[thrusters]] "
            "layout (docs/vessels.md)",
            file=sys.stderr,
        )
        return 2
    if problem := missing_folder("--plot", args.plot) or _plot_problem(args.plot):
        print(f"dpgw capability: {problem}", file=sys.stderr)
        return 2
    from dpgw.capability import Environment, capability, default_current, plot

    current = default_current(vessel) if args.current_mps is None else args.current_mps
    factor = args.dynamic_factor
    if factor is None:
        factor = BEAUFORT_DYNAMIC_FACTOR if args.sea == "beaufort" else 1.0
    env = Environment(
        current_mps=current,
        current=current > 0,
        waves=not args.no_waves,
        sea=args.sea,
        dynamic_factor=factor,
    )
    bar = terminal_bar(None, "direction", json=args.json, leave=False)  # a fine --step-deg: minutes

    def progress(done: int, total: int) -> None:
        if bar is not None:
            bar.total, bar.n = total, done
            bar.refresh()

    try:
        result = capability(
            vessel,
            environment=env,
            step_deg=args.step_deg,
            failures=args.failures,
            failure_groups=args.failure_group,
            progress=progress,
        )
    except ValueError as exc:  # a failure group naming a thruster the vessel does not have
        print(f"dpgw capability: --failure-group: {exc}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
    plot_error = None
    if args.plot:  # (before the figures are printed, so --json can name it; a failure does not lose them)
        try:
            plot(result, str(args.plot))
        except OSError as exc:
            plot_error = (
                f"dpgw capability: --plot {args.plot}: cannot write it ({exc.strerror or exc}): give a "
                "writable path"
            )
    if args.json:
        doc = result.to_dict()
        if args.plot and plot_error is None:
            doc["plot"] = str(args.plot)
        print(cli_json.dumps(doc, indent=1))
    else:
        _print_table(result)
    for warning in result.warnings:
        print(f"dpgw capability: note: {warning}", file=sys.stderr)
    if plot_error is not None:
        print(plot_error, file=sys.stderr)
        return 1
    if args.plot and not args.json:
        print(f"wrote {args.plot}")
    return 0


def _plot_problem(path: Path | None) -> str | None:
    """What is wrong with ``--plot PATH`` that can be seen before the analysis: a format the plot is not
    written in, or a folder in the way."""
    if path is None:
        return None
    if path.suffix.lower() not in PLOT_SUFFIXES:
        return f"--plot {path}: give a file name ending in {', '.join(PLOT_SUFFIXES)} (the plot's format)"
    try:
        folder = path.is_dir()
    except OSError as exc:  # (a name longer than the file system allows)
        return f"--plot {path}: not a usable path ({exc.strerror or exc}): give another"
    if folder:
        return f"--plot {path}: is a folder: give a file name in it, e.g. {path / 'capability.png'}"
    return None


def _print_table(result: object) -> None:
    from dpgw.capability import CapabilityResult

    assert isinstance(result, CapabilityResult)
    # U is the wind speed whether or not a wind load is computed (no [hull.wind] areas): then it is the
    # wind whose sea (and Beaufort current) act, and the relation says "no wind load", not "wind U"
    what = "1-hour mean wind at 10 m" + ("" if result.environment.wind else ", which sets the sea")
    print(f"DP capability of {result.vessel}: U_max (m/s, {what}); {result.environment.describe()}")
    lim = result.u_limit
    print(f"environment from (deg, clockwise from the bow); {lim:.3g} = at least {lim:.3g}")
    # (a laboratory model's speeds, Froude-scaled: 4.78 m/s at most for CyberShip II, need a second
    # decimal, or the search's end, 4.78, prints as 4.8 and cannot be told from a limit of 4.75)
    digits = 1 if lim >= 10.0 else 2
    cols: list[tuple[str, tuple[float, ...], tuple[int, ...] | None]] = [
        (c.label, c.u_max, c.dp_number) for c in result.cases
    ]
    if result.worst is not None and len(result.cases) == 1:
        cols.append(("worst failure", result.worst, result.worst_dp_number))
    if result.intact.dp_number is not None:
        print("each cell: U_max (DP capability number: the highest Beaufort number held with all below it)")
    head = f"{'from':>6s} " + " ".join(f"{label:>18s}" for label, _, _ in cols)
    limiting = result.limiting_failures()
    if limiting is not None:
        head += "  worst: thrusters failed"
    print(head)

    def cell(u: float, number: int | None) -> str:
        text = f"{u:.{digits}f}" + (f" (BF {number:2d})" if number is not None else "")
        return f"{text:>18s}"

    for i, d in enumerate(result.directions_deg):
        line = f"{d:6.1f} " + " ".join(cell(u[i], n[i] if n is not None else None) for _, u, n in cols)
        if limiting is not None:  # ("-": no failure lowers it, `limiting_failures`)
            line += "  " + ("+".join(map(str, limiting[i])) or "-")
        print(line)
