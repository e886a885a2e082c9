"""Pose files with motion (README "Pose files with motion"): a pose file that also logged the
unit being placed or lifted is solved from its still run, with a note naming its rows;
``--no-trim`` rejects it whole, as before; still runs in two orientations are exit 3; segment
writes the one still block of such a file.

Real files: ``tests/data/ncsu_microstrain_motion`` (six single-face logs of a factory-calibrated
MicroStrain IMU that start at rest and then log the handling; see its SOURCE.md). Synthetic ones
are made here with a known truth.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import assert_one_error, assert_untouched, precious, run

ROOT = Path(__file__).resolve().parent.parent
MOTION = ROOT / "tests" / "data" / "ncsu_microstrain_motion"
HEADS = ROOT / "tests" / "data" / "ncsu_microstrain"
FILES = ("xplus", "xminus", "yplus", "yminus", "zplus", "zminus")
#: The still run of each file (its data rows, first and last), as the detector finds it: each starts
#: at rest (SOURCE.md) and is still for 0.95-2.2 s before the hand lifts it.
RUNS = {
    "xplus": (0, 120),
    "xminus": (0, 134),
    "yplus": (0, 269),
    "yminus": (0, 118),
    "zplus": (0, 150),
    "zminus": (0, 268),
}
NOTE = re.compile(
    r"note: (?P<file>\S+): the unit moved while it logged; solved from its still run, "
    r"rows (?P<first>\d+)-(?P<last>\d+) \((?P<t0>[\d.]+)-(?P<t1>[\d.]+) s\) "
    r"of 0-(?P<end>\d+) \(0\.000-[\d.]+ s\); --no-trim rejects the file instead"
)


def six() -> list[Path]:
    return [MOTION / f"{name}.csv" for name in FILES]


def test_six_pose_files_with_motion_solve_from_their_still_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each file was rejected as moved (standard deviation 0.29-0.65 g on its up axis), with no
    way through; now each is solved from its still start, a note naming its rows and seconds,
    and the factory-calibrated unit reads 1 g per face: gains 0.9987-0.9999, offsets < 0.3 mg."""
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", *six(), "-o", out)
    assert r.code == 0, r.err
    notes = {Path(m["file"]).stem: m for m in NOTE.finditer(r.err)}
    assert sorted(notes) == sorted(FILES), r.err
    for name, (first, last) in RUNS.items():
        assert (int(notes[name]["first"]), int(notes[name]["last"])) == (first, last)
        assert float(notes[name]["t0"]) == 0.0
        assert 0.9 < float(notes[name]["t1"]) < 2.2  # the still start: about 1-2 s at 125 Hz
    cal = json.loads(out.read_text())
    assert cal["method"] == "six-pose-magnitude"
    np.testing.assert_allclose(cal["gain"], 1.0, atol=0.002)  # 0.99890 0.99871 0.99986
    np.testing.assert_allclose(cal["offset"], 0.0, atol=0.001)  # 3e-5, -2e-4, 2.4e-4 g
    for pose in cal["poses"]:
        name = Path(pose["file"]).stem
        assert tuple(pose["rows"]) == RUNS[name]  # the calibration records the rows used ...
        assert pose["samples"] == RUNS[name][1] - RUNS[name][0] + 1
        assert pose["times"] is not None  # ... and their times (the time column's, in ns)
        assert max(pose["std"]) < 0.02


def test_no_trim_keeps_the_strict_rejection(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *six(), "--no-trim", "-o", out)
    assert r.code == 3, r.err
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert len(errors) == 6
    assert all("the unit moved" in e for e in errors)
    assert "still run" not in r.err
    assert_untouched(out)
    solved = tumblecal.solve([str(p) for p in six()], no_trim=True)
    assert solved.status == 3
    assert [f.code for f in solved.rejections] == ["pose.moved"] * 6


def test_a_still_pose_file_is_solved_as_it_always_was(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Trimming is tried only when the whole files are rejected: files that pass give the same
    calibration byte for byte with or without --no-trim (and no note)."""
    heads = [ROOT / "tests" / "data" / "ncsu_xplus_head.csv", *(HEADS / f"{n}_head.csv" for n in FILES[1:])]
    texts = []
    for flags in ((), ("--no-trim",)):
        out = tmp_path / f"cal{len(flags)}.json"
        r = run(capsys, "solve", "--poses", *heads, "--max-noise", "0.05", *flags, "-o", out)
        assert r.code == 0, r.err
        assert "still run" not in r.err
        texts.append(re.sub(r'"created": "[^"]*"', "", out.read_text()))
    assert texts[0] == texts[1]


def _turned(tmp_path: Path, second_face: tuple[float, float, float], name: str) -> Path:
    """A +z pose file at 100 Hz, in g: 3 s at rest, a 1.5 s turn, then 3 s at rest facing
    ``second_face`` (the same face: put back where it was, 1° off)."""
    rng = np.random.default_rng(4)
    up, other = np.array([0.0, 0.0, 1.0]), np.array(second_face) / np.linalg.norm(second_face)
    s = np.linspace(0, 1, 150)[:, None]
    turn = (1 - s) * up + s * other + 0.3 * np.sin(np.pi * s) * np.array([1.0, 1.0, 0.0])  # never still
    values = np.concatenate([np.tile(up, (300, 1)), turn, np.tile(other, (300, 1))])
    values += rng.normal(0, 0.002, values.shape)
    path = tmp_path / name
    t = np.arange(len(values)) / 100.0
    np.savetxt(path, np.column_stack([t, values]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.6f")
    return path


def test_two_still_runs_in_different_orientations_is_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = _turned(tmp_path, (1.0, 0.0, 0.0), "zp.csv")
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", src, "-o", out)
    assert_one_error(
        r,
        f"{src}: two still runs in different orientations, 90° apart: rows 0-278 (0.000-2.780 s) (near +z) and "
        "rows 470-748 (4.700-7.480 s) (near +x); a pose file holds one pose",
        code=3,
        hint="--start 0r --end 278r",
    )
    assert_untouched(out)
    r = run(capsys, "solve", "--poses", src, "--json", "-o", out)
    assert r.code == 3
    assert [e["code"] for e in json.loads(r.out)["rejections"]] == ["pose.turned"]
    # the rows the hint gives solve it
    r = run(capsys, "solve", "--poses", src, "--start", "0r", "--end", "278r", "-o", tmp_path / "z.json")
    assert r.code == 0, r.err
    assert json.loads((tmp_path / "z.json").read_text())["poses"][0]["rows"] == [0, 278]


def test_two_still_runs_in_one_orientation_take_the_longer(tmp_path: Path) -> None:
    """Lifted and put back on the same face (1° off): one pose settled twice, not two poses."""
    src = _turned(tmp_path, (0.0175, 0.0, 1.0), "zp.csv")
    solved = tumblecal.solve(str(src))
    assert solved.status == 0, solved.error
    assert solved.calibration is not None
    assert solved.calibration.poses[0].rows == (0, 279)
    assert any("solved from its still run, rows 0-279 (0.000-2.790 s) of 0-749" in n for n in solved.notes)


def test_a_pose_in_memory_with_motion_is_trimmed_by_its_rate() -> None:
    values = np.loadtxt(MOTION / "zplus.csv", delimiter=",", skiprows=1)[:, 1:]
    solved = tumblecal.solve({"+z": values}, rate=125.0)
    assert solved.status == 0, solved.error
    assert solved.calibration is not None
    assert solved.calibration.poses[0].rows == RUNS["zplus"]
    assert any(
        "<+z>: the unit moved while it logged; solved from its still run, rows 0-150 (0.000-1.200 s)" in n
        for n in solved.notes
    )
    assert tumblecal.solve({"+z": values}, rate=125.0, no_trim=True).status == 3


def test_segment_writes_the_one_block_of_a_real_pose_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """NCSU's -z file (rest, then handling) holds one still block: segment writes it, exit 0
    (it was exit 3 "nothing to calibrate from: 1 still block kept"), and names no face it lacks."""
    out = tmp_path / "out"
    r = run(capsys, "segment", MOTION / "zminus.csv", "-d", out)
    assert r.code == 0, r.err
    assert sorted(p.name for p in out.iterdir()) == ["segments.csv", "zn.csv"]
    assert "faces: -z" in r.err
    assert "hint:" not in r.err
    assert "wrote 1 block file and segments.csv" in r.err
    r = run(capsys, "solve", "--poses", out / "zn.csv", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert "still run" not in r.err  # the block is still as a whole
