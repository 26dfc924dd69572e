"""A vessel's fluid-memory model, identified once and stored; a simulator start only reads a file.

Where a model is found (`load_fluid_memory`):

1. **Beside the vessel.** A built-in vessel's model ships in the package, ``observers/vessels/radiation/
   NAME.npz`` (with the fit report ``NAME.toml``), made by ``dpgw radiation HYDRO --vessel NAME``; a user
   vessel ``ship.toml`` has it in ``ship_radiation.npz`` beside the file. Shipping it means a simulator
   start needs neither the hydrodynamic data (they are large, and not ours to ship) nor the seconds the
   identification takes, and everyone simulates the same model, reviewable in the repository.
2. **In the user cache** (``$DPGW_CACHE_DIR``, else ``$XDG_CACHE_HOME/dpgw``, else ``~/.cache/dpgw``;
   subfolder ``radiation``), when the caller passes hydrodynamic data (``hydro=``) that the model beside
   the vessel was not made from (or there is none): identified on first use, written atomically under a
   key made of the data file's SHA-256, the identification settings and the file format, and read from
   there afterwards. The package folder is never written at run time (it may be read-only).

Every model file records in its ``meta`` the SHA-256 of the data it came from and the settings, so a
stale model is recognised instead of silently used.
"""

from __future__ import annotations

import hashlib
import json
import os
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from simulator.fluid_memory import FluidMemoryError, RadiationStateSpace
from wire.hydro import HydroError, load_radiation_model

FORMAT = 1
"""Version of what a model file means (bump when the identification or the state's layout changes)."""
SIX_DOF = (0, 1, 5)
"""Surge, sway, yaw in 6-DOF data (observers.radiation.SIX_DOF_INDEX, not imported: reading a stored
model must not load the identification and its scipy.optimize)."""


def settings() -> dict[str, Any]:
    """The identification settings a model depends on (the defaults of `observers.radiation`)."""
    from observers import radiation

    return {
        "max_order": radiation.MAX_ORDER,
        "r2_target": radiation.R2_TARGET,
        "significance": radiation.SIGNIFICANCE,
    }


def file_sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def cache_dir() -> Path:
    """The user cache folder of identified models (not created here)."""
    base = os.environ.get("DPGW_CACHE_DIR")
    if base:
        return Path(base) / "radiation"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "dpgw" / "radiation"


def beside_vessel(vessel: str | Path) -> Path:
    """Where the model of a vessel (a built-in name or a TOML path) is stored beside it (may not exist)."""
    from observers.vessel_files import builtin_vessels

    if str(vessel) in builtin_vessels():
        return Path(str(resources.files("observers") / "vessels" / "radiation" / f"{vessel}.npz"))
    path = Path(vessel)
    return path.with_name(f"{path.stem}_radiation.npz")


def meta_for(
    hydro_sha256: str,
    vessel: str = "",
    hydro_name: str = "",
    used: dict[str, Any] | None = None,
    m_rb: Any = None,
) -> dict[str, Any]:
    """What a model file records about its making (``used``: the settings, default `settings()`;
    ``m_rb``: the data's 6×6 rigid-body mass, of which surge, sway and yaw are kept)."""
    meta: dict[str, Any] = {
        "format": FORMAT,
        "hydro_sha256": hydro_sha256,
        "hydro_file": hydro_name,
        "settings": settings() if used is None else used,
        "vessel": vessel,
    }
    if m_rb is not None:
        meta["M_RB"] = np.asarray(m_rb, dtype=float)[np.ix_(SIX_DOF, SIX_DOF)].tolist()
    return meta


def _matches(meta: dict[str, Any], sha: str) -> bool:
    return (
        meta.get("format") == FORMAT
        and meta.get("hydro_sha256") == sha
        and meta.get("settings") == settings()
    )


def _read(path: Path) -> tuple[RadiationStateSpace, dict[str, Any]]:
    try:
        m = load_radiation_model(path)
    except HydroError as exc:
        raise FluidMemoryError(str(exc)) from exc
    sha = str(m.meta.get("hydro_sha256", ""))
    m_rb = np.asarray(m.meta["M_RB"], dtype=float) if "M_RB" in m.meta else None
    return RadiationStateSpace(m.Ar, m.Br, m.Cr, m.Dr, m.A_inf, str(path), sha, m_rb), m.meta


def identify_to(hydro: str | Path, stem: Path, vessel: str = "") -> Path:
    """Identify the model from the data file ``hydro`` with the default settings and write ``stem.npz`` /
    ``stem.toml``, with the meta a cache checks. Returns the .npz path. (The identification takes about
    a second.)"""
    from observers import radiation
    from wire.hydro import load_hydro, save_radiation_model

    try:
        data = load_hydro(hydro)
    except HydroError as exc:
        raise FluidMemoryError(str(exc)) from exc
    model = radiation.identify(data.freqs, data.A, data.B, **settings())
    if not model.passivity.passive:
        raise FluidMemoryError(f"{hydro}: the identified fluid-memory model is not passive; not stored")
    stem.parent.mkdir(parents=True, exist_ok=True)
    meta = meta_for(file_sha256(hydro), str(vessel), Path(hydro).name, m_rb=data.MRB)
    npz, _ = save_radiation_model(model, stem, meta)
    return npz


def load_fluid_memory(
    vessel: str | Path, *, hydro: str | Path | None = None, cache: Path | None = None
) -> RadiationStateSpace:
    """The fluid-memory model of ``vessel`` (a built-in name or a vessel TOML path).

    Without ``hydro``: the model stored beside the vessel, or FluidMemoryError saying how to make one.
    With ``hydro`` (A(ω), B(ω): a project .npz or an MSS .mat): the model beside the vessel if it was made
    from exactly these data with the current settings, else the user cache's (``cache`` overrides the
    folder), identified and stored there on first use."""
    beside = beside_vessel(vessel)
    if hydro is None:
        if not beside.is_file():
            raise FluidMemoryError(
                f"vessel '{vessel}': no fluid-memory model ({beside} does not exist); identify one with "
                f"`dpgw radiation HYDRO --vessel {vessel}`"
            )
        return _read(beside)[0]
    hydro = Path(hydro)
    if not hydro.is_file():
        raise FluidMemoryError(f"vessel '{vessel}': hydrodynamic data {hydro}: no such file")
    sha = file_sha256(hydro)
    if beside.is_file():
        model, meta = _read(beside)
        if _matches(meta, sha):
            return model
    key = hashlib.sha256(json.dumps([sha, settings(), FORMAT], sort_keys=True).encode()).hexdigest()[:24]
    stem = (cache or cache_dir()) / key
    path = stem.with_suffix(".npz")
    if path.is_file():
        try:
            model, meta = _read(path)
            if _matches(meta, sha):
                return model
        except FluidMemoryError:
            pass  # a damaged cache entry is made again below
    return _read(identify_to(hydro, stem, str(vessel)))[0]
