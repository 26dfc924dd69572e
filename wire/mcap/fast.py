"""`FastWriter`: the mcap library's `Writer` with a faster `add_message`, byte for byte the same file.

Why: replay writes ~3 messages per NMEA cycle, and `mcap.Writer.add_message` costs ~3.2 µs a message in
Python (a `Message` dataclass, then nine small writes into a BytesIO through `RecordBuilder`), the largest
single item in `bench/bench_replay.py` after decoding. Packing the record head in one `struct` call and
updating the same bookkeeping directly costs ~0.7 µs.

What it does is exactly what `Writer.add_message` + `ChunkBuilder.add_message` do (mcap 1.6): update the
statistics (start/end time, per-channel and total counts), the open chunk's start/end time and its
message index (log time, offset in the chunk), append the Message record (opcode 0x05, u64 length,
u16 channel, u32 sequence, u64 log time, u64 publish time, data), and close the chunk once it passes
`chunk_size`. It reaches the writer's private state (``_Writer__statistics``, ``_Writer__chunk_builder``,
``_Writer__chunk_size``, ``_Writer__finalize_chunk``); when a release of mcap lacks any of them — or the
writer was made without chunking — it falls back to the library's own method, so an mcap upgrade can cost
speed but never a file. The MCAP log tests write the same messages through both and compare the files
byte for byte.

Batches: `McapLogWriter`'s replay path writes a call's records into the open chunk itself and notes each
message's time and offset in `pending`; `settle` does their bookkeeping a channel at a time when the chunk
closes (or before any other message), with the result `add_message` gives one by one. Message indexes
keep their pairs flat and are written in one piece.

It also closes zstd chunks itself (`_Writer__finalize_chunk`: the library's method line for line) with one
compressor for its life, at ``zstd_level`` (the library's 3 by default, and then the library's bytes; the
gateway's `McapLogWriter` asks for 1). The library makes a new compressor for every chunk.
"""

from __future__ import annotations

import struct
import sys
import zlib
from array import array
from typing import Any

from mcap.records import Chunk, ChunkIndex, MessageIndex
from mcap.writer import CompressionType, IndexType, Writer

try:
    import zstandard
except ImportError:  # (the mcap library then refuses zstd itself)
    zstandard = None  # type: ignore[assignment]

_MESSAGE_OPCODE = 0x05
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, length, channel id, sequence, log time, publish time
_MESSAGE_FIXED = 22  # record length excluding the data: 2 + 4 + 8 + 8
_MESSAGE_INDEX_OPCODE = 0x07
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, length, channel id, byte length of the records


class _MessageIndex(MessageIndex):
    """`MessageIndex` that keeps its (log time, offset) pairs flat, ``[t0, o0, t1, o1, ...]`` in `flat`
    (`records` stays empty), and writes them in one piece (the library packs each u64 separately:
    ~two calls per message at every chunk close). Same bytes."""

    def __init__(self, channel_id: int) -> None:
        super().__init__(channel_id=channel_id, records=[])
        self.flat: list[int] = []

    def write(self, stream: Any) -> None:
        flat = self.flat
        stream.write(
            _INDEX_HEAD.pack(_MESSAGE_INDEX_OPCODE, 6 + 8 * len(flat), self.channel_id, 8 * len(flat))
        )
        stream.write(_pack_u64(flat))


_ARRAY_U64 = array("Q").itemsize == 8


def _pack_u64(values: list[int]) -> bytes:
    """``struct.pack(f"<{len(values)}Q", *values)``, without building the argument tuple."""
    if not _ARRAY_U64:
        return struct.pack(f"<{len(values)}Q", *values)
    packed = array("Q", values)
    if sys.byteorder != "little":
        packed.byteswap()
    return packed.tobytes()


class FastWriter(Writer):
    """`mcap.writer.Writer` with `add_message` in one pack (see module docstring)."""

    def __init__(self, *args: Any, zstd_level: int = 3, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._fast_stats = getattr(self, "_Writer__statistics", None)
        self._fast_chunk = getattr(self, "_Writer__chunk_builder", None)
        self._fast_chunk_size = getattr(self, "_Writer__chunk_size", None)
        self._fast_finalize = getattr(self, "_Writer__finalize_chunk", None)
        builder = self._fast_chunk
        # One zstd compressor for the writer's life: `zstandard.compress`, which the library calls for
        # every chunk, makes a new one each time (0.70 against 0.51 ms a 256 KiB chunk of replay JSON,
        # ~2 µs a replay cycle). At the library's level (3, the default) the same bytes as the library
        # (tests/test_mcaplog.py); ``zstd_level`` sets another.
        self._zstd = (
            zstandard.ZstdCompressor(level=zstd_level)
            if zstandard is not None
            and getattr(self, "_Writer__compression", None) == CompressionType.ZSTD
            and all(
                hasattr(self, f"_Writer__{a}")
                for a in ("statistics", "enable_crcs", "flush", "stream", "record_builder", "index_types",
                          "chunk_indices")
            )
            else None
        )  # fmt: skip
        self.fast = (
            self._fast_stats is not None
            and builder is not None
            and self._fast_chunk_size is not None
            and self._fast_finalize is not None
            and hasattr(getattr(builder, "record_writer", None), "_buffer")
            and all(hasattr(builder, a) for a in ("message_indices", "num_messages", "message_start_time"))
        )
        self.pending: dict[int, list[int]] = {}
        """Messages already in the open chunk's buffer whose bookkeeping is not done yet: per channel (in
        order of first appearance) their flat (log time, offset in the chunk) pairs. `McapLogWriter`'s
        batch path adds to it; `settle` does the bookkeeping before anything reads or adds to it."""

    def settle(self) -> None:
        """The bookkeeping of the `pending` messages, a channel at a time: what `add_message` does message
        by message (statistics, the chunk's start/end time and message count, its message indexes), with
        the same result — channels counted and indexed in order of first appearance, as one by one."""
        pending = self.pending
        if not pending:
            return
        self.pending = {}
        stats: Any = self._fast_stats
        counts = stats.channel_message_counts
        chunk: Any = self._fast_chunk
        indices = chunk.message_indices
        total = 0
        lo = hi = None
        for channel_id, flat in pending.items():
            k = len(flat) // 2
            counts[channel_id] += k
            total += k
            times = flat[0::2]
            t_lo, t_hi = min(times), max(times)
            if lo is None or t_lo < lo:
                lo = t_lo
            if hi is None or t_hi > hi:
                hi = t_hi
            index = indices.get(channel_id)
            if index is None:
                index = indices[channel_id] = _MessageIndex(channel_id)
            index.flat += flat
        assert lo is not None and hi is not None
        if stats.message_count == 0 or lo < stats.message_start_time:
            stats.message_start_time = lo
        if hi > stats.message_end_time:
            stats.message_end_time = hi
        stats.message_count += total
        if chunk.num_messages == 0 or lo < chunk.message_start_time:
            chunk.message_start_time = lo
        if hi > chunk.message_end_time:
            chunk.message_end_time = hi
        chunk.num_messages += total

    def add_message(
        self,
        channel_id: int,
        log_time: int,
        data: bytes,
        publish_time: int,
        sequence: int = 0,
    ) -> None:
        if not self.fast:
            super().add_message(channel_id, log_time, data, publish_time, sequence)
            return
        if self.pending:
            self.settle()
        stats: Any = self._fast_stats
        if stats.message_count == 0 or log_time < stats.message_start_time:
            stats.message_start_time = log_time
        if log_time > stats.message_end_time:
            stats.message_end_time = log_time
        stats.channel_message_counts[channel_id] += 1
        stats.message_count += 1

        chunk: Any = self._fast_chunk
        if chunk.num_messages == 0 or log_time < chunk.message_start_time:
            chunk.message_start_time = log_time
        if log_time > chunk.message_end_time:
            chunk.message_end_time = log_time
        buf = chunk.record_writer._buffer  # a new BytesIO after every chunk: fetch it each time
        offset = buf.tell()
        index = chunk.message_indices.get(channel_id)
        if index is None:
            index = chunk.message_indices[channel_id] = _MessageIndex(channel_id)
        index.flat += (log_time, offset)
        chunk.num_messages += 1
        buf.write(
            _MESSAGE_HEAD.pack(
                _MESSAGE_OPCODE, _MESSAGE_FIXED + len(data), channel_id, sequence, log_time, publish_time
            )
        )
        buf.write(data)
        if offset + 9 + _MESSAGE_FIXED + len(data) > self._fast_chunk_size:
            self._fast_finalize()  # type: ignore[misc]

    def _Writer__finalize_chunk(self) -> None:  # (overrides the library's private method)
        """The library's `Writer.__finalize_chunk` (mcap 1.6), line for line, with the writer's own zstd
        compressor (see `__init__`); any other compression, or a release without the state this reads,
        goes to the library's own method. The `pending` messages are settled first."""
        if self.pending:
            self.settle()
        if self._zstd is None:
            Writer._Writer__finalize_chunk(self)  # type: ignore[attr-defined]
            return
        builder: Any = self._fast_chunk
        if not builder or builder.num_messages == 0:
            return
        w: Any = self
        w._Writer__statistics.chunk_count += 1
        chunk_data = builder.end()
        compressed_data: bytes = self._zstd.compress(chunk_data)
        chunk = Chunk(
            compression="zstd",
            data=compressed_data,
            message_start_time=builder.message_start_time,
            message_end_time=builder.message_end_time,
            uncompressed_crc=zlib.crc32(chunk_data) if w._Writer__enable_crcs else 0,
            uncompressed_size=len(chunk_data),
        )
        w._Writer__flush()
        chunk_start_offset = w._Writer__stream.tell()
        record_builder = w._Writer__record_builder
        chunk.write(record_builder)
        chunk_size = record_builder.count
        chunk_index = ChunkIndex(
            message_start_time=chunk.message_start_time,
            message_end_time=chunk.message_end_time,
            chunk_start_offset=chunk_start_offset,
            chunk_length=chunk_size,
            message_index_offsets={},
            message_index_length=0,
            compression=chunk.compression,
            compressed_size=len(compressed_data),
            uncompressed_size=chunk.uncompressed_size,
        )
        w._Writer__flush()
        message_index_start_offset = w._Writer__stream.tell()
        if w._Writer__index_types & IndexType.MESSAGE:
            for id, index in builder.message_indices.items():
                chunk_index.message_index_offsets[id] = message_index_start_offset + record_builder.count
                index.write(record_builder)
        chunk_index.message_index_length = record_builder.count
        w._Writer__flush()
        w._Writer__chunk_indices.append(chunk_index)
        builder.reset()
