"""Which of dpgw's hot-path modules run compiled (mypyc), and running them interpreted when they must.

The install compiles the per-event hot path (decoding, reference checks, fusion, the pipeline, the outputs;
the list is in setup.py) to C with mypyc, from the same sources, and records in ``wire/_compiled.json``
the hash of each source it compiled. Python would import a compiled module in preference to its source
whatever happened to the source since, so at the first import of `wire` or `gateway` this module checks:

- ``DPGW_PURE_PYTHON=1`` in the environment: every compiled module is imported from its source (the
  readable reference; profilers see inside it; tests/test_compiled.py compares the two);
- a source changed since it was compiled (an edit in a checkout): likewise, for all of them, with a
  warning saying how to compile again. All or none, because compiled modules call each other directly:
  one module taken from source would still be called in its old compiled form by the others.

Otherwise nothing is done and the compiled modules load as usual. `status` says which it was.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import json
import os
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

PURE_ENV = "DPGW_PURE_PYTHON"
_ROOT = Path(__file__).resolve().parent.parent  # the folder holding the `wire` and `gateway` packages
_MANIFEST = _ROOT / "wire" / "_compiled.json"


@dataclass(frozen=True)
class Status:
    modules: tuple[str, ...]
    """The modules the install compiled (empty when it compiled none)."""
    why_not: str
    """Why the hot path runs interpreted ("" when it runs compiled)."""

    @property
    def compiled(self) -> bool:
        """The hot path runs compiled."""
        return not self.why_not

    def describe(self) -> str:
        if self.compiled:
            return f"compiled (mypyc, {len(self.modules)} modules)"
        return f"interpreted ({self.why_not})"


class _FromSource(importlib.abc.MetaPathFinder):
    """Imports the listed modules from their ``.py`` source, ahead of the compiled extension."""

    def __init__(self, names: frozenset[str]) -> None:
        self.names = names

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in self.names:
            return None
        source = _ROOT.joinpath(*fullname.split(".")).with_suffix(".py")
        return importlib.util.spec_from_file_location(fullname, source)


_status: Status | None = None


def _read_manifest() -> tuple[dict[str, str], str]:
    """The modules the build compiles and their sources' hashes; and if it compiled none, why."""
    try:
        manifest = json.loads(_MANIFEST.read_text())
    except (OSError, ValueError):
        return {}, "no compiled build recorded here (run from a checkout, or installed without one)"
    modules = {str(k): str(v) for k, v in manifest.get("modules", {}).items()}
    if not manifest.get("compiled"):
        return modules, f"not compiled at install: {manifest.get('reason') or 'no reason recorded'}"
    return modules, ""


def _changed(modules: dict[str, str]) -> list[str]:
    changed = []
    for name, digest in modules.items():
        source = _ROOT.joinpath(*name.split(".")).with_suffix(".py")
        try:
            now = hashlib.sha256(source.read_bytes()).hexdigest()
        except OSError:
            continue  # (a wheel without sources: nothing to prefer)
        if now != digest:
            changed.append(name)
    return changed


def install() -> Status:
    """Decide once per process (the first import of `wire` or `gateway` calls it) and return `status`."""
    global _status
    if _status is not None:
        return _status
    modules, why_none = _read_manifest()
    names = tuple(sorted(modules))
    if why_none:
        if names:  # (extensions an earlier build left beside the sources must not be imported)
            sys.meta_path.insert(0, _FromSource(frozenset(names)))
        _status = Status((), why_none)
        return _status
    if not any(_ROOT.joinpath("wire").glob("_native__mypyc.*")):
        _status = Status((), "the manifest names compiled modules but their library is missing")
        return _status
    if os.environ.get(PURE_ENV, "") not in ("", "0"):
        why = f"{PURE_ENV} is set"
    else:
        changed = _changed(modules)
        if not changed:
            _status = Status(names, "")
            return _status
        shown = ", ".join(changed[:3]) + (" ..." if len(changed) > 3 else "")
        why = f"changed since compiled: {shown}"
        warnings.warn(
            f"dpgw: {shown} changed since the install compiled it; running the hot path interpreted "
            "(slower) until `pip install -e .` compiles it again",
            RuntimeWarning,
            stacklevel=2,
        )
    loaded = [name for name in names if name in sys.modules]
    if loaded:  # (imported before the decision: cannot be undone; should not happen, see __init__)
        why += f"; already loaded compiled: {', '.join(loaded)}"
    sys.meta_path.insert(0, _FromSource(frozenset(names)))
    _status = Status(names, why)
    return _status


def status() -> Status:
    """Whether the hot path runs compiled in this process, which modules, and if not why."""
    return install()


def is_compiled(module: ModuleType) -> bool:
    """``module`` was loaded from a compiled extension (not from its ``.py`` source)."""
    origin = getattr(module, "__file__", "") or ""
    return origin.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES))
