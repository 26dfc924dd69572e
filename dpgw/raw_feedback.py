"""What wave filtering saved on a gateway's log: the same DP controller fed the raw measurements.

A DP system without a wave filter feeds its controller the measured position and heading and a filtered
derivative of them (`[control] feedback = "measurement"`, `Pipeline._raw_feedback`). The controller then
answers the vessel's first-order wave motion, which no thruster can stop, with wave-frequency thrust:
wear, fuel and noise for nothing. That is what the observer's wave filtering is for, and what a DP
engineer asks of it: by how much does it keep the wave band out of the commanded thrust?

The gateway's own log is replayed with that one setting changed: the same configuration, controller,
gains, operator's modes and setpoints, the same measurements. The commanded τ's wave-band RMS against the
live one's, in dB, is what the wave filter kept out. The replay is open loop: its commands move nothing,
the logged vessel moved as the live commands made it. The wave-frequency motion the raw controller answers
is the sea's, not the slow DP loop's, so its wave-band thrust is what such a system would command; its
slow thrust would differ (it has no bias estimate to feed forward), which the wave band leaves out.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gateway.report.data import force_prefix
from gateway.report.spectra import band_rms

COMMAND_TOPIC = "/dp/thrusters/command"

THRUST_WAVE_BAND = (0.3, 2.0)
"""rad/s: the first-order wave band of a full-scale vessel's seas (periods 3-21 s), in which the commanded
thrust is measured; a model's is Froude-scaled (`thrust_wave_band`). Its lower edge is above a DP loop's
bandwidth (0.07-0.1 rad/s at full scale), so the slow thrust that holds the vessel is not counted."""


def thrust_wave_band(vessel: Any) -> tuple[float, float]:
    """`THRUST_WAVE_BAND` for ``vessel`` (a `VesselModel`): × √λ for a 1:λ model (`observers.froude`), so
    CyberShip II's waves (1:70) are measured where they are, at ~2.5-17 rad/s."""
    from observers.froude import froude_scale, scaled_frequencies

    lo, hi = scaled_frequencies(THRUST_WAVE_BAND, froude_scale(vessel))
    return lo, hi


def dp_stretch(commands: Sequence[dict[str, Any]]) -> tuple[int, int] | None:
    """The first and last stamp (ns) of the longest run of consecutive commands made in dp (a trial's
    stretch on station: manual and standby commands around it are the crew's, not the controller's)."""
    best: tuple[int, int] | None = None
    start: int | None = None
    last = 0
    for c in sorted(commands, key=lambda c: int(c["stamp_ns"])):
        ns = int(c["stamp_ns"])
        if c.get("mode") == "dp":
            start = ns if start is None else start
            last = ns
            if best is None or last - start > best[1] - best[0]:
                best = (start, last)
        else:
            start = None
    return best


def raw_feedback_commands(logs: Sequence[str | Path]) -> list[dict[str, Any]] | None:
    """The thruster command payloads of the gateway logs ``logs`` (one run, possibly rotated into several
    files) replayed on their own configuration with ``[control] feedback = "measurement"``; None when
    the logs carry no gateway configuration (nothing says which controller ran), or one whose controller
    was already fed the raw measurements (no wave filter to measure)."""
    from gateway.replay import (
        ObserverSpec,
        build_config,
        build_pipeline,
        keyless_mavlink_sources,
        logged_signing_verdicts,
        open_inputs,
        run_replay,
        runs_its_own_controller,
    )

    inputs = open_inputs(logs)
    if not runs_its_own_controller(inputs, own_config=True):
        return None
    config = build_config(inputs)
    if config.control.feedback == "measurement":  # the live controller had no wave filter: nothing to compare
        return None
    config = dataclasses.replace(config, control=dataclasses.replace(config.control, feedback="measurement"))
    own = config.observer.type
    pipeline = build_pipeline(
        config,
        [ObserverSpec(own, own, {})],
        foxglove_channels=False,
        controller=True,
        # a signed thruster link's frames taken as the live gateway judged them (the log holds no key)
        signing_verdicts=logged_signing_verdicts(inputs, keyless_mavlink_sources(config)),
    )
    return run_replay(inputs, pipeline, collect=[COMMAND_TOPIC]).collected[COMMAND_TOPIC]


def in_stretch(
    commands: Sequence[dict[str, Any]], from_ns: int, to_ns: int, origin_ns: int | None = None
) -> tuple[list[dict[str, Any]], Any]:
    """The command payloads stamped from ``from_ns`` to ``to_ns``, in time order, and their times in s
    from ``origin_ns`` (None: from ``from_ns``)."""
    kept = sorted(
        (c for c in commands if from_ns <= int(c["stamp_ns"]) <= to_ns), key=lambda c: int(c["stamp_ns"])
    )
    origin = from_ns if origin_ns is None else origin_ns
    return kept, np.array([int(c["stamp_ns"]) - origin for c in kept], dtype=float) / 1e9


def wave_band_tau(
    commands: Sequence[dict[str, Any]], from_ns: int, to_ns: int, band_rad_s: tuple[float, float]
) -> Any:
    """The wave-band RMS of the commanded τ (``tau_demand``: surge N, sway N, yaw N·m) of the command
    payloads stamped from ``from_ns`` to ``to_ns`` (`gateway.report.spectra.band_rms`), or None."""
    kept, t = in_stretch(commands, from_ns, to_ns)
    if not kept:
        return None
    return band_rms(t, np.array([c["tau_demand"] for c in kept], dtype=float), band_rad_s)


def wave_band_thrust(
    commands: Sequence[dict[str, Any]], from_ns: int, to_ns: int, band_rad_s: tuple[float, float]
) -> dict[int, float]:
    """Per thruster id, the wave-band RMS of its commanded thrust (N) over the command payloads stamped
    from ``from_ns`` to ``to_ns``: what the allocation, within its thrust and turning rates, asked of each
    drive. Only thrusters in every command; none when too short to filter."""
    kept, t = in_stretch([c for c in commands if c.get("thrusters")], from_ns, to_ns)
    if not kept:
        return {}
    ids = sorted(set.intersection(*({int(x["id"]) for x in c["thrusters"]} for c in kept)))
    if not ids:
        return {}
    by_id = [{int(x["id"]): float(x["thrust_n"]) for x in c["thrusters"]} for c in kept]
    rms = band_rms(t, np.array([[row[i] for i in ids] for row in by_id], dtype=float), band_rad_s)
    return {} if rms is None else dict(zip(ids, rms.tolist(), strict=True))


def _db(ours: float, theirs: float) -> float | None:
    """20 log₁₀(theirs / ours); None where either is zero (no ratio, and no finite dB)."""
    return 20.0 * math.log10(theirs / ours) if ours > 0.0 and theirs > 0.0 else None


def wave_filtering_saved(
    live: Sequence[dict[str, Any]],
    raw: Sequence[dict[str, Any]],
    from_ns: int,
    band_rad_s: tuple[float, float],
    to_ns: int | None = None,
) -> dict[str, Any] | None:
    """The live commands' wave-band τ beside the raw-fed replay's, stamped from ``from_ns`` to ``to_ns``
    (None: to the end), per DOF, and the difference in dB (20 log₁₀ of the ratio of RMS: positive is
    what wave filtering kept out; None for a DOF where either has no wave-band thrust at all, a ratio
    with no meaning and no finite dB); None when either is too short to filter."""
    end = to_ns if to_ns is not None else max((int(c["stamp_ns"]) for c in live), default=from_ns)
    ours = wave_band_tau(live, from_ns, end, band_rad_s)
    theirs = wave_band_tau(raw, from_ns, end, band_rad_s)
    if ours is None or theirs is None:
        return None
    saved = [_db(a, b) for a, b in zip(ours.tolist(), theirs.tolist(), strict=True)]
    live_thrust = wave_band_thrust(live, from_ns, end, band_rad_s)
    raw_thrust = wave_band_thrust(raw, from_ns, end, band_rad_s)
    thrusters = [
        {
            "id": i,
            "wave_band_thrust_rms_n": live_thrust[i],
            "raw_feedback_wave_band_thrust_rms_n": raw_thrust[i],
            "saved_db": _db(live_thrust[i], raw_thrust[i]),
        }
        for i in sorted(live_thrust.keys() & raw_thrust.keys())
    ]
    return {
        "band_rad_s": [float(band_rad_s[0]), float(band_rad_s[1])],
        "scored_s": (end - from_ns) / 1e9,
        "wave_band_tau_rms": [float(x) for x in ours],
        "raw_feedback_wave_band_tau_rms": [float(x) for x in theirs],
        "saved_db": saved,
        # per drive (the allocation's commanded thrust, within its rates): the wear each is spared
        "thrusters": thrusters,
    }


@dataclass(frozen=True)
class Comparison:
    """`compare_with_raw_feedback`'s result: the figures (`wave_filtering_saved`, ``{"error": ...}`` or
    None), the raw-fed replay's command payloads (None if it did not run) and the stretch compared
    (first and last stamp, ns; None without one)."""

    figures: dict[str, Any] | None
    raw: list[dict[str, Any]] | None = None
    stretch: tuple[int, int] | None = None


def compare_with_raw_feedback(
    logs: Sequence[str | Path],
    live: Sequence[dict[str, Any]],
    band_rad_s: tuple[float, float],
    from_ns: int | None = None,
    after_engage_s: float = 0.0,
) -> Comparison:
    """What wave filtering saved on a gateway's logs: their live commands ``live`` against the raw-fed
    replay's (`raw_feedback_commands`), over the longest stretch in dp (`dp_stretch`), from ``from_ns`` on
    if given and ``after_engage_s`` after the stretch begins (the demo scores from 30 s after engaging,
    and not before 60 s; a replay of its log the same); with the raw-fed commands and the stretch kept,
    for a plot of both. The figures are None without a stretch in dp, a configuration in the logs, or
    enough of it to filter. A failure of the replay is the figures ``{"error": ...}``, not raised: it is
    one figure of a summary whose others must still come out."""
    stretch = dp_stretch(live)
    if stretch is None:
        return Comparison(None)
    start, end = stretch
    start += round(after_engage_s * 1e9)
    if from_ns is not None:
        start = max(start, from_ns)
    if end <= start:
        return Comparison(None)
    try:
        raw = raw_feedback_commands(logs)
    except Exception as exc:  # (a bug to report; the summary of a run that went well must still come out)
        return Comparison({"error": f"{type(exc).__name__}: {exc}"})
    if raw is None:
        return Comparison(None)
    return Comparison(wave_filtering_saved(live, raw, start, band_rad_s, end), raw, (start, end))


def force_words(x: float, unit: str = "N") -> str:
    """A force (N) or moment (N·m) in N, kN or MN (N·m, kN·m, MN·m) by its size, to two figures at least:
    a supply vessel's wave-band thrust is tens of kN, a basin model's fractions of a newton."""
    scale, prefix = force_prefix(x)
    x, unit = x / scale, prefix + unit
    if abs(x) >= 10:
        return f"{x:.0f} {unit}"
    return f"{x:.1f} {unit}" if abs(x) >= 1 else f"{x:.2g} {unit}"


def wave_filtering_words(w: dict[str, Any]) -> str:
    """`compare_with_raw_feedback`'s figures in one line of a summary (after "wave filtering: ")."""
    if "error" in w or "not_measured" in w:
        return f"not measured ({w.get('error') or w['not_measured']})"
    lo, hi = w["band_rad_s"]
    ours, theirs = w["wave_band_tau_rms"], w["raw_feedback_wave_band_tau_rms"]
    return (
        f"wave-band thrust ({lo:.2g}-{hi:.2g} rad/s) {force_words(ours[0])} surge, {force_words(ours[1])} "
        f"sway, {force_words(ours[2], 'N·m')} yaw RMS; the same controller fed the raw measurements would "
        f"command {force_words(theirs[0])}, {force_words(theirs[1])}, {force_words(theirs[2], 'N·m')} (this "
        f"log replayed): {_dbs(w['saved_db'])} dB less"
    )


def thruster_words(w: dict[str, Any]) -> str | None:
    """The per-thruster figures of `compare_with_raw_feedback` in one line, or None without them."""
    drives = w.get("thrusters")
    if not drives:
        return None
    return (
        f"per thruster ({', '.join(str(x['id']) for x in drives)}): "
        f"{_dbs([x['saved_db'] for x in drives])} dB less wave-band thrust commanded"
    )


def wave_filtering_lines(w: dict[str, Any]) -> list[str]:
    """The summary's lines of `compare_with_raw_feedback`'s figures (the demo's and the replay's, each
    indented to its summary): "wave filtering: …" (with the stretch compared, ``stretch_s``, when the
    figures carry it), and the per-thruster line under it when there is one."""
    drives = thruster_words(w)
    over = f" (over {w['stretch_s'][0]:.0f}-{w['stretch_s'][1]:.0f} s)" if w.get("stretch_s") else ""
    return [f"wave filtering{over}: {wave_filtering_words(w)}", *([f"  {drives}"] if drives else [])]


def _dbs(values: list[float | None]) -> str:
    return " / ".join("–" if d is None else f"{d:.0f}" for d in values)
