"""tumblecal align: the magnetometer's rotation onto the accelerometer's axes from the constant
angle between gravity and the field, and the rotation between several IMUs from their still
blocks (core.alignment, pipeline.align, cli.align)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import assert_one_error, run
from tests.ulog_writer import write_streams
from tumblecal_cli.core import alignment
from tumblecal_cli.io.calfiles import calfile

DATA = Path(__file__).parent / "data"
CK_ACC_LOG = DATA / "logs" / "ckexplorer_acc_log.csv"  # the accelerometer alone, paused in many orientations
CK_BOTH_LOG = DATA / "logs" / "ckexplorer_acc_mag_log.csv.gz"  # accelerometer and magnetometer, tumbled
PX4_SMALL = DATA / "px4" / "pyulog_sample_log_small.ulg.gz"  # PX4's sample: three raw sensor_accel

UP = np.array([0.0, 0.0, 1.0])
DIP = np.radians(60.0)
FIELD = np.array([np.cos(DIP), 0.0, -np.sin(DIP)])  # north and down
AXIS = np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0)
TRUE = alignment.exp_map(np.radians(3.0) * AXIS)  # v_acc = TRUE v_mag


def poses(rng: np.random.Generator, k: int) -> list[np.ndarray]:
    """``k`` random orientations of the unit (world to sensor: the transposes of random rotations)."""
    out = []
    for _ in range(k):
        q = rng.normal(size=4)
        w, x, y, z = q / np.linalg.norm(q)
        out.append(
            np.array(
                [
                    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                ]
            ).T
        )
    return out


def mag_blocks(rng: np.random.Generator, k: int = 12, samples: int = 200) -> tuple[np.ndarray, ...]:
    """Block means of a calibrated accelerometer (g, 2 mg per sample) and magnetometer (field of
    1, 0.5 % per sample) over ``samples`` each, the magnetometer turned by TRUE, and their noise."""
    c = poses(rng, k)
    g = np.array([m @ UP for m in c])
    m = np.array([r @ FIELD for r in c]) @ TRUE  # TRUE.T applied to each row
    sg, sm = 0.002 / np.sqrt(samples), 0.005 / np.sqrt(samples)
    g = g + rng.normal(size=g.shape) * sg
    m = m + rng.normal(size=m.shape) * sm
    return g, m, np.full(k, sg), np.full(k, sm)


def error_deg(fitted: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The rotation vector (degrees) that takes ``truth`` onto ``fitted`` (left perturbation)."""
    return np.degrees(alignment.log_map(fitted @ truth.T))


def test_a_3_degree_rotation_is_recovered_to_005_degrees() -> None:
    fit = alignment.mag_to_accel(*mag_blocks(np.random.default_rng(7)))
    r = fit.rotation
    assert np.linalg.norm(error_deg(r.matrix, TRUE)) < 0.05
    assert r.angle_deg == pytest.approx(3.0, abs=0.05)
    assert fit.dip_deg == pytest.approx(60.0, abs=0.05)
    assert r.observable()
    assert r.sigma_deg.max() < 0.05
    # the heading error a 3° misalignment causes, removed by the rotation: degrees, not tenths
    assert 1.0 < np.abs(fit.heading_error).max() < 6.0
    assert np.std(fit.dip_after) < np.std(fit.dip_before) / 5


@pytest.mark.slow
def test_mag_alignment_uncertainty_holds_in_monte_carlo() -> None:
    """The stated 1-sigma of each rotation component and of the dip: z-scores within ±3, spread near 1."""
    rng = np.random.default_rng(11)
    z, dz = [], []
    for _ in range(300):
        fit = alignment.mag_to_accel(*mag_blocks(rng, k=10, samples=20))
        z.append(error_deg(fit.rotation.matrix, TRUE) / fit.rotation.sigma_deg)
        dz.append((fit.dip_deg - 60.0) / fit.dip_sigma_deg)
    zs, dips = np.array(z), np.array(dz)
    assert np.abs(zs).max() < 4.5  # 900 draws: ±3 holds for all but a few
    assert np.mean(np.abs(zs) > 3) < 0.01
    assert np.all((zs.std(axis=0) > 0.7) & (zs.std(axis=0) < 1.2))
    assert np.abs(zs.mean(axis=0)).max() < 0.2
    assert np.mean(np.abs(dips) > 3) < 0.01
    assert 0.7 < dips.std() < 1.2


def test_turning_only_about_the_vertical_leaves_the_rotation_undetermined() -> None:
    """Turned about gravity alone, the east-west axis stays horizontal: rotation about the
    sensor's vertical axis changes no dot product, and its 1-sigma says so."""
    k = 10
    g, m = [], []
    for yaw in np.linspace(0, 2 * np.pi, k, endpoint=False):
        c = alignment.exp_map(np.array([0.0, 0.0, yaw]))
        g.append(c @ UP)
        m.append((c @ FIELD) @ TRUE)
    rng = np.random.default_rng(3)
    noisy = np.array(m) + rng.normal(size=(k, 3)) * 1e-4
    fit = alignment.mag_to_accel(np.array(g), noisy, np.full(k, 1e-4), np.full(k, 1e-4))
    assert not fit.rotation.observable()


def test_heading_change_of_a_turn_about_the_vertical_is_its_angle() -> None:
    g = np.array([[0.0, 0.0, 1.0]])
    m = np.array([[0.5, 0.0, -0.8]])
    turned = m @ alignment.exp_map(np.radians([0.0, 0.0, 2.0])).T
    assert alignment.heading_change(g, m, turned)[0] == pytest.approx(2.0)


def imu_blocks(rng: np.random.Generator, truth: np.ndarray, k: int = 8) -> tuple[np.ndarray, ...]:
    c = poses(rng, k)
    ref = np.array([m @ UP for m in c]) * 9.81
    other = ref @ truth  # truth.T applied to each row: ref = truth other
    s = 0.01
    return ref + rng.normal(size=ref.shape) * s, other + rng.normal(size=ref.shape) * s, np.full(k, s * np.sqrt(2))


def test_wahba_recovers_a_rotation_within_its_uncertainty() -> None:
    truth = alignment.exp_map(np.radians([1.0, -2.0, 0.5]))
    fit = alignment.wahba(*imu_blocks(np.random.default_rng(5), truth))
    assert np.all(np.abs(error_deg(fit.matrix, truth)) < 3 * fit.sigma_deg)
    assert fit.sigma_deg.max() < 0.2


@pytest.mark.slow
def test_wahba_uncertainty_holds_in_monte_carlo() -> None:
    truth = alignment.exp_map(np.radians([1.0, -2.0, 0.5]))
    rng = np.random.default_rng(9)
    zs = np.array(
        [
            (lambda f: error_deg(f.matrix, truth) / f.sigma_deg)(alignment.wahba(*imu_blocks(rng, truth, 6)))
            for _ in range(300)
        ]
    )
    assert np.mean(np.abs(zs) > 3) < 0.01
    assert np.all((zs.std(axis=0) > 0.7) & (zs.std(axis=0) < 1.2))


def imu_differences(rng: np.random.Generator, truth: np.ndarray, k: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Noiseless block means of two IMUs that differ by ``truth`` and by what their calibrations
    leave (an offset of 0.1 m/s² and a gain 0.5 % off on one axis)."""
    ref = np.array([m @ UP for m in poses(rng, k)]) * 9.81
    other = (ref * np.array([1.0, 1.005, 1.0]) + np.array([0.1, -0.05, 0.02])) @ truth
    return ref, other


def test_consistency_states_its_uncertainty() -> None:
    ref, other = imu_differences(np.random.default_rng(1), np.eye(3))
    noise = np.full(len(ref), 0.01)
    c = alignment.consistency(ref, other, None, noise)
    assert c.rms == pytest.approx(np.sqrt(np.mean(((ref - other) ** 2).sum(axis=1))))
    assert 0.001 < c.sigma < 0.01  # about noise / sqrt(blocks)
    assert c.noise == pytest.approx(0.01 * np.sqrt(3))
    assert alignment.consistency(ref, other).sigma == 0.0  # no noise given: none stated


@pytest.mark.slow
def test_consistency_uncertainty_holds_in_monte_carlo() -> None:
    """The consistency as read and after the fitted rotation, over 400 noisy draws of the same
    blocks: (figure - truth) / stated 1-sigma within ±3, spread near 1."""
    truth = alignment.exp_map(np.radians([1.0, -2.0, 0.5]))
    ref, other = imu_differences(np.random.default_rng(8), truth)
    s = np.full(len(ref), 0.01)
    as_read = alignment.consistency(ref, other).rms
    rotated = alignment.consistency(ref, other, alignment.wahba(ref, other, s).matrix).rms  # the noiseless best
    rng = np.random.default_rng(12)
    z = []
    for _ in range(400):
        r = ref + rng.normal(size=ref.shape) * s[0] / np.sqrt(2)
        o = other + rng.normal(size=ref.shape) * s[0] / np.sqrt(2)
        c0 = alignment.consistency(r, o, None, s)
        c1 = alignment.consistency(r, o, alignment.wahba(r, o, s).matrix, s)
        z.append([(c0.unbiased - as_read) / c0.sigma, (c1.unbiased - rotated) / c1.sigma])
    zs = np.array(z)
    assert as_read > 0.3
    assert 0.05 < rotated < 0.2
    assert np.abs(zs).max() < 3.5
    assert np.mean(np.abs(zs) > 3) < 0.01
    assert np.all((zs.std(axis=0) > 0.7) & (zs.std(axis=0) < 1.3))
    assert np.abs(zs.mean(axis=0)).max() < 0.2


# --- the magnetometer's alignment from a log ----------------------------------------------------


def cal_file(path: Path, sensor: str, columns: list[str]) -> Path:
    cal = calfile.Calibration(sensor, "ellipsoid", 1.0, columns, np.zeros(3), np.eye(3), np.ones(3))
    calfile.write(cal, str(path))
    return path


def mag_log(path: Path, rng: np.random.Generator, k: int = 10) -> Path:
    """A CSV log (100 Hz) of 10 still orientations 2 s each with turns between: accelerometer
    and magnetometer on each row, the magnetometer turned by TRUE."""
    rows, t = [], 0.0
    c = poses(rng, k)
    for a, b in zip(c, [*c[1:], c[0]], strict=True):
        for _ in range(200):
            g, m = a @ UP, (a @ FIELD) @ TRUE
            rows.append([t, *(g + rng.normal(size=3) * 0.002), *(m + rng.normal(size=3) * 0.005)])
            t += 0.01
        for s in np.linspace(0, 1, 60):  # a turn: moving readings
            v = (1 - s) * (a @ UP) + s * (b @ UP) + rng.normal(size=3) * 0.2
            f = (1 - s) * (a @ FIELD) + s * (b @ FIELD)
            rows.append([t, *v, *((f / np.linalg.norm(f)) @ TRUE + rng.normal(size=3) * 0.005)])
            t += 0.01
    text = "t,ax,ay,az,mx,my,mz\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows) + "\n"
    path.write_text(text)
    return path


@pytest.mark.slow
def test_align_finds_the_magnetometers_rotation_in_a_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2))
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    mag = cal_file(tmp_path / "mag.json", "magnetometer", ["mx", "my", "mz"])
    out = tmp_path / "alignment.json"
    code, stdout, err = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, log, "-o", out, "--json")
    assert code == 0, err
    doc, summary = json.loads(out.read_text()), json.loads(stdout)
    assert (summary["status"], summary["angle_deg"]) == ("pass", doc["angle_deg"])
    assert (doc["format"], doc["kind"]) == ("tumblecal-alignment", "magnetometer-to-accelerometer")
    assert doc["blocks"] == 10
    fitted = np.array(doc["rotation"])
    assert np.linalg.norm(error_deg(fitted, TRUE)) < 0.05
    assert np.all(np.abs(error_deg(fitted, TRUE)) < 3 * np.array(doc["rotation_sigma_deg"]))
    assert doc["dip_deg"] == pytest.approx(60.0, abs=3 * doc["dip_sigma_deg"] + 1e-3)
    assert doc["heading_error_deg"]["max"] > 1.0
    assert "rotation 2.99" in err or "rotation 3.00" in err, err
    assert "heading error removed" in err


def test_align_of_a_magnetometer_needs_both_calibrations(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    out = tmp_path / "alignment.json"
    result = run(capsys, "align", "--accel-cal", acc, tmp_path / "log.csv", "-o", out)
    assert_one_error(result, "the magnetometer's alignment takes both --accel-cal and --mag-cal")
    assert not out.exists()


def test_a_calibration_of_the_wrong_sensor_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2), k=4)
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    code, out, err = run(capsys, "align", "--accel-cal", acc, "--mag-cal", acc, log)
    assert code == 2
    assert out == ""
    assert "--mag-cal takes the magnetometer's calibration, not the accelerometer's" in err


def test_too_few_orientations_are_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2), k=2)
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    mag = cal_file(tmp_path / "mag.json", "magnetometer", ["mx", "my", "mz"])
    out = tmp_path / "alignment.json"
    code, stdout, err = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, log, "-o", out)
    assert code == 3
    assert stdout == ""
    assert not out.exists()
    assert "still blocks in 2 orientations" in err


# --- several IMUs --------------------------------------------------------------------------------


def imu_ulog(path: Path, rng: np.random.Generator, truth: np.ndarray, imus: int = 2, k: int = 8) -> Path:
    """A ULog with ``imus`` sensor_accel instances at 200 Hz (their clocks offset by 1.3 ms), still
    2 s in each of ``k`` orientations with turns between; instance i > 0 turned by ``truth``."""
    c = poses(rng, k)
    values = []
    for a, b in zip(c, [*c[1:], c[0]], strict=True):
        values += [a @ UP * 9.81] * 400
        values += [((1 - s) * (a @ UP) + s * (b @ UP)) * 9.81 for s in np.linspace(0, 1, 100)]
    v = np.array(values)
    streams = []
    for i in range(imus):
        t = (1_000_000 + 1300 * i + np.arange(len(v)) * 5000).astype(np.int64)
        mine = v if i == 0 else v @ truth
        streams.append(("sensor_accel", i, t, mine + rng.normal(size=v.shape) * 0.02))
    return write_streams(path, streams)


def test_align_finds_each_imus_rotation(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth = alignment.exp_map(np.radians([0.5, -1.0, 2.0]))
    log = imu_ulog(tmp_path / "three.ulg", np.random.default_rng(4), truth, imus=3)
    limits = tmp_path / "limits.yaml"
    limits.write_text("imu_consistency: 0.1\n")
    out = tmp_path / "imus.json"
    code, stdout, err = run(capsys, "align", log, "--limits", limits, "-o", out, "--json")
    assert code == 1, err  # turned 2.3°, the readings differ by 0.4 m/s² unrotated, 0.1 allowed
    doc = json.loads(out.read_text())
    assert (doc["kind"], doc["reference"], doc["orientations"]) == ("imus", "sensor_accel:0", 8)
    assert [p["stream"] for p in doc["imus"]] == ["sensor_accel:1", "sensor_accel:2"]
    for p in doc["imus"]:
        e = error_deg(np.array(p["rotation"]), truth)
        assert np.all(np.abs(e) < 3 * np.array(p["rotation_sigma_deg"]))
        assert p["consistency_aligned"] < 0.01 < 0.3 < p["consistency"]
    assert doc["verdict"]["pass"] is False
    assert json.loads(stdout)["status"] == "fail"
    assert "FAIL: imu_consistency 0.1 m/s^2" in err


def test_align_of_one_imu_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = imu_ulog(tmp_path / "one.ulg", np.random.default_rng(4), np.eye(3), imus=1, k=3)
    out = tmp_path / "imus.json"
    result = run(capsys, "align", log, "-o", out)
    assert_one_error(
        result,
        f"{log}: one IMU: the log holds 1 accelerometer stream with samples (sensor_accel:0); "
        "align compares two or three",
    )
    assert not out.exists()


@pytest.mark.slow
def test_real_px4_imus_judged_by_pxs_own_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """PX4's sample log: three raw sensor_accel streams at 1 Hz on the ground (one orientation):
    the rotation about gravity is not determined; uncalibrated, the second differs from the first
    by 0.36 m/s² RMS, inside PX4's own arming limit (COM_ARM_IMU_ACC, 0.7 m/s² by default) and
    outside a tighter one."""
    log = tmp_path / "sample_log_small.ulg"
    log.write_bytes(gzip.decompress(PX4_SMALL.read_bytes()))
    for bound, status in ((0.7, 0), (0.2, 1)):
        limits = tmp_path / "limits.yaml"
        limits.write_text(f"imu_consistency: {bound}\n")
        code, out, err = run(capsys, "align", log, "--window", "3", "--min-duration", "4", "--limits", limits, "--json")
        assert code == status, err
        doc = json.loads(out)
        assert (doc["orientations"], doc["units"]) == (1, "m/s^2")
        assert [p["stream"] for p in doc["imus"]] == ["sensor_accel:1", "sensor_accel:2"]
        assert [round(p["consistency"], 2) for p in doc["imus"]] == [0.36, 0.08]
        assert all("rotation" not in p for p in doc["imus"])
        assert "rotation not determined" in err
    assert [f["code"] for f in doc["verdict"]["failures"]] == ["limit.imu_consistency.1"]


@pytest.mark.slow
def test_real_ckexplorer_log_has_a_small_rotation(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """ckexplorer's log (a tumble by hand with short pauses): the rotation is below a degree and
    known to a few tenths, the dip the same in every block to about a degree."""
    acc, mag = tmp_path / "acc.json", tmp_path / "mag.json"
    assert run(capsys, "solve", "--log", CK_ACC_LOG, "-o", acc).code == 0
    solved = run(
        capsys, "solve", "--sensor", "magnetometer", "--method", "ellipsoid", "--poses", CK_BOTH_LOG, "-o", mag
    )
    assert solved.code == 0
    args = ["--window", "10", "--min-duration", "10", "--max-noise", "0.1", "--json"]
    code, out, err = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, CK_BOTH_LOG, *args)
    assert code == 0, err
    doc = json.loads(out)
    assert doc["blocks"] == 43
    assert doc["angle_deg"] == pytest.approx(0.42, abs=0.01)
    assert doc["angle_sigma_deg"] == pytest.approx(0.35, abs=0.01)
    assert doc["dip_deg"] == pytest.approx(-18.4, abs=0.05)
    assert doc["dip_spread_deg"]["after"] < 2.0


def test_aligned_magnetometer_calibration_reads_in_the_accelerometers_axes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--aligned-mag: the rotation in the matrix, recorded in the file, told by show; apply then
    gives readings whose angle to gravity is the same in every block."""
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2))
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    mag = cal_file(tmp_path / "mag.json", "magnetometer", ["mx", "my", "mz"])
    out = tmp_path / "mag-aligned.json"
    code, _, err = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, log, "-o", tmp_path / "a.json",
                       "--aligned-mag", out)  # fmt: skip
    assert code == 0, err
    cal = calfile.load(out)
    assert np.linalg.norm(error_deg(cal.matrix, TRUE)) < 0.05  # M' = R M, M = I
    record = cal.fields["alignment"]
    assert isinstance(record, dict)
    assert record["to"] == str(acc)
    code, shown, _ = run(capsys, "show", out)
    assert code == 0
    assert "aligned:     rotated 3.0" in shown or "aligned:     rotated 2.99" in shown


@pytest.mark.slow
def test_solve_align_to_rotates_a_magnetometers_matrix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2), k=24)
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    plain, turned = tmp_path / "mag.json", tmp_path / "mag-aligned.json"
    args: list[str | Path] = ["solve", "--sensor", "magnetometer", "--method", "ellipsoid", "--poses", log]
    assert run(capsys, *args, "-o", plain).code == 0
    code, _, err = run(capsys, *args, "--align-to", acc, "-o", turned)
    assert code == 0, err
    assert "note: aligned to" in err
    rotation = calfile.load(turned).matrix @ np.linalg.inv(calfile.load(plain).matrix)
    assert np.linalg.norm(error_deg(rotation, TRUE)) < 0.1


def test_solve_align_to_is_for_a_magnetometer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2), k=3)
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    out = tmp_path / "cal.json"
    result = run(capsys, "solve", "--method", "ellipsoid", "--poses", log, "--align-to", acc, "-o", out)
    assert_one_error(result, "--align-to aligns a magnetometer's axes to an accelerometer's, not the accelerometer's")
    assert not out.exists()


# --- several gyroscopes, from turns -------------------------------------------------------------

GYRO_TRUE = alignment.exp_map(np.radians(3.0) * AXIS)  # v_ref = GYRO_TRUE v_other
GYRO_BIAS = np.array([0.02, -0.01, 0.015])  # rad/s


def turn_rates(rng: np.random.Generator, axes: np.ndarray, rate_hz: float = 200.0) -> np.ndarray:
    """Angular rates (rad/s) of a unit at rest 2 s, then turned 1 s about each of ``axes`` in
    turn (a sin² profile peaking at 2 rad/s), at rest 1 s after each."""
    n_rest, n_turn = int(2 * rate_hz), int(rate_hz)
    out = [np.zeros((n_rest, 3))]
    for axis in axes:
        profile = 2.0 * np.sin(np.linspace(0, np.pi, n_turn)) ** 2 * rng.choice([-1.0, 1.0])
        out += [profile[:, None] * axis / np.linalg.norm(axis), np.zeros((n_rest // 2, 3))]
    return np.concatenate(out)


def gyro_ulog(path: Path, rng: np.random.Generator, axes: np.ndarray, imus: int = 2, gain: float = 1.0) -> Path:
    """A ULog of ``imus`` sensor_gyro instances at 200 Hz (clocks 1.3 ms apart), each with its own
    bias (GYRO_BIAS times its number plus one) and 0.005 rad/s of noise per sample; instance i > 0
    turned by GYRO_TRUE and its gain ``gain``."""
    w = turn_rates(rng, axes)
    t0 = np.arange(len(w)) * 5000
    streams = []
    for i in range(imus):
        t = 1_000_000 + 1300 * i + t0
        truth = w if i == 0 else w @ GYRO_TRUE  # the other's reading of the same rate
        if i:  # the same rate at the other's own (later) stamps
            s = (t0 + 1300 * i) / 1e6
            truth = np.column_stack([np.interp(s, t0 / 1e6, w[:, k]) for k in range(3)]) @ GYRO_TRUE * gain
        bias = GYRO_BIAS * (i + 1)
        streams.append(("sensor_gyro", i, t.astype(np.int64), truth + bias + rng.normal(size=w.shape) * 0.005))
    return write_streams(path, streams)


def test_align_finds_each_gyroscopes_rotation_from_turns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Three gyroscopes turned about three axes: a 3° rotation recovered within its stated
    uncertainty, and their rates agree to their noise once rotated."""
    axes = poses(np.random.default_rng(0), 1)[0]  # three orthogonal axes in a random frame
    log = gyro_ulog(tmp_path / "gyros.ulg", np.random.default_rng(6), axes, imus=3)
    limits = tmp_path / "limits.yaml"
    limits.write_text("gyro_consistency: 0.05\n")
    code, stdout, err = run(capsys, "align", "--sensor", "gyroscope", log, "--limits", limits, "--json")
    assert code == 1, err  # turned 3°, the rates differ by about 0.05 rad/s unrotated; 0.05 allowed
    doc = json.loads(stdout)
    assert (doc["sensor"], doc["turn_axes"], doc["units"]) == ("gyroscope", 3, "rad/s")
    assert doc["turning_samples"] > 400
    for p in doc["imus"]:
        e = error_deg(np.array(p["rotation"]), GYRO_TRUE)
        assert np.all(np.abs(e) < 3 * np.array(p["rotation_sigma_deg"])), (e, p["rotation_sigma_deg"])
        assert p["angle_deg"] == pytest.approx(3.0, abs=0.1)
        assert p["consistency_aligned"] < 1.1 * p["consistency_noise"]  # once rotated, only their noise is left
        assert p["consistency"] > 0.04
        assert p["consistency_sigma"] > 0
    assert [f["code"] for f in doc["verdict"]["failures"]] == ["limit.gyro_consistency.1", "limit.gyro_consistency.2"]
    assert "turning samples (faster than" in err
    assert "FAIL: gyro_consistency 0.05 rad/s" in err


def test_each_gyroscopes_calibration_is_applied_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The second gyroscope reads 2 % high: as read its rates differ from the first's by more than
    their noise even once rotated; through its calibration (gain 1.02) only the noise is left."""
    axes = poses(np.random.default_rng(0), 1)[0]
    log = gyro_ulog(tmp_path / "gyros.ulg", np.random.default_rng(6), axes, gain=1.02)
    cals: list[str | Path] = []
    for i, gain in enumerate((1.0, 1.02)):
        cal = calfile.Calibration("gyroscope", "turns", 0.0, ["x", "y", "z"], GYRO_BIAS * (i + 1), np.eye(3) / gain,
                                  np.full(3, gain), units="rad/s")  # fmt: skip
        calfile.write(cal, str(tmp_path / f"g{i}.json"))
        cals += ["--cal", tmp_path / f"g{i}.json"]
    as_read = run(capsys, "align", "--sensor", "gyroscope", log, "--json")
    calibrated = run(capsys, "align", "--sensor", "gyroscope", log, *cals, "--json")
    assert (as_read.code, calibrated.code) == (0, 0), calibrated.err
    before, after = (json.loads(r.out)["imus"][0] for r in (as_read, calibrated))
    assert before["consistency_aligned"] > 1.5 * before["consistency_noise"]
    assert after["consistency_aligned"] < 1.1 * after["consistency_noise"]
    assert after["angle_deg"] == pytest.approx(3.0, abs=3 * after["angle_sigma_deg"])


def test_gyroscopes_turned_about_one_axis_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = gyro_ulog(tmp_path / "yaw.ulg", np.random.default_rng(6), np.array([[0.0, 0.0, 1.0]] * 3))
    out = tmp_path / "alignment.json"
    code, stdout, err = run(capsys, "align", "--sensor", "gyroscope", log, "-o", out)
    assert (code, stdout) == (3, "")
    assert "the rotation is not determined by these turns: they were about one axis" in err
    assert not out.exists()


def test_gyroscopes_that_never_turn_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = gyro_ulog(tmp_path / "still.ulg", np.random.default_rng(6), np.zeros((0, 3)))
    code, _, err = run(capsys, "align", "--sensor", "gyroscope", log)
    assert code == 3
    assert "the gyroscopes' rotation needs turns" in err


def test_a_gyroscopes_rest_is_found_from_its_rates() -> None:
    rng = np.random.default_rng(2)
    w = turn_rates(rng, np.eye(3))
    w = w + np.array([0.01, -0.02, 0.03]) + rng.normal(size=w.shape) * 0.005
    found = alignment.rest(w)
    assert found is not None
    assert found.noise == pytest.approx(0.005, rel=0.1)
    assert np.allclose(found.level, [0.01, -0.02, 0.03], atol=0.001)
    assert alignment.turn_axes(w - found.level, found.noise) == 3


@pytest.mark.slow
def test_gyro_rotation_uncertainty_holds_in_monte_carlo() -> None:
    """Rate vectors of two gyroscopes turned about three axes, 300 draws: the rotation's z-scores
    within ±3 with a spread near 1, the consistency's likewise."""
    rng = np.random.default_rng(13)
    w = turn_rates(rng, np.eye(3))
    w = w[np.linalg.norm(w, axis=1) > 0.05]  # the turning samples: 10 x the noise
    s, sigma = 0.005, np.full(len(w), 0.005)
    plain = w @ GYRO_TRUE  # the rotation's test: the rates differ by it and their noise
    bent = plain + np.array([0.0, 0.0, 0.01]) * np.linalg.norm(w, axis=1)[:, None]  # and a little more
    rotated = alignment.consistency(w, bent, alignment.wahba(w, bent, sigma).matrix).rms  # the consistency's truth
    z, cz = [], []
    for _ in range(300):
        ref = w + rng.normal(size=w.shape) * s / np.sqrt(2)
        noise = rng.normal(size=w.shape) * s / np.sqrt(2)
        fit = alignment.wahba(ref, plain + noise, sigma)
        z.append(error_deg(fit.matrix, GYRO_TRUE) / fit.sigma_deg)
        c = alignment.consistency(ref, bent + noise, alignment.wahba(ref, bent + noise, sigma).matrix, sigma)
        cz.append((c.unbiased - rotated) / c.sigma)
    zs, czs = np.array(z), np.array(cz)
    assert np.mean(np.abs(zs) > 3) < 0.01
    assert np.all((zs.std(axis=0) > 0.7) & (zs.std(axis=0) < 1.3))
    assert np.abs(zs.mean(axis=0)).max() < 0.3
    assert np.mean(np.abs(czs) > 3) < 0.01
    assert 0.7 < czs.std() < 1.3


def test_a_gyroscope_that_never_rests_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Turning all the time (no second at rest): neither its bias nor its noise is known."""
    rng = np.random.default_rng(3)
    t = np.arange(2000) * 5000
    w = np.column_stack([np.sin(2 * np.pi * t / 1e6 * f) for f in (0.7, 1.1, 1.3)])
    streams = [("sensor_gyro", i, (1_000_000 + t).astype(np.int64), w + rng.normal(size=w.shape) * 0.005)
               for i in range(2)]  # fmt: skip
    log = write_streams(tmp_path / "spinning.ulg", streams)
    code, stdout, err = run(capsys, "align", "--sensor", "gyroscope", log)
    assert (code, stdout) == (3, "")
    assert "the gyroscope never rests" in err


def test_align_never_writes_onto_an_input_or_one_file_twice(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """-o onto the log (a 921 KB ULog became a 613-byte alignment), onto a calibration, and -o and
    --aligned-mag onto one file were all exit 0: each is exit 2 before any work, nothing changed."""
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2))
    acc = cal_file(tmp_path / "acc.json", "accelerometer", ["ax", "ay", "az"])
    mag = cal_file(tmp_path / "mag.json", "magnetometer", ["mx", "my", "mz"])
    before = {p: p.read_bytes() for p in (log, acc, mag)}
    out = tmp_path / "out.json"
    cases: list[tuple[list[str | Path], str]] = [
        (["-o", log], f"{log}: -o would overwrite the input {log}"),
        (["-o", acc], f"{acc}: -o would overwrite the input {acc}"),
        (["--aligned-mag", mag], f"{mag}: --aligned-mag would overwrite the input {mag}"),
        (["-o", out, "--aligned-mag", out], f"{out}: -o and --aligned-mag would write one file"),
    ]
    for extra, message in cases:
        result = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, log, *extra)
        assert result.code == 2, (extra, result.err)
        assert result.err.startswith(f"error: {message}")
        assert {p: p.read_bytes() for p in before} == before
        assert not out.exists()
    assert run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, log, "-o", out, "-q").err == ""


def test_solve_align_to_names_its_own_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = mag_log(tmp_path / "both.csv", np.random.default_rng(2))
    mag = cal_file(tmp_path / "mag.json", "magnetometer", ["mx", "my", "mz"])
    out = tmp_path / "x.json"
    r = run(
        capsys, "solve", "--sensor", "magnetometer", "-p", log, "--align-to", mag, "--no-check", "coverage", "-o", out
    )
    assert r.code == 2
    assert "--align-to takes the accelerometer's calibration, not the magnetometer's" in r.err


def test_one_stream_given_twice_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """It compared the IMU with itself: exit 0, 'consistency 0'."""
    log = imu_ulog(tmp_path / "two.ulg", np.random.default_rng(4), np.eye(3), imus=2, k=3)
    result = run(capsys, "align", log, "--stream", "sensor_accel:0", "--stream", "sensor_accel:0")
    assert_one_error(result, f"{log}: --stream sensor_accel:0 is given twice: an IMU compared with itself")


def test_align_consistency_names_its_units_when_the_log_has_none() -> None:
    """align printed "consistency 0.36 ± 0.025 RMS" for a log whose units are not known: a number
    without a unit. It says "(readings' units)" then; a log's own units as they are."""
    from types import SimpleNamespace

    from tumblecal_cli.cli.align import _imu_lines
    from tumblecal_cli.core.alignment import Consistency

    c = Consistency(rms=0.3606, sigma=0.025, unbiased=0.3606, noise=0.0)
    pair = SimpleNamespace(stream="b", fit=None, consistency=c, consistency_aligned=None)
    done = SimpleNamespace(units=None, blocks=9, orientations=8, turning=None, reference="a", pairs=[pair], limit=None)
    assert _imu_lines(done)[1] == "b: consistency 0.3606 ± 0.025 (readings' units) RMS; rotation not determined"  # type: ignore[arg-type]
    done.units = "m/s^2"
    assert _imu_lines(done)[1] == "b: consistency 0.3606 ± 0.025 m/s^2 RMS; rotation not determined"  # type: ignore[arg-type]
