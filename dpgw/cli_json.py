"""What ``--json`` prints: standard JSON (RFC 8259), which has no NaN or Infinity.

Python's `json.dumps` writes ``NaN`` and ``Infinity`` by default; jq and Python read them back, but
JavaScript's ``JSON.parse``, Go's encoding/json, serde_json and most other parsers reject the whole
document. dpgw's summaries have such values where there is nothing to report (an RMS error of no sample
after the settle time) or where a quantity is unbounded (the bias time constant of a random-walk bias):
both print as ``null``, which every parser reads.
"""

from __future__ import annotations

import json
from typing import Any


def dumps(value: Any, **kwargs: Any) -> str:
    """`json.dumps` of ``value`` made plain by `wire.json_payload.to_jsonable` (the rule of every payload
    dpgw publishes: NaN and infinities as null, numpy as lists and numbers): a document any parser reads."""
    from wire.json_payload import to_jsonable  # (numpy: imported when a command prints, not for --help)

    return json.dumps(to_jsonable(value), allow_nan=False, **kwargs)
