"""Sources of readings beside CSV: where a reader of another kind of file plugs in.

Every command that reads a log or a pose file does it through ``io.csv.readings`` (``read_log``,
``read_samples``, ``stream``), whatever the file: a CSV capture by ``io.csv.capture``, or a file a
registered :class:`Reader` claims (a binary autopilot log, a bag), which hands back its readings
as a :class:`Table`. A new kind of source is one module with one ``Reader``, appended to
``READERS``: the readings module turns its table into the ``Log`` every command takes, judges
its clock and temperature as it judges a CSV's, and names it in every message.
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
    """A kind of source: whether it ``claims`` a file (by its name or its first bytes), the
    ``streams`` it holds, and the readings of the sensor and stream ``spec`` names in it
    (``spec.stream``; ``label_column``: a text column to read beside them, when the source has
    one). Errors are InputErrors naming the file."""

    def claims(self, path: str, head: bytes) -> bool: ...

    def streams(self, path: str) -> list[Stream]: ...

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table: ...


@dataclass(frozen=True)
class Lazy:
    """A reader registered by its module's name (``module.READER``), imported only when a file it
    claims is read: ``tumblecal --help`` and the commands on CSV pay nothing for it. It claims a
    file by its first bytes (``magic``) or by ``claim`` (a function of the path and those bytes:
    a bag that is a folder). ``kind`` names the files in messages; ``extra`` is the pip extra that
    installs the packages in ``needs``: without them, reading such a file is exit 2 saying
    ``pip install 'tumblecal[extra]'``."""

    kind: str
    module: str
    magic: tuple[bytes, ...] = ()
    claim: Callable[[str, bytes], bool] | None = None
    extra: str | None = None
    needs: tuple[str, ...] = ()

    def claims(self, path: str, head: bytes) -> bool:
        if self.claim is not None:
            return self.claim(path, head)
        return any(head.startswith(m) for m in self.magic)

    def streams(self, path: str) -> list[Stream]:
        return self.load(path).streams(path)

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


def dataflash_text(path: str, head: bytes) -> bool:
    """An ArduPilot DataFlash log in its text form: its first line an FMT line."""
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"FMT,")


def ros_claim(path: str, head: bytes) -> bool:
    """A ROS 1 bag or an MCAP file by its first bytes, a ROS 2 bag's sqlite3 file (``.db3``), or a
    ROS 2 bag's folder (its metadata.yaml, or the .db3 or .mcap files of a recording cut short)."""
    if head.startswith((b"#ROSBAG V", b"\x89MCAP0\r\n")):
        return True
    if head or not os.path.isdir(path):
        return head.startswith(b"SQLite format 3\x00") and path.endswith(".db3")
    try:
        names = os.listdir(path)
    except OSError:
        return False
    return "metadata.yaml" in names or any(n.endswith((".db3", ".mcap")) for n in names)


#: The readers of sources beside CSV, asked in order; a file none claims is read as CSV.
READERS: list[Reader] = [
    Lazy("PX4 ULog", "tumblecal_cli.io.logs.ulog", magic=(b"ULog\x01\x12\x35",)),
    Lazy("ArduPilot DataFlash log", "tumblecal_cli.io.logs.dataflash", magic=(b"\xa3\x95\x80",)),
    Lazy("ArduPilot DataFlash text log", "tumblecal_cli.io.logs.dftext", claim=dataflash_text),
    Lazy("ROS bag or MCAP file", "tumblecal_cli.io.logs.ros", claim=ros_claim, extra="ros", needs=("rosbags",)),
]
#: How much of a file a reader is shown to claim it.
HEAD = 64
#: Readings in memory (the Python API's DataFrames and arrays) are a source too: each held here
#: under a name in angle brackets (``<DataFrame>``) for the length of one call, with what makes
#: its table for a spec (the sensor and columns it asks for) and a label column
#: (pipeline.frames.in_memory). No file is opened for these names.
MEMORY: dict[str, Callable[[ReadSpec, str | None], Table]] = {}


class _InMemory:
    """The Reader of the names in MEMORY."""

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
    return ", ".join(getattr(r, "kind", type(r).__name__) for r in READERS)


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
    """The stream of ``path`` that ``spec`` reads (None: a CSV capture, or stdin): the reader's own
    ``pick(path, spec)`` where it has one (to say more of what --stream names), else ``pick``."""
    reader = reader_for(path)
    if reader is None or reader is IN_MEMORY:
        return None
    own = getattr(reader.load(path) if isinstance(reader, Lazy) else reader, "pick", None)
    return cast("Stream", own(path, spec)) if own is not None else pick(path, reader.streams(path), spec)


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
