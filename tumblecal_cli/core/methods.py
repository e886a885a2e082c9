"""Which solver: ``auto`` resolved from the labels and the sensor, and each method's labels
checked by its family in core.catalog (:func:`pick`); the labels of unlabelled pose files, and
the evidence that chooses between six-pose and six-pose-magnitude for six faces
(:func:`auto_six`). The methods there are: core.catalog. numpy only."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import FACES, angle_deg
from tumblecal_cli.errors import InputError, said

SIX_FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
#: The sphere fit needs this many poses: 9 parameters, and some residual to judge the fit by.
SPHERE_MIN_POSES = 12
#: Four poses whose directions are not in one plane determine the 12 parameters (exactly: no
#: residual is left to judge the fit by); a fifth leaves one.
LEAST_SQUARES_MIN_POSES = 4


@dataclass(frozen=True)
class FaceEvidence:
    """How the six face poses sit on their faces, about the midpoint of opposite faces.

    ``angles``: each pose's angle from its face. ``disagreement``: for each axis, the angle
    between the directions its two faces give it (``m[+i] - b`` and ``b - m[-i]``). A fixture
    that tilts every face alike (rigid but misaligned) turns both directions together and
    six-pose takes that turn as the sensor's misalignment; faces placed by hand tilt each pose
    its own way, the two directions disagree, and six-pose's cross-axis terms absorb tilt."""

    angles: dict[str, float]
    disagreement: dict[str, float]

    @property
    def worst(self) -> float:
        return max(self.disagreement.values())

    def disagreeing(self) -> str:
        """The axis whose faces disagree most, for people: ``the faces of x disagree on its
        direction by 15.2° (+x 15.9°, -x 1.7° off)``."""
        axis = max(self.disagreement, key=lambda a: self.disagreement[a])
        tilts = ", ".join(f"{f} {self.angles[f]:.1f}°" for f in (f"+{axis}", f"-{axis}"))
        return f"the faces of {axis} disagree on its direction by {self.disagreement[axis]:.1f}° ({tilts} off)"


#: Above this disagreement between opposite faces, auto leaves six-pose for six-pose-magnitude.
#: Synthetic hand-placed tumbles (tests/test_solvers.py, cross-axis terms 0.2-2 %) put the
#: crossover of the two methods' held-out errors between 1° and 2° of disagreement; the real
#: logs in tests/data disagree by 0.3-1.4° on a fixture and 6-20° by hand.
CONSISTENT_DEG = 1.5


def face_evidence(means: FloatArray) -> FaceEvidence:
    """The evidence of six poses in the order +x -x +y -y +z -z (see :class:`FaceEvidence`)."""
    centre = 0.5 * (np.diag(means[0::2]) + np.diag(means[1::2]))
    angles = {
        face: angle_deg(m - centre, face) if np.any(m - centre) else 90.0
        for face, m in zip(SIX_FACES, means, strict=True)
    }
    disagreement = {}
    for i, axis in enumerate("xyz"):
        up, down = means[2 * i] - centre, centre - means[2 * i + 1]
        cos = float(up @ down) / max(float(np.linalg.norm(up) * np.linalg.norm(down)), 1e-300)
        disagreement[axis] = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
    return FaceEvidence(angles, disagreement)


def auto_six(means: FloatArray) -> tuple[str, str]:
    """auto's solver for six labelled faces and why: six-pose when each axis's two faces agree on
    its direction within CONSISTENT_DEG (a good or rigidly misaligned fixture: its cross-axis
    terms are the sensor's), else six-pose-magnitude (faces placed by hand: cross-axis terms would
    be tilt, and correct other orientations worse than no calibration)."""
    ev = face_evidence(means)
    if ev.worst <= CONSISTENT_DEG:
        return "six-pose", (
            f"auto chose six-pose: each axis's two faces agree on its direction within {ev.worst:.2g}° "
            f"(limit {CONSISTENT_DEG:g}°), so its cross-axis terms are the sensor's, not fixture tilt"
        )
    return "six-pose-magnitude", (
        f"auto chose six-pose-magnitude: {ev.disagreeing()}, as hand-placed faces do; six-pose would take that "
        f"tilt for cross-axis terms, the magnitude fit is immune to it ({said('auto.magnitude')})"
    )


THREE_FACES = ("+x", "+y", "+z")


def per_axis(labels: Sequence[str | None]) -> list[int] | None:
    """The order that puts one face per axis in the order x, y, z (any signs: ``-z -x +y`` is
    ``[1, 2, 0]``), or None when ``labels`` are not three faces on three different axes."""
    if len(labels) != 3 or not all(label in FACES for label in labels):
        return None
    axes = [str(label)[1] for label in labels]
    if sorted(axes) != ["x", "y", "z"]:
        return None
    return [axes.index(a) for a in "xyz"]


def absent_axes(labels: Sequence[str | None]) -> list[str]:
    """The axes on which no label is a face (neither its + nor its - face)."""
    return [a for a in "xyz" if not any(label in (f"+{a}", f"-{a}") for label in labels)]


def missing_faces_error(labels: Sequence[str | None], what: str | None = None) -> InputError:
    """The usage error of faces that leave an axis without a face: its offset or its gain has
    nothing to come from (``no face on the y axis: add +y or -y``). ``what``: the method named
    at the message's start (None: the poses' option)."""
    absent = absent_axes(labels)
    axes = " and ".join(absent)
    adds = ", and ".join(f"+{a} or -{a}" for a in absent)
    given = " ".join(str(label) for label in labels)
    return InputError(
        f"{what or said('poses')}: no face on the {axes} ax{'es' if len(absent) > 1 else 'is'}: add {adds} "
        f"(faces given: {given})",
        hint=said("faces.missing"),
    )


#: A table of orientations: rows further apart than this point different ways (as
#: solvers.DISTINCT_DEG: the sphere fit counts directions by the same angle).
TABLE_STEP_DEG = 10.0
#: ... and its rows point in at least this many directions that far apart.
TABLE_DIRECTIONS = 3
#: The rows judged: the first this many (a table of averaged orientations is short; a capture
#: longer than this has shown what it is long before).
TABLE_HEAD = 4096


#: The length of the mean of a table's row directions is at most this: rows about one direction
#: (a still capture with noise of 0.2 g: about 0.98) are not a table of orientations (+x +y +z: 0.58).
TABLE_CLUSTERED = 0.9


def orientation_table(values: FloatArray, centre: FloatArray) -> str | None:
    """Why the rows of one capture (``values``, (n, 3), less ``centre``: the nominal offset)
    are separate orientations, one averaged reading each, or None.

    A pose file's rows are one vector plus noise; a log's consecutive samples, at any rate that
    follows motion, differ by noise or by a small part of a turn. A table of orientations turns
    from each row to the next: it is one when at least half of the steps between consecutive
    rows turn the direction by more than TABLE_STEP_DEG, and the rows point in at least
    TABLE_DIRECTIONS directions that far apart. Judged on the first TABLE_HEAD rows."""
    head = values[:TABLE_HEAD] - centre
    with np.errstate(over="ignore", invalid="ignore"):  # readings near 1e308: not a table to judge
        norms = np.linalg.norm(head, axis=1)
    if len(head) < TABLE_DIRECTIONS or not np.all(np.isfinite(norms) & (norms > 0)):
        return None
    unit = head / norms[:, None]
    if float(np.linalg.norm(unit.mean(axis=0))) > TABLE_CLUSTERED:
        return None  # one direction with noise (a noisy still capture), not many orientations
    cos = np.clip((unit[1:] * unit[:-1]).sum(axis=1), -1.0, 1.0)
    steps = np.degrees(np.arccos(cos))
    median = float(np.median(steps))
    if median <= TABLE_STEP_DEG:
        return None
    limit = math.cos(math.radians(TABLE_STEP_DEG))
    kept: list[FloatArray] = []
    for u in unit:
        if all(float(u @ k) < limit for k in kept):
            kept.append(u)
            if len(kept) >= TABLE_DIRECTIONS:
                break
    if len(kept) < TABLE_DIRECTIONS:
        return None
    return (
        f"its rows point in different directions (from one row to the next by {median:.0f}° in the median, "
        f"more than {TABLE_STEP_DEG:g}°)"
    )


def default_labels(count: int, up: str) -> list[str | None]:
    """Labels of unlabelled pose files: 1 -> ``up``, 3 -> +x +y +z, 6 -> +x -x +y -y +z -z, in
    that order; any other count has none (for the orientation-free solvers)."""
    if count == 1:
        return [up]
    if count == 3:
        return list(THREE_FACES)
    if count == 6:
        return list(SIX_FACES)
    return [None] * count


def pick(method: str, labels: Sequence[str | None], sensor: str) -> tuple[str, list[int]]:
    """The method to run (``auto`` resolved) and the order of the poses it takes them in.

    The labels are checked by the method's family (core.catalog: a new six-pose variant is
    checked as six-pose is). Too few files, or labels a method cannot use, is a usage error
    (exit 2); the data's own shortcomings (directions that do not span) are judged by the
    solver (exit 3).
    """
    n = len(labels)
    order = list(range(n))
    if method == "auto":
        method = _auto(labels, sensor)
    if method == "gyro-bias" and sensor != "gyroscope":  # else the accelerometer's columns "moved"
        raise InputError(said("gyro.sensor", sensor=sensor))
    family = catalog.family(method)
    if family == "one-pose":
        if n != 1:
            raise InputError(f"{method} takes 1 pose file, got {n}")
        if labels[0] is None:
            raise InputError(said("up.missing", method=method))
        if labels[0] not in FACES:
            raise InputError(
                f"{method} takes a pose on a face (the axis up), not the direction {labels[0]}",
                hint=said("up.face"),
            )
    elif family == "three-pose":
        three = per_axis(labels)
        if three is None:
            given = " ".join(str(x) for x in labels) if any(labels) else f"{n} unlabelled files"
            raise InputError(
                f"{method} takes 3 pose files, one face per axis (+x or -x, +y or -y, +z or -z); got {given}",
                hint=said("three.labels"),
            )
        order = three
    elif family == "six-pose":
        wanted = SIX_FACES
        if sorted(str(x) for x in labels) != sorted(wanted):
            given = " ".join(str(x) for x in labels) if any(labels) else f"{n} unlabelled files"
            raise InputError(
                f"{method} takes {len(wanted)} pose files, one per face {' '.join(wanted)}; got {given}",
                hint=said("six.labels"),
            )
        order = [list(labels).index(f) for f in wanted]
    elif family == "least-squares":
        if n < LEAST_SQUARES_MIN_POSES or any(x is None for x in labels):
            raise InputError(
                f"{method} takes {LEAST_SQUARES_MIN_POSES} or more labelled pose files "
                + (f"(a face or a direction X,Y,Z each), got {n}" if all(labels) else f"got {n} unlabelled"),
                hint=said("least.labels"),
            )
        if all(x in FACES for x in labels) and absent_axes(labels):
            raise missing_faces_error(labels, method)
    elif family == "sphere" and n < SPHERE_MIN_POSES:
        raise InputError(
            f"{method} takes {SPHERE_MIN_POSES} or more static pose files (9 parameters, and a residual "
            f"to judge the fit by), got {n}",
            hint="capture more orientations, or label the poses for the face solvers",
        )
    return method, order


def _auto(labels: Sequence[str | None], sensor: str) -> str:
    if sensor == "gyroscope":
        return "gyro-bias"
    if sensor == "magnetometer":
        return "ellipsoid"
    n = len(labels)
    faces = sorted(str(x) for x in labels)
    if n == 1:
        return "one-pose"
    if all(label in FACES for label in labels):  # faces only: each axis needs one
        if absent_axes(labels):
            raise missing_faces_error(labels)
        if n == 3:  # one per axis, any signs
            return "three-pose"
        if faces == sorted(SIX_FACES):
            return "six-pose"
    if all(labels) and n >= LEAST_SQUARES_MIN_POSES:
        return "least-squares"
    if not any(labels) and n >= SPHERE_MIN_POSES:
        return "sphere"
    what = f"the labels {' '.join(str(x) for x in labels)}" if all(labels) else f"{n} unlabelled files"
    raise InputError(
        f"{said('poses')}: no solver takes {what}: give 1 (one-pose), 3 (+x +y +z), 6 (+x -x +y -y +z -z), "
        f"{SPHERE_MIN_POSES}+ unlabelled (sphere) or {LEAST_SQUARES_MIN_POSES}+ labelled (least-squares)",
        hint=said("poses.none"),
    )
