"""Fuzz the gateway's pipeline: a million malformed and hostile inputs between a clean on-station stream.

A vessel lies still at the datum, heading 45°; its DGPS sends GGA and its gyro HDT at 10 Hz, clean. Between
them, on the same three sources (DGPS, gyro, a MAVLink thruster link), go fuzzed inputs:

* NMEA (each one line, ending CR/LF): real sentences (GGA, GNS, RMC, VTG, GST, ZDA, HDT, THS, ROT, HDG at
  the true values) with flipped bytes, cut short, with a wrong checksum, with fields replaced by garbage
  under a *valid* checksum, overlong lines, random bytes;
* MAVLink: frames of every message the dialect defines with random payloads and a *valid* CRC (v1 and v2,
  random sequence, system and component), and the same with flipped bytes, cut short, or random bytes.

Well-formed inputs that carry a measurement the gateway uses — a valid fix farther than ``BOUND_M`` from the
truth, a heading farther than ``BOUND_DEG``, a thruster status of one of the vessel's thrusters — would move
the estimate by design until the gateway checks its references: they are set aside by an oracle (the
codec layer, run on each input alone) and fed afterwards in a phase of their own, reported separately.
Everything else must leave the estimate where the clean stream puts it.

Reports inputs/s, the largest estimate error against the true station (position and heading), the RSS
growth after a warm-up, and whether every input is counted: per source, ``received`` and ``rejected`` of
/dp/status against what the codec layer says of each input alone (MAVLink: of the same stream).

    python bench/fuzz_gateway.py [--inputs 1000000] [--seed 1] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import random
import resource
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from gateway.config import parse_config
from gateway.pipeline import USED_NMEA, Pipeline, PipelineSpec, RawEvent
from observers.vessel import load_vessel
from wire.codecs import mavlink as mv
from wire.codecs import nmea as nmea_codec
from wire.codecs import nmea_encode as enc
from wire.codecs.nmea_framing import NmeaFramer
from wire.geodesy import LocalFrame

DATUM = (59.4, 10.5)
HEADING_DEG = 45.0
BOUND_M = 0.25
"""A valid fix within this of the truth stays in the main phase (a flipped last digit of the minutes)."""
BOUND_DEG = 0.25
RATE_HZ = 10.0
NS = 1_000_000_000
START = datetime(2026, 6, 1, 10, 0, 0, tzinfo=UTC)
VESSEL = "mss_supply"
SOURCES = ("gps", "gyro", "thr")
KINDS = (
    "nmea_flip",
    "nmea_truncate",
    "nmea_bad_checksum",
    "nmea_garbage_fields",
    "nmea_overlong",
    "nmea_random",
    "mavlink_random_payload",
    "mavlink_flip",
    "mavlink_truncate",
    "mavlink_random",
)
_TOKENS = (
    "", "-", "+", ".", "NaN", "nan", "inf", "-inf", "1e999", "-1e999", "9" * 40, "0x1F", " 12", "12 ",
    "-0", "00000", "99999.99", "1,2", "N", "S", "E", "W", "T", "M", "A", "V", "Ω", "\x7f", "*", "$",
    "4500.0000", "18000.0", "-9000.0", "360.0", "-360", "1.2.3", "12e", "e5", "235960", "999999.99",
)  # fmt: skip


def pipeline() -> Pipeline:
    """The gateway's pipeline for a DGPS, a gyro and a MAVLink thruster link (as tests/test_pipeline.py)."""
    tables = {
        "vessel": {"name": VESSEL},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position"]},
            {"name": "gyro", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["heading"]},
            {"name": "thr", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"]},
        ],
        "observer": {"wave_period_s": 8.0},
        "log": {"path": ""},
    }
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd())))


CLEAN_NOISE_M = 0.05
CLEAN_NOISE_DEG = 0.02
"""Noise on the clean stream (a good RTK fix and gyro). A real receiver never repeats a value to the
last digit for seconds; one that does is frozen, and the reference tests say so (a noiseless stream
here was refused by the freeze test, and the estimate dead-reckoned away)."""


def clean_tick(k: int) -> list[tuple[str, bytes]]:
    """The clean stream's tick k: a GGA at the datum (quality 2) and an HDT of 45°, with a little noise
    (seeded by k, so every run and every pipeline sees the same stream)."""
    utc = START + timedelta(seconds=k / RATE_HZ)
    rng = random.Random(k)
    dlat = rng.gauss(0.0, CLEAN_NOISE_M) / 111_320.0
    dlon = rng.gauss(0.0, CLEAN_NOISE_M) / (111_320.0 * math.cos(math.radians(DATUM[0])))
    gga = enc.gga("GP", utc, DATUM[0] + dlat, DATUM[1] + dlon, 2, 12, 0.8, 20.0, None, 2.0, 1)
    heading = math.radians(HEADING_DEG + rng.gauss(0.0, CLEAN_NOISE_DEG))
    return [("gps", gga.encode()), ("gyro", enc.hdt("HE", heading).encode())]


@dataclass
class Expect:
    """What the codec layer says of the inputs fed to one source, each taken alone."""

    received: int = 0
    rejected: int = 0


@dataclass
class Tally:
    inputs: dict[str, int] = field(default_factory=lambda: dict.fromkeys(KINDS, 0))
    set_aside: dict[str, int] = field(default_factory=dict)
    silent: int = 0  # inputs the codec layer gives no count for (MAVLink noise without a frame marker)


class Fuzzer:
    """Makes fuzzed inputs, deterministic from ``seed``; `next` returns (source, bytes, kind, outlier)."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)
        utc = START
        lat, lon = DATUM
        psi = math.radians(HEADING_DEG)
        self.gps_templates = [
            enc.gga("GP", utc, lat, lon, 2, 12, 0.8, 20.0, None, 2.0, 1),
            enc.gns("GN", utc, lat, lon, "DD", 12, 0.8, 20.0, None, 2.0, 1),
            enc.rmc("GP", utc, lat, lon, 0.0, 0.0, True, "D"),
            enc.vtg("GP", 0.0, 0.0, "D"),
            enc.gst(
                "GP",
                utc,
                rms_m=0.3,
                sigma_major_m=0.3,
                sigma_minor_m=0.3,
                orient_rad=0.0,
                sigma_lat_m=0.3,
                sigma_lon_m=0.3,
                sigma_alt_m=0.45,
            ),
            enc.zda("GP", utc),
        ]
        self.gyro_templates = [
            enc.hdt("HE", psi),
            enc.ths("HE", psi, "A"),
            enc.rot("HE", 0.0, True),
            enc.hdg("HC", psi, 0.0, 0.0),
        ]
        d = mv.dialect()
        self.mav_classes = sorted(d.mavlink_map.items())
        self.mav = mv.encoder(1, 1)
        self.frame = LocalFrame(lat, lon, 0.0)
        self.thrusters = {t.id for t in load_vessel(VESSEL).thrusters}

    # --- NMEA ---------------------------------------------------------------------------------------------

    def _template(self) -> tuple[str, str]:
        if self.rng.random() < 0.6:
            return "gps", self.rng.choice(self.gps_templates)
        return "gyro", self.rng.choice(self.gyro_templates)

    def nmea(self, kind: str) -> tuple[str, bytes]:
        rng = self.rng
        source, text = self._template()
        body = text[1 : text.index("*")]
        if kind == "nmea_flip":
            data = bytearray(text.encode())
            for _ in range(rng.randint(1, 3)):
                i = rng.randrange(len(data) - 2)  # not the line end
                data[i] ^= 1 << rng.randrange(8)
            return source, bytes(data).rstrip(b"\r\n") + b"\r\n"
        if kind == "nmea_truncate":
            return source, text.encode()[: rng.randrange(1, len(text) - 2)] + b"\r\n"
        if kind == "nmea_bad_checksum":
            good = enc.checksum(body)
            bad = rng.choice([f"{rng.randrange(256):02X}" for _ in range(3)] + ["", "Z9", "1", "123"])
            if bad == good:
                bad = f"{int(good, 16) ^ 0x5A:02X}"
            return source, f"${body}*{bad}\r\n".encode()
        if kind == "nmea_garbage_fields":
            parts = body.split(",")
            for _ in range(rng.randint(1, 3)):
                i = rng.randrange(1, len(parts)) if len(parts) > 1 else 0
                parts[i] = self._token()
            if rng.random() < 0.1:
                parts += [self._token() for _ in range(rng.randint(1, 5))]
            elif rng.random() < 0.1 and len(parts) > 2:
                parts = parts[: rng.randrange(1, len(parts))]
            new = ",".join(parts).replace("*", "+").replace("$", "#").replace("\r", " ").replace("\n", " ")
            raw = new.encode("utf-8")  # non-ASCII garbage too, under a checksum computed over its bytes
            return source, b"$" + raw + b"*" + xor_checksum(raw) + b"\r\n"
        if kind == "nmea_overlong":
            filler = "".join(rng.choice("0123456789,.ABC") for _ in range(rng.randint(180, 600)))
            return source, f"${body},{filler}*{enc.checksum(body + ',' + filler)}\r\n".encode()
        # random bytes (never only line ends: a blank line is not an input)
        n = rng.randint(1, 120)
        noise = bytes(rng.getrandbits(8) for _ in range(n)).rstrip(b"\r\n") or b"\x00"
        return source, noise + b"\r\n"

    def _token(self) -> str:
        rng = self.rng
        r = rng.random()
        if r < 0.6:
            return rng.choice(_TOKENS)
        if r < 0.8:
            return f"{rng.uniform(-1e6, 1e6):.{rng.randint(0, 8)}f}"
        return "".join(chr(rng.randint(0x20, 0x7E)) for _ in range(rng.randint(1, 12)))

    # --- MAVLink ------------------------------------------------------------------------------------------

    def _valid_frame(self) -> bytes:
        """A frame of a dialect message with a random payload and the right CRC (v1 or v2)."""
        rng = self.rng
        msg_id, cls = rng.choice(self.mav_classes)
        size = struct_size(cls)
        payload = bytes(rng.getrandbits(8) for _ in range(size))
        seq, sysid, compid = rng.randrange(256), rng.randrange(256), rng.randrange(256)
        if msg_id < 256 and rng.random() < 0.2:
            header = bytes([0xFE, size, seq, sysid, compid, msg_id])
        else:
            if rng.random() < 0.5:  # MAVLink 2 trims trailing zero bytes of the payload
                payload = payload.rstrip(b"\x00") or b"\x00"
            header = bytes(
                [
                    0xFD,
                    len(payload),
                    0,
                    0,
                    seq,
                    sysid,
                    compid,
                    msg_id & 0xFF,
                    (msg_id >> 8) & 0xFF,
                    msg_id >> 16,
                ]
            )
        crc = mv.dialect().x25crc(header[1:] + payload)
        crc.accumulate(bytes((cls.crc_extra,)))
        return header + payload + crc.crc.to_bytes(2, "little")

    def mavlink(self, kind: str) -> bytes:
        rng = self.rng
        if kind == "mavlink_random_payload":
            return self._valid_frame()
        if kind == "mavlink_flip":
            data = bytearray(self._valid_frame())
            for _ in range(rng.randint(1, 3)):
                data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
            return bytes(data)
        if kind == "mavlink_truncate":
            frame = self._valid_frame()
            return frame[: rng.randrange(1, len(frame))]
        data = bytearray(rng.getrandbits(8) for _ in range(rng.randint(1, 120)))
        if rng.random() < 0.5:
            data[rng.randrange(len(data))] = rng.choice((0xFD, 0xFE))
        return bytes(data)

    def next(self) -> tuple[str, bytes, str]:
        kind = self.rng.choice(KINDS)
        if kind.startswith("nmea"):
            source, data = self.nmea(kind)
            return source, data, kind
        return "thr", self.mavlink(kind), kind


def xor_checksum(body: bytes) -> bytes:
    """NMEA's checksum of any bytes (two hex digits): the XOR of all of them."""
    x = 0
    for b in body:
        x ^= b
    return f"{x:02X}".encode()


_SIZES: dict[int, int] = {}


def struct_size(cls: Any) -> int:
    """The full payload length of a generated MAVLink message class (its unpacker's size)."""
    size = _SIZES.get(cls.id)
    if size is None:
        size = _SIZES[cls.id] = int(cls.unpacker.size)
    return size


class Oracle:
    """The codec layer on each input alone: how many frames it is good and bad for, and whether it carries
    a measurement the gateway would use that is farther than the bounds from the truth."""

    def __init__(self, fuzzer: Fuzzer) -> None:
        self.frame = fuzzer.frame
        self.thrusters = fuzzer.thrusters
        self.expect = {s: Expect() for s in SOURCES}
        # MAVLink is a stream: a frame cut short at the end of one input waits for the next one's bytes, so
        # the count to expect comes from one parser fed every input in turn (NMEA inputs end their line)
        self._stream = mv.FrameParser()
        self._stream_rejected = 0

    def judge(self, source: str, data: bytes) -> tuple[int, int, bool]:
        """(good, bad, outlier)."""
        if source == "thr":
            parser = mv.FrameParser()
            msgs = parser.feed(data) + parser.flush()
            outlier = any(
                isinstance(r, mv.ThrusterReport) and r.thruster_id in self.thrusters
                for m in msgs
                for r in mv.reports(m)
            )
            return len(msgs), sum(parser.rejected.values()), outlier
        framer = NmeaFramer()
        good = bad = 0
        outlier = False
        for frame in framer.feed(data) + framer.flush():
            if frame.text is None:
                bad += 1
                continue
            s = nmea_codec.decode(frame.text, only=USED_NMEA)
            if isinstance(s, nmea_codec.Reject):
                bad += 1
                continue
            good += 1
            outlier |= self._far(source, s)
        return good, bad, outlier

    def _far(self, source: str, s: Any) -> bool:
        if source == "gps" and isinstance(s, nmea_codec.Gga | nmea_codec.Gns):
            if not s.valid or s.lat_deg is None or s.lon_deg is None:
                return False
            n, e, _ = self.frame.to_ned(s.lat_deg, s.lon_deg, 0.0)
            return not math.hypot(n, e) <= BOUND_M
        if source == "gyro" and isinstance(s, nmea_codec.Heading) and s.valid and s.heading_rad is not None:
            diff = (math.degrees(s.heading_rad) - HEADING_DEG + 180.0) % 360.0 - 180.0
            return not abs(diff) <= BOUND_DEG
        return False

    def count(self, source: str, good: int, bad: int, data: bytes = b"") -> None:
        e = self.expect[source]
        if source == "thr":
            good = len(self._stream.feed(data))
            total = sum(self._stream.rejected.values())
            bad, self._stream_rejected = total - self._stream_rejected, total
        e.received += good
        e.rejected += bad


def rss_kib() -> int:
    """Resident set size now (KiB), from /proc; the peak from getrusage where /proc is missing."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


@dataclass
class Errors:
    position_m: float = 0.0
    heading_deg: float = 0.0

    def see(self, outputs: list[Any], frame: LocalFrame) -> None:
        for o in outputs:
            if o.topic != "/dp/estimate":
                continue
            eta = o.payload["eta"]
            self.position_m = max(self.position_m, math.hypot(eta[0], eta[1]))
            diff = (math.degrees(eta[2]) - HEADING_DEG + 180.0) % 360.0 - 180.0
            self.heading_deg = max(self.heading_deg, abs(diff))
            if not (math.isfinite(eta[0]) and math.isfinite(eta[1])):
                self.position_m = math.inf


def _integrity_reason(reason: str) -> bool:
    return reason.startswith("test_") or reason == "out_of_range"


def run(
    inputs: int, seed: int, warmup_s: float = 60.0, per_tick: int = 100, with_outliers: bool = False
) -> dict[str, Any]:
    """Feed ``inputs`` fuzzed inputs, ``per_tick`` between consecutive clean ticks, after ``warmup_s`` of
    the clean stream alone; then the set-aside outliers in a pipeline of their own. ``with_outliers``:
    the well-formed outliers stay in the stream too (the reference tests must keep them out of the
    estimate). Returns the figures."""
    fuzzer = Fuzzer(seed)
    oracle = Oracle(fuzzer)
    tally = Tally()
    p = pipeline()
    frame = fuzzer.frame
    tick_ns = int(NS / RATE_HZ)
    t0 = int(START.timestamp()) * NS
    k = 0

    def clean(p: Pipeline, k: int) -> list[Any]:
        out = []
        for source, data in clean_tick(k):
            oracle.count(source, 1, 0)
            out += p.feed(RawEvent(t0 + k * tick_ns, source, data))
        return out

    warm_ticks = int(warmup_s * RATE_HZ)
    for k in range(warm_ticks):
        clean(p, k)
    errors = Errors()
    outliers: list[tuple[str, bytes]] = []
    rss_start = 0
    fed = 0
    wall = time.perf_counter()
    fuzz_wall = 0.0
    rss_mark = inputs // 10  # RSS after a tenth of the inputs: caches and per-sender state are warm then
    while fed < inputs:
        k += 1
        errors.see(clean(p, k), frame)
        base = t0 + k * tick_ns
        for j in range(min(per_tick, inputs - fed)):
            source, data, kind = fuzzer.next()
            tally.inputs[kind] += 1
            good, bad, outlier = oracle.judge(source, data)
            if outlier and not with_outliers:
                outliers.append((source, data))
                tally.set_aside[kind] = tally.set_aside.get(kind, 0) + 1
                fed += 1
                continue
            if good == 0 and bad == 0:
                tally.silent += 1
            oracle.count(source, good, bad, data)
            start = time.perf_counter()
            out = p.feed(RawEvent(base + (j + 1) * (tick_ns // (per_tick + 1)), source, data))
            fuzz_wall += time.perf_counter() - start
            errors.see(out, frame)
            fed += 1
            if fed == rss_mark:
                rss_start = rss_kib()
    for _ in range(int(5 * RATE_HZ)):  # the clean stream a little longer: a late effect would show
        k += 1
        errors.see(clean(p, k), frame)
    rss_end = rss_kib()
    total_wall = time.perf_counter() - wall
    status = p.status(t0 + k * tick_ns).payload
    # the codec layer's rejects, to hold against the oracle; the reference monitor's (test_*: a decoded
    # fix or heading that failed a reference test; out_of_range: thruster feedback beyond its rating) are
    # counted apart: they are inputs the codecs passed and the integrity checks refused
    counted = {
        s: {
            "received": v["received"],
            "rejected": sum(n for k, n in v["rejected"].items() if not _integrity_reason(k)),
            "refused_by_integrity": sum(n for k, n in v["rejected"].items() if _integrity_reason(k)),
            "reasons": v["rejected"],
        }
        for s, v in status["sources"].items()
    }
    expected = {s: {"received": e.received, "rejected": e.rejected} for s, e in oracle.expect.items()}
    # the outliers, alone: what the gateway does with well-formed inputs whose values are implausible
    q = pipeline()
    outlier_errors = Errors()
    for k2 in range(warm_ticks):
        for source, data in clean_tick(k2):
            q.feed(RawEvent(t0 + k2 * tick_ns, source, data))
    k2 = warm_ticks
    for i, (source, data) in enumerate(outliers):
        if i % 10 == 0:
            k2 += 1
            for s, d in clean_tick(k2):
                outlier_errors.see(q.feed(RawEvent(t0 + k2 * tick_ns, s, d)), frame)
        outlier_errors.see(q.feed(RawEvent(t0 + k2 * tick_ns + 1000 * (i % 10 + 1), source, data)), frame)
    return {
        "inputs": fed,
        "seed": seed,
        "inputs_by_kind": tally.inputs,
        "main_phase_inputs": fed - len(outliers),
        "inputs_per_s": (fed - len(outliers)) / fuzz_wall if fuzz_wall else math.nan,
        "wall_s": total_wall,
        "max_position_error_m": errors.position_m,
        "max_heading_error_deg": errors.heading_deg,
        "rss_start_kib": rss_start,
        "rss_end_kib": rss_end,
        "rss_growth_kib": rss_end - rss_start,
        "counted": counted,
        "expected": expected,
        "silent_inputs": tally.silent,
        "outliers": {
            "inputs": len(outliers),
            "by_kind": tally.set_aside,
            "max_position_error_m": outlier_errors.position_m,
            "max_heading_error_deg": outlier_errors.heading_deg,
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--with-outliers",
        action="store_true",
        help="keep the well-formed implausible inputs in the stream (the reference tests must refuse them)",
    )
    args = ap.parse_args()
    r = run(args.inputs, args.seed, with_outliers=args.with_outliers)
    r["with_outliers"] = args.with_outliers
    if args.json:
        print(json.dumps(r, indent=1))
        return
    print(f"{r['inputs']:,} fuzzed inputs (seed {r['seed']}) in {r['wall_s']:.0f} s")
    print(f"  the pipeline: {r['inputs_per_s']:,.0f} inputs/s (feed only)")
    print(
        f"  largest estimate error: {r['max_position_error_m']:.3f} m, {r['max_heading_error_deg']:.3f}° "
        f"(bounds: {BOUND_M} m, {BOUND_DEG}° for well-formed fixes in this phase)"
    )
    print(
        f"  RSS growth after warm-up: {r['rss_growth_kib'] / 1024:.2f} MB ({r['rss_end_kib'] / 1024:.0f} MB)"
    )
    for s in SOURCES:
        c, e = r["counted"][s], r["expected"][s]
        print(
            f"  {s}: received {c['received']:,} (codec alone {e['received']:,}), "
            f"rejected {c['rejected']:,} (codec alone {e['rejected']:,}); {c['reasons']}"
        )
    print(
        "  inputs the codec gives no count for (MAVLink noise without a frame marker): "
        f"{r['silent_inputs']:,}"
    )
    o = r["outliers"]
    print(
        f"  set aside, well-formed with implausible values: {o['inputs']:,} {o['by_kind']}: alone, they move "
        f"the estimate {o['max_position_error_m']:.3g} m, {o['max_heading_error_deg']:.3g}°"
    )


if __name__ == "__main__":
    main()
