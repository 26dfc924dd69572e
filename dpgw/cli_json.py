"""What ``--json`` prints: standard JSON (RFC 8259), which has no NaN or Infinity.

Python's `json.dumps` writes ``NaN`` and ``Infinity`` by default; jq and Python read them back, but
JavaScript's ``JSON.parse``, Go's encoding/json, serde_json and most other parsers reject the whole
document. dpgw's summaries have such values where there is nothing to report (an RMS error of no sample
after the settle time) or where a quantity is unbounded (the bias time constant of a random-walk bias):
both print as ``null``, which every parser reads.
"""

from __future__ import annotations

import json
import math
from typing import Any


def finite(value: Any) -> Any:
    """``value`` with every NaN or infinite float (at any depth of dicts, lists and tuples) as None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """`json.dumps` of ``value`` with NaN and infinities as null (`finite`): a document any parser reads."""
    return json.dumps(finite(value), allow_nan=False, **kwargs)
