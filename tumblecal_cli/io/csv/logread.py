"""A log read block by block into the streaming detector (``core.scan``): segment and
solve --log on logs of any length.

``readings.read_log`` holds a whole log in memory (its readings, rows, clock and the text of
each block until the end): 3.5 GB for 20 million rows. Here a regular file of plain lines
(``io.csv.splice``'s rules) is read in blocks on a pool of threads, each block's sensor, time and
temperature cells parsed where they lie, and fed in order to ``core.scan.Scan``, which keeps
where the still periods are and bands of spreads of a fixed size (neither their readings nor a
spread each); the worker threads sum each CHUNK readings (``core.chunks``). At the end each
block's statistics are merged from those sums and from the few chunks where it or its third
begins or ends, read again (``_ScannedFile``). What is
returned is a ``readings.Log`` of each block's first and last reading (its row, time and line's
place in the file, so that ``segment`` copies the blocks' lines as they are); a block's
readings are read again when they are asked for (``Log.block``), and a file that is not as it
was then is an error.

Anything else returns None before anything is said or written, and the caller reads the log
whole, by the general rules: a stream, whitespace or CR line ends, a line that is not plain
(a comment, a blank line, a cell that is not a number, a partly empty reading), time that goes
backwards or is not a number, a clock stamped in bursts (core.clock: its first readings' say
so here, the whole log's ``Scan``), a reading that is not finite or too large, a label column,
or a log ``Scan`` cannot finish (its docstring). Every error message and every figure of those
logs is therefore the general path's own.
"""

from __future__ import annotations

import hashlib
import itertools
import os
from collections import deque
from collections.abc import Callable, Generator, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import model
from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.core.blocks import DetectorSettings, Measured, Segmentation, clock_of, sample_period, window_spread
from tumblecal_cli.core.chunks import CHUNK, Chunks, Cuts, chunk_sums
from tumblecal_cli.core.scan import Kept, Scan
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import capture, readings, sniff
from tumblecal_cli.io.csv.readings import Log, Stretch
from tumblecal_cli.io.csv.splice import Splicer, cuts, reader_for
from tumblecal_cli.io.readspec import ReadSpec

#: Files smaller than this keep their readings' rows and line offsets as int32 (4 bytes, not 8).
NARROW = 1 << 31

#: Readings the time unit and the first period are judged from (``readings.time_scale`` reads as many).
FIRST = 100_001

#: A log is read in blocks of this many capture.BLOCK_BYTES: each block has a fixed cost (its
#: parse's and its scan's calls), so fewer of them take less time, and each in hand more memory.
#: A 20M-row log, in one process: 1 MiB blocks 3.55-3.75 s and 346-352 MiB, 2 MiB 2.84-3.05 s and
#: 373-375 MiB, 3 MiB 2.70-2.75 s and 387-391 MiB, 4 MiB 2.77-2.80 s and 440-447 MiB.
SCALE = 2
#: The bytes of readings held until the end of the log (``coded``, 12 a reading: a 5M-row log's),
#: where the parts of the chunks a block cuts are measured without reading them again: a log
#: whose readings take more (by its first blocks' bytes a reading) holds none, and its memory
#: stays what it is at any length.
KEPT = 64 << 20
#: Blocks parsed ahead of the one the scan takes, beyond one a thread (and blocks the digest's
#: thread may be behind): each one's text and cells are held meanwhile.
AHEAD = 1


class _Shared(TypedDict, total=False):
    """What the threads that parse the blocks learn from the main thread as it goes."""

    window: int  # the Scan's window, once known: the threads compute a block's spreads
    odd: float  # a reading that is not a whole number, once one is found
    digits: int  # the decimals the last block's readings were kept in (``coded``) ...
    full: bool  # ... and whether the readings kept have filled KEPT: the threads code no more


class _Plain(Exception):
    """A block, a clock or a reading the streaming path does not take: read the log whole."""


def scan_log(
    path: str, spec: ReadSpec, *, settings: DetectorSettings, name: str | None = None, digest: bool = True
) -> tuple[Log, Segmentation] | None:
    """The log at ``path`` (a regular file) read by ``spec``, and its still blocks found by
    ``core.scan``, or None when it is to be read whole (the module's docstring). With
    ``spec.rate`` the time column is not judged (as ``read_log(use_time=False)``)."""
    time_unit, rate = spec.time_unit, spec.rate
    with capture.open_capture(path, spec, name=name) as cap:
        lay = cap.layout
        extra = [i for i in (lay.time, lay.per_row_column) if i is not None]
        splicer = reader_for(cap, also=extra)
        if splicer is None:
            return None
        where = [splicer.parsed.index(i) for i in (*lay.sensor, *extra)]
        try:
            return _scan(path, lay, splicer, where, settings, time_unit, rate, digest)
        except _Plain:  # the layout and its notes go with it: the whole read opens the log again
            return None


def _scan(
    path: str,
    lay: sniff.Layout,
    splicer: Splicer,
    where: list[int],
    settings: DetectorSettings,
    time_unit: str,
    rate: float | None,
    digest: bool,
) -> tuple[Log, Segmentation] | None:
    hasher = _Digest() if digest else None
    try:
        if hasher is not None:
            with open(path, "rb") as f:
                hasher.update(f.read(len(lay.head)))
        source = _ScannedFile(path, lay, splicer, where)
        feeder = _Feeder(lay, settings, time_unit, rate, source)
        for block in _blocks(path, lay, splicer, where, hasher, feeder.shared):
            feeder.check(block)
            feeder.add(block)
    except BaseException:
        if hasher is not None:
            hasher.cancel()
        raise
    sha256 = "" if hasher is None else hasher.hexdigest()
    _give_back()
    scan = feeder.started()
    done = scan.finish(feeder.measure)
    if done is None:
        return None
    seg, kept = done
    seg.gap_rows = [int(r) for r in scan.before_gaps[:, 0]] if len(scan.before_gaps) else []
    ends = feeder.ends
    at = np.array(sorted(ends), dtype=np.int64)
    found = [ends[int(p)] for p in at]
    narrow = np.int32 if source.size < NARROW else np.int64
    lines: IntArray = np.array([e.line for e in found], dtype=narrow).reshape(-1, 2)  # type: ignore[assignment]
    log = Log(
        lay,
        np.array([e.value for e in found]).reshape(-1, 3),
        np.array([e.row for e in found], dtype=narrow),
        np.array([e.clock for e in found]) if lay.time is not None else None,
        None,
        sha256,
        np.array([e.temperature for e in found]) if lay.per_row_column is not None else None,
        feeder.scale,
        lines=lines,
        extremes=feeder.extremes(),
        runs=(kept.run_first, kept.run_at),
        at=at,
        reread=source.block,
    )
    return log, seg


def _give_back() -> None:
    """Return to the system the memory the parsing threads have freed: glibc keeps each thread's
    for it (20M rows: 346 MiB before, 263 after), and the end of the log allocates anew. Where
    the C library has no malloc_trim (musl, macOS), nothing."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


@dataclass(frozen=True)
class _End:
    """A block's first or last reading, kept: its reading, data row, time and temperature cells
    (NaN where the log has none) and its line's first byte and end."""

    value: FloatArray
    row: int
    clock: float
    temperature: float
    line: tuple[int, int]


@dataclass(frozen=True)
class _ReadAgain:
    """Readings read again from a stretch of whole lines: each one's line among them (from 0)
    and its line's first byte and end in the file."""

    values: FloatArray
    clock: FloatArray | None
    temperature: FloatArray | None
    lines: IntArray
    starts: IntArray
    stops: IntArray


def part_moments(values: FloatArray, starts: IntArray, n: IntArray) -> tuple[IntArray, FloatArray, FloatArray]:
    """The count, sum and co-moment (``core.chunks.moments``) of the ``n`` readings of ``values``
    from each of ``starts`` (at most CHUNK of them), all at once: each sum taken down the readings
    in order, as numpy sums them along the first axis, so the same digits."""
    if not n.size:
        return n, np.zeros((0, 3)), np.zeros((0, 3))
    at = np.minimum(starts[:, None] + np.arange(int(n.max())), len(values) - 1)
    taken = values[at]  # (parts, width, 3)
    rows, last = np.arange(n.size), n - 1
    total = np.cumsum(taken, axis=1)[rows, last]
    m2 = np.cumsum(np.square(taken - (total / n[:, None])[:, None, :]), axis=1)[rows, last]
    return n, total, m2


def coded(values: FloatArray, digits: int | None) -> tuple[NDArray[np.int32], int] | None:
    """``values`` as whole numbers of 10**-d (int32: 12 bytes a reading, not 24), with ``d``, the
    fewest decimals (``digits`` tried first) that give every value back bit for bit (``decoded``:
    a number of d decimals parsed is the double nearest it, and so is k / 10**d, IEEE's division
    being correctly rounded); None when no d up to 9 does."""
    for d in ([digits] if digits is not None else []) + list(range(10)):
        scale = 10.0**d
        k = np.rint(values * scale)
        if float(np.abs(k).max(initial=0.0)) < 2**31 and np.array_equal(k / scale, values):
            return k.astype(np.int32), d
    return None


def decoded(k: NDArray[np.int32], d: int) -> FloatArray:
    """The readings ``coded`` kept, as they were parsed."""
    values: FloatArray = k / 10.0**d
    return values


class _Chunked:
    """Readings read again from stretches of whole lines (a log's chunks), parsed together: each
    stretch's first reading among them, and for each reading its line among its stretch's."""

    def __init__(
        self,
        cells: FloatArray,
        timed: bool,
        warm: bool,
        first: IntArray,
        line: IntArray,
        text: tuple[IntArray, IntArray, IntArray],
        ranges: IntArray,
    ) -> None:
        self.values: FloatArray = cells[:, :3]
        self.clock: FloatArray | None = cells[:, 3] if timed else None
        self.temperature: FloatArray | None = cells[:, 3 + timed] if warm else None
        self.first, self.line, self.ranges = first, line, ranges
        self._newline, self._offsets, self._line_of = text
        self.skip = np.zeros(len(first), dtype=np.int64)  # each stretch's readings before those parsed

    def moments(self, stretch: IntArray, lo: IntArray, hi: IntArray) -> tuple[IntArray, FloatArray, FloatArray]:
        """The count, sum and co-moment (``core.chunks.moments``) of the readings ``lo``..``hi``
        of each ``stretch`` (positions in it, at most CHUNK of them), all at once: each sum taken
        down the readings in order, as numpy sums them along the first axis, so the same digits."""
        return part_moments(self.values, self.first[stretch] + lo - self.skip[stretch], hi - lo + 1)

    def end(self, stretch: int, j: int, row: int) -> _End:
        """The ``j``-th reading of ``stretch``, whose first reading is the log's data row ``row``."""
        r = int(self.first[stretch]) + j - int(self.skip[stretch])
        line = int(self.line[r])
        start, stop = (int(v) for v in self.ranges[stretch])
        base = start - int(self._offsets[stretch])  # a byte of the text is this far from the file's
        at = int(self._line_of[stretch]) + line
        begins = start if not line else int(self._newline[at - 1]) + 1 + base
        return _End(
            self.values[r].copy(),
            row + line + int(self.skip[stretch]),
            np.nan if self.clock is None else float(self.clock[r]),
            np.nan if self.temperature is None else float(self.temperature[r]),
            (begins, min(int(self._newline[at]) + 1 + base, stop)),
        )


class _ScannedFile:
    """The log's file, read again where the scan kept nothing: the chunks where a block or its
    third begins or ends, and a block's lines when its readings are asked for. A file that is
    not the one scanned (its inode, or its size and time) is not read: at the end of the scan
    the whole read takes over (``_Plain``); a block asked for later is an error."""

    def __init__(self, path: str, lay: sniff.Layout, splicer: Splicer, where: list[int]) -> None:
        self.path, self.name, self.splicer, self.where = path, lay.name, splicer, where
        self.timed, self.warm = lay.time is not None, lay.per_row_column is not None
        st = os.stat(path)
        self.size = st.st_size
        self.stamp = capture.stamp(st)

    def read(
        self, ranges: IntArray, counts: IntArray, wanted: IntArray, each: Callable[[int, int, _Chunked], None]
    ) -> None:
        """The readings of each stretch of lines (``ranges``: its first byte and end), ``counts``
        of them, given to ``each`` a batch of stretches at a time (the first of them and the one
        after) as they are parsed, on a pool of threads: none is held longer. Of a stretch with a
        reading on every line only the lines of the readings ``wanted`` (its first and last) are
        parsed: ``_Chunked.skip`` says how many lines before them were left."""
        if not len(ranges):
            return
        sizes = np.cumsum(ranges[:, 1] - ranges[:, 0])
        cut = np.searchsorted(sizes, np.arange(capture.BLOCK_BYTES, int(sizes[-1]), capture.BLOCK_BYTES), side="right")
        edges = np.unique(np.concatenate([[0], cut + 1, [len(ranges)]]).clip(0, len(ranges))).tolist()
        batches = [(a, b) for a, b in itertools.pairwise(edges) if b > a]

        def parse(k: tuple[int, int]) -> None:
            a, b = k
            texts: list[bytes] = []
            places, skip, held = ranges[a:b].copy(), np.zeros(b - a, dtype=np.int64), counts[a:b].copy()
            for g, h in _near(ranges[a:b]):  # stretches close together: one read, their line ends found at once
                base = int(places[g, 0])
                text = _text(fd, base, int(places[h - 1, 1]))
                ends = np.flatnonzero(np.frombuffer(text, dtype=np.uint8) == 10) + base
                part = places[g:h]
                if not len(ends):  # one line, the file's last, without a line end: read whole
                    texts.append(text)
                    continue
                first, past = np.searchsorted(ends, part[:, 0]), np.searchsorted(ends, part[:, 1])
                closed = (past > first) & (ends[np.maximum(past - 1, 0)] == part[:, 1] - 1)  # its last line ended
                lo, hi = wanted[a + g : a + h, 0], wanted[a + g : a + h, 1]
                trim = ((lo > 0) | (hi < held[g:h] - 1)) & (past - first + ~closed == held[g:h])  # a reading a line
                begin = np.where(trim & (lo > 0), ends[np.clip(first + lo - 1, 0, len(ends) - 1)] + 1, part[:, 0])
                at = first + hi
                end = np.where(trim & (at < past), ends[np.minimum(at, len(ends) - 1)] + 1, part[:, 1])
                begin, end = np.where(trim, begin, part[:, 0]), np.where(trim, end, part[:, 1])
                skip[g:h], held[g:h] = np.where(trim, lo, 0), np.where(trim, hi - lo + 1, held[g:h])
                places[g:h, 0], places[g:h, 1] = begin, end
                texts += [text[x - base : y - base] for x, y in zip(begin.tolist(), end.tolist(), strict=True)]
            got = self._chunked(texts, places, held)
            got.skip = skip
            each(a, b, got)

        try:
            with open(self.path, "rb") as f:
                fd = f.fileno()
                self._same(os.fstat(fd))
                with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as pool:  # (pyarrow and numpy
                    list(pool.map(parse, batches))  # let go of the GIL)
                self._same(os.fstat(fd))
        except OSError:  # gone, or not readable: the whole read says so
            raise _Plain from None

    def _chunked(self, texts: list[bytes], ranges: IntArray, counts: IntArray) -> _Chunked:
        """The readings of stretches of lines (their texts, first bytes and ends, and how many
        readings each holds), parsed together."""
        texts = [text if text.endswith(b"\n") else text + self.splicer.eol for text in texts]
        found = self.splicer.read(b"".join(texts))
        if found is None:
            raise _Plain
        parsed, empty, newline = found
        offsets = np.cumsum([0] + [len(t) for t in texts])
        line_of = np.searchsorted(newline, offsets[:-1])  # each stretch's first line
        keep = np.flatnonzero(~empty)
        stretch = np.searchsorted(offsets, newline[keep], side="right") - 1  # each reading's stretch
        if not np.array_equal(np.bincount(stretch, minlength=len(texts)), counts):
            raise _Plain
        cells = _columns(parsed, self.where)[keep]
        first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        return _Chunked(
            cells, self.timed, self.warm, first, keep - line_of[stretch], (newline, offsets, line_of), ranges
        )

    def _same(self, st: os.stat_result) -> None:
        """Raise _Plain unless the file is the one scanned: the same file, its bytes then there
        still (a log still being written grows: the blocks found are in what was read)."""
        if capture.changed(self.stamp, capture.stamp(st)):
            raise _Plain

    def _parse(self, batch: list[tuple[int, int, int | None, bytes]]) -> list[_ReadAgain]:
        """Each stretch's readings (its first byte, end, how many readings it holds when that is
        known, and its text), parsed together."""
        texts = [text if text.endswith(b"\n") else text + self.splicer.eol for *_, text in batch]
        found = self.splicer.read(b"".join(texts))
        if found is None:
            raise _Plain
        parsed, empty, newline = found
        parsed = _columns(parsed, self.where)
        out, line, offset = [], 0, 0
        for (start, stop, n, _), text in zip(batch, texts, strict=True):
            k = text.count(b"\n")
            keep = np.flatnonzero(~empty[line : line + k])
            if n is not None and keep.size != n:
                raise _Plain
            stops = np.minimum(newline[line : line + k] - offset + 1 + start, stop)
            starts = np.concatenate([[start], stops[:-1]])
            cells = parsed[line : line + k][keep]
            clock = cells[:, 3] if self.timed else None
            temp = cells[:, 3 + self.timed] if self.warm else None
            out.append(_ReadAgain(cells[:, :3], clock, temp, keep, starts[keep], stops[keep]))
            line, offset = line + k, offset + len(text)
        return out

    def block(self, start: int, stop: int, count: int) -> Stretch:
        """The ``count`` readings of a block's lines (its first byte and end), read in pieces of
        whole lines."""
        read: list[_ReadAgain] = []
        at = start
        try:
            with open(self.path, "rb") as f:
                self._same(os.fstat(f.fileno()))
                while at < stop:
                    text = _text(f.fileno(), at, min(stop, at + capture.BLOCK_BYTES))
                    if at + len(text) < stop:  # up to the piece's last line end (a longer line: the rest)
                        cut = text.rfind(b"\n")
                        text = text[: cut + 1] if cut >= 0 else text + _text(f.fileno(), at + len(text), stop)
                    read += self._parse([(at, at + len(text), None, text)])
                    at += len(text)
                self._same(os.fstat(f.fileno()))
            if sum(len(r.values) for r in read) != count:
                raise _Plain
        except (_Plain, OSError):
            raise InputError(
                "the log is not as it was when its blocks were found: changed or gone", file=self.name
            ) from None
        values = np.asfortranarray(np.concatenate([r.values for r in read]))  # each axis's own: summed as kept
        clock = None if not self.timed else np.concatenate([r.clock for r in read if r.clock is not None])
        temp = None if not self.warm else np.concatenate([r.temperature for r in read if r.temperature is not None])
        return Stretch(values, clock, temp)


class _Digest:
    """The file's SHA-256, taken on a thread of its own (the main thread feeds the Scan), a few
    blocks behind at most (the blocks waiting are held in memory)."""

    def __init__(self) -> None:
        self._sha = hashlib.sha256()
        self._thread = ThreadPoolExecutor(max_workers=1)
        self._waiting: deque[Future[None]] = deque()

    def update(self, text: bytes) -> None:
        self._waiting.append(self._thread.submit(self._sha.update, text))  # in order: one thread
        while len(self._waiting) > AHEAD:
            self._waiting.popleft().result()

    def hexdigest(self) -> str:
        while self._waiting:
            self._waiting.popleft().result()
        self._thread.shutdown(wait=True)
        return self._sha.hexdigest()

    def cancel(self) -> None:
        self._thread.shutdown(wait=True, cancel_futures=True)


class _Block:
    """One block of the file, parsed on a worker thread: its readings (rows with sensor values)
    and what goes with them, ready for the Scan but for the data rows' offset."""

    def __init__(
        self,
        parsed: FloatArray,
        empty: BoolArray,
        newline: IntArray,
        place: tuple[int, int, int],
        timed: bool,
        shared: _Shared,
    ) -> None:
        """``newline``: each line's line feed in the block; ``place``: the block's first byte and
        length, and the file's size."""
        at, self.bytes, size = place
        keep = ~empty if empty.any() else None  # an interleaved logger's rows of another sensor: not readings
        self.lines = int(empty.size)  # lines in the block: all of them data rows (plain lines)
        # a time or temperature cell that is empty or not finite on any row, one without readings
        # too: the whole read judges the whole column (an error, or no clock at all with --rate)
        self.columns_ok = bool(np.isfinite(parsed[:, 3:]).all())
        parsed = parsed if keep is None else parsed[keep]
        self.values: FloatArray = parsed[:, :3]  # a view: the scan copies what it keeps
        self.clock: FloatArray | None = parsed[:, 3] if timed else None
        self.temp: FloatArray | None = parsed[:, 3 + timed] if parsed.shape[1] > 3 + timed else None
        m = len(self.values)
        rows = np.arange(self.lines) if keep is None else np.flatnonzero(keep)  # data row, from the block's first
        self.ints: IntArray = rows[:, None]  # what the Scan carries with each reading: its row (a gap's is said)
        self.floats: FloatArray = np.empty((m, 0))
        # each CHUNK readings: the first one's line's first byte, the last one's line end, the first one's row
        first = rows[::CHUNK]
        last = rows[np.minimum(np.arange(CHUNK - 1, m + CHUNK - 1, CHUNK), m - 1)]
        starts = np.where(first > 0, newline[np.maximum(first - 1, 0)] + 1 + at, at)
        self.chunk_lines: IntArray = np.column_stack([starts, np.minimum(newline[last] + 1 + at, size), first])
        self.finite = bool(np.isfinite(self.values).all())
        self.lo = float(self.values.min()) if self.values.size and self.finite else 0.0
        self.hi = float(self.values.max()) if self.values.size and self.finite else 0.0
        summed = self.finite and max(-self.lo, self.hi) <= model.MAX_READING  # (else the whole read says why)
        self.chunks = chunk_sums(self.values) if summed else None  # what a block's statistics are merged from
        self.coded = coded(self.values, shared.get("digits")) if summed and not shared.get("full") else None
        if self.coded is not None:
            shared["digits"] = self.coded[1]
        self.odd: float | None = None  # a reading that is not a whole number: one in the log is enough
        if self.finite and "odd" not in shared:
            fraction = self.values[self.values != np.round(self.values)]
            self.odd = float(fraction[0]) if fraction.size else None
        clock = self.clock
        self.backwards = clock is not None and clock.size > 1 and bool((np.diff(clock) < 0).any())
        window = shared.get("window")
        self.inside = window_spread([self.values], window) if window and len(self.values) >= window else None


class _Feeder:
    """The blocks into a Scan: judged first (what the streaming path does not take), held until
    the first FIRST readings give the time unit and the period."""

    def __init__(
        self, lay: sniff.Layout, settings: DetectorSettings, time_unit: str, rate: float | None, source: _ScannedFile
    ):
        self.lay, self.settings, self.time_unit, self.rate = lay, settings, time_unit, rate
        self.source, self.size = source, source.size
        self.scan: Scan | None = None
        self.chunks = Chunks()  # each CHUNK readings' sums, and where their lines are: (first byte, end, row)
        self.chunk_lines: list[IntArray] = []
        #: the readings of the first blocks (until KEPT): each one's first reading in the log, coded
        self.kept: list[tuple[int, NDArray[np.int32], int]] = []
        self.kept_bytes = 0
        #: after measure: the first and last reading of each block, by its position among those kept
        self.ends: dict[int, _End] = {}
        self.first: list[_Block] = []
        self.shared: _Shared = {}
        self.scale, self.zero, self.last_clock = 1.0, 0.0, -np.inf
        self.lo, self.hi = np.inf, -np.inf  # every reading's range ...
        self.odd: float | None = None  # ... and one that is not a whole number

    def check(self, block: _Block) -> None:
        if not block.finite or max(-block.lo, block.hi) > model.MAX_READING:
            raise _Plain  # the general path names the cell, or says what is too large
        self.lo, self.hi = min(self.lo, block.lo), max(self.hi, block.hi)
        if self.odd is None and block.odd is not None:
            self.odd = self.shared["odd"] = block.odd
        clock = block.clock
        if not block.columns_ok:
            raise _Plain
        if clock is not None and clock.size:
            if self.rate is None and (block.backwards or clock[0] < self.last_clock):
                raise _Plain  # time going backwards: the general path names the line
            self.last_clock = float(clock[-1])

    def add(self, block: _Block) -> None:
        if self.scan is not None:
            self._feed(self.scan, block)
            return
        self.first.append(block)
        if sum(len(b.values) for b in self.first) >= FIRST:
            self.started()

    def started(self) -> Scan:
        """The Scan, made from the first blocks (and fed them) if it is not yet."""
        if self.scan is not None:
            return self.scan
        if not sum(len(b.values) for b in self.first):
            raise _Plain  # no readings at all: the general path says so
        lay, seconds = self.lay, None
        if lay.time is not None:
            clock = np.concatenate([b.clock for b in self.first if b.clock is not None])
            self.zero = float(clock[0])
            try:
                self.scale = readings.time_scale(lay, clock, self.time_unit)
            except InputError:
                if self.rate is None:
                    raise _Plain from None  # the general path raises it, with everything before it said
                self.scale = sniff.TIME_SCALE[lay.time_unit or "s"]
            seconds = None if self.rate else (clock - self.zero) * self.scale
            found = clock_of(seconds)[0]
            if found is not None and found.bursty:
                raise _Plain  # stamped on arrival: the whole read takes the period from its mean step (core.clock)
        capacity = _capacity(self.first, self.size)
        read, count = sum(b.bytes for b in self.first), sum(len(b.values) for b in self.first)
        if 12 * self.size * count > KEPT * max(read, 1):  # not the whole log's readings: none kept
            self.shared["full"] = True
        scan = self.scan = Scan(sample_period(seconds, self.rate), self.settings, capacity=capacity, readings=False)
        self.shared["window"] = scan.window
        for b in self.first:
            self._feed(scan, b)
        self.first = []
        return scan

    def _feed(self, scan: Scan, block: _Block) -> None:
        clock = block.clock
        seconds = (clock - self.zero) * self.scale if clock is not None and self.rate is None else None
        inside = block.inside
        if inside is not None and inside.size + scan.window - 1 != len(block.values):
            inside = None  # computed with another window (before the first blocks gave it)
        first = scan.n
        scan.feed(block.values, seconds, block.floats, block.ints, inside)
        if block.chunks is not None and len(block.values):
            self.chunks.add(first, *block.chunks)
            self.chunk_lines.append(block.chunk_lines)
        if block.coded is not None and not self.shared.get("full") and self.kept_bytes + block.coded[0].nbytes <= KEPT:
            self.kept.append((first, *block.coded))
            self.kept_bytes += block.coded[0].nbytes
        elif block.coded is not None:
            self.shared["full"] = True

    def measure(self, kept: Kept, spans: list[tuple[int, int]]) -> list[Measured]:
        """Each block's statistics, merged from the chunks' sums and the parts of the chunks
        where a block or its third begins or ends: from the readings kept (``coded``), or read
        again (each batch of chunks' readings let go as soon as its parts are summed); and each
        block's first and last reading (``ends``), its line read again."""
        chunks = self.chunks
        chunks.done()
        lines = np.concatenate(self.chunk_lines) if self.chunk_lines else np.zeros((0, 3), dtype=np.int64)
        positions = np.array(spans, dtype=np.int64).reshape(-1)
        found = kept.log_index(positions) if positions.size else positions
        plan = chunks.plan([(int(a), int(b)) for a, b in found.reshape(-1, 2)])
        count = np.zeros(len(plan.parts), dtype=np.int64)
        total, m2 = np.zeros((len(plan.parts), 3)), np.zeros((len(plan.parts), 3))
        held = self._held(plan.parts)
        for k in np.unique(held[held >= 0]).tolist():  # the parts of the readings kept
            first, values, d = self.kept[k]
            mine = np.flatnonzero(held == k)
            c = plan.parts[mine]
            count[mine], total[mine], m2[mine] = part_moments(
                decoded(values, d), chunks.start[c[:, 0]] + c[:, 1] - first, c[:, 2] - c[:, 1] + 1
            )
        self._read_again(plan, np.flatnonzero(held < 0), found, positions, (count, total, m2), lines)
        return chunks.measured(plan, count, total, m2)

    def _held(self, parts: IntArray) -> IntArray:
        """Which of the readings kept each part's chunk is in (-1: none: it is read again)."""
        chunks = self.chunks
        if not self.kept:
            return np.full(len(parts), -1, dtype=np.int64)
        starts = chunks.start[parts[:, 0]]
        firsts = np.array([f for f, _, _ in self.kept], dtype=np.int64)
        k = np.searchsorted(firsts, starts, side="right") - 1
        sizes = np.array([len(v) for _, v, _ in self.kept], dtype=np.int64)
        inside = (k >= 0) & (starts + chunks.counts[parts[:, 0]] <= firsts[k] + sizes[k])
        return np.where(inside, k, -1)

    def _read_again(
        self,
        plan: Cuts,
        again: IntArray,
        found: IntArray,
        positions: IntArray,
        into: tuple[IntArray, FloatArray, FloatArray],
        lines: IntArray,
    ) -> None:
        """The parts ``again`` measured from their chunks read again, and each block's first and
        last reading (its line, time and temperature) from its own."""
        chunks = self.chunks
        count, total, m2 = into
        at = chunks.of(found) if found.size else found  # each block end's chunk
        need = np.union1d(plan.parts[again, 0], at).astype(np.int64)
        part_of = np.searchsorted(need, plan.parts[again, 0])  # each part's stretch among those read
        end_of = np.searchsorted(need, at)
        order = again[np.argsort(part_of, kind="stable")]
        bounds = np.searchsorted(np.sort(part_of), np.arange(len(need) + 1))
        stretch_of = np.zeros(len(plan.parts), dtype=np.int64)
        stretch_of[again] = part_of
        ends = [
            (int(s), int(i - chunks.start[c]), int(lines[c, 2]), p)
            for s, i, c, p in zip(end_of, found, at, positions.tolist(), strict=True)
        ]
        ends.sort()
        end_stretch = np.array([e[0] for e in ends], dtype=np.int64)

        def take(a: int, b: int, got: _Chunked) -> None:  # on a parsing thread: each writes its own parts
            mine = order[bounds[a] : bounds[b]]
            c, t, q = got.moments(stretch_of[mine] - a, plan.parts[mine, 1], plan.parts[mine, 2])
            count[mine], total[mine], m2[mine] = c, t, q
            for e in range(*np.searchsorted(end_stretch, [a, b]).tolist()):
                s, j, row, p = ends[e]
                self.ends[p] = got.end(s - a, j, row)

        wanted = np.column_stack([np.full(len(need), CHUNK), np.zeros(len(need), dtype=np.int64)])
        np.minimum.at(wanted[:, 0], part_of, plan.parts[again, 1])  # the first and last reading wanted of each
        np.maximum.at(wanted[:, 1], part_of, plan.parts[again, 2])
        j = (found - chunks.start[at]).astype(np.int64)
        np.minimum.at(wanted[:, 0], end_of, j)
        np.maximum.at(wanted[:, 1], end_of, j)
        self.source.read(lines[need, :2], chunks.counts[need], wanted, take)

    def extremes(self) -> FloatArray:
        """What gate.integer_rails judges the whole log's readings by: the lowest, the highest,
        and one that is not a whole number (if any)."""
        return np.array([[self.lo] * 3, [self.hi] * 3, [self.lo if self.odd is None else self.odd] * 3])


def _capacity(first: list[_Block], size: int) -> int:
    """As many readings as the file may hold, by the first blocks' bytes per reading (and a margin)."""
    read = sum(b.bytes for b in first)
    readings = sum(len(b.values) for b in first)
    return int(1.25 * size * readings / max(read, 1)) + (1 << 16)


def _blocks(
    path: str, lay: sniff.Layout, splicer: Splicer, where: list[int], hasher: _Digest | None, shared: _Shared
) -> Iterator[_Block]:
    """Each block of the file read and parsed on a pool of threads (numpy, pyarrow and the
    reads let go of the GIL), in file order, its rows numbered here; hashed here, in order."""

    blocks = cuts(path, len(lay.head), SCALE * capture.BLOCK_BYTES)
    if blocks is None:
        raise _Plain  # a line longer than a block
    workers = max(2, os.cpu_count() or 1)
    pending: deque[Future[tuple[_Block, bytes]]] = deque()
    row = 0
    size = os.path.getsize(path)
    timed = lay.time is not None
    with open(path, "rb") as f, ThreadPoolExecutor(max_workers=workers) as pool:
        for at, length in blocks:
            pending.append(pool.submit(_parse, splicer, f.fileno(), at, length, where, size, timed, shared))
            while len(pending) > workers + AHEAD:
                row = yield from _numbered(pending.popleft(), row, hasher)
        while pending:
            row = yield from _numbered(pending.popleft(), row, hasher)


def _numbered(job: Future[tuple[_Block, bytes]], row: int, hasher: _Digest | None) -> Generator[_Block, None, int]:
    block, text = job.result()
    if hasher is not None:
        hasher.update(text)
    if row:
        block.ints += row
        block.chunk_lines[:, 2] += row
    yield block
    return row + block.lines


def _parse(
    splicer: Splicer, fd: int, at: int, length: int, where: list[int], size: int, timed: bool, shared: _Shared
) -> tuple[_Block, bytes]:
    text = _text(fd, at, at + length)  # (_Plain: the file changed while it was read)
    found = splicer.read(text)
    if found is None:
        raise _Plain
    parsed, empty, newline = found
    return _Block(_columns(parsed, where), empty, newline, (at, length, size), timed, shared), text


def _columns(parsed: FloatArray, where: list[int]) -> FloatArray:
    """The parsed cells' columns in the order ``where`` gives (no copy when it is theirs)."""
    return parsed if where == list(range(parsed.shape[1])) else parsed[:, where]


#: Stretches of a file read again that lie closer together than this are read in one piece.
NEAR = 64 << 10


def _near(ranges: IntArray) -> list[tuple[int, int]]:
    """The runs of ``ranges`` (first byte, end; in order) each less than NEAR past the last."""
    if not len(ranges):
        return []
    apart = np.flatnonzero(ranges[1:, 0] - ranges[:-1, 1] >= NEAR) + 1
    edges = [0, *apart.tolist(), len(ranges)]
    return list(itertools.pairwise(edges))


def _text(fd: int, start: int, stop: int) -> bytes:
    """The file's bytes ``start`` .. ``stop - 1``; _Plain when it no longer holds them all."""
    text = os.pread(fd, stop - start, start)
    if len(text) != stop - start:
        raise _Plain
    return text
