"""A file sink (``file:///PATH`` or a plain path): appended, handed to the OS on every write."""

from __future__ import annotations

import errno
import os

from simulator.transports.base import Sink, TransportError


class FileSink(Sink):
    """Bytes appended to a file, handed to the OS on every write (no user-space buffering).

    A failed write (disk full) is dropped and counted. A path that is a FIFO or a device is opened as a
    file: writes may then block while the reader does not read — use ``pty`` or ``serial://`` instead.
    """

    def __init__(self, path: str, *, url: str | None = None) -> None:
        super().__init__()
        self.path = os.path.abspath(path)
        self.url = url or path
        try:
            self._file = open(self.path, "ab", buffering=0)  # noqa: SIM115 — owned by the sink, closed in close()
        except OSError as exc:
            fix = {
                errno.ENOENT: f"create the directory {os.path.dirname(self.path)} or choose another path",
                errno.EACCES: "choose a path you may write to",
                errno.EISDIR: "give a file name, not a directory",
                errno.EROFS: "choose a path on a writable file system",
            }.get(exc.errno or 0, "choose another path")
            raise TransportError(
                self.url, f"cannot open {self.path} for writing: {exc.strerror or exc}", fix
            ) from exc

    def write(self, data: bytes) -> None:
        self._check_open()
        view = memoryview(data)
        while view:
            try:
                n = self._file.write(view)
            except OSError as exc:
                self._drop(len(view), f"{self.describe()}: {exc.strerror or exc}")
                return
            if not n:  # a non-blocking device or FIFO that is full
                self._drop(len(view), f"{self.describe()}: would block")
                return
            self.bytes_written += n
            view = view[n:]

    def describe(self) -> str:
        return f"file://{self.path}"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        self._file.close()
