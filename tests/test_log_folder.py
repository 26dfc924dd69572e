"""The folder of a log to write (`wire.mcap.folder`), one rule for ``dpgw run`` (``--log``, ``log.path``),
``dpgw demo --out`` and ``dpgw sim --out``: a missing last folder is made and said on stderr; a path whose
folder's parent is missing too is refused, nothing made. Real files and processes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from dpgw.cli_paths import mcap_path_problem
from wire.mcap.folder import log_folder_problem, make_log_folder

ROOT = Path(__file__).resolve().parents[1]


def test_only_the_last_missing_level_is_made(tmp_path: Path) -> None:
    assert log_folder_problem(tmp_path / "x.mcap") is None
    assert make_log_folder(tmp_path / "x.mcap") is None  # there: nothing made
    assert make_log_folder(tmp_path / "new" / "x.mcap") == str(tmp_path / "new")
    assert (tmp_path / "new").is_dir()
    deep = tmp_path / "a" / "b" / "x.mcap"
    problem = log_folder_problem(deep)
    assert problem is not None and f"mkdir -p {tmp_path / 'a' / 'b'}" in problem, problem
    with pytest.raises(FileNotFoundError):
        make_log_folder(deep)
    assert not (tmp_path / "a").exists()
    assert mcap_path_problem("--out", deep, made=True) == f"--out {deep}: {problem}"
    assert mcap_path_problem("--out", tmp_path / "one" / "x.mcap", made=True) is None
    (tmp_path / "afile").write_text("")  # a file where the parent folder should be: the opening says so
    assert log_folder_problem(tmp_path / "afile" / "logs" / "x.mcap") is None
    with pytest.raises(NotADirectoryError):
        make_log_folder(tmp_path / "afile" / "logs" / "x.mcap")


def dpgw(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dpgw", *argv], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


def test_sim_makes_the_last_folder_and_says_so_and_refuses_more(tmp_path: Path) -> None:
    """``dpgw sim`` refused any missing folder, while the demo and the gateway made every level silently."""
    deep = tmp_path / "a" / "b" / "sim.mcap"
    p = dpgw("sim", "--scenario", "hassani", "--duration", "2", "--out", str(deep))
    assert p.returncode == 2 and f"dpgw sim: --out {deep}: neither the folder" in p.stderr, p.stderr
    assert not (tmp_path / "a").exists()
    one = tmp_path / "runs" / "sim.mcap"
    p = dpgw("sim", "--scenario", "hassani", "--duration", "2", "--out", str(one))
    assert p.returncode == 0, p.stderr
    assert f"dpgw sim: made the log's folder {one.parent} (it did not exist)" in p.stderr.splitlines()
    assert one.exists()


def test_demo_refuses_a_log_whose_folder_parent_is_missing(tmp_path: Path) -> None:
    deep = tmp_path / "a" / "b" / "demo.mcap"
    p = dpgw("demo", "--out", str(deep), "--no-foxglove", "--duration", "10")
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith(f"dpgw demo: --out {deep}: neither the folder {deep.parent} nor"), p.stderr
    assert not (tmp_path / "a").exists()


def test_sim_writes_its_other_files_by_the_same_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``dpgw sim --tlog`` and the open loop's ``--csv`` and ``--out`` refused any missing folder, while
    ``--out`` of a scenario run, ``dpgw run`` and ``dpgw demo`` made a log's own folder: the same rule now,
    the file's own folder made and said, a deeper missing one refused with nothing made. ``--inputs`` is
    read, not written: a missing one is said as such, naming the flag and the path, and nothing is made."""
    from dpgw.cli import main

    tlog = tmp_path / "bench" / "x.tlog"
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--tlog", str(tlog)]) == 0
    err = capsys.readouterr().err
    assert f"dpgw sim: made the folder {tlog.parent} for --tlog (it did not exist)" in err.splitlines(), err
    assert tlog.stat().st_size > 0
    deep = tmp_path / "a" / "b" / "x.tlog"
    assert main(["sim", "--scenario", "hassani", "--duration", "1", "--tlog", str(deep)]) == 2
    assert capsys.readouterr().err.startswith(f"dpgw sim: --tlog {deep}: neither the folder {deep.parent}")
    assert not (tmp_path / "a").exists()

    inputs = str(ROOT / "tests" / "data" / "mss-osv" / "steps_inputs.csv")
    csv, log = tmp_path / "states" / "s.csv", tmp_path / "logs" / "s.mcap"
    assert main(["sim", "--vessel", "mss_osv", "--inputs", inputs, "--csv", str(csv), "--out", str(log)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert f"dpgw sim: made the folder {csv.parent} for --csv (it did not exist)" in err, err
    assert f"dpgw sim: made the folder {log.parent} for --out (it did not exist)" in err, err
    assert len(csv.read_text().splitlines()) > 100 and log.stat().st_size > 0
    for flag, path in (("--csv", tmp_path / "c" / "d" / "s.csv"), ("--out", tmp_path / "c" / "d" / "s.mcap")):
        assert main(["sim", "--vessel", "mss_osv", "--inputs", inputs, flag, str(path)]) == 2
        assert capsys.readouterr().err.startswith(
            f"dpgw sim: {flag} {path}: neither the folder {path.parent}"
        )
    assert not (tmp_path / "c").exists()

    missing = tmp_path / "trial" / "inputs.csv"
    assert (
        main(["sim", "--vessel", "mss_osv", "--inputs", str(missing), "--csv", str(tmp_path / "n" / "s.csv")])
        == 2
    )
    assert capsys.readouterr().err.startswith(f"dpgw sim: --inputs {missing}: no such file"), missing
    assert not (tmp_path / "n").exists() and not (tmp_path / "trial").exists()


def test_the_open_loop_never_writes_over_a_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``dpgw sim --inputs … --out X.mcap`` wrote over an existing X, where every other command that
    writes a log goes on in the next free file of its set and says so."""
    import json

    from dpgw.cli import main

    inputs = str(ROOT / "tests" / "data" / "mss-osv" / "steps_inputs.csv")
    log = tmp_path / "s.mcap"
    args = ["sim", "--vessel", "mss_osv", "--inputs", inputs, "--out", str(log)]
    assert main(args) == 0
    first = log.read_bytes()
    capsys.readouterr()
    assert main([*args, "--json"]) == 0
    out, err = capsys.readouterr()
    nxt = tmp_path / "s_0001.mcap"
    assert f"log -> {nxt} ({log} exists: a log is never overwritten)" in err.splitlines(), err
    assert json.loads(out)["out"] == str(nxt)
    assert log.read_bytes() == first and nxt.stat().st_size > 0
