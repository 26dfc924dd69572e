"""A tlog of the MAVLink the simulator sends, as a ground station on the link would record it (``dpgw sim
--tlog``): each frame stamped with the simulation's UTC time at which it left the simulated drive.

Time base: the same `SimEpoch` that writes the UTC times into the NMEA sentences (GGA/RMC/ZDA), and that
stamps the frames in the simulator's MCAP log (its log time: when the bytes were sent). A replay of the
simulator's NMEA text (``--nmea file://...``) with this tlog therefore merges the two in the time order of
the run: the text log's cycles are at their sentences' times, the tlog's frames at theirs.

What is recorded is what a ground station records: frames it received whole and valid. Bytes of a
``garbage`` fault and frames of a ``bad_checksum`` fault (a wrong CRC) are not frames MAVProxy, Mission
Planner or QGroundControl would log; they are counted (`not_recorded`) instead, and stay in the MCAP log,
which keeps every byte sent.
"""

from __future__ import annotations

from simulator.clock import SimEpoch
from simulator.sensors import Emission
from wire.codecs.mavlink import FrameParser
from wire.tlog import TlogWriter


class TlogRecorder:
    """Called with every emission as it leaves (`Simulation.on_emit`); records the MAVLink ones."""

    def __init__(self, writer: TlogWriter, epoch: SimEpoch) -> None:
        self.writer = writer
        self.epoch = epoch
        self.not_recorded = 0
        """MAVLink emissions with no whole valid frame in them (garbage, a corrupted CRC)."""
        self._parser = FrameParser()
        self.sources: set[str] = set()
        """The streams whose frames it recorded."""

    def __call__(self, e: Emission) -> None:
        if e.protocol != "mavlink":
            return
        # Each emission is parsed on its own (flushed): garbage cannot splice onto the next good frame.
        parser = self._parser
        frames = [bytes(m.get_msgbuf()) for m in (*parser.feed(e.data), *parser.flush())]
        if not frames:
            self.not_recorded += 1
            return
        self.writer.write(self.epoch.stamp_ns(e.t_emit) // 1000, frames)
        self.sources.add(e.source)

    @property
    def records(self) -> int:
        return self.writer.records
