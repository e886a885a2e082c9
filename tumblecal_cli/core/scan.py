"""The still-block detector of ``core.blocks.detect``, fed a log block by block (numpy only).

``detect`` needs the whole log in memory: 20 million readings are 0.5 GB of floats before
anything else. ``Scan`` finds the same blocks while the log streams past and keeps only the
readings of the still periods (and those within a window of one), or only their spreads (and
``finish`` is given what measures the blocks: io.csv.logread's sums over chunks, core.chunks, 56
bytes a chunk of 256 readings): its memory grows with the still blocks, not with the log.

The rules are ``detect``'s (its docstring): the spread of the window centred on each sample,
``FLOOR_FACTOR`` times its ``FLOOR_PERCENTILE``-th percentile as the threshold, runs below it
split at gaps in time, reaching half a window past the still centres less the trim. Three
figures of the whole log are only known at its end, and each is kept exact:

- the sample period (the median time step): a count of each distinct step;
- the noise floor (a percentile of every sample's spread): a sample is a *candidate* when its
  spread is below the *bound* in force when it is seen, and candidates and their neighbours are
  kept with their spreads. The bound starts infinite and falls to ``BOUND_FACTOR`` times the
  threshold the log so far gives, each time the log has grown TIGHTEN times; every spread below the lowest
  bound used is among those kept, so the percentile is exact when it is below that bound;
- the gaps: every step over half a gap of the first blocks' period, judged at the end;
- whether the clock is bursty (``core.clock``): the time of every WINDOW-th sample.

``finish`` returns None when the log broke an assumption: its threshold came out above a bound
used earlier, its period differs from the first blocks' enough to change the window, its
steps are too many kinds to count, its clock is bursty (the whole read takes its period from
the mean step and its gaps by its pauses), or a spread lies on the threshold (within ``TIE``, or
``ROUNDING`` times (range / threshold)^2 where that is more: a quantised log's spreads take a
few exact values, and one can be the threshold itself; a quiet log's spreads are summed from
other stretches here than in the whole read; either way rounding alone would say which side).
The caller then reads the log whole and calls ``detect``.

A block's spreads may come computed (``feed(..., inside=)``, ``window_spread`` of the block
alone, on another thread): only the windows across its start are computed here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import clock
from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.core.blocks import (
    FLOOR_FACTOR,
    FLOOR_PERCENTILE,
    GAP_FACTOR,
    MIN_DURATION,
    WINDOW,
    DetectorSettings,
    Measured,
    Segmentation,
    in_samples,
    judge_blocks,
    smallest,
    true_runs,
    window_spread,
)
from tumblecal_cli.core.blocks import measure as segment_measure

#: A sample is a still candidate when its spread is below this many times the threshold so far ...
BOUND_FACTOR = 4.0
#: ... taken again each time the log has grown this many times (each take reads every spread kept).
TIGHTEN = 2
#: A spread this close to the threshold (relative) is on it: still or not by rounding alone, which
#: the whole read's sums and these do differently, so the log is read whole ...
TIE = 1e-9
#: ... and closer than this times (the readings' range / the threshold)^2: the two reads sum a
#: window from different stretches (window_spread), and their spreads differ by up to about
#: 80 ulp of that (1.3e-9 at 1e-3 g of noise beside faces 2 g apart, 3e-6 at 1e-5 g).
ROUNDING = 1e-13
#: A given --threshold keeps the spreads up to this much over it (relative), to judge them by the tie.
MARGIN = 1e-3
#: More distinct time steps than this and the median step is not counted: the caller reads whole.
MAX_STEPS = 1 << 20
#: The most kinds of time step counted one by one in a block before the rest are sorted.
PEELS = 4


@dataclass
class ScanPart:
    """Consecutive samples of a log: the index of the first, readings as axes (3, n), and what
    the caller carries with them: floats (n, f) and ints (n, k)."""

    first: int
    axes: FloatArray
    floats: FloatArray
    ints: IntArray

    def __len__(self) -> int:
        return int(self.axes.shape[1])

    def cut(self, a: int, b: int) -> ScanPart:
        """Samples ``a``..``b - 1`` of this part (views)."""
        return ScanPart(self.first + a, self.axes[:, a:b], self.floats[a:b], self.ints[a:b])


@dataclass
class Kept:
    """The samples kept, end to end, as runs of consecutive samples of the log."""

    axes: FloatArray  # (3, n)
    floats: FloatArray
    ints: IntArray
    spread: FloatArray
    run_first: IntArray  # each run's first sample: its index in the log ...
    run_at: IntArray  # ... and its position here
    run_size: IntArray

    @property
    def values(self) -> FloatArray:
        """The readings (n, 3): a view of ``axes``."""
        return self.axes.T

    def log_index(self, at: IntArray) -> IntArray:
        """The log's index of the samples at positions ``at``."""
        found: IntArray = log_index(self.run_first, self.run_at, at)
        return found

    def position(self, index: int) -> int | None:
        """Where the log's sample ``index`` is kept, or None."""
        k = int(np.searchsorted(self.run_first, index, side="right")) - 1
        if k < 0 or index >= self.run_first[k] + self.run_size[k]:
            return None
        return int(self.run_at[k] + index - self.run_first[k])


#: What measures a Scan's blocks when it kept no readings: the samples kept (their spreads and
#: where each run of them is in the log) and each block's first and last position among them.
Measure = Callable[[Kept, list[tuple[int, int]]], list[Measured]]


def log_index(run_first: IntArray, run_at: IntArray, at: IntArray | int) -> IntArray:
    """The log's index of the kept samples at positions ``at``, from where each run of them
    starts in the log (``run_first``) and among those kept (``run_at``)."""
    k = np.searchsorted(run_at, at, side="right") - 1
    index: IntArray = run_first[k] + (at - run_at[k])
    return index


class _Store:
    """Kept samples written end to end into arrays made once for as many as the log can hold
    (``capacity``: memory is only touched where written), grown if the guess was short; their
    spreads alone unless ``readings``."""

    def __init__(self, capacity: int, readings: bool = True) -> None:
        self.capacity = max(1024, capacity)
        self.readings = readings
        self.axes: FloatArray | None = None
        self.floats: FloatArray | None = None
        self.ints: IntArray | None = None
        self.spread = np.empty(self.capacity)
        self.runs: list[tuple[int, int]] = []  # (first index, size)
        self.size = 0

    def add(self, part: ScanPart, spread: FloatArray) -> None:
        n = len(part)
        if self.readings and (self.axes is None or self.floats is None or self.ints is None):
            self.axes = np.empty((3, self.capacity))
            self.floats = np.empty((self.capacity, part.floats.shape[1]))
            self.ints = np.empty((self.capacity, part.ints.shape[1]), dtype=part.ints.dtype)
        if self.size + n > self.capacity:
            self._grow(self.size + n)
        if self.runs and self.runs[-1][0] + self.runs[-1][1] == part.first:
            self.runs[-1] = (self.runs[-1][0], self.runs[-1][1] + n)
        else:
            self.runs.append((part.first, n))
        k = self.size
        if self.axes is not None and self.floats is not None and self.ints is not None:
            self.axes[:, k : k + n] = part.axes
            self.floats[k : k + n] = part.floats
            self.ints[k : k + n] = part.ints
        self.spread[k : k + n] = spread
        self.size += n

    def _grow(self, need: int) -> None:
        capacity = max(need, self.capacity * 3 // 2)
        self.spread = np.concatenate([self.spread[: self.size], np.empty(capacity - self.size)])
        self.capacity = capacity
        if self.axes is None or self.floats is None or self.ints is None:
            return
        axes = np.empty((3, capacity))
        axes[:, : self.size] = self.axes[:, : self.size]
        self.axes = axes
        self.floats = np.concatenate([self.floats[: self.size], np.empty((capacity - self.size, self.floats.shape[1]))])
        self.ints = np.concatenate(
            [self.ints[: self.size], np.empty((capacity - self.size, self.ints.shape[1]), dtype=self.ints.dtype)]
        )

    def smallest(self, k: int, bound: float) -> float | None:
        """The ``k``-th smallest spread kept below ``bound`` (``segment.smallest``)."""
        return smallest(self.spread[: self.size], k, bound)

    def join(self, template: ScanPart) -> Kept:
        k = self.size
        first = np.array([r[0] for r in self.runs], dtype=np.int64)
        size = np.array([r[1] for r in self.runs], dtype=np.int64)
        at = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64) if size.size else size
        if self.axes is None or self.floats is None or self.ints is None:  # their spreads alone
            return Kept(template.axes, template.floats, template.ints, self.spread[:k], first, at, size)
        return Kept(self.axes[:, :k], self.floats[:k], self.ints[:k], self.spread[:k], first, at, size)


class Scan:
    """Feed a log's blocks in order (``feed``), then ``finish``."""

    def __init__(
        self,
        period: float | None,
        settings: DetectorSettings | None = None,
        capacity: int = 1 << 16,
        readings: bool = True,
    ) -> None:
        """``period``: seconds per sample from the log's first blocks (the median step there),
        or 1/rate; None when neither is known (the window is then in samples). ``capacity``:
        how many samples the log may have, about (room for the kept ones is made once).
        ``readings``: keep the still samples' readings (and what goes with them), not their
        spreads alone; without them ``finish`` is given what measures the blocks."""
        settings = self.settings = settings or DetectorSettings()
        self.period = period
        self.window = in_samples(settings.window, WINDOW, period, 2)
        self.min_samples = in_samples(settings.min_duration, MIN_DURATION, period, 1)
        self.trim = self.window // 2 if settings.trim is None else in_samples(settings.trim, (0.0, 0), period, 0)
        self.reach = self.window // 2
        self.pad = max(0, self.reach - self.trim) + 1  # neighbours kept each side of a candidate
        self.n = 0  # samples fed
        self.carry: ScanPart | None = None  # the last window - 1 samples: the windows that go on
        self.finalized = 0  # samples whose spread is known
        self.tail_spread = 0.0  # the spread of the last whole window so far
        self.held: list[ScanPart] = []  # samples with a spread, waiting for their neighbours' verdict
        self.held_spread = np.zeros(0)
        self.held_candidate = np.zeros(0, dtype=bool)
        self.before = np.zeros(0, dtype=bool)  # candidate flags of the pad samples decided last
        self.store = _Store(capacity, readings)
        self.template: ScanPart | None = None
        # a given threshold is the bound, and a little over it: a spread on it must be seen (finish's tie)
        self.bound = np.inf if settings.threshold is None else float(settings.threshold) * (1 + MARGIN)
        self.least_bound = self.bound  # the lowest bound any sample was judged by
        self.tightened = 0  # samples finalized when the bound was last lowered
        self.lo, self.hi = np.full(3, np.inf), np.full(3, -np.inf)  # range of every 16th reading
        self.steps: dict[float, int] = {}
        self.last_second: float | None = None
        self.gap_at: list[IntArray] = []  # samples after a step over half a gap (judged at the end)
        self.gap_step: list[FloatArray] = []
        self.gap_ints: list[IntArray] = []  # ... and the ints of the sample before each
        self.last_ints: IntArray | None = None  # the ints of the last sample fed
        #: after finish: the ints of the sample before each gap of the segmentation (k, ints columns)
        self.before_gaps: IntArray = np.zeros((0, 0), dtype=np.int64)
        self.counted = True  # the steps could be counted (not too many kinds)
        self.every: list[FloatArray] = []  # the time of every clock.WINDOW-th sample (core.clock)

    def feed(
        self,
        values: FloatArray,
        seconds: FloatArray | None,
        floats: FloatArray,
        ints: IntArray,
        inside: FloatArray | None = None,
    ) -> None:
        """The next ``values`` (m, 3) of the log, their ``seconds`` and what goes with them;
        ``inside``: ``window_spread([values], window)``, when computed already."""
        m = values.shape[0]
        if m == 0:
            return
        self._time(seconds, ints)
        every = values[(-self.n) % 16 :: 16]  # the readings at multiples of 16 in the whole log
        if every.size:
            np.minimum(self.lo, every.min(axis=0), out=self.lo)
            np.maximum(self.hi, every.max(axis=0), out=self.hi)
        part = ScanPart(self.n, values.T, floats, ints)
        self.n += m
        if self.template is None:
            self.template = part.cut(0, 0)
        w = self.window
        carry = self.carry
        size = m + (len(carry) if carry is not None else 0)
        if size < w:
            self.carry = _join([carry, part]) if carry is not None else part
            return
        if carry is not None and len(carry) == w - 1 and inside is not None and m >= w:
            across = window_spread([carry.axes.T, values[: w - 1]], w)  # the windows that start in carry
            windows = np.concatenate([across, inside])
        else:
            windows = window_spread([p.axes.T for p in (carry, part) if p is not None], w)
        self.tail_spread = float(windows[-1])
        head = w // 2
        start = carry.first if carry is not None else part.first
        last_centre = start + size - w + head  # the last sample whose centred window is whole
        if self.finalized == 0:  # the log's first samples take the first whole window's spread
            windows = np.concatenate([np.full(head, windows[0]), windows])
        done = _between([carry, part], self.finalized, last_centre + 1)
        self.finalized = last_centre + 1
        self.carry = _join(_between([carry, part], self.n - (w - 1), self.n))
        self._take(done, windows)
        self._decide(final=False)

    def _time(self, seconds: FloatArray | None, ints: IntArray) -> None:
        before_block = self.last_ints
        self.last_ints = ints[-1].copy()
        if seconds is None or self.period is None:
            return
        if self.last_second is None:
            steps, offset = np.diff(seconds), self.n + 1
        else:
            steps, offset = np.diff(seconds, prepend=self.last_second), self.n
        self.last_second = float(seconds[-1])
        self.every.append(seconds[(-self.n) % clock.WINDOW :: clock.WINDOW].copy())
        if self.counted:
            _count(steps, self.steps)
            self.counted = len(self.steps) <= MAX_STEPS
        big = np.flatnonzero(steps > 0.5 * GAP_FACTOR * self.period)
        if big.size:
            self.gap_at.append(big + offset)
            self.gap_step.append(steps[big])
            before = big + (offset - self.n) - 1  # the sample before each, here (-1: the last block's last)
            found = ints[np.maximum(before, 0)]
            if before[0] < 0 and before_block is not None:
                found[0] = before_block
            self.gap_ints.append(found)

    def _take(self, done: list[ScanPart], spread: FloatArray) -> None:
        """Samples whose spread is now known: candidates are those below the bound in force."""
        self.least_bound = min(self.least_bound, self.bound)
        self.held += [p for p in done if len(p)]
        self.held_spread = np.concatenate([self.held_spread, spread])
        self.held_candidate = np.concatenate([self.held_candidate, spread < self.bound])
        if self.settings.threshold is None and self.finalized >= TIGHTEN * max(self.tightened, 2 * self.window):
            self._tighten()

    def _tighten(self) -> None:
        """A lower bound from the threshold of the log so far (each time the log has grown TIGHTEN times)."""
        self.tightened = self.finalized
        decided = self.finalized - self.held_spread.size
        if decided <= 0:
            return
        floor = self.store.smallest(_rank(decided), self.least_bound)
        if floor is not None:
            quantised = 1e-6 * (float((self.hi - self.lo).max()) or 1.0)  # finish's threshold for no spread
            self.bound = min(self.bound, BOUND_FACTOR * max(FLOOR_FACTOR * floor, quantised))

    def _decide(self, *, final: bool) -> None:
        """Keep each held sample within ``pad`` of a candidate; the last ``pad`` wait for what follows."""
        held = self.held
        size = self.held_spread.size
        ready = size if final else size - self.pad
        if not held or ready <= 0:
            return
        first = held[0].first
        flags = np.concatenate([self.before, self.held_candidate])
        pad, at = self.pad, self.before.size  # the first held sample's position in flags
        for a, b in _near(flags, pad, at, ready):  # runs of kept samples
            at = a
            for piece in _between(held, first + a, first + b):
                self.store.add(piece, self.held_spread[at : at + len(piece)])
                at += len(piece)
        self.before = self.held_candidate[max(0, ready - self.pad) : ready]
        rest = _between(held, first + ready, first + size)
        self.held = [ScanPart(p.first, p.axes.copy(), p.floats.copy(), p.ints.copy()) for p in rest]  # not the block
        self.held_spread = self.held_spread[ready:].copy()
        self.held_candidate = self.held_candidate[ready:].copy()

    def finish(self, measure: Measure | None = None) -> tuple[Segmentation, Kept] | None:
        """The segmentation, and the samples kept (each block's ``first``..``last`` are
        positions among them); None when the log must be read whole instead (the module's
        docstring). ``measure``: each block's statistics, for a Scan that kept no readings."""
        if self.n == 0 or self.template is None:
            return None
        if self.carry is not None and self.finalized < self.n:
            tail = self.carry.cut(self.finalized - self.carry.first, len(self.carry))
            if self.finalized == 0:  # shorter than a window: one window of every sample
                spread = np.full(len(tail), float(window_spread([tail.axes.T], len(tail))[0]))
            else:  # the last samples take the last whole window's spread
                spread = np.full(len(tail), self.tail_spread)
            self.finalized = self.n
            self._take([tail], spread)
        self._decide(final=True)
        period = self._period()
        if period is False or (period != self.period and not self._same_windows(period)):
            return None
        if period and self.every and self._bursty(period):
            return None
        floor = None
        threshold = self.settings.threshold
        span = float((self.hi - self.lo).max())  # the readings' range
        if threshold is None:
            floor = self.store.smallest(_rank(self.n), self.least_bound)
            if floor is None:
                return None
            scale = span or 1.0
            # quantised readings of a quiet sensor can have no spread at all: still is then "exactly level"
            threshold = FLOOR_FACTOR * floor if floor > 1e-9 * scale else 1e-6 * scale
        ratio = span / threshold if threshold > 0 else np.inf
        tie = max(TIE, ROUNDING * ratio * ratio) if ratio < 1e100 else np.inf  # (--threshold 0: no tie holds)
        if not threshold * (1 + tie) <= self.least_bound:
            return None  # a spread on the threshold could have been let go
        kept = self.store.join(self.template)
        on = kept.spread >= threshold * (1 - tie)
        on &= kept.spread <= threshold * (1 + tie)
        if on.any():
            return None  # a spread on the threshold (a quantised log's, a quiet one's): either side by rounding
        breaks = self._gaps(period)
        spans = self._spans(kept, breaks, threshold)
        if spans is None:
            return None
        seg = Segmentation(
            [],
            self.window,
            period,
            threshold,
            floor,
            self.min_samples,
            self.trim,
            np.zeros(3),
            self.settings.max_tilt_deg,
            [int(g) for g in breaks],
        )
        if self.steps:
            seg.zero_steps = self.steps.get(0.0, 0) / sum(self.steps.values())
            if period:
                short = {k: c for k, c in self.steps.items() if 0 <= k <= GAP_FACTOR * period}
                seg.mean_step = sum(k * c for k, c in short.items()) / sum(short.values())
        if measure is not None:
            measured = measure(kept, spans)
        elif self.store.readings:
            measured = segment_measure(kept.values, spans)
        else:
            raise ValueError("a Scan without readings is finished with what measures its blocks")
        return judge_blocks(seg, measured, spans, self.settings), kept

    def _period(self) -> float | bool | None:
        """The median step, as ``detect`` takes it (nearest rank); False when not counted."""
        if self.period is None or self.last_second is None or not self.steps:
            return self.period
        if not self.counted:
            return False
        kinds = np.array(sorted(self.steps))
        counts = np.array([self.steps[k] for k in kinds.tolist()])
        total = int(counts.sum())
        k = min(total - 1, max(0, round(0.5 * (total - 1))))
        return float(kinds[int(np.searchsorted(np.cumsum(counts), k + 1))])

    def _bursty(self, median: float) -> bool:
        """Whether the whole log's clock is bursty, as ``core.clock.judge`` judges it."""
        spans = np.diff(np.concatenate(self.every))
        zero = self.steps.get(0.0, 0) / max(1, sum(self.steps.values()))
        return clock.classify(median, clock.local_step(spans), zero)

    def _same_windows(self, period: float | None) -> bool:
        """Whether the whole log's period gives the windows its first blocks' did."""
        if period is None or self.period is None or not period >= 0.5 * self.period:
            return False
        s = self.settings
        trim = self.window // 2 if s.trim is None else in_samples(s.trim, (0.0, 0), period, 0)
        return (
            in_samples(s.window, WINDOW, period, 2) == self.window
            and in_samples(s.min_duration, MIN_DURATION, period, 1) == self.min_samples
            and trim == self.trim
        )

    def _gaps(self, period: float | None) -> IntArray:
        """The sample after each gap (and ``before_gaps``, the ints of the sample before it)."""
        if period is None or not self.gap_at:
            return np.zeros(0, dtype=np.int64)
        at, steps = np.concatenate(self.gap_at), np.concatenate(self.gap_step)
        self.before_gaps = np.concatenate(self.gap_ints)[steps > GAP_FACTOR * period]
        return at[steps > GAP_FACTOR * period].astype(np.int64)

    def _spans(self, kept: Kept, breaks: IntArray, threshold: float) -> list[tuple[int, int]] | None:
        """``detect``'s spans, as positions among the kept samples; None if one reaches past
        what was kept (it cannot, by the pad: a check)."""
        split = [kept.run_at[1:]]  # samples not kept between two runs: never still
        for g in breaks.tolist():  # a gap between two kept samples of one run
            at = kept.position(g)
            if at is not None and at > 0 and kept.position(g - 1) == at - 1:
                split.append(np.array([at]))
        starts, ends = true_runs(kept.spread < threshold, np.unique(np.concatenate(split)).astype(np.int64))
        reach, trim, w = self.reach, self.trim, self.window
        first, last = kept.log_index(starts), kept.log_index(ends)
        edges = np.concatenate([[0], breaks, [self.n]])
        stretch = np.searchsorted(breaks, first, side="right")
        first = np.maximum(first - reach + trim, edges[stretch])
        last = np.minimum(last + (w - reach - 1) - trim, edges[stretch + 1] - 1)
        spans = []
        for a, b in zip(first.tolist(), last.tolist(), strict=True):
            if b < a:
                continue
            pa, pb = kept.position(a), kept.position(b)
            if pa is None or pb is None or pb - pa != b - a:
                return None
            spans.append((pa, pb))
        return spans


def _near(flags: NDArray[np.bool_], pad: int, at: int, ready: int) -> list[tuple[int, int]]:
    """The runs (first, end) of positions 0 .. ``ready - 1`` (``flags``'s ``at`` ..) within ``pad``
    of a True flag: each run of True flags widened by ``pad`` each way, those that meet merged."""
    if not flags.size:
        return []
    bounds = np.concatenate([[0], np.flatnonzero(flags[1:] != flags[:-1]) + 1, [flags.size]])
    first = 0 if flags[0] else 1  # runs alternate: the first True one
    lo = np.maximum(bounds[first:-1:2] - pad - at, 0)
    hi = np.minimum(bounds[first + 1 :: 2] + pad - at, ready)
    ok = hi > lo
    lo, hi = lo[ok], hi[ok]
    if lo.size > 1:  # widened runs that meet are one
        starts = np.flatnonzero(np.concatenate([[True], lo[1:] > hi[:-1]]))
        lo, hi = lo[starts], np.maximum.reduceat(hi, starts)
    return list(zip(lo.tolist(), hi.tolist(), strict=True))


def _rank(n: int) -> int:
    """The nearest rank of the FLOOR_PERCENTILE-th percentile of n values (``segment._quantile``)."""
    return min(n - 1, max(0, round(FLOOR_PERCENTILE / 100 * (n - 1))))


def _join(parts: Sequence[ScanPart | None]) -> ScanPart:
    """Consecutive parts as one (a copy, unless there is one)."""
    found: list[ScanPart] = [p for p in parts if p is not None and len(p)]
    if not found:
        return next(p for p in parts if p is not None)
    if len(found) == 1:
        return found[0]
    return ScanPart(
        found[0].first,
        np.concatenate([p.axes for p in found], axis=1),
        np.concatenate([p.floats for p in found]),
        np.concatenate([p.ints for p in found]),
    )


def _between(parts: Sequence[ScanPart | None], first: int, end: int) -> list[ScanPart]:
    """The samples of consecutive ``parts`` whose log index is ``first`` .. ``end - 1`` (views)."""
    out = []
    for p in parts:
        if p is None or not len(p):
            continue
        lo, hi = max(first, p.first), min(end, p.first + len(p))
        if lo < hi:
            out.append(p.cut(lo - p.first, hi - p.first))
    return out


def _count(steps: FloatArray, counts: dict[float, int]) -> None:
    """Add each distinct step of ``steps`` to ``counts``: a clock's steps are a few kinds, each
    counted in one pass; any more, by their bits when they are close (neighbouring floats: a
    count, not a sort), else by sorting."""
    ahead = steps[steps > 0]
    if ahead.size < steps.size:  # a clock that stands still (or steps back, with --rate): sorted
        kinds, many = np.unique(steps[~(steps > 0)], return_counts=True)
        for k, c in zip(kinds.tolist(), many.tolist(), strict=True):
            counts[k] = counts.get(k, 0) + c
    for _ in range(PEELS):  # a clock's few kinds of step, one pass each (a sort costs ten times more)
        if not ahead.size:
            return
        kind = float(ahead[0])
        same = ahead == kind
        times = int(np.count_nonzero(same))
        counts[kind] = counts.get(kind, 0) + times
        if times == ahead.size:
            return
        ahead = ahead[~same]
    bits = ahead.view(np.int64)
    lo = int(bits.min())
    if int(bits.max()) - lo < 1 << 16:
        tally = np.bincount(bits - lo)
        found = np.flatnonzero(tally)
        kinds = (found + lo).view(np.float64)
        many = tally[found]
    else:
        kinds, many = np.unique(ahead, return_counts=True)
    for k, c in zip(kinds.tolist(), many.tolist(), strict=True):
        counts[k] = counts.get(k, 0) + c
