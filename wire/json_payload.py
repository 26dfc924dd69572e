"""JSON for every payload dpgw publishes or logs: compact UTF-8, NaN and ±inf as `null`, numpy understood.

JSON has no NaN or infinity, and a reader must see `null` for "not available", so every non-finite float
becomes `null`. numpy arrays and scalars become lists and numbers; bytes become base64 strings.

The typed messages (`wire.messages`) encode themselves with msgspec; these helpers serve payloads that
are plain mappings: inputs logged as received, records read back from a log, free-form topics.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import orjson

__all__ = ["encode_json", "to_jsonable"]


def to_jsonable(obj: Any) -> Any:
    """`obj` as plain JSON types: numpy -> lists/numbers, non-finite floats -> None, bytes -> base64 str."""
    if obj is None or isinstance(obj, bool | int | str):
        return obj
    if isinstance(obj, float):  # also np.float64, a float subclass
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "biu" or (obj.dtype.kind == "f" and bool(np.isfinite(obj).all())):
            return obj.tolist()  # fast path: nothing to replace
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(obj)).decode("ascii")
    if isinstance(obj, enum.Enum):
        return to_jsonable(obj.value)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)})
    raise TypeError(f"cannot encode {type(obj).__name__} as JSON: {obj!r}")


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError  # anything else: the careful path below


_ORJSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def encode_json(payload: Any) -> bytes:
    """Compact UTF-8 JSON of `payload` (see `to_jsonable`); never emits NaN/Infinity.

    Fast path first: orjson (compact, shortest round-trip floats, NaN/±inf as null — our rule —, numpy
    arrays and scalars natively). Anything it refuses (bytes, dataclasses, enums, odd numpy dtypes) goes
    through `to_jsonable`. The logger and the Zenoh publisher write hundreds of thousands of messages.
    """
    try:
        return orjson.dumps(payload, option=_ORJSON_OPTIONS)
    except TypeError:
        pass
    try:
        return json.dumps(
            payload, separators=(",", ":"), ensure_ascii=False, allow_nan=False, default=_json_default
        ).encode()
    except (ValueError, TypeError):
        return json.dumps(
            to_jsonable(payload), separators=(",", ":"), ensure_ascii=False, allow_nan=False
        ).encode()
