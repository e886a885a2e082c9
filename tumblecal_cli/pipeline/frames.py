"""Data in memory, for the Python API: DataFrames and (n, 3) arrays in, DataFrames out.

pandas is imported only by the functions that return a DataFrame; a DataFrame given in is read
through its own methods.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import itertools
import os
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from tumblecal_cli.core import arrays
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv import capture, posefile, readings, sniff
from tumblecal_cli.io.outputs import unsafe
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.pipeline.options import path_of

if TYPE_CHECKING:
    from collections.abc import Callable

    from tumblecal_cli.io.csv.readings import Samples
    from tumblecal_cli.pipeline.options import SolveOptions

#: A pandas DataFrame: pandas ships no types here, so to mypy it is Any (the one place that says so).
DataFrame: TypeAlias = Any
#: A JSON object the Python API returns (``to_dict``): read by key, each value as the calibration file has it.
JSONObject: TypeAlias = dict[str, Any]


def is_data(value: object) -> bool:
    """Whether ``value`` is readings in memory: a DataFrame (duck-typed: pandas is not imported
    for it) or a numpy array."""
    return isinstance(value, np.ndarray) or (hasattr(value, "columns") and hasattr(value, "iloc"))


_HELD = threading.Lock()  # (names are taken and given back from any thread: batch, Dask workers)


@contextlib.contextmanager
def in_memory(data: object, what: str) -> Iterator[str]:
    """``data`` where a capture's path goes, for the block: a path (text or os.PathLike) as it is;
    a DataFrame or an (n, k) array held as a source (io.sources.MEMORY) under ``<DataFrame>`` or
    ``<array>`` (``<DataFrame 2>`` ... when that is taken), read by the CSV rules (``table_of``);
    anything else an InputError saying ``what``."""
    if not is_data(data):
        yield path_of(data, what)
        return
    kind = "array" if isinstance(data, np.ndarray) else "DataFrame"
    with _HELD:
        name = next(n for k in itertools.count(1) if (n := f"<{kind}{f' {k}' if k > 1 else ''}>") not in sources.MEMORY)
        sources.MEMORY[name] = _maker(data, name)
    try:
        yield name
    finally:
        with _HELD:
            del sources.MEMORY[name]


def _maker(data: DataFrame, name: str) -> Callable[[ReadSpec, str | None], sources.Table]:
    def make(spec: ReadSpec, label_column: str | None) -> sources.Table:
        return table_of(data, name, spec, label_column)

    return make


def table_of(data: DataFrame, name: str, spec: ReadSpec, label_column: str | None = None) -> sources.Table:
    """The readings of a DataFrame (or an (n, k) array) by the rules a file's are read by: the
    sensor columns found by their names as a header's are (an array's: 3 columns are x, y, z, 4
    are t, x, y, z, as a headerless file's), the time, temperature and label columns likewise;
    rows whose sensor cells are all NaN left out (an empty row of an interleaved log). A cell
    that is not a number, or a row with some sensor cells empty, is an InputError naming its
    row and column; ``name`` is how messages name the data."""
    frame = not isinstance(data, np.ndarray)
    if frame:
        names, index = [str(c) for c in data.columns], data.index
    else:
        k = data.shape[1] if data.ndim == 2 else 0
        if k not in (3, 4) and not spec.columns:
            raise InputError(
                f"an array of readings is (n, 3): x, y, z, or (n, 4): t, x, y, z; got shape {data.shape}",
                file=name,
                hint="name its sensor columns by their indices: columns='0,1,2'",
            )
        names, index = (
            ["x", "y", "z"] if k == 3 else ["t", "x", "y", "z"] if k == 4 else [str(j) for j in range(k)],
            None,
        )
    lay = sniff.Layout(name, ",", names, frame, b"", 1, "\n")
    lay.sensor, lay.time = sniff.pick_columns(lay, spec.sensor, spec.columns, spec.prefer, spec.time_column)
    if spec.temperature_column is not None:
        lay.per_row_column = sniff.column_index(lay, spec.temperature_column, "--temperature-column")
    else:
        lay.per_row_column = next((j for j, n in enumerate(names) if n.lower() in sniff.TEMPERATURE_NAMES), None)
    if label_column is not None:
        lay.extra = sniff.column_index(lay, label_column, "column")
    sniff.no_column_twice(lay, spec.sensor, spec.columns, spec.prefer, spec.time_column, spec.temperature_column)

    def column(j: int) -> DataFrame:  # a Series, or an array's column
        return data.iloc[:, j] if frame else data[:, j]

    values = np.column_stack([numbers(column(j), names[j], name, index) for j in lay.sensor])
    blank = np.isnan(values)
    kept = ~blank.all(axis=1)
    partly = np.flatnonzero(blank.any(axis=1) & kept)
    if partly.size:
        i = int(partly[0])
        j = lay.sensor[int(np.argmax(blank[i]))]
        where = f"row {index[i]!r}" if index is not None else f"row {i}"
        raise InputError(
            f"empty sensor cell in a row whose other sensor cells are filled ({where}, column {names[j]})", file=name
        )

    def other(j: int | None) -> arrays.FloatArray | None:
        return None if j is None else numbers(column(j), names[j], name, index)[kept]

    labels = None
    if lay.extra is not None:
        cells = list(column(lay.extra))
        labels = ["" if _missing(cells[i]) else sniff.bare(str(cells[i])) for i in np.flatnonzero(kept)]
    values = values[kept]
    return sources.Table(
        (names[lay.sensor[0]], names[lay.sensor[1]], names[lay.sensor[2]]),
        values,
        clock=other(lay.time),
        time_unit=None if lay.time is None else sniff.unit_of_name(names[lay.time]),
        temperature=other(lay.per_row_column),
        labels=labels,
        sha256=hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest(),
    )


def numbers(cells: DataFrame, column: str, name: str, index: DataFrame = None) -> arrays.FloatArray:
    """A DataFrame's column (or an array's) as float64, NaN where it is empty: a cell that is not a
    number is an InputError naming it, its row (``index``: the DataFrame's) and ``column``."""
    out: arrays.FloatArray
    try:
        if hasattr(cells, "to_numpy"):
            out = np.asarray(cells.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)
        else:
            out = np.asarray(cells, dtype=np.float64)
        return out
    except (TypeError, ValueError):
        pass
    listed = list(cells.tolist())
    for i, cell in enumerate(listed):
        try:
            float(cell)
        except (TypeError, ValueError):
            if _missing(cell):
                continue
            where = f"row {index[i]!r}" if index is not None else f"row {i}"
            raise InputError(f"not a number: {sniff.quoted(cell)} ({where}, column {column})", file=name) from None
    raise InputError(f"not numbers (column {column})", file=name)


def _missing(cell: object) -> bool:
    """Whether a cell is empty: None, NaN, pandas.NA (whose comparisons are NA: no truth value)."""
    try:
        return bool(cell is None or cell != cell)
    except TypeError:
        return True


def samples_of(label: str, data: DataFrame, options: SolveOptions) -> Samples:
    """One pose from memory: a DataFrame (its sensor columns found as a file's header would be,
    or named by ``columns``) or an (n, 3) array; named ``<label>`` in messages and the file."""

    name = f"<{label}>"
    if isinstance(data, str | os.PathLike):  # a file, in a mapping of labels
        return read_pose(os.fspath(data), options)
    picked = ["x", "y", "z"]
    try:
        if hasattr(data, "columns") and hasattr(data, "to_numpy"):
            names = [str(c) for c in data.columns]
            triplet = sniff.sensor_triplet(names, sensor=options.read.sensor, columns=options.read.columns, name=name)
            picked = [names[i] for i in triplet]
            values = np.column_stack([numbers(data.iloc[:, i], names[i], name, data.index) for i in triplet])
        else:
            values = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(f"readings that are not numbers ({err})", file=name) from None
    if values.ndim != 2 or values.shape[1] != 3 or not len(values):
        raise InputError(f"a pose is (n, 3) readings, n >= 1; got shape {values.shape}", file=name)
    values = values[~np.isnan(values).all(axis=1)]  # rows with no reading, as in a file
    if not np.isfinite(values).all():
        raise InputError("a reading that is not a finite number", file=name)
    layout = sniff.Layout(name, ",", picked, True, b"", 1, "\n")
    digest = hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest()
    rows = np.arange(len(values), dtype=np.int64)
    log = readings.in_span(readings.Log(layout, values, rows, None, None, digest), options.read)  # --start/--end
    rate = options.read.rate
    duration = (len(log.values) / rate) if rate else None
    first, last = int(log.rows[0]), int(log.rows[-1])
    return readings.Samples(layout, log.values, (first, last), digest, duration, log=log)


def read_pose(path: str, options: SolveOptions) -> Samples:
    """A pose file ('-': stdin) read as solve's options say."""

    return posefile.read(path, options.read)


def read_capture(path: str | os.PathLike[str], *, no_header: bool = False) -> DataFrame:
    """A capture as a pandas DataFrame, read by the CSV rules of the command line (delimiter,
    header, comments, BOM and line ends detected; sensor cells checked): every column, integer,
    float or text, in the file's order."""
    import pandas as pd

    path = path_of(path, "read_capture reads a capture file")
    _, names, columns = capture.read_table(path, ReadSpec(no_header=no_header))
    return pd.DataFrame({name: col.to_pandas() for name, col in zip(names, columns, strict=True)})


def written_table(text: str) -> DataFrame:
    """The text of a CSV table tumblecal wrote (summary.csv, segments.csv) as a pandas DataFrame,
    each text cell as it was before its leading ``'`` kept a spreadsheet from taking it for a
    formula."""
    import pandas as pd

    frame = pd.read_csv(io.StringIO(text))
    for column in frame.columns:
        if not pd.api.types.is_numeric_dtype(frame[column]):
            frame[column] = frame[column].map(lambda v: unsafe(v) if isinstance(v, str) else v)
    return frame
