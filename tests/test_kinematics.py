"""The one smallest signed angle (observers.kinematics): its range, its meaning, and its three forms."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from observers.kinematics import rotation, ssa, ssa_jit, ssa_scalar

ANGLES = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)

# Angles where (angle + π) % 2π rounds up to 2π: a naive wrap returns +π here.
BOUNDARY = [float(np.nextafter(-math.pi - 2 * k * math.pi, -math.inf)) for k in range(4)]


def _same_bits(a: float, b: float) -> bool:
    return np.float64(a).tobytes() == np.float64(b).tobytes()


@given(ANGLES)
def test_ssa_is_in_range_and_differs_by_whole_turns(angle: float) -> None:
    a = ssa_scalar(angle)
    assert -math.pi <= a < math.pi
    turns = (angle - a) / (2 * math.pi)
    assert abs(turns - round(turns)) < 1e-9 * max(1.0, abs(angle))


@settings(deadline=None)  # the first call compiles ssa_jit
@given(ANGLES)
def test_the_three_forms_give_the_same_bits(angle: float) -> None:
    a = ssa_scalar(angle)
    assert _same_bits(a, ssa_jit(angle))
    assert _same_bits(a, float(ssa(angle)))
    assert _same_bits(a, float(ssa(np.array([angle, 0.0]))[0]))


def test_the_boundary_below_minus_pi_maps_to_minus_pi_not_plus_pi() -> None:
    for angle in BOUNDARY:
        assert ssa_scalar(angle) < math.pi, angle
        assert ssa_jit(angle) < math.pi, angle
    assert np.all(ssa(np.array(BOUNDARY)) < math.pi)
    assert ssa_scalar(math.pi) == -math.pi
    assert ssa_scalar(-math.pi) == -math.pi


def test_a_heading_crossing_north_is_a_small_step() -> None:
    before, after = math.radians(359.0), math.radians(1.0)
    assert math.isclose(ssa_scalar(after - before), math.radians(2.0), abs_tol=1e-14)
    np.testing.assert_allclose(ssa(np.array([after - before, before - after])), np.radians([2.0, -2.0]))


def test_nan_stays_nan() -> None:
    assert math.isnan(ssa_scalar(math.nan))
    assert np.isnan(ssa(np.array([math.nan]))[0])


def test_rotation_is_orthonormal_and_rotates_surge_to_heading() -> None:
    psi = math.radians(30.0)
    J = rotation(psi)
    np.testing.assert_allclose(J @ J.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(J @ [1.0, 0.0, 0.0], [math.cos(psi), math.sin(psi), 0.0])
