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
"""

from __future__ import annotations

import struct
from itertools import chain
from typing import Any

from mcap.records import MessageIndex
from mcap.writer import Writer

_MESSAGE_OPCODE = 0x05
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, length, channel id, sequence, log time, publish time
_MESSAGE_FIXED = 22  # record length excluding the data: 2 + 4 + 8 + 8
_MESSAGE_INDEX_OPCODE = 0x07
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, length, channel id, byte length of the records


class _MessageIndex(MessageIndex):
    """`MessageIndex` whose `write` packs its (log time, offset) pairs in one call (the library writes
    each u64 separately: ~two calls per message at every chunk close). Same bytes."""

    def write(self, stream: Any) -> None:
        records = self.records
        stream.write(
            _INDEX_HEAD.pack(_MESSAGE_INDEX_OPCODE, 6 + 16 * len(records), self.channel_id, 16 * len(records))
        )
        stream.write(struct.pack(f"<{2 * len(records)}Q", *chain.from_iterable(records)))


class FastWriter(Writer):
    """`mcap.writer.Writer` with `add_message` in one pack (see module docstring)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._fast_stats = getattr(self, "_Writer__statistics", None)
        self._fast_chunk = getattr(self, "_Writer__chunk_builder", None)
        self._fast_chunk_size = getattr(self, "_Writer__chunk_size", None)
        self._fast_finalize = getattr(self, "_Writer__finalize_chunk", None)
        builder = self._fast_chunk
        self.fast = (
            self._fast_stats is not None
            and builder is not None
            and self._fast_chunk_size is not None
            and self._fast_finalize is not None
            and hasattr(getattr(builder, "record_writer", None), "_buffer")
            and all(hasattr(builder, a) for a in ("message_indices", "num_messages", "message_start_time"))
        )

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
            index = chunk.message_indices[channel_id] = _MessageIndex(channel_id=channel_id, records=[])
        index.records.append((log_time, offset))
        chunk.num_messages += 1
        buf.write(
            _MESSAGE_HEAD.pack(
                _MESSAGE_OPCODE, _MESSAGE_FIXED + len(data), channel_id, sequence, log_time, publish_time
            )
        )
        buf.write(data)
        if offset + 9 + _MESSAGE_FIXED + len(data) > self._fast_chunk_size:
            self._fast_finalize()  # type: ignore[misc]
