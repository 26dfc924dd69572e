"""Serial ports and ptys (``serial://``, ``pty://``, pymavlink device strings), read with pyserial.

A pty is opened exactly like a serial port (the simulator's sensors are ptys), so there is one class.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import stat
from typing import Any

from gateway.sources.base import Backoff, Source, SourceError

log = logging.getLogger(__name__)

#: NMEA 0183 / IEC 61162-1 default, used for ``serial://`` URLs without ``baud``.
NMEA_DEFAULT_BAUD = 4800
#: Longest one pyserial read blocks, so `Source.stop` is prompt.
_SERIAL_POLL_S = 0.1
#: How often a port that is not there is looked for (a `stat`, no open attempt): a pty made again by a
#: restarted simulator, or a USB adapter plugged back in, is read within this of appearing, however long
#: it was away. The back-off is for a port that is there and still fails to open.
ABSENT_POLL_S = 0.2


class SerialSource(Source):
    """A serial port or a pty, via pyserial; raw bytes, no flow control, exclusive (``flock``).

    The device must exist at `start` (else `SourceError`), unless ``wait_if_absent`` (``dpgw run
    --wait-for-ports``, the service): then a device that does not exist yet is waited for as an unplugged
    one is (below), said once as a warning, and the other sources run meanwhile. Any other problem (no
    permission, not a serial device, in use) still raises: waiting would not mend it. When it fails while
    running (a USB adapter unplugged, the simulator's pty closed), the error is counted,
    ``stats.connected`` goes False and the port is reopened with back-off (0.5 s doubling to 10 s) until
    it is back, except that a port not there at all is looked for every `ABSENT_POLL_S` and opened as it
    appears (a restarted simulator's pty is read at once, not up to 10 s later); ``stats.reconnects``
    counts the reopenings, ``stats.last_disconnect`` says when and why it last failed. A pty has no baud
    rate: the setting is accepted and ignored.
    """

    kind = "serial"

    def __init__(
        self,
        name: str,
        url: str,
        device: str,
        baud: int = NMEA_DEFAULT_BAUD,
        *,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        timeout_s: float = 2.0,
    ) -> None:
        super().__init__(name, url, timeout_s=timeout_s)
        self.device = device
        self.baud = baud
        self.bytesize = bytesize
        self.parity = parity
        self.stopbits = stopbits
        self._ser: Any = None  # serial.Serial while open
        self.wait_if_absent = False
        """A device absent at `start` is waited for, not a `SourceError` (``--wait-for-ports``)."""
        self._absent_at_start = False

    def missing(self) -> SourceError | None:
        """The error of a device that does not exist (nothing opened: a look at the path), else None. The
        service looks before it compiles its kernels, so a mistyped port stops start-up at once."""
        if os.path.exists(self.device):
            return None
        return SourceError(
            self.name,
            self.url,
            f"serial port {self.device} does not exist",
            "check the cable/udev name (ls /dev/serial/by-id/; for the simulator: the pty it printed)",
            missing_port=True,
        )

    def _open_port(self) -> Any:
        try:
            import serial  # pyserial is needed only by serial sources
        except ImportError as exc:
            raise SourceError(
                self.name, self.url, "pyserial is not installed", "pip install pyserial"
            ) from exc
        missing = self.missing()
        if missing is not None:
            raise missing
        with contextlib.suppress(OSError):
            mode = os.stat(self.device).st_mode
            if stat.S_ISDIR(mode):  # (a folder cannot be read as a file either: no file:// hint)
                raise SourceError(
                    self.name,
                    self.url,
                    f"{self.device} is a folder, not a serial device",
                    "give the device itself (ls /dev/serial/by-id/; for the simulator: the pty it printed)",
                )
            if not stat.S_ISCHR(mode):
                raise SourceError(
                    self.name,
                    self.url,
                    f"{self.device} is not a serial device",
                    f"for a file write file://{os.path.abspath(self.device)}",
                )
        ser = serial.Serial()
        ser.port = self.device
        ser.baudrate = self.baud
        ser.bytesize = self.bytesize
        ser.parity = self.parity
        ser.stopbits = self.stopbits
        ser.timeout = _SERIAL_POLL_S
        ser.write_timeout = self.timeout_s
        ser.exclusive = True
        try:
            ser.open()
        except (serial.SerialException, OSError, ValueError) as exc:
            code = getattr(exc, "errno", None)
            text = str(exc)
            if code == errno.EAGAIN or "exclusively lock" in text:
                problem, fix = f"serial port {self.device} is in use", "another program has it open: stop it"
            elif code == errno.EACCES:
                problem = f"no permission to open serial port {self.device}"
                fix = "join the group owning the device (often 'dialout') and log in again"
            elif code == errno.ENOENT:  # (gone between the look and the open)
                raise self.missing() or SourceError(
                    self.name, self.url, f"serial port {self.device} does not exist", missing_port=True
                ) from exc
            elif code == errno.EBUSY:
                problem, fix = f"serial port {self.device} is busy", "another program has it open: stop it"
            elif code == errno.ENOTTY or "Inappropriate ioctl" in text:  # /dev/null, a sound card, ...
                problem = f"{self.device} is not a serial port (a device, but not a terminal)"
                fix = "give the serial device (ls /dev/serial/by-id/; for the simulator: the pty it printed)"
            else:
                problem, fix = (
                    f"cannot open serial port {self.device}: {text}",
                    "check the device and settings",
                )
            raise SourceError(self.name, self.url, problem, fix) from exc
        return ser

    def _open(self) -> None:
        try:
            self._ser = self._open_port()
        except SourceError as exc:
            if not self.wait_if_absent or os.path.exists(self.device):
                raise
            # not there yet (a USB adapter not enumerated at boot, unplugged, a simulator not started):
            # the reader thread opens it when it appears, as after an unplug
            self._absent_at_start = True
            self._error(
                "disconnected",
                f"{exc.problem}; waiting for it, the gateway runs without it meanwhile — {exc.fix}",
            )
            return
        self.stats.connected = True

    def _run(self) -> None:
        import serial

        backoff = Backoff()
        absent = False  # the last look found no device at the path: look again soon, not backed off
        while not self._stop.is_set():
            ser = self._ser
            if ser is None:
                if self._sleep(ABSENT_POLL_S if absent else backoff.next()):
                    return
                if not os.path.exists(self.device):
                    if not absent:  # (counted once per absence, not per look)
                        problem = f"serial port {self.device} does not exist; reopening"
                        self._error("reopen failed", problem, logging.DEBUG)
                    absent = True
                    continue
                absent = False
                try:
                    ser = self._open_port()
                except SourceError as exc:  # (the problem alone: the alarm already names the source)
                    self._error("reopen failed", f"{exc.problem}; reopening", logging.DEBUG)
                    continue
                with self._io_lock:
                    self._ser = ser
                self.stats.connected = True
                backoff.reset()
                if self._absent_at_start:  # (its absence was a warning: so is its coming)
                    self._absent_at_start = False
                    log.warning("source %r: serial port %s is there now: reading", self.name, self.device)
                else:
                    self.stats.reconnects += 1
                    log.info("source %r: serial port %s open again", self.name, self.device)
            data = b""
            try:
                data = ser.read(1)
                if data:
                    waiting = ser.in_waiting
                    if waiting:
                        data += ser.read(waiting)
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                if self._stop.is_set():
                    return
                if data:
                    self._emit(data)
                self.stats.note_disconnect(f"serial port {self.device} failed: {exc}")
                self._error(
                    "disconnected", f"serial port {self.device} failed: {exc}; reopening", always=True
                )
                self.stats.connected = False
                with self._io_lock:
                    self._ser = None
                    with contextlib.suppress(Exception):
                        ser.close()
                continue
            if data:
                self._emit(data)

    def write(self, data: bytes, peer: str | None = None) -> bool:
        import serial

        with self._io_lock:
            ser = self._ser
            if ser is None or self._stop.is_set():
                return False
            try:
                n = ser.write(data) or 0
            except serial.SerialTimeoutException:
                self._error("write timeout", f"write to {self.device} timed out after {self.timeout_s} s")
                return False
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                self._error("write failed", f"write to {self.device} failed: {exc}")
                return False
        self.stats.add_sent(n)
        return n == len(data)

    def _interrupt(self) -> None:
        ser = self._ser
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.cancel_read()

    def _close(self) -> None:
        with self._io_lock:
            ser, self._ser = self._ser, None
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.close()
        self.stats.connected = False
