"""Wave-frequency (WF) motion and wave-drift forces of the simulated vessel: a wave spectrum through RAOs.

The simulator's first-order wave motion is *not* the observer's 2nd-order wave model run backwards: it is a
sum of random-phase regular waves drawn from a `SeaState` spectrum (`simulator.spectra`), each filtered by the
vessel's motion response amplitude operators (RAOs) from a potential-flow code (Fossen (2021) Handbook
ch. 10.2.1 and 10.2.3, eqs. for wave elevation and motion-RAO superposition)::

    ζ(t, p)  = Σ_k a_k cos(θ_k),          θ_k = ω_k t − k_k (p_N cos χ + p_E sin χ) + ε_k
    x_j(t)   = Σ_k a_k |H_j(ω_k, β)| cos(θ_k + ∠H_j(ω_k, β)) = Re Σ_k a_k H_j(ω_k, β) e^{iθ_k}
    a_k      = √(2 S(ω_k) Δω),       k_k = ω_k² / g   (deep water),      β = χ − ψ

χ is the direction the waves travel towards (NED, clockwise from north), ψ the vessel's heading, p its
(low-frequency) position, ε_k uniform random phases and ω_k a random frequency inside the k-th band of width
Δω (the record does not repeat). j runs over surge, sway (m per m of wave amplitude) and yaw (rad/m) in the
body frame; η_WF = [N, E, ψ]_WF is the body surge/sway motion rotated to NED by ψ plus the yaw.

The mean wave-drift force (body frame, N, N, N·m) is, with drift coefficients C_j(ω, β) per unit amplitude²::

    F_j = Σ_k a_k² C_j(ω_k, β)  ≈ 2 ∫ S(ω) C_j(ω, β) dω

and, optionally, Newman's approximation of the slowly-varying (difference-frequency) part, which keeps only
the diagonal of the quadratic transfer function, written for coefficients of either sign::

    F_j(t) = |Σ_k a_k √C⁺_j(ω_k) e^{iθ_k}|² − |Σ_k a_k √C⁻_j(ω_k) e^{iθ_k}|²,    C± = max(±C, 0)

whose time mean is the mean drift above.

RAO data (`WaveResponse.mss_supply`): the 82.8 m ShipX/VERES supply vessel of the Marine Systems Simulator
(MSS, github.com/cybergalactic/MSS, HYDRO/vessels_shipx/supply/supply.mat, MIT), at zero speed. Conventions
found in the data (see docs/waves.md for the checks):

* β = 0 following sea (waves travel along the bow direction), β = π/2 waves travel towards starboard
  (coming from port), β = π head sea; β = χ − ψ.
* Phase is a lead on the wave elevation at the vessel: x_j = |H| ζa cos(ωt + ε + ∠H) when ζ = ζa cos(ωt + ε)
  (long-wave surge in a following sea lags the crest by 90°, like the water particles: ∠H = −π/2).
* Drift coefficients are forces on the ship in its body axes (x forward, y starboard, N positive bow to
  starboard): a head sea pushes astern (X < 0), waves from port push to starboard (Y > 0). MSS mirrors its
  0…180° table onto 190…350° with the yaw-moment sign unchanged, which is wrong for a port/starboard
  reflection; `mss_supply()` restores N(2π − β) = −N(β).

Vessels without RAOs use the supply vessel's, Froude-scaled to their length (`WaveResponse.froude_scaled`).

Attitude (``WaveResponse.attitude``, `WaveField.attitude`): the heave (m/m, down), roll and pitch (rad/m)
RAOs of the same data, with the same components and phases as surge, sway and yaw. A DP vessel's
controller never sees them, but a GNSS antenna on a mast does: 20 m above the reference point, 2° of roll
moves it 0.7 m sideways (the simulator's sensors use it, `simulator.sensors.antenna_position`).
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from importlib import resources
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import trapezoid

from observers.kinematics import ssa
from simulator import _wave_kernel
from simulator.spectra import SeaState

if TYPE_CHECKING:
    from observers.vessel import VesselModel

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]

G = 9.81
"""Acceleration of gravity (m/s²) used for the deep-water dispersion relation k = ω²/g."""

MSS_SUPPLY_LPP_M = 82.8
"""Length between perpendiculars of the ShipX supply vessel whose RAOs ship with dpgw (main.json: 82.8 m)."""

_DATA_FILE = "supply_hydro.npz"
_MSS_DOF = (0, 1, 5)  # surge, sway, yaw in MSS's 6-DOF order (surge, sway, heave, roll, pitch, yaw)
_ROTATION = np.array([False, False, True])  # which of our three DOFs is a rotation (rad/m)
_MSS_ATTITUDE_DOF = (2, 3, 4)  # heave (z down), roll, pitch in MSS's 6-DOF order
_ATTITUDE_ROTATION = np.array([False, True, True])
_HIGH_TAPER = 0.5  # RAOs taper linearly to 0 between ω_max and (1 + _HIGH_TAPER) ω_max


@dataclass(frozen=True, eq=False)
class WaveResponse:
    """First-order motion RAOs and mean wave-drift coefficients of one vessel, body frame, zero speed.

    ``omega`` (F,) rad/s ascending; ``beta`` (B,) relative wave directions 0, Δβ, …, 2π − Δβ (rad, β = χ − ψ,
    0 following sea, π/2 waves travelling to starboard, π head sea); ``rao`` (F, B, 3) complex RAOs for surge
    (m/m), sway (m/m), yaw (rad/m), phase a lead on the wave elevation at the vessel; ``drift_omega`` (Fd,)
    rad/s; ``drift`` (Fd, B, 3) mean drift force per unit wave amplitude² on surge (N/m²), sway (N/m²),
    yaw (N·m/m²). ``length_m`` is the length the data belong to.

    Interpolation (`rao_at`, `drift_at`) is linear in frequency and in β, wrapping 350° → 360° = 0°. The RAO
    is interpolated as a complex number (real and imaginary parts, as MSS does): no phase unwrapping, and
    where the response changes sign across β (sway near head/following sea, where H ∝ sin β), the
    amplitude correctly passes through zero instead of keeping its magnitude with an undefined phase.

    Outside the frequency table: below ω_min translations hold their first value (long waves: the hull
    follows the water particles, |H| → 1) and rotations go as (ω/ω_min)², like the wave slope k = ω²/g;
    above ω_max RAOs taper linearly to zero at 1.5 ω_max (short waves do not move a ship). Drift
    coefficients go linearly to zero below ω_min (long waves are not reflected) and hold their last value
    above ω_max (the short-wave limit of drift is finite: full reflection).
    """

    name: str
    length_m: float
    omega: Array
    beta: Array
    rao: CArray
    drift_omega: Array
    drift: Array
    source: str = ""
    attitude: CArray | None = None
    """(F, B, 3) complex RAOs of heave (m/m, positive down), roll (rad/m, starboard down) and pitch (rad/m,
    bow up) on the ``omega`` × ``beta`` grid, same phase convention; None: the vessel only moves in the
    horizontal plane (its sensors see no roll or pitch)."""
    _rao_closed: CArray = field(init=False, repr=False)
    _attitude_closed: CArray | None = field(init=False, repr=False)
    _drift_closed: Array = field(init=False, repr=False)

    def __post_init__(self) -> None:
        omega = _ascending(self.omega, "omega")
        drift_omega = _ascending(self.drift_omega, "drift_omega")
        beta = np.array(self.beta, dtype=float)
        nb = beta.size
        if beta.ndim != 1 or nb < 2 or not np.allclose(beta, np.arange(nb) * (2.0 * math.pi / nb), atol=1e-9):
            raise ValueError("beta must be equally spaced 0, Δβ, …, 2π − Δβ (rad)")
        rao = np.array(self.rao, dtype=np.complex128)
        drift = np.array(self.drift, dtype=float)
        if rao.shape != (omega.size, nb, 3):
            raise ValueError(f"rao must have shape (len(omega), len(beta), 3), got {rao.shape}")
        if drift.shape != (drift_omega.size, nb, 3):
            raise ValueError(f"drift must have shape (len(drift_omega), len(beta), 3), got {drift.shape}")
        if not (np.all(np.isfinite(rao)) and np.all(np.isfinite(drift))):
            raise ValueError("rao and drift must be finite")
        if not (math.isfinite(self.length_m) and self.length_m > 0):
            raise ValueError(f"length_m must be a positive finite number, got {self.length_m!r}")
        attitude = None if self.attitude is None else np.array(self.attitude, dtype=np.complex128)
        if attitude is not None and (attitude.shape != rao.shape or not np.all(np.isfinite(attitude))):
            raise ValueError(f"attitude must be finite with the shape of rao {rao.shape}")
        # Close the direction tables at 2π so that interpolation wraps 350° → 360° = 0°.
        rao_closed = np.concatenate([rao, rao[:, :1]], axis=1)
        att_closed = None if attitude is None else np.concatenate([attitude, attitude[:, :1]], axis=1)
        drift_closed = np.concatenate([drift, drift[:, :1]], axis=1)
        for name, value in (
            ("omega", omega),
            ("drift_omega", drift_omega),
            ("beta", beta),
            ("rao", rao),
            ("drift", drift),
            ("_rao_closed", rao_closed),
            ("_drift_closed", drift_closed),
            ("attitude", attitude),
            ("_attitude_closed", att_closed),
        ):
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    # -- construction ---------------------------------------------------------------------------------------

    @classmethod
    def mss_supply(cls) -> WaveResponse:
        """RAOs and drift coefficients of the 82.8 m MSS/ShipX supply vessel (package data, MIT)."""
        return _load_mss_supply()

    @classmethod
    def froude_scaled(cls, length_m: float) -> WaveResponse:
        """The supply vessel's data Froude-scaled to a vessel of length ``length_m`` (λ = L / 82.8)."""
        if not (math.isfinite(length_m) and length_m > 0):
            raise ValueError(f"length_m must be a positive finite number, got {length_m!r}")
        return cls.mss_supply().scaled(length_m / MSS_SUPPLY_LPP_M)

    @classmethod
    def for_vessel(cls, vessel: VesselModel) -> WaveResponse:
        """`mss_supply()` for the vessel named ``mss_supply``, else `froude_scaled` to ``vessel.length_m``."""
        if vessel.name == "mss_supply":
            return cls.mss_supply()
        return cls.froude_scaled(vessel.length_m)

    def scaled(self, lam: float) -> WaveResponse:
        """Froude scaling by the length ratio λ = L_new / L (geometric similarity, same water density).

        ``ω' = ω / √λ``; translation RAOs (m/m) unchanged; rotation RAOs (rad/m) × 1/λ; drift force per
        amplitude² (N/m²) × λ (force ∝ λ³, ζa² ∝ λ²); drift moment per amplitude² (N·m/m²) × λ².
        """
        if not (math.isfinite(lam) and lam > 0):
            raise ValueError(f"scale ratio must be a positive finite number, got {lam!r}")
        root = math.sqrt(lam)
        rao_gain = np.array([1.0, 1.0, 1.0 / lam])
        drift_gain = np.array([lam, lam, lam**2])
        length = self.length_m * lam
        return WaveResponse(
            name=f"{self.name} Froude-scaled to L = {length:g} m",
            length_m=length,
            omega=self.omega / root,
            beta=self.beta,
            rao=self.rao * rao_gain,
            drift_omega=self.drift_omega / root,
            drift=self.drift * drift_gain,
            source=f"{self.source}; Froude-scaled by λ = {lam:g}",
            attitude=None if self.attitude is None else self.attitude * np.array([1.0, 1.0 / lam, 1.0 / lam]),
        )

    # -- evaluation -----------------------------------------------------------------------------------------

    def rao_at(self, omega: ArrayLike, beta: ArrayLike) -> CArray:
        """Complex RAOs [surge m/m, sway m/m, yaw rad/m] at wave frequency ω and relative direction β.

        ``omega`` and ``beta`` broadcast against each other; the result has their shape + (3,).
        """
        return self._rao_table_at(self._rao_closed, _ROTATION, omega, beta)

    def attitude_at(self, omega: ArrayLike, beta: ArrayLike) -> CArray:
        """Complex RAOs [heave m/m (down), roll rad/m, pitch rad/m] at ω and β (zeros without ``attitude``);
        the same interpolation and extrapolation as `rao_at`."""
        if self._attitude_closed is None:
            shape = np.broadcast_shapes(np.shape(omega), np.shape(beta))
            return np.zeros((*shape, 3), dtype=np.complex128)
        return self._rao_table_at(self._attitude_closed, _ATTITUDE_ROTATION, omega, beta)

    def _rao_table_at(
        self, table: CArray, rotation: NDArray[np.bool_], omega: ArrayLike, beta: ArrayLike
    ) -> CArray:
        w, b = np.broadcast_arrays(np.asarray(omega, dtype=float), np.asarray(beta, dtype=float))
        H = _bilinear(table, self.omega, w, b)
        w1 = w[..., None]
        w_min, w_max = self.omega[0], self.omega[-1]
        low = np.where(rotation, (np.clip(w1, 0.0, w_min) / w_min) ** 2, 1.0)
        high = np.clip(1.0 - (w1 - w_max) / (_HIGH_TAPER * w_max), 0.0, 1.0)
        return np.asarray(H * low * high, dtype=np.complex128)

    def drift_at(self, omega: ArrayLike, beta: ArrayLike) -> Array:
        """Mean drift coefficients [X N/m², Y N/m², N N·m/m²] at ω and β (force = coefficient · ζa²)."""
        w, b = np.broadcast_arrays(np.asarray(omega, dtype=float), np.asarray(beta, dtype=float))
        C = _bilinear(self._drift_closed, self.drift_omega, w, b)
        low = np.clip(w / self.drift_omega[0], 0.0, 1.0)[..., None]
        return np.asarray(C.real * low, dtype=float)

    def response_spectrum(self, omega: ArrayLike, sea_state: SeaState, heading: float = 0.0) -> Array:
        """Body-frame response spectra |H_j(ω, β)|² S(ω) (m²·s/rad, m²·s/rad, rad²·s/rad), shape ω + (3,).

        β = wave direction − heading. Its integral over ω is the variance of the WF surge, sway and yaw.
        """
        w = np.asarray(omega, dtype=float)
        beta = ssa(sea_state.direction_rad - heading)
        H = self.rao_at(w, beta)
        return np.asarray(np.abs(H) ** 2 * sea_state.spectrum(w)[..., None], dtype=float)

    def mean_drift_force(self, sea_state: SeaState, heading: float = 0.0) -> Array:
        """Expected mean drift [X, Y, N] (N, N, N·m) in a sea state: 2 ∫ S(ω) C(ω, β) dω (trapezoidal)."""
        wp = sea_state.peak_frequency
        w = np.linspace(0.05 * wp, 12.0 * wp, 8001)
        beta = ssa(sea_state.direction_rad - heading)
        integrand = 2.0 * sea_state.spectrum(w)[:, None] * self.drift_at(w, beta)
        return np.asarray(trapezoid(integrand, w, axis=0), dtype=float)


def _ascending(value: ArrayLike, name: str) -> Array:
    a = np.array(value, dtype=float)
    if a.ndim != 1 or a.size < 2 or not np.all(np.diff(a) > 0) or a[0] <= 0:
        raise ValueError(f"{name} must be a 1-D ascending array of positive frequencies (rad/s)")
    return a


def _beta_index(beta: Array, n_beta: int) -> tuple[NDArray[np.intp], Array]:
    """Cell index j ∈ [0, B−1] and fraction f ∈ [0, 1) of β in an equally spaced table over [0, 2π]."""
    x = np.mod(beta, 2.0 * math.pi) * (n_beta / (2.0 * math.pi))
    j = np.minimum(np.floor(x).astype(np.intp), n_beta - 1)
    return j, x - j


def _bilinear(table: NDArray[Any], grid: Array, w: Array, beta: Array) -> NDArray[Any]:
    """Linear interpolation of a direction-closed table (F, B+1, D) in ω (clamped) and β (periodic)."""
    i = np.clip(np.searchsorted(grid, w, side="right") - 1, 0, grid.size - 2)
    fw = np.clip((w - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)[..., None]
    j, fb = _beta_index(beta, table.shape[1] - 1)
    fb = fb[..., None]
    at_i = (1.0 - fb) * table[i, j] + fb * table[i, j + 1]
    at_i1 = (1.0 - fb) * table[i + 1, j] + fb * table[i + 1, j + 1]
    return np.asarray((1.0 - fw) * at_i + fw * at_i1)


@lru_cache(maxsize=1)
def _load_mss_supply() -> WaveResponse:
    raw = (resources.files("simulator") / "data" / _DATA_FILE).read_bytes()
    with np.load(io.BytesIO(raw)) as d:
        dof = list(_MSS_DOF)
        # MSS arrays are (DOF, freq, heading); ours are (freq, heading, DOF).
        rao = np.moveaxis(d["motion_rao_amp"][dof] * np.exp(1j * d["motion_rao_phase"][dof]), 0, -1)
        att = list(_MSS_ATTITUDE_DOF)
        attitude = np.moveaxis(d["motion_rao_amp"][att] * np.exp(1j * d["motion_rao_phase"][att]), 0, -1)
        # MSS's drift table holds surge, sway, yaw in its first three DOF slots (read_veres_WD.m).
        drift = np.moveaxis(np.array(d["drift_amp"][:3], dtype=float), 0, -1)
        omega, drift_omega, beta = d["motion_rao_w"], d["drift_w"], d["headings"]
    # Restore port/starboard antisymmetry of the yaw drift moment on the mirrored half (β ∈ (π, 2π)):
    # MSS copies N(β) to 2π − β with an unchanged sign; a reflection y → −y reverses it.
    nb = beta.size
    for jj in range(1, nb // 2):
        drift[:, nb - jj, 2] = -drift[:, jj, 2]
    return WaveResponse(
        name="mss_supply",
        length_m=MSS_SUPPLY_LPP_M,
        omega=omega,
        beta=beta,
        rao=rao,
        drift_omega=drift_omega,
        drift=drift,
        source="MSS HYDRO/vessels_shipx/supply/supply.mat (ShipX/VERES, zero speed), MIT, T. I. Fossen",
        attitude=attitude,
    )


# ------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class WaveComponents:
    """The regular-wave components of one sea state: ω_k (rad/s), a_k (m), ε_k (rad), k_k (rad/m).

    ``rao`` (K, B+1, 3) complex holds a_k H(ω_k, β_j) on the direction-closed β grid; ``drift_pos`` and
    ``drift_neg`` (K, B+1, 3) hold a_k √C±(ω_k, β_j) for Newman's approximation; ``drift_mean`` (B+1, 3)
    holds Σ_k a_k² C(ω_k, β_j). Interpolating these linearly in β equals interpolating the RAO.
    """

    sea_state: SeaState
    omega: Array
    amplitude: Array
    phase: Array
    wavenumber: Array
    rao: CArray
    drift_pos: Array
    drift_neg: Array
    drift_mean: Array
    attitude: CArray | None = None
    """(K, B+1, 3) a_k × [heave, roll, pitch] RAOs on the closed β grid; None without attitude RAOs."""

    @cached_property
    def motion_table(self) -> CArray:
        """[rao | attitude] (K, B+1, 6), or ``rao`` alone without attitude RAOs: what the WF motion
        interpolates, joined once per sea state (~0.5 MB; it was copied at every 2 s block)."""
        return self.rao if self.attitude is None else np.concatenate([self.rao, self.attitude], axis=2)

    @cached_property
    def motion_table_parts(self) -> tuple[Array, Array]:
        """`motion_table`'s real and imaginary parts, contiguous: what the compiled synthesis reads."""
        table = self.motion_table
        return np.ascontiguousarray(table.real), np.ascontiguousarray(table.imag)


class WaveField:
    """A (possibly changing) irregular long-crested sea and the WF motion and drift it gives one vessel.

    ``schedule``: a `SeaState`, or a list of ``(t_start_s, SeaState)`` with strictly increasing start
    times at least ``fade_s`` apart. The first sea state also holds before its start time. At each change
    the old and the new field (independent random phases) are cross-faded over ``fade_s`` seconds with
    power-complementary weights cos(πs/2), sin(πs/2), s = (t − t_start)/fade_s: the variance moves
    monotonically from the old sea's to the new one's, and nothing jumps. (A linear cross-fade of the
    amplitudes of two independent fields would dip the variance by half at mid-fade.)

    ``response``: the vessel's `WaveResponse`. ``seed``: each sea state's components come from
    ``numpy.random.default_rng`` on a child of ``SeedSequence(seed)``: the same seed gives the same sea, and
    adding a later sea state does not change the earlier ones.

    ``n_components`` regular waves per sea state over the frequency range where S(ω) ≥ ``spectrum_cutoff``
    × max S (about 0.60 … 4.0 ωp for JONSWAP γ = 3.3, 0.58 … 5.1 ωp for PM), in equal bands Δω, each at a
    uniformly random frequency within its band, with a_k = √(2 S(ω_k) Δω) and random phase ε_k.
    (Torsetnes et al. (2004) Sec. V use 20 components. With equal bands a sum of K waves nearly repeats
    after 2π/Δω: about 70 s for 20 components of their Hs 6 m sea (Tp ≈ 11.5 s), shorter than the
    windows the wave-frequency estimators read; 150 stretch that to about 500 s, and the jitter within
    each band removes the exact repeat.)

    ``motion_gain`` multiplies η_WF = [N, E, ψ] per DOF (after rotation to NED); see `gain_for_limits`.
    Evaluations are vectorised over time and done in chunks of ``chunk_size`` samples to bound memory.
    """

    def __init__(
        self,
        schedule: SeaState | Sequence[tuple[float, SeaState]],
        response: WaveResponse,
        seed: int,
        n_components: int = 150,
        *,
        fade_s: float = 60.0,
        spectrum_cutoff: float = 1e-3,
        motion_gain: Sequence[float] = (1.0, 1.0, 1.0),
        chunk_size: int = 2048,
    ) -> None:
        if isinstance(schedule, SeaState):
            schedule = [(0.0, schedule)]
        entries = [(float(t0), ss) for t0, ss in schedule]
        if not entries:
            raise ValueError("wave schedule is empty: give at least one (t_start_s, SeaState)")
        if not (math.isfinite(fade_s) and fade_s >= 0):
            raise ValueError(f"fade_s must be a finite number ≥ 0 s, got {fade_s!r}")
        for k, (t0, ss) in enumerate(entries):
            if not isinstance(ss, SeaState):
                raise ValueError(f"wave schedule entry {k}: expected a SeaState, got {type(ss).__name__}")
            if not math.isfinite(t0):
                raise ValueError(f"wave schedule entry {k}: start time must be finite, got {t0!r}")
            if k and t0 - entries[k - 1][0] < max(fade_s, 1e-9):
                raise ValueError(
                    f"wave schedule entry {k}: start times must increase by at least fade_s = {fade_s} s "
                    f"(got {entries[k - 1][0]} s then {t0} s)"
                )
        if int(n_components) != n_components or n_components < 1:
            raise ValueError(f"n_components must be a positive integer, got {n_components!r}")
        if not (0.0 < spectrum_cutoff < 1.0):
            raise ValueError(f"spectrum_cutoff must be within (0, 1), got {spectrum_cutoff!r}")
        if int(chunk_size) != chunk_size or chunk_size < 1:
            raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
        self.response = response
        self.seed = seed
        self.n_components = int(n_components)
        self.fade_s = float(fade_s)
        self.spectrum_cutoff = float(spectrum_cutoff)
        self.chunk_size = int(chunk_size)
        self.motion_gain = _gain(motion_gain)
        self.schedule: tuple[tuple[float, SeaState], ...] = tuple(entries)
        self._starts = np.array([t0 for t0, _ in entries])
        children = np.random.SeedSequence(seed).spawn(len(entries))
        self.components: tuple[WaveComponents, ...] = tuple(
            self._make_components(ss, np.random.default_rng(child))
            for (_, ss), child in zip(entries, children, strict=True)
        )

    def _make_components(self, sea: SeaState, rng: np.random.Generator) -> WaveComponents:
        lo, hi = frequency_range(sea, self.spectrum_cutoff)
        K = self.n_components
        dw = (hi - lo) / K
        omega = lo + dw * (np.arange(K) + rng.uniform(0.0, 1.0, K))  # one random frequency per band
        phase = rng.uniform(0.0, 2.0 * math.pi, K)
        amplitude = np.sqrt(2.0 * sea.spectrum(omega) * dw)
        resp = self.response
        nb = resp.beta.size
        beta = np.arange(nb + 1) * (2.0 * math.pi / nb)  # closed grid, 0 … 2π
        H = resp.rao_at(omega[:, None], beta[None, :])  # (K, B+1, 3)
        C = resp.drift_at(omega[:, None], beta[None, :])
        a = amplitude[:, None, None]
        return WaveComponents(
            sea_state=sea,
            omega=omega,
            amplitude=amplitude,
            phase=phase,
            wavenumber=omega**2 / G,
            rao=np.asarray(a * H, dtype=np.complex128),
            drift_pos=a * np.sqrt(np.maximum(C, 0.0)),
            drift_neg=a * np.sqrt(np.maximum(-C, 0.0)),
            drift_mean=np.sum(a**2 * C, axis=0),
            attitude=None
            if resp.attitude is None
            else np.asarray(a * resp.attitude_at(omega[:, None], beta[None, :]), dtype=np.complex128),
        )

    def with_motion_gain(self, motion_gain: Sequence[float]) -> WaveField:
        """The same sea (same components) with another per-DOF NED motion gain."""
        other = object.__new__(WaveField)
        other.__dict__.update(self.__dict__)
        other.motion_gain = _gain(motion_gain)
        return other

    # -- schedule -------------------------------------------------------------------------------------------

    def _weights(self, t: Array) -> Array:
        """Amplitude weights (n_sea_states, n): cos/sin power-complementary cross-fades at each change."""
        if self.fade_s > 0:
            s = np.clip((t[None, :] - self._starts[1:, None]) / self.fade_s, 0.0, 1.0)
        else:
            s = (t[None, :] >= self._starts[1:, None]).astype(float)
        up = np.vstack([np.ones((1, t.size)), np.sin(0.5 * math.pi * s)])
        down = np.vstack([np.cos(0.5 * math.pi * s), np.ones((1, t.size))])
        w = up * down
        # Exact zeros outside each sea state's window, so whole chunks can be skipped.
        w[np.abs(w) < 1e-15] = 0.0
        return w

    def sea_state_at(self, t: float) -> SeaState:
        """The dominant sea state at time t (during a cross-fade, the new one after mid-fade)."""
        i = int(np.argmax(self._weights(np.array([float(t)]))[:, 0]))
        return self.components[i].sea_state

    def peak_frequency(self, t: ArrayLike) -> Array:
        """ωp = 2π/Tp (rad/s) of the dominant sea state at each t (switches at mid-fade), shape of t."""
        ta = np.asarray(t, dtype=float)
        wp = np.array([c.sea_state.peak_frequency for c in self.components])
        i = np.argmax(self._weights(ta.ravel()), axis=0)
        return np.asarray(wp[i].reshape(ta.shape), dtype=float)

    # -- evaluation -----------------------------------------------------------------------------------------

    def _prepare(self, t: ArrayLike, *others: ArrayLike) -> tuple[tuple[int, ...], Array, list[Array]]:
        ta = np.asarray(t, dtype=float)
        flat = [np.broadcast_to(np.asarray(x, dtype=float), ta.shape).ravel() for x in others]
        return ta.shape, ta.ravel(), flat

    def _chunks(self, n: int) -> list[slice]:
        return [slice(i, min(i + self.chunk_size, n)) for i in range(0, n, self.chunk_size)]

    def _active(self, ts: Array) -> Iterator[tuple[slice, WaveComponents, Array]]:
        """(chunk of the samples, sea-state components, their amplitude weights there) for every sea state
        with some weight in the chunk: the loop every field quantity sums over."""
        for sl in self._chunks(ts.size):
            weights = self._weights(ts[sl])
            for c, w in zip(self.components, weights, strict=True):
                if np.any(w):
                    yield sl, c, w

    @staticmethod
    def _theta(c: WaveComponents, t: Array, north: Array, east: Array) -> Array:
        """θ_k = ω_k t − k_k (N cos χ + E sin χ) + ε_k, shape (n, K)."""
        theta = np.multiply.outer(t, c.omega)
        theta += c.phase
        chi = c.sea_state.direction_rad
        along = north * math.cos(chi) + east * math.sin(chi)  # position along the travel direction
        if np.any(along):
            theta -= np.multiply.outer(along, c.wavenumber)
        return theta

    @classmethod
    def _carrier(cls, c: WaveComponents, t: Array, north: Array, east: Array) -> CArray:
        """e^{iθ_k}, shape (n, K); cos and sin written in place (cheaper than a complex exp)."""
        theta = cls._theta(c, t, north, east)
        carrier = np.empty(theta.shape, dtype=np.complex128)
        np.cos(theta, out=carrier.real)
        np.sin(theta, out=carrier.imag)
        return carrier

    @staticmethod
    def _at_beta(carrier: CArray, table: NDArray[Any], beta: Array) -> CArray:
        """Σ_k carrier_k · table_k(β) with table linear in β: (n, 3) complex.

        Only the β cells the samples touch are multiplied (the heading changes slowly, so usually one or
        two), then each sample blends its two neighbouring cells.
        """
        j, f = _beta_index(beta, table.shape[1] - 1)
        cells, inverse = np.unique(np.concatenate([j, j + 1]), return_inverse=True)
        K = table.shape[0]
        D = table.shape[2]
        P = (carrier @ table[:, cells, :].reshape(K, -1)).reshape(beta.size, cells.size, D)
        rows = np.arange(beta.size)
        lo = P[rows, inverse[: beta.size]]
        hi = P[rows, inverse[beta.size :]]
        return np.asarray((1.0 - f)[:, None] * lo + f[:, None] * hi, dtype=np.complex128)

    def elevation(self, t: ArrayLike, north: ArrayLike = 0.0, east: ArrayLike = 0.0) -> Array:
        """Wave elevation ζ(t) (m, positive up) at NED position (north, east) (default the origin)."""
        shape, ts, (north_f, east_f) = self._prepare(t, north, east)
        out = np.zeros(ts.size)
        for sl, c, w in self._active(ts):
            out[sl] += w * (np.cos(self._theta(c, ts[sl], north_f[sl], east_f[sl])) @ c.amplitude)
        return out.reshape(shape)

    def body_motion(
        self, t: ArrayLike, heading: ArrayLike, north: ArrayLike = 0.0, east: ArrayLike = 0.0
    ) -> Array:
        """WF motion in the body frame [surge m, sway m, yaw rad], shape t + (3,) (no motion gain)."""
        shape, ts, (psi, north_f, east_f) = self._prepare(t, heading, north, east)
        out = np.zeros((ts.size, 3))
        for sl, c, w in self._active(ts):
            carrier = self._carrier(c, ts[sl], north_f[sl], east_f[sl])
            beta = ssa(c.sea_state.direction_rad - psi[sl])
            out[sl] += w[:, None] * self._at_beta(carrier, c.rao, beta).real
        return out.reshape((*shape, 3))

    def attitude(
        self, t: ArrayLike, heading: ArrayLike, north: ArrayLike = 0.0, east: ArrayLike = 0.0
    ) -> Array:
        """WF heave, roll and pitch [z m (down), φ rad, θ rad] of the reference point, shape t + (3,).

        The same components and phases as `motion` (one sea, six degrees of freedom); zeros when the
        response has no attitude RAOs. ``motion_gain`` does not apply (it scales the horizontal motion to
        a paper's limits, not the sea).
        """
        return self.motion_with_attitude(t, heading, north, east)[1]

    def motion_with_attitude(
        self, t: ArrayLike, heading: ArrayLike, north: ArrayLike = 0.0, east: ArrayLike = 0.0
    ) -> tuple[Array, Array]:
        """(`motion`, `attitude`) from one evaluation of the wave carriers (what the simulator's sensors
        need at every sample: the cos/sin of the components are most of the cost)."""
        shape, ts, (psi, north_f, east_f) = self._prepare(t, heading, north, east)
        body = np.zeros((ts.size, 3))
        att = np.zeros((ts.size, 3))
        for sl, c, w in self._active(ts):
            carrier = self._carrier(c, ts[sl], north_f[sl], east_f[sl])
            beta = ssa(c.sea_state.direction_rad - psi[sl])
            table = c.motion_table
            both = self._at_beta(carrier, table, beta).real
            body[sl] += w[:, None] * both[:, :3]
            if c.attitude is not None:
                att[sl] += w[:, None] * both[:, 3:]
        return self._to_ned(body, psi).reshape((*shape, 3)), att.reshape((*shape, 3))

    def motion_block(
        self, t0: float, dt: float, n: int, heading: float, north: float = 0.0, east: float = 0.0
    ) -> Array:
        """[N, E, ψ, z, φ, θ] at t₀ + s·dt, s = 0 … n−1, for a held heading and position, shape (n, 6):
        `motion_with_attitude` on that grid, joined, computed by the compiled carrier recurrence of
        `simulator._wave_kernel` (the simulator's 2 s blocks; equal to the numpy path to round-off)."""
        out = np.zeros((n, 6))
        single = len(self.components) == 1  # (one sea state: no fade to weigh)
        weights = np.ones((1, n)) if single else self._weights(t0 + dt * np.arange(n, dtype=np.float64))
        for c, w in zip(self.components, weights, strict=True):
            if not np.any(w):
                continue
            chi = c.sea_state.direction_rad
            along = north * math.cos(chi) + east * math.sin(chi)
            tab_re, tab_im = c.motion_table_parts
            j, f = _beta_index(np.array([chi - heading]), tab_re.shape[1] - 1)
            # 6 columns with attitude RAOs, 3 without (the attitude then stays zero)
            _wave_kernel.synthesize(
                c.omega, c.phase, c.wavenumber, float(along), float(t0), float(dt), tab_re, tab_im,
                int(j[0]), float(f[0]), w, out[:, : tab_re.shape[2]],
            )  # fmt: skip
        out[:, :3] = self._to_ned(out[:, :3], np.full(n, float(heading)))
        return out

    def _to_ned(self, body: Array, psi: Array) -> Array:
        """Body surge/sway rotated to NED by ψ, yaw as is, times ``motion_gain``."""
        c, s = np.cos(psi), np.sin(psi)
        eta = np.stack(
            [c * body[:, 0] - s * body[:, 1], s * body[:, 0] + c * body[:, 1], body[:, 2]], axis=-1
        )
        return np.asarray(eta * self.motion_gain, dtype=float)

    def motion(
        self, t: ArrayLike, heading: ArrayLike, north: ArrayLike = 0.0, east: ArrayLike = 0.0
    ) -> Array:
        """WF motion η_WF = [N m, E m, ψ rad] earth-fixed, shape t + (3,).

        ``heading`` ψ (rad) and the vessel position (``north``, ``east``, m) are scalars or arrays shaped
        like ``t``; the RAO is taken at β = χ − ψ of each sample, the phase includes −k·(position along χ).
        Body surge/sway are rotated to NED by ψ, yaw is added as is; then ``motion_gain`` applies.
        """
        body = self.body_motion(t, heading, north, east)
        psi = np.broadcast_to(np.asarray(heading, dtype=float), body.shape[:-1])
        c, s = np.cos(psi), np.sin(psi)
        eta = np.stack(
            [c * body[..., 0] - s * body[..., 1], s * body[..., 0] + c * body[..., 1], body[..., 2]], axis=-1
        )
        return np.asarray(eta * self.motion_gain, dtype=float)

    def drift_force(
        self,
        t: ArrayLike,
        heading: ArrayLike,
        north: ArrayLike = 0.0,
        east: ArrayLike = 0.0,
        *,
        slowly_varying: bool = False,
    ) -> Array:
        """Wave-drift force [X N, Y N, N N·m] in the body frame, shape t + (3,).

        Default: the mean drift Σ_k a_k² C(ω_k, β) (changes only with β and the sea state). With
        ``slowly_varying=True``: Newman's approximation of the difference-frequency force, whose time mean
        is (to the β interpolation of √C) the same; it needs the vessel position for the wave phases.
        During a cross-fade the sea states' forces are weighted by their power weights.
        """
        shape, ts, (psi, north_f, east_f) = self._prepare(t, heading, north, east)
        out = np.zeros((ts.size, 3))
        for sl, c, w in self._active(ts):
            beta = ssa(c.sea_state.direction_rad - psi[sl])
            if slowly_varying:
                carrier = self._carrier(c, ts[sl], north_f[sl], east_f[sl])
                pos = np.abs(self._at_beta(carrier, c.drift_pos, beta)) ** 2
                neg = np.abs(self._at_beta(carrier, c.drift_neg, beta)) ** 2
                force = pos - neg
            else:
                j, f = _beta_index(beta, c.drift_mean.shape[0] - 1)
                force = (1.0 - f)[:, None] * c.drift_mean[j] + f[:, None] * c.drift_mean[j + 1]
            out[sl] += (w**2)[:, None] * force
        return out.reshape((*shape, 3))

    def gain_for_limits(
        self,
        limits: Sequence[float],
        t: ArrayLike,
        heading: ArrayLike,
        north: ArrayLike = 0.0,
        east: ArrayLike = 0.0,
    ) -> tuple[float, float, float]:
        """Per-DOF gains that make max |η_WF| over the record t equal ``limits`` = (N m, E m, ψ rad).

        E.g. Fossen & Strand (1999)'s WF motion of at most 10 m, 10 m, 1°::

            gain = field.gain_for_limits((10.0, 10.0, math.radians(1.0)), t, heading)
            field = field.with_motion_gain(gain)

        A DOF with no motion in the record keeps gain 1.
        """
        lim = np.asarray(limits, dtype=float)
        if lim.shape != (3,) or not np.all(np.isfinite(lim)) or np.any(lim < 0):
            raise ValueError(f"limits must be three finite numbers ≥ 0 (N m, E m, ψ rad), got {limits!r}")
        raw = self.with_motion_gain((1.0, 1.0, 1.0)).motion(t, heading, north, east).reshape(-1, 3)
        peak = np.max(np.abs(raw), axis=0)
        gain = np.where(peak > 0, lim / np.where(peak > 0, peak, 1.0), 1.0)
        return (float(gain[0]), float(gain[1]), float(gain[2]))


def frequency_range(sea: SeaState, cutoff: float = 1e-3) -> tuple[float, float]:
    """[ω_lo, ω_hi] (rad/s) where S(ω) ≥ cutoff · max S; 0.5 … 3 ωp for a calm sea (Hs = 0)."""
    wp = sea.peak_frequency
    w = np.linspace(0.2 * wp, 8.0 * wp, 4001)
    S = sea.spectrum(w)
    if not np.any(S > 0):
        return 0.5 * wp, 3.0 * wp
    above = np.flatnonzero(cutoff * S.max() <= S)
    return float(w[above[0]]), float(w[above[-1]])


def _gain(value: Sequence[float]) -> Array:
    g = np.array(value, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ValueError(f"motion_gain must be three finite numbers (N, E, ψ), got {value!r}")
    g.setflags(write=False)
    return g
