"""A log read block by block into the streaming detector (``core.scan``): segment and
solve --log on logs of any length.

``readings.read_log`` holds a whole log in memory (its readings, rows, clock and the text of
each block until the end): 3.5 GB for 20 million rows. Here a regular file of plain lines
(``io.splice``'s rules) is read in blocks on a pool of threads, each block's sensor, time and
temperature cells parsed where they lie, and fed in order to ``core.scan.Scan``, which keeps
the readings of the still periods only. What is kept is returned as a ``readings.Log`` whose
samples are those readings (a block's ``first``..``last`` index them), with each reading's
line's place in the file, so that ``segment`` copies the blocks' lines without reading the
file again.

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
import os
from collections import deque
from collections.abc import Generator, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypedDict

import numpy as np

from tumblecal_cli.core import model
from tumblecal_cli.core.scan import Scan
from tumblecal_cli.core.segment import (
    FloatArray,
    IntArray,
    Segmentation,
    Settings,
    clock_of,
    sample_period,
    window_spread,
)
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import capture, readings, rewrite, sniff
from tumblecal_cli.io.forked import cuts
from tumblecal_cli.io.readings import Log
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.splice import BoolArray, Offsets, Splicer

#: Files smaller than this keep their readings' rows and line offsets as int32 (4 bytes, not 8).
NARROW = 1 << 31

#: Readings the time unit and the first period are judged from (``readings.time_scale`` reads as many).
FIRST = 100_001


class _Shared(TypedDict, total=False):
    """What the threads that parse the blocks learn from the main thread as it goes."""

    window: int  # the Scan's window, once known: the threads compute a block's spreads
    odd: float  # a reading that is not a whole number, once one is found


class _Plain(Exception):
    """A block, a clock or a reading the streaming path does not take: read the log whole."""


def scan_log(
    path: str, spec: ReadSpec, *, settings: Settings, name: str | None = None, digest: bool = True
) -> tuple[Log, Segmentation] | None:
    """The log at ``path`` (a regular file) read by ``spec``, and its still blocks found by
    ``core.scan``, or None when it is to be read whole (the module's docstring). With
    ``spec.rate`` the time column is not judged (as ``read_log(use_time=False)``)."""
    time_unit, rate = spec.time_unit, spec.rate
    with capture.open_capture(path, spec, name=name) as cap:
        lay = cap.layout
        extra = [i for i in (lay.time, lay.temperature) if i is not None]
        splicer = rewrite.splicer_for(cap, [(lay.sensor, _same)], also=extra)
        if splicer is None:
            return None
        where = [splicer.parsed.index(i) for i in (*lay.sensor, *extra)]
        try:
            return _scan(path, lay, splicer, where, settings, time_unit, rate, digest)
        except _Plain:  # the layout and its notes go with it: the whole read opens the log again
            return None


def _same(values: FloatArray) -> FloatArray:
    return values


def _scan(
    path: str,
    lay: sniff.Layout,
    splicer: Splicer,
    where: list[int],
    settings: Settings,
    time_unit: str,
    rate: float | None,
    digest: bool,
) -> tuple[Log, Segmentation] | None:
    hasher = _Digest() if digest else None
    try:
        if hasher is not None:
            with open(path, "rb") as f:
                hasher.update(f.read(len(lay.head)))
        feeder = _Feeder(lay, settings, time_unit, rate, os.path.getsize(path))
        for block in _blocks(path, lay, splicer, where, hasher, feeder.shared):
            feeder.check(block)
            feeder.add(block)
    except BaseException:
        if hasher is not None:
            hasher.cancel()
        raise
    sha256 = "" if hasher is None else hasher.hexdigest()
    scan = feeder.started()
    done = scan.finish()
    if done is None:
        return None
    seg, kept = done
    seg.gap_rows = [int(r) for r in scan.before_gaps[:, 0]] if len(scan.before_gaps) else []
    timed, warm = lay.time is not None, lay.temperature is not None
    log = Log(
        lay,
        kept.values,
        kept.ints[:, 0],
        kept.floats[:, 0] if timed else None,
        None,
        sha256,
        kept.floats[:, 1 if timed else 0] if warm else None,
        feeder.scale,
        lines=kept.ints[:, 1:3],
        extremes=feeder.extremes(),
        runs=(kept.run_first, kept.run_at),
    )
    return log, seg


class _Digest:
    """The file's SHA-256, taken on a thread of its own (the main thread feeds the Scan), a few
    blocks behind at most (the blocks waiting are held in memory)."""

    def __init__(self) -> None:
        self._sha = hashlib.sha256()
        self._thread = ThreadPoolExecutor(max_workers=1)
        self._waiting: deque[Future[None]] = deque()

    def update(self, text: bytes) -> None:
        self._waiting.append(self._thread.submit(self._sha.update, text))  # in order: one thread
        while len(self._waiting) > 8:
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
        self, parsed: FloatArray, empty: BoolArray, lines: Offsets | IntArray, timed: bool, shared: _Shared
    ) -> None:
        keep = ~empty if empty.any() else None  # an interleaved logger's rows of another sensor: not readings
        self.lines = int(empty.size)  # lines in the block: all of them data rows (plain lines)
        # a time or temperature cell that is empty or not finite on any row, one without readings
        # too: the whole read judges the whole column (an error, or no clock at all with --rate)
        self.columns_ok = bool(np.isfinite(parsed[:, 3:]).all())
        parsed = parsed if keep is None else parsed[keep]
        self.values: FloatArray = parsed[:, :3]  # a view: the scan copies what it keeps
        self.clock: FloatArray | None = parsed[:, 3] if timed else None
        self.temp: FloatArray | None = parsed[:, 3 + timed] if parsed.shape[1] > 3 + timed else None
        # data row (from the block's first), its line's first byte and the byte after its line end
        self.ints: IntArray = np.empty((len(self.values), 3), dtype=lines.dtype)
        self.ints[:, 0] = np.arange(self.lines) if keep is None else np.flatnonzero(keep)
        self.ints[:, 1:] = lines if keep is None else lines[keep]
        extra = [c for c in (self.clock, self.temp) if c is not None]
        self.floats: FloatArray = np.column_stack(extra) if extra else np.zeros((len(self.values), 0))
        self.finite = bool(np.isfinite(self.values).all())
        self.lo = float(self.values.min()) if self.values.size and self.finite else 0.0
        self.hi = float(self.values.max()) if self.values.size and self.finite else 0.0
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

    def __init__(self, lay: sniff.Layout, settings: Settings, time_unit: str, rate: float | None, size: int):
        self.lay, self.settings, self.time_unit, self.rate, self.size = lay, settings, time_unit, rate, size
        self.scan: Scan | None = None
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
        scan = self.scan = Scan(sample_period(seconds, self.rate), self.settings, capacity=capacity)
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
        scan.feed(block.values, seconds, block.floats, block.ints, inside)

    def extremes(self) -> FloatArray:
        """What gate.integer_rails judges the whole log's readings by: the lowest, the highest,
        and one that is not a whole number (if any)."""
        return np.array([[self.lo] * 3, [self.hi] * 3, [self.lo if self.odd is None else self.odd] * 3])


def _capacity(first: list[_Block], size: int) -> int:
    """As many readings as the file may hold, by the first blocks' bytes per reading (and a margin)."""
    read = sum(int(b.ints[-1, 2] - b.ints[0, 1]) for b in first if len(b.ints))
    readings = sum(len(b.values) for b in first)
    return int(1.25 * size * readings / max(read, 1)) + (1 << 16)


def _blocks(
    path: str, lay: sniff.Layout, splicer: Splicer, where: list[int], hasher: _Digest | None, shared: _Shared
) -> Iterator[_Block]:
    """Each block of the file read and parsed on a pool of threads (numpy, pyarrow and the
    reads let go of the GIL), in file order, its rows numbered here; hashed here, in order."""

    blocks = cuts(path, len(lay.head), capture.BLOCK_BYTES)
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
            while len(pending) > workers + 2:
                row = yield from _numbered(pending.popleft(), row, hasher)
        while pending:
            row = yield from _numbered(pending.popleft(), row, hasher)


def _numbered(job: Future[tuple[_Block, bytes]], row: int, hasher: _Digest | None) -> Generator[_Block, None, int]:
    block, text = job.result()
    if hasher is not None:
        hasher.update(text)
    if row:
        block.ints[:, 0] += row
    yield block
    return row + block.lines


def _parse(
    splicer: Splicer, fd: int, at: int, length: int, where: list[int], size: int, timed: bool, shared: _Shared
) -> tuple[_Block, bytes]:
    text = os.pread(fd, length, at)
    if len(text) != length:
        raise _Plain  # the file changed while it was read
    found = splicer.read(text)
    if found is None:
        raise _Plain
    parsed, empty, newline = found
    lines = np.empty((newline.size, 2), dtype=np.int32 if size < NARROW else np.int64)  # the kept ints: half
    np.minimum(newline + 1 + at, size, out=lines[:, 1])  # a last line without its line end
    lines[0, 0] = at
    lines[1:, 0] = lines[:-1, 1]
    return _Block(parsed[:, where], empty, lines, timed, shared), text
