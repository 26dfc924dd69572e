"""Station keeping: the gateway's observer, controller and allocation close the loop on the
simulator (in process: the simulator's bytes in, the gateway's thruster commands out)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from dpgw.cli_demo import hold_setpoint
from dpgw.closed_loop import ClosedLoopRun, gateway_tables, run_closed_loop
from gateway.scoring import score
from observers.kinematics import ssa
from simulator.clock import SimEpoch
from simulator.scenarios import get_scenario
from simulator.spectra import SeaState

HOLD = [(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0})]


@pytest.mark.slow
def test_torsetnes_station_keeping_in_6_m_seas() -> None:
    """MSS supply vessel at (0, 0), heading 45°, JONSWAP Hs 6 m: 30 min after a 5 min settle, horizontal
    position error p95 ≤ 2.0 m and heading error p95 ≤ 2° (measured: 1.22 m, 1.33° for seed 1), and the
    integral action closes: the true LF heading's 30-minute mean within 0.2° of the setpoint and the
    position's mean within 0.2 m per axis (measured +0.115°, −0.05 m N, +0.03 m E for seed 1; seeds 0 and 2
    gave +0.15° and +0.02°, and 2 h of seed 0 +0.04°: what is left is the slowly varying load the
    integrator is still following at the end of the window, not an offset)."""
    r = run_closed_loop(get_scenario("torsetnes_2004"), 2100.0, seed=1, events=HOLD)
    keep = r.t >= 300.0
    pos = np.hypot(r.eta_lf[keep, 0], r.eta_lf[keep, 1])
    signed = np.degrees(ssa(r.eta_lf[keep, 2] - math.radians(45.0)))
    assert np.percentile(pos, 95) <= 2.0
    assert np.percentile(np.abs(signed), 95) <= 2.0
    assert abs(signed.mean()) <= 0.2
    assert np.all(np.abs(r.eta_lf[keep, :2].mean(axis=0)) <= 0.2)
    assert len(r.commands) > 20_000 and not any(math.isnan(v) for c in r.commands for v in c["tau_demand"])


def test_demo_holds_the_scenarios_station() -> None:
    """`dpgw demo` in dp commands the scenario's start position and heading as its setpoint (holding the
    first estimate instead held a wave-moved, noisy fix: 45.9° for torsetnes_2004's 45° station)."""

    assert hold_setpoint(get_scenario("torsetnes_2004")) == pytest.approx(
        {"north_m": 0.0, "east_m": 0.0, "heading_deg": 45.0}
    )


@pytest.mark.slow  # two seeds of 400 s: ~5 s
@pytest.mark.parametrize("seed", [0, 2])
def test_hassani_holds_its_heading_as_a_ship_does(seed: int) -> None:
    """CyberShip II (1:70) holding its start station in the `hassani` sea, scored after 100 s: heading p95
    ≤ 3° and position p95 ≤ 0.15 m, and the observer's own LF heading error p95 ≤ 2°. Angles are the same
    in Froude-scaled terms, and the ship of torsetnes_2004 is held to ≤ 2° (above); the passive observer's
    bias corner, capped at ~0.045 ω0 by its SPR condition, leaves the model ~1.5° of estimate error that
    a ship in its own sea does not have, hence 3°. The cause of the 5.5-6.5° before (0.20-0.25 m; estimate
    error 3.8-5.3°): the observer's velocity injection, a ratio to the sea's ω0 (0.11 s⁻¹), left its
    velocity error decaying two to three times slower than the Froude-scaled DP loop it fed (0.55-0.78
    rad/s); now held no slower than the loop (measured: 2.27°, 0.094 m, 1.57° on seed 0; 2.49°, 0.093 m,
    1.59° on seed 2)."""
    sc = get_scenario("hassani")
    r = run_closed_loop(sc, 400.0, seed=seed, events=[(0.0, "setpoint", hold_setpoint(sc))])
    keep = r.t >= 100.0
    psi0 = sc.eta0[2]
    heading = np.degrees(np.abs(ssa(r.eta_lf[keep, 2] - psi0)))
    pos = np.hypot(r.eta_lf[keep, 0] - sc.eta0[0], r.eta_lf[keep, 1] - sc.eta0[1])
    epoch_ns = SimEpoch(sc.start_utc).stamp_ns(0.0)  # sim time 0
    t_est = np.array([(m.stamp_ns - epoch_ns) / 1e9 for m in r.estimate_messages])
    at = np.searchsorted(t_est, r.t[keep], side="right") - 1  # the estimate in force at each truth sample
    psi_hat = np.array([m.eta[2] for m in r.estimate_messages])[at]
    observer = np.degrees(np.abs(ssa(psi_hat - r.eta_lf[keep, 2])))
    assert np.percentile(heading, 95) <= 3.0
    assert np.percentile(pos, 95) <= 0.15
    assert np.percentile(observer, 95) <= 2.0


def _wave_band_thrust(r: ClosedLoopRun, omega_p: float) -> np.ndarray:
    """Standard deviation of each thruster's commanded thrust in the band 0.5–2.5 ωp (after 5 min)."""
    t = (np.array([c["stamp_ns"] for c in r.commands]) - r.commands[0]["stamp_ns"]) / 1e9
    thrust = np.array([[th["thrust_n"] for th in c["thrusters"]] for c in r.commands])
    fs = 1.0 / np.median(np.diff(t))
    sos = butter(
        4, [0.5 * omega_p / (2 * math.pi), 2.5 * omega_p / (2 * math.pi)], btype="band", fs=fs, output="sos"
    )
    return np.asarray(sosfiltfilt(sos, thrust[t > 300.0], axis=0).std(axis=0))


@pytest.mark.slow
def test_wave_filtering_pays_20_db_in_commanded_thrust() -> None:
    """The same controller fed the raw measurements (position, heading and a filtered derivative for the
    velocity; no observer) commands ≥ 10× (20 dB) more wave-band thrust variation (measured: 13×)."""
    sc = get_scenario("torsetnes_2004")
    omega_p = sc.sea[0][1].peak_frequency
    filtered = _wave_band_thrust(run_closed_loop(sc, 900.0, seed=2, events=HOLD), omega_p)
    raw_tables = gateway_tables(sc, feedback="measurement")
    raw = _wave_band_thrust(run_closed_loop(sc, 900.0, seed=2, events=HOLD, tables=raw_tables), omega_p)
    assert np.linalg.norm(raw) / np.linalg.norm(filtered) >= 10.0


@pytest.mark.slow
def test_10_m_setpoint_step_overshoot_below_1_m() -> None:
    """A 10 m step north at t = 300 s (moderate sea, Hs 2 m): reached with overshoot ≤ 1 m (measured
    0.39 m on the true LF motion), settling near the target."""
    sea = ((0.0, SeaState(2.0, 8.0, direction_rad=math.radians(255.0))),)
    sc = replace(get_scenario("torsetnes_2004"), sea=sea)
    step = (300.0, "setpoint", {"north_m": 10.0, "east_m": 0.0, "heading_deg": 45.0})
    r = run_closed_loop(sc, 900.0, seed=1, events=[*HOLD, step])
    after = r.t >= 300.0
    north = r.eta_lf[after, 0]
    assert north.max() - 10.0 <= 1.0
    assert north.max() > 9.5  # it got there
    assert abs(north[r.t[after] > 800.0].mean() - 10.0) < 1.0


def test_snijders_2005_track_and_the_papers_table(capsys: pytest.CaptureFixture[str]) -> None:
    """The track of Snijders et al. Sec. 4 closed-loop, and their table: (1/n) Σ (η̂ − η)² per DOF for the
    passive ('existing') observer — the same order as the paper's 3.98e-2, 6.39e-2 (m²)."""
    r = run_closed_loop(get_scenario("snijders_2005"), 1800.0, seed=1, events=snijders_track())
    table = snijders_table(r)
    print(format_snijders_table(table))
    assert capsys.readouterr().out.count("\n") >= 4
    assert table[0] < 0.2 and table[1] < 0.3  # m², paper: 0.040 and 0.064
    assert np.degrees(np.sqrt(table[2])) < 1.0  # rad² → RMS below 1°
    assert np.allclose(r.eta_lf[-1, :2], [-10.0, -10.0], atol=2.0)
    assert abs(math.degrees(ssa(r.eta_lf[-1, 2])) - 45.0) < 3.0


@pytest.mark.slow
def test_snijders_table_on_the_full_plant() -> None:
    """Snijders et al.'s table off the observers' own model: on the full plant's nonlinear hull and in a
    0.5 m/s current with 10 m/s wind (`snijders_scenario`), both observers stay within 4× of their
    model-plant mean-square error in every DOF (measured, seeds 1–5: at most 1.9× on the hull, 3.0× in
    weather — the passive observer's yaw), within the paper's own scale in surge and sway (≤ 0.1 m²), and
    `sdre` at or below `passive` in every DOF (docs/sdre.md explains why, band by band)."""
    tables = {
        (plant, obs): snijders_tables(obs, [1], plant=plant)[0]
        for plant in SNIJDERS_PLANTS
        for obs in ("sdre", "passive")
    }
    for plant in ("full", "full+weather"):
        for obs in ("sdre", "passive"):
            ratio = tables[plant, obs] / tables["model", obs]
            assert np.all(ratio <= 4.0), (plant, obs, ratio)
            assert np.all(tables[plant, obs][:2] <= 0.1), (plant, obs)
    for plant in SNIJDERS_PLANTS:
        assert np.all(tables[plant, "sdre"] <= tables[plant, "passive"]), plant


def snijders_track() -> list[tuple[float, str, dict[str, float]]]:
    return [
        (0.0, "setpoint", {"north_m": 10.0, "east_m": 10.0, "heading_deg": 0.0}),
        (1000.0, "setpoint", {"north_m": -10.0, "east_m": -10.0, "heading_deg": 45.0}),
    ]


PAPER_SDRE = (6.3329e-2, 1.5498e-1, 4.9448e-3)
PAPER_EXISTING = (3.9768e-2, 6.3857e-2, 1.8719e-2)


SNIJDERS_PLANTS = ("model", "full", "full+weather")


def snijders_scenario(plant: str = "model") -> Any:
    """The snijders_2005 case on a plant: ``model`` — the paper's own (the observers' model, η' = J(ψ)ν,
    Mν' + Dν = τ + Jᵀb, first-order wave motion on top); ``full`` — the nonlinear hull of the full plant
    (Coriolis of rigid body and added mass, blended surge resistance, cross-flow drag; snijders_ship's
    [hull] table), the same Markov bias and waves; ``full+weather`` — that hull in a 0.5 m/s current and a
    10 m/s NORSOK wind, both with the waves (the paper has no current or wind of its own: its b stands for
    them; collinear environment is the usual DP design case)."""
    from simulator.current import CurrentModel
    from simulator.wind import WindModel

    sc = get_scenario("snijders_2005")
    if plant == "model":
        return sc
    if plant == "full":
        return replace(sc, plant="full")
    if plant == "full+weather":
        towards = math.degrees(sc.sea[0][1].direction_rad) % 360.0  # the waves travel towards 200°
        current = CurrentModel(
            speed_mps=0.5,
            direction_deg=towards,
            speed_sigma_mps=0.05,
            direction_sigma_deg=5.0,
            time_constant_s=900.0,
            speed_limits_mps=(0.3, 0.7),
            direction_limits_deg=(towards - 20.0, towards + 20.0),
        )
        wind = WindModel(speed_mps=10.0, from_deg=(towards + 180.0) % 360.0, gust="norsok")
        return replace(sc, plant="full", current=current, wind=wind)
    raise ValueError(f"plant: one of {SNIJDERS_PLANTS}, got {plant!r}")


def snijders_tables(
    observer: str, seeds: list[int], params: dict[str, Any] | None = None, plant: str = "model"
) -> np.ndarray:
    """The table of ``observer`` (an `observers.factory` name) on the snijders_2005 case, a row per seed."""
    sc = snijders_scenario(plant)
    rows = []
    for seed in seeds:
        tables = gateway_tables(sc)
        tables["observer"]["type"] = observer
        if params:
            tables["observer"]["params"] = params
        r = run_closed_loop(sc, 1800.0, seed=seed, events=snijders_track(), tables=tables)
        rows.append(snijders_table(r))
    return np.array(rows)


def format_snijders_comparison(columns: list[tuple[str, np.ndarray]]) -> str:
    """The paper's two columns beside dpgw's: (label, rows of `snijders_tables`) as mean ± sd over seeds."""
    head = f"  {'':6s} {'paper SDRE':>11s} {'paper exist.':>12s}" + "".join(f" {c[0]:>22s}" for c in columns)
    rows = [head + "  unit"]
    for i, (name, unit) in enumerate(zip(("Surge", "Sway", "Yaw"), ("m²", "m²", "rad²"), strict=True)):
        cells = "".join(f"  {t[:, i].mean():10.3e} ± {t[:, i].std(ddof=1):7.1e}" for _, t in columns)
        rows.append(f"  {name:6s} {PAPER_SDRE[i]:11.3e} {PAPER_EXISTING[i]:12.3e}{cells}  {unit}")
    seeds = len(columns[0][1])
    rows.append(
        f"  (dpgw: mean ± standard deviation over {seeds} seeds; the paper does not state its yaw unit)"
    )
    return "\n".join(rows)


def snijders_table(r: ClosedLoopRun) -> tuple[float, float, float]:
    est = np.array([e["eta"] for e in r.estimates])
    t_est = (np.array([e["stamp_ns"] for e in r.estimates]) - r.estimates[0]["stamp_ns"]) / 1e9
    s = score(t_est, est, r.t - r.t[0], r.eta_lf)
    return s.mean_square


def format_snijders_table(ms: tuple[float, float, float]) -> str:
    paper = PAPER_EXISTING
    rows = ["            dpgw passive      paper 'Existing'  (paper SDRE: 6.33e-2, 1.55e-1, 4.94e-3)"]
    for name, ours, theirs, unit in zip(
        ("Surge", "Sway", "Yaw"), ms, paper, ("m²", "m²", "rad²"), strict=True
    ):
        their_unit = "not stated" if unit == "rad²" else unit
        rows.append(f"  {name:6s}  {ours:12.4e} {unit:4s} {theirs:12.4e} (unit {their_unit})")
    return "\n".join(rows)


# Station-keeping figures of the same runs before the azimuths' turn cost was put in angle and the thrust
# biasing added (turn weight 1 on the cross force, no bias; seed 1, 400 s after 200 s): position p95 (m),
# heading p95 (°), and the azimuths' travel then (°/min). Kept to bound what the remedy may cost.
_BEFORE = {
    "torsetnes_2004": (0.874, 1.776, (545.0, 630.0, 331.4)),
    "hassani": (0.232, 6.044, (2214.4, 2187.4)),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(_BEFORE))
def test_azimuths_do_not_hunt_in_station_keeping(name: str) -> None:
    """Holding station, every azimuth travels less than 10 % of its slew rate (measured: torsetnes_2004
    11, 5, 16 °/min of 722 = 1.5, 0.7, 2.2 %; hassani 457, 375 of 5844 °/min = 7.8, 6.4 % — before: 46-87 %
    and 37-38 %; hassani's were 181, 255 °/min = 3.1, 4.4 % before its observer was held no slower than
    the DP loop, whose faster velocity estimate passes more of the sea to the azimuths), not one
    allocation step is reported saturated (before: none on torsetnes_2004, 8 % on hassani; the demand is
    well inside the thrusters' capacity, so a flag would be the anti-hunting terms taking τ), and the
    station keeping is not more than 10 % worse than before in position or heading p95
    (measured: 0.891 m and 1.750° against 0.874 m and 1.776°; 0.103 m and 2.431° against 0.232 m and
    6.044°). The before figures are what `dpgw.azimuth_travel --before` gives (`BEFORE`)."""
    from dpgw.azimuth_travel import measure

    fig = measure(name, seed=1, settle_s=200.0, window_s=400.0)
    pos_before, head_before, _ = _BEFORE[name]
    for k, travel in fig.travel_deg_per_min.items():
        assert travel < 0.10 * fig.slew_deg_per_min[k], (k, travel)
    assert fig.saturated_fraction == 0.0
    assert fig.position_p95_m <= 1.10 * pos_before
    assert fig.heading_p95_deg <= 1.10 * head_before
