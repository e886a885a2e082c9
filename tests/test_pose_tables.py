"""A table of orientations (one averaged reading per row) given as one pose file: recognised by its
rows, or taken with --rows-are-poses, and solved as that many poses; never a units hint from the
mean of different orientations.

Real data: Hassan & Bao's 49 averaged orientations in g and the 24- and 31-orientation subsets
their repository ships (``tests/data/hassan_gnls``, MIT, see its SOURCE.md and LICENSE).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import assert_one_error, assert_untouched, precious, run, write
from tests.montecarlo import fibonacci_directions
from tumblecal_cli.errors import InputError

DATA = Path(__file__).resolve().parent / "data"
HASSAN, DATA_LOGS = DATA / "hassan_gnls", DATA / "logs"
ORIENT49, ORIENT24 = HASSAN / "orient49.csv", HASSAN / "orient24.csv"


def rows(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", skiprows=1)


def held_out_of_24() -> np.ndarray:
    """The 25 of the 49 orientations that the 24-orientation file does not hold (matched by text)."""
    fitted = set(ORIENT24.read_text().splitlines()[1:])
    lines = ORIENT49.read_text().splitlines()[1:]
    return np.array([[float(v) for v in line.split(",")] for line in lines if line not in fitted])


def solved(capsys: pytest.CaptureFixture[str], out: Path, *args: str | Path) -> tuple[dict[str, Any], str]:
    r = run(capsys, "solve", "--poses", *args, "-o", out)
    assert r.code == 0, r.err
    doc: dict[str, Any] = json.loads(out.read_text())
    return doc, r.err


def test_real_table_of_49_orientations_is_recognised(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No flag: 49 rows, no time column, each row turned 23° from the last in the median. The
    sphere fit of 49 poses; no units hint (today's fault: "looks like raw counts: --reference
    0.0641", the magnitude of the mean of 49 directions)."""
    doc, err = solved(capsys, tmp_path / "cal.json", ORIENT49)
    assert doc["method"] == "sphere"
    assert len(doc["poses"]) == 49
    assert [p["rows"] for p in doc["poses"]] == [[k, k] for k in range(49)]
    assert {p["file"] for p in doc["poses"]} == {str(ORIENT49)}
    assert all(p["samples"] == 1 for p in doc["poses"])
    assert (
        "note: orient49.csv: 49 rows taken as 49 poses, one orientation each: its rows point in different "
        "directions (from one row to the next by 23° in the median, more than 10°), and it has no time column "
        "(--no-rows-are-poses takes it as one pose)"
    ) in err
    assert "note: one reading per pose: the noise of each is unknown, so the uncertainty comes from the fit's" in err
    assert "--reference" not in err
    assert "raw counts" not in err
    # measured: gains 0.9921, 1.0034, 1.0077; offsets 0.0009, -0.0057, 0.0139 g, each ± 0.0002-0.0003
    np.testing.assert_allclose(doc["gain"], [0.9921, 1.0034, 1.0077], atol=0.001)
    assert all(2e-4 < u < 4e-4 for u in doc["uncertainty"]["offset"])


def test_real_table_fitted_on_24_reads_the_other_25_orientations_as_1_g(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The honest check: the fit of the 24-row file, applied to the 25 orientations it did not
    see. Measured: |corrected| - 1 g RMS 0.0012, max 0.0034 (raw: RMS 0.016, max 0.034). The
    same calibration as 24 one-row files (tests/test_solvers_realdata.py)."""
    doc, _ = solved(capsys, tmp_path / "cal.json", ORIENT24)
    assert doc["method"] == "sphere"
    cal = tumblecal.load(tmp_path / "cal.json")
    rest = held_out_of_24()
    assert len(rest) == 25
    after = np.linalg.norm(cal.apply(rest), axis=1) - 1.0
    before = np.linalg.norm(rest, axis=1) - 1.0
    assert math.sqrt(float(np.mean(after**2))) < 0.002
    assert float(np.abs(after).max()) < 0.005
    assert math.sqrt(float(np.mean(before**2))) > 0.012
    lines = ORIENT24.read_text().splitlines()[1:]
    files = [write(tmp_path / f"o{k:02d}.csv", f"x,y,z\n{line}\n") for k, line in enumerate(lines)]
    split, _ = solved(capsys, tmp_path / "split.json", *files, "--min-samples", "1")
    np.testing.assert_allclose(doc["offset"], split["offset"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(doc["matrix"], split["matrix"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(doc["uncertainty"]["offset"], split["uncertainty"]["offset"], rtol=1e-9)


def test_real_table_as_one_pose_says_its_rows_point_different_ways(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--no-rows-are-poses: one pose, whose mean is over 49 directions: exit 2 saying so, never a
    --reference from that mean."""
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", ORIENT49, "--no-rows-are-poses", "-o", out)
    assert_one_error(
        r,
        f"{ORIENT49}: its rows point in different directions: their mean reads 0.06415 in magnitude, a row "
        "0.9985 (the median): not one pose",
        hint="a table of orientations, one row each: solve it with --rows-are-poses; a log of still poses: solve --log",
    )
    assert_untouched(out)


def test_a_log_given_as_a_pose_gets_no_units_hint(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """CK-Explorer's log (in g, no time column, a few hundred samples a second): not a table
    (consecutive samples differ by noise), and its mean over the log's orientations is no
    reason for a --reference."""
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", DATA_LOGS / "ckexplorer_acc_log.csv", "-o", out)
    assert r.code == 3  # its still runs point different ways: one pose file holds one pose
    assert "two still runs in different orientations" in r.err
    assert "a log of several poses: solve --log FILE" in r.err
    assert "raw counts" not in r.err
    assert "--reference" not in r.err
    assert_untouched(out)


def test_rows_are_poses_takes_a_timed_file_and_labels_six_rows_as_six_faces(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A station that logs one averaged row per face, with a time column: not recognised (a
    timed file is a log or a pose), taken with --rows-are-poses; six rows are the six faces in
    the order +x -x +y -y +z -z, as six unlabelled files are."""
    a = np.diag([1.02, 0.98, 1.01])
    b = np.array([0.02, -0.01, 0.03])
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    table = np.column_stack([np.arange(6) * 10.0, faces @ a.T + b])
    path = write(tmp_path / "station.csv", table)
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", path, "-o", out)
    assert r.code == 2  # one pose, whose rows point six ways
    assert "its rows point in different directions" in r.err
    assert_untouched(out)
    doc, err = solved(capsys, tmp_path / "cal.json", path, "--rows-are-poses")
    assert doc["method"] == "six-pose"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "-x", "+y", "-y", "+z", "-z"]
    np.testing.assert_allclose(doc["offset"], b, atol=1e-6)
    np.testing.assert_allclose(doc["gain"], np.diag(a), atol=1e-6)
    assert "note: 6 rows taken as 6 poses, one orientation each (--rows-are-poses)" in err
    assert "so the uncertainty reads 0, and the moved check cannot judge them" in err


def test_a_table_of_seven_rows_says_what_the_rows_are(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path / "seven.csv", fibonacci_directions(7), header="x,y,z")
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", path, "-o", out)
    assert_one_error(
        r,
        "--poses: no solver takes 7 unlabelled files: give 1 (one-pose), 3 (+x +y +z), 6 (+x -x +y -y +z -z), "
        "12+ unlabelled (sphere) or 4+ labelled (least-squares)",
        hint="the table's 7 rows are 7 poses; label a file",
    )
    assert_untouched(out)


def test_rows_are_poses_refuses_a_labelled_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", f"+z={ORIENT49}", "--rows-are-poses", "-o", out)
    assert_one_error(
        r,
        "--rows-are-poses takes unlabelled captures: each row is a pose of unknown orientation",
        hint="give the table's file without a label or --up",
    )
    assert_untouched(out)


@pytest.mark.slow  # pandas
def test_python_takes_a_table_in_memory() -> None:
    """An array or a DataFrame alone is one unlabelled capture: recognised as a table as a file is;
    ``rows_are_poses=False`` keeps it one pose."""
    import pandas as pd

    values = rows(ORIENT49)
    for data in (values, pd.DataFrame(values, columns=["ax", "ay", "az"]), [values]):
        solved_ = tumblecal.solve(data)
        assert solved_.status == 0
        assert solved_.calibration is not None
        assert solved_.calibration.method == "sphere"
        assert len(solved_.calibration.poses) == 49
    with pytest.raises(InputError, match="its rows point in different directions"):
        tumblecal.solve(values, rows_are_poses=False)
    with pytest.raises(InputError, match=r"rows_are_poses is True, False or None .*got 'yes'"):
        tumblecal.solve(values, rows_are_poses="yes")  # type: ignore[arg-type]


@pytest.mark.slow
def test_table_uncertainty_from_the_residuals_matches_the_scatter() -> None:
    """Over 300 synthetic tables of 49 one-reading orientations (σ = 0.002 per axis), the errors
    of the offsets and gains over their stated 1-sigma have RMS 1 (measured 1.02-1.09: the noise
    is estimated from 40 degrees of freedom) and mean 0."""
    rng = np.random.default_rng(29)
    a = np.diag([1.02, 0.97, 1.01]) + np.array([[0.0, 0.012, -0.02], [0.0, 0.0, 0.006], [0.0, 0.0, 0.0]])
    b = np.array([0.05, -0.03, 0.02])
    ideal = fibonacci_directions(49) @ a.T + b
    z = []
    for _ in range(300):
        solved_ = tumblecal.solve(ideal + rng.normal(0.0, 0.002, ideal.shape), rows_are_poses=True)
        cal = solved_.calibration
        assert cal is not None
        errors = np.concatenate([cal.offset - b, cal.gain - np.diag(a)])
        z.append(errors / np.concatenate([cal.uncertainty["offset"], cal.uncertainty["gain"]]))
    scores = np.array(z)
    rms = np.sqrt((scores**2).mean(axis=0))
    assert np.all((rms > 0.85) & (rms < 1.2)), rms
    assert np.all(np.abs(scores.mean(axis=0)) < 0.2), scores.mean(axis=0)


def test_verify_judges_each_row_of_a_table_held_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The held-out check of a table (fit on 24 rows, judge the 25 others) from the command
    line: each row a capture of its own, recognised as solve recognises a table, and the
    norm before calibration is each row's, not a mean's over orientations."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", ORIENT24, "-o", cal, "-q").code == 0
    lines = [",".join(str(float(v)) for v in r) for r in held_out_of_24()]
    others = write(tmp_path / "held.csv", "ax,ay,az\n" + "\n".join(lines) + "\n")
    r = run(capsys, "verify", "--cal", cal, others, "--json")
    assert r.code == 0, r.err
    found = json.loads(r.out)
    assert len(found["captures"]) == 25
    assert found["captures"][0]["file"] == f"{others} row 0"
    assert found["rms_error"] < 0.002 < found["rms_error_before"]  # 1 g to 0.0012 after, 0.016 before
    assert "each of its 25 rows is judged as a capture of its own" in r.err
    whole = run(capsys, "verify", "--cal", cal, others, "--no-rows-are-poses")
    assert whole.code == 3  # one capture over 25 orientations: not static
    api = tumblecal.verify(str(others), str(cal), rows_are_poses=True)
    assert [row["file"] for row in api.rows] == [f"{others} row {k}" for k in range(25)]


def test_a_noisy_still_capture_is_not_a_table() -> None:
    """Noise of 0.2 g turns consecutive rows by 15 degrees, but they all point one way."""
    from tumblecal_cli.core import methods

    noisy = np.tile([0.0, 0.0, 1.0], (500, 1)) + np.random.default_rng(301).normal(0, 0.2, (500, 3))
    assert methods.orientation_table(noisy, np.zeros(3)) is None
    assert methods.orientation_table(rows(ORIENT49), np.zeros(3)) is not None
