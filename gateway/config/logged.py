"""The config tables as a log keeps them: without the secrets written in them.

A gateway log carries the config it ran with (MCAP metadata ``dpgw.config``) so that ``dpgw replay``
rebuilds the same pipeline. A log is shared, copied and attached to reports: a MAVLink ``signing_key``
in it would let anyone who reads the log drive the vessel's thrusters. So the key is replaced by
`KEY_NOT_LOGGED` (`for_log`), and a replay rebuilds the source without a key (`without_unlogged_keys`):
replay commands no thrusters. In place of checking signatures, the replay applies the live gateway's
verdicts, which the log records (`SIGNING_VERDICTS_KEY`); a log from before has none, and its frames are
replayed with their signatures unchecked (docs/gateway.md, "Replay of a signed link").

It also writes out a default the replay must not take from its own version: ``[control]
wait_for_observer`` with ``initial_mode = "dp"`` (a gateway from before the wait engaged DP from the first
estimate, and a replay of its log must too: `gateway.replay`), so a log records which it was.
"""

from __future__ import annotations

from typing import Any

from gateway.config.defaults import DEFAULTS

KEY_NOT_LOGGED = "not logged"
"""What a log's config holds in place of a source's ``signing_key``."""

SIGNING_VERDICTS_KEY = "signing_verdicts"
"""Key of the log's config record (MCAP metadata ``dpgw.config``) saying that the log records the live
gateway's verdict on every frame of a signed link it refused for signing (`/raw/mavlink_rejected/<source>`,
none for accepted frames), so that a replay without the key refuses the same frames. A log without it was
written before gateways recorded them."""


def for_log(tables: dict[str, Any], *, takeover_fade_s: float | None = None) -> dict[str, Any]:
    """A copy of the config tables with every source's ``signing_key`` replaced by `KEY_NOT_LOGGED`,
    ``[control] wait_for_observer`` written out (its default where not given) with ``initial_mode = "dp"``,
    ``[control] takeover_fade_s`` written out (``takeover_fade_s``, the controller's resolved value, where
    the tables do not give it: a number, so the logged config stays one TOML can write), and a ``[commands]``
    table always, with ``accept`` and ``manual_tau_hold_s`` written out (their defaults where not given):
    a replay then knows the log is from a gateway with the command rules, the manual τ's dead-man and
    the takeover fade. `gateway.replay` replays a log without the table, or without the hold, as
    such a gateway ran (every input taken; the τ held until the next one) — so a gateway configured
    without the table, which took no input, must not log it without one, or its replay would obey the
    inputs it refused."""
    commands = tables.get("commands", {})
    if isinstance(commands, dict):  # (anything else is the config check's to refuse)
        d = DEFAULTS["commands"]
        written = {"accept": list(d["accept"]), "manual_tau_hold_s": d["manual_tau_hold_s"]}
        tables = {**tables, "commands": {**written, **commands}}
    control = tables.get("control", {})
    if isinstance(control, dict) and "takeover_fade_s" not in control and takeover_fade_s is not None:
        # written out: a replay tells a log of a gateway with the takeover fade from one of before it,
        # which it replays with none (`gateway.replay`)
        tables = {**tables, "control": {**control, "takeover_fade_s": takeover_fade_s}}
        control = tables["control"]
    waits = DEFAULTS["control"]["wait_for_observer"]
    if (
        isinstance(control, dict)
        and control.get("initial_mode") == "dp"
        and "wait_for_observer" not in control
    ):
        tables = {**tables, "control": {**control, "wait_for_observer": waits}}
    sources = tables.get("sources")
    if not isinstance(sources, list):
        return tables
    return {
        **tables,
        "sources": [
            {**src, "signing_key": KEY_NOT_LOGGED} if isinstance(src, dict) and "signing_key" in src else src
            for src in sources
        ],
    }


def unlogged_key_sources(tables: dict[str, Any]) -> list[str]:
    """The names of the sources whose signing key a log's config left out."""
    return [
        str(src.get("name"))
        for src in tables.get("sources", []) or []
        if isinstance(src, dict) and src.get("signing_key") == KEY_NOT_LOGGED
    ]


def without_unlogged_keys(tables: dict[str, Any]) -> dict[str, Any]:
    """A log's config tables made loadable again: a source whose key was not logged loses it, with what
    only made sense with it or with a live link: ``allow_unsigned`` (the frames are taken without a key
    anyway) and ``commands`` (a replay commands no thrusters; without a key the config would refuse it)."""
    sources = tables.get("sources")
    if not isinstance(sources, list):
        return tables
    dropped = {"signing_key", "allow_unsigned", "commands"}
    return {
        **tables,
        "sources": [
            {k: v for k, v in src.items() if k not in dropped}
            if isinstance(src, dict) and src.get("signing_key") == KEY_NOT_LOGGED
            else src
            for src in sources
        ],
    }
