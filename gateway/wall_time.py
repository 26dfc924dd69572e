"""Receive times on this computer's UTC clock without its backward steps (`dpgw run`, ``clock = "wall"``).

The live gateway stamps every chunk with its receive time, and everything downstream measures time by
those stamps: the jump test's allowance (a fixed part + ``max_speed_m_s × Δt``), the observer's step,
the sources' ages. When the computer's clock is stepped back (NTP or chrony correcting it, an operator
setting it), a stamp taken from it right after the step lies Δ before the one taken right before, and
every reference fails its jump test with a negative Δt (``moved 0.567 m in -30 s (limit -144 m)``): all
of them rejected together, the vessel without a reference for Δ plus the readmission time (measured: 36 s
for a 30 s step, 6 s for a 1 s step).

So a stamp is the monotonic clock's reading (which NTP slews with the UTC clock but never steps) plus an
offset taken from the UTC clock: the first receive time sets it, and a later receive time more than
`STEP_NS` *ahead* of the reckoning moves it forward (a step forward is taken: to the pipeline it is a
gap, like a silence of the sources, and log times stay UTC). A receive time more than `STEP_NS` *behind*
leaves it: stamps go on, strictly in order, ahead of the stepped clock by the step, until the clock is
stepped forward again or the gateway restarts; a status alarm says by how much meanwhile. The simulation
clock (``clock = "sim"``, `gateway.sim_time`) has its own rules.
"""

from __future__ import annotations

import logging
import time

log = logging.getLogger("dpgw")

STEP_NS = 500_000_000
"""A receive time this far from the reckoning (0.5 s) is a step of the computer's clock, not the few
microseconds between reading the two clocks; far below any source's timeout."""


class WallTime:
    """UTC receive stamps (ns) that never step back; `stamp` and `now` from one thread (the consumer)."""

    def __init__(self) -> None:
        self._offset_ns: int | None = None  # UTC ns at monotonic 0, as last taken from the UTC clock
        self.behind_ns = 0
        """How far this computer's UTC clock is behind the stamps (a backward step absorbed), 0 if not."""

    def stamp(self, wall_ns: int, mono_ns: int) -> int:
        """The stamp of something received at ``wall_ns`` on the UTC clock and ``mono_ns`` on the
        monotonic clock (read together)."""
        offset = self._offset_ns
        reckoned = 0 if offset is None else offset + mono_ns
        if offset is None or wall_ns - reckoned > STEP_NS:
            if offset is not None:
                log.warning("this computer's clock stepped forward %.1f s", (wall_ns - reckoned) / 1e9)
            offset = self._offset_ns = wall_ns - mono_ns
            self.behind_ns = 0
            return wall_ns
        behind = reckoned - wall_ns
        if behind > STEP_NS:
            if behind > self.behind_ns + STEP_NS:
                log.warning(
                    "this computer's clock stepped back %.1f s; receive times go on from the monotonic "
                    "clock, %.1f s ahead of it, until it is stepped forward again or the gateway restarts",
                    (behind - self.behind_ns) / 1e9,
                    behind / 1e9,
                )
            self.behind_ns = behind
        else:
            self.behind_ns = 0
        return reckoned

    def now(self) -> int:
        """The stamp of the present moment."""
        return self.stamp(time.time_ns(), time.monotonic_ns())

    def alarms(self) -> list[str]:
        if not self.behind_ns:
            return []
        return [
            f"clock: this computer's clock stepped back; receive times are {self.behind_ns / 1e9:.1f} s "
            "ahead of it (kept in order on the monotonic clock)"
        ]
