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
- **freeze**: the same decoded roll and pitch, exactly, for longer than this MRU's own last digit makes
  likely (an MRU repeating a buffer, or stuck on one value): the hold, at least ``attitude_freeze_s`` and
  at most ``attitude_freeze_max_s``, below. Exact repetition, not small motion: a vessel in a flat-calm
  basin may hardly move, but the MRU's own noise still moves its last digit — how often, depends on the
  MRU and the sea.

The freeze test's hold. A fixed hold cannot serve both a vessel in a sea way (roll changes the 0.01° of
every sample: a frozen MRU should be out in 2 s) and one in flat calm with an MRU whose noise is a
fraction of its resolution (σ 0.003° at 0.01° and a steady heel at mid-digit: the same two values for
2 s hundreds of times an hour; at σ 0.002° for 30 s). So each MRU's activity is learned while it passes:
``repeat``, the share of its samples whose roll and pitch both equal the previous sample's (an EMA, time
constant `ACTIVITY_TAU_S`; the plain mean over its first samples, from ½). A run of unchanged samples
starting now is allowed until it is improbable for that share; the hold is fixed at the run's start, and
samples that fail (a frozen run's beyond its hold among them) are not learned, so a freeze does not
lengthen the next hold. The model (no paper; the bound is derived here): the attitude is steady and its
noise white, so the samples are independent draws, each in "cell" k (the pair of last digits) with
probability P_k, and ``repeat`` = Σ P_k². A run of n repeats is n+1 samples in one cell: Σ P_kⁿ⁺¹ ≤
max P_kⁿ⁻¹ Σ P_k² ≤ repeat^((n+1)/2), since max P_k² ≤ Σ P_k². The hold is the smallest n with
repeat^((n+1)/2) ≤ `FREEZE_FALSE_ALARM_P`, times the mean sample interval, clamped to
[``attitude_freeze_s``, ``attitude_freeze_max_s``]. (The square root matters: taking the repeats as
independent, repeatⁿ, halves n, and σ 0.003° at mid-digit then false-alarms every few hours: a long run
is one cell hit n+1 times.) A frozen double buffer alternates between its two values, so no sample repeats the
previous one: a run in which every sample equals the one two back is held the same way (its n repeats are n+2
samples, the even ones in one cell and the odd ones in one: at most repeat^((n+2)/2), within the same bound;
it need not alternate, a constant run is one too, but a constant run is caught a sample sooner as a repeat of
the previous sample). Heave and heading (PASHR) are not used as signs of life: PHTRO has neither, and a
heading from a GNSS compass or a heave from its own filter can go on moving while the roll and pitch this test
protects are stuck. The activity survives a silence (the sea state is the vessel's, not the link's). What this
buys and costs: in a sea way the hold is ``attitude_freeze_s`` (repeat ≤ 0.14 at
10 Hz); in flat calm a frozen MRU is believed up to ``attitude_freeze_max_s``, while its frozen values
are wrong by only the little the hull moves (the lever-arm error a frozen MRU causes is the motion it no
longer follows). Not covered: an MRU whose output is smoothed over several samples (its runs are longer
than independent samples make them) or one quieter than a quarter of its resolution at a steady
attitude: such an MRU reaches ``attitude_freeze_max_s`` and may be failed there.

A rejected MRU is used again after passing for ``readmit_s`` (`SourceState`). What no test of one MRU can
see: an offset that grows slowly, or one present from the start (it needs a second MRU to compare with).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mypy_extensions import mypyc_attr

from gateway.references.params import IntegrityParams
from gateway.references.state import NS
from gateway.references.track import freeze_hold_ns, learned_repeat  # (the heading's freeze rule too)
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


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class AttitudeLimits:
    """The ``[integrity]`` attitude thresholds in rad, rad/s and ns, worked out once."""

    max_rad: float
    rate_rad_s: float
    jump_rad: float
    freeze_ns: int
    freeze_max_ns: int
    max_sigma_rad: float

    @classmethod
    def of(cls, p: IntegrityParams) -> AttitudeLimits:
        return cls(
            max_rad=p.attitude_max_deg * DEG,
            rate_rad_s=p.attitude_max_rate_deg_s * DEG,
            jump_rad=p.attitude_jump_deg * DEG,
            freeze_ns=int(p.attitude_freeze_s * NS),
            freeze_max_ns=int(p.attitude_freeze_max_s * NS),
            max_sigma_rad=p.attitude_max_sigma_deg * DEG,
        )


class FreezeRun:
    """A run of samples each equal to an earlier one (the previous, or the one two back): since when, and
    how long it may last (`AttitudeTrack.freeze_hold_ns`, fixed at its start); ``what`` it is, in words."""

    __slots__ = ("hold_ns", "since_ns", "what")

    def __init__(self, what: str) -> None:
        self.what = what
        self.since_ns = 0
        self.hold_ns = 0


class AttitudeTrack:
    """What the tests of one MRU remember: its previous sample, its latest rate, since when its values
    repeat (and how long they may), how often they repeat, the sample before a jump not yet judged, and
    the steps that stayed (an offset)."""

    def __init__(self) -> None:
        self.rx_ns = 0  # receive time of the latest sample, whatever it was (0: none yet): for staleness
        self.last_ns = 0  # receive time of the previous sample judged possible (in range)
        self.prev: tuple[float, float, float | None] | None = None  # (roll, pitch, UTC s of day)
        self.rate = (0.0, 0.0)  # (roll, pitch) rate between the last two samples that did not jump, rad/s
        # the sample before ``prev`` (roll, pitch): a frozen double buffer alternates between its two
        # values, so no sample repeats the previous one, but each the one two back
        self.prev2: tuple[float, float] | None = None
        # the freeze test's two runs: samples repeating the previous one, and the one two back
        self.repeats = FreezeRun("the same roll and pitch")
        self.alternation = FreezeRun("roll and pitch alternate between the same two values")
        self.repeat = 0.5  # share of passing samples that repeat the previous (EMA, `ACTIVITY_TAU_S`)
        self.learned = 0  # passing samples learned from (the EMA is their mean while its gain is lower)
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
            self.step, self.steady, self.prev2 = None, 0, None
        if not (math.isfinite(roll) and math.isfinite(pitch)):
            return "range: roll or pitch not finite"
        for axis, v in (("roll", roll), ("pitch", pitch)):
            if abs(v) > lim.max_rad:  # (not remembered: the next sample is judged against a possible one)
                return f"range: {axis} {v / DEG:.1f}° beyond ±{lim.max_rad / DEG:g}°"
        same = prev is not None and (roll, pitch) == prev[:2]
        runs = ((self.repeats, same), (self.alternation, not same and (roll, pitch) == self.prev2))
        for run, goes_on in runs:
            if not goes_on:
                run.since_ns = now_ns
        self.prev2 = None if prev is None else (prev[0], prev[1])
        self.prev, self.last_ns = (roll, pitch, utc_s), now_ns
        why = self._judge(lim, now_ns - last_ns, roll, pitch, prev, utc_s, sigmas)
        # (the holds after the jump test, which learns the sample interval they are counted in)
        for run, goes_on in runs:
            if not goes_on:
                run.hold_ns = self.freeze_hold_ns(lim)
            elif not why and now_ns - run.since_ns >= run.hold_ns:
                why = f"freeze: {run.what} for {(now_ns - run.since_ns) / NS:.1f} s"
        if not why and prev is not None:
            self._learn(same)
        return why

    def freeze_hold_ns(self, lim: AttitudeLimits) -> int:
        """How long a run of unchanged samples starting now may last, ns: the smallest n with
        repeat^((n+1)/2) ≤ `FREEZE_FALSE_ALARM_P` (module docstring) times the mean sample interval,
        within ``[freeze_ns, freeze_max_ns]``."""
        return freeze_hold_ns(self.repeat, self.interval_s, lim.freeze_ns, lim.freeze_max_ns)

    def _learn(self, same: bool) -> None:
        """One more passing sample in the MRU's activity: the mean of the first ones, then an EMA."""
        self.learned += 1
        self.repeat = learned_repeat(self.repeat, self.learned, self.interval_s, same)

    def _judge(
        self,
        lim: AttitudeLimits,
        dt_ns: int,
        roll: float,
        pitch: float,
        prev: tuple[float, float, float | None] | None,
        utc_s: float | None,
        sigmas: tuple[float | None, float | None],
    ) -> str:
        """The sigma, jump and offset tests of an in-range sample, ``dt_ns`` after the previous one."""
        for axis, sigma in zip(("roll", "pitch"), sigmas, strict=True):
            if sigma is not None and sigma > lim.max_sigma_rad:
                return (
                    f"sigma: the MRU reports its {axis} 1σ as {sigma / DEG:.3g}° "
                    f"(limit {lim.max_sigma_rad / DEG:g}°)"
                )
        if prev is not None:
            why = self._jump(lim, dt_ns, roll, pitch, prev, utc_s)
            if why:
                return why
        off = max(self.offset, key=abs)
        if abs(off) > lim.jump_rad:
            axis = "roll" if off == self.offset[0] else "pitch"
            return f"offset: {axis} stepped {off / DEG:+.2f}° and stayed (in use again once it steps back)"
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
