"""A source whose reads keep coming with nothing good in them (every checksum bad: a corrupting link, a
wrong baud rate that still frames) is neither silent nor fresh: it is alarmed by what is wrong with it,
``source NAME: no valid data for X s (N rejected: reason n, ...)``, and the alarm clears when good input
comes back. Before, only the reference said "no data" while the source's age read 0.2 s."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

from gateway.config import parse_config
from gateway.foxglove_channels import AlarmChanges
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from wire.codecs import nmea_encode as enc

S = 1_000_000_000
T0 = datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC)


def pipeline() -> Pipeline:
    tables = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "dgps1", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position"],
             "timeout_s": 2.0},
            {"name": "gyro1", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["heading"]},
        ],
    }  # fmt: skip
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


def fix(k: int, corrupt: bool) -> bytes:
    t = T0 + timedelta(seconds=k / 2)
    line = enc.gga("GP", t, 59.4 + 1e-6 * (k % 7), 10.5, 2, 12, 0.8, 20.0)
    if corrupt:  # the checksum of another sentence
        line = line[:-4] + ("00" if line[-4:-2] != "00" else "11") + "\r\n"
    return line.encode()


def source_alarms(p: Pipeline, now: int) -> list[str]:
    return [a for a in p.status_message(now).alarms if isinstance(a, str) and a.startswith("source dgps1")]


def test_a_source_with_only_bad_input_is_alarmed_by_what_is_wrong_and_cleared_when_good() -> None:
    p = pipeline()
    rx = int(T0.timestamp() * S)
    states = []
    for k in range(60):  # 30 s at 2 Hz: good, 10 s of bad checksums only, good again
        now = rx + k * S // 2
        p.feed(RawEvent(now, "dgps1", fix(k, corrupt=20 <= k < 40)))
        p.feed(RawEvent(now + 1000, "gyro1", enc.hdt("HE", 0.5 + 0.001 * (k % 5)).encode()))
        states.append((k, source_alarms(p, now + 1000)))
    by_k = dict(states)
    assert all(not a for k, a in states if k < 20)
    (alarm,) = by_k[35]
    assert alarm.startswith("source dgps1: no valid data for ") and "rejected: bad_checksum" in alarm, alarm
    seconds = float(alarm.split("no valid data for ")[1].split(" s")[0])
    assert 7.0 <= seconds <= 8.0, alarm  # since the last good fix (k = 19): 8 s
    assert p.status_message(rx + 35 * S // 2).sources["dgps1"].age_s < 1.0  # its reads are fresh
    assert not by_k[45]  # good again
    # the first 4 s of bad input stay within the timeout: no alarm yet
    assert not by_k[22]


def test_reads_that_carry_good_input_with_tag_blocks_or_ais_raise_nothing() -> None:
    p = pipeline()
    rx = int(T0.timestamp() * S)
    for k in range(20):
        now = rx + k * S // 2
        data = b"!AIVDM,1,1,,A,13aEOK?P00PD2wVMdLDRhgvL289?,0*26\r\n" + fix(k, corrupt=False)
        p.feed(RawEvent(now, "dgps1", data))
        assert not source_alarms(p, now)


def test_a_cleared_alarm_says_how_long_it_was_up() -> None:
    """A replay's log has few statuses (at state changes): the alarm's own figures are those it was raised
    with, "dead reckoning for 0 s"; the cleared line says how long it was up."""
    changes = AlarmChanges()
    text = "estimate dead reckoning for 0 s: no usable position reference"
    assert changes.update([text], 10 * S) == ([text], [])
    assert changes.update([text.replace("0 s", "3 s")], 13 * S) == ([], [])  # the same alarm, still up
    assert changes.update([], 15_500_000_000) == ([], [text.replace("0 s", "3 s") + " (up 5.5 s)"])
    assert changes.update([text], 20 * S) == ([text], [])  # raised again: its own time
    assert changes.update([], 21 * S)[1] == [text + " (up 1.0 s)"]


def test_the_reference_of_a_source_whose_reads_are_all_refused_is_rejected_not_stale() -> None:
    """The same source, as a position reference: its reads kept coming and every one was refused by the
    decoder, yet the reference went `ok -> stale: no data for 2.0 s` while the status said `no valid data
    (3 rejected: ...)`, an alarm that sends the engineer to the cable. Now `rejected` with what its reads
    are refused for; `stale` is left for a source that falls silent, as the integrity rules say."""
    p = pipeline()
    rx = int(T0.timestamp() * S)
    events: list[str] = []

    def step(now: int, k: int, dgps: bool, corrupt: bool = False) -> None:
        out = p.feed(RawEvent(now, "dgps1", fix(k, corrupt))) if dgps else []
        out += p.feed(RawEvent(now + 1000, "gyro1", enc.hdt("HE", 0.5 + 0.001 * (k % 5)).encode()))
        if k % 2:  # (the gateway's status a second)
            p.status_message(now + 1000)
        # a state change's events go out at once, in a status of their own
        events.extend(e for o in out if o.topic == "/dp/status" for e in o.message.events if "dgps1" in e)

    for k in range(60):  # good, 10 s of bad checksums only, good again
        step(rx + k * S // 2, k, True, corrupt=20 <= k < 40)
    out = [e for e in events if "ok -> " in e]
    assert len(out) == 1 and "ok -> rejected: no valid data for 2." in out[0], events
    assert "its reads are refused (bad_checksum" in out[0], out
    assert not any("-> stale" in e for e in events), events
    # good again: in use at once (no value of it failed a test; readmitting held a source whose first
    # reads were garbage out of use for 5 s)
    assert events[-1].endswith("rejected -> ok"), events
    # silent (nothing read at all): stale, as before
    events.clear()
    for k in range(60, 70):
        step(rx + k * S // 2, k, False)
    assert any("-> stale: no data for" in e for e in events), events
