"""Where a command will write, checked before it works: a folder that is not there, or one this user may
not write in (a read-only USB stick, a shared data folder, a log folder owned by the service's user), is
said at once, with what to do, instead of a traceback after the replay, the fit or the simulation."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path


def missing_folder(flag: str, path: str | Path | None) -> str | None:
    """``FLAG PATH: no folder DIR: create it or give another path`` when PATH's folder does not exist."""
    if path is None:
        return None
    if not Path(path).resolve().parent.is_dir():
        return f"{flag} {path}: no folder {Path(path).parent}: create it or give another path"
    return unwritable(flag, path)


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
    return f"{flag} {path}: {problem}" if problem else unwritable(flag, path)


def made_folder_problem(flag: str, path: str | Path | None) -> str | None:
    """What is wrong with the folder of PATH, a file the command writes (None when nothing): the rule of
    `wire.mcap.folder` for every file a command writes (a log, a tlog, a CSV of states), so that one
    command does not refuse a missing folder another makes: only the file's own folder may be missing
    (the command makes it, `make_folder_for`); a missing parent too is refused."""
    if path is None:
        return None
    from wire.mcap.folder import log_folder_problem

    problem = log_folder_problem(path)
    return f"{flag} {path}: {problem}" if problem else unwritable(flag, path)


def unwritable(flag: str, path: str | Path | None, *, folder: bool = False) -> str | None:
    """``FLAG PATH: cannot write there (why): ...`` when this process may not write in the folder of PATH,
    a file, or with ``folder`` in PATH itself, a folder (or make the missing levels of either); None when
    it may. The nearest existing level is the one asked (`writable`), so nothing is made here. Why, when
    it can be told: a read-only file system (a write-protected stick, a read-only mount) or a folder of
    another user's; what to do is the same either way. (A file that is there is not asked about: the
    logs are never overwritten, the next file of the set is written instead.)"""
    if path is None:
        return None
    level = os.path.abspath(path) if folder else os.path.dirname(os.path.abspath(path))
    if writable(level):
        return None
    while not os.path.lexists(level) and os.path.dirname(level) != level:
        level = os.path.dirname(level)
    why = "on a read-only file system" if _read_only(level) else f"not writable for this user ({user_name()})"
    what = "a folder" if folder else "a path in a folder"
    return f"{flag} {path}: cannot write there: {level} is {why}: give {what} you may write in"


def _read_only(path: str) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def user_name() -> str:
    """This process's user by name, as a message names who may not write somewhere; ``uid N`` for a uid
    without a passwd entry (a container's ``--user 1234``)."""
    import pwd

    try:
        return pwd.getpwuid(os.geteuid()).pw_name
    except KeyError:
        return f"uid {os.geteuid()}"


def output_folder_problem(flag: str, folder: str | Path | None) -> str | None:
    """What stops a command writing its files in FOLDER (made when missing), said before it works: a file
    in the folder's place, or a folder this user may not write in or make (`unwritable`)."""
    if folder is None:
        return None
    if Path(folder).exists() and not Path(folder).is_dir():
        return f"{flag} {folder}: a file, not a folder: give a folder (it is created)"
    return unwritable(flag, folder, folder=True)


def make_folder_for(command: str, flag: str, path: str | Path) -> None:
    """Make the missing folder of PATH (its parent exists: `made_folder_problem`), said on stderr as the
    gateway says the log's folder it makes; nothing when it is there. Raises `OSError` as `os.mkdir`."""
    from wire.mcap.folder import make_log_folder

    if folder := make_log_folder(path):
        print(f"{command}: made the folder {folder} for {flag} (it did not exist)", file=sys.stderr)


def cannot_create_in(folder: str) -> str | None:
    """Why no file can be made in the existing ``folder`` (the OS's words), or None when one can: a file
    made and removed at once. Permissions alone said yes where the filesystem says no (``/proc``, a
    read-only mount seen by root, a full disk's quota)."""
    import tempfile

    try:
        fd, name = tempfile.mkstemp(prefix=".dpgw-check-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)
    return None


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
