"""Quasi-static thrust capability: gateway/control/capability.py.

Analytic layouts (four azimuths at the corners of a rectangle, two tunnels, a single azimuth with a
barred sector), the polygon bound cos(π/n), scale invariance and the effect of a failure (hypothesis),
the forces of the optimum checked against the vessel's own configuration matrix, and agreement with
the run-time allocator: a load the LP says can be held with 5 % to spare is met by `QPAllocator`
without saturation, one 5 % beyond is not.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gateway.control.allocation import QPAllocator, ThrusterCommand
from gateway.control.capability import CapabilityLP, allowed_arcs, attainable_scale
from observers.vessel import Thruster, VesselModel, load_vessel

T = 1.0e5
N_SIDES = 64
POLY = math.cos(math.pi / N_SIDES)  # worst-case underestimate of the inscribed polygon


def four_azimuths() -> list[Thruster]:
    """Four identical azimuths at (±10, ±5) m: symmetric about the reference point."""
    return [
        Thruster(i + 1, "azimuth", x, y, T, azimuth_rate_rad_s=0.2)
        for i, (x, y) in enumerate([(10.0, 5.0), (10.0, -5.0), (-10.0, 5.0), (-10.0, -5.0)])
    ]


def two_tunnels() -> list[Thruster]:
    return [
        Thruster(1, "tunnel", 20.0, 0.0, T, -0.8 * T, angle_rad=math.pi / 2),
        Thruster(2, "tunnel", -20.0, 0.0, T, -0.8 * T, angle_rad=math.pi / 2),
    ]


def test_four_azimuths_surge_sway_and_yaw_are_the_analytic_figures() -> None:
    th = four_azimuths()
    X = 1.0e5
    # surge: every azimuth pushes ahead at full thrust (a polygon vertex lies on 0°: exact)
    assert attainable_scale(th, [X, 0.0, 0.0]) == pytest.approx(4 * T / X, rel=1e-9)
    assert attainable_scale(th, [0.0, -X, 0.0]) == pytest.approx(4 * T / X, rel=1e-9)
    # yaw: each pushes tangentially at full thrust, lever √(10² + 5²); the tangent may fall between
    # polygon vertices, so within cos(π/n) below
    Nz = 1.0e6
    exact = 4 * T * math.hypot(10.0, 5.0) / Nz
    k = attainable_scale(th, [0.0, 0.0, Nz])
    assert POLY * exact - 1e-9 <= k <= exact + 1e-9
    # surge at 45°: 4 T in any direction, within the polygon bound
    k45 = attainable_scale(th, [X, X, 0.0])
    assert POLY * 4 * T / (X * math.sqrt(2)) - 1e-9 <= k45 <= 4 * T / (X * math.sqrt(2)) + 1e-9


def test_tunnels_give_sway_and_yaw_but_no_surge() -> None:
    th = two_tunnels()
    assert attainable_scale(th, [0.0, 5.0e4, 0.0]) == pytest.approx(2 * T / 5.0e4, rel=1e-9)
    # to port the tunnels reverse: 0.8 T each
    assert attainable_scale(th, [0.0, -5.0e4, 0.0]) == pytest.approx(1.6 * T / 5.0e4, rel=1e-9)
    # pure yaw: the bow one at +T, the stern one at −0.8 T (the weaker direction binds)
    assert attainable_scale(th, [0.0, 0.0, 1.0e6]) == pytest.approx(2 * 20.0 * 0.8 * T / 1.0e6, rel=1e-9)
    assert attainable_scale(th, [1.0e4, 0.0, 0.0]) == 0.0
    assert attainable_scale(th, [0.0, 0.0, 0.0]) == math.inf


def test_a_non_reversing_main_propeller_cannot_push_astern() -> None:
    th = [Thruster(1, "main", -30.0, 0.0, T, 0.0)]
    assert attainable_scale(th, [5.0e4, 0.0, 0.0]) == pytest.approx(2.0, rel=1e-9)
    assert attainable_scale(th, [-5.0e4, 0.0, 0.0]) == 0.0


def test_a_barred_sector_is_respected_exactly_not_through_the_convex_hull() -> None:
    """One azimuth barred from pushing within ±60° of ahead: its force set is the disc minus that
    wedge, not convex. Ahead it cannot push at all (the convex hull would say cos 60° T); astern fully;
    at 70° (allowed) nearly fully."""
    th = [Thruster(1, "azimuth", 0.0, 0.0, T, azimuth_rate_rad_s=0.2, forbidden_sectors_deg=((-60.0, 60.0),))]
    assert attainable_scale(th, [1.0e4, 0.0, 0.0]) == 0.0
    assert attainable_scale(th, [-1.0e4, 0.0, 0.0]) == pytest.approx(T / 1.0e4, rel=1e-9)
    d = math.radians(70.0)
    k = attainable_scale(th, [1.0e4 * math.cos(d), 1.0e4 * math.sin(d), 0.0])
    assert POLY * T / 1.0e4 - 1e-9 <= k <= T / 1.0e4 + 1e-9
    # two of them side by side can combine directions in different pieces: 60° + (−60°) gives ahead
    two = [th[0], replace(th[0], id=2)]
    assert attainable_scale(two, [1.0e4, 0.0, 0.0]) == pytest.approx(2 * T * 0.5 / 1.0e4, rel=1e-9)
    assert CapabilityLP(two).lp_count == 4


def test_allowed_arcs_split_the_free_directions_into_convex_wedges() -> None:
    assert allowed_arcs(()) is None
    arcs = allowed_arcs(((350.0, 10.0), (5.0, 20.0)))  # overlapping, one across 0°
    assert arcs is not None and len(arcs) == 2
    assert sum(w for _, w in arcs) == pytest.approx(math.radians(330.0))
    assert all(w <= math.pi for _, w in arcs)
    assert arcs[0][0] == pytest.approx(math.radians(20.0))
    assert allowed_arcs(((0.0, 180.0), (180.0, 0.0))) == []  # all barred
    one = allowed_arcs(((0.0, 200.0),))  # 160° free: one convex piece
    assert one == [(pytest.approx(math.radians(200.0)), pytest.approx(math.radians(160.0)))]


def test_a_fully_barred_azimuth_gives_nothing() -> None:
    th = [
        Thruster(
            1,
            "azimuth",
            0.0,
            0.0,
            T,
            azimuth_rate_rad_s=0.2,
            forbidden_sectors_deg=((0.0, 180.0), (180.0, 0.0)),
        )
    ]
    assert attainable_scale(th, [1.0, 2.0, 0.0]) == 0.0


def test_a_failure_reduces_the_scale_and_unknown_ids_are_refused() -> None:
    th = four_azimuths()
    intact = attainable_scale(th, [1.0e5, 0.0, 0.0])
    one_down = attainable_scale(th, [1.0e5, 0.0, 0.0], failed={1})
    assert one_down < intact
    # three azimuths: at most 3 T ahead, and the yaw moment of the missing one must be balanced
    assert one_down <= 3 * T / 1.0e5 + 1e-9
    assert attainable_scale(th, [1.0e5, 0.0, 0.0], failed={1, 2, 3, 4}) == 0.0
    with pytest.raises(ValueError, match="unknown thruster ids"):
        attainable_scale(th, [1.0, 0.0, 0.0], failed={9})


taus = st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)).filter(
    lambda v: max(abs(x) for x in v) > 1e-3
)


@settings(max_examples=40, deadline=None)
@given(tau=taus, c=st.floats(1e-3, 1e3), fail=st.sampled_from([None, 1, 2, 3, 4, 5, 6]))
def test_scale_invariance_and_failures_never_help(
    tau: tuple[float, float, float], c: float, fail: int | None
) -> None:
    v = load_vessel("mss_supply")
    t = np.array(tau) * np.array([3.0e5, 3.0e5, 1.0e7])
    lp = CapabilityLP(v.thrusters)
    k = lp.scale(t)
    assert lp.scale(c * t) == pytest.approx(k / c, rel=1e-6, abs=1e-9)
    if fail is not None:
        assert CapabilityLP(v.thrusters, failed={fail}).scale(t) <= k * (1 + 1e-7) + 1e-12


@pytest.mark.parametrize("solver", ["daqp", "highs"])
def test_scale_invariance_holds_for_vanishing_and_huge_loads(solver: str) -> None:
    """k*(c τ) = k*(τ)/c down to a load decaying towards zero and up to an absurd one: the LP's direction
    is normalised without squaring the load (a norm of 1e-200 squared is 0, and the LP was NaN)."""
    v = load_vessel("mss_supply")
    lp = CapabilityLP(v.thrusters, solver=solver)
    t = np.array([1.0e5, -2.0e5, 3.0e6])
    k = lp.scale(t)
    assert 0.0 < k < math.inf
    for c in (1e-200, 1e-150, 1e150, 1e200):
        assert lp.scale(c * t) == pytest.approx(k / c, rel=1e-6)
    assert lp.scale([5e-324, 0.0, 0.0]) == math.inf  # (k* beyond the float range: inf, not an error)


@pytest.mark.parametrize("name", ["mss_supply", "hajivand_vessel", "cybership2", "mss_osv"])
def test_the_optimal_forces_give_k_tau_within_every_limit(name: str) -> None:
    v = load_vessel(name)
    rng = np.random.default_rng(3)
    scale = np.array([1.0, 1.0, v.length_m / 2]) * max(t.max_thrust_n for t in v.thrusters)
    for _ in range(10):
        tau = rng.normal(size=3) * scale
        sol = CapabilityLP(v.thrusters).solve(tau)
        assert sol.scale > 0
        got = v.generalized_force(sol.thrust, sol.azimuth)
        np.testing.assert_allclose(got, sol.scale * tau, rtol=1e-6, atol=1e-6 * np.abs(tau).max())
        for t, u in zip(v.thrusters, sol.thrust, strict=True):
            lo = 0.0 if t.kind == "azimuth" else min(t.min_thrust_n, 0.0)
            assert lo - 1e-6 * t.max_thrust_n <= u <= t.max_thrust_n * (1 + 1e-6)


def barred_supply() -> VesselModel:
    """mss_supply with a 60° barred sector on a stern azimuth (to starboard) and the bow azimuth (astern)."""
    base = load_vessel("mss_supply")
    th = list(base.thrusters)
    th[0] = replace(th[0], forbidden_sectors_deg=((60.0, 120.0),))
    th[2] = replace(th[2], forbidden_sectors_deg=((150.0, -150.0),))
    return replace(base, thrusters=tuple(th))


def _settle(vessel: VesselModel, tau: np.ndarray, failed: set[int]) -> bool:
    """Whether `QPAllocator`, given the steady demand τ long enough to turn and ramp every thruster,
    ends up saturated."""
    alloc = QPAllocator(vessel, dt=0.5)
    if failed:
        alloc.set_available({i: False for i in failed})
    cmd = ThrusterCommand.at_rest(vessel)
    res = alloc.allocate(tau, cmd)
    for _ in range(200):  # 100 s: a full azimuth turn takes 30 s on these vessels
        res = alloc.allocate(tau, cmd)
        cmd = res.command
    return res.saturated


@pytest.mark.parametrize(
    ("name", "failed"),
    [
        ("mss_supply", set()),
        ("mss_supply", {1}),
        ("mss_supply_barred", set()),
        ("hajivand_vessel", set()),
        ("mss_osv", set()),
    ],
)
def test_qp_allocator_meets_what_the_lp_says_can_be_held_and_not_more(name: str, failed: set[int]) -> None:
    """k* > 1.05: the run-time allocator (its polygon has 16 sides, cos(π/16) = 0.981) meets τ without
    saturation; k* < 0.95: it saturates. Also with barred sectors (the allocator's rate cone clipped by
    them, the LP's convex pieces)."""
    vessel = barred_supply() if name == "mss_supply_barred" else load_vessel(name)
    lp = CapabilityLP(vessel.thrusters, failed=failed)
    rng = np.random.default_rng(11)
    for j in range(6):
        direction = rng.normal(size=3) * np.array([1.0, 1.0, vessel.length_m / 4])
        k0 = lp.scale(direction)
        target = rng.uniform(1.06, 1.5) if j % 2 == 0 else rng.uniform(0.6, 0.94)
        tau = direction * k0 / target  # k*(tau) = target
        assert lp.scale(tau) == pytest.approx(target, rel=1e-6)
        assert _settle(vessel, tau, failed) == (target < 1.0), (j, target, tau)


def _with_sectors(vessel: VesselModel) -> list[Thruster]:
    """The vessel's thrusters, its azimuths given a barred sector each (30° and 200° wide in turn): the LP
    in several convex pieces."""
    out = []
    for i, t in enumerate(vessel.thrusters):
        if t.kind == "azimuth":
            t = replace(t, forbidden_sectors_deg=((60.0, 90.0),) if i % 2 == 0 else ((150.0, 350.0),))
        out.append(t)
    return out


@settings(max_examples=60, deadline=None)
@given(
    tau=taus,
    name=st.sampled_from(["mss_supply", "hajivand_vessel", "cybership2", "mss_osv"]),
    sectors=st.booleans(),
    fail=st.sampled_from([None, 1, 2, 3]),
)
# a yaw load with 6e-8 of surge, where k* jumps (answered only with surge of one sign): DAQP 0.73 against
# HiGHS 0 until a component below a millionth of the largest was taken as 0
@example(tau=(5.960464477539063e-08, 0.0, -1.0), name="cybership2", sectors=True, fail=2)
@example(tau=(0.0, 1.0, 5.960464477539063e-08), name="mss_supply", sectors=False, fail=None)
def test_daqp_agrees_with_highs(
    tau: tuple[float, float, float], name: str, sectors: bool, fail: int | None
) -> None:
    """The fast solver (DAQP) and the reference (HiGHS) give the same k* on the same LPs: the vessels'
    layouts, with barred sectors (several convex pieces) and a thruster failed. Same to 2e-4 of k* and
    1e-7 absolute: near a direction where k* jumps (a load the layout answers only with one sign of a
    component that is almost 0) the solvers' own tolerances move k* by up to ~1e-4 (fuzzes of 32,000
    adversarial loads: 9e-5 at most, 2e-8 absolute where k* is 0), far below the utilisation's 0.1 %
    and U_max's 0.1 m/s that anyone reads. DAQP solves every LP itself except there (a component
    below 1e-4 of the largest, in the LP's units), where it may hand one to HiGHS, as designed."""
    v = load_vessel(name)
    th = _with_sectors(v) if sectors else list(v.thrusters)
    failed = {fail} if fail is not None and fail <= len(th) else set()
    t = np.array(tau) * np.array([1.0, 1.0, v.length_m / 2]) * max(x.max_thrust_n for x in th)
    lp = CapabilityLP(th, failed=failed)
    fast = lp.solve(t)
    ref = CapabilityLP(th, failed=failed, solver="highs").solve(t)
    u = np.abs(t / lp.tau_ref)
    near_a_jump = bool(np.any((u > 0) & (u < 1e-4 * u.max())))
    assert lp.fallbacks == 0 or near_a_jump  # (elsewhere every LP is solved by DAQP, not handed to HiGHS)
    assert fast.scale == pytest.approx(ref.scale, rel=2e-4, abs=1e-7)
    got = v.generalized_force(fast.thrust, fast.azimuth)
    # compared in the LP's units (τ / tau_ref), where a component below a millionth of the largest is 0
    ref_units = lp.tau_ref
    np.testing.assert_allclose(
        got / ref_units,
        fast.scale * t / ref_units,
        rtol=1e-6,
        atol=2e-6 * max(fast.scale, 1.0) * np.abs(t / ref_units).max(),
    )


def test_an_unknown_solver_is_refused() -> None:
    with pytest.raises(ValueError, match="solver"):
        CapabilityLP(four_azimuths(), solver="glpk")
