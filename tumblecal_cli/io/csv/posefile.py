"""A pose file read in memory that does not grow with it.

A pose is judged by running sums (core.running), not by its rows. ``read`` streams a CSV pose
file as ``io.csv.readings.read_samples`` reads it (the same rows, clock, temperature and notes);
up to SUMMED_ROWS readings it is that reader exactly, its readings in memory. A longer file's
readings, clock and rows go to unnamed files on disk (in ``$TMPDIR``, gone when the pose is,
or when the process ends however it ends) as they are read, each block's sums kept: the pose's
``summary`` is what every check of a still pose reads, and its ``values`` are the readings
mapped from disk, for what reads them again (a pose that moved and is cut to its still run, a
plot, a table of orientations). A stream (stdin, a compressed file) is read once, so its
readings are kept on disk the same way rather than read twice.
"""

from __future__ import annotations

import tempfile
from typing import IO, Generic, TypeVar

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.running import Summary
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv.capture import Capture, cast_floats, open_capture, to_floats
from tumblecal_cli.io.csv.readings import Log, Samples, read_samples, time_scale
from tumblecal_cli.io.csv.sniff import TIME_SCALE, Layout
from tumblecal_cli.io.outputs import spool_room
from tumblecal_cli.io.readspec import ReadSpec

#: A pose file of more readings than this is summed as it is read (its readings kept on disk).
SUMMED_ROWS = 1 << 18


N = TypeVar("N", np.float64, np.int64)


class _Room:
    """What a pose file may keep in $TMPDIR, all its columns together: outputs.spool_room when
    the first column spills (at most 4 GiB, and never the disk's last margin), so that an endless
    stdin ends with an error, not a full disk."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.bound: int | None = None
        self.used = 0

    def take(self, size: int) -> None:
        if self.bound is None:
            self.bound = spool_room(tempfile.gettempdir())
        self.used += size
        if self.used > self.bound:
            raise InputError(
                f"more than {self.bound / 2**20:.0f} MiB of readings to keep in {tempfile.gettempdir()} "
                "(at most 4 GiB, and the free space there less a margin): an endless stream?",
                file=self.name,
                hint="give a pose file of fewer rows (a pose needs seconds, not hours) or a TMPDIR with room",
            )


class _Column(Generic[N]):
    """One column of a capture's kept rows: in memory, until ``spill`` puts what it holds (and
    all that comes after) in an unnamed file on disk."""

    def __init__(self, room: _Room, dtype: type[N], width: int = 0) -> None:
        self.room = room
        self.name = room.name  # the pose file's, for an error
        self.dtype: type[N] = dtype
        self.width = width
        self.parts: list[NDArray[N]] = []
        self.file: IO[bytes] | None = None
        self.count = 0

    def add(self, part: NDArray[N]) -> None:
        part = np.ascontiguousarray(part, dtype=self.dtype)
        self.count += len(part)
        if self.file is None:
            self.parts.append(part)
        else:
            _write(self.file, part, self.room)

    def spill(self) -> None:
        try:
            self.file = tempfile.TemporaryFile(prefix="tumblecal-pose-")  # noqa: SIM115 (kept open: written as read)
        except OSError as err:
            raise _no_room(err, self.name) from None
        for part in self.parts:
            _write(self.file, part, self.room)
        self.parts = []

    def done(self) -> NDArray[N]:
        shape = (self.count, self.width) if self.width else (self.count,)
        if self.file is None:
            if not self.parts:
                return np.empty(shape, dtype=self.dtype)
            return np.concatenate(self.parts) if len(self.parts) > 1 else self.parts[0]
        _write(self.file, None, self.room)
        if not self.count:
            self.file.close()
            return np.empty(shape, dtype=self.dtype)
        mapped = np.memmap(self.file, dtype=self.dtype, mode="r", shape=shape)
        self.file.close()  # the mapping holds the data: the file goes with it
        return mapped


def _write(file: IO[bytes], part: NDArray[N] | None, room: _Room) -> None:
    """``part`` written to ``file`` (None: what is written flushed), within ``room``."""
    try:
        if part is None:
            file.flush()
        else:
            room.take(part.nbytes)
            file.write(part.tobytes())
    except OSError as err:
        raise _no_room(err, room.name) from None


def _no_room(err: OSError, name: str) -> InputError:
    """A long pose's readings that cannot be kept on disk (a full or read-only $TMPDIR)."""
    return InputError(
        f"its readings are kept in {tempfile.gettempdir()} as it is read (a long pose file): {err.strerror or err}",
        file=name,
        hint="free some space there, or set TMPDIR to a folder with room (about the pose file's size)",
    )


class _Read:
    """What ``read`` gathers, block by block."""

    def __init__(self, name: str, timed: bool, warm: bool) -> None:
        room = _Room(name)
        self.values, self.rows = _Column(room, np.float64, 3), _Column(room, np.int64)
        self.clock: _Column[np.float64] | None = _Column(room, np.float64) if timed else None
        self.temps: _Column[np.float64] | None = _Column(room, np.float64) if warm else None
        self.summary = Summary()
        self.temp_sum = 0.0
        self.seen = 0  # data rows read, kept or not

    def close(self) -> None:
        for c in self.columns():
            if c.file is not None:
                c.file.close()

    def columns(self) -> list[_Column[np.float64] | _Column[np.int64]]:
        return [c for c in (self.values, self.rows, self.clock, self.temps) if c is not None]

    def add(self, cap: Capture, cols: list[pa.Array], values: FloatArray, keep: NDArray[np.bool_]) -> None:
        every = bool(keep.all())
        kept = values if every else values[keep]
        self.values.add(kept)
        self.rows.add(self.seen + (np.arange(len(keep)) if every else np.flatnonzero(keep)))
        self.seen += len(keep)
        self.summary.add(kept)
        k = 3
        if cap.layout.time is not None:
            if self.clock is not None:
                self.clock, _ = _numbers(cap, cols[k], keep, self.clock)
            k += 1
        if self.temps is not None:
            self.temps, total = _numbers(cap, cols[k], keep, self.temps)
            self.temp_sum += total
        if self.values.file is None and self.values.count > SUMMED_ROWS:
            for c in self.columns():
                c.spill()


def _numbers(
    cap: Capture, text: pa.Array, keep: NDArray[np.bool_], column: _Column[np.float64]
) -> tuple[_Column[np.float64] | None, float]:
    """``column`` with one more block of a time or temperature column read as numbers (on the
    kept rows), and their sum; None once a cell is not a number (then unknown, as io.csv.readings
    leaves it)."""
    try:
        floats = to_floats(cast_floats(cap.pointed(text), safe=False))
    except pa.ArrowInvalid:
        if column.file is not None:
            column.file.close()
        return None, 0.0
    kept = floats if keep.all() else floats[keep]
    column.add(kept)
    return column, float(kept.sum())


def read(path: str, spec: ReadSpec | None = None) -> Samples:
    """A pose file's Samples, as ``io.csv.readings.read_samples`` reads them; a CSV file of more than
    SUMMED_ROWS readings with its ``summary`` (other sources, and a part of a file given by
    --start or --end, are read whole by read_samples)."""
    spec = spec or ReadSpec()
    if sources.reader_for(path) is not None or spec.span() != (None, None):
        return read_samples(path, spec)
    with open_capture(path, spec) as cap:
        lay = cap.layout
        got = _Read(lay.name, lay.time is not None, lay.per_row_column is not None)
        try:
            for first_row, cols in cap.batches(only_sensor=True):
                values, empty = cap.finite_values(cols, first_row)
                got.add(cap, cols, values, ~empty)
        except BaseException:
            got.close()  # the files of what was kept: an error (or ^C) ends the read
            raise
        if got.values.count == 0:
            raise InputError(
                "no rows with sensor values", file=lay.name, hint=f"columns read: {', '.join(lay.sensor_names)}"
            )
        sha256 = cap.sha256()
    return _samples(got, lay, sha256, spec)


def _samples(got: _Read, lay: Layout, sha256: str, spec: ReadSpec) -> Samples:
    """The Samples of what ``read`` gathered, as read_samples makes them."""
    summed = got.values.file is not None
    values = got.values.done()
    used = got.rows.done()
    t = None if got.clock is None else got.clock.done()
    temp = None if got.temps is None else got.temps.done()
    scale = TIME_SCALE.get(spec.time_unit, 1.0)
    if t is not None:
        try:
            scale = time_scale(lay, t, spec.time_unit)
        except InputError:
            scale = TIME_SCALE[lay.time_unit or "s"]  # the time column is not used (--rate): no judgement
    log = Log(lay, values, used, t, None, sha256, temp, scale)
    got.summary.values = values
    duration = None
    if t is not None:
        duration = float(t[-1] - t[0]) * scale if np.isfinite(t[[0, -1]]).all() else None
    elif spec.rate:
        duration = (used[-1] - used[0] + 1) / spec.rate
    temperature = None
    if temp is not None and not summed:
        temperature = float(temp.mean()) if np.isfinite(temp).all() else None
    elif temp is not None and np.isfinite(got.temp_sum):  # (not finite: some temperature is not)
        temperature = got.temp_sum / len(temp)
    return Samples(
        lay,
        values,
        (int(used[0]), int(used[-1])),
        sha256,
        duration,
        temperature,
        log=log,
        summary=got.summary if summed else None,
    )
