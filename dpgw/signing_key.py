"""A MAVLink 2 signing key read from a file, for the command line (``dpgw sim --signing-key-file``).

The file holds the key as the gateway config's ``signing_key`` does: 64 hexadecimal characters (32 bytes),
surrounding whitespace ignored. A file, not the key itself on the command line: any user of the machine
reads a process's command line (``ps``), while a file can be kept to its owner (``chmod 600``). The key is
never printed: a bad file is described by its length only.
"""

from __future__ import annotations

import re
import stat
from pathlib import Path

from gateway.config.model import SIGNING_KEY


def read_key_file(option: str, path: str) -> tuple[bytes, str | None]:
    """The key in ``path`` and a warning when others may read the file (None when only its owner can).
    Raises ValueError with one message naming ``option`` and the file when it cannot be read or does not
    hold a key."""
    where = f"{option} {path}"
    try:
        mode = Path(path).stat().st_mode
        text = Path(path).read_text(encoding="ascii").strip()
    except FileNotFoundError:
        raise ValueError(
            f"{where}: no such file (expected a file holding 64 hexadecimal characters)"
        ) from None
    except IsADirectoryError:
        raise ValueError(f"{where}: a folder, not a key file") from None
    except UnicodeDecodeError:
        raise ValueError(
            f"{where}: not a signing key (expected 64 hexadecimal characters, not binary)"
        ) from None
    except OSError as exc:
        raise ValueError(f"{where}: cannot read the key file ({exc.strerror or exc})") from None
    if not SIGNING_KEY.fullmatch(text):
        raise ValueError(
            f"{where}: not a signing key (expected 64 hexadecimal characters, got {len(text)} characters"
            + (", not all hexadecimal" if re.search(r"[^0-9a-fA-F]", text) else "")
            + ")"
        )
    warning = None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        warning = f"{where}: other users of this machine may read the key (chmod 600 {path})"
    return bytes.fromhex(text), warning
