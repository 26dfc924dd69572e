"""`dpgw replay LOGS --config NETWORK.toml` whose sources take one device each (``tag_source``).

Live, such a source takes only the sentences whose TAG block names its device. Before, a text log fed to it
in replay lost its TAG blocks to the reader, so every sentence was counted ``other_tag_source`` and nothing
was replayed; a plain log (a serial logger's, no TAG blocks) fared the same; and a capture of one device was
not placed on the source that takes it ("sources that share a role ... say which takes the log"). Now a
capture keeps its blocks for the source to read, a capture of one device goes to the source that takes it,
and a plain log is taken whole by the source it is given to, its ``tag_source`` not applied (said)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dpgw.cli import main
from tests.test_mixed_rate_text_logs import sea_trial
from tests.test_network_capture_replay import network_capture
from tests.test_replay_with_config import config, source
from tests.test_stamped_log import receiver_and_stamped_gyro
from tests.test_tag_time import gyro_capture

NAVD = "239.192.0.4"  # (IEC 61162-450's group for navigation: every source listens on it)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("trial")
    plain, truth = sea_trial(folder, 300)
    gps, gyro = receiver_and_stamped_gyro(plain, folder)
    both, _ = network_capture(plain, folder / "navd.nmea")
    gp = folder / "gp0001.nmea"  # the receiver's datagrams alone: a capture of one device, timed by its GGA
    gp.write_bytes(b"".join(ln for ln in both.read_bytes().splitlines(keepends=True) if b"s:GP0001" in ln))
    he = gyro_capture(plain, folder / "he0001.nmea")  # the gyro's alone, timed by c:
    lines = he.read_bytes().splitlines(keepends=True)
    # 12 of its HDTs lost on the network (each a step less: the gyro steps the observer)
    he.write_bytes(b"".join(ln for k, ln in enumerate(lines) if k % 500 != 250))
    return {"truth": truth, "gps": gps, "gyro": gyro, "gp": gp, "he": he, "folder": folder}


def network(folder: Path) -> Path:
    return config(
        folder,
        "network",
        source("dgps1", ["position"], 60004, NAVD, tag_source="GP0001"),
        source("dgps2", ["position"], 60004, NAVD, tag_source="GP0002", priority=2),
        source("gyro", ["heading"], 60004, NAVD, tag_source="HE0001"),
    )


def replay(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[dict, str]:
    assert main(["replay", *args, "--json"]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def assert_estimates_as_with_vessel(summary: dict, steps: int = 3000) -> None:
    assert summary["estimates"]["passive"] == steps
    e = summary["error_vs_truth"]["passive"]
    assert e["horizontal_rms_m"] < 0.74 and e["rms_heading_deg"] < 0.35  # (--vessel: 0.724 m, 0.338 deg)


def test_a_capture_of_one_device_goes_to_the_source_that_takes_it_and_keeps_its_blocks(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = network(tmp_path)
    truth, out = str(logs["truth"]), str(tmp_path / "r.mcap")
    s, _ = replay(
        capsys, str(logs["gp"]), str(logs["he"]), "--config", str(cfg), "--truth", truth, "--out", out
    )
    dgps1, gyro = s["counts"]["source dgps1"], s["counts"]["source gyro"]
    assert dgps1["received"] == 1500 and "other_tag_source" not in dgps1
    assert gyro["received"] == 6000 - 12 and gyro["lost_lines"] == 12  # (read from the kept blocks)
    assert s["counts"]["source dgps2"]["received"] == 0
    assert_estimates_as_with_vessel(s, 3000 - 12)


def test_a_capture_given_to_a_source_keeps_its_blocks(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = network(tmp_path)
    given = [
        "--source",
        f"gyro={logs['he'].name}",
        "--truth",
        str(logs["truth"]),
        "--out",
        str(tmp_path / "r.mcap"),
    ]
    s, _ = replay(capsys, str(logs["gp"]), str(logs["he"]), "--config", str(cfg), *given)
    assert (
        s["counts"]["source gyro"]["received"] == 6000 - 12
        and "other_tag_source" not in s["counts"]["source gyro"]
    )
    assert_estimates_as_with_vessel(s, 3000 - 12)


def test_plain_logs_given_to_sources_that_take_a_device_are_taken_whole_and_it_is_said(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = network(tmp_path)
    given = ["--source", "dgps1=gps.nmea", "--source", "gyro=gyro.nmea"]
    more = ["--truth", str(logs["truth"]), "--out", str(tmp_path / "r.mcap")]
    s, err = replay(capsys, str(logs["gps"]), str(logs["gyro"]), "--config", str(cfg), *given, *more)
    assert s["counts"]["source dgps1"]["received"] == 1500 and s["counts"]["source gyro"]["received"] == 6000
    assert "gps.nmea has no TAG blocks: the tag_source of dgps1 is not applied to it" in err
    assert "gyro.nmea has no TAG blocks: the tag_source of gyro is not applied to it" in err
    assert_estimates_as_with_vessel(s)
