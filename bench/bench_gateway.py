"""Benchmark: the live gateway's latency, CPU and memory.

The gateway is a real ``dpgw run`` subprocess: a UDP NMEA source, Zenoh listening on an isolated loopback
endpoint, MCAP logging on with the defaults (zstd, 1 s flush, fsync). This process is both the sensor and
the consumer: it writes NMEA datagrams to the gateway's UDP port and subscribes to ``<prefix>/estimate``
over Zenoh, from another process, as a DP controller would.

1. **Latency**, datagram written -> estimate received by the Zenoh subscriber, at each input rate
   (``--rates``, default 10 and 50 Hz). One datagram per cycle, each giving one observer step and one
   estimate: at 10 Hz every datagram is GGA+HDT; above ``--gga-hz`` (10) every datagram carries HDT and
   every (rate/10)-th also GGA: a 50 Hz gyro with a 10 Hz DGPS. Both ends read ``time.time_ns()`` (one
   clock). Pairing: an estimate's ``stamp_ns`` is the gateway's receive time of its datagram, so it lies
   between that datagram's send time and the next one's; the datagram is the last one sent at or before
   ``stamp_ns``. A lost datagram gives no estimate and takes no other's place (counted as lost). The first
   ``--warmup`` seconds are discarded. Target p99 <= 2 ms. Also shown: the split at the gateway's receive
   stamp, and the floor: the same path without the gateway's work (a Python helper process with a UDP
   reader thread, a queue and a consumer thread publishing an estimate-sized JSON on Zenoh), measured the
   same way for a third as long.
2. **CPU** of the gateway process over the measured window: (utime + stime) / wall time from
   ``/proc/<pid>/stat``, all threads, in % of one core. Target <= 5 % at 10 Hz. The CPU used meanwhile by
   every other process on the machine is reported too: the tails depend on it.
3. **Memory** over ``--hours`` (1) of 10 Hz data, 36,000 GGA+HDT cycles, in a fresh gateway, sent at
   ``--speedup`` (200) times real time (an hour in 18 s; 0: as fast as it takes them), at most ``--window``
   estimates outstanding; RSS from ``/proc/<pid>/statm`` every minute of data: at start, middle, end, and
   the least-squares slope in MB per hour of data from the start. The start is after 3 minutes of data and
   after the first 6 s of wall time: the gateway keeps 5 s of receive time of headings, 50 entries at a
   real 10 Hz gyro but 5 s x the feed rate here (10,000 at 200x), and RSS rises while that fills. The
   gateway stamps receive time, so its log sees seconds, not an hour: the MCAP writer then closes a chunk
   per 256 KiB rather than one a second. So the same work also runs in this process
   under ``tracemalloc`` with sim-time stamps (one chunk a second, as on a vessel): the Python heap at
   start/middle/end, its slope, and the source lines whose allocations grew.
4. **Where the time goes**: the gateway consumer's work per datagram, as ``GatewayService._handle`` does it
   minus the Zenoh put, timed in this process on the same config, one datagram per period at each rate
   (as cold as in the gateway: caches and CPU clocks cool down between datagrams) and back to back.

    python bench/bench_gateway.py                    # about 3 minutes
    python bench/bench_gateway.py --quick            # about a minute: a smoke check
    python bench/bench_gateway.py --rates 10 50 --seconds 30 --hours 1 --json

Linux only (``/proc``). Cleans up after itself, also on Ctrl-C or SIGTERM: the gateway and helper get
SIGTERM (SIGKILL after 15 s), sockets and sessions are closed, the temporary folder (configs, MCAP logs)
is removed. Results in docs/performance.md.
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import json
import math
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from types import FrameType
from typing import IO, Any

import numpy as np

from gateway.bus import isolated_config, open_session
from gateway.config import load_config
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from wire.codecs import nmea_encode as enc
from wire.json_payload import encode_json
from wire.mcap.writer import McapLogWriter

REPO = Path(__file__).resolve().parents[1]
PREFIX = "dp/bench"
SOURCE = "mux"
LAT0, LON0 = 59.4, 10.5
M_PER_DEG_LAT = 111_320.0
CLK_TCK = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")
LATENCY_TARGET_MS = 2.0
CPU_TARGET_PCT = 5.0
MEMORY_RATE_HZ = 10.0
T_SIM0 = datetime(2026, 1, 1, tzinfo=UTC)


def progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


# --- the sensor: one datagram per cycle ---------------------------------------------------------------------


def datagram(k: int, rate_hz: float, gga_every: int, t_utc: datetime) -> bytes:
    """Cycle `k`: HDT, plus GGA on every `gga_every`-th cycle; a vessel swaying ±2 m and yawing ±2°."""
    t = k / rate_hz
    heading = math.radians(30.0 + 2.0 * math.sin(2 * math.pi * t / 45.0))
    text = ""
    if k % gga_every == 0:
        north = 2.0 * math.sin(2 * math.pi * t / 60.0)
        east = 1.5 * math.cos(2 * math.pi * t / 80.0)
        lat = LAT0 + north / M_PER_DEG_LAT
        lon = LON0 + east / (M_PER_DEG_LAT * math.cos(math.radians(LAT0)))
        text = enc.gga("GP", t_utc, lat, lon, 2, 12, 0.8, 20.0)
    return (text + enc.hdt("HE", heading)).encode()


def describe_input(rate_hz: float, gga_every: int) -> str:
    if gga_every == 1:
        return f"one datagram per cycle at {rate_hz:g} Hz, each GGA+HDT"
    return (
        f"one datagram per cycle at {rate_hz:g} Hz: HDT in every one, GGA in every {gga_every}th "
        f"(GGA at {rate_hz / gga_every:g} Hz)"
    )


def config_text(udp_port: int, zenoh_port: int | None, log_path: Path | None) -> str:
    zenoh = (
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{zenoh_port}"]\nmulticast_scouting = false\nprefix = "{PREFIX}"\n'
        if zenoh_port is not None
        else ""
    )
    return f"""
[vessel]
name = "mss_supply"
[datum]
lat_deg = {LAT0}
lon_deg = {LON0}
[[sources]]
name = "{SOURCE}"
url = "udp://127.0.0.1:{udp_port}"
protocol = "nmea"
roles = ["position", "heading"]
[observer]
wave_period_s = 9.0
{zenoh}[log]
path = "{log_path or ""}"
"""


# --- /proc --------------------------------------------------------------------------------------------------


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def cpu_seconds(pid: int | str) -> float:
    """utime + stime of every thread of `pid` (s)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14 and 15 of proc(5)


def machine_busy_seconds() -> float:
    """CPU seconds all cores spent not idle since boot (/proc/stat: all but idle and iowait)."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:8]]
    return (sum(v) - v[3] - v[4]) / CLK_TCK


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/statm") as f:
        return int(f.read().split()[1]) * PAGE / 1e6


@dataclass
class CpuWindow:
    """CPU of the gateway, of this process and of everything else over a stretch of wall time."""

    pid: int
    t0: float = 0.0
    gw0: float = 0.0
    me0: float = 0.0
    all0: float = 0.0

    def start(self) -> None:
        self.t0, self.gw0 = time.monotonic(), cpu_seconds(self.pid)
        self.me0, self.all0 = cpu_seconds("self"), machine_busy_seconds()

    def stop(self) -> dict[str, float]:
        wall = time.monotonic() - self.t0
        gw = cpu_seconds(self.pid) - self.gw0
        me = cpu_seconds("self") - self.me0
        other = machine_busy_seconds() - self.all0 - gw - me
        return {
            "gateway_pct": 100 * gw / wall,
            "bench_pct": 100 * me / wall,
            "other_processes_pct": max(0.0, 100 * other / wall),
            "window_s": wall,
        }


# --- the processes under test -------------------------------------------------------------------------------


def _stop_process(proc: subprocess.Popen[Any]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@dataclass
class Receiver:
    """Samples as they arrive: (receive time ns, payload bytes). List appends are atomic."""

    got: list[tuple[int, bytes]] = field(default_factory=list)

    def __call__(self, sample: Any) -> None:
        self.got.append((time.time_ns(), sample.payload.to_bytes()))  # the clock first


class Child:
    """A process that reads NMEA datagrams on a UDP port and publishes JSON with ``stamp_ns`` (its receive
    time) on a Zenoh key, listening on loopback; this process's UDP socket to it and Zenoh subscriber."""

    what = "child"

    def __init__(self, folder: Path, name: str, argv: list[str], key: str, udp_port: int, zenoh_port: int):
        self.udp_port, self.zenoh_port, self.key = udp_port, zenoh_port, key
        self._out: IO[str] = open(folder / f"{name}.stdout", "w+")  # noqa: SIM115 - closed in stop()
        self._err: IO[str] = open(folder / f"{name}.stderr", "w+")  # noqa: SIM115
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # not connected: no ICMP errors
        self.addr = ("127.0.0.1", udp_port)
        self.proc = subprocess.Popen(
            argv, stdout=self._out, stderr=self._err, stdin=subprocess.DEVNULL, cwd=REPO
        )
        self.pid = self.proc.pid
        self.receiver = Receiver()
        self.session: Any = None
        self._sub: Any = None
        self.stdout = ""

    def connect(self, timeout_s: float = 30.0) -> None:
        deadline = time.monotonic() + timeout_s
        while self.session is None:
            self.check_alive()
            try:
                self.session = open_session(isolated_config(connect=[f"tcp/127.0.0.1:{self.zenoh_port}"]))
            except Exception:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"could not connect to tcp/127.0.0.1:{self.zenoh_port}") from None
                time.sleep(0.2)
        self._sub = self.session.declare_subscriber(self.key, self.receiver)

    def check_alive(self) -> None:
        if self.proc.poll() is not None:
            self._err.seek(0)
            raise RuntimeError(f"{self.what} exited with {self.proc.returncode}:\n{self._err.read()[-4000:]}")

    def send(self, data: bytes) -> int:
        t = time.time_ns()
        self.sock.sendto(data, self.addr)
        return t

    def prime(self, rate_hz: float, gga_every: int, timeout_s: float = 30.0) -> None:
        """Send at the rate until answers come back over Zenoh (the subscription is up end to end)."""
        deadline = time.monotonic() + timeout_s
        k = 0
        while len(self.receiver.got) < 3:
            self.check_alive()
            if time.monotonic() > deadline:
                raise RuntimeError(f"nothing came back from the {self.what}")
            self.send(datagram(k, rate_hz, gga_every, datetime.now(UTC)))
            k += 1
            time.sleep(1.0 / rate_hz)

    def stop(self) -> None:
        """Close our end; SIGTERM the process (the gateway closes its log), SIGKILL after 15 s."""
        if self._sub is not None:
            with contextlib.suppress(Exception):
                self._sub.undeclare()
            self._sub = None
        if self.session is not None:
            with contextlib.suppress(Exception):
                self.session.close()
            self.session = None
        self.sock.close()
        _stop_process(self.proc)
        self._out.seek(0)
        self.stdout = self._out.read()
        self._out.close()
        self._err.close()


class Gateway(Child):
    """``dpgw run`` with a UDP source, Zenoh on loopback and an MCAP log (unless ``log=False``)."""

    what = "dpgw run"

    def __init__(self, folder: Path, name: str, *, log: bool = True, fifo: int | None = None) -> None:
        udp, zport = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
        config = folder / f"{name}.toml"
        config.write_text(config_text(udp, zport, folder / f"{name}.mcap" if log else None))
        argv = [*_chrt(fifo), sys.executable, "-m", "dpgw", "run", "--config", str(config), "--json"]
        super().__init__(folder, name, argv, f"{PREFIX}/estimate", udp, zport)

    def rejected(self) -> dict[str, int]:
        try:
            summary = json.loads(self.stdout)
        except ValueError:
            return {}
        return dict(summary.get("status", {}).get("sources", {}).get(SOURCE, {}).get("rejected", {}))


_SKELETON = """
import json, queue, signal, socket, sys, threading, time
signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the benchmark stops this helper
from gateway.bus import isolated_config, open_session
session = open_session(isolated_config(listen=[f"tcp/127.0.0.1:{sys.argv[2]}"]))
pub = session.declare_publisher("bench/skeleton", encoding="application/json")
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
sock.bind(("127.0.0.1", int(sys.argv[1])))
sock.settimeout(0.2)
q = queue.Queue()
body = {"observer": "passive", "status": "ok", "eta": [1.0] * 3, "nu": [0.1] * 3, "bias": [1e4] * 3,
        "eta_wf": [0.1] * 3, "omega0": [0.7] * 3, "lat_deg": 59.4, "lon_deg": 10.5, "heading_deg": 30.0,
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5}}
def read():
    while True:
        try:
            data, _ = sock.recvfrom(65536)
        except TimeoutError:
            continue
        q.put((time.time_ns(), data))
threading.Thread(target=read, daemon=True).start()
while True:
    try:
        rx, data = q.get(timeout=0.05)
    except queue.Empty:
        continue
    pub.put(json.dumps({"stamp_ns": rx, **body}))
"""


class Skeleton(Child):
    """The gateway's path without its work: a UDP reader thread, a queue, a consumer thread that publishes a
    JSON estimate-sized message on Zenoh. The floor the gateway's latency stands on."""

    what = "skeleton helper"

    def __init__(self, folder: Path, name: str, *, fifo: int | None = None) -> None:
        udp, zport = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
        argv = [*_chrt(fifo), sys.executable, "-c", _SKELETON, str(udp), str(zport)]
        super().__init__(folder, name, argv, "bench/skeleton", udp, zport)


def _chrt(fifo: int | None) -> list[str]:
    return [] if fifo is None else ["chrt", "--fifo", str(fifo)]


@contextlib.contextmanager
def fifo_scheduling(priority: int | None) -> Iterator[None]:
    """SCHED_FIFO at `priority` for this process (and the threads it starts meanwhile), then back."""
    if priority is None:
        yield
        return
    before = os.sched_getscheduler(0), os.sched_getparam(0)
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    try:
        yield
    finally:
        os.sched_setscheduler(0, before[0], before[1])


@contextlib.contextmanager
def running(child: Child) -> Iterator[Child]:
    try:
        child.connect()
        yield child
    finally:
        child.stop()


# --- 1 and 2: latency and CPU at a rate ---------------------------------------------------------------------


def quantiles(values_ns: list[int]) -> dict[str, float]:
    a = np.asarray(values_ns, dtype=float) / 1e6
    if a.size == 0:
        return {}
    p50, p90, p99 = np.percentile(a, [50, 90, 99])
    return {"p50_ms": p50, "p90_ms": p90, "p99_ms": p99, "max_ms": a.max(), "mean_ms": a.mean(), "n": a.size}


def latency_run(
    child: Child, rate_hz: float, gga_hz: float, warmup_s: float, seconds: float
) -> dict[str, Any]:
    """Paced datagrams to `child`, answers paired with them; latency and the child's CPU."""
    gga_every = max(1, round(rate_hz / gga_hz))
    period = 1.0 / rate_hz
    n_warm = round(warmup_s * rate_hz)
    n = n_warm + round(seconds * rate_hz)
    sends = [0] * n
    with running(child):
        child.prime(rate_hz, gga_every)
        got = child.receiver.got
        start = len(got)
        cpu = CpuWindow(child.pid)
        t_next = time.monotonic()
        for k in range(n):
            if k == n_warm:
                cpu.start()
            data = datagram(k, rate_hz, gga_every, datetime.now(UTC) + timedelta(seconds=period))
            delay = t_next - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            sends[k] = child.send(data)
            t_next += period
            if k % round(rate_hz) == 0:
                child.check_alive()
        child.check_alive()
        load = cpu.stop()
        rss = rss_mb(child.pid)
        time.sleep(0.5)  # stragglers
        arrivals = got[start:]
    # pairing: an answer came from the last datagram sent at or before its receive stamp
    by_k: dict[int, tuple[int, int]] = {}
    duplicates = 0
    for recv_ns, body in arrivals:
        stamp = int(json.loads(body)["stamp_ns"])
        k = bisect.bisect_right(sends, stamp) - 1
        if k < 0:
            continue  # from the priming cycles
        if k in by_k:
            duplicates += 1
            continue
        by_k[k] = (stamp, recv_ns)
    measured = [k for k in range(n_warm, n) if k in by_k]
    to_stamp = [by_k[k][0] - sends[k] for k in measured]
    return {
        "rate_hz": rate_hz,
        "input": describe_input(rate_hz, gga_every),
        "warmup_s": warmup_s,
        "seconds": seconds,
        "sent": n - n_warm,
        "paired": len(measured),
        "lost": n - n_warm - len(measured),
        "duplicates": duplicates,
        "latency": quantiles([by_k[k][1] - sends[k] for k in measured]),
        "latency_gga_cycles": (
            quantiles([by_k[k][1] - sends[k] for k in measured if k % gga_every == 0])
            if gga_every > 1
            else None
        ),
        "send_to_receive_stamp": quantiles(to_stamp),
        "receive_stamp_to_subscriber": quantiles([by_k[k][1] - by_k[k][0] for k in measured]),
        "max_send_to_stamp_in_periods": max(to_stamp) / 1e9 / period if to_stamp else None,
        "cpu": load,
        "rss_mb": rss,
        "_samples": [(k, sends[k], *by_k[k]) for k in measured],  # dropped from the output
    }


def gateway_latency(
    folder: Path,
    rate_hz: float,
    gga_hz: float,
    warmup_s: float,
    seconds: float,
    *,
    log: bool = True,
    fifo: int | None = None,
) -> dict[str, Any]:
    gw = Gateway(folder, f"latency_{rate_hz:g}hz", log=log, fifo=fifo)
    with fifo_scheduling(fifo):
        r = latency_run(gw, rate_hz, gga_hz, warmup_s, seconds)
    return {**r, "mcap_log": log, "sched_fifo": fifo, "rejected": gw.rejected()}


# --- 3: memory over an hour of data -------------------------------------------------------------------------


def memory_run(folder: Path, hours: float, window: int, speedup: float = 0.0) -> dict[str, Any]:
    """RSS of a fresh gateway fed `hours` of 10 Hz GGA+HDT, `speedup` times faster than real time or, if
    0, as fast as it takes them (at most `window` estimates outstanding either way)."""
    n = round(hours * 3600 * MEMORY_RATE_HZ)
    every = 600  # one RSS sample per minute of data
    samples: list[tuple[float, float, float]] = []  # (hours of data, wall s, RSS MB)
    gw = Gateway(folder, "memory")
    with running(gw):
        gw.prime(MEMORY_RATE_HZ, 1)
        got = gw.receiver.got
        time.sleep(1.0)
        rss_idle = rss_mb(gw.pid)
        base = len(got)
        deficit = 0  # estimates that never came (a lost datagram): not waited for
        stalls = 0
        cpu = CpuWindow(gw.pid)
        cpu.start()
        wall0 = time.monotonic()
        for k in range(n):
            if speedup:
                delay = wall0 + k / MEMORY_RATE_HZ / speedup - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if k % every == 0:
                samples.append((k / MEMORY_RATE_HZ / 3600, time.monotonic() - wall0, rss_mb(gw.pid)))
                gw.check_alive()
            last, since = len(got), time.monotonic()
            while k - (len(got) - base) - deficit > window:
                time.sleep(0.0002)
                c = len(got)
                if c != last:
                    last, since = c, time.monotonic()
                elif time.monotonic() - since > 0.5:
                    deficit = k - (c - base) - window // 2
                    stalls += 1
            gw.send(datagram(k, MEMORY_RATE_HZ, 1, T_SIM0 + timedelta(seconds=k / MEMORY_RATE_HZ)))
        deadline = time.monotonic() + 10
        while len(got) - base + deficit < n and time.monotonic() < deadline:
            time.sleep(0.01)
        wall = time.monotonic() - wall0
        gw.check_alive()
        load = cpu.stop()
        samples.append((n / MEMORY_RATE_HZ / 3600, wall, rss_mb(gw.pid)))
        received = len(got) - base
        time.sleep(2.0)
        rss_after = rss_mb(gw.pid)
    h = np.array([s[0] for s in samples])
    r = np.array([s[2] for s in samples])
    # The gateway keeps 5 s (receive time) of headings (gateway/fusion.py, HEADING_HISTORY_NS) to pair fixes
    # with headings: 50 entries at a real 10 Hz gyro, 5 s x the feed rate here. Start after it has filled.
    fill_h = 6.0 * speedup / 3600 if speedup else 0.0
    trend = _trend(h, r, max(0.05 * hours, min(0.5 * hours, fill_h)))
    return {
        "hours_of_data": hours,
        "cycles": n,
        "input": "GGA+HDT, one datagram per cycle, 10 Hz sim time, flow-controlled",
        "speedup": speedup,
        "heading_history_entries": round(5.0 * n / wall),
        "wall_s": wall,
        "cycles_per_s": n / wall,
        "times_real_time": n / MEMORY_RATE_HZ / wall,
        "estimates_received": received,
        "stalls": stalls,
        "cpu_ms_per_cycle": 1e3 * load["gateway_pct"] / 100 * wall / n,
        "rss_idle_mb": rss_idle,
        **{f"rss_{key}": v for key, v in trend.items()},
        "rss_2s_after_end_mb": rss_after,
        "log_mb": sum(p.stat().st_size for p in folder.glob("memory*.mcap")) / 1e6,
        "samples_h_wall_s_rss_mb": [[round(a, 4), round(b, 2), round(c, 2)] for a, b, c in samples],
        "rejected": gw.rejected(),
    }


def _trend(h: np.ndarray, v: np.ndarray, start_h: float) -> dict[str, float]:
    """Start (the first sample at or after `start_h` hours of data), middle, end, the least-squares slope per
    hour of data from the start on, the slope over the second half, and the residual spread."""
    warm = h >= start_h - 1e-9
    first = int(np.argmax(warm))
    mid = int(np.argmin(np.abs(h - h[-1] / 2)))
    slope, icpt = np.polyfit(h[warm], v[warm], 1)
    late = h >= h[-1] / 2
    return {
        "start_mb": float(v[first]),
        "start_at_h": float(h[first]),
        "mid_mb": float(v[mid]),
        "end_mb": float(v[-1]),
        "peak_mb": float(v.max()),
        "slope_mb_per_h": float(slope),
        "slope_second_half_mb_per_h": float(np.polyfit(h[late], v[late], 1)[0]),
        "residual_std_mb": float((v[warm] - (slope * h[warm] + icpt)).std()),
    }


def memory_in_process(folder: Path, hours: float) -> dict[str, Any]:
    """The consumer's work (`Pipeline` and `McapLogWriter` with the gateway's log options) over `hours` of
    10 Hz data stamped in sim time, in this process under `tracemalloc`."""
    n = round(hours * 3600 * MEMORY_RATE_HZ)
    config_path = folder / "inproc_mem.toml"
    config_path.write_text(config_text(0, None, folder / "inproc_mem.mcap"))
    config = load_config(config_path)
    pipe = Pipeline(PipelineSpec.from_config(config))
    t0 = int(T_SIM0.timestamp()) * 1_000_000_000
    step = round(1e9 / MEMORY_RATE_HZ)
    heap: list[tuple[float, float]] = []
    snaps: list[tracemalloc.Snapshot] = []
    tracemalloc.start(1)
    try:
        with McapLogWriter(folder / "inproc_mem.mcap", profile="dpgw", **config.log.writer_options()) as log:
            for k in range(n):
                rx = t0 + k * step
                data = datagram(k, MEMORY_RATE_HZ, 1, T_SIM0 + timedelta(seconds=k / MEMORY_RATE_HZ))
                log.write_raw_nmea(SOURCE, data, rx, rx)
                for o in pipe.feed(RawEvent(rx, SOURCE, data)):
                    encode_json(o.payload)  # as GatewayService._emit does for every output
                    log.write(o.topic, o.payload, o.stamp_ns, o.stamp_ns)
                if k % 600 == 0:
                    heap.append((k / MEMORY_RATE_HZ / 3600, tracemalloc.get_traced_memory()[0] / 1e6))
                if k == round(0.05 * n):
                    snaps.append(tracemalloc.take_snapshot())
            heap.append((n / MEMORY_RATE_HZ / 3600, tracemalloc.get_traced_memory()[0] / 1e6))
            snaps.append(tracemalloc.take_snapshot())
            files = len(log.paths)
    finally:
        tracemalloc.stop()
    growth = []
    mine = (tracemalloc.Filter(False, tracemalloc.__file__),)  # the snapshots themselves
    for st in snaps[1].filter_traces(mine).compare_to(snaps[0].filter_traces(mine), "lineno")[:6]:
        if st.size_diff > 0:
            where = f"{st.traceback[0].filename}:{st.traceback[0].lineno}"
            where = where.replace(str(REPO) + "/", "").replace(sys.prefix + "/lib/", "")
            growth.append({"where": where, "mb": st.size_diff / 1e6, "blocks": st.count_diff})
    h = np.array([x[0] for x in heap])
    m = np.array([x[1] for x in heap])
    return {
        "hours_of_data": hours,
        "cycles": n,
        "log_files": files,
        **{f"heap_{key}": v for key, v in _trend(h, m, 0.05 * hours).items()},
        "growth_by_line": growth,
    }


# --- 4: where the gateway's time goes -----------------------------------------------------------------------


def in_process_costs(folder: Path, rate_hz: float | None, gga_hz: float, seconds: float) -> dict[str, Any]:
    """The consumer's work per datagram as `GatewayService._handle` and `_emit` do it, minus the Zenoh put,
    one datagram every 1/`rate_hz` s (caches and clocks as cold as in the gateway at that rate), or back
    to back at 50 Hz stamps when `rate_hz` is None (`seconds` is then the stamped duration)."""
    paced = rate_hz is not None
    rate = rate_hz or 50.0
    gga_every = max(1, round(rate / gga_hz))
    name = f"inproc_{rate:g}hz" if paced else "inproc_hot"
    config_path = folder / f"{name}.toml"
    config_path.write_text(config_text(0, None, folder / f"{name}.mcap"))
    config = load_config(config_path)
    pipe = Pipeline(PipelineSpec.from_config(config))
    parts: dict[str, list[int]] = {"raw": [], "feed": [], "json": [], "log": []}
    n = round(seconds * rate)
    t0 = time.time_ns()
    step = round(1e9 / rate)
    t_next = time.monotonic()
    with McapLogWriter(folder / f"{name}.mcap", profile="dpgw", **config.log.writer_options()) as log:
        for k in range(n):
            data = datagram(k, rate, gga_every, datetime.now(UTC))
            if paced:
                t_next += 1.0 / rate
                time.sleep(max(0.0, t_next - time.monotonic()))
                rx = time.time_ns()
            else:
                rx = t0 + k * step
            a = time.perf_counter_ns()
            log.write_raw_nmea(SOURCE, data, rx, rx)
            b = time.perf_counter_ns()
            outs = pipe.feed(RawEvent(rx, SOURCE, data))
            c = time.perf_counter_ns()
            for o in outs:
                encode_json(o.payload)
            d = time.perf_counter_ns()
            for o in outs:
                log.write(o.topic, o.payload, o.stamp_ns, o.stamp_ns)
            e = time.perf_counter_ns()
            if k >= n // 10:
                for key, v in zip(parts, (b - a, c - b, d - c, e - d), strict=True):
                    parts[key].append(v)
    total = [sum(v) for v in zip(*parts.values(), strict=True)]

    def us(v: list[int]) -> dict[str, float]:
        return {"median_us": statistics.median(v) / 1e3, "p99_us": float(np.percentile(v, 99)) / 1e3}

    return {
        "rate_hz": rate_hz,
        "samples": len(total),
        "mcap_raw_write": us(parts["raw"]),
        "pipeline_feed": us(parts["feed"]),
        "json_for_zenoh": us(parts["json"]),
        "mcap_output_writes": us(parts["log"]),
        "total": us(total),
    }


# --- report -------------------------------------------------------------------------------------------------


def _q(q: dict[str, float]) -> str:
    return f"p50 {q['p50_ms']:.3f}  p99 {q['p99_ms']:.3f}  max {q['max_ms']:.3f} ms"


def print_report(res: dict[str, Any]) -> None:
    print(
        f"dpgw gateway benchmark: {res['cpu_count']} cores, Python {res['python']}, load average at start "
        f"{res['loadavg_at_start']:.2f}; MCAP logging on (zstd, 1 s flush)"
        + (f"; latency runs under SCHED_FIFO {res['sched_fifo']}" if res.get("sched_fifo") else "")
    )
    floor = res.get("floor", {})
    for r in res["latency"]:
        lat, c = r["latency"], r["cpu"]
        print(f"\n{r['rate_hz']:g} Hz: {r['input']}")
        print(
            f"  {r['paired']}/{r['sent']} estimates paired over {r['seconds']:g} s after {r['warmup_s']:g} s "
            f"warm-up; lost {r['lost']}, duplicates {r['duplicates']}, rejected {sum(r['rejected'].values())}"
        )
        if lat:
            ok = "ok" if lat["p99_ms"] <= LATENCY_TARGET_MS else "MISSED"
            print(
                f"  latency datagram -> Zenoh subscriber: {_q(lat)}   (p99 <= {LATENCY_TARGET_MS:g} ms: {ok})"
            )
            print(f"    send -> gateway receive stamp:      {_q(r['send_to_receive_stamp'])}")
            print(f"    receive stamp -> subscriber:        {_q(r['receive_stamp_to_subscriber'])}")
            if r["latency_gga_cycles"]:
                print(f"    datagrams with GGA only:            {_q(r['latency_gga_cycles'])}")
            f = floor.get(f"{r['rate_hz']:g}")
            if f and f["latency"]:
                print(f"  floor: the same path without the gateway's work ({f['paired']} samples):")
                print(f"    datagram -> Zenoh subscriber:       {_q(f['latency'])}")
                print(f"    send -> receive stamp:              {_q(f['send_to_receive_stamp'])}")
                print(f"    receive stamp -> subscriber:        {_q(f['receive_stamp_to_subscriber'])}")
        target = ""
        if r["rate_hz"] == 10:
            target = (
                f"  (<= {CPU_TARGET_PCT:g} %: {'ok' if c['gateway_pct'] <= CPU_TARGET_PCT else 'MISSED'})"
            )
        print(f"  gateway CPU {c['gateway_pct']:.2f} % of one core over {c['window_s']:.0f} s{target}")
        print(
            f"  meanwhile: this process {c['bench_pct']:.1f} %, other processes "
            f"{c['other_processes_pct']:.1f} % of one core; gateway RSS {r['rss_mb']:.1f} MB"
        )
    m = res.get("memory")
    if m:
        print(
            f"\nmemory, dpgw run: {m['hours_of_data']:g} h of 10 Hz data ({m['cycles']:,} GGA+HDT datagrams)"
            f" in {m['wall_s']:.1f} s ({m['times_real_time']:.0f}x real time, {m['cpu_ms_per_cycle']:.3f} ms "
            f"CPU per datagram), {m['estimates_received']:,} estimates, {m['log_mb']:.1f} MB of MCAP; "
            f"heading history {m['heading_history_entries']:,} entries (50 at 10 Hz real time)"
        )
        print(
            f"  RSS idle {m['rss_idle_mb']:.1f} MB; start ({m['rss_start_at_h'] * 60:.0f} min of data) "
            f"{m['rss_start_mb']:.1f}, middle {m['rss_mid_mb']:.1f}, end {m['rss_end_mb']:.1f} MB"
        )
        print(
            f"  slope {m['rss_slope_mb_per_h']:+.2f} MB/h of data (second half "
            f"{m['rss_slope_second_half_mb_per_h']:+.2f} MB/h); residual std "
            f"{m['rss_residual_std_mb']:.2f} MB"
        )
    mi = res.get("memory_in_process")
    if mi:
        print(
            f"memory, in-process Python heap with sim-time stamps (one MCAP chunk per second of data), "
            f"{mi['hours_of_data']:g} h, {mi['log_files']} log file(s):"
        )
        print(
            f"  start {mi['heap_start_mb']:.2f}, middle {mi['heap_mid_mb']:.2f}, end {mi['heap_end_mb']:.2f}"
            f" MB; slope {mi['heap_slope_mb_per_h']:+.2f} MB/h of data"
        )
        mcap = sum(g["mb"] for g in mi["growth_by_line"] if "/mcap/" in g["where"])
        grown = mi["heap_end_mb"] - mi["heap_start_mb"]
        print(
            f"  of which {mcap:.2f} of {grown:.2f} MB in the mcap package (one ChunkIndex per chunk, kept for"
        )
        print("  the file's summary until it is finished: [log] rotate_minutes, default 60); by line:")
        for g in mi["growth_by_line"]:
            print(f"    +{g['mb']:.3f} MB in {g['blocks']:+d} blocks  {g['where']}")
    costs = res.get("in_process", [])
    if costs:
        print("\nthe gateway's work per datagram (consumer thread, all but the Zenoh put), in-process, µs:")
        heads = [f"1 per {1e3 / c['rate_hz']:g} ms" if c["rate_hz"] else "back to back" for c in costs]
        print(f"  {'median / p99':52s}" + "".join(f"{h:>20s}" for h in heads))
        for key, label in (
            ("mcap_raw_write", "MCAP write of the raw datagram"),
            ("pipeline_feed", "Pipeline.feed (framing, decoding, fusion, observer)"),
            ("json_for_zenoh", "JSON encoding of the outputs for Zenoh"),
            ("mcap_output_writes", "MCAP writes of the outputs"),
            ("total", "total"),
        ):
            cells = "".join(f"{c[key]['median_us']:11.1f} /{c[key]['p99_us']:7.1f}" for c in costs)
            print(f"  {label:52s}{cells}")


# --- main ---------------------------------------------------------------------------------------------------


def _interrupt(signum: int, _frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rates", type=float, nargs="+", default=[10.0, 50.0], metavar="HZ", help="input rates")
    ap.add_argument("--gga-hz", type=float, default=10.0, help="GGA rate when the input rate is higher (10)")
    ap.add_argument("--seconds", type=float, default=30.0, help="measured seconds per rate (30)")
    ap.add_argument("--warmup", type=float, default=5.0, help="seconds discarded at each rate (5)")
    ap.add_argument("--hours", type=float, default=1.0, help="hours of 10 Hz data for the memory test (1)")
    ap.add_argument(
        "--speedup",
        type=float,
        default=200.0,
        help="memory test pace: times real time (200: an hour in 18 s); 0 = as fast as the gateway takes it",
    )
    ap.add_argument("--window", type=int, default=32, help="estimates outstanding in the memory test (32)")
    ap.add_argument("--quick", action="store_true", help="a short smoke run (about a minute)")
    ap.add_argument("--no-memory", action="store_true", help="skip the memory tests")
    ap.add_argument(
        "--fifo",
        type=int,
        metavar="PRIO",
        help="latency runs under SCHED_FIFO at PRIO (1-99; the gateway via chrt, and this process): what a "
        "real-time priority buys on a busy machine; needs root or CAP_SYS_NICE",
    )
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    ap.add_argument(
        "--samples",
        metavar="FILE.csv",
        help="write every paired datagram of the gateway runs: rate_hz, cycle, send_ns, gateway_rx_ns, "
        "subscriber_rx_ns",
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.seconds, args.warmup, args.hours = min(args.seconds, 8.0), min(args.warmup, 2.0), 0.1
    if args.hours < 0.05 or args.seconds < 3 or args.window < 1 or args.speedup < 0:
        ap.error("need --hours >= 0.05, --seconds >= 3, --window >= 1 and --speedup >= 0")
    if args.fifo is not None:
        try:
            with fifo_scheduling(args.fifo):
                pass
        except (OSError, ValueError) as exc:
            ap.error(f"--fifo {args.fifo}: cannot use SCHED_FIFO here ({exc})")
    if not Path("/proc/self/statm").exists():
        print("bench_gateway: needs Linux /proc", file=sys.stderr)
        return 2

    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # also when started with SIGINT ignored
    res: dict[str, Any] = {
        "cpu_count": os.cpu_count(),
        "python": sys.version.split()[0],
        "loadavg_at_start": os.getloadavg()[0],
        "sched_fifo": args.fifo,
        "latency": [],
        "floor": {},
    }
    try:
        with tempfile.TemporaryDirectory(prefix="dpgw-bench-") as tmp:
            folder = Path(tmp)
            for rate in args.rates:
                progress(
                    f"latency and CPU at {rate:g} Hz ({args.warmup:g} s warm-up + {args.seconds:g} s) ..."
                )
                res["latency"].append(
                    gateway_latency(folder, rate, args.gga_hz, args.warmup, args.seconds, fifo=args.fifo)
                )
            floor_s, floor_warm = args.seconds / 3, min(args.warmup, 2.0)
            for rate in args.rates:
                progress(
                    f"floor: UDP -> thread -> queue -> thread -> Zenoh at {rate:g} Hz ({floor_s:g} s) ..."
                )
                skeleton = Skeleton(folder, f"skeleton_{rate:g}hz", fifo=args.fifo)
                with fifo_scheduling(args.fifo):
                    f = latency_run(skeleton, rate, args.gga_hz, floor_warm, floor_s)
                res["floor"][f"{rate:g}"] = f
            if not args.no_memory:
                progress(f"memory: dpgw run over {args.hours:g} h of 10 Hz data ...")
                res["memory"] = memory_run(folder, args.hours, args.window, args.speedup)
                progress(f"memory: in-process heap over {args.hours:g} h of 10 Hz data ...")
                res["memory_in_process"] = memory_in_process(folder, args.hours)
            costs_s = min(args.seconds / 4, 8.0)
            progress(f"the gateway's work in-process ({costs_s:g} s per rate) ...")
            res["in_process"] = [
                *(in_process_costs(folder, rate, args.gga_hz, costs_s) for rate in args.rates),
                in_process_costs(folder, None, args.gga_hz, 60.0),
            ]
    except KeyboardInterrupt:
        print("bench_gateway: interrupted; gateway stopped, temporary files removed", file=sys.stderr)
        return 130
    samples = [(r["rate_hz"], r.pop("_samples")) for r in res["latency"]]
    for f in res["floor"].values():
        f.pop("_samples")
    if args.samples:
        with open(args.samples, "w") as out:
            out.write("rate_hz,cycle,send_ns,gateway_rx_ns,subscriber_rx_ns\n")
            for rate, rows in samples:
                out.writelines(f"{rate:g},{k},{a},{b},{c}\n" for k, a, b, c in rows)
    if args.json:
        print(json.dumps(res, indent=2))
    else:
        print_report(res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
