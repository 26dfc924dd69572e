"""Keelson output: whether the estimate has settled, on ``log_message``.

A real pipeline's estimates (GGA + HDT fed with their receive times, the observer's own settle clock) go
through the sink onto a loopback Zenoh session; a Keelson consumer decodes the envelopes with the keelson
package and reads, in the log, the estimate settling (WARNING, ``settled=false``, ``settle_s_left`` the
settle time) at the first estimate and settled (INFO, ``settled=true``, ``settle_s_left=0``) at the first
settled one, and nothing between; a restart of the settle clock is said again.
"""

from __future__ import annotations

import re
import socket
from pathlib import Path
from typing import Any

import msgspec
import pytest

keelson = pytest.importorskip("keelson")

from gateway.outputs.keelson import KeelsonSink  # noqa: E402
from gateway.pipeline import Output, RawEvent  # noqa: E402
from tests.conftest import free_port, gga_hdt_chunk, settling_bench, wait_for  # noqa: E402
from tests.test_keelson import BASE, ENTITY, LAT, LON, Listener, tables  # noqa: E402
from wire.messages import Estimate  # noqa: E402

S = 1_000_000_000
T0 = 1_780_000_000 * S
SETTLE_TEXT = re.compile(r"^estimate (settling|settled) \(settled=(true|false), settle_s_left=([0-9.]+)\)$")


def test_a_keelson_consumer_reads_when_the_estimate_settles(
    tmp_path: Path, loopback_sessions: tuple[int, Any, Any]
) -> None:
    zport, server, client = loopback_sessions
    config, pipeline, sink, settle_s = settling_bench(tables(free_port(socket.SOCK_DGRAM), zport), tmp_path)
    assert isinstance(sink, KeelsonSink)
    log_source = config.keelson.log_source_id
    listener = Listener(client)

    def lines() -> list[tuple[int, int, str]]:
        got = listener.of("log_message", log_source)
        return [
            (m.timestamp.ToNanoseconds(), m.level, m.message) for m in got if SETTLE_TEXT.match(m.message)
        ]

    try:
        sink.start(server)
        assert wait_for(
            lambda: len(list(client.liveliness().get(f"{BASE}/@v0/{ENTITY}/pubsub/*/{log_source}"))) == 1
        )
        # the listener's subscription must have reached the sink's session before the first estimate's
        # line goes out (a put made before is sent to nobody): a probe publisher there says when
        log_key = keelson.construct_pubsub_key(BASE, ENTITY, "log_message", log_source)
        probe = server.declare_publisher(log_key)
        try:
            assert wait_for(lambda: probe.matching_status.matching)
        finally:
            probe.undeclare()
        estimates: list[Estimate] = []
        for k in range(int((settle_s + 4.0) * 10)):  # until 4 s past the settle time, at 10 Hz
            out = pipeline.feed(RawEvent(T0 + k * S // 10, "dgps1", gga_hdt_chunk(k, LAT, LON)))
            estimates += [o.message for o in out if o.topic == "/dp/estimate"]  # type: ignore[misc]
            sink.emit(out, [])
        assert wait_for(lambda: len(lines()) >= 2, 10.0), lines()
        # the observer starts again (its settle clock with it): said again, with the time left
        last = estimates[-1]
        again = msgspec.structs.replace(
            last, stamp_ns=last.stamp_ns + S // 10, settled=False, settle_s_left=settle_s
        )
        sink.emit([Output("/dp/estimate", again, again.stamp_ns)], [])
        assert wait_for(lambda: len(lines()) >= 3, 10.0), lines()
        got = lines()
    finally:
        sink.close()
    first, flip = estimates[0], next(e for e in estimates if e.settled)
    assert first.settled is False and first.settle_s_left == pytest.approx(settle_s, abs=1e-6)
    Log = type(listener.of("log_message", log_source)[0])
    assert len(got) == 3
    parsed = []
    for stamp, level, text in got:
        m = SETTLE_TEXT.match(text)
        assert m is not None
        word, settled, left = m.group(1), m.group(2) == "true", float(m.group(3))
        assert (word == "settled") == settled
        assert level == (Log.INFO if settled else Log.WARNING)
        parsed.append((stamp, settled, left))
    # settling at the first estimate, with the whole settle time left; settled at the first settled one
    assert parsed[0][0] == first.stamp_ns and parsed[0][1] is False
    assert parsed[0][2] == pytest.approx(settle_s, abs=0.05) and parsed[0][2] > 0.0
    assert parsed[1] == (flip.stamp_ns, True, 0.0)
    assert flip.settle_s_left == 0.0
    assert parsed[2][0] == again.stamp_ns and parsed[2][1] is False
    assert parsed[2][2] == pytest.approx(settle_s, abs=0.05)
    # one line per change, not one per estimate (the log's other lines are the status's: state changes)
    all_lines = [m.message for m in listener.of("log_message", log_source)]
    assert [text for text in all_lines if "settl" in text] == [text for _, _, text in got]
