"""What every simulator sink shares: the `Sink` interface and its counters, and `TransportError` for
mistakes a person must fix. The sinks live in their own modules (`memory`, `pty`, `serial`, `udp`, `tcp`,
`file`); `url` turns a URL into one of them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType
from typing import Self

READ_CHUNK = 65536
MAX_READS_PER_PEER = 16  # per read call: bounds the time spent on a flooding peer


class TransportError(Exception):
    """A transport that cannot work as configured: the message names the URL and what to do."""

    def __init__(self, url: str, problem: str, fix: str = "") -> None:
        self.url = url
        self.problem = problem
        self.fix = fix
        super().__init__(f"{url}: {problem}" + (f" — {fix}" if fix else ""))


class Sink(ABC):
    """Where simulated hardware writes its bytes, and where bytes from its peers come back.

    Counters (plain ints, reset never):

    * ``bytes_written`` — bytes the operating system accepted (for a TCP server: summed over clients).
    * ``writes_dropped`` — writes not delivered, counted per peer (a TCP write that two clients could not
      take counts 2). A write with nobody to deliver it to (a TCP server with no client) is not a drop.
    * ``bytes_dropped`` — bytes of those writes, plus data discarded later (a pty's stale input, the
      backlog of a TCP client that is disconnected for being too slow).
    * ``last_error`` — the last OS error that caused a drop, as text (``None`` if there was none).
    """

    def __init__(self) -> None:
        self.bytes_written = 0
        self.writes_dropped = 0
        self.bytes_dropped = 0
        self.last_error: str | None = None
        self._closed = False

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Send ``data`` (one sentence, one frame or one burst) to the peers; never blocks for long."""

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        """Bytes that came back from peers since the last call, as ``(peer, bytes)`` items; non-blocking.

        UDP: one item per datagram; TCP: one item per client that sent something; pty and serial: one item.
        Keep peers apart when several may send at once (a MAVLink frame must not be spliced from two).
        """
        return []

    def read_available(self) -> bytes:
        """All bytes that came back from peers since the last call, concatenated; ``b""`` if none."""
        return b"".join(chunk for _, chunk in self.read_from_peers())

    def poll(self) -> None:  # noqa: B027 — optional hook, deliberately empty by default
        """Service peers without writing: accept waiting TCP clients, send what a busy peer could not take."""

    @abstractmethod
    def describe(self) -> str:
        """A one-line description a person can act on, e.g. the pty device to open."""

    def close(self) -> None:
        """Release the transport. Idempotent."""
        self._closed = True

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def bytes_pending(self) -> int:
        """Bytes taken by ``write`` that wait in user space for a busy peer (neither written nor dropped)."""
        return 0

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"I/O on a closed sink ({self.describe()})")

    def _drop(self, nbytes: int, error: str | None = None) -> None:
        self.writes_dropped += 1
        self.bytes_dropped += nbytes
        if error is not None:
            self.last_error = error

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return (
            f"<{type(self).__name__} {self.describe()} {state} bytes_written={self.bytes_written} "
            f"writes_dropped={self.writes_dropped}>"
        )
