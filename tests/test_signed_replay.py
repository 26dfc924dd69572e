"""Replay of a signed MAVLink link without its key: the log never holds the key, so the live gateway
records its verdict on every frame it refused for signing (`/raw/mavlink_rejected/<source>`), and `dpgw
replay` refuses exactly those frames, for the same reasons, instead of taking them unchecked. A log written
before gateways recorded verdicts replays as before: unchecked, and said so."""

from __future__ import annotations

import json
import math
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import pytest
from conftest import free_port, wait_for
from hypothesis import given, settings
from hypothesis import strategies as st

from dpgw.cli import main
from gateway.config import parse_config
from gateway.service import GatewayService
from simulator.runner import Route, Simulation
from simulator.scenarios import get_scenario
from simulator.sensors import ThrusterFeedbackConfig
from simulator.transports import UdpSink
from wire.codecs import mavlink as mv
from wire.mcap.reader import read_messages, read_metadata
from wire.mcap.writer import McapLogWriter

KEY = bytes(range(100, 132))
WRONG_KEY = bytes(range(32))
DRIVE = (1, 1)  # the simulated drives' system and component id (hajivand_2010's feedback)
ATTACKS = 3  # rounds of forged, unsigned and replayed frames from the second sender
COMPARED = ("/dp/estimate", "/dp/measurement", "/dp/thrusters/feedback")


def _attack_frames(round_: int) -> list[bytes]:
    """One round of the second sender: a datagram with a forged frame (the drive's ids, another key) and an
    unsigned one, then a genuine frame recorded two minutes ago (the drive's key and link, its timestamp
    old) replayed, split over two datagrams. Each reports a large thrust athwartships, which would move
    τ."""
    forger, plain, recorded = mv.encoder(*DRIVE), mv.encoder(*DRIVE), mv.encoder(*DRIVE)
    mv.setup_signing(forger, WRONG_KEY)
    mv.setup_signing(recorded, KEY, initial_timestamp=mv.signing_timestamp(time.time() - 120.0))
    thrust = 9e5 if round_ % 2 else -9e5
    forged = mv.azimuth_status_frame(forger, 0, 1, thrust, 200.0, math.pi / 2, 0)
    unsigned = mv.azimuth_status_frame(plain, 0, 2, thrust, 200.0, -math.pi / 2, 0)
    replayed = mv.azimuth_status_frame(recorded, 0, 1, -thrust, 200.0, math.pi / 2, 0)
    half = len(replayed) // 2
    return [forged + unsigned, replayed[:half], replayed[half:]]


SIGNED_STATUS_LEN = len(_attack_frames(0)[1]) + len(_attack_frames(0)[2])
"""Bytes of a signed AZIMUTH_THRUSTER_STATUS frame (the forged one, and the replayed one)."""


@dataclass
class LiveRun:
    log: Path
    rejected: dict[str, int]
    received: int


def _live_gateway(tmp: Path) -> LiveRun:
    """A gateway (`GatewayService`, as `dpgw run`) with GPS/gyro over UDP and a signed thruster link over
    UDP; the hajivand_2010 simulator's drives sign their feedback with the gateway's key; a second UDP
    sender injects forged, unsigned and replayed frames. The simulator is paced by the gateway: each step
    of sea goes out once the gateway has handled the last one (no datagram lost to a full buffer)."""
    scenario = get_scenario("hajivand_2010")
    fb = ThrusterFeedbackConfig(rate_hz=5.0, system_id=DRIVE[0], component_id=DRIVE[1])
    scenario = replace(scenario, feedback=fb)
    nav_port, thr_port = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
    log = tmp / "live.mcap"
    tables: dict[str, Any] = {
        "vessel": {"name": scenario.vessel.name},
        "datum": {"lat_deg": scenario.datum.lat_deg, "lon_deg": scenario.datum.lon_deg},
        "sources": [
            {"name": "nav", "url": f"udp://127.0.0.1:{nav_port}", "protocol": "nmea",
             "roles": ["position", "heading"], "timeout_s": 30.0},
            {"name": "thrusters", "url": f"udp://127.0.0.1:{thr_port}", "protocol": "mavlink",
             "roles": ["thrusters"], "signing_key": KEY.hex(), "system_id": DRIVE[0],
             "component_id": DRIVE[1], "timeout_s": 30.0},
        ],
        "observer": {"wave_period_s": scenario.sea[0][1].tp_s},
        "control": {"initial_mode": "standby"},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"], "multicast_scouting": False},
        "log": {"path": str(log)},
    }  # fmt: skip
    service = GatewayService(parse_config(tables, base_dir=tmp), config_tables=tables)
    service.start()
    loop = threading.Thread(target=service.run, name="consumer")
    loop.start()
    nav_sink, thr_sink = UdpSink("127.0.0.1", nav_port), UdpSink("127.0.0.1", thr_port)
    attacker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    attacker.bind(("127.0.0.1", 0))
    try:
        sim = Simulation(
            scenario, 0, routes=[Route(nav_sink, "nmea"), Route(thr_sink, "mavlink")], signing_key=KEY
        )
        counters = service.pipeline.counters

        def handled(nav_bytes: int, refused: int) -> bool:
            """The gateway has handled every byte of sea sent, and each round of the second sender (one
            sender's datagrams are handled in order: its last refusal means the round is through)."""
            thr = counters["thrusters"]
            return counters["nav"].bytes >= nav_bytes and thr.rejected["bad_signature"] >= refused

        attacked = 0
        for step in range(60):  # 60 s of sea
            sim.run(1.0)
            if step % 15 == 7 and attacked < ATTACKS:
                for datagram in _attack_frames(attacked):
                    attacker.sendto(datagram, ("127.0.0.1", thr_port))
                attacked += 1
            sent = sim.summary.bytes_sent
            assert wait_for(partial(handled, sent["dgps1"] + sent["gyro1"], 2 * attacked), 30.0), counters
        assert wait_for(lambda: counters["thrusters"].bytes >= sim.summary.bytes_sent["thrusters"], 30.0)
        # a status (1 Hz) with every refusal in it, logged, as a gateway running on after the attack has:
        # a log from before verdicts has only its last status to say what the live gateway refused
        assert wait_for(
            lambda: (
                service.last_status().get("sources", {}).get("thrusters", {}).get("rejected")
                == {"bad_signature": 2 * ATTACKS, "unsigned": ATTACKS}
            ),
            30.0,
        ), service.last_status()
    finally:
        service.stop_event.set()
        loop.join(timeout=30)
        service.close()
        attacker.close()
        nav_sink.close()
        thr_sink.close()
    c = service.pipeline.counters["thrusters"]
    return LiveRun(log, dict(c.rejected), c.received)


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> LiveRun:
    return _live_gateway(tmp_path_factory.mktemp("signed"))


def _replay(log: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[dict[str, Any], str]:
    assert main(["replay", str(log), "--out", str(out), "--json"]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def _channels(log: Path) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {t: [] for t in COMPARED}
    for topic, _, _, payload in read_messages(log, COMPARED):
        out[topic].append(payload)
    return out


@pytest.mark.slow  # a live gateway fed a minute of sea (~10-20 s), and a replay
def test_replay_without_the_key_refuses_the_frames_the_live_gateway_refused(
    live: LiveRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The live gateway refused each forged frame and each replayed one (`bad_signature`) and each
    unsigned one (`unsigned`), and took every frame of the signed drives. `dpgw replay` of its log, which
    holds no key, refuses the same frames for the same reasons, from the verdicts the log records, and
    says so; its estimates, measurements (τ) and thruster feedback are the live gateway's, bit for bit.
    (A replay that took the refused frames, as before, fed their thrust to the observer: other τ,
    other estimates.)"""
    assert live.rejected == {"bad_signature": 2 * ATTACKS, "unsigned": ATTACKS}, live.rejected
    assert live.received > 250  # 60 s of the drives' 5 Hz feedback and 1 Hz heartbeats
    verdicts = [p for _, _, _, p in read_messages(live.log, "/raw/mavlink_rejected/thrusters")]
    assert sorted(p["reason"] for p in verdicts) == ["bad_signature"] * 6 + ["unsigned"] * 3
    # the replayed frame completed by its second datagram: it began in the first one
    assert {(p["reason"], p["offset"]) for p in verdicts} == {
        ("bad_signature", 0),  # forged: the first frame of its datagram
        ("unsigned", SIGNED_STATUS_LEN),  # right after it
        ("bad_signature", -len(_attack_frames(0)[1])),  # replayed: it began in the datagram before
    }
    assert {p["link_id"] for p in verdicts if p["reason"] == "bad_signature"} == {0}
    assert all(p["peer"] for p in verdicts)  # the second sender, by address
    summary, err = _replay(live.log, tmp_path / "replay.mcap", capsys)
    counts = summary["counts"]["source thrusters"]
    assert {k: counts.get(k, 0) for k in live.rejected} == live.rejected
    assert counts["received"] == live.received
    assert summary["signature_verdicts"] == {"thrusters": {"bad_signature": 6, "unsigned": 3}}
    assert summary["signatures_unchecked"] == {}
    assert "thrusters: MAVLink signatures not checked" in err
    assert "the live gateway's verdicts, recorded in the log, applied instead" in err
    assert "9 frames refused as live (bad_signature 6, unsigned 3)" in err
    replayed, recorded = _channels(tmp_path / "replay.mcap"), _channels(live.log)
    assert len(recorded["/dp/estimate"]) > 200
    for topic in COMPARED:
        assert replayed[topic] == recorded[topic], topic
    # the replay's own log records the same verdicts, so that it replays the same way again
    again = [p for _, _, _, p in read_messages(tmp_path / "replay.mcap", "/raw/mavlink_rejected/thrusters")]
    assert again == verdicts


def _as_an_older_gateway_wrote_it(log: Path, old: Path) -> None:
    """The same log as a gateway from before verdicts were recorded wrote it: no verdict channel, no
    `signing_verdicts` in its config record."""
    with McapLogWriter(old) as w:
        for name, meta in read_metadata(log):
            w.add_metadata(name, {k: v for k, v in meta.items() if k != "signing_verdicts"})
        for topic, log_ns, pub_ns, payload in read_messages(log):
            if not topic.startswith("/raw/mavlink_rejected/"):
                w.write(topic, payload, log_ns, pub_ns)


@pytest.mark.slow  # the live gateway of the fixture, and a replay
def test_an_older_log_without_verdicts_replays_unchecked_and_says_so(
    live: LiveRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log without verdicts replays as before: the signed link's frames taken unchecked, the forged,
    unsigned and replayed ones too, and the note says how many frames the live gateway refused that this
    replay took (from the log's last status). Its estimates are then not the live gateway's."""
    old = tmp_path / "old.mcap"
    _as_an_older_gateway_wrote_it(live.log, old)
    summary, err = _replay(old, tmp_path / "old-replay.mcap", capsys)
    assert summary["signature_verdicts"] == {}
    live_status = summary["signatures_unchecked"]["thrusters"]
    assert live_status == {"bad_signature": 6, "unsigned": 3}
    assert "which this replay took" in err and "verdicts" not in err
    counts = summary["counts"]["source thrusters"]
    assert "bad_signature" not in counts and "unsigned" not in counts
    assert counts["received"] == live.received + 9
    replayed, recorded = _channels(tmp_path / "old-replay.mcap"), _channels(live.log)
    assert replayed["/dp/estimate"] != recorded["/dp/estimate"]


@pytest.mark.slow  # the live gateway of the fixture, and a replay
def test_a_verdict_that_names_another_frame_is_said_and_its_frame_taken(
    live: LiveRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The log edited so that one verdict's digest names no frame: the replay refuses the other eight,
    takes that frame unchecked, and says so (in the source's counts and in the note)."""
    edited = tmp_path / "edited.mcap"
    changed = False
    with McapLogWriter(edited) as w:
        for name, meta in read_metadata(live.log):
            w.add_metadata(name, meta)
        for topic, log_ns, pub_ns, payload in read_messages(live.log):
            if topic.startswith("/raw/mavlink_rejected/") and not changed:
                payload = {**payload, "digest": "0" * 16}
                changed = True
            w.write(topic, payload, log_ns, pub_ns)
    summary, err = _replay(edited, tmp_path / "edited-replay.mcap", capsys)
    counts = summary["counts"]["source thrusters"]
    assert sum(counts.get(k, 0) for k in live.rejected) == 8
    assert counts["received"] == live.received + 1
    assert counts["warning signing_verdict_unmatched"] == 1
    assert "1 verdicts matched no frame at their place in the log" in err


# --- the frame parser's verdicts --------------------------------------------------------------------------


def _stream() -> list[bytes]:
    """Frames of a signed link: genuine, forged, unsigned, a genuine one repeated, MAVLink 1, noise."""
    drive, forger, plain = mv.encoder(*DRIVE), mv.encoder(*DRIVE), mv.encoder(*DRIVE)
    mv.setup_signing(drive, KEY, initial_timestamp=mv.signing_timestamp(time.time()))
    mv.setup_signing(forger, WRONG_KEY, initial_timestamp=mv.signing_timestamp(time.time()))
    genuine = [mv.azimuth_status_frame(drive, 1000 * k, 1, 100.0 * k, 10.0, 0.1, 0) for k in range(6)]
    return [
        genuine[0],
        mv.azimuth_status_frame(forger, 0, 1, 5e5, 10.0, 0.0, 0),
        genuine[1],
        mv.heartbeat_frame(plain),
        genuine[2],
        genuine[1],  # repeated: not newer than the stream's last
        b"\xfd\x05junk",
        genuine[3],
        genuine[4],
        mv.azimuth_status_frame(forger, 0, 2, 5e5, 10.0, 0.0, 0),
        genuine[5],
    ]


def _chunks(blob: bytes, cuts: list[int]) -> Iterator[bytes]:
    at = 0
    for cut in sorted(set(cuts)):
        yield blob[at:cut]
        at = cut
    yield blob[at:]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=2000), max_size=30))
def test_logged_verdicts_refuse_the_same_frames_however_the_stream_is_cut(cuts: list[int]) -> None:
    """A parser without the key, given per chunk the verdicts the keyed parser recorded on it, returns
    the same messages and counts the same rejects, whatever the chunking (frames split across chunks
    included: their offsets are negative); accepted frames leave no record."""
    blob = b"".join(_stream())
    chunks = list(_chunks(blob, [c for c in cuts if c < len(blob)]))
    rx = mv.encoder(0, 0)
    mv.setup_signing(rx, KEY, sign_outgoing=False)
    keyed = mv.FrameParser(rx, keep_signing_rejects=True)
    keyless = mv.FrameParser(keep_signing_rejects=True)
    for chunk in chunks:
        live = keyed.feed(chunk)
        assert keyed.signing_rejects is not None
        keyless.verdicts = [(r.offset, mv.frame_digest(r.frame), r.reason) for r in keyed.signing_rejects]
        again = keyless.feed(chunk)
        assert keyless.verdicts == []  # every verdict found its frame
        assert [m.get_msgbuf() for m in again] == [m.get_msgbuf() for m in live]
        assert [(r.offset, r.reason, r.frame) for r in keyless.signing_rejects or []] == [
            (r.offset, r.reason, r.frame) for r in keyed.signing_rejects
        ]
        keyed.signing_rejects.clear()
        assert keyless.signing_rejects is not None
        keyless.signing_rejects.clear()
    assert keyed.rejected == keyless.rejected
    assert keyed.rejected["bad_signature"] == 3 and keyed.rejected["unsigned"] == 1
    assert keyed.received == keyless.received == 6


def test_a_verdict_whose_digest_does_not_match_is_not_applied() -> None:
    """A verdict names the frame by its place and its digest: another frame at that place (a log edited,
    or merged with another) is taken, and the verdict is left over for the caller to count."""
    frames = _stream()
    parser = mv.FrameParser()
    parser.verdicts = [(0, "0" * 16, "bad_signature")]
    assert len(parser.feed(frames[0])) == 1 and parser.verdicts == [(0, "0" * 16, "bad_signature")]
    assert not parser.rejected


def test_frame_ids_read_the_header_and_signature() -> None:
    drive = mv.encoder(7, 9)
    mv.setup_signing(drive, KEY, link_id=3, initial_timestamp=123_456)
    drive.seq = 41
    ids = mv.frame_ids(mv.heartbeat_frame(drive))
    assert ids == mv.FrameIds(7, 9, 41, 0, 3, 123_456)
    plain = mv.encoder(7, 9)
    assert mv.frame_ids(mv.azimuth_status_frame(plain, 0, 1, 1.0, 1.0, 0.0, 0)) == mv.FrameIds(
        7, 9, 0, mv.AZIMUTH_THRUSTER_STATUS_ID, None, None
    )


def test_the_pipeline_counts_a_verdict_that_found_no_frame(tmp_path: Path) -> None:
    """Through the replay's pipeline (`build_pipeline` with the log's verdicts, no key): the frame a
    verdict names is refused under the logged reason, and its record made again for the replay's own
    log; a verdict whose digest names another frame is not applied (the frame is taken) and is counted
    (`Pipeline.unmatched_verdicts`: the replay's `warning signing_verdict_unmatched`, which its note
    repeats). Two chunks of a sender at one receive time share its verdicts: the second chunk does not
    count the first one's as unmatched."""
    from gateway.pipeline import RawEvent
    from gateway.replay import SigningVerdicts, build_pipeline

    tables = {
        "vessel": {"name": "hajivand_vessel"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "nav", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
            {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]},
        ],
        "log": {"path": ""},
    }
    forged, replayed_head, replayed_tail = _attack_frames(0)
    t_ns, peer = 1_700_000_000_000_000_000, "127.0.0.1:40000"
    verdicts = SigningVerdicts(
        {"thr": {
            (peer, t_ns): ((0, mv.frame_digest(forged[:SIGNED_STATUS_LEN]), "bad_signature"),),
            (peer, t_ns + 1): ((-len(replayed_head), "0" * 16, "bad_signature"),),
        }},
        {"thr": {"bad_signature": 2, "unsigned": 0}},
    )  # fmt: skip
    pipeline = build_pipeline(parse_config(tables, base_dir=tmp_path), [], signing_verdicts=verdicts)
    first = pipeline.feed(RawEvent(t_ns, "thr", forged, peer=peer))  # the forged frame, the unsigned one
    pipeline.feed(RawEvent(t_ns, "thr", replayed_head, peer=peer))
    pipeline.feed(RawEvent(t_ns + 1, "thr", replayed_tail, peer=peer))
    c = pipeline.counters["thr"]
    assert dict(c.rejected) == {"bad_signature": 1}
    assert c.received == 2  # the unsigned frame (no verdict on it here) and the replayed one
    assert pipeline.unmatched_verdicts() == {"thr": 1}
    records = [o.message for o in first if o.topic == "/raw/mavlink_rejected/thr"]
    assert [(r.reason, r.offset, r.peer, r.stamp_ns) for r in records] == [("bad_signature", 0, peer, t_ns)]


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def _config_without_the_key(log: Path, path: Path, key: bytes | None) -> None:
    """The log's own config as an analyst's ``--config`` file: the signed link with ``key``, or none."""
    from gateway.replay import logged_config

    tables = logged_config(log)
    assert tables is not None
    lines: list[str] = []
    for section, body in tables.items():
        if section == "sources":
            for src in body:
                src = {k: v for k, v in src.items() if k not in ("signing_key", "allow_unsigned", "commands")}
                if key is not None and src["protocol"] == "mavlink":
                    src["signing_key"] = key.hex()
                lines += ["[[sources]]", *(f"{k} = {_toml_value(v)}" for k, v in src.items())]
        elif isinstance(body, dict) and section not in ("zenoh", "log"):
            lines += [f"[{section}]", *(f"{k} = {_toml_value(v)}" for k, v in body.items())]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow  # the live gateway of the fixture, and two replays
def test_a_config_without_the_key_still_refuses_what_the_live_gateway_refused(
    live: LiveRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--config` with the vessel's config as an analyst has it (no key): the log's verdicts are applied
    as without --config (before, with --config the frames were taken unchecked and nothing was said).
    With the key in the config the signatures are checked instead, and the same frames are refused."""
    for key, label in ((None, "keyless"), (KEY, "keyed")):
        config = tmp_path / f"{label}.toml"
        _config_without_the_key(live.log, config, key)
        out = tmp_path / f"{label}.mcap"
        assert main(["replay", str(live.log), "--config", str(config), "--out", str(out), "--json"]) == 0
        captured = capsys.readouterr()
        summary = json.loads(captured.out)
        counts = summary["counts"]["source thrusters"]
        assert {k: counts.get(k, 0) for k in live.rejected} == live.rejected, (label, counts)
        assert counts["received"] == live.received, label
        assert summary["signatures_unchecked"] == {}, label
        expected = {"thrusters": {"bad_signature": 6, "unsigned": 3}} if key is None else {}
        assert summary["signature_verdicts"] == expected, label


def test_a_refusal_completed_when_a_silent_sender_is_forgotten_is_recorded_and_replayed(
    tmp_path: Path,
) -> None:
    """A forged frame held behind a false start (a header whose length runs past it) completes only when
    its sender, silent past the source's timeout, is forgotten at another sender's chunk. The live
    pipeline counted it ``bad_signature`` but made no record of it, so a replay without the key took it
    (``sender gone``). Now it is recorded at that chunk's time with its own sender's peer, and the
    replay without the key refuses it for the same reason, at the same event."""
    from gateway.pipeline import RawEvent
    from gateway.replay import SigningVerdicts, build_pipeline

    def tables(key: bytes | None) -> dict[str, Any]:
        nav = {
            "name": "nav",
            "url": "udp://127.0.0.1:0",
            "protocol": "nmea",
            "roles": ["position", "heading"],
        }
        thr = {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]}
        thr["timeout_s"] = 1.0
        if key is not None:
            thr["signing_key"] = key.hex()
        return {
            "vessel": {"name": "hajivand_vessel"},
            "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
            "sources": [nav, thr],
            "log": {"path": ""},
        }

    forged = _attack_frames(0)[0][:SIGNED_STATUS_LEN]
    # a MAVLink 2 header saying 200 bytes of payload: the parser waits for them, the forged frame inside
    false_start = b"\xfd" + bytes([200, 0, 0, 0, 1, 1]) + mv.AZIMUTH_THRUSTER_STATUS_ID.to_bytes(3, "little")
    drive = mv.encoder(*DRIVE)
    mv.setup_signing(drive, KEY, initial_timestamp=1)
    t0, a, b = 1_700_000_000_000_000_000, "127.0.0.1:40000", "127.0.0.1:40001"
    events = [
        RawEvent(t0, "thr", false_start + forged, peer=a),
        RawEvent(t0 + 3 * 10**9, "thr", mv.heartbeat_frame(drive), peer=b),  # a silent 3 s: forgotten
    ]
    live = build_pipeline(parse_config(tables(KEY), base_dir=tmp_path), [])
    outputs = [o for ev in events for o in live.feed(ev)]
    assert live.counters["thr"].rejected["bad_signature"] == 1, live.counters["thr"].rejected
    records = [o.message for o in outputs if o.topic == "/raw/mavlink_rejected/thr"]
    assert [(r.reason, r.peer, r.stamp_ns, r.offset) for r in records] == [
        ("bad_signature", a, t0 + 3 * 10**9, -len(forged))
    ]
    table = {(r.peer, r.stamp_ns): ((r.offset, r.digest, r.reason),) for r in records}
    verdicts = SigningVerdicts({"thr": table}, {"thr": {"bad_signature": 1, "unsigned": 0}})
    keyless = build_pipeline(parse_config(tables(None), base_dir=tmp_path), [], signing_verdicts=verdicts)
    for ev in events:
        keyless.feed(ev)
    assert keyless.counters["thr"].rejected == live.counters["thr"].rejected
    assert keyless.unmatched_verdicts() == {"thr": 0}
