"""Gyroscope scale and misalignment from known turns: the Ferraris procedure. numpy only.

Ferraris et al. 1995 (docs/sources.md), in the form imucal's
``FerrarisCalibration`` implements (its ``compute``, equation by equation): the unit rests on
its six faces (the gyroscope's zero-rate bias and, against gravity, its g-sensitivity), then
turns through a known angle about each of its axes (the integrated rate gives the gyroscope's
scale and misalignment). In tumblecal's model (docs/reference/model.md)::

    raw = A ω + b + G a + noise       ω: true rate (deg/s), a: gravity in the sensor frame (g)
    corrected = M (raw - b)           M = inv(A)

``G`` (raw units per g, column ``j`` for gravity along ``+j``) is imucal's ``K_ga`` times its
``grav``; ``A`` is imucal's ``K_g R_g`` when the angles have the same sign. Angles follow the
right-hand rule about the named axis: a turn of +θ about ``+x`` integrates to ``A (θ e_x)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import Solution

#: A turn whose integrated angle is further than this (a fraction of the angle) from the angle
#: given, at the gain of the other turns, is not the turn it claims to be.
ANGLE_TOLERANCE = 0.25


@dataclass(frozen=True)
class FaceReadings:
    """The readings of the six faces, +x -x +y -y +z -z in that order: (n_i, 3) each."""

    acc: list[FloatArray]
    gyr: list[FloatArray]


@dataclass(frozen=True)
class KnownTurn:
    """One known turn: its readings, the axis it turns about (unit (3,)), the right-hand angle
    (degrees), and the seconds each sample stands for ((n,): 1/rate, or the time to the next)."""

    acc: FloatArray
    gyr: FloatArray
    axis: FloatArray
    angle_deg: float
    dt: FloatArray


@dataclass(frozen=True)
class TurnsFit:
    """The gyroscope calibration and what it was made of."""

    solution: Solution  # offset = b, matrix = M = inv(A)
    g_sensitivity: FloatArray  # (3, 3) G, raw gyroscope units per g
    acc_offset: FloatArray  # (3,) the accelerometer's offset that gave a (raw units)
    acc_matrix: FloatArray  # (3, 3) its matrix into g
    integrated: FloatArray  # (3, k) W: each turn's integrated rate, b and G a removed (raw units x s)
    measured_deg: FloatArray  # (k,) each turn's angle about its axis, as the calibration reads it
    residual_deg: FloatArray  # (k,) |M W_k - θ_k e_k|, degrees
    cross_se: FloatArray  # (3, 3) 1-sigma of A's off-diagonal terms
    noise: FloatArray  # (3,) the gyroscope's noise at rest, raw units (pooled over the faces)


def accelerometer_in_g(acc_means: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The six-face accelerometer calibration into g (Ferraris Eqs. 19-23, imucal's ``b_a`` and
    ``R_a⁻¹ K_a⁻¹`` with grav 1): ``b_i`` the mean of axis i's two vertical readings,
    ``M = 2 inv(U_d)`` with column ``j`` of ``U_d`` the +j face's mean less the -j face's."""
    plus, minus = acc_means[0::2], acc_means[1::2]
    offset: FloatArray = 0.5 * (np.diag(plus) + np.diag(minus))  # Eq. 20
    diff = (plus - minus).T  # Eq. 21: U_a_d, one column per face pair
    matrix = np.asarray(2.0 * np.linalg.inv(diff), dtype=np.float64)  # Eqs. 22-23: K_a R_a = U_a_d / (2 grav)
    return offset, matrix


def g_sensitivity(gyr_means: FloatArray) -> FloatArray:
    """Ferraris Eq. 9 (imucal's ``K_ga`` times grav): column ``j`` is half the difference of the
    gyroscope's means on the +j and -j faces, the rate it reads per g along +j."""
    plus, minus = gyr_means[0::2], gyr_means[1::2]
    out: FloatArray = ((plus - minus) / 2.0).T
    return out


def axes_rank(axes: FloatArray) -> int:
    """How many independent axes the turns are about ((k, 3) unit vectors)."""
    return int(np.linalg.matrix_rank(axes, tol=0.1)) if len(axes) else 0


def plausible_angles(integrated: FloatArray, axes: FloatArray, angles: FloatArray) -> FloatArray:
    """Each turn's angle about its axis as the turns themselves measure it: its integrated rate's
    length over the median gain of all turns (``|W_k| / |θ_k|``), signed by its component along
    the axis. Needs no calibration, so a turn the wrong way round, or the wrong turn, shows."""
    length = np.linalg.norm(integrated, axis=0)
    gain = float(np.median(length / np.abs(angles)))
    sign = np.sign(np.einsum("ik,ki->k", integrated, axes))
    out: FloatArray = sign * length / gain
    return out


def ferraris(still: FaceReadings, turns: list[KnownTurn]) -> TurnsFit:
    """Bias, g-sensitivity and ``A`` from the six faces and the turns (Ferraris, imucal's order).

    - ``b``: the mean of every still sample (imucal ``b_g``; the Earth's rate is ignored).
    - ``G``: :func:`g_sensitivity` (Eq. 9).
    - ``W_k = Σ (raw - b - G a) dt`` over turn k (Eqs. 13-14; imucal sums and divides by the rate),
      ``a`` the accelerometer in g by :func:`accelerometer_in_g`.
    - ``A Θ = W`` with ``Θ_k = θ_k e_k`` (Eq. 15): ``A = W Θ⁺`` (exact for three turns).

    Uncertainty from the noise at rest ``σ`` (pooled over the faces, each about its own mean):
    ``σ_b = σ / √N``; ``W`` carries the errors of ``b`` and ``G`` and the turn's own noise
    (:func:`_variance`).
    """
    acc_means = np.array([a.mean(axis=0) for a in still.acc])
    gyr_means = np.array([g.mean(axis=0) for g in still.gyr])
    acc_offset, acc_matrix = accelerometer_in_g(acc_means)
    resting = np.concatenate(still.gyr)
    bias: FloatArray = resting.mean(axis=0)
    sens = g_sensitivity(gyr_means)
    deviations = np.concatenate([g - m for g, m in zip(still.gyr, gyr_means, strict=True)])
    dof = max(len(resting) - len(still.gyr), 1)
    noise: FloatArray = np.sqrt((deviations**2).sum(axis=0) / dof)
    bias_se: FloatArray = noise / np.sqrt(len(resting))
    integrated = np.empty((3, len(turns)))
    gravity = np.empty((len(turns), 3))  # each turn's mean accelerometer reading, g
    for k, t in enumerate(turns):
        a = (t.acc - acc_offset) @ acc_matrix.T
        rate = t.gyr - bias - a @ sens.T
        integrated[:, k] = (rate * t.dt[:, None]).sum(axis=0)
        gravity[k] = a.mean(axis=0)
    theta = np.array([t.axis * t.angle_deg for t in turns]).T  # (3, k)
    pinv = np.linalg.pinv(theta)  # (k, 3)
    a_matrix = integrated @ pinv
    matrix = np.asarray(np.linalg.inv(a_matrix), dtype=np.float64)
    se = np.sqrt(_variance(still, turns, gravity, pinv, noise))
    fixed = matrix @ integrated
    measured = np.einsum("ik,ki->k", fixed, np.array([t.axis for t in turns]))
    residual = np.linalg.norm(fixed - theta, axis=0)
    solution = Solution("ferraris-turns", bias, matrix, bias_se, np.diag(se).copy())
    return TurnsFit(
        solution,
        sens,
        acc_offset,
        acc_matrix,
        integrated,
        measured,
        residual,
        se * (1 - np.eye(3)),
        noise,
    )


def _variance(
    still: FaceReadings, turns: list[KnownTurn], gravity: FloatArray, pinv: FloatArray, noise: FloatArray
) -> FloatArray:
    """The variance of each element of ``A = W Θ⁺`` from white noise ``σ_i`` per axis. Each face
    mean ``m_f`` errs by ``σ/√n_f``; ``b`` is their sample-weighted mean and ``G e_j`` half the
    +j face less the -j face, so ``δW_k = -T_k Σ_f c_kf δm_f + ε_k`` with ``T_k`` the turn's
    seconds, ``c_kf = n_f/N ± ā_kj/2`` (``ā_k`` its mean gravity in g, ``j`` the face's axis) and
    ``ε_k`` the turn's own noise, variance ``σ² Σ dt²``. Then ``δA_ij = Σ_k δW_ik Θ⁺_kj``."""
    counts = np.array([len(g) for g in still.gyr], dtype=np.float64)
    seconds = np.array([t.dt.sum() for t in turns])
    squares = np.array([(t.dt**2).sum() for t in turns])
    signs = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    axis_of = np.array([0, 0, 1, 1, 2, 2])
    c = counts[None, :] / counts.sum() + signs[None, :] * gravity[:, axis_of] / 2.0  # (k, 6)
    through = (seconds[:, None] * c).T @ pinv  # (6, 3): face f's effect on column j
    per_axis = ((through**2) / counts[:, None]).sum(axis=0) + squares @ pinv**2  # (3,)
    out: FloatArray = (noise**2)[:, None] * per_axis[None, :]
    return out
