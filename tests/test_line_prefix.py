"""NMEA text logs whose lines carry a logger's time stamp or a TAG block before the sentence
(`gateway.line_prefix`): replayed as their plain twins, the prefixes counted; comments and garbage left
for the framer. Before: "nothing to replay" (no line started with ``$``)."""

from __future__ import annotations

import gzip
import io
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.line_prefix import Unprefixed, open_text_log, prefixes_stripped
from gateway.replay import ObserverSpec, build_config, build_pipeline, open_inputs
from gateway.replay import run_replay as _run
from wire.codecs import nmea_encode as enc


def _tag_block(k: int) -> str:
    """One device's block (a capture naming several replays them as sources of their own:
    tests/test_network_capture_replay.py)."""
    body = f"s:GP0001,c:{1733541951 + k}"
    cs = 0
    for ch in body:
        cs ^= ord(ch)
    return f"\\{body}*{cs:02X}\\"


PREFIXES = {
    "iso": lambda k, t: t.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z ",
    "csv": lambda k, t: t.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + ",",
    "unix;": lambda k, t: f"{t.timestamp():.3f};",
    "tab": lambda k, t: t.strftime("%d/%m/%Y %H:%M:%S") + "\t",
    "tag block": lambda k, t: _tag_block(k),
    # a raw capture of an IEC 61162-450 network (socat, tcpdump's payloads): the datagram header too
    "450 capture": lambda k, t: "UdPbC\x00" + _tag_block(k),
}


def _logs(folder: Path, kind: str, cycles: int = 600) -> tuple[Path, Path]:
    """A plain 2 Hz GGA/RMC/HDT log with a gpsd comment holding a $, and its prefixed twin."""
    t0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
    plain: list[str] = ["# gpsd comment: $GPGGA is not a sentence here\r\n"]
    prefixed: list[str] = list(plain)
    for k in range(cycles):
        t = t0 + timedelta(seconds=0.5 * k)
        lat = 59.4 + 1e-6 * k
        for line in (
            enc.gga("GP", t, lat, 10.5, 2, 12, 0.8, 10.0),
            enc.rmc("GP", t, lat, 10.5, 0.1, 0.2, True),
            enc.hdt("HE", 30.0 + 0.01 * k),
        ):
            plain.append(line)
            prefixed.append(PREFIXES[kind](k, t) + line)
    a, b = folder / "plain.nmea", folder / f"prefixed_{kind.replace(' ', '_').replace(';', '')}.nmea"
    a.write_text("".join(plain))
    b.write_text("".join(prefixed))
    return a, b


def _replay(path: Path, fast_scan: bool) -> tuple[dict[str, int], list[list[float]]]:
    inputs = open_inputs([path])
    inputs[0].fast_scan = fast_scan
    pipeline = build_pipeline(
        build_config(inputs, vessel="mss_supply"), [ObserverSpec("passive", "passive", {})]
    )
    result = _run(inputs, pipeline, collect=["/dp/estimate"])
    counts = dict(inputs[0].counts.counts) | {
        "lines": inputs[0].counts.lines,
        "cycles": inputs[0].counts.cycles,
    }
    return counts, [e["eta"] for e in result.collected["/dp/estimate"]]


@pytest.mark.parametrize("kind", sorted(PREFIXES))
@pytest.mark.parametrize("fast_scan", [True, False], ids=["compiled scan", "line reader"])
def test_a_prefixed_log_replays_as_its_plain_twin(tmp_path: Path, kind: str, fast_scan: bool) -> None:
    plain, prefixed = _logs(tmp_path, kind)
    counts_a, eta_a = _replay(plain, fast_scan)
    counts_b, eta_b = _replay(prefixed, fast_scan)
    assert counts_a["cycles"] == 600 and len(eta_a) >= 590
    assert eta_b == eta_a
    assert counts_b.pop("line_prefix") == 3 * 600
    tags = {k: counts_b.pop(k) for k in list(counts_b) if k.startswith("tag ")}  # the devices TAG blocks name
    assert tags == ({"tag GP0001": 3 * 600} if "TAG" in kind.upper() or "450" in kind else {})
    assert counts_b == counts_a and "line_prefix" not in counts_a


def test_a_compressed_prefixed_log_is_both_decompressed_and_unprefixed(tmp_path: Path) -> None:
    plain, prefixed = _logs(tmp_path, "tag block", cycles=200)
    packed = tmp_path / "prefixed.nmea.gz"
    packed.write_bytes(gzip.compress(prefixed.read_bytes()))
    counts_b, eta_b = _replay(packed, True)
    assert counts_b.pop("line_prefix") == 600
    assert counts_b.pop("tag GP0001") == 600
    assert (counts_b, eta_b) == _replay(plain, True)


SENTENCE = st.builds(
    lambda start, talker, body: f"{start}{talker}{body}",
    st.sampled_from(["$", "!"]),
    st.sampled_from(["GPGGA", "GNHDT", "AIVDM", "HEROT"]),
    st.text(alphabet="0123456789,.ABCNSEW*", max_size=60),
)
PREFIX = st.one_of(
    st.just(""),
    st.builds(lambda s: f"\\{s}\\", st.text(alphabet="sc:,0123456789GP*ABCDEF", max_size=30)),
    st.builds(lambda s: f"UdPbC\x00\\{s}\\", st.text(alphabet="sn:,0123456789GP*", max_size=30)),
    st.builds(
        lambda d, sep: d + sep,
        st.from_regex(r"[0-9][-0-9TZ:./+ ]{0,25}", fullmatch=True),
        st.sampled_from([" ", ",", ";", "\t"]),
    ),
)
OTHER = st.one_of(
    st.builds(lambda s: "# " + s, st.text(alphabet="abc $GPGGA,12", max_size=40)),  # gpsd comment
    st.text(alphabet="xyz$!\\", max_size=20).filter(lambda s: not s[:1].isdigit() and s[:1] != "\\"),
)


@settings(max_examples=200, deadline=None)
@given(
    rows=st.lists(st.one_of(st.tuples(PREFIX, SENTENCE), st.tuples(st.just(""), OTHER)), max_size=60),
    read_size=st.integers(1, 4096),
    newline=st.sampled_from(["\n", "\r\n"]),
)
def test_prefixes_come_off_sentences_and_nothing_else_changes(
    rows: list[tuple[str, str]], read_size: int, newline: str
) -> None:
    """Any mix of prefixed and plain sentences, comments and garbage, read in any sizes: the prefix comes
    off each sentence that has one, every other byte stays, and the count is the prefixes taken off."""
    text = "".join(p + s + newline for p, s in rows).encode()
    want = "".join(s + newline for _, s in rows).encode()
    f = io.BufferedReader(Unprefixed(io.BufferedReader(io.BytesIO(text))))
    got = b"".join(iter(lambda: f.read(read_size), b""))
    assert got == want
    assert prefixes_stripped(f) == sum(1 for p, _ in rows if p)


def test_a_log_without_prefixes_is_read_as_it_is(tmp_path: Path) -> None:
    plain, _ = _logs(tmp_path, "iso", cycles=5)
    with open_text_log(plain) as f:
        assert not isinstance(getattr(f, "raw", None), Unprefixed)
        assert f.read() == plain.read_bytes()
