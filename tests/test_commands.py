"""Command inputs: off unless accepted; a setpoint far away, a τ beyond the thrusters, DP without a healthy
estimate and malformed inputs are refused, counted by reason in the status, and never acted on."""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.commands import tau_capacity
from gateway.config import parse_config
from gateway.pipeline import ControlEvent, Pipeline, PipelineSpec, RawEvent
from observers.vessel import load_vessel
from wire.codecs import nmea_encode as enc
from wire.geodesy import LocalFrame

T0 = 1_767_268_800_000_000_000
S = 1_000_000_000
DATUM = (59.4, 10.5)
ALL = ["mode", "setpoint", "tau"]


def pipeline(
    commands: dict[str, Any] | None = None, initial_mode: str = "standby", wait_for_observer: bool = False
) -> Pipeline:
    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "observer": {"wave_period_s": 8.0},
        # DP from the first estimate: these tests are about the commands, not the start-up's wait for the
        # observer (tests/test_settling.py)
        "control": {"initial_mode": initial_mode, "wait_for_observer": wait_for_observer},
        "log": {"path": ""},
    }
    if commands is not None:
        tables["commands"] = commands
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


def moving_fix(t_s: float, north: float, rng: np.random.Generator) -> bytes:
    """A GGA + HDT at ``t_s`` s into the run (its UTC time advancing, so nothing is frozen), ``north`` m from
    the datum, with a few cm / a twentieth of a degree of noise."""
    from datetime import UTC, datetime, timedelta

    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(north + rng.normal(0, 0.02), rng.normal(0, 0.02), 0.0)
    when = datetime(2026, 1, 1, 12, tzinfo=UTC) + timedelta(seconds=t_s)
    gga = enc.gga("GP", when, lat, lon, 2, 12, 0.8, 20.0)
    return (gga + enc.hdt("HE", 0.5 + rng.normal(0, 0.001))).encode()


def run(p: Pipeline, seconds: float, start_s: float = 0.0) -> list[Any]:
    """Fixes at the datum at 10 Hz from ``start_s``, live-like (`moving_fix`: the same sentence over and over
    is a frozen receiver after a few seconds, and the estimate then no longer healthy)."""
    rng = np.random.default_rng(round(start_s * 10))
    out = []
    for k in range(int(seconds * 10)):
        t = start_s + k / 10
        out += p.feed(RawEvent(T0 + int(t * S), "gps", moving_fix(t, 0.0, rng)))
    return out


def commands_status(p: Pipeline) -> dict[str, Any]:
    return p.status(p.last_ns).payload["commands"]  # type: ignore[no-any-return]


def test_command_inputs_are_off_unless_accepted() -> None:
    p = pipeline()  # no [commands]: the defaults
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    p.feed(ControlEvent(T0 + 2 * S, "tau", {"X": 1e4, "Y": 0.0, "N": 0.0}))
    p.feed(ControlEvent(T0 + 2 * S, "setpoint", {"north_m": 5.0, "east_m": 0.0, "heading_deg": 30.0}))
    run(p, 1.0, 2.1)
    assert p.mode == "standby" and p.setpoint is None and not p.manual_tau.any()
    c = commands_status(p)
    assert c["accepted"] == {}
    assert c["refused"] == {"mode: not accepted": 1, "tau: not accepted": 1, "setpoint: not accepted": 1}
    assert "commands.accept" in c["last_refused"]


def test_only_the_listed_inputs_are_taken() -> None:
    p = pipeline({"accept": ["setpoint"]})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "dp"))
    p.feed(ControlEvent(T0 + 2 * S, "setpoint", {"north_m": 5.0, "east_m": 0.0, "heading_deg": 30.0}))
    run(p, 1.0, 2.1)
    assert p.mode == "standby" and p.setpoint is not None
    assert commands_status(p)["refused"] == {"mode: not accepted": 1}


def test_a_setpoint_50_km_away_is_refused_with_the_reason_and_never_pursued() -> None:
    p = pipeline({"accept": ALL}, initial_mode="dp")
    run(p, 3.0)
    far = LocalFrame(*DATUM).to_geodetic(50_000.0, 0.0, 0.0)
    p.feed(ControlEvent(T0 + 3 * S, "setpoint", {"lat_deg": far[0], "lon_deg": far[1], "heading_deg": 30.0}))
    out = run(p, 5.0, 3.1)
    c = commands_status(p)
    assert c["refused"] == {"setpoint: too far": 1}
    text = c["last_refused"]
    assert re.search(r"4999\d\.\d m from the present position", text), text
    assert "max_setpoint_distance_m = 50 m" in text
    assert [r.reason for r in p.commands.take_refusals()] == ["too far"]  # for the service's log
    refs = [o.payload["reference"] for o in out if o.topic == "/dp/thrusters/command"]
    assert refs and max(abs(r[0]) for r in refs) < 1.0, "the far setpoint must never become the reference"
    # a setpoint within the limit is taken
    p.feed(ControlEvent(T0 + 9 * S, "setpoint", {"north_m": 20.0, "east_m": 0.0, "heading_deg": 30.0}))
    run(p, 1.0, 9.1)
    assert commands_status(p)["accepted"] == {"setpoint": 1}
    assert p.setpoint == {"north_m": 20.0, "east_m": 0.0, "heading_deg": 30.0}


def test_the_setpoint_distance_limit_is_configurable() -> None:
    p = pipeline({"accept": ALL, "max_setpoint_distance_m": 10.0}, initial_mode="dp")
    run(p, 3.0)
    p.feed(ControlEvent(T0 + 3 * S, "setpoint", {"north_m": 20.0, "east_m": 0.0, "heading_deg": 30.0}))
    run(p, 1.0, 3.1)
    assert commands_status(p)["refused"] == {"setpoint: too far": 1}


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        ({"north_m": math.nan, "east_m": 0.0, "heading_deg": 0.0}, "not finite"),
        ({"north_m": 1.0, "east_m": math.inf, "heading_deg": 0.0}, "not finite"),
        ({"lat_deg": 91.0, "lon_deg": 10.5, "heading_deg": 0.0}, "out of range"),
        ({"lat_deg": 59.4, "lon_deg": 10.5, "heading_deg": 1e9}, "out of range"),
        ({"north_m": "5", "east_m": 0.0, "heading_deg": 0.0}, "invalid"),
        ({"north_m": 5.0, "heading_deg": 0.0}, "invalid"),
        ("north", "invalid"),
    ],
)
def test_malformed_setpoints_are_refused(payload: Any, reason: str) -> None:
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, "setpoint", payload))
    assert commands_status_now(p) == {f"setpoint: {reason}": 1}
    assert p._pending_setpoint is None


def commands_status_now(p: Pipeline) -> dict[str, int]:
    return p.status(T0).payload["commands"]["refused"]  # type: ignore[no-any-return]


def test_tau_beyond_the_thrusters_is_refused_and_within_is_taken() -> None:
    cap = tau_capacity(load_vessel("mss_supply"))
    assert cap is not None
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, "mode", "manual"))
    for tau in ({"X": 1e12, "Y": 0.0, "N": 0.0}, {"X": 0.0, "Y": 0.0, "N": float(cap[2]) * 1.01}):
        p.feed(ControlEvent(T0, "tau", tau))
    p.feed(ControlEvent(T0, "tau", {"X": "nan", "Y": 0.0, "N": 0.0}))
    p.feed(ControlEvent(T0, "tau", {"X": math.nan, "Y": 0.0, "N": 0.0}))
    assert not p.manual_tau.any()
    assert commands_status_now(p) == {"tau: beyond capacity": 2, "tau: invalid": 1, "tau: not finite": 1}
    p.feed(ControlEvent(T0, "tau", {"X": float(cap[0]), "Y": -1e4, "N": 0.0}))
    np.testing.assert_allclose(p.manual_tau, [cap[0], -1e4, 0.0])


def test_tau_capacity_of_a_layout() -> None:
    cap = tau_capacity(load_vessel("mss_supply"))
    v = load_vessel("mss_supply")
    assert cap is not None
    assert cap[0] <= sum(max(t.max_thrust_n, -t.min_thrust_n) for t in v.thrusters)
    assert all(c > 0 for c in cap)


def test_dp_only_with_a_healthy_estimate_standby_and_manual_always() -> None:
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, "mode", "dp"))
    assert p.mode == "standby"
    assert commands_status_now(p) == {"mode: estimate not healthy": 1}
    p.feed(ControlEvent(T0, "mode", "manual"))  # never refused for health
    assert p.mode == "manual"
    run(p, 2.0)
    assert p.estimate_status == "ok"
    p.feed(ControlEvent(T0 + 2 * S, "mode", "dp"))
    assert p.mode == "dp"
    p.feed(ControlEvent(T0 + 2 * S, "mode", "warp"))
    assert p.mode == "dp"
    c = commands_status(p)
    assert c["accepted"] == {"mode": 2} and c["refused"]["mode: invalid"] == 1


@settings(max_examples=200, deadline=None)
@given(
    key=st.sampled_from(["mode", "setpoint", "tau", "other"]),
    payload=st.recursive(
        st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
        lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
        max_leaves=8,
    ),
)
def test_any_input_is_taken_or_counted_never_raised(key: str, payload: Any) -> None:
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, key, payload))
    c = p.status(T0).payload["commands"]
    assert sum(c["accepted"].values()) + sum(c["refused"].values()) <= 1
    assert np.all(np.isfinite(p.manual_tau))


def test_a_setpoint_given_before_dp_is_checked_again_when_dp_engages() -> None:
    """A setpoint given in standby was near when given; the vessel was then moved 200 m (by its crew, in
    standby). Engaging DP must not send it back 180 m on a setpoint beyond max_setpoint_distance_m of where
    it is now: DP holds the present position, and the refusal says why."""
    rng = np.random.default_rng(0)
    p = pipeline({"accept": ALL})
    t = 0.0
    while t < 3.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    p.feed(ControlEvent(T0 + round(t * S), "setpoint", {"north_m": 20.0, "east_m": 0.0, "heading_deg": 30.0}))
    while t < 233.0:  # 1 m/s north for 200 s, then still
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, min(max(t - 3.0, 0.0), 200.0), rng)))
        t += 0.1
    assert commands_status(p)["accepted"] == {"setpoint": 1}  # (taken when it was near)
    assert p.estimate_status == "ok"
    p.feed(ControlEvent(T0 + round(t * S), "mode", "dp"))
    out = []
    while t < 243.0:
        out += p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 200.0, rng)))
        t += 0.1
    assert p.mode == "dp"
    refs = [o.payload["reference"] for o in out if o.topic == "/dp/thrusters/command"]
    assert refs and min(r[0] for r in refs) > 195.0, "DP must hold where the vessel is, not go to north 20"
    assert p.controller is not None and abs(float(p.controller.reference.target[0]) - 200.0) < 5.0
    c = commands_status(p)
    assert c["refused"] == {"setpoint: too far": 1}
    assert re.search(r"on entering dp: 1\d\d\.\d m from the present position", c["last_refused"]), c
    assert p.setpoint is None


def test_entering_manual_starts_from_no_thrust_not_an_old_tau() -> None:
    """A τ given in an earlier manual spell (or while in dp or standby) is not what the operator means on
    taking manual again: manual starts from τ = 0 until the next τ."""
    p = pipeline({"accept": ALL})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    p.feed(ControlEvent(T0 + 2 * S, "tau", {"X": 1e5, "Y": 0.0, "N": 0.0}))
    out = run(p, 1.0, 2.1)
    assert [o.payload["tau_demand"][0] for o in out if o.topic == "/dp/thrusters/command"][-1] == 1e5
    p.feed(ControlEvent(T0 + 3 * S, "mode", "standby"))
    run(p, 1.0, 3.1)
    p.feed(ControlEvent(T0 + 4 * S, "mode", "manual"))
    out = run(p, 1.0, 4.1)
    taus = [o.payload["tau_demand"] for o in out if o.topic == "/dp/thrusters/command"]
    assert taus and all(tau == [0.0, 0.0, 0.0] for tau in taus), taus[:2]
    p.feed(ControlEvent(T0 + 5 * S, "tau", {"X": 2e4, "Y": 0.0, "N": 0.0}))
    out = run(p, 1.0, 5.1)
    assert [o.payload["tau_demand"][0] for o in out if o.topic == "/dp/thrusters/command"][-1] == 2e4


def test_dp_is_refused_when_every_source_has_been_silent() -> None:
    """The last estimate was "ok", but nothing has stepped the observer for a minute (the published
    estimates are dead-reckoned, then lost): DP is refused, by a rule of the input's time alone (a replay,
    which has no ticks, refuses it too)."""
    p = pipeline({"accept": ALL})
    run(p, 3.0)
    assert p.estimate_status == "ok"
    p.feed(ControlEvent(T0 + 63 * S, "mode", "dp"))
    assert p.mode == "standby"
    c = commands_status(p)
    assert c["refused"] == {"mode: estimate not healthy": 1}
    assert "no estimate step for 60.1 s" in c["last_refused"], c["last_refused"]


@pytest.mark.parametrize("key", ["setpoint", "tau"])
def test_an_integer_too_large_for_a_float_is_refused_not_raised(key: str) -> None:
    payload = (
        {"north_m": 10**400, "east_m": 0, "heading_deg": 0}
        if key == "setpoint"
        else {"X": 10**400, "Y": 0, "N": 0}
    )
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, key, payload))  # JSON has integers of any size
    assert commands_status_now(p) == {f"{key}: not finite": 1}


@contextlib.contextmanager
def live_gateway(tmp_path: Path) -> Iterator[tuple[Any, Any]]:
    """A gateway service in this process (its consumer loop on a thread) taking every command input on
    Zenoh prefix ``dp/cmd`` over loopback TCP, logging to ``tmp_path / "c.mcap"``; yields (service, a
    Zenoh session connected to it). Stopped, drained and its log closed on exit."""
    import threading

    from conftest import connect_when_listening, free_port

    from gateway.service import GatewayService

    zport = free_port()
    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": [{"name": "gps", "url": f"udp://127.0.0.1:{free_port(2)}", "protocol": "nmea",
                     "roles": ["position", "heading"]}],
        "observer": {"wave_period_s": 8.0},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"], "multicast_scouting": False, "prefix": "dp/cmd"},
        "commands": {"accept": ALL},
        "log": {"path": str(tmp_path / "c.mcap")},
    }  # fmt: skip
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    session = None
    try:
        session = connect_when_listening(zport, 20.0)
        yield service, session
    finally:
        if session is not None:
            session.close()
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        service.close()


def test_a_json_nested_too_deep_for_the_parser_is_refused_and_logged_over_zenoh(tmp_path: Path) -> None:
    """``[[[[…`` 100 000 deep makes `json.loads` raise RecursionError, not ValueError: it escaped the Zenoh
    callback, so the input was neither logged nor counted. It is refused as malformed, like any other."""
    import json

    import zenoh
    from conftest import wait_for

    from wire.mcap.reader import read_messages

    # BLOCK, as a console sends a command: Zenoh's default for a put drops it when the link's queue is full,
    # and on a loaded machine (the suite on Python 3.12, once) the put after the 100 kB one was dropped
    block = zenoh.CongestionControl.BLOCK
    with live_gateway(tmp_path) as (service, session):
        session.put("dp/cmd/mode", "[" * 100_000, congestion_control=block)
        session.put("dp/cmd/mode", json.dumps("manual"), congestion_control=block)
        assert wait_for(lambda: service.pipeline.mode == "manual", 20.0)
        counters = service.pipeline.commands.counters
        assert counters.refused == {"mode: invalid": 1}, counters
    logged = [p for _, _, _, p in read_messages(tmp_path / "c.mcap", "/dp/mode")]
    assert logged == [{"mode": "manual"}]
    # the malformed one as text on its own channel (on /dp/mode it broke that channel's schema)
    (malformed,) = [p for _, _, _, p in read_messages(tmp_path / "c.mcap", "/dp/input/malformed")]
    assert malformed["key"] == "mode" and json.loads(malformed["payload"])["invalid"].startswith("[[[[")


def test_a_replay_refuses_the_mode_inputs_the_live_gateway_refused(tmp_path: Path) -> None:
    """A mode is a bare JSON string; ``{"mode": "manual"}`` (an object) is refused live. It was logged as
    it came, which is also the log's wrapping of a good mode (``{mode}``), so a replay unwrapped it and
    took it: the replay's pipeline went to manual where the live one had refused."""
    import json

    from conftest import wait_for

    from gateway.replay import mcap_events

    with live_gateway(tmp_path) as (service, session):
        session.put("dp/cmd/mode", json.dumps({"mode": "manual"}))
        session.put("dp/cmd/tau", json.dumps({"X": 1.0, "Y": 0.0, "N": 0.0}))
        # (the τ, refused outside manual, says the inputs were handled)
        assert wait_for(lambda: service.pipeline.commands.counters.refused["tau: not in manual"] == 1, 20.0)
        live = service.pipeline.commands.counters
        assert live.refused == {"mode: invalid": 1, "tau: not in manual": 1}
        assert service.pipeline.mode == "standby"
    p = pipeline({"accept": ALL})
    for ev in mcap_events(tmp_path / "c.mcap"):
        if isinstance(ev, ControlEvent):
            p.feed(ev)
    assert p.mode == "standby"
    assert dict(p.commands.counters.refused) == {"mode: invalid": 1, "tau: not in manual": 1}


def test_a_setpoint_waits_while_the_position_estimate_is_lost() -> None:
    """No position fix for 75 s (the heading still comes): the estimate is "lost", its position a dead
    reckoning nobody can check a setpoint's distance against. A setpoint then is not pursued from it; it
    waits, as one before the first estimate does, for an estimate healthy enough for dp, and is checked
    against that."""
    rng = np.random.default_rng(1)
    p = pipeline({"accept": ALL}, initial_mode="dp")
    t = 0.0
    while t < 5.0:
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    while t < 80.0:  # the heading alone
        p.feed(RawEvent(T0 + round(t * S), "gps", enc.hdt("HE", 0.5 + rng.normal(0, 0.001)).encode()))
        t += 0.1
    assert p.estimate_status == "lost"
    p.feed(ControlEvent(T0 + round(t * S), "setpoint", {"north_m": 30.0, "east_m": 0.0, "heading_deg": 30.0}))
    for _ in range(20):
        p.feed(RawEvent(T0 + round(t * S), "gps", enc.hdt("HE", 0.5 + rng.normal(0, 0.001)).encode()))
        t += 0.1
    assert p.controller is not None
    assert abs(float(p.controller.reference.target[0])) < 1.0, "pursued from a lost position estimate"
    assert commands_status(p)["accepted"] == {}
    # a console reads back the setpoint waiting, as sent, and the one in force: the position held
    c = commands_status(p)
    assert c["setpoint_waiting"] == {"north_m": 30.0, "east_m": 0.0, "heading_deg": 30.0}
    assert abs(c["setpoint"]["north_m"]) < 1.0 and abs(c["setpoint"]["east_m"]) < 1.0
    while t < 100.0:  # the fixes are back
        p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        t += 0.1
    assert p.estimate_status == "ok"
    assert commands_status(p)["accepted"] == {"setpoint": 1}
    assert float(p.controller.reference.target[0]) == 30.0
    c = commands_status(p)
    assert "setpoint_waiting" not in c  # (none waits: left out, as null)
    sp = c["setpoint"]
    assert (sp["north_m"], sp["east_m"], sp["heading_deg"]) == pytest.approx((30.0, 0.0, 30.0))
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(30.0, 0.0, 0.0)
    assert (sp["lat_deg"], sp["lon_deg"]) == pytest.approx((lat, lon), abs=1e-9)
    p.feed(ControlEvent(T0 + round(t * S), "mode", "standby"))
    run(p, 0.5, start_s=t)
    assert "setpoint" not in commands_status(p)  # (outside DP there is no station being kept)


# --- the manual τ's dead-man ([commands] manual_tau_hold_s) ----------------------------------------------

EXPIRED = "manual τ expired: no new τ for 2.0 s; thrust demand set to zero"


def manual_run(p: Pipeline, start_s: float, seconds: float, taus_at: tuple[float, ...] = ()) -> list[Any]:
    """Fixes at 10 Hz from ``start_s`` (`run`) with a τ of 1e5 N ahead at each time of ``taus_at``, fed in
    time order: the pipeline's clock is the events' receive times, nothing sleeps."""
    rng = np.random.default_rng(round(start_s * 10))
    pending = sorted(taus_at)
    out = []
    for k in range(int(seconds * 10)):
        t = start_s + k / 10
        while pending and pending[0] <= t + 1e-9:
            p.feed(ControlEvent(T0 + round(pending.pop(0) * S), "tau", {"X": 1e5, "Y": 0.0, "N": 0.0}))
        out += p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
    return out


def surge_demands(out: list[Any]) -> list[tuple[float, float]]:
    """(time s from T0, τ X demanded) of each thruster command."""
    return [
        ((o.stamp_ns - T0) / S, o.payload["tau_demand"][0]) for o in out if o.topic == "/dp/thrusters/command"
    ]


def said(out: list[Any], text: str) -> list[str]:
    """The status events of ``out`` that start with ``text``."""
    return [
        e for o in out if o.topic == "/dp/status" for e in o.payload.get("events", []) if e.startswith(text)
    ]


def logged(out: list[Any], text: str) -> list[str]:
    """The Foxglove log lines (/dp/log) of ``out`` that contain ``text``."""
    return [o.payload["message"] for o in out if o.topic == "/dp/log" and text in o.payload["message"]]


def test_a_manual_tau_expires_after_the_hold_time_and_not_before() -> None:
    """The console sends one τ and dies: the thrusters push for the hold time (2 s by default) and no
    longer; the mode stays manual, the event is said once, the alarm is up and counted, and a fresh τ
    resumes and clears it."""
    p = pipeline({"accept": ALL})  # manual_tau_hold_s: the default, 2 s
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    out = manual_run(p, 2.0, 6.0, taus_at=(2.0,))
    demands = surge_demands(out)
    held = [x for t, x in demands if t <= 4.0 + 1e-9]
    after = [x for t, x in demands if t > 4.0 + 1e-9]
    assert len(held) >= 15 and all(x == 1e5 for x in held), held  # every command of the 2 s: the τ
    assert len(after) >= 30 and all(x == 0.0 for x in after), after  # every one after: zero
    assert p.mode == "manual" and p.manual_tau_expired
    assert said(out, "manual τ expired") == [EXPIRED]
    # the status that said it came with the event's sensor input (4.1 s), not a second later
    stamps = [o.stamp_ns for o in out if o.topic == "/dp/status" and EXPIRED in o.payload.get("events", [])]
    assert stamps == [T0 + round(4.1 * S)]
    status = p.status(p.last_ns).payload
    assert status["commands"]["expired"] == {"tau": 1}
    assert [a for a in status["alarms"] if a.startswith("manual τ expired")] == [
        "manual τ expired: thrust demand zero until a new τ (commands.manual_tau_hold_s = 2 s)"
    ]
    assert logged(out, EXPIRED) and len(logged(out, "alarm: manual τ expired")) == 1  # Foxglove /dp/log
    # a fresh τ resumes at once and clears the alarm (said once on /dp/log)
    out = manual_run(p, 8.0, 1.0, taus_at=(8.0,)) + p.status_outputs(p.last_ns)
    assert all(x == 1e5 for _, x in surge_demands(out)) and surge_demands(out)
    assert not p.manual_tau_expired
    assert not [a for a in p.status(p.last_ns).payload["alarms"] if "manual τ" in a]
    assert len(logged(out, "alarm cleared: manual τ expired")) == 1
    assert commands_status(p)["expired"] == {"tau": 1} and commands_status(p)["accepted"]["tau"] == 2


def test_a_manual_tau_renewed_within_the_hold_time_never_expires() -> None:
    """A console that sends its τ every 1.5 s (under the 2 s hold) keeps the thrusters on it throughout."""
    p = pipeline({"accept": ALL})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    out = manual_run(p, 2.0, 10.0, taus_at=tuple(2.0 + 1.5 * k for k in range(7)))
    demands = surge_demands(out)
    assert len(demands) >= 90 and all(x == 1e5 for _, x in demands)
    assert not said(out, "manual τ expired") and "expired" not in commands_status(p)


def test_a_manual_tau_hold_of_inf_holds_it_until_the_next_one() -> None:
    p = pipeline({"accept": ALL, "manual_tau_hold_s": math.inf})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    out = manual_run(p, 2.0, 20.0, taus_at=(2.0,))
    demands = surge_demands(out)
    assert len(demands) >= 190 and all(x == 1e5 for _, x in demands)
    assert not said(out, "manual τ expired") and "expired" not in commands_status(p)
    assert not [a for a in p.status(p.last_ns).payload["alarms"] if "manual τ" in a]


def test_the_hold_time_is_configurable_and_counts_each_expiry() -> None:
    """0.5 s: each τ pushes for half a second; two τ that both die are two expiries, two events."""
    p = pipeline({"accept": ALL, "manual_tau_hold_s": 0.5})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    out = manual_run(p, 2.0, 4.0, taus_at=(2.0, 4.0))
    demands = surge_demands(out)
    assert all(x == 1e5 for t, x in demands if 2.0 <= t <= 2.5 + 1e-9 or 4.0 <= t <= 4.5 + 1e-9)
    assert all(x == 0.0 for t, x in demands if 2.6 - 1e-9 <= t < 4.0 or t >= 4.6 - 1e-9)
    assert (
        said(out, "manual τ expired")
        == ["manual τ expired: no new τ for 0.5 s; thrust demand set to zero"] * 2
    )
    assert commands_status(p)["expired"] == {"tau": 2}


def test_leaving_manual_clears_an_expired_tau_alarm() -> None:
    p = pipeline({"accept": ALL})
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    manual_run(p, 2.0, 3.0, taus_at=(2.0,))
    assert p.manual_tau_expired
    p.feed(ControlEvent(T0 + 5 * S, "mode", "standby"))
    assert not [a for a in p.status(p.last_ns).payload["alarms"] if "manual τ" in a]


# --- setpoints dropped unapplied, τ outside manual -------------------------------------------------------


def test_a_setpoint_replaced_while_it_waited_is_counted_as_superseded() -> None:
    """Two setpoints before the first estimate: the first was never applied. It is counted and said, not
    lost without a trace; the second is applied."""
    p = pipeline({"accept": ALL}, initial_mode="dp")
    p.feed(ControlEvent(T0, "setpoint", {"north_m": 20.0, "east_m": 0.0, "heading_deg": 30.0}))
    p.feed(ControlEvent(T0, "setpoint", {"north_m": 10.0, "east_m": 5.0, "heading_deg": 40.0}))
    out = run(p, 3.0)
    c = commands_status(p)
    assert c["superseded"] == {"setpoint": 1} and c["accepted"] == {"setpoint": 1}
    assert p.setpoint == {"north_m": 10.0, "east_m": 5.0, "heading_deg": 40.0}
    assert said(out, "setpoint superseded") == [
        "setpoint superseded: (north 20.0 m, east 0.0 m, heading 30.0°) dropped unapplied, replaced by a "
        "newer one; it waited for an estimate healthy enough for dp (the estimate is not there yet)"
    ]
    assert logged(out, "setpoint superseded")  # on Foxglove's /dp/log too
    # one applied before the next arrives is not superseded
    p.feed(ControlEvent(T0 + 3 * S, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 30.0}))
    run(p, 1.0, 3.1)
    assert commands_status(p)["superseded"] == {"setpoint": 1}


@pytest.mark.parametrize("mode", ["standby", "dp"])
def test_a_tau_outside_manual_is_refused_not_taken(mode: str) -> None:
    p = pipeline({"accept": ALL}, initial_mode=mode)
    run(p, 2.0)
    p.feed(ControlEvent(T0 + 2 * S, "tau", {"X": 1e5, "Y": 0.0, "N": 0.0}))
    c = commands_status(p)
    assert c["accepted"] == {} and c["refused"] == {"tau: not in manual": 1}
    assert c["last_refused"] == f"τ ignored: mode is {mode} (a τ is taken in manual only)"
    assert [r.text for r in p.commands.take_refusals()] == [c["last_refused"]]  # for the service's log
    assert not p.manual_tau.any()
    # and it is not applied on entering manual either: manual starts from τ = 0
    p.feed(ControlEvent(T0 + 2 * S, "mode", "manual"))
    out = run(p, 1.0, 2.1)
    assert surge_demands(out) and all(x == 0.0 for _, x in surge_demands(out))


def test_every_accepted_mode_change_is_an_event_on_the_log_and_a_refused_one_is_not() -> None:
    """dp -> manual -> standby by the operator: each change is a status event (`mode: dp -> manual
    (operator)`) and an INFO line on /dp/log; a mode command that changes nothing, or one refused, says
    no mode change."""
    p = pipeline({"accept": ALL}, initial_mode="standby")
    out = run(p, 2.0)
    for k, mode in enumerate(("dp", "dp", "manual", "standby")):
        t = 2.0 + 2 * k
        p.feed(ControlEvent(T0 + round(t * S), "mode", mode))
        out += run(p, 2.0, start_s=t)
        out += p.status_outputs(T0 + round((t + 2.0) * S))
    assert said(out, "mode: ") == [
        "mode: standby -> dp (operator)",
        "mode: dp -> manual (operator)",
        "mode: manual -> standby (operator)",
    ]
    lines = [o.payload for o in out if o.topic == "/dp/log" and o.payload["message"].startswith("mode: ")]
    assert [(x["level"], x["message"]) for x in lines] == [
        (2, "mode: standby -> dp (operator)"),  # INFO
        (2, "mode: dp -> manual (operator)"),
        (2, "mode: manual -> standby (operator)"),
    ]
    # refused (no estimate yet): no mode change said
    q = pipeline({"accept": ALL}, initial_mode="standby")
    q.feed(ControlEvent(T0, "mode", "dp"))
    assert q.mode == "standby"
    assert not said(q.status_outputs(T0 + S), "mode: ")


def test_the_gateways_own_engagement_is_a_mode_change_saying_who_and_why() -> None:
    """``initial_mode = "dp"`` waiting for the observer: the gateway's engagement once it has settled is
    said as a mode change, by the gateway and why, on /dp/log too."""
    p = pipeline(initial_mode="dp", wait_for_observer=True)
    settle = p.settle_left_s(T0)
    out = run(p, settle + 2.0)
    out += p.status_outputs(p.last_ns)
    assert p.mode == "dp"
    assert said(out, "mode: ") == [
        "mode: standby -> dp (by the gateway, control.wait_for_observer): observer settled: DP engaged"
    ]
    assert logged(out, "mode: standby -> dp (by the gateway")


def test_entering_manual_from_dp_at_thrust_raises_no_saturation_alarm() -> None:
    """In DP, pushing towards a setpoint 9 m off; then manual (τ = 0 until the operator's next): the
    thrusters ramp down at their rates, the first commands fall short (`saturated`), and no status says
    "thrust allocation saturated" for a demand of zero they are ramping to."""
    p = pipeline({"accept": ALL}, initial_mode="dp")
    run(p, 3.0)
    p.feed(ControlEvent(T0 + 3 * S, "setpoint", {"north_m": 8.0, "east_m": 4.0, "heading_deg": 40.0}))
    run(p, 20.0, start_s=3.0)
    assert p.command is not None and np.max(np.abs(p.command.thrust)) > 5e4  # pushing hard
    p.feed(ControlEvent(T0 + 23 * S, "mode", "manual"))
    rng = np.random.default_rng(9)
    short, alarms = 0, []
    for k in range(30):
        t = 23.0 + k / 10
        out = p.feed(RawEvent(T0 + round(t * S), "gps", moving_fix(t, 0.0, rng)))
        short += sum(o.payload["saturated"] for o in out if o.topic == "/dp/thrusters/command")
        alarms += p.status(T0 + round(t * S)).payload["alarms"]
    assert short >= 2  # it did fall short while ramping down
    assert not [a for a in alarms if "saturated" in a], alarms


def test_one_consoles_inputs_on_different_keys_are_taken_in_the_order_sent(tmp_path: Path) -> None:
    """A console engages manual and streams its joystick's τ at once: the τ must not overtake the mode.
    Each input key has its own subscriber, and Zenoh ran each subscriber's Python callback on a thread of
    its own, so a τ put right after ``manual`` could be taken first and refused (``not in manual``)."""
    import json

    from conftest import wait_for

    rounds = 40
    with live_gateway(tmp_path) as (service, session):
        for k in range(rounds):
            session.put("dp/cmd/mode", json.dumps("manual"))
            session.put("dp/cmd/tau", json.dumps({"X": float(k + 1), "Y": 0.0, "N": 0.0}))
            session.put("dp/cmd/mode", json.dumps("standby"))
        counters = service.pipeline.commands.counters
        handled = lambda: sum(counters.accepted.values()) + sum(counters.refused.values())  # noqa: E731
        assert wait_for(lambda: handled() >= 3 * rounds, 30.0)
        assert dict(counters.refused) == {}, counters.refused
        assert counters.accepted["tau"] == rounds


def test_a_setpoint_waiting_when_the_plant_starts_again_is_refused_and_said_not_dropped_unseen() -> None:
    """A setpoint sent before the first estimate waits to be applied. The simulator under the gateway
    starts again (`Pipeline.start_over`): the new run starts without a setpoint, and the waiting one went
    with the old pipeline without a count or a word, so the console believed it on its way."""
    p = pipeline({"accept": ALL}, initial_mode="dp")
    p.feed(ControlEvent(T0, "setpoint", {"north_m": 5.0, "east_m": 0.0, "heading_deg": 30.0}))
    assert commands_status(p)["setpoint_waiting"] == {"north_m": 5.0, "east_m": 0.0, "heading_deg": 30.0}
    new = p.start_over(p.spec, "clock: the simulator started again")
    status = new.status(T0 + S).payload  # (the first status takes the events)
    c = status["commands"]
    assert "setpoint_waiting" not in c
    assert c["refused"] == {"setpoint: dropped at restart": 1}
    (refusal,) = new.commands.take_refusals()
    assert "dropped unapplied: the plant started again" in refusal.text and "send it again" in refusal.text
    events = status["events"]
    assert events.index("clock: the simulator started again") < events.index(refusal.text)
    # nothing waiting: nothing said
    again = new.start_over(new.spec, "clock: the simulator started again")
    assert sum(commands_status(again)["refused"].values()) == 1


def test_a_refusal_shows_the_payload_as_it_was_sent() -> None:
    """Bytes that were no JSON showed the service's wrapper (`mode {'invalid': 'garbage{'} is not one of
    ...`), and JSON objects as Python reprs (`tau {'X': 1, 'Y': 2}`); now what was put on the key."""
    p = pipeline({"accept": ALL})
    p.feed(ControlEvent(T0, "mode", {"invalid": "garbage{"}))  # (as the service hands on what no JSON parses)
    text = commands_status(p)["last_refused"]
    assert "mode 'garbage{' (not valid JSON) is not one of" in text and "invalid" not in text, text
    p.feed(ControlEvent(T0, "tau", {"X": 1, "Y": 2}))
    text = commands_status(p)["last_refused"]
    assert 'tau {"X": 1, "Y": 2}: expected' in text, text
