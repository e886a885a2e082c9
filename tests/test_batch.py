"""``tumblecal batch`` (many units: one calibration each and summary.csv) and ``apply`` over many captures.

Most tests call ``tumblecal_cli.cli.main`` in-process, as tests/test_cli.py does; ``--jobs 2``
runs the installed ``tumblecal`` script as a subprocess (its worker processes come from a
forkserver, which is better started from a clean process than from pytest). Unit folders are
built in ``tmp_path`` from copies of ``sample_data``. ``SOURCE_DATE_EPOCH`` is set for every test,
so the calibrations' ``created`` time, and hence their names, are fixed.
"""

from __future__ import annotations

import csv
import itertools
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import IMUCAL, SAMPLE, SIX_FACES, run, run_exe, snapshot, tumblecal_exe, unit
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.outputs import unsafe
from tumblecal_cli.pipeline.batch import summary as summaries
from tumblecal_cli.pipeline.batch import units as batch

LIMITS = SAMPLE / "limits.yaml"
SESSION = IMUCAL / "session_every4th.csv"
#: docs/commands/segment.md: the imucal session's still blocks need these
LOG_OPTIONS = ("--rate", "25.6", "--reference", "9.81")

EPOCH = "1700000000"
STAMP = "20231114T221320Z"  # EPOCH as a file name's UTC time
CREATED = "2023-11-14T22:13:20Z"  # and as the calibration's 'created'


# -- helpers -------------------------------------------------------------------------------


@pytest.fixture(autouse=True)
def _fixed_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)


def units(root: Path, kinds: dict[str, str]) -> Path:
    for serial, kind in kinds.items():
        unit(root, serial, kind)
    return root


def read_rows(path: Path) -> list[dict[str, str]]:
    """summary.csv's rows, each cell as it was before a leading ' kept a spreadsheet from taking
    it for a formula (labelled inputs, +x=x.csv, are written '+x=x.csv)."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == summaries.SUMMARY_COLUMNS
        return [{column: unsafe(cell) for column, cell in row.items()} for row in reader]


def by_serial(path: Path) -> dict[str, dict[str, str]]:
    return {r["serial"]: r for r in read_rows(path)}


def cal_name(serial: str, k: int = 1) -> str:
    return f"{serial}_{STAMP}{'' if k == 1 else f'_{k}'}.json"


MIXED = {"A1": "good", "B2": "rejected", "C3": "error", "D4": "six"}


# -- a folder of units: each unit's row, and the batch's exit status ------------------------


def test_batch_mixed_units_one_row_each(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """pass, fail (limits), rejected and error side by side; a failing unit never stops the batch."""
    src = units(tmp_path / "units", MIXED)
    out = tmp_path / "cals"
    r = run(capsys, "batch", src, "--out-dir", out, "--limits", LIMITS)
    assert r.code == 2, r.err  # an error unit: 2 wins over 3 and 1
    assert r.out == ""
    assert "Traceback" not in r.err
    rows = read_rows(out / "summary.csv")
    assert [row["serial"] for row in rows] == ["A1", "B2", "C3", "D4"]
    got = {row["serial"]: row for row in rows}

    a1 = got["A1"]
    assert (a1["status"], a1["verdict"], a1["codes"], a1["file"]) == ("0", "pass", "", cal_name("A1"))
    assert (a1["method"], a1["created"], a1["message"]) == ("three-pose", CREATED, "")
    for axis, offset, gain in zip("xyz", [0.021, -0.034, 0.047], [1.012, 0.987, 1.005], strict=True):
        assert float(a1[f"offset_{axis}"]) == pytest.approx(offset, abs=3e-4)
        assert float(a1[f"gain_{axis}"]) == pytest.approx(gain, abs=3e-4)
        assert 0 < float(a1[f"offset_se_{axis}"]) < 1e-3
        assert 0 < float(a1[f"gain_se_{axis}"]) < 1e-3
    assert a1["inputs"].split(";") == [f"+{n}={src / 'A1' / f'{n}.csv'}" for n in "xyz"]

    b2 = got["B2"]
    assert (b2["status"], b2["verdict"], b2["codes"], b2["file"]) == ("3", "rejected", "pose.orientation", "")
    assert "declared +y but reads like +x" in b2["message"]
    assert str(src / "B2" / "y.csv") in b2["message"]
    assert all(b2[c] == "" for c in summaries.NUMBERS)

    c3 = got["C3"]
    assert (c3["status"], c3["verdict"], c3["codes"], c3["file"]) == ("2", "error", "", "")
    assert str(src / "C3" / "z.csv") in c3["message"]
    assert "no data" in c3["message"]

    d4 = got["D4"]  # the six faces, labelled by their names, in counts, judged by limits in g: a units mistake
    assert (d4["status"], d4["verdict"], d4["file"], d4["method"]) == ("2", "error", "", "")
    assert "a units mistake?" in d4["message"]
    assert sorted(d4["inputs"].split(";")) == sorted(
        f"{face}={src / 'D4' / f'{name}.csv'}"
        for face, name in zip(["+x", "-x", "+y", "-y", "+z", "-z"], SIX_FACES, strict=True)
    )

    # nothing but the calibrations of the units that were solved, and the summary
    assert sorted(os.listdir(out)) == sorted([cal_name("A1"), "summary.csv"])
    # one line per unit on stderr, and the totals
    for serial in MIXED:
        assert any(line.startswith(f"{serial}: ") for line in r.err.splitlines()), r.err
    assert "4 units" in r.err


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kinds", "options", "expected"),
    [
        pytest.param({"A": "good", "B": "six"}, [], 0, id="all-pass"),
        pytest.param({"A": "good", "B": "six"}, ["--max-offset", "0.05"], 1, id="pass-fail"),
        pytest.param({"A": "good", "B": "rejected"}, [], 3, id="pass-rejected"),
        pytest.param({"A": "six", "B": "rejected"}, ["--max-offset", "0.05"], 3, id="fail-rejected"),
        pytest.param({"A": "good", "B": "error"}, [], 2, id="pass-error"),
        pytest.param({"A": "six", "B": "error"}, ["--max-offset", "0.05"], 2, id="fail-error"),
        pytest.param({"A": "error", "B": "rejected"}, [], 2, id="error-rejected"),
        pytest.param({"A": "good", "B": "good"}, ["--max-offset", "0.001"], 1, id="all-fail"),
        pytest.param({"A": "rejected", "B": "rejected"}, [], 3, id="all-rejected"),
    ],
)
def test_batch_exit_status_precedence(
    kinds: dict[str, str], options: list[str | Path], expected: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = units(tmp_path / "units", kinds)
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out", *options)
    assert r.code == expected, r.err
    statuses = {int(row["status"]) for row in read_rows(tmp_path / "out" / "summary.csv")}
    assert r.code == next((s for s in (2, 3, 1) if s in statuses), 0)


def test_status_precedence_over_every_combination() -> None:
    for n in range(1, 5):
        for combo in itertools.combinations_with_replacement([0, 1, 2, 3], n):
            rows: list[dict[str, Any]] = [{"status": s} for s in combo]
            expected = 2 if 2 in combo else 3 if 3 in combo else 1 if 1 in combo else 0
            assert summaries.status(rows) == expected, combo
            assert summaries.status(reversed(rows)) == expected, combo


def test_batch_limits_failure_still_writes_the_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"U1": "good"})
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out", "--max-offset", "0.001", "-q")
    assert (r.code, r.out, r.err) == (1, "", "")
    row = by_serial(tmp_path / "out" / "summary.csv")["U1"]
    assert (row["status"], row["verdict"], row["file"]) == ("1", "fail", cal_name("U1"))
    assert row["codes"].split(";") == ["limit.offset.x", "limit.offset.y", "limit.offset.z"]
    doc = json.loads((tmp_path / "out" / cal_name("U1")).read_text())
    assert doc["verdict"]["pass"] is False
    assert doc["unit"]["serial"] == "U1"


def test_batch_internal_error_in_one_unit_is_its_row(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bug while solving one unit is that unit's error (status 2), not the batch's end."""
    from tumblecal_cli.pipeline.solve import solving as pipeline

    solve = pipeline.calibrate

    def flaky(options: Any, **kwargs: Any) -> Any:
        if options.unit.serial == "B":
            raise RuntimeError("boom")
        return solve(options, **kwargs)

    monkeypatch.setattr(pipeline, "calibrate", flaky)
    src = units(tmp_path / "units", {"A": "good", "B": "good", "C": "good"})
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out")
    assert r.code == 2, r.err
    rows = by_serial(tmp_path / "out" / "summary.csv")
    assert [rows[s]["status"] for s in "ABC"] == ["0", "2", "0"]
    assert rows["B"]["message"] == "internal error: RuntimeError: boom"
    assert sorted(os.listdir(tmp_path / "out")) == [cal_name("A"), cal_name("C"), "summary.csv"]


# -- folder layouts ----------------------------------------------------------------------------


def test_batch_folder_layout_labels_and_notes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """+x.csv and xp.csv names label their files; other names are unlabelled, in name order;
    loose files, hidden folders and folders without data are left out (with a note)."""
    src = tmp_path / "units"
    plus = src / "PLUS"
    plus.mkdir(parents=True)
    for name in "zyx":  # created in reverse: the labels, not the order, decide
        shutil.copy(SAMPLE / f"{name}.csv", plus / f"+{name}.csv")
    plain = src / "PLAIN"
    plain.mkdir()
    for name, as_name in zip("xyz", ["a.csv", "b.csv", "c.csv"], strict=True):
        shutil.copy(SAMPLE / f"{name}.csv", plain / as_name)
    unit(src, "SIX", "six")
    (src / ".hidden").mkdir()
    shutil.copy(SAMPLE / "x.csv", src / ".hidden" / "x.csv")
    (src / "NODATA").mkdir()
    (src / "NODATA" / "x.bin").write_text("not a capture\n")
    shutil.copy(SAMPLE / "x.csv", src / "loose.csv")
    (plus / "notes.txt").write_text("operator: J. Doe\n")  # beside face-named files: not a pose

    out = tmp_path / "out"
    r = run(capsys, "batch", src, "--out-dir", out, "-q")
    assert r.code == 2, r.err  # a unit folder without captures is that unit's error, never a silent gap
    rows = by_serial(out / "summary.csv")
    assert sorted(rows) == ["NODATA", "PLAIN", "PLUS", "SIX"]
    nodata = rows.pop("NODATA")
    assert (nodata["status"], nodata["verdict"]) == ("2", "error")
    assert nodata["message"] == f"no pose files (.csv, .tsv, .txt, .dat) in {src / 'NODATA'}"
    assert r.err.splitlines() == [f"NODATA: error: {nodata['message']}"]  # -q still prints a unit's error
    assert rows["PLUS"]["inputs"].split(";") == [f"+{n}={plus / f'+{n}.csv'}" for n in "xyz"]
    assert rows["PLAIN"]["inputs"].split(";") == [str(plain / n) for n in ["a.csv", "b.csv", "c.csv"]]
    assert rows["SIX"]["method"] == "six-pose"
    assert {row["verdict"] for row in rows.values()} == {"pass"}
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "again")
    notes = [line for line in r.err.splitlines() if line.startswith("note:")]
    assert f"note: {plus}: notes.txt ignored (not named by a face like the unit's other files)" in notes
    assert any("beside the unit folders" in n for n in notes), notes


@pytest.mark.parametrize(
    "setup",
    [
        pytest.param("missing", id="no-such-folder"),
        pytest.param("empty", id="no-units"),
    ],
)
def test_batch_no_units_is_exit_2(setup: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "units"
    if setup == "empty":
        src.mkdir()
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out")
    assert r.code == 2
    assert r.out == ""
    assert r.err.startswith(f"error: {src}: ")
    assert not (tmp_path / "out").exists()


def test_batch_out_dir_that_is_a_file_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"A": "good"})
    target = tmp_path / "cals"
    target.write_text("a file\n")
    r = run(capsys, "batch", src, "--out-dir", target)
    assert r.code == 2
    assert "--out-dir takes a folder" in r.err
    assert target.read_text() == "a file\n"


# -- the calibration files are solve's ---------------------------------------------------------


def test_batch_calibrations_are_byte_identical_to_solve(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"A1": "good", "D4": "six"})
    out = tmp_path / "cals"
    r = run(capsys, "batch", src, "--out-dir", out, "--station", "ST-3", "--meta", "lot=42", "-q")
    assert r.code == 0, r.err

    # A1 as an operator would solve it by hand: unlabelled x y z, --serial the folder's name
    solo = tmp_path / "A1.json"
    poses = [src / "A1" / f"{n}.csv" for n in "xyz"]
    r = run(
        capsys, "solve", "-q", "--poses", *poses, "--serial", "A1", "--station", "ST-3", "--meta", "lot=42", "-o", solo
    )
    assert r.code == 0, r.err
    assert (out / cal_name("A1")).read_bytes() == solo.read_bytes()

    # D4 with the labels its file names give
    solo = tmp_path / "D4.json"
    faces = ["+x", "-x", "+y", "-y", "+z", "-z"]
    labelled = [f"{face}={src / 'D4' / f'{n}.csv'}" for face, n in zip(faces, SIX_FACES, strict=True)]
    r = run(
        capsys,
        "solve",
        "-q",
        "--poses",
        *labelled,
        "--serial",
        "D4",
        "--station",
        "ST-3",
        "--meta",
        "lot=42",
        "-o",
        solo,
    )
    assert r.code == 0, r.err
    assert (out / cal_name("D4")).read_bytes() == solo.read_bytes()

    doc = json.loads((out / cal_name("A1")).read_text())
    assert doc["created"] == CREATED
    assert doc["unit"]["serial"] == "A1"


def test_batch_calibration_values_match_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"A1": "good", "D4": "six"})
    out = tmp_path / "cals"
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 0
    for row in read_rows(out / "summary.csv"):
        doc = json.loads((out / row["file"]).read_text())
        assert row["method"] == doc["method"]
        assert row["created"] == doc["created"]
        for k, axis in enumerate("xyz"):
            assert float(row[f"offset_{axis}"]) == doc["offset"][k]  # repr: every digit
            assert float(row[f"gain_{axis}"]) == doc["gain"][k]
            assert float(row[f"offset_se_{axis}"]) == doc["uncertainty"]["offset"][k]
            assert float(row[f"gain_se_{axis}"]) == doc["uncertainty"]["gain"][k]


# -- never overwrite -----------------------------------------------------------------------------


def test_batch_rerun_with_summary_deleted_adds_numbered_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = units(tmp_path / "units", {"A": "good", "B": "six", "C": "error"})
    out = tmp_path / "out"
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 2
    first = snapshot(out)
    (out / "summary.csv").unlink()

    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 2
    rows = by_serial(out / "summary.csv")
    assert [rows[s]["file"] for s in "ABC"] == [cal_name("A", 2), cal_name("B", 2), ""]
    now = snapshot(out)
    for name, data in first.items():
        if name != "summary.csv":
            assert now[name] == data, f"{name} was replaced"
            assert now[name.replace(".json", "_2.json")] == data  # same unit, same time: same calibration
    assert sorted(now) == sorted([cal_name("A"), cal_name("A", 2), cal_name("B"), cal_name("B", 2), "summary.csv"])

    # and a third run: _3
    (out / "summary.csv").unlink()
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 2
    assert by_serial(out / "summary.csv")["A"]["file"] == cal_name("A", 3)


def test_publish_never_replaces_a_file(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    taken = out / "S1_20240102T030405Z.json"
    taken.write_bytes(b"the first calibration\n")
    staging = out / ".S1.partial.json"
    staging.write_bytes(b"the second calibration\n")

    name = batch.publish(str(staging), str(out), "S1", "2024-01-02T03:04:05Z")
    assert name == "S1_20240102T030405Z_2.json"
    assert taken.read_bytes() == b"the first calibration\n"
    assert (out / name).read_bytes() == b"the second calibration\n"

    name = batch.publish(str(staging), str(out), "S1", "2024-01-02T03:04:05Z")
    assert name == "S1_20240102T030405Z_3.json"
    assert batch.publish(str(staging), str(out), "S2", "2024-01-02T03:04:05Z") == "S2_20240102T030405Z.json"
    assert batch.publish(str(staging), str(out), "S1", "") == "S1_undated.json"
    assert taken.read_bytes() == b"the first calibration\n"
    for n in ["S1_20240102T030405Z_2.json", "S1_20240102T030405Z_3.json", "S2_20240102T030405Z.json"]:
        assert (out / n).read_bytes() == b"the second calibration\n"


# -- an existing summary: refused, or --resume -----------------------------------------------------


def test_batch_existing_summary_without_resume_changes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = units(tmp_path / "units", {"A": "good", "B": "rejected"})
    out = tmp_path / "out"
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 3
    unit(src, "C", "good")  # a new unit: still not solved without --resume
    before = snapshot(out)
    stats = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}

    r = run(capsys, "batch", src, "--out-dir", out)
    assert r.code == 2
    assert r.out == ""
    lines = r.err.splitlines()
    assert lines[0] == f"error: {out / 'summary.csv'}: a batch summary is already here"
    assert lines[1].startswith("hint:")
    assert "--resume" in lines[1]
    assert len(lines) == 2
    assert snapshot(out) == before
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stats


def test_batch_resume_skips_units_in_the_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A batch killed after some units: --resume does the rest and keeps the rows it had."""
    src = units(tmp_path / "units", {"A": "good", "B": "rejected", "C": "error", "D": "six", "E": "good"})
    full = tmp_path / "full"
    assert run(capsys, "batch", src, "--out-dir", full, "-q").code == 2
    full_text = (full / "summary.csv").read_text()
    lines = full_text.splitlines(keepends=True)
    header, rows = lines[0], {line.split(",", 1)[0]: line for line in lines[1:]}

    # what a batch killed after units D and B leaves: their rows, appended as they finished
    part = tmp_path / "part"
    part.mkdir()
    shutil.copy(full / cal_name("D"), part / cal_name("D"))
    (part / "summary.csv").write_text(header + rows["D"] + rows["B"])

    r = run(capsys, "batch", src, "--out-dir", part, "--resume")
    assert r.code == 2, r.err
    assert "resuming: 2 of 5 units already done" in r.err
    done_now = {line.split(":", 1)[0] for line in r.err.splitlines() if line[:2] in ("A:", "B:", "C:", "D:", "E:")}
    assert done_now == {"A", "C", "E"}, r.err  # D and B were not redone
    assert (part / "summary.csv").read_text() == full_text  # sorted by serial, as one run writes it
    assert sorted(os.listdir(part)) == sorted([cal_name("A"), cal_name("D"), cal_name("E"), "summary.csv"])

    # everything done: --resume solves nothing, and the status is still the summary's
    before = snapshot(part)
    r = run(capsys, "batch", src, "--out-dir", part, "--resume")
    assert r.code == 2, r.err
    assert "resuming: 5 of 5 units already done" in r.err
    assert snapshot(part) == before


def test_batch_resume_keeps_rows_as_they_were(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A unit in the summary is not redone whatever its row says; delete the row to redo it."""
    src = units(tmp_path / "units", {"A": "good", "B": "good"})
    out = tmp_path / "out"
    out.mkdir()
    row: dict[str, Any] = {"serial": "A", "status": 3, "verdict": "rejected", "codes": ["pose.moved"]}
    row["message"] = "rejected by yesterday's run"
    (out / "summary.csv").write_text(summaries.text([row]))

    r = run(capsys, "batch", src, "--out-dir", out, "--resume", "-q")
    assert r.code == 3, r.err  # the kept row's status counts
    rows = by_serial(out / "summary.csv")
    assert (rows["A"]["status"], rows["A"]["codes"], rows["A"]["message"]) == (
        "3",
        "pose.moved",
        "rejected by yesterday's run",
    )
    assert (rows["B"]["status"], rows["B"]["file"]) == ("0", cal_name("B"))
    assert not (out / cal_name("A")).exists()


def test_batch_resume_of_a_foreign_summary_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"A": "good"})
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.csv").write_text("serial,result\nA,ok\n")
    before = snapshot(out)
    r = run(capsys, "batch", src, "--out-dir", out, "--resume")
    assert r.code == 2
    assert "not a tumblecal batch summary" in r.err
    assert snapshot(out) == before


def test_batch_resume_twice_killed_during_the_first_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    src = units(tmp_path / "units", {"A": "good", "B": "good"})
    out = tmp_path / "out"
    out.mkdir()
    header = ",".join(summaries.SUMMARY_COLUMNS) + "\n"
    (out / "summary.csv").write_text(header)  # what a batch killed before its first unit finished leaves

    seen: list[str] = []
    run_unit = batch.run_unit

    def watching(*args: Any) -> dict[str, Any]:
        seen.append((out / "summary.csv").read_text())  # summary.csv as a kill now would leave it
        return run_unit(*args)

    monkeypatch.setattr(batch, "run_unit", watching)
    assert run(capsys, "batch", src, "--out-dir", out, "--resume", "-q").code == 0
    monkeypatch.setattr(batch, "run_unit", run_unit)
    assert seen[0].count(header) == 1, "summary.csv mid-run has its header twice"

    again = tmp_path / "again"
    again.mkdir()
    (again / "summary.csv").write_text(seen[0])
    r = run(capsys, "batch", src, "--out-dir", again, "--resume", "-q")
    assert r.code == 0, r.err


def test_batch_resume_repairs_a_last_row_cut_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A batch killed (or a disk full) while writing a row leaves it cut short: --resume drops
    it with a note and does that unit again. A cut row before the last is still exit 2."""
    src = units(tmp_path / "units", {"A": "good", "B": "good"})
    full = tmp_path / "full"
    assert run(capsys, "batch", src, "--out-dir", full, "-q").code == 0
    header, row_a, _ = (full / "summary.csv").read_text().splitlines(keepends=True)
    for torn in ("B,0,pa", "B,0,pa\n"):
        out = tmp_path / f"out{len(torn)}"
        out.mkdir()
        shutil.copy(full / cal_name("A"), out / cal_name("A"))  # the calibration its row names
        (out / "summary.csv").write_text(header + row_a + torn)
        r = run(capsys, "batch", src, "--out-dir", out, "--resume")
        assert r.code == 0, r.err
        assert (
            "its last row was cut short (a batch stopped while writing it): dropped, that unit is done again" in r.err
        )
        assert sorted(row["serial"] for row in read_rows(out / "summary.csv")) == ["A", "B"]
    out = tmp_path / "middle"
    out.mkdir()
    (out / "summary.csv").write_text(header + "B,0,pa\n" + row_a)
    r = run(capsys, "batch", src, "--out-dir", out, "--resume")
    assert r.code == 2
    assert "internal error" not in r.err
    assert "line 2" in r.err


# -- --json ----------------------------------------------------------------------------------------


def test_batch_json_matches_summary_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {**MIXED, "E5": "good"})
    out = tmp_path / "out"
    r = run(capsys, "batch", src, "--out-dir", out, "--max-offset", "0.05", "--json")
    assert r.code == 2, r.err
    doc = json.loads(r.out)
    assert list(doc) == ["status", "exit_status", "counts", "summary", "warnings", "units"]
    assert (doc["status"], doc["exit_status"]) == ("error", 2)
    assert doc["summary"] == str(out / "summary.csv")
    assert doc["counts"] == {"pass": 2, "fail": 1, "error": 1, "rejected": 1}

    rows = read_rows(out / "summary.csv")
    assert [u["serial"] for u in doc["units"]] == [row["serial"] for row in rows]
    for u, row in zip(doc["units"], rows, strict=True):
        assert list(u) == ["serial", "status", "exit_status", *summaries.SUMMARY_COLUMNS[2:]]
        # the status a word, as every --json gives it; summary.csv's number beside it
        assert (u["status"], u["exit_status"]) == (row["verdict"], int(row["status"]))
        assert isinstance(u["codes"], list)
        cells = {c: summaries.cell(u | {"status": u["exit_status"]}, c) for c in summaries.SUMMARY_COLUMNS}
        assert {c: unsafe(text) for c, text in cells.items()} == row  # (read_rows takes off a formula's ')
        for c in summaries.NUMBERS:  # numbers as numbers, equal to the CSV's text read back
            assert u[c] is None if row[c] == "" else u[c] == float(row[c])
    assert doc["counts"] == {v: sum(row["verdict"] == v for row in rows) for v in doc["counts"]}
    [failed] = [row for row in rows if row["verdict"] == "fail"]  # why: its limit failures, in its message
    assert failed["message"].startswith(failed["codes"].split(";")[0] + ": ")
    assert all(row["message"] == "" for row in rows if row["verdict"] == "pass")

    # a resumed batch (every unit done) prints the same units, read back from summary.csv
    r = run(capsys, "batch", src, "--out-dir", out, "--limits", LIMITS, "--json", "--resume", "-q")
    assert r.code == 2, r.err
    assert r.err == ""
    assert json.loads(r.out) == doc


def test_batch_json_all_pass_status_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = units(tmp_path / "units", {"A": "good"})
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out", "--json", "-q")
    assert (r.code, r.err) == (0, "")
    doc = json.loads(r.out)
    assert (doc["status"], doc["exit_status"]) == ("pass", 0)
    assert doc["counts"] == {"pass": 1, "fail": 0, "error": 0, "rejected": 0}
    assert doc["units"][0]["file"] == cal_name("A")
    assert doc["units"][0]["message"] is None


# -- a manifest ------------------------------------------------------------------------------------


def manifest_data(folder: Path) -> Path:
    data = folder / "data"
    data.mkdir(parents=True)
    for name in "xyz":
        shutil.copy(SAMPLE / f"{name}.csv", data / f"{name}.csv")
    for face in SIX_FACES:
        shutil.copy(IMUCAL / f"{face}.csv", data / f"{face}.csv")
    return data


def test_batch_manifest_labels_and_relative_paths(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    lot = tmp_path / "lot"
    data = manifest_data(lot)
    manifest = lot / "manifest.csv"
    manifest.write_text(
        "serial,z,y,x\n"  # the header labels its columns: the files are not in x y z order
        "M1,data/z.csv,data/y.csv,data/x.csv\n"
        "# a comment line\n"
        "\n"
        "M2,+y=data/y.csv,+x=data/x.csv,+z=data/z.csv\n"  # a cell's own label wins over its column's
        f"M3,-z={data / 'zn.csv'},+z=data/zp.csv,+x=data/xp.csv,-x=data/xn.csv,+y=data/yp.csv,-y=data/yn.csv\n"
        "M4,data/x.csv,data/y.csv,data/missing.csv\n"
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # files are relative to the manifest, not to the working folder
    r = run(capsys, "batch", "../lot/manifest.csv", "--out-dir", "cals")
    assert r.code == 2, r.err
    rows = by_serial(elsewhere / "cals" / "summary.csv")
    assert sorted(rows) == ["M1", "M2", "M3", "M4"]
    assert rows["M1"]["inputs"].split(";") == [f"+{n}={os.path.join('../lot', 'data', f'{n}.csv')}" for n in "zyx"]
    assert rows["M2"]["inputs"].split(";") == [f"+{n}={os.path.join('../lot', 'data', f'{n}.csv')}" for n in "yxz"]
    assert rows["M3"]["inputs"].split(";")[0] == f"-z={data / 'zn.csv'}"  # an absolute path stays as it is
    assert [rows[s]["verdict"] for s in ["M1", "M2", "M3", "M4"]] == ["pass", "pass", "pass", "error"]
    assert rows["M3"]["method"] == "six-pose"
    assert "missing.csv" in rows["M4"]["message"]
    # M1 solved from labelled files is the same calibration as x y z in order (same serial)
    solo = elsewhere / "m1.json"
    labelled = [f"+{n}=../lot/data/{n}.csv" for n in "zyx"]
    assert run(capsys, "solve", "-q", "--poses", *labelled, "--serial", "M1", "-o", solo).code == 0
    assert (elsewhere / "cals" / cal_name("M1")).read_bytes() == solo.read_bytes()


def test_batch_manifest_unlabelled_columns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Columns headed by other names are unlabelled: as solve takes them, files named for their
    faces take those faces in any order, the others take their faces from their order."""
    lot = tmp_path / "lot"
    data = manifest_data(lot)
    for name in "xyz":
        shutil.copy(data / f"{name}.csv", data / f"pose_{name}.csv")  # named for no face
    manifest = lot / "m.csv"
    manifest.write_text(
        "serial,first,second,third\nOK,data/x.csv,data/y.csv,data/z.csv\nNAMED,data/z.csv,data/y.csv,data/x.csv\n"
        "BAD,data/pose_z.csv,data/pose_y.csv,data/pose_x.csv\n"
    )
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out", "-q")
    assert r.code == 3, r.err
    rows = by_serial(tmp_path / "out" / "summary.csv")
    assert rows["OK"]["inputs"].split(";") == [str(lot / "data" / f"{n}.csv") for n in "xyz"]
    assert [rows[s]["verdict"] for s in ("OK", "NAMED", "BAD")] == ["pass", "pass", "rejected"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        pytest.param(
            "serial,x,y,z\nA,data/x.csv,data/y.csv,data/z.csv\nB,data/x.csv,data/y.csv,data/z.csv\n"
            "A,data/x.csv,data/y.csv,data/z.csv\n",
            "serial A is also on line 2 (line 4, column 1)",
            id="duplicate-serial",
        ),
        pytest.param(
            "serial,x,y,z\n# comment\nA,data/x.csv,data/y.csv,data/z.csv\n\nA,data/x.csv,data/y.csv,data/z.csv\n",
            "serial A is also on line 3 (line 5, column 1)",
            id="duplicate-serial-after-comments",
        ),
        pytest.param(
            "A,data/x.csv,data/y.csv,data/z.csv\n",
            "a manifest starts with a header whose first column is 'serial' (line 1)",
            id="no-header",
        ),
        pytest.param(
            "unit,x,y,z\nA,data/x.csv,data/y.csv,data/z.csv\n",
            "a manifest starts with a header whose first column is 'serial' (line 1)",
            id="wrong-header",
        ),
        pytest.param(
            "serial,x,y,z\n../A,data/x.csv\n", "serial '../A' cannot name a file (line 2, column 1)", id="bad-serial"
        ),
        pytest.param(  # a raw NUL went to stderr on the unit's line
            "serial,x,y,z\nSN\x001,data/x.csv\n",
            "serial 'SN\\x001' holds a control character (line 2, column 1)",
            id="control-character",
        ),
        pytest.param(  # 'File name too long', and a hint to run it again with --resume
            "serial,x,y,z\n" + "A" * 300 + ",data/x.csv\n",
            "serial of 300 bytes: a file is named after it (at most 200) (line 2, column 1)",
            id="long-serial",
        ),
    ],
)
def test_batch_bad_manifest_is_exit_2_before_any_unit(
    text: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lot = tmp_path / "lot"
    manifest_data(lot)
    manifest = lot / "m.csv"
    manifest.write_text(text)
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert r.code == 2
    assert r.out == ""
    assert r.err.splitlines()[0] == f"error: {manifest}: {message}"
    assert not (tmp_path / "out").exists()


def test_batch_manifest_row_without_files_is_that_units_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A row with a serial and no files does not stop the lot: it is that unit's row, status 2."""
    src = units(tmp_path / "units", {"A": "good"})
    manifest = tmp_path / "m.csv"
    files = ",".join(str(src / "A" / f"{n}.csv") for n in "xyz")
    manifest.write_text(f"serial,x,y,z\nA,{files}\nB\n")
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert r.code == 2
    rows = by_serial(tmp_path / "out" / "summary.csv")
    assert (rows["A"]["status"], rows["B"]["status"]) == ("0", "2")
    assert rows["B"]["message"] == "no files on its row of the manifest (line 3)"


# -- --log: one log per unit -----------------------------------------------------------------------


def test_batch_log_mode_on_the_sample_session(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    logs = tmp_path / "logs"
    (logs / "S2").mkdir(parents=True)
    (logs / "S3").mkdir()
    shutil.copy(SESSION, logs / "S1.csv")  # UNITS/<serial>.csv
    shutil.copy(SESSION, logs / "S2" / "session.csv")  # UNITS/<serial>/<log>.csv
    shutil.copy(SESSION, logs / "S3" / "a.csv")  # two logs: that unit's error
    shutil.copy(SESSION, logs / "S3" / "b.csv")
    out = tmp_path / "out"
    r = run(capsys, "batch", logs, "--log", *LOG_OPTIONS, "--out-dir", out)
    assert r.code == 2, r.err
    rows = by_serial(out / "summary.csv")
    assert sorted(rows) == ["S1", "S2", "S3"]
    assert [rows[s]["verdict"] for s in ["S1", "S2"]] == ["pass", "pass"]
    assert rows["S1"]["method"] == "six-pose"
    assert rows["S1"]["inputs"] == str(logs / "S1.csv")
    assert rows["S2"]["inputs"] == str(logs / "S2" / "session.csv")
    assert (rows["S3"]["status"], rows["S3"]["verdict"], rows["S3"]["file"]) == ("2", "error", "")
    assert "one log per unit" in rows["S3"]["message"]

    solo = tmp_path / "s1.json"
    r = run(capsys, "solve", "-q", "--log", logs / "S1.csv", *LOG_OPTIONS, "--serial", "S1", "-o", solo)
    assert r.code == 0, r.err
    assert (out / cal_name("S1")).read_bytes() == solo.read_bytes()
    for serial in ["S1", "S2"]:  # same log, same numbers
        assert rows[serial]["offset_x"] == rows["S1"]["offset_x"]


def test_batch_log_serial_both_folder_and_file_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    logs = tmp_path / "logs"
    (logs / "S1").mkdir(parents=True)
    shutil.copy(SESSION, logs / "S1.csv")
    shutil.copy(SESSION, logs / "S1" / "session.csv")
    r = run(capsys, "batch", logs, "--log", *LOG_OPTIONS, "--out-dir", tmp_path / "out")
    assert r.code == 2
    assert "serial S1 is both a folder and a log file" in r.err
    assert not (tmp_path / "out").exists()


# -- --jobs ----------------------------------------------------------------------------------------


@pytest.mark.slow
def test_batch_jobs_2_is_byte_identical_to_jobs_1(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    units(tmp_path / "units", {"A": "good", "B": "six", "C": "rejected", "D": "error", "E": "good", "F": "six"})
    scratch = tmp_path / "scratch"  # the worker pool's own temporary folder goes here, and must go
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    one = run_exe(["batch", "units", "--out-dir", "one", "--max-offset", "0.05", "-q"], cwd=tmp_path, text=True)
    two = run_exe(
        ["batch", "units", "--out-dir", "two", "--max-offset", "0.05", "-q", "--jobs", "2"], cwd=tmp_path, text=True
    )
    assert (one.returncode, one.stdout, two.returncode, two.stdout) == (2, "", 2, "")
    # -q: only the units with an error or a rejected capture, one line each
    assert [line.split(":")[0] for line in one.stderr.splitlines()] == ["C", "D"]
    assert sorted(two.stderr.splitlines()) == sorted(one.stderr.splitlines())
    first, second = snapshot(tmp_path / "one"), snapshot(tmp_path / "two")
    assert sorted(first) == sorted([*(cal_name(s) for s in "ABEF"), "summary.csv"])
    assert second == first
    assert list(scratch.iterdir()) == []


# -- options -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("options", "message"),
    [
        pytest.param(["--reference", "-1"], "--reference must be a positive number, got -1", id="reference"),
        pytest.param(["--max-noise", "0"], "--max-noise must be positive, got 0", id="max-noise"),
        pytest.param(["--limits", "MISSING"], "MISSING: no such limits file", id="limits-missing"),
        pytest.param(["--max-offset", "1,2"], "--max-offset", id="max-offset-two-values"),
        pytest.param(["--jobs", "0"], "--jobs", id="jobs-0"),
        pytest.param(["--jobs", "99999999999999999999999"], "--jobs", id="jobs-huge"),  # was OverflowError
        pytest.param(["--method", "bogus"], "--method", id="method"),
        pytest.param(["--up", "up"], "--up", id="up"),
    ],
)
def test_batch_bad_option_is_exit_2_before_any_unit(
    options: list[str],
    message: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def no_unit(*args: Any) -> dict[str, Any]:
        raise AssertionError("a unit was run")

    monkeypatch.setattr(batch, "run_unit", no_unit)
    src = units(tmp_path / "units", {"A": "good"})
    out = tmp_path / "out"
    missing = tmp_path / "nope.yaml"
    r = run(capsys, "batch", src, "--out-dir", out, *[o.replace("MISSING", str(missing)) for o in options])
    assert r.code == 2, r.err
    assert r.out == ""
    first = r.err.splitlines()[0]
    assert first.startswith("error: ")
    assert message.replace("MISSING", str(missing)) in first
    assert not out.exists(), "no summary, not even the folder"


def test_batch_help_lists_solve_options(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    r = run(capsys, "batch", "--help")
    assert r.code == 0
    text = r.out + r.err
    for option in [
        "--out-dir",
        "--log",
        "--jobs",
        "--resume",
        "--dask-scheduler",
        "--json",
        "--limits",
        "--max-noise",
        "--reference",
        "--max-offset",
        "--max-gain-error",
        "--nominal-gain",
        "--method",
        "--max-tilt",
        "--rate",
        "--station",
        "--meta",
    ]:
        assert option in text, option
    for own in ["--poses", "--serial", "--output"]:  # each unit's own: not the batch's
        assert own not in text, own


def test_batch_dask_without_distributed_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    src = units(tmp_path / "units", {"A": "good"})
    out = tmp_path / "out"
    r = run(capsys, "batch", src, "--out-dir", out, "--dask-scheduler", "tcp://127.0.0.1:8786")
    assert r.code == 2
    assert r.out == ""
    assert "error: --dask-scheduler needs" in r.err
    assert "pip install 'tumblecal[dask]'" in r.err
    assert not out.exists()


# -- apply over many captures ------------------------------------------------------------------------


@pytest.fixture
def calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    path = tmp_path / "cal.json"
    r = run(capsys, "solve", "-q", "--poses", *(SAMPLE / f"{n}.csv" for n in "xyz"), "-o", path)
    assert r.code == 0, r.err
    return path


def captures(folder: Path) -> list[Path]:
    """Three captures: the sample, its first 100 rows, and its last 50 rows (with the header)."""
    folder.mkdir(parents=True)
    lines = (SAMPLE / "capture.csv").read_text().splitlines(keepends=True)
    paths = [folder / "c1.csv", folder / "c2.csv", folder / "c3.csv"]
    paths[0].write_text("".join(lines))
    paths[1].write_text("".join(lines[:101]))
    paths[2].write_text("".join([lines[0], *lines[-50:]]))
    return paths


def one_by_one(capsys: pytest.CaptureFixture[str], cal: Path, capture: Path, output: Path) -> bytes:
    r = run(capsys, "apply", "-q", "--cal", cal, capture, "-o", output)
    assert r.code == 0, r.err
    return output.read_bytes()


def test_apply_glob_into_out_dir(tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path) -> None:
    paths = captures(tmp_path / "caps")
    (tmp_path / "caps" / "notes.txt").write_text("not a capture\n")
    out = tmp_path / "corrected"
    r = run(capsys, "apply", "--cal", calibration, str(tmp_path / "caps" / "*.csv"), "--out-dir", out)
    assert r.code == 0, r.err
    assert r.out == ""
    assert sorted(os.listdir(out)) == ["c1.csv", "c2.csv", "c3.csv"]
    for p in paths:
        assert (out / p.name).read_bytes() == one_by_one(capsys, calibration, p, tmp_path / f"one_{p.name}")
        assert f"corrected {p} -> {out / p.name}" in r.err
    assert (out / "c2.csv").read_text().count("\n") == 101


def test_apply_several_files_into_out_dir(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    paths = captures(tmp_path / "caps")
    out = tmp_path / "new" / "corrected"  # created, parents too
    r = run(capsys, "apply", "-q", "--cal", calibration, paths[2], paths[0], "--out-dir", out)
    assert (r.code, r.out, r.err) == (0, "", "")
    assert sorted(os.listdir(out)) == ["c1.csv", "c3.csv"]
    for p in [paths[0], paths[2]]:
        assert (out / p.name).read_bytes() == one_by_one(capsys, calibration, p, tmp_path / f"one_{p.name}")


def test_apply_one_capture_with_out_dir(tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path) -> None:
    paths = captures(tmp_path / "caps")
    r = run(capsys, "apply", "-q", "--cal", calibration, paths[1], "--out-dir", tmp_path / "out")
    assert r.code == 0, r.err
    assert (tmp_path / "out" / "c2.csv").read_bytes() == one_by_one(capsys, calibration, paths[1], tmp_path / "o.csv")


def test_apply_duplicate_basenames_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    captures(tmp_path / "caps")
    (tmp_path / "caps" / "sub").mkdir()
    shutil.copy(SAMPLE / "capture.csv", tmp_path / "caps" / "sub" / "c1.csv")
    out = tmp_path / "out"
    r = run(capsys, "apply", "--cal", calibration, str(tmp_path / "caps" / "**" / "c1.csv"), "--out-dir", out)
    assert r.code == 2
    assert r.out == ""
    first = r.err.splitlines()[0]
    assert first == (
        f"error: {tmp_path / 'caps' / 'c1.csv'} and {tmp_path / 'caps' / 'sub' / 'c1.csv'} "
        f"would both be written to {out / 'c1.csv'}"
    )
    assert not out.exists()


def test_apply_several_without_out_dir_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    paths = captures(tmp_path / "caps")
    before = snapshot(tmp_path)
    r = run(capsys, "apply", "--cal", calibration, paths[0], paths[1])
    assert r.code == 2
    assert r.out == ""
    assert (
        r.err.splitlines()[0] == "error: 2 captures need --out-dir DIR (each is corrected into DIR under its own name)"
    )
    r = run(capsys, "apply", "--cal", calibration, str(tmp_path / "caps" / "*.csv"), "-o", tmp_path / "one.csv")
    assert r.code == 2
    assert "3 captures need --out-dir" in r.err
    assert snapshot(tmp_path) == before


def test_apply_glob_matching_nothing_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    pattern = str(tmp_path / "caps" / "*.csv")
    r = run(capsys, "apply", "--cal", calibration, pattern, "--out-dir", tmp_path / "out")
    assert r.code == 2
    assert r.err.splitlines()[0] == f"error: no file matches {pattern}"
    assert not (tmp_path / "out").exists()


def test_apply_one_bad_capture_among_good_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    paths = captures(tmp_path / "caps")
    bad = tmp_path / "caps" / "c0_bad.csv"
    bad.write_text("foo,bar\n1,2\n")
    out = tmp_path / "out"
    r = run(capsys, "apply", "--cal", calibration, str(tmp_path / "caps" / "*.csv"), "--out-dir", out)
    assert r.code == 2
    assert r.out == ""
    errors = [line for line in r.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 2, r.err
    assert errors[0].startswith(f"error: {bad}: ")
    assert errors[1] == f"error: 1 of 4 captures failed (above); the others are in {out}"
    assert sorted(os.listdir(out)) == ["c1.csv", "c2.csv", "c3.csv"]  # the bad one not written, no leftovers
    for p in paths:
        assert (out / p.name).read_bytes() == one_by_one(capsys, calibration, p, tmp_path / f"one_{p.name}")
    alone = run(capsys, "apply", "--cal", calibration, bad, "--out-dir", tmp_path / "alone")
    assert alone.err.splitlines()[-1] == "error: 1 of 1 capture failed (above)"  # no others to point at
    assert not (tmp_path / "alone").exists()  # the folder it made for them is not left empty


def test_apply_many_never_replaces_a_file_in_the_out_dir(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    """A file of that name already in --out-dir (an earlier output, or a raw capture) is one
    error before any capture is corrected: nothing is replaced, nothing written."""
    paths = captures(tmp_path / "caps")
    out = tmp_path / "out"
    out.mkdir()
    (out / "c2.csv").write_text("a raw capture of someone else's\n")
    r = run(capsys, "apply", "--cal", calibration, *paths, "--out-dir", out)
    assert r.code == 2
    assert r.err.splitlines()[0] == f"error: {out / 'c2.csv'}: already exists: --out-dir never replaces a file"
    assert (out / "c2.csv").read_text() == "a raw capture of someone else's\n"
    assert sorted(os.listdir(out)) == ["c2.csv"]


def test_apply_many_refuses_o_with_out_dir(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    paths = captures(tmp_path / "caps")
    r = run(capsys, "apply", "--cal", calibration, *paths, "--out-dir", tmp_path / "out", "-o", tmp_path / "x.csv")
    assert r.code == 2
    assert "-o names one output" in r.err
    assert not (tmp_path / "out").exists()
    assert not (tmp_path / "x.csv").exists()


def test_apply_dask_without_distributed_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    captures(tmp_path / "caps")
    out = tmp_path / "out"
    pattern = str(tmp_path / "caps" / "*.csv")
    r = run(
        capsys, "apply", "--cal", calibration, pattern, "--out-dir", out, "--dask-scheduler", "tcp://127.0.0.1:8786"
    )
    assert r.code == 2
    assert r.out == ""
    assert "pip install 'tumblecal[dask]'" in r.err
    assert not out.exists()


def test_apply_dask_without_out_dir_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], calibration: Path
) -> None:
    paths = captures(tmp_path / "caps")
    r = run(capsys, "apply", "--cal", calibration, paths[0], "--dask-scheduler", "tcp://127.0.0.1:8786")
    assert r.code == 2
    assert r.err.splitlines()[0] == "error: --dask-scheduler corrects captures into --out-dir DIR"


def test_batch_folder_of_labelled_and_unlabelled_names_is_that_units_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """x.csv b.csv z.csv: two names are faces and one is not; the poses are the face-named
    files (b.csv is ignored with a note), and two faces are that unit's input error, not a
    guess at the order."""
    src = units(tmp_path / "units", {"A": "good"})
    mixed = src / "M"
    mixed.mkdir()
    for name, face in (("x", "x"), ("b", "y"), ("z", "z")):
        shutil.copy(SAMPLE / f"{face}.csv", mixed / f"{name}.csv")
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out")
    assert r.code == 2
    row = {row["serial"]: row for row in read_rows(tmp_path / "out" / "summary.csv")}["M"]
    assert (row["status"], row["verdict"]) == ("2", "error")
    assert row["message"].startswith("--poses: no face on the y axis: add +y or -y (faces given: +x +z)")  # b.csv
    assert f"note: {mixed}: b.csv ignored (not named by a face like the unit's other files)" in r.err


def test_batch_bad_source_date_epoch_is_one_error_before_any_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    src = units(tmp_path / "units", {"A": "good", "B": "good"})
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "abc")
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "out")
    assert r.code == 2
    assert r.err.splitlines()[0] == "error: SOURCE_DATE_EPOCH='abc' is not a whole number of seconds since 1970"
    assert not (tmp_path / "out").exists()


def test_batch_progress_bar_on_a_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a terminal: a progress bar (units done / total), the failing units printed above it,
    the passing ones not listed; in a log (not a terminal) one line per unit and no bar."""
    import io

    from rich.console import Console

    from tumblecal_cli.cli import render

    screen = io.StringIO()
    monkeypatch.setattr(
        render, "make_console", lambda stderr=True: Console(file=screen, force_terminal=True, width=100)
    )
    src = units(tmp_path / "units", {"A": "good", "B": "rejected", "C": "good"})
    assert run(capsys, "batch", src, "--out-dir", tmp_path / "tty").code == 3
    text = screen.getvalue()
    assert "3/3" in text
    assert "B: rejected (pose.orientation)" in text
    assert "A: pass" not in text
    assert "3 units: 2 pass, 1 rejected" in text

    monkeypatch.undo()
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "log")
    assert "3/3" not in r.err
    assert [line.split(":")[0] for line in r.err.splitlines() if line[:1] in "ABC"] == ["A", "B", "C"]


def test_batch_log_serial_keeps_its_dots_and_earlier_outputs_are_not_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    session = SAMPLE / "imucal" / "session_every4th.csv"
    shutil.copy(session, logs / "SN-1.0042.csv")
    args = ["--log", "--rate", "25.6", "--reference", "9.81", "-q"]
    assert run(capsys, "batch", logs, "--out-dir", logs / "first", *args).code == 0
    assert [r["serial"] for r in read_rows(logs / "first" / "summary.csv")] == ["SN-1.0042"]
    # a second batch over the same folder: the first one's output folder (it has a summary) is not a unit
    r = run(capsys, "batch", logs, "--out-dir", logs / "second", "--log", "--rate", "25.6", "--reference", "9.81")
    assert r.code == 0, r.err
    assert [r["serial"] for r in read_rows(logs / "second" / "summary.csv")] == ["SN-1.0042"]
    assert "a batch's output folder" in r.err


def test_batch_manifest_from_a_spreadsheet(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A byte-order mark, CRLF line ends and ';' separators; 'x=' labels as '+x='."""
    for name in ("x", "y", "z"):
        shutil.copy(SAMPLE / f"{name}.csv", tmp_path / f"{name}.csv")
    manifest = tmp_path / "lot.csv"
    manifest.write_bytes(b"\xef\xbb\xbfserial;a;b;c\r\nM1;z=z.csv;x=x.csv;y=y.csv\r\n")
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out", "-q")
    assert r.code == 0, r.err
    (row,) = read_rows(tmp_path / "out" / "summary.csv")
    assert (row["serial"], row["verdict"]) == ("M1", "pass")
    assert row["inputs"].split(";") == [f"+{n}={tmp_path / f'{n}.csv'}" for n in "zxy"]


@pytest.mark.slow
def test_batch_stopped_by_sigterm_leaves_no_calibration_without_a_row(tmp_path: Path) -> None:
    """SIGTERM mid-batch (--jobs 2): every calibration written has its row, no staging file is
    left, and --resume finishes the lot with exactly one calibration per unit."""
    import signal
    import time

    src = units(tmp_path / "units", {f"U{k:03d}": "good" for k in range(80)})
    out = tmp_path / "out"
    env = {**os.environ, "NO_COLOR": "1"}
    argv = [tumblecal_exe(), "batch", str(src), "--out-dir", str(out), "--jobs", "2", "-q"]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    summary = out / "summary.csv"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and (not summary.exists() or summary.read_text().count("\n") < 6):
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode in (130, 0), err  # 0 if it finished first
    rows = read_rows(summary)
    files = sorted(p.name for p in out.iterdir() if p.name != "summary.csv")
    assert files == sorted(row["file"] for row in rows)  # no calibration without its row, no staging file
    r = subprocess.run([*argv, "--resume"], env=env, capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    rows = read_rows(summary)
    assert sorted(row["serial"] for row in rows) == sorted(f"U{k:03d}" for k in range(80))
    assert len([p for p in out.iterdir() if p.suffix == ".json"]) == 80


def test_a_stop_just_after_publishing_waits_for_the_row(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C arriving between a calibration's link and its summary row (the race a SIGTERM hit
    in CI) is held until the row is written: the batch stops, but no calibration lacks its row."""
    import signal

    src = units(tmp_path / "units", {f"U{k}": "good" for k in range(3)})
    out = tmp_path / "out"
    publish = batch.publish

    def publish_then_stop(*args: Any) -> str:
        name = publish(*args)
        signal.raise_signal(signal.SIGINT)  # delivered at once, were it not held
        return name

    monkeypatch.setattr(batch, "publish", publish_then_stop)
    with pytest.raises(KeyboardInterrupt):
        batch.run_batch(str(src), str(out))
    rows = read_rows(out / "summary.csv")
    files = sorted(p.name for p in out.iterdir() if p.name != "summary.csv")
    assert len(rows) == 1
    assert files == [rows[0]["file"]]


def test_held_signals_act_after_the_block_and_are_put_back() -> None:
    import signal

    seen: list[str] = []

    def stop(signum: int, frame: Any) -> None:
        seen.append("handler")
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, stop)
    try:

        def two_stops_in_a_block() -> None:
            with batch.held_signals():
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGINT)
                seen.append("block done")

        with pytest.raises(KeyboardInterrupt):
            two_stops_in_a_block()
        assert seen == ["block done", "handler"]
        assert signal.getsignal(signal.SIGINT) is stop
    finally:
        signal.signal(signal.SIGINT, previous)


def test_held_signals_put_every_handler_back_whenever_a_stop_lands(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop landing while the handlers are swapped in (a SIGTERM the CLI turns into an
    exception) or put back (a Ctrl-C) leaves none of the holding ones behind: they would
    swallow every later Ctrl-C or SIGTERM."""
    import signal

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    real = signal.signal
    previous = real(signal.SIGTERM, stop)
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        for moment, sent in (("swapping in", signal.SIGTERM), ("putting back", signal.SIGINT)):

            def swap_then_stop(signum: int, handler: Any, moment: str = moment, sent: int = sent) -> Any:
                old = real(signum, handler)
                swapping_in = handler not in before.values()
                if signum == signal.SIGINT and swapping_in == (moment == "swapping in"):
                    signal.raise_signal(sent)  # acted on at the next bytecode
                return old

            monkeypatch.setattr(signal, "signal", swap_then_stop)
            with pytest.raises(KeyboardInterrupt), batch.held_signals():
                pass
            monkeypatch.setattr(signal, "signal", real)
            assert {s: signal.getsignal(s) for s in before} == before, moment
    finally:
        real(signal.SIGTERM, previous)


def test_a_block_that_fails_is_told_though_a_stop_was_held() -> None:
    import signal

    def full_disk() -> None:
        with batch.held_signals():
            signal.raise_signal(signal.SIGINT)
            raise InputError("no space left on device")

    with pytest.raises(InputError, match="no space"):
        full_disk()


@pytest.mark.slow
def test_batch_reads_a_manifest_from_stdin(tmp_path: Path) -> None:
    """`tumblecal batch - < manifest.csv`: its files are relative to the working folder."""
    manifest = (SAMPLE / "lot.csv").read_text()
    out = tmp_path / "out"
    env = {**os.environ, "NO_COLOR": "1", "SOURCE_DATE_EPOCH": "1795251600"}
    piped = subprocess.run(
        [tumblecal_exe(), "batch", "-", "--out-dir", str(out), "-q"],
        input=manifest, capture_output=True, text=True, cwd=SAMPLE, env=env, timeout=60, check=False,
    )  # fmt: skip
    named = subprocess.run(
        [tumblecal_exe(), "batch", str(SAMPLE / "lot.csv"), "--out-dir", str(tmp_path / "named"), "-q"],
        capture_output=True, text=True, env=env, timeout=60, check=False,
    )  # fmt: skip
    assert piped.returncode == named.returncode == 2  # lot.csv holds a unit with a missing file
    rows = {r["serial"]: r for r in read_rows(out / "summary.csv")}
    named_rows = {r["serial"]: r for r in read_rows(tmp_path / "named" / "summary.csv")}
    assert {s: r["status"] for s, r in rows.items()} == {s: r["status"] for s, r in named_rows.items()}
    assert rows["SN0001"]["offset_x"] == named_rows["SN0001"]["offset_x"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "stdin", "message"),
    [
        (["-", "--out-dir", "OUT"], "serial,x,y,z\n", "error: -: the manifest lists no units, only its header"),
        (
            ["MANIFEST", "--out-dir", "-"],
            "",
            "error: --out-dir takes a folder: the calibrations are files, not a stream",
        ),
    ],
    ids=["empty-manifest-on-stdin", "out-dir-stdout"],
)
def test_batch_stdin_and_stdout_usage_errors(tmp_path: Path, args: list[str], stdin: str, message: str) -> None:
    argv = [str(SAMPLE / "lot.csv") if a == "MANIFEST" else str(tmp_path / "out") if a == "OUT" else a for a in args]
    r = subprocess.run(
        [tumblecal_exe(), "batch", *argv], input=stdin, capture_output=True, text=True, cwd=tmp_path, timeout=60,
        check=False,
    )  # fmt: skip
    assert r.returncode == 2
    assert r.stderr.splitlines()[0].startswith(message)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_sigterm_while_applying_stops_the_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """apply over many captures: an interrupted file is not a failed one, the run stops."""
    from tumblecal_cli.errors import Interrupted
    from tumblecal_cli.pipeline import apply as correct

    def interrupted(*_: Any, **__: Any) -> None:
        raise Interrupted("interrupted (SIGTERM)")

    monkeypatch.setattr(correct, "correct", interrupted)
    with pytest.raises(Interrupted):
        correct.correct_one({}, "c.csv", "out/c.csv")


# -- the same pose file under two serials ----------------------------------------------------------


def test_batch_flags_the_same_pose_file_under_two_serials(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A and B hold copies of the same x, y, z captures (one unit's files given as another's);
    C has its own. Each is calibrated, and summary.csv, --json and a warning say which share."""
    src = units(tmp_path / "units", {"A": "good", "B": "good", "C": "six"})
    out = tmp_path / "out"
    r = run(capsys, "batch", src, "--out-dir", out, "--json")
    assert r.code == 0, r.err
    rows = by_serial(out / "summary.csv")
    assert {s: row["duplicate_of"] for s, row in rows.items()} == {"A": "B", "B": "A", "C": ""}
    warnings = [ln for ln in r.err.splitlines() if ln.startswith("warning:")]
    a, b = (", ".join(str(src / serial / f"{axis}.csv") for axis in "xyz") for serial in "AB")
    assert warnings == [
        f"warning: A and B record the same 3 pose files: A: {a}; B: {b}: at most one of them measured that unit"
    ]
    doc = json.loads(r.out)
    assert [(u["serial"], u["duplicate_of"]) for u in doc["units"]] == [("A", ["B"]), ("B", ["A"]), ("C", None)]
    assert doc["warnings"] == [w.removeprefix("warning: ") for w in warnings]


def test_batch_resume_flags_a_duplicate_of_a_unit_done_before(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A unit done in an earlier run (its poses read back from its calibration) and one added
    later from the same captures; an earlier version's summary (no duplicate_of) resumes too."""
    src = units(tmp_path / "units", {"A": "good"})
    out = tmp_path / "out"
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 0
    summary = out / "summary.csv"
    earlier = [line.rsplit(",", 1)[0] for line in summary.read_text().splitlines()]  # without duplicate_of
    assert earlier[0] == ",".join(summaries.SUMMARY_COLUMNS[:-1])
    summary.write_text("\n".join(earlier) + "\n")
    unit(src, "B", "good")
    r = run(capsys, "batch", src, "--out-dir", out, "--resume")
    assert r.code == 0, r.err
    assert {s: row["duplicate_of"] for s, row in by_serial(summary).items()} == {"A": "B", "B": "A"}
    assert "warning: A and B record the same 3 pose files" in r.err


def test_duplicates_are_by_content_across_serials() -> None:
    from tumblecal_cli.core import lot

    found = lot.duplicates(
        [
            ("A", "h1", "a/x.csv"),
            ("A", "h1", "a/x.csv"),  # A calibrated twice from its own file: not a duplicate
            ("B", "h2", "b/x.csv"),
            ("C", "h2", "c/x.csv"),
            (None, "h2", "x.csv"),  # no serial: nothing to compare
            ("D", None, "d/x.csv"),
        ]
    )
    assert [(d.sha256, d.uses) for d in found] == [("h2", (("B", "b/x.csv"), ("C", "c/x.csv")))]
    assert lot.duplicate_of(found) == {"B": ["C"], "C": ["B"]}


def test_a_serial_of_200_bytes_and_an_output_name_of_250(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The longest serial the manifest takes, and a plain -o name near the file system's 255
    bytes, failed 'File name too long': the temporary file's name added its own ~40 bytes."""
    src = units(tmp_path / "units", {"A": "good"})
    files = ",".join(str(src / "A" / f"{n}.csv") for n in "xyz")
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"serial,x,y,z\n{'S' * 200},{files}\n")
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out", "-q")
    assert r.code == 0, r.err
    assert any(p.name.startswith("S" * 200) for p in (tmp_path / "out").iterdir())
    named = tmp_path / f"{'L' * 250}.json"
    assert run(capsys, "solve", "-q", "-p", *(src / "A" / f"{n}.csv" for n in "xyz"), "-o", named).code == 0
    assert named.exists()
