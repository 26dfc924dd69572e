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
from conftest import free_port, stop_service

from gateway.bus import isolated_config, open_session
from gateway.config import parse_config
from gateway.pipeline import RawEvent
from gateway.service import GatewayService
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import read_messages

POISON = b"$POISON\r\n"  # the chunk carrying this marker makes the (patched) pipeline raise


class _PipelineWith:
    """A service's pipeline with some methods replaced. (The pipeline may be compiled, and a compiled
    class's methods cannot be patched on its instances: the service is given this stand-in instead.)"""

    def __init__(self, pipeline: Any, **methods: Callable[..., Any]) -> None:
        object.__setattr__(self, "_pipeline", pipeline)
        object.__setattr__(self, "_methods", methods)

    def __getattr__(self, name: str) -> Any:
        methods = object.__getattribute__(self, "_methods")
        return methods[name] if name in methods else getattr(object.__getattribute__(self, "_pipeline"), name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(object.__getattribute__(self, "_pipeline"), name, value)


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


def mux_tables(udp: int, zport: int, log_path: Path, status_hz: float) -> dict[str, Any]:
    """A gateway config: one NMEA multiplexer (position and heading) on UDP ``udp``, Zenoh on ``zport``."""
    return {
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
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"], "multicast_scouting": False},
        "status": {"rate_hz": status_hz},
        "log": {"path": str(log_path)},
    }


def test_a_bug_on_one_chunk_is_counted_logged_and_the_service_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    log_path = tmp_path / "live.mcap"
    tables = mux_tables(udp, zport, log_path, status_hz=10.0)
    tables["zenoh"]["prefix"] = "dp/t"
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)

    # A bug inside the pipeline, deep enough that the source's counters were already touched: it raises on
    # the chunk with the marker, after the rest of that chunk went through, and only on that one.
    real = service.pipeline

    def buggy_feed(ev: RawEvent | Any) -> list[Any]:
        if isinstance(ev, RawEvent) and POISON in ev.data:
            real.feed(RawEvent(ev.rx_ns, ev.source, ev.data.replace(POISON, b""), peer=ev.peer))
            raise ZeroDivisionError("a bug in the pipeline")
        return real.feed(ev)

    monkeypatch.setattr(service, "pipeline", _PipelineWith(real, feed=buggy_feed))
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


def test_the_logs_last_status_holds_every_count_of_the_run(tmp_path: Path) -> None:
    """The status goes out at ``[status] rate_hz``; at shutdown (`drain`) a last one goes out and into the
    log with every chunk handled. Before, a log's last status was the last periodic one: up to a period of
    the run left out (here, with a status every 10 s, none at all), and a replay of a signed link's older
    log reports from it what the live gateway refused."""
    udp, zport = free_port(socket.SOCK_DGRAM), free_port()
    log_path = tmp_path / "live.mcap"
    tables = mux_tables(udp, zport, log_path, status_hz=0.1)
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = [0]

    def send() -> None:
        tx.sendto(burst(sent[0]) + b"$GPXXX,garbage*00\r\n", ("127.0.0.1", udp))
        sent[0] += 1

    counters = service.pipeline.counters["mux"]
    try:
        wait_for("20 bursts", lambda: counters.received >= 40, send=send)
    finally:
        tx.close()
        stop_service(service, loop)
    statuses = [p for _, _, _, p in read_messages(log_path, "/dp/status")]
    assert statuses, "no status in the log"
    last = statuses[-1]["sources"]["mux"]
    assert last["received"] == counters.received and last["rejected"] == dict(counters.rejected)
    assert sum(last["rejected"].values()) >= 20  # every burst's bad sentence, counted


# --- the computer's clock stepped back ----------------------------------------------------------------


def test_receive_stamps_never_step_back_with_the_computers_clock() -> None:
    """WallTime: stamps follow the monotonic clock from an offset taken from the UTC clock; a step back of
    the UTC clock leaves them in order (and says by how much, until the clock is stepped forward again), a
    step forward is taken."""
    from gateway.wall_time import WallTime

    w = WallTime()
    wall, mono = 1_780_000_000 * 10**9, 5 * 10**9
    stamps = []
    for k in range(100):  # 10 Hz; the UTC clock steps back 30 s at k = 50
        stamps.append(w.stamp(wall + k * 10**8 - (30 * 10**9 if k >= 50 else 0), mono + k * 10**8))
    assert stamps == [wall + k * 10**8 for k in range(100)]
    assert w.behind_ns == 30 * 10**9 and "30.0 s ahead" in w.alarms()[0]
    # the clock is put right again (stepped forward 30 s): the alarm clears, the stamps go on
    assert w.stamp(wall + 100 * 10**8, mono + 100 * 10**8) == wall + 100 * 10**8
    assert w.behind_ns == 0 and w.alarms() == []
    # a step forward is taken (to the pipeline a gap, like a silence of the sources)
    assert w.stamp(wall + 3600 * 10**9, mono + 101 * 10**8) == wall + 3600 * 10**9
    assert w.stamp(wall + 3600 * 10**9 + 10**8, mono + 102 * 10**8) == wall + 3600 * 10**9 + 10**8


def test_a_clock_stepped_back_rejects_no_reference(tmp_path: Path) -> None:
    """The service stamps chunks received across a 30 s step back of the computer's clock in order: no
    reference fails its jump test (before, with the UTC clock's stamps, both were rejected for 36 s:
    `moved 0.567 m in -30 s (limit -144 m)`), and the estimates go on, their times increasing."""
    from gateway.sources import Chunk

    tables = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "mux", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "observer": {"wave_period_s": 9.0},
        "log": {"path": ""},
    }
    service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
    wall, mono = time.time_ns(), time.monotonic_ns()
    for k in range(600):  # a minute at 10 Hz; the clock steps back 30 s after 40 s
        step = 30 * 10**9 if k >= 400 else 0
        gga = enc.gga("GP", datetime.now(UTC), 59.4 + 1e-6 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
        data = (gga + enc.hdt("HE", 0.5 + 1e-4 * (k % 5))).encode()
        service._handle(Chunk("mux", data, wall + k * 10**8 - step, mono + k * 10**8))
    c = service.pipeline.counters["mux"]
    assert c.received == 1200 and not c.rejected, dict(c.rejected)
    assert service.pipeline.estimates >= 590
    assert service.wall_time.behind_ns == 30 * 10**9
    assert any("stepped back" in a for a in service._alarms())


def test_a_slow_first_compile_is_said_and_a_quick_one_is_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The first run after an install compiles numba's kernels for ~15 s before any source opens; without
    -v the gateway would sit silent. Past `COMPILE_NOTICE_S` it says what it is doing, once; a start from
    the cache (well under a second) says nothing."""
    import gateway.service as service_module

    tables = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "observer": {"wave_period_s": 9.0},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"], "multicast_scouting": False, "prefix": "dp/t"},
        "log": {"path": ""},
    }
    caplog.set_level(logging.WARNING, logger="dpgw")

    def said() -> list[str]:
        return [r.getMessage() for r in caplog.records if "compiling the numeric kernels" in r.getMessage()]

    for slow in (True, False):
        caplog.clear()
        # (the quick case's threshold far above its no-op compile, so a busy machine cannot cross it)
        monkeypatch.setattr(service_module, "COMPILE_NOTICE_S", 0.05 if slow else 5.0)
        service = GatewayService(parse_config(tables, base_dir=tmp_path), config_tables=tables)
        if slow:  # a compile that lasts until the notice has been given
            slow_compile = _PipelineWith(
                service.pipeline, compile_kernels=lambda: wait_for("the notice", lambda: bool(said()), 10.0)
            )
            monkeypatch.setattr(service, "pipeline", slow_compile)
        else:
            monkeypatch.setattr(
                service, "pipeline", _PipelineWith(service.pipeline, compile_kernels=lambda: None)
            )
        try:
            service.start()
        finally:
            service.close()
        assert len(said()) == (1 if slow else 0), said()
