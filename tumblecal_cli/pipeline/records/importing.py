"""Existing calibration files and batch folders taken into a records database
(``tumblecal records import``)."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass

from tumblecal_cli.errors import InputError, TumblecalError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.pipeline import report
from tumblecal_cli.pipeline.records import columns
from tumblecal_cli.pipeline.records.recording import now
from tumblecal_cli.pipeline.records.store import opened, shown


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


def report_lot(db: str, lot: str, judged: report.Judged) -> report.Reported:
    """``report --db DB --lot L``: the lot judged from its records (each calibration recorded
    with that lot; its re-tests left out), as ``report`` judges the files of a lot."""
    judged.check()
    with opened(db, write=False) as store:
        rows = store.execute(
            "SELECT id, document FROM records WHERE lot = ? AND kind = 'calibration' ORDER BY id", (lot,)
        ).fetchall()
    if not rows:
        raise InputError(f"no records of lot {lot!r}", file=shown(db))
    entries, unreadable, names = [], [], []
    for record, document in rows:
        name = f"{shown(db)}#{record}"
        names.append(name)
        try:
            entries.append(report.entry(calfile.validate(json.loads(document), name)))
        except (TumblecalError, ValueError) as err:
            unreadable.append((name, err.message if isinstance(err, TumblecalError) else f"not JSON ({err})"))
    return judged.report(entries, unreadable, names)
