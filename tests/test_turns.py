"""A gyroscope's scale and misalignment from known turns (``--turns``, method ferraris-turns):
known truth from synthetic sessions, imucal's own figures on its annotated session (pinned in
tests/data/imucal_gyro, see pin.py there), the rejections and the usage errors."""

from __future__ import annotations

import csv
import gzip
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import tumblecal as run
from tumblecal_cli.core import turn_fit

DATA = Path(__file__).resolve().parent / "data"
PINNED = json.loads((DATA / "imucal_gyro" / "ferraris_annotated.json").read_text())
IMUCAL = PINNED["expected_angle_-360"]  # imucal's default expected_angle
FACE_MAP = "x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z"
TURNS = "x_rot=+x,y_rot=+y,z_rot=+z"
SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
LABELS = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """imucal's annotated session (raw counts, 204.8 Hz, a `part` label column), decompressed."""
    target = tmp_path_factory.mktemp("imucal") / "annotated_session.csv"
    target.write_bytes(gzip.decompress((DATA / "logs" / "imucal_annotated_session.csv.gz").read_bytes()))
    return target


def solve_turns(log: Path, out: Path, *extra: str, angle: str = "360", turns: str = TURNS) -> Any:
    return run(
        "solve", "--sensor", "gyroscope", "--log", log, "--rate", "204.8", "--pose-column", "part",
        "--pose-map", FACE_MAP, "--turns", turns, "--turn-angle", angle, "-o", out, *extra,
    )  # fmt: skip


def imucal_matrix(pinned: dict[str, Any]) -> Any:
    """imucal corrects gyr_out = R_g⁻¹ K_g⁻¹ (gyr - b_g - K_ga acc): M = (K_g R_g)⁻¹."""
    return np.linalg.inv(np.asarray(pinned["K_g"]) @ np.asarray(pinned["R_g"]))


# -- imucal's annotated session --------------------------------------------------------------


def test_the_pinned_figures_are_imucals_run_on_the_session_in_tests_data(session: Path) -> None:
    import hashlib

    assert hashlib.sha256(session.read_bytes()).hexdigest() == PINNED["input"]["sha256"]
    assert PINNED["imucal_version"] == "2.6.0"


def test_cli_reproduces_imucals_gyroscope_calibration(session: Path, tmp_path: Path) -> None:
    """+360 (the turns read positive: right-hand about +x +y +z) is imucal's result with its
    expected_angle +360, and imucal's default (-360) negated: the same K_g, R_g's sign flipped."""
    out = tmp_path / "gyro.json"
    r = solve_turns(session, out, "-q")
    assert r.code == 0, r.err
    assert r.out == ""
    doc = json.loads(out.read_text())
    assert (doc["sensor"], doc["method"], doc["units"]) == ("gyroscope", "ferraris-turns", "deg/s")
    assert doc["columns"] == ["gyr_x", "gyr_y", "gyr_z"]
    np.testing.assert_allclose(doc["offset"], IMUCAL["b_g"], rtol=1e-6)
    np.testing.assert_allclose(doc["matrix"], -imucal_matrix(IMUCAL), rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(doc["matrix"], imucal_matrix(PINNED["expected_angle_+360"]), rtol=1e-6, atol=1e-12)
    sens = doc["g_sensitivity"]
    np.testing.assert_allclose(np.asarray(sens["matrix"]) / 9.81, IMUCAL["K_ga"], rtol=1e-6)  # imucal's is per m/s^2
    accel = np.linalg.inv(np.asarray(IMUCAL["K_a"]) @ np.asarray(IMUCAL["R_a"])) / 9.81  # m/s^2 into g
    np.testing.assert_allclose(sens["accelerometer"]["offset"], IMUCAL["b_a"], rtol=1e-6)
    np.testing.assert_allclose(sens["accelerometer"]["matrix"], accel, rtol=1e-6, atol=1e-12)
    assert [t["label"] for t in doc["turns"]] == ["x_rot", "y_rot", "z_rot"]
    assert [t["samples"] for t in doc["turns"]] == [1305, 1093, 1420]
    assert all(t["measured_deg"] == pytest.approx(360.0) and t["residual_deg"] < 1e-9 for t in doc["turns"])
    assert [p["pose"] for p in doc["poses"]] == list(SIX)
    assert [p["label"] for p in doc["poses"]] == list(LABELS)
    # 1-sigma from the noise at rest (3.5 counts per sample, 5.6k samples): small, not zero
    assert all(0 < u < 0.1 for u in doc["uncertainty"]["offset"])
    assert all(0 < u < 0.01 for u in doc["uncertainty"]["gain"])
    assert doc["verdict"]["pass"] is True


def test_core_with_imucals_angle_is_imucals_matrix(session: Path) -> None:
    """The same numbers with imucal's default expected_angle of -360 (what the CLI refuses on
    this session: its turns read positive)."""
    rows = list(csv.DictReader(session.read_text().splitlines()))

    def part(label: str, kind: str) -> Any:
        return np.array([[float(r[f"{kind}_{a}"]) for a in "xyz"] for r in rows if r["part"] == label])

    still = turn_fit.FaceReadings([part(x, "acc") for x in LABELS], [part(x, "gyr") for x in LABELS])
    turns = [
        turn_fit.KnownTurn(
            part(label, "acc"), part(label, "gyr"), np.eye(3)[k], -360.0, np.full(len(part(label, "gyr")), 1 / 204.8)
        )
        for k, label in enumerate(("x_rot", "y_rot", "z_rot"))
    ]
    fit = turn_fit.ferraris(still, turns)
    np.testing.assert_allclose(fit.solution.matrix, imucal_matrix(IMUCAL), rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(fit.solution.offset, IMUCAL["b_g"], rtol=1e-6)
    np.testing.assert_allclose(fit.g_sensitivity / 9.81, IMUCAL["K_ga"], rtol=1e-6)
    # K_g is the length of each row of A = K_g R_g, R_g those rows made unit length
    a = np.linalg.inv(fit.solution.matrix)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), np.diag(IMUCAL["K_g"]), rtol=1e-6)
    np.testing.assert_allclose(a / np.linalg.norm(a, axis=1)[:, None], IMUCAL["R_g"], rtol=1e-6, atol=1e-12)


def test_python_api_gives_the_same_calibration(session: Path, tmp_path: Path) -> None:
    solved = tumblecal.solve_log(
        session, sensor="gyroscope", rate=204.8, pose_column="part", pose_map=FACE_MAP, turns=TURNS, turn_angle=360
    )
    assert solved.status == 0
    cal = solved.calibration
    assert cal is not None
    assert cal.method == "ferraris-turns"
    np.testing.assert_allclose(cal.matrix, -imucal_matrix(IMUCAL), rtol=1e-6, atol=1e-12)
    raw = np.array([[10.0, -20.0, 30.0]])
    np.testing.assert_allclose(cal.apply(raw), (raw - cal.offset) @ cal.matrix.T)


def test_apply_corrects_the_gyroscope_columns(session: Path, tmp_path: Path) -> None:
    cal = tmp_path / "gyro.json"
    assert solve_turns(session, cal, "-q").code == 0
    out = tmp_path / "corrected.csv"
    r = run("apply", "--cal", cal, session, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(cal.read_text())
    first_in = next(csv.DictReader(session.read_text().splitlines()))
    first_out = next(csv.DictReader(out.read_text().splitlines()))
    raw = np.array([float(first_in[f"gyr_{a}"]) for a in "xyz"])
    want = np.asarray(doc["matrix"]) @ (raw - np.asarray(doc["offset"]))
    np.testing.assert_allclose([float(first_out[f"gyr_{a}"]) for a in "xyz"], want, rtol=1e-9)
    assert first_out["acc_x"] == first_in["acc_x"]  # the accelerometer's columns pass through


# -- rejections (exit 3, naming the section; nothing written) -------------------------------


def _edited(session: Path, tmp_path: Path, label: str, change: Any) -> Path:
    """The session with the gyroscope columns of one section's rows changed."""
    rows = list(csv.DictReader(session.read_text().splitlines()))
    rng = np.random.default_rng(7)
    for r in rows:
        if r["part"] == label:
            for a in "xyz":
                r[f"gyr_{a}"] = repr(change(float(r[f"gyr_{a}"]), rng))
    target = tmp_path / f"edited_{label}.csv"
    with target.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return target


def test_imucals_angle_on_a_session_that_turned_the_other_way_is_rejected(session: Path, tmp_path: Path) -> None:
    out = tmp_path / "gyro.json"
    r = solve_turns(session, out, "-q", angle="-360")
    assert r.code == 3
    assert r.err.startswith(
        f"error: {session}: turn x_rot: integrated +369° about +x (the other way round) where --turn-angle gives -360°"
    )
    assert "error: turn z_rot:" in r.err
    assert not out.exists()


def test_turns_about_two_axes_are_rejected(session: Path, tmp_path: Path) -> None:
    out = tmp_path / "gyro.json"
    r = solve_turns(session, out, "-q", turns="x_rot=+x,y_rot=+y,z_rot=-x")
    assert r.code == 3
    assert r.err.splitlines()[0] == (
        f"error: {session}: turns x_rot (+x), y_rot (+y), z_rot (-x): rotations about 2 independent axes; need 3"
    )
    assert not out.exists()


def test_a_turn_of_half_the_angle_is_rejected(session: Path, tmp_path: Path) -> None:
    log = _edited(session, tmp_path, "z_rot", lambda v, rng: v / 2)
    r = solve_turns(log, tmp_path / "gyro.json", "-q")
    assert r.code == 3
    first = r.err.splitlines()[0]
    assert first.startswith(f"error: {log}: turn z_rot: integrated +18")
    assert "where --turn-angle gives +360°" in first


def test_a_still_section_that_moved_is_rejected(session: Path, tmp_path: Path) -> None:
    log = _edited(session, tmp_path, "y_a", lambda v, rng: v + rng.normal(0, 100))  # 100 counts: ~6 deg/s
    out = tmp_path / "gyro.json"
    r = solve_turns(log, out, "-q")
    assert r.code == 3
    assert r.err.splitlines()[0].startswith(f"error: {log}: still section y_a moved: its gyroscope varies 6.")
    assert not out.exists()
    assert solve_turns(log, out, "-q", "--no-check", "moved").code == 0


def test_a_missing_face_is_rejected(session: Path, tmp_path: Path) -> None:
    r = run(
        "solve", "--sensor", "gyroscope", "--log", session, "--rate", "204.8", "--pose-column", "part",
        "--pose-map", "x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z", "--turns", TURNS, "--turn-angle", "360", "-q",
    )  # fmt: skip
    assert r.code == 3
    assert "ferraris-turns needs a still section on each face; none for -z" in r.err


# -- usage errors (exit 2) ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--turn-angle", "360"], "--turns calibrates a gyroscope: give --sensor gyroscope (not accelerometer)"),
        (["--sensor", "gyroscope"], "--turn-angle: the signed angle of each turn in degrees"),
        (["--sensor", "gyroscope", "--turn-angle", "0"], "--turn-angle: the signed angle of each turn in degrees"),
        (["--sensor", "gyroscope", "--turn-angle", "360", "--method", "six-pose"], "--turns is for the ferraris"),
    ],
)
def test_turn_options_that_cannot_work(session: Path, args: list[str], message: str) -> None:
    r = run("solve", "--log", session, "--rate", "204.8", "--pose-column", "part", "--turns", TURNS, *args)
    assert r.code == 2
    assert message in r.err


def test_turns_need_the_time(session: Path) -> None:
    r = run(
        "solve", "--sensor", "gyroscope", "--log", session, "--pose-column", "part", "--pose-map", FACE_MAP,
        "--turns", TURNS, "--turn-angle", "360",
    )  # fmt: skip
    assert r.code == 2
    assert "integrating the turns needs the time between samples" in r.err


def test_method_ferraris_turns_without_turns_is_a_usage_error(session: Path) -> None:
    r = run("solve", "--sensor", "gyroscope", "--log", session, "--method", "ferraris-turns")
    assert r.code == 2
    assert "ferraris-turns takes the turns of a labelled log" in r.err


# -- known truth ------------------------------------------------------------------------------


def synthetic(
    rng: np.random.Generator, rate: float = 200.0, noise: float = 3.0
) -> tuple[turn_fit.FaceReadings, list[turn_fit.KnownTurn]]:
    """A Ferraris session with known A, b, G: 5-s still faces, then 360° about +x, +y, +z in 6 s."""
    still_acc, still_gyr = [], []
    for face in np.vstack([np.eye(3), -np.eye(3)])[[0, 3, 1, 4, 2, 5]]:
        n = int(5 * rate)
        still_acc.append(ACC_A @ face + ACC_B + rng.normal(0, 2.0, (n, 3)))
        still_gyr.append(np.tile(B + G @ face, (n, 1)) + rng.normal(0, noise, (n, 3)))
    turns = []
    for k in range(3):
        n = int(6 * rate)
        omega = np.zeros((n, 3))
        omega[:, k] = 360.0 / (n / rate) * (1 - np.cos(np.linspace(0, 2 * np.pi, n)))  # smooth start and stop
        omega *= 360.0 / (omega[:, k].sum() / rate)
        up = np.eye(3)[k]
        acc = np.tile(ACC_A @ up + ACC_B, (n, 1)) + rng.normal(0, 2.0, (n, 3))
        gyr = omega @ A.T + B + G @ up + rng.normal(0, noise, (n, 3))
        turns.append(turn_fit.KnownTurn(acc, gyr, up, 360.0, np.full(n, 1 / rate)))
    return turn_fit.FaceReadings(still_acc, still_gyr), turns


A = np.array([[16.4, 0.15, -0.2], [-0.1, 16.9, 0.25], [0.2, -0.12, 15.9]])  # counts per deg/s, ~1° misaligned
B = np.array([2.0, -4.5, -3.6])
G = np.array([[0.02, -0.16, 0.18], [0.14, 0.05, -0.09], [-0.09, 0.08, -0.04]])  # counts per g
ACC_A = np.diag([2048.0, 2040.0, 2100.0]) + 5.0
ACC_B = np.array([-6.0, -48.0, -29.0])


def test_known_truth_is_recovered() -> None:
    fit = turn_fit.ferraris(*synthetic(np.random.default_rng(1)))
    np.testing.assert_allclose(np.linalg.inv(fit.solution.matrix), A, atol=5 * float(fit.solution.gain_se.max()))
    assert np.all(np.abs(fit.solution.offset - B) < 5 * fit.solution.offset_se)
    np.testing.assert_allclose(fit.g_sensitivity, G, atol=0.5)


def test_reported_uncertainty_matches_the_spread() -> None:
    """Monte Carlo: the gains' spread over 200 sessions against the 1-sigma each reports."""
    rng = np.random.default_rng(2)
    fits = [turn_fit.ferraris(*synthetic(rng, rate=100.0)) for _ in range(200)]
    gains = np.array([np.diag(np.linalg.inv(f.solution.matrix)) for f in fits])
    offsets = np.array([f.solution.offset for f in fits])
    ratio_gain = gains.std(axis=0) / np.mean([f.solution.gain_se for f in fits], axis=0)
    ratio_offset = offsets.std(axis=0) / np.mean([f.solution.offset_se for f in fits], axis=0)
    assert np.all((ratio_gain > 0.75) & (ratio_gain < 1.3)), ratio_gain
    assert np.all((ratio_offset > 0.75) & (ratio_offset < 1.3)), ratio_offset


def test_limits_judge_a_gyroscope_calibration(session: Path, tmp_path: Path) -> None:
    out = tmp_path / "gyro.json"
    r = solve_turns(session, out, "-q", "--max-offset", "1")  # the bias is 2-4.5 counts
    assert r.code == 1
    doc = json.loads(out.read_text())  # written: stations archive failing units too
    assert [f["code"] for f in doc["verdict"]["failures"]] == ["limit.offset.x", "limit.offset.y", "limit.offset.z"]
