"""A sensor's axes stated in the body's: a signed permutation (``--axes -y,-x,+z``). numpy only.

``--axes A,B,C`` names, for the body's x, y and z in turn, the sensor axis (with its sign) that
points along it: ``-y,-x,+z`` says the body's x is the sensor's −y, its y the sensor's −x and its
z the sensor's +z. As a matrix ``P`` (row i the signed unit vector of the sensor axis named
i-th), ``v_body = P v_sensor``. A board's datasheet or an autopilot's driver table states a
sensor this way (ArduPilot's and PX4's ``ROTATION_*``); cave-survey instruments list it as
``"-Y-X+Z"``. ``P`` may mirror (det −1: a left-handed sensor), which no rotation states.

A calibration keeps its offsets in the sensor's raw axes (ready for its offset registers) and
folds ``P`` into its matrix: ``corrected = P M (raw - b)``, in the body's axes (io.calfiles).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import direction, parse_label

NAMES = "xyz"
#: One signed axis of --axes: an optional sign (+ by default) and x, y or z.
_AXIS = re.compile(r"\s*([+-]?)\s*([xyzXYZ])\s*")
#: A rotation this close to a signed permutation (degrees) is that permutation and a small
#: misalignment: align names the --axes that states it.
NEAR_DEG = 10.0


@dataclass(frozen=True)
class Axes:
    """A signed permutation: ``sign[i]`` × the sensor axis ``source[i]`` is the body's axis i."""

    source: tuple[int, int, int]
    sign: tuple[int, int, int]

    @property
    def matrix(self) -> FloatArray:
        """``P`` (3, 3): ``v_body = P v_sensor``."""
        out = np.zeros((3, 3))
        for i, (j, s) in enumerate(zip(self.source, self.sign, strict=True)):
            out[i, j] = float(s)
        return out

    @property
    def text(self) -> str:
        """As --axes takes it: ``-y,-x,+z``."""
        return ",".join(f"{'+' if s > 0 else '-'}{NAMES[j]}" for j, s in zip(self.source, self.sign, strict=True))

    @property
    def identity(self) -> bool:
        return self.source == (0, 1, 2) and self.sign == (1, 1, 1)

    @property
    def mirrors(self) -> bool:
        """Whether ``P`` is a reflection (det −1): the sensor's axes are left-handed in the body's."""
        return bool(np.linalg.det(self.matrix) < 0)

    def sensor_label(self, label: str) -> str:
        """A pose label of the body's axes (a face, ``+x``, or a direction ``X,Y,Z``) as the
        sensor's direction along it (``-y`` for ``+x`` with -y,-x,+z)."""
        d = self.matrix.T @ direction(label)
        return parse_label(",".join(f"{v:.12g}" for v in d))

    def body(self, values: FloatArray) -> FloatArray:
        """Readings (n, 3) of the sensor's axes as the body's (``v Pᵀ``, by their columns: the
        same digits)."""
        out: FloatArray = values[:, list(self.source)] * np.asarray(self.sign, dtype=np.float64)
        return out

    def body_label(self, label: str) -> str:
        """A pose label of the sensor's axes (``-y``) as the body's direction it is (``+x`` with
        -y,-x,+z): ``sensor_label``'s inverse."""
        d = self.matrix @ direction(label)
        return parse_label(",".join(f"{v:.12g}" for v in d))

    def then(self, other: Axes) -> Axes:
        """These axes followed by ``other``'s (``P_other P_self``)."""
        return of_matrix(other.matrix @ self.matrix)


IDENTITY = Axes((0, 1, 2), (1, 1, 1))


def parse(text: str) -> Axes:
    """``-y,-x,+z`` (or ``-Y-X+Z``; a sign may be left out where it is +) as Axes, each sensor axis
    once; a ValueError saying what is wrong otherwise (the caller names the flag or the file)."""
    given = text.replace(",", " ").split() if "," in text or " " in text.strip() else _runs(text)
    found = [_AXIS.fullmatch(part) for part in given]
    if len(found) != 3 or any(m is None for m in found):
        raise ValueError("give three signed sensor axes, the body's x, y and z in turn (e.g. -y,-x,+z)")
    source = tuple(NAMES.index(m.group(2).lower()) for m in found if m is not None)
    sign = tuple(-1 if m.group(1) == "-" else 1 for m in found if m is not None)
    if sorted(source) != [0, 1, 2]:
        raise ValueError("a sensor axis is named twice: name each of x, y and z once (e.g. -y,-x,+z)")
    return Axes((source[0], source[1], source[2]), (sign[0], sign[1], sign[2]))


def _runs(text: str) -> list[str]:
    """``-Y-X+Z`` split before each axis's sign or letter run: ``['-Y', '-X', '+Z']``."""
    return re.findall(r"[+-]?\s*[A-Za-z]", text)


def of_matrix(matrix: FloatArray) -> Axes:
    """The Axes of a signed permutation matrix (rounded: each row's largest entry)."""
    source = tuple(int(np.argmax(np.abs(row))) for row in matrix)
    sign = tuple(1 if matrix[i, j] > 0 else -1 for i, j in enumerate(source))
    if sorted(source) != [0, 1, 2]:
        raise ValueError("not a signed permutation of the axes")
    return Axes((source[0], source[1], source[2]), (sign[0], sign[1], sign[2]))


def every(*, mirrored: bool | None = False) -> list[Axes]:
    """The 24 signed permutations that are rotations (``mirrored=False``), the 24 mirrors
    (``True``), or all 48 (``None``), the identity first."""
    out = []
    for source in itertools.permutations(range(3)):
        for sign in itertools.product((1, -1), repeat=3):
            a = Axes((source[0], source[1], source[2]), (sign[0], sign[1], sign[2]))
            if mirrored is None or a.mirrors == mirrored:
                out.append(a)
    return out


def nearest(matrix: FloatArray) -> tuple[Axes, float]:
    """The signed permutation closest to an orthogonal ``matrix`` (of its handedness), and the
    angle (degrees) of the rotation left between them."""
    mirrored = bool(np.linalg.det(matrix) < 0)
    best = min(every(mirrored=mirrored), key=lambda a: -float(np.trace(a.matrix.T @ matrix)))
    return best, angle_between(best.matrix, matrix)


def angle_between(a: FloatArray, b: FloatArray) -> float:
    """The angle (degrees) of the rotation ``aᵀ b`` between two orthogonal matrices of one handedness."""
    cos = (float(np.trace(a.T @ b)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
