"""Vessel models for the 3-DOF low-frequency ship model.

The low-frequency model of Fossen & Strand (1999), eq (3)::

    M ν' + D ν = τ + Jᵀ(ψ) b,        τ = B_u u                       (3), (4)

needs the inertia matrix M (rigid body plus zero-frequency added mass, eq (5)), the linear damping
matrix D (eq (6)) and, for the actuators, a thruster layout from which the configuration matrix B_u is
built. A `VesselModel` holds exactly these, in SI units (kg, kg·m, kg·m², N·s/m, N·m·s), for the body
frame at the vessel's reference point.

Built-in vessels are TOML files in ``observers/vessels/``; each cites its source. A user vessel is a TOML
file of the same form (see ``docs/vessels.md``). Either M and D are given directly, or, as in MSS
(``supply.m``), in Fossen's non-dimensional "bis" system::

    M = m · T · Mbis · T,      D = m · √(g/L) · T · Dbis · T,      T = diag(1, 1, L)

A model that cannot work is refused (`VesselError`) with a message naming the field and the reason:
M must be symmetric positive definite (assumption A1), D + Dᵀ positive definite (the dissipation that
makes the velocity-error dynamics strictly passive, Proposition 2), shapes 3×3, numbers finite.

A file may also give the rigid-body mass ``M_RB`` (the fluid-memory observer keeps M_RB + A(∞) above it),
or, instead of M, ``M_RB`` and ``A_inf``: the Cummins form of a source that prints the infinite-frequency
added mass (Hajivand & Mousavizadegan 2010). M is then M_RB + A_inf + [A(0) - A(∞)] of the built-in
radiation model Froude-scaled to the vessel (`cummins_low_frequency_inertia`), the slow-motion inertia
every observer and the controller use.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.hull import HullError, HullParams, hull_from_dict
from observers.spelling import did_you_mean, key_problem
from observers.vessel_files import builtin_vessels as builtin_vessels  # used here; re-exported

Array = NDArray[np.float64]

DEFAULT_MAX_RPM = 200.0
"""Shaft speed at full thrust of a thruster whose file does not say (`Thruster.max_rpm`)."""

THRUSTER_KINDS = ("azimuth", "tunnel", "main")
"""azimuth: rotatable, thrust in any direction within its sectors; tunnel: fixed athwartships (sway);
main: fixed fore-aft propeller (surge)."""


class VesselError(ValueError):
    """A vessel description that cannot be used. The message names the field and what is wrong."""


VESSEL_KEYS = (
    "name",
    "description",
    "source",
    "length_m",
    "mass_kg",
    "model_scale",
    "M",
    "D",
    "M_RB",
    "A_inf",
    "bis",
    "hull",
    "thrusters",
)
"""The top-level keys of a vessel file (docs/vessels.md); any other is refused."""

BIS_KEYS = ("g", "Mbis", "Dbis")
"""The keys of a ``[bis]`` table."""


def _check_keys(
    table: dict[str, Any], known: tuple[str, ...], required: tuple[str, ...], where: str, path: str = ""
) -> None:
    """Refuse a key of ``table`` the format does not know, with a "did you mean" (`observers.spelling`);
    a required key that is absent while a look-alike is present is said as missing, naming what was
    found. ``path`` is the table's place in the file (``bis``, ``thrusters[0]``; "" at the top)."""
    problem = key_problem(table, known, required)
    if problem is not None:
        key, message = problem
        raise VesselError(f"{where}: field '{path + '.' if path else ''}{key}': {message}")


@dataclass(frozen=True)
class Thruster:
    """One thruster of a vessel's layout, in the body frame of the reference point.

    ``x_m`` forward, ``y_m`` starboard. ``max_thrust_n`` is the largest thrust magnitude (N).
    ``min_thrust_n`` is the most negative thrust for fixed-direction units that reverse (tunnel, main;
    0 for azimuths, which turn instead). ``azimuth_rate_rad_s`` is the slew rate of an azimuth.
    ``thrust_time_constant_s`` is the first-order lag from commanded to delivered thrust.
    ``angle_rad`` is the fixed direction of a tunnel (π/2) or main propeller (0).
    ``max_rpm`` is the shaft speed at which ``max_thrust_n`` is reached: with the propeller law it turns a
    measured shaft speed into thrust (`thrust_at_rpm`). The default, 200 rpm, is what the simulator's
    drives report; set the real one for a vessel whose drives report rpm (ArduPilot ESC telemetry).
    ``forbidden_sectors_deg`` are an azimuth's barred zones: force directions (the convention of its
    azimuth: clockwise from the bow, degrees) it must not push in, each (start, end) from start clockwise
    to end — thruster-thruster interaction, the hull, a sensor in the race. Thrust allocation
    (`gateway.control.allocation.QPAllocator`) keeps out of them.
    """

    id: int
    kind: str
    x_m: float
    y_m: float
    max_thrust_n: float
    min_thrust_n: float = 0.0
    azimuth_rate_rad_s: float = 0.0
    thrust_time_constant_s: float = 1.0
    angle_rad: float = 0.0
    max_rpm: float = DEFAULT_MAX_RPM
    forbidden_sectors_deg: tuple[tuple[float, float], ...] = ()

    def thrust_at_rpm(self, rpm: float) -> float:
        """Thrust (N) at a shaft speed (rpm, negative astern) by the quadratic propeller law T = K n|n| of a
        fixed-pitch propeller near zero advance speed (K = ρ D⁴ K_T; Fossen, *Handbook of Marine Craft
        Hydrodynamics and Motion Control*, 2011, on propeller thrust). K is not known from a drive's
        feedback, so it is set so that ``max_rpm`` gives ``max_thrust_n``: T = T_max (n/n_max)|n/n_max|."""
        n = rpm / self.max_rpm
        return float(self.max_thrust_n * n * abs(n))


THRUSTER_KEYS = tuple(Thruster.__dataclass_fields__)
"""The keys of a ``[[thrusters]]`` entry: the fields of `Thruster`."""


@dataclass(frozen=True)
class VesselModel:
    """M, D and thruster layout of a vessel (SI units, body frame at the reference point)."""

    name: str
    M: Array
    D: Array
    length_m: float
    mass_kg: float
    source: str = ""
    description: str = ""
    thrusters: tuple[Thruster, ...] = field(default_factory=tuple)
    hull: HullParams | None = None  # the nonlinear plant's hull data (`observers.hull`); None: M and D only
    model_scale: float | None = None
    """λ of a 1:λ laboratory model (CyberShip II: 70); None for a ship. Sets the Froude scale of the
    default wave-frequency ranges (`observers.froude`)."""
    M_RB: Array | None = None
    """Rigid-body mass (3×3) when the file gives it (key ``M_RB``); else `rigid_body_diagonal` falls back
    on the hull table or on the mass. The fluid-memory observer keeps M_RB + A(∞) at least this."""
    A_inf: Array | None = None
    """Infinite-frequency added mass (3×3) of a file in the Cummins form (keys ``M_RB`` and ``A_inf``
    instead of ``M``): M is then M_RB + A_inf + [A(0) - A(∞)] of the built-in radiation model
    Froude-scaled to the vessel (`cummins_low_frequency_inertia`). None: M is given (M_RB + A(0))."""
    _layout: tuple[Array, Array, Array, Array] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        where = f"vessel '{self.name}'"
        object.__setattr__(self, "M", _matrix(self.M, "M", where))
        object.__setattr__(self, "D", _matrix(self.D, "D", where))
        _check_model(self.M, self.D, where)
        for key in ("length_m", "mass_kg"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise VesselError(f"{where}: field '{key}': must be a positive finite number, got {value!r}")
        if self.model_scale is not None and not (math.isfinite(self.model_scale) and self.model_scale > 0):
            raise VesselError(
                f"{where}: field 'model_scale': must be a positive finite number (the λ of a 1:λ model), "
                f"got {self.model_scale!r}"
            )
        ids = [t.id for t in self.thrusters]
        if len(set(ids)) != len(ids):
            raise VesselError(f"{where}: field 'thrusters': thruster ids must be unique, got {ids}")
        # the layout as arrays once: the gateway computes B_u(α) for every thruster feedback and step
        layout = (
            np.array([t.angle_rad for t in self.thrusters], dtype=float),
            np.array([t.kind == "azimuth" for t in self.thrusters], dtype=bool),
            np.array([t.x_m for t in self.thrusters], dtype=float),
            np.array([t.y_m for t in self.thrusters], dtype=float),
        )
        for array in layout:
            array.flags.writeable = False
        object.__setattr__(self, "_layout", layout)

    def configuration_matrix(self, angles: ArrayLike | None = None) -> Array:
        """B_u of eq (4) for the thrusters at the given force directions (rad, clockwise from the bow).

        Thruster i at (xᵢ, yᵢ) pushing with unit force in direction αᵢ contributes the column
        [cos αᵢ, sin αᵢ, xᵢ sin αᵢ − yᵢ cos αᵢ]ᵀ (yaw moment = l_x F_y − l_y F_x, Hajivand eq (22) with the
        signs restored: the printed (22) lost them). Tunnels and main propellers use their fixed
        ``angle_rad``; ``angles`` (one per thruster, in layout order) applies to azimuths and defaults to each
        thruster's ``angle_rad``.
        """
        a, azimuth, x, y = self._layout
        if angles is not None:
            given = np.broadcast_to(np.asarray(angles, dtype=float), a.shape)
            a = np.where(azimuth, given, a)
        c, s = np.cos(a), np.sin(a)
        out = np.empty((3, a.shape[0]))
        out[0], out[1], out[2] = c, s, x * s - y * c
        return out

    def generalized_force(self, thrust: ArrayLike, angles: ArrayLike | None = None) -> Array:
        """τ = B_u(α) u: generalised force [X, Y, N] from thrusts (N, signed for tunnel/main)."""
        return self.configuration_matrix(angles) @ np.asarray(thrust, dtype=float)

    @property
    def Minv(self) -> Array:
        return np.asarray(np.linalg.inv(self.M), dtype=np.float64)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, VesselModel):
            return NotImplemented
        return (
            self.name == other.name
            and np.array_equal(self.M, other.M)
            and np.array_equal(self.D, other.D)
            and self.thrusters == other.thrusters
            and _same(self.M_RB, other.M_RB)
            and _same(self.A_inf, other.A_inf)
        )

    __hash__ = None  # type: ignore[assignment]


def _same(a: Array | None, b: Array | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.array_equal(a, b))


def rigid_body_diagonal(vessel: VesselModel) -> Array:
    """Diagonal of the rigid-body mass [m, m, I_z] as far as the vessel gives it: the file's ``M_RB``, else
    its ``[hull]`` table (Fossen (2021) eq (3.44)), else m in surge and sway (M_RB,11 = M_RB,22 = m for
    any hull) and NaN in yaw (I_z unknown)."""
    m_rb = rigid_body_matrix(vessel)
    if m_rb is not None:
        return np.diag(m_rb).copy()
    return np.array([vessel.mass_kg, vessel.mass_kg, math.nan])


def rigid_body_matrix(vessel: VesselModel) -> Array | None:
    """The full rigid-body mass (3×3): the file's ``M_RB``, else from its ``[hull]`` table, else None."""
    if vessel.M_RB is not None:
        return np.array(vessel.M_RB)
    if vessel.hull is not None:
        return np.asarray(vessel.hull.rigid_body_mass(vessel.mass_kg))
    return None


def cummins_low_frequency_inertia(M_RB: Array, A_inf: Array, mass_kg: float) -> Array:
    """M = M_RB + A(∞) + [A(0) - A(∞)] for a vessel file in the Cummins form: the memory's share from the
    built-in radiation model Froude-scaled to ``mass_kg`` (the model the memory observer then lends it,
    so that its M_m is exactly M_RB + A(∞))."""
    from observers.radiation_builtin import builtin_radiation, froude_scale_for_mass, memory_added_mass

    model = builtin_radiation().froude_scaled(froude_scale_for_mass(mass_kg))
    return np.asarray(M_RB + A_inf + memory_added_mass(model))


def _matrix(value: Any, key: str, where: str) -> Array:
    try:
        A = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise VesselError(f"{where}: field '{key}': must be a 3×3 matrix of numbers ({exc})") from None
    if A.shape != (3, 3):
        raise VesselError(f"{where}: field '{key}': must be a 3×3 matrix, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise VesselError(f"{where}: field '{key}': contains non-finite numbers")
    A.setflags(write=False)
    return A


def _check_model(M: Array, D: Array, where: str) -> None:
    scale = float(np.max(np.abs(M)))
    if not np.allclose(M, M.T, rtol=1e-9, atol=1e-12 * scale):
        raise VesselError(
            f"{where}: field 'M': must be symmetric (assumption A1, M = Mᵀ > 0); "
            f"M[1,2] = {M[1, 2]:.6g} but M[2,1] = {M[2, 1]:.6g}"
        )
    eig_m = np.linalg.eigvalsh(M)
    if eig_m.min() <= 0:
        raise VesselError(
            f"{where}: field 'M': must be positive definite (assumption A1); eigenvalues {eig_m.tolist()}"
        )
    eig_d = np.linalg.eigvalsh(D + D.T)
    if eig_d.min() <= 0:
        raise VesselError(
            f"{where}: field 'D': D + Dᵀ must be positive definite (the damping must dissipate energy); "
            f"eigenvalues of D + Dᵀ {eig_d.tolist()}"
        )


def _check_rigid_body(M_RB: Array, M: Array, where: str) -> None:
    """M_RB symmetric positive definite, and no larger than M on the diagonal (added mass ≥ 0)."""
    if not np.allclose(M_RB, M_RB.T, rtol=1e-9) or np.linalg.eigvalsh(M_RB).min() <= 0:
        raise VesselError(f"{where}: field 'M_RB': must be symmetric positive definite")
    short = [i for i in range(3) if M_RB[i, i] > M[i, i]]
    if short:
        raise VesselError(
            f"{where}: field 'M_RB': exceeds M on the diagonal at {short} (M_RB {np.diag(M_RB).tolist()}, M "
            f"{np.diag(M).tolist()}): the added mass M - M_RB cannot be negative"
        )


def _thruster(entry: Any, index: int, where: str) -> Thruster:
    key = f"thrusters[{index}]"
    if not isinstance(entry, dict):
        raise VesselError(f"{where}: field '{key}': must be a table")
    _check_keys(entry, THRUSTER_KEYS, ("id", "kind", "x_m", "y_m", "max_thrust_n"), where, key)
    kind = entry.get("kind")
    if kind not in THRUSTER_KINDS:
        raise VesselError(f"{where}: field '{key}.kind': must be one of {THRUSTER_KINDS}, got {kind!r}")
    for required in ("id", "x_m", "y_m", "max_thrust_n"):
        if required not in entry:
            raise VesselError(f"{where}: field '{key}.{required}': missing")
    default_angle = {"tunnel": math.pi / 2, "main": 0.0, "azimuth": 0.0}[kind]
    values = dict(entry)
    values.setdefault("angle_rad", default_angle)
    if "forbidden_sectors_deg" in values:
        label = f"{where}: field '{key}.forbidden_sectors_deg'"
        values["forbidden_sectors_deg"] = _sectors(values["forbidden_sectors_deg"], kind, label)
    for name, value in values.items():
        if name in ("kind", "forbidden_sectors_deg"):
            continue
        if not isinstance(value, int | float) or not math.isfinite(value):
            raise VesselError(f"{where}: field '{key}.{name}': must be a finite number, got {value!r}")
    for positive in ("max_thrust_n", "max_rpm"):
        if values.get(positive, 1.0) <= 0:
            raise VesselError(f"{where}: field '{key}.{positive}': must be positive")
    if kind == "azimuth" and values.get("azimuth_rate_rad_s", 0.0) <= 0:
        raise VesselError(f"{where}: field '{key}.azimuth_rate_rad_s': an azimuth needs a positive slew rate")
    return Thruster(**values)


def _sectors(value: Any, kind: str, label: str) -> tuple[tuple[float, float], ...]:
    """``forbidden_sectors_deg``: a list of [start, end] pairs of finite degrees, each a non-empty sector;
    ``label`` names the field in the messages (``vessel: field 'thrusters[0].forbidden_sectors_deg'``)."""
    if kind != "azimuth":
        raise VesselError(f"{label}: only an azimuth has barred zones (a {kind} has a fixed direction)")
    if not isinstance(value, list) or not all(isinstance(p, list) and len(p) == 2 for p in value):
        raise VesselError(f"{label}: must be a list of [start, end] pairs (degrees), got {value!r}")
    out = []
    for start, end in value:
        if not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in (start, end)
        ):
            raise VesselError(f"{label}: must be finite numbers of degrees, got {[start, end]!r}")
        if (float(end) - float(start)) % 360.0 == 0.0:
            raise VesselError(f"{label}: sector [{start}, {end}] is empty or the whole circle")
        out.append((float(start), float(end)))
    return tuple(out)


def vessel_from_dict(data: dict[str, Any], where: str = "vessel") -> VesselModel:
    """Build a `VesselModel` from the parsed TOML table (see module docstring for the two forms).

    Every key of every table must be one the format knows: a misspelt key is an error with a "did you
    mean" (``model_scal = 70`` would otherwise be a full-scale vessel without a word)."""
    name = data.get("name")
    named = isinstance(name, str) and bool(name)
    if named:
        where = f"vessel '{name}' ({where})" if where != "vessel" else f"vessel '{name}'"
    _check_keys(data, VESSEL_KEYS, ("name", "length_m", "mass_kg"), where)
    if not isinstance(name, str) or not name:
        raise VesselError(f"{where}: field 'name': missing or not a string")
    for key in ("length_m", "mass_kg"):
        if not isinstance(data.get(key), int | float):
            raise VesselError(f"{where}: field '{key}': missing or not a number")
    length = float(data["length_m"])
    mass = float(data["mass_kg"])
    if "bis" in data:
        if "M" in data or "D" in data:
            raise VesselError(f"{where}: field 'bis': give either M and D or a [bis] table, not both")
        bis = data["bis"]
        if not isinstance(bis, dict):
            raise VesselError(f"{where}: field 'bis': must be a table (g, Mbis, Dbis)")
        for key in bis:
            if key in VESSEL_KEYS:  # `M_RB = ...` written below the [bis] header lands in the table
                raise VesselError(
                    f"{where}: field 'bis.{key}': {key} is a top-level key: move it above the [bis] header"
                )
        _check_keys(bis, BIS_KEYS, ("Mbis", "Dbis"), where, "bis")
        for key in ("Mbis", "Dbis"):
            if key not in bis:
                raise VesselError(f"{where}: field 'bis.{key}': missing (the bis system needs Mbis and Dbis)")
        g = bis.get("g", 9.81)
        if isinstance(g, bool) or not isinstance(g, int | float) or not (math.isfinite(g) and g > 0):
            raise VesselError(f"{where}: field 'bis.g': must be a positive number (m/s²), got {g!r}")
        g = float(g)
        Tl = np.diag([1.0, 1.0, length])
        Mbis = _matrix(bis.get("Mbis"), "bis.Mbis", where)
        Dbis = _matrix(bis.get("Dbis"), "bis.Dbis", where)
        M = mass * Tl @ Mbis @ Tl
        D = mass * math.sqrt(g / length) * Tl @ Dbis @ Tl
    elif "A_inf" in data:
        # the Cummins form: the file's inertia is M_RB + A(∞); the memory supplies A(0) - A(∞)
        if "M" in data:
            raise VesselError(
                f"{where}: field 'A_inf': give either M (= M_RB + A(0)) or M_RB and A_inf (the Cummins "
                "form), not both"
            )
        if "M_RB" not in data or "D" not in data:
            missing = "M_RB" if "M_RB" not in data else "D"
            raise VesselError(
                f"{where}: field '{missing}': missing (the Cummins form needs M_RB, A_inf and D)"
            )
        M = cummins_low_frequency_inertia(
            _matrix(data["M_RB"], "M_RB", where), _matrix(data["A_inf"], "A_inf", where), mass
        )
        D = data["D"]
    else:
        for key in ("M", "D"):
            if key not in data:
                raise VesselError(f"{where}: field '{key}': missing (or give a [bis] table)")
        M, D = data["M"], data["D"]
    m_rb = None if "M_RB" not in data else _matrix(data["M_RB"], "M_RB", where)
    a_inf = None if "A_inf" not in data else _matrix(data["A_inf"], "A_inf", where)
    if m_rb is not None:
        _check_rigid_body(m_rb, _matrix(M, "M", where), where)
    thrusters = tuple(_thruster(e, i, where) for i, e in enumerate(data.get("thrusters", [])))
    scale = data.get("model_scale")
    if scale is not None and (isinstance(scale, bool) or not isinstance(scale, int | float)):
        raise VesselError(
            f"{where}: field 'model_scale': must be a number (the λ of a 1:λ model), got {scale!r}"
        )
    try:
        vessel = VesselModel(
            name=name,
            M=M,
            D=D,
            length_m=length,
            mass_kg=mass,
            source=str(data.get("source", "")),
            description=str(data.get("description", "")),
            thrusters=thrusters,
            model_scale=None if scale is None else float(scale),
            M_RB=m_rb,
            A_inf=a_inf,
        )
    except VesselError as exc:
        # re-raise with the file named, keeping the field and reason
        msg = str(exc).replace(f"vessel '{name}'", where, 1)
        raise VesselError(msg) from None
    if "hull" in data:
        try:
            hull = hull_from_dict(data["hull"], where, mass, vessel.M)
        except HullError as exc:
            raise VesselError(str(exc)) from None
        vessel = replace(vessel, hull=hull)
    return vessel


def load_vessel(name_or_path: str | Path) -> VesselModel:
    """Load a built-in vessel by name, or a user vessel from a TOML file path."""
    text: str
    where: str
    path = Path(name_or_path)
    if str(name_or_path) in builtin_vessels():
        res = resources.files("observers") / "vessels" / f"{name_or_path}.toml"
        text, where = res.read_text(encoding="utf-8"), f"built-in {name_or_path}.toml"
    elif path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise VesselError(f"vessel file '{path}': does not exist")
        text, where = path.read_text(encoding="utf-8"), str(path)
    else:
        hint = did_you_mean(str(name_or_path), builtin_vessels(), quote='"')
        raise VesselError(
            f"vessel '{name_or_path}': not a built-in vessel{hint} ({', '.join(builtin_vessels())}) "
            "and not a .toml file"
        )
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise VesselError(f"{where}: not valid TOML: {exc}") from None
    if "name" not in data and ("sources" in data or isinstance(data.get("vessel"), dict)):
        raise VesselError(
            f"{where}: a gateway configuration ([vessel], [[sources]]), not a vessel file (its [vessel] "
            "table names the vessel; a vessel file has name, mass and the matrices: docs/vessels.md)"
        )
    return vessel_from_dict(data, where)
