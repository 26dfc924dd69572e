"""A status text's identity without its figures: what stays the same while only its numbers change.

One rule for every log that tells texts apart by what they say rather than by their numbers: the alarm
log (`gateway.foxglove_channels.alarm_key`, Keelson's `log_message`) and the references' events
(`gateway.references.state`: a reason whose figures alone changed is no new event).
"""

from __future__ import annotations

import re

# A number is a value (masked) unless it is part of a name: glued to letters or underscores ("dgps1",
# "gps_2", "gyro1/gyro2", "ttyUSB0"), a thruster's id ("thruster 3", "thrusters 1, 2") or an IPv4 address
# with its port ("127.0.0.1:10110": it named "#.#" before, every address the same). Scanned left to
# right, a name is taken whole before the numbers of the rest; a number may have an exponent ("3.82e+04").
_NAME_OR_NUMBER = re.compile(
    r"(?P<name>\bthrusters? \d+(?:(?:, | and )\d+)*|[A-Za-z_][\w-]*|\b\d+\.\d+\.\d+\.\d+(?::\d+)?\b)"
    r"|(?P<number>\d+(?:\.\d+)?(?:[eE][+-]?\d+)?)"
)


def without_figures(text: str) -> str:
    """``text`` with every number that is a value as ``#``; the digits of names (``dgps1``, ``thruster 3``)
    kept: "source dgps1: stale (3.1 s without data)" -> "source dgps1: stale (# s without data)"."""
    return _NAME_OR_NUMBER.sub(lambda m: m.group() if m.group("name") else "#", text)
