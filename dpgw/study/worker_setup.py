"""Loaded by every worker process of the local Dask cluster `dpgw study` starts (Dask's ``preload``).

Ctrl-C and a closed terminal send SIGINT/SIGHUP to every process of the terminal's foreground group, the
workers included: each died with a traceback of its own (four of them in one stopped study) while the
`dpgw study` process was stopping them anyway. The workers ignore both: their life is the client's, which
closes the cluster on Ctrl-C, SIGTERM and SIGHUP (docs/study.md, "Stopping a study").
"""

from __future__ import annotations

import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:
    # a worker process runs its Worker on its main thread, the only one that may set a handler
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
