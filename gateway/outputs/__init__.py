"""Extra output sinks beside the gateway's own Zenoh keys and MCAP log.

Each sink (a live Foxglove server, a ROS 2 bridge over rmw_zenoh, Keelson) lives in its own module here
and receives every batch of pipeline outputs, already encoded once as JSON, after the Zenoh puts and before
the MCAP write. A sink owns whatever it opens (sockets, Zenoh declarations) and releases it in `close`.
Sinks are optional: the service runs the same without any. `build.sinks_from_config` makes the ones a
config enables (``dpgw run``). A sink that also implements `RawSentenceSink` gets every raw NMEA sentence as
the pipeline frames it (`Pipeline.sentence_tap`), so it never frames the bytes a second time. A sink that
implements `InputSink` may hand commands (a setpoint from ROS 2) into the gateway's own input path.
"""

from gateway.outputs.base import InputSink, OutputSink, RawSentenceSink, Submit

__all__ = ["InputSink", "OutputSink", "RawSentenceSink", "Submit"]
