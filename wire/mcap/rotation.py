"""Names of a rotated set of MCAP files: `trial.mcap`, `trial_0001.mcap`, `trial_0002.mcap`, ...

The writer starts file n of a set at `rotated_path(path, n)` when a size or time limit is passed; readers
list the set in writing order with `log_files(path)`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = ["StrPath", "free_path", "log_files", "next_index", "rotated_path"]

StrPath = str | os.PathLike[str]


def rotated_path(path: StrPath, index: int) -> Path:
    """File `index` of a rotated set: 0 is `path` itself, n >= 1 is `<stem>_{n:04d}<suffix>`."""
    p = Path(path)
    return p if index == 0 else p.with_name(f"{p.stem}_{index:04d}{p.suffix}")


def log_files(path: StrPath) -> list[Path]:
    """The existing files of the rotated set that starts at `path`, in writing order."""
    return [q for _, q in _indexed(path)]


def next_index(path: StrPath) -> int:
    """The index after the last existing file of the set (0 when there is none): where a writer that
    continues the set starts."""
    files = _indexed(path)
    return files[-1][0] + 1 if files else 0


def free_path(path: StrPath) -> Path:
    """Where a command that never overwrites writes ``path``: ``path`` itself when it does not exist,
    else the first of ``<stem>_0001<suffix>``, ``<stem>_0002<suffix>``, ... that does not.

    Not `next_index`, which continues a set after its last file (a restarted service's log): a folder of
    sea-trial logs named by date (``trial_2024.mcap``, ``usv_202412071127.mcap``) reads as a set of that
    index, and ``--out trial.mcap`` went to ``trial_2025.mcap`` though ``trial.mcap`` was free."""
    p = Path(path)
    index = 0
    candidate = p
    while candidate.exists():
        index += 1
        candidate = rotated_path(p, index)
    return candidate


def _indexed(path: StrPath) -> list[tuple[int, Path]]:
    """(index, file) of the existing files of the set, in writing order."""
    p = Path(path)
    pattern = re.compile(re.escape(p.stem) + r"_(\d{4,})" + re.escape(p.suffix) + "$")
    numbered = []
    if p.parent.is_dir():
        for q in p.parent.iterdir():
            m = pattern.match(q.name)
            if m:
                numbered.append((int(m.group(1)), q))
    return ([(0, p)] if p.exists() else []) + sorted(numbered)
