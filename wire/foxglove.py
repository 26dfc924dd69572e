"""Foxglove-native message values built from what the NMEA sources report.

Foxglove's Map panel draws `foxglove.LocationFix` with its covariance ellipse and the 3D panel reads the
altitude, so a fix carries the receiver's own figures rather than zeros: the ellipsoidal height from GGA
and the 1σ errors from GST (docs/foxglove.md).
"""

from __future__ import annotations

from wire.messages import LocationFix, Time

NS = 1_000_000_000

COVARIANCE_UNKNOWN = 0
COVARIANCE_DIAGONAL_KNOWN = 2


def ellipsoidal_height_m(alt_msl_m: float | None, geoid_sep_m: float | None) -> float:
    """Height above the WGS-84 ellipsoid (Foxglove's and ROS NavSatFix's altitude) from GGA's fields.

    GGA gives the height above the geoid plus the geoid separation; without a separation the MSL height
    is the best figure there is (the separation is at most ~100 m, far below what a map shows). 0 when
    GGA gives no altitude (GNS, or an empty field)."""
    if alt_msl_m is None:
        return 0.0
    return alt_msl_m + (geoid_sep_m or 0.0)


def location_fix(
    stamp_ns: int,
    frame_id: str,
    lat_deg: float,
    lon_deg: float,
    altitude_m: float = 0.0,
    sigma_enu_m: tuple[float, float, float] | None = None,
    heading_rad: float | None = None,
) -> LocationFix:
    """A `foxglove.LocationFix`; ``sigma_enu_m``: 1σ east, north, up (GST's longitude, latitude and
    altitude errors). GST reports no correlation between the axes, so the covariance is diagonal
    (type DIAGONAL_KNOWN); without GST it is all zero and UNKNOWN. ``heading_rad``: clockwise from true
    north, the estimate's ψ (a GNSS fix has none of its own)."""
    if sigma_enu_m is None:
        cov = [0.0] * 9
        kind = COVARIANCE_UNKNOWN
    else:
        e, n, u = sigma_enu_m
        cov = [e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u]
        kind = COVARIANCE_DIAGONAL_KNOWN
    return LocationFix(
        timestamp=Time(sec=stamp_ns // NS, nsec=stamp_ns % NS),
        frame_id=frame_id,
        latitude=lat_deg,
        longitude=lon_deg,
        altitude=altitude_m,
        position_covariance=cov,
        position_covariance_type=kind,
        heading=heading_rad,
    )
