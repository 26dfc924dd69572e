"""The folder of a log to write: made when only its last level is missing, refused when more is.

A log's own folder missing is ordinary (``logs/`` beside a config in a fresh checkout, ``demo/`` given to
``--out``) and is made, and said. A path whose folder's parent is missing too is refused: on a vessel's PC
a mistyped path (``/var/lgo/dpgw/x.mcap``, ``/mnt/usb1/trial/x.mcap`` before the stick is mounted) would
otherwise make a tree of folders where nobody looks, as root when the gateway runs as root, and the trial's
log would be written there. ``mkdir -p`` first is the way to ask for a new tree. ``dpgw run`` (``--log``
and ``log.path``), ``dpgw demo --out`` and ``dpgw sim --out`` all hold to this rule.
"""

from __future__ import annotations

import os


def log_folder_problem(path: str | os.PathLike[str]) -> str | None:
    """Why the folder of the log ``path`` cannot be used, or None: neither the folder nor its parent
    exists. Says what to do."""
    folder = os.path.dirname(os.path.abspath(path))
    parent = os.path.dirname(folder)
    if os.path.lexists(folder) or os.path.lexists(parent):
        return None  # (a file in the folder's place, or in its parent's, is for the opening to say)
    return (
        f"neither the folder {folder} nor its parent {parent} exists: only the file's own folder is made, "
        f"so that a mistyped path does not make folders; check the path, or make it first (mkdir -p {folder})"
    )


def log_folder_blocked(path: str | os.PathLike[str]) -> str | None:
    """The file that stands where the log ``path``'s folder (or that folder's parent) must be, or None.
    Nothing that happens at start-up clears it (a service's ``LogsDirectory`` makes a missing folder, not
    one that a file holds), so a check of the config calls it a problem, not a note."""
    folder = os.path.dirname(os.path.abspath(path))
    for level in (folder, os.path.dirname(folder)):
        if os.path.lexists(level) and not os.path.isdir(level):
            return level
    return None


def make_log_folder(path: str | os.PathLike[str]) -> str | None:
    """Make the folder of the log ``path`` when it is missing and its parent exists; the folder made, or
    None when it was there. Raises `OSError` as `os.mkdir` does (a file in its place: `FileExistsError`),
    and `FileNotFoundError` when more than the last level is missing (`log_folder_problem`)."""
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(folder):
        return None
    if problem := log_folder_problem(path):
        raise FileNotFoundError(problem)
    os.mkdir(folder)
    return folder
