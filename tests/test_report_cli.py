"""tumblecal report from the command line, on sample_data/lot (tests/make_sample_lot.py: 30 units with
known truth, SN0013's x offset 0.07 g, SN0007 re-calibrated with its y offset moved 0.015 g)."""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.conftest import IMUCAL, POSES_3, SAMPLE, feed_stdin, run, tumblecal_exe

ROOT = Path(__file__).resolve().parent.parent
LOT = ROOT / "sample_data" / "lot"
LIMITS = ROOT / "sample_data" / "limits.yaml"


def rows(out: str) -> dict[str, dict[str, str]]:
    return {r["parameter"]: r for r in csv.DictReader(io.StringIO(out))}


def test_report_csv_on_stdout_table_on_stderr(capsys: pytest.CaptureFixture[str]) -> None:
    # 30 units are judged at the default --outlier-alpha, the power said (docs/lot-report.md)
    code, out, err = run(capsys, "report", str(LOT), "--limits", str(LIMITS))
    assert code == 1, err  # SN0013 is outside the limits, and an outlier
    assert rows(out)["offset.x"]["outliers"] == "SN0013=7.4"
    assert rows(out)["offset.x"]["outlier_rule"] == "|t|>5 (alpha 0.005 over 180)"
    assert (
        "outliers: |t| > 5 vs the other units (false alarms 0.005 per lot, 180 unit-figures; a unit 6σ off, "
        "in a lot this size, caught 91% of the time)"
    ) in err
    code, out, err = run(capsys, "report", str(LOT), "--limits", str(LIMITS), "--outlier-alpha", "0.05")
    table = rows(out)
    assert code == 1, err  # SN0013 is an outlier
    assert table["offset.x"]["outlier_rule"] == "|t|>4.14 (alpha 0.05 over 180)"
    assert list(table) == ["offset.x", "offset.y", "offset.z", "gain.x", "gain.y", "gain.z"]
    x = table["offset.x"]
    assert x["count"] == "30"  # 31 files, SN0007 counted once
    assert float(x["max"]) == pytest.approx(0.07, abs=3e-4)
    assert (x["lower"], x["upper"]) == ("-0.05", "0.05")
    assert x["outliers"].startswith("SN0013=")
    assert float(table["gain.y"]["mean"]) == pytest.approx(1.0, abs=0.003)  # truth: N(1, 0.004)
    assert "lot of 30 units (31 files)" in err
    assert "outlier: SN0013: offset.x" in err
    assert "give --max-drift to flag changes" in err


def test_report_drift_is_flagged_with_max_drift(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "report", str(LOT), "--max-drift", "offset=0.01,gain=0.002", "--json")
    doc = json.loads(out)
    assert code == 1
    flagged = [d for d in doc["drift"] if d["flagged"]]
    assert [(d["serial"], d["parameter"]) for d in flagged] == [("SN0007", "offset.y")]
    assert flagged[0]["change"] == pytest.approx(0.015, abs=3e-4)  # truth 0.015, noise 0.002/sqrt(200)
    assert "SN0007: offset.y changed +0.015" in err
    assert doc["units"] == 30
    assert doc["files"] == 31


def test_report_in_order_exits_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Without the outlier and with a drift limit the re-calibration stays within, the lot is in order."""
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    for path in lot.glob("SN0013_*.json"):
        path.unlink()
    args = ["report", str(lot), "--limits", str(LIMITS), "--max-drift", "offset=0.02", "--min-cpk", "1.0"]
    code, _, err = run(capsys, *args)
    assert code == 0, err
    assert "lot: in order" in err


def test_report_min_cpk(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "report", str(LOT), "--limits", str(LIMITS), "--min-cpk", "1.33", "--json")
    doc = json.loads(out)
    assert code == 1
    low = [p["parameter"] for p in doc["parameters"] if p["cpk"] is not None and p["cpk"] < 1.33]
    assert "offset.x" in low  # the outlier widens it


def test_report_unreadable_file_is_exit_2_after_the_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    (lot / "broken.json").write_text('{"format": "tumblecal-calibration",')
    (lot / ".SN0099.abc.partial.json").write_text("staging: ignored")
    code, out, err = run(capsys, "report", str(lot))
    assert code == 2
    assert rows(out)["offset.x"]["count"] == "30"  # the report is still printed
    assert f"error: {lot / 'broken.json'}: not valid JSON" in err
    assert "the report leaves out the 1 of 32 files that could not be read" in err
    assert "partial" not in err

    # --json: one document, the report of the files read, its status the word for exit 2
    code, out, err = run(capsys, "report", str(lot), "--json")
    assert code == 2
    doc = json.loads(out)  # one JSON document: no error object after the report
    assert (doc["status"], doc["exit_status"]) == ("error", 2)
    assert doc["unreadable"][0]["file"] == str(lot / "broken.json")
    assert f"error: {lot / 'broken.json'}: not valid JSON" in err


def test_report_json_needing_attention_is_fail(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "report", str(LOT), "--json", "--outlier-alpha", "0.05")  # the lot has an outlier
    assert r.code == 1
    doc = json.loads(r.out)
    assert list(doc)[:2] == ["status", "exit_status"]
    assert (doc["status"], doc["exit_status"]) == ("fail", 1)


def test_report_json_in_order_is_pass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    for path in lot.glob("SN0013_*.json"):
        path.unlink()
    r = run(capsys, "report", str(lot), "--max-drift", "offset=0.02", "--json")
    assert r.code == 0, r.err
    assert (json.loads(r.out)["status"], json.loads(r.out)["exit_status"]) == ("pass", 0)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--max-drift", "0.01"], "--max-drift offset=0.01,gain=0.002"),
        (["--max-drift", "speed=1"], "--max-drift"),
        (["--min-cpk", "0"], "--min-cpk must be a positive number"),
        (["--min-cpk", "1.33"], "--min-cpk needs --limits"),
        (["--plot", "-"], "--plot - would share stdout"),
        (["--plot", "lot.svg"], "give a file name ending in .png"),
        (["--limits", "missing.yaml"], "missing.yaml"),
    ],
)
def test_report_usage_errors(capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    code, out, err = run(capsys, "report", str(LOT), *args)
    assert (code, out) == (2, "")
    assert message in err


def test_report_no_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "report", str(tmp_path))
    assert (code, out) == (2, "")
    assert "no calibration files" in err
    code, _, err = run(capsys, "report", str(tmp_path / "nope"))
    assert code == 2
    assert "nope" in err


def test_report_flags_units_outside_the_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No outlier and no drift, but limits tighter than the lot: the units beyond them are named."""
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    for path in lot.glob("SN0013_*.json"):
        path.unlink()
    tight = tmp_path / "tight.yaml"
    tight.write_text("offset: 0.02\n")
    code, out, err = run(capsys, "report", str(lot), "--limits", str(tight))
    table = rows(out)
    assert code == 1
    outside = table["offset.x"]["outside"].split(";")
    assert outside
    assert all(s.startswith("SN") for s in outside)
    assert "outside the limits: offset.x:" in err


def test_report_csv_quotes_odd_serials(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    odd = lot / "SN0013_20261121T090000Z.json"
    odd.write_text(odd.read_text().replace('"SN0013"', '"SN,13 \\"x\\""'))
    code, out, _ = run(capsys, "report", str(lot), "--outlier-alpha", "0.05")
    assert code == 1
    parsed = list(csv.reader(io.StringIO(out)))
    assert {len(r) for r in parsed} == {16}
    assert rows(out)["offset.x"]["outliers"].startswith('SN,13 "x"=')


def test_report_skips_the_limits_file_kept_beside_the_calibrations(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lot = tmp_path / "lot"
    lot.mkdir()
    for path in sorted(LOT.glob("SN000[1-6]_*.json")):
        shutil.copy(path, lot)
    shutil.copy(LIMITS, lot / "limits.yaml")
    code, out, err = run(capsys, "report", str(lot), "--limits", str(lot / "limits.yaml"))
    assert code == 0, err
    assert "lot of 6 units (6 files)" in err
    assert rows(out)["offset.x"]["count"] == "6"
    code, _, err = run(capsys, "report", str(lot))  # not the limits file: another tool's file in the folder
    assert code == 2
    assert f"{lot / 'limits.yaml'}: " in err


def test_report_reads_a_calibration_from_stdin(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    one = LOT / "SN0001_20261121T090000Z.json"
    feed_stdin(monkeypatch, one.read_bytes())
    code, out, err = run(capsys, "report", "-")
    assert code == 0, err
    assert rows(out)["offset.x"]["count"] == "1"
    assert float(rows(out)["offset.x"]["mean"]) == pytest.approx(json.loads(one.read_text())["offset"][0], rel=1e-6)


def test_report_keeps_calibrations_in_other_units_apart(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A lot of g calibrations beside one made in m/s²: not one population of gains."""
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    other = json.loads((LOT / "SN0001_20261121T090000Z.json").read_text())
    other["unit"]["serial"] = "SN9001"
    other["units"] = "m/s^2"
    other["reference"] = 9.81
    other["matrix"] = [[v * 9.81 for v in row] for row in other["matrix"]]
    other["gain"] = [g / 9.81 for g in other["gain"]]
    (lot / "SN9001_ms2.json").write_text(json.dumps(other))
    _, out, err = run(capsys, "report", str(lot))
    assert "acc. (m/s^2) gain.x" in err
    table = list(csv.DictReader(io.StringIO(out)))
    sensors = {row["sensor"] for row in table}
    assert len(sensors) == 2
    g_rows = [row for row in table if row["parameter"] == "gain.x" and row["count"] == "30"]
    assert len(g_rows) == 1  # the g lot's statistics are its own
    assert float(g_rows[0]["mean"]) == pytest.approx(1.0, abs=0.01)


def test_report_flags_the_same_pose_file_under_two_serials(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """SN0002's calibration records SN0001's z capture (same sha256): at most one of them
    measured that unit, so the lot, otherwise in order, needs attention."""
    lot = tmp_path / "lot"
    shutil.copytree(LOT, lot)
    for path in lot.glob("SN0013_*.json"):
        path.unlink()
    args = ["report", str(lot), "--max-drift", "offset=0.02", "--json"]
    assert run(capsys, *args).code == 0  # in order
    [first] = lot.glob("SN0001_*.json")
    [second] = lot.glob("SN0002_*.json")
    shared = json.loads(first.read_text())["poses"][2]
    doc = json.loads(second.read_text())
    doc["poses"][2] |= {"sha256": shared["sha256"], "file": shared["file"]}
    second.write_text(json.dumps(doc))
    code, out, err = run(capsys, *args)
    assert code == 1
    report = json.loads(out)
    assert (report["status"], report["exit_status"]) == ("fail", 1)
    assert report["duplicates"] == [
        {"sha256": shared["sha256"], "serials": ["SN0001", "SN0002"], "files": [shared["file"], shared["file"]]}
    ]
    assert (
        f"warning: SN0001 and SN0002 record the same pose file (sha256 {shared['sha256'][:12]}): {shared['file']}: "
        "at most one of them measured that unit"
    ) in err.splitlines()
    assert "lot: needs attention" in err


@pytest.mark.slow
def test_a_report_into_a_file_or_pipe_cuts_no_number_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Written to a file (a station's log), the table was laid out for 80 columns and its numbers
    came out as '6.6e…' and Cpk as 'C…'; with COLUMNS given, that width is kept."""
    counts, g = tmp_path / "counts.json", tmp_path / "g.json"
    faces = [IMUCAL / f"{n}.csv" for n in ("xp", "xn", "yp", "yn", "zp", "zn")]
    assert run(capsys, "solve", "-q", "-p", *faces, "--reference", "9.81", "-o", counts).code == 0
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", g).code == 0
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    args = [tumblecal_exe(), "report", str(counts), str(g), "--limits", str(SAMPLE / "limits.yaml")]
    done = subprocess.run(args, capture_output=True, text=True, env=env, timeout=60, check=False)
    assert done.returncode in (0, 1), done.stderr
    assert "Cpk" in done.stderr
    assert "…" not in done.stderr
    narrow = subprocess.run(args, capture_output=True, text=True, env=env | {"COLUMNS": "80"}, timeout=60, check=False)
    assert "…" in narrow.stderr  # the width asked for


def test_a_batch_summary_given_for_a_calibration_is_named_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It was 'not valid JSON: Expecting value (line 1, column 1)'."""
    summary = tmp_path / "summary.csv"
    summary.write_text("serial,status,verdict,exit_status\nU1,pass,pass,0\n")
    r = run(capsys, "report", summary)
    assert r.code == 2
    assert f"error: {summary}: a batch summary (CSV), not a calibration" in r.err.splitlines()
    r = run(capsys, "apply", "--cal", summary, SAMPLE / "capture.csv", "-o", tmp_path / "out.csv")
    assert r.err.splitlines() == [
        f"error: {summary}: a batch summary (CSV), not a calibration",
        f"hint: give the calibrations: their folder ({tmp_path}) or its *.json files",
    ]
