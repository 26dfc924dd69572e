""" "Did you mean" for a misspelt key, column or name: one helper for every file dpgw reads.

A typo in a vessel file, a configuration or a CSV header is never silently ignored; the message names the
closest known word (`difflib`, the ratio of matching characters, at least 0.6), and a word that differs
only in case is always taken as meant (``N_1`` for ``n_1``). It lives in the lowest layer (no numpy, no
I/O) so that the vessel loader, the simulator and the gateway's configuration all use the same one.
"""

from __future__ import annotations

import difflib
from collections.abc import Collection, Iterable, Mapping, Sequence


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The choice ``word`` most likely misspells: one equal but for case, else the closest by difflib
    (ratio ≥ 0.6), else None."""
    options = list(choices)
    for choice in options:
        if choice.lower() == word.lower() and choice != word:
            return choice
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    return close[0] if close else None


def did_you_mean(word: str, choices: Iterable[str], quote: str = "'") -> str:
    """``, did you mean 'x'?`` for the closest choice, or ``""``."""
    close = closest(word, choices)
    return f", did you mean {quote}{close}{quote}?" if close is not None else ""


def key_problem(
    table: Mapping[str, object], known: Sequence[str], required: Collection[str] = ()
) -> tuple[str, str] | None:
    """The first misspelt key of a table read from a file, as (key, what is wrong), or None.

    Each key not in ``known`` is one. When the word it misspells is a ``required`` key the table lacks,
    that is the problem said — ``('length_m', "missing: 'lenght_m' is there, a misspelling of it?")`` —
    since a person reads "missing" and looks for the key they did write; otherwise the unknown key is
    named with its suggestion and the known keys. Required keys absent without a look-alike are left to
    the caller, which knows what each is for."""
    for key in table:
        if key in known:
            continue
        meant = closest(key, known)
        if meant is not None and meant in required and meant not in table:
            return meant, f"missing: '{key}' is there, a misspelling of it?"
        hint = f", did you mean '{meant}'?" if meant is not None else ""
        return key, f"unknown key{hint} (known: {', '.join(known)})"
    return None
