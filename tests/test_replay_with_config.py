"""`dpgw replay LOG --config FILE` of an NMEA text log or a tlog: the log is replayed on the config's sources.

Before, a text log's events went to a source named after its file (``trial``), which a user's config has
no reason to hold: the pipeline dropped every line, silently ("source bridge_mux: received 0", no
estimate, and a hint to add a log of the missing sensor). Now the log goes to the source named as its
file, else to the config's sources of its protocol when no two share a role, else where ``--source
NAME=LOG`` says, and a ship network's capture's devices to the sources whose ``tag_source`` names them.
Replayed with a config that matches the simulated sensors, the estimate is the one `--vessel` gives
(torsetnes_2004, 300 s, against the plant's truth: horizontal RMS 0.724 m either way)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dpgw.cli import main
from tests.test_mixed_rate_text_logs import sea_trial
from tests.test_network_capture_replay import network_capture, replay

HEAD = """
[vessel]
name = "mss_supply"

[datum]
first_fix = true
"""


def source(name: str, roles: list[str], port: int, host: str = "127.0.0.1", **extra: str | int) -> str:
    more = "".join(f"{k} = {json.dumps(v)}\n" for k, v in extra.items())
    return (
        f'\n[[sources]]\nname = "{name}"\nurl = "udp://{host}:{port}"\nprotocol = "nmea"\n'
        f"roles = {json.dumps(roles)}\n{more}"
    )


def config(folder: Path, name: str, *sources: str) -> Path:
    path = folder / f"{name}.toml"
    path.write_text(HEAD + "".join(sources))
    return path


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return sea_trial(tmp_path_factory.mktemp("trial"), 300)


@pytest.fixture(scope="module")
def by_vessel(trial: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    plain, truth = trial
    out = tmp_path_factory.mktemp("vessel") / "v.mcap"
    return replay(str(plain), "--vessel", "mss_supply", "--truth", str(truth), "--out", str(out))


def horizontal_rms(summary: dict) -> float:
    return summary["error_vs_truth"]["passive"]["horizontal_rms_m"]


@pytest.mark.parametrize(
    "sources",
    [
        [source("bridge_mux", ["position", "heading"], 10110)],  # one source of the protocol
        [source("gnss", ["position"], 10110), source("gyro", ["heading"], 10111)],  # no role shared
    ],
    ids=["one source", "a source per role"],
)
def test_a_text_log_is_replayed_on_the_configs_sources_as_with_vessel(
    trial: tuple[Path, Path], by_vessel: dict, tmp_path: Path, sources: list[str]
) -> None:
    plain, truth = trial
    cfg = config(tmp_path, "vessel", *sources)
    summary = replay(
        str(plain), "--config", str(cfg), "--truth", str(truth), "--out", str(tmp_path / "r.mcap")
    )
    lines = plain.read_text().count("\n")
    assert all(c["received"] == lines for k, c in summary["counts"].items() if k.startswith("source "))
    assert summary["estimates"]["passive"] >= 2900
    assert horizontal_rms(summary) == pytest.approx(horizontal_rms(by_vessel), abs=0.01)


def test_sources_that_share_a_role_need_the_user_to_say_which_takes_the_log(
    trial: tuple[Path, Path], by_vessel: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain, truth = trial
    cfg = config(
        tmp_path,
        "two_receivers",
        source("dgps1", ["position"], 10110, priority=1),
        source("dgps2", ["position"], 10111, priority=2),
        source("gyro", ["heading"], 10112),
    )
    out = tmp_path / "r.mcap"
    assert main(["replay", str(plain), "--config", str(cfg), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and not out.exists()
    assert "3 nmea sources that share a role (dgps1: position, dgps2: position, gyro: heading)" in err
    assert "--source dgps1=trial.nmea" in err
    summary = replay(
        str(plain), "--config", str(cfg), "--source", "dgps1=trial.nmea", "--source", f"gyro={plain}",
        "--truth", str(truth), "--out", str(out),
    )  # fmt: skip
    counts = summary["counts"]
    assert counts["source dgps2"]["received"] == 0 and counts["source dgps1"]["received"] > 0
    assert horizontal_rms(summary) == pytest.approx(horizontal_rms(by_vessel), abs=0.01)


def test_a_network_capture_goes_to_the_sources_that_take_its_devices(
    trial: tuple[Path, Path], by_vessel: dict, tmp_path: Path
) -> None:
    plain, truth = trial
    capture, _ = network_capture(plain, tmp_path / "navd.nmea", second_receiver_m=100.0)
    cfg = config(
        tmp_path,
        "navd",
        source("dgps1", ["position"], 60004, "239.192.0.4", tag_source="GP0001"),
        source("gyro", ["heading"], 60004, "239.192.0.4", tag_source="HE0001"),  # (GP0002: none takes it)
    )
    summary = replay(
        str(capture), "--config", str(cfg), "--truth", str(truth), "--out", str(tmp_path / "r.mcap")
    )
    counts = summary["counts"]
    assert counts["source dgps1"]["received"] == plain.read_text().count("$GP")
    assert counts["source gyro"]["received"] == plain.read_text().count("$HE")
    assert counts["log navd.nmea"]["no_source"] == plain.read_text().count("GGA,")  # GP0002's lines
    assert horizontal_rms(summary) == pytest.approx(horizontal_rms(by_vessel), abs=0.01)


@pytest.mark.parametrize(
    ("flag", "said"),
    [
        ("gnsss=trial.nmea", "has no source 'gnsss', did you mean 'gnss'? (it has: gnss, gyro)"),
        ("gnss=other.nmea", "'other.nmea' is not one of the logs given"),
        ("gnss", "expected NAME=LOG"),
        ("mav=trial.nmea", "source 'mav' is mavlink, and trial.nmea holds nmea"),
    ],
)
def test_a_wrong_source_flag_is_one_line_that_says_what_is_wrong(
    trial: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, said: str
) -> None:
    plain, _ = trial
    mav = '\n[[sources]]\nname = "mav"\nurl = "udpin:127.0.0.1:14550"\nprotocol = "mavlink"\n'
    mav += 'roles = ["thrusters"]\n'
    cfg = config(tmp_path, "c", source("gnss", ["position"], 10110), source("gyro", ["heading"], 10111), mav)
    if "mav=" not in flag:
        cfg.write_text(cfg.read_text().replace(mav, ""))
    assert (
        main(
            ["replay", str(plain), "--config", str(cfg), "--source", flag, "--out", str(tmp_path / "r.mcap")]
        )
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and said in err, err
    assert main(["replay", str(plain), "--vessel", "mss_supply", "--source", "gnss=trial.nmea"]) == 2
    assert "names a source of --config FILE, and none is given" in capsys.readouterr().err


def test_a_gateway_log_whose_sources_are_none_of_the_configs_is_refused(
    trial: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain, _ = trial
    cfg = config(tmp_path, "c", source("gnss", ["position"], 10110), source("gyro", ["heading"], 10111))
    logged = tmp_path / "logged.mcap"
    assert main(["replay", str(plain), "--vessel", "mss_supply", "--out", str(logged)]) == 0
    capsys.readouterr()
    assert main(["replay", str(logged), "--config", str(cfg), "--out", str(tmp_path / "r.mcap")]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        "its sources (trial) are none of --config" in err and "(gnss, gyro)" in err and err.count("\n") == 0
    )


def test_a_gateway_logs_sources_the_config_leaves_out_are_named(
    trial: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A config that leaves a logged sensor out (on purpose: "what if the second receiver had failed"; or
    renamed) replays the rest, and says whose input is not replayed."""
    plain, _ = trial
    capture, _ = network_capture(plain, tmp_path / "navd.nmea", second_receiver_m=1.0)
    logged = tmp_path / "logged.mcap"
    assert main(["replay", str(capture), "--vessel", "mss_supply", "--out", str(logged)]) == 0
    capsys.readouterr()
    cfg = config(
        tmp_path,
        "c",
        source("navd_gp0001", ["position"], 60004, "239.192.0.4", tag_source="GP0001"),
        source("navd_he0001", ["heading"], 60004, "239.192.0.4", tag_source="HE0001"),
    )
    assert main(["replay", str(logged), "--config", str(cfg), "--out", str(tmp_path / "r.mcap")]) == 0
    captured = capsys.readouterr()
    assert (
        f"note: logged.mcap: source navd_gp0002 not in --config {cfg}: its input is not replayed"
        in captured.err
    )
    assert "\n  source navd_gp0001: received" in captured.out
    assert "\n  source navd_gp0002" not in captured.out  # (the live log's alarms may name it)
