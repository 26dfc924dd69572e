"""The tests of a motion reference unit's (MRU's) roll and pitch before the lever-arm compensation uses
them (`gateway.fusion`): one wrong attitude moves a high antenna's reference point by the arm × the angle
(25 m × 5° ≈ 2.2 m), so an MRU is judged like a position or heading reference (docs/integrity.md, "The
MRU's attitude").

Every sample goes through, in order (the first failure rejects it, with that reason):

- **range**: |φ| or |θ| above ``attitude_max_deg``, or not finite (such a sample is not remembered as the
  previous one of the jump and freeze tests).
- **sigma** (PASHR only): the MRU's own 1σ of roll or pitch above ``attitude_max_sigma_deg`` (an INS
  aligning or unaided says so there). PASHR's aiding and IMU status flags are not used: roll and pitch are
  referenced to gravity and stay good without GNSS aiding, and makers give the IMU flag opposite meanings.
- **jump**: the change from the source's previous sample (received, passing or not) beyond
  ``attitude_jump_deg + attitude_max_rate_deg_s × Δt`` on either axis, Δt between the two samples' own
  UTC times where both have one (PASHR), else between their receive times. Against the previous sample,
  not the last good one: roll is continuous, so a spike fails on its way up and on its way down, and an
  MRU that steps to an offset fails at the step; a limit growing with the time since the last good
  sample would let a spike's own value back within a fraction of a second at a ship's roll rate.
- **freeze**: the same decoded roll and pitch, exactly, for ``attitude_freeze_s`` (an MRU repeating a
  buffer). Exact repetition, not small motion: a vessel in a flat-calm basin may hardly move, but the MRU's
  own noise still moves its last digit.

A rejected MRU is used again after passing for ``readmit_s`` (`SourceState`). What no test of one MRU can
see: an offset that grows slowly, or one present from the start (it needs a second MRU to compare with).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gateway.references.params import IntegrityParams
from gateway.references.state import NS
from wire.codecs.nmea_time import utc_step_s

DEG = math.pi / 180.0


@dataclass(frozen=True)
class AttitudeLimits:
    """The ``[integrity]`` attitude thresholds in rad, rad/s and ns, worked out once."""

    max_rad: float
    rate_rad_s: float
    jump_rad: float
    freeze_ns: int
    max_sigma_rad: float

    @classmethod
    def of(cls, p: IntegrityParams) -> AttitudeLimits:
        return cls(
            max_rad=p.attitude_max_deg * DEG,
            rate_rad_s=p.attitude_max_rate_deg_s * DEG,
            jump_rad=p.attitude_jump_deg * DEG,
            freeze_ns=int(p.attitude_freeze_s * NS),
            max_sigma_rad=p.attitude_max_sigma_deg * DEG,
        )


class AttitudeTrack:
    """What the tests of one MRU remember: its previous sample and since when its values repeat."""

    def __init__(self) -> None:
        self.rx_ns = 0  # receive time of the latest sample, whatever it was (0: none yet): for staleness
        self.last_ns = 0  # receive time of the previous sample judged possible (in range)
        self.prev: tuple[float, float, float | None] | None = None  # (roll, pitch, UTC s of day)
        self.same_since_ns = 0

    def problem(
        self,
        lim: AttitudeLimits,
        now_ns: int,
        timeout_ns: int,
        roll: float,
        pitch: float,
        utc_s: float | None = None,
        sigmas: tuple[float | None, float | None] = (None, None),
    ) -> str:
        """Why this sample may not be used ("" if it may), its reason starting with the test's name
        (module docstring). Remembers the sample for the next one's jump and freeze tests; after a silence
        longer than ``timeout_ns`` the jump and freeze tests start afresh."""
        prev, last_ns = self.prev, self.last_ns
        self.rx_ns = now_ns
        if prev is not None and now_ns - last_ns > timeout_ns:
            prev = None
        if not (math.isfinite(roll) and math.isfinite(pitch)):
            return "range: roll or pitch not finite"
        for axis, v in (("roll", roll), ("pitch", pitch)):
            if abs(v) > lim.max_rad:  # (not remembered: the next sample is judged against a possible one)
                return f"range: {axis} {v / DEG:.1f}° beyond ±{lim.max_rad / DEG:g}°"
        if prev is None or (roll, pitch) != prev[:2]:
            self.same_since_ns = now_ns
        self.prev, self.last_ns = (roll, pitch, utc_s), now_ns
        for axis, sigma in zip(("roll", "pitch"), sigmas, strict=True):
            if sigma is not None and sigma > lim.max_sigma_rad:
                return (
                    f"sigma: the MRU reports its {axis} 1σ as {sigma / DEG:.3g}° "
                    f"(limit {lim.max_sigma_rad / DEG:g}°)"
                )
        if prev is not None:
            dt = (now_ns - last_ns) / NS
            if utc_s is not None and prev[2] is not None:
                step = utc_step_s(prev[2], utc_s)
                if step > 0.0:
                    dt = step
            limit = lim.jump_rad + lim.rate_rad_s * dt
            for axis, v, before in (("roll", roll, prev[0]), ("pitch", pitch, prev[1])):
                if abs(v - before) > limit:
                    return (
                        f"jump: {axis} changed {(v - before) / DEG:+.2f}° in {dt:.2g} s "
                        f"(limit {limit / DEG:.2g}°)"
                    )
        frozen_ns = now_ns - self.same_since_ns
        if frozen_ns >= lim.freeze_ns:
            return f"freeze: the same roll and pitch for {frozen_ns / NS:.1f} s"
        return ""
