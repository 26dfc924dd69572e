"""DP controller: the nonlinear PID of Torsetnes, Jouffroy & Fossen (2004), eqs (57)–(59), (67)–(70).

Pure numerics (DESIGN.md rule 2): arrays in, arrays out; time only through the ``t`` passed to `update`.

Plant (Torsetnes (8)–(10), Fossen & Strand (1999) (1), (3))::

    η' = J(ψ) ν,      M ν' + D ν = τ + Jᵀ(ψ) b                                         (8), (10)

Control law implemented, fed by the observer's low-frequency estimates η̂, ν̂, b̂ only (never the raw
measurement: that is the point of wave filtering; eqs (67)–(70) are (57)–(59) with hats)::

    ξ̂ − ξ_d = z,   z' = η̃ = η̂ − η_d  (ψ component ssa(ψ̂ − ψ_d))                   (57), (58), (67), (68)
    τ = − Kp Jᵀ(ψ̂) η̃ − Kd ν̃ − Ki Jᵀ(ψ̂) z                                           (59), (69)–(70)
        + M ν̇_d + D ν_d                       (reference feed-forward, ``feedforward``)
        − Jᵀ(ψ̂) b̂                             (bias feed-forward, ``bias_feedforward``)
        − k_w τ̂_w(ū_rw, v̄_rw)                  (wind feed-forward, `gateway.control.wind_feedforward`)
    ν̃ = ν̂ − Jᵀ(ψ̂) η_d'

Notes on the paper (its ξ in (57)–(70) is the integral of η, not the wave state, whatever the print suggests):

* (69)–(70) is one equation broken over two lines by the OCR; Theorem 4 cites it as "(70)".
* (57)/(58) integrate η and η_d separately; only the difference z = ξ − ξ_d enters (59), so dpgw
  integrates the error, with the heading difference through `ssa` (the paper's ψ − ψ_d is not wrapped;
  integrating raw headings would wind up 2π on every crossing of ±180°). z is earth-fixed, as in the
  paper, and rotated into the body frame by Jᵀ(ψ̂): the integrator holds an earth-fixed force, the shape of
  the bias b it has to cancel.
* (59) damps ν, not ν − ν_d: it is written for regulation (η_d constant). For tracking the reference
  dpgw uses ν̃ = ν̂ − Jᵀ(ψ̂) η_d', the body-frame form of d/dt(η̃) (since η̃' = J(ψ)(ν − Jᵀ(ψ)η_d')), so P and D
  act on one signal. The paper is silent on feed-forward and on the bias estimate; both are dpgw's
  additions, each switchable. With both, the linearised error dynamics (ψ̂ ≈ ψ_d, observer exact) are
  M ë + (D + Kd) ė + Kp e + Ki ∫e = 0, e = Jᵀη̃: the matrix A_τ of (66).
* (62) has lost a factor: its last term is M⁻¹ Jᵀ(Ki ξ_d + Kp η_d), consistent with (59) and (65)–(66).
* The paper gives no gain formulas, only "critically damped, ωn = 0.8 rad/s" (Sec. V). That ωn lies in
  the wave band (0.3–1.3 rad/s for a full-scale ship): a loop that fast would try to cancel the
  first-order wave motion that the observer filters out, and would not be realisable with real thrusters.
  dpgw's default is 0.07 rad/s (closed-loop period 90 s) for a 76.2 m supply vessel, Froude-scaled with
  the vessel's length (below), four times below the lowest wave frequency and no faster than the
  observer's velocity-error decay (Dᵢᵢ/Mᵢᵢ + a: 1.1-1.5 ωn in torsetnes_2004's sea; the gateway's config
  holds the observer's a at ≥ ωn − Dᵢᵢ/Mᵢᵢ where the sea would not, docs/passive-observer.md).

Gains (`controller_gains`), per DOF i with closed-loop natural frequency ωᵢ, damping ζᵢ and integral
pole aᵢ = ρᵢ ωᵢ (ρ = ``integral_ratio``)::

    Kp = M diag(ωᵢ² + 2ζᵢωᵢaᵢ),   Kd = M diag(2ζᵢωᵢ + aᵢ) − D,   Ki = M diag(ωᵢ² aᵢ)

so that M⁻¹Kp, M⁻¹(D + Kd), M⁻¹Ki are diagonal and each DOF's characteristic polynomial is exactly
s³ + (2ζω + a)s² + (ω² + 2ζωa)s + ω²a = (s² + 2ζωs + ω²)(s + a): a pair at ωn, ζ and a real integral
pole at −a. The full M (not its diagonal) is used so that the sway–yaw coupling M₂₃ does not move the
poles; with one ω and ζ for all DOFs (the default) Kp and Ki are positive multiples of M, hence symmetric
positive definite. A slow integral pole (ρ = 0.1) removes steady-state error without changing the PD
response; it is what "Ki = Kp ωn/10" aims at, placed exactly. If the vessel's own damping exceeds the
desired one (Dᵢᵢ > Mᵢᵢ(2ζᵢωᵢ + aᵢ)), Kd would have to be negative, i.e. feed energy in: the damping
coefficient is raised to Dᵢᵢ/Mᵢᵢ (Kdᵢᵢ = 0) and `ControllerGains.clipped` says so.

Integral anti-windup (`update(..., saturated, tau_allocated)`; ``saturated`` and ``tau_allocated``
describe what allocation made of the previous demand):

* ``saturated`` with ``tau_allocated``: back-calculation (Åström & Hägglund). Besides η̃, the integrator
  moves the integral term towards the achievable force: per DOF the fraction min(dt/Tₜ, 1) of the excess
  τ_demand − τ_allocated is taken off the integral term each step, Tₜ = 1/ωᵢ (``tracking_time_s``).
* ``saturated`` without ``tau_allocated``: conditional integration — the integrator is frozen.
* not saturated: plain integration.

Wind feed-forward (`update(..., relative_wind=(u_rw, v_rw))`, the anemometer's apparent wind in body axes):
the wind force of the vessel's ``[hull.wind]`` areas on the low-passed measured wind, by the function the
simulator's plant uses (`observers.hull.relative_wind_force`), taken off τ with gain k_w
(``wind_feedforward_gain``, 0 = off) after a first-order filter of time constant ``wind_filter_s``. It
counters a gust as it is measured instead of after the position has drifted and the integrator has
caught up. When the wind is lost the last force is held and faded out linearly over ``wind_loss_fade_s``
(default `wind_feedforward.default_fade_s`: twice the slower of the integral time 1/a and the observer's
bias-mode time given as ``observer_bias_time_s``), so the integrator and b̂ take the load over gradually;
when it is back, the force returns at the same pace.
The filter runs in every mode (so it is warm on entering dp); the term acts only in dp. A vessel without
``[hull.wind]`` has none (`DPController.wind` is None).

Modes: ``standby`` (τ = 0, integrator reset, reference follows the estimate), ``dp`` (station keeping and
tracking through the reference model, `gateway.control.reference`), ``manual`` (τ from outside, the last one
given kept while `update` gets none; integrator reset; reference follows the estimate: how long an
operator's τ may stand without a new one is the gateway's dead-man, ``[commands] manual_tau_hold_s``,
which then gives τ = 0). Bumpless transfer into ``dp``:
the first `update` in dp starts the reference at η̂ moving with J(ψ̂)ν̂ (so η̃ = 0, ν̃ = 0) and sets the
integrator so that the first τ equals the τ output just before (the manual τ, or 0 from standby), or the
``tau_now`` given to `set_mode`. That start content of the integrator then fades to zero (a smoothstep) over
``takeover_fade_s`` (default 1/ωn), so τ moves from the τ before to the law's own, whose bias
feed-forward carries the load the observer knows: a τ_now of 0 (nobody held the vessel: standby, a
manual τ the dead-man expired) would otherwise cancel that load and leave the vessel drifting until the
integrator unwound through the loop (≈ 1/a, minutes). Without a bias estimate fed forward there is no
fade: the integrator keeps the load it was given. A DOF without integral action (ρᵢ = 0) cannot be
made bumpless this way and may jump. Entering dp with no setpoint given since dp was last left holds
the present position (DP-console convention); a setpoint given while in standby or manual becomes the
target on entering dp (the gateway checks its distance from the estimate again then, and
`forget_setpoint` drops one too far).

Defaults scale with the vessel (Froude scaling from a 76.2 m supply vessel, the MSS supply model of
Torsetnes' case study, factor λ = L/76.2): frequencies × λ^(-1/2), speeds × λ^(1/2), accelerations × 1,
angular accelerations × λ^(-1). For the 1.255 m CyberShip II (1:70 model) ωn = 0.55 rad/s, 0.064 m/s,
15.6°/s; its basin sea's wave band is also ≈ 8× higher, so the ratio to the waves is kept (not in the
`hassani` case's full-scale sea: docs/controller.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray

from gateway.control import _controller_kernel as _ck
from gateway.control.reference import ReferenceLimits, ReferenceModel, ReferenceState
from gateway.control.wind_feedforward import WindFeedForward, default_fade_s
from observers.kinematics import rotation, ssa_scalar
from observers.vessel import VesselModel

Array = NDArray[np.float64]

MODES = ("standby", "dp", "manual")

REFERENCE_LENGTH_M = 76.2
"""Length at which the defaults below hold (MSS supply vessel); other vessels are Froude-scaled."""
DEFAULT_BANDWIDTH_RAD_S = (0.07, 0.07, 0.10)
"""Surge, sway, yaw. Yaw is stiffer: in a 6 m sea (torsetnes_2004) 0.07 rad/s held the heading only to a
2.6° p95 on some seeds, 0.10 keeps it within 1.6° while the commanded thrust stays ≥ 20 dB quieter in the
wave band than without wave filtering (tests/test_station_keeping.py)."""
DEFAULT_MAX_SPEED_MPS = 0.5
DEFAULT_MAX_ACCEL_MPS2 = 0.05
DEFAULT_MAX_YAW_RATE_RAD_S = math.radians(2.0)
DEFAULT_MAX_YAW_ACCEL_RAD_S2 = math.radians(0.2)
RETURN_CLOSING = 0.1
"""A governed return starts only while the vessel closes on its reference at this fraction of the return
speed (or yaw-rate limit) or faster: not while it is merely held where it is (`DPController`)."""
RETURN_HOME = 0.05
"""A governed return ends when the reference is this fraction of the return radius (and heading) from
its target."""
DEFAULT_WIND_FILTER_S = 2.0
"""Time constant of the wind feed-forward's low-pass (s): see docs/controller.md for the measurement."""

ZERO3 = np.zeros(3)


class ControllerError(ValueError):
    """A tuning or an input the controller cannot use; the message names the field."""


def froude_defaults(vessel: VesselModel) -> dict[str, Any]:
    """Default bandwidth and reference limits for ``vessel``, Froude-scaled from the 76.2 m reference."""
    lam = vessel.length_m / REFERENCE_LENGTH_M
    s = math.sqrt(lam)
    return {
        "bandwidth_rad_s": tuple(w / s for w in DEFAULT_BANDWIDTH_RAD_S),
        "max_speed_mps": DEFAULT_MAX_SPEED_MPS * s,
        "max_accel_mps2": DEFAULT_MAX_ACCEL_MPS2,
        "max_yaw_rate_rad_s": DEFAULT_MAX_YAW_RATE_RAD_S / s,
        "max_yaw_accel_rad_s2": DEFAULT_MAX_YAW_ACCEL_RAD_S2 / lam,
    }


def _per_dof(value: Any, name: str, n: int = 3, allow_zero: bool = False) -> tuple[float, ...]:
    a = np.asarray(value, dtype=float).reshape(-1)
    if a.size == 1:
        a = np.repeat(a, n)
    ok = a.size == n and np.all(np.isfinite(a)) and np.all(a >= 0 if allow_zero else a > 0)
    if not ok:
        need = "non-negative" if allow_zero else "positive"
        count = "one value" if n == 1 else f"one value or {n} (one per DOF)"
        raise ControllerError(
            f"tuning '{name}': must be {need} and finite, {count}, got {np.asarray(value).tolist()}"
        )
    return tuple(float(x) for x in a)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ControllerTuning:
    """Controller tuning in physical terms. Per-DOF values are (surge, sway, yaw); one value means all.

    bandwidth_rad_s:           closed-loop natural frequency ωn (rad/s); None: Froude-scaled default
                               (0.07, 0.07, 0.10 rad/s at 76.2 m).
    damping:                   closed-loop relative damping ζ (1.0: critically damped).
    integral_ratio:            ρ = a/ωn, integral pole a as a fraction of ωn (0: no integral action).
    bias_feedforward:          add −Jᵀ(ψ̂) b̂ from the observer's bias estimate.
    feedforward:               add M ν̇_d + D ν_d from the reference model.
    max_speed_mps, max_accel_mps2, max_yaw_rate_rad_s, max_yaw_accel_rad_s2:
                               reference-model limits over ground; None: Froude-scaled 0.5 m/s,
                               0.05 m/s², 2°/s, 0.2°/s² at 76.2 m.
    reference_bandwidth_rad_s: ω of the reference model, one value or (translation, yaw); None: the
                               closed-loop ωn (min of surge and sway for translation).
    tracking_time_s:           Tₜ of back-calculation anti-windup, per DOF; None: 1/ωn.
    return_speed_mps:          speed limit over ground of a governed return to the station (a vessel
                               found far off its reference and coming back, `DPController`); None:
                               ``max_speed_mps``. At most ``max_speed_mps``.
    governed_return:           restart the reference at a vessel found far off it and coming back
                               (True, the default); False: the full error drives the return.
    wind_feedforward_gain:     k_w ∈ [0, 1] of the wind feed-forward (0: off; 1: the whole measured force).
    wind_filter_s:             T_w > 0 of the measured wind's first-order low-pass (s).
    wind_loss_fade_s:          T_f ≥ 0: after the wind is lost its force fades linearly to zero over T_f
                               (s; 0: drops at once); None: `wind_feedforward.default_fade_s`.
    takeover_fade_s:           T_x ≥ 0: after a bumpless entry into dp, the integrator's start content
                               fades to zero over T_x (s, along a smoothstep), so τ goes from the τ before
                               entry to the control law's own, bias feed-forward included (module docstring,
                               "Bumpless transfer"); 0: at once; inf: never (the integrator unwinds it
                               through the loop, ≈ 1/a); None: 1/ωn of the slowest DOF.
    """

    bandwidth_rad_s: float | tuple[float, ...] | None = None
    damping: float | tuple[float, ...] = 1.0
    integral_ratio: float | tuple[float, ...] = 0.1
    bias_feedforward: bool = True
    feedforward: bool = True
    max_speed_mps: float | None = None
    max_accel_mps2: float | None = None
    max_yaw_rate_rad_s: float | None = None
    max_yaw_accel_rad_s2: float | None = None
    reference_bandwidth_rad_s: float | tuple[float, ...] | None = None
    tracking_time_s: float | tuple[float, ...] | None = None
    return_speed_mps: float | None = None
    governed_return: bool = True
    wind_feedforward_gain: float = 1.0
    wind_filter_s: float = DEFAULT_WIND_FILTER_S
    wind_loss_fade_s: float | None = None
    takeover_fade_s: float | None = None

    def resolved(self, vessel: VesselModel) -> ControllerTuning:
        """This tuning with every default filled in for ``vessel`` and per-DOF values as tuples, checked."""
        d = froude_defaults(vessel)
        wn = _per_dof(
            d["bandwidth_rad_s"] if self.bandwidth_rad_s is None else self.bandwidth_rad_s, "bandwidth_rad_s"
        )
        limits: dict[str, float] = {}
        for key in ("max_speed_mps", "max_accel_mps2", "max_yaw_rate_rad_s", "max_yaw_accel_rad_s2"):
            value = getattr(self, key)
            limits[key] = _per_dof(d[key] if value is None else value, key, n=1)[0]
        ref = self.reference_bandwidth_rad_s
        ref_w = _per_dof((min(wn[0], wn[1]), wn[2]) if ref is None else ref, "reference_bandwidth_rad_s", n=2)
        tt = self.tracking_time_s
        ret = limits["max_speed_mps"] if self.return_speed_mps is None else self.return_speed_mps
        ret = _per_dof(ret, "return_speed_mps", n=1)[0]
        if ret > limits["max_speed_mps"]:
            raise ControllerError(
                f"tuning 'return_speed_mps': must be at most the reference's max_speed_mps "
                f"({limits['max_speed_mps']:g} m/s), got {self.return_speed_mps!r}"
            )
        # The values as given, not through the fields' float types: compiled (setup.py), reading a float
        # field turns True into 1.0 and fails on a string before these checks could say what is wrong.
        given: dict[str, Any] = vars(self)
        gain = given["wind_feedforward_gain"]
        if isinstance(gain, bool) or not isinstance(gain, int | float) or not 0.0 <= gain <= 1.0:
            raise ControllerError(
                f"tuning 'wind_feedforward_gain': must be a number in [0, 1] (0 = off), got {gain!r}"
            )
        wf = given["wind_filter_s"]
        if isinstance(wf, bool) or not isinstance(wf, int | float) or not (math.isfinite(wf) and wf > 0):
            raise ControllerError(f"tuning 'wind_filter_s': must be a finite number > 0 s, got {wf!r}")
        fade = given["wind_loss_fade_s"]
        if fade is not None and (
            isinstance(fade, bool)
            or not isinstance(fade, int | float)
            or not (math.isfinite(fade) and fade >= 0)
        ):
            raise ControllerError(
                f"tuning 'wind_loss_fade_s': must be a finite number >= 0 s (0: drop at once), got {fade!r}"
            )
        takeover = given["takeover_fade_s"]
        if takeover is None:
            takeover = 1.0 / min(wn)
        if (
            isinstance(takeover, bool)
            or not isinstance(takeover, int | float)
            or math.isnan(takeover)
            or takeover < 0
        ):
            raise ControllerError(
                "tuning 'takeover_fade_s': must be a number >= 0 s (0: at once, inf: never), "
                f"got {given['takeover_fade_s']!r}"
            )
        return replace(
            self,
            bandwidth_rad_s=wn,
            damping=_per_dof(self.damping, "damping"),
            integral_ratio=_per_dof(self.integral_ratio, "integral_ratio", allow_zero=True),
            bias_feedforward=bool(self.bias_feedforward),
            feedforward=bool(self.feedforward),
            reference_bandwidth_rad_s=ref_w,
            tracking_time_s=tuple(1.0 / w for w in wn) if tt is None else _per_dof(tt, "tracking_time_s"),
            return_speed_mps=ret,
            governed_return=bool(self.governed_return),
            wind_feedforward_gain=float(gain),
            wind_filter_s=float(wf),
            wind_loss_fade_s=None if fade is None else float(fade),
            takeover_fade_s=float(takeover),
            **limits,
        )


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ControllerGains:
    """Kp, Ki, Kd (3×3, SI: N/m and N·m/rad; N/(m·s) and N·m/(rad·s); N·s/m and N·m·s/rad) and their design.

    Per DOF: ``omega_n`` (rad/s), ``zeta`` (as asked), ``integral_pole`` a = ρ·ωn (rad/s), and
    ``char_poly`` rows [c, p, k] of the closed-loop polynomial s³ + c s² + p s + k (M⁻¹(D + Kd), M⁻¹Kp,
    M⁻¹Ki are diag(c), diag(p), diag(k)). ``clipped`` marks DOFs whose Kd would have been negative (c raised
    to Dᵢᵢ/Mᵢᵢ; their poles are then not at ωn, ζ). See the module docstring for the formulas.
    """

    Kp: Array
    Ki: Array
    Kd: Array
    omega_n: Array
    zeta: Array
    integral_pole: Array
    char_poly: Array
    clipped: tuple[bool, bool, bool]

    def design_poles(self) -> NDArray[np.complex128]:
        """The closed-loop poles the gains place (roots of s³ + c s² + p s + k per DOF), sorted.

        Exact (−ζω ± ω√(ζ² − 1), −a) where not clipped, so a critically damped double pole stays double.
        """
        out: list[complex] = []
        for i in range(3):
            w, z, a = float(self.omega_n[i]), float(self.zeta[i]), float(self.integral_pole[i])
            if self.clipped[i]:
                out.extend(complex(x) for x in np.roots(np.r_[1.0, self.char_poly[i]]))
            else:
                root = w * complex(z * z - 1.0) ** 0.5
                out.extend([-z * w + root, -z * w - root, complex(-a)])
        return np.sort_complex(np.array(out, dtype=np.complex128))


def controller_gains(
    vessel: VesselModel, omega_n: ArrayLike, zeta: ArrayLike = 1.0, integral_ratio: ArrayLike = 0.1
) -> ControllerGains:
    """Kp, Kd, Ki from M, D and per-DOF ωn, ζ, ρ (module docstring)."""
    w = np.array(_per_dof(omega_n, "bandwidth_rad_s"))
    z = np.array(_per_dof(zeta, "damping"))
    a = w * np.array(_per_dof(integral_ratio, "integral_ratio", allow_zero=True))
    M = np.asarray(vessel.M, dtype=float)
    D = np.asarray(vessel.D, dtype=float)
    c = 2 * z * w + a
    floor = np.diag(D) / np.diag(M)
    clipped = c < floor
    c = np.maximum(c, floor)
    p = w * w + 2 * z * w * a
    k = w * w * a
    Kp = M @ np.diag(p)
    Kd = M @ np.diag(c) - D
    Ki = M @ np.diag(k)
    cl = (bool(clipped[0]), bool(clipped[1]), bool(clipped[2]))
    return ControllerGains(Kp, Ki, Kd, w, z, a, np.column_stack([c, p, k]), cl)


def closed_loop_matrix(vessel: VesselModel, gains: ControllerGains) -> Array:
    """A_τ of Torsetnes (66), with the plant's damping: state [∫e, e, ė], e = Jᵀη̃ (heading frozen)."""
    Minv = vessel.Minv
    Z, eye = np.zeros((3, 3)), np.eye(3)
    D = np.asarray(vessel.D, dtype=float)
    return np.block(
        [
            [Z, eye, Z],
            [Z, Z, eye],
            [-Minv @ gains.Ki, -Minv @ gains.Kp, -Minv @ (D + gains.Kd)],
        ]
    )


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ControllerOutput:
    """One controller step.

    tau:        demanded generalised force [X, Y, N] (N, N, N·m, body frame).
    mode:       "standby", "dp" or "manual".
    valid:      False when dp had no finite estimate and held the previous τ.
    reference:  the reference state (in standby/manual it follows the estimate).
    eta_error:  η̃ = η̂ − η_d, earth frame, heading by ssa (zero outside dp).
    nu_error:   ν̃ = ν̂ − Jᵀ(ψ̂) η_d', body frame (zero outside dp).
    integral:   z = ∫η̃ dt, earth frame (m·s, m·s, rad·s).
    tau_p, tau_i, tau_d, tau_ff: the terms of τ (P, I, D, feed-forward incl. bias and wind); zero outside
                dp.
    tau_wind:   the wind feed-forward −k_w w τ̂_w within tau_ff: zero outside dp; after the wind is lost, its
                held force fading out (w), zero once faded (`WindFeedForward`).
    """

    t: float
    tau: Array
    mode: str
    valid: bool
    reference: ReferenceState
    eta_error: Array
    nu_error: Array
    integral: Array
    tau_p: Array
    tau_i: Array
    tau_d: Array
    tau_ff: Array
    tau_wind: Array = field(default_factory=lambda: np.zeros(3))


def _num(value: float | tuple[float, ...] | None) -> Array:
    """A resolved tuning value as an array (resolved tunings have no None)."""
    if value is None:
        raise ControllerError("tuning: unresolved value (use ControllerTuning.resolved)")
    return np.atleast_1d(np.asarray(value, dtype=float))


def _finite3(value: ArrayLike | None) -> Array | None:
    if value is None:
        return None
    if type(value) is np.ndarray and value.shape == (3,) and value.dtype == np.float64:
        # the common case (an estimate's array), without numpy's per-call overhead: the same result
        x0, x1, x2 = value.tolist()
        return value if math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2) else None
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        return None
    return a


@mypyc_attr(native_class=False)
class DPController:
    """Nonlinear PID with reference model, modes and anti-windup (module docstring).

    Starts in ``standby``. Call `update` once per control tick with the observer's estimate.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: ControllerTuning | None = None,
        *,
        compiled: bool = True,
        observer_bias_time_s: float | None = None,
    ):
        """``compiled``: run the steps of dp mode after the first in one compiled call
        (`gateway.control._controller_kernel`, the same equations on scalars; round-off apart the same
        numbers); False: this module's numpy code throughout, the reference the kernel is tested against.
        ``observer_bias_time_s``: the time constant of the feeding observer's slowest (bias) mode, for the
        default wind loss fade (`wind_feedforward.default_fade_s`); None: the integral time alone."""
        self.vessel = vessel
        self.compiled = compiled
        self.tuning = (tuning or ControllerTuning()).resolved(vessel)
        tu = self.tuning
        self.gains = controller_gains(
            vessel, _num(tu.bandwidth_rad_s), _num(tu.damping), _num(tu.integral_ratio)
        )
        limits = ReferenceLimits(
            float(_num(tu.max_speed_mps)[0]),
            float(_num(tu.max_accel_mps2)[0]),
            float(_num(tu.max_yaw_rate_rad_s)[0]),
            float(_num(tu.max_yaw_accel_rad_s2)[0]),
        )
        ref_w = _num(tu.reference_bandwidth_rad_s)
        self.reference = ReferenceModel((float(ref_w[0]), float(ref_w[1])), limits)
        self._M = np.asarray(vessel.M, dtype=float)
        self._D = np.asarray(vessel.D, dtype=float)
        self._Minv = vessel.Minv
        self._k = self.gains.char_poly[:, 2].copy()  # ω²a per DOF (M⁻¹Ki = diag(k))
        self._has_i = self._k > 0
        self._tracking_rate = 1.0 / _num(tu.tracking_time_s)
        self._mode = "standby"
        self._entering = False
        self._tau_now: Array | None = None
        self._setpoint: Array | None = None
        self._z = np.zeros(3)
        # the takeover fade: z loses its start content z₀ (earth frame) along a smoothstep over T_x
        self._takeover_s = float(_num(tu.takeover_fade_s)[0])
        self._fade_z = np.zeros(3)
        self._fade_left = 0.0
        self._tau = np.zeros(3)
        self._tau_manual = np.zeros(3)
        self._t: float | None = None
        # the compiled step's constants: [M, D, M⁻¹, Kp, Ki, Kd] and per DOF [k, has integral, 1/Tt]
        self._mats = np.ascontiguousarray(
            np.stack([self._M, self._D, self._Minv, self.gains.Kp, self.gains.Ki, self.gains.Kd]), dtype=float
        )
        self._dof = np.vstack(
            [self._k, self._has_i.astype(float), np.broadcast_to(self._tracking_rate, (3,))]
        ).astype(float)
        # governed return (`_govern_return`): the error beyond which the feedback alone would bring the
        # vessel back faster than the return speed / the yaw-rate limit (peak of the critically damped
        # step response e₀·ω/e)
        wn = self.gains.omega_n
        self.return_speed_mps = float(_num(tu.return_speed_mps)[0])
        self.return_radius_m = math.e * self.return_speed_mps / float(min(wn[0], wn[1]))
        self.return_heading_rad = math.e * limits.max_yaw_rate_rad_s / float(wn[2])
        self.returns = 0
        """Governed returns started so far (each restart of the reference's trajectory at the vessel)."""
        self.returning = False
        """A governed return is under way: from a restart until the reference is back at its target (or a
        new target, a new mode). The vessel is off its station not by the operator's choice, so the
        deviation alarms measure from the target meanwhile (`gateway.pipeline`)."""
        self.last_return: str | None = None
        """The words of the last governed return, for the status (`gateway.pipeline`)."""
        hull = vessel.hull
        self.wind: WindFeedForward | None = None
        """The wind feed-forward; None for a vessel without wind areas or with gain 0."""
        if hull is not None and hull.wind is not None and tu.wind_feedforward_gain > 0:
            fade = tu.wind_loss_fade_s
            if fade is None:
                a = self.gains.integral_pole
                integral_s = 1.0 / float(a[a > 0].min()) if np.any(a > 0) else math.inf
                fade = default_fade_s(integral_s, observer_bias_time_s)
            self.wind = WindFeedForward(
                hull.wind, vessel.length_m, tu.wind_filter_s, tu.wind_feedforward_gain, fade
            )

    # -- commands ---------------------------------------------------------------------------------------
    @property
    def mode(self) -> str:
        return self._mode

    @property
    def tau(self) -> Array:
        """The last τ output."""
        return self._tau.copy()

    @property
    def integral(self) -> Array:
        """z = ∫η̃ dt (earth frame)."""
        return self._z.copy()

    def set_mode(self, mode: str, *, tau_now: ArrayLike | None = None) -> None:
        """Switch to ``standby``, ``dp`` or ``manual``; takes effect at the next `update`.

        Entering dp is bumpless: the first τ in dp equals ``tau_now`` if given (e.g. the τ the thrusters
        actually deliver), else the τ this controller output last (the manual τ, or 0 from standby).
        """
        if mode not in MODES:
            raise ControllerError(f"mode: must be one of {MODES}, got {mode!r}")
        if mode == self._mode:
            return
        self.returning = False
        self._fade_left = 0.0
        if self._mode == "dp":
            self._setpoint = None  # leaving dp: re-entering holds the present position unless told otherwise
        if mode == "dp":
            self._entering = True
            self._tau_now = _finite3(tau_now)
        if mode == "manual":
            self._tau_manual = np.zeros(3)
        self._mode = mode

    @property
    def setpoint(self) -> Array | None:
        """The target of the last `set_setpoint` (None: dp holds the position it is entered at)."""
        return None if self._setpoint is None else self._setpoint.copy()

    def forget_setpoint(self) -> None:
        """Outside dp: forget the setpoint held for dp, which then holds the position it is entered at."""
        if self._mode != "dp":
            self._setpoint = None

    def set_setpoint(self, eta_target: ArrayLike) -> None:
        """Target [north_m, east_m, heading_rad] in local NED; the reference model moves to it."""
        r = np.asarray(eta_target, dtype=float).reshape(-1)
        if r.shape != (3,) or not np.all(np.isfinite(r)):
            raise ControllerError(
                "setpoint: must be 3 finite numbers [north_m, east_m, heading_rad], "
                f"got {np.asarray(eta_target).tolist()}"
            )
        r = r.copy()
        r[2] = ssa_scalar(float(r[2]))
        if self._setpoint is None or not np.array_equal(r, self._setpoint):
            self.returning = False  # the operator's own move from here on
        self._setpoint = r
        if self._mode == "dp" and not self._entering:
            self.reference.set_target(r)

    # -- the control law --------------------------------------------------------------------------------
    def update(
        self,
        t: float,
        eta_hat: ArrayLike,
        nu_hat: ArrayLike,
        bias_hat: ArrayLike | None = None,
        *,
        saturated: bool = False,
        tau_allocated: ArrayLike | None = None,
        tau_manual: ArrayLike | None = None,
        relative_wind: tuple[float, float] | None = None,
    ) -> ControllerOutput:
        """One control step at time t (s; any origin, variable steps; dt = t − previous t).

        eta_hat = [N, E, ψ] (m, m, rad), nu_hat = [u, v, r], bias_hat = earth-fixed b̂ [N, N, N·m] (None or
        non-finite: no bias feed-forward). ``saturated``/``tau_allocated``: allocation's verdict on the
        previous τ (anti-windup). ``tau_manual``: the manual τ (manual mode; None or non-finite: the last
        one given is kept; the gateway gives 0 once its dead-man expires it).
        ``relative_wind``: the measured apparent wind (u_rw, v_rw), body frame, m/s; None: none usable (wind
        feed-forward off).
        """
        t = float(t)
        dt = 0.0 if self._t is None or not math.isfinite(t) else t - self._t
        if not (math.isfinite(dt) and dt > 0):
            dt = 0.0
        if math.isfinite(t):
            self._t = t
        eta = _finite3(eta_hat)
        nu = _finite3(nu_hat)
        b = _finite3(bias_hat)
        tau_w = (
            ZERO3
            if self.wind is None
            else self.wind.update(dt, relative_wind, None if eta is None else float(eta[2]))
        )
        if self._mode == "dp":
            return self._update_dp(t, dt, eta, nu, b, saturated, _finite3(tau_allocated), tau_w)
        self._z = np.zeros(3)
        if self._mode == "manual":
            tm = _finite3(tau_manual)
            if tm is not None:
                self._tau_manual = tm
            self._tau = self._tau_manual.copy()
        else:
            self._tau = np.zeros(3)
        if eta is not None and nu is not None:
            self.reference.reset(eta, rotation(float(eta[2])) @ nu)
        return self._output(t, True, self.reference.state, ZERO3, ZERO3, ZERO3, ZERO3, ZERO3, ZERO3)

    def _update_dp(
        self,
        t: float,
        dt: float,
        eta: Array | None,
        nu: Array | None,
        b: Array | None,
        saturated: bool,
        tau_alloc: Array | None,
        tau_w: Array = ZERO3,
    ) -> ControllerOutput:
        if eta is None or nu is None:
            # no estimate (observer initialising): hold τ, freeze integrator; the reference waits
            return self._output(t, False, self.reference.state, ZERO3, ZERO3, ZERO3, ZERO3, ZERO3, ZERO3)
        if self.tuning.governed_return and not self._entering:
            self._govern_return(eta, nu)
        if self._fade_left > 0 and dt > 0 and not self._entering:
            self._fade_step(dt)
        if self.compiled and not self._entering:
            return self._update_dp_compiled(t, dt, eta, nu, b, saturated, tau_alloc, tau_w)
        R = rotation(float(eta[2]))
        if self._entering:
            self.reference.reset(eta, R @ nu, target=self._setpoint)
            ref = self.reference.state
        else:
            ref = self.reference.step(dt)
        e = eta - ref.eta_d
        e[2] = ssa_scalar(float(e[2]))
        nu_err = nu - R.T @ ref.eta_dot_d
        tau_ff = np.zeros(3)
        if self.tuning.feedforward:
            tau_ff = tau_ff + self._M @ ref.nu_dot_d + self._D @ ref.nu_d
        if self.tuning.bias_feedforward and b is not None:
            tau_ff = tau_ff - R.T @ b
        tau_ff = tau_ff + tau_w
        tau_p = -self.gains.Kp @ (R.T @ e)
        tau_d = -self.gains.Kd @ nu_err
        if self._entering:
            # bumpless: choose z so that τ = τ_now, i.e. −M diag(k) Jᵀz = τ_now − (P + D + FF)
            tau_now = self._tau if self._tau_now is None else self._tau_now
            w = np.zeros(3)
            need = -self._Minv @ (tau_now - (tau_p + tau_d + tau_ff))
            w[self._has_i] = need[self._has_i] / self._k[self._has_i]
            self._z = R @ w
            self._entering = False
            self._tau_now = None
            # ... and that start content fades out: τ moves from τ_now to the law's own (the load b̂ knows)
            self._start_takeover_fade(b is not None and self.tuning.bias_feedforward)
        elif dt > 0:
            if saturated and tau_alloc is not None:
                # back-calculation: take min(dt/Tt, 1) of the excess demand off the integral term
                frac = np.minimum(dt * self._tracking_rate, 1.0)
                dw = self._Minv @ (frac * (self._tau - tau_alloc))
                dw[self._has_i] /= self._k[self._has_i]
                dw[~self._has_i] = 0.0
                self._z = self._z + e * dt + R @ dw
            elif not saturated:
                self._z = self._z + e * dt
            # saturated without tau_allocated: conditional integration, z frozen
        self._z[~self._has_i] = 0.0
        tau_i = -self.gains.Ki @ (R.T @ self._z)
        self._tau = tau_p + tau_i + tau_d + tau_ff
        return self._output(t, True, ref, e, nu_err, tau_p, tau_i, tau_d, tau_ff, tau_w)

    def _start_takeover_fade(self, known_load: bool) -> None:
        """After the bumpless first step: z's start content fades to zero over ``takeover_fade_s``.

        The bumpless z makes the first τ equal τ_now, whatever τ_now was. When it was the load held (an
        operator on the joystick, thrusters already pushing), z starts near zero, as the bias feed-forward
        −Jᵀ(ψ̂) b̂ already asks for that load. But τ_now = 0 (from standby without thruster feedback, or
        a manual τ the dead-man expired) means nobody held the vessel: z then holds +Jᵀb̂ exactly cancelling
        the known load, and left to the closed loop it would unwind at the integral pole a (≈ 1/a, over
        two minutes for a supply vessel) while the vessel drifts off. Fading it instead takes the load up
        at a pace the thrusters can follow. Only with a bias estimate fed forward: without one the
        integrator is all the controller knows of the load, and keeps what it was given.

        The fade follows a smoothstep S(s) = 3s² − 2s³, s = t/T_x, not a ramp: its rate is zero at both
        ends, so τ's rate of change does not step when DP is engaged or when the fade ends (a linear
        fade of a supply vessel's 8 MN·m yaw braking feed-forward, also cancelled by the bumpless z,
        stepped τ by 38 kN·m in the first 0.1 s). Its peak rate is 1.5 z₀/T_x, at T_x/2."""
        fade = self._takeover_s
        if not known_load or not math.isfinite(fade):
            return
        if fade <= 0:
            self._z = np.zeros(3)
            return
        self._fade_z = self._z.copy()
        self._fade_left = fade

    def _fade_step(self, dt: float) -> None:
        """Take the part of z₀ the smoothstep removes over the next dt off z (`_start_takeover_fade`)."""
        fade = self._takeover_s
        s0 = 1.0 - self._fade_left / fade
        self._fade_left = max(self._fade_left - dt, 0.0)
        s1 = 1.0 - self._fade_left / fade
        share = (3 * s1 * s1 - 2 * s1 * s1 * s1) - (3 * s0 * s0 - 2 * s0 * s0 * s0)
        self._z = self._z - share * self._fade_z

    def _govern_return(self, eta: Array, nu: Array) -> None:
        """A vessel far off its reference and coming back to it returns at the reference model's pace.

        Translation: when the estimate is more than ``return_radius_m`` from η_d and its velocity over
        ground relative to η_d' closes the distance (or holds it), the reference's trajectory (η_d, η_d',
        prefilter) restarts at η̂ moving with J(ψ̂)ν̂, its speed limit lowered to ``return_speed_mps``;
        the target — the operator's setpoint — does not move. The reference then brakes the vessel's
        motion at ≤ a_max and walks it back at ≤ the return speed. Heading the same with
        ``return_heading_rad`` and the reference's yaw-rate limit. While the vessel still moves away (a
        drift-off beyond capability), nothing is restarted: the full error keeps pushing it back and the
        deviation alarms measure it from where the reference was. The integrator: back-calculation
        makes it hold a force against the unachievable P term, so it restarts at zero for the restarted
        DOFs."""
        n_d, e_d, psi_d, vn_d, ve_d, r_d = self.reference.trajectory()
        if self.returning and self._reference_home(n_d, e_d, psi_d):
            self.returning = False
        x0, x1, x2 = eta.tolist()
        u, v, r = nu.tolist()
        c, s = math.cos(x2), math.sin(x2)
        xd0, xd1 = c * u - s * v, s * u + c * v
        dn, de = x0 - n_d, x1 - e_d
        dist = math.hypot(dn, de)
        # Coming back: closing on the reference at a tenth of the return speed or more. A vessel merely
        # held where it is (a load at the edge of its capability) is not restarted: each restart zeroes
        # the integrator, the force that holds it, and it would drift off again.
        trans = (
            dist > self.return_radius_m
            and dn * (xd0 - vn_d) + de * (xd1 - ve_d) < -RETURN_CLOSING * self.return_speed_mps * dist
        )
        dpsi = ssa_scalar(x2 - psi_d)
        closing_rate = RETURN_CLOSING * self.reference.limits.max_yaw_rate_rad_s
        yaw = abs(dpsi) > self.return_heading_rad and dpsi * (r - r_d) < -closing_rate * abs(dpsi)
        if not (trans or yaw):
            return
        self.returning = True
        self.reference.restart(
            eta,
            (xd0, xd1, r),
            translation=trans,
            yaw=yaw,
            max_speed_mps=self.return_speed_mps if trans else None,
        )
        # The integrator restarts too, for the restarted DOFs: through the saturated drift-off
        # back-calculation has pulled the integral term against the (huge, unachievable) P term, so it holds
        # a force pointing away from the station; with the error gone it would drive the vessel off again.
        # The load is carried by the bias feed-forward b̂; the integrator re-learns the residual.
        if trans:
            self._z[0] = self._z[1] = 0.0
            self._fade_z[0] = self._fade_z[1] = 0.0
        if yaw:
            self._z[2] = 0.0
            self._fade_z[2] = 0.0
        words = []
        if trans:
            words.append(f"{dist:.1f} m off at ≤ {self.return_speed_mps:.2f} m/s")
        if yaw:
            rate = math.degrees(self.reference.limits.max_yaw_rate_rad_s)
            words.append(f"{math.degrees(abs(dpsi)):.1f}° off at ≤ {rate:.2f}°/s")
        self.returns += 1
        self.last_return = (
            "returning to station: " + ", ".join(words) + " (the reference restarted at the vessel; "
            "setpoint unchanged)"
        )

    def _reference_home(self, n_d: float, e_d: float, psi_d: float) -> bool:
        """The reference is back at its target: within a twentieth of the return radius and heading."""
        tn, te, tpsi = self.reference.target.tolist()
        return (
            math.hypot(n_d - tn, e_d - te) <= RETURN_HOME * self.return_radius_m
            and abs(ssa_scalar(psi_d - tpsi)) <= RETURN_HOME * self.return_heading_rad
        )

    def _update_dp_compiled(
        self,
        t: float,
        dt: float,
        eta: Array,
        nu: Array,
        b: Array | None,
        saturated: bool,
        tau_alloc: Array | None,
        tau_w: Array = ZERO3,
    ) -> ControllerOutput:
        """`_update_dp` after the first dp step, in one compiled call (`_controller_kernel.dp_step`); the
        wind feed-forward, a known term, is added to τ and τ_ff after it (so the τ that back-calculation
        compares with the allocated force at the next step includes it, as in `_update_dp`)."""
        rs, rp = self.reference.packed()
        use_b = self.tuning.bias_feedforward and b is not None
        inp = np.concatenate(
            (
                eta,
                nu,
                b if b is not None else ZERO3,
                tau_alloc if tau_alloc is not None else ZERO3,
                self._tau,
                self._z,
                self.reference.target,
            )
        )
        o = _ck.dp_step(
            rs,
            rp,
            inp,
            dt,
            use_b,
            tau_alloc is not None,
            saturated,
            self.tuning.feedforward,
            self._mats,
            self._dof,
        )
        self.reference.set_packed(rs)
        if tau_w is not ZERO3:
            o[0:3] += tau_w
            o[21:24] += tau_w
        self._tau, self._z = o[0:3].copy(), o[3:6].copy()
        ref = ReferenceState(o[24:27], o[27:30], o[30:33], o[33:36], o[36:39], self.reference.target)
        return ControllerOutput(
            t=t,
            tau=o[0:3].copy(),
            mode=self._mode,
            valid=True,
            reference=ref,
            eta_error=o[6:9],
            nu_error=o[9:12],
            integral=o[3:6].copy(),
            tau_p=o[12:15],
            tau_i=o[15:18],
            tau_d=o[18:21],
            tau_ff=o[21:24],
            tau_wind=tau_w.copy(),
        )

    def _output(
        self,
        t: float,
        valid: bool,
        ref: ReferenceState,
        e: Array,
        nu_err: Array,
        tau_p: Array,
        tau_i: Array,
        tau_d: Array,
        tau_ff: Array,
        tau_w: Array = ZERO3,
    ) -> ControllerOutput:
        return ControllerOutput(
            t=t,
            tau=self._tau.copy(),
            mode=self._mode,
            valid=valid,
            reference=ref,
            eta_error=np.array(e, dtype=float),
            nu_error=np.array(nu_err, dtype=float),
            integral=self._z.copy(),
            tau_p=np.array(tau_p, dtype=float),
            tau_i=np.array(tau_i, dtype=float),
            tau_d=np.array(tau_d, dtype=float),
            tau_ff=np.array(tau_ff, dtype=float),
            tau_wind=np.array(tau_w, dtype=float),
        )


__all__ = [
    "MODES",
    "ControllerError",
    "ControllerGains",
    "ControllerOutput",
    "ControllerTuning",
    "DPController",
    "closed_loop_matrix",
    "controller_gains",
    "froude_defaults",
]
