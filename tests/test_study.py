"""`dpgw study`: the grid, the scores, the cache (a resumed study reruns nothing it has), and the Dask run
giving exactly the serial run's rows."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dpgw.cli import main
from dpgw.study.cache import CaseCache, code_version
from dpgw.study.case import run_case
from dpgw.study.runner import run_study
from dpgw.study.scores import CONVERGENCE_WINDOW_S, convergence_time, score_run
from dpgw.study.spec import SeaSpec, StudySpec, StudySpecError, load_study_file

# Small cases: the snijders ship at 1 Hz is the cheapest scenario; hassani (10 Hz, CyberShip II) the other.
SMALL = StudySpec(
    scenarios=("snijders_2005", "hassani"),
    seeds=(0, 1),
    observers=("passive", "ekf", "mmae"),
    duration_s=40.0,
)


def _same(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    """Rows equal bit for bit (NaN equal to NaN)."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b, strict=True):
        if ra.keys() != rb.keys():
            return False
        for k in ra:
            x, y = ra[k], rb[k]
            if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
                continue
            if x != y or type(x) is not type(y):
                return False
    return True


# --- the grid -------------------------------------------------------------------------------------------


def test_grid_is_the_product_and_every_case_has_every_observer() -> None:
    spec = StudySpec(
        scenarios=("hassani", "snijders_2005"),
        seas=(SeaSpec(hs_m=1.0), SeaSpec(hs_m=2.0), SeaSpec(hs_m=3.0)),
        seeds=(0, 1, 2, 3),
    )
    spec.check()
    cases = spec.cases()
    assert len(cases) == 2 * 3 * 4
    from observers.factory import OBSERVER_TYPES

    assert all(c.observers == OBSERVER_TYPES for c in cases)
    assert cases[0].settle_s == pytest.approx(spec.duration_s / 3)


@pytest.mark.parametrize(
    ("spec", "key"),
    [
        (StudySpec(scenarios=("atlantis",)), "'scenarios'"),
        (StudySpec(scenarios=("hassani",), observers=("passive:omega9=1",)), "'observers'"),
        (StudySpec(scenarios=("hassani",), observers=("passive", "passive")), "'observers'"),
        (StudySpec(scenarios=("hassani",), seas=(SeaSpec(hs_m=-1.0),)), "'hs_m'"),
        (StudySpec(scenarios=("hassani",), duration_s=0.0), "'duration_s'"),
        (StudySpec(scenarios=("hassani",), seeds=()), "'seeds'"),
        (StudySpec(scenarios=("hassani",), seas=(SeaSpec(current_mps=0.2),)), "'current_mps'.*hull"),
        # what a study can do instead, not the plant's "switch its effects off" (a study has no option for it)
        (
            StudySpec(scenarios=("hassani",), seas=(SeaSpec(current_mps=0.2),)),
            r"^(?!.*plant options).*without a current, or .*: torsetnes_2004, .*snijders_2005",
        ),
    ],
)
def test_a_wrong_grid_stops_with_the_key_named(spec: StudySpec, key: str) -> None:
    with pytest.raises(StudySpecError, match=key):
        spec.check()


def test_study_file(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(
        'scenarios = ["hassani"]\nseeds = {count = 3, start = 5}\nobservers = ["passive", "ekf"]\n'
        "duration_s = 120\n[grid]\nhs_m = [0.05, 0.1]\ntp_s = [5.0, 7.0]\n[[sea]]\nhs_m = 0.2\n"
    )
    spec = load_study_file(path)
    assert spec.seeds == (5, 6, 7)
    assert len(spec.seas) == 2 * 2 + 1
    assert SeaSpec(hs_m=0.1, tp_s=7.0) in spec.seas and SeaSpec(hs_m=0.2) in spec.seas
    assert len(spec.cases()) == 5 * 3
    path.write_text('scenarios = ["hassani"]\n[grid]\nheight = [1.0]\n')
    with pytest.raises(StudySpecError, match="'height'"):
        load_study_file(path)


STUDY_FILES = sorted((Path(__file__).resolve().parents[1] / "dpgw" / "study" / "studies").glob("*.toml"))


@pytest.mark.parametrize("path", STUDY_FILES, ids=lambda p: p.name)
def test_shipped_study_files_load(path: Path) -> None:
    """The study files docs/study.md regenerates its tables from load and pass the grid's checks (known
    scenarios, observer specs that parse), so the printed commands get past their first step."""
    spec = load_study_file(path)
    assert spec.scenarios and spec.seeds and spec.cases()


def test_the_study_file_docs_study_md_shows_loads(tmp_path: Path) -> None:
    """The example under "Study files" in docs/study.md is a study file the loader takes, as printed."""
    import re

    doc = (Path(__file__).resolve().parents[1] / "docs" / "study.md").read_text(encoding="utf-8")
    section = doc.split("## Study files", 1)[1]
    (example,) = re.findall(r"```toml\n(.*?)```", section.split("\n## ", 1)[0], re.S)
    path = tmp_path / "study.toml"
    path.write_text(example)
    spec = load_study_file(path)
    assert spec.scenarios == ("torsetnes_2004", "hassani") and len(spec.seeds) == 8
    assert len(spec.seas) == 3 * 2 + 1


def test_there_are_shipped_study_files() -> None:
    assert {p.name for p in STUDY_FILES} >= {"observers.toml", "torsetnes_tp.toml"}


def test_a_shipped_study_runs_by_name_from_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: docs/study.md and --help printed `--file examples/studies/observers.toml`, which only ran in
    a checkout ("No such file or directory" anywhere else). The shipped studies are package data, taken
    by name; the old path still runs; a missing file lists them."""
    from dpgw.study.spec import SHIPPED_STUDIES, study_file_path

    monkeypatch.chdir(tmp_path)  # not a checkout
    for given in ("observers", "observers.toml", "examples/studies/observers.toml"):
        assert study_file_path(given) == SHIPPED_STUDIES / "observers.toml"
    assert study_file_path("elsewhere/observers.toml") == Path("elsewhere/observers.toml")
    from dpgw.cli import build_parser
    from dpgw.cli_study import build_spec

    for given in ("observers", "examples/studies/observers.toml"):  # as --help and docs/study.md print it
        spec = build_spec(build_parser().parse_args(["study", "--file", given]))
        assert spec.scenarios == ("torsetnes_2004", "hassani", "snijders_2005") and len(spec.seeds) == 12
    assert main(["study", "--file", "observer", "--serial"]) == 2
    err = capsys.readouterr().err
    assert "study file observer: no such file" in err and "observers, torsetnes_tp" in err


def test_cache_key_names_the_case_and_the_code() -> None:
    a, b = SMALL.cases()[:2]
    v = code_version()
    assert a.key(v) == SMALL.cases()[0].key(v)  # same case, same key
    assert a.key(v) != b.key(v)  # another seed
    assert a.key(v) != a.key(v + "changed")  # other code


# --- the scores -----------------------------------------------------------------------------------------


def test_convergence_time_is_when_the_start_transient_ends() -> None:
    t = np.arange(0.0, 300.0, 0.5)
    rng = np.random.default_rng(0)
    err = np.abs(0.1 * rng.standard_normal(len(t)))
    err[t < 40.0] += 5.0  # a 40 s transient
    conv = convergence_time(t, err)
    assert 40.0 <= conv <= 40.0 + CONVERGENCE_WINDOW_S
    assert convergence_time(t, np.abs(0.1 * rng.standard_normal(len(t)))) == 0.0
    late = np.abs(0.1 * rng.standard_normal(len(t)))
    late[(t > 100.0) & (t < 105.0)] += 5.0  # thrown off after converging: counts until the episode ends
    assert 105.0 <= convergence_time(t, late) <= 105.0 + CONVERGENCE_WINDOW_S


def test_a_perfect_estimate_scores_zero() -> None:
    t = np.arange(0.0, 100.0, 0.1)
    eta = np.column_stack([np.sin(0.01 * t), np.cos(0.01 * t), 0.1 * np.sin(0.02 * t)])
    nu = np.column_stack([0.01 * np.cos(0.01 * t), np.zeros_like(t), np.zeros_like(t)])
    bias = np.ones((len(t), 3))
    omega0 = np.full((len(t), 3), 0.8)
    s = score_run(t, eta, nu, bias, omega0, t, eta, nu, bias, 30.0, 0.8)
    for key in ("rms_horizontal_m", "rms_heading_deg", "rms_surge_mps", "bias_rms_x_n", "omega0_error_pct"):
        assert s[key] == pytest.approx(0.0, abs=1e-12), key
    assert s["convergence_s"] == 0.0


def test_a_case_scores_every_observer_on_the_same_measurements() -> None:
    case = SMALL.cases()[0]
    rows = run_case(case.as_dict())
    assert [r["observer"] for r in rows] == ["passive", "ekf", "mmae"]
    for r in rows:
        assert r["samples"] > 20  # 1 Hz, scored over the last 2/3 of 40 s
        assert 0 < r["rms_horizontal_m"] < 2.0 and 0 < r["rms_heading_deg"] < 3.0
        assert math.isfinite(r["bias_rms_x_n"]) and math.isfinite(r["rms_surge_mps"])
    # the fixed-gain observers are tuned to the scenario's own sea: no ω0 error
    assert rows[0]["omega0_error_pct"] == pytest.approx(0.0, abs=1e-9)
    assert _same(rows, run_case(case.as_dict()))  # deterministic


# --- cache and Dask -------------------------------------------------------------------------------------


def test_a_resumed_study_reuses_the_cache(tmp_path: Path) -> None:
    """A study stopped after two of four cases reruns only the other two, and its table is a fresh run's."""
    spec = StudySpec(
        scenarios=("snijders_2005",), seeds=(0, 1, 2, 3), observers=("passive", "sdre"), duration_s=30.0
    )
    cases = spec.cases()
    calls: list[int] = []

    class StoppedError(Exception):
        pass

    def interrupted(case: dict[str, Any]) -> list[dict[str, Any]]:
        if len(calls) == 2:
            raise StoppedError
        calls.append(case["seed"])
        return run_case(case)

    cache = CaseCache(tmp_path / "cache")
    with pytest.raises(StoppedError):
        run_study(cases, workers=0, cache=cache, case_fn=interrupted)
    assert len(list((tmp_path / "cache").glob("*.json"))) == 2

    resumed: list[int] = []

    def counting(case: dict[str, Any]) -> list[dict[str, Any]]:
        resumed.append(case["seed"])
        return run_case(case)

    r = run_study(cases, workers=0, cache=cache, case_fn=counting)
    assert (r.computed, r.cached) == (2, 2)
    assert sorted(resumed) == [2, 3]  # no case recomputed
    fresh = run_study(cases, workers=0)
    assert _same(r.rows, fresh.rows)
    again = run_study(cases, workers=0, cache=cache, case_fn=counting)
    assert (again.computed, again.cached) == (0, 4) and _same(again.rows, fresh.rows)


@pytest.mark.slow
def test_two_dask_workers_give_exactly_the_serial_rows() -> None:
    cases = SMALL.cases()
    serial = run_study(cases, workers=0)
    dask = run_study(cases, workers=2)
    assert dask.workers == 2 and dask.computed == len(cases)
    assert len(serial.rows) == len(cases) * 3
    assert _same(dask.rows, serial.rows)


def test_cli_writes_table_summary_plots_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    doc = tmp_path / "doc.md"
    head = "# t\nquoted: `<!-- study-table:begin -->`\n<!-- study-table:begin -->\n"
    doc.write_text(head + "old\n<!-- study-table:end -->\nafter\n")
    argv = ["study", "--scenario", "snijders_2005", "--seeds", "0-1", "--duration", "30",
            "--observer", "passive", "--observer", "ekf", "--serial", "--json", "--no-progress",
            "--out", str(out), "--update-doc", str(doc)]  # fmt: skip
    assert main(argv) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["cases"] == 2 and report["rows"] == 4 and report["computed"] == 2
    # 20 s scored of a 12 s sea: too short, said on stderr before the run (it can be stopped: it was said
    # only after it) and in the report
    warning, unsettled = report["warnings"]  # too short, and scored before the observers settled
    assert (
        unsettled.startswith("snijders_2005, nominal: scored from 10 s, but observer")
        and "--settle" in unsettled
    )
    assert warning.startswith("snijders_2005, nominal: 20 s scored, from 10 s to 30 s, less than the 96 s")
    assert captured.err.count(f"dpgw study: warning: {warning}\n") == 1
    assert captured.err.startswith(f"dpgw study: warning: {warning}\n"), captured.err
    assert {e["observer"] for e in report["summary"]} == {"passive", "ekf"}
    assert (out / "results.csv").read_text().count("\n") == 1 + 4
    assert (out / "summary.md").exists() and list(out.glob("box_*.png"))
    text = doc.read_text()
    assert "old" not in text and "| passive |" in text and text.endswith("after\n")
    assert text.startswith(head)
    assert main(argv) == 0  # again: everything from the cache
    assert json.loads(capsys.readouterr().out)["cached"] == 2
    assert main(["study", "--scenario", "snijders_2005", "--observer", "nope", "--serial"]) == 2
    err = capsys.readouterr().err
    assert "'observers'" in err and "study: study:" not in err  # the spec's "study: " said once
    # a named table; a file without its markers stops the study before any case
    doc.write_text("<!-- study-table:x:begin -->\n<!-- study-table:x:end -->\n")
    assert main([*argv[:-1], f"{doc}#x"]) == 0
    assert "| ekf |" in doc.read_text()
    assert main([*argv[:-1], f"{doc}#y"]) == 2
    assert "study-table:y:begin" in capsys.readouterr().err


def test_a_sea_state_of_the_grid_is_the_one_simulated() -> None:
    """Hs, Tp and direction replace the scenario's sea; a current runs the full plant (no bias truth)."""
    sea = SeaSpec(hs_m=2.0, tp_s=8.0, direction_deg=180.0, current_mps=0.3, current_dir_deg=90.0)
    spec = StudySpec(
        scenarios=("torsetnes_2004",), seas=(sea,), seeds=(0,), observers=("passive",), duration_s=30.0
    )
    spec.check()
    (row,) = run_case(spec.cases()[0].as_dict())
    assert (row["hs_m"], row["tp_s"], row["direction_deg"], row["current_mps"]) == (2.0, 8.0, 180.0, 0.3)
    assert row["sea"] == "Hs2 Tp8 dir180 cur0.3 @90"
    # tuned to the scenario's own Tp 11.5 s, not the case's 8 s
    assert row["omega0_error_pct"] == pytest.approx(
        100 * abs(2 * math.pi / 11.5 - 2 * math.pi / 8) / (2 * math.pi / 8)
    )
    assert math.isfinite(row["rms_horizontal_m"]) and math.isnan(row["bias_rms_x_n"])


@pytest.mark.slow
def test_an_existing_cluster_by_its_address_gives_the_same_rows() -> None:
    """--scheduler tcp://…: the client of a running cluster (here a LocalCluster started by the test)."""
    import logging

    from distributed import LocalCluster

    cases = SMALL.cases()[:2]
    serial = run_study(cases, workers=0)
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    ) as cluster:
        remote = run_study(cases, scheduler=cluster.scheduler_address)
    assert remote.scheduler == cluster.scheduler_address and remote.workers == 2
    assert _same(remote.rows, serial.rows)


def test_a_server_that_is_not_dask_at_the_address_is_said_not_waited_for() -> None:
    """--scheduler at a port where something else listens and never answers Dask's handshake (a web
    server, a forward to nothing): Dask's own timeout does not cover it and its client waits for ever; the
    study gives up after its wait and says what to give instead."""
    import socket

    from distributed import Client

    from dpgw.study.runner import StudyRunError, _connect

    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        t0 = time.monotonic()
        with pytest.raises(StudyRunError, match="nothing answered as a Dask scheduler within 2 s"):
            _connect(Client, address, wait_s=2.0)
        assert time.monotonic() - t0 < 30.0


@pytest.mark.parametrize("address", ["127.0.0.1", "foo://127.0.0.1:8786"])
def test_a_scheduler_address_dask_cannot_dial_is_said_in_one_line(address: str) -> None:
    """No port, or a scheme Dask does not know: Dask's ValueError was a traceback; now what to give."""
    from distributed import Client

    from dpgw.study.runner import StudyRunError, _connect

    with pytest.raises(StudyRunError, match=r"not an address Dask can dial .*tcp://HOST:8786"):
        _connect(Client, address, wait_s=10.0)


def test_the_measurements_are_the_ones_the_loop_observer_got() -> None:
    """The stream a case keeps is what the gateway's own observer was fed: the passive observer run over
    it offline gives the loop's live estimates (to rounding: the two clocks count from different origins)."""
    from dpgw.closed_loop import run_closed_loop
    from dpgw.study.case import build_scenario, loop_tables
    from gateway.config import parse_config
    from gateway.replay import parse_observer_spec
    from simulator.clock import SimEpoch

    case = StudySpec(scenarios=("hassani",), seeds=(3,), duration_s=20.0).cases()[0]
    scenario = build_scenario(case)
    tables = loop_tables(case, scenario, scenario.sea[0][1].tp_s)
    loop = run_closed_loop(
        scenario, case.duration_s, seed=case.seed, tables=tables, collect=("/dp/measurement",)
    )
    meas = loop.collected["/dp/measurement"]
    start = SimEpoch(scenario.start_utc).stamp_ns(0.0)
    t = np.array([(m["stamp_ns"] - start) / 1e9 for m in meas])
    y = np.array([[math.nan if v is None else v for v in m["eta"]] for m in meas], dtype=float)
    tau = np.array([m["tau"] for m in meas], dtype=float)
    run = parse_observer_spec("passive").make(parse_config(tables, base_dir=Path.cwd())).run(t, y, tau)
    offline = {m["stamp_ns"]: run.eta[k] for k, m in enumerate(meas)}
    live = [(e["stamp_ns"], np.array(e["eta"])) for e in loop.estimates]
    assert len(live) > 150
    worst = max(float(np.max(np.abs(offline[ns] - eta))) for ns, eta in live)
    assert worst < 1e-9


def test_table_reads_back_exactly(tmp_path: Path) -> None:
    """results.csv holds every digit (and NaN as an empty field)."""
    import csv

    from dpgw.study.outputs import write_table

    rows = [{"observer": "a", "seed": 1, "x": 0.1 + 0.2, "y": math.nan}]
    files = write_table(rows, tmp_path)
    with open(files[0]) as f:
        (back,) = list(csv.DictReader(f))
    assert float(back["x"]) == 0.1 + 0.2 and back["y"] == "" and back["seed"] == "1"


def test_parquet_table_where_pyarrow_is_installed(tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    from dpgw.study.outputs import write_table

    write_table([{"observer": "a", "seed": 1, "x": 0.1 + 0.2, "y": math.nan}], tmp_path)
    table = pq.read_table(tmp_path / "results.parquet").to_pylist()
    assert table[0]["x"] == 0.1 + 0.2 and math.isnan(table[0]["y"])


def test_box_whiskers_are_the_summarys_5_and_95_percent() -> None:
    """The box plot's whiskers end at the p5 and p95 the summary table prints; the values beyond them are
    points. Before, matplotlib's boxplot(whis=(5, 95)) ended them at the farthest value inside: with two
    seeds both whiskers sat on the box and neither end matched the table."""
    from dpgw.study.outputs import box_stats, spread

    values = [0.07052594863867588, 0.11045939424054986, math.nan]
    med, p5, p95, _ = spread(values)
    b = box_stats(values)
    assert (b["med"], b["whislo"], b["whishi"]) == (med, p5, p95)
    assert b["q1"] == pytest.approx(0.0805093) and b["q3"] == pytest.approx(0.1004760)
    assert sorted(b["fliers"]) == values[:2]
    twelve = [float(k) for k in range(12)]
    b = box_stats(twelve)
    assert (b["whislo"], b["whishi"]) == pytest.approx((0.55, 10.45)) and list(b["fliers"]) == [0.0, 11.0]
    assert math.isnan(box_stats([math.nan])["med"])


def test_the_summary_counts_seeds_and_cases_in_words() -> None:
    """One seed is "1 seed", not "1 seeds" (the heading of each group of the summary)."""
    from dpgw.study.outputs import SUMMARY_COLUMNS, summary_markdown

    row = {"scenario": "hassani", "sea": "own sea", "observer": "passive", "seed": 0, "hs_m": 1.0,
           "tp_s": 6.0, "duration_s": 60.0, "settle_s": 10.0}  # fmt: skip
    row.update({column: 1.0 for column, _, _ in SUMMARY_COLUMNS})
    for seeds, words in (([0], "1 seed,"), ([0, 1], "2 seeds,")):
        text = summary_markdown([{**row, "seed": k} for k in seeds])
        assert words in text, text


def test_the_summary_heading_gives_times_to_the_tenth_of_a_second() -> None:
    """The default settle time is a third of the duration: 200 s scored from 66.7 s, not 66.6667 s."""
    from dpgw.study.outputs import SUMMARY_COLUMNS, summary_markdown

    row = {"scenario": "hassani", "sea": "own sea", "observer": "passive", "seed": 0, "hs_m": 1.0,
           "tp_s": 6.0, "duration_s": 200.0, "settle_s": 200.0 / 3.0}  # fmt: skip
    row.update({column: 1.0 for column, _, _ in SUMMARY_COLUMNS})
    heading = summary_markdown([row]).splitlines()[0]
    assert heading.endswith(", 133.3 s scored, from 66.7 s to 200 s)"), heading


def test_a_sea_state_scored_too_briefly_is_warned_of() -> None:
    """Before: `--duration 10` printed a full table from 6.7 s of scoring under the heading "10 s scored
    from 3.3 s", and nothing said the figures were one sample. The least is the longer of 8 periods of the
    sea's Tp (the report's Welch segment) and the demo's 30 s."""
    from dpgw.study.outputs import SUMMARY_COLUMNS, least_scored_s, short_scoring_warnings, summary_markdown

    row = {"scenario": "hassani", "sea": "nominal", "observer": "passive", "seed": 0, "hs_m": 0.08,
           "tp_s": 6.75, "duration_s": 10.0, "settle_s": 10.0 / 3.0}  # fmt: skip
    row.update({column: 1.0 for column, _, _ in SUMMARY_COLUMNS})
    assert "(Hs 0.08 m, Tp 6.75 s, 1 seed, 6.7 s scored, from 3.3 s to 10 s)" in summary_markdown([row])
    assert least_scored_s(6.75) == 54.0 and least_scored_s(2.0) == 30.0
    [warning] = short_scoring_warnings([row, {**row, "observer": "ekf"}])  # one per sea state
    assert warning.startswith("hassani, nominal: 6.7 s scored, from 3.3 s to 10 s, less than the 54 s ")
    assert warning.endswith("give --duration 81 or more")  # a third of 81 s settling leaves 54 s
    assert short_scoring_warnings([{**row, "duration_s": 81.0, "settle_s": 27.0}]) == []
    given_settle = short_scoring_warnings([{**row, "duration_s": 80.0, "settle_s": 30.0}])
    assert given_settle[0].endswith("give --duration 84 or more (scored from --settle 30 s)")


def test_the_summary_pairs_each_observer_with_the_first_seed_by_seed() -> None:
    """The study is paired (every observer on the same measurements), and the summary says so: beside the
    spread over the seeds, each observer's error against the first observer's on the same seed. Here
    observer b is 10 % better than a on every seed while the seeds' spread (a factor 1-4, a sea that is
    harder on some seeds) makes their 5-95 % ranges overlap: the paired figures show it, the spread does
    not. The JSON summary carries the same, and the sea state and seeds of each entry."""
    from dpgw.study.outputs import SUMMARY_COLUMNS, json_summary, paired, summary_markdown

    base = {"scenario": "hassani", "sea": "nominal", "hs_m": 1.0, "tp_s": 6.0, "direction_deg": 90.0,
            "current_mps": 0.0, "duration_s": 60.0, "settle_s": 10.0}  # fmt: skip
    rows = []
    for seed, hard in enumerate((1.0, 2.0, 3.0, 4.0)):
        for obs, factor in (("a", 1.0), ("b", 0.9)):
            row = {**base, "observer": obs, "seed": seed}
            row.update({column: hard * factor for column, _, _ in SUMMARY_COLUMNS})
            rows.append(row)
    rows[-1]["rms_heading_deg"] = math.nan  # b's heading figure missing on the last seed
    a = [r for r in rows if r["observer"] == "a"]
    b = [r for r in rows if r["observer"] == "b"]
    p = paired(b, a, "rms_horizontal_m")
    assert (p["lower_on"], p["n"]) == (4, 4)
    assert p["ratio_median"] == pytest.approx(0.9) and p["ratio_p5"] == p["ratio_p95"] == pytest.approx(0.9)
    assert paired(b, a, "rms_heading_deg")["n"] == 3
    text = summary_markdown(rows)
    assert "Paired with a" in text
    assert "| b | 4/4 | 0.90 [0.90, 0.90] | 3/3 | 0.90 [0.90, 0.90] |" in text, text
    entries = {e["observer"]: e for e in json_summary(rows)}
    assert "paired" not in entries["a"]
    assert entries["b"]["paired"]["reference"] == "a"
    assert entries["b"]["paired"]["rms_horizontal_m"]["lower_on"] == 4
    assert entries["b"]["seeds"] == [0, 1, 2, 3] and entries["b"]["tp_s"] == 6.0
    json.dumps(entries, allow_nan=False)  # machine-readable: no NaN


@pytest.mark.parametrize("degrees", [0.0, 150.0, 200.0, 255.0, 359.0, -135.0, 45.0 + 180.0 + 30.0])
def test_the_tables_direction_is_the_degrees_given(degrees: float) -> None:
    """The scenarios keep their sea's direction in radians; the table's `direction_deg` is the degrees
    they were given (hassani's 150° was 150.00000000000003 in results.csv, snijders' 200°
    199.99999999999997: a filter on 150 found no row)."""
    from dpgw.study.case import direction_deg

    assert direction_deg(math.radians(degrees)) == degrees % 360.0
    assert direction_deg(math.radians(-1e-12)) == 0.0  # never 360.0


def test_a_study_too_short_to_score_is_warned_of_before_it_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The length is known before the run: the warning comes first, so an hour's study can be stopped
    and started again longer. Here the study is stopped at once (Ctrl-C as it starts): the warning was
    already said (before, it came only with the outputs of a finished study)."""
    import dpgw.study.runner as runner

    def stopped(*_: Any, **__: Any) -> Any:
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_study", stopped)
    argv = ["study", "--scenario", "snijders_2005", "--seeds", "0", "--duration", "30", "--serial",
            "--no-progress", "--out", str(tmp_path / "out")]  # fmt: skip
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.startswith("dpgw study: warning: snijders_2005, nominal: 20 s scored, from 10 s to 30 s"), err
    assert "give --duration 144 or more" in err and "stopped (Ctrl-C)" in err


@pytest.mark.parametrize("workers", ["-1", "x", "1.5"])
def test_a_worker_count_below_zero_is_a_usage_error(workers: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Before: ``--workers -1`` was taken and the study hung with no worker to run a case."""
    from dpgw.cli import build_parser

    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["study", "--scenario", "hassani", "--workers", workers])
    assert stop.value.code == 2
    assert "--workers" in capsys.readouterr().err
    assert build_parser().parse_args(["study", "--workers", "0"]).workers == 0
    with pytest.raises(ValueError, match="workers: -1"):
        run_study(SMALL.cases()[:1], workers=-1)


def test_a_study_scored_before_an_observer_settles_is_warned_before_it_runs() -> None:
    """`hassani` with the defaults (300 s, scored from 100 s): the MMAE's bank settles in ~126 s (its first
    identification), so its figures held its start-up (ω0 error 15-47 % against 3.2 % scored from 300 s),
    with no word. Now a warning names it and the --settle that leaves its start-up out; with that
    --settle, none."""
    from dpgw.study import outputs
    from dpgw.study.spec import StudySpec

    spec = StudySpec(scenarios=("hassani",), seeds=(0, 1), observers=("passive", "mmae", "sdre"))
    (warning,) = outputs.unsettled_warnings(spec.cases())  # (once for both seeds)
    assert warning.startswith("hassani, nominal: scored from 100 s, but observer 'mmae' (~"), warning
    need = int(warning.rsplit("give --settle ", 1)[1].split()[0])
    assert 110 <= need <= 200
    later = StudySpec(scenarios=("hassani",), seeds=(0,), observers=("passive", "mmae"), settle_s=need)
    assert outputs.unsettled_warnings(later.cases()) == []
