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
`dpgw sim` under a running gateway; its time starts again from its epoch): a new run of the plant. Its
ticks gather apart (`went_back` says so, `restart_mono_ns` when its first tick came) while the stamps still
come from the run being handled, so what the consumer still has of the old run, received before the new
run's first tick, is stamped on the old run's time. The consumer `follow`s the new run when it reaches the
new run's data: from then on stamps come from the new run's ticks only, anchored on its first (what was
received before it, stamped with its time exactly, as before the first tick of all), and they start again
from there (stamps never go back within a run). A tick a little behind (two Zenoh threads' callbacks
swapped) is only ignored, and so is a tick of the old run delivered after the new run's first (swapped
the same way at the restart: near the old run's newest, far ahead of the new run's).

Which simulator: a tick carries its run's identity (`SimClock.run`, drawn when the simulator starts; 0 from
one that does not say, told by its times as above among its own kind; beside or after one that says, 0 is
another run like any other identity, since a simulator never changes whether it says during a run).
Another run's tick is another simulator publishing on the same key (two benches sharing a prefix) when
the run being stamped ticks on after it: ignored and counted (`foreign`), never a restart; when the run
being stamped stays silent for `FOREIGN_SILENT_NS` it is a new run, from its first tick, whichever way
its time goes. A run never starts again
(its own tick far back is a bad tick), and a late tick of the run a restart left
is ignored. A gateway that knows its simulator's run `pin`s it: every other tick (of a run that does not
say, 0, too) is another simulator's, and what it took of another run before the pin is dropped.
"""

from __future__ import annotations

import threading
import time
from bisect import bisect_left, bisect_right

__all__ = ["FOREIGN_SILENT_NS", "RATE_WINDOW_NS", "RESTART_BACK_NS", "SimTime"]

RATE_WINDOW_NS = 1_000_000_000
"""Wall time over which the simulation rate is measured: long enough to average the simulator thread's
scheduling jitter, short enough to follow a change of speed within a second."""
RESTART_BACK_NS = 1_000_000_000
"""A tick this far (sim ns) behind the newest is a restarted simulator, not two ticks swapped in delivery
(those are a tick period apart, 0.05 s)."""
FOREIGN_SILENT_NS = 2_000_000_000
"""A tick of another run (another `SimClock.run`) while the run being stamped ticked within this much wall
time is kept apart until it is known whose it is: another simulator's clock on the same key once the run
being stamped ticks again after it (ignored and counted, `SimTime.foreign`); once the run being stamped
has been silent this long, a new run (a restarted simulator) from its first tick. A bench restarts
`dpgw sim` within this (its clock is up 0.9 s after the start): counted at once, the new run's first
ticks were lost and raised the alarm of two benches on one prefix for the rest of the run."""
_KEEP_TICKS = 16384
"""Ticks kept (about 20 s at 10x with a tick per event): a chunk that waited in the queue that long on a
busy machine is still stamped from the ticks around its receive instant."""


class _Ticks:
    """The ticks kept of one run of the plant: receive instants and simulation times, both ascending, and
    the run's `SimClock.run` (0: its simulator does not say)."""

    __slots__ = ("mono", "period_ns", "run_id", "sim")

    def __init__(self, run_id: int = 0) -> None:
        self.mono: list[int] = []
        self.sim: list[int] = []
        self.period_ns = 0
        self.run_id = run_id

    def add(self, sim_ns: int, period_s: float, mono_ns: int) -> None:
        if self.mono and mono_ns < self.mono[-1]:
            mono_ns = self.mono[-1]  # callbacks of two Zenoh threads may swap; keep the order
        self.mono.append(mono_ns)
        self.sim.append(sim_ns)
        if len(self.mono) > 2 * _KEEP_TICKS:  # amortised trim
            del self.mono[:-_KEEP_TICKS]
            del self.sim[:-_KEEP_TICKS]
        self.period_ns = round(period_s * 1e9)

    def rate(self, k: int) -> float:
        """The rate over the window of wall time ending at tick ``k``."""
        w_k = self.mono[k]
        i = min(bisect_left(self.mono, w_k - RATE_WINDOW_NS), k)
        return (self.sim[k] - self.sim[i]) / (w_k - self.mono[i]) if w_k > self.mono[i] else 0.0

    def at(self, mono_ns: int) -> int | None:
        if not self.mono:
            return None
        # the last tick received at or before mono_ns (before every tick kept: the oldest, exactly)
        k = max(bisect_right(self.mono, mono_ns) - 1, 0)
        ahead = min(self.rate(k) * max(mono_ns - self.mono[k], 0), self.period_ns)
        return min(self.sim[k] + round(ahead), self.sim[-1] + self.period_ns)


class SimTime:
    """Maps monotonic receive instants (ns) to simulation time (UTC ns); thread-safe (ticks arrive on
    Zenoh's threads, stamps are asked for by the service's consumer)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._run = _Ticks()  # the run stamps come from
        self._new: _Ticks | None = None  # a new run's ticks, until the consumer follows it
        self._last_out: int | None = None
        self._left_newest: int | None = None  # the newest tick of the run the last restart left
        self.ticks = 0
        """Ticks taken (of every run)."""
        self.ignored = 0
        """Ticks ignored: a little behind the newest (swapped in delivery), a late tick of the run a restart
        left (near its newest, far ahead of the new run's), or not a valid tick."""
        self.went_back: tuple[int, int] | None = None
        """(newest simulation time of the run being stamped, the new run's first tick) while a tick went
        back more than `RESTART_BACK_NS` (the simulator started again) and the new run is not followed
        yet; None otherwise."""
        self.restart_mono_ns = 0
        """The receive instant of the new run's first tick (while `went_back` is set)."""
        self.runs = 1
        """Runs of the plant stamped so far: 1, and one more at each `follow`."""
        self._left_id = 0  # the run the last restart left
        self.foreign = 0
        """Ticks of another simulator's run, ignored: they came while the run being stamped was ticking."""
        self.foreign_run = 0
        """The `SimClock.run` of the last such tick."""
        self.foreign_mono_ns = 0
        """When the last such tick was received (monotonic ns; 0 before any): whether the other simulator
        still ticks."""
        self._pinned = False  # `pin`: one run only
        self._cand: _Ticks | None = None  # another run's ticks while the run followed may still tick

    @property
    def run_id(self) -> int:
        """The `SimClock.run` of the run being stamped (0: its simulator does not say)."""
        return self._run.run_id

    def pin(self, run_id: int) -> None:
        """Follow run ``run_id`` only, from its first tick on: every other run's tick is another
        simulator's, whenever it comes, a simulator that does not say its run (0) among them. For a
        gateway that knows its simulator's run (`dpgw demo` publishes the clock itself); a gateway that
        does not follows the first run it hears. Ticks of another run taken before the pin (the clock is
        subscribed to before the publisher whose run is pinned exists) are dropped and counted as
        another simulator's: kept, they were the run followed, and every tick of the pinned run going
        back from them was ignored as a bad tick of that run."""
        with self._lock:
            if self.ticks and (self.run_id != run_id or self._new is not None):
                self.foreign += self.ticks
                dropped = self._new if self._new is not None else self._run
                self.foreign_run = dropped.run_id
                self.foreign_mono_ns = dropped.mono[-1] if dropped.mono else time.monotonic_ns()
                self._new = None
                self._last_out = self._left_newest = self.went_back = None
                self._left_id = 0
                self.ticks = 0
            self._cand = None
            self._run = _Ticks(run_id) if self.ticks == 0 else self._run
            self._pinned = True

    @property
    def started(self) -> bool:
        """A tick has arrived: stamps exist."""
        return self.ticks > 0

    def on_tick(self, sim_ns: int, period_s: float, mono_ns: int, run_id: int = 0) -> None:
        """A tick received at monotonic ``mono_ns``: the simulation is at ``sim_ns`` (UTC ns); ``run_id`` the
        `SimClock.run` of the simulator's run (0: not said)."""
        with self._lock:
            if not (period_s > 0.0):
                self.ignored += 1
                return
            if self._pinned and run_id != self.run_id:  # (0 too: a simulator that does not say)
                self.foreign += 1
                self.foreign_run, self.foreign_mono_ns = run_id, mono_ns
                return
            run = self._run if self._new is None else self._new
            current = run.run_id
            if run.sim and run_id != current:
                # another run's tick (0 and an identity differ too: a simulator never changes whether it
                # says during a run): a tick of the run a restart left, delivered late; another simulator
                # on this key while the run followed still ticks (two benches sharing a prefix, one
                # perhaps older); or, the run followed silent, a restarted simulator, whichever way its
                # time goes
                if run_id == self._left_id and (
                    run_id
                    or (self._left_newest is not None and abs(sim_ns - self._left_newest) <= RESTART_BACK_NS)
                ):
                    self.ignored += 1
                    return
                cand = self._cand if self._cand is not None and self._cand.run_id == run_id else None
                if mono_ns - run.mono[-1] > FOREIGN_SILENT_NS:
                    # the run followed silent: a new run, from its first tick (gathered while it was
                    # not known yet whether the run followed would tick again)
                    first_sim, first_mono = (cand.sim[0], cand.mono[0]) if cand else (sim_ns, mono_ns)
                    self._begin_new_run(first_sim, first_mono, run, run_id)
                    if cand is not None:
                        self._new, self._cand = cand, None
                        self.ticks += len(cand.sim)
                    self._add(sim_ns, period_s, mono_ns)
                    return
                if cand is None and self._cand is None:
                    # the run followed ticked within the silence: another simulator's, if it ticks again
                    # after this (the two then tick side by side); a restarted simulator's, if not (a
                    # bench restarts `dpgw sim` within a second)
                    cand = self._cand = _Ticks(run_id)
                if cand is not None:
                    cand.add(sim_ns, period_s, mono_ns)
                    return
                self.foreign += 1  # (a third simulator, while another is a candidate)
                self.foreign_run, self.foreign_mono_ns = run_id, mono_ns
                return
            if self._cand is not None and run.sim and mono_ns >= self._cand.mono[0]:
                # the run followed ticks on after the other's first tick: the other is another simulator
                self.foreign += len(self._cand.sim)
                self.foreign_mono_ns = self._cand.mono[-1]
                self.foreign_run, self._cand = self._cand.run_id, None
            if run_id and not run.sim:  # the first tick of the run being gathered: who it is
                run.run_id = run_id
            if run.sim and sim_ns < run.sim[-1]:
                if sim_ns >= run.sim[-1] - RESTART_BACK_NS:
                    self.ignored += 1  # two ticks swapped in delivery
                    return
                if run_id and run_id == current:  # the same run cannot start again: a bad tick
                    self.ignored += 1
                    return
                # the simulator started again (again: the newest restart is the one to follow)
                run = self._begin_new_run(sim_ns, mono_ns, run, run_id)
            elif (
                run.sim
                and sim_ns > run.sim[-1] + RESTART_BACK_NS
                and self._left_newest is not None
                and abs(sim_ns - self._left_newest) <= RESTART_BACK_NS
            ):
                # a tick of the run just left, delivered after the new run's first (swapped like above):
                # not the new run jumping ahead, whose next tick would look like another restart
                self.ignored += 1
                return
            run.add(sim_ns, period_s, mono_ns)
            self.ticks += 1

    def _begin_new_run(self, sim_ns: int, mono_ns: int, run: _Ticks, run_id: int) -> _Ticks:
        """A new run's first tick came (with the lock held): gather its ticks apart until it is followed."""
        self.went_back = (self._run.sim[-1], sim_ns)
        self.restart_mono_ns = mono_ns
        self._left_newest = run.sim[-1]
        self._left_id = run.run_id
        self._new = _Ticks(run_id)
        self._cand = None  # (of the run left)
        return self._new

    def _add(self, sim_ns: int, period_s: float, mono_ns: int) -> None:
        assert self._new is not None
        self._new.add(sim_ns, period_s, mono_ns)
        self.ticks += 1

    def of_new_run(self, mono_ns: int, gap_ns: int) -> bool:
        """While a new run waits to be followed: something received at ``mono_ns`` is of it, having come
        after its first tick, or after ``gap_ns`` without a tick of the run being stamped (between the old
        run's last tick and the new run's first: it cannot be the old run's, whose ticks had stopped)."""
        with self._lock:
            if self._new is None:
                return False
            return mono_ns >= self.restart_mono_ns or self._run.mono[-1] < mono_ns - gap_ns

    def follow(self) -> tuple[int, int]:
        """Stamp from the new run's ticks from now on (call while `went_back` is set); returns what
        `went_back` said."""
        with self._lock:
            assert self._new is not None and self.went_back is not None
            went_back, self.went_back = self.went_back, None
            self._run, self._new = self._new, None
            self._last_out = None
            self.runs += 1
            return went_back

    def silent_since(self, mono_ns: int, gap_ns: int) -> bool:
        """No tick has come from ``gap_ns`` before ``mono_ns`` until now: something received at ``mono_ns``
        came while the clock was silent, and nothing has said since which run of the plant it belongs to
        (a paused simulator's, or a restarted one's whose ticks are not through yet)."""
        with self._lock:
            return bool(self._run.mono) and self._newest_mono() < mono_ns - gap_ns

    def silent_s(self, mono_ns: int) -> float | None:
        """Wall seconds since the last tick (of any run; None before the first)."""
        with self._lock:
            return (mono_ns - self._newest_mono()) / 1e9 if self._run.mono else None

    def _newest_mono(self) -> int:
        return self._new.mono[-1] if self._new is not None else self._run.mono[-1]

    def rate(self) -> float:
        """Simulation seconds per wall second over the last `RATE_WINDOW_NS` (0.0 before two ticks apart
        in wall time)."""
        with self._lock:
            return self._run.rate(len(self._run.mono) - 1) if self._run.mono else 0.0

    def now(self, mono_ns: int) -> int | None:
        """Simulation time at ``mono_ns`` without handing out a stamp (for ticks and status); None before
        the first tick."""
        with self._lock:
            t = self._run.at(mono_ns)
            if t is not None and self._last_out is not None:
                t = max(t, self._last_out)
            return t

    def stamp(self, mono_ns: int) -> int | None:
        """The stamp of something received at ``mono_ns``: never less than the last stamp handed out (in
        this run); None before the first tick."""
        with self._lock:
            t = self._run.at(mono_ns)
            if t is None:
                return None
            if self._last_out is not None and t < self._last_out:
                t = self._last_out
            self._last_out = t
            return t
