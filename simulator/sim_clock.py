"""The simulator's clock on Zenoh (``<prefix>/sim/clock``, `wire.messages.SimClock`): the ROS ``/clock``
convention, so that a gateway with ``[time] clock = "sim"`` stamps what it receives with the plant's time.

`SimClockPublisher` is the runner's `Simulation.on_time` hook. At every advance of sim time (at least every
`Simulation.time_tick_s`, and at every instant the simulation sends something) it

1. waits on a paced clock until that sim time is due (so no tick is published before its wall time: a
   gateway interpolating from the tick cannot be ahead of the plant), and lets a `SpeedGovernor` see how
   late the loop is: the simulation's own lag, or the receiver's (``downstream_delay_s``), the larger;
2. with ``max_downstream_s``, waits while the receiver is more than that much *sim* time behind (its
   backlog in wall seconds × the speed), until it is back within half of it, and re-anchors the clock:
   the simulation pauses rather than run on while the receiver is stuck (a busy machine, a compiler
   warming up), so the measurement-to-command delay the plant sees stays bounded whatever the load;
3. publishes the tick — before the runner samples and sends what is due at that instant, so every burst
   of sensor data leaves after the tick of its own time.

The session is any object with ``declare_publisher`` (a `zenoh.Session`); the simulator does not import
Zenoh itself.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from typing import Any

from simulator.clock import Clock, RealtimeClock, SimEpoch, SpeedGovernor
from wire.messages import SIM_CLOCK_KEY, SimClock

__all__ = ["MAX_WAIT_S", "SimClockPublisher"]

MAX_WAIT_S = 10.0
"""Longest pause for a receiver that is behind (wall s); then the simulation goes on (a receiver that
died must not hang the simulator)."""


class SimClockPublisher:
    """Publishes sim time on ``<prefix>/sim/clock`` as it becomes due (see the module docstring)."""

    def __init__(
        self,
        session: Any,
        prefix: str,
        epoch: SimEpoch,
        clock: Clock,
        *,
        period_s: float = 0.05,
        governor: SpeedGovernor | None = None,
        downstream_delay_s: Callable[[], float] | None = None,
        max_downstream_s: float | None = None,
        sleep: Callable[[float], None] = time.sleep,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.key = f"{prefix}/{SIM_CLOCK_KEY}"
        self.epoch = epoch
        self.clock = clock
        self.period_s = period_s
        self.governor = governor
        self.downstream_delay_s = downstream_delay_s
        self.max_downstream_s = max_downstream_s
        self._sleep = sleep
        self._monotonic = monotonic
        self.pauses = 0
        """Times the simulation waited for the receiver."""
        self.paused_s = 0.0
        """Wall seconds spent waiting for the receiver."""
        # JSON, said as every dpgw payload says it (docs/interfaces.md); a string, as zenoh takes it: the
        # simulator does not import zenoh
        self._publisher = session.declare_publisher(self.key, encoding="application/json")
        self._last_t = -1.0
        self.published = 0
        # who is speaking: a gateway that hears two simulators on one key (two benches sharing a prefix on
        # one network) tells their ticks apart by this, not by guessing from the times; below 2^53 so
        # that any JSON reader keeps it exact
        self.run = secrets.randbelow(2**53 - 1) + 1

    def __call__(self, t: float) -> None:
        if t <= self._last_t:
            return  # nothing new to say (the runner may call twice at one instant)
        lag = self.clock.sleep_until(t)
        behind = self.downstream_delay_s() if self.downstream_delay_s is not None else 0.0
        if self.governor is not None:
            self.governor.observe(max(lag, behind))
        if self.max_downstream_s is not None and behind * self._speed() > self.max_downstream_s:
            self._wait_for_receiver(t)
        speed = self.clock.speed if isinstance(self.clock, RealtimeClock) else None
        tick = SimClock(stamp_ns=self.epoch.stamp_ns(t), period_s=self.period_s, speed=speed, run=self.run)
        self._publisher.put(tick.encode())
        self._last_t = t
        self.published += 1

    def _speed(self) -> float:
        return self.clock.speed if isinstance(self.clock, RealtimeClock) else 1.0

    def _wait_for_receiver(self, t: float) -> None:
        assert self.downstream_delay_s is not None and self.max_downstream_s is not None
        start = self._monotonic()
        while (
            self.downstream_delay_s() * self._speed() > self.max_downstream_s / 2
            and self._monotonic() - start < MAX_WAIT_S
        ):
            self._sleep(0.005)
        self.pauses += 1
        self.paused_s += self._monotonic() - start
        if isinstance(self.clock, RealtimeClock):
            self.clock.anchor(t)  # go on from here: the pause is not caught up

    def close(self) -> None:
        self._publisher.undeclare()
