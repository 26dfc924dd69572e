"""Which stretch of a run is scored: the estimate after the observer's start-up, station keeping after DP's
take-over, and the least sea a figure needs.

`dpgw demo`, `dpgw replay` and `dpgw study` score on the same stretch, so that a demo's figures, the same log
replayed and a study's case mean the same thing.
"""

from __future__ import annotations

SETTLE_S = 60.0
"""The estimate is scored from this sim second on: before it is the observer's start-up from its first fix,
not its filtering."""
DP_SETTLE_S = 30.0
"""Station keeping is scored from this long after DP was engaged (and never before ``SETTLE_S``): the
take-over and the reference model's first moves are not station keeping."""
MIN_SCORED_S = 30.0
"""Least sea scored for a figure (s): the estimate after ``SETTLE_S``, the station keeping after
`dp_scored_from`; a shorter stretch (a run stopped by Ctrl-C soon after the skip) is said "not scored". The
errors scored vary over tens of seconds (waves of ~10 s, the bias estimate's error over its time constant),
so a few seconds' RMS is one sample of them, not the run's: on the default demo (seed 0, 300 s scored) the
horizontal RMS over any 3 s after the skip ranged from 0.27 to 2.2 times the whole run's, over any 30 s
from 0.69 to 1.5 times (over 60 s, 0.73-1.3, which a 120 s demo engaged at its start would just miss)."""


def dp_scored_from(engaged_s: float | None) -> float:
    """The sim second station keeping is scored from: `DP_SETTLE_S` after DP was engaged (0 or None: at
    the start), never before the estimate is scored (`SETTLE_S`)."""
    return max(SETTLE_S, (engaged_s or 0.0) + DP_SETTLE_S)
