"""The live gateway: sources → one queue → the pipeline → Zenoh and MCAP (`dpgw run`).

Threads: one reader per source (``gateway.sources``) and the Zenoh callbacks put events on a single queue;
one consumer (the caller of `GatewayService.run`) takes them in arrival order, logs every raw chunk before
anything else looks at it (rule 4: nothing is lost), feeds the deterministic pipeline and publishes what it
returns. An unexpected exception while handling one item (a bug, not bad input: bad input is counted by
the pipeline) does not stop the service: it is logged with its traceback, counted per source as
``rejected["internal_error"]`` in ``/status`` with an alarm, and the loop goes on with the next item; the
raw chunk is already in the MCAP log, so the failing input can be replayed to find the bug.

Inputs from Zenoh (setpoint, mode, manual τ) become events on the same queue and are logged too, so a
replay sees exactly what the live run saw. Status goes out at ``status.rate_hz`` and answers the queryable
``<prefix>/status``. SIGINT/SIGTERM stop the loop; the log is flushed and closed.

Time: with ``[time] clock = "wall"`` (the default; at sea, always) a chunk is stamped with its receive time on
this computer's clock, kept free of its backward steps (`gateway.wall_time`: a clock stepped back would make
every reference fail its jump test at once). With ``clock = "sim"`` it is stamped with the simulation time a
simulator publishes on ``<prefix>/sim/clock`` (`gateway.sim_time`: interpolated between ticks, never more than
one tick ahead), so everything downstream (observer, controller, commands, log, reference checks, dead
reckoning) lives on the plant's time. Until the first tick arrives there is no time to stamp with: what is
received is held, in order (at most `HOLD_MAX` items, the oldest written to the log unhandled, on this
computer's clock, and counted; the log then goes on in the next file of its set at the first tick, so that no
file mixes the two clocks), and handled, stamped with the first tick's time, when it comes. Input shed or
left at a stop that has no time yet waits the same way, for the log only. A simulator started again under
the gateway (its time goes back) is followed: the log goes on in the next file of its set, the pipeline
starts over as at start-up, and the stamps come from the new run's ticks (`GatewayService._follow_new_run`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import msgspec
import zenoh

from gateway.bus import (
    JSON,
    REDIAL_S,
    Dialler,
    UnreachableError,
    command_acl,
    make_config,
    open_session,
    unlinked,
)
from gateway.config import GatewayConfig, ZenohConfig, config_notes, start_mode_line, wind_feedforward_line
from gateway.config.logged import SIGNING_VERDICTS_KEY, for_log
from gateway.outputs import InputSink, OutputSink, RawSentenceSink
from gateway.pipeline import (
    SIGNING_REJECTED_TOPIC,
    TICK_TOPIC,
    ControlEvent,
    Output,
    Pipeline,
    PipelineSpec,
    RawEvent,
)
from gateway.sim_time import SimTime
from gateway.sources import Chunk, SerialSource, SeveralSourcesError, Source, SourceError, open_source
from gateway.wall_time import WallTime
from wire.codecs import mavlink as mv
from wire.mcap.folder import make_log_folder
from wire.mcap.writer import McapLogWriter
from wire.messages import (
    SIM_CLOCK_KEY,
    DeadReckoningTick,
    SimClock,
    Status,
    ThrusterCommand,
    logged_input,
)

log = logging.getLogger("dpgw")

COMPILE_NOTICE_S = 1.0
"""If the compiled kernels are not ready after this long at start-up, the gateway says it is compiling
them (a first run): from numba's cache they take 0.2-0.8 s."""

INPUT_KEYS = ("setpoint", "mode", "tau")
TRACEBACKS_LOGGED = 10
"""Internal errors logged with a full traceback per source; after that every 1000th, so that a bug hit by
every chunk of a 50 Hz source cannot flood the log."""
HOLD_SILENT_NS = 1_000_000_000
"""With ``clock = "sim"``: what is received after this long (wall ns) without a tick is held until the next
tick says which run of the plant it is of: this one's (a paused simulator continued) or a new one's (a
restarted simulator whose data came before its ticks got through). A simulator at 1x ticks every 50 ms."""
HOLD_MAX = 10_000
"""Items held while waiting for the first simulation clock tick (a minute of a busy bench's input)."""
CLOCK_SILENT_S = 5.0
"""With ``clock = "sim"``: no tick for this long (wall s) raises a status alarm."""
FOREIGN_ALARM_S = 10.0
"""How long another simulator's clock on this gateway's key keeps its alarm up after its last tick: the
count of its ticks is kept, but a bench whose second simulator was stopped or given its own prefix is
clear again."""
DRAIN_S = 10.0
"""After a stop, queued input is handled for at most this long (wall s), the rest written to the log as
received (`GatewayService.drain`): the whole stop stays well inside the systemd unit's TimeoutStopSec
(30 s), after which the process would be killed. ``dpgw run`` and ``dpgw demo`` stop the same way."""
BEHIND_S = 1.0
"""The consumer is behind when the input it handles was received this long ago (wall s): a status alarm
and one log line each way. The estimates and thruster commands then come from inputs that old."""
QUEUE_MAX = 10_000
"""Inputs waiting for the consumer beyond which the oldest sensor data is written to the log as received,
without the pipeline, and counted (`GatewayService.shed`): an overloaded gateway's memory is bounded, and
what it handles is its newest input, not input minutes old. Tens of seconds of a busy vessel's input
(a few hundred chunks a second), a few MB to some tens of MB. Inputs from Zenoh (setpoint, mode, τ) are
never shed: an operator's command is handled, however late."""
QUEUE_LIMIT = 4 * QUEUE_MAX
"""Inputs waiting beyond which what arrives is not queued at all, only counted (`GatewayService.lost`):
reached only by a consumer that has stopped turning (an output blocked for good, which systemd's watchdog
ends), never by one that is merely slow, which sheds each turn."""


class LogPathError(OSError):
    """The log cannot be opened where it is configured (its folder cannot be made, or is not writable):
    a mistake in the configuration, which stops start-up. `problem` says what and what to do."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


def _open_log(path: str, options: dict[str, Any]) -> McapLogWriter:
    """The gateway's log writer at ``path``, its folder made first when only that last level is missing
    (the default ``logs/dpgw.mcap`` and the examples' paths are in a folder beside the config that a fresh
    checkout or install does not have), and said; more missing is refused (`wire.mcap.folder`: a mistyped
    path must not scatter folders). ``continue_set``: a restarted service (systemd, a reboot) adds to the
    set, never overwrites it."""
    folder = os.path.dirname(os.path.abspath(path))
    fix = "choose a folder the gateway may write to (a service: its LogsDirectory, /var/log/dpgw)"
    try:
        if make_log_folder(path):
            log.warning("made the log's folder %s (it did not exist)", folder)
    except FileNotFoundError as exc:  # more than the folder missing (`log_folder_problem`'s words)
        raise LogPathError(str(exc)) from None
    except FileExistsError:
        raise LogPathError(f"cannot make the log's folder {folder}: a file is in the way — {fix}") from None
    except OSError as exc:
        raise LogPathError(f"cannot make the log's folder {folder}: {exc.strerror or exc} — {fix}") from None
    try:
        return McapLogWriter(path, profile="dpgw", continue_set=True, **options)
    except OSError as exc:
        raise LogPathError(f"cannot write {path}: {exc.strerror or exc} — {fix}") from None


@dataclass(frozen=True)
class _Input:
    """A Zenoh input (setpoint, mode, τ) as received, before it is stamped."""

    key: str
    payload: Any
    rx_ns: int
    rx_mono_ns: int


def _input_name(item: Chunk | _Input) -> str:
    """What an input is counted under: its source, or ``input <key>`` for one from Zenoh."""
    return f"input {item.key}" if isinstance(item, _Input) else item.source


def _utc(ns: int) -> str:
    """A simulation time (UTC ns) as a person reads it in the logs: 2026-06-01 10:02:23.7."""
    from datetime import UTC, datetime

    return datetime.fromtimestamp(ns / 1e9, UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-5]


def zenoh_config(z: ZenohConfig) -> zenoh.Config:
    """The `zenoh.Config` of the configured session (`gateway.bus.make_config`); opens nothing.

    The gateway's session never dials the peers it discovers (consoles and tools come to it, on the
    listeners the config names: loopback by default); with ``commanders``, only they may put on the
    command keys."""
    acl = None
    if z.commanders:
        acl = command_acl([f"{z.prefix}/{key}" for key in INPUT_KEYS], z.commanders)
    return make_config(
        mode=z.mode,
        connect=z.connect,
        listen=z.listen,
        multicast_scouting=z.multicast_scouting,
        config_file=z.config_file,
        dial_scouted=False,
        users_file=z.users_file,
        user=z.user,
        password=z.password,
        access_control=acl,
    )


def next_due(last_due: int | None, now: int, period: int) -> int:
    """The next time something done every ``period`` is due on a clock that may jump (a simulation's): a
    period after the last due time, so that the rate holds; from ``now`` where that is not within the
    coming period (the clock jumped forward past it, or went back as a simulation started over)."""
    ahead = (now if last_due is None else last_due) + period
    return ahead if now < ahead <= now + period else now + period


class GatewayService:
    def __init__(
        self,
        config: GatewayConfig,
        *,
        session: zenoh.Session | None = None,
        log_path: str | None = None,
        config_tables: dict[str, Any] | None = None,
        sinks: Sequence[OutputSink] = (),
        wait_for_ports: bool = False,
    ) -> None:
        self.config = config
        self.wait_for_ports = wait_for_ports
        """A serial port that does not exist at `start` is waited for (an alarm), not a `SourceError`."""
        self.sinks: list[OutputSink] = list(sinks)
        """Extra outputs (`gateway.outputs`): each gets every batch of outputs after the Zenoh puts."""
        self.config_tables = config_tables
        self.prefix = config.zenoh.prefix
        self.pipeline = Pipeline(PipelineSpec.from_config(config))
        self._session = session
        self._own_session = session is None
        self._queue: queue.Queue[Chunk | _Input] = queue.Queue()
        self._sources: list[Source] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._declared: list[Any] = []
        self._started: list[OutputSink] = []  # the sinks started (with the session), in order
        self._dialler: Dialler | None = None  # a client's session while its router is not up yet
        self._status_json = b"{}"
        self._status_lock = threading.Lock()
        self._wall0_ns = 0
        self.sim_time = SimTime() if config.time.sim else None
        """The simulation clock (``[time] clock = "sim"``), else None: stamps are this computer's time."""
        self.wall_time = WallTime()
        """Receive stamps with ``clock = "wall"``: this computer's UTC clock without its backward steps."""
        self._held: deque[tuple[Chunk | _Input, bool]] = deque(maxlen=HOLD_MAX)
        """What waits for a simulation time (`_take`), in receive order: (item, whether the pipeline handles
        it; False: shed, or left at a stop, it only goes to the log, on the same time as the rest)."""
        self.held_dropped = 0
        """Items dropped while waiting for a simulation clock tick (more than `HOLD_MAX` held)."""
        self.wall_file: str | None = None
        """With ``clock = "sim"``: the log file that holds what was let go of the hold before the first tick,
        on this computer's clock (`_log_input`); the simulation time goes to the next file of the set."""
        self._on_wall = 0  # inputs in the file being written on this computer's clock
        self.clock_rejected = 0
        """Simulation clock ticks that were not a valid `SimClock`."""
        self.runs_followed = 0
        """New runs of the plant followed: the simulator started again under the gateway (its time went
        back)."""
        self.stop_event = threading.Event()
        self.opened = False
        """`start` opened the sources, Zenoh and the log (False when stopped before it opened them)."""
        path = log_path if log_path is not None else config.log.path
        self._log_path = str(path) if path else None
        for note in config_notes(config):
            log.warning("%s", note)
        wind = wind_feedforward_line(config)
        # The start-up facts go to the text log here, in the service's words; the pipeline's start-up
        # events (the same facts) reach it with the first logged status (`_emit`): not said twice there
        self._start_facts = frozenset(self.pipeline.startup_events)
        """What the configuration alone makes the pipeline say at start (the start mode; the wind
        feed-forward off for a vessel without an anemometer, or with its gain 0): information, not a
        fault, also when a pipeline started over (a simulator restarted) says it again. The wind lost at
        run time is said in other words, and stays a warning."""
        self._said_at_start = set(self._start_facts)
        if wind:  # once, at start-up (also the first /status event when off)
            log.info("%s", wind)
        if config.control is not None and config.control.initial_mode == "dp":
            # whether DP waits for the observer: once, at start-up (also the first /status event)
            log.info("%s", start_mode_line(config))
        # MAVLink links that take the dialect's thruster commands: one encoder each (own sequence numbers,
        # signed when the link has a key)
        self._command_links: dict[str, Any] = {}
        self._command_targets: dict[str, dict[str, int]] = {}  # the controller's ids; 0: broadcast
        for sc in config.sources:
            if sc.protocol == "mavlink" and sc.commands:
                # the ids of the udpout hello (`gateway.sources.url`): an onboard computer, not a ground
                # station (255): an autopilot that counts any frame from its GCS system as the GCS being
                # there would trigger its GCS failsafe each time the commands pause
                mav = mv.encoder(src_system=1, src_component=mv.dialect().MAV_COMP_ID_ONBOARD_COMPUTER)
                if sc.signing_key is not None:
                    mv.setup_signing(mav, sc.signing_key, link_id=1)
                else:  # the config refuses this unless allow_unsigned = true was written
                    log.warning(
                        "source %s: thruster commands go out UNSIGNED (allow_unsigned = true): anyone who "
                        "can write to this link can drive the thrusters; set a signing_key",
                        sc.name,
                    )
                self._command_links[sc.name] = mav
                self._command_targets[sc.name] = {
                    "target_system": sc.system_id or 0,
                    "target_component": sc.component_id or 0,
                }
        self.log: McapLogWriter | None = None
        self.published = 0
        self._zenoh_reached = True  # (a lost connection is logged when it is found lost, once)
        self._zenoh_ever_reached = False
        """A ``connect`` endpoint (or a peer) was reached once: a later miss is a loss, an earlier one is an
        endpoint not up yet (a bench's gateway started before its simulator), and is said so."""
        self.internal_errors: Counter[str] = Counter()  # source name or "input <key>" -> items not handled
        self.behind_ns = 0
        """How long ago the input last handled was received (0 when none waited): the consumer's lag."""
        self.behind_max_ns = 0
        """The largest `behind_ns` of the present spell behind (0 while not behind)."""
        self.heartbeat: Callable[[], None] | None = None
        """Called at every turn of the consumer loop (`dpgw.sd_notify`: systemd's watchdog): a loop that
        stops turning stops calling it."""
        self.logged_unhandled = 0
        """Inputs still queued at the end of `drain`'s time, written to the log without being handled."""
        self.drain_s = DRAIN_S
        """How long `drain` handles what is queued at a stop (wall s) before it only logs the rest."""
        self.queue_max = QUEUE_MAX
        """Inputs waiting beyond which the oldest sensor data is logged unhandled (`QUEUE_MAX`); what
        arrives while ``4 * queue_max`` wait is counted as lost (`QUEUE_LIMIT`)."""
        self.shed: Counter[str] = Counter()
        """Per source (or ``input <key>``): inputs written to the log without being handled because more
        than `queue_max` were waiting (the consumer's thread only)."""
        self.lost: Counter[str] = Counter()
        """Per source: inputs neither handled nor logged: ``4 * queue_max`` were waiting, or one to be shed
        had no log to go to."""
        self._lost_lock = threading.Lock()  # (`lost` is counted by the receiving threads)
        self._status_ns = 0  # the stamp of the periodic status logged last
        self._ticked_ns = 0  # the newest time the loop ticked the pipeline at (what it made is logged at it)
        self.queue_peak = 0
        """The most inputs that have waited at once (bounded by ``4 * queue_max``)."""
        self._shedding = False  # said once per spell behind
        self._foreign_said = False  # another simulator's clock on the key: said once in the log

    # --- start and stop -------------------------------------------------------------------------------------

    def start(self) -> None:
        """Open everything; a source that cannot open raises `SourceError` (several: `SeveralSourcesError`,
        every source tried) and nothing is left running."""
        self._wall0_ns = time.time_ns()
        self._look_for_ports()
        # numba's kernels compiled (or loaded from its cache) before any source opens, not in the loop
        t0 = time.perf_counter()
        # from numba's cache this takes well under a second; the first run after an install or an upgrade
        # compiles for ~10-15 s, silent without -v: say so, once, if it has not finished after a second
        slow = threading.Timer(
            COMPILE_NOTICE_S,
            log.warning,
            (
                "compiling the numeric kernels (the first run after an install or an upgrade; about 15 s, "
                "then kept in numba's cache): the sources open when it is done",
            ),
        )
        slow.daemon = True
        slow.start()
        try:
            self.pipeline.compile_kernels()
        finally:
            slow.cancel()
        log.info("compiled kernels ready in %.2f s", time.perf_counter() - t0)
        if self.stop_event.is_set():  # stopped while compiling (seconds on a first run): open nothing
            return
        try:
            failed = self._open_sources()
            if failed:
                raise failed[0] if len(failed) == 1 else SeveralSourcesError(failed)
            if self._session is None:
                self._session = self._open_session()
            # A query that arrives before the loop's first status tick gets a real status, never ``{}``;
            # the consumer loop is not running yet, so reading the pipeline here is race-free. It is not
            # logged (the log is not open yet), so it leaves the start-up events to the first status that is
            # (`Pipeline.status_message`, ``remember=False``).
            with self._status_lock:
                self._status_json = self._status_without_time().message.encode()
            if self._session is not None:
                self._attach(self._session)
            self._start_sinks(self._session)
            if self._log_path:
                self.log = _open_log(self._log_path, self.config.log.writer_options())
                meta = {"vessel": self.config.vessel.name, "prefix": self.prefix}
                if self.config_tables is not None:  # lets replay rebuild exactly this pipeline (no keys)
                    ctl = self.pipeline.controller
                    fade = None if ctl is None else ctl.tuning.takeover_fade_s
                    meta["json"] = json.dumps(for_log(self.config_tables, takeover_fade_s=fade))
                # without the keys, a replay takes this log's verdicts on the signed links' frames
                meta[SIGNING_VERDICTS_KEY] = f"{SIGNING_REJECTED_TOPIC}<source>"
                self.log.add_metadata("dpgw.config", meta)
        except BaseException:
            self.close()
            raise
        self.opened = True

    def _look_for_ports(self) -> None:
        """Stop at once on a serial port that does not exist (unless ``wait_for_ports``): the kernels
        compile for ~15 s on a first run before the sources open, and a mistyped port was said only after
        that. A look at each serial path; if one is missing, every source is opened and closed again, so
        that the one error names every source that cannot open (`SeveralSourcesError`)."""
        if self.wait_for_ports:
            return
        made = [open_source(sc.name, sc.url, timeout_s=sc.timeout_s) for sc in self.config.sources]
        if not any(isinstance(src, SerialSource) and src.missing() is not None for src in made):
            return
        # start-up stops: every source tried now, so that one message names them all (a UDP port in use
        # too), each opened and closed again without reading (`Source.probe`)
        failed: list[SourceError] = []
        for src in made:
            try:
                src.probe()
            except SourceError as exc:
                failed.append(exc)
        raise failed[0] if len(failed) == 1 else SeveralSourcesError(failed)

    def _open_sources(self) -> list[SourceError]:
        """Open and start every source; those that cannot open, every one tried: a person fixes them all
        before the next try."""
        failed: list[SourceError] = []
        for sc in self.config.sources:
            try:
                src = open_source(sc.name, sc.url, timeout_s=sc.timeout_s)
                if isinstance(src, SerialSource):
                    src.wait_if_absent = self.wait_for_ports
                self._sources.append(src)
                src.start(self._enqueue)
            except SourceError as exc:
                failed.append(exc)
        return failed

    def _open_session(self) -> zenoh.Session | None:
        """The configured session; None while a client (``mode = "client"``, no ``config_file``) waits
        for its router: a `Dialler` opens it when the router answers and the consumer loop attaches it."""
        z = self.config.zenoh
        try:
            return open_session(zenoh_config(z))
        except UnreachableError as exc:
            if z.mode != "client" or z.config_file:  # a config file keeps what it says (Zenoh: fail)
                raise
            log.error("zenoh: %s; the gateway starts and dials it until it answers", exc.problem)
            self._dialler = Dialler(lambda: zenoh_config(z))
            self._zenoh_reached = False
            return None

    def _attach(self, s: zenoh.Session) -> None:
        """Declare the publishers, the input subscribers and the status queryable."""
        for topic in ("estimate", "measurement", "status", "thrusters/feedback", "thrusters/command"):
            key = f"{self.prefix}/{topic}"
            self._publishers[key] = s.declare_publisher(key, encoding=JSON)
        # The inputs' callbacks run on Zenoh's receiving thread, in the order the samples arrived
        # (``indirect=False``): with a plain callable, Zenoh gives each subscriber a Python thread of its
        # own, and a console's τ put right after its ``manual`` could overtake the mode and be refused.
        # The callbacks only decode and queue (a few Hz of small JSON), so they hold that thread briefly; it
        # waits for the interpreter's lock as any Python callback's thread does.
        for key in INPUT_KEYS:
            handler = zenoh.handlers.Callback(self._on_input(key), indirect=False)
            self._declared.append(s.declare_subscriber(f"{self.prefix}/{key}", handler))
        if self.sim_time is not None:
            key = f"{self.prefix}/{SIM_CLOCK_KEY}"
            self._declared.append(s.declare_subscriber(key, self._on_clock))
        self._declared.append(s.declare_queryable(f"{self.prefix}/status", self._on_query))

    def _start_sinks(self, session: zenoh.Session | None) -> None:
        """Start the sinks not started yet: without a session (a client whose router has not answered),
        only those that need no Zenoh (``needs_zenoh = False``: the Foxglove server), which then fail at
        start-up like the others (a port in use) and show the bridge the gateway meanwhile."""
        for sink in self.sinks:
            if sink in self._started or (session is None and getattr(sink, "needs_zenoh", True)):
                continue
            if isinstance(sink, InputSink):  # its commands take the path of <prefix>/<key>
                sink.bind_inputs(self.submit)
            sink.start(session)  # type: ignore[arg-type]  # None only for a sink that needs no Zenoh
            self._started.append(sink)
        taps = [sink for sink in self._started if isinstance(sink, RawSentenceSink)]
        if taps:
            self.pipeline.sentence_tap = self._sentence_tap(taps)

    def _take_dialled(self) -> None:
        """The session of a client whose router has just answered: attached on the consumer thread."""
        assert self._dialler is not None
        session = self._dialler.take()
        if session is None:
            return
        self._dialler.close()
        self._dialler = None
        self._session = session
        try:
            self._attach(session)
            self._start_sinks(session)
        except Exception:
            self._internal_error("zenoh", "the session opened when the router answered")
        log.warning("zenoh: connected to %s; outputs go out", ", ".join(self.config.zenoh.connect))
        self._zenoh_reached = self._zenoh_ever_reached = True

    def close(self) -> None:
        if self._dialler is not None:
            self._dialler.close()
            self._dialler = None
        for sink in self._started:
            try:
                sink.close()
            except Exception:
                log.exception("output sink %s did not close cleanly", sink.name)
        for src in self._sources:
            src.stop()
        self._sources.clear()
        for d in [*self._declared, *self._publishers.values()]:
            with contextlib.suppress(Exception):  # already gone with the session
                d.undeclare()
        self._declared.clear()
        self._publishers.clear()
        if self._own_session and self._session is not None:
            self._session.close()
            self._session = None
        if self.log is not None:
            self.log.close()
            self.log = None

    # --- Zenoh callbacks (other threads): only put on the queue ---------------------------------------------

    def submit(self, key: str, payload: Any) -> None:
        """An input (``setpoint``, ``mode``, ``tau``) as if it had just arrived on Zenoh: stamped, logged
        and checked like one (`dpgw demo` holds the scenario's station this way)."""
        self._enqueue(_Input(key, payload, time.time_ns(), time.monotonic_ns()))

    def _enqueue(self, item: Chunk | _Input) -> None:
        """Queue an input for the consumer (from any thread), unless ``4 * queue_max`` already wait: then
        it is counted as lost (`QUEUE_LIMIT`: a consumer that has stopped turning), as a kernel counts
        the datagrams its full buffer drops."""
        waiting = self._queue.qsize()
        if waiting >= 4 * self.queue_max:
            with self._lost_lock:
                self.lost[_input_name(item)] += 1
            return
        self._queue.put(item)
        if waiting >= self.queue_peak:  # (racy between receiving threads: one off at worst)
            self.queue_peak = waiting + 1

    def _on_input(self, key: str) -> Any:
        def handler(sample: zenoh.Sample) -> None:
            try:
                payload = json.loads(sample.payload.to_bytes())
            except (ValueError, RecursionError):  # (nested deeper than the parser goes: RecursionError)
                payload = {"invalid": sample.payload.to_bytes().decode("utf-8", "replace")}
            self._enqueue(_Input(key, payload, time.time_ns(), time.monotonic_ns()))

        return handler

    def _on_clock(self, sample: zenoh.Sample) -> None:
        """A simulation clock tick: taken at once (not queued), so a chunk the simulator sends after the
        tick is stamped from it even while the consumer is behind."""
        mono = time.monotonic_ns()
        assert self.sim_time is not None
        try:
            tick = msgspec.json.decode(sample.payload.to_bytes(), type=SimClock)
        except (msgspec.DecodeError, msgspec.ValidationError):
            self.clock_rejected += 1
            return
        self.sim_time.on_tick(tick.stamp_ns, tick.period_s, mono, tick.run)
        if self.sim_time.foreign and not self._foreign_said:
            # (said once; also when the first were counted by `SimTime.pin`, which has no log)
            self._foreign_said = True
            log.warning("%s", self._foreign_clock_alarm())

    def _on_query(self, query: zenoh.Query) -> None:
        with self._status_lock:
            body = self._status_json
        query.reply(f"{self.prefix}/status", body, encoding=JSON)

    def last_status(self) -> dict[str, Any]:
        """The status last published (what a query on ``<prefix>/status`` gets); safe from any thread."""
        with self._status_lock:
            body = self._status_json
        status: dict[str, Any] = json.loads(body)
        return status

    # --- the consumer loop ---------------------------------------------------------------------------------

    def _now(self) -> int | None:
        """The pipeline's time now: this computer's (UTC ns), or the simulation's (None before its first
        tick)."""
        if self.sim_time is None:
            return self.wall_time.now()
        return self.sim_time.now(time.monotonic_ns())

    def _stamp(self, item: Chunk | _Input) -> int | None:
        """The time an item is handled at: its receive time, on the configured clock."""
        if self.sim_time is None:
            return self.wall_time.stamp(item.rx_ns, item.rx_mono_ns)
        return self.sim_time.stamp(item.rx_mono_ns)

    def run(self, duration_s: float | None = None) -> None:
        """Consume events until `stop_event` is set (or ``duration_s`` of wall time has passed)."""
        status_period_ns = int(1e9 / self.config.status.rate_hz)
        next_status = time.monotonic_ns()  # (a step of the UTC clock must not stop the status)
        # On the simulation's clock the status keeps its rate in the simulation's time, as everything the
        # gateway logs does: on the wall clock, a simulator at 10x gave a log one status per 10 s of its
        # time. Before the first time (nothing received, no clock tick), the wall schedules it.
        next_status_sim: int | None = None
        deadline = None if duration_s is None else time.monotonic() + duration_s
        while not self.stop_event.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                break
            if self.heartbeat is not None:
                try:  # (the supervisor's watchdog: a failure to tell it is counted, never stops the loop)
                    self.heartbeat()
                except Exception:
                    self._internal_error("watchdog", "the watchdog notification")
            if self._dialler is not None:
                self._take_dialled()
            try:
                item = self._queue.get(timeout=0.05)
            except queue.Empty:
                item = None
            if item is not None and self._queue.qsize() >= self.queue_max:
                item = self._shed_oldest(item)
            elif item is None:
                self._shedding = False  # (caught up: a next spell is said again)
            st = self.sim_time
            if item is not None:
                self._take(item)
            elif st is not None and st.started and (self._held or st.went_back is not None):
                if st.went_back is not None:  # nothing of the old run waits: follow the new one now
                    self._follow_new_run()
                self._release_held()
            self._measure_lag(item)
            mono = time.monotonic_ns()
            # While items wait in the queue, "now" is the newest time handled (none before the first): a
            # consumer that is behind (a busy machine) must not see its sources as silent, nor dead-reckon
            # past data it holds.
            now = self._now() if self._queue.empty() else (self.pipeline.last_ns or None)
            if now is not None:
                self._ticked_ns = max(self._ticked_ns, now)
                try:  # dead reckoning while every source is silent; sources going stale
                    ticked = self.pipeline.tick(now)
                    if self.pipeline.dead_reckoned:
                        self._log_tick(now)
                    self._emit(ticked)
                except Exception:
                    self._internal_error("tick", "the dead-reckoning tick")
            on_sim = self.sim_time is not None and now is not None
            if on_sim and now is not None:
                due = next_status_sim is None or not (now < next_status_sim <= now + status_period_ns)
            else:
                due = mono >= next_status
            if due:
                next_status = mono + status_period_ns
                if on_sim and now is not None:
                    next_status_sim = next_due(next_status_sim, now, status_period_ns)
                try:
                    if now is None:  # no time yet: the status goes out (stamped with the wall), not logged
                        self._publish([self._status_without_time()])
                    else:
                        # never before the one before, nor before a tick's outputs already logged: "now"
                        # is the clock's present while the queue is empty and the newest input handled
                        # while it is not, which can be behind a tick at the clock's present (a status
                        # stamped there went into the log after a dead-reckoned estimate of a later time)
                        self._status_ns = max(now, self._status_ns, self._ticked_ns)
                        self._emit(self.pipeline.status_outputs(self._status_ns, self._alarms()))
                except Exception:
                    self._internal_error("status", "the status")

    def _log_tick(self, now: int) -> None:
        """A tick that dead-reckoned moved the controller and the allocation on (and a copy of the
        observer): logged before its outputs, as an input is, so that a replay ticks at the same times
        (`gateway.pipeline.TICK_TOPIC`) and its commands after a silence are the live run's."""
        if self.log is not None:
            body = DeadReckoningTick(silent_s=self.pipeline.silence_s(now))
            self.log.write(TICK_TOPIC, body, now, now)

    def _shed_oldest(self, item: Chunk | _Input) -> Chunk | _Input | None:
        """More than `queue_max` wait: the oldest sensor data (``item`` first) is written to the log as
        received, without the pipeline, and counted, until fewer wait; returns the input to handle next
        (None: the queue emptied meanwhile). A Zenoh input (setpoint, mode, τ: an operator's) stops the
        shedding and is handled; so is a source's end-of-stream mark (its empty chunk). The pipeline then
        handles newer data, after a gap, as after a source silent for a while (a sentence cut by the gap
        is counted as rejected); a replay of the log handles what was shed."""
        if not self._shedding:
            self._shedding = True
            log.error(
                "gateway overloaded: more than %d inputs waiting; the oldest sensor data is written to the "
                "log without being handled (counted in /status) until it catches up",
                self.queue_max,
            )
        while isinstance(item, Chunk) and item.data and self._queue.qsize() >= self.queue_max:
            if self.log is None:  # (no log to write it to)
                with self._lost_lock:
                    self.lost[item.source] += 1
            else:  # to the log on the time it would have been handled at (held with the rest if need be)
                self.shed[item.source] += 1
                self._take(item, handle=False)
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return None
        return item

    def final_status(self) -> Output:
        """The status at the end of a run: at the pipeline's last time, or (nothing ever arrived, so it has
        none) at the wall clock, not at 1970 with every source "stale" for 56 years. With the alarms and
        the links' counts as they are now (`_alarms`). Never stamped before the periodic status logged
        last, which goes out at the simulation clock's present, ahead of the last input handled, nor before
        the last tick (a dead-reckoned estimate at the clock's present): the last status by log time (what
        a replay and a viewer take as the run's) is this one. The status alone (`dpgw run`'s summary);
        what `drain` logs is `final_status_outputs`."""
        last = self.pipeline.last_ns
        if not last:
            return self._status_without_time()
        return self.pipeline.status(self._final_status_ns(), self._alarms())

    def final_status_outputs(self) -> list[Output]:
        """`final_status` with its Foxglove log lines after it (`Pipeline.status_outputs`): what is logged."""
        if not self.pipeline.last_ns:
            return [self._status_without_time()]
        return self.pipeline.status_outputs(self._final_status_ns(), self._alarms())

    def _final_status_ns(self) -> int:
        """The last status's stamp: the pipeline's last time, the periodic status logged last, the last
        tick, whichever is latest (`final_status`)."""
        return max(self.pipeline.last_ns, self._status_ns, self._ticked_ns)

    def _status_without_time(self) -> Output:
        """The status while the pipeline has no time yet (``clock = "sim"`` before the first tick; and the
        one made at start-up for a query): stamped with the wall clock for Zenoh and ``dpgw run -v``, and
        kept out of everything that is logged, its Foxglove log lines included (a line at the wall clock in
        a log on the plant's time, months apart, would stretch the log's timeline and make the writer rotate
        the file). It says no event: the start-up events wait for the first status that is logged, which
        Zenoh gets too."""
        now = time.time_ns()
        return Output("/dp/status", self.pipeline.status_message(now, self._alarms(), remember=False), now)

    def _take(self, item: Chunk | _Input, handle: bool = True) -> None:
        """Handle an item, or hold it while there is no simulation time for it yet: before the first tick,
        and (`HOLD_SILENT_NS`) while the clock has been silent, until a tick says which run it belongs to.
        ``handle=False``: an item the pipeline does not get (shed, or left at a stop) goes the same way to
        the log only: held like the rest, it is written in receive order, on the time (and in the file of
        the run) the rest is; written at once, it was stamped on this computer's clock before the first
        tick, and ahead of what was held, on the old run's time, after a silence."""
        st = self.sim_time
        if st is None:
            self._handle_or_log(item, handle)
            return
        if st.went_back is not None and st.of_new_run(item.rx_mono_ns, HOLD_SILENT_NS):
            self._follow_new_run()  # (what came before it, the old run's, has been handled)
        if self._held:
            self._release_held()
        if not st.started or self._held or st.silent_since(item.rx_mono_ns, HOLD_SILENT_NS):
            if len(self._held) == HOLD_MAX:  # the oldest makes room: into the log, unhandled
                oldest, handled = self._held.popleft()
                logged = self._log_input(oldest)
                if handled:  # (one shed was counted so)
                    self.held_dropped += 1
                    self.logged_unhandled += logged
            self._held.append((item, handle))
            return
        self._handle_or_log(item, handle)

    def _handle_or_log(self, item: Chunk | _Input, handle: bool) -> None:
        if handle:
            self._handle(item)
        else:
            self._log_input(item)

    def _release_held(self) -> None:
        """What is held, in order, as soon as a tick came after it (what came before the first tick is
        stamped with the first tick's time). Once the simulator has started again (its time went back),
        what is held came between the old run's last tick and the new run's first: the new run's, handled
        in it, stamped with its first tick's time."""
        st = self.sim_time
        while self._held and st is not None and st.started:
            if st.went_back is not None:
                self._follow_new_run()
            if st.silent_since(self._held[0][0].rx_mono_ns, HOLD_SILENT_NS):
                return  # no tick since: which run it is of is not known yet
            self._handle_or_log(*self._held.popleft())

    def drain(self, within_s: float | None = None) -> None:
        """Handle whatever is already queued (used at shutdown so nothing received is dropped); what is
        still held for want of a simulation clock is written to the log unhandled (`_log_input`: which run
        of the plant it belongs to, and so its time, is not known).
        Then the last status goes out and into the log, with every count of the run: the periodic one
        (1 Hz) leaves up to a second of the run out, and a log's last status is what a replay reports of
        the live run (e.g. the frames the live gateway refused for signing).

        ``within_s`` (default `drain_s`): what is still queued after that long is written to the log as
        received, without the pipeline. A gateway far behind (`BEHIND_S`) held minutes of input in its
        queue, and handling it all after SIGTERM took minutes (measured: over two) while systemd kills a
        service that has not stopped after its ``TimeoutStopSec`` (30 s in the shipped unit): the log was
        cut without its summary and what was queued was lost. Outputs of input that old help nobody once
        the gateway is stopping; its bytes in the log do (a replay handles them). ``dpgw run`` and ``dpgw
        demo`` both stop through here with the default bound (the demo handled all of its queue)."""
        within_s = self.drain_s if within_s is None else within_s
        deadline = time.monotonic() + within_s
        logged_only = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if time.monotonic() >= deadline:
                if self.log is not None:  # (after what is held, if anything is: in receive order)
                    self._take(item, handle=False)
                    logged_only += 1
                continue
            self._take(item)
        if logged_only:
            log.warning(
                "stopping: %d inputs still queued after %.0f s were logged without being handled",
                logged_only,
                within_s,
            )
        held = 0
        while self._held:
            item, handled = self._held.popleft()
            logged = self._log_input(item)
            held += logged if handled else 0  # (the others are counted as shed or left above)
        if held:
            log.warning(
                "stopping: %d inputs held for want of a simulation clock tick were logged unhandled", held
            )
        self.logged_unhandled += logged_only + held
        if self.pipeline.last_ns:
            try:
                self._emit(self.final_status_outputs())
            except Exception:
                self._internal_error("status", "the last status")

    def _log_input(self, item: Chunk | _Input) -> int:
        """Write ``item`` to the log as it was received, without the pipeline (shed, left at a stop, let go
        by a full hold); 1 if it was written. Stamped on the configured clock; under ``clock = "sim"``
        before its first tick there is no simulation time, nor any way to know which the first tick will
        bring, and the item gets its receive time on this computer's clock: the file then holds this
        computer's time, and the simulation time, if it comes, goes to the next file of the set
        (`_leave_wall_file`), so that no file mixes the two. A replay handles it; dropping it lost what the
        sensors said; keeping it until the first tick would not bound memory."""
        rx = self._stamp(item)
        if rx is None:
            return int(self._log_received(item, self.wall_time.stamp(item.rx_ns, item.rx_mono_ns), wall=True))
        return int(self._log_received(item, rx))

    def _log_received(self, item: Chunk | _Input, rx: int, wall: bool = False) -> bool:
        """Write ``item`` to the log as it was received, stamped ``rx`` (``wall``: on this computer's clock
        while the simulation's has not started): a command input on its ``/dp/`` topic, a chunk on its
        source's raw channel. False when not written (no log, an unknown source)."""
        if self.log is None:
            return False
        if wall:
            self._on_wall += 1
        elif self._on_wall:
            self._leave_wall_file()
        if isinstance(item, _Input):
            # on its own channel when it fits that channel's schema (a mode wrapped as {mode}), else as
            # text on the malformed inputs' (`wire.messages.logged_input`): a replay feeds either
            topic, body = logged_input(item.key, item.payload)
            self.log.write(topic, body, rx, rx)
            return True
        spec = self.pipeline.sources.get(item.source)
        if spec is None:
            return False
        if spec.protocol == "nmea":
            self.log.write_raw_nmea(item.source, item.data, rx, rx, peer=item.peer)
        else:
            self.log.write_raw_mavlink(item.source, item.data, rx, rx, peer=item.peer)
        return True

    def _alarms(self) -> list[str]:
        alarms = [  # with what the OS last said: "port ... failed", "... not an address of this computer"
            f"source {s.name}: disconnected" + (f" ({s.stats.last_error})" if s.stats.last_error else "")
            for s in self._sources
            if not s.stats.connected and not s.finished
        ]
        self._copy_link_counts()
        for s in self._sources:
            dropped = getattr(s, "dropped", 0)
            if dropped:
                alarms.append(
                    f"source {s.name}: {dropped} datagrams dropped by the kernel (receive buffer full; "
                    "raise ?rcvbuf= or net.core.rmem_max)"
                )
        alarms += self._clock_alarms()
        alarms += self._behind_alarms()
        alarms += self._zenoh_alarms()
        if self.log is not None and self.log.error is not None:
            alarms.append(
                f"log: {self.log.error}; {self.log.lost} messages not logged; retrying every "
                f"{self.log.retry_s:g} s (outputs go on)"
            )
        alarms += [
            f"{what}: {n} not handled (internal error, traceback in the gateway's log)"
            for what, n in sorted(self.internal_errors.items())
        ]
        return alarms

    def _copy_link_counts(self) -> None:
        """What the transports count of their links into the pipeline's source counters, for a status:
        the datagrams the kernel dropped (UDP), the reconnects and the last disconnect. Once a status, not
        per chunk: the transports count where a link is lost or comes back."""
        for s in self._sources:
            counters = self.pipeline.counters.get(s.name)
            if counters is None:
                continue
            counters.dropped = getattr(
                s, "dropped", 0
            )  # UDP: the kernel's count of datagrams it could not hold
            counters.reconnects = s.stats.reconnects
            counters.last_disconnect = s.stats.last_disconnect

    def _measure_lag(self, item: Chunk | _Input | None) -> None:
        """How far behind the consumer is: the age of the input just handled (none: caught up). A consumer
        that cannot keep up (a machine overloaded, a source flooding, a slow output) lets inputs wait in
        the queue, and its estimates and commands are as late as they; nothing said so (measured: a
        gateway slowed under a profiler fell minutes behind a 5x simulator, whose vessel drifted 700 m
        off station under commands that late, with no alarm but the distance). Said once when it starts
        and once when it ends, an alarm meanwhile."""
        lag = 0 if item is None else max(0, time.monotonic_ns() - item.rx_mono_ns)
        was_behind = self.behind_max_ns > 0
        if lag > BEHIND_S * 1e9:
            if not was_behind:
                log.error(
                    "gateway behind: handling input received %.1f s ago (%d waiting); estimates and "
                    "commands are that late",
                    lag / 1e9,
                    self._queue.qsize(),
                )
            self.behind_max_ns = max(self.behind_max_ns, lag)
        elif was_behind and lag < BEHIND_S * 1e9 / 2:
            log.warning("gateway caught up (it was up to %.1f s behind)", self.behind_max_ns / 1e9)
            self.behind_max_ns = 0
            self._shedding = False
        self.behind_ns = lag

    def _behind_alarms(self) -> list[str]:
        """While behind: how late; over the whole run (a count does not come back): what the queue's
        bound (`QUEUE_MAX`, `QUEUE_LIMIT`) kept from the pipeline."""
        alarms = []
        if self.behind_max_ns:
            alarms.append(
                f"gateway behind: handling input received {self.behind_ns / 1e9:.1f} s ago "
                f"({self._queue.qsize()} waiting; up to {self.behind_max_ns / 1e9:.1f} s): estimates and "
                "commands are that late (is the computer overloaded, or a source flooding?)"
            )
        shed = sum(self.shed.values())
        if shed:
            per = ", ".join(f"{name} {n}" for name, n in sorted(self.shed.items()))
            alarms.append(
                f"gateway overloaded: {shed} inputs written to the log without being handled ({per}; more "
                f"than {self.queue_max} were waiting): a replay of the log handles them"
            )
        with self._lost_lock:
            lost = dict(self.lost)
        if lost:
            per = ", ".join(f"{name} {n}" for name, n in sorted(lost.items()))
            alarms.append(
                f"gateway overloaded: {sum(lost.values())} inputs lost, neither handled nor logged ({per}): "
                f"{4 * self.queue_max} were waiting (the gateway had stopped handling), or no log to write "
                "them to"
            )
        return alarms

    def _zenoh_alarms(self) -> list[str]:
        """With ``connect`` endpoints (a router, a simulator, a console), or a client dialling its router: an
        alarm naming each endpoint the session has no link to (`gateway.bus.unlinked`). It says outputs go
        nowhere only when the session has no peer nor router at all: a console on the gateway's own
        ``listen`` endpoint still has them while a simulator's endpoint is down. Zenoh redials the endpoints
        by itself (a restarted router is back within a second); a client's router that was not up when the
        gateway started is dialled by a `Dialler`, whose last failure, if another than nobody answering, the
        alarm adds. Meanwhile the status still goes to the log, Foxglove and ``dpgw run -v``."""
        connect = self.config.zenoh.connect or ["a router (multicast scouting)"]
        if self._dialler is not None:  # a client whose router has not answered yet
            down, anyone = connect, False
        elif not self.config.zenoh.connect or self._session is None:
            return []
        else:
            info = self._session.info
            down = unlinked(connect, self._session)
            anyone = any(True for _ in info.routers_zid()) or any(True for _ in info.peers_zid())
        reached = not down
        fate = "outputs go out" if anyone else "outputs are not reaching Zenoh"
        if reached != self._zenoh_reached:  # logged once each way
            if reached and self._zenoh_ever_reached:
                log.warning("zenoh: connected again (%s); outputs go out", ", ".join(connect))
            elif reached:
                log.warning("zenoh: connected to %s; outputs go out", ", ".join(connect))
            elif self._zenoh_ever_reached:
                until = " until it is back" if not anyone else " to the other peers"
                log.error("zenoh: lost %s (connect); %s%s", ", ".join(down), fate, until)
            else:  # never reached: not up yet, or a wrong endpoint; nothing was lost
                until = " until it answers" if not anyone else " to the other peers"
                log.error(
                    "zenoh: %s (connect) not reached yet (Zenoh redials it; is it up, and is the endpoint "
                    "right?); %s%s",
                    ", ".join(down), fate, until,
                )  # fmt: skip
            self._zenoh_reached = reached
        if reached:
            self._zenoh_ever_reached = True
            return []
        who = "Zenoh redials it" if self._dialler is None else f"dialled every {REDIAL_S:g} s"
        alarm = f"zenoh: not connected to {', '.join(down)} (connect; {who})"
        if not anyone:
            alarm += "; no Zenoh peer nor router reached: outputs go nowhere meanwhile"
        if self._dialler is not None and self._dialler.error is not None:
            alarm += f"; last dial: {self._dialler.error}"
        return [alarm]

    def _clock_alarms(self) -> list[str]:
        if self.sim_time is None:
            return self.wall_time.alarms()
        key = f"{self.prefix}/{SIM_CLOCK_KEY}"
        silent_s = self.sim_time.silent_s(time.monotonic_ns())
        alarms = []
        if silent_s is None:
            if time.time_ns() - self._wall0_ns > CLOCK_SILENT_S * 1e9:
                alarms.append(
                    f'clock: no simulation time on {key} yet (clock = "sim"): {len(self._held)} inputs '
                    "held; is the simulator publishing its clock on this prefix "
                    "(dpgw sim --zenoh --realtime)?"
                )
        elif silent_s > CLOCK_SILENT_S:
            held = f" ({len(self._held)} inputs held until one comes)" if self._held else ""
            alarms.append(f"clock: no simulation clock tick on {key} for {silent_s:.0f} s{held}")
        if self.held_dropped:
            # (logged only where there is a log: a gateway run without one has lost them)
            fate = "logged without being handled" if self.log is not None else "dropped (no log to keep them)"
            where = f"; those before the first, on this computer's clock, in {self.wall_file}"
            alarms.append(
                f"clock: {self.held_dropped} inputs {fate} while waiting for a tick "
                f"(more than {HOLD_MAX} held){where if self.wall_file else ''}"
            )
        if self.clock_rejected:
            alarms.append(f"clock: {self.clock_rejected} ticks on {key} were not a dpgw.SimClock")
        if self.sim_time.foreign:
            if time.monotonic_ns() - self.sim_time.foreign_mono_ns <= FOREIGN_ALARM_S * 1e9:
                alarms.append(self._foreign_clock_alarm())
            elif self._foreign_said:
                # the other simulator stopped (or was given its own prefix): the alarm clears, and it is
                # said again if one comes back
                self._foreign_said = False
                log.warning(
                    "clock: no tick of another simulator on %s for %g s: alarm cleared "
                    "(%d ticks ignored in all)",
                    key, FOREIGN_ALARM_S, self.sim_time.foreign,
                )  # fmt: skip
        return alarms

    def _foreign_clock_alarm(self) -> str:
        """Another simulator publishes its clock on this gateway's key while its own does (two benches on
        one network with one prefix): its ticks are ignored, and a person must part the two."""
        assert self.sim_time is not None
        st = self.sim_time
        theirs = f"run {st.foreign_run}" if st.foreign_run else "one that does not say its run"
        return (
            f"clock: another simulator's clock on {self.prefix}/{SIM_CLOCK_KEY} ({theirs}, not "
            f"run {st.run_id} that this gateway follows): {st.foreign} ticks ignored; two simulators share "
            'this prefix: give each bench its own ([zenoh] prefix here, "dpgw sim --prefix" there)'
        )

    def _leave_wall_file(self) -> None:
        """The simulation time has started, and the file being written holds inputs let go of the hold
        before it, on this computer's clock: finish that file and go on in the next of the set, on the
        simulation time, as a restarted simulator's run does (`_follow_new_run`). One file on two clocks
        (the wall's 2026 beside a scenario's epoch, months or years apart, in one channel) is out of order
        for a replay and stretches a viewer's timeline over the gap. Said once, in the next status."""
        assert self.log is not None
        n, self._on_wall = self._on_wall, 0
        self.wall_file = self.log.paths[-1].name if self.log.paths else None
        follows = self.log.rotate().name
        self.pipeline.say(
            f"clock: {n} inputs received before the first simulation clock tick were more "
            f"than the {HOLD_MAX} held for it: written unhandled to {self.wall_file}, on this computer's "
            f"clock (no simulation time yet); log continues in {follows}, on the simulation time"
        )

    def _follow_new_run(self) -> None:
        """The simulator started again under the gateway (a new run: its identity, or its time going
        back): follow the new run of the
        plant as a gateway started with it would. The log finishes its file and goes on in the next of the
        set, so each run is a file of its own that replays alone (one log of two runs on overlapping
        times could not be told apart). The pipeline starts over as at start-up (`Pipeline.start_over`:
        observers, fusion, reference tests, controller and mode, the sources' freshness), keeping its
        counts: the old run's estimate, setpoint and integrator are of another vessel's sea. The stamps
        come from the new run's ticks. Said once, in the gateway's log and in the next status."""
        st = self.sim_time
        assert st is not None
        newest, tick = st.follow()
        self.runs_followed += 1
        self._status_ns = self._ticked_ns = 0  # (the old run's time: not to be carried into the new file)
        where = ""
        if self.log is not None:
            where = f"; log continues in {self.log.rotate().name}"
        held = f"; {len(self._held)} inputs held for its first tick go to it" if self._held else ""
        moved = (
            f"went back {(newest - tick) / 1e9:.1f} s"
            if tick < newest
            else f"moved on {(tick - newest) / 1e9:.1f} s"
        )
        event = (
            f"clock: the simulator started again (the simulation time on {self.prefix}/{SIM_CLOCK_KEY} "
            f"{moved}, to {_utc(tick)} from {_utc(newest)}): following the new run (run {st.runs} of this "
            f"gateway){where}{held}"
        )
        # (said by the next status, on the new run's time: a status now could be stamped after the held
        # inputs, and the new file's times would not be in order)
        self.pipeline = self.pipeline.start_over(PipelineSpec.from_config(self.config), event)

    def _handle(self, item: Chunk | _Input) -> None:
        self._handle_item(item)
        # a setpoint is refused when it is applied (its distance needs the estimate), so after any item
        for r in self.pipeline.commands.take_refusals():
            log.warning("command refused: %s", r.text)

    def _handle_item(self, item: Chunk | _Input) -> None:
        rx = self._stamp(item)
        assert rx is not None  # held until the simulation clock has started
        # The input goes to the log before the pipeline sees it: whatever happens next, it is kept.
        self._log_received(item, rx)
        if isinstance(item, _Input):
            ev = ControlEvent(rx, item.key, item.payload)
            try:
                self._emit(self.pipeline.feed(ev))
            except Exception:
                self._internal_error(f"input {item.key}", f"the {item.key} input {item.payload!r:.200}")
            return
        try:
            self._emit(self.pipeline.feed(RawEvent(rx, item.source, item.data, peer=item.peer)))
        except Exception:
            self.pipeline.count_internal_error(item.source)
            self._internal_error(
                f"source {item.source}", f"a chunk of {len(item.data)} bytes (raw in the MCAP log)"
            )

    def _internal_error(self, what: str, item: str) -> None:
        """Count and log an unexpected exception (call from an ``except`` block); the loop carries on."""
        self.internal_errors[what] += 1
        n = self.internal_errors[what]
        if n <= TRACEBACKS_LOGGED or n % 1000 == 0:
            log.exception("internal error #%d (%s) while handling %s; carrying on", n, what, item)

    def _emit(self, outputs: list[Output]) -> None:
        for o in outputs:  # reference state changes go to the gateway's log as well as to /status
            if isinstance(o.message, Status):
                for text in o.message.events:
                    if text in self._said_at_start:
                        self._said_at_start.discard(text)
                        continue
                    (log.info if text in self._start_facts else log.warning)("%s", text)
        encoded = self._publish(outputs)
        for sink in self._started:
            try:
                sink.emit(outputs, encoded)
            except Exception:
                self._internal_error(f"sink {sink.name}", f"{len(outputs)} outputs")
        self._log_outputs(outputs, encoded)

    def _sentence_tap(self, taps: Sequence[RawSentenceSink]) -> Any:
        """Raw sentences to the sinks that take them; a sink's exception is its own internal error, not
        the source's (the chunk goes on through the pipeline)."""

        def tap(source: str, rx_ns: int, text: str, peer: str) -> None:
            for sink in taps:
                try:
                    sink.raw_nmea(source, rx_ns, text, peer)
                except Exception:
                    self._internal_error(f"sink {sink.name}", f"a sentence of {source}")

        return tap

    def _publish(self, outputs: list[Output]) -> list[bytes]:
        """Zenoh puts (estimate before measurement) and MAVLink commands; each message encoded once."""
        encoded = [o.message.encode() for o in outputs]
        order = sorted(range(len(outputs)), key=lambda k: outputs[k].topic != "/dp/estimate")
        for k in order:
            o, body = outputs[k], encoded[k]
            if o.zenoh and o.topic.startswith("/dp/"):
                pub = self._publishers.get(f"{self.prefix}/{o.topic[4:]}")
                if pub is not None:
                    pub.put(body)
                    self.published += 1
                if o.topic == "/dp/status":
                    with self._status_lock:
                        self._status_json = body
            if isinstance(o.message, ThrusterCommand) and self._command_links:
                self._send_mavlink_commands(o.message)
        return encoded

    def _log_outputs(self, outputs: list[Output], encoded: list[bytes]) -> None:
        if self.log is None:
            return
        if self._on_wall and outputs:  # (outputs are on the pipeline's time: the simulation's)
            self._leave_wall_file()
        for o, body in zip(outputs, encoded, strict=True):
            self.log.write_encoded(o.topic, body, o.stamp_ns, o.stamp_ns, schema=type(o.message))

    def _send_mavlink_commands(self, cmd: ThrusterCommand) -> None:
        """AZIMUTH_THRUSTER_COMMAND per thruster down every MAVLink link configured with commands = true,
        addressed to the source's ``system_id`` / ``component_id`` (0, broadcast, where not set) and sent to
        the sender of the last frame the link accepted. Before the first one they go only down a link with
        one far end (serial, TCP client, UDP with a target), never to an unknown sender of a shared one."""
        sources = {s.name: s for s in self._sources}
        for name, mav in self._command_links.items():
            src = sources.get(name)
            if src is None:
                continue
            target = self._command_targets[name]
            mv.keep_signing_time(mav, time.time())  # a drive that rebooted takes the stream as new
            frames = b"".join(
                mv.azimuth_command_frame(
                    mav, cmd.stamp_ns // 1000, int(th.id), th.thrust_n, th.azimuth_rad, **target
                )
                for th in cmd.thrusters
            )
            peer = self.pipeline.mavlink_peer.get(name)
            if not frames:
                continue
            if (peer is None and src.shared) or not src.write(frames, peer):
                src.stats.count_error("command not sent")  # (a shared link: no drive heard from yet)
