"""``dpgw radiation``: identify a vessel's fluid-memory model from A(ω), B(ω) and write it beside the data."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from dpgw.cli_paths import missing_folder, output_folder_problem
from dpgw.cli_types import finite_float, int_at_least

# observers.radiation's MIN_ORDER, MAX_ORDER and R2_TARGET, written here so that `dpgw radiation --help`
# needs no numpy or scipy (the fit is imported by `run`); a test holds them equal.
MIN_ORDER = 2
MAX_ORDER = 10
R2_TARGET = 0.99

NAME = "radiation"
HELP = "identify the fluid-memory (radiation) model from added mass and damping data"
DESCRIPTION = (
    "Fit K(jω) = B(ω) + jω(A(ω) − A(∞)) of surge, sway and yaw as a stable, passive state-space "
    "model (A(∞) estimated, order chosen automatically), print the fit and write the model as "
    "STEM.npz (matrices) and STEM.toml (report); with --plots DIR, one figure per element: A(ω), B(ω) "
    "and the retardation function K(t), data against the model. HYDRO is a file or the name of data "
    "that ship with dpgw: mss_supply (the ShipX A(ω), B(ω) of MSS's 82.8 m, 6362 t supply vessel, "
    "simulator/data/supply_hydro.npz in the package)."
)
EPILOG = (
    "examples:\n"
    "  dpgw radiation mss_supply --plots fit   # the shipped data; the model here, fit/radiation_*.png\n"
    "  dpgw radiation ship.mat --out ship_memory --json   # an MSS vessel .mat; the summary as JSON\n"
    "  dpgw radiation mss_supply --vessel mss_supply   # the model the simulator uses for mss_supply\n"
    "  dpgw radiation ship_hydro.npz --vessel ship.toml   # ship_radiation.npz beside ship.toml"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "hydro",
        type=Path,
        help="A(ω), B(ω): the project's .npz or an MSS vessel .mat, or mss_supply (the data that ship "
        "with dpgw)",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="STEM",
        help="output stem (default: HYDRO's stem + _radiation beside it; for mss_supply, "
        "mss_supply_radiation in the current folder)",
    )
    p.add_argument(
        "--vessel",
        metavar="NAME|FILE",
        help="store the model where the simulator looks for this vessel's fluid memory (a built-in vessel: "
        "observers/vessels/radiation/NAME.npz in this checkout; a vessel file ship.toml: ship_radiation.npz "
        "beside it), recording the data's SHA-256 and the settings",
    )
    p.add_argument(
        "--max-order",
        type=_order,
        default=MAX_ORDER,
        help=f"order cap per element, {MIN_ORDER} or more (default {MAX_ORDER})",
    )
    p.add_argument(
        "--r2",
        type=_r2,
        default=R2_TARGET,
        help=f"R² an order must reach on A and B, between 0 and 1 (default {R2_TARGET})",
    )
    p.add_argument(
        "--plots",
        type=Path,
        metavar="DIR",
        help="write the fit's figures in DIR (created): radiation_IJ.png per identified element (IJ: 6-DOF "
        "indices, e.g. 26 sway-yaw), A(ω), B(ω) and K(t) by eq (5) on the data against the model",
    )
    p.add_argument("--json", action="store_true", help="print the fit and the files written as JSON")
    p.set_defaults(func=run)


_order = int_at_least(MIN_ORDER, "K(s) needs a zero at s = 0 and a pole pair")
"""An order cap the fit can use: K(s) = s·G(s) needs a pole pair, so at least MIN_ORDER."""


def _r2(text: str) -> float:
    """An R² target an order can reach: above 0, at most 1 (above 1 every order fails and the cap is used)."""
    value = finite_float(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be above 0 and at most 1 (got {text})")
    return value


def run(args: argparse.Namespace) -> int:
    from observers import radiation
    from wire.hydro import HydroError, load_hydro, save_radiation_model

    # What cannot be written is said before the fit, not after it.
    if args.vessel and args.out:
        print("dpgw radiation: give --out or --vessel, not both", file=sys.stderr)
        return 2
    if args.vessel and not Path(args.vessel).is_file():
        # a name must be a built-in vessel: a misspelt one was taken for a file stem (NAME_radiation.npz
        # in the current folder); a vessel file is only where the model goes (it may not be complete yet)
        from observers.vessel import VesselError, load_vessel

        try:
            load_vessel(args.vessel)
        except VesselError as exc:
            print(f"dpgw radiation: --vessel: {exc}", file=sys.stderr)
            return 2
    if problem := missing_folder("--out", args.out) or output_folder_problem("--plots", args.plots):
        print(f"dpgw radiation: {problem}", file=sys.stderr)
        return 2
    hydro_path, builtin = _hydro_path(args.hydro)
    if not hydro_path.is_file():
        from observers.spelling import did_you_mean
        from simulator.hydro_data import BUILTIN_HYDRO

        names = ", ".join(BUILTIN_HYDRO)
        what = "a folder, not a file" if hydro_path.is_dir() else "no such file"  # (a folder: said so)
        if not hydro_path.is_dir():  # a misspelt name of shipped data, as `tune` and `capability` say it
            what += did_you_mean(str(args.hydro), BUILTIN_HYDRO)
        print(
            f"dpgw radiation: {hydro_path}: {what}: give A(ω), B(ω) as a .npz or an MSS vessel .mat, "
            f"or the name of data that ship with dpgw ({names})",
            file=sys.stderr,
        )
        return 2
    try:
        hydro = load_hydro(hydro_path)
    except HydroError as exc:
        print(f"dpgw radiation: {exc}", file=sys.stderr)
        return 2
    warnings = []
    if args.vessel and (mismatch := _other_hull(hydro_path, hydro.MRB, args.vessel)):
        warnings.append(mismatch)
        print(f"dpgw radiation: warning: {mismatch}", file=sys.stderr)
    if sign := radiation.damping_sign_problem(hydro.B):
        print(f"dpgw radiation: {hydro_path}: {sign}", file=sys.stderr)
        return 2
    try:
        model = radiation.identify(hydro.freqs, hydro.A, hydro.B, max_order=args.max_order, r2_target=args.r2)
    except ArithmeticError as exc:  # no passive model (the module says when): status 1, as documented
        print(
            f"dpgw radiation: {hydro_path}: no passive model could be identified ({exc}); look at the "
            "data's B(ω) (its sign, its units) or raise --max-order",
            file=sys.stderr,
        )
        return 1
    p = model.passivity
    # An element that missed the R² target keeps the best order tried (the model is still written, as a
    # user who asked for it may want it): said, so the fit is not taken for one that met the target.
    fits = list(model.fits.values())
    for row, fit in zip(model.report(), fits, strict=True):
        r2_a, r2_b = float(row["r2_A"]), float(row["r2_B"])  # type: ignore[arg-type]
        if min(r2_a, r2_b) < args.r2:
            fitted = fit.tried.get(fit.order, (r2_a, r2_b))
            if p.enforced == "residues" and min(fitted) > min(r2_a, r2_b) + 1e-4:
                # the fit was better: making the whole model passive moved this element's residues (a
                # poor fit of a coupling can take the others with it), said as such, not as the best fit
                why = (
                    f"after the passivity enforcement changed it (its fit at that order had A "
                    f"{fitted[0]:.4f}, B {fitted[1]:.4f}): raise --max-order, which may fit the model "
                    "passive without it, or lower --r2"
                )
            else:
                why = (
                    f"(the best of the orders up to --max-order {args.max_order}): raise --max-order or "
                    "lower --r2"
                )
            missed = (
                f"element {row['element']} {row['dofs']}: R² A {r2_a:.4f}, B {r2_b:.4f} below the target "
                f"{args.r2:g} at order {row['order']} {why}"
            )
            warnings.append(missed)
            print(f"dpgw radiation: warning: {missed}", file=sys.stderr)
    if not args.json:
        _print_fit(model)
    meta = None
    if args.vessel:
        from simulator.fluid_memory_cache import beside_vessel, file_sha256, meta_for

        used = {"max_order": args.max_order, "r2_target": args.r2, "significance": radiation.SIGNIFICANCE}
        meta = meta_for(file_sha256(hydro_path), str(args.vessel), hydro_path.name, used, hydro.MRB)
        stem = beside_vessel(args.vessel).with_suffix("")
        stem.parent.mkdir(parents=True, exist_ok=True)
    elif args.out:
        stem = args.out
    elif builtin:  # not into the package: in the current folder, under the data's name
        stem = Path(f"{args.hydro}_radiation")
    else:
        stem = hydro_path.with_name(hydro_path.stem + "_radiation")
    npz, toml = save_radiation_model(model, stem, meta)
    if not args.json:
        print(f"wrote {npz} and {toml}")
    plots: list[Path] = []
    if args.plots:
        # (after the model: a figure that cannot be drawn does not lose it)
        from dpgw.radiation_plots import write_fit_plots

        try:
            drawn = write_fit_plots(args.plots, hydro, model)
        except OSError as exc:  # (a full disk, a folder made read-only meanwhile)
            print(
                f"dpgw radiation: --plots {args.plots}: cannot write the figures ({exc.strerror or exc}): "
                f"the model is written ({npz}); give a writable folder",
                file=sys.stderr,
            )
            return 1
        if drawn is None:
            from gateway.report.writer import NO_MATPLOTLIB

            warnings.append(f"--plots: {NO_MATPLOTLIB}")
            print(f"dpgw radiation: --plots: {NO_MATPLOTLIB}", file=sys.stderr)
        else:
            plots = drawn
            if not args.json:
                print("wrote " + ", ".join(str(f) for f in plots))
    if args.json:
        from dpgw import cli_json

        summary = {
            "hydro": str(hydro_path),
            "elements": model.report(),
            "passivity": {
                "passive": p.passive,
                "margin": p.margin,
                "margin_w": p.margin_w,
                "min_diagonal_damping": p.min_diagonal_damping,
                "enforced": p.enforced,
            },
            "states": int(model.Ar.shape[0]),
            "model": [str(npz), str(toml)],
            "plots": [str(f) for f in plots],
            "warnings": warnings,
        }
        print(cli_json.dumps(summary, indent=2))
    return 0 if p.passive else 1


def _print_fit(model: Any) -> None:
    """The fit report as a table, and the passivity check."""
    print(
        f"{'element':8s} {'DOFs':11s} {'order':>5s} {'R² A':>7s} {'R² B':>7s} {'A(∞)':>11s} {'unit':6s}  "
        "excluded (rad/s)"
    )
    for row in model.report():
        excluded = ", ".join(f"{v:.3f}" for v in row["excluded_w"]) or "none"
        print(
            f"{row['element']:8s} {row['dofs']:11s} {row['order']:>5d} {row['r2_A']:7.4f} {row['r2_B']:7.4f} "
            f"{row['A_inf']:11.4g} {row['A_inf_unit']:6s}  {excluded}"
        )
    p = model.passivity
    state = "passive" if p.passive else "NOT passive"
    print(f"{state}: margin {p.margin:.4f} at {p.margin_w:.3g} rad/s, enforcement: {p.enforced}")


def _hydro_path(hydro: Path) -> tuple[Path, bool]:
    """HYDRO as a file, and whether it is the data shipped with dpgw under a name (`simulator.hydro_data`):
    a file of that name, if there is one, is read instead."""
    if hydro.is_file():
        return hydro, False
    from simulator.hydro_data import builtin_hydro

    shipped = builtin_hydro(str(hydro))
    return (shipped, True) if shipped is not None else (hydro, False)


MASS_RATIO = (0.5, 2.0)
"""Data and vessel of one hull: their masses within this ratio. Outside it the data are of another hull
(a model basin's 1:70 vessel against the full-scale ship's data is a ratio of 4·10⁻⁶)."""


def _other_hull(hydro: Path, data_mrb: Any, vessel: str) -> str | None:
    """What to say when the data's hull (its rigid-body mass M_RB) is not the vessel's: the model stored
    beside the vessel is used for it as it is, unscaled. None when they agree, or when either mass is
    unknown (data without M_RB, a vessel file that does not load yet)."""
    if data_mrb is None:
        return None
    from observers.vessel import VesselError, load_vessel

    try:
        v = load_vessel(vessel)
    except VesselError:
        return None
    m_data, m_vessel = float(data_mrb[0][0]), float(v.mass_kg)
    ratio = m_vessel / m_data
    if MASS_RATIO[0] <= ratio <= MASS_RATIO[1]:
        return None
    lam = ratio ** (1.0 / 3.0)
    return (
        f"the data are of another hull than vessel '{v.name}': {hydro.name} gives M_RB {m_data:.4g} kg, "
        f"{v.name} has {m_vessel:.4g} kg (ratio {ratio:.3g}, outside {MASS_RATIO[0]:g}-{MASS_RATIO[1]:g}); "
        f"the model is stored as {v.name}'s own, for the data's hull, unscaled. For a geometrically similar "
        f"hull Froude scaling carries a model over (λ = (m_vessel/m_data)^⅓ = {lam:.4g}: time × √λ, added "
        "mass × λ³): without --vessel the vessel has no model of its own and the fluid-memory observer and "
        "the simulator lend it dpgw's built-in one (the supply vessel's) Froude-scaled to its mass "
        "([observer.params] froude_scale sets λ)"
    )
