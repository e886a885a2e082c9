"""Where a gyroscope is still: the still blocks an accelerometer (or a label column) gives, cut
down to the samples the gyroscope itself sees at rest. numpy only.

A hand starts and stops a turn smoothly (the rate rises and falls as ``sin²``): its first and
last tenths of a second turn the unit by hundredths of a degree, which the accelerometer cannot
tell from its noise, while the gyroscope reads degrees per second there. Left in a still block
they move its mean, the gyroscope's bias, by many times its standard error (docs/gyroscopes.md, "A gyroscope
from hand turns").

Each block's ends are cut until the gyroscope there reads its level within its own noise at
every scale: the mean of the first (last) ``m`` samples, for ``m`` = 4, 8, ... up to the window,
is within ``MEAN_SIGMAS`` standard errors of an ``m``-sample mean of the block's level. The
standard error of an ``m``-sample mean is measured, not assumed: from the differences of
adjacent ``m``-sample means in the blocks (an Allan deviation, robust to the few that straddle
motion), so noise correlated from sample to sample (a sensor's low-pass filter) widens it as it
should. A block whose cut part is shorter than ``min_samples``, or whose spread is more than
``SPREAD_FACTOR`` times the gyroscope's noise at rest, is not still for the gyroscope.

The bias is the mean of the cut blocks; its standard error is the larger of that of batch
means (each block cut into windows, the windows' means about their block's mean: ``σ/√N`` for
white noise, more for correlated noise) and that of the blocks' own scatter (a rate that
differs from one orientation to the next, as a gyroscope's g-sensitivity makes it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray

#: An end of a block is moving while the mean of its first m samples is further than this many
#: standard errors (of an m-sample mean at rest) from the block's level, on any axis, at any m.
MEAN_SIGMAS = 5.0
#: A block whose gyroscope spreads more than this many times its noise at rest (1-sigma, on
#: any axis) moved during it.
SPREAD_FACTOR = 2.0
#: An end found moving loses this much of a window more: the turn's last samples, whose rate
#: is below the noise, still turn the unit.
MARGIN = 0.1
#: The shortest mean an end is judged by (fewer samples: a single outlier decides).
SHORTEST = 4
#: The most pairs of means (and samples of a block's middle), and the most blocks, the noise is
#: measured from: more cost time and tell nothing new.
PAIRS = 4096
BLOCKS = 256
#: 1.4826: the median absolute deviation of a normal variable over its standard deviation.
MAD_TO_SIGMA = 1.482602218505602
SHORT, MOVED = "the gyroscope never rests long enough in it", "the gyroscope spreads more than its noise in it"


@dataclass(frozen=True)
class Still:
    """What the gyroscope says of the blocks it was given, in their order: each one's part with
    its moving ends cut (``first``, ``last`` inclusive; None when nothing long enough is left),
    and whether it is still for the gyroscope (``why`` not: ``SHORT``, ``MOVED``; None: it is);
    its noise at rest per sample (1-sigma per axis); how many samples each end lost."""

    parts: list[tuple[int, int] | None]
    why: list[str | None]
    noise: FloatArray  # (3,)
    cut: list[tuple[int, int]]  # samples cut from the start and from the end of each block

    @property
    def spans(self) -> list[tuple[int, int] | None]:
        """Each block's still part, None for those that are not still for the gyroscope."""
        return [None if why else part for part, why in zip(self.parts, self.why, strict=True)]


def scales(window: int) -> list[int]:
    """The lengths the ends are judged at: 4, 8, 16, ... and the window itself."""
    out, m = [], SHORTEST
    while m < window:
        out.append(m)
        m *= 2
    return [*out, max(window, 1)]


def mean_noise(gyr: FloatArray, spans: Sequence[tuple[int, int]], m: int) -> FloatArray | None:
    """The standard error of an ``m``-sample mean at rest (per axis): adjacent ``m``-sample means
    differ by ``√2`` of it; their median absolute difference (robust to the few pairs that
    straddle motion) over the blocks, taken across the log until there are ``PAIRS``. None with
    fewer than 8 pairs."""
    diffs, count = [], 0
    for i in _spread_order(len(spans)):
        a, b = spans[i]
        k = min((b - a + 1) // m, PAIRS + 1)
        if k >= 2:
            means = gyr[a : a + k * m].reshape(k, m, 3).mean(axis=1)
            diffs.append(np.diff(means, axis=0))
            count += k - 1
            if count >= PAIRS:
                break
    if not diffs or sum(len(d) for d in diffs) < 8:
        return None
    d = np.abs(np.concatenate(diffs))
    out: FloatArray = MAD_TO_SIGMA * np.median(d, axis=0) / np.sqrt(2.0)
    return out


def _spread_order(n: int) -> list[int]:
    """0 .. n-1 in an order that samples the whole range early: 0, n/2, n/4, 3n/4, ..."""
    order, seen, step = [], set(), 1 << max(0, (n - 1).bit_length())
    while step >= 1:
        for i in range(0, n, step):
            if i not in seen:
                seen.add(i)
                order.append(i)
        step //= 2
    return order


def _middle(block: FloatArray) -> FloatArray:
    """The middle half of a block, at most ``PAIRS`` samples of it (its ends may hold a turn's
    slow start or stop)."""
    n = len(block)
    half = min(n - 2 * (n // 4), PAIRS)
    start = (n - half) // 2
    return block[start : start + half]


def rest_noise(gyr: FloatArray, spans: Sequence[tuple[int, int]]) -> FloatArray:
    """The gyroscope's noise per sample at rest (1-sigma per axis): the median over the blocks (up
    to ``BLOCKS`` of them across the log) of the spread of each one's middle (:func:`_middle`),
    and no less than the rounding of its readings (the smallest step between them over √12)."""
    middles = [_middle(gyr[spans[i][0] : spans[i][1] + 1]) for i in _spread_order(len(spans))[:BLOCKS]]
    spread = np.array([m.std(axis=0) if len(m) > 1 else np.zeros(3) for m in middles])
    steps = np.abs(np.diff(np.concatenate(middles), axis=0))
    steps = np.where(steps > 0, steps, np.inf)
    step = steps.min(axis=0) if len(steps) else np.full(3, np.inf)
    rounding = np.where(np.isfinite(step), step / np.sqrt(12.0), 0.0)
    out: FloatArray = np.maximum(np.median(spread, axis=0), rounding)
    return out


def _first_still(block: FloatArray, level: FloatArray, bounds: list[tuple[int, FloatArray]]) -> int:
    """How many samples at the start of ``block`` (n, 3) move: the first ``e`` from which every
    mean of ``m`` samples (``bounds``: m and its bound per axis) is within its bound of ``level``.
    Looked for in the first few windows, then in four times as many, and so on: a long block is
    not read whole for an end that moved for a tenth of a second."""
    n, longest = len(block), max(m for m, _ in bounds)
    head = np.cumsum(block[:longest] - level, axis=0)
    if all(m > n or (np.abs(head[m - 1] / m) <= bound).all() for m, bound in bounds):
        return 0  # an end at rest, the usual case: its first means alone
    reach = 4 * longest
    while True:
        upto = min(n, reach + longest - 1)
        starts = n if upto == n else reach  # the starts whose every mean lies within ``upto``
        sums = np.concatenate([np.zeros((1, 3)), np.cumsum(block[:upto] - level, axis=0)])
        moving = np.zeros(starts, dtype=bool)
        for m, bound in bounds:
            if m <= upto:
                means = (sums[m:] - sums[:-m]) / m  # the mean of m samples from each start
                reached = min(starts, len(means))
                moving[:reached] |= (np.abs(means[:reached]) > bound).any(axis=1)
        still = np.flatnonzero(~moving)
        if still.size:
            return int(still[0])
        if upto == n:
            return n
        reach *= 4


def _cut(block: FloatArray, bounds: list[tuple[int, FloatArray]], margin: int) -> tuple[int, int]:
    """Samples to cut from each end of ``block``: the level from the median, then from the mean
    of what is left once (a level pulled by the moving ends is then put right); an end found
    moving loses ``margin`` samples more (the last of a slowing turn, below the noise)."""
    level = np.median(_middle(block), axis=0)
    head = tail = 0
    for _ in range(2):
        head = _first_still(block, level, bounds)
        tail = _first_still(block[::-1], level, bounds)
        head, tail = (x + margin if x else 0 for x in (head, tail))
        if head + tail >= len(block):  # nothing left
            head = min(head, len(block))
            return head, len(block) - head
        level = block[head : len(block) - tail].mean(axis=0)
    return head, tail


def still(gyr: FloatArray, spans: Sequence[tuple[int, int]], window: int, min_samples: int) -> Still:
    """The part of each block (``spans``: first, last inclusive, into ``gyr`` (n, 3)) where the
    gyroscope is still: its moving ends cut (see the module), then judged by length and spread."""
    spans = [(int(a), int(b)) for a, b in spans]
    if not spans:
        return Still([], [], np.zeros(3), [])
    noise = rest_noise(gyr, spans)
    bounds = []
    for m in scales(window):
        measured = mean_noise(gyr, spans, m)
        white = noise / np.sqrt(m)
        bounds.append((m, MEAN_SIGMAS * (white if measured is None else np.maximum(measured, white))))
    margin = round(MARGIN * window)
    cuts = [_cut(gyr[a : b + 1], bounds, margin) for a, b in spans]
    parts = [(a + head, b - tail) for (a, b), (head, tail) in zip(spans, cuts, strict=True)]
    long_enough = [p for p in parts if p[1] - p[0] + 1 >= max(min_samples, 2)]
    if long_enough:  # the noise at rest from the parts that are
        noise = np.median(np.array([gyr[a : b + 1].std(axis=0) for a, b in long_enough]), axis=0)
    out: list[tuple[int, int] | None] = []
    why: list[str | None] = []
    for a, b in parts:
        reason = None
        if b - a + 1 < max(min_samples, 2):
            reason = SHORT
        elif (gyr[a : b + 1].std(axis=0) > SPREAD_FACTOR * noise).any():
            reason = MOVED
        out.append(None if reason == SHORT else (a, b))
        why.append(reason)
    return Still(out, why, noise, cuts)


def bias(gyr: FloatArray, spans: Sequence[tuple[int, int]], batch: int) -> tuple[FloatArray, FloatArray]:
    """The mean of the gyroscope over the still ``spans`` and its standard error, per axis the
    larger of two:

    - batch means: each span in ``batch``-sample batches, the variance of their means about their
      span's mean (pooled) times ``batch / N``: ``σ/√N`` for white noise, and no less when the
      noise is correlated from sample to sample (with fewer than two batches' worth of freedom,
      ``σ/√N``, σ about each span's mean);
    - the blocks' own scatter (``√(K/(K-1) Σ n_k² (m_k - m)²) / N`` over K blocks of n_k samples
      and mean m_k): what differs from block to block (a rate that depends on the orientation, a
      gyroscope's g-sensitivity; a drift) moves the mean of blocks held in a few orientations,
      and the noise within each block alone does not say so."""
    spans = [(int(a), int(b)) for a, b in spans]
    if not spans:
        return np.zeros(3), np.zeros(3)
    samples = np.concatenate([gyr[a : b + 1] for a, b in spans])
    total = len(samples)
    mean: FloatArray = samples.mean(axis=0)
    squares, dof = np.zeros(3), 0
    for a, b in spans:
        k = (b - a + 1) // max(batch, 1)
        if k >= 2:
            means = gyr[a : a + k * batch].reshape(k, batch, 3).mean(axis=1)
            squares += ((means - means.mean(axis=0)) ** 2).sum(axis=0)
            dof += k - 1
    if dof >= 2:
        se = np.sqrt(squares / dof * batch / total)
    else:
        deviations = np.concatenate([gyr[a : b + 1] - gyr[a : b + 1].mean(axis=0) for a, b in spans])
        se = np.sqrt((deviations**2).sum(axis=0) / max(total - len(spans), 1) / total)
    if len(spans) >= 2:
        counts = np.array([b - a + 1 for a, b in spans], dtype=np.float64)[:, None]
        block_means = np.array([gyr[a : b + 1].mean(axis=0) for a, b in spans])
        spread = len(spans) / (len(spans) - 1) * ((counts * (block_means - mean)) ** 2).sum(axis=0)
        se = np.maximum(se, np.sqrt(spread) / total)
    out: FloatArray = np.asarray(se, dtype=np.float64)
    return mean, out
