"""A log read block by block (io.csv.logread, core.scan) finds what the whole log read at once finds.

The streamed path keeps only the still periods' spreads and sums over chunks of readings; every
block it reports (its rows, face, verdict and statistics: the means to 1e-12, merged from those
sums), the threshold, the period and the gaps must be the whole path's.
Where it does not take a log (a comment, time going backwards, a label column...) it says so
and the whole path runs, so every error message stays that path's own.
"""

from __future__ import annotations

import gzip
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import cast

import numpy as np
import pytest

from tests.conftest import run, write
from tumblecal_cli.core import blocks as sc
from tumblecal_cli.core import scan as scan_core
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import capture, logread, readings
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.pipeline import segment as logs

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "logs"
BLOCK = 16 << 10  # small_blocks: a small log is hundreds of blocks


def tumble(rows: int, seed: int = 2, rate: float = 1000.0, noise: float = 0.002) -> np.ndarray:
    """t, x, y, z of a unit turned face to face: 15 s still, 5 s turning (at 1 kHz), repeated."""
    rng = np.random.default_rng(seed)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    t = np.arange(rows) / rate
    phase = (t % 20.0) / 20.0 * 20.0
    k = (t // 20.0).astype(int)
    w = np.clip((phase - 15.0) / 5.0, 0, 1)[:, None]
    g = (1 - w) * faces[k % 6] + w * faces[(k + 1) % 6] + np.sin(np.pi * w) * 0.3 * rng.normal(size=(rows, 3))
    xyz = g + np.array([0.01, -0.02, 0.015]) + rng.normal(0, noise, size=(rows, 3))
    return np.column_stack([t, xyz])


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Callable[[int], Path]:
    """``session(rows)``: the file of ``tumble(rows)``, written once for the module (the tests
    that take it only read it)."""
    folder = tmp_path_factory.mktemp("sessions")

    def written(rows: int) -> Path:
        path = folder / f"session_{rows}.csv"
        return path if path.exists() else write(path, tumble(rows))

    return written


def both(path: Path, rate: float | None = None, **settings: object) -> tuple[object, object]:
    """(the streamed log and segmentation or None, the whole log and segmentation)."""
    s = sc.DetectorSettings(**settings)  # type: ignore[arg-type]
    streamed = logread.scan_log(str(path), ReadSpec(rate=rate), settings=s)
    if streamed is not None:
        streamed = (streamed[0], logs.review(streamed[0], streamed[1], rate, s))
    whole = readings.read_log(str(path), use_time=rate is None)
    return streamed, (whole, logs.find_blocks(whole, rate, None, s))


def same(streamed: tuple[readings.Log, sc.Segmentation], whole: tuple[readings.Log, sc.Segmentation]) -> None:
    (a, sa), (b, sb) = streamed, whole
    assert a.sha256 == b.sha256
    assert sa.period == sb.period
    assert (sa.window, sa.min_samples, sa.trim, sa.gaps) == (sb.window, sb.min_samples, sb.trim, sb.gaps)
    assert sa.gap_rows == sb.gap_rows
    assert sa.zero_steps == sb.zero_steps
    assert sa.mean_step == pytest.approx(sb.mean_step, rel=1e-12) if sb.mean_step is not None else sa.mean_step is None
    assert sa.threshold == pytest.approx(sb.threshold, rel=1e-6)
    assert (sa.noise_floor is None) == (sb.noise_floor is None)
    assert sa.noise_floor == pytest.approx(sb.noise_floor, rel=1e-6) if sb.noise_floor is not None else True
    assert len(sa.blocks) == len(sb.blocks)
    for x, y in zip(sa.blocks, sb.blocks, strict=True):
        assert (a.row(x.first), a.row(x.last)) == (b.row(y.first), b.row(y.last))
        assert a.reading(x.first) == b.reading(y.first) == y.first  # among the whole log's readings
        assert (x.face, x.nearest, x.dropped, x.samples) == (y.face, y.nearest, y.dropped, y.samples)
        if a.clock is not None and b.clock is not None:
            assert (a.time(x.first), a.time(x.last)) == (b.time(y.first), b.time(y.last))
    # every block's statistics at once (one call per block took seconds on a log of 45,000 blocks)
    np.testing.assert_allclose([x.mean for x in sa.blocks], [y.mean for y in sb.blocks], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose([x.std for x in sa.blocks], [y.std for y in sb.blocks], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(sa.centre, sb.centre, rtol=1e-12, atol=1e-15)
    pa = [a.block(x.number, x.first, x.last) for x in sa.kept]
    pb = [b.block(y.number, y.first, y.last) for y in sb.kept]
    for p, q in zip(pa, pb, strict=True):
        assert (p.rows, p.duration, p.times, p.temperature) == (q.rows, q.duration, q.times, q.temperature)
        np.testing.assert_array_equal(p.values, q.values)


@pytest.mark.slow  # 150,000 rows read both ways, five times (the fast tier: test_rows_and_line_offsets_either_width)
@pytest.mark.parametrize(
    "settings",
    [{}, {"trim": 0.0}, {"trim": 0.4}, {"window": 0.05, "min_duration": 0.5}, {"threshold": 0.01}],
    ids=["defaults", "no-trim", "trim", "short-window", "threshold"],
)
def test_a_tumble_session_streamed_is_the_whole_read(
    session: Callable[[int], Path], small_blocks: None, settings: dict[str, float]
) -> None:
    streamed, whole = both(session(150_000), **settings)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    log = streamed[0]  # type: ignore[index]
    assert log.values.shape[0] < 0.9 * whole[0].values.shape[0]  # type: ignore[index]  # the turns are not kept


@pytest.mark.slow
def test_gaps_a_rate_and_interleaved_rows(
    tmp_path: Path, small_blocks: None, capsys: pytest.CaptureFixture[str]
) -> None:
    table = tumble(120_000)
    table[60_000:, 0] += 2.5  # the logger paused: a gap in time
    path = write(tmp_path / "gap.csv", table)
    streamed, whole = both(path)
    assert streamed is not None
    assert whole[1].gap_rows == [59_999]  # type: ignore[index]
    same(streamed, whole)  # type: ignore[arg-type]
    # the warning names the row before the gap (the streamed path once gave a kept position's row)
    r = run(capsys, "segment", path, "-d", tmp_path / "blocks")
    assert r.code == 0, r.err
    assert "1 gap in time (the first after data row 59999)" in r.err
    # no time column: --rate
    no_time = write(tmp_path / "rate.csv", table[:, 1:], header="x,y,z")
    streamed, whole = both(no_time, rate=1000.0)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    # a block's start is its first reading's place in the log (it once was its place among those kept)
    r = run(capsys, "segment", no_time, "--rate", "1000", "-d", tmp_path / "rated")
    assert r.code == 0, r.err
    starts = [line.split()[1:3] for line in r.err.splitlines() if line.split()[:1] and line.split()[0].isdigit()]
    assert len(starts) > 3
    for rows, start in starts:
        assert start == f"{int(rows.split('-')[0]) / 1000:.4g}", (rows, start)
    # another sensor's rows between (an interleaved logger): rows, not readings
    lines = ["t,ax,ay,az,gx,gy,gz"]
    for i, (t, x, y, z) in enumerate(table[:80_000]):
        lines.append(f"{t:.3f},{x:.6f},{y:.6f},{z:.6f},,,")
        if i % 3 == 0:
            lines.append(f"{t:.3f},,,,0.1,0.2,0.3")
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("\n".join(lines) + "\n")
    streamed, whole = both(mixed)
    assert streamed is not None
    assert whole[1].gap_rows == [59_999 + 20_000]  # type: ignore[index]  # a gyroscope row every third
    same(streamed, whole)  # type: ignore[arg-type]


def test_a_temperature_column_and_a_log_shorter_than_a_window(tmp_path: Path, small_blocks: None) -> None:
    table = tumble(60_000)
    temp = 20.0 + np.arange(table.shape[0]) * 1e-4
    path = write(tmp_path / "warm.csv", np.column_stack([table[:, :1], temp, table[:, 1:]]), header="t,temp,x,y,z")
    streamed, whole = both(path)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    short = write(tmp_path / "short.csv", tumble(300))  # 0.3 s: less than the 0.5 s window
    streamed, whole = both(short, min_duration=0.1)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["ckexplorer_acc_log.csv", "hassan_mobile_30orient.csv", "imucal_annotated_session"])
def test_real_logs_streamed_are_the_whole_read(tmp_path: Path, small_blocks: None, name: str) -> None:
    if name.startswith("imucal"):  # counts at 204.8 Hz, with a label column the detector ignores
        path = tmp_path / "imucal.csv"
        with gzip.open(DATA / "imucal_annotated_session.csv.gz", "rb") as src, path.open("wb") as dst:
            shutil.copyfileobj(src, dst)
        rate = 204.8
    else:
        path = tmp_path / name
        shutil.copy(DATA / name, path)
        rate = 100.0
    streamed, whole = both(path, rate=rate)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "change",
    [
        lambda text: text.replace("\n10.000000", "\n# a note\n10.000000", 1),
        lambda text: text.replace("\n10.000000", "\n9.000000", 1),  # time goes backwards
        lambda text: text.replace("\n10.000000,", "\n10.000000,,", 1),  # a row with a field too many
        lambda text: text.replace("\n", "\r", 3),
    ],
    ids=["comment", "time-backwards", "ragged", "cr"],
)
def test_what_the_stream_does_not_take_is_read_whole(
    session: Callable[[int], Path], tmp_path: Path, small_blocks: None, change: object
) -> None:
    path = tmp_path / "log.csv"
    path.write_text(change(session(30_000).read_text()))  # type: ignore[operator]
    assert logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings()) is None


@pytest.mark.slow
def test_a_floor_that_rises_after_the_first_blocks_is_still_exact(tmp_path: Path, small_blocks: None) -> None:
    """A quiet start and a noisy rest: the bound set early would miss the later still samples,
    so the scan says it cannot finish (or finishes exactly): never a different answer."""
    quiet = tumble(40_000, noise=0.0002)
    loud = tumble(160_000, seed=3, noise=0.004)
    loud[:, 0] += quiet[-1, 0] + 0.001
    path = write(tmp_path / "rise.csv", np.vstack([quiet, loud]))
    streamed, whole = both(path)
    if streamed is not None:
        same(streamed, whole)  # type: ignore[arg-type]


@pytest.mark.slow
def test_segment_writes_the_same_files_either_way(
    session: Callable[[int], Path], tmp_path: Path, small_blocks: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = session(130_000)
    logs.segment(str(path), out_dir=str(tmp_path / "streamed"))
    monkeypatch.setattr(logread, "scan_log", lambda *a, **k: None)
    logs.segment(str(path), out_dir=str(tmp_path / "whole"))
    streamed = sorted(p.name for p in (tmp_path / "streamed").iterdir())
    assert streamed == sorted(p.name for p in (tmp_path / "whole").iterdir())
    assert len(streamed) > 5
    for name in streamed:
        if name != "segments.csv":
            assert (tmp_path / "streamed" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    # the index: every cell the same, but the means merged from sums over chunks (core.chunks), to 1e-14
    a, b = (np.genfromtxt(tmp_path / side / "segments.csv", delimiter=",", dtype=str) for side in ("streamed", "whole"))
    means = [list(a[0]).index(f"mean_{axis}") for axis in "xyz"]
    others = [k for k in range(a.shape[1]) if k not in means]
    np.testing.assert_array_equal(a[:, others], b[:, others])
    np.testing.assert_allclose(a[1:, means].astype(float), b[1:, means].astype(float), rtol=1e-14)


def test_the_scan_keeps_a_bounded_share(tmp_path: Path) -> None:
    """The still samples and a pad around them, and the turning before the noise floor is known:
    not the whole log."""
    rng = np.random.default_rng(5)
    n = 200_000
    moving = rng.normal(0, 0.3, size=(n, 3)) + np.array([0.0, 0.0, 1.0])
    for start in (20_000, 90_000, 160_000):  # three still poses of 20 s: 30 % of the log
        moving[start : start + 20_000] = rng.normal(0, 0.002, size=(20_000, 3)) + np.array([0.0, 0.0, 1.0])
    scan = scan_core.Scan(0.001, sc.DetectorSettings())
    seconds = np.arange(n, dtype=np.float64) * 0.001
    for k in range(0, n, 7_000):
        m = len(moving[k : k + 7_000])
        scan.feed(moving[k : k + m], seconds[k : k + m], np.zeros((m, 0)), np.zeros((m, 0), dtype=np.int64))
    done = scan.finish()
    assert done is not None
    seg, kept = done
    whole = sc.detect(moving, seconds)
    assert [b.samples for b in seg.kept] == [b.samples for b in whole.kept] == [19_500] * 3
    # the still poses, and the turning before the first of them (until the noise floor is known)
    assert kept.values.shape[0] < 0.5 * n


@pytest.mark.slow
def test_a_block_file_that_cannot_be_written_leaves_the_folder_as_it_was(
    session: Callable[[int], Path], tmp_path: Path, small_blocks: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The block files are written on threads: a full disk in one of them is the run's error,
    and neither the others nor a staging folder stay."""
    import errno
    import threading

    from tumblecal_cli.errors import InputError

    path = session(130_000)
    out = tmp_path / "poses"
    calls, lock = [0], threading.Lock()
    real = capture._copy_range

    def full_disk(source: int, target: object, at: int, size: int) -> int:
        with lock:
            calls[0] += 1
            third = calls[0] == 3
        if third:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(source, target, at, size)  # type: ignore[arg-type]

    monkeypatch.setattr(capture, "_copy_range", full_disk)
    with pytest.raises(InputError, match="No space left on device"):
        logs.segment(str(path), out_dir=str(out))
    assert not out.exists() or list(out.iterdir()) == []


def test_a_quantised_log_whose_threshold_is_one_of_its_spreads_is_read_whole(tmp_path: Path) -> None:
    """Counts that sit still but for 1-count flicker (found in review): the spreads take a few
    exact values and the threshold, 3 x the floor, is one of them, so rounding alone would say
    which side a sample is on. The streamed path sees that and the log is read whole."""
    rng = np.random.default_rng(3)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]) * 1000 + [12, -7, 30]
    parts = []
    for k in range(6):
        still = np.tile(faces[k], (6000, 1))
        axis, sign = rng.integers(0, 3, 6000), rng.choice([-1, 1], 6000)
        flicker = rng.random(6000) < 0.1
        still[flicker, axis[flicker]] += sign[flicker]
        big = rng.random(6000) < 0.004
        still[big, axis[big]] += 3 * sign[big]
        w = np.linspace(0, 1, 800)[:, None]
        turn = np.round((1 - w) * faces[k] + w * faces[(k + 1) % 6] + rng.normal(0, 30, (800, 3)))
        parts += [still, turn.astype(int)]
    path = write(tmp_path / "counts.csv", np.vstack(parts), header="x,y,z", fmt="%d")
    assert logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings()) is None


def test_a_time_cell_empty_on_another_sensors_row_is_the_whole_reads_business(tmp_path: Path) -> None:
    """The whole read judges the whole time (and temperature) column, rows without readings
    too: an error, or with --rate no clock at all. The streamed path leaves such a log to it."""
    lines = ["t,ax,ay,az,gx,gy,gz"]
    for i, (t, x, y, z) in enumerate(tumble(30_000)):
        lines.append(f"{t:.3f},{x:.6f},{y:.6f},{z:.6f},,,")
        if i % 3 == 0:
            lines.append(",,,,0.1,0.2,0.3")
    path = tmp_path / "blank_time.csv"
    path.write_text("\n".join(lines) + "\n")
    assert logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings()) is None
    assert logread.scan_log(str(path), ReadSpec(rate=1000.0), settings=sc.DetectorSettings()) is None


def test_rolling_std_keeps_its_digits_on_a_long_log_of_counts() -> None:
    """Its running sums restart every SPAN samples: raw counts near 32768 over a million
    samples once lost 1e-5 of each spread (found in review)."""
    rng = np.random.default_rng(4)
    n = 1_000_000
    faces = np.repeat(np.array([[1000, 0, 0], [0, -1000, 0], [0, 0, 1000], [-1000, 0, 0]]), n // 4, axis=0)
    values = 32768.0 + faces + np.round(rng.normal(0, 3, (n, 3)))  # an unsigned ADC turned face to face
    spread = sc.rolling_std(values, 500)  # the sums over the whole log were off by 1e-7 here
    for i in (250, 123_456, 654_321, 999_000):
        window = values[i - 250 : i + 250]
        direct = float(np.sqrt(np.var(window, axis=0).sum()))
        assert spread[i] == pytest.approx(direct, rel=1e-12)


@pytest.mark.parametrize("kinds", [1, 3, scan_core.PEELS + 1, 200, 100_000])
def test_time_steps_are_counted_exactly_however_many_kinds(kinds: int) -> None:
    """The median step needs each step's exact count: a few kinds are counted one by one, the
    rest by bits or by sorting; a clock standing still or stepping back is counted too."""
    rng = np.random.default_rng(kinds)
    kind = 0.001 + np.arange(kinds) * (1e-12 if kinds < 1000 else 1e-6)
    steps = np.concatenate([kind[rng.integers(0, kinds, 50_000)], [0.0, 0.0, -0.5]])
    rng.shuffle(steps)
    counts: dict[float, int] = {0.001: 7}  # what earlier blocks counted
    scan_core._count(steps[:20_000], counts)
    scan_core._count(steps[20_000:], counts)
    values, many = np.unique(steps, return_counts=True)
    expected = dict(zip(values.tolist(), many.tolist(), strict=True))
    expected[0.001] = expected.get(0.001, 0) + 7
    assert counts == expected


@pytest.mark.parametrize("narrow", [0, 1 << 31], ids=["int64", "int32"])
def test_rows_and_line_offsets_either_width(
    session: Callable[[int], Path], small_blocks: None, monkeypatch: pytest.MonkeyPatch, narrow: int
) -> None:
    """Rows and line offsets are kept as int32 for files under NARROW bytes, else int64."""
    monkeypatch.setattr(logread, "NARROW", narrow)
    streamed, whole = both(session(60_000))
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    log = streamed[0]  # type: ignore[index]
    assert log.rows.dtype == (np.int64 if narrow == 0 else np.int32)
    assert log.lines is not None
    assert log.lines.dtype == log.rows.dtype


@pytest.mark.slow
@pytest.mark.parametrize("noise", [0.0, 1e-7], ids=["noise-free", "1e-7 g"])
def test_a_noise_free_or_very_quiet_log_keeps_whole_faces_either_way(
    tmp_path: Path, small_blocks: None, noise: float
) -> None:
    """Spreads far below the readings' range keep their digits (sums about a reading near
    them): faces printed to 4 decimals in m/s^2, exactly constant, were cut short by rounding
    (both reads, in different places), and at 1e-7 g the whole read saw a noise floor of 0
    and the two reads found different blocks."""
    if noise:
        table = tumble(120_000, noise=noise)
        path = write(tmp_path / "quiet.csv", table, fmt=["%.3f", "%.9f", "%.9f", "%.9f"])
    else:  # six faces of 15 s, 3 s turns, in m/s^2 to 4 decimals
        rng = np.random.default_rng(1)
        faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
        t = np.arange(108_000) / 1000.0
        k = (t // 18).astype(int)
        w = np.clip((t % 18 - 15) / 3, 0, 1)[:, None]
        g = (1 - w) * faces[k % 6] + w * faces[(k + 1) % 6] + np.sin(np.pi * w) * 0.3 * rng.normal(size=(t.size, 3))
        table = np.column_stack([t, (g + np.array([0.0123, -0.0217, 0.0151])) * 9.80665])
        path = write(tmp_path / "flat.csv", table, fmt=["%.3f", "%.4f", "%.4f", "%.4f"])
    streamed, whole = both(path)
    log, seg = cast("tuple[readings.Log, sc.Segmentation]", whole)
    rows = [(int(log.rows[y.first]), int(log.rows[y.last])) for y in seg.blocks]
    if noise:  # spreads 1e-7 beside faces 2 apart: the two reads' rounding differs by more than the
        assert streamed is None  # threshold's tie allows, so the log is read whole
        assert seg.noise_floor == pytest.approx(np.sqrt(3) * noise, rel=0.05)  # sqrt(3) sigma
    if streamed is not None:
        a, sa = cast("tuple[readings.Log, sc.Segmentation]", streamed)
        assert [(a.row(x.first), a.row(x.last)) for x in sa.blocks] == rows
    assert len(rows) == 6  # one block per face, none split
    assert len({last - first for first, last in rows[1:]}) == 1  # each face as long as the others
    assert rows[1][1] - rows[1][0] > 14_000  # 15 s still at 1 kHz, less the window's reach


@pytest.mark.slow
def test_a_clock_coarser_than_the_samples_is_named_with_rate(
    tmp_path: Path, small_blocks: None, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 3 kHz log stamped in whole milliseconds: two steps in three are 0. Both reads say so
    and point to --rate (they said the poses were too short), and --rate then finds the faces."""
    table = tumble(180_000, rate=3000.0)
    table[:, 0] = np.floor(table[:, 0] * 1000)  # integer milliseconds
    path = write(tmp_path / "coarse.csv", table, fmt=["%d", "%.6f", "%.6f", "%.6f"])
    streamed, whole = both(path)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    assert cast("tuple[readings.Log, sc.Segmentation]", whole)[1].zero_steps == pytest.approx(2 / 3, abs=1e-4)
    r = run(capsys, "segment", path, "-d", tmp_path / "blocks")
    assert r.code == 3
    assert "67% of the time column's steps are 0" in r.err
    assert "hint: the time column does not advance with the samples: give the sample rate with --rate HZ" in r.err
    r = run(capsys, "segment", path, "--rate", "3000", "-d", tmp_path / "rated")
    assert r.code == 0, r.err
    assert "faces: +x -x +y\n" in r.err  # the three faces of its first minute


def test_a_clock_that_repeats_a_stamp_now_and_then_is_not_coarse(tmp_path: Path, small_blocks: None) -> None:
    """A 1 kHz logger stamping whole ms on arrival repeats a stamp now and then (and skips one):
    its steps still average its median step, so no warning (the review found one at 2.8 %)."""
    table = tumble(60_000)
    rng = np.random.default_rng(5)
    table[:, 0] = np.floor(np.arange(table.shape[0]) + rng.uniform(0, 1.03, table.shape[0]))
    path = write(tmp_path / "jitter.csv", table, fmt=["%d", "%.6f", "%.6f", "%.6f"])
    streamed, whole = both(path)
    assert streamed is not None
    same(streamed, whole)  # type: ignore[arg-type]
    seg = cast("tuple[readings.Log, sc.Segmentation]", whole)[1]
    assert seg.zero_steps > logs.ZERO_STEPS
    assert seg.mean_step == pytest.approx(0.001, rel=0.01)
    assert not logs.coarse_clock(seg)
    assert not any("steps are 0" in w for w in seg.warnings)


def test_a_threshold_within_rounding_of_a_spread_is_the_whole_reads(tmp_path: Path) -> None:
    """A threshold 2e-9 from a spread the two reads round differently (found by a review: the
    streamed read ended a block one row later): the log is read whole, or the two agree."""
    path = write(tmp_path / "quiet.csv", tumble(120_000, seed=0, noise=1e-5), fmt="%.9f")
    streamed, whole = both(path, threshold=2.7250007230206297e-05)
    log, seg = cast("tuple[readings.Log, sc.Segmentation]", whole)
    rows = [(int(log.rows[y.first]), int(log.rows[y.last])) for y in seg.blocks]
    assert rows[5] == (100_249, 114_751)
    if streamed is not None:
        a, sa = cast("tuple[readings.Log, sc.Segmentation]", streamed)
        assert [(a.row(x.first), a.row(x.last)) for x in sa.blocks] == rows


@pytest.mark.parametrize("threshold", ["0", "1e-200"])
def test_a_threshold_of_nothing_is_the_whole_reads_exit_3(
    session: Callable[[int], Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], threshold: str
) -> None:
    """--threshold 0 (or 1e-200) crashed the streamed read (ZeroDivisionError, OverflowError)."""
    r = run(capsys, "segment", session(30_000), "--threshold", threshold, "-d", tmp_path / "blocks")
    assert r.code == 3, r.err
    assert "internal error" not in r.err
    assert "nothing to calibrate from: 0 still blocks kept" in r.err


def test_a_streamed_log_keeps_each_blocks_ends_and_reads_a_block_again(
    session: Callable[[int], Path], tmp_path: Path, small_blocks: None
) -> None:
    """The streamed Log holds each block's first and last reading only; a block's readings are
    read again from the file (one still being written, grown: as well), and a file rewritten
    since is an error naming it."""
    path = tmp_path / "log.csv"
    shutil.copy(session(130_000), path)
    streamed = logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings())
    assert streamed is not None
    log, seg = streamed
    assert log.values.shape == (2 * len(seg.blocks), 3)  # not the still readings: their ends
    first = seg.kept[0]
    again = log.block(first.number, first.first, first.last)
    assert len(again.values) == first.samples
    np.testing.assert_allclose(again.values.mean(axis=0), first.mean, rtol=1e-12)
    original = path.read_bytes()
    data = bytearray(original)
    at = data.index(b"\n", len(data) // 2) + 3
    data[at] = ord("7") if data[at] != ord("7") else ord("8")  # one digit rewritten in place: the same size
    stamp = path.stat().st_mtime_ns
    path.write_bytes(bytes(data))
    os.utime(path, ns=(stamp + 10**9, stamp + 10**9))
    with pytest.raises(InputError, match="not as it was when its blocks were found"):
        log.block(first.number, first.first, first.last)
    path.write_bytes(original)
    streamed = logread.scan_log(str(path), ReadSpec(), settings=sc.DetectorSettings())
    assert streamed is not None
    log = streamed[0]
    with path.open("ab") as f:  # a log still being written: what was read is there as it was
        f.write(b"1000,0,0,1\n")
    assert log.block(first.number, first.first, first.last).values.tolist() == again.values.tolist()


def test_solve_log_from_stdin_reads_its_blocks_again_from_the_copy(
    session: Callable[[int], Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """stdin is kept in a temporary file while the log is read: the blocks a solve takes are
    read again from it before it goes (the same calibration as from the file)."""
    import io as stdio

    path = session(130_000)
    r = run(capsys, "solve", "-q", "--log", str(path), "-o", str(tmp_path / "file.json"))
    assert r.code == 0, r.err
    stream = stdio.TextIOWrapper(stdio.BytesIO(path.read_bytes()))
    monkeypatch.setattr("sys.stdin", stream)
    r = run(capsys, "solve", "-q", "--log", "-", "-o", str(tmp_path / "stdin.json"))
    assert r.code == 0, r.err
    a, b = (json.loads((tmp_path / f).read_text()) for f in ("file.json", "stdin.json"))
    assert a["offset"] == b["offset"]
    assert a["matrix"] == b["matrix"]


@pytest.mark.parametrize("n", [1, 255, 256, 257, 1000, 5000])
def test_block_statistics_merged_from_chunks_are_numpys(n: int) -> None:
    """core.chunks: a span's mean, standard deviation and drift from the chunks' sums and the
    parts of the chunks it cuts equal numpy's on the readings themselves."""
    from tumblecal_cli.core import chunks as ck

    rng = np.random.default_rng(n)
    values = rng.normal([1e4, -3.0, 0.5], [2.0, 1e-3, 1e-6], size=(2 * n + 700, 3))  # std down to 2e-6 of the mean
    table = ck.Chunks()
    for at in range(0, len(values), 1000):  # fed as blocks of 1000, each cut in chunks of its own
        table.add(at, *ck.chunk_sums(values[at : at + 1000]))
    table.done()
    half = len(values) // 2
    spans = [(a, a + n - 1) for a in (0, 300, 256, half, len(values) - n)]  # on a chunk's edge, inside one
    parts = {}
    for c, wanted in table.wanted(spans).items():
        chunk = values[table.start[c] : table.start[c] + table.counts[c]]
        parts.update({(c, lo, hi): ck.moments(chunk[lo : hi + 1]) for lo, hi in wanted})
    for (a, b), m in zip(spans, table.measure(spans, parts), strict=True):
        want = sc.measure(values, [(a, b)])[0]
        np.testing.assert_allclose(m.stats.mean, want.stats.mean, rtol=1e-14)
        np.testing.assert_allclose(m.stats.std, want.stats.std, rtol=1e-9, atol=1e-300)
        np.testing.assert_allclose(m.drift, want.drift, rtol=1e-9, atol=1e-12)
        assert m.stats.samples == want.stats.samples == b - a + 1


def _floats(a: object, b: object, path: str = "") -> Iterator[tuple[str, float, float]]:
    """Every number of two calibration files side by side, by its place (the same keys)."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            yield from _floats(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from _floats(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        yield path, a, b
    else:
        assert a == b, path


def test_solve_log_streamed_is_the_whole_reads_calibration(
    session: Callable[[int], Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The calibration the same to 1e-12 either way, and every other number of its file to 1e-9:
    the two reads sum a block's readings in another order (a block's axes apart when streamed),
    which moves a figure found by cancellation (the tilt sensitivities: 6e-11) more than it
    moves the readings' means (1e-16 of their scale). ``created`` pinned: two runs may straddle a second."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    path = session(130_000)
    r = run(capsys, "solve", "-q", "--log", str(path), "-o", str(tmp_path / "streamed.json"))
    assert r.code == 0, r.err
    monkeypatch.setattr(logread, "scan_log", lambda *a, **k: None)
    r = run(capsys, "solve", "-q", "--log", str(path), "-o", str(tmp_path / "whole.json"))
    assert r.code == 0, r.err
    a, b = (json.loads((tmp_path / f"{side}.json").read_text()) for side in ("streamed", "whole"))
    for where, x, y in _floats(a, b):
        close = 1e-12 if where.split("[")[0] in (".offset", ".matrix", ".gain") else 1e-9
        assert x == pytest.approx(y, rel=close, abs=1e-15), (where, x, y)


def test_a_log_without_a_still_block_is_streamed_too(tmp_path: Path, small_blocks: None) -> None:
    """Nothing to read again: the streamed read still finishes (no block), not the whole read."""
    rng = np.random.default_rng(9)
    n = 60_000
    moving = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.3, size=(n, 3))
    path = write(tmp_path / "moving.csv", np.column_stack([np.arange(n) / 1000.0, moving]))
    streamed, whole = both(path, threshold=0.01)  # every window's spread is about 0.5
    assert streamed is not None
    assert len(cast("tuple[readings.Log, sc.Segmentation]", whole)[1].blocks) == 0
    same(streamed, whole)  # type: ignore[arg-type]
