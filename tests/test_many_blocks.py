"""A log turned through many orientations (issue 45): its blocks measured from the readings the
scan kept (``io.csv.logread.coded``) or from its chunks read again are the same bit for bit;
``solve --log`` given thousands of blocks takes each block's statistics from the scan
(``readings.Log.summarised``) and gives the calibration of the blocks read again to 1e-12; and
``solvers.distinct_directions`` counts as the greedy loop over pairs did."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests import bench
from tests.conftest import run
from tumblecal_cli.core import blocks as sc
from tumblecal_cli.core import solvers
from tumblecal_cli.io.csv import logread
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.pipeline import segment as logs

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def turned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 100 Hz log of 20 s still in random orientations, 3 s turning between: 80 blocks."""
    path = tmp_path_factory.mktemp("turned") / "turned.csv"
    bench.write_orientations(path, 185_000)
    return path


def _scan(path: Path) -> tuple[object, sc.Segmentation]:
    found = logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings())
    assert found is not None
    return found


def test_blocks_from_the_readings_kept_are_those_read_again(turned: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    kept_log, kept = _scan(turned)
    monkeypatch.setattr(logread, "KEPT", 0)  # none kept: every part read again
    again_log, again = _scan(turned)
    assert len(kept.blocks) == len(again.blocks) >= 70
    for x, y in zip(kept.blocks, again.blocks, strict=True):
        assert (x.first, x.last, x.dropped) == (y.first, y.last, y.dropped)
        for a, b in ((x.mean, y.mean), (x.std, y.std), (x.drift, y.drift)):
            assert np.array_equal(a, b)
    for field in ("values", "rows", "clock", "lines"):
        assert np.array_equal(getattr(kept_log, field), getattr(again_log, field)), field


def test_a_solve_of_many_blocks_from_their_statistics_is_that_of_the_blocks_read_again(
    turned: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    monkeypatch.setattr(logs, "BLOCK_BYTES", 0)  # every block's statistics from the scan
    r = run(capsys, "solve", "-q", "--log", str(turned), "-o", str(tmp_path / "stats.json"))
    assert r.code == 0, r.err
    monkeypatch.setattr(logs, "BLOCK_BYTES", 1 << 40)  # every block read again
    r = run(capsys, "solve", "-q", "--log", str(turned), "-o", str(tmp_path / "read.json"))
    assert r.code == 0, r.err
    a, b = (json.loads((tmp_path / f"{side}.json").read_text()) for side in ("stats", "read"))
    assert a["method"] == b["method"] == "sphere"
    assert len(a["poses"]) == len(b["poses"]) >= 70
    for key in ("offset", "gain"):
        np.testing.assert_allclose(a[key], b[key], rtol=1e-12)
    np.testing.assert_allclose(a["matrix"], b["matrix"], rtol=1e-12, atol=1e-15)
    for p, q in zip(a["poses"], b["poses"], strict=True):
        assert (p["rows"], p["samples"], p["block"]) == (q["rows"], q["samples"], q["block"])
        for key in ("mean", "std", "drift"):
            np.testing.assert_allclose(p[key], q[key], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("n", [0, 1, 2, 30, 500])
def test_distinct_directions_as_the_loop_over_pairs(n: int) -> None:
    rng = np.random.default_rng(n)
    cos = math.cos(math.radians(solvers.DISTINCT_DEG))
    for spread in (1.0, 0.1):
        d = np.array([0.0, 0.0, 1.0]) + spread * rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        kept: list[np.ndarray] = []
        for v in d:
            if not any(float(v @ k) >= cos for k in kept):
                kept.append(v)
        assert solvers.distinct_directions(d) == len(kept)


def test_interleaved_rows_and_no_last_line_end_read_again_as_kept(
    turned: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Rows of another sensor between the readings (a chunk's lines not all readings: read
    whole) and a last line without its line end: the parts read again are those kept."""
    lines = turned.read_text().splitlines()
    mixed = [lines[0] + ",gx,gy,gz"]
    for k, line in enumerate(lines[1:]):
        mixed.append(line + ",,,")
        if k % 7 == 3:  # a gyroscope's row at the same time
            mixed.append(line.split(",")[0] + ",,,,0.1,0.2,0.3")
    path = tmp_path / "mixed.csv"
    path.write_text("\n".join(mixed))  # no line end after the last
    kept_log, kept = _scan(path)
    monkeypatch.setattr(logread, "KEPT", 0)
    again_log, again = _scan(path)
    assert len(kept.blocks) == len(again.blocks) >= 70
    for x, y in zip(kept.blocks, again.blocks, strict=True):
        assert (x.first, x.last) == (y.first, y.last)
        for a, b in ((x.mean, y.mean), (x.std, y.std), (x.drift, y.drift)):
            assert np.array_equal(a, b)
    for field in ("values", "rows", "clock", "lines"):
        assert np.array_equal(getattr(kept_log, field), getattr(again_log, field)), field
