"""What a study writes: the results table (CSV; Parquet too when pyarrow is installed), the markdown
summary (median and 5–95 % per observer per sea state, and each observer paired seed by seed with the
first) and box plots (per sea state, a box per observer).

The table is the record (one row per case × observer, every column of docs/study.md); the summary and the
plots are made from it alone, so either can be made again from a table without running a case.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dpgw.scored_stretch import MIN_SCORED_S
from gateway.report.metrics import WELCH_PERIODS

# (column, header, format) of the summary and the plots, in order
SUMMARY_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("rms_horizontal_m", "pos RMS (m)", ".3f"),
    ("rms_heading_deg", "ψ RMS (°)", ".3f"),
    ("rms_surge_mps", "u RMS (m/s)", ".4f"),
    ("rms_yaw_rate_degps", "r RMS (°/s)", ".4f"),
    ("att_north_db", "att N (dB)", ".1f"),
    ("att_heading_db", "att ψ (dB)", ".1f"),
    ("omega0_error_pct", "ω0 err (%)", ".1f"),
    ("convergence_s", "conv. (s)", ".0f"),
)
PLOT_COLUMNS = ("rms_horizontal_m", "rms_heading_deg", "rms_surge_mps", "att_heading_db")
# (column, header) of the paired comparison: each observer against the sea state's first, seed by seed
PAIRED_COLUMNS: tuple[tuple[str, str], ...] = (
    ("rms_horizontal_m", "pos RMS"),
    ("rms_heading_deg", "ψ RMS"),
)


def _csv_value(v: Any) -> Any:
    """A float with all its digits (repr reads back exactly); NaN as an empty field."""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return v


def write_table(rows: Sequence[dict[str, Any]], folder: Path) -> list[Path]:
    """results.csv (floats written with repr: they read back exactly), and results.parquet if pyarrow is
    importable."""
    folder.mkdir(parents=True, exist_ok=True)
    columns = list(rows[0]) if rows else []
    out = [folder / "results.csv"]
    with open(out[0], "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for row in rows:
            w.writerow([_csv_value(row[c]) for c in columns])
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return out
    table = pa.table({c: [row[c] for row in rows] for c in columns})
    pq.write_table(table, folder / "results.parquet")
    out.append(folder / "results.parquet")
    return out


def groups(rows: Sequence[dict[str, Any]]) -> dict[tuple[str, str], dict[str, list[dict[str, Any]]]]:
    """(scenario, sea) → observer → rows, in the table's order."""
    out: dict[tuple[str, str], dict[str, list[dict[str, Any]]]] = {}
    for row in rows:
        out.setdefault((row["scenario"], row["sea"]), {}).setdefault(row["observer"], []).append(row)
    return out


def spread(values: Sequence[float]) -> tuple[float, float, float, int]:
    """Median, 5th and 95th percentile (linear) of the finite values, and how many there are."""
    v = np.array([x for x in values if isinstance(x, int | float) and math.isfinite(x)], dtype=float)
    if len(v) == 0:
        return math.nan, math.nan, math.nan, 0
    p5, med, p95 = np.percentile(v, [5.0, 50.0, 95.0])
    return float(med), float(p5), float(p95), len(v)


def _cell(values: Sequence[float], fmt: str) -> str:
    med, lo, hi, n = spread(values)
    if n == 0:
        return "–"
    text = f"{med:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]"
    return text if n == len(values) else f"{text} (n={n})"


def paired(
    rows: Sequence[dict[str, Any]], reference: Sequence[dict[str, Any]], column: str
) -> dict[str, Any]:
    """An observer against the reference on the same seeds (the same measurements: the study is paired):
    on how many of the seeds both have the figure the observer's is lower, and the median, 5th and 95th
    percentile of the ratio observer / reference over those seeds. The spread of the ratio is the
    observers' difference alone; the spread of each observer over the seeds (the summary's) also holds
    how hard each seed's sea was, which both observers share."""
    ref = {r["seed"]: r[column] for r in reference}
    pairs = [
        (float(r[column]), float(ref[r["seed"]]))
        for r in rows
        if r["seed"] in ref
        and math.isfinite(r[column])
        and math.isfinite(ref[r["seed"]])
        and ref[r["seed"]] > 0
    ]
    med, lo, hi, n = spread([a / b for a, b in pairs])
    return {
        "lower_on": sum(a < b for a, b in pairs),
        "n": n,
        "ratio_median": med if n else None,
        "ratio_p5": lo if n else None,
        "ratio_p95": hi if n else None,
    }


def _paired_markdown(by_obs: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Each observer but the first against the first, seed by seed (PAIRED_COLUMNS)."""
    names = list(by_obs)
    if len(names) < 2:
        return []
    ref = names[0]
    lines = [
        f"Paired with {ref}, seed by seed: on how many seeds the error is lower than {ref}'s, and the "
        f"ratio to {ref}'s, median [5 %, 95 %] over the seeds.",
        "",
        "| observer | " + " | ".join(f"{h}: lower on | {h} ratio" for _, h in PAIRED_COLUMNS) + " |",
        "|---|" + "---|---|" * len(PAIRED_COLUMNS),
    ]
    for obs in names[1:]:
        cells = []
        for column, _ in PAIRED_COLUMNS:
            p = paired(by_obs[obs], by_obs[ref], column)
            if p["n"] == 0:
                cells += ["–", "–"]
            else:
                cells += [
                    f"{p['lower_on']}/{p['n']}",
                    f"{p['ratio_median']:.2f} [{p['ratio_p5']:.2f}, {p['ratio_p95']:.2f}]",
                ]
        lines.append(f"| {obs} | " + " | ".join(cells) + " |")
    lines.append("")
    return lines


def seconds(s: float) -> str:
    """A time in a heading to the tenth of a second, without a trailing .0: ``66.7`` (a third of 200 s,
    which ``:g`` wrote 66.6667), ``60``."""
    return f"{round(s, 1):g}"


def scored_span(row: dict[str, Any]) -> str:
    """The stretch a row's figures come from: ``6.7 s scored, from 3.3 s to 10 s`` (the case's end)."""
    duration, settle = row["duration_s"], row["settle_s"]
    return f"{seconds(duration - settle)} s scored, from {seconds(settle)} s to {seconds(duration)} s"


def least_scored_s(tp_s: float) -> float:
    """The shortest scored stretch a sea of peak period ``tp_s`` gives figures worth reading from (s):
    `WELCH_PERIODS` of its periods, and never less than `MIN_SCORED_S`.

    The two rules the project already has, taken together. The attenuation is the replay report's, whose
    spectra take segments of `WELCH_PERIODS` periods of the wave band's lowest frequency (a bin spacing of
    an eighth of it); a scored stretch of fewer than that many periods of the sea's own peak is one short
    segment whose bins are too coarse to place the peak and the band around it. The RMS errors vary over
    tens of seconds (waves of several seconds, the bias estimate's error over its time constant): `dpgw
    demo` scores nothing shorter than its `MIN_SCORED_S` (30 s: over any 3 s of its default run the RMS
    ranged from 0.27 to 2.2 times the whole run's). On the defaults (300 s cases, scored from 100 s) every
    scenario's own sea passes (hassani needs 54 s, torsetnes_2004 92 s)."""
    return max(MIN_SCORED_S, WELCH_PERIODS * tp_s)


def short_scoring_warnings(rows: Sequence[dict[str, Any]]) -> list[str]:
    """One sentence per sea state scored on less than `least_scored_s` (the figures are printed all the
    same: the table of a too-short study is what the user asked for, with this said beside it)."""
    out = []
    for (scenario, sea), by_obs in groups(rows).items():
        first = next(iter(by_obs.values()))[0]
        duration, settle, tp = first["duration_s"], first["settle_s"], first["tp_s"]
        need = least_scored_s(tp)
        if duration - settle >= need:
            continue
        default_settle = math.isclose(settle, duration / 3.0)
        longer = math.ceil(1.5 * need if default_settle else settle + need)
        rule = f"the longer of {WELCH_PERIODS} periods of its Tp {tp:g} s and {MIN_SCORED_S:g} s"
        out.append(
            f"{scenario}, {sea}: {scored_span(first)}, less than the {seconds(need)} s its figures need "
            f"({rule}): an RMS over so short a stretch is one sample of the errors, not their level, and "
            f"the attenuation's spectrum cannot resolve the wave peak; give --duration {longer} or more"
            + ("" if default_settle else f" (scored from --settle {seconds(settle)} s)")
        )
    return out


def unsettled_warnings(cases: Sequence[Any]) -> list[str]:
    """One sentence per sea state whose figures are scored from before some observer has settled (its
    `settle_time_s` beyond the study's settle time): they then hold its start-up, not its filtering. A
    300 s study (scored from 100 s) put the MMAE's ω0 error on `hassani` at 15-47 %, against 3.2 % scored
    from 300 s of 900 s: its bank settles in ~126 s. Said before the run, from the cases (seeds alike)."""
    from dpgw.study.case import settle_times

    out, seen = [], set()
    for case in cases:
        key = (case.scenario, case.sea.label, case.settle_s, tuple(case.observers))
        if key in seen:
            continue
        seen.add(key)
        late = {label: t for label, t in settle_times(case).items() if t > case.settle_s}
        if not late:
            continue
        need = math.ceil(max(late.values()))
        who = ", ".join(f"'{label}' (~{t:.0f} s)" for label, t in late.items())
        several = len(late) > 1
        out.append(
            f"{case.scenario}, {case.sea.label}: scored from {seconds(case.settle_s)} s, but observer"
            f"{'s' if several else ''} {who} settle{'' if several else 's'} only after that (the slowest "
            "error mode; the MMAE's bank also waits for its first identification): the figures hold that "
            f"start-up, not the filtering; give --settle {need} (and a --duration leaving enough after it)"
        )
    return out


def planned_rows(cases: Sequence[Any]) -> list[dict[str, Any]]:
    """What `short_scoring_warnings` reads of a study's rows (scenario, sea, observer, duration, settle and
    the sea's peak period), from its cases before any runs: one row per case, so that a study too short
    to score is said before it runs, not after an hour."""
    from dpgw.study.case import build_scenario  # (the case's sea: its own values, else the scenario's)

    out = []
    for case in cases:
        tp = build_scenario(case).sea[0][1].tp_s
        out.append(
            {
                "scenario": case.scenario,
                "sea": case.sea.label,
                "observer": "",
                "duration_s": case.duration_s,
                "settle_s": case.settle_s,
                "tp_s": tp,
            }
        )
    return out


def summary_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """Per sea state a table: per observer the median [5 %, 95 %] of each column over the seeds; then each
    observer paired with the first, seed by seed (`paired`)."""
    lines: list[str] = []
    for (scenario, sea), by_obs in groups(rows).items():
        seeds = sorted({r["seed"] for rs in by_obs.values() for r in rs})
        first = next(iter(by_obs.values()))[0]
        lines.append(
            f"### {scenario}, {sea} (Hs {first['hs_m']:g} m, Tp {first['tp_s']:g} s, "
            f"{len(seeds)} seed{'s' if len(seeds) != 1 else ''}, {scored_span(first)})"
        )
        lines.append("")
        lines.append("| observer | " + " | ".join(h for _, h, _ in SUMMARY_COLUMNS) + " |")
        lines.append("|---|" + "---|" * len(SUMMARY_COLUMNS))
        for obs, rs in by_obs.items():
            cells = [_cell([r[c] for r in rs], fmt) for c, _, fmt in SUMMARY_COLUMNS]
            lines.append(f"| {obs} | " + " | ".join(cells) + " |")
        lines.append("")
        lines += _paired_markdown(by_obs)
    return "\n".join(lines)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")


def box_stats(values: Sequence[float]) -> dict[str, Any]:
    """One box as matplotlib's ``bxp`` draws it: median, quartiles, whiskers at the summary's own 5 and
    95 % (`spread`, linear percentiles) and the values beyond them as points. matplotlib's ``boxplot(whis=
    (5, 95))`` ends a whisker at the farthest *value* inside the percentile instead: with a few seeds at the
    box's edge, not at the table's figure."""
    v = np.array([x for x in values if math.isfinite(x)], dtype=float)
    if len(v) == 0:
        return {"med": math.nan, "q1": math.nan, "q3": math.nan, "whislo": math.nan, "whishi": math.nan,
                "fliers": np.array([])}  # fmt: skip
    med, p5, p95, _ = spread(v.tolist())
    q1, q3 = np.percentile(v, [25.0, 75.0])
    return {"med": med, "q1": float(q1), "q3": float(q3), "whislo": p5, "whishi": p95,
            "fliers": v[(v < p5) | (v > p95)]}  # fmt: skip


def box_plots(rows: Sequence[dict[str, Any]], folder: Path) -> list[Path]:
    """One PNG per sea state: a panel per column of PLOT_COLUMNS, a box per observer (whiskers 5–95 %)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    headers = {c: h for c, h, _ in SUMMARY_COLUMNS}
    out = []
    for (scenario, sea), by_obs in groups(rows).items():
        fig, axes = plt.subplots(1, len(PLOT_COLUMNS), figsize=(4.0 * len(PLOT_COLUMNS), 4.0))
        for ax, col in zip(axes, PLOT_COLUMNS, strict=True):
            ax.bxp([box_stats([r[col] for r in rs]) for rs in by_obs.values()], showfliers=True)
            ax.set_xticks(range(1, len(by_obs) + 1), list(by_obs), rotation=45, ha="right", fontsize=8)
            ax.set_title(headers[col], fontsize=9)
            ax.grid(True, axis="y", alpha=0.3)
        fig.suptitle(f"{scenario}, {sea}", fontsize=10)
        fig.tight_layout()
        path = folder / f"box_{_slug(scenario)}_{_slug(sea)}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        out.append(path)
    return out


def json_summary(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The summary as data: per sea state and observer the sea simulated (Hs, Tp, direction, current), the
    seeds, each column's median, p5, p95 and n (NaN → None), and (every observer but the sea state's first)
    `paired`: the comparison with the first observer seed by seed (`paired`)."""
    out = []
    for (scenario, sea), by_obs in groups(rows).items():
        ref = next(iter(by_obs))
        for obs, rs in by_obs.items():
            entry: dict[str, Any] = {"scenario": scenario, "sea": sea, "observer": obs, "cases": len(rs)}
            for key in ("hs_m", "tp_s", "direction_deg", "current_mps", "duration_s", "settle_s"):
                value = rs[0].get(key)
                entry[key] = None if isinstance(value, float) and math.isnan(value) else value
            entry["seeds"] = [r["seed"] for r in rs]
            for col, _, _ in SUMMARY_COLUMNS:
                med, lo, hi, n = spread([r[col] for r in rs])
                entry[col] = {
                    "median": med if n else None,
                    "p5": lo if n else None,
                    "p95": hi if n else None,
                    "n": n,
                }
            if obs != ref:
                entry["paired"] = {"reference": ref} | {
                    col: paired(rs, by_obs[ref], col) for col, _ in PAIRED_COLUMNS
                }
            out.append(entry)
    return out
