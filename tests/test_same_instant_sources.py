"""Several sources at one instant of a text log step the observer once.

A text log's cycle can feed several sources at the log's same time: a user's config with a source per role
(the GGA goes to the DGPS source, the HDT to the gyro's), a ship network's capture cut by device. Each
source's event used to step the observer, so every fix time was stepped twice: a step of dt zero and a
second estimate of the same stamp (torsetnes_2004, 300 s, a 1 Hz receiver and a 10 Hz gyro: 3,299
estimates for 3,000 cycles, 299 stamps twice). Now the replay tells the pipeline that another source's
event at the same time comes next (`Pipeline.feed`'s ``defer_step``) and the instant is stepped once, with
both: the same estimates, to the bit, as the log replayed as one source. Sources that share a role (two
receivers) still step in turn, as live: `tests/test_network_capture_replay.py`'s second receiver 100 m
off is refused by the prediction the first one's fix made, not pooled with it."""

from __future__ import annotations

import json
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from gateway.config import parse_config
from gateway.pipeline import Output, Pipeline, PipelineSpec, RawEvent
from gateway.replay import with_next
from tests.test_mixed_rate_text_logs import sea_trial
from tests.test_network_capture_replay import network_capture, replay
from tests.test_replay_with_config import config, source
from tests.test_stamped_log import receiver_and_stamped_gyro
from wire.codecs import nmea_encode as enc
from wire.geodesy import LocalFrame

S = 1_000_000_000
T0 = 1_780_000_000 * S
DATUM = (59.4, 10.5)


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return sea_trial(tmp_path_factory.mktemp("trial"), 300)


@pytest.fixture(scope="module")
def as_one_source(
    trial: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory
) -> list[tuple[int, dict]]:
    plain, _ = trial
    out = tmp_path_factory.mktemp("one") / "one.mcap"
    replay(str(plain), "--vessel", "mss_supply", "--out", str(out))
    return estimates(out)


def estimates(log: Path) -> list[tuple[int, dict]]:
    with log.open("rb") as f:
        return [
            (m.log_time, json.loads(m.data))
            for _, _, m in make_reader(f).iter_messages(topics=["/dp/estimate"], log_time_order=True)
        ]


def twice(stamps: list[int]) -> int:
    return sum(1 for n in Counter(stamps).values() if n > 1)


def test_a_source_per_role_steps_each_instant_once_as_one_source_does(
    trial: tuple[Path, Path], as_one_source: list[tuple[int, dict]], tmp_path: Path
) -> None:
    plain, _ = trial
    cfg = config(tmp_path, "vessel", source("gnss", ["position"], 10110), source("gyro", ["heading"], 10111))
    out = tmp_path / "two.mcap"
    replay(str(plain), "--config", str(cfg), "--out", str(out))
    got = estimates(out)
    assert len(as_one_source) == 3000
    assert twice([t for t, _ in got]) == 0
    assert got == as_one_source  # every stamp and every field of every estimate


def test_a_captures_devices_step_each_instant_once(
    trial: tuple[Path, Path], as_one_source: list[tuple[int, dict]], tmp_path: Path
) -> None:
    plain, _ = trial
    capture, _ = network_capture(plain, tmp_path / "navd.nmea")
    out = tmp_path / "navd.mcap"
    summary = replay(str(capture), "--vessel", "mss_supply", "--out", str(out))
    assert {"source navd_gp0001", "source navd_he0001"} <= set(summary["counts"])  # (two sources)
    got = estimates(out)
    assert twice([t for t, _ in got]) == 0
    assert [t for t, _ in got] == [t for t, _ in as_one_source]


def _pipeline() -> Pipeline:
    def src(name: str, roles: list[str]) -> dict[str, Any]:
        return {"name": name, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": roles}

    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": [src("gps", ["position"]), src("gyro", ["heading"])],
        "observer": {"type": "passive", "wave_period_s": 8.0},
        "log": {"path": ""},
    }
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


def _gga(north: float, east: float) -> bytes:
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(north, east, 0.0)
    when = datetime.fromtimestamp(T0 / S, UTC)  # (the pipeline times a fix by its arrival)
    return enc.gga("GP", when, lat, lon, 2, 12, 0.8, 0.0).encode()


def topics(out: list[Output]) -> list[str]:
    return [o.topic for o in out if o.topic in ("/dp/measurement", "/dp/estimate")]


def test_a_deferred_step_is_taken_with_the_next_event_and_holds_both_measurements() -> None:
    p = _pipeline()
    for k in range(50):  # 5 s of both at every instant, the fix's event deferred to the heading's
        t = T0 + k * S // 10
        assert topics(p.feed(RawEvent(t, "gps", _gga(1.0, 2.0)), True)) == []
        out = p.feed(RawEvent(t, "gyro", enc.hdt("HE", 0.5).encode()))
        measured = [o.message for o in out if o.topic == "/dp/measurement"]
        assert len(measured) == 1 and measured[0].stamp_ns == t
        assert measured[0].valid == [True, True, True]  # the deferred fix and the heading, one step
    assert p.estimates == 50  # (one a step: the observer starts on the first complete measurement)
    # a deferred step is taken by the next event even when that event brings nothing to use
    t = T0 + 50 * S // 10
    p.feed(RawEvent(t, "gps", _gga(1.0, 2.0)), True)
    out = p.feed(RawEvent(t, "gyro", enc.rot("HE", 0.0).encode()))
    assert topics(out) == ["/dp/measurement", "/dp/estimate"]


def test_a_step_owed_is_taken_by_an_event_the_pipeline_cannot_use() -> None:
    p = _pipeline()
    for k, then in enumerate([RawEvent(T0, "nobody", b"$HEHDT,1.0,T*00\r\n"), RawEvent(T0 + S, "gyro", b"")]):
        t = T0 + k * S  # (a source it does not have; the end of a stream)
        assert topics(p.feed(RawEvent(t, "gps", _gga(1.0, 2.0)), True)) == []
        assert topics(p.feed(then)) == ["/dp/measurement"]  # (a fix alone: no estimate yet)


def test_without_deferring_each_event_steps() -> None:
    p = _pipeline()
    t = T0
    out = p.feed(RawEvent(t, "gps", _gga(1.0, 2.0))) + p.feed(
        RawEvent(t, "gyro", enc.hdt("HE", 0.5).encode())
    )
    assert topics(out).count("/dp/measurement") == 2  # (live: inputs never share a receive time)


def test_with_next_pairs_each_event_with_the_one_after() -> None:
    a, b, c = (RawEvent(T0 + k, "gps", b"") for k in range(3))
    assert list(with_next([])) == []
    assert list(with_next([a])) == [(a, None)]
    assert list(with_next([a, b, c])) == [(a, b), (b, c), (c, None)]


def test_a_receivers_log_merged_with_a_gyros_steps_each_instant_once(
    trial: tuple[Path, Path], as_one_source: list[tuple[int, dict]], tmp_path: Path
) -> None:
    """Two files, each a source in both roles (as any text log): the receiver's, timed by its sentences,
    and the gyro's port stamped by its logger. At each fix time both have a cycle: what each measures
    (a position, a heading) tells that they are one instant."""
    plain, _ = trial
    gps, gyro = receiver_and_stamped_gyro(plain, tmp_path)
    out = tmp_path / "merged.mcap"
    replay(str(gps), str(gyro), "--vessel", "mss_supply", "--out", str(out))
    got = estimates(out)
    assert twice([t for t, _ in got]) == 0
    assert len(got) == 3000  # (a step at each stamp of the gyro's: its 10 Hz; the fixes' fall on them)
