"""Write the generated tables of docs/interfaces.md from the message classes (`wire.messages`).

The doc is hand-written prose around generated blocks. A block starts with a marker line naming what it
holds and ends with the end marker; everything between them is replaced:

    <!-- generated: dpgw.Estimate -->     the field table of the message with that schema name
    <!-- generated: topics -->            every MCAP topic, its schema name and Zenoh key
    <!-- end generated -->

    python tools/gen_interfaces.py           # rewrite the blocks in docs/interfaces.md
    python tools/gen_interfaces.py --check   # exit 1 (and say which blocks) if the doc is out of date

tests/test_messages.py runs the check, so a change to a message that is not carried into the doc fails.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from wire.message_schema import markdown_table, topics_table
from wire.messages import ANY, MESSAGES

DOC = Path(__file__).resolve().parents[1] / "docs" / "interfaces.md"
BLOCK = re.compile(r"(<!-- generated: (?P<name>[^ ]+) -->\n)(?P<body>.*?)(<!-- end generated -->)", re.DOTALL)


class DocError(ValueError):
    """A marker names nothing the messages define."""


def block(name: str) -> str:
    """The generated Markdown of block `name`."""
    if name == "topics":
        return topics_table()
    for cls in (*MESSAGES, ANY):
        if name == cls.TITLE:
            return markdown_table(cls)
    known = ", ".join(["topics", *(c.TITLE or "" for c in MESSAGES)])
    raise DocError(f"{DOC.name}: generated block '{name}' names no message (known: {known})")


def render(text: str) -> str:
    """`text` with every generated block rewritten."""
    return BLOCK.sub(lambda m: m.group(1) + block(m.group("name")) + m.group(4), text)


def stale_blocks(text: str) -> list[str]:
    """Names of the blocks whose committed content differs from what the messages give."""
    return [m.group("name") for m in BLOCK.finditer(text) if m.group("body") != block(m.group("name"))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="only check; exit 1 if the doc is out of date")
    ap.add_argument("--doc", type=Path, default=DOC, help=f"the document (default {DOC})")
    args = ap.parse_args(argv)
    text = args.doc.read_text(encoding="utf-8")
    try:
        stale = stale_blocks(text)
    except DocError as exc:
        print(f"gen_interfaces: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if stale:
            print(
                f"gen_interfaces: {args.doc} is out of date in: {', '.join(stale)} "
                "(run python tools/gen_interfaces.py)",
                file=sys.stderr,
            )
            return 1
        return 0
    args.doc.write_text(render(text), encoding="utf-8")
    print(
        f"gen_interfaces: {args.doc}: {len(stale)} block(s) rewritten"
        + (f" ({', '.join(stale)})" if stale else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
