"""Fluid memory of the plant: the radiation convolution of the Cummins equation as a state space.

Cummins (1962); Perez & Fossen (2008); Hajivand & Mousavizadegan (2010) eqs (2)-(7). In the body frame
(surge, sway, yaw; ν = [u, v, r] in m/s and rad/s, forces [X, Y, N] in N and N m) the radiation force is

    τ_rad = -A(∞) ν' - μ,        μ(t) = ∫₀ᵗ K(t - τ) ν(τ) dτ,
    K(t) = (2/π) ∫₀^∞ B(ω) cos(ωt) dω                                          (Perez & Fossen eq (5))

and the convolution is replaced by the identified state space (`observers.radiation.identify`):

    x_r' = A x_r + B ν,          μ = C x_r + D ν                               (eq (7))

so that the plant reads (M_RB + A(∞)) ν' + ... + μ = τ + ...; the memory is driven by the velocity
relative to the water (radiation is the wave field the hull makes by moving through the water, so a
current that carries hull and water together makes none). A plant integrates x_r in its own RK4 state
(`simulator._fluid_memory_kernel.memory_derivative`, `memory_force`) or steps it alone with
`CumminsMemory`, which is exact for ν linear over a step.

`RadiationStateSpace` is the object a plant takes; `simulator.fluid_memory_cache` loads it for a vessel
(identified once and stored, never at a simulator's start); `simulator.fluid_memory_energy` holds the
checks that it only dissipates.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from simulator._fluid_memory_kernel import memory_step

if TYPE_CHECKING:
    from observers.radiation import RadiationModel

Array = NDArray[np.floating[Any]]


class FluidMemoryError(ValueError):
    """A fluid-memory model that cannot be used; the message names where it came from and why."""


def _frozen(value: ArrayLike, shape: tuple[int, ...], name: str, source: str) -> Array:
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise FluidMemoryError(f"{source}: {name} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise FluidMemoryError(f"{source}: {name} has non-finite values")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class RadiationStateSpace:
    """x_r' = A x_r + B ν, μ = C x_r + D ν, and A(∞): the fluid memory of one vessel, 3-DOF body frame, SI.

    ``A`` (n×n) is block diagonal, one block per identified element K_ij of the symmetric 3×3 K(s) (a
    coupling element such as sway-yaw is realised twice, once from v to N and once from r to Y); ``B``
    (n×3), ``C`` (3×n), ``D`` (3×3, zero unless passivity had to be enforced by a constant damping);
    ``A_inf`` (3×3, symmetric) is the infinite-frequency added mass the plant adds to M_RB. The arrays
    are read-only copies."""

    A: Array
    B: Array
    C: Array
    D: Array
    A_inf: Array
    source: str = ""
    """Where the model came from (a file, a vessel name, "identified from ...")."""
    hydro_sha256: str = ""
    """SHA-256 of the hydrodynamic data file it was identified from ("" if unknown)."""
    M_RB: Array | None = None
    """Rigid-body mass (3×3) of the hull the data belong to, when the data give it: the mass A(∞) belongs
    with (the plant's mass is M_RB + A(∞))."""
    _discrete: dict[float, tuple[Array, Array, Array]] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        where = self.source or "fluid-memory model"
        a = np.asarray(self.A)
        if a.ndim != 2 or a.shape[0] != a.shape[1]:
            raise FluidMemoryError(f"{where}: A has shape {a.shape}, expected square (n, n)")
        n = a.shape[0]
        for name, shape in (("A", (n, n)), ("B", (n, 3)), ("C", (3, n)), ("D", (3, 3)), ("A_inf", (3, 3))):
            object.__setattr__(self, name, _frozen(getattr(self, name), shape, name, where))
        if not np.allclose(self.A_inf, self.A_inf.T, rtol=1e-9, atol=0.0):
            raise FluidMemoryError(f"{where}: A_inf is not symmetric")
        if self.M_RB is not None:
            m_rb = _frozen(self.M_RB, (3, 3), "M_RB", where)
            if not np.allclose(m_rb, m_rb.T, rtol=1e-9, atol=0.0) or np.linalg.eigvalsh(m_rb)[0] <= 0.0:
                raise FluidMemoryError(f"{where}: M_RB is not symmetric positive definite")
            object.__setattr__(self, "M_RB", m_rb)
        if n and np.max(np.linalg.eigvals(self.A).real) >= 0.0:
            raise FluidMemoryError(f"{where}: A has an eigenvalue with Re ≥ 0 (the memory would not fade)")

    @classmethod
    def from_model(
        cls,
        model: RadiationModel,
        *,
        source: str = "",
        hydro_sha256: str = "",
        M_RB: ArrayLike | None = None,
    ) -> RadiationStateSpace:
        """From an identified `observers.radiation.RadiationModel` (its block-diagonal realisation)."""
        m_rb = None if M_RB is None else np.asarray(M_RB, dtype=float)
        return cls(model.Ar, model.Br, model.Cr, model.Dr, model.A_inf, source, hydro_sha256, m_rb)

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    def frequency_response(self, w: ArrayLike) -> NDArray[np.complex128]:
        """K(jω) = C (jωI - A)⁻¹ B + D, (N, 3, 3)."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        eye = np.eye(self.n_states)
        return np.array([self.C @ np.linalg.solve(1j * wk * eye - self.A, self.B) + self.D for wk in w])

    def impulse_response(self, t: ArrayLike) -> Array:
        """K(t) = C e^{At} B, (N, 3, 3) (a feedthrough D adds D δ(t), not sampled)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        lam, v = np.linalg.eig(self.A)
        left, right = self.C @ v, np.linalg.solve(v, self.B)
        return np.real(np.einsum("il,tl,lj->tij", left, np.exp(np.outer(t, lam)), right))

    def zero_frequency_added_mass(self) -> Array:
        """A(0) = A(∞) + K'(0) = A(∞) - C A⁻² B: the added mass a slow motion feels (K(0) = 0)."""
        return self.A_inf - self.C @ np.linalg.solve(self.A, np.linalg.solve(self.A, self.B))

    def max_rk4_step(self) -> float:
        """The largest step (s) with which classical RK4 integrating x_r' = A x_r is stable: for every
        eigenvalue λ the largest h with |1 + z + z²/2 + z³/6 + z⁴/24| ≤ 1, z = λh (bisection per λ)."""
        best = np.inf
        for lam in np.linalg.eigvals(self.A):
            lo, hi = 0.0, 10.0 / abs(lam)
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                z = lam * mid
                lo, hi = (mid, hi) if abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1.0 else (lo, mid)
            best = min(best, lo)
        return float(best)

    def discretise(self, h: float) -> tuple[Array, Array, Array]:
        """(Φ, Γ₀, Γ₁) with x(t+h) = Φ x(t) + Γ₀ ν(t) + Γ₁ ν(t+h), exact for ν linear over the step
        (first-order hold, Van Loan's block exponential). Cached per h."""
        cached = self._discrete.get(h)
        if cached is not None:
            return cached
        n = self.n_states
        m = np.zeros((n + 6, n + 6))
        m[:n, :n] = self.A * h
        m[:n, n : n + 3] = self.B * h
        m[n : n + 3, n + 3 :] = np.eye(3)
        e = scipy.linalg.expm(m)
        phi, g_a, g_b = e[:n, :n], e[:n, n : n + 3], e[:n, n + 3 :]
        out = (np.ascontiguousarray(phi), np.ascontiguousarray(g_a - g_b), np.ascontiguousarray(g_b))
        self._discrete[h] = out
        return out


class CumminsMemory:
    """The memory states of one vessel stepped on their own: x_r' = A x_r + B ν, μ = C x_r + D ν.

    `step` advances exactly for ν linear over the step (constant if ``nu1`` is not given) with a compiled
    kernel; the discretisation is computed once per step size."""

    def __init__(self, model: RadiationStateSpace, x0: ArrayLike | None = None) -> None:
        self.model = model
        self._C = np.ascontiguousarray(model.C)
        self._D = np.ascontiguousarray(model.D)
        self.x = np.zeros(model.n_states) if x0 is None else np.array(x0, dtype=float)
        if self.x.shape != (model.n_states,):
            raise FluidMemoryError(f"x0 has shape {self.x.shape}, expected ({model.n_states},)")
        self._next = np.empty_like(self.x)

    def reset(self) -> None:
        self.x[:] = 0.0

    def force(self, nu: ArrayLike) -> Array:
        """μ = C x_r + D ν for the current state (N, N, N m); the plant applies -μ."""
        return self._C @ self.x + self._D @ np.asarray(nu, dtype=float)

    def derivative(self, x: ArrayLike, nu: ArrayLike) -> Array:
        """A x + B ν (numpy; a compiled plant calls `memory_derivative` instead)."""
        return self.model.A @ np.asarray(x, dtype=float) + self.model.B @ np.asarray(nu, dtype=float)

    def step(self, h: float, nu0: ArrayLike, nu1: ArrayLike | None = None) -> Array:
        """Advance by h s with ν going linearly from ``nu0`` to ``nu1`` (held at ``nu0`` if None); return μ
        at the end of the step."""
        phi, g0, g1 = self.model.discretise(h)
        a = np.ascontiguousarray(nu0, dtype=float)
        b = a if nu1 is None else np.ascontiguousarray(nu1, dtype=float)
        memory_step(self.x, a, b, phi, g0, g1, self._next)
        self.x, self._next = self._next, self.x
        return self.force(b)

    def run(self, h: float, nu: ArrayLike) -> Array:
        """μ at every sample of ν (N, 3) sampled every h s, ν linear between samples, from the current state
        (μ[0] is the current force). Returns (N, 3)."""
        nu = np.asarray(nu, dtype=float)
        out = np.empty_like(nu)
        out[0] = self.force(nu[0])
        for k in range(1, len(nu)):
            out[k] = self.step(h, nu[k - 1], nu[k])
        return out
