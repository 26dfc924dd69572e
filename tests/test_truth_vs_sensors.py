"""The ground truth agrees with the sensors: for every simulated sensor, measurement − truth at that sensor
has the configured noise statistics (zero mean, the configured σ, no correlation with the wave motion).

And the check can fail: the same statistics with the wave motion's sign flipped, or with the antenna's
lever arm turned by the heading alone (no roll and pitch), are far from the sensor's noise."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import pynmea2
import pytest

from simulator.runner import Simulation
from simulator.scenarios import Scenario, get_scenario
from simulator.sensors import DgpsConfig, GyroConfig, antenna_ned
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter

SIGMA_M = 0.3
SIGMA_HDG = math.radians(0.05)
SIGMA_ROT = math.radians(0.5) / 60.0
LEVER = (10.0, -2.0, -20.0)  # forward, to port, 20 m up a mast: heading, roll and pitch all move it
STD_TOLERANCE = 0.15  # std within 15 % of the configured σ
CORR_LIMIT = 0.15  # |correlation| with the wave motion


def _scenario() -> Scenario:
    return replace(
        get_scenario("torsetnes_2004"),
        dgps=(DgpsConfig(rate_hz=2.0, sigma_m=SIGMA_M, lever_arm_m=LEVER),),
        gyro=(GyroConfig(rate_hz=5.0, sentences=("HDT", "ROT"), sigma_rad=SIGMA_HDG),),
    )


@pytest.fixture(scope="module")
def samples(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """300 s of torsetnes_2004 (Hs 6 m) logged to MCAP; the decoded measurements beside the truth of
    their measurement instant (the log's publish time is the sample time)."""
    sc = _scenario()
    path: Path = tmp_path_factory.mktemp("truth") / "sim.mcap"
    with McapLogWriter(path) as log:
        Simulation(sc, seed=4, log=log).run(300.0)
    truth = {p["stamp_ns"]: p for _, _, _, p in read_messages(path, "/truth/state")}
    datum = sc.datum
    dgps: list[list[float]] = []
    hdt: list[list[float]] = []
    rot: list[list[float]] = []
    for _, _, pub_ns, payload in read_messages(path, ["/raw/nmea/dgps1", "/raw/nmea/gyro1"]):
        assert pub_ns in truth  # sensors sample on the truth's 0.1 s grid: every sample has its truth
        for line in payload["text"].split("\r\n"):
            if not line:
                continue
            m = pynmea2.parse(line, check=True)
            if m.sentence_type == "GGA":
                n, e, _ = pymap3d.geodetic2ned(
                    m.latitude, m.longitude, 0.0, datum.lat_deg, datum.lon_deg, 0.0
                )
                dgps.append([n, e, float(m.altitude), pub_ns])
            elif m.sentence_type == "HDT":
                hdt.append([math.radians(float(m.heading)), pub_ns])
            elif m.sentence_type == "ROT":
                rot.append([math.radians(float(m.rate_of_turn)) / 60.0, pub_ns])
    return {"truth": truth, "dgps": np.array(dgps), "hdt": np.array(hdt), "rot": np.array(rot), "sc": sc}


def _field(samples: dict[str, Any], stamps: np.ndarray, key: str) -> np.ndarray:
    return np.array([samples["truth"][int(s)][key] for s in stamps], dtype=float)


def _noise_like(residual: np.ndarray, sigma: float, wave: np.ndarray) -> list[str]:
    """What is wrong with ``residual`` as white noise of std σ (empty: nothing)."""
    n = residual.size
    problems = []
    if abs(residual.mean()) > 4.0 * sigma / math.sqrt(n):
        problems.append(f"mean {residual.mean():+.4g} beyond 4σ/√n = {4 * sigma / math.sqrt(n):.3g}")
    if abs(residual.std() / sigma - 1.0) > STD_TOLERANCE:
        problems.append(f"std {residual.std():.4g} not within 15 % of σ = {sigma:.4g}")
    for j in range(wave.shape[1]):
        c = np.corrcoef(residual, wave[:, j])[0, 1]
        if abs(c) > CORR_LIMIT:
            problems.append(f"correlation {c:+.2f} with wave motion component {j}")
    return problems


def _dgps_residuals(samples: dict[str, Any], sign: float = 1.0, roll_pitch: bool = True) -> np.ndarray:
    """GGA − the antenna rebuilt from the truth's LF motion, η_WF and WF attitude: [N, E, altitude].
    sign −1 / roll_pitch False rebuild it the wrong way (subtracting the wave motion, or turning the lever
    arm by the heading only)."""
    d = samples["dgps"]
    stamps = d[:, 3]
    lf, wf = _field(samples, stamps, "eta_lf"), _field(samples, stamps, "eta_wf")
    att = _field(samples, stamps, "wf_attitude")
    ant = np.array(
        [
            antenna_ned(lf[k] + sign * wf[k], LEVER, sign * att[k] if roll_pitch else None)
            for k in range(len(lf))
        ]
    )
    alt_ref = samples["sc"].dgps[0].alt_m
    return np.column_stack([d[:, 0] - ant[:, 0], d[:, 1] - ant[:, 1], d[:, 2] - (alt_ref - ant[:, 2])])


def _antennas(samples: dict[str, Any], stamps: np.ndarray) -> np.ndarray:
    return np.array([samples["truth"][int(s)]["antennas"]["dgps1"] for s in stamps], dtype=float)


def test_dgps_minus_true_antenna_is_the_configured_noise(samples: dict[str, Any]) -> None:
    d = samples["dgps"]
    stamps = d[:, 3]
    ant = _antennas(samples, stamps)
    wave = np.hstack([_field(samples, stamps, "eta_wf"), _field(samples, stamps, "wf_attitude")])
    assert np.std(wave[:, 3]) > math.radians(1.0)  # Hs 6 m rolls the ship: the mast matters
    alt_ref = samples["sc"].dgps[0].alt_m
    residual = {
        "north": (d[:, 0] - ant[:, 0], SIGMA_M),
        "east": (d[:, 1] - ant[:, 1], SIGMA_M),
        "altitude": (d[:, 2] - (alt_ref - ant[:, 2]), 1.5 * SIGMA_M),  # vertical σ = 1.5 × horizontal
    }
    assert len(d) >= 500
    for name, (r, sigma) in residual.items():
        assert not _noise_like(r, sigma, wave), f"DGPS {name}: {_noise_like(r, sigma, wave)}"


def test_gyro_minus_true_heading_is_the_configured_noise(samples: dict[str, Any]) -> None:
    h = samples["hdt"]
    stamps = h[:, 1]
    lf, wf = _field(samples, stamps, "eta_lf"), _field(samples, stamps, "eta_wf")
    r = np.angle(np.exp(1j * (h[:, 0] - lf[:, 2] - wf[:, 2])))
    assert len(r) >= 1200
    assert not _noise_like(r, SIGMA_HDG, wf), _noise_like(r, SIGMA_HDG, wf)
    # rate of turn: the LF yaw rate ν[2] (the WF yaw rate is not in the simulated ROT)
    rt = samples["rot"]
    nu = _field(samples, rt[:, 1], "nu")
    r_rot = rt[:, 0] - nu[:, 2]
    assert not _noise_like(r_rot, SIGMA_ROT, wf), _noise_like(r_rot, SIGMA_ROT, wf)


def test_the_check_fails_with_the_wrong_sign_or_without_roll_and_pitch(samples: dict[str, Any]) -> None:
    stamps = samples["dgps"][:, 3]
    wave = np.hstack([_field(samples, stamps, "eta_wf"), _field(samples, stamps, "wf_attitude")])
    right = _dgps_residuals(samples)  # the truth's 6-DOF pieces rebuild the antenna the sensors see
    rebuilt = _dgps_residuals(samples, sign=1.0, roll_pitch=False)
    flipped = _dgps_residuals(samples, sign=-1.0)
    for j in range(2):
        assert not _noise_like(right[:, j], SIGMA_M, wave)
        assert _noise_like(flipped[:, j], SIGMA_M, wave)  # LF − WF: the old demo's symptom
        assert _noise_like(rebuilt[:, j], SIGMA_M, wave)  # heading-only lever arm: the mast's swing is left
    # and agree with the antenna position the truth logs (to the NMEA's rounding, which is far below σ)
    d = samples["dgps"]
    logged = d[:, :2] - _antennas(samples, stamps)[:, :2]
    assert np.max(np.abs(logged - right[:, :2])) < 1e-6
