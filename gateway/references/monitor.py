"""The reference tests for all of a gateway's sources: what the pipeline asks before it uses a fix, a
heading or a thruster report, and what it reports (states, reasons, state changes, per-role health).

Every fix goes through, in order (the first failure rejects it, with that reason):
quality → jump/rate (against the source's last good value, allowance + speed × time) → freeze → variance →
prediction (against the observer's prediction, gated by the expected spread) → median of ≥ 3 references.
With exactly two references of a role their divergence raises a soft alarm on both (still used: nobody can
tell which is wrong). A rejected source is used again after passing for ``readmit_s``. An MRU's roll and
pitch (role ``attitude``) and thruster feedback (role ``thrusters``) have tests of their own
(`gateway.references.attitude`, `gateway.references.feedback`) and the same states, with one difference:
a failing sample or report of one in use rejects it only when ``attitude_rejects`` / ``feedback_rejects``
failed within ``readmit_s`` (docs/integrity.md, "Every role").

A heading rejected by the jump test while in use may be a spike (a GNSS compass's one-sample or burst
artefact): for ``readmit_s`` after it, each sample is tested against the heading before the jump (the
median of the last good ones) moved on at the estimate's rate of turn instead, and two samples in a row
back on that track readmit it at once (`SPIKE_CONFIRM`); docs/integrity.md, "A heading spike".
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

from mypy_extensions import mypyc_attr

from gateway.references.attitude import AttitudeLimits, AttitudeTrack
from gateway.references.feedback import feedback_problem
from gateway.references.params import IntegrityParams
from gateway.references.state import NS, OK, REJECTED, STALE, SUSPECT, SourceState, StateChange
from gateway.references.track import (
    MIN_SAMPLES_FOR_VARIANCE,
    AngleTrack,
    PlaneTrack,
    Track,
    freeze_hold_ns,
    learned_repeat,
)
from gateway.references.voting import divergence, median_distance
from observers.kinematics import ssa_scalar
from observers.vessel import Thruster

RoleHealth = Literal["ok", "degraded", "lost"]
"""A role's health: every reference ok; some usable but not all ok; none usable."""
GGA_QUALITY_NAMES = {
    0: "no fix",
    3: "PPS",
    6: "dead reckoning",
    7: "manual input",
    8: "simulator",
}
DIVERGENCE_CLEAR = 0.8  # hysteresis: a divergence alarm clears below 80 % of its threshold
SPIKE_ANCHOR = 5
"""The heading before a jump is the median of the last this many good values (1 s at 5 Hz), not the last
one alone: a real GNSS compass's spike may begin with a value that is only 2.8° off and passes (USV log,
a burst 233.2°, 230.3°, 239.8°, 231.7°, 240.8°, 241.6°, 241.3°, then 233.7°), and the track taken from it
missed the good values after the burst by 3.4°."""
SPIKE_CONFIRM = 2
"""Samples in a row back on the heading's track before the jump that readmit a heading at once: two, so
that the compass's samples agree with each other as well as with the track (one burst value landing near
the track by chance does not end the rejection; it is used, being within the jump allowance of the track,
and the next burst value fails)."""


VOTE_LATE = 3
"""A reference whose latest value is older than this many of its usual intervals between values is left
out of the votes until its next one (still fresh, not stale): its smoothed track stopped while the
others' went on following the wave motion, and two DGPS with the same data were judged 1 m apart 1.5 s
into one's silence, before its timeout. Three intervals: a late datagram or two is not a silence."""


JUMP_STEPS = 4.0
"""A position's jump allowance is at least this many times the RMS step between the source's consecutive
fixes, as measured (2σ of `Track.var`: E‖d‖² = 4σ² for two components), instead of ``jump_m`` alone,
before ``max_speed_m_s`` × Δt is added: ``max(jump_m, JUMP_STEPS · 2σ) + max_speed_m_s · Δt``. A slow
receiver in a big sea sees the vessel's first-order wave motion between two fixes (fossen_strand_1999 at
1 Hz: 5 m RMS, 14 m at most in a minute, against 10 m of plain allowance), which the plain allowance,
meant for noise and LF speed, took for a jump. Four: the limit is then about 5 RMS steps with the
speed term, and a long-crested sea moves the antenna along one line, so for a Gaussian step that is a
false rejection in about 10⁶ fixes, with a margin for a wave group above the last 50 fixes' average. A
fast receiver's step is mostly its noise (0.1 s of wave motion is small), 4 × 2σ stays under or near
``jump_m``, and the test is the plain one. Bounded: σ above ``max_sigma_m`` fails the variance test.
Not from a paper: the DP practice of testing a reference against what it can physically do, the wave
motion measured from the source's own fixes (docs/integrity.md, "Jump / rate")."""


ELLIPSE_EPS_M2 = 1e-12
"""Added to both variances before `ellipse_reach` inverts a covariance: a receiver's ellipse with a zero
minor axis (a line) becomes invertible, its reach across the line 3 µm instead of a division by zero."""


def ellipse_reach(cov_ne: tuple[float, float, float], dn: float, de: float) -> float:
    """How far the 1σ ellipse of the covariance (C_NN, C_NE, C_EE) reaches from its centre in the
    direction of (dn, de): 1 / √(uᵀ C⁻¹ u) with u = (dn, de) / ‖(dn, de)‖, the radius of the ellipse
    xᵀ C⁻¹ x = 1 along u. With C⁻¹ = adj(C) / det(C), adj(C) = [[C_EE, −C_NE], [−C_NE, C_NN]]::

        reach² = det(C) ‖d‖² / (C_EE dn² − 2 C_NE dn de + C_NN de²)

    (the semi-major axis along the major axis, the semi-minor across it, σ for a circle). 0 for a zero
    direction."""
    nn, ne, ee = cov_ne[0] + ELLIPSE_EPS_M2, cov_ne[1], cov_ne[2] + ELLIPSE_EPS_M2
    d2 = dn * dn + de * de
    q = ee * dn * dn - 2.0 * ne * dn * de + nn * de * de
    if d2 == 0.0 or q <= 0.0:
        return 0.0
    return math.sqrt(max(nn * ee - ne * ne, 0.0) * d2 / q)


class Prediction(NamedTuple):
    """Where the observer expects the next value (N, E) or (ψ,), and how long since the estimate last had
    a measurement of that DOF (s): an old prediction is trusted less, and not at all past a limit.
    (A NamedTuple: one is made for every fix and heading, and a frozen dataclass costs 4x as much.)"""

    value: tuple[float, ...]
    age_s: float
    rate: float = 0.0  # heading: the estimate's rate of turn (rad/s), which a spike's recovery extrapolates
    held: bool = False  # DP holds the DOF on this prediction: past the age limit the test still applies


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class _Limits:
    """One role's thresholds in the units of its values (m or rad), worked out once from the params
    rather than on every fix."""

    jump: float
    rate: float
    freeze_s: float
    gate: float
    median: float
    diverge: float
    grow: float  # how fast the prediction gate widens with the prediction's age (per s)
    max_sigma: float  # the variance test's limit (inf: no such test for the role)
    unit: str
    scale: float  # value -> the unit shown in reasons
    spike_s: float = 0.0  # how long after a jump a return to the track before it readmits at once (0: never)
    steps: float = 0.0  # the jump allowance is at least this many RMS steps between fixes (0: jump alone)
    # the freeze hold's least (s): 0 holds every run ``freeze_s``; above, a run is held by the source's
    # learned activity, within [freeze_min_s, freeze_s] (`_freeze`)
    freeze_min_s: float = 0.0


@dataclass
class _Ref:
    state: SourceState
    track: Track
    timeout_ns: int
    limits: _Limits
    alone: bool = False  # the only source of its role (set once the sources are known)
    # a jump out of use (a spike?): the last good value before it, when, and the rate of turn then
    spike: tuple[float, int, float] | None = None
    spike_run: int = 0  # samples in a row back on the track before the jump
    # its last good values and when (headings: `ReferenceMonitor._before`)
    recent: deque[tuple[float, int]] = field(default_factory=lambda: deque(maxlen=SPIKE_ANCHOR))
    # the learned freeze hold (`_freeze`): the share of passing values equal to the previous one, how
    # many were learned, and the holds of the present runs (the same value; two values in turn), ns
    repeat: float = 0.5
    learned: int = 0
    hold_ns: int = 0
    alternate_hold_ns: int = 0


class ReferenceMonitor:
    def __init__(
        self,
        params: IntegrityParams,
        positions: Mapping[str, int],
        headings: Mapping[str, int],
        feedback: Mapping[str, int] | None = None,
        thrusters: Mapping[int, Thruster] | None = None,
        attitudes: Mapping[str, int] | None = None,
    ) -> None:
        """``positions``, ``headings``, ``feedback``, ``attitudes``: source name → its timeout (ns)."""
        self.p = params
        readmit = int(params.readmit_s * NS)
        p = params
        deg = math.radians(1.0)
        position = _Limits(
            jump=p.jump_m,
            rate=p.max_speed_m_s,
            freeze_s=p.freeze_s,
            gate=p.prediction_gate_m,
            median=p.median_m,
            diverge=p.divergence_m,
            grow=p.max_speed_m_s / 10,
            max_sigma=p.max_sigma_m,
            unit="m",
            scale=1.0,
            steps=JUMP_STEPS,
        )
        heading = _Limits(
            jump=p.heading_jump_deg * deg,
            rate=p.max_rate_deg_s * deg,
            freeze_s=p.heading_freeze_s,
            gate=p.prediction_gate_deg * deg,
            median=p.heading_median_deg * deg,
            diverge=p.heading_divergence_deg * deg,
            grow=p.max_rate_deg_s * math.pi / 180 / 10,
            max_sigma=math.inf,
            unit="°",
            scale=1 / deg,
            spike_s=p.readmit_s,
            freeze_min_s=p.heading_freeze_min_s if p.heading_freeze_min_s < p.heading_freeze_s else 0.0,
        )
        self._limits = {"position": position, "heading": heading}
        # a restarted smoothed track votes after this long (`_vote`; docs/integrity.md, "A reference back
        # from a silence"): the seeded start's noise, one fix of each source, weighs e⁻¹ of it by then
        self._settle_ns = int(params.smoothing_s * NS)
        self._refs: dict[str, dict[str, _Ref]] = {
            "position": {
                n: _Ref(SourceState(n, "position", readmit), PlaneTrack(params.smoothing_s), t, position)
                for n, t in positions.items()
            },
            "heading": {
                n: _Ref(SourceState(n, "heading", readmit), AngleTrack(params.smoothing_s), t, heading)
                for n, t in headings.items()
            },
        }
        self._feedback = {n: SourceState(n, "thrusters", readmit) for n in (feedback or {})}
        # per feedback source: [its timeout, the receive time of its latest report whatever it was (0: none
        # yet)], a list to update in place: `refresh` reads it on every event
        self._feedback_rx = {n: [t, 0] for n, t in (feedback or {}).items()}
        self._feedback_timing = [(self._feedback[n], rx) for n, rx in self._feedback_rx.items()]
        self._attitude_limits = AttitudeLimits.of(params)
        self._attitude = {
            n: (SourceState(n, "attitude", readmit), AttitudeTrack(), t) for n, t in (attitudes or {}).items()
        }
        self._attitude_rejects: dict[str, deque[int]] = {n: deque() for n in self._attitude}
        self._attitude_why: dict[str, str] = {}
        for refs in self._refs.values():
            for r in refs.values():
                r.alone = len(refs) == 1
        # flat lists for what runs on every event: staleness, state changes, health
        self._all_refs = [r for refs in self._refs.values() for r in refs.values()]
        self._all_states = [r.state for r in self._all_refs] + list(self._feedback.values())
        self._all_states += [a[0] for a in self._attitude.values()]
        self._role_states = {role: [r.state for r in refs.values()] for role, refs in self._refs.items()}
        self._weight_floor = {"position": p.min_sigma_m, "heading": math.radians(0.05)}
        self._feedback_rejects: dict[str, deque[int]] = {n: deque() for n in self._feedback}
        self._thrusters = dict(thrusters or {})

    # --- position and heading --------------------------------------------------------------------------

    def position(
        self,
        source: str,
        now_ns: int,
        north: float,
        east: float,
        quality: int | None,
        pred: Prediction | None,
        shape_ne: tuple[float, float, float] | None = None,
    ) -> bool:
        """Test one fix (reference point, local NED). Returns whether it may be used. ``shape_ne``: the
        unit shape of the source's GST error ellipse (`wire.gst_covariance.unit_shape`), which turns the
        prediction test's 3σ of the measured spread into an ellipse of the same size (below)."""
        ref = self._refs["position"][source]
        if quality is not None and quality not in self.p.gga_quality:
            name = GGA_QUALITY_NAMES.get(quality, "")
            ref.state.fail(now_ns, f"GGA quality {quality}{f' ({name})' if name else ''} not accepted")
            return False
        if not (math.isfinite(north) and math.isfinite(east)):
            ref.state.fail(now_ns, "position not finite")
            return False
        return self._check(ref, "position", now_ns, (north, east), pred, shape_ne)

    def heading(self, source: str, now_ns: int, psi: float, pred: Prediction | None) -> bool:
        """Test one heading (rad). Returns whether it may be used."""
        ref = self._refs["heading"][source]
        if not math.isfinite(psi):
            ref.state.fail(now_ns, "heading not finite")
            return False
        return self._check(ref, "heading", now_ns, (psi,), pred)

    @staticmethod
    def _fmt(x: float, lim: _Limits) -> str:
        return f"{x * lim.scale:.3g} {lim.unit}"

    def _check(
        self,
        ref: _Ref,
        role: str,
        now_ns: int,
        v: tuple[float, ...],
        pred: Prediction | None,
        shape_ne: tuple[float, float, float] | None = None,
    ) -> bool:
        """The tests in order (module docstring). The prediction test's gate is g + 3σ + growth·age with σ
        the source's measured spread; with the unit shape S of its GST ellipse (trace 2, as I's) the 3σ
        becomes the reach of the ellipse σ² S toward the innovation d (`ellipse_reach`): a
        Mahalanobis test dᵀ (σ² S)⁻¹ d ≤ 3² widened by the fixed gate and the growth, as
        `beyond_prediction_gate` does with the covariance itself. The spread still sets the size: S only
        says in which direction the receiver's fixes scatter more."""
        tr, st, lim = ref.track, ref.state, ref.limits
        on_track = False
        spike = ref.spike
        if spike is not None:  # after a jump: back on the track before it? (`_spike`)
            on_track = self._spike(ref, now_ns, v[0], spike)
            if not on_track and ref.spike is not None:
                return False
        if tr.good is not None and not on_track:
            dt = (now_ns - tr.good_ns) / NS
            moved = tr.distance(v, tr.good)
            base = lim.jump
            if lim.steps and tr.samples >= MIN_SAMPLES_FOR_VARIANCE:  # the wave motion between fixes
                step = lim.steps * 2.0 * math.sqrt(tr.var)
                if step > base:
                    base = step
            limit = base + lim.rate * dt
            if moved > limit:
                if lim.spike_s and st.usable and spike is None:  # a jump out of use: a spike, perhaps
                    rate = pred.rate if pred is not None else 0.0
                    ref.spike, ref.spike_run = (self._before(ref, rate), tr.good_ns, rate), 0
                fmt = self._fmt
                why = f"jump: moved {fmt(moved, lim)} in {dt:.2g} s (limit {fmt(limit, lim)}"
                if base > lim.jump:  # widened by the source's own steps: say so
                    why += f", {lim.steps:g} × its RMS step of {fmt(base / lim.steps, lim)} + speed × time"
                st.fail(now_ns, why + ")")
                return False
        tr.observe(now_ns, v)
        if tr.start_ns == now_ns and not ref.alone:  # restarted (first value, or back from a gap)
            self._seed(ref, role, now_ns)
        frozen = (now_ns - tr.same_since) / NS  # (`Track.frozen_s`, inline: the track has a value now)
        alternating = (now_ns - tr.alternate_since) / NS
        if lim.freeze_min_s:
            if self._frozen(ref, now_ns, frozen, alternating):
                return False
        else:
            if frozen >= lim.freeze_s:
                st.fail(now_ns, f"frozen: the same value for {frozen:.1f} s")
                return False
            if alternating >= lim.freeze_s:  # (a frozen double buffer: its last two values in turn)
                st.fail(now_ns, f"frozen: alternating between the same two values for {alternating:.1f} s")
                return False
        # (`Track.sigma`, inline)
        sigma = math.sqrt(tr.var) if tr.samples >= MIN_SAMPLES_FOR_VARIANCE else None
        if sigma is not None and sigma > lim.max_sigma:
            st.fail(now_ns, f"variance: measured 1σ {sigma:.2f} m (limit {lim.max_sigma:g} m)")
            return False
        max_age = self.p.prediction_max_age_s
        if pred is not None and (pred.age_s <= max_age or pred.held):
            # Held (`Prediction.held`): in DP, the only references of the DOF were refused while their data
            # kept coming; time alone must not let them take the vessel, so the gate stops growing at
            # the age limit instead of the test ending there.
            innov = tr.distance(v, pred.value)
            spread = sigma or 0.0
            if shape_ne is not None and spread:
                spread *= ellipse_reach(shape_ne, v[0] - pred.value[0], v[1] - pred.value[1])
            limit = lim.gate + 3 * spread + lim.grow * min(pred.age_s, max_age)
            if innov > limit:
                fmt = self._fmt
                why = f"prediction: {fmt(innov, lim)} from the estimate's prediction (gate {fmt(limit, lim)})"
                if pred.age_s > max_age:
                    why += (
                        f"; refused for {pred.age_s:.0f} s while its data kept coming: in DP it is not taken "
                        "back by time (if it is right, switch to manual or standby, then engage DP again)"
                    )
                st.fail(now_ns, why)
                return False
        if ref.alone:  # `_vote` with nothing to vote with (inline: one source per role is the common case)
            if tr.smooth is not None and now_ns - tr.smooth_ns <= ref.timeout_ns:
                st.soft(now_ns, "")
        elif not self._vote(ref, role, now_ns, lim):
            return False
        tr.good, tr.good_ns = v, now_ns  # (`Track.accept`)
        if lim.freeze_min_s and tr.samples:  # a passing value teaches the source's activity (`_frozen`)
            ref.learned += 1
            ref.repeat = learned_repeat(ref.repeat, ref.learned, tr.interval_ns / NS, tr.same_since != now_ns)
        if lim.spike_s:
            ref.recent.append((v[0], now_ns))
        if on_track:  # the samples in a row back on the track (a failing one in between restarts the count)
            ref.spike_run = ref.spike_run + 1 if st.state == SUSPECT else 1
        st.passed(now_ns)
        if on_track and ref.spike_run >= SPIKE_CONFIRM:
            ref.spike = None
            why = f"back on its track of before the jump for {SPIKE_CONFIRM} samples: a spike"
            st.readmit_now(now_ns, why)
        return True

    @staticmethod
    def _frozen(ref: _Ref, now_ns: int, frozen_s: float, alternating_s: float) -> bool:
        """The freeze test with a learned hold (a heading: ``heading_freeze_min_s`` below
        ``heading_freeze_s``), failing the value if its run has outlasted its hold. A gyro's last digit
        changes from nearly every sample to the next in any sea way, and a frozen one should be out in
        about two seconds; on a steady heading in calm water a healthy gyro repeats a 0.1° value for many
        seconds. So each run of repeated values (and of two values in turn: a frozen double buffer) is
        held by the source's own activity, learned from its passing values, as an MRU's attitude is
        (`gateway.references.track.freeze_hold_ns`: at most one false alarm per 10⁹ run starts for
        values drawn independently; the hold is fixed when the run starts, and values that fail are not
        learned, so a freeze does not lengthen the next hold). Not from a paper.

        A heading is not white noise: it turns slowly, so runs cluster where the yaw turns. The learned
        share counts those runs too, which lengthens every hold: a gyro at 0.1° in a 0.5° yaw swing repeats
        about two thirds of its samples and is held 10-12 s, against its longest runs of 1.6 s in an hour
        (tests/test_integrity.py measures this and calm and a sea way)."""
        tr, lim = ref.track, ref.limits
        least, most = int(lim.freeze_min_s * NS), int(lim.freeze_s * NS)
        interval_s = tr.interval_ns / NS
        if tr.same_since == now_ns:  # a new run starts: its hold from the activity so far
            ref.hold_ns = freeze_hold_ns(ref.repeat, interval_s, least, most)
        if tr.alternate_since == now_ns:
            ref.alternate_hold_ns = freeze_hold_ns(ref.repeat, interval_s, least, most)
        if frozen_s * NS >= ref.hold_ns:
            hold = ref.hold_ns / NS
            ref.state.fail(now_ns, f"frozen: the same value for {frozen_s:.1f} s (hold {hold:.1f} s)")
            return True
        if alternating_s * NS >= ref.alternate_hold_ns:
            hold = ref.alternate_hold_ns / NS
            ref.state.fail(
                now_ns,
                f"frozen: alternating between the same two values for {alternating_s:.1f} s "
                f"(hold {hold:.1f} s)",
            )
            return True
        return False

    @staticmethod
    def _before(ref: _Ref, rate: float) -> float:
        """The heading before a jump at the time of the last good value: the median of the last
        `SPIKE_ANCHOR` good values, each moved on to that time at the rate of turn (as offsets from the
        last one, so that 359° and 1° are 2° apart)."""
        last, last_ns = ref.recent[-1]
        offsets = sorted(ssa_scalar(x + rate * (last_ns - t) / NS - last) for x, t in ref.recent)
        return ssa_scalar(last + offsets[len(offsets) // 2])

    def _spike(self, ref: _Ref, now_ns: int, psi: float, spike: tuple[float, int, float]) -> bool:
        """A heading after a jump that took it out of use: whether it is back on its track of before the
        jump, the heading then ψₐ (`_before`) moved on at the estimate's rate of turn rₐ then, within the
        jump allowance grown as the prediction gate grows (g = ``max_rate_deg_s`` / 10, for an error in
        rₐ): |ψ − (ψₐ + rₐ (t − tₐ))| ≤ ``heading_jump_deg`` + g (t − tₐ). A sample off that track fails
        (a burst of wrong values continues; values 0.6 s after the jump pass the ordinary jump test, whose
        allowance grows at ``max_rate_deg_s``, and once fed a real USV's burst to the observer). Past
        ``readmit_s``
        the track is forgotten (``ref.spike`` None) and the ordinary tests and readmission apply: a compass
        that stepped and stayed is a failed compass, not a spike, and is kept out for ``readmit_s`` more
        once it passes.

        Not from a paper: the rule is the DP practice of rejecting a reference's outlier while its
        neighbours are consistent; the track is the compass's own last good values and the estimate's rate
        of turn at the jump, not the prediction of each later moment (the estimate dead-reckons meanwhile,
        and a drifting prediction would hold a good compass out)."""
        psi_a, at_ns, rate = spike
        dt = (now_ns - at_ns) / NS
        lim = ref.limits
        if dt > lim.spike_s:
            ref.spike = None
            return False
        off = abs(ssa_scalar(psi - psi_a - rate * dt))
        limit = lim.jump + lim.grow * dt
        if off <= limit:
            return True
        fmt = self._fmt
        ref.state.fail(
            now_ns, f"jump: {fmt(off, lim)} off its track of before the jump (limit {fmt(limit, lim)})"
        )
        return False

    def _seed(self, ref: _Ref, role: str, now_ns: int) -> None:
        """Start a source's restarted smoothed track where it would be had it never stopped: at its
        value plus the others' lag behind their latest values (`Track.lag`, the component-wise median
        over the fresh ones). A first-order smoothing with a time constant of 5 s passes about a quarter
        of a 9 s wave's motion; a track restarted at its instantaneous value carries all of it, and
        compared at once with a track that has smoothed for minutes, two DGPS with the same data were
        1.7 m apart and both made suspect. Seeded, the two differ by what their values differ by now,
        noise and any real offset: a source back 5 m off is 5 m off its peers from its first fix.
        Not from a paper: like-with-like comparison of the same filter, the lag taken from the peers."""
        lags = []
        for r in self._refs[role].values():
            t = r.track
            if r is ref or t.smooth is None or now_ns - t.smooth_ns > r.timeout_ns:
                continue
            lag = t.lag()
            if lag is not None:
                lags.append(lag)
        if lags:
            ref.track.seed(tuple(_median([lag[i] for lag in lags]) for i in range(len(lags[0]))))

    def _vote(self, ref: _Ref, role: str, now_ns: int, lim: _Limits) -> bool:
        refs = self._refs[role]
        if len(refs) == 1:  # the common case: nothing to vote with, no alarm to raise or clear
            tr = ref.track
            if tr.smooth is not None and now_ns - tr.smooth_ns <= ref.timeout_ns:
                ref.state.soft(now_ns, "")
            return True
        median, diverge = lim.median, lim.diverge

        def fmt(x: float) -> str:
            return self._fmt(x, lim)

        settle = self._settle_ns
        smooth: dict[str, tuple[float, ...]] = {}
        held = False  # a fresh reference left out: restarted and not settled, or late
        for n, r in refs.items():
            t = r.track
            if t.smooth is None or now_ns - t.smooth_ns > r.timeout_ns:
                continue
            if now_ns - t.start_ns < settle or now_ns - t.smooth_ns > VOTE_LATE * t.interval_ns:
                held = True
                continue
            smooth[n] = t.smooth
        name = ref.state.source
        angle = role == "heading"
        if name not in smooth:
            if now_ns - ref.track.start_ns < settle:  # restarted: not judged, nor judging, until settled
                ref.state.soft(now_ns, "")
            return True
        if len(smooth) >= 3:
            d = median_distance(smooth, name, angle)
            if d > median:
                ref.state.fail(now_ns, f"median: {fmt(d)} from the median of {len(smooth)} references")
                return False
            ref.state.soft(now_ns, "")
        elif len(smooth) == 2:
            (other,) = (n for n in smooth if n != name)
            d = divergence(smooth[name], smooth[other], angle)
            if d > diverge:
                why = f"diverges from {{}} by {fmt(d)} (limit {fmt(diverge)}): cannot tell which is wrong"
                ref.state.soft(now_ns, why.format(other))
                refs[other].state.soft(now_ns, why.format(name))
            elif d < DIVERGENCE_CLEAR * diverge:
                ref.state.soft(now_ns, "")
                refs[other].state.soft(now_ns, "")
        elif not held:  # alone among fresh references: no alarm (one held out is judged when it is back)
            ref.state.soft(now_ns, "")
        return True

    # --- attitude (MRU) ----------------------------------------------------------------------------------

    def attitude(
        self,
        source: str,
        now_ns: int,
        roll: float,
        pitch: float,
        utc_s: float | None = None,
        sigmas: tuple[float | None, float | None] = (None, None),
    ) -> bool:
        """Test one MRU sample (rad; `AttitudeTrack.problem`). Returns whether it may be used: it passed,
        and the source is not rejected or readmitting. A failing sample is never used; it rejects the
        source when ``attitude_rejects`` samples failed within ``readmit_s``, and at once while the source
        is not in use (rejected, readmitting, stale, or not heard from yet: there are no good samples
        around it to keep, and a failing MRU is not silent): an MRU sends 10-100 samples a second, and one
        outlier (a spike)
        is dropped while its neighbours go on compensating the fixes, where taking the MRU out for
        ``readmit_s`` would switch every fix to heading only and back (which costs the observer a
        transient, docs/integrity.md). A frozen, offset or out-of-range MRU fails every sample and is
        rejected on the third."""
        st, track, timeout_ns = self._attitude[source]
        why = track.problem(self._attitude_limits, now_ns, timeout_ns, roll, pitch, utc_s, sigmas)
        recent = self._attitude_rejects[source]
        while recent and now_ns - recent[0] > st.readmit_ns:
            recent.popleft()
        if why:
            recent.append(now_ns)
            if len(recent) >= self.p.attitude_rejects or st.state != OK:
                st.fail(now_ns, why)
            self._attitude_why[source] = why
            return False
        self._attitude_why[source] = ""
        st.passed(now_ns)
        return st.usable

    def attitude_problem(self, source: str) -> str:
        """Why the MRU's latest sample failed (its test's name first); "" when it passed."""
        return self._attitude_why.get(source, "")

    def attitude_usable(self, source: str) -> bool:
        """The MRU is in use: neither rejected, readmitting nor stale."""
        return self._attitude[source][0].usable

    # --- thruster feedback -------------------------------------------------------------------------------

    def feedback(
        self,
        source: str,
        now_ns: int,
        thruster_id: int,
        thrust_n: float | None,
        azimuth_rad: float | None,
        rpm: float | None,
    ) -> str:
        """Range-check one thruster report: "" if it may be used, else why not. ``feedback_rejects``
        rejects within ``readmit_s`` reject the source (`feedback_usable` False) until it is clean that
        long; one rejects it at once while it is not in use (rejected, readmitting, stale, or not heard
        from yet), as for an MRU (`attitude`). Every report, passing or failing, keeps it from going
        stale (`refresh`)."""
        st = self._feedback[source]
        why = feedback_problem(
            self._thrusters.get(thruster_id), thrust_n, azimuth_rad, rpm, self.p.thrust_margin
        )
        self._feedback_rx[source][1] = now_ns
        recent = self._feedback_rejects[source]
        while recent and now_ns - recent[0] > st.readmit_ns:
            recent.popleft()
        if why:
            recent.append(now_ns)
            if len(recent) >= self.p.feedback_rejects or st.state != OK:
                st.fail(now_ns, f"{len(recent)} out-of-range reports in {self.p.readmit_s:g} s, last: {why}")
            return f"thruster {thruster_id}: {why}"
        st.passed(now_ns)
        return ""

    def feedback_usable(self, source: str) -> bool:
        st = self._feedback.get(source)
        return st is None or st.usable

    # --- reading -----------------------------------------------------------------------------------------

    def refresh(self, now_ns: int, refused: Callable[[str, int, int], str | None] | None = None) -> None:
        """Sources silent past their timeout become stale. Silent: nothing received, passing or failing.
        The track's time is that of the last value past the jump test, so a DGPS sending GGA quality 6
        (dead reckoning), or fixes 100 m off, for longer than its timeout used to become ``stale: no data
        for 2.0 s`` while its sentences kept coming: the alarm sent the engineer to the cable and lost the
        reason. It stays ``rejected`` with that reason while its data keep failing. An MRU and a thruster
        feedback source are timed from their latest sample or report, whatever it was, for the same rule:
        stale once silent, never while their data keep coming and failing.

        ``refused(source, now_ns, timeout_ns)``: what the source's reads within ``timeout_ns`` were refused
        for before any test here (a decoder's reject: no checksum, a bad one, garbage), or None when it
        has not been read within that time. A source whose reads keep coming and are all refused talks:
        it is ``rejected`` with that reason, not ``stale: no data``, which sent the engineer to the cable
        while the status said `no valid data (3 rejected: no_checksum 3)`."""
        for r in self._all_refs:
            last = r.track.last_ns
            if last and now_ns - last <= r.timeout_ns:
                continue
            st = r.state
            if st.failing(now_ns, r.timeout_ns):
                continue
            why = refused(st.source, now_ns, r.timeout_ns) if refused is not None else None
            if why is not None:
                ago = f"for {(now_ns - last) / NS:.1f} s" if last else "yet"
                st.refuse_reads(now_ns, f"no valid data {ago}: its reads are refused ({why})")
            elif last:
                st.stale(now_ns, (now_ns - max(last, st.failed_ns)) / NS)
        for st, track, timeout_ns in self._attitude.values():
            last = track.rx_ns  # (every sample, passing or failing: a failing MRU talks)
            if last and now_ns - last > timeout_ns:
                st.stale(now_ns, (now_ns - last) / NS)
        for st, (timeout_ns, last) in self._feedback_timing:  # (every report, passing or failing)
            if last and now_ns - last > timeout_ns:
                st.stale(now_ns, (now_ns - last) / NS)

    def usable(self, role: str, source: str) -> bool:
        r = self._refs[role].get(source)
        return r is not None and r.state.usable

    def beyond_prediction_gate(
        self,
        role: str,
        value: tuple[float, ...],
        predicted: tuple[float, ...],
        cov_ne: tuple[float, float, float] | None = None,
    ) -> str:
        """Whether ``value`` lies outside the prediction test's gate around ``predicted`` (the gate
        without its growth with age, grown by the 3σ error ellipse of the position's covariance
        ``cov_ne`` = (C_NN, C_NE, C_EE) when given), in words for an event ("6.2 m from the dead-reckoned
        estimate (gate 5 m)"); "" inside. What the pipeline asks of a reference that comes back after an
        outage (`Pipeline._reacquire`).

        With the covariance the gate is the fixed gate g plus the reach of the 3σ ellipse in the
        innovation's direction u = d / ‖d‖ (`ellipse_reach`)::

            ‖d‖ ≤ g + 3 / √(uᵀ C⁻¹ u)

        which for g = 0 is the Mahalanobis test dᵀ C⁻¹ d ≤ 3², and for a circle C = σ² I the gate g + 3σ
        of a scalar σ: a fix off along the receiver's narrow axis is caught sooner than one off along its
        wide axis."""
        lim = self._limits[role]
        off = divergence(value, predicted, angle=role == "heading")
        gate = lim.gate
        if cov_ne is not None and off > gate:
            gate += 3.0 * ellipse_reach(cov_ne, value[0] - predicted[0], value[1] - predicted[1])
        if off <= gate:
            return ""
        return f"{self._fmt(off, lim)} from the dead-reckoned estimate (gate {self._fmt(gate, lim)})"

    def sigma_m(self, source: str) -> float | None:
        """A position source's measured 1σ noise (m), once measured."""
        r = self._refs["position"].get(source)
        return None if r is None else r.track.sigma()

    def weight(self, role: str, source: str) -> float:
        """Inverse measured variance (floored), the weight of the source when references are pooled."""
        r = self._refs[role][source]
        floor = self._weight_floor[role]
        s = max(r.track.sigma() or floor, floor)
        return 1.0 / (s * s)

    def health(self, role: str) -> RoleHealth:
        states = self._role_states[role]
        if len(states) == 1:  # (one source: the common case, asked for every estimate)
            st = states[0]
            return "ok" if st.state == OK else "degraded" if st.usable else "lost"
        if not states or not any(s.usable for s in states):
            return "lost"
        return "ok" if all(s.state == OK for s in states) else "degraded"

    def states(self) -> dict[str, list[SourceState]]:
        """Source name → its states (one per role it has)."""
        out: dict[str, list[SourceState]] = {}
        for refs in self._refs.values():
            for n, r in refs.items():
                out.setdefault(n, []).append(r.state)
        for n, st in self._feedback.items():
            out.setdefault(n, []).append(st)
        for n, (st, _, _) in self._attitude.items():
            out.setdefault(n, []).append(st)
        return out

    def drain(self) -> list[StateChange]:
        """The state changes since the last call, in order."""
        for s in self._all_states:
            if s.changes:
                break
        else:
            return []  # (nothing changed: the common case, asked after every event)
        changes = [c for states in self.states().values() for s in states for c in s.drain()]
        return sorted(changes, key=lambda c: c.stamp_ns)

    def reason(self, role: str, source: str) -> str:
        if role == "attitude":
            return self._attitude[source][0].reason
        return self._refs[role][source].state.reason

    def refused_while_talking(self, role: str) -> bool:
        """Whether a source of ``role`` is out of use while its data keep coming (rejected, or readmitting:
        tested and refused or not yet trusted), as opposed to silent (stale)."""
        for st in self._role_states[role]:
            if st.state == REJECTED or (st.state == SUSPECT and not st.usable):
                return True
        return False

    def is_stale(self, role: str, source: str) -> bool:
        return self._refs[role][source].state.state == STALE


def _median(xs: list[float]) -> float:
    """The median of a few values (the mean of the middle two of an even count)."""
    xs = sorted(xs)
    k = len(xs) // 2
    return xs[k] if len(xs) % 2 else 0.5 * (xs[k - 1] + xs[k])
