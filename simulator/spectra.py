"""Wave spectra for the simulator: Pierson-Moskowitz and JONSWAP, and the `SeaState` that carries them.

All spectra are one-sided wave-elevation spectra S(ω) in m²·s/rad over circular frequency ω (rad/s), so that
the zeroth moment is the elevation variance::

    m0 = ∫₀^∞ S(ω) dω = Hs² / 16,          Hs = 4 √m0                                     (DNV-RP-C205 3.5.1)

Pierson-Moskowitz (DNV-RP-C205 (2010) eq. 3.5.5.1, Fossen (2021) Handbook ch. 10.2.1, modified PM)::

    S_PM(ω) = 5/16 · Hs² ωp⁴ · ω⁻⁵ · exp(−5/4 · (ω/ωp)⁻⁴),           ωp = 2π / Tp

JONSWAP (DNV-RP-C205 (2010) eq. 3.5.5.3)::

    S_J(ω) = A_γ · S_PM(ω) · γ^exp(−½ ((ω − ωp) / (σ ωp))²)
    σ = 0.07 for ω ≤ ωp,   σ = 0.09 for ω > ωp
    A_γ = 1 − 0.287 ln γ                                                                 (normalising factor)

A_γ is DNV's closed-form approximation of the factor that keeps m0 = Hs²/16 when the peak is enhanced: it is
exact for γ = 1 (PM) and within 0.3 % for 1 ≤ γ ≤ 5, about 1.8 % low at γ = 7. DNV-RP-C205 recommends JONSWAP
for 3.6 < Tp/√Hs < 5 (Hs in m, Tp in s); the functions do not enforce this, a simulator may want other seas.

Directions follow dpgw's NED convention: `SeaState.direction_rad` is the direction the waves travel *towards*,
clockwise from north (so waves "from the north-west", in the meteorological sense, travel towards 135°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import ssa_scalar

Array = NDArray[np.float64]

SpectrumKind = Literal["jonswap", "pm"]
SPECTRUM_KINDS: tuple[str, ...] = ("jonswap", "pm")

_SIGMA_LOW = 0.07  # spectral width parameter for ω ≤ ωp (DNV-RP-C205 3.5.5.3)
_SIGMA_HIGH = 0.09  # ... for ω > ωp


def _check_hs_tp(hs: float, tp: float) -> None:
    if not (math.isfinite(hs) and hs >= 0.0):
        raise ValueError(f"significant wave height hs must be a finite number ≥ 0 m, got {hs!r}")
    if not (math.isfinite(tp) and tp > 0.0):
        raise ValueError(f"peak period tp must be a finite number > 0 s, got {tp!r}")


def _check_gamma(gamma: float) -> None:
    # A_γ = 1 − 0.287 ln γ turns negative for γ > 32.6; DNV gives the formula for 1 ≤ γ ≤ 7.
    if not (math.isfinite(gamma) and 1.0 <= gamma <= 7.0):
        raise ValueError(f"JONSWAP peak enhancement gamma must be within [1, 7] (DNV-RP-C205), got {gamma!r}")


def pierson_moskowitz(omega: ArrayLike, hs: float, tp: float) -> Array:
    """Pierson-Moskowitz spectrum S(ω) (m²·s/rad), DNV-RP-C205 eq. 3.5.5.1.

    ``S(ω) = 5/16 Hs² ωp⁴ ω⁻⁵ exp(−5/4 (ω/ωp)⁻⁴)``, ωp = 2π/Tp; S(ω ≤ 0) = 0. ∫S dω = Hs²/16 exactly.
    """
    _check_hs_tp(hs, tp)
    w = np.asarray(omega, dtype=float)
    wp = 2.0 * math.pi / tp
    S = np.zeros_like(w)
    pos = w > 0.0
    x = wp / w[pos]
    # Written with x = ωp/ω so that tiny ω underflows cleanly to 0 instead of overflowing ω⁻⁵.
    S[pos] = 5.0 / 16.0 * hs**2 / wp * x**5 * np.exp(-1.25 * x**4)
    return S


def jonswap(omega: ArrayLike, hs: float, tp: float, gamma: float = 3.3) -> Array:
    """JONSWAP spectrum S(ω) (m²·s/rad), DNV-RP-C205 eq. 3.5.5.3.

    ``S(ω) = A_γ S_PM(ω) γ^exp(−½((ω − ωp)/(σ ωp))²)``, σ = 0.07 (ω ≤ ωp) / 0.09 (ω > ωp),
    A_γ = 1 − 0.287 ln γ. γ = 1 gives Pierson-Moskowitz.
    """
    _check_gamma(gamma)
    w = np.asarray(omega, dtype=float)
    S_pm = pierson_moskowitz(w, hs, tp)
    wp = 2.0 * math.pi / tp
    sigma = np.where(w <= wp, _SIGMA_LOW, _SIGMA_HIGH)
    peak = gamma ** np.exp(-0.5 * ((w - wp) / (sigma * wp)) ** 2)
    return np.asarray((1.0 - 0.287 * math.log(gamma)) * S_pm * peak, dtype=float)


@dataclass(frozen=True)
class SeaState:
    """A long-crested sea: significant wave height, peak period, spectrum shape and direction.

    ``hs_m`` significant wave height Hs (m, ≥ 0; 0 is a calm sea), ``tp_s`` peak period Tp (s),
    ``gamma`` JONSWAP peak enhancement (ignored for ``kind="pm"``), ``kind`` ``"jonswap"`` or ``"pm"``,
    ``direction_rad`` the direction the waves travel towards, NED, clockwise from north (rad), stored
    wrapped to [-π, π).
    """

    hs_m: float
    tp_s: float
    gamma: float = 3.3
    kind: SpectrumKind = "jonswap"
    direction_rad: float = 0.0

    def __post_init__(self) -> None:
        _check_hs_tp(self.hs_m, self.tp_s)
        if self.kind not in SPECTRUM_KINDS:
            raise ValueError(f"sea state kind must be one of {SPECTRUM_KINDS}, got {self.kind!r}")
        if self.kind == "jonswap":
            _check_gamma(self.gamma)
        if not math.isfinite(self.direction_rad):
            raise ValueError(f"wave direction_rad must be finite, got {self.direction_rad!r}")
        wrapped = ssa_scalar(self.direction_rad)
        object.__setattr__(self, "direction_rad", float(wrapped))

    @property
    def peak_frequency(self) -> float:
        """ωp = 2π / Tp (rad/s)."""
        return 2.0 * math.pi / self.tp_s

    def spectrum(self, omega: ArrayLike) -> Array:
        """S(ω) in m²·s/rad of this sea state."""
        if self.kind == "pm":
            return pierson_moskowitz(omega, self.hs_m, self.tp_s)
        return jonswap(omega, self.hs_m, self.tp_s, self.gamma)
