"""The estimate's own alarm: an estimate that is dead-reckoned or lost is said in `/dp/status` `alarms`
(and so raised and cleared on `/dp/log`) with what is not measured, for how long, and what DP does on it;
the settling count stands while nothing steps the observer; and the status's `estimates` counts the
observer's estimates, not the dead-reckoned ones of `tick`."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from gateway.pipeline import ControlEvent, Pipeline, RawEvent
from tests.test_commands import ALL, T0, S, moving_fix, pipeline
from wire.codecs import nmea_encode as enc


def estimate_alarms(p: Pipeline, t: float) -> list[str]:
    return [a for a in p.status(T0 + round(t * S)).payload["alarms"] if a.startswith("estimate ")]


def log_lines(out: list[Any]) -> list[str]:
    return [o.payload["message"] for o in out if o.topic == "/dp/log"]


def test_a_position_dead_reckoned_then_lost_in_dp_is_alarmed_and_cleared_when_measured_again() -> None:
    """No position fix (the heading still comes) in DP: an alarm "estimate dead reckoning", then "estimate
    lost" past integrity.lost_after_s (30 s), saying the controller holds on the dead-reckoned estimate;
    each raised once on /dp/log and cleared when the fixes are back."""
    rng = np.random.default_rng(3)
    p = pipeline({"accept": ALL}, initial_mode="dp")
    out: list[Any] = []
    t = 0.0
    while t < 5.0:
        out += p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    assert p.mode == "dp" and estimate_alarms(p, t) == []
    while t < 45.0:  # the heading alone
        out += p.feed(RawEvent(T0 + round(t * S), "gps", enc.hdt("HE", 0.5 + rng.normal(0, 0.001)).encode()))
        if abs(t - round(t)) < 1e-6:
            out += p.status_outputs(T0 + round(t * S))
        if abs(t - 15.0) < 1e-6:
            (dr,) = estimate_alarms(p, t)
            # (for 8 s: since the position last went into the observer, the fix's timeout after it came)
            assert re.match(
                r"estimate dead reckoning for [89] s: no usable position reference \(lost after", dr
            )
            assert "in DP: the controller holds the setpoint on the dead-reckoned estimate" in dr
        t += 0.1
    assert p.estimate_status == "lost"
    (lost,) = estimate_alarms(p, t)
    assert re.match(r"estimate lost: dead reckoning for 3[89] s, no usable position reference; in DP", lost)
    while t < 60.0:  # the fixes are back
        out += p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        if abs(t - round(t)) < 1e-6:
            out += p.status_outputs(T0 + round(t * S))
        t += 0.1
    assert estimate_alarms(p, t) == []
    lines = [m for m in log_lines(out) if m.split(": ", 1)[1].startswith("estimate ")]
    assert [m.split(" for ")[0] for m in lines] == [
        "alarm: estimate dead reckoning",
        "alarm: estimate lost: dead reckoning",  # (in one status: the raised, then the cleared)
        "alarm cleared: estimate dead reckoning",
        "alarm cleared: estimate lost: dead reckoning",
    ], lines


def test_outside_dp_the_alarm_says_nothing_of_dp() -> None:
    rng = np.random.default_rng(4)
    p = pipeline({"accept": ALL}, initial_mode="standby")
    t = 0.0
    while t < 5.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    while t < 8.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", enc.hdt("HE", 0.5).encode()))
        t += 0.1
    (dr,) = estimate_alarms(p, t)
    assert dr.startswith("estimate dead reckoning for ") and "DP" not in dr


def test_every_source_silent_in_dp_dp_commands_on_dead_reckoning_and_the_settling_count_stands() -> None:
    """Every source silent in DP (DP taken before the observer settled): the tick's dead-reckoned estimates
    go out, and so do the thruster commands on them at the control rate (before, none did: the thrusters
    held their last command, or stopped where a drive times its command out); the alarm says so, the
    settling count stands still, and the status's `estimates` counts only the observer's estimates."""
    rng = np.random.default_rng(5)
    p = pipeline({"accept": ALL}, initial_mode="standby")
    t = 0.0
    while t < 5.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    p.feed(ControlEvent(T0 + round(t * S), "mode", "dp"))
    while t < 10.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    assert p.mode == "dp" and not p.settled
    counted = p.status(p.last_ns).payload["estimates"]
    left_at_silence = p.settle_left_s(p.last_ns)
    ticked: list[Any] = []
    for k in range(1, 401):  # 40 s of ticks at 10 Hz, nothing received
        ticked += p.tick(p.last_ns + k * S // 10)
    now = p.last_ns + 40 * S
    dead_reckoned = [o.payload for o in ticked if o.topic == "/dp/estimate"]
    assert len(dead_reckoned) > 300
    assert dead_reckoned[-1]["status"] == "lost"
    commands = [o for o in ticked if o.topic == "/dp/thrusters/command"]
    # from the first dead-reckoned estimate (past the sources' 2 s timeout) on, at 10 Hz: ~380 in 38 s
    assert 370 <= len(commands) <= 382, len(commands)
    first_dr = next(o.stamp_ns for o in ticked if o.topic == "/dp/estimate")
    assert commands[0].stamp_ns == first_dr
    assert all(c.payload["mode"] == "dp" and len(c.payload["thrusters"]) == 6 for c in commands)
    # on station, dead-reckoning stays put: the command is the bias-compensating thrust, not a runaway
    assert max(abs(c.payload["tau_demand"][0]) for c in commands) < 5e5
    alarms = p.status(now).payload["alarms"]
    (lost,) = [a for a in alarms if a.startswith("estimate ")]
    assert re.match(
        r"estimate lost: dead reckoning for 40 s, no usable position and heading reference;", lost
    )
    assert lost.endswith(
        "in DP: the controller holds the setpoint on the dead-reckoned estimate "
        "(nothing measured: stepped on the gateway's clock)"
    )
    # the settling count stood where the last step left it, in the alarm and in the estimates
    assert p.settle_left_s(now) == left_at_silence
    assert dead_reckoned[-1]["settle_s_left"] == left_at_silence
    (settling,) = [a for a in alarms if "settling" in a]
    assert f"{left_at_silence:.0f} s left" in settling
    assert p.status(now).payload["estimates"] == counted  # the observer's estimates only


def test_the_settling_count_goes_on_after_a_silence_from_where_it_stood() -> None:
    """A silence of 10 s (every source, shorter than integrity.lost_after_s: no restart) while settling:
    the count stands through it and goes on from there, so the settle time is time measured."""
    rng = np.random.default_rng(6)
    p = pipeline({"accept": ALL}, initial_mode="standby")
    t = 0.0
    while t < 5.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    last = p.last_ns
    left = p.settle_left_s(last)
    assert left > 30.0
    assert p.settle_left_s(last + 10 * S) == left  # silent: stands
    t = (last - T0) / S + 10.0
    while t < (last - T0) / S + 15.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    assert p.restarts == 0
    assert abs(p.settle_left_s(p.last_ns) - (left - 4.9)) < 0.2
