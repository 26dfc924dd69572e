"""A replay paced in log time that a viewer drives: play, pause, seek, speed (``dpgw replay --foxglove``).

The events of the logs go through a pipeline as in `gateway.replay.run_replay`, but each is fed when the
wall clock reaches its log time: ``due = wall_anchor + (t_event − t_anchor) / speed``, the anchor being
reset by every play, seek and speed change so that changing the speed never jumps in log time.

The pipeline only runs forwards (its observer, integrity monitor and controller are causal state), so:
- a seek forwards feeds the events up to the target without sending their outputs (fast-forward, at
  replay speed: about an hour of 10 Hz data in a few seconds);
- a seek backwards builds a fresh pipeline and fast-forwards it from the start of the logs to the target:
  the state at the target is exactly what playing up to it would have made.

Requests come from the server's thread (`request`); the pacing loop (`run`) runs on the caller's thread
and does the feeding, so a request returns at once and a long fast-forward never holds the server. This
module knows nothing of Foxglove: the caller turns the app's requests into `request` calls and `state`
into the app's playback state.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from gateway.pipeline import ControlEvent, Output, RawEvent

Event = RawEvent | ControlEvent

MIN_SPEED = 0.01
MAX_SPEED = 100.0
TIME_EVERY_S = 1.0 / 30.0
"""The viewer's clock is told the log time at most this often (wall s): smooth enough for a time line."""
WAIT_MAX_S = 0.25
"""Longest single wait of the pacing loop (wall s): a stop is noticed within it."""

PLAYING, PAUSED, ENDED = "playing", "paused", "ended"


class _Feeds(Protocol):
    def feed(self, event: RawEvent | ControlEvent) -> list[Output]: ...


@dataclass(frozen=True)
class PlayerState:
    status: str
    time_ns: int
    speed: float
    did_seek: bool = False


def clamp_speed(speed: float) -> float:
    if math.isnan(speed) or speed < MIN_SPEED:
        return MIN_SPEED
    return min(speed, MAX_SPEED)


class ReplayPlayer:
    """Paced replay with play / pause / seek / speed.

    ``start``: a fresh pipeline and the events of the logs from their beginning (called again for a seek
    backwards). ``send(outputs)``: what playing produces (not called while fast-forwarding).
    ``on_time(ns)``: the log time as it advances (at most every `TIME_EVERY_S`). ``on_state``: a change
    the viewer did not ask for (the end of the logs)."""

    def __init__(
        self,
        start: Callable[[], tuple[_Feeds, Iterator[Event]]],
        time_range_ns: tuple[int, int],
        send: Callable[[list[Output]], None],
        *,
        on_time: Callable[[int], None] | None = None,
        on_state: Callable[[PlayerState], None] | None = None,
        on_seek: Callable[[], None] | None = None,
        speed: float = 1.0,
        playing: bool = False,
    ) -> None:
        self._start = start
        self.begin_ns, self.end_ns = time_range_ns
        self._send = send
        self._on_time = on_time or (lambda _ns: None)
        self._on_state = on_state or (lambda _s: None)
        self._on_seek = on_seek or (lambda: None)
        self._cond = threading.Condition()
        self.status = PLAYING if playing else PAUSED
        self.speed = clamp_speed(speed)
        self.time_ns = self.begin_ns  # the log time reached (the last event fed, or a seek's target)
        self._seek_to: int | None = None
        self._anchor = (self.begin_ns, time.monotonic())
        self._pipeline, self._events = start()
        self._next: Event | None = None
        self._fed_ns = self.begin_ns  # log time of the last event the pipeline took
        self.restarts = 0
        self.sent = 0

    # --- the viewer's side (any thread) -------------------------------------------------------------------

    def request(
        self, play: bool | None, speed: float | None = None, seek_ns: int | None = None
    ) -> PlayerState:
        """Play (True), pause (False) or neither (None); a new speed; a seek target (log ns, clamped to the
        logs' span). Returns the state the viewer should show: a seek's target at once, though the
        fast-forward to it runs on the player's thread."""
        with self._cond:
            now = time.monotonic()
            if speed is not None:
                self.speed = clamp_speed(speed)
                self._anchor = (self.time_ns, now)
            if seek_ns is not None:
                self._seek_to = self.time_ns = max(self.begin_ns, min(seek_ns, self.end_ns))
                if self.status == ENDED:
                    self.status = PAUSED
            if play is True and self.status != ENDED:
                self.status = PLAYING
                self._anchor = (self.time_ns, now)
            elif play is False and self.status != ENDED:
                self.status = PAUSED
            self._cond.notify_all()
            return PlayerState(self.status, self.time_ns, self.speed, seek_ns is not None)

    def state(self) -> PlayerState:
        with self._cond:
            return PlayerState(self.status, self.time_ns, self.speed)

    # --- the player's thread ----------------------------------------------------------------------------

    def run(self, stop: threading.Event) -> None:
        """Pace the events until ``stop`` is set (the end of the logs only pauses: a seek plays again)."""
        last_time = 0.0
        while not stop.is_set():
            with self._cond:
                target, self._seek_to = self._seek_to, None
            if target is not None:
                self._seek(target)
                continue
            with self._cond:
                if self.status != PLAYING:
                    self._cond.wait(WAIT_MAX_S)
                    continue
                ev = self._peek()
                if ev is None:
                    self.status, self.time_ns = ENDED, self.end_ns
                    state = PlayerState(ENDED, self.end_ns, self.speed)
                else:
                    t_anchor, wall_anchor = self._anchor
                    due = wall_anchor + (ev.rx_ns - t_anchor) / 1e9 / self.speed
                    wait = due - time.monotonic()
                    if wait > 0:
                        self._cond.wait(min(wait, WAIT_MAX_S))
                        continue
                    self._next = None
                    state = None
            if state is not None:
                self._on_state(state)
                continue
            assert ev is not None
            outputs = self._pipeline.feed(ev)
            self._fed_ns = ev.rx_ns
            with self._cond:
                if self._seek_to is None:
                    self.time_ns = max(self.time_ns, ev.rx_ns)
            if outputs:
                self._send(outputs)
                self.sent += len(outputs)
            now = time.monotonic()
            if now - last_time >= TIME_EVERY_S:
                last_time = now
                self._on_time(ev.rx_ns)

    def _peek(self) -> Event | None:
        if self._next is None:
            self._next = next(self._events, None)
        return self._next

    def _seek(self, target_ns: int) -> None:
        """Bring the pipeline to ``target_ns``: onwards from here, or from the start when it lies behind."""
        self._on_seek()
        if target_ns < self._fed_ns:
            self._pipeline, self._events = self._start()
            self._next = None
            self._fed_ns = self.begin_ns
            self.restarts += 1
        while True:
            ev = self._peek()
            if ev is None or ev.rx_ns >= target_ns:
                break
            self._next = None
            self._pipeline.feed(ev)
            self._fed_ns = ev.rx_ns
        with self._cond:
            if self._seek_to is None:  # (a newer seek waits its turn)
                self._anchor = (target_ns, time.monotonic())
        self._on_time(target_ns)
