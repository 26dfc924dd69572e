"""What one source's recent data looks like: last good value, smoothed track, measured noise, freeze."""

from __future__ import annotations

import math

NS = 1_000_000_000
MIN_SAMPLES_FOR_VARIANCE = 10


class Track:
    """A source's recent values in one or two components (heading: one, as an angle; position: N, E).

    - ``good``: the last value that passed every test (the jump test's reference) and when;
    - ``smooth``: first-order smoothing with time constant ``tau_s`` of every value that passed the
      sanity tests (quality, range, jump) — the votes compare these, so noise averages out while a drift
      shows;
    - ``var``: the measured noise variance per component, from consecutive differences (two independent
      errors per difference: E[d²] = 2σ² per component);
    - ``same_since``: when the value last changed (the freeze test).
    """

    def __init__(self, tau_s: float, angle: bool = False) -> None:
        self.tau_s = tau_s
        self.angle = angle
        self.good: tuple[float, ...] | None = None
        self.good_ns = 0
        self.smooth: tuple[float, ...] | None = None
        self.smooth_ns = 0
        self.last: tuple[float, ...] | None = None
        self.last_ns = 0
        self.var = 0.0
        self.samples = 0
        self.same_since = 0

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
        if self.last is not None and 0 < now_ns - self.last_ns <= 2 * NS:
            d2 = sum(x * x for x in self.diff(v, self.last)) / (2 * len(v))
            self.samples += 1
            alpha = 1.0 / min(self.samples, 50)  # a plain mean first, then a 50-sample running average
            self.var += alpha * (d2 - self.var)
        self.last, self.last_ns = v, now_ns
        if self.smooth is None or now_ns - self.smooth_ns > 5 * self.tau_s * NS:
            self.smooth = v
        else:
            a = min(1.0, (now_ns - self.smooth_ns) / NS / self.tau_s)
            self.smooth = tuple(
                s + a * d for s, d in zip(self.smooth, self.diff(v, self.smooth), strict=True)
            )
            if self.angle:
                self.smooth = tuple(_ssa(s) for s in self.smooth)
        self.smooth_ns = now_ns

    def accept(self, now_ns: int, v: tuple[float, ...]) -> None:
        self.good, self.good_ns = v, now_ns

    def sigma(self) -> float | None:
        """The measured 1σ per component, once there are enough samples."""
        return math.sqrt(self.var) if self.samples >= MIN_SAMPLES_FOR_VARIANCE else None

    def frozen_s(self, now_ns: int) -> float:
        return (now_ns - self.same_since) / NS if self.last is not None else 0.0


def _ssa(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
