"""One case of a study: simulate once, in process, and score every observer on the same measurements.

The vessel is kept on station by the gateway's own pipeline (`dpgw.closed_loop`, typed records: no wire
encoding) with the loop observer; the pipeline's `/dp/measurement` stream — the fused y and the τ it gave
its observer, sample by sample — is kept, and every studied observer is then run over exactly that stream
(`Observer.run`, bit for bit what `step` gives live). So the observers differ and nothing else: same
waves, same sensor noise, same vessel motion.

Deterministic per seed: everything random in a case comes from the scenario's seed (the simulator's
`SeedSequence`), nothing from the process, the clock or the order cases run in; a row is the same on any
worker (tests/test_study.py). One thing of the process did change the last bits: the number of BLAS
threads (OpenBLAS splits a product differently across threads, and Dask's worker processes start with one
thread where a plain process has one per core). A case therefore always runs with one BLAS thread — the
right number anyway, with one case per core.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dpgw.study.scores import score_run
from dpgw.study.spec import CaseSpec

TOP_DOFS = ("north", "east", "heading")


def build_scenario(case: CaseSpec) -> Any:
    """The case's scenario: the named one with the case's sea state in place of its sea schedule (the
    first sea state's spectrum shape, the values the case leaves None), and a current on the full plant."""
    from simulator.current import CurrentModel
    from simulator.scenarios import get_scenario

    scenario = get_scenario(case.scenario)
    base = scenario.sea[0][1]
    sea = case.sea
    state = replace(
        base,
        hs_m=base.hs_m if sea.hs_m is None else sea.hs_m,
        tp_s=base.tp_s if sea.tp_s is None else sea.tp_s,
        direction_rad=base.direction_rad if sea.direction_deg is None else math.radians(sea.direction_deg),
    )
    scenario = replace(scenario, sea=((0.0, state),))
    if sea.current_mps:
        # the model plant has no relative velocity: a current needs the full plant (and the vessel's hull)
        current = CurrentModel(sea.current_mps, sea.current_dir_deg or 0.0)
        scenario = replace(scenario, plant="full", current=current)
    return scenario


def loop_tables(case: CaseSpec, scenario: Any, nominal_tp_s: float) -> dict[str, Any]:
    """The gateway config of the loop: the scenario's sensors; every observer tuned to the scenario's own
    (nominal) wave period — what an operator sets from the forecast — not to the case's sea state."""
    from dpgw.closed_loop import gateway_tables, with_scenario_observer
    from gateway.replay import parse_observer_spec
    from observers.factory import tuning_keys

    tables = gateway_tables(scenario)
    loop = parse_observer_spec(case.loop_observer)
    observer: dict[str, Any] = {"type": loop.name}
    if "wave_period_s" in tuning_keys(loop.name):  # (the MMAE bank takes none of the common tuning)
        observer["wave_period_s"] = nominal_tp_s
    observer.update(loop.tuning_params())
    if loop.observer_params():
        observer["params"] = loop.observer_params()
    tables["observer"] = observer
    return with_scenario_observer(tables, scenario)  # the scenario's settings under the spec's


def case_tables(case: CaseSpec, scenario: Any) -> dict[str, Any]:
    """`loop_tables` of ``case`` on ``scenario``: the observers tuned to the named scenario's own wave
    period, whatever sea the case runs."""
    from simulator.scenarios import get_scenario

    return loop_tables(case, scenario, get_scenario(case.scenario).sea[0][1].tp_s)


def case_observers(case: CaseSpec, scenario: Any, tables: dict[str, Any]) -> list[tuple[str, Any, Any]]:
    """``case``'s observers as its scores run them, each ``(spec text, ObserverSpec, Observer)``: the
    config of ``tables``, the scenario's observer settings under each spec's own."""
    from gateway.config import parse_config
    from gateway.replay import parse_observer_spec

    config = parse_config(tables, base_dir=Path.cwd())
    out = []
    for text in case.observers:
        spec = parse_observer_spec(text)
        out.append((text, spec, spec.make(config, scenario.observer_params.get(spec.name))))
    return out


def settle_times(case: CaseSpec) -> dict[str, float]:
    """Each of ``case``'s observers' settle time (s, `Observer.settle_time_s`: its slowest error mode's, or
    for the MMAE its bank's identification too), built as `score_case` builds it, before any run: a study
    that scores an observer from before it settles is said before it runs (`outputs.unsettled_warnings`).
    """
    scenario = build_scenario(case)
    observers = case_observers(case, scenario, case_tables(case, scenario))
    return {spec.label: float(obs.settle_time_s) for _, spec, obs in observers}


def direction_deg(direction_rad: float) -> float:
    """The sea's direction for the table, in degrees [0, 360): the scenario's 150° (stored in radians) is
    150.0, not 150.00000000000003, so that a table filtered on the degrees it was given finds its rows.
    Rounded to 1e-9° (the radians' round trip is off by ~1e-14°)."""
    return round(math.degrees(direction_rad) % 360.0, 9) % 360.0


def run_case(case_dict: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows (one per observer spec) of one case, given as `CaseSpec.as_dict` (what a Dask worker gets)."""
    from threadpoolctl import threadpool_limits

    _load_numerics()
    with threadpool_limits(limits=1, user_api="blas"):
        return _run_case(CaseSpec.from_dict(case_dict))


def _load_numerics() -> None:
    """Import every library a case may call into before the BLAS threads are limited: threadpoolctl limits
    the BLAS libraries loaded when it is called, and scipy brings its own OpenBLAS (loaded with
    scipy.linalg, which an observer module may import only when it is built). Without this, the first case
    in a process ran scipy's products on all threads and differed from the next in the last bits."""
    import importlib

    import scipy.linalg  # noqa: F401

    from observers.factory import OBSERVERS

    for entry in OBSERVERS.values():
        importlib.import_module(entry.target.partition(":")[0])


def _run_case(case: CaseSpec) -> list[dict[str, Any]]:
    return score_case(case, build_scenario(case))


def score_case(case: CaseSpec, scenario: Any) -> list[dict[str, Any]]:
    """Rows of ``case`` run on ``scenario`` (`build_scenario`'s, or a variant of it: a plant option
    switched off to see what it changes); the observers tuned to the named scenario's own wave period."""
    from dpgw.closed_loop import run_closed_loop
    from gateway.report import ObserverTrace, ReplayData, compute_metrics
    from observers.base import STATUS_INITIALIZING
    from simulator.clock import SimEpoch
    from wire.messages import Measurement

    tables = case_tables(case, scenario)
    loop = run_closed_loop(
        scenario, case.duration_s, seed=case.seed, tables=tables, collect=("/dp/measurement",)
    )

    # the pipeline's measurements on the simulator's clock (sim time 0 = the epoch)
    start_ns = SimEpoch(scenario.start_utc).stamp_ns(0.0)
    meas = [m for m in loop.collected_messages["/dp/measurement"] if isinstance(m, Measurement)]
    t = np.array([(m.stamp_ns - start_ns) / 1e9 for m in meas])
    y = np.array([[math.nan if v is None else v for v in m.eta] for m in meas], dtype=float)
    tau = np.array([m.tau for m in meas], dtype=float)

    sea = scenario.sea[0][1]
    omega_p = 2.0 * math.pi / sea.tp_s
    rows: list[dict[str, Any]] = []
    traces = []
    for text, spec, observer in case_observers(case, scenario, tables):
        run = observer.run(t, y, tau)
        ok = run.status != STATUS_INITIALIZING
        te = run.t[ok]
        row: dict[str, Any] = {
            "scenario": case.scenario,
            "sea": case.sea.label,
            "hs_m": sea.hs_m,
            "tp_s": sea.tp_s,
            "direction_deg": direction_deg(sea.direction_rad),
            "current_mps": case.sea.current_mps or 0.0,
            "seed": case.seed,
            "observer": spec.label,
            "observer_spec": text,
            "duration_s": case.duration_s,
            "settle_s": case.settle_s,
            "samples": int(np.count_nonzero(te >= case.settle_s)),
        }
        row.update(
            score_run(
                te, run.eta[ok], run.nu[ok], run.bias[ok], run.omega0[ok],
                loop.t, loop.eta_lf, loop.nu, loop.bias, case.settle_s, omega_p,
            )
        )  # fmt: skip
        rows.append(row)
        traces.append(
            ObserverTrace(
                spec.label, te, run.eta[ok], run.nu[ok], run.bias[ok], run.eta_wf[ok], run.omega0[ok]
            )
        )
    # the wave-band attenuation of every observer from the same measurement spectrum (the replay report's)
    metrics = compute_metrics(
        ReplayData(scenario.name, scenario.vessel.name, t, y, tuple(traces)),
        settle_s=max(0.0, case.settle_s - float(t[0])) if len(t) else None,
    )
    for row, trace in zip(rows, traces, strict=True):
        per = metrics["observers"][trace.label]
        for dof in TOP_DOFS:
            att = per[dof]["attenuation_db"]
            row[f"att_{dof}_db"] = math.nan if att is None else float(att)
    return rows
