"""A capture of a ship's network whose sentences carry no time but whose TAG blocks carry ``c:``.

A gyro's group captured alone (HDT, ROT behind ``\\s:HE0001,n:..,c:1780308000.1*hh\\``) has no sentence with a
time of day. Before, it replayed nothing (``no_time`` for every line). Now it is read by its ``c:`` times,
as a logger's stamped file is (`gateway.stamped_log`), and merges by time with the receiver's log."""

from __future__ import annotations

import json
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gateway.logreaders import LogCounts
from gateway.stamped_log import is_stamped_only, line_tag_time, stamped_text_events, tag_time_ns
from tests.test_mixed_rate_text_logs import sea_trial
from wire.codecs.nmea_tag import encode_tag

NS = 1_000_000_000
START = int(datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC).timestamp())  # torsetnes_2004's start
HEADER = b"UdPbC\x00"


@given(st.integers(min_value=10**9, max_value=4 * 10**9 - 1), st.integers(min_value=0, max_value=999))
def test_c_is_read_as_seconds_or_milliseconds(seconds: int, ms: int) -> None:
    t = seconds * NS + ms * 1_000_000
    assert tag_time_ns(f"{seconds}.{ms:03d}") == t == tag_time_ns(f"{seconds * 1000 + ms}")
    assert tag_time_ns(str(seconds)) == seconds * NS
    line = HEADER + encode_tag({"s": "HE0001", "n": "7", "c": f"{seconds}.{ms:03d}"}) + b"$HEHDT,45.9,T*2F"
    got = line_tag_time(line)
    assert got is not None and got[0] == t


NOT_TIMES = ["", "17803080", "17803080001", "1780308000.", "1780308000.1234567890", "178030800010.5",
             "1780308000,1", "-1780308000", "1e9", "\uff11" * 10]  # fmt: skip


@pytest.mark.parametrize("value", NOT_TIMES)
def test_what_is_no_time_is_none(value: str) -> None:
    assert tag_time_ns(value) is None


def test_a_damaged_block_gives_no_time() -> None:
    good = encode_tag({"s": "HE0001", "c": str(START)})
    damaged = good.replace(b"HE0001", b"HE0002")  # (its checksum no longer matches)
    assert line_tag_time(good + b"$HEHDT,45.9,T*2F") is not None
    assert line_tag_time(damaged + b"$HEHDT,45.9,T*2F") is None
    assert line_tag_time(encode_tag({"s": "HE0001"}) + b"$HEHDT,45.9,T*2F") is None  # (no c:)


def gyro_capture(trial: Path, out: Path, devices: tuple[str, ...] = ("HE0001",), unit: str = "s") -> Path:
    """``trial``'s gyro sentences (10 Hz, an HDT and its ROT) as each of ``devices`` sent them on the
    network, timed by ``c:`` in seconds with milliseconds or in milliseconds, one datagram a sentence."""
    lines: list[bytes] = []
    j, n = -1, dict.fromkeys(devices, 0)
    for line in trial.read_bytes().splitlines():
        if line[3:6] not in (b"HDT", b"ROT"):
            continue
        j += line[3:6] == b"HDT"
        ms = START * 1000 + 100 * j
        c = f"{ms // 1000}.{ms % 1000:03d}" if unit == "s" else str(ms)
        for device in devices:
            n[device] += 1
            lines.append(HEADER + encode_tag({"s": device, "n": str(n[device]), "c": c}) + line)
    out.write_bytes(b"\r\n".join(lines) + b"\r\n")
    return out


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    folder = tmp_path_factory.mktemp("trial")
    plain, truth = sea_trial(folder, 300)
    gps = folder / "gps.nmea"
    gps.write_bytes(b"".join(ln for ln in plain.read_bytes().splitlines(keepends=True) if ln[3:6] != b"HDT"
                             and ln[3:6] != b"ROT"))  # fmt: skip
    return plain, gps, truth


def test_a_gyro_capture_is_one_read_per_c_time(trial: tuple[Path, Path, Path], tmp_path: Path) -> None:
    plain, _, _ = trial
    capture = gyro_capture(plain, tmp_path / "he.nmea")
    assert is_stamped_only(capture)
    counts = LogCounts()
    events = list(stamped_text_events(capture, "he", counts=counts))
    assert len(events) == 3000 and counts.counts["tag_time"] == 6000 and not counts.counts["no_stamp"]
    assert [e.rx_ns for e in events] == [START * NS + k * NS // 10 for k in range(3000)]
    assert all(e.data.startswith(b"$HEHDT") and e.data.count(b"\r\n") == 2 for e in events)  # (blocks off)


def replay(*args: str) -> dict:
    done = subprocess.run([sys.executable, "-m", "dpgw", "replay", *args, "--json"],
                          check=True, capture_output=True, text=True, timeout=600)  # fmt: skip
    return json.loads(done.stdout)


@pytest.mark.parametrize("unit", ["s", "ms"])
def test_a_gyro_capture_and_the_receivers_log_replay_together_against_the_truth(
    trial: tuple[Path, Path, Path], tmp_path: Path, unit: str
) -> None:
    plain, gps, truth = trial
    capture = gyro_capture(plain, tmp_path / "he.nmea", unit=unit)
    s = replay(str(gps), str(capture), "--vessel", "mss_supply", "--truth", str(truth), "--out",
               str(tmp_path / "r.mcap"))  # fmt: skip
    assert s["counts"]["source he"]["received"] == 6000
    assert s["counts"]["log he.nmea"]["tag_time"] == 6000 and "no_time" not in s["counts"]["log he.nmea"]
    e = s["error_vs_truth"]["passive"]
    assert e["samples"] >= 9 * 240 and e["rms_heading_deg"] < 0.4 and e["horizontal_rms_m"] < 1.0


def test_a_capture_of_two_gyros_is_a_source_per_device_that_counts_its_lost_lines(
    trial: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    plain, gps, truth = trial
    capture = gyro_capture(plain, tmp_path / "navd.nmea", devices=("HE0001", "HE0002"))
    lines = capture.read_bytes().splitlines(keepends=True)
    # (not its first line: lines lost before the first one seen cannot be told from a late start)
    lost = [k for k in range(50, len(lines)) if b"s:HE0002" in lines[k] and k % 50 == 1]
    capture.write_bytes(b"".join(ln for k, ln in enumerate(lines) if k not in set(lost)))
    s = replay(str(gps), str(capture), "--vessel", "mss_supply", "--truth", str(truth), "--out",
               str(tmp_path / "r.mcap"))  # fmt: skip
    one, two = s["counts"]["source navd_he0001"], s["counts"]["source navd_he0002"]
    assert one["received"] == 6000 and not one.get("lost_lines")
    assert two["received"] == 6000 - len(lost) and two["lost_lines"] == len(lost)
    assert s["error_vs_truth"]["passive"]["rms_heading_deg"] < 0.4


def test_a_groups_later_line_without_c_goes_with_the_read_before_it(tmp_path: Path) -> None:
    first = (
        HEADER + encode_tag({"g": "1-2-7", "s": "HE0001", "n": "1", "c": str(START)}) + b"$HEHDT,45.9,T*2F"
    )
    later = HEADER + encode_tag({"g": "2-2-7", "n": "2"}) + b"$HEROT,0.1,A*31"
    log = tmp_path / "he.nmea"
    log.write_bytes(first + b"\r\n" + later + b"\r\n")
    for keep_tags in (False, True):
        counts = LogCounts()
        (event,) = stamped_text_events(log, "he", counts=counts, keep_tags=keep_tags)
        assert event.rx_ns == START * NS and counts.counts["tag_time"] == counts.counts["no_stamp"] == 1
        lines = event.data.split(b"\r\n")[:-1]
        assert [ln[ln.index(b"$") :] for ln in lines] == [b"$HEHDT,45.9,T*2F", b"$HEROT,0.1,A*31"]
        assert all(ln.startswith(b"\\") == keep_tags and HEADER not in ln for ln in lines)


BYTES = st.binary(max_size=60).map(lambda b: b.replace(b"\n", b"").replace(b"\r", b""))
TAG_TEXT = st.text(
    st.characters(min_codepoint=0x21, max_codepoint=0x7E, exclude_characters="\\,*"), max_size=14
)
LINE = st.one_of(
    st.builds(  # a good line, its time anywhere in a minute
        lambda ms, dev: (
            HEADER + encode_tag({"s": dev, "c": f"{START + ms // 1000}.{ms % 1000:03d}"}) + b"$HEHDT,1.0,T*00"
        ),
        st.integers(0, 59_999),
        st.sampled_from(["HE0001", "HE0002"]),
    ),
    st.builds(lambda c: HEADER + b"\\s:HE0001,c:" + c + b"*00\\$HEHDT,1.0,T*00", BYTES),  # damaged
    st.builds(lambda c: encode_tag({"g": "2-2-7", "c": c}) + b"$HEROT,0.1,A*31", TAG_TEXT),  # c: anything
    BYTES,  # anything
)


@given(st.lists(LINE, max_size=40), st.booleans())
def test_no_line_is_lost_and_nothing_raises(lines: list[bytes], keep_tags: bool) -> None:
    """Whatever a capture holds, the reader never raises, and every line is in an event or counted: a line
    before the first time is counted (``no_stamp``) and left out, every other one kept, in order, in a
    read at its run's time."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "capture.nmea"
        # (an empty first line: a file that begins with a compressor's magic bytes is read as compressed)
        log.write_bytes(b"\r\n" + b"".join(ln + b"\r\n" for ln in lines))
        counts = LogCounts()
        events = list(stamped_text_events(log, "he", counts=counts, keep_tags=keep_tags))
    kept = [ln for e in events for ln in e.data.split(b"\r\n")[:-1]]
    nonempty = [ln for ln in lines if ln]
    first = next((k for k, ln in enumerate(nonempty) if line_tag_time(ln) is not None), len(nonempty))
    assert len(kept) == len(nonempty) - first
    assert counts.counts["tag_time"] + counts.counts["no_stamp"] == len(nonempty)
    times = [got[0] for ln in nonempty if (got := line_tag_time(ln)) is not None]
    runs = [t for k, t in enumerate(times) if k == 0 or t != times[k - 1]]
    assert [e.rx_ns for e in events] == runs  # a read per run of one time, at that time
