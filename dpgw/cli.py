"""The ``dpgw`` command line: one entry point, a subcommand per job.

argparse (standard library) is used: it gives ``--help`` on every subcommand and needs no dependency.
Each subcommand lives in its own module (``dpgw/cli_*.py``), which declares its ``NAME``, ``HELP``,
``DESCRIPTION`` and ``EPILOG`` texts and ``add_arguments(parser)``; the parsers are built here, one way
for all of them (`dpgw.cli_help.HelpFormatter`: descriptions wrap, the examples in an epilog keep their
line breaks).

Every parser is built at start-up, also for ``dpgw --help``; so a ``cli_*`` module imports only the
standard library and light modules of names at its top, and the heavy packages (numpy, numba, scipy,
Zenoh, pydantic, the simulator and the gateway) inside the functions that run its command. A test
(tests/test_cli_startup.py) holds this.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from types import FrameType

from dpgw import (
    cli_capability,
    cli_demo,
    cli_listen,
    cli_radiation,
    cli_replay,
    cli_run,
    cli_sim,
    cli_study,
    cli_tune,
    journal,
    numba_cache,
)
from dpgw.cli_help import HelpFormatter
from dpgw.stderr_guard import StderrGuard

SUBCOMMANDS = [
    cli_run,
    cli_demo,
    cli_sim,
    cli_replay,
    cli_tune,
    cli_listen,
    cli_radiation,
    cli_study,
    cli_capability,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dpgw",
        description=(
            "dpgw: hardware-in-the-loop gateway for dynamic positioning. Reads DGPS/gyro NMEA 0183 and "
            "MAVLink thruster feedback, runs wave-filtering observers, publishes on Zenoh, logs to MCAP."
        ),
        epilog="Run 'dpgw COMMAND --help' for the options of each command.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--version",
        action=_Version,
        help="print the version, and whether this install runs its hot path compiled (the speed of "
        "docs/performance.md) or interpreted, and why; then exit",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in SUBCOMMANDS:
        module.add_arguments(
            sub.add_parser(
                module.NAME,
                help=module.HELP,
                description=module.DESCRIPTION,
                epilog=module.EPILOG or None,
                formatter_class=HelpFormatter,
            )
        )
    return parser


class _Version(argparse.Action):
    """``--version``: worked out when asked (the compiled-or-not check reads the sources), not at every
    start-up."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, help=str(kwargs.get("help", "")))

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        from importlib.metadata import PackageNotFoundError, version

        from wire import compiled

        try:
            number = version("dpgw")
        except PackageNotFoundError:  # (run from a checkout without installing)
            number = "(not installed)"
        print(f"dpgw {number}\nhot path: {compiled.status().describe()}")  # (stdout, as argparse's own)
        parser.exit(0)


def subparser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    """The parser of ``dpgw COMMAND``."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    found: argparse.ArgumentParser = sub.choices[command]
    return found


BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def single_threaded_blas() -> None:
    """One BLAS thread unless the user set otherwise; call before numpy is imported.

    dpgw's matrices are small (at most a few hundred wave components by 18 columns), too small for a second
    BLAS thread to help, but OpenBLAS starts one per core anyway and lets it spin-wait after every call.
    Measured on a 2-core machine (``dpgw sim``'s loop, fossen_strand_1999 at 10 Hz): the same wall time
    either way, but twice the CPU time with the default threads, taken from whatever else runs (the
    gateway beside the simulator, a study's other worker, the vessel's other software).
    """
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


def hangup_as_terminate() -> None:
    """SIGHUP (the terminal or SSH session the command runs in closing) does what SIGTERM does in each
    command: ``dpgw run``, ``dpgw sim --realtime``, a paced replay stop and close their logs complete.

    Python's default for SIGHUP is to end the process at once, like SIGKILL: an engineer's SSH session to
    the bench dropping cut the gateway's and the simulator's MCAP logs (no summary, no footer). Each
    command sets its own SIGTERM handler when it is ready for one; the SIGHUP handler looks it up when the
    signal comes and calls it (with SIGHUP's number, so messages name SIGHUP), or, before the command has
    one, ends the process as SIGHUP would. A SIGHUP ignored from the start (``nohup dpgw ...``) stays
    ignored."""
    import signal

    hup = getattr(signal, "SIGHUP", None)  # (POSIX only)
    if hup is None or signal.getsignal(hup) == signal.SIG_IGN:
        return

    def on_hangup(signum: int, frame: FrameType | None) -> None:
        handler = signal.getsignal(signal.SIGTERM)
        if callable(handler):
            handler(signum, frame)
            return
        signal.signal(hup, signal.SIG_DFL)  # no handler yet: the default, as without this one
        os.kill(os.getpid(), hup)

    signal.signal(hup, on_hangup)


def main(argv: Sequence[str] | None = None) -> int:
    hangup_as_terminate()
    single_threaded_blas()
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        # argparse would report these with the top-level usage ("dpgw [-h] COMMAND ..."), which lists no
        # option of the command; the command's own usage shows what it takes.
        (parser if args.command is None else subparser(parser, args.command)).error(
            f"unrecognized arguments: {' '.join(unknown)}"
        )
    if args.command is None:
        parser.print_help()
        return 2
    numba_cache.ensure_writable_cache()  # before a command imports numba (not for --help)
    stderr = sys.stderr
    sys.stderr = StderrGuard(stderr)  # (before the log handlers take it)
    try:
        journal.default_logging(args.command)
        code: int = args.func(args)
    except BrokenPipeError:
        if not _stdout_gone():
            raise
        # `dpgw listen --json | head -3`: the reader stopped reading. Stop quietly, as shell tools killed by
        # SIGPIPE do (status 128 + 13), and point stdout at /dev/null so the interpreter's final flush of
        # what is left in its buffer does not fail again at exit.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 128 + 13
    except KeyboardInterrupt:
        # Ctrl-C where the command has no stop of its own (its start-up: reading the logs, loading the
        # vessel, compiling kernels; a short command: a fit, a capability plot): one line and the status a
        # shell gives (130), not a traceback. The long runs stop their own way, their files complete.
        off_a_bar = "\n" if stderr.isatty() else ""  # (a progress bar's line is left as it is)
        print(f"{off_a_bar}dpgw {args.command}: stopped by Ctrl-C before it finished", file=stderr)
        import signal

        return 128 + signal.SIGINT
    finally:
        sys.stderr = stderr
    return code


def _stdout_gone() -> bool:
    """Whether stdout is a pipe or socket whose reader has gone (poll reports an error on it)."""
    import select

    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # replaced by a test's capture, or closed
        return False
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))


if __name__ == "__main__":
    sys.exit(main())
