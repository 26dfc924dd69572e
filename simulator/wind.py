"""Wind: a mean speed with gusts from a spectrum, and the force it makes on the hull and superstructure.

Gusts. The longitudinal gust u_g(t) is a sum of N harmonics with random phases whose amplitudes follow a
gust spectrum, a_i = √(2 S(f_i) Δf_i), on log-spaced frequencies with jitter (no repetition period):

- NORSOK N-003 (2017) / DNV-RP-C205 Sec. 2.3.5, the Frøya spectrum for the North Sea:
  S(f) = 320 (U₀/10)² (z/10)^0.45 / (1 + f̃ⁿ)^{5/(3n)},  f̃ = 172 f (z/10)^{2/3} (U₀/10)^{−3/4}, n = 0.468,
  with U₀ the 1-hour mean at 10 m (m/s), z the height (m), f in Hz, S in m²/s²/Hz; the mean at height z
  is U₀ (1 + C ln(z/10)), C = 0.0573 √(1 + 0.15 U₀).
- Harris (1971): f S(f) / (κ U₁₀²) = 4 f̃ / (2 + f̃²)^{5/6}, f̃ = f L / U₁₀, L = 1800 m, κ = 0.002.

The mean at the wind areas' height is the NORSOK profile's for every spectrum, ``none`` included: the
speed given is the 1-hour mean at 10 m whichever shapes the gusts.

The series is evaluated on a 0.25 s grid in 64 s blocks (one vectorised call per block) and interpolated:
the spectrum has no energy that matters to a ship's LF motion above 0.2 Hz.

Force. With the relative wind u_rw = u − u_w, v_rw = v − v_w (body frame), V_rw its speed and
γ_rw = −atan2(v_rw, u_rw) its angle of attack (0 = on the bow), Fossen (2021) eqs (10.10)–(10.12):

    X = ½ ρ_a V_rw² C_X(γ) A_F,  Y = ½ ρ_a V_rw² C_Y(γ) A_L,  N = ½ ρ_a V_rw² C_N(γ) A_L L
    C_X = −c_x cos γ,  C_Y = c_y sin γ,  C_N = c_n sin 2γ

with the areas and c_x, c_y, c_n from the vessel's ``[hull.wind]`` table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.hull import WindArea, relative_wind, relative_wind_force

Array = NDArray[np.float64]

GUST_SPECTRA = ("norsok", "harris", "none")
_BLOCK_S = 64.0
_GRID_S = 0.25


@dataclass(frozen=True)
class WindModel:
    speed_mps: float  # 1-hour mean at 10 m (NORSOK U₀; Harris U₁₀)
    from_deg: float  # the direction it blows from, clockwise from north
    gust: str = "norsok"
    components: int = 200
    f_min_hz: float = 5e-4
    f_max_hz: float = 0.2

    def __post_init__(self) -> None:
        if self.gust not in GUST_SPECTRA:
            raise ValueError(f"wind: field 'gust': one of {GUST_SPECTRA}, got {self.gust!r}")
        if not self.speed_mps >= 0:
            raise ValueError(f"wind: field 'speed_mps': must be ≥ 0, got {self.speed_mps!r}")
        if not (0 < self.f_min_hz < self.f_max_hz) or self.components < 1:
            raise ValueError("wind: fields 'f_min_hz' < 'f_max_hz' and 'components' ≥ 1 required")


def norsok_spectrum(f: Array, u10: float, z: float = 10.0) -> Array:
    """NORSOK N-003 / Frøya gust spectrum S(f) (m²/s²/Hz)."""
    n = 0.468
    ft = 172.0 * f * (z / 10.0) ** (2.0 / 3.0) * (u10 / 10.0) ** -0.75
    return np.asarray(320.0 * (u10 / 10.0) ** 2 * (z / 10.0) ** 0.45 / (1.0 + ft**n) ** (5.0 / (3.0 * n)))


def norsok_mean(u10: float, z: float) -> float:
    """NORSOK mean wind speed at height z from the 1-hour mean at 10 m."""
    return u10 * (1.0 + 0.0573 * math.sqrt(1.0 + 0.15 * u10) * math.log(z / 10.0))


def harris_spectrum(f: Array, u10: float, length_m: float = 1800.0, kappa: float = 0.002) -> Array:
    """Harris gust spectrum S(f) (m²/s²/Hz)."""
    ft = f * length_m / max(u10, 1e-9)
    return np.asarray(4.0 * kappa * u10 * length_m / (2.0 + ft**2) ** (5.0 / 6.0))


class Wind:
    """Wind speed now (mean + gust) and the force on a hull (`force_body`)."""

    def __init__(self, model: WindModel, area: WindArea, length_m: float, rng: np.random.Generator) -> None:
        self.model = model
        self.area = area
        self.length_m = length_m
        z = area.height_m
        # the mean at the areas' height by the NORSOK profile whatever the gust spectrum: the speed is the
        # 10 m mean in every case, and the profile belongs to the mean wind, the spectra only to its gusts
        self.mean = norsok_mean(model.speed_mps, z)
        edges = np.geomspace(model.f_min_hz, model.f_max_hz, model.components + 1)
        df = np.diff(edges)
        f = edges[:-1] + df * rng.uniform(0.0, 1.0, model.components)  # jitter: no common period
        if model.gust == "norsok":
            s = norsok_spectrum(f, model.speed_mps, z)
        elif model.gust == "harris":
            s = harris_spectrum(f, model.speed_mps)
        else:
            s = np.zeros_like(f)
        self.omega = 2.0 * math.pi * f
        self.amplitude = np.sqrt(2.0 * s * df)
        self.phase = rng.uniform(0.0, 2.0 * math.pi, model.components)
        self._t0 = math.inf
        self._block: list[float] = []

    def gust(self, t: ArrayLike) -> Array:
        """u_g(t) (m/s), the sum of harmonics (the readable form the block cache interpolates)."""
        t = np.asarray(t, dtype=float)
        return np.asarray(np.cos(np.multiply.outer(t, self.omega) + self.phase) @ self.amplitude)

    def speed(self, t: float) -> float:
        if self.model.gust == "none":
            return self.mean
        if not (self._t0 <= t < self._t0 + _BLOCK_S):
            self._t0 = math.floor(t / _BLOCK_S) * _BLOCK_S
            grid = self._t0 + _GRID_S * np.arange(int(_BLOCK_S / _GRID_S) + 1)
            self._block = self.gust(grid).tolist()  # floats: scalar arithmetic on them is fast
        k = (t - self._t0) / _GRID_S
        i = int(k)
        g = self._block[i] + (k - i) * (self._block[i + 1] - self._block[i])
        return max(self.mean + g, 0.0)

    def force_body(self, t: float, psi: float, u: float, v: float) -> tuple[float, float, float]:
        """[X, Y, N] of the wind on the vessel at heading ψ moving at (u, v) (body frame), at time t."""
        return self.force_at(self.speed(t), psi, u, v)

    def mean_force_body(self, psi: float) -> tuple[float, float, float]:
        """The force of the mean wind (no gust) on the vessel at rest: a feed-forward's estimate."""
        return self.force_at(self.mean, psi, 0.0, 0.0)

    def force_at(self, speed: float, psi: float, u: float, v: float) -> tuple[float, float, float]:
        return wind_force(self.area, self.length_m, speed, self.model.from_deg, psi, u, v)


def wind_force(
    area: WindArea, length_m: float, speed: float, from_deg: float, psi: float, u: float, v: float
) -> tuple[float, float, float]:
    """[X, Y, N] (body frame) of a wind of this speed from this direction on a vessel at heading ψ moving at
    (u, v): Fossen (2021) eqs (10.10)–(10.12) on the relative wind, by the numerics layer's
    `observers.hull.relative_wind` and `observers.hull.relative_wind_force` (the functions the DP
    controller's wind feed-forward uses too)."""
    urw, vrw = relative_wind(float(speed), from_deg, float(psi), float(u), float(v))
    return relative_wind_force(area, length_m, urw, vrw)
