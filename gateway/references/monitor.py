"""The reference tests for all of a gateway's sources: what the pipeline asks before it uses a fix, a
heading or a thruster report, and what it reports (states, reasons, state changes, per-role health).

Every fix goes through, in order (the first failure rejects it, with that reason):
quality → jump/rate (against the source's last good value, allowance + speed × time) → freeze → variance →
prediction (against the observer's prediction, gated by the expected spread) → median of ≥ 3 references.
With exactly two references of a role their divergence raises a soft alarm on both (still used: nobody can
tell which is wrong). A rejected source is used again after passing for ``readmit_s``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from gateway.references.feedback import feedback_problem
from gateway.references.params import IntegrityParams
from gateway.references.state import NS, OK, STALE, SourceState, StateChange
from gateway.references.track import Track
from gateway.references.voting import divergence, median_distance
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


@dataclass(frozen=True)
class Prediction:
    """Where the observer expects the next value (N, E) or (ψ,), and how long since the estimate last had
    a measurement of that DOF (s): an old prediction is trusted less, and not at all past a limit."""

    value: tuple[float, ...]
    age_s: float


@dataclass
class _Ref:
    state: SourceState
    track: Track
    timeout_ns: int


class ReferenceMonitor:
    def __init__(
        self,
        params: IntegrityParams,
        positions: Mapping[str, int],
        headings: Mapping[str, int],
        feedback: Mapping[str, int] | None = None,
        thrusters: Mapping[int, Thruster] | None = None,
    ) -> None:
        """``positions``, ``headings``, ``feedback``: source name → its timeout (ns)."""
        self.p = params
        readmit = int(params.readmit_s * NS)
        self._refs: dict[str, dict[str, _Ref]] = {
            "position": {
                n: _Ref(SourceState(n, "position", readmit), Track(params.smoothing_s), t)
                for n, t in positions.items()
            },
            "heading": {
                n: _Ref(SourceState(n, "heading", readmit), Track(params.smoothing_s, angle=True), t)
                for n, t in headings.items()
            },
        }
        self._feedback = {n: SourceState(n, "thrusters", readmit) for n in (feedback or {})}
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
    ) -> bool:
        """Test one fix (reference point, local NED). Returns whether it may be used."""
        ref = self._refs["position"][source]
        p = self.p
        if quality is not None and quality not in p.gga_quality:
            name = GGA_QUALITY_NAMES.get(quality, "")
            ref.state.fail(now_ns, f"GGA quality {quality}{f' ({name})' if name else ''} not accepted")
            return False
        if not (math.isfinite(north) and math.isfinite(east)):
            ref.state.fail(now_ns, "position not finite")
            return False
        return self._check(
            ref,
            "position",
            now_ns,
            (north, east),
            pred,
            jump=p.jump_m,
            rate=p.max_speed_m_s,
            freeze_s=p.freeze_s,
            gate=p.prediction_gate_m,
            median=p.median_m,
            diverge=p.divergence_m,
            unit="m",
            scale=1.0,
        )

    def heading(self, source: str, now_ns: int, psi: float, pred: Prediction | None) -> bool:
        """Test one heading (rad). Returns whether it may be used."""
        ref = self._refs["heading"][source]
        p = self.p
        if not math.isfinite(psi):
            ref.state.fail(now_ns, "heading not finite")
            return False
        deg = math.radians(1.0)
        return self._check(
            ref,
            "heading",
            now_ns,
            (psi,),
            pred,
            jump=p.heading_jump_deg * deg,
            rate=p.max_rate_deg_s * deg,
            freeze_s=p.heading_freeze_s,
            gate=p.prediction_gate_deg * deg,
            median=p.heading_median_deg * deg,
            diverge=p.heading_divergence_deg * deg,
            unit="°",
            scale=1 / deg,
        )

    def _check(
        self,
        ref: _Ref,
        role: str,
        now_ns: int,
        v: tuple[float, ...],
        pred: Prediction | None,
        *,
        jump: float,
        rate: float,
        freeze_s: float,
        gate: float,
        median: float,
        diverge: float,
        unit: str,
        scale: float,
    ) -> bool:
        tr, st, p = ref.track, ref.state, self.p

        def fmt(x: float) -> str:
            return f"{x * scale:.3g} {unit}"

        if tr.good is not None:
            dt = (now_ns - tr.good_ns) / NS
            moved = tr.distance(v, tr.good)
            limit = jump + rate * dt
            if moved > limit:
                st.fail(now_ns, f"jump: moved {fmt(moved)} in {dt:.2g} s (limit {fmt(limit)})")
                return False
        tr.observe(now_ns, v)
        frozen = tr.frozen_s(now_ns)
        if frozen >= freeze_s:
            st.fail(now_ns, f"frozen: the same value for {frozen:.1f} s")
            return False
        sigma = tr.sigma()
        if role == "position" and sigma is not None and sigma > p.max_sigma_m:
            st.fail(now_ns, f"variance: measured 1σ {sigma:.2f} m (limit {p.max_sigma_m:g} m)")
            return False
        if pred is not None and pred.age_s <= p.prediction_max_age_s:
            grow = (p.max_speed_m_s if role == "position" else p.max_rate_deg_s * math.pi / 180) / 10
            limit = gate + 3 * (sigma or 0.0) + grow * pred.age_s
            innov = tr.distance(v, pred.value)
            if innov > limit:
                st.fail(
                    now_ns, f"prediction: {fmt(innov)} from the estimate's prediction (gate {fmt(limit)})"
                )
                return False
        if not self._vote(ref, role, now_ns, median, diverge, fmt):
            return False
        tr.accept(now_ns, v)
        st.passed(now_ns)
        return True

    def _vote(self, ref: _Ref, role: str, now_ns: int, median: float, diverge: float, fmt: object) -> bool:
        refs = self._refs[role]
        smooth = {
            n: r.track.smooth
            for n, r in refs.items()
            if r.track.smooth is not None and now_ns - r.track.smooth_ns <= r.timeout_ns
        }
        name = ref.state.source
        angle = role == "heading"
        assert callable(fmt)
        if name not in smooth:
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
        else:
            ref.state.soft(now_ns, "")
        return True

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
        """Range-check one thruster report: "" if it may be used, else why not. Enough rejects within
        ``readmit_s`` make the source suspect (`feedback_usable` False) until it is clean that long."""
        st = self._feedback[source]
        why = feedback_problem(
            self._thrusters.get(thruster_id), thrust_n, azimuth_rad, rpm, self.p.thrust_margin
        )
        recent = self._feedback_rejects[source]
        while recent and now_ns - recent[0] > st.readmit_ns:
            recent.popleft()
        if why:
            recent.append(now_ns)
            if len(recent) >= self.p.feedback_rejects or st.state not in (OK, STALE):
                st.fail(now_ns, f"{len(recent)} out-of-range reports in {self.p.readmit_s:g} s, last: {why}")
            return f"thruster {thruster_id}: {why}"
        st.passed(now_ns)
        return ""

    def feedback_usable(self, source: str) -> bool:
        st = self._feedback.get(source)
        return st is None or st.usable

    # --- reading -----------------------------------------------------------------------------------------

    def refresh(self, now_ns: int) -> None:
        """Sources silent past their timeout become stale."""
        for refs in self._refs.values():
            for r in refs.values():
                last = r.track.last_ns
                if last and now_ns - last > r.timeout_ns:
                    r.state.stale(now_ns, (now_ns - last) / NS)

    def usable(self, role: str, source: str) -> bool:
        r = self._refs[role].get(source)
        return r is not None and r.state.usable

    def sigma_m(self, source: str) -> float | None:
        """A position source's measured 1σ noise (m), once measured."""
        r = self._refs["position"].get(source)
        return None if r is None else r.track.sigma()

    def weight(self, role: str, source: str) -> float:
        """Inverse measured variance (floored), the weight of the source when references are pooled."""
        r = self._refs[role][source]
        floor = self.p.min_sigma_m if role == "position" else math.radians(0.05)
        s = max(r.track.sigma() or floor, floor)
        return 1.0 / (s * s)

    def health(self, role: str) -> RoleHealth:
        states = [r.state for r in self._refs[role].values()]
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
        return out

    def drain(self) -> list[StateChange]:
        """The state changes since the last call, in order."""
        changes = [c for states in self.states().values() for s in states for c in s.drain()]
        return sorted(changes, key=lambda c: c.stamp_ns)

    def reason(self, role: str, source: str) -> str:
        return self._refs[role][source].state.reason

    def is_stale(self, role: str, source: str) -> bool:
        return self._refs[role][source].state.state == STALE
