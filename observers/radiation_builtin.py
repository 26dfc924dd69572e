"""The radiation models that ship with dpgw: a built-in vessel's own (``vessels/radiation/NAME.npz``, written
by ``dpgw radiation HYDRO --vessel NAME``) and the one lent to vessels without one, MSS's supply vessel.

Read by the fluid-memory observer (`observers.memory_tuning`), by the vessel loader for a vessel file in
the Cummins form (`observers.vessel`: M_RB and A(∞) given, A(0) - A(∞) from this model) and, through the
same file, by the simulator's plant. No I/O beyond the package's own files.
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import numpy as np

from observers.radiation import RadiationStateSpace
from observers.vessel_files import builtin_vessels

RADIATION_FOLDER = "vessels/radiation"
"""Where a built-in vessel's identified model lives in the package, as ``NAME.npz`` (+ ``NAME.toml``)."""

BUILTIN_RADIATION = f"{RADIATION_FOLDER}/mss_supply.npz"
"""The built-in model, in the package: the one `dpgw radiation` identified for mss_supply (with its fit
report beside it, ``mss_supply.toml``), read by the plant and by the memory observer alike."""


def _load(name: str) -> RadiationStateSpace:
    with (
        resources.as_file(resources.files("observers") / f"{RADIATION_FOLDER}/{name}.npz") as path,
        np.load(path, allow_pickle=False) as data,
    ):
        meta = json.loads(str(data["meta"]))
        m_rb = np.array(meta["M_RB"], dtype=float) if "M_RB" in meta else None
        hull = f" ({m_rb[0, 0] / 1e3:.0f} t)" if m_rb is not None else ""
        source = (
            f"MSS supply vessel{hull}, ShipX A(ω), B(ω)"
            if name == "mss_supply"
            else f"{name}{hull}, its own A(ω), B(ω)"
        )
        return RadiationStateSpace(
            data["Ar"],
            data["Br"],
            data["Cr"],
            data["Dr"],
            data["A_inf"],
            source=source,
            hydro_sha256=str(meta.get("hydro_sha256", "")),
            M_RB=m_rb,
        )


@lru_cache(maxsize=1)
def builtin_radiation() -> RadiationStateSpace:
    """MSS's supply vessel, identified by dpgw from its ShipX data (17 states, passive): the 82.8 m,
    6362 t hull of the ShipX/VERES A(ω), B(ω), whose rigid-body mass the file records (``M_RB``)."""
    return _load("mss_supply")


@lru_cache(maxsize=16)
def stored_radiation(name: str) -> RadiationStateSpace | None:
    """The model identified for the built-in vessel ``name`` from its own A(ω), B(ω) (None if it has none:
    of the built-in vessels only ``mss_supply`` has hydrodynamic data)."""
    if name not in builtin_vessels():
        return None
    if not (resources.files("observers") / f"{RADIATION_FOLDER}/{name}.npz").is_file():
        return None
    return builtin_radiation() if name == "mss_supply" else _load(name)


def froude_scale_for_mass(mass_kg: float) -> float:
    """Length scale λ = (m / m_supply)^⅓ that carries the built-in model to a hull of mass ``mass_kg``."""
    m_rb = builtin_radiation().M_RB
    assert m_rb is not None  # the built-in file records it
    return float((mass_kg / m_rb[0, 0]) ** (1.0 / 3.0))


def memory_added_mass(radiation: RadiationStateSpace) -> np.ndarray:
    """A(0) - A(∞) (3×3, symmetrised): the added mass the fluid memory supplies to slow motion."""
    a = radiation.zero_frequency_added_mass() - radiation.A_inf
    return np.asarray(0.5 * (a + a.T))
