"""The estimate says when the observer has settled, and DP does not engage cold on its own.

`Observer.settle_time_s` (`observers.settling`: 1.5 time constants of the slowest error mode) after the
observer's first estimate the gateway's `/dp/estimate` says ``settled``; with ``[control] initial_mode =
"dp"`` the gateway holds standby until then and engages by itself (``wait_for_observer``, default on); an
operator's ``dp`` before that is honoured and alarmed. In the closed loop on torsetnes_2004 (Hs 6 m) DP
engaged on the settled estimate keeps the vessel within ~1.3 m / 1° where DP from the first estimate
drifted 7 m / 9° (docs/gateway.md, "Waiting for the observer").
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dpgw.cli_demo import engage_time
from dpgw.closed_loop import ClosedLoopRun, gateway_tables, run_closed_loop, with_scenario_observer
from gateway.config import ConfigError, describe, parse_config
from gateway.pipeline import PipelineSpec
from observers.factory import OBSERVERS, make_observer
from observers.passive_tuning import slowest_error_rate
from observers.settling import ENGAGE_TIME_CONSTANTS, UNKNOWN_SETTLE_S
from observers.vessel import load_vessel
from simulator.clock import SimEpoch
from simulator.scenarios import get_scenario

SCENARIO = get_scenario("torsetnes_2004")
SAMPLE_S = 0.1  # the gyro's interval: the observer steps at least this often


def settle_s(observer: str = "passive", scenario: Any = SCENARIO) -> float:
    """The settle time of the observer the closed loop runs for ``scenario``."""
    tables = gateway_tables(scenario)
    tables["observer"] = {**tables["observer"], "type": observer}
    spec = PipelineSpec.from_config(
        parse_config(with_scenario_observer(tables, scenario), base_dir=Path.cwd())
    )
    return float(spec.observer.settle_time_s)


EPOCH_NS = SimEpoch(SCENARIO.start_utc).stamp_ns(0.0)  # sim time 0


def rel_s(run: ClosedLoopRun, stamp_ns: int) -> float:
    """Sim seconds of a stamp."""
    return (stamp_ns - EPOCH_NS) / 1e9


def flip_time(run: ClosedLoopRun) -> tuple[float, float]:
    """(time of the first estimate, time of the first estimate that says settled), sim seconds."""
    est = run.estimate_messages
    first = next(e for e in est if e.settled)
    return rel_s(run, est[0].stamp_ns), rel_s(run, first.stamp_ns)


# --- each observer knows its settle time --------------------------------------------------------------------


def test_the_passive_settle_time_is_the_demos_engagement_time() -> None:
    """One definition: 1.5 time constants of the slowest error mode, the demo's engagement time (145 s on
    its default scenario, as before the definition moved out of the CLI)."""
    tables = with_scenario_observer(gateway_tables(SCENARIO), SCENARIO)
    observer = PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())).observer
    rate = slowest_error_rate(observer.vessel, observer.gains)  # type: ignore[attr-defined]
    assert observer.settle_time_s == pytest.approx(ENGAGE_TIME_CONSTANTS / -rate, rel=1e-12)
    assert 140.0 < observer.settle_time_s < 150.0  # ~96 s time constant

    class Args:
        engage_at = None

    # (the demo waits from there for the gateway to call the estimate settled: no rounding to the second)
    assert engage_time(Args(), observer) == observer.settle_time_s
    assert math.ceil(observer.settle_time_s) == 145


@pytest.mark.parametrize("name", list(OBSERVERS))
def test_every_observer_derives_a_finite_settle_time(name: str) -> None:
    """Each registered observer gives a figure from its own model (none falls back to the conservative
    value for an observer that cannot say), positive and below an hour."""
    settle = make_observer(name, load_vessel("mss_supply")).settle_time_s
    assert math.isfinite(settle) and 5.0 < settle < 3600.0
    assert settle != UNKNOWN_SETTLE_S


def test_the_sdre_settle_time_is_its_bias_pole() -> None:
    """docs/sdre.md: the slowest error pole −0.056 s⁻¹ for snijders_ship at ω0 = 2π/12 s (−0.052 for
    mss_supply), the bias: 1.5 / 0.056 ≈ 27 s."""
    from observers.sdre import SdreObserver
    from observers.sdre_tuning import SdreTuning

    v = load_vessel("snijders_ship")
    obs = SdreObserver(v, SdreTuning(omega0=2 * math.pi / 12))
    assert obs.settle_time_s == pytest.approx(1.5 / 0.0565, rel=0.03)


# --- the message says it ------------------------------------------------------------------------------------


@pytest.mark.parametrize("observer", ["passive", "sdre"])
def test_settled_flips_at_the_computed_time(observer: str) -> None:
    expected = settle_s(observer)
    tables = gateway_tables(SCENARIO)
    tables["observer"] = {**tables["observer"], "type": observer}
    run = run_closed_loop(SCENARIO, expected + 5.0, tables=tables, status_every_s=1.0)
    first, flipped = flip_time(run)
    assert abs(flipped - (first + expected)) <= SAMPLE_S + 1e-6, (first, flipped, expected)
    est = run.estimate_messages
    # before: not settled, the seconds left counting down to it; after: settled, none left
    before = [e for e in est if not e.settled]
    assert before and all(e.settle_s_left is not None and e.settle_s_left > 0 for e in before)
    left = [rel_s(run, e.stamp_ns) + e.settle_s_left for e in before]  # type: ignore[operator]
    assert max(left) - min(left) < 1e-6 and left[0] == pytest.approx(first + expected, abs=1e-6)
    assert all(e.settled and e.settle_s_left == 0.0 for e in est if rel_s(run, e.stamp_ns) >= flipped)
    # in the JSON for every consumer, and the status word's contract unchanged (ok from the start)
    assert est[0].to_dict()["settled"] is False and est[-1].to_dict()["settled"] is True
    assert est[0].status == "ok"
    # DP from the first estimate here (wait_for_observer = false): a notice until settled, then none
    notice = "DP from the first estimate (control.wait_for_observer = false): estimate settling"
    for s in run.statuses:
        t = rel_s(run, s["stamp_ns"])
        if first < t < flipped:
            assert any(notice in a for a in s["alarms"]), (t, s["alarms"])
        elif t > flipped:
            assert not any("settl" in a for a in s["alarms"]), (t, s["alarms"])


# --- DP waits ------------------------------------------------------------------------------------------


def waiting_run(duration_s: float, events: list[tuple[float, str, Any]] = ()) -> ClosedLoopRun:  # type: ignore[assignment]
    """The closed loop as `dpgw run` starts with initial_mode = "dp" (waiting for the observer) on a vessel
    held on joystick until the gateway commands, every status kept."""
    return run_closed_loop(
        SCENARIO,
        duration_s,
        tables=gateway_tables(SCENARIO, wait_for_observer=True),
        hold_on_joystick=True,
        events=events,
        collect=("/dp/status",),
        status_every_s=1.0,
    )


def statuses(run: ClosedLoopRun) -> list[tuple[float, dict[str, Any]]]:
    """Every status, in time: those made at once for an event and the periodic ones (1 Hz)."""
    every = run.collected["/dp/status"] + run.statuses
    return sorted(((rel_s(run, s["stamp_ns"]), s) for s in every), key=lambda ts: ts[0])


def events_said(run: ClosedLoopRun, text: str) -> list[float]:
    return [t for t, s in statuses(run) for e in s.get("events", []) if text in e]


def test_initial_dp_holds_standby_until_the_observer_has_settled_then_engages() -> None:
    settle = settle_s()
    run = waiting_run(settle + 40.0)
    _, flipped = flip_time(run)
    # no command while waiting; the first at the first control step after the flip
    engaged = rel_s(run, run.command_messages[0].stamp_ns)
    assert flipped <= engaged <= flipped + SAMPLE_S + 1e-6, (flipped, engaged)
    assert all(c.mode == "dp" for c in run.command_messages)
    # said once, at start and at the engagement; a notice in /dp/status while waiting, gone once engaged
    assert len(events_said(run, "standby until the observer has settled")) == 1
    assert events_said(run, "observer settled: DP engaged") == [pytest.approx(engaged, abs=1e-6)]
    waiting = [(t, s) for t, s in statuses(run) if t < flipped]
    after = [(t, s) for t, s in statuses(run) if t > engaged]
    assert waiting and after
    assert all(s["mode"] == "standby" for _, s in waiting)
    assert all(any("DP waits for the observer to settle" in a for a in s["alarms"]) for _, s in waiting)
    assert all(s["mode"] == "dp" for _, s in after)
    assert not [a for _, s in after for a in s["alarms"] if "settl" in a]
    # bumpless: the first command continues the thrust the vessel was held with (its τ within 10 % of the
    # load's scale), and the vessel stays near its station after the take-over
    tau0 = np.array(run.command_messages[0].tau_allocated)
    held = np.array(run.command_messages[5].tau_allocated)
    assert np.all(np.abs(tau0 - held) <= 0.1 * np.abs(held).max())
    k = (run.t >= engaged) & (run.t <= engaged + 30.0)
    assert np.hypot(*(run.eta_lf[k, :2] - np.array(SCENARIO.eta0[:2])).T).max() < 2.0


def test_an_operators_early_dp_is_honoured_and_alarmed_until_settled() -> None:
    settle = settle_s()
    run = waiting_run(settle + 10.0, events=[(30.0, "mode", "dp")])
    engaged = rel_s(run, run.command_messages[0].stamp_ns)
    # the operator decides: DP at once (the loop feeds an input after the chunk of sea it came in)
    assert 30.0 - 0.1 <= engaged <= 30.0 + SAMPLE_S
    _, flipped = flip_time(run)
    said = events_said(run, "DP engaged by the operator before the observer settled")
    assert len(said) == 1 and said[0] < flipped
    early = [s for t, s in statuses(run) if engaged < t < flipped]
    assert early and all(
        any("DP engaged before the observer settled" in a for a in s["alarms"]) for s in early
    )
    assert all(not any("DP waits" in a for a in s["alarms"]) for s in early)  # the wait ended
    later = [s for t, s in statuses(run) if t > flipped]
    assert later and not [a for s in later for a in s["alarms"] if "settl" in a]  # cleared once settled
    assert not events_said(run, "observer settled: DP engaged")  # no second engagement


def test_an_operators_standby_ends_the_wait() -> None:
    run = waiting_run(settle_s() + 10.0, events=[(20.0, "mode", "standby")])
    assert not run.command_messages  # never engaged by itself
    assert len(events_said(run, "DP no longer waits for the observer: the operator chose standby")) == 1


def test_waiting_for_the_observer_removes_the_cold_start_transient() -> None:
    """torsetnes_2004 (Hs 6 m, seed 0), the true LF motion over the 180 s after DP was engaged, against
    the station: DP from the first estimate (vessel not held: the HIL trial's start) drifted 7.3 m / 9.4°
    with 12 % of its commands saturated in the first minute; from the first estimate on a vessel held on
    joystick 5.0 m / 3.0° (the integrator took the load while the bias estimate grew and gives it back);
    engaged by itself once the observer settled, 1.3 m / 1.0°, none saturated."""

    def after_engagement(run: ClosedLoopRun, window_s: float = 180.0) -> tuple[float, float, float]:
        engaged = rel_s(run, run.command_messages[0].stamp_ns)
        k = (run.t >= engaged) & (run.t <= engaged + window_s)
        e = run.eta_lf[k] - np.array(SCENARIO.eta0)
        hdg = np.degrees(np.abs((e[:, 2] + math.pi) % (2 * math.pi) - math.pi))
        first_minute = [c for c in run.command_messages if rel_s(run, c.stamp_ns) <= engaged + 60.0]
        saturated = float(np.mean([c.saturated for c in first_minute]))
        return float(np.percentile(np.hypot(e[:, 0], e[:, 1]), 95)), float(np.percentile(hdg, 95)), saturated

    settle = settle_s()
    cold = after_engagement(run_closed_loop(SCENARIO, 185.0))
    cold_held = after_engagement(run_closed_loop(SCENARIO, 185.0, hold_on_joystick=True))
    waited = after_engagement(waiting_run(settle + 185.0))
    assert cold[0] > 5.0 and cold[1] > 6.0 and cold[2] > 0.05, cold
    assert waited[0] < 2.0 and waited[1] < 1.5 and waited[2] == 0.0, waited
    # waiting is what removes it: a held vessel engaged at once still has the transient
    assert waited[0] < cold_held[0] / 2.5 and waited[1] < cold_held[1] / 2.0, (waited, cold_held)


# --- the option ----------------------------------------------------------------------------------------


def test_wait_for_observer_is_on_by_default_and_must_be_a_boolean() -> None:
    tables = gateway_tables(SCENARIO)
    del tables["control"]["wait_for_observer"]
    config = parse_config(tables, base_dir=Path.cwd())
    assert config.control is not None and config.control.wait_for_observer is True
    # `dpgw run --check` says how DP starts
    assert "control: starts in standby, DP by itself once the observer has settled" in describe(config)
    tables["control"]["wait_for_observer"] = False
    assert "control: DP from the first estimate" in describe(parse_config(tables, base_dir=Path.cwd()))
    tables["control"]["wait_for_observer"] = "yes"
    with pytest.raises(ConfigError, match="wait_for_observer"):
        parse_config(tables, base_dir=Path.cwd())


# --- an observer restart while in DP ------------------------------------------------------------------------


def test_an_observer_restarted_in_dp_keeps_dp_and_settles_again() -> None:
    """Every reference silent past ``lost_after_s`` (30 s), then back: the observer restarts whole (bias
    from zero). DP is kept — standby would leave the thrusters to no one — and the estimate is unsettled
    again for its settle time, said once and alarmed until then."""
    from tests.test_integrity import Bench

    b = Bench(control=True)
    settle = b.p.observer.settle_time_s
    b.run(settle + 5.0)
    assert b.p.settled and b.p.mode == "dp"
    assert not [a for a in b.p.status_message(b.now).alarms if "settl" in str(a)]
    b.run(35.0, gps={"gps1": None}, gyro={"gyro1": None})
    m = b.mark()
    b.run(5.0)
    # (the gyro's sample comes first and restarts all, the DGPS's then restarts the position)
    assert b.p.restarts >= 1 and b.p.mode == "dp" and not b.p.settled
    restart_ns = b.first_event(m, "DP kept on the restarted observer")
    assert restart_ns is not None
    assert any(
        "observer restarted in DP: estimate settling" in str(a) for a in b.p.status_message(b.now).alarms
    )
    est = b.estimates(m)
    assert est and not est[-1]["settled"]
    assert est[-1]["settle_s_left"] == pytest.approx(settle - 5.0, abs=0.2)
    b.run(settle - 5.0 + 0.3)
    assert b.p.settled and b.p.mode == "dp"
    assert not [a for a in b.p.status_message(b.now).alarms if "settl" in str(a)]


@pytest.mark.parametrize(("flags", "mode"), [([], "standby"), (["--engage-at", "0"], "dp")])
def test_the_demo_engages_dp_itself_and_never_waits_twice(flags: list[str], mode: str) -> None:
    """`dpgw demo` starts the gateway in standby and switches to dp at the settle time (its operator), or,
    with ``--engage-at 0``, in dp from the first estimate as asked: never a gateway waiting on its own."""
    import argparse

    from dpgw import cli_demo
    from gateway.pipeline import Pipeline

    p = argparse.ArgumentParser()
    cli_demo.add_arguments(p)
    args = p.parse_args(["--out", "x.mcap", *flags])
    tables = cli_demo.demo_config(SCENARIO, "/dev/null", args)
    pipeline = Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))
    assert pipeline.mode == mode and not pipeline.waiting_for_observer


def test_a_replay_starts_dp_as_the_logged_gateway_did() -> None:
    """A log records the option with initial_mode = "dp" (its default written out), and a log from before
    the option — a gateway that engaged DP at its first estimate — is replayed so, not with the wait."""
    from gateway.config.logged import for_log
    from gateway.replay import _as_replayed

    tables = gateway_tables(SCENARIO)
    del tables["control"]["wait_for_observer"]
    logged = for_log(tables)
    assert logged["control"]["wait_for_observer"] is True  # the live gateway's default, recorded
    assert "wait_for_observer" not in tables["control"]  # (the caller's tables untouched)
    assert _as_replayed(logged)["control"]["wait_for_observer"] is True
    assert _as_replayed(tables)["control"]["wait_for_observer"] is False  # an older log
    standby = {**tables, "control": {"initial_mode": "standby"}}
    assert "wait_for_observer" not in for_log(standby)["control"]
    assert "wait_for_observer" not in _as_replayed(standby)["control"]


@pytest.mark.parametrize(("observer", "restarts"), [("mmae", 1), ("passive", 0)])
def test_a_silence_longer_than_the_observer_bridges_is_a_restart_the_gateway_sees(
    observer: str, restarts: int
) -> None:
    """The MMAE bank starts again by itself after a gap longer than its ``max_gap_s`` (60 s). With
    ``lost_after_s`` longer than that (120 s here), a 70 s silence must end in a restart the gateway makes
    and announces — counted, said, and the settle clock started again — not one the observer makes unseen
    while the gateway calls its estimate settled. The passive observer bridges any gap: the same silence,
    on a vessel that stayed put, is carried on from (its fixes return inside the prediction gate after the
    confirmation time) without a whole restart."""
    from tests.test_integrity import Bench

    b = Bench(observer=observer, integrity={"lost_after_s": 120.0})
    b.run(b.p.observer.settle_time_s + 2.0)
    assert b.p.settled and b.p.restarts == 0
    b.run(70.0, gps={"gps1": None}, gyro={"gyro1": None})
    m = b.mark()
    b.run(3.0)
    said = b.first_event(m, "nothing stepped the observer for 70 s (it bridges at most 60 s: max_gap_s)")
    assert b.p.restarts == restarts
    assert (said is not None) == bool(restarts)
    if restarts:
        assert not b.p.settled
        assert b.estimates(m)[-1]["settle_s_left"] == pytest.approx(b.p.observer.settle_time_s - 3.0, abs=0.2)
