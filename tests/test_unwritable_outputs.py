"""Where a command writes, when this user may not write there (a log on a write-protected stick, a shared
data folder, a folder of the service's user): said before any work with one line naming the flag, the
path, why and what to do, never as a traceback after the replay; a replay's default output beside such a
log goes to the current folder instead, said. Real processes; as root, without the capability that lets
root write anywhere (``CAP_DAC_OVERRIDE``), so that a folder's permissions hold for it as for a user."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from wire.codecs import nmea_encode as enc

ROOT = Path(__file__).resolve().parents[1]


def unprivileged() -> list[str]:
    """A command prefix without the privilege to write in a folder whose permissions forbid it: nothing
    when we lack it already; as root, ``setpriv`` dropping the capabilities that override permissions (root
    stays root, so the interpreter under /root stays reachable)."""
    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv to drop CAP_DAC_OVERRIDE")
    caps = "-dac_override,-dac_read_search"
    return ["setpriv", f"--bounding-set={caps}", f"--inh-caps={caps}"]


def dpgw(cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # (the checkout, from any current folder)
    return subprocess.run(
        [*unprivileged(), sys.executable, "-m", "dpgw", *argv],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture
def read_only(tmp_path: Path) -> Iterator[Path]:
    """A folder this user may read but not write, holding a 30 s NMEA log (GGA, HDT at 5 Hz)."""
    folder = tmp_path / "stick"
    folder.mkdir()
    t0 = datetime(2026, 6, 1, 12, 0, tzinfo=UTC)
    lines = []
    for k in range(150):
        t = t0 + timedelta(seconds=0.2 * k)
        lines.append(enc.gga("GP", t, 59.4 + 1e-6 * k, 10.5, 2, 12, 0.8, 10.0))
        lines.append(enc.hdt("HE", 30.0))
    (folder / "trial.nmea").write_text("".join(lines))
    folder.chmod(0o555)
    try:
        yield folder
    finally:
        folder.chmod(0o755)


def test_a_replay_beside_a_read_only_log_is_written_in_the_current_folder(
    read_only: Path, tmp_path: Path
) -> None:
    """The default output is beside the log; where that cannot be written, the current folder, said."""
    here = tmp_path / "work"
    here.mkdir()
    p = dpgw(here, "replay", str(read_only / "trial.nmea"), "--vessel", "mss_supply")
    assert p.returncode == 0, p.stderr
    assert (
        f"dpgw replay: out -> trial-replay.mcap (beside the log, {read_only / 'trial-replay.mcap'} cannot be "
        "written; --out names another place)"
    ) in p.stderr.splitlines(), p.stderr
    assert (here / "trial-replay.mcap").stat().st_size > 0
    assert sorted(x.name for x in read_only.iterdir()) == ["trial.nmea"]


def test_a_replay_where_neither_the_log_folder_nor_the_current_one_can_be_written(read_only: Path) -> None:
    p = dpgw(read_only, "replay", "trial.nmea", "--vessel", "mss_supply")
    assert p.returncode == 2
    assert p.stderr.splitlines()[-1].startswith(
        f"dpgw replay: --out trial-replay.mcap: cannot write there: {read_only} is not writable for this "
        "user ("
    ), p.stderr
    assert "Traceback" not in p.stderr and sorted(x.name for x in read_only.iterdir()) == ["trial.nmea"]


def _refusals(ro: Path, out: Path) -> list[tuple[list[str], str]]:
    """(command, the flag and path it must refuse): each writes into the read-only folder through one flag,
    everything else it writes going to ``out`` (writable)."""
    log, states = str(ro / "trial.nmea"), str(ro / "states.csv")
    csv = out / "inputs.csv"
    csv.write_text("t,current_speed,current_dir_deg,n_1,n_2,n_3,alpha_3,n_4,alpha_4\n0,0,0,0,0,0,0,0,0\n")
    return [
        (["replay", log, "--vessel", "mss_supply", "--out", str(ro / "r.mcap")], f"--out {ro / 'r.mcap'}"),
        (
            [
                "replay",
                log,
                "--vessel",
                "mss_supply",
                "--out",
                str(out / "r.mcap"),
                "--report",
                str(ro / "rep"),
            ],
            f"--report {ro / 'rep'}",
        ),
        (
            ["sim", "--scenario", "hassani", "--duration", "2", "--out", str(ro / "new" / "s.mcap")],
            f"--out {ro / 'new' / 's.mcap'}",
        ),
        (
            [
                "sim",
                "--vessel",
                "mss_osv",
                "--inputs",
                str(csv),
                "--out",
                str(out / "s.mcap"),
                "--csv",
                states,
            ],
            f"--csv {ro / 'states.csv'}",
        ),
        (
            ["demo", "--no-foxglove", "--duration", "10", "--out", str(ro / "demo.mcap")],
            f"--out {ro / 'demo.mcap'}",
        ),
        (
            ["study", "--scenario", "hassani", "--duration", "5", "--out", str(ro / "st")],
            f"--out {ro / 'st'}",
        ),
        (["radiation", "mss_supply", "--plots", str(ro / "fit")], f"--plots {ro / 'fit'}"),
        (["capability", "--vessel", "mss_supply", "--plot", str(ro / "cap.png")], f"--plot {ro / 'cap.png'}"),
    ]


def test_every_command_refuses_a_folder_it_cannot_write_before_it_works(
    read_only: Path, tmp_path: Path
) -> None:
    """One line, naming the flag, the path, why and what to do; nothing written anywhere (the replay does
    not run before its report is refused)."""
    out = tmp_path / "out"
    out.mkdir()
    for argv, named in _refusals(read_only, out):
        before = sorted(x.name for x in out.iterdir())
        p = dpgw(tmp_path, *argv)
        command = f"dpgw {argv[0]}"
        lines = [ln for ln in p.stderr.splitlines() if ln.startswith(f"{command}: ")]
        assert p.returncode == 2, (argv, p.stderr)
        assert "Traceback" not in p.stderr, (argv, p.stderr)
        assert lines and lines[-1].startswith(
            f"{command}: {named}: cannot write there: {read_only} is not "
        ), (
            argv,
            p.stderr,
        )
        assert "you may write in" in lines[-1], lines[-1]
        assert sorted(x.name for x in out.iterdir()) == before, argv
        assert sorted(x.name for x in read_only.iterdir()) == ["trial.nmea"], argv


def test_a_read_only_file_system_is_named_as_such(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Why a path cannot be written, when the file system says: a write-protected stick or a read-only
    mount is not a question of permissions. (A read-only mount cannot be made here without privileges, so
    the kernel's two answers are given: access(2) refuses, statvfs(2) flags the file system read-only.)"""
    from types import SimpleNamespace

    from dpgw.cli_paths import unwritable

    stick = tmp_path / "stick"
    stick.mkdir()
    real_access, real_statvfs = os.access, os.statvfs
    inside = (str(stick), str(stick) + os.sep)

    def access(path: str, mode: int) -> bool:
        return not str(path).startswith(inside) and real_access(path, mode)

    def statvfs(path: str) -> object:
        return SimpleNamespace(f_flag=os.ST_RDONLY) if str(path).startswith(inside) else real_statvfs(path)

    monkeypatch.setattr(os, "access", access)
    monkeypatch.setattr(os, "statvfs", statvfs)
    assert unwritable("--out", tmp_path / "x.mcap") is None
    assert unwritable("--out", stick / "logs" / "x.mcap") == (
        f"--out {stick / 'logs' / 'x.mcap'}: cannot write there: {stick} is on a read-only file system: "
        "give a path in a folder you may write in"
    )
    assert unwritable("--report", stick / "rep", folder=True) == (
        f"--report {stick / 'rep'}: cannot write there: {stick} is on a read-only file system: give a folder "
        "you may write in"
    )
