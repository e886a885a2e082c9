"""A source beside CSV plugs in as one Reader (io.sources): every command that reads a log or a
still capture takes it, and gives what it gives for the same readings in a CSV."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import ROOT, write
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Reader, Stream, Table


class NpzReader(Reader):
    """A stand-in for a binary log: numpy's .npz with ``t`` (s), ``acc`` (n, 3) and ``temp``."""

    kind = "numpy .npz archive"

    def claims(self, path: str, head: bytes) -> bool:
        return path.endswith(".npz") and head.startswith(b"PK")

    def streams(self, path: str) -> list[Stream]:
        with np.load(path) as data:
            return [Stream("acc", None, "accelerometer", len(data["acc"]), None, "g", corrected=False)]

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table:
        with np.load(path) as data:
            temp = data["temp"] if "temp" in data.files else None
            digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
            return Table(("acc_x", "acc_y", "acc_z"), data["acc"], data["t"], "s", temp, None, digest, ("npz: acc",))


@pytest.fixture
def npz_reader(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sources, "READERS", [NpzReader()])


def tumble(rows: int, rate: float = 500.0) -> tuple[np.ndarray, np.ndarray]:
    """t and x, y, z of a unit turned face to face: 8 s still, 2 s turning."""
    rng = np.random.default_rng(3)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    t = np.arange(rows) / rate
    k = (t // 10.0).astype(int)
    w = np.clip(((t % 10.0) - 8.0) / 2.0, 0, 1)[:, None]
    g = (1 - w) * faces[k % 6] + w * faces[(k + 1) % 6] + np.sin(np.pi * w) * 0.3 * rng.normal(size=(rows, 3))
    return t, g * np.array([1.01, 0.99, 1.02]) + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, (rows, 3))


def both(tmp_path: Path, t: np.ndarray, acc: np.ndarray) -> tuple[str, str]:
    """The same readings as a CSV (to 9 digits) and as an .npz (the numbers the CSV holds)."""
    csv = write(tmp_path / "log.csv", np.column_stack([t, acc]), header="t,acc_x,acc_y,acc_z", fmt="%.9g")
    back = np.loadtxt(csv, delimiter=",", skiprows=1)
    npz = tmp_path / "log.npz"
    np.savez(npz, t=back[:, 0], acc=back[:, 1:], temp=np.full(len(t), 25.0))
    return str(csv), str(npz)


@pytest.mark.slow
def test_a_log_from_another_reader_solves_as_its_csv_does(tmp_path: Path, npz_reader: None) -> None:
    csv, npz = both(tmp_path, *tumble(30_000))
    from_csv, from_npz = tumblecal.solve_log(csv), tumblecal.solve_log(npz)
    assert (from_csv.status, from_npz.status) == (0, 0)
    a, b = from_csv.calibration, from_npz.calibration
    assert a is not None
    assert b is not None
    assert b.method == a.method == "six-pose"
    np.testing.assert_allclose(b.offset, a.offset, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.matrix, a.matrix, rtol=0, atol=1e-12)
    assert b.columns == ["acc_x", "acc_y", "acc_z"]
    assert {p.file for p in b.poses} == {npz}
    segmented = tumblecal.segment(npz)
    assert len(segmented.files) == len(tumblecal.segment(csv).files) == 6


def test_a_still_capture_from_another_reader_has_the_noise_of_its_csv(tmp_path: Path, npz_reader: None) -> None:
    still = np.loadtxt(ROOT / "tests" / "data" / "xsens_acc_still.txt")
    csv, npz = both(tmp_path, still[:, 0], still[:, 1:])
    a, b = tumblecal.noise(csv), tumblecal.noise(npz)
    assert (b.rate, b.samples) == (a.rate, a.samples) == (100.0, 5000)
    assert (a.units, b.units) == (None, "g")  # the stream's units: its figures in µg, as a calibration's in g
    for x, y in zip(a.axes, b.axes, strict=True):
        assert x.noise_density.value is not None
        assert y.noise_density.value == pytest.approx(x.noise_density.value * 1e6, rel=1e-12)
    assert b.notes == ["npz: acc"]


def test_a_reader_s_clock_that_goes_back_is_one_error_naming_the_file(tmp_path: Path, npz_reader: None) -> None:
    t, acc = tumble(2_000)
    t[500] = t[10]
    _, npz = both(tmp_path, t, acc)
    with pytest.raises(InputError, match="clock goes back or is not a number at reading 501") as err:
        tumblecal.solve_log(npz)
    assert err.value.file == npz


def test_a_file_no_reader_claims_is_read_as_csv(tmp_path: Path, npz_reader: None) -> None:
    t, acc = tumble(6_000)
    csv, _ = both(tmp_path, t, acc)
    assert sources.reader_for(csv) is None
    assert sources.reader_for("-") is None
    assert isinstance(sources.reader_for(str(tmp_path / "log.npz")), NpzReader)


@pytest.mark.slow
def test_segment_writes_a_reader_s_blocks_as_csv_that_solve_reads_back(tmp_path: Path, npz_reader: None) -> None:
    _, npz = both(tmp_path, *tumble(30_000))
    done = tumblecal.segment(npz, out_dir=str(tmp_path / "blocks"))
    files = sorted((tmp_path / "blocks").glob("*.csv"))
    assert len(files) == 7  # six blocks and segments.csv
    first = next(f for f in files if f.name != "segments.csv")
    assert first.read_text().splitlines()[0] == "acc_x,acc_y,acc_z,time,temperature"
    poses = [
        f"{face}={tmp_path / 'blocks' / name}"
        for name, face in zip(done.files.values(), ("+x", "-x", "+y", "-y", "+z", "-z"), strict=True)
    ]
    assert tumblecal.solve(poses).status == 0
