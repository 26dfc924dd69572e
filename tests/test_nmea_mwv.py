"""NMEA MWV (wind speed and angle, an anemometer): the project's encoder round trip, units, status,
and bad input that becomes a counted reject, never an exception."""

from __future__ import annotations

import math

import pytest
from conftest import nmea_line
from hypothesis import given
from hypothesis import strategies as st

from wire.codecs import nmea_encode as enc
from wire.codecs.nmea import BAD_FIELD, BAD_FORMAT, MPS_PER_UNIT, REJECT_REASONS, Mwv, Reject, decode

line = nmea_line


def ok(text: str) -> Mwv:
    result = decode(text.rstrip("\r\n"))
    assert isinstance(result, Mwv), result
    return result


def angle_diff(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


@given(
    angle=st.floats(min_value=-4 * math.pi, max_value=4 * math.pi, allow_nan=False),
    speed=st.floats(min_value=0.0, max_value=80.0),
    reference=st.sampled_from("RT"),
    unit=st.sampled_from("KMNS"),
    valid=st.booleans(),
    decimals=st.integers(min_value=1, max_value=3),
    talker=st.sampled_from(["WI", "II", "IN", "YX"]),
)
def test_mwv_round_trip(
    angle: float, speed: float, reference: str, unit: str, valid: bool, decimals: int, talker: str
) -> None:
    s = ok(enc.mwv(talker, angle, speed, reference, unit, valid, decimals=decimals))
    assert s.kind == "MWV" and s.talker == talker and s.reference == reference and s.valid == valid
    assert s.angle_rad is not None and -math.pi <= s.angle_rad < math.pi
    assert angle_diff(s.angle_rad, angle) <= math.radians(0.5 * 10**-decimals) + 1e-12
    assert s.speed_mps is not None
    # the speed went out in `unit` at `decimals`: back in m/s within half a digit of that unit
    assert abs(s.speed_mps - speed) <= 0.5 * 10**-decimals * MPS_PER_UNIT[unit] + 1e-9


def test_mwv_units_and_fields() -> None:
    s = ok(line("WIMWV,90.0,R,10.0,N,A"))
    assert s.angle_rad == pytest.approx(math.pi / 2)
    assert s.speed_mps == pytest.approx(10.0 * 1852 / 3600)
    assert ok(line("WIMWV,270,T,36.0,K,A")).speed_mps == pytest.approx(10.0)
    assert ok(line("WIMWV,270,T,36.0,K,A")).angle_rad == pytest.approx(-math.pi / 2)
    assert ok(line("WIMWV,0,R,10,S,A")).speed_mps == pytest.approx(4.4704)
    assert ok(line("WIMWV,359.9,R,7.5,M,A")).angle_rad == pytest.approx(math.radians(-0.1))
    assert ok(line("WIMWV,360.0,R,7.5,M,A")).angle_rad == pytest.approx(0.0, abs=1e-12)


def test_mwv_void_and_empty_are_not_valid() -> None:
    assert not ok(line("WIMWV,45.0,R,12.0,M,V")).valid
    empty = ok(line("WIMWV,,R,,M,A"))
    assert not empty.valid and empty.angle_rad is None and empty.speed_mps is None
    no_status = ok(line("WIMWV,45.0,R,12.0,M"))  # an old talker without the status field
    assert not no_status.valid and no_status.speed_mps == pytest.approx(12.0)
    assert not ok(line("WIMWV,45.0,,12.0,M,A")).valid  # no reference: not usable


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("WIMWV,45.0,R,12.0,M,X", "status"),
        ("WIMWV,45.0,R,12.0,M,AA", "status"),
        ("WIMWV,45.0,Q,12.0,M,A", "reference"),
        ("WIMWV,45.0,R,12.0,F,A", "wind speed"),
        ("WIMWV,45.0,R,12.0,,A", "wind speed"),
        ("WIMWV,45.0,R,-3.0,M,A", "wind speed"),
        ("WIMWV,45.0,R,nan,M,A", "wind speed"),
        ("WIMWV,45.0,R,1e999,M,A", "wind speed"),
        ("WIMWV,361.0,R,12.0,M,A", "wind angle"),
        ("WIMWV,-5,R,12.0,M,A", "wind angle"),
        ("WIMWV,abc,R,12.0,M,A", "wind angle"),
    ],
)
def test_mwv_bad_fields_are_rejects(body: str, field: str) -> None:
    result = decode(line(body))
    assert isinstance(result, Reject) and result.reason == BAD_FIELD, result
    assert f"MWV {field}" in result.detail


def test_mwv_too_few_fields() -> None:
    result = decode(line("WIMWV,45.0,R,12.0"))
    assert isinstance(result, Reject) and result.reason == BAD_FORMAT


@given(
    address=st.sampled_from(["WIMWV", "IIVWR"]),
    fields=st.lists(st.text(alphabet="0123456789.-+eEAVRTKMNSLX ", max_size=8), min_size=0, max_size=9),
)
def test_mwv_any_fields_decode_or_reject_without_raising(address: str, fields: list[str]) -> None:
    result = decode(line(",".join([address, *fields])))
    if isinstance(result, Reject):
        assert result.reason in REJECT_REASONS and "decoder error" not in result.detail
    else:
        assert isinstance(result, Mwv)
        if result.valid:
            assert result.speed_mps is not None and result.speed_mps >= 0 and math.isfinite(result.speed_mps)
            assert result.angle_rad is not None and -math.pi <= result.angle_rad < math.pi


def test_encoder_refuses_bad_arguments() -> None:
    with pytest.raises(ValueError):
        enc.mwv("WI", 0.0, 1.0, reference="X")
    with pytest.raises(ValueError):
        enc.mwv("WI", 0.0, 1.0, unit="F")
    with pytest.raises(ValueError, match="wind speed cannot be negative"):
        enc.mwv("WI", 0.0, -1.0)


def test_vwr_is_the_same_relative_wind() -> None:
    starboard = ok(line("IIVWR,40.0,R,20.0,N,10.3,M,37.1,K"))
    assert starboard.kind == "VWR" and starboard.reference == "R" and starboard.valid
    assert starboard.angle_rad == pytest.approx(math.radians(40.0)) and starboard.speed_mps == pytest.approx(
        10.3
    )
    port = ok(line("IIVWR,120.5,L,20.0,N,,M,,K"))
    assert port.angle_rad == pytest.approx(math.radians(-120.5))
    assert port.speed_mps == pytest.approx(20.0 * 1852 / 3600)
    assert ok(line("IIVWR,180.0,L,,N,,M,36.0,K")).speed_mps == pytest.approx(10.0)
    assert ok(line("IIVWR,180.0,L,,N,,M,36.0,K")).angle_rad == pytest.approx(-math.pi)
    assert not ok(line("IIVWR,,,,N,,M,,K")).valid
    bad = [
        ("IIVWR,190.0,R,1,N,,M,,K", "wind angle and side"),
        ("IIVWR,10.0,X,1,N,,M,,K", "wind angle and side"),
        ("IIVWR,10.0,L,-1,N,,M,,K", "speed knots"),
    ]
    for body, name in bad:
        result = decode(line(body))
        assert isinstance(result, Reject) and result.reason == BAD_FIELD and f"VWR {name}" in result.detail
