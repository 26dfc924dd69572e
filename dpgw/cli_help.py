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
        out = []
        for line in text.splitlines():
            if len(indent) + len(line) <= width:
                out.append(indent + line)
                continue
            lead = indent + line[: len(line) - len(line.lstrip())]
            if lead != indent and line.lstrip().startswith(("dpgw ", "--")):
                commented = _COMMENTED.match(line)
                if commented:
                    comment = commented["comment"]
                    out.append(
                        textwrap.fill(comment, width, initial_indent=lead, subsequent_indent=lead + "# ")
                    )
                    line = commented["command"]
                out.append(indent + line)
                continue
            out.append(textwrap.fill(line.strip(), width, initial_indent=lead, subsequent_indent=lead))
        return "\n".join(out)
