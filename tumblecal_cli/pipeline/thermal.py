"""thermal: temperature sweeps in, a calibration with a ``thermal`` block out.

The steps: read the base calibration (``io.calfiles.calfile``) and each sweep with its temperature column
(``io.csv.readings.read_log``), refuse a temperature that cannot carry a fit (constant, noise without
a trend, a swing too small for the order: exit 3), fit the drift (``core.drift.fit``), judge the
sweeps with the quality checks of ``solve`` on their readings with the drift removed
(``core.gate``: a pose that moved is exit 3), and add the block to the base calibration.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from tumblecal_cli.core import drift, gate, model
from tumblecal_cli.core.model import direction
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.figures import plots
from tumblecal_cli.io.readspec import ReadSpec, column_list
from tumblecal_cli.pipeline.options import keywords_known
from tumblecal_cli.pipeline.solve.solving import pose_items

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.drift import Sweep, ThermalFit
    from tumblecal_cli.core.gate import Finding
    from tumblecal_cli.io.calfiles.calfile import Calibration, Thermal
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.io.readspec import ReadSpec

#: The default of --min-swing (°C): the swing order 1 needs.
MIN_SWING = 10.0
#: A temperature outside these (°C) is no sweep's: a wrong column, a broken cell, kelvin read as °C.
COLDEST, HOTTEST = -273.15, 1000.0
#: A sweep whose trend moves less than this share of its readings' scatter is noise, not a sweep.
NOISE_SHARE = 0.5


@dataclass
class SweepRead:
    """One sweep as read: its item's face (the sensor's direction up), file, the log, its trend
    range (°C), and its face as told (the body's, for a calibration into --axes)."""

    face: str | None
    file: str
    log: Log
    trend: tuple[float, float]
    told: str | None = None


@dataclass
class ThermalResult:
    """The outcome of :func:`thermal`: the calibration with its ``thermal`` block, the fit, the
    sweeps read, and what a person should know (``warnings`` from the checks, ``notes``)."""

    calibration: Calibration
    fit: ThermalFit
    sweeps: list[SweepRead]
    warnings: list[Finding] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    status: int = 0


class ThermalKeywords(TypedDict, total=False):
    """thermal's options (docs/commands/thermal.md): the command line's long options in snake case."""

    temperature_column: str | None
    reference_temperature: float | None
    order: int | str
    min_swing: float
    max_noise: float | None
    max_tilt: float
    columns: str | Sequence[str] | None
    sensor: str | None
    stream: str | None
    allow_corrected: bool


def thermal(
    poses: Sequence[str | os.PathLike[str]],
    cal: Calibration | str | os.PathLike[str],
    **options: Unpack[ThermalKeywords],
) -> ThermalResult:
    """Fit the temperature drift of ``cal``'s sensor from still sweeps, as ``tumblecal thermal``.

    ``poses``: the items of the command line (``FILE`` or ``LABEL=FILE``, labelled as ``solve
    --poses`` takes them; a gyroscope's in any pose). ``order``: 1, 2, 3 or ``"auto"``
    (cross-validation over temperature). Input errors raise InputError; a sweep that cannot
    be trusted raises CaptureRejected (exit 3).
    """

    keywords_known(options, ThermalKeywords, "thermal")
    sensor, order, min_swing = options.get("sensor"), options.get("order", "auto"), options.get("min_swing", MIN_SWING)
    max_noise, max_tilt = options.get("max_noise"), options.get("max_tilt", 25.0)
    base = calfile.resolve(cal)
    if sensor is not None and sensor != base.sensor:
        raise InputError(
            f"--sensor {sensor}, but the base calibration's sensor is {base.sensor}",
            file=base.path,
            hint="give the calibration of the sensor the sweeps are of",
        )
    if base.sensor == "magnetometer":
        raise InputError("thermal fits an accelerometer's or a gyroscope's drift, not a magnetometer's", file=base.path)
    wanted = _order(order)
    if not 0 < min_swing <= 1000.0:
        raise InputError(f"--min-swing must be a positive number of °C up to 1000, got {min_swing:g}")
    t_ref = _reference_temperature(base, options.get("reference_temperature"))
    spec = ReadSpec(
        sensor=base.sensor,
        columns=column_list(options.get("columns")),
        temperature_column=options.get("temperature_column"),
        prefer=tuple(base.columns),
        stream=options.get("stream"),
        allow_corrected=options.get("allow_corrected", False),
    )
    read = _read(poses, base, spec)
    _judge_temperature(read, wanted, min_swing)
    sweeps = [drift.Sweep(r.log.values, _finite(r), None if r.face is None else _up(r.face)) for r in read]
    gyro = base.sensor == "gyroscope"
    gain_scale = np.zeros(3) if gyro else np.abs(base.gain) * base.reference
    swing = max(r.trend[1] for r in read) - min(r.trend[0] for r in read)
    allowed = [k for k in drift.ORDERS if drift.required_swing(k, min_swing) <= swing]
    fitted = drift.fit(sweeps, gain_scale=gain_scale, t_ref=t_ref, order=wanted)
    if wanted is None and fitted.drift.order not in allowed:  # auto: the best order the swing allows
        fitted = drift.fit(sweeps, gain_scale=gain_scale, t_ref=t_ref, order=max(allowed))
        fitted = replace(fitted, order_auto=True)
    warnings = _checks(read, sweeps, fitted, base, max_noise, max_tilt)
    notes = []
    if t_ref < fitted.drift.t_min or t_ref > fitted.drift.t_max:
        notes.append(
            f"the reference temperature {t_ref:g} °C is outside the swept range "
            f"{fitted.drift.t_min:.1f} to {fitted.drift.t_max:.1f} °C: the drift there is clamped to the range's end"
        )
    folded = [a for a, k in zip("xyz", fitted.gain_drift, strict=True) if k == drift.FOLDED]
    if folded:
        notes.append(
            f"gain drift of {', '.join(folded)} folded into its offset drift: every sweep saw "
            f"{'that axis' if len(folded) == 1 else 'those axes'} the same way up "
            "(sweep the opposite face too to separate them)"
        )
    column = read[0].log.layout.names[read[0].log.layout.per_row_column or 0]
    block = _block(fitted, column, read, min_swing)
    out = replace(base, thermal=block)
    return ThermalResult(out, fitted, read, warnings, notes)


def plot(done: ThermalResult, path: str) -> None:
    """``thermal --plot``: each axis's drift against temperature, the fit and its residuals."""

    cal = done.calibration
    assert cal.thermal is not None
    model = cal.thermal.drift()
    gain_scale = np.zeros(3) if cal.sensor == "gyroscope" else np.abs(cal.gain) * cal.reference
    data = []
    for r in done.sweeps:
        sweep = drift.Sweep(r.log.values, _finite(r), None if r.face is None else _up(r.face))
        temp, seen, fitted = drift.observed(sweep, model, gain_scale)
        label = f"{r.told} {os.path.basename(r.file)}" if r.face else os.path.basename(r.file)
        data.append((label, temp, seen, fitted))
    title = f"{cal.sensor} temperature drift, order {model.order}" + (f", {cal.serial}" if cal.serial else "")
    plots.drift_figure(path, data, units=cal.input_units, title=title)


def _order(order: int | str) -> int | None:
    if order in ("auto", None):
        return None
    try:
        value = int(order)
    except (TypeError, ValueError):
        value = 0
    if value not in (1, 2, 3):
        raise InputError(f"--order must be 1, 2, 3 or auto, not {order!r}")
    return value


def _reference_temperature(base: Calibration, given: float | None) -> float:
    """T_ref: --reference-temperature, else the mean of the base calibration's pose temperatures."""
    if given is not None:
        if not COLDEST <= float(given) <= HOTTEST:  # nan, inf, or no temperature a sensor works at
            raise InputError(f"--reference-temperature must be in °C, from {COLDEST:g} to {HOTTEST:g}, got {given:g}")
        return float(given)
    recorded = [p.temperature for p in base.poses]
    temperatures = [t for t in recorded if t is not None]
    if recorded and len(temperatures) == len(recorded):
        return float(sum(temperatures)) / len(temperatures)
    raise InputError(
        "the base calibration records no temperature for its poses",
        file=base.path,
        hint="give the temperature it was made at: --reference-temperature DEGC",
    )


def _read(items: Sequence[str | os.PathLike[str]], base: Calibration, spec: ReadSpec) -> list[SweepRead]:

    texts = [os.fspath(i) for i in items]
    if not texts:
        raise InputError("give the sweeps: one or more FILE or LABEL=FILE", hint="see 'tumblecal thermal --help'")
    gyro = base.sensor == "gyroscope"
    placed = pose_items(texts, "+z")
    out = []
    for told, path in placed.items:
        # a calibration into the body's axes (--axes): its sweeps' faces are the body's, fitted
        # (as its drift is) as the sensor's directions along them
        face = told if base.axes is None or told is None else base.axes.sensor_label(told)
        log = readings.read_log(path, spec, use_time=False, need_temperature=True)
        temp = log.temperature
        assert temp is not None
        model.in_range(log.values, log.layout.name)
        finite = temp[np.isfinite(temp)]
        if finite.size == 0:
            raise InputError("the temperature column holds no numbers", file=log.layout.name)
        worst = float(finite.max() if finite.max() > HOTTEST else finite.min())
        if not COLDEST <= worst <= HOTTEST:
            raise InputError(
                f"a temperature of {worst:.5g} °C is none a sensor is swept through ({COLDEST:g} to {HOTTEST:g})",
                file=log.layout.name,
                hint="is --temperature-column the temperature, in °C?",
            )
        out.append(SweepRead(None if gyro else face, log.layout.name, log, drift.trend_range(finite), told))
    return out


def _finite(r: SweepRead) -> FloatArray:
    """The sweep's temperatures; a NaN cell takes its neighbour's value (interpolated)."""

    temp = r.log.temperature
    assert temp is not None
    ok = np.isfinite(temp)
    if ok.all():
        return temp
    index = np.arange(len(temp))
    filled: FloatArray = np.interp(index, index[ok], temp[ok])
    return filled


def _up(face: str) -> FloatArray:

    return direction(face)


def _judge_temperature(read: list[SweepRead], order: int | None, min_swing: float) -> None:
    """Exit 3 for a temperature that cannot carry the fit: constant, noise, or too small a swing."""

    temps = [r.log.temperature for r in read]
    lows = [float(np.nanmin(t)) for t in temps if t is not None]
    highs = [float(np.nanmax(t)) for t in temps if t is not None]
    name = read[0].log.layout.names[read[0].log.layout.per_row_column or 0]
    if max(highs) - min(lows) == 0:
        raise CaptureRejected(
            f"the temperature column {name!r} is constant at {lows[0]:g} °C in every sweep: "
            "nothing to fit a drift against",
            code="temperature.constant",
            hint="log the sensor while its temperature changes (a chamber ramp, or a unit warming up)",
        )
    scatter = max(highs) - min(lows)
    trend = max(r.trend[1] for r in read) - min(r.trend[0] for r in read)
    need = drift.required_swing(order or 1, min_swing)
    if trend < NOISE_SHARE * scatter and trend < need <= scatter:
        raise CaptureRejected(
            f"the temperature column {name!r} does not trend: its readings scatter over {scatter:.1f} °C "
            f"but its running median moves only {trend:.2f} °C (noise, not a sweep)",
            code="temperature.noise",
            hint="check that --temperature-column names the sensor's temperature",
        )
    if trend < need:
        which = f"order {order}" if order else "order 1 (the least)"
        raise CaptureRejected(
            f"the temperature swings {trend:.1f} °C ({min(r.trend[0] for r in read):.1f} to "
            f"{max(r.trend[1] for r in read):.1f} °C); {which} needs at least {need:g} °C",
            code="temperature.swing",
            hint="sweep a wider range, or lower --min-swing (a fit over a small swing extrapolates badly)",
        )


def _checks(
    read: list[SweepRead],
    sweeps: list[Sweep],
    fitted: ThermalFit,
    base: Calibration,
    max_noise: float | None,
    max_tilt: float,
) -> list[Finding]:
    """solve's quality checks on each sweep with its drift removed; rejections raise (exit 3)."""

    gyro = base.sensor == "gyroscope"
    bound = max_noise if max_noise is not None else (None if gyro else 0.02 * base.reference)
    options = gate.Options(
        noise_bound=bound,
        noise_rule="" if max_noise is not None or gyro else f"0.02 × reference {base.reference:g}",
        max_tilt_deg=max_tilt,
        min_samples=10,
        skip=frozenset({"saturated", "upside_down"}),
    )
    gain_scale = np.zeros(3) if gyro else np.abs(base.gain) * base.reference
    # a calibration into the body's axes (--axes) is checked in them, as its sweeps' faces were
    # told: P (raw - b) against the face, corrected by M P^T (its matrix is P M)
    turn = base.axes
    offset = base.offset if turn is None else turn.matrix @ base.offset
    poses = []
    for r, s in zip(read, sweeps, strict=True):
        flat = drift.detrended(s, fitted.drift, gain_scale)
        flat = flat if turn is None else turn.body(flat)
        poses.append(gate.measure(r.file, r.told if r.face else None, flat, model.pose_stats(flat), options))
    if not gyro:
        poses = gate.orient(poses, offset, max_tilt)
    matrix = base.matrix if turn is None else base.matrix @ turn.matrix.T
    solution = model.Solution(base.method, offset, matrix, np.zeros(3), np.zeros(3))
    rejected, warned = gate.check(poses, solution, options)
    if rejected:
        first = rejected[0]
        raise CaptureRejected(
            f"{first.message} (after removing the fitted drift)",
            file=first.file,
            code=first.code,
            more=tuple(f"{f.render()} (after removing the fitted drift)" for f in rejected[1:]),
            codes=tuple(f.code for f in rejected),
        )
    return warned


def _block(fitted: ThermalFit, column: str, read: list[SweepRead], min_swing: float) -> Thermal:

    drift = fitted.drift
    extra: dict[str, object] = {
        "uncertainty": {
            "offset": [[float(v) for v in row] for row in fitted.offset_se],
            "gain": [[float(v) for v in row] for row in fitted.gain_se],
        },
        "order_choice": {
            "method": "auto" if fitted.order_auto else "given",
            "cross_validation": {str(k): float(v) for k, v in fitted.cv_error.items()},
            "min_swing": min_swing,
        },
        "residual_rms": [float(v) for v in fitted.residual_rms],
        "sweeps": [
            {
                "pose": r.told if r.face else None,
                "file": r.file,
                "sha256": r.log.sha256,
                "samples": len(r.log.values),
                "temperature": [float(np.nanmin(_finite(r))), float(np.nanmax(_finite(r)))],
            }
            for r in read
        ],
    }
    return calfile.Thermal(
        column, drift.t_ref, (drift.t_min, drift.t_max), drift.offset, drift.gain, fitted.gain_drift, extra
    )
