"""MRU attitude sentences, proprietary $PASHR and $PHTRO: the project's encoder round trip, dpgw's signs
(roll starboard down, pitch bow up), a real POS MV-style log line, pynmea2 as a second reader, and bad input
that becomes a counted reject, never an exception."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import pynmea2
import pytest
from conftest import nmea_line
from hypothesis import given
from hypothesis import strategies as st

from wire.codecs import nmea_encode as enc
from wire.codecs.nmea import (
    BAD_FIELD,
    BAD_FORMAT,
    PROPRIETARY_TYPES,
    REJECT_REASONS,
    UNSUPPORTED,
    Attitude,
    Reject,
    decode,
)

HALF_CENTI_DEG = math.radians(0.005) + 1e-12


line = nmea_line


def ok(text: str) -> Attitude:
    result = decode(text.rstrip("\r\n"))
    assert isinstance(result, Attitude), result
    return result


def rejected(text: str) -> Reject:
    result = decode(text)
    assert isinstance(result, Reject), result
    return result


roll = st.floats(min_value=-math.radians(60), max_value=math.radians(60))
pitch = st.floats(min_value=-math.radians(30), max_value=math.radians(30))


@given(
    phi=roll,
    theta=pitch,
    psi=st.floats(min_value=-math.pi, max_value=math.pi),
    heave=st.floats(min_value=-20.0, max_value=20.0),
    sigma=st.floats(min_value=0.0, max_value=math.radians(5.0)),
    ms=st.integers(min_value=0, max_value=86_399_999),
)
def test_pashr_round_trip(phi: float, theta: float, psi: float, heave: float, sigma: float, ms: int) -> None:
    t = datetime(2026, 6, 1, tzinfo=UTC) + timedelta(milliseconds=ms)
    s = ok(
        enc.pashr(
            t,
            phi,
            theta,
            heading_rad=psi,
            heave_up_m=heave,
            roll_sigma_rad=sigma,
            pitch_sigma_rad=sigma,
            heading_sigma_rad=sigma,
        )
    )
    assert s.kind == "PASHR" and s.talker == "" and s.valid
    assert s.time_s == pytest.approx(ms / 1000.0, abs=1e-6)
    assert s.roll_rad == pytest.approx(phi, abs=HALF_CENTI_DEG)
    assert s.pitch_rad == pytest.approx(theta, abs=HALF_CENTI_DEG)
    assert s.heading_rad is not None
    assert abs((s.heading_rad - psi + math.pi) % (2 * math.pi) - math.pi) <= HALF_CENTI_DEG
    assert s.heave_up_m == pytest.approx(heave, abs=0.005 + 1e-9)
    for got in (s.roll_sigma_rad, s.pitch_sigma_rad, s.heading_sigma_rad):
        assert got == pytest.approx(sigma, abs=math.radians(0.0005) + 1e-12)
    assert (s.aiding, s.imu) == (1, 1)


@given(phi=st.floats(min_value=-math.pi, max_value=math.pi), theta=st.floats(-math.pi / 2, math.pi / 2))
def test_phtro_round_trip(phi: float, theta: float) -> None:
    s = ok(enc.phtro(phi, theta))
    assert s.kind == "PHTRO" and s.valid and s.time_s is None and s.heading_rad is None
    assert s.roll_rad == pytest.approx(phi, abs=HALF_CENTI_DEG)
    assert s.pitch_rad == pytest.approx(theta, abs=HALF_CENTI_DEG)


def test_signs_of_each_sentence() -> None:
    """Starboard down and bow up are positive in dpgw, whatever the sentence says."""
    # PHTRO: M bow up, P bow down; T port up (= starboard down), B port down
    s = ok(line("PHTRO,2.00,M,3.00,T"))
    assert s.pitch_rad == pytest.approx(math.radians(2.0)) and s.roll_rad == pytest.approx(math.radians(3.0))
    s = ok(line("PHTRO,2.00,P,3.00,B"))
    assert s.pitch_rad == pytest.approx(math.radians(-2.0))
    assert s.roll_rad == pytest.approx(math.radians(-3.0))
    # the encoder writes the letters the decoder reads: starboard down → T, bow down → P
    assert enc.phtro(math.radians(3.0), math.radians(-2.0)) == line("PHTRO,2.00,P,3.00,T") + "\r\n"
    # PASHR: roll + port up (starboard down), pitch + bow up, heave + up: taken as they are
    s = ok(line("PASHR,204132.000,010.51,T,+00.39,-00.79,-00.84,0.151,0.075,0.555,1,0"))
    assert s.roll_rad == pytest.approx(math.radians(0.39)) and s.pitch_rad == pytest.approx(
        math.radians(-0.79)
    )
    assert s.heave_up_m == pytest.approx(-0.84) and s.heading_rad == pytest.approx(math.radians(10.51))
    assert s.time_s == pytest.approx(20 * 3600 + 41 * 60 + 32.0)


def test_pashr_agrees_with_pynmea2() -> None:
    """pynmea2 reads the attitude PASHR too (its ``ASHRATT``): the same numbers in degrees."""
    t = datetime(2026, 6, 1, 12, 30, 15, 250000, tzinfo=UTC)
    text = enc.pashr(t, math.radians(-1.27), math.radians(0.84), heading_rad=math.radians(231.5),
                     heave_up_m=0.42, roll_sigma_rad=math.radians(0.02), pitch_sigma_rad=math.radians(0.02),
                     heading_sigma_rad=math.radians(0.1))  # fmt: skip
    theirs = pynmea2.parse(text.strip())
    ours = ok(text)
    assert float(theirs.roll) == pytest.approx(math.degrees(ours.roll_rad or 0.0))
    assert float(theirs.pitch) == pytest.approx(math.degrees(ours.pitch_rad or 0.0))
    assert float(theirs.heave) == pytest.approx(ours.heave_up_m)
    assert float(theirs.true_heading) == pytest.approx(231.5)


def test_empty_fields_are_not_valid_and_not_rejects() -> None:
    s = ok(enc.phtro(None, None))
    assert not s.valid and s.roll_rad is None and s.pitch_rad is None
    s = ok(line("PASHR,120000.00,,,+1.00,,,,,,,"))
    assert not s.valid and s.roll_rad == pytest.approx(math.radians(1.0)) and s.heading_rad is None
    # a heading not marked T is not used; the attitude still is
    s = ok(line("PASHR,120000.00,12.0,,+1.00,-2.00,0.1"))
    assert s.valid and s.heading_rad is None and s.roll_sigma_rad is None


@pytest.mark.parametrize(
    ("body", "reason", "what"),
    [
        ("PHTRO,2.00,X,3.00,T", BAD_FIELD, "pitch"),
        ("PHTRO,2.00,M,3.00,S", BAD_FIELD, "roll"),
        ("PHTRO,-2.00,M,3.00,T", BAD_FIELD, "pitch"),  # a magnitude with a sign
        ("PHTRO,91.00,M,3.00,T", BAD_FIELD, "pitch"),
        ("PHTRO,2.00,M,181,T", BAD_FIELD, "roll"),
        ("PHTRO,nan,M,3.00,T", BAD_FIELD, "pitch"),
        ("PHTRO,2.00,M", BAD_FORMAT, "fields"),
        ("PASHR,1200,12.0,T,+1.00,-2.00,0.1,,,,,", BAD_FIELD, "time"),
        ("PASHR,120000.00,12.0,M,+1.00,-2.00,0.1", BAD_FIELD, "true flag"),
        ("PASHR,120000.00,12.0,T,+181.00,-2.00,0.1", BAD_FIELD, "roll"),
        ("PASHR,120000.00,12.0,T,+1.00,-92.00,0.1", BAD_FIELD, "pitch"),
        ("PASHR,120000.00,12.0,T,+1.00,-2.00,inf", BAD_FIELD, "heave"),
        ("PASHR,120000.00,12.0,T,+1.00,-2.00,0.1,-0.1,,", BAD_FIELD, "roll sigma"),
        ("PASHR,120000.00,12.0,T,+1.00,-2.00,0.1,0.1,0.1,0.1,12", BAD_FIELD, "aiding"),
        ("PASHR,120000.00,12.0", BAD_FORMAT, "fields"),
        ("PASHR,POS,0,10,123519.00", UNSUPPORTED, "PASHR,POS"),
        ("PASHR,ATT,123519.0,12.0,1.0,2.0", UNSUPPORTED, "PASHR,ATT"),
        ("PHTRX,2.00,M,3.00,T", UNSUPPORTED, "PHTRX"),
    ],
)
def test_bad_attitude_is_a_counted_reject(body: str, reason: str, what: str) -> None:
    r = rejected(line(body))
    assert r.reason == reason and what in r.detail, r


FIELD_TEXTS = ["", "+", "-", "1", "9", ".", "M", "P", "T", "B", "x", "nan", "1e3", "+00.39", "120000.00"]


@given(st.lists(st.sampled_from(FIELD_TEXTS), max_size=13), st.sampled_from(PROPRIETARY_TYPES))
def test_any_fields_decode_or_reject_never_raise(fields: list[str], address: str) -> None:
    result = decode(line(",".join([address, *fields])))
    if isinstance(result, Reject):
        assert result.reason in REJECT_REASONS and "decoder error" not in result.detail
    else:
        assert isinstance(result, Attitude)
        for angle in (result.roll_rad, result.pitch_rad):
            assert angle is None or (math.isfinite(angle) and abs(angle) <= math.pi)
        assert result.valid == (result.roll_rad is not None and result.pitch_rad is not None)


def test_encoder_refuses_what_cannot_be_sent() -> None:
    t = datetime(2026, 6, 1, tzinfo=UTC)
    with pytest.raises(ValueError, match="pitch"):
        enc.pashr(t, 0.0, math.radians(95.0))
    with pytest.raises(ValueError, match="finite"):
        enc.phtro(math.nan, 0.0)
    with pytest.raises(ValueError, match="PHTRO"):
        enc.phtro(0.0, math.radians(100.0))
