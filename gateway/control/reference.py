"""Reference model for DP setpoint changes: smooth η_d, ν_d, ν̇_d with speed and acceleration limits.

A setpoint (target r = [N, E, ψ]) is never fed to the controller as a step. Per DOF group — horizontal
translation (N, E together) and yaw — a first-order prefilter in cascade with a critically damped
second-order filter whose velocity and acceleration are saturated::

    x_f' = ω (r − x_f)                                       first-order prefilter of the target
    v_c  = sat_vmax( (ω/2) (x_f − η_d) )                     velocity command, saturated
    η_d'' = a_d = sat_amax( 2ω (v_c − η_d') )                acceleration, saturated

Unsaturated, a_d = ω²(x_f − η_d) − 2ω η_d', and the cascade is the linear third-order reference model of
Fossen (2011, Handbook of Marine Craft Hydrodynamics and Motion Control, Sec. 12.1, eq. (12.12) with
Δ = I, i.e. critically damped) ::

    η_d''' + 3ω η_d'' + 3ω² η_d' + ω³ η_d = ω³ r              (triple pole at −ω)

whose step response is monotone (no overshoot) and whose acceleration is continuous (a step in r moves
x_f continuously, so a_d starts from zero: no jump in the M ν̇_d feed-forward). The saturations (Fossen's
"velocity and acceleration saturating elements") are written so that they hold by construction:

* Translation is saturated as a 2-D vector (speed and acceleration over ground, m/s and m/s² in NED),
  so a step moves the reference along a straight line and the diagonal is not √2 faster. Yaw is scalar.
* a_d is clipped, so |η_d''| ≤ a_max always. The velocity is never clipped: each sub-step
  η_d'(k+1) = η_d'(k) + h·a_d lies on the segment from η_d'(k) towards v_c (2ωh ≤ 1, see ``H_FACTOR``),
  so |η_d'| ≤ max(|η_d'(0)|, v_max): a reference started faster than v_max (from a drifting vessel)
  slows down at a_max and then stays within the limit.
* ω is capped at 2·a_max/v_max. In the decelerating phase v_c falls at (ω/2)|η_d'| and a_d lags it by
  about a quarter of the speed, i.e. needs ω·v/2 ≤ a_max; with the cap the acceleration limit does not
  bind while braking, which is what keeps a saturated move free of overshoot.

Heading: the target and every heading difference go through `ssa`, so a target from 170° to −170° turns
20° (through 180°), not 340°; ψ_d and the filter state are kept in [-π, π).

Body frame (ψ_d is the reference heading)::

    ν_d = Jᵀ(ψ_d) η_d',      ν̇_d = Jᵀ(ψ_d) η_d'' − r_d S ν_d = Jᵀ(ψ_d) η_d'' + r_d [v_d, −u_d, 0]ᵀ

(from J' = r J S, S = [[0, −1, 0], [1, 0, 0], [0, 0, 0]]). The limits apply in the earth frame; the body
acceleration ν̇_d also contains the turn-rate term.

Discrete time: `step(dt)` integrates in equal sub-steps of at most ``H_FACTOR/ω_max`` (the prefilter
exactly, position with the constant-acceleration formula). Deterministic, no clocks. Pure numerics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mypy_extensions import mypyc_attr
from numpy.typing import ArrayLike, NDArray

from observers.kinematics import rotation, ssa_scalar

Array = NDArray[np.float64]

H_FACTOR = 0.1
"""Sub-step h ≤ H_FACTOR/ω: 2ωh ≤ 0.2 keeps each velocity update a convex combination (limit by
construction) and the Euler error of the second-order filter below 1 %."""

MAX_SUBSTEPS = 100_000
"""Bound on the work of one `step` after a long gap (the reference then advances in larger steps)."""


class ReferenceModelError(ValueError):
    """Invalid reference-model parameters or inputs (the message names the field)."""


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ReferenceModelError(f"reference '{name}': must be a positive finite number, got {value!r}")
    return v


def _vec3(value: ArrayLike, name: str) -> Array:
    a = np.asarray(value, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ReferenceModelError(
            f"reference '{name}': must be 3 finite numbers, got {np.asarray(value).tolist()}"
        )
    return a.copy()


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ReferenceLimits:
    """Limits of the reference motion, over ground (earth frame): m/s, m/s², rad/s, rad/s²."""

    max_speed_mps: float
    max_accel_mps2: float
    max_yaw_rate_rad_s: float
    max_yaw_accel_rad_s2: float

    def __post_init__(self) -> None:
        for name in ("max_speed_mps", "max_accel_mps2", "max_yaw_rate_rad_s", "max_yaw_accel_rad_s2"):
            object.__setattr__(self, name, _positive(getattr(self, name), name))


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ReferenceState:
    """The reference at one time: earth-frame η_d, η_d', η_d''; body-frame ν_d, ν̇_d (at ψ_d); target r."""

    eta_d: Array
    eta_dot_d: Array
    eta_ddot_d: Array
    nu_d: Array
    nu_dot_d: Array
    target: Array


def _sat(v: Array, limit: float) -> Array:
    """Scale a vector down to norm ``limit`` (direction kept)."""
    n = float(np.hypot(v[0], v[1])) if v.shape == (2,) else abs(float(v[0]))
    return v * (limit / n) if n > limit else v


def _sat_scalar(x: float, limit: float) -> float:
    return max(-limit, min(limit, x))


@mypyc_attr(native_class=False)
class ReferenceModel:
    """Third-order reference model with limits, per group (translation N–E, yaw). See module docstring.

    ``bandwidth_rad_s`` is ω for (translation, yaw), or one value for both; each is capped at
    2·a_max/v_max of its group (`bandwidth` gives the values used).
    """

    def __init__(self, bandwidth_rad_s: float | tuple[float, float], limits: ReferenceLimits):
        w = (
            (bandwidth_rad_s, bandwidth_rad_s)
            if isinstance(bandwidth_rad_s, int | float)
            else tuple(bandwidth_rad_s)
        )
        if len(w) != 2:
            raise ReferenceModelError("reference 'bandwidth_rad_s': one value or (translation, yaw)")
        w_t = _positive(w[0], "bandwidth_rad_s")
        w_y = _positive(w[1], "bandwidth_rad_s")
        self.limits = limits
        self._w_t = min(w_t, 2.0 * limits.max_accel_mps2 / limits.max_speed_mps)
        self._w_y = min(w_y, 2.0 * limits.max_yaw_accel_rad_s2 / limits.max_yaw_rate_rad_s)
        self._h_max = H_FACTOR / max(self._w_t, self._w_y)
        self._vmax = limits.max_speed_mps  # the speed limit in force (lower during a governed return)
        self._p = np.zeros(2)  # η_d (N, E)
        self._v = np.zeros(2)  # η_d' (N, E)
        self._f = np.zeros(2)  # prefilter state x_f (N, E)
        self._psi = 0.0
        self._r = 0.0
        self._f_psi = 0.0
        self._target = np.zeros(3)

    @property
    def bandwidth(self) -> tuple[float, float]:
        """ω used for (translation, yaw), after the cap 2·a_max/v_max."""
        return (self._w_t, self._w_y)

    def reset(
        self, eta: ArrayLike, eta_dot: ArrayLike = (0.0, 0.0, 0.0), target: ArrayLike | None = None
    ) -> None:
        """Start the reference at η moving with η' (earth frame); prefilter at η; target r (default η)."""
        e = _vec3(eta, "eta")
        ed = _vec3(eta_dot, "eta_dot")
        self._p = e[:2].copy()
        self._v = ed[:2].copy()
        self._f = e[:2].copy()
        self._psi = ssa_scalar(float(e[2]))
        self._r = float(ed[2])
        self._f_psi = self._psi
        self._vmax = self.limits.max_speed_mps
        self.set_target(e if target is None else target)

    def restart(
        self,
        eta: ArrayLike,
        eta_dot: ArrayLike,
        *,
        translation: bool = True,
        yaw: bool = True,
        max_speed_mps: float | None = None,
    ) -> None:
        """Restart the trajectory (η_d, η_d', prefilter) of the chosen groups at η moving with η' (earth
        frame), keeping the target: the reference then brakes η' at the acceleration limit and moves to the
        same target within the limits. ``max_speed_mps`` lowers the speed limit (never above
        ``limits.max_speed_mps``) until the next different target or `reset`.

        This is how a vessel far off its reference comes back at the reference's pace without the
        target (the operator's setpoint) moving (`gateway.control.controller`, governed return)."""
        e = _vec3(eta, "eta")
        ed = _vec3(eta_dot, "eta_dot")
        if translation:
            self._p = e[:2].copy()
            self._v = ed[:2].copy()
            self._f = e[:2].copy()
        if yaw:
            self._psi = ssa_scalar(float(e[2]))
            self._r = float(ed[2])
            self._f_psi = self._psi
        if max_speed_mps is not None:
            self._vmax = min(_positive(max_speed_mps, "max_speed_mps"), self.limits.max_speed_mps)

    @property
    def speed_limit(self) -> float:
        """The speed limit in force (m/s over ground): ``limits.max_speed_mps``, or a return's lower one."""
        return self._vmax

    def trajectory(self) -> tuple[float, float, float, float, float, float]:
        """(N_d, E_d, ψ_d, N_d', E_d', ψ_d') as floats, earth frame: the state without a `ReferenceState`."""
        p, v = self._p.tolist(), self._v.tolist()
        return (p[0], p[1], self._psi, v[0], v[1], self._r)

    def set_target(self, eta_target: ArrayLike) -> None:
        """New target r = [N, E, ψ] (m, m, rad); the reference moves to it from its present state."""
        r = _vec3(eta_target, "eta_target")
        r[2] = ssa_scalar(float(r[2]))
        if not np.array_equal(r, self._target):
            self._vmax = self.limits.max_speed_mps  # a new move: the reference's own limit again
        self._target = r

    def _accel(self) -> tuple[Array, float]:
        lim = self.limits
        w, wy = self._w_t, self._w_y
        v_c = _sat(0.5 * w * (self._f - self._p), self._vmax)
        a = _sat(2.0 * w * (v_c - self._v), lim.max_accel_mps2)
        r_c = _sat_scalar(0.5 * wy * ssa_scalar(self._f_psi - self._psi), lim.max_yaw_rate_rad_s)
        ar = _sat_scalar(2.0 * wy * (r_c - self._r), lim.max_yaw_accel_rad_s2)
        return a, ar

    def step(self, dt: float) -> ReferenceState:
        """Advance by dt seconds (dt ≤ 0 or not finite: no motion) and return the new state."""
        if math.isfinite(dt) and dt > 0:
            n = min(MAX_SUBSTEPS, max(1, math.ceil(dt / self._h_max - 1e-9)))
            h = dt / n
            gf_t = 1.0 - math.exp(-self._w_t * h)
            gf_y = 1.0 - math.exp(-self._w_y * h)
            # the loop of `_accel` and the updates below on Python floats: the same operations in the same
            # order as on the 2-vectors (numpy's element-wise +, − and × are the same IEEE operations), so
            # the same numbers, without numpy's per-call overhead on arrays of two
            r0, r1, r2 = self._target.tolist()
            f0, f1 = self._f.tolist()
            p0, p1 = self._p.tolist()
            v0, v1 = self._v.tolist()
            lim = self.limits
            w, wy = self._w_t, self._w_y
            vmax, amax = self._vmax, lim.max_accel_mps2
            hw, tw = 0.5 * w, 2.0 * w
            hh = 0.5 * h * h
            for _ in range(n):
                # _accel
                c0, c1 = hw * (f0 - p0), hw * (f1 - p1)
                nc = float(np.hypot(c0, c1))
                if nc > vmax:
                    k = vmax / nc
                    c0, c1 = c0 * k, c1 * k
                a0, a1 = tw * (c0 - v0), tw * (c1 - v1)
                na = float(np.hypot(a0, a1))
                if na > amax:
                    k = amax / na
                    a0, a1 = a0 * k, a1 * k
                r_c = _sat_scalar(0.5 * wy * ssa_scalar(self._f_psi - self._psi), lim.max_yaw_rate_rad_s)
                ar = _sat_scalar(2.0 * wy * (r_c - self._r), lim.max_yaw_accel_rad_s2)
                # the updates
                f0, f1 = f0 + gf_t * (r0 - f0), f1 + gf_t * (r1 - f1)
                self._f_psi = ssa_scalar(self._f_psi + gf_y * ssa_scalar(r2 - self._f_psi))
                p0, p1 = p0 + h * v0 + hh * a0, p1 + h * v1 + hh * a1
                v0, v1 = v0 + h * a0, v1 + h * a1
                self._psi = ssa_scalar(self._psi + h * self._r + 0.5 * h * h * ar)
                self._r = self._r + h * ar
            self._f = np.array([f0, f1])
            self._p = np.array([p0, p1])
            self._v = np.array([v0, v1])
        return self.state

    def packed(self) -> tuple[Array, Array]:
        """(state, constants) as the compiled control step takes them (`_controller_kernel`: RS_*, RP_*)."""
        p, v, f = self._p.tolist(), self._v.tolist(), self._f.tolist()
        lim = self.limits
        rs = np.array([p[0], p[1], v[0], v[1], f[0], f[1], self._psi, self._r, self._f_psi])
        rp = np.array(
            [
                self._w_t,
                self._w_y,
                self._h_max,
                self._vmax,
                lim.max_accel_mps2,
                lim.max_yaw_rate_rad_s,
                lim.max_yaw_accel_rad_s2,
                float(MAX_SUBSTEPS),
            ]
        )
        return rs, rp

    def set_packed(self, rs: Array) -> None:
        """Take the state back from the compiled control step (the inverse of `packed`)."""
        self._p, self._v, self._f = rs[0:2].copy(), rs[2:4].copy(), rs[4:6].copy()
        self._psi, self._r, self._f_psi = float(rs[6]), float(rs[7]), float(rs[8])

    @property
    def target(self) -> Array:
        """The present target r = [N, E, ψ] (a copy)."""
        return self._target.copy()

    @property
    def state(self) -> ReferenceState:
        a, ar = self._accel()
        eta_d = np.array([self._p[0], self._p[1], self._psi])
        eta_dot = np.array([self._v[0], self._v[1], self._r])
        eta_ddot = np.array([a[0], a[1], ar])
        Rt = rotation(self._psi).T
        nu_d = Rt @ eta_dot
        nu_dot = Rt @ eta_ddot + self._r * np.array([nu_d[1], -nu_d[0], 0.0])
        return ReferenceState(eta_d, eta_dot, eta_ddot, nu_d, nu_dot, self._target.copy())
