"""DP controller (gateway/control/controller.py) and reference model (gateway/control/reference.py).

Closed loop: the controller drives `simulator.vessel_dynamics.VesselDynamics` (M ν' + D ν = τ + Jᵀ b) and
is fed the TRUE η, ν (the observer is tested elsewhere). Figures asserted here are quoted in
docs/controller.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from gateway.control.controller import (
    ControllerError,
    ControllerTuning,
    DPController,
    closed_loop_matrix,
    controller_gains,
    froude_defaults,
)
from gateway.control.reference import ReferenceLimits, ReferenceModel
from observers.kinematics import ssa
from observers.vessel import VesselModel, load_vessel
from simulator.vessel_dynamics import VesselDynamics

Array = NDArray[np.float64]
DEG = math.pi / 180


@pytest.fixture(scope="module")
def supply() -> VesselModel:
    return load_vessel("mss_supply")


@pytest.fixture(scope="module")
def cybership() -> VesselModel:
    return load_vessel("cybership2")


def scale(vessel: VesselModel) -> float:
    """Froude length ratio of ``vessel`` to mss_supply (the reference of the defaults)."""
    return vessel.length_m / 76.2


@dataclass
class Run:
    t: Array
    eta: Array
    nu: Array
    tau: Array  # demanded
    applied: Array
    eta_d: Array
    mode: list[str]


Event = tuple[float, Callable[[DPController], None]]


def simulate(
    ctrl: DPController,
    plant: VesselDynamics,
    t_end: float,
    dt: float | Callable[[int], float],
    bias: Callable[[float], Array] | None = None,
    bias_hat: Callable[[float], Array] | None = None,
    clip: Array | None = None,
    antiwindup: str = "back_calculation",
    events: Sequence[Event] = (),
    tau_manual: Array | None = None,
) -> Run:
    """Zero-order-hold loop: at each tick the controller sees the true state, τ is held until the next.

    ``clip``: per-DOF |τ| limit standing in for a saturating allocation. ``antiwindup``: what the harness
    tells the controller — "back_calculation" (saturated + τ_allocated), "conditional" (saturated only)
    or "none" (never saturated).
    """
    pending = sorted(events, key=lambda e: e[0])
    rec: dict[str, list] = {k: [] for k in ("t", "eta", "nu", "tau", "applied", "eta_d", "mode")}
    t, k = 0.0, 0
    saturated, allocated = False, None
    while t <= t_end + 1e-9:
        while pending and pending[0][0] <= t + 1e-9:
            pending.pop(0)[1](ctrl)
        b = np.zeros(3) if bias is None else bias(t)
        kw: dict = {}
        if antiwindup == "back_calculation":
            kw = {"saturated": saturated, "tau_allocated": allocated}
        elif antiwindup == "conditional":
            kw = {"saturated": saturated}
        out = ctrl.update(
            t, plant.eta, plant.nu, None if bias_hat is None else bias_hat(t), tau_manual=tau_manual, **kw
        )
        applied = out.tau if clip is None else np.clip(out.tau, -clip, clip)
        if clip is not None:
            saturated = bool(np.any(np.abs(out.tau) > clip))
            allocated = applied
        for key, value in (
            ("t", t),
            ("eta", plant.eta),
            ("nu", plant.nu),
            ("tau", out.tau),
            ("applied", applied),
            ("eta_d", out.reference.eta_d),
            ("mode", out.mode),
        ):
            rec[key].append(value)
        h = dt(k) if callable(dt) else dt
        plant.step(h, applied, b)
        t += h
        k += 1
    arr = {key: np.array(rec[key], dtype=float) for key in ("t", "eta", "nu", "tau", "applied", "eta_d")}
    return Run(mode=list(rec["mode"]), **arr)


def settling_time(run: Run, target: Array, tol: float, t0: float) -> float:
    """Time after t0 from which the horizontal position stays within ``tol`` of ``target``."""
    dist = np.hypot(run.eta[:, 0] - target[0], run.eta[:, 1] - target[1])
    outside = np.nonzero(dist > tol)[0]
    assert outside.size == 0 or outside[-1] < len(dist) - 1, "never settled"
    return 0.0 if outside.size == 0 else float(run.t[outside[-1] + 1] - t0)


def overshoot(run: Run, start: Array, target: Array) -> float:
    """Largest travel past the target along the start→target direction (m)."""
    d = target[:2] - start[:2]
    u = d / np.linalg.norm(d)
    return float(np.max((run.eta[:, :2] - start[:2]) @ u) - np.linalg.norm(d))


# --------------------------------------------------------------------------------------------- gains
def pole_mismatch(got: NDArray[Any], want: NDArray[np.complex128]) -> float:
    """Largest distance when each wanted pole takes the nearest remaining computed one."""
    left = list(got)
    worst = 0.0
    for w in want:
        j = int(np.argmin([abs(x - w) for x in left]))
        worst = max(worst, abs(left.pop(j) - w))
    return worst


@pytest.mark.parametrize("name", ["mss_supply", "cybership2"])
@pytest.mark.parametrize(
    "tuning",
    [
        {},
        {"damping": 0.7, "integral_ratio": 0.2},
        {"bandwidth_rad_s": (0.7, 1.0, 1.3), "damping": (1.0, 0.8, 0.9)},  # × the default ωn
    ],
    ids=["default", "zeta0.7", "per-dof"],
)
def test_closed_loop_poles_are_where_asked(name: str, tuning: dict) -> None:
    vessel = load_vessel(name)
    if "bandwidth_rad_s" in tuning:
        w0 = froude_defaults(vessel)["bandwidth_rad_s"]
        tuning = {
            **tuning,
            "bandwidth_rad_s": tuple(w * f for w, f in zip(w0, tuning["bandwidth_rad_s"], strict=True)),
        }
    ctrl = DPController(vessel, ControllerTuning(**tuning))
    g = ctrl.gains
    assert not any(g.clipped)
    eig = np.linalg.eigvals(closed_loop_matrix(vessel, g))
    # a critically damped pair is a double eigenvalue: numerically split by ~sqrt(eps)·ω
    assert pole_mismatch(eig, g.design_poles()) < 1e-6 * float(np.max(g.omega_n))
    # and the design is the asked one: pair at ωn, ζ; integral pole at ρ ωn
    tu = ctrl.tuning
    w, z, rho = (np.array(x, dtype=float) for x in (tu.bandwidth_rad_s, tu.damping, tu.integral_ratio))
    for i in range(3):
        c, p, k = g.char_poly[i]
        a = rho[i] * w[i]
        assert np.allclose([c, p, k], [2 * z[i] * w[i] + a, w[i] ** 2 + 2 * z[i] * w[i] * a, w[i] ** 2 * a])
    # M⁻¹Kp, M⁻¹(D + Kd), M⁻¹Ki diagonal: the sway–yaw coupling of M does not move the poles
    Minv = vessel.Minv
    for K in (g.Kp, g.Kd + vessel.D, g.Ki):
        A = Minv @ K
        assert np.allclose(A - np.diag(np.diag(A)), 0.0, atol=1e-12 * np.abs(A).max())


def test_default_poles_figures(supply: VesselModel, cybership: VesselModel) -> None:
    """The numbers quoted in docs/controller.md."""
    ps = DPController(supply).gains.design_poles()
    pc = DPController(cybership).gains.design_poles()
    assert np.allclose(np.sort(ps), np.sort([-0.07] * 4 + [-0.1] * 2 + [-0.007] * 2 + [-0.01]))
    f = math.sqrt(76.2 / 1.255)  # Froude scaling: the model ship is ≈ 7.8× faster
    w = 0.07 * f  # 0.5454 rad/s
    assert np.allclose(np.sort(pc), np.sort([-w] * 4 + [-0.1 * f] * 2 + [-0.1 * w] * 2 + [-0.01 * f]))
    d = froude_defaults(cybership)
    assert d["max_speed_mps"] == pytest.approx(0.5 / math.sqrt(76.2 / 1.255))
    assert d["max_yaw_rate_rad_s"] == pytest.approx(2 * DEG * math.sqrt(76.2 / 1.255))


def test_gains_do_not_depend_on_the_unit_system(supply: VesselModel) -> None:
    """Tonnes instead of kg: gains scale with M, D; the poles (what the user tunes) do not change."""
    tonnes = VesselModel("t", supply.M / 1000, supply.D / 1000, supply.length_m, supply.mass_kg / 1000)
    g_kg, g_t = DPController(supply).gains, DPController(tonnes).gains
    for a, b in ((g_kg.Kp, g_t.Kp), (g_kg.Kd, g_t.Kd), (g_kg.Ki, g_t.Ki)):
        assert np.allclose(a / 1000, b)
    assert np.allclose(
        np.linalg.eigvals(closed_loop_matrix(supply, g_kg)).real.sum(),
        np.linalg.eigvals(closed_loop_matrix(tonnes, g_t)).real.sum(),
    )


def test_kd_clipped_when_the_vessel_is_already_overdamped(supply: VesselModel) -> None:
    g = controller_gains(supply, omega_n=(0.07, 0.07, 0.001), zeta=1.0, integral_ratio=0.0)
    assert g.clipped == (False, False, True)
    assert g.Kd[2, 2] == pytest.approx(0.0, abs=1e-6)
    assert np.all(np.real(np.linalg.eigvals(closed_loop_matrix(supply, g))) <= 1e-12)


def test_bad_tuning_is_refused_with_the_field_named(supply: VesselModel) -> None:
    with pytest.raises(ControllerError, match="bandwidth_rad_s"):
        DPController(supply, ControllerTuning(bandwidth_rad_s=-1.0))
    with pytest.raises(ControllerError, match="damping"):
        DPController(supply, ControllerTuning(damping=(1.0, 1.0)))
    with pytest.raises(ControllerError, match="mode"):
        DPController(supply).set_mode("auto")
    with pytest.raises(ControllerError, match="setpoint"):
        DPController(supply).set_setpoint([1.0, math.nan, 0.0])


# ------------------------------------------------------------------------------------ setpoint steps
STEP_CASES = [
    # vessel, step (m), tuning label, plant mismatch (M factor, D factor), settle bound (s) for 0.2 m·λ
    ("mss_supply", 10.0, "default", (1.0, 1.0), 115.0),
    ("mss_supply", 10.0, "no-feedforward", (1.0, 1.0), 115.0),
    ("mss_supply", 10.0, "default", (1.25, 0.7), 115.0),
    ("mss_supply", 10.0, "no-feedforward", (0.8, 1.5), 115.0),
    ("cybership2", 10.0, "default", (1.0, 1.0), 115.0),  # scaled: 0.165 m step, 0.0165 m overshoot bound
    ("cybership2", 10.0, "no-feedforward", (0.8, 1.5), 115.0),
]


@pytest.mark.parametrize(("name", "step", "label", "mismatch", "settle_s"), STEP_CASES)
def test_setpoint_step(
    name: str, step: float, label: str, mismatch: tuple[float, float], settle_s: float
) -> None:
    """10 m step (Froude-scaled for the model ship) at 30° heading: overshoot ≤ 1 m, settles in time.

    The plant may differ from the controller's model (M, D scaled): the step must still hold.
    """
    vessel = load_vessel(name)
    lam = scale(vessel)
    tuning = ControllerTuning(feedforward=(label == "default"))
    ctrl = DPController(vessel, tuning)
    plant_model = VesselModel("plant", vessel.M * mismatch[0], vessel.D * mismatch[1], vessel.length_m, 1.0)
    psi = 30 * DEG
    plant = VesselDynamics(plant_model, eta0=(0.0, 0.0, psi))
    s = step * lam
    target = np.array([s, 0.0, psi])
    ctrl.set_mode("dp")
    t_step = 1.0
    run = simulate(
        ctrl,
        plant,
        400 * math.sqrt(lam),
        0.1 * math.sqrt(lam),
        events=[(t_step, lambda c: c.set_setpoint(target))],
    )
    assert overshoot(run, np.zeros(3), target) <= 1.0 * lam
    assert settling_time(run, target, 0.2 * lam, t_step) <= settle_s * math.sqrt(lam)
    assert np.max(np.abs(ssa(run.eta[:, 2] - psi))) < 0.1 * DEG
    # still converging on the slow integral pole (−0.1 ωn) when the feed-forward is off
    assert np.hypot(*(run.eta[-1, :2] - target[:2])) < (0.01 if label == "default" else 0.05) * lam


def test_literal_10_m_step_figures(supply: VesselModel) -> None:
    """mss_supply, a literal 10 m step north at heading 0 with jittered control intervals (0.05–0.3 s)."""
    rng = np.random.default_rng(7)
    dts = rng.uniform(0.05, 0.3, 4000)
    ctrl = DPController(supply)
    plant = VesselDynamics(supply)
    ctrl.set_mode("dp")
    target = np.array([10.0, 0.0, 0.0])
    run = simulate(
        ctrl, plant, 300.0, lambda k: float(dts[k]), events=[(1.0, lambda c: c.set_setpoint(target))]
    )
    ov = overshoot(run, np.zeros(3), target)
    ts = settling_time(run, target, 0.2, 1.0)
    assert ov <= 0.01  # the reference model is monotone and the loop tracks it: essentially none
    assert 95.0 <= ts <= 115.0  # ≈ 107 s (third-order reference at ω = 0.07 rad/s)
    assert np.max(np.hypot(run.nu[:, 0], run.nu[:, 1])) <= 0.5  # the reference speed limit


def test_long_step_is_speed_limited(supply: VesselModel) -> None:
    """A 100 m / 50 m step with a 90° turn: speed over ground within 0.5 m/s, no overshoot."""
    ctrl = DPController(supply)
    plant = VesselDynamics(supply)
    ctrl.set_mode("dp")
    target = np.array([100.0, 50.0, 90 * DEG])
    run = simulate(ctrl, plant, 700.0, 0.2, events=[(1.0, lambda c: c.set_setpoint(target))])
    speed = np.hypot(*(np.gradient(run.eta[:, :2], run.t, axis=0).T))
    assert speed.max() <= 0.5 * 1.01
    assert speed.max() >= 0.49
    assert overshoot(run, np.zeros(3), target) <= 0.05
    assert np.hypot(*(run.eta[-1, :2] - target[:2])) < 0.01


# ---------------------------------------------------------------------------- environmental forces
@pytest.mark.parametrize(
    ("bias_feedforward", "bias_hat"),
    [(True, "half"), (False, "true"), (True, "none")],
    ids=["ff-on-biased-estimate", "ff-off", "no-estimate"],
)
def test_constant_environmental_force_is_rejected(
    supply: VesselModel, bias_feedforward: bool, bias_hat: str
) -> None:
    """Current + wind (earth-fixed b of Fossen & Strand (3)): zero steady-state error by integral action."""
    b = np.array([8e4, -5e4, 2e6])
    bias = lambda t: b if t >= 10 else np.zeros(3)  # noqa: E731
    hat = {"half": lambda t: 0.5 * bias(t), "true": bias, "none": None}[bias_hat]
    ctrl = DPController(supply, ControllerTuning(bias_feedforward=bias_feedforward))
    psi = 0.5
    plant = VesselDynamics(supply, eta0=(0.0, 0.0, psi))
    ctrl.set_mode("dp")
    run = simulate(ctrl, plant, 2000.0, 0.25, bias=bias, bias_hat=hat)
    err = run.eta - np.array([0.0, 0.0, psi])
    err[:, 2] = ssa(err[:, 2])
    late = run.t > 1500
    assert np.max(np.abs(err[late, :2])) < 2e-3  # m
    assert np.max(np.abs(err[late, 2])) < 1e-4  # rad
    assert np.max(np.abs(err[:, :2])) < 1.5  # the transient: ≈ 1.27 m peak with no feed-forward


# ------------------------------------------------------------------------------------------- heading
def test_heading_takes_the_short_way(supply: VesselModel) -> None:
    ctrl = DPController(supply)
    plant = VesselDynamics(supply, eta0=(0.0, 0.0, 170 * DEG))
    ctrl.set_mode("dp")
    run = simulate(ctrl, plant, 400.0, 0.2, events=[(1.0, lambda c: c.set_setpoint([0.0, 0.0, -170 * DEG]))])
    turned = ssa(run.eta[:, 2] - 170 * DEG)  # signed angle turned from 170°
    assert turned.min() > -0.01 * DEG  # never turned to port (the long way)
    assert turned.max() <= 20.05 * DEG
    assert abs(ssa(run.eta[-1, 2] + 170 * DEG)) < 0.01 * DEG
    ref_turned = ssa(run.eta_d[:, 2] - 170 * DEG)
    assert np.all(np.diff(ref_turned) >= -1e-12)  # the reference turns monotonically through 180°
    assert run.tau[20, 2] > 0  # yaw moment to starboard


# ------------------------------------------------------------------------------------- anti-windup
def _drift_off(supply: VesselModel, antiwindup: str, governed_return: bool = False) -> tuple[float, float]:
    """τ clipped to 50 kN; a 80 kN beam current for 600 s (drift-off), then 20 kN. Returns
    (largest drift, overshoot past the setpoint on the way back) in m. The governed return is off unless
    asked: it restarts the integrator on the way back and would hide what the anti-windup does."""
    clip = np.array([5e4, 5e4, 3e6])

    def bias(t: float) -> Array:
        if t < 10:
            return np.zeros(3)
        return np.array([0.0, 8e4 if t < 610 else 2e4, 0.0])

    ctrl = DPController(supply, ControllerTuning(governed_return=governed_return))
    plant = VesselDynamics(supply)
    ctrl.set_mode("dp")
    run = simulate(ctrl, plant, 3000.0, 0.2, bias=bias, clip=clip, antiwindup=antiwindup)
    back = run.t > 610
    if antiwindup != "none":
        assert np.hypot(*run.eta[-1, :2]) < 0.01  # back on station
    return float(run.eta[:, 1].max()), float(-run.eta[back, 1].min())


def test_anti_windup(supply: VesselModel) -> None:
    drift_bc, over_bc = _drift_off(supply, "back_calculation")
    drift_ci, over_ci = _drift_off(supply, "conditional")
    drift_no, over_no = _drift_off(supply, "none")
    assert min(drift_bc, drift_ci, drift_no) > 40  # the vessel really was driven off (≈ 54–59 m)
    assert over_bc <= 0.05  # measured ≈ 0.0 m
    assert over_ci <= 0.3  # measured ≈ 0.07 m
    assert over_no > 30  # measured ≈ 71 m: the wound-up integrator throws the vessel past the setpoint
    assert max(over_bc, over_ci) < over_no / 100
    # with the governed return (the default), even without anti-windup the restart of the reference and
    # the integrator at the vessel keeps the return from throwing it past the setpoint (the restart waits
    # for the vessel to close at a tenth of the return speed, so some of the wound-up push is spent first)
    _, over_gov = _drift_off(supply, "none", governed_return=True)
    assert over_gov < 15  # measured 10.5 m (71 m without the governed return)


# ---------------------------------------------------------------------------------------- modes
def test_standby_outputs_zero_and_follows_the_estimate(supply: VesselModel) -> None:
    ctrl = DPController(supply)
    assert ctrl.mode == "standby"
    out = ctrl.update(0.0, [5.0, 6.0, 1.0], [0.1, 0.0, 0.0], [1e5, 0.0, 0.0], tau_manual=[1e5, 0.0, 0.0])
    assert np.array_equal(out.tau, np.zeros(3))
    assert np.array_equal(out.integral, np.zeros(3))
    assert np.allclose(out.reference.eta_d, [5.0, 6.0, 1.0])
    assert np.allclose(out.reference.nu_d, [0.1, 0.0, 0.0])


def test_manual_holds_the_last_tau(supply: VesselModel) -> None:
    ctrl = DPController(supply)
    ctrl.set_mode("manual")
    assert np.array_equal(ctrl.update(0.0, np.zeros(3), np.zeros(3)).tau, np.zeros(3))
    assert np.array_equal(
        ctrl.update(0.1, np.zeros(3), np.zeros(3), tau_manual=[1.0, 2.0, 3.0]).tau, [1, 2, 3]
    )
    assert np.array_equal(ctrl.update(0.2, np.zeros(3), np.zeros(3)).tau, [1, 2, 3])
    assert np.array_equal(
        ctrl.update(0.3, np.zeros(3), np.zeros(3), tau_manual=[math.nan, 0, 0]).tau, [1, 2, 3]
    )


@pytest.mark.parametrize("start", ["manual", "standby"])
def test_bumpless_transfer_into_dp(supply: VesselModel, start: str) -> None:
    """Under current, drifting (standby) or pushed by the joystick (manual); dp engaged at t = 100 s."""
    b = np.array([6e4, -4e4, 1e6])
    tau_manual = np.array([-5e4, 3e4, -5e5]) if start == "manual" else None
    ctrl = DPController(supply)
    plant = VesselDynamics(supply, eta0=(0.0, 0.0, 1.0))
    ctrl.set_mode(start)
    dt = 0.1
    run = simulate(
        ctrl,
        plant,
        600.0,
        dt,
        bias=lambda t: b,
        bias_hat=lambda t: b,
        events=[(100.0, lambda c: c.set_mode("dp"))],
        tau_manual=tau_manual,
    )
    i = round(100.0 / dt)
    assert run.mode[i - 1] == start and run.mode[i] == "dp"
    before = run.tau[i - 1]
    assert np.allclose(run.tau[i], before, rtol=0, atol=1e-6 * (1 + np.abs(before).max()))
    # afterwards τ changes smoothly: per 0.1 s at most 8 kN, 6 kN, 35 kN·m (measured from manual 5.8 kN,
    # 2.8 kN, 17.5 kN·m, from standby 0.7 kN, 3.6 kN, 29.8 kN·m: the takeover fade bringing in the load
    # and the reference's braking moment that the bumpless start had cancelled, along a smoothstep that
    # peaks 4 s in), against a 50 kN jump in X for a transfer that starts the integrator at zero
    steps = np.abs(np.diff(run.tau[i - 1 :], axis=0)).max(axis=0)
    assert np.all(steps <= [8e3, 6e3, 3.5e4]), steps
    # it holds the position where dp was engaged
    assert np.hypot(*(run.eta[-1, :2] - run.eta[i, :2])) < 1.0
    before_dp = np.zeros(3) if tau_manual is None else tau_manual
    assert np.all(run.tau[: i - 1] == before_dp)


def test_dp_entered_with_nobody_holding_takes_up_the_known_load(supply: VesselModel) -> None:
    """A manual τ the dead-man expired (τ = 0) with a 100 kN current the observer knows: the bumpless
    first τ is 0, and the integrator's start content (+Jᵀb̂, which cancels the bias feed-forward) fades out
    over ``takeover_fade_s`` (1/ωn = 14.3 s), so τ reaches the known load within it and the vessel
    stops near where DP was engaged. Left to the closed loop (``takeover_fade_s`` = inf: the rule before), the
    integrator unwinds at its pole a (143 s) and the vessel drifts off metres (a HIL bench saw 6-7 m)."""
    b = np.array([1e5, 3e4, 2e5])  # earth-frame current load, known to the observer (b̂ = b)
    dt = 0.1
    runs = {}
    for name, fade in (("fade", None), ("unwind", math.inf)):
        ctrl = DPController(supply, ControllerTuning(takeover_fade_s=fade))
        plant = VesselDynamics(supply, eta0=(0.0, 0.0, 0.3))
        ctrl.set_mode("manual")  # a τ that has expired: 0
        runs[name] = simulate(
            ctrl,
            plant,
            400.0,
            dt,
            bias=lambda t: b,
            bias_hat=lambda t: b,
            events=[(20.0, lambda c: c.set_mode("dp"))],
            tau_manual=np.zeros(3),
        )
    assert DPController(supply).tuning.takeover_fade_s == pytest.approx(1 / 0.07, rel=1e-3)
    i = round(20.0 / dt)
    fade_run = runs["fade"]
    for run in runs.values():
        assert np.allclose(run.tau[i], 0.0, atol=1.0)  # bumpless either way: the first τ is the τ before
    off = {k: np.hypot(*(r.eta[i:, :2] - r.eta[i, :2]).T).max() for k, r in runs.items()}
    # the vessel drifted 2.9 m in the 20 s before DP and is moving: measured 3.2 m further with the fade
    # (at its widest 17 s after engaging), 7.9 m unwinding (51 s after)
    assert off["fade"] < 4.0 and off["unwind"] > 2.0 * off["fade"], off
    # within 1.5 T_x of engaging, the surge/sway τ holds at least 80 % of the known load
    known = np.hypot(*b[:2])
    assert np.hypot(*fade_run.tau[i + 215, :2]) > 0.8 * known, fade_run.tau[i + 215]
    # and it ends on its station, where the unwinding is still 0.9 m off at 400 s
    assert np.hypot(*(fade_run.eta[-1, :2] - fade_run.eta[i, :2])) < 0.2
    # ... with no step on the way: per 0.1 s at most 5 % of the load (measured 3.4 %; a fade of 0 s
    # steps by 330 %)
    steps = np.hypot(*np.diff(fade_run.tau[i - 1 :, :2], axis=0).T)
    assert steps.max() < 0.05 * known


def test_takeover_fade_tuning_is_checked(supply: VesselModel) -> None:
    assert DPController(supply, ControllerTuning(takeover_fade_s=0)).tuning.takeover_fade_s == 0.0
    for bad in (-1.0, math.nan, "fast", True):
        with pytest.raises(ControllerError, match="takeover_fade_s"):
            DPController(supply, ControllerTuning(takeover_fade_s=bad))  # type: ignore[arg-type]


def test_setpoint_given_before_dp_becomes_the_target(supply: VesselModel) -> None:
    ctrl = DPController(supply)
    ctrl.update(0.0, np.zeros(3), np.zeros(3))
    ctrl.set_setpoint([3.0, 0.0, 0.0])
    ctrl.set_mode("dp")
    out = ctrl.update(0.1, np.zeros(3), np.zeros(3))
    assert np.allclose(out.reference.target, [3.0, 0.0, 0.0])
    ctrl.set_mode("standby")
    ctrl.set_mode("dp")  # left dp without a new setpoint: hold the present position
    out = ctrl.update(0.2, [1.0, 1.0, 0.0], np.zeros(3))
    assert np.allclose(out.reference.target, [1.0, 1.0, 0.0])


def test_no_estimate_holds_tau(supply: VesselModel) -> None:
    ctrl = DPController(supply)
    ctrl.set_mode("dp")
    ctrl.update(0.0, np.zeros(3), np.zeros(3))
    out1 = ctrl.update(0.1, [0.5, 0.0, 0.0], np.zeros(3))
    out2 = ctrl.update(0.2, [math.nan] * 3, np.zeros(3))
    assert not out2.valid and np.array_equal(out2.tau, out1.tau)
    assert np.array_equal(out2.integral, out1.integral)
    out3 = ctrl.update(0.1, [0.5, 0.0, 0.0], np.zeros(3))  # time going backwards: no integration
    assert np.array_equal(out3.integral, out1.integral)


def test_deterministic(supply: VesselModel) -> None:
    runs = []
    for _ in range(2):
        ctrl = DPController(supply)
        ctrl.set_mode("dp")
        plant = VesselDynamics(supply)
        runs.append(
            simulate(ctrl, plant, 60.0, 0.1, events=[(1.0, lambda c: c.set_setpoint([5.0, 5.0, 0.3]))])
        )
    assert np.array_equal(runs[0].tau, runs[1].tau)


# ----------------------------------------------------------------------------------- reference model
@pytest.mark.parametrize("name", ["mss_supply", "cybership2"])
def test_reference_respects_its_limits(name: str) -> None:
    vessel = load_vessel(name)
    d = froude_defaults(vessel)
    limits = ReferenceLimits(
        d["max_speed_mps"], d["max_accel_mps2"], d["max_yaw_rate_rad_s"], d["max_yaw_accel_rad_s2"]
    )
    w = d["bandwidth_rad_s"]
    ref = ReferenceModel((min(w[0], w[1]), w[2]), limits)  # (translation, yaw), as the controller builds it
    lam = scale(vessel)
    rng = np.random.default_rng(3)
    ref.reset([0.0, 0.0, 0.0])
    targets = [[100 * lam, 60 * lam, 120 * DEG], [-40 * lam, 10 * lam, -100 * DEG], [0.0, 0.0, 179 * DEG]]
    prev = ref.state
    for target in targets:
        ref.set_target(target)
        for _ in range(3000):
            h = float(rng.uniform(0.02, 0.5)) * math.sqrt(lam)
            s = ref.step(h)
            eps = 1 + 1e-9
            assert np.hypot(*s.eta_dot_d[:2]) <= limits.max_speed_mps * eps
            assert np.hypot(*s.eta_ddot_d[:2]) <= limits.max_accel_mps2 * eps
            assert abs(s.eta_dot_d[2]) <= limits.max_yaw_rate_rad_s * eps
            assert abs(s.eta_ddot_d[2]) <= limits.max_yaw_accel_rad_s2 * eps
            moved = np.hypot(*(s.eta_d[:2] - prev.eta_d[:2]))
            assert moved <= limits.max_speed_mps * h * eps
            assert abs(ssa(s.eta_d[2] - prev.eta_d[2])) <= limits.max_yaw_rate_rad_s * h * eps
            assert -math.pi <= s.eta_d[2] < math.pi
            prev = s
        assert np.allclose(s.eta_d[:2], target[:2], atol=1e-3 * lam)
        assert abs(ssa(s.eta_d[2] - target[2])) < 1e-4


def test_reference_started_too_fast_slows_down_within_the_limit(supply: VesselModel) -> None:
    d = froude_defaults(supply)
    limits = ReferenceLimits(
        d["max_speed_mps"], d["max_accel_mps2"], d["max_yaw_rate_rad_s"], d["max_yaw_accel_rad_s2"]
    )
    ref = ReferenceModel(0.07, limits)
    ref.reset([0.0, 0.0, 0.0], eta_dot=[2.0, 0.0, 0.0], target=[0.0, 0.0, 0.0])
    speeds = [np.hypot(*ref.step(0.1).eta_dot_d[:2]) for _ in range(600)]
    assert np.all(np.diff(speeds[:300]) <= 1e-12)  # monotone braking at ≤ a_max
    assert np.diff(speeds[:10]).min() >= -0.05 * 0.1 * (1 + 1e-9)
    assert max(speeds[300:]) <= 0.5


def test_reference_body_frame_quantities() -> None:
    """ν_d = Jᵀ(ψ_d) η_d', and ν̇_d matches the finite difference of ν_d during a combined move."""
    limits = ReferenceLimits(0.5, 0.05, 2 * DEG, 0.2 * DEG)
    ref = ReferenceModel(0.07, limits)
    ref.reset([0.0, 0.0, 0.0])
    ref.set_target([30.0, 20.0, 60 * DEG])
    h = 0.05
    s0 = ref.step(60.0)
    s1 = ref.step(h)
    s2 = ref.step(h)
    assert abs(s1.eta_dot_d[2]) > 0.5 * DEG and np.hypot(*s1.eta_dot_d[:2]) > 0.1  # turning while moving
    c, s = math.cos(s1.eta_d[2]), math.sin(s1.eta_d[2])
    ed = s1.eta_dot_d
    assert np.allclose(s1.nu_d, [c * ed[0] + s * ed[1], -s * ed[0] + c * ed[1], ed[2]])
    central = (s2.nu_d - s0.nu_d) / (2 * h)
    assert np.allclose(central, s1.nu_dot_d, rtol=0, atol=5e-5)  # the turn term r_d·[v, −u] is ≈ 4e-3


# ------------------------------------------------------------------------------------ governed return
def test_reference_restart_keeps_the_target_and_returns_within_the_lower_speed(supply: VesselModel) -> None:
    """`ReferenceModel.restart` moves the trajectory (not the target) to a vessel 100 m off and moving away
    at 0.4 m/s: the reference brakes that at ≤ a_max, comes back at ≤ the lowered speed limit, ends on the
    target without overshoot; a new, different target restores the reference's own limit."""
    d = froude_defaults(supply)
    limits = ReferenceLimits(
        d["max_speed_mps"], d["max_accel_mps2"], d["max_yaw_rate_rad_s"], d["max_yaw_accel_rad_s2"]
    )
    ref = ReferenceModel(0.07, limits)
    ref.reset([0.0, 0.0, 0.5])
    ref.restart([60.0, 80.0, 0.5], [0.24, 0.32, 0.0], yaw=False, max_speed_mps=0.3)
    assert ref.speed_limit == 0.3
    assert np.array_equal(ref.target, [0.0, 0.0, 0.5])
    states = [ref.step(0.1) for _ in range(9000)]
    eta = np.array([s.eta_d for s in states])
    speed = np.hypot(*np.array([s.eta_dot_d[:2] for s in states]).T)
    accel = np.hypot(*np.array([s.eta_ddot_d[:2] for s in states]).T)
    assert speed[speed.argmin() :].max() <= 0.3 + 1e-12  # after braking: within the return speed
    assert speed.max() <= 0.4 + 1e-12 and accel.max() <= 0.05 + 1e-12
    along = eta[:, :2] @ np.array([0.6, 0.8])  # distance along the line from the target to the vessel
    assert along.min() >= -1e-6 and np.hypot(*eta[-1, :2]) < 1e-3  # on the target, no overshoot
    ref.set_target([0.0, 0.0, 0.5])  # the same target again: still the return's limit
    assert ref.speed_limit == 0.3
    ref.set_target([10.0, 0.0, 0.5])
    assert ref.speed_limit == d["max_speed_mps"]


@pytest.mark.parametrize("compiled", [True, False])
def test_far_off_vessel_coming_back_restarts_the_reference_not_the_station(
    supply: VesselModel, compiled: bool
) -> None:
    """A vessel beyond the return radius (e·v_ret/ωn = 19.4 m for mss_supply at 0.5 m/s, 0.07 rad/s) and
    closing on its reference gets the reference's trajectory restarted at its position and velocity, the
    return speed as the limit, the integrator of the restarted DOFs at zero; the station stays. Moving away
    (a drift-off), or inside the radius, nothing is restarted."""
    ctl = DPController(supply, ControllerTuning(return_speed_mps=0.3), compiled=compiled)
    assert ctl.return_radius_m == pytest.approx(math.e * 0.3 / 0.07)
    station = np.array([0.0, 0.0, 0.3])
    ctl.set_setpoint(station)
    ctl.set_mode("dp")
    zero = np.zeros(3)
    ctl.update(0.0, station, zero, zero)
    away = np.array([0.0, 0.4, 0.0])  # body: at ψ = 0.3 rad, mostly east, i.e. away from the station
    for k in range(1, 50):  # drifting off, 4 m → 24 m east: no restart, the integrator winds
        ctl.update(0.1 * k, [0.0, 4.0 + 0.4 * k, 0.3], away, zero)
    assert ctl.returns == 0 and ctl.integral[1] > 20  # wound: η̃ up to 24 m for 5 s
    o = ctl.update(5.0, [0.0, 24.0, 0.3], -away, zero)  # coming back
    assert ctl.returns == 1 and ctl.last_return is not None
    assert ctl.last_return.startswith("returning to station: 24.0 m off at ≤ 0.30 m/s")
    assert np.allclose(o.reference.target, station, atol=1e-15, rtol=1e-15)  # the station stays
    assert np.allclose(ctl.reference.target, station, atol=1e-15, rtol=1e-15)
    assert ctl.reference.speed_limit == 0.3
    assert np.hypot(o.eta_error[0], o.eta_error[1]) < 0.05  # restarted at the vessel, then 0.1 s at 0.4 m/s
    assert np.abs(o.integral[:2]).max() < 0.005  # restarted at 0, then one step of η̃·dt (was > 20 m·s)
    n = ctl.returns
    for k in range(51, 60):  # following the restarted reference: no further restart
        ctl.update(0.1 * k, [0.0, 24.0 - 0.05 * (k - 50), 0.3], -0.5 * away, zero)
    assert ctl.returns == n
    near = DPController(supply, compiled=compiled)  # 15 m off (inside 19.4 m), coming back: the feedback
    near.set_setpoint(station)
    near.set_mode("dp")
    near.update(0.0, station, zero, zero)
    near.update(0.1, [0.0, 15.0, 0.3], -away, zero)
    assert near.returns == 0


@pytest.mark.parametrize("compiled", [True, False])
def test_a_vessel_held_far_off_is_not_restarted_and_a_return_ends_at_the_station(
    supply: VesselModel, compiled: bool
) -> None:
    """Held where it is 30 m off (a load at the edge of capability: no closing speed), the vessel keeps the
    full error and its integrator: a restart would zero the integral that holds it. Closing at 0.2 m/s
    it restarts; `returning` stays set until the reference is home, and a new setpoint ends it."""
    ctl = DPController(supply, compiled=compiled)
    station = np.array([0.0, 0.0, 0.0])
    ctl.set_setpoint(station)
    ctl.set_mode("dp")
    zero = np.zeros(3)
    ctl.update(0.0, station, zero, zero)
    for k in range(1, 300):  # 30 s held 30 m north, still
        ctl.update(0.1 * k, [30.0, 0.0, 0.0], zero, zero)
    assert ctl.returns == 0 and not ctl.returning and ctl.integral[0] > 0.0
    creep = np.array([-0.02, 0.0, 0.0])  # closing at 0.02 m/s: under a tenth of the return speed
    ctl.update(30.0, [30.0, 0.0, 0.0], creep, zero)
    assert ctl.returns == 0
    ctl.update(30.1, [30.0, 0.0, 0.0], 10 * creep, zero)  # closing at 0.2 m/s
    assert ctl.returns == 1 and ctl.returning
    t, k = 30.2, 0
    while ctl.returning and k < 20000:  # the vessel on its reference, walked home
        ref = ctl.reference.state
        ctl.update(t, ref.eta_d, ref.nu_d, zero)
        t, k = t + 0.1, k + 1
    assert not ctl.returning and np.hypot(*ctl.reference.state.eta_d[:2]) <= 0.05 * ctl.return_radius_m
    ctl.update(t, [30.0, 0.0, 0.0], 10 * creep, zero)  # far off again, closing: a second return
    assert ctl.returns == 2 and ctl.returning
    ctl.set_setpoint([5.0, 0.0, 0.0])  # the operator's own move: no longer a return
    assert not ctl.returning


def test_return_speed_above_the_reference_limit_is_refused(supply: VesselModel) -> None:
    with pytest.raises(ControllerError, match=r"return_speed_mps.*at most"):
        DPController(supply, ControllerTuning(return_speed_mps=0.6))
    with pytest.raises(ControllerError, match="return_speed_mps"):
        DPController(supply, ControllerTuning(return_speed_mps=0.0))
    assert DPController(supply).return_speed_mps == froude_defaults(supply)["max_speed_mps"]


def test_compiled_and_readable_agree_through_a_governed_return(supply: VesselModel) -> None:
    """The compiled step takes the reference's constants per step (`ReferenceModel.packed`): through a
    governed return, whose restart lowers the speed limit to the return speed, both steps give the same τ
    and the same reference, which walks back at ≤ the return speed."""
    ctls = [DPController(supply, ControllerTuning(return_speed_mps=0.2), compiled=c) for c in (True, False)]
    station, zero = np.zeros(3), np.zeros(3)
    outs: list[list[Any]] = [[], []]
    for ctl, out in zip(ctls, outs, strict=True):
        ctl.set_setpoint(station)
        ctl.set_mode("dp")
        ctl.update(0.0, station, zero, zero)
        ctl.update(0.1, [40.0, 0.0, 0.0], [-0.3, 0.0, 0.0], zero)  # 40 m off, closing: a return
        assert ctl.returns == 1
        for k in range(2, 1500):  # the vessel 2 m behind its reference, on its way home
            ref = ctl.reference.state
            out.append(ctl.update(0.1 * k, ref.eta_d + np.array([2.0, 0.0, 0.0]), ref.nu_d, zero))
    for a, b in zip(*outs, strict=True):
        np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=1e-9 * (1.0 + np.abs(b.tau).max()))
        np.testing.assert_allclose(a.reference.eta_d, b.reference.eta_d, rtol=0, atol=1e-9)
    speed = np.array([np.hypot(*o.reference.eta_dot_d[:2]) for o in outs[0]])
    # restarted at the vessel's 0.3 m/s, slowed (first order, 1/(2ω) = 7 s) to the return speed, held there
    assert speed[0] > 0.28 and np.all(np.diff(speed) <= 1e-12)
    assert abs(speed[-300:] - 0.2).max() < 1e-6
