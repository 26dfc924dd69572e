"""How config problems are reported: one line each, ``FILE: key.path: what is wrong (expected …, got …)``.

Every check (the schema's and the cross-field ones) adds to one `Problems` list, so a person sees every
problem at once, and `ConfigError` carries them all.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

from observers.spelling import did_you_mean as did_you_mean  # the one "did you mean" of dpgw; re-exported

__all__ = ["ConfigError", "Problems", "format_problems", "kind", "show"]


class ConfigError(ValueError):
    """A configuration that cannot be used. ``problems``: every problem found, one line each."""

    def __init__(self, problems: Sequence[str], *, unreadable: bool = False) -> None:
        self.problems: list[str] = list(problems)
        self.unreadable = unreadable
        """The file could not be read at all (missing, no permission): no key of it is in question."""
        n = len(self.problems)
        head = "invalid configuration" + (f" ({n} problems)" if n != 1 else "")
        super().__init__(head + ":\n" + "\n".join(f"  {p}" for p in self.problems))


def format_problems(error: ConfigError | Sequence[str], *, started: bool = True) -> str:
    """One message for a person: every problem on its own line, and that nothing was started (``started``
    False: a command that starts nothing anyway, ``dpgw run --check``, does not say it). Where to read
    about the keys closes it, unless the file could not be read at all (no key of it is in question)."""
    problems = error.problems if isinstance(error, ConfigError) else list(error)
    n = len(problems)
    stopped = "; nothing was started" if started else ""
    lines = [f"dpgw: the configuration has {n} problem{'s' if n != 1 else ''}{stopped}:"]
    lines += [f"  {p}" for p in problems]
    if not (isinstance(error, ConfigError) and error.unreadable):
        lines.append("Every key is described in docs/config.md; examples/ has working files.")
    return "\n".join(lines)


def show(value: Any) -> str:
    """A value as it is written in TOML (what the user wrote), for "got …"."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value == math.inf else repr(value))
    if isinstance(value, dict):
        return "a table" if not value else "a table {" + ", ".join(list(value)[:4]) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(show(v) for v in value[:6]) + (", …]" if len(value) > 6 else "]")
    return str(value)


def kind(value: Any) -> str:
    """What TOML calls a value's type, with its article ("a string")."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


class Problems:
    """Collects problems of one config (``where``: the file, or the name given to `parse_config`)."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.lines: list[str] = []

    def add(self, key: str, message: str) -> None:
        self.lines.append(f"{self.where}: {key}: {message}")

    def __len__(self) -> int:
        return len(self.lines)

    def order_since(self, n0: int, path: str, keys: Sequence[str]) -> None:
        """Put the problems added since ``n0`` under ``path`` in the order of ``keys`` (a table's keys as
        its schema declares them), unknown keys first: a person reads them key by key, whichever check
        found them. The sort is stable; problems of other paths keep their place at the end."""

        def rank(line: str) -> int:
            key = line[len(self.where) + 2 :].split(": ", 1)[0]
            if not key.startswith(path + "."):
                return len(keys) + 1
            first = key[len(path) + 1 :].split(".", 1)[0].split("[", 1)[0]
            return keys.index(first) if first in keys else -1

        self.lines[n0:] = sorted(self.lines[n0:], key=rank)

    def unknown_keys(self, table: Mapping[str, Any], path: str, known: Sequence[str]) -> None:
        """Every key of ``table`` not in ``known``: an error with a "did you mean" (a typo never passes)."""
        for key in table:
            if key not in known:
                prefix = f"{path}." if path else ""
                self.add(
                    f"{prefix}{key}",
                    f"unknown key{did_you_mean(key, known)} (expected one of: {', '.join(known)})",
                )
