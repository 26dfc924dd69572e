"""A position reference that comes back after a silence is compared with the others like with like.

Two DGPS carry the same fixes (a vessel heaving on first-order wave motion of a few metres at a 9 s
period, plus receiver noise): neither is wrong, so neither may be made suspect when one of them comes
back after 12 s of silence. One that comes back 5 m off must still be caught, within the bound
docs/integrity.md states (``smoothing_s`` after its first fix back, plus one fix). And a state that stays
the same while only its measured figure changes logs one event, not one per figure."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gateway.references.monitor import ReferenceMonitor
from gateway.references.params import IntegrityParams
from gateway.references.state import StateChange

S = 1_000_000_000
DT = S // 10  # 10 Hz
TIMEOUT = 2 * S


def wave(t_s: float) -> tuple[float, float]:
    """First-order wave motion of the antenna: 3 m and 2 m amplitude at 9 s and 8 s periods (a realistic
    sea for a supply vessel; the smoothing's 5 s time constant passes about a quarter of it)."""
    return (
        3.0 * math.sin(2 * math.pi * t_s / 9.0),
        2.0 * math.sin(2 * math.pi * t_s / 8.0 + 1.0),
    )


class Run:
    def __init__(self, names: tuple[str, ...], seed: int = 0) -> None:
        self.p = IntegrityParams()
        self.m = ReferenceMonitor(self.p, positions=dict.fromkeys(names, TIMEOUT), headings={})
        self.rng = np.random.default_rng(seed)
        self.t = 0
        self.events: list[StateChange] = []

    def step(
        self, silent: tuple[str, ...] = (), offset: dict[str, tuple[float, float]] | None = None
    ) -> None:
        self.t += DT
        wn, we = wave(self.t / S)
        n, e = wn + self.rng.normal(0, 0.3), we + self.rng.normal(0, 0.3)  # the same fix for every source
        for name in self.m._refs["position"]:
            if name in silent:
                continue
            dn, de = (offset or {}).get(name, (0.0, 0.0))
            self.m.position(name, self.t, n + dn, e + de, 2, None)
        self.m.refresh(self.t)
        self.events += self.m.drain()

    def run(self, seconds: float, **kw: object) -> None:
        for _ in range(round(seconds * S / DT)):
            self.step(**kw)  # type: ignore[arg-type]

    def state(self, name: str) -> str:
        return self.m._refs["position"][name].state.state


@pytest.mark.parametrize("seed", range(5))
def test_two_identical_dgps_one_back_from_12_s_of_silence_raise_no_divergence(seed: int) -> None:
    r = Run(("dgps1", "dgps2"), seed)
    r.run(60)
    assert r.m.health("position") == "ok"
    r.events.clear()
    r.run(12, silent=("dgps1",))
    assert r.state("dgps1") == "stale"
    r.run(30)
    texts = [c.text for c in r.events]
    assert not [t for t in texts if "diverges" in t], texts
    assert r.state("dgps1") == "ok" and r.state("dgps2") == "ok", texts
    assert r.m.health("position") == "ok"


@pytest.mark.parametrize("seed", range(3))
def test_a_dgps_back_5_m_off_is_made_suspect_within_smoothing_s(seed: int) -> None:
    r = Run(("dgps1", "dgps2"), seed)
    r.run(60)
    r.run(12, silent=("dgps1",))
    r.events.clear()
    back = r.t + DT
    r.run(20, offset={"dgps1": (3.0, 4.0)})
    first = next(c for c in r.events if c.source == "dgps1" and "diverges" in c.reason)
    assert first.new == "suspect"
    bound = r.p.smoothing_s * S + DT
    assert first.stamp_ns - back <= bound, (first.stamp_ns - back) / S
    assert r.state("dgps1") == "suspect" and r.state("dgps2") == "suspect"


def test_three_dgps_one_back_5_m_off_is_rejected_by_the_median_within_smoothing_s() -> None:
    r = Run(("dgps1", "dgps2", "dgps3"))
    r.p = r.m.p
    r.run(60)
    r.run(12, silent=("dgps1",))
    r.events.clear()
    back = r.t + DT
    r.run(20, offset={"dgps1": (3.0, 4.0)})
    first = next(c for c in r.events if c.source == "dgps1" and c.new == "rejected")
    assert "median" in first.reason
    assert first.stamp_ns - back <= r.p.smoothing_s * S + DT, (first.stamp_ns - back) / S


def test_three_identical_dgps_one_back_from_silence_is_not_rejected() -> None:
    r = Run(("dgps1", "dgps2", "dgps3"))
    r.run(60)
    r.run(12, silent=("dgps1",))
    r.events.clear()
    r.run(30)
    assert not [c.text for c in r.events if c.new == "rejected"], [c.text for c in r.events]
    assert r.state("dgps1") == "ok"


def test_a_divergence_whose_figure_changes_logs_one_event_per_source() -> None:
    """Two DGPS 1.5 m apart, the gap closing slowly to 0.9 m (still above the 0.8 m at which the alarm
    clears): each is made suspect once; its figure changes with every fix and is in its reason."""
    r = Run(("dgps1", "dgps2"))
    r.run(30)
    r.events.clear()
    for k in range(400):  # 40 s: 1.5 m -> 0.9 m
        gap = 1.5 - 0.6 * k / 400
        r.step(offset={"dgps1": (gap, 0.0)})
    per_source = {n: [c.text for c in r.events if c.source == n] for n in ("dgps1", "dgps2")}
    assert all(len(v) == 1 for v in per_source.values()), per_source
    assert all("diverges" in v[0] for v in per_source.values())
    now = r.m.reason("position", "dgps1")
    assert now.startswith("diverges from dgps2 by ") and "1.5" not in now.split(":")[0], now


# --- headings: the same return path, with the yaw's wave motion ------------------------------------------


def yaw_wave(t_s: float) -> float:
    """First-order yaw of a supply vessel in a beam-quartering sea: 1.5° and 1° at 9 s and 7 s (rad)."""
    return math.radians(
        1.5 * math.sin(2 * math.pi * t_s / 9.0) + 1.0 * math.sin(2 * math.pi * t_s / 7.0 + 0.5)
    )


class HeadingRun:
    """Gyros that all carry the same heading (0.5 rad, the yaw's wave motion and 0.05° of noise)."""

    def __init__(self, names: tuple[str, ...], seed: int = 0) -> None:
        self.p = IntegrityParams()
        self.m = ReferenceMonitor(self.p, positions={}, headings=dict.fromkeys(names, TIMEOUT))
        self.rng = np.random.default_rng(seed)
        self.t = 0
        self.events: list[StateChange] = []

    def step(self, silent: tuple[str, ...] = (), offset_deg: dict[str, float] | None = None) -> None:
        self.t += DT
        psi = 0.5 + yaw_wave(self.t / S) + math.radians(self.rng.normal(0, 0.05))
        for name in self.m._refs["heading"]:
            if name not in silent:
                self.m.heading(name, self.t, psi + math.radians((offset_deg or {}).get(name, 0.0)), None)
        self.m.refresh(self.t)
        self.events += self.m.drain()

    def run(self, seconds: float, **kw: object) -> None:
        for _ in range(round(seconds * S / DT)):
            self.step(**kw)  # type: ignore[arg-type]

    def state(self, name: str) -> str:
        return self.m._refs["heading"][name].state.state


@pytest.mark.parametrize("seed", range(5))
def test_two_identical_gyros_one_back_from_12_s_of_silence_raise_no_divergence(seed: int) -> None:
    """The yaw's 2.5° of wave motion against ``heading_divergence_deg`` = 2°: a gyro back from a silence,
    compared with a smoothed heading of the other that still held the silence's motion, would diverge."""
    r = HeadingRun(("gyro1", "gyro2"), seed)
    r.run(60)
    assert r.m.health("heading") == "ok"
    r.events.clear()
    r.run(12, silent=("gyro1",))
    assert r.state("gyro1") == "stale"
    r.run(30)
    texts = [c.text for c in r.events]
    assert not [t for t in texts if "diverges" in t], texts
    assert r.state("gyro1") == "ok" and r.state("gyro2") == "ok", texts
    assert r.m.health("heading") == "ok"


@pytest.mark.parametrize("seed", range(3))
def test_a_gyro_back_4_deg_off_is_made_suspect_within_smoothing_s(seed: int) -> None:
    r = HeadingRun(("gyro1", "gyro2"), seed)
    r.run(60)
    r.run(12, silent=("gyro1",))
    r.events.clear()
    back = r.t + DT
    r.run(20, offset_deg={"gyro1": 4.0})
    first = next(c for c in r.events if c.source == "gyro1" and "diverges" in c.reason)
    assert first.new == "suspect"
    assert first.stamp_ns - back <= r.p.smoothing_s * S + DT, (first.stamp_ns - back) / S
    assert r.state("gyro1") == "suspect" and r.state("gyro2") == "suspect"


def test_three_gyros_one_back_4_deg_off_is_rejected_by_the_median_and_identical_ones_are_not() -> None:
    r = HeadingRun(("gyro1", "gyro2", "gyro3"))
    r.run(60)
    r.run(12, silent=("gyro1",))
    r.events.clear()
    back = r.t + DT
    r.run(20, offset_deg={"gyro1": 4.0})
    first = next(c for c in r.events if c.source == "gyro1" and c.new == "rejected")
    assert "median" in first.reason
    assert first.stamp_ns - back <= r.p.smoothing_s * S + DT, (first.stamp_ns - back) / S
    same = HeadingRun(("gyro1", "gyro2", "gyro3"), seed=1)
    same.run(60)
    same.run(12, silent=("gyro1",))
    same.events.clear()
    same.run(30)
    assert not [c.text for c in same.events if c.new == "rejected"], [c.text for c in same.events]
    assert same.state("gyro1") == "ok"
