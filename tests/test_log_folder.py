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
