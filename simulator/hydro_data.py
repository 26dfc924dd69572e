"""The hydrodynamic data that ship with dpgw, by name.

``mss_supply``: the ShipX/VERES A(ω), B(ω) (with RAOs and drift coefficients) of MSS's 82.8 m supply vessel,
``simulator/data/supply_hydro.npz`` (provenance and keys: ``simulator/data/README.md``), the data the
built-in vessel ``mss_supply``'s fluid-memory model was identified from (``dpgw radiation mss_supply
--vessel mss_supply``). Named as that vessel is, so that the data and the vessel they belong to are said
alike; a file of the same name in the current folder is read instead (`dpgw.cli_radiation`).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

BUILTIN_HYDRO = {"mss_supply": "supply_hydro.npz"}
"""Built-in name → file in the package's ``simulator/data``."""


def builtin_hydro(name: str) -> Path | None:
    """The shipped data file called ``name`` (a `BUILTIN_HYDRO` key), or None if there is none of that name.
    A path in the installed package (setuptools installs package data as plain files)."""
    file = BUILTIN_HYDRO.get(name)
    if file is None:
        return None
    return Path(str(resources.files("simulator") / "data" / file))
