"""Finding the static poses in one continuous log: a pure-numpy core module (no I/O).

A sample is *still* when the readings in the window centred on it vary less than a threshold:
the rolling standard deviation (the root of the three axes' variances, from cumulative sums,
so one vectorised pass whatever the length) is below ``threshold``. Unless given, the
threshold is ``FLOOR_FACTOR`` times the data's own noise floor, the ``FLOOR_PERCENTILE``-th
percentile of the rolling standard deviation: in a tumble session the unit rests most of the
time, so the quietest tenth of the windows is sensor noise and nothing else (imu_tk instead
asks for a long still start to measure it, the source of its "not enough intervals").

A run of still samples is a *block*, never across a gap in time. Each block is then judged as
the quality checks judge a pose file (docs/production-test.md, core/gate.py): too short, too noisy or
drifting relative to its own magnitude drops it. Its label is the face nearest its direction
after removing a rough centre (the nominal offset, else the per-axis midpoint of the block
means: an unsigned ADC's counts sit near 32768), when that face is within ``max_tilt_deg``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import clock
from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.core.clock import Clock
from tumblecal_cli.core.model import FACES, PoseStats, angle_deg, pose_stats
from tumblecal_cli.errors import InputError, said

WINDOW = (0.5, 25)  # default rolling window: seconds when the time is known, else samples
MIN_DURATION = (1.0, 50)  # default shortest block kept, the same way
FLOOR_PERCENTILE = 10.0
FLOOR_FACTOR = 3.0
GAP_FACTOR = clock.GAP_FACTOR  # a time step this many times the typical one is a gap (core.clock)
SHORT, NOISY, DRIFTING, UNMAPPED = "too short", "too noisy", "drifting", "not a pose label"
#: A block whose mean is this many times noisier than the longest block of its face still
#: competes to be its face's block (white noise: a quarter of the samples).
NOISE_MARGIN = 2.0
TILT_MARGIN_DEG = 0.5
MISLABELLED = "not its label's face"  # a labelled block whose data points elsewhere (a wrong --pose-map)


@dataclass(frozen=True)
class DetectorSettings:
    """The detector's knobs, as the command line gives them (None: the default)."""

    window: float | None = None  # seconds when the time is known, else samples
    threshold: float | None = None  # raw units; None: FLOOR_FACTOR x the noise floor
    min_duration: float | None = None  # seconds when the time is known, else samples
    trim: float | None = None  # cut from each end of a still period; None: half the window
    max_noise: float = 0.02  # a block's std or drift above this fraction of its magnitude drops it
    max_tilt_deg: float = 25.0
    nominal_offset: FloatArray | None = None  # the rough centre; None: midpoint of the block means


@dataclass(frozen=True)
class Block:
    """One still period: ``first``..``last`` index the log's samples (inclusive)."""

    number: int  # 1-based, in time order
    first: int
    last: int
    mean: FloatArray
    std: FloatArray
    drift: FloatArray  # mean of the last third minus mean of the first third
    duration: float | None  # seconds, when the time is known
    nearest: str  # the face nearest the block's direction
    angle_deg: float  # from that face
    face: str | None  # ``nearest`` when within max_tilt_deg (or the label column's face)
    dropped: str | None = None  # why it is not used: SHORT, NOISY, DRIFTING, UNMAPPED
    label: str | None = None  # the label column's text, for labelled logs

    @property
    def samples(self) -> int:
        return self.last - self.first + 1

    @property
    def kept(self) -> bool:
        return self.dropped is None

    @property
    def stderr(self) -> float:
        """The standard error of the block's mean, its noisiest axis."""
        return float(self.std.max()) / math.sqrt(self.samples)


@dataclass
class Segmentation:
    """What the detector found, and how (for the table, the index and the calibration file)."""

    blocks: list[Block]
    window: int  # samples
    period: float | None  # seconds per sample, when known
    threshold: float | None  # None for a labelled log
    noise_floor: float | None  # None when the threshold was given
    min_samples: int
    trim: int  # samples
    centre: FloatArray
    max_tilt_deg: float = 25.0
    gaps: list[int] = field(default_factory=list)  # sample index after each gap in time
    gap_rows: list[int] = field(default_factory=list)  # data row of the reading before each gap (its caller's)
    zero_steps: float = 0.0  # the share of time steps that are 0: a clock coarser than the samples, or stopped
    mean_step: float | None = None  # the mean of the time steps no longer than a gap (beside the median, period)
    warnings: list[str] = field(default_factory=list)  # for people: how the log's time was read
    clock: Clock | None = None  # what the time column says (core.clock), when the period is taken from it

    @property
    def kept(self) -> list[Block]:
        return [b for b in self.blocks if b.kept]

    def dropped_counts(self) -> str:
        """How many blocks were dropped for each reason: ``3 too short, 1 drifting``."""
        reasons = [b.dropped for b in self.blocks]
        return ", ".join(
            f"{reasons.count(r)} {r}" for r in (SHORT, NOISY, DRIFTING, UNMAPPED, MISLABELLED) if r in reasons
        )

    def best(self) -> dict[str, Block]:
        """The best kept block of each face found: of the blocks whose mean is known within
        NOISE_MARGIN times as well as the longest one's, the least tilted (a face solver takes
        its block as exactly on the face, so tilt is its error, and noise only past this margin);
        the longest unless that one is more than TILT_MARGIN_DEG less tilted (a fixture's
        re-placements differ by tenths of a degree, a hand's by degrees)."""
        out: dict[str, Block] = {}
        for face in FACES:
            on = [b for b in self.kept if b.face == face]
            if not on:
                continue
            longest = max(on, key=lambda b: (b.samples, -float(b.std.max())))
            bound = NOISE_MARGIN * longest.stderr
            level = min((b for b in on if b.stderr <= bound), key=lambda b: (b.angle_deg, -b.samples))
            out[face] = level if level.angle_deg < longest.angle_deg - TILT_MARGIN_DEG else longest
        return out

    def as_dict(self) -> dict[str, object]:
        """How the blocks were found, for the calibration file."""
        doc: dict[str, object] = {
            "source": "detector" if self.threshold is not None else "label column",
            "window_samples": self.window,
            "sample_period_s": self.period,
            "threshold": self.threshold,
            "noise_floor": self.noise_floor,
            "min_samples": self.min_samples,
            "trim_samples": self.trim,
            "centre": [float(v) for v in self.centre],
            "blocks_found": len(self.blocks),
            "blocks_kept": len(self.kept),
            "gaps": len(self.gaps),
        }
        if self.threshold is None:
            for key in ("window_samples", "threshold", "noise_floor", "trim_samples"):
                del doc[key]
        return doc


def sample_period(times: FloatArray | None, rate: float | None) -> float | None:
    """Seconds per sample: the median time step, else 1/rate, else unknown."""
    if times is not None and times.size > 1:
        return _quantile(np.diff(times), 0.5)
    return 1.0 / rate if rate else None


def clock_of(times: FloatArray | None) -> tuple[Clock | None, IntArray]:
    """The clock of a log's ``times`` (seconds; core.clock: its median step by nearest rank, as
    ``sample_period``), and the index of each sample that follows a gap; None without two times."""
    if times is None or times.size < 2:
        return None, np.zeros(0, dtype=np.int64)
    steps = np.diff(times)
    found, at = clock.judge(steps, _quantile(steps, 0.5))
    return found, at + 1


def _timing(times: FloatArray | None, rate: float | None) -> tuple[Clock | None, float | None, IntArray]:
    """The clock, the seconds per sample (the clock's period, else 1/rate, else unknown) and the gaps."""
    found, breaks = clock_of(times)
    if found is not None:
        return found, found.period, breaks
    return None, (1.0 / rate if rate else None), breaks


def gaps(times: FloatArray | None, period: float | None) -> IntArray:
    """The index of each sample that follows a gap in time (a step over GAP_FACTOR periods)."""
    if times is None or period is None or times.size < 2:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(np.diff(times) > GAP_FACTOR * period).astype(np.int64) + 1


#: rolling_std takes the windows this many at a time (window_spread's temporaries stay small).
SPAN = 1 << 16


def rolling_std(values: FloatArray, window: int) -> FloatArray:
    """The standard deviation of the window of ``window`` samples centred on each sample (at
    the ends, the first or last whole window), as sqrt(var_x + var_y + var_z): from cumulative
    sums (``window_spread``), one vectorised pass per SPAN windows whatever the window."""
    n = values.shape[0]
    w = min(window, n)
    spread = np.concatenate(
        [window_spread([values[s : min(s + SPAN + w - 1, n)]], w) for s in range(0, n - w + 1, SPAN)]
    )
    head = w // 2  # the window centred on sample i starts at i - head
    out: FloatArray = np.concatenate([np.full(head, spread[0]), spread, np.full(n - head - spread.size, spread[-1])])
    return out


#: window_spread's sums start afresh every this many windows' length, about that stretch's first
#: reading: a reading far from it (a turn, another face) costs the still windows after it digits
#: only within this reach.
PIECE = 8


def window_spread(pieces: Sequence[FloatArray], w: int) -> FloatArray:
    """sqrt(var_x + var_y + var_z) of each whole window of ``w`` samples of the readings
    ``pieces`` (each (n, 3)) end to end, by its first sample: running sums over stretches of
    PIECE windows' length (overlapping by a window less one, so that each window lies in one),
    each about its first reading, so that a still stretch keeps its digits however far the
    readings before it were (sums over 65,536 samples about their first reading gave spreads
    of 1e-7 g beside faces 2 g apart wrong by 800 %, and of 1e-3 g by 5e-7)."""
    axes = np.concatenate([p.T for p in pieces], axis=1) if len(pieces) > 1 else np.array(pieces[0].T, order="C")
    n = axes.shape[1]
    m = n - w + 1  # whole windows
    length = PIECE * w
    if n <= length:  # one stretch: the three axes at once (the windows across a streamed log's blocks: short)
        var: FloatArray = _window_variance(axes - axes[:, :1], np.zeros((3, n + 1)), w).sum(axis=0)
        one: FloatArray = np.sqrt(np.maximum(var, 0.0))
        return one
    step = length - w + 1  # windows per stretch
    k = (n - length) // step + 1  # whole stretches; the windows after them are a shorter one's
    var = np.zeros(k * step)
    s = np.zeros((k, length + 1))
    for axis in axes:
        stretch = np.lib.stride_tricks.sliding_window_view(axis, length)[::step][:k]  # (k, length), a view
        var += _window_variance(stretch - stretch[:, :1], s, w).reshape(-1)
    spread = np.sqrt(np.maximum(var, 0.0))
    if k * step < m:
        spread = np.concatenate([spread, window_spread([axes[:, k * step :].T], w)])
    return spread


def _window_variance(y: FloatArray, s: FloatArray, w: int) -> FloatArray:
    """The variance of each window of ``w`` along the last axis of ``y`` (overwritten), from
    running sums kept in ``s`` (one longer)."""
    np.cumsum(y, axis=-1, out=s[..., 1:])
    mean = s[..., w:] - s[..., :-w]
    mean /= w
    np.square(y, out=y)
    np.cumsum(y, axis=-1, out=s[..., 1:])
    square = s[..., w:] - s[..., :-w]
    square /= w
    square -= np.square(mean, out=mean)
    return square


def _quantile(values: FloatArray, q: float) -> float:
    """The ``q`` quantile (nearest rank) by partition: np.percentile and np.median import
    numpy.ma, 10-20 ms of start-up."""
    k = min(values.size - 1, max(0, round(q * (values.size - 1))))
    found = smallest(values, k)  # None when the k-th is not below infinity (an inf, a NaN)
    return found if found is not None else float(np.partition(values, k)[k])


#: ``smallest`` brackets the k-th value from every STRIDE-th value, once there are BRACKETED ...
STRIDE, BRACKETED = 8, 1 << 16


def smallest(values: FloatArray, k: int, below: float = np.inf) -> float | None:
    """The ``k``-th smallest (0: the least) of the ``values`` under ``below``, exactly; None
    when there are no more than ``k``. A partition of millions copies them all (0.5 s for 20M
    on fresh pages): the k-th of every STRIDE-th value, give or take, brackets the answer, and
    only the values in that bracket are partitioned (all of them when it misses)."""
    if values.size >= BRACKETED:
        sample = values[::STRIDE]
        sample = sample[sample < below]
        j, margin = k // STRIDE, max(256, sample.size // 64)
        a, b = j - margin, j + margin
        ranks = [r for r in (a, b) if 0 <= r < sample.size]
        if ranks:  # (none: fewer values under ``below`` than a bracket spans, partitioned below)
            ends = np.partition(sample, ranks)
            lo = float(ends[a]) if a >= 0 else -np.inf
            hi = float(ends[b]) if b < sample.size else None  # None: up to ``below``
            under = int(np.count_nonzero(values < lo))
            inside = values >= lo
            inside &= values <= hi if hi is not None else values < below
            band = values[inside]
            if under <= k < under + band.size:
                return float(np.partition(band, k - under)[k - under])
            if hi is None and k >= under + band.size:
                return None  # every value under ``below`` is counted: there are k or fewer
    low = values[values < below]
    return float(np.partition(low, k)[k]) if low.size > k else None


def true_runs(mask: NDArray[np.bool_], breaks: IntArray) -> tuple[IntArray, IntArray]:
    """First and last index of each run of True in ``mask``, split before each of ``breaks``."""
    if not mask.size:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # where the runs of either kind start, and the end: runs of True are every other one
    edges = np.concatenate([[0], np.flatnonzero(mask[1:] != mask[:-1]) + 1, [mask.size]])
    first = 0 if mask[0] else 1
    starts, ends = edges[first:-1:2], edges[first + 1 :: 2] - 1
    if breaks.size:  # a run that spans a break becomes two
        cut = breaks[mask[breaks] & mask[breaks - 1]]
        starts = np.sort(np.concatenate([starts, cut]))
        ends = np.sort(np.concatenate([ends, cut - 1]))
    return starts.astype(np.int64), ends.astype(np.int64)


#: More samples than any log holds: a window or duration longer is a clock that is wrong.
MOST_SAMPLES = 2.0**53


def in_samples(value: float | None, default: tuple[float, int], period: float | None, floor: int) -> int:
    """A detector setting (seconds when the clock is known, else samples; None: ``default``) as a
    number of samples, at least ``floor``: the whole read's and the streamed scan's one rule."""
    if value is None:
        value = default[0] if period else default[1]
    samples = value / period if period else value
    if not samples <= MOST_SAMPLES:  # a clock of steps of 1e-300 s: windows no integer holds
        raise InputError(
            f"a sample every {period:.3g} s: {value:g} s would be {samples:.3g} samples (the log's clock is wrong)"
            if period
            else f"a window of {samples:.3g} samples: more than any log holds",
            hint=said("clock.wrong"),
        )
    return max(floor, round(samples))


def detect(
    values: FloatArray,
    times: FloatArray | None = None,
    rate: float | None = None,
    settings: DetectorSettings = DetectorSettings(),
) -> Segmentation:
    """Find, judge and label the still blocks of an (n, 3) log (``times`` in seconds)."""
    found, period, breaks = _timing(times, rate)
    window = in_samples(settings.window, WINDOW, period, 2)
    min_samples = in_samples(settings.min_duration, MIN_DURATION, period, 1)
    trim = window // 2 if settings.trim is None else in_samples(settings.trim, (0.0, 0), period, 0)
    spread = rolling_std(values, window)
    floor = None
    threshold = settings.threshold
    if threshold is None:
        floor = _quantile(spread, FLOOR_PERCENTILE / 100)
        scale = float(np.ptp(values[::16], axis=0).max()) or 1.0  # every 16th: a scale, not an exact range
        # quantised readings of a quiet sensor can have no spread at all: still is then "exactly level"
        threshold = FLOOR_FACTOR * floor if floor > 1e-9 * scale else 1e-6 * scale
    starts, ends = true_runs(spread < threshold, breaks)
    # the still period reaches half a window past the still centres, less the trim at each end
    reach = window // 2
    # ... and never across a gap: the first and last sample of the stretch between gaps bound it
    edges = np.concatenate([[0], breaks, [values.shape[0]]])
    stretch = np.searchsorted(breaks, starts, side="right")
    starts = np.maximum(starts - reach + trim, edges[stretch])
    ends = np.minimum(ends + (window - reach - 1) - trim, edges[stretch + 1] - 1)
    spans = [(int(a), int(b)) for a, b in zip(starts, ends, strict=True) if b >= a]
    seg = Segmentation(
        [],
        window,
        period,
        threshold,
        floor,
        min_samples,
        trim,
        np.zeros(3),
        settings.max_tilt_deg,
        [int(g) for g in breaks],
        clock=found,
    )
    return judge_blocks(seg, measure(values, spans), spans, settings)


def from_labels(
    values: FloatArray,
    labels: Sequence[str],
    mapping: Mapping[str, str],
    times: FloatArray | None = None,
    rate: float | None = None,
    settings: DetectorSettings = DetectorSettings(),
) -> Segmentation:
    """Blocks from a label column: each run of one label is a block, its face the label's
    entry in ``mapping`` (labels with none, such as a rotation's, are dropped)."""
    text = np.asarray(labels, dtype=object)
    if text.size == 0:
        spans: list[tuple[int, int]] = []
    else:
        change = np.flatnonzero(text[1:] != text[:-1]) + 1
        firsts = np.concatenate([[0], change])
        lasts = np.concatenate([change - 1, [text.size - 1]])
        spans = [(int(a), int(b)) for a, b in zip(firsts, lasts, strict=True) if str(text[a]).strip()]
    found, period, _ = _timing(times, rate)
    seg = Segmentation(
        [],
        0,
        period,
        None,
        None,
        in_samples(settings.min_duration, (0.0, 1), period, 1),
        0,
        np.zeros(3),
        settings.max_tilt_deg,
        clock=found,
    )
    names = {a: str(text[a]).strip() for a, _ in spans}
    faces = {a: mapping.get(names[a]) for a, _ in spans}
    return judge_blocks(seg, measure(values, spans), spans, settings, faces, names)


@dataclass(frozen=True)
class Measured:
    """A span's statistics, and its drift: the mean of its last third less that of its first."""

    stats: PoseStats
    drift: FloatArray


def measure(values: FloatArray, spans: list[tuple[int, int]]) -> list[Measured]:
    """Each span's statistics and drift, from the readings (n, 3) it indexes."""
    axes = values.T  # (3, n): each block's axes contiguous, 3x faster sums
    if axes.strides[1] != axes.itemsize:
        axes = np.ascontiguousarray(axes)
    found = []
    for a, b in spans:
        (_, first), (last, _) = thirds(a, b)
        drift = axes[:, last : b + 1].mean(axis=1) - axes[:, a : first + 1].mean(axis=1)
        found.append(Measured(pose_stats(axes[:, a : b + 1].T), drift))
    return found


def thirds(a: int, b: int) -> tuple[tuple[int, int], tuple[int, int]]:
    """The first and last third of the span ``a``..``b`` (first and last index each, inclusive;
    a reading at least): a block's drift is the mean of its last less that of its first."""
    third = max(1, (b - a + 1) // 3)
    return (a, a + third - 1), (b + 1 - third, b)


def judge_blocks(
    seg: Segmentation,
    measured: list[Measured],
    spans: list[tuple[int, int]],
    settings: DetectorSettings,
    faces: Mapping[int, str | None] | None = None,
    names: Mapping[int, str] | None = None,
) -> Segmentation:
    """Find the rough centre from each block's statistics, then label and keep or drop each one."""
    stats = [m.stats for m in measured]
    # the centre from the blocks that are poses: a labelled log's rotations (unmapped) average
    # to the centre itself and would pull the estimate there
    posed = [faces is None or faces[a] is not None for a, _ in spans]
    long_enough = [
        st.mean for (a, b), st, pose in zip(spans, stats, posed, strict=True) if b - a + 1 >= seg.min_samples and pose
    ]
    means = np.array(long_enough or [st.mean for st in stats] or [np.zeros(3)])
    if settings.nominal_offset is not None:
        seg.centre = np.asarray(settings.nominal_offset, dtype=float)
    else:
        seg.centre = rough_centre(means, settings.max_tilt_deg)
    _label(seg, measured, spans, settings, faces, names)
    if settings.nominal_offset is None:  # the midpoint of opposite faces, where both are found
        centre = face_midpoint(seg)
        if not np.array_equal(centre, seg.centre):
            seg.centre, seg.blocks = centre, []
            _label(seg, measured, spans, settings, faces, names)
    return seg


def face_midpoint(seg: Segmentation) -> FloatArray:
    """The centre with each axis whose two faces both have a block moved to the midpoint of those
    blocks (each face's best): the offset cancels between opposite faces, so this is the reading
    at zero stimulus to second order in their tilt, where the median of the block means is off by
    whatever the orientations happen to be (seen: faces labelled 11-18° off on a real log)."""
    centre = seg.centre.copy()
    best = seg.best()
    for i, axis in enumerate("xyz"):
        up, down = best.get(f"+{axis}"), best.get(f"-{axis}")
        if up is not None and down is not None:
            centre[i] = 0.5 * (up.mean[i] + down.mean[i])
    return centre


def _label(
    seg: Segmentation,
    measured: list[Measured],
    spans: list[tuple[int, int]],
    settings: DetectorSettings,
    faces: Mapping[int, str | None] | None,
    names: Mapping[int, str] | None,
) -> None:
    """Each block measured about ``seg.centre``: its face, or why it is dropped."""
    nearest_faces = _nearest_faces(np.array([m.stats.mean for m in measured]).reshape(-1, 3) - seg.centre)
    for number, ((a, b), m, found) in enumerate(zip(spans, measured, nearest_faces, strict=True), start=1):
        st, drift = m.stats, m.drift
        nearest, angle, magnitude = found
        face = nearest if angle <= settings.max_tilt_deg else None
        dropped = None
        if faces is not None:  # a labelled log: the label says the face, and the angle is from it
            face = faces[a]
            dropped = UNMAPPED if face is None else None
            if face in FACES and magnitude > 0:
                angle = angle_deg(st.mean - seg.centre, face)
                dropped = MISLABELLED if angle > settings.max_tilt_deg else None
        if dropped is None and b - a + 1 < seg.min_samples:
            dropped = SHORT
        elif dropped is None and faces is None and float(st.std.max()) > settings.max_noise * magnitude:
            dropped = NOISY
        elif dropped is None and faces is None and float(np.abs(drift).max()) > settings.max_noise * magnitude:
            dropped = DRIFTING
        seg.blocks.append(
            Block(
                number=number,
                first=a,
                last=b,
                mean=st.mean,
                std=st.std,
                drift=drift,
                duration=None if seg.period is None else (b - a + 1) * seg.period,
                nearest=nearest,
                angle_deg=angle,
                face=face,
                dropped=dropped,
                label=None if names is None else names[a],
            )
        )


def table_rows(values: FloatArray, centre: FloatArray) -> Segmentation:
    """A table of orientations (one averaged reading a row, methods.orientation_table) as still
    blocks of one row each: nothing dropped, no spread known (0), no clock."""
    zero = np.zeros(values.shape[1])
    rows = []
    for k, (mean, (nearest, angle, _)) in enumerate(zip(values, _nearest_faces(values - centre), strict=True)):
        rows.append(Block(k + 1, k, k, mean.copy(), zero.copy(), zero.copy(), None, nearest, angle, None))
    return Segmentation(rows, 1, None, None, None, 1, 0, np.asarray(centre, dtype=np.float64))


def rough_centre(means: FloatArray, max_tilt_deg: float) -> FloatArray:
    """The reading at zero stimulus, roughly, from the block means alone: of the per-axis
    midpoint (right when opposite faces are there, and for turns through all orientations), the
    per-axis median (right when only some faces are: +x +y +z) and zero (a single block of data
    already in g), the first that puts the most blocks within ``max_tilt_deg`` of a face."""
    ordered = np.sort(means, axis=0)
    median = (ordered[(len(means) - 1) // 2] + ordered[len(means) // 2]) / 2
    candidates = [(ordered[-1] + ordered[0]) / 2, median, np.zeros(means.shape[1])]
    best: tuple[int, float, FloatArray] | None = None
    for centre in candidates:
        norms = np.linalg.norm(means - centre, axis=1)
        if float(norms.min()) <= 0.1 * float(norms.max()):
            continue  # a block at the centre itself: no direction to judge
        tilts = [t for _, t, _ in _nearest_faces(means - centre)]
        labelled, tilt = sum(t <= max_tilt_deg for t in tilts), float(sum(tilts))
        # as many labelled: the centre that puts them nearer their faces (two blocks of one face
        # 4 degrees apart have their midpoint between them, which tilts each 12 degrees onto +-y)
        if best is None or labelled > best[0] or (labelled == best[0] and tilt < best[1] - 1e-9):
            best = (labelled, tilt, centre)
    return candidates[0] if best is None else best[2]


def _nearest_faces(v: FloatArray) -> list[tuple[str, float, float]]:
    """For each row of ``v`` (n, 3): the face nearest its direction, the angle to it in degrees,
    and |v| (as np.linalg.norm takes it: the same digits), every row's norm in one call."""
    if not len(v):
        return []
    norms = np.sqrt(np.matmul(v[:, None, :], v[:, :, None])[:, 0, 0]).tolist()
    axes = np.argmax(np.abs(v), axis=1)
    along = v[np.arange(len(v)), axes].tolist()
    found = []
    for norm, axis, x in zip(norms, axes.tolist(), along, strict=True):
        if norm == 0.0:
            found.append(("+z", 90.0, 0.0))
        else:
            face = ("+" if x > 0 else "-") + "xyz"[axis]
            found.append((face, math.degrees(math.acos(min(1.0, abs(x) / norm))), norm))
    return found


def missing(seg: Segmentation, faces: Sequence[str]) -> list[str]:
    """Why each face of ``faces`` has no kept block: one hint per face, naming what to change."""
    have = seg.best()
    hints = []
    for face in faces:
        if face in have:
            continue
        if seg.threshold is None:  # a labelled log
            wrong = [b for b in seg.blocks if b.face == face and b.dropped == MISLABELLED]
            if wrong:
                b = wrong[0]
                hints.append(
                    f"no {face} block: label {b.label!r} is mapped to {face} but its block {b.number} reads like "
                    f"{b.nearest} ({b.angle_deg:.0f}° from {face}); {said('blocks.mislabelled')}"
                )
            else:
                hints.append(f"no {face} block: no label names {face} ({said('blocks.unnamed', face=face)})")
            continue
        near = [b for b in seg.blocks if b.nearest == face]
        facing = [b for b in near if b.angle_deg <= seg.max_tilt_deg]
        if facing:
            block = max(facing, key=lambda b: b.samples)
            if block.dropped == SHORT:
                length, limit = _length(block.samples, seg.period), _length(seg.min_samples, seg.period)
                hints.append(
                    f"no {face} block: the longest still period facing {face} was {length}, "
                    f"{said('blocks.short', limit=limit)}"
                )
            else:
                hints.append(
                    f"no {face} block: the longest still period facing {face} (block {block.number}) was "
                    f"{block.dropped} ({said('blocks.noisy')})"
                )
        elif near:
            block = min(near, key=lambda b: b.angle_deg)
            hints.append(
                f"no {face} block: the closest still period (block {block.number}) is {block.angle_deg:.0f}° "
                f"from {face}, {said('blocks.tilted', tilt=seg.max_tilt_deg)}"
            )
        else:
            hints.append(f"no {face} block: no still period faces {face}; rest the unit on that face and hold it still")
    return hints


def _length(samples: int, period: float | None) -> str:
    return f"{samples * period:.3g} s" if period else f"{samples} samples"
