"""NMEA 0183 framing: an arbitrary byte stream in, candidate sentences and rejected chunks out.

The packet layer of the NMEA codec, shaped like gpsd's (``gpsd/packet.c``): it only finds where sentences
begin and end and resynchronises after noise; it never looks inside a sentence. Decoding (checksum, fields,
units) is :func:`wire.codecs.nmea.decode`'s job.

Bytes arrive chopped anywhere (serial reads, UDP datagrams with one or several sentences, TCP segments);
:meth:`NmeaFramer.feed` keeps a partial sentence between calls, and the frames it returns do not depend on
where the stream was cut (tested). The rules (``docs/nmea.md``):

* A sentence starts at ``$`` (or ``!``, an AIS/encapsulation sentence: reason ``ais``, not decoded here) and
  ends at the first CR or LF. Line terminators are framing: CR, LF, CRLF, LFCR and blank lines between
  sentences belong to no frame.
* Bytes between the end of one frame and the next ``$``/``!`` that are not a sentence are one ``garbage``
  frame (in pieces of at most :data:`MAX_CHUNK` bytes, so noise without a ``$`` never grows memory).
* A line that begins with ``#`` is a ``comment`` frame, to its line end whatever it holds (a ``$`` in it
  starts no sentence): gpsd's test logs and capture tools head their files with such lines, which are
  no sentence and no noise either. No NMEA sentence begins with ``#``.
* A ``$`` or ``!`` inside a sentence starts a new one; the part before it is ``truncated``.
* A sentence longer than ``max_length`` characters (``$`` to checksum, terminator excluded) is
  ``overlong``: it is dropped up to its line end or the next ``$``/``!``, where the framer resyncs.
* A byte that is not printable ASCII (0x20-0x7E) inside a sentence (a NUL, 0xFF from a wrong baud rate, ...)
  makes the sentence ``non_ascii``.
* Precedence when several apply to one frame: ``overlong``, then ``non_ascii``, then ``truncated``.
* A TAG block (NMEA 4.10, IEC 61162-450: ``\\s:GP0001*hh\\``) directly before a ``$``/``!`` is a
  ``tag_block`` frame, and the IEC 61162-450 datagram header ``UdPbC\\0`` directly before a TAG block or
  a sentence is an ``iec_61162_450`` frame: framing of a ship's network, not noise. Only the two
  backslashes and printable ASCII between them (at most `wire.codecs.nmea_tag.MAX_TAG_LENGTH` bytes)
  make a TAG block; what it says is `wire.codecs.nmea_tag.decode_tag`'s to read.

The framer counts nothing (the caller counts frames by :attr:`Frame.reason`) and loses nothing: every byte
it rejects comes back in a frame's ``raw``, so the gateway can log it (DESIGN.md rule 4). It never raises.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from wire.codecs.nmea_tag import HEADER_450, MAX_TAG_LENGTH

GARBAGE = "garbage"
TRUNCATED = "truncated"
OVERLONG = "overlong"
NON_ASCII = "non_ascii"
AIS = "ais"
COMMENT = "comment"
TAG_BLOCK = "tag_block"
IEC_61162_450 = "iec_61162_450"
FRAME_REASONS = (GARBAGE, TRUNCATED, OVERLONG, NON_ASCII, AIS, COMMENT, TAG_BLOCK, IEC_61162_450)
"""Every value :attr:`Frame.reason` can take besides ``None``: stable strings, counted per source."""

DEFAULT_MAX_LENGTH = 180
"""Default longest sentence, ``$`` to checksum: NMEA's 82 characters with CRLF, doubled and then some for
the high-precision sentences RTK receivers send (90 characters in the project's USV logs)."""

MAX_CHUNK = 1024
"""Garbage and overlong bytes are handed back in frames of at most this many bytes (or ``max_length + 1``
if that is larger), so a stream that never sends a ``$`` cannot grow the framer's memory."""


class Frame(NamedTuple):
    """One unit of the byte stream.

    * ``reason is None``: a candidate NMEA sentence. ``text`` is the sentence from ``$`` to the checksum
      without the line terminator (``$GPGGA,...*5C``), printable ASCII; decode it with
      :func:`wire.codecs.nmea.decode`.
    * otherwise ``text`` is ``None`` and ``reason`` is one of :data:`FRAME_REASONS`: a chunk the framer
      rejects (``garbage``, ``truncated``, ``overlong``, ``non_ascii``), a complete printable ``!``
      sentence (AIS ``!AIVDM``/``!AIVDO``, reason ``ais``) that dpgw does not decode, a ``#`` comment
      line (``comment``: not bad input), or a ship network's framing before a sentence (``tag_block``,
      ``iec_61162_450``: not bad input either).

    So ``text is None`` exactly when ``reason is not None``.

    ``raw`` is always the frame's bytes as received, line terminators excluded (a garbage chunk keeps any
    CR/LF inside it).
    """

    text: str | None
    raw: bytes
    reason: str | None


_GROUND, _SENTENCE, _OVERLONG, _COMMENT = 0, 1, 2, 3

# Bytes that end the printable run of a sentence: controls (CR, LF, NUL, ...), '!' (0x21), '$' (0x24), DEL
# and everything >= 0x80.
_SENTENCE_STOP = re.compile(rb"[^\x20\x22\x23\x25-\x7e]")
_LEAD = re.compile(rb"[$!]")
_EOL_OR_LEAD = re.compile(rb"[\r\n$!]")
_EOL_ANY = re.compile(rb"[\r\n]")
_EOL = b"\r\n"
_new_frame = tuple.__new__  # Frame(...) without NamedTuple's Python-level __new__
_LEADS = b"$!"
_HEADER_450 = HEADER_450
# A TAG block at the end of a run of bytes outside sentences (the run ends where a sentence's lead byte is).
_TAG_AT_END = re.compile(rb"\\[\x20-\x5b\x5d-\x7e]{3,%d}\\\Z" % (MAX_TAG_LENGTH - 2))


class NmeaFramer:
    """Splits a byte stream into :class:`Frame` s, with gpsd-style resynchronisation (module docstring).

    >>> framer = NmeaFramer()
    >>> for frame in framer.feed(b"xx$GPHDT,12.0,T*06\\r\\n$GPH"):
    ...     print(frame.reason, frame.raw)
    garbage b'xx'
    None b'$GPHDT,12.0,T*06'
    >>> framer.feed(b"DT,1")
    []
    >>> framer.flush()
    [Frame(text=None, raw=b'$GPHDT,1', reason='truncated')]
    """

    fast_path = True
    """Frame clean sentences with C-level finds first. ``False`` runs the general rules alone: the readable
    reference the fast path is tested against."""

    def __init__(self, max_length: int = DEFAULT_MAX_LENGTH) -> None:
        if max_length < 8:
            raise ValueError(f"max_length must be at least 8 characters, got {max_length}")
        self.max_length = max_length
        self._chunk = max(MAX_CHUNK, max_length + 1)
        self._state = _GROUND
        self._buf = bytearray()  # the pending sentence, overlong line or garbage
        self._bad = False  # the pending sentence holds a non-printable byte
        self._skip_eol = True  # at a line start: CR/LF bytes are terminators, not garbage

    def feed(self, data: bytes) -> list[Frame]:
        """The frames completed by ``data`` (any bytes-like object, any length, cut anywhere), in stream
        order. Never raises."""
        data = bytes(data)
        out: list[Frame] = []
        try:
            self._feed(data, out)
        except Exception:  # pragma: no cover - a bug must not stop the gateway; keep every byte
            out.append(Frame(None, bytes(self._buf) + data, GARBAGE))
            self._reset()
        return out

    def flush(self) -> list[Frame]:
        """End of stream: whatever is pending, as one frame (a partial sentence is ``truncated``, pending
        noise ``garbage``, the rest of a long line ``overlong``); the framer starts afresh."""
        out: list[Frame] = []
        if self._buf:
            if self._state == _GROUND:
                out.append(Frame(None, bytes(self._buf), GARBAGE))
            elif self._state == _COMMENT:
                out.append(Frame(None, bytes(self._buf), COMMENT))
            elif self._state == _OVERLONG:
                out.append(Frame(None, bytes(self._buf), OVERLONG))
            else:
                out.append(Frame(None, bytes(self._buf), NON_ASCII if self._bad else TRUNCATED))
        self._reset()
        return out

    @property
    def pending(self) -> int:
        """Number of bytes held back, waiting for the rest of their frame."""
        return len(self._buf)

    # ------------------------------------------------------------------------------------------ internals

    def _reset(self) -> None:
        self._state = _GROUND
        self._buf = bytearray()
        self._bad = False
        self._skip_eol = True

    def _feed(self, data: bytes, out: list[Frame]) -> None:
        i = 0
        n = len(data)
        buf = self._buf
        max_length = self.max_length
        fast = self.fast_path
        while i < n:
            state = self._state
            if state == _SENTENCE:
                if not buf and not self._bad:
                    # data[i] is a lead byte. Fast path, the common case: a clean sentence and its line end
                    # inside `data` (C-level finds, bounded by max_length so a stream without line ends stays
                    # linear). It gives the frames the general rules below give (tested with fast_path off).
                    k = -1
                    if fast:
                        window = i + max_length + 1
                        k = data.find(b"\n", i, window)
                        cr = data.find(b"\r", i, k if k >= 0 else window)
                        if cr >= 0:
                            k = cr
                    if k >= 0:
                        raw = data[i:k]
                        if raw.isascii():
                            text = raw.decode("ascii")
                            if text.isprintable() and text.find("$", 1) < 0 and text.find("!", 1) < 0:
                                if raw[0] == 36:  # '$'
                                    out.append(_new_frame(Frame, (text, raw, None)))
                                else:
                                    out.append(_new_frame(Frame, (None, raw, AIS)))
                                i = k + 1
                                while i < n and (data[i] == 10 or data[i] == 13):
                                    i += 1
                                if i < n and (data[i] == 36 or data[i] == 33):
                                    continue  # the next sentence follows its predecessor's line end
                                self._state = _GROUND
                                self._skip_eol = True
                                continue
                    # The general rules, for a sentence that starts in `data`.
                    m = _SENTENCE_STOP.search(data, i + 1)
                    j = m.start() if m else n
                    if j - i > max_length:
                        buf += data[i:j]
                        self._to_overlong(out)
                        i = j
                        continue
                    if m is None:
                        buf += data[i:]
                        return
                    c = data[j]
                    if c == 13 or c == 10:
                        raw = data[i:j]
                        if raw[0] == 36:  # '$'
                            out.append(Frame(raw.decode("ascii"), raw, None))
                        else:
                            out.append(Frame(None, raw, AIS))
                        self._state = _GROUND
                        self._skip_eol = True
                        i = j + 1
                    elif c == 36 or c == 33:  # '$' or '!': restart
                        out.append(Frame(None, data[i:j], TRUNCATED))
                        i = j
                    else:  # a non-printable byte: the sentence is poisoned, keep it to its end
                        buf += data[i : j + 1]
                        self._bad = True
                        i = j + 1
                        if len(buf) > max_length:
                            self._to_overlong(out)
                    continue
                # Slow path: continue a sentence held in `buf`.
                m = _SENTENCE_STOP.search(data, i)
                j = m.start() if m else n
                buf += data[i:j]
                if len(buf) > max_length:
                    self._to_overlong(out)
                    i = j
                    continue
                if m is None:
                    return
                c = data[j]
                if c == 13 or c == 10:
                    self._emit_sentence(out)
                    self._skip_eol = True
                    i = j + 1
                elif c == 36 or c == 33:
                    out.append(Frame(None, bytes(buf), NON_ASCII if self._bad else TRUNCATED))
                    buf.clear()
                    self._bad = False
                    i = j  # the lead byte starts the next sentence, on the fast path
                else:
                    buf.append(c)
                    self._bad = True
                    i = j + 1
                    if len(buf) > max_length:
                        self._to_overlong(out)
            elif state == _GROUND:
                if self._skip_eol and data[i] == 35 and not buf:  # '#' at a line start: a comment line
                    self._state = _COMMENT
                    continue
                # Garbage runs end at a line end as well as at a lead byte: each line of noise is one
                # reject, so "every line of a capture is used or counted" holds line by line.
                m = _EOL_OR_LEAD.search(data, i)
                j = m.start() if m else n
                if j > i:
                    buf += data[i:j]
                    self._skip_eol = False
                    self._spill(out, GARBAGE)
                if m is None:
                    return
                if data[j] == 13 or data[j] == 10:
                    if buf:
                        out.append(Frame(None, bytes(buf), GARBAGE))
                        buf.clear()
                    self._skip_eol = True
                    i = j + 1
                    continue
                if buf:
                    self._end_run(out)
                self._state = _SENTENCE
                self._bad = False
                i = j
            elif state == _COMMENT:  # to the line end, whatever it holds
                m = _EOL_ANY.search(data, i)
                j = m.start() if m else n
                buf += data[i:j]
                self._spill(out, COMMENT)
                if m is None:
                    return
                if buf:
                    out.append(Frame(None, bytes(buf), COMMENT))
                    buf.clear()
                self._state = _GROUND
                self._skip_eol = True
                i = j + 1
            else:  # _OVERLONG: drop to the line end or the next lead byte
                m = _EOL_OR_LEAD.search(data, i)
                j = m.start() if m else n
                buf += data[i:j]
                self._spill(out, OVERLONG)
                if m is None:
                    return
                if buf:
                    out.append(Frame(None, bytes(buf), OVERLONG))
                    buf.clear()
                self._bad = False
                if data[j] in _LEADS:
                    self._state = _SENTENCE
                    i = j
                else:
                    self._state = _GROUND
                    self._skip_eol = True
                    i = j + 1

    def _end_run(self, out: list[Frame]) -> None:
        """A run of bytes outside sentences has reached a sentence's lead byte: its end may be a ship
        network's framing (a TAG block, after the IEC 61162-450 header), the rest is garbage."""
        buf = self._buf
        run = bytes(buf)
        buf.clear()
        m = _TAG_AT_END.search(run)
        tag = b""
        if m is not None:
            run, tag = run[: m.start()], run[m.start() :]
        header = b""
        if run.endswith(_HEADER_450):
            run, header = run[: -len(_HEADER_450)], _HEADER_450
        if run:
            out.append(Frame(None, run, GARBAGE))
        if header:
            out.append(Frame(None, header, IEC_61162_450))
        if tag:
            out.append(Frame(None, tag, TAG_BLOCK))

    def _emit_sentence(self, out: list[Frame]) -> None:
        """The sentence in the buffer has reached its line end."""
        buf = self._buf
        raw = bytes(buf)
        if self._bad:
            out.append(Frame(None, raw, NON_ASCII))
        elif raw[0] == 36:
            out.append(Frame(raw.decode("ascii"), raw, None))
        else:
            out.append(Frame(None, raw, AIS))
        buf.clear()
        self._bad = False
        self._state = _GROUND

    def _to_overlong(self, out: list[Frame]) -> None:
        self._state = _OVERLONG
        self._spill(out, OVERLONG)

    def _spill(self, out: list[Frame], reason: str) -> None:
        """Hand back full pieces of a garbage or overlong buffer (a byte count, so chop-independent)."""
        buf = self._buf
        size = self._chunk
        while len(buf) >= size:
            out.append(Frame(None, bytes(buf[:size]), reason))
            del buf[:size]
