"""Shared test set-up."""

from __future__ import annotations

import pynmea2

if "THS" not in pynmea2.TalkerSentence.sentence_types:
    # pynmea2 1.19 has no THS; registering a layout is pynmea2's own extension mechanism (the checksum and
    # field splitting stay pynmea2's), so THS is still checked by an independent parser.
    class THS(pynmea2.TalkerSentence):
        fields = (("Heading, degrees true", "heading", float), ("Mode indicator", "mode"))
