"""A command stopped by a signal: how the console names the signal, and the signals noted while a run
goes on so that it ends at a step of its own choosing, its files complete.

SIGINT (Ctrl-C) and SIGTERM (``kill``, ``timeout``, ``systemctl stop``) are noted; SIGHUP (the terminal or
SSH session closed) comes through `dpgw.cli.hangup_as_terminate` as SIGTERM's handler, with its own
number. The handlers that were there are given back on the way out: `dpgw.cli.main` also runs in-process
(tests, a notebook), whose handlers stay theirs.
"""

from __future__ import annotations

import signal
import threading
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


def set_from_handler(*events: threading.Event) -> None:
    """Set ``events`` from a signal handler without taking their locks in it.

    A handler runs in the main thread between two of its bytecodes, which may be inside that thread's own
    `threading.Event.set` or `wait` of the same event, holding the event's lock (not reentrant). Set there,
    the handler waits for the main thread, which waits for the handler: for ever, and every later signal
    nests another wait (seen: `dpgw run` deaf to SIGINT and SIGTERM, its log without its end, after a
    second SIGINT came as it was stopping). A thread of its own sets them once the main thread lets go."""
    pending = [e for e in events if not e.is_set()]  # (is_set takes no lock)
    if pending:
        threading.Thread(target=_set_all, args=(pending,), name="dpgw-signal", daemon=True).start()


def _set_all(events: list[threading.Event]) -> None:
    for e in events:
        e.set()
