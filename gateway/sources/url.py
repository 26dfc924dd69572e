"""From a source URL (or a pymavlink connection string) to the `Source` it names: `open_source`.

Parsing and validation only; nothing is opened until `Source.start`. The URL forms are listed in the
package docstring and in ``docs/sources.md``.
"""

from __future__ import annotations

import math
import re
from urllib.parse import parse_qs, unquote, urlsplit

from gateway.sources.base import Source, SourceError
from gateway.sources.file import FileSource
from gateway.sources.serial import NMEA_DEFAULT_BAUD, SerialSource
from gateway.sources.tcp import TcpClientSource, TcpListenSource
from gateway.sources.udp import UdpSource

#: pymavlink's default baud rate, used for MAVLink device strings without one (``/dev/ttyUSB0``).
MAVLINK_DEFAULT_BAUD = 115200

URL_FORMS = (
    "serial:///dev/DEVICE?baud=4800, pty:///PATH, udp://HOST:PORT, tcp://HOST:PORT, "
    "tcp-listen://HOST:PORT, file:///PATH?rate=fast|realtime|HZ, or pymavlink's udpin:H:P, udpout:H:P, "
    "tcp:H:P, tcpin:H:P, /dev/DEVICE,BAUD, serial:/dev/DEVICE:BAUD"
)

_OPTIONS: dict[str, tuple[str, ...]] = {
    "serial": ("baud", "bytesize", "parity", "stopbits"),
    "pty": ("baud", "bytesize", "parity", "stopbits"),
    "udp": ("target", "iface"),
    "tcp": (),
    "tcp-listen": (),
    "file": ("rate",),
}
_PYMAVLINK = ("udpin", "udp", "udpout", "tcp", "tcpin", "serial")
_PARITY = {
    **{k: k.upper() for k in "neoms"},
    **{"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"},
}


def _options(name: str, url: str, scheme: str, query: str) -> dict[str, str]:
    try:
        parsed = parse_qs(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError as exc:
        raise SourceError(
            name, url, f"malformed options {query!r}", "write them as ?name=value&name=value"
        ) from exc
    allowed = _OPTIONS[scheme]
    out: dict[str, str] = {}
    for key, values in parsed.items():
        if key not in allowed:
            raise SourceError(
                name,
                url,
                f"unknown option {key!r} for {scheme}",
                f"options for {scheme}: {', '.join(allowed) if allowed else 'none'}",
            )
        if len(values) != 1:
            raise SourceError(name, url, f"option {key!r} given {len(values)} times", "give it once")
        out[key] = values[0].strip()
    return out


def _host_port(name: str, url: str, text: str, *, need_host: bool, allow_zero: bool) -> tuple[str, int]:
    """``HOST:PORT`` or ``[V6]:PORT`` (``:PORT`` when the host may be empty) → (host, port)."""
    m = re.fullmatch(r"\[([^\]]+)\]:(\d{1,5})|([^:\[\]/@?#\s]*):(\d{1,5})", text)
    if not m:
        raise SourceError(name, url, f"{text!r} is not HOST:PORT", "e.g. 127.0.0.1:10110 or [::1]:10110")
    host = m.group(1) if m.group(1) is not None else m.group(3)
    port = int(m.group(2) or m.group(4))
    if need_host and not host:
        raise SourceError(name, url, "no host given", "e.g. 127.0.0.1:5760")
    low = 0 if allow_zero else 1
    if not low <= port <= 65535:
        raise SourceError(
            name,
            url,
            f"port {port} is out of range",
            f"use {low}–65535" + (" (0: any free port)" if low == 0 else ""),
        )
    return host, port


def _serial_source(
    name: str, url: str, device: str, opts: dict[str, str], default_baud: int, timeout_s: float
) -> SerialSource:
    if not device:
        raise SourceError(name, url, "no device given", "e.g. serial:///dev/ttyUSB0?baud=4800")
    baud_text = opts.get("baud", str(default_baud))
    if not baud_text.isdigit() or not 0 < int(baud_text) <= 20_000_000:
        raise SourceError(
            name, url, f"baud {baud_text!r} is not a baud rate", "e.g. baud=4800, 38400 or 115200"
        )
    bytesize_text = opts.get("bytesize", "8")
    if bytesize_text not in ("5", "6", "7", "8"):
        raise SourceError(
            name, url, f"bytesize {bytesize_text!r} is not 5, 6, 7 or 8", "NMEA and MAVLink use 8"
        )
    parity = _PARITY.get(opts.get("parity", "N").lower())
    if parity is None:
        raise SourceError(name, url, f"parity {opts['parity']!r} is not one of N, E, O, M, S", "NMEA uses N")
    stop_text = opts.get("stopbits", "1")
    if stop_text not in ("1", "1.5", "2"):
        raise SourceError(name, url, f"stopbits {stop_text!r} is not 1, 1.5 or 2", "NMEA uses 1")
    return SerialSource(
        name,
        url,
        device,
        int(baud_text),
        bytesize=int(bytesize_text),
        parity=parity,
        stopbits=float(stop_text) if stop_text == "1.5" else int(stop_text),
        timeout_s=timeout_s,
    )


def _default_hello() -> bytes:
    """A MAVLink 2 HEARTBEAT of an onboard computer (system 1, component 191), not a ground station: a
    GCS heartbeat (system 255) that stops later could trigger an autopilot's GCS failsafe."""
    from wire.codecs import mavlink  # only udpout needs the (large) dialect

    d = mavlink.dialect()
    mav = mavlink.encoder(1, d.MAV_COMP_ID_ONBOARD_COMPUTER)
    return mavlink.heartbeat_frame(mav, mav_type=d.MAV_TYPE_ONBOARD_CONTROLLER)


def _pymavlink_source(name: str, url: str, text: str, timeout_s: float, hello: bytes | None) -> Source | None:
    """pymavlink connection strings; None if ``text`` is not one."""
    m = re.fullmatch(r"([a-z]+):(.*)", text, flags=re.IGNORECASE)
    if m is None or "://" in text:
        if text.startswith("/") and "://" not in text:  # /dev/ttyUSB0[,57600]
            device, _, baud = text.partition(",")
            return _serial_source(
                name, url, device, {"baud": baud} if baud else {}, MAVLINK_DEFAULT_BAUD, timeout_s
            )
        return None
    scheme, rest = m.group(1).lower(), m.group(2)
    if scheme not in _PYMAVLINK:
        return None
    if scheme == "serial":  # serial:/dev/ttyUSB0[:57600]
        device, baud = rest, ""
        tail = re.fullmatch(r"(.*):(\d+)", rest)
        if tail:
            device, baud = tail.group(1), tail.group(2)
        return _serial_source(
            name, url, device, {"baud": baud} if baud else {}, MAVLINK_DEFAULT_BAUD, timeout_s
        )
    if scheme in ("udpin", "udp"):
        host, port = _host_port(name, url, rest, need_host=False, allow_zero=True)
        return UdpSource(name, url, host, port, timeout_s=timeout_s)
    if scheme == "udpout":
        host, port = _host_port(name, url, rest, need_host=True, allow_zero=False)
        return UdpSource(
            name,
            url,
            "",
            0,
            target=(host, port),
            hello=_default_hello() if hello is None else hello,
            timeout_s=timeout_s,
        )
    if scheme == "tcp":
        host, port = _host_port(name, url, rest, need_host=True, allow_zero=False)
        return TcpClientSource(name, url, host, port, timeout_s=timeout_s)
    host, port = _host_port(name, url, rest, need_host=False, allow_zero=True)  # tcpin
    return TcpListenSource(name, url, host, port, timeout_s=timeout_s)


def open_source(name: str, url: str, *, timeout_s: float = 2.0, hello: bytes | None = None) -> Source:
    """The source a URL names (module docstring, ``docs/sources.md``); validated, not opened yet.

    ``timeout_s``: how long one TCP connect attempt or a blocked write may take, and the default of
    `Source.is_stale`. ``hello``: for ``udpout:``, the datagram that announces the gateway to the far end
    (default: a MAVLink HEARTBEAT, see `_default_hello`); ``b""`` sends none.

    Raises `SourceError` for a URL that cannot work, with the URL and what to do in the message.
    """
    if not isinstance(name, str) or not name.strip():
        raise SourceError(str(name), str(url), "a source needs a name", "name it in the config")
    text = url.strip() if isinstance(url, str) else ""
    if not text:
        raise SourceError(name, str(url), "empty URL", f"give one of: {URL_FORMS}")
    if not (isinstance(timeout_s, int | float) and math.isfinite(timeout_s) and timeout_s > 0):
        raise SourceError(name, url, f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
    if any(c.isspace() or not c.isprintable() for c in text):
        raise SourceError(name, url, "the URL contains spaces or control characters", "remove them")

    if re.fullmatch(r"pty:?/*", text, flags=re.IGNORECASE):
        raise SourceError(
            name, url, "no pty path given", "give the path the simulator printed, e.g. pty:///tmp/dpgw-gps"
        )
    mav = _pymavlink_source(name, url, text, timeout_s, hello)
    if mav is not None:
        return mav
    if "://" not in text:
        m = re.match(r"([A-Za-z][A-Za-z0-9+.-]*):", text)
        if m and m.group(1).lower() in _OPTIONS:
            raise SourceError(
                name,
                url,
                "not a URL I understand",
                f"did you mean {m.group(1)}://{text[m.end() :].lstrip('/')}?",
            )
        if re.fullmatch(r"[^:/]*:\d+", text):
            raise SourceError(name, url, "no transport given", f"write udp://{text} or tcp://{text}")
        raise SourceError(name, url, "not a URL I understand", f"give one of: {URL_FORMS}")
    try:
        parts = urlsplit(text)
    except ValueError as exc:
        raise SourceError(name, url, f"malformed URL: {exc}", f"give one of: {URL_FORMS}") from exc
    scheme = parts.scheme.lower()
    if scheme not in _OPTIONS:
        raise SourceError(name, url, f"unknown transport {parts.scheme!r}", f"give one of: {URL_FORMS}")
    if parts.fragment:
        raise SourceError(name, url, f"unexpected '#{parts.fragment}'", "remove it")
    opts = _options(name, url, scheme, parts.query)

    if scheme in ("serial", "pty", "file"):
        if parts.netloc not in ("", "localhost"):
            raise SourceError(
                name,
                url,
                f"{parts.netloc!r} is read as a host name",
                f"write an absolute path with three slashes: {scheme}:///{parts.netloc}{parts.path}",
            )
        path = unquote(parts.path)
        if scheme == "file":
            if not path:
                raise SourceError(name, url, "no file given", "e.g. file:///data/run1.nmea?rate=fast")
            raw_rate = opts.get("rate", "realtime").lower()
            rate: str | float = raw_rate
            if raw_rate not in ("fast", "realtime"):
                try:
                    rate = float(raw_rate)
                except ValueError:
                    rate = math.nan
                if not (math.isfinite(rate) and rate > 0):
                    raise SourceError(
                        name,
                        url,
                        f"rate {opts['rate']!r} is not fast, realtime or lines per second",
                        "e.g. rate=10",
                    )
            return FileSource(name, url, path, rate, timeout_s=timeout_s)
        if scheme == "pty" and not path:
            raise SourceError(
                name,
                url,
                "no pty path given",
                "give the path the simulator printed, e.g. pty:///tmp/dpgw-gps",
            )
        return _serial_source(name, url, path, opts, NMEA_DEFAULT_BAUD, timeout_s)

    if parts.path not in ("", "/"):
        raise SourceError(name, url, f"unexpected path {parts.path!r}", f"write {scheme}://HOST:PORT")
    if scheme == "tcp":
        host, port = _host_port(name, url, parts.netloc, need_host=True, allow_zero=False)
        return TcpClientSource(name, url, host, port, timeout_s=timeout_s)
    if scheme == "tcp-listen":
        host, port = _host_port(name, url, parts.netloc, need_host=False, allow_zero=True)
        return TcpListenSource(name, url, host, port, timeout_s=timeout_s)
    host, port = _host_port(name, url, parts.netloc, need_host=False, allow_zero=True)
    target = None
    if "target" in opts:
        target = _host_port(name, url, opts["target"], need_host=True, allow_zero=False)
    source = UdpSource(
        name, url, host, port, target=target, iface=opts.get("iface") or None, timeout_s=timeout_s
    )
    if opts.get("iface") and not source.multicast:
        raise SourceError(name, url, "iface is for multicast groups (224.0.0.0–239.255.255.255)", "remove it")
    return source
