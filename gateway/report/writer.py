"""The report's files: `write_report` writes metrics.json, report.md and the PNGs into a folder."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from gateway.report.data import ReplayData
from gateway.report.markdown import report_markdown
from gateway.report.metrics import Analysis, analyse
from gateway.report.plots import draw_plots, load_figure


def _json_clean(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _json_clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_clean(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


# matplotlib is a dependency of dpgw; an install without it (a trimmed environment, a vendored copy) still
# gets the metrics and the table, and this note (in report.md, and on the console from `dpgw replay`).
NO_MATPLOTLIB = "Plots were not drawn: matplotlib is not installed. Install it with `pip install matplotlib`."


def write_report(
    data: ReplayData,
    folder: str | Path,
    *,
    plots: bool = True,
    wave_band: tuple[float, float] | None = None,
    settle_s: float | None = None,
) -> list[Path]:
    """Write metrics.json, report.md and (with matplotlib, if `plots`) the six PNGs into `folder`
    (created if needed). Returns the files written."""
    return write_analysis(data, analyse(data, wave_band, settle_s), folder, plots=plots)


def write_analysis(data: ReplayData, an: Analysis, folder: str | Path, *, plots: bool = True) -> list[Path]:
    """`write_report` of an analysis already made (`metrics.analyse`): a caller that also says what the
    report found (its ``warnings``) on the console analyses once."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    pngs: list[Path] = []
    if not plots:
        note = "Plots were not requested (`plots=False`)."
    else:
        Figure = load_figure()
        if Figure is None:
            note = NO_MATPLOTLIB
        else:
            note = ""
            pngs = draw_plots(data, an, out, Figure)
    metrics_path = out / "metrics.json"
    metrics_path.write_text(json.dumps(_json_clean(an.metrics), indent=2, ensure_ascii=False) + "\n")
    report_path = out / "report.md"
    report_path.write_text(report_markdown(data, an.metrics, note, pngs), encoding="utf-8")
    return [metrics_path, report_path, *pngs]
