"""The study's cache: one JSON file per case, so that an interrupted study resumes where it stopped.

The file name is the case's key (`CaseSpec.key`): a hash of the case spec and of the code that computes
it (`code_version`: the dpgw version and a hash of every source and data file of the packages a case
runs). A changed observer, simulator or scoring line therefore makes a new key and the case is run again;
an old file is never read for a case it does not describe. Rows are stored as JSON (NaN as null) and read
back to the same floats (JSON round-trips a float exactly).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

# What a case's result depends on: all of our packages (the closed loop runs the gateway's pipeline).
_PACKAGES = ("observers", "wire", "simulator", "gateway", "dpgw")
_SUFFIXES = (".py", ".toml", ".npz", ".xml", ".json", ".csv")


@lru_cache(maxsize=1)
def code_version() -> str:
    """The dpgw version and a hash of the sources and package data (``.py``, ``.toml``, ``.npz`` …)."""
    try:
        version = metadata.version("dpgw")
    except metadata.PackageNotFoundError:
        version = "0+unknown"
    root = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for package in _PACKAGES:
        for path in sorted((root / package).rglob("*")):
            if path.suffix in _SUFFIXES and "__pycache__" not in path.parts and path.is_file():
                h.update(str(path.relative_to(root)).encode())
                h.update(path.read_bytes())
    return f"{version}+{h.hexdigest()[:16]}"


def _clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _restore(value: Any) -> Any:
    return math.nan if value is None else value


class CaseCache:
    """``folder``/``key``.json per case; writes are atomic (a study killed mid-write leaves no half file)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}.json"

    def get(self, key: str) -> list[dict[str, Any]] | None:
        try:
            doc = json.loads(self.path(key).read_text())
        except (OSError, ValueError):
            return None
        # NaN was stored as null; the text columns are never null
        return [{k: _restore(v) for k, v in row.items()} for row in doc["rows"]]

    def put(self, key: str, case: dict[str, Any], rows: list[dict[str, Any]]) -> None:
        doc = {
            "case": case,
            "code": code_version(),
            "rows": [{k: _clean(v) for k, v in r.items()} for r in rows],
        }
        tmp = self.path(key).with_suffix(f".tmp{os.getpid()}")
        tmp.write_text(json.dumps(doc, allow_nan=False))
        os.replace(tmp, self.path(key))
