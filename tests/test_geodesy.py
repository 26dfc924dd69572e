"""Fast geodesy against pymap3d (the reference)."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wire.geodesy import LocalFrame


@settings(max_examples=300, deadline=None)
@given(
    lat0=st.floats(-89.0, 89.0),
    lon0=st.floats(-180.0, 180.0),
    n=st.floats(-1e5, 1e5),
    e=st.floats(-1e5, 1e5),
    d=st.floats(-100.0, 100.0),
)
def test_ned_to_geodetic_matches_pymap3d(lat0: float, lon0: float, n: float, e: float, d: float) -> None:
    frame = LocalFrame(lat0, lon0, 10.0)
    lat, lon, h = frame.to_geodetic(n, e, d)
    rlat, rlon, rh = pymap3d.ned2geodetic(n, e, d, lat0, lon0, 10.0)
    assert lat == pytest.approx(rlat, abs=1e-10)
    assert (lon - rlon + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-9)
    assert h == pytest.approx(rh, abs=1e-4)
    back = frame.to_ned(lat, lon, h)
    np.testing.assert_allclose(back, (n, e, d), atol=1e-4)


def test_vectorised_matches_scalar() -> None:
    frame = LocalFrame(59.4, 10.5)
    rng = np.random.default_rng(0)
    lat = 59.4 + rng.normal(0, 0.01, 100)
    lon = 10.5 + rng.normal(0, 0.01, 100)
    arr = frame.to_ned_array(lat, lon, 5.0)
    ref = np.array([pymap3d.geodetic2ned(a, b, 5.0, 59.4, 10.5, 0.0) for a, b in zip(lat, lon, strict=True)])
    np.testing.assert_allclose(arr, ref, atol=1e-6)


def test_bad_datum() -> None:
    with pytest.raises(ValueError, match="latitude"):
        LocalFrame(95.0, 0.0)


@settings(max_examples=500, deadline=None)
@given(
    lat0=st.floats(-85.0, 85.0),
    lon0=st.floats(-180.0, 180.0),
    north=st.floats(-1e5, 1e5),
    east=st.floats(-1e5, 1e5),
)
def test_lat_lon_is_to_geodetic_without_the_height_bit_for_bit(
    lat0: float, lon0: float, north: float, east: float
) -> None:
    """The estimate's shortcut gives the very latitude and longitude `to_geodetic` gives."""
    frame = LocalFrame(lat0, lon0)
    assert frame.to_lat_lon(north, east) == frame.to_geodetic(north, east, 0.0)[:2]
