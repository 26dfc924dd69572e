"""Argument types for numbers that must be positive (a duration, a speed, a count), and which options
were given.

argparse's ``type=float`` takes ``--duration -5``; the command then ran for nothing and reported success
(``dpgw demo --duration -5`` wrote an empty demo.mcap, status 0). With these types argparse stops at once
with the command's usage and ``argument --duration: must be a positive number (got -5)``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TypeVar

_T = TypeVar("_T", int, float)


def finite_float(text: str) -> float:
    """A finite number (no inf, no nan); the range checks are the caller's."""
    return _number(text)


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number (got {text})")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be a number >= 0 (got {text})")
    return value


def int_at_least(minimum: int, why: str = "") -> Callable[[str], int]:
    """An argument type for a whole number >= ``minimum``; ``why`` (the reason for the minimum) goes into
    the message of a number below it."""

    def parse(text: str) -> int:
        value = _parsed(text, int, "a whole number")
        if value < minimum:
            reason = f": {why}" if why else ""
            raise argparse.ArgumentTypeError(f"must be {minimum} or more{reason} (got {text})")
        return value

    return parse


positive_int = int_at_least(1)
"""A whole number >= 1."""

seed_int = int_at_least(0, "numpy's random generators take no negative seed")
"""A random seed: a whole number >= 0."""


def flags_given(*options: tuple[str, object]) -> list[str]:
    """The flags of ``(flag, value)`` pairs whose value is set (truthy): options a command refuses in a
    mode that would ignore them, named in one message."""
    return [flag for flag, value in options if value]


def _parsed(text: str, kind: Callable[[str], _T], what: str) -> _T:
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what} (got {text})") from None


def _number(text: str) -> float:
    value = _parsed(text, float, "a number")
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number (got {text})")
    return value
