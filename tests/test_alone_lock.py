"""The ``alone`` marker (tests/alone_lock.py) keeps every other test off the cores while a test that
measures timing under its own load runs: checked on a small suite run with two xdist workers, where
without the lock the other worker runs its short tests beside the ``alone`` one (the second check, which
fails with the hook removed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).parent

SUITE = """
import json, os, time
from pathlib import Path

import pytest


def span(name, seconds):
    start = time.monotonic()
    time.sleep(seconds)  # (the work whose overlap is looked at)
    with Path(os.environ["ALONE_LOG"]).open("a") as f:
        f.write(json.dumps([name, os.environ["PYTEST_XDIST_WORKER"], start, time.monotonic()]) + "\\n")


@pytest.mark.parametrize("k", range(10))
def test_before(k):
    span(f"before{k}", 0.05)


@pytest.mark.alone
def test_alone():
    span("alone", 1.0)


@pytest.mark.parametrize("k", range(30))
def test_after(k):
    span(f"after{k}", 0.05)
"""


@pytest.mark.parametrize("with_lock", [True, False])
def test_an_alone_test_runs_with_no_other_test_beside_it(tmp_path: Path, with_lock: bool) -> None:
    (tmp_path / "test_suite.py").write_text(SUITE)
    hook = "from alone_lock import pytest_runtest_protocol  # noqa: F401\n"
    (tmp_path / "conftest.py").write_text(hook if with_lock else "")
    (tmp_path / "pytest.ini").write_text(
        "[pytest]\nmarkers =\n    alone: runs with no other test beside it\n"
    )
    log = tmp_path / "spans.jsonl"
    env = {**os.environ, "ALONE_LOG": str(log), "PYTHONPATH": str(TESTS)}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2", "--dist", "worksteal",
         "--strict-markers", str(tmp_path)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    spans = {
        name: (worker, start, end)
        for name, worker, start, end in map(json.loads, log.read_text().splitlines())
    }
    assert len(spans) == 41
    assert len({worker for worker, _, _ in spans.values()}) == 2, "the suite did not run on two workers"
    _, start0, end0 = spans.pop("alone")
    beside = [name for name, (_, start, end) in spans.items() if start < end0 and end > start0]
    if with_lock:
        assert not beside, f"{beside} ran beside the alone test"
    else:  # the check can fail: without the lock the other worker goes on beside it
        assert beside
