"""Simulation time from the simulator's clock ticks (`wire.messages.SimClock` on ``<prefix>/sim/clock``).

The ROS ``/clock`` + ``use_sim_time`` convention: with ``[time] clock = "sim"`` the gateway stamps what it
receives with the plant's time, not its own, so a simulator that falls behind (a busy machine) slows the
whole loop down instead of pulling the estimate's time base away from the truth's.

A chunk received at monotonic instant ``w`` is stamped

    s_k + min(rate · (w − w_k), period)

where ``(w_k, s_k)`` is the last tick received at or before ``w`` (receive instant, sim time), ``rate``
is the simulation rate observed over the ticks of the last `RATE_WINDOW_NS` of wall time (sim ns per
wall ns), and ``period`` the simulator's longest spacing between ticks (the tick's ``period_s``). So a
stamp is exact at a tick, follows the simulation between ticks, and never runs more than one tick ahead of
the newest tick received, however late the next one is. Stamps handed out are also never smaller than
the one before (the pipeline's time does not go back when two sources' chunks are handled out of receive
order, or when the observed rate overshot a tick that came late).

Before the first tick there is no simulation time: `stamp` returns None and the caller holds the data
(the service releases it, stamped with the first tick's time, when the first tick comes).

A tick more than `RESTART_BACK_NS` behind the newest is a simulator that started again (a bench restarts
`dpgw sim` under a running gateway; its time starts again from its epoch): `went_back` keeps the first
such jump. Its data belongs to another run of the plant: the service does not stamp it onto this one (every
chunk would get this run's last time, Δt = 0, and the observer a second vessel's measurements), it counts
it and alarms until the gateway is restarted. A tick a little behind (two Zenoh threads' callbacks
swapped) is only ignored.
"""

from __future__ import annotations

import threading
from bisect import bisect_left, bisect_right

__all__ = ["RATE_WINDOW_NS", "RESTART_BACK_NS", "SimTime"]

RATE_WINDOW_NS = 1_000_000_000
"""Wall time over which the simulation rate is measured: long enough to average the simulator thread's
scheduling jitter, short enough to follow a change of speed within a second."""
RESTART_BACK_NS = 1_000_000_000
"""A tick this far (sim ns) behind the newest is a restarted simulator, not two ticks swapped in delivery
(those are a tick period apart, 0.05 s)."""
_KEEP_TICKS = 16384
"""Ticks kept (about 20 s at 10x with a tick per event): a chunk that waited in the queue that long on a
busy machine is still stamped from the ticks around its receive instant."""


class SimTime:
    """Maps monotonic receive instants (ns) to simulation time (UTC ns); thread-safe (ticks arrive on
    Zenoh's threads, stamps are asked for by the service's consumer)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._mono: list[int] = []  # receive instants of the ticks kept, ascending
        self._sim: list[int] = []  # their simulation times, ascending
        self._period_ns = 0
        self._last_out: int | None = None
        self.ticks = 0
        """Ticks taken."""
        self.ignored = 0
        """Ticks ignored: going back in time (a restarted simulator) or not a valid tick."""
        self.went_back: tuple[int, int] | None = None
        """(newest simulation time, the tick's) of the first tick that went back more than
        `RESTART_BACK_NS`: the simulator started again; None while it has not."""

    @property
    def started(self) -> bool:
        """A tick has arrived: stamps exist."""
        return self.ticks > 0

    def on_tick(self, sim_ns: int, period_s: float, mono_ns: int) -> None:
        """A tick received at monotonic ``mono_ns``: the simulation is at ``sim_ns`` (UTC ns)."""
        with self._lock:
            if not (period_s > 0.0) or (self._sim and sim_ns < self._sim[-1]):
                self.ignored += 1
                if period_s > 0.0 and sim_ns < self._sim[-1] - RESTART_BACK_NS and self.went_back is None:
                    self.went_back = (self._sim[-1], sim_ns)
                return
            if self._mono and mono_ns < self._mono[-1]:
                mono_ns = self._mono[-1]  # callbacks of two Zenoh threads may swap; keep the order
            self._mono.append(mono_ns)
            self._sim.append(sim_ns)
            if len(self._mono) > 2 * _KEEP_TICKS:  # amortised trim
                del self._mono[:-_KEEP_TICKS]
                del self._sim[:-_KEEP_TICKS]
            self._period_ns = round(period_s * 1e9)
            self.ticks += 1

    def silent_since(self, mono_ns: int, gap_ns: int) -> bool:
        """No tick has come from ``gap_ns`` before ``mono_ns`` until now: something received at ``mono_ns``
        came while the clock was silent, and nothing has said since which run of the plant it belongs to
        (a paused simulator's, or a restarted one's whose ticks are not through yet)."""
        with self._lock:
            return bool(self._mono) and self._mono[-1] < mono_ns - gap_ns

    def silent_s(self, mono_ns: int) -> float | None:
        """Wall seconds since the last tick (None before the first)."""
        with self._lock:
            return (mono_ns - self._mono[-1]) / 1e9 if self._mono else None

    def rate(self) -> float:
        """Simulation seconds per wall second over the last `RATE_WINDOW_NS` (0.0 before two ticks apart
        in wall time)."""
        with self._lock:
            return self._rate(len(self._mono) - 1) if self._mono else 0.0

    def _rate(self, k: int) -> float:
        """The rate over the window of wall time ending at tick ``k``."""
        w_k = self._mono[k]
        i = min(bisect_left(self._mono, w_k - RATE_WINDOW_NS), k)
        return (self._sim[k] - self._sim[i]) / (w_k - self._mono[i]) if w_k > self._mono[i] else 0.0

    def _at(self, mono_ns: int) -> int | None:
        if not self._mono:
            return None
        # the last tick received at or before mono_ns (before every tick kept: the oldest, exactly)
        k = max(bisect_right(self._mono, mono_ns) - 1, 0)
        ahead = min(self._rate(k) * max(mono_ns - self._mono[k], 0), self._period_ns)
        return min(self._sim[k] + round(ahead), self._sim[-1] + self._period_ns)

    def now(self, mono_ns: int) -> int | None:
        """Simulation time at ``mono_ns`` without handing out a stamp (for ticks and status); None before
        the first tick."""
        with self._lock:
            t = self._at(mono_ns)
            if t is not None and self._last_out is not None:
                t = max(t, self._last_out)
            return t

    def stamp(self, mono_ns: int) -> int | None:
        """The stamp of something received at ``mono_ns``: never less than the last stamp handed out;
        None before the first tick."""
        with self._lock:
            t = self._at(mono_ns)
            if t is None:
                return None
            if self._last_out is not None and t < self._last_out:
                t = self._last_out
            self._last_out = t
            return t
