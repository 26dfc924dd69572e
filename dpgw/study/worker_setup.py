"""Loaded by every worker process of the local Dask cluster `dpgw study` starts (Dask's ``preload``).

Ctrl-C and a closed terminal send SIGINT/SIGHUP to every process of the terminal's foreground group, the
workers included: each died with a traceback of its own (four of them in one stopped study) while the
`dpgw study` process was stopping them anyway. The workers ignore both: their life is the client's, which
closes the cluster on Ctrl-C, SIGTERM and SIGHUP (docs/study.md, "Stopping a study").

For the same reason a worker keeps quiet about a heartbeat that found the scheduler gone: in the local
cluster the scheduler lives in the client's process and goes only when the client closes it, so that
failure is the stop itself. It printed an ERROR and a traceback amid the stop's one line when a worker's
heartbeat fell between the scheduler closing and the worker being told to.
"""

from __future__ import annotations

import logging
import signal
import threading
from typing import Any

HEARTBEAT_LOST = "Failed to communicate with scheduler during heartbeat"
"""The start of `distributed.worker`'s message for a heartbeat that could not reach the scheduler (an
OSError: the worker carries on and tries again; it is closed moments later at a study's stop)."""


def not_a_lost_heartbeat(record: logging.LogRecord) -> bool:
    """A logging filter: False for the worker's lost-heartbeat message, True for every other record."""
    return not str(record.msg).startswith(HEARTBEAT_LOST)


def dask_setup(worker: Any) -> None:
    # a worker process runs its Worker on its main thread, the only one that may set a handler
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    worker_logger = logging.getLogger("distributed.worker")
    if not_a_lost_heartbeat not in worker_logger.filters:
        worker_logger.addFilter(not_a_lost_heartbeat)
