"""The ``alone`` marker: a test that no other test may run beside (pytest plugin hook; tests/conftest.py
imports it).

The suite runs on every core through pytest-xdist (``-n auto`` in `pyproject.toml`). A few tests measure
timing under a load they make themselves (two CPU hogs beside `dpgw demo`); another worker's simulation
beside them would be a load their bounds were not set for.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest


def _lock_folder(config: pytest.Config, run_id: str) -> Path:
    """Where the workers of this run keep their lock files: beside their temporary folders (xdist gives
    each worker ``<run's base>/popen-gwN``, and pytest removes old runs' bases), else in the system's."""
    factory = getattr(config, "_tmp_path_factory", None)  # (pytest's, what the tmp_path fixture uses)
    base = factory.getbasetemp().parent if factory is not None else Path(tempfile.gettempdir())
    folder = base / f"dpgw-alone-{run_id}"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Tests marked ``alone`` run with no other test beside them (the suite runs on every core through
    pytest-xdist: `pyproject.toml`). Such a test measures timing under a load it makes itself — two
    CPU hogs beside `dpgw demo` — and a second worker's simulation would be a third hog the bound was not
    set for.

    A readers-writer lock over the workers, with two `fcntl.flock` files: every test holds ``run``
    shared while it sets up, runs and tears down; an ``alone`` test first takes ``gate`` exclusively, so
    no worker starts another test, then waits for ``run`` exclusively, i.e. for the tests already running
    to end. Locks of a process that dies are released by the kernel. In one process (``-n 0``) there is
    nothing to wait for."""
    run_id = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run_id is None:
        yield
        return
    folder = _lock_folder(item.config, run_id)
    alone = item.get_closest_marker("alone") is not None
    with open(folder / "gate", "a") as gate, open(folder / "run", "a") as run:
        if alone:
            fcntl.flock(gate, fcntl.LOCK_EX)
            fcntl.flock(run, fcntl.LOCK_EX)
        else:
            fcntl.flock(gate, fcntl.LOCK_SH)  # (waits while an alone test holds or waits for the run)
            fcntl.flock(run, fcntl.LOCK_SH)
            fcntl.flock(gate, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(run, fcntl.LOCK_UN)
            if alone:
                fcntl.flock(gate, fcntl.LOCK_UN)
