"""The passive observer's default tuning follows the vessel (Froude scaling, `PassiveTuning.for_vessel`).

Data: CyberShip II (the 1:70 model of a supply vessel) at (0, 0), heading 0, in two basin seas through the
model's RAOs (`simulator.waves.WaveField`): the default's own sea, the 7 s wave period Froude-scaled
(JONSWAP Tp 7/√70 = 0.84 s, ωp 7.5 rad/s, Hs 5 cm), and the gain-scheduled test's (Tp 1.65 s, ωp 3.8
rad/s, Hs 6 cm: tests/test_gain_scheduled_model_scale.py); plus a slow LF motion from the model's LF
dynamics under a weak station-keeping law (the full-scale tests' 120 s loop and 100-600 s forcing,
Froude-scaled), plus the `hassani` scenario's sensor noise (1 cm position, 0.1° heading), at 10 Hz.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from basin_sea import DEFAULT_SEA, MODEL, RATE, SHIPS, basin
from basin_sea import SCALE as R

from gateway.report.metrics import wave_band_for_length
from gateway.report.wave_check import check_wave_tuning
from observers.factory import make_observer
from observers.gain_scheduled import GainScheduledObserver
from observers.kinematics import ssa
from observers.passive import PassiveObserver
from observers.passive_tuning import (
    FREQUENCY_FIELDS,
    TIME_FIELDS,
    PassiveTuning,
    check_gains,
    froude_scaled_fields,
    passive_gains,
)
from observers.vessel import load_vessel
from simulator.spectra import SeaState

BASIN_SEA = SeaState(hs_m=0.06, tp_s=2 * math.pi / 3.8, gamma=3.3, direction_rad=math.radians(150.0))
SETTLE_S = 150.0


def observer_config(vessel: str, observer: dict[str, Any]) -> Any:
    """The `[observer]` section as `gateway.config.parse_config` reads it for ``vessel``."""
    from dpgw.closed_loop import gateway_tables
    from gateway.config import parse_config
    from simulator.scenarios import get_scenario

    tables = gateway_tables(get_scenario("hassani"))
    tables["vessel"] = {"name": vessel}
    tables["observer"] = observer
    return parse_config(tables, base_dir=Path.cwd()).observer


# --- the scaling ------------------------------------------------------------------------------------------


def test_ships_keep_todays_default_tuning_field_by_field() -> None:
    """λ = 1: the same tuning, field by field, from every place that makes the default (the class, the
    gains without a tuning, the config without a wave period). The config adds one field, the DP loop's
    bandwidth (``loop_bandwidth``, from ``[control]``), whose floor lies below every ship's default
    injection: the config's gains are today's to the bit."""
    assert {"mss_supply", "mss_osv", "northern_clipper", "hajivand_vessel", "snijders_ship"} <= set(SHIPS)
    today = PassiveTuning()
    for name in SHIPS:
        vessel = load_vessel(name)
        mine = PassiveTuning.for_vessel(vessel)
        for key, value in today.__dict__.items():
            assert getattr(mine, key) == value, (name, key)
        assert mine.omega0 == 2 * math.pi / 7.0 and mine.bias_time_constant_s == math.inf
        g, g0 = passive_gains(vessel), passive_gains(vessel, today)
        for key in ("omega0", "zeta", "zeta_n", "omega_c", "K1", "K2", "K3", "K4", "T"):
            np.testing.assert_array_equal(getattr(g, key), getattr(g0, key), err_msg=f"{name} {key}")
        config = observer_config(name, {})
        for key, value in today.__dict__.items():
            if key != "loop_bandwidth":
                assert getattr(config.tuning, key) == value, (name, key)
        assert config.tuning.loop_bandwidth is not None
        gc = passive_gains(vessel, config.tuning)
        for key in ("omega0", "zeta", "zeta_n", "omega_c", "K1", "K2", "K3", "K4", "T"):
            np.testing.assert_array_equal(getattr(gc, key), getattr(g0, key), err_msg=f"{name} {key}")


def test_a_1_to_70_model_is_scaled_by_sqrt_70() -> None:
    tuning = PassiveTuning.for_vessel(MODEL)
    assert tuning.omega0 == pytest.approx(2 * math.pi / 7.0 * R, rel=1e-12)  # 7.51 rad/s, a 0.84 s sea
    assert tuning.bias_time_constant_s == math.inf  # the random walk stays a random walk
    for key in ("zeta", "zeta_n", "cutoff_ratio", "velocity_injection_ratio", "bias_corner_ratio"):
        assert getattr(tuning, key) == getattr(PassiveTuning(), key), key  # ratios: kept
    g, g_ship = passive_gains(MODEL), passive_gains(MODEL, PassiveTuning())
    np.testing.assert_allclose(g.omega_c, g_ship.omega_c * R, rtol=1e-12)
    np.testing.assert_allclose(g.bias_corner, g_ship.bias_corner * R, rtol=1e-12)
    # every dimensional field, where set: frequencies × √λ, times ÷ √λ, per DOF too
    full = {"omega0": (0.9, 0.8, 0.7), "omega_c": 1.1, "velocity_injection": 0.1, "bias_corner": 0.03}
    scaled = froude_scaled_fields({**full, "bias_time_constant_s": 1000.0, "zeta": 0.1}, 70.0)
    assert set(FREQUENCY_FIELDS) == set(full) and TIME_FIELDS == ("bias_time_constant_s",)
    assert scaled["omega0"] == pytest.approx((0.9 * R, 0.8 * R, 0.7 * R), rel=1e-12)
    assert scaled["omega_c"] == pytest.approx(1.1 * R) and scaled["bias_corner"] == pytest.approx(0.03 * R)
    assert scaled["velocity_injection"] == pytest.approx(0.1 * R)
    assert scaled["bias_time_constant_s"] == pytest.approx(1000.0 / R) and scaled["zeta"] == 0.1
    # the observers built by name without a tuning get it; the checks hold
    obs = make_observer("passive", MODEL)
    assert isinstance(obs, PassiveObserver)
    np.testing.assert_allclose(obs.omega0, tuning.omega0, rtol=1e-12)
    assert all(c.ok for c in check_gains(passive_gains(MODEL)))  # rule (48) and SPR hold, scaled


def test_the_config_scales_what_is_not_given_and_keeps_what_is() -> None:
    default = observer_config("cybership2", {}).tuning
    # (and the DP loop's bandwidth from [control], already the model's: Froude-scaled by the controller)
    assert replace(default, loop_bandwidth=None) == PassiveTuning.for_vessel(MODEL)
    # the user's wave period or ω0 is the user's (a model's own scale): not scaled
    assert observer_config("cybership2", {"wave_period_s": 7.0}).tuning.omega0 == 2 * math.pi / 7.0
    assert observer_config("cybership2", {"omega0": 0.93}).tuning.omega0 == 0.93
    mine = observer_config("cybership2", {"bias_time_constant_s": 1000.0, "omega_c": 9.5}).tuning
    assert mine.bias_time_constant_s == 1000.0 and mine.omega_c == 9.5
    assert mine.omega0 == pytest.approx(2 * math.pi / 7.0 * R)  # the rest scaled
    per_dof = observer_config("cybership2", {"wave_period_s": [1.0, 1.2, 1.4]}).tuning.omega0
    assert per_dof == pytest.approx((2 * math.pi, 2 * math.pi / 1.2, 2 * math.pi / 1.4), rel=1e-12)


def test_the_hassani_cases_keep_the_papers_wave_peak() -> None:
    """Hassani's case runs a full-scale sea (0.93 rad/s) on the 1:70 model: its gateway config gives the
    wave period explicitly, so the passive tuning is the paper's ω0, not the model's default."""
    from dpgw.closed_loop import gateway_tables
    from gateway.config import parse_config
    from simulator.scenarios import get_scenario

    for name in ("hassani", "hassani_sea_change"):
        scenario = get_scenario(name)
        config = parse_config(gateway_tables(scenario), base_dir=Path.cwd())
        assert config.observer.tuning.omega0 == pytest.approx(2 * math.pi / scenario.sea[0][1].tp_s)
        assert config.observer.tuning.omega0 < 1.6  # a full-scale sea, as the paper's
    assert get_scenario("hassani").sea[0][1].peak_frequency == pytest.approx(0.93, rel=0.01)
    # the gain-scheduled observer with the paper's full-scale range and the model's default ω0 starts
    # at the same sea in the range's scale (7.51/√70 = 2π/7 s), not refused
    gs = observer_config(
        "cybership2", {"type": "gain_scheduled", "params": {"omega_min": 0.3, "omega_max": 1.6}}
    )
    obs = make_observer("gain_scheduled", MODEL, gs.tuning, params=gs.params)
    assert isinstance(obs, GainScheduledObserver)
    np.testing.assert_allclose(obs.omega0_initial, 2 * math.pi / 7.0, rtol=1e-12)


# --- the model in a basin sea -----------------------------------------------------------------------------


def errors(tuning: PassiveTuning, sea: SeaState, seed: int) -> dict[str, float]:
    """RMS after `SETTLE_S` of the LF estimate against the true LF motion and of the WF estimate against
    the true WF motion (horizontal position in m, heading in rad), and the LF estimate's power in the
    sea's band [ωp/2, 2ωp] (north + east, Welch)."""
    from scipy import signal

    t, y, lf, wf = basin(sea, 300.0, seed)
    k = int(SETTLE_S * RATE)
    r = PassiveObserver(MODEL, tuning).run(t, y)
    e = r.eta[k:] - lf[k:]
    e[:, 2] = ssa(e[:, 2])
    ew = r.eta_wf[k:] - wf[k:]
    f, p = signal.welch(r.eta[k:, :2] - r.eta[k:, :2].mean(axis=0), fs=RATE, nperseg=512, axis=0)
    w, wp = 2 * math.pi * f, sea.peak_frequency
    band = (w >= wp / 2) & (w <= 2 * wp)
    return {
        "lf_pos": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))),
        "lf_psi": float(np.sqrt(np.mean(e[:, 2] ** 2))),
        "wf_pos": float(np.sqrt(np.mean(ew[:, 0] ** 2 + ew[:, 1] ** 2))),
        "wf_psi": float(np.sqrt(np.mean(ew[:, 2] ** 2))),
        "band_power": float(p[band].sum()),
    }


def db(old: float, new: float) -> float:
    return 20.0 * math.log10(old / new)


@pytest.mark.parametrize("seed", range(3))
def test_the_scaled_default_follows_the_model_where_the_ships_default_does_not(seed: int) -> None:
    """The ship's default (ω0 0.90 rad/s, ωc 1.1 rad/s) on the model notches the model's own LF motion:
    its station-keeping loop (0.44 rad/s) and slow forcing (0.09-0.52 rad/s) are the 120 s and 100-600 s
    of a ship made √70 faster. The LF estimate follows y at −5 dB at 0.5 rad/s and −19 dB at 1 rad/s
    (`lf_response`), the rest of the LF motion goes to the WF estimate, and the slowest error pole is
    −0.011 s⁻¹ (−0.34 s⁻¹ scaled). Measured, seeds 0-5, RMS after 150 s, old → scaled default:

    * the default's own sea (ωp 7.5 rad/s): LF position error 7.0-7.8 cm → 0.68-0.86 cm (18.7-20.5 dB),
      heading 1.96-3.11° → 0.10-0.17° (22.7-26.9 dB); WF estimate error 14.3-15.1 dB (position) and
      19.6-22.9 dB (heading) smaller;
    * the 3.8 rad/s basin sea (a 13.8 s sea at full scale, 2 × below the default's): LF position error
      → 1.06-1.21 cm (15.8-17.1 dB), heading → 0.31-0.36° (15.7-20.0 dB); WF 11.9-12.9 / 12.3-16.5 dB.

    Required: 15 dB (LF) and 11 dB (WF) in the default's sea, 12 dB (LF) and 9 dB (WF) in the other: 3-4
    dB under the worst of six seeds (the seed-to-seed spread is 2-4 dB), far above no improvement.

    What the scaled default gives up: the LF estimate's power in the sea's own band is 5.0-5.7 dB (own
    sea) and 8.5-8.7 dB (3.8 rad/s sea) *higher* than the ship's default's, whose cut-off lies below the
    model's whole sea and makes it a low-pass there — one that also removes the model's LF motion, so
    its estimate is not the vessel's. Pinned here (3-7 and 6-11 dB) so that docs/passive-observer.md's
    figures stay true. In the 3.8 rad/s sea the fix is the wave period (or the gain-scheduled observer),
    which the replay's wave check advises (next test)."""
    old, new = PassiveTuning(), PassiveTuning.for_vessel(MODEL)
    for sea, lf_db, wf_db, band_db in (
        (DEFAULT_SEA, 15.0, 11.0, (3.0, 7.0)),
        (BASIN_SEA, 12.0, 9.0, (6.0, 11.0)),
    ):
        a, b = errors(old, sea, seed), errors(new, sea, seed)
        assert db(a["lf_pos"], b["lf_pos"]) >= lf_db, (sea.tp_s, a, b)
        assert db(a["lf_psi"], b["lf_psi"]) >= lf_db, (sea.tp_s, a, b)
        assert db(a["wf_pos"], b["wf_pos"]) >= wf_db, (sea.tp_s, a, b)
        assert db(a["wf_psi"], b["wf_psi"]) >= wf_db, (sea.tp_s, a, b)
        more = 10.0 * math.log10(b["band_power"] / a["band_power"])
        assert band_db[0] <= more <= band_db[1], (sea.tp_s, more)


def test_the_wave_check_on_the_model_judges_the_scaled_default() -> None:
    """The replay's check (`gateway.report.wave_check`) compares the measured peak with the ω0 in use, in
    the vessel's Froude-scaled band: in the default's own sea the scaled default is silent and the ship's
    default called mistuned; in the 3.8 rad/s sea the scaled default (7.51 rad/s) is called mistuned and
    the advice is the sea's own model-scale period (1.65 s), which the check then accepts."""
    band = wave_band_for_length(MODEL.length_m, MODEL.model_scale)
    new = PassiveTuning.for_vessel(MODEL).omega0
    old = PassiveTuning().omega0
    t, y, _, _ = basin(DEFAULT_SEA, 300.0, 0)
    wc = check_wave_tuning(t, y, band, {"scaled": np.full(len(t), new), "ship": np.full(len(t), old)})
    assert wc.measured is not None and abs(wc.measured / new - 1) < 0.25, wc.as_dict()
    assert [o.label for o in wc.observers if o.mistuned] == ["ship"]
    t, y, _, _ = basin(BASIN_SEA, 300.0, 0)
    kinds = {"passive": ("passive", False)}
    wc = check_wave_tuning(t, y, band, {"passive": np.full(len(t), new)}, kinds)
    assert wc.measured is not None and abs(wc.measured / 3.8 - 1) < 0.15, wc.as_dict()
    (warning,) = wc.warnings()
    assert "ω0 = 7.51 rad/s" in warning, warning
    m = re.search(r"--observer passive:wave_period_s=([0-9.]+), or", warning)
    assert m is not None and abs(float(m.group(1)) / 1.65 - 1) < 0.1, warning
    advised = 2 * math.pi / float(m.group(1))
    assert check_wave_tuning(t, y, band, {"passive": np.full(len(t), advised)}, kinds).warnings() == []
