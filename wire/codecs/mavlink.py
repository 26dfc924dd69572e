"""MAVLink 2 codec over the project's dialect (``dpgw.xml``: ardupilotmega.xml + azimuth thrusters).

A small typed layer over the module mavgen generates (:mod:`wire.codecs.generated.dpgw`):

* :func:`encoder` makes a ``MAVLink`` object (``file=None``) whose sequence numbers and signing state belong
  to one outgoing link; the ``*_frame`` helpers take SI values, convert them to the wire units of the
  message (DESIGN.md rule 3: units change only here), pack one frame and return its bytes.
* :func:`setup_signing` turns on MAVLink 2 message signing (SHA-256, 48-bit signature, 32-byte key) for
  the outgoing frames of an encoder and/or the checking of incoming frames by a decoder.
* :class:`FrameParser` (streaming) and :func:`parse_frames` (one buffer) decode frames robustly: bytes that
  are not a valid frame are skipped and counted per reason, never raised.
* :func:`reports` turns a decoded message into typed SI records (:class:`PositionReport`,
  :class:`HeadingReport`, :class:`ThrusterReport`, :class:`EscDirectionReport`): the MAVLink integer units
  (1e-7 degrees, centidegrees, millimetres, PWM microseconds) end here, so the gateway behind the codec
  sees only degrees of latitude and longitude, metres and radians. ArduPilot motor and servo outputs are
  mapped onto the vessel's thrusters by the source's wiring (:class:`ArduPilotWiring`).

Message layouts: ``docs/mavlink-dialect.md``. MAVLink 2 framing: https://mavlink.io/en/guide/serialization.html;
signing: https://mavlink.io/en/guide/message_signing.html.
"""

from __future__ import annotations

import hashlib
import math
import struct
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntFlag
from functools import cached_property
from types import ModuleType
from typing import Any

from mypy_extensions import mypyc_attr

from observers.kinematics import ssa_scalar
from wire.codecs.generated import dpgw as _dpgw

MAVLink = _dpgw.MAVLink
MAVLinkMessage = _dpgw.MAVLink_message

AZIMUTH_THRUSTER_STATUS_ID: int = _dpgw.MAVLINK_MSG_ID_AZIMUTH_THRUSTER_STATUS
AZIMUTH_THRUSTER_COMMAND_ID: int = _dpgw.MAVLINK_MSG_ID_AZIMUTH_THRUSTER_COMMAND

SIGNING_KEY_LEN = 32
"""Length of a MAVLink 2 signing secret key (bytes)."""

SIGNING_EPOCH_UNIX_S = 1420070400
"""Signing timestamps count 10 µs units from 2015-01-01T00:00:00Z (this many seconds after the UNIX epoch)."""

ESC_TELEMETRY_BLOCKS = tuple(range(1, 33, 4))
"""First ESC numbers of ESC_TELEMETRY_1_TO_4, _5_TO_8, ..., _29_TO_32 (ardupilotmega.xml)."""

_UINT16_MAX = 0xFFFF
_MAH_PER_COULOMB = 1.0 / 3.6
GPS_FIX_TYPE_2D_FIX: int = _dpgw.GPS_FIX_TYPE_2D_FIX
"""The first ``GPS_RAW_INT.fix_type`` that is a position (0 no GPS, 1 no fix, 2 2D, 3 3D, 4 DGPS …)."""
HDG_UNKNOWN = _UINT16_MAX
"""``GLOBAL_POSITION_INT.hdg`` when the heading is not known."""


class AzimuthThrusterFlags(IntFlag):
    """``AZIMUTH_THRUSTER_STATUS.flags`` (enum ``DPGW_AZIMUTH_THRUSTER_FLAGS`` in dpgw.xml)."""

    READY = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_READY
    RUNNING = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_RUNNING
    REMOTE_CONTROL = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_REMOTE_CONTROL
    LOCAL_CONTROL = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_LOCAL_CONTROL
    FAULT = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_FAULT
    WARNING = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_WARNING
    THRUST_LIMITED = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_THRUST_LIMITED
    AZIMUTH_LIMITED = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_AZIMUTH_LIMITED
    AZIMUTH_FOLLOW_UP_ERROR = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_AZIMUTH_FOLLOW_UP_ERROR
    EMERGENCY_STOP = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_EMERGENCY_STOP
    COMMAND_TIMEOUT = _dpgw.DPGW_AZIMUTH_THRUSTER_FLAGS_COMMAND_TIMEOUT


def dialect() -> ModuleType:
    """The generated dialect module (message classes, enums, ``MAVLink``, ``mavlink_map``)."""
    return _dpgw


def encoder(src_system: int = 1, src_component: int = _dpgw.MAV_COMP_ID_AUTOPILOT1) -> MAVLink:
    """A MAVLink 2 protocol object for one outgoing link, with ``file=None``: build frames with the
    ``*_frame`` helpers (or ``msg.pack(mav)``) and write the bytes yourself.

    ``src_system``/``src_component`` go into every frame header (1..255; component 1 is
    ``MAV_COMP_ID_AUTOPILOT1``, the usual id of a thruster controller running on an autopilot; the gateway
    itself would use ``MAV_COMP_ID_ONBOARD_COMPUTER`` = 191). The same object can also decode.
    """
    _check_uint("src_system", src_system, 8)
    _check_uint("src_component", src_component, 8)
    mav = _dpgw.MAVLink(None, srcSystem=src_system, srcComponent=src_component)
    mav.robust_parsing = True
    return mav


def signing_timestamp(unix_time_s: float) -> int:
    """MAVLink 2 signing timestamp (10 µs units since 2015-01-01T00:00:00Z) of a UNIX time in seconds."""
    return max(0, int((unix_time_s - SIGNING_EPOCH_UNIX_S) * 100_000))


def setup_signing(
    mav: MAVLink,
    secret_key: bytes,
    link_id: int = 0,
    *,
    sign_outgoing: bool = True,
    allow_unsigned: bool | Callable[[MAVLink, int], bool] = False,
    initial_timestamp: int | None = None,
) -> None:
    """Configure MAVLink 2 message signing on ``mav``.

    With a key set, frames packed with ``mav`` are signed (``sign_outgoing``) with ``link_id`` (0..255), and
    frames decoded with ``mav`` must carry a valid signature: a frame with a wrong signature, or a replayed
    / old timestamp, is rejected; an unsigned frame is rejected unless ``allow_unsigned`` is True or a
    callback ``(mav, msg_id) -> bool`` that accepts it. ``initial_timestamp`` (10 µs units since 2015, see
    :func:`signing_timestamp`) defaults to the current time; a simulator that must be reproducible passes
    one. The timestamp then increases by one for every signed frame, as the protocol requires.
    """
    if len(secret_key) != SIGNING_KEY_LEN:
        raise ValueError(f"MAVLink signing key must be {SIGNING_KEY_LEN} bytes, got {len(secret_key)}")
    _check_uint("link_id", link_id, 8)
    mav.signing.secret_key = bytes(secret_key)
    mav.signing.link_id = link_id
    mav.signing.sign_outgoing = sign_outgoing
    if initial_timestamp is None:
        initial_timestamp = signing_timestamp(time.time())
    _check_uint("initial_timestamp", initial_timestamp, 48)
    mav.signing.timestamp = initial_timestamp
    if callable(allow_unsigned):
        mav.signing.allow_unsigned_callback = allow_unsigned
    elif allow_unsigned:
        mav.signing.allow_unsigned_callback = lambda _mav, _msg_id: True
    else:
        mav.signing.allow_unsigned_callback = None


def keep_signing_time(mav: MAVLink, unix_time_s: float) -> None:
    """Bring ``mav``'s signing timestamp up to ``unix_time_s`` if it fell behind (never back).

    pymavlink adds one (10 µs) per signed frame and never reads the clock again: a link sending tens of
    frames a second advances its timestamp by under a millisecond per second, so after a minute of
    running it is a minute behind the wall. A receiver that meets the stream new (a drive that rebooted,
    a second listener) rejects a first timestamp more than a minute behind its own clock as a replay, so
    every frame after such a reboot would be refused. The protocol asks for a timestamp that follows
    real time and grows by at least one per frame; calling this before each burst gives both."""
    if mav.signing.sign_outgoing:
        mav.signing.timestamp = max(mav.signing.timestamp, signing_timestamp(unix_time_s))


# ---------------------------------------------------------------------------------------------- encoding


def pack(mav: MAVLink, msg: MAVLinkMessage) -> bytes:
    """Pack one message as a frame with ``mav``'s header ids, sequence number and signing; advance the
    sequence number (``MAVLink.pack`` alone does not, only ``MAVLink.send`` does)."""
    buf = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    mav.total_packets_sent += 1
    mav.total_bytes_sent += len(buf)
    return bytes(buf)


_V2_HEADER = struct.Struct("<BBBBBBBHB")  # magic, len, incompat, compat, seq, system, component, msgid 24 bit
_STATUS = _dpgw.MAVLink_azimuth_thruster_status_message
_STATUS_ID, _STATUS_CRC_EXTRA, _STATUS_PACK = _STATUS.id, _STATUS.crc_extra, _STATUS.unpacker.pack
_U64, _U32 = 2**64, 2**32


_BYTE = [bytes((v,)) for v in range(256)]


def _pack_fast(mav: MAVLink, msg_id: int, crc_extra: int, payload: bytes) -> bytes | None:
    """What `pack` makes of a message with this id and packed payload, without building the pymavlink
    message object (about 5x faster; the simulator sends six status frames per thruster sample). None
    when ``mav`` signs or the compiled CRC is missing: then the library packs (the readable reference,
    tests/test_codecs_encode.py checks that both give the same bytes)."""
    if mav.signing.sign_outgoing or _dpgw.mcrf4xx is None:
        return None
    body = payload.rstrip(b"\x00") or payload[:1]  # MAVLink 2 drops trailing zero bytes, keeping one
    head = _V2_HEADER.pack(
        _dpgw.PROTOCOL_MARKER_V2, len(body), 0, 0, mav.seq, mav.srcSystem, mav.srcComponent,
        msg_id & 0xFFFF, msg_id >> 16,
    )  # fmt: skip
    frame = head + body
    crc = _dpgw.mcrf4xx(frame[1:] + _BYTE[crc_extra], 0xFFFF)
    frame += crc.to_bytes(2, "little")
    mav.seq = (mav.seq + 1) % 256
    mav.total_packets_sent += 1
    mav.total_bytes_sent += len(frame)
    return frame


def azimuth_status_frame(
    mav: MAVLink,
    time_usec: int,
    id: int,
    thrust_n: float,
    rpm: float,
    azimuth_rad: float,
    flags: int,
    *,
    thrust_setpoint_n: float = math.nan,
    azimuth_setpoint_rad: float = math.nan,
    azimuth_rate_rad_s: float = math.nan,
    power_w: float = math.nan,
    fault_code: int = 0,
) -> bytes:
    """One ``AZIMUTH_THRUSTER_STATUS`` frame. Azimuths are wrapped to [-π, π) (clockwise from the bow, body
    frame, direction of the thrust force); unknown optional values go as NaN."""
    flags = int(flags)
    if not (0 <= time_usec < _U64 and 0 <= id < 256 and 0 <= flags < _U32 and 0 <= fault_code < 65536):
        _check_uint("time_usec", time_usec, 64)  # (one comparison chain; these name the bad one)
        _check_uint("id", id, 8)
        _check_uint("flags", flags, 32)
        _check_uint("fault_code", fault_code, 16)
    frame = _pack_fast(
        mav,
        _STATUS_ID,
        _STATUS_CRC_EXTRA,
        _STATUS_PACK(
            time_usec, float(thrust_n), float(rpm), ssa_scalar(float(azimuth_rad)), int(flags),
            float(thrust_setpoint_n), ssa_scalar(float(azimuth_setpoint_rad)), float(azimuth_rate_rad_s),
            float(power_w), fault_code, id,
        ),
    )  # fmt: skip
    if frame is not None:
        return frame
    msg = _dpgw.MAVLink_azimuth_thruster_status_message(
        time_usec=time_usec,
        id=id,
        thrust=float(thrust_n),
        rpm=float(rpm),
        azimuth=ssa_scalar(float(azimuth_rad)),
        flags=int(flags),
        thrust_setpoint=float(thrust_setpoint_n),
        azimuth_setpoint=ssa_scalar(float(azimuth_setpoint_rad)),
        azimuth_rate=float(azimuth_rate_rad_s),
        power=float(power_w),
        fault_code=fault_code,
    )
    return pack(mav, msg)


def azimuth_command_frame(
    mav: MAVLink,
    time_usec: int,
    id: int,
    thrust_n: float,
    azimuth_rad: float,
    *,
    target_system: int = 0,
    target_component: int = 0,
) -> bytes:
    """One ``AZIMUTH_THRUSTER_COMMAND`` frame (azimuth wrapped to [-π, π)). Target 0 = broadcast."""
    _check_uint("time_usec", time_usec, 64)
    _check_uint("id", id, 8)
    _check_uint("target_system", target_system, 8)
    _check_uint("target_component", target_component, 8)
    msg = _dpgw.MAVLink_azimuth_thruster_command_message(
        time_usec=time_usec,
        target_system=target_system,
        target_component=target_component,
        id=id,
        thrust=float(thrust_n),
        azimuth=ssa_scalar(float(azimuth_rad)),
    )
    return pack(mav, msg)


def esc_telemetry_frame(
    mav: MAVLink,
    rpm: Sequence[float],
    *,
    temperature_degc: Sequence[float] = (),
    voltage_v: Sequence[float] = (),
    current_a: Sequence[float] = (),
    consumed_c: Sequence[float] = (),
    count: Sequence[int] = (),
    first_esc: int = 1,
) -> bytes:
    """One ArduPilot ``ESC_TELEMETRY_<first>_TO_<first+3>`` frame (ardupilotmega.xml, BLHeli layout) for up
    to four ESCs; missing entries are sent as 0.

    Converted to the wire's integer units and saturated to its field ranges: rpm → |rpm| (the field is
    unsigned, the direction is lost), temperature °C → uint8 °C, voltage V → cV, current A → cA, consumed
    charge C → mAh (uint16 each), ``count`` (packets received by the ESC) wraps at 65536.
    """
    if first_esc not in ESC_TELEMETRY_BLOCKS:
        raise ValueError(f"first_esc must be one of {ESC_TELEMETRY_BLOCKS}, got {first_esc}")
    name = f"ESC_TELEMETRY_{first_esc}_TO_{first_esc + 3}"
    msg_id = getattr(_dpgw, f"MAVLINK_MSG_ID_{name}")
    msg_cls: Any = _dpgw.mavlink_map[msg_id]  # one of the ESC_TELEMETRY_* classes (same fields)
    msg = msg_cls(
        temperature=_quad("temperature_degc", temperature_degc, 1.0, 0xFF),
        voltage=_quad("voltage_v", voltage_v, 100.0, _UINT16_MAX),
        current=_quad("current_a", current_a, 100.0, _UINT16_MAX),
        totalcurrent=_quad("consumed_c", consumed_c, _MAH_PER_COULOMB, _UINT16_MAX),
        rpm=_quad("rpm", [abs(r) for r in rpm], 1.0, _UINT16_MAX),
        count=[int(c) % (_UINT16_MAX + 1) for c in _pad4("count", count)],
    )
    return pack(mav, msg)


def servo_output_raw_frame(mav: MAVLink, time_usec: int, pwm_us: Sequence[int], port: int = 0) -> bytes:
    """One ``SERVO_OUTPUT_RAW`` frame (common.xml) with up to 16 outputs (µs pulse widths, 1000-2000 for
    a standard PWM ESC; 0 = output unused). ``time_usec`` is a uint32 on the wire (time since boot): it is
    sent modulo 2**32."""
    if len(pwm_us) > 16:
        raise ValueError(f"SERVO_OUTPUT_RAW carries at most 16 outputs, got {len(pwm_us)}")
    _check_uint("port", port, 8)
    values = [min(max(round(v), 0), _UINT16_MAX) for v in pwm_us] + [0] * (16 - len(pwm_us))
    msg = _dpgw.MAVLink_servo_output_raw_message(int(time_usec) % 2**32, port, *values)
    return pack(mav, msg)


def heartbeat_frame(
    mav: MAVLink,
    mav_type: int = _dpgw.MAV_TYPE_SURFACE_BOAT,
    autopilot: int = _dpgw.MAV_AUTOPILOT_INVALID,
    base_mode: int = 0,
    custom_mode: int = 0,
    system_status: int = _dpgw.MAV_STATE_ACTIVE,
) -> bytes:
    """One ``HEARTBEAT`` frame (1 Hz on every MAVLink link). Defaults: a surface vessel's component that is
    not a flight controller (``MAV_AUTOPILOT_INVALID``), active; an ArduPilot thruster controller sends
    ``autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA`` and its mode in ``base_mode``/``custom_mode``."""
    for name, value, bits in (
        ("mav_type", mav_type, 8),
        ("autopilot", autopilot, 8),
        ("base_mode", base_mode, 8),
        ("custom_mode", custom_mode, 32),
        ("system_status", system_status, 8),
    ):
        _check_uint(name, value, bits)
    msg = _dpgw.MAVLink_heartbeat_message(
        type=mav_type,
        autopilot=autopilot,
        base_mode=base_mode,
        custom_mode=custom_mode,
        system_status=system_status,
        mavlink_version=3,
    )
    return pack(mav, msg)


# ---------------------------------------------------------------------------------------------- decoding

_V1, _V2 = _dpgw.PROTOCOL_MARKER_V1, _dpgw.PROTOCOL_MARKER_V2
_MARKERS = frozenset((_V1, _V2))


SIGNING_REASONS = ("bad_signature", "unsigned")
"""Why :class:`FrameParser` refuses a complete frame for signing (the frame is genuine, its CRC right)."""


def frame_digest(frame: bytes | bytearray) -> str:
    """The first 8 bytes of a frame's SHA-256, in hexadecimal: which frame a logged verdict is about (a
    replay checks it against the frame it finds at the logged offset)."""
    return hashlib.sha256(frame).hexdigest()[:16]


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class FrameIds:
    """What a frame's header and signature block say of it (MAVLink 1 or 2; no decoding)."""

    system_id: int
    component_id: int
    seq: int
    msg_id: int
    link_id: int | None  # signed MAVLink 2 frames only
    signature_timestamp: int | None  # 10 µs units since 2015 (`signing_timestamp`), signed frames only


def frame_ids(frame: bytes | bytearray) -> FrameIds:
    """System, component, sequence, message id and signing link and timestamp of a complete frame."""
    if frame[0] != _V2:  # MAVLink 1: STX, len, seq, sys, comp, msgid
        return FrameIds(frame[3], frame[4], frame[2], frame[5], None, None)
    msg_id = frame[7] | (frame[8] << 8) | (frame[9] << 16)
    if not frame[2] & _dpgw.MAVLINK_IFLAG_SIGNED:
        return FrameIds(frame[5], frame[6], frame[4], msg_id, None, None)
    timestamp = int.from_bytes(frame[-12:-6], "little")
    return FrameIds(frame[5], frame[6], frame[4], msg_id, frame[-13], timestamp)


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class SigningReject:
    """A complete frame refused for signing: ``reason`` (one of `SIGNING_REASONS`), ``offset`` where its
    first byte is in the chunk whose :meth:`FrameParser.feed` completed it (negative: it began in an
    earlier chunk of the same sender, held back), and the frame's bytes."""

    reason: str
    offset: int
    frame: bytes


LoggedVerdict = tuple[int, str, str]
"""A logged refusal of one frame of a chunk: (offset in the chunk, `frame_digest`, reason)."""


class FrameParser:
    """Incremental, robust MAVLink 1/2 frame parser for one incoming byte stream (one source).

    :meth:`feed` takes any chunk of bytes and returns the messages completed by it. Invalid input is never
    raised: it is skipped and counted in :attr:`rejected` by reason, and the parser resynchronises on the
    next start-of-frame marker (0xFD MAVLink 2, 0xFE MAVLink 1). Reasons:

    * ``bad_crc`` - a marker whose frame fails its CRC;
    * ``unknown_message`` - a message id the dialect does not define, so its CRC cannot be checked (no
      CRC_EXTRA);
    * ``bad_header`` - a MAVLink 2 header with incompatibility flags this parser does not know;
    * ``truncated`` - a frame cut off by the end of the data (:meth:`flush` only).

      For these four only the marker byte is dropped and the scan restarts right after it: a stray marker
      in line noise, whose length byte claims up to 280 bytes, cannot swallow the good frames behind it.
      A frame of another dialect is not decoded either way.
    * ``bad_signature`` - a signed frame that fails the signature or timestamp (replay) check (the
      signature is checked first, so a forged frame cannot advance a stream's timestamp);
    * ``unsigned`` - an unsigned frame on a link where signing is required;
    * ``undecodable`` - a frame with a valid CRC whose payload the dialect cannot unpack.

      These frames are genuine (their CRC is right) and are consumed whole.

    :attr:`skipped_bytes` counts bytes dropped outside valid frames. Pass a ``mav`` from :func:`encoder`
    configured with :func:`setup_signing` to check signatures; without a key, signed frames are accepted
    unchecked (as pymavlink does), unless :attr:`verdicts` says otherwise. Decoded messages keep their raw
    frame (``msg.get_msgbuf()``) for logging.

    With ``keep_signing_rejects``, every frame refused for signing (``bad_signature``, ``unsigned``) is
    also kept in :attr:`signing_rejects` (a `SigningReject`: the reason, where the frame starts in the
    chunk whose :meth:`feed` completed it, the frame) until the caller takes them: the gateway logs them,
    so that a replay without the key can refuse the same frames. Accepted frames cost nothing for it.
    """

    def __init__(self, mav: MAVLink | None = None, *, keep_signing_rejects: bool = False) -> None:
        self.mav: MAVLink = mav if mav is not None else encoder(0, 0)
        self.rejected: Counter[str] = Counter()
        self.skipped_bytes = 0
        self.received = 0
        self.signing_rejects: list[SigningReject] | None = [] if keep_signing_rejects else None
        """The frames refused for signing since the caller last emptied it (None: not kept)."""
        self.verdicts: list[LoggedVerdict] | None = None
        """Without a key: the logged verdicts on the frames of the next chunk (a replay of a signed link,
        whose log holds no key): a frame found here, at its offset and with its digest, is refused with
        the logged reason, and the verdict is taken off the list; the others are accepted unchecked. What
        is left after :meth:`feed` matched no frame. Ignored when the parser has a key (it checks)."""
        self._buf = bytearray()
        self._held = 0  # bytes held back before the chunk being scanned: frame offsets count from its end

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[MAVLinkMessage]:
        """Add bytes; return the messages whose frames are now complete and valid, in stream order."""
        self._held = len(self._buf)
        self._buf.extend(data)
        return self._scan(final=False)

    def flush(self) -> list[MAVLinkMessage]:
        """No more data is coming (end of file, or a line idle for longer than a frame takes): resolve what
        is held back, treating an incomplete frame as a false start, and empty the buffer."""
        self._held = len(self._buf)
        return self._scan(final=True)

    def _scan(self, final: bool) -> list[MAVLinkMessage]:
        buf = self._buf
        out: list[MAVLinkMessage] = []
        pos = 0
        n = len(buf)
        while True:
            start = _next_marker(buf, pos)
            self.skipped_bytes += start - pos
            pos = start
            if pos >= n:
                break
            size = _frame_size(buf, pos)
            if size is None or n - pos < size:
                if not final:
                    break  # wait for the rest of the header / frame
                verdict: str | None = "truncated"
            elif size < 0:
                verdict = "bad_header"
            else:
                verdict = self._check(buf, pos)
            if verdict is not None:
                self.rejected[verdict] += 1
                self.skipped_bytes += 1
                pos += 1
                continue
            assert size is not None
            frame = bytearray(buf[pos : pos + size])
            pos += size
            refused = self._signing_verdict(frame, pos - size)
            if refused is not None:
                self._refuse(refused, frame, pos - size)
                continue
            try:
                msg = self.mav.decode(frame)
            except _dpgw.MAVError:
                reason = self._signing_reason(frame)
                if reason == "undecodable":
                    self.rejected[reason] += 1
                else:
                    self._refuse(reason, frame, pos - size)
                continue
            except Exception:  # a payload the generated class cannot build: count it, keep going
                self.rejected["undecodable"] += 1
                continue
            self.received += 1
            out.append(msg)
        del buf[:pos]
        return out

    @staticmethod
    def _check(buf: bytearray, pos: int) -> str | None:
        """``None`` if the complete frame at ``pos`` is a known message with a good CRC, else why not."""
        if buf[pos] == _V2:
            header_len = _dpgw.HEADER_LEN_V2
            msg_id = buf[pos + 7] | (buf[pos + 8] << 8) | (buf[pos + 9] << 16)
        else:
            header_len = _dpgw.HEADER_LEN_V1
            msg_id = buf[pos + 5]
        msg_cls = _dpgw.mavlink_map.get(msg_id)
        if msg_cls is None:
            return "unknown_message"
        payload_end = pos + header_len + buf[pos + 1]
        crc = _dpgw.x25crc(buf[pos + 1 : payload_end])
        crc.accumulate(bytes((msg_cls.crc_extra,)))
        (wire_crc,) = struct.unpack_from("<H", buf, payload_end)
        return None if crc.crc == wire_crc else "bad_crc"

    def _signing_verdict(self, frame: bytearray, start: int) -> str | None:
        """``bad_signature`` for a signed frame whose signature does not match the configured key, else
        None (pymavlink's decode checks the rest: timestamps, unsigned frames). Checked before that decode,
        which records a stream's timestamp before comparing signatures: a forged frame with a future
        timestamp would otherwise make the genuine frames of that stream look replayed. Without a key, the
        logged verdict on the frame at ``start`` (:attr:`verdicts`), if any."""
        key = self.mav.signing.secret_key
        if key is None:
            return None if self.verdicts is None else self._logged_verdict(frame, start - self._held)
        if frame[0] != _V2 or not frame[2] & _dpgw.MAVLINK_IFLAG_SIGNED:
            return None
        if hashlib.sha256(key + bytes(frame[:-6])).digest()[:6] == bytes(frame[-6:]):
            return None
        return "bad_signature"

    def _logged_verdict(self, frame: bytearray, offset: int) -> str | None:
        verdicts = self.verdicts
        assert verdicts is not None
        digest = None
        for k, (at, logged_digest, reason) in enumerate(verdicts):
            if at != offset:
                continue
            if digest is None:
                digest = frame_digest(frame)
            if logged_digest == digest:
                del verdicts[k]
                return reason
        return None

    def _refuse(self, reason: str, frame: bytearray, start: int) -> None:
        self.rejected[reason] += 1
        if self.signing_rejects is not None:
            self.signing_rejects.append(SigningReject(reason, start - self._held, bytes(frame)))

    def _signing_reason(self, frame: bytearray) -> str:
        if self.mav.signing.secret_key is None:
            return "undecodable"
        signed = frame[0] == _V2 and bool(frame[2] & _dpgw.MAVLINK_IFLAG_SIGNED)
        return "bad_signature" if signed else "unsigned"


# ---------------------------------------------------------------------------------------------- SI records


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class PositionReport:
    """A GNSS position: WGS-84 latitude and longitude (degrees), altitude above mean sea level (m).

    ``fix_type`` is ``GPS_RAW_INT``'s ``GPS_FIX_TYPE``; None for ``GLOBAL_POSITION_INT`` (the autopilot's
    fused position, which it only sends when it has one)."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    fix_type: int | None = None

    @property
    def valid(self) -> bool:
        """A position at all: a 2D fix or better (``GPS_RAW_INT`` also reports "no fix", lat = lon = 0)."""
        return self.fix_type is None or self.fix_type >= GPS_FIX_TYPE_2D_FIX


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class HeadingReport:
    """A heading (rad, clockwise from true north; not wrapped here: the fusion wraps every angle once)."""

    heading_rad: float


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class ThrusterReport:
    """Feedback of one thruster of the vessel's layout, with what the frame carries and nothing else.

    ``thrust_n`` (N, negative astern) and ``azimuth_rad`` (direction of the thrust force, clockwise from
    the bow) are None when the frame does not carry them (NaN when the sender does not know them);
    ``rpm`` is the shaft speed as reported (ArduPilot ESC telemetry: unsigned, the direction is lost);
    ``pwm_us`` the servo pulse width the azimuth was computed from; ``esc`` the ArduPilot ESC index whose
    telemetry carried the (unsigned) rpm, None for any other frame; ``flags`` the drive's
    `AzimuthThrusterFlags` (``AZIMUTH_THRUSTER_STATUS`` only, None for any other frame)."""

    thruster_id: int
    thrust_n: float | None = None
    azimuth_rad: float | None = None
    rpm: float | None = None
    pwm_us: int | None = None
    esc: int | None = None
    flags: int | None = None


@mypyc_attr(native_class=False)
@dataclass(frozen=True, slots=True)
class EscDirectionReport:
    """The direction an ArduPilot reversible motor output drives an ESC: ``direction`` +1 ahead (pulse
    above the output's neutral by more than the dead band), −1 astern (below it), 0 inside the dead band
    (not driven); ``pwm_us`` the pulse width it was read from."""

    esc: int
    direction: int
    pwm_us: int


Report = PositionReport | HeadingReport | ThrusterReport | EscDirectionReport

SERVO_NEUTRAL_US = 1500.0
"""Default servo pulse width of azimuth 0 (thrust ahead): the middle of a standard 1000-2000 µs servo."""
SERVO_HALF_TURN_US = 400.0
"""Default change of pulse width for half a turn (π): −π…π is 1100…1900 µs, inside the standard range."""
MOTOR_NEUTRAL_US = 1500.0
"""Default neutral (``SERVOn_TRIM``) of a reversible motor output: ArduPilot's default trim."""
ESC_DEAD_BAND_US = 25.0
"""Default half width of the band around a motor output's neutral where the ESC is not driven (µs): the
common ±25 µs of reversible (bidirectional) ESCs."""


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ArduPilotWiring:
    """How an ArduPilot's outputs reach the vessel's thrusters (the source's ``[sources.ardupilot]``).

    ``esc``: ESC index (1-32, as in ``ESC_TELEMETRY_1_TO_4`` … ``_29_TO_32``) → thruster id, whose
    shaft speed the ESC reports. ``servo``: servo output channel (1-32; ``SERVO_OUTPUT_RAW`` port p carries
    channels 16p+1 … 16p+16) → azimuth thruster id, whose angle the pulse width sets linearly:
    azimuth = π (pwm − ``servo_neutral_us``) / ``servo_half_turn_us`` (a negative half turn reverses a
    servo mounted the other way round). ``esc_direction``: ESC index → (servo output channel of its
    reversible motor output, that output's neutral in µs): the sign of the ESC's rpm, which its telemetry
    does not carry; a pulse within ``esc_dead_band_us`` of the neutral does not drive the motor.
    """

    esc: Mapping[int, int] = field(default_factory=dict)
    servo: Mapping[int, int] = field(default_factory=dict)
    servo_neutral_us: float = SERVO_NEUTRAL_US
    servo_half_turn_us: float = SERVO_HALF_TURN_US
    esc_direction: Mapping[int, tuple[int, float]] = field(default_factory=dict)
    esc_dead_band_us: float = ESC_DEAD_BAND_US

    def azimuth_rad(self, pwm_us: float) -> float:
        """The azimuth (rad, not wrapped) a servo pulse width commands."""
        return (pwm_us - self.servo_neutral_us) / self.servo_half_turn_us * math.pi

    def direction(self, pwm_us: float, neutral_us: float) -> int:
        """+1 ahead / −1 astern for a motor output pulse beyond the dead band around its neutral, else 0."""
        if pwm_us > neutral_us + self.esc_dead_band_us:
            return 1
        if pwm_us < neutral_us - self.esc_dead_band_us:
            return -1
        return 0

    @cached_property
    def direction_channels(self) -> Mapping[int, tuple[tuple[int, float], ...]]:
        """Servo output channel → the (ESC index, neutral µs) whose direction it gives."""
        out: dict[int, list[tuple[int, float]]] = {}
        for esc, (channel, neutral) in sorted(self.esc_direction.items()):
            out.setdefault(channel, []).append((esc, neutral))
        return {ch: tuple(v) for ch, v in out.items()}


_NO_WIRING = ArduPilotWiring()
_ESC_FIRST = {getattr(_dpgw, f"MAVLINK_MSG_ID_ESC_TELEMETRY_{n}_TO_{n + 3}"): n for n in ESC_TELEMETRY_BLOCKS}
_SERVO_FIELDS = tuple(f"servo{k}_raw" for k in range(1, 17))


def reports(msg: MAVLinkMessage, ardupilot: ArduPilotWiring | None = None) -> list[Report]:
    """The SI records a decoded message carries, in the order the gateway uses them; [] for a message the
    gateway does not use.

    * ``AZIMUTH_THRUSTER_STATUS`` → a :class:`ThrusterReport` (thrust, azimuth, rpm);
    * ``ESC_TELEMETRY_*`` → a :class:`ThrusterReport` (unsigned rpm, its ESC index) per ESC wired to a
      thruster;
    * ``SERVO_OUTPUT_RAW`` → a :class:`ThrusterReport` (azimuth, pwm) per used channel wired to a thruster,
      then an :class:`EscDirectionReport` per ESC whose direction a used channel gives (0 µs means the
      output is not in use);
    * ``GPS_RAW_INT`` → a :class:`PositionReport` with its fix type;
    * ``GLOBAL_POSITION_INT`` → a :class:`PositionReport`, then a :class:`HeadingReport` if ``hdg`` is known;
    * ``ATTITUDE`` → a :class:`HeadingReport` (its yaw).
    """
    m: Any = msg  # pymavlink messages carry their fields as dynamic attributes
    mid = m.get_msgId()
    if mid == AZIMUTH_THRUSTER_STATUS_ID:
        return [
            ThrusterReport(int(m.id), float(m.thrust), float(m.azimuth), float(m.rpm), flags=int(m.flags))
        ]
    wiring = ardupilot or _NO_WIRING
    first = _ESC_FIRST.get(mid)
    if first is not None:
        out: list[Report] = []
        for k, rpm in enumerate(m.rpm):
            tid = wiring.esc.get(first + k)
            if tid is not None:
                out.append(ThrusterReport(tid, rpm=float(rpm), esc=first + k))
        return out
    if mid == _dpgw.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW:
        base = 16 * int(m.port)
        # (channel, pulse width) of the outputs in use; servo9..16 are extensions: absent in a short frame
        used = [
            (base + k + 1, pwm)
            for k, name in enumerate(_SERVO_FIELDS)
            if (pwm := int(getattr(m, name, 0) or 0))
        ]
        out = [
            ThrusterReport(tid, azimuth_rad=wiring.azimuth_rad(pwm), pwm_us=pwm)
            for channel, pwm in used
            if (tid := wiring.servo.get(channel)) is not None
        ]
        if wiring.esc_direction:
            channels = wiring.direction_channels
            for channel, pwm in used:
                for esc, neutral in channels.get(channel, ()):
                    out.append(EscDirectionReport(esc, wiring.direction(pwm, neutral), pwm))
        return out
    if mid == _dpgw.MAVLINK_MSG_ID_GPS_RAW_INT:
        return [PositionReport(m.lat / 1e7, m.lon / 1e7, m.alt / 1e3, int(m.fix_type))]
    if mid == _dpgw.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
        position = PositionReport(m.lat / 1e7, m.lon / 1e7, m.alt / 1e3)
        if m.hdg == HDG_UNKNOWN:
            return [position]
        return [position, HeadingReport(math.radians(m.hdg / 100.0))]
    if mid == _dpgw.MAVLINK_MSG_ID_ATTITUDE:
        return [HeadingReport(float(m.yaw))]
    return []


def parse_frames(data: bytes | bytearray | memoryview, mav: MAVLink | None = None) -> list[MAVLinkMessage]:
    """All valid frames in one complete buffer, in order; bad bytes and a trailing incomplete frame are
    skipped, never raised. For a stream, or to see what was rejected, use :class:`FrameParser`."""
    parser = FrameParser(mav)
    return parser.feed(data) + parser.flush()


# ---------------------------------------------------------------------------------------------- helpers


def _next_marker(buf: bytearray, pos: int) -> int:
    """Index of the next MAVLink 1 or 2 start marker at or after ``pos`` (``len(buf)`` if none)."""
    n = len(buf)
    i2 = buf.find(_V2, pos)
    i1 = buf.find(_V1, pos)
    candidates = [i for i in (i1, i2) if i >= 0]
    return min(candidates) if candidates else n


def _frame_size(buf: bytearray, pos: int) -> int | None:
    """Total frame length starting at ``pos``; None if the header is not complete yet, -1 if invalid."""
    if buf[pos] == _V2:
        if len(buf) - pos < 3:
            return None
        length, incompat = buf[pos + 1], buf[pos + 2]
        if incompat & ~_dpgw.MAVLINK_IFLAG_SIGNED:
            return -1
        signature = _dpgw.MAVLINK_SIGNATURE_BLOCK_LEN if incompat & _dpgw.MAVLINK_IFLAG_SIGNED else 0
        return _dpgw.HEADER_LEN_V2 + length + 2 + signature
    if len(buf) - pos < 2:
        return None
    return _dpgw.HEADER_LEN_V1 + buf[pos + 1] + 2


def _check_uint(name: str, value: int, bits: int) -> None:
    if not 0 <= value < 2**bits:
        raise ValueError(f"{name} must be in 0..{2**bits - 1}, got {value}")


def _pad4(name: str, values: Sequence[float]) -> list[float]:
    if len(values) > 4:
        raise ValueError(f"{name}: an ESC_TELEMETRY message carries 4 ESCs, got {len(values)} values")
    return [*values, *([0] * (4 - len(values)))]


def _quad(name: str, values: Sequence[float], scale: float, top: int) -> list[int]:
    """Four values scaled to integer wire units and saturated to 0..top (NaN is an error)."""
    out = []
    for v in _pad4(name, values):
        if math.isnan(v):
            raise ValueError(f"{name}: NaN cannot be sent in an integer field")
        out.append(min(max(round(v * scale), 0), top))
    return out
