"""Calibration files, format version 1 (docs/reference/calibration-file.md): the typed
:class:`Calibration`, and its JSON/YAML form, the only place it is a ``dict``
(:meth:`Calibration.to_dict`, :func:`from_dict`, :func:`validate`; its parts' forms are in
``io.calfiles.calparts``).

JSON by default, YAML when the path ends in ``.yaml``/``.yml`` (read with ``yaml.safe_load``
only: a ``!!python/object`` tag is an error, never run).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from datetime import UTC, date, datetime
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.axes import Axes
from tumblecal_cli.core.current_fit import correct as current_correct
from tumblecal_cli.core.drift import correct as thermal_correct
from tumblecal_cli.core.model import MAX_READING, SENSORS, Solution, parse_label
from tumblecal_cli.core.model import apply as apply_model
from tumblecal_cli.core.quantities import REFERENCE_UNITS
from tumblecal_cli.errors import InputError, control_character
from tumblecal_cli.io.calfiles.calparts import (
    GAIN_DRIFT_KINDS,
    THERMAL_KEYS,
    Accelerometer,
    Covariance,
    Current,
    Doc,
    Gap,
    GSensitivity,
    LeftOut,
    Pose,
    Residuals,
    Rotation,
    SegmentationPart,
    Thermal,
    Tilt,
    Turn,
    Unit,
    Verdict,
    axes_of,
    current_from,
    floats,
    is_number,
    named,
    number,
    read_covariance,
    read_g_sensitivity,
    read_gap,
    read_left_out,
    read_list,
    read_pose,
    read_residuals,
    read_rotation,
    read_segmentation,
    read_tilt,
    read_turn,
    read_verdict,
    rows_of,
    same,
    text,
    thermal_from,
    unit_fields,
)
from tumblecal_cli.io.calfiles.documents import is_yaml, read_object
from tumblecal_cli.io.outputs import atomic_output
from tumblecal_cli.version import __version__

if TYPE_CHECKING:
    from tumblecal_cli.core.solvers import Fit

__all__ = [  # the parts, for code that names them as calfile's
    "GAIN_DRIFT_KINDS",
    "THERMAL_KEYS",
    "Accelerometer",
    "Covariance",
    "Current",
    "GSensitivity",
    "Gap",
    "Pose",
    "Residuals",
    "Rotation",
    "SegmentationPart",
    "Thermal",
    "Tilt",
    "Turn",
    "Unit",
    "Verdict",
    "is_number",
    "thermal_from",
]

#: A pandas DataFrame, which ``Calibration.apply`` takes and gives as well as arrays: pandas ships
#: no types here, and io never imports it (tests/test_layers.py), so it is unchecked.
Frame: TypeAlias = Any

FORMAT = "tumblecal-calibration"
VERSION = 1
REQUIRED = ("format", "version", "sensor", "method", "reference", "columns", "offset", "matrix", "gain")
#: The fields of the contract, in the file's order (docs/reference/calibration-file.md).
ORDER = (
    "format",
    "version",
    "sensor",
    "method",
    "reference",
    "units",
    "input_units",
    "columns",
    "offset",
    "matrix",
    "gain",
    "uncertainty",
    "tilt_sensitivity",
    "thermal",
    "current",
    "poses",
    "unit",
    "verdict",
    "created",
    "tool",
)
#: The parts some methods add (docs/reference/calibration-file.md), in the order they follow ``poses``
#: when given to a calibration that was read without them.
PARTS = (
    "turns",
    "g_sensitivity",
    "rotations",
    "covariance",
    "coverage",
    "coverage_gaps",
    "residuals",
    "outliers",
    "segmentation",
)


@dataclass(frozen=True, eq=False)
class Calibration:
    """A sensor's calibration: ``corrected = matrix @ (raw - offset)``.

    ``offset`` (3,) is in raw units, ``matrix`` (3, 3) is M = inv(A), ``gain`` (3,) the diagonal
    of A; with ``axes`` (the body's axes in the sensor's, core.axes) ``matrix`` is P M, correcting
    into the body's axes, and ``offset``, ``gain`` and A stay the sensor's (``sensor_matrix``: M);
    ``uncertainty`` holds the 1-sigma of ``offset`` and ``gain`` (and ``cross_axis`` where solved).
    The other parts are typed (``io.calfiles.calparts``), None (or empty) where the file has none.
    ``fields`` holds what is not typed: the fields of other writers, and a field whose value is of
    another kind than tumblecal writes, each as written and kept in its place (``order``, the
    file's order of its fields) when the file is written again.
    """

    sensor: str
    method: str
    reference: float
    columns: list[str]  # the sensor columns x, y, z as named in the captures
    offset: FloatArray
    matrix: FloatArray
    gain: FloatArray
    units: str | None = None
    input_units: str | None = None
    axes: Axes | None = None
    uncertainty: Mapping[str, FloatArray] = field(default_factory=dict)
    tilt_sensitivity: Tilt | None = None
    thermal: Thermal | None = None
    current: Current | None = None  # a magnetometer's offset per ampere (docs/current.md)
    poses: tuple[Pose, ...] = ()
    unit: Unit | None = None
    verdict: Verdict | None = None
    created: str | None = None
    tool: str | None = None
    covariance: Covariance | None = None
    coverage: float | None = None  # 0-1, the share of directions with a sample near them
    coverage_gaps: tuple[Gap, ...] | None = None  # the directions without (a turned capture's)
    residuals: Residuals | None = None
    outliers: LeftOut | None = None  # the samples a robust fit left out (core.robust)
    segmentation: SegmentationPart | None = None
    turns: tuple[Turn, ...] | None = None
    g_sensitivity: GSensitivity | None = None
    rotations: tuple[Rotation, ...] | None = None
    fields: Mapping[str, object] = field(default_factory=dict)
    order: tuple[str, ...] = ORDER  # the file's own order of its fields
    path: str | None = None  # the file it was read from

    def __post_init__(self) -> None:  # numbers given as lists (a Calibration built by hand) become arrays
        for name, shape in (("offset", (3,)), ("matrix", (3, 3)), ("gain", (3,))):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != shape:
                raise InputError(f"a Calibration's {name} has shape {shape}, got {value.shape}", file=self.path)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "columns", [str(c) for c in self.columns])

    @property
    def failed(self) -> bool:
        """Whether the calibration carries a failing verdict."""
        return self.verdict is not None and not self.verdict.passed

    @property
    def sensor_matrix(self) -> FloatArray:
        """M in the sensor's own axes: ``matrix`` without the axes folded into it (Pᵀ matrix)."""
        return self.matrix if self.axes is None else self.axes.matrix.T @ self.matrix

    def in_axes(self, axes: Axes | None) -> Calibration:
        """The same calibration correcting into ``axes`` (None or the identity: the sensor's own)."""
        axes = None if axes is None or axes.identity else axes
        return replace(self, matrix=self.sensor_matrix if axes is None else axes.matrix @ self.sensor_matrix, axes=axes)

    @property
    def serial(self) -> str | None:
        return None if self.unit is None else self.unit.serial

    def apply(self, data: Frame, temperature: ArrayLike | None = None) -> Frame:  # an ndarray or a DataFrame
        """Correct readings: an (n, 3) array gives an (n, 3) array; a pandas DataFrame gives a copy
        with the calibration's ``columns`` corrected (matched case-insensitively; other columns,
        the index and their dtypes untouched). With a ``thermal`` block each row is corrected at its
        own temperature: the DataFrame's ``thermal.column``, or ``temperature`` (n,) °C given with
        an array (clamped to the calibrated range). With a ``current`` block each row is corrected
        at its own current the same way: the DataFrame's ``current.column``, or ``temperature``
        given with an array holds the (n,) amperes."""
        if hasattr(data, "columns") and hasattr(data, "loc"):  # a DataFrame, without importing pandas
            where = _frame_columns(data, self.columns, self.path)
            out = data.copy()
            try:
                raw = np.asarray(data.iloc[:, where].to_numpy(dtype=np.float64, na_value=np.nan))
            except (TypeError, ValueError) as err:
                raise InputError(f"the DataFrame's {', '.join(self.columns)} are not numbers ({err})") from None
            per_row = self.thermal or self.current
            if per_row is not None and temperature is None:
                (at,) = _frame_columns(data, [per_row.column], self.path)
                try:
                    temperature = data.iloc[:, at].to_numpy(dtype=np.float64, na_value=np.nan)
                except (TypeError, ValueError) as err:
                    raise InputError(f"the DataFrame's {per_row.column} is not numbers ({err})") from None
            fixed = self._corrected(raw, temperature)
            for k, position in enumerate(where):
                out.isetitem(position, fixed[:, k])
            return out
        try:
            values = np.asarray(data, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"apply takes (n, 3) readings or a DataFrame, got a {type(data).__name__}") from None
        if values.ndim != 2 or values.shape[1] != 3:
            raise InputError(f"apply takes (n, 3) readings or a DataFrame, got an array of shape {values.shape}")
        return self._corrected(values, temperature)

    def _corrected(self, raw: FloatArray, temperature: ArrayLike | None) -> FloatArray:
        if self.current is not None:
            return self._at_current(raw, temperature, self.current)
        if self.thermal is None:
            return apply_model(raw, self.offset, self.matrix)
        temp = self._per_row(raw, temperature, ("temperature", "temperature", "°C"), self.thermal.column)
        fixed, _ = thermal_correct(raw, temp, self.offset, self.matrix, self.thermal.drift())
        return fixed

    def _at_current(self, raw: FloatArray, amperes: ArrayLike | None, block: Current) -> FloatArray:
        current = self._per_row(raw, amperes, ("motor current", "the current", "amperes"), block.column)
        return current_correct(raw, current, self.offset, self.matrix, block.per_amp)

    def _per_row(self, raw: FloatArray, given: ArrayLike | None, said: tuple[str, str, str], column: str) -> FloatArray:
        """The value each row is corrected at (``temperature=``), one per row of ``raw``; ``said``:
        what it is, how a count of them is named, and its unit."""
        what, counted, unit = said
        if given is None:
            raise InputError(
                f"this calibration corrects each row at its {what}: give temperature= (n,) {unit} "
                f"(its column {column!r})",
                file=self.path,
            )
        values = np.asarray(given, dtype=np.float64).reshape(-1)
        if values.shape[0] != raw.shape[0]:
            raise InputError(f"{counted} has {values.shape[0]} values for {raw.shape[0]} rows", file=self.path)
        return values

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write atomically: JSON, or YAML when ``path`` ends in .yaml/.yml; '-' is stdout."""
        write(self, os.fspath(path))

    def _typed(self) -> dict[str, object]:
        """Every typed field in the file's form."""

        def each(parts: Sequence[Pose | Turn | Rotation | Gap] | None) -> list[dict[str, object]] | None:
            return None if parts is None else [p.as_dict() for p in parts]

        return {
            "format": FORMAT,
            "version": VERSION,
            "sensor": self.sensor,
            "method": self.method,
            "reference": self.reference,
            "units": self.units,
            "input_units": self.input_units,
            "columns": list(self.columns),
            "axes": None if self.axes is None else self.axes.text,
            "offset": floats(self.offset),
            "matrix": rows_of(self.matrix),
            "gain": floats(self.gain),
            "uncertainty": {k: _nested(v) for k, v in self.uncertainty.items()} if self.uncertainty else None,
            "tilt_sensitivity": None if self.tilt_sensitivity is None else self.tilt_sensitivity.as_dict(),
            "thermal": None if self.thermal is None else self.thermal.as_dict(),
            "current": None if self.current is None else self.current.as_dict(),
            "poses": each(self.poses),
            "unit": None if self.unit is None else self.unit.as_dict(),
            "verdict": None if self.verdict is None else self.verdict.as_dict(),
            "created": self.created,
            "tool": self.tool,
            "turns": each(self.turns),
            "g_sensitivity": None if self.g_sensitivity is None else self.g_sensitivity.as_dict(),
            "rotations": each(self.rotations),
            "covariance": None if self.covariance is None else self.covariance.as_dict(),
            "coverage": self.coverage,
            "coverage_gaps": each(self.coverage_gaps),
            "residuals": None if self.residuals is None else self.residuals.as_dict(),
            "outliers": None if self.outliers is None else self.outliers.as_dict(),
            "segmentation": None if self.segmentation is None else self.segmentation.as_dict(),
        }

    def to_dict(self) -> dict[str, object]:
        """The file's document (the JSON/YAML boundary)."""
        typed = self._typed()
        doc: dict[str, object] = {}
        for key in self.order:
            if key in self.fields:
                doc[key] = self.fields[key]
            elif key in typed:
                doc[key] = typed[key]
        for key in ("unit", "verdict"):  # given since the file was read (a verdict judged afresh)
            if key not in doc and typed[key] is not None:
                doc[key] = typed[key]
        if "axes" not in doc and self.axes is not None:
            doc = _insert(doc, "offset", {"axes": self.axes.text}, after=False)
        for block in ("thermal", "current"):  # added to a file that had none: before poses
            if block not in doc and typed[block] is not None:
                doc = _insert(doc, "poses", {block: typed[block]}, after=False)
        added = {k: typed[k] for k in PARTS if k not in doc and typed[k] is not None}
        return _insert(doc, "poses", added, after=True) if added else doc

    def with_verdict(self, verdict: Verdict) -> Calibration:
        return replace(self, verdict=verdict)

    def __repr__(self) -> str:
        serial = f", serial={self.serial!r}" if self.serial else ""
        return (
            f"Calibration({self.sensor}, {self.method}, reference={self.reference:g}{serial}, "
            f"offset={floats(self.offset)}, gain={floats(self.gain)})"
        )


def _frame_columns(frame: Frame, wanted: Sequence[str], path: str | None) -> list[int]:
    """Where ``wanted`` are among the DataFrame's columns: the column of that exact name, else the
    one column of that name in another case; an error names those missing or ambiguous."""
    names = [str(c) for c in frame.columns]
    where, missing = [], []
    for w in wanted:
        exact = [k for k, n in enumerate(names) if n == w]
        near = exact or [k for k, n in enumerate(names) if n.lower() == w.lower()]
        if len(near) > 1:
            raise InputError(
                f"the DataFrame has {len(near)} columns named {w!r}: which one is the sensor's?", file=path
            )
        if not near:
            missing.append(w)
        else:
            where.append(near[0])
    if missing:
        raise InputError(
            f"the DataFrame has no column{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
            f"which the calibration corrects (columns: {', '.join(names)})",
            file=path,
        )
    return where


def _nested(value: FloatArray) -> list[float] | list[list[float]]:
    array = np.asarray(value, dtype=np.float64)
    return floats(array) if array.ndim == 1 else rows_of(array)


Part = TypeVar("Part")


def from_dict(doc: Doc, path: str | None = None) -> Calibration:
    """A Calibration from a document that :func:`validate` has accepted. A field whose typed
    form would not write it as it was (another writer's form) is kept in ``fields``."""
    kept = {k: v for k, v in doc.items() if k not in ORDER and k not in PARTS and k != "axes"}

    def part(key: str, reader: Callable[[object], Part | None]) -> Part | None:
        """The field ``key`` read typed; as written in ``kept`` when it is of another kind."""
        value = doc.get(key)
        read = reader(value)
        if read is None and value is not None:
            kept[key] = value
        return read

    uncertainty = doc.get("uncertainty") or {}
    assert isinstance(uncertainty, dict)
    poses = doc.get("poses") or []
    assert isinstance(poses, list)
    coverage = doc.get("coverage")
    if coverage is not None and not same(number(coverage), coverage):
        kept["coverage"] = coverage
    tool = doc.get("tool")
    if tool is not None and not isinstance(tool, str):
        kept["tool"] = tool
    reference, columns = doc["reference"], doc["columns"]
    assert is_number(reference)
    assert isinstance(columns, list)
    return Calibration(
        sensor=str(doc["sensor"]),
        method=str(doc["method"]),
        reference=float(reference),
        columns=[str(c) for c in columns],
        offset=np.array(doc["offset"], dtype=np.float64),
        matrix=np.array(doc["matrix"], dtype=np.float64),
        gain=np.array(doc["gain"], dtype=np.float64),
        units=text(doc.get("units")),
        input_units=text(doc.get("input_units")),
        axes=axes_of(doc.get("axes"), path),
        uncertainty={str(k): np.array(v, dtype=np.float64) for k, v in uncertainty.items() if v is not None},
        tilt_sensitivity=part("tilt_sensitivity", _object(read_tilt)),
        thermal=None if doc.get("thermal") is None else thermal_from(doc["thermal"], path),
        current=_current(doc, path),
        poses=tuple(read_pose(p) for p in poses),
        unit=_unit(doc.get("unit"), kept),
        verdict=part("verdict", _object(read_verdict)),
        created=created_text(doc.get("created")),
        tool=text(tool),
        covariance=part("covariance", _object(read_covariance)),
        coverage=number(coverage),
        coverage_gaps=part("coverage_gaps", lambda v: read_list(v, read_gap)),
        residuals=part("residuals", _object(read_residuals)),
        outliers=part("outliers", _object(read_left_out)),
        segmentation=part("segmentation", _object(read_segmentation)),
        turns=part("turns", lambda v: read_list(v, read_turn)),
        g_sensitivity=part("g_sensitivity", _object(read_g_sensitivity)),
        rotations=part("rotations", lambda v: read_list(v, read_rotation)),
        fields=kept,
        order=tuple(doc),
        path=path,
    )


def _current(doc: Doc, path: str | None) -> Current | None:
    """The ``current`` block, of a magnetometer without a ``thermal`` block (apply reads one per-row column)."""
    if doc.get("current") is None:
        return None
    if doc["sensor"] != "magnetometer" or doc.get("thermal") is not None:
        raise InputError("field 'current' belongs to a magnetometer's calibration without a 'thermal' block", file=path)
    return current_from(doc["current"], path)


def _object(reader: Callable[[Doc], Part | None]) -> Callable[[object], Part | None]:
    """``reader`` of a JSON object, given any value (None for one that is not an object)."""
    return lambda value: reader(value) if isinstance(value, dict) else None


def _unit(value: object, kept: dict[str, object]) -> Unit | None:
    """The unit block (validated: an object with a meta object), always written with its four
    fields; one whose values are not text (a YAML serial read as a number) is kept as written."""
    if not isinstance(value, dict):
        return None
    meta = value.get("meta") or {}
    assert isinstance(meta, dict)
    written = {k: value.get(k) for k in ("serial", "station", "operator")} | {"meta": dict(meta)}
    unit = Unit(
        named(written["serial"]),
        named(written["station"]),
        named(written["operator"]),
        {str(k): str(v) for k, v in meta.items()},
    )
    if not same(unit.as_dict(), written):
        kept["unit"] = written
    return unit


@dataclass(frozen=True)
class Basis:
    """What a calibration is of and in: the ``sensor``, the ``reference`` magnitude, the sensor
    ``columns``, the output and input units; and the tolerances its tilt sensitivity is stated
    for (the fixture's ``tolerance_deg``, and ``gain_tolerance``, the gain error a 1-pose up
    offset's tilt sensitivity allows for)."""

    sensor: str
    reference: float
    columns: Sequence[str]
    units: str | None = None
    input_units: str | None = None
    tolerance_deg: float = 1.0
    gain_tolerance: float | None = None


@dataclass(frozen=True)
class Made:
    """How a calibration's poses were found and what a gyroscope turned through: the
    ``segmentation`` of a continuous log, a gyroscope's known ``turns`` and ``g_sensitivity``,
    or its hand ``rotations``."""

    segmentation: SegmentationPart | None = None
    turns: Sequence[Turn] | None = None
    g_sensitivity: GSensitivity | None = None
    rotations: Sequence[Rotation] | None = None


def build(
    solution: Solution,
    basis: Basis,
    poses: Sequence[Pose | Doc],
    *,
    fit: Fit | None = None,
    unit: Unit | Doc | None = None,
    verdict: Verdict | None = None,
    made: Made | None = None,
    outliers: LeftOut | None = None,
) -> Calibration:
    """The calibration of a solution, fields in the order of docs/reference/calibration-file.md
    (format version 1); ``fit`` adds what the solver measured beyond the parameters (tilt sensitivity,
    covariance, coverage, residuals); ``made`` how the poses were found in a continuous log
    (after ``poses``, and after a gyroscope's ``turns`` and ``g_sensitivity`` or
    ``rotations``). ``poses`` and ``unit`` may also be given in the file's form (objects)."""
    sensor, reference, columns, units = basis.sensor, basis.reference, list(basis.columns), basis.units
    tolerance_deg, gain_tolerance = basis.tolerance_deg, basis.gain_tolerance
    made = made or Made()
    segmentation, turns, g_sensitivity, rotations = made.segmentation, made.turns, made.g_sensitivity, made.rotations
    if units is None and sensor == "accelerometer":  # 1: g, 9.80665: m/s^2, 1000: mg (export needs them)
        units = REFERENCE_UNITS.get(reference)
    kept: dict[str, object] = {}  # a unit given as an object, if its values are not text
    uncertainty = {"offset": solution.offset_se, "gain": solution.gain_se}
    tilt = covariance = residuals = None
    coverage = gaps = None
    if fit is not None:
        if fit.cross_se is not None:
            uncertainty["cross_axis"] = fit.cross_se
        if fit.tilt is not None:
            offset, gain, cross = fit.tilt
            tilt = Tilt(offset, gain, None if fit.cross_se is None else cross, tolerance_deg, gain_tolerance)
        if fit.covariance is not None:
            covariance = Covariance(fit.covariance)
        coverage = fit.coverage
        if fit.reach is not None and fit.reach.gaps:
            gaps = tuple(Gap(name, round(angle, 1)) for name, angle in fit.reach.gaps)
        if fit.residuals is not None and len(fit.residuals):
            r = fit.residuals
            residuals = Residuals(float(np.abs(r).max()), float(np.sqrt(np.mean(r**2))), len(r))
    given = (
        ("covariance", covariance),
        ("coverage", coverage),
        ("coverage_gaps", gaps),
        ("residuals", residuals),
        ("outliers", outliers),
    )
    measured = [k for k, v in given if v is not None]
    turned = [
        k for k, v in (("turns", turns), ("g_sensitivity", g_sensitivity), ("rotations", rotations)) if v is not None
    ]
    found = ["segmentation"] if segmentation is not None else []
    order = [*ORDER[:11], "uncertainty", *(["tilt_sensitivity", *measured] if tilt else []), "poses"]
    order += [*turned, *found, *([] if tilt else measured)] if turned else [*([] if tilt else measured), *found]
    return Calibration(
        sensor=sensor,
        method=solution.method,
        reference=reference,
        columns=columns,
        offset=solution.offset,
        matrix=solution.matrix,
        gain=solution.gain,
        units=units,
        input_units=basis.input_units,
        uncertainty=uncertainty,
        tilt_sensitivity=tilt,
        poses=tuple(p if isinstance(p, Pose) else read_pose(p) for p in poses),
        unit=unit if isinstance(unit, Unit) else _unit(unit, kept) if unit is not None else Unit(),
        verdict=verdict or Verdict(),
        created=created(),
        tool=f"tumblecal {__version__}",
        covariance=covariance,
        coverage=coverage,
        coverage_gaps=gaps,
        residuals=residuals,
        outliers=outliers,
        segmentation=segmentation,
        turns=None if turns is None else tuple(turns),
        g_sensitivity=g_sensitivity,
        rotations=None if rotations is None else tuple(rotations),
        fields=kept,
        order=(*order, "unit", "verdict", "created", "tool"),
    )


def _insert(doc: dict[str, object], key: str, extra: dict[str, object], *, after: bool) -> dict[str, object]:
    """``doc`` with ``extra`` placed before (or ``after``) ``key`` (at the end when ``key`` is not there)."""
    if key not in doc:
        return {**doc, **extra}
    out: dict[str, object] = {}
    for k, v in doc.items():
        if k == key and not after:
            out.update(extra)
        out[k] = v
        if k == key and after:
            out.update(extra)
    return out


#: ``SOURCE_DATE_EPOCH`` as the caller set it ("": not set), for work done on its behalf
#: elsewhere (a batch's unit on a Dask worker, whose environment is not the caller's).
CALLER_EPOCH: ContextVar[str | None] = ContextVar("CALLER_EPOCH", default=None)


def created_text(value: object) -> str | None:
    """``created`` as text: a hand-written YAML file's unquoted timestamp is read as a datetime."""
    if value is None:
        return None
    if isinstance(value, datetime):
        when = value if value.tzinfo is not None else value.replace(tzinfo=UTC)
        return when.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    if isinstance(value, date):
        return value.isoformat()
    return str(value)


def created() -> str:
    """Now in UTC, or ``SOURCE_DATE_EPOCH`` when set (reproducible files)."""
    epoch = CALLER_EPOCH.get()
    epoch = (os.environ.get("SOURCE_DATE_EPOCH", "") if epoch is None else epoch).strip()
    if epoch and not epoch.isdigit():  # reproducible-builds.org: a malformed value is an error
        raise InputError(f"SOURCE_DATE_EPOCH={epoch!r} is not a whole number of seconds since 1970")
    try:
        when = datetime.fromtimestamp(int(epoch), UTC) if epoch else datetime.now(UTC)
    except (ValueError, OverflowError, OSError):  # a year past 9999: no ISO 8601 time for it
        raise InputError(f"SOURCE_DATE_EPOCH={epoch} is out of range for a date") from None
    return when.strftime("%Y-%m-%dT%H:%M:%SZ")


def dumps(cal: Calibration | Doc, path: str) -> str:
    """Text of a calibration (or a document) in the format the path's suffix asks for."""
    doc = cal.to_dict() if isinstance(cal, Calibration) else dict(cal)
    if is_yaml(path):
        import yaml

        return str(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100))
    return _json(doc, 0) + "\n"


def write(cal: Calibration | Doc, path: str) -> None:
    """Write a calibration (or its document) atomically ('-': stdout)."""
    text = dumps(cal, path).encode()
    with atomic_output(path) as out:
        out.write(text)


def load(path: str | os.PathLike[str]) -> Calibration:
    """Read and validate a calibration file ('-': stdin); every problem names the file and the field."""
    if not isinstance(path, str | os.PathLike):
        raise InputError(f"load takes a calibration file's path, not a {type(path).__name__}")
    name = os.fspath(path)
    return validate(read_object(name, "calibration file"), name)


def resolve(cal: Calibration | str | os.PathLike[str]) -> Calibration:
    """A calibration given as itself or as its file."""
    if isinstance(cal, Calibration):
        return cal
    if not isinstance(cal, str | os.PathLike):  # (load(None) says as much; this names the kind)
        raise InputError(f"a calibration is a Calibration or its file, not a {type(cal).__name__}")
    return load(cal)


def validate(doc: Doc, path: str) -> Calibration:
    """The Calibration of a document, validated as :func:`load` does."""
    if doc.get("format") != FORMAT:
        what = f"unknown format {doc['format']!r}" if "format" in doc else "missing field 'format'"
        raise InputError(f"not a tumblecal calibration: {what} (expected {FORMAT!r})", file=path)
    if "version" not in doc:
        raise InputError("missing field 'version'", file=path)
    if isinstance(doc["version"], bool) or doc["version"] != VERSION:  # True == 1 in Python
        raise InputError(
            f"unsupported calibration version {doc['version']!r} (this tumblecal reads version {VERSION})",
            file=path,
            hint="upgrade tumblecal to read newer calibration files",
        )
    for name in REQUIRED:
        if name not in doc:
            raise InputError(f"missing field {name!r}", file=path)
    if doc["sensor"] not in SENSORS:
        raise InputError(f"field 'sensor' must be one of {', '.join(SENSORS)}", file=path)
    columns = doc["columns"]
    if not (isinstance(columns, list) and len(columns) == 3 and all(isinstance(c, str) for c in columns)):
        raise InputError("field 'columns' must be a list of three column names", file=path)
    if len({c.strip().lower() for c in columns}) != 3:  # one column corrected twice, another not at all
        raise InputError(f"field 'columns' must name three different columns, got {', '.join(columns)}", file=path)
    vector_field(doc["gain"], "gain", path)  # required by the contract, so validated like offset
    _optional_fields(doc, path)
    offset_field(doc["offset"], "offset", path)
    invertible(_matrix(doc["matrix"], "matrix", path), path)
    return from_dict(doc, path)


def _pose_entry(pose: Doc, name: str, path: str) -> None:
    """The fields of one pose entry that are there, validated (``name``: ``poses[k]``)."""
    if pose.get("pose") is not None and not (isinstance(pose["pose"], str) and _is_label(pose["pose"])):
        raise InputError(
            f"field '{name}.pose' must be a face (+x -x +y -y +z -z), a direction X,Y,Z or null", file=path
        )
    samples = pose.get("samples", 1)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise InputError(f"field '{name}.samples' must be a positive integer", file=path)
    for key in ("mean", "std"):
        if key in pose:
            vector_field(pose[key], f"{name}.{key}", path)
    if pose.get("angle_deg") is not None:
        number_field(pose["angle_deg"], f"{name}.angle_deg", path)


def _is_label(text: str) -> bool:
    try:
        return parse_label(text) == text
    except ValueError:
        return False


def _optional_fields(doc: Doc, path: str) -> None:
    """Fields beyond REQUIRED that ``show`` and ``check`` read, validated where present (null: absent)."""
    if not isinstance(doc["method"], str):
        raise InputError("field 'method' must be a string", file=path)
    reference = number_field(doc["reference"], "reference", path)
    if reference < 0 or (reference == 0 and doc["sensor"] != "gyroscope"):
        raise InputError(f"field 'reference' must be positive (0 only for a gyroscope), got {reference:g}", file=path)
    for name in ("units", "input_units", "axes"):
        if doc.get(name) is not None and not isinstance(doc[name], str):
            raise InputError(f"field {name!r} must be a string or null", file=path)
    axes_of(doc.get("axes"), path)
    for block in ("uncertainty", "tilt_sensitivity"):
        value = doc.get(block)
        if value is None:
            continue
        if not (isinstance(value, dict) and "offset" in value and "gain" in value):
            raise InputError(f"field {block!r} must be an object with 'offset' and 'gain'", file=path)
        vector_field(value["offset"], f"{block}.offset", path)
        vector_field(value["gain"], f"{block}.gain", path)
        for key in ("tolerance_deg", "gain_tolerance"):
            if value.get(key) is not None:
                number_field(value[key], f"{block}.{key}", path)
    _nested_fields(doc, path)


def _nested_fields(doc: Doc, path: str) -> None:
    """residuals, unit, poses and verdict, validated where present."""
    residuals = doc.get("residuals")
    if residuals is not None:
        if not (isinstance(residuals, dict) and "max" in residuals):
            raise InputError("field 'residuals' must be an object with rms, max and count", file=path)
        for key in ("rms", "max"):
            if key in residuals:
                number_field(residuals[key], f"residuals.{key}", path)
    unit = doc.get("unit")
    if unit is not None and not isinstance(unit, dict):
        raise InputError("field 'unit' must be an object (serial, station, operator, meta)", file=path)
    if not isinstance((unit or {}).get("meta") or {}, dict):
        raise InputError("field 'unit.meta' must be an object (KEY: VALUE)", file=path)
    for key in ("serial", "station", "operator"):  # one line each: a line break would split report's lines
        value = (unit or {}).get(key)
        if isinstance(value, str) and control_character(value):
            raise InputError(f"field 'unit.{key}' holds a control character: {value!r}", file=path)
    unit_fields(unit, path)  # text, as every export writes it and import reads it back
    poses = doc.get("poses")
    if poses is not None:
        if not isinstance(poses, list):
            raise InputError("field 'poses' must be a list of pose objects", file=path)
        for k, pose in enumerate(poses):
            if not (isinstance(pose, dict) and all(key in pose for key in ("pose", "mean", "samples"))):
                raise InputError(f"field 'poses[{k}]' must be an object with pose, mean and samples", file=path)
            _pose_entry(pose, f"poses[{k}]", path)
    _verdict_field(doc.get("verdict"), path)


def _verdict_field(verdict: object, path: str) -> None:
    if verdict is not None and not (
        isinstance(verdict, dict)
        and isinstance(verdict.get("pass"), bool)
        and isinstance(verdict.get("failures"), list)
    ):
        raise InputError(
            "field 'verdict' must be an object with 'pass' (true/false) and 'failures' (a list)", file=path
        )
    if verdict is not None:
        for k, failure in enumerate(verdict["failures"]):
            if not (isinstance(failure, dict) and isinstance(failure.get("code"), str)):
                raise InputError(f"field 'verdict.failures[{k}]' must be an object with a 'code'", file=path)
        if not isinstance(verdict.get("limits") or {}, dict):
            raise InputError("field 'verdict.limits' must be an object", file=path)
        if verdict["pass"] == bool(verdict["failures"]):  # edited by hand: which one is true?
            said = "passes" if verdict["pass"] else "fails"
            raise InputError(
                f"field 'verdict' {said} with {len(verdict['failures'])} failures: the file was altered",
                file=path,
                hint="solve again, or judge it afresh with `tumblecal check` and your limits",
            )


def number_field(value: object, name: str, path: str | None) -> float:
    if not is_number(value):
        raise InputError(f"field {name!r} must be a finite number", file=path)
    return float(value)


def vector_field(value: object, name: str, path: str | None) -> FloatArray:
    if not (isinstance(value, list) and len(value) == 3):
        raise InputError(f"field {name!r} must be a list of 3 numbers", file=path)
    return np.array([number_field(v, name, path) for v in value])


def offset_field(value: object, name: str, path: str) -> FloatArray:
    """An offset is a reading (core.model.MAX_READING bounds both): past it, the corrected
    readings' squares overflow and every figure made from them comes out inf or NaN."""
    offset = vector_field(value, name, path)
    largest = float(np.abs(offset).max())
    if largest > MAX_READING:
        raise InputError(
            f"field {name!r} has an entry of {largest:.3g}: beyond any reading tumblecal computes with "
            f"(|reading| <= {MAX_READING:g})",
            file=path,
        )
    return offset


def invertible(matrix: FloatArray, path: str, name: str = "matrix") -> FloatArray:
    """M must have an inverse (A, whose diagonal is the gain): a singular one corrects nothing."""
    if not np.isfinite(np.linalg.cond(matrix)) or np.linalg.cond(matrix) > 1e12:
        raise InputError(f"field {name!r} is singular (it has no inverse)", file=path)
    largest = float(np.abs(matrix).max())
    if not 1e-100 <= largest <= 1e100:  # its inverse, the gains, the exports would overflow
        raise InputError(f"field {name!r} has entries of {largest:.3g}: no sensor's correction is that", file=path)
    return matrix


def _matrix(value: object, name: str, path: str) -> FloatArray:
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) and len(r) == 3 for r in value)):
        raise InputError(f"field {name!r} must be a 3x3 list of numbers", file=path)
    return np.array([[number_field(v, name, path) for v in row] for row in value])


def _json(value: object, depth: int) -> str:
    """JSON with two-space indent, lists of plain values on one line (vectors, matrix rows)."""
    if type(value) is float and "n" not in (text := float.__repr__(value)):  # (nan, inf: json's NaN, Infinity)
        return text
    if isinstance(value, list) and value and all(type(v) is float for v in value):  # a vector: most of a file
        text = ", ".join(map(float.__repr__, value))
        if "n" not in text:
            return f"[{text}]"
    pad, inner = "  " * depth, "  " * (depth + 1)
    if isinstance(value, dict) and value:
        items = [f"{inner}{_key(k)}: {_json(v, depth + 1)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{pad}}}"
    if isinstance(value, list) and value and not all(isinstance(v, int | float | str | None) for v in value):
        return "[\n" + ",\n".join(inner + _json(v, depth + 1) for v in value) + f"\n{pad}]"
    plain = _plain(value) if not isinstance(value, list) else [_plain(v) for v in value]
    if isinstance(plain, str):
        return plain
    if isinstance(plain, list) and None not in plain:
        return "[" + ", ".join(plain) + "]"  # type: ignore[arg-type]
    return json.dumps(value, ensure_ascii=False, separators=(", ", ": "))


_KEYS: dict[object, str] = {}


def _key(k: object) -> str:
    """json.dumps of a key, each once (a file of thousands of poses names the same keys again)."""
    found = _KEYS.get(k)
    if found is None:
        found = _KEYS[k] = json.dumps(k)
    return found


def _plain(v: object) -> str | None:
    """json.dumps of None, a bool, an int or a float (float.__repr__, as json's), without its
    call; None for anything else."""
    if v is None or isinstance(v, bool):
        return {None: "null", True: "true", False: "false"}[v]
    if isinstance(v, float):
        return float.__repr__(v) if v - v == 0 else "NaN" if v != v else "Infinity" if v > 0 else "-Infinity"
    return int.__repr__(v) if isinstance(v, int) else None


def refuse_failed(cal: Calibration, doing: str, command: str) -> None:
    """A calibration whose verdict failed goes nowhere without --force (apply, export)."""
    failures = cal.verdict.failures if cal.verdict is not None else ()
    codes = ", ".join(f.code for f in failures)
    raise InputError(
        f"this unit failed its limits ({codes or 'verdict: fail'}): refusing to {doing}",
        file=cal.path,
        hint=f"pass --force to {command} it anyway",
    )
