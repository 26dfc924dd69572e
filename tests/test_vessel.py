"""Vessel models: built-ins load with their sources; impossible models are refused naming the field."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from observers.vessel import VesselError, builtin_vessels, load_vessel, vessel_from_dict

GOOD = {
    "name": "test_ship",
    "length_m": 50.0,
    "mass_kg": 1.0e6,
    "M": [[1.1e6, 0, 0], [0, 1.5e6, 1e5], [0, 1e5, 3e8]],
    "D": [[1e4, 0, 0], [0, 5e4, -1e5], [0, -1e5, 4e7]],
}


def test_builtin_vessels_load_and_cite_sources() -> None:
    names = builtin_vessels()
    assert set(names) >= {"northern_clipper", "mss_supply", "cybership2", "snijders_ship", "hajivand_vessel"}
    for name in names:
        v = load_vessel(name)
        assert v.name == name and v.source, name
        assert np.all(np.linalg.eigvalsh(v.M) > 0) and np.all(np.linalg.eigvalsh(v.D + v.D.T) > 0)


def test_northern_clipper_is_the_papers_model() -> None:
    v = load_vessel("northern_clipper")
    assert v.M[0, 0] == 5.3122e6 and v.M[2, 2] == 3.7454e9
    assert v.D[1, 2] == -4.3933e6 and v.mass_kg == 4.591e6 and v.length_m == 76.2


def test_mss_supply_from_bis_system() -> None:
    """M = m T Mbis T, D = m √(g/L) T Dbis T, T = diag(1, 1, L), as in MSS supply.m."""
    v = load_vessel("mss_supply")
    m, L, g = 6.0e6, 76.2, 9.81
    assert v.M[0, 0] == pytest.approx(m * 1.1274)
    assert v.M[1, 2] == pytest.approx(m * -0.0744 * L)
    assert v.M[2, 2] == pytest.approx(m * 0.1278 * L**2)
    assert v.D[1, 1] == pytest.approx(m * math.sqrt(g / L) * 0.1183)
    assert v.D[2, 1] == pytest.approx(m * math.sqrt(g / L) * -0.0041 * L)
    assert v.D[1, 2] == pytest.approx(m * math.sqrt(g / L) * -0.0124 * L)


def test_other_papers_models() -> None:
    assert load_vessel("cybership2").M[1, 2] == 1.0115
    assert load_vessel("snijders_ship").M[2, 2] == pytest.approx(3.193e9)
    haj = load_vessel("hajivand_vessel")
    assert haj.M_RB is not None and haj.A_inf is not None  # the Cummins form: M_RB + A(∞) as printed
    assert (haj.M_RB + haj.A_inf)[2, 2] == pytest.approx(3.46e11 + 5.46e10)
    assert haj.M[2, 2] > 3.46e11 + 5.46e10  # plus A(0) - A(∞) of the lent radiation model
    assert haj.D[1, 1] == pytest.approx(1.2e7)


# M and D exactly as each paper prints them (Hajivand's M is its M_RB plus its A; its "1.210^7" is 1.2e7).
PAPERS_MATRICES = {
    "northern_clipper": (  # Fossen & Strand (1999), (56)-(57)
        [[5.3122e6, 0, 0], [0, 8.2831e6, 0], [0, 0, 3.7454e9]],
        [[5.0242e4, 0, 0], [0, 2.7229e5, -4.3933e6], [0, -4.3933e6, 4.1894e8]],
    ),
    "cybership2": (  # Hassani et al., (A.1)
        [[25.8, 0, 0], [0, 33.8, 1.0115], [0, 1.0115, 2.76]],
        [[2, 0, 0], [0, 7, 0.1], [0, 0.1, 0.5]],
    ),
    "snijders_ship": (  # Snijders, van der Woude & Westhuis (2005), Sec. 4
        (1e9 * np.array([[0.0070, 0, 0], [0, 0.0110, -0.0130], [0, -0.0130, 3.1930]])).tolist(),
        [[200000, 0, 0], [0, 100000, -700000], [0, -700000, 63900000]],
    ),
    "hajivand_vessel": (  # Hajivand & Mousavizadegan (2010), 'Simulations results': M_RB + A, D
        (
            np.array([[1.2e8, 0, 0], [0, 1.4e8, 3e7], [0, 3e7, 3.46e11]])
            + np.array([[3e6, 0, 0], [0, 2.1e7, 3.5e7], [0, 3.5e7, 5.46e10]])
        ).tolist(),
        [[2e6, 0, 0], [0, 1.2e7, -7e6], [0, -7e6, 2.23e10]],
    ),
}


@pytest.mark.parametrize("name", sorted(PAPERS_MATRICES))
def test_papers_vessels_have_every_printed_entry(name: str) -> None:
    """Every entry of M and D of the four papers' vessels, not one or two: a transposed coupling or a
    dropped sign in a vessel file would move every observer table built on it."""
    M, D = PAPERS_MATRICES[name]
    v = load_vessel(name)
    # Hajivand's file is in the Cummins form: the printed M_RB + A is M_RB + A(∞) (docs/vessels.md)
    printed_M = v.M if v.A_inf is None else v.M_RB + v.A_inf
    np.testing.assert_allclose(printed_M, M, rtol=1e-12, atol=0)
    np.testing.assert_allclose(v.D, D, rtol=1e-12, atol=0)


def test_user_vessel_from_toml(tmp_path: Path) -> None:
    f = tmp_path / "my_ship.toml"
    f.write_text(
        'name = "my_ship"\nlength_m = 50.0\nmass_kg = 1.0e6\nsource = "sea trial 2026"\n'
        "M = [[1.1e6, 0, 0], [0, 1.5e6, 1e5], [0, 1e5, 3e8]]\n"
        "D = [[1e4, 0, 0], [0, 5e4, -1e5], [0, -1e5, 4e7]]\n"
        '[[thrusters]]\nid = 1\nkind = "azimuth"\nx_m = -20.0\ny_m = 3.0\nmax_thrust_n = 2e5\n'
        "azimuth_rate_rad_s = 0.2\n"
        '[[thrusters]]\nid = 2\nkind = "tunnel"\nx_m = 20.0\ny_m = 0.0\nmax_thrust_n = 1e5\n'
        "min_thrust_n = -1e5\n"
    )
    v = load_vessel(f)
    assert v.name == "my_ship" and len(v.thrusters) == 2
    assert v.thrusters[1].angle_rad == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        ({"M": [[1e6, 0, 0], [0, 1e6, 5e5], [0, 0, 1e8]]}, "'M'", "symmetric"),
        ({"M": [[1e6, 0, 0], [0, -1e6, 0], [0, 0, 1e8]]}, "'M'", "positive definite"),
        ({"D": [[1e4, 0, 0], [0, -5e4, 0], [0, 0, 4e7]]}, "'D'", "D + Dᵀ must be positive definite"),
        ({"D": [[1e4, 0], [0, 5e4]]}, "'D'", "3×3"),
        ({"M": [[1e6, 0, 0], [0, float("nan"), 0], [0, 0, 1e8]]}, "'M'", "non-finite"),
        ({"M": "heavy"}, "'M'", "3×3"),
        ({"length_m": -3.0}, "'length_m'", "positive"),
        ({"mass_kg": None}, "'mass_kg'", "missing"),
        ({"name": ""}, "'name'", "missing"),
        ({"thrusters": [{"id": 1, "kind": "jet", "x_m": 0, "y_m": 0, "max_thrust_n": 1}]}, "kind", "one of"),
        (
            {"thrusters": [{"id": 1, "kind": "azimuth", "x_m": 0, "y_m": 0, "max_thrust_n": 1e5}]},
            "azimuth_rate",
            "",
        ),
        (
            {"thrusters": [{"id": 1, "kind": "main", "x_m": 0, "y_m": 0, "max_thrust_n": 1, "rpm": 3}]},
            "unknown",
            "",
        ),
    ],
)
def test_bad_models_are_refused_naming_the_field(change: dict, field: str, reason: str) -> None:
    data = {**GOOD, **change}
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(VesselError) as err:
        vessel_from_dict(data, "ship.toml")
    msg = str(err.value)
    assert field in msg and reason in msg, msg


def test_bad_files(tmp_path: Path) -> None:
    with pytest.raises(VesselError, match="not a built-in vessel"):
        load_vessel("titanic")
    with pytest.raises(VesselError, match="does not exist"):
        load_vessel(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\nM = [[1,2]\n")
    with pytest.raises(VesselError, match="not valid TOML"):
        load_vessel(bad)


def test_barred_zones_read_from_the_vessel_file() -> None:
    az = {"id": 3, "kind": "azimuth", "x_m": 25, "y_m": 0, "max_thrust_n": 2e5, "azimuth_rate_rad_s": 0.2}
    v = vessel_from_dict({**GOOD, "thrusters": [{**az, "forbidden_sectors_deg": [[150, -150], [60, 80]]}]})
    assert v.thrusters[0].forbidden_sectors_deg == ((150.0, -150.0), (60.0, 80.0))
    for bad, reason in (
        ([[150]], "pairs"),
        ([[150, "x"]], "finite"),
        ([[10, 10]], "empty"),
        (5, "pairs"),
    ):
        with pytest.raises(VesselError) as err:
            vessel_from_dict({**GOOD, "thrusters": [{**az, "forbidden_sectors_deg": bad}]}, "ship.toml")
        assert "thrusters[0].forbidden_sectors_deg" in str(err.value) and reason in str(err.value), err.value
    tunnel = {"id": 4, "kind": "tunnel", "x_m": 30, "y_m": 0, "max_thrust_n": 1e5, "min_thrust_n": -1e5}
    with pytest.raises(VesselError, match="only an azimuth"):
        vessel_from_dict({**GOOD, "thrusters": [{**tunnel, "forbidden_sectors_deg": [[0, 10]]}]}, "ship.toml")


# --- a misspelt key is refused, never ignored ------------------------------------------------------------

VESSELS = Path(__file__).resolve().parents[1] / "observers" / "vessels"


def _copy_with(tmp_path: Path, builtin: str, old: str, new: str) -> Path:
    """A user's copy of a built-in vessel file with one line's text changed (the first occurrence)."""
    text = (VESSELS / f"{builtin}.toml").read_text(encoding="utf-8")
    assert old in text, old
    f = tmp_path / f"my_{builtin}.toml"
    f.write_text(text.replace(old, new, 1), encoding="utf-8")
    return f


def _refusal(f: Path) -> str:
    with pytest.raises(VesselError) as err:
        load_vessel(f)
    msg = str(err.value)
    assert "\n" not in msg and str(f) in msg, msg
    return msg


@pytest.mark.parametrize(
    ("builtin", "old", "new", "said"),
    [
        # before, each loaded: model_scal gave a full-scale CyberShip II to `dpgw capability`
        (
            "cybership2",
            "model_scale =",
            "model_scal =",
            "field 'model_scal': unknown key, did you mean 'model_scale'?",
        ),
        ("cybership2", "source =", "sorce =", "field 'sorce': unknown key, did you mean 'source'?"),
        (
            "cybership2",
            "description =",
            "descripton =",
            "field 'descripton': unknown key, did you mean 'description'?",
        ),
        ("mss_supply", "[bis]\ng", "[bis]\ngg = 9.81\ng", "field 'bis.gg': unknown key, did you mean 'g'?"),
        # before: "field 'length_m': missing or not a number", not a word about the key written
        (
            "cybership2",
            "length_m =",
            "lenght_m =",
            "field 'length_m': missing: 'lenght_m' is there, a misspelling of it?",
        ),
        # before: "field 'bis.Mbis': must be a 3×3 matrix, got shape ()"
        (
            "mss_supply",
            "Mbis =",
            "Mbiss =",
            "field 'bis.Mbis': missing: 'Mbiss' is there, a misspelling of it?",
        ),
        ("mss_supply", "Mbis =", "inertia =", "field 'bis.inertia': unknown key (known: g, Mbis, Dbis)"),
        (
            "mss_supply",
            "[bis]\ng",
            "[bis]\nM_RB = 1\ng",
            "field 'bis.M_RB': M_RB is a top-level key: move it above the [bis] header",
        ),
        (
            "cybership2",
            "max_thrust_n =",
            "max_thrust =",
            "field 'thrusters[0].max_thrust_n': missing: 'max_thrust' is there, a misspelling of it?",
        ),
        (
            "cybership2",
            "thrust_time_constant_s =",
            "thrust_time_constant =",
            "field 'thrusters[0].thrust_time_constant': unknown key, did you mean 'thrust_time_constant_s'?",
        ),
        (
            "mss_osv",
            "beam_m =",
            "beam =",
            "field 'hull.beam_m': missing: 'beam' is there, a misspelling of it?",
        ),
        ("mss_osv", "notes =", "note =", "field 'hull.note': unknown key, did you mean 'notes'?"),
        ("mss_osv", "cx =", "c_x =", "field 'hull.wind.c_x': unknown key, did you mean 'cx'?"),
    ],
)
def test_a_misspelt_key_is_refused_with_did_you_mean(
    tmp_path: Path, builtin: str, old: str, new: str, said: str
) -> None:
    msg = _refusal(_copy_with(tmp_path, builtin, old, new))
    assert said in msg, msg


def test_a_bis_table_without_its_matrices_says_missing(tmp_path: Path) -> None:
    """Before: "must be a 3×3 matrix, got shape ()" for a key that is not there."""
    text = (VESSELS / "mss_supply.toml").read_text(encoding="utf-8")
    start = text.index("Dbis =")
    end = text.index("]]", start) + 2
    f = tmp_path / "ship.toml"
    f.write_text(text[:start] + text[end:], encoding="utf-8")
    assert "field 'bis.Dbis': missing (the bis system needs Mbis and Dbis)" in _refusal(f)


def test_every_built_in_vessel_uses_only_known_keys() -> None:
    """Each built-in file loads as a user's copy would: every key it has is one the loader reads."""
    for name in builtin_vessels():
        v = load_vessel(VESSELS / f"{name}.toml")
        assert v == load_vessel(name), name


def test_capability_on_a_misspelt_vessel_file_stops_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dpgw.cli import main

    f = _copy_with(tmp_path, "cybership2", "model_scale =", "model_scal =")
    assert main(["capability", "--vessel", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "did you mean 'model_scale'?" in err and str(f) in err, err
