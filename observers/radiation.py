"""Radiation-force (fluid-memory) identification from frequency-domain hydrodynamic data.

The Cummins equation (Hajivand & Mousavizadegan 2010, eqs (2), (3), (6)) writes the radiation force as
an infinite-frequency added mass A(∞) and a convolution with the retardation function K(t)::

    f_rad = -A(∞) ν' - μ,      μ(t) = ∫₀ᵗ K(t - τ) ν(τ) dτ                                   (3), (6)

and replaces the convolution by a state-space model (eq (7))::

    ξ' = A_r ξ + B_r ν,        μ = C_r ξ + D_r ν                                              (7)

Its frequency response is K(jω) = B(ω) + jω(A(ω) - A(∞)); K(t) follows from B(ω) by eq (5) (written here
without the B(∞) term of the printed form: potential damping vanishes as ω → ∞)::

    K(t) = (2/π) ∫₀^∞ B(ω) cos(ωt) dω                                                         (5)

What this module does, per significant element of the horizontal-plane block (surge, sway, yaw):

1. **A(∞) jointly with K.** The data (strip theory, a finite band) lack A(∞). We fit the *complex added
   mass* H(jω) = A(ω) - jB(ω)/ω = A(∞) + G(jω), with K(s) = s G(s) and G strictly proper with numerator
   degree ≤ n - 2 (so K has the zero at s = 0 and relative degree one that radiation kernels have: K(0) = 0,
   K(t=0) finite). A(∞) is then the feedthrough of one causal rational model fitted to A and B together,
   so A(ω), B(ω) and A(∞) stay consistent with the Kramers-Kronig relations; a value read off the last
   few A(ω) points would not be (the data stop at 3.1 rad/s, where A(ω) is still moving). This is the
   joint identification of Perez & Fossen (2008, Modeling, Identification and Control 29(1)).
2. **Fit.** Vector fitting (Gustavsen & Semlyen 1999: pole relocation with unstable poles reflected into
   the left half-plane) gives starting poles; a variable-projection Gauss-Newton refinement then moves
   the poles, parametrised as -exp(θ) so they can only be stable, with residues and A(∞) solved linearly
   at every step. The residuals are weighted so that their sum of squares is exactly
   (1 - R²_A) + (1 - R²_B): the fit optimises the figures it is judged by.
3. **Data screening.** A point that no causal model of the cap order can reach (residual beyond
   `OUTLIER_SIGMAS` robust standard deviations, e.g. a zero-frequency artefact in A(ω) at the first
   frequency) is dropped and reported; at most `MAX_OUTLIER_FRACTION` of the points may go.
4. **Order.** The smallest order with R² ≥ `R2_TARGET` on both A and B, else the best up to the cap.
5. **Passivity.** K(jω) of the whole 3×3 must be positive real: its Hermitian part (the fitted damping
   matrix B̂(ω), K being symmetric) positive semidefinite at every frequency. Checked on a dense
   logarithmic grid from 1/1000 of the lowest to 1000 times the highest data frequency (beyond which the
   leading asymptotic terms, ∝ ω² and ∝ 1/ω², decide and are already visible). Enforced by residue
   perturbation (Gustavsen & Semlyen 2001): with the poles fixed, B̂ is linear in the residues; the
   smallest change of the weighted fit that lifts every violating eigenvalue back to the margin is a
   quadratic programme, repeated until no violation is left. If that fails, a diagonal feedthrough
   D_r (constant damping, the last resort) is added.

The passivity margin reported is the smallest eigenvalue, over the grid, of B̂(ω) scaled by its own
diagonal, D^{-1/2} B̂ D^{-1/2}: 1 for uncoupled elements, 0 on the boundary of positive-realness, < 0 for
a model that generates energy. It is scale-free, so it does not vanish where B̂ itself tends to zero
(ω → 0 and ω → ∞). The diagonal itself is checked separately (`min_diagonal_damping`, relative to its peak).

Pure numerics: arrays in, arrays out; loading files is `wire.hydro`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.special
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.floating[Any]]
CArray = NDArray[np.complexfloating[Any, Any]]

DOF_NAMES = ("surge", "sway", "yaw")
"""The horizontal-plane degrees of freedom, in the order of ν = [u, v, r]."""
YAW_INDEX = 2
"""Where yaw, the one rotation, sits in `DOF_NAMES`."""
SIX_DOF_INDEX = (0, 1, 5)
"""Where surge, sway and yaw sit in 6-DOF hydrodynamic data (1-based: 1, 2, 6)."""

R2_TARGET = 0.99
"""An order is good enough when both A(ω) and B(ω) reach this coefficient of determination."""
MAX_ORDER = 10
"""Order cap of one element; beyond this the model only chases the data's own noise."""
MIN_ORDER = 2
SIGNIFICANCE = 0.01
"""An off-diagonal element is modelled when max|B_ij| ≥ SIGNIFICANCE·√(max B_ii · max B_jj): its
damping is at least 1 % of the geometric mean of the two diagonal dampings it couples (the coupling
coefficient bounded by 1 for a passive body). Below that its fluid memory is within the fit error of
the diagonal elements."""
SCREEN_ORDER = 6
OUTLIER_SIGMAS = 6.0
MAX_OUTLIER_FRACTION = 0.1
DAMPING_FLOOR = 1e-6
"""A diagonal damping is kept above DAMPING_FLOOR × its peak, shaped like its asymptotes (∝ ω² below the
peak frequency, ∝ ω⁻² above): strictly positive, and never more than the model structure can give."""
PASSIVITY_MARGIN_TARGET = 1e-3
"""Margin the enforcement aims for when it has to act (a hair above the boundary, so rounding in a
simulation cannot cross it)."""
MIN_DAMPING_RATIO = 0.3
"""Smallest damping ratio of a fitted pole pair. Radiation kernels of ships decay within tens of seconds
(the poles MSS identifies for its supply vessel have ζ ≥ 0.4); a nearly undamped pole is how a fit
chases one bad point with a resonance narrower than the data can resolve."""
GRID_DECADES = 3.0
GRID_POINTS = 3000


# --------------------------------------------------------------------------------------------------
# One element: G(s) = Σ r_k / (s - p_k), K(s) = s G(s), H(s) = A∞ + G(s)
# --------------------------------------------------------------------------------------------------


def _basis(s: CArray, poles: CArray) -> CArray:
    """Real-parameter basis of G. ``poles`` holds one entry per real pole and one (Im > 0) per conjugate
    pair; a real pole has one parameter (its residue), a pair two (Re and Im of the residue of p, the
    conjugate pole getting the conjugate residue). Columns: m × order."""
    cols = []
    for p in poles:
        if p.imag == 0.0:
            cols.append(1.0 / (s - p))
        else:
            a, b = 1.0 / (s - p), 1.0 / (s - np.conj(p))
            cols.append(a + b)
            cols.append(1j * a - 1j * b)
    return np.stack(cols, axis=1)


def _residue_sum_row(poles: CArray) -> Array:
    """c with cᵀx = Σ_k r_k over all poles (conjugates included): Σr = 0 makes the numerator degree of G
    at most n - 2, i.e. K strictly proper (B(∞) = 0)."""
    row: list[float] = []
    for p in poles:
        row.extend([1.0] if p.imag == 0.0 else [2.0, 0.0])
    return np.array(row)


def _realisation(poles: CArray, x: Array) -> tuple[Array, Array, Array]:
    """Real (a, b, c) with c (sI - a)⁻¹ b = Σ x-weighted basis of `_basis` (the parameters ``x``)."""
    n = len(x)
    a = np.zeros((n, n))
    b = np.zeros(n)
    c = np.zeros(n)
    i = 0
    for p in poles:
        if p.imag == 0.0:
            a[i, i] = p.real
            b[i] = 1.0
            c[i] = x[i]
            i += 1
        else:
            a[i : i + 2, i : i + 2] = [[p.real, p.imag], [-p.imag, p.real]]
            b[i] = 2.0
            c[i : i + 2] = x[i : i + 2]
            i += 2
    return a, b, c


def _order(poles: CArray) -> int:
    return int(sum(1 if p.imag == 0.0 else 2 for p in poles))


@dataclass(frozen=True)
class ElementModel:
    """The identified model of one element K_ij: poles, residues of G and A_ij(∞).

    ``poles`` and ``x`` follow `_basis` (one entry per real pole or conjugate pair; real parameters).
    """

    poles: CArray
    x: Array
    a_inf: float

    @property
    def order(self) -> int:
        return _order(self.poles)

    def G(self, w: ArrayLike) -> CArray:
        s = 1j * np.atleast_1d(np.asarray(w, dtype=float))
        return _basis(s, self.poles) @ self.x

    def K(self, w: ArrayLike) -> CArray:
        """K(jω) = B(ω) + jω(A(ω) - A(∞))."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        return 1j * w * self.G(w)

    def added_mass(self, w: ArrayLike) -> Array:
        return self.a_inf + self.G(w).real

    def damping(self, w: ArrayLike) -> Array:
        return self.K(w).real

    def state_space(self) -> tuple[Array, Array, Array]:
        """Real (a, b, c) of K itself: K(s) = s·G(s) = Σ r_k p_k / (s - p_k) when Σ r_k = 0."""
        a, b, c = _realisation(self.poles, self.x)
        return a, b, c @ a

    def impulse(self, t: ArrayLike) -> Array:
        """K(t) = c e^{at} b, the model's retardation function."""
        a, b, c = self.state_space()
        t = np.atleast_1d(np.asarray(t, dtype=float))
        lam, v = np.linalg.eig(a)
        cb = (c @ v) * np.linalg.solve(v, b)
        return np.real(np.exp(np.outer(t, lam)) @ cb)


@dataclass(frozen=True)
class _Data:
    """One element's data prepared for fitting: weights turn residuals into (1 - R²) shares."""

    w: Array
    A: Array
    B: Array
    a_share: float = 1.0
    """Relative weight of A(ω) against B(ω); the screening fit ignores A (see `_screen`)."""
    diagonal: bool = False
    """A diagonal element: its damping must stay positive, also at the ends (`_asymptote_rows`)."""
    coupling_bounds: tuple[float, float] | None = None
    """An off-diagonal element: bounds on |its asymptote coefficients| (ω → 0, ω → ∞), from the two
    diagonal elements it couples (`coupling_bounds`)."""

    @property
    def weight_a(self) -> float:
        return self.a_share / max(float(np.linalg.norm(self.A - self.A.mean())), 1e-300)

    @property
    def weight_b(self) -> float:
        return 1.0 / max(float(np.linalg.norm(self.B - self.B.mean())), 1e-300)


def r_squared(y: ArrayLike, y_hat: ArrayLike) -> float:
    """Coefficient of determination 1 - Σ(y - ŷ)² / Σ(y - ȳ)²."""
    y, y_hat = np.asarray(y, dtype=float), np.asarray(y_hat, dtype=float)
    ss = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - y_hat) ** 2)) / ss if ss > 0 else 1.0


def _design(data: _Data, poles: CArray) -> tuple[Array, Array, Array]:
    """Weighted real least-squares system for (y, A∞) with x = Z y (Σr = 0 built in).

    Rows: weighted A residuals (real part of H), then weighted B residuals (-ω × imaginary part of H).
    Returns (matrix, right-hand side, Z)."""
    phi = _basis(1j * data.w, poles)
    z = scipy.linalg.null_space(_residue_sum_row(poles)[None, :])
    pz = phi @ z
    wa, wb = data.weight_a, data.weight_b
    top = np.hstack([wa * pz.real, wa * np.ones((len(data.w), 1))])
    bottom = np.hstack([wb * (-data.w[:, None] * pz.imag), np.zeros((len(data.w), 1))])
    return np.vstack([top, bottom]), np.concatenate([wa * data.A, wb * data.B]), z


def _moment_row(poles: CArray, f: CArray) -> Array:
    """Row c with cᵀx = Σ_k r_k f(p_k) over all poles (conjugates included; f(p̄) = conj f(p))."""
    row: list[float] = []
    for p, fp in zip(poles, f, strict=True):
        row.extend([fp.real] if p.imag == 0.0 else [2.0 * fp.real, -2.0 * fp.imag])
    return np.array(row)


def _asymptote_rows(data: _Data, poles: CArray, z: Array) -> tuple[Array, Array]:
    """Linear constraints (rows on [y, A∞], bounds) that keep a diagonal B̂(ω) positive at both ends.

    B̂(ω) → ω² Σ r/p² as ω → 0 and → -Σ r p²/ω² as ω → ∞ (Σr = 0). Both coefficients must be at least
    the `_damping_floor` (10⁻⁶ of the peak damping on those asymptotes): a fit left free there picks
    whichever sign suits the data, and data that fall off like ω⁶ below the band do not care."""
    low = np.append(_moment_row(poles, 1.0 / poles**2) @ z, 0.0)
    high = np.append(-_moment_row(poles, poles**2) @ z, 0.0)
    if data.coupling_bounds is not None:  # -bound ≤ coefficient ≤ bound, both ends
        b_low, b_high = data.coupling_bounds
        return np.vstack([low, -low, high, -high]), -np.array([b_low, b_low, b_high, b_high])
    k = int(np.argmax(data.B))
    peak, w_peak = float(data.B[k]), float(data.w[k])
    rows = np.vstack([low, high])
    return rows, DAMPING_FLOOR * peak * np.array([1.0 / w_peak**2, w_peak**2])


def asymptotes(model: ElementModel) -> tuple[float, float]:
    """(c₀, c_∞) with B̂(ω) ≈ c₀ ω² as ω → 0 and B̂(ω) ≈ c_∞ / ω² as ω → ∞."""
    p = model.poles
    return float(_moment_row(p, 1.0 / p**2) @ model.x), float(-_moment_row(p, p**2) @ model.x)


def coupling_bounds(diag_i: ElementModel, diag_j: ElementModel, share: float = 0.99) -> tuple[float, float]:
    """Bounds on the asymptote coefficients of K_ij: ``share`` of √(c_ii c_jj) at each end, so that the
    2×2 block [[B̂_ii, B̂_ij], [B̂_ij, B̂_jj]] stays positive definite where the asymptotes rule (its
    scaled coupling at most ``share`` there). A real body may couple strongly at the ends (the test
    system's sway–yaw coupling is 0.62 there), so the bound is near the limit, not a design margin."""
    (li, hi), (lj, hj) = asymptotes(diag_i), asymptotes(diag_j)
    return share * math.sqrt(max(li * lj, 0.0)), share * math.sqrt(max(hi * hj, 0.0))


def _lstsq_with_bounds(m: Array, rhs: Array, g: Array, h: Array) -> Array:
    """min ‖m v - rhs‖ subject to g v ≥ h, for a handful of rows: every active set is tried (KKT).

    If rounding leaves no active set feasible (poles far outside the band make the rows ill-conditioned),
    the least violating candidate is returned; the passivity check downstream still judges the model."""
    norms = np.maximum(np.linalg.norm(g, axis=1), 1e-300)
    g, h = g / norms[:, None], h / norms
    best, best_key = None, (math.inf, math.inf)
    n = g.shape[0]
    for mask in range(1 << n):
        active = [i for i in range(n) if mask >> i & 1]
        if active:
            ga, ha = g[active], h[active]
            v0, *_ = np.linalg.lstsq(ga, ha, rcond=None)
            ns = scipy.linalg.null_space(ga)
            u, *_ = np.linalg.lstsq(m @ ns, rhs - m @ v0, rcond=None)
            v = v0 + ns @ u
        else:
            v, *_ = np.linalg.lstsq(m, rhs, rcond=None)
        violation = float(np.max(h - g @ v, initial=0.0))
        tolerance = 1e-9 * float(np.max(np.abs(h) + np.abs(g) @ np.abs(v), initial=1.0))
        key = (max(violation - tolerance, 0.0), float(np.sum((m @ v - rhs) ** 2)))
        if key < best_key:
            best, best_key = v, key
    assert best is not None
    return best


def _solve_linear(data: _Data, poles: CArray) -> tuple[ElementModel, Array]:
    m, rhs, z = _design(data, poles)
    if data.diagonal or data.coupling_bounds is not None:
        sol = _lstsq_with_bounds(m, rhs, *_asymptote_rows(data, poles, z))
    else:
        sol, *_ = np.linalg.lstsq(m, rhs, rcond=None)
    model = ElementModel(poles=poles, x=z @ sol[:-1], a_inf=float(sol[-1]))
    return model, m @ sol - rhs


def _stable(poles: CArray) -> CArray:
    """Reflect right-half-plane poles; keep one entry per conjugate pair (Im > 0) and real poles."""
    out = []
    for p in poles:
        p = complex(-abs(p.real) if p.real != 0 else -1e-6, p.imag)
        if p.imag >= 0:
            out.append(p if abs(p.imag) > 1e-12 * abs(p) else complex(p.real, 0.0))
    return np.array(out, dtype=complex)


def _initial_poles(w: Array, order: int) -> CArray:
    """Gustavsen's start: lightly damped pairs spread log-uniformly over the band, a real pole if odd."""
    n_pairs = order // 2
    beta = np.geomspace(w.min(), w.max(), n_pairs) if n_pairs else np.array([])
    poles = [complex(-0.01 * b, b) for b in beta]
    if order % 2:
        poles.append(complex(-math.sqrt(w.min() * w.max()), 0.0))
    return np.array(poles, dtype=complex)


def _vector_fit(data: _Data, order: int, iterations: int = 30) -> CArray:
    """Pole relocation of vector fitting on H(jω) = A(ω) - jB(ω)/ω (Gustavsen & Semlyen 1999)."""
    poles = _initial_poles(data.w, order)
    s = 1j * data.w
    h = data.A - 1j * data.B / data.w
    # weights per row as in `_design`, applied to real and imaginary parts of σH ≈ (σH)_fit
    wa, wb = data.weight_a, data.weight_b
    for _ in range(iterations):
        phi = _basis(s, poles)
        n = phi.shape[1]
        lhs = np.hstack([phi, np.ones((len(s), 1)), -h[:, None] * phi])
        mat = np.vstack([wa * lhs.real, wb * data.w[:, None] * lhs.imag])
        rhs = np.concatenate([wa * h.real, wb * data.w * h.imag])
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        x_sigma = sol[n + 1 :]
        a, b, c = _realisation(poles, x_sigma)
        new = _stable(np.linalg.eigvals(a - np.outer(b, c)).astype(complex))
        if _order(new) != order:  # a pair came out real twice etc.: keep the order by re-pairing
            break
        if len(new) == len(poles) and np.allclose(np.sort_complex(new), np.sort_complex(poles), rtol=1e-8):
            poles = new
            break
        poles = new
    return poles


def _theta(poles: CArray) -> Array:
    """Unconstrained parameters of stable, damped poles: a real pole -exp(θ); a pair ω_n = exp(θ₁),
    ζ = ζ_min + (1 - ζ_min)·logistic(θ₂)."""
    th: list[float] = []
    for p in poles:
        if p.imag == 0.0:
            th.append(math.log(max(-p.real, 1e-12)))
        else:
            wn = abs(p)
            zeta = min(max(-p.real / wn, MIN_DAMPING_RATIO + 1e-3), 1.0 - 1e-6)
            q = (zeta - MIN_DAMPING_RATIO) / (1.0 - MIN_DAMPING_RATIO)
            th.extend([math.log(wn), math.log(q / (1.0 - q))])
    return np.array(th)


def _poles_from_theta(th: Array, template: CArray) -> CArray:
    th = np.clip(th, -12.0, 12.0)  # a runaway step of the optimiser must not overflow exp
    out = []
    i = 0
    for p in template:
        if p.imag == 0.0:
            out.append(complex(-math.exp(th[i]), 0.0))
            i += 1
        else:
            wn = math.exp(th[i])
            zeta = MIN_DAMPING_RATIO + (1.0 - MIN_DAMPING_RATIO) / (1.0 + math.exp(-th[i + 1]))
            out.append(complex(-zeta * wn, wn * math.sqrt(max(1.0 - zeta * zeta, 1e-12))))
            i += 2
    return np.array(out, dtype=complex)


def _refine(data: _Data, poles: CArray) -> ElementModel:
    """Variable projection: poles move (stable by construction), residues and A∞ are linear."""

    def residual(th: Array) -> Array:
        return _solve_linear(data, _poles_from_theta(th, poles))[1]

    th0 = _theta(poles)
    res = scipy.optimize.least_squares(residual, th0, method="lm", max_nfev=400 * (len(th0) + 1))
    th = res.x if res.cost <= 0.5 * float(np.sum(residual(th0) ** 2)) else th0
    return _solve_linear(data, _poles_from_theta(th, poles))[0]


def fit_order(
    w: ArrayLike,
    A: ArrayLike,
    B: ArrayLike,
    order: int,
    *,
    diagonal: bool = False,
    bounds: tuple[float, float] | None = None,
    a_share: float = 1.0,
) -> ElementModel:
    """Fit one element at a given order (≥ 2). All poles stable; A∞ estimated jointly; a ``diagonal``
    element keeps positive damping asymptotes."""
    if order < MIN_ORDER:
        raise ValueError(f"order must be at least {MIN_ORDER} (K needs a zero at s = 0 and a pole pair)")
    data = _Data(np.asarray(w, float), np.asarray(A, float), np.asarray(B, float), a_share, diagonal, bounds)
    return _refine(data, _vector_fit(data, order))


@dataclass(frozen=True)
class ElementFit:
    """The chosen model of one element and how it was chosen."""

    dofs: tuple[int, int]
    model: ElementModel
    r2_a: float
    r2_b: float
    excluded_w: Array
    tried: dict[int, tuple[float, float]]
    """order → (R²_A, R²_B) for every order tried."""

    @property
    def order(self) -> int:
        return self.model.order


def _screen(data: _Data, order: int) -> NDArray[np.bool_]:
    """Points inconsistent with the rest: robust outliers of the residuals of a fit driven by B(ω) alone.

    Its A(ω) is the one the Kramers-Kronig relations imply from B(ω), up to the constant A∞ (taken as
    the median offset), so an artefact in A(ω), such as a zero-frequency value in the first bin, cannot
    bend it. A joint fit would chase such a point with a pole below the data band, where no other point
    contradicts it. The order is moderate (`SCREEN_ORDER`): enough for B's shape, no spare poles."""
    model = fit_order(data.w, data.A, data.B, order, a_share=0.0)
    implied = model.G(data.w).real
    implied += float(np.median(data.A - implied))
    errors = [
        (data.A - implied) / max(float(np.ptp(data.A)), 1e-300),
        (data.B - model.damping(data.w)) / max(float(np.ptp(data.B)), 1e-300),
    ]
    keep = np.ones(len(data.w), dtype=bool)
    for err in errors:
        dev = np.abs(err - np.median(err))
        # floor of 0.1 % of the data's range: a near-perfect fit must not turn rounding into outliers
        scale = max(1.4826 * float(np.median(dev)), 1e-3)
        keep &= dev <= OUTLIER_SIGMAS * scale
    allowed = int(MAX_OUTLIER_FRACTION * len(data.w))
    if np.count_nonzero(~keep) > allowed:  # never more than the allowance: drop only the worst
        worst_first = np.argsort(-np.maximum(np.abs(errors[0]), np.abs(errors[1])))
        keep[:] = True
        keep[worst_first[:allowed]] = False
    return keep


def fit_element(
    w: ArrayLike,
    A: ArrayLike,
    B: ArrayLike,
    *,
    dofs: tuple[int, int] = (0, 0),
    max_order: int = MAX_ORDER,
    r2_target: float = R2_TARGET,
    screen: bool = True,
    bounds: tuple[float, float] | None = None,
) -> ElementFit:
    """Choose the order and fit one element (see the module docstring for the method). ``bounds`` for an
    off-diagonal element come from `coupling_bounds` of its diagonal elements."""
    w, A, B = (np.asarray(v, dtype=float) for v in (w, A, B))
    if not (w.shape == A.shape == B.shape and w.ndim == 1 and len(w) >= 4):
        raise ValueError("w, A, B must be 1-D arrays of the same length (at least 4 frequencies)")
    if np.any(w <= 0) or np.any(np.diff(w) <= 0):
        raise ValueError("frequencies must be positive and increasing")
    keep = _screen(_Data(w, A, B), min(SCREEN_ORDER, max_order)) if screen else np.ones(len(w), bool)
    wk, Ak, Bk = w[keep], A[keep], B[keep]
    diagonal = dofs[0] == dofs[1]
    grid = passivity_grid(w)
    tried: dict[int, tuple[float, float]] = {}
    models: dict[int, ElementModel] = {}
    for n in range(MIN_ORDER, max_order + 1):
        m = fit_order(wk, Ak, Bk, n, diagonal=diagonal, bounds=None if diagonal else bounds)
        if diagonal:  # Re K_ii ≥ 0 everywhere, not only at the ends: part of the fit, judged after it
            fixed = _enforce_residues({dofs: (_Data(wk, Ak, Bk, diagonal=True), m)}, grid)
            if fixed is None:
                continue
            m = fixed[dofs]
        models[n] = m
        tried[n] = (r_squared(Ak, m.added_mass(wk)), r_squared(Bk, m.damping(wk)))
        if min(tried[n]) >= r2_target:
            break
    if not tried:
        raise ArithmeticError(f"no passive model of element {dofs} up to order {max_order}")
    good = [n for n, r in tried.items() if min(r) >= r2_target]
    n_best = min(good) if good else max(tried, key=lambda n: min(tried[n]))
    return ElementFit(dofs, models[n_best], *tried[n_best], w[~keep], tried)


# --------------------------------------------------------------------------------------------------
# The 3×3 model: significance, passivity, state space
# --------------------------------------------------------------------------------------------------


def significant_elements(B: ArrayLike, threshold: float = SIGNIFICANCE) -> list[tuple[int, int]]:
    """Upper-triangle elements (i ≤ j) of a 3×3×N damping array worth modelling (see `SIGNIFICANCE`)."""
    B = np.asarray(B, dtype=float)
    peak = np.max(np.abs(B), axis=2)
    out = []
    for i in range(3):
        for j in range(i, 3):
            if i == j:
                if peak[i, i] > 0:
                    out.append((i, j))
            elif peak[i, j] >= threshold * math.sqrt(peak[i, i] * peak[j, j]) and peak[i, j] > 0:
                out.append((i, j))
    return out


def passivity_grid(w: ArrayLike) -> Array:
    """Dense logarithmic grid from 10⁻³ × the lowest to 10³ × the highest data frequency, plus the data,
    plus the two limits ω = 0 and ω = ∞ (evaluated on the asymptotes, `asymptote_matrices`)."""
    w = np.asarray(w, dtype=float)
    lo, hi = math.log10(w.min()) - GRID_DECADES, math.log10(w.max()) + GRID_DECADES
    return np.concatenate([[0.0], np.unique(np.concatenate([np.logspace(lo, hi, GRID_POINTS), w])), [np.inf]])


@dataclass(frozen=True)
class PassivityReport:
    passive: bool
    margin: float
    """min over the grid of λ_min(D^{-1/2} B̂ D^{-1/2}), D = diag B̂ (1: uncoupled, 0: boundary)."""
    margin_w: float
    """Frequency (rad/s) where the margin is attained (0 or inf: on the asymptotes)."""
    min_diagonal_damping: float
    """min over the grid and the diagonal of B̂_ii(ω) / max_ω B̂_ii(ω) (must be ≥ 0)."""
    enforced: str
    """"none", "residues" (perturbed), or "feedthrough" (constant damping added)."""


def _element_damping(m: ElementModel, grid: Array) -> Array:
    """B̂(ω) on the grid; at ω = 0 and ω = ∞ the asymptote coefficients c₀ and c_∞ (`asymptotes`)."""
    out = np.empty(len(grid))
    finite = np.isfinite(grid) & (grid > 0)
    out[finite] = m.damping(grid[finite])
    c0, cinf = asymptotes(m)
    out[grid == 0] = c0
    out[np.isinf(grid)] = cinf
    return out


def _element_damping_jacobian(m: ElementModel, z: Array, grid: Array) -> Array:
    """∂B̂/∂δ for x = x⁰ + Z δ, on the grid (rows at 0 and ∞: of the asymptote coefficients)."""
    out = np.empty((len(grid), z.shape[1]))
    finite = np.isfinite(grid) & (grid > 0)
    out[finite] = -grid[finite, None] * (_basis(1j * grid[finite], m.poles) @ z).imag
    out[grid == 0] = _moment_row(m.poles, 1.0 / m.poles**2) @ z
    out[np.isinf(grid)] = -_moment_row(m.poles, m.poles**2) @ z
    return out


def damping_matrix(elements: dict[tuple[int, int], ElementModel], w: Array, d: Array | None = None) -> Array:
    """B̂(ω) = Re K(jω) as an (N, 3, 3) array from the fitted elements (symmetric), plus feedthrough d.
    Grid points 0 and ∞ hold the asymptote coefficient matrices (`asymptotes`)."""
    out = np.zeros((len(w), 3, 3))
    for (i, j), m in elements.items():
        b = _element_damping(m, w)
        out[:, i, j] = b
        out[:, j, i] = b
    if d is not None and np.any(d):
        ends = (w == 0) | np.isinf(w)
        out[~ends] += np.diag(d)[None, :, :]
        out[ends] = np.diag(d)[None, :, :]  # a constant damping dominates both limits
    return out


def _floors(bh_ii: Array, grid: Array) -> Array:
    """The diagonal floor (`DAMPING_FLOOR` of the peak, shaped like the asymptotes) on the grid."""
    finite = np.isfinite(grid) & (grid > 0)
    k = int(np.argmax(np.where(finite, bh_ii, -np.inf)))
    peak, w_peak = bh_ii[k], grid[k]
    out = np.empty(len(grid))
    ratio = grid[finite] / w_peak
    out[finite] = DAMPING_FLOOR * peak * np.minimum(ratio, 1.0 / ratio) ** 2
    out[grid == 0] = DAMPING_FLOOR * peak / w_peak**2
    out[np.isinf(grid)] = DAMPING_FLOOR * peak * w_peak**2
    return out


def _check(
    elements: dict[tuple[int, int], ElementModel], grid: Array, d: Array | None = None
) -> tuple[float, float, float, Array, Array]:
    """(margin, ω at margin, min relative diagonal, per-ω margins, per-ω eigenvectors in B̂ coordinates).

    Only the DOFs that have a diagonal model count (an unmodelled DOF has no fluid memory at all)."""
    bh = damping_matrix(elements, grid, d)
    dofs = sorted({i for i, j in elements if i == j})
    mask = np.zeros(3, dtype=bool)
    mask[dofs] = True
    bh = np.where(mask[None, :, None] & mask[None, None, :], bh, np.eye(3)[None])
    diag = np.diagonal(bh, axis1=1, axis2=2)
    finite = np.isfinite(grid) & (grid > 0)
    peak = np.maximum(np.max(np.abs(diag[finite]), axis=0), 1e-300)
    min_diag = float(np.min(diag[finite] / peak))
    if np.any(diag[~finite] < 0.0):  # an asymptote of the wrong sign: negative somewhere beyond the grid
        min_diag = -1.0
    scale = 1.0 / np.sqrt(np.maximum(diag, 1e-300 * np.abs(diag).max()))
    s = bh * scale[:, :, None] * scale[:, None, :]
    lam, vec = np.linalg.eigh(s)
    per_w = lam[:, 0]
    k = int(np.argmin(per_w))
    u = vec[:, :, 0] * scale  # back to B̂ coordinates: λ_min(S) ≥ m  ⇔  uᵀ(B̂ - m diag B̂)u ≥ 0
    return float(per_w[k]), float(grid[k]), min_diag, per_w, u


def _refine_grid(elements: dict[tuple[int, int], ElementModel], grid: Array, d: Array | None = None) -> Array:
    """The grid with 32 more points around each of its 20 lowest local minima of the margin and of each
    diagonal damping: an enforced model touches the bound at grid points and may dip between them."""
    _, _, _, per_w, _ = _check(elements, grid, d)
    diag = np.diagonal(damping_matrix(elements, grid, d), axis1=1, axis2=2)
    inner = np.arange(2, len(grid) - 2)  # neighbours of the 0 and ∞ rows are finite points
    extra = []
    for values in [per_w, *(diag[:, i] / max(np.max(np.abs(diag[1:-1, i])), 1e-300) for i in range(3))]:
        v = values[inner]
        minima = inner[(v <= values[inner - 1]) & (v <= values[inner + 1])]
        for k in minima[np.argsort(values[minima])][:20]:
            extra.append(np.geomspace(grid[k - 1], grid[k + 1], 34)[1:-1])
    if not extra:
        return grid
    finite = np.unique(np.concatenate([grid[1:-1], *extra]))
    return np.concatenate([[0.0], finite, [np.inf]])


def _min_change(h: Array, g: Array, rhs: Array) -> Array:
    """argmin ½ vᵀ h v subject to g v ≥ rhs (SLSQP from v = 0: the smallest weighted change of the fit)."""
    res = scipy.optimize.minimize(
        lambda v: 0.5 * float(v @ h @ v),
        np.zeros(h.shape[0]),
        jac=lambda v: h @ v,
        constraints=[{"type": "ineq", "fun": lambda v: g @ v - rhs, "jac": lambda v: g}],
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-14},
    )
    return np.asarray(res.x, dtype=float)


def _enforce_residues(
    fits: dict[tuple[int, int], tuple[_Data, ElementModel]], grid: Array, iterations: int = 30
) -> dict[tuple[int, int], ElementModel] | None:
    """Residue perturbation: the smallest weighted change of the fit that makes B̂ ⪰ margin·diag B̂ and
    B̂_ii ≥ floor at the violating grid points (the asymptotes included); repeated, since lifting one
    frequency can push down another."""
    keys = list(fits)
    models = {k: fits[k][1] for k in keys}
    target = PASSIVITY_MARGIN_TARGET
    for _ in range(iterations):
        grid = _refine_grid(models, grid)
        margin, _, min_diag, per_w, u = _check(models, grid)
        if margin >= 0.0 and min_diag >= 0.0:
            return models
        # Parametrisation: x_k = x_k⁰ + Z_k δ_k (Σr = 0 preserved); B̂ is linear in δ.
        zs, dbs, objs, offsets = [], [], [], [0]
        for k in keys:
            data, m = fits[k]
            z = scipy.linalg.null_space(_residue_sum_row(m.poles)[None, :])
            dbs.append(_element_damping_jacobian(m, z, grid))
            pd = _basis(1j * data.w, m.poles) @ z
            objs.append(np.vstack([data.weight_a * pd.real, data.weight_b * (-data.w[:, None] * pd.imag)]))
            zs.append(z)
            offsets.append(offsets[-1] + z.shape[1])
        nvar = offsets[-1]
        bh = damping_matrix(models, grid)
        diag = np.diagonal(bh, axis1=1, axis2=2)
        rows: list[Array] = []
        rhs: list[float] = []
        # diagonal: B̂_ii + ΔB̂_ii ≥ floor_i(ω) where below it
        for idx, (i, j) in enumerate(keys):
            if i != j:
                continue
            floor = _floors(diag[:, i], grid)
            bad = np.flatnonzero(diag[:, i] < floor)
            for g in np.unique(np.r_[bad[:: max(1, len(bad) // 60)], bad[[0, -1]] if len(bad) else []]):
                row = np.zeros(nvar)
                row[offsets[idx] : offsets[idx + 1]] = dbs[idx][int(g)]
                rows.append(row)
                rhs.append(floor[int(g)] - diag[int(g), i])
        # coupling: uᵀ(B̂ + ΔB̂ - m·diag(B̂ + ΔB̂))u ≥ 0 where the diagonal is already positive (elsewhere
        # the diagonal constraints come first; the eigenvector there means nothing yet)
        positive = np.all((diag > 0.0) | ~np.isin(np.arange(3), [i for i, j in keys if i == j]), axis=1)
        bad = np.flatnonzero((per_w < target) & positive)
        for g in bad[:: max(1, len(bad) // 60)]:
            uu = u[g]
            row = np.zeros(nvar)
            for idx, (i, j) in enumerate(keys):
                coef = uu[i] * uu[i] * (1.0 - target) if i == j else 2.0 * uu[i] * uu[j]
                row[offsets[idx] : offsets[idx + 1]] += coef * dbs[idx][g]
            rows.append(row)
            rhs.append(-float(uu @ (bh[g] - target * np.diag(np.diag(bh[g]))) @ uu))
        if not rows:
            break
        g_rows, g_rhs = np.array(rows), np.array(rhs)
        norms = np.maximum(np.linalg.norm(g_rows, axis=1), 1e-300)  # SLSQP's tolerance is absolute
        g_rows, g_rhs = g_rows / norms[:, None], g_rhs / norms
        obj = scipy.linalg.block_diag(*objs)
        res_x = _min_change(obj.T @ obj, g_rows, g_rhs)
        new = {}
        for idx, k in enumerate(keys):
            data, m = fits[k]
            x = m.x + zs[idx] @ res_x[offsets[idx] : offsets[idx + 1]]
            a_inf = float(np.mean(data.A - (_basis(1j * data.w, m.poles) @ x).real))  # A∞ re-fitted
            new[k] = ElementModel(m.poles, x, a_inf)
            fits[k] = (data, new[k])
        models = new
    grid = _refine_grid(models, grid)
    margin, _, min_diag, _, _ = _check(models, grid)
    return models if margin >= 0.0 and min_diag >= 0.0 else None


def _feedthrough(elements: dict[tuple[int, int], ElementModel], grid: Array) -> Array:
    """Smallest t with B̂ + t·diag(peak B̂_ii) passive on the grid (bisection): the last resort."""
    finite = np.isfinite(grid) & (grid > 0)
    peak = np.max(np.abs(np.diagonal(damping_matrix(elements, grid[finite]), axis1=1, axis2=2)), axis=0)

    def ok(t: float) -> bool:
        margin, _, min_diag, _, _ = _check(elements, grid, t * peak)
        return margin >= 0.0 and min_diag >= 0.0

    lo, hi = 0.0, 1e-6
    while not ok(hi):
        lo, hi = hi, hi * 4.0
        if hi > 1.0:
            raise ArithmeticError("no feedthrough up to the peak damping makes the model passive")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi * peak


class _StateSpaceResponses:
    """The frequency and impulse responses of μ = C_r ξ + D_r ν, ξ' = A_r ξ + B_r ν with A(∞): one
    implementation for the identified model with its report and for the bare state space."""

    Ar: Array
    Br: Array
    Cr: Array
    Dr: Array
    A_inf: Array

    def frequency_response(self, w: ArrayLike) -> CArray:
        """K(jω) = C_r (jωI - A_r)⁻¹ B_r + D_r, (N, 3, 3)."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        n = self.Ar.shape[0]
        out = np.empty((len(w), 3, 3), dtype=complex)
        for k, wk in enumerate(w):
            out[k] = self.Cr @ np.linalg.solve(1j * wk * np.eye(n) - self.Ar, self.Br) + self.Dr
        return out

    def added_mass(self, w: ArrayLike) -> Array:
        """A(ω) = A(∞) + Im K(jω)/ω, (N, 3, 3)."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        return self.A_inf[None] + self.frequency_response(w).imag / w[:, None, None]

    def damping(self, w: ArrayLike) -> Array:
        """B(ω) = Re K(jω), (N, 3, 3)."""
        return self.frequency_response(w).real

    def impulse_response(self, t: ArrayLike) -> Array:
        """K(t) = C_r e^{A_r t} B_r, (N, 3, 3) (a feedthrough D_r adds D_r δ(t), not sampled here)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        lam, v = np.linalg.eig(self.Ar)
        left = self.Cr @ v
        right = np.linalg.solve(v, self.Br)
        return np.real(np.einsum("il,tl,lj->tij", left, np.exp(np.outer(t, lam)), right))


@dataclass(frozen=True)
class RadiationModel(_StateSpaceResponses):
    """Fluid-memory model μ = C_r ξ + D_r ν, ξ' = A_r ξ + B_r ν (3 inputs ν = [u, v, r], 3 outputs μ), with
    the infinite-frequency added mass and the fit report."""

    Ar: Array
    Br: Array
    Cr: Array
    Dr: Array
    A_inf: Array
    fits: dict[tuple[int, int], ElementFit]
    passivity: PassivityReport
    w_data: Array = field(repr=False)

    @property
    def elements(self) -> dict[tuple[int, int], ElementModel]:
        return {k: f.model for k, f in self.fits.items()}

    def report(self) -> list[dict[str, object]]:
        """One row per element: DOFs, order, R² of A and B, A(∞) and its unit, excluded frequencies."""
        rows: list[dict[str, object]] = []
        for (i, j), f in self.fits.items():
            rows.append(
                {
                    "element": f"({SIX_DOF_INDEX[i] + 1},{SIX_DOF_INDEX[j] + 1})",
                    "dofs": f"{DOF_NAMES[i]}-{DOF_NAMES[j]}",
                    "order": f.order,
                    "r2_A": f.r2_a,
                    "r2_B": f.r2_b,
                    "A_inf": f.model.a_inf,
                    "A_inf_unit": added_mass_unit(i, j),
                    "excluded_w": [float(v) for v in f.excluded_w],
                }
            )
        return rows


def added_mass_unit(i: int, j: int) -> str:
    """The SI unit of added-mass element (i, j) of (surge, sway, yaw): kg between two translations, kg·m
    between a translation and the rotation, kg·m² for yaw on yaw (force per acceleration, force per
    angular acceleration, moment per angular acceleration)."""
    rotations = (i == YAW_INDEX) + (j == YAW_INDEX)
    return ("kg", "kg·m", "kg·m²")[rotations]


def _assemble(elements: dict[tuple[int, int], ElementModel], d: Array) -> tuple[Array, Array, Array, Array]:
    """Block-diagonal MIMO realisation: element (i, j) maps ν_j to μ_i; an off-diagonal element is realised
    twice, once for (i, j) and once for (j, i) (K is symmetric)."""
    blocks = []
    for (i, j), m in elements.items():
        blocks.append((i, j, m))
        if i != j:
            blocks.append((j, i, m))
    n = sum(m.order for _, _, m in blocks)
    Ar, Br, Cr = np.zeros((n, n)), np.zeros((n, 3)), np.zeros((3, n))
    k = 0
    for i, j, m in blocks:
        a, b, c = m.state_space()
        o = len(b)
        Ar[k : k + o, k : k + o] = a
        Br[k : k + o, j] = b
        Cr[i, k : k + o] = c
        k += o
    return Ar, Br, Cr, np.diag(d)


def damping_sign_problem(B: ArrayLike) -> str | None:
    """Why ``B`` (as `identify` takes it) cannot be radiation damping, or None: a diagonal element that is
    negative over most of the frequencies where it is not negligible (under 1 % of its largest magnitude).

    Radiation damping takes energy out of the motion: B_ii(ω) ≥ 0 on the diagonal (the 3×3 B(ω) is positive
    semi-definite). A few slightly negative values are a panel code's numerical noise (irregular
    frequencies) and are left to the passivity check; a whole element below zero is data exported with the
    other sign convention, which no passive model fits (the identification ends without a model)."""
    b = np.asarray(B, dtype=float)
    if b.ndim != 3 or b.shape[0] != b.shape[1] or b.shape[0] not in (3, 6):
        return None  # (`identify` says what shape it needs)
    dofs = SIX_DOF_INDEX if b.shape[0] == 6 else range(3)
    for name, k in zip(DOF_NAMES, dofs, strict=True):
        bii = b[k, k]
        big = np.abs(bii) >= 0.01 * np.max(np.abs(bii), initial=0.0)
        if np.count_nonzero(big) and np.count_nonzero(bii[big] < 0) > 0.5 * np.count_nonzero(big):
            return (
                f"B({name}, {name}) is negative at {np.count_nonzero(bii[big] < 0)} of "
                f"{np.count_nonzero(big)} frequencies (as low as {bii.min():.3g}): radiation damping is "
                "≥ 0 on the diagonal; is the data's sign convention the other one (B exported as −B)?"
            )
    return None


def identify(
    w: ArrayLike,
    A: ArrayLike,
    B: ArrayLike,
    *,
    max_order: int = MAX_ORDER,
    r2_target: float = R2_TARGET,
    significance: float = SIGNIFICANCE,
    screen: bool = True,
) -> RadiationModel:
    """Identify the 3×3 fluid-memory model from A(ω), B(ω).

    ``A`` and ``B`` are (6, 6, N) (6-DOF data; surge, sway, yaw are taken) or (3, 3, N) arrays, ``w`` the N
    frequencies (rad/s). The off-diagonal data are symmetrised ((B_ij + B_ji)/2) before fitting."""
    w = np.asarray(w, dtype=float)
    a_in, b_in = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    if (
        a_in.shape != b_in.shape
        or a_in.shape[-1] != len(w)
        or a_in.shape[0] != a_in.shape[1]
        or a_in.shape[0] not in (3, 6)
    ):
        raise ValueError(
            f"A and B must be (6, 6, N) or (3, 3, N) with N = len(w); got {a_in.shape}, {b_in.shape}"
        )
    if a_in.shape[0] == 6:
        idx = np.ix_(SIX_DOF_INDEX, SIX_DOF_INDEX)
        a_in, b_in = a_in[idx], b_in[idx]
    a3 = 0.5 * (a_in + a_in.transpose(1, 0, 2))
    b3 = 0.5 * (b_in + b_in.transpose(1, 0, 2))
    fits: dict[tuple[int, int], ElementFit] = {}
    # diagonal elements first: their asymptotes bound the coupling elements' (`coupling_bounds`)
    for i, j in sorted(significant_elements(b3, significance), key=lambda k: k[0] != k[1]):
        bounds = None
        if i != j:
            if (i, i) not in fits or (j, j) not in fits:
                continue  # coupling between DOFs without fluid memory of their own: nothing to couple
            bounds = coupling_bounds(fits[(i, i)].model, fits[(j, j)].model)
        fits[(i, j)] = fit_element(
            w,
            a3[i, j],
            b3[i, j],
            dofs=(i, j),
            max_order=max_order,
            r2_target=r2_target,
            screen=screen,
            bounds=bounds,
        )
    elements = {k: f.model for k, f in fits.items()}
    grid = _refine_grid(elements, passivity_grid(w))
    margin, _, min_diag, _, _ = _check(elements, grid)
    enforced = "none"
    d: Array = np.zeros(3)
    if margin < 0.0 or min_diag < 0.0:
        per = {}
        for k, f in fits.items():
            keep = ~np.isin(w, f.excluded_w)
            per[k] = (_Data(w[keep], a3[k][keep], b3[k][keep]), f.model)
        fixed = _enforce_residues(per, grid)
        if fixed is not None:
            enforced = "residues"
            for k, m in fixed.items():
                data = per[k][0]
                f = fits[k]
                fits[k] = ElementFit(
                    f.dofs,
                    m,
                    r_squared(data.A, m.added_mass(data.w)),
                    r_squared(data.B, m.damping(data.w)),
                    f.excluded_w,
                    f.tried,
                )
            elements = fixed
        else:
            enforced = "feedthrough"
            d = _feedthrough(elements, grid)
    grid = _refine_grid(elements, grid, d)
    margin, margin_w, min_diag, _, _ = _check(elements, grid, d)
    report = PassivityReport(margin >= 0.0 and min_diag >= 0.0, margin, margin_w, min_diag, enforced)
    Ar, Br, Cr, Dr = _assemble(elements, d)
    A_inf = np.zeros((3, 3))
    for (i, j), m in elements.items():
        A_inf[i, j] = A_inf[j, i] = m.a_inf
    return RadiationModel(Ar, Br, Cr, Dr, A_inf, fits, report, w)


def retardation_from_damping(w: ArrayLike, B: ArrayLike, t: ArrayLike, *, tail: bool = False) -> Array:
    """K(t) = (2/π) ∫ B(ω) cos(ωt) dω, eq (5), from sampled B(ω) (last axis = frequency).

    B is taken piecewise linear between the samples and zero at ω = 0 (potential damping vanishes there);
    each linear piece is integrated exactly against cos(ωt) (not sampled: at t = 30 s a 0.6 rad/s step of
    the data spans 18 rad of phase). Beyond the last frequency ω_m, B is zero (``tail=False``: what the data
    say, with a truncation error of about (2/π)·B(ω_m)·ω_m at t = 0 that rings down like 1/t), or
    ``tail=True``: B(ω_m)(ω_m/ω)², the decay of every model of the form fitted here (relative degree one),
    integrated exactly with the sine integral."""
    w = np.concatenate([[0.0], np.asarray(w, dtype=float)])
    B = np.asarray(B, dtype=float)
    B = np.concatenate([np.zeros((*B.shape[:-1], 1)), B], axis=-1)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    slope = np.diff(B, axis=-1) / np.diff(w)
    out = np.empty((*B.shape[:-1], len(t)))
    wm = float(w[-1])
    for k, tk in enumerate(t):
        if tk == 0.0:
            val = np.sum(0.5 * (B[..., 1:] + B[..., :-1]) * np.diff(w), axis=-1)
        else:
            # ∫ B cos(ωt) dω = [B sin(ωt)/t] + [β cos(ωt)/t²] per piece; the first term telescopes
            val = (B[..., -1] * math.sin(wm * tk) - B[..., 0] * math.sin(w[0] * tk)) / tk
            val = val + np.sum(slope * np.diff(np.cos(w * tk)), axis=-1) / tk**2
        if tail:
            # ∫_ωm^∞ cos(ωt)/ω² dω = cos(ωm t)/ωm - t (π/2 - Si(ωm t))
            si = float(scipy.special.sici(wm * tk)[0])
            val = val + B[..., -1] * wm**2 * (math.cos(wm * tk) / wm - tk * (0.5 * math.pi - si))
        out[..., k] = val
    return (2.0 / math.pi) * out


# --------------------------------------------------------------------------------------------------
# The 3×3 state space on its own: what the fluid-memory observer and the simulator's plant integrate
# --------------------------------------------------------------------------------------------------

_YAW_LENGTHS = np.array([0.0, 0.0, 1.0])
"""Powers of length each DOF adds to a coefficient: surge and sway none, yaw one (a moment, a rad/s)."""


class RadiationStateSpaceError(ValueError):
    """A radiation state space that cannot be used; the message names where it came from and why."""


def _frozen(value: ArrayLike, shape: tuple[int, ...], name: str, source: str) -> Array:
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise RadiationStateSpaceError(f"{source}: {name} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise RadiationStateSpaceError(f"{source}: {name} has non-finite values")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class RadiationStateSpace(_StateSpaceResponses):
    """μ = C_r ξ + D_r ν, ξ' = A_r ξ + B_r ν (ν = [u, v, r] in, μ = [X, Y, N] out, SI) with A(∞).

    The one object for a vessel's fluid memory: the plant integrates it (``simulator.plant``,
    ``simulator.fluid_memory``), the fluid-memory observer carries it (``observers.memory``). The matrices
    alone, without the fit report: `RadiationModel` gives one (`model_state_space`, `from_model`),
    `radiation_state_space` assembles one from per-element fits, and `froude_scaled` carries one to a
    geometrically similar hull. A_r is block diagonal, one block per identified element K_ij of the
    symmetric 3×3 K(s) (a coupling element such as sway-yaw is realised twice, once from v to N and once
    from r to Y); D_r is zero unless passivity had to be enforced by a constant damping. The arrays are
    read-only copies, checked on construction (shapes, finite, A(∞) symmetric, A_r stable).

    ``source`` says where it came from; ``hydro_sha256`` the SHA-256 of the hydrodynamic data it was
    identified from ("" if unknown); ``M_RB`` the rigid-body mass of the hull the data belong to, when the
    data give it (the mass A(∞) belongs with: a plant's mass is M_RB + A(∞))."""

    Ar: Array
    Br: Array
    Cr: Array
    Dr: Array
    A_inf: Array
    source: str = ""
    hydro_sha256: str = ""
    M_RB: Array | None = None
    _discrete: dict[float, tuple[Array, Array, Array]] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        where = self.source or "fluid-memory model"
        a = np.asarray(self.Ar)
        if a.ndim != 2 or a.shape[0] != a.shape[1]:
            raise RadiationStateSpaceError(f"{where}: A has shape {a.shape}, expected square (n, n)")
        n = a.shape[0]
        for name, key, shape in (
            ("A", "Ar", (n, n)),
            ("B", "Br", (n, 3)),
            ("C", "Cr", (3, n)),
            ("D", "Dr", (3, 3)),
            ("A_inf", "A_inf", (3, 3)),
        ):
            object.__setattr__(self, key, _frozen(getattr(self, key), shape, name, where))
        if not np.allclose(self.A_inf, self.A_inf.T, rtol=1e-9, atol=0.0):
            raise RadiationStateSpaceError(f"{where}: A_inf is not symmetric")
        if self.M_RB is not None:
            m_rb = _frozen(self.M_RB, (3, 3), "M_RB", where)
            if not np.allclose(m_rb, m_rb.T, rtol=1e-9, atol=0.0) or np.linalg.eigvalsh(m_rb)[0] <= 0.0:
                raise RadiationStateSpaceError(f"{where}: M_RB is not symmetric positive definite")
            object.__setattr__(self, "M_RB", m_rb)
        if n and np.max(np.linalg.eigvals(self.Ar).real) >= 0.0:
            raise RadiationStateSpaceError(
                f"{where}: A has an eigenvalue with Re ≥ 0 (the memory would not fade)"
            )

    @classmethod
    def from_model(
        cls, model: RadiationModel, *, source: str = "", hydro_sha256: str = "", M_RB: ArrayLike | None = None
    ) -> RadiationStateSpace:
        """From an identified `RadiationModel` (its block-diagonal realisation)."""
        m_rb = None if M_RB is None else np.asarray(M_RB, dtype=float)
        return cls(model.Ar, model.Br, model.Cr, model.Dr, model.A_inf, source, hydro_sha256, m_rb)

    @property
    def n_states(self) -> int:
        return int(self.Ar.shape[0])

    def static_gain(self) -> Array:
        """K(0) = D_r - C_r A_r⁻¹ B_r: the damping the fluid memory adds at zero frequency (0 without D_r)."""
        return np.asarray(self.Dr - self.Cr @ np.linalg.solve(self.Ar, self.Br))

    def zero_frequency_added_mass(self) -> Array:
        """A(0) = A(∞) + dK/ds(0) = A(∞) - C_r A_r⁻² B_r: the added mass of slow motion."""
        return np.asarray(self.A_inf - self.Cr @ np.linalg.solve(self.Ar, np.linalg.solve(self.Ar, self.Br)))

    def passivity_margin(self, w: ArrayLike) -> tuple[float, float]:
        """(smallest eigenvalue of the Hermitian part of K(jω) over ``w``, scaled by the largest diagonal
        damping seen, and the frequency where it occurs). ≥ 0 (to round-off): the model only dissipates."""
        w = np.asarray(w, dtype=float)
        K = self.frequency_response(w)
        herm = 0.5 * (K + np.conj(K.transpose(0, 2, 1)))
        lam = np.linalg.eigvalsh(herm)[:, 0]
        scale = max(float(np.max(np.real(np.diagonal(herm, axis1=1, axis2=2)))), 1e-300)
        k = int(np.argmin(lam))
        return float(lam[k] / scale), float(w[k])

    def max_rk4_step(self) -> float:
        """The largest step (s) with which classical RK4 integrating ξ' = A_r ξ is stable: for every
        eigenvalue λ the largest h with |1 + z + z²/2 + z³/6 + z⁴/24| ≤ 1, z = λh (bisection per λ)."""
        best = np.inf
        for lam in np.linalg.eigvals(self.Ar):
            lo, hi = 0.0, 10.0 / abs(lam)
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                z = lam * mid
                lo, hi = (mid, hi) if abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1.0 else (lo, mid)
            best = min(best, lo)
        return float(best)

    def discretise(self, h: float) -> tuple[Array, Array, Array]:
        """(Φ, Γ₀, Γ₁) with ξ(t+h) = Φ ξ(t) + Γ₀ ν(t) + Γ₁ ν(t+h), exact for ν linear over the step
        (first-order hold, Van Loan's block exponential). Cached per h."""
        cached = self._discrete.get(h)
        if cached is not None:
            return cached
        n = self.n_states
        m = np.zeros((n + 6, n + 6))
        m[:n, :n] = self.Ar * h
        m[:n, n : n + 3] = self.Br * h
        m[n : n + 3, n + 3 :] = np.eye(3)
        e = scipy.linalg.expm(m)
        phi, g_a, g_b = e[:n, :n], e[:n, n : n + 3], e[:n, n + 3 :]
        out = (np.ascontiguousarray(phi), np.ascontiguousarray(g_a - g_b), np.ascontiguousarray(g_b))
        self._discrete[h] = out
        return out

    def froude_scaled(self, scale: float) -> RadiationStateSpace:
        """The same hull ``scale`` times larger (lengths × λ), by Froude's law: time × √λ, added mass
        × λ³ (× λ per yaw index), damping × λ^2.5 (× λ per yaw index). Exact for the state space: with
        K̃(s) = c_ij K(√λ s), A_r and B_r are divided by √λ and the output/input scaling is congruent, so a
        passive model stays passive."""
        lam = float(scale)
        if not (lam > 0 and math.isfinite(lam)):
            raise ValueError(f"Froude scale must be a positive number, got {scale}")
        p = np.diag(lam**_YAW_LENGTHS)
        root = math.sqrt(lam)
        return RadiationStateSpace(
            Ar=self.Ar / root,
            Br=self.Br @ p / root,
            Cr=lam**2.5 * p @ self.Cr,
            Dr=lam**2.5 * p @ self.Dr @ p,
            A_inf=lam**3 * p @ self.A_inf @ p,
            source=f"{self.source} (Froude-scaled ×{lam:.4g})"
            if self.source
            else f"Froude-scaled ×{lam:.4g}",
        )

    def dof_scaled(self, s: ArrayLike) -> RadiationStateSpace:
        """S K(s) S with S = diag(s) (s > 0, one factor per DOF): element (i, j) of K(jω), A(ω) and A(∞)
        multiplied by sᵢ sⱼ, the time scale kept. A congruence, so K stays symmetric and a passive model
        stays passive (Herm[S K S] = S Herm[K] S ⪰ 0). ``M_RB`` is dropped: the result is no longer the
        model of that hull."""
        f = np.asarray(s, dtype=float).reshape(-1)
        if f.shape != (3,) or not np.all(np.isfinite(f) & (f > 0)):
            raise ValueError(f"DOF scale factors must be three positive numbers, got {s!r}")
        S = np.diag(f)
        return RadiationStateSpace(
            Ar=self.Ar,
            Br=self.Br @ S,
            Cr=S @ self.Cr,
            Dr=S @ self.Dr @ S,
            A_inf=S @ self.A_inf @ S,
            source=f"{self.source} (DOF-scaled ×{', '.join(f'{x:.4g}' for x in f)})",
            hydro_sha256=self.hydro_sha256,
        )


def radiation_state_space(
    elements: dict[tuple[int, int], ElementModel], feedthrough: ArrayLike | None = None, source: str = ""
) -> RadiationStateSpace:
    """The 3×3 block state space assembled from per-element fits (element (i, j) maps ν_j to μ_i; an
    off-diagonal element is realised for (i, j) and (j, i): K is symmetric) with A(∞) from the elements'
    feedthroughs and an optional constant diagonal damping ``feedthrough`` (3,)."""
    d = np.zeros(3) if feedthrough is None else np.asarray(feedthrough, dtype=float).reshape(3)
    Ar, Br, Cr, Dr = _assemble(elements, d)
    A_inf = np.zeros((3, 3))
    for (i, j), m in elements.items():
        A_inf[i, j] = A_inf[j, i] = m.a_inf
    return RadiationStateSpace(Ar, Br, Cr, Dr, A_inf, source)


def model_state_space(model: RadiationModel, source: str = "") -> RadiationStateSpace:
    """The identified model's matrices as a `RadiationStateSpace` (drops the fit report)."""
    return RadiationStateSpace(model.Ar, model.Br, model.Cr, model.Dr, model.A_inf, source)
