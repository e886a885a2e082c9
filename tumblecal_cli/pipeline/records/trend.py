"""Stations watched over time (``tumblecal records trend``): each station's records charted by
``core.control``, the alarms named with the unit where they fired and what they usually mean."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from itertools import chain, groupby
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import control
from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.figures import trendhtml
from tumblecal_cli.io.outputs import atomic_output
from tumblecal_cli.pipeline.records.store import PARAMETERS, Store, opened

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
    """One station's records of one sensor in time order: their ids, the baseline's units, and
    each parameter's values (None where a record has none of it)."""

    station: str
    sensor: str
    ids: IntArray
    baseline: BoolArray
    values: dict[str, FloatArray | None]


def _read(store: Store, station: str | None, since: str | None, base: Baseline) -> list[_Series]:
    """The records, each station and sensor's in time order, as numbers: the database sorts and
    groups them and a row is its id and numbers only (its text, the serial and time, is read for
    the units an alarm names): no text is made per record, and no sort in Python."""
    where, values = ["kind = 'calibration'"], []
    if station is not None:
        where.append("station = ?")
        values.append(station)
    if since is not None:
        where.append("created >= ?")
        values.append(since)
    text = ' COLLATE "C"' if store.dialect == "postgresql" else ""  # (code point order, as SQLite's)
    key = f"coalesce(station, '(no station)'){text}, sensor{text}"
    created = f"coalesce(created, ''){text}"
    missing = ", ".join(f"count(*) - count({p})" for p in PARAMETERS)
    flag, flagged = "0", []
    if base.period is not None:  # (a date takes in that whole day)
        flag = f"CASE WHEN {created} >= ? AND substr({created}, 1, {len(base.period[1])}) <= ? THEN 1 ELSE 0 END"
        flagged = list(base.period)
    numbers = ", ".join(f"coalesce({p}, 0.0)" for p in PARAMETERS)
    condition = " AND ".join(where)
    with store.snapshot():  # (both queries see the same records)
        groups = store.execute(
            f"SELECT {key}, count(*), {missing} FROM records WHERE {condition} GROUP BY {key} ORDER BY {key}", values
        ).fetchall()
        total, width = sum(g[2] for g in groups), len(PARAMETERS) + 2
        rows = store.execute(
            f"SELECT id, {flag}, {numbers} FROM records WHERE {condition} ORDER BY {key}, {created}, id",
            [*flagged, *values],
        )
        table = np.fromiter(chain.from_iterable(rows), np.float64, total * width).reshape(total, width)
    out: list[_Series] = []
    start = 0
    for name, sensor, count, *nulls in groups:
        part = table[start : start + count]
        start += count
        mask = part[:, 1] > 0 if base.period is not None else np.arange(count) < base.units
        of = {p: (part[:, 2 + k] if not nulls[k] else None) for k, p in enumerate(PARAMETERS)}
        out.append(_Series(name, sensor, part[:, 0].astype(np.int64), mask, of))
    return out


def _who(store: Store, ids: set[int]) -> dict[int, tuple[str | None, str | None]]:
    """The serial and time of each record of ``ids``."""
    out: dict[int, tuple[str | None, str | None]] = {}
    listed = sorted(ids)
    for start in range(0, len(listed), 500):
        part = listed[start : start + 500]
        marks = ", ".join("?" for _ in part)
        rows = store.execute(
            f"SELECT id, serial, coalesce(created, '') FROM records WHERE id IN ({marks})", part
        ).fetchall()
        out.update({int(r[0]): (r[1], r[2]) for r in rows})
    return out


_Charted = tuple[_Series, str, control.Chart, FloatArray]


def trend(db: str, station: str | None = None, since: str | None = None, baseline: Baseline | None = None) -> Trended:
    """Every station's (or ``station``'s) records since ``since`` charted, and the alarms."""
    base = baseline or Baseline()
    with opened(db, write=False) as store:
        series = _read(store, station, since, base)
        charts: list[_Charted] = []
        for s in series:
            kept = {p: v for p, v in s.values.items() if v is not None and np.isfinite(v).all()}
            if not s.baseline.any() or not kept:
                continue
            drawn_on = control.charts(np.stack(list(kept.values())), s.baseline)
            charts += [(s, p, c, v) for (p, v), c in zip(kept.items(), drawn_on, strict=True) if c is not None]
        units = sum(s.ids.size for s in series)
        stations = tuple(sorted({s.station for s in series}))
        if not charts:
            return Trended(base.stated(), None, 0, units, stations)
        points = sum(int(c.judged.sum()) for _, _, c, _ in charts)
        lim = {n: control.limits(points, n) for n in {c.baseline for _, _, c, _ in charts}}
        found: list[tuple[_Charted, dict[str, int]]] = []
        for _, group in groupby(charts, key=lambda chart: id(chart[0])):  # (a station's series judged together)
            together = list(group)
            at = lim[together[0][2].baseline]
            found += zip(together, control.fired_together([g[2] for g in together], at), strict=True)
        compared = _compared(charts)
        who = _who(store, {int(ch[0].ids[i]) for ch, f in found for i in f.values()} | {i for _, i in compared})
    alarms: list[Alarm] = []
    drawn: list[trendhtml.SeriesChart] = []
    for (s, p, c, values), fired in found:
        at = lim[c.baseline]
        alarms += _alarms(s, p, fired, at, who)
        if fired:
            drawn.append(_drawn(s, p, c, values, fired, at))
    alarms += [replace(a, serial=who[i][0], created=who[i][1]) for a, i in compared]
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


def _alarms(
    s: _Series,
    parameter: str,
    found: dict[str, int],
    lim: control.ControlLimits,
    who: dict[int, tuple[str | None, str | None]],
) -> list[Alarm]:
    out = []
    for rule, at in found.items():
        serial, created = who[int(s.ids[at])]
        out.append(
            Alarm(s.station, s.sensor, parameter, rule, serial, created, _words(rule, lim), meaning(parameter, rule))
        )
    return out


def _compared(charts: list[_Charted]) -> list[tuple[Alarm, int]]:
    """Each station beyond the others on a parameter: its alarm (without its first unit's serial
    and time) and that unit's record id."""
    groups: dict[tuple[str, str], dict[str, FloatArray]] = {}
    firsts: dict[tuple[str, str, str], int] = {}
    for s, parameter, c, values in charts:
        if c.judged.any():
            groups.setdefault((s.sensor, parameter), {})[s.station] = values[c.judged]
            firsts[(s.station, s.sensor, parameter)] = int(s.ids[int(np.flatnonzero(c.judged)[0])])
    comparisons = sum(len(g) for g in groups.values() if len(g) > 1)
    out = []
    for (sensor, parameter), by_station in groups.items():
        for found in control.compare(by_station, comparisons):
            if found.beyond:
                words = control.RULE_WORDS["station"].format(z=abs(found.t))
                said = meaning(parameter, "station")
                alarm = Alarm(found.station, sensor, parameter, "station", None, None, words, said)
                out.append((alarm, firsts[(found.station, sensor, parameter)]))
    return out
