"""NMEA over a ship's network (IEC 61162-450): datagrams headed ``UdPbC\\0``, each sentence after a TAG block
naming its device, several devices on one multicast group.

The framer takes the header and the TAG blocks as framing, not noise (before: every datagram counted one
``garbage``); a TAG block is checked (its checksum) and read (`wire.codecs.nmea_tag`); a source's
``tag_source`` takes one device's sentences from a group several share (before: two receivers on one
group were one source, their fixes interleaved). Live over a real multicast socket into the running gateway,
the log replaying to the same counts."""

from __future__ import annotations

import math
import socket
import threading
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port, wait_for
from hypothesis import given, settings
from hypothesis import strategies as st
from test_nmea_decode import SAMPLE_BYTES, check_stream, frames_of

from gateway.config import ConfigError, parse_config
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from gateway.replay import config_from_log, mcap_events
from gateway.service import GatewayService
from wire.codecs import nmea_encode as enc
from wire.codecs.nmea_framing import GARBAGE, IEC_61162_450, TAG_BLOCK, Frame
from wire.codecs.nmea_tag import HEADER_450, TagBlock, TagReject, decode_tag, encode_tag, iec_450_datagram

T0 = datetime(2026, 11, 29, 12, 0, 0, tzinfo=UTC)
NS = 1_000_000_000
GROUP = "239.192.0.4"  # IEC 61162-450's NAVD group, where position and heading go


def datagram(source: str, n: int, *sentences: str) -> bytes:
    """One IEC 61162-450 sentence datagram: the header, then each sentence after its TAG block (``s:`` the
    device, ``n:`` its line count from ``n`` on, ``g:`` grouping when there are several)."""
    return iec_450_datagram("".join(sentences).encode("ascii"), source, n)[0]


def reasons(frames: list[Frame]) -> list[str | None]:
    return [f.reason for f in frames]


# ------------------------------------------------------------------------------------------ framing


def test_a_450_datagram_is_header_tag_blocks_and_sentences_with_no_garbage() -> None:
    hdt, rot = enc.hdt("HE", 0.5), enc.rot("HE", 0.01)
    frames = frames_of(datagram("HE0001", 7, hdt, rot))
    assert reasons(frames) == [IEC_61162_450, TAG_BLOCK, None, TAG_BLOCK, None]
    assert frames[0].raw == b"UdPbC\x00"
    assert decode_tag(frames[1].raw) == TagBlock({"s": "HE0001", "n": "7", "g": "1-2-7"})
    assert [f.text for f in frames if f.reason is None] == [hdt.strip(), rot.strip()]


def test_what_is_not_a_tag_block_stays_garbage() -> None:
    hdt = enc.hdt("HE", 0.5).encode()
    for junk, expected in [
        (b"noise \\s:GP0001*00\\", [GARBAGE, TAG_BLOCK]),  # noise before a block: the noise alone
        (b"\\s:GP0001*00\\ ", [GARBAGE]),  # not directly before the sentence
        (b"\\s:GP\x01001*00\\", [GARBAGE]),  # not printable
        (b"\\" + b"x" * 500 + b"\\", [GARBAGE]),  # longer than any TAG block
        (b"UdPbC", [GARBAGE]),  # half a header
        (b"RaUdP\x00", [GARBAGE]),  # a 450 binary-transfer header: no sentences follow it
        (b"UdPbC\x00", [IEC_61162_450]),  # a header without TAG block (not 450, but not noise either)
    ]:
        assert reasons(frames_of(junk + hdt))[:-1] == expected, junk


@st.composite
def tagged_streams(draw: st.DrawFn) -> bytes:
    """Sentences, each perhaps after a TAG block, in datagrams perhaps headed by the 450 header, perhaps
    with the noise a link adds."""
    out = bytearray()
    for _ in range(draw(st.integers(1, 6))):
        if draw(st.booleans()):
            out += HEADER_450
        if draw(st.booleans()):
            out += draw(st.sampled_from([b"", b"xx", b"\\", b"*", b"\\s:\\"]))
        if draw(st.booleans()):
            out += encode_tag({"s": draw(st.sampled_from(["GP0001", "GP0002", "HE0001"])), "n": "1"})
        out += draw(st.sampled_from(SAMPLE_BYTES))
    return bytes(out)


@settings(max_examples=300, deadline=None)
@given(tagged_streams(), st.lists(st.integers(0, 2000), max_size=12))
def test_tagged_streams_chopped_anywhere_frame_alike_and_lose_no_byte(data: bytes, cuts: list[int]) -> None:
    frames = check_stream(data, [c % (len(data) + 1) for c in cuts])  # (whole = chopped = general rules)
    # every TAG block the stream holds directly before a sentence is found and reads back
    for frame in frames:
        if frame.reason == TAG_BLOCK:
            assert isinstance(decode_tag(frame.raw), TagBlock)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.sampled_from([b"\\", b"UdPbC\x00", b"s:GP01*7A", b"$GPHDT,1.0,T*", b"\r\n", b",", b"!"])).map(
        b"".join
    ),
    st.lists(st.integers(0, 2000), max_size=12),
)
def test_backslash_and_header_soup_never_raises(data: bytes, cuts: list[int]) -> None:
    check_stream(data, [c % (len(data) + 1) for c in cuts])


# ------------------------------------------------------------------------------------------ decoding

codes = st.text(st.sampled_from("cdgnrstix"), min_size=1, max_size=2)
values = st.text(
    st.characters(min_codepoint=0x20, max_codepoint=0x7E, exclude_characters=",*\\"), max_size=20
)


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(codes, values, min_size=1, max_size=5))
def test_tag_blocks_round_trip(params: dict[str, str]) -> None:
    assert decode_tag(encode_tag(params)) == TagBlock(params)


@settings(max_examples=500, deadline=None)
@given(st.dictionaries(codes, values, min_size=1, max_size=4), st.integers(1, 200), st.integers(0x20, 0x7E))
def test_a_changed_character_is_a_reject_or_the_same_reading(params: dict[str, str], at: int, c: int) -> None:
    raw = bytearray(encode_tag(params))
    at = 1 + at % (len(raw) - 2)  # (inside the backslashes)
    raw[at] = c
    got = decode_tag(bytes(raw))
    assert isinstance(got, TagReject) or got == TagBlock(params) or bytes(raw) == encode_tag(got.params)


def test_tag_rejects_say_why() -> None:
    assert decode_tag(b"\\s:GP0001*00\\") == TagReject("tag_checksum", "checksum 00, computed 5F")
    assert decode_tag(b"\\s:GP0001\\").reason == "tag_malformed"  # (NMEA 4.10: the checksum is required)
    assert decode_tag(b"\\s:GP0001*G1\\").reason == "tag_malformed"
    good_sum = encode_tag({"s": "GP0001"})[-4:-1]
    assert decode_tag(b"\\sGP0001" + good_sum + b"\\").reason in ("tag_malformed", "tag_checksum")


# ------------------------------------------------------------------------------------------ pipeline


def tables(url: str, log: Path | None = None) -> dict[str, Any]:
    """Two DGPS receivers and a gyro on one multicast group, each source taking one device."""
    src = {"url": url, "protocol": "nmea"}
    t: dict[str, Any] = {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "gnss1", "roles": ["position"], "tag_source": "GP0001", "priority": 1, **src},
            {"name": "gnss2", "roles": ["position"], "tag_source": "GP0002", "priority": 2, **src},
            {"name": "gyro", "roles": ["heading"], "tag_source": "HE0001", **src},
        ],
        "observer": {"wave_period_s": 9.0},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"], "multicast_scouting": False},
    }
    if log is not None:
        t["log"] = {"path": str(log)}
    return t


def network(seconds: int, damaged_every: int = 0, apart_deg: float = 9e-6) -> list[bytes]:
    """What the group carries, 2 Hz: GP0001 at (59.4, 10.5), GP0002 ``apart_deg`` north of it (1 m: two
    antennas on one vessel), HE0001's heading.
    Every ``damaged_every``-th GP0001 datagram has its TAG block's checksum broken."""
    out = []
    for k in range(2 * seconds):
        t = T0 + timedelta(seconds=k / 2)
        wander = 2e-6 * math.sin(0.3 * k)  # (a fix that never moves is a frozen receiver)
        fix1 = datagram("GP0001", k % 999 + 1, enc.gga("GP", t, 59.4 + wander, 10.5, 2, 12, 0.8, 20.0))
        if damaged_every and k % damaged_every == damaged_every - 1:
            end = fix1.index(b"\\", len(HEADER_450) + 1)  # the TAG block's closing backslash
            wrong = b"%02X" % (int(fix1[end - 2 : end], 16) ^ 0x5A)
            fix1 = fix1[: end - 2] + wrong + fix1[end:]
        out += [
            fix1,
            datagram(
                "GP0002", k % 999 + 1, enc.gga("GP", t, 59.4 + apart_deg + wander, 10.5, 2, 12, 0.8, 20.0)
            ),
            datagram("HE0001", 2 * k % 999 + 1, enc.hdt("HE", 0.5 + wander), enc.rot("HE", 0.0)),
        ]
    return out


def test_each_source_takes_its_own_devices_sentences_and_counts_the_others() -> None:
    pipe = Pipeline(
        PipelineSpec.from_config(parse_config(tables("udp://239.192.0.4:60004"), base_dir=Path.cwd()))
    )
    taken: dict[str, list[str]] = {"gnss1": [], "gnss2": [], "gyro": []}
    pipe.sentence_tap = lambda source, rx_ns, text, peer: taken[source].append(text)
    rx = int(T0.timestamp() * 1e9)
    for k, d in enumerate(network(20, damaged_every=10)):
        for name in taken:  # (every source on the group hears every datagram)
            pipe.feed(RawEvent(rx + k * 10**8, name, d, peer="10.0.0.9:1024"))
    c = pipe.counters
    minutes = {name: [float(s.split(",")[2]) - 5900.0 for s in taken[name]] for name in ("gnss1", "gnss2")}
    assert all(abs(m - 24.0) < 2e-4 for m in minutes["gnss1"]), minutes["gnss1"][:3]  # GP0001's alone
    assert all(abs(m - 24.00054) < 2e-4 for m in minutes["gnss2"]), minutes["gnss2"][:3]  # GP0002's alone
    assert all(s.startswith(("$HEHDT", "$HEROT")) for s in taken["gyro"])
    assert (c["gnss1"].received, c["gnss2"].received, c["gyro"].received) == (36, 40, 80)
    assert dict(c["gnss1"].rejected) == {
        "iec_61162_450": 120, "tag_block": 156, "tag_checksum": 4, "other_tag_source": 124
    }  # fmt: skip
    assert c["gnss2"].rejected["other_tag_source"] == 120 and c["gnss2"].rejected["tag_checksum"] == 4
    assert c["gyro"].rejected["other_tag_source"] == 80
    assert "garbage" not in c["gyro"].rejected


def test_a_tag_block_and_its_sentence_in_different_reads_still_pair() -> None:
    """A serial link or a TCP relay cuts anywhere: the block's device is held for the sender's next read."""
    pipe = Pipeline(
        PipelineSpec.from_config(parse_config(tables("udp://239.192.0.4:60004"), base_dir=Path.cwd()))
    )
    data = b"".join(network(5))
    rx = int(T0.timestamp() * 1e9)
    for k in range(0, len(data), 7):
        pipe.feed(RawEvent(rx + k * 10**5, "gnss1", data[k : k + 7], peer="p"))
    assert pipe.counters["gnss1"].received == 10
    assert pipe.counters["gnss1"].rejected["other_tag_source"] == 30


def grouped(device: str, n: int, first: str, later: str, ident: str | None = None) -> bytes:
    """Two lines grouped as NMEA 4.10 writes them: the device named on the first line only (``g:`` and
    ``n:`` on the second), as an AIS receiver's ``\\g:1-2-73874,n:157036,s:r003669945,c:1241544035*4A\\
    !AIVDM,...`` then ``\\g:2-2-73874,n:157037*1F\\$ARVSI,...``."""
    ident = ident or str(n)
    return (
        encode_tag({"g": f"1-2-{n}", "n": str(n), "s": device}) + first.encode()
        + encode_tag({"g": f"2-2-{ident}", "n": str(n + 1)}) + later.encode()
    )  # fmt: skip


def test_a_groups_later_line_without_its_device_is_the_devices_and_keeps_its_line_count() -> None:
    """Before, a tag_source source refused a group's second line (its block names no device), here the
    receiver's GST, its fix's error estimate; and the device's line count seemed to skip one line a group
    (counted lost). A later line of another group than the one held is still nobody's."""
    pipe = Pipeline(
        PipelineSpec.from_config(parse_config(tables("udp://239.192.0.4:60004"), base_dir=Path.cwd()))
    )
    taken: list[str] = []
    pipe.sentence_tap = lambda source, rx_ns, text, peer: taken.append(text) if source == "gnss1" else None
    rx = int(T0.timestamp() * 1e9)
    for k in range(20):
        t = T0 + timedelta(seconds=k)
        gga = enc.gga("GP", t, 59.4 + 1e-6 * math.sin(k), 10.5, 2, 12, 0.8, 20.0)
        gst = enc.gst(
            "GP", t, rms_m=0.3, sigma_major_m=0.3, sigma_minor_m=0.3, orient_rad=0.0, sigma_lat_m=0.3,
            sigma_lon_m=0.3, sigma_alt_m=0.45,
        )  # fmt: skip
        data = grouped("GP0001", 2 * k + 1, gga, gst)
        pipe.feed(RawEvent(rx + k * NS, "gnss1", data, peer="10.0.0.9:1024"))
    assert sum(x.startswith("$GPGST") for x in taken) == 20 and len(taken) == 40
    c = pipe.counters["gnss1"]
    assert "other_tag_source" not in c.rejected and c.lost_lines == 0
    stray = grouped("GP0001", 41, gga, gst, ident="9999")  # (its second line names another group)
    pipe.feed(RawEvent(rx + 20 * NS, "gnss1", stray, peer="10.0.0.9:1024"))
    assert c.rejected["other_tag_source"] == 1 and len(taken) == 41


def test_a_tag_blocks_group_is_read() -> None:
    assert decode_tag(encode_tag({"g": "2-3-73874", "n": "1"})).group == (2, "73874")
    assert decode_tag(encode_tag({"s": "GP0001"})).group is None
    assert (
        decode_tag(encode_tag({"g": "x-3-1"})).group is None
        and decode_tag(encode_tag({"g": "1-3"})).group is None
    )


def test_without_tag_source_a_source_takes_every_device_and_counts_the_framing() -> None:
    t = tables("udp://239.192.0.4:60004")
    del t["sources"][1:]
    del t["sources"][0]["tag_source"]
    t["sources"][0]["roles"] = ["position", "heading"]
    pipe = Pipeline(PipelineSpec.from_config(parse_config(t, base_dir=Path.cwd())))
    for k, d in enumerate(network(5, damaged_every=5, apart_deg=9e-4)):
        pipe.feed(RawEvent(k * 10**8, "gnss1", d))
    c = pipe.counters["gnss1"]
    codec = {k: n for k, n in c.rejected.items() if not k.startswith("test_")}
    assert c.received == 40 and codec == {"iec_61162_450": 30, "tag_block": 38, "tag_checksum": 2}
    # two receivers 100 m apart taken as one source: the jump test refuses a fix in every cycle (what
    # tag_source is for)
    assert c.rejected["test_jump"] >= 5


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"tag_source": "GP 0001"}, "sources.gnss1.tag_source: not a TAG block source"),
        ({"tag_source": "X" * 16}, "sources.gnss1.tag_source: not a TAG block source"),
        (
            {"protocol": "mavlink", "roles": ["thrusters"]},
            'sources.gnss1.tag_source: only for protocol "nmea"',
        ),
    ],
)
def test_a_wrong_tag_source_stops_start_up_naming_it(change: dict[str, Any], message: str) -> None:
    t = tables("udp://239.192.0.4:60004")
    t["sources"][0].update(change)
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_config(t, base_dir=Path.cwd())


# ------------------------------------------------------------------------------------------ live


def test_live_multicast_group_with_three_devices_into_three_sources_and_the_log_replays_alike(
    tmp_path: Path,
) -> None:
    port = free_port(socket.SOCK_DGRAM)
    log = tmp_path / "navd.mcap"
    t = tables(f"udp://{GROUP}:{port}?iface=127.0.0.1", log)
    service = GatewayService(parse_config(t, base_dir=tmp_path), config_tables=t)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    counters = service.pipeline.counters
    names = ("gnss1", "gnss2", "gyro")
    sent = 0

    def send(d: bytes) -> None:
        nonlocal sent
        sender.sendto(d, (GROUP, port))
        sent += len(d)

    try:
        send(datagram("HE0001", 0, enc.hdt("HE", 0.5)))
        if not wait_for(lambda: counters["gyro"].bytes >= sent, 5.0):  # pragma: no cover
            pytest.skip("multicast is not routed on loopback here")
        for k, d in enumerate(network(30, damaged_every=10)):
            send(d)
            if k % 20 == 19:  # (paced: a socket buffer is finite, and what the kernel drops is not ours)
                assert wait_for(lambda: all(counters[n].bytes >= sent for n in names))
        assert wait_for(lambda: all(counters[n].bytes >= sent for n in names))
        assert loop.is_alive()
    finally:
        sender.close()
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        service.close()
    live = {n: (counters[n].received, dict(counters[n].rejected)) for n in names}
    assert live["gnss1"][0] == 54 and live["gnss1"][1]["other_tag_source"] == 60 + 121 + 6
    assert live["gnss2"][0] == 60 and live["gnss2"][1]["tag_checksum"] == 6
    assert live["gyro"][0] == 121 and "garbage" not in live["gyro"][1]
    # the log holds the config (tag_source included) and every byte: a replay counts the same
    again = Pipeline(PipelineSpec.from_config(config_from_log(log)))
    for ev in mcap_events(log):
        again.feed(ev)
    assert {n: (again.counters[n].received, dict(again.counters[n].rejected)) for n in names} == live


def test_the_example_network_config_names_each_sources_device() -> None:
    from gateway.config import load_config
    from gateway.config.summary import describe

    example = Path(__file__).resolve().parents[1] / "examples" / "iec_61162_450_network.toml"
    config = load_config(example)
    assert [s.tag_source for s in config.sources] == ["GP0001", "GP0002", "HE0001"]
    assert (
        "source dgps2: nmea position priority 2 <- udp://239.192.0.4:60004?iface=eth1, the device GP0002"
        in (describe(config))
    )


def test_run_status_counts_the_network_framing_and_other_devices_as_not_used() -> None:
    """`dpgw run -v`: a healthy 450 source is not shown rejecting its every datagram; a damaged block is."""
    from dpgw.cli_run import status_line

    c = {
        "received": 5,
        "age_s": 0.1,
        "rejected": {"tag_block": 5, "iec_61162_450": 5, "other_tag_source": 10},
    }
    assert "dgps1 5 rx 0.1 s ago (20 not used)" in status_line({"sources": {"dgps1": c}}, 3.0)
    c["rejected"]["tag_checksum"] = 1
    assert "(1 rejected, 20 not used)" in status_line({"sources": {"dgps1": c}}, 3.0)
    c["lost_lines"] = 4
    assert "(1 rejected, 20 not used, 4 lost on the network)" in status_line({"sources": {"dgps1": c}}, 3.0)


# ------------------------------------------------------------------------------------------ simulator


def test_a_udp_sink_with_tag_source_sends_450_datagrams_the_gateway_reads() -> None:
    from simulator.transports import open_sink

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    sink = open_sink(f"udp://127.0.0.1:{rx.getsockname()[1]}?tag_source=GP0001")
    try:
        burst = (enc.gga("GP", T0, 59.4, 10.5, 2, 12, 0.8, 20.0) + enc.zda("GP", T0)).encode()
        rx.settimeout(10.0)
        got = []
        for _ in range(1000):  # (the line count runs 1-999, then again)
            sink.write(burst)
            got.append(rx.recv(2048))
    finally:
        sink.close()
        rx.close()
    frames = frames_of(got[0])
    assert reasons(frames) == [IEC_61162_450, TAG_BLOCK, None, TAG_BLOCK, None]
    assert decode_tag(frames[1].raw) == TagBlock({"s": "GP0001", "n": "1", "g": "1-2-1"})
    assert b"".join(f.raw + b"\r\n" for f in frames if f.reason is None) == burst
    # the device's line count, one per sentence, 1-999 and again
    assert [int(decode_tag(frames_of(d)[1].raw).params["n"]) for d in got] == [
        2 * k % 999 + 1 for k in range(1000)
    ]
    assert decode_tag(frames[3].raw) == TagBlock({"s": "GP0001", "n": "2", "g": "2-2-1"})


@pytest.mark.parametrize(
    ("url", "problem"),
    [
        ("udp://127.0.0.1:10110?iface=lo", "iface is for multicast groups"),
        (f"udp://{GROUP}:60004?iface=no_such_if0", "cannot send by interface no_such_if0"),
        (f"udp://{GROUP}:60004?tag_source=GP,1", "is not a TAG block source"),
    ],
)
def test_a_wrong_450_sink_is_one_clear_error(url: str, problem: str) -> None:
    from simulator.transports import TransportError, open_sink

    with pytest.raises(TransportError, match=problem):
        open_sink(url)


def test_dpgw_sim_as_two_devices_of_one_group_into_the_gateway(tmp_path: Path) -> None:
    """A bench standing in for a ship's network: `dpgw sim` sends the DGPS as GP0001 and the gyro as
    HE0001 to one multicast group; the gateway's two sources on that group each take their device."""
    import subprocess
    import sys

    port = free_port(socket.SOCK_DGRAM)
    group = f"udp://{GROUP}:{port}?iface=127.0.0.1"
    t = tables(group)
    t["vessel"]["name"] = "mss_supply"
    t["sources"] = [t["sources"][0], t["sources"][2]]  # gnss1 <- GP0001, gyro <- HE0001
    service = GatewayService(parse_config(t, base_dir=tmp_path), config_tables=t)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    counters = service.pipeline.counters
    try:
        sim = subprocess.run(
            [sys.executable, "-m", "dpgw", "sim", "--scenario", "torsetnes_2004", "--duration", "60",
             "--json", "--nmea", f"dgps1={group}&tag_source=GP0001",
             "--nmea", f"gyro1={group}&tag_source=HE0001"],
            capture_output=True, text=True, timeout=300, check=True,
        )  # fmt: skip
        import json

        sent = json.loads(sim.stdout)["bytes_sent"]
        total = sent["dgps1"] + sent["gyro1"]
        if not wait_for(lambda: counters["gyro"].bytes > 0, 10.0):  # pragma: no cover
            pytest.skip("multicast is not routed on loopback here")
        assert wait_for(lambda: counters["gnss1"].bytes >= total and counters["gyro"].bytes >= total, 60.0), (
            counters["gnss1"].bytes,
            total,
        )
        assert "as the device GP0001 of an IEC 61162-450 network" in sim.stderr + sim.stdout
    finally:
        service.stop_event.set()
        loop.join(timeout=30)
        service.drain()
        service.close()
    gnss, gyro = counters["gnss1"], counters["gyro"]
    # every sentence each device sent, and only its own; no byte of the network framing taken for noise
    assert "garbage" not in gnss.rejected and "garbage" not in gyro.rejected
    assert gnss.received == gyro.rejected["other_tag_source"] > 0
    assert gyro.received == gnss.rejected["other_tag_source"] > 0
    assert gnss.rejected["tag_block"] == gyro.rejected["tag_block"] == gnss.received + gyro.received


# ------------------------------------------------------------------------------------------ text captures


def test_a_text_capture_of_the_network_replays_and_names_its_devices(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A capture of the group's datagrams as a text file (what socat or a logger on the network writes):
    the headers come off (before: the header hid every sentence, "nothing to replay"), the devices are
    counted, and each is replayed as a source of its own (tests/test_network_capture_replay.py)."""
    from dpgw.cli import main

    capture = tmp_path / "navd.nmea"
    capture.write_bytes(b"".join(network(60)))
    assert main(["replay", str(capture), "--vessel", "mss_supply", "--out", str(tmp_path / "r.mcap")]) == 0
    out = capsys.readouterr().out
    assert "line_prefix 360, tag GP0001 120, tag GP0002 120, tag HE0001 240" in out  # (360 datagrams)
    assert "3 devices' TAG blocks in one text log (GP0001, GP0002, HE0001): each replayed as a source" in out
    assert "source navd_gp0002: received 120" in out


# ------------------------------------------------------------------------------------------ lost lines


def test_sentences_lost_on_the_network_are_counted_from_the_line_counts() -> None:
    """Drop datagrams from what the group carried (a switch's buffer overflowing): each device's TAG line
    counts skip, and every sentence lost is counted once for the source that hears it, over the 999 wrap;
    a device restarting (its count back to 1) is not a loss."""
    t = tables("udp://239.192.0.4:60004")
    pipe = Pipeline(PipelineSpec.from_config(parse_config(t, base_dir=Path.cwd())))
    carried = network(600)  # 1,200 cycles: every device's count wraps past 999
    lost: dict[str, int] = {"GP0001": 0, "GP0002": 0, "HE0001": 0}
    kept = []
    for k, d in enumerate(carried):
        if k % 97 in (5, 6, 7) or 1500 <= k < 1512:  # three in a row now and then, and a longer burst
            lost[decode_tag(frames_of(d)[1].raw).params["s"]] += d.count(b"$")
            continue
        kept.append(d)
    # then GP0001 restarts: its count starts again at 1
    t_restart = T0 + timedelta(seconds=700)
    kept.append(datagram("GP0001", 1, enc.gga("GP", t_restart, 59.4, 10.5, 2, 12, 0.8, 20.0)))
    for k, d in enumerate(kept):
        for name in ("gnss1", "gnss2", "gyro"):
            pipe.feed(RawEvent(k * 10**8, name, d, peer="p"))
    c = pipe.counters
    assert lost["GP0001"] > 30 and lost["HE0001"] > 60
    everyone = sum(lost.values())
    assert c["gnss1"].lost_lines == c["gnss2"].lost_lines == c["gyro"].lost_lines == everyone
    assert pipe.status_message(k * 10**8).sources["gyro"].lost_lines == everyone


def test_a_network_without_loss_counts_none_and_the_status_leaves_it_out() -> None:
    pipe = Pipeline(
        PipelineSpec.from_config(parse_config(tables("udp://239.192.0.4:60004"), base_dir=Path.cwd()))
    )
    for k, d in enumerate(network(600)):
        pipe.feed(RawEvent(k * 10**8, "gyro", d, peer="p"))
    assert pipe.counters["gyro"].lost_lines == 0
    assert "lost_lines" not in pipe.status_message(10**12).to_dict()["sources"]["gyro"]


def test_a_flood_of_made_up_device_names_does_not_grow_memory() -> None:
    """Every datagram from a new device name (a fuzzer, a broken switch): the line counts followed stay
    bounded, and the first devices' losses are still counted."""
    from gateway.pipeline import MAX_SENDERS

    t = tables("udp://239.192.0.4:60004")
    del t["sources"][0]["tag_source"]
    pipe = Pipeline(PipelineSpec.from_config(parse_config(t, base_dir=Path.cwd())))
    hdt = enc.hdt("HE", 0.5)
    pipe.feed(RawEvent(0, "gnss1", datagram("HE0001", 1, hdt)))
    for k in range(5000):
        pipe.feed(RawEvent(k + 1, "gnss1", datagram(f"X{k:05d}", 1, hdt)))
    pipe.feed(RawEvent(10**6, "gnss1", datagram("HE0001", 4, hdt)))  # lines 2 and 3 lost
    assert len(pipe._tag_lines) == MAX_SENDERS
    assert pipe.counters["gnss1"].lost_lines == 2


def test_a_device_that_is_silent_on_the_group_is_no_data_then_stale() -> None:
    """Before, a source taking one device of a group was as fresh as the group: a backup receiver that
    never sent (GP0002) showed age 0 s and no alarm, and a primary that stopped (GP0001) stayed fresh while
    the gyro's datagrams came, with no `stale` alarm. Freshness is now the device's own."""
    pipe = Pipeline(
        PipelineSpec.from_config(parse_config(tables("udp://239.192.0.4:60004"), base_dir=Path.cwd()))
    )
    rx = int(T0.timestamp() * 1e9)
    sent = [d for d in network(30) if b"s:GP0002" not in d]  # the backup never sends
    last_gp1 = 0
    for k, d in enumerate(sent):
        t = rx + k * 10**8
        if b"s:GP0001" in d and k >= len(sent) // 2:
            continue  # the primary stops half-way; the gyro goes on
        last_gp1 = t if b"s:GP0001" in d else last_gp1
        for name in ("gnss1", "gnss2", "gyro"):
            pipe.feed(RawEvent(t, name, d, peer="10.0.0.9:1024"))
    now = rx + len(sent) * 10**8
    status = pipe.status_message(now)
    assert "source gnss2: no data yet" in status.alarms
    assert status.sources["gnss2"].age_s is None
    age = (now - last_gp1) / 1e9
    assert age > pipe.sources["gnss1"].timeout_s
    assert status.sources["gnss1"].age_s == pytest.approx(age)
    assert f"source gnss1: stale ({age:.1f} s without data)" in status.alarms
    assert status.sources["gyro"].age_s == pytest.approx(0.1) and not any("gyro" in a for a in status.alarms)
