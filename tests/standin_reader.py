"""A stand-in kind of log and its reader, registered in one place (:func:`register`): the proof
that a new reader needs its module and one row in the registry, nothing else.

The format is made up: the bytes ``STANDIN1``, then one record a sample, four little-endian
float64s: the time in s and an accelerometer's x, y, z in g. Its one stream is ``acc``.

tests/test_extension_reader.py runs it through the contract every reader keeps
(tests/reader_contract.py) and through the command line in a subprocess. A registration made in
a test process is not seen by a new process, so there the command runs as the console script
does, with this module imported first: ``python -c "import tests.standin_reader as s;
s.register(); from tumblecal_cli.cli.app import main_exit; main_exit()" ARGS``
(tests/conftest.with_registered), from the repository's root: the same entry point and code path as ``tumblecal ARGS``.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.logs import LogFormat
from tumblecal_cli.io.logs.fields import NAMES
from tumblecal_cli.io.logs.reader import LogReader
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream, Table

MAGIC = b"STANDIN1"
#: The stand-in's row: its kind, the module holding its READER, its first bytes.
ROW = LogFormat("stand-in log", "tests.standin_reader", magic=(MAGIC,))


def register() -> None:
    """The one place the stand-in is registered: its row in io.sources' registry, after io.logs' own."""
    sources.register(ROW)


def write(path: Path, t: FloatArray, xyz: FloatArray) -> Path:
    """A stand-in log of the times ``t`` (s) and readings ``xyz`` ((n, 3), g)."""
    path.write_bytes(MAGIC + np.column_stack([t, xyz]).astype("<f8").tobytes())
    return path


@dataclass(frozen=True)
class Samples:
    """A stand-in log read once: its times, readings and sha256."""

    t: FloatArray
    xyz: FloatArray
    sha256: str


class StandinReader(LogReader[Samples]):
    """The Reader of stand-in logs."""

    row = ROW
    called = "a stand-in log"
    corrected_as = "corrected"

    def walk(self, path: str) -> Samples:
        data = Path(path).read_bytes()
        if not data.startswith(MAGIC) or (len(data) - len(MAGIC)) % 32:
            raise InputError("not a stand-in log: its records are not 32 bytes each", file=path)
        rows = np.frombuffer(data, dtype="<f8", offset=len(MAGIC)).reshape(-1, 4).astype(np.float64)
        return Samples(rows[:, 0].copy(), rows[:, 1:].copy(), hashlib.sha256(data).hexdigest())

    def streams(self, path: str) -> list[Stream]:
        found = self.index(path)
        span = float(found.t[-1] - found.t[0]) if len(found.t) > 1 else 0.0
        rate = (len(found.t) - 1) / span if span > 0 else None
        how = "raw: a stand-in log holds the readings as the sensor gave them"
        return [Stream("acc", None, "accelerometer", len(found.t), rate, "g", False, how)]

    def table(self, path: str, spec: ReadSpec) -> Table:
        chosen = self.pick(path, spec)
        found = self.index(path)
        note = self.read_note(path, chosen, len(found.t))
        names = NAMES[chosen.sensor]
        return Table(names, found.xyz, found.t, "s", None, None, found.sha256, (note,), stream=chosen)


READER = StandinReader()
