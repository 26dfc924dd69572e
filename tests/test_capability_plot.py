"""The DP capability plot: dpgw/capability.py and ``dpgw capability``.

The environment relation (the Pierson–Moskowitz sea of the wind), the loads' port/starboard symmetry
and the terms left out with a warning, the U_max search on known functions, U_max as the point where the
thrusters' scale k* crosses 1, the worst failure as the minimum, the command's table, JSON and plot, and,
once, the quasi-static limit against the closed loop: the gateway in the simulator holds station at
0.8 U_max and is blown off at 1.3 U_max.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from dpgw.capability import (
    BEAUFORT_TABLE,
    U_TOL_MPS,
    Environment,
    EnvironmentLoads,
    beaufort_sea,
    capability,
    default_current,
    limit_speed,
    pm_sea,
)
from dpgw.cli import main
from gateway.control.capability import CapabilityLP
from observers.vessel import load_vessel
from simulator.spectra import SeaState
from simulator.waves import G
from simulator.wind import norsok_mean


def test_pm_sea_is_the_fully_developed_pierson_moskowitz_spectrum() -> None:
    """The (Hs, Tp) of `pm_sea` through the simulator's PM spectrum give Pierson & Moskowitz's one-parameter
    spectrum S(ω) = α g²/ω⁵ exp(−0.74 (g/(U₁₉.₅ ω))⁴), α = 0.0081, to the rounding of 0.21 and 0.877."""
    for u10 in (8.0, 15.0, 25.0):
        hs, tp = pm_sea(u10)
        u195 = norsok_mean(u10, 19.5)
        w = np.linspace(0.2, 2.5, 200)
        ours = SeaState(hs_m=hs, tp_s=tp, kind="pm").spectrum(w)
        theirs = 0.0081 * G**2 / w**5 * np.exp(-0.74 * (G / (u195 * w)) ** 4)
        np.testing.assert_allclose(ours, theirs, rtol=0.02, atol=1e-3 * theirs.max())


def test_loads_mirror_port_and_starboard_and_point_the_right_way() -> None:
    loads = EnvironmentLoads(load_vessel("mss_supply"))
    for beta in (30.0, 90.0, 135.0):
        a = loads.components(20.0, math.radians(beta))
        b = loads.components(20.0, math.radians(-beta))
        for key in ("wind", "current", "waves"):
            np.testing.assert_allclose(
                b[key], a[key] * [1, -1, -1], rtol=1e-6, atol=1e-6 * np.abs(a[key]).max()
            )
    head = loads.components(20.0, 0.0)
    assert head["wind"][0] < 0 and head["current"][0] < 0 and head["waves"][0] < 0  # from ahead: astern
    beam = loads.components(20.0, math.radians(90.0))  # from starboard: pushed to port
    assert beam["wind"][1] < 0 and beam["current"][1] < 0 and beam["waves"][1] < 0
    # wind ∝ U² through the NORSOK profile; current independent of U
    w1, w2 = loads.components(10.0, 1.0)["wind"], loads.components(20.0, 1.0)["wind"]
    ratio = (norsok_mean(20.0, 10.0 if loads.area is None else loads.area.height_m)) ** 2 / (
        norsok_mean(10.0, 10.0 if loads.area is None else loads.area.height_m)
    ) ** 2
    np.testing.assert_allclose(w2, w1 * ratio, rtol=1e-9)
    np.testing.assert_allclose(loads.components(10.0, 1.0)["current"], loads.components(30.0, 1.0)["current"])


def test_missing_data_is_left_out_with_a_warning() -> None:
    bare = load_vessel("hajivand_vessel")  # M, D and thrusters only
    assert bare.hull is None
    loads = EnvironmentLoads(bare)
    text = " ".join(loads.warnings)
    assert "no [hull.wind]" in text and "linear damping D" in text and "Froude-scaled" in text
    model = EnvironmentLoads(load_vessel("cybership2"))
    assert any("1:70 model" in w for w in model.warnings)
    assert default_current(load_vessel("cybership2")) == pytest.approx(0.75 / math.sqrt(70.0))
    assert default_current(load_vessel("mss_supply")) == 0.75
    assert not np.any(loads.components(20.0, 1.0)["wind"])
    assert np.any(loads.components(20.0, 1.0)["current"])
    assert EnvironmentLoads(load_vessel("mss_supply")).warnings == []


def test_limit_speed_finds_the_crossing() -> None:
    assert limit_speed(lambda u: (20.0 / u) ** 2 if u else math.inf) == pytest.approx(20.0, abs=U_TOL_MPS)
    assert limit_speed(lambda u: 0.5) == 0.0  # not even U = 0
    assert limit_speed(lambda u: 2.0, u_limit=30.0) == 30.0
    # lost between 11 and 13 m/s and regained above: the first loss counts
    assert limit_speed(lambda u: 0.9 if 11.5 < u < 12.5 else 1.5) == pytest.approx(11.5, abs=U_TOL_MPS)


def test_limit_speed_tries_the_limit_itself_off_the_grid() -> None:
    # the Beaufort scale ends at 32.6 m/s, not a multiple of the 2 m/s scan: held to 32.45 and no further
    # is not "at least 32.6" (the scan used to stop at 32 and return the limit)
    got = limit_speed(lambda u: 1.0 if u <= 32.45 else 0.99, u_limit=32.6)
    assert got == pytest.approx(32.45, abs=U_TOL_MPS)
    assert got < 32.6
    assert limit_speed(lambda u: 1.2, u_limit=32.6) == 32.6


def test_u_max_is_where_the_thrusters_scale_crosses_one_and_worst_is_the_minimum() -> None:
    v = load_vessel("mss_supply")
    res = capability(v, directions_deg=[60.0, 90.0], failures="each")
    loads = EnvironmentLoads(v)
    for case in res.cases:
        lp = CapabilityLP(v.thrusters, failed=case.failed)
        for d, u in zip(res.directions_deg, case.u_max, strict=True):
            assert 0 < u < 40.0
            assert lp.scale(-loads.tau(u, math.radians(d))) >= 1.0
            assert lp.scale(-loads.tau(u + 2 * U_TOL_MPS, math.radians(d))) < 1.0
    assert res.worst is not None and res.worst_failed is not None
    for i in range(2):
        fails = [c.u_max[i] for c in res.cases[1:]]
        assert res.worst[i] == min(fails) <= res.intact.u_max[i]
        assert res.cases[1:][fails.index(min(fails))].failed == res.worst_failed[i]


def test_progress_is_told_after_each_direction_and_changes_nothing() -> None:
    """A fine --step-deg takes minutes: the command's progress bar is told after each direction, the
    directions counted up to all of them; the result is the same as without it."""
    v = load_vessel("mss_supply")
    told: list[tuple[int, int]] = []
    res = capability(
        v, step_deg=90.0, failures="none", progress=lambda done, total: told.append((done, total))
    )
    assert told == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert res == capability(v, step_deg=90.0, failures="none")


def test_the_command_prints_a_table_json_and_a_plot(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:  # type: ignore[no-untyped-def]
    png = tmp_path / "cap.png"
    args = ["capability", "--vessel", "mss_supply", "--step-deg", "90", "--failures", "worst"]
    assert main([*args, "--json", "--plot", str(png)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["directions_deg"] == [0.0, 90.0, 180.0, 270.0]
    assert doc["plot"] == str(png)  # a program reading the JSON learns where the plot went
    intact = doc["cases"][0]["u_max_mps"]
    worst = doc["worst_failure"]["u_max_mps"]
    assert intact[1] == pytest.approx(intact[3]) and all(w <= i for w, i in zip(worst, intact, strict=True))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "intact" in out and "worst failure" in out and " 90.0 " in out
    assert main(["capability", "--vessel", "no_such_ship"]) == 2
    assert "not a built-in vessel" in capsys.readouterr().err
    assert main(["capability", "--vessel", "mss_supply", "--failure-group", "1,9"]) == 2
    assert "--failure-group" in capsys.readouterr().err


def test_the_table_names_a_worst_failure_only_where_a_failure_lowers_the_limit(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """hajivand_vessel (no [hull]: the linear D's beam current load, 9 MN, beyond its three azimuths' 4 MN)
    holds nothing on the beam even intact: no failure makes that worse, and naming one (thruster 1)
    would send the reader to a thruster that is not the cause."""
    args = ["capability", "--vessel", "hajivand_vessel", "--step-deg", "90", "--failures", "worst"]
    assert main(args) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()[3:]}
    assert rows["90.0"][1:] == ["0.0", "0.0", "-"]  # intact 0, worst 0, no failure to blame
    assert rows["0.0"][1:] == ["40.0", "40.0", "-"]
    # and the JSON, which programs read, says the same: no failure ids there
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["worst_failure"]["failed"] == [[], [], [], []]
    assert main(["capability", "--vessel", "mss_supply", "--step-deg", "90", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["worst_failure"]["failed"] == [[], [3], [], [3]]  # (ahead and astern: ≥ 40 m/s whatever fails)


def test_a_laboratory_model_s_table_shows_the_search_s_end_as_it_is_said(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """CyberShip II (1:70): the search ends at 40/√70 = 4.78 m/s and the header says "4.78 = at least
    4.78"; the rows must print it so (not 4.8, which could be a limit of 4.75)."""
    assert main(["capability", "--vessel", "cybership2", "--step-deg", "90", "--failures", "none"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "4.78 = at least 4.78" in lines[1]
    rows = {line.split()[0]: line.split()[1] for line in lines[3:]}
    assert rows["0.0"] == "4.78" and rows["180.0"] == "4.78"  # (head and stern: current only, held)


def test_failure_groups_with_no_failures_analysed_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """--failures none would drop the groups given without a word: the user asked for them."""
    args = ["capability", "--vessel", "mss_supply", "--failures", "none", "--failure-group", "1,2"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--failure-group with --failures none" in err and "give --failures worst or each" in err


def test_a_plot_path_that_cannot_be_written_is_said_without_a_traceback(
    tmp_path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:  # type: ignore[no-untyped-def]
    args = ["capability", "--vessel", "mss_supply", "--step-deg", "180", "--failures", "none"]
    # a format the plot is not written in, or a folder: refused before the analysis
    assert main([*args, "--plot", str(tmp_path / "cap.txt")]) == 2
    assert "give a file name ending in .png, .svg, .pdf" in capsys.readouterr().err
    (tmp_path / "dir.png").mkdir()
    assert main([*args, "--plot", str(tmp_path / "dir.png")]) == 2
    assert "is a folder" in capsys.readouterr().err
    long = tmp_path / ("x" * 300 + ".png")  # (longer than the file system allows)
    assert main([*args, "--plot", str(long)]) == 2
    assert "not a usable path" in capsys.readouterr().err
    # a file that cannot be written when the plot is saved (as a non-root user in a read-only folder): the
    # figures are printed first, then what went wrong, without a traceback
    import dpgw.capability

    def refused(result: object, path: str) -> None:
        raise PermissionError(13, "Permission denied", path)

    monkeypatch.setattr(dpgw.capability, "plot", refused)
    assert main([*args, "--json", "--plot", str(tmp_path / "cap.png")]) == 1
    out, err = capsys.readouterr()
    assert json.loads(out)["cases"][0]["label"] == "intact"
    assert "plot" not in json.loads(out)
    assert "cannot write it (Permission denied)" in err


@pytest.mark.parametrize("factor", ["0", "-1", "nan", "100", "x"])
def test_a_wrong_dynamic_factor_gets_one_message(factor: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["capability", "--vessel", "mss_supply", "--dynamic-factor", factor])
    assert stop.value.code == 2
    assert f"must be a positive factor below 100, e.g. 1.25 (got {factor})" in capsys.readouterr().err


def test_a_failure_group_is_no_better_than_any_of_its_thrusters_alone() -> None:
    v = load_vessel("mss_supply")
    single = capability(v, directions_deg=[90.0], failures="each")
    group = capability(v, directions_deg=[90.0], failure_groups=[(1, 4), (3,)])
    # (thrusters 2, 5 and 6, in no group, are each still lost alone: their own failure is a single failure)
    assert [c.label for c in group.cases] == [
        "intact",
        "thrusters 1+4 failed",
        "thruster 3 failed",
        "thruster 2 failed",
        "thruster 5 failed",
        "thruster 6 failed",
    ]
    by_label = {c.label: c.u_max[0] for c in single.cases}
    assert group.cases[1].u_max[0] <= min(by_label["thruster 1 failed"], by_label["thruster 4 failed"])
    assert group.cases[2].u_max[0] == by_label["thruster 3 failed"]
    assert group.worst is not None and group.worst_failed is not None
    assert group.worst[0] == min(c.u_max[0] for c in group.cases[1:])
    assert group.cases[3].u_max[0] == by_label["thruster 2 failed"]


def test_quasi_static_limit_agrees_with_the_closed_loop() -> None:
    """mss_supply in the simulator (full plant, steady wind and current from the starboard beam, no waves,
    no bias) under the gateway's own DP controller and allocation: it holds station at 0.8 U_max and is
    blown off at 1.3 U_max. Loads by the same functions as the analysis (U the 10 m mean in both, brought
    to the areas' height by the same NORSOK profile). U_max here (~45 m/s, wind and current only) is
    beyond any real wind: the test is of the balance."""
    from dpgw.closed_loop import run_closed_loop
    from simulator.current import CurrentModel
    from simulator.environment import BiasModel
    from simulator.plant_params import PlantOptions
    from simulator.scenarios import mss_supply_storm
    from simulator.wind import WindModel

    v = load_vessel("mss_supply")
    assert v.hull is not None and v.hull.wind is not None
    beta, current = 90.0, 0.75
    env = Environment(current_mps=current, waves=False)
    u_max = capability(v, environment=env, directions_deg=[beta], failures="none", u_limit=80.0).intact.u_max[
        0
    ]
    assert 30.0 < u_max < 80.0
    base = mss_supply_storm()
    final: dict[float, tuple[float, float, float]] = {}
    for factor in (0.8, 1.3):
        u = factor * u_max
        scenario = replace(
            base,
            name="capability_check",
            eta0=(0.0, 0.0, 0.0),
            sea=((0.0, SeaState(hs_m=0.0, tp_s=10.0)),),
            bias=BiasModel(),
            plant_options=PlantOptions(),  # no fluid memory: steady loads, and faster
            current=CurrentModel(speed_mps=current, direction_deg=beta + 180.0),
            wind=WindModel(speed_mps=u, from_deg=beta, gust="none"),
        )
        run = run_closed_loop(
            scenario,
            600.0,
            seed=1,
            events=[(0.0, "setpoint", {"north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0})],
        )
        dist = np.hypot(run.eta_lf[:, 0], run.eta_lf[:, 1])
        late = run.t >= 450.0
        half = int(np.searchsorted(run.t, 300.0))
        final[factor] = (
            float(dist[late].max()),
            float(np.degrees(np.abs(run.eta_lf[late, 2])).max()),
            float(dist[-1] - dist[half]),
        )
    held, lost = final[0.8], final[1.3]
    assert held[0] < 1.0 and held[1] < 1.0, held  # at 0.8 U_max: on station, on heading
    assert lost[0] > 50.0 and lost[2] > 20.0, lost  # at 1.3 U_max: far off and still going


def test_the_command_takes_a_gateway_config_s_vessel_and_failure_groups(
    tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:  # type: ignore[no-untyped-def]
    """The switchboards the online consequence analysis tests ([consequence] failure_groups) are the
    failures the capability plot analyses, from the same file."""
    cfg = tmp_path / "dp.toml"
    cfg.write_text(
        '[vessel]\nname = "mss_supply"\n[[sources]]\nname = "gps"\nurl = "udp://127.0.0.1:10110"\n'
        'protocol = "nmea"\nroles = ["position", "heading"]\n'
        "[consequence]\nfailure_groups = [[1, 2], [3, 4, 5]]\n"
    )
    args = ["capability", "--config", str(cfg), "--step-deg", "90", "--failures", "each", "--json"]
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["vessel"] == "mss_supply"
    assert [c["failed"] for c in doc["cases"]] == [[], [1, 2], [3, 4, 5], [6]]  # (6, in neither, alone)
    # given on the command line, they win
    assert main([*args, "--failure-group", "1,2,3", "--failure-group", "4,5,6"]) == 0
    assert [c["failed"] for c in json.loads(capsys.readouterr().out)["cases"]] == [[], [1, 2, 3], [4, 5, 6]]
    bad = tmp_path / "bad.toml"
    bad.write_text(cfg.read_text().replace("[3, 4, 5]", "[3, 4, 9]"))
    assert main(["capability", "--config", str(bad)]) == 2
    assert "consequence.failure_groups[1]: no thruster 9 on this vessel" in capsys.readouterr().err


def test_the_beaufort_sea_is_the_tables_rows_and_linear_between_them() -> None:
    """DNV-ST-0111 Table 2-1 as the relation: at a row's wind speed exactly that row's Hs, Tp and current,
    in between linear in U, nothing growing with the wind going down; on a 1:λ model Froude-scaled."""
    for row in BEAUFORT_TABLE[1:]:
        assert beaufort_sea(row.wind_mps) == (row.hs_m, row.tp_s, row.current_mps)
    lo, hi = BEAUFORT_TABLE[6], BEAUFORT_TABLE[7]
    hs, tp, vc = beaufort_sea(0.5 * (lo.wind_mps + hi.wind_mps))
    assert hs == pytest.approx(0.5 * (lo.hs_m + hi.hs_m)) and tp == pytest.approx(0.5 * (lo.tp_s + hi.tp_s))
    assert vc == 0.75
    winds = np.linspace(0.0, 35.0, 200)
    seas = np.array([beaufort_sea(float(u)) for u in winds])
    assert np.all(np.diff(seas, axis=0) >= 0.0)
    assert beaufort_sea(0.0)[0] == 0.0 and beaufort_sea(40.0) == beaufort_sea(32.6)
    lam = 70.0
    hs_m, tp_m, vc_m = beaufort_sea(13.8 / math.sqrt(lam), lam)
    assert (hs_m, tp_m, vc_m) == pytest.approx((3.1 / lam, 8.5 / math.sqrt(lam), 0.75 / math.sqrt(lam)))


def test_the_dp_capability_number_is_the_last_beaufort_row_held_with_every_row_below() -> None:
    """Per direction and thruster condition, the number n is the standard's: k* ≥ 1 at Beaufort rows
    1…n of Table 2-1 (loads × the dynamic factor) and k* < 1 at row n + 1; the worst failure's number is
    the least over the failures; the dynamic factor multiplies the loads and can only lower the numbers."""
    v = load_vessel("mss_supply")
    env = Environment(sea="beaufort", dynamic_factor=1.25)
    res = capability(v, environment=env, directions_deg=[0.0, 60.0, 90.0, 150.0], failures="each")
    loads = EnvironmentLoads(v, env)
    checked = set()
    for case in res.cases:
        assert case.dp_number is not None
        lp = CapabilityLP(v.thrusters, failed=case.failed)
        for d, n in zip(res.directions_deg, case.dp_number, strict=True):
            scales = [lp.scale(-loads.tau(r.wind_mps, math.radians(d))) for r in BEAUFORT_TABLE[1:]]
            assert all(k >= 1.0 for k in scales[:n])
            if n < 11:
                assert scales[n] < 1.0
            checked.add(n)
    assert len(checked) >= 3  # beam, quartering and head seas give different numbers
    assert res.worst_dp_number == tuple(
        min(c.dp_number[i] for c in res.cases[1:] if c.dp_number) for i in range(4)
    )
    mean = EnvironmentLoads(v, Environment(sea="beaufort"))
    np.testing.assert_allclose(loads.tau(17.1, 1.2), 1.25 * mean.tau(17.1, 1.2), rtol=1e-12)
    plain = capability(
        v, environment=Environment(sea="beaufort"), directions_deg=[60.0, 90.0], failures="none"
    )
    factored = capability(v, environment=env, directions_deg=[60.0, 90.0], failures="none")
    assert plain.intact.dp_number is not None and factored.intact.dp_number is not None
    assert all(f <= p for f, p in zip(factored.intact.dp_number, plain.intact.dp_number, strict=True))
    assert factored.intact.dp_number != plain.intact.dp_number  # 1.25 on the loads costs a Beaufort step here


def test_the_command_gives_dp_capability_numbers_with_the_beaufort_sea(
    tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:  # type: ignore[no-untyped-def]
    png = tmp_path / "bf.png"
    args = ["capability", "--vessel", "mss_supply", "--step-deg", "90", "--sea", "beaufort"]
    assert main([*args, "--json", "--plot", str(png)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["environment"]["sea"] == "beaufort" and doc["environment"]["dynamic_factor"] == 1.25
    assert doc["environment"]["current_mps"] is None  # (the table's, per row)
    assert [r["wind_mps"] for r in doc["environment"]["beaufort_table"]][6] == 13.8
    numbers = doc["cases"][0]["dp_capability_number"]
    worst = doc["worst_failure"]["dp_capability_number"]
    assert len(numbers) == 4 and all(0 <= w <= n <= 11 for w, n in zip(worst, numbers, strict=True))
    assert numbers[1] == numbers[3] and numbers[1] < numbers[0]  # the beams alike, below head seas
    assert doc["u_limit_mps"] == 32.6
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(args) == 0
    assert "(BF " in capsys.readouterr().out
    assert main([*args, "--current-mps", "1.0"]) == 2
    assert "--sea pm for a fixed current" in capsys.readouterr().err


def test_a_vessel_without_wind_areas_is_said_to_have_no_wind_load_in_the_table_and_json(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Before: for hajivand_vessel (no [hull.wind]) the header read "U_max (m/s, 1-hour mean wind at 10 m);
    wind U, ..." and the JSON had environment.wind true, while "no wind load" was only a note on stderr."""
    args = ["capability", "--vessel", "hajivand_vessel", "--step-deg", "90", "--failures", "none"]
    assert main(args) == 0
    captured = capsys.readouterr()
    header = captured.out.splitlines()[0]
    assert header == (
        "DP capability of hajivand_vessel: U_max (m/s, 1-hour mean wind at 10 m, which sets the sea); "
        "no wind load, fully developed PM sea Hs = 0.21 U19.5²/g, current 0.75 m/s, co-linear"
    )
    assert "wind U" not in captured.out and "no [hull.wind] areas: no wind load" in captured.err
    assert main([*args, "--json"]) == 0
    env = json.loads(capsys.readouterr().out)["environment"]
    assert env["wind"] is False and env["relation"].startswith("no wind load, ")
    # a vessel with the areas: the wind load is computed and said
    assert (
        main(["capability", "--vessel", "mss_supply", "--step-deg", "90", "--failures", "none", "--json"])
        == 0
    )
    env = json.loads(capsys.readouterr().out)["environment"]
    assert env["wind"] is True and env["relation"].startswith("wind U, ")


def test_a_step_that_does_not_divide_360_is_said_and_a_negative_one_is_out_of_range(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`--step-deg 70` ran at 72° steps without a word; `--step-deg -10` said "must be >= 0" while 0 said
    "must be above 0". The rounding is a note (text and JSON), and every step out of range one message."""
    import json

    assert (
        main(["capability", "--vessel", "mss_supply", "--step-deg", "70", "--failures", "none", "--json"])
        == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["directions_deg"]) == 5 and doc["directions_deg"][1] == pytest.approx(72.0)
    assert "a step of 70° does not divide 360°: 5 directions 72° apart" in doc["warnings"]
    assert (
        main(["capability", "--vessel", "mss_supply", "--step-deg", "90", "--failures", "none", "--json"])
        == 0
    )
    assert not any("divide" in w for w in json.loads(capsys.readouterr().out)["warnings"])
    for bad in ("-10", "0", "200"):
        with pytest.raises(SystemExit):
            main(["capability", "--vessel", "mss_supply", "--step-deg", bad])
        assert "must be above 0 and at most 180 degrees" in capsys.readouterr().err
