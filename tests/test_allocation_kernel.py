"""The compiled allocation step (gateway/control/_allocation_kernel.py) against its readable reference.

`QPAllocator(solver="compiled")` (the default) runs the whole step — state, limits, QP, solution,
commands — in one compiled call with a Goldfarb–Idnani dual active-set solver; `solver="daqp"` is the
Python path around DAQP. Both must give the same QP optimum (the QP is strictly convex: one optimum) and
the same commands, on random feasible demands and on infeasible ones (slack active), for four layouts, with
narrow cones, half-planes and free directions, with and without forbidden sectors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from gateway.control import _allocation_kernel as kernel
from gateway.control.allocation import QPAllocator, ThrusterCommand
from observers.kinematics import ssa
from tests.test_allocation import get_vessel, random_state, sectors_for

VESSELS = ["mss_supply", "hajivand_vessel", "cybership2", "mains"]
X_TOL = 1e-7  # scaled units (force / T_max, slack / τ_ref): observed ~1e-8 between the two solvers

cases = st.tuples(
    st.sampled_from(VESSELS),
    st.sampled_from([0.1, 1.0, 10.0, 30.0]),  # dt: narrow cones, wider ones, half-planes, free directions
    st.booleans(),  # forbidden sectors
    st.integers(0, 2**32 - 1),  # seed of the previous state and the demand's direction
    st.sampled_from([0.0, 0.01, 0.1, 0.3, 1.0, 3.0]),  # demand size, fraction of τ_ref
)


def _pair(name: str, dt: float, sectors: bool) -> tuple[QPAllocator, QPAllocator]:
    vessel = get_vessel(name)
    sec = sectors_for(vessel) if sectors else None
    return (
        QPAllocator(vessel, dt=dt, forbidden_sectors=sec),
        QPAllocator(vessel, dt=dt, forbidden_sectors=sec, solver="daqp"),
    )


def _state_and_demand(a: QPAllocator, seed: int, size: float) -> tuple[ThrusterCommand, np.ndarray]:
    rng = np.random.default_rng(seed)
    prev = random_state(a.layout.vessel, rng)  # may lie inside a forbidden sector: that thruster is off
    return prev, rng.normal(size=3) * a.layout.tau_ref * size


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(cases)
def test_compiled_qp_matches_daqp(case: tuple[str, float, bool, int, float]) -> None:
    name, dt, sectors, seed, size = case
    fast, ref = _pair(name, dt, sectors)
    prev, tau = _state_and_demand(fast, seed, size)
    a, b = fast.solve_qp(tau, prev), ref.solve_qp(tau, prev)
    assert fast.fallbacks == 0, "the compiled solver gave up"
    assert a.status == b.status == "optimal"
    L = fast.layout
    slack_active = bool(np.max(np.abs(b.slack) / L.tau_ref) > 1e-6)
    event(f"slack active: {slack_active}")
    scale = L.cap[L.owner]
    np.testing.assert_allclose(a.forces / scale, b.forces / scale, rtol=0, atol=X_TOL)
    np.testing.assert_allclose(a.slack / L.tau_ref, b.slack / L.tau_ref, rtol=0, atol=X_TOL)
    # 1e-8 relative: with ρ₁ = ρ₂/10 an infeasible demand's objective is mostly ρ₁|ŝ| + ½ρ₂ŝ² (10⁵ times the
    # slack), so the two solvers' round-off in ŝ shows 100 times larger in it than with ρ₁ = √ρ₂ (seen:
    # 1.9e-9 at an objective of 427, the forces equal within X_TOL)
    assert abs(a.objective - b.objective) <= 1e-8 * (1.0 + abs(b.objective))


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(cases)
def test_compiled_step_matches_python_step(case: tuple[str, float, bool, int, float]) -> None:
    """The whole `allocate`: thrusts, azimuths, τ, saturation. Where the reference's force on an azimuth is
    within round-off of the idle threshold, either branch is right: those azimuths are not compared."""
    name, dt, sectors, seed, size = case
    fast, ref = _pair(name, dt, sectors)
    prev, tau = _state_and_demand(fast, seed, size)
    ra, rb = fast.allocate(tau, prev), ref.allocate(tau, prev)
    assert fast.fallbacks == 0
    L = fast.layout
    sol = ref.solve_qp(tau, prev)
    mag = np.hypot(
        sol.forces[L.first], np.where(L.is_az, sol.forces[np.minimum(L.first + 1, L.n_ext - 1)], 0)
    )
    clear = ~L.is_az | (np.abs(mag - fast.idle_thrust) > 1e-6 * L.cap)
    assert ra.status == rb.status == "optimal"
    np.testing.assert_allclose((ra.thrust / L.cap)[clear], (rb.thrust / L.cap)[clear], rtol=0, atol=1e-6)
    np.testing.assert_allclose(ssa(ra.azimuth - rb.azimuth)[clear], 0.0, rtol=0, atol=1e-6)
    if clear.all():
        np.testing.assert_allclose(ra.tau_allocated / L.tau_ref, rb.tau_allocated / L.tau_ref, atol=1e-6)
        if abs(np.max(np.abs(sol.slack) / L.tau_ref) - 1e-6) > 1e-8:  # not at the saturation threshold
            assert ra.saturated == rb.saturated
    assert np.all(ra.azimuth >= -math.pi) and np.all(ra.azimuth < math.pi)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(cases)
def test_bounded_start_gives_the_cold_start_optimum(case: tuple[str, float, bool, int, float]) -> None:
    """The solver starts at the minimum over the simple bounds (x₀ clipped, those bounds active) instead of
    G&I's unconstrained x₀: the same optimum (one optimum; the path and its round-off differ) to 1e-9 in
    scaled units, far inside X_TOL."""
    name, dt, sectors, seed, size = case
    fast, _ = _pair(name, dt, sectors)
    prev, tau = _state_and_demand(fast, seed, size)
    d = fast.qp_data(tau, prev)
    args = (np.diag(d.P), d.q, d.A, d.b_eq, d.ub_A, d.lb, d.ub, d.n_eq)
    xb, sb, _ = kernel.solve_qp_data(*args)
    xc, sc, _ = kernel.solve_qp_data(*args, bounded_start=False)
    assert sb == sc == kernel.OK
    np.testing.assert_allclose(xb, xc, rtol=0, atol=1e-9)


def test_bounded_start_saves_the_iterations_of_the_shortfall_bounds() -> None:
    """Why it starts there: along a DP-like demand the τ slacks and bias shortfalls (q > 0, bound 0) would
    otherwise enter one at a time while the τ equalities push forces onto bounds that must be dropped
    again (~42 iterations a step against ~13 on the benchmark's sequence); the optimum is the same."""
    fast, _ = _pair("mss_supply", 0.1, False)
    L = fast.layout
    prev: ThrusterCommand | None = None
    iterations = {True: 0, False: 0}
    for k in range(300):
        t = 0.1 * k
        tau = L.tau_ref * np.array([0.25 * math.sin(t / 12), 0.12 * math.cos(t / 9), 0.05 * math.sin(t / 4)])
        d = fast.qp_data(tau, prev)
        args = (np.diag(d.P), d.q, d.A, d.b_eq, d.ub_A, d.lb, d.ub, d.n_eq)
        xs = {}
        for bounded in (True, False):
            xs[bounded], status, it = kernel.solve_qp_data(*args, bounded_start=bounded)
            assert status == kernel.OK
            iterations[bounded] += it
        np.testing.assert_allclose(xs[True], xs[False], rtol=0, atol=1e-9)
        prev = fast.allocate(tau, prev).command
    assert iterations[True] < 0.5 * iterations[False]


@pytest.mark.parametrize("sectors", [False, True])
def test_same_commands_along_a_closed_loop(sectors: bool) -> None:
    """Each allocator fed its own previous command, 1000 steps of a DP-like demand with a gust beyond
    capacity: the two command sequences stay together (no drift from round-off) and no step falls back."""
    fast, ref = _pair("mss_supply", 0.1, sectors)
    L = fast.layout
    rng = np.random.default_rng(3)
    pa: ThrusterCommand | None = None
    pb: ThrusterCommand | None = None
    saturated = 0
    for k in range(1000):
        t = 0.1 * k
        tau = L.tau_ref * np.array([0.25 * math.sin(t / 12), 0.12 * math.cos(t / 9), 0.05 * math.sin(t / 4)])
        tau += rng.normal(0.0, 0.01, 3) * L.tau_ref
        if 40.0 < t < 45.0:
            tau[0] += 1.5 * L.tau_ref[0]
        ra, rb = fast.allocate(tau, pa), ref.allocate(tau, pb)
        np.testing.assert_allclose(ra.thrust / L.cap, rb.thrust / L.cap, rtol=0, atol=1e-6)
        np.testing.assert_allclose(ssa(ra.azimuth - rb.azimuth), 0.0, rtol=0, atol=1e-6)
        saturated += ra.saturated
        pa, pb = ra.command, rb.command
    assert fast.fallbacks == 0
    assert saturated > 10  # the gust was beyond capacity: the slack was active on those steps


def test_a_step_the_compiled_solver_gives_up_on_is_solved_by_daqp(monkeypatch: pytest.MonkeyPatch) -> None:
    fast, ref = _pair("mss_supply", 0.1, True)
    prev, tau = _state_and_demand(fast, 7, 0.3)
    monkeypatch.setattr(kernel, "allocate_step", lambda *a: kernel.FAIL_ITER)
    ra, rb = fast.allocate(tau, prev), ref.allocate(tau, prev)
    assert fast.fallbacks == 1
    np.testing.assert_array_equal(ra.thrust, rb.thrust)
    np.testing.assert_array_equal(ra.azimuth, rb.azimuth)


def test_infeasible_qp_is_reported_not_solved() -> None:
    """x ≥ 1 and x ≤ 0: the solver says infeasible (the allocator's QPs are always feasible; this is the
    guard that makes a failure fall back instead of returning a wrong x)."""
    A = np.zeros((4, 2))
    A[0, 1] = 1.0  # one equality: x1 = 0
    A[3, 0] = 1.0  # x0 ≤ 0
    _, status, _ = kernel.solve_qp_data(
        np.ones(2), np.zeros(2), A, np.zeros(1), np.array([0, 0, 0, 0.0]), np.array([1.0, -np.inf]),
        np.full(2, np.inf), 1,
    )  # fmt: skip
    assert status == kernel.FAIL_INFEASIBLE


def test_unconstrained_and_bound_optimum_exact() -> None:
    """min ½(x0² + 4 x1²) − x0 − 4 x1 s.t. x0 + x1 = 1.5, x1 ≤ 0.25: optimum (1.25, 0.25) by hand (the bound
    is active: without it (1.2, 0.3))."""
    A = np.array([[1.0, 1.0], [0.0, 0.0]])
    x, status, _ = kernel.solve_qp_data(
        np.array([1.0, 4.0]), np.array([-1.0, -4.0]), A, np.array([1.5]), np.array([0.0, np.inf]),
        np.full(2, -np.inf), np.array([np.inf, 0.25]), 1,
    )  # fmt: skip
    assert status == kernel.OK
    np.testing.assert_allclose(x, [1.25, 0.25], atol=1e-14)
