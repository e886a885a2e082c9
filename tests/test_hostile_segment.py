"""Hostile inputs, round 3: ``segment`` (and ``solve --log``) of a long log in bounded memory.

The streamed scan (core.scan) kept the spread of every still sample until the end of the log,
where the noise floor (a percentile of every sample's spread) is known: 8 bytes and more a still
reading, 217 MiB at 6M rows where 1M took 155, 4.1 GB for a 5 GB CSV. The floor now comes from
a band of spreads about the percentile so far (core.scan._Floor), and the kept samples' spreads
from runs below or above the threshold so far, exact only near it (core.scan._Spreads): the
same blocks, threshold and floor, to the bit, in memory flat in the log's length.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import peak_rss, still_pose, write
from tests.test_logread import both, same, tumble
from tumblecal_cli.core import blocks as sc
from tumblecal_cli.core import scan as scan_core

BLOCK = 64 << 10  # small_blocks


@pytest.fixture
def narrow(monkeypatch: pytest.MonkeyPatch) -> None:
    """Bands a few thousand spreads wide: a log of a few hundred thousand readings narrows the
    floor's many times and sorts the kept samples' spreads into runs many times."""
    monkeypatch.setattr(scan_core, "FLOOR_SPREADS", 1 << 13)
    monkeypatch.setattr(scan_core, "FLOOR_KEEP", 1 << 11)
    monkeypatch.setattr(scan_core, "EXACT_SPREADS", 1 << 12)
    monkeypatch.setattr(scan_core, "SLICE", 1 << 10)


def _scan(values: np.ndarray, seconds: np.ndarray, settings: sc.DetectorSettings) -> scan_core.Scan:
    scan = scan_core.Scan(0.001, settings)
    for k in range(0, len(values), 7_000):
        m = len(values[k : k + 7_000])
        scan.feed(values[k : k + m], seconds[k : k + m], np.zeros((m, 0)), np.zeros((m, 0), dtype=np.int64))
    return scan


def _found(scan: scan_core.Scan) -> tuple[sc.Segmentation, list[tuple[int, int]]] | None:
    """The segmentation, and each block's first and last reading (its index in the log)."""
    done = scan.finish()
    if done is None:
        return None
    seg, kept = done
    ends = [tuple(int(i) for i in kept.log_index(np.array([b.first, b.last]))) for b in seg.blocks]
    return seg, ends  # type: ignore[return-value]


def _blocks(seg: sc.Segmentation, ends: list[tuple[int, int]]) -> list[tuple[object, ...]]:
    return [(a, b, x.face, x.dropped, x.samples) for (a, b), x in zip(ends, seg.blocks, strict=True)]


def _same_as_unbounded_and_detect(
    values: np.ndarray, seconds: np.ndarray, settings: sc.DetectorSettings, monkeypatch: pytest.MonkeyPatch
) -> scan_core.Scan:
    """Scan ``values`` with the bands as they are (narrow) and with bands wider than the log:
    the same segmentation to the bit, and ``detect``'s on the whole log; the narrow Scan."""
    scan = _scan(values, seconds, settings)
    found = _found(scan)
    with monkeypatch.context() as m:
        for name in ("FLOOR_SPREADS", "FLOOR_KEEP", "EXACT_SPREADS"):
            m.setattr(scan_core, name, 1 << 26)  # (made once, touched where written)
        wide = _found(_scan(values, seconds, settings))
    assert found is not None
    assert wide is not None
    (seg, ends), (seg_wide, ends_wide) = found, wide
    assert (seg.threshold, seg.noise_floor, seg.window, seg.gaps) == (
        seg_wide.threshold,
        seg_wide.noise_floor,
        seg_wide.window,
        seg_wide.gaps,
    )
    assert _blocks(seg, ends) == _blocks(seg_wide, ends_wide)
    np.testing.assert_array_equal([b.mean for b in seg.blocks], [b.mean for b in seg_wide.blocks])
    whole = sc.detect(values, seconds, settings=settings)
    assert seg.threshold == pytest.approx(whole.threshold, rel=1e-12)
    assert (seg.noise_floor is None) == (whole.noise_floor is None)
    if whole.noise_floor is not None:
        assert seg.noise_floor == pytest.approx(whole.noise_floor, rel=1e-12)
    assert _blocks(seg, ends) == [(b.first, b.last, b.face, b.dropped, b.samples) for b in whole.blocks]
    np.testing.assert_allclose([b.mean for b in seg.blocks], [b.mean for b in whole.blocks], rtol=1e-12)
    np.testing.assert_allclose([b.std for b in seg.blocks], [b.std for b in whole.blocks], rtol=1e-9)
    return scan


def test_many_still_blocks_with_turns_between_are_detects_in_narrow_bands(
    narrow: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """24 faces, 15 s still and 5 s turning each: the floor's band narrowed, the spreads sorted
    into runs, and what the Scan holds of them bounded by the bands, not by the log."""
    table = tumble(480_000)
    scan = _same_as_unbounded_and_detect(table[:, 1:], table[:, 0], sc.DetectorSettings(), monkeypatch)
    floor, spreads = scan.floor, scan.spreads
    assert floor is not None
    assert floor.lo > -np.inf  # narrowed
    assert floor.hi < np.inf
    assert floor.taken <= 3 * scan_core.FLOOR_SPREADS
    assert not floor.heavy
    assert (spreads.kind == scan_core.BELOW).any()  # sorted
    assert spreads.held <= scan_core.EXACT_SPREADS + 7_000
    assert spreads.start.size < 200  # runs: a few per block


def test_a_given_threshold_and_a_short_window_in_narrow_bands(narrow: None, monkeypatch: pytest.MonkeyPatch) -> None:
    table = tumble(300_000, seed=4)
    for settings in (sc.DetectorSettings(threshold=0.01), sc.DetectorSettings(window=0.05, min_duration=0.5)):
        _same_as_unbounded_and_detect(table[:, 1:], table[:, 0], settings, monkeypatch)


def test_quantised_readings_whose_spreads_take_few_values(narrow: None, monkeypatch: pytest.MonkeyPatch) -> None:
    """Counts of a quiet sensor: the spreads of its still windows repeat, so many of one value
    are counted rather than kept (the band could not narrow past them), exactly."""
    table = tumble(300_000, seed=6, noise=0.00002)
    counts = np.round(table[:, 1:] * 4096.0)
    scan = _same_as_unbounded_and_detect(counts, table[:, 0], sc.DetectorSettings(), monkeypatch)
    assert scan.floor is not None
    assert scan.floor.heavy


def test_a_floor_that_drifts_out_of_the_band_is_read_whole(narrow: None) -> None:
    """The noise of a log that gets quieter and quieter: the percentile leaves the band it was
    narrowed to, and finish says the log is to be read whole (core.blocks.detect), not a floor."""
    table = tumble(300_000, seed=8)
    values, seconds = table[:, 1:], table[:, 0]
    quiet = values.copy()
    quiet -= np.mean(values, axis=0)
    quiet *= np.linspace(1.0, 0.2, len(values))[:, None]
    assert _found(_scan(quiet, seconds, sc.DetectorSettings())) is None


def test_a_log_read_in_blocks_in_narrow_bands_is_the_whole_read(
    tmp_path: Path, small_blocks: None, narrow: None
) -> None:
    """io.csv.logread's path, its blocks' spreads computed on its threads, and the whole read."""
    path = write(tmp_path / "session.csv", tumble(200_000, seed=3))
    for settings in ({}, {"trim": 0.0}):
        streamed, whole = both(path, **settings)
        assert streamed is not None
        same(streamed, whole)  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss is in KiB on Linux")
def test_segment_memory_is_flat_in_the_logs_length(tmp_path: Path) -> None:
    """A still pose at 1 kHz: 6M rows took 1.34 times the memory of 1M (206 MiB, 153; 30M rows
    504), 8 bytes and more a row; now within 1.3 times (by hand: 180 MiB and 156; 30M rows 192,
    what grows being the chunks' sums and the clock's every 64th time, under a byte a row)."""
    small = still_pose(tmp_path / "small.csv", 1_000_000)
    large = still_pose(tmp_path / "large.csv", 6_000_000)
    base = peak_rss("segment", small, "-d", tmp_path / "small")
    grown = peak_rss("segment", large, "-d", tmp_path / "large")
    assert grown <= 1.3 * base, f"segment: {grown / 2**20:.0f} MiB at 6M rows, {base / 2**20:.0f} MiB at 1M"
    for side, rows in (("small", 1_000_000), ("large", 6_000_000)):
        index = (tmp_path / side / "segments.csv").read_text().splitlines()
        assert len(index) == 2, index
        assert index[1].startswith(f"1,zp.csv,kept,,0,{rows - 2},"), index


@pytest.mark.slow
def test_a_tumble_session_longer_than_the_floors_band_is_the_whole_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """3M rows, 150 faces: more still samples than FLOOR_SPREADS, so the floor's band is
    narrowed as it is for any log of an hour or more at 1 kHz; the streamed path is the whole
    read, block for block."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    narrowed: list[None] = []
    narrow = scan_core._Floor._narrow
    monkeypatch.setattr(scan_core._Floor, "_narrow", lambda self, *a: narrowed.append(narrow(self, *a)))

    table = tumble(3_000_000, seed=9)
    path = tmp_path / "session.csv"
    columns = [pa.array(np.round(table[:, j], 6)).cast(pa.decimal128(12, 6), safe=False) for j in range(4)]
    with path.open("wb") as f:
        pcsv.write_csv(pa.table(columns, names=["t", "x", "y", "z"]), f, pcsv.WriteOptions(quoting_style="none"))
    streamed, whole = both(path)
    assert streamed is not None
    assert narrowed
    same(streamed, whole)  # type: ignore[arg-type]
