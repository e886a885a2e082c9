"""solve --sensor gyroscope --spin RATE=FILE: a gyroscope spun at known rates (a rate table, a
record player at 33⅓ and 45 rpm), its offset, gains and cross-axis terms fitted to the files'
steady runs (core.spin).

``RATE`` has its unit (``45rpm``, ``33.333rpm``, ``270deg/s``, ``4.712rad/s``; ``0`` for rest;
a minus sign for the other direction, with a face); ``+z@45rpm=FILE`` says that axis pointed up, the platter
turning counter-clockwise seen from above, which fixes the signs and the misalignment the
magnitude alone cannot. Each file's steady runs at its stated rate are used; the platter's
spin-up and spin-down, the handling between orientations and the runs at another rate are left
out and named by rows (a note, ``outliers`` in the file and in --json).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import gate, model, quantities, robust, spin
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.core.solvers import Fit
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.calfiles.calparts import LeftOut, LeftOutStretch, Pose
from tumblecal_cli.io.csv import readings
from tumblecal_cli.pipeline.options import axes_given
from tumblecal_cli.pipeline.solve.turns import Outcome

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.axes import Axes
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.io.readspec import ReadSpec
    from tumblecal_cli.pipeline.options import Settings, SolveOptions

#: RATE of --spin: an optional face and @, a signed number, its unit (none for 0).
SPIN = re.compile(
    r"\s*(?:(?P<face>[+-][xyzXYZ])\s*@\s*)?(?P<number>[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(?P<unit>\S*)\s*"
)
#: Revolutions per minute, beside core.quantities' units of angular rate (rad/s each).
RPM = 2.0 * math.pi / 60.0
#: A rate beyond this (rad/s: about 1,900 rpm, 11,000 deg/s) is no table's or platter's.
MAX_RATE = 200.0
#: Seconds of readings per window of the steady-run detector, and the shortest run kept.
WINDOW_S, MIN_RUN_S = 0.5, 1.0
#: Samples per window when the files have no clock (no time column, no --rate).
WINDOW_SAMPLES = 25
#: Fewest runs in different orientations the magnitude fit (orientation unknown) is made from.
MIN_RUNS = 7
#: Readings whose magnitude at the stated rates is within this share of a unit are in it.
UNITS_SLACK = 0.25
#: A labelled run further off its fit than this share of its rate turned about another axis.
MISPLACED = 0.2
#: The runs' scatter about the fit beyond this share of the largest rate is warned of.
SCATTER_SHARE = 0.005


@dataclass(frozen=True)
class Spin:
    """One --spin item: as given, the rate (rad/s, signed), the face up (None: not said), the file."""

    text: str
    rate: float
    face: str | None
    file: str


def parse(item: str) -> Spin:
    """``RATE=FILE`` (``+z@45rpm=FILE``) as a Spin; an InputError naming the item otherwise."""
    rate_text, sep, path = item.partition("=")
    found = SPIN.fullmatch(rate_text)
    usage = "give RATE=FILE, the rate with its unit: 45rpm=a.csv, 270deg/s=b.csv, 0=rest.csv, +z@45rpm=c.csv"
    if not sep or not path or found is None:
        raise InputError(f"--spin {item!r}: {usage}")
    value, unit = float(found.group("number")), found.group("unit")
    if unit in ("rpm", "RPM"):
        per = RPM
    elif unit:
        measure = quantities.UNITS.get(unit)
        if measure is None or measure.quantity != quantities.ANGULAR_RATE:
            raise InputError(f"--spin {item!r}: {unit!r} is not a unit of angular rate (rpm, rad/s, deg/s)")
        per = measure.factor
    elif value == 0:
        per = 1.0
    else:
        raise InputError(f"--spin {item!r}: the rate has no unit: {usage}")
    rate = value * per
    if not math.isfinite(rate) or abs(rate) > MAX_RATE:
        raise InputError(
            f"--spin {item!r}: {abs(value):g} {unit} is no rate table's or platter's (at most {MAX_RATE / RPM:.0f} rpm)"
        )
    face = found.group("face")
    if rate < 0 and face is None:
        raise InputError(
            f"--spin {item!r}: a minus sign turns a labelled face the other way (+z@{rate_text.strip()}={path}); "
            "without a face the fit sees only the rate's size",
            hint="give the rate without its sign, or the face that pointed up",
        )
    return Spin(rate_text.strip(), rate, None if face is None else face.lower(), path)


@dataclass(frozen=True)
class SpinFile:
    """A --spin file read: its Spin, its readings (corrected, for verify), their steady runs, and
    the median magnitude of its readings as read (raw units)."""

    given: Spin
    log: Log
    runs: list[spin.Run]
    raw_median: float


def solve_spins(options: SolveOptions, given: Settings) -> Outcome:
    """The gyroscope's calibration from its --spin files (module docstring)."""
    if options.read.sensor != "gyroscope":
        raise InputError(
            f"--spin spins a gyroscope at known rates, not the {options.read.sensor}'s",
            hint="give --sensor gyroscope (and the gyroscope's columns)",
        )
    if given.method not in ("auto", "known-rates"):
        raise InputError(f"--spin is solved by the known-rates method, not {given.method}", hint="leave --method out")
    spins = [parse(item) for item in options.spin]
    if not any(s.rate for s in spins):
        raise InputError("--spin gives no turning rate: only rest (0=FILE) gives no gains", hint="add 45rpm=FILE ...")
    files = [read(s, options.read) for s in spins]
    _once(files)
    units = _units(files, options)
    scale = quantities.UNITS[units.out].factor
    slowest = min(abs(s.rate) for s in spins if s.rate) / scale
    chosen, notes, left = [], [units.note] if units.note else [], []
    for f in files:
        used, said, out = runs_at_rate(f, f.given.rate / scale, units.gain, slowest, units.out)
        chosen += [(f, r) for r in used]
        notes.append(said)
        left += out
    axes = axes_given(options.axes)  # a labelled face is the body's: the sensor's direction along it is fitted
    runs = [spin.SpinRun(r.mean, r.stderr, f.given.rate / scale, _face(f.given.face, axes)) for f, r in chosen]
    _enough(runs, files)
    try:
        fit = spin.fit_rates(runs, trim=not options.no_robust)
    except CaptureRejected as err:  # most runs off any one fit: named on the first file, as the others
        raise _rejected(err.message, files[0].log.layout.name, "check each file's rate and face") from None
    _determined(fit, runs, chosen)
    trimmed = [(f, r) for (f, r), keep in zip(chosen, fit.kept, strict=True) if not keep]
    notes += [
        f"{f.log.layout.name} rows {_row(f, r.first)}–{_row(f, r.last)}: off the fit by {res:.3g} {units.out}, left out"
        for (f, r), res in zip(trimmed, fit.residuals[~fit.kept], strict=True)
    ]
    notes += _off_rate(fit, runs, chosen)
    return _outcome(fit, runs, chosen, (left, trimmed), notes, options, given, units)


def _off_rate(fit: spin.RateFit, runs: list[spin.SpinRun], chosen: list[tuple[SpinFile, spin.Run]]) -> list[str]:
    """A warning when one file's runs read, as calibrated, a rate off the others' by more than
    SCATTER_SHARE (its platter at another speed than stated: a gain the fit cannot tell from it),
    or when the runs scatter about the fit by more than that (the unit loose on the platter)."""
    ratio: dict[str, list[float]] = {}
    for (f, _), r in zip(chosen, runs, strict=True):
        if r.rate:
            read = float(np.linalg.norm(fit.matrix @ (r.mean - fit.offset)))
            ratio.setdefault(f.log.layout.name, []).append(read / abs(r.rate) - 1.0)
    means = {name: float(np.mean(v)) for name, v in ratio.items()}
    out = []
    if len(means) > 1:
        middle = float(np.median(list(means.values())))
        name, off = max(((n, m - middle) for n, m in means.items()), key=lambda p: abs(p[1]))
        if abs(off) > SCATTER_SHARE:
            out.append(
                f"warning: {name}'s runs read {off:+.2%} off the other files' as calibrated: is its rate the one "
                "stated? (a platter's speed varies by a few tenths of a percent; a gain cannot be told from it)"
            )
    largest = max(abs(r.rate) for r in runs)
    if not out and fit.scatter > SCATTER_SHARE * largest:
        out.append(
            f"warning: the runs scatter about the fit by {fit.scatter / largest:.2%} of the largest rate, where a "
            "platter's speed varies by a few tenths of a percent: the unit loose on the platter?"
        )
    return out


def _face(face: str | None, axes: Axes | None) -> FloatArray | None:
    """A --spin face (the body's, with --axes) as the unit vector of the sensor's direction up."""
    if face is None:
        return None
    up = model.direction(face)
    return up if axes is None else axes.matrix.T @ up


def _once(files: list[SpinFile]) -> None:
    """A file given twice (by name, or the same bytes) would count its runs twice: false precision."""
    seen: dict[str, str] = {}
    for f in files:
        key = f.log.sha256 or f.given.file
        if key in seen:
            raise InputError(
                f"--spin gives this file twice ({seen[key]} and {f.given.text}={f.given.file}): its runs would count "
                "twice",
                file=f.log.layout.name,
                hint="give each file once",
            )
        seen[key] = f"{f.given.text}={f.given.file}"


def _determined(fit: spin.RateFit, runs: list[spin.SpinRun], chosen: list[tuple[SpinFile, spin.Run]]) -> None:
    """A fit the runs do not determine (their spin axes in too few directions), or a labelled run its
    fit cannot place near its face (the label wrong): exit 3, naming it."""
    gains = np.abs(np.diag(np.linalg.inv(fit.matrix))) if np.all(np.isfinite(fit.matrix)) else np.zeros(3)
    if not (np.all(np.isfinite(fit.gain_se)) and np.all(gains > 0)) or float((fit.gain_se / gains).max()) > 0.1:
        raise _rejected(
            "the runs do not determine the gains: their spin axes do not point along the sensor's three axes",
            chosen[0][0].log.layout.name,
            "place the unit in more orientations on the platter (each axis up and tilted), or label the faces",
        )
    for (f, r), run, res in zip(chosen, runs, fit.residuals, strict=True):
        if run.face is not None and run.rate and res > MISPLACED * abs(run.rate):
            raise _rejected(
                f"rows {_row(f, r.first)}–{_row(f, r.last)} turn about another axis than {f.given.face} says "
                f"(off the fit by {res / abs(run.rate):.0%} of the rate)",
                f.log.layout.name,
                "check the face that pointed up (+z@45rpm: +z up, the platter counter-clockwise seen from above)",
            )


def read(s: Spin, spec: ReadSpec, cal: Calibration | None = None) -> SpinFile:
    """A --spin file's readings (corrected by ``cal`` when given: verify's) and their steady runs."""
    if not os.path.exists(s.file) and s.file != "-":
        raise InputError(f"--spin {s.text}={s.file}: no such file")
    log = readings.read_log(s.file, replace(spec, sensor="gyroscope"), use_time=spec.rate is None)
    model.in_range(log.values, log.layout.name)
    finite = np.isfinite(log.values).all(axis=1)
    if not finite.all():
        log = replace(log, values=log.values[finite], rows=log.rows[finite])
    raw_median = float(np.median(np.linalg.norm(log.values, axis=1))) if len(log.values) else math.nan
    if cal is not None:
        log = replace(log, values=cal.apply(log.values))
    window = WINDOW_SAMPLES
    seconds = None if spec.rate else log.seconds()
    period = 1.0 / spec.rate if spec.rate else None
    if period is None and seconds is not None and len(seconds) > 1:
        steps = np.diff(seconds)
        period = float(np.median(steps[steps > 0])) if (steps > 0).any() else None
    if period:
        window = max(round(WINDOW_S / period), 4)
    return SpinFile(s, log, spin.steady_runs(log.values, window, 2 * window), raw_median)


@dataclass(frozen=True)
class Units:
    """The corrected units, the readings' gain in them (raw per corrected unit: a rough one when
    the raw units are not known), the raw units (None: counts, or not known) and a note when they
    were judged from the readings."""

    out: str
    gain: float
    raw: str | None
    note: str | None


def _units(files: list[SpinFile], options: SolveOptions) -> Units:
    """The units (:class:`Units`): --units names the corrected ones (else the readings'), the
    readings' are --input-units' (checked against their magnitude at the stated rates: a units
    mistake is exit 2) or judged from that magnitude (rad/s, deg/s, or counts of their own)."""
    magnitudes, rates = [], []
    for f in files:
        if f.given.rate and f.runs:
            m = np.array([np.linalg.norm(r.mean) for r in f.runs])
            n = np.array([r.samples for r in f.runs])
            keep = m >= 0.5 * m.max()
            magnitudes.append(float(np.average(m[keep], weights=n[keep])))
            rates.append(abs(f.given.rate))
    ratio = float(np.median(np.array(magnitudes) / np.array(rates))) if magnitudes else 1.0  # raw per rad/s
    if options.units is not None and _rate_unit(options.units) is None:
        raise InputError(f"--units {options.units}: --spin corrects into a unit of angular rate: rad/s or deg/s")
    raw, note = _raw_unit(options.input_units, ratio, files)
    out = (options.units or raw or "rad/s").strip()
    per = quantities.UNITS[out].factor
    gain = per / quantities.UNITS[raw].factor if raw is not None else ratio * per
    if raw is None and options.input_units is None:
        note = f"the readings are in units of their own ({ratio:.4g} a rad/s): corrected into {out}"
    return Units(out, gain, raw, note)


def _rate_unit(name: str) -> str | None:
    measure = quantities.UNITS.get(name.strip())
    return name.strip() if measure is not None and measure.quantity == quantities.ANGULAR_RATE else None


def _raw_unit(given: str | None, ratio: float, files: list[SpinFile]) -> tuple[str | None, str | None]:
    """The readings' unit and a note: --input-units' when it is a unit of angular rate (its
    magnitude at the stated rates within 25 % of it, else exit 2), None for counts or another
    name; without it, rad/s or deg/s when the magnitude says one of them."""
    if given is not None:
        unit = _rate_unit(given)
        if unit is None:
            return None, None
        expected = 1.0 / quantities.UNITS[unit].factor  # raw per rad/s
        if abs(ratio / expected - 1.0) > UNITS_SLACK:
            spun = next(f for f in files if f.given.rate and f.runs)
            raise InputError(
                f"its readings at {spun.given.text} are {ratio * abs(spun.given.rate):.4g} a reading, "
                f"{ratio / expected:.3g} times what --input-units {given} says",
                file=spun.log.layout.name,
                hint="check --input-units (rad/s, deg/s; counts for raw counts), or leave it out to judge it by the "
                "readings",
            )
        return unit, None
    for unit in ("rad/s", "deg/s"):
        if abs(ratio * quantities.UNITS[unit].factor - 1.0) < UNITS_SLACK:
            return unit, f"the readings are taken as {unit}, the units their magnitude at the stated rates says"
    return None, None


def _row(f: SpinFile, k: int) -> int:
    return int(f.log.rows[min(k, len(f.log.rows) - 1)])


def _spans(f: SpinFile, used: list[spin.Run]) -> list[tuple[int, int]]:
    """The stretches of samples of ``f`` outside the runs ``used`` (first, last; 0-based)."""
    inside = np.zeros(len(f.log.values), dtype=bool)
    for r in used:
        inside[r.first : r.last + 1] = True
    edges = np.flatnonzero(np.diff(np.concatenate([[1], inside.astype(np.int8), [1]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def runs_at_rate(
    f: SpinFile, rate: float, gain: float, slowest: float, units: str
) -> tuple[list[spin.Run], str, list[tuple[SpinFile, int, int]]]:
    """The runs of ``f`` at its stated rate, what to say of them, and the stretches left out."""
    name, said = f.log.layout.name, f"{f.given.text} ({rate:.4g} {units})"
    if not f.runs:
        raise _rejected(
            f"{said}: no steady stretch of {MIN_RUN_S:g} s or more: the file does not spin (or rest) at a constant "
            "rate",
            name,
            "give each --spin the file of its rate; `tumblecal segment --sensor gyroscope` lists a log's stretches",
        )
    magnitudes = np.array([np.linalg.norm(r.mean) for r in f.runs]) / gain
    at = magnitudes <= spin.AT_RATE * slowest if rate == 0 else np.abs(magnitudes / abs(rate) - 1.0) <= spin.AT_RATE
    used = [r for r, ok in zip(f.runs, at, strict=True) if ok]
    if not used:
        held = ", ".join(f"{m:.4g}" for m in sorted({round(float(x), 4) for x in magnitudes})[:6])
        raise _rejected(
            f"{said}: no steady stretch at that rate; its steady stretches turn at {held} {units}",
            name,
            "check the file's rate (a platter's 33⅓ and 45 rpm are 3.491 and 4.712 rad/s) and its units (--units)",
        )
    out = [(f, a, b) for a, b in _spans(f, used)]
    rows = ", ".join(f"{_row(f, a)}–{_row(f, b)}" for _, a, b in out[:4]) + (" …" if len(out) > 4 else "")
    left = sum(b - a + 1 for _, a, b in out)
    note = f"{name} at {said}: {len(used)} steady run{'s' if len(used) != 1 else ''} used"
    why = "handling, turning" if rate == 0 else "spin-up, handling, other rates"
    note += f"; {left:,} rows left out (rows {rows}: {why})" if left else ""
    return used, note, out


def _enough(runs: list[spin.SpinRun], files: list[SpinFile]) -> None:
    labelled = any(r.face is not None for r in runs)
    spinning = sum(1 for r in runs if r.rate != 0)
    if not labelled and spinning < MIN_RUNS:
        raise _rejected(
            f"{spinning} steady runs at the stated rates; the fit of an unknown orientation needs {MIN_RUNS} or more, "
            "in different orientations",
            files[0].log.layout.name,
            "place the unit on the platter in more orientations (each axis up, and tilted), or label each file's "
            "face (+z@45rpm=FILE)",
        )


def _rejected(message: str, name: str, hint: str) -> CaptureRejected:
    return CaptureRejected(message, file=name, hint=hint, code="spin.runs")


def _outcome(
    fit: spin.RateFit,
    runs: list[spin.SpinRun],
    chosen: list[tuple[SpinFile, spin.Run]],
    left: tuple[list[tuple[SpinFile, int, int]], list[tuple[SpinFile, spin.Run]]],
    notes: list[str],
    options: SolveOptions,
    given: Settings,
    said: Units,
) -> Outcome:
    """The calibration of the fit, judged by the limits; its poses the runs used."""
    solution = model.Solution("known-rates", fit.offset, fit.matrix, fit.offset_se, fit.gain_se)
    limits = given.limits.for_method(solution.method)
    failures: list[Finding] = gate.verdict(solution.method, solution.offset, solution.matrix, [], limits)
    poses = [_pose(f, r, kept) for (f, r), kept in zip(chosen, fit.kept, strict=True) if kept]
    first, units = chosen[0][0].log, said.out
    basis = calfile.Basis("gyroscope", 0.0, first.layout.sensor_names, units, options.input_units or said.raw)
    residuals = fit.residuals[fit.kept]
    cal = calfile.build(
        solution,
        basis,
        poses,
        fit=Fit(solution, residuals=residuals, covariance=fit.covariance, cross_se=fit.cross_se if fit.full else None),
        unit=given.unit,
        verdict=calfile.Verdict(not failures, tuple(failures), limits),
        outliers=_left_out(left, chosen, fit, runs),
    )
    factors = spin.scale_factors(runs, fit)
    if factors:
        cal = _with_factors(cal, factors, units)
        notes += [_factor_line(a, units) for a in factors]
    notes.append(
        f"{'full M (faces labelled)' if fit.full else 'symmetric M (orientations unknown: the rotation is not seen)'}"
        f"; the runs' scatter about the fit {fit.scatter:.3g} {units} RMS"
    )
    return Outcome(1 if failures else 0, cal, cal, notes=notes, failures=failures)


def _pose(f: SpinFile, r: spin.Run, kept: bool) -> Pose:
    part = f.log.values[r.first : r.last + 1]
    return Pose(
        face=f.given.face,
        mean=r.mean,
        samples=r.samples,
        std=part.std(axis=0),
        file=f.log.layout.name,
        sha256=f.log.sha256,
        rows=(_row(f, r.first), _row(f, r.last)),
        label=f.given.text,
    )


def _left_out(
    left: tuple[list[tuple[SpinFile, int, int]], list[tuple[SpinFile, spin.Run]]],
    chosen: list[tuple[SpinFile, spin.Run]],
    fit: spin.RateFit,
    runs: list[spin.SpinRun],
) -> LeftOut | None:
    """The rows left out: between the runs used (spin-up, handling, other rates), and runs off the fit."""
    stretches = [LeftOutStretch(f.log.layout.name, (_row(f, a), _row(f, b)), None, None) for f, a, b in left[0]]
    largest = max(abs(r.rate) for r in runs)
    for (f, r), res in zip(left[1], fit.residuals[~fit.kept], strict=True):
        stretches.append(LeftOutStretch(f.log.layout.name, (_row(f, r.first), _row(f, r.last)), None, res / largest))
    if not stretches:
        return None
    count = sum(b - a + 1 for _, a, b in left[0]) + sum(r.samples for _, r in left[1])
    total = sum(len(f.log.values) for f in {id(f): f for f, _ in chosen}.values())
    scale = robust.FLOOR * largest
    return LeftOut(count, total, scale, tuple(stretches))


def _factor_line(a: spin.AxisScale, units: str) -> str:
    at = ", ".join(f"{f:.6g} at {r:+.4g}" for r, f in zip(a.rates, a.factors, strict=True))
    asym = "" if a.asymmetry_ppm is None else f", asymmetry {a.asymmetry_ppm:.0f} ppm"
    return (
        f"scale factor {a.axis} (raw per {units}): {at}; least squares {a.least_squares:.6g}, non-linearity "
        f"{a.nonlinearity_ppm:.0f} ppm of the largest rate{asym}"
    )


def _with_factors(cal: Calibration, factors: list[spin.AxisScale], units: str) -> Calibration:
    """The calibration with its ``scale_factors`` (IEEE Std 952/1431): a field of its own."""
    record = {
        "units": f"raw per {units}",
        "axes": [
            {
                "axis": a.axis,
                "rates": list(a.rates),
                "factors": list(a.factors),
                "least_squares": a.least_squares,
                "nonlinearity_ppm": a.nonlinearity_ppm,
                "asymmetry_ppm": a.asymmetry_ppm,
            }
            for a in factors
        ],
    }
    return replace(cal, fields={**cal.fields, "scale_factors": record}, order=(*cal.order, "scale_factors"))
