"""A read that holds several of a source's cycles (a byte stream read late: serial, a pty, TCP, on a busy
machine) is cut into its cycles, each stepped at the time it most likely arrived: spread back from the
read's time over the time since the sentence's previous arrival, at most its last period apart, never at
or before the observer's last step. Before, the read was used as one: every cycle but the last was
overwritten unstepped (measured in the demo on a loaded machine: up to 5 gyro cycles a read, 13 % of the
observer's steps lost)."""

from __future__ import annotations

import math
from datetime import UTC, datetime

from gateway.pipeline import Pipeline, RawEvent
from tests.test_pipeline import T0, S, gga_at, nmea_src, pipeline
from wire.codecs import nmea_encode as enc

MS = 1_000_000


def hdt(deg: float) -> bytes:
    return enc.hdt("HE", math.radians(deg)).encode()


def rot() -> bytes:
    return b"$HEROT,0.5,A*" + enc.checksum("HEROT,0.5,A").encode() + b"\r\n"


def gyro_and_gps() -> Pipeline:
    """A DGPS on UDP and a gyro on a serial line, 10 Hz each, 10 s of steady data: the observer runs."""
    p = pipeline([nmea_src("gps", ["position"]), nmea_src("gyro", ["heading"])])
    for k in range(100):
        p.feed(RawEvent(T0 + k * 100 * MS, "gps", gga_at(0.0, 0.0)))
        p.feed(RawEvent(T0 + k * 100 * MS + 5 * MS, "gyro", hdt(10.0) + rot()))
    assert p.observer.initialized
    return p


def steps(out: list) -> list[tuple[int, float]]:  # type: ignore[type-arg]
    """(stamp, measured heading in degrees) of every observer step among ``out``."""
    return [
        (o.stamp_ns, math.nan if o.message.eta[2] is None else math.degrees(o.message.eta[2]))
        for o in out
        if o.topic == "/dp/measurement"
    ]


def test_a_read_of_three_gyro_cycles_is_three_steps_a_period_apart() -> None:
    p = gyro_and_gps()
    last_gyro = T0 + 99 * 100 * MS + 5 * MS
    rx = last_gyro + 300 * MS  # the reader was held up for three of the gyro's cycles
    out = p.feed(RawEvent(rx, "gyro", hdt(11.0) + rot() + hdt(12.0) + rot() + hdt(13.0) + rot()))
    got = steps(out)
    assert [t for t, _ in got] == [rx - 200 * MS, rx - 100 * MS, rx]
    assert [round(h, 6) for _, h in got] == [11.0, 12.0, 13.0]
    assert p.counters["gyro"].received == 200 + 6


def test_a_burst_after_a_silence_is_spread_over_one_period_not_the_silence() -> None:
    p = gyro_and_gps()
    rx = T0 + 99 * 100 * MS + 5 * MS + 5 * S  # 5 s of nothing from the gyro, then two cycles at once
    got = steps(p.feed(RawEvent(rx, "gyro", hdt(11.0) + hdt(12.0))))
    assert [t for t, _ in got] == [rx - 100 * MS, rx]


def test_a_cycle_that_falls_before_the_last_step_goes_with_the_next() -> None:
    """The DGPS stepped the observer 40 ms before the read: the gyro's cycle spread back to 95 ms before
    the read has no time of its own after that step, and is used with the read's last cycle (as before)."""
    p = gyro_and_gps()
    last_gyro = T0 + 99 * 100 * MS + 5 * MS
    rx = last_gyro + 200 * MS
    p.feed(RawEvent(rx - 40 * MS, "gps", gga_at(0.0, 0.0)))
    got = steps(p.feed(RawEvent(rx, "gyro", hdt(11.0) + hdt(12.0))))
    assert [(t, round(h, 6)) for t, h in got] == [(rx, 12.0)]


def test_one_cycle_a_read_and_sentences_that_ride_with_a_cycle_are_not_cut() -> None:
    """A read of one cycle is one step at the read's time, whatever else it holds: several GST or wind
    sentences, a GGA beside a GNS of the same receiver."""
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    for k in range(10):
        p.feed(RawEvent(T0 + k * S, "gps", gga_at(0.0, 0.0)))
    gst = enc.gst(
        "GP", datetime(2026, 6, 1, tzinfo=UTC), rms_m=0.5, sigma_major_m=0.4, sigma_minor_m=0.2,
        orient_rad=0.3, sigma_lat_m=0.3, sigma_lon_m=0.3, sigma_alt_m=0.6,
    ).encode()  # fmt: skip
    got = steps(p.feed(RawEvent(T0 + 10 * S, "gps", gga_at(0.0, 0.0) + gst + gst)))
    assert [t for t, _ in got] == [T0 + 10 * S]


def test_the_first_read_of_a_source_is_not_spread() -> None:
    """Nothing came from the gyro before: there is no time to spread its cycles back over."""
    p = pipeline([nmea_src("gps", ["position"]), nmea_src("gyro", ["heading"])])
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0)))
    got = steps(p.feed(RawEvent(T0 + 50 * MS, "gyro", hdt(11.0) + hdt(12.0))))
    assert [(t, round(h, 6)) for t, h in got] == [(T0 + 50 * MS, 12.0)]
