"""The direction of rotation of ArduPilot ESCs, learnt from their reversible motor outputs.

``ESC_TELEMETRY_x_TO_y`` carries rpm as an unsigned integer: a motor running astern reports the same
number as ahead. ArduPilot drives a reversible motor (Rover throttle, Sub thrusters, DShot 3D) with an
output that centres on its trim (``SERVOn_TRIM``): above it ahead, below it astern, and ``SERVO_OUTPUT_RAW``
reports that pulse. `EscDirections` holds, per source and ESC, the direction the latest pulses gave
(`wire.codecs.mavlink.EscDirectionReport`) and says which sign an rpm report takes:

* a pulse beyond the dead band sets the direction (+1 ahead, −1 astern);
* a pulse inside the dead band (the ESC not driven) keeps the direction last driven: a propeller that is
  no longer driven coasts down the way it turned. With none driven since the pulses became fresh, the
  direction is unknown;
* pulses older than the source's ``timeout_s``: the direction is unknown (the stream stopped), and a
  held direction is forgotten when they resume.

An unknown direction gives no sign: the pipeline then does not use that ESC's rpm as thrust (0 rpm excepted:
no thrust either way), so its thruster has no fresh feedback and τ counts it with its commanded thrust
(`gateway.fusion.Fusion.tau`). What this cannot see: while a motor reverses, the output has changed
side before the propeller has, so the spin-down of the old direction reads with the new sign for as long
as it lasts (small thrust: it goes with rpm²).

Pure state (no I/O, no clocks: times come with the data).
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["EscDirections"]


class _Held(NamedTuple):
    direction: int  # +1, -1, or 0 (none driven since the pulses became fresh)
    rx_ns: int  # when the latest pulse was received
    valid_ns: int  # how long it stays fresh (its source's timeout)


class EscDirections:
    """Per (source, ESC index), the direction of rotation its motor output's latest pulses give."""

    def __init__(self) -> None:
        self._held: dict[tuple[str, int], _Held] = {}

    def add(self, source: str, esc: int, direction: int, rx_ns: int, valid_ns: int) -> None:
        """A motor output pulse read as ``direction`` (+1, −1, or 0 inside the dead band) at ``rx_ns``,
        fresh for ``valid_ns``."""
        key = (source, esc)
        if direction == 0:
            old = self._held.get(key)
            if old is not None and rx_ns - old.rx_ns <= old.valid_ns:
                direction = old.direction  # not driven: coasting the way it was last driven
        self._held[key] = _Held(direction, rx_ns, valid_ns)

    def sign(self, source: str, esc: int, now_ns: int) -> int:
        """+1 ahead, −1 astern, 0 unknown (no pulse yet, a stale one, or none driven since they resumed)."""
        held = self._held.get((source, esc))
        if held is None or now_ns - held.rx_ns > held.valid_ns:
            return 0
        return held.direction
