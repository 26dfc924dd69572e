"""Thrust allocation: gateway/control/allocation.py.

The constrained QP (DAQP) is checked against the thrusters' physical limits directly, against the
unconstrained weighted pseudo-inverse where no limit is active, and against an independent cvxpy
formulation of the same problem (fixed frame of Hajivand eq (22), solved by Clarabel) on seeded random
demands and previous states for mss_supply, hajivand_vessel, cybership2 and a vessel with main propellers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gateway.control.allocation import (
    PseudoInverseAllocator,
    QPAllocator,
    ThrusterCommand,
    extended_configuration_matrix,
    reference_solve_cvxpy,
)
from observers.kinematics import ssa
from observers.vessel import Thruster, VesselModel, load_vessel

VESSELS = ["mss_supply", "hajivand_vessel", "cybership2"]
ANGLE_TOL = 1e-9


def mains_vessel() -> VesselModel:
    """Two non-reversing main propellers, a bow tunnel and a bow azimuth (covers kind "main")."""
    base = load_vessel("mss_supply")
    return VesselModel(
        name="mains",
        M=base.M,
        D=base.D,
        length_m=base.length_m,
        mass_kg=base.mass_kg,
        thrusters=(
            Thruster(1, "main", -35.0, -6.0, 5.0e5, 0.0, thrust_time_constant_s=3.0),
            Thruster(2, "main", -35.0, 6.0, 5.0e5, 0.0, thrust_time_constant_s=3.0),
            Thruster(
                3, "tunnel", 30.0, 0.0, 1.5e5, -1.5e5, thrust_time_constant_s=1.0, angle_rad=math.pi / 2
            ),
            Thruster(4, "azimuth", 20.0, 0.0, 2.0e5, 0.0, azimuth_rate_rad_s=0.2, thrust_time_constant_s=1.5),
        ),
    )


def get_vessel(name: str) -> VesselModel:
    return mains_vessel() if name == "mains" else load_vessel(name)


def azimuth_ids(vessel: VesselModel) -> list[int]:
    return [t.id for t in vessel.thrusters if t.kind == "azimuth"]


def sectors_for(vessel: VesselModel) -> dict[int, list[tuple[float, float]]]:
    """A forbidden sector on the first azimuth (through ±180°) and on the last (around the bow)."""
    ids = azimuth_ids(vessel)
    out = {ids[0]: [(2.6, -2.7)]}
    if len(ids) > 1:
        out[ids[-1]] = [(-0.4, 0.25)]
    return out


def in_sector(angle: float, start: float, end: float) -> bool:
    """Strictly inside the sector from start clockwise to end."""
    width = (end - start) % (2 * math.pi)
    p = (angle - start) % (2 * math.pi)
    return ANGLE_TOL < p < width - ANGLE_TOL


def random_state(
    vessel: VesselModel,
    rng: np.random.Generator,
    sectors: dict[int, list[tuple[float, float]]] | None = None,
    fraction: float = 1.0,
) -> ThrusterCommand:
    """Random thrusts up to ``fraction`` of the maximum; azimuths outside ``sectors``."""
    thrust, azimuth = [], []
    for t in vessel.thrusters:
        if t.kind == "azimuth":
            thrust.append(rng.uniform(0.0, fraction * t.max_thrust_n))
            while True:
                a = rng.uniform(-math.pi, math.pi)
                if not any(in_sector(a, s, e) for s, e in (sectors or {}).get(t.id, [])):
                    break
            azimuth.append(a)
        else:
            thrust.append(rng.uniform(min(t.min_thrust_n, 0.0), t.max_thrust_n))
            azimuth.append(t.angle_rad)
    return ThrusterCommand(np.array(thrust), np.array(azimuth))


def reachable_state(
    allocator: QPAllocator,
    prev: ThrusterCommand,
    rng: np.random.Generator,
    sectors: dict[int, list[tuple[float, float]]] | None = None,
) -> ThrusterCommand:
    """A command the thrusters can reach from ``prev`` in one step (from the raw thruster data, not from
    the allocator's own limits): within 90 % of each rate limit, below the inscribed polygon, and an
    azimuth path that does not cross a forbidden sector."""
    thrust, azimuth = prev.thrust.copy(), prev.azimuth.copy()
    cos_n = math.cos(math.pi / allocator.polygon_sides)
    for i, t in enumerate(allocator.layout.vessel.thrusters):
        dT = 0.9 * t.max_thrust_n / t.thrust_time_constant_s * allocator.dt
        if t.kind == "azimuth":
            lo, hi = max(0.0, prev.thrust[i] - dT), min(prev.thrust[i] + dT, 0.97 * cos_n * t.max_thrust_n)
            assert lo <= hi, "previous thrust too close to the maximum for this generator"
            thrust[i] = rng.uniform(lo, hi)
            turn = min(0.9 * t.azimuth_rate_rad_s * allocator.dt, 1.2)
            while True:
                step = rng.uniform(-turn, turn)
                path = prev.azimuth[i] + np.linspace(0.0, step, 50)
                bad = [(s, e) for s, e in (sectors or {}).get(t.id, [])]
                if not any(in_sector(float(a), s, e) for a in path for s, e in bad):
                    break
            azimuth[i] = float(ssa(prev.azimuth[i] + step))
        else:
            lo, hi = min(t.min_thrust_n, 0.0), t.max_thrust_n
            thrust[i] = np.clip(prev.thrust[i] + rng.uniform(-dT, dT), lo, hi)
    return ThrusterCommand(thrust, azimuth)


def check_limits(
    allocator: QPAllocator,
    prev: ThrusterCommand,
    res_thrust: np.ndarray,
    res_azimuth: np.ndarray,
    sectors: dict[int, list[tuple[float, float]]] | None = None,
) -> None:
    """Every limit, from the raw thruster data: thrust range, thrust rate, azimuth rate, sectors."""
    assert np.all(np.isfinite(res_thrust)) and np.all(np.isfinite(res_azimuth))
    assert np.all(res_azimuth >= -math.pi) and np.all(res_azimuth < math.pi)
    for i, t in enumerate(allocator.layout.vessel.thrusters):
        T, a = res_thrust[i], res_azimuth[i]
        dT = t.max_thrust_n / t.thrust_time_constant_s * allocator.dt
        assert t.max_thrust_n * (1 + 1e-12) >= T, (t.id, T)
        assert abs(T - prev.thrust[i]) <= dT * (1 + 1e-9) + 1e-9 * t.max_thrust_n, (t.id, T, prev.thrust[i])
        if t.kind == "azimuth":
            assert T >= 0.0
            assert abs(ssa(a - prev.azimuth[i])) <= t.azimuth_rate_rad_s * allocator.dt + ANGLE_TOL
            if T > 0.0:
                for s, e in (sectors or {}).get(t.id, []):
                    assert not in_sector(a, s, e), (t.id, a, s, e)
        else:
            assert min(t.min_thrust_n, 0.0) - 1e-9 * t.max_thrust_n <= T
            assert a == pytest.approx(ssa(t.angle_rad))


# ---- the extended configuration (Hajivand eq (22), signs restored) ---------------------------------------


@pytest.mark.parametrize("name", [*VESSELS, "mains"])
def test_extended_matrix_matches_vessel_configuration(name: str) -> None:
    vessel = get_vessel(name)
    B = extended_configuration_matrix(vessel)
    rng = np.random.default_rng(0)
    cmd = random_state(vessel, rng)
    f = []
    for t, T, a in zip(vessel.thrusters, cmd.thrust, cmd.azimuth, strict=True):
        f += [T * math.cos(a), T * math.sin(a)] if t.kind == "azimuth" else [T]
    np.testing.assert_allclose(B @ np.array(f), vessel.generalized_force(cmd.thrust, cmd.azimuth), rtol=1e-12)


def test_extended_matrix_has_the_signs_the_printed_22_lost() -> None:
    """Azimuth at (x, y): F_x contributes yaw −y·F_x, F_y contributes x·F_y (eq (22), signs restored)."""
    vessel = load_vessel("hajivand_vessel")
    B = extended_configuration_matrix(vessel)
    for j, t in enumerate(vessel.thrusters):
        np.testing.assert_array_equal(B[:, 2 * j], [1.0, 0.0, -t.y_m])
        np.testing.assert_array_equal(B[:, 2 * j + 1], [0.0, 1.0, t.x_m])


# ---- pseudo-inverse baseline ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", [*VESSELS, "mains"])
def test_pseudo_inverse_meets_feasible_demand_and_scales_infeasible(name: str) -> None:
    vessel = get_vessel(name)
    pinv = PseudoInverseAllocator(vessel)
    tau_ref = pinv.layout.tau_ref
    tau = np.array([0.05, -0.03, 0.02]) * tau_ref
    r = pinv.allocate(tau)
    if name != "mains":  # the mains cannot reverse: the baseline clips them and cannot meet every τ
        assert not r.saturated and r.status == "optimal" and r.alarms == ()
        np.testing.assert_allclose(r.tau_allocated, tau, rtol=1e-9, atol=1e-9 * np.max(tau_ref))
    for demand in ([1.0, 0.4, 0.1], [-1.0, -0.4, 0.1]):
        big = pinv.allocate(10 * np.array(demand) * tau_ref)
        assert big.saturated and big.status == "scaled" and big.alarms
        assert np.all(big.thrust <= pinv.layout.tmax * (1 + 1e-12))
        assert np.all(big.thrust >= pinv.layout.tmin * (1 + 1e-12))  # mains do not reverse
        assert np.all(np.isfinite(big.thrust)) and np.all(np.isfinite(big.azimuth))
        np.testing.assert_allclose(
            big.tau_allocated, vessel.generalized_force(big.thrust, big.azimuth), rtol=1e-12
        )


def test_pseudo_inverse_agrees_with_qp_when_no_constraint_is_active() -> None:
    for name in VESSELS:
        vessel = load_vessel(name)
        # without thrust biasing: the bias floor (each azimuth ≥ β·T_max) is by design not the unconstrained
        # optimum; the turn cost still has zero gradient at the previous direction, so it does not move it
        pinv, qp = PseudoInverseAllocator(vessel), QPAllocator(vessel, bias_fraction=0.0)
        rng = np.random.default_rng(3)
        L = qp.layout
        for _ in range(40):
            tau = rng.normal(size=3) * 0.1 * L.tau_ref
            p = pinv.allocate(tau)
            assert not p.saturated
            # the thrusters already deliver p: no rate limit binds, every thrust is below its maximum
            q = qp.allocate(tau, p.command)
            assert not q.saturated and q.status == "optimal"
            np.testing.assert_allclose(q.thrust, p.thrust, rtol=0, atol=1e-9 * L.cap.max())
            np.testing.assert_allclose(ssa(q.azimuth - p.azimuth), 0.0, atol=1e-9)
            np.testing.assert_allclose(q.tau_allocated, tau, rtol=0, atol=1e-9 * float(np.linalg.norm(tau)))


# ---- constrained QP: feasible demands, limits ----------------------------------------------------------


@pytest.mark.parametrize("name", [*VESSELS, "mains"])
@pytest.mark.parametrize("with_sectors", [False, True])
def test_feasible_demand_met_exactly_and_every_limit_holds(name: str, with_sectors: bool) -> None:
    vessel = get_vessel(name)
    sectors = sectors_for(vessel) if with_sectors else None
    rng = np.random.default_rng(11)
    for dt in (0.1, 1.0, 5.0):
        qp = QPAllocator(vessel, dt=dt, forbidden_sectors=sectors, bias_fraction=0.0)
        for _ in range(15):
            prev = random_state(vessel, rng, sectors, fraction=0.9)
            target = reachable_state(qp, prev, rng, sectors)
            tau = vessel.generalized_force(target.thrust, target.azimuth)  # feasible by construction
            r = qp.allocate(tau, prev)
            assert r.status == "optimal" and not r.saturated and r.alarms == ()
            assert np.linalg.norm(r.tau_allocated - tau) <= 1e-6 * np.linalg.norm(tau)
            np.testing.assert_allclose(r.slack, tau - r.tau_allocated)
            np.testing.assert_allclose(
                r.tau_allocated, vessel.generalized_force(r.thrust, r.azimuth), rtol=1e-12, atol=1e-6
            )
            check_limits(qp, prev, r.thrust, r.azimuth, sectors)


@pytest.mark.parametrize("name", VESSELS)
def test_limits_hold_for_any_demand(name: str) -> None:
    """Random demands up to 3× capacity from random states: limits always hold, never NaN."""
    vessel = load_vessel(name)
    sectors = sectors_for(vessel)
    rng = np.random.default_rng(5)
    qp = QPAllocator(vessel, forbidden_sectors=sectors)
    for _ in range(60):
        prev = random_state(vessel, rng, sectors)
        tau = rng.normal(size=3) * qp.layout.tau_ref * rng.choice([0.01, 0.3, 3.0])
        r = qp.allocate(tau, prev)
        assert r.status == "optimal"
        check_limits(qp, prev, r.thrust, r.azimuth, sectors)
        # an alarm exactly when saturated, but for a demand the thrusters can give that one step's rate
        # limits did not reach (`test_a_ramp_to_a_reachable_demand_is_no_alarm_for_as_long_as_a_ramp_takes`)
        assert r.saturated == bool(r.alarms) or (r.saturated and not r.alarms and qp.reachable(tau))


def test_previous_azimuth_inside_forbidden_sector_gives_no_thrust_and_turns_out() -> None:
    vessel = load_vessel("mss_supply")
    sectors = {3: [(-0.4, 0.25)]}
    qp = QPAllocator(vessel, forbidden_sectors=sectors)
    half_pi = math.pi / 2
    prev = ThrusterCommand(
        np.array([1e5, 1e5, 1e5, 0, 0, 0]), np.array([0, 0, 0.1, half_pi, half_pi, half_pi])
    )
    tau = vessel.generalized_force(prev.thrust, prev.azimuth)
    for _ in range(60):
        r = qp.allocate(tau, prev)
        assert r.status == "optimal" and np.all(np.isfinite(r.thrust))
        if in_sector(r.azimuth[2], -0.4, 0.25) or in_sector(prev.azimuth[2], -0.4, 0.25):
            assert r.thrust[2] == 0.0
        assert abs(ssa(r.azimuth[2] - prev.azimuth[2])) <= 0.21 * qp.dt + ANGLE_TOL
        prev = r.command
    assert not in_sector(prev.azimuth[2], -0.4, 0.25)


# ---- constrained QP: infeasible demands ----------------------------------------------------------------


def test_infeasible_demand_gives_closest_achievable_tau() -> None:
    """3× total surge capacity with every azimuth already at full thrust ahead: the closest achievable τ
    is all of it, [Σ T_max, 0, 0] (the layout is symmetric); saturated, an alarm, no NaN."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel)
    L = qp.layout
    prev = ThrusterCommand(np.where(L.is_az, L.tmax, 0.0), L.fixed_angle.copy())
    surge = float(np.sum(L.tmax[L.is_az]))
    tau = np.array([3 * surge, 0.0, 0.0])
    r = qp.allocate(tau, prev)
    assert r.saturated and r.status == "optimal" and len(r.alarms) == 1 and "saturated" in r.alarms[0]
    assert np.all(np.isfinite(r.thrust)) and np.all(np.isfinite(r.azimuth)) and np.all(np.isfinite(r.slack))
    np.testing.assert_allclose(r.tau_allocated, [surge, 0.0, 0.0], rtol=0, atol=1e-6 * surge)
    np.testing.assert_allclose(r.slack, tau - r.tau_allocated)
    ref = reference_solve_cvxpy(qp, tau, prev)
    assert ref.status == "optimal"
    np.testing.assert_allclose(r.tau_allocated, tau - ref.slack, rtol=0, atol=1e-6 * L.tau_ref.max())
    check_limits(qp, prev, r.thrust, r.azimuth)


@pytest.mark.parametrize("name", VESSELS)
def test_infeasible_random_demands_match_reference(name: str) -> None:
    vessel = load_vessel(name)
    qp = QPAllocator(vessel, dt=2.0)
    L = qp.layout
    rng = np.random.default_rng(8)
    for _ in range(6):
        prev = random_state(vessel, rng)
        tau = 3.0 * L.tau_ref * rng.choice([-1.0, 1.0], 3) * rng.uniform(0.3, 1.0, 3)
        r = qp.allocate(tau, prev)
        ref = reference_solve_cvxpy(qp, tau, prev)
        assert r.saturated and r.alarms and ref.status == "optimal"
        np.testing.assert_allclose(
            r.tau_allocated / L.tau_ref, (tau - ref.slack) / L.tau_ref, rtol=0, atol=1e-6
        )


# ---- QP against the independent cvxpy formulation ------------------------------------------------------


@pytest.mark.parametrize(
    "name",
    # cvxpy takes over 2 s on the two larger layouts: those are in the slow set, the quick set keeps two
    [
        pytest.param(n, marks=pytest.mark.slow) if n in ("mss_supply", "hajivand_vessel") else n
        for n in VESSELS
    ]
    + ["mains"],
)
def test_qp_and_cvxpy_reach_the_same_optimum(name: str) -> None:
    """Random demands (feasible and not) and previous states, several dt (narrow cones, half-planes and
    free directions) with and without forbidden sectors: the same objective and solution within 1e-6."""
    vessel = get_vessel(name)
    rng = np.random.default_rng(2026)
    for k in range(50):
        dt = float(rng.choice([0.1, 1.0, 10.0, 30.0]))
        sectors = sectors_for(vessel) if k % 2 else None
        qp = QPAllocator(vessel, dt=dt, forbidden_sectors=sectors)
        L = qp.layout
        prev = random_state(vessel, rng)  # may lie inside a forbidden sector: then that thruster is off
        tau = rng.normal(size=3) * L.tau_ref * float(rng.choice([0.01, 0.1, 0.3, 1.0, 3.0]))
        mine = qp.solve_qp(tau, prev)
        ref = reference_solve_cvxpy(qp, tau, prev)
        assert mine.status == "optimal" and ref.status == "optimal"
        assert abs(mine.objective - ref.objective) <= 1e-6 * (1.0 + abs(ref.objective)), (k, mine, ref)
        scale = L.cap[L.owner]
        np.testing.assert_allclose(mine.forces / scale, ref.forces / scale, rtol=0, atol=1e-6)
        np.testing.assert_allclose(mine.slack / L.tau_ref, ref.slack / L.tau_ref, rtol=0, atol=1e-6)


def test_qp_and_cvxpy_agree_along_a_closed_loop() -> None:
    """Previous states produced by the allocator itself (many constraints exactly active)."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel, forbidden_sectors={3: [(math.radians(150), math.radians(-150))]})
    L = qp.layout
    prev: ThrusterCommand | None = None
    checked = 0
    for k in range(400):
        t = 0.1 * k
        tau = L.tau_ref * np.array([0.25 * math.sin(t / 8), 0.12 * math.cos(t / 6), 0.05 * math.sin(t / 4)])
        if 20.0 < t < 25.0:
            tau[0] += 1.5 * L.tau_ref[0]
        if k % 20 == 7:
            mine, ref = qp.solve_qp(tau, prev), reference_solve_cvxpy(qp, tau, prev)
            assert ref.status == "optimal"
            assert abs(mine.objective - ref.objective) <= 1e-6 * (1.0 + abs(ref.objective))
            np.testing.assert_allclose(mine.forces / L.cap[L.owner], ref.forces / L.cap[L.owner], atol=1e-6)
            checked += 1
        prev = qp.allocate(tau, prev).command
    assert checked == 20


# ---- no azimuth chattering -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", VESSELS)
def test_slow_zero_crossing_does_not_swing_azimuths(name: str) -> None:
    vessel = load_vessel(name)
    qp = QPAllocator(vessel)
    L = qp.layout
    rate = np.where(L.is_az, L.rate * qp.dt, 0.0)
    for axis, other in ((0, 1), (1, 0)):
        tau = np.zeros(3)
        tau[other] = 0.05 * L.tau_ref[other]
        tau[axis] = 0.1 * L.tau_ref[axis]
        prev = PseudoInverseAllocator(vessel).allocate(tau).command
        steps = 1500
        for k in range(steps):
            tau[axis] = 0.1 * L.tau_ref[axis] * math.cos(math.pi * k / steps)
            r = qp.allocate(tau, prev)
            assert np.all(np.abs(ssa(r.azimuth - prev.azimuth)) <= rate + ANGLE_TOL)
            prev = r.command


def test_near_zero_thrust_azimuth_keeps_its_angle() -> None:
    """Without thrust biasing (with it, the azimuths never go idle: next test)."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel, bias_fraction=0.0)
    L = qp.layout
    prev = PseudoInverseAllocator(vessel).allocate(np.array([0.1, 0.05, 0.02]) * L.tau_ref).command
    rng = np.random.default_rng(4)
    for _ in range(200):  # demand drops to zero: thrusts ramp down at their rate, angles stay
        prev = qp.allocate(np.zeros(3), prev).command
    assert np.all(prev.thrust[L.is_az] < qp.idle_thrust[L.is_az])
    parked = prev.azimuth.copy()
    for _ in range(300):  # noise around zero demand, far below any thruster's idle threshold
        r = qp.allocate(rng.normal(size=3) * 1e-7 * L.tau_ref, prev)
        np.testing.assert_array_equal(r.azimuth[L.is_az], parked[L.is_az])
        prev = r.command


def test_bias_gives_way_to_tau_and_azimuths_hold_at_zero_demand() -> None:
    """Thrust biasing is a soft floor: the demand drops to zero from a configuration where the azimuths
    all push roughly the same way, so they cannot keep β·T_max each and still give τ = 0. τ wins: once
    the thrusts are down (thrust rate), it is met exactly and never reported saturated (a hard floor left
    it unreachable while they turned), the azimuths going idle instead. With noise around zero demand
    they do not hunt: each travels less than 5 % of its slew rate."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel)
    L = qp.layout
    prev = PseudoInverseAllocator(vessel).allocate(np.array([0.1, 0.05, 0.02]) * L.tau_ref).command
    for k in range(600):
        r = qp.allocate(np.zeros(3), prev)
        # the first steps are short of τ = 0 for real: the thrusts come down at their thrust rate
        assert k < 100 or (not r.saturated and np.all(np.abs(r.tau_allocated) <= 1e-6 * L.tau_ref))
        prev = r.command
    rng = np.random.default_rng(4)
    travel = np.zeros(L.n)
    for _ in range(600):  # 60 s
        r = qp.allocate(rng.normal(size=3) * 1e-7 * L.tau_ref, prev)
        assert not r.saturated
        travel += np.abs(ssa(r.azimuth - prev.azimuth))
        prev = r.command
    assert np.all(travel[L.is_az] < 0.05 * L.rate[L.is_az] * 60.0)


def test_bias_floor_holds_where_the_azimuths_can_push_against_each_other() -> None:
    """Azimuths that can cancel each other's force (mss_supply's aft pair splayed ±60° and the bow one
    pointing aft) keep the bias β·T_max at zero demand: its shortfall is priced above the power cost."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel)
    L = qp.layout
    az = np.flatnonzero(L.is_az)
    angle = np.zeros(L.n)
    angle[az] = np.radians([60.0, -60.0, 180.0])[: len(az)]
    thrust = np.zeros(L.n)
    thrust[az] = 0.1 * L.cap[az]
    prev = ThrusterCommand(thrust=thrust, azimuth=angle)
    for _ in range(50):
        r = qp.allocate(np.zeros(3), prev)
        assert not r.saturated and np.all(np.abs(r.tau_allocated) <= 1e-6 * L.tau_ref)
        prev = r.command
    assert np.all(prev.thrust[az] >= (qp.bias_fraction - 1e-6) * L.cap[az]), prev.thrust[az] / L.cap[az]


def test_azimuth_pointing_the_wrong_way_turns_round() -> None:
    """All azimuths idle and pointing aft, demand ahead: they turn (at their rate) and then deliver."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel)
    L = qp.layout
    prev = ThrusterCommand(np.zeros(L.n), np.where(L.is_az, -math.pi, L.fixed_angle))
    tau = np.array([0.3 * L.tau_ref[0], 0.0, 0.0])
    steps_needed = math.ceil(math.pi / (0.21 * qp.dt)) + 3 * 20  # the turn, then the thrust ramp
    for _ in range(steps_needed):
        r = qp.allocate(tau, prev)
        assert np.all(
            np.abs(ssa(r.azimuth - prev.azimuth)) <= np.where(L.is_az, L.rate * qp.dt, 0) + ANGLE_TOL
        )
        prev = r.command
    assert not r.saturated
    np.testing.assert_allclose(r.tau_allocated, tau, atol=1e-6 * float(np.linalg.norm(tau)))


# ---- bad input, configuration --------------------------------------------------------------------------


def test_non_finite_demand_holds_previous_command() -> None:
    vessel = load_vessel("cybership2")
    qp = QPAllocator(vessel)
    prev = PseudoInverseAllocator(vessel).allocate([0.5, 0.2, 0.05]).command
    for alloc in (qp, PseudoInverseAllocator(vessel)):
        r = alloc.allocate([math.nan, 0.0, 0.0], prev)
        assert r.status == "invalid_input" and r.saturated and r.alarms
        np.testing.assert_allclose(r.thrust, prev.thrust)
        np.testing.assert_allclose(r.azimuth, prev.azimuth)
        assert np.all(np.isfinite(r.tau_allocated))
    r = qp.allocate([0.5, 0.2, 0.05], prev)  # and the next good demand is allocated as usual
    assert r.status == "optimal"


def test_previous_none_is_at_rest_and_ramps_up() -> None:
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel)
    L = qp.layout
    r = qp.allocate(0.2 * L.tau_ref * np.array([1.0, 0.0, 0.0]), None)
    rest = ThrusterCommand.at_rest(vessel)
    check_limits(qp, rest, r.thrust, r.azimuth)
    assert r.saturated  # 20 % of capacity is more than one step's ramp from rest


@pytest.mark.parametrize("solver", ["compiled", "daqp"])
def test_a_ramp_to_a_reachable_demand_is_no_alarm_for_as_long_as_a_ramp_takes(solver: str) -> None:
    """Every azimuth at full thrust ahead, then a demand of zero (entering manual, a manual τ expired):
    the thrusters come down at their thrust rate, so the first steps fall short (`saturated`, for the
    controller's anti-windup), but that is ramping, not saturation: no alarm. The same from rest up to 60 %
    of capacity ahead. A reachable demand still not met after the layout's longest ramp (`ramp_s`) is
    alarmed; one beyond capacity at once."""
    vessel = load_vessel("mss_supply")
    qp = QPAllocator(vessel, dt=0.1, solver=solver)
    L = qp.layout
    assert qp.ramp_s == pytest.approx(math.pi / 0.21)  # mss_supply: an azimuth's half turn, 15 s
    full = ThrusterCommand(np.where(L.is_az, L.tmax, 0.0), L.fixed_angle.copy())
    cmd, short = full, 0
    for _ in range(50):
        r = qp.allocate(np.zeros(3), cmd)
        short += r.saturated
        assert r.alarms == (), r.alarms
        cmd = r.command
    assert short >= 5 and not r.saturated  # it fell short while ramping down, then met the demand
    assert np.all(np.abs(cmd.thrust) < 1e-6 * L.cap)
    up = np.array([0.6 * float(np.sum(L.tmax[L.is_az])), 0.0, 0.0])
    cmd, short = ThrusterCommand.at_rest(vessel), 0
    for _ in range(100):
        r = qp.allocate(up, cmd)
        short += r.saturated
        assert r.alarms == (), r.alarms
        cmd = r.command
    assert short >= 5 and not r.saturated
    # held back at rest at every step (the thrusters never get there): alarmed once a ramp is over
    rest = ThrusterCommand.at_rest(vessel)
    alarmed = [bool(qp.allocate(up, rest).alarms) for _ in range(round(qp.ramp_s / 0.1) + 5)]
    assert not any(alarmed[: round(qp.ramp_s / 0.1)]) and alarmed[-1]
    # beyond capacity: alarmed at the first step
    fresh = QPAllocator(vessel, dt=0.1, solver=solver)
    r = fresh.allocate(np.array([3.0 * float(np.sum(L.tmax[L.is_az])), 0.0, 0.0]), full)
    assert r.saturated and len(r.alarms) == 1 and r.alarms[0].startswith("thrust allocation saturated")


def test_configuration_errors_are_refused() -> None:
    vessel = load_vessel("mss_supply")
    with pytest.raises(ValueError, match="unknown thruster id"):
        QPAllocator(vessel, forbidden_sectors={9: [(0.0, 1.0)]})
    with pytest.raises(ValueError, match="not an azimuth"):
        QPAllocator(vessel, forbidden_sectors={4: [(0.0, 1.0)]})
    with pytest.raises(ValueError, match="dt"):
        QPAllocator(vessel, dt=0.0)
    with pytest.raises(ValueError, match="weights"):
        QPAllocator(vessel, weights={1: -1.0})
    with pytest.raises(ValueError, match="polygon_sides"):
        QPAllocator(vessel, polygon_sides=4)


def test_solve_time_reported() -> None:
    vessel = load_vessel("mss_supply")
    r = QPAllocator(vessel).allocate([1e5, 0.0, 0.0])
    assert 0.0 < r.solve_time_s < 1.0


@pytest.mark.parametrize("solver", ["compiled", "daqp"])
def test_unavailable_thruster_gets_nothing_and_the_others_take_its_share_at_their_rates(solver: str) -> None:
    """A tripped drive (thruster 1, aft port azimuth of mss_supply) is taken out of the allocation: from the
    next step it is commanded zero thrust, the others change by at most their rate limits per step and meet
    a feasible demand again within their time constants; back in service, it ramps up from zero at its own
    thrust rate and shares the load again."""
    vessel = load_vessel("mss_supply")
    dt = 0.1
    alloc = QPAllocator(vessel, dt=dt, solver=solver)
    L = alloc.layout
    dT = alloc.thrust_rate * dt
    turn = np.where(L.is_az, L.rate * dt, 0.0)
    tau = np.array([3.0e5, 1.0e5, 2.0e6])
    cmd = ThrusterCommand.at_rest(vessel)
    for _ in range(300):
        cmd = alloc.allocate(tau, cmd).command
    assert cmd.thrust[0] > 5e4  # thruster 1 carries a share before it trips
    alloc.set_available({1: False})
    assert alloc.available.tolist() == [False, True, True, True, True, True]
    met_at = None
    for k in range(300):
        res = alloc.allocate(tau, cmd)
        assert res.thrust[0] == 0.0
        others = slice(1, None)
        assert np.all(np.abs(res.thrust[others] - cmd.thrust[others]) <= dT[others] * (1 + 1e-9) + 1e-6)
        assert np.all(np.abs(ssa(res.azimuth - cmd.azimuth)) <= turn + ANGLE_TOL)
        if met_at is None and not res.saturated:
            met_at = k * dt
        cmd = res.command
    assert met_at is not None and met_at < 20.0
    assert np.allclose(res.tau_allocated, tau, rtol=1e-6, atol=1e-6 * L.tau_ref.max())
    alloc.set_available({1: True})
    before = cmd.thrust[0]
    res = alloc.allocate(tau, cmd)
    assert res.thrust[0] - before <= dT[0] * (1 + 1e-9) + 1e-6
    for _ in range(300):
        cmd = alloc.allocate(tau, cmd).command
    assert cmd.thrust[0] > 5e4


def test_pseudo_inverse_leaves_an_unavailable_thruster_out() -> None:
    vessel = load_vessel("mss_supply")
    alloc = PseudoInverseAllocator(vessel)
    alloc.set_available([True, True, False, True, True, True])
    res = alloc.allocate([1.0e5, 5.0e4, 1.0e6])
    assert res.thrust[2] == 0.0
    assert np.allclose(res.tau_allocated, [1.0e5, 5.0e4, 1.0e6], rtol=1e-9, atol=1e-3)


def test_set_available_refuses_unknown_ids() -> None:
    alloc = QPAllocator(load_vessel("mss_supply"))
    with pytest.raises(ValueError, match="unknown thruster"):
        alloc.set_available({99: False})


@pytest.mark.parametrize("solver", ["compiled", "daqp"])
@pytest.mark.parametrize("scale", [1e4, 1e15, 1e30, 1e300])
def test_absurdly_large_finite_demand_gives_full_thrust_the_right_way(solver: str, scale: float) -> None:
    """A finite demand far beyond capacity (a wild estimate, a broken controller) is saturated, never a
    solver failure that holds the thrusters where they were: from rest, surge ahead at full capacity, the
    shortfall reported against the demand as given."""
    vessel = load_vessel("mss_supply")
    alloc = QPAllocator(vessel, dt=0.1, solver=solver)
    tau = np.array([1.0, 0.0, 0.0]) * scale * 1e3
    cmd = ThrusterCommand.at_rest(vessel)
    for _ in range(300):
        res = alloc.allocate(tau, cmd)
        assert res.status == "optimal" and res.saturated and len(res.alarms) == 1
        assert np.all(np.isfinite(res.thrust))
        cmd = res.command
    az_capacity = sum(t.max_thrust_n for t in vessel.thrusters if t.kind == "azimuth")
    assert res.tau_allocated[0] == pytest.approx(az_capacity, rel=1e-6)
    assert abs(res.tau_allocated[1]) < 1e-6 * az_capacity
    assert np.array_equal(res.tau_demand, tau) and np.array_equal(res.slack, tau - res.tau_allocated)
    assert alloc.fallbacks == 0


def _with_sector(sector_deg: tuple[float, float]) -> VesselModel:
    from dataclasses import replace

    base = load_vessel("mss_supply")
    th = list(base.thrusters)
    th[2] = replace(th[2], forbidden_sectors_deg=(sector_deg,))  # the bow azimuth, id 3
    return replace(base, thrusters=tuple(th))


@pytest.mark.parametrize("solver", ["compiled", "daqp"])
def test_vessel_file_barred_zones_are_respected_by_default(solver: str) -> None:
    """The barred zones of the vessel's layout (thruster-thruster interaction, hull) apply to every
    `QPAllocator` of that vessel without being passed again: the bow azimuth never pushes aft in its
    sector, even for an astern demand that the unconstrained allocation would meet with it pushing aft."""
    vessel = _with_sector((150.0, -150.0))
    alloc = QPAllocator(vessel, dt=0.1, solver=solver)
    assert 2 in alloc.forbidden
    lo, hi = math.radians(150.0), math.radians(210.0)
    cmd = ThrusterCommand.at_rest(vessel)
    for k in range(600):
        tau = np.array([-3.0e5, 2.0e4 * math.sin(0.01 * k), 0.0])
        res = alloc.allocate(tau, cmd)
        a = float(res.azimuth[2]) % (2 * math.pi)
        if res.thrust[2] > 1e-3 * 2.5e5:
            assert not (lo + 1e-9 < a < hi - 1e-9), (k, math.degrees(a))
        cmd = res.command
    free = QPAllocator(load_vessel("mss_supply"), dt=0.1, solver=solver)
    res = free.allocate(
        [-3.0e5, 0.0, 0.0], ThrusterCommand(np.zeros(6), np.array([math.pi] * 3 + [math.pi / 2] * 3))
    )
    assert abs(ssa(res.azimuth[2] - math.pi)) < 1e-6 and res.thrust[2] > 1e4  # without it, it pushes aft


def test_explicit_sectors_replace_the_vessel_file_ones() -> None:
    vessel = _with_sector((150.0, -150.0))
    assert QPAllocator(vessel, forbidden_sectors={}).forbidden == {}
