"""Comparing references with each other: the median of three or more, the divergence of two.

With three or more, the component-wise median is a position no single faulty reference can move far, so a
reference far from it is the odd one out (a DP system's median test). With two, a disagreement can be seen
but not attributed: both are flagged and the operator is told. The compared values are each source's
smoothed track (`Track.smooth`), so noise averages out and a slow drift stands out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

Point = tuple[float, ...]


def _ssa(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def median_distance(points: Mapping[str, Point], name: str, angle: bool = False) -> float:
    """Distance of ``points[name]`` from the component-wise median of all ``points`` (three or more).
    Angles are taken relative to ``points[name]`` first, so the median does not straddle ±π."""
    ref = points[name]
    rel = [[_ssa(a - r) if angle else a - r for a, r in zip(p, ref, strict=True)] for p in points.values()]
    median = [_median([p[k] for p in rel]) for k in range(len(ref))]
    return math.hypot(*median)


def _median(xs: list[float]) -> float:
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def divergence(a: Point, b: Point, angle: bool = False) -> float:
    return math.hypot(*(_ssa(x - y) if angle else x - y for x, y in zip(a, b, strict=True)))
