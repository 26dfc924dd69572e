"""How every ``dpgw`` help page is laid out.

Descriptions are written as one long paragraph and must wrap to the terminal; epilogs hold examples laid
out by hand (aligned comments, continuation lines) and must not. argparse offers one or the other per
parser, so this formatter wraps a line only when it is wider than the terminal, keeping its indentation:
a hand-made example line fits and stays as written, a paragraph is refilled.

An example command (an indented line starting with ``dpgw`` or a continuation ``--option``) is never
broken: a new user copies it, and half a command on the next line looks like a command of its own. When
it does not fit, its trailing ``# comment`` moves to a line of its own above it; a command still too wide
is left to the terminal, which wraps it without breaking the copy.
"""

from __future__ import annotations

import argparse
import re
import textwrap

_COMMENTED = re.compile(r"^(?P<command>.*?\S)\s{2,}(?P<comment># .*)$")


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    def _fill_text(self, text: str, width: int, indent: str) -> str:
        out: list[str] = []
        start = 0  # where in ``out`` the command the line belongs to begins (its comment goes above it)
        for line in text.splitlines():
            if not (out and out[-1].endswith("\\")):  # (a continuation line belongs to the command above)
                start = len(out)
            if len(indent) + len(line) <= width:
                out.append(indent + line)
                continue
            lead = indent + line[: len(line) - len(line.lstrip())]
            if lead != indent and line.lstrip().startswith(("dpgw ", "--")):
                commented = _COMMENTED.match(line)
                if commented:
                    # above the command's first line: between a line ending in "\\" and the next, the
                    # comment ended the command there (pasted, the rest ran as a command of its own)
                    first = out[start] if start < len(out) else indent + line
                    lead = first[: len(first) - len(first.lstrip())]
                    comment = commented["comment"]
                    out.insert(
                        start,
                        textwrap.fill(comment, width, initial_indent=lead, subsequent_indent=lead + "# "),
                    )
                    line = commented["command"]
                out.append(indent + line)
                continue
            out.append(textwrap.fill(line.strip(), width, initial_indent=lead, subsequent_indent=lead))
        return "\n".join(out)
