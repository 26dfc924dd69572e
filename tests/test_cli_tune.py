"""`dpgw tune`: text, --json (keys other programs read), exit codes, errors that say what to do."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

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


def test_tune_shows_the_gains_the_gateway_runs(capsys, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A gateway config holds the observer's velocity injection at no slower than its DP loop; `dpgw tune`
    does the same by default, so the gains it shows are the ones `dpgw run` uses (the 1:70 CyberShip II in
    a 6.8 s sea: a rises from 0.12 ω0 to the loop's floor), and ``--loop-bandwidth none`` shows the
    observer on its own."""
    import numpy as np

    from gateway.config import parse_config
    from observers.passive_tuning import passive_gains

    tables = {
        "vessel": {"name": "cybership2"},
        "datum": {"lat_deg": 59.4, "lon_deg": 10.5},
        "sources": [
            {"name": "gps", "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": ["position", "heading"]}
        ],
        "observer": {"wave_period_s": 6.8},
        "log": {"path": ""},
    }  # fmt: skip
    config = parse_config(tables, base_dir=tmp_path)
    gateway_k4 = passive_gains(config.vessel, config.observer.tuning).K4
    assert main(["tune", "--vessel", "cybership2", "--wave-period", "6.8", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(shown["K4"], gateway_k4, rtol=1e-12)
    assert min(shown["velocity_injection_per_s"]) > 0.3  # the loop's floor, not 0.12 ω0 = 0.11
    assert (
        main(["tune", "--vessel", "cybership2", "--wave-period", "6.8", "--loop-bandwidth", "none", "--json"])
        == 0
    )
    alone = json.loads(capsys.readouterr().out)
    assert alone["loop_bandwidth"] is None
    np.testing.assert_allclose(alone["velocity_injection_per_s"], 0.12 * 2 * np.pi / 6.8, rtol=1e-9)
    with pytest.raises(SystemExit) as refused:  # (argparse: the usage and the message, exit status 2)
        main(["tune", "--vessel", "cybership2", "--wave-period", "6.8", "--loop-bandwidth", "fast"])
    assert refused.value.code == 2 and "--loop-bandwidth" in capsys.readouterr().err


@pytest.mark.parametrize("period", ["1e9", "1e-6"])
def test_a_wave_period_no_sea_has_is_tuned_and_checked_with_a_note(capsys, period: str) -> None:  # type: ignore[no-untyped-def]
    """Before: 1e9 s stopped on a traceback (the SPR check's frequency band was empty below 1e-6 rad/s).
    Its checks are made on a frequency grid that reaches a decade beyond the tuning's corners."""
    code = main(["tune", "--vessel", "mss_supply", "--wave-period", period, "--json"])
    r = json.loads(capsys.readouterr().out)
    assert code in (0, 1)
    spr = next(c for c in r["checks"] if c["name"] == "spr")
    assert "margin" in spr["detail"]
    assert len(r["notes"]) == 1 and r["notes"][0].startswith(
        f"a wave period of {float(period):g} s is no sea's (2-25 s at full scale): check that it is the "
        "period in seconds, not ω0 in rad/s"
    ), r["notes"]


def test_the_note_on_a_wave_period_knows_the_vessels_scale(capsys) -> None:  # type: ignore[no-untyped-def]
    """ω0 given as the period, a full-scale period given for a 1:70 model: each said, with what it likely
    meant; a sea's period at the vessel's scale: no note."""

    def notes(vessel: str, period: str) -> list[str]:
        main(["tune", "--vessel", vessel, "--wave-period", period, "--json"])
        return json.loads(capsys.readouterr().out)["notes"]

    assert notes("mss_supply", "9") == [] and notes("cybership2", "0.84") == []
    assert notes("mss_supply", "0.9") == [
        "a wave period of 0.9 s is no sea's (2-25 s at full scale): check that it is the period in seconds, "
        "not ω0 in rad/s (ω0 = 2π/T: 6.98 rad/s here)"
    ]
    assert notes("cybership2", "8") == [
        "a wave period of 8 s is no sea's (0.24-3 s for this 1:70 model, Froude-scaled): a full-scale "
        "period? At 1:70 it is 0.956 s"
    ]
    assert main(["tune", "--vessel", "cybership2", "--wave-period", "8"]) in (0, 1)
    assert "note: a wave period of 8 s is no sea's" in capsys.readouterr().out


def _tune(capsys, *extra: str) -> tuple[int, dict]:  # type: ignore[no-untyped-def,type-arg]
    code = main(["tune", "--vessel", "mss_supply", "--wave-period", "9", *extra, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_an_unstable_tuning_is_called_unstable_and_fails(capsys) -> None:  # type: ignore[no-untyped-def]
    """Before: a growing error mode (λ/κ = 0.5·ω0) was printed as the slowest one with a negative time
    constant and the advice to raise the velocity injection."""
    code, r = _tune(capsys, "--bias-corner-ratio", "0.5")
    assert code == 1
    stable = next(c for c in r["checks"] if c["name"] == "stability")
    assert not stable["ok"] and "grows" in stable["detail"] and "diverges" in stable["detail"]
    assert stable["values"]["max_real_part_per_s"][0] == pytest.approx(r["slowest_rate_any_heading"])
    assert r["slowest_rate_any_heading"] > 0
    assert not any("velocity injection" in n for n in r["notes"])
    main(["tune", "--vessel", "mss_supply", "--wave-period", "9", "--bias-corner-ratio", "0.5"])
    out = capsys.readouterr().out
    assert "UNSTABLE" in out and "FAIL  stability" in out and "time constant -" not in out
    code, r = _tune(capsys)
    assert code == 0 and next(c for c in r["checks"] if c["name"] == "stability")["ok"]
    assert r["notes"] == []  # the default tuning: nothing to advise


def test_advice_on_a_slow_mode_is_the_direction_that_helps(capsys) -> None:  # type: ignore[no-untyped-def]
    """The slowest mode is not monotonic in the velocity injection a: at a = 1 1/s it is 139 s and a
    higher a makes it slower still. The advice names an a that was tried, and it does what it says."""
    _, r = _tune(capsys, "--loop-bandwidth", "none", "--velocity-injection", "1")
    assert -1 / r["slowest_rate_any_heading"] > 100
    (note,) = [n for n in r["notes"] if n.startswith("slowest error mode")]
    assert "lower velocity injection" in note
    advised = note.split("--velocity-injection ")[1].split(",")[0]
    _, again = _tune(capsys, "--loop-bandwidth", "none", "--velocity-injection", advised)
    assert -1 / again["slowest_rate_any_heading"] < 100
    assert float(note.split("gives ")[1].split(" s")[0]) == pytest.approx(
        -1 / again["slowest_rate_any_heading"], abs=1
    )


@pytest.mark.parametrize("a", ["20", "5"])
def test_a_tuning_that_does_not_filter_the_waves_says_so(capsys, a: str) -> None:  # type: ignore[no-untyped-def]
    """Before: a velocity injection far above ω0 passed with no word while the LF estimate kept (a = 5:
    -2.7 dB) or amplified (a = 20: +2 dB) the wave motion."""
    _, r = _tune(capsys, "--loop-bandwidth", "none", "--velocity-injection", a)
    assert max(r["notch_db"]) > -10
    (note,) = [n for n in r["notes"] if n.startswith("weak wave filtering")]
    assert ("amplifies" if max(r["notch_db"]) > 0 else "keeps") in note and "fills the notch" in note
    # the a it names filters, as it says (found by trying it)
    advised = note.split("--velocity-injection ")[1].split(" ")[0]
    said = float(note.split(f"--velocity-injection {advised} gives ")[1].split(" dB")[0])
    _, again = _tune(capsys, "--loop-bandwidth", "none", "--velocity-injection", advised)
    assert max(again["notch_db"]) <= -10 and max(again["notch_db"]) == pytest.approx(said, abs=0.05)
    _, r = _tune(capsys, "--loop-bandwidth", "none", "--velocity-injection", a)
    main(
        [
            "tune",
            "--vessel",
            "mss_supply",
            "--wave-period",
            "9",
            "--loop-bandwidth",
            "none",
            "--velocity-injection",
            a,
        ]
    )
    assert f"note: {note}" in capsys.readouterr().out  # the text says what the JSON says


def test_json_says_the_settings_the_gains_came_from(capsys) -> None:  # type: ignore[no-untyped-def]
    """`--json` had the gains but not ζ, ζn, the cutoff ratio, ...: a program could not tell them apart."""
    _, r = _tune(capsys, "--zeta", "0.08", "--zeta-n", "0.9", "--bias-corner-ratio", "0.03")
    s = r["settings"]
    assert s["zeta"] == [0.08] * 3 and s["zeta_n"] == [0.9] * 3 and s["bias_corner_ratio"] == 0.03
    assert s["cutoff_ratio"] == pytest.approx(
        [w / w0 for w, w0 in zip(r["omega_c"], r["omega0"], strict=True)]
    )


def test_an_inverted_notch_is_blamed_on_its_dampings_not_the_velocity_injection(capsys) -> None:  # type: ignore[no-untyped-def]
    """ζn = 0.05 below ζ = 0.1 (rule (48) fails): the note blamed a = 0.084 1/s, 12 % of ω0, as "close to
    or above ω0", and said the same of a = 0.01; it names ζn and ζ now."""
    for extra in ([], ["--velocity-injection", "0.01"]):
        _, r = _tune(capsys, "--zeta-n", "0.05", *extra)
        (note,) = [n for n in r["notes"] if n.startswith("weak wave filtering")]
        assert "ζn must be above ζ" in note and "raise --zeta-n" in note, note
        assert "velocity injection" not in note


def test_the_spr_margin_is_the_one_near_the_notch_not_the_asymptotes(capsys) -> None:  # type: ignore[no-untyped-def]
    """Before: with the default random-walk bias the phase tends to -90° as ω → 0, and the margin read
    0.00° for every tuning. It is taken from λ/κ to 10·ωc: the default's 0.4° just below ω0 (rule (48)
    does not imply SPR; the default λ/κ = 0.04·ω0 is just inside the edge at ~0.045·ω0)."""
    _, r = _tune(capsys)
    spr = next(c for c in r["checks"] if c["name"] == "spr")
    w0 = r["omega0"][0]
    assert 0.1 < spr["values"]["margin_deg"][0] < 2.0
    assert 0.6 * w0 < spr["values"]["margin_at_rad_s"][0] < w0
    _, lower = _tune(capsys, "--bias-corner-ratio", "0.02")
    margin = next(c for c in lower["checks"] if c["name"] == "spr")["values"]["margin_deg"][0]
    assert margin > spr["values"]["margin_deg"][0] + 1.0  # a lower bias corner: further from the edge
