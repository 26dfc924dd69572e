"""``[[sources]]``: each entry read with the schema, its URL checked with the one URL grammar
(`wire.urls`), and the checks across entries (unique names, one device or port per source, a position
and a heading source, distinct priorities per role).

A source is named in messages by its ``name`` (``sources.dgps1.url``), which the user finds in the file;
an entry without a usable name (missing, invalid, or a duplicate) by its index (``sources[2].url``).
Nothing is opened here: the gateway opens the sources at start-up (`gateway.sources.open_source`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gateway.config.model import (
    BAUD_RATES,
    MAX_ARDUPILOT_INDEX,
    ROLES,
    SIGNING_KEY,
    SOURCE_NAME,
    ArdupilotMap,
    SourceConfig,
)
from gateway.config.problems import Problems, did_you_mean, kind, show
from gateway.config.schema import SourceTable, read_table
from observers.vessel import VesselModel
from wire.codecs import nmea_tag
from wire.foxglove import FRAMES
from wire.urls import SOURCE_OPTIONS, Endpoint, UrlError, file_rate, parse_url, serial_settings

__all__ = ["read_sources"]

_NMEA_ONLY = ("allow_missing_checksum", "tag_source")
_MAVLINK_ONLY = ("system_id", "component_id", "signing_key", "allow_unsigned", "ardupilot", "commands")
_EXAMPLE = '[[sources]] name = "dgps1", url = "serial:///dev/ttyUSB0?baud=4800", protocol = "nmea", ...'


def source_labels(entries: list[Any]) -> list[str]:
    """How each entry is named in messages: ``sources.NAME``, or ``sources[i]`` without a usable name."""
    labels: list[str] = []
    seen: set[str] = set()
    for i, entry in enumerate(entries):
        name = entry.get("name") if isinstance(entry, dict) else None
        if isinstance(name, str) and SOURCE_NAME.fullmatch(name) and name not in seen:
            labels.append(f"sources.{name}")
            seen.add(name)
        else:
            labels.append(f"sources[{i}]")
    return labels


def read_sources(
    p: Problems, data: Mapping[str, Any], base_dir: Path, vessel: VesselModel | None
) -> tuple[SourceConfig, ...] | None:
    value = data.get("sources")
    if value is None:
        p.add("sources", f"missing (expected at least one {_EXAMPLE})")
        return None
    if isinstance(value, dict):
        p.add(
            "sources", "wrong type (expected an array of tables, written [[sources]], got a table [sources])"
        )
        return None
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        p.add("sources", f"wrong type (expected an array of tables [[sources]], got {kind(value)})")
        return None
    if not value:
        p.add("sources", f"empty (expected at least one {_EXAMPLE})")
        return None
    labels = source_labels(value)
    ok = True
    out: list[SourceConfig] = []
    resources: dict[str, int] = {}
    for i, entry in enumerate(value):
        # (the URL's resource comes with the entry's own problems: a person sees both in one pass)
        source, resource = _read_source(p, entry, labels[i], base_dir, vessel)
        if resource is not None:
            if resource in resources:
                j = resources[resource]
                p.add(f"{labels[i]}.url", _same_resource(resource, labels[j], value[j].get("name")))
                ok = False
            else:
                resources[resource] = i
        if source is None:
            ok = False
        else:
            out.append(source)
    # Checks across entries run on what was written, also when an entry has problems of its own.
    names: dict[str, int] = {}
    for i, entry in enumerate(value):
        name = entry.get("name")
        if not isinstance(name, str):
            continue
        if name in names:
            p.add(
                f"{labels[i]}.name",
                f"source name {show(name)} is used twice, here and by {labels[names[name]]} (expected "
                "unique names: a source's name keys its status, its log channels and its alarms)",
            )
            ok = False
        else:
            names[name] = i
    written_roles = {
        role for entry in value if isinstance(entry.get("roles"), list) for role in entry["roles"]
    }
    for role, device in (("position", "DGPS"), ("heading", "gyro compass")):
        if role not in written_roles:
            p.add(
                "sources",
                f"no source has role '{role}' — add roles = [\"{role}\"] to the {device}'s [[sources]] entry "
                "(expected a source of position and one of heading: the observer needs both)",
            )
            ok = False
    for role in ("position", "heading", "thrusters"):
        by_priority: dict[int, str] = {}
        for sc in out:
            if role not in sc.roles:
                continue
            if by_priority.get(sc.priority) == sc.name:  # (a name used twice: said as such above)
                continue
            if sc.priority in by_priority:
                p.add(
                    f"{labels[names[sc.name]]}.priority",
                    f"sources '{by_priority[sc.priority]}' and '{sc.name}' both have role '{role}' with "
                    f"priority {sc.priority} (expected different priorities: the lower wins, the other is "
                    "its failover)",
                )
                ok = False
            else:
                by_priority[sc.priority] = sc.name
    return tuple(out) if ok else None


def _same_resource(resource: str, other: str, other_name: Any) -> str:
    """The problem of a second source on ``resource`` (``serial:/dev/x``, ``udp:N``, ``tcp:N``), first used
    by ``other``. Two devices (two DGPS receivers) need a port each; one device sending several sentence
    types (a multiplexer's GGA and HDT) is one source with several roles."""
    what, _, where = resource.partition(":")
    if what == "serial":
        clash, fix = "use the same serial device", "give each its own device"
    else:
        clash, fix = "listen on the same port", "give each its own port"
    return (
        f"same {what} {where} as {other} ({show(other_name)}): two sources cannot {clash}: {fix} (or, if "
        "it is one device sending several sentence types, one source with several roles)"
    )


def _read_source(
    p: Problems, t: Mapping[str, Any], path: str, base_dir: Path, vessel: VesselModel | None
) -> tuple[SourceConfig | None, str | None]:
    """The entry's `SourceConfig` (None when it has a problem, each added to ``p``) and the resource its URL
    occupies (`check_source_url`), known whenever the URL itself is right."""
    n0 = len(p)
    protocol_written = t.get("protocol")
    protocol = protocol_written if protocol_written in ROLES else None
    allowed = ROLES.get(protocol or "", ())
    roles_exp = (
        "an array of roles from " + ", ".join(f'"{x}"' for x in allowed) + f' (protocol "{protocol}")'
        if protocol
        else "an array of roles: nmea: position, heading, wind, attitude; "
        "mavlink: thrusters, position, heading"
    )
    v = read_table(SourceTable, t, path, p, expected={"roles": roles_exp})
    name, roles = v["name"], v["roles"]
    if name is not None and not SOURCE_NAME.fullmatch(name):
        p.add(
            f"{path}.name", f"not a valid name (expected lowercase letters, digits and _, got {show(name)})"
        )
    elif name in FRAMES and roles is not None and "position" in roles:
        # (a position source's fixes are drawn in its antenna's frame, named after it)
        p.add(
            f"{path}.name",
            f"{show(name)} is the name of one of the frames the gateway draws in (expected another name, "
            f"not one of {', '.join(FRAMES)}: the fixes of a position source are in a frame of its name)",
        )
    if roles is not None:
        if not roles:
            p.add(f"{path}.roles", f"empty (expected {roles_exp})")
        if len(set(roles)) != len(roles):
            p.add(f"{path}.roles", f"a role is repeated (expected each role once, got {show(roles)})")
        if protocol is not None:
            for role in roles:
                if role not in allowed:
                    hint = did_you_mean(role, allowed, quote='"')
                    p.add(
                        f"{path}.roles",
                        f'role {show(role)} is not available for protocol "{protocol}"'
                        f"{hint} (expected {roles_exp})",
                    )
    transport: str | None = None
    url: str | None = None
    resource: str | None = None
    if v["url"] is not None:
        # with protocol unknown (reported above), check the syntax as permissively as for MAVLink
        checked = check_source_url(v["url"], protocol or "mavlink", base_dir)
        if isinstance(checked, str):
            p.add(f"{path}.url", checked)
        else:
            transport, url, resource = checked
    lever = v["lever_arm_m"]
    if "lever_arm_m" in t and roles is not None and "position" not in roles:
        p.add(
            f"{path}.lever_arm_m",
            'only for sources with role "position" (expected no lever_arm_m, or add "position" to roles)',
        )
    if lever is not None and vessel is not None and math.dist(lever, (0, 0, 0)) > 2 * vessel.length_m:
        p.add(
            f"{path}.lever_arm_m",
            f"farther from the reference point than twice the vessel length (expected metres within "
            f"{2 * vessel.length_m:g} m, got {show(t['lever_arm_m'])})",
        )
    for key in _NMEA_ONLY:
        if key in t and protocol == "mavlink":
            p.add(f"{path}.{key}", 'only for protocol "nmea" (expected no such key here)')
    tag_source = v["tag_source"]
    if tag_source is not None and not nmea_tag.SOURCE.fullmatch(tag_source):
        p.add(
            f"{path}.tag_source",
            f"not a TAG block source (expected {nmea_tag.SOURCE_EXPECTED}; got {show(tag_source)})",
        )
    if protocol == "nmea":
        for key in _MAVLINK_ONLY:
            if key in t:
                p.add(f"{path}.{key}", 'only for protocol "mavlink" (expected no such key for "nmea")')
    signing_key: bytes | None = None
    key_text = v["signing_key"]
    if key_text is not None:
        if SIGNING_KEY.fullmatch(key_text):
            signing_key = bytes.fromhex(key_text)
        else:
            # never echo a secret back into a log: only its length
            p.add(
                f"{path}.signing_key",
                f"not a signing key (expected 64 hexadecimal characters, got {len(key_text)} characters"
                + (", not all hexadecimal" if re.search(r"[^0-9a-fA-F]", key_text) else "")
                + ")",
            )
    if protocol == "mavlink" and "signing_key" not in t:
        # Without a key, allow_unsigned means only one thing: thruster commands go out unsigned. Anyone who
        # can write to the link can then drive the thrusters, so that is written down, never a default.
        if v["commands"] and not v["allow_unsigned"]:
            p.add(
                f"{path}.commands",
                "thruster commands would go out unsigned (expected a signing_key, or allow_unsigned = true "
                "to send them unsigned on a link nobody else can reach)",
            )
        elif v["allow_unsigned"] and not v["commands"]:
            p.add(
                f"{path}.allow_unsigned",
                "has no effect without a signing_key or commands = true (expected a signing_key, or no "
                "allow_unsigned)",
            )
    if v["commands"] and roles is not None and "thrusters" not in roles:
        p.add(f"{path}.commands", 'sends thruster commands (expected "thrusters" in roles)')
    ardupilot: ArdupilotMap | None = None
    if v["ardupilot"] is not None and protocol == "mavlink":
        if roles is not None and "thrusters" not in roles:
            p.add(f"{path}.ardupilot", 'maps thruster feedback (expected "thrusters" in roles)')
        ardupilot = _read_ardupilot(p, v["ardupilot"], f"{path}.ardupilot", vessel)
    p.order_since(n0, path, list(SourceTable.model_fields))
    if len(p) != n0:
        return None, resource
    assert name is not None and protocol is not None and roles is not None and url is not None
    assert transport is not None
    source = SourceConfig(
        name=name,
        url=url,
        protocol=protocol,
        roles=tuple(roles),
        transport=transport,
        lever_arm_m=lever,
        timeout_s=v["timeout_s"],
        allow_missing_checksum=v["allow_missing_checksum"],
        tag_source=tag_source,
        priority=v["priority"],
        system_id=v["system_id"],
        component_id=v["component_id"],
        signing_key=signing_key,
        allow_unsigned=v["allow_unsigned"],
        ardupilot=ardupilot,
        commands=bool(v["commands"]),
    )
    return source, resource


def _read_ardupilot(p: Problems, t: Mapping[str, Any], path: str, vessel: VesselModel | None) -> ArdupilotMap:
    p.unknown_keys(
        t,
        path,
        ("esc", "servo", "servo_neutral_us", "servo_half_turn_us", "esc_direction_servo", "esc_dead_band_us"),
    )
    neutral = _servo_us(p, t, "servo_neutral_us", path, 1500.0, 500.0, 2500.0)
    dead_band = _servo_us(p, t, "esc_dead_band_us", path, 25.0, 0.0, 400.0)
    half_turn = _servo_us(p, t, "servo_half_turn_us", path, 400.0, -1000.0, 1000.0)
    if abs(half_turn) < 1.0:
        p.add(
            f"{path}.servo_half_turn_us",
            f"maps every pulse width to one angle (expected the µs change for half a turn, e.g. 400 or -400 "
            f"for a reversed servo, got {half_turn:g})",
        )
    if not t.get("esc") and not t.get("servo"):
        p.add(path, "maps nothing (expected esc = {1 = 1, ...} and/or servo = {1 = 1, ...})")
    thrusters = {th.id: th for th in vessel.thrusters} if vessel is not None else None
    maps: dict[str, dict[int, int]] = {}
    for key, what in (("esc", "ESC index"), ("servo", "servo output channel")):
        maps[key] = {}
        m = t.get(key)
        if m is None:
            continue
        if not isinstance(m, dict):
            p.add(f"{path}.{key}", f"wrong type (expected a [{path}.{key}] table, got {kind(m)} {show(m)})")
            continue
        used: dict[int, int] = {}
        for k, thruster in m.items():
            name = f"{path}.{key}.{k}"
            if not k.isdigit() or not 1 <= int(k) <= MAX_ARDUPILOT_INDEX:
                p.add(name, f"not a {what} (expected 1 to {MAX_ARDUPILOT_INDEX}, got {show(k)})")
                continue
            if isinstance(thruster, bool) or not isinstance(thruster, int):
                p.add(
                    name,
                    f"wrong type (expected a thruster id, an integer, got {kind(thruster)} {show(thruster)})",
                )
                continue
            if thrusters is not None and thruster not in thrusters:
                ids = ", ".join(str(i) for i in sorted(thrusters)) or "none"
                p.add(
                    name,
                    f"vessel '{vessel.name if vessel else ''}' has no thruster {thruster} (expected one of "
                    f"its thruster ids: {ids})",
                )
                continue
            if key == "servo" and thrusters is not None and thrusters[thruster].kind != "azimuth":
                p.add(
                    name,
                    f"thruster {thruster} is a {thrusters[thruster].kind} thruster (expected an azimuth "
                    "thruster: a servo channel gives the azimuth angle)",
                )
                continue
            if thruster in used:
                p.add(
                    name,
                    f"thruster {thruster} is also mapped from {key} {used[thruster]} (expected one {what} "
                    "per thruster)",
                )
                continue
            used[thruster] = int(k)
            maps[key][int(k)] = thruster
    return ArdupilotMap(
        esc=maps["esc"],
        servo=maps["servo"],
        servo_neutral_us=neutral,
        servo_half_turn_us=half_turn,
        esc_direction_servo=_read_esc_direction(p, t, path, maps["esc"], maps["servo"]),
        esc_dead_band_us=dead_band,
    )


def _read_esc_direction(
    p: Problems, t: Mapping[str, Any], path: str, esc: Mapping[int, int], servo: Mapping[int, int]
) -> dict[int, tuple[int, float]]:
    """``esc_direction_servo``: ESC index → its reversible motor output, as a channel (neutral 1500 µs) or
    ``{servo = channel, neutral_us = µs}``; the ESC must be in ``esc``, the channel not an azimuth servo."""
    key = "esc_direction_servo"
    m = t.get(key)
    if m is None:
        return {}
    if not isinstance(m, dict):
        p.add(f"{path}.{key}", f"wrong type (expected a [{path}.{key}] table, got {kind(m)} {show(m)})")
        return {}
    out: dict[int, tuple[int, float]] = {}
    for k, v in m.items():
        name = f"{path}.{key}.{k}"
        if not k.isdigit() or not 1 <= int(k) <= MAX_ARDUPILOT_INDEX:
            p.add(name, f"not an ESC index (expected 1 to {MAX_ARDUPILOT_INDEX}, got {show(k)})")
            continue
        if int(k) not in esc:
            p.add(
                name,
                f"ESC {k} is not mapped to a thruster (expected one of the ESCs in {path}.esc: "
                f"{', '.join(str(i) for i in sorted(esc)) or 'none'})",
            )
            continue
        neutral = 1500.0
        if isinstance(v, dict):
            p.unknown_keys(v, name, ("servo", "neutral_us"))
            neutral = _servo_us(p, v, "neutral_us", name, 1500.0, 500.0, 2500.0)
            if "servo" not in v:
                p.add(name, "has no servo (expected { servo = channel, neutral_us = µs })")
                continue
            channel, where = v["servo"], f"{name}.servo"
        else:
            channel, where = v, name
        if (
            isinstance(channel, bool)
            or not isinstance(channel, int)
            or not 1 <= channel <= MAX_ARDUPILOT_INDEX
        ):
            p.add(
                where,
                f"not a servo output channel (expected 1 to {MAX_ARDUPILOT_INDEX}, the SERVO_OUTPUT_RAW "
                f"output of ESC {k}'s motor, got {kind(channel)} {show(channel)})",
            )
            continue
        if channel in servo:
            p.add(
                where,
                f"servo output {channel} is the azimuth servo of thruster {servo[channel]} in {path}.servo "
                f"(expected the channel of ESC {k}'s motor output)",
            )
            continue
        out[int(k)] = (channel, neutral)
    return out


def _servo_us(
    p: Problems, t: Mapping[str, Any], key: str, path: str, default: float, lo: float, hi: float
) -> float:
    """A servo pulse width in µs within [lo, hi]; a problem (and the default) otherwise."""
    value = t.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
        p.add(f"{path}.{key}", f"not a pulse width (expected {lo:g} to {hi:g} µs, got {show(value)})")
        return default
    return float(value)


# --- the URL ---------------------------------------------------------------------------------------------

_URL_FORMS = (
    "serial:///dev/ttyUSB0?baud=4800, pty:///PATH, udp://0.0.0.0:10110, tcp://HOST:PORT, "
    "tcp-listen://0.0.0.0:PORT, file:///path/log.nmea, file:relative/log.nmea, or pymavlink's "
    "udpin:0.0.0.0:14550, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, /dev/ttyACM0,57600"
)


def check_source_url(url: str, protocol: str, base_dir: Path) -> tuple[str, str, str | None] | str:
    """(transport, url, resource) for a source URL, or the problem (syntax and option values only).

    ``transport`` is the URL's scheme, or ``pymavlink`` for a pymavlink connection string. ``resource``
    names what the URL occupies on this machine (a serial device, a listening port), so two sources that
    would fight over it are caught; None for links that occupy nothing exclusively. A relative
    ``file:`` path is made absolute against ``base_dir`` (the config file's folder).
    """
    try:
        ep = parse_url(url, options=SOURCE_OPTIONS, pymavlink=True, relative_files=True)
        _check_values(ep, protocol, url)
    except UrlError as exc:
        expected = exc.expected
        if expected.startswith("one of ") and "pymavlink" in expected:
            expected = f"one of {_URL_FORMS}"
        return f"{exc.problem} (expected {expected}, got {show(url)})" if expected else exc.problem
    text = url.strip()
    transport = "pymavlink" if ep.pymavlink else ep.scheme
    if ep.scheme == "file":
        if not ep.path.startswith("/"):  # file:relative/path, relative to the config file
            absolute = Endpoint("file", path=(base_dir / ep.path).resolve().as_posix(), options=ep.options)
            text = absolute.format()
        return transport, text, None
    if ep.scheme in ("serial", "pty"):
        return transport, text, f"serial:{ep.path}"
    if ep.scheme == "tcp" or not ep.listens:
        return transport, text, None
    multicast = re.fullmatch(r"(22[4-9]|23\d)\.\d+\.\d+\.\d+", ep.host) is not None
    # a listening socket occupies its port; port 0 (any free port) and multicast groups share
    resource = (
        None if ep.port == 0 or multicast else f"{'tcp' if ep.scheme == 'tcp-listen' else 'udp'}:{ep.port}"
    )
    return transport, text, resource


def _check_values(ep: Endpoint, protocol: str, url: str) -> None:
    """Option values the gateway would refuse at start-up, and a serial baud rate not on the list."""
    if ep.scheme in ("serial", "pty"):
        baud = ep.option("baud")
        if ep.pymavlink and not baud and protocol == "nmea":
            raise UrlError(
                "a pymavlink device string without a baud rate opens at 115200 baud",
                f"serial://{ep.path}?baud=4800 for NMEA 0183",
            )
        if baud is not None and not (baud.isdigit() and int(baud) in BAUD_RATES):
            raise UrlError(f"unsupported baud rate {baud!r}", f"one of {', '.join(map(str, BAUD_RATES))}")
        serial_settings(ep)
    if ep.scheme == "file":
        file_rate(ep)
