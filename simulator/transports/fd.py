"""What the pty and serial sinks share: raw tty mode and a non-blocking descriptor written whole or
dropped whole."""

from __future__ import annotations

import errno
import os
import termios

from simulator.transports.base import MAX_READS_PER_PEER, READ_CHUNK, Sink


def make_raw(fd: int) -> None:
    """cfmakeraw(3): bytes pass unchanged — no echo, no CR/LF translation, no signals, no flow control."""
    attrs = termios.tcgetattr(fd)
    iflag, oflag, cflag, lflag = attrs[0], attrs[1], attrs[2], attrs[3]
    iflag &= ~(
        termios.IGNBRK
        | termios.BRKINT
        | termios.PARMRK
        | termios.ISTRIP
        | termios.INLCR
        | termios.IGNCR
        | termios.ICRNL
        | termios.IXON
        | termios.IXOFF
        | termios.INPCK
    )
    oflag &= ~termios.OPOST
    lflag &= ~(termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN)
    cflag &= ~(termios.CSIZE | termios.PARENB)
    cflag |= termios.CS8
    attrs[0], attrs[1], attrs[2], attrs[3] = iflag, oflag, cflag, lflag
    cc = attrs[6]
    cc[termios.VMIN] = 1
    cc[termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


class FdSink(Sink):
    """A non-blocking file descriptor (pty master, serial port) written whole-or-dropped.

    A write the kernel takes only in part keeps its tail in ``_pending``, sent before anything else; while
    a tail is pending, new writes are dropped whole. So the stream is never cut inside a write, and at
    most one write's worth of bytes waits in user space.
    """

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd
        self._pending = bytearray()

    @property
    def bytes_pending(self) -> int:
        return len(self._pending)

    def _flush_pending(self) -> bool:
        """Send the pending tail; True when nothing is pending any more."""
        while self._pending:
            try:
                n = os.write(self._fd, self._pending)
            except BlockingIOError:
                return False
            except OSError as exc:
                # the tail of a write cannot follow: give it up (its head is already out)
                self.bytes_dropped += len(self._pending)
                self.last_error = f"{self.describe()}: {exc.strerror or exc}"
                self._pending.clear()
                return True
            if n <= 0:
                return False
            self.bytes_written += n
            del self._pending[:n]
        return True

    def _before_write(self) -> None:
        """Hook run before each write (the pty discards stale input here)."""

    def write(self, data: bytes) -> None:
        self._check_open()
        if not data:
            return
        self._before_write()
        if not self._flush_pending():
            self._drop(len(data), f"{self.describe()}: buffer full (the reader is slow or absent)")
            return
        try:
            n = os.write(self._fd, data)
        except BlockingIOError:
            self._drop(len(data), f"{self.describe()}: buffer full (the reader is slow or absent)")
            return
        except OSError as exc:
            self._drop(len(data), f"{self.describe()}: {exc.strerror or exc}")
            return
        self.bytes_written += n
        if n < len(data):
            self._pending += data[n:]

    def poll(self) -> None:
        if not self._closed:
            self._flush_pending()

    def read_from_peers(self) -> list[tuple[str, bytes]]:
        self._check_open()
        chunks: list[bytes] = []
        for _ in range(MAX_READS_PER_PEER):
            try:
                chunk = os.read(self._fd, READ_CHUNK)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:  # EIO: no one at the other end
                if exc.errno != errno.EIO:
                    self.last_error = f"{self.describe()}: read: {exc.strerror or exc}"
                break
            if not chunk:
                break
            chunks.append(chunk)
        return [(self.describe(), b"".join(chunks))] if chunks else []
