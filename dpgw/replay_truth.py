"""Scoring a gateway's log against the ground truth of the simulator that fed it (`dpgw replay --truth`).

On a HIL bench the gateway and the simulator are separate processes, each writing its own log: the
gateway's holds the sentences it received (its raw channels) and its estimates, the simulator's holds the
same sentences as it sent them and the plant's truth (`/truth/state`). Replaying both logs together would
feed every sentence twice (refused: `fed_twice`); the gateway's log is replayed and the simulator's log
only lends its truth (`--truth`).

The truth is in the simulator's NED frame (its datum, in its metadata); the replay's estimates are in
the gateway's (its configured datum, or its first fix). The truth's positions are moved into the
replay's frame through latitude and longitude (`to_replay_frame`). Headings are kept: the two frames'
north differ by the meridian convergence, about 1e-5 rad for datums a kilometre apart.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gateway.replay import Input, logged_config, logged_datum, logged_sim, truth_records
from wire.geodesy import LocalFrame


def fed_twice(inputs: list[Input]) -> str | None:
    """Why replaying these logs together would feed the sensors twice, or None: a gateway's own log
    (its configuration, no simulator description) and a simulator's log (a simulator description, no
    gateway configuration) among the inputs. A `dpgw demo` log holds both in one file, and is fine."""
    # (each log's metadata read once: is it a gateway's, a simulator's)
    kinds = [
        (i.path, logged_config(i.path) is not None, logged_sim(i.path) is not None)
        for i in inputs
        if i.kind == "mcap"
    ]
    gateway = [path for path, config, sim in kinds if config and not sim]
    simulator = [path for path, config, sim in kinds if sim and not config]
    if not (gateway and simulator):
        return None
    g, s = gateway[0], simulator[0]
    return (
        f"{g} is a gateway's log and {s} a simulator's: the gateway logged the sentences it received, the "
        "simulator the ones it sent, so replaying both feeds every sentence twice. To score the gateway's "
        f"log against the simulator's ground truth: dpgw replay {g} --truth {s}"
    )


def truth_log_problem(path: Path) -> str | None:
    """What is wrong with ``path`` as a --truth log, or None."""
    if not path.is_file():
        return f"--truth {path}: no such file"
    if logged_sim(path) is None:
        return f"--truth {path}: not a simulator log (no dpgw.sim metadata): give the log of dpgw sim --out"
    if logged_datum(path) is None:
        return f"--truth {path}: the log does not say which datum its truth is in (written by an older dpgw)"
    return None


def to_replay_frame(path: Path, frame: LocalFrame) -> list[dict[str, Any]]:
    """The truth records of the simulator log ``path`` with their LF positions (``eta_lf`` north, east) in
    ``frame``, the replay's NED frame; heading and the wave-frequency motion as they are."""
    datum = logged_datum(path)
    assert datum is not None  # (`truth_log_problem` first)
    sim = LocalFrame(datum["lat_deg"], datum["lon_deg"], datum["alt_m"])
    same = (sim.lat_deg, sim.lon_deg, sim.alt_m) == (frame.lat_deg, frame.lon_deg, frame.alt_m)
    out = []
    for rec in truth_records(path):
        if not same:
            n, e, psi = rec["eta_lf"]
            lat, lon, h = sim.to_geodetic(n, e, 0.0)
            n2, e2, _ = frame.to_ned(lat, lon, h)
            rec = {**rec, "eta_lf": [n2, e2, psi]}
        out.append(rec)
    return out


def span_overlap_s(truth: list[dict[str, Any]], first_ns: int, last_ns: int) -> float:
    """Seconds of the replayed log's span [first_ns, last_ns] that the truth covers."""
    if not truth:
        return 0.0
    a = max(first_ns, int(truth[0]["stamp_ns"]))
    b = min(last_ns, int(truth[-1]["stamp_ns"]))
    return max(0.0, (b - a) / 1e9)


MISMATCH_M = 10.0
"""A truth whose position lies further than this (median, m) from the log's own measurements is not this
log's: position references at sea are off by metres at worst, after their lever arms."""

STEADY_SPREAD_M = 3.0
"""An offset whose 90th percentile spread about its mean (in the vessel's frame) is within this, or a
quarter of the offset, is steady: a lever arm or a datum, not another run (a position reference's noise
and the wave motion the truth's LF + WF leaves spread it by a metre or two)."""

MISMATCH_DEG = 10.0
"""The same for the heading (median, degrees): a gyro is off by a degree or two at worst."""


def truth_mismatch(
    stamps_ns: list[int], measured: list[list[float | None]], truth: list[dict[str, Any]]
) -> dict[str, Any] | None:
    """How far the truth (LF + WF motion, in the replay's frame) lies from the log's fused measurements
    (``stamps_ns``, ``measured`` [N, E, ψ] with None where not measured) at the same times: the medians of
    the horizontal distance (m) and of the heading difference (deg), when either is beyond `MISMATCH_M` or
    `MISMATCH_DEG`; else None. The simulator log of another run (another seed, scenario or start) gives
    errors of hundreds of metres that would otherwise be printed as the observers' own."""
    import numpy as np

    from gateway.scoring import truth_at
    from observers.kinematics import ssa

    if not truth or not stamps_ns:
        return None
    tt = np.array([r["stamp_ns"] for r in truth], dtype=np.int64)
    total = np.array([r["eta_lf"] for r in truth], dtype=float) + np.nan_to_num(
        np.array([r.get("eta_wf") or [0.0, 0.0, 0.0] for r in truth], dtype=float)
    )
    y = np.array([[np.nan if v is None else v for v in e] for e in measured], dtype=float).reshape(-1, 3)
    at = truth_at(
        (np.array(stamps_ns, dtype=np.int64) - tt[0]) / 1e9, (tt - tt[0]) / 1e9, total
    )  # NaN outside
    dist = np.hypot(y[:, 0] - at[:, 0], y[:, 1] - at[:, 1])
    dpsi = np.degrees(np.abs(ssa(y[:, 2] - at[:, 2])))
    d = float(np.nanmedian(dist)) if np.isfinite(dist).any() else 0.0
    h = float(np.nanmedian(dpsi)) if np.isfinite(dpsi).any() else 0.0
    if d <= MISMATCH_M and h <= MISMATCH_DEG:
        return None
    out: dict[str, Any] = {"median_position_m": d, "median_heading_deg": h}
    # Another run's truth wanders from the log's fixes by tens to hundreds of metres; the same run seen
    # through a wrong lever arm (or datum) sits a steady offset off, fixed in the vessel's frame: the
    # measured reference point is the antenna less the config's arm, the truth's the antenna less the
    # true one. So a steady offset is said as the arm that would explain it, not as "another run".
    ok = np.isfinite(dist) & np.isfinite(y[:, 2])
    if h <= MISMATCH_DEG and np.count_nonzero(ok) >= 10:
        dn, de, psi = y[ok, 0] - at[ok, 0], y[ok, 1] - at[ok, 1], y[ok, 2]
        body = np.column_stack([np.cos(psi) * dn + np.sin(psi) * de, -np.sin(psi) * dn + np.cos(psi) * de])
        mean = body.mean(axis=0)
        spread = float(np.percentile(np.hypot(*(body - mean).T), 90))
        if spread <= max(STEADY_SPREAD_M, 0.25 * float(np.hypot(*mean))):
            out["steady_offset_body_m"] = [float(mean[0]), float(mean[1])]
    return out
