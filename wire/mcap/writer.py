"""The MCAP log every dpgw program writes: `McapLogWriter`.

One channel per topic, JSON Schema (`jsonschema`) schemas, `json` messages. A typed message
(`wire.messages`) brings its own schema; a plain mapping gets the schema of its topic
(`wire.messages.message_for_topic`). `log_time` is the receive time, `publish_time` the event's stamp
(DESIGN.md, "Time"). Reading a log back: `wire.mcap.reader`.

Crash safety: the mcap `Writer` keeps the open chunk in memory, so a killed process would lose the whole
chunk. `McapLogWriter` closes the chunk and hands it to the OS (write + flush: survives `kill -9`) at least
every `flush_interval_s` of log time or of wall time. A background thread does the wall-time flush when
no messages arrive, and the fsync (survives power loss) about once per `flush_interval_s`, outside the
lock, so a slow disk never blocks the tasks that write.

Rotation: the first file is `path` itself; when a limit is passed the file is finished cleanly (summary,
footer) and writing continues in `<stem>_0001<suffix>`, `<stem>_0002<suffix>`, ... beside it
(`trial.mcap`, `trial_0001.mcap`, ...; `wire.mcap.rotation`). Each file is self-contained: schemas and
channels are registered again in every file.

Failures: a write the disk refuses (full, gone, read-only, an I/O error) never raises into the caller:
the program writing the log is a DP gateway, and its outputs must go on. The file being written is left
as it is (readable up to its last whole record), `error` says what failed (logged once), messages are
dropped and counted in `lost` until a new file of the set can be opened, tried every `retry_s` of wall
time; then logging resumes (logged too) in the next file of the set.

Restarts: with ``continue_set=True`` (the gateway's log) the first file is the next free one of the set
(`trial_0003.mcap` when `trial.mcap` .. `trial_0002.mcap` are there), so a restarted service never
overwrites what the run before it logged.

JSON: numpy arrays and scalars become lists and numbers; non-finite floats (NaN, ±inf) become `null`,
since JSON has no NaN; bytes become base64 strings (`wire.json_payload`).
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import functools
import heapq
import json
import logging
import math
import os
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import msgspec
import numpy as np
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from wire.json_payload import encode_json
from wire.mcap.fast import _MESSAGE_HEAD, FastWriter
from wire.mcap.format import RECORD_HEADER
from wire.mcap.rotation import StrPath, next_index, rotated_path
from wire.message_schema import json_schema
from wire.messages import LocationFix, Message, RawMavlink, RawNmea, Time, message_for_topic

__all__ = ["RETRY_S", "McapLogWriter", "SchemaSpec"]

log = logging.getLogger(__name__)

_DISK_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO})
"""Errors of the disk, not of the path: at start-up they do not stop the program (writing retries)."""

RETRY_S = 10.0
"""After a failed write, a new file is tried this often (wall s): a disk that has room again, a directory
that is back, is written to within this time, and a disk still full costs one attempt per period."""

SchemaSpec = tuple[str, Mapping[str, Any]] | type[Message]
"""A channel's schema: a message class, or (schema name, JSON Schema) for a payload nobody typed."""


@functools.cache
def library_name() -> str:
    """The MCAP header's `library` (which program wrote the file, for whoever debugs it): ``"dpgw 0.1.0
    (mcap 1.6.0)"``, dpgw's release and that of the mcap library whose record layout the file has; a
    name alone for a package not installed (a checkout run in place)."""
    from importlib.metadata import PackageNotFoundError, version

    parts = []
    for package in ("dpgw", "mcap"):
        try:
            parts.append(f"{package} {version(package)}")
        except PackageNotFoundError:
            parts.append(package)
    return f"{parts[0]} ({parts[1]})"


@functools.cache
def _schema_bytes(cls: type[Message]) -> tuple[str, bytes]:
    """(schema name, JSON Schema as compact JSON) of a message class: made once per process."""
    return _dump_schema(cls.TITLE or "", json_schema(cls))


def _dump_schema(name: str, schema: Mapping[str, Any]) -> tuple[str, bytes]:
    return name, json.dumps(schema, separators=(",", ":"), ensure_ascii=False).encode()


_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}

ZSTD_LEVEL = 1
"""zstd level of the chunks. 1, not the mcap library's 3: on dpgw's JSON it is both faster (0.35 against
0.51 ms a 256 KiB chunk of replay output, ~1.6 µs a replay cycle) and smaller (6.3 against 5.9 times)."""

# Record sizes from the MCAP specification (opcode u8 + length u64 + fields), used to keep every chunk's
# uncompressed content <= chunk_size. The mcap Writer only closes a chunk *after* the message that took it
# past chunk_size, so on its own a chunk can exceed the limit by one message.
_MESSAGE_FIXED = RECORD_HEADER + 2 + 4 + 8 + 8  # channel_id u16, sequence u32, log_time, publish_time
# Kept free in each chunk so the Chunk record itself also fits in chunk_size: its header (start/end time,
# uncompressed size and crc, compression string, records length: 49 bytes) plus the few bytes a zstd/lz4
# frame adds to data that does not compress.
_CHUNK_MARGIN = 128


def _schema_record_size(name: str, encoding: str, data: bytes) -> int:
    return RECORD_HEADER + 2 + (4 + len(name.encode())) + (4 + len(encoding.encode())) + (4 + len(data))


def _channel_record_size(topic: str, message_encoding: str) -> int:
    # id u16, schema_id u16, topic, message_encoding, metadata map (u32 byte length; empty here)
    return RECORD_HEADER + 2 + 2 + (4 + len(topic.encode())) + (4 + len(message_encoding.encode())) + 4


def raw_nmea_record(source: str, text: str | bytes, peer: str = "") -> tuple[str, bytes]:
    """Topic and payload of `McapLogWriter.write_raw_nmea` (schema `RawNmea`), for `write_many`.

    The common chunk — ASCII bytes ending in a line terminator, from a link with one sender — is written
    from the source's cached JSON head and the text alone: 0.53 against 0.71 µs for a USV log's cycle
    (~260 bytes; best of 7, timeit). Every other chunk goes through the `RawNmea` message
    (`raw_nmea_record_reference`). The bytes are the same (tests/test_mcaplog.py): the message's other
    fields hold their defaults then, and are left out."""
    if not peer and type(text) is bytes:
        raw = text.rstrip(b"\r\n")
        if len(raw) == len(text) - 2 and text[-2:] == b"\r\n" and raw.isascii():
            known = _RAW_NMEA_HEADS.get(source)
            if known is None:
                known = _RAW_NMEA_HEADS[source] = (
                    f"/raw/nmea/{source}",
                    b'{"source":' + _JSON_ENCODE(source) + b',"text":',
                )
            return known[0], known[1] + _JSON_ENCODE(raw.decode("ascii")) + b"}"
    return raw_nmea_record_reference(source, text, peer)


_RAW_NMEA_HEADS: dict[str, tuple[str, bytes]] = {}
"""Source -> (topic, the JSON of a `RawNmea` up to its text), for `raw_nmea_record`."""
_JSON_ENCODE = msgspec.json.Encoder().encode  # (a str is encoded as within any message)


def raw_nmea_record_reference(source: str, text: str | bytes, peer: str = "") -> tuple[str, bytes]:
    """`raw_nmea_record` by way of the `RawNmea` message: the readable form, for every chunk."""
    if isinstance(text, str):
        cut = text.rstrip("\r\n")
        eol = _eol(text[len(cut) :])
        msg = RawNmea(source=source, text=cut, peer=peer, unterminated=cut == text, eol=eol)
    else:
        data = bytes(text)
        raw = data.rstrip(b"\r\n")
        open_end = len(raw) == len(data)  # (an empty chunk too: an empty datagram ended no line)
        eol = _eol(data[len(raw) :].decode("ascii"))
        try:
            msg = RawNmea(source=source, text=raw.decode("ascii"), peer=peer, unterminated=open_end, eol=eol)
        except UnicodeDecodeError:
            text_shown = raw.decode("ascii", "backslashreplace")
            msg = RawNmea(source=source, text=text_shown, data=raw, peer=peer, unterminated=open_end, eol=eol)
    return f"/raw/nmea/{source}", msg.encode()


def _eol(end: str) -> str:
    """`RawNmea.eol` of a chunk whose stripped line terminator was ``end``: left out ("") for CR LF (the
    common case) and for none (the chunk is then `unterminated`); otherwise the exact CR/LF characters, so
    the log keeps every byte (a bare LF, a CR LF split across two reads, blank lines)."""
    return "" if end in ("", "\r\n") else end


def raw_mavlink_record(source: str, frame: bytes, peer: str = "") -> tuple[str, bytes]:
    """Topic and payload of `McapLogWriter.write_raw_mavlink` (schema `RawMavlink`), for `write_many`."""
    return f"/raw/mavlink/{source}", RawMavlink(data=bytes(frame), source=source, peer=peer).encode()


class McapLogWriter:
    """Thread-safe MCAP log writer: lazy channels, bounded chunks, time-bounded crash loss, rotation.

    `rotate_bytes`: start a new file once this one has reached this size on disk (checked when a chunk is
    written, so a file can exceed it by about one chunk plus the summary). `rotate_seconds`: start a new
    file before a message whose log time is this far past the file's first message (log time, so replay
    rotates exactly as live did). `fsync=False` keeps crash safety against a killed process (the OS has the
    data) but not against power loss. `background_flush=False` leaves wall-time flushing to `write` calls.
    `continue_set`: start after the last existing file of the set instead of overwriting `path`.
    `retry_s`: after a failure, how often a new file is tried (default `RETRY_S`); `error`, `lost` and
    `failures` say what happened.

    Do not call `close()` from a signal handler (a write may be half done in the interrupted frame): set a
    flag there and close from the main flow, or use `loop.add_signal_handler` in asyncio.
    """

    def __init__(
        self,
        path: StrPath,
        *,
        chunk_size: int = 256 * 1024,
        flush_interval_s: float = 1.0,
        flush_on_log_time: bool = True,
        rotate_bytes: int | None = None,
        rotate_seconds: float | None = None,
        profile: str = "",
        library: str | None = None,
        compression: str = "zstd",
        fsync: bool = True,
        background_flush: bool = True,
        continue_set: bool = False,
        retry_s: float | None = None,
    ) -> None:
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of {sorted(_COMPRESSION)}, not {compression!r}")
        if chunk_size <= 2 * _CHUNK_MARGIN or flush_interval_s <= 0:
            raise ValueError(f"need chunk_size > {2 * _CHUNK_MARGIN} and flush_interval_s > 0")
        self._base = Path(path)
        self._chunk_budget = chunk_size - _CHUNK_MARGIN  # uncompressed bytes of records per chunk
        self._flush_interval_s = flush_interval_s
        self._flush_interval_ns = int(flush_interval_s * 1e9)
        # Live, log time is wall time and both clocks bound the loss on a crash. Replay writes hours of log
        # time a second: flushing on log time there only makes tiny chunks, so it can be turned off.
        self._flush_on_log_time = flush_on_log_time
        self._rotate_bytes = rotate_bytes
        self._rotate_ns = None if rotate_seconds is None else int(rotate_seconds * 1e9)
        self._profile = profile
        self._library = library_name() if library is None else library
        self._compression = _COMPRESSION[compression]
        self._fsync = fsync
        self._lock = threading.Lock()
        # `hold_for_order`: records held until the log's newest time is this far past them (0: none held)
        self._reorder_ns = 0
        self._held: list[tuple[int, int, str, bytes, int, Any]] = []
        self._held_seq = 0
        self._newest_ns = 0
        self._closed = False
        self._warned_closed = False
        self._metadata: list[tuple[str, dict[str, str]]] = []
        self.paths: list[Path] = []
        """Every file opened so far, in order."""
        self.message_count = 0
        """Messages written over all files."""
        self.error: str | None = None
        """What failed, while writing is failed (None when the log is being written)."""
        self.lost = 0
        """Messages dropped because writing had failed (over the writer's life; besides them, what the
        failed file had not yet handed to the OS: at most `flush_interval_s` of messages)."""
        self.failures = 0
        """Times writing failed (each followed by retries until a new file could be opened)."""
        self.retry_s = RETRY_S if retry_s is None else retry_s
        """After a failure, how often a new file is tried (wall s)."""
        self._retry_at = 0.0
        self._lost_since_fail = 0
        self._next_index = 0

        # State of the current file; None between a rotation and the next write.
        self._file: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._file_first_log_ns: int | None = None
        self._pending_bytes = 0  # uncompressed bytes in the open chunk (spec record sizes)
        self._dirty = False  # messages not yet handed to the OS
        self._last_flush_wall = time.monotonic()
        self._last_fsync_wall = self._last_flush_wall
        self._unsynced = False  # data handed to the OS but not fsynced yet
        self._last_flush_log_ns: int | None = None
        self._max_log_ns: int | None = None

        if continue_set:
            self._next_index = next_index(self._base)
        # Open the first file now, so a bad path stops start-up with a clear error, not the first write. A
        # disk that is full (or failing) is not a mistake in the path: writing starts failed and retries.
        try:
            self._open(self._next_index)
        except OSError as exc:
            if exc.errno not in _DISK_ERRNOS:
                raise
            self._fail_locked(exc)

        self._stop = threading.Event()
        self._flusher: threading.Thread | None = None
        if background_flush:
            self._flusher = threading.Thread(target=self._flush_loop, name="mcaplog-flush", daemon=True)
            self._flusher.start()
        # A program that exits without close() (or on an uncaught exception) still gets a complete file.
        atexit.register(self.close)

    # -- public API

    @property
    def path(self) -> Path:
        """The file being written (or last written; the first to be, if none could be opened yet)."""
        return self.paths[-1] if self.paths else rotated_path(self._base, self._next_index)

    def write(
        self,
        topic: str,
        payload: Message | Mapping[str, Any],
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        schema: SchemaSpec | None = None,
    ) -> None:
        """Log `payload` on `topic`: a typed message (`wire.messages`), or a JSON object (a mapping;
        numpy and NaN allowed) such as an input as received or a record read back from a log.

        The channel and its schema are registered on the first write to a topic: `schema` if given, else
        the message's own class, else the one `wire.messages.message_for_topic` picks. `publish_time_ns`
        defaults to `log_time_ns`.
        """
        if type(payload) is dict:  # (checked first: ABC checks are slow)
            data = encode_json(payload)
        elif isinstance(payload, Message):
            data = payload.encode()
            schema = schema or type(payload)
        elif isinstance(payload, Mapping):
            data = encode_json(payload)
        else:
            raise TypeError(
                f"payload must be a message or a JSON object (Mapping), not {type(payload).__name__}"
            )
        self.write_encoded(topic, data, log_time_ns, publish_time_ns, schema=schema)

    def write_raw_nmea(
        self,
        source: str,
        text: str | bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        peer: str = "",
    ) -> None:
        """Log one NMEA sentence as received on `/raw/nmea/<source>`. Bytes that are not ASCII are kept
        exactly in `data` (base64) and shown escaped in `text`; ``peer``: the sender on a shared link."""
        topic, data = raw_nmea_record(source, text, peer)
        self.write_encoded(topic, data, log_time_ns, publish_time_ns, schema=RawNmea)

    def write_raw_mavlink(
        self,
        source: str,
        frame: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        peer: str = "",
    ) -> None:
        """Log one MAVLink frame as received on `/raw/mavlink/<source>` (`data` = base64 of the bytes;
        ``peer``: the sender on a shared link)."""
        topic, data = raw_mavlink_record(source, frame, peer)
        self.write_encoded(topic, data, log_time_ns, publish_time_ns, schema=RawMavlink)

    def write_location_fix(
        self,
        source: str,
        lat_deg: float,
        lon_deg: float,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        altitude_m: float = 0.0,
        position_covariance: Sequence[float] | np.ndarray | None = None,
        covariance_type: int = 0,
        heading_rad: float | None = None,
        topic: str | None = None,
    ) -> bool:
        """Log a `foxglove.LocationFix` on `topic` (default `/gnss/<source>/fix`), stamped with
        `publish_time_ns` (default `log_time_ns`). `position_covariance` is 3x3 row-major ENU (m²), as
        Foxglove defines it. Returns False, writing nothing, if latitude or longitude is not finite: the
        Foxglove schema has no null. A non-finite covariance is logged as zeros with type 0 (unknown)."""
        if not (math.isfinite(lat_deg) and math.isfinite(lon_deg)):
            return False
        stamp = int(log_time_ns if publish_time_ns is None else publish_time_ns)
        cov = [0.0] * 9
        if position_covariance is not None:
            c = np.asarray(position_covariance, dtype=float).reshape(9)
            if np.isfinite(c).all():
                cov = c.tolist()
            else:
                covariance_type = 0
        fix = LocationFix(
            timestamp=Time(sec=max(stamp, 0) // 1_000_000_000, nsec=max(stamp, 0) % 1_000_000_000),
            frame_id=source,
            latitude=float(lat_deg),
            longitude=float(lon_deg),
            altitude=float(altitude_m) if math.isfinite(altitude_m) else 0.0,
            position_covariance=cov,
            position_covariance_type=int(covariance_type),
            heading=float(heading_rad) if heading_rad is not None and math.isfinite(heading_rad) else None,
        )
        self.write(topic or f"/gnss/{source}/fix", fix, log_time_ns, stamp)
        return True

    def write_encoded(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        schema: SchemaSpec | None = None,
    ) -> None:
        """`write` for a payload already encoded (`Message.encode()`, `encode_json`): the live service
        encodes each message once for Zenoh and the log. `schema` as for `write`."""
        log_time_ns = int(log_time_ns)
        publish_time_ns = log_time_ns if publish_time_ns is None else int(publish_time_ns)
        with self._lock:
            if self._closed:
                if not self._warned_closed:
                    log.warning("McapLogWriter(%s) is closed; dropping writes (first: %s)", self._base, topic)
                    self._warned_closed = True
                return
            if self.error is not None and not self._recover_locked():
                self._drop(1)
                return
            if self._reorder_ns:
                self._hold_locked(topic, data, log_time_ns, publish_time_ns, schema)
                return
            try:
                self._write_locked(topic, data, log_time_ns, publish_time_ns, schema)
            except OSError as exc:
                self._fail_locked(exc, lost=1)

    def hold_for_order(self, window_s: float) -> None:
        """From now on write every record only once the newest log time written to this log is
        ``window_s`` past it (and the rest at close), in log-time order: for a log that several producers
        write into, each in its own order but at its own pace. `dpgw demo`'s simulator writes its truth as
        the plant computes it, up to ~0.4 s before the gateway logs the inputs of that time, and the
        gateway's records of a time can come a few ms before the truth's: written as they came, a reader
        that streams the file (without its index) saw time go back at nearly every step (479 times in a
        150 s demo). A crash loses at most the window's records more. 0: write at once again."""
        with self._lock:
            self._reorder_ns = max(0, round(window_s * 1e9))
            if not self._reorder_ns:
                self._release_held_locked(None)

    def _hold_locked(
        self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int, schema: Any
    ) -> None:
        """`hold_for_order`'s heap: hold the record, then write every held one the window has passed."""
        heapq.heappush(self._held, (log_time_ns, self._held_seq, topic, data, publish_time_ns, schema))
        self._held_seq += 1
        if log_time_ns > self._newest_ns:
            self._newest_ns = log_time_ns
        self._release_held_locked(self._newest_ns - self._reorder_ns)

    def _release_held_locked(self, until_ns: int | None) -> None:
        """Write the held records up to ``until_ns`` (None: all), oldest first."""
        held = self._held
        wrote = False
        while held and (until_ns is None or held[0][0] <= until_ns):
            ns, _, topic, data, publish_ns, schema = heapq.heappop(held)
            try:
                self._write_locked(topic, data, ns, publish_ns, schema, check_flush=False)
            except OSError as exc:
                self._fail_locked(exc, lost=1 + len(held))
                held.clear()
                return
            wrote = True
        if wrote:
            try:
                self._after_write()  # (its flush finds a file removed under it, a full disk)
            except OSError as exc:
                self._fail_locked(exc, lost=len(held))
                held.clear()

    def write_many(self, items: Sequence[tuple[str, bytes, int, SchemaSpec | None]]) -> None:
        """`write_encoded` for several payloads in order, each ``(topic, data, time_ns, schema)`` with the
        same log and publish time: one lock and one flush-time check for all of them (replay writes a
        cycle's raw input and outputs at once, ~4 messages; the per-call overhead was a third of the
        writing). Rotation by size is still checked after every message, so files split as with
        `write_encoded`. A sequence, not any iterable, so that a write that fails counts every message
        of the call as lost however far it got, the same way whether the writer was already failed or
        failed now."""
        with self._lock:
            if self._closed:
                if not self._warned_closed:
                    log.warning("McapLogWriter(%s) is closed; dropping writes", self._base)
                    self._warned_closed = True
                return
            if self.error is not None and not self._recover_locked():
                self._drop(len(items))
                return
            if self._reorder_ns:
                for topic, data, time_ns, schema in items:
                    self._hold_locked(topic, data, int(time_ns), int(time_ns), schema)
                return
            try:
                writer = self._writer
                if (
                    self._rotate_bytes is None
                    and self._rotate_ns is None
                    and isinstance(writer, FastWriter)
                    and writer.fast
                ):
                    wrote = self._write_many_fast(writer, items)
                else:
                    wrote = False
                    for topic, data, time_ns, schema in items:
                        self._write_locked(topic, data, int(time_ns), int(time_ns), schema, check_flush=False)
                        wrote = True
                if wrote:
                    self._after_write()
            except OSError as exc:
                self._fail_locked(exc, lost=len(items))

    def _write_many_fast(self, writer: FastWriter, items: Iterable[tuple[str, bytes, int, Any]]) -> bool:
        """`write_many`'s loop without rotation: `_write_locked` (known channel) and `FastWriter.add_message`
        inlined, with two savings over calling them per message. The records (head, data) of a call are
        joined and written to the chunk's buffer at once, their offsets counted here instead of asked of
        the buffer. And the bookkeeping (statistics, chunk times, message indexes) is left to
        `FastWriter.settle`, a channel at a time when the chunk closes: this loop only notes each
        message's time and offset under its channel. Replay writes ~8 messages a cycle on a 5 Hz log;
        this writes a USV cycle in ~1.2 µs less than the loop before it, which inlined the same calls
        message by message (11.6 against 12.8 µs, compression included; best of 6 interleaved runs). A
        message on a new channel goes the readable way. Same file byte for byte (tests/test_mcaplog.py).
        """
        channels = self._channels
        budget = self._chunk_budget
        pending = self._pending_bytes
        max_ns = self._max_log_ns
        chunk: Any = writer._fast_chunk
        chunk_size = writer._fast_chunk_size
        pack = _MESSAGE_HEAD.pack
        marks = writer.pending  # channel id -> flat (time, offset) pairs, settled when the chunk closes
        parts: list[bytes] = []  # this call's records not yet in the chunk's buffer
        buf = chunk.record_writer._buffer  # (a new BytesIO after every chunk)
        offset = buf.tell()  # where the next record goes in the chunk
        written = 0
        for topic, data, time_ns, schema in items:
            time_ns = int(time_ns)
            channel_id = channels.get(topic)
            size = _MESSAGE_FIXED + len(data)
            if channel_id is None or (pending and pending + size > budget):
                if parts:
                    buf.write(b"".join(parts))
                    parts.clear()
                if channel_id is None:  # a new channel: its schema and channel records first
                    self._pending_bytes, self._max_log_ns = pending, max_ns
                    self._write_locked(topic, data, time_ns, time_ns, schema, check_flush=False)
                    pending, max_ns = self._pending_bytes, self._max_log_ns
                    marks = writer.pending
                    buf = chunk.record_writer._buffer
                    offset = buf.tell()
                    written += 1
                    continue
                self._close_chunk()  # before this message overfills the chunk
                pending = 0
                marks = writer.pending  # (settled: a new one)
                buf = chunk.record_writer._buffer
                offset = 0
            flat = marks.get(channel_id)
            if flat is None:
                flat = marks[channel_id] = []
            flat += (time_ns, offset)
            parts += (pack(5, size - 9, channel_id, 0, time_ns, time_ns), data)
            offset += size
            if offset > chunk_size:  # one record larger than a chunk: closed as its own chunk
                buf.write(b"".join(parts))
                parts.clear()
                writer._fast_finalize()  # type: ignore[misc]
                marks = writer.pending
                buf = chunk.record_writer._buffer
                offset = 0
            pending += size
            if pending > budget:
                pending = 0
            if max_ns is None or time_ns > max_ns:
                max_ns = time_ns
            written += 1
        if parts:
            buf.write(b"".join(parts))
        self._pending_bytes, self._max_log_ns = pending, max_ns
        self.message_count += written
        if written:
            self._dirty = True
        return written > 0

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Add an MCAP Metadata record (e.g. the configuration); repeated in every rotated file."""
        entry = (name, {str(k): str(v) for k, v in data.items()})
        with self._lock:
            if self._closed:
                return
            self._metadata.append(entry)
            if self._writer is not None:
                try:
                    self._writer.add_metadata(*entry)
                except OSError as exc:
                    self._fail_locked(exc)

    def rotate(self) -> Path:
        """Finish the file being written and start the next of the set now, as a size or time limit
        would (the gateway starts a file for each run of a restarted simulator, so that each replays
        alone); a file with no message yet is kept instead. Returns the file written from now on (the one
        to be tried next while writing has failed). The log-time flush starts again with the new file:
        its times may be earlier than the last file's. What `hold_for_order` holds is written first, to the
        file being finished (its records are of the run before), and the order starts again with the new
        file: held on, the last records of a simulator's run went into the next run's file."""
        with self._lock:
            if self._held and not self._closed:
                self._release_held_locked(None)
            self._newest_ns = 0
            if not self._closed and self.error is None:
                try:
                    if self._writer is None or self._file_first_log_ns is not None:
                        self._finish_file()
                        self._open(self._next_index)
                except OSError as exc:
                    self._fail_locked(exc)
            self._max_log_ns = self._last_flush_log_ns = None
            return self.paths[-1] if self._writer is not None else rotated_path(self._base, self._next_index)

    def flush(self, fsync: bool | None = None) -> None:
        """Close the open chunk and hand everything to the OS now; fsync too if `fsync` (default: the
        writer's setting)."""
        with self._lock:
            if not self._closed and self.error is None:
                try:
                    self._flush_locked(self._fsync if fsync is None else fsync)
                except OSError as exc:
                    self._fail_locked(exc)

    def close(self) -> None:
        """Write the summary and footer and close the file. Idempotent."""
        with self._lock:
            if self._closed:
                return
            if self._held:
                self._release_held_locked(None)
            self._closed = True
            try:
                self._finish_file()
            except OSError as exc:
                self._fail_locked(exc)
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join()
        atexit.unregister(self.close)

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> McapLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- internals (all *_locked methods and _open/_finish_file run with self._lock held)

    def _open(self, index: int) -> None:
        path = rotated_path(self._base, index)
        existed = os.path.lexists(path)
        self._file = open(path, "wb")  # noqa: SIM115 - lives until _finish_file
        try:
            self._writer = FastWriter(
                self._file,
                chunk_size=self._chunk_budget,
                compression=self._compression,
                zstd_level=ZSTD_LEVEL,
            )
            self._writer.start(profile=self._profile, library=self._library)
            for name, data in self._metadata:
                self._writer.add_metadata(name, data)
            self._channels.clear()
            self._schemas.clear()
            self._file_first_log_ns = None
            self._pending_bytes = 0
            # A new file's name must survive power loss too: fsync the directory entry once.
            self._hand_to_os(self._fsync)
            if self._fsync:
                _fsync_dir(path.parent)
        except OSError as exc:
            if exc.filename is None:  # (a write, not the open: name the file all the same)
                exc.filename = str(path)
            self._abandon_file()
            if not existed:  # (a header that did not fit: the retry starts this file again)
                with contextlib.suppress(OSError):
                    path.unlink()
            raise
        self.paths.append(path)
        self._next_index = index + 1

    def _abandon_file(self) -> None:
        """Let go of the file being written after a failure: left as it is (readable up to its last whole
        record), its descriptor closed even if the close cannot write what Python still buffered."""
        f = self._file
        self._file = None
        self._writer = None
        self._dirty = False
        self._unsynced = False
        self._pending_bytes = 0
        if f is not None:
            with contextlib.suppress(OSError):
                f.close()  # (closes the descriptor even when its flush fails)

    def _fail_locked(self, exc: OSError, lost: int = 0) -> None:
        """Writing failed: say so (once), drop the file, retry a new one in `retry_s`."""
        error = self._cannot_write(exc)
        if self.error is None:
            self.failures += 1
            self._lost_since_fail = 0
            log.error(
                "log: %s; messages are dropped (counted) and a new file is tried every %g s",
                error,
                self.retry_s,
            )
        self.error = error
        self._drop(lost)
        self._abandon_file()
        self._retry_at = time.monotonic() + self.retry_s

    def _cannot_write(self, exc: OSError) -> str:
        """What `error` says of a failure: the file (the one being written if the error names none)."""
        path = exc.filename or (self.paths[-1] if self.paths else self._base)
        return f"cannot write {path}: {exc.strerror or exc}"

    def _drop(self, n: int) -> None:
        """``n`` messages not logged because writing has failed."""
        self.lost += n
        self._lost_since_fail += n

    def _recover_locked(self) -> bool:
        """After a failure, when `retry_s` has passed: open the next file of the set. True if writing."""
        now = time.monotonic()
        if now < self._retry_at:
            return False
        self._retry_at = now + self.retry_s
        try:
            self._open(self._next_index)
        except OSError as exc:
            self.error = self._cannot_write(exc)
            log.debug("log: still failing: %s", self.error)
            return False
        log.warning(
            "log: writing again, to %s (%d messages were not logged after: %s)",
            self.paths[-1],
            self._lost_since_fail,
            self.error,
        )
        self.error = None
        return True

    def _finish_file(self) -> None:
        if self._writer is None or self._file is None:
            return
        self._writer.finish()  # closes the open chunk, writes summary + footer + magic
        self._file.flush()
        if self._fsync:
            os.fsync(self._file.fileno())
        self._file.close()
        self._writer = None
        self._file = None
        self._dirty = False
        self._unsynced = False

    def _write_locked(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int,
        schema: SchemaSpec | None,
        check_flush: bool = True,
    ) -> None:
        # The common case is kept short (replay writes ~150,000 messages a second): a known channel (so
        # this file already has a message and its log times are set) and no rotation due.
        channel_id = self._channels.get(topic)
        if (
            channel_id is None
            or self._writer is None
            or (self._rotate_ns is not None and log_time_ns - self._file_first_log_ns >= self._rotate_ns)  # type: ignore[operator]
        ):
            channel_id, size = self._prepare(topic, len(data), log_time_ns, schema)
        else:
            size = _MESSAGE_FIXED + len(data)
            # Close the chunk *before* this message would take it past its budget.
            if self._pending_bytes and self._pending_bytes + size > self._chunk_budget:
                self._close_chunk()
        writer = self._writer
        assert writer is not None
        writer.add_message(channel_id, log_time_ns, data, publish_time_ns)
        self.message_count += 1
        self._dirty = True
        self._pending_bytes += size
        if self._pending_bytes > self._chunk_budget:
            # A single record larger than chunk_size: the mcap Writer has already closed it as its own chunk.
            self._pending_bytes = 0
        if self._max_log_ns is None or log_time_ns > self._max_log_ns:
            self._max_log_ns = log_time_ns
        if check_flush:
            self._after_write()
        elif (
            self._rotate_bytes is not None
            and self._file is not None
            and self._file.tell() >= self._rotate_bytes
        ):
            self._finish_file()  # (as `_after_write` would: a file splits where it did)

    def _prepare(
        self, topic: str, data_len: int, log_time_ns: int, schema: SchemaSpec | None
    ) -> tuple[int, int]:
        """For a new channel, a new file or a rotation: rotate or open as due, close the chunk if the
        message and the records it brings would overfill it, register schema and channel. Returns the
        channel id and the bytes the message adds to the chunk."""
        if (
            self._rotate_ns is not None
            and self._file_first_log_ns is not None
            and log_time_ns - self._file_first_log_ns >= self._rotate_ns
        ):
            self._finish_file()
        if self._writer is None:
            self._open(self._next_index)
        writer = self._writer
        assert writer is not None

        size = _MESSAGE_FIXED + data_len
        channel_id = self._channels.get(topic)
        new_schema: tuple[str, bytes] | None = None
        if channel_id is None:
            if schema is None:
                new_schema = _schema_bytes(message_for_topic(topic))
            elif isinstance(schema, tuple):
                new_schema = _dump_schema(*schema)
            else:
                new_schema = _schema_bytes(schema)
            name = new_schema[0]
            if name not in self._schemas:
                size += _schema_record_size(name, SchemaEncoding.JSONSchema, new_schema[1])
            size += _channel_record_size(topic, MessageEncoding.JSON)
        if self._pending_bytes and self._pending_bytes + size > self._chunk_budget:
            self._close_chunk()
        if channel_id is None:
            assert new_schema is not None
            name, schema_bytes = new_schema
            schema_id = self._schemas.get(name)
            if schema_id is None:
                schema_id = writer.register_schema(name, SchemaEncoding.JSONSchema, schema_bytes)
                self._schemas[name] = schema_id
            channel_id = writer.register_channel(topic, MessageEncoding.JSON, schema_id)
            self._channels[topic] = channel_id
        if self._file_first_log_ns is None:
            self._file_first_log_ns = log_time_ns
        if self._last_flush_log_ns is None:
            self._last_flush_log_ns = log_time_ns
        return channel_id, size

    def _after_write(self) -> None:
        """Flush on wall or log time, rotate on size: the checks after every message."""
        now = time.monotonic()
        if now - self._last_flush_wall >= self._flush_interval_s or (
            self._flush_on_log_time and self._max_log_ns - self._last_flush_log_ns >= self._flush_interval_ns  # type: ignore[operator]
        ):
            # fsync here only when there is no background thread to do it off the writers' path.
            self._flush_locked(
                self._fsync
                and self._flusher is None
                and now - self._last_fsync_wall >= self._flush_interval_s
            )

        if (
            self._rotate_bytes is not None
            and self._file is not None
            and self._file.tell() >= self._rotate_bytes
        ):
            self._finish_file()

    def _close_chunk(self) -> None:
        """Close the open chunk and write it (and its message indexes) to the file object."""
        writer = self._writer
        assert writer is not None
        # mcap >= 1.6 has the public Writer.flush(): "finishes the chunk in progress, if any, writes
        # everything buffered so far to the output stream, and flushes the stream". Older releases (1.1 ..
        # 1.5, allowed by pyproject) only have the private, name-mangled Writer.__finalize_chunk, which does
        # the same minus the stream flush (it ends by writing its record buffer to the stream); both are
        # no-ops when the open chunk holds no message.
        if hasattr(writer, "flush"):
            writer.flush()
        else:
            writer._Writer__finalize_chunk()  # type: ignore[attr-defined]
        self._pending_bytes = 0

    def _hand_to_os(self, fsync: bool) -> None:
        assert self._file is not None
        self._file.flush()  # Python's buffer -> OS: now a killed process loses nothing of it
        self._unsynced = True
        if fsync:
            os.fsync(self._file.fileno())  # OS -> disk: survives power loss
            self._last_fsync_wall = time.monotonic()
            self._unsynced = False

    def _flush_locked(self, fsync: bool) -> None:
        self._last_flush_wall = time.monotonic()
        self._last_flush_log_ns = self._max_log_ns
        if self._writer is None or not self._dirty:
            return
        self._close_chunk()
        self._hand_to_os(fsync)
        self._dirty = False
        self._check_file_locked()  # (once a flush interval: one fstat)

    def _check_file_locked(self) -> None:
        """Raise if the file being written has been removed (its directory deleted, a disk unmounted
        lazily): writes to it would succeed and land nowhere anyone can read."""
        if self._file is not None and os.fstat(self._file.fileno()).st_nlink == 0:
            raise FileNotFoundError(errno.ENOENT, "the file was removed while being written", str(self.path))

    def _flush_loop(self) -> None:
        """Wall-time flush while no messages arrive (writes check the clocks themselves), and the fsync."""
        while True:
            sync_fd = None
            with self._lock:
                if self._closed:
                    return
                now = time.monotonic()
                if now - self._last_flush_wall >= self._flush_interval_s:
                    try:
                        self._flush_locked(False)
                    except OSError as exc:
                        self._fail_locked(exc)
                if self._fsync and self._unsynced and self._file is not None:
                    # fsync a duplicate descriptor after releasing the lock: it stays valid even if the file
                    # is closed by a rotation meanwhile, and writers are not held up by the disk.
                    sync_fd = os.dup(self._file.fileno())
                    self._unsynced = False
                wait = self._last_flush_wall + self._flush_interval_s - now
            if sync_fd is not None:
                try:
                    os.fsync(sync_fd)
                except OSError as exc:
                    with self._lock:
                        if not self._closed:
                            self._fail_locked(exc)
                finally:
                    os.close(sync_fd)
                self._last_fsync_wall = time.monotonic()
            if self._stop.wait(max(wait, 0.005)):
                return


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return  # e.g. Windows: directories cannot be opened; nothing to do
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
