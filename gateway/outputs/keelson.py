"""Keelson output: dpgw's streams under Keelson's key space on the gateway's Zenoh session.

Keelson (RISE's maritime key space on Zenoh; the `keelson` package, docs/keelson.md names the version) fixes
three things, all followed here with the package's own helpers and message classes:
- the key ``{base_path}/@v0/{entity_id}/pubsub/{subject}/{source_id}`` (`keelson.construct_pubsub_key`);
- the payload: a protobuf ``core.Envelope`` (``enclosed_at`` = when it was enclosed, this computer's clock)
  holding the subject's well-known payload type (``subjects.yaml``: ``keelson.TimestampedFloat``,
  ``foxglove.LocationFix``, ``keelson.Decomposed3DVector``, ``keelson.TimestampedString``,
  ``foxglove.Log``), whose own ``timestamp`` is the event time dpgw stamped the output with;
- presence: one liveliness token per source id, ``{base_path}/@v0/{entity_id}/pubsub/*/{source_id}``.

Units are the subject's (its name ends in them): dpgw's SI values and radians become degrees, deg/s and
knots here, at the edge. The mapping table (dpgw field → subject, source id, unit) is in docs/keelson.md;
the code below is that table, one function per dpgw message.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import keelson
from keelson.payloads.Decomposed3DVector_pb2 import Decomposed3DVector
from keelson.payloads.foxglove.LocationFix_pb2 import LocationFix as PbLocationFix
from keelson.payloads.foxglove.Log_pb2 import Log
from keelson.payloads.Primitives_pb2 import TimestampedFloat, TimestampedString

from gateway.config import GatewayConfig, KeelsonConfig
from gateway.foxglove_channels import AlarmChanges, raised_critical, state_change_level
from gateway.outputs.base import SettlingChanges
from wire.geodesy import LocalFrame
from wire.messages import (
    Estimate,
    LocationFix,
    Measurement,
    Status,
    ThrusterCommand,
    ThrusterFeedback,
)

if TYPE_CHECKING:
    import zenoh
    from google.protobuf.message import Message as PbMessage

    from gateway.pipeline import Output

KNOT_M_S = 1852.0 / 3600.0
"""One knot in m/s (the international nautical mile per hour)."""
NAME = "dpgw"
"""The ``name`` (process) of every `foxglove.Log` this sink publishes."""

ESTIMATE_TOPIC = "/dp/estimate"
"""Only the main observer's estimate goes out: the comparison observers (``/dp/estimates/<label>``) are
for the log and for tuning, not for other programs aboard."""
FIX_TOPIC_PREFIX = "/gnss/"
_UNKNOWN_COVARIANCE = (0.0,) * 9


class KeelsonSink:
    """An `OutputSink` (and `RawSentenceSink`) publishing to Keelson; built by `keelson_sink`."""

    name = "keelson"

    def __init__(
        self,
        cfg: KeelsonConfig,
        sources: Sequence[str],
        datum_alt_m: float = 0.0,
        datum: tuple[float, float] | None = None,
    ) -> None:
        self.cfg = cfg
        self.sources = tuple(sources)
        self.datum_alt_m = datum_alt_m
        """The datum's height: the measured position is on the same tangent plane as the estimate's."""
        self.published = 0
        self._session: zenoh.Session | None = None
        self._publishers: dict[tuple[str, str], Any] = {}
        self._tokens: list[Any] = []
        # the datum, to place the measured position: the configured one, else the estimate's (first fix)
        self._frame = None if datum is None else LocalFrame(datum[0], datum[1], datum_alt_m)
        self._alarms = AlarmChanges()
        self._mode: str | None = None
        self._settling = SettlingChanges()
        self._sensor_ids = {s: cfg.sensor(s) for s in self.sources}
        self._dispatch: dict[type, Callable[[Output, int], None]] = {
            Estimate: self._estimate,
            Measurement: self._measurement,
            LocationFix: self._fix,
            ThrusterCommand: self._command,
            ThrusterFeedback: self._feedback,
            Status: self._status,
        }

    # --- OutputSink ------------------------------------------------------------------------------------

    def source_ids(self) -> list[str]:
        """Every source id this sink publishes under (one liveliness token each)."""
        c = self.cfg
        fixed = [
            c.estimate_source_id,
            c.measurement_source_id,
            c.demand_source_id,
            c.allocated_source_id,
            c.feedback_source_id,
            c.log_source_id,
        ]
        return fixed + [self._sensor_ids[s] for s in self.sources]

    def start(self, session: zenoh.Session) -> None:
        self._session = session
        c = self.cfg
        for source_id in self.source_ids():
            key = keelson.construct_liveliness_key(c.base_path, c.entity_id, source_id)
            self._tokens.append(session.liveliness().declare_token(key))

    def emit(self, outputs: list[Output], encoded: list[bytes]) -> None:
        now = time.time_ns()  # one enclosed_at for the batch: they are enclosed together
        dispatch = self._dispatch
        for o in outputs:
            handler = dispatch.get(type(o.message))
            if handler is not None:
                handler(o, now)

    def raw_nmea(self, source: str, rx_ns: int, text: str, peer: str) -> None:
        source_id = self._sensor_ids.get(source)
        if source_id is None:
            return
        msg = TimestampedString(value=text)
        msg.timestamp.FromNanoseconds(rx_ns)
        self._put("raw_nmea0183", source_id, msg, time.time_ns())

    def close(self) -> None:
        for d in [*self._tokens, *self._publishers.values()]:
            with contextlib.suppress(Exception):  # already gone with the session
                d.undeclare()
        self._tokens.clear()
        self._publishers.clear()
        self._session = None

    # --- publishing ------------------------------------------------------------------------------------

    def _put(self, subject: str, source_id: str, payload: PbMessage, now_ns: int) -> None:
        pub = self._publishers.get((subject, source_id))
        if pub is None:
            if self._session is None:
                return  # not started, or closed
            c = self.cfg
            key = keelson.construct_pubsub_key(c.base_path, c.entity_id, subject, source_id)
            pub = self._publishers[(subject, source_id)] = self._session.declare_publisher(key)
        pub.put(keelson.enclose(payload.SerializeToString(), now_ns))
        self.published += 1

    def _float(self, subject: str, source_id: str, stamp_ns: int, value: float | None, now_ns: int) -> None:
        """A `keelson.TimestampedFloat` (a 32-bit float: ~7 significant digits); nothing when not finite
        (an unknown value is left out, never sent as NaN)."""
        if value is None or not math.isfinite(value):
            return
        msg = TimestampedFloat(value=value)
        msg.timestamp.FromNanoseconds(stamp_ns)
        self._put(subject, source_id, msg, now_ns)

    def _force_moment(
        self, source_id: str, stamp_ns: int, xyn: Sequence[float | None] | None, frame_id: str, now_ns: int
    ) -> None:
        """[X, Y, N] as ``force_newton`` (X, Y, 0) and ``moment_newton_meter`` (0, 0, N), each a
        `keelson.Decomposed3DVector` in ``frame_id`` (``body``: x forward, y starboard, z down; ``ned``)."""
        if xyn is None or len(xyn) != 3:
            return
        x, y, n = xyn
        if x is not None and y is not None and math.isfinite(x) and math.isfinite(y):
            force = Decomposed3DVector(frame_id=frame_id)
            force.timestamp.FromNanoseconds(stamp_ns)
            v = force.vector
            v.x, v.y, v.z = x, y, 0.0
            self._put("force_newton", source_id, force, now_ns)
        if n is not None and math.isfinite(n):
            moment = Decomposed3DVector(frame_id=frame_id)
            moment.timestamp.FromNanoseconds(stamp_ns)
            v = moment.vector
            v.x, v.y, v.z = 0.0, 0.0, n
            self._put("moment_newton_meter", source_id, moment, now_ns)

    def _location(
        self,
        source_id: str,
        stamp_ns: int,
        frame_id: str,
        lat: float,
        lon: float,
        now_ns: int,
        altitude: float = 0.0,
        covariance: Sequence[float] | None = None,
        covariance_type: int = 0,
    ) -> None:
        """A ``location_fix``. Foxglove's schema (the payload type's) requires 9 covariance entries, and
        consumers index them (a bridge to ROS's NavSatFix, whose array is fixed at 9): without a covariance
        (the estimate's, the measurement's) they are 9 zeros with type UNKNOWN, never an empty array."""
        msg = PbLocationFix(frame_id=frame_id, latitude=lat, longitude=lon, altitude=altitude)
        msg.timestamp.FromNanoseconds(stamp_ns)
        if covariance is not None:
            msg.position_covariance.extend(covariance)
            msg.position_covariance_type = covariance_type
        else:
            msg.position_covariance.extend(_UNKNOWN_COVARIANCE)
        self._put("location_fix", source_id, msg, now_ns)

    # --- one function per dpgw message ---------------------------------------------------------------

    def _estimate(self, o: Output, now: int) -> None:
        if o.topic != ESTIMATE_TOPIC:
            return
        e: Estimate = o.message  # type: ignore[assignment]
        sid, t = self.cfg.estimate_source_id, e.stamp_ns
        if e.datum is not None and (
            self._frame is None
            or (self._frame.lat_deg, self._frame.lon_deg) != (e.datum.lat_deg, e.datum.lon_deg)
        ):
            self._frame = LocalFrame(e.datum.lat_deg, e.datum.lon_deg, self.datum_alt_m)
        if e.lat_deg is not None and e.lon_deg is not None:
            self._location(sid, t, "estimate", e.lat_deg, e.lon_deg, now)
        self._float("heading_true_north_deg", sid, t, e.heading_deg, now)
        u, v, r = e.nu
        psi = e.eta[2]
        if u is not None and v is not None:
            self._float("surge_velocity_mps", sid, t, u, now)
            self._float("sway_velocity_mps", sid, t, v, now)
            speed = math.hypot(u, v)
            self._float("speed_over_ground_knots", sid, t, speed / KNOT_M_S, now)
            # the course is the heading plus the drift angle atan2(v, u); at rest it has no direction
            if psi is not None and speed > 0.0:
                self._float(
                    "course_over_ground_deg", sid, t, math.degrees(psi + math.atan2(v, u)) % 360.0, now
                )
        if r is not None:
            self._float("yaw_rate_degps", sid, t, math.degrees(r), now)
        self._force_moment(sid, t, e.bias, "ned", now)  # the bias is earth-fixed (wire.messages)
        self._settle_log(e, now)

    def _settle_log(self, e: Estimate, now: int) -> None:
        """``log_message`` when the estimate starts settling (its first estimate, a restart: the time left
        grows) and when it has settled: Keelson has no well-known subject for an estimate's readiness, and
        its log is where this sink says what changed (docs/keelson.md, "Decisions"). WARNING while
        settling (DP does not engage by itself on it), INFO once settled; the values as ``key=value`` in
        the text, so a program can read them."""
        settled, left = e.settled, e.settle_s_left
        if settled is None or left is None:
            return  # (an estimate that does not say)
        if not self._settling.update(settled, left):
            return
        if settled:
            level, text = Log.INFO, f"estimate settled (settled=true, settle_s_left={left:g})"
        else:
            level, text = Log.WARNING, f"estimate settling (settled=false, settle_s_left={left:.1f})"
        msg = Log(level=level, message=text, name=NAME)
        msg.timestamp.FromNanoseconds(e.stamp_ns)
        self._put("log_message", self.cfg.log_source_id, msg, now)

    def _measurement(self, o: Output, now: int) -> None:
        m: Measurement = o.message  # type: ignore[assignment]
        sid, t = self.cfg.measurement_source_id, m.stamp_ns
        north, east, psi = m.eta
        if m.valid[2] and psi is not None:
            self._float("heading_true_north_deg", sid, t, math.degrees(psi) % 360.0, now)
        frame = self._frame
        if frame is not None and m.valid[0] and m.valid[1] and north is not None and east is not None:
            lat, lon = frame.to_lat_lon(north, east)
            self._location(sid, t, "measurement", lat, lon, now)
        self._float("location_fix_accuracy_horizontal_m", sid, t, m.sigma_m, now)

    def _fix(self, o: Output, now: int) -> None:
        """A receiver's own fix (``/gnss/<source>/fix``: height from GGA, covariance from GST)."""
        if not o.topic.startswith(FIX_TOPIC_PREFIX):
            return  # (the estimate's fix goes out with every estimate, from the estimate)
        f: LocationFix = o.message  # type: ignore[assignment]
        sid = self._sensor_ids.get(f.frame_id)
        if sid is None:
            return
        t = f.timestamp.sec * 1_000_000_000 + f.timestamp.nsec
        self._location(
            sid,
            t,
            f.frame_id,
            f.latitude,
            f.longitude,
            now,
            f.altitude,
            f.position_covariance,
            f.position_covariance_type,
        )

    def _command(self, o: Output, now: int) -> None:
        c: ThrusterCommand = o.message  # type: ignore[assignment]
        self._force_moment(self.cfg.demand_source_id, c.stamp_ns, c.tau_demand, "body", now)
        self._force_moment(self.cfg.allocated_source_id, c.stamp_ns, c.tau_allocated, "body", now)

    def _feedback(self, o: Output, now: int) -> None:
        f: ThrusterFeedback = o.message  # type: ignore[assignment]
        self._force_moment(self.cfg.feedback_source_id, f.stamp_ns, f.tau_allocated, "body", now)

    def _status(self, o: Output, now: int) -> None:
        """``log_message``: what changed since the last status, never the whole status again: each
        reference state change (at its new state's level: INFO back to ok, WARNING stale or suspect, ERROR
        rejected, as on `/dp/log`), an alarm raised (ERROR if critical, else WARNING, as on `/dp/log`:
        `gateway.alarms`) or cleared (INFO), a mode change (INFO). An
        alarm is known by its text with the numbers masked (`AlarmChanges`): "stale (3.1 s without data)"
        becoming "(4.1 s ...)" at the next status is the same alarm still active."""
        s: Status = o.message  # type: ignore[assignment]
        lines: list[tuple[Any, str]] = [(state_change_level(text), text) for text in s.events]
        raised, cleared = self._alarms.update(s.alarms, s.stamp_ns)
        critical = raised_critical(s)
        lines += [(Log.ERROR if t in critical else Log.WARNING, f"alarm: {t}") for t in raised]
        lines += [(Log.INFO, f"alarm cleared: {t}") for t in cleared]
        if s.mode != self._mode:
            # each mode change is an event of the status (with who made it); a change without one (a
            # pipeline started over under a restarted simulator, back to its initial mode) is said here
            if self._mode is not None and not any(e.startswith("mode: ") for e in s.events):
                lines.append((Log.INFO, f"mode: {self._mode} -> {s.mode}"))
            self._mode = s.mode
        for level, text in lines:
            msg = Log(level=level, message=text, name=NAME)
            msg.timestamp.FromNanoseconds(s.stamp_ns)
            self._put("log_message", self.cfg.log_source_id, msg, now)


def keelson_sink(config: GatewayConfig) -> KeelsonSink:
    """The sink ``[keelson]`` describes, for the config's input sources (each gets a sensor source id)."""
    d = config.datum
    datum = (d.lat_deg, d.lon_deg) if d.fixed and d.lat_deg is not None and d.lon_deg is not None else None
    return KeelsonSink(config.keelson, [s.name for s in config.sources], d.alt_m, datum)
