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
from pathlib import Path
from typing import Any

import numpy as np

from gateway.scoring import wave_band_rms

COMMAND_TOPIC = "/dp/thrusters/command"


def raw_feedback_commands(logs: Sequence[str | Path]) -> list[dict[str, Any]] | None:
    """The thruster command payloads of the gateway logs ``logs`` (one run, possibly rotated into several
    files) replayed on their own configuration with ``[control] feedback = "measurement"``; None when
    the logs carry no gateway configuration (nothing says which controller ran)."""
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


def wave_band_tau(commands: Sequence[dict[str, Any]], from_ns: int, band_rad_s: tuple[float, float]) -> Any:
    """The wave-band RMS of the commanded τ (``tau_demand``: surge N, sway N, yaw N·m) of the command
    payloads stamped from ``from_ns`` on (`gateway.scoring.wave_band_rms`), or None."""
    kept = [c for c in commands if int(c["stamp_ns"]) >= from_ns]
    if not kept:
        return None
    t = np.array([int(c["stamp_ns"]) - from_ns for c in kept], dtype=float) / 1e9
    tau = np.array([c["tau_demand"] for c in kept], dtype=float)
    return wave_band_rms(t, tau, band_rad_s)


def wave_filtering_saved(
    live: Sequence[dict[str, Any]],
    raw: Sequence[dict[str, Any]],
    from_ns: int,
    band_rad_s: tuple[float, float],
) -> dict[str, Any] | None:
    """The live commands' wave-band τ beside the raw-fed replay's, from ``from_ns`` on, per DOF, and the
    difference in dB (20 log₁₀ of the ratio of RMS: positive is what wave filtering kept out); None when
    either is too short to filter."""
    ours = wave_band_tau(live, from_ns, band_rad_s)
    theirs = wave_band_tau(raw, from_ns, band_rad_s)
    if ours is None or theirs is None:
        return None
    saved = [
        20.0 * math.log10(b / a) if a > 0.0 and b > 0.0 else (math.inf if b > 0.0 else 0.0)
        for a, b in zip(ours.tolist(), theirs.tolist(), strict=True)
    ]
    return {
        "band_rad_s": [float(band_rad_s[0]), float(band_rad_s[1])],
        "wave_band_tau_rms": [float(x) for x in ours],
        "raw_feedback_wave_band_tau_rms": [float(x) for x in theirs],
        "saved_db": saved,
    }
