"""The figures of a radiation-model fit (`dpgw radiation --plots`, `bench/radiation_fit.py --plots`): per
identified element one PNG with three panels, each data against the model:

- A(ω): the added-mass data against the model's A(ω) = A(∞) + Im K(jω)/ω;
- B(ω): the damping data against the model's Re K(jω);
- K(t): the retardation function by eq (5), K(t) = (2/π) ∫ B(ω) cos(ωt) dω on the data's B(ω) (Perez &
  Fossen 2008; `observers.radiation.retardation_from_damping`, continued beyond the last frequency by
  B(ω_m)(ω_m/ω)², the decay of every model of this form), against the model's impulse response
  C e^{At} B (`impulse_response`).

Frequencies the identification screened out are drawn as red crosses. A caller may add a reference model's
curves (``reference``: the bench adds MSS's FDI result, whose data dpgw does not ship).

The curves are computed here (`element_data`, numpy only); matplotlib is imported only to draw, through the
replay report's `load_figure` (no pyplot: no global state), so that a missing matplotlib is said as the
replay report says it and the model is still written.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from observers.radiation import RadiationModel
    from wire.hydro import HydroData

Array = NDArray[np.float64]

T_KERNEL = np.linspace(0.0, 60.0, 241)
"""Time axis of K(t) (s): the supply vessel's kernels have decayed to < 1 % of their peak by 60 s."""


@dataclass(frozen=True)
class ElementData:
    """One identified element: (i, j) of surge, sway, yaw and its 6-DOF indices (I, J); the data the fit
    used (``w``, ``a``, ``b``), those it screened out (``excluded_*``), and K(t) by eq (5) on ``b`` at
    ``t``."""

    i: int
    j: int
    I: int  # (the 6-DOF index, as the papers write it)
    J: int
    dofs: str
    unit: str
    """The unit of A(ω) (kg, kg·m, kg·m²); B(ω) is in unit/s, K(t) in unit/s²."""
    order: int
    w: Array
    a: Array
    b: Array
    excluded_w: Array
    excluded_a: Array
    excluded_b: Array
    t: Array
    kernel: Array

    @property
    def name(self) -> str:
        """The element as the fit report names it: (2,6), 6-DOF indices from 1."""
        return f"({self.I + 1},{self.J + 1})"


@dataclass(frozen=True)
class ReferenceCurves:
    """Another model's curves of one element: A and B on the dense frequency grid, K at the times."""

    label: str
    added_mass: Array
    damping: Array
    kernel: Array


Reference = Callable[[int, int, Array, Array], "ReferenceCurves | None"]
"""(I, J, ω grid, t) → a reference model's curves of element (I, J) (6-DOF indices), or None if it has
none of it."""


def element_data(hydro: HydroData, model: RadiationModel, t: Array = T_KERNEL) -> list[ElementData]:
    """The data of every element `model` identified, split into used and screened out, with K(t) by eq (5)
    on the used B(ω) (``tail=True``: continued beyond the last frequency as the model decays)."""
    from observers.radiation import DOF_NAMES, SIX_DOF_INDEX, added_mass_unit, retardation_from_damping

    out = []
    for (i, j), fit in model.fits.items():
        I, J = SIX_DOF_INDEX[i], SIX_DOF_INDEX[j]
        keep = ~np.isin(hydro.freqs, fit.excluded_w)
        w, a, b = hydro.freqs[keep], hydro.A[I, J, keep], hydro.B[I, J, keep]
        out.append(
            ElementData(
                i=i,
                j=j,
                I=I,
                J=J,
                dofs=f"{DOF_NAMES[i]}-{DOF_NAMES[j]}",
                unit=added_mass_unit(i, j),
                order=fit.order,
                w=w,
                a=a,
                b=b,
                excluded_w=hydro.freqs[~keep],
                excluded_a=hydro.A[I, J, ~keep],
                excluded_b=hydro.B[I, J, ~keep],
                t=np.asarray(t, dtype=float),
                kernel=np.asarray(retardation_from_damping(w, b, t, tail=True), dtype=np.float64),
            )
        )
    return out


def dense_grid(w: Array) -> Array:
    """The frequencies the models are drawn at: half the lowest to three times the highest datum,
    log-spaced."""
    return np.geomspace(w[0] / 2.0, 3.0 * w[-1], 400)


def figure_name(e: ElementData) -> str:
    """``radiation_26.png``: the element's 6-DOF indices."""
    return f"radiation_{e.I + 1}{e.J + 1}.png"


def draw_fit(
    folder: Path,
    title: str,
    elements: list[ElementData],
    model: RadiationModel,
    Figure: Any,
    reference: Reference | None = None,
) -> list[Path]:
    """One PNG per element into ``folder`` (created), drawn with matplotlib's ``Figure`` class; returns
    the files."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for e in elements:
        wd = dense_grid(e.w)
        k_model = model.impulse_response(e.t)[:, e.i, e.j]
        fig = Figure(figsize=(12, 3.8), layout="constrained")
        ax_a, ax_b, ax_k = fig.subplots(1, 3)
        label = f"model (order {e.order})"
        ax_a.plot(e.w, e.a, "ko", ms=3, label="data")
        ax_a.plot(wd, model.added_mass(wd)[:, e.i, e.j], "C0", label=label)
        ax_b.plot(e.w, e.b, "ko", ms=3, label="data")
        ax_b.plot(wd, model.damping(wd)[:, e.i, e.j], "C0", label=label)
        ax_k.plot(e.t, e.kernel, "k", lw=2.5, alpha=0.4, label="eq (5) on the data's B(ω)")
        ax_k.plot(e.t, k_model, "C0", label="model's impulse response")
        ref = reference(e.I, e.J, wd, e.t) if reference is not None else None
        if ref is not None:
            ax_a.plot(wd, ref.added_mass, "C1--", label=ref.label)
            ax_b.plot(wd, ref.damping, "C1--", label=ref.label)
            ax_k.plot(e.t, ref.kernel, "C1--", label=ref.label)
        if len(e.excluded_w):
            ax_a.plot(e.excluded_w, e.excluded_a, "rx", label="screened out")
            ax_b.plot(e.excluded_w, e.excluded_b, "rx", label="screened out")
        ij = f"{e.I + 1}{e.J + 1}"
        ax_a.set(xlabel="ω (rad/s)", ylabel=f"A{ij}(ω) ({e.unit})", xscale="log", title="added mass")
        ax_b.set(xlabel="ω (rad/s)", ylabel=f"B{ij}(ω) ({e.unit}/s)", xscale="log", title="damping")
        ax_k.set(xlabel="t (s)", ylabel=f"K{ij}(t) ({e.unit}/s²)", title="retardation function")
        for ax in (ax_a, ax_b, ax_k):
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"{e.name} {e.dofs}: {title}")
        path = folder / figure_name(e)
        fig.savefig(path, dpi=110)
        written.append(path)
    return written


def write_fit_plots(
    folder: str | Path,
    hydro: HydroData,
    model: RadiationModel,
    reference: Reference | None = None,
) -> list[Path] | None:
    """`draw_fit` of every element of ``model`` on ``hydro``'s data; None (nothing written) when
    matplotlib is not installed (`gateway.report.writer.NO_MATPLOTLIB` says what to do)."""
    from gateway.report.plots import load_figure

    Figure = load_figure()
    if Figure is None:
        return None
    title = f"{Path(hydro.source).name}, data against the identified model"
    return draw_fit(Path(folder), title, element_data(hydro, model), model, Figure, reference)
