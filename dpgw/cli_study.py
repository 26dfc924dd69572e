"""``dpgw study``: a Monte Carlo study of the observers, scenarios × sea states × seeds, on Dask."""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from dpgw.cli_types import int_at_least, non_negative_float, positive_float
from dpgw.scenario_names import SCENARIO_NAMES
from observers.observer_names import OBSERVER_NAMES

# Only the parser is built at import; the simulator, the observers and Dask are imported by `run`.

NAME = "study"
HELP = "Monte Carlo study: every observer over scenarios, sea states and seeds (Dask), with a table"
DESCRIPTION = (
    "Simulate each case (scenario, sea state, seed) once in process, with the gateway keeping the "
    "vessel on station, run every observer on the same measurements and score it against the truth: "
    "LF position and heading RMS, velocity RMS, bias error, wave-band attenuation, ω0 error, "
    "convergence time. Writes OUT/results.csv (and .parquet with pyarrow), OUT/summary.md (median and "
    "5-95 % per observer and sea state) and box plots OUT/box_*.png. Cases run on a local Dask cluster "
    "(one process per core) or on an existing one (--scheduler); each case's result is cached under "
    "OUT/cache, so an interrupted study resumes. The sea values given are combined (every Hs with "
    "every Tp, ...); a value not given is the scenario's own. docs/study.md defines every column."
)
EPILOG = (
    "examples:\n"
    "  dpgw study --scenario hassani --seeds 0-7 --duration 300 --out study_hassani\n"
    "  dpgw study --scenario torsetnes_2004 --hs 2,4,6 --tp 8,11.5 --observer passive \\\n"
    "       --observer ekf --observer gain_scheduled:omega0=0.83@gs --workers 2\n"
    "  dpgw study --file observers --out study_observers   # a shipped study: docs/study.md's table\n"
    "  dpgw study --scenario hassani --scheduler tcp://10.0.0.5:8786   # an existing Dask cluster\n"
    "  dpgw study --scenario hassani --serial --json                   # no Dask, summary as JSON"
)

# the studies shipped with dpgw (dpgw/study/studies, package data), which --file takes by name
SHIPPED_STUDY_NAMES = sorted(p.stem for p in (Path(__file__).parent / "study" / "studies").glob("*.toml"))

DOC_BEGIN = "<!-- study-table:begin -->"
DOC_END = "<!-- study-table:end -->"


def doc_markers(section: str) -> tuple[str, str]:
    """The markers of a table in a markdown file: FILE.md → DOC_BEGIN/DOC_END; FILE.md#NAME → the same
    with ``:NAME`` (several tables in one document)."""
    if not section:
        return DOC_BEGIN, DOC_END
    return f"<!-- study-table:{section}:begin -->", f"<!-- study-table:{section}:end -->"


def _numbers(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected numbers separated by commas, e.g. 2,4.5,6"
        ) from None
    if not values:
        raise argparse.ArgumentTypeError(f"{text!r}: expected numbers separated by commas, e.g. 2,4.5,6")
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: every value must be a finite number")
    return values


def _numbers_in(lowest: float, inclusive: bool, what: str, unit: str) -> Callable[[str], list[float]]:
    """`_numbers`, each ≥ ``lowest`` (> with ``inclusive`` False): the message says what the value is and
    its range, and argparse puts the option's name before it (the grid's own check named the study file's
    key, ``'seas'[0]: 'hs_m' out of range (-1.0)``, for a value given as --hs)."""

    def parse(text: str) -> list[float]:
        values = _numbers(text)
        bad = [v for v in values if (v < lowest if inclusive else v <= lowest)]
        if bad:
            among = f" in {text}" if len(values) > 1 else ""
            raise argparse.ArgumentTypeError(
                f"{what} must be {'≥' if inclusive else '>'} {lowest:g} {unit} (got {bad[0]:g}{among})"
            )
        return values

    return parse


def _seeds(text: str) -> list[int]:
    """0-7,10,12 → [0..7, 10, 12]."""
    out: list[int] = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        lo, dash, hi = part.partition("-")
        try:
            first, last = (int(lo), int(hi)) if dash else (int(part), int(part))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{part!r}: expected whole numbers and ranges, e.g. 0-7,9"
            ) from None
        if last < first:
            raise argparse.ArgumentTypeError(f"{part!r}: an empty range (write {last}-{first})")
        out += range(first, last + 1)
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--file", metavar="STUDY.toml|NAME",
        help="the grid from a study file (docs/study.md), or a study shipped with dpgw by its name: "
        f"{', '.join(SHIPPED_STUDY_NAMES)} (the grids of the tables in docs/study.md)",
    )  # fmt: skip
    p.add_argument(
        "--scenario", action="append", default=[], choices=SCENARIO_NAMES, metavar="NAME",
        help=f"scenario (repeatable): {', '.join(SCENARIO_NAMES)}",
    )  # fmt: skip
    p.add_argument(
        "--hs", type=_numbers_in(0.0, True, "a significant wave height", "m"), metavar="M[,M...]",
        help="significant wave heights (m, ≥ 0)",
    )  # fmt: skip
    p.add_argument(
        "--tp", type=_numbers_in(0.0, False, "a peak period", "s"), metavar="S[,S...]",
        help="peak periods (s, > 0)",
    )  # fmt: skip
    p.add_argument(
        "--direction", type=_numbers, metavar="DEG[,...]", help="wave directions, going towards (°)"
    )
    p.add_argument(
        "--current", type=_numbers_in(0.0, True, "a current speed", "m/s"), metavar="M/S[,...]",
        help="current speeds (m/s, ≥ 0; > 0 runs the full plant, which needs the vessel's hull data)",
    )  # fmt: skip
    p.add_argument(
        "--current-dir", type=_numbers, metavar="DEG[,...]", help="current directions, going towards (°)"
    )
    p.add_argument("--seeds", type=_seeds, metavar="0-7,9", help="seeds (default 0-7)")
    p.add_argument(
        "--observer", action="append", default=[], metavar="SPEC",
        help="observer spec as dpgw replay takes it, NAME[:key=value,...][@label], NAME one of "
        f"{', '.join(OBSERVER_NAMES)} (repeatable; default: every one of them)",
    )  # fmt: skip
    p.add_argument(
        "--loop-observer", metavar="SPEC", help="the observer the DP controller acts on (default passive)"
    )
    p.add_argument(
        "--duration", type=positive_float, metavar="S", help="simulated seconds per case (default 300)"
    )
    p.add_argument(
        "--settle",
        type=non_negative_float,
        metavar="S",
        help="scored from S s on, less than --duration (default a third of the case)",
    )
    p.add_argument(
        "--out", type=Path, default=Path("study_out"), metavar="DIR", help="output folder (default study_out)"
    )
    p.add_argument("--cache", type=Path, metavar="DIR", help="case cache (default OUT/cache)")
    p.add_argument("--no-cache", action="store_true", help="run every case, read and write no cache")
    run_on = p.add_mutually_exclusive_group()
    run_on.add_argument(
        "--workers", type=int_at_least(0, "0 runs serially, N >= 1 starts N local Dask workers"), metavar="N",
        help="local Dask worker processes (default: one per core); 0 = serial, in this process",
    )  # fmt: skip
    run_on.add_argument("--serial", action="store_true", help="= --workers 0 (no Dask)")
    run_on.add_argument("--scheduler", metavar="tcp://HOST:8786", help="run on this existing Dask cluster")
    p.add_argument("--no-plots", action="store_true", help="write no box plots")
    p.add_argument(
        "--update-doc", metavar="FILE.md[#NAME]",
        help=f"also put the summary between {DOC_BEGIN} and {DOC_END} in FILE.md (with #NAME: between "
        "<!-- study-table:NAME:begin --> and <!-- study-table:NAME:end -->)",
    )  # fmt: skip
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=run)


def build_spec(args: argparse.Namespace) -> Any:
    """The grid: the study file's, with any flag given on the command line in place of its value."""
    from dataclasses import replace

    from dpgw.study.spec import StudySpec, StudySpecError, load_study_file, seas_product, study_file_path

    spec = load_study_file(study_file_path(args.file)) if args.file else StudySpec(scenarios=())
    sea_grid = {
        key: values
        for key, values in (
            ("hs_m", args.hs), ("tp_s", args.tp), ("direction_deg", args.direction),
            ("current_mps", args.current), ("current_dir_deg", args.current_dir),
        )
        if values
    }  # fmt: skip
    changes: dict[str, Any] = {}
    if args.scenario:
        changes["scenarios"] = tuple(dict.fromkeys(args.scenario))
    if sea_grid:
        changes["seas"] = seas_product(sea_grid)
    if args.seeds is not None:
        changes["seeds"] = tuple(args.seeds)
    if args.observer:
        changes["observers"] = tuple(args.observer)
    if args.loop_observer:
        changes["loop_observer"] = args.loop_observer
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if args.settle is not None:
        changes["settle_s"] = args.settle
    spec = replace(spec, **changes)
    if args.settle is not None and args.settle >= spec.duration_s:
        raise StudySpecError(
            f"--settle {args.settle:g}: scoring must start before the case ends: give less than the "
            f"duration, {spec.duration_s:g} s (or a longer --duration)"
        )
    if not spec.scenarios:
        raise StudySpecError("study: no scenario: give --scenario NAME or --file STUDY.toml")
    spec.check()
    return spec


def _marker_lines(doc: str, begin: str, end: str) -> tuple[int, int] | None:
    """Indexes of the lines that are exactly the two markers (a marker quoted in the text does not count)."""
    lines = doc.split("\n")
    starts = [k for k, line in enumerate(lines) if line.strip() == begin]
    ends = [k for k, line in enumerate(lines) if line.strip() == end]
    if len(starts) != 1 or len(ends) != 1 or ends[0] < starts[0]:
        return None
    return starts[0], ends[0]


def doc_target(spec: str) -> tuple[Path, str, str]:
    """FILE.md[#NAME] → the file and its markers, each alone on a line, once; raises ValueError naming what
    is missing."""
    name, _, section = spec.partition("#")
    path = Path(name)
    begin, end = doc_markers(section)
    try:
        doc = path.read_text()
    except OSError as exc:
        raise ValueError(f"--update-doc {spec}: {exc.strerror}") from None
    if _marker_lines(doc, begin, end) is None:
        raise ValueError(
            f"--update-doc {spec}: no {begin} … {end} markers (each once, alone on a line) to put the "
            "table between"
        )
    return path, begin, end


def update_doc(spec: str, text: str, command: str) -> None:
    path, begin, end = doc_target(spec)
    lines = path.read_text().split("\n")
    found = _marker_lines("\n".join(lines), begin, end)
    assert found is not None
    first, last = found
    body = [begin, f"<!-- made by: {command} -->", "", *text.split("\n"), end]
    path.write_text("\n".join([*lines[:first], *body, *lines[last + 1 :]]))


@contextmanager
def stopped_by_signals() -> Iterator[None]:
    """SIGTERM (``kill``, a service stopped) and SIGHUP (the SSH session or terminal closed) stop the study
    as Ctrl-C does: `StudyInterrupted` is raised where the study is, the workers are stopped on the way out
    and what is kept is said; the exit code is the shell's for the signal (143, 129). Before, the process
    died at once with 143 and no word, and its worker processes' semaphores leaked (multiprocessing's
    resource tracker warned). A second signal while stopping is ignored: the first one is being obeyed."""
    from dpgw.study.runner import StudyInterrupted

    stopping = (signal.SIGTERM, signal.SIGHUP)

    def stop(signum: int, _frame: object) -> None:
        for s in stopping:
            signal.signal(s, signal.SIG_IGN)
        raise StudyInterrupted(signal.Signals(signum).name, 128 + signum)

    old = {s: signal.signal(s, stop) for s in stopping}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


def run(args: argparse.Namespace) -> int:
    from dpgw.study.runner import StudyInterrupted

    with stopped_by_signals():
        try:
            return _run(args)
        except StudyInterrupted as stop:  # a signal between the study's end and the outputs' start
            print(f"\ndpgw study: stopped ({stop.why})", file=sys.stderr)
            return stop.exit_code


def _out_problem(args: argparse.Namespace) -> str | None:
    """What stops the study writing its outputs and its cache where asked: a file in a folder's place, or
    a folder this user may not write in (or make)."""
    from dpgw.cli_paths import output_folder_problem

    cache = None if args.no_cache else args.cache or args.out / "cache"
    return output_folder_problem("--out", args.out) or output_folder_problem("--cache", cache)


def _run(args: argparse.Namespace) -> int:
    from dpgw.study.cache import CaseCache
    from dpgw.study.runner import StudyInterrupted, StudyRunError, run_study
    from dpgw.study.spec import StudySpecError

    try:
        spec = build_spec(args)
        if args.update_doc:
            doc_target(args.update_doc)  # before the study: a wrong file stops it now, not after an hour
    except (StudySpecError, ValueError) as exc:
        # (a spec's own messages start "study: " for library callers: said once here)
        print(f"dpgw study: {str(exc).removeprefix('study: ')}", file=sys.stderr)
        return 2
    if problem := _out_problem(args):  # before the study, not after its hour
        print(f"dpgw study: {problem}", file=sys.stderr)
        return 2
    cache = None if args.no_cache else CaseCache(args.cache or args.out / "cache")
    workers = 0 if args.serial else args.workers
    cases = spec.cases()
    from dpgw.study import outputs

    # said before the run, so that a study too short to score can be stopped and given a longer duration
    _warn(outputs.short_scoring_warnings(outputs.planned_rows(cases)))
    unsettled = outputs.unsettled_warnings(cases)
    _warn(unsettled)
    try:
        result = run_study(
            cases, workers=workers, scheduler=args.scheduler, cache=cache, progress=not args.no_progress
        )
    except StudyRunError as exc:
        print(f"dpgw study: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # an hour's study is stopped this way; say what is kept, no traceback
        stop = exc if isinstance(exc, StudyInterrupted) else StudyInterrupted()
        print(f"\ndpgw study: stopped ({stop.why}); {kept_text(stop, cache)}", file=sys.stderr)
        return stop.exit_code
    try:
        return _write_outputs(args, result, unsettled)
    except KeyboardInterrupt as exc:
        why = exc.why if isinstance(exc, StudyInterrupted) else "Ctrl-C"
        print(
            f"\ndpgw study: stopped ({why}) while writing the outputs in {args.out}; the cases are cached: "
            "run the same command again to write them",
            file=sys.stderr,
        )
        return exc.exit_code if isinstance(exc, StudyInterrupted) else 130


def kept_text(stop: Any, cache: Any) -> str:
    """What a stopped study keeps: ``8 of 64 cases done and cached in DIR: the same command resumes from
    them`` (``stop``: a `StudyInterrupted` with its count)."""
    if cache is None:
        return f"{stop.done} of {stop.total} cases done, none kept (--no-cache)"
    if stop.done == 0:
        return f"0 of {stop.total} cases done: nothing is cached in {cache.folder} yet"
    return (
        f"{stop.done} of {stop.total} case{'' if stop.total == 1 else 's'} done and cached in "
        f"{cache.folder}: the same command resumes from them"
    )


def _write_outputs(args: argparse.Namespace, result: Any, unsettled: list[str]) -> int:
    """The table, the summary, the plots and the report of a finished study."""
    from dpgw.study import outputs

    files = outputs.write_table(result.rows, args.out)
    text = outputs.summary_markdown(result.rows)
    (args.out / "summary.md").write_text(text + "\n")
    files.append(args.out / "summary.md")
    if not args.no_plots:
        files += outputs.box_plots(result.rows, args.out)
    if args.update_doc:
        command = "dpgw study " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["study"] else "dpgw study"
        update_doc(args.update_doc, text, command)
    warnings = outputs.short_scoring_warnings(result.rows) + unsettled
    where = "serial" if result.workers == 0 else f"{result.workers} Dask workers"
    report = {
        "cases": result.cases,
        "computed": result.computed,
        "cached": result.cached,
        "rows": len(result.rows),
        "seconds": round(result.seconds, 2),
        "cases_per_minute": round(60.0 * result.computed / result.seconds, 2) if result.computed else None,
        "run_on": where,
        "scheduler": result.scheduler or None,
        "files": [str(f) for f in files],
        "warnings": warnings,
        "summary": outputs.json_summary(result.rows),
    }
    if args.json:  # (the warnings in the report; on stderr before the run)
        print(json.dumps(report, indent=2, allow_nan=False, default=str))
        return 0
    print(text)
    if warnings:  # (said in full before the run; a pointer after the table, where it is read)
        _warn([f"{len(warnings)} warning(s) above on what the figures hold (said before the run)"])
    print(
        f"{result.cases} case{'' if result.cases == 1 else 's'} ({result.computed} run, {result.cached} "
        f"from the cache) on {where} in "
        f"{result.seconds:.1f} s; files in {args.out}/",
        file=sys.stderr,
    )
    return 0


def _warn(warnings: list[str]) -> None:
    sys.stdout.flush()
    for warning in warnings:
        print(f"dpgw study: warning: {warning}", file=sys.stderr)
