"""Sources of readings beside CSV: where a reader of another kind of file plugs in.

Every command that reads a log or a pose file does it through ``io.csv.readings`` (``read_log``,
``read_samples``, ``stream``), whatever the file: a CSV capture by ``io.csv.capture``, or a file a
registered :class:`Reader` claims (a binary autopilot log, a bag), which hands back its readings
as a :class:`Table`. A new kind of log is one module with one ``READER`` (an
``io.logs.reader.LogReader``) and one row in ``io.logs.FORMATS``: the registry (``READERS``)
imports that module only when a file it claims is read; the readings module turns its table into
the ``Log`` every command takes, judges its clock and temperature as it judges a CSV's, and names
it in every message.
"""

from __future__ import annotations

import importlib
import os
import stat
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, cast

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.logs import FORMATS, LogFormat
from tumblecal_cli.io.readspec import ReadSpec


@dataclass(frozen=True)
class Table:
    """A whole source's readings of one sensor: ``values`` (n, 3), one row per sample, the
    triplet's ``names`` (what a calibration records as its columns); each row's time in
    ``clock`` (in ``time_unit``: s, ms, us or ns) and temperature in °C where the source has
    them; a ``labels`` column where one was asked for; the source's ``sha256``; and ``notes``
    a person should be told (which stream was read, and why)."""

    names: tuple[str, str, str]
    values: FloatArray
    clock: FloatArray | None = None
    time_unit: str | None = "s"  # None: not known, judged as a CSV's time column is (readings.time_scale)
    temperature: FloatArray | None = None
    labels: list[str] | None = None
    sha256: str = ""
    notes: tuple[str, ...] = field(default_factory=tuple)
    #: the source says these readings were already corrected by a calibration (an autopilot's
    #: calibrated stream): a fit of them calibrates the residual, not the sensor
    corrected: bool = False
    #: the stream of the source they are (a log's: what --stream picked, and how its
    #: correction is told), for the messages about it
    stream: Stream | None = None

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != 3:
            raise ValueError(f"a Table's values are (n, 3), got shape {values.shape}")
        n = len(values)
        for what, column in (("clock", self.clock), ("temperature", self.temperature), ("labels", self.labels)):
            if column is not None and len(column) != n:
                raise ValueError(f"a Table's {what} has {len(column)} rows for {n} readings")
        object.__setattr__(self, "values", values)


@dataclass(frozen=True)
class Stream:
    """One stream a log holds (``tumblecal logs``): its ``name`` and ``instance`` (what
    ``--stream NAME[:INSTANCE]`` picks), the ``sensor`` it carries, its ``rows`` and ``rate`` (Hz,
    None when unknown), its ``units``, whether it is ``corrected`` by the autopilot and ``how``
    that is told (the field, parameter or convention, with its source)."""

    name: str
    instance: int | None
    sensor: str
    rows: int
    rate: float | None
    units: str
    corrected: bool
    how: str = ""

    @property
    def key(self) -> str:
        """What ``--stream`` takes to pick this stream."""
        return self.name if self.instance is None else f"{self.name}:{self.instance}"


class Reader(Protocol):
    """A kind of source: its ``kind`` (its name in messages), whether it reads a label column
    beside the readings (``labels``), whether it ``claims`` a file (by its name or its first
    bytes), the ``streams`` it holds, the one a spec reads (``pick``: by default
    :func:`pick` among its streams), and the readings of the sensor and stream ``spec`` names in
    it (``spec.stream``; ``label_column``: a text column to read beside them, where ``labels``).
    Errors are InputErrors naming the file. A class that subclasses it inherits ``pick`` and
    ``labels`` (False); mypy checks every reader registered against it."""

    @property
    def kind(self) -> str: ...

    @property
    def labels(self) -> bool:
        return False

    def claims(self, path: str, head: bytes) -> bool: ...

    def streams(self, path: str) -> list[Stream]: ...

    def pick(self, path: str, spec: ReadSpec) -> Stream:
        """The stream of ``path`` that ``spec`` reads (by default :func:`pick` among ``streams``)."""
        return pick(path, self.streams(path), spec)

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table: ...


@dataclass(frozen=True)
class Lazy(LogFormat):
    """A reader registered by its format's row (io.logs.LogFormat: ``module.READER``), its module
    imported only when a file it claims is read: ``tumblecal --help`` and the commands on CSV pay
    nothing for it. A package in ``needs`` not installed: exit 2 naming the extra."""

    labels = False  # a log's still blocks are found by the detector: its reader refuses a label column

    @classmethod
    def of(cls, row: LogFormat) -> Lazy:
        """The registry's entry for ``row``."""
        return cls(row.kind, row.module, row.magic, row.claim, row.extra, row.needs)

    def streams(self, path: str) -> list[Stream]:
        return self.load(path).streams(path)

    def pick(self, path: str, spec: ReadSpec) -> Stream:
        return self.load(path).pick(path, spec)

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table:
        return self.load(path).read(path, spec, label_column)

    def load(self, path: str) -> Reader:
        """The reader itself, its module imported now (an extra not installed: exit 2)."""
        try:
            module = importlib.import_module(self.module)
        except ModuleNotFoundError as err:
            missing = (err.name or "").partition(".")[0]
            if missing not in self.needs:
                raise
            raise InputError(
                f"reading a {self.kind} needs the {missing} package, which is not installed",
                file=path,
                hint=f"pip install 'tumblecal[{self.extra}]'",
            ) from None
        return cast("Reader", module.READER)


#: The readers of sources beside CSV, asked in order; a file none claims is read as CSV.
READERS: list[Reader] = [Lazy.of(row) for row in FORMATS]


def register(row: LogFormat) -> None:
    """Add a kind of log outside io.logs (a plugin, a test's stand-in), asked after those there:
    its module is imported when a file it claims is read. A kind registered already is refused."""
    if any(r.kind == row.kind for r in READERS):
        raise ValueError(f"a reader of {row.kind!r} is registered already")
    READERS.append(Lazy.of(row))


#: How much of a file a reader is shown to claim it.
HEAD = 64
#: Readings in memory (the Python API's DataFrames and arrays) are a source too: each held here
#: under a name in angle brackets (``<DataFrame>``) for the length of one call, with what makes
#: its table for a spec (the sensor and columns it asks for) and a label column
#: (pipeline.frames.in_memory). No file is opened for these names.
MEMORY: dict[str, Callable[[ReadSpec, str | None], Table]] = {}


class _InMemory(Reader):
    """The Reader of the names in MEMORY."""

    kind = "readings in memory"
    labels = True

    def claims(self, path: str, head: bytes) -> bool:
        return path in MEMORY

    def streams(self, path: str) -> list[Stream]:
        return []  # its columns are its one stream, as a CSV's

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table:
        return MEMORY[path](spec, label_column)


IN_MEMORY = _InMemory()


def reader_for(path: str, opener: Callable[[str], bytes] | None = None) -> Reader | None:
    """The reader that claims ``path`` (None: a CSV capture, or stdin: CSV is what a pipe holds)."""
    if path in MEMORY:
        return IN_MEMORY
    if path == "-" or not READERS:
        return None
    if opener is None and _stream_like(path):
        return None  # a pipe is read once, by the CSV reader: a look at its head would take it
    try:
        head = opener(path) if opener is not None else _head(path)
    except IsADirectoryError:
        head = b""  # a folder: a reader may claim it by name (a ROS 2 bag), else the CSV reader says what it is
    except OSError:
        return None  # the CSV reader opens it and says what is wrong
    return next((r for r in READERS if r.claims(path, head)), None)


def _stream_like(path: str) -> bool:
    """Whether ``path`` is a named pipe or a device (read once, as stdin is), not a file."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return stat.S_ISFIFO(mode) or stat.S_ISCHR(mode) or stat.S_ISSOCK(mode)


def _head(path: str) -> bytes:
    with open(path, "rb") as f:
        return f.read(HEAD)


def kinds() -> str:
    """The kinds of source the readers read, for messages: "PX4 ULog, ..."."""
    return ", ".join(r.kind for r in READERS)


def streams(path: str) -> list[Stream]:
    """The streams of the log ``path`` (``tumblecal logs``): an InputError when no reader claims it."""
    if path != "-" and not os.path.exists(path):
        raise InputError("no such file", file=path)
    reader = reader_for(path)
    if reader is None and os.path.isdir(path):
        raise InputError(f"is a directory, not a log ({kinds()})", file=path)
    if reader is None:
        raise InputError(
            f"not a log of a kind tumblecal reads by streams ({kinds()})",
            file=path,
            hint="a CSV capture is read as it is: its columns are its one stream (--columns, --sensor)",
        )
    return reader.streams(path)


def stream_of(path: str, spec: ReadSpec) -> Stream | None:
    """The stream of ``path`` that ``spec`` reads (None: a CSV capture, or stdin): its reader's
    ``pick`` (a reader may say more of what --stream names)."""
    reader = reader_for(path)
    if reader is None or reader is IN_MEMORY:
        return None
    return reader.pick(path, spec)


def parse_stream(text: str) -> tuple[str, int | None]:
    """``--stream NAME[:INSTANCE]`` as (name, instance): ``sensor_accel:1``, ``IMU:0``, ``/imu/data``."""
    name, colon, number = text.strip().rpartition(":")
    if colon and number.isdigit() and name:
        return name, int(number)
    if not text.strip():
        raise InputError("--stream takes NAME or NAME:INSTANCE, e.g. sensor_accel:1 (tumblecal logs FILE lists them)")
    return text.strip(), None


def pick(path: str, found: Sequence[Stream], spec: ReadSpec) -> Stream:
    """The stream of ``found`` (a log's) that ``spec`` asks for: ``spec.stream``'s, of
    ``spec.sensor`` (a stream carrying several sensors gives the one --sensor names); without
    --stream the log's one raw stream of that sensor with samples (or its one stream, raw or
    not). None, or several: an InputError listing them and the --stream that picks each."""
    sensor = spec.sensor
    if spec.stream is None:
        mine = [s for s in found if s.sensor == sensor and s.rows > 0]
        raw = [s for s in mine if not s.corrected]
        chosen = raw or mine
        if len(chosen) == 1:
            return chosen[0]
        if not chosen:
            raise InputError(
                f"the log holds no {sensor} stream with samples",
                file=path,
                hint=_listing(found, None) + " (tumblecal logs FILE); --sensor picks another sensor",
            )
        raise InputError(
            f"the log holds {len(chosen)} {'raw ' if raw else ''}{sensor} streams: "
            f"{', '.join(s.key for s in chosen)}; give one with --stream",
            file=path,
            hint=f"e.g. --stream {chosen[0].key}; tumblecal logs FILE lists them with their rows and rates",
        )
    name, instance = parse_stream(spec.stream)
    named = [s for s in found if s.name == name and (instance is None or s.instance == instance)]
    if not named:
        raise InputError(f"the log has no stream {spec.stream}", file=path, hint=_listing(found, None))
    fitting = [s for s in named if s.sensor == sensor]
    if not fitting:
        carried = ", ".join(sorted({s.sensor for s in named}))
        raise InputError(
            f"{spec.stream} carries {carried}, not the {sensor}",
            file=path,
            hint=f"give --sensor {named[0].sensor}, or a stream of the {sensor}: " + _listing(found, sensor),
        )
    if len(fitting) > 1:
        raise InputError(
            f"{spec.stream} has {len(fitting)} instances: {', '.join(s.key for s in fitting)}; name one",
            file=path,
            hint=f"e.g. --stream {fitting[0].key}",
        )
    if fitting[0].rows == 0:
        raise InputError(f"{fitting[0].key} has no samples in this log", file=path, hint=_listing(found, sensor))
    return fitting[0]


def _listing(found: Sequence[Stream], sensor: str | None) -> str:
    """The --stream of each stream with samples (of ``sensor``, or all)."""
    keys = dict.fromkeys(s.key for s in found if s.rows > 0 and (sensor is None or s.sensor == sensor))
    return "its streams: " + (", ".join(keys) if keys else "none with samples")
