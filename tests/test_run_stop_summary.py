"""What ``dpgw run`` says when it stops, in text: why it stopped (the end of ``--duration``, Ctrl-C,
SIGTERM) and, when it made no estimate or alarms are up, the alarms, one line each, capped. Before, a trial
whose sources sent nothing ended on ``dpgw run: stopped; 0 estimates, 6 messages published`` and the
reason (``source ...: no data yet``) was only in ``--json``. Real processes on a real UDP port."""

from __future__ import annotations

import json
import queue
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from conftest import free_port, one_source_config

from dpgw.cli_run import ALARMS_SHOWN, alarm_lines

ROOT = Path(__file__).resolve().parents[1]


def silent_config(tmp: Path) -> Path:
    """One NMEA source on a UDP port nobody sends to."""
    return one_source_config(tmp, f"udp://127.0.0.1:{free_port(socket.SOCK_DGRAM)}", datum=True)


def test_a_run_ended_by_its_duration_says_so_and_why_nothing_came(tmp_path: Path) -> None:
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(silent_config(tmp_path)), "--duration", "2"],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert lines[0].startswith("dpgw run: stopped: --duration 2 s reached; 0 estimates, "), p.stdout
    assert "dpgw run: alarm: source dgps1: no data yet" in lines, p.stdout
    assert len(lines) <= 1 + ALARMS_SHOWN + 1, p.stdout
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(silent_config(tmp_path)), "--duration", "1",
         "--json"],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 0 and json.loads(p.stdout)["stopped_by"] is None, p.stdout  # (not a signal)


def test_ctrl_c_is_named_in_the_summary_and_in_json(tmp_path: Path) -> None:
    cfg = silent_config(tmp_path)
    for options in ((), ("--json",)):
        proc = subprocess.Popen(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), *options],
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )  # fmt: skip
        assert proc.stderr is not None
        started: queue.Queue[str] = queue.Queue()
        err: list[str] = []

        def read(stream=proc.stderr, err=err, started=started) -> None:  # type: ignore[no-untyped-def]
            try:
                for line in stream:
                    err.append(line)
                    if line.startswith("dpgw run: vessel"):
                        started.put(line)
            except ValueError:  # `communicate` below closed the stream it read the rest of: done
                pass

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            started.get(timeout=120)  # the sources, Zenoh and the log are open
        except queue.Empty:
            proc.kill()
            pytest.fail(f"dpgw run did not start: {''.join(err)}")
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
        reader.join(timeout=10)
        assert proc.returncode == 0, "".join(err)
        if options:
            assert json.loads(out)["stopped_by"] == "SIGINT"  # (the signal's name, as dpgw demo's JSON)
        else:
            assert out.startswith("dpgw run: stopped: Ctrl-C (SIGINT); "), out
            assert "dpgw run: alarm: source dgps1: no data yet" in out.splitlines(), out


def test_the_alarms_are_capped_and_a_silent_run_says_so() -> None:
    alarms = [f"source s{k}: no data yet" for k in range(ALARMS_SHOWN + 3)]
    lines = alarm_lines(alarms, estimates=0)
    assert lines[:ALARMS_SHOWN] == [f"alarm: {a}" for a in alarms[:ALARMS_SHOWN]]
    assert lines[ALARMS_SHOWN:] == ["... and 3 more alarms (all of them: --json)"]
    assert alarm_lines([], estimates=120) == []
    assert alarm_lines(["source s0: stale"], estimates=120) == ["alarm: source s0: stale"]
    assert len(alarm_lines([], estimates=0)) == 1  # no estimate and nothing up: said, not silent
