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

import numpy as np

from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.core.blocks import Measured, thirds
from tumblecal_cli.core.model import PoseStats

#: Readings summed together: a block cuts two chunks and its thirds two more, read again (a
#: thousand blocks read 1M readings again); the table holds 56 bytes a chunk (the caller's
#: place of each in the file, 24 more).
CHUNK = 256

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
        for a, b in self.thirds(spans):
            for c, lo, hi in self._cuts(a, b):
                found.setdefault(c, []).append((lo, hi))
        return found

    def measure(self, spans: Sequence[tuple[int, int]], parts: Mapping[Part, Moments]) -> list[Measured]:
        """Each span's (the log's readings ``a``..``b``) statistics and drift, from the chunks and
        ``parts``: the ``moments`` of each part ``wanted`` named."""
        ranges = self.thirds(spans)
        found = []
        for k in range(0, len(ranges), 3):
            count, total, m2 = self._part(*ranges[k], parts)
            mean = total / count
            std = np.sqrt(np.maximum(m2, 0.0) / (count - 1)) if count > 1 else np.zeros(3)
            first, last = self._part(*ranges[k + 1], parts), self._part(*ranges[k + 2], parts)
            found.append(Measured(PoseStats(mean, std, count), last[1] / last[0] - first[1] / first[0]))
        return found

    def _part(self, a: int, b: int, parts: Mapping[Part, Moments]) -> Moments:
        """The count, sum and co-moment of the log's readings ``a``..``b``."""
        cuts = self._cuts(a, b)
        if len(cuts) == 1:
            return parts[cuts[0]]
        inner = slice(cuts[0][0] + 1, cuts[1][0])
        counts = self.counts[inner]
        found = [parts[cuts[0]]]
        if counts.size:
            n = int(counts.sum())
            total = self.sums[inner].sum(axis=0)
            means = self.sums[inner] / counts[:, None]
            m2 = self.m2[inner].sum(axis=0) + (counts[:, None] * np.square(means - total / n)).sum(axis=0)
            found.append((n, total, m2))
        found.append(parts[cuts[1]])
        return _merge(found)


def moments(values: FloatArray) -> Moments:
    """The count, sum and co-moment (each axis's squares about the mean) of readings (n, 3)."""
    n = len(values)
    total = values.sum(axis=0)
    return n, total, np.square(values - total / n).sum(axis=0)


def _merge(parts: list[Moments]) -> Moments:
    """Counts, sums and co-moments of consecutive parts as one (each co-moment about its own mean)."""
    if len(parts) == 1:
        return parts[0]
    n = sum(p[0] for p in parts)
    total = np.sum([p[1] for p in parts], axis=0)
    mean = total / n
    m2 = np.sum([p[2] + p[0] * np.square(p[1] / p[0] - mean) for p in parts], axis=0)
    return n, total, m2
