"""Under systemd, `dpgw run`'s log lines carry their priority for the journal (`dpgw.journal`), so that
``journalctl -u dpgw -p warning`` lists the faults; elsewhere they are as they were. Real processes: the
journal's stream is a pipe whose device and inode are given in ``JOURNAL_STREAM``, as systemd does."""

from __future__ import annotations

import logging
import os
import re
import socket
import subprocess
import sys
import threading
from pathlib import Path

from conftest import one_source_config

from dpgw.journal import JournalFormatter

ROOT = Path(__file__).resolve().parents[1]
RUN = [sys.executable, "-m", "dpgw", "run", "--config"]


def write_config(tmp: Path) -> Path:
    return one_source_config(tmp, f"serial://{tmp / 'ttyUSB1'}?baud=4800", "gyro1")


def run_with_stderr(cfg: Path, journal: bool) -> list[str]:
    """``dpgw run --wait-for-ports`` for a moment (its serial port missing: a warning), stderr on a pipe;
    with ``journal``, that pipe announced as the journal's stream."""
    code, lines = run_on_stderr_pipe([str(cfg), "--wait-for-ports", "--duration", "0.5"], journal)
    assert code == 0, lines
    return lines


def run_on_stderr_pipe(args: list[str], journal: bool) -> tuple[int, list[str]]:
    """``dpgw run --config ARGS...``: its status and its stderr's lines, stderr on a pipe; with
    ``journal``, that pipe announced as the journal's stream."""
    r, w = os.pipe()
    env = dict(os.environ)
    env.pop("JOURNAL_STREAM", None)
    if journal:
        st = os.fstat(w)
        env["JOURNAL_STREAM"] = f"{st.st_dev}:{st.st_ino}"
    lines: list[str] = []
    with os.fdopen(r, encoding="utf-8") as reader:
        collect = threading.Thread(target=lambda: lines.extend(reader), daemon=True)
        collect.start()
        p = subprocess.run([*RUN, *args], cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=w, timeout=120)
        os.close(w)
        collect.join(30)
    return p.returncode, lines


def test_log_lines_carry_their_priority_for_the_journal(tmp_path: Path) -> None:
    cfg = write_config(tmp_path)
    lines = run_with_stderr(cfg, journal=True)
    waiting = [ln for ln in lines if "waiting for it" in ln]
    assert len(waiting) == 1 and waiting[0].startswith("<4>source 'gyro1'"), lines  # a warning
    plain = run_with_stderr(cfg, journal=False)
    assert not [ln for ln in plain if ln.startswith("<")], plain
    assert any(ln.startswith("source 'gyro1'") and "waiting for it" in ln for ln in plain), plain


def test_another_stream_than_the_journals_gets_no_prefix(tmp_path: Path) -> None:
    """``JOURNAL_STREAM`` inherited by a process whose stderr is something else (run from a shell that a
    service started, redirected to a file): no prefix."""
    cfg = write_config(tmp_path)
    env = dict(os.environ, JOURNAL_STREAM="1:1")
    with open(tmp_path / "err.txt", "w") as err:
        p = subprocess.run(
            [*RUN, str(cfg), "--wait-for-ports", "--duration", "0.5"],
            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=err, timeout=120,
        )  # fmt: skip
    text = (tmp_path / "err.txt").read_text()
    assert p.returncode == 0 and "waiting for it" in text and "<4>" not in text, text


def test_every_line_of_a_traceback_carries_the_priority() -> None:
    """journald takes each line as an entry: a traceback's lines after the first went in at the default
    priority (info), and ``journalctl -p err`` showed an internal error without its traceback."""
    try:
        raise ValueError("a bug")
    except ValueError:
        record = logging.LogRecord(
            "dpgw", logging.ERROR, __file__, 1, "internal error #1", None, sys.exc_info()
        )
    text = JournalFormatter("%(message)s").format(record)
    lines = text.split("\n")
    assert len(lines) > 3 and "ValueError: a bug" in lines[-1], text
    assert all(line.startswith("<3>") for line in lines), text


def test_a_mistake_that_stops_start_up_is_an_error_in_the_journal(tmp_path: Path) -> None:
    """A config that does not parse, a serial port that is not there, a Zenoh endpoint that cannot be
    opened: each stops start-up (status 2) with one message naming what and where, at error priority in the
    journal (``<3>`` on each of its lines). Printed plain, it went in at info: ``journalctl -u dpgw -p
    err`` of a service that failed every start showed nothing. Elsewhere the message is as it was."""
    bad = tmp_path / "bad"
    bad.mkdir()
    cfg = write_config(bad)
    cfg.write_text(cfg.read_text().replace('protocol = "nmea"', 'protocol = "nmea"\nbaud_rate = 4800'))
    missing = tmp_path / "missing"
    missing.mkdir()
    no_port = one_source_config(missing, "serial:///dev/ttyUSB_nope?baud=4800")
    taken = tmp_path / "taken"
    taken.mkdir()
    in_use = one_source_config(taken, "udp://127.0.0.1:0")
    with socket.socket() as other:  # Zenoh's listen endpoint held by another program
        other.bind(("127.0.0.1", 0))
        other.listen()
        port = other.getsockname()[1]
        text = re.sub(r"tcp/127\.0\.0\.1:[0-9]+", f"tcp/127.0.0.1:{port}", in_use.read_text())
        in_use.write_text(text)
        cases = {
            "config": ([str(cfg)], ["baud_rate"]),
            "serial port": ([str(no_port)], ["sources.dgps1.url", "/dev/ttyUSB_nope does not exist"]),
            "zenoh": ([str(in_use)], [str(in_use), f"127.0.0.1:{port}"]),
        }
        for what, (args, named) in cases.items():
            code, lines = run_on_stderr_pipe([*args, "--duration", "5"], journal=True)
            assert code == 2, (what, lines)
            assert lines and all(ln.startswith("<3>") for ln in lines), (what, lines)
            assert all(name in "".join(lines) for name in named), (what, lines)
            assert "Traceback" not in "".join(lines), (what, lines)
            if what != "config":  # (a config's problems: one line each, under one heading)
                assert len(lines) == 1, (what, lines)
            code, plain = run_on_stderr_pipe([*args, "--duration", "5"], journal=False)
            assert code == 2 and plain == [ln[3:] for ln in lines], (what, plain, lines)
