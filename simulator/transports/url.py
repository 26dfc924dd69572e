"""From a sink URL (or a plain file path) to the `Sink` it names, opened: `open_sink`.

The URL forms are listed in the package docstring and in ``docs/transports.md``.
"""

from __future__ import annotations

import math

from simulator.transports.base import Sink, TransportError
from simulator.transports.file import FileSink
from simulator.transports.pty import PtySink
from simulator.transports.serial import SerialSink
from simulator.transports.tcp import TcpServerSink
from simulator.transports.udp import UdpSink
from wire.urls import SINK_OPTIONS, Endpoint, UrlError, parse_url, serial_settings, split_host_port

#: The URL forms `open_sink` understands, for error messages.
URL_FORMS = (
    "pty, pty:///PATH/TO/LINK, udp://HOST:PORT[?bind=HOST:PORT&iface=I&tag_source=S], "
    "tcp-listen://HOST:PORT, serial:///dev/DEVICE[?baud=4800], file:///PATH or a plain file path"
)


def _number(url: str, key: str, value: str) -> float:
    try:
        x = float(value)
    except ValueError:
        x = math.nan
    if not (math.isfinite(x) and x > 0):
        raise TransportError(url, f"option {key}={value!r} is not a positive number")
    return x


def open_sink(url: str) -> Sink:
    """Open the sink a URL names (see the module docstring and ``docs/transports.md``).

    Raises `TransportError` (message: the URL, the problem, what to do) when it cannot work.
    """
    text = url.strip()
    if not text:
        raise TransportError(repr(url), "empty transport", f"give one of: {URL_FORMS}")
    try:
        ep = parse_url(text, options=SINK_OPTIONS, bare_path="file")
        return _sink_for(url, ep)
    except UrlError as exc:
        raise TransportError(url, exc.problem, f"expected {exc.expected}" if exc.expected else "") from None


def _sink_for(url: str, ep: Endpoint) -> Sink:
    """The sink for a parsed URL (`wire.urls`: the one URL grammar); option values checked here."""
    if ep.scheme == "pty":
        stale: float | None = 2.0
        raw = ep.option("stale_s")
        if raw is not None:
            stale = None if raw.lower() in ("none", "off", "inf") else _number(url, "stale_s", raw)
        return PtySink(ep.path or None, stale_s=stale, url=url)
    if ep.scheme == "file":
        return FileSink(ep.path, url=url)
    if ep.scheme == "serial":
        return SerialSink(ep.path, serial_settings(ep).baud, url=url)
    port = ep.port or 0
    if ep.scheme == "udp":
        if not ep.host:
            raise TransportError(url, "no destination host", "e.g. udp://127.0.0.1:10110")
        bind_text = ep.option("bind")
        bind = split_host_port(bind_text, need_host=False, allow_zero=True) if bind_text else None
        if bind is not None and not bind[0]:
            bind = ("0.0.0.0", bind[1])
        return UdpSink(
            ep.host, port, bind=bind, iface=ep.option("iface"), tag_source=ep.option("tag_source"), url=url
        )
    max_backlog = 262_144
    backlog_text = ep.option("max_backlog")
    if backlog_text is not None:
        if not backlog_text.isdigit():
            raise TransportError(url, f"max_backlog {backlog_text!r} is not a whole number of bytes")
        max_backlog = int(backlog_text)
    return TcpServerSink(ep.host or "0.0.0.0", port, max_backlog=max_backlog, url=url)
