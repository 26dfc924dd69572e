"""How every ``dpgw`` help page is laid out.

Descriptions are written as one long paragraph and must wrap to the terminal; epilogs hold examples laid
out by hand (aligned comments, continuation lines) and must not. argparse offers one or the other per
parser, so this formatter wraps a line only when it is wider than the terminal, keeping its indentation:
a hand-made example line fits and stays as written, a paragraph is refilled.
"""

from __future__ import annotations

import argparse
import textwrap


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    def _fill_text(self, text: str, width: int, indent: str) -> str:
        out = []
        for line in text.splitlines():
            if len(indent) + len(line) <= width:
                out.append(indent + line)
                continue
            lead = indent + line[: len(line) - len(line.lstrip())]
            out.append(textwrap.fill(line.strip(), width, initial_indent=lead, subsequent_indent=lead))
        return "\n".join(out)
