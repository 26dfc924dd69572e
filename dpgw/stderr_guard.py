"""stderr that a reader going away cannot break: a command's diagnostics are for a person, never a reason
to stop or hang it.

`dpgw demo 2>&1 | head -2` closed the pipe after two lines; the demo's next line to stderr raised
`BrokenPipeError` between the gateway's start and the code that stops it, the command returned with the
gateway's threads still running, and the process hung at exit. A gateway at sea whose console goes
away (a terminal closed, a pipe to a pager quit) must not fail the same way. So stderr is wrapped: the
first write that finds the reader gone points the descriptor at /dev/null and every write after it,
that one included, goes nowhere, silently. stdout is left as it is: what a program reads there
(`dpgw listen --json | head -3`) stops the command when its reader stops reading (`dpgw.cli.main`).
"""

from __future__ import annotations

import errno
import os
from typing import Any, TextIO


class StderrGuard:
    """A text stream forwarding to ``stream`` until its reader is gone (EPIPE), then to nothing."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.gone = False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                return self.stream.write(text)
            except OSError as exc:
                self._lost(exc)
        return len(text)

    def flush(self) -> None:
        if not self.gone:
            try:
                self.stream.flush()
            except OSError as exc:
                self._lost(exc)

    def _lost(self, exc: OSError) -> None:
        if not isinstance(exc, BrokenPipeError) and exc.errno != errno.EPIPE:
            raise exc
        self.gone = True
        try:  # what the stream's buffer still holds, and the interpreter's last flush, go nowhere too
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self.stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):  # (a test's capture has no descriptor)
            pass

    def __getattr__(self, name: str) -> Any:  # fileno, isatty, encoding, ...: the stream's own
        return getattr(self.stream, name)
