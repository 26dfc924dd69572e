"""Reading dpgw's MCAP logs back: messages, and what a log holds; complete files or cut ones.

A file cut by `kill -9` or power loss (no summary, no footer) is read up to its last complete record,
which holds everything the writer had handed to the OS (`wire.mcap.writer`). A rotated set is read in
order with `read_messages(log_files(path))` (`wire.mcap.rotation`).
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import struct
from collections.abc import Iterable, Iterator
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, DataEnd, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.well_known import MessageEncoding, SchemaEncoding

from wire.mcap.format import MAGIC, OPCODE_DATA_END, OPCODE_FOOTER, OPCODE_METADATA, RECORD_HEADER
from wire.mcap.rotation import StrPath, log_files

__all__ = [
    "ChannelSummary",
    "LogSummary",
    "is_complete",
    "log_files",
    "read_messages",
    "read_metadata",
    "summary",
]


def _whole_records(f: IO[bytes]) -> tuple[int, bool]:
    """(end offset of the whole records of `f`, whether the file is complete: footer and closing magic).

    Walks record headers (opcode u8, length u64) with seeks, without reading record bodies. A file cut by
    `kill -9` or power loss ends in a partial record (or none); everything before it is intact. For a
    complete file the offset includes the closing magic.
    """
    f.seek(0, io.SEEK_END)
    size = f.tell()
    f.seek(0)
    magic = f.read(len(MAGIC))
    if magic != MAGIC[: len(magic)] or not magic:
        if size == 0:
            return 0, False  # created but nothing saved yet
        raise ValueError("not an MCAP file (bad magic)")
    pos = len(magic)
    while pos + RECORD_HEADER <= size:
        opcode, length = struct.unpack("<BQ", f.read(RECORD_HEADER))
        end = pos + RECORD_HEADER + length
        if end > size:
            break
        pos = end
        f.seek(pos)
        if opcode == OPCODE_FOOTER:
            if f.read(len(MAGIC)) == MAGIC:
                return pos + len(MAGIC), True
            break
    return pos, False


def is_complete(path: StrPath) -> bool:
    """Whether a file ends in MCAP's footer and closing magic (False for one cut by `kill -9` or power
    loss, or still being written). Walks the record headers with seeks: cheap on any size."""
    with open(path, "rb") as f:
        return _whole_records(f)[1]


class _Slice(io.RawIOBase):
    """Read-only view of the bytes [start, stop) of a file."""

    def __init__(self, f: IO[bytes], start: int, stop: int) -> None:
        self._f = f
        self._left = max(stop - start, 0)
        f.seek(start)

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        n = min(len(view), self._left)
        if n <= 0:
            return 0
        data = self._f.read(n)
        view[: len(data)] = data
        self._left -= len(data)
        return len(data)


def _iter_records(path: StrPath) -> Iterator[Schema | Channel | Message]:
    """Schema, Channel and Message records of a complete or truncated MCAP file, in file order."""
    with open(path, "rb") as f:
        stop, complete = _whole_records(f)
        if stop <= len(MAGIC):
            return
        # mcap's non-seeking StreamReader over the whole records only (leading magic skipped here). On a
        # complete file it stops at the footer; on a truncated one its next read hits the end of the slice
        # exactly at a record boundary and raises EndOfFile, which then means "end of what was saved".
        reader = StreamReader(io.BufferedReader(_Slice(f, len(MAGIC), stop)), skip_magic=True)
        try:
            for record in reader.records:
                if isinstance(record, DataEnd):
                    return  # the summary section after it repeats schemas and channels, never messages
                if isinstance(record, Schema | Channel | Message):
                    yield record
        except EndOfFile:
            if complete:
                raise


def read_metadata(path: StrPath) -> list[tuple[str, dict[str, str]]]:
    """The Metadata records (name, key/value map) of one file, in file order, complete or truncated.

    A complete file lists them in its summary's metadata index; a file cut by `kill -9` or power loss has
    no index, but the records themselves are in its data section (the writer puts the configuration
    right after the header, `wire.mcap.writer`), so they are found by walking the record headers with
    seeks, reading only the bodies of Metadata records (chunks are skipped, not decompressed).
    """
    with open(path, "rb") as f:
        stop, complete = _whole_records(f)
        if complete:
            f.seek(0)
            reader = make_reader(f)
            return [(r.name, dict(r.metadata)) for r in reader.iter_metadata()]
        found: list[tuple[str, dict[str, str]]] = []
        pos = len(MAGIC)
        f.seek(pos)
        while pos + RECORD_HEADER <= stop:
            opcode, length = struct.unpack("<BQ", f.read(RECORD_HEADER))
            if opcode == OPCODE_DATA_END:
                break
            if opcode == OPCODE_METADATA:
                record = Metadata.read(ReadDataStream(io.BytesIO(f.read(length))))
                found.append((record.name, dict(record.metadata)))
            pos += RECORD_HEADER + length
            f.seek(pos)
        return found


def _topic_set(topics: str | Iterable[str] | None) -> set[str] | None:
    if topics is None:
        return None
    return {topics} if isinstance(topics, str) else set(topics)


def _paths(path: StrPath | Iterable[StrPath]) -> list[StrPath]:
    if isinstance(path, str | os.PathLike):
        return [path]
    return list(path)


def read_messages(
    path: StrPath | Iterable[StrPath], topics: str | Iterable[str] | None = None
) -> Iterator[tuple[str, int, int, dict[str, Any]]]:
    """Yield (topic, log_time_ns, publish_time_ns, payload) in file order from one file or several (e.g.
    `log_files(path)`), complete or truncated (everything before the cut). Only `json` channels are read;
    `null` comes back as None (it was NaN/inf or null when written)."""
    wanted = _topic_set(topics)
    for p in _paths(path):
        channels: dict[int, Channel] = {}
        for record in _iter_records(p):
            if isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or channel.message_encoding != MessageEncoding.JSON:
                    continue
                if wanted is not None and channel.topic not in wanted:
                    continue
                yield channel.topic, record.log_time, record.publish_time, json.loads(record.data)


@dataclasses.dataclass
class ChannelSummary:
    topic: str
    schema_name: str
    schema_encoding: str
    message_encoding: str
    message_count: int


@dataclasses.dataclass
class LogSummary:
    """What a log holds. `complete` is False for a file without footer (e.g. killed writer)."""

    complete: bool
    message_count: int
    start_ns: int | None
    end_ns: int | None
    channels: dict[str, ChannelSummary]
    schemas: dict[str, dict[str, Any]]  # schema name -> JSON Schema (jsonschema-encoded schemas only)
    chunk_count: int | None  # None when not known (truncated file)


def summary(path: StrPath) -> LogSummary:
    """Channels, schemas and message counts of one file: from its summary section if it is complete, else by
    scanning what was saved."""
    with open(path, "rb") as f:
        _, complete = _whole_records(f)
        if complete:
            f.seek(0)
            s = make_reader(f).get_summary()
            if s is not None and s.statistics is not None:
                stats = s.statistics
                channels = {}
                for cid, ch in s.channels.items():
                    sch = s.schemas.get(ch.schema_id)
                    channels[ch.topic] = ChannelSummary(
                        ch.topic,
                        sch.name if sch else "",
                        sch.encoding if sch else "",
                        ch.message_encoding,
                        stats.channel_message_counts.get(cid, 0),
                    )
                has_messages = stats.message_count > 0
                return LogSummary(
                    complete=True,
                    message_count=stats.message_count,
                    start_ns=stats.message_start_time if has_messages else None,
                    end_ns=stats.message_end_time if has_messages else None,
                    channels=channels,
                    schemas=_decode_schemas(s.schemas.values()),
                    chunk_count=stats.chunk_count,
                )
    # Truncated (or written without statistics): count by scanning.
    schemas: dict[int, Schema] = {}
    by_id: dict[int, ChannelSummary] = {}
    count, start, end = 0, None, None
    for record in _iter_records(path):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            sch = schemas.get(record.schema_id)
            by_id[record.id] = ChannelSummary(
                record.topic, sch.name if sch else "", sch.encoding if sch else "", record.message_encoding, 0
            )
        elif record.channel_id in by_id:
            by_id[record.channel_id].message_count += 1
            count += 1
            start = record.log_time if start is None else min(start, record.log_time)
            end = record.log_time if end is None else max(end, record.log_time)
    return LogSummary(
        complete=complete,
        message_count=count,
        start_ns=start,
        end_ns=end,
        channels={c.topic: c for c in by_id.values()},
        schemas=_decode_schemas(schemas.values()),
        chunk_count=None,
    )


def _decode_schemas(schemas: Iterable[Schema]) -> dict[str, dict[str, Any]]:
    return {s.name: json.loads(s.data) for s in schemas if s.encoding == SchemaEncoding.JSONSchema}
