"""The wave-band RMS of a commanded τ (`gateway.report.spectra.band_rms`) and what wave filtering saved
(`dpgw.raw_feedback.wave_filtering_saved`): the figures `dpgw demo` prints beside station keeping."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dpgw.raw_feedback import (
    dp_stretch,
    raw_feedback_commands,
    thruster_words,
    wave_filtering_saved,
    wave_filtering_words,
)
from gateway.replay import CONFIG_METADATA
from gateway.report.spectra import band_rms
from tests.test_service import mux_tables
from wire.mcap.writer import McapLogWriter

BAND = (0.3, 2.0)


@settings(max_examples=60, deadline=None)
@given(
    amplitude=st.floats(1e-3, 1e7),
    omega=st.floats(0.6, 1.3),
    phase=st.floats(0.0, 2 * math.pi),
    offset=st.floats(-1e7, 1e7),
    jitter_s=st.floats(0.0, 0.02),
    seed=st.integers(0, 2**16),
)
def test_a_sine_inside_the_band_keeps_its_rms_and_one_outside_is_taken_out(
    amplitude: float, omega: float, phase: float, offset: float, jitter_s: float, seed: int
) -> None:
    """A sine well inside the band keeps its RMS (A/√2) within 1.5 % whatever its mean, on a control step
    that is not exactly periodic (jitter up to 20 % of the 0.1 s step); the slow drift and a fast
    ripple beside it, outside the band, add less than 1 % of their own RMS each (most of that is the
    linear resampling of a jittered 6 rad/s ripple)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 600.0, 0.1) + rng.uniform(-jitter_s, jitter_s, 6000)
    wave = amplitude * np.sin(omega * t + phase)
    got = band_rms(t, offset + wave, BAND)
    assert got is not None and abs(got[0] / (amplitude / math.sqrt(2)) - 1.0) <= 0.015
    slow = amplitude * np.sin(0.05 * t)  # a slowly varying load: the DP loop's own band
    fast = amplitude * np.sin(6.0 * t + 1.0)  # above the waves
    both = band_rms(t, np.column_stack([slow, fast]), BAND)
    assert both is not None and np.all(both <= 1e-2 * amplitude / math.sqrt(2))


def test_the_columns_are_filtered_apart_and_the_order_of_samples_does_not_matter() -> None:
    t = np.arange(0.0, 300.0, 0.1)
    v = np.column_stack([np.sin(0.8 * t), 3.0 * np.sin(1.1 * t), np.zeros_like(t)])
    got = band_rms(t, v, BAND)
    assert got is not None
    np.testing.assert_allclose(got[:2], [1 / math.sqrt(2), 3 / math.sqrt(2)], rtol=0.015)
    assert got[2] == 0.0
    shuffled = np.random.default_rng(1).permutation(len(t))
    np.testing.assert_allclose(band_rms(t[shuffled], v[shuffled], BAND), got)  # type: ignore[arg-type]


def test_too_little_to_filter_is_none() -> None:
    """Less than one period of the band's lower edge (21 s), a band above Nyquist, or no samples: no
    figure rather than a filter's start-up transient."""
    t = np.arange(0.0, 20.0, 0.1)
    assert band_rms(t, np.sin(t), BAND) is None
    assert band_rms(np.arange(0.0, 300.0, 2.0), np.zeros(150), BAND) is None  # Nyquist 1.6 rad/s < 2
    assert band_rms(np.array([]), np.zeros((0, 3)), BAND) is None
    # NaN samples are left out, not spread through the filter
    t = np.arange(0.0, 300.0, 0.1)
    v = np.sin(0.8 * t)
    v[100] = np.nan
    got = band_rms(t, v, BAND)
    assert got is not None and abs(got[0] * math.sqrt(2) - 1.0) < 0.015


def _commands(t: np.ndarray, amplitude: float) -> list[dict[str, object]]:
    """τ and two drives' thrust with wave-band content ∝ ``amplitude``; drive 2 steady (no ratio), and a
    drive 3 in half the commands only (a thruster out of service for a while: not compared)."""
    return [
        {
            "stamp_ns": round(1e9 * (1000.0 + s)),
            "tau_demand": [amplitude * math.sin(0.9 * s), 0.0, 2.0 * amplitude * math.sin(0.7 * s)],
            "thrusters": [
                {"id": 1, "thrust_n": 5e4 + 0.5 * amplitude * math.sin(1.1 * s)},
                {"id": 2, "thrust_n": 3e4},
                *([{"id": 3, "thrust_n": amplitude * math.sin(s)}] if k % 2 else []),
            ],
        }
        for k, s in enumerate(t)
    ]


def test_what_wave_filtering_saved_is_the_ratio_of_wave_band_rms_in_db() -> None:
    """Ten times the wave-band thrust fed raw is 20 dB saved; commands before ``from_ns`` are left out
    (the stretch before DP, which would otherwise dominate a raw controller's figure); a DOF where both
    are zero has no ratio (None, not an infinite or a 0 dB that JSON and a reader would take at its
    word)."""
    t = np.arange(0.0, 400.0, 0.1)
    live = _commands(t, 1.0e4)
    raw = _commands(t, 1.0e5)
    for c in raw[:1000]:  # a huge transient in the first 100 s, before the scored stretch
        c["tau_demand"] = [1e9, 0.0, 1e9]
    w = wave_filtering_saved(live, raw, int(1e9 * 1100.0), BAND)
    assert w is not None
    assert w["band_rad_s"] == [0.3, 2.0]
    np.testing.assert_allclose(w["saved_db"][0], 20.0, atol=0.1)
    np.testing.assert_allclose(w["saved_db"][2], 20.0, atol=0.1)
    assert w["saved_db"][1] is None  # (no wave-band thrust either way: no ratio)
    assert wave_filtering_words(w).endswith("(this log replayed): 20 / – / 20 dB less")
    np.testing.assert_allclose(w["wave_band_tau_rms"][0], 1e4 / math.sqrt(2), rtol=0.015)
    # per drive: the allocation's commanded thrust, each thruster that is in every command
    drives = {x["id"]: x for x in w["thrusters"]}
    assert sorted(drives) == [1, 2]
    np.testing.assert_allclose(drives[1]["saved_db"], 20.0, atol=0.1)
    np.testing.assert_allclose(drives[1]["wave_band_thrust_rms_n"], 0.5e4 / math.sqrt(2), rtol=0.015)
    assert drives[2]["saved_db"] is None
    assert thruster_words(w) == "per thruster (1, 2): 20 / – dB less wave-band thrust commanded"
    # too short a scored stretch: no figure
    assert wave_filtering_saved(live, raw, int(1e9 * 1390.0), BAND) is None


def test_the_demo_measures_a_models_wave_band_where_its_waves_are() -> None:
    """A full-scale scenario is measured in 0.3-2 rad/s; CyberShip II (1:70, `hassani`) in that band × √λ,
    where its waves are (at full scale its whole wave band is above 2 rad/s)."""
    from dpgw.raw_feedback import THRUST_WAVE_BAND as WAVE_BAND
    from dpgw.raw_feedback import force_words as _force
    from dpgw.raw_feedback import thrust_wave_band
    from observers.froude import froude_scale
    from simulator.scenarios import get_scenario

    assert thrust_wave_band(get_scenario("torsetnes_2004").vessel) == WAVE_BAND
    model = get_scenario("hassani")
    lo, hi = thrust_wave_band(model.vessel)
    root = math.sqrt(froude_scale(model.vessel))
    assert root > 5.0
    np.testing.assert_allclose([lo, hi], [WAVE_BAND[0] * root, WAVE_BAND[1] * root])
    # the figures in the units they come in: a basin model's fractions of a newton, a ship's kN and MN·m
    assert [_force(x) for x in (0.0123, 3.2, 46.0, 18_511.0, 3_984_592.0)] == [
        "0.012 N",
        "3.2 N",
        "46 N",
        "19 kN",
        "4.0 MN",
    ]
    assert _force(244_346.0, "N·m") == "244 kN·m"


def test_the_stretch_scored_is_the_longest_run_of_commands_in_dp() -> None:
    """A trial's crew takes the vessel in manual and back: the figure is over the longest stretch in dp,
    not across a manual spell (whose joystick thrust is nobody's wave filter's)."""
    modes = ["standby"] * 5 + ["dp"] * 10 + ["manual"] * 3 + ["dp"] * 20 + ["standby"] * 2
    commands = [{"stamp_ns": k * 10**9, "mode": m} for k, m in enumerate(modes)]
    assert dp_stretch(commands) == (18 * 10**9, 37 * 10**9)
    assert dp_stretch(list(reversed(commands))) == (18 * 10**9, 37 * 10**9)  # (by stamp, not by order)
    assert dp_stretch([{"stamp_ns": 0, "mode": "standby"}]) is None
    assert dp_stretch([]) is None


def _gateway_log(path: Path, feedback: str) -> Path:
    """An MCAP file holding only a gateway's configuration (what the comparison reads first)."""
    tables = mux_tables(10110, 7447, path, 1.0)
    tables["control"] = {"feedback": feedback}
    with McapLogWriter(str(path), profile="dpgw") as log:
        log.add_metadata(CONFIG_METADATA, {"json": json.dumps(tables)})
    return path


def test_a_log_whose_controller_had_no_wave_filter_has_nothing_to_compare(tmp_path: Path) -> None:
    """A live run already fed the raw measurements (`[control] feedback = "measurement"`) would be compared
    with itself: 0 dB, said as if a wave filter had been measured. No figure instead; a log of an estimate-fed
    controller is replayed (no events here: no commands)."""
    assert raw_feedback_commands([_gateway_log(tmp_path / "raw.mcap", "measurement")]) is None
    assert raw_feedback_commands([_gateway_log(tmp_path / "filtered.mcap", "estimate")]) == []
