"""Benchmark: building and encoding the live messages with each way of typing them, side by side.

Every estimate, measurement and thruster command the gateway publishes is built from the observer's and
the allocator's numpy arrays and encoded to JSON once per step, on the live path (Zenoh and the MCAP log
share the bytes). The message contract is defined once as typed classes (`wire.messages`); this measures
what that typing costs against what the pipeline did before (a dict literal encoded by orjson), so the
choice rests on figures:

- ``dict + orjson``: the baseline, a dict literal, ``orjson.dumps`` (as `wire.json_payload.encode_json`).
- ``TypedDict + orjson``: the same dict, typed statically (a TypedDict is a plain dict at run time).
- ``dataclass(slots) + orjson``: orjson serialises dataclass instances natively.
- ``msgspec.Struct``: msgspec's own JSON encoder (``gc=False`` structs, one reused ``Encoder``).
- ``pydantic``: ``BaseModel(...)`` validated, and ``model_construct`` (no validation), ``model_dump_json``.
- ``wire.messages``: the module the gateway uses, as `gateway.pipeline` calls it.

Each candidate takes the same inputs (numpy arrays, as the observer returns them) and returns the JSON
bytes; the bytes are checked against the baseline's (``same bytes``: the consumers and the replay outputs
must not change). Rounds interleave the candidates (the machine is shared); the best round is reported.

    python bench/bench_messages.py [--rounds 7] [--n 20000] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any, Literal, TypedDict

import numpy as np
import orjson

from wire import messages as wm
from wire.json_payload import encode_json

try:
    import msgspec
except ImportError:  # optional: the benchmark reports what is installed
    msgspec = None  # type: ignore[assignment]
try:
    import pydantic
except ImportError:
    pydantic = None  # type: ignore[assignment]

OPTS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


# --- the inputs: what the observer, fusion and allocator hand over -------------------------------------


@dataclasses.dataclass
class Inputs:
    stamp: int = 1_750_000_000_123_456_789
    eta: np.ndarray = dataclasses.field(default_factory=lambda: np.array([1.2345678, -0.9876543, 0.5235987]))
    nu: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.0123, -0.0045, 0.00067]))
    bias: np.ndarray = dataclasses.field(default_factory=lambda: np.array([12345.6, -2345.7, 98765.4]))
    eta_wf: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.31, -0.12, 0.0045]))
    omega0: np.ndarray = dataclasses.field(default_factory=lambda: np.full(3, 0.8975979))
    lat: float = 63.4305123456
    lon: float = 10.3950987654
    heading: float = 29.99999
    datum: tuple[float, float] = (63.43, 10.395)
    y: np.ndarray = dataclasses.field(default_factory=lambda: np.array([1.25, math.nan, 0.524]))
    valid: list[bool] = dataclasses.field(default_factory=lambda: [True, False, True])
    sources: list[str] = dataclasses.field(default_factory=lambda: ["dgps1", "gyro1"])
    sigma: float = 0.3
    tau: np.ndarray = dataclasses.field(default_factory=lambda: np.array([1.5e4, -2.5e3, 1.2e5]))
    thrust: np.ndarray = dataclasses.field(default_factory=lambda: np.array([1.1e4, -5.2e3, 8.8e3, 2.0e3]))
    azimuth: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.1, -1.2, 3.0, 1.5707963]))
    reference: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.5, 0.25, 0.5235987]))


IDS = [1, 2, 3, 4]


# --- baseline: dict literal + orjson (the pipeline before wire.messages) --------------------------------


def dict_estimate(x: Inputs) -> bytes:
    return encode_json(
        {
            "stamp_ns": x.stamp,
            "observer": "passive",
            "status": "ok",
            "eta": x.eta.tolist(),
            "nu": x.nu.tolist(),
            "bias": x.bias.tolist(),
            "eta_wf": x.eta_wf.tolist(),
            "omega0": np.asarray(x.omega0, dtype=float).tolist(),
            "lat_deg": x.lat,
            "lon_deg": x.lon,
            "heading_deg": x.heading,
            "datum": {"lat_deg": x.datum[0], "lon_deg": x.datum[1]},
        }
    )


def dict_measurement(x: Inputs) -> bytes:
    return encode_json(
        {
            "stamp_ns": x.stamp,
            "eta": [None if v != v else v for v in x.y.tolist()],
            "valid": x.valid,
            "sources": sorted(x.sources),
            "quality": 2,
            "sigma_m": x.sigma,
            "tau": x.tau.tolist(),
            "tau_source": "allocated",
        }
    )


def dict_command(x: Inputs) -> bytes:
    return encode_json(
        {
            "stamp_ns": x.stamp,
            "mode": "dp",
            "tau_demand": x.tau.tolist(),
            "tau_allocated": np.asarray(x.tau, dtype=float).tolist(),
            "saturated": False,
            "thrusters": [
                {"id": tid, "thrust_n": float(f), "azimuth_rad": float(a)}
                for tid, f, a in zip(IDS, x.thrust, x.azimuth, strict=True)
            ],
            "reference": x.reference.tolist(),
        }
    )


# --- TypedDict: the same dicts, typed for mypy ---------------------------------------------------------


class TdDatum(TypedDict):
    lat_deg: float
    lon_deg: float


class TdEstimate(TypedDict):
    stamp_ns: int
    observer: str
    status: str
    eta: list[float]
    nu: list[float]
    bias: list[float]
    eta_wf: list[float]
    omega0: list[float]
    lat_deg: float | None
    lon_deg: float | None
    heading_deg: float
    datum: TdDatum | None


def typeddict_estimate(x: Inputs) -> bytes:
    msg = TdEstimate(
        stamp_ns=x.stamp,
        observer="passive",
        status="ok",
        eta=x.eta.tolist(),
        nu=x.nu.tolist(),
        bias=x.bias.tolist(),
        eta_wf=x.eta_wf.tolist(),
        omega0=np.asarray(x.omega0, dtype=float).tolist(),
        lat_deg=x.lat,
        lon_deg=x.lon,
        heading_deg=x.heading,
        datum=TdDatum(lat_deg=x.datum[0], lon_deg=x.datum[1]),
    )
    return encode_json(msg)


# --- dataclass(slots) + orjson -------------------------------------------------------------------------


@dataclasses.dataclass(slots=True)
class DcDatum:
    lat_deg: float
    lon_deg: float


@dataclasses.dataclass(slots=True)
class DcEstimate:
    stamp_ns: int
    observer: str
    status: str
    eta: list[float]
    nu: list[float]
    bias: list[float]
    eta_wf: list[float]
    omega0: list[float]
    lat_deg: float | None
    lon_deg: float | None
    heading_deg: float
    datum: DcDatum | None


@dataclasses.dataclass(slots=True)
class DcMeasurement:
    stamp_ns: int
    eta: list[float | None]
    valid: list[bool]
    sources: list[str]
    quality: Any
    sigma_m: float | None
    tau: list[float]
    tau_source: str


@dataclasses.dataclass(slots=True)
class DcThruster:
    id: int | str
    thrust_n: float
    azimuth_rad: float


@dataclasses.dataclass(slots=True)
class DcCommand:
    stamp_ns: int
    mode: str
    tau_demand: list[float]
    tau_allocated: list[float]
    saturated: bool
    thrusters: list[DcThruster]
    reference: list[float]


def dc_estimate(x: Inputs) -> bytes:
    return orjson.dumps(
        DcEstimate(
            x.stamp,
            "passive",
            "ok",
            x.eta.tolist(),
            x.nu.tolist(),
            x.bias.tolist(),
            x.eta_wf.tolist(),
            np.asarray(x.omega0, dtype=float).tolist(),
            x.lat,
            x.lon,
            x.heading,
            DcDatum(*x.datum),
        ),
        option=OPTS,
    )


def dc_measurement(x: Inputs) -> bytes:
    return orjson.dumps(
        DcMeasurement(
            x.stamp, x.y.tolist(), x.valid, sorted(x.sources), 2, x.sigma, x.tau.tolist(), "allocated"
        ),
        option=OPTS,
    )


def dc_command(x: Inputs) -> bytes:
    return orjson.dumps(
        DcCommand(
            x.stamp,
            "dp",
            x.tau.tolist(),
            np.asarray(x.tau, dtype=float).tolist(),
            False,
            [DcThruster(t, f, a) for t, f, a in zip(IDS, x.thrust.tolist(), x.azimuth.tolist(), strict=True)],
            x.reference.tolist(),
        ),
        option=OPTS,
    )


# --- msgspec -------------------------------------------------------------------------------------------

CANDIDATES: dict[str, dict[str, Callable[[Inputs], bytes]]] = {}

if msgspec is not None:

    class MsDatum(msgspec.Struct, gc=False):
        lat_deg: float
        lon_deg: float

    class MsEstimate(msgspec.Struct, gc=False):
        stamp_ns: int
        observer: str
        status: str
        eta: list[float]
        nu: list[float]
        bias: list[float]
        eta_wf: list[float]
        omega0: list[float]
        lat_deg: float | None
        lon_deg: float | None
        heading_deg: float
        datum: MsDatum | None

    class MsMeasurement(msgspec.Struct, gc=False):
        stamp_ns: int
        eta: list[float | None]
        valid: list[bool]
        sources: list[str]
        quality: Any
        sigma_m: float | None
        tau: list[float]
        tau_source: str

    class MsThruster(msgspec.Struct, gc=False):
        id: int | str
        thrust_n: float
        azimuth_rad: float

    class MsCommand(msgspec.Struct, gc=False):
        stamp_ns: int
        mode: str
        tau_demand: list[float]
        tau_allocated: list[float]
        saturated: bool
        thrusters: list[MsThruster]
        reference: list[float]

    _ms = msgspec.json.Encoder()

    def ms_estimate(x: Inputs) -> bytes:
        return _ms.encode(
            MsEstimate(
                x.stamp,
                "passive",
                "ok",
                x.eta.tolist(),
                x.nu.tolist(),
                x.bias.tolist(),
                x.eta_wf.tolist(),
                np.asarray(x.omega0, dtype=float).tolist(),
                x.lat,
                x.lon,
                x.heading,
                MsDatum(*x.datum),
            )
        )

    def ms_measurement(x: Inputs) -> bytes:
        return _ms.encode(
            MsMeasurement(
                x.stamp, x.y.tolist(), x.valid, sorted(x.sources), 2, x.sigma, x.tau.tolist(), "allocated"
            )
        )

    def ms_command(x: Inputs) -> bytes:
        return _ms.encode(
            MsCommand(
                x.stamp,
                "dp",
                x.tau.tolist(),
                np.asarray(x.tau, dtype=float).tolist(),
                False,
                [
                    MsThruster(t, f, a)
                    for t, f, a in zip(IDS, x.thrust.tolist(), x.azimuth.tolist(), strict=True)
                ],
                x.reference.tolist(),
            )
        )

    CANDIDATES["msgspec.Struct"] = {
        "estimate": ms_estimate,
        "measurement": ms_measurement,
        "command": ms_command,
    }


# --- pydantic ------------------------------------------------------------------------------------------

if pydantic is not None:

    class PdDatum(pydantic.BaseModel):
        lat_deg: float
        lon_deg: float

    class PdEstimate(pydantic.BaseModel):
        stamp_ns: int
        observer: str
        status: Literal["initializing", "ok", "dead_reckoning", "degraded"]
        eta: list[float]
        nu: list[float]
        bias: list[float]
        eta_wf: list[float]
        omega0: list[float]
        lat_deg: float | None
        lon_deg: float | None
        heading_deg: float
        datum: PdDatum | None

    class PdMeasurement(pydantic.BaseModel):
        stamp_ns: int
        eta: list[float | None]
        valid: list[bool]
        sources: list[str]
        quality: Any
        sigma_m: float | None
        tau: list[float]
        tau_source: str

    class PdThruster(pydantic.BaseModel):
        id: int | str
        thrust_n: float
        azimuth_rad: float

    class PdCommand(pydantic.BaseModel):
        stamp_ns: int
        mode: str
        tau_demand: list[float]
        tau_allocated: list[float]
        saturated: bool
        thrusters: list[PdThruster]
        reference: list[float]

    def pd_estimate(x: Inputs, construct: bool = False) -> bytes:
        make = PdEstimate.model_construct if construct else PdEstimate
        datum = PdDatum.model_construct if construct else PdDatum
        return (
            make(
                stamp_ns=x.stamp,
                observer="passive",
                status="ok",
                eta=x.eta.tolist(),
                nu=x.nu.tolist(),
                bias=x.bias.tolist(),
                eta_wf=x.eta_wf.tolist(),
                omega0=np.asarray(x.omega0, dtype=float).tolist(),
                lat_deg=x.lat,
                lon_deg=x.lon,
                heading_deg=x.heading,
                datum=datum(lat_deg=x.datum[0], lon_deg=x.datum[1]),
            )
            .model_dump_json()
            .encode()
        )

    def pd_measurement(x: Inputs, construct: bool = False) -> bytes:
        make = PdMeasurement.model_construct if construct else PdMeasurement
        return (
            make(
                stamp_ns=x.stamp,
                eta=x.y.tolist(),
                valid=x.valid,
                sources=sorted(x.sources),
                quality=2,
                sigma_m=x.sigma,
                tau=x.tau.tolist(),
                tau_source="allocated",
            )
            .model_dump_json()
            .encode()
        )

    def pd_command(x: Inputs, construct: bool = False) -> bytes:
        make = PdCommand.model_construct if construct else PdCommand
        th = PdThruster.model_construct if construct else PdThruster
        return (
            make(
                stamp_ns=x.stamp,
                mode="dp",
                tau_demand=x.tau.tolist(),
                tau_allocated=np.asarray(x.tau, dtype=float).tolist(),
                saturated=False,
                thrusters=[
                    th(id=t, thrust_n=f, azimuth_rad=a)
                    for t, f, a in zip(IDS, x.thrust.tolist(), x.azimuth.tolist(), strict=True)
                ],
                reference=x.reference.tolist(),
            )
            .model_dump_json()
            .encode()
        )

    CANDIDATES["pydantic (validated)"] = {
        "estimate": pd_estimate,
        "measurement": pd_measurement,
        "command": pd_command,
    }
    CANDIDATES["pydantic (model_construct)"] = {
        "estimate": lambda x: pd_estimate(x, True),
        "measurement": lambda x: pd_measurement(x, True),
        "command": lambda x: pd_command(x, True),
    }


# --- wire.messages, as the pipeline calls it ----------------------------------------------------------


def wm_estimate(x: Inputs) -> bytes:
    return wm.Estimate(
        stamp_ns=x.stamp,
        observer="passive",
        status="ok",
        eta=x.eta.tolist(),
        nu=x.nu.tolist(),
        bias=x.bias.tolist(),
        eta_wf=x.eta_wf.tolist(),
        omega0=np.asarray(x.omega0, dtype=float).tolist(),
        lat_deg=x.lat,
        lon_deg=x.lon,
        heading_deg=x.heading,
        datum=wm.Datum(lat_deg=x.datum[0], lon_deg=x.datum[1]),
    ).encode()


def wm_measurement(x: Inputs) -> bytes:
    return wm.Measurement(
        stamp_ns=x.stamp,
        eta=[None if v != v else v for v in x.y.tolist()],
        valid=x.valid,
        sources=sorted(x.sources),
        quality=2,
        sigma_m=x.sigma,
        tau=x.tau.tolist(),
        tau_source="allocated",
    ).encode()


def wm_command(x: Inputs) -> bytes:
    return wm.ThrusterCommand(
        stamp_ns=x.stamp,
        mode="dp",
        tau_demand=x.tau.tolist(),
        tau_allocated=np.asarray(x.tau, dtype=float).tolist(),
        saturated=False,
        thrusters=[
            wm.Thruster(id=tid, thrust_n=float(f), azimuth_rad=float(a))
            for tid, f, a in zip(IDS, x.thrust, x.azimuth, strict=True)
        ],
        reference=x.reference.tolist(),
    ).encode()


BASELINE = "dict + orjson (before)"
ALL: dict[str, dict[str, Callable[[Inputs], bytes]]] = {
    BASELINE: {"estimate": dict_estimate, "measurement": dict_measurement, "command": dict_command},
    "TypedDict + orjson": {"estimate": typeddict_estimate},
    "dataclass(slots) + orjson": {
        "estimate": dc_estimate,
        "measurement": dc_measurement,
        "command": dc_command,
    },
    **CANDIDATES,
    "wire.messages (chosen)": {"estimate": wm_estimate, "measurement": wm_measurement, "command": wm_command},
}


def same_json(a: bytes, b: bytes) -> bool:
    """Equal as JSON documents, key order included (bytes may differ in float spelling or spaces)."""
    return list(json.loads(a).items()) == list(json.loads(b).items())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=7, help="interleaved rounds; the best is reported (7)")
    ap.add_argument("--n", type=int, default=20000, help="messages per candidate and round (20000)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    x = Inputs()
    kinds = ("estimate", "measurement", "command")
    best: dict[tuple[str, str], float] = {}
    for _ in range(args.rounds):
        for name, fns in ALL.items():
            for kind, fn in fns.items():
                loop = range(args.n)
                t0 = time.perf_counter()
                for _k in loop:
                    fn(x)
                us = (time.perf_counter() - t0) / args.n * 1e6
                best[name, kind] = min(best.get((name, kind), math.inf), us)
    rows = []
    for name, fns in ALL.items():
        for kind in kinds:
            if kind not in fns:
                continue
            ref = ALL[BASELINE][kind](x)
            got = fns[kind](x)
            rows.append(
                {
                    "candidate": name,
                    "message": kind,
                    "us_per_message": best[name, kind],
                    "ratio_to_before": best[name, kind] / best[BASELINE, kind],
                    "same_bytes": got == ref,
                    "same_json": same_json(got, ref),
                }
            )
    if args.json:
        print(
            json.dumps({"python": sys.version.split()[0], "n": args.n, "rounds": args.rounds, "rows": rows})
        )
        return
    print(f"build + encode to JSON, µs per message (best of {args.rounds} interleaved rounds of {args.n:,})")
    print(f"  {'candidate':28s} {'message':12s} {'µs':>7s} {'/before':>8s}  same bytes / same JSON")
    for r in rows:
        print(
            f"  {r['candidate']:28s} {r['message']:12s} {r['us_per_message']:7.2f} "
            f"{r['ratio_to_before']:8.2f}  {'yes' if r['same_bytes'] else 'no':3s} / "
            f"{'yes' if r['same_json'] else 'no'}"
        )


if __name__ == "__main__":
    main()
