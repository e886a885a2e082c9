"""The production-test gate: quality checks on each pose, limits, and the verdict. numpy only.

Part of the core layer (docs/development.md): pure functions on numbers, no files, no terminal.

- A **rejection** (exit 3) says the capture cannot be trusted: a pose moved, is not the pose it
  claims, clipped, is too short, or solves to a gain that is not positive.
- A **failure** (exit 1) says the calibration was computed and the unit is outside its limits.

Each has a stable ``code`` scripts can branch on (``pose.moved``, ``limit.offset.x`` ...). A check
whose value comes within ``1 - NARROW`` of its bound without crossing it passes with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.drift import Drift, extremes
from tumblecal_cli.core.model import FACES, PoseStats, Reach, Solution, angle_deg, chunks, direction, suggest_reference
from tumblecal_cli.core.quantities import REFERENCE_UNITS, STANDARD_GRAVITY
from tumblecal_cli.core.running import Summary
from tumblecal_cli.errors import InputError, said

#: The quality checks there are (core.catalog): each pose's, judged in this order, and the fit's.
CHECKS, FIT_CHECKS = catalog.CHECKS, catalog.FIT_CHECKS
#: The coverage check: a capture turned through many orientations must come within this angle
#: of every face. Past 45° (where solvers.coverage stops counting a face as covered) the ellipsoid
#: fit extrapolates: in a 50 µT field disturbed by 1 µT that changes within a second, its
#: correction along a face 57° from the nearest sample is off twice as much as along a reached
#: face (tests/test_mag_coverage.py). Min/max's offset is off by R(1 − cos θ)/2
#: (solvers.minmax_bias): 3 % of the field at 20°.
ELLIPSOID_REACH_DEG = 45.0
MINMAX_REACH_DEG = 20.0
#: A value past this fraction of its bound (still inside it) is a narrow pass: a warning.
NARROW = 0.8
#: With ``--full-scale V``, a sample at or above this fraction of V counts as clipped.
CLIP_FRACTION = 0.98
#: What a pose not on its face suggests when each pose's face came from its file's name.
NAMED_HINT = (
    "capture each pose with the face its file's name gives pointing up (xp.csv: +x), or label the files (+x=FILE)"
)
LABELLED_HINT = "label each file with the face that pointed up while it was captured (+x=FILE: its x axis up)"
AXES = "xyz"


@dataclass(frozen=True)
class Finding:
    """One rejection, failure or warning: a stable code, the measured value and its bound."""

    code: str  # "pose.moved", "limit.offset.x", ...
    message: str  # one line for people (without the file name)
    value: float
    bound: float
    file: str | None = None  # the pose file it is about, if any
    pose: str | None = None  # that pose's face
    hint: str | None = None  # what to do, when it differs from the check's usual advice

    def render(self) -> str:
        return f"{self.file}: {self.message}" if self.file else self.message

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"code": self.code, "value": _num(self.value), "bound": _num(self.bound)}
        if self.file is not None:
            out["pose"] = self.pose
            out["file"] = self.file
        out["message"] = self.message
        return out


@dataclass(frozen=True)
class PoseCheck:
    """What the gate measured on one pose, before and after calibration."""

    file: str
    face: str | None  # the pose's label: a face, a direction "x,y,z", or None (orientation unknown)
    stats: PoseStats
    angle_deg: float | None  # between the centred mean and the declared face; None: no direction
    looks_like: str | None  # the nearest face to the centred mean
    clipped: int  # samples at the clip level on any axis
    peak_fraction: float | None  # largest |sample| over the clip level (None: no known level)
    drift: FloatArray  # (3,) raw units: mean of the last third minus mean of the first third
    direction: FloatArray  # (3,) centred mean, normalised (zeros when undefined)


Rails = tuple[float, float, float]  # (low rail, high rail, middle) of an integer type


@dataclass(frozen=True)
class Options:
    """The checks' settings (the solve options of the same names)."""

    noise_bound: float | None = None  # output units; None: the moved check is off
    noise_rule: str = ""  # how --max-noise made the bound, for the message: "0.02 × reference 9.81"
    max_tilt_deg: float = 25.0
    nominal_offset: FloatArray = field(default_factory=lambda: np.zeros(3))  # raw units
    full_scale: float | None = None  # raw units; None: integer-type limits
    min_samples: int = 10
    skip: frozenset[str] = frozenset()  # names from CHECKS
    rails: Rails | None = None  # the integer type's limits (integer_rails); None: no known limit
    faces_by_name: bool = False  # the faces came from the files' names, not their order: no order to blame
    faces_labelled: bool = False  # ... or from the labels given (+x=FILE): the labels to blame


def measure(file: str, face: str | None, values: FloatArray | Summary, stats: PoseStats, options: Options) -> PoseCheck:
    """The per-pose measurements the checks need (the direction comes later, from orient());
    of a long pose, from its running sums (core.running)."""
    if isinstance(values, Summary):
        clipped, peak = _clipping(values, options.full_scale, options.rails)
        return PoseCheck(file, face, stats, None, None, clipped, peak, values.drift(), np.zeros(3))
    n = values.shape[0]
    third = n // 3
    drift = values[-third:].mean(axis=0) - values[:third].mean(axis=0) if third else np.zeros(3)
    clipped, peak = _clipping(values, options.full_scale, options.rails)
    return PoseCheck(file, face, stats, None, None, clipped, peak, drift, np.zeros(3))


def orient(poses: Sequence[PoseCheck], nominal_offset: FloatArray, max_tilt_deg: float = 25.0) -> list[PoseCheck]:
    """Give each pose its direction, angle from its face and nearest face.

    The centre removed from each mean is ``nominal_offset``, except on an axis where both of its
    faces were captured and agree: there the midpoint of the two (docs/reference/model.md: opposite
    faces cancel the offset). They agree when their difference points along that axis (either
    way: a swapped pair has the same midpoint) within ``max_tilt_deg``; a pair that does not
    (one of them is some other pose) would move the
    centre and make every pose read wrong, so that axis keeps the nominal offset and only the
    wrong pose is judged so.
    """
    centre = np.array(nominal_offset, dtype=np.float64)
    faces = {p.face: p for p in poses}
    for i, axis in enumerate(AXES):
        if f"+{axis}" in faces and f"-{axis}" in faces:
            plus, minus = faces[f"+{axis}"].stats.mean, faces[f"-{axis}"].stats.mean
            span = plus - minus
            length = float(np.linalg.norm(span))
            if length > 0 and abs(span[i]) / length >= math.cos(math.radians(max_tilt_deg)):  # swapped: same midpoint
                centre[i] = 0.5 * (plus[i] + minus[i])
    out = []
    for p in poses:
        d = p.stats.mean - centre
        norm = float(np.linalg.norm(d))
        if p.face is None or norm == 0.0 or not math.isfinite(norm):
            out.append(p)
            continue
        unit = d / norm
        angle = angle_deg(d, p.face)
        nearest = max(FACES, key=lambda f: float(unit @ np.asarray(FACES[f])))
        out.append(replace(p, angle_deg=angle, looks_like=nearest, direction=unit))
    return out


def check(poses: Sequence[PoseCheck], solution: Solution, options: Options) -> tuple[list[Finding], list[Finding]]:
    """(rejections, warnings) of the quality checks on every pose, in the order of CHECKS.

    A pose without a direction (not oriented: a gyroscope at rest) is not judged on orientation.
    """
    rejected: list[Finding] = []
    warned: list[Finding] = []
    declared = [p.face for p in poses]
    misread = False  # a pose is not what it claims: it spoils the solution moved and upside_down judge through
    for check_name in CHECKS:
        misread = misread or any(r.code in ("pose.orientation", "pose.upside_down") for r in rejected)
        if check_name in options.skip or (misread and check_name in ("moved", "upside_down")):
            continue
        for p in poses:
            if any(r.file == p.file for r in rejected):
                continue  # one reason per pose: the first, in the order of CHECKS
            judged = JUDGES[check_name](p, declared, solution, options)
            if judged is None:
                continue
            finding, fails, narrow, close = judged
            if fails:
                rejected.append(finding)
            elif narrow:  # passed narrowly: a warning with the message ``close``
                warned.append(replace(finding, message=close, hint=None))
    return rejected, warned


#: A pose's finding under one check, whether it fails, whether it passed narrowly, and the
#: warning's message then; None where the check does not apply to the pose.
Judged = tuple[Finding, bool, bool, str] | None


def _short(p: PoseCheck, declared: list[str | None], solution: Solution, options: Options) -> Judged:
    n, least = p.stats.samples, options.min_samples
    fewer, close = said("pose.short", least=least), said("pose.short.close", least=least)
    finding = Finding("pose.short", f"{_samples(n)}, {fewer}", n, least, file=p.file, pose=p.face)
    return finding, n < least, least > 1 and n < least / NARROW, f"only {_samples(n)}, {close}"


def _saturated(p: PoseCheck, declared: list[str | None], solution: Solution, options: Options) -> Judged:
    if p.peak_fraction is None:
        return None
    level = (
        str(said("pose.saturated.level", fraction=CLIP_FRACTION, full_scale=options.full_scale))
        if options.full_scale
        else "the limit of its integer type"
    )
    message = f"{_samples(p.clipped)} clipped at {level} (peak {p.peak_fraction:.0%} of that)"
    finding = Finding("pose.saturated", message, p.clipped, 0, file=p.file, pose=p.face)
    close = f"peaks at {p.peak_fraction:.0%} of {level}, close to clipping"
    return finding, p.clipped > 0, p.peak_fraction > NARROW, close


def _oriented(p: PoseCheck, declared: list[str | None], solution: Solution, options: Options) -> Judged:
    if p.angle_deg is None:
        return None
    tilt = options.max_tilt_deg
    finding = _orientation(p, declared, tilt, by_name=options.faces_by_name, labelled=options.faces_labelled)
    close = f"{p.angle_deg:.1f}° from {p.face}, {said('pose.orientation.close', tilt=tilt)}"
    return finding, p.angle_deg > tilt, p.angle_deg > NARROW * tilt, close


def _moved(p: PoseCheck, declared: list[str | None], solution: Solution, options: Options) -> Judged:
    if options.noise_bound is None or catalog.turned(solution.method):
        return None
    # standard deviation and drift in output units, through the solved matrix
    std = output_std(solution.matrix, p.stats.std)
    drift = np.abs(solution.matrix) @ np.abs(p.drift)
    worst_std, worst_drift = int(np.argmax(std)), int(np.argmax(drift))
    bound = options.noise_bound
    rule = f" ({said('pose.moved.rule', rule=options.noise_rule) if options.noise_rule else said('pose.moved')})"
    if drift[worst_drift] > std[worst_std]:
        what = f"drifts by {drift[worst_drift]:.3g} on {AXES[worst_drift]} (first vs last third)"
        value = float(drift[worst_drift])
    else:
        what = f"standard deviation {std[worst_std]:.3g} on {AXES[worst_std]}"
        value = float(std[worst_std])
    finding = Finding(
        "pose.moved", f"{what}, above {bound:.3g}{rule}: the unit moved", value, bound, file=p.file, pose=p.face
    )
    return finding, not value <= bound, value > NARROW * bound, f"{what}, close to {bound:.3g}{rule}"  # NaN fails


def _upside_down(p: PoseCheck, declared: list[str | None], solution: Solution, options: Options) -> Judged:
    if catalog.fixes_gains(solution.method) or p.face not in FACES:
        return None
    assert p.face is not None
    axis = "xyz".index(p.face[1])
    alone = f"+{p.face[1]}" not in declared  # a - face without its + face (three-pose of mixed signs)
    if not ((p.face[0] == "+" or alone) and solution.gain[axis] <= 0):
        return None
    by_name, labelled = options.faces_by_name, options.faces_labelled
    cause = "its file misnamed" if by_name else "its label wrong" if labelled else "the files out of order"
    way = "up" if p.face[0] == "+" else "down"
    finding = Finding(
        "pose.upside_down",
        f"gain {solution.gain[axis]:.4g} on {p.face[1]} (mean {_vec(p.stats.mean)}): "
        f"its {p.face[1]} axis was not pointing {way} (upside down, or {cause})",
        float(solution.gain[axis]),
        0.0,
        hint=NAMED_HINT if by_name else LABELLED_HINT if labelled else None,
        file=p.file,
        pose=p.face,
    )
    return finding, True, False, ""


#: Each check of CHECKS and how it judges one pose (tests/test_gate.py holds the two to each other).
JUDGES = {
    "short": _short,
    "saturated": _saturated,
    "orientation": _oriented,
    "moved": _moved,
    "upside_down": _upside_down,
}


def beyond(faces: dict[str, float], within_deg: float) -> str:
    """The faces farther than ``within_deg`` from every sample, for a message:
    "nothing within 45° of +z (nearest 57°) or of -x (nearest 50°)"."""
    far = sorted(((f, a) for f, a in faces.items() if a > within_deg), key=lambda g: -g[1])
    each = " or of ".join(f"{f} (nearest {a:.0f}°)" for f, a in far)
    return f"nothing within {within_deg:.0f}° of {each}"


def turn_hint(faces: dict[str, float], within_deg: float) -> str:
    """What to do about the faces of a turned capture that no sample comes within ``within_deg`` of."""
    far = [f for f, a in sorted(faces.items(), key=lambda g: -g[1]) if a > within_deg]
    which = f"its {far[0]} axis points" if len(far) == 1 else f"each of its {' and '.join(far)} axes has pointed"
    return f"turn the unit until {which} along the field (north, and down in the northern hemisphere) while capturing"


def check_coverage(
    reach: Reach | None, method: str, cover: float | None, skip: frozenset[str], file: str | None = None
) -> tuple[list[Finding], list[Finding]]:
    """(rejections, warnings) of the coverage check on a turned capture (``reach`` of the
    ellipsoid or 3-D min/max fit; None for the other methods): a face no sample comes within
    ELLIPSOID_REACH_DEG (min/max: MINMAX_REACH_DEG) of, said with min/max's bias on its axis.
    With the check off (``"coverage"`` in ``skip``) it is a warning instead."""
    if reach is None:
        return [], []
    within = MINMAX_REACH_DEG if method == "minmax" else ELLIPSOID_REACH_DEG
    far = {f: a for f, a in reach.faces.items() if a > within}
    if not far:
        return [], []
    what = f"coverage {cover:.0%}: " if cover is not None else ""
    what += beyond(reach.faces, within)
    ways = [turn_hint(reach.faces, within)]
    if method == "minmax":
        axes = sorted({f[1] for f in far})
        what += ", so " + "; ".join(_minmax_shift(reach, axis, within) for axis in axes)
        if max(far.values()) <= ELLIPSOID_REACH_DEG:
            ways.append(str(said("poses.coverage.minmax", reach=ELLIPSOID_REACH_DEG)))
    else:
        what += ": the ellipsoid fit extrapolates there"
    hint = f"{', '.join(ways)}, or {said('poses.coverage.keep')}"
    finding = Finding("poses.coverage", what, max(far.values()), within, file=file, hint=hint)
    return ([], [finding]) if "coverage" in skip else ([finding], [])


def _minmax_shift(reach: Reach, axis: str, within: float) -> str:
    """How far min/max's offset on ``axis`` is moved by the faces of that axis its samples miss."""
    assert reach.bias is not None
    assert reach.radius is not None
    i = AXES.index(axis)
    bias, radius = float(reach.bias[i]), float(reach.radius[i])
    plus, minus = reach.faces[f"+{axis}"], reach.faces[f"-{axis}"]
    if min(plus, minus) <= within:  # one side missed: R (cos θ+ - cos θ-) / 2 is about this
        why = f"R(1 − cos θ)/2 with R {radius:.3g}, θ {max(plus, minus):.0f}°"
    else:
        why = f"R(cos θ+ − cos θ−)/2 with R {radius:.3g}, θ+ {plus:.0f}°, θ− {minus:.0f}°"
    return f"min/max's {axis} offset may be about {abs(bias):.3g} too {'low' if bias < 0 else 'high'} ({why})"


def _orientation(
    p: PoseCheck, declared: Sequence[str | None], max_tilt: float, *, by_name: bool = False, labelled: bool = False
) -> Finding:
    where = {"file": p.file, "pose": p.face}
    assert p.angle_deg is not None
    assert p.face is not None
    mean = _vec(p.stats.mean)
    if p.face in FACES and p.looks_like != p.face:
        text = f"declared {p.face} but reads like {p.looks_like} (mean {mean})"
        if p.looks_like in declared and by_name:  # no order to blame: the names gave the faces
            text += f"; its file's name gives {p.face}: was it captured on another face, or misnamed?"
            return Finding("pose.orientation", text, p.angle_deg, max_tilt, hint=NAMED_HINT, **where)
        if p.looks_like in declared and labelled:  # the user's labels gave the faces
            text += f"; it is labelled {p.face}: was it captured on another face, or labelled wrong?"
            return Finding("pose.orientation", text, p.angle_deg, max_tilt, hint=LABELLED_HINT, **where)
        if p.looks_like in declared:
            order = " ".join(f[1] if f[0] == "+" else f for f in map(str, declared))
            text += f"; were the files given in the order {order}?"
            hint = f"give the pose files in the order {' '.join(map(str, declared))}"
            return Finding("pose.orientation", text, p.angle_deg, max_tilt, hint=hint, **where)
        elif p.looks_like == ("-" if p.face[0] == "+" else "+") + p.face[1]:
            text += ": upside down"
            way = "up" if p.face[0] == "+" else "down"
            hint = (
                f"turn the unit over so that its {p.face[1]} axis points {way} (a sensor that reads -1 g "
                "on the axis pointing up is declared as the opposite face)"
            )
            return Finding("pose.upside_down", text, p.angle_deg, max_tilt, hint=hint, **where)
    else:
        more = said("pose.orientation.tilt", tilt=max_tilt)
        text = f"declared {p.face} but is {p.angle_deg:.1f}° from it (mean {mean}), {more}"
    # No axis near zero: a common offset. Uncentred unsigned counts often still lean towards the
    # declared face (+x reads 49352, 32618, 33018: 43° off), so this is said in either case.
    if float(np.min(np.abs(p.direction))) > 0.3:
        text += f"; {said('pose.orientation.centre')}"
        hint = str(said("pose.orientation.centre.hint"))
        return Finding("pose.orientation", text, p.angle_deg, max_tilt, hint=hint, **where)
    return Finding("pose.orientation", text, p.angle_deg, max_tilt, **where)


def integer_rails(captures: Sequence[FloatArray | Summary]) -> Rails | None:
    """The limits of the 16-bit integer type that holds every sample of a unit's captures:
    signed (-32768, 32767) unless some value needs the unsigned range (0, 65535). Judged over
    all the captures together, so a pose of an unsigned ADC whose values all happen to sit
    below 32768 is not taken for a signed one at its rail. None: not integers, or no 16-bit
    type holds them all (no known limit)."""
    summed = [c for c in captures if isinstance(c, Summary) and c.count]
    arrays = [c for c in captures if not isinstance(c, Summary) and c.size]
    if not arrays and not summed:
        return None
    lo = min([float(c.min()) for c in arrays] + [c.low for c in summed])
    hi = max([float(c.max()) for c in arrays] + [c.high for c in summed])
    if lo < -32768 or hi > 65535 or (lo < 0 and hi > 32767):
        return None
    if not all(c.whole for c in summed):
        return None
    if not all(np.array_equal(part, np.round(part)) for c in arrays for part in chunks(c)):
        return None
    if hi > 32767:  # unsigned: 0 and 65535 are the rails, the middle is 32768
        return 0.0, 65535.0, 32768.0
    return -32768.0, 32767.0, 0.0


def _clipping(values: FloatArray | Summary, full_scale: float | None, rails: Rails | None) -> tuple[int, float | None]:
    """(samples at the clip level, peak |value| as a fraction of that level).

    With a full scale V, the level is ``CLIP_FRACTION·V``; without, the rails of the integer
    type (integer_rails). Other data has no known limit.
    """
    if isinstance(values, Summary):
        return _summed_clipping(values, full_scale, rails)
    if values.size == 0:
        return 0, None
    if full_scale:
        level = CLIP_FRACTION * full_scale
        clipped, top = 0, 0.0
        for c in chunks(values):  # a chunk at a time: no temporary as large as the capture
            peak = np.abs(c).max(axis=1)
            clipped += int((peak >= level).sum())
            top = max(top, float(peak.max()))
        return clipped, float(top / level)
    if rails is None:
        return 0, None
    low_rail, high_rail, mid = rails
    clipped, top = 0, 0.0
    for c in chunks(values):
        clipped += int(((c <= low_rail) | (c >= high_rail)).any(axis=1).sum())
        top = max(top, float(np.abs(c - mid).max()))
    return clipped, float(top / (high_rail - mid))


def _summed_clipping(values: Summary, full_scale: float | None, rails: Rails | None) -> tuple[int, float | None]:
    """_clipping of a long pose's running sums: the blocks that reach the level read again."""
    if not values.count:
        return 0, None
    if full_scale:
        level = CLIP_FRACTION * full_scale
        return values.at_level(-level, level), float(values.largest / level)
    if rails is None:
        return 0, None
    low_rail, high_rail, mid = rails
    top = max(values.high - mid, mid - values.low)
    return values.at_level(low_rail, high_rail), float(top / (high_rail - mid))


# -- limits and the verdict ----------------------------------------------------------------


@dataclass(frozen=True)
class Limits:
    """Bounds a good unit stays within (each None: not judged)."""

    offset: FloatArray | None = None  # (3,) bound on |offset - nominal_offset|, raw units
    nominal_offset: FloatArray = field(default_factory=lambda: np.zeros(3))  # unsigned counts: 32768
    gain_error: FloatArray | None = None  # (3,) bound on |gain / nominal_gain - 1|
    nominal_gain: FloatArray = field(default_factory=lambda: np.ones(3))
    nominal_gain_given: bool = False  # named (a limits file, --nominal-gain): the gains are judged by it, 1 too
    cross_axis: float | None = None  # bound on |A[i, j] / A[i, i]|, i != j
    noise: float | None = None  # bound on each pose's standard deviation, output units
    residual: float | None = None  # bound on each pose's | |M (mean - offset)| - reference |
    offset_drift: FloatArray | None = (
        None  # (3,) bound on |offset(T) - offset(T_ref)| over the thermal range, raw units
    )
    offset_drift_per_degc: FloatArray | None = None  # (3,) bound on |d offset / dT|, raw units per °C
    dip_angle: float | None = None  # degrees: bound on each still block's dip angle from the model's (or their mean)

    def for_method(self, method: str) -> Limits:
        """The limits that apply to a method (its catalog row's ``not_applying``: no gain limit
        where the gains are fixed, no cross-axis limit where there are no cross-axis terms ...)."""
        dropped: dict[str, None] = dict.fromkeys(self.not_applying(method))
        return replace(self, **dropped)  # type: ignore[arg-type]  # each a field that may be None

    def not_applying(self, method: str) -> dict[str, str]:
        """The limits given that do not apply to ``method``, each with the reason."""
        return {name: why for name, why in catalog.not_applying(method).items() if getattr(self, name) is not None}

    def not_applying_notes(self, method: str) -> list[str]:
        """A note for each limit given that does not apply to ``method`` (:meth:`not_applying`)."""
        return [
            f"the {method} solver {why}, so the {name.replace('_', '-')} limit does not apply"
            for name, why in self.not_applying(method).items()
        ]

    def judges(self) -> bool:
        """Whether any bound is set (a nominal gain alone judges nothing)."""
        return any(
            getattr(self, name) is not None
            for name in ("offset", "gain_error", "offset_drift", "offset_drift_per_degc", "dip_angle", *catalog.LIMITS)
        )

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {}
        if self.offset is not None:
            out["offset"] = [float(v) for v in self.offset]
            if np.any(self.nominal_offset != 0.0):
                out["nominal_offset"] = [float(v) for v in self.nominal_offset]
        if self.gain_error is not None:
            out["gain_error"] = [float(v) for v in self.gain_error]
        if self.gain_error is not None or np.any(self.nominal_gain != 1.0):  # given: export's gain trim reads it
            out["nominal_gain"] = [float(v) for v in self.nominal_gain]
        for name in ("cross_axis", "noise", "residual", "dip_angle"):
            if getattr(self, name) is not None:
                out[name] = float(getattr(self, name))
        for name in ("offset_drift", "offset_drift_per_degc"):
            if getattr(self, name) is not None:
                out[name] = [float(v) for v in getattr(self, name)]
        return out

    def __getitem__(self, name: str) -> object:
        """A bound as the calibration file writes it (``verdict.limits["offset"]``: [x, y, z])."""
        return self.as_dict()[name]


@dataclass(frozen=True)
class Corrected:
    """A pose after calibration, in output units."""

    norm_error: float  # |M (mean - offset)| - reference
    vector_error: float | None  # |M (mean - offset) - reference * direction|; None: orientation unknown
    std: FloatArray  # (3,) the pose's standard deviation through M


def corrected(
    mean: FloatArray, std: FloatArray, face: str | None, offset: FloatArray, matrix: FloatArray, reference: float
) -> Corrected:
    """How a pose (its mean and standard deviation) reads once corrected, against the reference."""
    c = matrix @ (mean - offset)  # docs/reference/model.md: corrected = M (raw - b)
    return Corrected(
        norm_error=float(np.linalg.norm(c) - reference),
        vector_error=None if face is None else float(np.linalg.norm(c - reference * direction(face))),
        std=output_std(matrix, std),
    )


def output_std(matrix: FloatArray, std: FloatArray) -> FloatArray:
    """(3,) per-axis standard deviation in output units, through M (axes' noise independent)."""
    result: FloatArray = np.sqrt((matrix**2) @ std**2)
    return result


def verdict(
    method: str,
    offset: FloatArray,
    matrix: FloatArray,
    poses: Sequence[tuple[str, str | None, Corrected]],
    limits: Limits,
    fit_residual: float | None = None,
    drift: tuple[FloatArray, FloatArray] | None = None,
) -> list[Finding]:
    """Every limit the unit is outside of (empty: pass). ``poses`` are (file, face, corrected).

    A capture turned through many orientations (catalog.turned) has no pose to read against the
    reference: its residual limit judges ``fit_residual``, the fit's largest residual over
    the samples, instead. ``drift``: a thermal block's largest offset drift over its range and
    largest drift per °C, per axis (core.drift.extremes), judged by the offset_drift limits."""
    failures: list[Finding] = _drift_failures(limits, drift)
    a = np.asarray(np.linalg.inv(matrix), dtype=np.float64)
    gain = np.diag(a)
    for i, axis in enumerate(AXES):
        away = offset[i] - limits.nominal_offset[i]
        if limits.offset is not None and not abs(away) <= limits.offset[i]:  # NaN fails
            centre = f"{limits.nominal_offset[i]:g} " if limits.nominal_offset[i] else ""
            failures.append(
                Finding(
                    f"limit.offset.{axis}",
                    f"offset {offset[i]:.6g} on {axis} is outside {centre}±{limits.offset[i]:g}",
                    float(away),  # what is judged against ±bound (the offset itself when the centre is 0)
                    float(limits.offset[i]),
                )
            )
    if limits.gain_error is not None and not catalog.fixes_gains(method):
        for i, axis in enumerate(AXES):
            error = gain[i] / limits.nominal_gain[i] - 1.0
            if not abs(error) <= limits.gain_error[i]:
                failures.append(
                    Finding(
                        f"limit.gain.{axis}",
                        f"gain {gain[i]:.6g} on {axis} is {error:+.3%} from nominal {limits.nominal_gain[i]:g}, "
                        f"outside ±{limits.gain_error[i]:.3%}",
                        float(error),
                        float(limits.gain_error[i]),
                    )
                )
    if limits.cross_axis is not None and np.count_nonzero(matrix - np.diag(np.diag(matrix))):
        for i in range(3):
            for j in range(3):
                ratio = cross_term(a, i, j)
                if i != j and abs(ratio) > limits.cross_axis:
                    failures.append(
                        Finding(
                            f"limit.cross.{AXES[i]}{AXES[j]}",
                            f"cross-axis term {AXES[i]}{AXES[j]} is {ratio:+.3%}, outside ±{limits.cross_axis:.3%}",
                            float(ratio),
                            limits.cross_axis,
                        )
                    )
    if catalog.turned(method):
        if limits.residual is not None and fit_residual is not None and not abs(fit_residual) <= limits.residual:
            failures.append(
                Finding(
                    "limit.residual",
                    f"the fit's largest residual over the samples is {fit_residual:.3g}, outside ±{limits.residual:g}",
                    fit_residual,
                    limits.residual,
                )
            )
        return failures
    for file, face, c in poses:
        where = {"file": file, "pose": face}
        worst = int(np.argmax(c.std))
        if limits.noise is not None and c.std[worst] > limits.noise:
            failures.append(
                Finding(
                    "limit.noise",
                    f"noise {c.std[worst]:.3g} on {AXES[worst]} is above {limits.noise:g}",
                    float(c.std[worst]),
                    limits.noise,
                    **where,
                )
            )
        if limits.residual is not None and abs(c.norm_error) > limits.residual:
            failures.append(
                Finding(
                    "limit.residual",
                    f"reads {c.norm_error:+.3g} from the reference after calibration, outside ±{limits.residual:g}",
                    c.norm_error,
                    limits.residual,
                    **where,
                )
            )
    return failures


def dip_failures(limits: Limits, angles: FloatArray, model: float | None) -> list[Finding]:
    """The dip_angle limit (docs/real-world.md): each still block's angle between gravity and the
    field (degrees) against the model's, 90 - inclination (their mean where no model is given):
    a field bent by steel or a motor, or a magnetometer turned against the accelerometer, fails."""
    if limits.dip_angle is None or not len(angles):
        return []
    centre = float(np.mean(angles)) if model is None else model
    k = int(np.argmax(np.abs(angles - centre)))
    away = float(angles[k] - centre)
    if abs(away) <= limits.dip_angle:
        return []
    # said as the inclination (quantities.DIP_SAID), the one convention printed: 90° less the angle
    against = f"the model's {90.0 - model:.2f}°" if model is not None else f"their mean {90.0 - centre:.2f}°"
    return [
        Finding(
            "limit.dip_angle",
            f"the dip of still block {k + 1} of {len(angles)} is {90.0 - angles[k]:.2f}°, {-away:+.2f}° from "
            f"{against}, outside ±{limits.dip_angle:g}°",
            away,
            limits.dip_angle,
            hint="calibrate away from steel, motors and cables, or check the accelerometer calibration",
        )
    ]


def _drift_failures(limits: Limits, drift: tuple[FloatArray, FloatArray] | None) -> list[Finding]:
    """The offset-drift limits (docs/commands/thermal.md): over the range, and per °C."""
    out: list[Finding] = []
    if drift is None:
        return out
    for bound, values, code, what in (
        (limits.offset_drift, drift[0], "limit.offset_drift", "offset drifts by {:.4g} on {} over the range"),
        (limits.offset_drift_per_degc, drift[1], "limit.offset_drift_per_degc", "offset drifts {:.4g} per °C on {}"),
    ):
        if bound is None:
            continue
        for i, axis in enumerate(AXES):
            if not values[i] <= bound[i]:
                out.append(
                    Finding(
                        f"{code}.{axis}",
                        f"{what.format(values[i], axis)}, above {bound[i]:g}",
                        float(values[i]),
                        float(bound[i]),
                    )
                )
    return out


def _samples(n: int) -> str:
    return "1 sample" if n == 1 else f"{n} samples"


def _vec(v: FloatArray) -> str:
    return ", ".join(f"{x:.3g}" for x in v)


def _num(value: float) -> float | int:
    return int(value) if float(value).is_integer() and abs(value) < 2**53 else float(value)


def cross_term(a: FloatArray, i: int, j: int) -> float:
    """A[i, j] / A[i, i], the cross-axis term; infinite where A[i, i] is 0 (a matrix that maps
    another axis onto axis i: no limit passes it)."""
    return float(a[i, j]) / float(a[i, i]) if a[i, i] else math.inf


# -- gains in other units, and judging a calibration again --------------------------------------

#: Gains this far from nominal are not a sensor's error but a units mistake (exit 2, not exit 1).
GAIN_UNITS_TOLERANCE = 0.25


def check_gains(gain: FloatArray, reference: float, nominal: FloatArray, *, again: bool = False) -> None:
    """Gains judged against a nominal (a gain-error limit, or --nominal-gain) that are all more
    than GAIN_UNITS_TOLERANCE from it, and alike: the data is in other units than the station
    was set up for. Exit 2, naming the --reference (or --nominal-gain) the data suggests; exit 1
    would fail good hardware on a misconfigured station. Unjudged gains are whatever scale the
    data needs (16384 for counts into g): a gain solver corrects any units. ``again``: a
    calibration judged after solve, which is to be solved again with that --reference."""
    ratio = gain / nominal
    # a units mistake scales every axis alike; one axis off (a swapped or upside-down pose, a
    # broken axis) is the quality checks' and the limits' to judge
    alike = bool((ratio > 0).all()) and float(ratio.max() / ratio.min()) <= 1.0 + GAIN_UNITS_TOLERANCE
    if not alike or float(abs(ratio - 1.0).min()) <= GAIN_UNITS_TOLERANCE:
        return
    shown = ", ".join(f"{g:.4g}" for g in gain)
    nominal_text = ", ".join(f"{n:g}" for n in nominal) if len(set(nominal.tolist())) > 1 else f"{nominal[0]:g}"
    typical = float(gain.mean())
    suggested = suggest_reference(reference * typical / float(nominal.mean()))
    units = REFERENCE_UNITS.get(suggested)
    if abs(typical - 1.0) <= GAIN_UNITS_TOLERANCE:
        hint = said("gains.near_one")
    elif units is not None and suggested != reference:
        hint = said("gains.units", units=units, verb="solve it again" if again else "run", reference=suggested)
    else:
        per_unit, counts = suggest_reference(typical), suggest_reference(reference * typical)
        hint = said("gains.counts", typical=typical, gain=per_unit, reference=counts)
    raise InputError(
        f"gains {shown} are {float(ratio.mean()) - 1:+.0%} from the nominal gain {nominal_text}: a units mistake?",
        hint=hint,
    )


#: How near standard gravity (or its inverse) an accelerometer's gains are when they are the
#: data's units changed from m/s^2 into g (or back), not the sensor's own: local gravity (9.78
#: to 9.83 m/s^2) and a sensor's gain error of a few % within it.
UNITS_NOTE_TOLERANCE = 0.05


def units_note(gain: FloatArray, reference: float) -> str | None:
    """The note for gains that all sit near 9.81 with a reference of 1 (data in m/s^2 corrected
    into g) or near 1/9.81 with a reference near 9.81 (data in g corrected into m/s^2): a units
    change the station may not have meant, that no limit judged (check_gains: unjudged gains
    are whatever scale the data needs). None for any other gains: data in the reference's units
    (gains near 1), counts (16384), mg (1000)."""
    gravity = STANDARD_GRAVITY
    near_gravity = abs(reference / gravity - 1.0) <= 0.01
    for expected, meant, other, ref_meant in ((gravity, "m/s^2", "g", 1.0), (1.0 / gravity, "g", "m/s^2", gravity)):
        if not (reference == 1.0 if ref_meant == 1.0 else near_gravity):
            continue
        if bool((abs(gain / expected - 1.0) <= UNITS_NOTE_TOLERANCE).all()):
            shown = ", ".join(f"{g:.4g}" for g in gain)
            again = said("units.again.si", gravity=gravity) if meant == "m/s^2" else said("units.again.g")
            return (
                f"the gains ({shown}) are about {expected:.3g}: the data looks like {meant}, corrected into {other} "
                f"{said('units.asked', reference=reference)}; for corrected data in {meant}, run with {again}"
            )
    return None


@dataclass(frozen=True)
class Recorded:
    """A pose as a calibration records it: its name (file, and block), face, mean (3,) and
    standard deviation (3,), None where the record has none."""

    name: str
    face: str | None
    mean: FloatArray
    std: FloatArray | None


@dataclass(frozen=True)
class Calibrated:
    """What judging a calibration again reads: its parameters, the poses it records (None: it
    records none, as an imported one), its fit's largest residual and its thermal drift."""

    method: str
    reference: float
    offset: FloatArray  # (3,) raw units
    matrix: FloatArray  # (3, 3) M
    gain: FloatArray  # (3,) diag(inv(M))
    poses: Sequence[Recorded] | None
    fit_residual: float | None = None
    drift: Drift | None = None


def judge_again(cal: Calibrated, given: Limits, not_applying: str) -> list[Finding]:
    """The limits a calibration is outside of, judged afresh (``tumblecal check``) with the
    rules solve judged it by: gains in other units are an input error (check_gains), and so
    are limits it has nothing to be judged by (``not_applying``: why the limits given do not
    apply to its method). The errors name no file: the caller knows it."""
    bounds = given.for_method(cal.method)
    judged_gain = bounds.gain_error is not None or given.nominal_gain_given
    if catalog.judges_gains(cal.method) and cal.reference > 0 and judged_gain:
        check_gains(cal.gain, cal.reference, given.nominal_gain, again=True)
    if not bounds.judges():
        raise InputError(f"no limits to judge against: {not_applying}")
    if cal.poses is None and (bounds.noise is not None or bounds.residual is not None):
        raise InputError(
            "has no poses to judge the noise and residual limits by",
            hint="judge it by offset, gain_error and cross_axis only (a limits file without noise and residual)",
        )
    poses = []
    for k, p in enumerate(cal.poses or ()):
        if p.std is None:
            raise InputError(f"field 'poses[{k}]' must be an object with pose, mean, std and samples")
        fixed = corrected(p.mean, p.std, p.face, cal.offset, cal.matrix, cal.reference)
        poses.append((p.name, p.face, fixed))
    if catalog.turned(cal.method) and bounds.residual is not None and cal.fit_residual is None:
        raise InputError(
            "has no fit residuals to judge the residual limit by",
            hint="judge it without the residual limit, or solve the capture again",
        )
    drift = None
    if bounds.offset_drift is not None or bounds.offset_drift_per_degc is not None:
        if cal.drift is None:
            raise InputError(
                "has no thermal block to judge the offset_drift limits by",
                hint="add one with 'tumblecal thermal', or judge it without those limits",
            )
        drift = extremes(cal.drift)
    return verdict(cal.method, cal.offset, cal.matrix, poses, bounds, cal.fit_residual, drift)
