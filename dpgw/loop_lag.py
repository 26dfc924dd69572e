"""How far the gateway is behind the simulator, in sim seconds, for `dpgw demo`'s pacing.

The simulator knows when it sent each burst (sim time) and how many bytes; the gateway counts the bytes
it has handled from each source and knows the stamp of the newest chunk (sim time too, on
``clock = "sim"``). The lag is the age of the oldest burst sent and not yet handled: whatever held it up
(the kernel's buffers, a pty, a reader thread that did not get the CPU, the gateway's queue) shows. A
source that sent nothing new contributes nothing, so a slow sensor (DGPS at 1 Hz) is not mistaken for a
late one.

Both methods are called from the simulator's thread (the sinks' writes and the clock publisher); the
gateway's counters are only read.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from simulator.clock import SimEpoch
from simulator.transports import Sink

__all__ = ["LoopLag", "WatchedSink"]


class LoopLag:
    """``received(source)``: (the stamp, UTC ns, of the newest chunk the gateway handled from it, or None;
    the bytes it has handled from it)."""

    def __init__(
        self, epoch: SimEpoch, received: Callable[[str], tuple[int | None, int]], *, tolerance_s: float = 0.05
    ) -> None:
        self.epoch = epoch
        self.received = received
        self.tolerance_s = tolerance_s
        """A burst also counts as handled when the gateway has handled something stamped at most this much
        before it (a transport that changes the byte count, such as a pty's line discipline, is then still
        followed)."""
        self._unhandled: dict[str, deque[tuple[float, int]]] = {}  # (sim time sent, bytes sent after it)
        self._sent_bytes: dict[str, int] = {}

    def sent(self, source: str, t: float, n_bytes: int) -> None:
        """The simulator sent ``n_bytes`` of ``source``'s at sim time ``t``."""
        total = self._sent_bytes.get(source, 0) + n_bytes
        self._sent_bytes[source] = total
        q = self._unhandled.setdefault(source, deque())
        if q and q[-1][0] == t:  # one entry per instant (a burst is several writes)
            q[-1] = (t, total)
        else:
            q.append((t, total))

    def lag_s(self, now: float) -> float:
        """Sim seconds the oldest unhandled burst has waited at sim time ``now`` (0.0 when none waits)."""
        lag = 0.0
        for source, q in self._unhandled.items():
            stamp, n_bytes = self.received(source)
            handled = -1.0 if stamp is None else (stamp - self.epoch.start_ns) / 1e9 + self.tolerance_s
            # handled: every byte of it counted (exact, whatever the stamps), or something as late handled
            while q and (q[0][1] <= n_bytes or q[0][0] <= handled):
                q.popleft()
            if q:
                lag = max(lag, now - q[0][0])
        return lag


class WatchedSink(Sink):
    """A sink that tells a `LoopLag` when it sends (``now()``: the simulation's time)."""

    def __init__(self, inner: Sink, source: str, lag: LoopLag, now: Callable[[], float]) -> None:
        super().__init__()
        self.inner = inner
        self.source = source
        self.lag = lag
        self.now = now

    def write(self, data: bytes) -> None:
        self.lag.sent(self.source, self.now(), len(data))
        self.inner.write(data)

    def describe(self) -> str:
        return self.inner.describe()

    def close(self) -> None:
        self.inner.close()
