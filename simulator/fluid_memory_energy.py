"""Energy checks of a fluid-memory model: it may only dissipate.

A radiation force does no work on a body over a motion from rest: ∫₀ᵀ νᵀμ dt ≥ 0 for every ν(t) and
every T (the hull radiates waves that carry energy away; none comes back). For the state space
x' = A x + B ν, μ = C x + D ν this is positive-realness of K(s) (the positive-real lemma, Kalman-
Yakubovich-Popov): there is a storage function V(x) = ½ xᵀ P x, P = Pᵀ > 0, with

    V' ≤ νᵀ μ        ⇔     [[AᵀP + PA, PB - Cᵀ], [BᵀP - C, -(D + Dᵀ)]] ⪯ 0.

Two checks are made here, without an LMI solver:

- **Hamiltonian certificate** (every frequency at once, no grid): K is positive real iff the Hermitian
  part of K(jω) is positive semidefinite for all ω. A radiation kernel has D = 0 and a Hermitian part
  that vanishes at ω → 0 and ∞, so the check is made on K + εI (in units scaled by each DOF's peak
  damping, so ε is relative): its Hermitian part is singular at some ω iff the Hamiltonian matrix
  H = [[A - BR⁻¹C, -BR⁻¹Bᵀ], [CᵀR⁻¹C, -(A - BR⁻¹C)ᵀ]], R = D + Dᵀ + 2εI, has the eigenvalue jω. At
  ω → ∞ the Hermitian part is εI > 0, so "no imaginary eigenvalue" proves λ_min(Herm K(jω)) > -ε peak
  damping at every frequency (Grivet-Talocia 2004; Boyd, Balakrishnan & Kabamba 1989).
- **Storage function**: the stabilising solution of the positive-real Riccati equation
  AᵀP + PA + (PB - Cᵀ)R⁻¹(BᵀP - C) = 0 (scipy's CARE with X = -P, Q = 0, S = Cᵀ). It exists with P > 0
  for a (regularised) positive-real minimal model, and gives V' ≤ νᵀμ + ε|ν̃|² (ν̃ the scaled velocity):
  the energy the memory holds, which a free decay exchanges with the vessel's kinetic energy.

And the free decay of a vessel with only the memory, (M_RB + A(∞)) ν' = -μ, solved exactly (matrix
exponential of the linear system): its kinetic energy E = ½νᵀ(M_RB + A(∞))ν plus the stored V never
grows, and ν tends to (M_RB + A(0))⁻¹(M_RB + A(∞))ν₀ (the final-value theorem: K(0) = 0, so a steady
motion is not damped; the fluid that moves with the hull then adds A(0) instead of A(∞)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from simulator.fluid_memory import FluidMemoryError, RadiationStateSpace

Array = NDArray[np.floating[Any]]

EPSILON = 1e-6
"""Regularisation of the checks, relative to each DOF's peak damping: passivity is proven to within
10⁻⁶ of the peak damping at every frequency (the fit's own misfit is 10⁻³-10⁻²)."""
IMAGINARY_TOLERANCE = 1e-3
"""A Hamiltonian eigenvalue with |Re λ| ≤ this × max(1, |λ|) is a candidate crossing, confirmed (or not)
by the Hermitian part of K(jω) at ω = |Im λ| itself: the Hamiltonian's norm is 10¹⁴ and more (forces of
10⁹ N m against velocities of 10⁻² rad/s, over ε), so a crossing's computed real part is not zero but
10⁻¹⁰-10⁻⁶ of |λ|; a passive model's nearest eigenvalue is 10⁻² off (the supply vessel: 0.019)."""


def damping_scale(model: RadiationStateSpace) -> Array:
    """Peak Re K_ii(jω) over 10⁻³-10² rad/s per DOF (N s/m, N s/m, N m s), 1 for a DOF without memory."""
    w = np.geomspace(1e-3, 1e2, 1000)
    diag = np.real(np.diagonal(model.frequency_response(w), axis1=1, axis2=2))
    peak = np.max(diag, axis=0)
    return np.where(peak > 0.0, peak, 1.0)


def _scaled(model: RadiationStateSpace, eps: float) -> tuple[Array, Array, Array, Array, Array]:
    """(A, B̃, C̃, R, T) with ν = T ν̃, μ̃ = T μ (so ν̃ᵀμ̃ = νᵀμ), K̃ = T K T, R = D̃ + D̃ᵀ + 2εI."""
    t = np.diag(1.0 / np.sqrt(damping_scale(model)))
    d = t @ model.Dr @ t
    return model.Ar, model.Br @ t, t @ model.Cr, d + d.T + 2.0 * eps * np.eye(3), t


def _balanced(a: Array, b: Array, c: Array) -> tuple[Array, Array, Array]:
    """The same system in states scaled so that each state's row of B and column of C have equal norms
    (x = S z): the identified C carries forces of 10⁶-10⁹ N while B is of order one, which would make the
    Hamiltonian's norm 10¹⁸ and its eigenvalues no more accurate than that."""
    nb = np.linalg.norm(b, axis=1)
    nc = np.linalg.norm(c, axis=0)
    s = np.sqrt(np.where((nb > 0) & (nc > 0), nb / np.where(nc > 0, nc, 1.0), 1.0))
    return a * (1.0 / s)[:, None] * s[None, :], b / s[:, None], c * s[None, :]


@dataclass(frozen=True)
class PassivityCertificate:
    passive: bool
    epsilon: float
    crossings_rad_s: Array
    """Frequencies where λ_min(Herm K(jω)) = -ε (relative), each confirmed negative by evaluating K(jω)
    there: empty for a passive model."""
    smallest_relative_real_part: float
    """min |Re λ| / max(1, |λ|) over the Hamiltonian's eigenvalues: how far from a crossing."""


def hamiltonian_certificate(model: RadiationStateSpace, eps: float = EPSILON) -> PassivityCertificate:
    """Positive-realness of K + εI at every frequency from the Hamiltonian's eigenvalues (module doc)."""
    a, b, c, r, _ = _scaled(model, eps)
    a, b, c = _balanced(a, b, c)
    ri = np.linalg.inv(r)
    ab = a - b @ ri @ c
    h = np.block([[ab, -b @ ri @ b.T], [c.T @ ri @ c, -ab.T]])
    lam = np.linalg.eigvals(h)
    rel = np.abs(lam.real) / np.maximum(1.0, np.abs(lam))
    candidates = np.unique(np.abs(lam.imag[rel <= IMAGINARY_TOLERANCE]))
    scale = 1.0 / np.sqrt(damping_scale(model))
    crossings = []
    for w in candidates:
        k = model.frequency_response([w])[0] * scale[:, None] * scale[None, :]
        # at a true crossing λ_min = -ε exactly; rounding near ω = 0 or ∞ (where K̃ → 0) is far smaller
        if np.linalg.eigvalsh(0.5 * (k + k.conj().T))[0] <= -0.5 * eps:
            crossings.append(float(w))
    return PassivityCertificate(not crossings, eps, np.array(crossings), float(np.min(rel)))


@dataclass(frozen=True)
class StorageFunction:
    """V(x) = ½ xᵀ P x with V' ≤ νᵀμ + ε |T⁻¹ν|² along every motion (module doc)."""

    P: Array
    epsilon: float
    scale: Array
    """T (diagonal, 3×3): ν̃ = T⁻¹ ν is the velocity in units of each DOF's peak damping."""

    def __call__(self, x: ArrayLike) -> Array:
        """V at each state (the last axis is the state)."""
        x = np.asarray(x, dtype=float)
        return 0.5 * np.einsum("...i,ij,...j->...", x, self.P, x)

    def slack(self, nu: ArrayLike) -> Array:
        """ε |T⁻¹ν|²: the supply the regularisation allows on top of νᵀμ (W), per sample of ν (..., 3)."""
        nu_s = np.asarray(nu, dtype=float) / np.diag(self.scale)
        return self.epsilon * np.sum(nu_s**2, axis=-1)


def storage_function(model: RadiationStateSpace, eps: float = EPSILON) -> StorageFunction:
    """The storage function from the positive-real Riccati equation; FluidMemoryError if there is none
    with P > 0 (the model is not positive real, or not minimal)."""
    a, b, c, r, t = _scaled(model, eps)
    try:
        x = scipy.linalg.solve_continuous_are(a, b, np.zeros_like(a), r, s=c.T)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise FluidMemoryError(f"{model.source or 'model'}: no storage function ({exc})") from exc
    p = -0.5 * (x + x.T)
    lam = np.linalg.eigvalsh(p)
    if lam[0] <= 0.0:
        raise FluidMemoryError(
            f"{model.source or 'model'}: the Riccati solution is not positive definite "
            f"(smallest eigenvalue {lam[0]:.3g}): not positive real"
        )
    return StorageFunction(p, eps, t)


@dataclass(frozen=True)
class FreeDecay:
    t: Array
    nu: Array
    """(N, 3) velocities."""
    x: Array
    """(N, n) memory states."""
    mu: Array
    """(N, 3) memory force."""
    kinetic: Array
    """½ νᵀ (M_RB + A(∞)) ν (J)."""
    final_velocity: Array
    """(M_RB + A(0))⁻¹ (M_RB + A(∞)) ν₀, the final-value theorem's limit."""


def free_decay(model: RadiationStateSpace, m_rb: ArrayLike, nu0: ArrayLike, t: ArrayLike) -> FreeDecay:
    """(M_RB + A(∞)) ν' = -μ from ν(0) = ν₀, x_r(0) = 0, exactly at the times ``t`` (s, from 0)."""
    m = np.asarray(m_rb, dtype=float) + model.A_inf
    n = model.n_states
    mi = np.linalg.inv(m)
    sys = np.zeros((3 + n, 3 + n))
    sys[:3, :3] = -mi @ model.Dr
    sys[:3, 3:] = -mi @ model.Cr
    sys[3:, :3] = model.Br
    sys[3:, 3:] = model.Ar
    t = np.asarray(t, dtype=float)
    z0 = np.concatenate([np.asarray(nu0, dtype=float), np.zeros(n)])
    dt = np.diff(t)
    z = np.empty((len(t), 3 + n))
    z[0] = z0
    step: dict[float, Array] = {}
    for k, h in enumerate(dt):
        e = step.get(float(h))
        if e is None:
            e = step[float(h)] = scipy.linalg.expm(sys * h)
        z[k + 1] = e @ z[k]
    nu, x = z[:, :3], z[:, 3:]
    mu = x @ model.Cr.T + nu @ model.Dr.T
    kinetic = 0.5 * np.einsum("ti,ij,tj->t", nu, m, nu)
    final = np.linalg.solve(np.asarray(m_rb, dtype=float) + model.zero_frequency_added_mass(), m @ z0[:3])
    return FreeDecay(t, nu, x, mu, kinetic, final)
