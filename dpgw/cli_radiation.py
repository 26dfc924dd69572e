"""``dpgw radiation``: identify a vessel's fluid-memory model from A(ω), B(ω) and write it beside the data."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dpgw.cli_paths import missing_folder
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
    "STEM.npz (matrices) and STEM.toml (report). Plots of the fit: bench/radiation_fit.py."
)
EPILOG = (
    "examples:\n"
    "  dpgw radiation supply_hydro.npz   # writes supply_hydro_radiation.npz and .toml\n"
    "  dpgw radiation supply_hydro.npz --vessel mss_supply   # the model the simulator uses for mss_supply"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("hydro", type=Path, help="A(ω), B(ω): the project's .npz or an MSS vessel .mat")
    p.add_argument(
        "--out", type=Path, metavar="STEM", help="output stem (default: HYDRO's stem + _radiation)"
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
    if problem := missing_folder("--out", args.out):
        print(f"dpgw radiation: {problem}", file=sys.stderr)
        return 2
    try:
        hydro = load_hydro(args.hydro)
    except HydroError as exc:
        print(f"dpgw radiation: {exc}", file=sys.stderr)
        return 2
    model = radiation.identify(hydro.freqs, hydro.A, hydro.B, max_order=args.max_order, r2_target=args.r2)
    print(
        f"{'element':8s} {'DOFs':11s} {'order':>5s} {'R² A':>7s} {'R² B':>7s} {'A(∞)':>11s} {'unit':6s}  "
        "excluded (rad/s)"
    )
    for row in model.report():
        excluded = ", ".join(f"{v:.3f}" for v in row["excluded_w"]) or "none"  # type: ignore[attr-defined]
        print(
            f"{row['element']:8s} {row['dofs']:11s} {row['order']:>5d} {row['r2_A']:7.4f} {row['r2_B']:7.4f} "
            f"{row['A_inf']:11.4g} {row['A_inf_unit']:6s}  {excluded}"
        )
    p = model.passivity
    state = "passive" if p.passive else "NOT passive"
    print(f"{state}: margin {p.margin:.4f} at {p.margin_w:.3g} rad/s, enforcement: {p.enforced}")
    meta = None
    if args.vessel:
        from simulator.fluid_memory_cache import beside_vessel, file_sha256, meta_for

        used = {"max_order": args.max_order, "r2_target": args.r2, "significance": radiation.SIGNIFICANCE}
        meta = meta_for(file_sha256(args.hydro), str(args.vessel), args.hydro.name, used, hydro.MRB)
        stem = beside_vessel(args.vessel).with_suffix("")
        stem.parent.mkdir(parents=True, exist_ok=True)
    else:
        stem = args.out or args.hydro.with_name(args.hydro.stem + "_radiation")
    npz, toml = save_radiation_model(model, stem, meta)
    print(f"wrote {npz} and {toml}")
    return 0 if p.passive else 1
