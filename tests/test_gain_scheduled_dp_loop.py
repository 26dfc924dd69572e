"""The gain-scheduled observer's ω0 estimate under a DP loop whose band reaches into the wave band.

`hassani` runs a full-scale 6.8 s sea (0.93 rad/s) on the 1:70 CyberShip II, held by the model's
Froude-scaled DP loop (ωn = 0.55 / 0.55 / 0.78 rad/s). The closed loop's own motion then fills the low
end of the estimator's range (0.3-1.6 rad/s): 20 dB above the wave peak in heading. Searched from
ω_min, the estimate either never updated or locked at 0.32-0.40 rad/s (7 of 12 study seeds), and the
observer's notch on the loop's motion cost it 2.2-3.1° heading RMS. The estimator now searches above the
loop's band where the loop is known (`observers.wave_frequency`, "Above the DP loop's band").

Closed loop: the study's own case (`dpgw.study.case.score_case`, the vessel held by the passive observer,
the gain-scheduled one run over the same measurements) on three of the seeds that were thrown off.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from observers.wave_frequency import WaveFrequencyConfig, WaveFrequencyEstimator

HASSANI_PEAK = 0.93  # rad/s, the scenario's sea


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 5, 8])
def test_hassani_study_case_tracks_the_sea_not_the_dp_loop(seed: int) -> None:
    """Seeds 1, 5, 8 settled ω0 at 0.37, 0.32, 0.36 rad/s with 2.2, 2.9, 3.1° heading RMS; now the median
    ω0 over the scored part lies within 8 % of the sea's 0.93 rad/s (measured 6.0, 0.8, 2.4 %) and the
    heading RMS below 1° and within 15 % of the fixed observer's that holds the loop (0.73, 0.73, 0.80°
    against 0.68, 0.72, 0.77°)."""
    from dpgw.study.case import build_scenario, score_case
    from dpgw.study.spec import CaseSpec, SeaSpec

    case = CaseSpec("hassani", SeaSpec(), seed, 900.0, 300.0, ("gain_scheduled", "passive"))
    rows = {row["observer"]: row for row in score_case(case, build_scenario(case))}
    gs, fixed = rows["gain_scheduled"], rows["passive"]
    assert abs(gs["omega0_median_rad_s"] - HASSANI_PEAK) / HASSANI_PEAK < 0.08
    assert gs["rms_heading_deg"] < 1.0
    assert gs["rms_heading_deg"] < 1.15 * fixed["rms_heading_deg"]


def _loop_and_sea(seed: int, duration_s: float = 900.0) -> tuple[np.ndarray, np.ndarray]:
    """10 Hz [N, E, ψ]: a sea peaking at 0.93 rad/s (the 2nd-order wave model (18), ζ = 0.1, driven by
    white noise) plus a DP loop's motion (white forcing through a first-order disturbance, 1/(1 + 10 s),
    and a 2nd-order closed loop, ζ = 0.7), shaped and sized as the measured motion in `hassani` (its
    roll-off from 0.5 rad/s; at 0.3 rad/s a few dB above the wave peak in position, 20 dB in heading)."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    dt = 0.1
    t = np.arange(0.0, duration_s, dt)
    w0, z = HASSANI_PEAK, 0.1
    wave = signal.lti([1.0, 0.0], [1.0, 2 * z * w0, w0**2])
    y = np.zeros((t.size, 3))
    for i, (wn, wave_gain, loop_gain) in enumerate([(0.5, 0.02, 0.3), (0.5, 0.012, 0.25), (0.5, 1e-3, 0.35)]):
        _, waves, _ = signal.lsim(wave, rng.standard_normal(t.size), t)
        loop = signal.lti([wn**2], np.polymul([10.0, 1.0], [1.0, 2 * 0.7 * wn, wn**2]))
        _, lf, _ = signal.lsim(loop, rng.standard_normal(t.size), t)
        y[:, i] = wave_gain * waves + loop_gain * lf + rng.standard_normal(t.size) * (0.01 if i < 2 else 1e-3)
    return t, y


def _estimates(config: WaveFrequencyConfig, t: np.ndarray, y: np.ndarray) -> list[float | None]:
    est = WaveFrequencyEstimator(config)
    out: list[float | None] = []
    for j in est.add_until_updates(t, y):
        e = est.estimate(float(t[j]))
        out.append(None if e is None else float(e[0]))
    return out


def test_the_estimate_is_searched_above_the_dp_loop() -> None:
    """On the synthetic sea + loop record: searched from ω_min, fewer than half the updates give an
    estimate within 15 % of the sea's peak (the loop's motion holds the maximum at the low edge, or takes
    a bump of it just above for a peak: 0.32-0.49 rad/s); with the loop's bandwidth known, every estimate
    is within 15 % (measured 0.86-0.95 rad/s) and at least half the updates make one (measured 8-13 of
    14; the others keep the estimate in use: the maximum sat on the edge of the searched band)."""
    base = WaveFrequencyConfig()
    known = replace(base, loop_bandwidth=(0.55, 0.55, 0.78))

    def near(e: float | None) -> bool:
        return e is not None and abs(e - HASSANI_PEAK) < 0.15 * HASSANI_PEAK

    for seed in range(3):
        t, y = _loop_and_sea(seed)
        blind, aware = _estimates(base, t, y), _estimates(known, t, y)
        assert sum(near(e) for e in blind) < len(blind) / 2
        made = [e for e in aware if e is not None]
        assert len(made) >= len(aware) / 2 and all(near(e) for e in made)


def test_a_slow_loop_changes_nothing() -> None:
    """A ship's DP loop (ωn 0.07-0.1 rad/s, below ω_min = 0.3): the same estimates bit for bit."""
    t, y = _loop_and_sea(0)
    base = WaveFrequencyConfig()
    ship = replace(base, loop_bandwidth=(0.07, 0.07, 0.1))
    assert ship.search_floor == (0.3, 0.3, 0.3)
    assert _estimates(ship, t, y) == _estimates(base, t, y)


def test_loop_bandwidth_settings() -> None:
    one = WaveFrequencyConfig(loop_bandwidth=0.8)
    assert one.loop_bandwidth == (0.8, 0.8, 0.8) and one.search_floor == (0.8, 0.8, 0.8)
    shared = WaveFrequencyConfig(loop_bandwidth=(0.55, 0.55, 0.78))
    assert shared.search_floor == (0.78, 0.78, 0.78)  # one ω0 for all DOFs: one band, the highest loop's
    own = WaveFrequencyConfig(loop_bandwidth=(0.55, 0.55, 0.78), per_dof=True)
    assert own.search_floor == (0.55, 0.55, 0.78)
    scaled = shared.for_model(70.0)  # a frequency: × √70 on the 1:70 model, as ω_min
    assert scaled.search_floor[0] == pytest.approx(0.78 * math.sqrt(70.0))
    hash(shared)  # stays a hashable, comparable config
    assert WaveFrequencyConfig().held_by((0.55, 0.55, 0.78)) == shared  # an observer's tuning's loop
    assert one.held_by((0.55, 0.55, 0.78)) is one and shared.held_by(None) is shared  # its own kept
    with pytest.raises(ValueError, match="no wave band is left above the loop"):
        WaveFrequencyConfig(loop_bandwidth=1.7)
    with pytest.raises(ValueError, match="loop_bandwidth must be a positive number"):
        WaveFrequencyConfig(loop_bandwidth=(0.5, -1.0, 0.5))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 5])
def test_adaptive_sdre_searches_above_the_dp_loop_too(seed: int) -> None:
    """The adaptive SDRE's estimator gets the loop's band from the same tuning. Without it seeds 1 and 5
    settled ω0 at 0.37 and 0.32 rad/s with 0.38 and 0.55° heading RMS; with it 0.87 and 0.92 rad/s and
    0.121°, level with the fixed SDRE tuned to the sea's own peak (0.120, 0.121°)."""
    from dpgw.study.case import build_scenario, score_case
    from dpgw.study.spec import CaseSpec, SeaSpec

    case = CaseSpec("hassani", SeaSpec(), seed, 900.0, 300.0, ("sdre:adaptive=true@adaptive", "sdre"))
    rows = {row["observer"]: row for row in score_case(case, build_scenario(case))}
    adaptive, fixed = rows["adaptive"], rows["sdre"]
    assert abs(adaptive["omega0_median_rad_s"] - HASSANI_PEAK) / HASSANI_PEAK < 0.08
    assert adaptive["rms_heading_deg"] < 1.1 * fixed["rms_heading_deg"]


def test_adaptive_sdre_takes_the_loop_band_from_its_tuning() -> None:
    """Built by name with a tuning that knows its loop, as a gateway config builds it; an estimator band
    given explicitly is kept."""
    from observers.passive_tuning import PassiveTuning
    from observers.sdre import SdreObserver
    from observers.vessel import load_vessel

    vessel = load_vessel("mss_supply")
    tuning = PassiveTuning.for_vessel(vessel)
    tuning = replace(tuning, loop_bandwidth=(0.4, 0.4, 0.5))
    obs = SdreObserver.from_params(vessel, tuning, {"adaptive": True})
    assert obs.estimator.config.search_floor == (0.5, 0.5, 0.5)  # one ω0: the highest loop's band
    plain = SdreObserver.from_params(vessel, replace(tuning, loop_bandwidth=None), {"adaptive": True})
    assert plain.estimator.config.search_floor == (0.3, 0.3, 0.3)
