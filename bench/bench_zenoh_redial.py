"""Benchmark: how long after its router comes a Zenoh client session (``[zenoh] mode = "client"``) has it.

Two cases, each round with a real Zenoh router opened in this process on a loopback port:

* ``first``: the router is not up when the client starts (`gateway.bus.Dialler`, what the gateway does
  when its router is not up yet); the router opens after a random wait (so that it falls anywhere in the
  dial period); measured from the moment the router is ready (its ``zenoh.open`` returned) to the moment
  the dialler hands over a connected session.
* ``first, peer``: a peer session (the default mode) whose router in ``connect`` is not up when it
  opens; Zenoh dials it in the background (the gateway's redial period against Zenoh's default back-off);
  measured from the router ready to the peer listing it among its routers.
* ``restart``: a connected client; the router closes and opens again after a random 0.5-3 s; measured
  from the moment the router is ready to the moment the client lists it among its routers again. Side by side:
  the gateway's redial period (``connect.retry``, `gateway.bus.REDIAL_S`) and Zenoh's default back-off
  (1 s doubling to 4 s), in the same rounds, interleaved.

Beside: how long the router's own ``zenoh.open`` goes on after its port accepts TCP connections (a plain
connect every millisecond from another thread): a dial that comes meanwhile waits for it, so a client is
connected at most a dial period after the router starts listening, and about when it is ready. Median
and maximum over the rounds (negative: connected a moment before ``zenoh.open`` returned in the router).

    python bench/bench_zenoh_redial.py             # 6 rounds, about a minute
    python bench/bench_zenoh_redial.py --rounds 10 --json
"""

from __future__ import annotations

import argparse
import json
import random
import socket
import statistics
import threading
import time
from collections.abc import Callable

import zenoh

from gateway.bus import Dialler, make_config

ZENOH_DEFAULT_RETRY = {"period_init_ms": 1000, "period_max_ms": 4000, "period_increase_factor": 2}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def open_router(endpoint: str) -> tuple[zenoh.Session, float, float]:
    """A router listening on ``endpoint``; with the monotonic times its port first accepted a TCP
    connection (a plain connect every millisecond from another thread) and its ``zenoh.open`` returned."""
    conf = {
        "mode": "router",
        "listen": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}},
    }
    port = int(endpoint.rsplit(":", 1)[1])
    listening: list[float] = []

    def probe() -> None:
        while True:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    listening.append(time.monotonic())
                    return
            time.sleep(0.001)

    prober = threading.Thread(target=probe)
    prober.start()
    router = zenoh.open(zenoh.Config.from_json5(json.dumps(conf)))
    opened = time.monotonic()
    prober.join()
    return router, listening[0], opened


def client_config(endpoint: str, zenoh_default: bool = False, mode: str = "client") -> zenoh.Config:
    config = make_config(mode=mode, connect=[endpoint], multicast_scouting=False)
    if zenoh_default:
        config.insert_json5("connect/retry", json.dumps(ZENOH_DEFAULT_RETRY))
    return config


def wait(predicate: Callable[[], bool], timeout: float = 30.0) -> float:
    """Poll every millisecond; the monotonic time ``predicate`` held."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError("not connected within 30 s")
        time.sleep(0.001)
    return time.monotonic()


def first(rng: random.Random) -> tuple[float, float]:
    """(connected - router ready, ready - listening) for a router that was not up when the client began."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    dialler = Dialler(lambda: client_config(endpoint))
    got: list[zenoh.Session] = []

    def connected() -> bool:
        session = dialler.take()
        if session is not None:
            got.append(session)
        return bool(got)

    try:
        time.sleep(rng.uniform(0.6, 1.6))
        router, t0, t1 = open_router(endpoint)
        try:
            t2 = wait(connected)
        finally:
            for s in got:
                s.close()
            router.close()
    finally:
        dialler.close()
    return t2 - t1, t1 - t0


def first_peer(rng: random.Random, zenoh_default: bool) -> tuple[float, float]:
    """(connected - router ready, ready - listening) for a peer session (``mode = "peer"``, the default)
    whose router in ``connect`` was not up when it opened: Zenoh dials it in the background."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    peer = zenoh.open(client_config(endpoint, zenoh_default, mode="peer"))
    try:
        time.sleep(rng.uniform(0.6, 3.0))
        router, t0, t1 = open_router(endpoint)
        try:
            t2 = wait(lambda: any(True for _ in peer.info.routers_zid()))
        finally:
            router.close()
    finally:
        peer.close()
    return t2 - t1, t1 - t0


def restart(rng: random.Random, zenoh_default: bool) -> tuple[float, float]:
    """(connected again - router ready, ready - listening) for a router that closed and came back."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router, _, _ = open_router(endpoint)
    client = zenoh.open(client_config(endpoint, zenoh_default))
    try:
        router.close()
        wait(lambda: not any(True for _ in client.info.routers_zid()))
        time.sleep(rng.uniform(0.5, 3.0))
        router, t0, t1 = open_router(endpoint)
        t2 = wait(lambda: any(True for _ in client.info.routers_zid()))
    finally:
        client.close()
        router.close()
    return t2 - t1, t1 - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    cases: dict[str, list[tuple[float, float]]] = {
        "first (Dialler)": [],
        "restart (gateway retry)": [],
        "restart (Zenoh default retry)": [],
        "first, peer (gateway retry)": [],
        "first, peer (Zenoh default retry)": [],
    }
    for _ in range(args.rounds):
        cases["first (Dialler)"].append(first(rng))
        cases["restart (gateway retry)"].append(restart(rng, zenoh_default=False))
        cases["restart (Zenoh default retry)"].append(restart(rng, zenoh_default=True))
        cases["first, peer (gateway retry)"].append(first_peer(rng, zenoh_default=False))
        cases["first, peer (Zenoh default retry)"].append(first_peer(rng, zenoh_default=True))
    out = {
        name: {
            "median_s": statistics.median(d for d, _ in v),
            "max_s": max(d for d, _ in v),
            "open_after_listen_median_s": statistics.median(o for _, o in v),
        }
        for name, v in cases.items()
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return
    head = f"{'case':32s} {'after ready: median s':>22s} {'max s':>7s} {'listen->ready s':>16s}"
    print(f"{head}   ({args.rounds} rounds)")
    for name, r in out.items():
        print(f"{name:32s} {r['median_s']:22.3f} {r['max_s']:7.3f} {r['open_after_listen_median_s']:16.3f}")


if __name__ == "__main__":
    main()
