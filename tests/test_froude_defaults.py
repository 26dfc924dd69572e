"""Model-scale (Froude) defaults: the one √λ (`observers.froude.froude_scaled`), the gain-scheduled observer's
step, ramp and tuning on a model, and a scenario's observer settings applied the one way by the study, the
replay, the in-process closed loop and `dpgw demo` (the `hassani` full-scale range, adaptive SDRE too).

Data for the step test: the shared basin sea of the model-scale tests (tests/basin_sea.py)."""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from basin_sea import DEFAULT_SEA, MODEL, SHIPS, basin
from basin_sea import SCALE as R
from conftest import simulator_log

from observers.froude import froude_scaled, scaled_frequencies
from observers.gain_scheduled import (
    DEFAULT_TUNING,
    H_MAX_S,
    RAMP_TIME_CONSTANT_S,
    GainScheduledObserver,
    _initial_for_range,
)
from observers.passive_tuning import PassiveTuning, froude_scaled_fields
from observers.vessel import load_vessel
from observers.wave_frequency import WaveFrequencyConfig
from simulator.scenarios import FULL_SCALE_OMEGA_RANGE, get_scenario

REPO = Path(__file__).resolve().parents[1]

HASSANI_RANGE = {"omega_min": 0.3, "omega_max": 1.6}


# --- the one √λ -------------------------------------------------------------------------------------------


def test_froude_scaled_is_the_one_square_root() -> None:
    assert froude_scaled(0.3, 70.0, "frequency") == 0.3 * R
    assert froude_scaled(300.0, 70.0, "time") == 300.0 / R
    x = np.array([0.3, 1.6])
    assert froude_scaled(x, 1.0, "frequency") is x  # a ship's numbers are the very same
    with pytest.raises(ValueError, match="kind"):
        froude_scaled(1.0, 4.0, "length")  # type: ignore[arg-type]
    # every user goes through it: the estimator, the tuning, the wave band, the start of ω0
    c = WaveFrequencyConfig.for_vessel(MODEL)
    d = WaveFrequencyConfig()
    assert (c.omega_min, c.omega_max) == (froude_scaled(d.omega_min, 70.0, "frequency"), d.omega_max * R)
    assert (c.window_s, c.update_period_s, c.segment_s, c.max_gap_s) == tuple(
        froude_scaled(v, 70.0, "time") for v in (d.window_s, d.update_period_s, d.segment_s, d.max_gap_s)
    )
    assert WaveFrequencyConfig().scaled(1 / 70) == WaveFrequencyConfig().for_model(70.0)
    assert froude_scaled_fields({"omega0": 0.9, "bias_time_constant_s": 1000.0}, 70.0) == {
        "omega0": 0.9 * R,
        "bias_time_constant_s": 1000.0 / R,
    }
    assert scaled_frequencies((0.2, 2.0), 70.0) == (0.2 * R, 2.0 * R)
    w = np.full(3, 0.9)
    assert np.all(_initial_for_range(w, c, 70.0) == w * R)
    assert np.all(_initial_for_range(w * R, WaveFrequencyConfig(), 70.0) == w * R / R)


# --- the gain-scheduled observer's step, ramp and tuning --------------------------------------------------


@pytest.mark.parametrize("name", SHIPS)
def test_a_full_scale_vessel_keeps_todays_gain_scheduled_defaults_field_by_field(name: str) -> None:
    obs = GainScheduledObserver(load_vessel(name))
    assert obs.h_max == 0.1 and H_MAX_S == 0.1
    assert obs.ramp_time_constant_s == 15.0 and RAMP_TIME_CONSTANT_S == 15.0
    assert obs.max_hold_s == 2.0
    assert obs.tuning == DEFAULT_TUNING == PassiveTuning()
    assert obs.config == WaveFrequencyConfig()
    assert np.all(obs.omega0_initial == 2 * math.pi / 7.0)
    assert obs.scheduling


def test_on_a_model_the_step_and_the_ramp_are_froude_scaled_and_the_tuning_is_the_vessels() -> None:
    obs = GainScheduledObserver(MODEL)
    assert obs.h_max == 0.1 / R
    assert obs.ramp_time_constant_s == 15.0 / R
    assert obs.max_hold_s == 2.0  # a sensor-dropout setting, as the passive observer's: not scaled
    assert obs.tuning == PassiveTuning.for_vessel(MODEL)
    np.testing.assert_array_equal(obs.omega0_initial, PassiveTuning.for_vessel(MODEL).omega0)
    # given values are the user's
    mine = GainScheduledObserver(MODEL, h_max=0.05, ramp_time_constant_s=3.0)
    assert (mine.h_max, mine.ramp_time_constant_s) == (0.05, 3.0)


def test_the_models_default_step_integrates_its_fast_error_dynamics() -> None:
    """A model's error poles are √70 faster than a ship's (−20 s⁻¹ at 13.4 rad/s): the ship's 0.1 s step
    leaves an integration error of the order of a millimetre in a 7.5 rad/s basin sea (a fifth of the
    observer's own LF error there); the scaled step agrees with a 1 ms reference to round-off level."""
    sea = DEFAULT_SEA
    t, y, _, _ = basin(sea, 300.0, 0)
    reference = GainScheduledObserver(MODEL, h_max=0.001).run(t, y).eta[1500:, :2]

    def off(**kw: float) -> float:
        return float(np.abs(GainScheduledObserver(MODEL, **kw).run(t, y).eta[1500:, :2] - reference).max())

    assert off(h_max=0.1) > 5e-4
    assert off() < 1e-5


# --- a scenario's observer settings, one way --------------------------------------------------------------


def demo_tables(scenario_name: str, monkeypatch: pytest.MonkeyPatch, observer: str) -> dict:
    from dpgw import cli_demo

    monkeypatch.setattr(cli_demo, "DEMO_OBSERVER", observer)
    p = argparse.ArgumentParser()
    cli_demo.add_arguments(p)
    args = p.parse_args(["--out", "x.mcap"])
    return cli_demo.demo_config(get_scenario(scenario_name), "/dev/null", args)


def test_demo_and_closed_loop_apply_the_scenarios_observer_settings_as_the_study(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from dpgw.closed_loop import gateway_tables, with_scenario_observer
    from dpgw.study.case import loop_tables
    from dpgw.study.spec import CaseSpec, SeaSpec
    from gateway.config import parse_config

    scenario = get_scenario("hassani")
    assert scenario.observer_params == {"gain_scheduled": HASSANI_RANGE, "sdre": HASSANI_RANGE}
    demo = demo_tables("hassani", monkeypatch, "gain_scheduled")
    assert demo["observer"]["params"] == HASSANI_RANGE
    case = CaseSpec(
        scenario="hassani", sea=SeaSpec(), seed=0, duration_s=60.0, settle_s=0.0,
        observers=("gain_scheduled",), loop_observer="gain_scheduled",
    )  # fmt: skip
    study = loop_tables(case, scenario, scenario.sea[0][1].tp_s)
    tables = gateway_tables(scenario)
    tables["observer"] = {"type": "gain_scheduled", "wave_period_s": scenario.sea[0][1].tp_s}
    loop = with_scenario_observer(tables, scenario)
    configs = [parse_config(x, base_dir=Path.cwd()).observer for x in (demo, study, loop)]
    assert all(c.params == HASSANI_RANGE for c in configs)
    # the user's own settings win, and applying twice changes nothing
    tables["observer"]["params"] = {"omega_max": 1.2}
    mine = with_scenario_observer(tables, scenario)
    assert mine["observer"]["params"] == {"omega_min": 0.3, "omega_max": 1.2}
    assert with_scenario_observer(mine, scenario) == mine
    # the demo's own passive observer takes none
    assert "params" not in demo_tables("hassani", monkeypatch, "passive")["observer"]


def test_the_in_process_closed_loop_runs_the_full_scale_range_on_hassani() -> None:
    """The hassani sea (0.93 rad/s, the config's wave period) lies in the full-scale range: the loop's
    observer starts there; with the model's default range (2.5-13.4 rad/s) it would start at 0.93·√70."""
    from dpgw.closed_loop import gateway_tables, run_closed_loop

    scenario = get_scenario("hassani")
    tables = gateway_tables(scenario)
    tables["observer"] = {"type": "gain_scheduled", "wave_period_s": scenario.sea[0][1].tp_s}
    run = run_closed_loop(scenario, 3.0, seed=0, tables=tables)
    omega = [e["omega0"] for e in run.estimates if e.get("omega0") is not None]
    assert omega, "no estimate with ω0"
    np.testing.assert_allclose(omega[-1], 2 * math.pi / scenario.sea[0][1].tp_s, rtol=1e-9)


def test_the_adaptive_sdre_gets_the_full_scale_range_and_a_fixed_one_is_not_refused() -> None:
    from dpgw.closed_loop import gateway_tables, with_scenario_observer
    from gateway.config import parse_config
    from gateway.replay import parse_observer_spec
    from observers.factory import with_defaults
    from observers.sdre_adaptive import AdaptiveSdreObserver

    scenario = get_scenario("hassani")
    defaults = scenario.observer_params.get("sdre")
    assert defaults == dict(FULL_SCALE_OMEGA_RANGE)
    config = parse_config(gateway_tables(scenario), base_dir=Path.cwd())
    adaptive = parse_observer_spec("sdre:adaptive=true").make(config, defaults)
    assert isinstance(adaptive, AdaptiveSdreObserver)
    c = adaptive.estimator.config
    assert (c.omega_min, c.omega_max) == (0.3, 1.6)
    fixed = parse_observer_spec("sdre").make(config, defaults)  # no estimator: the range is not its
    assert not isinstance(fixed, AdaptiveSdreObserver)
    assert with_defaults("sdre", defaults, {}) == {}
    assert with_defaults("sdre", defaults, {"adaptive": 1.0}) == {"adaptive": 1.0, **HASSANI_RANGE}
    # a user's estimator setting on a fixed SDRE is still the user's mistake, refused with the reason
    with pytest.raises(ValueError, match="adaptive = true"):
        parse_observer_spec("sdre:omega_min=0.4").make(config, defaults)
    # in a loop's config too
    tables = gateway_tables(scenario)
    tables["observer"] = {"type": "sdre", "params": {"adaptive": True}}
    assert with_scenario_observer(tables, scenario)["observer"]["params"] == {
        "adaptive": True,
        **HASSANI_RANGE,
    }
    tables["observer"] = {"type": "sdre"}
    assert "params" not in with_scenario_observer(tables, scenario)["observer"]


@pytest.fixture(scope="module")
def hassani_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulator_log(tmp_path_factory.mktemp("hassani") / "sim.mcap", "hassani", 0, 240.0)


def _replayed_omega0(
    log: Path, tmp_path: Path, spec: str = "gain_scheduled", *extra: str
) -> tuple[float, str]:
    """The median ω0 of the observer ``spec`` replaying ``log`` (rad/s), and replay's stderr."""
    out = tmp_path / f"r{len(list(tmp_path.glob('*.mcap')))}.mcap"
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(log), "--observer", spec, *extra,
         "--out", str(out), "--json"],
        capture_output=True, text=True, check=True, cwd=REPO,
    )  # fmt: skip
    (tuning,) = json.loads(p.stdout)["wave_check"]["observers"].values()
    return float(tuning["omega0_rad_s"]), p.stderr


def test_a_replayed_hassani_log_runs_the_scenarios_full_scale_range(
    hassani_log: Path, tmp_path: Path
) -> None:
    """A simulator log names its scenario: replayed on its own vessel, the gain-scheduled observer searches
    the scenario's full-scale range (0.3-1.6 rad/s) around its 0.93 rad/s sea, as the study and the demo run
    it, and the replay says so. Before, it searched the model's Froude-scaled range and settled at ~4.3
    rad/s, four times the sea, with nothing said. On another vessel the scenario's settings do not apply."""
    omega0, err = _replayed_omega0(hassani_log, tmp_path)
    assert 0.3 <= omega0 <= 1.6, omega0
    assert abs(omega0 / 0.93 - 1.0) < 0.3, omega0
    note = (
        "dpgw replay: note: the simulator's scenario 'hassani' sets gain_scheduled: omega_min=0.3, "
        "omega_max=1.6 under the observers' own settings, as its study and demo run it"
    )
    assert note in err.splitlines(), err
    # the user's own range wins over the scenario's
    mine, err = _replayed_omega0(
        hassani_log, tmp_path, "gain_scheduled:wave_period_s=2,omega_min=2.5,omega_max=6"
    )
    assert 2.5 <= mine <= 6.0 and "scenario 'hassani' sets" in err
    # and the scenario's vessel only: on mss_supply its range is not that vessel's
    _, err = _replayed_omega0(hassani_log, tmp_path, "gain_scheduled", "--vessel", "mss_supply")
    assert "scenario 'hassani'" not in err
