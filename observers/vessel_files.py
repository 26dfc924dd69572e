"""The vessels that ship with dpgw, by name: a listing of the package's ``vessels/`` folder.

Kept apart from `observers.vessel` (numpy, the model's matrices) so that the command line can list the
names in ``--help`` without importing the numerics.
"""

from importlib import resources


def builtin_vessels() -> list[str]:
    """Names of the vessels that ship with dpgw."""
    folder = resources.files("observers") / "vessels"
    return sorted(p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml"))
