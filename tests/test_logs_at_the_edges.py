"""What a new user met on real logs after the readers landed: a compressed log, a missing one,
a pose file that is a log's stream, and a rejection the Python API must carry in its findings."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np

import tumblecal_cli as tumblecal
from tests import ulog_writer
from tests.conftest import tumblecal as run

G = 9.80665


def still_ulog(path: Path, up: tuple[float, float, float] = (0.0, 0.0, G), rows: int = 2000) -> Path:
    t = np.arange(rows, dtype=np.int64) * 2000 + 1_000_000
    xyz = np.tile(up, (rows, 1)) + np.random.default_rng(1).normal(0, 0.01, (rows, 3))
    return ulog_writer.write(path, t, xyz)


def test_a_compressed_log_is_named_as_one_and_a_ulog_given_to_apply_too(tmp_path: Path) -> None:
    log = still_ulog(tmp_path / "still.ulg")
    packed = tmp_path / "still.ulg.gz"
    packed.write_bytes(gzip.compress(log.read_bytes()))
    r = run("solve", "--log", packed, "-o", tmp_path / "c.json")
    assert r.code == 2
    assert "hint: it is a gzip-compressed PX4 ULog: decompress it first" in r.err
    assert "does not start like it" not in r.err
    assert not (tmp_path / "c.json").exists()
    cal = tmp_path / "cal.json"
    assert run("solve", "--poses", "+z=" + str(log), "--method", "one-pose", "--up", "+z", "-o", cal).code == 0
    r = run("apply", "--cal", cal, log, "-o", tmp_path / "out.csv")
    assert r.code == 2
    assert "it is a PX4 ULog: solve --log, segment, noise, thermal and verify read it" in r.err


def test_logs_names_a_missing_file_and_a_folder(tmp_path: Path) -> None:
    r = run("logs", tmp_path / "nothing.ulg")
    assert (r.code, r.err.strip()) == (2, f"error: {tmp_path / 'nothing.ulg'}: no such file")
    r = run("logs", tmp_path)
    assert r.code == 2
    assert f"{tmp_path}: is a directory, not a log" in r.err


def test_a_pose_file_that_is_a_stream_in_m_s2_is_solved_against_standard_gravity(tmp_path: Path) -> None:
    log = still_ulog(tmp_path / "up.ulg")
    solved = tumblecal.solve([str(log)], method="one-pose", up="+z")
    assert solved.status == 0, solved.error
    assert solved.calibration is not None
    assert solved.calibration.reference == G
    assert any("sensor_accel:0 is in m/s^2: solved against standard gravity" in n for n in solved.notes)
    assert abs(solved.calibration.offset[2]) < 0.01  # not a units mistake of 9.8


def test_a_rejection_without_a_check_s_finding_is_in_rejections(tmp_path: Path) -> None:
    """The README promises status 3 "with the reasons in rejections": a log with one still
    block is rejected by no pose check, and its reason is still there."""
    rng = np.random.default_rng(0)
    n = 3000
    values = np.tile([0.0, 0.0, 1.0], (n, 1)) + rng.normal(0, 0.002, (n, 3))
    path = tmp_path / "one.csv"
    np.savetxt(path, np.c_[np.arange(n) / 100, values], delimiter=",", header="t,ax,ay,az", comments="")
    solved = tumblecal.solve_log(str(path))
    assert solved.status == 3
    assert [f.code for f in solved.rejections] == ["log.blocks"]
    assert "nothing to calibrate from" in solved.rejections[0].message


def test_two_blocks_of_one_face_are_that_face_not_plus_and_minus_y() -> None:
    """PX4's robologs log rests twice on -z, 4 degrees apart: their midpoint as the centre took
    them for -y and +y (12 degrees off), each judged against a remainder of 0.37 m/s^2."""
    from tumblecal_cli.core import blocks

    means = np.array([[-0.10, -0.26, -9.76], [-0.25, 0.46, -9.79]])
    np.testing.assert_array_equal(blocks.rough_centre(means, 15.0), np.zeros(3))
    six = np.array(
        [[9.8, 0.1, 0.2], [-9.8, 0.1, 0.2], [0.0, 9.9, 0.2], [0.0, -9.7, 0.2], [0, 0.1, 9.9], [0, 0.1, -9.5]]
    )
    np.testing.assert_allclose(blocks.rough_centre(six, 15.0), [0.0, 0.1, 0.2])  # the midpoint, as before
