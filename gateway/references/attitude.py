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
- **jump**: the change from the source's previous sample beyond ``attitude_jump_deg +
  attitude_max_rate_deg_s × Δt`` on either axis, Δt between the two samples' own UTC times where both
  have one (PASHR), else between their receive times but at least their mean interval (a link that
  batches delivers two samples at once). Against the previous sample, not the last good one:
  roll is continuous, so a spike or a step to an offset fails where it jumps; a limit growing with the
  time since the last good sample would let a spike's value back within a fraction of a second.
- **offset**: the sample after a jump tells a spike from a step. Back near where the MRU would have been
  without the jump (the sample before it moved on at its rate), it was a spike, over; near the jumped-to
  values (moved on likewise), the step stayed: it is added to the MRU's offset, and while the offset
  exceeds ``attitude_jump_deg`` every sample fails, until the MRU steps back (the offset sums to ~0) or
  falls silent longer than its timeout (restarted: its tests start afresh). A roll cannot step, so an
  MRU that stepped and stayed is wrong on one side of the step; which side, one MRU cannot tell, and the
  side after it is the one that is not trusted. Either way the sample must be within the jump test's
  limit of the motion or of the jumped-to values: one that is neither continues a burst of wrong values
  and fails too, judged the same way by the next (for at most `BURST_SAMPLES` and `BURST_S`; after a
  longer burst no step is counted from it). A step whose next sample jumps again is a burst too: it is
  taken off the offset. Steps are judged only after `STEADY_SAMPLES` passed in a row.
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
INTERVAL_GAIN = 0.1
"""Gain of the mean receive interval of an MRU's samples (about the last ten): without sensor times the
jump test's Δt is at least that mean, so two samples a link delivers together (the same receive time)
are allowed the change of one sample interval, not of none."""
BURST_SAMPLES = 3
BURST_S = 0.5
"""A jump followed by samples that are neither back on the motion nor where the jump went (a burst of
wrong values) is judged, as a spike or a step, against the motion extrapolated from before it for at
most this many samples and this long: longer, the extrapolation by one rate is no longer the motion (a
roll turns within seconds; at 100 Hz the sampled rate's noise grows with it), and the burst is only
failed: the MRU's next steady motion passes without a step counted from it, as after a restart."""
STEADY_SAMPLES = 3
"""A jump is judged as a spike or a step (the offset test) only after this many samples in a row passed
the jump test: at the start, and after a burst, whose wrong values may agree by chance for a sample or
two and would be taken for the motion a step is measured from (an offset that never steps back)."""


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
    """What the tests of one MRU remember: its previous sample, its latest rate, since when its values
    repeat, the sample before a jump not yet judged, and the steps that stayed (an offset)."""

    def __init__(self) -> None:
        self.rx_ns = 0  # receive time of the latest sample, whatever it was (0: none yet): for staleness
        self.last_ns = 0  # receive time of the previous sample judged possible (in range)
        self.prev: tuple[float, float, float | None] | None = None  # (roll, pitch, UTC s of day)
        self.rate = (0.0, 0.0)  # (roll, pitch) rate between the last two samples that did not jump, rad/s
        self.same_since_ns = 0
        # after a failed jump: (roll, pitch) expected had there been none (the sample before it moved on by
        # its rate to the jump's time), the jumped-to values, and the rate; judged by the next sample
        # (and how many samples and seconds since the jump, while a burst goes on)
        self.pending: (
            tuple[tuple[float, float], tuple[float, float], tuple[float, float], int, float] | None
        ) = None
        self.offset = (0.0, 0.0)  # the sum of the steps that stayed (roll, pitch), rad
        # the step just added to `offset` (and the motion before it, moved on to now, its rate, the
        # burst's samples and seconds): taken back if the next sample jumps again (a burst, not a step)
        self.step: tuple[tuple[float, float], tuple[float, float], tuple[float, float], int, float] | None = (
            None
        )
        self.interval_s = 0.0  # mean receive interval (EMA) of the MRU's samples, s
        self.steady = 0  # samples in a row that passed the jump test (`STEADY_SAMPLES`)

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
        (module docstring). Remembers the sample for the next one's tests; after a silence longer than
        ``timeout_ns`` (the MRU restarted, or the link) the jump, offset and freeze tests start afresh."""
        prev, last_ns = self.prev, self.last_ns
        self.rx_ns = now_ns
        if prev is not None and now_ns - last_ns > timeout_ns:
            prev, self.pending, self.offset, self.rate = None, None, (0.0, 0.0), (0.0, 0.0)
            self.step, self.steady = None, 0
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
            why = self._jump(lim, now_ns - last_ns, roll, pitch, prev, utc_s)
            if why:
                return why
        off = max(self.offset, key=abs)
        if abs(off) > lim.jump_rad:
            axis = "roll" if off == self.offset[0] else "pitch"
            return f"offset: {axis} stepped {off / DEG:+.2f}° and stayed (in use again once it steps back)"
        frozen_ns = now_ns - self.same_since_ns
        if frozen_ns >= lim.freeze_ns:
            return f"freeze: the same roll and pitch for {frozen_ns / NS:.1f} s"
        return ""

    def _jump(
        self,
        lim: AttitudeLimits,
        dt_ns: int,
        roll: float,
        pitch: float,
        prev: tuple[float, float, float | None],
        utc_s: float | None,
    ) -> str:
        """The jump test against the previous sample, and the judgement of a jump by the sample after it:
        back near where the MRU would have been without it (extrapolated by its rate) is a spike (this
        sample passes); near the jumped-to values is a step that stayed, added to `offset` (and taken back
        if the sample after it jumps again: a burst). Before `STEADY_SAMPLES` passed in a row (the first
        samples, after a burst) a jump is only a jump: an offset needs the extrapolation of a motion the
        MRU has shown, else the first samples' motion, or a burst's values, would count as a step."""
        dt = dt_ns / NS
        if dt > 0.0:  # (a link that batches delivers some samples together: the mean keeps the spacing)
            self.interval_s = (
                dt if not self.interval_s else self.interval_s + INTERVAL_GAIN * (dt - self.interval_s)
            )
        dt = max(dt, self.interval_s)
        if utc_s is not None and prev[2] is not None:
            utc_dt = utc_step_s(prev[2], utc_s)
            if utc_dt > 0.0:
                dt = utc_dt
        if dt <= 0.0:
            return ""  # (the first two samples at once, without times: no spacing to judge a change by)
        pending, self.pending = self.pending, None
        step, self.step = self.step, None
        limit = lim.jump_rad + lim.rate_rad_s * dt
        if pending is not None:
            expected, jumped, rate, n, since = pending
            here = (expected[0] + rate[0] * dt, expected[1] + rate[1] * dt)
            back = max(abs(roll - here[0]), abs(pitch - here[1]))
            stay = max(abs(roll - jumped[0] - rate[0] * dt), abs(pitch - jumped[1] - rate[1] * dt))
            if back <= stay and back <= limit:
                return ""  # a spike, over: this sample continues the motion from before it
            if stay < back and stay <= limit:
                d = (jumped[0] - expected[0], jumped[1] - expected[1])
                self.offset = (self.offset[0] + d[0], self.offset[1] + d[1])
                self.step = (d, here, rate, n + 1, since + dt)
                self.rate = ((roll - prev[0]) / dt, (pitch - prev[1]) / dt)
                return ""
            # neither back on the motion nor where the jump went: a burst of wrong values goes on
            self._burst_goes_on(here, (roll, pitch), rate, n + 1, since + dt)
            return (
                f"jump: roll {(roll - prev[0]) / DEG:+.2f}°, pitch {(pitch - prev[1]) / DEG:+.2f}° in a burst"
            )
        for axis, v, before in (("roll", roll, prev[0]), ("pitch", pitch, prev[1])):
            if abs(v - before) > limit:
                if step is not None:  # the step just counted jumps again: a burst, not a step
                    d, motion, rate, n, since = step
                    self.offset = (self.offset[0] - d[0], self.offset[1] - d[1])
                    here = (motion[0] + rate[0] * dt, motion[1] + rate[1] * dt)
                    self._burst_goes_on(here, (roll, pitch), rate, n + 1, since + dt)
                    return f"jump: {axis} changed {(v - before) / DEG:+.2f}° in a burst"
                rate = self.rate
                if self.steady >= STEADY_SAMPLES:  # (else a jump is only a jump)
                    expected = (prev[0] + rate[0] * dt, prev[1] + rate[1] * dt)
                    self.pending = (expected, (roll, pitch), rate, 1, dt)
                return (
                    f"jump: {axis} changed {(v - before) / DEG:+.2f}° in {dt:.2g} s "
                    f"(limit {limit / DEG:.2g}°)"
                )
        self.rate, self.steady = ((roll - prev[0]) / dt, (pitch - prev[1]) / dt), self.steady + 1
        return ""

    def _burst_goes_on(
        self,
        here: tuple[float, float],
        jumped: tuple[float, float],
        rate: tuple[float, float],
        n: int,
        since: float,
    ) -> None:
        """A burst of wrong values goes on: its next sample is judged against the motion from before it
        (``here``, moved on by ``rate``) while it is short enough to extrapolate through (`BURST_SAMPLES`,
        `BURST_S`); beyond that no step will be counted from it."""
        if n <= BURST_SAMPLES and since <= BURST_S:
            self.pending = (here, jumped, rate, n, since)
        else:
            self.steady = 0
