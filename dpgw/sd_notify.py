"""systemd's service notification (sd_notify(3)), spoken directly: readiness, watchdog, status, stopping.

The shipped unit is ``Type=notify`` with ``WatchdogSec=``: systemd then knows when the gateway is up (its
kernels compiled, its sources, Zenoh and log open: ``systemctl start`` waits for it and ``systemctl
status`` shows the gateway's own status line), and restarts a gateway whose consumer loop has stopped
turning (a deadlock, an output blocked for good) — which a process that is alive but hung never got from
``Restart=``: its outputs had stopped, its alarms with them, and nothing said so. The watchdog is fed from
the consumer loop itself (`GatewayService.heartbeat`), never from a thread of its own, which would go on
feeding it while the loop is stuck.

The protocol is one datagram per message to the unix socket in ``NOTIFY_SOCKET`` (``@`` = the abstract
namespace); ``WATCHDOG_USEC`` (for this process: ``WATCHDOG_PID``, when set, is its pid) is the period.
Without ``NOTIFY_SOCKET`` (a terminal, any other supervisor) nothing is sent. A send that fails is
ignored: notification must never stop the gateway.
"""

from __future__ import annotations

import contextlib
import os
import socket
import time
from collections.abc import Callable, Mapping

STATUS_EVERY_S = 5.0
"""The ``STATUS=`` line (``systemctl status``) at most this often."""


class Notifier:
    def __init__(self, env: Mapping[str, str] | None = None) -> None:
        env = os.environ if env is None else env
        address = env.get("NOTIFY_SOCKET", "")
        self._address = "\0" + address[1:] if address.startswith("@") else address
        self._sock: socket.socket | None = None
        if self._address:
            try:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
            except OSError:
                self._sock = None
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        mine = not pid or pid == str(os.getpid())
        self.watchdog_ns = int(usec) * 1000 if usec.isdigit() and mine else 0
        """systemd's watchdog period (ns); 0: no watchdog."""
        self._last_ping = 0
        self._last_status = 0

    @property
    def enabled(self) -> bool:
        return self._sock is not None

    def send(self, text: str) -> None:
        if self._sock is None:
            return
        with contextlib.suppress(OSError):
            self._sock.sendto(text.encode("utf-8", "replace"), self._address)

    def ready(self, status: str) -> None:
        """Start-up done: sources, Zenoh and log open."""
        self.send(f"READY=1\nSTATUS={status}")

    def heartbeat(self, status: Callable[[], str] | None = None) -> None:
        """From the consumer loop, every turn: ``WATCHDOG=1`` twice per watchdog period, and the line
        ``status()`` gives (when given) every `STATUS_EVERY_S`. Cheap when nothing is due."""
        if self._sock is None:
            return
        now = time.monotonic_ns()
        parts = []
        if self.watchdog_ns and now - self._last_ping >= self.watchdog_ns // 2:
            self._last_ping = now
            parts.append("WATCHDOG=1")
        if status is not None and now - self._last_status >= STATUS_EVERY_S * 1e9:
            self._last_status = now
            parts.append(f"STATUS={status()}")
        if parts:
            self.send("\n".join(parts))

    def stopping(self) -> None:
        self.send("STOPPING=1\nSTATUS=stopping: closing the log")

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
