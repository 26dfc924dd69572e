"""TOML → a checked `GatewayConfig`, or one `ConfigError` listing every problem.

Each table is read with its schema (`gateway.config.schema`: types, ranges, unknown keys), then the
checks that need several keys or other files run here: the vessel file, the datum, the Zenoh endpoints
and key prefix, the log's limits; the sources and the observer have their own modules. Loading reads
the config file, a vessel file and a Zenoh config file if named; it opens no device, port, socket or
log. Relative paths (``vessel.file``, ``log.path``, ``zenoh.config_file``, ``file:`` source URLs) are
resolved against the folder of the config file.
"""

from __future__ import annotations

import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from gateway.config.defaults import DEFAULTS
from gateway.config.model import (
    COMMAND_INPUTS,
    ZENOH_PROTOCOLS,
    CommandsConfig,
    ConsequenceConfig,
    ControlConfig,
    DatumConfig,
    FoxgloveConfig,
    GatewayConfig,
    IntegrityConfig,
    KeelsonConfig,
    LogConfig,
    ObserverConfig,
    Ros2Config,
    StatusConfig,
    TimeConfig,
    ZenohConfig,
)
from gateway.config.observer_section import read_observer
from gateway.config.problems import ConfigError, Problems, did_you_mean, kind, show
from gateway.config.schema import (
    CommandsTable,
    ConsequenceTable,
    ControlTable,
    DatumTable,
    FoxgloveTable,
    IntegrityTable,
    KeelsonTable,
    LogTable,
    Ros2Table,
    StatusTable,
    TimeTable,
    VesselTable,
    ZenohTable,
    read_table,
)
from gateway.config.source_entries import read_sources
from gateway.control.controller import ControllerTuning, froude_defaults
from observers.vessel import VesselError, VesselModel, builtin_vessels, load_vessel
from wire.rmw_zenoh import fully_qualified, is_ros_name
from wire.urls import UrlError, split_host_port, valid_host

__all__ = ["load_config", "parse_config", "prefix_problem"]

_TOP_KEYS = (
    "vessel",
    "datum",
    "sources",
    "observer",
    "zenoh",
    "log",
    "status",
    "control",
    "consequence",
    "integrity",
    "commands",
    "time",
    "keelson",
    "ros2",
    "foxglove",
)


def load_config(path: str | Path) -> GatewayConfig:
    """Read, check and return the configuration in ``path``; raise `ConfigError` listing every problem."""
    where = str(path)
    file = Path(path)
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        raise ConfigError([f"{where}: cannot read: no such file"], unreadable=True) from None
    except OSError as exc:
        raise ConfigError([f"{where}: cannot read: {exc.strerror or exc}"], unreadable=True) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError([f"{where}: not UTF-8 text (byte {exc.start}): save the file as UTF-8"]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{where}: not valid TOML: {exc}"]) from None
    resolved = file.resolve()
    return _parse(data, base_dir=resolved.parent, where=where, path=resolved)


def parse_config(data: dict[str, Any], *, base_dir: Path, where: str = "<config>") -> GatewayConfig:
    """Check a parsed config (a dict as from `tomllib`); relative paths are resolved against ``base_dir``.

    ``where`` names the config in messages. Raises `ConfigError` listing every problem.
    """
    base = Path(base_dir).resolve()
    return _parse(data, base_dir=base, where=where, path=base / where)


def _parse(data: dict[str, Any], *, base_dir: Path, where: str, path: Path) -> GatewayConfig:
    p = Problems(where)
    if not isinstance(data, dict):
        raise ConfigError(
            [f"{where}: (top level): wrong type (expected a table of sections, got {kind(data)})"]
        )
    p.unknown_keys(data, "", _TOP_KEYS)

    vessel, vessel_source, reference_point = _read_vessel(p, data, base_dir)
    datum = _read_datum(p, data)
    sources = read_sources(p, data, base_dir, vessel)
    observer_table = _section(p, data, "observer")
    observer = read_observer(p, observer_table, vessel) if observer_table is not None else None
    zenoh_config = _read_zenoh(p, data, base_dir, vessel)
    log = _read_log(p, data, base_dir)
    status = _read_status(p, data)
    control = _read_control(p, data, vessel)
    integrity = _read_integrity(p, data)
    consequence = _read_consequence(p, data, vessel)
    commands = _read_commands(p, data)
    time_config = _read_time(p, data)
    keelson = _read_keelson(p, data)
    ros2 = _read_ros2(p, data)
    foxglove = _read_foxglove(p, data)

    if p.lines:
        raise ConfigError(p.lines)
    assert vessel is not None and vessel_source is not None and reference_point is not None
    assert datum is not None and sources is not None and observer is not None
    assert zenoh_config is not None and log is not None and status is not None and control is not None
    assert integrity is not None and consequence is not None
    assert commands is not None and time_config is not None and keelson is not None and ros2 is not None
    assert foxglove is not None
    observer = with_loop_bandwidth(observer, control, vessel)
    return GatewayConfig(
        vessel=vessel,
        vessel_source=vessel_source,
        reference_point_m=reference_point,
        datum=datum,
        sources=sources,
        observer=observer,
        zenoh=zenoh_config,
        log=log,
        status=status,
        path=path,
        control=control,
        integrity=integrity,
        consequence=consequence,
        commands=commands,
        time=time_config,
        keelson=keelson,
        ros2=ros2,
        foxglove=foxglove,
    )


def _section(
    p: Problems, data: Mapping[str, Any], key: str, *, required: bool = False
) -> dict[str, Any] | None:
    """The table ``[key]`` ({} when absent and optional), or None after reporting why it is unusable."""
    value = data.get(key)
    if value is None:
        if required:
            p.add(key, f"missing (expected a [{key}] table)")
            return None
        return {}
    if not isinstance(value, dict):
        p.add(key, f"wrong type (expected a [{key}] table, got {kind(value)} {show(value)})")
        return None
    return value


def _read_vessel(
    p: Problems, data: Mapping[str, Any], base_dir: Path
) -> tuple[VesselModel | None, str | None, tuple[float, float] | None]:
    t = _section(p, data, "vessel", required=True)
    if t is None:
        return None, None, None
    v = read_table(VesselTable, t, "vessel", p)
    builtins = builtin_vessels()
    vessel: VesselModel | None = None
    source: str | None = None
    if "name" in t and "file" in t:
        p.add("vessel", "both name and file given (expected one: a built-in vessel name or a vessel file)")
    elif "name" in t:
        name = v["name"]
        if name is not None:
            if name not in builtins:
                hint = did_you_mean(name, builtins, quote='"')
                p.add(
                    "vessel.name",
                    f"not a built-in vessel{hint} (expected one of "
                    f'{", ".join(builtins)}, or give file = "my_ship.toml" for a vessel file; '
                    f"got {show(name)})",
                )
            else:
                try:
                    vessel, source = load_vessel(name), name
                except VesselError as exc:
                    p.add("vessel.name", str(exc))
    elif "file" in t:
        file = v["file"]
        if file is not None:
            vessel_path = (base_dir / file).resolve()
            if not file:
                p.add("vessel.file", "empty (expected a vessel TOML file path)")
            elif not vessel_path.is_file():
                p.add(
                    "vessel.file",
                    f"no such file {vessel_path} (expected a vessel TOML file; relative paths are relative "
                    f"to the config file's folder; got {show(file)})",
                )
            else:
                try:
                    vessel, source = load_vessel(vessel_path), str(vessel_path)
                except VesselError as exc:
                    p.add("vessel.file", str(exc))
    else:
        p.add(
            "vessel",
            f'missing name or file (expected name = one of {", ".join(builtins)}, or file = "my_ship.toml")',
        )
    ref = v["reference_point_m"]
    reference: tuple[float, float] | None = None
    if ref is not None:
        reference = (ref[0], ref[1])
        if vessel is not None and max(abs(ref[0]), abs(ref[1])) > vessel.length_m:
            p.add(
                "vessel.reference_point_m",
                f"outside the vessel (expected |x|, |y| <= the vessel length {vessel.length_m:g} m, got "
                f"{show(t['reference_point_m'])})",
            )
            reference = None
    return vessel, source, reference


def _read_datum(p: Problems, data: Mapping[str, Any]) -> DatumConfig | None:
    if "datum" not in data:
        return DatumConfig(first_fix=True)
    t = _section(p, data, "datum")
    if t is None:
        return None
    v = read_table(DatumTable, t, "datum", p)
    first_fix, alt, lat, lon = v["first_fix"], v["alt_m"], v["lat_deg"], v["lon_deg"]
    has_lat, has_lon = "lat_deg" in t, "lon_deg" in t
    if first_fix is None or alt is None:
        return None
    if first_fix:
        if has_lat or has_lon or "alt_m" in t:
            p.add(
                "datum",
                "first_fix = true and a fixed point given (expected either lat_deg, lon_deg [, alt_m] or "
                "first_fix = true)",
            )
            return None
        return DatumConfig(first_fix=True)
    if not has_lat or not has_lon:
        missing = " and ".join(k for k, has in (("lat_deg", has_lat), ("lon_deg", has_lon)) if not has)
        both = not has_lat and not has_lon
        p.add(
            "datum" if both else f"datum.{missing}",
            f"missing{' ' + missing if both else ''} (expected lat_deg and lon_deg of the local NED origin, "
            "or first_fix = true)",
        )
        return None
    if lat is None or lon is None:
        return None
    return DatumConfig(lat_deg=lat, lon_deg=lon, alt_m=alt, first_fix=False)


def _check_zenoh_endpoint(endpoint: str, *, listen: bool = False) -> str | None:
    m = re.fullmatch(r"([a-z][a-z0-9-]*)/([^?#]+)([?#].*)?", endpoint)
    if not m:
        return (
            "not a Zenoh endpoint (expected <protocol>/<address>, e.g. tcp/192.168.1.10:7447, "
            f"got {show(endpoint)})"
        )
    proto, address = m.group(1), m.group(2)
    if proto not in ZENOH_PROTOCOLS:
        known = ", ".join(ZENOH_PROTOCOLS)
        return f"unknown Zenoh protocol '{proto}' (expected one of {known}, got {show(endpoint)})"
    if proto in ("tcp", "udp", "tls", "quic"):
        try:
            host, port = split_host_port(address, need_host=False, allow_zero=listen)
        except UrlError as exc:
            example = f"{proto}/HOST:PORT, e.g. {proto}/192.168.1.10:7447"
            return f"{exc.problem} (expected {example}, got {show(endpoint)})"
        if not host:
            return f"no host (expected {proto}/HOST:PORT, e.g. {proto}/0.0.0.0:{port}, got {show(endpoint)})"
    return None


def prefix_problem(prefix: str) -> str | None:
    """Why ``prefix`` cannot be a key prefix (`[zenoh] prefix`, `--prefix`), or None: plain chunks."""
    if prefix.startswith("/") or prefix.endswith("/") or "//" in prefix:
        return (
            "empty chunk in the key expression (expected chunks separated by single '/', no leading or "
            f"trailing '/', e.g. dp/my_ship, got {show(prefix)})"
        )
    bad = "".join(sorted(set(prefix) & set("*$?#")))
    if not bad and any(c.isspace() for c in prefix):
        bad = "whitespace"
    if bad:
        return (
            f"'{bad}' not allowed in a key expression prefix (expected plain chunks such as dp/my_ship, "
            f"got {show(prefix)})"
        )
    return None


def _read_zenoh(
    p: Problems, data: Mapping[str, Any], base_dir: Path, vessel: VesselModel | None
) -> ZenohConfig | None:
    t = _section(p, data, "zenoh")
    if t is None:
        return None
    n0 = len(p)
    d = DEFAULTS["zenoh"]
    v = read_table(ZenohTable, t, "zenoh", p)
    for key in ("connect", "listen"):
        for i, endpoint in enumerate(v[key] or []):
            problem = _check_zenoh_endpoint(endpoint, listen=key == "listen")
            if problem:
                p.add(f"zenoh.{key}[{i}]", problem)
    config_file: Path | None = None
    if v["config_file"]:
        config_file = (base_dir / v["config_file"]).resolve()
        for key in ("mode", "connect", "listen", "multicast_scouting", *_AUTH_KEYS):
            if key in t and t[key] != d[key]:
                p.add(
                    f"zenoh.{key}",
                    f"has no effect when zenoh.config_file is set (expected it in {config_file.name}, or no "
                    "config_file)",
                )
        if not config_file.is_file():
            p.add("zenoh.config_file", f"no such file {config_file} (expected a Zenoh JSON5 config file)")
        else:
            import zenoh  # the library reads its own format; nothing is opened

            try:
                zenoh.Config.from_file(str(config_file))
            except Exception as exc:  # zenoh raises its own ZError
                p.add("zenoh.config_file", f"not a valid Zenoh config: {exc}")
    users, user, password = _read_zenoh_auth(p, t, v, base_dir)
    prefix = v["prefix"]
    if prefix == "" and vessel is not None:
        prefix = f"dp/{vessel.name}"
    if prefix:
        problem = prefix_problem(prefix)
        if problem:
            p.add("zenoh.prefix", problem)
    if len(p) != n0 or prefix is None:
        return None
    return ZenohConfig(
        prefix=prefix,
        mode=v["mode"],
        connect=tuple(v["connect"]),
        listen=tuple(v["listen"]),
        config_file=config_file,
        multicast_scouting=v["multicast_scouting"],
        users_file=users,
        user=user,
        password=password,
        commanders=tuple(v["commanders"]),
    )


_AUTH_KEYS = ("users_file", "user", "password_file", "commanders")


def _read_zenoh_auth(
    p: Problems, t: Mapping[str, Any], v: Mapping[str, Any], base_dir: Path
) -> tuple[Path | None, str, str]:
    """The user/password dictionary, this session's own credentials, and the commanders (who must be
    users of the dictionary: a name that cannot authenticate would lock everyone out of commanding)."""
    users_file: Path | None = None
    users: set[str] | None = None
    if v["users_file"]:
        users_file = (base_dir / v["users_file"]).resolve()
        users = _read_users(p, users_file)
    user, password = v["user"] or "", ""
    if v["password_file"]:
        path = (base_dir / v["password_file"]).resolve()
        try:
            password = path.read_text(encoding="utf-8").strip()
        except OSError as exc:
            p.add("zenoh.password_file", f"cannot read {path}: {exc.strerror or exc} (expected a file)")
        else:
            if not password:
                p.add("zenoh.password_file", f"{path} is empty (expected this session's password)")
    if v["user"] is not None and v["password_file"] is not None and bool(user) != bool(v["password_file"]):
        given, other = ("user", "password_file") if user else ("password_file", "user")
        p.add(f"zenoh.{given}", f"given without zenoh.{other} (expected both, or neither)")
    commanders = v["commanders"] or []
    if commanders and users_file is None and v["users_file"] is not None:
        p.add(
            "zenoh.commanders",
            "needs zenoh.users_file (expected the users' dictionary: a commander is known by the user name "
            "it authenticates with)",
        )
    elif users is not None:
        for i, name in enumerate(commanders):
            if name not in users:
                hint = did_you_mean(name, sorted(users), quote='"')
                p.add(
                    f"zenoh.commanders[{i}]",
                    f"not a user of {users_file}{hint} (expected one of its user names, got {show(name)})",
                )
    return users_file, user, password


def _read_users(p: Problems, path: Path) -> set[str] | None:
    """The user names of a Zenoh ``user:password`` dictionary; a bad line is named by number only (a
    password is never echoed)."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        p.add(
            "zenoh.users_file", f"cannot read {path}: {exc.strerror or exc} (expected a user:password file)"
        )
        return None
    users: set[str] = set()
    bad = 0
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        name, sep, pw = line.partition(":")
        if not sep or not name or not pw:
            p.add("zenoh.users_file", f"{path.name} line {n} is not user:password (expected user:password)")
            bad += 1
            continue
        users.add(name)
    if not users and not bad:
        p.add("zenoh.users_file", f"{path} has no users (expected user:password lines)")
    return users


def _read_log(p: Problems, data: Mapping[str, Any], base_dir: Path) -> LogConfig | None:
    t = _section(p, data, "log")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(LogTable, t, "log", p)
    path: Path | None = None
    if v["path"]:
        # Absolute, but not resolved: a link in the path is the user's (a log folder linked to a data
        # disk; the file itself a link), and the file's name is the one given. Resolved, a log path that
        # was a link was refused as "not an MCAP file name" by its target's name.
        path = Path(os.path.abspath(base_dir / v["path"]))
        if path.suffix != ".mcap":
            p.add(
                "log.path", f"not an MCAP file name (expected a path ending in .mcap, got {show(v['path'])})"
            )
    rotate_mb, rotate_min = v["rotate_mb"], v["rotate_minutes"]
    if rotate_mb is not None and 0 < rotate_mb < 1:
        p.add("log.rotate_mb", f"too small (expected 0 (never) or >= 1 MiB, got {show(t['rotate_mb'])})")
    if rotate_min is not None and 0 < rotate_min < 1:
        p.add(
            "log.rotate_minutes",
            f"too small (expected 0 (never) or >= 1 minute, got {show(t['rotate_minutes'])})",
        )
    if len(p) != n0:
        return None
    return LogConfig(
        path=path,
        rotate_mb=rotate_mb,
        rotate_minutes=rotate_min,
        flush_interval_s=v["flush_interval_s"],
        compression=v["compression"],
    )


def _read_status(p: Problems, data: Mapping[str, Any]) -> StatusConfig | None:
    t = _section(p, data, "status")
    if t is None:
        return None
    rate = read_table(StatusTable, t, "status", p)["rate_hz"]
    return None if rate is None else StatusConfig(rate_hz=rate)


def _read_time(p: Problems, data: Mapping[str, Any]) -> TimeConfig | None:
    t = _section(p, data, "time")
    if t is None:
        return None
    clock = read_table(TimeTable, t, "time", p)["clock"]
    return None if clock is None else TimeConfig(clock=clock)


def with_loop_bandwidth(
    observer: ObserverConfig, control: ControlConfig, vessel: VesselModel
) -> ObserverConfig:
    """``observer`` with the natural frequency of the DP loop its estimate feeds (the controller's
    bandwidth, its Froude-scaled default unless ``[control] bandwidth_rad_s``) as the tuning's
    ``loop_bandwidth``: a ratio-set velocity injection is then held at no slower than the loop
    (`observers.passive_tuning`, "No slower than the loop it feeds"). A controller fed the raw
    measurement (``feedback = "measurement"``) leaves it as it is."""
    if control.feedback != "estimate":
        return observer
    wn = ControllerTuning(bandwidth_rad_s=control.bandwidth_rad_s).resolved(vessel).bandwidth_rad_s
    return replace(observer, tuning=replace(observer.tuning, loop_bandwidth=wn))


def _read_control(p: Problems, data: Mapping[str, Any], vessel: VesselModel | None) -> ControlConfig | None:
    t = _section(p, data, "control")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(ControlTable, t, "control", p)
    ret = v["return_speed_mps"]
    if ret is not None and vessel is not None:
        top = froude_defaults(vessel)["max_speed_mps"]
        if ret > top:
            p.add(
                "control.return_speed_mps",
                f"above the reference model's speed limit (expected at most {top:.3g} m/s for this "
                f"{vessel.length_m:g} m vessel, got {show(t['return_speed_mps'])}): a return may not be "
                "faster than a setpoint move",
            )
    if len(p) != n0:
        return None
    return ControlConfig(
        rate_hz=v["rate_hz"],
        initial_mode=v["initial_mode"],
        wait_for_observer=v["wait_for_observer"],
        allocator=v["allocator"],
        bandwidth_rad_s=v["bandwidth_rad_s"],
        damping=v["damping"],
        feedback=v["feedback"],
        return_speed_mps=ret,
        wind_feedforward_gain=v["wind_feedforward_gain"],
        wind_filter_s=v["wind_filter_s"],
        wind_loss_fade_s=v["wind_loss_fade_s"],
        takeover_fade_s=v["takeover_fade_s"],
    )


def _read_consequence(
    p: Problems, data: Mapping[str, Any], vessel: VesselModel | None
) -> ConsequenceConfig | None:
    t = _section(p, data, "consequence")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(ConsequenceTable, t, "consequence", p)
    groups = v["failure_groups"]
    if groups is not None and vessel is not None:
        ids = {th.id for th in vessel.thrusters}
        for i, g in enumerate(groups):
            unknown = sorted(set(g) - ids)
            if not g or unknown:
                known = ", ".join(str(k) for k in sorted(ids)) or "none"
                what = (
                    "an empty group"
                    if not g
                    else f"no thruster {', '.join(map(str, unknown))} on this vessel"
                )
                p.add(
                    f"consequence.failure_groups[{i}]",
                    f"{what} (expected ids of the vessel's thrusters: {known}; got {show(g)})",
                )
    if len(p) != n0:
        return None
    return ConsequenceConfig(
        enabled=v["enabled"],
        failure_groups=tuple(tuple(g) for g in groups),
        filter_s=v["filter_s"],
    )


def _read_integrity(p: Problems, data: Mapping[str, Any]) -> IntegrityConfig | None:
    t = _section(p, data, "integrity")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(IntegrityTable, t, "integrity", p)
    codes = v["gga_quality"]
    if codes is not None and (not codes or not all(1 <= c <= 9 for c in codes)):
        p.add(
            "integrity.gga_quality",
            f"not GGA quality codes (expected an array of codes from 1 to 9, got {show(t['gga_quality'])})",
        )
    if len(p) != n0:
        return None
    v["gga_quality"] = tuple(codes)
    return IntegrityConfig(**v)


def _read_commands(p: Problems, data: Mapping[str, Any]) -> CommandsConfig | None:
    t = _section(p, data, "commands")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(CommandsTable, t, "commands", p)
    accept = v["accept"]
    for i, key in enumerate(accept or []):
        if key not in COMMAND_INPUTS:
            hint = did_you_mean(str(key), COMMAND_INPUTS, quote='"')
            p.add(
                f"commands.accept[{i}]",
                f'not a command input{hint} (expected "mode", "setpoint" or "tau", got {show(key)})',
            )
    if accept is not None and len(set(accept)) != len(accept):
        p.add("commands.accept", f"an input is repeated (expected each once, got {show(accept)})")
    if len(p) != n0:
        return None
    return CommandsConfig(
        accept=frozenset(accept),
        max_setpoint_distance_m=v["max_setpoint_distance_m"],
        manual_tau_hold_s=v["manual_tau_hold_s"],
    )


_KEY_CHUNKS = re.compile(r"[a-z0-9_]+(/[a-z0-9_]+)*")
"""Keelson's keys are snake_case (its protocol specification); no wildcard, no ``@`` (verbatim) chunk."""


def _read_keelson(p: Problems, data: Mapping[str, Any]) -> KeelsonConfig | None:
    t = _section(p, data, "keelson")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(KeelsonTable, t, "keelson", p)
    for key in ("base_path", *(k for k in v if k.endswith("_source_id"))):
        value = v[key]
        if value is None:
            continue
        probe = value.replace("{source}", "s", 1) if key == "sensor_source_id" else value
        if not _KEY_CHUNKS.fullmatch(probe):
            p.add(
                f"keelson.{key}",
                f"not a Keelson key part (expected {_expected(key)}, got {show(value)})",
            )
        elif key == "sensor_source_id" and "{source}" not in value:
            p.add(
                "keelson.sensor_source_id",
                f'has no "{{source}}" (expected {_expected(key)}, got {show(value)})',
            )
    entity = v["entity_id"]
    if entity is not None:
        if not entity and v["enabled"]:
            p.add(
                "keelson.entity_id",
                'missing (expected one key chunk in snake_case naming the vessel, e.g. "my_ship", when '
                "keelson.enabled = true)",
            )
        elif entity and not re.fullmatch(r"[a-z0-9_]+", entity):
            p.add(
                "keelson.entity_id",
                f"not a Keelson key chunk (expected {_expected('entity_id')}, got {show(entity)})",
            )
    seen: dict[str, str] = {}
    for key in (k for k in v if k.endswith("_source_id") and k != "sensor_source_id"):
        value = v[key]
        if value is None:
            continue
        if value in seen:  # one source id would carry two streams' values on the same keys
            p.add(
                f"keelson.{key}",
                f"the same as keelson.{seen[value]} (expected a source id of its own, got {show(value)})",
            )
        seen.setdefault(value, key)
    if len(p) != n0:
        return None
    return KeelsonConfig(**v)


def _read_foxglove(p: Problems, data: Mapping[str, Any]) -> FoxgloveConfig | None:
    t = _section(p, data, "foxglove")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(FoxgloveTable, t, "foxglove", p)
    host = v["host"]
    if host is not None and not valid_host(host):
        extra = FoxgloveTable.model_fields["host"].json_schema_extra
        expected = extra.get("expected", "") if isinstance(extra, dict) else ""
        p.add("foxglove.host", f"not an address or host name (expected {expected}, got {show(host)})")
    if len(p) != n0:
        return None
    return FoxgloveConfig(**v)


def _expected(key: str) -> str:
    extra = KeelsonTable.model_fields[key].json_schema_extra
    return str(extra.get("expected", "")) if isinstance(extra, dict) else ""


_FRAME_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
"""A tf2 frame id as REP 105 writes them (``map``, ``base_link``): no leading "/" (tf2 refuses one)."""


def _read_ros2(p: Problems, data: Mapping[str, Any]) -> Ros2Config | None:
    t = _section(p, data, "ros2")
    if t is None:
        return None
    n0 = len(p)
    v = read_table(Ros2Table, t, "ros2", p)
    ns = v["namespace"]
    if ns is not None and not is_ros_name(ns, absolute=True):
        p.add(
            "ros2.namespace",
            f"not a ROS 2 namespace (expected {_expected_ros2('namespace')}, got {show(ns)})",
        )
    node = v["node_name"]
    if node is not None and ("/" in node or not is_ros_name(node, absolute=False)):
        p.add(
            "ros2.node_name",
            f"not a ROS 2 node name (expected {_expected_ros2('node_name')}, got {show(node)})",
        )
    for key in ("frame_id", "child_frame_id"):
        value = v[key]
        if value is not None and not _FRAME_ID.fullmatch(value):
            p.add(f"ros2.{key}", f"not a frame id (expected {_expected_ros2(key)}, got {show(value)})")
    if v["frame_id"] is not None and v["frame_id"] == v["child_frame_id"]:
        p.add(
            "ros2.child_frame_id",
            f"the same as ros2.frame_id (expected the vessel's own frame, got {show(v['frame_id'])})",
        )
    seen: dict[str, str] = {}
    for key in ("odom_topic", "pose_topic", "fix_topic", "setpoint_topic"):
        value = v[key]
        if value is None:
            continue
        name = value[1:] if value.startswith("/") else value
        if not name or not is_ros_name(name, absolute=False):
            p.add(
                f"ros2.{key}", f"not a ROS 2 topic name (expected {_expected_ros2(key)}, got {show(value)})"
            )
            continue
        full = fully_qualified(ns or "/", value)
        if full in seen:
            p.add(
                f"ros2.{key}",
                f"the same topic as ros2.{seen[full]} (expected a topic of its own, got {show(value)})",
            )
        seen.setdefault(full, key)
    if len(p) != n0:
        return None
    return Ros2Config(**v)


def _expected_ros2(key: str) -> str:
    extra = Ros2Table.model_fields[key].json_schema_extra
    return str(extra.get("expected", "")) if isinstance(extra, dict) else ""
