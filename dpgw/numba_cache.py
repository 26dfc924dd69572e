"""A folder numba may cache the compiled kernels in, found before numba is imported.

dpgw's kernels are ``numba.njit(cache=True)``: numba compiles them at their first call (about 15 s for
all of them) and keeps the machine code in a cache, in the first of these it can write: ``NUMBA_CACHE_DIR``,
``__pycache__`` beside the module, ``$XDG_CACHE_HOME/numba`` (``~/.cache/numba``; macOS
``~/Library/Caches/numba``). Where none of them is writable it raises ``RuntimeError: cannot cache
function ...: no locator available`` *when the module is imported*, so every command that imports the
numerics stopped with a traceback. That is the onboard install as documented: dpgw in a virtual
environment root owns (``/opt/dpgw/venv``), run by a system user whose home does not exist
(``useradd --system`` makes none; systemd's ``StateDirectory`` makes it only when the service starts),
so ``sudo -u dpgw dpgw run --config ... --check`` failed before the unit was ever started; and under the
unit's ``ProtectSystem=strict`` only the service's own folders are writable.

`choose` says where numba will cache; when none of numba's places is writable it picks a folder of this
user's under the temporary directory, which `main` sets as ``NUMBA_CACHE_DIR`` (and says so on stderr:
there, the cache may not outlive a reboot, and under ``PrivateTmp`` not a restart; each start without it
compiles again). A cache is code this process loads: a folder of that name that another user could have
made or may write to is not used (a fresh private one is made instead). The shipped unit sets
``NUMBA_CACHE_DIR`` to its ``CacheDirectory`` (``/var/cache/dpgw``), so the service never needs this.
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from dpgw.cli_paths import writable

# A module with compiled kernels: numba's in-tree cache is ``__pycache__`` beside each such module, and
# dpgw's packages are installed together, so one stands for all.
KERNEL_PACKAGE = Path(__file__).resolve().parent.parent / "observers"


@dataclass(frozen=True)
class CacheChoice:
    path: str
    """Where numba will cache the kernels."""
    fallback: bool
    """True: none of numba's own places was writable; ``path`` is this user's folder under the temporary
    directory, to be set as ``NUMBA_CACHE_DIR``."""
    tried: tuple[str, ...]
    """numba's places, in its order, that were not writable (for the message)."""


def user_wide_dir(env: Mapping[str, str]) -> str:
    """numba's user-wide cache folder (``numba.misc.appdirs.user_cache_dir("numba")``)."""
    if sys.platform == "darwin":
        return os.path.join(os.path.expanduser("~/Library/Caches"), "numba")
    base = env.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "numba")


def private_dir(base: str) -> str:
    """``<base>/dpgw-numba-<uid>``, made mode 700 if absent; if it exists but is not this user's own
    folder that nobody else may write to, a fresh private folder instead (a cache is code we load)."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = os.path.join(base, f"dpgw-numba-{uid}")
    try:
        os.mkdir(path, 0o700)
        return path
    except FileExistsError:
        st = os.lstat(path)
        if stat.S_ISDIR(st.st_mode) and st.st_uid == uid and not st.st_mode & 0o022:
            return path
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="dpgw-numba-", dir=base)


def choose(env: Mapping[str, str] | None = None, package: Path = KERNEL_PACKAGE) -> CacheChoice:
    """Where numba will cache dpgw's kernels (numba's order), or this user's folder under the temporary
    directory when none of numba's places is writable (made here, to be set as ``NUMBA_CACHE_DIR``)."""
    env = os.environ if env is None else env
    places = [env["NUMBA_CACHE_DIR"]] if env.get("NUMBA_CACHE_DIR") else []
    places += [str(package / "__pycache__"), user_wide_dir(env)]
    for k, place in enumerate(places):
        if writable(place):
            return CacheChoice(place, fallback=False, tried=tuple(places[:k]))
    return CacheChoice(private_dir(tempfile.gettempdir()), fallback=True, tried=tuple(places))


def ensure_writable_cache() -> None:
    """Call before numba is imported: if numba could cache nowhere, give it a folder, and say so."""
    choice = choose()
    if not choice.fallback:
        return
    os.environ["NUMBA_CACHE_DIR"] = choice.path
    print(
        f"dpgw: numba cannot cache the compiled kernels in {' or '.join(choice.tried)} (not writable for "
        f"this user); caching them in {choice.path}. Set NUMBA_CACHE_DIR to a folder this user may write "
        "to keep them across reboots (the service unit uses /var/cache/dpgw); without a kept cache each "
        "start compiles them again (about 15 s)",
        file=sys.stderr,
    )
