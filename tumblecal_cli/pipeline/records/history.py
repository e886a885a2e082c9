"""A unit's history (``tumblecal records history SERIAL``), and the files taken into a database
(``tumblecal records import``)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

from tumblecal_cli.errors import TumblecalError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.pipeline import report
from tumblecal_cli.pipeline.records import columns
from tumblecal_cli.pipeline.records.recording import now
from tumblecal_cli.pipeline.records.store import opened

_SHOWN = ("id", "kind", "serial", "station", "operator", "lot", "created", "recorded", "sensor", "method", "verdict")
_NUMBERED = (*columns.PARAMETERS, *columns.SIGMAS)


@dataclass(frozen=True)
class Change:
    """One parameter's change from the unit's previous record: ``delta`` in its units (new − old)
    and ``sigmas``, the change over the stated σ of the two, √(σ_new² + σ_old²) (None where
    either has none)."""

    parameter: str
    delta: float
    sigmas: float | None

    def as_dict(self) -> dict[str, object]:
        return {"parameter": self.parameter, "change": self.delta, "sigmas": self.sigmas}


@dataclass(frozen=True)
class UnitRecord:
    """One record of a unit: its text columns (``facts``), its numbers, and its changes from the
    record before it of the same sensor (empty for the first)."""

    facts: dict[str, object]
    numbers: dict[str, float | None]
    changes: tuple[Change, ...]

    def as_dict(self) -> dict[str, object]:
        values = {p: self.numbers.get(p) for p in columns.PARAMETERS}
        return {**self.facts, "values": values, "changes": [c.as_dict() for c in self.changes]}


def _changes(new: dict[str, float | None], old: dict[str, float | None]) -> tuple[Change, ...]:
    out = []
    for name in columns.PARAMETERS:
        a, b = new.get(name), old.get(name)
        if a is None or b is None or a == b:
            continue
        sa, sb = new.get(f"{name}_sd"), old.get(f"{name}_sd")
        spread = math.hypot(sa, sb) if sa is not None and sb is not None else 0.0
        out.append(Change(name, a - b, (a - b) / spread if spread > 0 else None))
    return tuple(out)


def history(db: str, serial: str) -> list[UnitRecord]:
    """Every record of ``serial``, newest first, each with its changes from the one before it."""
    names = (*_SHOWN, *_NUMBERED)
    with opened(db, write=False) as store:
        rows = store.execute(
            f"SELECT {', '.join(names)} FROM records WHERE serial = ? ORDER BY created, id", (serial,)
        ).fetchall()
    out: list[UnitRecord] = []
    last: dict[str, dict[str, float | None]] = {}
    for row in rows:
        facts = dict(zip(_SHOWN, row[: len(_SHOWN)], strict=True))
        numbers = dict(zip(_NUMBERED, row[len(_SHOWN) :], strict=True))
        before = last.get(str(facts["sensor"]))
        out.append(UnitRecord(facts, numbers, () if before is None else _changes(numbers, before)))
        last[str(facts["sensor"])] = numbers
    return out[::-1]


@dataclass(frozen=True)
class ImportDone:
    """What an import did: records ``added``, those there already (``known``), and the files that
    could not be read as calibrations, with why."""

    added: int
    known: int
    unreadable: tuple[tuple[str, str], ...]


def _lot_of(path: str, given: str | None) -> str | None:
    """A file's lot: ``given``, else the name of the batch folder (one holding summary.csv) it is in."""
    if given is not None:
        return given
    folder = os.path.dirname(os.path.abspath(path))
    return os.path.basename(folder) if os.path.isfile(os.path.join(folder, "summary.csv")) else None


def import_files(db: str, paths: Sequence[str], lot: str | None = None) -> ImportDone:
    """Calibration files and folders of them (batch folders: their lot is the folder's name) taken
    into ``db``, in one transaction; a file already recorded (the same content) adds nothing."""
    files = report.find(list(paths))
    rows, unreadable = [], []
    when = now()
    for path in files:
        try:
            cal = calfile.load(path)
        except TumblecalError as err:
            unreadable.append((path, err.message))
            continue
        status = 1 if cal.failed else 0
        origin = columns.Origin(lot=_lot_of(path, lot), command="import", status=status, source=path)
        rows.append(columns.row_of(cal, origin, when))
    added = 0
    with opened(db, write=True) as store:
        store.begin()
        try:
            for row in rows:
                added += store.insert(row, columns.tool())
            store.commit()
        except BaseException:
            store.rollback()
            raise
    return ImportDone(added, len(rows) - added, tuple(unreadable))
