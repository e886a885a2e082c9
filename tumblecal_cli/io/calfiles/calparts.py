"""The typed parts of a calibration file (docs/reference/calibration-file.md): its poses, tilt
sensitivity, residuals, covariance, segmentation, hand or known turns, unit, verdict and thermal
block, each a frozen dataclass with its JSON/YAML form (``as_dict``) and its reader (``read_*``).

A part read from a file written by another tool (or edited by hand) may hold keys tumblecal
does not know, a value of another kind than the field's (``"rows": "all"``) or its keys in
another order. A :class:`Part` keeps those as written (``keys``, ``extra``), so that a file read
and written again keeps them; the typed fields hold what tumblecal reads, best effort.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeGuard, TypeVar

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.axes import Axes
from tumblecal_cli.core.axes import parse as parse_axes
from tumblecal_cli.core.drift import Drift
from tumblecal_cli.core.gate import Finding, Limits
from tumblecal_cli.errors import InputError, control_character

#: A JSON/YAML object as parsed (the boundary: its values are whatever the file holds).
Doc = Mapping[str, object]


def is_number(value: object) -> TypeGuard[int | float]:
    """A finite JSON/YAML number (not a boolean, which Python counts as an int)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer beyond any float (1e400 written out)
        return False


def floats(values: FloatArray | Sequence[float]) -> list[float]:
    return [float(v) for v in values]


def rows_of(matrix: FloatArray) -> list[list[float]]:
    return [floats(row) for row in matrix]


def same(a: object, b: object) -> bool:
    """Whether two JSON/YAML values are written alike (type, key order and digits)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and (repr(a) == repr(b) if isinstance(a, float) else a == b)


# -- best-effort readers of one value: None when it is of another kind -------------------------


def text(value: object) -> str | None:
    return value if isinstance(value, str) else None


def named(value: object) -> str | None:
    """A name as the file's readers print it (a number given as a file name reads as its text)."""
    return None if value is None else str(value)


def number(value: object) -> float | None:
    return float(value) if is_number(value) else None


def whole(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def vector(value: object, size: int | None = 3) -> FloatArray | None:
    if not (isinstance(value, list) and (size is None or len(value) == size) and all(map(is_number, value))):
        return None
    return np.array(value, dtype=np.float64)


def matrix_of(value: object, rows: int | None = 3, cols: int | None = 3) -> FloatArray | None:
    if not (isinstance(value, list) and (rows is None or len(value) == rows)):
        return None
    read = [vector(row, cols) for row in value]
    if not read or any(r is None for r in read) or len({len(r) for r in read if r is not None}) != 1:
        return None
    return np.array(read, dtype=np.float64)


def pair(value: object, kind: Callable[[object], float | int | None]) -> tuple[float, float] | None:
    if not (isinstance(value, list) and len(value) == 2):
        return None
    first, last = kind(value[0]), kind(value[1])
    return None if first is None or last is None else (first, last)


def pair_of_ints(value: object) -> tuple[int, int] | None:
    if not (isinstance(value, list) and len(value) == 2):
        return None
    first, last = whole(value[0]), whole(value[1])
    return None if first is None or last is None else (first, last)


# -- a part of the file, kept as written ---------------------------------------------------------


@dataclass(frozen=True)
class Part:
    """An object of the file. ``keys``: the keys it has, in order (None: tumblecal's own form,
    :meth:`own_keys`); ``extra``: the values of keys it holds untyped (another writer's keys,
    and values of another kind than the field's), written as they were."""

    keys: tuple[str, ...] | None = field(default=None, kw_only=True)
    extra: Mapping[str, object] = field(default_factory=dict, kw_only=True, compare=False)

    def typed(self) -> dict[str, object]:
        """The typed fields in the file's form, in tumblecal's order."""
        raise NotImplementedError

    def own_keys(self, typed: Mapping[str, object]) -> tuple[str, ...]:
        """The keys tumblecal writes: every typed field, then the extra ones."""
        return (*typed, *(k for k in self.extra if k not in typed))

    def as_dict(self) -> dict[str, object]:
        typed = self.typed()
        keys = self.own_keys(typed) if self.keys is None else self.keys
        return {k: self.extra[k] if k in self.extra else typed[k] for k in keys}


P = TypeVar("P", bound=Part)


def as_read(part: P, raw: Doc) -> P:
    """``part`` (read best effort from ``raw``) keeping what of ``raw`` it does not reproduce."""
    typed = part.typed()
    kept = {k: v for k, v in raw.items() if k not in typed or not same(typed[k], v)}
    written = replace(part, keys=tuple(raw), extra=kept)
    return part if written.own_keys(typed) == tuple(raw) and not kept else written


def optional(typed: dict[str, object], *names: str) -> dict[str, object]:
    """``typed`` without the ``names`` whose value is None (keys tumblecal writes only when known)."""
    return {k: v for k, v in typed.items() if not (k in names and v is None)}


# -- poses ---------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Pose(Part):
    """A pose the calibration was solved from (docs/reference/calibration-file.md: ``poses[]``): its face
    (``pose``), where it was read from, its statistics, and how it reads once corrected. Fields
    that are None are absent from the entry, except those tumblecal writes as null (the
    orientation-dependent ones: ``angle_deg``, ``vector_error``) where ``keys`` has them."""

    face: str | None
    mean: FloatArray  # (3,) raw units
    samples: int
    std: FloatArray | None = None  # (3,); 0.0 for one sample; other writers may leave it out
    file: str | None = None
    sha256: str | None = None
    rows: tuple[int, int] | None = None  # first and last data row used (0-based)
    label: str | None = None  # a log's section label (known turns)
    block: int | None = None  # a log's block number
    times: tuple[float, float] | None = None  # a block's first and last time
    duration_s: float | None = None
    temperature: float | None = None  # °C, the mean of the temperature column
    angle_deg: float | None = None
    clipped: int | None = None
    drift: FloatArray | None = None  # (3,) raw units, last third's mean minus the first's
    norm_error: float | None = None
    vector_error: float | None = None
    accelerometer_mean: FloatArray | None = None  # (3,) a gyroscope pose's accelerometer reading

    #: The entry of a pose of solve: always these, with None written as null.
    SOLVED = ("pose", "file", "sha256", "rows", "samples", "mean", "std", "angle_deg", "clipped", "drift")

    def typed(self) -> dict[str, object]:
        return {
            "pose": self.face,
            "file": self.file,
            "sha256": self.sha256,
            "rows": None if self.rows is None else list(self.rows),
            "label": self.label,
            "block": self.block,
            "times": None if self.times is None else list(self.times),
            "samples": self.samples,
            "mean": floats(self.mean),
            "std": None if self.std is None else floats(self.std),
            "duration_s": self.duration_s,
            "temperature": self.temperature,
            "angle_deg": self.angle_deg,
            "clipped": self.clipped,
            "drift": None if self.drift is None else floats(self.drift),
            "norm_error": self.norm_error,
            "vector_error": self.vector_error,
            "accelerometer_mean": None if self.accelerometer_mean is None else floats(self.accelerometer_mean),
        }

    def own_keys(self, typed: Mapping[str, object]) -> tuple[str, ...]:
        present = [k for k, v in typed.items() if v is not None or k in ("pose", "angle_deg", "vector_error")]
        if self.norm_error is None:  # not a pose of solve: no orientation fields either
            present = [k for k in present if k not in ("angle_deg", "vector_error")]
        return (*present, *(k for k in self.extra if k not in typed))

    @property
    def name(self) -> str:
        """How messages name the pose: its file, and its block when cut from a log."""
        return (self.file or "") + ("" if self.block is None else f" block {self.block}")

    def __getitem__(self, key: str) -> object:
        """The entry's field as the file writes it (``pose["samples"]``), for code that reads the
        poses as the file's objects."""
        return self.as_dict()[key]


def read_pose(raw: Doc) -> Pose:
    """A pose entry that :func:`calfile.validate` has accepted (pose, mean and samples there)."""
    mean = vector(raw.get("mean"))
    assert mean is not None
    block = raw.get("block")
    pose = Pose(
        face=text(raw.get("pose")),
        mean=mean,
        samples=whole(raw.get("samples")) or 1,
        std=vector(raw.get("std")),
        file=named(raw.get("file")),
        sha256=named(raw.get("sha256")),
        rows=pair_of_ints(raw.get("rows")),
        label=text(raw.get("label")),
        block=block if isinstance(block, int) else None,  # (True: a block number 1, as it was read)
        times=pair(raw.get("times"), number),
        duration_s=number(raw.get("duration_s")),
        temperature=number(raw.get("temperature")),
        angle_deg=number(raw.get("angle_deg")),
        clipped=whole(raw.get("clipped")),
        drift=vector(raw.get("drift")),
        norm_error=number(raw.get("norm_error")),
        vector_error=number(raw.get("vector_error")),
        accelerometer_mean=vector(raw.get("accelerometer_mean")),
    )
    return as_read(pose, raw)


# -- what a solver measured beyond the parameters ---------------------------------------------------


@dataclass(frozen=True, eq=False)
class Tilt(Part):
    """``tilt_sensitivity``: the worst-case shift of the offsets and gains (and cross-axis terms)
    if each pose is ``tolerance_deg`` off level; ``gain_tolerance`` the gain error a 1-pose up
    offset's entry allows for."""

    offset: FloatArray  # (3,)
    gain: FloatArray  # (3,)
    cross_axis: FloatArray | None = None  # (3, 3)
    tolerance_deg: float | None = None
    gain_tolerance: float | None = None

    def typed(self) -> dict[str, object]:
        doc: dict[str, object] = {
            "offset": floats(self.offset),
            "gain": floats(self.gain),
            "cross_axis": None if self.cross_axis is None else rows_of(self.cross_axis),
            "tolerance_deg": self.tolerance_deg,
            "gain_tolerance": self.gain_tolerance,
        }
        return optional(doc, "cross_axis", "gain_tolerance")


def axes_of(value: object, path: str | None) -> Axes | None:
    """A file's ``axes`` (the body's axes in the sensor's, core.axes): None where there is none; a
    value that is not three signed axes is an InputError naming the field."""
    if value is None:
        return None
    try:
        return parse_axes(str(value))
    except ValueError as err:
        raise InputError(f"field 'axes' {value!r}: {err}", file=path) from None


def read_tilt(raw: Doc) -> Tilt:
    offset, gain = vector(raw.get("offset")), vector(raw.get("gain"))
    assert offset is not None
    assert gain is not None  # validated
    tilt = Tilt(
        offset,
        gain,
        matrix_of(raw.get("cross_axis")),
        number(raw.get("tolerance_deg")),
        number(raw.get("gain_tolerance")),
    )
    return as_read(tilt, raw)


@dataclass(frozen=True)
class Residuals(Part):
    """``residuals``: the RMS and largest of |M (mean - offset)| - reference over the ``count``
    poses or samples fitted."""

    max: float | None
    rms: float | None = None
    count: int | None = None

    def typed(self) -> dict[str, object]:
        return {"rms": self.rms, "max": self.max, "count": self.count}


def read_residuals(raw: Doc) -> Residuals:
    return as_read(Residuals(number(raw.get("max")), number(raw.get("rms")), whole(raw.get("count"))), raw)


@dataclass(frozen=True)
class LeftOutStretch(Part):
    """``outliers.stretches[]``: consecutive samples a robust fit left out: their ``file``, its data
    ``rows`` (0-based, first and last; None where the rows are not known: then ``samples``, the
    sample indices), and ``worst``, their largest |residual| as a share of the reference."""

    file: str | None
    rows: tuple[int, int] | None
    samples: tuple[int, int] | None
    worst: float | None

    def typed(self) -> dict[str, object]:
        rows, samples = (None if v is None else list(v) for v in (self.rows, self.samples))
        return {"file": self.file, "rows": rows, "samples": samples, "worst": self.worst}


def _pair(value: object) -> tuple[int, int] | None:
    if isinstance(value, list) and len(value) == 2 and all(whole(v) is not None for v in value):
        return (int(value[0]), int(value[1]))
    return None


def read_left_out_stretch(raw: Doc) -> LeftOutStretch:
    rows, samples = _pair(raw.get("rows")), _pair(raw.get("samples"))
    return as_read(LeftOutStretch(text(raw.get("file")), rows, samples, number(raw.get("worst"))), raw)


@dataclass(frozen=True, eq=False)
class LeftOut(Part):
    """``outliers``: what a fit over samples left out (core.robust): ``count`` of the ``of``
    samples, each beyond ``bound`` (|residual|, output units), in ``stretches``."""

    count: int | None
    of: int | None
    bound: float | None
    stretches: tuple[LeftOutStretch, ...] = ()

    def typed(self) -> dict[str, object]:
        return {
            "count": self.count,
            "of": self.of,
            "bound": self.bound,
            "stretches": [s.as_dict() for s in self.stretches],
        }


def read_left_out(raw: Doc) -> LeftOut:
    stretches = read_list(raw.get("stretches"), read_left_out_stretch) or ()
    return as_read(LeftOut(whole(raw.get("count")), whole(raw.get("of")), number(raw.get("bound")), stretches), raw)


@dataclass(frozen=True)
class Gap(Part):
    """``coverage_gaps[]``: a direction of ``coverage`` (``+z``, ``+x+z``, ``-x+y+z``) with no
    sample within 45°, and the angle to its nearest sample."""

    direction: str | None
    nearest_deg: float | None

    def typed(self) -> dict[str, object]:
        return {"direction": self.direction, "nearest_deg": self.nearest_deg}


def read_gap(raw: Doc) -> Gap:
    return as_read(Gap(text(raw.get("direction")), number(raw.get("nearest_deg"))), raw)


#: The order of the covariance's rows: the offset, then A = inv(M) row by row.
COVARIANCE_PARAMETERS = ("offset.x", "offset.y", "offset.z", *(f"A.{i}{j}" for i in "xyz" for j in "xyz"))


@dataclass(frozen=True, eq=False)
class Covariance(Part):
    """``covariance`` of the solved parameters (``parameters`` names its rows), 1σ²."""

    matrix: FloatArray  # (12, 12)
    parameters: tuple[str, ...] = COVARIANCE_PARAMETERS

    def typed(self) -> dict[str, object]:
        return {"parameters": list(self.parameters), "matrix": rows_of(self.matrix)}


def read_covariance(raw: Doc) -> Covariance | None:
    matrix, names = matrix_of(raw.get("matrix"), None, None), raw.get("parameters")
    if matrix is None or not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        return None
    return as_read(Covariance(matrix, tuple(names)), raw)


@dataclass(frozen=True, eq=False)
class SegmentationPart(Part):
    """``segmentation``: how the poses were found in a continuous log (docs/reference/calibration-file.md):
    the ``log``, its ``sha256``, the ``source`` of the blocks (``detector`` or ``label column``)
    and, where the detector ran, its settings and counts."""

    log: str | None
    sha256: str | None
    source: str | None
    window_samples: int | None = None
    sample_period_s: float | None = None
    threshold: float | None = None
    noise_floor: float | None = None
    min_samples: int | None = None
    trim_samples: int | None = None
    centre: FloatArray | None = None
    blocks_found: int | None = None
    blocks_kept: int | None = None
    gaps: int | None = None

    def typed(self) -> dict[str, object]:
        return {
            "log": self.log,
            "sha256": self.sha256,
            "source": self.source,
            "window_samples": self.window_samples,
            "sample_period_s": self.sample_period_s,
            "threshold": self.threshold,
            "noise_floor": self.noise_floor,
            "min_samples": self.min_samples,
            "trim_samples": self.trim_samples,
            "centre": None if self.centre is None else floats(self.centre),
            "blocks_found": self.blocks_found,
            "blocks_kept": self.blocks_kept,
            "gaps": self.gaps,
        }

    def own_keys(self, typed: Mapping[str, object]) -> tuple[str, ...]:
        """A gyroscope's turns name the log alone; a label column has no detector settings."""
        if self.blocks_found is None:
            keys = ["log", "sha256", "source"]
        elif self.threshold is None:
            detector = ("window_samples", "threshold", "noise_floor", "trim_samples")
            keys = [k for k in typed if k not in detector]
        else:
            keys = list(typed)
        return (*keys, *(k for k in self.extra if k not in typed))


def read_segmentation(raw: Doc) -> SegmentationPart:
    seg = SegmentationPart(
        named(raw.get("log")),
        text(raw.get("sha256")),
        text(raw.get("source")),
        whole(raw.get("window_samples")),
        number(raw.get("sample_period_s")),
        number(raw.get("threshold")),
        number(raw.get("noise_floor")),
        whole(raw.get("min_samples")),
        whole(raw.get("trim_samples")),
        vector(raw.get("centre")),
        whole(raw.get("blocks_found")),
        whole(raw.get("blocks_kept")),
        whole(raw.get("gaps")),
    )
    return as_read(seg, raw)


# -- a gyroscope's turns ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Rotation(Part):
    """``rotations[]``: a hand turn between two still blocks, its angle and its residual."""

    between: str | None
    angle_deg: float | None
    residual_deg: float | None

    def typed(self) -> dict[str, object]:
        return {"between": self.between, "angle_deg": self.angle_deg, "residual_deg": self.residual_deg}


def read_rotation(raw: Doc) -> Rotation:
    rotation = Rotation(text(raw.get("between")), number(raw.get("angle_deg")), number(raw.get("residual_deg")))
    return as_read(rotation, raw)


@dataclass(frozen=True, eq=False)
class Turn(Part):
    """``turns[]``: a known turn (its section ``label``, ``axis`` and ``angle_deg`` given), where
    it is in the log, the rates integrated over it, and the angle measured after calibration."""

    label: str | None
    axis: str | None
    angle_deg: float | None
    rows: tuple[int, int] | None = None
    samples: int | None = None
    duration_s: float | None = None
    integrated: FloatArray | None = None  # (3,) raw units x s
    measured_deg: float | None = None
    residual_deg: float | None = None

    def typed(self) -> dict[str, object]:
        return {
            "label": self.label,
            "axis": self.axis,
            "angle_deg": self.angle_deg,
            "rows": None if self.rows is None else list(self.rows),
            "samples": self.samples,
            "duration_s": self.duration_s,
            "integrated": None if self.integrated is None else floats(self.integrated),
            "measured_deg": self.measured_deg,
            "residual_deg": self.residual_deg,
        }


def read_turn(raw: Doc) -> Turn:
    turn = Turn(
        text(raw.get("label")),
        text(raw.get("axis")),
        number(raw.get("angle_deg")),
        pair_of_ints(raw.get("rows")),
        whole(raw.get("samples")),
        number(raw.get("duration_s")),
        vector(raw.get("integrated")),
        number(raw.get("measured_deg")),
        number(raw.get("residual_deg")),
    )
    return as_read(turn, raw)


@dataclass(frozen=True, eq=False)
class Accelerometer(Part):
    """The accelerometer calibration a gyroscope's g-sensitivity was measured through."""

    columns: tuple[str, ...] | None
    offset: FloatArray | None
    matrix: FloatArray | None

    def typed(self) -> dict[str, object]:
        return {
            "columns": None if self.columns is None else list(self.columns),
            "offset": None if self.offset is None else floats(self.offset),
            "matrix": None if self.matrix is None else rows_of(self.matrix),
        }


@dataclass(frozen=True, eq=False)
class GSensitivity(Part):
    """``g_sensitivity``: a gyroscope's reading per g of gravity along each axis (known turns;
    not applied by apply), and the accelerometer calibration it was measured through."""

    matrix: FloatArray | None  # (3, 3) raw units per g; column j: gravity along +j
    units: str | None
    accelerometer: Accelerometer | None

    def typed(self) -> dict[str, object]:
        return {
            "matrix": None if self.matrix is None else rows_of(self.matrix),
            "units": self.units,
            "accelerometer": None if self.accelerometer is None else self.accelerometer.as_dict(),
        }


def read_g_sensitivity(raw: Doc) -> GSensitivity:
    acc = raw.get("accelerometer")
    accelerometer = None
    if isinstance(acc, dict):
        columns = acc.get("columns")
        names = tuple(columns) if isinstance(columns, list) and all(isinstance(c, str) for c in columns) else None
        accelerometer = as_read(Accelerometer(names, vector(acc.get("offset")), matrix_of(acc.get("matrix"))), acc)
    return as_read(GSensitivity(matrix_of(raw.get("matrix")), text(raw.get("units")), accelerometer), raw)


def read_list(value: object, reader: Callable[[Doc], P]) -> tuple[P, ...] | None:
    """A list of objects, each read by ``reader``; None when it is not a list of objects."""
    if not (isinstance(value, list) and all(isinstance(v, dict) for v in value)):
        return None
    return tuple(reader(v) for v in value)


# -- who, and the verdict ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Unit:
    """Who and what was calibrated (``--serial``, ``--station``, ``--operator``, ``--meta``)."""

    serial: str | None = None
    station: str | None = None
    operator: str | None = None
    meta: Mapping[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        return {"serial": self.serial, "station": self.station, "operator": self.operator, "meta": dict(self.meta)}


def unit_fields(unit: object, path: str) -> None:
    """The unit block's values are text, as ``--serial``, ``--station``, ``--operator`` and
    ``--meta`` write them, so that every export can write them and ``import`` read them back:
    serial, station and operator a string or null, each meta KEY: VALUE a string. A whole number
    is read as its text (a hand-written YAML ``serial: 1234``); a list, an object, true/false, a
    decimal number (YAML's ``1.50`` is 1.5: its text is lost), a control character or text that
    is not Unicode (a lone surrogate, ``"\\ud800"`` in JSON) is an error naming the field."""
    if not isinstance(unit, dict):
        return
    for key in ("serial", "station", "operator"):
        if unit.get(key) is not None:
            _unit_text(unit[key], f"field 'unit.{key}'", path)
    meta = unit.get("meta") or {}
    for key, value in meta.items() if isinstance(meta, dict) else ():
        _unit_text(key, "a key of field 'unit.meta'", path)
        _unit_text(value, f"field 'unit.meta.{str(key)[:40]}'", path)


ONE_LINE = (
    "a serial, station, operator or meta value is one line of text (in YAML, quote one that looks like another kind)"
)


def _unit_text(value: object, name: str, path: str) -> None:
    """``value`` (``name`` says where it is) as text, or an error naming it."""
    if isinstance(value, bool) or not isinstance(value, str | int):
        kind = {bool: "true/false", float: "a decimal number", list: "a list", dict: "an object"}
        what = "null" if value is None else kind.get(type(value), type(value).__name__)
        raise InputError(f"{name} must be text, not {what}", file=path, hint=ONE_LINE)
    text = str(value)
    if bad := control_character(text):
        raise InputError(f"{name} holds a control character: {bad!r}", file=path)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as err:
        half = text[err.start : err.end]
        raise InputError(f"{name} is not Unicode text: {half!r} is half of a surrogate pair", file=path) from None


@dataclass(frozen=True, eq=False)
class Verdict(Part):
    """The judgement against limits: ``passed``, the ``failures`` (the findings of the limits it
    is outside), and the ``limits`` judged by. Always written with pass, failures and limits; a
    file's failures or limits in another form than tumblecal writes are kept as written."""

    passed: bool = True
    failures: tuple[Finding, ...] = ()
    limits: Limits = field(default_factory=Limits)

    def typed(self) -> dict[str, object]:
        return {
            "pass": self.passed,
            "failures": [f.as_dict() for f in self.failures],
            "limits": self.limits.as_dict(),
        }

    def own_keys(self, typed: Mapping[str, object]) -> tuple[str, ...]:
        return ("pass", "failures", "limits")

    @property
    def limit_names(self) -> tuple[str, ...]:
        """The limits judged by, as the file names them, in its order."""
        written = self.as_dict()["limits"]
        return tuple(map(str, written)) if isinstance(written, dict) else ()


def read_verdict(raw: Doc) -> Verdict:
    """A verdict that :func:`calfile.validate` has accepted (pass a bool, failures a list of
    objects with a code, limits an object or absent)."""
    failures = raw["failures"]
    limits = raw.get("limits") or {}
    assert isinstance(failures, list)
    assert isinstance(limits, dict)
    verdict = Verdict(bool(raw["pass"]), tuple(map(read_finding, failures)), read_limits(limits))
    typed = verdict.typed()
    kept = {k: raw[k] for k in ("failures", "limits") if k in raw and not same(typed[k], raw[k])}
    if "limits" not in raw:  # written since (as {}): the file had none
        kept.pop("limits", None)
    return replace(verdict, extra=kept) if kept else verdict


def read_finding(raw: Doc) -> Finding:
    """A failure as written, best effort (another writer's may have only its code)."""
    value, bound = number(raw.get("value")), number(raw.get("bound"))
    file, pose = raw.get("file"), raw.get("pose")
    return Finding(
        str(raw.get("code")),
        str(raw.get("message", "")),
        math.nan if value is None else value,
        math.nan if bound is None else bound,
        file=str(file) if file else None,
        pose=None if pose is None else str(pose),
    )


def read_limits(raw: Doc) -> Limits:
    """The limits a verdict records (Limits.as_dict's form), best effort."""

    def triple(name: str) -> FloatArray | None:
        value = raw.get(name)
        return vector(value) if isinstance(value, list) else None

    nominal_offset, nominal_gain = triple("nominal_offset"), triple("nominal_gain")
    return Limits(
        offset=triple("offset"),
        nominal_offset=np.zeros(3) if nominal_offset is None else nominal_offset,
        gain_error=triple("gain_error"),
        nominal_gain=np.ones(3) if nominal_gain is None else nominal_gain,
        nominal_gain_given=nominal_gain is not None,
        cross_axis=number(raw.get("cross_axis")),
        noise=number(raw.get("noise")),
        residual=number(raw.get("residual")),
        offset_drift=triple("offset_drift"),
        offset_drift_per_degc=triple("offset_drift_per_degc"),
        dip_angle=number(raw.get("dip_angle")),
    )


# -- the thermal block ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Thermal:
    """The temperature drift (docs/commands/thermal.md): ``offset`` (3, order) raw units per °C^k
    and ``gain`` (3, order) relative change per °C^k, k = 1..order, of d = T - ``reference_temperature``
    with T clamped to ``range``; read from the capture's ``column``. ``gain_drift`` says per axis
    how its gain drift is known (separate, folded into the offset drift, unobserved); ``extra``
    keeps the block's other fields (uncertainty, order choice, sweeps) as written."""

    column: str
    reference_temperature: float
    range: tuple[float, float]
    offset: FloatArray
    gain: FloatArray
    gain_drift: tuple[str, ...] = ("separate", "separate", "separate")
    extra: Mapping[str, object] = field(default_factory=dict)

    @property
    def order(self) -> int:
        return int(np.asarray(self.offset).shape[1])

    def drift(self) -> Drift:

        return Drift(self.reference_temperature, self.range[0], self.range[1], self.offset, self.gain)

    def as_dict(self) -> dict[str, object]:
        doc: dict[str, object] = {
            "column": self.column,
            "reference_temperature": self.reference_temperature,
            "range": [float(self.range[0]), float(self.range[1])],
            "order": self.order,
            "offset": rows_of(self.offset),
            "gain": rows_of(self.gain),
            "gain_drift": list(self.gain_drift),
        }
        doc.update(self.extra)
        return doc


THERMAL_KEYS = ("column", "reference_temperature", "range", "order", "offset", "gain", "gain_drift")
GAIN_DRIFT_KINDS = ("separate", "folded", "unobserved")


def thermal_from(value: object, path: str | None) -> Thermal:
    """The ``thermal`` block of a file, validated (every problem names the field)."""
    value, column = _per_row_block(value, "thermal", THERMAL_KEYS, path)
    t_ref = checked_number(value["reference_temperature"], "thermal.reference_temperature", path)
    low, high = _block_range(value["range"], "thermal", "°C", path)
    order = value["order"]
    if isinstance(order, bool) or order not in (1, 2, 3):
        raise InputError("field 'thermal.order' must be 1, 2 or 3", file=path)
    rows = {}
    for key in ("offset", "gain"):
        table = value[key]
        if not (
            isinstance(table, list) and len(table) == 3 and all(isinstance(r, list) and len(r) == order for r in table)
        ):
            raise InputError(f"field 'thermal.{key}' must be 3 lists of {order} numbers (one per axis)", file=path)
        rows[key] = np.array([[checked_number(v, f"thermal.{key}", path) for v in row] for row in table])
    kinds = value["gain_drift"]
    if not (isinstance(kinds, list) and len(kinds) == 3 and all(k in GAIN_DRIFT_KINDS for k in kinds)):
        raise InputError(f"field 'thermal.gain_drift' must be 3 of {', '.join(GAIN_DRIFT_KINDS)}", file=path)
    extra = {k: v for k, v in value.items() if k not in THERMAL_KEYS}
    return Thermal(column, t_ref, (low, high), rows["offset"], rows["gain"], tuple(map(str, kinds)), extra)


def checked_number(value: object, name: str, path: str | None) -> float:
    if not is_number(value):
        raise InputError(f"field {name!r} must be a finite number", file=path)
    return float(value)


# -- the current block ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Current:
    """Current compensation (docs/current.md): ``per_amp`` (3,) the offset's change per ampere,
    raw units per A, of the current read from the capture's ``column``; apply corrects
    ``M (raw - offset - per_amp I)``. ``range`` the lowest and highest current fitted (A);
    ``extra`` keeps the block's other fields (uncertainty, explained share, logs) as written."""

    column: str
    per_amp: FloatArray
    range: tuple[float, float]
    extra: Mapping[str, object] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        doc: dict[str, object] = {
            "column": self.column,
            "per_amp": floats(self.per_amp),
            "range": [float(self.range[0]), float(self.range[1])],
        }
        doc.update(self.extra)
        return doc


CURRENT_KEYS = ("column", "per_amp", "range")


def current_from(value: object, path: str | None) -> Current:
    """The ``current`` block of a file, validated (every problem names the field)."""
    value, column = _per_row_block(value, "current", CURRENT_KEYS, path)
    per_amp = value["per_amp"]
    if not (isinstance(per_amp, list) and len(per_amp) == 3):
        raise InputError("field 'current.per_amp' must be a list of 3 numbers (raw units per ampere)", file=path)
    low, high = _block_range(value["range"], "current", "amperes", path)
    extra = {k: v for k, v in value.items() if k not in CURRENT_KEYS}
    return Current(column, np.array([checked_number(v, "current.per_amp", path) for v in per_amp]), (low, high), extra)


def _per_row_block(value: object, name: str, keys: tuple[str, ...], path: str | None) -> tuple[dict[str, object], str]:
    """A block that corrects each row at a column's value (``thermal``, ``current``): an object
    with every one of ``keys``, and the name of its column."""
    if not isinstance(value, dict):
        raise InputError(f"field {name!r} must be an object ({', '.join(keys[:3])}, ...)", file=path)
    for key in keys:
        if key not in value:
            raise InputError(f"field {name!r} has no {key!r}", file=path)
    column = value["column"]
    if not isinstance(column, str) or not column:
        raise InputError(f"field '{name}.column' must be a column name", file=path)
    return value, column


def _block_range(span: object, name: str, unit: str, path: str | None) -> tuple[float, float]:
    """A per-row block's ``range``: [lowest, highest] of its column, in ``unit``."""
    if not (isinstance(span, list) and len(span) == 2):
        raise InputError(f"field '{name}.range' must be [lowest, highest] {unit}", file=path)
    low, high = (checked_number(v, f"{name}.range", path) for v in span)
    if low >= high:
        raise InputError(f"field '{name}.range' [{low:g}, {high:g}] must be [lowest, highest] {unit}", file=path)
    return low, high
