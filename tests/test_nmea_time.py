"""The one NMEA time-of-day parser (wire/codecs/nmea_time.py): values, the strict grammar, and agreement with
the encoder and the sentence-level readers that use it."""

from __future__ import annotations

from datetime import UTC, datetime
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gateway.logreaders import _sentence_time
from gateway.sources import nmea_time_of_day
from wire.codecs.nmea import Gga, decode
from wire.codecs.nmea_encode import checksum, zda
from wire.codecs.nmea_time import parse_time_of_day, time_of_day_or_none

fraction_digits = st.text(alphabet="0123456789", max_size=12)


@given(st.integers(0, 23), st.integers(0, 59), st.integers(0, 60), fraction_digits, st.booleans())
def test_value_is_the_exact_time_correctly_rounded(h: int, m: int, s: int, frac: str, point: bool) -> None:
    text = f"{h:02d}{m:02d}{s:02d}" + (f".{frac}" if point or frac else "")
    exact = h * 3600 + m * 60 + s + (Fraction(int(frac), 10 ** len(frac)) if frac else 0)
    got = parse_time_of_day(text)
    assert got is not None
    assert abs(Fraction(got) - exact) <= Fraction(2.0**-36)  # within an ulp or so of 86 400 (1.5e-11 s)
    assert got == h * 3600 + m * 60 + float(f"{s:02d}.{frac}" if frac else f"{s}")


@given(st.text(max_size=20))
def test_anything_else_is_a_value_error_never_another_exception(text: str) -> None:
    try:
        v = parse_time_of_day(text)
    except ValueError as e:
        assert repr(text) in str(e)  # the message names the field
        assert time_of_day_or_none(text) is None
        return
    assert (v is None) == (text == "")
    if v is not None:
        assert 0.0 <= v < 86_401.0
        assert text[:6].isascii() and text[:6].isdigit()


@pytest.mark.parametrize(
    "text",
    [
        "12345",  # too short
        "1234567",  # a digit too many, no point
        "12:34:56",
        "240000",  # hours
        "126000",  # minutes
        "123461",  # seconds past a leap second
        "+12345",  # float() would take these; a time field must not
        " 123456",
        "123456 ",
        "12_3456",
        "123456e0",
        "123456.5e1",
        "١٢٣٤٥٦",  # Arabic-Indic digits: str.isdigit() is true, not NMEA
    ],
)
def test_malformed_or_out_of_range_fields_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="time of day"):
        parse_time_of_day(text)


def test_forms_receivers_send() -> None:
    assert parse_time_of_day("") is None
    assert parse_time_of_day("000000") == 0.0
    assert parse_time_of_day("235959.99") == pytest.approx(86_399.99, abs=1e-9)
    assert parse_time_of_day("235960.5") == 86_400.5  # inside a leap second
    assert parse_time_of_day("123456.") == 12 * 3600 + 34 * 60 + 56


@given(st.datetimes(min_value=datetime(2000, 1, 1), max_value=datetime(2099, 12, 30)), st.integers(0, 6))
def test_encoder_and_parser_agree(t: datetime, decimals: int) -> None:
    t = t.replace(tzinfo=UTC)
    sentence = zda("GP", t, time_decimals=decimals)
    field = sentence.split(",")[1]
    midnight = t.replace(hour=0, minute=0, second=0, microsecond=0)
    got = parse_time_of_day(field)
    assert got is not None
    off = (got - (t - midnight).total_seconds()) % 86_400.0  # rounding may carry into the next day
    assert min(off, 86_400.0 - off) <= 0.5 * 10.0**-decimals + 1e-9


@given(st.integers(0, 23), st.integers(0, 59), st.integers(0, 59), st.text(alphabet="0123456789", max_size=4))
def test_every_reader_gives_the_parsers_value(h: int, m: int, s: int, frac: str) -> None:
    field = f"{h:02d}{m:02d}{s:02d}" + (f".{frac}" if frac else "")
    want = parse_time_of_day(field)
    body = f"GPGGA,{field},5924.04,N,01030.04,E,1,12,0.8,40.2,M,,,,"
    line = f"${body}*{checksum(body)}"
    assert nmea_time_of_day(f"{line}\r\n".encode()) == want  # the file source's pacing
    assert nmea_time_of_day(f"$GPGLL,4916.45,N,12311.12,W,{field}\r\n".encode()) == want  # last, no *hh
    assert _sentence_time(line)[0] == want  # the log reader's cycle clock
    gga = decode(line)
    assert isinstance(gga, Gga) and gga.time_s == want  # the sentence decoder
