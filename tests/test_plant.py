"""The full plant (simulator.plant): kernel = readable reference, each term's physics, the fluid-memory
hook, the current and wind models, and its wiring into scenarios."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from scipy.linalg import expm

from observers.vessel import VesselError, load_vessel, vessel_from_dict
from simulator.crossflow import crossflow, crossflow_strips, hoerner_cd, strips
from simulator.current import Current, CurrentModel
from simulator.plant import FullPlant
from simulator.plant_params import PlantError, PlantOptions, PlantParams
from simulator.plant_reference import rk4_step
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from simulator.vessel_dynamics import VesselDynamics
from simulator.wind import Wind, WindModel, harris_spectrum, norsok_mean, norsok_spectrum

OSV = load_vessel("mss_osv")


@dataclass
class OneState:
    """A hand-made radiation model with one state: sway velocity in, sway and yaw force out."""

    Ar: np.ndarray
    Br: np.ndarray
    Cr: np.ndarray
    Dr: np.ndarray
    A_inf: np.ndarray


def one_state(a: float = 0.2, b: float = 1.0, c: float = 3e5, d: float = 2e4) -> OneState:
    A_inf = np.array(OSV.hull.added_mass) * 1.1  # type: ignore[union-attr]
    return OneState(
        Ar=np.array([[-a]]),
        Br=np.array([[0.0, b, 0.0]]),
        Cr=np.array([[0.0], [c], [-4.0 * c]]),
        Dr=np.diag([0.0, d, 0.0]),
        A_inf=A_inf,
    )


@pytest.mark.parametrize(
    "options",
    [PlantOptions(), PlantOptions(added_mass_coriolis="absolute"), PlantOptions(radiation=one_state())],
    ids=["all", "ca_absolute", "radiation"],
)
def test_kernel_agrees_with_the_readable_reference(options: PlantOptions) -> None:
    plant = FullPlant(OSV, (3.0, -2.0, 0.4), (1.5, -0.4, 0.01), options)
    p = plant.params
    x = plant.x.copy()
    rng = np.random.default_rng(1)
    for _ in range(40):
        tau = rng.normal(0, [3e5, 2e5, 5e6])
        b = rng.normal(0, [5e4, 5e4, 1e6])
        vc = rng.normal(0, 0.6, 2)
        for _ in range(5):
            x = rk4_step(x, 0.05, tau, b, vc, p)
        plant.step(0.25, tau, b, vc)
    scale = np.maximum(np.abs(x), 1.0)
    assert np.max(np.abs(plant.x - x) / scale) < 1e-9


def test_with_every_effect_off_it_is_the_observers_model() -> None:
    """No Coriolis, no drag, no current: exactly M ν' + D ν = τ + Jᵀ b, the model plant."""
    full = FullPlant(OSV, (0.0, 0.0, 0.3), (0.5, 0.1, 0.002), PlantOptions.model_only())
    model = VesselDynamics(OSV, (0.0, 0.0, 0.3), (0.5, 0.1, 0.002))
    for k in range(200):
        tau, b = [2e5 * math.sin(0.05 * k), 5e4, 1e6], [1e4, -2e4, 0.0]
        full.step(0.5, tau, b)
        model.step(0.5, tau, b)
    np.testing.assert_allclose(full.x, model.x, rtol=1e-12, atol=1e-12)


def test_crossflow_closed_form_is_the_strip_integral() -> None:
    """The closed form equals the limit of the strip sum, with and without a sign change of v_r + x r."""
    k, L = 1000.0, 83.0
    fine, dxf = strips(L, 400_000)
    cases = [(0.5, 0.0), (0.3, 0.01), (-0.2, 0.02), (0.0, -0.01), (1.0, -0.03), (-0.5, 1e-9), (0.02, 0.0004)]
    for v, r in cases:
        exact = crossflow(v, r, k, L)
        limit = crossflow_strips(v, r, k, fine, dxf)
        np.testing.assert_allclose(exact, limit, rtol=1e-6, atol=1e-9 * k * L**2)


def test_hoerner_coefficient() -> None:
    assert hoerner_cd(18.0, 5.0) == pytest.approx(0.6664, abs=1e-3)  # B/2T = 1.8
    assert hoerner_cd(100.0, 1.0) == pytest.approx(0.559315)  # past the curve: its last value


def test_munk_moment_of_a_hull_held_in_a_current() -> None:
    """C_A(ν_r): a hull held still at 45° to a 1 m/s current feels the Munk moment (M_A,22 − M_A,11) u_r v_r;
    with C_A evaluated at the absolute velocity (osv.m's convention) it feels none."""
    MA = OSV.hull.added_mass  # type: ignore[union-attr]
    vc = np.array([math.cos(math.radians(45)), math.sin(math.radians(45))])
    on = FullPlant(OSV).current_load(vc)
    off = FullPlant(OSV, options=replace(PlantOptions(), coriolis=False)).current_load(vc)
    absolute = FullPlant(OSV, options=PlantOptions(added_mass_coriolis="absolute")).current_load(vc)
    u_r, v_r = -vc
    assert on[2] - off[2] == pytest.approx(-(MA[1, 1] - MA[0, 0]) * u_r * v_r, rel=1e-9)
    assert absolute[2] == pytest.approx(off[2], rel=1e-12)


def test_surge_resistance_is_linear_slow_and_quadratic_fast() -> None:
    p = PlantParams.build(OSV)
    plant = FullPlant(OSV)
    for u_c, expect in [(-0.01, p.Xu * 0.01), (-8.0, p.Xuu * 64.0)]:
        X = plant.current_load([u_c, 0.0])[0]  # a current from ahead: u_r = -u_c
        assert pytest.approx(-expect, rel=0.02 if abs(u_c) < 1 else 0.05) == X
    # symmetric: astern is resisted as ahead is (the blending weight is of |u_r|)
    assert plant.current_load([1.0, 0.0])[0] == pytest.approx(-plant.current_load([-1.0, 0.0])[0])


def test_radiation_hook_with_a_one_state_system() -> None:
    """(M_RB + A∞) ν' + μ + D ν = τ, x_r' = A x_r + B ν, μ = C x_r + D_r ν: against the matrix exponential."""
    rad = one_state()
    options = PlantOptions(coriolis=False, surge_resistance=False, crossflow=False, radiation=rad)
    plant = FullPlant(OSV, options=options)
    M = OSV.hull.rigid_body_mass(OSV.mass_kg) + rad.A_inf  # type: ignore[union-attr]
    np.testing.assert_allclose(plant.params.M, M)
    assert plant.x.shape == (7,)
    Minv = np.linalg.inv(M)
    # linear in z = [u, v, r, x_r] (no Coriolis, no drag, no current, no bias): z' = F z + G τ
    F = np.zeros((4, 4))
    F[:3, :3] = -Minv @ (OSV.D + rad.Dr)
    F[:3, 3:] = -Minv @ rad.Cr
    F[3:, :3] = rad.Br
    F[3:, 3:] = rad.Ar
    G = np.zeros((4, 3))
    G[:3] = Minv
    tau = np.array([1e5, 2e5, -3e6])
    T = 60.0
    E = expm(np.block([[F, G @ tau[:, None]], [np.zeros((1, 5))]]) * T)
    expected = E[:4, 4]
    plant.step(T, tau)
    np.testing.assert_allclose(plant.x[3:], expected, rtol=1e-6, atol=1e-9)
    assert abs(plant.x[6]) > 0.1  # the radiation state moved
    # and it matters: without the radiation force the sway speed is different
    bare = FullPlant(OSV, options=PlantOptions.model_only())
    bare.step(T, tau)
    assert abs(bare.x[4] - plant.x[4]) > 0.05 * abs(plant.x[4])


def test_radiation_hook_refuses_wrong_shapes_and_unstable_models() -> None:
    with pytest.raises(PlantError, match=r"radiation\.Cr"):
        FullPlant(OSV, options=PlantOptions(radiation=replace(one_state(), Cr=np.zeros((2, 1)))))
    with pytest.raises(PlantError, match=r"radiation\.Ar"):
        FullPlant(OSV, options=PlantOptions(radiation=replace(one_state(), Ar=np.array([[0.1]]))))


def test_full_plant_needs_a_hull() -> None:
    with pytest.raises(PlantError, match=r"\[hull\].*coriolis=off, surge_resistance=off, crossflow=off\)$"):
        FullPlant(load_vessel("northern_clipper"))
    with pytest.raises(PlantError, match=r"\(plant options surge_resistance=off\)$"):
        FullPlant(load_vessel("northern_clipper"), options=PlantOptions(coriolis=False, crossflow=False))
    FullPlant(load_vessel("northern_clipper"), options=PlantOptions.model_only())  # nothing nonlinear: fine


def test_hull_table_errors_name_the_field() -> None:
    import tomllib
    from importlib import resources

    data = tomllib.loads((resources.files("observers") / "vessels" / "mss_osv.toml").read_text())
    broken = {**data, "hull": {k: v for k, v in data["hull"].items() if k != "draft_m"}}
    with pytest.raises(VesselError, match=r"hull\.draft_m"):
        vessel_from_dict(broken)
    wrong = {**data, "hull": {**data["hull"], "x_g_m": 4.5}}
    with pytest.raises(VesselError, match=r"M_RB.*must\s+equal M"):
        vessel_from_dict(wrong)
    typo = {**data, "hull": {**data["hull"], "beam": 18.0}}
    with pytest.raises(VesselError, match=r"field 'hull\.beam': unknown key, did you mean 'beam_m'\?"):
        vessel_from_dict(typo)


def test_current_is_gauss_markov_within_limits() -> None:
    free = Current(CurrentModel(0.5, 30.0, 0.1, 10.0, time_constant_s=50.0), np.random.default_rng(2))
    speeds = []
    for _ in range(100_000):
        free.step(1.0)
        speeds.append(free.speed)
    s = np.array(speeds)
    assert s.mean() == pytest.approx(0.5, abs=0.01)
    assert s.std() == pytest.approx(0.1, rel=0.08)  # the stationary σ
    lag = np.corrcoef(s[:-50], s[50:])[0, 1]
    assert lag == pytest.approx(math.exp(-1.0), abs=0.05)  # correlation e^{-τ/T} at τ = T
    held = Current(
        CurrentModel(
            0.5, 30.0, 0.3, 20.0, 50.0, speed_limits_mps=(0.4, 0.6), direction_limits_deg=(20.0, 40.0)
        ),
        np.random.default_rng(3),
    )
    for _ in range(20_000):
        held.step(1.0)
        assert 0.4 <= held.speed <= 0.6 and 20.0 <= held.direction_deg <= 40.0


def test_gusts_have_the_spectrum_variance() -> None:
    area = OSV.hull.wind  # type: ignore[union-attr]
    for gust, spectrum in [("norsok", norsok_spectrum), ("harris", harris_spectrum)]:
        model = WindModel(15.0, 0.0, gust=gust)
        f = np.geomspace(model.f_min_hz, model.f_max_hz, 20_000)
        var = np.trapezoid(spectrum(f, 15.0), f)
        wind = Wind(model, area, 83.0, np.random.default_rng(1))
        assert np.sum(wind.amplitude**2) / 2 == pytest.approx(var, rel=0.05)  # the harmonics carry S(f) df
        series = wind.gust(np.arange(0.0, 40_000.0, 2.0))
        assert series.var() == pytest.approx(
            var, rel=0.3
        )  # and the series shows it (40 periods of the slowest)
    wind = Wind(WindModel(15.0, 0.0), area, 83.0, np.random.default_rng(0))
    t = np.arange(100.0, 300.0, 0.05)
    direct = wind.mean + wind.gust(t)
    cached = np.array([wind.speed(x) for x in t])
    assert np.max(np.abs(direct - cached)) < 0.01


def test_wind_force_signs() -> None:
    """Head wind pushes astern; wind from starboard pushes to port; on the starboard bow it turns the bow to
    port."""
    area = OSV.hull.wind  # type: ignore[union-attr]
    head = Wind(WindModel(15.0, 0.0, gust="none"), area, 83.0, np.random.default_rng(0)).force_body(
        0, 0, 0, 0
    )
    assert head[0] < 0 and abs(head[1]) < 1e-6 * abs(head[0])
    beam = Wind(WindModel(15.0, 90.0, gust="none"), area, 83.0, np.random.default_rng(0)).force_body(
        0, 0, 0, 0
    )
    at_height = norsok_mean(15.0, area.height_m)  # (15 m/s is the 10 m mean, whatever the gusts)
    assert beam[1] < 0 and beam[1] == pytest.approx(
        -0.5 * 1.226 * at_height**2 * area.cy * area.lateral_area_m2
    )
    bow = Wind(WindModel(15.0, 45.0, gust="none"), area, 83.0, np.random.default_rng(0)).force_body(
        0, 0, 0, 0
    )
    assert bow[2] < 0


def test_model_scenarios_keep_the_model_plant() -> None:
    for name in ("torsetnes_2004", "snijders_2005", "fossen_strand_1999"):
        sim = Simulation(get_scenario(name), 0)
        assert isinstance(sim.dynamics, VesselDynamics) and sim.plant_env is None


def test_mss_osv_scenario_runs_the_full_plant_in_current_and_wind() -> None:
    sim = Simulation(get_scenario("mss_osv"), 0)
    assert isinstance(sim.dynamics, FullPlant)
    sim.run(120.0)
    env = sim.plant_env
    assert env is not None and env.current is not None and env.wind is not None
    assert 0.3 <= env.current.speed <= 0.7
    assert np.linalg.norm(env.wind_body) > 1e4
    assert np.all(np.isfinite(sim.dynamics.x))


def test_current_or_wind_on_the_model_plant_is_refused() -> None:
    with pytest.raises(ValueError, match="'plant'"):
        replace(get_scenario("torsetnes_2004"), current=CurrentModel(0.5, 0.0))
    with pytest.raises(ValueError, match="'plant'"):
        replace(get_scenario("torsetnes_2004"), plant="fancy")


def test_thruster_rpm_follows_each_thrusters_own_law() -> None:
    """The simulator's drives report rpm by the vessel file's max_rpm per thruster — the law the gateway
    reads them with (a fixed 200 rpm would put mss_osv's tunnels beyond their 140 rpm and be rejected)."""
    from simulator.thrusters import ThrusterBank

    bank = ThrusterBank(OSV)
    bank.thrust[:] = [t.max_thrust_n for t in OSV.thrusters]
    np.testing.assert_allclose(bank.rpm, [t.max_rpm for t in OSV.thrusters])
    for t, rpm, thrust in zip(OSV.thrusters, bank.rpm, bank.thrust, strict=True):
        assert t.thrust_at_rpm(rpm) == pytest.approx(thrust)
