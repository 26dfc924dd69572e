"""A real serial port sink (``serial:///dev/DEVICE?baud=4800``): raw 8N1, no flow control."""

from __future__ import annotations

import contextlib
import errno
import os
import termios

from simulator.transports.base import TransportError
from simulator.transports.fd import FdSink, make_raw


def _baud_constant(baud: int) -> int | None:
    value = getattr(termios, f"B{baud}", None)
    return value if isinstance(value, int) else None


class SerialSink(FdSink):
    """A real serial port (or any tty): raw 8N1 at ``baud``, no flow control, modem lines ignored.

    Writes are non-blocking: when the simulator produces faster than the line's baud rate carries, the
    driver's buffer fills and writes are dropped whole, as on an overloaded NMEA talker.
    """

    def __init__(self, device: str, baud: int = 4800, *, url: str | None = None) -> None:
        self.device = device
        self.baud = baud
        self.url = url or f"serial://{device}?baud={baud}"
        speed = _baud_constant(baud)
        if speed is None:
            rates = [
                b
                for b in (4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
                if _baud_constant(b)
            ]
            raise TransportError(
                self.url, f"unsupported baud rate {baud}", f"use one of {', '.join(map(str, rates))}"
            )
        try:
            fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            fix = {
                errno.ENOENT: "check the device name (ls /dev/serial/by-id/)",
                errno.EACCES: "join the group owning the device (often 'dialout') and log in again",
                errno.EBUSY: "another program has the port open",
            }.get(exc.errno or 0, "")
            raise TransportError(self.url, f"cannot open {device}: {exc.strerror or exc}", fix) from exc
        try:
            if not os.isatty(fd):
                raise TransportError(
                    self.url, f"{device} is not a serial device", "use file://PATH for a file"
                )
            make_raw(fd)
            attrs = termios.tcgetattr(fd)
            attrs[2] &= ~(termios.CSTOPB | termios.CRTSCTS | termios.HUPCL)
            attrs[2] |= termios.CLOCAL | termios.CREAD
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except OSError as exc:
            os.close(fd)
            raise TransportError(self.url, f"cannot configure {device}: {exc.strerror or exc}") from exc
        except BaseException:
            os.close(fd)
            raise
        super().__init__(fd)

    def describe(self) -> str:
        return f"serial://{self.device}?baud={self.baud}"

    def close(self) -> None:
        if self._closed:
            return
        super().close()
        with contextlib.suppress(OSError):
            os.close(self._fd)
