"""``dpgw replay``: logged sea trials back through the pipeline, with other tunings or observers."""

from __future__ import annotations

import argparse
import functools
import json
import signal
import sys
import textwrap
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from dpgw import cli_json
from dpgw.cli_foxglove import add_foxglove_arg, connect_lines
from dpgw.cli_paths import mcap_path_problem, output_folder_problem, unwritable
from dpgw.cli_progress import terminal_bar
from dpgw.cli_types import flags_given, non_negative_float, positive_float
from dpgw.cli_zenoh import ZENOH_FLAGS, add_endpoint_args, listen_endpoints
from dpgw.scored_stretch import DP_SETTLE_S, MIN_SCORED_S, SETTLE_S
from observers.observer_names import OBSERVER_NAMES

if TYPE_CHECKING:
    import numpy as np

    from dpgw.raw_feedback import Comparison
    from gateway.pipeline import Output
    from gateway.replay import Event, ObserverSpec, ReplayResult
    from gateway.report.data import ThrustTrace
    from observers.vessel import VesselModel

# Only the parser is built at import; the pipeline (numpy, numba, scipy) and Zenoh are imported by the
# functions that replay, so `dpgw replay --help` answers at once.

# The keys of an observer spec that set the passive tuning (`gateway.replay.TUNING_KEYS`, written out here
# so that --help imports no numerics; a test holds the two equal).
SPEC_TUNING_KEYS = (
    "wave_period_s",
    "omega0",
    "zeta",
    "zeta_n",
    "cutoff_ratio",
    "omega_c",
    "bias_time_constant_s",
    "velocity_injection_ratio",
    "velocity_injection",
    "injection_damping_ratio",
    "bias_corner_ratio",
    "bias_corner",
)
SPEC_TUNING_KEYS_TEXT = "\n  ".join(textwrap.wrap(", ".join(SPEC_TUNING_KEYS), 76))

NAME = "replay"
HELP = "re-run observers on recorded logs (MCAP, NMEA text, MAVLink tlog), with a report"
DESCRIPTION = (
    "Feed recorded logs through the same pipeline as the live gateway, as fast as the CPU allows: "
    "the gateway's own MCAP logs (re-decoded from their raw channels: a live log is reproduced bit "
    "for bit), simulator logs (scored against their ground truth), raw NMEA text logs (time from the "
    "sentences; headings from a gyro faster than the fixes spread between them) and MAVLink tlogs. "
    "Several observer specs run side by side in one pass. Bad input (truncated lines, garbage, checksum "
    "failures, time gaps, backwards or repeated time, duplicates) is counted, never fatal."
)
EPILOG = (
    "observer specs: NAME[:key=value,...][@label]; keys: the observer's own\n"
    "(a wrong key lists them) and of the passive tuning, all of which passive,\n"
    "gain_scheduled and memory use:\n"
    f"  {SPEC_TUNING_KEYS_TEXT}\n"
    "sdre and ekf use only wave_period_s, omega0 and zeta; mmae none (its zeta\n"
    "is its own); a list is numbers joined by /: mmae:candidates=2/2.8/3.6/4.5\n"
    "wave periods and frequencies are the vessel's own scale, used as given; what\n"
    "a spec leaves out is the config's tuning, whose default is a ship's 7 s sea,\n"
    "Froude-scaled on a model (times / sqrt(scale): 0.84 s on 1:70 cybership2).\n"
    "every replay checks the measured wave peak against the wave frequency each\n"
    "observer used and warns, with a spec to re-run with, when they differ by\n"
    "more than a factor 1.4; a log without a clear wave peak (calm, short, under\n"
    "way) gets a note that the check could not be made. --report also warns of an\n"
    "observer whose LF estimate amplifies the motion at the measured peak\n"
    "(attenuation above 0 dB), on the console and in report.md, which lists\n"
    "every such line. Every replay checks the vessel against the log: motion\n"
    "faster than the vessel makes (a clear peak above its wave band: a small craft\n"
    "replayed as a ship) gives a line of advice naming --vessel and the built-ins\n"
    "that fit\n"
    "examples:\n"
    "  dpgw replay trial.mcap --out again.mcap                      # a gateway log, its own config\n"
    "  dpgw replay usv.txt --vessel cybership2 --observer passive:wave_period_s=1.6 \\\n"
    "       --observer passive:wave_period_s=2.5@long --out usv.mcap --report usv_report\n"
    "  dpgw replay trial.nmea --config vessel.toml --source dgps1=trial.nmea \\\n"
    "       --source gyro=trial.nmea --out trial.mcap   # a sea trial's log on the vessel's sources\n"
    "  dpgw replay sim.mcap --out est.mcap --json   # RMS errors vs the truth (the log names its vessel)\n"
    "  dpgw replay gateway.mcap --truth sim.mcap      # a HIL bench: the gateway's log vs the plant\n"
    "  dpgw replay trial.mcap --out again.mcap --speed 5              # publish on Zenoh, 5x\n"
    "  dpgw replay trial.mcap --foxglove          # watch it in Foxglove: play, pause, seek, speed"
)


UTC_2000_NS = 946_684_800 * 10**9  # 2000-01-01T00:00:00Z


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "logs",
        nargs="+",
        metavar="LOG",
        help="MCAP, NMEA text or tlog files (merged by time); text logs and tlogs may be compressed "
        "(gzip, xz, bzip2, zstd)",
    )
    p.add_argument(
        "--vessel",
        metavar="NAME|FILE",
        help="vessel (needed unless the log or --config has one; a simulator log names its own)",
    )
    p.add_argument("--config", metavar="FILE", help="a gateway config (sources, lever arms, tuning)")
    p.add_argument(
        "--source",
        action="append",
        default=[],
        metavar="NAME=LOG",
        help="with --config: replay the text log or tlog LOG as the config's source NAME (repeatable; a "
        "log may feed several sources, each taking the sentences of its roles). Without it, a log goes to "
        "the source named as its file, else to the config's sources of its protocol when no two share a "
        "role; a ship network's capture's devices go to the sources whose tag_source names them",
    )
    p.add_argument(
        "--observer",
        action="append",
        default=[],
        metavar="SPEC",
        help=f"observer spec NAME[:key=value,...][@label], NAME one of {', '.join(OBSERVER_NAMES)} "
        "(repeatable: side by side; default: the observer of the log's or --config's [observer] type, "
        "else passive)",
    )
    p.add_argument(
        "--out",
        metavar="OUT.mcap",
        help="write inputs and estimates here (default: beside the first log, LOG-replay.mcap, or in the "
        "current folder where the log's cannot be written; never the log itself). One that exists is "
        "kept: the replay goes on in the next file of its set (OUT_0001.mcap, ...), named on the console, "
        "as dpgw run, demo and sim do",
    )
    p.add_argument(
        "--no-foxglove-channels",
        dest="foxglove_channels",
        action="store_false",
        help="leave out the Foxglove-native channels (/gnss/<source>/fix, /dp/estimate/fix, poses, /dp/tf, "
        "/dp/scene/*, /dp/log): only the JSON channels and the raw input are written. Faster (on a 5 Hz "
        "log about half the messages) but Foxglove then shows no map or 3D scene without setup",
    )
    p.add_argument(
        "--report",
        nargs="?",
        const="",
        action=_ReportFolder,
        metavar="DIR",
        help="write plots (PNG), metrics.json and report.md in DIR (created); without DIR, in "
        "<out>-report beside --out (put a bare --report after the logs). One that holds a report is kept, "
        "as --out's file is: the report goes in the next free folder, DIR_0001, ..., named on the console. "
        "On a gateway's log with DP, also what its wave filtering kept out of the commanded thrust, in dB "
        "(the log replayed once more with the controller fed the raw measurements)",
    )
    pace = p.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed", type=positive_float, metavar="X", help="pace at X times real time and publish on Zenoh"
    )
    pace.add_argument("--realtime", action="store_true", help="= --speed 1")
    p.add_argument("--prefix", help="Zenoh prefix when publishing (default the config's)")
    add_endpoint_args(p)
    p.add_argument("--no-scouting", action="store_true", help="Zenoh multicast scouting off")
    p.add_argument(
        "--stamp-zone",
        metavar="ZONE",
        help="the zone a text log's time stamps without one were written in (UTC, or an offset: +02:00): "
        "a logger's file of one port, every line stamped and none with a sentence time (a gyro's HDT), "
        "is then replayed by its stamps. Stamps with Z or an offset, and UNIX seconds, need none",
    )
    p.add_argument(
        "--settle",
        type=non_negative_float,
        metavar="S",
        help="leave out the first S s when scoring against the truth and in the report (default: a dpgw "
        "demo log's own settle time, which its summary scored after; else the first 10 %% of the log, at "
        "most 60 s)",
    )
    p.add_argument(
        "--truth",
        metavar="SIM.mcap",
        help="score against the ground truth of this simulator log (dpgw sim --out): a HIL bench's "
        "gateway log against the simulator that fed it. Only its truth is read (its sentences are the "
        "ones the gateway logged: giving both logs as LOG feeds them twice, refused). The gateway must "
        'have run on the simulator\'s time (clock = "sim") for the two to line up; the truth is moved into '
        "the gateway's datum",
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_foxglove_arg(
        p,
        what="the replay, paced in log time and driven from the app (play, pause, seek, speed; starts "
        "paused unless --speed/--realtime is given; runs until Ctrl-C, writes no --out or --report)",
    )
    p.set_defaults(func=run)
    p.error = functools.partial(_error_with_hints, p, p.error)  # type: ignore[method-assign]


class _ReportFolder(argparse.Action):
    """``--report [DIR]``, remembering its value on the parser: a value that is a file while no LOG was
    given is the log, taken as the folder (`_error_with_hints`)."""

    def __call__(
        self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any, option: Any = None
    ) -> None:
        setattr(namespace, self.dest, values)
        setattr(parser, REPORT_VALUE, values)


REPORT_VALUE = "_dpgw_report_value"


def _error_with_hints(
    parser: argparse.ArgumentParser, error: Callable[[str], NoReturn], message: str
) -> NoReturn:
    """argparse's error, with what went wrong when ``--report`` took the log as its folder: `--report
    usv.txt --vessel cybership2` said only that LOG is required."""
    took = getattr(parser, REPORT_VALUE, None)
    if "required: LOG" in message and took and Path(took).is_file():
        message += (
            f" (--report took {took} as the report's folder: its folder is optional, so put a bare "
            f"--report after the logs, 'dpgw replay {took} ... --report', or give it one: --report DIR)"
        )
    error(message)


# Observers that schedule ω0 from the measured sea themselves (the sdre observer does with adaptive=true).
SCHEDULES_OMEGA0 = frozenset({"gain_scheduled", "mmae"})


def nothing_to_replay(inputs: list[Any], result: ReplayResult) -> str:
    """Why a replay found no event: each log and what its reader counted in it (lines without a time ...)."""
    found = "; ".join(
        f"{where}: " + ", ".join(f"{k} {v}" for k, v in c.items()) for where, c in result.counts.items() if c
    )
    hints = [h for c in result.counts.values() if (h := stamps_without_zone(c))]
    return (
        f"nothing to replay in {', '.join(str(i.path) for i in inputs)}: no NMEA sentence with a time, no "
        f"MAVLink frame, no dpgw channel{f' ({found})' if found else ''}; give a gateway or simulator MCAP "
        "log, an NMEA 0183 text log or a MAVLink tlog" + "".join(f" ({h})" for h in hints[:1])
    )


def stamps_without_zone(counts: dict[str, int]) -> str | None:
    """What to say of a text log whose lines had a logger's stamp (``line_prefix``) and no time: stamps
    without a zone, which replay does not take as UTC (`gateway.stamped_log`)."""
    if counts.get("no_time") and counts.get("line_prefix"):
        return (
            f"{counts['no_time']} lines without a time: their logger's stamps name no zone, so they may be "
            "local time and are not taken as times; give the zone the logger wrote in (--stamp-zone UTC, "
            "--stamp-zone +02:00) to replay the log by its stamps"
        )
    return None


def default_out(first_log: str) -> str:
    """``trial.mcap`` -> ``trial-replay.mcap`` beside it (a replay never overwrites what it reads)."""
    path = Path(first_log)
    return str(path.with_name(f"{path.stem}-replay.mcap"))


def next_free_out(out: str) -> Path:
    """The file a replay writes for ``--out OUT``: OUT itself when it is not there, else the first free
    file of its set (``usv_0001.mcap``, `wire.mcap.rotation.free_path`), never one that exists."""
    from wire.mcap.rotation import free_path

    return free_path(out)


REPORT_FILES = ("report.md", "metrics.json")
"""A folder with one of these holds a report (`gateway.report.writer.write_analysis` writes both)."""


def holds_report(folder: Path) -> bool:
    return any((folder / name).exists() for name in REPORT_FILES)


def next_free_report(folder: str) -> Path:
    """The folder a replay writes its report in for ``--report DIR`` (or the one beside --out): DIR itself
    unless it holds a report, else the first of ``DIR_0001``, ``DIR_0002``, ... that holds none (and is no
    file), as `next_free_out` numbers a log's set."""
    path = Path(folder)
    index = 0
    candidate = path
    while holds_report(candidate) or (index and candidate.exists() and not candidate.is_dir()):
        index += 1
        candidate = path.with_name(f"{path.name}_{index:04d}")
    return candidate


def run(args: argparse.Namespace) -> int:
    from dpgw.replay_truth import fed_twice, truth_log_problem
    from gateway.bus import BusError
    from gateway.config import ConfigError, format_problems
    from gateway.replay import (
        ObserverSpec,
        ReplayError,
        build_config,
        build_pipeline,
        carried_metadata,
        keyless_mavlink_sources,
        logged_signing_verdicts,
        logged_sim,
        open_inputs,
        parse_observer_spec,
        run_replay,
        runs_its_own_controller,
    )
    from observers.passive_tuning import TuningError
    from observers.vessel import VesselError
    from wire.mcap.writer import McapLogWriter

    if args.foxglove is not None and (args.out or args.report is not None):
        print(
            "dpgw replay: --foxglove plays the logs interactively (seeking runs parts again) and writes no "
            "--out or --report: run once without --foxglove for those",
            file=sys.stderr,
        )
        return 2
    if args.out is None and args.foxglove is None:
        args.out = default_out(args.logs[0])
        if unwritable("--out", args.out):
            # beside a log on a write-protected stick, a read-only mount or in a folder of another user's:
            # the current folder, as most tools write there, said (refused below if it cannot be written
            # either)
            beside, args.out = args.out, Path(args.out).name
            print(
                f"dpgw replay: out -> {args.out} (beside the log, {beside} cannot be written; --out names "
                "another place)",
                file=sys.stderr,
            )
    elif args.out is not None and any(Path(args.out).resolve() == Path(log).resolve() for log in args.logs):
        print(
            f"dpgw replay: --out {args.out} is one of the logs being replayed: give another file",
            file=sys.stderr,
        )
        return 2
    zenoh = flags_given(
        ("--prefix", args.prefix),
        ("--zenoh-listen", args.zenoh_listen),
        ("--zenoh-connect", args.zenoh_connect),
        ("--no-scouting", args.no_scouting),
    )
    if zenoh and not (args.speed or args.realtime):  # accepted and ignored before
        print(
            f"dpgw replay: {', '.join(zenoh)}: a replay publishes on Zenoh only when paced: add --speed X "
            "or --realtime (as fast as the CPU allows, it writes --out and publishes nothing)",
            file=sys.stderr,
        )
        return 2
    if args.prefix is not None:
        from gateway.config.load import prefix_problem

        if problem := prefix_problem(args.prefix):
            print(f"dpgw replay: --prefix: {problem}", file=sys.stderr)
            return 2
    # Said once the replay will run (a refusal below names no file it never writes): where it writes
    # instead of a file or folder that exists.
    renamed: list[str] = []
    if (
        args.out is not None
        and not mcap_path_problem("--out", args.out)  # (a folder or another name is refused below)
        and (free := next_free_out(args.out)) != Path(args.out)
    ):
        # An --out that exists is not overwritten (it may hold an earlier replay): the replay goes on in the
        # next file of its set (usv_0001.mcap), as `dpgw run`, `dpgw demo` and `dpgw sim` do with theirs.
        renamed.append(f"dpgw replay: out -> {free} ({args.out} exists: a log is never overwritten)")
        args.out = str(free)
    if args.report == "":  # a bare --report: beside the output
        beside = Path(args.out)
        args.report = str(beside.with_name(f"{beside.stem}-report"))
    # Where the results go is checked before the replay, not found out after it.
    if problem := output_folder_problem("--report", args.report) or mcap_path_problem("--out", args.out):
        print(f"dpgw replay: {problem}", file=sys.stderr)
        return 2
    if args.report is not None and (free_report := next_free_report(args.report)) != Path(args.report):
        # A report folder is kept as --out's file is: given or made beside --out, one that holds a report
        # (it was written over, files of the earlier replay mixed with the new) gives way to the next free
        # folder of its set, said here and named in the summary.
        renamed.append(
            f"dpgw replay: report -> {free_report} ({args.report} holds a report: a report is never "
            "overwritten)"
        )
        args.report = str(free_report)
    if args.vessel is not None:  # (checked as the flag it is, not as the config key it becomes)
        from observers.vessel import load_vessel

        try:
            load_vessel(args.vessel)
        except VesselError as exc:
            print(f"dpgw replay: --vessel: {exc}", file=sys.stderr)
            return 2
    if args.truth is not None and (problem := truth_log_problem(Path(args.truth))):
        print(f"dpgw replay: {problem}", file=sys.stderr)
        return 2
    try:
        inputs = open_inputs(args.logs)
        if args.stamp_zone is not None:
            from gateway.stamped_log import parse_zone

            try:
                zone = parse_zone(args.stamp_zone)
            except ValueError as exc:
                print(f"dpgw replay: --stamp-zone: {exc}", file=sys.stderr)
                return 2
            for inp in inputs:
                inp.stamp_zone = zone
        if why := fed_twice(inputs):
            raise ReplayError(why)
        if args.truth is not None and (sim := next((i for i in inputs if logged_sim(i.path)), None)):
            raise ReplayError(
                f"--truth: {sim.path} is a simulator log with its own truth: give one or the other"
            )
        config = build_config(inputs, config_path=args.config, vessel=args.vessel, source_args=args.source)
        for inp in inputs:
            if inp.untagged:  # (a plain log fed to sources that take a device on the network)
                print(
                    f"dpgw replay: note: {inp.path.name} has no TAG blocks: the tag_source of "
                    f"{', '.join(inp.untagged)} is not applied to it (the log is taken as that device's)",
                    file=sys.stderr,
                )
            if inp.unconfigured:
                print(
                    f"dpgw replay: note: {inp.path.name}: source{'s' if len(inp.unconfigured) > 1 else ''} "
                    f"{', '.join(inp.unconfigured)} not in --config {args.config}: "
                    f"{'their' if len(inp.unconfigured) > 1 else 'its'} input is not replayed",
                    file=sys.stderr,
                )
        # Without --observer, the observer the config names (the log's own for a gateway log: what ran live).
        own = config.observer.type
        specs = [parse_observer_spec(s) for s in args.observer] or [ObserverSpec(own, own, {})]
        labels = [s.label for s in specs]
        if twice := next((x for i, x in enumerate(labels) if x in labels[:i]), None):
            # each observer's estimates are counted, published and reported under its label
            raise ReplayError(f"--observer: label '{twice}' given twice (name each: SPEC@label)")
        own_controller = runs_its_own_controller(inputs, own_config=own_config(args))
        # a signed link's key is not in the log: its frames are refused where the live gateway refused
        # them (the verdicts the log records), or taken unchecked from an older log that has none; a
        # --config that gives the key checks the signatures instead
        keyless = keyless_mavlink_sources(config)
        verdicts = logged_signing_verdicts(inputs, keyless)
        defaults, defaults_note = scenario_observer_defaults(inputs, config.vessel.name, specs)
        # the pipeline for any observers: the replay's, the Foxglove player's at every seek, and the wave
        # check's advice tried on a log's truth
        pipeline_for = functools.partial(
            build_pipeline,
            config,
            controller=own_controller,
            signing_verdicts=verdicts,
            observer_defaults=defaults,
        )
        pipeline = pipeline_for(specs, foxglove_channels=args.foxglove_channels)
    except ConfigError as exc:
        print(format_problems(exc), file=sys.stderr)
        return 2
    except (ReplayError, VesselError, TuningError, OSError) as exc:
        print(f"dpgw replay: {exc}", file=sys.stderr)
        return 2
    for line in renamed:
        print(line, file=sys.stderr)
    if defaults_note is not None:
        print(f"dpgw replay: note: {defaults_note}", file=sys.stderr)
    speed = 1.0 if args.realtime else args.speed
    if args.foxglove is not None:
        return serve(args, inputs, specs, speed, pipeline_for)
    try:
        publisher = _Publisher(args, config.zenoh.prefix, speed) if speed else None
    except BusError as exc:
        print(f"dpgw replay: {exc.describe(ZENOH_FLAGS)}", file=sys.stderr)
        return 2
    # Keep in memory only what the summary (errors against a simulator log's truth) and the report need.
    topics = ["/dp/estimate", *(f"/dp/estimates/{s.label}" for s in specs[1:])]
    if args.report:
        topics.append("/dp/measurement")
    elif args.truth is None and not any(inp.kind == "mcap" for inp in inputs):
        topics = []  # a text log or tlog has no truth, and none was given: nothing to score
    bar = terminal_bar(None, " events", json=args.json)
    evidence = _WaveEvidence(pipeline.fusion)
    on_outputs = evidence.on_outputs
    if publisher is not None:
        on_outputs = evidence.chain(publisher.on_outputs)
    stop = _StopOnSignal()
    on_outputs = stop.between_events(on_outputs)
    t0 = time.perf_counter()
    truth_note: str | None = None
    try:
        with (
            stop,
            McapLogWriter(args.out, profile="dpgw-replay", flush_on_log_time=False) as out,  # (a free file)
        ):
            out.add_metadata("dpgw.replay", {"logs": json.dumps([str(i.path) for i in inputs])})
            for name, meta in carried_metadata(inputs, own_config=own_config(args)):
                out.add_metadata(name, meta)
            result = run_replay(
                inputs,
                pipeline,
                out=out,
                collect=topics,
                on_outputs=on_outputs,
                progress=(lambda n: bar.update(n - bar.n)) if bar is not None else None,
                status_period_ns=round(1e9 / config.status.rate_hz),
            )
            if args.truth is not None:
                truth_note = _take_truth(Path(args.truth), pipeline, result, out)
    except (BusError, OSError) as exc:
        print(f"dpgw replay: {exc}", file=sys.stderr)
        return 2
    except _StopRequestedError as exc:
        if bar is not None:
            bar.close()  # (before the line; closing it again below does nothing)
        print(
            f"dpgw replay: stopped ({exc.name}) after {stop.events} events, at log time {exc.at}; {args.out} "
            "holds what was replayed until then (a complete MCAP file); no summary or report",
            file=sys.stderr,
        )
        return 128 + exc.signum
    finally:
        if bar is not None:
            bar.close()
        if publisher is not None:
            publisher.close()
    # The replay is done and its output complete; the analysis after it (the summary, the comparison
    # with raw feedback that replays the log once more, the report's plots) can take as long again. A
    # signal there stops it at once, said, instead of a KeyboardInterrupt traceback (or, on SIGTERM, a
    # killed process) with the report half written.
    try:
        with _RaiseOnSignal():
            return _conclude(
                args, inputs, config, specs, result, evidence, verdicts, keyless, truth_note, t0, pipeline_for
            )
    except _StopRequestedError as exc:
        report = f"; the report in {args.report} is incomplete" if args.report else ""
        print(
            f"dpgw replay: stopped ({exc.name}) after the replay, while {exc.at}; {args.out} is complete "
            f"(the whole log replayed){report}; no summary",
            file=sys.stderr,
        )
        return 128 + exc.signum


def _conclude(
    args: argparse.Namespace,
    inputs: list[Any],
    config: Any,
    specs: list[ObserverSpec],
    result: ReplayResult,
    evidence: _WaveEvidence,
    verdicts: Any,
    keyless: Any,
    truth_note: str | None,
    t0: float,
    pipeline_for: Callable[..., Any],
) -> int:
    """After the replay: the summary (console or --json), the live log's DP performance, the checks and
    the report; the command's exit status."""
    from gateway.replay import logged_min_scored_s, logged_settle_s, unchecked_signatures

    if result.events == 0:
        Path(args.out).unlink(missing_ok=True)
        print(f"dpgw replay: {nothing_to_replay(inputs, result)}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - t0
    if args.settle is None:  # a demo's log is scored over the stretch the demo scored it over
        args.settle = logged_settle_s(inputs)
    # and on as much sea as the demo scores (a demo stopped soon after its skip: "not scored", as it
    # said)
    args.min_scored = logged_min_scored_s(inputs, older_demo=MIN_SCORED_S)
    data_span = _data_span_ns(evidence, result, specs)
    summary = _summary(args, specs, result, wall, data_span)
    if args.settle is None and "settle_s" in summary:
        # the report leaves out the same start as the summary's errors against the truth, by construction
        args.settle = summary["settle_s"]
    if result.truth:
        from dpgw.replay_truth import MISMATCH_DEG, MISMATCH_M, truth_mismatch

        if (far := truth_mismatch(evidence.stamps, evidence.eta, result.truth)) is not None:
            summary["truth_mismatch"] = far
            if (arm := far.get("steady_offset_body_m")) is not None:
                truth_note = (
                    f"the log's measured positions sit a steady {far['median_position_m']:.1f} m from "
                    f"{args.truth or 'the truth'} (a position reference is off by metres at worst: "
                    f"{MISMATCH_M:g} m allowed), fixed in the vessel's frame: as if the antenna were "
                    f"{arm[0]:+.1f} m forward and {arm[1]:+.1f} m to starboard of where the config's lever "
                    "arm puts it. Check the position sources' lever_arm_m (and the datum); the errors "
                    "printed include that offset. (Another run's truth would wander from the fixes, not "
                    "sit a steady offset off.)"
                )
            else:
                truth_note = (
                    f"{args.truth or 'the truth'} is not this log's: its motion lies a median "
                    f"{far['median_position_m']:.1f} m and {far['median_heading_deg']:.1f}° from the log's "
                    f"own measurements (a position reference is off by metres at worst: {MISMATCH_M:g} m, "
                    f"{MISMATCH_DEG:g}° allowed). Give the simulator log of the run that made this log (its "
                    "scenario, seed and start); the errors printed are against another run's truth"
                )
    live = _live_records(inputs)
    first_ns = min((a for a, _ in result.spans.values()), default=0)
    summary["dp_performance"] = _dp_performance(live, first_ns)
    compared = None
    if args.report is not None and summary["dp_performance"] is not None:
        # with a report (the analysis): what the live gateway's wave filtering kept out of its
        # commanded thrust, against the same controller fed the raw measurements (the log replayed
        # once more)
        from dpgw.raw_feedback import compare_with_raw_feedback, thrust_wave_band

        # over the stretch the demo scores (its log replayed gives its figures): from DP_SETTLE_S after
        # DP was engaged, not before SETTLE_S of the log; the stretch said, as the two once differed
        compared = compare_with_raw_feedback(
            args.logs,
            live["/dp/thrusters/command"],
            thrust_wave_band(config.vessel),
            from_ns=first_ns + round(SETTLE_S * 1e9),
            after_engage_s=DP_SETTLE_S,
        )
        summary["dp_performance"]["wave_filtering"] = compared.figures
        if compared.figures is not None and compared.stretch is not None and "error" not in compared.figures:
            compared.figures["stretch_s"] = [(t - first_ns) / 1e9 for t in compared.stretch]
    kinds = {s.label: (s.name, s.name in SCHEDULES_OMEGA0 or bool(s.params.get("adaptive"))) for s in specs}
    wave_check = evidence.check(config.vessel.length_m, config.vessel.model_scale, kinds)
    summary["wave_check"] = wave_check.as_dict()
    if result.truth and summary.get("error_vs_truth") and (advised := wave_check.advised()):
        # a simulator's log has its truth: the advice is tried on it before it is given
        summary["wave_check"]["advice_on_truth"] = _advice_on_truth(
            args, inputs, pipeline_for, advised, summary["error_vs_truth"], result.truth, data_span
        )
    summary["vessel_check"] = evidence.vessel_check(config.vessel).as_dict()
    summary["measurements"] = evidence.measured()
    summary["cut_logs"] = cut_logs(inputs)
    # a signed link's key is not in the log (docs/gateway.md, "Replay of a signed link"): the live
    # gateway's verdicts applied, or (an older log) its frames taken with their signatures unchecked
    summary["signature_verdicts"] = verdicts.counts if verdicts is not None else {}
    summary["signatures_unchecked"] = unchecked_signatures(inputs, keyless)
    # What the console warns of, in its order; report.md's Warnings section repeats it, with the vessel
    # check's advice (on the console in the summary): a report read alone said nothing of an observer
    # that made no estimate, nor of a vessel that does not fit the log.
    checks = [
        *([f"warning: --truth: {truth_note}"] if truth_note is not None else []),
        *(f"warning: {w}" for w in [*_cut(summary), *_no_estimates(summary)]),
        *(f"warning: {w}" for w in summary["wave_check"]["warnings"]),
        *(f"note: {n}" for n in _advice_notes(summary["wave_check"].get("advice_on_truth", {}))),
        *(f"note: {n}" for n in summary["wave_check"]["notes"]),
        *(f"note: {n}" for n in _no_thrust(summary)),
    ]
    advice = summary["vessel_check"].get("advice")
    report_warnings: list[str] = []
    if args.report:
        said = [*checks, *([f"advice: {advice}"] if advice else [])]
        written, report_warnings = _report(
            args, config.vessel, specs, result, evidence.new, said, live, compared, summary["dp_performance"]
        )
        summary["report"] = [str(p) for p in written]
        summary["report_warnings"] = report_warnings
        if not any(p.suffix == ".png" for p in written):
            from gateway.report.plots import load_figure

            if load_figure() is None:
                from gateway.report.writer import NO_MATPLOTLIB

                print(f"dpgw replay: --report: {NO_MATPLOTLIB}", file=sys.stderr)
    if args.json:
        print(cli_json.dumps(summary, indent=2))
    else:
        _print(summary)
    for line in checks:  # (in report.md too, as said here)
        print(f"dpgw replay: {line}", file=sys.stderr)
    for warning in report_warnings:
        print(f"dpgw replay: warning: report: {warning}", file=sys.stderr)
    for source, live in summary["signature_verdicts"].items():
        print(f"dpgw replay: note: {_verdict_note(source, live, result.counts)}", file=sys.stderr)
    for source, live in summary["signatures_unchecked"].items():
        rejected = sum(live.values())
        print(
            f"dpgw replay: note: {source}: MAVLink signatures not checked (a log never holds the "
            "signing key); "
            + (
                "the live gateway rejected no frame for its signature: the same frames as live"
                if not rejected
                else f"the live gateway rejected {rejected} frames for their signature "
                f"({', '.join(f'{k} {v}' for k, v in live.items() if v)}), which this replay took"
            ),
            file=sys.stderr,
        )
    return 0


def _take_truth(path: Path, pipeline: Any, result: ReplayResult, out: Any) -> str | None:
    """The simulator log's truth in the replay's frame into ``result`` (and --out's log, so that it
    replays scored too); or why there is none to score against."""
    from dpgw.replay_truth import span_overlap_s, to_replay_frame

    frame = pipeline.fusion.datum
    if frame is None:
        return "the log gave no position fix, so there is no frame to put the truth in: nothing scored"
    truth = to_replay_frame(path, frame)
    first = min((a for a, _ in result.spans.values()), default=0)
    last = max((b for _, b in result.spans.values()), default=0)
    if span_overlap_s(truth, first, last) < 1.0:
        return (
            f"{path}'s truth ({_utc(int(truth[0]['stamp_ns']))} on) and the log "
            f"({_utc(first)} to {_utc(last)}) do not overlap in time: a gateway on the wall clock stamps "
            'its inputs with its own time; run it with [time] clock = "sim" (docs/gateway.md, "Simulation '
            'time") to score it'
            if truth
            else f"{path} holds no /truth/state"
        )
    result.truth = truth
    for rec in truth:
        out.write("/truth/state", rec, rec["stamp_ns"], rec["stamp_ns"])
    return None


LIVE_TOPICS = ("/dp/thrusters/command", "/dp/estimate", "/dp/status")
"""What the live gateway logged of how DP did (`gateway.report.station_keeping`)."""


def _live_records(inputs: list[Any]) -> dict[str, list[dict[str, Any]]]:
    """The live gateway's commands, estimates and statuses in the MCAP inputs (none in a simulator's log
    or a text log): how DP did in the trial, whatever observer this replay runs."""
    from wire.mcap.reader import read_messages

    out: dict[str, list[dict[str, Any]]] = {t: [] for t in LIVE_TOPICS}
    paths = [i.path for i in inputs if i.kind == "mcap"]
    if paths:
        for topic, _, _, payload in read_messages(paths, LIVE_TOPICS):
            out[topic].append(payload)
    return out


def _dp_performance(live: dict[str, list[dict[str, Any]]], start_ns: int) -> dict[str, Any] | None:
    from gateway.report.station_keeping import dp_performance

    return dp_performance(live["/dp/thrusters/command"], live["/dp/estimate"], live["/dp/status"], start_ns)


def _thrust_trace(
    live: dict[str, list[dict[str, Any]]], compared: Comparison, t0_ns: int
) -> ThrustTrace | None:
    """The live and raw-fed commanded τ over the stretch compared, on the report's time axis (s from
    ``t0_ns``), for thrust.png; None when the comparison has no figures (too short, or it failed)."""
    import numpy as np

    from dpgw.raw_feedback import in_stretch
    from gateway.report.data import ThrustTrace

    w = compared.figures
    if not w or "error" in w or compared.raw is None or compared.stretch is None:
        return None
    start, end = compared.stretch

    def series(commands: list[dict[str, Any]]) -> tuple[Any, Any]:
        kept, t = in_stretch(commands, start, end, origin_ns=t0_ns)
        return t, np.array([c["tau_demand"] for c in kept], dtype=float).reshape(-1, 3)

    t, tau = series(live["/dp/thrusters/command"])
    t_raw, tau_raw = series(compared.raw)
    lo, hi = w["band_rad_s"]
    return ThrustTrace(t, tau, t_raw, tau_raw, (float(lo), float(hi)))


def _print_dp(dp: dict[str, Any]) -> None:
    """The summary's lines of how DP did (`gateway.report.station_keeping`)."""
    modes = ", ".join(f"{m} {t:.0f} s" for m, t in dp["modes"]["time_s"].items())
    print(f"  DP in the live log: {modes}")
    sk = dp["station_keeping"]
    if sk is not None:
        pos, hdg = sk["position_error_m"], sk["heading_error_deg"]
        print(
            f"    off the DP reference: p95 {pos['p95']:.2f} m (max {pos['max']:.2f} m), heading p95 "
            f"{hdg['p95']:.2f}° (max {hdg['max']:.2f}°); saturated {100 * sk['saturated_share']:.0f} % of "
            f"{sk['commands']} commands"
        )
    if dp.get("wave_filtering"):
        from dpgw.raw_feedback import wave_filtering_lines

        for text in wave_filtering_lines(dp["wave_filtering"]):
            print(f"    {text}")
    dr = dp["dead_reckoning"]
    if dr["spells"]:
        print(
            f"    dead reckoning: {dr['spells']} spell{'s' if dr['spells'] > 1 else ''}, longest "
            f"{dr['longest_s']:.0f} s, in all {dr['total_s']:.0f} s ({dr['in_dp_s']:.0f} s in dp)"
        )
    alarms = dp["alarms"]
    if alarms:
        critical = sum(a["level"] == "critical" for a in alarms)
        print(f"    alarms: {len(alarms)} ({critical} critical); the longest up:")
        for a in alarms[:ALARMS_LISTED]:
            print(
                f"      {a['level']}: {a['first_text']} (raised {a['raised']}x at {a['first_s']:.0f} s on, "
                f"up {a['up_s']:.0f} s)"
            )
        if len(alarms) > ALARMS_LISTED:
            print(f"      ... and {len(alarms) - ALARMS_LISTED} more (--json, --report)")


ALARMS_LISTED = 5


def _verdict_note(source: str, live: dict[str, int], counts: dict[str, dict[str, int]]) -> str:
    """What the replay of a signed link without its key did: the live gateway's verdicts, from the log."""
    refused = sum(live.values())
    unmatched = counts.get(f"source {source}", {}).get("warning signing_verdict_unmatched", 0)
    note = (
        f"{source}: MAVLink signatures not checked (a log never holds the signing key): the live "
        "gateway's verdicts, recorded in the log, applied instead: "
        + (
            f"{refused} frames refused as live ({', '.join(f'{k} {v}' for k, v in live.items() if v)})"
            if refused
            else "it refused no frame, so the same frames as live"
        )
    )
    if unmatched:
        note += (
            f"; {unmatched} verdicts matched no frame at their place in the log (a log edited, or merged "
            "with another): those frames were taken unchecked"
        )
    return note


def cut_logs(inputs: list[Any]) -> list[str]:
    """The MCAP inputs that end without MCAP's footer: cut by `kill -9` or power loss (or still written)."""
    from wire.mcap.reader import is_complete

    return [str(inp.path) for inp in inputs if inp.kind == "mcap" and not is_complete(inp.path)]


def _cut(s: dict[str, Any]) -> list[str]:
    """A log cut short is replayed up to its last complete record: say so, it is not the whole trial."""
    return [
        f"{path} ends without its summary (the writer was killed or lost power, or is still writing it): "
        "replayed up to its last complete record"
        for path in s["cut_logs"]
    ]


def _no_estimates(s: dict[str, Any]) -> list[str]:
    """Why an observer made no estimate, from what the fused measurements held."""
    silent = [label for label, n in s["estimates"].items() if n == 0]
    if not silent:
        return []
    m = s["measurements"]
    who = f"observer{'s' if len(silent) > 1 else ''} {', '.join(repr(x) for x in silent)} made no estimate"
    had = (
        f"of the {m['samples']} fused measurements {m['position']} had a position and {m['heading']} "
        "a heading"
    )
    if m["position"] and m["heading"]:  # not a missing sensor: the observer itself did not start
        return [f"{who}, although {had}: the events in /dp/status of the output say why"]
    return [
        f"{who}: an observer needs position and heading, and {had}. Replay it together with a log of the "
        "missing sensor (several LOGs are merged by time)"
    ]


def _no_thrust(s: dict[str, Any]) -> list[str]:
    """Every observer ran with τ = 0 when no measurement had a thrust: the log holds no thruster feedback
    (and no logged controller's demand). The observers' model then takes the vessel as unpowered: the bias
    estimate carries the thrust, and the velocity and bias estimates lag every change of it. Said, because
    nothing else in the output shows it and an analyst comparing model-based observers must know."""
    m = s["measurements"]
    if not m["samples"] or m["tau_from_feedback"] or m["tau_from_demand"] or not any(s["estimates"].values()):
        return []
    return [
        "no thruster feedback in the log: the observers ran with τ = 0, so their bias estimates carry the "
        "thrust and their velocity estimates lag its changes. Give the thrusters' feedback too (a MAVLink "
        "tlog or the gateway's MCAP: several LOGs are merged by time)"
    ]


def scenario_observer_defaults(
    inputs: list[Any], vessel_name: str, specs: list[Any]
) -> tuple[dict[str, dict[str, Any]], str | None]:
    """The observer settings of the scenario a simulator log names (`Scenario.observer_params`), when the
    replay runs that scenario's vessel, as the study, the demo and the closed loop run the scenario; and a
    note saying which of them the replay's observers take (None when none does). The `hassani` scenarios
    run full-scale seas on a model's M and D: a gain-scheduled observer replaying their log searched the
    model's Froude-scaled range (2.5-13.4 rad/s), far above the sea, and settled there. On another
    vessel (--vessel) a scenario's settings are not that vessel's: none apply."""
    from gateway.replay import logged_sim
    from observers.factory import with_defaults
    from simulator.scenarios import SCENARIOS, get_scenario

    for inp in inputs:
        if inp.kind != "mcap" or (meta := logged_sim(inp.path)) is None:
            continue
        name = meta.get("scenario")
        if name not in SCENARIOS or meta.get("vessel") != vessel_name:
            return {}, None
        params = get_scenario(name).observer_params
        # what each spec's observer takes of them: `with_defaults` decides (a fixed SDRE takes no range)
        taken = [
            f"{s.name}: {', '.join(f'{k}={v:g}' for k, v in ours.items() if k in used)}"
            for s in specs
            if (ours := params.get(s.name))
            and (used := with_defaults(s.name, ours, s.observer_params()).keys() & ours.keys())
        ]
        note = (
            f"the simulator's scenario '{name}' sets {'; '.join(dict.fromkeys(taken))} under the observers' "
            "own settings, as its study and demo run it"
            if taken
            else None
        )
        return params, note
    return {}, None


def own_config(args: argparse.Namespace) -> bool:
    """The replay runs on the logs' own configuration: no --config, no --vessel."""
    return args.config is None and args.vessel is None


def serve(
    args: argparse.Namespace,
    inputs: list[Any],
    specs: list[Any],
    speed: float | None,
    pipeline_for: Callable[..., Any],
) -> int:
    """``--foxglove``: the replay paced in log time on a Foxglove server with playback control
    (`gateway.replay_player`), until SIGINT/SIGTERM; ``pipeline_for(specs)`` is the replay's pipeline,
    made anew at every seek."""
    import signal
    import threading

    from foxglove.websocket import PlaybackCommand, PlaybackControlRequest, PlaybackState, PlaybackStatus

    from gateway.outputs.foxglove_server import FoxgloveServerError, FoxgloveServerSink
    from gateway.replay import merged_events
    from gateway.replay_player import ENDED, PLAYING, PlayerState, ReplayPlayer

    first = last = None
    for ev in merged_events(inputs):  # the span the app's time line shows (one pass, reading only)
        first = ev.rx_ns if first is None else first
        last = ev.rx_ns
    if first is None or last is None:
        print(f"dpgw replay: {', '.join(args.logs)}: no events to play", file=sys.stderr)
        return 2
    status = {PLAYING: PlaybackStatus.Playing, ENDED: PlaybackStatus.Ended}

    def playback_state(s: PlayerState, request_id: str | None = None) -> PlaybackState:
        return PlaybackState(
            status=status.get(s.status, PlaybackStatus.Paused),
            current_time=s.time_ns,
            playback_speed=s.speed,
            did_seek=s.did_seek,
            request_id=request_id,
        )

    def on_request(req: PlaybackControlRequest) -> PlaybackState:
        play = req.playback_command == PlaybackCommand.Play
        return playback_state(player.request(play, req.playback_speed, req.seek_time), req.request_id)

    host, port = args.foxglove
    name = ", ".join(Path(p).name for p in args.logs)
    sink = FoxgloveServerSink(
        host,
        port,
        server_name=f"dpgw replay {name}",
        playback=on_request,
        time_range_ns=(first, last),
        port_given_by="--foxglove [HOST:]PORT",  # (a replay's config is the log's: no [foxglove] to edit)
    )
    player = ReplayPlayer(
        lambda: (
            pipeline_for(specs),
            merged_events(inputs),
        ),
        (first, last),
        lambda outputs: sink.emit(outputs, [o.message.encode() for o in outputs]),
        on_time=sink.broadcast_time,
        on_state=lambda s: sink.broadcast_playback_state(playback_state(s)),
        on_seek=sink.forget_held,
        speed=speed or 1.0,
        playing=speed is not None,
    )
    try:
        sink.start()
    except FoxgloveServerError as exc:
        print(f"dpgw replay: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    stopped_by: list[str] = []

    def on_signal(signum: int, _frame: object) -> None:
        from dpgw.cli_stops import set_from_handler

        stopped_by.append(signal.Signals(signum).name)
        set_from_handler(stop)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    for line in connect_lines(sink.url, sink.app_url()):
        print(f"dpgw replay: {line}", file=sys.stderr)
    span = (last - first) / 1e9
    how = f"playing at {player.speed:g}x" if speed else "paused at the start: press play in Foxglove"
    print(f"dpgw replay: {span:.0f} s of log, {how}; Ctrl-C to stop", file=sys.stderr, flush=True)
    try:
        player.run(stop)
    finally:
        sink.close()
    # Serving until stopped, as `dpgw run` does, a signal is how it ends: exit status 0, the signal named
    summary = {
        "sent": player.sent,
        "restarts": player.restarts,
        "foxglove": sink.stats.as_dict(),
        "stopped_by": stopped_by[0] if stopped_by else None,
    }
    if args.json:
        print(cli_json.dumps(summary, indent=2))
    else:
        print(
            f"dpgw replay: stopped; {player.sent} outputs sent, {player.restarts} seeks back (each replayed "
            "from the start)"
        )
    return 0


class _WaveEvidence:
    """What the wave-tuning check needs, kept as the outputs go by: the measured η (stamp, N, E, ψ) and
    each observer's ω0. Plain tuples, no payload dicts: this runs on every replay."""

    def __init__(self, fusion: Any = None) -> None:
        self.stamps: list[int] = []
        self.eta: list[list[float | None]] = []
        self.omega0: dict[str, list[list[float]]] = {}
        # per multiple-model observer, the ω0 its bank spans (its first estimate's candidates): the check
        # must not advise a bank it already had
        self.spans: dict[str, tuple[float, float]] = {}
        # per /dp/measurement, which DOFs [N, E, ψ] the fusion received since the previous one (the others
        # are held: the report's measurement counts only new samples)
        self.fusion = fusion
        self.new: list[tuple[bool, bool, bool]] = []
        self._received: tuple[int, ...] = (-1, -1, -1)
        # the measurements whose τ came from the thrusters' feedback, and those with any τ at all (a demand:
        # a logged controller's): with neither, every observer ran with τ = 0
        self.tau_feedback = 0
        self.tau_demand = 0

    def on_outputs(self, ev: Event, outputs: list[Output]) -> None:
        for o in outputs:
            msg = o.message
            if o.topic == "/dp/measurement":
                self.stamps.append(msg.stamp_ns)  # type: ignore[attr-defined]
                self.eta.append(msg.eta)  # type: ignore[attr-defined]
                if msg.tau_source == "feedback":  # type: ignore[attr-defined]
                    self.tau_feedback += 1
                elif any(msg.tau):  # type: ignore[attr-defined]
                    self.tau_demand += 1
                if self.fusion is not None:
                    received = tuple(self.fusion.measurement_received_ns())
                    self.new.append(tuple(r != p for r, p in zip(received, self._received, strict=True)))
                    self._received = received
            elif o.topic == "/dp/estimate" or o.topic.startswith("/dp/estimates/"):
                label = msg.observer  # type: ignore[attr-defined]
                self.omega0.setdefault(label, []).append(msg.omega0)  # type: ignore[attr-defined]
                if label not in self.spans and (bank := msg.extra.get("candidates")):  # type: ignore[attr-defined]
                    self.spans[label] = (float(min(bank)), float(max(bank)))

    def measured(self) -> dict[str, int]:
        """How many fused measurements there were, and how many had a position and a heading."""
        return {
            "samples": len(self.eta),
            "position": sum(1 for e in self.eta if e[0] is not None and e[1] is not None),
            "heading": sum(1 for e in self.eta if e[2] is not None),
            "tau_from_feedback": self.tau_feedback,
            "tau_from_demand": self.tau_demand,
        }

    def chain(self, then: Any) -> Any:
        def both(ev: Event, outputs: list[Output]) -> None:
            self.on_outputs(ev, outputs)
            then(ev, outputs)

        return both

    def _series(self) -> tuple[Any, Any]:
        """Times (s from the first) and the measured η (N×3, NaN where not received)."""
        import numpy as np

        t = (np.array(self.stamps, dtype=np.int64) - (self.stamps[0] if self.stamps else 0)) / 1e9
        # only what the fusion received, as the report's measurement: a DOF held between two samples of
        # another sensor is a staircase whose steps are a spectral line of their own (the 10 Hz heading
        # held at the 10 Hz fixes 20 ms later read as a 15.7 rad/s "wave peak")
        y = _received_only(
            np.array([[np.nan if v is None else v for v in e] for e in self.eta], dtype=float).reshape(-1, 3),
            self.new,
        )
        return t, y

    def check(
        self, vessel_length_m: float | None, model_scale: float | None, kinds: dict[str, tuple[str, bool]]
    ) -> Any:
        import numpy as np

        from gateway.report.metrics import wave_band_for_length
        from gateway.report.wave_check import check_wave_tuning
        from observers.froude import froude_scale_of

        t, y = self._series()
        w0 = {label: np.array(w, dtype=float) for label, w in self.omega0.items()}
        band = wave_band_for_length(vessel_length_m, model_scale)
        scale = froude_scale_of(vessel_length_m, model_scale)
        return check_wave_tuning(t, y, band, w0, kinds, spans=self.spans, froude_scale=scale)

    def vessel_check(self, vessel: Any) -> Any:
        """Motion faster than the vessel makes (`gateway.report.vessel_check`)."""
        from gateway.report.vessel_check import builtin_scales, check_vessel_scale

        t, y = self._series()
        return check_vessel_scale(t, y, vessel.name, vessel.length_m, vessel.model_scale, builtin_scales())


def _received_only(y: Any, new: list[tuple[bool, bool, bool]]) -> Any:
    """The fused measurements ``y`` (n, 3) with NaN where a DOF was held, not received since the step
    before (`_WaveEvidence.new`); as they are when ``new`` is not of the same length (no fusion seen)."""
    import numpy as np

    if len(new) == len(y):
        y[~np.array(new, dtype=bool).reshape(-1, 3)] = np.nan
    return y


class _StopRequestedError(Exception):
    def __init__(self, signum: int, at: str) -> None:
        super().__init__(signum)
        self.signum, self.at = signum, at
        self.name = signal.Signals(signum).name


class _StopOnSignal:
    """Ctrl-C (SIGINT) or SIGTERM while replaying: stop between two events, so that the output is closed
    as a complete file and the command ends with one line, not a KeyboardInterrupt traceback (or, on
    SIGTERM, a killed process and an output without its summary). A paced replay (--speed, --realtime) is
    a long-running process that is stopped this way; so is a long log replayed flat out."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.events = 0
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> _StopOnSignal:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.signum = signum

    def between_events(self, then: Any) -> Any:
        def checked(ev: Event, outputs: list[Output]) -> None:
            then(ev, outputs)
            self.events += 1
            if self.signum is not None:
                at = datetime.fromtimestamp(ev.rx_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-4]
                raise _StopRequestedError(self.signum, at)

        return checked


class _RaiseOnSignal(_StopOnSignal):
    """Ctrl-C (SIGINT) or SIGTERM after the replay, while it is analysed: `_StopRequestedError` at once
    (the analysis holds no file open that a stop would leave cut: the output is closed already)."""

    def _on_signal(self, signum: int, _frame: object) -> None:
        raise _StopRequestedError(signum, "analysing it for the summary and the report")


class _Publisher:
    """--speed / --realtime: pace by event time and publish on Zenoh as if live."""

    def __init__(self, args: argparse.Namespace, prefix: str, speed: float) -> None:
        from gateway.bus import JSON, make_config, open_session

        self._json = JSON
        self.session = open_session(
            make_config(
                connect=args.zenoh_connect,
                listen=listen_endpoints(args.zenoh_listen),
                multicast_scouting=not args.no_scouting,
            )
        )
        self.prefix = args.prefix or prefix
        self.speed = speed
        self.t0_ns: int | None = None
        self.wall0 = 0.0

    def on_outputs(self, ev: Event, outputs: list[Output]) -> None:
        if self.t0_ns is None:
            self.t0_ns, self.wall0 = ev.rx_ns, time.monotonic()
        due = self.wall0 + (ev.rx_ns - self.t0_ns) / 1e9 / self.speed
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        for o in outputs:
            if o.zenoh and o.topic.startswith("/dp/"):
                # JSON, said as the live gateway says it: a reader that checks the encoding sees the same
                self.session.put(f"{self.prefix}/{o.topic[4:]}", o.message.encode(), encoding=self._json)

    def close(self) -> None:
        self.session.close()


def _traces(result: ReplayResult, topic: str) -> tuple[np.ndarray, np.ndarray] | None:
    import numpy as np

    rows = result.collected.get(topic, [])
    if not rows:
        return None
    return np.array([r["stamp_ns"] for r in rows], dtype=np.int64), np.array(
        [r["eta"] for r in rows], dtype=float
    )


def _estimate_topics(specs: list[ObserverSpec]) -> list[str]:
    return ["/dp/estimate", *(f"/dp/estimates/{x.label}" for x in specs[1:])]


def _data_span_ns(
    evidence: _WaveEvidence, r: ReplayResult, specs: list[ObserverSpec]
) -> tuple[int, int] | None:
    """The span of the replay's own data, as the report counts it (`gateway.report.metrics.analyse`): from
    the earliest fused measurement or estimate to the latest. The start left out of the scoring counts
    from its first time, and its length is the report's rule on it, not on the truth's span: a simulator
    log (``--truth``) runs from before the gateway started to after it stopped."""
    firsts, lasts = [], []
    if evidence.stamps:
        firsts.append(evidence.stamps[0])
        lasts.append(evidence.stamps[-1])
    for topic in _estimate_topics(specs):
        rows = r.collected.get(topic, [])
        if rows:
            firsts.append(int(rows[0]["stamp_ns"]))
            lasts.append(int(rows[-1]["stamp_ns"]))
    return (min(firsts), max(lasts)) if firsts else None


def _summary(
    args: argparse.Namespace,
    specs: list[ObserverSpec],
    r: ReplayResult,
    wall: float,
    data_span: tuple[int, int] | None = None,
) -> dict[str, Any]:
    s: dict[str, Any] = {
        "logs": args.logs,
        "out": args.out,
        "events": r.events,
        "sentences": r.sentences,
        "wall_seconds": wall,
        "sentences_per_second": r.sentences / wall if wall > 0 else None,
        # every observer asked for, also one that made no estimate (a log without heading)
        "estimates": {spec.label: r.estimates.get(spec.label, 0) for spec in specs},
        "observer_restarts": r.restarts,
        "counts": r.counts,
        "spans": {where: _span(a, b) for where, (a, b) in r.spans.items()},
    }
    if r.truth:
        errors, scored, settle = _errors_vs_truth(args, specs, r, r.truth, data_span)
        s["error_vs_truth"] = errors
        s["settle_s"] = settle
        s["estimate_scored_s"] = scored
        s["min_scored_s"] = getattr(args, "min_scored", None)
    return s


def _advice_on_truth(
    args: argparse.Namespace,
    inputs: list[Any],
    pipeline_for: Callable[..., Any],
    advised: dict[str, str],
    errors_now: dict[str, Any],
    truth: list[dict[str, Any]],
    data_span: tuple[int, int] | None,
) -> dict[str, dict[str, Any]]:
    """The wave check's advice (``advised``: a spec by observer label) replayed on the same log through the
    same pipeline (``pipeline_for`` those specs), all in one pass, and scored against the log's truth as the
    observers were: by label, the spec and both errors.

    A wave filter tuned to the sea keeps more of the waves out of the LF estimate, but a lower ω0 lowers
    its LF bandwidth too: on an open-loop log, whose vessel drifts far, the retuned filter can follow the
    LF motion less closely and score worse against the truth. A log with its truth can say which, so the
    advice comes with its score instead of being taken on trust."""
    from gateway.replay import parse_observer_spec, run_replay

    specs = [parse_observer_spec(f"{spec}@{label}") for label, spec in advised.items() if label in errors_now]
    if not specs:
        return {}
    result = run_replay(inputs, pipeline_for(specs, foxglove_channels=False), collect=_estimate_topics(specs))
    # (scored on the truth the observers were: --truth's, moved into the replay's frame, is not the log's)
    errors, _, _ = _errors_vs_truth(args, specs, result, truth, data_span)
    return {
        s.label: {
            "advised": advised[s.label],
            "error_vs_truth": errors[s.label],
            "as_run": errors_now[s.label],
        }
        for s in specs
        if s.label in errors
    }


ADVICE_DOFS = (("N", "rms_north_m", " m"), ("E", "rms_east_m", " m"), ("ψ", "rms_heading_deg", "°"))


def _rms_words(e: dict[str, Any]) -> str:
    """``N 0.464 m, E 0.574 m, ψ 0.351°`` of a `gateway.scoring.Score` dict."""
    return ", ".join(f"{d} {e[k]:.3g}{u}" for d, k, u in ADVICE_DOFS)


def _advice_notes(tried: dict[str, dict[str, Any]]) -> list[str]:
    """What the advice scored on the log's truth, one line an observer: better or worse, by DOF."""
    out = []
    for label, t in tried.items():
        now, then = t["as_run"], t["error_vs_truth"]
        better = [d for d, k, _ in ADVICE_DOFS if then[k] < now[k]]
        worse = [d for d, k, _ in ADVICE_DOFS if then[k] > now[k]]
        if not worse:
            verdict = "better in every DOF: take it"
        elif not better:
            verdict = (
                "worse in every DOF: on this log the filter tuned to the sea follows the LF motion less "
                "closely (its cut-off moves down with ω0) by more than it gains in waves. Keep the tuning as "
                "run, or compare both in the report (attenuation against error)"
            )
        else:
            verdict = (
                f"better in {', '.join(better)}, worse in {', '.join(worse)}: compare both in the report "
                "(attenuation against error) before choosing"
            )
        out.append(
            f"the advice for '{label}' tried on this log's truth: --observer {t['advised']} gives LF errors "
            f"(RMS) {_rms_words(then)} against {_rms_words(now)} as run: {verdict}"
        )
    return out


def _errors_vs_truth(
    args: argparse.Namespace,
    specs: list[ObserverSpec],
    r: ReplayResult,
    truth: list[dict[str, Any]],
    data_span: tuple[int, int] | None,
) -> tuple[dict[str, Any], dict[str, float], float]:
    """Each observer's LF errors in ``r`` against ``truth`` (`gateway.scoring.score`), the sea scored (s)
    and the settle time skipped: an estimate scored on less sea than ``args.min_scored`` is left out."""
    import numpy as np

    from gateway.scoring import score

    tt_ns = np.array([x["stamp_ns"] for x in truth], dtype=np.int64)
    eta_t = np.array([x["eta_lf"] for x in truth], dtype=float)
    first, last = data_span or (int(tt_ns[0]), int(tt_ns[-1]))
    settle = args.settle if args.settle is not None else default_settle_s((last - first) / 1e9)
    errors, scored = {}, {}
    least = getattr(args, "min_scored", None)
    for spec, topic in zip(specs, _estimate_topics(specs), strict=True):
        tr = _traces(r, topic)
        if tr is None:
            continue
        t_ns, eta = tr
        # the sea after the skip, as `dpgw demo` counts it: from the first estimate on
        scored[spec.label] = max(0.0, float(t_ns[-1] - t_ns[0]) / 1e9 - settle)
        if least is not None and scored[spec.label] < least:
            continue  # said "not scored" (`_print`), as the demo said it
        sc = score((t_ns - first) / 1e9, eta, (tt_ns - first) / 1e9, eta_t, settle_s=settle)
        errors[spec.label] = sc.as_dict()
    return errors, scored, settle


def _span(first_ns: int, last_ns: int) -> dict[str, Any]:
    """What a log covers, in its own (UTC) times: an analyst checks a replay against the trial's clock."""
    return {"start_utc": _utc(first_ns), "end_utc": _utc(last_ns), "seconds": (last_ns - first_ns) / 1e9}


def _utc(ns: int) -> str:
    """ISO 8601 UTC to the millisecond, e.g. 2024-12-05T02:27:18.800Z."""
    from datetime import UTC, datetime

    return datetime.fromtimestamp(ns // 1_000_000 / 1e3, UTC).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def _span_words(span: dict[str, Any]) -> str:
    """``2024-12-05 02:27:18.8 to 02:38:04.6 UTC (645.8 s)``; the end's date too when it is another day."""
    start, end = span["start_utc"], span["end_utc"]
    a_day, a_time = start[:10], start[11:-3].rstrip("0").rstrip(".")
    b_day, b_time = end[:10], end[11:-3].rstrip("0").rstrip(".")
    seconds = span["seconds"]
    length = (
        f"{seconds:.1f} s"
        if seconds < 600
        else f"{seconds / 60:.1f} min"
        if seconds < 36000
        else f"{seconds / 3600:.1f} h"
    )
    return f"{a_day} {a_time} to {'' if b_day == a_day else b_day + ' '}{b_time} UTC ({length})"


def default_settle_s(duration_s: float) -> float:
    """The report's rule (`gateway.report`), so that the summary and the report leave out the same start."""
    from gateway.report.metrics import default_settle_s as report_rule

    return report_rule(duration_s)


def _print(s: dict[str, Any]) -> None:
    rate = s["sentences_per_second"] or 0.0
    print(
        f"dpgw replay: {s['events']} events, {s['sentences']} sentences/frames in {s['wall_seconds']:.1f} s "
        f"({rate:,.0f}/s) -> {s['out']}"
    )
    for label, n in s["estimates"].items():
        print(f"  observer {label}: {n} estimates")
    if s["observer_restarts"]:
        print(
            f"  observers restarted {s['observer_restarts']}x: a reference came back far from the "
            "dead-reckoned estimate, or after it was lost (when and why: the events in /dp/status)"
        )
    spans = s["spans"]
    for where, c in s["counts"].items():
        span = f"; {_span_words(spans[where])}" if where in spans else ""
        print(f"  {where}: " + ", ".join(f"{k} {v}" for k, v in c.items()) + span)
        if c.get("comment"):
            print(
                f"    ({c['comment']} comment lines: lines beginning with #, a log's header as gpsd's test "
                "logs have; not bad input, kept in the raw log)"
            )
        if zoneless := stamps_without_zone(c):
            print(f"    ({zoneless})")
        devices = [k.removeprefix("tag ") for k in c if k.startswith("tag ")]
        if len(devices) > 1:
            print(
                f"    ({len(devices)} devices' TAG blocks in one text log ({', '.join(devices)}): each "
                "replayed as a source of its own that takes its device (tag_source), as dpgw run takes "
                "them from the network)"
            )
        if c.get("no_source"):
            print(
                f"    ({c['no_source']} lines no source of the config takes (a device no tag_source names): "
                "not replayed; --source NAME=LOG gives the whole log to a source)"
            )
        if c.get("other_tag_source"):
            print(
                f"    ({c['other_tag_source']} sentences of other devices: their TAG blocks name another "
                "source than the config's tag_source; not bad input, kept in the raw log)"
            )
    for where, span in spans.items():
        if where not in s["counts"]:  # (an MCAP log: its counts are its sources')
            print(f"  {where}: {_span_words(span)}")
    least = s.get("min_scored_s")
    for label, scored in s.get("estimate_scored_s", {}).items():
        if least is not None and label not in s["error_vs_truth"]:  # (a demo's log: as the demo says it)
            from gateway.scoring import not_scored_note

            print(f"  {label} vs truth: {not_scored_note(scored, s['settle_s'], least)}")
    for label, e in s.get("error_vs_truth", {}).items():
        if not e["samples"]:
            print(
                f"  {label} vs truth: no estimate after the settle time {s['settle_s']:g} s to score "
                "(give a shorter --settle)"
            )
            continue
        print(
            f"  {label} vs truth (after {s['settle_s']:.0f} s): RMS N {e['rms_north_m']:.3f} m, "
            f"E {e['rms_east_m']:.3f} m, heading {e['rms_heading_deg']:.3f} deg"
        )
    if s.get("dp_performance"):
        _print_dp(s["dp_performance"])
    advice = s.get("vessel_check", {}).get("advice")
    if advice:
        print(f"  advice: {advice}")
    for path in s.get("report", []):
        print(f"  report: {path}")


def _report(
    args: argparse.Namespace,
    vessel: VesselModel,
    specs: list[ObserverSpec],
    r: ReplayResult,
    new: list[tuple[bool, bool, bool]],
    checks: list[str],
    live: dict[str, list[dict[str, Any]]] | None = None,
    compared: Comparison | None = None,
    dp: dict[str, Any] | None = None,
) -> tuple[list[Path], list[str]]:
    """The report of the replay. Its measurement is the fused stream with only the samples the fusion
    received since the previous step (`new`): the pipeline steps on every input chunk with each DOF's
    latest measurement held (docs/gateway.md), so a 2 Hz fix among 10 Hz headings appeared five times,
    which made the sample interval the heading's, pulled the innovation's lag-1 autocorrelation towards 1
    and its RMS down (the estimate catching up with a held fix)."""
    import numpy as np

    from gateway.report import ObserverTrace, ReplayData
    from gateway.report.metrics import analyse
    from gateway.report.writer import write_analysis

    meas = r.collected.get("/dp/measurement", [])
    if not meas:
        return [], []
    t0 = meas[0]["stamp_ns"]
    # a log's stamps are UTC (the fixes' own time, or a logger's clock); before 2000 they are a time of
    # day without its date (sentences with no date to join), which the report does not call a date
    stamps_are_utc = t0 >= UTC_2000_NS
    t_meas = (np.array([m["stamp_ns"] for m in meas], dtype=np.int64) - t0) / 1e9
    y = _received_only(
        np.array([[np.nan if v is None else v for v in m["eta"]] for m in meas], dtype=float), new
    )
    traces = []
    for spec, topic in zip(
        specs, ["/dp/estimate", *(f"/dp/estimates/{x.label}" for x in specs[1:])], strict=True
    ):
        rows = r.collected.get(topic, [])
        if not rows:
            continue
        traces.append(
            ObserverTrace(
                label=spec.label,
                t=(np.array([e["stamp_ns"] for e in rows], dtype=np.int64) - t0) / 1e9,
                eta=np.array([e["eta"] for e in rows], dtype=float),
                nu=np.array([e["nu"] for e in rows], dtype=float),
                bias=np.array([e["bias"] for e in rows], dtype=float),
                eta_wf=np.array([e["eta_wf"] for e in rows], dtype=float),
                omega0=np.array([e["omega0"] for e in rows], dtype=float),
                observer=spec.name,
            )
        )
    truth_kw: dict[str, Any] = {}
    if r.truth:
        truth_kw = {
            "truth_t": (np.array([x["stamp_ns"] for x in r.truth], dtype=np.int64) - t0) / 1e9,
            "truth_eta_lf": np.array([x["eta_lf"] for x in r.truth], dtype=float),
            "truth_eta_wf": np.array([x["eta_wf"] for x in r.truth], dtype=float),
        }
    data = ReplayData(
        title=", ".join(Path(p).name for p in args.logs),
        vessel=vessel.name,
        # its length and scale as loaded: a user's vessel file, known by its name alone, was "not a
        # built-in vessel" to the report, which searched a 1:70 model's log in the full-scale wave band
        vessel_length_m=float(vessel.length_m),
        vessel_model_scale=vessel.model_scale,
        t_meas=t_meas,
        y=y,
        traces=tuple(traces),
        counts=r.counts,
        start_ns=t0 if stamps_are_utc else None,
        checks=tuple(checks),
        # what each log covers, as the summary says it: from its first sentence with a time, which can be
        # before the first fused measurement (a cycle without a fix), the report's t = 0
        log_spans={where: _span_words(_span(a, b)) for where, (a, b) in r.spans.items()},
        min_scored_s=getattr(args, "min_scored", None),
        # the summary's own (its times from the log's start, as the console and --json say them): one
        # object everywhere; computed again from the report's t = 0 (the first fused measurement) its
        # times were 0.12 s off the --json's, and a start "-0 s"
        dp_performance=dp,
        thrust=_thrust_trace(live, compared, t0) if live is not None and compared is not None else None,
        **truth_kw,
    )
    an = analyse(data, None, args.settle)
    return write_analysis(data, an, args.report), list(an.metrics["warnings"])
