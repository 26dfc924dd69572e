"""How the live gateway reads the vessel's streams: serial ports, ptys, UDP, TCP and files — one interface.

A `Source` is opened from a URL by `open_source` and started with a ``deliver`` callback. A daemon reader
thread reads the transport and calls ``deliver`` with one `Chunk` per read (a UDP datagram, a serial read,
a TCP segment, whole lines of a file), stamped with the UTC and monotonic receive times. The consumer (the
pipeline) puts chunks on a queue; decoding is not done here. ``write`` sends bytes back (MAVLink commands)::

    serial:///dev/ttyUSB0?baud=4800[&bytesize=8&parity=N&stopbits=1]   a serial port (pyserial)
    pty:///tmp/dpgw-gps                   the same, on a pty path (e.g. the simulator's link)
    udp://0.0.0.0:10110[?target=H:P]      listen for datagrams; write() answers the last peer (or target)
    udp://239.1.2.3:10110?iface=eth0      ... joining a multicast group (iface: address or interface name)
    tcp://HOST:PORT                       a TCP client that reconnects with exponential back-off
    tcp-listen://0.0.0.0:PORT             a TCP server; any number of clients
    file:///path/log.nmea?rate=fast|realtime|HZ   a file read as a stream (tests, demos)
    udpin:H:P  udp:H:P  udpout:H:P  tcp:H:P  tcpin:H:P  /dev/ttyUSB0,57600  serial:/dev/ttyUSB0:57600
                                          pymavlink connection strings, mapped onto the above

Errors a person must fix (a malformed URL, a serial port that does not exist or is in use, a UDP port
taken) raise one `SourceError` naming the source, the URL and what to do — from `open_source` (the URL)
or from `Source.start` (opening it). Everything that can heal by itself is counted and retried, never
raised: a TCP server that is down (or goes down), a USB serial adapter unplugged while running. See
``docs/sources.md``.

One module per job, imported in this order (each only from the ones before it):

    base      the `Source` interface and reader thread, `Chunk`, `SourceError`, `SourceStats`, back-off
    sockets   socket helpers shared by UDP and TCP
    serial    `SerialSource`: serial ports and ptys (pyserial)
    udp       `UdpSource`
    tcp       `TcpClientSource` (reconnects), `TcpListenSource` (server)
    file      `FileSource`, `nmea_time_of_day`
    url       `open_source`: the URL (or pymavlink string) → the source it names; validates, opens nothing

The transport modules do not import each other (an import-linter contract in pyproject.toml holds them
to it), so a new transport is one new module plus its URL form in `url`.
"""

from gateway.sources.base import (
    BACKOFF_FIRST_S,
    BACKOFF_MAX_S,
    POLL_S,
    STOP_JOIN_S,
    Chunk,
    SeveralSourcesError,
    Source,
    SourceError,
    SourceStats,
)
from gateway.sources.file import FileSource, nmea_time_of_day
from gateway.sources.serial import NMEA_DEFAULT_BAUD, SerialSource
from gateway.sources.tcp import TcpClientSource, TcpListenSource
from gateway.sources.udp import UdpSource
from gateway.sources.url import MAVLINK_DEFAULT_BAUD, URL_FORMS, open_source

__all__ = [
    "BACKOFF_FIRST_S",
    "BACKOFF_MAX_S",
    "MAVLINK_DEFAULT_BAUD",
    "NMEA_DEFAULT_BAUD",
    "POLL_S",
    "STOP_JOIN_S",
    "URL_FORMS",
    "Chunk",
    "FileSource",
    "SerialSource",
    "SeveralSourcesError",
    "Source",
    "SourceError",
    "SourceStats",
    "TcpClientSource",
    "TcpListenSource",
    "UdpSource",
    "nmea_time_of_day",
    "open_source",
]
