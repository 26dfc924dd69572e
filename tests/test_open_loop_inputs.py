"""INPUTS.csv as a person saves it from a spreadsheet, and the mistakes they make in it: `dpgw sim --vessel
NAME --inputs INPUTS.csv` reads what is meant and says, in one line naming the file, the line and the
column, what is wrong and what to do."""

from __future__ import annotations

import shlex
from pathlib import Path

import numpy as np
import pytest

from dpgw.cli import main
from observers.vessel import load_vessel
from simulator.open_loop import InputsError, read_inputs

REPO = Path(__file__).resolve().parents[1]
STEPS = REPO / "tests" / "data" / "mss-osv" / "steps_inputs.csv"
OSV = load_vessel("mss_osv")  # thrusters 1, 2 tunnels (140 rpm); 3, 4 azimuths (150, 200 rpm)


def _lines(n: int = 40) -> list[str]:
    return STEPS.read_text(encoding="utf-8").splitlines()[:n]


def _write(tmp_path: Path, lines: list[str], data: bytes = b"", name: str = "inputs.csv") -> Path:
    f = tmp_path / name
    f.write_bytes(data + ("\n".join(lines)).encode("utf-8"))
    return f


def _refusal(f: Path) -> str:
    with pytest.raises(InputsError) as err:
        read_inputs(f, OSV)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{f}: "), msg
    return msg


def test_excel_utf8_bom_and_blank_lines_read_as_the_plain_file(tmp_path: Path) -> None:
    """Excel's "CSV UTF-8" starts with a byte-order mark (before: column '\\ufefft' unknown, 't' missing);
    a trailing empty line and a row of empty cells are not rows (before: "line 41: 1 fields")."""
    lines = _lines()
    plain = read_inputs(_write(tmp_path, lines, name="plain.csv"), OSV)
    saved = [*lines[:20], "", ",,,,,,,,", *lines[20:], "", ""]
    excel = read_inputs(_write(tmp_path, saved, b"\xef\xbb\xbf", name="excel.csv"), OSV)
    assert len(excel.t) == len(plain.t) == len(lines) - 1
    for a, b in ((excel.t, plain.t), (excel.rpm, plain.rpm), (excel.alpha_deg, plain.alpha_deg)):
        np.testing.assert_array_equal(a, b)
    # the lines a problem names are still the file's own, counted across the skipped ones
    broken = [*saved[:30], "x" + saved[30][saved[30].index(",") :], *saved[31:]]
    assert "line 31, column 't': not a number: 'x'" in _refusal(_write(tmp_path, broken, b"\xef\xbb\xbf"))


def test_a_semicolon_separated_file_is_said_to_be_one(tmp_path: Path) -> None:
    """Before: "missing columns t, current_speed, …" — every column, though every one was there."""
    f = _write(tmp_path, [line.replace(",", ";") for line in _lines()])
    msg = _refusal(f)
    assert "line 1: the separator is ',' but the file seems to use ';': save it as CSV with commas" in msg, (
        msg
    )


def test_a_column_in_the_wrong_case_gets_did_you_mean(tmp_path: Path) -> None:
    lines = _lines()
    f = _write(tmp_path, [lines[0].replace("n_1", "N_1"), *lines[1:]])
    assert "line 1, column 'N_1': unknown, did you mean 'n_1'?" in _refusal(f)


def test_an_angle_for_a_tunnel_thruster_says_it_has_none(tmp_path: Path) -> None:
    lines = _lines()
    f = _write(tmp_path, [lines[0] + ",alpha_1", *(line + ",90" for line in lines[1:])])
    msg = _refusal(f)
    assert "column 'alpha_1': thruster 1 is a tunnel (a fixed direction, 90°: no angle to record)" in msg, msg
    f = _write(tmp_path, [lines[0] + ",n_5", *(line + ",0" for line in lines[1:])])
    assert "column 'n_5': no thruster 5: mss_osv has 4, numbered 1 to 4" in _refusal(f)


def test_rpm_beyond_the_thrusters_max_is_warned_once_per_thruster_and_run_unclipped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1000 rpm on the 150 rpm azimuth 3 (rad/s or rps taken for rpm would look like this): a warning on
    stderr naming the column and the max, once however many rows; the run goes on with what was
    recorded."""
    lines = _lines()
    col = lines[0].split(",").index("n_3")

    def with_rpm(line: str, rpm: str) -> str:
        cells = line.split(",")
        cells[col] = rpm
        return ",".join(cells)

    rows = [lines[0], *lines[1:10], *(with_rpm(line, "1000") for line in lines[10:20]), *lines[20:]]
    rows[25] = with_rpm(rows[25], "-400")
    f = _write(tmp_path, rows)
    assert float(np.max(np.abs(read_inputs(f, OSV).rpm[:, col - 3]))) == 1000.0  # as recorded
    out = tmp_path / "states.csv"
    assert main(["sim", "--vessel", "mss_osv", "--inputs", str(f), "--csv", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"dpgw sim: warning: {f}: column 'n_3': |n| up to 1000 rpm (first at t = 9 s)")
    assert "beyond thruster 3's max_rpm 150: a unit mistake (rps, rad/s, %)?" in err[0], err[0]
    assert len(out.read_text().splitlines()) == len(rows)


def test_a_vessel_without_hull_gives_the_flags_to_copy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The error names exactly the plant options still on, as flags; run with them copied, it works."""
    f = _write(tmp_path, ["t,current_speed,current_dir_deg", "0,0.5,90", "10,0.5,90", "20,0.5,90"])
    argv = ["sim", "--vessel", "northern_clipper", "--inputs", str(f), "--csv", str(tmp_path / "s.csv")]
    assert main([*argv, "--plant-option", "crossflow=off"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "vessel 'northern_clipper' (northern_clipper) has no [hull] table" in err, err
    flags = err.split(" with ", 1)[1]
    assert flags == "--plant-option coriolis=off --plant-option surge_resistance=off", err
    assert main([*argv, "--plant-option", "crossflow=off", *shlex.split(flags)]) == 0
    assert main(argv) == 2
    flags = capsys.readouterr().err.strip().split(" with ", 1)[1]
    assert (
        flags
        == "--plant-option coriolis=off --plant-option surge_resistance=off --plant-option crossflow=off"
    )
    assert main([*argv, *shlex.split(flags)]) == 0


def test_an_open_loop_run_stopped_at_a_row_returns_the_whole_runs_rows_up_to_it() -> None:
    """``go_on`` (a progress bar, a stop): the rows before the stop are exactly the whole run's."""
    from simulator.open_loop import run_open_loop

    inputs = read_inputs(STEPS, OSV)
    whole = run_open_loop(OSV, inputs)
    asked: list[int] = []

    def go_on(i: int) -> bool:
        asked.append(i)
        return i < 25

    part = run_open_loop(OSV, inputs, go_on=go_on)
    assert asked == list(range(26)) and part.shape == (26, whole.shape[1])
    np.testing.assert_array_equal(part, whole[:26])


def test_ctrl_c_stops_an_open_loop_run_with_what_ran_written(tmp_path: Path) -> None:
    """A long open-loop run (days of recorded inputs) stopped with Ctrl-C: the states up to the row reached
    are written (the CSV and a complete log), said on stderr and in the summary, exit status 130. Before:
    a KeyboardInterrupt traceback, nothing written, or a log cut short. Waits for the progress bar (stderr
    on a terminal) to show the run under way, then interrupts it."""
    import fcntl
    import os
    import pty
    import re
    import signal
    import struct
    import subprocess
    import sys
    import termios

    from conftest import wait_for

    from wire.mcap.reader import read_messages, summary

    head, *rows = STEPS.read_text(encoding="utf-8").splitlines()
    step = float(rows[1].split(",")[0]) - float(rows[0].split(",")[0])
    body = [",".join([f"{k * step:g}", *r.split(",")[1:]]) for k, r in enumerate(rows * 300)]
    inputs = _write(tmp_path, [head, *body])  # 180,000 rows: ~30 s to run, stopped long before
    csv, log = tmp_path / "states.csv", tmp_path / "states.mcap"
    argv = ["sim", "--vessel", "mss_osv", "--inputs", str(inputs), "--csv", str(csv), "--out", str(log)]
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # (a new pty is 0 wide)
    proc = subprocess.Popen(
        [sys.executable, "-m", "dpgw", *argv],
        cwd=REPO, stdout=subprocess.PIPE, stderr=slave, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    os.close(slave)
    seen = bytearray()

    def under_way() -> bool:
        try:
            seen.extend(os.read(master, 65536))
        except OSError:  # (EIO: the process ended, every end of the terminal closed)
            pytest.fail(f"the run ended before it was stopped: {proc.wait()} {seen.decode(errors='replace')}")
        return re.search(rb"\d+/\d+ \[", seen) is not None and b" 0/" not in seen[-200:]

    try:
        assert wait_for(under_way, 120.0), seen.decode(errors="replace")
        proc.send_signal(signal.SIGINT)
        stdout, _ = proc.communicate(timeout=60)
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                break
            if not chunk:
                break
            seen.extend(chunk)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    err = seen.decode(errors="replace")
    assert proc.returncode == 130, (stdout, err)
    assert "Traceback" not in err, err
    said = re.search(r"dpgw sim: stopped by Ctrl-C at row (\d+) of (\d+) \(", err)
    assert said is not None and int(said[2]) == len(body), err
    ran = int(said[1])
    assert 0 < ran < len(body)
    assert stdout.startswith(f"mss_osv: {ran} of {len(body)} input rows, "), stdout
    assert len(csv.read_text().splitlines()) == ran + 1
    assert summary(log).complete
    assert sum(1 for _ in read_messages(log, "/truth/state")) == ran


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--vessel", "mss_osv"], "(open loop from recorded inputs): --vessel goes with --inputs"),
        ([], "(open loop from recorded inputs)"),
        (["--scenario", "hassani", "--inputs", "x.csv"], "INPUTS.csv, not both"),
    ],
)
def test_sim_says_what_is_missing_as_what_was_given(
    argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """`dpgw sim --vessel mss_osv --csv o.csv` (--inputs forgotten) was told "... (not both)": it gave
    neither. Now as what was given."""
    from dpgw.cli import main

    assert main(["sim", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(
        "dpgw sim: give --scenario NAME, or --vessel NAME --inputs INPUTS.csv"
    ) and err.endswith(said), err
