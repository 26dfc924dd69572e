"""A pseudo-terminal sink (``pty``, ``pty:///PATH/TO/LINK``): any serial program can read the simulator."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import math
import os
import socket
import struct
import sys
import termios
import time

from simulator.transports.base import TransportError
from simulator.transports.fd import FdSink, make_raw


def _queued(fd: int, request: int) -> int:
    """Bytes in a tty's input (TIOCINQ) or output (TIOCOUTQ) queue; 0 if the driver cannot tell."""
    try:
        raw = fcntl.ioctl(fd, request, b"\0\0\0\0")
    except OSError:
        return 0
    return int(struct.unpack("i", raw)[0])


class PtySink(FdSink):
    """A pseudo-terminal: the simulator holds the master; a serial program opens ``device`` (the slave).

    The slave is put in raw mode so bytes pass unchanged. The sink keeps its own descriptor on the slave so
    the pty lives on while readers come and go (without it the master gets EIO once the last reader
    closes). With ``link``, a symlink ``link -> device`` is made (an existing symlink there is replaced;
    any other file is an error) and removed on close if it still points at this pty. A link another
    running program serves (`claim_link`: a second simulator started on a running bench's link) is
    refused rather than taken over.

    When no reader drains the pty the kernel's buffer (some tens of KiB) fills and writes are dropped
    whole. When the pty's input has not once been empty for ``stale_s`` seconds (checked at each write),
    it is discarded (counted in ``bytes_dropped`` and ``stale_flushes``), so a reader that opens the pty
    late gets current sentences, as from a sensor on a serial line, not a backlog of old ones. A reader
    that keeps up empties the input within milliseconds and is never affected. ``stale_s=None`` keeps
    everything.
    """

    def __init__(
        self, link: str | None = None, *, stale_s: float | None = 2.0, url: str | None = None
    ) -> None:
        self.url = url or ("pty" if link is None else f"pty://{link}")
        if stale_s is not None and not (math.isfinite(stale_s) and stale_s > 0):
            raise TransportError(self.url, f"stale_s must be a positive number of seconds, got {stale_s!r}")
        master, slave = os.openpty()
        try:
            make_raw(slave)
            os.set_blocking(master, False)
            self.device = os.ttyname(slave)
        except OSError as exc:
            os.close(master)
            os.close(slave)
            raise TransportError(self.url, f"cannot set up the pty: {exc.strerror or exc}") from exc
        super().__init__(master)
        self._slave = slave
        self.stale_s = stale_s
        #: times stale input was discarded
        self.stale_flushes = 0
        self._last_drained = time.monotonic()
        self.link: str | None = None
        self._claim: socket.socket | None = None
        if link is not None:
            try:
                self._claim = claim_link(link, self.url)
                self.link = _make_symlink(link, self.device, self.url)
            except BaseException:
                if self._claim is not None:
                    self._claim.close()
                os.close(master)
                os.close(slave)
                raise

    def _before_write(self) -> None:
        if self.stale_s is None:
            return
        now = time.monotonic()
        waiting = _queued(self._slave, termios.TIOCINQ)
        if waiting == 0:
            self._last_drained = now
        elif now - self._last_drained > self.stale_s:
            # Nobody has emptied the input for stale_s: discard it (and the tail of a write whose head
            # went with it), as a serial line loses what is sent while nobody listens.
            termios.tcflush(self._slave, termios.TCIFLUSH)
            self.bytes_dropped += waiting + len(self._pending)
            self._pending.clear()
            self.stale_flushes += 1
            self._last_drained = now

    def describe(self) -> str:
        return f"{self.link} -> {self.device}" if self.link else self.device

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        if self.link is not None:
            with contextlib.suppress(OSError):
                if os.readlink(self.link) == self.device:
                    os.unlink(self.link)
        for fd in (self._fd, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        if self._claim is not None:
            self._claim.close()


def claim_link(link: str, url: str) -> socket.socket | None:
    """Claim the link path for this process while it serves it: a Linux abstract Unix socket named after
    the absolute path (no file is made, and the kernel releases it when the process ends, however it
    ends). A second simulator started with the same link while the first runs replaced the first's link
    (the gateway's next reopen read the wrong pty, or none) and, stopping, removed it: a bench that was
    running lost its gyro. Refused instead, naming the link. A link left by a program that has ended
    (``kill -9``) is not claimed and is replaced as before. Elsewhere than Linux there is no abstract
    namespace: None (not claimed; the link is replaced)."""
    if not sys.platform.startswith("linux"):
        return None
    path = os.path.abspath(link)
    name = b"\0dpgw-pty-link:" + hashlib.sha256(path.encode()).hexdigest()[:40].encode()
    claim = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        claim.bind(name)
    except OSError as exc:
        claim.close()
        raise TransportError(
            url,
            f"{path} is the link of a pty another program is serving now (another simulator running?)",
            "stop that one first, or give this one another link path",
        ) from exc
    return claim


def _make_symlink(link: str, target: str, url: str) -> str:
    path = os.path.abspath(link)
    if os.path.lexists(path) and not os.path.islink(path):
        raise TransportError(
            url, f"{path} exists and is not a symlink", "remove it or choose another link path"
        )
    if not os.path.isdir(os.path.dirname(path)):
        raise TransportError(url, f"directory {os.path.dirname(path)} does not exist", "create it first")
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.symlink(target, tmp)
        os.replace(tmp, path)  # atomic: a reader never sees the link missing or half-made
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise TransportError(
            url, f"cannot create symlink {path}: {exc.strerror or exc}", "choose a writable directory"
        ) from exc
    return path
