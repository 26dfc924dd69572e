"""docs/interfaces.md ("Command summaries") names every key `dpgw run`, `dpgw demo` and `dpgw sim` print
with ``--json``: a program reading them learns what each means there, not by reading the source. The
run's and the demo's keys are read from their code (every key written into the summary); the
simulator's from a real run's output, with its optional keys (``log``, ``tlog``) made to appear."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "interfaces.md"


def documented() -> dict[str, set[str]]:
    """{command: keys} from the table of the "Command summaries (`--json`)" section."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("## Command summaries (`--json`)", 1)[1].split("\n## ", 1)[0]
    keys: dict[str, set[str]] = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].startswith("`dpgw "):
            keys.setdefault(cells[0].strip("`"), set()).update(re.findall(r"`(\w+)`", cells[1]))
    return keys


def keys_written(module: Path, names: tuple[str, ...]) -> set[str]:
    """The string keys a module writes into the dicts named ``names``: their literals' keys and every
    ``name["key"] = ...``."""
    keys: set[str] = set()
    for node in ast.walk(ast.parse(module.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Name) and t.id in names and isinstance(node.value, ast.Dict):
                    keys |= {k.value for k in node.value.keys if isinstance(k, ast.Constant)}
                if (
                    isinstance(t, ast.Subscript)
                    and isinstance(t.value, ast.Name)
                    and t.value.id in names
                    and isinstance(t.slice, ast.Constant)
                ):
                    keys.add(t.slice.value)
    return keys


@pytest.mark.parametrize(
    ("command", "module", "names"),
    [("dpgw run", "dpgw/cli_run.py", ("summary",)), ("dpgw demo", "dpgw/cli_demo.py", ("summary", "result"))],
)
def test_the_run_and_the_demo_summary_keys_are_documented(
    command: str, module: str, names: tuple[str, ...]
) -> None:
    keys = keys_written(ROOT / module, names)
    assert "stopped_by" in keys  # (the check reads the code it means to)
    missing = keys - documented().get(command, set())
    assert not missing, f"{command} --json keys not in docs/interfaces.md: {sorted(missing)}"


def test_the_simulator_summary_keys_are_documented(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dpgw.cli import main

    argv = ["sim", "--scenario", "hassani", "--duration", "1", "--json"]
    assert main([*argv, "--out", str(tmp_path / "s.mcap"), "--tlog", str(tmp_path / "s.tlog")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert {"not_sent", "log", "tlog"} <= set(summary)
    missing = set(summary) - documented().get("dpgw sim", set())
    assert not missing, f"dpgw sim --json keys not in docs/interfaces.md: {sorted(missing)}"
