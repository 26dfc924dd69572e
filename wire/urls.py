"""The one grammar of link URLs: where the gateway reads and where the simulator writes.

The config (``[[sources]] url``), the gateway's sources and the simulator's sinks all parse a link with
`parse_url`, so a spelling means the same thing everywhere. Parsing is pure: nothing is opened, no name
is resolved. The result is a typed `Endpoint`; `Endpoint.format` writes it back (``parse_url(e.format())
== e``)::

    serial:///dev/ttyUSB0?baud=4800   a serial port (three slashes: the path is absolute)
    pty:///tmp/dpgw-gps                a pseudo-terminal at a path (``pty`` alone: a new one, simulator)
    udp://HOST:PORT                    UDP: a reader listens on HOST:PORT (a group address joins it),
                                       a writer sends to HOST:PORT
    tcp://HOST:PORT                    TCP client: connect to HOST:PORT (and reconnect)
    tcp-listen://HOST:PORT             TCP server: listen on HOST:PORT (``:PORT`` = all interfaces)
    file:///ABSOLUTE/PATH              a file (``file:RELATIVE/PATH`` where the caller allows it)

and, where MAVLink is read, pymavlink's connection strings, mapped onto the forms above:
``udpin:H:P`` and ``udp:H:P`` (= ``udp://H:P``), ``udpout:H:P`` (= ``udp://:0?target=H:P``), ``tcp:H:P``
(= ``tcp://H:P``), ``tcpin:H:P`` (= ``tcp-listen://H:P``), ``/dev/ttyACM0[,BAUD]`` and
``serial:/dev/ttyACM0[:BAUD]`` (= ``serial:///dev/ttyACM0?baud=BAUD``).

Why ``tcp://`` is always the client: a URL names the far end you connect to, as in every other tool
(gpsd, socat, pymavlink's ``tcp:``); listening is the exception and says so (``tcp-listen://``). The
simulator once read ``tcp://`` as its TCP server; that spelling now fails with a message naming
``tcp-listen://`` rather than silently doing the opposite.

Errors are `UrlError` (``problem`` and ``expected``): each caller frames them in its own message style
(the source's name, the config key). Options are ``?key=value&...``; which keys a scheme takes depends on
the side (reader or writer), so callers pass them (`SOURCE_OPTIONS`, `SINK_OPTIONS`).
"""

from __future__ import annotations

import difflib
import ipaddress
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from urllib.parse import parse_qs, quote, unquote, urlencode

__all__ = [
    "PYMAVLINK_PREFIXES",
    "SCHEMES",
    "SINK_OPTIONS",
    "SOURCE_OPTIONS",
    "Endpoint",
    "SerialSettings",
    "UrlError",
    "file_rate",
    "format_host_port",
    "is_multicast",
    "listen_address",
    "parse_url",
    "receive_buffer",
    "serial_settings",
    "split_host_port",
    "valid_host",
]

SCHEMES = ("serial", "pty", "udp", "tcp", "tcp-listen", "file")
"""The URL schemes of the grammar."""
PYMAVLINK_PREFIXES = ("udpin", "udpout", "udp", "tcp", "tcpin", "serial")
"""pymavlink connection strings ``prefix:...`` (accepted where ``pymavlink=True``)."""

SOURCE_OPTIONS: Mapping[str, tuple[str, ...]] = {
    "serial": ("baud", "bytesize", "parity", "stopbits"),
    "pty": ("baud", "bytesize", "parity", "stopbits"),
    "udp": ("target", "iface", "rcvbuf"),
    "tcp": (),
    "tcp-listen": (),
    "file": ("rate",),
}
"""Options of each scheme where the gateway reads (`gateway.sources`)."""
SINK_OPTIONS: Mapping[str, tuple[str, ...]] = {
    "pty": ("stale_s",),
    "udp": ("bind", "iface", "tag_source"),
    "tcp-listen": ("max_backlog",),
    "serial": ("baud",),
    "file": (),
}
"""Options of each scheme where the simulator writes (`simulator.transports`); it has no TCP client."""

URL_FORMS = (
    "serial:///dev/DEVICE?baud=4800, pty:///PATH, udp://HOST:PORT, tcp://HOST:PORT (client), "
    "tcp-listen://HOST:PORT (server), file:///PATH"
)
PYMAVLINK_FORMS = (
    "pymavlink's udpin:H:P, udpout:H:P, tcp:H:P, tcpin:H:P, /dev/DEVICE,BAUD, serial:/dev/DEVICE:BAUD"
)

_PATH_SCHEMES = ("serial", "pty", "file")
_PARITY = {
    **{k: k.upper() for k in "neoms"},
    **{"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"},
}
_HOST_PORT = re.compile(r"\[([^\]]+)\]:(\d+)|([^:\[\]/@?#\s]*):(\d+)")  # (any digits: the range is said)


class UrlError(ValueError):
    """A URL that does not parse: ``problem`` (what is wrong) and ``expected`` (what to write instead)."""

    def __init__(self, problem: str, expected: str = "") -> None:
        self.problem = problem
        self.expected = expected
        super().__init__(problem + (f" (expected {expected})" if expected else ""))


@dataclass(frozen=True)
class Endpoint:
    """A parsed link URL.

    ``host``/``port`` for ``udp``, ``tcp``, ``tcp-listen``; ``path`` (unquoted) for ``serial``, ``pty``,
    ``file``. ``options`` are the ``?key=value`` pairs in the order written. ``pymavlink`` is the prefix
    when the text was a pymavlink connection string (``"udpout"``, ``"device"`` for ``/dev/X[,BAUD]``,
    ...), else ``""``: it changes defaults (a serial link without a baud rate opens at 115200, not 4800)
    and whether ``udpout`` announces itself.
    """

    scheme: str
    host: str = ""
    port: int | None = None
    path: str = ""
    options: tuple[tuple[str, str], ...] = field(default=())
    pymavlink: str = ""

    def option(self, key: str, default: str | None = None) -> str | None:
        for k, v in self.options:
            if k == key:
                return v
        return default

    @property
    def address(self) -> str:
        """``host:port`` (``[v6]:port``) for socket schemes."""
        return format_host_port(self.host, self.port or 0)

    @property
    def listens(self) -> bool:
        """Whether a reader on this endpoint listens (binds) rather than connects."""
        return self.scheme in ("udp", "tcp-listen") and not self.option("target")

    def format(self) -> str:
        """The canonical URL (always the ``scheme://`` form, also for pymavlink strings)."""
        query = ("?" + urlencode(self.options, safe=":[]/,")) if self.options else ""
        if self.scheme in _PATH_SCHEMES:
            if not self.path.startswith("/"):  # file:RELATIVE/PATH (resolved by the config)
                return f"{self.scheme}:{quote(self.path)}{query}"
            return f"{self.scheme}://{quote(self.path)}{query}"
        return f"{self.scheme}://{self.address}{query}"


def format_host_port(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def is_multicast(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_multicast
    except ValueError:
        return False


def split_host_port(text: str, *, need_host: bool, allow_zero: bool, example: str = "") -> tuple[str, int]:
    """``HOST:PORT``, ``[V6]:PORT`` or (when the host may be empty) ``:PORT`` → (host, port).

    ``allow_zero``: port 0 (any free port) is allowed, as for a socket that listens.
    """
    m = _HOST_PORT.fullmatch(text)
    if not m:
        raise UrlError(f"{text!r} is not HOST:PORT", example or "e.g. 127.0.0.1:10110 or [::1]:10110")
    host = m.group(1) if m.group(1) is not None else m.group(3)
    port = int(m.group(2) or m.group(4))
    low = 0 if allow_zero else 1
    if not low <= port <= 65535:
        span = f"{low}–65535" + (", 0: any free port" if not low else "")
        raise UrlError(f"port {port} is out of range ({span})", example or "a port in that range")
    if need_host and not host:
        raise UrlError("no host given", example or "e.g. 127.0.0.1:5760")
    return host, port


def _forms(pymavlink: bool) -> str:
    return f"one of {URL_FORMS}" + (f", or {PYMAVLINK_FORMS}" if pymavlink else "")


def parse_url(
    text: str,
    *,
    options: Mapping[str, Sequence[str]] = SOURCE_OPTIONS,
    pymavlink: bool = False,
    bare_path: str = "",
    relative_files: bool = False,
) -> Endpoint:
    """Parse a link URL (module docstring) into an `Endpoint`; raise `UrlError` if it does not parse.

    ``options``: the schemes this side accepts and each one's option keys. ``pymavlink``: accept
    pymavlink connection strings. ``bare_path``: what a plain path without a scheme is (``"file"`` for the
    simulator's output files; ``""`` = not accepted, except a device path when ``pymavlink``).
    ``relative_files``: accept ``file:RELATIVE/PATH`` (the config resolves it against its own folder).
    """
    url = text.strip()
    if not url:
        raise UrlError("empty URL", _forms(pymavlink))
    if any(c.isspace() or not c.isprintable() for c in url):
        raise UrlError("the URL contains spaces or control characters", "a URL without them")
    if "://" not in url:
        return _parse_short(url, options, pymavlink, bare_path, relative_files)
    scheme_text, _, rest = url.partition("://")
    scheme = scheme_text.lower()
    if scheme not in options:
        if scheme == "tcp" and "tcp-listen" in options:
            raise UrlError(
                "tcp:// connects to a TCP server (a client), and there is no TCP client here",
                f"tcp-listen://{rest} for a TCP server (tcp://HOST:PORT as a server is the old spelling)",
            )
        if scheme in SCHEMES:  # a scheme of the grammar this side does not use
            raise UrlError(f"{scheme}:// is not available here", _forms(pymavlink))
        close = difflib.get_close_matches(scheme, list(options), n=1, cutoff=0.6)
        hint = f", did you mean {close[0]}://?" if close else ""
        raise UrlError(f"unknown transport {scheme_text!r}{hint}", _forms(pymavlink))
    rest, hash_, fragment = rest.partition("#")
    if hash_:
        raise UrlError(f"unexpected '#{fragment}'", "no fragment")
    rest, _, query = rest.partition("?")
    opts = _parse_options(query, scheme, options[scheme])
    if scheme in _PATH_SCHEMES:
        netloc, slash, path_text = rest.partition("/")
        if netloc not in ("", "localhost"):
            raise UrlError(
                f"{netloc!r} is read as a host name",
                f"an absolute path with three slashes: {scheme}:///{netloc}{slash}{path_text}",
            )
        path = unquote(slash + path_text)
        if not path.strip("/") and scheme != "pty":
            example = {"serial": "serial:///dev/ttyUSB0?baud=4800", "file": "file:///data/run1.nmea"}[scheme]
            raise UrlError("no path given", f"e.g. {example}")
        return Endpoint(scheme, path=path, options=opts)
    netloc, slash, path_text = rest.partition("/")
    if path_text:
        raise UrlError(f"unexpected path {'/' + path_text!r}", f"{scheme}://HOST:PORT")
    if scheme == "tcp":
        try:
            host, port = split_host_port(netloc, need_host=False, allow_zero=False, example="tcp://HOST:PORT")
        except UrlError as exc:
            raise UrlError(exc.problem, "tcp://HOST:PORT") from None
        if not host:
            raise UrlError(
                "no host to connect to",
                f"tcp://HOST:{port} (a client), or tcp-listen://0.0.0.0:{port} to listen",
            )
    else:
        try:
            host, port = split_host_port(netloc, need_host=False, allow_zero=True)
        except UrlError as exc:
            raise UrlError(exc.problem, f"{scheme}://HOST:PORT") from None
    endpoint = Endpoint(scheme, host=host, port=port, options=opts)
    _check_socket_options(endpoint)
    return endpoint


def _parse_short(
    url: str, options: Mapping[str, Sequence[str]], pymavlink: bool, bare_path: str, relative_files: bool
) -> Endpoint:
    """The forms without ``://``: pymavlink strings, device or file paths, ``pty``, ``file:REL``."""
    if re.fullmatch(r"pty:?", url, flags=re.IGNORECASE) and "pty" in options:
        return Endpoint("pty")
    m = re.fullmatch(r"pty:?(\?.*)", url, flags=re.IGNORECASE)
    if m and "pty" in options:  # pty?stale_s=5: a new pty with options
        return Endpoint("pty", options=_parse_options(m.group(1)[1:], "pty", options["pty"]))
    if url.startswith("/"):
        if pymavlink:  # /dev/ttyACM0[,57600]
            device, comma, baud = url.partition(",")
            return _serial_short(device, baud, comma, "device", url)
        if bare_path == "file":
            return Endpoint("file", path=url)
    m = re.fullmatch(r"([A-Za-z][A-Za-z0-9+.-]*):(.*)", url)
    if m is None:
        if bare_path == "file":
            return Endpoint("file", path=url)
        if re.fullmatch(r"[^:/]*:\d+", url):
            raise UrlError("no transport given", f"udp://{url} or tcp://{url}")
        raise UrlError("not a URL", _forms(pymavlink))
    prefix, rest = m.group(1).lower(), m.group(2)
    if prefix == "file" and relative_files and "file" in options:
        rel, _, query = rest.partition("?")
        if not rel:
            raise UrlError("no path given", "file:PATH or file:///ABSOLUTE/PATH")
        return Endpoint("file", path=unquote(rel), options=_parse_options(query, "file", options["file"]))
    if pymavlink and prefix in PYMAVLINK_PREFIXES:
        return _parse_pymavlink(prefix, rest, url)
    if prefix in SCHEMES:
        raise UrlError(
            f"not a URL I understand, did you mean {prefix}://{rest.lstrip('/')}?", _forms(pymavlink)
        )
    if bare_path == "file":  # a relative file name with a colon in it
        return Endpoint("file", path=url)
    known = list(options) + (list(PYMAVLINK_PREFIXES) if pymavlink else [])
    close = difflib.get_close_matches(prefix, known, n=1, cutoff=0.6)
    hint = ""
    if close:
        hint = f", did you mean {close[0]}{'://' if close[0] in options else ':'}?"
    raise UrlError(f"unknown transport {prefix!r}{hint}", _forms(pymavlink))


def _serial_short(device: str, baud: str, sep: str, form: str, url: str) -> Endpoint:
    if not device.strip("/") or not device.startswith("/"):
        problem = "no device given" if not device.strip("/") else f"{device!r} is not an absolute device path"
        raise UrlError(problem, "e.g. /dev/ttyACM0,57600 or serial:///dev/ttyACM0?baud=57600")
    if sep and not baud:
        raise UrlError("no baud rate after the separator", f"e.g. {device}{sep}57600")
    opts = (("baud", baud),) if baud else ()
    endpoint = Endpoint("serial", path=device, options=opts, pymavlink=form)
    if baud:
        serial_settings(endpoint)
    return endpoint


def _parse_pymavlink(prefix: str, rest: str, url: str) -> Endpoint:
    if prefix == "serial":  # serial:/dev/ttyUSB0[:57600]
        tail = re.fullmatch(r"(.*):(\d+)", rest)
        device, baud = (tail.group(1), tail.group(2)) if tail else (rest, "")
        return _serial_short(device, baud, ":" if tail else "", "serial", url)
    listening = prefix in ("udpin", "udp", "tcpin")
    example = (
        f"{prefix}:HOST:PORT, e.g. {'udpin:0.0.0.0:14550' if listening else prefix + ':192.168.1.20:14550'}"
    )
    try:
        host, port = split_host_port(rest, need_host=False, allow_zero=listening)
    except UrlError as exc:
        raise UrlError(exc.problem, example) from None
    if not host and not listening:
        raise UrlError(f"no host to {'send' if prefix == 'udpout' else 'connect'} to", example)
    if prefix == "udpout":
        target = (("target", format_host_port(host, port)),)
        return Endpoint("udp", host="", port=0, options=target, pymavlink=prefix)
    scheme = {"udpin": "udp", "udp": "udp", "tcp": "tcp", "tcpin": "tcp-listen"}[prefix]
    return Endpoint(scheme, host=host, port=port, pymavlink=prefix)


def _parse_options(query: str, scheme: str, allowed: Sequence[str]) -> tuple[tuple[str, str], ...]:
    if not query:
        return ()
    try:
        parsed = parse_qs(query, keep_blank_values=True, strict_parsing=True)
    except ValueError:
        raise UrlError(f"malformed options {query!r}", "?name=value&name=value") from None
    out: list[tuple[str, str]] = []
    for key, values in parsed.items():
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
            hint = f", did you mean {close[0]!r}?" if close else ""
            known = ", ".join(allowed) if allowed else "none"
            raise UrlError(f"unknown option {key!r} for {scheme}{hint}", f"options for {scheme}: {known}")
        if len(values) != 1:
            raise UrlError(f"option {key!r} given {len(values)} times", "it once")
        out.append((key, values[0].strip()))
    return tuple(out)


def _check_socket_options(endpoint: Endpoint) -> None:
    target = endpoint.option("target")
    if target is not None:
        split_host_port(
            target, need_host=True, allow_zero=False, example="target=HOST:PORT, e.g. target=10.0.0.2:14550"
        )
    iface = endpoint.option("iface")
    if iface and not is_multicast(endpoint.host):
        raise UrlError("iface is for multicast groups (224.0.0.0–239.255.255.255)", "no iface here")
    bind = endpoint.option("bind")
    if bind is not None:
        split_host_port(
            bind, need_host=False, allow_zero=True, example="bind=HOST:PORT, e.g. bind=0.0.0.0:10111"
        )


# --- typed option values (shared by the sides that take them) --------------------------------------------


@dataclass(frozen=True)
class SerialSettings:
    """A serial line's settings from a URL: baud rate, data bits, parity (N, E, O, M, S), stop bits."""

    baud: int
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1


def serial_settings(endpoint: Endpoint, default_baud: int = 4800) -> SerialSettings:
    """The serial settings of a ``serial``/``pty`` endpoint (defaults 8N1); `UrlError` for a bad value."""
    baud_text = endpoint.option("baud") or str(default_baud)
    if not baud_text.isdigit() or not 0 < int(baud_text) <= 20_000_000:
        raise UrlError(f"baud {baud_text!r} is not a baud rate", "e.g. baud=4800, 38400 or 115200")
    bytesize_text = endpoint.option("bytesize", "8") or "8"
    if bytesize_text not in ("5", "6", "7", "8"):
        raise UrlError(f"bytesize {bytesize_text!r} is not 5, 6, 7 or 8", "8: NMEA and MAVLink use 8")
    parity_text = endpoint.option("parity", "N") or "N"
    parity = _PARITY.get(parity_text.lower())
    if parity is None:
        raise UrlError(f"parity {parity_text!r} is not one of N, E, O, M, S", "N: NMEA uses N")
    stop_text = endpoint.option("stopbits", "1") or "1"
    if stop_text not in ("1", "1.5", "2"):
        raise UrlError(f"stopbits {stop_text!r} is not 1, 1.5 or 2", "1: NMEA uses 1")
    return SerialSettings(
        int(baud_text), int(bytesize_text), parity, float(stop_text) if stop_text == "1.5" else int(stop_text)
    )


def receive_buffer(endpoint: Endpoint, default: int) -> int:
    """A UDP source's kernel receive buffer in bytes: ``rcvbuf=N``, ``Nk`` or ``NM`` (KiB, MiB), 4 KiB to
    1 GiB; ``default`` when not given."""
    raw = endpoint.option("rcvbuf")
    if raw is None:
        return default
    m = re.fullmatch(r"([0-9]{1,10})([kKmM]?)", raw.strip())
    size = int(m.group(1)) * {"": 1, "k": 1024, "m": 1024**2}[m.group(2).lower()] if m else 0
    if not 4096 <= size <= 1024**3:
        raise UrlError(
            f"rcvbuf {raw!r} is not a buffer size", "bytes, or with k or M, 4k to 1024M, e.g. rcvbuf=8M"
        )
    return size


def file_rate(endpoint: Endpoint) -> str | float:
    """A file source's pace: ``"fast"``, ``"realtime"`` (default) or lines per second."""
    raw = (endpoint.option("rate") or "realtime").lower()
    if raw in ("fast", "realtime"):
        return raw
    try:
        rate = float(raw)
    except ValueError:
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise UrlError(
            f"rate {endpoint.option('rate')!r} is not fast, realtime or lines per second", "e.g. rate=10"
        )
    return rate


_HOST_NAME = re.compile(
    r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*"
)
"""A host name: RFC 1123 labels joined by dots."""


def valid_host(host: str) -> bool:
    """An IPv4 or IPv6 address, or a host name: what a server can be told to listen on."""
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return bool(_HOST_NAME.fullmatch(host))


def listen_address(text: str, default_host: str = "127.0.0.1", example: str = "") -> tuple[str, int]:
    """``[HOST:]PORT`` (a server's address on a command line: ``8765``, ``0.0.0.0:8765``, ``[::1]:8765``)
    → (host, port); a bare port listens on ``default_host``. Port 0: any free port."""
    value = text.strip()
    if value.isdigit():
        value = f":{value}"
    elif not _HOST_PORT.fullmatch(value):
        raise UrlError(f"{text!r} is not [HOST:]PORT", example or "e.g. 8765 or 127.0.0.1:8765")
    host, port = split_host_port(value, need_host=False, allow_zero=True, example=example)
    host = host or default_host
    if not valid_host(host):
        raise UrlError(f"{host!r} is not an address or host name", example or "e.g. 127.0.0.1:8765")
    return host, port
