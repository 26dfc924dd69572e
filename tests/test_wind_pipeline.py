"""The gateway's wind input: a source with role ``wind`` feeds the controller's wind feed-forward through the
fusion; a bad, invalid or stale anemometer is counted and flagged, and the gateway keeps station."""

from __future__ import annotations

import logging
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dpgw.closed_loop import gateway_tables, run_closed_loop
from gateway.config import ConfigError, describe, parse_config, wind_feedforward_line
from gateway.pipeline import WIND_ON_CONFIRM_S, Pipeline, PipelineSpec, RawEvent
from simulator.faults import Fault
from simulator.scenarios import get_scenario
from wire.codecs import nmea_encode as enc

NS = 1_000_000_000


def events_of(run: Any) -> list[tuple[float, str]]:
    out = []
    for status in run.collected.get("/dp/status", []):
        out += [(status["stamp_ns"], e) for e in status["events"] if "wind feed-forward" in e]
    return out


def test_stale_and_corrupt_anemometer_is_flagged_and_the_gateway_keeps_station() -> None:
    """Wind bytes with bad checksums and line noise, then 40 s of silence: the rejects are counted, the
    feed-forward goes off once (an event) and back on once when the wind has returned for
    `WIND_ON_CONFIRM_S`; estimates and commands never stop and the vessel stays within a few metres."""
    base = get_scenario("mss_supply_storm")
    scenario = replace(
        base,
        faults=(
            Fault("bad_checksum", "wind1", 20.0, 40.0, {"probability": 0.5}),
            Fault("garbage", "wind1", 20.0, 40.0, {"probability": 0.5}),
            Fault("dropout", "wind1", 60.0, 100.0),
        ),
    )
    run = run_closed_loop(scenario, 150.0, seed=2, wire=True, collect=("/dp/status",))
    wind = run.status["sources"]["wind1"]
    assert wind["rejected"].get("bad_checksum", 0) > 5 and wind["received"] > 150
    events = events_of(run)
    on = "wind feed-forward on: wind from wind1"
    off = "wind feed-forward fading out over 286 s: no valid wind from wind1 within the source timeout"
    texts = [e for _, e in events]
    # said once per change: on and off alternate, starting and ending on; back after a loss the force
    # fades in over what is left of the fade (the dropout took ≈ 40 s of 286 s off, ≈ 10 s came back)
    assert texts[0] == on and texts[-1].startswith(on) and len(texts) % 2 == 1, texts
    assert all(e.startswith(on) if k % 2 == 0 else e == off for k, e in enumerate(texts)), texts
    rest = re.fullmatch(re.escape(on) + r", fading in over (\d+) s", texts[-1])
    assert rest is not None and 15 <= int(rest.group(1)) <= 40, texts[-1]
    t0 = run.collected["/dp/status"][0]["stamp_ns"] - run.collected["/dp/status"][0]["stamp_ns"] % NS
    times = [(t - t0) / NS for t, _ in events]
    offs = [t for t, e in zip(times, texts, strict=True) if e == off]
    # off only where the wind was missing for longer than the source's timeout (2 s): half the sentences
    # corrupted (20-40 s) can do that, and the dropout (60-100 s) does, within a control tick or two
    assert all(20.0 < t < 42.5 or 60.0 < t < 62.5 for t in offs), times
    assert any(60.0 < t < 62.5 for t in offs)
    # back on once the wind has held for WIND_ON_CONFIRM_S (10 s) after the dropout
    assert 100.0 + WIND_ON_CONFIRM_S <= times[-1] < 101.0 + WIND_ON_CONFIRM_S
    ons = [t for t, e in zip(times, texts, strict=True) if e.startswith(on)]
    assert all(b - a >= WIND_ON_CONFIRM_S for a, b in zip(offs, ons[1:], strict=True))  # no flapping
    stale_alarms = [
        a for s in run.collected["/dp/status"] for a in s["alarms"] if a.startswith("source wind1: stale")
    ]
    assert stale_alarms  # the per-source alarm while it is silent
    t_est = np.array([e.stamp_ns for e in run.estimate_messages]) / NS
    assert np.max(np.diff(t_est)) < 1.0  # estimates throughout
    t_cmd = np.array([c.stamp_ns for c in run.command_messages]) / NS
    assert np.max(np.diff(t_cmd)) < 0.5  # and commands
    pos = np.hypot(run.eta_lf[:, 0], run.eta_lf[:, 1])
    assert pos.max() < 10.0


def pipeline_for(**control: Any) -> Pipeline:
    tables = gateway_tables(get_scenario("mss_supply_storm"), **control)
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


def test_invalid_and_malformed_mwv_are_counted_not_used() -> None:
    p = pipeline_for()
    t = 1_700_000_000 * NS
    sentences = [
        enc.mwv("WI", math.radians(40.0), 15.0, "R", "M", valid=False),  # status V
        "$WIMWV,40.0,R,15.0,M,X*" + enc.checksum("WIMWV,40.0,R,15.0,M,X") + "\r\n",  # bad status
        "$WIMWV,40.0,R,15.0,F,A*" + enc.checksum("WIMWV,40.0,R,15.0,F,A") + "\r\n",  # unknown unit
        "$WIMWV,40.0,R,15.0,M,A*00\r\n",  # bad checksum
    ]
    for k, text in enumerate(sentences):
        p.feed(RawEvent(t + k * NS // 10, "wind1", text.encode("ascii")))
    c = p.counters["wind1"]
    assert dict(c.rejected) == {"wind_invalid": 1, "bad_field": 2, "bad_checksum": 1}
    assert p.fusion.wind(t + NS) is None
    p.feed(RawEvent(t + NS, "wind1", enc.mwv("WI", math.radians(90.0), 10.0).encode("ascii")))
    u, v, reference, source = p.fusion.wind(t + NS) or (0, 0, "", "")
    assert (u, v, reference, source) == (pytest.approx(0.0, abs=1e-12), pytest.approx(10.0), "R", "wind1")
    assert p.fusion.wind(t + NS + 3 * NS) is None  # older than the source's timeout (2 s)


def test_start_up_says_once_why_the_wind_feedforward_is_off() -> None:
    scenario = get_scenario("mss_supply_storm")
    tables = gateway_tables(scenario)
    config = parse_config(tables, base_dir=Path.cwd())
    assert wind_feedforward_line(config) == "wind feed-forward on: from wind1, gain 1, filter 2 s"
    assert "  wind feed-forward on: from wind1" in describe(config)
    assert Pipeline(PipelineSpec.from_config(config)).wind_feedforward == "no wind measured yet"
    no_wind = dict(tables, sources=[s for s in tables["sources"] if s["name"] != "wind1"])
    config = parse_config(no_wind, base_dir=Path.cwd())
    why = 'no source has role "wind" (an anemometer sending MWV)'
    assert wind_feedforward_line(config) == f"wind feed-forward off: {why}"
    p = Pipeline(PipelineSpec.from_config(config))
    assert p.status_message(1).events == [f"wind feed-forward off: {why}"]
    assert p.status_message(2).events == []  # once
    small = gateway_tables(get_scenario("hassani"))  # cybership2: no [hull.wind]
    small["sources"].append(dict(tables["sources"][-2]))  # the wind source
    assert small["sources"][-1]["roles"] == ["wind"]
    assert wind_feedforward_line(parse_config(small, base_dir=Path.cwd())) == (
        "wind feed-forward off: vessel 'cybership2' has no wind areas ([hull.wind], docs/vessels.md)"
    )
    off = gateway_tables(scenario, wind_feedforward_gain=0)
    assert wind_feedforward_line(parse_config(off, base_dir=Path.cwd())) == (
        "wind feed-forward off: control.wind_feedforward_gain = 0"
    )


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("wind_feedforward_gain", 1.5, "control.wind_feedforward_gain"),
        ("wind_feedforward_gain", -0.1, "control.wind_feedforward_gain"),
        ("wind_filter_s", 0.0, "control.wind_filter_s"),
        ("wind_filter_s", "fast", "control.wind_filter_s"),
        ("wind_loss_fade_s", -1.0, "control.wind_loss_fade_s"),
        ("wind_loss_fade_s", 7200.0, "control.wind_loss_fade_s"),
        ("wind_loss_fade_s", "slow", "control.wind_loss_fade_s"),
    ],
)
def test_bad_wind_tuning_stops_start_up_naming_the_key(key: str, value: Any, words: str) -> None:
    tables = gateway_tables(get_scenario("mss_supply_storm"), **{key: value})
    with pytest.raises(ConfigError, match=words.replace(".", r"\.")):
        parse_config(tables, base_dir=Path.cwd())


def test_the_loss_fade_is_configured_or_derived() -> None:
    """[control] wind_loss_fade_s reaches the controller; without it the fade is twice the slower of the
    integral time (143 s for mss_supply) and the observer's bias mode (96 s here): 286 s; 0 drops at once."""
    assert pipeline_for(wind_loss_fade_s=120).controller.wind.fade_s == 120.0  # type: ignore[union-attr]
    assert pipeline_for(wind_loss_fade_s=0).controller.wind.fade_s == 0.0  # type: ignore[union-attr]
    p = pipeline_for()
    ctl = p.controller
    assert ctl is not None and ctl.wind is not None
    from gateway.control.wind_feedforward import observer_bias_time_s

    t_b = observer_bias_time_s(p.observer)
    t_i = 1.0 / float(ctl.gains.integral_pole.min())
    assert t_b is not None and t_b < t_i
    assert ctl.wind.fade_s == pytest.approx(2.0 * t_i) == pytest.approx(285.714, rel=1e-5)


def test_a_lost_wind_stays_a_known_load_of_the_observer_while_it_fades() -> None:
    """The observer's τ is τ − τ_wind while a lost wind fades (b̂ takes the force as it is taken off), and
    the plain τ once the fade is done; the status says "fading out" once."""
    from observers.base import Estimate

    p = pipeline_for(wind_loss_fade_s=20.0)
    ctl = p.controller
    assert ctl is not None and ctl.wind is not None
    est = Estimate(0.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), "ok")
    t0 = 1_700_000_000 * NS
    tau = np.array([1e4, -2e4, 3e5])
    events: list[str] = []
    for k in range(600):  # 60 s at 10 Hz: wind for 10 s, then none
        now = t0 + k * NS // 10
        if k < 100 and k % 5 == 0:
            p.feed(RawEvent(now, "wind1", enc.mwv("WI", math.radians(60.0), 18.0).encode("ascii")))
        ctl.wind.update(0.0 if k == 0 else 0.1, p._relative_wind(now, est))
        events += [e for e in p.status_message(now).events if "wind feed-forward" in e]
        if k == 99:
            full = ctl.wind.tau.copy()
            np.testing.assert_array_equal(p._with_wind_load(tau), tau - full)
        if k == 100 + 20 + 100:  # 10 s into the fade (the wind went stale 2 s after the last sentence)
            assert ctl.wind.fading and np.all(np.abs(ctl.wind.tau) < np.abs(full))
            assert np.all(np.abs(ctl.wind.tau) > 0.3 * np.abs(full))
            np.testing.assert_array_equal(p._with_wind_load(tau), tau - ctl.wind.tau)
    assert not ctl.wind.fading and np.all(ctl.wind.tau == 0)
    np.testing.assert_array_equal(p._with_wind_load(tau), tau)
    assert events == [
        "wind feed-forward on: wind from wind1",
        "wind feed-forward fading out over 20 s: no valid wind from wind1 within the source timeout",
    ]


def test_wind_role_is_for_nmea_sources_only() -> None:
    tables = gateway_tables(get_scenario("mss_supply_storm"))
    for s in tables["sources"]:
        if s["name"] == "thrusters":
            s["roles"] = ["thrusters", "wind"]
    with pytest.raises(ConfigError, match='role "wind" is not available for protocol "mavlink"'):
        parse_config(tables, base_dir=Path.cwd())


@pytest.mark.slow
def test_the_observer_is_told_the_wind_force_so_its_bias_is_the_rest() -> None:
    """With the feed-forward on, the observer's τ input includes the wind force the feed-forward answers, so
    b̂ no longer holds the wind (else the bias feed-forward would cancel the wind a second time): over the
    last 200 s of 600 s on mss_supply_wind, b̂ without the feed-forward minus b̂ with it is the mean wind
    force (earth axes) within 10 % per axis."""
    from simulator.scenarios import mss_supply_wind

    scenario = mss_supply_wind()
    runs = {
        gain: run_closed_loop(
            scenario, 600.0, seed=1, tables=gateway_tables(scenario, wind_feedforward_gain=gain)
        )
        for gain in (0.0, 1.0)
    }
    bias = {}
    for gain, run in runs.items():
        t = np.array([e.stamp_ns for e in run.estimate_messages]) / NS
        b = np.array([e.bias for e in run.estimate_messages])
        bias[gain] = b[t >= t[-1] - 200.0].mean(axis=0)
    # the mean wind force on the vessel at its heading, earth axes (at rest: the vessel barely moves)
    from observers.hull import relative_wind, relative_wind_force

    wind = scenario.wind
    assert wind is not None and scenario.vessel.hull is not None and scenario.vessel.hull.wind is not None
    from simulator.wind import norsok_mean

    area = scenario.vessel.hull.wind
    mean = norsok_mean(wind.speed_mps, area.height_m)
    psi = scenario.eta0[2]
    x, y, n = relative_wind_force(
        area, scenario.vessel.length_m, *relative_wind(mean, wind.from_deg, psi, 0, 0)
    )
    c, s = math.cos(psi), math.sin(psi)
    earth = np.array([c * x - s * y, s * x + c * y, n])
    diff = bias[0.0] - bias[1.0]
    # measured: (65.5 kN, -92.9 kN, -1028 kN·m) against (68.0, -97.5, -1049): within 5 %
    assert np.all(np.abs(diff - earth) <= 0.1 * np.abs(earth)), (diff, earth)


@pytest.mark.parametrize("from_deg", [20.0, 110.0, 200.0, 300.0])
@pytest.mark.parametrize(("psi", "u", "v"), [(0.0, 1.5, 0.0), (0.9, 0.8, -0.6), (-2.4, -0.5, 1.2)])
def test_true_wind_gives_the_feedforward_of_the_relative_wind_it_makes(
    from_deg: float, psi: float, u: float, v: float
) -> None:
    """The same true wind on a moving vessel, sent as MWV reference T (true, still relative to the bow) to
    one gateway and as the apparent wind it makes, reference R, to another: the controller's wind input
    and the feed-forward τ are the same (the T path adds ν̂, u_rw = u + V_t cos β_t)."""
    from observers.base import Estimate
    from observers.hull import relative_wind

    speed = 14.0
    urw, vrw = relative_wind(speed, from_deg, psi, u, v)
    sent = {
        "R": (math.atan2(vrw, urw), math.hypot(urw, vrw)),
        "T": (math.radians(from_deg) - psi, speed),  # the true wind's angle from the bow
    }
    est = Estimate(1.0, np.array([0.0, 0.0, psi]), np.array([u, v, 0.01]), np.zeros(3), np.zeros(3), "ok")
    t = 1_700_000_000 * NS
    got, tau = {}, {}
    for reference, (angle, spd) in sent.items():
        p = pipeline_for()
        angle = math.remainder(angle, 2 * math.pi) % (2 * math.pi)
        text = enc.mwv("WI", angle, spd, reference, decimals=6)
        p.feed(RawEvent(t, "wind1", text.encode("ascii")))
        assert p.fusion.wind(t) is not None and p.fusion.wind(t)[2] == reference  # type: ignore[index]
        wind = p._relative_wind(t, est)
        assert wind is not None
        got[reference] = wind
        ctl = p.controller
        assert ctl is not None and ctl.wind is not None
        ctl.wind.update(0.0, wind)  # the filter's first sample: dt 0 keeps it at zero
        for _ in range(300):
            ctl.wind.update(0.1, wind)  # 30 s = 15 T_w: converged
        tau[reference] = ctl.wind.tau.copy()
    np.testing.assert_allclose(got["T"], got["R"], rtol=0, atol=1e-5)
    np.testing.assert_allclose(got["R"], (urw, vrw), rtol=0, atol=1e-5)
    scale = np.abs(tau["R"]).max()
    assert scale > 1e3  # a real force (N), not two zeros
    np.testing.assert_allclose(tau["T"], tau["R"], rtol=0, atol=1e-5 * scale)


def test_a_flapping_anemometer_is_said_off_once_and_on_once_it_holds() -> None:
    """An anemometer that loses six sentences in seven (2 Hz: a good one every 3.5 s, gaps beyond its 2 s
    timeout) for 60 s, then sends cleanly: the feed-forward uses each fresh wind at once (as before), but
    the status says "off" once and "on" once, when the wind has held for `WIND_ON_CONFIRM_S` — not "on",
    "off" at every good sentence (before: 35 events)."""
    from observers.base import Estimate

    p = pipeline_for()
    ctl = p.controller
    assert ctl is not None and ctl.wind is not None
    est = Estimate(0.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), "ok")
    t0 = 1_700_000_000 * NS
    good = enc.mwv("WI", math.radians(40.0), 15.0).encode("ascii")
    bad = b"$WIMWV,40.0,R,15.0,M,A*00\r\n"  # bad checksum
    events: list[tuple[float, str]] = []
    used = []
    for k in range(1000):  # 100 s at the control rate, 10 Hz
        now = t0 + k * NS // 10
        if k % 5 == 0:  # an MWV every 0.5 s: from 5 s to 65 s six of seven are corrupt
            n = k // 5
            p.feed(RawEvent(now, "wind1", good if not (10 <= n < 130) or n % 7 == 0 else bad))
        wind = p._relative_wind(now, est)
        ctl.wind.update(0.0 if k == 0 else 0.1, wind)  # (as the control step does: the weight it says)
        used.append(wind is not None)
        events += [((now - t0) / NS, e) for e in p.status_message(now).events if "wind feed-forward" in e]
    on, off = (
        "wind feed-forward on: wind from wind1",
        ("wind feed-forward fading out over 286 s: no valid wind from wind1 within the source timeout"),
    )
    assert p.counters["wind1"].rejected["bad_checksum"] > 90
    # the feed-forward itself still follows the wind: on for 2 s after each good sentence of the flapping
    flapping = np.array(used[70:650])
    assert 0.4 < flapping.mean() < 0.8 and np.count_nonzero(np.diff(flapping.astype(int)) == -1) > 10
    assert [e for _, e in events] == [on, off, on], events
    t_on, t_off, t_back = (t for t, _ in events)
    assert t_on == 0.0 and 6.5 < t_off < 7.5  # the last good sentence before the flapping at 4.5 s
    clean = 0.5 * max(n for n in range(10, 130) if n % 7 == 0)  # 63 s: unbroken fresh wind from here
    assert clean + WIND_ON_CONFIRM_S <= t_back < clean + WIND_ON_CONFIRM_S + 0.2


def test_a_wind_lost_again_while_fading_in_is_said_to_fade_out_over_what_is_left() -> None:
    """The wind lost, faded out completely, back long enough to be said "on" (fading in over what is left
    of the 20 s), then lost again before it is fully in: the force fades from where the fade-in got to,
    over that fraction of the 20 s, and the status says that time, not the whole fade time."""
    from observers.base import Estimate

    p = pipeline_for(wind_loss_fade_s=20.0)
    ctl = p.controller
    assert ctl is not None and ctl.wind is not None
    est = Estimate(0.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), "ok")
    t0 = 1_700_000_000 * NS
    events: list[str] = []
    weight_at_loss = None
    for k in range(1000):  # 100 s at 10 Hz: wind 0-10 s, none 10-40 s, back 40-56 s, none after
        now = t0 + k * NS // 10
        if (k < 100 or 400 <= k < 560) and k % 5 == 0:
            p.feed(RawEvent(now, "wind1", enc.mwv("WI", math.radians(60.0), 18.0).encode("ascii")))
        wind = p._relative_wind(now, est)
        new = [e for e in p.status_message(now).events if "wind feed-forward" in e]
        if k > 560 and any("fading out" in e for e in new):
            weight_at_loss = ctl.wind.weight
        ctl.wind.update(0.0 if k == 0 else 0.1, wind)
        events += new
    assert weight_at_loss is not None and 0.6 < weight_at_loss < 0.95
    assert len(events) == 4 and events[2].startswith("wind feed-forward on: wind from wind1, fading in over")
    said = re.fullmatch(r"wind feed-forward fading out over (\d+) s: .*", events[3])
    assert said is not None, events
    assert abs(int(said.group(1)) - weight_at_loss * 20.0) <= 0.6, (events[3], weight_at_loss)


def test_the_gateways_text_log_says_the_wind_feedforward_off_once(caplog: pytest.LogCaptureFixture) -> None:
    """Said at start-up (before any input) and carried by the first logged status as an event, whose
    events also go to the text log: the text log has it once."""
    from gateway.service import GatewayService

    tables = gateway_tables(get_scenario("mss_supply_storm"))
    tables["sources"] = [s for s in tables["sources"] if s["name"] != "wind1"]
    line = 'wind feed-forward off: no source has role "wind" (an anemometer sending MWV)'
    with caplog.at_level(logging.INFO, logger="dpgw"):
        service = GatewayService(parse_config(tables, base_dir=Path.cwd()), config_tables=tables)
        status = service.pipeline.status(1)
        assert line in status.message.events
        service._emit([status])
        service._emit([service.pipeline.status(2)])
    assert [r.getMessage() for r in caplog.records].count(line) == 1


def test_a_vessel_without_an_anemometer_is_information_not_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """No source of wind is a configuration, not a fault: its "wind feed-forward off" is said at info
    (``journalctl -p warning`` of every start showed it), at start-up and when the pipeline starts over
    (a simulator restarted under the gateway) and says it again; the wind lost while running stays a
    warning (in other words: the source that went quiet)."""
    from gateway.service import GatewayService

    tables = gateway_tables(get_scenario("mss_supply_storm"))
    tables["sources"] = [s for s in tables["sources"] if s["name"] != "wind1"]
    line = 'wind feed-forward off: no source has role "wind" (an anemometer sending MWV)'
    with caplog.at_level(logging.DEBUG, logger="dpgw"):
        config = parse_config(tables, base_dir=Path.cwd())
        service = GatewayService(config, config_tables=tables)
        service._emit([service.pipeline.status(1)])
        service.pipeline = service.pipeline.start_over(
            PipelineSpec.from_config(config), "the simulator restarted"
        )
        status = service.pipeline.status(2)
        assert line in status.message.events
        service._emit([status])
    levels = [r.levelno for r in caplog.records if r.getMessage() == line]
    assert levels == [logging.INFO, logging.INFO], levels


def test_the_gateways_text_log_says_the_start_mode_once(caplog: pytest.LogCaptureFixture) -> None:
    """With ``initial_mode = "dp"`` the start mode is said at start-up in the service's words, and the
    pipeline's start-up event of it (in the first logged status, for /status and the log) is not said
    again in the text log."""
    from gateway.config import start_mode_line
    from gateway.service import GatewayService

    tables = gateway_tables(get_scenario("mss_supply_storm"), wait_for_observer=True)
    with caplog.at_level(logging.INFO, logger="dpgw"):
        service = GatewayService(parse_config(tables, base_dir=Path.cwd()), config_tables=tables)
        status = service.pipeline.status(1)
        assert any(e.startswith("initial mode dp: standby") for e in status.message.events)
        service._emit([status])
    said = [r.getMessage() for r in caplog.records]
    assert said.count(start_mode_line(service.config)) == 1
    assert not [m for m in said if m.startswith("initial mode dp")]
