"""Radiation-model identification of a vessel side by side with MSS's FDI toolbox result.

Identifies the horizontal-plane fluid-memory model from A(ω), B(ω) (`observers.radiation.identify`) and
prints, per element, the order, R² of A and B and A(∞), for this identification and for MSS's identified
model (``supplyABC.mat``, scored on the same frequencies), then the passivity margin of both 3×3 models on
the same dense grid and the RMS difference of each model's retardation function K(t) from eq (5) on the
data. With ``--plots DIR`` it writes one figure per element (A(ω), B(ω), K(t): data against both
models), the figures of ``dpgw radiation --plots`` (`dpgw.radiation_plots`) with MSS's model added; with
``--out STEM`` the identified model (``STEM.npz`` and ``STEM.toml``).

    python bench/radiation_fit.py [--hydro supply_hydro.npz] [--mss supplyABC.mat] [--plots DIR] [--out STEM]

Defaults: the supply vessel's data shipped in the package (``simulator/data/supply_hydro.npz``, the
built-in name ``mss_supply``), and the copy of MSS's ``supplyABC.mat`` under ``tests/data/mss-supply``
(MSS's identified model is compared here only: it does not ship with dpgw).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dpgw.radiation_plots import T_KERNEL as T
from dpgw.radiation_plots import ReferenceCurves, element_data, write_fit_plots
from gateway.report.writer import NO_MATPLOTLIB
from observers import radiation as rad
from simulator.hydro_data import builtin_hydro
from wire.hydro import MssRadiationModel, load_hydro, load_mss_abc, save_radiation_model

REPO = Path(__file__).resolve().parents[1]
DEFAULT_HYDRO = builtin_hydro("mss_supply")
DEFAULT_MSS = REPO / "tests" / "data" / "mss-supply" / "supplyABC.mat"


def mss_response(mss: MssRadiationModel, w: NDArray[np.float64]) -> NDArray[np.complex128]:
    """MSS's 3×3 K(jω) (surge, sway, yaw), symmetric, from the elements it identified."""
    six = rad.SIX_DOF_INDEX
    k = np.zeros((len(w), 3, 3), dtype=complex)
    for i in range(3):
        for j in range(3):
            if (six[i], six[j]) in mss.elements:
                k[:, i, j] = mss.frequency_response(six[i], six[j], w)
    return k


def margin(k: NDArray[np.complex128], w: NDArray[np.float64]) -> tuple[float, float, float]:
    """(margin, ω at it, smallest diagonal damping / its peak) of K(jω) on the grid: the margin is the
    smallest eigenvalue of the Hermitian part of K scaled by its own diagonal, over frequency (1: uncoupled,
    0: the boundary of positive-realness, < 0: generates energy). Frequencies where a diagonal damping is
    below 10⁻⁹ of its peak are left out of the margin (its sign is below the rounding of K there) and
    judged by the diagonal figure instead."""
    herm = 0.5 * (k + np.conj(k.transpose(0, 2, 1)))
    d = np.real(np.diagonal(herm, axis1=1, axis2=2))
    peak = np.max(np.abs(d), axis=0)
    ok = np.all(d >= 1e-9 * peak, axis=1)
    s = 1.0 / np.sqrt(d[ok])
    lam = np.linalg.eigvalsh(herm[ok] * s[:, :, None] * s[:, None, :])[:, 0]
    i = int(np.argmin(lam))
    return float(lam[i]), float(w[ok][i]), float(np.min(d / peak))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hydro", type=Path, default=DEFAULT_HYDRO, help="A(ω), B(ω): project .npz or MSS .mat")
    ap.add_argument("--mss", type=Path, default=DEFAULT_MSS, help="MSS's identified model (vesselABC .mat)")
    ap.add_argument("--plots", type=Path, help="directory for the figures (needs matplotlib)")
    ap.add_argument("--out", type=Path, help="write the identified model as OUT.npz and OUT.toml")
    args = ap.parse_args()
    if not args.hydro.is_file():
        sys.exit(f"{args.hydro}: no such file (pass --hydro)")
    hydro = load_hydro(args.hydro)
    model = rad.identify(hydro.freqs, hydro.A, hydro.B)
    mss = load_mss_abc(args.mss)
    six = rad.SIX_DOF_INDEX
    k_ours = model.impulse_response(T)
    print(f"{hydro.source}: {len(hydro.freqs)} frequencies {hydro.freqs[0]:.3f}-{hydro.freqs[-1]:.3f} rad/s")
    print(
        f"{'element':9s} {'order':>9s} {'R² A':>15s} {'R² B':>15s} {'A(∞)':>21s} {'K(t) RMS/peak':>15s}"
        "  excluded"
    )
    print(
        f"{'':9s} {'dpgw MSS':>9s} {'dpgw   MSS':>15s} {'dpgw   MSS':>15s} {'dpgw      MSS':>21s} "
        f"{'dpgw  MSS':>15s}  (rad/s)"
    )
    fits = model.fits
    for e in element_data(hydro, model, T):
        f, I, J, w, a, k5 = fits[(e.i, e.j)], e.I, e.J, e.w, e.a, e.kernel
        peak = float(np.max(np.abs(k5)))
        rms_ours = float(np.sqrt(np.mean((k_ours[:, e.i, e.j] - k5) ** 2))) / peak
        if (I, J) in mss.elements:
            km = mss.frequency_response(I, J, w)
            m_order = str(mss.order(I, J))
            m_r2a = f"{rad.r_squared(a, mss.MA[I, J] + km.imag / w):.4f}"
            m_r2b = f"{rad.r_squared(e.b, km.real):.4f}"
            m_ainf = f"{mss.MA[I, J]:.4g}"
            k_mss = mss.impulse_response(I, J, T)
            m_rms = f"{float(np.sqrt(np.mean((k_mss - k5) ** 2))) / peak:.4f}"
        else:
            m_order = m_r2a = m_r2b = m_ainf = m_rms = "-"
        excluded = ", ".join(f"{v:.3f}" for v in f.excluded_w) or "none"
        print(
            f"({I + 1},{J + 1})     {f.order:>4d} {m_order:>4s} {f.r2_a:7.4f} {m_r2a:>7s} "
            f"{f.r2_b:7.4f} {m_r2b:>7s} {f.model.a_inf:10.4g} {m_ainf:>10s} {rms_ours:7.4f} {m_rms:>7s}  "
            f"{excluded}"
        )
    grid = rad.passivity_grid(hydro.freqs)[1:-1]
    ours = margin(model.frequency_response(grid), grid)
    theirs = margin(mss_response(mss, grid), grid)
    lo, hi = grid[0], grid[-1]
    print(f"\npassivity of the 3×3 on {len(grid)} frequencies {lo:.2g}-{hi:.3g} rad/s (margin: smallest")
    print("eigenvalue of the diagonally scaled Hermitian part of K(jω); ≥ 0 is positive real):")
    for name, (m, at, dmin) in (("dpgw", ours), ("MSS ", theirs)):
        print(f"  {name}: margin {m:.4f} at {at:.3g} rad/s, min diagonal damping {dmin:.3g} of its peak")
    p = model.passivity
    print(f"  dpgw's own check, ω → 0 and ∞ included: margin {p.margin:.4f} at {p.margin_w:.3g} rad/s")
    print(f"  passivity enforcement needed: {p.enforced}")
    mss_states = sum(mss.order(I, J) for I in six for J in six if (I, J) in mss.elements)
    print(f"  states of the 3×3 model: dpgw {model.Ar.shape[0]}, MSS {mss_states}")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        npz, toml = save_radiation_model(model, args.out)
        print(f"wrote {npz} and {toml}")
    if args.plots:
        written = write_fit_plots(args.plots, hydro, model, reference=mss_curves(mss))
        if written is None:
            sys.exit(f"--plots: {NO_MATPLOTLIB}")
        for path in written:
            print(f"wrote {path}")


def mss_curves(
    mss: MssRadiationModel,
) -> Callable[[int, int, NDArray[np.float64], NDArray[np.float64]], ReferenceCurves | None]:
    """MSS's identified model as the figures' reference line (`dpgw.radiation_plots.Reference`)."""

    def curves(I: int, J: int, w: NDArray[np.float64], t: NDArray[np.float64]) -> ReferenceCurves | None:
        if (I, J) not in mss.elements:
            return None
        k = mss.frequency_response(I, J, w)
        return ReferenceCurves(
            f"MSS FDI (order {mss.order(I, J)})",
            mss.MA[I, J] + k.imag / w,
            k.real,
            mss.impulse_response(I, J, t),
        )

    return curves


if __name__ == "__main__":
    main()
