"""A logger's file of one serial port, each line stamped with its UTC receive time and no sentence with a
time of day (a gyro's HDT/ROT): replayed by its stamps, and merged by time with the receiver's own log.

Before: "no_time" for every line, no heading, no estimate ("replay it together with a log of the missing
sensor" — which it was)."""

from __future__ import annotations

import gzip
import json
import math
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mixed_rate_text_logs import sea_trial

from gateway.logreaders import LogCounts
from gateway.stamped_log import STAMP, is_stamped_only, parse_zone, stamp_ns, stamped_text_events
from wire.codecs import nmea_encode as enc

T0 = datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC)
NS = 1_000_000_000


@pytest.mark.parametrize(
    ("stamp", "utc"),
    [
        ("2026-06-01T10:00:00.250Z", T0 + timedelta(seconds=0.25)),
        ("2026-06-01 12:00:00.250+02:00", T0 + timedelta(seconds=0.25)),  # (an offset: turned into UTC)
        ("2026-06-01T12:00:00+0200", T0),
        (f"{T0.timestamp() + 0.5:.3f}", T0 + timedelta(seconds=0.5)),
    ],
)
def test_utc_stamps_are_read(stamp: str, utc: datetime) -> None:
    for sep in (" ", ",", ";", "\t"):
        m = STAMP.match(f"{stamp}{sep}$HEHDT,45.9,T*2F".encode())
        assert (
            m is not None
            and stamp_ns(m) == int(utc.replace(microsecond=0).timestamp()) * NS + utc.microsecond * 1000
        )


@pytest.mark.parametrize(
    "line",
    [
        "01/06/2026 10:00:00 $HEHDT,45.9,T*2F",  # day or month first?
        "2026-06-01T10:00:00Z$HEHDT,45.9,T*2F",  # no separator
    ],
)
def test_what_is_no_stamp_is_not_taken(line: str) -> None:
    assert STAMP.match(line.encode()) is None


def test_a_stamp_without_a_zone_is_taken_only_in_the_zone_given() -> None:
    m = STAMP.match(b"2026-06-01 12:00:00.250 $HEHDT,45.9,T*2F")
    assert m is not None and stamp_ns(m) is None  # perhaps local time: not a time without --stamp-zone
    utc = int(T0.timestamp()) * NS + 250_000_000
    assert stamp_ns(m, parse_zone("+02:00")) == utc == stamp_ns(m, parse_zone("+0200"))
    assert stamp_ns(m, parse_zone("UTC")) == utc + 7200 * NS
    for bad in ("CET", "+2", "+25:00", "02:00"):
        with pytest.raises(ValueError, match="is not a zone"):
            parse_zone(bad)


@settings(max_examples=200, deadline=None)
@given(st.datetimes(min_value=datetime(2000, 1, 1), max_value=datetime(2099, 12, 31)), st.integers(0, 999))
def test_iso_stamps_round_trip(when: datetime, ms: int) -> None:
    when = when.replace(microsecond=ms * 1000, tzinfo=UTC)
    m = STAMP.match((when.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z $HEROT,0.1,A*00").encode())
    assert m is not None and stamp_ns(m) == int(when.timestamp()) * NS + ms * 1_000_000


def gyro_file(path: Path, seconds: int = 20, hz: int = 10) -> Path:
    lines = []
    for k in range(seconds * hz):
        t = T0 + timedelta(seconds=k / hz)
        stamp = t.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z "
        lines += [stamp + enc.hdt("HE", 0.8 + 1e-3 * k), stamp + enc.rot("HE", 0.01)]
    path.write_text("".join(lines))
    return path


def test_a_stamped_gyro_file_is_one_read_per_stamp(tmp_path: Path) -> None:
    log = gyro_file(tmp_path / "gyro.nmea")
    assert is_stamped_only(log)
    counts = LogCounts()
    events = list(stamped_text_events(log, "gyro", counts=counts))
    assert len(events) == 200 and counts.cycles == 200 and counts.counts["line_prefix"] == 400
    assert [e.rx_ns for e in events] == [round((T0.timestamp() + k / 10) * 1e9) for k in range(200)]
    assert all(e.data.startswith(b"$HEHDT") and e.data.count(b"\r\n") == 2 and not e.cycle for e in events)


def test_damage_is_counted_and_kept_in_order(tmp_path: Path) -> None:
    log = gyro_file(tmp_path / "gyro.nmea", seconds=2)
    lines = log.read_bytes().splitlines(keepends=True)
    lines.insert(5, b"$HEHDT,1.0,T*00\r\n")  # no stamp: goes with the read before it
    lines.insert(9, lines[0])  # a stamp from before: backwards
    lines.append(b"2026-06-01T10:01:00.000Z $HEHDT,1.0,T*00\r\n")  # a minute on: a gap
    lines.insert(0, b"$HEROT,0.0,A*00\r\n")  # before any stamp: counted, left out
    packed = tmp_path / "gyro.nmea.gz"
    packed.write_bytes(gzip.compress(b"".join(lines)))
    assert is_stamped_only(packed)
    counts = LogCounts()
    events = list(stamped_text_events(packed, "gyro", counts=counts))
    assert counts.counts["no_stamp"] == 2 and counts.counts["time_backwards"] == 1
    assert counts.counts["time_gap"] == 1
    assert sum(e.data.count(b"\r\n") for e in events) == len(lines) - 1  # every line but the unstamped first


def test_a_file_with_sentence_times_is_read_the_ordinary_way(tmp_path: Path) -> None:
    log = tmp_path / "gps.nmea"
    log.write_text(T0.strftime("%Y-%m-%dT%H:%M:%SZ ") + enc.gga("GP", T0, 59.4, 10.5, 2, 12, 0.8, 10.0))
    assert not is_stamped_only(log)
    local = tmp_path / "local.nmea"
    local.write_text("2026-06-01 10:00:00.000 " + enc.hdt("HE", 0.8))
    assert not is_stamped_only(local)  # (no zone: not read by its stamps)


def receiver_and_stamped_gyro(trial: Path, folder: Path) -> tuple[Path, Path]:
    """A `sea_trial` log as two loggers write it: the receiver's sentences (timed by themselves) in
    ``folder``/gps.nmea, and the gyro's port (HDT and ROT, 10 Hz) stamped with its UTC time in
    ``folder``/gyro.nmea."""
    start = datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC)  # torsetnes_2004's start
    gps, gyro, j = [], [], -1
    for line in trial.read_bytes().splitlines():
        if line[3:6] in (b"HDT", b"ROT"):
            j += line[3:6] == b"HDT"  # (the simulator's gyro: 10 Hz, an HDT and its ROT)
            stamp = (start + timedelta(seconds=j / 10)).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z "
            gyro.append(stamp.encode() + line)
        else:
            gps.append(line)
    (folder / "gps.nmea").write_bytes(b"\r\n".join(gps) + b"\r\n")
    (folder / "gyro.nmea").write_bytes(b"\r\n".join(gyro) + b"\r\n")
    return folder / "gps.nmea", folder / "gyro.nmea"


def test_a_receivers_log_and_a_stamped_gyro_log_replay_together_against_the_truth(tmp_path: Path) -> None:
    """A sea trial's two files as two loggers write them: the receiver's sentences (timed by themselves)
    and the gyro's port, stamped. Merged by time, scored against the plant's truth."""
    trial, truth = sea_trial(tmp_path, 300)
    receiver_and_stamped_gyro(trial, tmp_path)
    replay = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(tmp_path / "gps.nmea"), str(tmp_path / "gyro.nmea"),
         "--vessel", "mss_supply", "--truth", str(truth), "--out", str(tmp_path / "r.mcap"), "--json"],
        check=True, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    s = json.loads(replay.stdout)
    assert s["counts"]["source gyro"]["received"] == 2 * 3000
    e = s["error_vs_truth"]["passive"]
    assert e["samples"] >= 9 * 240 and e["rms_heading_deg"] < 0.4 and e["horizontal_rms_m"] < 1.0


def test_a_local_time_gyro_file_replays_with_its_zone_and_says_so_without(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A logger on the bridge writing local time (UTC+2, no zone in its stamps) beside the receiver's log:
    without --stamp-zone the replay says why the gyro gave nothing; with it, the two merge."""
    from dpgw.cli import main

    gps = tmp_path / "gps.nmea"
    fixes = []
    for k in range(20):  # (RMC gives the log its date; a fix that never moves is a frozen receiver)
        t, lat = T0 + timedelta(seconds=k), 59.4 + 2e-6 * math.sin(k)
        fixes += [enc.gga("GP", t, lat, 10.5, 2, 12, 0.8, 10.0), enc.rmc("GP", t, lat, 10.5, 0.1, 0.2, True)]
    gps.write_text("".join(fixes))
    utc_file = gyro_file(tmp_path / "gyro_utc.nmea")
    local = tmp_path / "gyro.nmea"
    lines = utc_file.read_text().splitlines(keepends=True)
    local.write_text(
        "".join(
            (datetime.fromisoformat(ln[:24]) + timedelta(hours=2)).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
            + ln[24:]
            for ln in lines
        )
    )
    args = [str(gps), str(local), "--vessel", "mss_supply", "--json"]
    assert main(["replay", *args, "--out", str(tmp_path / "a.mcap")]) == 0
    without = json.loads(capsys.readouterr().out)
    assert without["counts"]["source gyro"]["received"] == 0
    assert main(["replay", *args, "--out", str(tmp_path / "b.mcap"), "--stamp-zone", "+02:00"]) == 0
    given = json.loads(capsys.readouterr().out)
    assert given["counts"]["source gyro"]["received"] == 400
    assert (
        main(
            [
                "replay",
                str(gps),
                str(utc_file),
                "--vessel",
                "mss_supply",
                "--json",
                "--out",
                str(tmp_path / "c.mcap"),
            ]
        )
        == 0
    )
    as_utc = json.loads(capsys.readouterr().out)
    assert given["estimates"] == as_utc["estimates"] and given["estimates"]["passive"] >= 190
    assert main(["replay", str(local), "--vessel", "mss_supply", "--out", str(tmp_path / "d.mcap")]) == 2
    assert "give the zone the logger wrote in (--stamp-zone UTC" in capsys.readouterr().err
    assert main(["replay", str(local), "--vessel", "mss_supply", "--stamp-zone", "CET"]) == 2
    assert "--stamp-zone: 'CET' is not a zone" in capsys.readouterr().err
