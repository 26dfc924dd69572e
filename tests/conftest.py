"""Shared test set-up."""

from __future__ import annotations

import os

# Tests run the simulator and the gateway as `dpgw` runs them: one BLAS thread (dpgw.cli.single_threaded_blas:
# OpenBLAS's extra threads only spin-wait on matrices this small, taking the second core from the test's
# other process). Set before numpy loads; a value given by whoever runs the tests stays.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import math  # noqa: E402
import socket  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, TypeVar  # noqa: E402

import pynmea2  # noqa: E402
import pytest  # noqa: E402
from alone_lock import pytest_runtest_protocol  # noqa: E402, F401  (the ``alone`` marker's hook)

T = TypeVar("T")

if "THS" not in pynmea2.TalkerSentence.sentence_types:
    # pynmea2 1.19 has no THS; registering a layout is pynmea2's own extension mechanism (the checksum and
    # field splitting stay pynmea2's), so THS is still checked by an independent parser.
    class THS(pynmea2.TalkerSentence):
        fields = (("Heading, degrees true", "heading", float), ("Mode indicator", "mode"))


def wait_for(predicate: Callable[[], T], timeout: float = 30.0, interval: float = 0.02) -> T:
    """Poll `predicate` until it returns something truthy, or `timeout` seconds pass; return its last value.

    Tests wait for the event that matters, never for a fixed time: on a loaded machine a fixed sleep is
    too short, on an idle one too long. The timeout is generous because it costs nothing when the event
    comes; use it as ``assert wait_for(lambda: ..., 10.0), "what did not happen"``."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() >= deadline:
            return value
        time.sleep(interval)


def connect_when_listening(port: int, timeout: float = 30.0, alive: Callable[[], bool] | None = None) -> Any:
    """A Zenoh client session to a process that listens on 127.0.0.1:``port`` once it has started: retried
    (the process may still be importing) until it connects, ``timeout`` passes, or ``alive()`` says the
    process has ended. Fails the test with what did not happen."""
    from gateway.bus import isolated_config, open_session

    deadline = time.monotonic() + timeout
    while True:
        try:
            return open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
        except Exception as exc:  # zenoh raises a plain ZError while nobody listens yet
            if time.monotonic() >= deadline or (alive is not None and not alive()):
                raise AssertionError(f"no Zenoh peer listening on 127.0.0.1:{port}: {exc}") from exc
            time.sleep(0.1)


@pytest.fixture
def loopback_sessions() -> Iterator[tuple[int, Any, Any]]:
    """(port, server, client): two Zenoh sessions joined on 127.0.0.1:port, one listening (the gateway's
    side: start a sink on it) and one connecting (a consumer's); closed after the test."""
    from gateway.bus import isolated_config, open_session

    port = free_port()
    server = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{port}"]))
    client = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{port}"]))
    try:
        yield port, server, client
    finally:
        client.close()
        server.close()


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port on 127.0.0.1 that was free a moment ago (TCP by default; ``socket.SOCK_DGRAM`` for UDP)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def one_source_config(
    tmp: Path, url: str, name: str = "dgps1", *, datum: bool = False, log: bool = True
) -> Path:
    """``tmp/vessel.toml`` for ``dpgw run``: mss_supply, one NMEA source of position and heading at
    ``url``, Zenoh on a free loopback port without scouting, the log in ``tmp/live.mcap`` (``log=False``:
    none); ``datum``: a datum of its own (59.4 N, 10.5 E)."""
    cfg = tmp / "vessel.toml"
    datum_table = "[datum]\nlat_deg = 59.4\nlon_deg = 10.5\n" if datum else ""
    cfg.write_text(f"""
[vessel]
name = "mss_supply"
{datum_table}[[sources]]
name = "{name}"
url = "{url}"
protocol = "nmea"
roles = ["position", "heading"]
[zenoh]
listen = ["tcp/127.0.0.1:{free_port()}"]
multicast_scouting = false
[log]
path = "{tmp / "live.mcap" if log else ""}"
""")
    return cfg


class Recorder:
    """An output sink that keeps what the pipeline handed the sinks, to compare an output's messages with
    (a second sink beside the one under test)."""

    name = "recorder"

    def __init__(self) -> None:
        self.outputs: list[Any] = []
        self.lock = threading.Lock()

    def start(self, session: Any) -> None:
        pass

    def emit(self, outputs: list[Any], encoded: list[bytes]) -> None:
        with self.lock:
            self.outputs.extend(outputs)

    def close(self) -> None:
        pass

    def of(self, kind: type, topic: str | None = None) -> list[Any]:
        """The messages of type ``kind`` (on ``topic``, or on any)."""
        with self.lock:
            return [o.message for o in self.outputs if type(o.message) is kind and topic in (None, o.topic)]


def nmea_line(body: str) -> str:
    """``$<body>*HH`` with its checksum (no line end): a sentence from its text between ``$`` and ``*``."""
    from wire.codecs.nmea_encode import checksum

    return f"${body}*{checksum(body)}"


QUICK_SETTLING_OBSERVER = {"wave_period_s": 9.0, "bias_time_constant_s": 5.0, "allow_unchecked": True}
"""A passive observer whose settle time is seconds of fed data, not minutes (bias time constant 5 s): for
the tests of what the outputs say while the estimate settles."""


def settling_bench(tables: dict[str, Any], tmp_path: Path) -> tuple[Any, Any, Any, float]:
    """(config, pipeline, the first output sink the config makes, the observer's settle time in s) of a
    gateway config with `QUICK_SETTLING_OBSERVER`."""
    from gateway.config import parse_config
    from gateway.outputs.build import sinks_from_config
    from gateway.pipeline import Pipeline, PipelineSpec

    config = parse_config({**tables, "observer": dict(QUICK_SETTLING_OBSERVER)}, base_dir=tmp_path)
    spec = PipelineSpec.from_config(config)
    settle_s = float(spec.observer.settle_time_s)
    assert 5.0 < settle_s < 30.0
    return config, Pipeline(spec), sinks_from_config(config)[0], settle_s


def gga_hdt_chunk(k: int, lat_deg: float, lon_deg: float) -> bytes:
    """The k-th tenth of a second of a DGPS with a gyro, a vessel on station near (``lat_deg``,
    ``lon_deg``) heading about 30°: GGA and HDT with small slow wiggles."""
    from datetime import UTC, datetime

    from wire.codecs import nmea_encode as enc

    t = datetime.now(UTC)
    gga = enc.gga("GP", t, lat_deg + 2e-6 * math.sin(k / 50), lon_deg, 2, 12, 0.8, 20.0, 35.5)
    return (gga + enc.hdt("HE", 30.0 + 0.02 * math.sin(k / 30))).encode()


def run_demo_beside(
    args: Any, operator: Callable[[], None] | None = None, release: Callable[[], None] | None = None
) -> int:
    """``dpgw demo`` (`dpgw.cli_demo.run` of the parsed ``args``) in this process, with ``operator`` in a
    thread beside it (what a person or a tool does meanwhile). Afterwards the SIGINT and SIGTERM handlers
    the demo installs are put back, ``release`` is called (what lets the operator finish), and the
    operator's thread is joined. Returns the demo's exit status."""
    import signal

    from dpgw import cli_demo

    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    thread = threading.Thread(target=operator, name="operator", daemon=True) if operator else None
    if thread is not None:
        thread.start()
    try:
        return cli_demo.run(args)
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
        if release is not None:
            release()
        if thread is not None:
            thread.join(30)


def simulator_log(path: Path, scenario: str, seed: int, seconds: float) -> Path:
    """``path``: an MCAP log of the simulator running ``scenario`` with ``seed`` for ``seconds`` (its
    inputs, its truth, and the metadata that names the scenario), as `dpgw sim --out` writes one."""
    from simulator.runner import Simulation
    from simulator.scenarios import get_scenario
    from wire.mcap.writer import McapLogWriter

    with McapLogWriter(path) as w:
        Simulation(get_scenario(scenario), seed=seed, log=w).run(seconds)
    return path


def stop_service(service: Any, loop: threading.Thread) -> None:
    """Stop a `GatewayService` whose loop runs in ``loop``, as `dpgw run` does at its end: the loop ends,
    what is left is handled and logged (`drain`), and everything is closed."""
    service.stop_event.set()
    loop.join(timeout=30)
    service.drain()
    service.close()
