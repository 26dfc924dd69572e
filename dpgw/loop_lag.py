"""How far the gateway is behind the simulator, in sim seconds, for `dpgw demo`'s pacing.

The simulator knows when it sent each burst (sim time); the gateway knows the stamp of the newest chunk it
has handled from each source (sim time too, on ``clock = "sim"``). The lag is the age of the oldest burst
sent and not yet handled: whatever held it up — the kernel's buffers, a pty, a reader thread that did not
get the CPU, the gateway's queue — it shows. A source that sent nothing new contributes nothing, so a
slow sensor (DGPS at 1 Hz) is not mistaken for a late one.

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
    """``received(source)``: the stamp (UTC ns) of the newest chunk the gateway handled from it, or None."""

    def __init__(
        self, epoch: SimEpoch, received: Callable[[str], int | None], *, tolerance_s: float = 0.05
    ) -> None:
        self.epoch = epoch
        self.received = received
        self.tolerance_s = tolerance_s
        """A burst counts as handled when the gateway has handled something stamped at most this much
        before it: a stamp interpolated from the tick before (when the tick's delivery was slower than
        the data's) can be a little early, never more than a tick."""
        self._unhandled: dict[str, deque[float]] = {}

    def sent(self, source: str, t: float) -> None:
        """The simulator sent ``source``'s bytes at sim time ``t``."""
        q = self._unhandled.setdefault(source, deque())
        if not q or q[-1] != t:  # one entry per instant (a burst is several writes)
            q.append(t)

    def lag_s(self, now: float) -> float:
        """Sim seconds the oldest unhandled burst has waited at sim time ``now`` (0.0 when none waits)."""
        lag = 0.0
        for source, q in self._unhandled.items():
            stamp = self.received(source)
            if stamp is not None:
                handled = (stamp - self.epoch.start_ns) / 1e9 + self.tolerance_s
                while q and q[0] <= handled:
                    q.popleft()
            if q:
                lag = max(lag, now - q[0])
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
        self.lag.sent(self.source, self.now())
        self.inner.write(data)

    def describe(self) -> str:
        return self.inner.describe()

    def close(self) -> None:
        self.inner.close()
