"""From a sink URL (or a plain file path) to the `Sink` it names, opened: `open_sink`.

The URL forms are listed in the package docstring and in ``docs/transports.md``.
"""

from __future__ import annotations

import math
import re
from urllib.parse import parse_qs, unquote, urlsplit

from simulator.transports.base import Sink, TransportError
from simulator.transports.file import FileSink
from simulator.transports.pty import PtySink
from simulator.transports.serial import SerialSink
from simulator.transports.tcp import TcpServerSink
from simulator.transports.udp import UdpSink

#: The URL forms `open_sink` understands, for error messages.
URL_FORMS = (
    "pty, pty:///PATH/TO/LINK, udp://HOST:PORT[?bind=HOST:PORT], tcp://HOST:PORT, "
    "serial:///dev/DEVICE[?baud=4800], file:///PATH or a plain file path"
)


_SCHEMES = ("pty", "udp", "tcp", "serial", "file")
_OPTIONS = {"pty": ("stale_s",), "udp": ("bind",), "tcp": ("max_backlog",), "serial": ("baud",), "file": ()}


def _options(url: str, scheme: str, query: str) -> dict[str, str]:
    try:
        parsed = parse_qs(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError as exc:
        raise TransportError(
            url, f"malformed options {query!r}", "write them as ?name=value&name=value"
        ) from exc
    allowed = _OPTIONS[scheme]
    out: dict[str, str] = {}
    for key, values in parsed.items():
        if key not in allowed:
            known = ", ".join(allowed) if allowed else "none"
            raise TransportError(
                url, f"unknown option {key!r} for {scheme}", f"options for {scheme}: {known}"
            )
        if len(values) != 1:
            raise TransportError(url, f"option {key!r} given {len(values)} times", "give it once")
        out[key] = values[0]
    return out


def _split_host_port(url: str, text: str, what: str) -> tuple[str, int]:
    """'HOST:PORT' or '[V6]:PORT' → (host, port)."""
    m = re.fullmatch(r"\[([^\]]*)\]:(\d+)|([^:\[\]]*):(\d+)", text)
    if not m:
        raise TransportError(url, f"{what} {text!r} is not HOST:PORT", "e.g. 127.0.0.1:10110 or [::1]:10110")
    host = m.group(1) if m.group(1) is not None else m.group(3)
    port = int(m.group(2) or m.group(4))
    if port > 65535:
        raise TransportError(url, f"{what} port {port} is out of range", "use a port 0–65535")
    return host, port


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
    m = re.fullmatch(r"pty:?(\?.*)?", text, flags=re.IGNORECASE)
    if m:  # "pty", "pty:", "pty?stale_s=5": a pty without a link
        text = "pty://" + (m.group(1) or "")
    if "://" not in text:
        m = re.match(r"([A-Za-z][A-Za-z0-9+.-]*):", text)
        if m and m.group(1).lower() in _SCHEMES:
            raise TransportError(
                url, "not a URL I understand", f"did you mean {m.group(1)}://{text[m.end() :].lstrip('/')}?"
            )
        return FileSink(text, url=url)
    parts = urlsplit(text)
    scheme = parts.scheme.lower()
    if scheme not in _SCHEMES:
        raise TransportError(url, f"unknown transport {parts.scheme!r}", f"give one of: {URL_FORMS}")
    if parts.fragment:
        raise TransportError(url, f"unexpected '#{parts.fragment}'", "remove it")
    opts = _options(url, scheme, parts.query)

    if scheme in ("pty", "file", "serial"):
        if parts.netloc not in ("", "localhost"):
            raise TransportError(
                url,
                f"{parts.netloc!r} is read as a host name",
                f"write an absolute path with three slashes: {scheme}:///{parts.netloc}{parts.path}",
            )
        path = unquote(parts.path)
        if scheme == "pty":
            stale: float | None = 2.0
            if "stale_s" in opts:
                raw = opts["stale_s"].lower()
                stale = None if raw in ("none", "off", "inf") else _number(url, "stale_s", raw)
            return PtySink(path or None, stale_s=stale, url=url)
        if not path:
            raise TransportError(
                url, "no path given", f"e.g. {scheme}:///dev/ttyUSB0" if scheme == "serial" else ""
            )
        if scheme == "file":
            return FileSink(path, url=url)
        baud_text = opts.get("baud", "4800")
        if not baud_text.isdigit():
            raise TransportError(
                url, f"baud {baud_text!r} is not a whole number", "e.g. ?baud=4800 or ?baud=38400"
            )
        return SerialSink(path, int(baud_text), url=url)

    if parts.path not in ("", "/"):
        raise TransportError(url, f"unexpected path {parts.path!r}", f"write {scheme}://HOST:PORT")
    host, port = _split_host_port(url, parts.netloc, "address")
    if scheme == "udp":
        if not host:
            raise TransportError(url, "no destination host", "e.g. udp://127.0.0.1:10110")
        bind = _split_host_port(url, opts["bind"], "bind address") if "bind" in opts else None
        if bind is not None and not bind[0]:
            bind = ("0.0.0.0", bind[1])
        return UdpSink(host, port, bind=bind, url=url)
    max_backlog = 262_144
    if "max_backlog" in opts:
        if not opts["max_backlog"].isdigit():
            raise TransportError(url, f"max_backlog {opts['max_backlog']!r} is not a whole number of bytes")
        max_backlog = int(opts["max_backlog"])
    return TcpServerSink(host or "0.0.0.0", port, max_backlog=max_backlog, url=url)
