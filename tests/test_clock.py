"""The sample rate from a log's time column (core.clock, docs/reference/csv.md): a clock stamped
on arrival in bursts (a sensor read over a serial link: a few samples a couple of milliseconds
apart, then a pause) is read at the rate its samples cover, with a note naming both steps and
--rate; a gap is reported and never averaged or integrated over; a regular clock's rate is its
median step, as it always was (its calibrations stay byte for byte the same)."""

from __future__ import annotations

import csv
import gzip
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import run, write
from tests.conftest import tumblecal as run_cli
from tumblecal_cli.core import allan, blocks, clock
from tumblecal_cli.io import readspec
from tumblecal_cli.io.csv import logread
from tumblecal_cli.io.outputs import unsafe

DATA = Path(__file__).resolve().parent / "data"
#: The MPU-6050 log this is modelled on: 65,067 samples over 655 s, 75 % of its steps under 5 ms.
TRUE_RATE = 99.3
SAMPLES = 65_067
DENSITY = 0.0129  # white noise density of the synthetic gyroscope (units/√Hz)


def arrival_stamps(true: Any, seed: int = 0, every: float = 0.040) -> Any:
    """The times a host stamps samples taken at the times ``true`` with, reading a serial link:
    each line is complete 2 ms after its sample, the host reads what has come every 24-56 ms
    and stamps the lines as it parses them, 1.5-2.5 ms apart."""
    rng = np.random.default_rng(seed)
    ready = np.asarray(true) + 0.002
    reads = ready[0] + np.cumsum(rng.uniform(0.6, 1.4, int((ready[-1] - ready[0]) / every) + 50) * every)
    at = np.searchsorted(reads, ready)
    first = np.r_[True, at[1:] != at[:-1]]
    index = np.arange(ready.size)
    place = index - np.maximum.accumulate(np.where(first, index, 0))  # the line's place in its read
    return np.maximum.accumulate(reads[at] + place * rng.uniform(0.0015, 0.0025, ready.size))


def steps_of(times: Any) -> Any:
    return np.diff(times)


# -- the clock --------------------------------------------------------------------------------


def test_a_bursty_clock_is_read_at_the_rate_its_samples_cover() -> None:
    steps = steps_of(arrival_stamps(np.arange(SAMPLES) / TRUE_RATE))
    assert np.mean(steps < 0.005) > 0.7  # most steps under 5 ms, as the MPU-6050 log's
    median = float(np.median(steps))
    assert 1 / median > 300  # the median step's rate: what was used before
    found, gaps = clock.judge(steps, median)
    assert found.bursty
    assert gaps.size == 0  # its pauses are not gaps: the samples are all there
    assert 1 / found.period == pytest.approx(TRUE_RATE, rel=2e-4)
    assert found.period == pytest.approx(steps.sum() / steps.size)  # (n - 1) / span
    assert found.jitter == pytest.approx(steps.std(), rel=1e-9)
    said = clock.note(found, "serial.csv", None)
    assert said is not None
    assert f"median {median * 1e3:.3g} ms ({1 / median:.4g} Hz), mean {found.mean * 1e3:.3g} ms" in said
    assert "the rate used is 99.3" in said
    assert "--rate" in said


@pytest.mark.parametrize("samples", [100, 300, 500])
def test_a_short_bursty_clock_is_bursty_too(samples: int) -> None:
    """A capture of a few seconds (or the part --start/--end pick) is too short for windows of
    64 steps: judged on shorter windows, not taken as regular for its length alone."""
    steps = steps_of(arrival_stamps(np.arange(samples) / TRUE_RATE, seed=samples))
    found, _ = clock.judge(steps, float(np.median(steps)))
    assert found.bursty
    assert 1 / found.period == pytest.approx(TRUE_RATE, rel=0.03)


@pytest.mark.parametrize("samples", [64, 100, 500])
def test_a_short_regular_clock_stays_regular(samples: int) -> None:
    rng = np.random.default_rng(samples)
    steps = steps_of(np.sort(np.arange(samples) / 200.0 + rng.normal(0, 2e-4, samples)))
    found, _ = clock.judge(steps, float(np.median(steps)))
    assert not found.bursty
    assert found.period == float(np.median(steps))


def test_a_regular_clock_keeps_its_median_step_exactly() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(50_000) / 200.0 + rng.normal(0, 2e-4, 50_000)  # 4 % of a period of jitter
    steps = steps_of(np.sort(t))
    median = float(np.median(steps))
    found, gaps = clock.judge(steps, median)
    assert not found.bursty
    assert found.period == median
    assert gaps.size == 0
    assert clock.note(found, "x.csv", None) is None


def test_a_logger_that_paused_keeps_its_rate() -> None:
    """An hour's pause in ten minutes of data (or 100 s in a bursty log) is one gap: it moves
    neither the rate nor the mean step, which leave the gaps out."""
    t = np.arange(120_000) / 200.0
    t[60_000:] += 3600.0
    steps = steps_of(t)
    found, gaps = clock.judge(steps, float(np.median(steps)))
    assert not found.bursty
    assert 1 / found.period == pytest.approx(200.0)
    assert 1 / found.mean == pytest.approx(200.0)
    assert list(gaps + 1) == [60_000]
    assert found.gaps == 1
    assert found.gap_seconds == pytest.approx(3600.005)
    true = np.arange(SAMPLES) / TRUE_RATE
    true[40_000:] += 100.0
    steps = steps_of(arrival_stamps(true))
    found, gaps = clock.judge(steps, float(np.median(steps)))
    assert found.bursty
    assert list(gaps + 1) == [40_000]
    assert 1 / found.period == pytest.approx(TRUE_RATE, rel=2e-4)  # the gap's 100 s left out


def test_a_coarse_clock_is_not_taken_for_a_bursty_one() -> None:
    """A 3 kHz log stamped in whole milliseconds keeps the warning it had (segment's, naming --rate)."""
    steps = steps_of(np.floor(np.arange(30_000) / 3.0))
    found, _ = clock.judge(steps, float(np.median(steps)))
    assert not found.bursty


def test_a_streamed_clock_counts_as_one_read_whole() -> None:
    """noise judges the clock by its first block, then counts each block's steps into it."""
    true = np.arange(20_000) / TRUE_RATE
    true[12_000:] += 30.0
    steps = steps_of(arrival_stamps(true, seed=4))
    whole, at = clock.judge(steps, float(np.median(steps)))
    first, at_first = clock.judge(steps[:5000], float(np.median(steps[:5000])))
    more, at_more = first.tally(steps[5000:])
    assert at_first.size == 0
    assert list(at_more + 5000) == list(at) == [11_999]
    assert (more.steps, more.gaps) == (whole.steps, whole.gaps)
    assert more.mean == pytest.approx(whole.mean, rel=1e-12)
    assert more.jitter == pytest.approx(whole.jitter, rel=1e-9)


# -- the Allan deviation across a gap ---------------------------------------------------------


def test_no_cluster_spans_a_gap() -> None:
    """Two runs of samples: each cluster's terms are those of each run, pooled (SP 1065 eq. 11
    over each run), and each point's EDF that of the pooled terms."""
    rng = np.random.default_rng(7)
    y = rng.normal(0, 1, (30_000, 3)) + np.cumsum(rng.normal(0, 0.01, (30_000, 3)), axis=0)
    cut = 12_345
    stream = allan.AllanStream()
    stream.add(y[:cut])
    stream.restart()
    for first in range(cut, len(y), 7919):
        stream.add(y[first : first + 7919])
    curve = stream.result(100.0)
    for k, m in enumerate(curve.m.tolist()):
        sums, terms = np.zeros(3), 0
        for run_ in (y[:cut], y[cut:]):
            s = np.concatenate([np.zeros((1, 3)), np.cumsum(run_ - y[:cut].mean(axis=0), axis=0)])
            d = s[2 * m :] - 2 * s[m:-m] + s[: -2 * m]
            sums += (d * d).sum(axis=0)
            terms += max(0, d.shape[0])
        np.testing.assert_allclose(curve.adev[k], np.sqrt(sums / (2 * m * m * terms)), rtol=1e-9)
        assert curve.terms[k] == terms
    assert curve.points is not None
    np.testing.assert_array_equal(curve.points, curve.terms + 2 * curve.m)
    whole = allan.AllanStream()
    whole.add(y)
    assert whole.result(100.0).points is None  # one run: its EDF as before


# -- noise ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def serial_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A still gyroscope (white noise of DENSITY) at a true 99.3 Hz, stamped on arrival."""
    rng = np.random.default_rng(1)
    t = arrival_stamps(np.arange(SAMPLES) / TRUE_RATE)
    y = rng.normal(0, DENSITY * np.sqrt(TRUE_RATE), (SAMPLES, 3))
    return write(tmp_path_factory.mktemp("serial") / "mpu6050.csv", np.column_stack([t, y]), header="t,gx,gy,gz")


@pytest.mark.slow
def test_noise_of_a_bursty_capture_is_read_at_its_true_rate(
    serial_capture: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It read "65067 samples at 437 Hz" before, every figure √(437/99.3) off, without a word."""
    r = run(capsys, "noise", serial_capture, "--sensor", "gyroscope", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["rate"] == pytest.approx(TRUE_RATE, rel=2e-4)
    for axis in "xyz":
        assert doc["axes"][axis]["noise_density"]["value"] == pytest.approx(DENSITY, rel=0.03)
    timing = doc["clock"]
    assert (timing["bursty"], timing["from"], timing["gaps"]) == (True, "mean step", 0)
    assert timing["rate"] == doc["rate"]
    assert timing["median_step_s"] < 0.003
    assert timing["mean_step_s"] == pytest.approx(1 / TRUE_RATE, rel=2e-4)
    assert 0.005 < timing["jitter_s"] < 0.05  # bursts and pauses: far from a regular clock's
    lines = r.err.splitlines()
    assert lines[0] == f"{serial_capture}: 65067 samples at {doc['rate']:g} Hz (655.3 s)"
    notes = [line for line in lines if line.startswith(f"note: {serial_capture}: the time column's steps are bursty")]
    assert len(notes) == 1
    assert ", mean 10.1 ms; the rate used is 99.3" in notes[0]
    assert "--rate HZ" in notes[0]
    assert doc["notes"] == [notes[0].removeprefix("note: ")]


def test_noise_of_a_bursty_capture_at_the_rate_given_says_nothing_of_its_clock(
    serial_capture: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "noise", serial_capture, "--sensor", "gyroscope", "--rate", "99.3", "--json", "-q")
    doc = json.loads(r.out)
    assert (doc["rate"], doc["clock"], doc["notes"]) == (99.3, None, [])


def test_noise_reports_a_gap_and_no_cluster_spans_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A logger that paused ten minutes: the gap is named (the data row before it), the rate is
    the samples' and the deviation that of the two runs, not of samples 10 min apart."""
    rng = np.random.default_rng(2)
    t = np.arange(20_000) / 100.0
    t[10_000:] += 600.0
    y = np.round(rng.normal(0, 0.1, (20_000, 3)), 6)  # as written
    y[10_000:] += 0.05  # the unit settled a little while the logger was off: a step across the gap
    path = write(tmp_path / "paused.csv", np.column_stack([t, y]))
    r = run(capsys, "noise", path, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["rate"] == 100.0
    assert (doc["clock"]["gaps"], doc["clock"]["gap_s"]) == (1, pytest.approx(600.01))
    said = f"{path}: 1 gap in time (the first after data row 9999), 600 s in all (a step over 0.03 s): "
    assert [n for n in doc["notes"] if n.startswith(said)] == doc["notes"]
    assert f"note: {said}" in r.err
    stream = allan.AllanStream()
    stream.add(y[:10_000])
    stream.restart()
    stream.add(y[10_000:])
    expected = stream.result(100.0)
    np.testing.assert_allclose(doc["adev"]["x"], expected.adev[:, 0], rtol=1e-12)
    assert doc["adev"]["terms"] == expected.terms.tolist()
    assert max(doc["adev"]["tau"]) < 100.0 / 2  # no cluster longer than half a run


def test_noise_of_a_regular_capture_says_nothing_of_its_clock(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(20_000) / 100.0
    t[::5] += 3e-4  # a sample in five stamped late: steps of 10.3 and 9.7 ms among the 10 ms
    t[7::50] += 0.002  # ... and now and then one 2 ms late
    path = write(tmp_path / "still.csv", np.column_stack([t, rng.normal(0, 0.1, (20_000, 3))]))
    r = run(capsys, "noise", path, "--json")
    doc = json.loads(r.out)
    assert doc["rate"] == 100.0  # the median step's, as ever
    assert (doc["clock"]["bursty"], doc["clock"]["from"], doc["clock"]["gaps"], doc["notes"]) == (
        False,
        "median step",
        0,
        [],
    )
    assert "note:" not in r.err


# -- segment and solve --log ------------------------------------------------------------------


FACE_G = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}


def tumble_log(path: Path, *, bursty: bool, hold: float = 4.0, seed: int = 5) -> Path:
    """t,ax,ay,az at a true 99.3 Hz: each face held ``hold`` s, 2 s of turning between (times on
    arrival over a serial link when ``bursty``, else the true ones)."""
    rng = np.random.default_rng(seed)
    pieces = []
    here = np.array([0.6, 0.48, 0.64])
    for face in FACE_G.values():
        there = np.array(face, dtype=float)
        s = np.linspace(0, 1, int(2 * TRUE_RATE))[:, None]
        turn = (1 - s) * here + s * there + 0.4 * np.sin(np.pi * s) * rng.normal(size=(len(s), 3))
        pieces += [turn, np.tile(there, (int(hold * TRUE_RATE), 1))]
        here = there
    g = np.vstack(pieces) + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, (sum(len(p) for p in pieces), 3))
    true = np.arange(len(g)) / TRUE_RATE
    t = arrival_stamps(true, seed=seed) if bursty else true
    return write(path, np.column_stack([t, g]), header="t,ax,ay,az")


@pytest.mark.slow
def test_segment_of_a_bursty_log_measures_durations_in_true_seconds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, its median step (2 ms) made a 4-s pose 0.8 s, below the 1-s --min-duration: no block."""
    bursty = tumble_log(tmp_path / "bursty.csv", bursty=True)
    regular = tumble_log(tmp_path / "regular.csv", bursty=False)
    found = {}
    for name, log in (("bursty", bursty), ("regular", regular)):
        r = run(capsys, "segment", log, "-d", tmp_path / name)
        assert r.code == 0, r.err
        index = csv.DictReader(io.StringIO((tmp_path / name / "segments.csv").read_text()))
        found[name] = [(unsafe(row["face"]), float(row["duration_s"])) for row in index if row["status"] == "kept"]
    assert [face for face, _ in found["bursty"]] == [face for face, _ in found["regular"]] == list(FACE_G)
    for (_, long), (_, true) in zip(found["bursty"], found["regular"], strict=True):
        assert long == pytest.approx(true, abs=0.1)  # 4 s held, less the window's reach, both
    r = run(capsys, "segment", bursty, "-d", tmp_path / "long", "--min-duration", "4.5")
    assert r.code == 3  # the holds are 4 s: none is 4.5
    assert f"note: {bursty}: the time column's steps are bursty" in r.err


def test_a_bursty_log_is_read_whole_and_its_period_is_the_mean_step(tmp_path: Path) -> None:
    log = tumble_log(tmp_path / "bursty.csv", bursty=True)
    spec = readspec.ReadSpec()
    assert logread.scan_log(str(log), spec, settings=blocks.DetectorSettings()) is None  # the streamed read steps aside
    t = np.loadtxt(log, delimiter=",", skiprows=1, usecols=0)
    values = np.loadtxt(log, delimiter=",", skiprows=1, usecols=(1, 2, 3))
    seg = blocks.detect(values, t - t[0])
    assert seg.clock is not None
    assert seg.clock.bursty
    assert seg.period == pytest.approx(1 / TRUE_RATE, rel=1e-3)
    assert seg.window == round(0.5 * TRUE_RATE)
    assert seg.gaps == []


@pytest.mark.slow
def test_solve_log_records_a_bursty_clock_in_the_calibration(tmp_path: Path) -> None:
    log = tumble_log(tmp_path / "bursty.csv", bursty=True)
    out = tmp_path / "cal.json"
    r = run_cli("solve", "--log", log, "-o", out)
    assert r.code == 0, r.err
    assert "steps are bursty" in r.err
    seg = json.loads(out.read_text())["segmentation"]
    assert seg["sample_period_s"] == pytest.approx(1 / TRUE_RATE, rel=1e-3)
    assert seg["clock"]["from"] == "mean step"
    assert seg["clock"]["rate"] == pytest.approx(TRUE_RATE, rel=1e-3)
    regular = tumble_log(tmp_path / "regular.csv", bursty=False)
    r = run_cli("solve", "--log", regular, "-o", tmp_path / "regular.json")
    assert r.code == 0, r.err
    assert "clock" not in json.loads((tmp_path / "regular.json").read_text())["segmentation"]


# -- known turns ------------------------------------------------------------------------------


FACE_MAP = "x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z"
TURNS = "x_rot=+x,y_rot=+y,z_rot=+z"


@pytest.fixture(scope="module")
def stamped_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """imucal's annotated session (204.8 Hz, no time column) with a time column stamped on
    arrival, as a serial link would."""
    lines = gzip.decompress((DATA / "logs" / "imucal_annotated_session.csv.gz").read_bytes()).decode().splitlines()
    true = np.arange(len(lines) - 1) / 204.8
    stamps = arrival_stamps(true, seed=9)
    path = tmp_path_factory.mktemp("turns") / "stamped.csv"
    body = [f"t,{lines[0]}"] + [f"{s:.6f},{line}" for s, line in zip(stamps, lines[1:], strict=True)]
    path.write_text("\n".join(body) + "\n")
    return path


def solve_turns(log: Path, out: Path, *extra: str) -> Any:
    return run_cli(
        "solve", "--sensor", "gyroscope", "--log", log, "--pose-column", "part", "--pose-map", FACE_MAP,
        "--turns", TURNS, "--turn-angle", "360", "--columns", "gyr_x,gyr_y,gyr_z", "-o", out, *extra,
    )  # fmt: skip


@pytest.mark.slow
def test_known_turns_on_a_bursty_clock_integrate_by_the_sample_count(stamped_session: Path, tmp_path: Path) -> None:
    """Each reading stands for the mean period, not for the time to the next arrival (a reading
    before a pause would stand for the whole pause): the calibration is the one at the true
    rate, to the rate's own error."""
    log = stamped_session
    at_rate = solve_turns(log, tmp_path / "rate.json", "--rate", "204.8")
    stamped = solve_turns(log, tmp_path / "stamped.json")
    assert (at_rate.code, stamped.code) == (0, 0), stamped.err
    a = json.loads((tmp_path / "rate.json").read_text())
    b = json.loads((tmp_path / "stamped.json").read_text())
    np.testing.assert_allclose(b["matrix"], a["matrix"], rtol=1e-3, atol=1e-5)
    np.testing.assert_allclose(b["offset"], a["offset"], rtol=1e-9)
    assert "steps are bursty" in stamped.err


@pytest.mark.slow
def test_a_known_turn_across_a_gap_is_refused(stamped_session: Path, tmp_path: Path) -> None:
    log = stamped_session
    header, *rows = log.read_text().splitlines()
    turn = [k for k, row in enumerate(rows) if row.split(",")[1] == "y_rot"]
    middle = turn[len(turn) // 2]
    shifted = [
        ",".join([f"{float(row.split(',')[0]) + (30.0 if k >= middle else 0.0):.6f}", *row.split(",")[1:]])
        for k, row in enumerate(rows)
    ]
    gapped = tmp_path / "gapped.csv"
    gapped.write_text("\n".join([header, *shifted]) + "\n")
    out = tmp_path / "x.json"
    r = solve_turns(gapped, out)
    assert r.code == 3, r.err
    assert f"error: {gapped}: turn y_rot spans a gap in time (after data row {middle - 1})" in r.err
    assert not out.exists()


@pytest.mark.slow
def test_hand_turns_on_a_bursty_clock_integrate_by_the_sample_count(tmp_path: Path) -> None:
    """Hand turns between still poses (rotations), stamped on arrival: solved as at the true
    times (before: refused, its repeated stamps taken for a clock coarser than the samples)."""
    from tests.test_rotations import ACC_A, ACC_B, synthetic_log
    from tumblecal_cli.io.calfiles.calfile import Calibration

    acc = tmp_path / "acc.json"
    Calibration(
        "accelerometer", "six-pose", 1.0, ["acc_x", "acc_y", "acc_z"], ACC_B, np.linalg.inv(ACC_A), np.diag(ACC_A)
    ).save(acc)
    regular = tmp_path / "hand.csv"
    synthetic_log(regular, np.random.default_rng(5), rate=100.0)
    header, *rows = regular.read_text().splitlines()
    stamps = arrival_stamps(np.array([float(row.split(",", 1)[0]) for row in rows]), seed=3)
    bursty = tmp_path / "hand_bursty.csv"
    lines = [f"{s:.6f},{row.split(',', 1)[1]}" for s, row in zip(stamps, rows, strict=True)]
    bursty.write_text("\n".join([header, *lines]) + "\n")
    gains = []
    for log in (regular, bursty):
        r = run_cli("solve", "--sensor", "gyroscope", "--log", log, "--accel-cal", acc, "-o", tmp_path / "g.json")
        assert r.code == 0, r.err
        gains.append(np.linalg.inv(np.array(json.loads((tmp_path / "g.json").read_text())["matrix"])))
    np.testing.assert_allclose(gains[1], gains[0], rtol=1e-3, atol=2e-3)  # the rate's own error: 50 s of arrivals
