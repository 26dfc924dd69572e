"""Simulation time from clock ticks (`gateway.sim_time.SimTime`): stamps are exact at the ticks, follow the
simulation between them, never run more than one tick ahead of the newest tick, and never go back."""

from __future__ import annotations

import itertools
import threading

from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.sim_time import SimTime

MS = 1_000_000
EPOCH = 1_700_000_000 * 1_000_000_000  # sim time 0 as UTC ns
PERIOD_S = 0.05


def regular(clock: SimTime, n: int, speed: float, wall_step_ms: float = 5.0) -> list[tuple[int, int]]:
    """n ticks, a sim period apart, arriving at the rate ``speed`` would give; returns (wall, sim)."""
    ticks = []
    for k in range(n):
        wall = round(k * PERIOD_S / speed * 1e9)
        sim = EPOCH + round(k * PERIOD_S * 1e9)
        clock.on_tick(sim, PERIOD_S, wall)
        ticks.append((wall, sim))
    return ticks


def test_no_time_before_the_first_tick_then_the_first_ticks_time() -> None:
    clock = SimTime()
    assert clock.stamp(123) is None and clock.now(123) is None and not clock.started
    clock.on_tick(EPOCH, PERIOD_S, 1_000 * MS)
    # data received before the tick (held by the service) is stamped with the first tick's time
    assert clock.stamp(500 * MS) == EPOCH
    assert clock.started


def test_exact_at_ticks_and_linear_between_them_at_a_steady_rate() -> None:
    clock = SimTime()
    ticks = regular(clock, 100, speed=10.0)
    for wall, sim in ticks[50:]:
        assert clock.now(wall) == sim
    # halfway between two ticks: halfway in sim time (the observed rate is exactly 10)
    w0, s0 = ticks[60]
    w1, s1 = ticks[61]
    assert abs(clock.now((w0 + w1) // 2) - (s0 + s1) // 2) <= 1


def test_never_more_than_one_tick_ahead_when_the_ticks_stop() -> None:
    clock = SimTime()
    ticks = regular(clock, 50, speed=10.0)
    last_wall, last_sim = ticks[-1]
    # the simulator stalls (a busy machine): time stops one tick ahead of the last tick, whatever the wait
    for wait_s in (0.001, 0.005, 0.1, 10.0):
        assert clock.now(last_wall + round(wait_s * 1e9)) <= last_sim + round(PERIOD_S * 1e9)
    assert clock.stamp(last_wall + 10**10) == last_sim + round(PERIOD_S * 1e9)


def test_follows_a_change_of_speed_within_the_rate_window() -> None:
    clock = SimTime()
    ticks = regular(clock, 200, speed=10.0)  # 1 s of wall time at 10x
    wall0, sim0 = ticks[-1]
    for k in range(1, 101):  # then 2x for 2.5 s of wall time
        clock.on_tick(sim0 + round(k * PERIOD_S * 1e9), PERIOD_S, wall0 + round(k * PERIOD_S / 2.0 * 1e9))
    assert abs(clock.rate() - 2.0) < 1e-9


def test_a_tick_going_back_is_a_new_run_stamped_apart_once_followed() -> None:
    clock = SimTime()
    ticks = regular(clock, 40, speed=1.0)  # 2 s of a run
    wall_end, sim_end = ticks[-1]
    clock.on_tick(sim_end - 20_000_000, PERIOD_S, wall_end + 1)  # a tick swapped in delivery: ignored
    assert clock.ignored == 1 and clock.went_back is None
    restart = wall_end + 3 * 10**9
    clock.on_tick(EPOCH, PERIOD_S, restart)  # a restarted simulator: its epoch again
    clock.on_tick(EPOCH + 50_000_000, PERIOD_S, restart + 50_000_000)
    assert clock.went_back == (sim_end, EPOCH) and clock.restart_mono_ns == restart
    # until followed, stamps come from the old run (what the consumer still has of it), never going back
    a = clock.stamp(wall_end)
    b = clock.stamp(wall_end - 10**9)
    assert a == sim_end and b == a
    assert not clock.of_new_run(wall_end + 500_000_000, 10**9)  # 0.5 s after the old run's last tick
    assert clock.of_new_run(wall_end + 1_500_000_000, 10**9)  # 1.5 s after it: not the old run's
    assert clock.of_new_run(restart + 1, 10**9)  # after the new run's first tick
    assert clock.follow() == (sim_end, EPOCH) and clock.went_back is None and clock.runs == 2
    assert clock.stamp(wall_end + 2 * 10**9) == EPOCH  # before the new run's first tick: its time exactly
    assert clock.stamp(restart + 50_000_000) == EPOCH + 50_000_000
    assert not clock.of_new_run(restart + 10**10, 10**9)  # nothing pending any more


def test_a_late_tick_of_the_old_run_is_not_a_second_restart() -> None:
    """A tick of the old run delivered after the new run's first (two Zenoh threads' callbacks swapped at
    the restart) is the old run's straggler: ignored, not taken as the new run jumping ahead (whose next
    tick would then look like a second restart: a spurious run, log file and pipeline start-over)."""
    for follow_first in (False, True):
        clock = SimTime()
        ticks = regular(clock, 40, speed=1.0)
        wall_end, sim_end = ticks[-1]
        restart = wall_end + 3 * 10**9
        clock.on_tick(EPOCH, PERIOD_S, restart)  # the new run's first tick
        if follow_first:  # the consumer follows at once
            assert clock.follow() == (sim_end, EPOCH)
        clock.on_tick(sim_end + 50_000_000, PERIOD_S, restart + 1)  # the old run's last, delivered late
        clock.on_tick(EPOCH + 50_000_000, PERIOD_S, restart + 50_000_000)
        clock.on_tick(EPOCH + 100_000_000, PERIOD_S, restart + 100_000_000)
        assert clock.ignored == 1
        if not follow_first:
            assert clock.went_back == (sim_end, EPOCH) and clock.restart_mono_ns == restart
            clock.follow()
        assert clock.went_back is None and clock.runs == 2
        # stamps on the new run's time, never the old run's
        assert clock.stamp(restart + 50_000_000) == EPOCH + 50_000_000
        assert clock.stamp(restart + 100_000_000) == EPOCH + 100_000_000


@settings(max_examples=200, deadline=None)
@given(
    gaps=st.lists(
        st.tuples(
            st.floats(0.0005, 0.05),  # sim time between ticks (s): a period at most
            st.floats(0.0, 0.2),  # wall time between ticks (s): any load
        ),
        min_size=2,
        max_size=60,
    ),
    queries=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40),
)
def test_properties_for_any_tick_sequence(gaps: list[tuple[float, float]], queries: list[float]) -> None:
    """Whatever the ticks' spacing in sim and wall time: stamps asked in increasing wall order are monotone,
    never more than one period ahead of the newest tick received, and never behind the tick they follow."""
    clock = SimTime()
    wall, sim = 0, EPOCH
    clock.on_tick(sim, PERIOD_S, wall)
    walls = [wall]
    for d_sim, d_wall in gaps:
        wall += round(d_wall * 1e9)
        sim += round(d_sim * 1e9)
        clock.on_tick(sim, PERIOD_S, wall)
        walls.append(wall)
    span = walls[-1] + 10**9
    previous = None
    for q in sorted(queries):
        w = round(q * span)
        s = clock.stamp(w)
        assert s is not None
        assert s <= sim + round(PERIOD_S * 1e9)  # never more than one tick ahead of the newest tick
        if previous is not None:
            assert s >= previous  # monotone
        previous = s


def test_ticks_from_several_threads_keep_a_consistent_history() -> None:
    clock = SimTime()

    def feed(offset: int) -> None:
        for k in range(2000):
            clock.on_tick(EPOCH + (2 * k + offset) * 50 * MS, PERIOD_S, (2 * k + offset) * 5 * MS)

    threads = [threading.Thread(target=feed, args=(i,)) for i in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert clock.ticks + clock.ignored == 4000
    stamps = [clock.stamp(k * MS) for k in range(0, 20_000, 7)]
    assert all(a is not None and b is not None and b >= a for a, b in itertools.pairwise(stamps))


# --- which simulator is speaking (`SimClock.run`) -----------------------------------------------------------

A, B = 11, 22  # two simulators' runs


def test_another_simulators_ticks_are_ignored_while_its_own_still_come() -> None:
    """Two benches sharing a prefix: the gateway's own simulator at EPOCH, another an hour ahead on the
    same key, their ticks interleaved. The other's are ignored and counted; the stamps are the own run's
    as if the other were not there; no restart."""
    clock, alone = SimTime(), SimTime()
    for k in range(200):
        wall = k * 10 * MS
        own = EPOCH + k * 50 * MS
        clock.on_tick(own, PERIOD_S, wall, A)
        alone.on_tick(own, PERIOD_S, wall, A)
        clock.on_tick(own + 3600 * 10**9, PERIOD_S, wall + 3 * MS, B)  # ahead, interleaved
        if k % 7 == 0:
            clock.on_tick(own - 600 * 10**9, PERIOD_S, wall + 4 * MS, B + 1)  # and a third, behind
    assert clock.went_back is None and clock.run_id == A
    # (each counted once the own run ticks after it: the last, not yet, might be a restart's)
    assert clock.foreign == 200 + 29 - 1 and clock.foreign_run in (B, B + 1)
    for w in range(0, 2_000 * MS, 7 * MS):
        assert clock.stamp(w) == alone.stamp(w)


def test_a_new_run_is_followed_once_the_old_one_is_silent_whichever_way_its_time_goes() -> None:
    """A restarted simulator whose epoch is later than the old run's newest time (its time moves on, not
    back): with run identities it is a new run all the same, once the old run has stopped ticking; a
    late tick of the old run after the new one's first is ignored, not another simulator."""
    clock = SimTime()
    for k in range(100):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, k * 10 * MS, A)
    later = EPOCH + 7200 * 10**9
    t_new = 990 * MS + 2_500 * MS  # the old run silent for 2.5 s
    clock.on_tick(later, PERIOD_S, t_new, B)
    assert clock.went_back == (EPOCH + 99 * 50 * MS, later) and clock.foreign == 0
    clock.on_tick(EPOCH + 100 * 50 * MS, PERIOD_S, t_new + MS, A)  # the old run's last, delivered late
    assert clock.foreign == 0 and clock.ignored == 1
    clock.follow()
    assert clock.run_id == B and clock.runs == 2
    clock.on_tick(later + 50 * MS, PERIOD_S, t_new + 10 * MS, B)
    assert clock.stamp(t_new + 10 * MS) == later + 50 * MS


def test_one_run_never_starts_again() -> None:
    """A tick of the run being followed that goes far back is a bad tick of that run, not a restart."""
    clock = SimTime()
    for k in range(50):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, k * 10 * MS, A)
    clock.on_tick(EPOCH - 60 * 10**9, PERIOD_S, 500 * MS, A)
    assert clock.went_back is None and clock.ignored == 1 and clock.runs == 1


def test_a_simulator_that_does_not_say_is_followed_by_its_times_as_before() -> None:
    clock = SimTime()
    for k in range(50):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, k * 10 * MS)
    clock.on_tick(EPOCH - 60 * 10**9, PERIOD_S, 500 * MS)  # went back: a restart
    assert clock.went_back is not None and clock.foreign == 0


def test_a_pinned_run_is_the_only_one_followed_even_when_another_speaks_first() -> None:
    """`dpgw demo` knows its own simulator's run: another demo's clock heard first is not followed."""
    clock = SimTime()
    clock.pin(A)
    clock.on_tick(EPOCH + 3600 * 10**9, PERIOD_S, 0, B)  # another simulator, first
    assert not clock.started and clock.foreign == 1
    for k in range(10):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS, A)
        clock.on_tick(EPOCH + 3600 * 10**9 + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS + 1, B)
    for k in range(10):  # ours silent for 10 s: the other is still not taken for a restart
        clock.on_tick(EPOCH + 3600 * 10**9 + (k + 10) * 50 * MS, PERIOD_S, 10_000 * MS + k * MS, B)
    assert clock.went_back is None and clock.foreign == 21 and clock.stamp(100 * MS) == EPOCH + 450 * MS


def test_a_pin_drops_another_simulators_ticks_heard_before_it() -> None:
    """`dpgw demo` subscribes to the clock (`GatewayService.start`) before its publisher exists to be
    pinned: a tick of another demo reached by scouting in between must not stay the run followed (its
    time an hour ahead, every tick of the demo's own simulator was a bad tick of "the same run" going
    back, and the demo had no time to stamp with)."""
    clock = SimTime()
    for k in range(3):  # another simulator, heard before the pin
        clock.on_tick(EPOCH + 3600 * 10**9 + k * 50 * MS, PERIOD_S, k * MS, B)
    clock.pin(A)
    assert not clock.started and clock.foreign == 3 and clock.foreign_run == B
    for k in range(10):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS, A)
    assert clock.run_id == A and clock.went_back is None and clock.ignored == 0
    assert clock.stamp(100 * MS) == EPOCH + 450 * MS


def test_a_pinned_run_ignores_a_simulator_that_does_not_say() -> None:
    """A pinned gateway follows its run only: a simulator that does not say its run (``run`` 0, an older
    one on the same key) is another simulator too, neither followed as a restart when its time is
    behind nor mixed into the pinned run's ticks, nor taken for the first tick before the own one."""
    clock = SimTime()
    clock.pin(A)
    clock.on_tick(EPOCH + 3600 * 10**9, PERIOD_S, 0)  # before the own run's first tick
    assert not clock.started and clock.foreign == 1
    for k in range(10):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS, A)
        clock.on_tick(EPOCH - 600 * 10**9 + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS + 1)  # behind
        clock.on_tick(EPOCH + 1800 * 10**9 + k * 50 * MS, PERIOD_S, (k + 1) * 10 * MS + 2)  # ahead
    assert clock.went_back is None and clock.runs == 1 and clock.run_id == A and clock.foreign == 21
    assert clock.stamp(100 * MS) == EPOCH + 450 * MS


def test_a_simulator_that_does_not_say_beside_one_that_does_is_another_simulator() -> None:
    """Two benches sharing a prefix, one `dpgw sim` new enough to say its run and one older (run 0): a
    simulator never changes whether it says during a run, so a tick of the other kind while the run
    followed still ticks is another simulator's, either way round. Before, the older one's ticks an hour
    behind were a restart, the newer one's then taken for the restarted run's own (its id adopted), and
    the gateway went to and fro between the two."""
    for ours, theirs in ((A, 0), (0, A)):
        clock, alone = SimTime(), SimTime()
        for k in range(200):
            wall = k * 10 * MS
            own = EPOCH + k * 50 * MS
            clock.on_tick(own, PERIOD_S, wall, ours)
            alone.on_tick(own, PERIOD_S, wall, ours)
            clock.on_tick(own + (-1 if k % 2 else 1) * 3600 * 10**9, PERIOD_S, wall + 3 * MS, theirs)
        assert clock.went_back is None and clock.runs == 1 and clock.run_id == ours, (ours, theirs)
        assert clock.foreign == 199 and clock.foreign_run == theirs  # (the last: the own run not since)
        for w in range(0, 2_000 * MS, 7 * MS):
            assert clock.stamp(w) == alone.stamp(w)


def test_a_simulator_replaced_by_one_of_the_other_kind_is_a_new_run() -> None:
    """A bench's `dpgw sim` replaced by an older one (run 0) and back, each after the other stopped: each
    is a new run once the one before is silent, whichever way its time goes; a late tick of the run left
    (delivered after the new run's first) is ignored, not another simulator."""
    clock, wall = SimTime(), 0
    runs = [(A, EPOCH), (0, EPOCH + 7200 * 10**9), (B, EPOCH - 3600 * 10**9), (0, EPOCH)]
    for n, (run_id, start) in enumerate(runs):
        wall += 2_500 * MS  # the one before silent for 2.5 s
        for k in range(50):
            clock.on_tick(start + k * 50 * MS, PERIOD_S, wall + k * 10 * MS, run_id)
            if k == 0 and n:  # the run before's last tick, delivered late
                left_id, left_start = runs[n - 1]
                clock.on_tick(left_start + 50 * 50 * MS, PERIOD_S, wall + MS, left_id)
            if clock.went_back is not None:
                clock.follow()
        wall += 50 * 10 * MS
        assert clock.runs == n + 1 and clock.run_id == run_id and clock.foreign == 0, n
        assert clock.stamp(wall) == start + 49 * 50 * MS + 50 * MS  # (one tick ahead at most)


def test_a_simulator_restarted_within_the_silence_is_no_other_simulator() -> None:
    """A bench restarts `dpgw sim` at once (measured: its clock publisher is up 0.9 s after the start):
    the new run's first ticks come within `FOREIGN_SILENT_NS` of the old run's last. The old run never
    ticks again, so they are not another simulator's: nothing counted or alarmed as such (the alarm
    stays for the whole run and tells the operator to part two benches there are not), and the new run
    begins at its first tick, not 2 s later with its first ticks lost."""
    clock = SimTime()
    for k in range(100):
        clock.on_tick(EPOCH + 3600 * 10**9 + k * 50 * MS, PERIOD_S, k * 50 * MS, A)
    first = 99 * 50 * MS + 1_200 * MS  # the old run's last tick 1.2 s before
    for k in range(60):  # 3 s of the new run
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, first + k * 50 * MS, B)
    assert clock.foreign == 0 and clock.went_back == (EPOCH + 3600 * 10**9 + 99 * 50 * MS, EPOCH)
    assert clock.restart_mono_ns == first
    clock.follow()
    assert clock.run_id == B and clock.stamp(first) == EPOCH  # from its first tick
    # a stray tick of yet another run, once, then silence: no other simulator later either
    clock.on_tick(EPOCH + 999 * 10**9, PERIOD_S, first + 60 * 50 * MS, A + B)
    later = first + 60 * 50 * MS + 2_500 * MS  # B silent for 2.5 s: restarted again, as C
    for k in range(20):
        clock.on_tick(EPOCH + k * 50 * MS, PERIOD_S, later + k * 50 * MS, B + 1)
        if clock.went_back is not None:
            clock.follow()
    assert clock.foreign == 0 and clock.run_id == B + 1 and clock.runs == 3
