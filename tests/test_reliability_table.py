"""bench/reliability_table.py: the table's machinery on short runs — a fault reaches the gateway through the
closed loop, the detection column reads alarms and source states, the doc's table is replaced in place."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

from reliability_table import Case, cases, detection, run_case, write_doc

REPO = Path(__file__).resolve().parent.parent


def by_name(word: str) -> Case:
    return next(c for c in cases() if word in c.name)


def test_a_silent_dgps_is_detected_by_its_staleness_alarm() -> None:
    row = run_case(by_name("the only DGPS"), settle_s=60.0, after_s=5.0, seed=1)
    assert row["detected_s"] == pytest.approx(2.0, abs=0.3)  # the source's 2 s timeout
    assert "dgps1" in row["alarm"] and "stale" in row["alarm"]
    assert row["max_position_error_m"] < 5.0


def test_a_far_fix_reaches_the_gateway_and_is_scored() -> None:
    """One GGA at 91° E through the closed loop: the row shows what the gateway did with it (on a gateway
    that believes it, hundreds of kilometres; once rejected, the baseline's error)."""
    row = run_case(by_name("91°"), settle_s=60.0, after_s=5.0, seed=1)
    baseline = run_case(by_name("baseline"), settle_s=60.0, after_s=5.0, seed=1)
    assert baseline["detected_s"] is None and baseline["max_position_error_m"] < 1.0
    assert row["max_position_error_m"] > 1e5 or row["detected_s"] is not None
    assert 0.0 < baseline["max_thrust_pct"] <= 100.0


def status(t_ns: int, alarms: list[str], **states: Any) -> dict[str, Any]:
    return {
        "stamp_ns": t_ns,
        "alarms": alarms,
        "sources": {name: {"received": 1, "rejected": rej, **st} for name, (st, rej) in states.items()},
    }


def test_detection_reads_new_alarms_and_source_state_changes_naming_the_source() -> None:
    def sim_t(ns: int) -> float:
        return ns / 1e9

    old = "thrust allocation saturated: demand τ = [1 N, 0 N, 0 N·m] not achievable"
    statuses = [
        status(9_900_000_000, [old], dgps1=({"state": "ok"}, {}), gyro1=({"state": "ok"}, {})),
        status(10_000_000_000, [old, "source gyro1: something"], dgps1=({"state": "ok"}, {"jump": 1})),
        status(10_300_000_000, [old], dgps1=({"state": "rejected", "reason": "jump 50 m"}, {"jump": 3})),
    ]
    assert detection(statuses, sim_t, 10.0, ("dgps1",)) == (
        pytest.approx(0.3),
        "dgps1: rejected (jump 50 m)",
        3,
    )
    # an alarm that names the source counts as well, the first one wins
    assert detection(statuses, sim_t, 10.0, ("gyro1",))[:2] == (0.0, "source gyro1: something")
    # alarms present before the fault and alarms about other things are not a detection
    assert detection(statuses, sim_t, 10.0, ("setpoint",))[0] is None


def test_the_doc_table_is_replaced_between_its_markers(tmp_path: Path) -> None:
    doc = tmp_path / "r.md"
    doc.write_text("# R\n\nprose\n<!-- reliability-table -->\nold\n<!-- /reliability-table -->\nmore prose\n")
    write_doc(doc, "| new |")
    assert (
        doc.read_text()
        == "# R\n\nprose\n<!-- reliability-table -->\n| new |\n<!-- /reliability-table -->\nmore prose\n"
    )
    shipped = (REPO / "docs" / "reliability.md").read_text()
    assert "python bench/reliability_table.py" in shipped and "| baseline (no fault) |" in shipped
