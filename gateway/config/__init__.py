"""The gateway's TOML configuration (``dpgw run --config FILE``): read, check, and turn into typed values.

One file per vessel or bench (``docs/config.md`` lists every key; ``examples/`` has working files).
Loading either returns a complete, validated, frozen `GatewayConfig` or raises one `ConfigError` whose
message lists **every** problem found, each as ``FILE: key.path: what is wrong (expected …, got …)``.
Unknown keys are errors with a "did you mean" suggestion, so a typo is never silently ignored.
``dpgw run --config FILE --check`` is the command that checks a file.

One module per concern: `model` (the typed result), `defaults` (the embedded defaults), `schema` (the
file's shape, validated with pydantic), `load` (TOML → model, the checks across keys),
`source_entries` and `observer_section` (the two tables with the most rules), `problems` (the message
format), `summary` (the check command's summary). The config sits below the gateway's sources, bus and
service: it opens nothing and imports none of them.
"""

from gateway.config.defaults import default_config
from gateway.config.load import load_config, parse_config
from gateway.config.model import (
    BAUD_RATES,
    COMPRESSIONS,
    OBSERVER_TYPES,
    PROTOCOLS,
    ROLES,
    ArdupilotMap,
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
    SourceConfig,
    StatusConfig,
    TimeConfig,
    ZenohConfig,
)
from gateway.config.problems import ConfigError, format_problems
from gateway.config.summary import (
    config_notes,
    describe,
    enabled_lines,
    start_mode_line,
    wind_feedforward_line,
    wind_feedforward_off,
)

__all__ = [
    "BAUD_RATES",
    "COMPRESSIONS",
    "OBSERVER_TYPES",
    "PROTOCOLS",
    "ROLES",
    "ArdupilotMap",
    "CommandsConfig",
    "ConfigError",
    "ConsequenceConfig",
    "ControlConfig",
    "DatumConfig",
    "FoxgloveConfig",
    "GatewayConfig",
    "IntegrityConfig",
    "KeelsonConfig",
    "LogConfig",
    "ObserverConfig",
    "Ros2Config",
    "SourceConfig",
    "StatusConfig",
    "TimeConfig",
    "ZenohConfig",
    "config_notes",
    "default_config",
    "describe",
    "enabled_lines",
    "format_problems",
    "load_config",
    "parse_config",
    "start_mode_line",
    "wind_feedforward_line",
    "wind_feedforward_off",
]
