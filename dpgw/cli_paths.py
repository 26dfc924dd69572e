"""Where a command will write, checked before it works: a folder that is not there is said at once, with
what to do, instead of a traceback after the replay, the fit or the simulation."""

from __future__ import annotations

from pathlib import Path


def missing_folder(flag: str, path: str | Path | None) -> str | None:
    """``FLAG PATH: no folder DIR: create it or give another path`` when PATH's folder does not exist."""
    if path is None or Path(path).resolve().parent.is_dir():
        return None
    return f"{flag} {path}: no folder {Path(path).parent}: create it or give another path"
