"""What one source's recent data looks like: last good value, smoothed track, measured noise, freeze."""

from __future__ import annotations

import math

NS = 1_000_000_000
MIN_SAMPLES_FOR_VARIANCE = 10
RESTART_NS = 2 * NS
"""A gap in a source's values longer than this restarts its smoothed track (``Track.start_ns``): the
same 2 s after which the freeze clock and the noise measure restart. A first-order step across a longer
gap would leave the track wherever the step's weight put it between the value before the gap and the
first after it, which is no smoothing of anything; the vote compares a restarted track with the others
only once it is comparable (`ReferenceMonitor`, docs/integrity.md "A reference back from a silence")."""


FREEZE_FALSE_ALARM_P = 1e-9
"""Chance, per run start, that a healthy source's steady value repeats for the freeze test's hold: at
10 Hz a run can start every 0.1 s, so at most one false alarm in about three years of the flat calm in
which it is that likely (`freeze_hold_ns`)."""
ACTIVITY_TAU_S = 60.0
"""Time constant of a source's learned activity (the share of samples repeating the previous one): long
enough to average the last digit over a minute of waves, short against how fast a sea state calms
(tens of minutes); the hold is judged from a minute of the sea as it is now."""


def freeze_hold_ns(repeat: float, interval_s: float, least_ns: int, most_ns: int) -> int:
    """How long a run of unchanged samples starting now may last, ns: the smallest n with
    repeat^((n+1)/2) ≤ `FREEZE_FALSE_ALARM_P` times the mean sample interval, within [least, most].
    ``repeat`` is the source's learned share of samples equal to the previous one (`learned_repeat`).
    The bound (docs/integrity.md, "Freeze"; `gateway.references.attitude` derives it): a run of n repeats
    is n+1 samples in one cell of the last digit, of probability Σ P_kⁿ⁺¹ ≤ repeat^((n+1)/2)."""
    if repeat <= 0.0:
        return least_ns
    if repeat >= 1.0 or interval_s <= 0.0:
        return max(least_ns, most_ns)
    n = math.ceil(2.0 * math.log(FREEZE_FALSE_ALARM_P) / math.log(repeat) - 1.0)
    return max(least_ns, min(most_ns, round(n * interval_s * NS)))


def learned_repeat(repeat: float, learned: int, interval_s: float, same: bool) -> float:
    """``repeat`` after one more passing sample (``same``: it equals the previous one), the ``learned``-th:
    the mean of the first ones (from ½), then an EMA of time constant `ACTIVITY_TAU_S`."""
    gain = max(interval_s / ACTIVITY_TAU_S, 1.0 / (learned + 2))
    return repeat + min(gain, 1.0) * (float(same) - repeat)


class Track:
    """A source's recent values in one or two components (heading: one, as an angle; position: N, E).

    - ``good``: the last value that passed every test (the jump test's reference) and when;
    - ``smooth``: first-order smoothing with time constant ``tau_s`` of every value that passed the
      sanity tests (quality, range, jump) — the votes compare these, so noise averages out while a drift
      shows; ``start_ns``: when it last (re)started, at the first value or after a gap over `RESTART_NS`
      (`seed` then sets where it starts);
    - ``var``: the measured noise variance per component, from consecutive differences (two independent
      errors per difference: E[d²] = 2σ² per component);
    - ``same_since``: when the value last changed (the freeze test);
    - ``alternate_since``: since when every value has equalled the one two before it but not the one
      before (a frozen double buffer alternates between its last two values: the freeze test too).
    """

    def __init__(self, tau_s: float, angle: bool = False) -> None:
        self.tau_s = tau_s
        self.angle = angle
        self.good: tuple[float, ...] | None = None
        self.good_ns = 0
        self.smooth: tuple[float, ...] | None = None
        self.smooth_ns = 0
        self.start_ns = 0
        self.interval_ns = 0  # the source's usual time between values (a running average of 8)
        self.last: tuple[float, ...] | None = None
        self.last_ns = 0
        self.var = 0.0
        self.samples = 0
        self.same_since = 0
        self.before_last: tuple[float, ...] | None = None
        self.alternate_since = 0

    def diff(self, a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, ...]:
        if self.angle:
            return tuple(_ssa(x - y) for x, y in zip(a, b, strict=True))
        return tuple(x - y for x, y in zip(a, b, strict=True))

    def distance(self, a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return math.hypot(*self.diff(a, b))

    def observe(self, now_ns: int, v: tuple[float, ...]) -> None:
        """A value that passed the sanity tests: update freeze clock, noise and the smoothed track."""
        if self.last is None or v != self.last or now_ns - self.last_ns > 2 * NS:
            self.same_since = now_ns  # changed, or after a gap: a freeze is a source repeating itself
        if self.last is None or v == self.last or v != self.before_last or now_ns - self.last_ns > 2 * NS:
            self.alternate_since = now_ns
        self.before_last = self.last
        if self.last is not None and 0 < now_ns - self.last_ns <= 2 * NS:
            d2 = sum(x * x for x in self.diff(v, self.last)) / (2 * len(v))
            self.samples += 1
            alpha = 1.0 / min(self.samples, 50)  # a plain mean first, then a 50-sample running average
            self.var += alpha * (d2 - self.var)
            gap = now_ns - self.last_ns
            self.interval_ns = (
                gap if not self.interval_ns else self.interval_ns + (gap - self.interval_ns) // 8
            )
        self.last, self.last_ns = v, now_ns
        if self.smooth is None or now_ns - self.smooth_ns > RESTART_NS:
            self.smooth, self.start_ns = v, now_ns
        else:
            a = min(1.0, (now_ns - self.smooth_ns) / NS / self.tau_s)
            self.smooth = tuple(
                s + a * d for s, d in zip(self.smooth, self.diff(v, self.smooth), strict=True)
            )
            if self.angle:
                self.smooth = tuple(_ssa(s) for s in self.smooth)
        self.smooth_ns = now_ns

    def lag(self) -> tuple[float, ...] | None:
        """How far the smoothed track is from the latest value (smooth − last): the smoothing's lag
        behind the vessel's wave motion, the same for every source that sees that motion."""
        if self.smooth is None or self.last is None:
            return None
        return self.diff(self.smooth, self.last)

    def seed(self, lag: tuple[float, ...]) -> None:
        """Start a just-restarted track at its latest value plus ``lag`` (the others' `lag`): where its
        smoothed track would be had it never stopped, so that it compares with theirs like with like."""
        assert self.last is not None
        v = tuple(x + d for x, d in zip(self.last, lag, strict=True))
        self.smooth = tuple(_ssa(x) for x in v) if self.angle else v

    def accept(self, now_ns: int, v: tuple[float, ...]) -> None:
        self.good, self.good_ns = v, now_ns

    def sigma(self) -> float | None:
        """The measured 1σ per component, once there are enough samples."""
        return math.sqrt(self.var) if self.samples >= MIN_SAMPLES_FOR_VARIANCE else None

    def frozen_s(self, now_ns: int) -> float:
        """How long the source has repeated itself: one value, or a double buffer's two in turn."""
        since = self.same_since if self.same_since < self.alternate_since else self.alternate_since
        return (now_ns - since) / NS if self.last is not None else 0.0


_PI = math.pi
_TWO_PI = 2 * math.pi


def _ssa(a: float) -> float:
    return (a + _PI) % _TWO_PI - _PI


class PlaneTrack(Track):
    """`Track` of a position (N, E), the same arithmetic unrolled for two components.

    Every fix of every position source goes through `observe` and `distance` twice or more, and the
    generic version's generators and `zip` cost more than the arithmetic (about 8 µs a fix). The numbers
    are the generic version's to the bit (same operations in the same order; tests/test_integrity.py
    feeds both the same values and compares)."""

    def __init__(self, tau_s: float) -> None:
        super().__init__(tau_s, angle=False)

    def diff(self, a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, ...]:
        return (a[0] - b[0], a[1] - b[1])

    def distance(self, a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return math.hypot(a[0] - b[0], a[1] - b[1])

    def observe(self, now_ns: int, v: tuple[float, ...]) -> None:
        last = self.last
        gap = now_ns - self.last_ns
        if last is None or v != last or gap > 2 * NS:
            self.same_since = now_ns
        if last is None or v == last or v != self.before_last or gap > 2 * NS:
            self.alternate_since = now_ns
        self.before_last = last
        if last is not None and 0 < gap <= 2 * NS:
            dn, de = v[0] - last[0], v[1] - last[1]
            d2 = (dn * dn + de * de) / 4  # (Σ d² over the 2 components) / (2 · 2)
            self.samples += 1
            self.var += (1.0 / (self.samples if self.samples < 50 else 50)) * (d2 - self.var)
            self.interval_ns = (
                gap if not self.interval_ns else self.interval_ns + (gap - self.interval_ns) // 8
            )
        self.last, self.last_ns = v, now_ns
        s = self.smooth
        if s is None or now_ns - self.smooth_ns > RESTART_NS:
            self.smooth, self.start_ns = v, now_ns
        else:
            a = (now_ns - self.smooth_ns) / NS / self.tau_s
            if not a < 1.0:
                a = 1.0
            self.smooth = (s[0] + a * (v[0] - s[0]), s[1] + a * (v[1] - s[1]))
        self.smooth_ns = now_ns


class AngleTrack(Track):
    """`Track` of a heading (one angle), the same arithmetic as the generic version with one component
    (``hypot`` of one value is its magnitude); see `PlaneTrack` for why."""

    def __init__(self, tau_s: float) -> None:
        super().__init__(tau_s, angle=True)

    def diff(self, a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, ...]:
        return (_ssa(a[0] - b[0]),)

    def distance(self, a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return abs((a[0] - b[0] + _PI) % _TWO_PI - _PI)  # (`_ssa`, inline: twice per heading)

    def observe(self, now_ns: int, v: tuple[float, ...]) -> None:
        last = self.last
        gap = now_ns - self.last_ns
        if last is None or v != last or gap > 2 * NS:
            self.same_since = now_ns
        if last is None or v == last or v != self.before_last or gap > 2 * NS:
            self.alternate_since = now_ns
        self.before_last = last
        if last is not None and 0 < gap <= 2 * NS:
            d = _ssa(v[0] - last[0])
            d2 = d * d / 2
            self.samples += 1
            self.var += (1.0 / (self.samples if self.samples < 50 else 50)) * (d2 - self.var)
            self.interval_ns = (
                gap if not self.interval_ns else self.interval_ns + (gap - self.interval_ns) // 8
            )
        self.last, self.last_ns = v, now_ns
        s = self.smooth
        if s is None or now_ns - self.smooth_ns > RESTART_NS:
            self.smooth, self.start_ns = v, now_ns
        else:
            a = (now_ns - self.smooth_ns) / NS / self.tau_s
            if not a < 1.0:
                a = 1.0
            self.smooth = (_ssa(s[0] + a * _ssa(v[0] - s[0])),)
        self.smooth_ns = now_ns
