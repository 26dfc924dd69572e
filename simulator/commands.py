"""Thruster commands coming back into the simulator: the HIL loop closed from outside.

Two ways in: the dpgw dialect's AZIMUTH_THRUSTER_COMMAND over the MAVLink link (bytes that
peers send back on the simulator's UDP/TCP/pty MAVLink sink), and JSON on Zenoh
``<prefix>/thrusters/command`` (DESIGN.md: ``thrusters: [{id, thrust_n, azimuth_rad}]``). Both yield
`ThrusterCommand`s; the runner applies them. Bad input is counted, never raised.
"""

from __future__ import annotations

import json
import logging
import math
import threading
from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from simulator.transports import Sink
from wire.codecs.mavlink import (
    AZIMUTH_THRUSTER_COMMAND_ID,
    SIGNING_REASONS,  # a drive with a key: a frame unsigned, or signed wrongly or replayed
    FrameParser,
    dialect,
    encoder,
    setup_signing,
)

log = logging.getLogger(__name__)


if TYPE_CHECKING:
    from simulator.sensors import ThrusterFeedbackConfig


@dataclass(frozen=True)
class ThrusterCommand:
    id: int
    thrust_n: float
    azimuth_rad: float | None  # None: keep the angle (fixed thrusters, or not given)


@dataclass(frozen=True)
class TauCommand:
    """A generalised force for a vessel without a thruster layout (the papers' simulated ships): the
    command's ``tau_allocated`` when it lists no thrusters."""

    tau: tuple[float, float, float]


Command = ThrusterCommand | TauCommand


class MavlinkCommandInput:
    """Reads AZIMUTH_THRUSTER_COMMAND frames that peers send on a sink (one parser per peer).

    As the drive it stands in for: a command addressed to another system or component (``target_system``
    / ``target_component`` neither 0, broadcast, nor this drive's ``system_id`` / ``component_id``) is
    not taken, only counted (``rejected["other target"]``): on a link shared with other vehicles it is
    theirs.

    With a ``signing_key`` (32 bytes, MAVLink 2 signing) it takes only frames signed with that key: an
    unsigned frame is counted ``rejected["unsigned"]``, a wrong signature or a replayed (not newer)
    timestamp ``rejected["bad_signature"]``, and the first of each per peer is logged with its first
    bytes. One signing state serves every peer, so a frame recorded from one address and replayed from
    another is still old. Without a key every frame is taken (signed ones unchecked), as before."""

    def __init__(
        self,
        sink: Sink,
        system_id: int | None = None,
        component_id: int | None = None,
        *,
        signing_key: bytes | None = None,
    ) -> None:
        self.sink = sink
        self.system_id = system_id
        self.component_id = component_id
        self.parsers: dict[str, FrameParser] = {}
        self._rejected: Counter[str] = Counter()
        self.received = 0
        self._verifier = None
        if signing_key is not None:
            self._verifier = encoder(system_id or 1, component_id or 1)
            setup_signing(self._verifier, signing_key, sign_outgoing=False, allow_unsigned=False)
        self._logged: set[tuple[str, str]] = set()

    @property
    def signed(self) -> bool:
        """Takes signed commands only (built with a ``signing_key``)."""
        return self._verifier is not None

    @property
    def rejected(self) -> Counter[str]:
        """Frames and commands not taken, by reason: the parsers' (bad CRC, ``unsigned``,
        ``bad_signature`` …) and this input's own (``other target``, ``non_finite``)."""
        total = Counter(self._rejected)
        for parser in self.parsers.values():
            total.update(parser.rejected)
        return total

    @classmethod
    def for_drive(
        cls, sink: Sink, drive: ThrusterFeedbackConfig | None, *, signing_key: bytes | None = None
    ) -> MavlinkCommandInput:
        """As the scenario's simulated drive: it takes what is addressed to its ids (or broadcast); without
        a drive (no thruster feedback), every target. ``signing_key``: signed commands only."""
        if drive is None:
            return cls(sink, signing_key=signing_key)
        return cls(sink, drive.system_id, drive.component_id, signing_key=signing_key)

    def poll(self) -> list[Command]:
        out: list[Command] = []
        for peer, data in self.sink.read_from_peers():
            parser = self.parsers.get(peer)
            if parser is None:
                parser = self.parsers[peer] = FrameParser(self._verifier)
            before = {r: parser.rejected[r] for r in SIGNING_REASONS} if self.signed else None
            msgs = parser.feed(data)
            if before is not None:
                self._log_signing_rejects(peer, parser, before, data)
            for msg in msgs:
                if msg.get_msgId() != AZIMUTH_THRUSTER_COMMAND_ID:
                    continue
                assert isinstance(msg, dialect().MAVLink_azimuth_thruster_command_message)
                self.received += 1
                if not (
                    _addressed(msg.target_system, self.system_id)
                    and _addressed(msg.target_component, self.component_id)
                ):
                    self._rejected["other target"] += 1
                    continue
                if not (math.isfinite(msg.thrust) and math.isfinite(msg.azimuth)):
                    self._rejected["non_finite"] += 1
                    continue
                out.append(ThrusterCommand(int(msg.id), float(msg.thrust), float(msg.azimuth)))
        return out

    def _log_signing_rejects(
        self, peer: str, parser: FrameParser, before: dict[str, int], data: bytes
    ) -> None:
        """Log the first frame of each signing reason rejected from ``peer`` (the count goes on in
        `rejected`): someone is writing to the drive's link without its key."""
        for reason in SIGNING_REASONS:
            if parser.rejected[reason] > before[reason] and (peer, reason) not in self._logged:
                self._logged.add((peer, reason))
                log.warning(
                    "thruster commands from %s rejected: %s (the drive takes signed commands only; "
                    "counted from now on, not logged again); first bytes %s",
                    peer,
                    "not signed" if reason == "unsigned" else "bad signature or replayed timestamp",
                    bytes(data[:32]).hex(" "),
                )


def _addressed(target: int, own: int | None) -> bool:
    """A MAVLink target id names this receiver: 0 (broadcast), its own id, or any when it has none."""
    return own is None or target in (0, own)


class ZenohCommandInput:
    """Subscribes ``<prefix>/thrusters/command`` on a Zenoh session; keeps what arrived since the last
    poll."""

    def __init__(self, session: Any, prefix: str) -> None:
        self.key = f"{prefix}/thrusters/command"
        self._lock = threading.Lock()
        self._pending: list[Command] = []
        self.rejected: Counter[str] = Counter()
        self.received = 0
        self._sub = session.declare_subscriber(self.key, self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        try:
            payload = json.loads(sample.payload.to_bytes())
            cmds: list[Command] = [
                ThrusterCommand(
                    int(th["id"]),
                    float(th["thrust_n"]),
                    None if th.get("azimuth_rad") is None else float(th["azimuth_rad"]),
                )
                for th in payload["thrusters"]
            ]
            if not cmds and payload.get("tau_allocated") is not None:
                tau = tuple(float(v) for v in payload["tau_allocated"])
                if len(tau) != 3 or not all(math.isfinite(v) for v in tau):
                    raise ValueError("tau_allocated must be 3 finite numbers")
                cmds = [TauCommand((tau[0], tau[1], tau[2]))]
            if not all(math.isfinite(c.thrust_n) for c in cmds if isinstance(c, ThrusterCommand)):
                raise ValueError("non-finite thrust")
        except (ValueError, KeyError, TypeError) as exc:
            with self._lock:
                self.rejected[type(exc).__name__] += 1
            return
        with self._lock:
            self.received += 1
            self._pending.extend(cmds)

    def poll(self) -> list[Command]:
        with self._lock:
            out, self._pending = self._pending, []
        return out

    def close(self) -> None:
        self._sub.undeclare()
