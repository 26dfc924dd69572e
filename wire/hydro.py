"""Frequency-domain hydrodynamic data in and identified radiation models out (files; numerics elsewhere).

Reads A(ω), B(ω) from
- the project's ``.npz`` (keys ``freqs`` (N,), ``A``, ``B`` (6, 6, N), optional ``MRB`` (6, 6)), as in
  ``mss-supply/supply_hydro.npz``;
- an MSS ``vessel`` struct in a MATLAB ``.mat`` file (Marine Systems Simulator, ShipX/WAMIT readers: fields
  ``freqs``, ``A``, ``B``, ``MRB``; ``A``/``B`` may carry a fourth axis of forward speeds, of which the
  first, zero speed for DP, is taken);
and MSS's own identified fluid-memory model (``vesselABC`` struct: per-element ``Ar``, ``Br``, ``Cr``, ``Dr``
and ``MA`` = A(∞) + ...), so that a fit can be compared with it.

Writes the identified model (`observers.radiation.RadiationModel`) as ``.npz`` (the matrices) beside a
TOML report a person reads. A file that cannot be used raises `HydroError` naming the file, the field and
the reason.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.io
from numpy.typing import NDArray

if TYPE_CHECKING:  # only the type: this module reads and writes files and needs none of the numerics
    from observers.radiation import RadiationModel

Array = NDArray[np.float64]


class HydroError(ValueError):
    """Hydrodynamic data that cannot be used; the message names the file, the field and the reason."""


@dataclass(frozen=True)
class HydroData:
    """A(ω), B(ω) (6, 6, N) at the frequencies ``freqs`` (rad/s, increasing), SI units."""

    freqs: Array
    A: Array
    B: Array
    MRB: Array | None
    source: str


def _check(path: Path, freqs: object, A: object, B: object, MRB: object | None) -> HydroData:
    w = np.asarray(freqs, dtype=float).ravel()
    a, b = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    if a.ndim == 4:  # MSS: (6, 6, N, speeds); zero speed first
        a, b = a[..., 0], b[..., 0] if b.ndim == 4 else b
    for name, arr in (("A", a), ("B", b)):
        if arr.shape != (6, 6, len(w)):
            raise HydroError(
                f"{path}: field {name} has shape {arr.shape}, expected (6, 6, {len(w)}) to match freqs"
            )
        if not np.all(np.isfinite(arr)):
            raise HydroError(f"{path}: field {name} has non-finite values")
    if len(w) < 4 or np.any(w <= 0) or np.any(np.diff(w) <= 0) or not np.all(np.isfinite(w)):
        raise HydroError(f"{path}: field freqs must be at least 4 positive, increasing frequencies (rad/s)")
    mrb = None if MRB is None else np.asarray(MRB, dtype=float)
    if mrb is not None and mrb.shape != (6, 6):
        raise HydroError(f"{path}: field MRB has shape {mrb.shape}, expected (6, 6)")
    return HydroData(w, a, b, mrb, str(path))


def _loadmat(path: Path) -> dict[str, Any]:
    try:
        return dict(scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False))
    except Exception as exc:  # scipy raises ValueError, IndexError, NotImplementedError (v7.3), ...
        raise HydroError(f"{path}: not a MATLAB file scipy can read ({exc})") from exc


def load_hydro(path: str | Path) -> HydroData:
    """A(ω), B(ω) from a project ``.npz`` or an MSS ``vessel`` struct in a ``.mat`` file."""
    path = Path(path)
    if not path.is_file():
        raise HydroError(f"{path}: no such file")
    if path.suffix == ".npz":
        try:
            npz = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            # (a file that is not a zip archive of arrays: numpy takes it for a pickle, which it refuses)
            raise HydroError(f"{path}: not a NumPy .npz archive ({type(exc).__name__})") from None
        if not isinstance(npz, np.lib.npyio.NpzFile):  # a single .npy array named .npz
            raise HydroError(f"{path}: one array, not a .npz archive of named arrays (freqs, A, B)")
        with npz as data:
            missing = [k for k in ("freqs", "A", "B") if k not in data.files]
            if missing:
                raise HydroError(
                    f"{path}: missing field(s) {', '.join(missing)} (have {', '.join(data.files)})"
                )
            try:
                freqs, a, b = data["freqs"], data["A"], data["B"]
                mrb = data["MRB"] if "MRB" in data.files else None
            except (ValueError, OSError, zipfile.BadZipFile) as exc:  # object arrays, a damaged member
                raise HydroError(f"{path}: cannot read its arrays ({exc})") from None
            return _check(path, freqs, a, b, mrb)
    if path.suffix == ".mat":
        mat = _loadmat(path)
        vessel = mat.get("vessel")
        if vessel is None:
            names = ", ".join(k for k in mat if not k.startswith("__"))
            raise HydroError(f"{path}: no MSS 'vessel' struct (variables: {names or 'none'})")
        fields = getattr(vessel, "_fieldnames", [])
        missing = [k for k in ("freqs", "A", "B") if k not in fields]
        if missing:
            raise HydroError(f"{path}: vessel struct lacks field(s) {', '.join(missing)}")
        return _check(path, vessel.freqs, vessel.A, vessel.B, getattr(vessel, "MRB", None))
    raise HydroError(f"{path}: unknown format '{path.suffix}' (expected .npz or an MSS .mat)")


@dataclass(frozen=True)
class MssRadiationModel:
    """MSS's identified fluid-memory model: ``elements[(i, j)] = (Ar, Br, Cr, Dr)`` for the 6-DOF indices
    (0-based) it modelled, and ``MA`` (6, 6), the added mass it pairs with them (A(∞))."""

    elements: dict[tuple[int, int], tuple[Array, Array, Array, float]]
    MA: Array

    def frequency_response(self, i: int, j: int, w: Array) -> NDArray[np.complex128]:
        a, b, c, d = self.elements[(i, j)]
        eye = np.eye(a.shape[0])
        return np.array([c @ np.linalg.solve(1j * wk * eye - a, b) + d for wk in w])

    def impulse_response(self, i: int, j: int, t: Array) -> Array:
        """K_ij(t) = C_r e^{A_r t} B_r (a feedthrough would add D_r δ(t), not sampled)."""
        a, b, c, _ = self.elements[(i, j)]
        lam, v = np.linalg.eig(a)
        cb = (c @ v) * np.linalg.solve(v, b)
        return np.real(np.exp(np.outer(np.asarray(t, dtype=float), lam)) @ cb)

    def order(self, i: int, j: int) -> int:
        return int(self.elements[(i, j)][0].shape[0])


def load_mss_abc(path: str | Path) -> MssRadiationModel:
    """MSS's ``vesselABC`` struct (FDI toolbox output, e.g. ``supplyABC.mat``)."""
    path = Path(path)
    if not path.is_file():
        raise HydroError(f"{path}: no such file")
    mat = _loadmat(path)
    abc = mat.get("vesselABC")
    if abc is None:
        raise HydroError(f"{path}: no MSS 'vesselABC' struct")
    elements: dict[tuple[int, int], tuple[Array, Array, Array, float]] = {}
    for i in range(6):
        for j in range(6):
            a = np.atleast_2d(np.asarray(abc.Ar[i, j], dtype=float))
            if a.size == 0:
                continue
            b = np.asarray(abc.Br[i, j], dtype=float).ravel()
            c = np.asarray(abc.Cr[i, j], dtype=float).ravel()
            d = float(np.asarray(abc.Dr[i, j], dtype=float).sum())
            elements[(i, j)] = (a, b, c, d)
    return MssRadiationModel(elements, np.asarray(abc.MA, dtype=float))


RADIATION_FIELDS = ("Ar", "Br", "Cr", "Dr", "A_inf")


def save_radiation_model(
    model: RadiationModel, stem: str | Path, meta: dict[str, Any] | None = None
) -> tuple[Path, Path]:
    """Write ``<stem>.npz`` (Ar, Br, Cr, Dr, A_inf; SI units, ν = [u, v, r] in, μ = [X, Y, N] out; ``meta``,
    if given, as a JSON string under the key ``meta``: where the model came from, for a cache to check)
    and ``<stem>.toml`` (the fit report). Returns both paths. The .npz is written to a temporary name and
    renamed, so a reader never sees half a file."""
    stem = Path(stem)
    if stem.suffix in (".npz", ".toml"):  # the model's own file named: the stem is the rest
        stem = stem.with_suffix("")
    # appended, not `with_suffix`: a stem with a dot of its own (model_v1.2) kept its name up to that dot,
    # and model_v1.2 and model_v1.3 were both written as model_v1.npz, the second over the first
    npz, toml = stem.with_name(stem.name + ".npz"), stem.with_name(stem.name + ".toml")
    arrays: dict[str, Any] = {k: getattr(model, k) for k in RADIATION_FIELDS}
    if meta is not None:
        arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    tmp = npz.with_name(f".{npz.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
    os.replace(tmp, npz)
    p = model.passivity
    lines = [
        "# Fluid-memory model identified by dpgw (observers.radiation); matrices in the .npz beside.",
        "# mu = Cr xi + Dr nu, xi' = Ar xi + Br nu; nu = [u, v, r] (m/s, rad/s), mu = [X, Y, N] (N, N m).",
        f"states = {model.Ar.shape[0]}",
        "",
        "[passivity]",
        f"passive = {str(p.passive).lower()}",
        f"margin = {p.margin:.6g}",
        f"margin_at_rad_s = {p.margin_w:.6g}",
        f"min_diagonal_damping = {p.min_diagonal_damping:.6g}",
        f'enforced = "{p.enforced}"',
    ]
    for row in model.report():
        lines += [
            "",
            "[[element]]",
            f'element = "{row["element"]}"',
            f'dofs = "{row["dofs"]}"',
            f"order = {row['order']}",
            f"r2_A = {row['r2_A']:.6f}",
            f"r2_B = {row['r2_B']:.6f}",
            f"A_inf = {row['A_inf']:.9g}",
            f"excluded_rad_s = {json.dumps(row['excluded_w'])}",
        ]
    toml.write_text("\n".join(lines) + "\n")
    return npz, toml


@dataclass(frozen=True)
class RadiationMatrices:
    """A model written by `save_radiation_model`: the matrices and its ``meta`` ({} if none)."""

    Ar: Array
    Br: Array
    Cr: Array
    Dr: Array
    A_inf: Array
    meta: dict[str, Any]
    source: str


def load_radiation_model(path: str | Path) -> RadiationMatrices:
    """Read a model written by `save_radiation_model` (HydroError naming the file and field if unusable)."""
    path = Path(path)
    if not path.is_file():
        raise HydroError(f"{path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in RADIATION_FIELDS if k not in data.files]
            if missing:
                raise HydroError(
                    f"{path}: missing field(s) {', '.join(missing)} (have {', '.join(data.files)})"
                )
            arrays = {k: np.asarray(data[k], dtype=float) for k in RADIATION_FIELDS}
            meta = json.loads(str(data["meta"])) if "meta" in data.files else {}
    except HydroError:
        raise
    except Exception as exc:  # a truncated or foreign file: zipfile, pickle and JSON errors alike
        raise HydroError(f"{path}: not a radiation model file ({exc})") from exc
    if not isinstance(meta, dict):
        raise HydroError(f"{path}: field meta is not a JSON object")
    return RadiationMatrices(**arrays, meta=meta, source=str(path))
