"""Readings in memory: a pose file's ``Samples`` and a whole ``Log``, with their clock.

``read_log`` streams a capture (``io.csv.capture``) into arrays: the sensor triplet of every
non-empty row, its data row, the time column (its unit judged by ``time_scale``), the
temperature and a label column; ``read_samples`` is the same for a pose file.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.core.blocks import Block
from tumblecal_cli.core.running import Summary
from tumblecal_cli.core.scan import log_index
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv.capture import BLOCK_BYTES, Capture, cast_floats, open_capture, to_floats, unquote
from tumblecal_cli.io.csv.sniff import NUMBER, TEMPERATURE_NAMES, TIME_SCALE, UNIT_WORDS, Layout, bare, quoted
from tumblecal_cli.io.readspec import Bound, ReadSpec
from tumblecal_cli.io.sources import Table


@dataclass(frozen=True)
class Samples:
    """The sensor readings of one capture (or of one block of a log), empty rows dropped."""

    layout: Layout
    values: FloatArray  # (n, 3) raw units
    rows: tuple[int, int]  # first and last data row used (0-based, inclusive)
    sha256: str
    duration: float | None  # seconds spanned by the time column (or --rate), if known
    temperature: float | None = None  # mean of the temperature column, if there is one
    block: int | None = None  # the block's number, for a pose cut from a log
    times: tuple[float, float] | None = None  # a block's first and last time, when the log has them
    row: bool = False  # one row of a table of orientations (its data row: rows[0])
    #: The capture these readings are (a pose file read whole, or its part from --start to --end):
    #: its rows and clock, for a part of it (a pose file's still run: pipeline.solve.trimming).
    log: Log | None = None
    #: A long pose file's running sums (io.csv.posefile): what its checks read, not ``values``.
    summary: Summary | None = None

    @property
    def readings(self) -> FloatArray | Summary:
        """What a still pose's statistics and checks are taken from: the running sums of a long
        pose file, else its readings."""
        return self.values if self.summary is None else self.summary

    @property
    def name(self) -> str:
        """How messages name this pose: its file, and its block when cut from a log (its row,
        counted from 1, when it is one row of a table)."""
        if self.row:
            return f"{self.layout.name} row {self.rows[0] + 1}"
        return self.layout.name if self.block is None else f"{self.layout.name} block {self.block}"


@dataclass(frozen=True)
class Log:
    """A whole log in memory: the sensor readings of every non-empty row, with their data row,
    time (``clock``: the time column in its own unit, ``scale`` seconds each) and label. A log
    read block by block (io.csv.logread) holds each still block's first and last reading only
    (``at``): read a block's position through ``row``, ``time``, ``line_span`` and ``block``,
    not by indexing the arrays."""

    layout: Layout
    values: FloatArray  # (n, 3)
    rows: NDArray[np.int64]  # data row (0-based) of each reading (int32 from io.csv.logread)
    clock: FloatArray | None
    labels: list[str] | None
    sha256: str
    temperature: FloatArray | None = None
    scale: float = 1.0
    #: Each reading's line in the file: its first byte and the byte after its line end (a log
    #: read block by block, io.csv.logread; int32 for a file under 2 GiB, as its rows).
    lines: NDArray[np.int64] | None = None
    #: ... and then what the whole log's readings are judged by for their integer type
    #: (gate.integer_rails): the lowest, the highest, and one that is not a whole number if any;
    extremes: FloatArray | None = None
    #: and where each run of the still periods' readings starts among the whole log's and among
    #: those (the positions a block's ``first`` and ``last`` are).
    runs: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None
    #: Seconds from the capture's first reading to the first one here (a part read from --start).
    first_s: float = 0.0
    #: A log read block by block keeps each block's first and last reading only (io.csv.logread):
    #: ``values``, ``rows``, ``clock``, ``temperature`` and ``lines`` hold those, in order, and
    #: ``at`` is the position of each among the readings of the still periods (what a block's
    #: ``first`` and ``last`` index); ``reread`` reads a block's readings again from its lines.
    at: NDArray[np.int64] | None = None
    reread: Callable[[int, int, int], Stretch] | None = None

    def _entry(self, position: int) -> int:
        """Where the reading at ``position`` is in this log's arrays."""
        if self.at is None:
            return position
        k = int(np.searchsorted(self.at, position))
        if k >= self.at.size or int(self.at[k]) != position:
            raise IndexError(f"reading {position} of {self.layout.name} is not kept: only each block's first and last")
        return k

    def row(self, position: int) -> int:
        """The data row (0-based) of the reading at ``position``."""
        return int(self.rows[self._entry(position)])

    def time(self, position: int) -> float | None:
        """The time cell (in its own unit) of the reading at ``position``, if the log has a clock."""
        return None if self.clock is None else float(self.clock[self._entry(position)])

    def line_span(self, first: int, last: int) -> tuple[int, int] | None:
        """Where the lines of readings ``first``..``last`` are in the file: the first's first
        byte and the byte after the last's line end (a log read block by block)."""
        if self.lines is None:
            return None
        return int(self.lines[self._entry(first), 0]), int(self.lines[self._entry(last), 1])

    def reading(self, position: int) -> int:
        """The index among the whole log's readings of the reading at ``position`` here (the
        same, unless the log was read block by block and only its still periods kept)."""
        if self.runs is None:
            return position

        return int(log_index(*self.runs, position))

    def seconds(self) -> FloatArray | None:
        """Seconds since the first reading (differences first: epoch nanoseconds keep their digits)."""
        return None if self.clock is None else (self.clock - self.clock[0]) * self.scale

    def block(self, number: int, first: int, last: int) -> Samples:
        """Readings ``first``..``last`` (inclusive) as a pose."""
        span = self.line_span(first, last)
        if self.reread is not None and span is not None:
            found = self.reread(*span, last - first + 1)
            values, clock, temp = found.values, found.clock, found.temperature
        else:
            values, clock, temp = self.values[first : last + 1], self.clock, self.temperature
            clock = None if clock is None else clock[first : last + 1]
            temp = None if temp is None else temp[first : last + 1]
        times = None if clock is None else (float(clock[0]), float(clock[-1]))
        return Samples(
            self.layout,
            values,
            (self.row(first), self.row(last)),
            self.sha256,
            None if clock is None else float(clock[-1] - clock[0]) * self.scale,
            None if temp is None else float(temp.mean()),
            block=number,
            times=times,
        )

    def summarised(self, block: Block) -> Samples:
        """A block of a log read block by block as a pose, from the statistics the scan found
        (its count, mean, spread and drift): none of its readings read again. For a solver of
        means, on readings that are not whole numbers (no integer rails to judge), judged
        without a full scale: those ask for the readings (``block``)."""
        first, last = block.first, block.last
        clock = (
            None
            if self.clock is None
            else (float(self.clock[self._entry(first)]), float(self.clock[self._entry(last)]))
        )
        n = block.samples
        lo, hi = (0.0, 0.0) if self.extremes is None else (float(self.extremes[0, 0]), float(self.extremes[1, 0]))
        summary = BlockSummary(
            values=np.empty((0, 3)),
            ends=[n],
            sums=[block.mean * n],
            lows=[lo],
            highs=[hi],
            peaks=[max(-lo, hi)],
            whole=False,
            count=n,
            mean=block.mean,
            spread=block.std,
            change=block.drift,
        )
        return Samples(
            self.layout,
            np.empty((0, 3)),
            (self.row(first), self.row(last)),
            self.sha256,
            None if clock is None else (clock[1] - clock[0]) * self.scale,
            None,
            block=block.number,
            times=clock,
            summary=summary,
        )


@dataclass
class BlockSummary(Summary):
    """A log's still block as the scan measured it (io.csv.logread): its count, sum, spread
    (``spread``: each axis's standard deviation) and drift (``change``); the log's lowest and
    highest reading stand for the block's (judged only where no integer rails or full scale are)."""

    spread: FloatArray = field(default_factory=lambda: np.zeros(3))
    change: FloatArray = field(default_factory=lambda: np.zeros(3))

    @property
    def std(self) -> FloatArray:
        return self.spread

    def drift(self) -> FloatArray:
        return self.change


@dataclass(frozen=True)
class Stretch:
    """The readings of a stretch of a log's lines, read again (io.csv.logread): a block's."""

    values: FloatArray  # (n, 3)
    clock: FloatArray | None
    temperature: FloatArray | None


def read_samples(path: str, spec: ReadSpec | None = None) -> Samples:
    """Read the sensor columns of a small capture (a pose file) into memory, by ``spec``."""
    spec = spec or ReadSpec()
    log = read_log(path, spec, use_time=False)
    rate = spec.rate
    t, used = log.clock, log.rows
    duration = None
    if t is not None:
        duration = float(t[-1] - t[0]) * log.scale if np.isfinite(t[[0, -1]]).all() else None
    elif rate:
        duration = (used[-1] - used[0] + 1) / rate
    temp = log.temperature
    temperature = float(temp.mean()) if temp is not None and np.isfinite(temp).all() else None
    part = t is not None and spec.span() != (None, None)  # --start/--end: the times of the part, as a block's
    times = (float(t[0]), float(t[-1])) if part and t is not None else None
    return Samples(
        log.layout, log.values, (int(used[0]), int(used[-1])), log.sha256, duration, temperature, times=times, log=log
    )


def read_log(
    path: str,
    spec: ReadSpec | None = None,
    *,
    label_column: str | None = None,
    use_time: bool = True,
    name: str | None = None,
    digest: bool = True,
    need_temperature: bool = False,
) -> Log:
    """Read a whole capture into memory by ``spec`` (a log to segment, or a pose file). With
    ``use_time`` its time column must hold numbers that never go backwards (else a time cell
    that is not a number leaves ``clock`` unknown); ``label_column`` is read as text; ``digest``
    off leaves ``sha256`` empty (a second pass over the file saved). ``need_temperature``: the
    temperature column (``spec.temperature_column``, else one of TEMPERATURE_NAMES) must be
    there and hold a number on every row with sensor values (an error names the line and
    column)."""
    spec = spec or ReadSpec()
    reader = sources.reader_for(path)
    if reader is not None:  # a source beside CSV (io.sources)
        table = reader.read(path, spec, label_column)
        log = from_table(table, name or path, spec, use_time=use_time, need_temperature=need_temperature)
        return in_span(log if digest else replace(log, sha256=""), spec)
    time_unit = spec.time_unit
    with open_capture(path, spec, name=name, extra=label_column) as cap:
        lay = cap.layout
        if need_temperature:
            _require_temperature(lay)
        readings = _Readings(_file_bytes(path))
        keep, times, temps, labels = [], [], [], []
        floats: list[FloatArray] | None = []  # the time column as numbers, when it is not judged
        for first_row, cols in cap.batches(only_sensor=True):
            values, empty = cap.finite_values(cols, first_row)
            readings.add(values)
            keep.append(~empty)
            k = 3
            if lay.time is not None and use_time:
                times.append((first_row, cols[k]))
            elif lay.time is not None and floats is not None:
                floats = _as_floats(cap, cols[k], floats)
            k += lay.time is not None
            if lay.per_row_column is not None:
                temps.append(cap.temperature_values(cols[k], first_row, empty) if need_temperature else cols[k])
                k += 1
            if lay.extra is not None:
                labels.extend(cols[k].to_pylist())
        values = readings.done()
        mask = np.concatenate(keep) if keep else np.zeros(0, dtype=bool)
        every = bool(mask.all())  # no empty rows (the usual case): no copies to drop them
        used = np.flatnonzero(mask).astype(np.int64, copy=False)  # (intp: no copy on 64-bit)
        if used.size == 0:
            raise InputError(
                "no rows with sensor values", file=lay.name, hint=f"columns read: {', '.join(lay.sensor_names)}"
            )
        t = None
        if times:
            t = _times(cap, times, None if every else mask)
        elif lay.time is not None and floats:  # None: a time cell that is not a number, the duration unknown
            t = np.concatenate(floats)[mask]
        temperature = _temperatures(cap, temps, mask) if temps else None
        text = None if lay.extra is None else [bare(str(labels[i] or "")) for i in used]
        sha256 = cap.sha256() if digest else ""
    scale = TIME_SCALE.get(time_unit, 1.0)
    if t is not None:
        try:
            scale = time_scale(lay, t, time_unit)
        except InputError:
            if use_time:
                raise
            scale = TIME_SCALE[lay.time_unit or "s"]  # the time column is not used (--rate): no judgement
    return in_span(Log(lay, values if every else values[mask], used, t, text, sha256, temperature, scale), spec)


def in_span(log: Log, spec: ReadSpec) -> Log:
    """The readings of ``log`` from --start to --end (``spec.span``), both included, with a note
    saying which; the log itself when neither is given. Seconds count from the capture's first
    reading, by --rate when given, else by the time column. A part that holds no reading, or
    seconds with neither a time column nor a rate, is an InputError naming the flag."""
    start, end = spec.span()
    if start is None and end is None:
        return log
    n, name = len(log.values), log.layout.name
    seconds = np.arange(n) / spec.rate if spec.rate else log.seconds()

    def where(b: Bound, after: bool) -> BoolArray:  # the readings at or after (before) the bound
        if b.row:
            return log.rows >= b.value if after else log.rows <= b.value
        if seconds is None:
            row = b.text.rstrip("sS")
            raise InputError(
                f"{b.flag} {b.text}: seconds need a time column or --rate",
                file=name,
                hint=f"give --rate HZ, or a data row ({row}r is data row {row})",
            )
        return seconds >= b.value if after else seconds <= b.value

    def at(i: int, j: int | None = None) -> str:  # a reading, or readings i to j, as a person finds them
        rows = f"{int(log.rows[i])}" + ("" if j is None else f"-{int(log.rows[j])}")
        if seconds is None:
            return rows
        return f"{rows} ({float(seconds[i]):.4g}" + ("" if j is None else f"-{float(seconds[j]):.4g}") + " s)"

    first, last = 0, n - 1
    if start is not None:
        after = where(start, True)
        if not after.any():
            raise InputError(f"--start {start.text} is past the capture's last reading, row {at(n - 1)}", file=name)
        first = int(np.argmax(after))
    if end is not None:
        before = where(end, False)
        if not before.any():
            raise InputError(f"--end {end.text} is before the capture's first reading, row {at(0)}", file=name)
        last = n - 1 - int(np.argmax(before[::-1]))
    if last < first:
        told = " and ".join(f"{b.flag} {b.text}" for b in (start, end) if b is not None)
        raise InputError(f"{told} hold no reading", file=name)
    log.layout.notes.append(f"{name}: --start/--end: read rows {at(first, last)} of {at(0, n - 1)}")
    part = slice(first, last + 1)
    return replace(
        log,
        values=log.values[part],
        rows=log.rows[part],
        clock=None if log.clock is None else log.clock[part],
        labels=None if log.labels is None else log.labels[part],
        temperature=None if log.temperature is None else log.temperature[part],
        first_s=log.first_s + (0.0 if seconds is None else float(seconds[first])),
    )


def _file_bytes(path: str) -> int | None:
    """The size of a regular file (None: stdin, a pipe, or not a file here)."""
    try:
        return os.path.getsize(path) if path != "-" and os.path.isfile(path) else None
    except OSError:
        return None


class _Readings:
    """A capture's readings as its blocks are read, in one buffer (not a list of blocks joined
    at the end: that held every reading twice). A regular file's buffer is sized from its first
    block's rows per byte, with room to spare that costs nothing until it is written; it grows
    by half when that was too little (a stream's, from its first block on)."""

    def __init__(self, size: int | None) -> None:
        self.size = size
        self.buffer: FloatArray = np.empty((0, 3))
        self.count = 0

    def add(self, values: FloatArray) -> None:
        end = self.count + len(values)
        if end > len(self.buffer):
            guess = end + end // 2
            if self.count == 0 and self.size is not None:
                guess = max(guess, int(len(values) * 1.5 * (self.size / BLOCK_BYTES + 1)))
            grown = np.empty((guess, 3))
            grown[: self.count] = self.buffer[: self.count]
            self.buffer = grown
        self.buffer[self.count : end] = values
        self.count = end

    def done(self) -> FloatArray:
        return self.buffer[: self.count]


def _as_floats(cap: Capture, column: pa.Array, floats: list[FloatArray]) -> list[FloatArray] | None:
    """``floats`` with one more block of a time column that is not judged (--rate), read as
    numbers; None once a cell is not a number (the duration is then unknown)."""
    try:
        floats.append(to_floats(cast_floats(cap.pointed(column), safe=False)))
    except pa.ArrowInvalid:
        return None
    return floats


def from_table(table: Table, name: str, spec: ReadSpec, *, use_time: bool, need_temperature: bool) -> Log:
    """The Log of a source a reader of another kind read (io.sources): its readings judged as a
    CSV's are (finite numbers; a clock that never goes back, its unit judged; a temperature on
    every row where one is needed), each problem named by the file and the reading's row."""
    if table.corrected and not spec.allow_corrected:
        raise _corrected(table, name)
    names = [*table.names]
    time = temperature = extra = None
    if table.clock is not None:
        time, names = len(names), [*names, "time"]
    if table.temperature is not None:
        temperature, names = len(names), [*names, "temperature"]
    if table.labels is not None:
        extra, names = len(names), [*names, "label"]
    lay = Layout(name, ",", names, True, b"", 1, "\n", (0, 1, 2), time, temperature, extra, list(table.notes))
    lay.time_unit = table.time_unit
    values = table.values
    if len(values) == 0:
        raise InputError("no rows with sensor values", file=name, hint=f"columns read: {', '.join(table.names)}")
    bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
    if bad.size:
        raise InputError(f"reading {int(bad[0]) + 1} ({table.names[0]}...) is not a finite number", file=name)
    if need_temperature:
        _require_temperature(lay)
        assert table.temperature is not None
        hot = np.flatnonzero(~np.isfinite(table.temperature))
        if hot.size:
            raise InputError(f"reading {int(hot[0]) + 1} has no temperature", file=name)
    clock = None if table.clock is None else np.asarray(table.clock, dtype=np.float64)
    scale = TIME_SCALE[table.time_unit or "s"]
    if clock is not None and use_time:
        back = np.flatnonzero(np.diff(clock) < 0)
        if back.size or not np.isfinite(clock).all():
            at = int(back[0]) + 2 if back.size else int(np.flatnonzero(~np.isfinite(clock))[0]) + 1
            raise InputError(
                f"the clock goes back or is not a number at reading {at}", file=name, hint="give --rate HZ"
            )
        scale = time_scale(lay, clock, spec.time_unit)
    rows = np.arange(len(values), dtype=np.int64)
    return Log(lay, values, rows, clock, table.labels, table.sha256, table.temperature, scale)


def _corrected(table: Table, name: str) -> InputError:
    """The refusal of a stream corrected before it was logged (by an autopilot, a filter), and how that is told."""
    stream = table.stream
    what = "these readings are" if stream is None else f"{stream.key} ({stream.sensor}) is"
    how = "" if stream is None or not stream.how else f" ({stream.how})"
    return InputError(
        f"{what} already corrected before it was logged{how}: a fit of it calibrates the residual, not the sensor",
        file=name,
        hint="read a raw stream (tumblecal logs FILE lists them: --stream NAME:INSTANCE), "
        "or give --allow-corrected to fit the residual all the same",
    )


def _require_temperature(lay: Layout) -> None:
    if lay.per_row_column is None:
        raise InputError(
            f"no temperature column (looked for {', '.join(TEMPERATURE_NAMES)})",
            file=lay.name,
            hint=f"name it with --temperature-column (columns: {', '.join(lay.names)})",
        )


def _temperatures(cap: Capture, temps: list[FloatArray] | list[pa.Array], mask: BoolArray) -> FloatArray | None:
    """The temperature column of the rows kept: blocks already read as numbers
    (``Capture.temperature_values``), or text, where a cell that is not a number leaves the
    temperature unknown (None)."""
    if isinstance(temps[0], np.ndarray):
        out: FloatArray = np.concatenate(temps)[mask]
        return out
    try:
        floats = [to_floats(cast_floats(cap.pointed(c), safe=False)) for c in temps]
    except pa.ArrowInvalid:
        return None
    found: FloatArray = np.concatenate(floats)[mask]
    return found


#: The seconds between samples of a sensor's log: 50 kHz to 0.1 Hz.
_PERIODS = (2e-5, 10.0)


def _epoch_unit(first: float, step: float) -> str | None:
    """The unit of a clock that counts from 1970 (years 2001-2286 in s, ms, µs or ns), when its
    spacing is a sensor's in that unit."""
    for unit, scale in TIME_SCALE.items():
        if 1e9 <= first * scale < 1e10 and _PERIODS[0] <= step * scale <= _PERIODS[1]:
            return unit
    return None


def time_scale(layout: Layout, clock: FloatArray, unit: str) -> float:
    """Seconds per unit of a log's time column: ``unit`` (--time-unit) when given; with "auto",
    the unit its name gives (``timestamp_ms``) unless its spacing contradicts it, else the unit of
    an epoch clock (1.7e18: ns), else the unit its spacing implies (a median step under 0.2: s;
    to 200: ms; to 2e5: µs; to 2e8: ns: each unit right from 5 Hz to 5 kHz), with a note. A clock
    that then advances less than 1/FASTEST s a sample is an error, whichever the unit."""
    step = _step(clock)
    if unit != "auto":
        return _not_too_fast(layout, step, TIME_SCALE[unit])
    assert layout.time is not None
    column, named = layout.names[layout.time], layout.time_unit
    if step is None:  # one reading, or a clock that never moves: nothing to judge by
        return TIME_SCALE[named or "s"]
    spaced = _epoch_unit(float(clock[0]), step) or next(
        (u for u, top in (("s", 0.2), ("ms", 200.0), ("us", 2e5), ("ns", 2e8)) if step <= top), None
    )
    hint = "give --time-unit s, ms, us or ns (or --rate HZ to use the sample rate instead)"
    if named is not None:
        period = step * TIME_SCALE[named]
        if _PERIODS[0] <= period <= _PERIODS[1]:
            return TIME_SCALE[named]
        raise InputError(
            f"time column {column!r} is named in {UNIT_WORDS[named]}, but it advances {step:g} per sample "
            f"(a sample every {period:.3g} s)" + (f"; its spacing suggests {UNIT_WORDS[spaced]}" if spaced else ""),
            file=layout.name,
            hint=hint,
        )
    if spaced is None:
        raise InputError(
            f"time column {column!r} advances {step:g} per sample: not seconds, ms, µs or ns at a sensor's rate",
            file=layout.name,
            hint=hint,
        )
    if spaced != "s":
        rate = 1.0 / (step * TIME_SCALE[spaced])
        layout.notes.append(
            f"{layout.name}: time column {column!r} read in {UNIT_WORDS[spaced]}: it advances {step:g} per sample "
            f"({rate:.4g} Hz); if it is not, give --time-unit"
        )
    return _not_too_fast(layout, step, TIME_SCALE[spaced])


#: The most samples a second a sensor's log is read at (as --rate's bound): a faster clock is
#: a wrong one, and its windows would be more samples than any integer holds.
FASTEST = 1e9


def check_rate(rate: float | None) -> None:
    """A --rate given is a positive number of Hz up to FASTEST; None is no rate given."""
    if rate is not None and not 0 < rate <= FASTEST:
        raise InputError(f"--rate must be a positive number of Hz up to {FASTEST:g}, got {rate:g}")


def _step(clock: FloatArray) -> float | None:
    """The median of the first 100,000 positive steps of a clock (None: it never moves)."""
    d = np.diff(clock[:100_001])
    d = d[d > 0]
    return float(np.median(d)) if d.size else None


def _not_too_fast(layout: Layout, step: float | None, scale: float) -> float:
    """``scale``, unless the clock then advances less than 1/FASTEST s per sample (a time column
    of steps of 1e-300: windows of 5e299 samples)."""
    if step is not None and step * scale < 1 / FASTEST:
        column = layout.names[layout.time] if layout.time is not None else "time"
        raise InputError(
            f"time column {column!r} advances {step:g} per sample: a sample every {step * scale:.3g} s, "
            f"faster than any sensor's clock (up to {FASTEST:g} Hz)",
            file=layout.name,
            hint="give --time-unit s, ms, us or ns (or --rate HZ to use the sample rate instead)",
        )
    return scale


def block_times(cap: Capture, first_row: int, column: pa.Array, empty: BoolArray) -> FloatArray:
    """One block's time column as numbers, on the rows with sensor values (a capture streamed
    block by block: its clock, core.clock)."""
    clock = _time_numbers(cap, first_row, column)
    return clock[~empty] if empty.any() else clock


def _time_numbers(cap: Capture, first_row: int, text: pa.Array) -> FloatArray:
    """One block's time cells as numbers, else an error naming the line of the first that is not."""
    lay = cap.layout
    assert lay.time is not None
    text = cap.pointed(text)
    try:
        return to_floats(cast_floats(text))
    except pa.ArrowInvalid:
        ok = pc.match_substring_regex(pc.utf8_trim_whitespace(unquote(text)), NUMBER)
        i = int(pc.index(ok, False).as_py())
        raise InputError(
            f"time is not a number: {quoted(text[i].as_py())}",
            file=lay.name,
            line=cap.line_of_row(first_row + i),
            column=lay.names[lay.time],
            hint="give the sample rate with --rate HZ instead of the time column (--time-column to pick another)",
        ) from None


def _times(cap: Capture, times: list[tuple[int, pa.Array]], mask: BoolArray | None) -> FloatArray:
    """A log's time column on the rows ``mask`` keeps (all when None): numbers that never go
    backwards, else an error naming the line. Rows without sensor values are not judged: an
    interleaved logger stamps each sensor's rows with its own clock."""
    lay = cap.layout
    assert lay.time is not None
    t = np.concatenate([_time_numbers(cap, first_row, text) for first_row, text in times])
    rows = np.arange(t.size) if mask is None else np.flatnonzero(mask)
    t = t if mask is None else t[mask]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        line = cap.line_of_row(int(rows[k]))
        raise InputError(
            f"time goes backwards: {float(t[k])!r} after {float(t[k - 1])!r}",
            file=lay.name,
            line=line,
            column=lay.names[lay.time],
            hint="sort the log by time, or split it where the logger restarted",
        )
    return t
