"""dpgw runs where numba cannot cache beside its code nor in the user's home (`dpgw.numba_cache`).

The onboard install: the package in a virtual environment root owns, run by a system user without a home.
numba then raised ``RuntimeError: cannot cache function ...: no locator available`` at import, and the
documented ``sudo -u dpgw dpgw run --config ... --check`` stopped with a traceback. The test builds that
install for real in a subprocess — a copy of dpgw's packages whose ``__pycache__`` places are files in
the way (numba cannot make its cache there, as in a read-only tree; a test running as root cannot use
permissions for this), a HOME that is a file — and runs the documented check.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from dpgw import numba_cache

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("dpgw", "gateway", "observers", "simulator", "wire")


def _read_only_install(into: Path) -> Path:
    """dpgw's packages copied to ``into``, each folder's ``__pycache__`` a file (numba cannot write)."""
    for name in PACKAGES:
        shutil.copytree(ROOT / name, into / name, ignore=shutil.ignore_patterns("__pycache__"))
    for folder, _dirs, _files in os.walk(into):
        (Path(folder) / "__pycache__").write_bytes(b"")
    return into


def test_check_runs_as_a_user_numba_cannot_cache_for(tmp_path: Path) -> None:
    install = _read_only_install(tmp_path / "site")
    home = tmp_path / "home-is-a-file"
    home.write_bytes(b"")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "XDG_"))}
    env.update(HOME=str(home), TMPDIR=str(tmp), PYTHONPATH=str(install), PYTHONDONTWRITEBYTECODE="1")
    config = ROOT / "examples" / "hil_bench.toml"
    r = subprocess.run(
        [sys.executable, "-m", "dpgw", "run", "--config", str(config), "--check"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "no locator available" not in r.stderr, r.stderr
    assert r.returncode == 0, r.stderr
    cache = tmp / f"dpgw-numba-{os.getuid()}"
    assert f"caching them in {cache}" in r.stderr
    # numba made its per-package cache folders there (one per folder of kernels it saw imported)
    assert any(p.name.startswith("observers_") for p in cache.iterdir()), list(cache.iterdir())
    assert (cache.stat().st_mode & 0o777) == 0o700


def test_numba_own_places_are_kept_when_writable(tmp_path: Path) -> None:
    package = tmp_path / "observers"
    package.mkdir()
    given = tmp_path / "given"
    assert numba_cache.choose({"NUMBA_CACHE_DIR": str(given)}, package).path == str(given)
    choice = numba_cache.choose({"XDG_CACHE_HOME": str(tmp_path / "x")}, package)
    assert (choice.path, choice.fallback) == (str(package / "__pycache__"), False)
    (package / "__pycache__").write_bytes(b"")  # in the way: the user-wide folder is next
    choice = numba_cache.choose({"XDG_CACHE_HOME": str(tmp_path / "x")}, package)
    assert (choice.path, choice.fallback) == (str(tmp_path / "x" / "numba"), False)


def test_a_private_folder_someone_else_could_write_is_not_used(tmp_path: Path) -> None:
    planted = tmp_path / f"dpgw-numba-{os.getuid()}"
    planted.mkdir(mode=0o777)
    planted.chmod(0o777)  # (past the umask) anyone could have put a cache there: code we would load
    chosen = numba_cache.private_dir(str(tmp_path))
    assert chosen != str(planted)
    assert Path(chosen).parent == tmp_path
    assert (Path(chosen).stat().st_mode & 0o777) == 0o700
    planted.chmod(0o700)
    assert numba_cache.private_dir(str(tmp_path)) == str(planted)
