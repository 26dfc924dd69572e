"""Replay's fast NMEA text reader (compiled line scan) against the readable reference, line for line.

The fast path must be invisible: the same events (time, bytes), the same counts, and the same pipeline
outputs as `nmea_text_events_reference` + the framer + the decoder, on real logs and on generated logs
full of damage (hypothesis), for any block size.
"""

from __future__ import annotations

import dataclasses
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gateway.logreaders import LogCounts, nmea_text_events, nmea_text_events_reference
from gateway.pipeline import USED_NMEA, Pipeline, PipelineSpec
from gateway.replay import build_config, open_inputs
from wire.codecs.nmea_encode import checksum
from wire.codecs.nmea_scan import CLEAN, DIRTY, TIME_ASK, TIME_NONE, TIME_OK, scan_lines, used_codes
from wire.codecs.nmea_time import time_of_day_or_none

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def both(path: Path, block_bytes: int, only: frozenset[str] | None = USED_NMEA) -> tuple[Any, Any]:
    c_ref, c_fast = LogCounts(), LogCounts()
    ref = list(nmea_text_events_reference(path, "gps", counts=c_ref))
    fast = list(nmea_text_events(path, "gps", counts=c_fast, only=only, block_bytes=block_bytes))
    return (ref, c_ref), (fast, c_fast)


def assert_same(ref: Any, fast: Any) -> None:
    (er, cr), (ef, cf) = ref, fast
    assert [(e.rx_ns, e.source, e.data) for e in ef] == [(e.rx_ns, e.source, e.data) for e in er]
    assert (cf.lines, cf.cycles, dict(cf.counts)) == (cr.lines, cr.cycles, dict(cr.counts))


def pipeline_outputs(path: Path, events: list[Any]) -> list[tuple[str, Any]]:
    config = build_config(open_inputs([path]), vessel="cybership2")
    pipeline = Pipeline(PipelineSpec.from_config(config))
    name = next(iter(pipeline.sources))
    out = []
    for ev in events:
        out.extend((o.topic, o.payload) for o in pipeline.feed(dataclasses.replace(ev, source=name)))
    status = pipeline.status(pipeline.last_ns).payload
    return [*out, ("counters", status["sources"][name])]


REAL_LOGS = sorted((DATA / "usv-nmea").glob("*.txt")) + sorted((DATA / "gpsd-logs").glob("*.log"))


@pytest.mark.parametrize("path", REAL_LOGS, ids=lambda p: p.name)
def test_real_logs_same_events_counts_and_outputs(path: Path) -> None:
    for block in (1 << 22, 777):
        ref, fast = both(path, block)
        assert_same(ref, fast)
    assert any(e.checked is not None for e in fast[0])  # the fast path was taken
    outputs_fast = pipeline_outputs(path, fast[0])
    outputs_ref = pipeline_outputs(path, [dataclasses.replace(e, checked=None) for e in fast[0]])
    assert outputs_fast == outputs_ref


# --- generated logs ---------------------------------------------------------------------------------------


def sentence(body: str) -> str:
    return f"${body}*{checksum(body)}"


@st.composite
def times(draw: Any) -> str:
    kind = draw(st.integers(0, 10))
    if kind == 10:  # anything a damaged field may hold (no comma, star or line end: those end the field)
        return draw(st.text(alphabet="0123456789.+-e_: aA\x7f", max_size=18))
    h, m, s = draw(st.integers(0, 23)), draw(st.integers(0, 59)), draw(st.integers(0, 60))
    if kind == 0:
        return ""
    if kind == 1:
        return draw(st.sampled_from(["12345", "123456.", "1234567", "12:34:56", "99", "1234ab.00", "235961"]))
    if kind == 2:
        return f"{h:02d}{m:02d}{s:02d}"
    digits = draw(st.integers(1, 9))
    frac = draw(st.integers(0, 10**digits - 1))
    return f"{h:02d}{m:02d}{s:02d}.{frac:0{digits}d}"


@st.composite
def damaged_log(draw: Any) -> bytes:
    """Cycles of GGA/RMC/HDT/VTG/ZDA/GLL/ROT with times stepping (sometimes backwards, across midnight,
    repeated), and every kind of damage a serial line or a logger produces."""
    lines: list[str] = []
    tod = draw(st.integers(0, 86_399))
    for _ in range(draw(st.integers(1, 25))):
        step = draw(st.sampled_from([0.1, 0.2, 1.0, 0.0, -1.0, 7.0, 43_300.0, -50_000.0]))
        tod = (tod + step) % 86_400
        h, rem = divmod(tod, 3600)
        m, s = divmod(rem, 60)
        t = f"{int(h):02d}{int(m):02d}{s:05.2f}" if draw(st.booleans()) else draw(times())
        body = [
            f"GPGGA,{t},5924.041169,N,01030.045537,E,{draw(st.sampled_from('0124'))},12,0.8,40.2,M,,,,",
            f"GPRMC,{t},A,5924.041169,N,01030.045537,E,0.1,21.5,{draw(st.sampled_from(['010326', '']))},,,D",
            f"HEHDT,{draw(st.floats(0, 359.99)):.2f},T",
            "GNVTG,85.0,T,88.4,M,0.05,N,0.09,K,D",
            f"GPZDA,{t},01,03,2026,00,00",
            f"GPGLL,5924.04,N,01030.04,E,{t},A",
            "TIROT,-0.3,A",
            "PSXN,23,0.02,-0.01,21.5,0.1",
            f"GPGNS,{t},5924.04,N,01030.04,E,DD,12,0.8,40.2,,,",
            "GPGST,100319.90,1.2,0.5,0.4,30.0,0.3,0.3,0.6",
        ]
        for b in draw(st.lists(st.sampled_from(body), min_size=1, max_size=6)):
            line = sentence(b)
            damage = draw(st.integers(0, 14))
            if damage == 1:
                line = line[: draw(st.integers(0, len(line)))]  # truncated
            elif damage == 2:
                k = draw(st.integers(1, len(line) - 1))
                line = (
                    line[:k] + draw(st.sampled_from(["X", "$", "!", "\x07", "é", "*", ","])) + line[k + 1 :]
                )
            elif damage == 3:
                line = line.rsplit("*", 1)[0]  # no checksum
            elif damage == 4:
                line = line[:-2] + line[-2:].lower()  # lower-case checksum (still good)
            elif damage == 5:
                line = line + "," * 200  # overlong
            elif damage == 6:
                line = "garbage\x00\xff" + line
            elif damage == 7:
                lines.append(line)  # duplicate
            elif damage == 8:
                lines.append("")  # blank line
            elif damage == 9:
                line = "!AIVDM,1,1,,A,13aEOK?P00PD2wVMdLDRhgvL289?,0*26"
            lines.append(line)
    eols = draw(st.lists(st.sampled_from(["\r\n", "\n", "\r\r\n", "\n\r\n"]), min_size=1, max_size=3))
    text = "".join(line + eols[k % len(eols)] for k, line in enumerate(lines))
    if draw(st.booleans()):
        text = text.rstrip("\r\n")  # no final line end
    return text.encode("utf-8", "surrogateescape")


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(damaged_log(), st.sampled_from([64, 200, 1 << 20]), st.booleans())
def test_damaged_logs_same_events_counts_and_outputs(
    tmp_path: Path, data: bytes, block: int, with_only: bool
) -> None:
    path = tmp_path / "log.nmea"
    path.write_bytes(data)
    ref, fast = both(path, block, USED_NMEA if with_only else None)
    assert_same(ref, fast)
    if fast[0]:
        outputs_fast = pipeline_outputs(path, fast[0])
        outputs_ref = pipeline_outputs(path, [dataclasses.replace(e, checked=None) for e in fast[0]])
        assert outputs_fast == outputs_ref


# --- the kernel's own decisions ---------------------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(times())
def test_time_of_day_is_exactly_the_readable_parsers(t: str) -> None:
    line = sentence(f"GPGGA,{t},5924.04,N,01030.04,E,1,12,0.8,40.2,M,,,,").encode()
    scan = scan_lines(np.frombuffer(line, np.uint8), b"", used_codes(USED_NMEA), 180)
    expected = time_of_day_or_none(t)
    if scan.time_status[0] == TIME_OK:
        assert scan.tod[0] == expected  # exact, not approximately
    elif scan.time_status[0] == TIME_NONE:
        assert expected is None
    else:
        assert scan.time_status[0] == TIME_ASK  # undecided is allowed, a wrong answer is not


def test_clean_and_dirty_lines() -> None:
    good = sentence("GPGGA,100319.90,5924.041169,N,01030.045537,E,2,12,0.80,40.290,M,,,2.0,0001")
    lines = [
        good,
        good[:-1] + ("0" if good[-1] != "0" else "1"),  # bad checksum
        good[:20],  # truncated
        sentence("HEHDT,21.52,T"),
        sentence("GNVTG,85.0,T,88.4,M,0.05,N,0.09,K,D"),
        sentence("PSXN,23,0.02"),
        "",
    ]
    data = "\r\n".join(lines).encode()
    scan = scan_lines(np.frombuffer(data, np.uint8), b"", used_codes(USED_NMEA), 180)
    assert scan.kind.tolist()[:6] == [CLEAN, DIRTY, DIRTY, CLEAN, CLEAN, CLEAN]
    assert scan.used.tolist()[:6] == [True, False, False, True, False, True]  # proprietary: always decoded
    assert scan.time_status[0] == TIME_OK and scan.tod[0] == pytest.approx(36199.9)


def test_long_day_of_lines_crosses_blocks_with_cycles_intact(tmp_path: Path) -> None:
    base = date(2026, 3, 1)
    assert base  # the date comes from RMC; here there is none: the default date is used
    lines = []
    for k in range(3000):
        tod = 86_390 + k * 0.1
        h, rem = divmod(tod % 86_400, 3600)
        m, s = divmod(rem, 60)
        t = f"{int(h):02d}{int(m):02d}{s:05.2f}"
        lines += [sentence(f"GPGGA,{t},5924.04,N,01030.04,E,1,12,0.8,40.2,M,,,,"), sentence("HEHDT,1.0,T")]
    path = tmp_path / "midnight.nmea"
    path.write_text("\r\n".join(lines) + "\r\n")
    for block in (100, 4096, 1 << 22):
        assert_same(*both(path, block))


def test_non_ascii_timed_line_is_not_fatal(tmp_path: Path) -> None:
    """Found by the generated logs: a timed sentence with a non-ASCII byte crashed the reference reader."""
    good = sentence("GPGGA,000000.20,5924.04,N,01030.04,E,1,12,0.8,40.2,M,,,,")
    path = tmp_path / "log.nmea"
    path.write_bytes(f"{good}\r\n".encode() + b"$GPGGA\xc3\xa9000000.30,5924.04,N*03\r\n" + good.encode())
    assert_same(*both(path, 1 << 20))
    assert len(list(nmea_text_events_reference(path))) == 1
