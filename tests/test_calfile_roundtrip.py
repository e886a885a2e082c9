"""Every calibration file read and written again is the same document: the typed Calibration
(io.calfiles.calfile, io.calfiles.calparts) holds all of it. The files of tests/data and sample_data, those solve
writes for each solver and method, thermal, known and hand turns, a segmented log and import,
and files another writer (or a hand) left in forms tumblecal does not write."""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tumblecal_cli.cli import main
from tumblecal_cli.errors import TumblecalError
from tumblecal_cli.io.calfiles import calfile, documents

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data"
DATA = ROOT / "tests" / "data"
THREE = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
SIX = [str(SAMPLE / f) for f in ("x.csv", "xn.csv", "y.csv", "yn.csv", "z.csv", "zn.csv")]
IMUCAL = [str(SAMPLE / "imucal" / f"{n}.csv") for n in ("xp", "xn", "yp", "yn", "zp", "zn")]
THERMAL = SAMPLE / "thermal"
SWEEPS = [
    f"{face}={THERMAL / name}.csv"
    for face, name in (
        ("+x", "sweep_up_xp"),
        ("-x", "sweep_down_xn"),
        ("+y", "sweep_up_yp"),
        ("-y", "sweep_down_yn"),
        ("+z", "sweep_up_zp"),
        ("-z", "sweep_down_zn"),
    )
]
FACE_MAP = "x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z"


def assert_round_trip(path: Path) -> None:
    """``path`` read, and its document made again, is the same JSON (and written alike)."""
    text = path.read_bytes()
    cal = calfile.load(str(path))
    doc = documents.parse_object(text, str(path), "calibration file")
    again = cal.to_dict()
    assert again == doc
    assert list(again) == list(doc)  # each field in its place
    if not documents.is_yaml(str(path)):
        assert json.dumps(again) == json.dumps(doc)  # every digit, every key in its order, nested too


def stored_files() -> list[Path]:
    found = sorted(SAMPLE.rglob("*.json")) + sorted(DATA.rglob("*.json")) + sorted(DATA.rglob("*.yaml"))
    out = []
    for path in found:
        try:
            calfile.load(str(path))
        except TumblecalError:
            continue  # not a calibration, or one of tests/data/bad's
        out.append(path)
    return out


@pytest.mark.parametrize("path", stored_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_stored_calibrations_round_trip(path: Path) -> None:
    assert_round_trip(path)


def solved(tmp_path: Path, name: str, *argv: str) -> Path:
    out = tmp_path / name
    assert main([*argv, "-o", str(out), "--quiet"]) in (0, 1), argv
    return out


SOLVES = {
    "three-pose.json": ["solve", "--poses", *THREE, "--limits", str(SAMPLE / "limits.yaml"), "--serial", "SN1"],
    "three-pose.yaml": ["solve", "--poses", *THREE, "--max-offset", "0.04"],
    "one-pose.json": ["solve", "--poses", str(SAMPLE / "z.csv"), "--up", "+z", "--gain-tolerance", "0.01"],
    "one-pose-tilt.json": ["solve", "--poses", str(SAMPLE / "z.csv"), "--up", "+z", "--method", "one-pose-tilt"],
    **{
        f"{method}.json": ["solve", "--poses", *SIX, "--method", method, "--max-noise", "0.5"]
        for method in ("six-pose", "six-pose-diagonal", "six-pose-magnitude", "least-squares", "minmax", "ellipsoid")
    },
    "counts.yaml": ["solve", "--poses", *IMUCAL, "--reference", "9.81", "--input-units", "counts"],
    "log.json": ["solve", "--log", str(DATA / "logs" / "ckexplorer_acc_log.csv")],
    "sphere-log.json": ["solve", "--log", str(DATA / "logs" / "hassan_mobile_30orient.csv")],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SOLVES))
def test_solved_calibrations_round_trip(name: str, tmp_path: Path) -> None:
    assert_round_trip(solved(tmp_path, name, *SOLVES[name]))


@pytest.mark.slow
def test_thermal_turns_rotations_and_import_round_trip(tmp_path: Path) -> None:
    base = solved(
        tmp_path,
        "base.json",
        "solve",
        "--poses",
        *(str(THERMAL / f"{n}.csv") for n in ("xp", "xn", "yp", "yn", "zp", "zn")),
    )
    assert_round_trip(solved(tmp_path, "thermal.json", "thermal", *SWEEPS, "--cal", str(base)))
    session = tmp_path / "session.csv"
    session.write_bytes(gzip.decompress((DATA / "logs" / "imucal_annotated_session.csv.gz").read_bytes()))
    labelled = ["--log", str(session), "--rate", "204.8", "--pose-column", "part", "--pose-map", FACE_MAP]
    assert_round_trip(solved(tmp_path, "labelled.json", "solve", *labelled))
    turns = ["--turns", "x_rot=+x,y_rot=+y,z_rot=+z", "--turn-angle", "360"]
    assert_round_trip(solved(tmp_path, "turns.json", "solve", "--sensor", "gyroscope", *labelled, *turns))
    from tests.test_rotations import ACC_A, ACC_B, synthetic_log

    acc = tmp_path / "acc.json"
    calfile.Calibration(
        "accelerometer", "six-pose", 1.0, ["acc_x", "acc_y", "acc_z"], ACC_B, np.linalg.inv(ACC_A), np.diag(ACC_A)
    ).save(acc)
    assert_round_trip(acc)
    synthetic_log(tmp_path / "hand.csv", np.random.default_rng(5))
    hand = ["--sensor", "gyroscope", "--log", str(tmp_path / "hand.csv"), "--accel-cal", str(acc)]
    assert_round_trip(solved(tmp_path, "rotations.json", "solve", *hand))
    imported = DATA / "imucal_session" / "example_cal.json"
    assert_round_trip(solved(tmp_path, "imported.json", "import", str(imported)))


def edited(tmp_path: Path, change: Any) -> Path:
    doc = json.loads(solved(tmp_path, "base.json", *SOLVES["three-pose.json"]).read_text())
    change(doc)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(doc))
    return path


EDITS = {
    "integers": lambda d: d.update(coverage=1, residuals={"rms": 0, "max": 1, "count": 3}),
    "failures of another writer": lambda d: d.update(
        verdict={"pass": False, "failures": [{"code": "x", "extra": 1}, {"message": 3, "code": "y", "file": 5}]}
        | {"limits": {"offset": [1, 1, 1], "foo": 2}}
    ),
    "limits in another order": lambda d: d.update(
        verdict={"pass": True, "failures": [], "limits": {"noise": 1.0, "offset": [0.5] * 3}}
    ),
    "a pose of another writer": lambda d: d["poses"][0].update(file=7, rows="all", new=[1], samples=2),
    "poses' keys in another order": lambda d: d.update(poses=[dict(reversed(list(p.items()))) for p in d["poses"]]),
    "a pose with the least": lambda d: d.update(poses=[{"pose": "+x", "mean": [1, 0, 0], "samples": 1}]),
    "tilt of another writer": lambda d: d.update(tilt_sensitivity={"gain": [1, 1, 1], "offset": [0, 0, 0], "z": "q"}),
    "fields of another writer": lambda d: d.update(zfield={"a": 1}, segmentation={"log": 3}, covariance=[1]),
    "nulls": lambda d: d.update(tilt_sensitivity=None, residuals=None, coverage=None, covariance=None, unit=None),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(EDITS))
def test_files_of_other_writers_round_trip(name: str, tmp_path: Path) -> None:
    assert_round_trip(edited(tmp_path, EDITS[name]))
