"""Live Foxglove: the `foxglove-sdk` package's WebSocket server, fed every output of the pipeline.

The Foxglove app (or any client of Foxglove's WebSocket protocol, subprotocol ``foxglove.sdk.v1``)
connects to ``ws://HOST:PORT`` and sees the same channels as the MCAP log: dpgw's JSON channels
(``/dp/estimate``, ``/dp/measurement``, ``/dp/status``, ``/gnss/<source>/fix``, ...) with the JSON Schema
their MCAP channels carry, and the Foxglove-native channels the pipeline derives
(`gateway.foxglove_channels`: ``/dp/estimate/fix``, ``/dp/tf``, ``/dp/scene/*``, ``/dp/log``, ...). The
payload is the JSON the service has already encoded once for Zenoh and the log: nothing is encoded twice.

Channels are advertised on first use: a topic appears when its first message is made, so every
advertised channel has data, and channels that only carry events (``/dp/log``: a reference state change,
an alarm) appear only once something happened. A message made while no client is subscribed to its
channel is held instead of sent (the last one per channel, the last `LOG_HELD` lines of ``/dp/log``) and
goes out when the first client subscribes: a client that connects after the hull, the setpoint or an
alarm was published still sees them. A later second client gets what is made from then on.

Never blocking the pipeline: `foxglove.Channel.log` copies the message into each subscribed client's
queue and returns (the SDK's server runs on its own threads); a client too slow to keep up loses its
oldest queued messages (``message_backlog_size``, the SDK's own policy, per client) or, when even its
control queue fills, is disconnected. Those drops happen inside the SDK and are not visible from Python;
what this sink counts is what it sees: messages sent, held, superseded while held (never sent because a
newer one replaced it before anyone subscribed), channels advertised again (`RESUBSCRIBE_AFTER_NS`) and log
calls that raised.

The server has no authentication and no encryption: it binds to 127.0.0.1 unless told otherwise
(``[foxglove] host``), docs/foxglove.md "Live" says what binding to another interface exposes.
"""

from __future__ import annotations

import functools
import json
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import foxglove
from foxglove.websocket import (
    Capability,
    ChannelView,
    Client,
    ClientChannel,
    PlaybackControlRequest,
    PlaybackState,
    ServerListener,
    WebSocketServer,
)

from wire.message_schema import json_schema
from wire.messages import Message

if TYPE_CHECKING:
    import zenoh

    from gateway.config import GatewayConfig
    from gateway.pipeline import Output

log = logging.getLogger(__name__)

SERVER_NAME = "dpgw"
LOG_TOPIC = "/dp/log"
LOG_HELD = 100
"""Log lines held for the first subscriber of ``/dp/log`` (the other channels hold their last message:
each is a state that the next one replaces)."""
TIME_EVERY_NS = 50_000_000
"""Live, the server's time (the latest output's stamp) is sent at most this often (wall): the app's clock
follows the gateway's (the simulation's, in the demo) without a time message per output."""
RESUBSCRIBE_AFTER_NS = 1_000_000_000
"""A channel made while a client is connected is advertised again (closed and made anew) if a connected
client has not subscribed to it within this long (wall), doubled after each time, at most
`READVERTISE_MAX` times: the SDK sends the advertisement before it registers the channel for that
client, so a client that answers at once (on a busy machine, where the sending thread can be preempted
between the two) has its subscription refused ("Unknown channel ID") and would never get the channel's
data. The wait doubles because a client slowed by the same busy machine may take longer than a second to
answer, and advertising again meanwhile loses its answer too (seen on a loaded CI machine: a channel
advertised three times in three seconds and never received). A client that does not want the channel
(the app subscribes to what its panels show) costs a few extra advertisements in its first minute."""
READVERTISE_MAX = 5  # waits of 1, 2, 4, 8 and 16 s: given up after about half a minute
BEFORE_ANSWER_NS = 10_000_000_000
"""A channel made while no client has subscribed to anything yet is watched this long (wall) for a first
subscription. The server cannot tell "no client" from "a client connected whose answers have not come
yet" (the SDK says nothing of a connection until its first subscription), and such a client's answer to
this channel's advertisement may be lost as above: seen on a loaded CI machine, a client connected before
the first fix, its subscription to the fix channel lost, and the channel never advertised again because
no client had subscribed to anything when it was made. A channel older than this when the first client
subscribes was made before that client connected, and was advertised to it at its connection."""
SUBPROTOCOL = "foxglove.sdk.v1"
"""What the SDK's server speaks (its handshake refuses a client that does not offer it)."""


class FoxgloveServerError(OSError):
    """The server could not start (the port is in use, the address is not this computer's): one line
    saying what to do. An `OSError`, so the commands report it like any socket that cannot open."""


@functools.cache
def channel_schema(cls: type[Message]) -> foxglove.Schema:
    """The JSON Schema of a message class, as the MCAP log's channel carries it (`wire.message_schema`)."""
    data = json.dumps(json_schema(cls), separators=(",", ":"), ensure_ascii=False).encode()
    return foxglove.Schema(name=cls.TITLE or cls.__name__, encoding="jsonschema", data=data)


@dataclass
class ServerStats:
    """What the sink saw (the SDK's own per-client drops are not visible: module docstring)."""

    sent: int = 0
    held: int = 0
    superseded: int = 0
    errors: int = 0
    channels: int = 0
    readvertised: int = 0

    def as_dict(self) -> dict[str, int]:
        return {
            "sent": self.sent,
            "held": self.held,
            "superseded": self.superseded,
            "errors": self.errors,
            "channels": self.channels,
            "readvertised": self.readvertised,
        }


class _Listener(ServerListener):
    """The SDK's callbacks (on its own threads): subscriptions are logged, playback requests go to the
    replay's handler. Every method of the protocol is defined: the SDK calls each one."""

    def __init__(
        self,
        playback: Callable[[PlaybackControlRequest], PlaybackState | None] | None,
        subscriptions: _Subscriptions,
    ) -> None:
        self._playback = playback
        self._subscriptions = subscriptions

    # (per channel, a client's connect makes a line per channel each way: debug; the SDK says at info that a
    # client registered and left, which ``dpgw run -v`` shows)
    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        log.debug("foxglove: client %d subscribed to %s", client.id, channel.topic)
        self._subscriptions.change(client.id, channel.topic, 1)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        log.debug("foxglove: client %d unsubscribed from %s", client.id, channel.topic)
        self._subscriptions.change(client.id, channel.topic, -1)

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        return None

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        return None

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        return None

    def on_get_parameters(
        self, client: Client, param_names: list[str], request_id: str | None = None
    ) -> list:
        return []

    def on_set_parameters(self, client: Client, parameters: list, request_id: str | None = None) -> list:
        return parameters

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        return None

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        return None

    def on_connection_graph_subscribe(self) -> None:
        return None

    def on_connection_graph_unsubscribe(self) -> None:
        return None

    def on_playback_control_request(
        self, playback_control_request: PlaybackControlRequest
    ) -> PlaybackState | None:
        if self._playback is None:
            return None
        try:
            return self._playback(playback_control_request)
        except Exception:  # an exception would be lost in the SDK's thread: say it here
            log.exception("foxglove: playback request failed")
            return None


class _Subscriptions:
    """Which topics each client is subscribed to, from the SDK's callbacks (its threads, hence the lock).
    Counted, not a set: when a channel is made anew, the old channel's unsubscription may come after the
    new one's subscription."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._count: dict[int, dict[str, int]] = {}

    def change(self, client_id: int, topic: str, delta: int) -> None:
        with self._lock:
            topics = self._count.setdefault(client_id, {})
            topics[topic] = topics.get(topic, 0) + delta
            if topics[topic] <= 0:
                del topics[topic]
            if not topics:
                del self._count[client_id]

    def missing(self, topic: str) -> list[int]:
        """The clients subscribed to something but not to ``topic``."""
        with self._lock:
            return [c for c, topics in self._count.items() if topic not in topics]

    def any_client(self) -> bool:
        with self._lock:
            return bool(self._count)


@dataclass
class _Channel:
    channel: foxglove.Channel
    held: deque[tuple[bytes, int]] = field(default_factory=lambda: deque(maxlen=1))
    cls: type[Message] | None = None
    last: tuple[bytes, int] | None = None  # the last message made (what a re-advertisement holds)
    made_ns: int = 0  # when the channel was made (monotonic)
    readvertised: int = 0


class FoxgloveServerSink:
    """An `OutputSink` serving the pipeline's outputs to Foxglove over WebSocket.

    ``playback``: for a replay, the handler of the app's play/pause/seek/speed requests and the log's time
    range (ns); the server then advertises the playback-control capability. Live, the server advertises
    none (a live gateway cannot be paused)."""

    name = "foxglove"
    needs_zenoh = False  # started with the gateway even while a client's router has not answered

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8765,
        *,
        server_name: str = SERVER_NAME,
        playback: Callable[[PlaybackControlRequest], PlaybackState | None] | None = None,
        time_range_ns: tuple[int, int] | None = None,
        message_backlog_size: int | None = None,
        port_given_by: str = "--foxglove PORT or [foxglove] port",
    ) -> None:
        self.host = host
        self.requested_port = port
        self.port_given_by = port_given_by  # where the user gives another port: a failed start says it
        self.server_name = server_name
        self._playback = playback
        self._time_range_ns = time_range_ns
        self._backlog = message_backlog_size
        self.stats = ServerStats()
        self.server: WebSocketServer | None = None
        self._context: foxglove.Context | None = None
        self._channels: dict[str, _Channel] = {}
        self._waiting: set[str] = set()  # topics with held messages
        self._live_time = playback is None  # (a replay sends its own time: the player's log time)
        self._next_time_ns = 0
        self._subscriptions = _Subscriptions()
        self._watched: set[str] = set()  # channels a client may not have got (RESUBSCRIBE_AFTER_NS)
        self._next_watch_ns = 0

    # --- OutputSink ------------------------------------------------------------------------------------

    @property
    def port(self) -> int:
        """The port the server listens on (the one the system chose when asked for 0)."""
        return self.server.port if self.server is not None else self.requested_port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def app_url(self) -> str | None:
        """The Foxglove app link that opens this server as a data source."""
        return self.server.app_url() if self.server is not None else None

    def start(self, session: zenoh.Session | None = None) -> None:
        """Start listening; `FoxgloveServerError` (one line) when the address cannot be bound."""
        if self.server is not None:
            return
        self._context = foxglove.Context()  # this sink's own channels, never the SDK's global ones
        capabilities = [Capability.Time]
        if self._playback is not None:  # (live, the server offers only its time: nothing comes in)
            capabilities.append(Capability.PlaybackControl)
        try:
            self.server = foxglove.start_server(
                name=self.server_name,
                host=self.host,
                port=self.requested_port,
                capabilities=capabilities,
                server_listener=_Listener(self._playback, self._subscriptions),
                context=self._context,
                playback_time_range=self._time_range_ns if self._playback is not None else None,
                message_backlog_size=self._backlog,
            )
        except RuntimeError as exc:  # the SDK's FoxgloveError
            raise FoxgloveServerError(
                bind_problem(self.host, self.requested_port, str(exc), self.port_given_by)
            ) from None

    def emit(self, outputs: list[Output], encoded: list[bytes]) -> None:
        if self._waiting:
            self._flush_waiting()
        send = self.send
        latest = 0
        for o, body in zip(outputs, encoded, strict=True):
            send(o.topic, type(o.message), body, o.stamp_ns)
            latest = max(latest, o.stamp_ns)
        if self._live_time and latest and self.server is not None:
            now = time.monotonic_ns()
            if now >= self._next_time_ns:
                self._next_time_ns = now + TIME_EVERY_NS
                self.server.broadcast_time(latest)
        if self._watched:
            self._check_watched()

    def close(self) -> None:
        server, self.server = self.server, None
        if server is not None:
            server.stop()
        for ch in self._channels.values():
            ch.channel.close()
        self._channels.clear()
        self._waiting.clear()
        self._watched.clear()
        self._context = None

    # --- sending ---------------------------------------------------------------------------------------

    def send(self, topic: str, cls: type[Message], body: bytes, log_time_ns: int) -> None:
        """One message: to the subscribed clients, or held until the first subscribes."""
        ch = self._channels.get(topic)
        if ch is None:
            if self._context is None:
                return  # not started, or closed
            ch = self._channels[topic] = _Channel(
                self._new_channel(topic, cls), deque(maxlen=LOG_HELD if topic == LOG_TOPIC else 1), cls
            )
            self.stats.channels += 1
            # watched for a client that does not subscribe to it (`RESUBSCRIBE_AFTER_NS`), also while no
            # client has subscribed to anything yet (`BEFORE_ANSWER_NS`)
            ch.made_ns = time.monotonic_ns()
            self._watched.add(topic)
        ch.last = (body, log_time_ns)
        if ch.channel.has_sinks():
            try:
                ch.channel.log(body, log_time=log_time_ns)
                self.stats.sent += 1
            except Exception:
                self._error(topic)
            return
        if len(ch.held) == ch.held.maxlen:
            self.stats.superseded += 1
        ch.held.append((body, log_time_ns))
        self.stats.held += 1
        self._waiting.add(topic)

    def broadcast_time(self, time_ns: int) -> None:
        """The server's current time (the app's clock follows it; a replay sends its log time)."""
        if self.server is not None:
            self.server.broadcast_time(time_ns)

    def broadcast_playback_state(self, state: PlaybackState) -> None:
        if self.server is not None:
            self.server.broadcast_playback_state(state)

    def forget_held(self) -> None:
        """Drop what is held (a replay that seeks: what was held belongs to another time)."""
        for topic in self._waiting:
            self._channels[topic].held.clear()
        self._waiting.clear()

    def _new_channel(self, topic: str, cls: type[Message]) -> foxglove.Channel:
        return foxglove.Channel(
            topic, schema=channel_schema(cls), message_encoding="json", context=self._context
        )

    def _check_watched(self) -> None:
        """Advertise again a channel that a connected client has not subscribed to (RESUBSCRIBE_AFTER_NS)."""
        now = time.monotonic_ns()
        if now < self._next_watch_ns:
            return
        self._next_watch_ns = now + RESUBSCRIBE_AFTER_NS // 4
        anyone = self._subscriptions.any_client()
        for topic in list(self._watched):
            ch = self._channels[topic]  # (watched topics are made channels: both go only at close)
            if not anyone:  # nobody has answered yet: a client may be connected, its answers to come
                if now - ch.made_ns > BEFORE_ANSWER_NS:
                    self._watched.discard(topic)
                continue
            if now - ch.made_ns < RESUBSCRIBE_AFTER_NS << ch.readvertised:
                continue
            if not self._subscriptions.missing(topic) or ch.readvertised >= READVERTISE_MAX:
                self._watched.discard(topic)
                continue
            self._readvertise(topic, ch, now)

    def _readvertise(self, topic: str, ch: _Channel, now: int) -> None:
        """Close the channel and make it anew (a new id, advertised to every client), the last message held
        for the next subscriber."""
        assert ch.cls is not None
        ch.channel.close()
        ch.channel = self._new_channel(topic, ch.cls)
        ch.readvertised += 1
        ch.made_ns = now
        if ch.last is not None and topic != LOG_TOPIC:
            ch.held.clear()
            ch.held.append(ch.last)
            self._waiting.add(topic)
        self.stats.readvertised += 1
        # (debug: the SDK's race worked around, counted in `stats.readvertised`; a line per channel at
        # info filled a service's journal with one per slow client's channel under -v)
        log.debug("foxglove: %s advertised again (a client had not subscribed to it)", topic)

    def _flush_waiting(self) -> None:
        for topic in list(self._waiting):
            ch = self._channels[topic]
            if not ch.channel.has_sinks():
                continue
            self._waiting.discard(topic)
            while ch.held:
                body, ns = ch.held.popleft()
                try:
                    ch.channel.log(body, log_time=ns)
                    self.stats.sent += 1
                except Exception:
                    self._error(topic)

    def _error(self, topic: str) -> None:
        self.stats.errors += 1
        if self.stats.errors <= 3 or self.stats.errors % 1000 == 0:
            log.exception("foxglove: could not send on %s (#%d); carrying on", topic, self.stats.errors)


def bind_problem(
    host: str, port: int, sdk_message: str, given_by: str = "--foxglove PORT or [foxglove] port"
) -> str:
    """The one line a failed start prints: what could not be bound, why, and what to do (``given_by``:
    where this command takes another port; `dpgw demo` and `dpgw replay` have no config)."""
    where = f"{host}:{port}"
    if "in use" in sdk_message:
        return (
            f"foxglove: cannot listen on {where}: the port is in use (another dpgw or Foxglove server?); "
            f"give another with {given_by}, or 0 for any free port"
        )
    if "assign requested address" in sdk_message or "not available" in sdk_message:
        return (
            f"foxglove: cannot listen on {where}: {host} is not an address of this computer; "
            "give one of its addresses, 127.0.0.1 for this computer only or 0.0.0.0 for every interface"
        )
    return f"foxglove: cannot listen on {where}: {sdk_message}"


def foxglove_sink(config: GatewayConfig) -> FoxgloveServerSink:
    """The sink ``[foxglove]`` describes."""
    f = config.foxglove
    return FoxgloveServerSink(f.host, f.port)
