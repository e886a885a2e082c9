"""Hostile inputs, memory (issue "Hostile input, round two"): each test is named for the defect
it pins, and failed on the main branch before its fix."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import assert_one_error, peak_rss, run, still_pose


def _pose_file(path: Path, rows: int) -> Path:
    """A still +z pose of ``rows`` readings (ax,ay,az, six decimals, 27 bytes a row)."""
    rng = np.random.default_rng(7)
    with path.open("w") as f:
        f.write("ax,ay,az\n")
        for start in range(0, rows, 500_000):
            block = 0.02 + 0.01 * rng.standard_normal((min(500_000, rows - start), 3))
            block[:, 2] += 1.0
            np.savetxt(f, block, fmt="%.6f", delimiter=",")
    return path


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss is in KiB on Linux")
def test_solve_memory_grows_by_no_more_than_the_readings_with_the_capture(tmp_path: Path) -> None:
    """A pose file's readings were held twice while read (a list of blocks, then their join),
    with their row numbers copied and whole-capture temporaries in the statistics and checks:
    85 bytes of memory a row between these two sizes (1.47 GB at 20M rows); now about 54 (34
    at 20M rows: 0.85 GB), the readings (24 bytes a row) and their row numbers (8) held once;
    and since a pose file past 262,144 readings is summed as it is read, about none
    (test_pose_file_memory_is_flat_in_rows)."""
    small, large = 100_000, 2_100_000
    low = peak_rss("solve", "--poses", _pose_file(tmp_path / "small.csv", small), "-o", tmp_path / "small.json")
    high = peak_rss("solve", "--poses", _pose_file(tmp_path / "large.csv", large), "-o", tmp_path / "large.json")
    per_row = (high - low) / (large - small)
    assert per_row < 65, f"{per_row:.1f} bytes of memory a row"


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss is in KiB on Linux")
def test_pose_file_memory_is_flat_in_rows(tmp_path: Path) -> None:
    """solve and verify held a pose file's every reading, row number and time: 603 MB at 5M
    rows, 1.08 GiB at 10M. A pose is judged by running sums (core.running) and its readings kept
    on disk: a pose file of 8M rows takes no more than 1.3 times the memory of one of 1M (by
    hand, three poses of 20M rows: 1.04-1.12 times three of 1M for solve, 0.98 for verify)."""
    small = still_pose(tmp_path / "small.csv", 1_000_000)
    large = still_pose(tmp_path / "large.csv", 8_000_000)
    base = peak_rss("solve", "--poses", small, "-o", tmp_path / "small.json")
    solved = peak_rss("solve", "--poses", large, "-o", tmp_path / "large.json")
    verified = peak_rss("verify", "-c", tmp_path / "small.json", large)
    assert solved <= 1.3 * base, f"solve: {solved / 2**20:.0f} MiB at 8M rows, {base / 2**20:.0f} MiB at 1M"
    assert verified <= 1.3 * base, f"verify: {verified / 2**20:.0f} MiB at 8M rows, {base / 2**20:.0f} MiB at 1M"


@pytest.mark.slow
def test_manifest_of_100000_pose_columns_is_refused_not_held(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 600 KB manifest whose one row lists 100,000 pose files reached 1.14 GB and grew, every
    pose held until the unit was solved: a unit is at most 1,000 files (batch.UNIT_FILES), and
    a row beyond it is exit 2 naming the manifest and its line, before any file is read; a
    manifest over 16 MiB (batch.MANIFEST_BYTES, read whole) likewise."""
    for name in "xyz":
        (tmp_path / f"{name}.csv").write_text("ax,ay,az\n0,0,1\n")
    manifest = tmp_path / "lot.csv"
    manifest.write_text("serial\nSN1,x.csv,y.csv,z.csv\nSN2," + ",".join(["x.csv", "y.csv", "z.csv"] * 33_334) + "\n")
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert_one_error(
        r,
        f"{manifest}: 100,002 files on the row of 'SN2': a unit is at most 1,000 pose files, "
        "solved together, each held in memory until the unit is (line 3)",
    )
    assert not (tmp_path / "out").exists()
    manifest.write_bytes(b"serial\n" + b"SN1,x.csv,y.csv,z.csv\n" * 800_000)  # 17.6 MB
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert_one_error(r, f"{manifest}: the manifest is larger than 16 MiB: a batch reads it whole")
