"""apply says when a capture is not what its calibration was made for (issue "Real recordings,
round 3": a magnetometer calibration applied to a recording whose hard iron had changed gave a
corrected median |B| of 458 µT against a 46 µT reference, exit 0, not a word). One warning line
on stderr, the exit status unchanged for pipelines."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.conftest import POSES_3, SAMPLE, run

MAG = Path(__file__).resolve().parent / "data" / "ckexplorer_mag" / "mag_every10.csv"


@pytest.fixture
def mag_cal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    out = tmp_path / "mag.json"
    assert run(capsys, "solve", "--sensor", "magnetometer", "--poses", MAG, "-o", out, "-q").code == 0
    return out


def _shifted(path: Path, out: Path, by: float) -> Path:
    lines = path.read_text().splitlines()
    rows = [[float(v) for v in ln.split(",")] for ln in lines[1:]]
    out.write_text("\n".join([lines[0], *(f"{x + by:.5f},{y:.5f},{z:.5f}" for x, y, z in rows)]) + "\n")
    return out


def test_apply_warns_when_the_hard_iron_changed(
    mag_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "apply", "--cal", mag_cal, MAG, "-o", tmp_path / "same.csv")
    assert r.code == 0, r.err
    assert "warning" not in r.err
    moved = _shifted(MAG, tmp_path / "moved.csv", 2.0)  # the field's 0.3 gauss, a new hard iron of 2
    r = run(capsys, "apply", "--cal", mag_cal, moved, "-o", tmp_path / "out.csv")
    assert r.code == 0, r.err  # a pipeline's status is the correction's, which is written whole
    warned = [ln for ln in r.err.splitlines() if ln.startswith("warning:")]
    assert len(warned) == 1, r.err
    assert warned[0].startswith(f"warning: {moved}: the corrected magnetometer reads 6.5")
    assert warned[0].endswith("from the calibration's 1: the field or the hard iron changed: recalibrate")
    assert len((tmp_path / "out.csv").read_text().splitlines()) == 1201


def test_apply_warns_of_an_accelerometer_capture_in_other_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = tmp_path / "acc.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal, "-q").code == 0
    r = run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", tmp_path / "ok.csv")
    assert "warning" not in r.err
    text = (SAMPLE / "capture.csv").read_text().splitlines()
    head, rows = text[0], [ln.split(",") for ln in text[1:] if ln and not ln.startswith("#")]
    scaled = tmp_path / "ms2.csv"
    scaled.write_text(
        "\n".join([head, *(",".join([r[0], *(f"{9.80665 * float(v):.6f}" for v in r[1:4])]) for r in rows)])
    )
    r = run(capsys, "apply", "--cal", cal, scaled, "-o", tmp_path / "out.csv")
    assert r.code == 0, r.err
    assert "the corrected accelerometer reads 9.7" in r.err  # (the offsets scaled with the readings)
    assert "the sensor, its mounting or its units are not the calibration's: recalibrate" in r.err


@pytest.mark.slow
def test_apply_of_a_big_file_on_forked_workers_warns_too(
    mag_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file past forked.MIN_BYTES is corrected by worker processes: the magnitudes they see are
    counted in memory shared with them."""
    rng = np.random.default_rng(2)
    n = 700_000
    v = rng.normal(size=(n, 3))
    v = 0.3 * v / np.linalg.norm(v, axis=1)[:, None] + [2.1, 0.4, -0.06]
    big = tmp_path / "big.csv"
    np.savetxt(big, v, delimiter=",", header="mx,my,mz", comments="", fmt="%.6f")
    assert big.stat().st_size > 16 << 20
    r = run(capsys, "apply", "--cal", mag_cal, big, "-o", tmp_path / "out.csv")
    assert r.code == 0, r.err
    assert "the field or the hard iron changed: recalibrate" in r.err


def test_verify_of_a_turning_magnetometer_capture_reports_its_magnitude_error_and_coverage(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """verify of a magnetometer calibration on a turning recording refused it: "not a static
    capture / capture it again holding the unit still". A magnetometer's capture that turns is
    judged as one: each sample's |corrected| - reference (RMS, largest) and the share of the
    sphere's directions it reaches; --max-norm-error judges the RMS (exit 1 over it). Held out:
    solved on the first half of a real hand-turned recording, verified on the second."""
    import json

    lines = MAG.read_text().splitlines()
    half = (len(lines) - 1) // 2
    first, second = tmp_path / "first.csv", tmp_path / "second.csv"
    first.write_text("\n".join([lines[0], *lines[1 : 1 + half]]) + "\n")
    second.write_text("\n".join([lines[0], *lines[1 + half :]]) + "\n")
    cal = tmp_path / "mag.json"
    assert run(capsys, "solve", "--sensor", "magnetometer", "--poses", first, "-o", cal, "-q").code == 0
    r = run(capsys, "verify", "--cal", cal, second, "--json")
    assert r.code == 0, r.err
    row = json.loads(r.out)["captures"][0]
    assert row["turning"] is True
    assert 0 < row["error_after"] < 0.03 < row["max_error"] < 0.1  # a few % of 1, as the fit's own residual
    assert row["coverage"] >= 0.9
    assert f"{second}: a turning capture: |corrected| - reference RMS " in r.err
    r = run(capsys, "verify", "--cal", cal, second, "--max-norm-error", "0.005")
    assert r.code == 1, r.err
