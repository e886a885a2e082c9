"""current: magnetometer logs with a motor-current column in, a calibration with a ``current``
block out (docs/current.md).

The steps: read the base calibration (``io.calfiles.calfile``: a magnetometer's) and each log with its
current column (``io.csv.readings.read_log``, the column read as text and then as numbers here, so
that a cell that is not one is named with its line), refuse a current that never changes or too
few readings (exit 3), fit the offset per ampere (``core.current_fit.fit``: one slope, each log its
own reading at 0 A), and add the block to the base calibration.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from tumblecal_cli.core import current_fit as core
from tumblecal_cli.core import model
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile, limitfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.readspec import ReadSpec, column_list
from tumblecal_cli.pipeline.options import keywords_known

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray, IntArray
    from tumblecal_cli.core.current_fit import CurrentFit
    from tumblecal_cli.io.calfiles.calfile import Calibration, Current
    from tumblecal_cli.io.csv.readings import Log

#: Below this share of the field's variation explained, the fit is said to be doubtful.
DOUBTFUL = 0.5


@dataclass
class LogRead:
    """One log as read: its file, the log, and its current (A) per reading."""

    file: str
    log: Log
    current: FloatArray


@dataclass
class CurrentResult:
    """The outcome of :func:`current`: the calibration with its ``current`` block, the fit, the
    logs read, and what a person should know (``notes``; ``warnings``, lines of their own)."""

    calibration: Calibration
    fit: CurrentFit
    logs: list[LogRead]
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: The corrected field's change at the largest current over the reference, and its 1-sigma.
    interference: tuple[float, float] = (0.0, 0.0)
    #: The limits file's ``current_interference`` (None: not judged), and what it failed.
    limit: float | None = None
    failures: list[Finding] = field(default_factory=list)

    @property
    def status(self) -> int:
        """1 when the interference is above its limit, else 0 (the calibration is written either way)."""
        return 1 if self.failures else 0


class CurrentKeywords(TypedDict, total=False):
    """current's options (docs/current.md): the command line's long options in snake case."""

    current_column: str | None
    columns: str | Sequence[str] | None
    sensor: str | None
    stream: str | None
    allow_corrected: bool
    limits: str | os.PathLike[str] | None


def current(
    logs: Sequence[str | os.PathLike[str]],
    cal: Calibration | str | os.PathLike[str],
    **options: Unpack[CurrentKeywords],
) -> CurrentResult:
    """Fit a magnetometer's offset per ampere of motor current from logs with a current column,
    as ``tumblecal current``. Input errors raise InputError (exit 2); a current that never changes
    or too few readings raise CaptureRejected (exit 3). ``limits``: a limits file whose
    ``current_interference`` judges the field's change at the largest current (``status`` 1)."""

    keywords_known(options, CurrentKeywords, "current")
    base = calfile.resolve(cal)
    sensor, column = options.get("sensor"), options.get("current_column")
    if base.sensor != "magnetometer" or sensor not in (None, "magnetometer"):
        raise InputError(
            f"current compensation is a magnetometer's, and this calibration is of the {base.sensor}"
            + (f" (--sensor {sensor})" if sensor not in (None, base.sensor) else ""),
            file=base.path,
            hint="give the magnetometer's calibration with --cal",
        )
    if not column:
        raise InputError("give the current column: --current-column NAME", hint="see 'tumblecal current --help'")
    spec = ReadSpec(
        sensor=base.sensor,
        columns=column_list(options.get("columns")),
        prefer=tuple(base.columns),
        stream=options.get("stream"),
        allow_corrected=options.get("allow_corrected", False),
    )
    paths = [os.fspath(p) for p in logs]
    if not paths:
        raise InputError("give the logs: one or more FILE", hint="see 'tumblecal current --help'")
    read = [_read(p, spec, column) for p in paths]
    values = np.concatenate([r.log.values for r in read])
    amperes = np.concatenate([r.current for r in read])
    group = np.concatenate([np.full(len(r.current), k, dtype=np.int64) for k, r in enumerate(read)])
    _judge(read, amperes, group, column)
    fitted = core.fit(values, amperes, group)
    share = core.interference(fitted, base.matrix, base.reference) if base.reference else (0.0, 0.0)
    block = _block(fitted, column, read, base, share)
    limit = _limit(options.get("limits"))
    failures = []
    if limit is not None and not share[0] <= limit:
        failures.append(
            Finding(
                "limit.current_interference",
                f"at {max(map(abs, fitted.span)):.3g} A the field moves {share[0]:.1%} of the reference, "
                f"above {limit:.1%}",
                share[0],
                limit,
            )
        )
    said = _said(fitted, base)
    return CurrentResult(replace(base, current=block), fitted, read, *said, share, limit, failures)


def _limit(path: str | os.PathLike[str] | None) -> float | None:
    if path is None:
        return None
    value = limitfile.load_limits(os.fspath(path)).get("current_interference")
    return None if value is None else float(np.asarray(value).ravel()[0])


def _read(path: str, spec: ReadSpec, column: str) -> LogRead:
    """A log and its current column as numbers: a cell that is not one names its line."""

    try:
        log = readings.read_log(path, spec, label_column=column, use_time=False)
    except InputError as err:
        if "has no label column" in err.message:  # a log of a flight controller: its current is another message's
            kind = err.message.split(" has no label column")[0]
            raise InputError(
                f"{kind}'s current is in a message of its own, on its own clock: current reads CSV logs",
                file=err.file,
                hint="write the magnetometer's readings with the current beside each row to a CSV (docs/current.md)",
            ) from None
        if err.message.startswith("--pose-column names "):  # the label column's own check: here it is the current's
            raise InputError(
                "--current-column" + err.message.removeprefix("--pose-column"),
                file=err.file,
                hint="name the column of the motor current in amperes, not one of the sensor's",
            ) from None
        if not err.message.startswith(f"column {column!r} not found"):
            raise
        raise InputError(
            f"--current-column {err.message.removeprefix('column ')}",
            file=err.file,
            hint="name the column of the motor current in amperes (its header, or its 0-based index)",
        ) from None
    model.in_range(log.values, log.layout.name)
    text = log.labels or []
    amperes = np.empty(len(text))
    for i, cell in enumerate(text):
        try:
            amperes[i] = float(cell)
        except (TypeError, ValueError):
            amperes[i] = np.nan
        if not np.isfinite(amperes[i]):
            raise InputError(
                f"current is not a finite number: {str(cell).strip()!r}",
                file=log.layout.name,
                line=log.layout.data_line + int(log.rows[i]),
                column=column,
                hint="every row with magnetometer readings needs its current in amperes",
            )
    return LogRead(log.layout.name, log, amperes)


def _judge(read: list[LogRead], amperes: FloatArray, group: IntArray, column: str) -> None:
    """Exit 3 for a current that cannot carry a fit: too few readings, or one that never changes."""

    if len(amperes) < core.MIN_SAMPLES + len(read):
        raise CaptureRejected(
            f"{len(amperes)} readings: a fit of the offset per ampere needs at least {core.MIN_SAMPLES + len(read)}",
            file=read[0].file,
            code="current.short",
            hint="log the magnetometer longer while the motors run up",
        )
    if core.spread(amperes, group) == 0:
        value = f" at {amperes[0]:g} A" if float(amperes.min()) == float(amperes.max()) else ""
        raise CaptureRejected(
            f"the current column {column!r} never changes{value} within a log: "
            "nothing to fit an offset per ampere against",
            file=read[0].file,
            code="current.constant",
            hint="log the vehicle still while the motors run from idle to full throttle",
        )


def _block(
    fitted: CurrentFit, column: str, read: list[LogRead], base: Calibration, share: tuple[float, float]
) -> Current:

    corrected = base.matrix @ fitted.per_amp
    extra: dict[str, object] = {
        "uncertainty": {"per_amp": [float(v) for v in fitted.per_amp_se]},
        "per_amp_corrected": [float(v) for v in corrected],
        "explained": [float(v) for v in fitted.explained],
        "explained_total": fitted.explained_total,
        "residual_rms": [float(v) for v in fitted.residual_rms],
        "autocorrelation": [float(v) for v in fitted.autocorrelation],
        "interference": share[0],
        "interference_sigma": share[1],
        "logs": [
            {
                "file": r.file,
                "sha256": r.log.sha256,
                "samples": len(r.current),
                "current": [float(r.current.min()), float(r.current.max())],
                "at_zero": [float(v) for v in fitted.at_zero[k]],
            }
            for k, r in enumerate(read)
        ],
    }
    return calfile.Current(column, fitted.per_amp, fitted.span, extra)


def _said(fitted: CurrentFit, base: Calibration) -> tuple[list[str], list[str]]:
    warnings, notes = [], []
    if fitted.explained_total < DOUBTFUL:
        warnings.append(
            f"warning: the current explains only {fitted.explained_total:.0%} of the field's variation: "
            "did the vehicle move or turn while the current changed? (hold it still, in one attitude)"
        )
    low, high = fitted.span
    if low > 0.25 * high:
        notes.append(
            f"the current ran from {low:.3g} to {high:.3g} A: a log that starts at idle (near 0 A) pins the "
            "reading at 0 A down best"
        )
    return warnings, notes
