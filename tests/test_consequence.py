"""The online consequence analysis's logic (`gateway.control.consequence`): the load it tests, the failure
cases, when it tests them and its alarm's hysteresis.

Its verdicts come from `capability.attainable_scale`, tested on its own (tests/test_capability.py). Here
the attainable set is a box, each thruster adding capacity per degree of freedom, so that every expected
utilisation is a sum and a division."""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np
import pytest

from gateway.control.consequence import ConsequenceAnalysis
from observers.vessel import Thruster

# capacity per thruster and DOF [X, Y, N], for the box model below
CAP = {1: (100.0, 50.0, 1000.0), 2: (100.0, 50.0, 1000.0), 3: (0.0, 100.0, 3000.0)}
THRUSTERS = [Thruster(id=i, kind="azimuth", x_m=10.0 * i, y_m=0.0, max_thrust_n=100.0) for i in CAP]


def box(thrusters: Sequence[Thruster], tau: np.ndarray, failed: Collection[int]) -> float:
    box.calls += 1  # type: ignore[attr-defined]
    cap = np.sum([CAP[t.id] for t in thrusters if t.id not in failed] or [np.zeros(3)], axis=0)
    with np.errstate(divide="ignore"):
        ks = [c / abs(x) if x else math.inf for c, x in zip(cap, tau, strict=True)]
    return float(min(ks))


box.calls = 0  # type: ignore[attr-defined]


def analysis(**kw: object) -> ConsequenceAnalysis:
    return ConsequenceAnalysis(THRUSTERS, box, **kw)  # type: ignore[arg-type]


def test_each_thruster_alone_is_a_failure_case_and_the_worst_is_the_highest_utilisation() -> None:
    ca = analysis()
    v = ca.update(0.0, [50.0, 60.0, 0.0])
    assert v is not None
    assert v.intact == pytest.approx(max(50 / 200, 60 / 200))
    by_lost = {c.lost: c.utilisation for c in v.cases}
    assert by_lost == {(1,): pytest.approx(0.5), (2,): pytest.approx(0.5), (3,): pytest.approx(0.6)}
    assert v.worst is not None and v.worst.lost == (3,) and v.worst.holds
    assert not ca.alarm and ca.alarm_text() is None


def test_a_failure_group_loses_its_thrusters_together() -> None:
    ca = analysis(failure_groups=[[1, 2], [3]])
    v = ca.update(0.0, [20.0, 60.0, 0.0])
    assert v is not None
    assert {c.lost: c.utilisation for c in v.cases} == {(1, 2): math.inf, (3,): pytest.approx(0.6)}
    assert v.worst is not None and v.worst.lost == (1, 2)
    assert ca.alarm
    assert ca.alarm_text() == (
        "consequence analysis: after losing thrusters 1, 2 the rest could not push against the present load"
    )


def test_a_thruster_in_no_failure_group_is_still_lost_alone() -> None:
    """Failure groups name what a switchboard takes with it; a thruster on none of them still fails on its
    own (its drive trips), a single failure the analysis must test: here the worst one. Without it only
    the group would be tested (80 %) and the alarm would stay down."""
    ca = analysis(failure_groups=[[1]])
    v = ca.update(0.0, [0.0, 120.0, 0.0])
    assert v is not None
    by_lost = {c.lost: c.utilisation for c in v.cases}
    assert by_lost == {
        (1,): pytest.approx(120 / 150),
        (2,): pytest.approx(120 / 150),
        (3,): pytest.approx(1.2),
    }
    assert v.worst is not None and v.worst.lost == (3,) and ca.alarm


def test_the_alarm_is_raised_over_100_percent_and_cleared_below_95() -> None:
    # (the load follows τ at once, and every step is tested: a move of 2 % of capacity, 6 N, is more
    # than the steps below)
    ca = analysis(filter_s=1e-3, min_period_s=0.0, retest_fraction=0.0)
    ca.update(0.0, [0.0, 101.0, 0.0])  # losing 3: 101 of 100 in sway
    assert ca.alarm
    text = ca.alarm_text()
    assert text == (
        "consequence analysis: after losing thruster 3 the rest would need 101 % of their thrust for the "
        "present load (over 100 %: position lost; the alarm clears below 95 %)"
    )
    ca.update(1.0, [0.0, 97.0, 0.0])  # 97 %: between the two thresholds, still up
    assert ca.alarm
    # ... and says what is so now, in the same words
    assert ca.alarm_text() == (
        "consequence analysis: after losing thruster 3 the rest would need 97 % of their thrust for the "
        "present load (over 100 %: position lost; the alarm clears below 95 %)"
    )
    ca.update(2.0, [0.0, 94.0, 0.0])
    assert not ca.alarm and ca.alarm_text() is None
    ca.update(3.0, [0.0, 99.0, 0.0])  # 99 %: below 100, stays down
    assert not ca.alarm
    assert ca.verdict is not None and ca.verdict.t == 3.0  # (each step above was a verdict)


def test_a_load_about_100_percent_is_one_alarm_in_the_logs_not_one_cleared_and_another_raised() -> None:
    """The logs of alarms raised and cleared (/dp/log, Keelson's log_message) know an alarm by its text
    with the numbers masked (`alarm_key`). A load going over and under 100 % while the alarm is held up
    (down to 95 %) must keep that identity: else each crossing is logged as a clear and a raise, the
    chatter the hysteresis is there to prevent."""
    from gateway.foxglove_channels import AlarmChanges

    ca = analysis(filter_s=1e-3, min_period_s=0.0, retest_fraction=0.0)
    log = AlarmChanges()
    changes = []
    for k, sway in enumerate([101.0, 98.0, 102.0, 97.0, 101.0, 96.0]):
        ca.update(float(k), [0.0, sway, 0.0])
        assert ca.alarm  # (held up all along: 96 % and more)
        text = ca.alarm_text()
        assert text is not None
        changes.append(log.update([text]))
    assert changes[0] == ([changes[0][0][0]], [])  # raised once
    assert all(c == ([], []) for c in changes[1:])  # then neither cleared nor raised again


def test_the_load_is_the_demanded_tau_low_passed() -> None:
    ca = analysis(filter_s=30.0)
    ca.update(0.0, [0.0, 0.0, 0.0])
    for k in range(1, 301):  # a step to 90 N of sway, 30 s at 10 Hz: one time constant
        ca.update(0.1 * k, [0.0, 90.0, 0.0])
    assert ca.load[1] == pytest.approx(90.0 * (1 - math.exp(-1.0)), rel=1e-9)
    # a gust of one step moves the mean by 1/300 of itself, not to it
    before = ca.load[1]
    ca.update(30.1, [0.0, 1000.0, 0.0])
    assert ca.load[1] - before == pytest.approx((1000.0 - before) * (1 - math.exp(-0.1 / 30)), rel=1e-9)


def test_failure_cases_are_retested_when_the_load_moves_a_thruster_changes_or_a_minute_passes() -> None:
    ca = analysis(filter_s=1e-3)
    box.calls = 0  # type: ignore[attr-defined]
    per_test = 1 + 3  # intact + three cases
    assert ca.update(0.0, [10.0, 10.0, 0.0]) is not None
    # the same load at 10 Hz for 59 s: nothing new to test
    assert all(ca.update(0.1 * k, [10.0, 10.0, 0.0]) is None for k in range(1, 590))
    assert box.calls == per_test  # type: ignore[attr-defined]
    assert ca.update(60.0, [10.0, 10.0, 0.0]) is not None  # a minute on
    # 2 % of capacity is 2 % of 300 N in sway: 5 N is below, 7 N above
    assert ca.update(61.0, [10.0, 15.0, 0.0]) is None
    assert ca.update(62.0, [10.0, 17.0, 0.0]) is not None
    # not more often than once a second, however much the load moves
    assert ca.update(62.5, [10.0, 60.0, 0.0]) is None
    assert ca.update(63.0, [10.0, 60.0, 0.0]) is not None
    # a thruster out of DP: tested at once (after the second), and it is no case any more
    v = ca.update(64.0, [10.0, 60.0, 0.0], out={3})
    assert v is not None
    assert [c.lost for c in v.cases] == [(1,), (2,)]
    assert v.intact == pytest.approx(60 / 100)  # sway from 1 and 2 alone


def test_losing_every_thruster_left_is_the_worst_case_not_no_case() -> None:
    # a failure group that feeds every thruster: nothing would be left, whatever the load
    ca = analysis(failure_groups=[[1, 2, 3]])
    v = ca.update(0.0, [10.0, 10.0, 0.0])
    assert v is not None and [(c.lost, c.utilisation) for c in v.cases] == [((1, 2, 3), math.inf)]
    assert ca.alarm
    assert ca.alarm_text() == (
        "consequence analysis: after losing thrusters 1, 2, 3 no thruster would be left to hold the position"
    )
    # the last thruster in service: losing it is a case, and the alarm stays up
    ca = analysis(filter_s=1e-3, min_period_s=0.0)
    v = ca.update(0.0, [10.0, 10.0, 0.0], out={1, 2})
    assert v is not None and [(c.lost, c.utilisation) for c in v.cases] == [((3,), math.inf)]
    assert ca.alarm_text() == (
        "consequence analysis: after losing thruster 3 no thruster would be left to hold the position"
    )
    # with no load at all, losing everything loses nothing
    v = ca.update(1.0, [0.0, 0.0, 0.0], out={1, 2})
    assert v is not None and v.cases[0].utilisation == 0.0 and not ca.alarm


def test_a_case_whose_thrusters_are_all_out_already_is_no_case() -> None:
    ca = analysis(failure_groups=[[1, 2], [3]])
    v = ca.update(0.0, [10.0, 10.0, 0.0], out={1, 2})
    assert v is not None and [c.lost for c in v.cases] == [(3,)]
    ca = analysis(failure_groups=[[1, 2], [3]])
    v = ca.update(0.0, [10.0, 10.0, 0.0], out={1, 2, 3})
    assert v is not None and v.cases == () and v.worst is None and not ca.alarm


def test_a_clock_that_goes_back_does_not_freeze_the_verdict() -> None:
    """A restarted simulation clock (``[time] sim``) starts again at 0: the analysis tests at once rather
    than wait, with the old verdict and alarm, until the clock is past the last test again; the mean
    load starts again from τ, as at the first step."""
    ca = analysis()
    assert ca.update(3600.0, [0.0, 150.0, 0.0]) is not None and ca.alarm
    v = ca.update(1.0, [0.0, 10.0, 0.0])
    assert v is not None and v.t == 1.0 and v.load == (0.0, 10.0, 0.0) and not ca.alarm
    assert ca.update(1.5, [0.0, 10.0, 0.0]) is None  # (and then at its usual pace)


def test_reset_forgets_the_load_and_the_alarm() -> None:
    ca = analysis(filter_s=1e-3)
    ca.update(0.0, [0.0, 150.0, 0.0])
    assert ca.alarm
    ca.reset()
    assert not ca.alarm and ca.verdict is None and not np.any(ca.load)


def test_bad_settings_and_unknown_thrusters_are_refused() -> None:
    with pytest.raises(ValueError, match="filter_s"):
        analysis(filter_s=0.0)
    with pytest.raises(ValueError, match=r"\[7\]"):
        analysis(failure_groups=[[1, 7]])


def test_through_a_heading_change_the_load_turns_with_the_vessel_at_once() -> None:
    """An environment pushing 100 N north, the vessel turning from north to east in 10 s: in body axes the
    demand turns from ahead to port. A mean kept in body axes would lag by the filter's 30 s (after the
    turn it would still point ~70° off); kept in earth axes it is the right body load at every step."""
    ca = analysis(filter_s=30.0)
    ca.update(0.0, [100.0, 0.0, 0.0], psi=0.0)
    for k in range(1, 101):
        psi = math.radians(90.0) * k / 100
        body = [100.0 * math.cos(psi), -100.0 * math.sin(psi), 0.0]  # Rᵀ(ψ) [100, 0]
        ca.update(0.1 * k, body, psi=psi)
        np.testing.assert_allclose(ca.load, body, atol=1e-9)


def test_a_failing_evaluation_is_retried_each_second_not_at_every_step() -> None:
    """A solver that raises is the caller's alarm (the pipeline words it), but the analysis must not try
    again at every 10 Hz control step (it did: each try solves every failure case): it is retried once
    `min_period_s` has passed, `failed` says so meanwhile, and once the solver works it is evaluated at
    the next try whatever the load did."""
    calls = {"n": 0, "broken": True}

    def flaky(thrusters: Sequence[Thruster], tau: np.ndarray, failed: Collection[int]) -> float:
        calls["n"] += 1
        if calls["broken"]:
            raise RuntimeError("capability LP: solver status 4")
        return box(thrusters, tau, failed)

    ca = ConsequenceAnalysis(THRUSTERS, flaky)  # type: ignore[arg-type]
    tries = 0
    for k in range(31):  # 3 s at 10 Hz, the same load
        try:
            ca.update(0.1 * k, [50.0, 60.0, 0.0])
        except RuntimeError:
            tries += 1
        assert ca.failed
    assert tries == 4  # at 0, 1, 2 and 3 s
    calls["broken"] = False
    assert ca.update(3.05, [50.0, 60.0, 0.0]) is None  # (within a second of the last try)
    v = ca.update(4.0, [50.0, 60.0, 0.0])
    assert v is not None and not ca.failed and v.worst is not None and v.worst.lost == (3,)
