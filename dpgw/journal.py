"""The gateway's log lines with their priority when systemd's journal reads them (the service).

Under systemd a service's stderr goes to the journal, one entry per line, every line at the unit's
default priority (info) unless it starts with a kernel-style ``<N>`` prefix (``SyslogLevelPrefix=``, on by
default), which journald takes as the line's priority and strips. Without it, ``journalctl -u dpgw -p
warning`` — the faults of weeks in service: a source lost and back, the log's disk full, Zenoh gone —
showed nothing, and an engineer had to grep. systemd says where the journal is: ``JOURNAL_STREAM`` holds
the device and inode of the stream it connected, and a process whose stderr is that stream writes to
the journal (sd_journal_stream_fd(3)); under a terminal, a pipe or a file stderr is another file, and
lines stay as they were.

A person's mistake that stops start-up (a config that does not parse, a serial port that is not there, a
Zenoh endpoint that cannot be opened, a log folder the service may not write) is said by `start_up_error`
at error priority: printed plain, such a line went into the journal at info, and ``journalctl -u dpgw -p
err`` of a service that restarted every 5 s until systemd gave up on it showed nothing.
"""

from __future__ import annotations

import logging
import os
import sys

# syslog priorities (RFC 5424) by logging level
PRIORITY = {
    logging.CRITICAL: 2,
    logging.ERROR: 3,
    logging.WARNING: 4,
    logging.INFO: 6,
    logging.DEBUG: 7,
}


def stderr_is_journal(env: dict[str, str] | None = None) -> bool:
    """stderr is the stream systemd connected to its journal (``JOURNAL_STREAM`` = ``device:inode``)."""
    stream = (os.environ if env is None else env).get("JOURNAL_STREAM", "")
    try:
        st = os.fstat(sys.stderr.fileno())
    except (OSError, ValueError, AttributeError):  # (stderr closed or replaced)
        return False
    return stream == f"{st.st_dev}:{st.st_ino}"


def with_priority(text: str, priority: int) -> str:
    """``<N>`` before each line of ``text``: journald takes each line as an entry of its own."""
    return "\n".join(f"<{priority}>{line}" for line in text.split("\n"))


def start_up_error(text: str) -> None:
    """A mistake that stops start-up, on stderr as it is (one message naming what and where), at error
    priority when stderr is the journal."""
    error = PRIORITY[logging.ERROR]
    print(with_priority(text, error) if stderr_is_journal() else text, file=sys.stderr, flush=True)


class JournalFormatter(logging.Formatter):
    """``<N>message``: the record's syslog priority first, for journald, on each of its lines. journald
    takes every line of the stream as an entry of its own, with the default priority unless it has the
    prefix: a traceback (``log.exception``: an internal error) would otherwise be left out of ``journalctl
    -p err`` but for its first line."""

    def format(self, record: logging.LogRecord) -> str:
        level = max((lv for lv in PRIORITY if lv <= record.levelno), default=logging.DEBUG)
        return with_priority(super().format(record), PRIORITY[level])


SDK_LOGGER = "foxglove"
"""The Foxglove SDK's logger: its Rust code logs through Python's `logging` under its module paths
(``foxglove.websocket.server``: "Started server on …", "Registered client …", "Shutting down"; checked
with foxglove-sdk 0.30)."""


class SdkPrefix(logging.Filter):
    """``foxglove: started server on …``: the SDK's lines named like dpgw's own (``zenoh: …``, ``source
    gps: …``), so that a line in the journal says what said it. Prefixed once, whatever the handlers."""

    def filter(self, record: logging.LogRecord) -> bool:
        named = record.name == SDK_LOGGER or record.name.startswith(SDK_LOGGER + ".")
        if named and not getattr(record, "dpgw_prefixed", False):
            text = record.getMessage()
            if text[:1].isupper() and text[1:2].islower():  # ("Started server", not "TLS")
                text = text[0].lower() + text[1:]
            record.msg, record.args = f"{SDK_LOGGER}: {text}", ()
            record.dpgw_prefixed = True
        return True


def configure_logging(level: int) -> None:
    """`logging.basicConfig` at ``level``, message alone; with each line's priority for the journal (in
    place of `default_logging`'s handler). The Foxglove SDK's lines at WARNING and above, prefixed
    (`SdkPrefix`); with ``level`` INFO (``-v``) its INFO too (a client registered, gone), never its DEBUG.
    The level is set before the SDK's first line: it reads it once per logger (``FOXGLOVE_LOG_LEVEL``, if
    set, is the SDK's own override)."""
    handler = logging.StreamHandler()
    handler.setFormatter(JournalFormatter("%(message)s") if stderr_is_journal() else logging.Formatter())
    handler.addFilter(SdkPrefix())
    root = logging.getLogger()
    for h in [h for h in root.handlers if getattr(h, "dpgw_default", False)]:
        root.removeHandler(h)
    logging.basicConfig(level=level, handlers=[handler])
    logging.getLogger(SDK_LOGGER).setLevel(max(level, logging.INFO))


def default_logging(command: str) -> None:
    """Warnings of a command that sets no logging of its own on stderr as ``dpgw COMMAND: message``, like
    its own lines: without a handler Python printed them bare (``heading reference gyro1: stale -> ok``
    amid ``dpgw demo: ...`` lines, with nothing saying which program said it). Nothing changes where the
    root logger has a handler already (a test's, a notebook's)."""
    root = logging.getLogger()
    if root.handlers:
        return
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter(f"dpgw {command}: %(message)s"))
    handler.dpgw_default = True  # type: ignore[attr-defined]  # (`configure_logging` replaces it)
    handler.addFilter(SdkPrefix())
    root.addHandler(handler)
