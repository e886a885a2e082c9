"""Hostile inputs, memory (issue "Hostile input, round two"): each test is named for the defect
it pins, and failed on the main branch before its fix."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

#: Runs the command given after it and prints its peak resident memory (KiB on Linux): a fresh
#: process each time, so the children's peak is that command's alone.
PEAK = (
    "import resource, subprocess, sys; "
    "done = subprocess.run(sys.argv[1:], capture_output=True, check=False); "
    "print(done.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


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


def _solve_peak(pose: Path, out: Path) -> int:
    """Peak resident bytes of ``tumblecal solve --poses POSE`` (which must succeed)."""
    command = [sys.executable, "-c", PEAK, sys.executable, "-m", "tumblecal_cli", "solve", "--poses", str(pose)]
    done = subprocess.run([*command, "-o", str(out)], capture_output=True, text=True, timeout=600, check=True)
    code, peak = done.stdout.split()
    assert code == "0"
    return int(peak) * 1024


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss is in KiB on Linux")
def test_solve_memory_grows_by_no_more_than_the_readings_with_the_capture(tmp_path: Path) -> None:
    """A pose file's readings were held twice while read (a list of blocks, then their join),
    with their row numbers copied and whole-capture temporaries in the statistics and checks:
    85 bytes of memory a row between these two sizes (1.47 GB at 20M rows); now about 54 (34
    at 20M rows: 0.85 GB), the readings (24 bytes a row) and their row numbers (8) held once."""
    small, large = 100_000, 2_100_000
    low = _solve_peak(_pose_file(tmp_path / "small.csv", small), tmp_path / "small.json")
    high = _solve_peak(_pose_file(tmp_path / "large.csv", large), tmp_path / "large.json")
    per_row = (high - low) / (large - small)
    assert per_row < 65, f"{per_row:.1f} bytes of memory a row"
