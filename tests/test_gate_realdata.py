"""The gate on captures nobody here made: good real poses pass every check untouched, and the
real defects (a pose on the opposite face, a range too small for the pose) are caught.

Data: ``sample_data/imucal`` (imucal, MIT; raw counts, about 2040-2110 per g) and
``tests/data/ncsu_xplus_head.csv`` (NCSU AirBrakes MicroStrain 3DM-CX5 at rest, MIT); see the
docs next to each.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import IMUCAL, ROOT, run

pytestmark = pytest.mark.slow

NCSU_HEAD = ROOT / "tests" / "data" / "ncsu_xplus_head.csv"


def summary(capsys: pytest.CaptureFixture[str], tmp_path: Path, *args: str | Path) -> tuple[int, dict[str, object]]:
    r = run(capsys, "solve", *args, "-o", tmp_path / "cal.json", "--json", "--quiet")
    doc: dict[str, object] = json.loads(r.out)
    return r.code, doc


def test_real_three_pose_capture_passes_every_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, doc = summary(
        capsys, tmp_path, "-p", IMUCAL / "xp.csv", IMUCAL / "yp.csv", IMUCAL / "zp.csv", "--reference", "9.81"
    )
    assert code == 0, doc
    assert doc["status"] == "pass"
    assert doc["rejections"] == []
    assert doc["warnings"] == []
    poses = doc["poses"]
    assert isinstance(poses, list)
    for pose in poses:
        assert pose["clipped"] == 0  # 16-bit counts far from the rails
        assert pose["angle_deg"] < 3.0  # a level fixture, offsets of a few tens of counts
        # the 3-pose gains fit each up axis exactly; the rest is second order in the horizontal readings
        assert abs(pose["norm_error"]) < 0.01  # m/s^2, against 9.81


def test_real_pose_on_the_opposite_face_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # labelled: unlabelled, xn.csv's name would give it -x (and no solver takes -x +y +z)
    poses = [f"+x={IMUCAL / 'xn.csv'}", f"+y={IMUCAL / 'yp.csv'}", f"+z={IMUCAL / 'zp.csv'}"]
    code, doc = summary(capsys, tmp_path, "-p", *poses, "--reference", "9.81")
    assert code == 3
    assert doc["status"] == "rejected"
    rejections = doc["rejections"]
    assert isinstance(rejections, list)
    assert [(r["code"], r["pose"], r["file"]) for r in rejections] == [
        ("pose.upside_down", "+x", str(IMUCAL / "xn.csv"))
    ]
    assert rejections[0]["message"].startswith("declared +x but reads like -x (mean ")
    assert rejections[0]["message"].endswith(": upside down")
    assert not (tmp_path / "cal.json").exists()


def test_real_pose_beyond_a_stated_full_scale_is_saturated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The +x pose reads about 2040 counts on x: a part whose range ended at 2000 counts clipped it."""
    code, doc = summary(
        capsys, tmp_path, "-p", IMUCAL / "xp.csv", "--up", "+x", "--reference", "2048", "--full-scale", "2000"
    )
    assert code == 3
    rejections = doc["rejections"]
    assert isinstance(rejections, list)
    assert [r["code"] for r in rejections] == ["pose.saturated"]
    assert rejections[0]["value"] > 100  # most of the 1028 samples sit above 0.98 * 2000


def test_real_factory_calibrated_pose_at_rest_passes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A MicroStrain at rest on +x (g, factory calibrated): 1-pose, every check passes, offsets tiny."""
    code, doc = summary(capsys, tmp_path, "-p", NCSU_HEAD, "--up", "+x")
    assert code == 0, doc
    assert doc["rejections"] == []
    assert doc["warnings"] == []
    offset = doc["offset"]
    assert isinstance(offset, list)
    assert max(abs(v) for v in offset) < 0.05  # g
