"""Part of a capture (docs/reference/csv.md): ``--start``/``--end`` read only the readings from
one to the other, in seconds from the capture's first reading or as 0-based data rows (``1200r``),
in ``solve`` (pose files, data in memory, ``--log``), ``noise``, ``verify`` and ``segment``, on the
command line and in the Python API; a bad one is exit 2 naming the flag.

Real files: ``tests/data/ncsu_microstrain_motion`` (MicroStrain pose files at about 125 Hz, time
in ns; SOURCE.md there), ``tests/data/ncsu_microstrain`` (their still heads) and
``tests/data/xsens_acc_still.txt`` (imu_tk's still start, time in s).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import assert_one_error, assert_untouched, precious, run

ROOT = Path(__file__).resolve().parent.parent
MOTION = ROOT / "tests" / "data" / "ncsu_microstrain_motion"
HEADS = [ROOT / "tests" / "data" / "ncsu_xplus_head.csv"] + [
    ROOT / "tests" / "data" / "ncsu_microstrain" / f"{n}_head.csv"
    for n in ("xminus", "yplus", "yminus", "zplus", "zminus")
]
XSENS_STILL = ROOT / "tests" / "data" / "xsens_acc_still.txt"


def test_solve_start_end_in_rows_and_in_seconds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = MOTION / "xplus.csv"
    rows = tmp_path / "rows.json"
    r = run(capsys, "solve", "--poses", src, "--up", "+x", "--start", "10r", "--end", "110r", "-o", rows)
    assert r.code == 0, r.err
    assert "still run" not in r.err  # the part given is still: nothing trimmed
    assert f"note: {src}: --start/--end: read rows 10-110 (0.07956-0.8769 s) of 0-189 (0-1.56 s)" in r.err
    pose = json.loads(rows.read_text())["poses"][0]
    assert (pose["rows"], pose["samples"]) == ([10, 110], 101)
    seconds = tmp_path / "seconds.json"
    r = run(capsys, "solve", "--poses", src, "--up", "+x", "--start", "0.0795", "--end", "0.877s", "-o", seconds)
    assert r.code == 0, r.err
    assert json.loads(seconds.read_text())["poses"][0]["rows"] == [10, 110]
    solved = tumblecal.solve([str(src)], up="+x", start="10r", end=0.877)
    assert solved.calibration is not None
    assert solved.calibration.poses[0].rows == (10, 110)
    assert solved.calibration.offset.tolist() == json.loads(rows.read_text())["offset"]


def test_data_in_memory_takes_start_and_end() -> None:
    """A DataFrame or an array: rows are its readings, seconds come from --rate."""
    import pandas as pd

    frame = pd.read_csv(MOTION / "zplus.csv")
    solved = tumblecal.solve({"+z": frame}, start="20r", end="100r")
    assert solved.calibration is not None
    assert (solved.calibration.poses[0].rows, solved.calibration.poses[0].samples) == ((20, 100), 81)
    values = frame[["scaledAccelX", "scaledAccelY", "scaledAccelZ"]].to_numpy()
    in_seconds = tumblecal.solve({"+z": values}, rate=125.0, start=0.16, end=0.8)
    assert in_seconds.calibration is not None
    assert in_seconds.calibration.poses[0].rows == (20, 100)
    assert in_seconds.calibration.offset.tolist() == solved.calibration.offset.tolist()
    with pytest.raises(tumblecal.InputError, match=r"<\+z>: --end 0.8: seconds need a time column or --rate"):
        tumblecal.solve({"+z": frame}, end=0.8)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (
            ("--start", "abc"),
            "--start 'abc': give seconds from the capture's first reading (2.5) or a 0-based data row (1200r)",
        ),
        (("--end", "-1"), "--end '-1': give seconds"),
        (("--start", "1.5r"), "--start 1.5r: give seconds"),
        (("--start", "2", "--end", "1"), "--start 2 is not before --end 1"),
        (("--start", "20r", "--end", "20r"), "--start 20r is not before --end 20r"),
    ],
)
def test_a_bad_start_or_end_is_one_line_naming_the_flag(
    flags: tuple[str, ...], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", MOTION / "xplus.csv", *flags, "-o", out)
    assert r.code == 2, r.err
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1
    assert errors[0].startswith(f"error: {message}")
    assert "Traceback" not in r.err
    assert_untouched(out)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (("--start", "5"), "--start 5 is past the capture's last reading, row 189 (1.56 s)"),
        (("--start", "190r"), "--start 190r is past the capture's last reading, row 189 (1.56 s)"),
        (("--start", "100r", "--end", "0.5"), "--start 100r and --end 0.5 hold no reading"),
    ],
)
def test_a_part_with_no_reading_names_the_file_and_the_flag(
    flags: tuple[str, ...], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = MOTION / "xplus.csv"
    r = run(capsys, "solve", "--poses", src, "--up", "+x", *flags, "-o", tmp_path / "cal.json")
    assert_one_error(r, f"{src}: {message}")
    assert not (tmp_path / "cal.json").exists()


def test_seconds_need_a_clock(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "zp.csv"
    np.savetxt(src, np.tile([0.0, 0.0, 1.0], (50, 1)), delimiter=",", header="ax,ay,az", comments="")
    r = run(capsys, "solve", "--poses", src, "--end", "0.2", "-o", tmp_path / "cal.json")
    assert_one_error(r, f"{src}: --end 0.2: seconds need a time column or --rate", hint="0.2r")
    r = run(capsys, "solve", "--poses", src, "--end", "0.2", "--rate", "100", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert json.loads((tmp_path / "cal.json").read_text())["poses"][0]["rows"] == [0, 20]


def test_noise_start_end(capsys: pytest.CaptureFixture[str]) -> None:
    """imu_tk's still start (time in s from 0.0298, 100 Hz): 10 s to 40 s from its first reading
    are its rows 1001-4000."""
    whole = json.loads(run(capsys, "noise", XSENS_STILL, "--no-header", "--json", "-q").out)
    r = run(capsys, "noise", XSENS_STILL, "--no-header", "--start", "10", "--end", "40", "--json")
    assert r.code == 0, r.err
    part = json.loads(r.out)
    assert (whole["samples"], part["samples"]) == (5000, 3000)
    assert "--start/--end: read rows 1001-4000 (10.01-40 s) of 0-4999 (0-49.98 s)" in r.err
    api = tumblecal.noise(XSENS_STILL, no_header=True, start=10, end="4000r")
    assert api.samples == 3000
    assert api.axes[0].noise_density.value == part["axes"]["x"]["noise_density"]["value"]


def test_verify_start_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A capture whose unit moved is not static (exit 3) whole; its still part verifies."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *HEADS, "--max-noise", "0.05", "-o", cal).code == 0
    held = MOTION / "zminus.csv"
    assert run(capsys, "verify", "--cal", cal, held).code == 3
    r = run(capsys, "verify", "--cal", cal, held, "--start", "0.5", "--end", "2", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["captures"][0]["samples"] == 187  # 0.5-2 s at 125.6 Hz
    assert abs(doc["captures"][0]["error_after"]) < 0.001
    api = tumblecal.verify([held], cal, start=0.5, end=2)
    assert (api.status, api.rows[0]["samples"]) == (0, 187)


def _session(tmp_path: Path) -> Path:
    """A log at 100 Hz in g: +z 3 s, a turn, +x 3 s, a turn, -y 3 s."""
    z, x, y = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0])
    s = np.linspace(0, 1, 150)[:, None]
    wobble = 0.3 * np.sin(np.pi * s)

    def turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        out: np.ndarray = (1 - s) * a + s * b + wobble * np.array([0.5, 0.5, 0.5])
        return out

    values = np.concatenate([np.tile(z, (300, 1)), turn(z, x), np.tile(x, (300, 1)), turn(x, y), np.tile(y, (300, 1))])
    values += np.random.default_rng(5).normal(0, 0.002, values.shape)
    path = tmp_path / "session.csv"
    t = np.arange(len(values)) / 100.0
    np.savetxt(path, np.column_stack([t, values]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.6f")
    return path


def test_segment_start_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = _session(tmp_path)
    whole = run(capsys, "segment", src, "--nominal-offset", "0")
    assert whole.code == 0, whole.err
    assert [ln.split(",")[16] for ln in whole.out.splitlines()[1:]] == ["+z", "+x", "-y"]
    r = run(capsys, "segment", src, "--nominal-offset", "0", "--start", "4", "--end", "899r", "-d", tmp_path / "out")
    assert r.code == 0, r.err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["segments.csv", "xp.csv"]
    found = tumblecal.segment(str(src), nominal_offset=0, start=4, end="899r").table()
    assert list(found["face"]) == ["+x"]
    assert int(found["first_row"][0]) >= 450  # the file's own rows, not counted from --start
    assert int(found["last_row"][0]) <= 749
    kept = (tmp_path / "out" / "xp.csv").read_text().splitlines()
    assert len(kept) - 1 == int(found["last_row"][0]) - int(found["first_row"][0]) + 1
    r = run(
        capsys,
        "solve",
        "--log",
        src,
        "--nominal-offset",
        "0",
        "--end",
        "4",
        "--method",
        "one-pose",
        "--up",
        "+z",
        "-o",
        tmp_path / "cal.json",
    )
    assert r.code == 0, r.err
    assert json.loads((tmp_path / "cal.json").read_text())["poses"][0]["pose"] == "+z"
