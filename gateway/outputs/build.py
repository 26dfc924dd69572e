"""The extra output sinks a config asks for (``dpgw run``): one block per sink, each imported only when
its table enables it, so an optional package that is not installed costs nothing until it is asked for."""

from __future__ import annotations

import importlib.util

from gateway.config import GatewayConfig
from gateway.outputs.base import OutputSink
from gateway.outputs.ros2_topics import prefix_in_domain, topic_clashes
from wire.rmw_zenoh import is_ros_name

__all__ = ["OutputError", "output_problems", "sinks_from_config"]


class OutputError(Exception):
    """An enabled sink cannot be built (its package is missing, its topics clash); each of ``problems`` is
    a ``FILE: key: problem`` line, and the message is them all."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = problems


def output_problems(config: GatewayConfig, where: str | None = None) -> list[str]:
    """What would stop `sinks_from_config`, as ``FILE: key: problem`` lines (``dpgw run --check``); FILE is
    ``where`` (the config as the user named it), or its absolute path."""
    where = where or str(config.path)
    problems = []
    if config.keelson.enabled and importlib.util.find_spec("keelson") is None:
        problems.append(
            f"{where}: keelson.enabled: true, but the keelson package is not installed (install it "
            "with pip install 'dpgw[keelson]', or set keelson.enabled = false)"
        )
    if config.ros2.enabled:
        missing = [m for m in ("rosbags", "xxhash") if importlib.util.find_spec(m) is None]
        if missing:
            problems.append(
                f"{where}: ros2.enabled: true, but {' and '.join(missing)} "
                f"{'is' if len(missing) == 1 else 'are'} not installed (install with pip install "
                "'dpgw[ros2]', or set ros2.enabled = false)"
            )
        for s in config.sources_for("position"):
            if not is_ros_name(s.name, absolute=False):
                problems.append(
                    f"{where}: sources: {s.name}: not a ROS 2 name token, so ros2.fix_topic/{s.name} "
                    "is no topic (expected a source name not starting with a digit, or ros2.enabled = false)"
                )
            for key in ("frame_id", "child_frame_id"):
                if s.name == getattr(config.ros2, key):
                    problems.append(
                        f"{where}: sources: {s.name}: also ros2.{key}, so its antenna frame on "
                        "/tf_static would be a child of itself (expected another source name, or another "
                        f"ros2.{key})"
                    )
        problems += topic_clashes(config)
        problems += prefix_in_domain(config)
    if config.foxglove.enabled and importlib.util.find_spec("foxglove") is None:  # a core dependency
        problems.append(
            f"{where}: foxglove.enabled: true, but the foxglove-sdk package is not installed (install "
            "it with pip install foxglove-sdk, or set foxglove.enabled = false)"
        )
    return problems


def sinks_from_config(config: GatewayConfig) -> list[OutputSink]:
    """The sinks the config enables, not yet started (`GatewayService` starts and closes them)."""
    problems = output_problems(config)
    if problems:
        raise OutputError(problems)
    sinks: list[OutputSink] = []
    if config.keelson.enabled:
        from gateway.outputs.keelson import keelson_sink

        sinks.append(keelson_sink(config))
    if config.ros2.enabled:
        from gateway.outputs.ros2 import ros2_sink

        sinks.append(ros2_sink(config))
    if config.foxglove.enabled:
        from gateway.outputs.foxglove_server import foxglove_sink

        sinks.append(foxglove_sink(config))
    return sinks
