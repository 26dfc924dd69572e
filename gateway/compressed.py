"""A recorded log's bytes, decompressed on the fly when it is compressed: sea-trial logs are archived
compressed (NMEA text packs about tenfold), and a text log or a tlog is read front to back, so nothing is
unpacked to disk.

The format is told by the file's first bytes, not its name (a ``trial.log`` that is gzip'd, a ``.gz`` that
is not): gzip (``.gz``), xz (``.xz``), bzip2 (``.bz2``) and Zstandard (``.zst``), the four an archive of
logs is likely to be in. A file cut short (a copy interrupted, a disk that filled) is read up to the cut,
and `Decompressed.cut` says it happened, instead of the decompressor's error stopping the replay with
everything before the cut unread. An MCAP log is read by seeking in it and is never given here
compressed (`gateway.replay.input_kind` says so): MCAP compresses its own chunks.

This module is interpreted on purpose: a class deriving from `io.RawIOBase` cannot be compiled by mypyc
for Python 3.12 and later (its instance dict layout), and it reads megabytes a call, so nothing is lost.
"""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import zlib
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple


class Compression(NamedTuple):
    """A compressed format a log may be archived in, and how a person tests and unpacks one."""

    name: str  # "gzip": as the counts name a cut (``gzip_cut``)
    magic: bytes  # the first bytes of every such file
    test: str  # the command that tests a file's integrity
    unpack: str  # the command that unpacks one, keeping the compressed file


COMPRESSIONS = (
    Compression("gzip", b"\x1f\x8b", "gzip -t", "gunzip -k"),
    Compression("xz", b"\xfd7zXZ\x00", "xz -t", "unxz -k"),
    Compression("bzip2", b"BZh", "bzip2 -t", "bunzip2 -k"),  # (and a block size '1'-'9': checked)
    Compression("zstd", b"\x28\xb5\x2f\xfd", "zstd -t", "unzstd"),
)


def compression_of(path: str | Path) -> Compression | None:
    """The format ``path`` is compressed in, from its first bytes; None for a file that is not."""
    with Path(path).open("rb") as f:
        head = f.read(6)
    for c in COMPRESSIONS:
        if head.startswith(c.magic) and (c.name != "bzip2" or head[3:4] in b"123456789"):
            return c
    return None


class Decompressed(io.RawIOBase):
    """The decompressed bytes of a compressed file, ending where its data ends: at a cut (the stream ends
    before its end marker) or at corrupt data from there on, ``cut`` is set and the stream ends."""

    def __init__(self, path: str | Path, compression: Compression) -> None:
        self.compression = compression
        self.cut = False
        self._file = Path(path).open("rb")  # noqa: SIM115 (closed by close())
        self._zstd: Any = None
        self._stream: Any = None
        # what a decompressor raises at a cut or at corrupt data from there on
        self._cut_errors: tuple[type[Exception], ...] = (EOFError, OSError, zlib.error, lzma.LZMAError)
        if compression.name == "zstd":
            import zstandard

            self._cut_errors += (zstandard.ZstdError,)
            self._new_frame = zstandard.ZstdDecompressor().decompressobj
            self._zstd = self._new_frame()
            self._in_frame = False  # data of a frame given, its end not yet seen
            self._pending = b""
        else:
            opener = {"gzip": gzip.GzipFile, "xz": lzma.LZMAFile, "bzip2": bz2.BZ2File}[compression.name]
            self._stream = opener(fileobj=self._file) if opener is gzip.GzipFile else opener(self._file)

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        if self.cut:
            return 0
        try:
            data = self._read_zstd(len(buffer)) if self._zstd is not None else self._stream.read1(len(buffer))
        except self._cut_errors:
            self.cut = True
            return 0
        buffer[: len(data)] = data
        return len(data)

    def _read_zstd(self, n: int) -> bytes:
        """Up to ``n`` bytes of a Zstandard file of one or more frames. Its decompressor does not raise at
        a cut: a frame whose end was not seen when the file ends is the cut."""
        while not self._pending:
            chunk = self._file.read(1 << 16)
            if not chunk:
                self.cut = self._in_frame
                return b""
            out = [self._zstd.decompress(chunk)]
            self._in_frame = True
            while self._zstd.eof:  # a frame ended: what is left of the chunk starts the next one
                rest = self._zstd.unused_data
                self._zstd = self._new_frame()
                self._in_frame = bool(rest)
                if not rest:
                    break
                out.append(self._zstd.decompress(rest))
            self._pending = b"".join(out)
        data, self._pending = self._pending[:n], self._pending[n:]
        return data

    def close(self) -> None:
        if self._stream is not None:
            self._stream.close()
        self._file.close()
        super().close()


def open_log(path: str | Path) -> io.BufferedReader:
    """A log file's bytes, decompressed on the fly when it is compressed (`compression_of`); a file cut
    short reads up to the cut (`was_cut`)."""
    if (c := compression_of(path)) is not None:
        return io.BufferedReader(Decompressed(path, c))
    return Path(path).open("rb")


def was_cut(f: BinaryIO) -> Compression | None:
    """The compression of `open_log`'s file ``f`` when, read to its end, it ended at a cut rather than at
    its stream's end; else None."""
    raw = getattr(f, "raw", None)
    return raw.compression if isinstance(raw, Decompressed) and raw.cut else None
