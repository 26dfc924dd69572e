"""Where a command will write, checked before it works: a folder that is not there is said at once, with
what to do, instead of a traceback after the replay, the fit or the simulation."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def missing_folder(flag: str, path: str | Path | None) -> str | None:
    """``FLAG PATH: no folder DIR: create it or give another path`` when PATH's folder does not exist."""
    if path is None or Path(path).resolve().parent.is_dir():
        return None
    return f"{flag} {path}: no folder {Path(path).parent}: create it or give another path"


def mcap_path_problem(flag: str, path: str | Path | None, *, made: bool = False) -> str | None:
    """What is wrong with PATH as an MCAP file to write (None when nothing): a folder, a name that does not
    end in .mcap (Foxglove, the mcap tools and `dpgw replay` go by it), or a folder that does not exist
    (with ``made``: only when its parent does not exist either, `wire.mcap.folder`; the command makes the
    log's own folder and says so, as the gateway does for a config's ``log.path``)."""
    if path is None:
        return None
    p = Path(path)
    if p.is_dir():
        return f"{flag} {path}: a folder, not a file: give a file in it, e.g. {p / 'trial.mcap'}"
    if p.suffix != ".mcap":
        return f"{flag} {path}: not an MCAP file name (expected a path ending in .mcap, e.g. {p.stem}.mcap)"
    if not made:
        return missing_folder(flag, path)
    from wire.mcap.folder import log_folder_problem  # (light: the os module only; at use, as the rest)

    problem = log_folder_problem(path)
    return f"{flag} {path}: {problem}" if problem else None


def made_folder_problem(flag: str, path: str | Path | None) -> str | None:
    """What is wrong with the folder of PATH, a file the command writes (None when nothing): the rule of
    `wire.mcap.folder` for every file a command writes (a log, a tlog, a CSV of states), so that one
    command does not refuse a missing folder another makes: only the file's own folder may be missing
    (the command makes it, `make_folder_for`); a missing parent too is refused."""
    if path is None:
        return None
    from wire.mcap.folder import log_folder_problem

    problem = log_folder_problem(path)
    return f"{flag} {path}: {problem}" if problem else None


def make_folder_for(command: str, flag: str, path: str | Path) -> None:
    """Make the missing folder of PATH (its parent exists: `made_folder_problem`), said on stderr as the
    gateway says the log's folder it makes; nothing when it is there. Raises `OSError` as `os.mkdir`."""
    from wire.mcap.folder import make_log_folder

    if folder := make_log_folder(path):
        print(f"{command}: made the folder {folder} for {flag} (it did not exist)", file=sys.stderr)


def writable(path: str) -> bool:
    """``path`` is a folder this process may write in, or can be made as one (its nearest existing
    ancestor is a writable folder). No side effect: nothing is made."""
    p = os.path.abspath(path)
    while not os.path.lexists(p):
        parent = os.path.dirname(p)
        if parent == p:
            return False
        p = parent
    return os.path.isdir(p) and os.access(p, os.W_OK | os.X_OK)
