"""report: the calibration files of a lot, found and read, then summarised by ``core.lot``."""

from __future__ import annotations

import os
import urllib.parse
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import catalog, lot, outliers
from tumblecal_cli.errors import InputError, TumblecalError
from tumblecal_cli.io.calfiles import calfile, limitfile
from tumblecal_cli.io.figures import lothtml, plots
from tumblecal_cli.version import __version__

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
    outlier_alpha: float = outliers.OUTLIER_ALPHA,
) -> Reported:
    """Statistics of the calibration files in ``paths`` (files, or folders searched for
    *.json and *.yaml): per parameter count, mean, std, min/max, Cpk against ``limits`` (a limits
    file), outliers at the lot-wide false-alarm rate ``outlier_alpha`` (``core.outliers``), and
    drift beyond ``max_drift`` (``offset=0.01,gain=0.002``)."""
    judged = Judged(limits, max_drift, min_cpk, outlier_alpha)
    judged.check()
    if not isinstance(paths, str | os.PathLike | Sequence):
        raise InputError(f"report takes calibration files (one, or a list), not a {type(paths).__name__}")
    given = [paths] if isinstance(paths, str | os.PathLike) else list(paths)
    found = find([os.fspath(p) for p in given], skip=limits)
    entries, unreadable = _load(found)
    return judged.report(entries, unreadable, found)


@dataclass(frozen=True)
class Judged:
    """How a lot is judged (``report``'s options): checked before any work, then applied to the
    entries of the files (or of the records, ``records``' ``report_lot``)."""

    limits: str | None = None
    max_drift: str | Mapping[str, float] | None = None
    min_cpk: float | None = None
    outlier_alpha: float = outliers.OUTLIER_ALPHA

    def check(self) -> None:
        outliers.check_alpha(self.outlier_alpha)
        if self.min_cpk is not None and not (np.isfinite(self.min_cpk) and self.min_cpk > 0):
            raise InputError(f"--min-cpk must be a positive number, got {self.min_cpk}")
        if self.min_cpk is not None and self.limits is None:
            raise InputError("--min-cpk needs --limits: Cpk is measured against the limits")
        lot.parse_max_drift(self.max_drift)

    def report(self, entries: list[lot.Entry], unreadable: list[tuple[str, str]], found: list[str]) -> Reported:
        drift_limits = lot.parse_max_drift(self.max_drift)
        bounds = limitfile.load_limits(self.limits) if self.limits else {}
        result = lot.summarise(
            entries, unreadable, bounds, max_drift=drift_limits, min_cpk=self.min_cpk, outlier_alpha=self.outlier_alpha
        )
        return Reported(result, entries, bounds, found)


def unit_name(e: lot.Entry) -> str:
    """How the report names a unit: its serial, or its file's name when it has none."""
    return e.serial if e.serial is not None else os.path.basename(e.path)


def histograms(reported: Reported) -> list[plots.Histogram]:
    """One histogram per row of the report: the lot's values of that parameter, its limits, and
    its failing units and outliers marked by name."""
    result, members = reported.result, lot.split_by_units(lot.lot(reported.entries))
    several = len({r.sensor for r in result.rows}) != 1
    out = []
    for row in result.rows:
        having = [e for e in members if e.sensor == row.sensor and row.parameter in e.values]
        flagged = {unit for unit, _, _ in row.outliers}
        outside = set(row.outside)
        kinds = {(True, True): "both", (True, False): "outside", (False, True): "outlier"}
        marks = tuple(
            plots.Mark(unit_name(e), e.values[row.parameter], kinds[unit_name(e) in outside, unit_name(e) in flagged])
            for e in having
            if unit_name(e) in outside or unit_name(e) in flagged
        )
        name = f"{row.sensor} {row.parameter}" if several else row.parameter
        values = np.array([e.values[row.parameter] for e in having])
        out.append(plots.Histogram(name, values, row.lower, row.upper, marks=marks))
    return out


def write_html(reported: Reported, path: str, *, limits: str | None = None, drift_given: bool = False) -> None:
    """``report --html``: the lot report as one self-contained page (``io.figures.lothtml``), its figures
    drawn by matplotlib (the ``[plot]`` extra), each unit linked to its calibration file."""
    panels = plots.lot_panels_svg(histograms(reported)) if reported.result.rows else []
    names = [f"{row.sensor} {row.parameter}" for row in reported.result.rows]
    several = len({row.sensor for row in reported.result.rows}) > 1
    page = lothtml.Page(
        report=reported.result,
        units=unit_lines(reported, os.path.dirname(os.path.abspath(path))),
        panels=[(name if several else name.split(" ", 1)[1], svg) for name, svg in zip(names, panels, strict=True)],
        limits=os.path.basename(limits) if limits else None,
        tool=f"tumblecal {__version__}",
        drift_given=drift_given,
    )
    lothtml.write(path, page)


def unit_lines(reported: Reported, folder: str) -> list[lothtml.UnitLine]:
    """Each unit of the lot with why it fails or needs a look, linked relative to ``folder``."""
    result = reported.result
    failing: dict[tuple[str, str], list[str]] = {}
    flagged: dict[tuple[str, str], list[str]] = {}
    members = lot.split_by_units(lot.lot(reported.entries))
    for row in result.rows:
        where = f"outside {row.lower:.4g} … {row.upper:.4g}" if row.lower is not None and row.upper is not None else ""
        for e in members:
            if e.sensor == row.sensor and unit_name(e) in row.outside:
                value = e.values[row.parameter]
                failing.setdefault((e.sensor, unit_name(e)), []).append(f"{row.parameter} {value:.4g} {where}".strip())
        for unit, value, t in row.outliers:
            limit = f" (limit {row.outlier_limit:.3g})" if row.outlier_limit is not None else ""
            flagged.setdefault((row.sensor, unit), []).append(
                f"{row.parameter} {value:.4g}: an outlier, t {t:+.1f} against the other units{limit}"
            )
    drifted = {(d.sensor, d.serial): d for d in result.drift if d.flagged}
    shared = lot.duplicate_of(result.duplicates)
    lines = []
    for e in members:
        key = (e.sensor, unit_name(e))
        why = list(failing.get(key, []))
        if e.passed is False:
            why.append("failed its limits when it was calibrated (its verdict)")
        look = list(flagged.get(key, []))
        if key in drifted and e.serial is not None:
            d = drifted[key]
            look.append(f"{d.parameter} changed {d.change:+.4g} since {d.previous_created or d.previous}")
        if e.serial in shared:
            look.append(f"shares a pose file with {', '.join(shared[e.serial])}")
        link = (
            None
            if e.path == "-"
            else urllib.parse.quote(os.path.relpath(os.path.abspath(e.path), folder).replace(os.sep, "/"))
        )
        lines.append(
            lothtml.UnitLine(
                unit_name(e), e.created, e.sensor, e.method, e.station, e.operator, link, tuple(why), tuple(look)
            )
        )
    return lines


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
    a = np.linalg.inv(cal.sensor_matrix)  # load() has refused a singular M; the sensor's axes (--axes aside)
    if not catalog.fixes_gains(cal.method):
        values.update({name: float(g) for name, g in zip(lot.GAINS, np.diag(a), strict=True)})
    if np.count_nonzero(cal.sensor_matrix - np.diag(np.diag(cal.sensor_matrix))):  # as gate.verdict: M has cross terms
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
        station=cal.unit.station if cal.unit is not None else None,
        operator=cal.unit.operator if cal.unit is not None else None,
        passed=cal.verdict.passed if cal.verdict is not None else None,
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
