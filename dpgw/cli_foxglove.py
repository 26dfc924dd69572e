"""The ``--foxglove [HOST:]PORT`` option of ``dpgw run``, ``demo`` and ``replay``, and what they print.

Light on purpose (standard library only at import): every command's parser is built at start-up, also for
``--help``; the address is checked (`wire.urls.listen_address`) only when the option is given.
"""

from __future__ import annotations

import argparse
from typing import Any

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
LAYOUT = "foxglove-layout.json"
"""The layout to import in the app (its panels name the channels the gateway publishes), shipped in this
package so that an installed dpgw can point at it; `layout_path` gives its full path."""


def layout_path() -> str:
    """The full path of the shipped Foxglove layout (what the demo tells the user to import)."""
    from pathlib import Path

    return str(Path(__file__).resolve().parent / LAYOUT)


class _FromConfig:
    def __repr__(self) -> str:
        return "FROM_CONFIG"


FROM_CONFIG = _FromConfig()
"""``--foxglove`` without a value on ``dpgw run``: the config's ``[foxglove]`` host and port. Not a string:
argparse passes a string ``const`` through the option's ``type`` (`address`), which refused it, so that
``dpgw run --config FILE --foxglove`` stopped with "'config' is not [HOST:]PORT"."""


def address(text: str) -> tuple[str, int]:
    """argparse ``type``: ``[HOST:]PORT`` → (host, port); a bare port listens on 127.0.0.1."""
    from wire.urls import UrlError, listen_address

    try:
        return listen_address(
            text, DEFAULT_HOST, "e.g. 8765, 127.0.0.1:8765 or 0.0.0.0:8765 (0: any free port)"
        )
    except UrlError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_foxglove_arg(p: Any, *, what: str, on_by_default: bool = False, bare: Any = None) -> None:
    """``--foxglove [HOST:]PORT`` (and ``--no-foxglove`` where it is on by default)."""
    default = f"on by default at {DEFAULT_HOST}:{DEFAULT_PORT}" if on_by_default else "off by default"
    p.add_argument(
        "--foxglove",
        nargs="?",
        type=address,
        const=bare if bare is not None else (DEFAULT_HOST, DEFAULT_PORT),
        default=None,
        metavar="[HOST:]PORT",
        help=f"serve {what} live to the Foxglove app over WebSocket ({default}; a bare PORT listens on "
        f"{DEFAULT_HOST}, this computer only; 0.0.0.0:PORT on every interface: no authentication, see "
        "docs/foxglove.md)",
    )
    if on_by_default:
        p.add_argument("--no-foxglove", action="store_true", help="no Foxglove server")


def connect_lines(url: str, app_url: str | None, *, note: str = "") -> list[str]:
    """How to open the server in Foxglove: the WebSocket URL, the app link, the layout."""
    lines = [f"Foxglove live: {url}{note} (in the app: Open connection → Foxglove WebSocket)"]
    if app_url:
        lines.append(f"  in the browser: {app_url}")
    lines.append(f"  panels: import the layout {layout_path()}")
    return lines
