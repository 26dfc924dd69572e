"""Simulation clocks: as fast as possible, or paced against the wall clock; sim time to UTC.

The simulator advances in simulation seconds (a float from ``start``, 0 by default). A clock decides how
sim time relates to the wall:

* `VirtualClock` — as fast as the CPU allows. ``sleep_until(t)`` only advances ``now()`` to ``t``; nothing
  sleeps. For tests, batch runs and writing logs.
* `RealtimeClock` — paced. Sim time ``t`` is due at wall time ``wall0 + (t - start) / speed`` on
  ``time.monotonic`` (never the adjustable system clock). Each deadline is computed from that one anchor,
  never by adding up sleeps, so rounding and oversleeping never accumulate into drift. When the
  simulation falls behind (a step took longer than its share of wall time), ``sleep_until`` returns at once
  and reports how late it was (`RealtimeClock.lag_s`, `max_lag_s`, `late_count`, a log warning when the
  lag crosses ``warn_lag_s``); the following steps run back to back until the schedule is met again.
  With ``resync_lag_s`` set, a lag beyond it (a suspended laptop, a debugger stop) is not caught up:
  the schedule is re-anchored so sim time simply continues from the late step. `set_speed` changes the
  speed from where the simulation has got to (re-anchored there: no catching up).
* `SpeedGovernor` — lowers a `RealtimeClock`'s speed (halves it, down to a floor) when the loop has been
  late by more than ``max_delay_s`` of sim time for ``persist_s`` of wall time: a machine that cannot keep
  up gets a slower simulation instead of a control loop whose delays grow with the speed.

`SimEpoch` maps sim time to the UTC date and time written in sentences (``$GPGGA`` time of day,
``$GPZDA``, MAVLink ``time_unix_usec``) and to ``stamp_ns`` (UTC ns, POSIX: no leap seconds).
"""

from __future__ import annotations

import logging
import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

__all__ = ["Clock", "RealtimeClock", "SimEpoch", "SpeedGovernor", "VirtualClock"]

log = logging.getLogger(__name__)


class Clock(ABC):
    """The simulator's notion of time: ``now()`` in sim seconds; ``sleep_until(t)`` waits until sim time t."""

    @abstractmethod
    def now(self) -> float:
        """Current sim time (s)."""

    @abstractmethod
    def sleep_until(self, t: float) -> float:
        """Wait until sim time ``t`` is due; return how late the call was (wall s; 0.0 if on time)."""


class VirtualClock(Clock):
    """As fast as possible: sim time is whatever the simulation last advanced it to. Never sleeps."""

    def __init__(self, start: float = 0.0) -> None:
        if not math.isfinite(start):
            raise ValueError(f"start must be a finite number of seconds, got {start!r}")
        self._t = float(start)

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> float:
        """Advance to ``t`` at once. Time never goes back: a ``t`` in the past leaves ``now()`` unchanged."""
        if t > self._t:
            self._t = float(t)
        return 0.0

    def __repr__(self) -> str:
        return f"VirtualClock(now={self._t!r})"


class RealtimeClock(Clock):
    """Paced: sim time runs at ``speed`` times wall time (1.0 = real time, 10.0 = ten times faster).

    The clock is anchored (sim time ``start`` ↔ the wall instant) on first use — the first ``now()`` or
    ``sleep_until()`` — or explicitly with `anchor`, so set-up work before the loop does not count as lag.

    ``monotonic`` and ``sleep`` are injectable for tests; they default to ``time.monotonic`` and
    ``time.sleep``.
    """

    def __init__(
        self,
        speed: float = 1.0,
        *,
        start: float = 0.0,
        warn_lag_s: float = 0.5,
        resync_lag_s: float | None = None,
        monotonic: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be a positive finite factor (1.0 = real time), got {speed!r}")
        if not math.isfinite(start):
            raise ValueError(f"start must be a finite number of seconds, got {start!r}")
        if resync_lag_s is not None and not resync_lag_s > 0.0:
            raise ValueError(f"resync_lag_s must be positive or None, got {resync_lag_s!r}")
        self.speed = float(speed)
        self.start = float(start)
        self.warn_lag_s = float(warn_lag_s)
        self.resync_lag_s = resync_lag_s
        self._monotonic = monotonic
        self._sleep = sleep
        self._t0 = self.start
        self._wall0: float | None = None
        self._last_t = self.start
        #: lag of the last `sleep_until` (wall s; 0.0 when it was on time)
        self.lag_s = 0.0
        #: largest lag seen (wall s)
        self.max_lag_s = 0.0
        #: number of `sleep_until` calls that arrived after their deadline
        self.late_count = 0
        #: number of times the schedule was re-anchored because the lag exceeded ``resync_lag_s``
        self.resync_count = 0
        self._warned = False

    @property
    def anchored(self) -> bool:
        return self._wall0 is not None

    def anchor(self, t_sim: float | None = None) -> None:
        """Make sim time ``t_sim`` (default: ``start``, or where the clock has got to) due now."""
        if t_sim is None:
            t_sim = self._last_t if self._wall0 is not None else self.start
        self._t0 = float(t_sim)
        self._wall0 = self._monotonic()
        self._last_t = self._t0

    def set_speed(self, speed: float) -> None:
        """Run at ``speed`` from now on, from where the simulation has got to (the lag so far is dropped,
        not caught up)."""
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be a positive finite factor (1.0 = real time), got {speed!r}")
        self.speed = float(speed)
        if self._wall0 is not None:
            self.anchor(self._last_t)

    def _anchor_wall(self) -> float:
        if self._wall0 is None:
            self.anchor()
        assert self._wall0 is not None
        return self._wall0

    def deadline(self, t: float) -> float:
        """The ``time.monotonic`` instant at which sim time ``t`` is due."""
        return self._anchor_wall() + (t - self._t0) / self.speed

    def now(self) -> float:
        """The sim time corresponding to the wall clock now."""
        wall0 = self._anchor_wall()
        return self._t0 + (self._monotonic() - wall0) * self.speed

    def sleep_until(self, t: float) -> float:
        target = self.deadline(t)
        self._last_t = max(self._last_t, float(t))
        now = self._monotonic()
        if now < target:
            # time.sleep uses CLOCK_MONOTONIC (as time.monotonic) and is not cut short by signals; the loop is
            # a guard against an early wake-up all the same, bounded so a broken clock cannot hang us.
            for _ in range(8):
                self._sleep(target - now)
                now = self._monotonic()
                if now >= target:
                    break
            lag = 0.0
        else:
            lag = now - target
            if lag > 0.0:
                self.late_count += 1
        self.lag_s = lag
        self.max_lag_s = max(self.max_lag_s, lag)
        if lag > self.warn_lag_s and not self._warned:
            self._warned = True
            log.warning(
                "simulation is %.3f s behind real time (speed %g): a step takes longer than its share of "
                "wall time; lower the speed or the output rates",
                lag,
                self.speed,
            )
        elif lag <= self.warn_lag_s / 2:
            self._warned = False
        if self.resync_lag_s is not None and lag > self.resync_lag_s:
            self.resync_count += 1
            log.warning("simulation %.3f s behind real time: re-anchoring sim time %.3f s to now", lag, t)
            self.anchor(t)
        return lag

    def __repr__(self) -> str:
        return f"RealtimeClock(speed={self.speed!r}, lag_s={self.lag_s:.4f}, max_lag_s={self.max_lag_s:.4f})"


class SpeedGovernor:
    """Halves a `RealtimeClock`'s speed (not below ``floor``) when the loop has been late by more than
    ``max_delay_s`` of *sim* time for ``persist_s`` of wall time; then judges afresh.

    `observe` takes how late the loop is, in wall seconds (the simulation's own lag behind its schedule,
    or how long the data waits before a consumer handles it: the caller gives the larger). At ``speed``
    times real time a wall delay d is d × speed of sim time between a measurement and the command it
    causes: that is what breaks a control loop, and what halving the speed halves. The delay is smoothed
    over about a second of wall time, so a single slow step (a page fault, a garbage collection) is no
    reason; only a delay that persists is. ``monotonic`` is injectable for tests."""

    def __init__(
        self,
        clock: RealtimeClock,
        *,
        max_delay_s: float = 0.5,
        persist_s: float = 2.0,
        smoothing_s: float = 1.0,
        floor: float = 1.0,
        on_lower: Callable[[float, float, float], None] | None = None,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (max_delay_s > 0.0 and persist_s > 0.0 and smoothing_s > 0.0 and floor > 0.0):
            raise ValueError("max_delay_s, persist_s, smoothing_s and floor must be positive")
        self.clock = clock
        self.max_delay_s = max_delay_s
        self.persist_s = persist_s
        self.smoothing_s = smoothing_s
        self.floor = floor
        self.on_lower = on_lower
        """Called with (old speed, new speed, smoothed delay in sim s) when the speed is lowered."""
        self._monotonic = monotonic
        self._smoothed = 0.0
        self._last: float | None = None
        self._behind_since: float | None = None
        self.requested_speed = clock.speed
        #: (old speed, new speed, smoothed delay in sim s) of each change, in order
        self.changes: list[tuple[float, float, float]] = []

    @property
    def delay_s(self) -> float:
        """The smoothed delay, in sim seconds."""
        return self._smoothed

    def observe(self, late_wall_s: float) -> float | None:
        """Take how late the loop is now (wall s); return the new speed when it was lowered, else None."""
        now = self._monotonic()
        dt = 0.0 if self._last is None else max(now - self._last, 0.0)
        self._last = now
        w = 1.0 - math.exp(-dt / self.smoothing_s)
        self._smoothed += w * (max(late_wall_s, 0.0) * self.clock.speed - self._smoothed)
        if self._smoothed <= self.max_delay_s:
            self._behind_since = None
            return None
        if self._behind_since is None:
            self._behind_since = now
            return None
        if now - self._behind_since < self.persist_s or self.clock.speed <= self.floor:
            return None
        old = self.clock.speed
        new = max(self.floor, old / 2.0)
        self.clock.set_speed(new)
        delay = self._smoothed
        self._behind_since = None
        self._smoothed *= new / old  # the same wall delay is half the sim time now
        self.changes.append((old, new, delay))
        if self.on_lower is not None:
            self.on_lower(old, new, delay)
        return new


class SimEpoch:
    """Sim time ↔ UTC: sim time 0 is ``start_utc`` (a timezone-aware datetime; converted to UTC).

    ``SimEpoch.from_wall_clock()`` starts at the current UTC time (whole second), so that with a
    `RealtimeClock` at speed 1 the sentences' times match the receiving computer's clock.
    """

    def __init__(self, start_utc: datetime) -> None:
        if start_utc.tzinfo is None or start_utc.utcoffset() is None:
            raise ValueError(
                f"start_utc must be timezone-aware (e.g. datetime(2024, 6, 1, tzinfo=UTC)), got {start_utc!r}"
            )
        self.start_utc = start_utc.astimezone(UTC)
        delta = self.start_utc - datetime(1970, 1, 1, tzinfo=UTC)
        self._start_ns = (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1_000

    @classmethod
    def from_wall_clock(cls) -> SimEpoch:
        return cls(datetime.now(UTC).replace(microsecond=0))

    @property
    def start_ns(self) -> int:
        """The epoch as UTC ns since 1970-01-01."""
        return self._start_ns

    def utc(self, t_sim: float) -> datetime:
        """The UTC datetime of sim time ``t_sim`` (microsecond resolution)."""
        return self.start_utc + timedelta(microseconds=round(t_sim * 1e6))

    def stamp_ns(self, t_sim: float) -> int:
        """UTC ns since 1970-01-01 of sim time ``t_sim``."""
        return self._start_ns + round(t_sim * 1e9)

    def sim_time(self, utc: datetime) -> float:
        """The sim time of a timezone-aware datetime (inverse of `utc`)."""
        if utc.tzinfo is None or utc.utcoffset() is None:
            raise ValueError(f"utc must be timezone-aware, got {utc!r}")
        return (utc - self.start_utc).total_seconds()

    def __repr__(self) -> str:
        return f"SimEpoch({self.start_utc.isoformat()!r})"
