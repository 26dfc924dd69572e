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


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    value = _parsed(text, int, "a whole number")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more (got {text})")
    return value


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
