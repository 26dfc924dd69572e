"""Replay: real NMEA logs, simulator and gateway logs, bad time, several observers, tlogs."""

from __future__ import annotations

import fcntl
import json
import math
import os
import pty
import signal
import socket
import struct
import subprocess
import sys
import termios
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import connect_when_listening
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.logreaders import LogCounts, nmea_text_events, tlog_events
from gateway.replay import (
    ObserverSpec,
    ReplayError,
    build_config,
    build_pipeline,
    open_inputs,
    parse_observer_spec,
)
from gateway.replay import run_replay as _run
from observers.kinematics import ssa
from simulator.runner import Simulation
from simulator.scenarios import get_scenario
from wire.codecs import mavlink as mv
from wire.codecs import nmea_encode as enc
from wire.mcap.reader import read_messages
from wire.mcap.writer import McapLogWriter

REPO = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
USV = DATA / "usv-nmea"


def need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} not present (../shared/data beside the clone)")
    return path


def replay_text(path: Path, vessel: str = "cybership2", specs: list[str] | None = None):  # type: ignore[no-untyped-def]
    inputs = open_inputs([path])
    config = build_config(inputs, vessel=vessel)
    parsed = [parse_observer_spec(s) for s in specs] if specs else [ObserverSpec("passive", "passive", {})]
    pipeline = build_pipeline(config, parsed)
    topics = ["/dp/measurement", "/dp/estimate", *(f"/dp/estimates/{s.label}" for s in parsed[1:])]
    return _run(inputs, pipeline, collect=topics), inputs[0]


def replay_text_many(paths: list[Path], vessel: str = "mss_supply"):  # type: ignore[no-untyped-def]
    inputs = open_inputs(paths)
    pipeline = build_pipeline(build_config(inputs, vessel=vessel), [ObserverSpec("passive", "passive", {})])
    return _run(inputs, pipeline, collect=["/dp/measurement", "/dp/estimate"]), inputs


def test_usv_log_an_estimate_every_cycle_and_the_truncated_first_line_counted() -> None:
    result, inp = replay_text(need(USV / "202412051037.txt"))
    cycles = inp.counts.cycles
    est = result.collected["/dp/estimate"]
    assert cycles > 3000
    first = result.collected["/dp/measurement"]
    before_init = next(k for k, m in enumerate(first) if all(v is not None for v in m["eta"]))
    assert len(est) == cycles - before_init  # every cycle after initialisation
    counts = result.counts[f"source {inp.source}"]
    assert counts["garbage"] == 1  # the truncated first line: counted, not fatal


def test_usv_heading_crossing_north_leaves_no_step_and_lf_is_smoother() -> None:
    result, _ = replay_text(need(USV / "202412061745.txt"))
    meas = np.array(
        [[np.nan if v is None else v for v in m["eta"]] for m in result.collected["/dp/measurement"]]
    )
    est = np.array([e["eta"] for e in result.collected["/dp/estimate"]])
    compass = np.mod(meas[:, 2][~np.isnan(meas[:, 2])], 2 * math.pi)  # as the gyro says it: 0..360°
    crossings = np.sum(np.abs(np.diff(compass)) > math.pi)
    assert crossings >= 5  # the log does cross 0°/360°
    dpsi = np.abs(ssa(np.diff(est[:, 2])))
    assert dpsi.max() < math.radians(5.0)  # no 2π step, ever
    assert np.all(np.abs(np.diff(est[:, 2])[dpsi < 1.0]) < 1.0)
    # the LF estimate is smoother than the measurement (first differences)
    m = meas[-len(est) :]
    for k in range(2):
        ok = ~np.isnan(m[:, k])
        assert np.std(np.diff(est[ok, k])) < np.std(np.diff(m[ok, k]))


def _hdt_spikes(path: Path, threshold_deg: float = 5.0) -> list[tuple[float, float]]:
    """(time of day in s, distance from the median in rad) of the cycles whose HDT stands more than
    ``threshold_deg`` from the median of its seven neighbours: a heading that no vessel turns (there and
    back within 0.2 s)."""
    times, headings = [], []
    t = math.nan
    for line in path.read_text(errors="replace").splitlines():
        fields = line.split(",")
        if line.startswith("$") and "GGA" in fields[0] and len(fields) > 1 and len(fields[1]) >= 6:
            hh, mm, ss = fields[1][:2], fields[1][2:4], fields[1][4:]
            t = int(hh) * 3600 + int(mm) * 60 + float(ss)
        elif line.startswith("$") and "HDT" in fields[0] and len(fields) > 1 and fields[1]:
            times.append(t)
            headings.append(float(fields[1]))
    h = np.radians(headings)
    off = [abs(ssa(h[k] - np.median(h[max(0, k - 3) : k + 4]))) for k in range(len(h))]
    return [(times[k], off[k]) for k in range(len(h)) if off[k] > math.radians(threshold_deg)]


def test_usv_heading_glitches_are_what_the_rate_test_rejects() -> None:
    """The USV's GNSS compass gives one-sample heading spikes of 6-14° (there and back within 0.2 s, three
    clusters four and six minutes apart). The jump test rejects spikes and nothing else, and the LF
    heading estimate does not step: at most 1.25° between samples (1.7° when the allowance was 5°, 7°
    at 5 Hz, and the 6-7° spikes passed; now 2°, 4° at 5 Hz)."""
    path = need(USV / "202412051037.txt")
    spikes = _hdt_spikes(path)
    assert len(spikes) >= 3
    inputs = open_inputs([path])
    pipeline = build_pipeline(
        build_config(inputs, vessel="mss_supply"), [ObserverSpec("passive", "passive", {})]
    )
    result = _run(inputs, pipeline, collect=["/dp/status", "/dp/estimate"])
    rejected = [
        (s["stamp_ns"] / 1e9) % 86400
        for s in result.collected["/dp/status"]
        for text in s["events"]
        if text.startswith("heading reference") and "-> rejected" in text
    ]
    assert rejected, "no heading rejected"
    for t in rejected:
        assert min(abs(t - x) for x, _ in spikes) <= 1.0, f"a heading rejected at {t:.1f} s, not at a spike"
    clusters = {round(x / 60) for x, _ in spikes}  # minutes with spikes
    assert len({round(t / 60) for t in rejected} & clusters) >= 2
    counts = next(c for where, c in result.counts.items() if where.startswith("source"))
    # rejected sentences: about as many as the spike samples (a sample next to a spike may fail too)
    assert 1 <= counts.get("test_jump", 0) <= 2 * len(spikes)
    psi = np.array([e["eta"][2] for e in result.collected["/dp/estimate"]])
    assert np.abs(ssa(np.diff(psi))).max() < math.radians(1.25)


@pytest.mark.parametrize("vessel", ["cybership2", "mss_supply"])
def test_usv_compass_spikes_keep_the_heading_out_of_use_only_while_they_last(vessel: str) -> None:
    """The USV's compass spikes (202412051037: a one-sample spike and two bursts of 0.8-1.2 s) are
    rejected and the heading is back in use on the second sample after each, with the small model the
    replay help suggests for the USV (cybership2) as with mss_supply: never out of use longer than the
    burst and 0.4 s, never more than 1.5 s, the observer not restarted and the estimate not stepping.
    Before, a burst's values 0.6 s after the jump passed the jump test (its allowance grows at 10°/s)
    and went into the observer although the compass was 'readmitting'; with cybership2 the estimate
    then turned at 5-6°/s, dead-reckoned 21° off, and the observer restarted (largest step 21.5°)."""
    path = need(USV / "202412051037.txt")
    spikes = [t for t, _ in _hdt_spikes(path)]
    inputs = open_inputs([path])
    pipeline = build_pipeline(build_config(inputs, vessel=vessel), [ObserverSpec("passive", "passive", {})])
    result = _run(inputs, pipeline, collect=["/dp/measurement", "/dp/estimate"])
    assert result.restarts == 0
    meas = result.collected["/dp/measurement"]
    runs: list[tuple[float, float]] = []  # (start, end) time of day of each run of headings not in use
    for m in meas:
        t = (m["stamp_ns"] / 1e9) % 86400
        if not m["valid"][2]:
            if runs and runs[-1][1] < 0:
                continue
            runs.append((t, -1.0))
        elif runs and runs[-1][1] < 0:
            runs[-1] = (runs[-1][0], t)
    assert len(runs) >= 3 and all(end > 0 for _, end in runs), runs
    for start, end in runs:
        near = [x for x in spikes if start - 0.5 <= x <= start + 2.0]
        assert near, f"heading out of use at {start:.1f} s, not at a spike"
        assert end - start <= 1.5, (start, end)
        assert end - max(near) <= 0.6, (start, end, near)  # the last wrong value and two good ones
    psi = np.array([e["eta"][2] for e in result.collected["/dp/estimate"]])
    assert np.abs(ssa(np.diff(psi))).max() < math.radians(1.5)


def test_two_usv_logs_a_day_apart_replay_without_locking_out_the_second() -> None:
    """Two sea-trial logs of the same USV replayed as one, 18 h apart: the second log's references come
    back after the estimate was lost, and the observer restarts from them. Before the restart rule the
    dead-reckoned estimate stayed where the first log ended, the prediction test rejected 754 of the
    second log's 1,701 sentences, and the observer integrated 18 h of dead reckoning in 0.1 s steps."""
    first, second = need(USV / "202412061745.txt"), need(USV / "202412071127.txt")
    inputs = open_inputs([first, second])
    config = build_config(inputs, vessel="mss_supply")
    pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
    result = _run(inputs, pipeline, collect=["/dp/measurement", "/dp/estimate"])
    assert 1 <= result.restarts <= 2  # the heading, then the position (their cycles come 0.2 s apart)
    for where, counts in result.counts.items():
        if where.startswith("source"):
            assert not any(k.startswith("test_") for k in counts), (where, counts)
    # the last estimate sits on the second log's track
    last_meas = [m["eta"] for m in result.collected["/dp/measurement"] if None not in m["eta"]][-1]
    last_est = result.collected["/dp/estimate"][-1]["eta"]
    assert math.hypot(last_est[0] - last_meas[0], last_est[1] - last_meas[1]) < 5.0


def test_a_restart_on_a_heading_alone_does_not_carry_the_velocity_across_the_gap(tmp_path: Path) -> None:
    """Two logs a day apart, the second starting with a cycle of RMC and HDT only (the USV's logs do:
    its first cycle has no GGA). The heading restarts the observer, and the position, not measured in
    that cycle, starts from the dead-reckoned prediction. Before, the prediction moved the last estimate
    on by its velocity for the whole gap: 0.15 m/s for 17 h put the USV's estimate 9.8 km away (plotted
    as a spike in the report); now for at most lost_after_s."""
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    first, second = tmp_path / "a.nmea", tmp_path / "b.nmea"
    write_text_log(first, [t0 + timedelta(seconds=k) for k in range(120)])  # 0.11 m/s north
    t1 = t0 + timedelta(days=1)
    write_text_log(second, [t1 + timedelta(seconds=k + 1) for k in range(20)])
    lead = enc.rmc("GP", t1, 59.4, 10.5, 0.1, 0.2, True) + enc.hdt("HE", 0.3)
    second.write_text(lead + second.read_text())
    result, _ = replay_text_many([first, second])
    fixes = np.array([m["eta"][:2] for m in result.collected["/dp/measurement"] if m["eta"][0] is not None])
    est = np.array([e["eta"][:2] for e in result.collected["/dp/estimate"]])
    lo, hi = fixes.min(axis=0) - 20.0, fixes.max(axis=0) + 20.0  # the vessel's whole track, and 20 m
    far = [p for p in est if not (np.all(p >= lo) and np.all(p <= hi))]
    assert not far, f"{len(far)} estimates off the track, e.g. {far[0]}"
    assert result.restarts == 2  # the heading, then the position


def test_a_receiver_without_a_fix_and_a_gyro_without_a_heading_are_counted() -> None:
    """gpsd's Hemisphere capture: 215 GGA of which 194 say no fix (quality 0, empty fields) and 215 HDT of
    which 211 are empty. Before, the summary said 'received 753, garbage 2' and the replay made 5
    estimates, with nothing to say why; now `test_no_fix` and `test_no_heading` count them (received,
    then refused, as the reference tests count what they refuse)."""
    path = need(DATA / "gpsd-logs" / "hemi.log")
    lines = path.read_text(errors="replace").splitlines()
    no_fix = sum(1 for x in lines if x.startswith("$GPGGA") and x.split(",")[6] == "0")
    empty_hdt = sum(1 for x in lines if x.startswith("$GPHDT") and x.split(",")[1] == "")
    assert (no_fix, empty_hdt) == (194, 211)  # (what the file holds, counted here without dpgw)
    result, inp = replay_text(path, vessel="mss_supply")
    counts = result.counts[f"source {inp.source}"]
    assert counts["test_no_fix"] == no_fix and counts["test_no_heading"] == empty_hdt
    measured = [m["eta"] for m in result.collected["/dp/measurement"]]
    gga = sum(1 for x in lines if x.startswith("$GPGGA"))
    assert sum(1 for m in measured if m[0] is not None) == gga - no_fix  # every fix, and only those


def test_two_logs_years_apart_restart_the_observer_instead_of_dead_reckoning_the_gap(tmp_path: Path) -> None:
    """Two receivers' logs of different years merged (the gpsd captures are from 2011 and 2020): no event
    lies between them, so nothing stepped the observer in the gap. Before, the first fix of the second
    log stepped it across the whole gap, dead reckoning 277 million seconds in RK4 sub-steps (the replay
    ran for hours); a gap without a step longer than ``lost_after_s`` now restarts the observer from the
    returning references, as a reference back after being lost does."""
    first, second = tmp_path / "a.nmea", tmp_path / "b.nmea"
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    write_text_log(first, [t0 + timedelta(seconds=k) for k in range(20)])
    t1 = t0 + timedelta(days=2)  # long enough to see, short enough to finish without the rule
    write_text_log(second, [t1 + timedelta(seconds=k) for k in range(20)])
    inputs = open_inputs([first, second])
    config = build_config(inputs, vessel="mss_supply")
    pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
    lost_after = config.integrity.lost_after_s
    observer, spans, last = pipeline.observer, [], [math.nan]
    step = observer.step

    def spying_step(t: float, y: Any, tau: Any = None) -> Any:
        est = step(t, y, tau)
        if observer.initialized and last[0] == last[0]:
            spans.append(t - last[0])
        last[0] = t
        return est

    observer.step = spying_step  # type: ignore[method-assign]
    observer_reset = observer.reset

    def spying_reset() -> None:
        observer_reset()
        last[0] = math.nan  # a restart integrates nothing: the next step initialises

    observer.reset = spying_reset  # type: ignore[method-assign]
    result = _run(inputs, pipeline, collect=["/dp/status", "/dp/estimate"])
    assert max(spans) <= lost_after, f"the observer dead-reckoned {max(spans):.0f} s in one step"
    assert result.restarts == 1
    events = [text for s in result.collected["/dp/status"] for text in s["events"]]
    assert any(
        text.startswith("observer restarted from the measurement: position back after") for text in events
    )
    assert len(result.collected["/dp/estimate"]) == 40  # every cycle of both logs


@pytest.mark.parametrize(
    "name", ["hemi.log", "nmea-rtk.log", "polarx2.log", "rst39.log", "saab-r4.log", "skytraq-PX1172RH_DS.log"]
)
def test_gpsd_logs_replay_without_error(name: str) -> None:
    result, inp = replay_text(need(DATA / "gpsd-logs" / name), vessel="mss_supply")
    assert inp.counts.lines > 0 and result.events > 0
    c = result.counts[f"source {inp.source}"]
    assert c["received"] > 0


def _compress(data: bytes, fmt: str) -> bytes:
    """``data`` as the tools of each format write it (Zstandard: two frames, as ``zstd`` of a file
    appended to, or `cat a.zst b.zst`)."""
    import bz2
    import gzip
    import lzma

    import zstandard

    if fmt == "zst":
        half = len(data) // 3
        z = zstandard.ZstdCompressor()
        return z.compress(data[:half]) + z.compress(data[half:])
    if fmt == "bz2":  # 100 kB blocks (bzip2 -1): a cut keeps the whole blocks before it (-9's are 900 kB)
        return bz2.compress(data, compresslevel=1)
    return {"gz": gzip.compress, "xz": lzma.compress}[fmt](data)


COMPRESSED = ["gz", "xz", "bz2", "zst"]


@pytest.mark.parametrize("fmt", COMPRESSED)
@pytest.mark.parametrize("fast_scan", [True, False], ids=["compiled scan", "line reader"])
def test_a_compressed_text_log_replays_as_the_log_itself(tmp_path: Path, fast_scan: bool, fmt: str) -> None:
    """Sea-trial logs are archived compressed. Before, a .gz was read as text: no sentence with a time, and
    "nothing to replay" (and an .xz, .bz2 or .zst until later). Now each is decompressed on the fly, with
    the same counts and estimates."""
    plain = need(USV / "202412071127.txt")
    packed = tmp_path / f"202412071127.txt.{fmt}"
    packed.write_bytes(_compress(plain.read_bytes(), fmt))
    runs = []
    for path in (plain, packed):
        inputs = open_inputs([path])
        inputs[0].fast_scan = fast_scan
        pipeline = build_pipeline(
            build_config(inputs, vessel="cybership2"), [ObserverSpec("passive", "passive", {})]
        )
        result = _run(inputs, pipeline, collect=["/dp/estimate"])
        runs.append((inputs[0], result))
    (a, ra), (b, rb) = runs
    assert b.kind == "nmea" and b.source == a.source == "log_202412071127"  # named without .txt.gz
    assert b.counts.lines == a.counts.lines == 1702 and b.counts.cycles == a.counts.cycles
    assert rb.counts[f"source {b.source}"] == ra.counts[f"source {a.source}"]
    assert [e["eta"] for e in rb.collected["/dp/estimate"]] == [
        e["eta"] for e in ra.collected["/dp/estimate"]
    ]


@pytest.mark.parametrize("fmt", COMPRESSED)
@pytest.mark.parametrize("fast_scan", [True, False], ids=["compiled scan", "line reader"])
def test_a_compressed_log_cut_short_replays_up_to_the_cut_and_says_so(
    tmp_path: Path, fast_scan: bool, fmt: str
) -> None:
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    log = tmp_path / "trial.nmea"
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(2000)])
    packed = _compress(log.read_bytes(), fmt)
    cut = tmp_path / f"trial.nmea.{fmt}"
    cut.write_bytes(packed[: len(packed) // 2])  # a copy interrupted half way
    inputs = open_inputs([cut])
    inputs[0].fast_scan = fast_scan
    pipeline = build_pipeline(
        build_config(inputs, vessel="mss_supply"), [ObserverSpec("passive", "passive", {})]
    )
    result = _run(inputs, pipeline, collect=["/dp/estimate"])  # before: EOFError from gzip, a traceback
    name = {"gz": "gzip", "xz": "xz", "bz2": "bzip2", "zst": "zstd"}[fmt]
    assert inputs[0].counts.counts[f"{name}_cut"] == 1
    assert 100 < inputs[0].counts.cycles < 1900  # what came before the cut, replayed
    assert len(result.collected["/dp/estimate"]) >= inputs[0].counts.cycles - 2


@settings(max_examples=60, deadline=None)
@given(
    data=st.binary(max_size=200_000),
    fmt=st.sampled_from(COMPRESSED),
    cut=st.floats(0.0, 1.0),
    read_size=st.integers(1, 100_000),
)
def test_the_decompressed_bytes_are_the_bytes_up_to_a_cut_in_any_reads(
    data: bytes, fmt: str, cut: float, read_size: int
) -> None:
    """Whatever the bytes, the format and the reads' sizes: a whole file gives back exactly its bytes
    and no cut; a file cut anywhere gives back a prefix of them, said cut unless what is left is whole
    (zstd's frames and bzip2's blocks can end at the cut)."""
    import tempfile

    from gateway.compressed import compression_of, open_log, was_cut

    packed = _compress(data, fmt)
    with tempfile.TemporaryDirectory() as folder:
        for size in (len(packed), int(len(packed) * cut)):
            path = Path(folder) / f"log.{fmt}"
            path.write_bytes(packed[:size])
            if size < 6 or compression_of(path) is None:
                continue  # (too short to be told compressed: read as it is)
            with open_log(path) as f:
                got = b"".join(iter(lambda f=f: f.read(read_size), b""))
                cut_at = was_cut(f)
            if size == len(packed):
                assert got == data and cut_at is None
            else:
                assert data.startswith(got)
                assert cut_at is not None or got == data or (fmt == "zst" and got == data[: len(data) // 3])


def test_a_gzipd_mcap_or_a_broken_gzip_is_refused_saying_what_to_do(tmp_path: Path) -> None:
    import gzip

    mcap_gz = tmp_path / "trial.mcap.gz"
    mcap_gz.write_bytes(gzip.compress(b"\x89MCAP0\r\n" + bytes(100)))
    with pytest.raises(ReplayError, match=r"a gzip-compressed MCAP log: .* decompress it first \(gunzip -k "):
        open_inputs([mcap_gz])
    broken = tmp_path / "trial.txt.gz"
    broken.write_bytes(b"\x1f\x8b" + bytes(range(100)))
    with pytest.raises(ReplayError, match=r"starts like a gzip file but does not decompress: give the log"):
        open_inputs([broken])
    for fmt, unpack, magic in (("xz", "unxz -k", b"\xfd7zXZ\x00"), ("zst", "unzstd", b"\x28\xb5\x2f\xfd")):
        packed = tmp_path / f"trial.mcap.{fmt}"
        packed.write_bytes(_compress(b"\x89MCAP0\r\n" + bytes(100), fmt))
        with pytest.raises(ReplayError, match=rf"compressed MCAP log: .* decompress it first \({unpack} "):
            open_inputs([packed])
        broken = tmp_path / f"trial.txt.{fmt}"
        broken.write_bytes(magic + bytes(range(100)))
        with pytest.raises(ReplayError, match=r"file but does not decompress: give the log itself"):
            open_inputs([broken])


def test_the_summary_says_what_each_log_covers_in_its_own_utc_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An analyst checks a replay against the trial's clock: which day, from when to when. Before, the
    summary gave the wall time of the replay and counts only; the report, seconds from its start."""
    from dpgw.cli import main

    path = need(USV / "202412051037.txt")
    times = [
        line.split(",")[1]
        for line in path.read_text(errors="replace").splitlines()
        if line.startswith("$GPGGA")
    ]
    first, last = times[0], times[-1]  # hhmmss.ss of the log's first and last fix (the date is its RMC's)
    assert (
        main(["replay", str(path), "--vessel", "cybership2", "--out", str(tmp_path / "a.mcap"), "--json"])
        == 0
    )
    span = json.loads(capsys.readouterr().out)["spans"]["log 202412051037.txt"]
    assert span["start_utc"] == f"2024-12-05T{first[:2]}:{first[2:4]}:{first[4:6]}.{first[7:9]}0Z"
    assert span["end_utc"] == f"2024-12-05T{last[:2]}:{last[2:4]}:{last[4:6]}.{last[7:9]}0Z"
    assert span["seconds"] == pytest.approx(645.8)
    # across midnight: the end's date is printed too
    log = tmp_path / "night.nmea"
    t0 = datetime(2026, 3, 1, 23, 59, 50, tzinfo=UTC)
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(20)])
    assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "b.mcap")]) == 0
    out = capsys.readouterr().out
    assert (
        "log night.nmea: lines 60, cycles 20; 2026-03-01 23:59:50 to 2026-03-02 00:00:09 UTC (19.0 s)" in out
    )


def write_text_log(path: Path, times: list[datetime], *, dup: int | None = None) -> None:
    lines = []
    for k, t in enumerate(times):
        lat = 59.4 + 1e-6 * k
        cycle = [enc.gga("GP", t, lat, 10.5, 2, 12, 0.8, 10.0), enc.rmc("GP", t, lat, 10.5, 0.1, 0.2, True)]
        cycle.append(enc.hdt("HE", 0.3))
        lines += cycle
        if dup == k:
            lines.append(cycle[-1])
    path.write_text("".join(lines))


def _replay_with_raw(path: Path, tmp_path: Path):  # type: ignore[no-untyped-def]
    inputs = open_inputs([path])
    config = build_config(inputs, vessel="mss_supply")
    pipeline = build_pipeline(config, [ObserverSpec("passive", "passive", {})])
    out = tmp_path / "out.mcap"
    with McapLogWriter(out, flush_on_log_time=False) as w:
        result = _run(inputs, pipeline, out=w)
    raw = "".join(p["text"] + "\n" for t, _, _, p in read_messages(out) if t.startswith("/raw/nmea/"))
    counts = next(c for where, c in result.counts.items() if where.startswith("source"))
    return counts, raw


def test_gpsd_comment_lines_are_counted_as_comments_not_garbage_and_logged_raw(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """gpsd's test logs begin with ``#`` lines (name, submitter, date, licence). Before, replay counted
    each as garbage (saab-r4.log: 'garbage 4'); now as ``comment``, and the raw log keeps them."""
    path = need(DATA / "gpsd-logs" / "saab-r4.log")
    comments = [x for x in path.read_text(errors="replace").splitlines() if x.startswith("#")]
    assert len(comments) == 4
    counts, raw = _replay_with_raw(path, tmp_path)
    assert counts["comment"] == len(comments)
    assert "garbage" not in counts
    for line in comments:
        assert line in raw
    from dpgw.cli import main  # the summary says what they are

    assert main(["replay", str(path), "--vessel", "mss_supply", "--out", str(tmp_path / "s.mcap")]) == 0
    assert "4 comment lines: lines beginning with #" in capsys.readouterr().out


def test_comment_lines_in_a_generated_log_anywhere_and_holding_a_dollar(tmp_path: Path) -> None:
    """A generated log with a header of comments, a comment between two cycles that quotes a sentence
    (its ``$`` starts no sentence) and a line of real noise: the comments are counted as comments, the
    noise as garbage, every cycle still gives its estimate, and the raw log holds every line."""
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    path = tmp_path / "commented.nmea"
    write_text_log(path, [t0 + timedelta(seconds=k) for k in range(20)])
    body = path.read_text().splitlines(keepends=True)
    quoted = "# a fix read: " + body[0].strip()
    lines = ["# Name: generated\r\n", "#\r\n", *body[:30], quoted + "\r\n", "noise\r\n", *body[30:]]
    path.write_text("".join(lines))
    counts, raw = _replay_with_raw(path, tmp_path)
    assert counts["comment"] == 3 and counts["garbage"] == 1, counts
    assert counts["received"] == len(body)  # every sentence still decoded
    assert quoted in raw and "# Name: generated" in raw and "noise" in raw


def test_a_replay_logs_a_status_a_second_of_log_time_as_the_live_gateway_does(tmp_path: Path) -> None:
    """The live gateway logs `/dp/status` at its status rate (1 Hz); a replay's output had one only at a
    reference state change (19 in 220 s of a sea trial), so its counters and alarms in Foxglove were
    minutes apart. Now one a second of the log's time, and the last at the last event, as at a stop."""
    from dpgw.cli import main

    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    path = tmp_path / "five_hz.nmea"
    write_text_log(path, [t0 + timedelta(seconds=0.2 * k) for k in range(300)])  # 60 s at 5 Hz
    out = tmp_path / "out.mcap"
    assert main(["replay", str(path), "--vessel", "mss_supply", "--out", str(out)]) == 0
    stamps = np.array([p["stamp_ns"] for t, _, _, p in read_messages(out) if t == "/dp/status"]) / 1e9
    first, last = t0.timestamp(), (t0 + timedelta(seconds=0.2 * 299)).timestamp()
    assert len(stamps) >= 60 and np.all(np.diff(stamps) <= 1.0 + 1e-6), np.diff(stamps).max()
    assert stamps[0] == pytest.approx(first) and stamps[-1] == pytest.approx(last)
    assert len(set(stamps.tolist())) == len(stamps)  # never two at one time


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_paced_replay_stops_on_ctrl_c_or_sigterm_with_a_complete_output(
    tmp_path: Path, sig: signal.Signals
) -> None:
    """Before: Ctrl-C gave a KeyboardInterrupt traceback; SIGTERM killed the process and left the output
    without its summary. Now it stops between two events, closes the output and says so in one line."""
    from conftest import wait_for

    from wire.mcap.reader import summary

    log, out = tmp_path / "trial.txt", tmp_path / "out.mcap"
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(600)])  # 10 min: never done at --speed 5
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    argv = [sys.executable, "-m", "dpgw", "replay", str(log), "--vessel", "mss_supply", "--out", str(out)]
    proc = subprocess.Popen(
        [*argv, "--speed", "5", "--no-scouting"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=tmp_path,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as a terminal starts it
    )
    try:
        # replaying: the output has its first chunk (the writer flushes about every second of wall time)
        wait_for(lambda: proc.poll() is not None or (out.exists() and out.stat().st_size > 1000), 120.0)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"dpgw replay: stopped ({sig.name}) after "), err
    info = summary(out)
    assert info.complete and info.channels["/dp/estimate"].message_count > 0


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_replay_is_analysed_stops_it_saying_what_is_complete(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], sig: signal.Signals
) -> None:
    """After the replay, its analysis (the summary, the comparison with raw feedback, the report's plots)
    can take as long again. Ctrl-C there gave a KeyboardInterrupt traceback (SIGTERM: a killed process),
    the report half written. Now one line says what is complete and what is not, status 128 + signal. The
    signal is the process's own, sent as the report starts (in process: where it lands is then certain)."""
    import dpgw.cli_replay as cli_replay
    from dpgw.cli import main
    from wire.mcap.reader import summary

    log, out, report = tmp_path / "trial.txt", tmp_path / "out.mcap", tmp_path / "rep"
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(120)])
    real_report = cli_replay._report

    def report_interrupted(*a: Any, **k: Any) -> Any:
        os.kill(os.getpid(), sig)
        return real_report(*a, **k)

    monkeypatch.setattr(cli_replay, "_report", report_interrupted)
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = main(
            ["replay", str(log), "--vessel", "mss_supply", "--out", str(out), "--report", str(report)]
        )
    finally:
        assert {s: signal.getsignal(s) for s in handlers} == handlers  # given back
    err = capsys.readouterr().err
    assert code == 128 + sig, err
    assert "Traceback" not in err
    assert err.splitlines()[-1] == (
        f"dpgw replay: stopped ({sig.name}) after the replay, while analysing it for the summary and the "
        f"report; {out} is complete (the whole log replayed); the report in {report} is incomplete; no "
        "summary"
    ), err
    info = summary(out)
    assert info.complete and info.channels["/dp/estimate"].message_count > 100


def test_ctrl_c_while_a_command_starts_is_one_line_and_status_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Where a command has no stop of its own (here: a replay reading its logs before it replays them; a
    fit, a capability plot), Ctrl-C ends it with one line and the status a shell gives, not a traceback.
    The signal is the process's own, sent while the logs are opened."""
    import gateway.replay
    from dpgw.cli import main

    log = tmp_path / "trial.txt"
    write_text_log(log, [datetime(2026, 3, 1, 12, 0, k, tzinfo=UTC) for k in range(10)])
    real_open = gateway.replay.open_inputs

    def open_interrupted(*a: Any, **k: Any) -> Any:
        os.kill(os.getpid(), signal.SIGINT)
        return real_open(*a, **k)

    monkeypatch.setattr(gateway.replay, "open_inputs", open_interrupted)
    code = main(["replay", str(log), "--vessel", "mss_supply", "--out", str(tmp_path / "out.mcap")])
    err = capsys.readouterr().err
    assert code == 130, err
    assert err.splitlines() == ["dpgw replay: stopped by Ctrl-C before it finished"], err


def test_midnight_rollover_and_bad_time_are_counted(tmp_path: Path) -> None:
    t0 = datetime(2026, 3, 1, 23, 59, 50, tzinfo=UTC)
    times = [t0 + timedelta(seconds=k) for k in range(20)]  # crosses midnight
    times += [times[-1] + timedelta(seconds=30 + k) for k in range(5)]  # a 30 s gap
    times.append(times[-1] - timedelta(seconds=2))  # repeated (an earlier finished cycle)
    times.append(times[-1] - timedelta(seconds=0.5))  # backwards to a time never seen
    times += [times[-3] + timedelta(seconds=k + 1) for k in range(3)]
    log = tmp_path / "trial.nmea"
    write_text_log(log, times, dup=3)
    counts = LogCounts()
    events = list(nmea_text_events(log, "gps", counts=counts))
    stamps = [e.rx_ns for e in events]
    assert stamps[10] - stamps[9] == 1_000_000_000  # 23:59:59 -> 00:00:00 next day, no jump back
    assert datetime.fromtimestamp(stamps[10] / 1e9, UTC).date() == datetime(2026, 3, 2).date()
    assert counts.counts["time_gap"] == 1
    assert counts.counts["repeated_time"] == 1 and counts.counts["time_backwards"] == 1
    assert counts.counts["duplicate"] == 1
    result, _ = replay_text(log)  # and the pipeline takes it all without raising
    assert len(result.collected["/dp/estimate"]) > 20


def test_several_observers_side_by_side(tmp_path: Path) -> None:
    result, _ = replay_text(
        need(USV / "202412071127.txt"),
        specs=["passive:wave_period_s=5", "passive:wave_period_s=10@long", "passive:velocity_injection=0.1"],
    )
    a = result.collected["/dp/estimate"]
    b = result.collected["/dp/estimates/long"]
    c = result.collected["/dp/estimates/passive_velocity_injection0.1"]
    assert len(a) == len(b) == len(c) > 100
    assert a[0]["observer"] == "passive_wave_period_s5" and b[0]["observer"] == "long"
    assert b[0]["omega0"][0] == pytest.approx(2 * math.pi / 10)
    assert a[-1]["eta"] != b[-1]["eta"]  # different filters, different estimates


def test_adaptive_observers_publish_omega0_and_weights_in_the_log(tmp_path: Path) -> None:
    """End to end: the gain-scheduled observer's ω0 (and its estimator's fields) and the
    MMAE's ω0, weights and identified noise reach the estimate messages of the MCAP replay writes."""
    inputs = open_inputs([need(USV / "202412051037.txt")])
    config = build_config(inputs, vessel="cybership2")
    specs = [parse_observer_spec(s) for s in ("passive", "gain_scheduled", "mmae")]
    out = tmp_path / "out.mcap"
    with McapLogWriter(out, flush_on_log_time=False) as w:
        _run(inputs, build_pipeline(config, specs), out=w)
    gs = [p for _, _, _, p in read_messages(out, "/dp/estimates/gain_scheduled")]
    mm = [p for _, _, _, p in read_messages(out, "/dp/estimates/mmae")]
    assert len(gs) > 3000 and len(mm) > 3000
    assert all(len(p["omega0"]) == 3 for p in gs) and gs[-1]["omega0_updates"] > 0
    assert len({tuple(p["omega0"]) for p in gs}) > 1  # scheduled: ω0 moves during the log
    last = mm[-1]
    assert len(last["weights"]) == len(last["candidates"]) == 8
    assert sum(last["weights"]) == pytest.approx(1.0)
    assert last["omega0"][0] == pytest.approx(last["omega0_blended"][0])
    assert all(v > 0 for v in last["measurement_sigma"]) and all(v > 0 for v in last["wave_sigma"])


def test_bad_observer_spec() -> None:
    with pytest.raises(ReplayError, match="wave_peroid"):
        parse_observer_spec("passive:wave_peroid=9")
    with pytest.raises(ReplayError, match="unknown observer"):
        parse_observer_spec("kalman")


def test_an_observer_spec_takes_a_list_joined_by_slashes_and_a_wrong_value_says_so(tmp_path: Path) -> None:
    """MMAE's bank is a list; a spec's commas separate keys, so a list is joined by /. Before, a list
    could not be given, and `mmae:candidates=2.5` stopped with a TypeError traceback."""
    spec = parse_observer_spec("mmae:candidates=2/3.5/5")
    assert spec.params == {"candidates": (2.0, 3.5, 5.0)} and spec.label == "mmae_candidates2_3.5_5"
    log = tmp_path / "trial.nmea"
    write_text_log(log, [datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)])
    config = build_config(open_inputs([log]), vessel="cybership2")
    obs = spec.make(config)
    assert list(obs.extra()["candidates"]) == [2.0, 3.5, 5.0]
    with pytest.raises(ReplayError, match=r"'mmae:candidates=2.5': .*a list is numbers joined by /"):
        parse_observer_spec("mmae:candidates=2.5").make(config)
    with pytest.raises(ReplayError, match=r"candidates must be distinct"):
        parse_observer_spec("mmae:candidates=2/2").make(config)
    with pytest.raises(ReplayError, match=r"zeta takes one number, not a list"):
        parse_observer_spec("passive:zeta=1/2")
    with pytest.raises(
        ReplayError, match=r"not a number \(or true/false, or a list of numbers joined by /\)"
    ):
        parse_observer_spec("mmae:candidates=a/b")


@pytest.mark.slow  # a 300 s simulation, then replay
def test_simulator_log_is_scored_against_its_truth(tmp_path: Path) -> None:
    log = tmp_path / "sim.mcap"
    with McapLogWriter(log) as w:
        Simulation(get_scenario("torsetnes_2004"), seed=4, log=w).run(300.0)
    p = subprocess.run(
        [sys.executable, "-m", "dpgw", "replay", str(log), "--vessel", "mss_supply",
         "--observer", "passive:wave_period_s=11.5", "--observer", "passive:wave_period_s=5@bad",
         "--out", str(tmp_path / "est.mcap"), "--json"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    s = json.loads(p.stdout)
    good = s["error_vs_truth"]["passive_wave_period_s11.5"]
    bad = s["error_vs_truth"]["bad"]
    # Replayed in the datum the simulator logged (not at the first fix, which put every estimate ~0.9 m off
    # the truth's frame): measured 0.35 m horizontal RMS (0.72 m for the badly tuned observer).
    assert good["samples"] > 1000 and good["horizontal_rms_m"] < 0.6
    assert good["horizontal_rms_m"] < bad["horizontal_rms_m"]  # tuned to the sea: closer to the truth
    topics = {t for t, *_ in read_messages(tmp_path / "est.mcap")}
    assert {"/dp/estimate", "/dp/estimates/bad", "/truth/state", "/raw/nmea/dgps1"} <= topics


def test_simulator_log_replays_in_the_datum_its_truth_is_in(tmp_path: Path) -> None:
    """A simulator log records its NED datum (metadata dpgw.sim); replay without a config uses it instead of
    the first fix, so the estimates and the truth share one frame."""
    from dataclasses import replace

    from gateway.replay import build_config, logged_datum, open_inputs
    from simulator.sensors import Datum

    scenario = replace(get_scenario("fossen_strand_1999"), datum=Datum(63.4, 10.4, 12.0))
    log = tmp_path / "sim.mcap"
    with McapLogWriter(log) as w:
        Simulation(scenario, seed=1, log=w).run(5.0)
    assert logged_datum(log) == {"lat_deg": 63.4, "lon_deg": 10.4, "alt_m": 12.0}
    datum = build_config(open_inputs([log]), vessel="northern_clipper").datum
    assert (datum.lat_deg, datum.lon_deg, datum.alt_m, datum.first_fix) == (63.4, 10.4, 12.0, False)


def test_a_cut_log_replays_with_its_own_configuration(tmp_path: Path) -> None:
    """A log cut by kill -9 or power loss (no summary, no metadata index) still carries the configuration and
    the simulator's description at its start: replay finds them, as in a complete log, instead of asking
    for --vessel."""
    from gateway.replay import build_config, open_inputs

    log = tmp_path / "sim.mcap"
    with McapLogWriter(log, background_flush=False, fsync=False) as w:
        w.add_metadata(
            "dpgw.config",
            {
                "json": json.dumps(
                    {
                        "vessel": {"name": "cybership2"},
                        "sources": [
                            {
                                "name": "dgps1",
                                "url": "udp://127.0.0.1:10110",
                                "protocol": "nmea",
                                "roles": ["position"],
                            },
                            {
                                "name": "gyro1",
                                "url": "udp://127.0.0.1:10111",
                                "protocol": "nmea",
                                "roles": ["heading"],
                            },
                        ],
                        "observer": {"wave_period_s": 1.25},
                    }
                )
            },
        )
        Simulation(get_scenario("fossen_strand_1999"), seed=1, log=w).run(5.0)
    data = log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    assert sum(1 for _ in read_messages(cut)) > 0
    config = build_config(open_inputs([cut]))
    assert config.vessel.name == "cybership2"  # the config's, not the simulator's northern_clipper
    assert np.allclose(config.observer.tuning.omega0, 2 * math.pi / 1.25)


def test_a_vessel_file_given_for_a_gateway_log_is_where_the_user_said(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--vessel ship.toml is relative to where dpgw runs, also for a log that carries its own config (before:
    relative to the log's folder, where a vessel file given on the command line is not)."""
    from importlib import resources

    from gateway.replay import build_config, open_inputs

    logs = tmp_path / "logs"
    logs.mkdir()
    log = logs / "trial.mcap"
    sources = [
        {"name": "dgps1", "url": "udp://127.0.0.1:10110", "protocol": "nmea", "roles": ["position"]},
        {"name": "gyro1", "url": "udp://127.0.0.1:10111", "protocol": "nmea", "roles": ["heading"]},
    ]
    with McapLogWriter(log, background_flush=False, fsync=False) as w:
        w.add_metadata(
            "dpgw.config", {"json": json.dumps({"vessel": {"name": "mss_supply"}, "sources": sources})}
        )
        Simulation(get_scenario("fossen_strand_1999"), seed=1, log=w).run(2.0)
    ship = (resources.files("observers") / "vessels" / "cybership2.toml").read_text(encoding="utf-8")
    (tmp_path / "ship.toml").write_text(ship.replace('name = "cybership2"', 'name = "my_ship"', 1))
    monkeypatch.chdir(tmp_path)
    assert build_config(open_inputs([log]), vessel="ship.toml").vessel.name == "my_ship"


def test_replay_of_a_cut_log_says_it_was_cut(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A log cut short replays up to its last complete record, and the replay says so (on the console and
    as `cut_logs` in --json): the result is not the whole trial."""
    from dpgw.cli import main

    log = tmp_path / "sim.mcap"
    with McapLogWriter(log, background_flush=False, fsync=False) as w:
        Simulation(get_scenario("fossen_strand_1999"), seed=1, log=w).run(20.0)
    assert main(["replay", str(log), "--out", str(tmp_path / "a.mcap"), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["cut_logs"] == []
    assert "ends without its summary" not in err
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(log.read_bytes()[: log.stat().st_size * 2 // 3])
    assert main(["replay", str(cut), "--out", str(tmp_path / "b.mcap"), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["cut_logs"] == [str(cut)]
    assert f"dpgw replay: warning: {cut} ends without its summary" in err


def test_simulator_log_replays_with_its_own_vessel(tmp_path: Path) -> None:
    """A simulator log names its vessel (metadata dpgw.sim): replay needs no --vessel; --vessel still wins; a
    vessel that is not built in (only its name is in the log) is one message saying to give its file."""
    log = tmp_path / "sim.mcap"
    with McapLogWriter(log) as w:
        Simulation(get_scenario("fossen_strand_1999"), seed=1, log=w).run(5.0)
    assert build_config(open_inputs([log])).vessel.name == get_scenario("fossen_strand_1999").vessel.name
    assert build_config(open_inputs([log]), vessel="cybership2").vessel.name == "cybership2"
    other = tmp_path / "other.mcap"
    with McapLogWriter(other) as w:
        w.add_metadata("dpgw.sim", {"vessel": "my_ship", "mode": "open loop"})
        w.write_raw_nmea("gyro1", b"$HEHDT,10.0,T*2C\r\n", 1_780_000_000_000_000_000)
    with pytest.raises(ReplayError, match=r"vessel 'my_ship', which is not a built-in vessel: give its file"):
        build_config(open_inputs([other]))


def test_the_count_of_sentences_and_frames_is_every_sources_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A simulator log's MAVLink is one MCAP record per read, several frames each: the summary counted
    records (9,901 "sentences/frames" where its sources received 17,707). Now every source's own count."""
    from dpgw.cli import main

    log = tmp_path / "sim.mcap"
    with McapLogWriter(log) as w:
        Simulation(get_scenario("torsetnes_2004"), seed=1, log=w).run(20.0)
    assert main(["replay", str(log), "--out", str(tmp_path / "o.mcap"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    sources = {k: v for k, v in doc["counts"].items() if k.startswith("source ")}
    assert "source thrusters" in sources
    per_source = sum(
        n for counts in sources.values() for k, n in counts.items() if not k.startswith("warning")
    )
    assert doc["sentences"] == per_source, (doc["sentences"], sources)


def test_tlog_replay(tmp_path: Path) -> None:
    """A MAVLink tlog (8-byte µs time + frame per record) with GPS_RAW_INT, ATTITUDE and thruster status."""
    d = mv.dialect()
    mav = mv.encoder(1, 1)
    t0_us = 1_780_000_000_000_000
    records = bytearray()
    for k in range(100):
        t_us = t0_us + k * 100_000
        for frame in (
            mv.pack(mav, d.MAVLink_attitude_message(k, 0.0, 0.0, 0.7, 0.0, 0.0, 0.0)),
            mv.pack(
                mav, d.MAVLink_gps_raw_int_message(k, 3, 594_000_000, 105_000_000, 0, 100, 100, 0, 0, 12)
            ),
            mv.azimuth_status_frame(mav, t_us, 1, 0.0, 0.0, 0.2, 0),
        ):
            records += struct.pack(">Q", t_us) + frame
    records += b"\x00\x01garbage!!"  # a damaged tail
    path = tmp_path / "boat.tlog"
    path.write_bytes(bytes(records))
    counts = LogCounts()
    assert len(list(tlog_events(path, "boat", counts))) == 300
    result, inp = replay_text(path, vessel="cybership2")
    assert inp.kind == "tlog"
    est = result.collected["/dp/estimate"]
    assert len(est) > 50 and est[-1]["eta"][2] == pytest.approx(0.7, abs=0.01)
    # a tlog's count is of records (one frame each), not of text lines and cycles
    logged = result.counts["log boat.tlog"]
    assert logged["records"] == 300 and "lines" not in logged and "cycles" not in logged


@pytest.mark.slow
def test_speed_publishes_on_zenoh_as_if_live(tmp_path: Path) -> None:
    """`--speed 10`: estimates go out on Zenoh (in another process, this test's) paced at 10× the log's
    time, as a live gateway would publish them: with the live gateway's encoding, `application/json`."""
    log = tmp_path / "trial.nmea"
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    write_text_log(log, [t0 + timedelta(seconds=0.2 * k) for k in range(300)])  # 60 s at 5 Hz
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = int(s.getsockname()[1])
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "dpgw", "replay", str(log), "--vessel", "cybership2",
            "--out", str(tmp_path / "out.mcap"), "--speed", "10", "--prefix", "test/replay",
            "--no-scouting", "--zenoh-listen", f"tcp/127.0.0.1:{port}", "--json",
        ],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    received: list[tuple[float, dict]] = []  # type: ignore[type-arg]
    encodings: set[str] = set()

    def on_sample(s: Any) -> None:
        encodings.add(str(s.encoding))
        received.append((time.monotonic(), json.loads(s.payload.to_bytes())))

    session = connect_when_listening(port, alive=lambda: proc.poll() is None)
    sub = session.declare_subscriber("test/replay/estimate", on_sample)
    stdout, stderr = proc.communicate(timeout=120)
    sub.undeclare()
    session.close()
    assert proc.returncode == 0, stderr
    assert json.loads(stdout)["estimates"]["passive"] == 300
    assert len(received) >= 150  # the subscriber joins a second or two into the 6 s run
    assert encodings == {"application/json"}
    stamps = [p["stamp_ns"] for _, p in received]
    assert stamps == sorted(stamps)
    wall = received[-1][0] - received[0][0]
    log_s = (stamps[-1] - stamps[0]) / 1e9
    assert wall == pytest.approx(log_s / 10, rel=0.3)  # paced, not as fast as possible


@pytest.mark.slow
def test_progress_bar_on_a_terminal(tmp_path: Path) -> None:
    """On a terminal (stderr a tty) replay shows a progress bar; piped (as in the other tests) it does not."""
    log = tmp_path / "trial.nmea"
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    write_text_log(log, [t0 + timedelta(seconds=0.2 * k) for k in range(5000)])
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal has a size
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", "replay", str(log), "--vessel", "cybership2",
         "--out", str(tmp_path / "out.mcap")],
        stdout=subprocess.PIPE, stderr=slave, text=True,
    )  # fmt: skip
    os.close(slave)
    seen = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        seen += chunk
    proc.wait(timeout=120)
    os.close(master)
    assert proc.returncode == 0
    assert b"events" in seen and b"5000" in seen  # tqdm's line: "... 5000 events ..."


def test_a_sentence_split_across_reads_replays_as_it_was_received(tmp_path: Path) -> None:
    """A chunk without a line terminator (TCP and serial deliver sentences in pieces) is logged as such
    and replayed without one, so the next chunk completes the sentence as it did live."""
    from gateway.replay import mcap_events
    from wire.codecs import nmea_encode as enc
    from wire.mcap.writer import McapLogWriter

    gga = enc.hdt("HE", 12.5).encode()
    path = tmp_path / "split.mcap"
    with McapLogWriter(path) as w:
        w.write_raw_nmea("gyro", gga[:9], 1_000)
        w.write_raw_nmea("gyro", gga[9:], 2_000, peer="10.0.0.1:5000")
    events = list(mcap_events(path))
    assert b"".join(e.data for e in events) == gga  # no terminator added inside the sentence
    assert [e.peer for e in events] == ["", "10.0.0.1:5000"]


def test_small_text_logs_use_the_line_reader_and_large_ones_the_compiled_scan(tmp_path: Path) -> None:
    """The path depends on the size only (both give the same events and counts, tested above): a log
    under FAST_SCAN_MIN_BYTES is read line by line (the scan's first call would cost more than it saves),
    a larger one scanned."""
    from datetime import UTC, datetime, timedelta

    from gateway.replay import FAST_SCAN_MIN_BYTES, open_inputs
    from wire.codecs import nmea_encode as enc

    t0 = datetime(2026, 6, 1, tzinfo=UTC)
    small = tmp_path / "small.nmea"
    small.write_text(
        "".join(
            enc.gga("GP", t0 + timedelta(seconds=k), 59.4, 10.5, 2, 12, 0.8, 20.0) + enc.hdt("HE", 1.0)
            for k in range(10)
        )
    )
    (inp,) = open_inputs([small])
    events = list(inp.events())
    assert len(events) == 10 and all(e.checked is None for e in events)  # the pipeline frames the bytes
    inp.fast_scan = True
    events = list(inp.events())
    assert len(events) == 10 and all(e.checked is not None for e in events)
    assert small.stat().st_size < FAST_SCAN_MIN_BYTES


def test_replay_without_out_writes_beside_the_log_and_never_over_it(tmp_path: Path) -> None:
    """`dpgw replay LOG` works as the demo prints it: the output goes to LOG-replay.mcap; --out naming the
    log itself is refused (exit 2) instead of destroying the input."""
    from datetime import UTC, datetime, timedelta

    from dpgw.cli import main
    from wire.codecs import nmea_encode as enc

    t0 = datetime(2026, 6, 1, tzinfo=UTC)
    log = tmp_path / "trial.nmea"
    log.write_text(
        "".join(
            enc.gga("GP", t0 + timedelta(seconds=k), 59.4, 10.5, 2, 12, 0.8, 20.0) + enc.hdt("HE", 1.0)
            for k in range(20)
        )
    )
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 0
    assert (tmp_path / "trial-replay.mcap").stat().st_size > 0
    before = log.read_bytes()
    assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(log)]) == 2
    assert log.read_bytes() == before


def test_observer_spec_switches_are_true_or_false() -> None:
    from gateway.replay import ReplayError, parse_observer_spec

    spec = parse_observer_spec("sdre:adaptive=true,update_period_s=30@a")
    assert spec.params == {"adaptive": 1.0, "update_period_s": 30.0} and spec.label == "a"
    with pytest.raises(ReplayError, match="not a number"):
        parse_observer_spec("sdre:adaptive=maybe")


def test_a_log_from_an_older_gateway_replays() -> None:
    """A config logged before the command rules (commands = true on an unsigned link, no [commands]
    table) still parses for replay: replay sends no commands, and takes every command input as that
    gateway did."""
    from gateway.config import parse_config
    from gateway.replay import _as_replayed

    tables = {
        "vessel": {"name": "mss_supply"},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
            {
                "name": "thr",
                "url": "udp://127.0.0.1:0",
                "protocol": "mavlink",
                "roles": ["thrusters"],
                "commands": True,
            },
        ],
        "log": {"path": ""},
    }
    config = parse_config(_as_replayed(tables), base_dir=Path.cwd())
    assert not config.source("thr").commands
    assert config.commands.accept == {"mode", "setpoint", "tau"}
    assert config.commands.manual_tau_hold_s == math.inf  # that gateway held a manual τ until the next one


def test_a_log_records_the_manual_tau_hold_and_replays_with_it() -> None:
    """A [commands] table is logged with ``manual_tau_hold_s`` written out (its default where not given),
    and replayed with it; one logged without it (a gateway from before the dead-man) replays with the τ
    held until the next one, as that gateway ran."""
    from gateway.config import parse_config
    from gateway.config.logged import for_log
    from gateway.replay import _as_replayed

    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "commands": {"accept": ["mode", "tau"]},
        "log": {"path": ""},
    }
    logged = json.loads(json.dumps(for_log(tables)))  # (as the log's metadata holds it)
    assert logged["commands"] == {"accept": ["mode", "tau"], "manual_tau_hold_s": 2.0}
    assert parse_config(_as_replayed(logged), base_dir=Path.cwd()).commands.manual_tau_hold_s == 2.0
    tables["commands"]["manual_tau_hold_s"] = 0.5
    logged = json.loads(json.dumps(for_log(tables)))
    assert parse_config(_as_replayed(logged), base_dir=Path.cwd()).commands.manual_tau_hold_s == 0.5
    older = {**tables, "commands": {"accept": ["mode", "tau"]}}
    assert parse_config(_as_replayed(older), base_dir=Path.cwd()).commands.manual_tau_hold_s == math.inf


def test_no_foxglove_channels_leaves_them_out_and_every_other_message_unchanged(tmp_path: Path) -> None:
    """`--no-foxglove-channels`: no Foxglove-native topic in the log; the raw input and the JSON channels
    message for message (bytes, times) as in a default replay, which has the Foxglove channels."""
    from mcap.reader import make_reader

    from dpgw.cli import main

    t0 = datetime(2026, 6, 1, tzinfo=UTC)
    log = tmp_path / "trial.nmea"
    lines = []
    for k in range(300):  # 5 Hz, 60 s, a 3 s gap (sources go stale: statuses and /dp/log lines)
        if 100 <= k < 115:
            continue
        t = t0 + timedelta(seconds=0.2 * k)
        lines.append(
            enc.gga("GP", t, 59.4 + 1e-6 * k, 10.5, 2, 12, 0.8, 20.0) + enc.hdt("HE", 1.0 + 0.01 * k)
        )
    log.write_text("".join(lines))

    def messages(out: Path) -> dict[str, list[tuple[int, int, bytes]]]:
        got: dict[str, list[tuple[int, int, bytes]]] = {}
        with out.open("rb") as f:
            for _, channel, m in make_reader(f).iter_messages(log_time_order=False):
                got.setdefault(channel.topic, []).append((m.log_time, m.publish_time, m.data))
        return got

    on, off = tmp_path / "on.mcap", tmp_path / "off.mcap"
    assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(on), "--json"]) == 0
    assert (
        main(["replay", str(log), "--vessel", "mss_supply", "--out", str(off), "--no-foxglove-channels"]) == 0
    )
    with_fx, without = messages(on), messages(off)
    foxglove = {t for t in with_fx if t.startswith(("/gnss/", "/dp/scene/", "/dp/tf", "/dp/log")) or
                t in ("/dp/estimate/fix", "/dp/estimate/pose", "/dp/measurement/pose")}  # fmt: skip
    assert {"/gnss/trial/fix", "/dp/estimate/pose", "/dp/tf", "/dp/scene/hull", "/dp/log"} <= foxglove
    assert set(without) == set(with_fx) - foxglove
    assert {"/raw/nmea/trial", "/dp/measurement", "/dp/estimate", "/dp/status"} <= set(without)
    for topic, msgs in without.items():
        assert msgs == with_fx[topic], topic


def test_observer_specs_keep_the_configs_integrity_and_command_sections() -> None:
    """`--observer` changes the observers and nothing else: a logged or given config's reference-test
    thresholds and command policy stay in force (they were once dropped when specs were given), and the
    replay still commands no thrusters."""
    from gateway.config import parse_config

    tables = {
        "vessel": {"name": "mss_supply"},
        "sources": [
            {
                "name": "dgps1",
                "url": "udp://127.0.0.1:10110",
                "protocol": "nmea",
                "roles": ["position", "heading"],
            }
        ],
        "integrity": {"jump_m": 12.5, "readmit_s": 9.0, "pooling": "priority"},
        "commands": {"accept": ["mode", "setpoint"], "max_setpoint_distance_m": 80.0},
        "log": {"path": ""},
    }
    config = parse_config(tables, base_dir=Path.cwd())
    pipeline = build_pipeline(config, [parse_observer_spec("passive@p"), parse_observer_spec("sdre")])
    spec = pipeline.spec
    assert spec.integrity == config.integrity and spec.integrity.jump_m == 12.5
    assert spec.commands == config.commands and spec.commands.max_setpoint_distance_m == 80.0
    assert spec.observer_name == "p" and [label for label, _ in spec.extra_observers] == ["sdre"]
    assert spec.control is None


def test_an_observer_spec_sets_only_what_the_observer_uses() -> None:
    """Before, every observer took every key of the passive tuning and ignored what it does not use:
    `ekf:zeta_n=3` and `sdre:bias_time_constant_s=50` gave estimates bit for bit the defaults', every key
    was lost on mmae, and `mmae:zeta=0.3` set the (unused) passive ζ instead of the MMAE bank's own ζ."""
    for spec, key in (("ekf:zeta_n=3", "zeta_n"), ("sdre:bias_time_constant_s=50", "bias_time_constant_s")):
        with pytest.raises(
            ReplayError, match=f"does not use {key} of the passive tuning \\(it uses omega0, "
        ):
            parse_observer_spec(spec)
    with pytest.raises(
        ReplayError, match="mmae does not use wave_period_s of the passive tuning \\(it uses none"
    ):
        parse_observer_spec("mmae:wave_period_s=9")
    mmae = parse_observer_spec("mmae:zeta=0.3")
    assert mmae.observer_params() == {"zeta": 0.3} and mmae.tuning_params() == {}
    ekf = parse_observer_spec("ekf:wave_period_s=9,zeta=0.2,position_sigma_m=0.5")
    assert ekf.tuning_params() == {"wave_period_s": 9.0, "zeta": 0.2}
    assert ekf.observer_params() == {"position_sigma_m": 0.5}
    gs = parse_observer_spec("gain_scheduled:zeta_n=2,window_s=60")
    assert gs.tuning_params() == {"zeta_n": 2.0} and gs.observer_params() == {"window_s": 60.0}


def test_a_replays_output_replays_as_its_input_did(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The output keeps the simulator's description (vessel, datum) and, on the log's own configuration,
    that configuration. Before, `dpgw replay OUT.mcap` of a replay's own output stopped with 'no
    configuration in the log', though the output holds the raw input and the truth."""
    from dpgw.cli import main

    log, first, again = tmp_path / "sim.mcap", tmp_path / "a.mcap", tmp_path / "b.mcap"
    with McapLogWriter(log) as w:
        Simulation(get_scenario("fossen_strand_1999"), seed=2, log=w).run(40.0)
    assert main(["replay", str(log), "--out", str(first), "--json"]) == 0
    one = json.loads(capsys.readouterr().out)
    assert main(["replay", str(first), "--out", str(again), "--json"]) == 0
    two = json.loads(capsys.readouterr().out)
    assert one["error_vs_truth"] == two["error_vs_truth"] and one["estimates"] == two["estimates"]
    assert two["error_vs_truth"]["passive"]["samples"] > 50


def test_replay_checks_a_signed_links_frames_against_the_logs_time(tmp_path: Path) -> None:
    """A signed thruster link recorded a year ago, replayed with its key (a config that gives it): every
    stream's first frame is taken whatever its age, and then as live, a frame that is not newer than the
    one before (a replayed frame) or has the wrong key is rejected. Checked against this host's clock, as
    live, every frame of the year-old log would be refused as a replay."""
    from gateway.config import parse_config
    from gateway.pipeline import RawEvent

    key = bytes(range(32))
    tables = {
        "vessel": {"name": "cybership2"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
            {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"],
             "signing_key": key.hex()},
        ],
        "log": {"path": ""},
    }  # fmt: skip
    pipeline = build_pipeline(parse_config(tables, base_dir=tmp_path), [])
    recorded_unix_s = time.time() - 365 * 86_400
    drive = mv.encoder(1, 1)
    mv.setup_signing(drive, key, link_id=0, initial_timestamp=mv.signing_timestamp(recorded_unix_s))
    forger = mv.encoder(1, 1)
    mv.setup_signing(forger, bytes(32), link_id=0, initial_timestamp=mv.signing_timestamp(recorded_unix_s))
    t_ns = int(recorded_unix_s * 1e9)
    frames = [mv.azimuth_status_frame(drive, 200_000 * k, 1, 0.5 + 0.25 * k, 10.0, 0.0, 0) for k in range(3)]
    for k, frame in enumerate(
        [*frames, frames[1], mv.azimuth_status_frame(forger, 600_000, 1, 0.1, 10.0, 0.0, 0)]
    ):
        pipeline.feed(RawEvent(t_ns + k * 200_000_000, "thr", frame))
    counts = pipeline.counters["thr"]
    assert counts.received == 3, counts
    assert counts.rejected["bad_signature"] == 2, counts.rejected  # the repeat and the forgery
    assert pipeline.fusion.thrust[1][0] == 1.0  # the last genuine report


def test_replay_never_overwrites_an_existing_out_and_says_which_file_it_wrote(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--out usv.mcap` where usv.mcap holds an earlier replay: that file stays byte for byte, the replay goes
    on in the next file of its set (usv_0001.mcap, then usv_0002.mcap), as `dpgw run`, `dpgw demo` and
    `dpgw sim` continue theirs, and the console names the file written. Before, it was overwritten."""
    from dpgw.cli import main

    t0 = datetime(2026, 6, 1, 10, tzinfo=UTC)
    before, log = tmp_path / "before.nmea", tmp_path / "usv.nmea"
    write_text_log(before, [t0 + timedelta(seconds=k) for k in range(10)])  # another replay, other bytes
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(20)])
    out = tmp_path / "usv.mcap"
    assert main(["replay", str(before), "--vessel", "mss_supply", "--out", str(out), "--json"]) == 0
    first = capsys.readouterr()
    assert json.loads(first.out)["out"] == str(out) and "never overwritten" not in first.err
    earlier = out.read_bytes()
    for n in (1, 2):
        assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(out), "--report"]) == 0
        again = capsys.readouterr()
        written = tmp_path / f"usv_{n:04d}.mcap"
        assert out.read_bytes() == earlier
        assert f"out -> {written} ({out} exists: a log is never overwritten)" in again.err
        assert f"-> {written}\n" in again.out  # the summary's first line
        topics = {t for t, *_ in read_messages(written)}
        assert "/dp/estimate" in topics
        # the report beside it is the new file's, not the earlier one's
        assert (tmp_path / f"usv_{n:04d}-report" / "report.md").exists()
    # a replay that finds nothing removes only the file it made, never the earlier ones
    empty = tmp_path / "empty.nmea"
    empty.write_text("no sentences here\n")
    assert main(["replay", str(empty), "--vessel", "mss_supply", "--out", str(out)]) == 2
    assert out.read_bytes() == earlier and (tmp_path / "usv_0002.mcap").exists()
    assert not (tmp_path / "usv_0003.mcap").exists()


def test_date_stamped_logs_beside_out_are_not_taken_for_its_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder of sea-trial logs named by date: `trial_2024.mcap` beside a free `trial.mcap`. Before, the
    replay read the date as the set's index and wrote `trial_2025.mcap`, saying `trial.mcap exists`; now
    `--out trial.mcap` is written, and once it exists the next is `trial_0001.mcap` (`dpgw sim --out` the
    same)."""
    from dpgw.cli import main
    from wire.mcap.rotation import free_path

    t0 = datetime(2026, 6, 1, 10, tzinfo=UTC)
    log = tmp_path / "usv.nmea"
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(10)])
    dated = tmp_path / "trial_2024.mcap"
    dated.write_bytes(b"an earlier trial")
    out = tmp_path / "trial.mcap"
    for written in (out, tmp_path / "trial_0001.mcap"):
        assert main(["replay", str(log), "--vessel", "mss_supply", "--out", str(out), "--json"]) == 0
        said = capsys.readouterr()
        assert json.loads(said.out)["out"] == str(written)
        assert ("never overwritten" in said.err) == (written != out), said.err
    assert dated.read_bytes() == b"an earlier trial" and not (tmp_path / "trial_2025.mcap").exists()
    assert free_path(out) == tmp_path / "trial_0002.mcap"
    (tmp_path / "trial_0001.mcap").unlink()  # a gap: the first free file, never one that exists
    assert free_path(out) == tmp_path / "trial_0001.mcap"


def test_a_refused_replay_names_no_file_it_would_have_written_instead(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw replay sim.nmea` with sim-replay.mcap there and no --vessel: it said "out ->
    sim-replay_0001.mcap (...)" and then refused, naming a file it never writes. The new name is said
    once the replay runs."""
    from dpgw.cli import main

    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    log = tmp_path / "sim.nmea"
    write_text_log(log, [t0 + timedelta(seconds=k) for k in range(10)])
    (tmp_path / "sim-replay.mcap").write_bytes(b"an earlier replay")
    assert main(["replay", str(log)]) == 2
    err = capsys.readouterr().err
    assert "names no vessel" in err and "out ->" not in err, err
    assert main(["replay", str(log), "--vessel", "mss_supply"]) == 0
    assert f"out -> {tmp_path / 'sim-replay_0001.mcap'}" in capsys.readouterr().err


def test_the_report_takes_a_users_vessel_file_for_its_length_and_scale(tmp_path: Path) -> None:
    """`--vessel my_usv.toml` (CyberShip II's file under another name, 1:70): the console's wave check
    searched the model's band, but report.md looked the vessel up by its name alone, found no built-in,
    and searched the full-scale band ("length unknown: ... not a built-in vessel"), its warnings with it."""
    from importlib import resources

    from dpgw.cli import main

    own = tmp_path / "my_usv.toml"
    text = (resources.files("observers") / "vessels" / "cybership2.toml").read_text()
    own.write_text(text.replace('name = "cybership2"', 'name = "my_usv"'))
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    log = tmp_path / "usv.nmea"
    write_text_log(log, [t0 + timedelta(seconds=0.2 * k) for k in range(300)])
    report = tmp_path / "rep"
    argv = [
        "replay",
        str(log),
        "--vessel",
        str(own),
        "--out",
        str(tmp_path / "o.mcap"),
        "--report",
        str(report),
    ]
    assert main(argv) == 0
    md = (report / "report.md").read_text()
    assert "- wave band searched: 1.67–16.7 rad/s — Froude-scaled: 1:70 model (L = 1.255 m)" in md, md
    assert "length unknown" not in md


def test_report_md_repeats_every_warning_the_console_gave(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A receiver's log without a heading: the console warned that the observer made no estimate, and
    report.md, read alone, said nothing of it (no Warnings section; `observers: {}`). Its Warnings section
    now repeats the console's lines, as docs/cli.md says."""
    from dpgw.cli import main

    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    log = tmp_path / "gga.nmea"
    log.write_text(
        "".join(
            enc.gga("GP", t0 + timedelta(seconds=k), 59.4 + 1e-6 * k, 10.5, 2, 12, 0.8, 10.0)
            for k in range(60)
        )
    )
    report = tmp_path / "rep"
    argv = [
        "replay",
        str(log),
        "--vessel",
        "mss_supply",
        "--out",
        str(tmp_path / "o.mcap"),
        "--report",
        str(report),
    ]
    assert main(argv) == 0
    err = capsys.readouterr().err
    said = [line.removeprefix("dpgw replay: ") for line in err.splitlines() if "made no estimate" in line]
    assert len(said) == 1, err
    md = (report / "report.md").read_text()
    assert "## Warnings" in md and f"- {said[0]}" in md, md


def test_a_gateway_without_a_commands_table_logs_one_and_its_replay_refuses_what_it_refused() -> None:
    """A gateway configured without ``[commands]`` takes no input (``accept = []``, the default). Its log's
    config had no table either, which is how a log from before the command rules looks, and those replay
    taking every input: the replay obeyed a mode the live gateway had refused. The table is now logged
    with its defaults, and the replay refuses the same."""
    from gateway.config import parse_config
    from gateway.config.logged import for_log
    from gateway.pipeline import ControlEvent, Pipeline, PipelineSpec
    from gateway.replay import _as_replayed

    tables: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "log": {"path": ""},
    }
    live = parse_config(tables, base_dir=Path.cwd())
    assert live.commands.accept == set()
    logged = json.loads(json.dumps(for_log(tables)))  # (as the log's metadata holds it)
    assert logged["commands"] == {"accept": [], "manual_tau_hold_s": 2.0}
    replayed = parse_config(_as_replayed(logged), base_dir=Path.cwd())
    assert replayed.commands.accept == set() and replayed.commands.manual_tau_hold_s == 2.0
    p = Pipeline(PipelineSpec.from_config(replayed))
    p.feed(ControlEvent(1, "mode", "manual"))
    assert p.mode == "standby" and sum(p.commands.counters.refused.values()) == 1
    # a [commands] table given only in part gets the rest of its defaults written out too
    partial = json.loads(json.dumps(for_log({**tables, "commands": {"max_setpoint_distance_m": 20.0}})))
    assert partial["commands"]["accept"] == [] and partial["commands"]["manual_tau_hold_s"] == 2.0
