"""NMEA 0183 TAG blocks (NMEA 0183 v4.10 §7.9) and the IEC 61162-450 datagram header: decoding.

A ship's network under IEC 61162-450 carries NMEA sentences in UDP multicast datagrams. Each datagram
starts with the 6-byte header ``UdPbC\\0`` and each sentence in it is preceded by a TAG block that names the
device that sent it::

    UdPbC\\0\\s:GP0001,n:123*17\\$GPGGA,...*5C\\r\\n

A TAG block sits between two backslashes directly before a sentence's ``$`` or ``!``: comma-separated
``code:value`` parameters, then ``*`` and two hex digits, the XOR of the characters between the opening
backslash and the ``*`` (the sentence checksum's rule). The codes NMEA 4.10 and IEC 61162-450 define:

==== ============================================================================================
code meaning
==== ============================================================================================
s    source: the sending device (450: its System Function ID, two letters and four digits, "GP0001")
d    destination
n    line count (450: a datagram counter, 1-999)
g    sentence grouping ``x-y-id`` (this is the x-th line of y, group id)
c    the source's UNIX time (s; some loggers write ms)
r    relative time
t    free text
==== ============================================================================================

Finding the block in a byte stream is the framer's job (`wire.codecs.nmea_framing`: ``tag_block`` and
``iec_61162_450`` frames); this module only reads one. What the gateway uses is ``s``: a source's
``tag_source`` takes the sentences of one device from a multicast group several devices share. The time
``c`` is the sender's and not used as a receive time (the gateway stamps receive times itself, as for any
source); it stays in the raw log with the rest of the bytes.
"""

from __future__ import annotations

import re
from typing import NamedTuple

HEADER_450 = b"UdPbC\x00"
"""The IEC 61162-450 datagram header of sentence datagrams ("UDP broadcast", NUL-terminated)."""

MAX_TAG_LENGTH = 400
"""Longest TAG block the framer takes (backslashes included). NMEA 4.10 bounds a TAG block with its sentence
by the line's length; 450 by the datagram's. 400 leaves room for the longest ``t:`` text seen in practice
while a run of noise that merely ends in a backslash pair is not taken for one."""

SOURCE = re.compile(r"[\x21-\x29\x2b\x2d-\x5b\x5d-\x7e]{1,15}")
"""A device name a TAG block can carry after ``s:``: NMEA 4.10 bounds it at 15 characters; IEC 61162-450
writes a System Function ID, two letters and four digits ("GP0001"). Printable, without ``,`` ``*`` ``\\``
(they would end the parameter, the block or its checksum) or spaces."""
SOURCE_EXPECTED = (
    '1-15 printable characters without , * \\ or spaces, as a device writes after "s:", e.g. "GP0001"'
)

TAG_CHECKSUM = "tag_checksum"
TAG_MALFORMED = "tag_malformed"
OTHER_TAG_SOURCE = "other_tag_source"
"""Counted for a sentence a source with a ``tag_source`` does not take: another device's (not bad input)."""


class TagBlock(NamedTuple):
    """A decoded TAG block: its parameters by code, in order (``{"s": "GP0001", "n": "123"}``)."""

    params: dict[str, str]

    @property
    def source(self) -> str | None:
        """The sending device (``s:``), None without one."""
        return self.params.get("s")

    @property
    def group(self) -> tuple[int, str] | None:
        """Which line of which group this is (``g:x-y-id``: ``(x, id)``), None without a readable ``g:``.
        NMEA 4.10 lets a group's later lines carry only ``g:`` (and ``n:``), their device (``s:``) on the
        first line alone, as an AIS receiver's pair ``\\g:1-2-73874,n:157036,s:r003669945*hh\\!AIVDM,...``
        then ``\\g:2-2-73874,n:157037*hh\\$ARVSI,...``."""
        g = self.params.get("g")
        if g is None:
            return None
        x, _, rest = g.partition("-")
        _, _, ident = rest.partition("-")
        return (int(x), ident) if x.isdigit() and ident else None


class TagReject(NamedTuple):
    """A TAG block that cannot be read: ``reason`` is ``tag_checksum`` or ``tag_malformed``."""

    reason: str
    detail: str


def decode_tag(raw: bytes) -> TagBlock | TagReject:
    """The TAG block ``raw`` (with its two backslashes, as the framer's ``tag_block`` frame holds it).

    A checksum is required (NMEA 4.10 makes it mandatory) and must match; a parameter without ``:`` or with
    an empty code is malformed. Never raises.

    >>> decode_tag(b"\\\\s:GP0001,n:123*17\\\\").source
    'GP0001'
    >>> decode_tag(b"\\\\s:GP0001,n:123*16\\\\").reason
    'tag_checksum'
    """
    if len(raw) < 5 or raw[0] != 0x5C or raw[-1] != 0x5C:
        return TagReject(TAG_MALFORMED, "not between two backslashes")
    body = raw[1:-1]
    star = body.rfind(b"*")
    if star < 0 or len(body) - star != 3:
        return TagReject(TAG_MALFORMED, "no *hh checksum at its end")
    try:
        given = int(body[star + 1 :], 16)
        text = body[:star].decode("ascii")
    except ValueError:  # (UnicodeDecodeError is one)
        return TagReject(TAG_MALFORMED, "checksum not two hex digits, or a byte not ASCII")
    computed = 0
    for b in body[:star]:
        computed ^= b
    if computed != given:
        return TagReject(TAG_CHECKSUM, f"checksum {given:02X}, computed {computed:02X}")
    params: dict[str, str] = {}
    for part in text.split(","):
        code, colon, value = part.partition(":")
        if not colon or not code:
            return TagReject(TAG_MALFORMED, f"parameter {part!r} is not code:value")
        params[code] = value
    return TagBlock(params)


def encode_tag(params: dict[str, str]) -> bytes:
    """A TAG block holding ``params`` in order, with its checksum (for the simulator and tests)."""
    text = ",".join(f"{k}:{v}" for k, v in params.items()).encode("ascii")
    checksum = 0
    for b in text:
        checksum ^= b
    return b"\\" + text + b"*%02X\\" % checksum


def next_line(line: int) -> int:
    """The line count after ``line``: 1-999, then 1 again."""
    return line % 999 + 1


def iec_450_datagram(sentences: bytes, source: str, line: int) -> tuple[bytes, int]:
    """The IEC 61162-450 sentence datagram of ``sentences`` (whole lines, CRLF-terminated) sent by the
    device ``source``, and the line count its next sentence takes. The header, then each sentence after
    a TAG block with ``s:`` the source, ``n:`` the device's line count (``line`` for the first sentence,
    one more for each after it, 1-999 then 1 again) and, when the datagram holds several sentences,
    ``g:`` grouping them (``x-y-id``: the x-th of y, the group named by its first sentence's count)."""
    lines = [s for s in sentences.splitlines(keepends=True) if s.strip()]
    out = bytearray(HEADER_450)
    group = str(line)
    for k, sentence in enumerate(lines, 1):
        params = {"s": source, "n": str(line)}
        if len(lines) > 1:
            params["g"] = f"{k}-{len(lines)}-{group}"
        out += encode_tag(params)
        out += sentence
        line = next_line(line)
    return bytes(out), line
