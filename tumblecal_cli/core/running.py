"""A long pose's readings as running sums: the statistics every check of a still pose needs,
gathered block by block as the capture is read, so that a pose of any length is judged in
memory that does not grow with it. numpy only.

A :class:`Summary` keeps, for each block of readings read (io.csv.posefile: some 30,000 rows each),
its count, sum, mean and co-moment, lowest and highest value, largest row peak and whether
every value is a whole number; the blocks' means and co-moments (each about its own block's
mean) are merged by the pairwise update formula, as stable as the two-pass formula. The readings
themselves are kept where reading a few of them again costs no memory (an array mapped from
a file on disk): a check that needs some rows (the first and last thirds' means cut inside a
block, the rows at a clip level) reads those blocks alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tumblecal_cli.core.arrays import FloatArray


@dataclass
class Summary:
    """Running sums of a pose's readings, block by block; ``values`` the readings themselves
    (an (n, 3) array, mapped from disk), read again only where a block must be."""

    values: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    ends: list[int] = field(default_factory=list)  # the count of readings up to each block's end
    sums: list[FloatArray] = field(default_factory=list)
    lows: list[float] = field(default_factory=list)
    highs: list[float] = field(default_factory=list)
    peaks: list[float] = field(default_factory=list)  # each block's largest |value|
    whole: bool = True  # every value a whole number
    count: int = 0
    mean: FloatArray = field(default_factory=lambda: np.zeros(3))
    comoment: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))

    def add(self, block: FloatArray) -> None:
        """One block of readings (k, 3), finite, in the order read."""
        k = len(block)
        if not k:
            return
        columns = np.ascontiguousarray(block.T)  # (3, k): numpy sums a row of these far faster
        moment = np.empty((3, 3))  # (products summed by numpy, not BLAS: slow on 3 rows when threads are busy)
        n = self.count + k
        with np.errstate(over="ignore", invalid="ignore"):  # readings near 1e308: in_range refuses them
            total = columns.sum(axis=1)
            mean = total / k
            centred = columns - mean[:, None]
            for i in range(3):
                for j in range(i, 3):
                    moment[i, j] = moment[j, i] = (centred[i] * centred[j]).sum()
            delta = mean - self.mean
            self.mean = self.mean + delta * (k / n)
            self.comoment = self.comoment + moment + np.outer(delta, delta) * (self.count * k / n)
        self.count = n
        self.ends.append(n)
        self.sums.append(total)
        low, high = float(columns.min()), float(columns.max())
        self.lows.append(low)
        self.highs.append(high)
        self.peaks.append(max(-low, high))
        if self.whole:
            self.whole = bool(np.array_equal(columns, np.round(columns)))

    @property
    def std(self) -> FloatArray:
        """Each axis's sample standard deviation (ddof=1; 0 for one reading)."""
        if self.count < 2:
            return np.zeros(3)
        return np.sqrt(np.clip(np.diag(self.comoment), 0.0, None) / (self.count - 1))

    @property
    def low(self) -> float:
        return min(self.lows) if self.lows else 0.0

    @property
    def high(self) -> float:
        return max(self.highs) if self.highs else 0.0

    @property
    def largest(self) -> float:
        """The largest |reading|."""
        return max(self.peaks) if self.peaks else 0.0

    def block(self, i: int) -> FloatArray:
        """The readings of block ``i``, read again."""
        start = self.ends[i - 1] if i else 0
        return np.asarray(self.values[start : self.ends[i]], dtype=np.float64)

    def head_sum(self, rows: int) -> FloatArray:
        """The sum of the first ``rows`` readings: whole blocks' sums, and the rows of the block
        the count ends in read again."""
        whole = int(np.searchsorted(self.ends, rows, side="right"))
        start = self.ends[whole - 1] if whole else 0
        total = np.sum(self.sums[:whole], axis=0) if whole else np.zeros(3)
        if rows > start:
            total = total + np.ascontiguousarray(self.block(whole)[: rows - start].T).sum(axis=1)
        return np.asarray(total, dtype=np.float64)

    def drift(self) -> FloatArray:
        """The mean of the last third of the readings less that of the first (0 under three)."""
        third = self.count // 3
        if not third:
            return np.zeros(3)
        everything = np.sum(self.sums, axis=0)
        last = everything - self.head_sum(self.count - third)
        return np.asarray(last / third - self.head_sum(third) / third, dtype=np.float64)

    def at_level(self, low: float, high: float) -> int:
        """Readings with a value at or below ``low`` or at or above ``high`` (the blocks that
        reach either read again)."""
        clipped = 0
        for i, (lo, hi) in enumerate(zip(self.lows, self.highs, strict=True)):
            if lo <= low or hi >= high:
                c = self.block(i)
                clipped += int(((c <= low) | (c >= high)).any(axis=1).sum())
        return clipped
