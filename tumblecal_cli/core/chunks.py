"""A long log's readings as sums over chunks of consecutive readings (numpy only).

``core.scan`` finds a log's still blocks as it streams past, but where each block begins and
ends is only known at the end of the log, when its threshold is. Rather than keep every
reading until then (24 bytes each, 52 with its time, row and line), the caller keeps the
count, sum and co-moment (each axis's sum of squares about its own chunk's mean) of each CHUNK
readings in turn: a block's mean, standard deviation and drift (the mean of its last third
less its first's) are then merged from the chunks it covers whole (Chan, Golub and LeVeque's
pairwise update, as stable as the two-pass formula) and from the ``moments`` of the parts of
the few chunks it cuts (``wanted``), which the caller reads again.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.core.blocks import Measured, thirds
from tumblecal_cli.core.model import PoseStats

#: Readings summed together: a block cuts two chunks and its thirds two more, read again (a
#: thousand blocks read 1M readings again); the table holds 56 bytes a chunk (the caller's
#: place of each in the file, 24 more).
CHUNK = 256
#: A span covering up to this many whole chunks between its cuts is merged with the others at once
#: (longer ones one by one: few, as a log holds few of them).
SHORT = 64

#: A count of readings, their sum (3,) and co-moment (3,: each axis's squares about their mean).
Moments = tuple[int, FloatArray, FloatArray]
#: Part of a chunk: the chunk, and the first and last of its readings (positions in it).
Part = tuple[int, int, int]


def chunk_sums(values: FloatArray, size: int = CHUNK) -> tuple[IntArray, FloatArray, FloatArray]:
    """The count (k,), sum (k, 3) and co-moment (k, 3: each axis's squares about the chunk's
    own mean) of each ``size`` consecutive readings of ``values`` (n, 3), the last chunk shorter."""
    n = len(values)
    whole = n // size
    counts = np.full(whole + (n > whole * size), size, dtype=np.int64)
    sums = np.empty((counts.size, 3))
    m2 = np.empty((counts.size, 3))
    if whole:
        body = values[: whole * size].reshape(whole, size, 3)
        sums[:whole] = body.sum(axis=1)
        m2[:whole] = np.square(body - (sums[:whole] / size)[:, None, :]).sum(axis=1)
    if n > whole * size:
        rest = values[whole * size :]
        counts[-1] = len(rest)
        sums[-1] = rest.sum(axis=0)
        m2[-1] = np.square(rest - sums[-1] / len(rest)).sum(axis=0)
    return counts, sums, m2


class Chunks:
    """The chunks of a log, in order (``add``), then what a span of it holds (``measure``)."""

    def __init__(self) -> None:
        self._parts: list[tuple[int, IntArray, FloatArray, FloatArray]] = []
        self.start = np.zeros(0, dtype=np.int64)  # after done(): each chunk's first reading (its index in the log)
        self.counts = np.zeros(0, dtype=np.int64)
        self.sums = np.zeros((0, 3))
        self.m2 = np.zeros((0, 3))

    def add(self, first: int, counts: IntArray, sums: FloatArray, m2: FloatArray) -> None:
        """Consecutive chunks, the first beginning at the log's reading ``first``."""
        self._parts.append((first, counts, sums, m2))

    def done(self) -> None:
        if not self._parts:
            return
        starts = [first + np.concatenate([[0], np.cumsum(c)[:-1]]) for first, c, _, _ in self._parts]
        self.start = np.concatenate(starts).astype(np.int64)
        self.counts = np.concatenate([c for _, c, _, _ in self._parts])
        self.sums = np.concatenate([s for _, _, s, _ in self._parts])
        self.m2 = np.concatenate([m for _, _, _, m in self._parts])
        self._parts = []

    def of(self, index: IntArray | int) -> IntArray:
        """The chunk that holds the log's reading ``index``."""
        found: IntArray = np.searchsorted(self.start, index, side="right") - 1
        return found

    @staticmethod
    def thirds(spans: Sequence[tuple[int, int]]) -> list[tuple[int, int]]:
        """Each span, its first third and its last third (``segment.thirds``), in turn."""
        return [r for a, b in spans for r in ((a, b), *thirds(a, b))]

    def _cuts(self, a: int, b: int) -> list[Part]:
        """The parts of chunks the log's readings ``a``..``b`` begin and end in: one, or the
        first chunk's from ``a`` and the last one's up to ``b`` (the chunks between are whole)."""
        ca, cb = int(self.of(a)), int(self.of(b))
        first = int(self.start[ca])
        if ca == cb:
            return [(ca, a - first, b - first)]
        return [(ca, a - first, int(self.counts[ca]) - 1), (cb, 0, b - int(self.start[cb]))]

    def wanted(self, spans: Sequence[tuple[int, int]]) -> dict[int, list[tuple[int, int]]]:
        """What ``measure`` needs of the readings, by chunk: the parts (first, last: positions in
        the chunk) where a span or one of its thirds begins or ends."""
        found: dict[int, list[tuple[int, int]]] = {}
        for c, lo, hi in self.plan(spans).parts.tolist():
            found.setdefault(c, []).append((lo, hi))
        return found

    def plan(self, spans: Sequence[tuple[int, int]]) -> Cuts:
        """The parts of chunks each span and its thirds begin and end in (``_cuts``, every range
        at once), each part once."""
        ranges = np.array(self.thirds(spans), dtype=np.int64).reshape(-1, 2)
        a, b = ranges[:, 0], ranges[:, 1]
        ca, cb = self.of(a), self.of(b)
        one = ca == cb
        first = np.column_stack([ca, a - self.start[ca], np.where(one, b - self.start[ca], self.counts[ca] - 1)])
        two = np.flatnonzero(~one)
        last = np.column_stack([cb[two], np.zeros(two.size, dtype=np.int64), b[two] - self.start[cb[two]]])
        parts, which = np.unique(np.concatenate([first, last]).reshape(-1, 3), axis=0, return_inverse=True)
        which = which.reshape(-1)
        return Cuts(ca, cb, parts, which[: len(a)], which[len(a) :], two)

    def measure(self, spans: Sequence[tuple[int, int]], parts: Mapping[Part, Moments]) -> list[Measured]:
        """Each span's (the log's readings ``a``..``b``) statistics and drift, from the chunks and
        ``parts``: the ``moments`` of each part ``wanted`` named."""
        plan = self.plan(spans)
        found = [parts[(c, lo, hi)] for c, lo, hi in plan.parts.tolist()]
        return self.measured(
            plan,
            np.array([p[0] for p in found], dtype=np.int64),
            np.array([p[1] for p in found], dtype=np.float64).reshape(-1, 3),
            np.array([p[2] for p in found], dtype=np.float64).reshape(-1, 3),
        )

    def measured(self, plan: Cuts, count: IntArray, total: FloatArray, m2: FloatArray) -> list[Measured]:
        """Each span's statistics and drift from the count, sum and co-moment of each of
        ``plan.parts`` and the chunks between them: every span at once, with the arithmetic of
        merging one span's parts (``_merged``) in the same order, so the same digits."""
        if not plan.first.size:
            return []
        last = count[plan.last], total[plan.last], m2[plan.last]
        count, total, m2 = count[plan.first], total[plan.first], m2[plan.first]
        two = plan.two
        if two.size:
            inner = self._inner(plan.ca[two] + 1, plan.cb[two])
            count[two], total[two], m2[two] = _merged((count[two], total[two], m2[two]), inner, last)
        n = count[0::3]
        mean = total[0::3] / n[:, None]
        many = n > 1
        std = np.zeros_like(mean)
        std[many] = np.sqrt(np.maximum(m2[0::3][many], 0.0) / (n[many] - 1)[:, None])
        drift = total[2::3] / count[2::3, None] - total[1::3] / count[1::3, None]
        return [Measured(PoseStats(mean[k], std[k], int(n[k])), drift[k]) for k in range(len(n))]

    def _inner(self, lo: IntArray, hi: IntArray) -> tuple[IntArray, FloatArray, FloatArray]:
        """The chunks ``lo`` .. ``hi - 1`` of each range merged (count 0 where there are none):
        each sum taken down the chunks in order, as numpy sums them along the first axis."""
        length = hi - lo
        k = len(lo)
        count = np.zeros(k, dtype=np.int64)
        total, m2 = np.zeros((k, 3)), np.zeros((k, 3))
        short = np.flatnonzero((length > 0) & (length <= SHORT))
        if short.size:
            width = int(length[short].max())
            at = np.minimum(lo[short, None] + np.arange(width), len(self.counts) - 1)  # (m, width)
            last = length[short] - 1
            rows = np.arange(short.size)
            counts = self.counts[at]
            n = np.cumsum(counts, axis=1)[rows, last]
            sums = self.sums[at]
            summed = np.cumsum(sums, axis=1)[rows, last]
            means = sums / counts[:, :, None]
            spread = counts[:, :, None] * np.square(means - (summed / n[:, None])[:, None, :])
            own = np.cumsum(self.m2[at], axis=1)[rows, last]
            count[short], total[short] = n, summed
            m2[short] = own + np.cumsum(spread, axis=1)[rows, last]
        for j in np.flatnonzero(length > SHORT):  # a long block: its chunks summed as one
            inner = slice(int(lo[j]), int(hi[j]))
            counts_j = self.counts[inner]
            n_j = int(counts_j.sum())
            total_j = self.sums[inner].sum(axis=0)
            means_j = self.sums[inner] / counts_j[:, None]
            m2[j] = self.m2[inner].sum(axis=0) + (counts_j[:, None] * np.square(means_j - total_j / n_j)).sum(axis=0)
            count[j], total[j] = n_j, total_j
        return count, total, m2


def moments(values: FloatArray) -> Moments:
    """The count, sum and co-moment (each axis's squares about the mean) of readings (n, 3)."""
    n = len(values)
    total = values.sum(axis=0)
    return n, total, np.square(values - total / n).sum(axis=0)


@dataclass(frozen=True)
class Cuts:
    """Where each range (a span, its first third, its last third, in turn) begins and ends: its
    first chunk ``ca`` and last ``cb``; the parts of chunks the ranges cut (chunk, first, last:
    positions in the chunk), each once; each range's ``first`` part (its only one when it lies
    in one chunk) and, for the ranges ``two`` that span chunks, their ``last`` part."""

    ca: IntArray
    cb: IntArray
    parts: IntArray
    first: IntArray
    last: IntArray
    two: IntArray


def _merged(
    first: tuple[IntArray, FloatArray, FloatArray],
    inner: tuple[IntArray, FloatArray, FloatArray],
    last: tuple[IntArray, FloatArray, FloatArray],
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Each range's first part, its inner chunks (where it has any: a count above 0) and its last
    part merged as one, every range at once: the sums in order (first, inner, last), each
    co-moment about its own mean moved to the merged one (Chan, Golub and LeVeque)."""
    n = first[0] + inner[0] + last[0]
    some = inner[0] > 0
    total = first[1] + np.where(some[:, None], inner[1], 0.0)
    total = np.where(some[:, None], total, first[1]) + last[1]
    mean = total / n[:, None]

    def term(p: tuple[IntArray, FloatArray, FloatArray]) -> FloatArray:
        c = np.maximum(p[0], 1)[:, None]
        found: FloatArray = p[2] + c * np.square(p[1] / c - mean)
        return found

    m2 = term(first) + np.where(some[:, None], term(inner), 0.0)
    m2 = np.where(some[:, None], m2, term(first)) + term(last)
    return n, total, np.asarray(m2, dtype=np.float64)
