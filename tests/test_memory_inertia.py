"""The fluid-memory observer's inertia M_m = M - [A(0) - A(∞)] (Hajivand & Mousavizadegan 2010, eq (20):
M_RB + A(∞)) is never below the rigid-body mass: for every built-in vessel, with the radiation model dpgw
picks for it (its own, or the built-in one Froude-scaled and fitted per DOF to the vessel's added mass,
`memory_tuning.fit_scale`), and for the vessel file in the Cummins form (Hajivand's: M_RB and A(∞) given).
Before the fit the borrowed model's A(0) - A(∞) exceeded the vessel's own added mass in surge on four
built-in vessels (M_m / M_RB - 1: hajivand -12 %, cybership2 -6 %, mss_osv -3 %, mss_supply -2 %)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from observers.memory_tuning import (
    builtin_radiation,
    check_model,
    check_radiation_passivity,
    check_velocity_passivity,
    fit_scale,
    memory_model,
    memory_share,
    own_radiation,
)
from observers.radiation_builtin import memory_added_mass
from observers.vessel import VesselError, builtin_vessels, load_vessel, rigid_body_diagonal, vessel_from_dict


def _table() -> str:
    rows = []
    for name in builtin_vessels():
        v = load_vessel(name)
        m = memory_model(v)
        rows.append(f"{name}: M_m {np.diag(m.M).round(4).tolist()} M_RB {rigid_body_diagonal(v).tolist()}")
    return "\n".join(rows)


@pytest.mark.parametrize("name", builtin_vessels())
def test_memory_inertia_is_not_below_the_rigid_body_mass(name: str) -> None:
    vessel = load_vessel(name)
    model = memory_model(vessel)
    rb = rigid_body_diagonal(vessel)
    assert np.all(np.isfinite(rb[:2])), "surge and sway M_RB are the mass: always known"
    known = np.isfinite(rb)
    ratio = np.diag(model.M)[known] / rb[known] - 1.0
    assert np.all(ratio >= 0.0), f"M_m / M_RB - 1 = {ratio} (an A(∞) < 0)\n{_table()}"
    assert np.linalg.eigvalsh(model.M).min() > 0
    assert check_model(model).ok
    assert check_radiation_passivity(model.radiation).ok
    assert check_velocity_passivity(model).ok


@pytest.mark.parametrize("name", [n for n in builtin_vessels() if load_vessel(n).A_inf is None])
def test_fitted_model_leaves_the_vessel_the_model_hulls_share_of_A_inf(name: str) -> None:
    """Zero-frequency form (M = M_RB + A(0)): per DOF with M_RB known, the implied A(∞) is at least
    (1 - share) of the vessel's added mass, share the model hull's (A(0) - A(∞)) / A(0); where the
    Froude-scaled model fits, it is not changed (s = 1)."""
    vessel = load_vessel(name)
    model = memory_model(vessel)
    rb = rigid_body_diagonal(vessel)
    a = np.diag(vessel.M) - rb
    a_inf = np.diag(model.M) - rb
    share = memory_share(model.radiation)
    for i in range(3):
        if math.isfinite(rb[i]):
            assert a_inf[i] >= (1.0 - share[i]) * a[i] * (1 - 1e-9), (i, a_inf[i], a[i], share[i])
    s = fit_scale(vessel, model.radiation)
    assert np.allclose(s, 1.0), "fitting a fitted model changes nothing"


def test_dof_scaling_is_a_congruence_that_keeps_passivity() -> None:
    r = builtin_radiation()
    s = np.array([0.5, 1.2, 0.8])
    S = np.diag(s)
    scaled = r.dof_scaled(s)
    w = np.logspace(-2, 1, 40)
    K, Ks = r.frequency_response(w), scaled.frequency_response(w)
    assert np.allclose(Ks, S @ K @ S, rtol=1e-12, atol=0)
    assert np.allclose(scaled.A_inf, S @ r.A_inf @ S)
    assert np.allclose(memory_added_mass(scaled), S @ memory_added_mass(r) @ S)
    assert np.allclose(memory_share(scaled), memory_share(r))
    assert check_radiation_passivity(scaled).ok
    Cr = scaled.Cr.copy()
    Cr[1] *= -1  # the check can fail: one output reversed
    from dataclasses import replace

    assert not check_radiation_passivity(replace(scaled, Cr=Cr)).ok
    with pytest.raises(ValueError, match="three positive"):
        r.dof_scaled([1.0, 0.0, 1.0])


def test_mss_supply_uses_its_own_model_fitted_where_its_file_disagrees_with_its_data() -> None:
    """mss_supply's data (ShipX, 82.8 m hull) give A(0) = 1.57e6 kg in surge; its file (supply.m) has an
    added mass M - M_RB of 0.76e6 kg there, and agrees with the data in sway and yaw (within 2 % and 6 %).
    Its own model keeps its time scale (not Froude-scaled) and is scaled only in surge."""
    vessel = load_vessel("mss_supply")
    own = own_radiation(vessel)
    assert own is builtin_radiation()
    model = memory_model(vessel)
    assert np.array_equal(model.radiation.Ar, own.Ar)  # the data's hull: no Froude scaling
    s = fit_scale(vessel, own)
    a = np.diag(vessel.M) - rigid_body_diagonal(vessel)
    a0 = np.diag(own.zero_frequency_added_mass())
    assert a0[0] > 2 * a[0] and abs(a0[1] / a[1] - 1) < 0.03 and abs(a0[2] / a[2] - 1) < 0.07
    assert s[0] < 0.75 and s[1] == 1.0 and s[2] == 1.0
    assert np.allclose(
        model.radiation.frequency_response([0.5])[0],
        np.diag(s) @ own.frequency_response([0.5])[0] @ np.diag(s),
    )
    # a user file that only borrows the name is not the built-in vessel: no own model
    other = vessel_from_dict(
        {
            "name": "mss_supply",
            "length_m": 76.2,
            "mass_kg": 6.0e6,
            "M": vessel.M.tolist(),
            "D": (vessel.D * 2).tolist(),
        }
    )
    assert own_radiation(other) is None


def test_cummins_form_gives_eq_20_its_printed_inertia_and_everyone_else_the_low_frequency_one() -> None:
    """Hajivand's file gives M_RB and A(∞) (the paper's printed M_RB and A): the memory observer's inertia
    is exactly M_RB + A(∞), and the vessel's M (the passive observer's, the controller's, the plant without
    memory's) is that plus A(0) - A(∞) of the same model, so that both agree as ω → 0."""
    vessel = load_vessel("hajivand_vessel")
    assert vessel.M_RB is not None and vessel.A_inf is not None
    model = memory_model(vessel)
    assert np.allclose(model.M, vessel.M_RB + vessel.A_inf, rtol=1e-12)
    assert np.allclose(vessel.M, model.M + memory_added_mass(model.radiation), rtol=1e-12)
    assert np.allclose(np.diag(model.M), [1.23e8, 1.61e8, 4.006e11])


def test_cummins_form_file_errors_name_the_field() -> None:
    base = {"name": "x", "length_m": 100.0, "mass_kg": 1e7, "D": np.diag([1e5, 1e5, 1e9]).tolist()}
    m_rb = np.diag([1e7, 1e7, 6e9]).tolist()
    a_inf = np.diag([1e6, 5e6, 3e9]).tolist()
    with pytest.raises(VesselError, match=r"field 'A_inf'.*not both"):
        vessel_from_dict({**base, "M": m_rb, "M_RB": m_rb, "A_inf": a_inf})
    with pytest.raises(VesselError, match="field 'M_RB': missing"):
        vessel_from_dict({**base, "A_inf": a_inf})
    with pytest.raises(VesselError, match="field 'M_RB': exceeds M"):
        vessel_from_dict(
            {**base, "M": np.diag([1e7, 2e7, 7e9]).tolist(), "M_RB": np.diag([1.1e7, 1e7, 6e9]).tolist()}
        )
    v = vessel_from_dict({**base, "M_RB": m_rb, "A_inf": a_inf})
    assert np.all(np.diag(v.M) > np.diag(np.array(m_rb) + np.array(a_inf)))


def test_plant_with_memory_is_the_memory_observers_model_and_the_files_ship_at_low_frequency() -> None:
    """mss_supply_storm's plant integrates the model the memory observer uses: its mass M_RB + A(∞) is the
    observer's M_m, and with the memory's A(0) - A(∞) it is the vessel file's M (the plant without memory,
    the passive observer) — before, the plant had the data's A(∞) and 7.57e6 kg in surge at ω → 0 against
    the file's 6.76e6."""
    from simulator.plant_params import PlantParams
    from simulator.scenarios import get_scenario

    scenario = get_scenario("mss_supply_storm")
    radiation = scenario.plant_options.radiation
    model = memory_model(scenario.vessel)
    assert radiation is not None
    for name in ("Ar", "Br", "Cr", "Dr", "A_inf"):
        assert np.array_equal(getattr(radiation, name), getattr(model.radiation, name)), name
    plant = PlantParams.build(scenario.vessel, scenario.plant_options)
    np.testing.assert_allclose(plant.M, model.M, rtol=1e-12)
    np.testing.assert_allclose(plant.M + memory_added_mass(radiation), scenario.vessel.M, rtol=1e-12)
