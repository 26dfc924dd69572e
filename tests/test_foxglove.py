"""Foxglove-native channels: the GNSS LocationFix carries GGA's height and GST's covariance, and decodes
with the schema its channel carries."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest
from hypothesis import given
from hypothesis import strategies as st
from jsonschema import Draft202012Validator

from gateway.pipeline import RawEvent
from tests.test_pipeline import DATUM, T0, S, gga_at, gst, nmea_src, pipeline
from wire import foxglove as fx
from wire.codecs import nmea_encode as enc
from wire.foxglove import ellipsoidal_height_m, heading_yaw, location_fix, ned_pose, yaw_quaternion
from wire.geodesy import LocalFrame
from wire.message_schema import json_schema
from wire.messages import LocationFix


def _gga_high(alt_m: float, geoid_sep_m: float) -> bytes:
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(0.0, 0.0, 0.0)
    t = datetime(2026, 6, 1, tzinfo=UTC)
    return enc.gga("GP", t, lat, lon, 2, 12, 0.8, alt_m, geoid_sep_m).encode()


def _fixes(out: list) -> list[dict]:  # type: ignore[type-arg]
    return [o.payload for o in out if o.topic == "/gnss/gps/fix"]


def test_gnss_fix_carries_gga_height_and_gst_covariance_and_fits_its_schema() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=2.0)])
    hdt = enc.hdt("HE", 0.3).encode()
    first = _fixes(p.feed(RawEvent(T0, "gps", _gga_high(20.0, 40.5) + hdt)))
    p.feed(RawEvent(T0 + S // 10, "gps", gst(0.3, 0.4)))  # σ lat 0.3, lon 0.4, alt 1.0
    second = _fixes(p.feed(RawEvent(T0 + S, "gps", _gga_high(21.0, 40.5) + hdt)))
    stale = _fixes(p.feed(RawEvent(T0 + 4 * S, "gps", gga_at(0.0, 0.0) + hdt)))  # GST 3.9 s old > 2 s
    validator = Draft202012Validator(json_schema(LocationFix))
    for fix in first + second + stale:
        assert not list(validator.iter_errors(fix))
    (f0,), (f1,), (f2,) = first, second, stale
    assert f0["altitude"] == pytest.approx(60.5)  # above the ellipsoid: MSL height + geoid separation
    assert f0["position_covariance_type"] == 0 and f0["position_covariance"] == [0.0] * 9  # no GST yet
    assert f1["altitude"] == pytest.approx(61.5)
    assert f1["position_covariance_type"] == 2
    # ENU, row-major: east = σ lon², north = σ lat², up = σ alt²
    assert f1["position_covariance"] == pytest.approx([0.16, 0, 0, 0, 0.09, 0, 0, 0, 1.0])
    assert f2["position_covariance_type"] == 0 and f2["altitude"] == pytest.approx(20.0)


def test_location_fix_defaults_and_height() -> None:
    assert ellipsoidal_height_m(None, 40.0) == 0.0
    assert ellipsoidal_height_m(12.0, None) == 12.0
    fix = location_fix(T0 + 5, "estimate", 59.4, 10.5)
    assert fix.timestamp.sec == T0 // S and fix.timestamp.nsec == 5
    assert fix.position_covariance_type == 0


@given(st.floats(-50.0, 50.0), st.floats(-1e4, 1e4), st.floats(-1e4, 1e4))
def test_ned_pose_is_the_yaw_quaternion_of_the_heading_to_the_bit(psi: float, n: float, e: float) -> None:
    """`ned_pose` computes its orientation inline: the same numbers as `yaw_quaternion(heading_yaw(ψ))`."""
    pose = ned_pose(n, e, psi)
    assert pose.orientation == yaw_quaternion(heading_yaw(psi))
    assert (pose.position.x, pose.position.y, pose.position.z) == (e, n, 0.0)


def test_an_antennas_frame_is_its_lever_arm_turned_to_flu() -> None:
    """dpgw's lever arm is x forward, y starboard, z down; Foxglove's vessel frame x forward, y port, z up."""
    t = fx.antenna_transform(T0, "dgps1", (10.0, 2.0, -25.0))
    assert (t.parent_frame_id, t.child_frame_id) == ("vessel", "dgps1")
    assert (t.translation.x, t.translation.y, t.translation.z) == (10.0, -2.0, 25.0)
    assert (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w) == (0.0, 0.0, 0.0, 1.0)
    assert t.timestamp.sec * 1_000_000_000 + t.timestamp.nsec == T0
