"""The report's `report.md`: span, settle time and wave band, the measurement's dominant frequency, one
table per observer, the bad-input counts and the plots (or why there are none).

Numbers come from `compute_metrics` (SI units, radians); here heading is shown in degrees (deg² for the
mean square) and a missing value as "–".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gateway.report.data import DOF, DOF_SYMBOL, ReplayData, force_prefix


def _fmt(x: Any, digits: int = 3, scale: float = 1.0) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{float(x) * scale:.{digits}g}"


def _signed(x: Any) -> str:
    """An attenuation with its sign: +1.21 dB (the LF estimate lifted the motion) against −22.4 dB."""
    text = _fmt(x)
    return "+" + text if text != "–" and float(x) > 0 else text


def _span(m: dict[str, Any]) -> str:
    """The span in seconds (0.1 s), its length also in min over 10 min and in h over 10 h, as the plots'
    time axes: `4.4 %g` made a two-day merge of logs '(1.764e+05 s)' and 90 s '89.9043 s'."""
    t0, t1 = m["span_s"]
    d = m["duration_s"]
    if t0 is None or t1 is None or d is None:
        return "–"
    length = f"{d:.1f} s" if d <= 600 else f"{d / 60:.1f} min" if d <= 36000 else f"{d / 3600:.1f} h"
    text = f"{t0:.1f} s to {t1:.1f} s ({length})"
    utc = m.get("span_utc")
    if utc and utc[0] and utc[1]:  # a log stamped in UTC: when, as well as how long
        a, b = (u.replace("T", " ").removesuffix("Z") for u in utc)
        text += f", {a} to {b} UTC"
    return text


def report_markdown(data: ReplayData, m: dict[str, Any], plot_note: str, pngs: Sequence[Path]) -> str:
    deg = math.degrees(1.0)
    lines = [f"# Replay report: {data.title}", ""]
    lines += [
        f"- vessel: {data.vessel or '–'}",
        f"- span: {_span(m)} — from the first fused measurement (t = 0 s in the tables and plots) to the "
        "last estimate",
        *(
            f"- {where}: {span} — its first to last sentence or record with a time"
            for where, span in m.get("log_spans", {}).items()
        ),
        f"- measurements: {m['measurement']['samples']} samples; metrics after a settle time of "
        f"{_fmt(m['settle_s'], 4)} s",
        f"- wave band searched: {m['wave_band_rad_s'][0]:.3g}–{m['wave_band_rad_s'][1]:.3g} rad/s "
        f"— {m['wave_band_basis']}",
        f"- ground truth: {'yes (simulator log)' if m['truth'] else 'no'}",
        "",
    ]
    said = [*m.get("checks", []), *(f"warning: {w}" for w in m.get("warnings", []))]
    if said:  # what the console said too: the report and the console agree
        lines += ["## Warnings", "", *(f"- {w}" for w in said), ""]
    lines += [
        "## Measurement: dominant wave frequency",
        "",
        "| DOF | valid samples | sample interval (s) | peak ω (rad/s) | peak period (s) | Welch segments |",
        "|---|---|---|---|---|---|",
    ]
    for k, d in enumerate(DOF):
        md = m["measurement"][d]
        edge = " (band edge: no clear wave peak)" if md["peak_at_band_edge"] else ""
        lines.append(
            f"| {DOF_SYMBOL[k]} | {md['valid']} | {_fmt(md['sample_interval_s'])} | "
            f"{_fmt(md['dominant_frequency_rad_s'])}{edge} | {_fmt(md['dominant_period_s'])} | "
            f"{md['psd_segments']} |"
        )
    units = ("N (m)", "E (m)", "ψ (deg)")
    for label, od in m["observers"].items():
        lines += ["", f"## Observer `{label}`", ""]
        head = (
            "| DOF | ω₀ in use (rad/s) | attenuation at peak (dB) | innovation mean | innovation std | "
            "innovation RMS | lag-1 autocorr. | smoothness ratio |"
        )
        sep = "|---|---|---|---|---|---|---|---|"
        if m["truth"]:
            head += " RMS error LF | mean square error LF | RMS error WF |"
            sep += "---|---|---|"
        lines += [head, sep]
        for k, d in enumerate(DOF):
            dd = od[d]
            s = deg if k == 2 else 1.0
            inn = dd["innovation"]
            row = (
                f"| {units[k]} | {_fmt(dd['omega0_median_rad_s'])} | {_signed(dd['attenuation_db'])} | "
                f"{_fmt(inn['mean'], 3, s)} | {_fmt(inn['std'], 3, s)} | {_fmt(inn['rms'], 3, s)} | "
                f"{_fmt(inn['lag1_autocorrelation'], 2)} | {_fmt(dd['smoothness']['ratio'], 2)} |"
            )
            if m["truth"]:
                row += (
                    f" {_fmt(dd['rms_error'], 3, s)} | {_fmt(dd['mean_square_error'], 3, s * s)} | "
                    f"{_fmt(dd['rms_error_wf'], 3, s)} |"
                )
            lines.append(row)
        lines.append("")
        lines.append(
            f"{od['samples']} estimates. Heading rows in degrees (mean square in deg²). Smoothness ratio = "
            "std of the LF estimate's first difference / that of the measurement (< 1: smoother)."
        )
        if od.get("truth_not_scored"):  # (the error columns are "–": the console says it in these words)
            lines += ["", f"LF estimate vs truth: {od['truth_not_scored']}."]
    if m.get("dp_performance"):
        lines += ["", *dp_section(m["dp_performance"])]
    lines += ["", "## Bad input", ""]
    if m["counts"]:
        lines += ["| source / log | counter | count |", "|---|---|---|"]
        for src, c in m["counts"].items():
            for reason, n in c.items():
                lines.append(f"| {src} | {reason} | {n} |")
    else:
        lines.append("No counts were passed to the report.")
    lines += ["", "## Plots", ""]
    if pngs:
        for p in pngs:
            lines += [f"![{p.stem}]({p.name})", ""]
    else:
        lines.append(plot_note)
    lines += ["", "Numbers: `metrics.json` (SI units, radians). Definitions: dpgw `docs/report.md`.", ""]
    return "\n".join(lines)


def wave_filtering_section(w: dict[str, Any] | None) -> list[str]:
    """What the live gateway's wave filtering kept out of its commanded thrust (`dpgw replay --report` on
    a gateway's log: the same controller fed the raw measurements, the log replayed), as a table."""
    if not w:
        return []
    if "error" in w:
        return ["", f"Wave filtering: not measured ({w['error']})."]
    lo, hi = w["band_rad_s"]
    ours, theirs, saved = w["wave_band_tau_rms"], w["raw_feedback_wave_band_tau_rms"], w["saved_db"]

    scale, k = force_prefix(max([*ours, *theirs]), mega=False)

    def kilo(values: list[float]) -> str:  # to three figures, thousands grouped
        return " | ".join(f"{x / scale:,.0f}" if x >= 100 * scale else f"{x / scale:.3g}" for x in values)

    return [
        "",
        f"| commanded τ, RMS in the wave band {lo:.2g}-{hi:.2g} rad/s "
        f"| surge ({k}N) | sway ({k}N) | yaw ({k}N·m) |",
        "|---|---|---|---|",
        f"| live (the observer's LF estimate) | {kilo(ours)} |",
        f"| the same controller fed the raw measurements | {kilo(theirs)} |",
        "| kept out by wave filtering (dB) | "
        + " | ".join("–" if d is None else f"{d:.1f}" for d in saved)
        + " |",
        "",
        *_thruster_rows(w.get("thrusters") or []),
        f"Over the longest stretch in dp ({w['scored_s']:.0f} s). The second row is the log replayed with "
        '`[control] feedback = "measurement"` (raw position and heading, a filtered derivative for the '
        "velocity: a DP system without a wave filter), open loop: its wave band is what such a system "
        "would command on this sea. The thrusters' rows are the allocation's commanded thrust per drive, "
        "within its thrust and turning rates: the wear each drive is spared.",
    ]


def _thruster_rows(drives: list[dict[str, Any]]) -> list[str]:
    """The wave-band thrust each drive was commanded, live and fed raw (the allocation within its rates)."""
    if not drives:
        return []
    scale, k = force_prefix(
        max(
            v for x in drives for v in (x["wave_band_thrust_rms_n"], x["raw_feedback_wave_band_thrust_rms_n"])
        ),
        mega=False,
    )
    unit = f"{k}N"
    return [
        f"| thruster | live, wave-band thrust RMS ({unit}) | fed the raw measurements ({unit}) "
        "| kept out (dB) |",
        "|---|---|---|---|",
        *(
            f"| {x['id']} | {x['wave_band_thrust_rms_n'] / scale:.3g} | "
            f"{x['raw_feedback_wave_band_thrust_rms_n'] / scale:.3g} | "
            + ("–" if x["saved_db"] is None else f"{x['saved_db']:.1f}")
            + " |"
            for x in drives
        ),
        "",
    ]


def dp_section(dp: dict[str, Any]) -> list[str]:
    """How DP did in the live gateway's log (`gateway.report.station_keeping`), as report.md shows it."""
    lines = ["## DP performance (the live gateway's log)", ""]
    lines += ["| mode | time (s) |", "|---|---|"]
    lines += [f"| {mode} | {t:.0f} |" for mode, t in dp["modes"]["time_s"].items()]
    spans = dp["modes"]["spans"]
    if len(spans) > 1:
        # (whole seconds by `round`, an int: a span starting a hair before the first record read "-0 s")
        lines += [
            "",
            "Mode changes: " + "; ".join(f"{round(s['from_s'])} s {s['mode']}" for s in spans) + ".",
        ]
    sk = dp["station_keeping"]
    lines.append("")
    if sk is None:
        lines.append("No DP command with an estimate before it: no station keeping to score.")
    else:
        pos, hdg = sk["position_error_m"], sk["heading_error_deg"]
        lines += [
            "| off the DP reference | p50 | p95 | max |",
            "|---|---|---|---|",
            f"| position (m) | {pos['p50']:.2f} | {pos['p95']:.2f} | {pos['max']:.2f} |",
            f"| heading (°) | {hdg['p50']:.2f} | {hdg['p95']:.2f} | {hdg['max']:.2f} |",
            "",
            f"At each of {sk['commands']} DP commands, the estimate then against the reference the command "
            f"was made for. Saturated (the allocation could not deliver τ): "
            f"{100 * sk['saturated_share']:.1f} % of them.",
        ]
    lines += wave_filtering_section(dp.get("wave_filtering"))
    dr = dp["dead_reckoning"]
    lines.append("")
    if dr["spells"]:
        lines += [
            f"Dead reckoning (no usable reference in a DOF): {dr['spells']} "
            f"spell{'s' if dr['spells'] > 1 else ''}, the longest "
            f"{dr['longest_s']:.1f} s, {dr['total_s']:.1f} s in all, {dr['in_dp_s']:.1f} s of it in dp.",
            "",
            "| from (s) | to (s) | worst | mode |",
            "|---|---|---|---|",
            *(
                f"| {s['from_s']:.1f} | {s['to_s']:.1f} | {s['worst']} | {s.get('mode', '–')} |"
                for s in dr["list"]
            ),
        ]
    else:
        lines.append("No dead reckoning: a usable reference in every DOF throughout.")
    alarms = dp["alarms"]
    lines.append("")
    if alarms:
        lines += [
            "| level | alarm (its first text) | first (s) | raised | up (s) |",
            "|---|---|---|---|---|",
            *(
                f"| {a['level']} | {a['first_text']} | {a['first_s']:.0f} | {a['raised']} | {a['up_s']:.0f} |"
                for a in alarms
            ),
        ]
    else:
        lines.append("No alarm in the gateway's statuses.")
    return lines
