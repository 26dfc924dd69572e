"""The progress bar of a command's long work (a simulation, a replay, an open-loop run, a capability
plot): on a terminal only, never with ``--json`` (a program reads stdout, a person is not watching), and
on stderr, so that stdout stays the command's result."""

from __future__ import annotations

import sys
from typing import Any


def terminal_bar(total: float | None, unit: str, *, json: bool = False, leave: bool = True) -> Any:
    """A tqdm bar counting ``unit`` up to ``total`` (None: no end known), or None where none is shown:
    stderr not a terminal, or ``json``. tqdm is imported only when a bar is drawn."""
    if json or not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(
        total=None if total is None else round(total),
        unit=unit,
        file=sys.stderr,
        dynamic_ncols=True,
        leave=leave,
    )
