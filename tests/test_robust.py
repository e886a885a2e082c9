"""Fits over samples that outliers cannot bend (core.robust; issue "Real recordings, round 3",
item 1): two glitch rows in a hand-turned magnetometer capture made a false coverage refusal;
disturbed still stretches bent the fit and PASSed with nothing said. Judged on a real capture
nobody here made (CK-Explorer's hand-turned magnetometer, tests/data/ckexplorer_mag) with the
glitches and disturbances planted, and on synthetic truth over many sessions."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import run
from tumblecal_cli.core import fits, model
from tumblecal_cli.errors import CaptureRejected

MAG = Path(__file__).resolve().parent / "data" / "ckexplorer_mag" / "mag_every10.csv"


def _real() -> tuple[str, np.ndarray]:
    lines = MAG.read_text().splitlines()
    return lines[0], np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])


def _write(path: Path, head: str, values: np.ndarray) -> Path:
    np.savetxt(path, values, delimiter=",", header=head, comments="", fmt="%.5f")
    return path


def _solve(
    capsys: pytest.CaptureFixture[str], capture: Path, out: Path, *extra: str
) -> tuple[int, dict[str, Any], str]:
    r = run(capsys, "solve", "--sensor", "magnetometer", "--poses", capture, "-o", out, "--json", *extra)
    return r.code, json.loads(r.out), r.err


@pytest.fixture
def clean(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    code, doc, _ = _solve(capsys, MAG, tmp_path / "clean.json")
    assert code == 0
    return doc


def test_two_glitch_rows_are_left_out_not_a_false_coverage_refusal(
    clean: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two rows at about ten times the field, in opposite directions: the plain fit refuses
    ("nothing within 45° of -x ..."); the robust one leaves the two out, names their rows, and
    gives the clean capture's calibration."""
    head, v = _real()
    v[300], v[800] = [3.1, 2.9, -3.0], [-2.9, -3.2, 3.3]
    capture = _write(tmp_path / "glitch.csv", head, v)
    code, _, err = _solve(capsys, capture, tmp_path / "plain.json", "--no-robust")
    assert code == 3, err
    assert "do not cover enough directions" in err or "uncovered" in err
    code, doc, err = _solve(capsys, capture, tmp_path / "robust.json")
    assert code == 0, err
    left = doc["outliers"]
    assert (left["count"], left["of"]) == (2, 1200)
    assert [s["rows"] for s in left["stretches"]] == [[300, 300], [800, 800]]
    assert all(s["worst"] > 5 for s in left["stretches"])
    assert "outliers: 2 of 1,200 samples left out of the fit" in err
    assert "glitch.csv row 300 (off by " in err
    assert json.loads((tmp_path / "robust.json").read_text())["outliers"] == left
    sigma = np.array(clean["uncertainty"]["offset"])
    assert np.all(np.abs(np.array(doc["offset"]) - clean["offset"]) < 0.5 * sigma)


def test_disturbed_stretches_are_left_out_and_named(
    clean: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two still stretches in a disturbed field (1.18 and 1.41 times it, 4 % of the rows): the
    plain fit's residual triples and its offsets move by many sigma; the robust fit names the two
    stretches by their rows and stays on the clean capture's calibration."""
    head, v = _real()
    centre = np.median(v, axis=0)
    v[100:125] = centre + (v[100:125] - centre) * 1.18
    v[600:625] = centre + (v[600:625] - centre) * 1.41
    capture = _write(tmp_path / "disturbed.csv", head, v)
    code, plain, _ = _solve(capsys, capture, tmp_path / "plain.json", "--no-robust")
    assert code == 0
    assert "outliers" not in plain or plain["outliers"] is None
    code, doc, err = _solve(capsys, capture, tmp_path / "robust.json")
    assert code == 0, err
    assert [s["rows"] for s in doc["outliers"]["stretches"]] == [[100, 124], [600, 624]]
    sigma = np.array(clean["uncertainty"]["offset"])
    robust_z = (np.array(doc["offset"]) - clean["offset"]) / sigma
    plain_z = (np.array(plain["offset"]) - clean["offset"]) / sigma
    assert np.all(np.abs(robust_z) < 1.0)
    assert np.abs(plain_z).max() > 3.0
    assert plain["residuals"]["rms"] > 2 * doc["residuals"]["rms"]


def test_a_clean_capture_is_the_plain_fit_to_the_last_digit(
    clean: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, plain, _ = _solve(capsys, MAG, tmp_path / "plain.json", "--no-robust")
    assert code == 0
    assert (plain["offset"], plain["matrix"], plain["uncertainty"]) == (
        clean["offset"],
        clean["matrix"],
        clean["uncertainty"],
    )
    assert clean["outliers"] is None


def test_minmax_is_robust_to_glitches_too(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--method minmax refused the glitched capture ("nothing within 60° of −x"): its extremes
    were the glitches."""
    head, v = _real()
    v[300], v[800] = [3.1, 2.9, -3.0], [-2.9, -3.2, 3.3]
    capture = _write(tmp_path / "glitch.csv", head, v)
    code, doc, err = _solve(capsys, capture, tmp_path / "m.json", "--method", "minmax")
    assert code == 0, err
    assert doc["outliers"]["count"] == 2
    _, clean, _ = _solve(capsys, MAG, tmp_path / "c.json", "--method", "minmax")
    assert np.allclose(doc["offset"], clean["offset"], atol=1e-3)


def test_the_python_api_takes_no_robust(tmp_path: Path) -> None:
    head, v = _real()
    v[300] = [3.1, 2.9, -3.0]
    capture = _write(tmp_path / "glitch.csv", head, v)
    robust = tumblecal.solve([str(capture)], sensor="magnetometer")
    assert robust.calibration is not None
    assert robust.calibration.outliers is not None
    assert robust.calibration.outliers.count == 1
    plain = tumblecal.solve([str(capture)], sensor="magnetometer", no_robust=True)
    assert plain.status == 3  # one glitch: the plain fit's false coverage refusal


# -- synthetic truth: the stated uncertainty covers the error with 0-20 % outliers ----------------

SESSIONS = 50


def _session(rng: np.random.Generator, share: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A hand-turned magnetometer (reference 1): a known symmetric M and offset, noise 0.5 %,
    ``share`` of its samples outliers (half glitches anywhere, half disturbed stretches at 1.15-1.5
    times the field). Returns the samples, the true offset and the true gains (diag of M⁻¹)."""
    n = 1500
    a = np.eye(3) + 0.05 * rng.standard_normal((3, 3))
    a = 0.5 * (a + a.T) * rng.uniform(0.8, 1.2)
    b = rng.normal(0, 0.5, 3)
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    raw = u @ a.T + b + rng.normal(0, 0.005, (n, 3))
    bad = int(share * n)
    for _ in range(bad // 2):
        raw[rng.integers(n)] = b + rng.normal(0, 5, 3)
    done = 0
    while done < bad - bad // 2:
        start, length = int(rng.integers(n - 60)), int(rng.integers(20, 60))
        length = min(length, bad - bad // 2 - done)
        raw[start : start + length] = b + (raw[start : start + length] - b) * rng.uniform(1.15, 1.5)
        done += length
    return raw, b, np.diag(a)


def _fit(raw: np.ndarray, robust: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    settings = fits.SolverSettings(reference=1.0, tolerance_deg=1.0, bias_spread=0.01, robust=robust)
    stats = [model.pose_stats(raw)]
    given = fits.SolverInput("ellipsoid", stats, [raw], [None], ["synthetic"], settings)
    fit = fits.fit_ellipsoid(given)
    s = fit.solution
    return s.offset, s.gain, s.offset_se, s.gain_se


@pytest.mark.slow
@pytest.mark.parametrize("share", [0.0, 0.05, 0.1, 0.2])
def test_robust_fit_stays_within_its_stated_uncertainty_of_the_truth(share: float) -> None:
    """Over 50 sessions per share: the robust fit's z-scores (offset and gain) within ±3 … well,
    within ±4.5 over 300 of them, and their RMS 0.8-1.25; the plain fit's, with outliers, far
    outside."""
    rng = np.random.default_rng(int(share * 100) + 7)
    robust_z, plain_z = [], []
    for _ in range(SESSIONS):
        raw, b, gain = _session(rng, share)
        offset, g, offset_se, gain_se = _fit(raw, True)
        robust_z += [*((offset - b) / offset_se), *((g - gain) / gain_se)]
        if share:
            try:
                offset, g, offset_se, gain_se = _fit(raw, False)
            except (CaptureRejected, RuntimeWarning):  # the glitches' false coverage refusal, or worse
                plain_z.append(np.inf)
                continue
            plain_z += [*((offset - b) / offset_se), *((g - gain) / gain_se)]
    z = np.array(robust_z)
    assert np.abs(z).max() < 4.5, np.abs(z).max()
    assert 0.8 <= float(np.sqrt(np.mean(z**2))) <= 1.25, float(np.sqrt(np.mean(z**2)))
    if share:
        assert float(np.sqrt(np.mean(np.array(plain_z) ** 2))) > 3.0


def test_a_capture_too_poorly_spread_once_its_glitches_are_out_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Coverage is judged on the samples kept: a capture that never turned its +z up is refused
    for that, saying the outliers were left out first, not for a direction the glitches made."""
    head, v = _real()
    centre = np.median(v, axis=0)
    low = v[v[:, 2] < centre[2]]  # one hemisphere of the field only
    low[10], low[20] = [3.1, 2.9, -3.0], [-2.9, -3.2, 3.3]
    capture = _write(tmp_path / "half.csv", head, low)
    r = run(capsys, "solve", "--sensor", "magnetometer", "--poses", capture, "-o", tmp_path / "h.json")
    assert r.code == 3, r.err
    first = r.err.splitlines()[0]
    assert "do not cover enough directions" in first
    assert f"(judged on the {len(low) - 2:,} samples kept: 2 outliers left out)" in first
    assert not (tmp_path / "h.json").exists()


def _directions_session(disturbed: float) -> dict[str, np.ndarray]:
    """Eight labelled poses (the six faces and two diagonals) of a known accelerometer, the last
    read ``disturbed`` times as far from its offset (a pose held in a disturbed field, or pushed)."""
    rng = np.random.default_rng(3)
    a = np.array([[1.01, 0.005, 0.0], [0.0, 0.99, 0.004], [0.003, 0.0, 1.02]])
    b = np.array([0.02, -0.01, 0.03])
    dirs = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1), (0.707, 0.707, 0), (0, 0.707, 0.707)]
    out = {}
    for k, d in enumerate(dirs):
        v = np.array(d, dtype=float) / np.linalg.norm(d)
        out[",".join(f"{x:.6g}" for x in v)] = (
            a @ (v * (disturbed if k == 7 else 1.0)) + b + rng.normal(size=(300, 3)) * 0.002
        )
    return out


def test_a_least_squares_pose_off_the_fit_of_the_others_is_left_out_and_named() -> None:
    """Issue "Real recordings, round 3", item 1: least-squares over more poses than its 12
    parameters need. One pose 15 % off bent the offsets by up to 8.7 mg (its residual spread over
    every pose); left out by its deleted residual, the fit is the others' (within 0.1 mg)."""
    truth_b = np.array([0.02, -0.01, 0.03])
    robust_fit = tumblecal.solve(_directions_session(1.15), method="least-squares")
    plain_fit = tumblecal.solve(_directions_session(1.15), method="least-squares", no_robust=True)
    clean = tumblecal.solve(_directions_session(1.0), method="least-squares")
    assert robust_fit.calibration is not None and plain_fit.calibration is not None  # noqa: PT018
    assert np.abs(robust_fit.calibration.offset - truth_b).max() < 2e-4
    assert np.abs(plain_fit.calibration.offset - truth_b).max() > 5e-3
    left = robust_fit.calibration.outliers
    assert left is not None
    assert left.count == 300
    assert [s.file for s in left.stretches] == ["<0,0.707107,0.707107>"]
    assert any("outliers: 300 of 2,400 samples left out" in n for n in robust_fit.notes)
    assert clean.calibration is not None
    assert clean.calibration.outliers is None  # a clean session: the plain fit


def test_a_sphere_pose_off_the_fit_is_left_out_and_named() -> None:
    """The sphere over 14 static poses (orientation unknown), one read 12 % long (a block held in a
    disturbed field): left out, named, and the fit the others'; --no-robust keeps it."""
    rng = np.random.default_rng(9)
    a, b = np.diag([1.02, 0.98, 1.01]), np.array([0.02, -0.03, 0.01])
    ups = rng.normal(size=(14, 3))
    ups /= np.linalg.norm(ups, axis=1)[:, None]
    data = [a @ (u * (1.12 if k == 5 else 1.0)) + b + rng.normal(size=(200, 3)) * 0.002 for k, u in enumerate(ups)]
    given = {",".join(f"{x:.6g}" for x in u): d for u, d in zip(ups, data, strict=True)}
    done = tumblecal.solve(given, method="sphere")
    plain = tumblecal.solve(given, method="sphere", no_robust=True)
    assert done.calibration is not None
    assert plain.calibration is not None
    assert np.abs(done.calibration.offset - b).max() < 2e-3
    assert np.abs(plain.calibration.offset - b).max() > 4e-3
    left = done.calibration.outliers
    assert left is not None
    assert left.count == 200
