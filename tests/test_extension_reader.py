"""A new kind of log is one module and one registered row: the stand-in of tests/standin_reader.py,
registered there and nowhere else, passes the contract every reader keeps and is taken end to end
by the command line (``logs`` lists its stream, ``segment`` and ``solve --log`` read it), giving
the calibration its readings give as a CSV."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests import standin_reader
from tests.conftest import ROOT, with_registered, write
from tests.reader_contract import ReaderContract, Sample
from tests.test_sources import tumble
from tumblecal_cli.io import sources
from tumblecal_cli.io.logs import LogFormat


@pytest.fixture
def registered(monkeypatch: pytest.MonkeyPatch) -> None:
    """The stand-in registered for one test (the registry as it was after it)."""
    monkeypatch.setattr(sources, "READERS", list(sources.READERS))
    standin_reader.register()


class TestStandinReader(ReaderContract):
    @pytest.fixture
    def sample(self, registered: None, tmp_path: Path) -> Sample:
        t = np.arange(400) / 100.0
        xyz = np.tile([0.01, -0.02, 1.0], (400, 1)) + np.random.default_rng(2).normal(0, 0.001, (400, 3))
        path = standin_reader.write(tmp_path / "still.sti", t, xyz)
        return Sample(path, "accelerometer", "acc", "a stand-in log")


def run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``tumblecal ARGS`` with the stand-in reader registered, in a new process."""
    return with_registered("import tests.standin_reader as s; s.register()", *args, columns=None)


def test_the_command_line_lists_segments_and_solves_a_stand_in_log(tmp_path: Path) -> None:
    t, acc = tumble(6_000, rate=100.0)
    log = standin_reader.write(tmp_path / "session.sti", t, acc)
    csv = write(tmp_path / "session.csv", np.column_stack([t, acc]), header="t,acc_x,acc_y,acc_z", fmt="%.17g")
    done = run("logs", log, "--json")
    assert done.returncode == 0, done.stderr
    [stream] = json.loads(done.stdout)["streams"]
    assert (stream["stream"], stream["sensor"], stream["rows"], stream["units"]) == ("acc", "accelerometer", 6000, "g")
    assert run("logs", csv).stderr.startswith(f"error: {csv}: not a log of a kind tumblecal reads by streams (")
    assert "stand-in log)" in run("logs", csv).stderr.splitlines()[0]
    done = run("segment", log, "-d", tmp_path / "blocks")
    assert done.returncode == 0, done.stderr
    assert len(list((tmp_path / "blocks").glob("*.csv"))) == 7  # six faces and segments.csv
    cal = tmp_path / "cal.json"
    done = run("solve", "--log", log, "-o", cal)
    assert done.returncode == 0, done.stderr
    assert f"{log}: read acc (accelerometer, 6000 samples, g, raw)" in done.stderr
    from_csv = tumblecal.solve_log(str(csv)).calibration
    assert from_csv is not None
    got = json.loads(cal.read_text())
    assert got["method"] == from_csv.method == "six-pose"
    # a CSV log is streamed, a log of another kind read whole: the same to 1e-12
    np.testing.assert_allclose(got["offset"], from_csv.offset, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["matrix"], from_csv.matrix, rtol=0, atol=1e-12)


def test_without_its_registration_the_stand_in_is_no_log(tmp_path: Path) -> None:
    log = standin_reader.write(tmp_path / "session.sti", np.arange(10.0), np.zeros((10, 3)))
    assert sources.reader_for(str(log)) is None
    done = subprocess.run(
        [sys.executable, "-m", "tumblecal_cli", "logs", str(log)], capture_output=True, text=True, cwd=ROOT, check=False
    )
    assert done.returncode == 2
    assert "not a log of a kind tumblecal reads by streams" in done.stderr


def test_a_kind_of_log_is_registered_once(registered: None) -> None:
    with pytest.raises(ValueError, match="registered already"):
        standin_reader.register()
    with pytest.raises(ValueError, match="registered already"):
        sources.register(LogFormat("PX4 ULog", "tests.standin_reader", magic=(b"X",)))
