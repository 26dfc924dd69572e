"""The message contract (`wire.messages`): one definition gives the JSON payload, the JSON Schema in MCAP and
the field tables of docs/interfaces.md; these tests hold the three together."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import hypothesis.strategies as st
import pytest
from hypothesis import given, settings
from jsonschema import Draft202012Validator

from wire.json_payload import encode_json
from wire.message_schema import json_schema
from wire.messages import (
    ANY,
    MESSAGES,
    TOPICS,
    Datum,
    Estimate,
    Measurement,
    RawNmea,
    message_for_topic,
)

ROOT = Path(__file__).resolve().parents[1]

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
vec3 = st.lists(floats, min_size=3, max_size=3)


def test_interface_doc_is_generated_from_the_messages() -> None:
    """docs/interfaces.md's tables are what tools/gen_interfaces.py writes from the classes: a field added,
    renamed or redescribed in `wire.messages` and not carried into the doc fails here."""
    p = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_interfaces.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert p.returncode == 0, p.stderr


def test_gen_interfaces_check_fails_on_a_stale_doc(tmp_path: Path) -> None:
    """The check can fail: a doc with one generated table edited by hand is reported, naming the block."""
    doc = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8")
    stale = tmp_path / "interfaces.md"
    stale.write_text(doc.replace("| `sigma_m` |", "| `sigma` |", 1), encoding="utf-8")
    p = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_interfaces.py"), "--check", "--doc", str(stale)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert p.returncode == 1 and "dpgw.Measurement" in p.stderr


@pytest.mark.parametrize("cls", [*MESSAGES, ANY], ids=lambda c: c.TITLE)
def test_every_schema_is_a_valid_draft_2020_12_schema(cls: Any) -> None:
    schema = json_schema(cls)
    Draft202012Validator.check_schema(schema)
    assert schema.get("title") == cls.TITLE


def test_every_topic_resolves_to_its_message() -> None:
    """An exact topic wins; a family by its longest prefix; anything else is `dpgw.Any`."""
    for t in TOPICS:
        topic = t.pattern + "x" if t.pattern.endswith("/") else t.pattern
        assert message_for_topic(topic) is t.message
    assert message_for_topic("/raw/nmea/gps1") is RawNmea
    assert message_for_topic("/somebody/else") is ANY


@settings(max_examples=300, deadline=None)
@given(
    stamp=st.integers(0, 2**63 - 1),
    eta=vec3,
    nu=vec3,
    bias=vec3,
    eta_wf=vec3,
    omega0=vec3,
    lat=st.none() | finite,
    heading=finite,
    datum=st.none() | st.tuples(finite, finite),
    status=st.sampled_from(["initializing", "ok", "dead_reckoning", "degraded"]),
    extra=st.dictionaries(
        st.text(st.characters(codec="ascii", categories=["Ll"]), min_size=1, max_size=8).filter(
            lambda k: k not in Estimate.__struct_fields__
        ),
        st.lists(finite, max_size=4) | finite | st.text(max_size=5),
        max_size=3,
    ),
)
def test_estimate_payload_is_the_dict_payload_byte_for_byte_and_valid(
    stamp: int,
    eta: list[float],
    nu: list[float],
    bias: list[float],
    eta_wf: list[float],
    omega0: list[float],
    lat: float | None,
    heading: float,
    datum: tuple[float, float] | None,
    status: str,
    extra: dict[str, Any],
) -> None:
    """The typed message writes the same bytes as the dict the pipeline built before (so consumers and a
    replay's outputs do not change), non-finite numbers as null, and the payload validates against the
    schema that goes into MCAP."""
    msg = Estimate(
        stamp_ns=stamp,
        observer="passive",
        status=status,  # type: ignore[arg-type]
        eta=eta,
        nu=nu,
        bias=bias,
        eta_wf=eta_wf,
        omega0=omega0,
        lat_deg=lat,
        lon_deg=lat,
        heading_deg=heading,
        datum=None if datum is None else Datum(lat_deg=datum[0], lon_deg=datum[1]),
        extra=extra,
    )
    as_dict: dict[str, Any] = {
        "stamp_ns": stamp,
        "observer": "passive",
        "status": status,
        "eta": eta,
        "nu": nu,
        "bias": bias,
        "eta_wf": eta_wf,
        "omega0": omega0,
        "lat_deg": lat,
        "lon_deg": lat,
        "heading_deg": heading,
        "datum": None if datum is None else {"lat_deg": datum[0], "lon_deg": datum[1]},
        **extra,
    }
    data = msg.encode()
    before = encode_json(as_dict)
    # The same numbers always (floats to the bit); the same bytes for every magnitude below 1e16. From
    # 1e16 up the two encoders spell the exponent differently (msgspec 1e16, orjson 1e+16): equal JSON.
    assert json.loads(data) == json.loads(before)
    numbers = [*eta, *nu, *bias, *eta_wf, *omega0, heading, *(datum or ()), lat or 0.0]
    numbers += [
        v for x in extra.values() for v in (x if isinstance(x, list) else [x]) if isinstance(v, float)
    ]
    if all(not math.isfinite(v) or abs(v) < 1e16 for v in numbers):
        assert data == before
    decoded = json.loads(data)
    assert all(v is None or math.isfinite(v) for v in decoded["eta"])
    Draft202012Validator(json_schema(Estimate)).validate(decoded)


@settings(max_examples=200, deadline=None)
@given(eta=vec3, sigma=st.none() | floats, valid=st.lists(st.booleans(), min_size=3, max_size=3))
def test_measurement_nulls_validate(eta: list[float], sigma: float | None, valid: list[bool]) -> None:
    msg = Measurement(
        stamp_ns=1,
        eta=[None if v != v else v for v in eta],
        valid=valid,
        sources=["gps1"],
        quality=2,
        sigma_m=sigma,
        tau=[0.0, 0.0, 0.0],
        tau_source="demand",
    )
    Draft202012Validator(json_schema(Measurement)).validate(json.loads(msg.encode()))
