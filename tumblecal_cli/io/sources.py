"""Sources of readings beside CSV: where a reader of another kind of file plugs in.

Every command that reads a log or a pose file does it through ``io.readings`` (``read_log``,
``read_samples``, ``stream``), whatever the file: a CSV capture by ``io.capture``, or a file a
registered :class:`Reader` claims (a binary autopilot log, a bag), which hands back its readings
as a :class:`Table`. A new kind of source is one module with one ``Reader``, appended to
``READERS``: the readings module turns its table into the ``Log`` every command takes, judges
its clock and temperature as it judges a CSV's, and names it in every message.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from tumblecal_cli.core.model import FloatArray
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

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != 3:
            raise ValueError(f"a Table's values are (n, 3), got shape {values.shape}")
        n = len(values)
        for what, column in (("clock", self.clock), ("temperature", self.temperature), ("labels", self.labels)):
            if column is not None and len(column) != n:
                raise ValueError(f"a Table's {what} has {len(column)} rows for {n} readings")
        object.__setattr__(self, "values", values)


class Reader(Protocol):
    """A kind of source: whether it ``claims`` a file (by its name or its first bytes), and the
    readings of the sensor and stream ``spec`` names in it (``label_column``: a text column
    to read beside them, when the source has one). Errors are InputErrors naming the file."""

    def claims(self, path: str, head: bytes) -> bool: ...

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table: ...


#: The readers of sources beside CSV, asked in order; a file none claims is read as CSV.
READERS: list[Reader] = []
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

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table:
        return MEMORY[path](spec, label_column)


IN_MEMORY = _InMemory()


def reader_for(path: str, opener: Callable[[str], bytes] | None = None) -> Reader | None:
    """The reader that claims ``path`` (None: a CSV capture, or stdin: CSV is what a pipe holds)."""
    if path in MEMORY:
        return IN_MEMORY
    if path == "-" or not READERS:
        return None
    try:
        head = opener(path) if opener is not None else _head(path)
    except OSError:
        return None  # the CSV reader opens it and says what is wrong
    return next((r for r in READERS if r.claims(path, head)), None)


def _head(path: str) -> bytes:
    with open(path, "rb") as f:
        return f.read(HEAD)
