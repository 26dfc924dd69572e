"""The pipeline under fuzzed input (bench/fuzz_gateway.py, 30,000 inputs): mutated NMEA — flipped bytes,
truncations, wrong checksums, garbage fields under valid checksums, overlong lines, random bytes — and
CRC-valid MAVLink frames with random payloads of every dialect message, between a clean on-station GGA+HDT
stream at 10 Hz. Nothing raises, the estimate stays within 0.5 m of the true station, and every input is
counted: received and rejected per source are what the codec layer says of each input alone (of the
same stream for MAVLink, where a frame cut short waits for the next input's bytes)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

from fuzz_gateway import KINDS, SOURCES, run


def test_30000_fuzzed_inputs_leave_the_estimate_on_station_and_are_all_counted() -> None:
    r = run(30_000, seed=7, warmup_s=60.0)
    assert r["inputs"] == 30_000
    assert all(r["inputs_by_kind"][k] > 2000 for k in KINDS)  # every sort of mutation was tried
    assert r["max_position_error_m"] < 0.5
    assert r["max_heading_error_deg"] < 1.0
    for source in SOURCES:
        assert r["counted"][source]["received"] == r["expected"][source]["received"]
        assert r["counted"][source]["rejected"] == r["expected"][source]["rejected"]
    # the bad inputs are the bulk, and each was counted as a reject (MAVLink noise without a frame marker
    # is the codec's "skipped bytes", counted only in the source's bytes)
    rejected = sum(r["counted"][s]["rejected"] for s in SOURCES)
    assert rejected >= 0.6 * r["main_phase_inputs"] - r["silent_inputs"]
    assert r["counted"]["thr"]["received"] > 1000  # CRC-valid random payloads got through the parser
    assert r["rss_growth_kib"] < 5 * 1024


def test_well_formed_outliers_are_set_aside_and_reported() -> None:
    """Valid-checksum sentences whose fields the mutation turned into a far fix or heading are kept out of
    the bounded phase and measured on their own: the report says what they do to the estimate."""
    r = run(10_000, seed=3, warmup_s=30.0)
    o = r["outliers"]
    assert o["inputs"] == sum(o["by_kind"].values())
    assert o["inputs"] < 0.01 * r["inputs"]
    assert o["max_position_error_m"] >= 0.0


def test_with_the_well_formed_outliers_in_the_stream_the_reference_tests_keep_the_estimate() -> None:
    """The same fuzz with the implausible-but-valid inputs left in (far fixes, wild headings, CRC-valid
    thruster status of any thrust): the reference and feedback tests refuse them, so the estimate still
    stays within 0.5 m and 1° of the station (before those tests, they moved it 1.3e24 m)."""
    r = run(30_000, seed=7, warmup_s=60.0, with_outliers=True)
    assert r["max_position_error_m"] < 0.5
    assert r["max_heading_error_deg"] < 1.0
