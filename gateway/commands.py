"""Command inputs (mode, setpoint, manual τ): what the pipeline takes, and what it refuses and why.

Every input from Zenoh passes here before it can move the vessel. It is refused, counted by reason and
kept as text for the log when:

* its key is not in ``[commands] accept`` (command inputs are off unless enabled: a gateway that only
  estimates must not be steerable by any peer that finds it);
* it is malformed: not the documented shape, a number that is not finite, a latitude, longitude or
  heading out of range;
* a setpoint lies farther than ``max_setpoint_distance_m`` from the present position estimate (a typo
  in a coordinate, or a hostile peer, would otherwise send the vessel kilometres away at full thrust);
  a setpoint given before there is an estimate, or while it is not healthy enough for dp (below), waits
  for one that is and is checked then (a dead-reckoned or lost position is nothing to measure from); one
  taken
  outside dp (held for when dp is entered) is checked again when dp is entered, against the estimate of
  that moment: the vessel may have been moved far in standby or manual since, and dp then holds the
  present position;
* a manual τ exceeds, in any degree of freedom, what all thrusters together can give in that degree of
  freedom (the vessel's thruster layout, each at its largest thrust and best angle): such a demand is
  a mistake or an attack, never a wish the allocation could meet;
* the mode ``dp`` is asked for while the estimate is not healthy (observer not initialised, its status
  neither ``ok`` nor ``degraded``, or no observer step for longer than every source's timeout: every
  source silent, the estimate dead-reckoned however ``ok`` the last step was). Standby and manual are
  never refused for health: an operator must always be able to take the thrusters back;
* a manual τ arrives while the mode is not ``manual`` (``not in manual``): it would move nothing then,
  and entering manual starts from τ = 0 anyway, so taking it only hid that the operator's console and
  the gateway disagree on the mode.

Two more outcomes are counted apart, as they are not refusals of the input as it came:

* ``superseded``: a setpoint taken but not applied yet (it waits for the next control step, or for an
  estimate healthy enough for dp) that a newer setpoint replaced: the older one is dropped unapplied;
* ``expired``: a manual τ not renewed within ``[commands] manual_tau_hold_s`` (the dead-man): the pipeline
  then sets the thrust demand to zero (`gateway.pipeline.Pipeline`), until a fresh τ.

The checks are pure functions of the event and the pipeline's state, so a replay refuses exactly what
the live run refused.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from mypy_extensions import mypyc_attr

from observers.vessel import VesselModel

INPUTS = ("mode", "setpoint", "tau")
MODES = ("standby", "dp", "manual")
HEALTHY_FOR_DP = ("ok", "degraded")
"""Estimate statuses under which the mode ``dp`` may be entered. ``degraded`` is a backup reference that
still passes its checks: refusing DP there would strand a vessel whose primary DGPS just failed."""
MAX_HEADING_DEG = 360.0
DOFS = (("X", "N"), ("Y", "N"), ("N", "Nm"))
REFUSALS_KEPT = 100
"""Refusal texts kept for the caller to log between two `CommandGate.take_refusals` calls; the counters
are never capped, so a flood of hostile commands costs bounded memory and is still counted."""


def tau_capacity(vessel: VesselModel) -> np.ndarray | None:
    """[X N, Y N, N Nm]: the largest |τ| all thrusters together can give in each degree of freedom alone
    (an azimuth turned the best way, a fixed unit at its larger thrust ahead or astern); None for a vessel
    without a thruster layout."""
    if not vessel.thrusters:
        return None
    cap = np.zeros(3)
    for th in vessel.thrusters:
        f = max(abs(th.max_thrust_n), abs(th.min_thrust_n))
        if th.kind == "azimuth":
            cap += f * np.array([1.0, 1.0, math.hypot(th.x_m, th.y_m)])
        else:
            c, s = math.cos(th.angle_rad), math.sin(th.angle_rad)
            cap += f * np.abs(np.array([c, s, th.x_m * s - th.y_m * c]))
    return cap


@dataclass
class CommandCounters:
    """Inputs taken by key, inputs refused by reason, the last refusal as text; inputs taken but dropped
    unapplied for a newer one (``superseded``) and manual τ held past their hold time (``expired``), by
    key."""

    accepted: Counter[str] = field(default_factory=Counter)
    refused: Counter[str] = field(default_factory=Counter)
    last_refused: str | None = None
    superseded: Counter[str] = field(default_factory=Counter)
    expired: Counter[str] = field(default_factory=Counter)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class Refusal:
    """Why one input was refused: ``reason`` is the counter's key, ``text`` the sentence for the log."""

    key: str
    reason: str
    text: str


class CommandGate:
    """Checks command inputs against the config and the present estimate; counts what it refuses."""

    def __init__(self, accept: frozenset[str], max_setpoint_distance_m: float, vessel: VesselModel) -> None:
        self.accept = accept
        self.max_setpoint_distance_m = max_setpoint_distance_m
        self.capacity = tau_capacity(vessel)
        self.counters = CommandCounters()
        self._refusals: list[Refusal] = []

    # --- the checks: each returns None (taken) or a Refusal, already counted ------------------------------

    def admit(self, key: str, payload: Any) -> Refusal | None:
        """The first check of every input: is its key accepted at all?"""
        if key not in INPUTS:
            return self.refuse(key, "unknown input", f"unknown input key {key!r}")
        if key not in self.accept:
            return self.refuse(
                key, "not accepted", f"{key} inputs are not accepted (commands.accept does not list {key!r})"
            )
        return None

    def check_mode(
        self, payload: Any, initialized: bool, estimate_status: str | None, silent_s: float | None = None
    ) -> Refusal | None:
        """``estimate_status``: of the last estimate an observer step published; ``silent_s``: how long no
        step has been made when that is longer than every source's timeout (None while one is fresh). The
        estimates published meanwhile are dead-reckoned (`Pipeline.tick`), so the last step's status no
        longer describes the estimate; ticks are not replayed, so the refusal is by the input's time."""
        if payload not in MODES:
            return self.refuse("mode", "invalid", f"mode {_show(payload)} is not one of {', '.join(MODES)}")
        if payload == "dp":
            if not initialized or estimate_status is None:
                return self.refuse("mode", "estimate not healthy", "mode dp refused: no estimate yet")
            if silent_s is not None:
                return self.refuse(
                    "mode",
                    "estimate not healthy",
                    f"mode dp refused: no estimate step for {silent_s:.1f} s (every position and heading "
                    "source silent: the estimate is dead-reckoned)",
                )
            if estimate_status not in HEALTHY_FOR_DP:
                return self.refuse(
                    "mode", "estimate not healthy", f"mode dp refused: the estimate is {estimate_status}"
                )
        return None

    def check_setpoint_shape(self, payload: Any) -> Refusal | None:
        """Shape, finiteness and range of a setpoint {north_m, east_m, heading_deg} or {lat_deg, lon_deg,
        heading_deg}; the distance is checked when it is applied (`check_setpoint_distance`)."""
        expected = "expected {north_m, east_m, heading_deg} or {lat_deg, lon_deg, heading_deg}"
        if not isinstance(payload, Mapping):
            return self.refuse("setpoint", "invalid", f"setpoint {_show(payload)}: {expected}")
        keys = (
            ("north_m", "east_m") if "north_m" in payload or "east_m" in payload else ("lat_deg", "lon_deg")
        )
        values: dict[str, float] = {}
        for k in (*keys, "heading_deg"):
            v = payload.get(k)
            if isinstance(v, bool) or not isinstance(v, int | float):
                return self.refuse("setpoint", "invalid", f"setpoint {_show(payload)}: {expected}")
            f = _as_float(v)
            if f is None:
                return self.refuse("setpoint", "not finite", f"setpoint {k} = {_show(v)} is not finite")
            values[k] = f
        limits = {"lat_deg": 90.0, "lon_deg": 180.0, "heading_deg": MAX_HEADING_DEG}
        for k, v in values.items():
            lim = limits.get(k)
            if lim is not None and abs(v) > lim:
                return self.refuse(
                    "setpoint", "out of range", f"setpoint {k} = {v:g} is out of range (±{lim:g})"
                )
        return None

    def check_setpoint_distance(
        self, target_ned: np.ndarray, eta: np.ndarray, entering_dp: bool = False
    ) -> Refusal | None:
        """``entering_dp``: the check again, at the estimate of the moment, of a setpoint taken outside dp
        and held for it (the vessel may have been moved far since)."""
        d = math.hypot(float(target_ned[0] - eta[0]), float(target_ned[1] - eta[1]))
        if not d <= self.max_setpoint_distance_m:
            when = " on entering dp" if entering_dp else ""
            then = "; dp holds the present position" if entering_dp else ""
            return self.refuse(
                "setpoint",
                "too far",
                f"setpoint refused{when}: {d:.1f} m from the present position "
                f"(commands.max_setpoint_distance_m = {self.max_setpoint_distance_m:g} m){then}",
            )
        return None

    def check_tau_mode(self, mode: str) -> Refusal | None:
        """A manual τ is taken in ``manual`` only (checked after `check_tau`: a malformed τ is refused for
        that whatever the mode)."""
        if mode != "manual":
            return self.refuse(
                "tau", "not in manual", f"τ ignored: mode is {mode} (a τ is taken in manual only)"
            )
        return None

    def check_tau(self, payload: Any) -> np.ndarray | Refusal:
        """The manual τ [X, Y, N] as an array, or why not."""
        if not isinstance(payload, Mapping):
            return self.refuse("tau", "invalid", f"tau {_show(payload)}: expected {{X, Y, N}} in N, N, Nm")
        tau = []
        for k in ("X", "Y", "N"):
            v = payload.get(k)
            if isinstance(v, bool) or not isinstance(v, int | float):
                return self.refuse(
                    "tau", "invalid", f"tau {_show(payload)}: expected {{X, Y, N}} in N, N, Nm"
                )
            f = _as_float(v)
            if f is None:
                return self.refuse("tau", "not finite", f"tau {k} = {_show(v)} is not finite")
            tau.append(f)
        t = np.array(tau)
        if self.capacity is not None:
            over = [i for i in range(3) if abs(t[i]) > self.capacity[i]]
            if over:
                i = over[0]
                dof, unit = DOFS[i]
                return self.refuse(
                    "tau",
                    "beyond capacity",
                    f"tau {dof} = {t[i]:.4g} {unit} is beyond what the thrusters can give "
                    f"({self.capacity[i]:.4g} {unit})",
                )
        return t

    # --- counting ---------------------------------------------------------------------------------------

    def accepted(self, key: str) -> None:
        self.counters.accepted[key] += 1

    def superseded(self, key: str) -> None:
        """An input taken but not applied yet, dropped for a newer one of the same key."""
        self.counters.superseded[key] += 1

    def expired(self, key: str) -> None:
        """An input held past its hold time (a manual τ: `Pipeline`'s dead-man)."""
        self.counters.expired[key] += 1

    def refuse(self, key: str, reason: str, text: str) -> Refusal:
        r = Refusal(key, reason, text)
        self.counters.refused[f"{key}: {reason}"] += 1
        self.counters.last_refused = text
        if len(self._refusals) < REFUSALS_KEPT:
            self._refusals.append(r)
        return r

    def take_refusals(self) -> list[Refusal]:
        """The refusals since the last call (at most `REFUSALS_KEPT`), for the caller to log."""
        out, self._refusals = self._refusals, []
        return out


def _as_float(v: int | float) -> float | None:
    """A JSON number as a finite float; None for NaN, ±inf and an integer beyond a float's range (JSON
    integers have any number of digits: ``float(10**400)`` raises, and the input must be refused, not
    raise)."""
    try:
        f = float(v)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def _show(value: Any) -> str:
    """A refused payload as it was sent: its JSON (a Python repr showed `{'X': 1}` for the `{"X": 1}`
    put), or, for bytes that were no JSON at all (the service's ``{"invalid": text}``), the text and so,
    not the wrapper (`mode {'invalid': 'garbage{'}`); at most 80 characters."""
    if isinstance(value, dict) and len(value) == 1 and isinstance(value.get("invalid"), str):
        text = f"{value['invalid']!r} (not valid JSON)"
    else:
        try:
            text = json.dumps(value, ensure_ascii=False, allow_nan=True)
        except (TypeError, ValueError):
            text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."
