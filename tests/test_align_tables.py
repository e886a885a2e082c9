"""align takes a table of orientations as solve does (issue "Real recordings, round 3", item 3):
a cave-survey instrument's 24 calibration shots, one averaged reading a row (furbrain's SAP5,
tests/data/furbrain_sap, Unlicense), were refused "0 still blocks in 0 orientations … hold the
unit still (1 s or more)"."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import run
from tumblecal_cli.core.arrays import FloatArray

SAP = Path(__file__).resolve().parent / "data" / "furbrain_sap"
SHOTS = SAP / "sap5_ab_shots.csv"


def _device_dip_spread() -> float:
    """The spread of the dip over the 24 shots through the instrument's own calibration
    (M (raw + o), its first 12 numbers; SOURCE.md)."""
    with SHOTS.open(newline="") as shots:
        rows = list(csv.DictReader(shots))
    conf = json.loads((SAP / "sap5_ab_device_cal.json").read_text())["conf"]["calib"]

    def calibrated(keys: tuple[str, str, str], part: str) -> FloatArray:
        v = np.array([[float(r[k]) for k in keys] for r in rows])
        m, o = np.array(conf[part][:9]).reshape(3, 3), np.array(conf[part][9:12])
        out: FloatArray = (v + o) @ m.T
        unit: FloatArray = out / np.linalg.norm(out, axis=1)[:, None]
        return unit

    g, field = calibrated(("ax", "ay", "az"), "accel"), calibrated(("mx", "my", "mz"), "mag")
    return float(np.std(np.degrees(np.arcsin(np.einsum("ij,ij->i", g, field)))))


@pytest.fixture
def cals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, Path]:
    """The accelerometer's and the magnetometer's calibrations, each solved from the same table."""
    acc, mag = tmp_path / "acc.json", tmp_path / "mag.json"
    for sensor, columns, out in (("accelerometer", "ax,ay,az", acc), ("magnetometer", "mx,my,mz", mag)):
        assert (
            run(capsys, "solve", "--sensor", sensor, "--poses", SHOTS, "--columns", columns, "-o", out, "-q").code == 0
        )
    return acc, mag


def test_align_of_a_table_of_shots_is_at_or_below_the_devices_own_dip_spread(
    cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, mag = cals
    out = tmp_path / "aligned.json"
    r = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, SHOTS, "-o", out, "--json")
    assert r.code == 0, r.err
    assert f"{SHOTS}: a table of 24 orientations, one averaged reading a row" in r.err
    assert "1 s or more" not in r.err
    assert json.loads(out.read_text())["blocks"] == 24
    line = next(ln for ln in r.err.splitlines() if "spread over the blocks" in ln)
    spread = float(line.split("before, ")[1].split("°")[0])
    assert spread <= _device_dip_spread(), (spread, _device_dip_spread())  # 0.316° against the device's 0.344°
    assert "chi2 1)" in r.err  # the uncertainty from the rows' scatter about the fit


def test_a_table_too_few_shots_for_the_alignment_says_what_to_add(
    cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, mag = cals
    few = tmp_path / "few.csv"
    few.write_text("\n".join(SHOTS.read_text().splitlines()[:4]) + "\n")
    r = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, few)
    assert r.code in (2, 3), r.err
    assert "1 s or more" not in r.err


def test_solve_align_to_takes_the_table_too(
    cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, _ = cals
    args: list[str | Path] = [
        "solve",
        "--sensor",
        "magnetometer",
        "--poses",
        SHOTS,
        "--columns",
        "mx,my,mz",
        "--align-to",
        acc,
    ]
    r = run(capsys, *args, "-o", tmp_path / "mag.json")
    assert r.code == 0, r.err
    assert f"note: aligned to {acc} from 24 still blocks: rotated 2.19" in r.err
    assert "alignment" in json.loads((tmp_path / "mag.json").read_text())


def test_the_dip_check_takes_a_table_each_row_a_block(
    cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """solve --log TABLE --accel-cal ACC refused "0 still blocks kept … hold each pose longer";
    each row is a still block now, and aligned the dip spread is at or below the device's own."""
    acc, _ = cals
    out = tmp_path / "mag.json"
    given: list[str | Path] = ["--sensor", "magnetometer", "--log", SHOTS, "--columns", "mx,my,mz", "--accel-cal", acc]
    r = run(capsys, "solve", *given, "--align-to", acc, "-o", out)
    assert r.code == 0, r.err
    assert f"{SHOTS}: a table of 24 orientations, one averaged reading a row: each row a still block" in r.err
    assert "hint:" not in r.err
    assert "longer" not in r.err
    assert "so the uncertainty comes from the fit's residuals instead" in r.err  # the rows' scatter, not 0
    doc = json.loads(out.read_text())
    assert min(doc["uncertainty"]["offset"]) > 0
    dip = doc["dip"]
    assert dip["blocks"] == 24
    assert dip["spread_deg"] <= _device_dip_spread()
