"""The replay report (gateway/report/): metrics on synthetic data with known answers, and the files."""

from __future__ import annotations

import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gateway.report import (
    ObserverTrace,
    ReplayData,
    compute_metrics,
    decimate,
    wave_band_for_length,
    write_report,
)
from gateway.report.data import utc_text

W_WAVE = 0.6  # rad/s
DOFS = ("north", "east", "heading")
PNGS = ("position", "wave", "velocity", "bias", "omega0", "psd")


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def lf_motion(t: np.ndarray) -> np.ndarray:
    """Slow motion: metres in N/E, heading close to 180° so that it wraps."""
    return np.column_stack(
        [
            3.0 * np.sin(0.01 * t) + 0.5 * np.sin(0.031 * t + 1.0),
            -2.0 * np.cos(0.013 * t),
            np.radians(179.0) + 0.02 * np.sin(0.02 * t),
        ]
    )


def wf_motion(t: np.ndarray) -> np.ndarray:
    return np.column_stack(
        [1.0 * np.sin(W_WAVE * t), 0.7 * np.sin(W_WAVE * t + 0.5), 0.01 * np.sin(W_WAVE * t + 1.0)]
    )


def trace(label: str, t: np.ndarray, wf_left: float, omega0: float = 0.8976) -> ObserverTrace:
    """An "observer" whose LF estimate is the LF motion plus `wf_left` of the wave motion."""
    eta = lf_motion(t) + wf_left * wf_motion(t)
    eta[:, 2] = wrap(eta[:, 2])
    n = len(t)
    return ObserverTrace(
        label=label,
        t=t,
        eta=eta,
        nu=np.column_stack([0.1 * np.cos(0.01 * t), np.zeros(n), np.zeros(n)]),
        bias=np.tile([2.0e4, -1.0e4, 3.0e5], (n, 1)),
        eta_wf=(1.0 - wf_left) * wf_motion(t),
        omega0=np.full((n, 3), omega0),
    )


def measurement(t: np.ndarray, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = lf_motion(t) + wf_motion(t) + rng.normal(0.0, [0.02, 0.02, 0.0005], (len(t), 3))
    y[:, 2] = wrap(y[:, 2])
    return y


@pytest.fixture(scope="module")
def data() -> ReplayData:
    t_meas = np.arange(0.0, 1800.0, 1.0)  # 1 Hz fixes, 30 min
    t_est = np.arange(0.0, 1800.0, 0.2)  # 5 Hz estimates
    return ReplayData(
        title="synthetic.mcap",
        vessel="mss_supply",
        t_meas=t_meas,
        y=measurement(t_meas),
        traces=(trace("passive", t_est, 0.05), trace("passive_T9", t_est, 0.5, omega0=0.7)),
        truth_t=t_est,
        truth_eta_lf=lf_motion(t_est),
        truth_eta_wf=wf_motion(t_est),
        counts={
            "dgps": {"received": 1800, "checksum": 3, "garbage": 1},
            "trial.mcap": {
                "truncated": 1,
                "time_gap": 2,
                "time_backwards": 0,
                "repeated_time": 4,
                "duplicate": 5,
            },
        },
    )


@pytest.fixture(scope="module")
def metrics(data: ReplayData) -> dict[str, Any]:
    return compute_metrics(data)


# ---------------------------------------------------------------------------------------- attenuation
def test_dominant_wave_frequency_is_found(metrics: dict[str, Any]) -> None:
    for dof in DOFS:
        w = metrics["measurement"][dof]["dominant_frequency_rad_s"]
        assert w == pytest.approx(W_WAVE, rel=0.05), dof
        assert metrics["measurement"][dof]["peak_at_band_edge"] is False
        assert metrics["measurement"][dof]["dominant_period_s"] == pytest.approx(2 * math.pi / w)


def test_attenuation_at_the_wave_peak(metrics: dict[str, Any]) -> None:
    for dof in DOFS:  # heading included: it wraps at ±180° in both y and the estimate
        assert metrics["observers"]["passive"][dof]["attenuation_db"] == pytest.approx(
            20 * math.log10(0.05), abs=1
        )
        assert metrics["observers"]["passive_T9"][dof]["attenuation_db"] == pytest.approx(
            20 * math.log10(0.5), abs=1
        )


def test_nan_gaps_in_the_measurement(data: ReplayData) -> None:
    y = data.y.copy()
    y[100:102] = np.nan  # short dropouts: interpolated
    y[400:403, :2] = np.nan
    y[700:1000, 0] = np.nan  # a long one in north: the record is split
    y[1500:, 1] = np.nan
    y[::37, 2] = np.nan
    gappy = ReplayData(data.title, data.vessel, data.t_meas, y, data.traces)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = compute_metrics(gappy)
    assert m["measurement"]["north"]["valid"] == len(y) - 2 - 3 - 300
    for dof in DOFS:
        assert m["measurement"][dof]["dominant_frequency_rad_s"] == pytest.approx(W_WAVE, rel=0.05)
        obs = m["observers"]["passive"][dof]
        assert obs["attenuation_db"] == pytest.approx(-26.0, abs=1.5)
        assert math.isfinite(obs["innovation"]["std"]) and math.isfinite(obs["smoothness"]["ratio"])


def test_a_dof_without_any_measurement_gives_nulls(data: ReplayData) -> None:
    y = data.y.copy()
    y[:, 1] = np.nan
    m = compute_metrics(ReplayData(data.title, data.vessel, data.t_meas, y, data.traces))
    assert m["measurement"]["east"]["dominant_frequency_rad_s"] is None
    assert m["observers"]["passive"]["east"]["attenuation_db"] is None
    assert m["observers"]["passive"]["east"]["innovation"]["samples"] == 0
    assert m["observers"]["passive"]["north"]["attenuation_db"] == pytest.approx(-26.0, abs=1)


def test_wave_band_follows_the_vessel() -> None:
    assert wave_band_for_length(76.2) == (0.2, 2.0)
    assert wave_band_for_length(None) == (0.2, 2.0)
    lo, hi = wave_band_for_length(1.255)  # CyberShip II, Froude-scaled from 80 m
    assert lo == pytest.approx(0.2 * math.sqrt(80 / 1.255)) and hi == pytest.approx(10 * lo)
    t = np.arange(0.0, 300.0, 0.05)
    w = 7.0  # a model-basin wave
    y = np.column_stack([0.05 * np.sin(w * t), 0.03 * np.sin(w * t), 0.01 * np.sin(w * t)])
    m = compute_metrics(ReplayData("basin", "cybership2", t, y, ()))
    # CyberShip II's file says 1:70 (model_scale): the band × √70, the observers' rule (observers.froude)
    assert m["wave_band_rad_s"] == pytest.approx([0.2 * math.sqrt(70), 2.0 * math.sqrt(70)])
    assert m["measurement"]["north"]["dominant_frequency_rad_s"] == pytest.approx(w, rel=0.05)
    given = compute_metrics(ReplayData("basin", "cybership2", t, y, ()), wave_band=(0.5, 3.0))
    assert given["wave_band_rad_s"] == [0.5, 3.0] and given["wave_band_basis"] == "given"


# ------------------------------------------------------------------------------------ innovations
def _known_residual_data() -> tuple[ReplayData, np.ndarray]:
    t = np.arange(0.0, 200.0, 1.0)
    n = len(t)
    eta = np.column_stack([np.full(n, 5.0), np.full(n, -3.0), np.full(n, np.radians(179.95))])
    eta_wf = np.column_stack([0.2 * np.sin(0.6 * t), np.zeros(n), np.zeros(n)])
    alt = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    r = np.column_stack([0.3 + 0.1 * alt, 0.2 * alt, np.radians(0.1) * np.ones(n)])
    y = eta + eta_wf + r
    y[:, 2] = wrap(y[:, 2])  # 180.05° is stored as -179.95°
    z = np.zeros((n, 3))
    tr = ObserverTrace("p", t, eta, z, z, eta_wf, np.full((n, 3), 0.9))
    return ReplayData("known", "", t, y, (tr,)), r


def test_innovation_statistics_of_a_known_residual() -> None:
    d, _ = _known_residual_data()
    o = compute_metrics(d, settle_s=0.0)["observers"]["p"]
    n = o["north"]["innovation"]
    assert n["samples"] == 200
    assert n["mean"] == pytest.approx(0.3)
    assert n["std"] == pytest.approx(0.1)
    assert n["rms"] == pytest.approx(math.sqrt(0.3**2 + 0.1**2))
    assert n["lag1_autocorrelation"] == pytest.approx(-1.0)
    e = o["east"]["innovation"]
    assert e["mean"] == pytest.approx(0.0, abs=1e-12) and e["rms"] == pytest.approx(0.2)
    h = o["heading"]["innovation"]  # across ±180°: 0.1°, not 0.1° - 360°
    assert h["mean"] == pytest.approx(np.radians(0.1)) and h["std"] == pytest.approx(0.0, abs=1e-9)
    assert h["lag1_autocorrelation"] is None  # a constant residual has no autocorrelation


def test_innovation_whiteness_hint_of_white_noise() -> None:
    d, _ = _known_residual_data()
    rng = np.random.default_rng(3)
    y = d.y.copy()
    y[:, 0] = d.traces[0].eta[:, 0] + d.traces[0].eta_wf[:, 0] + rng.normal(0, 0.1, len(y))
    o = compute_metrics(ReplayData("w", "", d.t_meas, y, d.traces), settle_s=0.0)["observers"]["p"]
    assert abs(o["north"]["innovation"]["lag1_autocorrelation"]) < 0.2


def test_settle_time_default_and_override() -> None:
    d, _ = _known_residual_data()  # 199 s: 10 % is 19.9 s
    m = compute_metrics(d)
    assert m["settle_s"] == pytest.approx(19.9)
    assert m["observers"]["p"]["north"]["innovation"]["samples"] == 180  # t = 20 … 199 s
    assert compute_metrics(d, settle_s=50.0)["observers"]["p"]["north"]["innovation"]["samples"] == 150
    t = np.arange(0.0, 3600.0, 10.0)
    long = ReplayData("l", "", t, np.zeros((len(t), 3)), ())
    assert compute_metrics(long)["settle_s"] == 60.0


def test_smoothness_compares_first_differences(metrics: dict[str, Any]) -> None:
    s = metrics["observers"]["passive"]["north"]["smoothness"]
    assert s["std_diff_estimate"] < s["std_diff_measurement"]
    assert s["ratio"] == pytest.approx(s["std_diff_estimate"] / s["std_diff_measurement"])
    # the LF part barely changes in 1 s; what is left is 5 % of the wave's difference
    assert s["ratio"] < 0.1
    assert metrics["observers"]["passive_T9"]["north"]["smoothness"]["ratio"] == pytest.approx(0.5, abs=0.05)


# ------------------------------------------------------------------------------------------ truth
def test_rms_error_against_truth_with_heading_wrap() -> None:
    t = np.arange(0.0, 100.0, 0.5)
    n = len(t)
    truth = np.column_stack([np.sin(0.05 * t), np.cos(0.05 * t), np.full(n, np.radians(-179.9))])
    eta = truth.copy()
    eta[:, 0] += 0.5
    eta[:, 1] += np.where(np.arange(n) % 2 == 0, 0.2, -0.2)
    eta[:, 2] = np.radians(179.9)  # 0.2° from the truth, across ±180°
    eta[t < 10.0, 0] += 100.0  # a start-up transient, inside the settle time
    z = np.zeros((n, 3))
    tr = ObserverTrace("p", t, eta, z, z, z, np.full((n, 3), 0.9))
    d = ReplayData("truth", "", t, truth, (tr,), truth_t=t, truth_eta_lf=truth, truth_eta_wf=np.zeros((n, 3)))
    m = compute_metrics(d, settle_s=10.0)
    assert m["truth"] is True
    o = m["observers"]["p"]
    assert o["north"]["truth_samples"] == n - 20
    assert o["north"]["rms_error"] == pytest.approx(0.5)
    assert o["north"]["mean_square_error"] == pytest.approx(0.25)
    assert o["east"]["rms_error"] == pytest.approx(0.2)
    assert o["east"]["mean_square_error"] == pytest.approx(0.04)
    assert o["heading"]["rms_error"] == pytest.approx(np.radians(0.2))
    assert o["heading"]["rms_error_wf"] == pytest.approx(0.0)
    assert compute_metrics(d, settle_s=0.0)["observers"]["p"]["north"]["rms_error"] > 10.0


def test_no_truth_gives_null_errors(data: ReplayData) -> None:
    m = compute_metrics(ReplayData(data.title, data.vessel, data.t_meas, data.y, data.traces))
    assert m["truth"] is False
    assert m["observers"]["passive"]["north"]["rms_error"] is None


def test_counts_are_copied(metrics: dict[str, Any], data: ReplayData) -> None:
    assert metrics["counts"] == {k: dict(v) for k, v in data.counts.items()}


# ------------------------------------------------------------------------------------------ files
def _strict_json(text: str) -> Any:
    def no_nan(name: str) -> None:
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=no_nan)


@pytest.fixture(scope="module")
def report_dir(data: ReplayData, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    folder = tmp_path_factory.mktemp("report") / "new" / "folder"
    return folder, write_report(data, folder)


@pytest.mark.slow  # matplotlib draws every figure, ~3 s
def test_write_report_writes_pngs_metrics_and_table(
    report_dir: tuple[Path, list[Path]], metrics: dict[str, Any]
) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.image

    folder, files = report_dir
    assert [f.name for f in files] == ["metrics.json", "report.md", *(f"{p}.png" for p in PNGS)]
    for name in PNGS:
        path = folder / f"{name}.png"
        raw = path.read_bytes()
        assert raw[:8] == b"\x89PNG\r\n\x1a\n" and len(raw) > 20_000, name
        img = matplotlib.image.imread(path)
        assert img.shape[0] > 300 and img.shape[1] > 1000
        assert float(np.std(img[..., :3])) > 0.01  # not a blank canvas
    stored = _strict_json((folder / "metrics.json").read_text())
    assert stored["observers"]["passive"]["north"]["attenuation_db"] == pytest.approx(
        metrics["observers"]["passive"]["north"]["attenuation_db"]
    )
    assert stored["counts"]["dgps"]["checksum"] == 3
    md = (folder / "report.md").read_text()
    assert "## Observer `passive`" in md and "## Observer `passive_T9`" in md
    assert "| N (m) | 0.898 | -26 |" in md
    assert "| dgps | checksum | 3 |" in md and "| trial.mcap | repeated_time | 4 |" in md
    for name in PNGS:
        assert f"]({name}.png)" in md


def test_write_report_without_plots(data: ReplayData, tmp_path: Path) -> None:
    files = write_report(data, tmp_path, plots=False)
    assert [f.name for f in files] == ["metrics.json", "report.md"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.json", "report.md"]
    assert "not requested" in (tmp_path / "report.md").read_text()
    _strict_json((tmp_path / "metrics.json").read_text())


def test_write_report_without_matplotlib(
    data: ReplayData, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for mod in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    files = write_report(data, tmp_path)
    assert [f.name for f in files] == ["metrics.json", "report.md"]
    assert "pip install matplotlib" in (tmp_path / "report.md").read_text()


def test_metrics_json_has_no_nan(tmp_path: Path) -> None:
    t = np.arange(0.0, 30.0, 1.0)  # too short for any spectrum
    y = np.full((len(t), 3), np.nan)
    d = ReplayData("short", "", t, y, (trace("p", t, 0.05),))
    write_report(d, tmp_path, plots=False)
    m = _strict_json((tmp_path / "metrics.json").read_text())
    assert m["observers"]["p"]["north"]["attenuation_db"] is None


# --------------------------------------------------------------------------------------- decimate
def test_decimate_keeps_the_envelope_and_the_gaps() -> None:
    t = np.arange(1_000_000) * 0.1
    x = np.sin(0.6 * t) + 0.001 * t
    x[300_000:400_000] = np.nan
    td, xd = decimate(t, x, 20_000)
    assert len(td) <= 20_000
    assert np.all(np.diff(td) >= 0)
    assert np.nanmax(xd) == pytest.approx(np.nanmax(x)) and np.nanmin(xd) == pytest.approx(np.nanmin(x))
    assert np.isnan(xd[(td > 30_500) & (td < 39_500)]).all()
    assert np.array_equal(decimate(t[:100], x[:100], 20_000)[0], t[:100])  # short lines untouched


def test_welch_psd_holds_the_variance_of_a_sinusoid_and_the_level_of_white_noise() -> None:
    """Parseval for the one-sided PSD per rad/s: ∫ S(ω) dω = variance; for white noise of variance σ²
    sampled every Δt the level is flat at σ²·Δt/π. Two stretches average with one weight per segment."""
    from gateway.report.spectra import welch

    dt, w = 0.5, 0.6
    t = np.arange(0.0, 4000.0, dt)
    x = 2.0 * np.sin(w * t)  # variance 2
    p = welch([x[:5000], x[5000:]], dt, seg_s=400.0, highpass=None)
    assert p is not None and p.segments >= 2 * 7
    dw = p.omega[1] - p.omega[0]
    assert float(np.sum(p.psd) * dw) == pytest.approx(2.0, rel=0.02)
    assert p.omega[np.argmax(p.psd)] == pytest.approx(w, abs=dw)
    noise = np.random.default_rng(0).normal(0.0, 0.3, 40_000)
    q = welch([noise], dt, seg_s=100.0, highpass=None)
    assert q is not None
    inner = q.psd[5:-5]  # away from DC (detrend) and Nyquist
    assert float(np.mean(inner)) == pytest.approx(0.3**2 * dt / math.pi, rel=0.03)


def test_zoom_row_only_when_it_shows_a_detail() -> None:
    """The zoom row: the last 20 dominant periods (at least 60 s), only on a record at least twice as long.
    Before, a 300 s simulator log with an 11.2 s sea got a 'zoom' on its last 225 s, three quarters of it."""
    from gateway.report.plots import zoom_window

    w = 2.0 * math.pi / 11.2
    assert zoom_window(0.0, 300.0, [w, w, float("nan")]) is None
    assert zoom_window(0.0, 900.0, [w, w, w]) == pytest.approx((900.0 - 224.0, 900.0))
    assert zoom_window(0.0, 340.8, [3.9, 4.0, 2.9]) == pytest.approx((280.8, 340.8))  # a model: 60 s least
    assert zoom_window(0.0, 100.0, []) is None and zoom_window(0.0, 120.0, []) == pytest.approx((60.0, 120.0))


def drawn_figures(d: ReplayData, an: Any, tmp_path: Path) -> dict[str, Any]:
    """The report's figures drawn for ``d`` (its `analyse` result ``an``), kept by name ("position", …)
    for a test to look into (skips without matplotlib)."""
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from gateway.report.plots import draw_plots

    made: list[Any] = []

    class Kept(Figure):  # type: ignore[misc]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)

    draw_plots(d, an, tmp_path, Kept)
    return {f.get_suptitle().rsplit(": ", 1)[1]: f for f in made}


def split_across_days(data: ReplayData, days: int) -> ReplayData:
    """``data`` as two logs merged: its second half (from 900 s) ``days`` days later; no truth."""
    from dataclasses import replace

    shift = days * 86400.0
    t_meas = np.where(data.t_meas >= 900.0, data.t_meas + shift, data.t_meas)
    traces = tuple(replace(tr_, t=np.where(tr_.t >= 900.0, tr_.t + shift, tr_.t)) for tr_ in data.traces)
    return replace(data, t_meas=t_meas, traces=traces, truth_t=None, truth_eta_lf=None, truth_eta_wf=None)


def test_plots_mark_only_a_clear_wave_peak(data: ReplayData, tmp_path: Path) -> None:
    """A DOF whose spectral maximum sits on the band edge has no wave peak (`peak_at_band_edge`): the omega0
    plot draws no 'PSD peak of y' line for it and the PSD panel says so. Before, a dashed 'peak' line sat
    at the band edge of a calm DOF (the USV log 202412051037: east and heading) beside the real one."""
    from dataclasses import replace

    from gateway.report.metrics import analyse

    calm = data.y.copy()  # east: no waves, a random walk (a spectrum falling through the band)
    calm[:, 1] = lf_motion(data.t_meas)[:, 1] + np.cumsum(
        np.random.default_rng(3).normal(0.0, 0.02, len(calm))
    )
    d = replace(data, y=calm)
    an = analyse(d, None, None)
    assert [an.metrics["measurement"][k]["peak_at_band_edge"] for k in DOFS] == [False, True, False]
    by_name = drawn_figures(d, an, tmp_path)
    peak_lines = [
        [ln for ln in ax.get_lines() if ln.get_label() == "PSD peak of y"] for ax in by_name["omega0"].axes
    ]
    assert [len(x) for x in peak_lines] == [1, 0, 1]
    assert "PSD peak of y" in [t.get_text() for t in by_name["omega0"].legends[0].get_texts()]
    notes = [" ".join(t.get_text() for t in ax.texts) for ax in by_name["psd"].axes]
    assert "peak ω = 0.6" in notes[0] and "no clear wave peak" in notes[1] and "peak ω" not in notes[1]


def test_a_measurement_at_a_fraction_of_the_stream_rate_is_drawn_as_a_line() -> None:
    """`dpgw replay --report` gives the report each measurement once (held copies NaN), so a 2 Hz fix in a
    10 Hz stream is NaN at four samples of five: drawn as it was, the north and east measurement lines
    vanished. Valid samples are joined; a real dropout (longer than the metrics bridge) still breaks."""
    from gateway.report.plots import measured_line

    t = np.arange(0.0, 100.0, 0.1)
    x = np.sin(0.5 * t)
    x[np.arange(len(t)) % 5 != 0] = np.nan  # 2 Hz in a 10 Hz stream
    x[(t > 40.0) & (t < 50.0)] = np.nan  # a 10 s dropout
    tl, xl = measured_line(t, x)
    breaks = np.flatnonzero(np.isnan(xl))
    assert len(breaks) == 1 and 40.0 < tl[breaks[0]] < 50.0  # one break, inside the dropout, at a time
    assert np.count_nonzero(np.isfinite(xl)) == np.count_nonzero(np.isfinite(x))
    assert np.all(np.diff(tl) > 0)


@pytest.mark.parametrize(
    ("t1", "text"),
    [
        (89.9043, "0.0 s to 89.9 s (89.9 s)"),
        (1800.0, "0.0 s to 1800.0 s (30.0 min)"),
        (176397.0, "0.0 s to 176397.0 s (49.0 h)"),
    ],
)
def test_report_span_reads_in_the_plots_units(t1: float, text: str) -> None:
    """Before: '0 s to 89.9043 s (89.9 s)', and a two-day merge of logs '(1.764e+05 s)'. The last record is
    sampled once an hour, more slowly than a Welch segment is long: compute_metrics raised (nperseg=0)
    where a metric it cannot compute is null."""
    from gateway.report.markdown import report_markdown

    t = np.linspace(0.0, t1, 50)
    d = ReplayData(title="x", vessel="mss_supply", t_meas=t, y=np.zeros((50, 3)), traces=())
    assert f"- span: {text} — from the first fused measurement" in report_markdown(
        d, compute_metrics(d), "", []
    )


@pytest.mark.parametrize("rising", [False, True], ids=["falling through the band", "rising through it"])
def test_a_maximum_on_the_band_edge_is_reported_inside_the_band(rising: bool) -> None:
    """LF motion leaves a spectrum falling through the wave band, so its maximum sits on the low edge.
    Before, the parabola through the edge bin and the bin outside moved it up to half a bin out of the
    band: the report of a USV log said 1.57 rad/s for a band it searched from 1.67."""
    from gateway.report.spectra import Psd, peak

    omega = np.arange(1, 100) * 0.2  # 0.2 rad/s bins, a model's coarse resolution
    # concave log-PSDs: the parabola through the edge bin leans out of the band
    psd = omega**4.0 if rising else np.exp(-0.5 * omega**2)
    band = (1.75, 16.65)  # edge bins 1.8 and 16.6: half a bin out is 1.7 and 16.7
    w, at_edge = peak(Psd(omega, psd, 1), band)
    assert at_edge
    assert band[0] <= w <= band[1]
    inside = omega[(omega >= band[0]) & (omega <= band[1])]
    assert w == pytest.approx(inside[-1] if rising else inside[0])


def test_estimate_lines_break_where_logs_merged_across_days_leave_a_gap(
    data: ReplayData, tmp_path: Path
) -> None:
    """Three USV logs of three days replayed as one: before, every estimate line (position, wave,
    velocity, bias, ω0) ran straight through the 31 h and 17 h between them, as if the vessel had moved
    along it; the measurement's line broke there. Now every line breaks where its samples stop."""

    from gateway.report.metrics import analyse

    d = split_across_days(data, 1)  # the second half a day later
    by_name = drawn_figures(d, analyse(d, None, None), tmp_path)
    for name in ("position", "wave", "velocity", "bias", "omega0"):
        ax = by_name[name].axes[0]  # the first DOF, the whole record
        lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 100]  # (not a reference line)
        assert lines, name
        for ln in lines:
            x = np.asarray(ln.get_xdata(), dtype=float)
            y = np.asarray(ln.get_ydata(), dtype=float)
            joined = np.isfinite(y[:-1]) & np.isfinite(y[1:]) & (np.diff(x) > 0.5 * (x[-1] - x[0]))
            assert not joined.any(), f"{name}: '{ln.get_label()}' drawn across the day between the logs"


def test_a_long_log_reads_by_utc_and_its_zoom_in_seconds(data: ReplayData, tmp_path: Path) -> None:
    """A merge of logs a day apart: the zoom row's axis counted hours from the first log's start, so a 224 s
    zoom read '48.9825 h' to '48.9847 h', and report.md gave only seconds since the start. Now the zoom row
    counts seconds from its own start, which its label gives in UTC, the whole-record rows say from when
    they count, and report.md and metrics.json give the span in UTC."""
    from dataclasses import replace
    from datetime import UTC, datetime

    from gateway.report.markdown import report_markdown
    from gateway.report.metrics import analyse

    day = 86400.0
    start_ns = 1_733_395_032 * 10**9  # 2024-12-05T10:37:12Z
    d = replace(split_across_days(data, 2), start_ns=start_ns)
    an = analyse(d, None, None)
    t0, t1 = an.metrics["span_s"]
    assert t0 == 0.0 and 2 * day < t1 < 2 * day + 1800.0
    assert an.metrics["span_utc"] == ["2024-12-05T10:37:12.0Z", utc_text(start_ns, t1)]
    end = utc_text(start_ns, t1)
    assert end is not None and end.startswith("2024-12-07T1")
    md = report_markdown(d, an.metrics, "", [])
    assert f"2024-12-05 10:37:12.0 to {end.replace('T', ' ').removesuffix('Z')} UTC" in md
    position = drawn_figures(d, an, tmp_path)["position"]
    whole, zoom = position.axes[0], position.axes[3]  # row 1 (the record), row 2 (its zoom)
    assert whole.get_xlabel() == "time (h) from 2024-12-05 10:37:12 UTC"
    length = float(zoom.get_title(loc="right").split()[2])  # "zoom: last 209 s"
    label = zoom.get_xlabel()
    assert label.startswith("time (s) from ") and label.endswith(" UTC"), label
    at = datetime.strptime(label[14:-4], "%Y-%m-%d %H:%M:%S").replace(tzinfo=UTC).timestamp()
    assert abs(at - (start_ns / 1e9 + t1 - length)) <= 1.0, label  # (the title's length is rounded)
    xs = np.concatenate([np.asarray(ln.get_xdata(), dtype=float) for ln in zoom.get_lines()])
    xs = xs[np.isfinite(xs)]
    assert xs.min() >= 0.0 and length - 1.0 <= xs.max() <= length + 1.0, (xs.min(), xs.max(), length)


def test_utc_text_rounds_the_instant_as_a_whole() -> None:
    start = 1_733_395_032 * 10**9  # 2024-12-05T10:37:12Z
    assert utc_text(start, 0.96) == "2024-12-05T10:37:13.0Z"  # not 10:37:12.10
    assert utc_text(start, 0.04) == "2024-12-05T10:37:12.0Z"
    assert utc_text(start, 59.5, digits=0) == "2024-12-05T10:38:12Z"
    assert utc_text(start, float("nan")) is None and utc_text(start, None) is None


def test_a_vessel_that_cannot_be_loaded_is_said_in_the_wave_band_basis(tmp_path: Path) -> None:
    """The report's wave band comes from the vessel's length and scale. A vessel file that cannot be loaded
    (here a misspelt key) fell back to full scale without a word, as if the vessel were merely unknown:
    the basis now says why, and a fault that is not the vessel's is not hidden."""
    t = np.arange(0.0, 300.0, 0.05)
    y = np.column_stack([0.05 * np.sin(0.6 * t)] * 3)
    broken = tmp_path / "boat.toml"
    text = (Path(__file__).resolve().parents[1] / "observers" / "vessels" / "cybership2.toml").read_text()
    broken.write_text(text.replace("length_m", "lenght_m", 1))
    m = compute_metrics(ReplayData("trial", str(broken), t, y, ()))
    assert m["wave_band_basis"].startswith("full scale (length unknown: "), m["wave_band_basis"]
    assert "lenght_m" in m["wave_band_basis"], m["wave_band_basis"]
    unknown = compute_metrics(ReplayData("trial", "no_such_boat", t, y, ()))
    assert "not a built-in vessel" in unknown["wave_band_basis"], unknown["wave_band_basis"]
    assert compute_metrics(ReplayData("trial", "", t, y, ()))["wave_band_basis"] == (
        "full scale (length unknown: no vessel named)"
    )


def test_a_gateway_logs_thrust_live_and_fed_raw_is_plotted_with_its_figures(
    data: ReplayData, tmp_path: Path
) -> None:
    """`dpgw replay --report` on a gateway's log with DP: thrust.png, the live commanded τ against the same
    controller's fed the raw measurements, after the six, with the dB kept out in report.md."""
    pytest.importorskip("matplotlib")
    import dataclasses

    from gateway.report.data import ThrustTrace

    t = np.arange(300.0, 900.0, 0.1)
    wave = np.column_stack([np.sin(0.6 * t), np.sin(0.6 * t + 1.0), 10.0 * np.sin(0.6 * t + 2.0)])
    slow = np.array([1.0e5, 2.0e4, 3.0e6])
    thrust = ThrustTrace(t, slow + 1.0e4 * wave, t, slow + 2.0e5 * wave, (0.3, 2.0))
    figures = {
        "band_rad_s": [0.3, 2.0],
        "scored_s": 600.0,
        "wave_band_tau_rms": [7.07e3, 7.07e3, 7.07e4],
        "raw_feedback_wave_band_tau_rms": [1.41e5, 1.41e5, 1.41e6],
        "saved_db": [26.0, 26.0, 26.0],
        "thrusters": [
            {
                "id": 1,
                "wave_band_thrust_rms_n": 4.0e3,
                "raw_feedback_wave_band_thrust_rms_n": 8.0e4,
                "saved_db": 26.0,
            },
            {
                "id": 2,
                "wave_band_thrust_rms_n": 0.0,
                "raw_feedback_wave_band_thrust_rms_n": 0.0,
                "saved_db": None,
            },
        ],
    }
    dp = {
        "modes": {"from": "statuses", "spans": [], "time_s": {"dp": 600.0}},
        "station_keeping": None,
        "dead_reckoning": {"spells": 0, "total_s": 0.0, "longest_s": 0.0, "in_dp_s": 0.0, "list": []},
        "alarms": [],
        "wave_filtering": figures,
    }
    files = write_report(dataclasses.replace(data, thrust=thrust, dp_performance=dp), tmp_path)
    assert [f.name for f in files][-1] == "thrust.png"
    assert len((tmp_path / "thrust.png").read_bytes()) > 20_000
    md = (tmp_path / "report.md").read_text()
    assert "](thrust.png)" in md
    assert "| kept out by wave filtering (dB) | 26.0 | 26.0 | 26.0 |" in md
    assert "| the same controller fed the raw measurements | 141 | 141 | 1,410 |" in md
    assert "| 1 | 4 | 80 | 26.0 |" in md and "| 2 | 0 | 0 | – |" in md
    # without a stretch in dp to compare, no such plot
    assert "thrust.png" not in [f.name for f in write_report(data, tmp_path / "plain")]


def test_a_log_that_never_moved_is_reported_without_a_warning_on_the_console(tmp_path: Path) -> None:
    """A bench's fixed position and heading have a PSD of zeros: the log-log panel stays empty instead of
    matplotlib warning ("Data has no positive values, and therefore cannot be log-scaled") on the console
    of every such `dpgw replay --report`."""
    pytest.importorskip("matplotlib")
    import warnings

    t = np.arange(0.0, 600.0, 0.5)
    still = np.tile([1.0, 2.0, 0.5], (len(t), 1))
    n = len(t)
    tr = ObserverTrace(
        "p", t, still, np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.full((n, 3), 0.9)
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        files = write_report(ReplayData("still", "mss_supply", t, still, (tr,)), tmp_path)
    assert "psd.png" in [f.name for f in files]
    assert not [w for w in caught if "log-scaled" in str(w.message)], [str(w.message) for w in caught]


def test_mode_changes_at_the_logs_start_read_0_s_not_minus_0() -> None:
    """A demo's first status a hair before the first record made report.md read "Mode changes: -0 s
    standby; 145 s dp"."""
    from gateway.report.markdown import dp_section

    dp = {
        "modes": {
            "time_s": {"standby": 145.0, "dp": 155.0},
            "spans": [
                {"mode": "standby", "from_s": -0.004, "to_s": 145.2},
                {"mode": "dp", "from_s": 145.2, "to_s": 300.0},
            ],
        },
        "station_keeping": None,
        "dead_reckoning": {"spells": 0},
        "alarms": [],
    }
    (line,) = [x for x in dp_section(dp) if x.startswith("Mode changes")]
    assert line == "Mode changes: 0 s standby; 145 s dp.", line
