"""The online consequence analysis in the closed loop, on the full plant (`mss_supply_storm`: nonlinear
hull, current, gusting wind, fluid memory), checked against what the failures it predicts then do.

Two switchboards: the aft azimuths (1, 2) and the bow units (azimuth 3, tunnels 4 and 5). In this storm
the analysis says losing the aft pair leaves the rest at ~86 % (held) and losing the bow units at ~260 %
(position lost), and raises its alarm for the bow. Then each failure is made to happen in the simulator
(its drives report the fault, the gateway reallocates): the vessel holds after losing the aft pair and
is blown off after losing the bow units. The analysis predicted both.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from dpgw.closed_loop import ClosedLoopRun, gateway_tables, run_closed_loop
from simulator.faults import Fault
from simulator.scenarios import get_scenario

AFT, BOW = (1, 2), (3, 4, 5)
T_FAIL = 400.0
DURATION = 700.0


@cache
def run(lost: tuple[int, ...]) -> ClosedLoopRun:
    sc = get_scenario("mss_supply_storm")
    sc = replace(sc, faults=tuple(Fault("thruster_failure", str(i), T_FAIL) for i in lost))
    tables = gateway_tables(sc)
    tables["consequence"] = {"failure_groups": [list(AFT), list(BOW)]}
    return run_closed_loop(sc, DURATION, seed=1, tables=tables, status_every_s=10.0)


def off_station(r: ClosedLoopRun, after_s: float) -> np.ndarray:
    """Horizontal distance (m) of the true LF position from where it was at 200 s, after ``after_s``."""
    ref = r.eta_lf[np.searchsorted(r.t, 200.0)]
    keep = r.t > after_s
    return np.hypot(r.eta_lf[keep, 0] - ref[0], r.eta_lf[keep, 1] - ref[1])


def test_the_analysis_predicts_which_switchboard_loss_would_lose_the_position() -> None:
    r = run(())
    before = [s for s in r.statuses if s.get("consequence")]
    assert before, "no status carried the consequence analysis in DP"
    last = r.statuses[-1]["consequence"]
    cases = {tuple(c["lost"]): c["utilisation"] for c in last["cases"]}
    assert set(cases) == {AFT, BOW, (6,)}  # (the aft tunnel 6, on neither switchboard, is lost alone)
    assert cases[AFT] < 0.95  # held, with the margin the alarm's clearing needs
    assert cases[BOW] > 1.5  # lost, by far
    assert tuple(last["worst"]["lost"]) == BOW
    assert 0.0 < last["utilisation"] < cases[AFT]  # intact: less than after any failure
    alarms = [a for a in r.statuses[-1]["alarms"] if a.startswith("consequence analysis")]
    assert alarms == [
        f"consequence analysis: after losing thrusters 3, 4, 5 the rest would need "
        f"{100 * cases[BOW]:.0f} % of their thrust for the present load (over 100 %: position lost; the "
        "alarm clears below 95 %)"
    ]


@pytest.mark.parametrize(("lost", "held"), [(AFT, True), (BOW, False)])
def test_the_failures_do_what_the_analysis_said(lost: tuple[int, ...], held: bool) -> None:
    intact = off_station(run(()), T_FAIL)
    failed = off_station(run(lost), T_FAIL)
    if held:  # the aft pair lost: still on station, the excursions hardly larger
        assert failed.max() < 1.5 * intact.max() + 1.0, (failed.max(), intact.max())
    else:  # the bow units lost: blown off station, far beyond any watch circle
        assert failed[-1] > 50.0 and failed[-1] > 10 * intact.max(), (failed[-1], intact.max())


def test_off_when_disabled_and_outside_dp() -> None:
    sc = get_scenario("torsetnes_2004")
    off = gateway_tables(sc)
    off["consequence"] = {"enabled": False}
    r = run_closed_loop(sc, 60.0, seed=1, tables=off, status_every_s=10.0)
    assert all("consequence" not in s for s in r.statuses)
    on = run_closed_loop(sc, 60.0, seed=1, status_every_s=10.0, events=[(30.0, "mode", "standby")])
    assert any("consequence" in s for s in on.statuses if s["mode"] == "dp")
    standby = [s for s in on.statuses if s["mode"] == "standby"]
    assert standby and all("consequence" not in s for s in standby)


def test_the_config_summary_says_what_is_tested() -> None:
    from pathlib import Path

    from gateway.config import describe, parse_config

    tables = gateway_tables(get_scenario("mss_supply_storm"))
    assert "consequence analysis in dp: each thruster lost alone" in describe(
        parse_config(tables, base_dir=Path())
    )
    tables["consequence"] = {"failure_groups": [[1, 2], [3, 4, 5]]}
    text = describe(parse_config(tables, base_dir=Path()))
    assert "consequence analysis in dp: thrusters 1+2, 3+4+5 lost together; 6 alone" in text
    tables["consequence"] = {"enabled": False}
    assert "consequence analysis off" in describe(parse_config(tables, base_dir=Path()))


def test_after_the_aft_pair_is_lost_the_analysis_tests_what_is_left() -> None:
    """The pipeline hands the analysis the thrusters out of DP: with the aft pair out, its case is gone,
    the intact figure is that of the bow units and the aft tunnel 6 (in neither switchboard, so also a
    case alone), and losing the bow units too would leave the tunnel alone, which cannot push against
    the storm's surge load."""
    last = run(AFT).statuses[-1]
    assert [f"thruster {i} out of DP" in " ".join(last["alarms"]) for i in AFT] == [True, True]
    q = last["consequence"]
    assert [tuple(c["lost"]) for c in q["cases"]] == [BOW, (6,)]
    assert q["cases"][0]["utilisation"] is None  # (∞: nothing left)
    assert 0.5 < q["utilisation"] < 1.0  # what is left holds the storm's mean load, as predicted
    assert (
        "consequence analysis: after losing thrusters 3, 4, 5 the rest could not push against the present "
        "load" in last["alarms"]
    )


def test_a_failing_analysis_is_an_alarm_not_a_stopped_control_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """The analysis is a monitor: a solver that raises (HiGHS on a bad status, say) must not take the
    thruster commands with it."""
    from gateway.control import consequence

    def broken(*_: object) -> float:
        raise RuntimeError("capability LP: solver status 4")

    monkeypatch.setattr(consequence.CachedCapability, "__call__", broken)
    sc = get_scenario("torsetnes_2004")
    r = run_closed_loop(sc, 30.0, seed=1, status_every_s=10.0)
    assert len(r.command_messages) > 200  # commands at 10 Hz all along
    assert any(
        "consequence analysis: not evaluated (RuntimeError: capability LP: solver status 4)" in s["alarms"]
        for s in r.statuses
    )
