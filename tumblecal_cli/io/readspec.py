"""How to read a source: one frozen value from the command line (or the Python API) down to
the reader, whatever the kind of source.

``ReadSpec`` holds what the user says of where the readings are and how the file is written:
the sensor whose triplet is read, its columns, the time column and its unit (or the rate),
the temperature column, the file's dialect, and the columns a calibration recorded. Every
reader takes one (``io.csv.capture.open_capture``, ``io.csv.readings.read_log`` and
``io.csv.logread.scan_log``); a reader of another kind of source (a binary log) takes the same
value and ignores what does not apply to it (``no_header``, ``dialect``).

The Python API names the same things as the command line's long options in snake case
(``ReadKeywords``); :func:`read_spec` is the one place a ReadSpec is made of them: solve's
options (``pipeline.options.SolveOptions.of``, for the command line, batch and the Python API),
segment's and noise's keywords, and (:func:`file_spec`) verify's and correct's.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypedDict, cast

from tumblecal_cli.errors import InputError


@dataclass(frozen=True)
class Dialect:
    """How a station wrote its file, where the sniffer should not guess (docs/reference/csv.md):
    ``skip_rows`` lines before the header (None: a metadata preamble is found by its field
    count), the ``decimal`` mark (None: a comma when every number of a ``;`` or tab separated
    file has one), and whether an incomplete last line (a logger stopped mid-write) is dropped."""

    skip_rows: int | None = None
    decimal: str | None = None
    drop_incomplete: bool = False

    def __post_init__(self) -> None:
        skip = self.skip_rows
        if skip is not None and (isinstance(skip, bool) or not isinstance(skip, int) or skip < 0):
            raise InputError(f"--skip-rows takes a whole number of 0 or more, got {skip!r}")
        if self.decimal not in (None, ".", ","):
            raise InputError(f"--decimal is '.' or ',', got {self.decimal!r}")


TIME_UNITS = ("auto", "s", "ms", "us", "ns")


@dataclass(frozen=True)
class ReadSpec:
    """How to read a source's readings (docs/reference/csv.md): ``sensor`` (accelerometer,
    gyroscope, magnetometer) names the triplet found by its column names unless ``columns``
    gives it; ``time_column`` and ``time_unit`` the clock (``rate`` in Hz when the clock is not
    to be used); ``temperature_column`` the temperature (else one of the usual names);
    ``prefer`` a calibration's recorded columns, used when a file has them all; ``stream``
    the stream of a log that holds several (``--stream NAME[:INSTANCE]``, io.sources), and
    ``allow_corrected`` whether a stream the autopilot already corrected may be read (a fit of
    it calibrates the residual, not the sensor: refused without it); ``start`` and
    ``end`` the part of the capture to read (--start/--end: :func:`bound`; None: its first or
    last reading); ``paired`` that the accelerometer and the gyroscope are read as one log's rows
    (the turns pipelines): a log that holds them in separate streams gives the gyroscope stream's
    samples and its instance's accelerometer resampled onto them (io.logs.ulog)."""

    sensor: str = "accelerometer"
    columns: tuple[str, ...] | None = None
    no_header: bool = False
    time_column: str | None = None
    time_unit: str = "auto"
    rate: float | None = None
    dialect: Dialect = field(default_factory=Dialect)
    temperature_column: str | None = None
    prefer: tuple[str, ...] | None = None
    stream: str | None = None
    allow_corrected: bool = False
    start: str | float | None = None
    end: str | float | None = None
    paired: bool = False

    def __post_init__(self) -> None:  # a list given in Python is kept as a tuple (a frozen value)
        for name in ("columns", "prefer"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, tuple):
                object.__setattr__(self, name, tuple(value))
        self.span()  # --start/--end judged before any file is read

    def span(self) -> tuple[Bound | None, Bound | None]:
        """--start and --end as :class:`Bound` (None where not given); a start that is not before
        the end (both seconds, or both rows) is an InputError."""
        start, end = bound(self.start, "--start"), bound(self.end, "--end")
        if start is not None and end is not None and start.row == end.row and not start.value < end.value:
            raise InputError(
                f"--start {start.text} is not before --end {end.text}",
                hint="--start is the first reading to use, --end the last (seconds, or data rows such as 1200r)",
            )
        return start, end


@dataclass(frozen=True)
class Bound:
    """One end of the part of a capture read (--start, --end): ``value`` seconds from the
    capture's first reading, or with ``row`` a 0-based data row (the rows a calibration's poses
    record); ``text`` as given, for messages."""

    value: float
    row: bool
    flag: str
    text: str


#: --start/--end: seconds (an optional ``s``), or a data row (a whole number and ``r``).
BOUND = re.compile(r"\s*(?P<number>[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(?P<unit>[sSrR]?)\s*")


def bound(value: str | float | None, flag: str) -> Bound | None:
    """``value`` of ``flag`` (--start, --end) as a Bound: a number is seconds from the capture's
    first reading (its time column, or --rate); text is seconds (``2.5``, ``2.5s``) or, with an
    ``r``, a 0-based data row (``1200r``). Anything else is one InputError naming the flag."""
    if value is None:
        return None
    usage = "seconds from the capture's first reading (2.5) or a 0-based data row (1200r)"
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise InputError(f"{flag} takes {usage}, not a {type(value).__name__}")
    text = value if isinstance(value, str) else f"{value:g}"
    found = BOUND.fullmatch(value) if isinstance(value, str) else None
    if isinstance(value, str) and found is None:
        raise InputError(f"{flag} {value!r}: give {usage}")
    number = float(found.group("number")) if found is not None else float(value)
    row = found is not None and found.group("unit") in ("r", "R")
    if not (math.isfinite(number) and number >= 0) or (row and not number.is_integer()):
        raise InputError(f"{flag} {text}: give {usage}")
    return Bound(number, row, flag, text.strip())


def column_list(value: str | Sequence[str] | None) -> tuple[str, ...] | None:
    """``--columns`` as given (``"ax,ay,az"``, or a sequence in Python) as names; empty is none."""
    if value is None or value == "":
        return None
    return tuple(value.split(",")) if isinstance(value, str) else tuple(str(c) for c in value)


class FileKeywords(TypedDict, total=False):
    """How the Python API's functions are told a file's shape and its sensor columns: the
    command line's long options in snake case (verify and correct: the sensor is the
    calibration's)."""

    columns: str | Sequence[str] | None
    no_header: bool
    skip_rows: int | None
    decimal: str | None
    drop_incomplete: bool


class StreamKeywords(TypedDict, total=False):
    """Which stream of a log (a PX4 ULog's ``sensor_accel:1``: ``--stream``), and whether one the
    autopilot already corrected may be read (``--allow-corrected``; io.sources)."""

    stream: str | None
    allow_corrected: bool


class ReadKeywords(FileKeywords, StreamKeywords, total=False):
    """... and the sensor and the clock: all a ``ReadSpec`` holds (``read_spec`` makes one)."""

    sensor: str
    time_column: str | None
    time_unit: str
    rate: float | None
    start: str | float | None
    end: str | float | None


#: The keywords of a ReadSpec, in the order the command line lists them.
READ_NAMES = tuple(ReadKeywords.__annotations__)
#: ... of which these say the file's shape and its sensor columns alone.
FILE_NAMES = tuple(FileKeywords.__annotations__)


def read_spec(given: ReadKeywords, prefer: Sequence[str] | None = None) -> ReadSpec:
    """The ReadSpec of a function's keyword options (``prefer``: a calibration's columns); what is
    not given takes ReadSpec's default. Judged as the fields are: the columns, the dialect, then
    --start and --end."""
    return ReadSpec(
        sensor=given.get("sensor", "accelerometer"),
        columns=column_list(given.get("columns")),
        no_header=given.get("no_header", False),
        time_column=given.get("time_column"),
        time_unit=given.get("time_unit", "auto"),
        rate=given.get("rate"),
        dialect=Dialect(given.get("skip_rows"), given.get("decimal"), given.get("drop_incomplete", False)),
        prefer=None if prefer is None else tuple(prefer),
        stream=given.get("stream"),
        allow_corrected=given.get("allow_corrected", False),
        start=given.get("start"),
        end=given.get("end"),
    )


def file_spec(given: FileKeywords, prefer: Sequence[str] | None = None) -> ReadSpec:
    """:func:`read_spec` of the keywords on a file's shape and its sensor columns alone (the
    sensor and the clock left at their defaults: a command that reads the sensor a calibration
    names)."""
    return read_spec(cast(ReadKeywords, {k: v for k, v in given.items() if k in FILE_NAMES}), prefer)
