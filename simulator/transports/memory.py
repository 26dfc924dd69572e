"""An in-memory sink for tests: keeps what is written, replays what a test feeds as peer input."""

from __future__ import annotations

from simulator.transports.base import Sink


class MemorySink(Sink):
    """Keeps everything written in ``data``; ``feed`` queues bytes for `read_available`. For tests."""

    def __init__(self) -> None:
        super().__init__()
        self.data = bytearray()
        self._incoming: list[bytes] = []

    def write(self, data: bytes) -> None:
        self._check_open()
        self.data += data
        self.bytes_written += len(data)

    def feed(self, data: bytes) -> None:
        """Queue ``data`` as if a peer had sent it."""
        self._incoming.append(bytes(data))

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        items, self._incoming = self._incoming, []
        return [("memory", chunk) for chunk in items]

    def describe(self) -> str:
        return "memory"
