"""Data in memory, for the Python API: DataFrames and (n, 3) arrays in, DataFrames out.

pandas is imported only by the functions that return a DataFrame; a DataFrame given in is read
through its own methods.
"""

from __future__ import annotations

import hashlib
import io
import os
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from tumblecal_cli.errors import InputError
from tumblecal_cli.io import capture, readings, sniff
from tumblecal_cli.io.outputs import unsafe
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.pipeline.options import path_of

if TYPE_CHECKING:
    from tumblecal_cli.io.readings import Samples
    from tumblecal_cli.pipeline.options import SolveOptions

#: A pandas DataFrame: pandas ships no types here, so to mypy it is Any (the one place that says so).
DataFrame: TypeAlias = Any
#: A JSON object the Python API returns (``to_dict``): read by key, each value what README's format says.
JSONObject: TypeAlias = dict[str, Any]


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
            values = np.asarray(data.iloc[:, list(triplet)].to_numpy(dtype=np.float64, na_value=np.nan))
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

    return readings.read_samples(path, options.read)


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
