"""A text capture of a ship's IEC 61162-450 network (datagram headers, each sentence after a TAG block naming
its device) replays as `dpgw run` takes the network: a source per device, each taking only its device.

Before, such a capture was one source. With a second receiver 100 m from the first (another antenna, no
lever arm configured) in it, the replay of 300 s of torsetnes_2004 made no estimate at all: the fixes
jumped 100 m at every cycle and none was taken. Now the second receiver is a source of its own whose
fixes the prediction test refuses, and the estimate is that of the first receiver alone (horizontal RMS
against the plant's truth 0.726 m, against 0.725 m without the second receiver and 0.724 m for the plain
log); each device's lost lines are counted."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from gateway.line_prefix import CaptureDevices, capture_devices, split_by_device
from gateway.logreaders import LogCounts, nmea_text_events_reference, spread_headings
from gateway.pipeline import RawEvent
from gateway.replay import build_config, open_inputs
from tests.test_mixed_rate_text_logs import sea_trial
from wire.codecs.nmea_encode import checksum
from wire.codecs.nmea_tag import HEADER_450, encode_tag, iec_450_datagram

M_PER_DEG_LAT = 111_320.0


def moved_north(gga: str, metres: float) -> str:
    """A GGA ``metres`` north of ``gga``'s fix (a second antenna), its checksum made anew."""
    fields = gga[1 : gga.rindex("*")].split(",")
    lat = int(fields[2][:2]) + float(fields[2][2:]) / 60 + metres / M_PER_DEG_LAT
    fields[2] = f"{int(lat):02d}{(lat - int(lat)) * 60:09.6f}"
    body = ",".join(fields)
    return f"${body}*{checksum(body)}\r\n"


def network_capture(
    plain: Path, out: Path, *, second_receiver_m: float | None = None, drop_every: int = 0
) -> tuple[Path, int]:
    """``plain``'s sentences as a capture of the network: one datagram a sentence, the receiver's as
    GP0001, the gyro's as HE0001 and, with ``second_receiver_m``, each GGA again from GP0002 that far
    north. Every ``drop_every``-th GP0001 datagram is lost upstream. Returns the capture and how many
    datagrams were lost."""
    counts = {"GP0001": 1, "GP0002": 1, "HE0001": 1}
    parts: list[bytes] = []
    lost = 0

    def send(device: str, sentence: str) -> None:
        nonlocal lost
        data, counts[device] = iec_450_datagram(sentence.encode("ascii"), device, counts[device])
        if device == "GP0001" and drop_every and counts[device] % drop_every == 0:
            lost += 1
            return
        parts.append(data)

    for line in plain.read_text().splitlines(keepends=True):
        send("HE0001" if line.startswith("$HE") else "GP0001", line)
        if second_receiver_m is not None and line[3:6] == "GGA":
            send("GP0002", moved_north(line, second_receiver_m))
    out.write_bytes(b"".join(parts))
    return out, lost


def replay(*args: str) -> dict:
    """`dpgw replay ARGS --json`'s summary."""
    done = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", *args, "--json"],
        check=True, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    return json.loads(done.stdout)


def replay_json(log: Path, truth: Path, out: Path) -> dict:
    return replay(str(log), "--vessel", "mss_supply", "--truth", str(truth), "--out", str(out))


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return sea_trial(tmp_path_factory.mktemp("trial"), 300)


def test_a_second_receiver_100_m_off_is_a_source_of_its_own_and_costs_the_estimate_nothing(
    trial: tuple[Path, Path], tmp_path: Path
) -> None:
    plain, truth = trial
    one, _ = network_capture(plain, tmp_path / "one.nmea")
    two, _ = network_capture(plain, tmp_path / "two.nmea", second_receiver_m=100.0)
    alone = replay_json(one, truth, tmp_path / "one.mcap")
    both = replay_json(two, truth, tmp_path / "two.mcap")

    counts = both["counts"]
    assert {k for k in counts if k.startswith("source ")} == {
        "source two_gp0001",
        "source two_gp0002",
        "source two_he0001",
    }
    # each source took its own device's sentences and no other's
    gga = plain.read_text().count("GGA,")
    assert counts["source two_gp0002"]["received"] == gga
    assert counts["source two_gp0001"]["received"] == plain.read_text().count("$GP")
    assert "other_tag_source" not in counts["source two_gp0001"]
    assert counts["log two.nmea"]["heading_spread"] == 300 * 9  # the gyro's 10 Hz still spread in time
    # the primary receiver's fixes all used; the estimate as good as with it alone
    assert all(not k.startswith("test_") for k in counts["source two_gp0001"]), counts["source two_gp0001"]
    e1, e2 = alone["error_vs_truth"]["passive"], both["error_vs_truth"]["passive"]
    assert e1["samples"] >= 9 * 240 and e2["samples"] >= 9 * 240
    assert e2["horizontal_rms_m"] < 1.05 * e1["horizontal_rms_m"] + 0.02, (e1, e2)
    assert e2["horizontal_rms_m"] < 1.0  # (as one source: a 100 m jump every second)
    assert e2["rms_heading_deg"] < 1.05 * e1["rms_heading_deg"] + 0.02


def test_sentences_lost_upstream_are_counted_for_their_device(
    trial: tuple[Path, Path], tmp_path: Path
) -> None:
    plain, truth = trial
    capture, lost = network_capture(plain, tmp_path / "lossy.nmea", drop_every=7)
    summary = replay_json(capture, truth, tmp_path / "lossy.mcap")
    counts = summary["counts"]
    assert lost > 100
    assert counts["source lossy_gp0001"]["lost_lines"] == lost
    assert "lost_lines" not in counts["source lossy_he0001"]


def test_the_sources_take_their_device_in_the_roles_its_sentences_fill(
    trial: tuple[Path, Path], tmp_path: Path
) -> None:
    plain, _ = trial
    capture, _ = network_capture(plain, tmp_path / "navd.nmea", second_receiver_m=1.0)
    inputs = open_inputs([capture])
    assert inputs[0].device_sources() == {
        "GP0001": "navd_gp0001",
        "HE0001": "navd_he0001",
        "GP0002": "navd_gp0002",
    }
    config = build_config(inputs, vessel="mss_supply")
    got = {s.name: (s.tag_source, s.roles) for s in config.sources}
    assert got == {
        "navd_gp0001": ("GP0001", ("position",)),
        "navd_he0001": ("HE0001", ("heading",)),
        "navd_gp0002": ("GP0002", ("position",)),
    }


def test_a_capture_of_one_device_stays_one_source(trial: tuple[Path, Path], tmp_path: Path) -> None:
    plain, _ = trial
    lines = [ln for ln in plain.read_text().splitlines(keepends=True) if ln.startswith("$GP")]
    one = tmp_path / "gps.nmea"
    one.write_bytes(
        b"".join(iec_450_datagram(ln.encode(), "GP0001", 1 + k % 999)[0] for k, ln in enumerate(lines))
    )
    inputs = open_inputs([one])
    assert inputs[0].device_sources() == {} and inputs[0].sources() == {"gps": "nmea"}


def _tagged(device: str | None, sentence: str, **params: str) -> bytes:
    tag = {"s": device, **params} if device is not None else dict(params)
    return encode_tag({k: v for k, v in tag.items() if v is not None}) + sentence.encode()


def test_capture_devices_finds_each_device_its_sentences_and_the_sentences_of_nobody(tmp_path: Path) -> None:
    lines = [
        HEADER_450 + _tagged("GP0001", "$GPGGA,1*00"),
        _tagged("HE0001", "$HEHDT,1*00"),
        _tagged("HE0001", "$HEROT,1*00"),
        b"$GPVTG,1*00",  # no TAG block
        b"2026-06-01T10:00:00Z $GPZDA,1*00",  # a logger's stamp, no TAG block
        _tagged("GP 01", "$GPGGA,1*00"),  # not a device's name (a space)
        _tagged("GP0002", "$GPGGA,1*00"),
        _tagged("GP0001", "$GPRMC,1*00"),
    ]
    log = tmp_path / "c.nmea"
    log.write_bytes(b"\r\n".join(lines) + b"\r\n")
    assert capture_devices(log) == CaptureDevices(
        {
            "GP0001": frozenset({"GGA", "RMC"}),
            "HE0001": frozenset({"HDT", "ROT"}),
            "GP0002": frozenset({"GGA"}),
        },
        3,
    )
    plain = tmp_path / "p.nmea"
    plain.write_bytes(b"$GPGGA,1*00\r\n" * 10_000 + _tagged("GP0001", "$GPGGA,1*00") + b"\r\n")
    assert capture_devices(plain) == CaptureDevices(
        {}, 0
    )  # (no TAG block in its first buffer: not read through)


def test_split_by_device_keeps_a_groups_later_lines_with_its_first() -> None:
    data = (
        b"\r\n".join(
            [
                _tagged("HE0001", "$HEHDT,1*00", n="1", g="1-2-1"),
                _tagged(None, "$HEROT,1*00", g="2-2-1"),  # (only g: on a group's later line)
                b"$GPVTG,1*00",
                _tagged("GP0001", "$GPGGA,1*00", n="5"),
                _tagged("XX0009", "$XXDPT,1*00"),  # a device without a source of its own
            ]
        )
        + b"\r\n"
    )
    events = list(
        split_by_device(iter([RawEvent(7, "navd", data, cycle=True)]), {"HE0001": "gyro", "GP0001": "gps"})
    )
    assert [(e.rx_ns, e.source, e.data.count(b"\r\n")) for e in events] == [
        (7, "gyro", 2),
        (7, "navd", 2),
        (7, "gps", 1),
    ]
    assert events[0].data.split(b"\r\n")[1].endswith(b"$HEROT,1*00") and all(e.cycle for e in events)


def test_headings_of_a_split_cycle_are_spread_and_come_out_in_time_order(
    trial: tuple[Path, Path], tmp_path: Path
) -> None:
    plain, _ = trial
    capture, _ = network_capture(plain, tmp_path / "navd.nmea")
    counts = LogCounts()
    tagged = nmea_text_events_reference(capture, "navd", counts=counts, keep_tags=True)
    events = list(spread_headings(split_by_device(tagged, {"GP0001": "gps", "HE0001": "gyro"}), counts))
    t = [e.rx_ns for e in events]
    assert t == sorted(t) and counts.cycles == 300 and counts.counts["heading_spread"] == 300 * 9
    gyro = [e for e in events if e.source == "gyro"]
    assert len(gyro) == 3000 and all(e.data.count(b"HDT,") == 1 for e in gyro)
    # each heading at the time it has in the plain log (10 Hz, spread over its cycle)
    plain_events = spread_headings(nmea_text_events_reference(plain, "mux"), LogCounts())
    assert [e.rx_ns for e in gyro] == [e.rx_ns for e in plain_events if b"HDT," in e.data]
    assert {e.source for e in events} == {"gps", "gyro"} and counts.counts["tag GP0001"] > 0
