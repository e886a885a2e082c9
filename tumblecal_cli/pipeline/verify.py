"""verify: a calibration checked on static captures it was not fitted on (the test of a
calibration model in Sports Sensing 2023: the norm of each corrected mean against the reference)."""

from __future__ import annotations

import contextlib
import functools
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NotRequired, TypedDict, Unpack

import numpy as np

from tumblecal_cli.core import catalog, drift, gate, methods, model, quantities, rotation_fit, solvers
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import UNITS_TOLERANCE
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.csv import posefile, readings
from tumblecal_cli.io.readspec import FileKeywords, ReadSpec, StreamKeywords, column_list, file_spec
from tumblecal_cli.pipeline import places
from tumblecal_cli.pipeline.frames import in_memory, is_data
from tumblecal_cli.pipeline.options import LogOptions, SolveOptions, keywords_known, path_of
from tumblecal_cli.pipeline.solve import spins
from tumblecal_cli.pipeline.solve.rotations import hand_turns

if TYPE_CHECKING:
    from tumblecal_cli.core.running import Summary
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.csv.readings import Samples
    from tumblecal_cli.io.readspec import ReadSpec
    from tumblecal_cli.pipeline.frames import DataFrame


class CaptureRow(TypedDict):
    """A held-out capture's figures (verify's table and --json): its norm before and after
    correction and their errors against the reference (before: None when raw and corrected
    are in different units), the spread of the corrected readings."""

    file: str
    samples: int
    norm_before: float
    error_before: float | None
    norm_after: float
    error_after: float
    std: list[float]
    turning: NotRequired[bool]  # a turning capture (a magnetometer's): error_after is the samples' RMS
    max_error: NotRequired[float]  # ... and this their largest |error|
    coverage: NotRequired[float]  # ... and this the share of the sphere's directions they reach
    rate: NotRequired[float]  # verify --spin: the rate the file turned at (the calibration's units)


class RotationRow(TypedDict):
    """A held-out hand turn's figures (verify --log): its angle, and how far the gyroscope misses
    the gravity direction after it, with the nominal gain and with the calibration."""

    rotation: str
    angle_deg: float
    error_before_deg: float
    error_after_deg: float


@dataclass
class Verified:
    """verify's figures: one row per capture, the overall errors, and the outcome (``status``
    0 within ``max_norm_error`` or none given, 1 outside it, 3 a capture that is not static)."""

    status: int
    cal: Calibration  # the Calibration judged
    reference: float
    max_norm_error: float | None
    rows: list[CaptureRow]  # each capture's figures, as --json and table() give them
    overall: dict[str, float]
    rejected: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def error(self) -> CaptureRejected | None:
        """The rejection as the command line reports it (None: none)."""
        if not self.rejected:
            return None
        return CaptureRejected(
            self.rejected[0], more=tuple(self.rejected[1:]), hint="capture it again holding the unit still"
        )

    def table(self) -> DataFrame:
        """The per-capture rows as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.rows)


class VerifyKeywords(FileKeywords, StreamKeywords, total=False):
    """verify's options beside the captures' shape (docs/commands/verify.md)."""

    reference: float | None
    location: str | None
    gravity: float | None
    date: str | None
    max_norm_error: float | None
    max_noise: float
    start: str | float | None
    end: str | float | None
    rate: float | None
    rows_are_poses: bool | None
    spin: Sequence[str] | None  # a gyroscope's RATE=FILE items (pipeline.solve.spins)


@dataclass(frozen=True)
class _Judge:
    """What each capture is judged by: the calibration, the reference, whether raw and corrected
    share units, and the limits (--max-noise, --max-norm-error)."""

    cal: Calibration
    reference: float
    same_units: bool
    max_noise: float
    max_norm_error: float | None


def verify(
    captures: Sequence[str | os.PathLike[str] | DataFrame] | str | os.PathLike[str] | DataFrame,
    cal: Calibration | str | os.PathLike[str],
    **options: Unpack[VerifyKeywords],
) -> Verified:
    """The norm error of each static capture before and after correction with ``cal``. A capture
    may be its data in memory: a DataFrame, or an (n, 3) array, read as its file would be."""

    keywords_known(options, VerifyKeywords, "verify")
    given: list[object]
    if isinstance(captures, str | os.PathLike) or is_data(captures):
        given = [captures]
    elif isinstance(captures, Sequence):
        given = list(captures)
    else:
        raise InputError(
            f"verify takes capture files (one, or a list) or their data (DataFrames, arrays), "
            f"not a {type(captures).__name__}"
        )
    with contextlib.ExitStack() as held:  # data in memory: a source for the length of the call
        what = "verify reads static captures: files, DataFrames or (n, 3) arrays"
        return _verify([held.enter_context(in_memory(c, what)) for c in given], cal, options)


def _verify(paths: list[str], cal: Calibration | str | os.PathLike[str], options: VerifyKeywords) -> Verified:
    """verify on the captures' paths (or the names their data in memory is held under)."""
    reference, max_norm_error = options.get("reference"), options.get("max_norm_error")
    max_noise = options.get("max_noise", 0.02)
    if options.get("spin"):
        return spun(calfile.resolve(cal), list(options.get("spin") or []), paths, options)
    if not paths:
        raise InputError("verify needs one static capture or more")
    if sum(f == "-" for f in paths) + (cal == "-") > 1:
        raise InputError("only one file can be read from stdin ('-')")
    c = calfile.resolve(cal)
    units = c.units or ("g" if c.sensor == "accelerometer" and c.reference == 1 else None)
    where = (options.get("location"), options.get("gravity"), options.get("date"))
    local = places.local_reference(places.Asked(c.sensor, units, None, *where, reference=reference))
    ref = c.reference if reference is None else reference
    if local is not None:
        ref = local[0]
    if not math.isfinite(ref) or ref < 0 or (ref == 0 and c.sensor != "gyroscope"):
        raise InputError(
            f"--reference must be a positive number, got {ref:g}", hint="0 only for a gyroscope's calibration"
        )
    if max_norm_error is not None and not max_norm_error > 0:
        raise InputError(f"--max-norm-error must be positive, got {max_norm_error:g}")
    spec = _spec(options, c)
    # raw and corrected share units, so "before" means something: fixed gains, the same unit
    # labels, or gains within 20 % of 1 (data already in g, m/s^2 ...: counts are far from it)
    gains = [float(g) for g in c.gain]
    same_units = (
        catalog.fixes_gains(c.method)
        or (c.input_units is not None and c.input_units == c.units)
        or (len(gains) == 3 and all(abs(g - 1.0) < 0.2 for g in gains))
    )
    fitted = {p.sha256: str(p.file) for p in c.poses if p.sha256}
    result = Verified(0, c, ref, max_norm_error, [], {})
    judge = _Judge(c, ref, same_units, max_noise, max_norm_error)
    for path in paths:
        s = _read(path, c, spec, result.notes)
        result.notes += s.layout.notes
        model.in_range(s.readings, s.layout.name)
        if s.sha256 in fitted:
            result.notes.append(
                f"{s.layout.name}: the calibration was fitted on this capture ({fitted[s.sha256]}): "
                "it reads the reference by construction, a self-check rather than a verification"
            )
        reload = functools.partial(_readings, path, spec)
        for name, values in _poses(s, c, options.get("rows_are_poses"), result.notes):
            _check(result, name, values, judge, reload)
    errors = [r["error_after"] for r in result.rows]
    result.overall = {
        "rms_error": float((sum(e * e for e in errors) / len(errors)) ** 0.5),
        "max_error": float(max(r.get("max_error", abs(r["error_after"])) for r in result.rows)),
    }
    if same_units:
        raw_errors = [e for r in result.rows if (e := r["error_before"]) is not None]  # each, with same_units
        result.overall["rms_error_before"] = float((sum(e * e for e in raw_errors) / len(raw_errors)) ** 0.5)
        result.overall["max_error_before"] = float(max(abs(e) for e in raw_errors))
    result.status = 3 if result.rejected else (1 if result.failed else 0)
    return result


def _poses(s: Samples, c: Calibration, rows: bool | None, notes: list[str]) -> list[tuple[str, FloatArray | Summary]]:
    """A capture as the poses it holds: itself, or each of its rows where they are separate
    orientations (a table, one averaged reading each: --rows-are-poses, or recognised as solve
    recognises one when it has no time column), with a note."""
    name = s.layout.name
    why = None
    if rows is None and s.layout.time is None and c.sensor != "gyroscope":
        why = methods.orientation_table(s.values, np.asarray(c.offset, dtype=float))
    if not (rows or why):
        return [(name, s.readings)]
    notes.append(
        f"{name}: {why or 'its rows are poses (--rows-are-poses)'}: each of its {len(s.values)} rows is judged "
        "as a capture of its own (--no-rows-are-poses judges the file as one)"
    )
    return [(f"{name} row {k}", s.values[k : k + 1]) for k in range(len(s.values))]


def _check(
    result: Verified, name: str, values: FloatArray | Summary, judge: _Judge, reload: Callable[[], FloatArray]
) -> None:
    """One capture's norm before and after correction, in ``result``: a row, and a rejection
    (not static) or a failure (past --max-norm-error) where it has one. A magnetometer's capture
    that is not static is judged as a turning one (:func:`_turning`; ``reload``: its readings,
    where ``values`` holds only their sums)."""
    c, ref = judge.cal, judge.reference
    st = model.pose_stats(values)
    before = float((st.mean**2).sum() ** 0.5)
    fixed = gate.corrected(st.mean, st.std, None, c.offset, c.matrix, ref)  # the norm error, as solve's
    std = fixed.std
    row: CaptureRow = {
        "file": name,
        "samples": st.samples,
        "norm_before": before,
        "error_before": before - ref if judge.same_units else None,
        "norm_after": fixed.norm_error + ref,
        "error_after": fixed.norm_error,
        "std": [float(v) for v in std],
    }
    if judge.max_noise > 0 and ref > 0 and float(std.max()) > judge.max_noise * ref and c.sensor in TURNED:
        _turning(result, name, values if isinstance(values, np.ndarray) else reload(), judge)
        return
    result.rows.append(row)
    if judge.max_noise > 0 and ref > 0 and float(std.max()) > judge.max_noise * ref:
        result.rejected.append(
            f"{name}: standard deviation {float(std.max()):.3g} is above --max-noise "
            f"({judge.max_noise * ref:.3g}): not a static capture"
        )
        return
    _units(name, c, before, fixed.norm_error + ref, ref)  # a static capture: its magnitude judged
    if judge.max_norm_error is not None and not abs(row["error_after"]) <= judge.max_norm_error:
        result.failed.append(row["file"])


#: The sensors whose calibration a turning capture checks: |corrected| is the reference in every
#: orientation, still or not (an accelerometer's turned readings hold the motion's acceleration).
TURNED = ("magnetometer",)


def _turning(result: Verified, name: str, values: FloatArray, judge: _Judge) -> None:
    """A turning capture of a magnetometer: each sample's |corrected| − reference (their RMS is
    the row's error, judged by --max-norm-error; their largest, its ``max_error``) and the share
    of the sphere's directions its corrected samples reach (``coverage``): a calibration that fits
    in every direction the capture turned through. ``verify`` of a turning recording refused it
    as "not a static capture"."""
    c, ref = judge.cal, judge.reference
    finite = values[np.isfinite(values).all(axis=1)]
    fixed = model.apply(finite, c.offset, c.matrix)
    size = np.linalg.norm(fixed, axis=1)
    errors = size - ref
    rms, largest = float(np.sqrt(np.mean(errors**2))), float(np.abs(errors).max())
    reached = solvers.coverage(fixed / size[:, None])
    raw = float(np.median(np.linalg.norm(finite, axis=1)))
    row: CaptureRow = {
        "file": name,
        "samples": len(finite),
        "norm_before": raw,
        "error_before": raw - ref if judge.same_units else None,
        "norm_after": float(np.median(size)),
        "error_after": rms,
        "std": [float(v) for v in fixed.std(axis=0)],
        "turning": True,
        "max_error": largest,
        "coverage": reached,
    }
    result.rows.append(row)
    result.notes.append(
        f"{name}: a turning capture: |corrected| - reference RMS {rms:.3g}, largest {largest:.3g} over "
        f"{len(finite)} samples; they reach {reached:.0%} of the sphere's directions"
        + ("" if reached >= 0.5 else " (turn it through more of them to judge the calibration everywhere)")
    )
    _units(name, c, raw, float(np.median(size)), ref)
    if judge.max_norm_error is not None and not rms <= judge.max_norm_error:
        result.failed.append(name)


def spun(c: Calibration, items: list[str], paths: list[str], options: VerifyKeywords) -> Verified:
    """verify --spin: a gyroscope's calibration on files spun at known rates: over each file's
    steady runs at its rate (pipeline.solve.spins), |corrected| − |rate| sample by sample, or with
    a face (``+z@45rpm``) |corrected − rate · face| (RMS: the row's error, judged by
    --max-norm-error; the largest: ``max_error``)."""
    if c.sensor != "gyroscope":
        raise InputError(f"--spin checks a gyroscope's calibration, not the {c.sensor}'s", file=c.path)
    if paths:
        raise InputError("--spin gives the files to check: not captures beside it")
    units = (c.units or "rad/s").strip()
    per = quantities.UNITS[units].factor if units in quantities.UNITS else 1.0
    given = [spins.parse(item) for item in items]
    slowest = min((abs(g.rate) for g in given if g.rate), default=1.0) / per
    limit = options.get("max_norm_error")
    result = Verified(0, c, 0.0, limit, [], {})
    for g in given:
        f = spins.read(g, _spec(options, c), c)
        used, said, _ = spins.runs_at_rate(f, g.rate / per, 1.0, slowest, units)
        corrected = np.concatenate([f.log.values[r.first : r.last + 1] for r in used])
        size = np.linalg.norm(corrected, axis=1)
        errors = size - abs(g.rate / per)
        if g.face is not None:  # a labelled face: the rate's direction is known, the vector is judged
            errors = np.linalg.norm(corrected - g.rate / per * model.direction(g.face), axis=1)
        rms, largest = float(np.sqrt(np.mean(errors**2))), float(np.abs(errors).max())
        row: CaptureRow = {
            "file": f.log.layout.name,
            "samples": len(corrected),
            "norm_before": f.raw_median,
            "error_before": None,
            "norm_after": float(np.median(size)),
            "error_after": rms,
            "std": [float(v) for v in corrected.std(axis=0)],
            "turning": True,
            "max_error": largest,
            "rate": g.rate / per,
        }
        result.rows.append(row)
        judged = "|corrected| − rate" if g.face is None else f"|corrected − rate along {g.face}|"
        result.notes.append(f"{said}: {judged} RMS {rms:.3g}, largest {largest:.3g} {units}")
        if limit is not None and not rms <= limit:
            result.failed.append(f.log.layout.name)
    errors_after = [r["error_after"] for r in result.rows]
    result.overall = {
        "rms_error": float(np.sqrt(np.mean(np.square(errors_after)))),
        "max_error": float(max(r.get("max_error", 0.0) for r in result.rows)),
    }
    result.status = 1 if result.failed else 0
    return result


def _readings(path: str, spec: ReadSpec) -> FloatArray:
    """A capture's every reading, read again (a long pose file is summed as it is read)."""
    return readings.read_log(path, spec, use_time=False).values


def _spec(options: VerifyKeywords, c: Calibration) -> ReadSpec:
    """How verify reads its captures: their shape, the calibration's sensor and columns, and the
    part of each (--start/--end; --rate gives its seconds when a capture has no time column)."""
    rate = options.get("rate")
    readings.check_rate(rate)
    return replace(
        file_spec(options, prefer=c.columns),
        sensor=c.sensor,
        rate=rate,
        start=options.get("start"),
        end=options.get("end"),
        stream=options.get("stream"),
        allow_corrected=options.get("allow_corrected", False),
    )


def _units(name: str, c: Calibration, raw: float, norm: float, ref: float) -> None:
    """A capture whose corrected magnitude is far from the reference: exit 2, with the raw
    magnitude the calibration's own poses read (it would report a -97 % error, "not judged")."""

    if not ref > 0 or abs(norm - ref) <= UNITS_TOLERANCE * ref:
        return
    made = [float(sum(v * v for v in p.mean) ** 0.5) for p in c.poses]
    hint = "correct captures in the units the calibration was made from"
    if made:
        typical = sorted(made)[len(made) // 2]
        hint = f"the calibration's poses read about {typical:.4g} in raw magnitude, this capture {raw:.4g}: {hint}"
    if c.sensor == "magnetometer":
        hint += "; where the field differs from the calibration's, give it with --reference"
    off = norm / ref - 1
    away = f"{off:+.0%} from" if abs(off) < 100 else f"{norm / ref:.3g} times"  # not 150 digits of %
    raise InputError(
        f"corrected magnitude {norm:.4g} is {away} the reference {ref:g}: a units mistake, "
        "or another sensor's calibration?",
        file=name,
        hint=hint,
    )


def _read(path: str, c: Calibration, spec: ReadSpec, notes: list[str]) -> Samples:
    """A static capture's readings; with a thermal block, each row brought to T_ref at its own
    temperature (core.drift.at_reference), the rows outside the range noted."""

    if c.thermal is None:
        return posefile.read(path, spec)
    spec = replace(spec, temperature_column=c.thermal.column)
    log = readings.read_log(path, spec, use_time=False, need_temperature=True)
    temp = log.temperature
    assert temp is not None
    model = c.thermal.drift()
    outside = int(np.count_nonzero((temp < model.t_min) | (temp > model.t_max)))
    if outside:
        notes.append(
            f"{log.layout.name}: {outside} rows outside the calibrated temperature range "
            f"{model.t_min:g} to {model.t_max:g} °C, corrected at its nearest end"
        )
    values = drift.at_reference(log.values, temp, c.offset, model)
    rows = (int(log.rows[0]), int(log.rows[-1]))
    return readings.Samples(log.layout, values, rows, log.sha256, None, float(np.nanmean(temp)))


@dataclass
class VerifiedRotations:
    """verify of a gyroscope calibration on a log of hand turns: one row per rotation between
    still blocks (its angle, and how far the gravity direction it predicts misses the measured
    one, before and after the calibration's matrix), and the overall RMS and largest."""

    status: int
    cal: Calibration
    rows: list[RotationRow]  # each rotation's figures, as --json and table() give them
    overall: dict[str, float]
    notes: list[str] = field(default_factory=list)

    def table(self) -> DataFrame:
        import pandas as pd

        return pd.DataFrame(self.rows)


def verify_rotations(
    log: str | os.PathLike[str] | DataFrame,
    cal: Calibration | str | os.PathLike[str],
    *,
    accel_cal: str | os.PathLike[str],
    rate: float | None = None,
    time_column: str | None = None,
    time_unit: str = "auto",
    columns: str | Sequence[str] | None = None,
    **source: Unpack[StreamKeywords],
) -> VerifiedRotations:
    """A gyroscope calibration judged on a log it was not fitted on: the rotations between its
    still blocks (pipeline.solve.rotations.hand_turns, gravity from ``accel_cal``). "Before" is the
    calibration's bias and its mean gain alone (no per-axis scale, no cross-axis terms): what a
    datasheet sensitivity gives; "after" is its full matrix."""

    c = calfile.resolve(cal)
    if c.sensor != "gyroscope":
        raise InputError(
            f"--log with --accel-cal verifies a gyroscope's calibration, not the {c.sensor}'s", file=c.path
        )

    readings.check_rate(rate)
    options = SolveOptions(
        read=ReadSpec(
            sensor="gyroscope",
            columns=column_list(columns),
            time_column=time_column,
            time_unit=time_unit,
            rate=rate,
            stream=source.get("stream"),
            allow_corrected=source.get("allow_corrected", False),
        ),
        log=LogOptions(accel_cal=path_of(accel_cal, "--accel-cal takes a calibration file")),
    )
    with in_memory(log, "verify --log takes a log: a file, a DataFrame or an array") as path:
        turns = hand_turns(path, options)
    if not turns.rotations:
        raise CaptureRejected(
            f"no rotation between still blocks ({len(turns.kept)} kept)",
            file=turns.gyr.layout.name,
            hint="rest the unit between turns; `tumblecal segment` lists the still blocks",
            code="rotations.few",
        )
    nominal = np.eye(3) / float(np.mean(np.abs(c.gain)))
    _, before, _ = rotation_fit.judged(turns.rotations, c.offset, nominal)
    angles, after, _ = rotation_fit.judged(turns.rotations, c.offset, c.matrix)
    rows = [
        RotationRow(rotation=n, angle_deg=float(a), error_before_deg=float(b), error_after_deg=float(e))
        for n, a, b, e in zip(turns.names, angles, before, after, strict=True)
    ]
    overall = {
        "rms_error_before_deg": float(np.sqrt(np.mean(before**2))),
        "max_error_before_deg": float(before.max()),
        "rms_error_after_deg": float(np.sqrt(np.mean(after**2))),
        "max_error_after_deg": float(after.max()),
    }
    return VerifiedRotations(0, c, rows, overall)
