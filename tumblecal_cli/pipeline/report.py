"""report: the calibration files of a lot, found and read, then summarised by ``core.lot``."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import gate, lot
from tumblecal_cli.errors import InputError, TumblecalError
from tumblecal_cli.io import calfile, limitfile

#: Suffixes of calibration files a folder is searched for (case-insensitive, as documents.is_yaml).
SUFFIXES = (".json", ".yaml", ".yml")


@dataclass(frozen=True)
class Reported:
    """A lot's report: the statistics, the entries they were made from, and the limits judged by."""

    result: lot.Report
    entries: list[lot.Entry]
    limits: Mapping[str, object]
    files: list[str]

    @property
    def status(self) -> int:
        """2 when a file could not be read, 1 when the lot needs attention, else 0."""
        return 2 if self.result.unreadable else 1 if self.result.needs_attention else 0


def report(
    paths: Sequence[str | os.PathLike[str]] | str | os.PathLike[str],
    *,
    limits: str | None = None,
    max_drift: str | Mapping[str, float] | None = None,
    min_cpk: float | None = None,
) -> Reported:
    """Statistics of the calibration files in ``paths`` (files, or folders searched for
    *.json and *.yaml): per parameter count, mean, std, min/max, Cpk against ``limits`` (a limits
    file), outliers, and drift beyond ``max_drift`` (``offset=0.01,gain=0.002``)."""
    if min_cpk is not None and not (np.isfinite(min_cpk) and min_cpk > 0):
        raise InputError(f"--min-cpk must be a positive number, got {min_cpk}")
    if min_cpk is not None and limits is None:
        raise InputError("--min-cpk needs --limits: Cpk is measured against the limits")
    drift_limits = lot.parse_max_drift(max_drift)
    bounds = limitfile.load_limits(limits) if limits else {}
    if not isinstance(paths, str | os.PathLike | Sequence):
        raise InputError(f"report takes calibration files (one, or a list), not a {type(paths).__name__}")
    given = [paths] if isinstance(paths, str | os.PathLike) else list(paths)
    found = find([os.fspath(p) for p in given], skip=limits)
    entries, unreadable = _load(found)
    result = lot.summarise(entries, unreadable, bounds, max_drift=drift_limits, min_cpk=min_cpk)
    return Reported(result, entries, bounds, found)


def find(paths: list[str], skip: str | None = None) -> list[str]:
    """The calibration files named: each path a file (taken as it is, whatever its name; '-'
    stdin) or a folder searched recursively for ``*.json``, ``*.yaml``, ``*.yml``. Inside a
    folder, hidden files and folders (a name starting with '.', such as batch's staging files
    ``.SN1.abc.partial.json``) are skipped, and so is ``skip`` (the limits file, kept beside the
    calibrations). Sorted, each file once."""
    found: set[str] = set()
    for path in paths:
        if path == "-":  # '-' means stdin wherever a path is taken (docs/reference/csv.md, "Pipes")
            found.add(path)
            continue
        if not os.path.exists(path):
            raise InputError("no such file or folder", file=path)
        if not os.path.isdir(path):
            found.add(os.path.normpath(path))
            continue
        for folder, dirs, names in os.walk(path):
            dirs[:] = [d for d in dirs if not d.startswith(".")]  # os.walk descends only into what is left
            for name in names:
                file = os.path.join(folder, name)
                if name.startswith(".") or not name.lower().endswith(SUFFIXES):
                    continue
                if skip is not None and os.path.exists(skip) and os.path.samefile(file, skip):
                    continue
                found.add(os.path.normpath(file))
    if not found:
        raise InputError(f"no calibration files (*.json, *.yaml) in {', '.join(paths)}")
    return sorted(found)


def entry(cal: calfile.Calibration) -> lot.Entry:
    """The parameters of one loaded calibration."""
    values = {name: float(v) for name, v in zip(lot.OFFSETS, cal.offset, strict=True)}
    a = np.linalg.inv(cal.matrix)  # load() has refused a singular M
    if cal.method not in gate.FIXED_GAINS:
        values.update({name: float(g) for name, g in zip(lot.GAINS, np.diag(a), strict=True)})
    if np.count_nonzero(cal.matrix - np.diag(np.diag(cal.matrix))):  # as gate.verdict: M has cross terms
        for i, row in enumerate(lot.AXES):
            for j, col in enumerate(lot.AXES):
                if i != j and a[i, i]:  # (A[i, i] 0: a matrix that maps another axis onto this one, no term)
                    values[f"cross.{row}{col}"] = float(a[i, j] / a[i, i])
    serial = cal.serial
    imported = cal.fields.get("imported")  # another writer's field: read as written
    # an imported calibration dates from when it was made, as its export recorded
    made = calfile.created_text(imported.get("created") if isinstance(imported, dict) else None) or cal.created
    return lot.Entry(
        path=cal.path or "-",
        serial=None if serial is None or str(serial).strip() == "" else str(serial),
        created=made or "",
        sensor=cal.sensor,
        method=cal.method,
        values=values,
        units=(f"{cal.input_units} -> " if cal.input_units else "") + str(cal.units or "no units"),
        poses=tuple((p.sha256, p.file or "") for p in cal.poses if p.sha256),
    )


def load_all(paths: list[str]) -> tuple[list[lot.Entry], list[tuple[str, str]]]:
    """Every calibration file ``find`` finds, loaded. A file that cannot be read, or is not a
    tumblecal calibration (another tool's JSON in the folder), does not stop the others: it is
    returned as ``(path, message)`` (the message without the path) for the caller to warn about."""
    return _load(find(paths))


def _load(paths: list[str]) -> tuple[list[lot.Entry], list[tuple[str, str]]]:
    entries: list[lot.Entry] = []
    unreadable: list[tuple[str, str]] = []
    for path in paths:
        try:
            entries.append(entry(calfile.load(path)))
        except TumblecalError as err:
            unreadable.append((path, _message(err)))
    return entries, unreadable


def _message(err: TumblecalError) -> str:
    where = [f"line {err.line}"] if err.line is not None else []
    if err.column is not None:
        where.append(f"column {err.column}")
    return f"{err.message} ({', '.join(where)})" if where else err.message
