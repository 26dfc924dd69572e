"""The unrolled reference tracks (`PlaneTrack` for N/E, `AngleTrack` for a heading) against the generic
`Track` they replace on the per-fix path: the same values, the same state after every step, to the bit."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.references.track import AngleTrack, PlaneTrack, Track

NS = 1_000_000_000

# time steps: equal stamps, normal sensor periods, just under / over the 2 s gap, long silences
STEPS = st.sampled_from([0, 1, 50_000_000, 200_000_000, 1_999_999_999, 2 * NS, 2 * NS + 1, 7 * NS, 40 * NS])
COORD = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
ANGLE = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)  # beyond ±π: wrapping must agree


def _state(t: Track) -> tuple[object, ...]:
    return (
        t.good,
        t.good_ns,
        t.smooth,
        t.smooth_ns,
        t.last,
        t.last_ns,
        t.var,
        t.samples,
        t.same_since,
        t.before_last,
        t.alternate_since,
    )


def _same(a: object, b: object) -> bool:
    return repr(a) == repr(b)  # bit-exact for floats (and NaN equal to NaN)


def _run(fast: Track, ref: Track, samples: list[tuple[int, tuple[float, ...], bool]]) -> None:
    now = NS
    for k, (step, v, accept) in enumerate(samples):
        now += step
        # a repeated value now and then, as a frozen source sends
        if k and accept and ref.last is not None:
            v = ref.last
        for probe in (ref.good, ref.smooth, v):
            if probe is not None:
                assert _same(fast.distance(v, probe), ref.distance(v, probe))
                assert _same(fast.diff(v, probe), ref.diff(v, probe))
        fast.observe(now, v)
        ref.observe(now, v)
        if accept:
            fast.accept(now, v)
            ref.accept(now, v)
        assert _same(_state(fast), _state(ref)), f"after sample {k}"
        assert _same(fast.sigma(), ref.sigma())
        assert _same(fast.frozen_s(now), ref.frozen_s(now))


@settings(max_examples=150, deadline=None)
@given(
    tau=st.sampled_from([0.5, 2.0, 10.0]),
    samples=st.lists(st.tuples(STEPS, st.tuples(COORD, COORD), st.booleans()), min_size=1, max_size=80),
)
def test_plane_track_is_the_generic_track_to_the_bit(
    tau: float, samples: list[tuple[int, tuple[float, ...], bool]]
) -> None:
    _run(PlaneTrack(tau), Track(tau), samples)


@settings(max_examples=150, deadline=None)
@given(
    tau=st.sampled_from([0.5, 2.0, 10.0]),
    samples=st.lists(st.tuples(STEPS, st.tuples(ANGLE), st.booleans()), min_size=1, max_size=80),
)
def test_angle_track_is_the_generic_track_to_the_bit(
    tau: float, samples: list[tuple[int, tuple[float, ...], bool]]
) -> None:
    _run(AngleTrack(tau), Track(tau, angle=True), samples)


def test_a_heading_track_across_north_agrees() -> None:
    """A heading crossing ±π every sample: the smoothed value and the noise wrap the same way."""
    psi = [math.pi - 0.01, -math.pi + 0.01] * 30
    _run(AngleTrack(2.0), Track(2.0, angle=True), [(100_000_000, (p,), True) for p in psi])
