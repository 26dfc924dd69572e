"""Wire encoders the simulator emits: NMEA 0183 sentences and the dpgw MAVLink dialect.

Checked with parsers that are not ours: pynmea2 for NMEA, pymavlink's generated ``MAVLink.parse_buffer``
for MAVLink, and pymavlink's mavgen/mavparse for the dialect itself.
"""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from datetime import UTC, datetime, time, timedelta
from pathlib import Path
from types import ModuleType

import numpy as np
import pynmea2
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from observers.kinematics import ssa_scalar as ssa
from wire.codecs import mavlink as mv
from wire.codecs import nmea_encode as nmea

REPO = Path(__file__).resolve().parent.parent

if "THS" not in pynmea2.TalkerSentence.sentence_types:
    # pynmea2 1.19 has no THS; registering a layout is pynmea2's own extension mechanism. The checksum and
    # field splitting are still pynmea2's.
    class THS(pynmea2.TalkerSentence):
        fields = (("Heading, degrees true", "heading", float), ("Mode indicator", "mode"))


def parse(text: str) -> pynmea2.NMEASentence:
    assert text.startswith("$") and text.endswith("\r\n")
    return pynmea2.parse(text.strip(), check=True)


def angle_diff_deg(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


def time_of_day_error_s(parsed: time, t: datetime) -> float:
    """Signed difference between a parsed time of day and ``t`` (modulo a day: GGA, GNS carry no date)."""
    got = parsed.hour * 3600 + parsed.minute * 60 + parsed.second + parsed.microsecond * 1e-6
    want = t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6
    return (got - want + 43200.0) % 86400.0 - 43200.0


# time: full days over 2000-2068 (two-digit RMC years as pynmea2 reads them), midnight and carries included
times = st.datetimes(
    min_value=datetime(2000, 1, 1), max_value=datetime(2068, 12, 31, 23, 59, 59, 994999)
).map(lambda t: t.replace(tzinfo=UTC))
lats = st.floats(min_value=-90.0, max_value=90.0, allow_nan=False)
lons = st.floats(min_value=-180.0, max_value=180.0, allow_nan=False)
angles = st.floats(min_value=-4 * math.pi, max_value=4 * math.pi, allow_nan=False)
MIDNIGHT = datetime(2024, 12, 31, 23, 59, 59, 995000, tzinfo=UTC)  # rounds to 2025-01-01 00:00:00.00
HALF_CENTISECOND = timedelta(microseconds=5001)  # half the printed resolution + pynmea2's float truncation

# ---------------------------------------------------------------------------------------------- framing


def test_checksum_of_the_classic_gga_example() -> None:
    body = "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
    assert nmea.checksum(body) == "47"
    assert nmea.sentence("GP", "HDT", ["274.07", "T"]) == "$GPHDT,274.07,T*03\r\n"
    assert float(parse(nmea.sentence("GP", "HDT", ["274.07", "T"])).heading) == 274.07


@given(body=st.text(alphabet=st.characters(min_codepoint=0, max_codepoint=127), max_size=400))
@example(body="")
@example(body="GPGGA," + "9" * 122)  # 128 bytes: the last length of the unrolled folds
@example(body="GPGGA," + "9" * 123)
def test_checksum_folds_equal_the_byte_loop(body: str) -> None:
    assert nmea.checksum(body) == nmea.checksum_reference(body)


@given(
    value=st.floats(allow_nan=False, allow_infinity=False) | st.floats(min_value=-1e3, max_value=1e3),
    decimals=st.integers(min_value=0, max_value=12),
)
@example(value=-0.0004, decimals=3)
@example(value=2.0005, decimals=3)
def test_fixed_point_fields_equal_format_specs(value: float, decimals: int) -> None:
    """The encoders' printf-style formats give the digits of Python's format spec ``.nf`` (never -0)."""
    text = f"{value:.{decimals}f}"
    expected = text[1:] if text.startswith("-") and text.strip("-0.") == "" else text
    assert nmea._fixed(value, decimals) == expected


@pytest.mark.parametrize(
    ("talker", "kind", "fields"),
    [("gp", "HDT", []), ("GPS", "HDT", []), ("GP", "HD", []), ("GP", "HDT", ["1*2"]), ("GP", "HDT", ["a,b"])],
)
def test_sentence_rejects_bad_addresses_and_reserved_characters(
    talker: str, kind: str, fields: list[str]
) -> None:
    with pytest.raises(ValueError):
        nmea.sentence(talker, kind, fields)


def test_corrupt_checksum_fails_pynmea2_check_and_changes_nothing_else() -> None:
    good = nmea.hdt("HE", 1.0)
    bad = nmea.corrupt_checksum(good)
    assert bad != good and bad[:-4] == good[:-4] and bad.endswith("\r\n")
    parse(good)
    with pytest.raises(pynmea2.ChecksumError):
        pynmea2.parse(bad.strip(), check=True)
    with pytest.raises(ValueError):
        nmea.corrupt_checksum("$HEHDT,1.0,T")


# ---------------------------------------------------------------------------------------------- position


@settings(max_examples=150, deadline=None)
@given(t=times, lat=lats, lon=lons)
@example(t=MIDNIGHT, lat=90.0, lon=180.0)
@example(t=MIDNIGHT, lat=-90.0, lon=-180.0)
@example(t=datetime(2024, 1, 1, tzinfo=UTC), lat=0.0, lon=0.0)
@example(t=datetime(2024, 1, 1, tzinfo=UTC), lat=-1e-12, lon=-1e-12)
@example(t=datetime(2024, 1, 1, tzinfo=UTC), lat=10 + 59.9999996 / 60, lon=-(179 + 59.9999999 / 60))
def test_gga_round_trips(t: datetime, lat: float, lon: float) -> None:
    text = nmea.gga("GP", t, lat, lon, 4, 14, 0.7, -12.345, 39.25, 1.5, 1023)
    msg = parse(text)
    assert abs(msg.latitude - lat) < 1e-7
    assert abs(angle_diff_deg(msg.longitude, lon)) < 1e-7
    assert msg.lat_dir in "NS" and msg.lon_dir in "EW"
    assert float(msg.lat[2:]) < 60.0 and float(msg.lon[3:]) < 60.0  # no 60-minute carry error
    assert abs(time_of_day_error_s(msg.timestamp, t)) <= 0.005001
    assert (msg.gps_qual, msg.num_sats, msg.horizontal_dil) == (4, "14", "0.70")
    assert (msg.altitude, float(msg.geo_sep), float(msg.age_gps_data), msg.ref_station_id) == (
        -12.345,
        39.25,
        1.5,
        "1023",
    )


def test_gga_without_fix_has_null_fields() -> None:
    msg = parse(nmea.gga("GN", MIDNIGHT, None, None, 0, 0, None, None))
    assert (msg.lat, msg.lon, msg.gps_qual, msg.altitude) == ("", "", 0, None)


def test_latlon_formatting_and_carry() -> None:
    text = nmea.gga("GP", MIDNIGHT, 63 + 25.8301234 / 60, -(10 + 59.9999996 / 60), 2, 8, 1.0, 5.0)
    fields = text.split(",")
    assert fields[2:6] == ["6325.830123", "N", "01100.000000", "W"]
    assert nmea.gga("GP", MIDNIGHT, 1.0, 2.0, 1, 8, 1.0, 5.0, decimals=8).split(",")[2] == "0100.00000000"
    assert nmea.gga("GP", MIDNIGHT, 0.0, 540.0, 1, 8, 1.0, 5.0).split(",")[4:6] == ["18000.000000", "W"]
    with pytest.raises(ValueError):
        nmea.gga("GP", MIDNIGHT, 90.5, 0.0, 1, 8, 1.0, 5.0)
    with pytest.raises(ValueError):
        nmea.gga("GP", MIDNIGHT, math.nan, 0.0, 1, 8, 1.0, 5.0)
    with pytest.raises(ValueError):
        nmea.gga("GP", MIDNIGHT, 0.0, 0.0, 9, 8, 1.0, 5.0)


@settings(max_examples=60, deadline=None)
@given(t=times, lat=lats, lon=lons, mode=st.sampled_from(["DD", "RR", "FF", "AAN", "NN", "DDDDDD"]))
@example(t=MIDNIGHT, lat=-90.0, lon=180.0, mode="RR")
def test_gns_round_trips(t: datetime, lat: float, lon: float, mode: str) -> None:
    msg = parse(nmea.gns("GN", t, lat, lon, mode, 21, 0.6, 12.5, 40.125, 2.0, 17, "S"))
    assert abs(msg.latitude - lat) < 1e-7
    assert abs(angle_diff_deg(msg.longitude, lon)) < 1e-7
    assert msg.mode_indicator == mode and msg.num_sats == "21"
    assert (float(msg.altitude), float(msg.geo_sep), float(msg.age_gps_data), msg.diferential) == (
        12.5,
        40.125,
        2.0,
        "0017",
    )
    assert msg.data[12] == "S"  # navigational status (NMEA 4.10), past pynmea2's known fields
    assert abs(time_of_day_error_s(msg.timestamp, t)) <= 0.005001


@settings(max_examples=150, deadline=None)
@given(
    t=times,
    lat=lats,
    lon=lons,
    sog=st.floats(min_value=0.0, max_value=30.0),
    cog=angles,
    valid=st.booleans(),
    var=st.floats(min_value=-0.5, max_value=0.5),
)
@example(t=MIDNIGHT, lat=0.0, lon=0.0, sog=0.0, cog=2 * math.pi - 1e-9, valid=True, var=0.0)
@example(
    t=datetime(2024, 2, 28, 23, 59, 59, 999999, tzinfo=UTC), lat=1, lon=1, sog=1, cog=0, valid=True, var=0
)
def test_rmc_round_trips_date_and_time_together(
    t: datetime, lat: float, lon: float, sog: float, cog: float, valid: bool, var: float
) -> None:
    msg = parse(nmea.rmc("GP", t, lat, lon, sog, cog, valid, "R", mag_var_rad=var))
    stamp = datetime.combine(msg.datestamp, msg.timestamp)
    assert abs(stamp - t) <= HALF_CENTISECOND  # the date follows a rounding carry past midnight
    assert abs(msg.latitude - lat) < 1e-7
    assert abs(angle_diff_deg(msg.longitude, lon)) < 1e-7
    assert msg.spd_over_grnd == pytest.approx(sog * 3600 / 1852, abs=0.0005 + 1e-12)
    assert 0.0 <= msg.true_course < 360.0
    assert abs(angle_diff_deg(msg.true_course, math.degrees(cog))) <= 0.005 + 1e-9
    assert msg.status == ("A" if valid else "V") and msg.mode_indicator == "R"
    signed_var = float(msg.mag_variation) * (1 if msg.mag_var_dir == "E" else -1)
    assert signed_var == pytest.approx(math.degrees(var), abs=0.05 + 1e-9)


def test_rmc_rejects_negative_speed_and_bad_mode() -> None:
    with pytest.raises(ValueError):
        nmea.rmc("GP", MIDNIGHT, 0.0, 0.0, -0.1, 0.0, True)
    with pytest.raises(ValueError):
        nmea.rmc("GP", MIDNIGHT, 0.0, 0.0, 0.1, 0.0, True, mode="X")


@settings(max_examples=80, deadline=None)
@given(cog=angles, sog=st.floats(min_value=0.0, max_value=50.0), var=st.floats(min_value=-0.5, max_value=0.5))
@example(cog=-1e-9, sog=0.0, var=0.0)
def test_vtg_round_trips(cog: float, sog: float, var: float) -> None:
    msg = parse(nmea.vtg("II", cog, sog, "D", mag_var_rad=var))
    assert abs(angle_diff_deg(msg.true_track, math.degrees(cog))) <= 0.005 + 1e-9
    assert abs(angle_diff_deg(float(msg.mag_track), math.degrees(cog - var))) <= 0.005 + 1e-9
    assert 0.0 <= msg.true_track < 360.0 and 0.0 <= float(msg.mag_track) < 360.0
    assert float(msg.spd_over_grnd_kts) == pytest.approx(sog * 3600 / 1852, abs=0.0005 + 1e-9)
    assert msg.spd_over_grnd_kmph == pytest.approx(sog * 3.6, abs=0.0005 + 1e-9)
    assert msg.faa_mode == "D"
    assert parse(nmea.vtg("GP", 1.0, 1.0)).mag_track is None  # no variation: null magnetic course


@settings(max_examples=60, deadline=None)
@given(
    t=times, sig=st.lists(st.floats(min_value=0.0, max_value=100.0), min_size=6, max_size=6), orient=angles
)
def test_gst_round_trips(t: datetime, sig: list[float], orient: float) -> None:
    text = nmea.gst(
        "GN",
        t,
        rms_m=sig[0],
        sigma_major_m=sig[1],
        sigma_minor_m=sig[2],
        orient_rad=orient,
        sigma_lat_m=sig[3],
        sigma_lon_m=sig[4],
        sigma_alt_m=sig[5],
    )
    msg = parse(text)
    got = [msg.rms, msg.std_dev_major, msg.std_dev_minor, msg.std_dev_latitude, msg.std_dev_longitude]
    assert got == pytest.approx(sig[:5], abs=0.0005 + 1e-9)
    assert msg.std_dev_altitude == pytest.approx(sig[5], abs=0.0005 + 1e-9)
    assert 0.0 <= msg.orientation < 180.0
    diff = (msg.orientation - math.degrees(orient) + 90.0) % 180.0 - 90.0  # an axis is defined mod 180°
    assert abs(diff) <= 0.05 + 1e-9


@settings(max_examples=80, deadline=None)
@given(t=times)
@example(t=MIDNIGHT)
@example(t=datetime(2023, 12, 31, 23, 59, 59, 994999, tzinfo=UTC))
def test_zda_round_trips(t: datetime) -> None:
    msg = parse(nmea.zda("GP", t))
    stamp = datetime.combine(msg.datestamp, msg.timestamp)
    assert abs(stamp - t) <= HALF_CENTISECOND
    assert (msg.local_zone, msg.local_zone_minutes) == (0, 0)


def test_time_formatting_precision_and_time_zones() -> None:
    t = datetime(2024, 6, 1, 12, 34, 56, 789012, tzinfo=UTC)
    assert nmea.zda("GP", t).split(",")[1] == "123456.79"
    assert nmea.zda("GP", t, time_decimals=3).split(",")[1] == "123456.789"
    assert nmea.zda("GP", t, time_decimals=0).split(",")[1] == "123457"
    assert nmea.zda("GP", t.replace(tzinfo=None)) == nmea.zda("GP", t)  # naive = UTC
    oslo = t.astimezone(__import__("zoneinfo").ZoneInfo("Europe/Oslo"))
    assert nmea.zda("GP", oslo) == nmea.zda("GP", t)
    assert nmea.zda("GP", MIDNIGHT).split(",")[1:5] == ["000000.00", "01", "01", "2025"]


# ---------------------------------------------------------------------------------------------- heading


@settings(max_examples=150, deadline=None)
@given(heading=angles, decimals=st.integers(min_value=1, max_value=4))
@example(heading=2 * math.pi, decimals=2)
@example(heading=2 * math.pi - 1e-7, decimals=2)
@example(heading=-1e-12, decimals=2)
@example(heading=0.0, decimals=1)
def test_hdt_and_ths_round_trip_to_resolution(heading: float, decimals: int) -> None:
    expected = math.degrees(heading)
    hdt = parse(nmea.hdt("HE", heading, decimals=decimals))
    assert 0.0 <= hdt.heading < 360.0 and hdt.hdg_true == "T"
    assert abs(angle_diff_deg(float(hdt.heading), expected)) <= 0.5 * 10**-decimals + 1e-9
    assert len(str(hdt.heading).split(".")[1]) == decimals
    ths = parse(nmea.ths("IN", heading, "E", decimals=decimals))
    assert 0.0 <= ths.heading < 360.0 and ths.mode == "E"
    assert abs(angle_diff_deg(ths.heading, expected)) <= 0.5 * 10**-decimals + 1e-9


def test_heading_360_prints_as_zero_and_null_heading() -> None:
    assert nmea.hdt("HE", math.radians(359.996)) == nmea.sentence("HE", "HDT", ["0.00", "T"])
    assert nmea.hdt("HE", math.radians(-0.001)) == nmea.sentence("HE", "HDT", ["0.00", "T"])
    assert nmea.ths("HE", None, "V") == nmea.sentence("HE", "THS", [None, "V"])
    with pytest.raises(ValueError):
        nmea.ths("HE", 1.0, "X")


@settings(max_examples=100, deadline=None)
@given(rate=st.floats(min_value=-1.0, max_value=1.0), valid=st.booleans())
@example(rate=-1e-9, valid=True)
@example(rate=0.0, valid=False)
def test_rot_round_trips_with_port_negative(rate: float, valid: bool) -> None:
    msg = parse(nmea.rot("HE", rate, valid))
    deg_per_min = math.degrees(rate) * 60.0
    assert float(msg.rate_of_turn) == pytest.approx(deg_per_min, abs=0.05 + 1e-9)
    assert msg.status == ("A" if valid else "V")
    assert msg.rate_of_turn != "-0.0"
    if deg_per_min < -0.05:
        assert msg.rate_of_turn.startswith("-")  # bow turning to port


@settings(max_examples=80, deadline=None)
@given(
    heading=angles, dev=st.floats(min_value=-0.3, max_value=0.3), var=st.floats(min_value=-0.5, max_value=0.5)
)
def test_hdg_round_trips(heading: float, dev: float, var: float) -> None:
    msg = parse(nmea.hdg("HC", heading, dev, var))
    assert abs(angle_diff_deg(float(msg.heading), math.degrees(heading))) <= 0.05 + 1e-9
    signed_dev = float(msg.deviation) * (1 if msg.dev_dir == "E" else -1)
    signed_var = float(msg.variation) * (1 if msg.var_dir == "E" else -1)
    assert signed_dev == pytest.approx(math.degrees(dev), abs=0.05 + 1e-9)
    assert signed_var == pytest.approx(math.degrees(var), abs=0.05 + 1e-9)
    assert parse(nmea.hdg("HC", heading)).deviation is None


# ---------------------------------------------------------------------------------------------- MAVLink


def f32(x: float) -> float:
    return float(np.float32(x))


def decode_one(frame: bytes, mav: mv.MAVLink | None = None) -> mv.MAVLinkMessage:
    """Decode with pymavlink's own parser (not our FrameParser)."""
    rx = mav if mav is not None else mv.dialect().MAVLink(None)
    msgs = rx.parse_buffer(frame)
    assert msgs is not None and len(msgs) == 1
    return msgs[0]


finite32 = st.floats(width=32, allow_nan=False, allow_infinity=False)


@settings(max_examples=100, deadline=None)
@given(
    time_usec=st.integers(min_value=0, max_value=2**64 - 1),
    tid=st.integers(min_value=0, max_value=255),
    thrust=finite32,
    rpm=finite32,
    azimuth=angles,
    flags=st.integers(min_value=0, max_value=2**32 - 1),
    extra=st.lists(finite32, min_size=4, max_size=4),
    fault=st.integers(min_value=0, max_value=2**16 - 1),
)
def test_azimuth_status_round_trips(
    time_usec: int,
    tid: int,
    thrust: float,
    rpm: float,
    azimuth: float,
    flags: int,
    extra: list[float],
    fault: int,
) -> None:
    tx = mv.encoder(7, 42)
    frame = mv.azimuth_status_frame(
        tx,
        time_usec,
        tid,
        thrust,
        rpm,
        azimuth,
        flags,
        thrust_setpoint_n=extra[0],
        azimuth_setpoint_rad=extra[1],
        azimuth_rate_rad_s=extra[2],
        power_w=extra[3],
        fault_code=fault,
    )
    msg = decode_one(frame)
    assert msg.get_type() == "AZIMUTH_THRUSTER_STATUS" and msg.get_msgId() == mv.AZIMUTH_THRUSTER_STATUS_ID
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == (7, 42)
    assert (msg.time_usec, msg.id, msg.flags, msg.fault_code) == (time_usec, tid, flags, fault)
    assert (msg.thrust, msg.rpm, msg.thrust_setpoint, msg.azimuth_rate, msg.power) == (
        thrust,
        rpm,
        extra[0],
        extra[2],
        extra[3],
    )
    wrapped = (azimuth + math.pi) % (2 * math.pi) - math.pi
    assert msg.azimuth == f32(wrapped)
    assert abs(math.remainder(msg.azimuth - azimuth, 2 * math.pi)) < 1e-6
    assert abs(math.remainder(msg.azimuth_setpoint - extra[1], 2 * math.pi)) < 1e-5 * max(1.0, abs(extra[1]))


@given(
    time_usec=st.integers(min_value=0, max_value=2**64 - 1),
    tid=st.integers(min_value=0, max_value=255),
    values=st.lists(st.one_of(finite32, st.just(0.0), st.just(math.nan)), min_size=6, max_size=6),
    flags=st.integers(min_value=0, max_value=2**32 - 1) | st.just(0),
    fault=st.integers(min_value=0, max_value=2**16 - 1) | st.just(0),
    seq=st.integers(min_value=0, max_value=255),
)
def test_azimuth_status_fast_packing_gives_the_librarys_bytes(
    time_usec: int, tid: int, values: list[float], flags: int, fault: int, seq: int
) -> None:
    """The status frame is packed without pymavlink's message object; the bytes, the sequence number and
    the link counters are what the library's own packing gives (trailing zero bytes dropped, one kept)."""
    fast, slow = mv.encoder(7, 42), mv.encoder(7, 42)
    fast.seq = slow.seq = seq
    thrust, rpm, azimuth, setpoint, az_setpoint, power = values
    args = (time_usec, tid, thrust, rpm, azimuth, flags)
    kwargs = {"thrust_setpoint_n": setpoint, "azimuth_setpoint_rad": az_setpoint, "power_w": power}
    frame = mv.azimuth_status_frame(fast, *args, fault_code=fault, **kwargs)  # type: ignore[arg-type]
    msg = mv.dialect().MAVLink_azimuth_thruster_status_message(
        time_usec=time_usec, id=tid, thrust=thrust, rpm=rpm, azimuth=ssa(azimuth), flags=flags,
        thrust_setpoint=setpoint, azimuth_setpoint=ssa(az_setpoint), azimuth_rate=math.nan, power=power,
        fault_code=fault,
    )  # fmt: skip
    assert frame == mv.pack(slow, msg)
    assert (fast.seq, fast.total_packets_sent, fast.total_bytes_sent) == (
        slow.seq,
        slow.total_packets_sent,
        slow.total_bytes_sent,
    )
    signed = mv.encoder(7, 42)
    mv.setup_signing(signed, bytes(32), initial_timestamp=1)  # signing: the library packs
    signed_frame = mv.azimuth_status_frame(signed, *args, fault_code=fault, **kwargs)  # type: ignore[arg-type]
    assert signed_frame[2] & 1 and len(signed_frame) == len(frame) + 13  # the signed flag and signature
    assert decode_one(signed_frame).id == tid


def test_azimuth_status_defaults_are_nan_and_flags_enum_matches_xml() -> None:
    flags = mv.AzimuthThrusterFlags.READY | mv.AzimuthThrusterFlags.RUNNING
    msg = decode_one(mv.azimuth_status_frame(mv.encoder(), 1, 3, 1000.0, 120.0, 0.5, flags))
    assert math.isnan(msg.thrust_setpoint) and math.isnan(msg.power) and msg.fault_code == 0
    assert mv.AzimuthThrusterFlags(msg.flags) == flags
    entries = mv.dialect().enums["DPGW_AZIMUTH_THRUSTER_FLAGS"]
    xml = {e.name.removeprefix("DPGW_AZIMUTH_THRUSTER_FLAGS_"): v for v, e in entries.items() if v < 2**31}
    xml.pop("ENUM_END", None)
    assert xml == {f.name: f.value for f in mv.AzimuthThrusterFlags}


@settings(max_examples=100, deadline=None)
@given(
    time_usec=st.integers(min_value=0, max_value=2**64 - 1),
    tid=st.integers(min_value=0, max_value=255),
    thrust=finite32,
    azimuth=angles,
    target=st.tuples(st.integers(0, 255), st.integers(0, 255)),
)
def test_azimuth_command_round_trips(
    time_usec: int, tid: int, thrust: float, azimuth: float, target: tuple[int, int]
) -> None:
    tx = mv.encoder(255, 191)
    frame = mv.azimuth_command_frame(
        tx, time_usec, tid, thrust, azimuth, target_system=target[0], target_component=target[1]
    )
    msg = decode_one(frame)
    assert msg.get_type() == "AZIMUTH_THRUSTER_COMMAND" and msg.get_msgId() == mv.AZIMUTH_THRUSTER_COMMAND_ID
    assert (msg.time_usec, msg.id, msg.thrust, msg.target_system, msg.target_component) == (
        time_usec,
        tid,
        thrust,
        *target,
    )
    assert msg.azimuth == f32((azimuth + math.pi) % (2 * math.pi) - math.pi)


def test_helpers_reject_out_of_range_integers() -> None:
    tx = mv.encoder()
    with pytest.raises(ValueError):
        mv.azimuth_status_frame(tx, 0, 256, 0.0, 0.0, 0.0, 0)
    with pytest.raises(ValueError):
        mv.azimuth_command_frame(tx, -1, 0, 0.0, 0.0)
    with pytest.raises(ValueError):
        mv.encoder(src_system=300)


def test_esc_telemetry_converts_to_wire_units_and_saturates() -> None:
    tx = mv.encoder()
    frame = mv.esc_telemetry_frame(
        tx,
        [1200.4, -800.0, 70000.0],
        temperature_degc=[45.2, -5.0, 300.0, 20.0],
        voltage_v=[48.3, 700.0],
        current_a=[12.34],
        consumed_c=[3600.0],
        count=[5, 65537],
    )
    msg = decode_one(frame)
    assert msg.get_type() == "ESC_TELEMETRY_1_TO_4"
    assert msg.rpm == [1200, 800, 65535, 0]  # unsigned on the wire: magnitude, saturated
    assert msg.temperature == [45, 0, 255, 20]
    assert msg.voltage == [4830, 65535, 0, 0]  # cV
    assert msg.current == [1234, 0, 0, 0]  # cA
    assert msg.totalcurrent == [1000, 0, 0, 0]  # mAh
    assert msg.count == [5, 1, 0, 0]
    assert decode_one(mv.esc_telemetry_frame(tx, [1.0], first_esc=29)).get_type() == "ESC_TELEMETRY_29_TO_32"
    with pytest.raises(ValueError):
        mv.esc_telemetry_frame(tx, [1.0], first_esc=2)
    with pytest.raises(ValueError):
        mv.esc_telemetry_frame(tx, [1.0] * 5)


def test_servo_output_raw_and_heartbeat() -> None:
    tx = mv.encoder(3, 1)
    pwm = [1100 + 50 * i for i in range(16)]
    msg = decode_one(mv.servo_output_raw_frame(tx, 2**32 + 17, pwm, port=1))
    assert msg.get_type() == "SERVO_OUTPUT_RAW" and (msg.time_usec, msg.port) == (17, 1)
    assert [getattr(msg, f"servo{i}_raw") for i in range(1, 17)] == pwm
    short = decode_one(mv.servo_output_raw_frame(tx, 5, [1500, 1600]))
    assert (short.servo1_raw, short.servo2_raw, short.servo3_raw, short.servo16_raw) == (1500, 1600, 0, 0)
    d = mv.dialect()
    hb = decode_one(mv.heartbeat_frame(tx))
    assert (hb.type, hb.autopilot, hb.system_status, hb.mavlink_version) == (
        d.MAV_TYPE_SURFACE_BOAT,
        d.MAV_AUTOPILOT_INVALID,
        d.MAV_STATE_ACTIVE,
        3,
    )
    hb = decode_one(
        mv.heartbeat_frame(tx, autopilot=d.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode=129, custom_mode=4)
    )
    assert (hb.autopilot, hb.base_mode, hb.custom_mode) == (d.MAV_AUTOPILOT_ARDUPILOTMEGA, 129, 4)


def test_frames_are_mavlink2_with_advancing_sequence() -> None:
    tx = mv.encoder(9, 10)
    frames = [mv.heartbeat_frame(tx) for _ in range(300)]
    assert all(f[0] == 0xFD for f in frames)
    assert [f[4] for f in frames[:3]] == [0, 1, 2] and frames[256][4] == 0  # seq wraps at 256
    assert (frames[0][5], frames[0][6]) == (9, 10)
    status = mv.azimuth_status_frame(tx, 1, 1, 1.0, 1.0, 1.0, 0)
    assert int.from_bytes(status[7:10], "little") == 0x445000


# ---------------------------------------------------------------------------------------------- parsing


def _sample_frames() -> list[bytes]:
    tx = mv.encoder(1, 1)
    return [
        mv.heartbeat_frame(tx),
        mv.azimuth_status_frame(tx, 123, 1, 5e4, 150.0, 0.3, 3),
        mv.azimuth_command_frame(tx, 124, 2, 6e4, -1.0),
        mv.esc_telemetry_frame(tx, [100.0, 200.0]),
        mv.servo_output_raw_frame(tx, 99, [1500] * 8),
    ]


def test_parse_frames_skips_noise_and_recovers_behind_stray_markers() -> None:
    frames = _sample_frames()
    corrupted = bytearray(frames[1])
    corrupted[12] ^= 0x40
    stray = bytes([0xFD, 0xFF, 0x00, 0, 0, 1, 1, 0x30, 0x2A, 0x00])  # claims a 267-byte frame
    unknown = bytes([0xFD, 0x10, 0x00, 0, 0, 1, 1, 0x01, 0x02, 0x03])  # unknown message id
    data = b"junk" + frames[0] + stray + frames[1] + bytes(corrupted) + unknown + frames[2] + b"\xfe\x05"
    data += frames[3] + frames[4] + frames[0][:9]
    parser = mv.FrameParser()
    msgs = parser.feed(data)
    msgs += parser.flush()
    assert [m.get_msgbuf() for m in msgs] == [frames[i] for i in (0, 1, 2, 3, 4)]
    assert parser.rejected["bad_crc"] >= 1 and parser.rejected["unknown_message"] >= 1
    assert parser.rejected["truncated"] >= 1 and parser.pending == 0 and parser.received == 5
    assert [m.get_msgbuf() for m in mv.parse_frames(data)] == [m.get_msgbuf() for m in msgs]


def test_frame_parser_is_streaming() -> None:
    frames = _sample_frames()
    data = b"".join(frames)
    parser = mv.FrameParser()
    got = [m.get_msgbuf() for i in range(len(data)) for m in parser.feed(data[i : i + 1])]
    assert got == frames and parser.pending == 0 and not parser.rejected


@settings(max_examples=60, deadline=None)
@given(
    order=st.lists(st.integers(0, 4), min_size=1, max_size=8),
    noise=st.lists(st.binary(max_size=40), min_size=9, max_size=9),
    chunk=st.integers(1, 64),
)
def test_frames_survive_arbitrary_noise(order: list[int], noise: list[bytes], chunk: int) -> None:
    frames = _sample_frames()
    sent = [frames[i] for i in order]
    data = b"".join(noise[i] + f for i, f in enumerate(sent)) + noise[-1]
    parser = mv.FrameParser()
    got: list[bytes] = []
    for i in range(0, len(data), chunk):
        got += [m.get_msgbuf() for m in parser.feed(data[i : i + chunk])]
    got += [m.get_msgbuf() for m in parser.flush()]
    it = iter(got)
    assert all(any(g == f for g in it) for f in sent)  # every frame sent comes out, in order


KEY = bytes(range(32))


def test_signed_frames_verify_with_the_right_key_only() -> None:
    tx = mv.encoder(1, 1)
    mv.setup_signing(tx, KEY, link_id=3, initial_timestamp=mv.signing_timestamp(1.7e9))
    unsigned_tx = mv.encoder(1, 1)
    frame = mv.azimuth_status_frame(tx, 1, 2, 3.0, 4.0, 0.5, 1)
    plain = mv.azimuth_status_frame(unsigned_tx, 1, 2, 3.0, 4.0, 0.5, 1)
    assert frame[2] & 0x01 and len(frame) == len(plain) + 13 and frame[-13] == 3

    rx = mv.encoder(255, 191)
    mv.setup_signing(rx, KEY, sign_outgoing=False, initial_timestamp=mv.signing_timestamp(1.7e9))
    (msg,) = mv.parse_frames(frame, rx)
    assert msg._signed and msg._link_id == 3 and msg.thrust == 3.0
    assert decode_one(frame).thrust == 3.0  # no key configured: pymavlink accepts without checking

    wrong = mv.encoder()
    mv.setup_signing(wrong, bytes(32), sign_outgoing=False)
    parser = mv.FrameParser(wrong)
    assert parser.feed(frame) == [] and parser.rejected == {"bad_signature": 1}

    replay = mv.FrameParser(rx)
    assert replay.feed(frame) == [] and replay.rejected == {"bad_signature": 1}  # timestamp already seen
    assert len(replay.feed(mv.azimuth_status_frame(tx, 2, 2, 3.0, 4.0, 0.5, 1))) == 1

    assert replay.feed(plain) == [] and replay.rejected["unsigned"] == 1
    lenient = mv.encoder()
    mv.setup_signing(lenient, KEY, allow_unsigned=True)
    assert len(mv.parse_frames(plain, lenient)) == 1

    with pytest.raises(ValueError):
        mv.setup_signing(mv.encoder(), b"short")


def test_forged_frame_cannot_poison_a_signed_stream() -> None:
    now = mv.signing_timestamp(1.7e9)
    forger, genuine = mv.encoder(1, 1), mv.encoder(1, 1)
    mv.setup_signing(forger, bytes(32), link_id=0, initial_timestamp=now + 10**9)  # wrong key, far future
    mv.setup_signing(genuine, KEY, link_id=0, initial_timestamp=now)
    rx = mv.encoder()
    mv.setup_signing(rx, KEY, sign_outgoing=False, initial_timestamp=now)
    parser = mv.FrameParser(rx)
    assert parser.feed(mv.heartbeat_frame(forger)) == [] and parser.rejected == {"bad_signature": 1}
    assert len(parser.feed(mv.heartbeat_frame(genuine))) == 1


# ---------------------------------------------------------------------------------------------- dialect


def _generator() -> ModuleType:
    path = REPO / "tools" / "generate_dialect.py"
    spec = importlib.util.spec_from_file_location("generate_dialect", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("generate_dialect", module)
    spec.loader.exec_module(module)
    return module


def test_dialect_xml_and_generated_module_agree() -> None:
    """Version independent: every message and enum of dpgw.xml is in the committed module as defined."""
    from pymavlink.generator import mavparse

    gen = _generator()
    xml = mavparse.MAVXML(str(gen.DIALECT_XML), mavparse.PROTOCOL_2_0)
    d = mv.dialect()
    assert {m.name for m in xml.message} == {"AZIMUTH_THRUSTER_STATUS", "AZIMUTH_THRUSTER_COMMAND"}
    for m in xml.message:
        cls = d.mavlink_map[m.id]
        assert cls.msgname == m.name and cls.fieldnames == m.fieldnames
        assert cls.crc_extra == m.crc_extra and cls.unpacker.size == m.wire_length
        assert 0xFFFF < m.id < 2**24  # outside the 16-bit space upstream allocates from
    for e in xml.enum:
        generated = {x.name: v for v, x in d.enums[e.name].items() if not x.name.endswith("_ENUM_END")}
        assert {x.name: x.value for x in e.entry} == generated


def test_regenerating_the_dialect_reproduces_the_committed_module() -> None:
    gen = _generator()
    committed = gen.GENERATED.read_text(encoding="utf-8")
    if gen.committed_version() != gen.pymavlink_version():
        pytest.skip(
            f"module generated with pymavlink {gen.committed_version()}, installed {gen.pymavlink_version()}:"
            " run python tools/generate_dialect.py"
        )
    assert gen.generate_text() == committed, "dpgw.xml changed: run python tools/generate_dialect.py"


def test_message_ids_are_unused_by_every_upstream_dialect() -> None:
    gen = _generator()
    used = set()
    for path in gen.upstream_xml_dir().glob("*.xml"):
        used |= {int(i) for i in re.findall(r'<message id="(\d+)"', path.read_text(encoding="utf-8"))}
    ours = {mv.AZIMUTH_THRUSTER_STATUS_ID, mv.AZIMUTH_THRUSTER_COMMAND_ID}
    assert ours == {0x445000, 0x445001} and not ours & used
    assert (0x445000 >> 8).to_bytes(2, "big") == b"DP"
