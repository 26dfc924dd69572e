"""The live service keeps everything (DESIGN rule 4): a chunk is logged raw before the pipeline sees it, and a
bug hit while handling one chunk is counted, logged with its traceback, and does not stop the service."""

from __future__ import annotations

import json
import logging
import socket
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port

from gateway.bus import isolated_config, open_session
from gateway.config import parse_config
from gateway.pipeline import RawEvent, SourceCounters, SourceSpec
from gateway.service import GatewayService
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import read_messages

POISON = b"$POISON\r\n"  # the chunk carrying this marker makes the (patched) pipeline raise


def burst(k: int) -> bytes:
    gga = enc.gga("GP", datetime.now(UTC), 59.4 + 1e-6 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
    return (gga + enc.hdt("HE", 0.5)).encode()


def wait_for(
    what: str, ok: Callable[[], bool], timeout_s: float = 30.0, send: Callable[[], None] | None = None
) -> None:
    deadline = time.monotonic() + timeout_s
    while not ok():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        if send is not None:
            send()
        time.sleep(0.02)


def test_a_bug_on_one_chunk_is_counted_logged_and_the_service_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    log_path = tmp_path / "live.mcap"
    tables = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {
                "name": "mux",
                "url": f"udp://127.0.0.1:{udp}",
                "protocol": "nmea",
                "roles": ["position", "heading"],
            }
        ],
        "observer": {"wave_period_s": 9.0},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"], "multicast_scouting": False, "prefix": "dp/t"},
        "status": {"rate_hz": 10.0},
        "log": {"path": str(log_path)},
    }
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)

    # A bug inside the pipeline, deep enough that the source's counters were already touched: it raises on
    # the chunk with the marker and only on that one.
    real_nmea = service.pipeline._nmea

    def buggy_nmea(spec: SourceSpec, c: SourceCounters, ev: RawEvent, out: list[Any]) -> bool:
        if POISON in ev.data:
            raise ZeroDivisionError("a bug in the pipeline")
        return real_nmea(spec, c, ev, out)

    monkeypatch.setattr(service.pipeline, "_nmea", buggy_nmea)
    caplog.set_level(logging.ERROR, logger="dpgw")
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{zport}"]))
    sent = [0]

    def send(extra: bytes = b"") -> None:
        tx.sendto(extra + burst(sent[0]), ("127.0.0.1", udp))
        sent[0] += 1

    def status() -> dict[str, Any]:
        replies = [r for r in client.get("dp/t/status", timeout=2.0) if r.ok is not None]
        return json.loads(replies[0].ok.payload.to_bytes()) if replies else {}

    counters = service.pipeline.counters["mux"]
    try:
        wait_for("the first estimates", lambda: service.pipeline.estimates >= 5, send=send)
        # the poisoned chunk, resent until it has arrived (UDP), then good chunks again
        wait_for(
            "the poisoned chunk", lambda: counters.rejected["internal_error"] >= 1, send=lambda: send(POISON)
        )
        after = service.pipeline.estimates
        wait_for("estimates after the bug", lambda: service.pipeline.estimates >= after + 5, send=send)
        wait_for(
            "the error in /status",
            lambda: (
                status().get("sources", {}).get("mux", {}).get("rejected", {}).get("internal_error", 0) >= 1
            ),
        )
        s = status()
        assert any("source mux" in a and "internal error" in a for a in s["alarms"]), s["alarms"]
    finally:
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        client.close()
        tx.close()
        service.close()
    assert not loop.is_alive()
    n_errors = counters.rejected["internal_error"]
    assert service.internal_errors["source mux"] == n_errors

    # logged with the traceback, once per failing chunk
    errors = [r for r in caplog.records if "internal error" in r.getMessage()]
    assert len(errors) == n_errors and errors[0].exc_info is not None
    assert errors[0].exc_info[0] is ZeroDivisionError and "mux" in errors[0].getMessage()

    # the poisoned chunk is in the log, raw, and estimates go on after it
    raw = [(t, m) for _, t, _, m in read_messages(log_path, "/raw/nmea/mux")]
    poisoned = [t for t, m in raw if "POISON" in m.get("text", "")]
    assert len(poisoned) == n_errors
    estimates = [t for _, t, _, _ in read_messages(log_path, "/dp/estimate")]
    assert sum(t > max(poisoned) for t in estimates) >= 5
