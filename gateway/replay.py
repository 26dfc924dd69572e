"""Replay: the gateway's own MCAP log back through the same pipeline (DESIGN.md rule 1).

The live service logs every raw chunk (`/raw/nmea/<source>`, `/raw/mavlink/<source>`) with its receive time
as `log_time`, and every Zenoh input (`/dp/setpoint`, `/dp/mode`, `/dp/tau`), and the configuration it ran
with (metadata `dpgw.config`). Feeding those events, in log-time order, to a `Pipeline` built from that
configuration reproduces the live estimates bit for bit. (`dpgw replay` with other observers, raw NMEA
text logs and tlogs, reports and plots is built on this.)
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from gateway.config import GatewayConfig, parse_config
from gateway.mcaplog import read_messages
from gateway.pipeline import ControlEvent, Output, Pipeline, PipelineSpec, RawEvent

CONFIG_METADATA = "dpgw.config"


def logged_config(path: str | Path) -> dict[str, Any] | None:
    """The configuration (as the TOML tables) a live run stored in its log, if any."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        try:
            for record in reader.iter_metadata():
                if record.name == CONFIG_METADATA and "json" in record.metadata:
                    data: dict[str, Any] = json.loads(record.metadata["json"])
                    return data
        except Exception:  # a truncated file has no metadata index: fall through
            return None
    return None


def events(path: str | Path) -> Iterator[RawEvent | ControlEvent]:
    """Input events of a gateway log in log-time order (the order the live consumer saw them)."""
    for topic, log_ns, _pub_ns, payload in read_messages(path):
        if topic.startswith("/raw/nmea/"):
            data = base64.b64decode(payload["data"]) if "data" in payload else payload["text"].encode("ascii")
            # the writer strips the final line terminator of a chunk; put one back for the framer
            yield RawEvent(log_ns, topic[len("/raw/nmea/") :], data + b"\r\n")
        elif topic.startswith("/raw/mavlink/"):
            yield RawEvent(log_ns, topic[len("/raw/mavlink/") :], base64.b64decode(payload["data"]))
        elif topic in ("/dp/setpoint", "/dp/mode", "/dp/tau"):
            key = topic[len("/dp/") :]
            value = payload.get(key, payload) if key == "mode" else payload
            yield ControlEvent(log_ns, key, value)


def replay(config: GatewayConfig, path: str | Path) -> list[Output]:
    """Every output the pipeline gives for the logged events (status excluded: it is clock driven)."""
    pipeline = Pipeline(PipelineSpec.from_config(config))
    out: list[Output] = []
    for ev in events(path):
        out.extend(pipeline.feed(ev))
    return out


def config_from_log(path: str | Path, base_dir: Path | None = None) -> GatewayConfig:
    data = logged_config(path)
    if data is None:
        raise ValueError(f"{path}: no dpgw configuration in the log's metadata (give --config)")
    return parse_config(data, base_dir=base_dir or Path(path).resolve().parent, where=f"{path} metadata")
