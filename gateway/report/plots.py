"""The report's plots in the style of the papers' figures (Fossen & Strand 1999, Figs. 9-14; Torsetnes et
al. 2004, Figs. 3-8): measurement against LF and WF estimates per DOF, velocities, bias, the wave frequency in
use and the power spectra.

matplotlib (a dependency) is imported only when a report draws (`load_figure`), so
importing the report, or writing one without plots, never needs it. `decimate` has no matplotlib in it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gateway.report.data import DOF_SYMBOL, Array, ReplayData, force_prefix, utc_text
from gateway.report.metrics import MAX_GAP_SAMPLES, Analysis
from gateway.report.spectra import nominal_dt
from observers.kinematics import ssa

# Each plotted line is decimated to at most this many points (its envelope kept).
MAX_PLOT_POINTS = 20_000

_RAW_FED: dict[str, Any] = {
    "color": "tab:red",
    "lw": 0.7,
    "alpha": 0.8,
    "zorder": 10,
    "label": "the same controller fed the raw measurements (replayed)",
}
_LIVE_THRUST: dict[str, Any] = {
    "color": "black",
    "lw": 1.0,
    "zorder": 20,
    "label": "live (on the LF estimate)",
}
_COLOURS = ("black", "tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange", "tab:brown", "tab:cyan")
_MEAS: dict[str, Any] = {"color": "0.70", "lw": 0.8}
_TRUTH: dict[str, Any] = {"color": "0.35", "lw": 1.0, "ls": "--", "zorder": 50}


def zoom_window(t_beg: float, t_end: float, peaks_rad_s: Any) -> tuple[float, float] | None:
    """The zoom row's window (Torsetnes et al. Figs. 7-8): the last 20 dominant wave periods of the record,
    at least 60 s; None (no zoom row) unless the record is at least twice as long, since a zoom on most of
    the record shows nothing the first row does not."""
    peaks = [w for w in peaks_rad_s if math.isfinite(w) and w > 0]
    length = max(20.0 * 2.0 * math.pi / float(np.median(peaks)) if peaks else 0.0, 60.0)
    if t_end - t_beg < 2.0 * length:
        return None
    return (t_end - length, t_end)


def measured_line(t: Array, x: Array) -> tuple[Array, Array]:
    """A measured DOF as a line: its valid samples joined, broken (a NaN) only where a gap is longer than
    the metrics bridge (`MAX_GAP_SAMPLES` nominal intervals). A DOF measured at a fifth of the stream's
    rate (a fix among headings; the other samples NaN) would otherwise be isolated points, drawn as
    nothing."""
    ok = np.isfinite(x)
    t, x = np.asarray(t, dtype=float)[ok], np.asarray(x, dtype=float)[ok]
    if len(t) < 2:
        return t, x
    gaps = np.flatnonzero(np.diff(t) > MAX_GAP_SAMPLES * nominal_dt(t)) + 1
    # the break at the gap's middle (a time, so that a zoom window keeps it)
    return np.insert(t, gaps, 0.5 * (t[gaps - 1] + t[gaps])), np.insert(x, gaps, np.nan)


def broken_at_gaps(t: Array, x: Array) -> tuple[Array, Array]:
    """An estimate's line broken (a NaN) where its samples are farther apart than the metrics bridge,
    as `measured_line` breaks a measurement's: logs merged across hours or days (two days of a USV's
    trials) were otherwise joined by a straight line through the days nobody measured, drawn as if the
    vessel had moved along it."""
    t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    if len(t) < 3:
        return t, x
    gaps = np.flatnonzero(np.diff(t) > MAX_GAP_SAMPLES * nominal_dt(t)) + 1
    if len(gaps) == 0:
        return t, x
    return np.insert(t, gaps, 0.5 * (t[gaps - 1] + t[gaps])), np.insert(x, gaps, np.nan, axis=0)


def decimate(t: NDArray[Any], x: NDArray[Any], max_points: int = MAX_PLOT_POINTS) -> tuple[Array, Array]:
    """At most `max_points` points of a line that keep its envelope: the min and max of each bucket, in
    time order. NaN (gaps) survive where a whole bucket is NaN, so lines still break there."""
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = len(t)
    if n <= max_points:
        return t, x
    b = math.ceil(n / (max_points // 2))
    m = math.ceil(n / b)
    pad = m * b - n
    xp = np.concatenate([x, np.full(pad, np.nan)]).reshape(m, b)
    finite = np.isfinite(xp)
    any_f = finite.any(axis=1)
    imin = np.argmin(np.where(finite, xp, np.inf), axis=1)
    imax = np.argmax(np.where(finite, xp, -np.inf), axis=1)
    lo = np.minimum(imin, imax) + b * np.arange(m)
    hi = np.maximum(imin, imax) + b * np.arange(m)
    idx = np.column_stack([lo, hi]).reshape(-1)
    idx = np.minimum(idx, n - 1)
    xs = x[idx].copy()
    xs[np.repeat(~any_f, 2)] = np.nan
    return t[idx], xs


def _heading_deg(t: Array, psi: Array, centre: float) -> tuple[Array, Array]:
    """Heading in degrees within ±180° of `centre` (rad), with a break (NaN) where it wraps."""
    d = np.degrees(centre + ssa(psi - centre))
    jumps = np.flatnonzero(np.abs(np.diff(d)) > 180.0) + 1
    if len(jumps):
        d = np.insert(d, jumps, np.nan)
        t = np.insert(t, jumps, np.nan)
    return t, d


def _time_scale(duration: float) -> tuple[float, str]:
    if duration > 10 * 3600:
        return 3600.0, "time (h)"
    if duration > 600:
        return 60.0, "time (min)"
    return 1.0, "time (s)"


def _clock_text(start_ns: int, t_s: float) -> str:
    """``2024-12-05 10:37:12 UTC``: the instant ``t_s`` after ``start_ns``, for an axis label."""
    text = utc_text(start_ns, t_s, digits=0) or ""
    return text.replace("T", " ").removesuffix("Z") + " UTC"


def load_figure() -> Any:
    """matplotlib's Figure class, or None if matplotlib is not installed. No pyplot: no global state,
    safe in threads; PNGs are drawn by the Agg canvas."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return None
    return Figure


def draw_plots(data: ReplayData, an: Analysis, folder: Path, Figure: Any) -> list[Path]:
    """The PNGs of docs/report.md into `folder`, drawn with matplotlib's `Figure` class (from
    `load_figure`); returns their paths in the order position, wave, velocity, bias, omega0, psd, and
    thrust when ``data.thrust`` is given."""
    prep = an.prep
    t_meas, y, traces, truth = prep.t_meas, prep.y, prep.traces, prep.truth
    span = an.metrics["span_s"]
    scale, tlabel = _time_scale((span[1] or 0.0) - (span[0] or 0.0))
    if data.start_ns is not None:  # the axis counts from the log's start: say when that was
        tlabel += f" from {_clock_text(data.start_ns, 0.0)}"
    # heading plotted around the circular mean of the measured (else estimated) heading
    psi_ref = y[:, 2][np.isfinite(y[:, 2])]
    if len(psi_ref) == 0 and traces and len(traces[0].t):
        psi_ref = traces[0].eta[:, 2][np.isfinite(traces[0].eta[:, 2])]
    centre = float(np.arctan2(np.mean(np.sin(psi_ref)), np.mean(np.cos(psi_ref)))) if len(psi_ref) else 0.0
    suptitle = f"{data.title} — {data.vessel}" if data.vessel else data.title

    t_end = span[1] or 0.0
    t_beg = span[0] or 0.0
    measured = an.metrics["measurement"]
    at_edge = [bool(measured[dof]["peak_at_band_edge"]) for dof in ("north", "east", "heading")]
    window = zoom_window(t_beg, t_end, [w for w, edge in zip(an.meas_peak, at_edge, strict=True) if not edge])
    use_zoom = window is not None
    zoom = window or (t_beg, t_end)
    # the zoom rows count seconds from the window's start (a long log's hours would read "48.9825 h")
    zoom_start = _clock_text(data.start_ns, zoom[0]) if data.start_ns is not None else f"t = {zoom[0]:.1f} s"
    zoom_label = f"time (s) from {zoom_start}"

    def figure(name: str, rows: int = 1) -> tuple[Any, Any]:
        fig = Figure(figsize=(15.0, 0.6 + 3.6 * rows), layout="constrained")
        axes = fig.subplots(rows, 3, squeeze=False, sharex="row" if name != "psd" else False)
        fig.suptitle(f"{suptitle}: {name}", fontsize=11)
        for ax in axes.flat:
            ax.grid(True, color="0.9", lw=0.6)
            ax.tick_params(labelsize=8)
        return fig, axes

    def line(
        ax: Any,
        t: Array,
        x: Array,
        *,
        deg: bool = False,
        wrap: bool = False,
        window: tuple[float, float] | None = None,
        **kw: Any,
    ) -> None:
        if window is not None:
            m = (t >= window[0]) & (t <= window[1])
            t, x = t[m], x[m]
        if len(t) == 0:
            return
        t, x = broken_at_gaps(t, x)  # (a measurement's line is broken already: it has no such gap left)
        if wrap:
            t, x = _heading_deg(t, x, centre)
        elif deg:
            x = np.degrees(x)
        td, xd = decimate(t, x)
        if window is not None:  # a zoom row: seconds from the window's start, whatever the log's length
            ax.plot(td - window[0], xd, **kw)
        else:
            ax.plot(td / scale, xd, **kw)

    def colour(i: int) -> str:
        return _COLOURS[i % len(_COLOURS)]

    def z(i: int) -> float:
        """The first observer (black) is drawn on top of the others, as in the papers."""
        return 40.0 - i * 30.0 / max(len(traces), 1)

    def save(fig: Any, axes: Any, name: str, zoom_text: str | None = None) -> Path:
        for r, row in enumerate(axes):
            label = "frequency ω (rad/s)" if name == "psd" else (zoom_text or zoom_label) if r else tlabel
            for ax in row:
                ax.set_xlabel(label, fontsize=9)
        # every label of the first row once (a line drawn in one panel only still gets its entry)
        found: dict[str, Any] = {}
        for ax in axes[0]:
            for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
                found.setdefault(label, handle)
        handles, labels = list(found.values()), list(found)
        if handles:
            fig.legend(handles, labels, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
        path = folder / f"{name}.png"
        fig.savefig(path, dpi=100)
        return path

    def mark_zoom(axes: Any) -> None:
        for ax in axes[0]:
            ax.axvspan(zoom[0] / scale, zoom[1] / scale, color="tab:olive", alpha=0.12, lw=0, zorder=0)
        for ax in axes[1]:
            ax.set_title(f"zoom: last {zoom[1] - zoom[0]:.0f} s", fontsize=8, loc="right")

    written = []
    rows = 2 if use_zoom else 1
    windows: list[tuple[float, float] | None] = [None, zoom] if use_zoom else [None]

    # 1. position: measurement, LF estimates, true LF motion (Fossen & Strand Figs. 13-14)
    pos_units = ("north (m)", "east (m)", "heading ψ (deg)")
    fig, axes = figure("position", rows)
    for r, win in enumerate(windows):
        for k, ax in enumerate(axes[r]):
            line(ax, *measured_line(t_meas, y[:, k]), wrap=k == 2, window=win, label="measurement y", **_MEAS)
            if truth is not None:
                line(ax, truth[0], truth[1][:, k], wrap=k == 2, window=win, label="true LF η", **_TRUTH)
            for i, tr_ in enumerate(traces):
                lab = f"η̂ {tr_.label}"
                kw: dict[str, Any] = {"color": colour(i), "lw": 1.0, "zorder": z(i), "label": lab}
                line(ax, tr_.t, tr_.eta[:, k], wrap=k == 2, window=win, **kw)
            ax.set_ylabel(pos_units[k], fontsize=9)
            if r == 0:
                ax.set_title(f"{DOF_SYMBOL[k]}: measurement and LF estimate", fontsize=9)
    if use_zoom:
        mark_zoom(axes)
    written.append(save(fig, axes, "position"))

    # 2. wave: WF estimates on the true WF motion (grey, as in Fossen & Strand Figs. 9-11)
    wf_units = ("north η_w (m)", "east η_w (m)", "heading ψ_w (deg)")
    fig, axes = figure("wave", rows)
    for r, win in enumerate(windows):
        for k, ax in enumerate(axes[r]):
            if truth is not None and truth[2] is not None:
                kw_t: dict[str, Any] = {"color": "0.6", "lw": 1.2, "zorder": 1, "label": "true WF η_w"}
                line(ax, truth[0], truth[2][:, k], deg=k == 2, window=win, **kw_t)
            for i, tr_ in enumerate(traces):
                kw_w: dict[str, Any] = {
                    "color": colour(i),
                    "lw": 0.8,
                    "zorder": z(i),
                    "label": f"η̂_w {tr_.label}",
                }
                line(ax, tr_.t, tr_.eta_wf[:, k], deg=k == 2, window=win, **kw_w)
            ax.set_ylabel(wf_units[k], fontsize=9)
            if r == 0:
                ax.set_title(f"{DOF_SYMBOL[k]}: WF estimate", fontsize=9)
    if use_zoom:
        mark_zoom(axes)
    written.append(save(fig, axes, "wave"))

    # 3. velocity
    fig, axes = figure("velocity")
    vel_units = ("surge u (m/s)", "sway v (m/s)", "yaw rate r (deg/s)")
    for k, ax in enumerate(axes[0]):
        for i, tr_ in enumerate(traces):
            line(
                ax,
                tr_.t,
                tr_.nu[:, k],
                deg=k == 2,
                color=colour(i),
                lw=1.0,
                zorder=z(i),
                label=f"ν̂ {tr_.label}",
            )
        ax.set_ylabel(vel_units[k], fontsize=9)
        ax.set_title(("u", "v", "r")[k] + ": velocity estimate", fontsize=9)
    written.append(save(fig, axes, "velocity"))

    # 4. bias (kN / MN when large)
    fig, axes = figure("bias")
    for k, ax in enumerate(axes[0]):
        div, prefix = force_prefix(
            max((float(np.nanmax(np.abs(tr_.bias[:, k]), initial=0.0)) for tr_ in traces), default=0.0), 10.0
        )
        for i, tr_ in enumerate(traces):
            td, xd = decimate(*broken_at_gaps(tr_.t, tr_.bias[:, k] / div))
            ax.plot(td / scale, xd, color=colour(i), lw=1.0, zorder=z(i), label=f"b̂ {tr_.label}")
        unit = f"{prefix}N·m" if k == 2 else f"{prefix}N"
        ax.set_ylabel(f"{('X', 'Y', 'N')[k]} ({unit})", fontsize=9)
        ax.set_title(f"{('X', 'Y', 'N')[k]}: bias estimate (earth-fixed)", fontsize=9)
    written.append(save(fig, axes, "bias"))

    # 5. omega0: wave frequency in use, and the measurement's spectral peak
    fig, axes = figure("omega0")
    for k, ax in enumerate(axes[0]):
        for i, tr_ in enumerate(traces):
            td, xd = decimate(*broken_at_gaps(tr_.t, tr_.omega0[:, k]))
            ax.plot(td / scale, xd, color=colour(i), lw=1.2, zorder=z(i), label=f"ω₀ {tr_.label}")
        if math.isfinite(an.meas_peak[k]) and not at_edge[k]:  # a maximum on the band edge is no wave
            ax.axhline(an.meas_peak[k], color="0.5", ls="--", lw=1.0, label="PSD peak of y")
        ax.set_ylabel("ω₀ (rad/s)", fontsize=9)
        ax.set_title(f"{DOF_SYMBOL[k]}: wave frequency in use", fontsize=9)
    written.append(save(fig, axes, "omega0"))

    # 6. psd: measurement vs LF estimate, wave band shaded, attenuation annotated
    fig, axes = figure("psd")
    psd_units = ("PSD north (m²·s/rad)", "PSD east (m²·s/rad)", "PSD heading (deg²·s/rad)")
    for k, ax in enumerate(axes[0]):
        conv = math.degrees(1.0) ** 2 if k == 2 else 1.0
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axvspan(an.band[0], an.band[1], color="0.93", zorder=0, label="wave band searched")
        drawn = False
        pm = an.meas_psd[k]
        # (only what a log axis can show: a DOF that never moved, a bench's fixed position, has a PSD of
        # zeros, which matplotlib warned about on the console at every such report)
        if pm is not None and np.any(m := (pm.omega > 0) & (pm.psd > 0)):
            ax.plot(pm.omega[m], pm.psd[m] * conv, label="measurement y", **_MEAS, zorder=45)
            drawn = True
        notes = []
        for i, tr_ in enumerate(traces):
            pe = an.est_psd[i][k]
            if pe is not None and np.any(m := (pe.omega > 0) & (pe.psd > 0)):
                ax.plot(
                    pe.omega[m],
                    pe.psd[m] * conv,
                    color=colour(i),
                    lw=1.0,
                    zorder=z(i),
                    label=f"η̂ {tr_.label}",
                )
                drawn = True
            a = an.attenuation[i][k]
            notes.append(f"{tr_.label}: {a:+.1f} dB" if math.isfinite(a) else f"{tr_.label}: –")
        wp = an.meas_peak[k]
        if math.isfinite(wp) and at_edge[k]:
            notes.insert(0, f"no clear wave peak (largest at the band edge, {wp:.3g} rad/s)")
        elif math.isfinite(wp):
            ax.axvline(wp, color="0.4", ls=":", lw=1.0)
            notes.insert(0, f"peak ω = {wp:.3g} rad/s (T = {2 * math.pi / wp:.3g} s)")
        if notes:
            ax.text(
                0.02,
                0.03,
                "\n".join(notes),
                transform=ax.transAxes,
                ha="left",
                va="bottom",
                fontsize=8,
                zorder=100,
                bbox={"facecolor": "white", "edgecolor": "0.8", "alpha": 0.85},
            )
        if not drawn:
            ax.set_xlim(an.band[0] / 10.0, an.band[1] * 2.0)
        ax.set_ylabel(psd_units[k], fontsize=9)
        ax.set_title(f"{DOF_SYMBOL[k]}: PSD, attenuation at the wave peak", fontsize=9)
    written.append(save(fig, axes, "psd"))

    # 7. thrust: the commanded τ live and fed the raw measurements (what wave filtering kept out)
    th = data.thrust
    if th is not None and len(th.t) and len(th.t_raw):
        lo, hi = th.band_rad_s
        # the zoom: the stretch's last six periods of the band's lower edge (~2 min for a ship)
        length = min(6.0 * 2.0 * math.pi / lo, float(th.t[-1] - th.t[0]))
        z_win = (float(th.t[-1]) - length, float(th.t[-1]))
        z_start = (
            _clock_text(data.start_ns, z_win[0]) if data.start_ns is not None else f"t = {z_win[0]:.1f} s"
        )
        div, prefix = force_prefix(float(np.nanmax(np.abs(th.tau_raw), initial=0.0)), 10.0)
        fig, axes = figure("thrust", 2)
        saved = (data.dp_performance or {}).get("wave_filtering") or {}
        for r, win in enumerate([None, z_win]):
            for k, ax in enumerate(axes[r]):
                for t_, tau_, style in (
                    (th.t_raw, th.tau_raw, _RAW_FED),  # under the live line
                    (th.t, th.tau, _LIVE_THRUST),
                ):
                    line(ax, t_, tau_[:, k] / div, window=win, **style)
                unit = f"{prefix}N·m" if k == 2 else f"{prefix}N"
                ax.set_ylabel(f"commanded {('X', 'Y', 'N')[k]} ({unit})", fontsize=9)
                if r == 0:
                    db = saved.get("saved_db")
                    gain = (
                        f": {db[k]:.0f} dB less in {lo:.2g}-{hi:.2g} rad/s"
                        if db and db[k] is not None
                        else ""
                    )
                    ax.set_title(f"{('surge', 'sway', 'yaw')[k]} τ{gain}", fontsize=9)
                    ax.axvspan(
                        z_win[0] / scale, z_win[1] / scale, color="tab:olive", alpha=0.12, lw=0, zorder=0
                    )
                else:
                    ax.set_title(f"zoom: last {length:.0f} s in dp", fontsize=8, loc="right")
        written.append(save(fig, axes, "thrust", f"time (s) from {z_start}"))
    return written
