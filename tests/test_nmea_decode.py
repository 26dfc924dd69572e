"""NMEA 0183 framing and decoding: real receiver logs, the project's encoder, pynmea2, and fuzzing.

Real data is read from ``../shared/data`` beside the clone (gpsd's test logs, BSD-2-Clause; the USV logs
have no licence and are never copied into the repository); those tests skip when it is absent.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections import Counter
from datetime import UTC, date, datetime, timedelta
from pathlib import Path

import pynmea2
import pytest
from conftest import nmea_line
from hypothesis import example, given, settings
from hypothesis import strategies as st

from wire.codecs import nmea_encode as enc
from wire.codecs.nmea import (
    BAD_CHECKSUM,
    BAD_FIELD,
    BAD_FORMAT,
    NO_CHECKSUM,
    REJECT_REASONS,
    SENTENCE_TYPES,
    UNSUPPORTED,
    Attitude,
    Gga,
    Gns,
    Gst,
    Heading,
    Mwv,
    Reject,
    Rmc,
    Rot,
    Sentence,
    Vtg,
    Zda,
    _new_gga,
    _xor,
    decode,
)
from wire.codecs.nmea_framing import (
    AIS,
    COMMENT,
    FRAME_REASONS,
    GARBAGE,
    MAX_CHUNK,
    NON_ASCII,
    OVERLONG,
    TRUNCATED,
    Frame,
    NmeaFramer,
)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def frames_of(
    data: bytes, cuts: list[int] | None = None, max_length: int = 180, fast_path: bool = True
) -> list[Frame]:
    """All frames of ``data`` fed in pieces cut at ``cuts`` (one piece if None), flushed at the end."""
    framer = NmeaFramer(max_length)
    framer.fast_path = fast_path
    out: list[Frame] = []
    start = 0
    for cut in sorted(cuts or []):
        out += framer.feed(data[start:cut])
        start = cut
    out += framer.feed(data[start:])
    out += framer.flush()
    return out


def without_eol(data: bytes) -> bytes:
    return data.replace(b"\r", b"").replace(b"\n", b"")


def deg(angle_rad: float) -> float:
    """Radians → degrees in [0, 360)."""
    return math.degrees(angle_rad) % 360.0


def angle_diff_deg(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


def ok(text: str, **kwargs: bool) -> Sentence:
    result = decode(text, **kwargs)
    assert not isinstance(result, Reject), result
    return result


def rejected(text: str, **kwargs: bool) -> Reject:
    result = decode(text, **kwargs)
    assert isinstance(result, Reject), result
    assert result.reason in REJECT_REASONS
    return result


line = nmea_line


# ---------------------------------------------------------------------------------------------- real data


def log_bytes(path: Path) -> bytes:
    """A log file's bytes, line ends kept, without gpsd's ``#`` comment lines."""
    return b"".join(x for x in path.read_bytes().splitlines(keepends=True) if not x.startswith(b"#"))


def run_log(path: Path) -> tuple[Counter[str], Counter[str], list[tuple[str, Sentence]]]:
    """Frame and decode a whole log: reject reasons, decoded talker+kind counts, and the decoded list."""
    data = log_bytes(path)
    frames = frames_of(data)
    assert without_eol(b"".join(f.raw for f in frames)) == without_eol(data)  # nothing lost
    reasons: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    decoded: list[tuple[str, Sentence]] = []
    for frame in frames:
        if frame.reason is not None:
            assert frame.reason in FRAME_REASONS
            reasons[frame.reason] += 1
            continue
        assert frame.text is not None
        result = decode(frame.text)
        if isinstance(result, Reject):
            assert result.reason in REJECT_REASONS
            assert "decoder error" not in result.detail
            reasons[result.reason] += 1
            if result.reason == UNSUPPORTED:
                reasons["unsupported " + result.detail] += 1
        else:
            kinds[result.talker + result.kind] += 1
            decoded.append((frame.text, result))
    return reasons, kinds, decoded


def need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} not present (real data lives beside the clone in ../shared/data)")
    return path


GPSD = DATA / "gpsd-logs"
USV = DATA / "usv-nmea"

# Expectations read off the files (grep): reject reasons (unsupported also per type) and decoded sentences.
EXPECTED = {
    "gpsd-logs/hemi.log": ({}, {"GPHDT": 215, "GPGGA": 215, "GPVTG": 215, "GPZDA": 108}),
    "gpsd-logs/nmea-rtk.log": ({}, {"GNGGA": 50, "GNRMC": 50, "GPGGA": 72, "GPRMC": 72}),
    "gpsd-logs/polarx2.log": (
        {
            "unsupported": 45,
            "unsupported GSV": 25,
            "unsupported GSA": 5,
            "unsupported GLL": 5,
            "unsupported GBS": 5,
            "unsupported GRS": 5,
        },
        {"GPGST": 5, "GPGGA": 5, "GPGNS": 5, "GPRMC": 5, "GPVTG": 5, "GPZDA": 5},
    ),
    "gpsd-logs/rst39.log": (
        {},
        {"GPGGA": 40, "GPRMC": 4, "GPHDT": 4, "GPZDA": 4, "PASHR": 100},  # PASHR: MRU attitude at 25 Hz
    ),
    "gpsd-logs/saab-r4.log": (
        {
            "ais": 14,  # !AIVDM x2, !AIVDO x12
            "unsupported": 36,
            "unsupported proprietary PFEC": 12,
            "unsupported GLL": 12,
            "unsupported DTM": 12,
        },
        {"GPZDA": 12, "GPGGA": 12, "GPVTG": 12, "GPRMC": 12, "HEHDT": 12, "HEROT": 12},
    ),
    "gpsd-logs/skytraq-PX1172RH_DS.log": (
        {
            "garbage": 3,  # gpsd's three JSON lines before the first sentence: one reject per line
            "unsupported": 141,
            "unsupported GSA": 36,
            "unsupported GSV": 42,
            "unsupported GLL": 9,
            "unsupported proprietary PSTI": 54,
        },
        {"GPGGA": 9, "GNRMC": 9, "GNVTG": 9, "GNZDA": 9, "GNTHS": 9, "GNHDT": 9},
    ),
    # Each USV file starts with the tail of a sentence cut by the logger: noise before the first '$'.
    "usv-nmea/202412051037.txt": (
        {"garbage": 1},
        {"GPGGA": 3230, "GPRMC": 3230, "GNVTG": 3229, "GNHDT": 3222, "GPHDT": 4, "BDHDT": 3},
    ),
    "usv-nmea/202412061745.txt": (
        {"garbage": 1},
        {"GPGGA": 1705, "GPRMC": 1705, "GNVTG": 1705, "GNHDT": 1705},
    ),
    "usv-nmea/202412071127.txt": ({"garbage": 1}, {"GPGGA": 425, "GPRMC": 426, "GNVTG": 425, "GNHDT": 425}),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_real_logs_decode_or_reject_with_a_reason(name: str) -> None:
    reasons, kinds, _ = run_log(need(DATA / name))
    want_reasons, want_kinds = EXPECTED[name]
    assert dict(reasons) == want_reasons
    assert dict(kinds) == want_kinds


def test_every_real_log_file_is_covered() -> None:
    need(DATA)
    files = {p.relative_to(DATA).as_posix() for d in (GPSD, USV) for p in d.iterdir() if p.name != "COPYING"}
    assert files == set(EXPECTED)


def valid_count(decoded: list[tuple[str, Sentence]], kind: str) -> tuple[int, int]:
    """(valid, invalid) counts of one sentence kind."""
    flags = [getattr(s, "valid") for _, s in decoded if s.kind == kind]  # noqa: B009
    return sum(flags), len(flags) - sum(flags)


def test_hemisphere_empty_fields_are_invalid_measurements_not_rejects() -> None:
    reasons, _, decoded = run_log(need(GPSD / "hemi.log"))
    assert not reasons
    assert valid_count(decoded, "HDT") == (4, 211)  # $GPHDT,,T*1B
    assert valid_count(decoded, "GGA") == (21, 194)  # $GPGGA,,,,,,0,,,,M,,M,,*66
    assert valid_count(decoded, "VTG") == (21, 194)  # $GPVTG,,T,,M,,N,,K,N*2C
    for _, s in decoded:
        if isinstance(s, Heading) and not s.valid:
            assert s.heading_rad is None
        if isinstance(s, Gga) and not s.valid:
            assert s.quality == 0 and s.lat_deg is None and s.time_s is None
        if isinstance(s, Zda):
            assert s.utc is not None and s.utc.date() == date(2018, 9, 7)


def test_saab_heading_rate_and_dgps() -> None:
    _, _, decoded = run_log(need(GPSD / "saab-r4.log"))
    ggas = [s for _, s in decoded if isinstance(s, Gga)]
    assert {g.quality for g in ggas} == {2} and all(g.valid for g in ggas)
    assert all(g.n_sats is None and g.hdop is None for g in ggas)  # $GPGGA,...,W,2,,,,,,,*6A: 13 fields
    heads = [s for _, s in decoded if isinstance(s, Heading)]
    assert all(h.talker == "HE" and h.kind == "HDT" and h.valid for h in heads)
    assert deg(heads[0].heading_rad or 0.0) == pytest.approx(4.0)
    rots = [s for _, s in decoded if isinstance(s, Rot)]
    assert all(r.valid and r.rate_rad_s == 0.0 for r in rots)
    zdas = [s for _, s in decoded if isinstance(s, Zda)]
    assert zdas[0].utc == datetime(2011, 6, 1, 13, 7, 11, tzinfo=UTC)  # zone 01:00 ignored: ZDA time is UTC


def test_skytraq_ths_matches_hdt_and_rtk_float() -> None:
    _, _, decoded = run_log(need(GPSD / "skytraq-PX1172RH_DS.log"))
    ths = [s for _, s in decoded if isinstance(s, Heading) and s.kind == "THS"]
    hdt = [s for _, s in decoded if isinstance(s, Heading) and s.kind == "HDT"]
    assert len(ths) == len(hdt) == 9
    for a, b in zip(ths, hdt, strict=True):
        assert a.valid and a.mode == "A" and a.heading_rad == b.heading_rad
        assert -math.pi <= (a.heading_rad or 0.0) < 0.0  # 244° is -116°
    ggas = [s for _, s in decoded if isinstance(s, Gga)]
    assert {g.quality for g in ggas} == {5}
    rmcs = [s for _, s in decoded if isinstance(s, Rmc)]
    assert all(
        r.valid and r.mode == "F" and r.nav_status == "V" and r.date == date(2022, 3, 29) for r in rmcs
    )


def test_polarx2_gst_and_gns() -> None:
    _, _, decoded = run_log(need(GPSD / "polarx2.log"))
    gst = next(s for _, s in decoded if isinstance(s, Gst))
    assert (gst.rms_m, gst.sigma_major_m, gst.sigma_minor_m) == (0.387, 317.719, 3.872)
    assert gst.orient_rad == pytest.approx(math.radians(1.791))
    assert (gst.sigma_lat_m, gst.sigma_lon_m, gst.sigma_alt_m) == (317.563, 10.659, 180.746)
    assert gst.time_s == pytest.approx(11 * 3600 + 22 * 60 + 57)
    gns = next(s for _, s in decoded if isinstance(s, Gns))
    assert gns.valid and gns.mode == "AN" and gns.alt_m is None
    gga = next(s for _, s in decoded if isinstance(s, Gga))
    assert gga.lat_deg == gns.lat_deg and gga.lon_deg == gns.lon_deg and gga.lon_deg is not None
    vtgs = [s for _, s in decoded if isinstance(s, Vtg)]
    assert vtgs[0].cog_rad is not None and vtgs[1].cog_rad is None and vtgs[1].valid  # empty course at rest


@pytest.mark.parametrize("name", ["202412051037.txt", "202412061745.txt", "202412071127.txt"])
def test_usv_rtk_logs(name: str) -> None:
    _, _, decoded = run_log(need(USV / name))
    ggas = [s for _, s in decoded if isinstance(s, Gga)]
    assert {g.quality for g in ggas} == {4} and all(g.valid for g in ggas)
    assert all(22.5 < (g.lat_deg or 0) < 22.6 and 114.5 < (g.lon_deg or 0) < 114.6 for g in ggas)
    assert all(s.valid for _, s in decoded if isinstance(s, Rmc | Vtg))
    heads = [s for _, s in decoded if isinstance(s, Heading)]
    assert all(-math.pi <= (h.heading_rad or 0.0) < math.pi for h in heads)
    assert [h.talker for h in heads if not h.valid] == (["GP"] * 4 if name == "202412051037.txt" else [])
    times = [g.time_s for g in ggas]
    steps = Counter(round((b or 0) - (a or 0), 3) for a, b in itertools.pairwise(times))
    assert steps.most_common(1)[0][0] == 0.2  # 5 Hz


@settings(max_examples=8, deadline=None)
@given(cuts=st.lists(st.integers(min_value=0, max_value=110_000), min_size=1, max_size=200))
def test_a_real_log_chopped_anywhere_gives_the_same_frames(cuts: list[int]) -> None:
    data = log_bytes(need(USV / "202412071127.txt")) + log_bytes(need(GPSD / "saab-r4.log"))
    assert frames_of(data, cuts) == frames_of(data) == frames_of(data, fast_path=False)


def test_usv_heading_crosses_north() -> None:
    _, _, decoded = run_log(need(USV / "202412061745.txt"))
    heads = [s.heading_rad for _, s in decoded if isinstance(s, Heading) and s.heading_rad is not None]
    crossings = sum(1 for a, b in itertools.pairwise(heads) if a < 0 <= b or b < 0 <= a)
    assert crossings > 4


def test_real_lines_agree_with_pynmea2() -> None:
    """Independent check: lat/lon/heading/time/speed equal pynmea2's reading of the same lines."""
    need(DATA)
    checked: Counter[str] = Counter()
    for path in sorted(GPSD.glob("*.log")) + sorted(USV.glob("*.txt")):
        for text, s in run_log(path)[2]:
            if s.kind not in ("GGA", "RMC", "HDT"):
                continue
            msg = pynmea2.parse(text, check=True)
            if isinstance(s, Gga | Rmc) and s.lat_deg is not None and s.lon_deg is not None:
                assert abs(s.lat_deg - msg.latitude) <= 1e-9, text
                assert abs(s.lon_deg - msg.longitude) <= 1e-9, text
                t = msg.timestamp
                want = t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6
                assert s.time_s == pytest.approx(want, abs=1e-6), text
                checked[s.kind] += 1
            if isinstance(s, Rmc) and s.sog_mps is not None:
                assert s.sog_mps == pytest.approx(float(msg.spd_over_grnd) * 1852 / 3600, rel=1e-12)
                assert s.date == msg.datestamp
            if isinstance(s, Heading) and s.heading_rad is not None:
                assert abs(angle_diff_deg(deg(s.heading_rad), float(msg.heading))) <= 1e-9, text
                checked["HDT"] += 1
    assert checked["GGA"] > 5000 and checked["RMC"] > 5000 and checked["HDT"] > 5000


# ---------------------------------------------------------------------------------------------- encoder

times = st.datetimes(min_value=datetime(2000, 1, 1), max_value=datetime(2068, 12, 31, 23, 59, 59)).map(
    lambda t: t.replace(tzinfo=UTC)
)
lats = st.floats(min_value=-90.0, max_value=90.0, allow_nan=False)
lons = st.floats(min_value=-180.0, max_value=180.0, allow_nan=False)
angles = st.floats(min_value=-4 * math.pi, max_value=4 * math.pi, allow_nan=False)
talkers = st.sampled_from(["GP", "GN", "GL", "GA", "GB", "BD", "HE", "HC", "IN", "II", "QZ"])
maybe = st.one_of(st.none(), st.floats(min_value=0.0, max_value=999.0))
LATLON_TOL = 1e-6 / 60 + 1e-12  # 6 decimals of minutes
TIME_TOL = 0.005 + 1e-6  # 2 decimals of seconds


def tod(t: datetime) -> float:
    return t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6


def tod_error(got: float | None, t: datetime) -> float:
    assert got is not None
    return abs((got - tod(t) + 43200.0) % 86400.0 - 43200.0)


def utc_of(day: date | None, time_s: float | None) -> datetime:
    assert day is not None and time_s is not None
    return datetime(day.year, day.month, day.day, tzinfo=UTC) + timedelta(seconds=time_s)


def decoded(sentence_crlf: str) -> Sentence:
    assert sentence_crlf.endswith("\r\n")
    (frame,) = frames_of(sentence_crlf.encode("ascii"))
    assert frame.reason is None and frame.text is not None
    return ok(frame.text)


@settings(max_examples=120, deadline=None)
@given(t=times, lat=lats, lon=lons, talker=talkers, quality=st.sampled_from(sorted(enc.GGA_QUALITY)))
@example(
    t=datetime(2024, 12, 31, 23, 59, 59, 995000, tzinfo=UTC), lat=-90.0, lon=180.0, talker="GN", quality=4
)
@example(t=datetime(2024, 1, 1, tzinfo=UTC), lat=10 + 59.9999996 / 60, lon=-1e-12, talker="GP", quality=0)
def test_gga_round_trip(t: datetime, lat: float, lon: float, talker: str, quality: int) -> None:
    s = decoded(enc.gga(talker, t, lat, lon, quality, 14, 0.7, -12.345, 39.25, 1.5, 1023))
    assert isinstance(s, Gga) and s.kind == "GGA" and s.talker == talker
    assert abs((s.lat_deg or 0.0) - lat) <= LATLON_TOL
    assert abs(angle_diff_deg(s.lon_deg or 0.0, lon)) <= LATLON_TOL
    assert tod_error(s.time_s, t) <= TIME_TOL
    assert (s.quality, s.n_sats, s.hdop, s.alt_m, s.geoid_sep_m, s.age_s, s.station_id) == (
        quality,
        14,
        0.7,
        -12.345,
        39.25,
        1.5,
        1023,
    )
    assert s.valid == (quality >= 1)
    empty = decoded(enc.gga(talker, t, None, None, 0, 0, None, None))
    assert isinstance(empty, Gga) and not empty.valid and empty.lat_deg is None and empty.alt_m is None


@settings(max_examples=60, deadline=None)
@given(t=times, lat=lats, lon=lons, mode=st.sampled_from(["DD", "RR", "FF", "AAN", "NN", "N", "DDDDDD"]))
def test_gns_round_trip(t: datetime, lat: float, lon: float, mode: str) -> None:
    s = decoded(enc.gns("GN", t, lat, lon, mode, 20, 0.6, 12.5, -31.25, 2.0, 7, nav_status="S"))
    assert isinstance(s, Gns)
    assert (
        abs((s.lat_deg or 0.0) - lat) <= LATLON_TOL
        and abs(angle_diff_deg(s.lon_deg or 0.0, lon)) <= LATLON_TOL
    )
    assert tod_error(s.time_s, t) <= TIME_TOL
    assert (s.mode, s.n_sats, s.hdop, s.alt_m, s.geoid_sep_m, s.age_s, s.station_id, s.nav_status) == (
        mode,
        20,
        0.6,
        12.5,
        -31.25,
        2.0,
        7,
        "S",
    )
    assert s.valid == (set(mode) != {"N"})


@settings(max_examples=120, deadline=None)
@given(
    t=times,
    lat=lats,
    lon=lons,
    sog=st.floats(min_value=0.0, max_value=30.0),
    cog=angles,
    valid=st.booleans(),
    mode=st.sampled_from(list(enc.POSITION_MODES)),
    var=st.one_of(st.none(), st.floats(min_value=-0.5, max_value=0.5)),
)
@example(
    t=datetime(2024, 12, 31, 23, 59, 59, 996000, tzinfo=UTC),
    lat=0.0,
    lon=0.0,
    sog=0.0,
    cog=math.pi,
    valid=True,
    mode="R",
    var=None,
)
def test_rmc_round_trip(
    t: datetime,
    lat: float,
    lon: float,
    sog: float,
    cog: float,
    valid: bool,
    mode: str,
    var: float | None,
) -> None:
    s = decoded(enc.rmc("GP", t, lat, lon, sog, cog, valid, mode, mag_var_rad=var))
    assert isinstance(s, Rmc)
    assert abs(utc_of(s.date, s.time_s) - t) <= timedelta(seconds=TIME_TOL)  # date and time carry together
    assert (
        abs((s.lat_deg or 0.0) - lat) <= LATLON_TOL
        and abs(angle_diff_deg(s.lon_deg or 0.0, lon)) <= LATLON_TOL
    )
    assert s.sog_mps == pytest.approx(sog, abs=0.0005 * 1852 / 3600 + 1e-12)
    assert s.cog_rad is not None and -math.pi <= s.cog_rad < math.pi
    assert abs(angle_diff_deg(math.degrees(s.cog_rad), math.degrees(cog))) <= 0.005 + 1e-9
    assert s.mode == mode and s.nav_status is None
    assert s.valid == (valid and mode != "N")
    if var is None:
        assert s.mag_var_rad is None
    else:
        assert s.mag_var_rad == pytest.approx(var, abs=math.radians(0.05) + 1e-12)


@settings(max_examples=80, deadline=None)
@given(
    cog=angles, sog=st.floats(min_value=0.0, max_value=50.0), mode=st.sampled_from(list(enc.POSITION_MODES))
)
def test_vtg_round_trip(cog: float, sog: float, mode: str) -> None:
    s = decoded(enc.vtg("GN", cog, sog, mode, mag_var_rad=0.1))
    assert isinstance(s, Vtg)
    assert (
        s.cog_rad is not None and abs(angle_diff_deg(math.degrees(s.cog_rad), math.degrees(cog))) <= 0.005001
    )
    assert s.sog_mps == pytest.approx(sog, abs=0.0005 * 1852 / 3600 + 1e-12)
    assert s.mode == mode and s.valid == (mode != "N")
    empty = decoded(enc.vtg("GN", None, None, "N"))
    assert isinstance(empty, Vtg) and empty.cog_rad is None and empty.sog_mps is None and not empty.valid


@settings(max_examples=60, deadline=None)
@given(
    t=times,
    sig=st.lists(st.one_of(st.none(), st.floats(min_value=0.0, max_value=99.0)), min_size=6, max_size=6),
    orient=st.one_of(st.none(), angles),
)
def test_gst_round_trip(t: datetime, sig: list[float | None], orient: float | None) -> None:
    text = enc.gst(
        "GP",
        t,
        rms_m=sig[0],
        sigma_major_m=sig[1],
        sigma_minor_m=sig[2],
        orient_rad=orient,
        sigma_lat_m=sig[3],
        sigma_lon_m=sig[4],
        sigma_alt_m=sig[5],
    )
    s = decoded(text)
    assert isinstance(s, Gst)
    assert tod_error(s.time_s, t) <= TIME_TOL
    got = [s.rms_m, s.sigma_major_m, s.sigma_minor_m, s.sigma_lat_m, s.sigma_lon_m, s.sigma_alt_m]
    for g, want in zip(got, sig, strict=True):
        assert (g is None) == (want is None)
        if want is not None:
            assert g == pytest.approx(want, abs=0.0005 + 1e-12)
    if orient is None:
        assert s.orient_rad is None
    else:
        assert s.orient_rad is not None and 0.0 <= s.orient_rad < math.pi
        diff = (math.degrees(s.orient_rad - orient) + 90.0) % 180.0 - 90.0  # an axis: modulo 180°
        assert abs(diff) <= 0.05 + 1e-9


@settings(max_examples=60, deadline=None)
@given(t=times)
def test_zda_round_trip(t: datetime) -> None:
    s = decoded(enc.zda("GP", t))
    assert isinstance(s, Zda) and s.utc is not None
    assert abs(s.utc - t) <= timedelta(seconds=TIME_TOL)
    assert s.utc == utc_of(s.date, s.time_s)


@settings(max_examples=100, deadline=None)
@given(heading=angles, decimals=st.integers(min_value=1, max_value=4), mode=st.sampled_from(list("AEMSV")))
@example(heading=math.pi, decimals=2, mode="A")
@example(heading=2 * math.pi - 1e-9, decimals=2, mode="A")
def test_hdt_and_ths_round_trip(heading: float, decimals: int, mode: str) -> None:
    tol = 0.5 * 10.0**-decimals + 1e-9
    for text, kind in (
        (enc.hdt("HE", heading, decimals=decimals), "HDT"),
        (enc.ths("IN", heading, mode), "THS"),
    ):
        s = decoded(text)
        assert isinstance(s, Heading) and s.kind == kind and not s.magnetic
        assert s.heading_rad is not None and -math.pi <= s.heading_rad < math.pi
        assert abs(angle_diff_deg(math.degrees(s.heading_rad), math.degrees(heading))) <= max(
            tol, 0.005 + 1e-9
        )
        assert s.valid == (kind == "HDT" or mode != "V")
        assert s.mode == (mode if kind == "THS" else None)


@settings(max_examples=80, deadline=None)
@given(
    heading=angles,
    dev=st.one_of(st.none(), st.floats(min_value=-0.3, max_value=0.3)),
    var=st.one_of(st.none(), st.floats(min_value=-0.5, max_value=0.5)),
)
def test_hdg_round_trip(heading: float, dev: float | None, var: float | None) -> None:
    s = decoded(enc.hdg("HC", heading, dev, var))
    assert isinstance(s, Heading) and s.kind == "HDG" and s.valid and s.mode is None
    assert s.magnetic == (var is None)
    want = math.degrees(heading + (dev or 0.0) + (var or 0.0))
    assert s.heading_rad is not None and -math.pi <= s.heading_rad < math.pi
    assert abs(angle_diff_deg(math.degrees(s.heading_rad), want)) <= 0.15 + 1e-9


@settings(max_examples=80, deadline=None)
@given(rate=st.floats(min_value=-1.0, max_value=1.0), valid=st.booleans())
def test_rot_round_trip(rate: float, valid: bool) -> None:
    s = decoded(enc.rot("HE", rate, valid))
    assert isinstance(s, Rot) and s.valid == valid
    assert s.rate_rad_s == pytest.approx(rate, abs=math.radians(0.05) / 60 + 1e-12)
    empty = decoded(enc.rot("HE", None, True))
    assert isinstance(empty, Rot) and empty.rate_rad_s is None and not empty.valid


def test_every_supported_type_is_round_tripped_above() -> None:
    assert set(SENTENCE_TYPES) == {
        *("GGA", "GNS", "RMC", "VTG", "GST", "ZDA", "HDT", "THS", "HDG", "ROT"),
        *("MWV", "VWR"),  # tests/test_nmea_mwv.py
    }


# ---------------------------------------------------------------------------------------------- semantics


def test_empty_fields_give_invalid_measurements() -> None:
    gga = ok("$GPGGA,,,,,,0,,,,M,,M,,*66")
    assert isinstance(gga, Gga) and not gga.valid and gga.quality == 0 and gga.lat_deg is None
    # a position with quality 0, and quality 1 with an empty position: both "no measurement"
    for text in (
        "GPGGA,120000,4807.038,N,01131.000,E,0,08,0.9,545.4,M,46.9,M,,",
        "GPGGA,120000,,,,,1,08,0.9,,,,,,",
    ):
        gga = ok(line(text))
        assert isinstance(gga, Gga) and not gga.valid
    rmc = ok(line("GPRMC,120000,V,4807.038,N,01131.000,E,0.0,0.0,010124,,,N"))
    assert isinstance(rmc, Rmc) and not rmc.valid and rmc.lat_deg == pytest.approx(48 + 7.038 / 60)
    ths = ok(line("GNTHS,123.4,V"))
    assert isinstance(ths, Heading) and not ths.valid and ths.heading_rad is not None
    hdt = ok("$GPHDT,,T*1B")
    assert isinstance(hdt, Heading) and not hdt.valid and hdt.heading_rad is None
    rot = ok(line("HEROT,1.5,V"))
    assert isinstance(rot, Rot) and not rot.valid and rot.rate_rad_s == pytest.approx(math.radians(1.5) / 60)
    gns = ok(line("GPGNS,112257.00,3844.24011,N,00908.43828,W,NN,03,10.5,,,,"))
    assert isinstance(gns, Gns) and not gns.valid


def test_units_and_signs() -> None:
    gga = ok(line("GPGGA,123519.25,4807.038,S,01131.000,W,1,08,0.9,545.4,M,46.9,M,,"))
    assert isinstance(gga, Gga)
    assert gga.lat_deg == pytest.approx(-(48 + 7.038 / 60), abs=1e-12)
    assert gga.lon_deg == pytest.approx(-(11 + 31.0 / 60), abs=1e-12)
    assert gga.time_s == pytest.approx(12 * 3600 + 35 * 60 + 19.25, abs=1e-9)
    rmc = ok(line("GPRMC,235959.99,A,0000.000,N,18000.000,E,10.0,270.0,311299,3.4,W,A"))
    assert isinstance(rmc, Rmc) and rmc.valid
    assert rmc.sog_mps == pytest.approx(10 * 1852 / 3600) and rmc.cog_rad == pytest.approx(-math.pi / 2)
    assert rmc.date == date(1999, 12, 31) and rmc.mag_var_rad == pytest.approx(math.radians(-3.4))
    assert rmc.lon_deg == 180.0
    for text, want in [("HEHDT,0.0,T", 0.0), ("HEHDT,180.0,T", -math.pi), ("HEHDT,360.0,T", 0.0)]:
        h = ok(line(text))
        assert isinstance(h, Heading) and h.heading_rad == pytest.approx(want, abs=1e-15)
    vtg_kmh = ok(line("GPVTG,10.0,T,,M,,N,36.0,K,A"))
    assert isinstance(vtg_kmh, Vtg) and vtg_kmh.sog_mps == pytest.approx(10.0)
    old_vtg = ok(line("GPVTG,054.7,034.4,005.5,010.2"))
    assert (
        isinstance(old_vtg, Vtg)
        and old_vtg.mode is None
        and old_vtg.sog_mps == pytest.approx(5.5 * 1852 / 3600)
    )
    hdg = ok(line("HCHDG,350.0,5.0,E,20.0,E"))
    assert isinstance(hdg, Heading) and not hdg.magnetic and deg(hdg.heading_rad or 0) == pytest.approx(15.0)
    hdg_mag = ok(line("HCHDG,98.3,,,,"))
    assert (
        isinstance(hdg_mag, Heading)
        and hdg_mag.magnetic
        and deg(hdg_mag.heading_rad or 0) == pytest.approx(98.3)
    )
    rot = ok(line("TIROT,-60.0,A"))
    assert isinstance(rot, Rot) and rot.rate_rad_s == pytest.approx(-math.radians(1.0))
    zda = ok(line("GPZDA,235960.5,31,12,2016,00,00"))  # a leap second
    assert isinstance(zda, Zda) and zda.utc == datetime(2017, 1, 1, 0, 0, 0, 500000, tzinfo=UTC)


def test_high_precision_rtk_latitude() -> None:
    gga = ok("$GNGGA,132819.60,4134.49795459,N,09345.03431408,W,2,10,0.9,278.161,M,-31.442,M,6.6,0133*6A")
    assert isinstance(gga, Gga)
    assert gga.lat_deg == pytest.approx(41 + 34.49795459 / 60, abs=1e-13)
    assert gga.lon_deg == pytest.approx(-(93 + 45.03431408 / 60), abs=1e-13)
    assert gga.station_id == 133 and gga.age_s == 6.6


def test_require_checksum_false_accepts_sentences_without_one() -> None:
    assert rejected("$HEHDT,12.5,T").reason == NO_CHECKSUM
    h = ok("$HEHDT,12.5,T", require_checksum=False)
    assert isinstance(h, Heading) and deg(h.heading_rad or 0) == pytest.approx(12.5)
    assert rejected("$HEHDT,12.5,T*00", require_checksum=False).reason == BAD_CHECKSUM


def test_lower_case_checksum_and_a_trailing_line_end_are_accepted() -> None:
    assert ok("$HEHDT,4.0,T*2b").kind == "HDT"
    assert ok("$HEHDT,4.0,T*2B\r\n") == ok("$HEHDT,4.0,T*2B")


@pytest.mark.parametrize(
    ("text", "reason", "detail"),
    [
        ("$HEHDT,12.5,T", NO_CHECKSUM, ""),
        ("$HEHDT,12.5,T*04", BAD_CHECKSUM, "checksum 04, computed 19"),
        ("$HEHDT,12.5,T*0", BAD_CHECKSUM, "hex"),
        ("$HEHDT,12.5,T*0G", BAD_CHECKSUM, "hex"),
        ("$HEHDT,12.5,T*03*03", BAD_CHECKSUM, "hex"),
        ("HEHDT,12.5,T*03", BAD_FORMAT, ""),
        ("", BAD_FORMAT, ""),
        ("$", BAD_FORMAT, ""),
        ("$HEHDT,12.5°,T*03", BAD_FORMAT, ""),
        (line("HEHDTX,12.5,T"), BAD_FORMAT, "address"),
        (line("he,12.5,T"), BAD_FORMAT, "address"),
        (line("H1DT2,12.5,T"), BAD_FORMAT, "address"),
        (line(""), BAD_FORMAT, "address"),
        (line("GPGGA,123519,4807.038,N"), BAD_FORMAT, "fields"),
        (line("GNTHS,12.5"), BAD_FORMAT, "fields"),
        (line("GPGSV,3,1,10,25,70,260,46"), UNSUPPORTED, "GSV"),
        (line("GNGSA,A,3,05,12,,,,,,,,,,,1.7,0.8,1.6,1"), UNSUPPORTED, "GSA"),
        (line("PASHR,POS,0,10,123519.00,4807.038,N"), UNSUPPORTED, "PASHR"),  # an Ashtech reply
        (line("PFEC,GPatt,123.4,1.2,0.5"), UNSUPPORTED, "PFEC"),
        ("!AIVDM,1,1,,B,13aGhtw0R<OJf=6LgQ?Ad1FF05`L,0*24", UNSUPPORTED, "VDM"),
        (line("GPGGA,1235,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "time"),
        (line("GPGGA,253519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "time"),
        (line("GPGGA,123519,48x7.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "latitude"),
        (line("GPGGA,123519,4807.038,X,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "latitude"),
        (line("GPGGA,123519,4867.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "latitude"),
        (line("GPGGA,123519,9107.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "latitude"),
        (line("GPGGA,123519,-4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "latitude"),
        (line("GPGGA,123519,4807.038,N,18131.000,E,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "longitude"),
        (line("GPGGA,123519,4807.038,N,01131.000,N,1,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "longitude"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,X,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "quality"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,12,08,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "quality"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,-8,0.9,545.4,M,46.9,M,,"), BAD_FIELD, "satellites"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,08,nan,545.4,M,46.9,M,,"), BAD_FIELD, "hdop"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,inf,M,46.9,M,,"), BAD_FIELD, "altitude"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,4.6.9,M,,"), BAD_FIELD, "geoid"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,-1,"), BAD_FIELD, "age"),
        (line("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,AB"), BAD_FIELD, "station"),
        (line("GPRMC,120000,X,4807.038,N,01131.000,E,0.0,0.0,010124,,,A"), BAD_FIELD, "status"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,-1,0.0,010124,,,A"), BAD_FIELD, "speed"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,361,010124,,,A"), BAD_FIELD, "course"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,310224,,,A"), BAD_FIELD, "date"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,0101,,,A"), BAD_FIELD, "date"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,010124,3.4,Q,A"), BAD_FIELD, "variation"),
        (line("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,010124,,,a"), BAD_FIELD, "mode"),
        (line("GPVTG,x,T,,M,0.0,N,0.0,K,A"), BAD_FIELD, "course"),
        (line("GPVTG,1.0,T,,M,,N,-5,K,A"), BAD_FIELD, "km/h"),
        (line("GPVTG,1.0,2.0"), BAD_FORMAT, "fields"),
        (line("GPGNS,112257.00,3844.24011,N,00908.43828,W,a1,03,10.5,,,,"), BAD_FIELD, "mode"),
        (line("GPGST,112257.00,0.387,-1,3.872,1.791,317.563,10.659,180.746"), BAD_FIELD, "sigma major"),
        (line("GPZDA,193913.00,32,09,2018,00,00"), BAD_FIELD, "day,month,year (field 2): '32,09,2018'"),
        (line("GPZDA,235960.00,31,12,9999,00,00"), BAD_FIELD, "year"),
        (line("GPZDA,193913.00,07,x9,2018,00,00"), BAD_FIELD, "month"),
        (line("HEHDT,-0.5,T"), BAD_FIELD, "heading"),
        (line("HEHDT,360.5,T"), BAD_FIELD, "heading"),
        (line("INTHS,12.0,Q"), BAD_FIELD, "mode"),
        (line("HCHDG,400,,,,"), BAD_FIELD, "heading"),
        (line("HCHDG,40,200,E,,"), BAD_FIELD, "deviation"),
        (line("HEROT,1.0,X"), BAD_FIELD, "status"),
        (line("HEROT,1e999,A"), BAD_FIELD, "rate"),
    ],
)
def test_each_reject_reason(text: str, reason: str, detail: str) -> None:
    r = rejected(text)
    assert r.reason == reason, r
    assert detail in r.detail


def test_bad_field_detail_names_the_field_and_value() -> None:
    r = rejected(line("GPGGA,123519,48x7.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"))
    assert r.detail == "GGA latitude (field 2): '48x7.038,N'"


def test_reject_reasons_are_stable() -> None:
    assert REJECT_REASONS == ("no_checksum", "bad_checksum", "bad_format", "unsupported", "bad_field")
    assert FRAME_REASONS == (
        "garbage",
        "truncated",
        "overlong",
        "non_ascii",
        "ais",
        "comment",
        "tag_block",
        "iec_61162_450",
    )


def test_fast_constructor_makes_ordinary_frozen_instances() -> None:
    values = ("GP", 1.5, 48.1, 11.5, 4, 14, 0.7, 3.5, 39.25, None, 1023, True)
    fast, slow = _new_gga("GGA", *values), Gga(*values)
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.asdict(fast) == dataclasses.asdict(slow) and fast.kind == "GGA"
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.lat_deg = 0.0  # type: ignore[misc]
    decoded_gga = ok(enc.gga("GP", datetime(2024, 1, 1, tzinfo=UTC), 48.0, 11.0, 4, 14, 0.7, 3.5).strip())
    assert dataclasses.replace(decoded_gga, talker="GN").talker == "GN"


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=300))
def test_folded_checksum_equals_the_encoder_checksum(body: str) -> None:
    assert _xor(body) == int(enc.checksum(body), 16)


# ---------------------------------------------------------------------------------------------- framing


def reasons_of(frames: list[Frame]) -> list[str | None]:
    return [f.reason for f in frames]


def test_line_terminators_cr_lf_crlf_lfcr_and_blank_lines() -> None:
    a, b = "$HEHDT,4.0,T*2B", "$HEROT,0.0,A*2B"
    for eol in (b"\r", b"\n", b"\r\n", b"\n\r", b"\r\n\r\n", b"\n\n\n"):
        data = eol + a.encode() + eol + b.encode() + eol
        frames = frames_of(data)
        assert [(f.text, f.reason) for f in frames] == [(a, None), (b, None)], eol


def test_garbage_is_one_frame_per_line_with_all_its_bytes() -> None:
    frames = frames_of(b"\x00\xffjunk\r\nmore junk\r\n$HEHDT,4.0,T*2B\r\nxyz")
    assert [(f.raw, f.reason) for f in frames] == [
        (b"\x00\xffjunk", GARBAGE),
        (b"more junk", GARBAGE),
        (b"$HEHDT,4.0,T*2B", None),
        (b"xyz", GARBAGE),
    ]


COMMENTED = (
    b"# Name: Saab AIS-GPS R4\r\n#\r\n$HEHDT,4.0,T*2B\r\n# $GPGGA in a comment starts nothing\r\n"
    b"xx # not at a line start\r\n$HEROT,0.0,A*2B\r\n#no line end"
)


def test_a_line_beginning_with_hash_is_one_comment_frame_with_all_its_bytes() -> None:
    """gpsd's test logs begin with ``#`` lines; they are comments, not garbage, to their line end whatever
    they hold (a ``$`` in one starts no sentence). A ``#`` that does not begin a line is garbage."""
    frames = frames_of(COMMENTED)
    assert [(f.raw, f.reason) for f in frames] == [
        (b"# Name: Saab AIS-GPS R4", COMMENT),
        (b"#", COMMENT),
        (b"$HEHDT,4.0,T*2B", None),
        (b"# $GPGGA in a comment starts nothing", COMMENT),
        (b"xx # not at a line start", GARBAGE),
        (b"$HEROT,0.0,A*2B", None),
        (b"#no line end", COMMENT),
    ]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(0, len(COMMENTED)), max_size=12), st.booleans())
def test_comment_frames_do_not_depend_on_where_the_stream_is_cut(cuts: list[int], fast: bool) -> None:
    assert frames_of(COMMENTED, cuts, fast_path=fast) == frames_of(COMMENTED)


def test_dollar_inside_a_sentence_restarts_and_the_cut_part_is_truncated() -> None:
    frames = frames_of(b"$GPGGA,1235$HEHDT,4.0,T*2B\r\n$GPGG!AIVDO,1,1,,B,13`kvwO0,0*5B\r\n")
    assert [(f.raw, f.reason) for f in frames] == [
        (b"$GPGGA,1235", TRUNCATED),
        (b"$HEHDT,4.0,T*2B", None),
        (b"$GPGG", TRUNCATED),
        (b"!AIVDO,1,1,,B,13`kvwO0,0*5B", AIS),
    ]
    assert all(f.text is None for f in frames if f.reason is not None)


def test_overlong_lines_are_dropped_and_the_framer_resyncs() -> None:
    long = b"$GPGGA," + b"1" * 200
    frames = frames_of(long + b"\r\n$HEHDT,4.0,T*2B\r\n" + long + b"$HEROT,0.0,A*2B\r\n")
    assert [(f.raw, f.reason) for f in frames] == [
        (long, OVERLONG),
        (b"$HEHDT,4.0,T*2B", None),
        (long, OVERLONG),
        (b"$HEROT,0.0,A*2B", None),
    ]
    exact = b"$" + b"A" * 179
    assert reasons_of(frames_of(exact + b"\n")) == [None]
    assert reasons_of(frames_of(exact + b"A\n")) == [OVERLONG]
    assert reasons_of(frames_of(b"$" + b"A" * 20 + b"\n", max_length=20)) == [OVERLONG]


def test_noise_without_lead_bytes_comes_back_in_bounded_chunks() -> None:
    noise = (
        bytes(range(256)).replace(b"$", b"").replace(b"!", b"").replace(b"\r", b"").replace(b"\n", b"") * 20
    )
    framer = NmeaFramer()
    frames = framer.feed(noise)
    assert all(len(f.raw) == MAX_CHUNK for f in frames) and framer.pending < MAX_CHUNK
    frames += framer.flush()
    assert b"".join(f.raw for f in frames) == noise and set(reasons_of(frames)) == {GARBAGE}
    # with line ends in the noise: one frame per line, every byte but the line ends kept
    lines = b"abc\x00\r\ndef\xff\n\nghi"
    frames = frames_of(lines)
    assert [f.raw for f in frames] == [b"abc\x00", b"def\xff", b"ghi"] and set(reasons_of(frames)) == {
        GARBAGE
    }
    endless = b"$" + b"x" * 5000
    frames = frames_of(endless)
    assert b"".join(f.raw for f in frames) == endless and set(reasons_of(frames)) == {OVERLONG}
    assert max(len(f.raw) for f in frames) <= MAX_CHUNK


def test_non_ascii_inside_a_sentence() -> None:
    for bad in (b"\x00", b"\xff", b"\x7f", b"\t", "é".encode()):
        data = b"$HEHDT,4" + bad + b".0,T*2B\r\n$HEROT,0.0,A*2B\r\n"
        frames = frames_of(data)
        assert [(f.raw, f.reason) for f in frames] == [
            (b"$HEHDT,4" + bad + b".0,T*2B", NON_ASCII),
            (b"$HEROT,0.0,A*2B", None),
        ]
        assert frames[0].text is None


def test_partial_sentences_wait_for_the_next_feed_and_flush_as_truncated() -> None:
    framer = NmeaFramer()
    assert framer.feed(b"$HEHDT,4.") == [] and framer.pending == 9
    assert framer.feed(b"0,T*2B") == []
    assert framer.feed(b"\r") == [Frame("$HEHDT,4.0,T*2B", b"$HEHDT,4.0,T*2B", None)]
    assert framer.feed(b"\n") == [] and framer.pending == 0
    assert framer.feed(b"$HEROT,0") == []
    assert framer.flush() == [Frame(None, b"$HEROT,0", TRUNCATED)]
    assert framer.flush() == [] and framer.feed(b"") == []


def test_several_sentences_in_one_datagram() -> None:
    datagram = b"".join(s.encode() for s in (enc.hdt("HE", 0.1), enc.rot("HE", 0.01), enc.ths("HE", 0.1)))
    frames = NmeaFramer().feed(datagram)
    assert [ok(f.text or "").kind for f in frames] == ["HDT", "ROT", "THS"]


def test_bad_max_length_is_a_config_error() -> None:
    with pytest.raises(ValueError):
        NmeaFramer(0)


# ---------------------------------------------------------------------------------------------- fuzzing

T0 = datetime(2024, 12, 5, 2, 27, 18, 800000, tzinfo=UTC)
SAMPLES = [
    enc.gga("GP", T0, 22.5672510, 114.5320887, 4, 19, 0.9, 3.4038, -1.3415, 0.0, 0),
    enc.gns("GN", T0, -33.9, 151.2, "RR", 20, 0.6, 12.5, -31.25),
    enc.rmc("GP", T0, 22.5672510, 114.5320887, 0.3, 2.0, True, "D", mag_var_rad=-0.06),
    enc.vtg("GN", 1.48, 0.03, "D"),
    enc.gst(
        "GP",
        T0,
        rms_m=0.4,
        sigma_major_m=0.02,
        sigma_minor_m=0.01,
        orient_rad=0.5,
        sigma_lat_m=0.02,
        sigma_lon_m=0.01,
        sigma_alt_m=0.03,
    ),
    enc.zda("GP", T0),
    enc.hdt("GN", -2.2),
    enc.ths("GN", 1.2, "A"),
    enc.hdg("HC", 0.5, 0.01, -0.02),
    enc.rot("HE", -0.01),
    "$GPHDT,,T*1B\r\n",
    "$GPGSV,5,5,17,50,45,190,*43\r\n",
    "$PASHR,204132.000,010.51,T,+00.39,-00.79,-00.84,0.151,0.075,0.555,1,0*03\r\n",
    "!AIVDO,1,1,,B,13`kvwO005wJnb0Lfo:@7P8F05`L,0*5B\r\n",
]
SAMPLE_BYTES = [s.encode("ascii") for s in SAMPLES]

streams = st.lists(st.sampled_from(SAMPLE_BYTES), min_size=1, max_size=8).map(b"".join)


def check_stream(data: bytes, cuts: list[int]) -> list[Frame]:
    """Frame ``data`` whole and chopped, decode every candidate: nothing raises, nothing is lost, the
    chopping changes nothing, and the framer's fast path gives what its general rules give."""
    whole = frames_of(data)
    assert frames_of(data, cuts) == whole
    assert frames_of(data, fast_path=False) == whole  # the fast path agrees with the general rules
    assert frames_of(data, cuts, max_length=40) == frames_of(data, max_length=40, fast_path=False)
    assert without_eol(b"".join(f.raw for f in whole)) == without_eol(data)
    for frame in whole:
        assert frame.reason in (None, *FRAME_REASONS)
        assert (frame.text is None) == (frame.reason is not None)
        if frame.text is not None:
            assert frame.text.encode("ascii") == frame.raw and frame.text.isprintable()
            assert len(frame.text) <= 180
            result = decode(frame.text)
            assert isinstance(
                result, Reject | Gga | Gns | Rmc | Vtg | Gst | Zda | Heading | Rot | Mwv | Attitude
            )
            if isinstance(result, Reject):
                assert result.reason in REJECT_REASONS and "decoder error" not in result.detail
            result = decode(frame.text, require_checksum=False)
            assert not isinstance(result, Reject) or "decoder error" not in result.detail
    return whole


@st.composite
def chopped(draw: st.DrawFn, data_strategy: st.SearchStrategy[bytes]) -> tuple[bytes, list[int]]:
    data = draw(data_strategy)
    cuts = draw(st.lists(st.integers(min_value=0, max_value=len(data)), max_size=12))
    return data, cuts


@settings(max_examples=200, deadline=None)
@given(chopped(streams))
def test_valid_streams_chopped_anywhere_give_the_same_sentences(case: tuple[bytes, list[int]]) -> None:
    data, cuts = case
    frames = check_stream(data, cuts)
    # in order, one frame per sentence, and every one of ours decodes
    expected = []
    rest = data
    while rest:
        s = next(s for s in SAMPLE_BYTES if rest.startswith(s))
        expected.append(s.rstrip(b"\r\n"))
        rest = rest[len(s) :]
    assert [f.raw for f in frames] == expected
    for frame in frames:
        if frame.reason is None and frame.text is not None and not frame.text.startswith("$GPGSV"):
            assert not isinstance(decode(frame.text), Reject)


@settings(max_examples=500, deadline=None)
@given(chopped(st.binary(max_size=400)))
def test_random_bytes_never_raise(case: tuple[bytes, list[int]]) -> None:
    check_stream(*case)


@settings(max_examples=200, deadline=None)
@given(
    chopped(
        st.lists(st.sampled_from(list(b"$!*,\r\n\x00\xffGPAHDT0123456789.NSEW")), max_size=300).map(bytes)
    )
)
def test_nmea_alphabet_soup_never_raises(case: tuple[bytes, list[int]]) -> None:
    check_stream(*case)


INSERTS = [b"$", b"!", b"\r", b"\n", b"\x00", b"\xff", b",", b"*", b"\r\n"]


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    data = bytearray(draw(streams))
    for _ in range(draw(st.integers(min_value=1, max_value=6))):
        if not data:
            break
        op = draw(st.sampled_from(["flip", "drop_comma", "insert", "truncate", "delete"]))
        at = draw(st.integers(min_value=0, max_value=len(data) - 1))
        if op == "flip":
            data[at] = draw(st.integers(min_value=0, max_value=255))
        elif op == "drop_comma":
            comma = data.find(b",", at)
            if comma >= 0:
                del data[comma]
        elif op == "insert":
            data[at:at] = draw(st.sampled_from(INSERTS))
        elif op == "truncate":
            del data[at:]
        else:
            del data[at : at + draw(st.integers(min_value=1, max_value=10))]
    return bytes(data)


@settings(max_examples=800, deadline=None)
@given(chopped(mutated()))
def test_mutated_sentences_never_raise(case: tuple[bytes, list[int]]) -> None:
    check_stream(*case)


@settings(max_examples=300, deadline=None)
@given(
    sample=st.sampled_from(SAMPLES[:10]),
    at=st.integers(min_value=1, max_value=200),
    char=st.characters(min_codepoint=0x20, max_codepoint=0x7E),
)
def test_a_changed_character_is_a_reject_or_an_equal_reading(sample: str, at: int, char: str) -> None:
    """One printable character changed anywhere after '$' is never a silent wrong measurement: a change
    in the body always changes the XOR (bad_checksum); in the checksum field it is a reject or, for a hex
    digit's other case, the same reading."""
    text = sample.rstrip("\r\n")
    at = at % (len(text) - 1) + 1
    changed = text[:at] + char + text[at + 1 :]
    result = decode(changed)
    if changed == text:
        assert not isinstance(result, Reject)
    elif at < len(text) - 3:
        assert isinstance(result, Reject) and result.reason == BAD_CHECKSUM
    else:
        assert isinstance(result, Reject) or result == decode(text)


# The GGA decoder is the generic layout walk unrolled (it runs for every DGPS cycle): the same sentence or
# the same reject, for good fields, bad ones in every position, and too few or too many fields.
_GGA_SAMPLES = [
    "",
    "032551.20",
    "235960",
    "2234.53863009",
    "11431.56",
    "N",
    "S",
    "E",
    "W",
    "x",
    "4",
    "0",
    "9",
    "10",
    "21",
    "0.7",
    "-4.43",
    "nan",
    "inf",
    "1e400",
    "M",
    "03",
    "0000",
    "-1",
    "12a",
    " 5",
    "6061.0",
]
_GGA_FIELD = st.one_of(st.sampled_from(_GGA_SAMPLES), st.text(alphabet="0123456789.-+eENSWM ", max_size=12))
_GOOD_GGA = "032551.20,2234.53863009,N,11431.56012939,E,4,21,0.7,-4.43,M,-1.37,M,03,0000"


@settings(max_examples=400, deadline=None)
@given(talker=st.sampled_from(["GP", "GN"]), fields=st.lists(_GGA_FIELD, min_size=0, max_size=17))
@example(talker="GP", fields=_GOOD_GGA.split(","))
@example(talker="GP", fields=[*_GOOD_GGA.split(",")[:6], "x"])
def test_unrolled_gga_decoder_is_the_layout_walk(talker: str, fields: list[str]) -> None:
    from wire.codecs.nmea import _gga, _gga_reference

    fast, ref = _gga(talker, [f"{talker}GGA", *fields]), _gga_reference(talker, [f"{talker}GGA", *fields])
    assert type(fast) is type(ref)
    assert repr(fast) == repr(ref)  # every field (and a reject's reason) to the bit
