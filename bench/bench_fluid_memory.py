"""Fluid memory in the plant: what stepping the memory states costs, and the figures of its energy.

Speed, side by side in one run (the machine is shared; ratios are what to read), per plant step of
0.05 s (simulator.vessel_dynamics.MAX_STEP_S) for the ``mss_supply`` model (17 states):

- ``plant RK4``: today's plant step (simulator.vessel_dynamics._rk4, 6 states), the baseline;
- ``plant RK4 + memory``: the same step with the memory states carried in the RK4 state (x_r' = A x_r +
  B ν and -μ = -(C x_r + D ν) in the force at each of the four stages, as the nonlinear plant will);
- ``memory, exact step``: the compiled first-order-hold step alone (`memory_step` + `memory_force`);
- ``memory, numpy reference``: the same in numpy (what a plant without the kernel would pay);
- ``CumminsMemory.step``: the Python object's step (what a test or a script pays).

Then the share of the simulator's budget at 360× real time (2.78 ms of wall time per simulated second, 20
plant steps) the memory takes. With ``--plots DIR``: K(t) from eq (5) on the data against the model's
C e^{At} B per element, and the free-decay energy curves (needs matplotlib and the hydrodynamic data).

    python bench/bench_fluid_memory.py [--steps 200000] [--plots DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from simulator import _fluid_memory_kernel as kern
from simulator.fluid_memory import CumminsMemory, RadiationStateSpace
from simulator.fluid_memory_cache import load_fluid_memory
from simulator.hydro_data import builtin_hydro
from simulator.vessel_dynamics import MAX_STEP_S, _derivative, _rk4

REPO = Path(__file__).resolve().parents[1]
HYDRO = builtin_hydro("mss_supply")  # the shipped ShipX/VERES data
assert HYDRO is not None
H = MAX_STEP_S
BUDGET_360X = 1.0 / 360.0
"""Wall seconds per simulated second at 360× real time."""


@njit(cache=True)
def _rk4_with_memory(x, xr, h, tau, minv, d, a, b, c, dm):  # type: ignore[no-untyped-def]
    """One RK4 step of [η, ν] and the memory states x_r together: force τ - μ, μ = C x_r + D_m ν.
    (Kinematics and linear damping as today's plant; the nonlinear plant adds its own terms.)"""
    n = xr.shape[0]
    k = np.empty((4, 6))
    kr = np.empty((4, n))
    xt = np.empty(6)
    xrt = np.empty(n)
    f = np.empty(3)
    mu = np.empty(3)
    nu = np.empty(3)
    for stage in range(4):
        w = 0.0 if stage == 0 else (h if stage == 3 else 0.5 * h)
        for j in range(6):
            xt[j] = x[j] + (w * k[stage - 1, j] if stage else 0.0)
        for j in range(n):
            xrt[j] = xr[j] + (w * kr[stage - 1, j] if stage else 0.0)
        for j in range(3):
            nu[j] = xt[3 + j]
        kern.memory_force(xrt, nu, c, dm, mu)
        for j in range(3):
            f[j] = tau[j] - mu[j]
        _derivative(xt, f, minv, d, k[stage])
        kern.memory_derivative(xrt, nu, a, b, kr[stage])
    for j in range(6):
        x[j] += h / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
    for j in range(n):
        xr[j] += h / 6.0 * (kr[0, j] + 2.0 * kr[1, j] + 2.0 * kr[2, j] + kr[3, j])


def _per_step(fn, steps: int) -> float:  # type: ignore[no-untyped-def]
    """Best of 3 runs of ``steps`` calls, seconds per call."""
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        fn(steps)
        best = min(best, time.perf_counter() - t0)
    return best / steps


def speed(model: RadiationStateSpace, steps: int) -> dict[str, float]:
    from observers.vessel import load_vessel

    vessel = load_vessel("mss_supply")
    minv = np.ascontiguousarray(vessel.Minv)  # the cost is the same with M_RB + A(∞)
    d = np.ascontiguousarray(vessel.D)
    a, b, c, dm = (np.ascontiguousarray(m) for m in (model.Ar, model.Br, model.Cr, model.Dr))
    phi, g0, g1 = model.discretise(H)
    tau = np.array([1e4, 2e4, 1e5])
    zero = np.zeros(3)
    x = np.zeros(6)
    xr = np.zeros(model.n_states)
    out = np.empty_like(xr)
    mu = np.empty(3)
    nu0, nu1 = np.array([0.3, 0.1, 0.001]), np.array([0.31, 0.09, 0.0011])

    @njit(cache=False)
    def plant(n, x, tau, zero, minv, d):  # type: ignore[no-untyped-def]
        for _ in range(n):
            _rk4(x, H, tau, zero, minv, d)

    @njit(cache=False)
    def plant_memory(n, x, xr, tau, minv, d, a, b, c, dm):  # type: ignore[no-untyped-def]
        for _ in range(n):
            _rk4_with_memory(x, xr, H, tau, minv, d, a, b, c, dm)

    @njit(cache=False)
    def exact(n, xr, out, nu0, nu1, phi, g0, g1, c, dm, mu):  # type: ignore[no-untyped-def]
        for _ in range(n):
            kern.memory_step(xr, nu0, nu1, phi, g0, g1, out)
            kern.memory_force(out, nu1, c, dm, mu)
            xr[:] = out

    def reference(n: int) -> None:
        xx = xr
        for _ in range(n):
            xx = kern.memory_step_reference(xx, nu0, nu1, phi, g0, g1)
            kern.memory_force_reference(xx, nu1, c, dm)

    mem = CumminsMemory(model)

    def wrapped(n: int) -> None:
        for _ in range(n):
            mem.step(H, nu0, nu1)

    plant(10, x, tau, zero, minv, d)  # compile outside the timing
    plant_memory(10, x, xr, tau, minv, d, a, b, c, dm)
    exact(10, xr, out, nu0, nu1, phi, g0, g1, c, dm, mu)
    return {
        "plant RK4": _per_step(lambda n: plant(n, x, tau, zero, minv, d), steps),
        "plant RK4 + memory": _per_step(lambda n: plant_memory(n, x, xr, tau, minv, d, a, b, c, dm), steps),
        "memory, exact step": _per_step(lambda n: exact(n, xr, out, nu0, nu1, phi, g0, g1, c, dm, mu), steps),
        "memory, numpy reference": _per_step(reference, max(1000, steps // 50)),
        "CumminsMemory.step": _per_step(wrapped, max(1000, steps // 50)),
    }


def plots(model: RadiationStateSpace, directory: Path) -> None:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        sys.exit("--plots needs matplotlib (pip install 'dpgw[plot]')")
    from observers import radiation as rad
    from simulator import fluid_memory_energy as energy
    from wire.hydro import load_hydro

    if not HYDRO.is_file():
        sys.exit(f"{HYDRO}: no such file (the plots compare with the data)")
    hydro = load_hydro(HYDRO)
    directory.mkdir(parents=True, exist_ok=True)
    idx = [0, 1, 5]
    t = np.linspace(0.0, 60.0, 601)
    b = hydro.B[np.ix_(idx, idx)]
    k5 = rad.retardation_from_damping(hydro.freqs, 0.5 * (b + b.transpose(1, 0, 2)), t, tail=True)
    kss = model.impulse_response(t)
    fig = Figure(figsize=(12, 3.4), layout="constrained")
    for ax, (i, j, name) in zip(
        fig.subplots(1, 4), [(0, 0, "K11"), (1, 1, "K22"), (2, 2, "K66"), (1, 2, "K26")], strict=True
    ):
        ax.plot(t, k5[i, j], "k", lw=2.5, alpha=0.4, label="eq (5) on B(ω) (+ω⁻² tail)")
        ax.plot(t, kss[:, i, j], "C0", label="C e^{At} B (shipped model)")
        ax.set(xlabel="t (s)", title=name)
        ax.grid(True, alpha=0.3)
    fig.axes[0].legend(fontsize=8)
    fig.savefig(directory / "fluid_memory_kernels.png", dpi=110)
    m_rb = model.M_RB if model.M_RB is not None else hydro.MRB[np.ix_(idx, idx)]
    v = energy.storage_function(model)
    td = np.arange(0.0, 200.0, 0.1)
    fig = Figure(figsize=(12, 3.4), layout="constrained")
    for ax, nu0 in zip(fig.subplots(1, 3), [(1.0, 0, 0), (0, 1.0, 0), (0, 0, 0.02)], strict=True):
        fd = energy.free_decay(model, m_rb, nu0, td)
        e0 = fd.kinetic[0]
        ax.plot(td, fd.kinetic / e0, "C0", label="kinetic ½νᵀ(M_RB+A∞)ν")
        ax.plot(td, v(fd.x) / e0, "C1", label="stored in the memory V(x)")
        ax.plot(td, (fd.kinetic + v(fd.x)) / e0, "k", label="total (never grows)")
        ax.set(xlabel="t (s)", ylabel="energy / initial", title=f"free decay from ν₀ = {nu0}")
        ax.grid(True, alpha=0.3)
    fig.axes[0].legend(fontsize=8)
    fig.savefig(directory / "fluid_memory_free_decay.png", dpi=110)
    print(f"wrote {directory / 'fluid_memory_kernels.png'} and {directory / 'fluid_memory_free_decay.png'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=200_000, help="plant steps per timing (best of 3)")
    ap.add_argument("--plots", type=Path, help="directory for the figures")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    model = load_fluid_memory("mss_supply")
    times = speed(model, args.steps)
    base = times["plant RK4"]
    added = times["plant RK4 + memory"] - base
    share = added / H / BUDGET_360X  # wall per simulated second / budget
    if args.json:
        print(json.dumps({"seconds_per_step": times, "memory_share_of_360x_budget": share}, indent=2))
    else:
        print(f"mss_supply fluid memory: {model.n_states} states; per plant step of {H} s (best of 3)")
        for name, s in times.items():
            print(f"  {name:26s} {s * 1e9:9.0f} ns   {s / base:6.2f}× plant RK4")
        print(
            f"memory in the RK4 state adds {added * 1e9:.0f} ns per step = {added / H * 1e6:.1f} µs per "
            f"simulated second: {100 * share:.2f} % of the 360× budget ({BUDGET_360X * 1e3:.2f} ms)"
        )
    if args.plots:
        plots(model, args.plots)


if __name__ == "__main__":
    main()
