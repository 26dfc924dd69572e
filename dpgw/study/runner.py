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
import sys
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


@contextmanager
def dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A client of the cluster at ``scheduler``, or of a LocalCluster of ``workers`` processes (one thread
    each) started and closed here."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise StudyRunError(f"--scheduler {scheduler}: no Dask scheduler answers ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


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
    finally:
        bar.close()
    rows = [row for i in range(len(cases)) for row in results[i]]
    return StudyResult(rows, len(cases), len(todo), cached, time.perf_counter() - t0, n_workers, address)
