"""The contract every registered log reader keeps (io.sources' ``Reader``, io.logs.reader's
``LogReader``), as one base of tests: a test class that subclasses :class:`ReaderContract` and
gives a ``sample`` fixture (a log of its reader's own kind, in a test's folder) runs it all.

The reader claims its own log, and nothing else registered does, and not a CSV capture; it
lists the log's streams; it picks the stream a spec without --stream reads; it reads that
stream into a Table whose shapes, times and first note are sane; it refuses a label column in
one line, the same line for every log; and it keeps a log's index while the file is unchanged
and walks it again once the file is written again. tests/test_readers.py runs every reader of
io.logs through it; tests/test_extension_reader.py, a stand-in registered by a test."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import ROOT
from tests.conftest import tumblecal as cli
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.logs.fields import NAMES
from tumblecal_cli.io.logs.reader import LogReader
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream

#: A CSV capture no log reader may claim.
CSV = ROOT / "sample_data" / "x.csv"


@dataclass(frozen=True)
class Sample:
    """A log of one reader's kind, as the contract reads it: its ``path`` (a file in a test's
    folder, which the contract may write again), the ``sensor`` and the stream key the reader
    picks for it without --stream (``default``), and how the reader's messages call such a log
    (``called``: "a PX4 ULog")."""

    path: Path
    sensor: str
    default: str
    called: str

    @property
    def spec(self) -> ReadSpec:
        """What a command reads of it without --stream (a corrected stream allowed: the reader's
        part is the same for both)."""
        return ReadSpec(sensor=self.sensor, allow_corrected=True)


def reader_of(sample: Sample) -> LogReader[object]:
    """The registered reader that reads ``sample``: the registry's entry, its module loaded."""
    entry = sources.reader_for(str(sample.path))
    assert isinstance(entry, sources.Lazy), f"no registered reader claims {sample.path}"
    reader = entry.load(str(sample.path))
    assert isinstance(reader, LogReader)
    assert reader.kind == entry.kind
    return reader


def head(path: Path) -> bytes:
    with open(path, "rb") as f:
        return f.read(sources.HEAD)


class ReaderContract:
    """The tests every log reader passes; a subclass gives the ``sample`` fixture."""

    @pytest.fixture
    def sample(self) -> Sample:
        raise NotImplementedError("a test class of the contract gives its reader's sample")

    def test_it_claims_its_own_log_alone_and_not_a_csv(self, sample: Sample) -> None:
        reader = reader_of(sample)
        first = head(sample.path)
        assert reader.claims(str(sample.path), first)
        assert [r.kind for r in sources.READERS if r.claims(str(sample.path), first)] == [reader.kind]
        assert not reader.claims(str(CSV), head(CSV))
        assert sources.reader_for(str(CSV)) is None
        assert sources.reader_for("-") is None

    def test_it_lists_its_streams(self, sample: Sample) -> None:
        listed = reader_of(sample).streams(str(sample.path))
        assert listed == tumblecal.streams(str(sample.path))
        assert listed
        assert all(isinstance(s, Stream) for s in listed)
        assert len({(s.key, s.sensor) for s in listed}) == len(listed)
        for s in listed:
            assert s.sensor in NAMES, s
            assert s.rows >= 0, s
            assert s.rate is None or s.rate > 0, s
            assert s.units, s
        assert (sample.default, sample.sensor) in {(s.key, s.sensor) for s in listed}

    def test_it_picks_the_stream_a_spec_without_stream_reads(self, sample: Sample) -> None:
        reader = reader_of(sample)
        chosen = reader.pick(str(sample.path), sample.spec)
        assert (chosen.key, chosen.sensor) == (sample.default, sample.sensor)
        listed = {(s.key, s.sensor): s for s in reader.streams(str(sample.path))}
        assert chosen.rows == listed[chosen.key, chosen.sensor].rows
        assert chosen.corrected == listed[chosen.key, chosen.sensor].corrected
        again = sources.stream_of(str(sample.path), sample.spec)
        assert again is not None
        assert (again.key, again.sensor) == (chosen.key, chosen.sensor)

    def test_it_reads_a_table_of_sane_shapes_and_times(self, sample: Sample) -> None:
        reader = reader_of(sample)
        path = str(sample.path)
        chosen = reader.pick(path, sample.spec)
        table = reader.read(path, sample.spec, None)
        n = len(table.values)
        assert n == chosen.rows > 1
        assert table.values.shape == (n, 3)
        assert np.isfinite(table.values).all()
        assert table.names == NAMES[sample.sensor]
        assert table.clock is not None
        assert len(table.clock) == n
        assert (np.diff(table.clock) >= 0).all()
        assert table.time_unit in ("s", "ms", "us", "ns")
        assert table.temperature is None or len(table.temperature) == n
        assert table.labels is None
        assert table.stream is not None
        assert (table.stream.key, table.stream.sensor, table.corrected) == (chosen.key, chosen.sensor, chosen.corrected)
        assert table.sha256 == hashlib.sha256(sample.path.read_bytes()).hexdigest()
        assert table.notes[0].startswith(reader.read_note(path, chosen, n).removesuffix(")"))
        log = readings.read_log(path, sample.spec)  # and as every command reads it
        assert len(log.values) == n
        assert log.sha256 == table.sha256

    def test_it_refuses_a_label_column_in_one_line(self, sample: Sample, tmp_path: Path) -> None:
        reader = reader_of(sample)
        assert not reader.labels
        with pytest.raises(InputError) as err:
            reader.read(str(sample.path), sample.spec, "part")
        said = f"{sample.called} has no label column ('part'): its still blocks are found by the detector"
        assert (err.value.message, err.value.file) == (said, str(sample.path))
        assert err.value.hint == "leave --pose-column out"
        out = tmp_path / "c.json"
        code, stdout, stderr = cli(
            "solve", "--log", sample.path, "--pose-column", "part", "--allow-corrected", "-o", str(out)
        )
        assert (code, stdout) == (2, "")
        assert stderr == f"error: {sample.path}: {said}\nhint: leave --pose-column out\n"
        assert not out.exists()

    def test_its_index_is_kept_while_the_file_is_unchanged_and_walked_again_once_written(self, sample: Sample) -> None:
        reader = reader_of(sample)
        path = str(sample.path)
        reader.forget()
        first = reader.index(path)
        assert reader.index(path) is first
        listed = reader.streams(path)
        assert reader.index(path) is first
        before = os.stat(path)
        sample.path.write_bytes(sample.path.read_bytes())  # written again, the same bytes
        os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns + 1_000_000_000))  # a clock's tick later
        again = reader.index(path)
        assert again is not first
        assert reader.index(path) is again
        assert reader.streams(path) == listed
