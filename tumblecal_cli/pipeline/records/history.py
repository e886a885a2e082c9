"""A unit's history (``tumblecal records history SERIAL``): its records, newest first, and what
changed between them. Reads the typed columns only: no numpy, no calibration file read."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from tumblecal_cli.pipeline.records.store import PARAMETERS, SIGMAS, opened

if TYPE_CHECKING:
    from tumblecal_cli.pipeline.frames import DataFrame

_SHOWN = ("id", "kind", "serial", "station", "operator", "lot", "created", "recorded", "sensor", "method", "verdict")
_NUMBERED = (*PARAMETERS, *SIGMAS)


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
        values = {p: self.numbers.get(p) for p in PARAMETERS}
        return {**self.facts, "values": values, "changes": [c.as_dict() for c in self.changes]}


def _changes(new: dict[str, float | None], old: dict[str, float | None]) -> tuple[Change, ...]:
    out = []
    for name in PARAMETERS:
        a, b = new.get(name), old.get(name)
        if a is None or b is None or a == b:
            continue
        sa, sb = new.get(f"{name}_sd"), old.get(f"{name}_sd")
        spread = math.hypot(sa, sb) if sa is not None and sb is not None else 0.0
        out.append(Change(name, a - b, (a - b) / spread if spread > 0 else None))
    return tuple(out)


def history_table(db: str, serial: str) -> DataFrame:
    """:func:`history` as a pandas DataFrame: one row per record, newest first, its text columns
    and each parameter (the changes are in :func:`history`)."""
    import pandas as pd

    rows = [{**r.facts, **{p: r.numbers.get(p) for p in PARAMETERS}} for r in history(db, serial)]
    return pd.DataFrame(rows, columns=[*_SHOWN, *PARAMETERS])


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
