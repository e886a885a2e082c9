"""Statistics over a production lot of calibration files (``tumblecal report cals/ --limits ...``).

Numbers in, numbers out: which files make the lot, one row of statistics per sensor and
parameter (count, mean, spread, capability against the limits, outliers), and how each
re-calibrated unit moved since its previous calibration. numpy only: the pipeline
(``tumblecal_cli.pipeline.report``) finds and reads the files, the command line formats what
:func:`summarise` returns.

**Which calibrations make the lot statistics.** Stations keep every calibration a unit ever got
(batch publishes ``<serial>_<UTC time>.json`` and never replaces one), so a unit re-calibrated
three times has three files. The lot statistics take only the LATEST calibration of each
(sensor, serial), latest by ``created`` (ties broken by path), so that unit counts once, with
its newest result. A file without a serial cannot be matched with any other and counts on its
own. The earlier calibrations are not lost: the one before the latest is the baseline of the
unit's drift.

The parameters, from the model ``corrected = M·(raw − offset)`` with ``A = M⁻¹``:

- ``offset.x offset.y offset.z``: the offset, raw units;
- ``gain.x gain.y gain.z``: ``diag(A)``, except for methods whose gains are fixed
  (``catalog.fixes_gains``: one-pose, minmax, ...), which have none;
- ``cross.xy cross.xz cross.yx cross.yz cross.zx cross.zy``: ``A[i, j] / A[i, i]``, only when M
  has a non-zero off-diagonal term (as ``gate.verdict`` judges them).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import SENSORS
from tumblecal_cli.core.outliers import OUTLIER_ALPHA, OutlierRule, check_alpha
from tumblecal_cli.errors import InputError, Said, said

AXES = "xyz"
OFFSETS = tuple(f"offset.{k}" for k in AXES)
GAINS = tuple(f"gain.{k}" for k in AXES)
CROSS = tuple(f"cross.{i}{j}" for i in AXES for j in AXES if i != j)
#: Every parameter, in the order of the report's rows.
PARAMETERS = OFFSETS + GAINS + CROSS
#: |modified z| above this marks an outlier. Iglewicz and Hoaglin 1993 suggest 3.5; a lot report
#: is read by people who act on every flag, so it takes the more conservative 4.
OUTLIER_Z = 4.0
#: Families of parameters a drift limit is given for (``--max-drift offset=...,gain=...,cross=...``).
DRIFT_KEYS = ("offset", "gain", "cross")
DRIFT_ALIASES = {"cross_axis": "cross"}
DRIFT_HINT = str(said("drift.hint"))
#: Columns of ``Report.csv_rows``.
CSV_HEADER = [
    "sensor",
    "parameter",
    "count",
    "mean",
    "std",
    "min",
    "max",
    "lower",
    "upper",
    "cpk",
    "outliers",
    "drift_flagged",
    "outside",
    "outlier_rule",
    "cpk_low",
    "cpk_high",
]


# --- one calibration ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Entry:
    """One calibration file's parameters (see the module docstring for their names)."""

    path: str
    serial: str | None
    created: str
    sensor: str
    method: str
    values: dict[str, float]
    units: str = ""  # "[input units -> ]output units", to keep calibrations of other units apart
    poses: tuple[tuple[str, str], ...] = ()  # (sha256, file) of each pose file it was solved from
    station: str | None = None
    operator: str | None = None
    passed: bool | None = None  # the calibration's own verdict (None: it has none)


def _when(e: Entry) -> tuple[int, float, str, str]:
    """Sort key, oldest first: ``created`` as a time (ISO 8601; no zone read as UTC), ties by path.
    A file without a readable ``created`` sorts before every dated one."""
    try:
        when = datetime.fromisoformat(e.created)
    except ValueError:
        return (0, 0.0, e.created, e.path)
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return (1, when.timestamp(), e.created, e.path)


def lot(entries: Iterable[Entry]) -> list[Entry]:
    """The entries that make the lot statistics: the latest of each (sensor, serial), and every
    entry without a serial (see the module docstring). In the order of their paths."""
    latest: dict[tuple[str, str], Entry] = {}
    alone: list[Entry] = []
    for e in entries:
        if e.serial is None:
            alone.append(e)
            continue
        key = (e.sensor, e.serial)
        if key not in latest or _when(e) > _when(latest[key]):
            latest[key] = e
    return sorted([*latest.values(), *alone], key=lambda e: e.path)


# --- the same pose file under two serials -------------------------------------------------------


@dataclass(frozen=True)
class Duplicate:
    """One pose file's content (its sha256) recorded in the calibrations of more than one
    serial: at most one of them can have been measured on that unit. ``uses``: (serial, the
    file as that serial's calibration names it), one per serial, by serial."""

    sha256: str
    uses: tuple[tuple[str, str], ...]

    @property
    def serials(self) -> tuple[str, ...]:
        return tuple(serial for serial, _ in self.uses)

    def as_dict(self) -> dict[str, object]:
        return {"sha256": self.sha256, "serials": list(self.serials), "files": [f for _, f in self.uses]}


def duplicates(records: Iterable[tuple[str | None, str | None, str]]) -> list[Duplicate]:
    """The pose files (by sha256) recorded under two or more serials, from (serial, sha256,
    file) records. A serial's own files recorded twice (a unit calibrated again from the same
    captures) are not a duplicate; records without a serial or a sha256 cannot be compared."""
    seen: dict[str, dict[str, str]] = {}
    for serial, sha256, file in records:
        if serial and sha256:
            seen.setdefault(sha256, {}).setdefault(serial, file)
    found = [Duplicate(sha, tuple(sorted(uses.items()))) for sha, uses in seen.items() if len(uses) > 1]
    return sorted(found, key=lambda d: (d.serials, d.sha256))


def duplicate_warnings(found: Iterable[Duplicate]) -> list[str]:
    """One line for each set of serials that share pose files, naming the serials and the files
    (each serial's own name for them when the names differ), by serials then file."""
    groups: dict[tuple[str, ...], list[Duplicate]] = {}
    for d in found:
        groups.setdefault(d.serials, []).append(d)
    lines = []
    for serials, shared in sorted(groups.items()):
        shared.sort(key=lambda d: d.uses)
        who = " and ".join(serials) if len(serials) == 2 else ", ".join(serials)
        what = "the same pose file" if len(shared) == 1 else f"the same {len(shared)} pose files"
        sha = f" (sha256 {shared[0].sha256[:12]})" if len(shared) == 1 else ""
        if all(len({f for _, f in d.uses}) == 1 for d in shared):  # each file by one name
            named = ", ".join(d.uses[0][1] for d in shared)
        else:
            named = "; ".join(f"{s}: {', '.join(d.uses[k][1] for d in shared)}" for k, s in enumerate(serials))
        lines.append(f"{who} record {what}{sha}: {named}: at most one of them measured that unit")
    return lines


def duplicate_of(found: Iterable[Duplicate]) -> dict[str, list[str]]:
    """Each serial in ``found`` and the other serials that share a pose file with it, sorted."""
    out: dict[str, set[str]] = {}
    for d in found:
        for serial in d.serials:
            out.setdefault(serial, set()).update(s for s in d.serials if s != serial)
    return {serial: sorted(others) for serial, others in out.items()}


# --- statistics ---------------------------------------------------------------------------------


def bounds(parameter: str, limits: Mapping[str, float | FloatArray]) -> tuple[float | None, float | None]:
    """(lower, upper) specification limits of a parameter from a ``limitfile.load_limits`` dict,
    as ``gate.verdict`` judges a single unit: |offset − nominal| ≤ L, |gain / nominal − 1| ≤ e, |cross| ≤ L.
    (None, None) when the limits do not bound it."""
    family, _, name = parameter.partition(".")
    if family == "offset" and limits.get("offset") is not None:
        bound = _axis(limits["offset"], name)
        centre = _axis(limits["nominal_offset"], name) if limits.get("nominal_offset") is not None else 0.0
        return (centre - bound, centre + bound)
    if family == "gain" and limits.get("gain_error") is not None:
        error = _axis(limits["gain_error"], name)
        nominal = _axis(limits["nominal_gain"], name) if limits.get("nominal_gain") is not None else 1.0
        return (nominal * (1.0 - error), nominal * (1.0 + error))
    if family == "cross" and limits.get("cross_axis") is not None:
        bound = float(limits["cross_axis"])
        return (-bound, bound)
    return (None, None)


def _axis(value: float | FloatArray, axis: str) -> float:
    """One axis of a per-axis limit: a number, or an [x, y, z] list or (3,) array."""
    array = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,))
    return float(array[AXES.index(axis)])


def cpk(values: Sequence[float] | FloatArray, lower: float | None, upper: float | None) -> float | None:
    """Process capability index Cpk = min(USL − μ, μ − LSL) / 3σ, with σ the sample standard
    deviation (ddof=1); with one specification limit, the one-sided index (CPU or CPL). None when
    there are fewer than 2 values, σ is 0, or there is no limit."""
    # Source: AIAG 2005, Statistical Process Control (SPC) reference manual, 2nd ed., ch. IV
    # (CPU = (USL − X̄)/3σ, CPL = (X̄ − LSL)/3σ, Cpk = min); Montgomery, Introduction to Statistical
    # Quality Control, ch. 8 (process capability; one-sided Cpu / Cpl). A lot of calibrations has no
    # rational subgroups, so σ is the overall sample σ (ddof=1): what AIAG calls Ppk; the report
    # names it Cpk, the term stations use.
    x = np.asarray(values, dtype=np.float64)
    if len(x) < 2 or (lower is None and upper is None):
        return None
    sigma = float(np.std(x, ddof=1))
    if not sigma > 0:
        return None
    mu = float(np.mean(x))
    sides = []
    if upper is not None:
        sides.append((upper - mu) / (3.0 * sigma))  # CPU
    if lower is not None:
        sides.append((mu - lower) / (3.0 * sigma))  # CPL
    return min(sides)


#: The fewest units a Cpk interval is given for (Bissell 1990 is good from about 30, rough below).
CPK_INTERVAL_MIN = 10


def cpk_interval(value: float | None, n: int, z: float = 1.959964) -> tuple[float | None, float | None]:
    """Two-sided confidence interval of Cpk from n values (95 % with the default z): Bissell 1990's
    normal approximation, Cpk ± z·√(1/(9n) + Cpk²/(2(n − 1))). (None, None) without a Cpk, or
    from fewer than CPK_INTERVAL_MIN values, where it is wider than anything it could tell (2 units
    of Cpk 21.9 gave -8.45 to 52.2)."""
    # Source: Bissell 1990, "How reliable is your capability index?", Applied Statistics 39(3),
    # eq. for the standard error of Ĉpk (normal data; good from about n = 30, rough below).
    if value is None or n < CPK_INTERVAL_MIN:
        return (None, None)
    half = z * math.sqrt(1.0 / (9.0 * n) + value * value / (2.0 * (n - 1.0)))
    return (value - half, value + half)


def robust_z(values: Sequence[float] | FloatArray) -> FloatArray:
    """Modified z-score of each value: 0.6745·(x − median) / MAD. When MAD is 0 (more than half
    the values equal), (x − median) / (1.253314·MeanAD) with MeanAD the mean absolute deviation
    from the median; when that is 0 too (all equal), zeros."""
    # Source: Iglewicz and Hoaglin 1993, "How to Detect and Handle Outliers", ASQC Basic References
    # in Quality Control vol. 16: M_i = 0.6745·(x_i − x̃)/MAD (0.6745: the 0.75 normal quantile,
    # so M_i ~ z for normal data). The MAD = 0 fallback with MeanAD·1.253314 (√(π/2): E|X − μ| = σ·√(2/π)
    # for normal data) is the one IBM documents for its modified z score (Cognos Analytics / SPSS).
    x = np.asarray(values, dtype=np.float64)
    if len(x) == 0:
        return np.zeros(0)
    deviation = x - np.median(x)
    mad = float(np.median(np.abs(deviation)))
    if mad > 0:
        z: FloatArray = 0.6745 * deviation / mad
        return z
    mean_ad = float(np.mean(np.abs(deviation)))
    if mean_ad > 0:
        fallback: FloatArray = deviation / (1.253314 * mean_ad)
        return fallback
    return np.zeros(len(x))


@dataclass(frozen=True)
class ParameterRow:
    """Statistics of one parameter of one sensor over the lot. ``outliers``: (serial, or the file's
    name when it has none; value; t against the other units) flagged by the report's
    ``OutlierRule``, largest |t| first; ``outlier_limit`` the |t| beyond which a unit is flagged
    (None: the figure has too few units to be judged)."""

    sensor: str
    parameter: str
    count: int
    mean: float
    std: float | None
    min: float
    max: float
    lower: float | None
    upper: float | None
    cpk: float | None
    outliers: list[tuple[str, float, float]]
    outside: list[str] = field(default_factory=list)  # units whose value is beyond a limit
    outlier_limit: float | None = None
    cpk_low: float | None = None  # 95 % confidence interval of cpk (cpk_interval)
    cpk_high: float | None = None


@dataclass(frozen=True)
class ParameterDrift:
    """How one parameter of a re-calibrated unit moved: latest minus the calibration before it.
    ``limit`` is from ``--max-drift``; for a gain it bounds the relative change
    (``relative`` = change / previous gain), for offsets and cross terms the change itself."""

    sensor: str
    serial: str
    previous: str
    latest: str
    previous_created: str
    latest_created: str
    parameter: str
    change: float
    limit: float | None
    flagged: bool
    relative: float | None = None


def parse_max_drift(text: str | Mapping[str, float] | None) -> dict[str, float]:
    """``offset=0.01,gain=0.002,cross=0.001`` (any subset; ``cross_axis`` is ``cross``; or a
    mapping of the same) as a dict. None: no drift limits."""
    if text is None:
        return {}
    if isinstance(text, Mapping):
        text = ",".join(f"{k}={v}" for k, v in text.items())
    out: dict[str, float] = {}
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise _drift_error(said("drift.empty"))
    for item in items:
        key, equals, value = (part.strip() for part in item.partition("="))
        if not equals:
            raise _drift_error(said("drift.item", item=item))
        key = DRIFT_ALIASES.get(key, key)
        if key not in DRIFT_KEYS:
            raise _drift_error(said("drift.key", key=key, known=", ".join(DRIFT_KEYS)))
        if key in out:
            raise _drift_error(said("drift.twice", key=key))
        try:
            number = float(value)
        except ValueError:
            raise _drift_error(said("drift.number", key=key, value=value)) from None
        if not (math.isfinite(number) and number > 0):
            raise _drift_error(said("drift.positive", key=key, value=value))
        out[key] = number
    return out


def _drift_error(words: Said) -> InputError:
    """A refused drift limit: its words (pipeline.hints), and the form that works."""
    return InputError(words, hint=DRIFT_HINT)


def drift(entries: Iterable[Entry], max_drift: dict[str, float]) -> list[ParameterDrift]:
    """For every (sensor, serial) calibrated at least twice: each parameter both of its last two
    calibrations have, latest minus previous (by ``created``, ties by path). Sorted by serial,
    sensor, then parameter in the report's order."""
    history: dict[tuple[str, str], list[Entry]] = {}
    for e in entries:
        if e.serial is not None:
            history.setdefault((e.sensor, e.serial), []).append(e)
    out: list[ParameterDrift] = []
    for (sensor, serial), cals in history.items():
        if len(cals) < 2:
            continue
        previous, latest = sorted(cals, key=_when)[-2:]
        for parameter in PARAMETERS:
            if parameter not in previous.values or parameter not in latest.values:
                continue  # e.g. a one-pose calibration (no gains) after a three-pose one
            before, after = previous.values[parameter], latest.values[parameter]
            change = after - before
            family = parameter.partition(".")[0]
            limit = max_drift.get(family)
            relative = change / before if family == "gain" and before != 0 else None
            measured = abs(relative) if family == "gain" and relative is not None else abs(change)
            out.append(
                ParameterDrift(
                    sensor=sensor,
                    serial=serial,
                    previous=previous.path,
                    latest=latest.path,
                    previous_created=previous.created,
                    latest_created=latest.created,
                    parameter=parameter,
                    change=change,
                    limit=limit,
                    flagged=limit is not None and measured > limit,
                    relative=relative,
                )
            )
    order = {sensor: k for k, sensor in enumerate(SENSORS)}
    out.sort(key=lambda d: (d.serial, order.get(d.sensor, len(order)), d.sensor, PARAMETERS.index(d.parameter)))
    return out


# --- the report ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Report:
    """What ``tumblecal report`` shows. ``files``: calibration files found (read or not);
    ``units``: entries in the lot statistics (the latest per unit)."""

    files: int
    units: int
    rows: list[ParameterRow]
    drift: list[ParameterDrift]
    unreadable: list[tuple[str, str]]
    min_cpk: float | None = None
    duplicates: list[Duplicate] = field(default_factory=list)
    outlier_rule: OutlierRule = field(default_factory=OutlierRule)

    @property
    def needs_attention(self) -> bool:
        """Any unit outside a limit, any outlier, any flagged drift, the same pose file under
        two serials, or (with ``min_cpk``) any Cpk below it."""
        if any(row.outliers or row.outside for row in self.rows) or any(d.flagged for d in self.drift):
            return True
        if self.duplicates:
            return True
        threshold = self.min_cpk
        return threshold is not None and any(row.cpk is not None and row.cpk < threshold for row in self.rows)

    @property
    def outlier_text(self) -> str:
        """The outlier rule this report used, in one sentence."""
        return self.outlier_rule.describe(max((row.count for row in self.rows), default=0))

    def as_dict(self) -> dict[str, object]:
        """JSON-ready: plain floats, ints, strings and None (NaN and infinities are None)."""
        return {
            "files": self.files,
            "units": self.units,
            "min_cpk": _plain(self.min_cpk),
            "needs_attention": self.needs_attention,
            "outlier_rule": self.outlier_rule.as_dict() | {"text": self.outlier_text},
            "parameters": [
                {
                    "sensor": row.sensor,
                    "parameter": row.parameter,
                    "count": row.count,
                    "mean": _plain(row.mean),
                    "std": _plain(row.std),
                    "min": _plain(row.min),
                    "max": _plain(row.max),
                    "lower": _plain(row.lower),
                    "upper": _plain(row.upper),
                    "cpk": _plain(row.cpk),
                    "cpk_interval": [_plain(row.cpk_low), _plain(row.cpk_high)],
                    "outliers": [{"unit": u, "value": _plain(v), "t": _plain(z)} for u, v, z in row.outliers],
                    "outlier_limit": _plain(row.outlier_limit),
                    "outside": list(row.outside),
                }
                for row in self.rows
            ],
            "drift": [
                {
                    "sensor": d.sensor,
                    "serial": d.serial,
                    "parameter": d.parameter,
                    "previous": d.previous,
                    "latest": d.latest,
                    "previous_created": d.previous_created,
                    "latest_created": d.latest_created,
                    "change": _plain(d.change),
                    "relative": _plain(d.relative),
                    "limit": _plain(d.limit),
                    "flagged": d.flagged,
                }
                for d in self.drift
            ],
            "unreadable": [{"file": path, "error": message} for path, message in self.unreadable],
            "duplicates": [d.as_dict() for d in self.duplicates],
        }

    def csv_rows(self) -> tuple[list[str], list[list[str]]]:
        """(header, rows) of the report as CSV text cells: one row per sensor and parameter;
        numbers at full precision (``repr``), an empty cell for none; ``outliers`` as
        ``SN1=5.2;SN7=-4.4`` (unit=t against the other units), ``drift_flagged`` the serials whose
        drift of that parameter is flagged, ``outlier_rule`` the rule that figure was judged by."""
        flagged: dict[tuple[str, str], list[str]] = {}
        for d in self.drift:
            if d.flagged:
                flagged.setdefault((d.sensor, d.parameter), []).append(d.serial)
        rows = []
        for row in self.rows:
            rows.append(
                [
                    row.sensor,
                    row.parameter,
                    str(row.count),
                    *(_cell(v) for v in (row.mean, row.std, row.min, row.max, row.lower, row.upper, row.cpk)),
                    ";".join(f"{unit}={z:.1f}" for unit, _, z in row.outliers),
                    ";".join(flagged.get((row.sensor, row.parameter), [])),
                    ";".join(row.outside),
                    self.outlier_rule.cell(row.count, row.outlier_limit),
                    _cell(row.cpk_low),
                    _cell(row.cpk_high),
                ]
            )
        return list(CSV_HEADER), rows


def _plain(value: float | None) -> float | None:
    if value is None:
        return None
    number = float(value)
    return number if math.isfinite(number) else None


def split_by_units(entries: Sequence[Entry]) -> list[Entry]:
    """The entries, a sensor calibrated in more than one kind of units named with its units."""
    kinds: dict[str, set[str]] = {}
    for e in entries:
        kinds.setdefault(e.sensor, set()).add(e.units)
    return [replace(e, sensor=f"{e.sensor} ({e.units})") if len(kinds[e.sensor]) > 1 else e for e in entries]


def _cell(value: float | None) -> str:
    plain = _plain(value)
    return "" if plain is None else repr(plain)


def summarise(
    entries: Sequence[Entry],
    unreadable: Sequence[tuple[str, str]],
    limits: Mapping[str, float | FloatArray],
    *,
    max_drift: dict[str, float],
    min_cpk: float | None = None,
    outlier_alpha: float = OUTLIER_ALPHA,
) -> Report:
    """The lot report: statistics over the latest calibration of each unit (module docstring),
    bounded by ``limits`` (a ``limitfile.load_limits`` dict, possibly empty), and the drift of every
    re-calibrated unit against ``max_drift`` (``parse_max_drift``).

    Calibrations of one sensor in different units (counts to g beside m/s² to m/s²) are not
    one population: each kind is reported apart, as "accelerometer (m/s^2)".

    Outliers: ``outliers.OutlierRule`` at the lot-wide false-alarm rate ``outlier_alpha``, over
    every unit of every figure of the report."""
    check_alpha(outlier_alpha)
    members = split_by_units(lot(entries))  # the latest of each unit first: a unit counts once
    order = {sensor: k for k, sensor in enumerate(SENSORS)}
    sensors = sorted({e.sensor for e in members}, key=lambda s: (order.get(s, len(order)), s))
    figures = []
    for sensor in sensors:
        group = [e for e in members if e.sensor == sensor]
        for parameter in PARAMETERS:
            having = [e for e in group if parameter in e.values]
            if having:
                figures.append((sensor, parameter, having))
    rule = OutlierRule(outlier_alpha, sum(len(having) for _, _, having in figures))
    rows = [_row(sensor, parameter, having, limits, rule) for sensor, parameter, having in figures]
    return Report(
        files=len(entries) + len(unreadable),
        units=len(members),
        rows=rows,
        drift=drift(entries, max_drift),
        unreadable=list(unreadable),
        min_cpk=min_cpk,
        duplicates=duplicates((e.serial, sha, file) for e in entries for sha, file in e.poses),
        outlier_rule=rule,
    )


def _row(
    sensor: str, parameter: str, having: list[Entry], limits: Mapping[str, float | FloatArray], rule: OutlierRule
) -> ParameterRow:
    x = np.array([e.values[parameter] for e in having])
    lower, upper = bounds(parameter, limits)
    flagged, t = rule.flags(x)
    outliers = [
        (e.serial if e.serial is not None else os.path.basename(e.path), float(v), float(ti))
        for e, v, ti, flag in zip(having, x, t, flagged, strict=True)
        if flag
    ]
    outliers.sort(key=lambda o: (-abs(o[2]), o[0]))
    outside = sorted(
        e.serial if e.serial is not None else os.path.basename(e.path)
        for e, v in zip(having, x, strict=True)
        if (lower is not None and v < lower) or (upper is not None and v > upper)
    )
    capability = cpk(x, lower, upper)
    low, high = cpk_interval(capability, len(x))
    return ParameterRow(
        sensor=sensor,
        parameter=parameter,
        count=len(x),
        mean=float(np.mean(x)),
        std=float(np.std(x, ddof=1)) if len(x) >= 2 else None,
        min=float(np.min(x)),
        max=float(np.max(x)),
        lower=lower,
        upper=upper,
        cpk=capability,
        outliers=outliers,
        outside=outside,
        outlier_limit=rule.figure_limit(len(x)),
        cpk_low=low,
        cpk_high=high,
    )
