"""Runs a study's cases: serially in this process, or on Dask (a local cluster of processes, or a running
one at ``tcp://host:8786``).

Dask rather than a pool of our own: its scheduler already does what a study needs (work stealing, a lost
worker's cases rerun, a dashboard, and the same code on one laptop or a hundred machines). Workers only
compute (`dpgw.study.case.run_case`, a case dict in, rows out); the cache and every file stay with the
client, so a remote cluster needs no shared disk. The rows come back in the grid's order whatever order the
cases finish in, so the table of a Dask run is the serial run's, byte for byte.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from dpgw.study.cache import CaseCache, code_version
from dpgw.study.spec import CaseSpec

CaseFn = Callable[[dict[str, Any]], list[dict[str, Any]]]


class StudyRunError(RuntimeError):
    """The study cannot run (no scheduler at the address, workers with other code, …)."""


class StudyInterrupted(KeyboardInterrupt):
    """The study stopped before its end: Ctrl-C, or a signal that `dpgw study` turns into this (SIGTERM,
    SIGHUP). `run_study` fills in how many cases were done by then (``done`` of ``total``: the cache holds
    them); ``exit_code`` is the shell's for the signal (130, 143, 129)."""

    def __init__(self, why: str = "Ctrl-C", exit_code: int = 130) -> None:
        super().__init__(why)
        self.why = why
        self.exit_code = exit_code
        self.done = 0
        self.total = 0


@dataclass
class StudyResult:
    rows: list[dict[str, Any]]
    cases: int
    computed: int  # cases run now
    cached: int  # cases read from the cache
    seconds: float
    workers: int  # 0: serial
    scheduler: str = ""
    failures: list[str] = field(default_factory=list)


def default_workers() -> int:
    """One worker process per core this process may use (a case is single-threaded numerics)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="case", file=sys.stderr, disable=not enabled, desc="study", leave=False)


# The loggers of Dask's and its web server's this process holds: the client, and for a LocalCluster its
# scheduler and nannies too (they run in this process).
DASK_LOGGERS = ("distributed", "dask", "tornado", "bokeh")


def quiet_dask_logs() -> None:
    """Dask's loggers in this process at ERROR, for good (a study's messages are its own).

    `distributed` configures its loggers when imported, and only where the root logger has no handler yet:
    under `dpgw study` the root has one (`journal.default_logging`), so `distributed` stays at INFO and
    propagates, and its start-up, per-worker and shut-down chatter came out on stderr as ``dpgw study: ...``
    lines. LocalCluster's ``silence_logs`` only lowers the handlers of the ``distributed`` logger itself, of
    which there are none then; it still quiets the worker processes, where the root has no handler."""
    loggers = [logging.getLogger(name) for name in DASK_LOGGERS]
    # and those below them with a level of their own (distributed.client and distributed.gc: WARNING)
    loggers += [
        logger
        for name, logger in list(logging.Logger.manager.loggerDict.items())
        if isinstance(logger, logging.Logger) and name.partition(".")[0] in DASK_LOGGERS and logger.level
    ]
    for logger in loggers:
        if logger.level < logging.ERROR:  # (tornado's CRITICAL stays)
            logger.setLevel(logging.ERROR)


@contextmanager
def dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A client of the cluster at ``scheduler``, or of a LocalCluster of ``workers`` processes (one thread
    each) started and closed here."""
    from distributed import Client, LocalCluster

    quiet_dask_logs()
    if scheduler:
        client = _connect(Client, scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    _resource_tracker_ignoring_sighup()
    cluster = _local_cluster(LocalCluster, workers)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


CONNECT_WAIT_S = 20.0
"""How long a study waits for the cluster at ``--scheduler`` to answer before it says so."""


def _connect(client_class: Any, scheduler: str, wait_s: float = CONNECT_WAIT_S) -> Any:
    """A client of the scheduler at ``scheduler``, or a `StudyRunError` saying why there is none.

    Dask's own ``timeout`` covers a closed port, but not a server of another kind at the address (a web
    server, a port forward to nothing): its handshake then waits for ever. The attempt runs in a thread of
    its own, given up after ``wait_s``; the thread, if still waiting, is a daemon and dies with the process.
    """
    from distributed.comm.addressing import get_address_host_port, parse_address
    from distributed.comm.registry import get_backend

    try:  # the address's form first, as Dask's client reads it (no client, no thread, for a typo)
        get_backend(parse_address(scheduler)[0])
        get_address_host_port(scheduler)
    except ValueError as exc:
        raise StudyRunError(
            f"--scheduler {scheduler}: not an address Dask can dial ({exc}); give it as a `dask "
            "scheduler` prints it, tcp://HOST:8786"
        ) from None
    outcome: dict[str, Any] = {}

    def attempt() -> None:
        try:
            outcome["client"] = client_class(scheduler, timeout=f"{wait_s / 2:g}s")
        except BaseException as exc:  # handed to the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=attempt, name="dpgw-dask-connect", daemon=True)
    thread.start()
    thread.join(wait_s)
    if thread.is_alive():
        raise StudyRunError(
            f"--scheduler {scheduler}: nothing answered as a Dask scheduler within {wait_s:g} s; give the "
            "address a `dask scheduler` prints (tcp://HOST:8786), or leave --scheduler out to run here"
        )
    error = outcome.get("error")
    if isinstance(error, OSError):
        raise StudyRunError(f"--scheduler {scheduler}: no Dask scheduler answers ({error})") from None
    if error is not None:
        raise error
    return outcome["client"]


def _resource_tracker_ignoring_sighup() -> None:
    """multiprocessing's resource tracker (a process of its own, which unlinks the workers' semaphores)
    started now, with SIGHUP ignored, which it keeps: a closed terminal sends SIGHUP to the whole
    foreground group, and the tracker, which ignores only SIGINT and SIGTERM, died of it before the workers
    were stopped, with a traceback for every semaphore it had lost. In another thread than the main one
    (a test's) only the main one may set a handler: the tracker starts when the cluster does, as before."""
    from multiprocessing import resource_tracker

    if threading.current_thread() is not threading.main_thread():
        return
    old = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        resource_tracker.ensure_running()
    finally:
        signal.signal(signal.SIGHUP, old)


def _local_cluster(local_cluster: Any, workers: int) -> Any:
    return local_cluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        # No dashboard, and the scheduler's HTTP server (which it starts in any case, for its health and
        # metrics routes) on a free loopback port: with ``dashboard_address=None`` it took :8787 on every
        # interface and logged "dashboard at: http://...:8787/status"
        dashboard_address="127.0.0.1:0",
        scheduler_kwargs={"dashboard": False},
        silence_logs=logging.ERROR,
        preload=["dpgw.study.worker_setup"],  # the workers ignore Ctrl-C and SIGHUP: the client stops them
    )


def check_workers(client: Any) -> None:
    """Every worker runs the same code as this client (the case hash and the rows depend on it)."""
    mine = code_version()
    theirs = client.run(_worker_code_version)
    wrong = {addr: v for addr, v in theirs.items() if v != mine}
    if wrong:
        addr, v = next(iter(wrong.items()))
        raise StudyRunError(
            f"{len(wrong)} Dask worker(s) run other dpgw code than this client (worker {addr}: {v}, "
            f"here: {mine}); install the same dpgw on every worker (docs/study.md)"
        )


def _worker_code_version() -> str:
    return code_version()


def run_study(
    cases: list[CaseSpec],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    cache: CaseCache | None = None,
    progress: bool = False,
    case_fn: CaseFn | None = None,
) -> StudyResult:
    """Every case's rows in the grid's order. ``workers`` 0: serially in this process; None: one Dask worker
    process per core; ``scheduler``: an existing Dask cluster (``workers`` ignored). ``case_fn`` replaces
    the case (tests and the overhead benchmark)."""
    from dpgw.study.case import run_case

    if workers is not None and workers < 0 and not scheduler:  # (a cluster of no worker waits forever)
        raise ValueError(f"workers: {workers}: give 0 (serial), a number of workers, or None (one per core)")
    fn: CaseFn = case_fn or run_case
    t0 = time.perf_counter()
    version = code_version()
    keys = [c.key(version) for c in cases]
    results: dict[int, list[dict[str, Any]]] = {}
    if cache is not None:
        for i, key in enumerate(keys):
            rows = cache.get(key)
            if rows is not None:
                results[i] = rows
    cached = len(results)
    todo = [i for i in range(len(cases)) if i not in results]
    n_workers = 0 if (workers == 0 and not scheduler) else (workers or default_workers())
    bar = _progress(len(cases), progress)
    bar.update(cached)

    def done(i: int, rows: list[dict[str, Any]]) -> None:
        results[i] = rows
        if cache is not None:
            cache.put(keys[i], cases[i].as_dict(), rows)
        bar.update(1)

    address = ""
    try:
        if n_workers == 0 or not todo:
            for i in todo:
                done(i, fn(cases[i].as_dict()))
        else:
            from distributed import as_completed

            with dask_client(n_workers, scheduler) as client:
                address = str(client.scheduler.address)
                n_workers = len(client.scheduler_info()["workers"])
                check_workers(client)
                # pure: the key names the case and its code; a cluster that holds the result reuses it
                futures = client.map(
                    fn, [cases[i].as_dict() for i in todo], key=[f"dpgw-case-{keys[i]}" for i in todo]
                )
                index = {f.key: i for f, i in zip(futures, todo, strict=True)}
                for future in as_completed(futures):
                    done(index[future.key], future.result())
    except KeyboardInterrupt as exc:
        stop = exc if isinstance(exc, StudyInterrupted) else StudyInterrupted()
        stop.done, stop.total = len(results), len(cases)
        raise stop from None
    finally:
        bar.close()
    rows = [row for i in range(len(cases)) for row in results[i]]
    return StudyResult(rows, len(cases), len(todo), cached, time.perf_counter() - t0, n_workers, address)
