"""The report's input: one observer's estimates, a replay's measurements and truth; checked and sorted.

`ObserverTrace` and `ReplayData` are what a caller hands to `compute_metrics` / `write_report`; `prepare`
turns them into float arrays of checked shapes, sorted by time, which every other part of the report reads.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

DOF = ("north", "east", "heading")
DOF_SYMBOL = ("N", "E", "ψ")


@dataclass(frozen=True)
class ObserverTrace:
    """One observer's estimates; arrays (n,) or (n, 3), SI units and radians."""

    label: str  # e.g. "passive", "passive_T9"
    t: NDArray[Any]  # seconds since the replay's start
    eta: NDArray[Any]  # LF estimate [N, E, ψ]
    nu: NDArray[Any]  # [u, v, r]
    bias: NDArray[Any]  # earth-fixed bias [X, Y, N] (N, N, N·m)
    eta_wf: NDArray[Any]  # WF estimate [N, E, ψ]
    omega0: NDArray[Any]  # wave frequency in use per DOF (rad/s); constant for a fixed-gain observer
    observer: str = ""  # its name in `--observer NAME:...` (passive, gain_scheduled, ...); "" not known


@dataclass(frozen=True)
class ThrustTrace:
    """The commanded τ over a stretch in dp, live and from the same controller fed the raw measurements
    (`dpgw.raw_feedback`): times (n,) in s on the report's axis, τ (n, 3) as [X N, Y N, N N·m]."""

    t: NDArray[Any]
    tau: NDArray[Any]
    t_raw: NDArray[Any]
    tau_raw: NDArray[Any]
    band_rad_s: tuple[float, float]


@dataclass(frozen=True)
class ReplayData:
    """Everything a replay report shows."""

    title: str  # e.g. log file name(s)
    vessel: str
    t_meas: NDArray[Any]  # (m,) measurement times, s
    y: NDArray[Any]  # (m, 3) measurements [N, E, ψ], NaN where missing
    traces: tuple[ObserverTrace, ...]
    truth_t: NDArray[Any] | None = None  # simulator logs: /truth/state
    truth_eta_lf: NDArray[Any] | None = None
    truth_eta_wf: NDArray[Any] | None = None
    # per source {"received": n, "<reject reason>": n, "warning <reason>": n, ...};
    # per input log {"truncated": n, "time_gap": n, "time_backwards": n, ...}
    counts: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    # UTC of t = 0 (ns since the Unix epoch), where the log's stamps are UTC: the report then says when
    # (a merge of logs over days is read by date and clock time, not by hours since its start)
    start_ns: int | None = None
    # the lines the replay's console printed of its wave-tuning check (`gateway.report.wave_check`: a
    # mistuned observer, or no clear wave peak to check against), shown in report.md as they were said
    checks: tuple[str, ...] = ()
    # the vessel's length (m) and Froude scale as the replay loaded it (a user's vessel file is known by
    # its name only, which no lookup finds again); None: looked up from `vessel` (a built-in's name or a
    # vessel file's path)
    vessel_length_m: float | None = None
    vessel_model_scale: float | None = None
    # per input log, what it covers as the console's summary says it (first to last sentence or record
    # with a time, UTC): it can start before the first fused measurement, which is t = 0 here
    log_spans: Mapping[str, str] = field(default_factory=dict)
    # the least sea after the settle time an estimate is scored against the truth on (s); a shorter stretch
    # is "not scored", said in report.md (`gateway.scoring.not_scored_note`). `dpgw replay` gives the one
    # a `dpgw demo` log records, so that a demo stopped soon after its skip is not given a figure here
    # either; None: any stretch is scored
    min_scored_s: float | None = None
    # how DP did in the live gateway's log (`gateway.report.station_keeping.dp_performance`, times from
    # t = 0 here); None: not a gateway's log
    dp_performance: Mapping[str, Any] | None = None
    # the commanded τ live and fed the raw measurements (`dpgw replay --report` on a gateway's log with a
    # stretch in dp): plotted as thrust.png; None: no such figure
    thrust: ThrustTrace | None = None


def force_prefix(largest: float, least: float = 1.0, *, mega: bool = True) -> tuple[float, str]:
    """The divisor and SI prefix a force (N) or moment (N·m) of size ``largest`` reads best in: k from
    ``least`` kN on, M from ``least`` MN on (unless not ``mega``), else none: a supply vessel's thrust is
    tens of kN, its yaw moment MN·m, a basin model's thrust fractions of a newton. A plot's axis takes
    ``least`` = 10 (no "1.2 k" ticks), a table one prefix for its columns (``mega`` False), a sentence
    each value by itself."""
    x = abs(largest)
    if mega and x >= least * 1e6:
        return 1e6, "M"
    return (1e3, "k") if x >= least * 1e3 else (1.0, "")


def utc_text(start_ns: int, t_s: float | None, *, digits: int = 1) -> str | None:
    """The UTC instant ``t_s`` seconds after ``start_ns`` in ISO 8601 (``2024-12-05T10:37:12.4Z``), or
    None for a missing time."""
    if t_s is None or not math.isfinite(t_s):
        return None
    unit = 10**digits  # rounded as a whole (12.96 s is 13.0, not 12.10)
    whole, frac = divmod(round((start_ns / 1e9 + float(t_s)) * unit), unit)
    text = datetime.fromtimestamp(whole, tz=UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return text + (f".{frac:0{digits}d}" if digits else "") + "Z"


def _col3(a: NDArray[Any] | None, n: int) -> Array:
    """An (n, 3) float array from (n, 3) or (n,) (broadcast to the three DOFs); NaN if missing."""
    if a is None:
        return np.full((n, 3), np.nan)
    x = np.asarray(a, dtype=float)
    if x.ndim == 1:
        x = np.repeat(x[:, None], 3, axis=1)
    if x.shape != (n, 3):
        raise ValueError(f"expected an array of shape ({n}, 3) or ({n},), got {x.shape}")
    return x


@dataclass(frozen=True)
class PreparedTrace:
    """One `ObserverTrace` as (n, 3) float arrays (an (n,) input broadcast to the three DOFs), sorted by
    time."""

    label: str
    t: Array
    eta: Array
    nu: Array
    bias: Array
    eta_wf: Array
    omega0: Array
    observer: str = ""  # `ObserverTrace.observer`


@dataclass(frozen=True)
class Prepared:
    """The report's inputs as float arrays of checked shapes, sorted by time."""

    t_meas: Array
    y: Array
    traces: list[PreparedTrace]
    truth: tuple[Array, Array, Array | None] | None  # t, η_LF, η_WF


def prepare(data: ReplayData) -> Prepared:
    """Check the shapes and sort every record by time (stable: equal times keep their order)."""
    t_meas = np.asarray(data.t_meas, dtype=float).reshape(-1)
    o = np.argsort(t_meas, kind="stable")
    y = _col3(data.y, len(t_meas))[o]
    traces = []
    for tr in data.traces:
        t = np.asarray(tr.t, dtype=float).reshape(-1)
        n = len(t)
        oo = np.argsort(t, kind="stable")
        eta, nu, bias, eta_wf, omega0 = (
            _col3(a, n)[oo] for a in (tr.eta, tr.nu, tr.bias, tr.eta_wf, tr.omega0)
        )
        traces.append(PreparedTrace(str(tr.label), t[oo], eta, nu, bias, eta_wf, omega0, tr.observer))
    truth = None
    if data.truth_t is not None and data.truth_eta_lf is not None and len(data.truth_t) > 1:
        tt = np.asarray(data.truth_t, dtype=float).reshape(-1)
        to = np.argsort(tt, kind="stable")
        wf = _col3(data.truth_eta_wf, len(tt))[to] if data.truth_eta_wf is not None else None
        truth = (tt[to], _col3(data.truth_eta_lf, len(tt))[to], wf)
    return Prepared(t_meas[o], y, traces, truth)
