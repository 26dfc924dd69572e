"""Replay: recorded logs back through the same pipeline as the live gateway (DESIGN.md rule 1), only faster.

Inputs (any mix, merged by time):
- the gateway's own MCAP: every raw chunk (`/raw/nmea/<source>`, `/raw/mavlink/<source>`) with its receive
  time as `log_time`, every Zenoh input (`/dp/setpoint`, `/dp/mode`, `/dp/tau`), and the configuration it
  ran with (metadata `dpgw.config`): feeding those events in log-time order to a pipeline built from that
  configuration reproduces the live estimates bit for bit. Simulator logs (`dpgw sim --out`) have the same
  raw channels plus `/truth/state`, which replay scores against.
- raw NMEA text logs and MAVLink tlogs (`gateway.logreaders`).

Several observer specs in one pass: the first is published on `/dp/estimate` (as live), the others on
`/dp/estimates/<label>`, side by side. Spec syntax: ``NAME[:key=value,...][@label]``, e.g.
``passive``, ``passive:wave_period_s=9@T9``; keys are `PassiveTuning` fields (or ``wave_period_s``).
"""

from __future__ import annotations

import base64
import dataclasses
import gc
import heapq
import json
import math
import re
import struct
from collections import Counter
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from datetime import tzinfo
from itertools import chain, pairwise
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mypy_extensions import mypyc_attr

from gateway.compressed import compression_of, open_log, was_cut
from gateway.config import GatewayConfig, default_config, parse_config
from gateway.config.logged import SIGNING_VERDICTS_KEY, unlogged_key_sources, without_unlogged_keys
from gateway.config.problems import did_you_mean
from gateway.line_prefix import CaptureDevices, capture_devices, split_by_device
from gateway.logreaders import (
    LogCounts,
    nmea_text_events,
    nmea_text_events_reference,
    spread_headings,
    tlog_events,
)
from gateway.pipeline import (
    SIGNING_REJECTED_TOPIC,
    TICK_TOPIC,
    USED_NMEA,
    ControlEvent,
    Output,
    Pipeline,
    PipelineSpec,
    RawEvent,
)
from gateway.stamped_log import is_stamped_only, stamped_text_events
from observers.factory import (
    OBSERVER_PARAMS,
    OBSERVER_TYPES,
    TUNING_KEYS,
    Observer,
    make_observer,
    tuning_keys,
    with_defaults,
)
from observers.passive_tuning import PassiveTuning
from wire.codecs import mavlink as mv
from wire.mcap.reader import read_messages, read_metadata
from wire.mcap.writer import McapLogWriter, raw_mavlink_record, raw_nmea_record
from wire.messages import (
    MALFORMED_INPUT_TOPIC,
    SIM_METADATA,
    Estimate,
    Message,
    RawMavlink,
    RawNmea,
    encoder_of,
    input_from_log,
    logged_input,
)

CONFIG_METADATA = "dpgw.config"
DEMO_METADATA = "dpgw.demo"
"""What `dpgw demo` says of its log: ``settle_s``, the start it left out of its scores, and
``min_scored_s``, the least sea after it that it scores (a log of a demo stopped soon after the skip)."""
MCAP_MAGIC = b"\x89MCAP0\r\n"
Event = RawEvent | ControlEvent


class ReplayError(ValueError):
    """A replay that cannot start (unknown input, no vessel, bad observer spec): the message says why."""


# --- inputs ----------------------------------------------------------------------------------------------


def input_kind(path: str | Path) -> str:
    """'mcap', 'tlog' or 'nmea' (a text log), from the file's first bytes and name."""
    p = Path(path)
    if p.is_dir():
        raise ReplayError(f"{p}: a folder, not a log file: give the logs in it (e.g. {p / '*.mcap'})")
    if not p.is_file():
        raise ReplayError(f"{p}: no such log file")
    with open_log(p) as f:
        head = f.read(64)
        cut = was_cut(f)
    if not head and cut is not None:
        raise ReplayError(
            f"{p}: starts like a {cut.name} file but does not decompress: give the log itself, or a complete "
            f"copy of the compressed file ({cut.test} FILE tests one)"
        )
    if not head:
        raise ReplayError(f"{p}: empty file: nothing to replay")
    if head.startswith(MCAP_MAGIC):
        if (packed := compression_of(p)) is not None:
            raise ReplayError(
                f"{p}: a {packed.name}-compressed MCAP log: MCAP is read by seeking in it, so decompress it "
                f"first ({packed.unpack} {p}) and give the .mcap; MCAP compresses its own chunks (zstd or "
                "lz4)"
            )
        return "mcap"
    if p.suffix.lower() == ".mcap":
        raise ReplayError(
            f"{p}: not an MCAP file (it does not start with MCAP's magic bytes): another format named .mcap"
        )
    if _raw_mavlink_stream(p):
        raise ReplayError(
            f"{p}: a raw MAVLink byte stream (frames without record times, as `dpgw sim --mavlink "
            "file://...` writes), not a tlog (each record an 8-byte time, then its frame): replay needs the "
            "times; give a tlog (MAVProxy, Mission Planner, QGroundControl, `dpgw sim --tlog`) or the "
            "gateway's MCAP log"
        )
    if p.suffix.lower() in (".tlog", ".bin") or (len(head) > 8 and head[8] in (0xFE, 0xFD)):
        return "tlog"
    return "nmea"


def _raw_mavlink_stream(path: Path) -> bool:
    """Whether a file starts with two back-to-back MAVLink frames (v1 0xFE or v2 0xFD), not tlog records.

    A tlog record starts with its time (big-endian µs since 1970: a first byte of 0 until the year 2540),
    so a file that starts with a start-of-frame marker, and has another right after the first frame's
    length, is frames alone."""
    with open_log(path) as f:
        head = f.read(2 * 280)
    at = 0
    for _ in range(2):
        if len(head) < at + 2 or head[at] not in (0xFD, 0xFE):
            return False
        if head[at] == 0xFE:  # v1: STX, len, seq, sys, comp, msgid, payload, crc (2)
            at += 8 + head[at + 1]
        else:  # v2: STX, len, incompat, compat, seq, sys, comp, msgid (3), payload, crc (2), signature (13)
            if len(head) < at + 3:
                return False
            at += 12 + head[at + 1] + (13 if head[at + 2] & 0x01 else 0)
    return at <= len(head) and (at == len(head) or head[at] in (0xFD, 0xFE))


def logged_config(path: str | Path) -> dict[str, Any] | None:
    """The configuration (as the TOML tables) a live run stored in its log, if any; also from a log cut by
    `kill -9` or power loss (the record is at the file's start)."""
    meta = _logged(path, CONFIG_METADATA)
    if meta is None or "json" not in meta:
        return None
    data: dict[str, Any] = json.loads(meta["json"])
    return data


def _logged(path: str | Path, name: str) -> dict[str, str] | None:
    """The MCAP metadata record ``name`` of a log (complete or cut), if it has one."""
    try:
        records = read_metadata(path)
    except (OSError, ValueError, struct.error):  # unreadable, or not MCAP: the caller reports that
        return None
    return next((meta for record_name, meta in records if record_name == name), None)


def logged_sim(path: str | Path) -> dict[str, str] | None:
    """A simulator log's own description (metadata `SIM_METADATA`: scenario, seed, vessel, datum), if any."""
    return _logged(path, SIM_METADATA)


def logged_settle_s(inputs: list[Input]) -> float | None:
    """The settle time the run that made a log scored itself with (`DEMO_METADATA`, written by `dpgw demo`),
    so that a replay of that log scores the same stretch and prints the same errors; None if no input
    says."""
    for inp in inputs:
        if inp.kind != "mcap":
            continue
        meta = _logged(inp.path, DEMO_METADATA)
        try:
            settle = float(meta["settle_s"]) if meta is not None else None
        except (KeyError, ValueError):
            continue  # (a record from another version: the default rule then)
        if settle is not None and math.isfinite(settle) and settle >= 0.0:
            return settle
    return None


def logged_min_scored_s(inputs: list[Input], *, older_demo: float) -> float | None:
    """The least sea after the settle time the run that made a log scored on (`DEMO_METADATA`), so that a
    replay of a `dpgw demo` log stopped soon after the skip says "not scored" where the demo did, not a
    figure on a few seconds; ``older_demo`` for a demo log written before the demo recorded it; None for
    a log no demo wrote."""
    for inp in inputs:
        if inp.kind != "mcap" or (meta := _logged(inp.path, DEMO_METADATA)) is None:
            continue
        try:
            least = float(meta.get("min_scored_s", older_demo))
        except ValueError:
            least = older_demo
        return least if math.isfinite(least) and least >= 0.0 else older_demo
    return None


def carried_metadata(inputs: list[Input], *, own_config: bool) -> list[tuple[str, dict[str, str]]]:
    """What a replay's output keeps of its first MCAP input's metadata, so that the output replays as
    the input did: the simulator's description (vessel, datum of the truth it carries) and, when the
    replay ran on the log's own configuration (``own_config``: no --config, no --vessel), that
    configuration."""
    for inp in inputs:
        if inp.kind != "mcap":
            continue
        names = (
            [SIM_METADATA, DEMO_METADATA, CONFIG_METADATA] if own_config else [SIM_METADATA, DEMO_METADATA]
        )
        return [(name, meta) for name in names if (meta := _logged(inp.path, name)) is not None]
    return []


def logged_datum(path: str | Path) -> dict[str, float] | None:
    """The NED datum a simulator log's truth is in (metadata `SIM_METADATA`), if the log has one."""
    meta = logged_sim(path)
    if meta is None or "datum" not in meta:  # an older log has no datum
        return None
    datum = json.loads(meta["datum"])
    return {k: float(datum[k]) for k in ("lat_deg", "lon_deg", "alt_m")}


def logged_vessel(inputs: list[Input]) -> str | None:
    """The built-in vessel a simulator log names (metadata `SIM_METADATA`), so that a log of `dpgw sim`
    replays without --vessel. A vessel that is not built in (a vessel file) is an error naming it: the
    log holds only its name, not the file."""
    from observers.vessel_files import builtin_vessels

    for inp in inputs:
        if inp.kind == "mcap" and (meta := logged_sim(inp.path)) is not None and meta.get("vessel"):
            name = meta["vessel"]
            if name not in builtin_vessels():
                raise ReplayError(
                    f"{inp.path}: the simulator ran vessel '{name}', which is not a built-in vessel: give "
                    "its file with --vessel FILE"
                )
            return name
    return None


def mcap_events(path: str | Path) -> Iterator[Event]:
    """Input events of a gateway or simulator log in log-time order (the order the live consumer saw)."""
    for topic, log_ns, _pub_ns, payload in read_messages(path):
        if topic.startswith("/raw/nmea/"):
            data = base64.b64decode(payload["data"]) if "data" in payload else payload["text"].encode("ascii")
            # the writer strips the final line terminator of a chunk into `eol` (left out for CR LF): put
            # back exactly what came, nothing if the chunk had none (a sentence split across reads: the
            # next chunk completes it, as live)
            end = b"" if payload.get("unterminated") else payload.get("eol", "\r\n").encode("ascii")
            yield RawEvent(log_ns, topic[len("/raw/nmea/") :], data + end, peer=payload.get("peer", ""))
        elif topic.startswith("/raw/mavlink/"):
            yield RawEvent(
                log_ns,
                topic[len("/raw/mavlink/") :],
                base64.b64decode(payload["data"]),
                peer=payload.get("peer", ""),
            )
        elif topic in ("/dp/setpoint", "/dp/mode", "/dp/tau", TICK_TOPIC, MALFORMED_INPUT_TOPIC):
            # (a tick at which the live gateway dead-reckoned: `Pipeline.tick` runs there again; an input
            # that fit no schema, as text: fed as received, refused as live)
            yield ControlEvent(log_ns, *input_from_log(topic, payload))


def mcap_sources(path: str | Path) -> dict[str, str]:
    """Raw sources in a log: name -> protocol."""
    out: dict[str, str] = {}
    with open(path, "rb") as f:
        try:
            summary = make_reader(f).get_summary()
        except Exception:
            summary = None
    topics = (
        [c.topic for c in summary.channels.values()]
        if summary is not None
        else sorted({t for t, *_ in read_messages(path)})
    )
    for topic in topics:
        if topic.startswith("/raw/nmea/"):
            out[topic[len("/raw/nmea/") :]] = "nmea"
        elif topic.startswith("/raw/mavlink/"):
            out[topic[len("/raw/mavlink/") :]] = "mavlink"
    return out


def truth_records(path: str | Path) -> list[dict[str, Any]]:
    return [p for _, _, _, p in read_messages(path, "/truth/state")]


FAST_SCAN_MIN_BYTES = 64 * 1024
"""NMEA text logs from this size on go through the compiled line scan (`wire.codecs.nmea_scan`); smaller
ones through the line-by-line reader. The two give the same events and counts (tests/test_replay.py);
they differ in cost. The scan saves about 25 µs a cycle (the pipeline then neither frames nor checksums
the lines), and its own first call costs 6-8 ms once per process beyond numba's start-up (~0.25 s, which
the observer's kernel pays anyway, whichever runs first); it pays from roughly 300 cycles, about 70 KB of
NMEA. (It was 8 MiB while loading the scan cost ~0.3 s of its own; measured with bench/bench_replay.py,
which reports both readers on the real logs.)"""


@dataclass
class Input:
    path: Path
    kind: str
    source: str  # source name for text logs and tlogs
    counts: LogCounts = field(default_factory=LogCounts)
    fast_scan: bool | None = None
    """NMEA text: the compiled line scan (True), the line-by-line reader (False), or by size (None)."""
    stamp_zone: tzinfo | None = None
    """NMEA text: the zone a logger's stamps without one were written in (`gateway.stamped_log`)."""
    capture: CaptureDevices | None = None
    """NMEA text: the devices its TAG blocks name (`device_sources`; found on first use)."""
    fed: dict[str, tuple[str, ...]] | None = None
    """NMEA text and tlogs replayed with a config of the user's: the config's sources each of the log's
    own sources feeds (`assign_sources`); None: the log's own names, as `build_config` configures them."""
    split_devices: bool = True
    """NMEA text: whether a capture's devices are replayed apart (`device_sources`)."""
    keep_tags: bool = False
    """NMEA text replayed as one log: its TAG blocks stay on its lines, for the config's sources that
    take a device (``tag_source``) to read, as they read them live (`assign_sources`)."""
    untagged: tuple[str, ...] = ()
    """NMEA text without TAG blocks fed to sources with a ``tag_source``: those sources, whose
    ``tag_source`` the replay does not apply (`assign_sources`)."""
    unconfigured: tuple[str, ...] = ()
    """MCAP, replayed with a config of the user's: the logged sources the config does not have, whose
    input is not replayed (`assign_sources`)."""

    @property
    def protocol(self) -> str:
        """What the log's own sources speak (an MCAP log's are told by `own_sources`)."""
        return "mavlink" if self.kind == "tlog" else "nmea"

    def events(self) -> Iterator[Event]:
        own = self.own_events()
        if self.fed is None:
            return own
        return _fed(own, self.fed, self.counts, per_line=self.kind == "nmea")

    def own_events(self) -> Iterator[Event]:
        """The log's events under its own source names."""
        if self.kind == "mcap":
            return mcap_events(self.path)
        if self.kind == "tlog":
            return tlog_events(self.path, self.source, self.counts)
        if is_stamped_only(self.path, self.stamp_zone):  # (a logger's file of one port without sentence
            # times, a gyro's; or a capture of the network whose TAG blocks carry the times, c:)
            devices = self.device_sources()
            keep = bool(devices) or self.keep_tags
            stamped = stamped_text_events(
                self.path, self.source, counts=self.counts, zone=self.stamp_zone, keep_tags=keep
            )
            return split_by_device(stamped, devices) if devices else stamped
        if devices := self.device_sources():
            tagged = nmea_text_events_reference(self.path, self.source, counts=self.counts, keep_tags=True)
            return spread_headings(split_by_device(tagged, devices), self.counts)
        if self.keep_tags:  # (one log to sources that take a device: they read its TAG blocks, as live)
            tagged = nmea_text_events_reference(self.path, self.source, counts=self.counts, keep_tags=True)
            return spread_headings(tagged, self.counts)
        if self.fast_scan if self.fast_scan is not None else self.path.stat().st_size >= FAST_SCAN_MIN_BYTES:
            cycles = nmea_text_events(self.path, self.source, counts=self.counts, only=USED_NMEA)
        else:
            cycles = nmea_text_events_reference(self.path, self.source, counts=self.counts)
        return spread_headings(cycles, self.counts)

    def sources(self) -> dict[str, str]:
        """The sources the log's events come from: name -> protocol."""
        if self.fed is None:
            return self.own_sources()
        return {name: self.protocol for names in self.fed.values() for name in names}

    def own_sources(self) -> dict[str, str]:
        """The log's own sources: name -> protocol (an MCAP log's as logged; a text log or a tlog named
        after its file, a capture's devices after the file and the device)."""
        if self.kind == "mcap":
            return mcap_sources(self.path)
        if devices := self.device_sources():
            own = {self.source: "nmea"} if self.capture is not None and self.capture.others else {}
            return {**own, **{name: "nmea" for name in devices.values()}}
        return {self.source: self.protocol}

    def device_sources(self) -> dict[str, str]:
        """NMEA text: for a capture of a ship's network whose TAG blocks name two devices or more, each
        device and the name of the source it is replayed as (the log's source and the device:
        ``navd_gp0001``); empty otherwise, the log one source. The sentences of no device go to the log's
        own source (`gateway.line_prefix.split_by_device`)."""
        if not self.split_devices or len(devices := self.tag_devices()) < 2:
            return {}
        names: dict[str, str] = {}
        for device in devices:
            name = base = f"{self.source}_{re.sub(r'[^a-z0-9_]', '_', device.lower())}"
            k = 1
            while name in names.values() or name == self.source:  # ("GP-01" and "GP_01")
                k += 1
                name = f"{base}_{k}"
            names[device] = name
        return names

    def tag_devices(self) -> dict[str, frozenset[str]]:
        """NMEA text: the devices its TAG blocks name (`capture_devices`; none for a plain log)."""
        if self.kind != "nmea":
            return {}
        if self.capture is None:
            self.capture = capture_devices(self.path)
        return self.capture.devices

    def source_entry(self, name: str) -> dict[str, Any]:
        """What a configured source replaying ``name`` is beyond the defaults: a device's source takes
        only that device (``tag_source``) in the roles its sentences fill."""
        for device, source in self.device_sources().items():
            if source == name and self.capture is not None:
                kinds = self.capture.devices[device]
                roles = [role for role, fills in DEVICE_ROLES.items() if kinds & fills]
                return {"tag_source": device, "roles": roles or ["position", "heading"]}
        return {}


DEVICE_ROLES = {"position": frozenset({"GGA", "GNS"}), "heading": frozenset({"HDT", "THS", "HDG"})}
"""The roles the sentences fill: those a device of a ship network's capture is replayed in, by the
sentences it sent (one that sent neither gets both, as a text log does), and what a replayed event
measures (`measures`)."""

COMPRESSED_SUFFIXES = (".gz", ".xz", ".bz2", ".zst")
"""The names of compressed logs (`gateway.compressed`), left out of the source's name as ``.txt`` is."""


def open_inputs(paths: Iterable[str | Path]) -> list[Input]:
    inputs: list[Input] = []
    names: Counter[str] = Counter()
    for p in paths:
        path = Path(p)
        kind = input_kind(path)
        packed = path.suffix.lower() in COMPRESSED_SUFFIXES
        stem = Path(path.stem).stem if packed else path.stem  # trial.txt.gz: trial
        name = re.sub(r"[^a-z0-9_]", "_", stem.lower()) or "log"
        if name[0].isdigit():
            name = f"log_{name}"
        names[name] += 1
        if names[name] > 1:
            name = f"{name}_{names[name]}"
        inputs.append(Input(path, kind, name))
    if not inputs:
        raise ReplayError("no log given")
    return inputs


def _fed(
    events: Iterator[Event], fed: Mapping[str, tuple[str, ...]], counts: LogCounts, per_line: bool
) -> Iterator[Event]:
    """``events`` under the names of the configured sources they feed (`Input.fed`): one copy for each,
    none (counted ``no_source``: lines, or a tlog's records) where no source takes them."""
    for ev in events:
        if not isinstance(ev, RawEvent):
            yield ev
            continue
        names = fed.get(ev.source, ())
        if not names:
            counts.counts["no_source"] += ev.data.count(b"\n") if per_line else 1
        for name in names:
            yield RawEvent(ev.rx_ns, name, ev.data, ev.checked, ev.peer, ev.records, ev.cycle)


def _input_of(inputs: list[Input], log: str) -> Input | None:
    """The input ``log`` names: its path as given, resolved, or its file name alone."""
    for inp in inputs:
        if log in (str(inp.path), inp.path.name) or Path(log).resolve() == inp.path.resolve():
            return inp
    return None


def assign_sources(
    inputs: list[Input], config: GatewayConfig, given: Iterable[str] = (), where: str = "--config"
) -> GatewayConfig:
    """Place the logs on ``config``'s sources (`place_sources`) and return the config to replay them with.

    A source with a ``tag_source`` takes, live, only the sentences whose TAG block names its device. A
    text log that feeds one whole (``--source``, or the only source of its protocol) keeps its TAG blocks
    on its lines, so the source reads them as it does live (`Input.keep_tags`). A log without TAG blocks
    (a serial logger's) has nothing to filter by: the sources it feeds take it whole, their
    ``tag_source`` not applied (said in `Input.untagged`), unless a capture feeds them too. Before, every
    sentence of such a log, or of a capture whose blocks the reader had taken off, was counted
    ``other_tag_source`` and nothing was replayed."""
    place_sources(inputs, config, given, where)
    tagged_to: set[str] = set()
    untagged_to: dict[int, set[str]] = {}
    by_name = {s.name: s for s in config.sources}
    for k, inp in enumerate(inputs):
        if inp.kind != "nmea" or inp.fed is None:
            continue
        takers = {n for names in inp.fed.values() for n in names if by_name[n].tag_source is not None}
        if not takers:
            continue
        if inp.tag_devices():
            tagged_to |= takers
            if not inp.device_sources():  # (a capture split by device carries its blocks already)
                inp.keep_tags = True
        else:
            untagged_to[k] = takers
    lifted = {n for takers in untagged_to.values() for n in takers} - tagged_to
    for k, takers in untagged_to.items():
        inputs[k].untagged = tuple(sorted(takers & lifted))
    if not lifted:
        return config
    return dataclasses.replace(
        config,
        sources=tuple(
            dataclasses.replace(s, tag_source=None) if s.name in lifted else s for s in config.sources
        ),
    )


def place_sources(
    inputs: list[Input], config: GatewayConfig, given: Iterable[str] = (), where: str = "--config"
) -> None:
    """Which of a user's ``config``'s sources each NMEA text log and tlog feeds (`Input.fed`), or a
    `ReplayError` that says how to choose. A gateway's MCAP log names its sources as it logged them:
    one whose sources are none of the config's is refused (nothing of it would be replayed); the ones
    the config leaves out (a sensor left out on purpose, or renamed) are noted in `Input.unconfigured`.

    For a text log or a tlog, in this order:

    1. ``given``: ``NAME=LOG`` (``--source``, repeatable: a log may feed several sources, each taking
       the sentences of its roles);
    2. a capture of a ship's network whose TAG blocks name devices that sources take (``tag_source``):
       each device the sources that take it, as live (the lines of devices no source takes are counted
       ``no_source``, not replayed); a capture of one device, to the sources that take it;
    3. the source named as the log's own (`open_inputs`: the file's name);
    4. the config's sources of the log's protocol, if there is one, or if no two of them share a role
       (a multiplexer's log to a config with a receiver and a gyro: each takes its own sentences).

    Otherwise (several sources that share a role, or none of the protocol) the log cannot be placed
    without the user, and the error names the sources and the flag."""
    by_name = {s.name: s for s in config.sources}
    chosen: dict[int, list[str]] = {}
    for text in given:
        name, sep, log = text.partition("=")
        if not sep or not name.strip() or not log.strip():
            raise ReplayError(f"--source {text!r}: expected NAME=LOG, the config's source and a log given")
        name, log = name.strip(), log.strip()
        spec = by_name.get(name)
        if spec is None:
            raise ReplayError(
                f"--source {text}: {where} has no source '{name}'{did_you_mean(name, by_name)} "
                f"(it has: {', '.join(by_name)})"
            )
        inp = _input_of(inputs, log)
        if inp is None:
            raise ReplayError(f"--source {text}: '{log}' is not one of the logs given")
        if inp.kind == "mcap":
            raise ReplayError(
                f"--source {text}: {log} is an MCAP log, which names its sources itself (NMEA text logs "
                "and tlogs take --source)"
            )
        if spec.protocol != inp.protocol:
            raise ReplayError(
                f"--source {text}: source '{name}' is {spec.protocol}, and {log} holds {inp.protocol}"
            )
        chosen.setdefault(inputs.index(inp), []).append(name)
    for k, inp in enumerate(inputs):
        if inp.kind == "mcap":
            logged = inp.own_sources()
            if logged and not any(name in by_name for name in logged):
                raise ReplayError(
                    f"{inp.path}: its sources ({', '.join(logged)}) are none of {where}'s "
                    f"({', '.join(by_name)}): nothing of it would be replayed. Give a config whose "
                    "sources are named as the log's (the log's own is used without --config)"
                )
            inp.unconfigured = tuple(name for name in logged if name not in by_name)  # (left out on purpose?)
            continue
        protocol = inp.protocol
        if k in chosen:
            inp.split_devices = False  # (the whole log to the sources named; a tag_source still filters)
            inp.fed = {inp.source: tuple(chosen[k])}
            continue
        devices = inp.device_sources()
        if devices:
            taken = {
                source: tuple(s.name for s in config.sources if s.tag_source == device)
                for device, source in devices.items()
            }
            if any(taken.values()):
                if inp.source in by_name and by_name[inp.source].protocol == protocol:
                    taken[inp.source] = (inp.source,)  # (the lines of no device)
                inp.fed = taken
                continue
            inp.split_devices = False  # (no source takes a device: the log is one source, as without TAGs)
        elif len(one := inp.tag_devices()) == 1:  # a capture of one device: to the sources that take it
            takers = tuple(s.name for s in config.sources if s.tag_source in one and s.protocol == protocol)
            if takers:
                inp.fed = {inp.source: takers}
                continue
        own = by_name.get(inp.source)
        if own is not None and own.protocol == protocol:
            inp.fed = {inp.source: (inp.source,)}
            continue
        candidates = [s for s in config.sources if s.protocol == protocol]
        roles = [role for s in candidates for role in s.roles]
        if candidates and (len(candidates) == 1 or len(roles) == len(set(roles))):
            inp.fed = {inp.source: tuple(s.name for s in candidates)}
            continue
        kind = "NMEA text" if protocol == "nmea" else "MAVLink"
        if not candidates:
            raise ReplayError(
                f"{inp.path}: {where} has no {protocol} source to take this {kind} log: add one, or "
                "replay it with --vessel alone"
            )
        listed = ", ".join(f"{s.name}: {'/'.join(s.roles)}" for s in candidates)
        raise ReplayError(
            f"{inp.path}: {where} has {len(candidates)} {protocol} sources that share a role "
            f"({listed}), and none named "
            f"'{inp.source}': say which takes the log, e.g. --source {candidates[0].name}={inp.path.name} "
            "(repeatable)"
        )


def merged_events(inputs: list[Input]) -> Iterator[Event]:
    """All inputs' events merged by time (each input is already in its own time order)."""
    if len(inputs) == 1:
        yield from inputs[0].events()
        return
    yield from heapq.merge(*(inp.events() for inp in inputs), key=lambda e: e.rx_ns)


_MEASURED_BY = tuple(
    (role, tuple(f"{kind},".encode("ascii") for kind in sorted(kinds)))
    for role, kinds in DEVICE_ROLES.items()
)
"""`DEVICE_ROLES` as the bytes of an event: each role and its sentences' formatters with their comma."""


def measures(ev: RawEvent, roles: frozenset[str]) -> frozenset[str]:
    """Which of its source's ``roles`` an event's sentences measure: position (GGA, GNS), heading (HDT,
    THS, HDG). Told from the bytes: a sentence the pipeline will reject still counts, so two events that
    might both measure one thing are never stepped as one instant."""
    data = ev.data
    return frozenset(
        role for role, kinds in _MEASURED_BY if role in roles and any(kind in data for kind in kinds)
    )


def with_next(events: Iterable[Event]) -> Iterator[tuple[Event, Event | None]]:
    """Each event with the one after it (None after the last)."""
    return pairwise(chain(events, (None,)))  # type: ignore[arg-type]  # (only the last pair holds None)


# --- configuration and observers --------------------------------------------------------------------------


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class ObserverSpec:
    name: str
    label: str
    params: dict[str, Any]  # numbers; a list (MMAE's candidates) a tuple of numbers

    def tuning(self, base: PassiveTuning) -> PassiveTuning:
        kw: dict[str, Any] = {k: v for k, v in base.__dict__.items()}
        for key, value in self.params.items():
            if key == "wave_period_s":
                kw["omega0"] = 2 * math.pi / value
            elif key in tuning_keys(self.name):
                kw[key] = value
        return PassiveTuning(**kw)

    def tuning_params(self) -> dict[str, float]:
        """The spec's keys of the common tuning (the rest are the observer's own)."""
        return {k: v for k, v in self.params.items() if k in tuning_keys(self.name)}

    def observer_params(self) -> dict[str, Any]:
        return {k: v for k, v in self.params.items() if k not in tuning_keys(self.name)}

    def make(self, config: GatewayConfig, defaults: Mapping[str, Any] | None = None) -> Observer:
        """The observer for ``config``'s vessel: ``defaults`` (a scenario's, `Scenario.observer_params`)
        under the config's params for this type, under the spec's own."""
        base = config.observer.params if self.name == config.observer.type else {}
        try:
            return make_observer(
                self.name,
                config.vessel,
                self.tuning(config.observer.tuning),
                params=with_defaults(self.name, defaults, {**base, **self.observer_params()}),
                allow_unchecked=config.observer.allow_unchecked,
            )
        except (TypeError, ValueError) as exc:  # a value of the right kind the observer refuses
            given = ",".join(f"{k}={_spec_value(v)}" for k, v in self.params.items())
            hint = (
                " (a list is numbers joined by /: candidates=2.5/3.8/5)" if isinstance(exc, TypeError) else ""
            )
            raise ReplayError(
                f"observer spec '{self.name}{':' + given if given else ''}': {exc}{hint}"
            ) from None


def parse_observer_spec(text: str) -> ObserverSpec:
    body, _, label = text.partition("@")
    name, _, rest = body.partition(":")
    name = name.strip()
    if name not in OBSERVER_TYPES:
        raise ReplayError(
            f"observer spec '{text}': unknown observer '{name}'{did_you_mean(name, OBSERVER_TYPES)} "
            f"(known: {', '.join(OBSERVER_TYPES)})"
        )
    keys = sorted(tuning_keys(name) | set(OBSERVER_PARAMS[name]))
    params: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        if eq and key in TUNING_KEYS and key not in keys:
            used = sorted(tuning_keys(name))
            raise ReplayError(
                f"observer spec '{text}': {name} does not use {key} of the passive tuning "
                f"({'it uses ' + ', '.join(used) if used else 'it uses none of it'}; its own keys: "
                f"{', '.join(OBSERVER_PARAMS[name]) or 'none'})"
            )
        if eq and key not in keys:
            key_hint = did_you_mean(key.strip(), keys)
            raise ReplayError(
                f"observer spec '{text}': unknown key '{key}'{key_hint} ({name} takes {', '.join(keys)})"
            )
        if not eq:
            raise ReplayError(f"observer spec '{text}': '{item}' is not key=value with a key of {keys}")
        switch = {"true": 1.0, "false": 0.0}.get(value.strip().lower())  # adaptive=true, per_dof=false
        if "/" in value and key in TUNING_KEYS:  # (a list: MMAE's candidates=2.5/3.8/5)
            raise ReplayError(f"observer spec '{text}': {key} takes one number, not a list")
        try:
            if "/" in value:  # (the comma separates keys)
                params[key] = tuple(float(x) for x in value.split("/"))
            else:
                params[key] = switch if switch is not None else float(value)
        except ValueError:
            raise ReplayError(
                f"observer spec '{text}': {key}={value!r} is not a number (or true/false, or a list "
                "of numbers joined by /)"
            ) from None
    if not label:
        label = name + "".join(f"_{k}{_spec_value(v)}" for k, v in params.items())
    label = re.sub(r"[^A-Za-z0-9_.-]", "_", label)
    return ObserverSpec(name, label, params)


def _spec_value(v: float | tuple[float, ...]) -> str:
    """A spec's value as written: 1.6, or a list 2.5/3.8/5."""
    return "/".join(f"{x:g}" for x in v) if isinstance(v, tuple) else f"{v:g}"


def _as_replayed(tables: dict[str, Any]) -> dict[str, Any]:
    """A logged gateway config as replay runs it. Replay commands no thrusters, so no source sends
    commands (and an unsigned link's ``allow_unsigned``, which only allowed that, goes too). A log written
    before ``[commands]`` existed came from a gateway that took every command input: so does its replay,
    or the replay would refuse the setpoints and modes the live run obeyed. One from before ``[control]
    wait_for_observer`` (a gateway that started in dp engaged DP at its first estimate; logs since record
    the option, `gateway.config.logged.for_log`) is replayed so too, and so is one from before ``[commands]
    manual_tau_hold_s`` (its gateway held a manual τ until the next one: ``inf``; logs since record it),
    and one from before ``[control] takeover_fade_s`` (its gateway kept the integrator's bumpless start
    content: ``inf``; logs since record the option, null for its default)."""
    out = without_unlogged_keys(tables)
    sources = []
    for src in out.get("sources", []):
        if isinstance(src, dict) and src.get("commands"):
            src = {k: v for k, v in src.items() if k != "commands"}
            if "signing_key" not in src:
                src.pop("allow_unsigned", None)
        sources.append(src)
    if "sources" in out:
        out["sources"] = sources
    commands = out.setdefault("commands", {"accept": ["mode", "setpoint", "tau"]})
    if isinstance(commands, dict) and "manual_tau_hold_s" not in commands:
        out["commands"] = {**commands, "manual_tau_hold_s": math.inf}
    control = out.get("control")
    if isinstance(control, dict) and control.get("initial_mode") == "dp":
        out["control"] = {"wait_for_observer": False, **control}
    control = out.get("control", {})
    if isinstance(control, dict) and "takeover_fade_s" not in control:
        # a gateway of before the takeover fade kept the integrator's bumpless start (`DPController`)
        out["control"] = {**control, "takeover_fade_s": math.inf}
    return out


def _unlogged_key_sources(
    inputs: list[Input], keyless: Collection[str] | None = None
) -> tuple[list[str], bool]:
    """The sources of the logged config whose signing key the log does not hold
    (`gateway.config.logged`) — of those, only the ``keyless`` ones if given: the sources the replay's
    config (a ``--config``) gives no key either — and whether the log records the live gateway's verdicts
    on their frames (`SIGNING_VERDICTS_KEY` in its config record; older logs do not)."""
    for inp in inputs:
        if inp.kind == "mcap" and (tables := logged_config(inp.path)) is not None:
            meta = _logged(inp.path, CONFIG_METADATA) or {}
            names = unlogged_key_sources(tables)
            if keyless is not None:
                names = [n for n in names if n in keyless]
            return names, SIGNING_VERDICTS_KEY in meta
    return [], False


def keyless_mavlink_sources(config: GatewayConfig) -> frozenset[str]:
    """The MAVLink sources ``config`` gives no signing key: a replay with it takes their frames as the
    log's verdicts say (`logged_signing_verdicts`), or unchecked (`unchecked_signatures`)."""
    return frozenset(s.name for s in config.sources if s.protocol == "mavlink" and s.signing_key is None)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class SigningVerdicts:
    """The live gateway's verdicts on the frames of its signed links, as a log records them
    (`/raw/mavlink_rejected/<source>`), for a replay without the keys.

    ``tables``: per source, (peer, chunk receive time ns) → the (offset, digest, reason) of each frame of
    that chunk it refused (`SourceSpec.logged_verdicts`); ``counts``: per source, the refusals by reason,
    as the live gateway counted them."""

    tables: dict[str, dict[tuple[str, int], tuple[mv.LoggedVerdict, ...]]]
    counts: dict[str, dict[str, int]]


def logged_signing_verdicts(
    inputs: list[Input], keyless: Collection[str] | None = None
) -> SigningVerdicts | None:
    """The verdicts the logs record for the sources whose key they do not hold; None for a log written
    before gateways recorded them (its signed links are then replayed unchecked: `unchecked_signatures`).
    Reads only the verdict channels (rejections are rare: a few records). ``keyless``: as
    `_unlogged_key_sources`."""
    names, recorded = _unlogged_key_sources(inputs, keyless)
    if not names or not recorded:
        return None
    tables: dict[str, dict[tuple[str, int], list[mv.LoggedVerdict]]] = {name: {} for name in names}
    counts: dict[str, dict[str, int]] = {name: dict.fromkeys(mv.SIGNING_REASONS, 0) for name in names}
    logs = [inp.path for inp in inputs if inp.kind == "mcap"]
    topics = [SIGNING_REJECTED_TOPIC + name for name in names]
    for topic, _, _, p in read_messages(logs, topics):
        name = topic[len(SIGNING_REJECTED_TOPIC) :]
        reason = p.get("reason")
        if reason not in mv.SIGNING_REASONS:
            continue  # (a reason of a later version: not one this replay can apply)
        chunk = (str(p.get("peer", "")), int(p["stamp_ns"]))
        tables[name].setdefault(chunk, []).append((int(p["offset"]), str(p["digest"]), reason))
        counts[name][reason] += 1
    return SigningVerdicts(
        {name: {chunk: tuple(v) for chunk, v in t.items()} for name, t in tables.items()}, counts
    )


def unchecked_signatures(
    inputs: list[Input], keyless: Collection[str] | None = None
) -> dict[str, dict[str, int]]:
    """The sources of the logged config `build_config` replays whose MAVLink signing key the log does not
    hold (`gateway.config.logged`) and whose live verdicts it does not record either (a log written before
    gateways recorded them): their frames are replayed with their signatures unchecked. Per source, the
    frames the live gateway rejected for signing (``bad_signature``, ``unsigned``), from the last
    ``/dp/status`` of the logs: those the replay takes and the live run did not (none: the same frames)."""
    names, recorded = _unlogged_key_sources(inputs, keyless)
    if not names or recorded:
        return {}
    last: dict[str, Any] = {}
    logs = [inp.path for inp in inputs if inp.kind == "mcap"]
    for _, _, _, status in read_messages(logs, "/dp/status"):
        last = status
    counts = last.get("sources", {}) if isinstance(last, dict) else {}
    return {
        name: {
            reason: int((counts.get(name) or {}).get("rejected", {}).get(reason, 0))
            for reason in ("bad_signature", "unsigned")
        }
        for name in names
    }


def build_config(
    inputs: list[Input],
    *,
    config_path: str | Path | None = None,
    vessel: str | None = None,
    source_args: Iterable[str] = (),
) -> GatewayConfig:
    """The configuration to replay with: --config, else the log's own, else one built for --vessel.
    With --config, the text logs and tlogs are placed on its sources (`assign_sources`; ``source_args``:
    --source ``NAME=LOG``)."""
    from gateway.config import load_config

    if config_path is not None:
        config = load_config(config_path)
        return assign_sources(inputs, config, source_args, where=f"--config {config_path}")
    if given := list(source_args):
        raise ReplayError(f"--source {given[0]}: names a source of --config FILE, and none is given")
    for inp in inputs:
        if inp.kind == "mcap" and (tables := logged_config(inp.path)) is not None:
            if vessel is not None:
                tables = dict(tables)
                tables["vessel"] = (  # a --vessel file is where the user said, not beside the log
                    {"name": vessel}
                    if "/" not in vessel and not vessel.endswith(".toml")
                    else {"file": str(Path(vessel).resolve())}
                )
            tables = {**_as_replayed(tables), "log": {"path": ""}}
            return parse_config(tables, base_dir=inp.path.resolve().parent, where=f"{inp.path} (metadata)")
    if vessel is None:
        vessel = logged_vessel(inputs)
    if vessel is None:
        logs = ", ".join(str(inp.path) for inp in inputs)
        what = (
            "carries no configuration (not a dpgw gateway or simulator log, or cut before its start was"
            " saved)"
            if any(inp.kind == "mcap" for inp in inputs)
            else "names no vessel (an NMEA text log or a tlog does not)"
        )
        raise ReplayError(f"{logs}: {what}: give --vessel NAME|FILE or --config FILE")
    tables = default_config(vessel)
    # A simulator's log says which datum its truth is in: replay there, not at the first fix (a wave-moved,
    # noisy position ~1 m off, which every score against the truth would carry as a constant error).
    for inp in inputs:
        if inp.kind == "mcap" and (datum := logged_datum(inp.path)) is not None:
            tables["datum"] = datum
            break
    sources: list[dict[str, Any]] = []
    for inp in inputs:
        for name, protocol in inp.sources().items():
            roles = ["position", "heading"] if protocol == "nmea" else ["position", "heading", "thrusters"]
            url = "udp://127.0.0.1:0" if protocol == "nmea" else "udpin:127.0.0.1:0"
            sources.append(
                {
                    "name": name,
                    "url": url,
                    "protocol": protocol,
                    "roles": roles,
                    "timeout_s": 5.0,
                    "priority": len(sources) + 1,  # sources sharing a role need distinct priorities
                    **inp.source_entry(name),
                }
            )
    if not sources:
        raise ReplayError("the logs hold no NMEA or MAVLink input")
    tables["sources"] = sources
    tables["log"] = {"path": ""}
    return parse_config(tables, base_dir=Path.cwd(), where="dpgw replay")


def build_pipeline(
    config: GatewayConfig,
    specs: list[ObserverSpec],
    *,
    foxglove_channels: bool = True,
    controller: bool = False,
    signing_verdicts: SigningVerdicts | None = None,
    observer_defaults: Mapping[str, Mapping[str, Any]] | None = None,
) -> Pipeline:
    """The live pipeline for ``config`` with the observers of ``specs``; ``foxglove_channels=False`` leaves
    out the Foxglove-native channels. Estimation only unless ``controller``: replay sends no command
    anywhere, and a controller would only make the observer believe its own commands were delivered
    (without thruster feedback the observer's τ is the commanded one) on a trial where something else
    drove the thrusters. ``controller=True`` is for a dpgw log replayed with its own config: the live
    gateway's controller then did command the vessel, and its state is part of what the observer saw
    (the wind feed-forward's load, the commanded τ when feedback was stale), so the replay keeps it to
    reproduce the live estimates; the commands it recomputes go to the output log only.

    ``signing_verdicts`` (`logged_signing_verdicts`): a signed link whose key the log does not hold
    refuses the frames the live gateway refused, for the same reasons, and takes the others.

    ``observer_defaults``: settings by observer type under the config's and the specs' own (a simulator
    log's scenario's, `Scenario.observer_params`), as the study and the closed loop apply them."""
    spec = dataclasses.replace(PipelineSpec.from_config(config), foxglove_channels=foxglove_channels)
    # a link signed with a key the config gives (a log written before logs left keys out, or --config):
    # the logged frames' signatures are checked against the log's own time, not this host's clock
    tables = signing_verdicts.tables if signing_verdicts is not None else {}
    spec = dataclasses.replace(
        spec,
        sources=tuple(
            dataclasses.replace(
                s,
                signatures_from_a_log=True,
                logged_verdicts=tables.get(s.name) if s.signing_key is None else None,
            )
            for s in spec.sources
        ),
    )
    defaults = observer_defaults or {}
    if specs:
        # Only the observers change: every other part of the config's pipeline (reference checks,
        # command policy, sources, datum) is the one the config describes. Rebuilding the spec field by
        # field once dropped the integrity and command sections of a logged or given config.
        primary = specs[0]
        spec = dataclasses.replace(
            spec,
            observer=primary.make(config, defaults.get(primary.name)),
            observer_name=primary.label,
            extra_observers=tuple((s.label, s.make(config, defaults.get(s.name))) for s in specs[1:]),
        )
    if not controller:
        spec = dataclasses.replace(spec, control=None)
    return Pipeline(spec)


def runs_its_own_controller(inputs: list[Input], *, own_config: bool) -> bool:
    """True when the replay runs on a dpgw log's own configuration (``own_config``: no --config, no
    --vessel, as for `carried_metadata`) and a log has one: the live gateway's controller drove the
    vessel, and `build_pipeline` keeps it (``controller=True``)."""
    return own_config and any(inp.kind == "mcap" and logged_config(inp.path) is not None for inp in inputs)


# --- the job ----------------------------------------------------------------------------------------------

GC_FREEZE_EVERY = 5000
"""Events between `gc.freeze()` calls in `run_replay`."""


@dataclass
class ReplayResult:
    events: int = 0
    sentences: int = 0
    outputs: int = 0
    estimates: Counter[str] = field(default_factory=Counter)
    restarts: int = 0  # observer restarts from a returning reference (`Pipeline.restarts`)
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    # "log NAME" -> (first, last) event time in ns since 1970 (UTC): what the log covers, from its own times
    spans: dict[str, tuple[int, int]] = field(default_factory=dict)
    collected: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # topic -> payloads
    truth: list[dict[str, Any]] = field(default_factory=list)


def replay(config: GatewayConfig, path: str | Path) -> list[Output]:
    """Every output the pipeline gives for a gateway log's events (status excluded: it is clock driven)."""
    pipeline = Pipeline(PipelineSpec.from_config(config))
    out: list[Output] = []
    for ev in mcap_events(path):
        out.extend(pipeline.feed(ev))
    return out


def config_from_log(path: str | Path, base_dir: Path | None = None) -> GatewayConfig:
    data = logged_config(path)
    if data is None:
        raise ValueError(f"{path}: no dpgw configuration in the log's metadata (give --config)")
    data = {**without_unlogged_keys(data), "log": {"path": ""}}
    return parse_config(data, base_dir=base_dir or Path(path).resolve().parent, where=f"{path} metadata")


def run_replay(
    inputs: list[Input],
    pipeline: Pipeline,
    *,
    out: McapLogWriter | None = None,
    collect: Iterable[str] = (),
    on_outputs: Callable[[Event, list[Output]], None] | None = None,
    progress: Callable[[int], None] | None = None,
    status_period_ns: int | None = None,
) -> ReplayResult:
    """Feed every event through the pipeline; write outputs to ``out``; keep the ``collect`` topics.

    ``status_period_ns``: a `/dp/status` (with its Foxglove log lines) this often in the log's time, and
    one after the last event, as the live gateway gives them at its status rate; None: only the statuses
    the pipeline makes itself, at a reference state change. A status falls after the outputs of the first
    event at or past its due time, stamped with that event's time (a log's time has no ticks between
    events); one the pipeline made at that event already counts as it."""
    result = ReplayResult()
    wanted = set(collect)
    for topic in wanted:
        result.collected[topic] = []
    for inp in inputs:
        if inp.kind == "mcap":
            result.truth.extend(truth_records(inp.path))
    # A simulator log's truth goes into --out at its times, before each event's records: written all
    # first, a reader streaming the file (without its index) saw time go back by the whole log.
    truth = sorted(result.truth, key=lambda r: int(r["stamp_ns"])) if out is not None else []
    truth_ns = [int(r["stamp_ns"]) for r in truth]
    truth_at = 0  # the next truth record to write
    frozen = gc.get_freeze_count()
    protocols = {name: spec.protocol for name, spec in pipeline.sources.items()}
    estimates = result.estimates
    collected = result.collected
    feed = pipeline.feed
    encoders: dict[type[Message], Callable[[Message], bytes]] = {}  # message class -> `encoder_of` it
    events = sentences = outputs_n = 0  # (locals in the loop, into `result` at the end)
    source_spans: dict[str, list[int]] = {}  # source -> [first, last] event time (ns)
    # The sources a text log or a tlog feeds, and their roles. Their events are at the log's times: two
    # sources' at one time that measure different things (the position and the heading) are one instant,
    # stepped once with both (`Pipeline.feed`'s defer_step). Two that measure the same (two receivers) step
    # one after the other, in the log's order, as their datagrams arrived live: the first fix taken is
    # what the second is tested against (two receivers that disagree from the start are not averaged into
    # a position that is neither's). An MCAP log's events are the receive times the live gateway stepped
    # on, as they were.
    by_log_time = {
        name: pipeline.sources[name].roles
        for inp in inputs
        if inp.kind != "mcap"
        for name in inp.sources()
        if name in pipeline.sources
    }
    next_status_ns = status_ns = -1  # the next periodic status due, the last one made (ns)
    last_event: Event | None = None
    for ev, after in with_next(merged_events(inputs)):
        last_event = ev
        events += 1
        if frozen == 0 and events % GC_FREEZE_EVERY == 0:
            # Everything alive now (the outputs kept in `collect`, the pipeline) is long-lived: take it out
            # of the garbage collector's passes, which otherwise re-traverse it and grow with the log
            # (2.3-3.1 s instead of 1.9 s for an hour of 10 Hz data when estimates are collected).
            gc.freeze()
        records: list[tuple[str, bytes, int, Any]] = []
        if isinstance(ev, RawEvent):
            span = source_spans.get(ev.source)
            if span is None:
                source_spans[ev.source] = [ev.rx_ns, ev.rx_ns]
            elif ev.rx_ns > span[1]:
                span[1] = ev.rx_ns
            elif ev.rx_ns < span[0]:  # (a log's time may step back: counted, kept)
                span[0] = ev.rx_ns
            protocol = protocols.get(ev.source, "nmea")
            # NMEA: lines (every event ends with its line end; a first line that is a sentence's tail
            # counts too); MAVLink: its source's frames, counted by the pipeline, after the loop (an
            # MCAP record holds every frame of a read: 1,501 records held 9,307 frames)
            if protocol == "nmea":
                sentences += ev.data.count(b"\n")
            if out is not None:
                if protocol == "nmea":
                    records.append((*raw_nmea_record(ev.source, ev.data), ev.rx_ns, RawNmea))
                else:
                    records.append((*raw_mavlink_record(ev.source, ev.data), ev.rx_ns, RawMavlink))
        elif out is not None and isinstance(ev, ControlEvent):
            # a command input or a dead-reckoning tick, as the live gateway logged it (wrapped as the
            # service wraps it), before its outputs: the replay's log replays as the live log does
            topic, body = logged_input(ev.key, ev.payload)
            out.write(topic, body, ev.rx_ns, ev.rx_ns)
        if (
            type(after) is RawEvent
            and after.rx_ns == ev.rx_ns
            and type(ev) is RawEvent
            and after.source != ev.source
            and after.source in by_log_time
            and ev.source in by_log_time
            and measures(ev, by_log_time[ev.source]).isdisjoint(measures(after, by_log_time[after.source]))
        ):
            outputs = feed(ev, True)
        else:
            outputs = feed(ev)
        if status_period_ns is not None:
            made = any(o.topic == "/dp/status" for o in outputs)
            if ev.rx_ns >= next_status_ns:
                if not made:
                    outputs = outputs + pipeline.status_outputs(ev.rx_ns)
                    made = True
                next_status_ns = ev.rx_ns + status_period_ns
            if made:
                status_ns = ev.rx_ns
        for o in outputs:
            msg = o.message
            if out is not None:
                kind = type(msg)
                encode = encoders.get(kind)
                if encode is None:
                    encode = encoders[kind] = encoder_of(kind)
                records.append((o.topic, encode(msg), o.stamp_ns, kind))  # (encode(msg): msg.encode())
            if wanted and o.topic in wanted:
                collected[o.topic].append(o.payload)
            if isinstance(msg, Estimate):
                estimates[msg.observer] += 1
        if out is not None:
            while truth_at < len(truth_ns) and truth_ns[truth_at] <= ev.rx_ns:
                out.write("/truth/state", truth[truth_at], truth_ns[truth_at], truth_ns[truth_at])
                truth_at += 1
            out.write_many(records)  # the cycle's raw input, then its outputs: the order `write` would give
        outputs_n += len(outputs)
        if on_outputs is not None:
            on_outputs(ev, outputs)
        if progress is not None and events % 2000 == 0:
            progress(events)
    if out is not None:
        for k in range(truth_at, len(truth_ns)):  # (the truth after the last event)
            out.write("/truth/state", truth[k], truth_ns[k], truth_ns[k])
    if status_period_ns is not None and events and pipeline.last_ns > status_ns:
        last = pipeline.status_outputs(pipeline.last_ns)  # the last status, as the live gateway's at its stop
        if out is not None:
            out.write_many(
                [(o.topic, encoder_of(type(o.message))(o.message), o.stamp_ns, type(o.message)) for o in last]
            )
        if on_outputs is not None and last_event is not None:
            on_outputs(last_event, last)
        for o in last:
            if wanted and o.topic in wanted:
                collected[o.topic].append(o.payload)
        outputs_n += len(last)
    result.events, result.outputs = events, outputs_n
    if progress is not None:
        progress(events)  # the bar ends at the true count
    if frozen == 0 and gc.get_freeze_count():  # (a caller's own frozen objects are left alone)
        gc.unfreeze()  # (back to normal collection; anything cyclic frozen meanwhile is collected later)
    result.restarts = pipeline.restarts
    now = pipeline.last_ns
    status = pipeline.status_message(now)
    unmatched = pipeline.unmatched_verdicts()
    for name, c in status.sources.items():
        warned = {f"warning {k}": v for k, v in c.warnings.items()}  # (used: apart from the rejects)
        if unmatched.get(name):  # logged verdicts that found no frame: those frames were taken unchecked
            warned["warning signing_verdict_unmatched"] = unmatched[name]
        lost = {"lost_lines": c.lost_lines} if c.lost_lines else {}  # (a ship network's, by its line counts)
        result.counts[f"source {name}"] = {"received": c.received, **c.rejected, **warned, **lost}
        if protocols.get(name, "nmea") != "nmea" and name in source_spans:  # (frames: see the loop)
            sentences += c.received + sum(c.rejected.values())
    result.sentences = sentences
    for inp in inputs:
        covered = [source_spans[src] for src in inp.sources() if src in source_spans]
        if covered:
            result.spans[f"log {inp.path.name}"] = (min(a for a, _ in covered), max(b for _, b in covered))
        if inp.kind == "nmea":
            result.counts[f"log {inp.path.name}"] = {
                "lines": inp.counts.lines,
                "cycles": inp.counts.cycles,
                **inp.counts.counts,
            }
        elif inp.kind == "tlog":  # (records of one frame each: no lines, no cycles)
            result.counts[f"log {inp.path.name}"] = {"records": inp.counts.lines, **inp.counts.counts}
    return result
