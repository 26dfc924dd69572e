"""The full plant's options and its parameters packed for the kernel (`simulator.plant`).

`PlantOptions` switches each effect off separately, so a paper's case can run on the paper's own model
(all off, no current, no wind: exactly M ν' + D ν = τ + Jᵀ b). `PlantParams` is what the kernel and the
readable reference both read: plain arrays and floats built once from a `VesselModel` with a ``[hull]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from observers.vessel import VesselModel
from simulator.crossflow import hoerner_cd

Array = NDArray[np.float64]


class RadiationModel(Protocol):
    """A state-space model of the radiation (fluid-memory) force, Cummins' convolution replaced by

        x_r' = A_r x_r + B_r ν_r,      μ = C_r x_r + D_r ν_r

    with the infinite-frequency added mass A_inf taking M_A's place in the mass matrix.
    ``observers.radiation.RadiationStateSpace`` is one."""

    @property
    def Ar(self) -> NDArray[np.floating[Any]]: ...  # n×n
    @property
    def Br(self) -> NDArray[np.floating[Any]]: ...  # n×3
    @property
    def Cr(self) -> NDArray[np.floating[Any]]: ...  # 3×n
    @property
    def Dr(self) -> NDArray[np.floating[Any]]: ...  # 3×3
    @property
    def A_inf(self) -> NDArray[np.floating[Any]]: ...  # 3×3


class PlantError(ValueError):
    """A vessel or option the full plant cannot use; the message names the field."""


class MissingHullError(PlantError):
    """The vessel has no ``[hull]`` table and the plant's options need one: what a caller without plant
    options of its own (a study) says differently from the message's "switch its effects off"."""


@dataclass(frozen=True)
class PlantOptions:
    """Which effects the full plant has (all on by default). Current and wind are the scenario's."""

    coriolis: bool = True  # C_RB(ν) ν_r and C_A(ν_r) ν_r
    surge_resistance: bool = True  # blended linear/quadratic surge resistance instead of D₁₁ u_r
    crossflow: bool = True  # strip-theory cross-flow drag in sway and yaw
    radiation: RadiationModel | None = None  # fluid memory (Cummins); None: constant M_A
    # C_A at the relative velocity, C_A(ν_r) ν_r (Fossen 2021), or "absolute": C_A(ν) ν_r, as MSS osv.m (2024)
    # evaluates it — no Munk moment on a hull held still in a current. Only for comparing with osv.m.
    added_mass_coriolis: str = "relative"

    def __post_init__(self) -> None:
        if self.added_mass_coriolis not in ("relative", "absolute"):
            raise PlantError(
                "plant option 'added_mass_coriolis': 'relative' or 'absolute', "
                f"got {self.added_mass_coriolis!r}"
            )

    @classmethod
    def model_only(cls) -> PlantOptions:
        """The observers' own model: nothing nonlinear."""
        return cls(coriolis=False, surge_resistance=False, crossflow=False)


DEFAULT_OPTIONS = PlantOptions()


@dataclass(frozen=True)
class PlantParams:
    M: Array  # M_RB + M_A, or M_RB + A_inf with fluid memory
    Minv: Array
    D: Array  # linear damping on ν_r; D₁₁ = 0 when the blended surge resistance replaces it
    m: float
    x_g: float
    MA: Array  # the added mass in C_A (M_A, or A_inf with fluid memory)
    coriolis: bool
    ca_absolute: bool
    surge: bool
    Xu: float  # |X_u| (N s/m)
    Xuu: float  # |X_|u|u| (N s²/m²)
    u_cross: float
    crossflow: bool
    cf_k: float  # ½ ρ T C_d
    length: float  # the hull length the cross-flow drag is integrated over
    rA: Array
    rB: Array
    rC: Array
    rD: Array

    @property
    def n_radiation(self) -> int:
        return int(self.rA.shape[0])

    @classmethod
    def build(cls, vessel: VesselModel, options: PlantOptions = DEFAULT_OPTIONS) -> PlantParams:
        hull = vessel.hull
        needs_hull = options.coriolis or options.surge_resistance or options.crossflow or options.radiation
        if hull is None and needs_hull:
            on = [k for k in ("coriolis", "surge_resistance", "crossflow") if getattr(options, k)]
            on += ["radiation"] if options.radiation is not None else []
            raise MissingHullError(
                f"vessel '{vessel.name}': the full plant needs a [hull] table (M_A, x_g, beam, draught, "
                "surge resistance; docs/vessels.md), or switch its effects off (plant options "
                + ", ".join(f"{k}=off" if k != "radiation" else "radiation=None" for k in on)
                + ")"
            )
        M = np.array(vessel.M, dtype=float)
        MA = np.array(hull.added_mass if hull is not None else np.zeros((3, 3)), dtype=float)
        D = np.array(vessel.D, dtype=float)
        n = 0
        rA, rB, rC, rD = np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((3, 0)), np.zeros((3, 3))
        if options.radiation is not None:
            assert hull is not None
            rad = options.radiation
            rA, rB, rC, rD = (
                np.ascontiguousarray(np.asarray(a, dtype=float)) for a in (rad.Ar, rad.Br, rad.Cr, rad.Dr)
            )
            n = rA.shape[0]
            A_inf = np.asarray(rad.A_inf, dtype=float)
            shapes = {
                "Ar": (rA.shape, (n, n)),
                "Br": (rB.shape, (n, 3)),
                "Cr": (rC.shape, (3, n)),
                "Dr": (rD.shape, (3, 3)),
                "A_inf": (A_inf.shape, (3, 3)),
            }
            for key, (got, want) in shapes.items():
                if got != want:
                    raise PlantError(f"plant option 'radiation.{key}': shape {got}, expected {want}")
            if n and np.max(np.linalg.eigvals(rA).real) >= 0:
                raise PlantError("plant option 'radiation.Ar': not stable (an eigenvalue with real part ≥ 0)")
            M = hull.rigid_body_mass(vessel.mass_kg) + A_inf
            MA = A_inf.copy()
        Xu = float(D[0, 0])
        if options.surge_resistance:
            D[0, 0] = 0.0
        cd = 0.0
        if hull is not None:
            cd = hull.crossflow_cd if hull.crossflow_cd is not None else hoerner_cd(hull.beam_m, hull.draft_m)
        rho = hull.water_density if hull is not None else 1025.0
        return cls(
            M=M,
            Minv=np.linalg.inv(M),
            D=D,
            m=vessel.mass_kg,
            x_g=hull.x_g_m if hull is not None else 0.0,
            MA=MA,
            coriolis=options.coriolis,
            ca_absolute=options.added_mass_coriolis == "absolute",
            surge=options.surge_resistance,
            Xu=Xu,
            Xuu=hull.surge_quadratic if hull is not None else 0.0,
            u_cross=hull.surge_blend_speed_mps if hull is not None else 1.0,
            crossflow=options.crossflow,
            cf_k=0.5 * rho * (hull.draft_m if hull is not None else 0.0) * cd,
            length=vessel.length_m,
            rA=rA,
            rB=rB,
            rC=rC,
            rD=rD,
        )
