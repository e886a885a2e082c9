"""Synthetic gyroscope sessions turned by hand, with a known truth: the unit rests, is turned with
a smooth start and stop (a hand accelerates and brakes: the rate follows ``sin²`` over the turn,
so the first and last tenths of a second turn it by hundredths of a degree, which an
accelerometer cannot tell from rest and a gyroscope can), rests again, and so on.

    gyroscope     raw = A · ω + b + G · a + noise    ω: body rate, deg/s; a: gravity, g
    accelerometer raw = ACC_A · (gravity in the sensor frame, g) + ACC_B + noise

:func:`hand_session` is the log ``solve --accel-cal`` takes (still blocks joined by turns about
random axes); :func:`known_session` the log ``solve --turns`` takes (six labelled faces joined by
smooth moves, then a 360° turn about each axis), its labels drawn as a person marks them: each
face's label runs a little into the moves before and after it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: The gyroscope: counts per deg/s (an MPU-6050 at ±2000 deg/s reads 16.4), 1-2 % scale errors,
#: cross-axis terms up to 1 %; its bias in counts; its noise 0.05 deg/s (0.8 counts) per sample.
A = np.array([[16.4, 0.15, -0.2], [-0.1, 16.7, 0.12], [0.16, -0.12, 16.1]])
B = np.array([2.0, -4.5, -3.6])
#: g-sensitivity (counts per g, column j for gravity along +j): known turns solve for it.
G = np.array([[0.02, -0.16, 0.18], [0.14, 0.05, -0.09], [-0.09, 0.08, -0.04]])
#: ... and as much as a MEMS gyroscope's data sheet allows (0.1 deg/s per g: 1.6 counts per g).
G_MEMS = G / np.abs(G).max() * 1.6
GYRO_NOISE_DPS = 0.05
#: The accelerometer: counts per g, its offset; noise 3 mg per sample at 200 Hz.
ACC_A = np.array([[2048.0, 10.0, -5.0], [-8.0, 2040.0, 6.0], [4.0, -7.0, 2100.0]])
ACC_B = np.array([-6.0, -48.0, -29.0])
ACC_NOISE_G = 0.003
HEADER = "t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z"


@dataclass
class Session:
    """A synthetic log: time (s), the accelerometer and gyroscope (raw counts), where the unit was
    truly still (a bool per sample), the body's true rate (deg/s) and the label of each sample
    ('' for none)."""

    t: FloatArray
    acc: FloatArray
    gyr: FloatArray
    still: NDArray[np.bool_]
    rate: FloatArray
    labels: list[str] = field(default_factory=list)

    def turning(self, spans: list[tuple[int, int]]) -> FloatArray:
        """What the true rate adds to the mean of the gyroscope over ``spans`` (raw counts): the
        error of a bias taken there, noise aside."""
        rate = np.concatenate([self.rate[a : b + 1] for a, b in spans])
        out: FloatArray = A @ rate.mean(axis=0)
        return out

    def write(self, path: Path) -> Path:
        """The log as CSV (with a ``part`` label column when it has labels)."""
        labelled = bool(self.labels)
        lines = [HEADER + (",part" if labelled else "")]
        for i in range(len(self.t)):
            cells = [f"{self.t[i]:.5f}", *(f"{v:.3f}" for v in self.acc[i]), *(f"{v:.4f}" for v in self.gyr[i])]
            lines.append(",".join(cells + ([self.labels[i]] if labelled else [])))
        path.write_text("\n".join(lines) + "\n")
        return path


def rotmat(axis: FloatArray, angle: float) -> FloatArray:
    """The rotation by ``angle`` (radians) about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    out: FloatArray = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return out


class _Recorder:
    """Appends still stretches and smooth turns, sample by sample, keeping the body's attitude."""

    def __init__(
        self, rng: np.random.Generator, rate: float, gyro_noise: float, acc_noise: float, g: FloatArray | None = None
    ) -> None:
        self.rng, self.rate = rng, rate
        self.g = np.zeros((3, 3)) if g is None else g
        self.gyro_sigma, self.acc_sigma = gyro_noise * float(np.mean(np.diag(A))), acc_noise * 2048.0
        self.body = np.eye(3)  # sensor to world
        self.acc: list[FloatArray] = []
        self.gyr: list[FloatArray] = []
        self.still: list[NDArray[np.bool_]] = []
        self.turning: list[FloatArray] = []  # the body's rate, deg/s
        self.labels: list[str] = []

    def rest(self, seconds: float, label: str = "") -> None:
        n = round(seconds * self.rate)
        up = self.body.T @ np.array([0.0, 0.0, 1.0])
        self.acc.append(ACC_A @ up + ACC_B + self.rng.normal(0, self.acc_sigma, (n, 3)))
        self.gyr.append(B + self.g @ up + self.rng.normal(0, self.gyro_sigma, (n, 3)))
        self.still.append(np.ones(n, dtype=bool))
        self.turning.append(np.zeros((n, 3)))
        self.labels += [label] * n

    def turn(self, axis: FloatArray, angle_deg: float, seconds: float, label: str = "") -> None:
        """A turn about the body ``axis`` whose rate is ``sin²`` from rest to rest: each sample's
        rate held for one period turns the body by exactly that rate times the period."""
        n = round(seconds * self.rate)
        phase = (np.arange(n) + 0.5) / n
        rate_dps = np.sin(np.pi * phase) ** 2
        rate_dps *= angle_deg / (rate_dps.sum() / self.rate)
        theta = np.radians(np.cumsum(rate_dps) / self.rate)[:, None]  # the angle turned after each sample
        # the world's up seen from the sensor turns the other way: Rodrigues with -theta
        u = self.body.T @ np.array([0.0, 0.0, 1.0])
        up = u * np.cos(theta) - np.sin(theta) * np.cross(axis, u) + (1 - np.cos(theta)) * (axis @ u) * axis
        self.body = self.body @ rotmat(axis, float(theta[-1, 0]))
        self.acc.append(up @ ACC_A.T + ACC_B + self.rng.normal(0, self.acc_sigma, (n, 3)))
        gyr = np.outer(rate_dps, axis) @ A.T + B + up @ self.g.T
        self.gyr.append(gyr + self.rng.normal(0, self.gyro_sigma, (n, 3)))
        self.still.append(np.zeros(n, dtype=bool))
        self.turning.append(np.outer(rate_dps, axis))
        self.labels += [label] * n

    def session(self, labelled: bool) -> Session:
        acc, gyr = np.vstack(self.acc), np.vstack(self.gyr)
        t = np.arange(len(acc)) / self.rate
        still, turning = np.concatenate(self.still), np.vstack(self.turning)
        return Session(t, acc, gyr, still, turning, self.labels if labelled else [])


def hand_session(
    rng: np.random.Generator,
    *,
    blocks: int = 24,
    rate: float = 200.0,
    still_s: float = 2.0,
    gyro_noise: float = GYRO_NOISE_DPS,
    acc_noise: float = ACC_NOISE_G,
    g: FloatArray | None = None,
) -> Session:
    """``blocks`` still stretches of ``still_s`` joined by smooth turns of 45-180° about random
    axes, each 1-2 s long (a peak rate of 45-360 deg/s); the gyroscope sensitive to gravity by
    ``g`` (counts per g; None: not at all)."""
    rec = _Recorder(rng, rate, gyro_noise, acc_noise, g)
    for k in range(blocks):
        rec.rest(still_s)
        if k < blocks - 1:
            axis = rng.normal(size=3)
            rec.turn(axis / np.linalg.norm(axis), float(rng.uniform(45, 180)), float(rng.uniform(1.0, 2.0)))
    return rec.session(labelled=False)


#: Each face of a known-turns session and the label its still section carries, in imucal's order.
FACES = (("+x", "x_p"), ("-x", "x_a"), ("+y", "y_p"), ("-y", "y_a"), ("+z", "z_p"), ("-z", "z_a"))
FACE_MAP = ",".join(f"{label}={face}" for face, label in FACES)
TURNS = "x_rot=+x,y_rot=+y,z_rot=+z"


def _towards(body: FloatArray, face: str) -> tuple[FloatArray, float]:
    """The body axis and angle (degrees) of the shortest turn that puts ``face`` up."""
    want = np.zeros(3)
    want["xyz".index(face[1])] = 1.0 if face[0] == "+" else -1.0
    up = body.T @ np.array([0.0, 0.0, 1.0])  # the world's up in the sensor frame, now
    # seen from the sensor, up turns the other way round from the body: turning the body about
    # want x up brings up onto want
    cross = np.cross(want, up)
    angle = float(np.degrees(np.arctan2(np.linalg.norm(cross), up @ want)))
    if np.linalg.norm(cross) < 1e-9:
        cross = np.cross(up, np.eye(3)[int(np.argmin(np.abs(up)))])
    return cross / np.linalg.norm(cross), angle


def known_session(
    rng: np.random.Generator,
    *,
    rate: float = 200.0,
    face_s: float = 4.0,
    spill_s: tuple[float, float] = (0.02, 0.12),
    gyro_noise: float = GYRO_NOISE_DPS,
    acc_noise: float = ACC_NOISE_G,
) -> Session:
    """imucal's protocol, the gyroscope sensitive to gravity (``G``): the six faces (``face_s``
    each), each reached by a smooth move of 1-2 s, then 360° about +x, +y and +z (4-6 s each, from
    rest on that face to rest). The face labels run ``spill_s`` (uniform) into the moves on both
    sides; each turn's label covers the turn and a little rest either side."""
    rec = _Recorder(rng, rate, gyro_noise, acc_noise, G)
    rec.rest(1.0)
    for face, label in FACES:
        axis, angle = _towards(rec.body, face)
        if angle > 1e-6:
            rec.turn(axis, angle, float(rng.uniform(1.0, 2.0)))
        rec.rest(face_s, label)
    for k, (face, label) in enumerate((("+x", "x_rot"), ("+y", "y_rot"), ("+z", "z_rot"))):
        axis, angle = _towards(rec.body, ("+z", "+x", "+y")[k])  # rest on a face whose up is not the turn's axis
        rec.turn(axis, angle, float(rng.uniform(1.0, 2.0)))
        rec.rest(1.0)
        rec.rest(0.3, label)
        rec.turn(np.eye(3)["xyz".index(face[1])], 360.0, float(rng.uniform(4.0, 6.0)), label)
        rec.rest(0.3, label)
        rec.rest(1.0)
    session = rec.session(labelled=True)
    _spill(session, rng, spill_s, rate)
    return session


def _spill(session: Session, rng: np.random.Generator, spill_s: tuple[float, float], rate: float) -> None:
    """Each face's label stretched ``spill_s`` seconds into the unlabelled samples either side."""
    labels = np.array(session.labels, dtype=object)
    original = labels.copy()
    faces = {label for _, label in FACES}
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    firsts, lasts = np.concatenate([[0], change]), np.concatenate([change - 1, [len(labels) - 1]])
    for a, b in zip(firsts, lasts, strict=True):
        if original[a] in faces:
            before, after = (int(rng.uniform(*spill_s) * rate) for _ in range(2))
            lo, hi = max(0, a - before), min(len(labels), b + 1 + after)
            free = labels[lo:hi] == ""
            labels[lo:hi][free] = original[a]
    session.labels = [str(x) for x in labels]
