"""`dpgw radiation --plots` and the data it needs in a fresh clone: the fit's figures (A, B and K(t), data
against the model, one PNG per identified element) on the data shipped in the package (the built-in name
``mss_supply``), `bench/radiation_fit.py` drawing the same figures from the same data, and the warning when
the data's hull is not the vessel the model is stored for."""

from __future__ import annotations

import importlib.util
import json
import shutil
import struct
from pathlib import Path
from types import ModuleType

import pytest

from dpgw.cli import main

REPO = Path(__file__).resolve().parents[1]
VESSELS = REPO / "observers" / "vessels"
ELEMENT_FIGURES = ["radiation_11.png", "radiation_22.png", "radiation_66.png", "radiation_26.png"]
"""What the supply vessel's data identify: surge, sway, yaw and the sway-yaw coupling (docs/radiation.md)."""
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_size(path: Path) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk (after the signature, the chunk's length and type)."""
    head = path.read_bytes()[:24]
    assert head[:8] == PNG_SIGNATURE and head[12:16] == b"IHDR", path
    return struct.unpack(">II", head[16:24])


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("radiation_fit", REPO / "bench" / "radiation_fit.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_plots_of_the_shipped_data_one_png_per_element_and_listed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before, `dpgw radiation` had no --plots (argparse refused it) and no --json, and the shipped data had
    no name: a fresh clone could not draw the fit. Now `dpgw radiation mss_supply --plots DIR` writes one
    figure per identified element (three panels at 12 × 3.8 in, 110 dpi) and lists them; the model goes to
    the current folder, not into the package."""
    monkeypatch.chdir(tmp_path)
    assert main(["radiation", "mss_supply", "--plots", "fit", "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["plots"] == [str(Path("fit") / name) for name in ELEMENT_FIGURES]
    assert [e["element"] for e in summary["elements"]] == ["(1,1)", "(2,2)", "(6,6)", "(2,6)"]
    assert summary["model"] == ["mss_supply_radiation.npz", "mss_supply_radiation.toml"]
    assert summary["warnings"] == [] and captured.err == ""
    assert Path(summary["hydro"]).resolve() == (REPO / "simulator" / "data" / "supply_hydro.npz").resolve()
    assert sorted(p.name for p in (tmp_path / "fit").iterdir()) == sorted(ELEMENT_FIGURES)
    for name in ELEMENT_FIGURES:
        png = tmp_path / "fit" / name
        assert png.stat().st_size > 20_000, name  # three panels of lines and points, not an empty canvas
        assert _png_size(png) == (1320, 418), name
    for stem in summary["model"]:
        assert (tmp_path / stem).stat().st_size > 0
    # without --json: the same files, said on the console
    assert main(["radiation", "mss_supply", "--plots", "again", "--out", "again_model"]) == 0
    out = capsys.readouterr().out
    assert "wrote again_model.npz and again_model.toml" in out
    assert "wrote " + ", ".join(str(Path("again") / n) for n in ELEMENT_FIGURES) in out


def test_without_matplotlib_the_model_is_still_written_and_the_reason_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import gateway.report.plots
    from gateway.report.writer import NO_MATPLOTLIB

    monkeypatch.setattr(gateway.report.plots, "load_figure", lambda: None)
    stem = tmp_path / "model"
    assert (
        main(["radiation", "mss_supply", "--out", str(stem), "--plots", str(tmp_path / "fit"), "--json"]) == 0
    )
    captured = capsys.readouterr()
    assert captured.err == f"dpgw radiation: --plots: {NO_MATPLOTLIB}\n"
    summary = json.loads(captured.out)
    assert summary["plots"] == [] and summary["warnings"] == [f"--plots: {NO_MATPLOTLIB}"]
    assert stem.with_suffix(".npz").is_file() and not (tmp_path / "fit").exists()


def test_plots_into_a_file_is_refused_before_the_fit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    hydro = tmp_path / "hydro.npz"
    hydro.write_bytes(b"not read: the check comes first")
    (tmp_path / "afile").write_text("")
    assert main(["radiation", str(hydro), "--plots", str(tmp_path / "afile")]) == 2
    assert capsys.readouterr().err == (
        f"dpgw radiation: --plots {tmp_path / 'afile'}: a file, not a folder: give a folder (it is created)\n"
    )


def test_a_missing_hydro_file_names_the_built_in_data(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["radiation", str(tmp_path / "missing.npz")]) == 2
    err = capsys.readouterr().err
    assert "missing.npz: no such file" in err and "mss_supply" in err


def test_the_bench_reads_the_shipped_data_and_draws_the_same_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before, its default data were a path beside the checkout (``../shared/...``): in a fresh clone it
    stopped with "no such file (pass --hydro)". Now the package's file, and the figures of the command's
    module, with MSS's model added."""
    bench = _bench()
    assert bench.DEFAULT_HYDRO.is_file()
    assert bench.DEFAULT_HYDRO.resolve().is_relative_to(REPO)
    monkeypatch.setattr("sys.argv", ["radiation_fit.py", "--plots", str(tmp_path / "bench")])
    bench.main()
    out = capsys.readouterr().out
    assert "states of the 3×3 model: dpgw 17, MSS 19" in out
    assert sorted(p.name for p in (tmp_path / "bench").iterdir()) == sorted(ELEMENT_FIGURES)
    for name in ELEMENT_FIGURES:
        assert f"wrote {tmp_path / 'bench' / name}" in out
        assert _png_size(tmp_path / "bench" / name) == (1320, 418)


def _vessel_copy(name: str, folder: Path) -> Path:
    """A built-in vessel's file copied into ``folder``: `--vessel FILE` stores the model beside it there,
    not in the package."""
    path = folder / f"{name}.toml"
    shutil.copyfile(VESSELS / f"{name}.toml", path)
    return path


def test_a_model_stored_for_a_vessel_of_another_hull_is_warned_of(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, the 82.8 m, 6362 t ship's model was stored beside the 23.8 kg CyberShip II without a word."""
    vessel = _vessel_copy("cybership2", tmp_path)
    assert main(["radiation", "mss_supply", "--vessel", str(vessel), "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith(
        "dpgw radiation: warning: the data are of another hull than vessel 'cybership2': supply_hydro.npz "
        "gives M_RB 6.362e+06 kg, cybership2 has 23.8 kg (ratio 3.74e-06, outside 0.5-2)"
    )
    assert "Froude scaling" in captured.err and "λ = (m_vessel/m_data)^⅓ = 0.01552" in captured.err
    assert captured.err.count("\n") == 1  # one line
    assert json.loads(captured.out)["warnings"] == [
        captured.err.removeprefix("dpgw radiation: warning: ")[:-1]
    ]
    assert (tmp_path / "cybership2_radiation.npz").is_file()  # stored all the same: a warning, not a refusal


def test_no_warning_for_the_vessel_the_data_belong_to(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """mss_supply (MSS supply.m, 6000 t) and the ShipX data (6362 t): one hull class, ratio 0.94."""
    vessel = _vessel_copy("mss_supply", tmp_path)
    assert main(["radiation", "mss_supply", "--vessel", str(vessel)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert f"wrote {tmp_path / 'mss_supply_radiation.npz'}" in captured.out


def test_the_hull_check_by_vessel_name_and_its_bounds() -> None:
    """The check alone, for built-in names (which store into the package, so not run end to end here)."""
    import numpy as np

    from dpgw.cli_radiation import _other_hull

    data = Path("supply_hydro.npz")
    mrb = np.diag([6.362e6, 6.362e6, 6.362e6, 1.0, 1.0, 2.9e9])
    assert _other_hull(data, mrb, "mss_supply") is None
    assert "vessel 'cybership2'" in (_other_hull(data, mrb, "cybership2") or "")
    assert _other_hull(data, None, "cybership2") is None  # data without M_RB: nothing to compare
    # the bounds: 6000 t within 0.5-2 of 3100 t and of 11900 t, not of 2900 t or 12100 t
    for m_data, warned in ((3.1e6, False), (11.9e6, False), (2.9e6, True), (12.1e6, True)):
        assert (_other_hull(data, np.diag([m_data] * 6), "mss_supply") is not None) is warned, m_data
