"""The embedded defaults: one place that the config schema and `default_config` (``dpgw demo``) both read."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

from gateway.config.model import FoxgloveConfig, IntegrityConfig, KeelsonConfig, Ros2Config
from observers.passive_tuning import PassiveTuning
from observers.vessel import builtin_vessels

DEFAULT_TUNING = PassiveTuning()
DEFAULTS: dict[str, dict[str, Any]] = {
    "vessel": {"reference_point_m": [0.0, 0.0]},
    "datum": {"alt_m": 0.0, "first_fix": False},
    "source": {
        "lever_arm_m": [0.0, 0.0, 0.0],
        "timeout_s": 2.0,
        "allow_missing_checksum": False,
        "priority": 1,
        "allow_unsigned": False,
    },
    "observer": {
        "type": "passive",
        "wave_period_s": 7.0,
        "zeta": DEFAULT_TUNING.zeta,
        "zeta_n": DEFAULT_TUNING.zeta_n,
        "cutoff_ratio": DEFAULT_TUNING.cutoff_ratio,
        "bias_time_constant_s": DEFAULT_TUNING.bias_time_constant_s,
        "velocity_injection_ratio": DEFAULT_TUNING.velocity_injection_ratio,
        "injection_damping_ratio": DEFAULT_TUNING.injection_damping_ratio,
        "bias_corner_ratio": DEFAULT_TUNING.bias_corner_ratio,
        "allow_unchecked": False,
        "rate_hz": 10.0,
    },
    "zenoh": {
        "mode": "peer",
        "connect": [],
        "listen": ["tcp/127.0.0.1:0"],
        "config_file": "",
        "prefix": "",
        "multicast_scouting": True,
        "users_file": "",
        "user": "",
        "password_file": "",
        "commanders": [],
    },
    "commands": {"accept": [], "max_setpoint_distance_m": 50.0, "manual_tau_hold_s": 2.0},
    "log": {
        "path": "logs/dpgw.mcap",
        "rotate_mb": 1024,
        "rotate_minutes": 60,
        "flush_interval_s": 1.0,
        "compression": "zstd",
    },
    "status": {"rate_hz": 1.0},
    "time": {"clock": "wall"},
    "keelson": asdict(KeelsonConfig()),
    "ros2": asdict(Ros2Config()),
    "foxglove": asdict(FoxgloveConfig()),
    "control": {
        "rate_hz": 10.0,
        "initial_mode": "standby",
        "wait_for_observer": True,
        "allocator": "qp",
        "damping": 1.0,
        "feedback": "estimate",
        "wind_feedforward_gain": 1.0,
        "wind_filter_s": 2.0,
    },
    "consequence": {"enabled": True, "failure_groups": [], "filter_s": 30.0},
    "integrity": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(IntegrityConfig()).items()},
}


def default_config(vessel: str = "mss_supply") -> dict[str, Any]:
    """The embedded defaults as a config dict (what `dpgw demo` starts from); ``sources`` is left empty.

    ``vessel`` is a built-in vessel name or a vessel file path. Fill in ``sources`` and pass the dict to
    `parse_config`.
    """
    # A word that is no built-in is a misspelt name, not a file: the check then lists the built-in names.
    is_file = vessel not in builtin_vessels() and (
        "/" in vessel or vessel.endswith(".toml") or Path(vessel).is_file()
    )
    vessel_table: dict[str, Any] = {"file": vessel} if is_file else {"name": vessel}
    vessel_table.update(copy_table(DEFAULTS["vessel"]))
    return {
        "vessel": vessel_table,
        "datum": {"first_fix": True},
        "sources": [],
        # The tuning's defaults depend on the vessel (a model's are Froude-scaled: PassiveTuning.for_vessel);
        # a key written here would count as given, so the parser fills them in for the vessel.
        "observer": {k: v for k, v in DEFAULTS["observer"].items() if k not in TUNING_DEFAULT_KEYS},
        "zenoh": copy_table(DEFAULTS["zenoh"]),
        "log": copy_table(DEFAULTS["log"]),
        "status": copy_table(DEFAULTS["status"]),
    }


TUNING_DEFAULT_KEYS = frozenset(PassiveTuning.__dataclass_fields__) | {"wave_period_s"}
"""The keys of ``DEFAULTS["observer"]`` that are the passive tuning's (a ship's values; `default_config`
leaves them out)."""


def copy_table(table: dict[str, Any]) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, list) else v for k, v in table.items()}
