"""Shared test set-up."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import pynmea2

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
