"""The 15-state vector of dpgw's wave-filtering observers, by name.

Fossen & Strand (1999) eq (15) and Hassani et al. eq (13) use the same order::

    x = [ξ1 (3), ξ2 = η_w (3), η (3), b (3), ν (3)]

ξ1, ξ2 are the states of the second-order wave model (ξ2 is the wave-frequency motion η_w), η = [N, E, ψ]
the low-frequency position and heading, b the slowly varying force (bias), ν = [u, v, r] the body-frame
velocity. (The MMAE keeps η and b in vessel-parallel axes; see `observers.mmae`.)

The compiled kernels work on flat arrays for speed; they index them with the block starts below
(``x[I_ETA + i]``: numba folds the constants, so naming costs nothing). Python code takes the slices or a
`StateView`, so that it reads ``state.eta`` rather than ``x[6:9]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

N_STATE = 15

I_XI1 = 0
"""First index of ξ1, the wave model's first state."""
I_XI2 = 3
"""First index of ξ2 = η_w, the wave-frequency motion."""
I_ETA = 6
"""First index of η = [N, E, ψ]."""
I_PSI = I_ETA + 2
"""Index of the heading ψ (kept in [-π, π))."""
I_BIAS = 9
"""First index of the bias b = [X, Y, N]."""
I_NU = 12
"""First index of ν = [u, v, r]."""

XI1 = slice(I_XI1, I_XI1 + 3)
XI2 = slice(I_XI2, I_XI2 + 3)
ETA_WF = XI2
XI = slice(I_XI1, I_XI2 + 3)
ETA = slice(I_ETA, I_ETA + 3)
BIAS = slice(I_BIAS, I_BIAS + 3)
NU = slice(I_NU, I_NU + 3)


class StateView:
    """Named views of one 15-state vector (no copies: writing ``view.eta[:] = …`` writes the vector)."""

    __slots__ = ("x",)

    def __init__(self, x: Array) -> None:
        if x.shape != (N_STATE,):
            raise ValueError(f"a wave-filter state has {N_STATE} elements, got shape {x.shape}")
        self.x = x

    @classmethod
    def zeros(cls) -> StateView:
        return cls(np.zeros(N_STATE))

    @property
    def xi(self) -> Array:
        """[ξ1, ξ2] (6)."""
        return self.x[XI]

    @property
    def xi1(self) -> Array:
        return self.x[XI1]

    @property
    def eta_wf(self) -> Array:
        """ξ2 = η_w, the wave-frequency motion."""
        return self.x[XI2]

    @property
    def eta(self) -> Array:
        return self.x[ETA]

    @property
    def psi(self) -> float:
        return float(self.x[I_PSI])

    @property
    def bias(self) -> Array:
        return self.x[BIAS]

    @property
    def nu(self) -> Array:
        return self.x[NU]

    def __repr__(self) -> str:
        parts = ", ".join(f"{k}={getattr(self, k).tolist()}" for k in ("xi1", "eta_wf", "eta", "bias", "nu"))
        return f"StateView({parts})"
