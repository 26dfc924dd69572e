"""Where the simulator's bytes go: a pty, UDP, a TCP server, a serial port or a file — one interface.

The simulator is a vessel at sea that behaves like real hardware on the wire. Its NMEA sentences and
MAVLink frames are written to a `Sink`; thruster commands (MAVLink) that peers send back are read from the
same sink with `Sink.read_available`. `open_sink` turns a URL into a sink::

    pty                          PtySink: a new pseudo-terminal; any serial program opens .device
    pty:///tmp/dpgw-gps          ... with a stable symlink to it (removed on close)
    udp://HOST:PORT              UdpSink: one datagram per write to HOST:PORT; replies are read back
    udp://HOST:PORT?bind=H:P     ... sending from (and listening on) H:P
    udp://GROUP:PORT?iface=I&tag_source=GP0001   ... to a multicast group by interface I, as the device
                                 GP0001 of an IEC 61162-450 network (header and TAG blocks)
    tcp-listen://HOST:PORT       TcpServerSink: a TCP server; every write goes to every client
    serial:///dev/ttyUSB0?baud=4800   SerialSink: a real serial port, raw 8N1, no flow control
    file:///path/to/file, PATH   FileSink: appended, handed to the OS on every write

Behaviour every sink shares (``docs/transports.md`` has the details and how to connect programs):

* ``write`` never blocks the simulation for long and never raises because a peer is slow, absent or gone.
  A write is delivered whole or dropped whole — never cut in the middle of a sentence — and a drop is
  counted (``writes_dropped``, ``bytes_dropped``, ``last_error``).
* Errors a person must fix (a malformed URL, a port in use, an unwritable path) raise one
  `TransportError` when the sink is opened, naming the URL and what to do.
* Sinks are not thread-safe: one simulation thread writes and reads. There are no background threads;
  work on peers (accepting TCP clients, sending what a busy peer could not take yet) is done in each
  ``write``, ``read_available`` and ``poll``.

One module per job, imported in this order (each only from the ones before it):

    base      the `Sink` interface and its counters, `TransportError`
    memory    `MemorySink` (tests)
    fd        raw tty mode and the whole-or-dropped descriptor writer that pty and serial share
    pty       `PtySink`
    serial    `SerialSink`
    sockets   socket helpers shared by UDP and TCP
    udp       `UdpSink`
    tcp       `TcpServerSink`
    file      `FileSink`
    url       `open_sink`: the URL → the sink it names, opened

The sink modules do not import each other (an import-linter contract in pyproject.toml holds them to it),
so a new transport is one new module plus its URL form in `url`.
"""

from simulator.transports.base import Sink, TransportError
from simulator.transports.file import FileSink
from simulator.transports.memory import MemorySink
from simulator.transports.pty import PtySink
from simulator.transports.serial import SerialSink
from simulator.transports.tcp import TcpServerSink
from simulator.transports.udp import UdpSink
from simulator.transports.url import URL_FORMS, open_sink

__all__ = [
    "URL_FORMS",
    "FileSink",
    "MemorySink",
    "PtySink",
    "SerialSink",
    "Sink",
    "TcpServerSink",
    "TransportError",
    "UdpSink",
    "open_sink",
]
