"""Alarms with an identity and a level (`gateway.alarms`, `Status.alarm_details`): a console tells alarms
apart by a key that stays the same while the alarm's figures change (before, it saw the texts, which carry
live figures, raised and cleared every second), and the alarms that mean DP cannot be trusted to hold the
vessel now are critical: on `/dp/log` at ERROR (before, the estimate lost in DP was a WARNING, as loud as
a heading warning)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from gateway.alarms import alarm_key, alarm_level
from gateway.pipeline import RawEvent
from tests.test_commands import ALL, T0, S, moving_fix, pipeline
from wire import foxglove as fx
from wire.codecs import nmea_encode as enc


def run_heading_only(mode: str) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """5 s of fixes and headings, then 40 s of headings only, a status each second: (statuses, log lines)."""
    rng = np.random.default_rng(3)
    p = pipeline({"accept": ALL}, initial_mode=mode)
    out: list[Any] = []
    t = 0.0
    while t < 45.0:
        data = moving_fix(t, 0.0, rng) if t < 5.0 else enc.hdt("HE", 0.5 + rng.normal(0, 0.001)).encode()
        out += p.feed(RawEvent(T0 + round(t * S), "gps", data))
        if abs(t - round(t)) < 1e-6:
            out += p.status_outputs(T0 + round(t * S))
        t += 0.1
    statuses = [o.payload for o in out if o.topic == "/dp/status"]
    logs = [o.payload for o in out if o.topic == "/dp/log"]
    return statuses, logs


def details_of(status: dict[str, Any], start: str) -> list[dict[str, Any]]:
    return [
        d
        for a, d in zip(status["alarms"], status.get("alarm_details", []), strict=True)
        if a.startswith(start)
    ]


def test_in_dp_the_estimate_dead_reckoning_is_one_critical_alarm_while_its_seconds_count() -> None:
    statuses, logs = run_heading_only("dp")
    dr = [(s["stamp_ns"], s["alarms"], details_of(s, "estimate dead reckoning")) for s in statuses]
    dr = [(ns, d[0]) for ns, _, d in dr if d]
    assert len(dr) >= 15, dr
    keys = {d["key"] for _, d in dr}
    assert keys == {"estimate dead reckoning"}, keys  # its state: what it lacks may change while it is up
    assert {d["level"] for _, d in dr} == {"critical"}
    assert {d["since_ns"] for _, d in dr} == {dr[0][0]}  # raised once: the first status with it
    texts = {a for s in statuses for a in s["alarms"] if a.startswith("estimate dead reckoning")}
    assert len(texts) >= 10  # the texts did change every second: what a console compared before
    lost = [d for s in statuses for d in details_of(s, "estimate lost")]
    assert lost and {d["level"] for d in lost} == {"critical"}
    raised = {m["message"].split(" for ")[0]: m["level"] for m in logs if m["message"].startswith("alarm: ")}
    assert raised["alarm: estimate dead reckoning"] == fx.LOG_ERROR
    assert raised["alarm: estimate lost: dead reckoning"] == fx.LOG_ERROR


def test_outside_dp_dead_reckoning_is_a_warning_and_a_stale_source_keeps_its_key() -> None:
    statuses, logs = run_heading_only("standby")
    dr = [d for s in statuses for d in details_of(s, "estimate dead reckoning")]
    assert dr and {d["level"] for d in dr} == {"warning"}
    raised = {m["message"].split(" for ")[0]: m["level"] for m in logs if m["message"].startswith("alarm: ")}
    assert raised["alarm: estimate dead reckoning"] == fx.LOG_WARNING
    # the estimate lost is critical in any mode: the estimate is a guess
    assert {d["level"] for s in statuses for d in details_of(s, "estimate lost")} == {"critical"}
    assert all(len(s.get("alarm_details", [])) == len(s["alarms"]) for s in statuses)


@pytest.mark.parametrize(
    ("text", "mode", "level"),
    [
        ("position 12.3 m off the DP reference: beyond the alarm circle (10 m)", "dp", "critical"),
        ("position 6.1 m off the DP reference: beyond the warning circle (5 m)", "dp", "warning"),
        ("heading 5.2° off the DP reference: beyond the alarm limit (5°)", "dp", "critical"),
        ("heading 3.1° off the DP reference: beyond the warning limit (3°)", "dp", "warning"),
        ("source dgps1: stale (3.1 s without data)", "dp", "warning"),
        ("thruster 2 out of DP (emergency stop)", "dp", "warning"),
        (
            "estimate dead reckoning for 4 s: no usable heading reference (lost after ...)",
            "manual",
            "warning",
        ),
    ],
)
def test_alarm_levels(text: str, mode: str, level: str) -> None:
    assert alarm_level(text, mode) == level


def test_an_alarm_key_keeps_names_and_masks_values() -> None:
    assert alarm_key("source dgps1: stale (3.1 s without data)") == alarm_key(
        "source dgps1: stale (14.0 s without data)"
    )
    assert alarm_key("source dgps1: stale (3.1 s without data)") != alarm_key(
        "source dgps2: stale (3.1 s without data)"
    )


def test_an_estimate_alarm_stays_one_alarm_while_what_it_lacks_changes() -> None:
    """After every source was lost, the heading came back first: "no usable position and heading
    reference" became "no usable position reference", which was read as a clear and a new critical alarm,
    raised while the vessel was recovering and cleared 0.1 s later. An estimate's alarm is its state alone;
    dead reckoning that becomes lost is another, louder one."""
    both = "estimate lost: dead reckoning for 46 s, no usable position and heading reference"
    one = "estimate lost: dead reckoning for 47 s, no usable position reference"
    assert alarm_key(both) == alarm_key(one)
    assert alarm_level(both, "standby") == alarm_level(one, "dp") == "critical"
    dr = "estimate dead reckoning for 3 s: no usable heading reference (lost after ... = 30 s)"
    in_dp = dr + "; in DP: the controller holds the setpoint on the dead-reckoned estimate"
    assert alarm_key(dr) == alarm_key(in_dp) != alarm_key(one)
    assert (alarm_level(dr, "standby"), alarm_level(in_dp, "dp")) == ("warning", "critical")


def test_an_alarm_key_keeps_an_address_whole() -> None:
    """A source's address is its name: it read "cannot connect to #.#:#" before, every address alike."""
    a = alarm_key("source dgps1: disconnected (cannot connect to 127.0.0.1:20101: Connection refused)")
    assert "127.0.0.1:20101" in a
    assert a != alarm_key("source dgps1: disconnected (cannot connect to 10.0.0.7:20101: Connection refused)")
