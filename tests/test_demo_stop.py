"""`dpgw demo` stopped while its gateway is far behind ends in bounded time, as `dpgw run` does: what is
still queued after `gateway.service.DRAIN_S` is written to the log as received, not handled (it handled
its whole queue first, however long that took). Real demo (simulator, pty, UDP, Zenoh, MCAP), in this
process so that its gateway's output can be made slow and its stop timed; the flood comes over the real
UDP link of its DGPS."""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import run_demo_beside, wait_for

import gateway.service as service_module
from dpgw.cli import build_parser
from gateway.service import GatewayService
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import log_files, read_messages

FLOOD = 300
"""Inputs queued at the stop: with each handled in 20 ms or more, 6 s and more to handle them all."""
BOUND_S = 1.0
"""`DRAIN_S` for this test (10 s in service)."""


@pytest.mark.slow  # a demo started, jammed and stopped: ~10 s
def test_a_demo_stopped_far_behind_stops_in_time_with_every_input_logged(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(service_module, "DRAIN_S", BOUND_S)
    services: list[GatewayService] = []
    moving = threading.Event()  # cleared: the gateway's output blocks (a jammed output)
    moving.set()
    slow = threading.Event()  # set: each output takes 20 ms (an overloaded machine)
    drains: list[tuple[float, int]] = []
    start, emit, drain = GatewayService.start, GatewayService._emit, GatewayService.drain

    def started(self: GatewayService) -> None:
        services.append(self)
        start(self)

    def jammed_emit(self: GatewayService, outputs: Any) -> None:
        moving.wait()
        if slow.is_set():
            time.sleep(0.02)
        emit(self, outputs)

    def timed_drain(self: GatewayService, *args: Any, **kwargs: Any) -> None:
        t0 = time.monotonic()
        drain(self, *args, **kwargs)
        drains.append((time.monotonic() - t0, self.logged_unhandled))

    monkeypatch.setattr(GatewayService, "start", started)
    monkeypatch.setattr(GatewayService, "_emit", jammed_emit)
    monkeypatch.setattr(GatewayService, "drain", timed_drain)
    out = tmp_path / "demo.mcap"
    args = build_parser().parse_args(
        ["demo", "--duration", "3600", "--speed", "1", "--out", str(out), "--json", "--no-scouting",
         "--no-foxglove"]
    )  # fmt: skip
    flood = [enc.sentence("GP", "TXT", ["01", "01", "02", f"FLOOD {k}"]).encode() for k in range(FLOOD)]
    problems: list[str] = []

    def operator() -> None:
        """Once the demo runs: jam its gateway, flood its DGPS port, then stop it (SIGTERM) slowed."""
        try:
            if not wait_for(lambda: services and services[0].pipeline.estimates > 5, 120):
                problems.append("the demo never ran")
                return
            service = services[0]
            dgps = next(s for s in service._sources if s.url.startswith("udp") and s.name != "thrusters")
            moving.clear()
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
                for body in flood:
                    tx.sendto(body, ("127.0.0.1", int(getattr(dgps, "port", 0))))
            if not wait_for(lambda: service._queue.qsize() >= FLOOD, 30):
                problems.append(f"only {service._queue.qsize()} queued")
            slow.set()
        finally:
            os.kill(os.getpid(), signal.SIGTERM)  # the demo's own stop (its handler), as systemctl stop
            moving.set()

    code = run_demo_beside(args, operator, release=moving.set)
    assert not problems, problems
    assert code == 143  # SIGTERM stops a demo short of its --duration: 128 + 15, as a shell says it
    assert len(drains) == 1, drains
    took, logged_only = drains[0]
    assert took < BOUND_S + 1.5, took  # the bound (and a slow item past it), not FLOOD x 20 ms
    assert logged_only > FLOOD // 2, logged_only
    texts = [p.get("text", "") for _, _, _, p in read_messages(log_files(out)) if "text" in p]
    assert sum("FLOOD" in t for t in texts) == FLOOD  # every one in the log, handled or not
