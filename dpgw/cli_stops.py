"""A command stopped by a signal: how the console names the signal, and the signals noted while a run
goes on so that it ends at a step of its own choosing, its files complete.

SIGINT (Ctrl-C) and SIGTERM (``kill``, ``timeout``, ``systemctl stop``) are noted; SIGHUP (the terminal or
SSH session closed) comes through `dpgw.cli.hangup_as_terminate` as SIGTERM's handler, with its own
number. The handlers that were there are given back on the way out: `dpgw.cli.main` also runs in-process
(tests, a notebook), whose handlers stay theirs.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager

STOPPED_BY = {"SIGINT": "Ctrl-C"}
"""Signals a summary names otherwise than by their names."""


def stop_name(signum: int) -> str:
    """How a summary names the signal that stopped a run: Ctrl-C for SIGINT, else its name."""
    name = signal.Signals(signum).name
    return STOPPED_BY.get(name, name)


@contextmanager
def signals_noted() -> Iterator[list[int]]:
    """SIGINT and SIGTERM noted instead of obeyed at once: the list yielded holds the last one's number
    (empty while none came), for the run to look at between its steps."""
    caught: list[int] = []

    def note(signum: int, _frame: object) -> None:
        caught[:1] = [signum]

    previous = {sig: signal.signal(sig, note) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield caught
    finally:
        for sig, handler in previous.items():
            if handler is not None:  # (None: installed outside Python, cannot be put back from here)
                signal.signal(sig, handler)
