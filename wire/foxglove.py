"""Foxglove-native message values: fixes, frames, poses, 3D scene entities and log lines.

Foxglove's Map panel draws `foxglove.LocationFix` with its covariance ellipse and the 3D panel reads the
altitude, so a fix carries the receiver's own figures rather than zeros: the ellipsoidal height from GGA
and the covariance from GST's error ellipse (docs/foxglove.md).

**Frames.** dpgw computes in local NED at the datum with a body frame x forward, y starboard, z down
(Fossen's convention). Foxglove's 3D panel, like ROS (REP 103), expects z up: drawn in NED the scene is
seen from below, mirrored. So everything here is turned at this edge, and only here:
- world frame `ltp`: the datum's local tangent plane, x east, y north, z up (ENU): (x, y) = (E, N);
- vessel frames `vessel` / `vessel_measured`: x forward, y port, z up (FLU): a body point (x, y, z)
  in dpgw's frame is (x, −y, −z);
- a heading ψ (clockwise from north) is the yaw π/2 − ψ about +z (counter-clockwise from east); a
  thruster azimuth α (clockwise from the bow) is the yaw −α in the vessel frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from wire.gst_covariance import GstCovariance
from wire.messages import (
    ArrowPrimitive,
    Color,
    Duration,
    FrameTransform,
    KeyValuePair,
    LinePrimitive,
    LocationFix,
    Log,
    Point3,
    Pose,
    PoseInFrame,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    Time,
    Vector3,
)

WORLD_FRAME = "ltp"
"""The datum's local tangent plane, ENU."""
VESSEL_FRAME = "vessel"
"""The LF estimate of the vessel's reference point, FLU."""
MEASURED_FRAME = "vessel_measured"
"""The fused measurement of the reference point, FLU."""


FRAMES = (WORLD_FRAME, VESSEL_FRAME, MEASURED_FRAME)
"""The frames dpgw draws in; no GNSS source may take one of their names (the config refuses it)."""


def antenna_frame(source: str) -> str:
    """The frame of a GNSS source's antenna: the source's name (its fixes' `frame_id`, as a ROS NavSatFix
    names its antenna's frame, and what the Keelson and ROS 2 outputs know the source by): a child of
    `VESSEL_FRAME` at the source's lever arm (`antenna_transform`)."""
    return source


LINE_STRIP, LINE_LOOP = 0, 1
LOG_INFO = 2
LOG_WARNING = 3
LOG_ERROR = 4
DELETE_MATCHING_ID = 0

NS = 1_000_000_000

COVARIANCE_UNKNOWN = 0
COVARIANCE_APPROXIMATED = 1
COVARIANCE_DIAGONAL_KNOWN = 2
COVARIANCE_KNOWN = 3


def ellipsoidal_height_m(alt_msl_m: float | None, geoid_sep_m: float | None) -> float:
    """Height above the WGS-84 ellipsoid (Foxglove's and ROS NavSatFix's altitude) from GGA's fields.

    GGA gives the height above the geoid plus the geoid separation; without a separation the MSL height
    is the best figure there is (the separation is at most ~100 m, far below what a map shows). 0 when
    GGA gives no altitude (GNS, or an empty field), and when the sum is not a number (two fields near the
    float's limit add up to infinity, which JSON writes as `null` where Foxglove's schema has a number)."""
    if alt_msl_m is None:
        return 0.0
    height = alt_msl_m + (geoid_sep_m or 0.0)
    return height if math.isfinite(height) else 0.0


def location_fix(
    stamp_ns: int,
    frame_id: str,
    lat_deg: float,
    lon_deg: float,
    altitude_m: float = 0.0,
    covariance: GstCovariance | None = None,
    heading_rad: float | None = None,
) -> LocationFix:
    """A `foxglove.LocationFix`; ``covariance``: the receiver's GST covariance (`wire.gst_covariance`),
    given in east, north, up, row-major (the schema's order, as ROS's NavSatFix): type KNOWN when it
    came from the error ellipse (the east-north term filled in), DIAGONAL_KNOWN when only GST's per-axis
    σ were usable, APPROXIMATED when GST had no σ_alt (the up variance is then an estimate from the
    horizontal: `GstCovariance.up_known`); without GST it is all zero and UNKNOWN. ``heading_rad``:
    clockwise from true north, the estimate's ψ (a GNSS fix has none of its own)."""
    if covariance is None:
        cov = [0.0] * 9
        kind = COVARIANCE_UNKNOWN
    else:
        cov = covariance.enu()
        if not covariance.up_known:
            kind = COVARIANCE_APPROXIMATED
        else:
            kind = COVARIANCE_KNOWN if covariance.full else COVARIANCE_DIAGONAL_KNOWN
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


def stamp(ns: int) -> Time:
    return Time(sec=ns // NS, nsec=ns % NS)


def yaw_quaternion(yaw_rad: float) -> Quaternion:
    """A rotation by ``yaw_rad`` about +z (counter-clockwise seen from above)."""
    h = 0.5 * yaw_rad
    return Quaternion(x=0.0, y=0.0, z=math.sin(h), w=math.cos(h))


def heading_yaw(psi_rad: float) -> float:
    """ENU yaw (counter-clockwise from east) of a heading (clockwise from north)."""
    return 0.5 * math.pi - psi_rad


def ned_pose(north_m: float, east_m: float, psi_rad: float) -> Pose:
    """The pose in `ltp` (ENU) of a point at (N, E) heading ψ."""
    # (`yaw_quaternion(heading_yaw(ψ))` inline, the same operations: two poses for most estimates)
    h = 0.5 * (0.5 * math.pi - psi_rad)
    return Pose(
        position=Vector3(x=east_m, y=north_m, z=0.0),
        orientation=Quaternion(x=0.0, y=0.0, z=math.sin(h), w=math.cos(h)),
    )


def frame_transform(
    stamp_ns: int, child: str, north_m: float, east_m: float, psi_rad: float
) -> FrameTransform:
    """`ltp` → ``child``: the vessel frame at (N, E) heading ψ."""
    return frame_transform_of(stamp(stamp_ns), child, ned_pose(north_m, east_m, psi_rad))


def frame_transform_of(time: Time, child: str, pose: Pose) -> FrameTransform:
    """`frame_transform` from a stamp and an `ned_pose` already made (shared with `pose_in_frame_of`)."""
    return FrameTransform(
        timestamp=time,
        parent_frame_id=WORLD_FRAME,
        child_frame_id=child,
        translation=pose.position,
        rotation=pose.orientation,
    )


def antenna_transform(stamp_ns: int, source: str, lever_arm_m: Sequence[float]) -> FrameTransform:
    """`vessel` → `antenna_frame` (source): the antenna at its lever arm (x forward, y starboard, z down
    from the reference point, dpgw's body frame; FLU here: (x, −y, −z)), not rotated."""
    x, y, z = lever_arm_m
    return FrameTransform(
        timestamp=stamp(stamp_ns),
        parent_frame_id=VESSEL_FRAME,
        child_frame_id=antenna_frame(source),
        translation=Vector3(x=float(x), y=-float(y), z=-float(z)),
        rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )


def pose_in_frame(stamp_ns: int, north_m: float, east_m: float, psi_rad: float) -> PoseInFrame:
    return pose_in_frame_of(stamp(stamp_ns), ned_pose(north_m, east_m, psi_rad))


def pose_in_frame_of(time: Time, pose: Pose) -> PoseInFrame:
    """`pose_in_frame` from a stamp and an `ned_pose` already made."""
    return PoseInFrame(timestamp=time, frame_id=WORLD_FRAME, pose=pose)


def color(r: float, g: float, b: float, a: float = 1.0) -> Color:
    return Color(r=r, g=g, b=b, a=a)


def entity(
    stamp_ns: int,
    frame_id: str,
    id: str,
    *,
    frame_locked: bool = True,
    arrows: list[ArrowPrimitive] | None = None,
    lines: list[LinePrimitive] | None = None,
    metadata: dict[str, str] | None = None,
) -> SceneEntity:
    """A scene entity that lasts until replaced (lifetime 0), with every array Foxglove requires."""
    return SceneEntity(
        timestamp=stamp(stamp_ns),
        frame_id=frame_id,
        id=id,
        lifetime=Duration(sec=0, nsec=0),
        frame_locked=frame_locked,
        metadata=[KeyValuePair(key=k, value=v) for k, v in (metadata or {}).items()],
        arrows=arrows or [],
        cubes=[],
        spheres=[],
        cylinders=[],
        lines=lines or [],
        triangles=[],
        texts=[],
        models=[],
    )


def deletion(stamp_ns: int, id: str) -> SceneEntityDeletion:
    return SceneEntityDeletion(timestamp=stamp(stamp_ns), type=DELETE_MATCHING_ID, id=id)


_IDENTITY = Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def line(
    points: Sequence[tuple[float, float]], rgba: Color, kind: int = LINE_LOOP, width_px: float = 2.0
) -> LinePrimitive:
    """A line through (x, y) points at z = 0, ``width_px`` pixels wide whatever the zoom."""
    return LinePrimitive(
        type=kind,
        pose=_IDENTITY,
        thickness=width_px,
        scale_invariant=True,
        points=[Point3(x=x, y=y, z=0.0) for x, y in points],
        color=rgba,
        colors=[],
        indices=[],
    )


def hull_outline(length_m: float, beam_m: float) -> list[tuple[float, float]]:
    """A ship's waterline seen from above in FLU, centred on the reference point: a rectangle from the
    stern to 0.3 L before the bow, then a bow that narrows to a point. The vessel file gives length and
    beam only, so this is a sketch of the size and the bow's direction, not the hull's lines."""
    half_l, half_b = 0.5 * length_m, 0.5 * beam_m
    shoulder = half_l - 0.3 * length_m
    return [
        (-half_l, half_b),
        (shoulder, half_b),
        (half_l - 0.1 * length_m, 0.5 * half_b),
        (half_l, 0.0),
        (half_l - 0.1 * length_m, -0.5 * half_b),
        (shoulder, -half_b),
        (-half_l, -half_b),
    ]


def circle(center_x: float, center_y: float, radius_m: float, n: int = 72) -> list[tuple[float, float]]:
    step = 2.0 * math.pi / n
    return [
        (center_x + radius_m * math.cos(k * step), center_y + radius_m * math.sin(k * step)) for k in range(n)
    ]


def arrow(
    x_m: float, y_m: float, yaw_rad: float, length_m: float, rgba: Color, diameter_m: float
) -> ArrowPrimitive:
    """An arrow with its tail at (x, y) pointing at ``yaw_rad``, ``length_m`` long overall (a third of it
    head)."""
    return ArrowPrimitive(
        pose=Pose(position=Vector3(x=x_m, y=y_m, z=0.0), orientation=yaw_quaternion(yaw_rad)),
        shaft_length=max(length_m * 2.0 / 3.0, 0.0),
        shaft_diameter=diameter_m,
        head_length=max(length_m / 3.0, 0.0),
        head_diameter=2.0 * diameter_m,
        color=rgba,
    )


def thrust_arrow(
    x_fwd_m: float,
    y_stbd_m: float,
    thrust_n: float,
    azimuth_rad: float,
    max_thrust_n: float,
    scale_m: float,
    rgba: Color,
) -> ArrowPrimitive:
    """One thruster's thrust at its position in the vessel frame (FLU): along its azimuth, reversed for a
    negative thrust, ``scale_m`` long at ``max_thrust_n``."""
    yaw = -azimuth_rad + (math.pi if thrust_n < 0 else 0.0)
    frac = abs(thrust_n) / max_thrust_n if max_thrust_n > 0 else 0.0
    return arrow(x_fwd_m, -y_stbd_m, yaw, frac * scale_m, rgba, 0.04 * scale_m)


def log(stamp_ns: int, level: int, message: str, name: str) -> Log:
    return Log(timestamp=stamp(stamp_ns), level=level, message=message, name=name, file="", line=0)
