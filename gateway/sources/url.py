"""From a source URL (or a pymavlink connection string) to the `Source` it names: `open_source`.

Parsing is `wire.urls` (the one URL grammar, shared with the config and the simulator's sinks); here
the parsed URL becomes a source. Validation only; nothing is opened until `Source.start`. The URL forms
are listed in the package docstring and in ``docs/sources.md``.
"""

from __future__ import annotations

import math

from gateway.sources.base import Source, SourceError
from gateway.sources.file import FileSource
from gateway.sources.serial import NMEA_DEFAULT_BAUD, SerialSource
from gateway.sources.tcp import TcpClientSource, TcpListenSource
from gateway.sources.udp import DEFAULT_RECEIVE_BUFFER, UdpSource
from wire import urls
from wire.urls import Endpoint, UrlError

#: pymavlink's default baud rate, used for MAVLink device strings without one (``/dev/ttyUSB0``).
MAVLINK_DEFAULT_BAUD = 115200

URL_FORMS = (
    "serial:///dev/DEVICE?baud=4800, pty:///PATH, udp://HOST:PORT, tcp://HOST:PORT, "
    "tcp-listen://HOST:PORT, file:///PATH?rate=fast|realtime|HZ, or pymavlink's udpin:H:P, udpout:H:P, "
    "tcp:H:P, tcpin:H:P, /dev/DEVICE,BAUD, serial:/dev/DEVICE:BAUD"
)


def _default_hello() -> bytes:
    """A MAVLink 2 HEARTBEAT of an onboard computer (system 1, component 191), not a ground station: a
    GCS heartbeat (system 255) that stops later could trigger an autopilot's GCS failsafe."""
    from wire.codecs import mavlink  # only udpout needs the (large) dialect

    d = mavlink.dialect()
    mav = mavlink.encoder(1, d.MAV_COMP_ID_ONBOARD_COMPUTER)
    return mavlink.heartbeat_frame(mav, mav_type=d.MAV_TYPE_ONBOARD_CONTROLLER)


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
    try:
        endpoint = urls.parse_url(text, options=urls.SOURCE_OPTIONS, pymavlink=True)
        return _source_for(name, url, endpoint, timeout_s, hello)
    except UrlError as exc:
        raise SourceError(
            name, url, exc.problem, f"expected {exc.expected}" if exc.expected else ""
        ) from None


def _source_for(name: str, url: str, ep: Endpoint, timeout_s: float, hello: bytes | None) -> Source:
    """The source for a parsed URL (`wire.urls`: the one URL grammar); option values checked here."""
    if ep.scheme == "file":
        return FileSource(name, url, ep.path, urls.file_rate(ep), timeout_s=timeout_s)
    if ep.scheme == "pty" and not ep.path.strip("/"):
        raise UrlError("no pty path given", "the path the simulator printed, e.g. pty:///tmp/dpgw-gps")
    if ep.scheme in ("serial", "pty"):
        s = urls.serial_settings(ep, MAVLINK_DEFAULT_BAUD if ep.pymavlink else NMEA_DEFAULT_BAUD)
        return SerialSource(
            name, url, ep.path, s.baud, bytesize=s.bytesize, parity=s.parity, stopbits=s.stopbits,
            timeout_s=timeout_s,
        )  # fmt: skip
    port = ep.port or 0
    if ep.scheme == "tcp":
        return TcpClientSource(name, url, ep.host, port, timeout_s=timeout_s)
    if ep.scheme == "tcp-listen":
        return TcpListenSource(name, url, ep.host, port, timeout_s=timeout_s)
    target_text = ep.option("target")
    target = urls.split_host_port(target_text, need_host=True, allow_zero=False) if target_text else None
    # udpout sends first: it announces the gateway, so the far end learns where to send
    announce = ep.pymavlink == "udpout"
    hello = (_default_hello() if hello is None else hello) if announce else None
    rcvbuf = urls.receive_buffer(ep, DEFAULT_RECEIVE_BUFFER)
    return UdpSource(
        name, url, ep.host, port, target=target, iface=ep.option("iface") or None, hello=hello,
        timeout_s=timeout_s, receive_buffer=rcvbuf,
    )  # fmt: skip
