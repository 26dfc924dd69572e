"""Benchmark: what recording the signing verdicts costs on the live path of a signed MAVLink link.

The gateway logs a record for each frame it refuses for its signature (`/raw/mavlink_rejected/<source>`),
so that a replay without the key refuses the same frames; an accepted frame must cost nothing more than
before. This times, per frame, on a link signed with a key (as `gateway.pipeline` builds it):

- ``parser accepted``: `FrameParser.feed` of one genuine signed AZIMUTH_THRUSTER_STATUS frame per chunk
  (a UDP datagram), signature checked;
- ``pipeline accepted``: `Pipeline.feed` of the same chunk on a signed thruster source: parse, check,
  decode, the report into the fusion, the feedback output;
- ``pipeline refused``: `Pipeline.feed` of a forged frame (another key): counted, and (where the tree
  records verdicts) its record made.

Run it in two trees to compare them (it uses only what both have):

    PYTHONPATH=. python bench/bench_signing_verdicts.py [--frames 3000] [--rounds 7] [--json]

Each round builds a fresh parser or pipeline (a signed stream's timestamps must grow) and feeds every
frame once; the best round is reported (the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

from gateway.config import parse_config
from gateway.config.defaults import default_config
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from wire.codecs import mavlink as mv

KEY = bytes(range(100, 132))
WRONG_KEY = bytes(range(32))


def _parser() -> mv.FrameParser:
    rx = mv.encoder(255, 190)
    mv.setup_signing(rx, KEY, sign_outgoing=False, allow_unsigned=False)
    try:  # (a tree that records verdicts: as the pipeline builds it)
        return mv.FrameParser(rx, keep_signing_rejects=True)  # type: ignore[call-arg]
    except TypeError:
        return mv.FrameParser(rx)


def _pipeline() -> Pipeline:
    tables = default_config("hajivand_vessel")
    tables["datum"] = {"lat_deg": 59.4, "lon_deg": 10.5}
    tables["sources"] = [
        {"name": "nav", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]},
        {"name": "thr", "url": "udp://127.0.0.1:0", "protocol": "mavlink", "roles": ["thrusters"],
         "signing_key": KEY.hex(), "system_id": 1, "component_id": 1},
    ]  # fmt: skip
    tables["log"] = {"path": ""}
    return Pipeline(PipelineSpec.from_config(parse_config(tables, base_dir=Path.cwd(), where="bench")))


def _frames(n: int, key: bytes) -> list[bytes]:
    drive = mv.encoder(1, 1)
    mv.setup_signing(drive, key, initial_timestamp=mv.signing_timestamp(time.time()))
    return [mv.azimuth_status_frame(drive, 1000 * k, 1 + k % 3, 1e4 + k, 100.0, 0.1, 0) for k in range(n)]


def _per_frame(rounds: int, make: Callable[[], Callable[[bytes, int], object]], frames: list[bytes]) -> float:
    best = math.inf
    t0_ns = time.time_ns()
    for _ in range(rounds):
        feed = make()
        t0 = time.perf_counter()
        for k, frame in enumerate(frames):
            feed(frame, t0_ns + k * 100_000_000)
        best = min(best, time.perf_counter() - t0)
    return best / len(frames)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    genuine, forged = _frames(args.frames, KEY), _frames(args.frames, WRONG_KEY)

    def parser_feed() -> Callable[[bytes, int], object]:
        p = _parser()
        return lambda frame, _ns: p.feed(frame)

    def pipeline_feed() -> Callable[[bytes, int], object]:
        p = _pipeline()
        return lambda frame, ns: p.feed(RawEvent(ns, "thr", frame, peer="127.0.0.1:14555"))

    out = {
        "parser accepted": _per_frame(args.rounds, parser_feed, genuine),
        "pipeline accepted": _per_frame(args.rounds, pipeline_feed, genuine),
        "pipeline refused": _per_frame(args.rounds, pipeline_feed, forged),
    }
    check = _pipeline()
    for k, frame in enumerate(forged[:10]):
        outputs = check.feed(RawEvent(time.time_ns() + k, "thr", frame, peer="127.0.0.1:14555"))
    records = sum(o.topic.startswith("/raw/mavlink_rejected/") for o in outputs)
    if args.json:
        print(json.dumps({k: v * 1e6 for k, v in out.items()} | {"records_per_refused_frame": records}))
        return
    for what, s in out.items():
        print(f"{what:>20}: {s * 1e6:7.2f} µs/frame")
    print(f"{'records':>20}: {records} per refused frame")


if __name__ == "__main__":
    main()
