"""``dpgw run`` (and ``dpgw sim --realtime``) as a process stopped by signals: SIGINT (Ctrl-C), SIGTERM
(``systemctl stop``) and SIGHUP (the terminal or SSH session closing), while running and during start-up.
Each must end the process with status 0, no traceback, and the MCAP log closed complete (summary and
footer) holding every byte the gateway received; a SIGHUP ignored by ``nohup`` stays ignored. Real
processes, a real pty and real UDP; the test waits for the gateway's own lines and for estimates on disk,
never for a fixed time."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import pty
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port, wait_for

from wire.codecs import nmea_encode as enc
from wire.mcap.reader import read_messages, summary

ROOT = Path(__file__).resolve().parents[1]


def write_config(tmp: Path, pty_device: str, udp_port: int) -> Path:
    cfg = tmp / "vessel.toml"
    cfg.write_text(f"""
[vessel]
name = "mss_supply"
[datum]
lat_deg = 59.4
lon_deg = 10.5
[[sources]]
name = "gps"
url = "serial://{pty_device}?baud=4800"
protocol = "nmea"
roles = ["position", "heading"]
[[sources]]
name = "mux"
url = "udp://127.0.0.1:{udp_port}"
protocol = "nmea"
roles = ["position", "heading"]
priority = 2
[zenoh]
listen = ["tcp/127.0.0.1:{free_port()}"]
multicast_scouting = false
[log]
path = "{tmp / "live.mcap"}"
""")
    return cfg


class Talkers:
    """A DGPS on a pty and a multiplexer on UDP, both sending GGA + HDT at 10 Hz until stopped."""

    def __init__(self) -> None:
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)
        self.device = os.ttyname(self.slave)
        self.udp_port = free_port(socket.SOCK_DGRAM)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._talk, daemon=True)

    def _talk(self) -> None:
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        k = 0
        while not self._stop.wait(0.1):  # a receiver's 10 Hz: pacing, not a wait for an event
            burst = (
                enc.gga("GP", datetime.now(UTC), 59.4 + 1e-7 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
                + enc.hdt("HE", 0.5 + 0.01 * (k % 5))
            ).encode()
            # (the pty buffer full before the gateway opened it: the next burst will do)
            with contextlib.suppress(OSError):
                os.write(self.master, burst)
            tx.sendto(burst, ("127.0.0.1", self.udp_port))
            k += 1
        tx.close()

    def __enter__(self) -> Talkers:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self.slave)


class Gateway:
    """``dpgw run -v --json`` in its own process, its stderr read line by line as it comes."""

    def __init__(
        self, cfg: Path, hangup: Any = signal.SIG_DFL, options: tuple[str, ...] = ("-v", "--json")
    ) -> None:
        """``hangup``: SIGHUP's disposition the gateway inherits (``SIG_IGN``: as under ``nohup``);
        ``options``: of ``dpgw run`` (without ``--json``, `finish` cannot read stdout: read it instead)."""
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "dpgw", "run", "--config", str(cfg), *options],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            # the test may itself run in the background of a shell, which ignores SIGINT: the gateway is
            # started as from a terminal, with the default dispositions
            preexec_fn=lambda: (
                signal.signal(signal.SIGINT, signal.SIG_DFL),
                signal.signal(signal.SIGHUP, hangup),
            ),
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.err: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.err.append(line)
            self.lines.put(line)

    def wait_line(self, text: str, timeout: float = 120.0) -> None:
        """Block until the gateway prints a line containing ``text``, for at most ``timeout`` s in all (a
        timeout per line would never end while other lines keep coming, e.g. ``-v``'s status line)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                pytest.fail(f"no line with {text!r} within {timeout} s: {''.join(self.err)}")
            if text in line:
                return

    def finish(self) -> tuple[int, dict, str]:  # type: ignore[type-arg]
        assert self.proc.stdout is not None
        out = self.proc.stdout.read()  # (stderr is this object's reader's: not `communicate`)
        self.proc.wait(timeout=60)
        self._reader.join(timeout=60)
        return self.proc.returncode, json.loads(out) if out.strip() else {}, "".join(self.err)


def logged_bytes(path: Path, topic: str) -> int:
    """Bytes of the raw NMEA channel ``topic`` as a replay rebuilds them."""
    n = 0
    for _, _, _, p in read_messages(path, topic):
        body = base64.b64decode(p["data"]) if "data" in p else p["text"].encode("ascii")
        n += len(body) + (0 if p.get("unterminated") else len(p.get("eol", "\r\n")))
    return n


def assert_log_complete_with_every_byte(log: Path, status: dict) -> None:  # type: ignore[type-arg]
    assert summary(log).complete, "the log was not closed: no summary and footer"
    for name in ("gps", "mux"):
        assert logged_bytes(log, f"/raw/nmea/{name}") == status["sources"][name]["bytes"], name


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_while_running_closes_the_log_with_every_byte(tmp_path: Path, sig: signal.Signals) -> None:
    """Before: SIGHUP killed the gateway like SIGKILL (status 129), its log without summary or footer
    ("RecordLengthLimitExceeded" from the mcap library); SIGTERM and SIGINT were already clean."""
    with Talkers() as talk:
        log = tmp_path / "live.mcap"
        gw = Gateway(write_config(tmp_path, talk.device, talk.udp_port))
        gw.wait_line("dpgw run: vessel")  # started: sources, Zenoh and the log are open
        assert wait_for(
            lambda: gw.proc.poll() is not None or sum(1 for _ in read_messages(log, "/dp/estimate")) >= 10,
            60.0,
        ), "no estimates on disk within 60 s"
        gw.proc.send_signal(sig)
        code, result, err = gw.finish()
    assert code == 0, err
    assert "Traceback" not in err
    assert result["estimates"] >= 10
    assert_log_complete_with_every_byte(log, result["status"])


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_during_start_up_stops_cleanly(tmp_path: Path, sig: signal.Signals) -> None:
    """The signal comes as the kernels are ready, while the sources, Zenoh and the log are being opened
    (``systemctl stop`` of a unit still starting; Ctrl-C on a first run, whose kernels take seconds to
    compile). Before: SIGTERM and SIGHUP killed the process (status -15, -1), leaving the log opened but
    unreadable; SIGINT printed a KeyboardInterrupt traceback (status 1)."""
    with Talkers() as talk:
        log = tmp_path / "live.mcap"
        gw = Gateway(write_config(tmp_path, talk.device, talk.udp_port))
        gw.wait_line("compiled kernels ready")
        gw.proc.send_signal(sig)
        code, result, err = gw.finish()
    assert code == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    if log.exists():  # opened before the signal was seen: then closed complete
        assert_log_complete_with_every_byte(log, result["status"])
    else:
        assert f"stopped by {sig.name} during start-up; nothing was opened" in err


def test_a_hangup_ignored_by_nohup_stays_ignored(tmp_path: Path) -> None:
    """``nohup dpgw run ...`` asks for SIGHUP to be ignored: the gateway goes on estimating after one,
    and SIGTERM then stops it as usual."""
    with Talkers() as talk:
        log = tmp_path / "live.mcap"
        gw = Gateway(write_config(tmp_path, talk.device, talk.udp_port), hangup=signal.SIG_IGN)
        gw.wait_line("dpgw run: vessel")

        def on_disk() -> int:
            return sum(1 for _ in read_messages(log, "/dp/estimate"))

        assert wait_for(lambda: gw.proc.poll() is not None or on_disk() >= 10, 60.0)
        gw.proc.send_signal(signal.SIGHUP)
        after_hup = on_disk()
        assert wait_for(lambda: gw.proc.poll() is not None or on_disk() >= after_hup + 10, 60.0)
        assert gw.proc.poll() is None, "a SIGHUP ignored by nohup stopped the gateway"
        gw.proc.send_signal(signal.SIGTERM)
        code, result, err = gw.finish()
    assert code == 0, err
    assert_log_complete_with_every_byte(log, result["status"])


def _stop_a_running_simulator(sig: signal.Signals, *argv: str) -> tuple[int, str, str]:
    """``dpgw sim --scenario mss_supply_wind --realtime ARGV`` sending MAVLink to a free port, stopped with
    ``sig`` once it says where its MAVLink goes (it runs then): its exit status, stdout and stderr. The
    signal's default action is restored for the child, as a terminal or an SSH session starts it."""
    mavlink = f"udp://127.0.0.1:{free_port(socket.SOCK_DGRAM)}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "sim", "--scenario", "mss_supply_wind", "--realtime", "--mavlink",
         mavlink, *argv],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(sig, signal.SIG_DFL),
    )  # fmt: skip
    assert proc.stderr is not None
    for line in proc.stderr:
        if line.startswith("MAVLink ->"):
            break
    else:
        pytest.fail(f"the simulator did not start: {proc.wait()}")
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    return proc.returncode, stdout, stderr


def test_a_hangup_stops_a_realtime_simulator_with_its_log_complete(tmp_path: Path) -> None:
    """``dpgw sim --realtime`` on the bench, started over SSH: the session dropping (SIGHUP) ends the run
    as Ctrl-C does, the log complete and the summary saying it was interrupted. Before: killed at once
    (status -1), its log without summary or footer."""
    out = tmp_path / "sim.mcap"
    code, stdout, stderr = _stop_a_running_simulator(signal.SIGHUP, "--json", "--out", str(out))
    assert code == 0, stderr
    run = json.loads(stdout)
    assert run["interrupted"] is True and run["stopped_by"] == "SIGHUP", run
    assert summary(out).complete, "the log was not closed: no summary and footer"


def test_a_simulator_stopped_early_says_so_in_its_summary(tmp_path: Path) -> None:
    """Ctrl-C before ``--duration``: the summary's first line says the run was stopped, and when, of how
    much was asked (it said "1740 s simulated in 2.9 s", which read as a run that went its course)."""
    argv = ("--duration", "600", "--out", str(tmp_path / "s.mcap"))
    code, stdout, stderr = _stop_a_running_simulator(signal.SIGINT, *argv)
    assert code == 0, stderr
    first = stdout.splitlines()[0]
    assert re.fullmatch(r"mss_supply_wind: stopped by Ctrl-C at \d+ s simulated of 600 asked in .*", first), (
        first
    )


def test_a_signal_handler_never_waits_for_a_lock_its_own_thread_holds() -> None:
    """A signal handler runs in the main thread between two of its bytecodes, possibly inside that thread's
    own `Event.set` or `wait` of the event it sets, holding the event's lock. Before, ``dpgw run``'s handler
    set the service's stop event there and waited for itself for ever: a gateway that got a second SIGINT
    as it was stopping ignored every signal after it, its log left without its end. The handler now sets
    it from a thread of its own: it returns at once, and the event is set once the lock is free."""
    from types import SimpleNamespace

    from dpgw.cli_run import StopSignals  # (the handler `dpgw run` installs)

    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        stop = StopSignals()
        service = SimpleNamespace(stop_event=threading.Event())
        stop.attach(service)  # type: ignore[arg-type]
        with service.stop_event._cond:  # type: ignore[attr-defined]  # (the main thread inside Event.set)
            returned = threading.Event()
            handler = threading.Thread(target=lambda: (stop._on_signal(signal.SIGINT, None), returned.set()))
            handler.start()
            assert returned.wait(5.0), "the handler waits for the lock"
            assert stop.signum == signal.SIGINT
        assert wait_for(service.stop_event.is_set, 5.0) and wait_for(stop.requested.is_set, 5.0)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
