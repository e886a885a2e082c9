"""Captures as test stations write them (docs/reference/csv.md): time columns in ms/µs/ns (from
the name or the spacing), a metadata preamble before the header, decimal commas, and a last line
cut short by a logger stopped mid-write. Each on a file of that shape, through the reader, the
command line and the Python API."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import POSES_3, PRECIOUS, SAMPLE, assert_untouched, run, tumblecal_exe, write
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv.readings import read_log, read_samples
from tumblecal_cli.io.readspec import Dialect, ReadSpec

DATA = Path(__file__).resolve().parent / "data"
NCSU = DATA / "ncsu_xplus_head.csv"


def still_log(unit_step: float, header: str = "t,ax,ay,az", n: int = 200) -> str:
    """A still +z log: ``n`` rows, the time column advancing ``unit_step`` a row."""
    rng = np.random.default_rng(3)
    rows = [f"{i * unit_step:g},{rng.normal(0, 1e-3):.6f},{rng.normal(0, 1e-3):.6f},1.0\n" for i in range(n)]
    return header + "\n" + "".join(rows)


# -- time columns in ms, µs, ns ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "step", "scale"),
    [("timestamp_ms", 10, 1e-3), ("t_us", 10_000, 1e-6), ("time_ns", 1e7, 1e-9), ("time (ms)", 10, 1e-3)],
)
def test_the_unit_in_a_time_column_name_is_used_without_a_note(
    tmp_path: Path, name: str, step: float, scale: float
) -> None:
    log = read_log(str(write(tmp_path / "log.csv", still_log(step, f"{name},ax,ay,az"))))
    assert log.layout.names[log.layout.time or 0] == name
    assert log.scale == scale
    assert log.layout.notes == []
    seconds = log.seconds()
    assert seconds is not None
    assert seconds[-1] == pytest.approx(199 * 0.01)


@pytest.mark.parametrize(("step", "unit"), [(0.01, "s"), (10, "ms"), (10_000, "us"), (1e7, "ns")])
def test_an_unnamed_unit_comes_from_the_spacing_with_a_note(tmp_path: Path, step: float, unit: str) -> None:
    log = read_log(str(write(tmp_path / "log.csv", still_log(step))))
    seconds = log.seconds()
    assert seconds is not None
    assert seconds[-1] == pytest.approx(199 * 0.01)
    words = {"ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}
    said = f"time column 't' read in {words.get(unit)}: it advances {step:g} per sample (100 Hz)"
    expected = [] if unit == "s" else [f"{tmp_path / 'log.csv'}: {said}; if it is not, give --time-unit"]
    assert [n for n in log.layout.notes if "time column" in n] == expected


def test_an_explicit_time_unit_wins_over_the_spacing(tmp_path: Path) -> None:
    log = read_log(str(write(tmp_path / "log.csv", still_log(10))), ReadSpec(time_unit="s"))
    assert log.scale == 1.0
    assert log.layout.notes == []


def test_real_epoch_nanoseconds_are_recognised_by_their_spacing() -> None:
    """NCSU's MicroStrain log names its column `timestamp` and writes epoch nanoseconds (~1 kHz)."""
    s = read_samples(str(NCSU))
    assert s.duration == pytest.approx(read_samples(str(NCSU), ReadSpec(time_unit="ns")).duration)
    assert s.duration is not None
    assert 0.05 < s.duration < 1.0
    assert any("read in nanoseconds" in n for n in s.layout.notes)


def test_a_name_its_spacing_contradicts_is_exit_2_naming_time_unit(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    log = write(tmp_path / "log.csv", still_log(0.01, "timestamp_ms,ax,ay,az"))  # seconds, named ms
    with pytest.raises(InputError, match=r"named in milliseconds, but it advances 0.01 per sample") as err:
        read_log(str(log))
    assert "--time-unit" in (err.value.hint or "")
    code, _, text = run(capsys, "solve", "--log", log, "-o", tmp_path / "cal.json")
    assert code == 2
    assert "--time-unit" in text
    assert "Traceback" not in text
    assert not (tmp_path / "cal.json").exists()


def test_a_clock_at_no_sensor_rate_is_exit_2(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"advances 1e\+10 per sample: not seconds, ms, µs or ns"):
        read_log(str(write(tmp_path / "log.csv", still_log(1e10))))


def test_the_time_column_is_not_judged_when_rate_replaces_it(tmp_path: Path) -> None:
    log = read_log(str(write(tmp_path / "log.csv", still_log(1e10))), use_time=False)
    assert log.scale == 1.0


@pytest.mark.slow
def test_segment_refuses_hundreds_of_tiny_blocks_and_says_why(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A log in ms read as seconds (--time-unit s): a sample every 10 s, every wobble a "pose"."""
    lines = (DATA / "logs" / "ckexplorer_acc_log.csv").read_text().splitlines()
    log = write(
        tmp_path / "ms.csv", "t," + lines[0] + "\n" + "".join(f"{10 * i},{ln}\n" for i, ln in enumerate(lines[1:]))
    )
    out = tmp_path / "blocks"
    code, _, err = run(capsys, "segment", log, "--time-unit", "s", "-d", out)
    assert code == 2
    assert "the log's time scale is wrong, not its poses" in err
    assert "--time-unit" in err
    assert not out.exists()
    code, _, err = run(capsys, "solve", "--log", log, "--time-unit", "s", "-o", tmp_path / "cal.json")
    assert code == 2, err
    # by default the spacing says milliseconds, and the same log is segmented at 100 Hz
    code, _, err = run(capsys, "segment", log, "--min-duration", "0.3", "-d", out)
    assert code == 0, err
    assert "read in milliseconds" in err


# -- a metadata preamble --------------------------------------------------------------------

PREAMBLE = "Device,MPU6050\nFs,100\nLogging Type,0\n"


def test_a_preamble_before_the_header_is_skipped_with_a_note(tmp_path: Path) -> None:
    path = write(tmp_path / "z.csv", PREAMBLE + still_log(0.01))
    s = read_samples(str(path))
    assert s.layout.names == ["t", "ax", "ay", "az"]
    assert s.values.shape == (200, 3)
    assert s.layout.data_line == 5
    assert s.layout.notes[0].startswith(f"{path}: 3 lines before the header skipped (lines 1-3: 'Device,MPU6050'")


def test_skip_rows_forces_the_preamble(tmp_path: Path) -> None:
    # a preamble line as wide as the table is no preamble by its shape: --skip-rows says so
    path = write(tmp_path / "z.csv", "serial,station,operator,date\n" + still_log(0.01))
    with pytest.raises(InputError, match="no accelerometer x,y,z columns found"):
        read_samples(str(path))
    s = read_samples(str(path), ReadSpec(dialect=Dialect(skip_rows=1)))
    assert s.layout.names == ["t", "ax", "ay", "az"]
    assert s.values.shape == (200, 3)
    with pytest.raises(InputError, match="--skip-rows takes a whole number"):
        Dialect(skip_rows=-1)


def test_a_header_narrower_than_its_rows_is_no_preamble(tmp_path: Path) -> None:
    path = write(tmp_path / "z.csv", "ax,ay,az\n1,2,3,4\n1,2,3,4\n")
    with pytest.raises(InputError, match="row has 4 fields, the header has 3"):
        read_samples(str(path))


def test_apply_keeps_the_preamble_and_solve_notes_it(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    poses = []
    for p in POSES_3:
        target = tmp_path / Path(p).name
        target.write_text(PREAMBLE + Path(p).read_text())
        poses.append(target)
    code, _, err = run(capsys, "solve", "--poses", *poses, "-o", tmp_path / "cal.json")
    assert code == 0, err
    assert "3 lines before the header skipped" in err
    plain = tmp_path / "plain.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", plain).code == 0
    np.testing.assert_array_equal(tumblecal.load(tmp_path / "cal.json").offset, tumblecal.load(plain).offset)
    capture = write(tmp_path / "capture.csv", PREAMBLE + (SAMPLE / "capture.csv").read_text())
    code, out, err = run(capsys, "apply", "--cal", plain, capture)
    assert code == 0, err
    assert out.startswith(PREAMBLE + (SAMPLE / "capture.csv").read_text().splitlines()[0] + "\n")
    code, expected, _ = run(capsys, "apply", "--cal", plain, SAMPLE / "capture.csv")
    assert out == PREAMBLE + expected


# -- decimal commas ------------------------------------------------------------------------


def european(text: str) -> str:
    """A comma-separated capture as a European spreadsheet exports it: ';' and decimal commas."""
    return "".join(";".join(c.replace(".", ",") for c in line.split(",")) + "\n" for line in text.splitlines())


def test_decimal_commas_are_read_and_written_back(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    poses = [write(tmp_path / Path(p).name, european(Path(p).read_text())) for p in POSES_3]
    assert ",".join(["1", "2"]) not in poses[0].read_text().splitlines()[0]
    code, _, err = run(capsys, "solve", "--poses", *poses, "-o", tmp_path / "cal.json")
    assert code == 0, err
    assert "decimal comma" in err
    plain = tmp_path / "plain.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", plain).code == 0
    np.testing.assert_allclose(tumblecal.load(tmp_path / "cal.json").matrix, tumblecal.load(plain).matrix, rtol=1e-12)
    capture = write(tmp_path / "capture.csv", european((SAMPLE / "capture.csv").read_text()))
    code, out, err = run(capsys, "apply", "--cal", plain, capture)
    assert code == 0, err
    _, expected, _ = run(capsys, "apply", "--cal", plain, SAMPLE / "capture.csv")
    assert out == european(expected)


def test_headerless_decimal_commas_are_not_taken_for_columns(tmp_path: Path) -> None:
    path = write(tmp_path / "z.csv", "0,01;0,02;1,01\n0,011;-0,02;1,0\n")
    s = read_samples(str(path))
    assert s.layout.delimiter == ";"
    np.testing.assert_array_equal(s.values, [[0.01, 0.02, 1.01], [0.011, -0.02, 1.0]])


def test_decimal_option_forces_it_and_the_hint_names_it(tmp_path: Path) -> None:
    mixed = "ax;ay;az\n0.5;0;1\n0,01;0,02;1,01\n"  # both marks: not unambiguous, so not guessed
    path = write(tmp_path / "z.csv", mixed)
    with pytest.raises(InputError, match=r"not a number: '0,01' \(line 3, column ax\)") as err:
        read_samples(str(path))
    assert "--decimal ," in (err.value.hint or "")
    s = read_samples(
        str(write(tmp_path / "c.csv", "ax;ay;az\n0,01;0,02;1,01\n")), ReadSpec(dialect=Dialect(decimal=","))
    )
    np.testing.assert_array_equal(s.values, [[0.01, 0.02, 1.01]])
    with pytest.raises(InputError, match="--decimal , needs columns separated by something else"):
        read_samples(str(write(tmp_path / "d.csv", "ax,ay,az\n0,0,1\n")), ReadSpec(dialect=Dialect(decimal=",")))


# -- a last line cut short -------------------------------------------------------------------


def test_an_incomplete_last_line_is_named_and_drop_incomplete_drops_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    text = (SAMPLE / "z.csv").read_text()
    lines = text.splitlines()
    path = write(tmp_path / "z.csv", text + lines[-1][:12])  # the logger stopped mid-row
    with pytest.raises(InputError, match="last line incomplete") as err:
        read_samples(str(path))
    assert err.value.line == len(lines) + 1
    out = tmp_path / "cal.json"
    out.write_bytes(PRECIOUS)
    code, _, msg = run(capsys, "solve", "--poses", path, "-o", out)
    assert code == 2
    assert "--drop-incomplete" in msg
    assert_untouched(out)
    code, _, msg = run(capsys, "solve", "--poses", path, "--drop-incomplete", "-o", out)
    assert code == 0, msg
    assert "the last line is incomplete" in msg
    assert tumblecal.load(out).poses[0]["samples"] == len(lines) - 1
    code, corrected, msg = run(capsys, "apply", "--cal", out, path, "--drop-incomplete")
    assert code == 0, msg
    assert corrected.count("\n") == len(lines)  # the header and every whole row


def test_a_complete_last_line_without_a_line_end_is_kept(tmp_path: Path) -> None:
    text = (SAMPLE / "z.csv").read_text().rstrip("\n")
    s = read_samples(str(write(tmp_path / "z.csv", text)))
    assert len(s.values) == len(text.splitlines()) - 1


@pytest.mark.slow
def test_drop_incomplete_from_a_pipe() -> None:
    text = (SAMPLE / "z.csv").read_text()
    cut = text + text.splitlines()[-1][:9]
    done = subprocess.run(
        [tumblecal_exe(), "solve", "--poses", "-", "--drop-incomplete", "--json", "-o", "/dev/null"],
        input=cut.encode(),
        capture_output=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert b"the last line is incomplete" in done.stderr


def test_python_api_takes_the_same_options(tmp_path: Path) -> None:
    poses = [write(tmp_path / Path(p).name, PREAMBLE + european(Path(p).read_text())) for p in POSES_3]
    solved = tumblecal.solve([str(p) for p in poses], skip_rows=3, decimal=",")
    assert solved.status == 0
    plain = tumblecal.solve(POSES_3)
    assert plain.calibration is not None
    assert solved.calibration is not None
    np.testing.assert_allclose(solved.calibration.offset, plain.calibration.offset, rtol=1e-12)
    with pytest.raises(InputError, match="--decimal"):
        tumblecal.solve(POSES_3, decimal=";")


# -- found in review: each failed before its fix ------------------------------------------------


def test_ts_and_times_are_names_not_t_in_seconds(tmp_path: Path) -> None:
    """`ts` is a time column's name, not t + s: an epoch-ms clock named ts is read as such."""
    rows = "".join(f"{1730147632975 + 10 * i},0.01,0.02,1.0\n" for i in range(300))
    log = read_log(str(write(tmp_path / "ts.csv", "ts,ax,ay,az\n" + rows)))
    assert log.scale == 1e-3
    assert any("read in milliseconds" in n for n in log.layout.notes)


def test_a_step_of_200_is_milliseconds_at_5_hz(tmp_path: Path) -> None:
    log = read_log(str(write(tmp_path / "slow.csv", still_log(200))))
    assert log.scale == 1e-3


def test_a_whole_last_line_wider_than_64_kib_without_a_line_end_is_data(tmp_path: Path) -> None:
    row = ",".join(["0.01", "0.02", "1.0", *(["23456.789"] * 12_000)])
    header = ",".join(["ax", "ay", "az", *(f"c{i}" for i in range(12_000))])
    s = read_samples(str(write(tmp_path / "wide.csv", header + "\n" + row + "\n" + row)))
    assert s.values.shape == (2, 3)


def test_a_cut_last_line_of_a_cr_only_file_names_its_line(tmp_path: Path) -> None:
    path = write(tmp_path / "cr.csv", "t,ax,ay,az\r0,1,2,3\r1,1,2,3\r2,1,2")
    with pytest.raises(InputError, match="last line incomplete") as err:
        read_samples(str(path))
    assert err.value.line == 4


def test_apply_says_it_dropped_a_cut_last_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    cut = write(tmp_path / "cut.csv", "t,ax,ay,az\n0,1,2,3\n1,1,2,3\n2,1,2,3e")
    code, out, err = run(capsys, "apply", "--cal", cal, cut, "--drop-incomplete")
    assert code == 0, err
    assert "note: " in err
    assert "the last line is incomplete ('2,1,2,3e'), dropped (--drop-incomplete)" in err
    assert out.count("\n") == 3


def test_a_one_line_preamble_is_named_alone(tmp_path: Path) -> None:
    path = write(tmp_path / "z.csv", "Fs,100\n" + still_log(0.01))
    note = read_samples(str(path)).layout.notes[0]
    assert note == f"{path}: 1 line before the header skipped (line 1: 'Fs,100'); --skip-rows N says how many"
