"""``tumblecal segment`` and ``solve --log`` on whole real logs nobody here made
(``tests/data/logs``, see its SOURCE.md): the still blocks a person would mark, labelled with
the face they rest on, and the calibration they give.

Every bound was measured on these files (the figure in the comment next to it) and given a margin.
"""

from __future__ import annotations

import csv
import gzip
import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import tumblecal
from tests.test_solvers_realdata import SESSION_FACES
from tumblecal_cli.io.outputs import unsafe

pytestmark = pytest.mark.slow

LOGS = Path(__file__).resolve().parent / "data" / "logs"
SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
IMUCAL_MAP = ",".join(f"{label}={face}" for label, face in SESSION_FACES.items())
#: imucal's published calibration of its annotated session (Ferraris 6-position, gravity 9.81),
#: as in tests/test_solvers_cli.py
IMUCAL_OFFSET = [-6.018868019671572, -48.287874016760156, -28.96636637224333]
IMUCAL_MATRIX = [
    [4.7941075750e-3, -3.3657395500e-5, 5.2667296510e-5],
    [4.0523316827e-5, 4.8076518588e-3, -1.0969773274e-4],
    [-1.0191238382e-4, 5.2568900273e-5, 4.6548524031e-3],
]


def unpacked(tmp_path: Path, name: str) -> Path:
    """A log of tests/data/logs, decompressed into ``tmp_path`` when it is gzipped."""
    source = LOGS / name
    if not name.endswith(".gz"):
        return source
    target = tmp_path / name.removesuffix(".gz")
    with gzip.open(source, "rb") as f, target.open("wb") as out:
        shutil.copyfileobj(f, out)
    return target


def segments(log: Path, *options: str) -> list[dict[str, str]]:
    """``tumblecal segment LOG`` (exit 0): the index it prints, one dict per block (each cell
    without the ' that keeps a spreadsheet from taking a face, +x, for a formula)."""
    r = tumblecal("segment", log, "--quiet", *options)
    assert r.code == 0, r.err
    return [{column: unsafe(cell) for column, cell in row.items()} for row in csv.DictReader(r.out.splitlines())]


def kept(index: list[dict[str, str]]) -> list[dict[str, str]]:
    return [row for row in index if row["status"] == "kept"]


def faces(index: list[dict[str, str]]) -> set[str]:
    return {row["face"] for row in kept(index) if row["face"]}


# -- imucal: a continuous Ferraris session, the owner's sections as the known answer -----------


def test_imucal_session_every_owner_section_lies_in_one_block_of_its_face(tmp_path: Path) -> None:
    log = unpacked(tmp_path, "imucal_ferraris_session.csv.gz")
    sections = json.loads((LOGS / "imucal_ferraris_session_list.json").read_text())
    index = segments(log, "--rate", "102.4")
    assert len(kept(index)) == 13  # 13 still periods: the six faces, and the re-placements around the rotations
    for label, face in SESSION_FACES.items():
        first, last = sections[label]["start"], sections[label]["end"] - 1  # imucal's iloc[start:end]
        holding = [r for r in index if int(r["first_row"]) <= first and last <= int(r["last_row"])]
        assert len(holding) == 1, (label, first, last)
        assert holding[0]["status"] == "kept"
        assert holding[0]["face"] == face
        assert float(holding[0]["angle_deg"]) < 2  # measured: 0.2-1.1°
    for label in ("x_rot", "y_rot", "z_rot"):  # the rotations are not still: no block overlaps their middle
        middle = (sections[label]["start"] + sections[label]["end"]) // 2
        assert not [r for r in index if int(r["first_row"]) <= middle <= int(r["last_row"])]


def test_imucal_session_solve_log_equals_the_hand_labelled_sections(tmp_path: Path) -> None:
    log = unpacked(tmp_path, "imucal_ferraris_session.csv.gz")
    sections = json.loads((LOGS / "imucal_ferraris_session_list.json").read_text())
    lines = log.read_text().splitlines(keepends=True)
    hand = []
    for label, face in SESSION_FACES.items():
        part = tmp_path / f"{label}.csv"
        part.write_text(lines[0] + "".join(lines[1 + sections[label]["start"] : 1 + sections[label]["end"]]))
        hand.append(f"{face}={part}")
    r = tumblecal("solve", "-p", *hand, "--reference", "9.81", "-o", tmp_path / "hand.json", "-q")
    assert r.code == 0, r.err
    r = tumblecal("solve", "--log", log, "--rate", "102.4", "--reference", "9.81", "-o", tmp_path / "log.json", "-q")
    assert r.code == 0, r.err
    by_hand, by_log = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("hand", "log"))
    assert by_log["method"] == "six-pose"
    for name in ("offset", "gain"):
        for a, b, sa, sb in zip(
            by_hand[name], by_log[name], by_hand["uncertainty"][name], by_log["uncertainty"][name], strict=True
        ):
            # measured: at most 1.5 sigma of one estimate (1.1 of the two combined); the +z block the
            # log picks is a longer re-placement of the unit than the owner's section
            assert abs(a - b) < 3 * math.hypot(sa, sb), (name, a, b, sa, sb)
    # The cross-axis terms absorb the fixture's tilt to first order: the +z block the log picks
    # was placed again (about 0.1 degrees apart), so they differ by more than their noise (up to
    # 33 sigma, measured) but stay within the tilt_sensitivity both files report for them.
    cross = [np.linalg.inv(d["matrix"]) * (1 - np.eye(3)) for d in (by_hand, by_log)]  # A's off-diagonal
    noise = np.hypot(*(np.asarray(d["uncertainty"]["cross_axis"]) for d in (by_hand, by_log)))
    tilt = np.asarray(by_hand["tilt_sensitivity"]["cross_axis"])
    assert by_hand["tilt_sensitivity"]["tolerance_deg"] == 1.0
    assert np.all(np.abs(cross[0] - cross[1]) <= 3 * noise + tilt), (cross, noise, tilt)
    assert float(np.abs(cross[0] - cross[1]).max()) < 0.15 * float(tilt.max())
    seg = by_log["segmentation"]
    assert seg["source"] == "detector"
    assert seg["blocks_kept"] == 13
    assert [p["pose"] for p in by_log["poses"]] == list(SIX)
    assert all(p["file"] == str(log) and "block" in p for p in by_log["poses"])


def test_imucal_annotated_log_by_its_label_column_reproduces_imucal(tmp_path: Path) -> None:
    """The owner's `part` column gives the blocks; the result is imucal's published calibration."""
    log = unpacked(tmp_path, "imucal_annotated_session.csv.gz")
    cal = tmp_path / "cal.json"
    r = tumblecal(
        "solve", "--log", log, "--pose-column", "part", "--pose-map", IMUCAL_MAP, "--reference", "9.81",
        "--rate", "204.8", "-o", cal, "-q",
    )  # fmt: skip
    assert r.code == 0, r.err
    doc = json.loads(cal.read_text())
    assert doc["segmentation"]["source"] == "label column"
    for got, want in zip(doc["offset"], IMUCAL_OFFSET, strict=True):
        assert got == pytest.approx(want, rel=1e-6)
    for row, want_row in zip(doc["matrix"], IMUCAL_MATRIX, strict=True):
        for got, want in zip(row, want_row, strict=True):
            assert got == pytest.approx(want, rel=1e-6, abs=1e-12)
    index = segments(log, "--pose-column", "part", "--pose-map", IMUCAL_MAP)
    dropped = {r["label"]: r["reason"] for r in index if r["status"] == "dropped"}
    assert dropped == {"x_rot": "not a pose label", "y_rot": "not a pose label", "z_rot": "not a pose label"}


# -- imu_tk's Xsens log: headerless, whitespace, raw counts near 32768, time in seconds ----------


def test_xsens_log_has_30_still_blocks_every_face_and_the_tilted_x(tmp_path: Path) -> None:
    log = unpacked(tmp_path, "xsens_acc.txt.gz")
    index = segments(log)
    assert len(kept(index)) >= 30  # measured: 38 kept of 41 found
    assert faces(index) == set(SIX)
    plus_x = [r for r in kept(index) if r["face"] == "+x"]
    assert len(plus_x) == 1
    assert 12 < float(plus_x[0]["angle_deg"]) < 20  # measured: 15.9°
    assert all(r["start_time"] and float(r["start_time"]) >= 0 for r in index)  # time from the t column


def test_xsens_log_orientation_free_fit_converges(tmp_path: Path) -> None:
    log = unpacked(tmp_path, "xsens_acc.txt.gz")
    cal = tmp_path / "cal.json"
    r = tumblecal("solve", "--log", log, "--method", "sphere", "-o", cal, "-q")
    assert r.code == 0, r.err
    doc = json.loads(cal.read_text())
    assert doc["method"] == "sphere"
    assert len(doc["poses"]) >= 30
    assert all(abs(o - 32768) < 1000 for o in doc["offset"])  # an unsigned ADC's zero
    assert all(3000 < g < 5000 for g in doc["gain"])  # about 4000 counts/g
    assert doc["residuals"]["rms"] < 0.01  # g; measured 0.0021


def test_xsens_log_auto_fits_the_sphere_to_its_hand_placed_blocks(tmp_path: Path) -> None:
    """Its +x block is 15.9° off the face: six-pose would take that for cross-axis terms (±11 %)
    and read other orientations worse than raw, so auto fits the sphere to all the blocks."""
    log = unpacked(tmp_path, "xsens_acc.txt.gz")
    cal = tmp_path / "cal.json"
    r = tumblecal("solve", "--log", log, "-o", cal)
    assert r.code == 0, r.err
    assert json.loads(cal.read_text())["method"] == "sphere"
    assert (
        "note: auto fits the sphere to all 38 still blocks: the faces of x disagree on its direction by 15.2° "
        "(+x 15.9°, -x 1.7° off)" in r.err
    )
    r = tumblecal("solve", "--log", log, "--method", "six-pose", "-o", cal)  # asked for: fitted, with a warning
    assert r.code == 0, r.err
    assert "warning: the faces +x (15.9° off) and -x (1.7° off) disagree by 15.2° on the direction of x" in r.err
    assert "(poses.hand_placed)" in r.err


# -- Hassan & Bao's phone log: no time column ------------------------------------------------------


def test_hassan_phone_log_has_25_still_blocks(tmp_path: Path) -> None:
    index = segments(LOGS / "hassan_mobile_30orient.csv")
    assert len(kept(index)) >= 25  # measured: 32 kept of 38 found
    assert all(not r["start_time"] and not r["duration_s"] for r in index)  # no time: lengths in samples


# -- CK-Explorer: many short pauses, the +Z face rare ------------------------------------------------


def test_ckexplorer_log_has_90_blocks_and_labels_only_within_tolerance(tmp_path: Path) -> None:
    index = segments(LOGS / "ckexplorer_acc_log.csv")
    assert len(kept(index)) >= 90  # measured: 111 kept of 187 found
    for row in index:
        if row["face"]:
            assert float(row["angle_deg"]) <= 25
    # tighter: the faces it cannot find within 10° are named, not guessed
    strict = segments(LOGS / "ckexplorer_acc_log.csv", "--max-tilt", "10")
    assert all(float(r["angle_deg"]) <= 10 for r in strict if r["face"])
    found = faces(strict)
    assert found
    assert found != set(SIX)
    r = tumblecal("segment", LOGS / "ckexplorer_acc_log.csv", "--max-tilt", "10")
    for face in sorted(set(SIX) - found):
        assert f"hint: no {face} block" in r.err, r.err
    r = tumblecal(
        "solve", "--log", LOGS / "ckexplorer_acc_log.csv", "--max-tilt", "10", "--method", "six-pose", "--json",
        "-o", tmp_path / "cal.json",
    )  # fmt: skip
    assert r.code == 3
    summary: dict[str, Any] = json.loads(r.out)
    assert summary["rejections"][0]["code"] == "log.faces"
    assert not (tmp_path / "cal.json").exists()
