"""MAVLink telemetry logs (tlogs), as MAVProxy, Mission Planner and QGroundControl write them: records back to
back, each an 8-byte big-endian unsigned count of microseconds since 1970-01-01 UTC (the time the ground
station received the frame), then that one whole MAVLink 1 or 2 frame. There is no file header and no
length field: a reader finds the frame's length in its own header. (pymavlink's ``mavutil.mavlogfile`` is
the reference reader and writer; MAVProxy keeps a link number in the two low bits of the time, which one
link leaves 0 or ignores.)

`TlogWriter` writes one; the gateway reads them with `gateway.logreaders.tlog_events`.
"""

from __future__ import annotations

import struct
from pathlib import Path
from types import TracebackType
from typing import Self

RECORD_TIME = struct.Struct(">Q")
"""The time that starts every record: µs since 1970-01-01 UTC, big-endian, unsigned 64-bit."""

MAX_TIME_US = 2**64 - 1


def record(time_us: int, frame: bytes | bytearray | memoryview) -> bytes:
    """One tlog record: the time (µs since 1970 UTC) and the frame."""
    if not 0 <= time_us <= MAX_TIME_US:
        raise ValueError(f"a tlog time is 0..2^64-1 µs since 1970, got {time_us}")
    return RECORD_TIME.pack(time_us) + bytes(frame)


class TlogWriter:
    """A tlog written record by record, each write handed to the OS at once (no user-space buffer): a run
    that is killed leaves a tlog whole up to its last record, which a reader follows while it grows.

    The file is created, or emptied if it exists: a tlog's times must not go back, and a second run
    appended to the first would start again at its own beginning. A failed write (disk full) is not
    raised: it is counted (`records_dropped`, `last_error`) and the next record is tried.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 — owned here, closed in close()
        self.records = 0
        self.bytes_written = 0
        self.records_dropped = 0
        self.last_error: str | None = None

    def write(self, time_us: int, frames: list[bytes]) -> None:
        """Records for ``frames`` (whole frames, received together) at one time: one write to the OS."""
        if not frames:
            return
        data = b"".join(record(time_us, f) for f in frames)
        view = memoryview(data)
        try:
            while view:
                n = self._file.write(view)
                if not n:
                    raise OSError("the file took no bytes")
                view = view[n:]
        except OSError as exc:  # a record cut short stays cut: readers resynchronise on the next one
            self.records_dropped += len(frames)
            self.last_error = f"{self.path}: {exc.strerror or exc}"
            return
        self.records += len(frames)
        self.bytes_written += len(data)

    def close(self) -> None:
        self._file.close()

    @property
    def closed(self) -> bool:
        return self._file.closed

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
