"""Gyroscope scale and misalignment from hand turns between still poses, gravity the reference.
numpy only.

Tedaldi et al. 2014 (docs/sources.md), sect. III-C: between two still
poses the gyroscope, integrated, must carry the gravity direction measured before onto the one
measured after. In tumblecal's model ``ω = M (raw - b)`` (deg/s), each rotation's quaternion is
the ordered product of the per-sample rotations ``exp(ω dt / 2)`` (body frame, right-multiplied:
no Euler angles), and ``u_after ≈ R(q)ᵀ u_before`` for the unit gravity directions ``u`` the
accelerometer calibration gives. ``M`` minimises the squared differences over all rotations
(Levenberg-Marquardt, as the sphere fit); the bias ``b`` is the still samples' mean (measured at
rest, where it is known to ``σ/√N``: the rotations would only blur it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray

#: A rotation whose gravity direction the fit misses by more than this is not a rigid turn of
#: the unit (it moved during a "still" block, or the log skipped samples).
MAX_RESIDUAL_DEG = 5.0
#: Fewer rotations than this leave M (9 parameters, two constraints per rotation) too loosely fixed.
MIN_ROTATIONS = 6


@dataclass(frozen=True)
class RotationReadings:
    """The raw gyroscope readings between two still blocks, the seconds each stands for, and the
    unit gravity directions (sensor frame) measured in the block before and the block after."""

    gyr: FloatArray
    dt: FloatArray
    before: FloatArray
    after: FloatArray


@dataclass(frozen=True)
class RotationsFit:
    matrix: FloatArray  # M (3, 3): deg/s = M (raw - b)
    matrix_cov: FloatArray  # (9, 9) covariance of M row by row, from the residuals
    angle_deg: FloatArray  # (k,) each rotation's angle, as calibrated
    residual_deg: FloatArray  # (k,) the angle between predicted and measured gravity after it
    axes: FloatArray  # (k, 3) each rotation's axis, as calibrated


def qmul(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton products of (..., 4) quaternions (w, x, y, z)."""
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    out: FloatArray = np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )
    return out


def integrate(rate_dps: FloatArray, dt: FloatArray) -> FloatArray:
    """The rotation (unit quaternion) of the body rates ``rate_dps`` (n, 3) held for ``dt`` (n,)
    each: ``q = Π exp(ω_i dt_i / 2)`` in time order, multiplied pairwise (associative: log2 n
    vectorised steps instead of n)."""
    half = np.radians(rate_dps) * dt[:, None] / 2.0
    angle = np.linalg.norm(half, axis=1)
    sinc = np.where(angle > 1e-12, np.sin(angle) / np.where(angle > 1e-12, angle, 1.0), 1.0)
    q = np.column_stack([np.cos(angle), half * sinc[:, None]])
    while len(q) > 1:
        if len(q) % 2:
            q = np.vstack([q, [1.0, 0.0, 0.0, 0.0]])
        q = qmul(q[0::2], q[1::2])
    out: FloatArray = q[0] if len(q) else np.array([1.0, 0.0, 0.0, 0.0])
    return out


def rotate_into(q: FloatArray, u: FloatArray) -> FloatArray:
    """``R(q)ᵀ u``: a world-fixed direction ``u`` seen from the sensor after the rotation ``q``."""
    w, v = q[0], -q[1:]  # the conjugate rotates the vector the other way
    t = 2.0 * np.cross(v, u)
    out: FloatArray = u + w * t + np.cross(v, t)
    return out


def _residuals(m_flat: FloatArray, rotations: list[RotationReadings], bias: FloatArray) -> FloatArray:
    m = m_flat.reshape(3, 3)
    out = []
    for r in rotations:
        q = integrate((r.gyr - bias) @ m.T, r.dt)
        out.append(rotate_into(q, r.before) - r.after)
    return np.concatenate(out)


def _cost(m_flat: FloatArray, rotations: list[RotationReadings], bias: FloatArray) -> float:
    r = _residuals(m_flat, rotations, bias)
    return float(r @ r)


def start_scale(rotations: list[RotationReadings], bias: FloatArray) -> float:
    """The scalar ``s`` of ``M = s I`` that fits best, on a log grid from 1e-5 to 1e3 then refined:
    the raw units are unknown (counts, mdps, rad/s), and LM needs a start of the right size."""
    grid = np.logspace(-5, 3, 161)
    costs = [_cost((s * np.eye(3)).ravel(), rotations, bias) for s in grid]
    best = float(grid[int(np.argmin(costs))])
    fine = best * np.logspace(-0.05, 0.05, 21)
    costs = [_cost((s * np.eye(3)).ravel(), rotations, bias) for s in fine]
    return float(fine[int(np.argmin(costs))])


def fit(rotations: list[RotationReadings], bias: FloatArray) -> RotationsFit:
    """Levenberg-Marquardt on ``Σ |R(q_k(M))ᵀ u_before - u_after|²`` over the 9 entries of M,
    from :func:`start_scale`, Jacobian by central differences; covariance ``s² (JᵀJ)⁻¹`` with
    ``s²`` the residual variance (the directions' noise is not known per rotation): the squared
    residuals over ``2k - 9`` degrees of freedom, two per rotation (a difference of unit vectors
    is nearly perpendicular to them)."""
    theta = (start_scale(rotations, bias) * np.eye(3)).ravel()

    def jacobian(x: FloatArray) -> FloatArray:
        cols = []
        for j in range(9):
            h = 1e-6 * max(1e-3, float(np.abs(x).max()))
            e = np.zeros(9)
            e[j] = h
            cols.append((_residuals(x + e, rotations, bias) - _residuals(x - e, rotations, bias)) / (2 * h))
        return np.column_stack(cols)

    r = _residuals(theta, rotations, bias)
    jac = jacobian(theta)
    cost, lam = float(r @ r), 1e-3
    for _ in range(100):
        jtj, grad = jac.T @ jac, jac.T @ r
        step = np.linalg.lstsq(jtj + lam * np.diag(np.diag(jtj) + 1e-30), -grad, rcond=None)[0]
        trial = theta + step
        r_new = _residuals(trial, rotations, bias)
        new_cost = float(r_new @ r_new)
        if np.isfinite(new_cost) and new_cost <= cost:
            done = cost - new_cost <= 1e-14 * (1.0 + cost)
            theta, r, cost, lam = trial, r_new, new_cost, max(lam / 10, 1e-12)
            jac = jacobian(theta)
            if done:
                break
        else:
            lam *= 10
            if lam > 1e12:
                break
    dof = max(2 * len(rotations) - 9, 1)  # each rotation's 3 residuals hold 2 degrees of freedom (unit vectors)
    cov = np.asarray((cost / dof) * np.linalg.pinv(jac.T @ jac), dtype=np.float64)
    m = theta.reshape(3, 3)
    angles, residuals, axes = judged(rotations, bias, m)
    return RotationsFit(m, cov, angles, residuals, axes)


def judged(
    rotations: list[RotationReadings], bias: FloatArray, matrix: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Each rotation under the calibration (bias, M): its angle (degrees), the angle between the
    gravity direction it predicts after it and the one measured (degrees), and its axis."""
    angles, residuals, axes = [], [], []
    for rot in rotations:
        q = integrate((rot.gyr - bias) @ matrix.T, rot.dt)
        q = q if q[0] >= 0 else -q
        angles.append(np.degrees(2 * np.arctan2(np.linalg.norm(q[1:]), q[0])))
        axes.append(q[1:] / max(float(np.linalg.norm(q[1:])), 1e-300))
        predicted = rotate_into(q, rot.before)
        residuals.append(np.degrees(np.arctan2(np.linalg.norm(np.cross(predicted, rot.after)), predicted @ rot.after)))
    return np.array(angles), np.array(residuals), np.array(axes).reshape(-1, 3)


def gain_se(matrix: FloatArray, cov: FloatArray) -> tuple[FloatArray, FloatArray]:
    """1-sigma of A = M⁻¹ (its diagonal, and its off-diagonal terms), from M's covariance:
    ``dA = -A dM A``, so ``dA_ij = -Σ A_ik A_lj dM_kl``."""
    a = np.linalg.inv(matrix)
    jac = -np.einsum("ik,lj->ijkl", a, a).reshape(9, 9)
    var = np.einsum("pk,kl,pl->p", jac, cov, jac).reshape(3, 3)
    se = np.sqrt(np.maximum(var, 0.0))
    return np.diag(se).copy(), se * (1 - np.eye(3))
