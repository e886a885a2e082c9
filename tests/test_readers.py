"""Every log reader registered in io.logs (FORMATS) through the one contract of
tests/reader_contract.py, each with a small log of its own kind: a real PX4 log, logs of the
DataFlash test writer in the binary and the text form, a real ROS 1 bag. A format registered
without a sample here fails the first test; each reader's module is imported only when a log of
its kind is read."""

from __future__ import annotations

import gzip
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests import dataflash_writer
from tests.conftest import ROOT, imported
from tests.reader_contract import ReaderContract, Sample
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.logs.reader import LogReader


def ulog_sample(folder: Path) -> Sample:
    """A real PX4 log whose one accelerometer stream is PX4's sensor_combined."""
    path = folder / "auterion_esc_status.ulg"
    path.write_bytes(gzip.decompress((ROOT / "tests" / "data" / "px4" / "auterion_esc_status.ulg.gz").read_bytes()))
    return Sample(path, "accelerometer", "sensor_combined:0", "a PX4 ULog")


def dataflash_still(folder: Path) -> Path:
    """A still +z capture as a DataFlash log of the test writer (IMU:0, raw)."""
    t = np.arange(500, dtype=np.int64) * 2000 + 1_000_000
    acc = np.tile([0.01, -0.02, 9.80665], (500, 1)) + np.random.default_rng(1).normal(0, 0.01, (500, 3))
    return dataflash_writer.write(folder / "still.bin", t, acc)


def dataflash_sample(folder: Path) -> Sample:
    return Sample(dataflash_still(folder), "gyroscope", "IMU:0", "an ArduPilot DataFlash log")


def dftext_sample(folder: Path) -> Sample:
    text = dataflash_writer.text_of(dataflash_still(folder), folder / "still.log")
    return Sample(text, "accelerometer", "IMU:0", "an ArduPilot DataFlash log")


def ros_sample(folder: Path) -> Sample:
    """A real ROS 1 bag of one Imu topic, /imu/data."""
    path = Path(shutil.copy(ROOT / "tests" / "data" / "ros" / "test2_cut.bag", folder / "test2_cut.bag"))
    return Sample(path, "accelerometer", "/imu/data", "a ROS bag")


#: Each registered format's sample, by its kind.
SAMPLES: dict[str, Callable[[Path], Sample]] = {
    logs.ULOG.kind: ulog_sample,
    logs.DATAFLASH.kind: dataflash_sample,
    logs.DFTEXT.kind: dftext_sample,
    logs.ROS.kind: ros_sample,
}


def test_every_registered_format_has_a_sample_and_a_reader_of_its_row() -> None:
    assert [r.kind for r in sources.READERS] == [f.kind for f in logs.FORMATS] == list(SAMPLES)
    for entry, row in zip(sources.READERS, logs.FORMATS, strict=True):
        assert isinstance(entry, sources.Lazy)
        reader = entry.load("-")
        assert isinstance(reader, LogReader)
        assert reader.row == row


class TestEveryReader(ReaderContract):
    @pytest.fixture(params=list(SAMPLES))
    def sample(self, request: pytest.FixtureRequest, tmp_path: Path) -> Sample:
        return SAMPLES[request.param](tmp_path)


def test_no_reader_is_imported_by_the_registry_or_a_csv_read() -> None:
    watch = tuple(sorted({f.module for f in logs.FORMATS} | {n for f in logs.FORMATS for n in f.needs}))
    assert imported("import tumblecal_cli.io.sources, tumblecal_cli.io.csv.readings", watch) == []
    body = "import tumblecal_cli as t\nt.noise('tests/data/xsens_acc_still.txt', rate=100.0)"
    assert imported(body, watch) == []


@pytest.mark.parametrize("row", logs.FORMATS, ids=[f.module.rpartition(".")[2] for f in logs.FORMATS])
def test_a_reader_s_module_is_imported_when_a_log_of_its_kind_is_read_and_no_other(
    row: logs.LogFormat, tmp_path: Path
) -> None:
    sample = SAMPLES[row.kind](tmp_path)
    watch = tuple(sorted({f.module for f in logs.FORMATS} | {n for f in logs.FORMATS for n in f.needs}))
    found = imported(f"import tumblecal_cli as t\nt.streams({str(sample.path)!r})", watch)
    base = {"tumblecal_cli.io.logs.dataflash"} if row is logs.DFTEXT else set()  # the text form reads as the binary
    assert found == sorted({row.module, *row.needs, *base})
