"""The numeric core: pose statistics, the tumble solvers, and apply. numpy only.

Measurement model (docs/reference/model.md)::

    raw = A @ v + b + noise        v: true stimulus in the sensor frame, |v| = reference
    corrected = M @ (raw - b)      M = inv(A)

``b`` (offset) is in raw units; ``A`` has the gains on its diagonal. Every formula cites its
source by author and year, listed in docs/sources.md: Vitali 2018 is ST's design tip "1-point /
3-point tumble sensor calibration", cited below by its equations and sections.

Nothing here reads files or talks to a terminal; errors carry no file name unless the caller
passes one in ``names``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.quantities import REFERENCE_UNITS
from tumblecal_cli.core.running import Summary
from tumblecal_cli.errors import CaptureRejected, InputError, said

#: Face name -> unit vector of gravity's reaction in the sensor frame ("+x": x points up).
FACES: dict[str, tuple[float, float, float]] = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}
#: Script-friendly aliases (docs/reference/model.md): xp = +x, xn = -x, ...
FACE_ALIASES = {f"{axis}{s}": f"{sign}{axis}" for axis in "xyz" for s, sign in (("p", "+"), ("n", "-"))}

#: The sensors tumblecal calibrates, in the order reports list them.
SENSORS = catalog.SENSORS  # the sensors there are (core.catalog: numpy-free, for the command line)

#: A 1-pose magnitude further than this fraction from ``reference`` is a units mistake.
UNITS_TOLERANCE = 0.25


def parse_face(text: str) -> str:
    """Canonical face name (``+x`` ... ``-z``) for a face or alias; ValueError otherwise."""
    key = text.strip().lower()
    key = FACE_ALIASES.get(key, key)
    if key not in FACES:
        raise ValueError(f"unknown face {text!r}: use one of +x -x +y -y +z -z (or xp xn yp yn zp zn)")
    return key


_NAMED = re.compile(r"([+-])([xyz])|([xyz])(?:[_-]?(p|n|pos|neg|plus|minus))?")


def face_of_name(text: str) -> str | None:
    """The face a file name's stem or a column header names, or None: ``x`` (+x), ``+x``,
    ``-x``, ``xp``/``xn``, ``x_p``/``x_n``, ``xplus``/``xminus``, ``x_pos``/``x_neg`` (any case)."""
    match = _NAMED.fullmatch(text.strip().lower())
    if match is None:
        return None
    sign, axis, bare, suffix = match.groups()
    if axis:
        return sign + axis
    return ("-" if suffix in ("n", "neg", "minus") else "+") + bare


def parse_label(text: str) -> str:
    """Canonical pose label: a face (``+x`` ... ``-z``, or an alias), or an expected direction
    written as three comma-separated numbers, normalised to unit length (``0.707,0,0.707`` ->
    ``0.707107,0,0.707107``). ValueError otherwise."""
    if "," not in text:
        return parse_face(text)
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    norm = math.sqrt(sum(v * v for v in values)) if len(values) == 3 else 0.0
    if len(values) != 3 or not math.isfinite(norm) or norm == 0.0:
        raise ValueError(f"pose label {text!r} is neither a face nor a direction X,Y,Z (three numbers, not all 0)")
    unit = [v / norm for v in values]
    for face, vec in FACES.items():  # 0,0,1 is the +z face
        if all(abs(u - f) < 1e-12 for u, f in zip(unit, vec, strict=True)):
            return face
    return ",".join(f"{u:.6g}" for u in unit)


def direction(label: str) -> FloatArray:
    """Unit vector of a canonical pose label (see :func:`parse_label`)."""
    if label in FACES:
        return np.asarray(FACES[label], dtype=np.float64)
    v = np.array([float(x) for x in label.split(",")])
    result: FloatArray = v / np.linalg.norm(v)
    return result


def angle_deg(vector: FloatArray, label: str) -> float:
    """Degrees between a (non-zero) ``vector`` and a pose label's direction: how far a pose's
    centred mean is from its face."""
    unit = vector / float(np.linalg.norm(vector))
    return math.degrees(math.acos(min(1.0, max(-1.0, float(unit @ direction(label))))))


@dataclass(frozen=True)
class PoseStats:
    """One static pose averaged to a triplet."""

    mean: FloatArray  # (3,) raw units
    std: FloatArray  # (3,) sample standard deviation (ddof=1); 0.0 when samples == 1
    samples: int

    @property
    def stderr(self) -> FloatArray:
        """Standard error of each mean, std / sqrt(n)."""
        return self.std / math.sqrt(self.samples)


def pose_stats(samples: FloatArray | Summary) -> PoseStats:
    """Mean, standard deviation and count of an (n, 3) block of readings (n >= 1), or of a long
    pose's running sums (core.running)."""
    if isinstance(samples, Summary):
        if not samples.count:
            raise InputError("no samples in this pose")
        return PoseStats(np.sum(samples.sums, axis=0) / samples.count, samples.std, samples.count)
    n = int(samples.shape[0])
    if n == 0:
        raise InputError("no samples in this pose")
    mean = samples.mean(axis=0)
    if n == 1:
        return PoseStats(mean=mean, std=np.zeros(3), samples=n)
    # numpy's std(ddof=1), a chunk at a time: no temporary as large as the capture (the same
    # digits up to CHUNK readings, the last digit or so beyond)
    m2 = sum((np.square(c - mean).sum(axis=0) for c in chunks(samples)), np.zeros(3))
    return PoseStats(mean=mean, std=np.sqrt(m2 / (n - 1)), samples=n)


#: Readings a statistic over a whole capture works through at a time: its temporaries stay
#: this small however long the capture.
CHUNK = 1 << 16


def chunks(values: FloatArray) -> Iterator[FloatArray]:
    """``values`` (n, ...) in consecutive slices of at most CHUNK rows (views, not copies)."""
    for start in range(0, len(values), CHUNK):
        yield values[start : start + CHUNK]


@dataclass(frozen=True)
class Solution:
    """What a solver estimates: the offset, the correction matrix, and their 1-sigma errors."""

    method: str
    offset: FloatArray  # (3,) raw units, b
    matrix: FloatArray  # (3, 3) M = inv(A): corrected = M @ (raw - offset)
    offset_se: FloatArray  # (3,) standard error of offset from sample noise
    gain_se: FloatArray  # (3,) standard error of gain (zeros when the method fixes the gains)

    @property
    def gain(self) -> FloatArray:
        """Diagonal of A = inv(M), raw units per output unit."""
        return np.diag(np.linalg.inv(self.matrix)).copy()


@dataclass(frozen=True)
class Reach:
    """How near a capture turned through many orientations comes to each direction: ``faces``,
    the angle (degrees) from each face to its nearest sample; ``gaps``, the directions of
    ``solvers.coverage`` with no sample within COVERAGE_CAP_DEG and their nearest angle, farthest
    first; for min/max, ``bias``, how far the faces its samples do not reach move each offset
    (signed, raw units: ``solvers.minmax_bias``), and ``radius``, the field's radius along each axis."""

    faces: dict[str, float]
    gaps: tuple[tuple[str, float], ...] = ()
    bias: FloatArray | None = None
    radius: FloatArray | None = None


def solve_one_pose(pose: PoseStats, up: str, reference: float) -> Solution:
    """1-pose tumble: offsets only, gains fixed at 1 (Vitali 2018, "1 姿勢タンブル較正").

    With true stimulus ``v = reference * FACES[up]``, Vitali 2018 eqs. 1-3 (``AccX = 0 + Xofs`` ...
    ``AccZ = 1 + Zofs``) give ``offset = mean - v``. The data must already be in the units of
    ``reference``: there is no gain to absorb a unit change.
    """
    v = reference * np.asarray(FACES[up])
    offset = pose.mean - v  # Vitali 2018 eqs. 1-3
    return Solution(
        method="one-pose",
        offset=offset,
        matrix=np.eye(3),
        offset_se=pose.stderr,  # offset is one mean shifted by a constant
        gain_se=np.zeros(3),
    )


def solve_three_pose(
    poses: Sequence[PoseStats],
    reference: float,
    names: Sequence[str] = ("+x", "+y", "+z"),
    faces: Sequence[str] = ("+x", "+y", "+z"),
) -> Solution:
    """3-pose tumble: per-axis offset and gain from one pose per axis (Vitali 2018, "3 姿勢").

    With ``m[k]`` the mean of pose k (k = 0, 1, 2 for +x, +y, +z), Vitali 2018 averages, for each
    axis, the two poses where that axis is horizontal::

        Xofs = (AccX2 + AccX3) / 2, Yofs = (AccY1 + AccY3) / 2, Zofs = (AccZ1 + AccZ2) / 2
        Xgain = AccX1 - Xofs, ...      (per 1 g; here divided by ``reference``)

    and corrects by subtracting the offset and dividing by the gain, so ``M = diag(1 / gain)``.
    The offsets come from horizontal readings, so they shift to first order with fixture tilt
    (Vitali 2018, notes; docs/reference/model.md).

    ``faces``: the face of each pose, one per axis in the order x, y, z, of either sign. On a
    ``-`` face the axis reads ``offset - gain·reference`` (the model ``raw = A v + b`` with
    ``v = -reference·e_i``), so its gain is the same difference with its sign turned; the offsets,
    and every 1-sigma, are those of the ``+`` faces.
    """
    if reference <= 0:
        raise InputError(said("three.reference"))
    means = np.array([p.mean for p in poses])  # means[k, i]: pose k, axis i
    se = np.array([p.stderr for p in poses])
    offset = np.empty(3)
    offset_se = np.empty(3)
    gain = np.empty(3)
    gain_se = np.empty(3)
    for axis in range(3):
        horizontal = [k for k in range(3) if k != axis]
        # Vitali 2018: Xofs = (AccX2 + AccX3) / 2, and cyclically for y and z
        offset[axis] = means[horizontal, axis].mean()
        offset_se[axis] = 0.5 * math.hypot(*se[horizontal, axis])
        # Vitali 2018: Xgain = AccX1 - Xofs, scaled to raw units per output unit
        gain[axis] = (means[axis, axis] - offset[axis]) / reference
        if faces[axis][0] == "-":  # the -x pose reads Xofs - Xgain
            gain[axis] = -gain[axis]
        gain_se[axis] = math.sqrt(se[axis, axis] ** 2 + offset_se[axis] ** 2) / reference
    for axis, g in enumerate(gain):
        if not g:  # a negative gain is judged by the gate (pose.upside_down); zero has no inverse
            ax = "xyz"[axis]
            raise CaptureRejected(
                f"the {faces[axis]} pose reads the same on {ax} as the poses where {ax} is horizontal "
                f"(mean {_fmt(means[axis])}): its gain on {ax} cannot be determined",
                file=names[axis],
                hint="give the files in the order +x +y +z, each with that axis pointing up",
                code="pose.upside_down",
            )
    return Solution(
        method="three-pose",
        offset=offset,
        matrix=np.diag(1.0 / gain),  # Vitali 2018: subtract the offset, multiply by 1 / gain
        offset_se=offset_se,
        gain_se=gain_se,
    )


def tilt_sensitivity(
    method: str, gain: FloatArray, reference: float, faces: Sequence[str], tolerance_deg: float
) -> tuple[FloatArray, FloatArray]:
    """Worst-case shift of (offset, gain) if every pose is off its face by ``tolerance_deg``.

    Vitali 2018 (notes on 1-/3-point tumble) and Ding and Uchida 2012 (patent CN102313822, the
    vertical axis's gravity term is a cosine): tilting a pose by θ moves a
    reading on a horizontal axis by ``gain·reference·sin θ`` (first order: 1° -> 17 mg) and the
    vertical one by ``gain·reference·(1 - cos θ)`` (second order: 1° -> 0.15 mg).

    - one-pose: ``offset = mean - v`` (gains fixed at 1, raw units = reference units), so each
      horizontal offset moves by ``reference·sin θ``, the vertical one by ``reference·(1 - cos θ)``.
    - three-pose: each offset is the mean of two horizontal readings, so it moves by up to
      ``|g|·reference·sin θ`` (both poses tilted the same way); each gain is a vertical reading
      minus that offset, over ``reference``: ``|g|·(sin θ + 1 - cos θ)``.
    """
    theta = math.radians(tolerance_deg)
    horizontal, vertical = math.sin(theta), 1.0 - math.cos(theta)
    g = np.abs(gain)
    if method == "one-pose":
        up = np.abs(np.asarray(FACES[faces[0]]))
        return reference * np.where(up > 0, vertical, horizontal), np.zeros(3)
    if method == "three-pose":
        # the solved gain is itself off by up to (sin θ + 1 - cos θ) of the true one: bound the true
        # gain from it so that the shift stays a bound in the worst case
        shift = horizontal + vertical
        g = g / (1.0 - shift)
        return g * reference * horizontal, g * shift
    raise ValueError(f"no tilt model for method {method!r}")


#: The largest reading tumblecal computes with: squares and sums of squares stay finite.
MAX_READING = 1e150


def in_range(values: FloatArray | Summary, name: str) -> None:
    """Readings beyond MAX_READING (1e200 in a capture) overflow the statistics: an input error
    naming ``name``. NaN (an empty reading) is left to the caller."""
    largest = values.largest if isinstance(values, Summary) else 0.0  # the largest |reading| not NaN
    for c in () if isinstance(values, Summary) else chunks(values):  # a chunk at a time
        size = np.abs(c[~np.isnan(c)])
        largest = max(largest, float(size.max())) if size.size else largest
    if not largest <= MAX_READING:
        raise InputError(
            f"a reading of {largest:.3g} is beyond what tumblecal computes with (|reading| <= {MAX_READING:g})",
            file=name,
            hint="are these the sensor's columns, in its units?",
        )


def units_mistake(mean: FloatArray, reference: float) -> float | None:
    """The reference the data suggests when |mean| is far from ``reference``, else None.

    Only meaningful for solvers without gains (1-pose), where the output keeps the raw units
    (docs/reference/model.md). Offsets are a few percent of full scale, so a magnitude more than
    ``UNITS_TOLERANCE`` away from ``reference`` means the data is in other units.
    """
    magnitude = float(np.linalg.norm(mean))
    if reference <= 0 or abs(magnitude - reference) <= UNITS_TOLERANCE * reference:
        return None  # a zero reference (gyroscope at rest) has no magnitude to compare
    return suggest_reference(magnitude)


def suggest_reference(magnitude: float) -> float:
    """A conventional reference near ``magnitude``: 1 (g), 9.80665 (m/s^2), 1000 (mg) or 2^k counts."""
    candidates = [*REFERENCE_UNITS] + [float(2**k) for k in range(4, 17)]
    best = min(candidates, key=lambda c: abs(math.log(c / magnitude)) if magnitude > 0 else math.inf)
    if magnitude > 0 and abs(best - magnitude) <= 0.1 * best:
        return best
    return float(f"{magnitude:.3g}")


def apply(raw: FloatArray, offset: FloatArray, matrix: FloatArray) -> FloatArray:
    """Correct (n, 3) raw readings: ``corrected = M @ (raw - offset)`` for each row.

    Written as sums of products over contiguous columns, not ``@``: a (n, 3) @ (3, 3) product
    goes to OpenBLAS, whose spinning threads made ``tumblecal apply`` 1.5x slower on 2 cores.
    Each value is ``(d0 * M[i, 0] + d1 * M[i, 1]) + d2 * M[i, 2]``, in that order.
    """
    raw = np.asarray(raw, dtype=np.float64)
    out: FloatArray = np.empty(raw.shape)
    with np.errstate(invalid="ignore", over="ignore"):  # nan and inf readings pass through, quietly
        columns = [raw[:, j] - offset[j] for j in range(3)]  # d = raw - offset, a column at a time
        for i in range(3):
            total = columns[0] * matrix[i, 0]
            total += columns[1] * matrix[i, 1]
            total += columns[2] * matrix[i, 2]
            out[:, i] = total
        if not all(np.isfinite(c).all() for c in columns):  # inf x 0 is nan: an axis M does not
            d = np.column_stack(columns)  # mix in must not spoil the others
            odd = ~np.isfinite(d).all(axis=1)
            rows = d[odd]
            fixed = np.zeros_like(rows)
            for i, j in zip(*np.nonzero(matrix), strict=True):
                fixed[:, i] += rows[:, j] * matrix[i, j]
            out[odd] = fixed
    return out


def _fmt(v: FloatArray) -> str:
    return ", ".join(f"{x:.4g}" for x in v)
