"""The still-block detector of ``core.blocks.detect``, fed a log block by block (numpy only).

``detect`` needs the whole log in memory: 20 million readings are 0.5 GB of floats before
anything else. ``Scan`` finds the same blocks while the log streams past and keeps only the
readings of the still periods (and those within a window of one), or only where they are (and
``finish`` is given what measures the blocks: io.csv.logread's sums over chunks, core.chunks, 56
bytes a chunk of 256 readings): its memory does not grow with the still readings (a few bytes a
run of them, and bands of spreads of a fixed size), nor with the log.

The rules are ``detect``'s (its docstring): the spread of the window centred on each sample,
``FLOOR_FACTOR`` times its ``FLOOR_PERCENTILE``-th percentile as the threshold, runs below it
split at gaps in time, reaching half a window past the still centres less the trim. Three
figures of the whole log are only known at its end, and each is kept exact:

- the sample period (the median time step): a count of each distinct step;
- the noise floor (a percentile of every sample's spread): a sample is a *candidate* when its
  spread is below the *bound* in force when it is seen, and candidates and their neighbours are
  kept. The bound starts infinite and falls to ``BOUND_FACTOR`` times the threshold the log so
  far gives, each time the log has grown TIGHTEN times; every spread below the lowest bound
  used is a kept sample's. Those spreads are counted in a band about the percentile so far
  (``_Floor``): all of them until FLOOR_SPREADS are, then those below the band counted, those
  in it kept (FLOOR_KEEP each side of the percentile, narrowed again each time it holds
  FLOOR_SPREADS), those above it let go; the percentile is exact when it is below the lowest
  bound and in the band at the end;
- which kept samples are below the threshold: their spreads, exact until EXACT_SPREADS are,
  then runs of them below the threshold so far (SPREAD_MARGIN of it; a run keeps its highest
  spread), above it (its lowest), or near it, each one exact (``_Spreads``);
- the gaps: every step over half a gap of the first blocks' period, judged at the end;
- whether the clock is bursty (``core.clock``): the time of every WINDOW-th sample.

``finish`` returns None when the log broke an assumption: its threshold came out above a bound
used earlier, its noise floor left the band (a log whose noise grows or falls over hours: a
percentile far from the one of its first hour), a run taken as below or above the threshold so
far has a spread within the tie of the end's (below), its period differs from the first blocks'
enough to change the window, its steps are too many kinds to count, its clock is bursty (the
whole read takes its period from the mean step and its gaps by its pauses), or a spread lies on
the threshold (within ``TIE``, or ``ROUNDING`` times (range / threshold)^2 where that is more: a
quantised log's spreads take a few exact values, and one can be the threshold itself; a quiet
log's spreads are summed from other stretches here than in the whole read; either way rounding
alone would say which side). The caller then reads the log whole and calls ``detect``.

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


#: What measures a Scan's blocks when it kept no readings: the samples kept (where each run of
#: them is in the log) and each block's first and last position among them.
Measure = Callable[[Kept, list[tuple[int, int]]], list[Measured]]


def log_index(run_first: IntArray, run_at: IntArray, at: IntArray | int) -> IntArray:
    """The log's index of the kept samples at positions ``at``, from where each run of them
    starts in the log (``run_first``) and among those kept (``run_at``)."""
    k = np.searchsorted(run_at, at, side="right") - 1
    index: IntArray = run_first[k] + (at - run_at[k])
    return index


class _Store:
    """Kept samples written end to end into arrays made once for as many as the log can hold
    (``capacity``: memory is only touched where written), grown if the guess was short: where
    each run of them is in the log, and their readings if ``readings``."""

    def __init__(self, capacity: int, readings: bool = True) -> None:
        self.capacity = max(1024, capacity)
        self.readings = readings
        self.axes: FloatArray | None = None
        self.floats: FloatArray | None = None
        self.ints: IntArray | None = None
        self.runs: list[tuple[int, int]] = []  # (first index, size)
        self.size = 0

    def add(self, part: ScanPart) -> None:
        n = len(part)
        if self.readings and (self.axes is None or self.floats is None or self.ints is None):
            self.axes = np.empty((3, self.capacity))
            self.floats = np.empty((self.capacity, part.floats.shape[1]))
            self.ints = np.empty((self.capacity, part.ints.shape[1]), dtype=part.ints.dtype)
        if self.readings and self.size + n > self.capacity:
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
        self.size += n

    def _grow(self, need: int) -> None:
        capacity = max(need, self.capacity * 3 // 2)
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

    def join(self, template: ScanPart) -> Kept:
        k = self.size
        first = np.array([r[0] for r in self.runs], dtype=np.int64)
        size = np.array([r[1] for r in self.runs], dtype=np.int64)
        at = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64) if size.size else size
        if self.axes is None or self.floats is None or self.ints is None:  # no readings
            return Kept(template.axes, template.floats, template.ints, first, at, size)
        return Kept(self.axes[:, :k], self.floats[:k], self.ints[:k], first, at, size)


class _Floor:
    """The spreads the noise floor is the percentile of, in a band ``lo`` .. ``hi`` about it:
    those below it counted (``under``), those in it kept, those over it let go. The band is
    everything at first, and is narrowed about the percentile so far (FLOOR_KEEP spreads each
    side of it) whenever FLOOR_SPREADS are kept: a percentile the band no longer holds is not
    known. A spread that comes many times (a quantised log's take a few values) is counted,
    not kept (``heavy``)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.lo, self.hi = -np.inf, np.inf
        self.under = 0
        self.kept = np.empty(0)  # ``taken`` spreads, as they came (made once: memory is touched where written)
        self.taken = 0
        self.heavy: dict[float, int] = {}
        self.due = size  # narrowed when this many are kept

    def add(self, spread: FloatArray, below: float, rank: int) -> None:
        """Spreads of the samples kept (those under ``below`` count); ``rank``: the percentile's
        rank so far, which a narrowed band is about."""
        if self.taken + spread.size > self.due:  # (before these are judged by the band)
            self._narrow(below, rank)
            self.due = max(self.size, 2 * self.taken)
        found = spread[spread < min(below, self.hi)]
        if self.lo > -np.inf:
            low = found < self.lo
            if low.any():
                self.under += int(np.count_nonzero(low))
                found = found[~low]
        for value in self.heavy:
            same = found == value
            if same.any():
                self.heavy[value] += int(np.count_nonzero(same))
                found = found[~same]
        n = found.size
        if self.taken + n > self.kept.size:  # (more than ``size``: a band that could not be narrowed)
            room = np.empty(max(self.taken + n, self.kept.size * 3 // 2, self.size + (1 << 18)))
            room[: self.taken] = self.kept[: self.taken]
            self.kept = room
        self.kept[self.taken : self.taken + n] = found
        self.taken += n

    def _narrow(self, below: float, rank: int) -> None:
        """The band about the spread of ``rank`` (FLOOR_KEEP each side), those under ``below``."""
        kept = self.kept[: self.taken]
        low, lo = self.smallest(rank - FLOOR_KEEP, below) if rank - FLOOR_KEEP >= self.under else (False, None)
        high, hi = self.smallest(rank + FLOOR_KEEP, below)
        if low and lo is not None and lo > self.lo:
            self.under += int(np.count_nonzero(kept < lo)) + sum(c for v, c in self.heavy.items() if v < lo)
            self.lo = lo
        if high and hi is not None and hi < self.hi:
            self.hi = hi
        inside = (kept >= self.lo) & (kept < min(below, self.hi))
        found = kept[inside]
        self.heavy = {v: c for v, c in self.heavy.items() if self.lo <= v < min(below, self.hi)}
        if found.size > self.size // 2:  # spreads that come many times: counted, not kept
            values, counts = np.unique(found, return_counts=True)
            many = counts > self.size // 64
            for v, c in zip(values[many].tolist(), counts[many].tolist(), strict=True):
                self.heavy[v] = self.heavy.get(v, 0) + c
            if many.any():
                found = found[~np.isin(found, values[many])]
        self.taken = found.size
        self.kept[: self.taken] = found

    def smallest(self, k: int, below: float) -> tuple[bool, float | None]:
        """Whether the ``k``-th smallest spread under ``below`` is known, and it (None: there
        are no more than ``k``), as ``blocks.smallest`` finds it among them all."""
        if self.lo > -np.inf and not self.lo < below:
            return False, None  # those counted under the band may be over ``below``
        at = k - self.under
        if at < 0:
            return False, None
        kept = self.kept[: self.taken]
        before = 0  # the heavy spreads below the one looked at
        for value in sorted(v for v in self.heavy if v < below):
            rank = int(np.count_nonzero(kept < value)) + before
            if at < rank:
                break
            if at < rank + self.heavy[value]:
                return True, value
            before += self.heavy[value]
        found = smallest(kept, at - before, below)
        if found is None and self.hi < below:
            return False, None  # the k-th is over the band
        return True, found


#: The noise floor's band holds up to this many spreads before it is narrowed ...
FLOOR_SPREADS = 1 << 21
#: ... to this many each side of the percentile so far.
FLOOR_KEEP = FLOOR_SPREADS // 4
#: The spreads of the samples kept are kept exact up to this many, then only those near the
#: threshold so far are (SPREAD_MARGIN of it each way): the others are below it or above.
EXACT_SPREADS = 1 << 19
#: ... and nearer still (down to MIN_MARGIN) while more than half of EXACT_SPREADS are that near.
SPREAD_MARGIN, MIN_MARGIN = 0.5, 1e-3
BELOW, EXACT, ABOVE = 0, 1, 2


class _Spreads:
    """The spread of each sample kept, by its position among them, as far as the end needs it:
    runs of positions whose spreads are all below the threshold so far (BELOW: the run's
    highest is kept), all above it (ABOVE: its lowest), or near it (EXACT: each one kept)."""

    def __init__(self) -> None:
        self.start = np.zeros(0, dtype=np.int64)  # each run's first position, its kind (BELOW,
        self.kind = np.zeros(0, dtype=np.int8)  # EXACT or ABOVE) and for BELOW its highest
        self.edge = np.zeros(0)  # spread, for ABOVE its lowest
        self.fresh: list[int] = []  # the first position of each run added since (EXACT)
        self.exact = np.empty(EXACT_SPREADS + SLICE)  # the EXACT runs' spreads, in order (made once) ...
        self.held = 0  # ... this many
        self.size = 0
        self.due = EXACT_SPREADS  # sorted when this many are exact

    def add(self, spread: FloatArray) -> None:
        n = spread.size
        if self.held + n > self.exact.size:
            grown = np.empty(max(self.held + n, self.exact.size * 3 // 2))
            grown[: self.held] = self.exact[: self.held]
            self.exact = grown
        self.exact[self.held : self.held + n] = spread
        self.fresh.append(self.size)
        self.size += n
        self.held += n

    def runs(self) -> Runs:
        """Every run, those added since too."""
        exact = self.exact[: self.held]
        if not self.fresh:
            return self.start, self.kind, self.edge, exact
        return (
            np.concatenate([self.start, np.array(self.fresh, dtype=np.int64)]),
            np.concatenate([self.kind, np.full(len(self.fresh), EXACT, dtype=np.int8)]),
            np.concatenate([self.edge, np.full(len(self.fresh), np.nan)]),
            exact,
        )

    def sort(self, low: float, high: float) -> None:
        """The exact spreads under ``low`` made BELOW, those ``high`` or over ABOVE."""
        self.start, self.kind, self.edge, exact = _sort(self.runs(), self.size, low, high, self.exact)
        self.fresh, self.held = [], exact.size


#: Runs of positions: each one's first, kind and edge, and the EXACT ones' spreads (_Spreads).
Runs = tuple[IntArray, NDArray[np.int8], FloatArray, FloatArray]
#: _sort takes the exact spreads this many at a time (what it makes for each stays small).
SLICE = 1 << 16


def _sort(runs: Runs, size: int, low: float, high: float, out: FloatArray | None = None) -> Runs:
    """``runs`` (up to position ``size``) with their exact spreads under ``low`` made BELOW and
    those ``high`` or over ABOVE; runs that meet, of a kind, are one. The spreads still exact
    are written to the start of ``out`` if given (the array ``runs``'s are in: each after it is read)."""
    start, kind, edge, exact = runs
    if not start.size:
        return runs
    inside = kind == EXACT
    lengths = np.diff(np.append(start, size))[inside]
    offset = np.cumsum(lengths) - lengths  # each EXACT run's first spread in ``exact``
    firsts = start[inside]
    starts, kinds, edges, kept = [start[~inside]], [kind[~inside]], [edge[~inside]], []
    written = 0
    for a in range(0, exact.size, SLICE):
        values = exact[a : a + SLICE]
        b = a + values.size
        r0, r1 = np.searchsorted(offset, [a, b - 1], side="right") - 1  # the runs the slice is in
        ends = np.minimum(offset[r0 : r1 + 1] + lengths[r0 : r1 + 1], b)
        run = np.repeat(np.arange(r0, r1 + 1), np.maximum(ends - np.maximum(offset[r0 : r1 + 1], a), 0))
        at = firsts[run] + (np.arange(a, b) - offset[run])  # each spread's position
        sort = np.full(values.size, EXACT, dtype=np.int8)
        sort[values < low] = BELOW
        sort[values >= high] = ABOVE
        first = np.flatnonzero(np.concatenate([[True], (sort[1:] != sort[:-1]) | (at[1:] != at[:-1] + 1)]))
        starts.append(at[first])
        kinds.append(sort[first])
        edges.append(_edges(values, first, sort[first]))
        near = values[sort == EXACT]
        if out is None:
            kept.append(near)
        else:
            out[written : written + near.size] = near
            written += near.size
    start, kind, edge = np.concatenate(starts), np.concatenate(kinds), np.concatenate(edges)
    order = np.argsort(start, kind="stable")
    start, kind, edge = start[order], kind[order], edge[order]
    first = np.flatnonzero(np.concatenate([[True], kind[1:] != kind[:-1]]))
    exact = np.concatenate([np.zeros(0), *kept]) if out is None else out[:written]
    return start[first], kind[first], _edges(edge, first, kind[first]), exact


def _edges(values: FloatArray, first: IntArray, kind: NDArray[np.int8]) -> FloatArray:
    """Of each run of ``values`` (from each of ``first``), the highest for BELOW, the lowest for
    ABOVE, NaN for EXACT."""
    if not first.size:
        return np.zeros(0)
    found = np.where(kind == BELOW, np.fmax.reduceat(values, first), np.fmin.reduceat(values, first))
    found[kind == EXACT] = np.nan
    return found


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
        ``readings``: keep the still samples' readings (and what goes with them), not only
        where they are; without them ``finish`` is given what measures the blocks."""
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
        self.spreads = _Spreads()  # the kept samples' spreads, as far as the end needs them
        self.floor = _Floor(FLOOR_SPREADS) if settings.threshold is None else None
        self.margin = SPREAD_MARGIN  # how near the threshold so far a spread is kept exact (relative)
        self.estimate: float | None = None  # the noise floor so far, when last known
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
        known, floor = self._floor(_rank(decided))
        if known and floor is not None:
            self.estimate = floor
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
                self.store.add(piece)
                spread = self.held_spread[at : at + len(piece)]
                self.spreads.add(spread)
                if self.floor is not None:
                    self.floor.add(spread, self.least_bound, _rank(self.finalized))
                at += len(piece)
        if self.spreads.held > self.spreads.due:
            self._sort_spreads()
        self.before = self.held_candidate[max(0, ready - self.pad) : ready]
        rest = _between(held, first + ready, first + size)
        self.held = [ScanPart(p.first, p.axes.copy(), p.floats.copy(), p.ints.copy()) for p in rest]  # not the block
        self.held_spread = self.held_spread[ready:].copy()
        self.held_candidate = self.held_candidate[ready:].copy()

    def _floor(self, rank: int) -> tuple[bool, float | None]:
        """Whether the ``rank``-th smallest spread under the lowest bound is known, and it."""
        if self.floor is None:
            return False, None
        return self.floor.smallest(rank, self.least_bound)

    def _threshold(self, floor: float) -> float:
        """The threshold a noise floor gives, by the readings' range so far (``finish``'s rule)."""
        scale = float((self.hi - self.lo).max()) or 1.0
        return FLOOR_FACTOR * floor if floor > 1e-9 * scale else 1e-6 * scale

    def _sort_spreads(self) -> None:
        """Keep exact only the spreads near the threshold so far (``margin`` of it each way):
        below or above it the others (each bound checked at the end); nearer while more than
        half of EXACT_SPREADS are that near."""
        threshold = self.settings.threshold
        if threshold is None and self.estimate is not None:
            threshold = self._threshold(self.estimate)
        spreads = self.spreads
        if threshold is None or not threshold > 0:
            spreads.due = 2 * spreads.held
            return
        span = float((self.hi - self.lo).max())
        tie = min(1.0, max(TIE, ROUNDING * (span / threshold) ** 2))  # finish's, by the range so far
        while True:
            margin = max(self.margin, 2 * tie)
            spreads.sort(threshold * max(0.1, 1 - margin), min(self.least_bound, threshold * (1 + margin)))
            if spreads.held <= EXACT_SPREADS // 2 or self.margin <= MIN_MARGIN:
                break
            self.margin = max(MIN_MARGIN, self.margin / 4)
        spreads.due = max(EXACT_SPREADS, 2 * spreads.held)

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
            _, floor = self._floor(_rank(self.n))
            if floor is None:
                return None  # (or not known: the band about the floor so far no longer holds it)
            scale = span or 1.0
            # quantised readings of a quiet sensor can have no spread at all: still is then "exactly level"
            threshold = FLOOR_FACTOR * floor if floor > 1e-9 * scale else 1e-6 * scale
        ratio = span / threshold if threshold > 0 else np.inf
        tie = max(TIE, ROUNDING * ratio * ratio) if ratio < 1e100 else np.inf  # (--threshold 0: no tie holds)
        if not threshold * (1 + tie) <= self.least_bound:
            return None  # a spread on the threshold could have been let go
        still = self._still(threshold, tie)
        if still is None:
            return None  # a spread on the threshold (a quantised log's, a quiet one's): either side by rounding
        kept = self.store.join(self.template)
        breaks = self._gaps(period)
        spans = self._spans(kept, breaks, *still)
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

    def _still(self, threshold: float, tie: float) -> tuple[IntArray, IntArray] | None:
        """The runs (first, last: positions) of kept samples whose spread is below ``threshold``;
        None if one lies on it (within ``tie``), or may: one taken as below or above the
        threshold so far (``_sort_spreads``) by a bound that is not outside this tie."""
        spreads = self.spreads
        runs = spreads.runs()
        _, kind, edge, exact = runs
        on = exact >= threshold * (1 - tie)
        on &= exact <= threshold * (1 + tie)
        if on.any():
            return None
        if not (edge[kind == BELOW] < threshold * (1 - tie)).all():
            return None
        if not (edge[kind == ABOVE] > threshold * (1 + tie)).all():
            return None
        start, kind, _, _ = _sort(runs, spreads.size, threshold, threshold)  # every one below it or not
        below = np.flatnonzero(kind == BELOW)
        last = np.append(start[1:], spreads.size) - 1
        return start[below], last[below]

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

    def _spans(self, kept: Kept, breaks: IntArray, starts: IntArray, ends: IntArray) -> list[tuple[int, int]] | None:
        """``detect``'s spans, as positions among the kept samples, from the runs of them below
        the threshold (``starts``, ``ends``: positions); None if one reaches past what was kept
        (it cannot, by the pad: a check)."""
        split = [kept.run_at[1:]]  # samples not kept between two runs: never still
        for g in breaks.tolist():  # a gap between two kept samples of one run
            at = kept.position(g)
            if at is not None and at > 0 and kept.position(g - 1) == at - 1:
                split.append(np.array([at]))
        starts, ends = _split(starts, ends, np.unique(np.concatenate(split)).astype(np.int64))
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


def _split(starts: IntArray, ends: IntArray, breaks: IntArray) -> tuple[IntArray, IntArray]:
    """Runs (first, last) split before each of ``breaks`` inside one (``true_runs``'s rule)."""
    if not starts.size or not breaks.size:
        return starts.astype(np.int64), ends.astype(np.int64)
    k = np.searchsorted(starts, breaks, side="right") - 1
    inside = k >= 0
    inside[inside] = (breaks[inside] > starts[k[inside]]) & (breaks[inside] <= ends[k[inside]])
    cut = breaks[inside]
    return np.sort(np.concatenate([starts, cut])).astype(np.int64), np.sort(np.concatenate([ends, cut - 1])).astype(
        np.int64
    )


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
