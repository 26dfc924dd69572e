"""Hull data of a vessel for a nonlinear manoeuvring plant: what M and D alone do not say.

The observers need only M and D (`observers.vessel`). A plant with Coriolis, quadratic and cross-flow drag
and wind (`simulator.plant`) also needs how M splits into rigid body and added mass, the hull's beam and
draught (strip theory), the surge resistance and the wind areas. A vessel file gives them in an optional
``[hull]`` table (and ``[hull.wind]``); docs/vessels.md has the format and where each number comes from.

    M_RB = [[m, 0, 0], [0, m, m x_g], [0, m x_g, m (R₆₆² + x_g²)]]       Fossen (2021) eq (3.44), 3 DOF
    M    = M_RB + M_A                                                   checked to 0.5 % against the file's M
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from observers.spelling import key_problem

Array = NDArray[np.float64]

WATER_DENSITY = 1025.0
AIR_DENSITY = 1.226


class HullError(ValueError):
    """A [hull] table that cannot be used; the message names the field."""


@dataclass(frozen=True)
class WindArea:
    """Projected wind areas and the coefficients of Fossen (2021) eq (10.12):
    C_X = −c_x cos γ, C_Y = c_y sin γ, C_N = c_n sin 2γ (γ the relative wind's angle of attack)."""

    frontal_area_m2: float
    lateral_area_m2: float
    cx: float = 0.7
    cy: float = 0.8
    cn: float = 0.1
    height_m: float = 10.0  # the height the wind speed is given at for this vessel (NORSOK: 10 m)


@dataclass(frozen=True)
class HullParams:
    beam_m: float
    draft_m: float
    x_g_m: float
    yaw_gyration_radius_m: float
    added_mass: Array  # 3×3 M_A (surge, sway, yaw), symmetric
    surge_quadratic: float  # |X_|u|u| (N s²/m²), the quadratic surge resistance at speed
    surge_blend_speed_mps: float = 2.0  # the blending speed of the linear and quadratic surge resistance
    crossflow_cd: float | None = None  # None: Hoerner's 2-D coefficient at B/(2T)
    water_density: float = WATER_DENSITY
    wind: WindArea | None = None
    notes: str = field(default="", compare=False)

    def rigid_body_mass(self, mass_kg: float) -> Array:
        m, xg, r66 = mass_kg, self.x_g_m, self.yaw_gyration_radius_m
        return np.array([[m, 0.0, 0.0], [0.0, m, m * xg], [0.0, m * xg, m * (r66**2 + xg**2)]])


_HULL_REQUIRED = ("beam_m", "draft_m", "x_g_m", "yaw_gyration_radius_m", "added_mass", "surge_quadratic")
_HULL_KEYS = (
    *_HULL_REQUIRED,
    "surge_blend_speed_mps",
    "crossflow_cd",
    "water_density",
    "wind",
    "notes",
)
_WIND_REQUIRED = ("frontal_area_m2", "lateral_area_m2")
_WIND_KEYS = tuple(WindArea.__dataclass_fields__)


def _check_keys(table: dict[str, Any], known: tuple[str, ...], required: tuple[str, ...], label: str) -> None:
    """A key the table does not know is an error with a "did you mean" (`observers.spelling`)."""
    problem = key_problem(table, known, required)
    if problem is not None:
        raise HullError(f"{label}.{problem[0]}': {problem[1]}")


def _positive(table: dict[str, Any], key: str, where: str, default: float | None = None) -> float:
    value = table.get(key, default)
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not math.isfinite(value)
        or value <= 0
    ):
        raise HullError(f"{where}: field '{key}': must be a positive number, got {value!r}")
    return float(value)


def hull_from_dict(data: Any, where: str, mass_kg: float, M: Array) -> HullParams | None:
    """Parse a ``[hull]`` table (None if absent). M is the file's M: M_RB + M_A must reproduce it."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise HullError(f"{where}: field 'hull': must be a table")
    _check_keys(data, _HULL_KEYS, _HULL_REQUIRED, f"{where}: field 'hull")
    for key in _HULL_REQUIRED:
        if key not in data:
            raise HullError(f"{where}: field 'hull.{key}': missing")
    x_g = data["x_g_m"]
    if isinstance(x_g, bool) or not isinstance(x_g, int | float) or not math.isfinite(x_g):
        raise HullError(f"{where}: field 'hull.x_g_m': must be a finite number, got {x_g!r}")
    try:
        MA = np.array(data["added_mass"], dtype=float)
    except (TypeError, ValueError):
        raise HullError(f"{where}: field 'hull.added_mass': must be a 3×3 matrix of numbers") from None
    if MA.shape != (3, 3) or not np.all(np.isfinite(MA)):
        raise HullError(
            f"{where}: field 'hull.added_mass': must be a finite 3×3 matrix, got shape {MA.shape}"
        )
    if not np.allclose(MA, MA.T, rtol=1e-9, atol=1e-9 * float(np.max(np.abs(MA)))):
        raise HullError(f"{where}: field 'hull.added_mass': must be symmetric")
    cd = data.get("crossflow_cd")
    wind = None
    if "wind" in data:
        w = data["wind"]
        if not isinstance(w, dict):
            raise HullError(f"{where}: field 'hull.wind': must be a table")
        _check_keys(w, _WIND_KEYS, _WIND_REQUIRED, f"{where}: field 'hull.wind")
        for key in _WIND_REQUIRED:
            if key not in w:
                raise HullError(f"{where}: field 'hull.wind.{key}': missing")
        wind = WindArea(**{k: _positive(w, k, f"{where}: hull.wind") for k in w})
    hull = HullParams(
        beam_m=_positive(data, "beam_m", f"{where}: hull"),
        draft_m=_positive(data, "draft_m", f"{where}: hull"),
        x_g_m=float(x_g),
        yaw_gyration_radius_m=_positive(data, "yaw_gyration_radius_m", f"{where}: hull"),
        added_mass=MA,
        surge_quadratic=_positive(data, "surge_quadratic", f"{where}: hull"),
        surge_blend_speed_mps=_positive(data, "surge_blend_speed_mps", f"{where}: hull", 2.0),
        crossflow_cd=None if cd is None else _positive(data, "crossflow_cd", f"{where}: hull"),
        water_density=_positive(data, "water_density", f"{where}: hull", WATER_DENSITY),
        wind=wind,
        notes=str(data.get("notes", "")),
    )
    total = hull.rigid_body_mass(mass_kg) + MA
    scale = np.abs(np.diag(M))
    worst = np.max(np.abs(total - M) / np.sqrt(np.outer(scale, scale)))
    if worst > 5e-3:
        raise HullError(
            f"{where}: field 'hull': M_RB(mass_kg, x_g_m, yaw_gyration_radius_m) + hull.added_mass must "
            "equal M "
            f"(within 0.5 %); they differ by {100 * worst:.2g} % (M_RB + M_A = {total.round(0).tolist()})"
        )
    return hull


def relative_wind(speed_mps: float, from_deg: float, psi: float, u: float, v: float) -> tuple[float, float]:
    """(u_rw, v_rw) = (u − u_w, v − v_w): the vessel's velocity relative to the air, body frame, for a wind
    of ``speed_mps`` blowing from ``from_deg`` (degrees clockwise from north, as a wind is given) and a
    vessel at heading ψ moving at (u, v) — Fossen (2021) eq (10.10). An anemometer on the vessel reads
    this as an apparent wind of speed √(u_rw² + v_rw²) from β = atan2(v_rw, u_rw) clockwise from the bow
    (NMEA MWV, reference R)."""
    towards = math.radians(from_deg + 180.0)
    wn, we = speed_mps * math.cos(towards), speed_mps * math.sin(towards)
    c, s = math.cos(psi), math.sin(psi)
    return u - (c * wn + s * we), v - (-s * wn + c * we)


def apparent_wind_body(speed_mps: float, angle_rad: float) -> tuple[float, float]:
    """(u_rw, v_rw) of an apparent (relative) wind measured on board: ``speed_mps`` from ``angle_rad``
    clockwise from the bow (MWV reference R). The inverse of reading `relative_wind` as speed and angle:
    u_rw = V cos β, v_rw = V sin β (a wind from ahead, β = 0, is the vessel moving into still air)."""
    return speed_mps * math.cos(angle_rad), speed_mps * math.sin(angle_rad)


def relative_wind_force(
    area: WindArea, length_m: float, u_rw: float, v_rw: float
) -> tuple[float, float, float]:
    """[X, Y, N] (body frame) of the relative wind (u_rw, v_rw) on a hull with wind areas ``area`` and length
    L: Fossen (2021) eqs (10.10)–(10.12),

        V_rw² = u_rw² + v_rw²,  γ_rw = −atan2(v_rw, u_rw)  (0: wind on the bow)
        X = ½ ρ_a V_rw² C_X(γ) A_F,  Y = ½ ρ_a V_rw² C_Y(γ) A_L,  N = ½ ρ_a V_rw² C_N(γ) A_L L
        C_X = −c_x cos γ,  C_Y = c_y sin γ,  C_N = c_n sin 2γ

    The one wind force of dpgw: the simulator's plant (`simulator.wind.wind_force`) and the DP
    controller's wind feed-forward (`gateway.control.wind_feedforward`) both call it."""
    q = 0.5 * AIR_DENSITY * (u_rw * u_rw + v_rw * v_rw)
    gamma = -math.atan2(v_rw, u_rw)
    return (
        -q * area.cx * math.cos(gamma) * area.frontal_area_m2,
        q * area.cy * math.sin(gamma) * area.lateral_area_m2,
        q * area.cn * math.sin(2.0 * gamma) * area.lateral_area_m2 * length_m,
    )
