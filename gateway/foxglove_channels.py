"""Foxglove-native channels derived from the pipeline's own outputs, beside the JSON ones.

The pipeline hands every list of outputs it makes to `FoxgloveChannels.derive`, which returns the Foxglove
messages that mirror them (values converted to Foxglove's frames by `wire.foxglove`, which states the
convention): so live, replay and the live Foxglove server (it mirrors every output) carry the same channels
from the same numbers, and the JSON channels stay as they are for the programs that read them.

What comes from what, and how often (docs/foxglove.md has the reasons):
- `/dp/estimate` → `/dp/estimate/fix` (LocationFix with the heading, for the map), `/dp/estimate/pose`
  and the `ltp` → `vessel` transform on `/dp/tf`; the `/dp/measurement` of the same step →
  `/dp/measurement/pose` and `ltp` → `vessel_measured` (only when N, E and ψ were all measured). At the
  estimate's rate up to ~5 Hz (`POSE_PERIOD_NS`): a 3D view or a map of a DP vessel moves smoothly at
  that, and an estimate stepped at 10-50 Hz would otherwise multiply the log's size and the replay's
  time (the JSON channels keep every step, for plots).
- the hull (`/dp/scene/hull`): with the first estimate, then every `STATIC_PERIOD_NS`, so a player that
  seeks into the middle of a log finds it within that time. With it, on `/dp/tf`, each GNSS antenna's
  frame (`vessel` → the source's name, at its lever arm): the frame its `/gnss/<source>/fix` is in.
- `/dp/thrusters/command` → commanded arrows; `/dp/thrusters/feedback` → fed-back arrows, at most
  every `ARROW_PERIOD_NS` (`/dp/scene/thrusters`).
- the DP setpoint and its watch circles (`/dp/scene/setpoint`): when the setpoint changes, and every
  `STATIC_PERIOD_NS` while in dp; deleted when dp is left.
- `/dp/status` → `/dp/log`: each reference state change, and each alarm raised or cleared (`logs`, which
  the pipeline calls with every status it makes, so the lines go out right after their status).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Protocol

from gateway.alarms import alarm_key
from observers.vessel import Thruster, VesselModel
from wire import foxglove as fx
from wire.messages import (
    ArrowPrimitive,
    Color,
    Estimate,
    Measurement,
    Message,
    SceneUpdate,
    Status,
    ThrusterCommand,
    ThrusterFeedback,
)
from wire.messages import FrameTransforms as FrameTransformsMessage

NS = 1_000_000_000
STATIC_PERIOD_NS = 10 * NS
"""The hull and the setpoint are repeated this often (a player seeking into a log shows them within it)."""
POSE_PERIOD_NS = 190_000_000
"""Least time between two poses, frames and estimate fixes: ~5 Hz, a little under 200 ms so that a 5 Hz
source's steps all pass despite their receive-time jitter. A DP vessel's LF motion has periods of tens of
seconds and its wave motion of 5-15 s, so 5 Hz draws both smoothly; 10 Hz cost a replay twice as much
(docs/foxglove.md)."""
ARROW_PERIOD_NS = NS // 10
"""Fed-back thruster arrows at most 10 Hz: a drive may report at 50 Hz, more than a 3D view can show."""
WATCH_CIRCLES_M = (5.0, 10.0)
"""Default watch circles around the setpoint (warning, alarm), m, when the config gives none."""
BEAM_PER_LENGTH = 0.2
"""Beam from length when the vessel file has no `[hull]` beam (L/B ≈ 5, a supply vessel's)."""

COMMANDED = fx.color(0.2, 0.6, 1.0, 0.9)
FED_BACK = fx.color(1.0, 0.55, 0.0, 0.9)
HULL = fx.color(0.9, 0.9, 0.9, 1.0)
SETPOINT = fx.color(0.1, 0.9, 0.3, 1.0)
WATCH = (fx.color(1.0, 0.85, 0.0, 0.9), fx.color(1.0, 0.2, 0.2, 0.9))

_NEW_STATE = re.compile(r" -> (\w+)")
_STATE_LEVEL = {
    "ok": fx.LOG_INFO,
    "stale": fx.LOG_WARNING,
    "suspect": fx.LOG_WARNING,
    "rejected": fx.LOG_ERROR,
}


class _Output(Protocol):
    """What the pipeline's `Output` offers (that class lives above this module)."""

    @property
    def topic(self) -> str: ...
    @property
    def message(self) -> Message: ...
    @property
    def stamp_ns(self) -> int: ...


def alarm_text(alarm: str | dict[str, Any]) -> str:
    """A status's alarm as one line: a text as it is, an object (``code``, ``message``) as "code: message"."""
    return alarm if isinstance(alarm, str) else f"{alarm.get('code', '?')}: {alarm.get('message', '')}"


class AlarmChanges:
    """The alarms raised and cleared since the last status, each alarm known by `alarm_key`: what every log
    of alarms (this `/dp/log`, Keelson's `log_message`) says, rather than the whole list at every status."""

    def __init__(self) -> None:
        self.active: dict[str, str] = {}  # alarm_key -> text, of the alarms active at the last status
        self.raised_ns: dict[str, int] = {}  # alarm_key -> the stamp of the status that raised it

    def update(
        self, alarms: Iterable[str | dict[str, Any]], now_ns: int | None = None
    ) -> tuple[list[str], list[str]]:
        """(raised, cleared) texts since the last call, each in the order the statuses listed them. With
        the status's stamp ``now_ns``, a cleared alarm's text ends with how long it was up, "(up 5.5 s)":
        its own figures are those of the last status that listed it, which for a log made of few statuses
        (a replay's, at state changes) are those it was raised with ("dead reckoning for 0 s")."""
        now = {alarm_key(t): t for t in map(alarm_text, alarms)}
        raised = [t for k, t in now.items() if k not in self.active]
        cleared = []
        for k, t in self.active.items():
            if k in now:
                continue
            since = self.raised_ns.pop(k, None)
            up = f" (up {(now_ns - since) / 1e9:.1f} s)" if now_ns is not None and since is not None else ""
            cleared.append(t + up)
        if now_ns is not None:
            for k in now:
                self.raised_ns.setdefault(k, now_ns)
        self.active = now
        return raised, cleared


def raised_critical(status: Status) -> set[str]:
    """The texts of a status's critical alarms (`Status.alarm_details`, `gateway.alarms.alarm_level`):
    raised, they are logged at ERROR, the rest at WARNING."""
    details = status.alarm_details
    if not details:
        return set()
    return {alarm_text(a) for a, d in zip(status.alarms, details, strict=False) if d.level == "critical"}


def state_change_level(text: str) -> int:
    """The Foxglove log level (`foxglove.Log`'s, which Keelson's `log_message` shares) of a reference state
    change's text (``"<role> reference <source>: <old> -> <new>[: why]"``): that of its new state, INFO
    back to ok, WARNING stale or suspect, ERROR rejected; INFO for a mode change (``"mode: <old> -> <new>
    (<who>)"``); WARNING for a text of another form."""
    if text.startswith("mode: "):  # a mode change (`Pipeline._control`, the gateway's own engagement)
        return fx.LOG_INFO
    m = _NEW_STATE.search(text)
    return _STATE_LEVEL.get(m.group(1), fx.LOG_WARNING) if m else fx.LOG_WARNING


class FoxgloveChannels:
    def __init__(
        self,
        vessel: VesselModel,
        watch_circles_m: Sequence[float] = WATCH_CIRCLES_M,
        antennas: Mapping[str, tuple[float, float, float]] | None = None,
    ) -> None:
        """``antennas``: GNSS source -> its antenna's lever arm (m, x forward, y starboard, z down), the
        frames its fixes are given in (`fx.antenna_frame`)."""
        self.vessel = vessel
        self.antennas = dict(antennas or {})
        self.watch_circles_m = tuple(watch_circles_m)
        self.beam_m = vessel.hull.beam_m if vessel.hull is not None else BEAM_PER_LENGTH * vessel.length_m
        self.arrow_scale_m = 0.25 * vessel.length_m  # an arrow at full thrust: a quarter of the hull
        self._thrusters: dict[int | str, Thruster] = {t.id: t for t in vessel.thrusters}
        self._next_hull_ns = 0
        self._next_pose_ns = 0
        self._next_feedback_ns = 0
        self._setpoint: tuple[float, float, float] | None = None
        self._next_setpoint_ns = 0
        self._alarms = AlarmChanges()

    # --- what the pipeline calls ----------------------------------------------------------------------------

    def derive(self, outputs: Sequence[_Output]) -> list[tuple[str, Message, int]]:
        """(topic, message, stamp) of the Foxglove channels that mirror ``outputs`` (the pipeline's, in
        order). Not the log lines of a status: those go out with the status itself (`logs`)."""
        out: list[tuple[str, Message, int]] = []
        measured: Measurement | None = None
        for o in outputs:
            msg, ns = o.message, o.stamp_ns
            kind = type(msg)
            if kind is Measurement:
                measured = msg  # type: ignore[assignment]
            elif kind is Estimate and o.topic == "/dp/estimate":  # (not a side-by-side observer's)
                self._estimate(msg, measured, ns, out)  # type: ignore[arg-type]
                measured = None
            elif kind is ThrusterCommand:
                scene = self._arrows(msg, "command", COMMANDED, ns)  # type: ignore[arg-type]
                out.append(("/dp/scene/thrusters", scene, ns))
            elif kind is ThrusterFeedback and ns >= self._next_feedback_ns:
                self._next_feedback_ns = ns + ARROW_PERIOD_NS
                scene = self._arrows(msg, "feedback", FED_BACK, ns)  # type: ignore[arg-type]
                out.append(("/dp/scene/thrusters", scene, ns))
        return out

    def setpoint(
        self, target: tuple[float, float, float] | None, now_ns: int
    ) -> list[tuple[str, Message, int]]:
        """The setpoint scene when the DP target (N, E, ψ; None outside dp) changed, or is due again."""
        if target == self._setpoint and (target is None or now_ns < self._next_setpoint_ns):
            return []
        was, self._setpoint = self._setpoint, target
        self._next_setpoint_ns = now_ns + STATIC_PERIOD_NS
        if target is None:
            gone = SceneUpdate(deletions=[fx.deletion(now_ns, "setpoint")], entities=[]) if was else None
            return [] if gone is None else [("/dp/scene/setpoint", gone, now_ns)]
        return [("/dp/scene/setpoint", self._setpoint_scene(target, now_ns), now_ns)]

    # --- the channels ---------------------------------------------------------------------------------------

    def _estimate(
        self, est: Estimate, measured: Measurement | None, ns: int, out: list[tuple[str, Message, int]]
    ) -> None:
        n, e, psi = est.eta
        if ns < self._next_pose_ns or not (math.isfinite(n) and math.isfinite(e) and math.isfinite(psi)):
            return
        self._next_pose_ns = ns + POSE_PERIOD_NS
        if est.lat_deg is not None and est.lon_deg is not None:
            out.append(
                (
                    "/dp/estimate/fix",
                    fx.location_fix(ns, fx.VESSEL_FRAME, est.lat_deg, est.lon_deg, heading_rad=psi),
                    ns,
                )
            )
        # The pose and the frame of one point share their stamp and pose objects (values, never changed):
        # the same messages as `fx.frame_transform` and `fx.pose_in_frame` give, built once.
        stamp = fx.stamp(ns)
        pose = fx.ned_pose(n, e, psi)
        transforms = [fx.frame_transform_of(stamp, fx.VESSEL_FRAME, pose)]
        out.append(("/dp/estimate/pose", fx.pose_in_frame_of(stamp, pose), ns))
        if measured is not None and all(measured.valid):
            mn, me, mpsi = measured.eta
            assert mn is not None and me is not None and mpsi is not None  # valid: measured, not null
            pose = fx.ned_pose(mn, me, mpsi)
            transforms.append(fx.frame_transform_of(stamp, fx.MEASURED_FRAME, pose))
            out.append(("/dp/measurement/pose", fx.pose_in_frame_of(stamp, pose), ns))
        out.append(("/dp/tf", FrameTransformsMessage(transforms=transforms), ns))
        if ns >= self._next_hull_ns:
            self._next_hull_ns = ns + STATIC_PERIOD_NS
            out.append(("/dp/scene/hull", self._hull(ns), ns))
            if self.antennas:  # (fixed: with the hull, so a player that seeks finds them within its period)
                antennas = [fx.antenna_transform(ns, src, arm) for src, arm in sorted(self.antennas.items())]
                out.append(("/dp/tf", FrameTransformsMessage(transforms=antennas), ns))

    def _hull(self, ns: int) -> SceneUpdate:
        v = self.vessel
        outline = fx.line(fx.hull_outline(v.length_m, self.beam_m), HULL)
        heading = fx.arrow(0.0, 0.0, 0.0, 0.3 * v.length_m, HULL, 0.01 * v.length_m)  # the bow's direction
        meta = {"vessel": v.name, "length_m": f"{v.length_m:g}", "beam_m": f"{self.beam_m:g}"}
        return SceneUpdate(
            deletions=[],
            entities=[
                fx.entity(ns, fx.VESSEL_FRAME, "hull", lines=[outline], arrows=[heading], metadata=meta)
            ],
        )

    def _arrows(
        self, msg: ThrusterCommand | ThrusterFeedback, what: str, rgba: Color, ns: int
    ) -> SceneUpdate:
        arrows: list[ArrowPrimitive] = []
        meta: dict[str, str] = {}
        for th in msg.thrusters:
            spec = self._thrusters.get(th.id)
            if spec is None or not (math.isfinite(th.thrust_n) and math.isfinite(th.azimuth_rad)):
                continue
            arrows.append(
                fx.thrust_arrow(
                    spec.x_m, spec.y_m, th.thrust_n, th.azimuth_rad, spec.max_thrust_n, self.arrow_scale_m,
                    rgba,
                )
            )  # fmt: skip
            meta[f"{th.id}"] = f"{th.thrust_n:.0f} N at {math.degrees(th.azimuth_rad):.1f}°"
        ent = fx.entity(ns, fx.VESSEL_FRAME, f"thrusters/{what}", arrows=arrows, metadata=meta)
        return SceneUpdate(deletions=[], entities=[ent])

    def _setpoint_scene(self, target: tuple[float, float, float], ns: int) -> SceneUpdate:
        n, e, psi = target
        length = self.vessel.length_m
        lines = [fx.line(fx.circle(e, n, r), WATCH[min(k, 1)]) for k, r in enumerate(self.watch_circles_m)]
        heading = fx.arrow(e, n, fx.heading_yaw(psi), 0.3 * length, SETPOINT, 0.01 * length)
        meta = {"north_m": f"{n:.2f}", "east_m": f"{e:.2f}", "heading_deg": f"{math.degrees(psi) % 360:.1f}"}
        meta |= {f"watch_circle_{k + 1}_m": f"{r:g}" for k, r in enumerate(self.watch_circles_m)}
        ent = fx.entity(
            ns, fx.WORLD_FRAME, "setpoint", frame_locked=False, arrows=[heading], lines=lines, metadata=meta
        )
        return SceneUpdate(deletions=[], entities=[ent])

    def logs(self, status: Status) -> list[tuple[str, Message, int]]:
        """Log lines for a status: each reference state change (INFO back to ok, WARNING stale or suspect,
        ERROR rejected), each alarm raised (WARNING) or cleared (INFO) since the status before, all at the
        status's stamp. Call it once for every status that is logged, in their order, and write the lines
        right after their status: so the file stays in log-time order (a line held for a later call was
        written after records of later times, and a reader streaming the file saw time go back)."""
        ns = status.stamp_ns
        out: list[tuple[str, Message, int]] = []
        for text in status.events:
            out.append(("/dp/log", fx.log(ns, state_change_level(text), text, "dpgw.reference"), ns))
        raised, cleared = self._alarms.update(status.alarms, ns)
        critical = raised_critical(status)
        lines = [(fx.LOG_ERROR if t in critical else fx.LOG_WARNING, f"alarm: {t}") for t in raised]
        lines += [(fx.LOG_INFO, f"alarm cleared: {t}") for t in cleared]
        out += [("/dp/log", fx.log(ns, level, text, "dpgw.alarm"), ns) for level, text in lines]
        return out
