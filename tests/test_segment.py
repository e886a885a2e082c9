"""Finding the static poses in one continuous log: the detector (tumblecal_cli/core/blocks.py), the
``segment`` command and ``solve --log`` (tumblecal_cli/cli/blocks.py, tumblecal_cli/pipeline/blocks.py).

Every log is synthetic with a known truth: a sensor with a known offset and gain/cross-axis matrix
(raw = A · g + b + noise, raw counts near 32768) held still on known faces for a known number of
samples, with a smooth rotation (an arc at constant angular speed plus a wobble, hundreds of counts
per sample against a noise of 3) between the poses. So each test knows where every still period
starts and ends and which face it rests on. CLI runs are in-process through ``run(capsys, ...)``.
"""

from __future__ import annotations

import csv
import gzip
import io
import itertools
import json
import math
import shutil
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import ROOT, Result, assert_untouched, assert_usage_error, feed_stdin, precious, run
from tests.synth import FloatArray, stimulus
from tumblecal_cli.core import blocks
from tumblecal_cli.core.model import FACES
from tumblecal_cli.io.outputs import unsafe
from tumblecal_cli.pipeline.segment import INDEX_COLUMNS

#: the truth of the synthetic sensor: raw counts = A g + OFFSET + noise, |g| = 1 (an unsigned 16-bit ADC)
NOMINAL = 32768.0
OFFSET = np.array([NOMINAL + 150.0, NOMINAL - 220.0, NOMINAL + 90.0])
A_TRUE = np.diag([4010.0, 3985.0, 4020.0]) + np.array([[0.0, 16.0, -12.0], [8.0, 0.0, 20.0], [-16.0, 12.0, 0.0]])
NOISE = 3.0  # counts, 1 sigma per axis and sample
RATE = 100.0  # Hz, the time column's
HOLD = 400  # samples each pose is held still (4 s)
MOVE = 150  # samples of rotation between two poses (1.5 s)
SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
ALIAS = {"+x": "xp", "-x": "xn", "+y": "yp", "-y": "yn", "+z": "zp", "-z": "zn"}
#: the label column's names of the faces (README's example), and its --pose-map
LABEL = {"+x": "x_p", "-x": "x_a", "+y": "y_p", "-y": "y_a", "+z": "z_p", "-z": "z_a"}
POSE_MAP = ",".join(f"{name}={face}" for face, name in LABEL.items())
ROTATION = "rot"
CENTRE_OPTION = ("--nominal-offset", f"{NOMINAL:g}")


# -- the synthetic log -----------------------------------------------------------------------


@dataclass(frozen=True)
class Pose:
    """One pose of the session: the face up, held ``hold`` samples, tilted ``tilt_deg`` off level."""

    face: str
    hold: int = HOLD
    tilt_deg: float = 0.0
    noise: float | None = None  # None: the log's


@dataclass(frozen=True)
class SynthLog:
    raw: FloatArray  # (n, 3) raw counts
    times: FloatArray  # (n,) seconds
    still: list[tuple[int, int]]  # the true still period of each held pose: first and last sample, inclusive
    faces: list[str]  # the face of each still period
    labels: list[str]  # per sample: the face's label while still, ROTATION while turning
    quantised: bool


def _arc(u0: FloatArray, u1: FloatArray, n: int) -> FloatArray:
    """``n`` directions turning from ``u0`` to ``u1`` (both excluded) at a constant angular speed,
    with a wobble that vanishes at the ends: never still, whatever the two directions."""
    s = np.arange(1, n + 1) / (n + 1)
    cos = float(np.clip(u0 @ u1, -1.0, 1.0))
    perp = u1 - cos * u0
    if float(np.linalg.norm(perp)) < 1e-6:  # opposite faces: turn through any perpendicular
        perp = np.cross(u0, np.array([0.3, 0.5, 0.8]))
    perp = perp / np.linalg.norm(perp)
    angle = s * math.acos(cos)
    path = np.cos(angle)[:, None] * u0 + np.sin(angle)[:, None] * perp
    wobble = 0.3 * np.sin(np.pi * s)[:, None] * np.stack([np.sin(2 * np.pi * 3 * s + k) for k in range(3)], axis=1)
    path = path + wobble
    out: FloatArray = path / np.linalg.norm(path, axis=1)[:, None]
    return out


def synth_log(
    poses: Sequence[Pose], *, seed: int = 0, noise: float = NOISE, quantised: bool = True, move: int = MOVE
) -> SynthLog:
    """A continuous log: a rotation, then each pose held still followed by a rotation to the next."""
    rng = np.random.default_rng(seed)
    here = np.array([0.6, 0.48, 0.64])
    pieces: list[FloatArray] = []
    sigma: list[FloatArray] = []
    still: list[tuple[int, int]] = []
    faces: list[str] = []
    labels: list[str] = []
    n = 0
    for pose in poses:
        there = stimulus(FACES[pose.face], 1.0, pose.tilt_deg)
        pieces += [_arc(here, there, move), np.tile(there, (pose.hold, 1))]
        sigma += [np.full(move, noise), np.full(pose.hold, noise if pose.noise is None else pose.noise)]
        labels += [ROTATION] * move + [LABEL[pose.face]] * pose.hold
        if pose.hold:
            still.append((n + move, n + move + pose.hold - 1))
            faces.append(pose.face)
        n += move + pose.hold
        here = there
    pieces.append(_arc(here, np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62]), move))
    sigma.append(np.full(move, noise))
    labels += [ROTATION] * move
    directions = np.concatenate(pieces)
    raw = directions @ A_TRUE.T + OFFSET + np.concatenate(sigma)[:, None] * rng.standard_normal(directions.shape)
    if quantised:
        raw = np.rint(raw)
    return SynthLog(raw, np.arange(len(raw)) / RATE, still, faces, labels, quantised)


def six_poses(tilted: Sequence[str] = (), tilt_deg: float = 3.0, **kw: Any) -> list[Pose]:
    return [Pose(f, tilt_deg=tilt_deg if f in tilted else 0.0, **kw) for f in SIX]


def log_text(
    log: SynthLog,
    *,
    times: FloatArray | None = None,
    with_time: bool = True,
    with_labels: bool = False,
) -> str:
    """The log as CSV text: ``t,ax,ay,az`` (and ``part``, the label column)."""
    t = log.times if times is None else times
    header = (["t"] if with_time else []) + ["ax", "ay", "az"] + (["part"] if with_labels else [])
    fmt = "{:.0f}" if log.quantised else "{:.3f}"
    lines = [",".join(header)]
    for k, row in enumerate(log.raw):
        cells = ([f"{t[k]:.2f}"] if with_time else []) + [fmt.format(v) for v in row]
        lines.append(",".join(cells + ([log.labels[k]] if with_labels else [])))
    return "\n".join(lines) + "\n"


def write_log(path: Path, log: SynthLog, **kw: Any) -> Path:
    path.write_text(log_text(log, **kw))
    return path


def detect(log: SynthLog, *, with_time: bool = True, **settings: Any) -> blocks.Segmentation:
    return blocks.detect(log.raw, log.times if with_time else None, None, blocks.DetectorSettings(**settings))


def assert_found(seg: blocks.Segmentation, log: SynthLog, *, coverage: float = 0.8) -> None:
    """Exactly the held poses: one kept block per still period, inside it, covering most of it, on its face."""
    assert len(seg.blocks) == len(log.still), [(b.first, b.last, b.dropped) for b in seg.blocks]
    for b, (first, last), face in zip(seg.blocks, log.still, log.faces, strict=True):
        assert b.kept, (b.number, b.dropped)
        assert first <= b.first <= b.last <= last, (b.number, (b.first, b.last), (first, last))
        assert b.samples >= coverage * (last - first + 1), (b.number, b.samples)
        assert b.face == face


def index_of(text: str) -> list[dict[str, str]]:
    """segments.csv's rows, each cell as it was before a leading ' kept a spreadsheet from taking
    it for a formula (a label =x; a face +x is written as it is)."""
    reader = csv.DictReader(io.StringIO(text))
    assert reader.fieldnames == INDEX_COLUMNS
    return [{column: unsafe(cell) for column, cell in row.items()} for row in reader]


def error_lines(r: Result) -> list[str]:
    return [ln for ln in r.err.splitlines() if ln.startswith("error:")]


@pytest.fixture(scope="module")
def six_tilted() -> SynthLog:
    """The six faces, +y and -z 3° off level."""
    return synth_log(six_poses(tilted=("+y", "-z")), seed=1)


@pytest.fixture(scope="module")
def six_level() -> SynthLog:
    return synth_log(six_poses(), seed=2)


@pytest.fixture
def six_level_csv(six_level: SynthLog, tmp_path: Path) -> Path:
    return write_log(tmp_path / "session.csv", six_level)


# -- the detector ----------------------------------------------------------------------------


def test_detect_finds_exactly_the_held_poses(six_tilted: SynthLog) -> None:
    seg = detect(six_tilted)
    assert_found(seg, six_tilted)
    assert seg.gaps == []
    assert list(seg.best()) == list(SIX)
    for b in seg.blocks:  # the angle is the fixture's tilt
        assert b.angle_deg == pytest.approx(3.0 if b.face in ("+y", "-z") else 0.0, abs=1.0)
    # the rough centre is the offset: the midpoint of opposite faces' means (a 3° tilt moves it ~3 counts)
    np.testing.assert_allclose(seg.centre, OFFSET, atol=5.0)


def test_threshold_sits_between_noise_and_motion(six_tilted: SynthLog) -> None:
    seg = detect(six_tilted)
    assert seg.noise_floor is not None
    assert seg.threshold is not None
    assert seg.threshold == pytest.approx(blocks.FLOOR_FACTOR * seg.noise_floor)
    # the floor is the sensor noise: the rolling std of three axes of pure noise is about sqrt(3) sigma
    assert 0.7 * math.sqrt(3) * NOISE < seg.noise_floor < 1.1 * math.sqrt(3) * NOISE
    spread = blocks.rolling_std(six_tilted.raw, seg.window)
    half = seg.window
    quiet = np.concatenate([spread[a + half : b - half] for a, b in six_tilted.still])
    moving = np.concatenate([spread[b + 1 + half : b + MOVE - half] for _, b in six_tilted.still])
    assert float(quiet.max()) < seg.threshold < float(moving.min())


def test_a_given_threshold_is_used_as_given(six_tilted: SynthLog) -> None:
    seg = detect(six_tilted, threshold=40.0)
    assert seg.threshold == 40.0
    assert seg.noise_floor is None
    assert_found(seg, six_tilted)
    below_noise = detect(six_tilted, threshold=1.0)  # under the noise: nothing is still
    assert below_noise.threshold == 1.0
    assert below_noise.blocks == []
    everything = detect(six_tilted, threshold=1e9)  # over the motion: the whole log is one still run
    assert len(everything.blocks) == 1
    assert everything.blocks[0].first == 0
    assert everything.blocks[0].last >= len(six_tilted.raw) - 2  # an even window trims one sample off the end


def test_window_and_min_duration_are_seconds_with_time_and_samples_without(six_tilted: SynthLog) -> None:
    timed, untimed = detect(six_tilted), detect(six_tilted, with_time=False)
    assert timed.period == pytest.approx(0.01)
    assert (timed.window, timed.min_samples, timed.trim) == (50, 100, 25)
    assert (untimed.period, untimed.window, untimed.min_samples, untimed.trim) == (None, 25, 50, 12)
    rate = blocks.detect(six_tilted.raw, None, RATE)
    assert (rate.window, rate.min_samples) == (50, 100)
    assert all(b.duration == pytest.approx(b.samples / RATE) for b in timed.blocks)
    assert all(b.duration is None for b in untimed.blocks)
    assert_found(untimed, six_tilted)

    seconds = detect(six_tilted, window=0.3, min_duration=2.0, trim=0.1)
    assert (seconds.window, seconds.min_samples, seconds.trim) == (30, 200, 10)
    samples = detect(six_tilted, with_time=False, window=30, min_duration=200, trim=10)
    assert (samples.window, samples.min_samples, samples.trim) == (30, 200, 10)
    assert [(b.first, b.last) for b in seconds.blocks] == [(b.first, b.last) for b in samples.blocks]

    # 4.5 s is longer than every hold (4 s); 4.5 samples is shorter than every block
    too_long = detect(six_tilted, min_duration=4.5)
    assert [b.dropped for b in too_long.blocks] == [blocks.SHORT] * 6
    assert too_long.kept == []
    assert_found(detect(six_tilted, with_time=False, min_duration=4.5), six_tilted)


def test_a_gap_in_time_splits_a_still_pose(six_tilted: SynthLog) -> None:
    first, last = six_tilted.still[2]  # +y
    gap = (first + last) // 2
    times = six_tilted.times.copy()
    times[gap:] += 5.0
    seg = blocks.detect(six_tilted.raw, times)
    assert seg.gaps == [gap]
    for b in seg.blocks:
        assert not b.first < gap <= b.last, (b.first, b.last)
    plus_y = [b for b in seg.blocks if b.face == "+y"]
    assert len(plus_y) == 2
    assert first <= plus_y[0].first
    assert plus_y[0].last < gap <= plus_y[1].first
    assert plus_y[1].last <= last
    assert [b.face for b in seg.blocks] == ["+x", "-x", "+y", "+y", "-y", "+z", "-z"]


def test_a_gap_splits_a_still_pose_whatever_the_trim(six_tilted: SynthLog) -> None:
    first, last = six_tilted.still[2]
    gap = (first + last) // 2
    times = six_tilted.times.copy()
    times[gap:] += 5.0
    seg = blocks.detect(six_tilted.raw, times, None, blocks.DetectorSettings(trim=0.0))
    assert seg.gaps == [gap]
    spans = [(b.first, b.last) for b in seg.blocks]
    for a, b in spans:
        assert not a < gap <= b, (a, b)
    assert all(b0 < a1 for (_, b0), (a1, _) in itertools.pairwise(spans)), "blocks overlap"


def test_a_short_pose_is_dropped_and_missing_says_min_duration() -> None:
    log = synth_log([*six_poses()[:5], Pose("-z", hold=80)], seed=3)
    seg = detect(log, nominal_offset=np.full(3, NOMINAL))
    assert len(seg.blocks) == 6
    short = seg.blocks[-1]
    assert (short.dropped, short.face) == (blocks.SHORT, "-z")
    assert short.samples < seg.min_samples == 100
    assert [b.dropped for b in seg.blocks[:5]] == [None] * 5
    assert list(seg.best()) == ["+x", "-x", "+y", "-y", "+z"]
    hints = blocks.missing(seg, list(SIX))
    assert len(hints) == 1
    assert hints[0].startswith("no -z block:")
    assert "below --min-duration 1 s" in hints[0]


def test_a_pose_beyond_max_tilt_has_no_face_and_missing_says_max_tilt() -> None:
    log = synth_log([*six_poses()[:5], Pose("-z", tilt_deg=40.0)], seed=4)
    seg = detect(log, nominal_offset=np.full(3, NOMINAL))
    tilted = seg.blocks[-1]
    assert tilted.kept
    assert tilted.face is None
    assert tilted.nearest == "-z"
    # its angle from -z in raw counts less the nominal offset: the 40° tilt seen through A and the offset
    seen = A_TRUE @ stimulus(FACES["-z"], 1.0, 40.0) + OFFSET - NOMINAL
    assert tilted.angle_deg == pytest.approx(math.degrees(math.acos(-seen[2] / np.linalg.norm(seen))), abs=0.5)
    hints = blocks.missing(seg, list(SIX))
    assert len(hints) == 1
    assert hints[0].startswith("no -z block:")
    assert "beyond --max-tilt 25°" in hints[0]
    assert "block 6" in hints[0]
    # a wider --max-tilt takes it
    wide = detect(log, nominal_offset=np.full(3, NOMINAL), max_tilt_deg=45.0)
    assert wide.blocks[-1].face == "-z"
    assert blocks.missing(wide, list(SIX)) == []


@pytest.mark.parametrize("order", ["short-first", "long-first"])
def test_best_prefers_the_longer_block(order: str) -> None:
    holds = (250, 450) if order == "short-first" else (450, 250)
    poses = [Pose("+x", hold=holds[0]), Pose("-x"), Pose("+x", hold=holds[1]), *six_poses()[2:]]
    log = synth_log(poses, seed=5)
    seg = detect(log)
    assert_found(seg, log)
    longer = seg.blocks[0] if order == "long-first" else seg.blocks[2]
    assert seg.best()["+x"] is longer
    assert list(seg.best()) == list(SIX)


@pytest.mark.parametrize(("tilt", "chosen"), [(8.0, "level"), (0.3, "longer")])
def test_best_prefers_a_level_block_to_a_longer_tilted_one(tilt: float, chosen: str) -> None:
    """A hand-placed +x held long but 8° off, and again level for 60 % as long: the face solvers
    get the level one (its mean is nearly as well known, and tilt is their error). 0.3° apart is
    a fixture's re-placement, within the margin: the longer block stays."""
    poses = [Pose("+x", hold=500, tilt_deg=tilt), Pose("-x"), Pose("+x", hold=300), *six_poses()[2:]]
    log = synth_log(poses, seed=5)
    seg = detect(log)
    assert_found(seg, log)
    level, longer = seg.blocks[2], seg.blocks[0]
    assert seg.best()["+x"] is (level if chosen == "level" else longer)


@pytest.mark.parametrize("order", ["quiet-first", "noisy-first"])
def test_best_among_equal_lengths_is_the_quieter(order: str) -> None:
    noises = (NOISE, 4 * NOISE) if order == "quiet-first" else (4 * NOISE, NOISE)
    poses = [Pose("+x", noise=noises[0]), Pose("-x"), Pose("+x", noise=noises[1]), *six_poses()[2:]]
    log = synth_log(poses, seed=6)
    mapping = {name: face for face, name in LABEL.items()}
    seg = blocks.from_labels(log.raw, log.labels, mapping, log.times)
    plus_x = [b for b in seg.kept if b.face == "+x"]
    assert [b.samples for b in plus_x] == [HOLD, HOLD]
    quieter = plus_x[0] if order == "quiet-first" else plus_x[1]
    assert seg.best()["+x"] is quieter


def test_quantised_noise_free_data_still_segments() -> None:
    log = synth_log(six_poses(), noise=0.0, seed=7)
    for a, b in log.still:
        assert np.ptp(log.raw[a : b + 1], axis=0).max() == 0.0  # no spread at all while still
    seg = detect(log)
    assert seg.noise_floor == 0.0
    assert seg.threshold is not None
    assert 0.0 < seg.threshold < 1.0
    assert_found(seg, log)


def test_from_labels_drops_unmapped_labels(six_tilted: SynthLog) -> None:
    mapping = {name: face for face, name in LABEL.items()}
    seg = blocks.from_labels(six_tilted.raw, six_tilted.labels, mapping, six_tilted.times)
    assert seg.threshold is None
    rotations = [b for b in seg.blocks if b.label == ROTATION]
    poses = [b for b in seg.blocks if b.label != ROTATION]
    assert len(rotations) == 7
    assert all(b.dropped == blocks.UNMAPPED and b.face is None for b in rotations)
    assert [(b.first, b.last) for b in poses] == six_tilted.still  # exactly the labelled rows
    assert [b.face for b in poses] == list(SIX)
    assert all(b.kept for b in poses)
    assert list(seg.best()) == list(SIX)
    # a mapping that leaves out -z: its block is dropped too, and missing says how to map it
    partial = blocks.from_labels(six_tilted.raw, six_tilted.labels, {k: v for k, v in mapping.items() if v != "-z"})
    assert partial.blocks[-2].label == LABEL["-z"]
    assert partial.blocks[-2].dropped == blocks.UNMAPPED
    hints = blocks.missing(partial, list(SIX))
    assert len(hints) == 1
    assert "--pose-map LABEL=-z" in hints[0]


# -- tumblecal segment -----------------------------------------------------------------------


def data_lines(path: Path) -> tuple[bytes, list[bytes]]:
    """A CSV's preamble and header (everything up to its first data row), and its data rows:
    every line that is not blank or a # comment."""
    lines = path.read_bytes().splitlines(keepends=True)
    head: list[bytes] = []
    rows: list[bytes] = []
    for line in lines:
        text = line.strip()
        if not text or text.startswith(b"#"):
            if not rows and (not head or head[-1].lstrip().startswith(b"#")):
                head.append(line)
            continue
        if not head or head[-1].lstrip().startswith(b"#"):
            head.append(line)  # the header
        else:
            rows.append(line)
    return b"".join(head), rows


def messy(text: str) -> str:
    """The same log with CRLF line ends, a preamble, a comment and a blank line between rows and a
    row with no sensor values inside a still pose."""
    lines = text.splitlines()
    lines[300] = lines[300].split(",")[0] + ",,,"  # data row 299: inside the +x hold
    lines.insert(320, "# the operator sneezed")
    lines.insert(1000, "")
    return "\r\n".join(["# logger v1, 100 Hz", *lines]) + "\r\n"


@pytest.mark.parametrize("style", ["plain", "messy"])
def test_segment_writes_the_faces_byte_for_byte(
    style: str, six_tilted: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = log_text(six_tilted)
    src = tmp_path / "session.csv"
    src.write_bytes((text if style == "plain" else messy(text)).encode())
    out = tmp_path / "poses"
    r = run(capsys, "segment", src, "-d", out)
    assert r.code == 0, r.err
    assert r.out == ""
    assert sorted(p.name for p in out.iterdir()) == sorted([f"{ALIAS[f]}.csv" for f in SIX] + ["segments.csv"])
    index = index_of((out / "segments.csv").read_text())
    assert [row["face"] for row in index] == list(SIX)
    assert [row["file"] for row in index] == [f"{ALIAS[f]}.csv" for f in SIX]
    assert {row["status"] for row in index} == {"kept"}
    head, rows = data_lines(src)
    for row, (first, last) in zip(index, six_tilted.still, strict=True):
        a, b = int(row["first_row"]), int(row["last_row"])
        assert first <= a <= b <= last  # data rows, 0-based
        block_head, block_rows = data_lines(out / row["file"])
        assert block_head == head
        assert block_rows == rows[a : b + 1]
        assert row["start_time"] == repr(a / RATE)
        assert row["end_time"] == repr(b / RATE)
    assert "wrote 6 block files and segments.csv" in r.err


def test_segment_writes_other_kept_blocks_as_blockNN(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = [Pose("+x", hold=250), Pose("-x"), Pose("+x", hold=450), *six_poses()[2:]]
    src = write_log(tmp_path / "session.csv", synth_log(poses, seed=5))
    out = tmp_path / "poses"
    r = run(capsys, "segment", src, "-d", out, "-q")
    assert r.code == 0, r.err
    assert r.err == ""
    index = index_of((out / "segments.csv").read_text())
    assert [row["file"] for row in index] == ["block01.csv", "xn.csv", "xp.csv", "yp.csv", "yn.csv", "zp.csv", "zn.csv"]
    _, rows = data_lines(src)
    _, first_block = data_lines(out / "block01.csv")
    assert first_block == rows[int(index[0]["first_row"]) : int(index[0]["last_row"]) + 1]


def test_segment_again_into_the_same_folder_replaces_the_earlier_blocks(
    six_level_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Re-running (a new --threshold, another log) must not leave the first run's block files
    beside the new ones for `solve --poses out/*.csv` to pick up; other files stay."""
    poses = [Pose("+x", hold=250), Pose("-x"), Pose("+x", hold=450), *six_poses()[2:]]
    first = write_log(tmp_path / "first.csv", synth_log(poses, seed=5))
    out = tmp_path / "poses"
    assert run(capsys, "segment", first, "-d", out, "-q").code == 0
    assert (out / "block01.csv").exists()
    (out / "notes.csv").write_text("operator notes\n")
    r = run(capsys, "segment", six_level_csv, "-d", out)
    assert r.code == 0, r.err
    assert (
        r.err.splitlines()[-1]
        == f"wrote 6 block files and segments.csv to {out}; removed 1 block files of the earlier segmentation"
    )
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["notes.csv", "segments.csv", "xp.csv", "xn.csv", "yp.csv", "yn.csv", "zp.csv", "zn.csv"]
    )
    assert [row["file"] for row in index_of((out / "segments.csv").read_text())] == [
        "xp.csv", "xn.csv", "yp.csv", "yn.csv", "zp.csv", "zn.csv"
    ]  # fmt: skip


def test_segment_again_never_removes_its_own_input(
    six_level_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The log of the new run is one of the earlier run's block files: it stays."""
    poses = [Pose("+x", hold=250), Pose("-x"), Pose("+x", hold=450), *six_poses()[2:]]
    out = tmp_path / "poses"
    assert (
        run(capsys, "segment", write_log(tmp_path / "first.csv", synth_log(poses, seed=5)), "-d", out, "-q").code == 0
    )
    again = out / "block01.csv"
    shutil.copy(six_level_csv, again)  # the user re-segments a file that sits in the folder
    before = again.read_bytes()
    r = run(capsys, "segment", again, "-d", out, "-q")
    assert r.code == 0, r.err
    assert again.read_bytes() == before


def test_segment_never_replaces_a_file_it_did_not_write(
    six_level_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "poses"
    out.mkdir()
    (out / "xp.csv").write_text("my own +x capture\n")
    r = run(capsys, "segment", six_level_csv, "-d", out)
    assert_usage_error(
        r,
        str(out),
        "--out-dir already holds xp.csv, which no earlier `tumblecal segment` wrote there",
        reported_first=True,
    )
    assert sorted(p.name for p in out.iterdir()) == ["xp.csv"]
    assert (out / "xp.csv").read_text() == "my own +x capture\n"


def test_segment_without_out_dir_prints_the_index(
    six_level_csv: Path,
    six_level: SynthLog,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    r = run(capsys, "segment", six_level_csv)
    assert r.code == 0, r.err
    index = index_of(r.out)
    assert [row["face"] for row in index] == list(SIX)
    for row, (first, last) in zip(index, six_level.still, strict=True):
        assert first <= int(row["first_row"]) <= int(row["last_row"]) <= last
        assert int(row["samples"]) == int(row["last_row"]) - int(row["first_row"]) + 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert "faces: +x -x +y -y +z -z" in r.err


def test_segment_reads_stdin(
    six_level_csv: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from_file = run(capsys, "segment", six_level_csv, "-q")
    assert from_file.code == 0, from_file.err
    feed_stdin(monkeypatch, six_level_csv.read_bytes())
    out = tmp_path / "poses"
    from_stdin = run(capsys, "segment", "-", "-d", out)
    assert from_stdin.code == 0, from_stdin.err
    assert (out / "segments.csv").read_text() == from_file.out
    assert "<stdin>" in from_stdin.err
    _, rows = data_lines(six_level_csv)
    row = index_of(from_file.out)[0]
    assert data_lines(out / "xp.csv")[1] == rows[int(row["first_row"]) : int(row["last_row"]) + 1]


def test_segment_warns_of_a_gap_and_no_block_spans_it(
    six_tilted: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, last = six_tilted.still[2]
    gap = (first + last) // 2
    times = six_tilted.times.copy()
    times[gap:] += 5.0
    src = write_log(tmp_path / "gappy.csv", six_tilted, times=times)
    r = run(capsys, "segment", src)
    assert r.code == 0, r.err
    warnings = [ln for ln in r.err.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1
    assert "gap" in warnings[0]
    assert "gappy.csv" in warnings[0]
    assert f"data row {gap - 1}" in warnings[0]
    index = index_of(r.out)
    assert len(index) == 7
    for row in index:
        assert not int(row["first_row"]) < gap <= int(row["last_row"]), row


def test_segment_pose_column(six_tilted: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "annotated.csv", six_tilted, with_labels=True)
    out = tmp_path / "poses"
    r = run(capsys, "segment", src, "--pose-column", "part", "--pose-map", POSE_MAP, "-d", out, "-v")
    assert r.code == 0, r.err
    index = index_of((out / "segments.csv").read_text())
    kept = [row for row in index if row["status"] == "kept"]
    dropped = [row for row in index if row["status"] == "dropped"]
    assert [(int(row["first_row"]), int(row["last_row"])) for row in kept] == six_tilted.still
    assert [row["face"] for row in kept] == list(SIX)
    assert [row["label"] for row in kept] == [LABEL[f] for f in SIX]
    assert len(dropped) == 7
    assert {(row["label"], row["reason"], row["file"]) for row in dropped} == {(ROTATION, blocks.UNMAPPED, "")}
    head, rows = data_lines(src)
    for row in kept:
        assert data_lines(out / row["file"]) == (head, rows[int(row["first_row"]) : int(row["last_row"]) + 1])


def test_a_pose_map_that_contradicts_the_data_is_caught(
    six_tilted: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """x_p and x_a mapped the wrong way round: each block's angle is from its label's face (not
    the nearest one), so both are dropped as mislabelled and the hint says to check the map."""
    src = write_log(tmp_path / "annotated.csv", six_tilted, with_labels=True)
    swapped = POSE_MAP.replace("x_p=+x", "x_p=TMP").replace("x_a=-x", "x_a=+x").replace("x_p=TMP", "x_p=-x")
    r = run(capsys, "segment", src, "--pose-column", "part", "--pose-map", swapped)
    assert r.code == 0, r.err
    rows = {row["label"]: row for row in index_of(r.out) if row["label"] in ("x_p", "x_a")}
    for label, face in (("x_p", "-x"), ("x_a", "+x")):
        row = rows[label]
        assert (row["status"], row["reason"], row["face"]) == ("dropped", blocks.MISLABELLED, face)
        assert float(row["angle_deg"]) > 150.0  # from the label's face, not the nearest one's few degrees
    hint = (
        "hint: no +x block: label 'x_a' is mapped to +x but its block 4 reads like -x (180° from +x); check --pose-map"
    )
    assert hint in r.err.splitlines(), r.err
    r = run(capsys, "solve", "--log", src, "--pose-column", "part", "--pose-map", swapped, "-o", tmp_path / "c.json")
    assert r.code == 3
    assert "hint: map each face's label with --pose-map" in r.err


def test_a_pose_map_label_not_in_the_column_is_warned_of(
    six_tilted: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`xp=+x` where the column says x_p: a typo, or a face this log lacks (a fixed station map
    on a log missing a face: the capture's problem, judged as a missing face) -- said, never
    silent, and not a usage error."""
    src = write_log(tmp_path / "annotated.csv", six_tilted, with_labels=True)
    typo = POSE_MAP.replace("x_p=+x", "xp=+x")
    r = run(capsys, "segment", src, "--pose-column", "part", "--pose-map", typo)
    assert r.code == 0, r.err
    warning = f"warning: {src}: --pose-map names 'xp', not a label of column 'part' (labels: "
    assert any(line.startswith(warning) for line in r.err.splitlines()), r.err
    r = run(
        capsys,
        "solve",
        "--log",
        src,
        "--pose-column",
        "part",
        "--pose-map",
        typo,
        "-m",
        "six-pose",
        "-o",
        tmp_path / "c.json",
    )
    assert r.code == 3  # no +x block: the face is missing
    assert any(line.startswith(warning) for line in r.err.splitlines()), r.err


def test_a_labelled_log_centre_ignores_its_rotations(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Unsigned counts with a full turn after each face, labelled *_rot (unmapped): a turn
    averages to the centre itself, and counted with the faces it pulled the centre to zero,
    so every face read as 'not its label's face'. The centre comes from the faces alone."""
    rng = np.random.default_rng(8)
    centre, g = 32768.0, 16384.0
    lines = ["part,ax,ay,az"]
    for face, label in LABEL.items():
        lines += [
            f"{label},{x:.0f},{y:.0f},{z:.0f}"
            for x, y, z in centre + g * np.asarray(FACES[face]) + rng.normal(0, 20, (300, 3))
        ]
        axis = "xyz".index(face[1])
        turn = np.zeros((300, 3))
        others = [k for k in range(3) if k != axis]
        angle = np.linspace(0, 2 * math.pi, 300, endpoint=False)
        turn[:, others[0]], turn[:, others[1]] = np.cos(angle), np.sin(angle)
        lines += [f"{face[1]}_rot,{x:.0f},{y:.0f},{z:.0f}" for x, y, z in centre + g * turn]
    src = tmp_path / "lab.csv"
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, "--pose-column", "part", "--pose-map", POSE_MAP, "--rate", "100", "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    np.testing.assert_allclose(doc["offset"], [centre] * 3, atol=5.0)


# -- tumblecal solve --log -------------------------------------------------------------------


def assert_recovers_the_truth(doc: dict[str, Any], *, sigmas: float = 5.0) -> None:
    se = doc["uncertainty"]
    offset = np.array(doc["offset"])
    assert np.all(np.abs(offset - OFFSET) < sigmas * np.array(se["offset"])), (offset - OFFSET, se["offset"])
    a = np.linalg.inv(np.array(doc["matrix"]))  # raw = A g + offset, corrected = M (raw - offset)
    bound = sigmas * (np.diag(se["gain"]) + np.array(se["cross_axis"]))
    assert np.all(np.abs(a - A_TRUE) < bound), (a - A_TRUE, bound)


def test_solve_log_recovers_the_known_calibration(
    six_level_csv: Path, six_level: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", six_level_csv, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "six-pose"
    assert_recovers_the_truth(doc)
    assert [p["pose"] for p in doc["poses"]] == list(SIX)
    assert [p["block"] for p in doc["poses"]] == [1, 2, 3, 4, 5, 6]
    for pose, (first, last) in zip(doc["poses"], six_level.still, strict=True):
        a, b = pose["rows"]
        assert first <= a <= b <= last
        assert pose["times"] == [pytest.approx(a / RATE), pytest.approx(b / RATE)]
        assert pose["file"] == str(six_level_csv)
    seg = doc["segmentation"]
    assert seg["log"] == str(six_level_csv)
    assert (seg["source"], seg["blocks_found"], seg["blocks_kept"], seg["gaps"]) == ("detector", 6, 6, 0)
    assert (seg["window_samples"], seg["min_samples"]) == (50, 100)
    assert seg["sample_period_s"] == pytest.approx(1 / RATE)
    np.testing.assert_allclose(seg["centre"], OFFSET, atol=2.0)
    assert seg["sha256"] == doc["poses"][0]["sha256"]


def test_solve_log_three_pose_uses_plus_x_y_z(
    six_level_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", six_level_csv, "--method", "three-pose", "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "+y", "+z"]
    assert [p["block"] for p in doc["poses"]] == [1, 3, 5]


def test_solve_log_pose_column(six_level: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "annotated.csv", six_level, with_labels=True)
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, "--pose-column", "part", "--pose-map", POSE_MAP, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "six-pose"
    assert [tuple(p["rows"]) for p in doc["poses"]] == six_level.still
    assert doc["segmentation"]["source"] == "label column"
    assert_recovers_the_truth(doc)


def test_solve_log_missing_face_names_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "five.csv", synth_log(six_poses()[:5], seed=8))
    out = tmp_path / "cal.json"
    args = ("solve", "--log", src, "--method", "six-pose", *CENTRE_OPTION, "--json", "-o", out)
    r = run(capsys, *args)
    assert r.code == 3, r.err
    doc = json.loads(r.out)
    assert doc["status"] == "rejected"
    assert [rej["code"] for rej in doc["rejections"]] == ["log.faces"]
    assert "faces found: +x -x +y -y +z" in doc["rejections"][0]["message"]
    errors = error_lines(r)
    assert errors[0].startswith(f"error: {src}: not the faces six-pose needs")
    assert [e for e in errors[1:] if e.startswith("error: no ")] == [errors[1]]
    assert errors[1].startswith("error: no -z block:")
    assert not out.exists()


def test_solve_log_auto_three_faces_is_three_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "three.csv", synth_log([Pose("+x"), Pose("+y"), Pose("+z")], seed=9))
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"


def test_solve_log_auto_one_face_per_axis_of_mixed_signs_is_three_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log of -z -x +y (a driver that reads -1 g up, placed as it reads): three-pose on those
    faces, not exit 3 for want of +x and +z."""
    src = write_log(tmp_path / "three.csv", synth_log([Pose("-z"), Pose("-x"), Pose("+y")], seed=9))
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, *CENTRE_OPTION, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"
    assert [p["pose"] for p in doc["poses"]] == ["-x", "+y", "-z"]
    assert np.all(np.array(doc["gain"]) > 3900)  # each gain with its face's sign
    r = run(capsys, "solve", "--log", src, *CENTRE_OPTION, "--method", "three-pose", "-o", out)
    assert r.code == 0, r.err
    assert [p["pose"] for p in json.loads(out.read_text())["poses"]] == ["-x", "+y", "-z"]


def test_solve_log_auto_five_faces_is_least_squares(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "five.csv", synth_log(six_poses()[:5], seed=8))
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "least-squares"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "-x", "+y", "-y", "+z"]


def test_solve_log_five_faces_with_nominal_offset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "five.csv", synth_log(six_poses()[:5], seed=8))
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, *CENTRE_OPTION, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "least-squares"
    assert sorted(p["pose"] for p in doc["poses"]) == sorted(["+x", "-x", "+y", "-y", "+z"])
    assert_recovers_the_truth(doc)


# -- bad input -------------------------------------------------------------------------------


def moving_log(still_poses: int) -> SynthLog:
    """A log that keeps turning through eight directions, with ``still_poses`` of them held."""
    faces = ["+x", "+z", "-y", "-x", "+y", "-z", "+x", "-y"]
    return synth_log([Pose(f, hold=HOLD if k < still_poses else 0) for k, f in enumerate(faces)], seed=10)


@pytest.mark.parametrize(
    ("command", "still_poses"),
    [("segment", 0), ("solve", 0), ("solve", 1)],
    ids=["segment-no-still-block", "solve-no-still-block", "solve-one-still-block"],
)
def test_nothing_to_calibrate_from(
    command: str, still_poses: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = write_log(tmp_path / "moving.csv", moving_log(still_poses))
    out_dir = tmp_path / "poses"
    out_dir.mkdir()
    index = precious(out_dir / "segments.csv")
    cal = precious(tmp_path / "cal.json")
    # a lone block needs the nominal offset to be judged (see test_a_lone_quiet_block_is_not_too_noisy)
    centre = CENTRE_OPTION if still_poses else ()
    if command == "segment":
        r = run(capsys, "segment", src, "-d", out_dir, *centre)
    else:
        r = run(capsys, "solve", "--log", src, "-o", cal, *centre)
    assert r.code == 3, r.err
    assert r.out == ""
    errors = error_lines(r)
    assert len(errors) == 1
    kept = "1 still block kept (1 found)" if still_poses else "0 still blocks kept"
    assert errors[0].startswith(f"error: {src}: nothing to calibrate from: {kept}")
    assert_untouched(index)
    assert_untouched(cal)
    assert [p.name for p in out_dir.iterdir()] == ["segments.csv"]


def test_segment_writes_a_lone_block_whatever_its_face(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """segment cuts what there is: one still block is written, exit 0 (it was exit 3 "nothing to
    calibrate from: 1 still block kept", with a hint for each of the five faces never held);
    whether its faces are enough is for solve to judge."""
    src = write_log(tmp_path / "moving.csv", moving_log(1))
    out_dir = tmp_path / "poses"
    r = run(capsys, "segment", src, "-d", out_dir, *CENTRE_OPTION)
    assert r.code == 0, r.err
    assert sorted(p.name for p in out_dir.iterdir()) == ["segments.csv", "xp.csv"]
    assert "wrote 1 block file and segments.csv" in r.err
    assert "faces: +x" in r.err
    assert "hint:" not in r.err  # no "no -x block: no still period faces -x" for faces never held
    with (out_dir / "xp.csv").open() as f:
        rows = list(csv.reader(f))
    with (out_dir / "segments.csv").open() as f:
        index = list(csv.DictReader(f))
    assert [row["status"] for row in index] == ["kept"]
    assert len(rows) - 1 == int(index[0]["last_row"]) - int(index[0]["first_row"]) + 1


def test_nothing_to_calibrate_from_json_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "moving.csv", moving_log(1))
    r = run(capsys, "solve", "--log", src, *CENTRE_OPTION, "--json", "-o", tmp_path / "cal.json")
    assert r.code == 3, r.err
    assert [rej["code"] for rej in json.loads(r.out)["rejections"]] == ["log.blocks"]
    assert not (tmp_path / "cal.json").exists()


def test_a_lone_quiet_block_is_not_too_noisy() -> None:
    seg = detect(moving_log(1))
    assert len(seg.blocks) == 1
    assert float(seg.blocks[0].std.max()) < 2 * NOISE
    assert seg.blocks[0].dropped is None


@pytest.mark.parametrize("command", ["segment", "solve"])
def test_time_going_backwards_names_the_file_and_line(
    command: str, six_level: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    times = six_level.times.copy()
    times[1000] = times[998]  # data row 1000 is line 1002 (after the header)
    src = write_log(tmp_path / "restarted.csv", six_level, times=times)
    out = tmp_path / "poses"
    args = ("segment", src, "-d", out) if command == "segment" else ("solve", "--log", src, "-o", out)
    r = run(capsys, *args)
    assert_usage_error(r, str(src), "time goes backwards", "line 1002")
    assert not out.exists()


def test_time_of_rows_without_sensor_values_is_not_judged(
    six_level: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An interleaved logger stamps its other sensor's rows with their own clock: only the rows
    tumblecal reads must go forward in time (seen on the NCSU MicroStrain logs)."""
    lines = log_text(six_level).splitlines()
    other = [f"{float(line.split(',')[0]) - 0.5:.2f},,," for line in lines[1::50]]
    mixed = [lines[0]] + [
        row for k, line in enumerate(lines[1:]) for row in ([line, other[k // 50]] if k % 50 == 0 else [line])
    ]
    src = tmp_path / "interleaved.csv"
    src.write_text("\n".join(mixed) + "\n")
    r = run(capsys, "segment", src, "-q")
    assert r.code == 0, r.err
    assert len(index_of(r.out)) >= 6
    times = six_level.times.copy()
    times[1000] = times[998]
    bad = log_text(six_level, times=times).splitlines()
    src.write_text("\n".join([bad[0], "0.00,,,", *bad[1:]]) + "\n")  # the backwards row is now line 1003
    r = run(capsys, "segment", src, "-q")
    assert_usage_error(
        r,
        str(src),
        "time goes backwards",
        "line 1003",
        f"{float(f'{times[1000]:.2f}')!r} after {float(f'{times[999]:.2f}')!r}",
    )


@pytest.mark.slow
def test_how_the_time_was_read_is_said_when_it_looks_wrong(
    six_level: SynthLog, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A time column in milliseconds: read as such from its spacing (with a note), and read as
    seconds (--time-unit s: 100 Hz looks like 0.1 Hz) refused with the reason rather than cut
    into hundreds of blocks of noise; --rate over a time column (its gaps and order go
    unchecked), and --window with no time at all."""
    src = write_log(tmp_path / "ms.csv", six_level, times=six_level.times * 1000.0)
    r = run(capsys, "segment", src)
    assert len(index_of(r.out)) == 6, r.err
    assert f"note: {src}: time column 't' read in milliseconds: it advances 10 per sample (100 Hz)" in r.err
    r = run(capsys, "segment", src, "--time-unit", "s")
    assert r.code == 2
    assert "the log's time scale is wrong, not its poses" in r.err
    assert r.out == ""
    r = run(capsys, "segment", src, "--time-unit", "ms")
    assert (r.code, "advances" in r.err) == (0, False), r.err
    r = run(capsys, "segment", src, "--rate", "100")
    assert r.code == 0, r.err
    assert f"warning: {src}: --rate 100 is used, not the time column t (no gap or order check)" in r.err.splitlines()
    plain = write_log(tmp_path / "plain.csv", six_level, with_time=False)
    r = run(capsys, "segment", plain, "--window", "40")
    assert f"warning: {plain}: no time column and no --rate: --window and --min-duration are in samples" in r.err


@pytest.fixture
def usage_files(six_level_csv: Path, tmp_path: Path) -> dict[str, str]:
    pose = tmp_path / "pose.csv"
    pose.write_text("ax,ay,az\n" + "0.01,0.02,1.0\n" * 20)
    return {"LOG": str(six_level_csv), "POSE": str(pose), "OUT": str(tmp_path / "out")}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "words"),
    [
        pytest.param(
            ["segment", "LOG", "--pose-map", POSE_MAP, "-d", "OUT"], ["--pose-map", "--pose-column"], id="map-no-column"
        ),
        pytest.param(
            ["solve", "--log", "LOG", "--pose-map", POSE_MAP, "-o", "OUT"], ["--pose-map"], id="solve-map-no-column"
        ),
        pytest.param(["segment", "LOG", "--window", "0", "-d", "OUT"], ["--window", "positive"], id="window-0"),
        pytest.param(["solve", "--log", "LOG", "--window", "0", "-o", "OUT"], ["--window"], id="solve-window-0"),
        pytest.param(
            ["solve", "--poses", "POSE", "--log", "LOG", "-o", "OUT"],
            ["--poses", "--log", "not both"],
            id="poses-and-log",
        ),
        pytest.param(
            ["solve", "--poses", "POSE", "--window", "0.5", "-o", "OUT"], ["--window", "--log"], id="window-without-log"
        ),
        pytest.param(
            ["solve", "--log", "LOG", "--sensor", "gyroscope", "-o", "OUT"],
            ["accelerometer", "gyroscope"],
            id="gyroscope-log",
        ),
    ],
)
def test_usage_errors(
    args: list[str], words: list[str], usage_files: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, *(usage_files.get(a, a) for a in args))
    assert_usage_error(r, *words)
    assert not Path(usage_files["OUT"]).exists()


def test_solve_log_three_faces_with_nominal_offset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write_log(tmp_path / "three.csv", synth_log([Pose("+x"), Pose("+y"), Pose("+z")], seed=9))
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--log", src, *CENTRE_OPTION, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "+y", "+z"]
    assert [p["block"] for p in doc["poses"]] == [1, 2, 3]


# -- the floor's percentile and the still runs, exactly -------------------------------------------


def _arrays(rng: np.random.Generator) -> Iterator[FloatArray]:
    """Spreads as a log gives them and worse: random, sorted either way, a few values many
    times, one value, and every STRIDE-th the least (the sample that brackets misleads)."""
    for n in (1, 7, blocks.BRACKETED - 1, blocks.BRACKETED, 300_000):
        yield rng.random(n)
        yield np.sort(rng.random(n))
        yield np.sort(rng.random(n))[::-1].copy()
        yield rng.integers(0, 5, n).astype(float)
        yield np.full(n, 2.0)
        tricked = rng.random(n)
        tricked[:: blocks.STRIDE] = 0.0
        yield tricked


@pytest.mark.slow
def test_smallest_is_the_kth_of_those_under_the_bound_whatever_their_order() -> None:
    rng = np.random.default_rng(7)
    for values in _arrays(rng):
        n = values.size
        for below in (np.inf, 0.5, 0.0, 3.0, float(np.median(values))):
            under = np.sort(values[values < below])
            for k in sorted({0, n // 10, n // 2, n - 1, n, int(rng.integers(0, n))}):
                want = float(under[k]) if k < under.size else None
                assert blocks.smallest(values, k, below) == want, (n, k, below)
    # fewer values under the bound than a bracket spans (no rank of the sample to partition at)
    few = rng.random(blocks.BRACKETED)
    assert blocks.smallest(few, 0, 0.003) == float(np.sort(few[few < 0.003])[0])
    # the whole read's percentile (and sample_period's median) takes an inf as a partition would
    with_inf = np.r_[rng.random(100_000), np.full(50_000, np.inf)]
    assert blocks._quantile(with_inf, 1.0) == np.inf
    assert blocks._quantile(with_inf, 0.5) == float(np.partition(with_inf, 75_000)[75_000])


def test_runs_are_the_still_stretches_split_at_the_breaks() -> None:
    """Each run checked at once for all (a loop over the 150,000 runs of a 300,000-long mask
    took over a second): in order, inside the mask, starting after a False or at a break,
    ending before one, and together the whole mask."""
    rng = np.random.default_rng(8)
    for values in _arrays(rng):
        n = values.size
        breaks = np.unique(rng.integers(1, n, 4)) if n > 1 else np.zeros(0, dtype=np.int64)
        for mask in (values < np.median(values), values >= np.median(values), np.zeros(n, bool), np.ones(n, bool)):
            starts, ends = blocks.true_runs(mask, breaks)
            assert starts.shape == ends.shape
            assert np.all(starts <= ends)
            covered = np.cumsum(np.bincount(starts, minlength=n + 1) - np.bincount(ends + 1, minlength=n + 1))[:n]
            assert not covered[~mask].any()  # every run lies inside the mask
            before, after = mask[np.maximum(starts - 1, 0)], mask[np.minimum(ends + 1, n - 1)]
            assert np.all((starts == 0) | ~before | np.isin(starts, breaks))  # a run starts after a False or at a break
            assert np.all((ends == n - 1) | ~after | np.isin(ends + 1, breaks))
            assert np.array_equal(covered > 0, mask)
    assert [x.tolist() for x in blocks.true_runs(np.zeros(0, bool), np.zeros(0, dtype=np.int64))] == [[], []]


@pytest.mark.parametrize("ending", ["\r", "mixed"])
def test_segment_writes_the_blocks_of_a_log_with_cr_or_mixed_line_ends(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ending: str
) -> None:
    """The block files were cut at LF alone: 'internal error: IndexError' for a CR-only log
    (read as one line), one row short for a log of mixed line ends."""
    plain = gzip.decompress((ROOT / "tests" / "data" / "logs" / "imucal_annotated_session.csv.gz").read_bytes())
    lines = plain.decode().splitlines(keepends=True)
    if ending == "\r":
        odd = plain.replace(b"\n", b"\r")
    else:  # LF, CR LF and CR in turn
        odd = "".join(ln[:-1] + ("\n", "\r\n", "\r")[k % 3] for k, ln in enumerate(lines)).encode()
    (tmp_path / "plain.csv").write_bytes(plain)
    (tmp_path / "odd.csv").write_bytes(odd)
    assert run(capsys, "segment", "-q", tmp_path / "plain.csv", "-d", tmp_path / "plain").code == 0
    r = run(capsys, "segment", "-q", tmp_path / "odd.csv", "-d", tmp_path / "odd")
    assert r.code == 0, r.err
    names = sorted(p.name for p in (tmp_path / "plain").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "odd").iterdir())
    assert len(names) > 10
    for name in names:
        got = (tmp_path / "odd" / name).read_bytes().replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        assert got == (tmp_path / "plain" / name).read_bytes(), name


def test_a_full_temporary_folder_is_named_not_stdout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A log on stdin is kept in $TMPDIR for a second read; a full one said
    'error: <stdout>: cannot write: No space left on device'."""
    import errno
    import tempfile

    def full(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(shutil, "copyfileobj", full)
    feed_stdin(monkeypatch, (ROOT / "sample_data" / "x.csv").read_bytes())
    r = run(capsys, "segment", "-")
    assert r.code == 2
    assert r.err.splitlines() == [
        f"error: {tmp_path}: cannot keep the log for a second read: No space left on device",
        "hint: set TMPDIR to a folder with room for the log",
    ]
    assert list(tmp_path.iterdir()) == []  # its temporary file removed


@pytest.mark.parametrize(("column", "role"), [("acc_x", "one of the accelerometer columns"), ("t", "the time column")])
def test_a_pose_column_that_is_a_sensor_or_the_time_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], column: str, role: str
) -> None:
    """It was 'internal error: KeyError: Field "3" exists 2 times in schema'."""
    plain = gzip.decompress((ROOT / "tests" / "data" / "logs" / "imucal_annotated_session.csv.gz").read_bytes())
    lines = plain.decode().splitlines()
    log = tmp_path / "ann.csv"
    log.write_text("\n".join([f"t,{lines[0]}", *(f"{k / 204.8:.4f},{ln}" for k, ln in enumerate(lines[1:]))]) + "\n")
    commands: list[list[str | Path]] = [
        ["segment", "-q", log],
        ["solve", "-q", "--log", log, "-o", tmp_path / "c.json"],
    ]
    for command in commands:
        r = run(capsys, *command, "--pose-column", column)
        assert r.code == 2
        assert r.err.splitlines()[0] == f"error: {log}: --pose-column names '{column}', {role}"


def test_index_writes_faces_as_they_are_not_as_formulas(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """segments.csv wrote its face column as '+z: the formula escaping meant for text from the
    inputs, applied to tumblecal's own vocabulary, which a script reading the index then compared
    wrongly. A face is written as it is; a label that would start a formula is still escaped."""
    from tumblecal_cli.io.outputs import spreadsheet_safe

    assert [spreadsheet_safe(c) for c in ("+z", "-x", "+zz", "=x", "+x=x.csv", "'+z")] == [
        "+z", "-x", "'+zz", "'=x", "'+x=x.csv", "''+z",
    ]  # fmt: skip
    r = run(capsys, "segment", ROOT / "sample_data" / "imucal" / "session_every4th.csv", "--rate", "25.6")
    assert r.code == 0, r.err
    faces = {row["face"] for row in csv.DictReader(io.StringIO(r.out))}
    assert faces - {""}, faces
    assert faces <= {"", "+x", "-x", "+y", "-y", "+z", "-z"}, faces
