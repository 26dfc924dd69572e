"""A console that goes away never stops or hangs a command: `dpgw demo 2>&1 | head -2` hung for ever
(the demo's third line to stderr raised BrokenPipeError between the gateway's start and the code that
stops it; the command returned with the gateway's threads running). stderr is guarded now
(`dpgw.stderr_guard`); stdout still stops a command whose reader stopped reading."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from conftest import free_port

from dpgw.stderr_guard import StderrGuard


def test_a_write_to_stderr_whose_reader_is_gone_goes_nowhere() -> None:
    r, w = os.pipe()
    stream = os.fdopen(w, "w", buffering=1)
    guard = StderrGuard(stream)
    assert guard.write("first line\n") == len("first line\n")
    assert os.read(r, 100) == b"first line\n"
    os.close(r)  # the reader goes away
    assert guard.write("nobody reads this\n") == len("nobody reads this\n")  # no BrokenPipeError
    guard.flush()
    assert guard.gone
    guard.write("nor this\n")
    stream.close()


def test_the_demo_piped_into_head_ends_instead_of_hanging(tmp_path: Path) -> None:
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "demo", "--duration", "8", "--speed", "10", "--out",
         str(tmp_path / "demo.mcap"), "--no-scouting", "--zenoh-listen", f"tcp/127.0.0.1:{port}",
         "--foxglove", str(free_port())],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    assert proc.stdout is not None
    head = [proc.stdout.readline() for _ in range(2)]  # `| head -2`
    proc.stdout.close()
    try:
        code = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert all(line.startswith(b"dpgw demo: ") for line in head), head
    # the run went on to its end (its log is complete) and stopped as a shell tool stops on SIGPIPE
    assert code == 128 + 13, code
    assert (tmp_path / "demo.mcap").stat().st_size > 10_000


def test_stderr_is_the_callers_again_after_a_command(tmp_path: Path) -> None:
    from dpgw.cli import main

    before = sys.stderr
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--out", str(tmp_path / "s.mcap")]) == 0
    assert sys.stderr is before
