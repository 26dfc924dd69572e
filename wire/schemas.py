"""JSON Schemas (draft 2020-12) of every stream dpgw publishes on Zenoh and logs to MCAP.

These dicts are the contract of DESIGN.md ("Interfaces other programs rely on") in machine-readable form;
`docs/interfaces.md` is the same contract in prose. Extend them (new optional fields, new topics); do not
rename or remove a field.

Conventions shared by every schema:
- SI units and radians; local NED at the datum (η = [N, E, ψ]), body frame ν = [u, v, r], τ = [X, Y, N].
- Every float may be `null`: JSON has no NaN or ±inf, so the MCAP writer (and the Zenoh bus) encode a
  non-finite float as `null`. Hence `_num()` is `["number", "null"]`.
- Objects accept extra fields (`additionalProperties` is not restricted) so the payloads can grow, e.g. the
  MMAE observer adds `weights` to the estimate.

`validate()` is a deliberately tiny validator for the subset of JSON Schema used here, so tests of any
module can check a payload against the contract without a new dependency.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

Schema = dict[str, Any]


def _num(description: str) -> Schema:
    return {"type": ["number", "null"], "description": description}


def _vec3(description: str) -> Schema:
    return {
        "type": "array",
        "items": {"type": ["number", "null"]},
        "minItems": 3,
        "maxItems": 3,
        "description": description,
    }


def _stamp() -> Schema:
    return {
        "type": "integer",
        "description": "Event time, UTC nanoseconds since the Unix epoch (sensor time where the sentence "
        "has one, else receive time). Note: JavaScript readers parse it as a double (~256 ns resolution).",
    }


def _object(title: str, description: str, properties: dict[str, Schema], required: list[str]) -> Schema:
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
    }


ETA = "η = [N, E, ψ]: north (m), east (m), heading (rad, clockwise from true north, in [-π, π))."
NU = "ν = [u, v, r]: surge (m/s, forward), sway (m/s, starboard), yaw rate (rad/s)."
TAU = "[X, Y, N]: surge force (N), sway force (N), yaw moment (N·m), in the body frame."

ESTIMATE_STATUS = ("initializing", "ok", "dead_reckoning", "degraded")
MODES = ("standby", "dp", "manual")

ESTIMATE: Schema = _object(
    "dpgw.Estimate",
    "Observer state estimate of the vessel's reference point (Zenoh `<prefix>/estimate`).",
    {
        "stamp_ns": _stamp(),
        "observer": {"type": "string", "description": "Observer name, e.g. `passive`, `mmae`, `kalman`."},
        "status": {
            "enum": list(ESTIMATE_STATUS),
            "description": "initializing: not yet converged / no datum; ok: measurements fresh; "
            "dead_reckoning: position measurements lost, predicting from the model; "
            "degraded: running on a subset of sensors.",
        },
        "eta": _vec3("Low-frequency position and heading " + ETA),
        "nu": _vec3("Low-frequency velocity " + NU),
        "bias": _vec3("Slowly varying environmental force estimate (earth-fixed axes) " + TAU),
        "eta_wf": _vec3("Wave-frequency motion [N (m), E (m), ψ (rad)]."),
        "omega0": _vec3("Wave peak frequency used by the wave model per DOF [N, E, ψ] (rad/s)."),
        "lat_deg": _num("Latitude of η (degrees, WGS-84, north positive)."),
        "lon_deg": _num("Longitude of η (degrees, WGS-84, east positive)."),
        "heading_deg": _num("Heading ψ (degrees, [0, 360), clockwise from true north)."),
        "datum": {
            "type": ["object", "null"],
            "description": "Origin of the local NED frame; null before the first valid fix.",
            "properties": {
                "lat_deg": _num("Datum latitude (degrees, WGS-84)."),
                "lon_deg": _num("Datum longitude (degrees, WGS-84)."),
            },
            "required": ["lat_deg", "lon_deg"],
        },
    },
    [
        "stamp_ns",
        "observer",
        "status",
        "eta",
        "nu",
        "bias",
        "eta_wf",
        "omega0",
        "lat_deg",
        "lon_deg",
        "heading_deg",
        "datum",
    ],
)

MEASUREMENT: Schema = _object(
    "dpgw.Measurement",
    "Fused position/heading measurement y fed to the observer (Zenoh `<prefix>/measurement`).",
    {
        "stamp_ns": _stamp(),
        "eta": _vec3("Measured " + ETA + " Lever arms compensated; null where not measured."),
        "valid": {
            "type": "array",
            "items": {"type": "boolean"},
            "minItems": 3,
            "maxItems": 3,
            "description": "Per component of eta [N, E, ψ]: true if measured and accepted this step.",
        },
        "sources": {
            "type": "array",
            "items": {"type": "string"},
            "description": "Names of the sources (config names) that contributed.",
        },
        "quality": {
            "description": "Source quality indicators, free form; by convention an object keyed by source "
            'name, e.g. {"dgps1": {"fix_quality": 2, "hdop": 0.9, "num_sats": 11}}.',
        },
    },
    ["stamp_ns", "eta", "valid", "sources", "quality"],
)

_THRUSTER: Schema = {
    "type": "object",
    "properties": {
        "id": {"type": ["integer", "string"], "description": "Thruster id as in the vessel model."},
        "thrust_n": _num("Thrust magnitude (N); negative for reversed thrust."),
        "azimuth_rad": _num("Azimuth angle (rad) of the thrust, body frame, from the bow, clockwise."),
    },
    "required": ["id", "thrust_n", "azimuth_rad"],
}


def _thrusters(title: str, description: str, required: list[str]) -> Schema:
    return _object(
        title,
        description,
        {
            "stamp_ns": _stamp(),
            "mode": {"enum": list(MODES), "description": "Gateway mode when the command was made."},
            "tau_demand": _vec3("Generalised force demanded by the DP controller / manual input " + TAU),
            "tau_allocated": _vec3("Generalised force the allocation achieves " + TAU),
            "thrusters": {"type": "array", "items": _THRUSTER, "description": "One entry per thruster."},
        },
        required,
    )


THRUSTER_COMMAND: Schema = _thrusters(
    "dpgw.ThrusterCommand",
    "Thrust allocation output (Zenoh `<prefix>/thrusters/command`).",
    ["stamp_ns", "mode", "tau_demand", "tau_allocated", "thrusters"],
)

THRUSTER_FEEDBACK: Schema = _thrusters(
    "dpgw.ThrusterFeedback",
    "Thruster feedback decoded from MAVLink (Zenoh `<prefix>/thrusters/feedback`); the fields of the "
    "command, of which only stamp_ns and thrusters are always present.",
    ["stamp_ns", "thrusters"],
)

STATUS: Schema = _object(
    "dpgw.Status",
    "Gateway health (Zenoh `<prefix>/status`).",
    {
        "stamp_ns": _stamp(),
        "mode": {"enum": list(MODES), "description": "Current gateway mode."},
        "sources": {
            "type": "object",
            "description": "Per input source, keyed by source name.",
            "additionalProperties": {
                "type": "object",
                "properties": {
                    "age_s": _num("Seconds since the last accepted message (s); null if none yet."),
                    "received": {"type": "integer", "description": "Messages received (count)."},
                    "rejected": {
                        "type": "object",
                        "additionalProperties": {"type": "integer"},
                        "description": 'Rejected messages by reason (count), e.g. {"checksum": 2}.',
                    },
                },
                "required": ["age_s", "received", "rejected"],
            },
        },
        "alarms": {
            "type": "array",
            "items": {"type": ["string", "object"]},
            "description": "Active alarms: short strings, or objects with at least `code` and `message`.",
        },
    },
    ["stamp_ns", "mode", "sources", "alarms"],
)

RAW_NMEA: Schema = _object(
    "dpgw.RawNmea",
    "One NMEA 0183 sentence exactly as received, valid or not (MCAP `/raw/nmea/<source>`).",
    {
        "text": {
            "type": "string",
            "description": "The sentence without its CR LF terminator. Non-ASCII bytes are shown as "
            "backslash escapes, and then `data` holds the exact bytes.",
        },
        "source": {"type": "string", "description": "Source name from the configuration."},
        "data": {"type": "string", "contentEncoding": "base64", "description": "Exact bytes (base64)."},
    },
    ["text"],
)

RAW_MAVLINK: Schema = _object(
    "dpgw.RawMavlink",
    "One MAVLink frame exactly as received, valid or not (MCAP `/raw/mavlink/<source>`).",
    {
        "data": {"type": "string", "contentEncoding": "base64", "description": "Frame bytes (base64)."},
        "source": {"type": "string", "description": "Source name from the configuration."},
    },
    ["data"],
)

TRUTH_STATE: Schema = _object(
    "dpgw.TruthState",
    "Simulator ground truth (MCAP `/truth/state`, simulator logs only).",
    {
        "stamp_ns": _stamp(),
        "eta_lf": _vec3("True low-frequency " + ETA),
        "nu": _vec3("True low-frequency velocity " + NU),
        "bias": _vec3("True environmental force (earth-fixed axes) " + TAU),
        "eta_wf": _vec3("True wave-frequency motion [N (m), E (m), ψ (rad)]."),
        "omega0": _vec3("True wave peak frequency per DOF [N, E, ψ] (rad/s)."),
    },
    ["stamp_ns", "eta_lf", "nu", "bias", "eta_wf", "omega0"],
)

SETPOINT: Schema = _object(
    "dpgw.Setpoint",
    "Position/heading setpoint as received on Zenoh `<prefix>/setpoint` (logged so replay sees it): "
    "either north_m/east_m (local NED) or lat_deg/lon_deg, with heading_deg.",
    {
        "north_m": _num("North (m) in the local NED frame."),
        "east_m": _num("East (m) in the local NED frame."),
        "lat_deg": _num("Latitude (degrees, WGS-84)."),
        "lon_deg": _num("Longitude (degrees, WGS-84)."),
        "heading_deg": _num("Heading (degrees, clockwise from true north)."),
    },
    ["heading_deg"],
)

MODE_REQUEST: Schema = _object(
    "dpgw.ModeRequest",
    "Mode request as received on Zenoh `<prefix>/mode` (a bare JSON string there), wrapped as an object.",
    {"mode": {"enum": list(MODES), "description": "Requested mode."}},
    ["mode"],
)

MANUAL_TAU: Schema = _object(
    "dpgw.ManualTau",
    "Manual generalised force as received on Zenoh `<prefix>/tau`.",
    {"X": _num("Surge force (N)."), "Y": _num("Sway force (N)."), "N": _num("Yaw moment (N·m).")},
    ["X", "Y", "N"],
)

# foxglove.LocationFix: the field names, types and constraints of Foxglove's published JSON schema (same
# title, so Foxglove recognises the channel and shows the log on its Map panel); descriptions are ours.
# Numbers here are plain `number`s as Foxglove defines them: writers must not put null in this schema.
LOCATION_FIX: Schema = {
    "title": "foxglove.LocationFix",
    "description": "GNSS position fix (WGS-84), for Foxglove's Map panel.",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
            "description": "Time of the fix (UTC): whole seconds and nanoseconds since the Unix epoch.",
        },
        "frame_id": {"type": "string", "description": "Name of the antenna / source that produced the fix."},
        "latitude": {"type": "number", "description": "Latitude (degrees, north positive)."},
        "longitude": {"type": "number", "description": "Longitude (degrees, east positive)."},
        "altitude": {"type": "number", "description": "Altitude (m)."},
        "position_covariance": {
            "type": "array",
            "items": {"type": "number"},
            "minItems": 9,
            "maxItems": 9,
            "description": "3x3 position covariance (m^2), row-major, axes East, North, Up (ENU) in the "
            "tangent plane at the fix.",
        },
        "position_covariance_type": {
            "title": "foxglove.PositionCovarianceType",
            "description": "How position_covariance is known: 0 unknown, 1 approximated, 2 diagonal known, "
            "3 known.",
            "oneOf": [
                {"title": "UNKNOWN", "const": 0},
                {"title": "APPROXIMATED", "const": 1},
                {"title": "DIAGONAL_KNOWN", "const": 2},
                {"title": "KNOWN", "const": 3},
            ],
        },
        "heading": {"type": "number", "description": "Heading (rad, clockwise from true north); optional."},
    },
    "required": [
        "timestamp",
        "frame_id",
        "latitude",
        "longitude",
        "altitude",
        "position_covariance",
        "position_covariance_type",
    ],
}

# For topics nobody registered: any JSON object.
PERMISSIVE: Schema = {
    "$schema": JSON_SCHEMA_DIALECT,
    "title": "dpgw.Any",
    "description": "Free-form JSON object (no schema registered for this topic).",
    "type": "object",
}

# Topic -> (schema name, schema). A key ending in "/" matches every topic under it, e.g. "/raw/nmea/dgps1".
# Exact keys win over prefixes; the longest prefix wins among prefixes.
TOPIC_SCHEMAS: dict[str, tuple[str, Schema]] = {
    "/dp/estimate": ("dpgw.Estimate", ESTIMATE),
    "/dp/measurement": ("dpgw.Measurement", MEASUREMENT),
    "/dp/thrusters/command": ("dpgw.ThrusterCommand", THRUSTER_COMMAND),
    "/dp/thrusters/feedback": ("dpgw.ThrusterFeedback", THRUSTER_FEEDBACK),
    "/dp/status": ("dpgw.Status", STATUS),
    "/dp/setpoint": ("dpgw.Setpoint", SETPOINT),
    "/dp/mode": ("dpgw.ModeRequest", MODE_REQUEST),
    "/dp/tau": ("dpgw.ManualTau", MANUAL_TAU),
    "/dp/estimate/fix": ("foxglove.LocationFix", LOCATION_FIX),
    "/truth/state": ("dpgw.TruthState", TRUTH_STATE),
    "/raw/nmea/": ("dpgw.RawNmea", RAW_NMEA),
    "/raw/mavlink/": ("dpgw.RawMavlink", RAW_MAVLINK),
    "/gnss/": ("foxglove.LocationFix", LOCATION_FIX),
}


def schema_for_topic(topic: str) -> tuple[str, Schema]:
    """(schema name, schema) for `topic`: exact match, else longest matching prefix, else PERMISSIVE."""
    if topic in TOPIC_SCHEMAS and not topic.endswith("/"):
        return TOPIC_SCHEMAS[topic]
    prefixes = [k for k in TOPIC_SCHEMAS if k.endswith("/") and topic.startswith(k) and len(topic) > len(k)]
    if prefixes:
        return TOPIC_SCHEMAS[max(prefixes, key=len)]
    return (PERMISSIVE["title"], PERMISSIVE)


# --- a tiny validator -------------------------------------------------------------------------------------

# Keywords validate() checks, and annotation-only keywords it may ignore. A test walks every schema above
# and fails if it meets a keyword in neither set, so the validator never silently skips a constraint.
VALIDATED_KEYWORDS = frozenset(
    {
        "type",
        "properties",
        "required",
        "additionalProperties",
        "items",
        "minItems",
        "maxItems",
        "enum",
        "const",
        "oneOf",
        "minimum",
        "maximum",
    }
)
ANNOTATION_KEYWORDS = frozenset({"$schema", "title", "description", "$comment", "contentEncoding"})

_TYPE_CHECKS = {
    "object": lambda v: isinstance(v, Mapping),
    "array": lambda v: isinstance(v, list | tuple),
    "string": lambda v: isinstance(v, str),
    "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "number": lambda v: isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v),
    "boolean": lambda v: isinstance(v, bool),
    "null": lambda v: v is None,
}


def validate(instance: Any, schema: Schema, path: str = "$") -> list[str]:
    """Errors (empty if valid) of `instance` against `schema`, for the keywords in VALIDATED_KEYWORDS."""
    errors: list[str] = []
    if "type" in schema:
        types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        if not any(_TYPE_CHECKS[t](instance) for t in types):
            return [f"{path}: {instance!r} is not of type {types}"]
    if "enum" in schema and instance not in schema["enum"]:
        errors.append(f"{path}: {instance!r} not in {schema['enum']}")
    if "const" in schema and instance != schema["const"]:
        errors.append(f"{path}: {instance!r} != {schema['const']!r}")
    if "oneOf" in schema:
        matches = sum(not validate(instance, sub, path) for sub in schema["oneOf"])
        if matches != 1:
            errors.append(f"{path}: {instance!r} matches {matches} of oneOf, not exactly 1")
    if isinstance(instance, int | float) and not isinstance(instance, bool):
        if "minimum" in schema and instance < schema["minimum"]:
            errors.append(f"{path}: {instance} < minimum {schema['minimum']}")
        if "maximum" in schema and instance > schema["maximum"]:
            errors.append(f"{path}: {instance} > maximum {schema['maximum']}")
    if isinstance(instance, Mapping):
        for key in schema.get("required", []):
            if key not in instance:
                errors.append(f"{path}: missing required field {key!r}")
        properties = schema.get("properties", {})
        extra = schema.get("additionalProperties", True)
        for key, value in instance.items():
            if key in properties:
                errors += validate(value, properties[key], f"{path}.{key}")
            elif extra is False:
                errors.append(f"{path}: unexpected field {key!r}")
            elif isinstance(extra, dict):
                errors += validate(value, extra, f"{path}.{key}")
    if isinstance(instance, list | tuple):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            errors.append(f"{path}: {len(instance)} items < minItems {schema['minItems']}")
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            errors.append(f"{path}: {len(instance)} items > maxItems {schema['maxItems']}")
        if "items" in schema:
            for i, item in enumerate(instance):
                errors += validate(item, schema["items"], f"{path}[{i}]")
    return errors
