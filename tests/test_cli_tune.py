"""`dpgw tune`: text, --json (keys other programs read), exit codes, errors that say what to do."""

from __future__ import annotations

import json
import subprocess
import sys

from dpgw.cli import main


def test_tune_text(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["tune", "--vessel", "mss_supply", "--wave-period", "9"]) == 0
    out = capsys.readouterr().out
    for word in ("K1", "K2", "K3", "K4", "eigenvalues", "PASS  tuning_rule", "PASS  spr", "notch depth"):
        assert word in out


def test_tune_json_in_a_subprocess() -> None:
    """The console script as a user runs it; --json is one object with the documented keys."""
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "dpgw",
            "tune",
            "--vessel",
            "northern_clipper",
            "--wave-period",
            "7",
            "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    r = json.loads(p.stdout)
    assert {"K1", "K2", "K3", "K4", "T", "eigenvalues", "checks", "notch_db"} <= set(r)
    assert len(r["K1"]) == 6 and len(r["K1"][0]) == 3
    assert round(r["K1"][0][0], 4) == -2.2059
    assert all(c["ok"] for c in r["checks"])
    assert all(d <= -20 for d in r["notch_db"])
    assert max(e[0] for e in r["eigenvalues"]) < -0.01


def test_tune_failing_check_exits_1(capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(["tune", "--vessel", "mss_supply", "--wave-period", "7", "--bias-corner-ratio", "0.2"])
    assert code == 1
    assert "FAIL  spr" in capsys.readouterr().out


def test_tune_bad_vessel_says_what_to_do(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["tune", "--vessel", "titanic", "--wave-period", "9"]) == 2
    err = capsys.readouterr().err
    assert "titanic" in err and "mss_supply" in err
