"""The one interface an extra output sink implements (see the package docstring)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    import zenoh

    from gateway.pipeline import Output


class OutputSink(Protocol):
    """Receives the pipeline's outputs on the gateway's consumer thread.

    ``emit`` must not block for long (it runs between an observer step and the next): a sink that talks
    to a slow peer queues or drops, and counts what it drops. An exception raised by ``emit`` is counted
    as an internal error of the sink and the gateway goes on."""

    name: str

    def start(self, session: zenoh.Session) -> None:
        """Open sockets and declarations (called once, with the gateway's open Zenoh session, which a sink
        may declare publishers, subscribers and liveliness tokens on but must not close). A client gateway
        (``mode = "client"``) opens its session when its router answers, and starts its sinks then; a
        sink with the attribute ``needs_zenoh = False`` is started at once, with None."""

    def emit(self, outputs: list[Output], encoded: list[bytes]) -> None:
        """One batch of outputs and their JSON encodings (the same order)."""

    def close(self) -> None:
        """Release everything `start` opened; safe to call twice."""


@runtime_checkable
class RawSentenceSink(Protocol):
    """A sink that also wants every raw NMEA sentence as framed (the service hands them over through
    `Pipeline.sentence_tap`, on the consumer thread, before the outputs of the chunk they came in)."""

    name: str

    def raw_nmea(self, source: str, rx_ns: int, text: str, peer: str) -> None:
        """One sentence from ``$``/``!`` to its checksum, without the line end, valid or not."""


class SettlingChanges:
    """When an output that tells the estimate's settling (`wire.messages.Estimate` ``settled``,
    ``settle_s_left``) has a change to tell: the first estimate that says, the estimate settling, and its
    settle clock starting again (the time left grows: an observer restart). A countdown is no change."""

    def __init__(self) -> None:
        self.last: tuple[bool, float] | None = None

    def update(self, settled: bool, left_s: float) -> bool:
        """Take one estimate's values; whether they are a change from the last."""
        last, self.last = self.last, (settled, left_s)
        return last is None or settled != last[0] or left_s > last[1]


Submit = Callable[[str, Any], None]
"""``submit(key, payload)``: an input (``setpoint``, ``mode``, ``tau``) into the gateway's queue, stamped,
logged and checked by `gateway.commands` exactly like one from ``<prefix>/<key>``
(`GatewayService.submit`)."""


@runtime_checkable
class InputSink(Protocol):
    """A sink that also takes commands from its peers (a ROS 2 setpoint): the service hands it `Submit`
    before `OutputSink.start`, and the sink calls it from any thread."""

    name: str

    def bind_inputs(self, submit: Submit) -> None:
        """Keep ``submit`` for the commands this sink receives."""
