"""A short human summary of a loaded configuration (``dpgw run --config FILE --check``)."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from gateway.config.endpoints import is_loopback
from gateway.config.model import ControlConfig, GatewayConfig
from observers.vessel import VesselModel

__all__ = [
    "config_notes",
    "describe",
    "enabled_lines",
    "start_mode_line",
    "wind_feedforward_line",
    "wind_feedforward_off",
]


def describe(config: GatewayConfig) -> str:
    """A short human summary of a loaded configuration."""
    lines = [
        f"config {config.path}: ok",
        f"  vessel {config.vessel.name} ({config.vessel_source}), "
        f"reference point {list(config.reference_point_m)} m",
        "  datum: first valid fix"
        if config.datum.first_fix
        else f"  datum: {config.datum.lat_deg:.6f}°, {config.datum.lon_deg:.6f}°, {config.datum.alt_m:g} m",
    ]
    for s in config.sources:
        device = f", the device {s.tag_source} (TAG blocks)" if s.tag_source else ""
        lines.append(
            f"  source {s.name}: {s.protocol} {'/'.join(s.roles)} priority {s.priority} <- {s.url}{device}"
        )
    obs = config.observer
    lines.append(
        f"  observer {obs.type} (a step at every position and heading), "
        f"ω0 = {show_dof(obs.tuning.omega0)} rad/s"
        + ("" if not config.observer.failed_checks else " (UNCHECKED: tuning checks fail)")
    )
    z = config.zenoh
    lines.append(
        f"  zenoh {z.mode} prefix {z.prefix}"
        + (f", config file {z.config_file}" if z.config_file else "")
        + (f", connect {list(z.connect)}" if z.connect else "")
        + (f", listen {list(z.listen)}" if z.listen else "")
    )
    line = start_mode_line(config)
    if line:
        lines.append(f"  {line}")
    line = wind_feedforward_line(config)
    if line:
        lines.append(f"  {line}")
    line = consequence_line(config)
    if line:
        lines.append(f"  {line}")
    lines.append(f"  log {config.log.path}" if config.log.enabled else "  log disabled")
    lines += [f"  {line}" for line in enabled_lines(config)]
    if config.time.sim:
        lines.append(f"  clock: simulation time from {z.prefix}/sim/clock (not this computer's)")
    return "\n".join(lines)


def config_notes(config: GatewayConfig) -> list[str]:
    """What the config allows but an engineer should know (``--check`` prints them, start-up logs them):
    an ArduPilot ESC wired to a thruster that reverses, without ``esc_direction_servo`` for it.
    ``ESC_TELEMETRY`` carries rpm unsigned, so that thruster's feedback is taken as thrust ahead even while
    it runs astern (a tunnel pushing to port, a skid-steering motor in reverse), and τ for the observer has
    the wrong sign for it then. With its motor output named, the sign comes from that output's pulse."""
    notes = []
    thrusters = {t.id: t for t in config.vessel.thrusters}
    for sc in config.sources:
        if sc.ardupilot is None:
            continue
        for esc, tid in sorted(sc.ardupilot.esc.items()):
            th = thrusters.get(tid)
            if th is not None and th.min_thrust_n < 0 and esc not in sc.ardupilot.esc_direction_servo:
                notes.append(
                    f"sources.{sc.name}.ardupilot.esc: ESC {esc} reports thruster {tid}, which reverses "
                    f"(min_thrust_n {th.min_thrust_n:g} N), but ESC telemetry rpm has no sign: its thrust "
                    f"is taken as ahead also when it runs astern (name its motor output in "
                    f"sources.{sc.name}.ardupilot.esc_direction_servo, e.g. {{{esc} = channel}})"
                )
    keyed = [sc.name for sc in config.sources if sc.signing_key is not None]
    if keyed and (note := key_file_note(config.path, keyed)):
        notes.append(note)
    if note := open_commands_note(config, network_only=True):
        notes.append(note)
    return notes


def open_commands_note(config: GatewayConfig, *, network_only: bool = False) -> str | None:
    """Commands accepted with no one named to give them: without ``[zenoh] commanders`` Zenoh lets every
    peer that reaches the session put on the command keys, so whoever reaches it may engage DP, move the
    setpoint or push the thrusters. Fine on a bench on this computer, not what a vessel wants on its
    LAN; the note says who can reach it (the listeners, a router) and how to name the commanders. A
    ``config_file`` sets its own access control, which this does not read: no note then.
    ``network_only``: none for a session reached from this computer only (loopback: the network layer's
    default, docs/security.md), which start-up does not warn of (`dpgw demo` takes its operator's
    commands so); ``--check`` says it either way."""
    z = config.zenoh
    accepted = sorted(config.commands.accept)
    if not accepted or z.commanders or z.config_file is not None:
        return None
    wide = [f"listen {e}" for e in z.listen if not is_loopback(e)]
    wide += [f"connect {e}" for e in z.connect if not is_loopback(e)]
    if wide:
        reach = "anyone on the network that reaches " + ", ".join(wide)
    elif network_only:
        return None
    else:
        reach = "any user or program on this computer (it listens on loopback only)"
    return (
        f"commands.accept = {accepted}: with no zenoh.commanders, every Zenoh peer that reaches this "
        f"session may command the vessel: {reach}. To let only named users command, give "
        "zenoh.users_file and zenoh.commanders (docs/security.md)"
    )


def key_file_note(path: Path | None, keyed: list[str]) -> str | None:
    """A config holding a MAVLink signing key that every user of this computer may read: whoever reads
    the key can sign thruster commands the drives obey (a log never holds it for that reason). ``0640``,
    group the service's, is what the service needs (examples/README.md)."""
    try:
        mode = os.stat(path).st_mode if path is not None else 0
    except OSError:
        return None
    if not mode & stat.S_IROTH:
        return None
    where = ", ".join(f"sources.{name}.signing_key" for name in keyed)
    return (
        f"{where}: {path} is readable by every user of this computer (mode {stat.S_IMODE(mode):04o}), and "
        "whoever reads the key can sign thruster commands: sudo chmod 640 and sudo chgrp to the "
        "service's group (dpgw)"
    )


def enabled_lines(config: GatewayConfig, *, foxglove: bool = True) -> list[str]:
    """One short line for each of what is on beyond the core (``[foxglove]``, ``[keelson]``, ``[ros2]``,
    Zenoh authentication and its commanders, the log's rotation), none for what is off. ``foxglove``
    False: left to the server's own lines (`dpgw run` prints its address as bound)."""
    lines = []
    fx = config.foxglove
    if foxglove and fx.enabled:
        lines.append(f"foxglove live server on {fx.host}:{fx.port or '(any free port)'}")
    k = config.keelson
    if k.enabled:
        lines.append(f"keelson under {k.base_path}/@v0/{k.entity_id}/pubsub/…")
    r = config.ros2
    if r.enabled:
        lines.append(f"ros2 (rmw_zenoh) domain {r.domain_id}, node {r.namespace.rstrip('/')}/{r.node_name}")
    z = config.zenoh
    if z.users_file is not None:
        who = (
            f"commands only from {', '.join(z.commanders)}"
            if z.commanders
            else "commands from any authenticated peer (no commanders)"
        )
        lines.append(f"zenoh authentication: users of {z.users_file}; {who}")
    if z.user:
        lines.append(f"zenoh: this session authenticates as user {z.user}")
    lg = config.log
    if lg.enabled and (lg.rotate_mb > 0 or lg.rotate_minutes > 0):
        limits = [f"{lg.rotate_mb:g} MB"] * (lg.rotate_mb > 0) + [f"{lg.rotate_minutes:g} min"] * (
            lg.rotate_minutes > 0
        )
        lines.append(
            f"log rotated at {' or '.join(limits)}" + (", whichever first" if len(limits) > 1 else "")
        )
    return lines


def start_mode_line(config: GatewayConfig) -> str:
    """The mode the controller starts in, in one line ("" without a controller): with ``initial_mode =
    "dp"``, whether it waits for the observer to settle (``wait_for_observer``) or engages at once."""
    cc = config.control
    if cc is None:
        return ""
    if cc.initial_mode != "dp":
        return f"control: starts in {cc.initial_mode}"
    if cc.wait_for_observer:
        return "control: starts in standby, DP by itself once the observer has settled (wait_for_observer)"
    return "control: DP from the first estimate (wait_for_observer = false: a cold start)"


def consequence_line(config: GatewayConfig) -> str:
    """The consequence analysis in one line ("" when the vessel has fewer than two thrusters): off, or the
    failure cases it tests in DP."""
    if len(config.vessel.thrusters) < 2:
        return ""
    q = config.consequence
    if not q.enabled:
        return "consequence analysis off (consequence.enabled = false)"
    if not q.failure_groups:
        return "consequence analysis in dp: each thruster lost alone"
    # (imported here: the analysis brings the LP solvers, which a config's loading does not need)
    from gateway.control.consequence import failure_cases

    groups = ", ".join("+".join(str(i) for i in g) for g in q.failure_groups)
    # the cases after the groups: each thruster in no group, lost alone
    cases = failure_cases([t.id for t in config.vessel.thrusters], q.failure_groups)
    alone = ", ".join(str(c[0]) for c in cases[len(q.failure_groups) :])
    return f"consequence analysis in dp: thrusters {groups} lost together" + (
        f"; {alone} alone" if alone else ""
    )


def show_dof(value: Any) -> str:
    if isinstance(value, tuple | list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"


def wind_feedforward_off(control: ControlConfig, vessel: VesselModel, roles: Iterable[Iterable[str]]) -> str:
    """Why the controller can have no wind feed-forward ("" if it can): a gain of 0, a vessel without wind
    areas (``[hull.wind]``), or no source with role ``wind`` (``roles``: each source's roles). Said once at
    start-up (`config_notes`) and in the pipeline's first status."""
    if control.wind_feedforward_gain == 0:
        return "control.wind_feedforward_gain = 0"
    if vessel.hull is None or vessel.hull.wind is None:
        return f"vessel '{vessel.name}' has no wind areas ([hull.wind], docs/vessels.md)"
    if not any("wind" in r for r in roles):
        return 'no source has role "wind" (an anemometer sending MWV)'
    return ""


def wind_feedforward_line(config: GatewayConfig) -> str:
    """The controller's wind feed-forward in one line ("" without a controller): on, from which sources,
    with its gain and filter, or off and why. `describe` shows it and the gateway logs it at start-up."""
    cc = config.control
    if cc is None:
        return ""
    why = wind_feedforward_off(cc, config.vessel, (s.roles for s in config.sources))
    if why:
        return f"wind feed-forward off: {why}"
    names = ", ".join(s.name for s in config.sources if "wind" in s.roles)
    return (
        f"wind feed-forward on: from {names}, gain {cc.wind_feedforward_gain:g}, "
        f"filter {cc.wind_filter_s:g} s"
    )
