"""The documentation's references hold: every relative Markdown link in README.md, docs/*.md and
examples/README.md points to a file that exists (and, with `#anchor`, to a heading of that file), and
every repository path a doc names in backticks (`docs/x.md`, `gateway/service.py`, `examples/…`) exists.

A renamed or deleted file otherwise leaves the docs pointing at nothing, silently."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", ROOT / "examples" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")
# A path in backticks that starts at one of the repository's top-level folders.
TOP = ("docs", "examples", "gateway", "wire", "observers", "simulator", "dpgw", "bench", "tests", "tools")
_TOP = "|".join(TOP)
CODE_PATH = re.compile(rf"`((?:{_TOP})/[\w./-]+\.(?:py|md|toml|json|xml|service))`")
# Files of other projects that the docs cite by their own paths (rmw_zenoh's, Keelson's).
OTHER_PROJECTS = {("ros2.md", "docs/design.md"), ("keelson.md", "docs/protocol-specification.md")}


def _anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    lines = path.read_text(encoding="utf-8").splitlines()
    return {_anchor(line.lstrip("#")) for line in lines if line.startswith("#")}


def _ids(p: Path) -> str:
    return str(p.relative_to(ROOT))


@pytest.mark.parametrize("doc", DOCS, ids=_ids)
def test_relative_links_resolve(doc: Path) -> None:
    broken = []
    for target in LINK.findall(doc.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        file = (doc.parent / path).resolve() if path else doc
        if not file.exists():
            broken.append(f"{target}: no such file")
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
            broken.append(f"{target}: no heading #{anchor} in {file.name}")
    assert not broken, broken


@pytest.mark.parametrize("doc", DOCS, ids=_ids)
def test_named_repository_paths_exist(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    missing = sorted(
        {
            p
            for p in CODE_PATH.findall(text)
            if not (ROOT / p).exists() and (doc.name, p) not in OTHER_PROJECTS
        }
    )
    assert not missing, missing


def test_the_checks_find_what_they_look_for(tmp_path: Path) -> None:
    """The patterns catch a broken link, a missing heading and a missing path (a test that cannot fail
    is no test)."""
    assert LINK.findall("see [config](config.md#the-file) and [x](https://e.org)") == [
        "config.md#the-file",
        "https://e.org",
    ]
    assert "the-file" in _anchors(ROOT / "docs" / "config.md")
    assert "no-such-heading" not in _anchors(ROOT / "docs" / "config.md")
    assert CODE_PATH.findall("in `gateway/nothing_here.py` and `docs/config.md`") == [
        "gateway/nothing_here.py",
        "docs/config.md",
    ]


def test_readme_lists_every_doc() -> None:
    """README's "Documentation" section links every file of docs/: a new doc is not left unfound."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## Documentation", 1)[1]
    linked = set(re.findall(r"\]\(docs/([\w.-]+\.md)\)", section))
    assert {p.name for p in (ROOT / "docs").glob("*.md")} <= linked


def test_simulator_doc_has_a_row_per_scenario() -> None:
    """docs/simulator.md's table of scenarios has a row for every scenario `dpgw sim --scenario` takes."""
    from dpgw.scenario_names import SCENARIO_NAMES

    text = (ROOT / "docs" / "simulator.md").read_text(encoding="utf-8")
    table = text.split("## Scenarios", 1)[1].split("\n## ", 1)[0]
    rows = set(re.findall(r"^\| `(\w+)` \|", table, re.M))
    assert set(SCENARIO_NAMES) == rows
