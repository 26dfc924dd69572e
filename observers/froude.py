"""The vessel's Froude scale: which seas its wave filters should expect.

Wave filters need a range of sea peak frequencies (the gain-scheduled observer's [ω_min, ω_max], the
report's wave band). At full scale the sea does not depend on the ship: 0.3-1.6 rad/s (periods 4-21 s)
covers wind sea and swell for a 30 m crew boat as for a 200 m drillship. A laboratory model is different:
it sails in a basin whose waves are the full-scale sea made small by Froude's law. A 1:λ model of a ship
(lengths ÷ λ, same gravity) sees times ÷ √λ and so frequencies × √λ::

    ω_model = √λ · ω_full,      λ = L_full / L_model                                         (Froude)

so CyberShip II (1:70) sees the 0.3-1.6 rad/s of a North Sea day at 2.5-13.4 rad/s, and a filter left on
the full-scale range settles on its lower clip. A small craft at sea (a USV of a few metres in a harbour)
is in the same position: the waves that move it are the short ones.

**The rule** (`froude_scale`): λ is the vessel's own ``model_scale`` (its file's 1:λ, e.g. 70 for
CyberShip II) where given; else, for a vessel shorter than `MODEL_MAX_LENGTH_M` (10 m), the ratio to a
`PROTOTYPE_LENGTH_M` (80 m) prototype, a supply vessel of the size of the papers' ships; else 1 — a ship is
full scale and keeps the full-scale numbers exactly. Every vessel has a length (``length_m`` is required),
so the rule always has an answer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

MODEL_MAX_LENGTH_M = 10.0
"""Vessels shorter than this without a ``model_scale`` are taken as models (or small craft) of a prototype."""
PROTOTYPE_LENGTH_M = 80.0
"""The prototype's length for such a vessel: a supply vessel of the papers' size (76-83 m)."""
SEA_PERIOD_S = (2.0, 25.0)
"""Wave periods a sea has at full scale (s): from a short wind sea to a long swell. A model sees them
÷ √λ. A wave filter tuned outside them is told so (`dpgw tune`); a spectral peak slower than them is
the vessel's own slow motion more often than a sea (the replay's wave check)."""


class _Scaled(Protocol):
    @property
    def length_m(self) -> float: ...
    @property
    def model_scale(self) -> float | None: ...


def froude_scale_of(length_m: float | None, model_scale: float | None = None) -> float:
    """λ = L_full / L_model (≥ 1 for a model, 1 at full scale; see the module docstring for the rule).

    ``model_scale`` wins where given; a missing or invalid length is full scale (λ = 1)."""
    if model_scale is not None:
        if not (math.isfinite(model_scale) and model_scale > 0):
            raise ValueError(f"model_scale must be a positive number, got {model_scale!r}")
        return float(model_scale)
    if length_m is None or not math.isfinite(length_m) or length_m <= 0 or length_m >= MODEL_MAX_LENGTH_M:
        return 1.0
    return PROTOTYPE_LENGTH_M / float(length_m)


def froude_scale(vessel: _Scaled) -> float:
    """λ of a `observers.vessel.VesselModel` (its ``model_scale``, or from its length)."""
    return froude_scale_of(vessel.length_m, vessel.model_scale)


Quantity = TypeVar("Quantity", float, NDArray[np.float64])


def froude_scaled(value: Quantity, scale: float, kind: Literal["frequency", "time"]) -> Quantity:
    """A full-scale frequency or rate (rad/s, 1/s) or time (s) as the 1:``scale`` model sees it (Froude)::

        frequency × √λ,      time ÷ √λ,      λ = ``scale``

    The one place dpgw writes Froude's √λ for the observers' defaults (`froude_scale`'s λ). λ = 1 returns
    ``value`` itself: a ship's numbers are today's bit for bit. ``value`` is a float or a float array; to go
    back from the model's scale to the ship's, scale a frequency as a time (÷ √λ) and a time as a
    frequency (× √λ)."""
    if scale == 1.0:
        return value
    if kind not in ("frequency", "time"):
        raise ValueError(f"kind must be 'frequency' or 'time', got {kind!r}")
    r = math.sqrt(scale)
    return value * r if kind == "frequency" else value / r


def scaled_frequencies(full_scale: Sequence[float], scale: float) -> tuple[float, ...]:
    """Full-scale frequencies (rad/s) as the 1:``scale`` model sees them: × √λ. λ = 1 returns them exactly."""
    return tuple(froude_scaled(float(w), scale, "frequency") for w in full_scale)
