"""Benchmark: the thrust-allocation QP on a six-thruster vessel, QP solvers side by side.

Target: median ≤ 200 µs and p99 ≤ 1 ms per solve for six thrusters (mss_supply: 3 azimuths and
3 tunnels; 15 variables, 57 general rows, 15 bounds). A closed-loop run of `QPAllocator` (DAQP) on a DP-like
demand (slow swings, noise, a stretch beyond capacity, a forbidden sector on the bow azimuth) records the
QP of every step; then every solver solves the same sequence of QPs in order, each warm-started and with
its problem set up once and updated in place where its Python interface allows (the factorised problem is
reused; only values change). Times are per solve including the update of the solver's data; "dev" is
the largest difference from DAQP's solution in scaled units (fraction of T_max, τ_ref). In the same run:
the independent cvxpy formulation (`reference_solve_cvxpy`, rebuilt every call as a reference is), and
`QPAllocator.allocate` (the compiled step, and the Python path around DAQP) and
`PseudoInverseAllocator.allocate` end to end, interleaved step by step.

    python bench/bench_allocation.py [--vessel mss_supply] [--steps 3000] [--cvxpy-steps 200] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from dpgw.azimuth_travel import BEFORE  # the allocation's options before the anti-hunting terms
from gateway.control.allocation import (
    PseudoInverseAllocator,
    QPAllocator,
    QPData,
    ThrusterCommand,
    reference_solve_cvxpy,
)
from observers.vessel import load_vessel

BIG = 1e3  # stands for ±inf for solvers that want finite bounds (scaled units: every |x| is O(1))


def demand(k: int, dt: float, tau_ref: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    t = k * dt
    tau = tau_ref * np.array(
        [
            0.25 * math.sin(2 * math.pi * t / 120),
            0.12 * math.cos(2 * math.pi * t / 90),
            0.05 * math.sin(t / 40),
        ]
    )
    tau += rng.normal(0.0, 0.01, 3) * tau_ref
    if 0.45 < (t % 200.0) / 200.0 < 0.5:  # a gust beyond capacity
        tau[0] += 1.5 * tau_ref[0]
    return tau


def record(allocator: QPAllocator, steps: int) -> tuple[list[QPData], list[np.ndarray], list[Any]]:
    rng = np.random.default_rng(5)
    L = allocator.layout
    prev: ThrusterCommand | None = None
    datas, taus, prevs = [], [], []
    for k in range(steps):
        tau = demand(k, allocator.dt, L.tau_ref, rng)
        datas.append(allocator.qp_data(tau, prev))
        taus.append(tau)
        prevs.append(prev)
        prev = allocator.allocate(tau, prev).command
    return datas, taus, prevs


# ---- one adapter per solver: set up on the first QP, then update values and solve ----------------------
# Each returns the solution, or None when the solver itself reports that it did not solve the QP.

Solve = Callable[[QPData], "np.ndarray | None"]


def _bounds(d: QPData) -> tuple[np.ndarray, np.ndarray]:
    m = d.A.shape[0]
    return np.concatenate((d.ub, d.b_eq, d.ub_A[3:])), np.concatenate((d.lb, d.b_eq, np.full(m - 3, -np.inf)))


def _sense(d: QPData) -> np.ndarray:
    sense = np.zeros(len(d.q) + d.A.shape[0], dtype=np.int32)
    sense[len(d.q) : len(d.q) + d.n_eq] = 5  # DAQP: equality
    return sense


def daqp_warm() -> Solve:
    import daqp

    model = daqp.Model()
    state = {"setup": False}

    def solve(d: QPData) -> np.ndarray | None:
        bu, bl = _bounds(d)
        if not state["setup"]:
            model.setup(d.P, d.q, d.A, bu, bl, _sense(d))
            state["setup"] = True
        else:
            model.update(H=d.P, A=d.A, bupper=bu, blower=bl)  # H: the turn cost follows the thrust
        x, _, flag, _ = model.solve()
        return np.asarray(x) if flag >= 1 else None

    return solve


def daqp_cold() -> Solve:
    import daqp

    def solve(d: QPData) -> np.ndarray | None:
        bu, bl = _bounds(d)
        x, _, flag, _ = daqp.solve(d.P, d.q, d.A, bu, bl, _sense(d))
        return np.asarray(x) if flag >= 1 else None

    return solve


def compiled_cold() -> Solve:
    """The allocator's own compiled solver (`gateway.control._allocation_kernel.gi_solve`) on the QP data:
    includes converting QPData to its sparse rows and allocating its work arrays each call."""
    from gateway.control import _allocation_kernel as kernel

    def solve(d: QPData) -> np.ndarray | None:
        x, status, _ = kernel.solve_qp_data(np.diag(d.P), d.q, d.A, d.b_eq, d.ub_A, d.lb, d.ub, d.n_eq)
        return x if status == kernel.OK else None

    return solve


def quadprog_cold() -> Solve:
    """Goldfarb–Idnani dual active set; no warm start. Rows C x ≥ b, equalities first, infinite rows out."""
    import quadprog

    def solve(d: QPData) -> np.ndarray | None:
        eye = np.eye(len(d.q))
        fin_a, fin_l, fin_u = np.isfinite(d.ub_A[3:]), np.isfinite(d.lb), np.isfinite(d.ub)
        C = np.vstack((d.A[:3], -d.A[3:][fin_a], eye[fin_l], -eye[fin_u]))
        b = np.concatenate((d.b_eq, -d.ub_A[3:][fin_a], d.lb[fin_l], -d.ub[fin_u]))
        try:
            return np.asarray(quadprog.solve_qp(d.P, -d.q, C.T, b, 3)[0])
        except ValueError:
            return None

    return solve


def qpsolvers_cold(solver: str) -> Solve:
    import qpsolvers

    def solve(d: QPData) -> np.ndarray | None:
        fin = np.isfinite(d.ub_A[3:])
        x = qpsolvers.solve_qp(
            d.P, d.q, d.A[3:][fin], d.ub_A[3:][fin], d.A[:3], d.b_eq, d.lb, d.ub, solver=solver
        )
        return None if x is None else np.asarray(x)

    return solve


def _sparse_pattern(datas: list[QPData]) -> np.ndarray:
    """Union of the nonzeros of [A; I] over the run (OSQP updates the values in a fixed pattern)."""
    mask = np.zeros_like(datas[0].A, dtype=bool)
    for d in datas:
        mask |= d.A != 0
    mask[: datas[0].n_eq] = True
    return np.vstack((mask, np.eye(len(datas[0].q), dtype=bool)))


def osqp_warm(datas: list[QPData], eps: float) -> Solve:
    """ADMM; set up once, then ``update(Ax=, l=, u=)`` in the fixed pattern, warm-started."""
    import osqp
    from scipy import sparse

    rows, cols = np.nonzero(_sparse_pattern(datas))
    order = np.lexsort((rows, cols))  # CSC order: by column, then row
    rows, cols = rows[order], cols[order]
    solver = osqp.OSQP()
    state = {"setup": False}

    def solve(d: QPData) -> np.ndarray | None:
        n = len(d.q)
        A = np.vstack((d.A, np.eye(n)))
        lo = np.concatenate((d.b_eq, np.full(d.A.shape[0] - 3, -np.inf), d.lb))
        hi = np.concatenate((d.b_eq, d.ub_A[3:], d.ub))
        if not state["setup"]:
            A_csc = sparse.csc_matrix((A[rows, cols], (rows, cols)), shape=A.shape)
            solver.setup(
                sparse.csc_matrix(np.triu(d.P)), d.q, A_csc, lo, hi, verbose=False, eps_abs=eps,
                eps_rel=eps, polishing=True, warm_starting=True, max_iter=20000,
            )  # fmt: skip
            state["setup"] = True
        else:
            solver.update(Px=np.diag(d.P).copy(), Ax=A[rows, cols], l=lo, u=hi)
        res = solver.solve()
        return np.asarray(res.x) if res.info.status_val == 1 else None  # 1: solved

    return solve


def clarabel_cold() -> Solve:
    """Interior point (no warm start), set up each call with the infinite rows left out. (Set up once and
    updated in place, the rows must stay, with a finite stand-in for ∞ (presolve off): on this problem
    that cost it accuracy, 3e-2 to 2e-1 off DAQP with stand-ins from 1e2 to 1e6.)"""
    import clarabel
    from scipy import sparse

    settings = clarabel.DefaultSettings()
    settings.verbose = False

    def solve(d: QPData) -> np.ndarray | None:
        n = len(d.q)
        A = np.vstack((d.A, np.eye(n), -np.eye(n)))
        b = np.concatenate((d.b_eq, d.ub_A[3:], d.ub, -d.lb))
        keep = np.isfinite(b)
        P = sparse.csc_matrix(np.triu(d.P))
        cones = [clarabel.ZeroConeT(3), clarabel.NonnegativeConeT(int(keep.sum()) - 3)]
        sol = clarabel.DefaultSolver(P, d.q, sparse.csc_matrix(A[keep]), b[keep], cones, settings).solve()
        return np.asarray(sol.x) if sol.status == clarabel.SolverStatus.Solved else None

    return solve


def proxsuite_cold(eps: float) -> Solve:
    """proxsuite 0.8.0 is set up afresh each call: its in-place ``update`` + warm start hung (past
    ``max_iter``) or crashed the process on this problem's sequence, so only the cold path is timed."""
    import proxsuite

    def solve(d: QPData) -> np.ndarray | None:
        C = d.A[3:]
        u = np.minimum(d.ub_A[3:], BIG)
        qp = proxsuite.proxqp.dense.QP(len(d.q), 3, C.shape[0], True)
        qp.settings.eps_abs = eps
        qp.settings.max_iter = 1000
        lb, ub = np.maximum(d.lb, -BIG), np.minimum(d.ub, BIG)
        qp.init(d.P, d.q, d.A[:3], d.b_eq, C, np.full(len(u), -BIG), u, lb, ub)
        qp.solve()
        ok = qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        return np.asarray(qp.results.x) if ok else None

    return solve


def piqp_update() -> Solve:
    """Proximal interior point, dense; set up once, then ``update``; default tolerances (tighter ones,
    e.g. eps_abs 1e-8 with eps_rel 0, ended at max_iter on most steps here)."""
    import piqp

    state: dict[str, Any] = {}

    def solve(d: QPData) -> np.ndarray | None:
        A_eq = np.asfortranarray(d.A[:3])
        G = np.asfortranarray(d.A[3:])
        h_u = np.minimum(d.ub_A[3:], BIG)  # unused rows: finite, or PIQP zeroes them with a warning
        if "s" not in state:
            s = piqp.DenseSolver()
            s.settings.verbose = False
            s.setup(np.asfortranarray(d.P), d.q, A_eq, d.b_eq, G, None, h_u, d.lb, d.ub)
            state["s"] = s
        else:
            state["s"].update(P=np.asfortranarray(d.P), A=A_eq, b=d.b_eq, G=G, h_u=h_u, x_l=d.lb, x_u=d.ub)
        status = state["s"].solve()
        return np.asarray(state["s"].result.x) if status == piqp.PIQP_SOLVED else None

    return solve


# ---- run -----------------------------------------------------------------------------------------------


def stats(times: list[float]) -> dict[str, float]:
    a = np.asarray(times) * 1e6
    return {"median_us": float(np.median(a)), "p99_us": float(np.percentile(a, 99)), "n": len(a)}


def run_solver(make: Callable[[], Solve], datas: list[QPData], ref: list[np.ndarray]) -> dict[str, float]:
    """Solve the sequence in order (the first QP sets the solver up and is not timed)."""
    solve = make()
    solve(datas[0])
    gc.collect()
    times, dev, failed = [], 0.0, 0
    for d, xr in zip(datas[1:], ref[1:], strict=True):
        t0 = time.perf_counter()
        x = solve(d)
        times.append(time.perf_counter() - t0)
        if x is None or not np.all(np.isfinite(x)):
            failed += 1
        else:
            dev = max(dev, float(np.max(np.abs(x - xr))))
    return stats(times) | {"dev": dev, "failed": failed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vessel", default="mss_supply")
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--cvxpy-steps", type=int, default=200, help="steps solved by the cvxpy reference")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    vessel = load_vessel(args.vessel)
    az = [t.id for t in vessel.thrusters if t.kind == "azimuth"]
    sectors = {az[-1]: [(math.radians(150), math.radians(-150))]}  # e.g. the bow azimuth's jet on the hull
    allocator = QPAllocator(vessel, forbidden_sectors=sectors)
    datas, taus, prevs = record(allocator, args.steps)

    # end to end, in the same closed loop (first: before the other solvers and cvxpy fill the heap)
    results: dict[str, dict[str, float]] = {}
    allocators: dict[str, QPAllocator | PseudoInverseAllocator] = {
        "QPAllocator.allocate, compiled (default)": QPAllocator(vessel, forbidden_sectors=sectors),
        "QPAllocator.allocate, daqp (Python path)": QPAllocator(
            vessel, forbidden_sectors=sectors, solver="daqp"
        ),
        # the same without the anti-hunting terms (turn cost on the cross force, no thrust bias): their
        # cost in time, side by side
        "QPAllocator.allocate, compiled, BEFORE (no anti-hunting)": QPAllocator(
            vessel, forbidden_sectors=sectors, **BEFORE
        ),
        "PseudoInverseAllocator.allocate": PseudoInverseAllocator(vessel),
    }
    # interleaved step by step (each fed its own previous command), so that the machine's load falls on all
    gc.collect()
    times: dict[str, list[float]] = {name: [] for name in allocators}
    prevs_e2e: dict[str, ThrusterCommand | None] = dict.fromkeys(allocators)
    saturated = dict.fromkeys(allocators, 0)
    for tau in taus:
        for name, alloc in allocators.items():
            t0 = time.perf_counter()
            res = alloc.allocate(tau, prevs_e2e[name])
            times[name].append(time.perf_counter() - t0)
            prevs_e2e[name] = res.command
            saturated[name] += res.saturated
    for name in allocators:
        results[name] = stats(times[name][1:]) | {
            "dev": math.nan,
            "failed": 0,
            "saturated_steps": saturated[name],
        }

    # DAQP's own solutions are the yardstick for the others' deviation (DAQP against cvxpy: below)
    ref_solve = daqp_cold()
    ref = [ref_solve(d) for d in datas]
    assert all(x is not None for x in ref)

    solvers: dict[str, Callable[[], Solve]] = {
        "daqp (Model: set up once, update, warm)": daqp_warm,
        "daqp (solve: cold)": daqp_cold,
        "compiled Goldfarb-Idnani (numba, cold, on QPData)": compiled_cold,
        "quadprog (cold)": quadprog_cold,
        "piqp dense (update)": piqp_update,
        "osqp (update, warm, eps 1e-6, polish)": lambda: osqp_warm(datas, 1e-6),
        "clarabel (cold)": clarabel_cold,
        "proxsuite dense (cold, eps 1e-6)": lambda: proxsuite_cold(1e-6),
        # last: importing qpsolvers loads every solver it knows, after which proxsuite 0.8.0 crashed here
        "qpsolvers -> daqp (cold)": lambda: qpsolvers_cold("daqp"),
    }
    for name, make in solvers.items():
        try:
            results[name] = run_solver(make, datas, [np.asarray(x) for x in ref])
        except Exception as exc:  # a solver that breaks is reported, not fatal
            results[name] = {"error": str(exc)[:80]}  # type: ignore[dict-item]

    n_ref = min(args.cvxpy_steps, len(datas))
    t_cvx, dev_cvx, failed_cvx = [], 0.0, 0
    gc.collect()
    scale = allocator.layout.cap[allocator.layout.owner]
    for k in np.linspace(0, len(datas) - 1, n_ref).astype(int):
        t0 = time.perf_counter()
        sol = reference_solve_cvxpy(allocator, taus[k], prevs[k])
        t_cvx.append(time.perf_counter() - t0)
        if sol.status != "optimal":
            failed_cvx += 1
            continue
        mine = allocator.solve_qp(taus[k], prevs[k])
        dev_cvx = max(dev_cvx, float(np.max(np.abs(sol.forces - mine.forces) / scale)))
    results["cvxpy formulation (Clarabel, built per call)"] = stats(t_cvx) | {
        "dev": dev_cvx,
        "failed": failed_cvx,
    }

    d0 = datas[0]
    header = (
        f"{args.vessel}: {len(vessel.thrusters)} thrusters, QP of {len(d0.q)} variables, "
        f"{d0.A.shape[0]} rows ({d0.n_eq} equalities) and {len(d0.q)} bounds; {len(datas)} closed-loop steps"
    )
    if args.json:
        print(json.dumps({"problem": header, "results": results}, indent=2))
        return
    print(header)
    print(f"{'solver':48s} {'median µs':>10s} {'p99 µs':>10s} {'dev':>9s} {'failed':>7s}")
    e2e = [k for k in results if k.endswith(".allocate") or ".allocate " in k]
    for name in [k for k in results if k not in e2e] + e2e:  # the solvers, cvxpy, then end to end
        r = results[name]
        if "error" in r:
            print(f"{name:48s} broke: {r['error']}")
            continue
        print(f"{name:48s} {r['median_us']:10.1f} {r['p99_us']:10.1f} {r['dev']:9.1e} {int(r['failed']):7d}")
    print("dev: largest |x - x_daqp| (scaled units; cvxpy: forces / T_max) over the solved steps")
    print("target: median <= 200 µs, p99 <= 1000 µs per solve")


if __name__ == "__main__":
    main()
