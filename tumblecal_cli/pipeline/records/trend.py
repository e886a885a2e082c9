"""Stations watched over time (``tumblecal records trend``): each station's records charted by
``core.control``, the alarms named with the unit where they fired and what they usually mean."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import control
from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.figures import trendhtml
from tumblecal_cli.io.outputs import atomic_output
from tumblecal_cli.pipeline.records.store import PARAMETERS, opened

if TYPE_CHECKING:
    from tumblecal_cli.pipeline.frames import DataFrame

#: What an alarm on a parameter's family usually means: a shift or drift, and one unit far off.
MEANINGS = {
    ("offset", "drift"): "a creeping offset on one axis: the fixture tilting (or its mount working loose)",
    ("offset", "point"): "one unit's offset far off: a unit defect, a pose logged in the wrong orientation, "
    "or the fixture knocked",
    ("gain", "drift"): "gains moving together: the reference changed (local gravity, a magnetometer's "
    "surroundings), or the station's temperature",
    ("gain", "point"): "one unit's gain far off: a unit defect or a saturated pose",
    ("cross", "drift"): "cross-axis terms moving: the fixture's faces no longer square (a worn or shifted jig)",
    ("cross", "point"): "one unit's cross-axis term far off: the unit seated crooked in the fixture",
    ("residual", "drift"): "the fit getting worse: vibration at the station, a loose clamp, a noisier sensor lot",
    ("residual", "point"): "one poor fit: the unit moved while it was logged",
}
_STATION_MEANING = "this station's fixture or reference differs from the other stations': level or check it"
_POINT_RULES = ("beyond-limit",)


def family(parameter: str) -> str:
    return parameter.split("_")[0]


def meaning(parameter: str, rule: str) -> str:
    if rule == "station":
        return _STATION_MEANING
    return MEANINGS[(family(parameter), "point" if rule in _POINT_RULES else "drift")]


#: The keys of an alarm's JSON, and the columns of ``Trended.table``.
ALARM_COLUMNS = ("station", "sensor", "parameter", "rule", "first_serial", "first_created", "what", "meaning")


@dataclass(frozen=True)
class Alarm:
    """One rule that fired on one station's parameter: the first unit where it did."""

    station: str
    sensor: str
    parameter: str
    rule: str
    serial: str | None
    created: str | None
    words: str
    meaning: str

    def as_dict(self) -> dict[str, object]:
        return {
            "station": self.station,
            "sensor": self.sensor,
            "parameter": self.parameter,
            "rule": self.rule,
            "first_serial": self.serial,
            "first_created": self.created,
            "what": self.words,
            "meaning": self.meaning,
        }


@dataclass(frozen=True)
class Trended:
    """A trend run: the ``baseline`` stated, the ``limits`` the rules used, how many ``series``
    and ``units`` were charted, and the ``alarms``."""

    baseline: str
    limits: control.ControlLimits | None
    series: int
    units: int
    stations: tuple[str, ...]
    alarms: list[Alarm] = field(default_factory=list)
    charts: tuple[trendhtml.SeriesChart, ...] = ()  # each series with an alarm, as --html draws it

    def table(self) -> DataFrame:
        """The alarms as a pandas DataFrame, one row each (the Python API)."""
        import pandas as pd

        return pd.DataFrame([a.as_dict() for a in self.alarms], columns=list(ALARM_COLUMNS))

    def as_dict(self) -> dict[str, object]:
        return {
            "baseline": self.baseline,
            "limits": None if self.limits is None else self.limits.as_dict(),
            "stations": list(self.stations),
            "series": self.series,
            "units": self.units,
            "alarms": [a.as_dict() for a in self.alarms],
        }


@dataclass(frozen=True)
class Baseline:
    """The units the control limits come from: the first ``units`` of each series, or those
    created in ``period`` (first, last: ISO dates or times, inclusive)."""

    units: int = control.BASELINE_UNITS
    period: tuple[str, str] | None = None

    def stated(self) -> str:
        if self.period is not None:
            return f"the units created {self.period[0]} to {self.period[1]} of each station"
        return f"the first {self.units} units of each station"

    def mask(self, created: list[str]) -> BoolArray:
        if self.period is None:
            return np.arange(len(created)) < self.units
        first, last = self.period
        end = last + "\uffff"  # a date takes in that whole day
        return np.array([first <= c <= end for c in created], dtype=bool)


def parse_baseline(text: str | None) -> Baseline:
    """``--baseline``: N (the first N units) or FIRST..LAST (dates)."""
    if text is None:
        return Baseline()
    if re.fullmatch(r"[0-9]+", text.strip()):
        n = int(text)
        if n < control.MIN_BASELINE:
            raise InputError(f"--baseline {n}: a baseline needs {control.MIN_BASELINE} units or more")
        return Baseline(units=n)
    first, sep, last = text.partition("..")
    date = r"\d{4}-\d{2}-\d{2}[0-9T:.Z+-]*"
    if not sep or not re.fullmatch(date, first.strip()) or not re.fullmatch(date, last.strip()):
        raise InputError(
            f"--baseline {text!r}: give N (the first N units) or FIRST..LAST (dates, 2026-01-05..2026-02-01)"
        )
    return Baseline(period=(first.strip(), last.strip()))


@dataclass
class _Series:
    station: str
    sensor: str
    serials: list[str | None]
    created: list[str]
    values: dict[str, FloatArray]


def _read(db: str, station: str | None, since: str | None) -> list[_Series]:
    where, values = ["kind = 'calibration'"], []
    if station is not None:
        where.append("station = ?")
        values.append(station)
    if since is not None:
        where.append("created >= ?")
        values.append(since)
    names = ", ".join(PARAMETERS)
    sql = (
        f"SELECT coalesce(station, '(no station)'), sensor, serial, coalesce(created, ''), id, {names} "
        f"FROM records WHERE {' AND '.join(where)}"
    )
    with opened(db, write=False) as store:
        rows = store.execute(sql, values).fetchall()
    # sorted here, not by the database: an ORDER BY walks the index and reads each row where it
    # lies (4 times the time on 100,000 records)
    rows.sort(key=lambda r: (r[0], r[1], r[3], r[4]))
    out: list[_Series] = []
    start = 0
    for i in range(1, len(rows) + 1):
        if i == len(rows) or rows[i][:2] != rows[start][:2]:
            block = rows[start:i]
            numbers = np.array([r[5:] for r in block], dtype=np.float64)  # (None: NaN)
            values_of = {p: numbers[:, k] for k, p in enumerate(PARAMETERS)}
            out.append(_Series(block[0][0], block[0][1], [r[2] for r in block], [r[3] for r in block], values_of))
            start = i
    return out


def trend(db: str, station: str | None = None, since: str | None = None, baseline: Baseline | None = None) -> Trended:
    """Every station's (or ``station``'s) records since ``since`` charted, and the alarms."""
    base = baseline or Baseline()
    series = _read(db, station, since)
    charts: list[tuple[_Series, str, control.Chart, FloatArray]] = []
    for s in series:
        mask = base.mask(s.created)
        for parameter, values in s.values.items():
            finite = np.isfinite(values)
            if not finite.all():
                continue
            c = control.chart(values, mask) if mask.any() else None
            if c is not None:
                charts.append((s, parameter, c, values))
    points = sum(int(c.judged.sum()) for _, _, c, _ in charts)
    units = sum(len(s.created) for s in series)
    stations = tuple(sorted({s.station for s in series}))
    if not charts:
        return Trended(base.stated(), None, 0, units, stations)
    lim = {n: control.limits(points, n) for n in {c.baseline for _, _, c, _ in charts}}
    alarms: list[Alarm] = []
    drawn: list[trendhtml.SeriesChart] = []
    for s, p, c, values in charts:
        found = control.fired(c, lim[c.baseline])
        alarms += _alarms(s, p, found, lim[c.baseline])
        if found:
            drawn.append(_drawn(s, p, c, values, found, lim[c.baseline]))
    alarms += _compared(charts)
    shown = lim[min(lim)]
    return Trended(base.stated(), shown, len(charts), units, stations, alarms, tuple(drawn))


def write_html(trended: Trended, path: str, stated: Sequence[str]) -> None:
    """``records trend --html``: the page (``io.figures.trendhtml``) written atomically; ``stated``
    the lines the text output starts with (baseline, limits, counts)."""
    rows = [
        (a.station, f"{a.sensor} {a.parameter}", a.rule, str(a.serial), str(a.created), a.meaning)
        for a in trended.alarms
    ]
    text = trendhtml.page("tumblecal records trend", stated, rows, trended.charts).encode()
    with atomic_output(path) as out:
        out.write(text)


def _words(rule: str, lim: control.ControlLimits, **facts: float) -> str:
    return control.RULE_WORDS[rule].format(
        l1=lim.l1, l2=lim.l2, l3=lim.l3, run=lim.run, lam=lim.lam, le=lim.le, **facts
    )


def _drawn(
    s: _Series, parameter: str, c: control.Chart, values: FloatArray, found: dict[str, int], lim: control.ControlLimits
) -> trendhtml.SeriesChart:
    """An alarmed series as the page draws it: rule 1's limit either side of the centre."""
    limit = lim.l1 * c.sigma * math.sqrt(1.0 + 1.0 / c.baseline)
    last = int(np.flatnonzero(~c.judged)[-1]) + 1 if (~c.judged).any() else 0
    title = f"station {s.station}, {s.sensor} {parameter}"
    return trendhtml.SeriesChart(title, values.tolist(), c.centre, limit, last, tuple(found.items()))


def _alarms(s: _Series, parameter: str, found: dict[str, int], lim: control.ControlLimits) -> list[Alarm]:
    out = []
    for rule, at in found.items():
        out.append(
            Alarm(
                s.station,
                s.sensor,
                parameter,
                rule,
                s.serials[at],
                s.created[at],
                _words(rule, lim),
                meaning(parameter, rule),
            )
        )
    return out


def _compared(charts: list[tuple[_Series, str, control.Chart, FloatArray]]) -> list[Alarm]:
    groups: dict[tuple[str, str], dict[str, FloatArray]] = {}
    firsts: dict[tuple[str, str, str], tuple[str | None, str | None]] = {}
    for s, parameter, c, values in charts:
        if c.judged.any():
            groups.setdefault((s.sensor, parameter), {})[s.station] = values[c.judged]
            at = int(np.flatnonzero(c.judged)[0])
            firsts[(s.station, s.sensor, parameter)] = (s.serials[at], s.created[at])
    comparisons = sum(len(g) for g in groups.values() if len(g) > 1)
    out = []
    for (sensor, parameter), by_station in groups.items():
        for found in control.compare(by_station, comparisons):
            if found.beyond:
                serial, created = firsts[(found.station, sensor, parameter)]
                words = control.RULE_WORDS["station"].format(z=abs(found.t))
                out.append(
                    Alarm(
                        found.station,
                        sensor,
                        parameter,
                        "station",
                        serial,
                        created,
                        words,
                        meaning(parameter, "station"),
                    )
                )
    return out
