"""How DP did in a gateway's log: the mode timeline, station keeping against the DP reference, the time
on a dead-reckoned estimate, and the alarms — what a DP engineer reads first after a trial.

From what the live gateway logged (its `/dp/thrusters/command`, `/dp/estimate` and `/dp/status`), not
from a replay's recomputed estimates: the trial as it happened, whichever observer a replay compares.

- **Modes**: from the statuses (the gateway's mode at each, 1 Hz and at once on a change), else from the
  commands (sent in dp and manual only); spans and the time in each.
- **Station keeping** in dp: at each command, the position and heading of the estimate then (the last
  estimate at or before the command) against the reference η_d the command was made for (the
  controller's error η̃; the vessel following a setpoint move is not off station): p50, p95 and the
  largest; and the share of commands the allocation could not deliver (saturated).
- **Dead reckoning**: the spells of estimates whose status was `dead_reckoning` or `lost` (no usable
  reference in a DOF): how many, the longest, the total, and how much of it in dp.
- **Alarms**: each alarm by its key (`gateway.alarms.alarm_key`: the text with its figures masked), how
  often it was raised, how long it was up (the time between the statuses that listed it), its level
  and its first text.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from gateway.alarms import alarm_key, alarm_level
from gateway.foxglove_channels import alarm_text

NS = 1_000_000_000
DEAD_RECKONED = ("dead_reckoning", "lost")


def dp_performance(
    commands: Iterable[Mapping[str, Any]],
    estimates: Iterable[Mapping[str, Any]],
    statuses: Iterable[Mapping[str, Any]],
    start_ns: int,
) -> dict[str, Any] | None:
    """The DP performance of a log (module docstring); times in s from ``start_ns``. None when the log
    holds neither a command nor a status (not a gateway's log: a simulator's, a text log)."""
    cmd = sorted(commands, key=lambda c: int(c["stamp_ns"]))
    st = sorted(statuses, key=lambda s: int(s["stamp_ns"]))
    if not cmd and not st:
        return None
    est = sorted(estimates, key=lambda e: int(e["stamp_ns"]))
    return {
        "modes": _modes(st, cmd, start_ns),
        "station_keeping": _station_keeping(cmd, est),
        "dead_reckoning": _dead_reckoning(est, st, start_ns),
        "alarms": _alarms(st, start_ns),
    }


def _modes(st: list[Mapping[str, Any]], cmd: list[Mapping[str, Any]], start_ns: int) -> dict[str, Any]:
    stream = st if st else cmd
    spans: list[dict[str, Any]] = []
    for rec in stream:
        t = (int(rec["stamp_ns"]) - start_ns) / NS
        mode = str(rec.get("mode") or "standby")
        if spans and spans[-1]["mode"] == mode:
            spans[-1]["to_s"] = t
        else:
            if spans:
                spans[-1]["to_s"] = t
            spans.append({"mode": mode, "from_s": t, "to_s": t})
    time_in: dict[str, float] = {}
    for s in spans:
        time_in[s["mode"]] = time_in.get(s["mode"], 0.0) + s["to_s"] - s["from_s"]
    return {"from": "statuses" if st else "commands", "spans": spans, "time_s": time_in}


def _station_keeping(cmd: list[Mapping[str, Any]], est: list[Mapping[str, Any]]) -> dict[str, Any] | None:
    dp = [c for c in cmd if c.get("mode") == "dp" and c.get("reference") is not None]
    if not dp or not est:
        return None
    t_est = np.array([int(e["stamp_ns"]) for e in est], dtype=np.int64)
    eta = np.array([e["eta"] for e in est], dtype=float)
    t_cmd = np.array([int(c["stamp_ns"]) for c in dp], dtype=np.int64)
    ref = np.array([c["reference"] for c in dp], dtype=float)
    k = np.searchsorted(t_est, t_cmd, side="right") - 1  # the last estimate at or before each command
    ok = k >= 0
    if not ok.any():
        return None
    e = eta[k[ok]] - ref[ok]
    pos = np.hypot(e[:, 0], e[:, 1])
    hdg = np.abs(np.degrees((e[:, 2] + math.pi) % (2 * math.pi) - math.pi))
    sat = np.array([bool(c.get("saturated")) for c in dp], dtype=bool)
    return {
        "commands": int(ok.sum()),
        "position_error_m": _quantiles(pos),
        "heading_error_deg": _quantiles(hdg),
        "saturated_share": float(sat.mean()),
    }


def _quantiles(x: np.ndarray) -> dict[str, float]:
    return {"p50": float(np.percentile(x, 50)), "p95": float(np.percentile(x, 95)), "max": float(x.max())}


def _dead_reckoning(
    est: list[Mapping[str, Any]], st: list[Mapping[str, Any]], start_ns: int
) -> dict[str, Any]:
    spells: list[dict[str, Any]] = []
    open_from: int | None = None
    worst = ""
    last_ns = 0
    for e in est:
        ns, status = int(e["stamp_ns"]), str(e.get("status", ""))
        if status in DEAD_RECKONED:
            if open_from is None:
                open_from, worst = ns, status
            elif status == "lost":
                worst = "lost"
        elif open_from is not None:
            spells.append(_spell(open_from, ns, worst, start_ns))
            open_from = None
        last_ns = ns
    if open_from is not None:
        spells.append(_spell(open_from, last_ns, worst, start_ns))
    in_dp = 0.0
    if st:
        t_st = np.array([int(s["stamp_ns"]) for s in st], dtype=np.int64)
        modes = [str(s.get("mode")) for s in st]
        for sp in spells:  # the mode of the status at or before the spell's start
            k = int(np.searchsorted(t_st, start_ns + round(sp["from_s"] * NS), side="right")) - 1
            sp["mode"] = modes[k] if k >= 0 else modes[0]
            if sp["mode"] == "dp":
                in_dp += sp["to_s"] - sp["from_s"]
    lengths = [sp["to_s"] - sp["from_s"] for sp in spells]
    return {
        "spells": len(spells),
        "total_s": float(sum(lengths)),
        "longest_s": float(max(lengths, default=0.0)),
        "in_dp_s": in_dp,
        "list": spells,
    }


def _spell(a_ns: int, b_ns: int, worst: str, start_ns: int) -> dict[str, Any]:
    return {"from_s": (a_ns - start_ns) / NS, "to_s": (b_ns - start_ns) / NS, "worst": worst}


def _alarms(st: list[Mapping[str, Any]], start_ns: int) -> list[dict[str, Any]]:
    seen: dict[str, dict[str, Any]] = {}
    active: set[str] = set()
    prev_ns: int | None = None
    for s in st:
        ns = int(s["stamp_ns"])
        now: dict[str, str] = {}
        for text in map(alarm_text, s.get("alarms", [])):
            now[alarm_key(text)] = text
        for key, text in now.items():
            entry = seen.get(key)
            if entry is None:
                entry = seen[key] = {
                    "key": key,
                    "first_text": text,
                    "first_s": (ns - start_ns) / NS,
                    "raised": 0,
                    "up_s": 0.0,
                    "level": "warning",
                }
            if key not in active:
                entry["raised"] += 1
            elif prev_ns is not None:
                entry["up_s"] += (ns - prev_ns) / NS
            if alarm_level(text, str(s.get("mode"))) == "critical":
                entry["level"] = "critical"
        active = set(now)
        prev_ns = ns
    order = {"critical": 0, "warning": 1}
    return sorted(seen.values(), key=lambda e: (order[e["level"]], -e["up_s"], e["first_s"]))
