"""JSON Schema and documentation tables derived from the message classes of `wire.messages`.

The classes are the one definition of each message; this module reads their field types and
`msgspec.Meta` annotations (description, unit, length and range constraints) and writes:
- `json_schema(cls)`: the JSON Schema (draft 2020-12) embedded in each MCAP channel. Nested objects are
  inlined (no `$ref`), so a reader needs nothing but the schema record.
- `markdown_table(cls)` and `topics_table()`: the tables of `docs/interfaces.md` (`tools/gen_interfaces.py`
  writes them; a test fails when the committed doc differs).

Type mapping: `int` -> integer, `float` -> `["number", "null"]` (a non-finite float is encoded as null;
plain `number` in Foxglove's schemas), `str` -> string, `bool` -> boolean, `bytes` -> base64 string,
`Literal` -> enum, `list[T]` -> array, `dict[str, T]` -> object with `additionalProperties: T`, a record ->
object, `X | None` -> X or null, `Any` -> anything. A field with a default is optional (not in
`required`). Objects never forbid extra properties: payloads may grow.
"""

from __future__ import annotations

import inspect
import types
import typing
from dataclasses import dataclass
from typing import Any, Literal, Union

import msgspec

from wire.messages import TOPICS, Message, Record

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

Schema = dict[str, Any]

__all__ = ["JSON_SCHEMA_DIALECT", "FieldDoc", "field_docs", "json_schema", "markdown_table", "topics_table"]


def _unwrap(tp: Any) -> tuple[Any, list[msgspec.Meta]]:
    """(the type inside any `Annotated`, the `msgspec.Meta` annotations on it)."""
    metas: list[msgspec.Meta] = []
    while typing.get_origin(tp) is typing.Annotated:
        base, *extras = typing.get_args(tp)
        metas += [m for m in extras if isinstance(m, msgspec.Meta)]
        tp = base
    return tp, metas


def _is_union(tp: Any) -> bool:
    return typing.get_origin(tp) in (Union, types.UnionType)


def _is_record(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, Record)


def _fields(cls: type[Record]) -> list[tuple[str, Any, bool]]:
    """(name, annotated type, required) of each field of `cls`, in declaration order."""
    hints = typing.get_type_hints(cls, include_extras=True)
    return [
        (f.name, hints[f.name], f.default is msgspec.NODEFAULT and f.default_factory is msgspec.NODEFAULT)
        for f in msgspec.structs.fields(cls)
    ]


def _description(cls: type) -> str:
    text = inspect.cleandoc(cls.__doc__ or "")
    return " ".join(text.split())


# --- JSON Schema ----------------------------------------------------------------------------------------


def _with_null(schema: Schema) -> Schema:
    if "enum" in schema:
        return {**schema, "enum": [*schema["enum"], None]}
    t = schema.get("type")
    if t is None:
        return schema  # anything: null included
    types_ = t if isinstance(t, list) else [t]
    return schema if "null" in types_ else {**schema, "type": [*types_, "null"]}


def _apply(schema: Schema, metas: list[msgspec.Meta]) -> Schema:
    for m in metas:
        extra = m.extra or {}
        if "schema" in extra:
            schema = dict(extra["schema"])
        if m.min_length is not None:
            schema["minItems"] = m.min_length
        if m.max_length is not None:
            schema["maxItems"] = m.max_length
        if m.ge is not None:
            schema["minimum"] = m.ge
        if m.le is not None:
            schema["maximum"] = m.le
        if m.description:
            schema["description"] = m.description
    return schema


def _schema(tp: Any, nullable_floats: bool, none_omitted: bool = False) -> Schema:
    """`none_omitted`: an optional field whose None is left out of the JSON, never written as null."""
    tp, metas = _unwrap(tp)
    out: Schema
    if tp is Any:
        out = {}
    elif tp is bool:
        out = {"type": "boolean"}
    elif tp is int:
        out = {"type": "integer"}
    elif tp is float:
        out = {"type": ["number", "null"]} if nullable_floats else {"type": "number"}
    elif tp is str:
        out = {"type": "string"}
    elif tp is bytes:
        out = {"type": "string", "contentEncoding": "base64"}
    elif typing.get_origin(tp) is Literal:
        out = {"enum": list(typing.get_args(tp))}
    elif _is_union(tp):
        members = [a for a in typing.get_args(tp) if a is not type(None)]
        subs = [_schema(a, nullable_floats) for a in members]
        if len(subs) == 1:
            out = subs[0]
        elif all(set(s) == {"type"} for s in subs):  # int | str, str | dict: one type list
            out = {
                "type": [t for s in subs for t in (s["type"] if isinstance(s["type"], list) else [s["type"]])]
            }
        else:
            out = {"anyOf": subs}
        if len(members) < len(typing.get_args(tp)) and not none_omitted:
            out = _with_null(out)
    elif typing.get_origin(tp) is list:
        (item,) = typing.get_args(tp)
        out = {"type": "array", "items": _schema(item, nullable_floats)}
    elif typing.get_origin(tp) is dict:
        _, value = typing.get_args(tp)
        out = {"type": "object"}
        if _unwrap(value)[0] is not Any:
            out["additionalProperties"] = _schema(value, nullable_floats)
    elif _is_record(tp):
        out = _object(tp, nullable_floats)
    else:
        raise TypeError(f"no JSON Schema for {tp!r}")
    return _apply(out, metas)


def _object(cls: type[Record], nullable_floats: bool) -> Schema:
    out: Schema = {}
    if cls.TITLE is not None:
        out["title"] = cls.TITLE
    out["type"] = "object"
    fields = [f for f in _fields(cls) if f[0] not in cls.FLATTEN]
    if fields:
        out["properties"] = {name: _schema(tp, nullable_floats, not req) for name, tp, req in fields}
        out["required"] = [name for name, _, req in fields if req]
    return out


def json_schema(cls: type[Message]) -> Schema:
    """The JSON Schema of message `cls`, as embedded in its MCAP channels."""
    body = _object(cls, nullable_floats=not cls.FOXGLOVE)
    head: Schema = {} if cls.FOXGLOVE else {"$schema": JSON_SCHEMA_DIALECT}
    head["title"] = cls.TITLE
    head["description"] = _description(cls)
    return {**head, **{k: v for k, v in body.items() if k != "title"}}


# --- documentation tables -------------------------------------------------------------------------------


@dataclass(frozen=True)
class FieldDoc:
    """One row of a message's table in docs/interfaces.md."""

    name: str
    type: str
    unit: str
    meaning: str


def _type_text(tp: Any, none_omitted: bool = False) -> str:
    tp, metas = _unwrap(tp)
    length = next(
        (m.min_length for m in metas if m.min_length is not None and m.min_length == m.max_length), None
    )
    if tp is Any:
        return "any"
    if tp is bool:
        return "boolean"
    if tp is int:
        return "integer"
    if tp is float:
        return "number"
    if tp is str:
        return "string"
    if tp is bytes:
        return "string (base64)"
    if typing.get_origin(tp) is Literal:
        values = [f"`{v}`" for v in typing.get_args(tp)]
        return "one of " + ", ".join(values)
    if _is_union(tp):
        members = [a for a in typing.get_args(tp) if a is not type(None)]
        text = " or ".join(_type_text(a) for a in members)
        nullable = len(members) < len(typing.get_args(tp)) and not none_omitted
        return text + (" or null" if nullable else "")
    if typing.get_origin(tp) is list:
        (item,) = typing.get_args(tp)
        inner = _type_text(item)
        return f"[{length}] {inner}" if length is not None else f"[{inner}]"
    if typing.get_origin(tp) is dict:
        _, value = typing.get_args(tp)
        return "object" if _unwrap(value)[0] is Any else f"{{name: {_type_text(value)}}}"
    if _is_record(tp):
        return "object"
    raise TypeError(f"no documentation type for {tp!r}")


def _nested(tp: Any) -> tuple[str, type[Record]] | None:
    """(path suffix, record class) when `tp` holds records: `.` for a record, `[].` for a list of them,
    `.<name>.` for a mapping of them."""
    tp, _ = _unwrap(tp)
    if _is_union(tp):
        for a in typing.get_args(tp):
            found = _nested(a)
            if found is not None:
                return found
        return None
    if _is_record(tp):
        return ".", tp
    if typing.get_origin(tp) is list:
        found = _nested(typing.get_args(tp)[0])
        return None if found is None else ("[]" + found[0], found[1])
    if typing.get_origin(tp) is dict:
        found = _nested(typing.get_args(tp)[1])
        return None if found is None else (".<name>" + found[0], found[1])
    return None


def field_docs(cls: type[Record], prefix: str = "") -> list[FieldDoc]:
    """Rows for every field of `cls`, nested records' fields following their parent (`datum.lat_deg`,
    `thrusters[].id`, `sources.<name>.age_s`)."""
    rows: list[FieldDoc] = []
    for name, tp, required in _fields(cls):
        _, metas = _unwrap(tp)
        unit = next((str(m.extra["unit"]) for m in metas if m.extra and "unit" in m.extra), "")
        meaning = " ".join(m.description for m in metas if m.description)
        if name in cls.FLATTEN:
            rows.append(FieldDoc("(more fields)", "any", "", meaning))
            continue
        text = _type_text(tp, not required) + ("" if required else ", optional")
        rows.append(FieldDoc(prefix + name, text, unit, meaning))
        nested = _nested(tp)
        if nested is not None:
            rows += field_docs(nested[1], prefix + name + nested[0])
    return rows


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def markdown_table(cls: type[Record]) -> str:
    """The field table of message `cls` (Markdown)."""
    lines = ["| field | type | unit | meaning |", "|---|---|---|---|"]
    for r in field_docs(cls):
        name = r.name if r.name.startswith("(") else f"`{r.name}`"
        lines.append(f"| {name} | {_cell(r.type)} | {_cell(r.unit)} | {_cell(r.meaning)} |")
    return "\n".join(lines) + "\n"


def topics_table() -> str:
    """Every MCAP topic, its schema name and what it carries (Markdown)."""
    lines = ["| topic | schema name | Zenoh key | content |", "|---|---|---|---|"]
    for t in TOPICS:
        topic = t.pattern + "*" if t.pattern.endswith("/") else t.pattern  # a prefix: every topic under it
        key = f"`<prefix>/{t.zenoh[0]}` ({t.zenoh[1]})" if t.zenoh else ""
        lines.append(f"| `{topic}` | `{t.message.TITLE}` | {key} | {_cell(t.content)} |")
    lines.append("| any other topic | `dpgw.Any` | | any JSON object |")
    return "\n".join(lines) + "\n"
