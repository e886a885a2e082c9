"""Synthetic tumble captures with a known truth (the measurement model of docs/reference/model.md).

    raw = A · v + b + noise,   A = diag(gain) + cross,   |v| = reference

Used by the known-answer and Hypothesis tests: generate a pose with :func:`pose_samples`, solve it,
compare with the truth that made it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Truth:
    """What a synthetic capture is made of: raw = diag(gain) · v + offset + noise, |v| = reference."""

    reference: float
    offset: tuple[float, float, float]  # raw units
    gain: tuple[float, float, float]  # raw units per reference unit
    noise: float  # raw units, 1 sigma per sample


def stimulus(face_vector: ArrayLike, reference: float, tilt_deg: float = 0.0) -> FloatArray:
    """The true stimulus ``v`` for a face, tilted by ``tilt_deg`` towards the next axis.

    The face's axis ``i`` (x=0, y=1, z=2) leans towards the positive ``(i + 1) % 3`` axis, which is
    perpendicular to it: ``+x`` leans towards ``+y``, ``+y`` towards ``+z``, ``+z`` towards ``+x``. So
    ``v = reference · (cos θ · face + sin θ · e_next)``, and ``|v| = reference`` for every θ.
    """
    face = np.asarray(face_vector, dtype=np.float64)
    axis = int(np.argmax(np.abs(face)))
    lean = np.zeros(3)
    lean[(axis + 1) % 3] = 1.0
    theta = math.radians(tilt_deg)
    v: FloatArray = reference * (math.cos(theta) * face + math.sin(theta) * lean)
    return v


def pose_samples(
    rng: np.random.Generator,
    face_vector: ArrayLike,
    *,
    offset: ArrayLike,
    gain: ArrayLike,
    reference: float,
    noise: float,
    n: int,
    cross: ArrayLike | None = None,
    tilt_deg: float = 0.0,
) -> FloatArray:
    """(n, 3) raw readings of one static pose: ``A · v + offset`` plus Gaussian noise (σ = ``noise``).

    ``face_vector`` is the unit vector of the face pointing up (``core.FACES["+x"]`` = (1, 0, 0));
    ``offset`` (3,) is in raw units; ``gain`` (3,) is raw units per reference unit; ``cross`` is an
    optional 3x3 of off-diagonal (cross-axis) terms added to ``diag(gain)``; ``tilt_deg`` tilts the
    fixture (see :func:`stimulus`).
    """
    a = np.diag(np.asarray(gain, dtype=np.float64))
    if cross is not None:
        a = a + np.asarray(cross, dtype=np.float64)
    ideal = a @ stimulus(face_vector, reference, tilt_deg) + np.asarray(offset, dtype=np.float64)
    raw: FloatArray = ideal + rng.normal(0.0, noise, size=(n, 3))
    return raw


def hand_turned(
    rng: np.random.Generator,
    n: int,
    *,
    avoid: ArrayLike = (0.0, 0.0, 1.0),
    cap_deg: float = 0.0,
    rate: float = 50.0,
    speed: float = 1.5,
) -> FloatArray:
    """(n, 3) unit directions of a steady field in the frame of a unit turned by hand: a smooth
    walk over the sphere (angular speed about ``speed`` rad/s at ``rate`` Hz, its velocity an
    Ornstein-Uhlenbeck process with a 0.7 s memory), which bounces off the cap of half-angle
    ``cap_deg`` around ``avoid`` (0: the whole sphere), as a user who never turns that face
    towards the field. The walk starts at the cap's opposite."""
    axis = np.asarray(avoid, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    edge = math.cos(math.radians(cap_deg)) if cap_deg > 0 else 2.0
    dt, tau = 1.0 / rate, 0.7
    kick = speed * math.sqrt(2.0 * dt / tau)
    u, v = -axis.copy(), np.zeros(3)
    out = np.empty((n, 3))
    for k, step in enumerate(rng.standard_normal((n, 3))):
        v += -v * dt / tau + kick * step
        v -= (v @ u) * u  # tangent to the sphere
        nxt = u + v * dt
        nxt /= np.linalg.norm(nxt)
        if nxt @ axis > edge:  # at the cap's rim: turn back
            towards = axis - (axis @ u) * u
            towards /= max(float(np.linalg.norm(towards)), 1e-12)
            v -= 2.0 * max(float(v @ towards), 0.0) * towards
            nxt = u + v * dt
            nxt /= np.linalg.norm(nxt)
            if nxt @ axis > edge:
                nxt = u
        u = nxt
        out[k] = u
    return out
