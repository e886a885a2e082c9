"""The rotation between two sensors' axes from still blocks seen by both. numpy only.

- **Magnetometer to accelerometer.** At rest the accelerometer measures "up" and the
  magnetometer the Earth's field; the angle between them is 90° plus the dip (inclination) in
  every orientation. With calibrated unit directions ``g_i`` (accelerometer frame) and ``m_i``
  (magnetometer frame) the rotation ``R`` (``v_acc = R v_mag``) and ``c = -sin(dip)`` minimise
  ``Σ w_i (g_i · R m_i - c)²`` (Gauss-Newton on a rotation vector, each residual weighted by
  the blocks' noise). A small rotation ``δφ`` changes
  each residual by ``δφ · (R m_i × g_i)``: the normal of the plane of gravity and the field, i.e.
  the horizontal east-west axis seen from the sensor in block ``i``. All three components of
  ``R`` are observable when those axes span space: the unit turned about more than the vertical.
- **Several IMUs.** Two sensors of one kind see the same vector in each still block: the
  rotation ``R`` (``v_ref = R v_other``) is Wahba's problem, solved by the SVD of
  ``Σ w_i ref_i other_iᵀ`` (Markley 1988). Its covariance is the inverse of the Fisher matrix
  ``Σ w_i (|v_i|² I - v_i v_iᵀ)`` (``v_i = R other_i``): rotation about a direction every block
  shares is not observable.

- **Several gyroscopes.** At rest a gyroscope reads only its bias; turning, two gyroscopes
  read the same angular rate: Wahba's problem again, over the rate vectors of the samples where
  the unit turns (``rest`` finds a gyroscope's bias and noise from its rates alone,
  ``turn_axes`` whether the turns determine the rotation).
- **Consistency.** The RMS difference of two sensors' corrected vectors, with its 1-sigma and
  its noise bias (``consistency``).

Every covariance is from the blocks' stated noise, scaled up by the reduced chi-square when
the residuals are larger than that noise explains (never down).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tumblecal_cli.core import axes as signed
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.axes import Axes

#: Fewer blocks than this (at distinct orientations) leave the rotation and the dip too loose.
MIN_BLOCKS = 4
#: A rotation component whose 1-sigma exceeds this many degrees is not observable from the blocks
#: (they share a direction: the unit turned only about the vertical, or not at all).
MAX_SIGMA_DEG = 5.0


@dataclass(frozen=True)
class Fitted:
    """A rotation (``v_ref = matrix · v_other``), its rotation vector (degrees, the axis times
    the angle) with covariance (degrees²), the angle and its 1-sigma, the reduced chi-square of
    the fit (1 when the blocks' noise explains the residuals), and the residual per block.

    ``axes``: the signed permutation (core.axes) the matrix is within signed.NEAR_DEG of, when it
    is not the identity, or when the matrix mirrors (det −1, which no rotation is); the rotation
    vector and angle are then those of the rest, ``axes.matrixᵀ · matrix``."""

    matrix: FloatArray  # (3, 3)
    vector_deg: FloatArray  # (3,)
    cov_deg2: FloatArray  # (3, 3)
    angle_deg: float
    angle_sigma_deg: float
    chi2: float
    residuals: FloatArray  # (k,)
    axes: Axes | None = None

    @property
    def sigma_deg(self) -> FloatArray:
        """(3,) the 1-sigma of each rotation-vector component."""
        out: FloatArray = np.sqrt(np.maximum(np.diag(self.cov_deg2), 0.0))
        return out

    def observable(self) -> bool:
        """Whether every component is determined to within MAX_SIGMA_DEG."""
        return bool(np.all(np.isfinite(self.sigma_deg)) and np.all(self.sigma_deg <= MAX_SIGMA_DEG))

    def loosest(self) -> tuple[FloatArray, float]:
        """The axis (unit, in the reference sensor's axes) the rotation is least determined about,
        and its 1-sigma (degrees): the covariance's largest eigenvector (``vector_deg`` is in the
        reference's axes, the residual rotation's covariance turned back by ``axes``)."""
        cov = self.cov_deg2 if self.axes is None else self.axes.matrix @ self.cov_deg2 @ self.axes.matrix.T
        values, vectors = np.linalg.eigh((cov + cov.T) / 2.0)
        return vectors[:, -1], float(np.sqrt(max(float(values[-1]), 0.0)))


@dataclass(frozen=True)
class MagAlignment:
    """The magnetometer-to-accelerometer rotation, the dip (inclination, degrees, positive down)
    with its 1-sigma, and per block: the dip before and after alignment and the heading change
    (degrees) alignment makes, i.e. the heading error it removes."""

    rotation: Fitted
    dip_deg: float
    dip_sigma_deg: float
    dip_before: FloatArray  # (k,)
    dip_after: FloatArray  # (k,)
    heading_error: FloatArray  # (k,)


def exp_map(phi: FloatArray) -> FloatArray:
    """The rotation matrix of the rotation vector ``phi`` (radians; Rodrigues' formula)."""
    angle = float(np.linalg.norm(phi))
    k = np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])
    if angle < 1e-12:
        small: FloatArray = np.eye(3) + k
        return small
    out: FloatArray = np.eye(3) + np.sin(angle) / angle * k + (1 - np.cos(angle)) / angle**2 * (k @ k)
    return out


def log_map(matrix: FloatArray) -> FloatArray:
    """The rotation vector (radians) of a rotation matrix (its angle below 180°)."""
    cos = np.clip((np.trace(matrix) - 1.0) / 2.0, -1.0, 1.0)
    angle = float(np.arccos(cos))
    w = np.array([matrix[2, 1] - matrix[1, 2], matrix[0, 2] - matrix[2, 0], matrix[1, 0] - matrix[0, 1]]) / 2.0
    if angle < 1e-9:
        return w
    out: FloatArray = w * angle / np.sin(angle)
    return out


def unit(v: FloatArray) -> FloatArray:
    out: FloatArray = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


def inverse(information: FloatArray) -> FloatArray:
    """The covariance of an information (Fisher) matrix: a direction it does not determine (an
    eigenvalue below 1e-12 of the largest) gets a variance of 1e200, not the 0 a pseudo-inverse
    gives it."""
    values, vectors = np.linalg.eigh((information + information.T) / 2.0)
    floor = 1e-12 * max(float(values.max()), 1e-300)
    inv = np.where(values > floor, 1.0 / np.where(values > floor, values, 1.0), 1e200)
    out: FloatArray = (vectors * inv) @ vectors.T
    return out


def _fitted(matrix: FloatArray, cov_rad: FloatArray, chi2: float, residuals: FloatArray) -> Fitted:
    """A Fitted from a rotation and its small-angle covariance (radians², left perturbation):
    near a signed permutation P (or mirroring), the rest ``Pᵀ R`` (whose left perturbation is
    ``Pᵀ δφ``: its covariance ``Pᵀ C P``) is what the vector and the angle describe."""
    nearest, apart = signed.nearest(matrix)
    axes = None
    if nearest.mirrors or (not nearest.identity and apart <= signed.NEAR_DEG):
        axes = nearest
        matrix_rest = nearest.matrix.T @ matrix
        cov_rad = nearest.matrix.T @ cov_rad @ nearest.matrix
        return replace(_fitted_rotation(matrix_rest, cov_rad, chi2, residuals), matrix=matrix, axes=axes)
    return _fitted_rotation(matrix, cov_rad, chi2, residuals)


def _fitted_rotation(matrix: FloatArray, cov_rad: FloatArray, chi2: float, residuals: FloatArray) -> Fitted:
    phi = log_map(matrix)
    angle = float(np.linalg.norm(phi))
    axis = phi / angle if angle > 1e-12 else np.zeros(3)
    cov = np.degrees(np.degrees(cov_rad))
    sigma = float(np.sqrt(max(float(axis @ cov @ axis), 0.0))) if angle > 1e-12 else float(np.sqrt(np.trace(cov)))
    return Fitted(matrix, np.degrees(phi), cov, float(np.degrees(angle)), sigma, chi2, residuals)


def wahba(ref: FloatArray, other: FloatArray, sigma: FloatArray) -> Fitted:
    """The rotation ``R`` with ``ref_i ≈ R other_i`` (both (k, 3), one row per still block, in the
    same units), each pair's per-component noise ``sigma`` (k,) (both sensors' together): Wahba's
    problem by SVD, with the covariance from the Fisher matrix (module docstring)."""
    w = 1.0 / np.asarray(sigma, dtype=np.float64) ** 2
    b = (w[:, None] * ref).T @ other  # Σ w_i ref_i other_iᵀ, without a (k, 3, 3) array: k may be a gyroscope's samples
    u, _, vt = np.linalg.svd(b)
    d = np.diag([1.0, 1.0, float(np.linalg.det(u) * np.linalg.det(vt))])
    r = u @ d @ vt
    v = other @ r.T
    diff = ref - v
    chi2_sum = float((w * (diff**2).sum(axis=1)).sum())
    dof = max(3 * len(ref) - 3, 1)
    fisher = float((w * (v**2).sum(axis=1)).sum()) * np.eye(3) - (w[:, None] * v).T @ v
    chi2 = chi2_sum / dof
    cov = inverse(fisher) * max(chi2, 1.0)
    return _fitted(r, cov, chi2, np.linalg.norm(diff, axis=1))


def _dip_residuals(g: FloatArray, m: FloatArray, r: FloatArray, c: float) -> FloatArray:
    out: FloatArray = np.einsum("ij,ij->i", g, m @ r.T) - c
    return out


def _dot_sigma(g: FloatArray, m: FloatArray, r: FloatArray, noise: tuple[FloatArray, FloatArray]) -> FloatArray:
    """The 1-sigma of ``g_i · R m_i`` from each direction's per-component noise (radians): each
    unit vector moves perpendicular to itself, so only the other's perpendicular part counts."""
    rm = m @ r.T
    dot = np.einsum("ij,ij->i", g, rm)
    across = np.maximum(1.0 - dot**2, 1e-12)  # |rm - (g·rm) g|², the same from either side
    out: FloatArray = np.sqrt(across * (noise[0] ** 2 + noise[1] ** 2))
    return out


#: The signed permutations nearest the blocks (by their residuals unrefined) that Gauss-Newton
#: refines; the others lie a quarter turn or more from the best.
STARTS = 3


def _start_cost(g: FloatArray, m: FloatArray, noise: tuple[FloatArray, FloatArray], start: FloatArray) -> float:
    """The weighted residuals' sum of squares at ``R = start``, c their mean (no step taken)."""
    dots = np.einsum("ij,ij->i", g, m @ start.T)
    w = 1.0 / _dot_sigma(g, m, start, noise) ** 2
    return float((w * (dots - np.average(dots, weights=w)) ** 2).sum())


def _gauss_newton(
    g: FloatArray, m: FloatArray, noise: tuple[FloatArray, FloatArray], start: FloatArray
) -> tuple[FloatArray, float, FloatArray, FloatArray]:
    """``(R, c)`` from ``R = start`` (an orthogonal matrix: R keeps its handedness), and the final
    weights and residuals."""
    r = start
    c = float(np.mean(np.einsum("ij,ij->i", g, m @ r.T)))
    for _ in range(50):
        w = 1.0 / _dot_sigma(g, m, r, noise) ** 2
        res = _dip_residuals(g, m, r, c)
        jac = np.column_stack([np.cross(m @ r.T, g), -np.ones(len(g))])
        step = np.linalg.lstsq(jac * np.sqrt(w)[:, None], -res * np.sqrt(w), rcond=None)[0]
        r, c = exp_map(step[:3]) @ r, c + float(step[3])
        if np.abs(step).max() < 1e-12:
            break
    w = 1.0 / _dot_sigma(g, m, r, noise) ** 2
    return r, c, w, _dip_residuals(g, m, r, c)


def mag_to_accel(g: FloatArray, m: FloatArray, g_sigma: FloatArray, m_sigma: FloatArray) -> MagAlignment:
    """The rotation ``R`` (``v_acc = R v_mag``) and the dip from still blocks: ``g`` (k, 3) the
    accelerometer's calibrated readings (up, any magnitude), ``m`` (k, 3) the magnetometer's
    calibrated readings of the same blocks, ``g_sigma`` and ``m_sigma`` (k,) each direction's
    per-component noise in radians (a block's noise over its magnitude over √samples). Gauss-
    Newton on ``(δφ, c)`` from the STARTS of the 24 signed permutations that are rotations
    (core.axes) whose unrefined residuals are least, the best fit kept: a rotation of any size.
    A mirror is not tried: ``-R`` fits as well as ``R`` with the dip's sign turned, so the blocks
    cannot tell a mirrored magnetometer from a field pointing the other way (module docstring)."""
    g, m = unit(np.asarray(g, dtype=np.float64)), unit(np.asarray(m, dtype=np.float64))
    noise = (np.asarray(g_sigma, dtype=np.float64), np.asarray(m_sigma, dtype=np.float64))
    every = [a.matrix for a in signed.every(mirrored=False)]
    first = sorted(every, key=lambda q: _start_cost(g, m, noise, q))[:STARTS]  # the nearest starts, refined
    starts = [_gauss_newton(g, m, noise, q) for q in first]
    r, c, w, res = min(starts, key=lambda found: float((found[2] * found[3] ** 2).sum()))
    jac = np.column_stack([np.cross(m @ r.T, g), -np.ones(len(g))])
    chi2 = float((w * res**2).sum()) / max(len(g) - 4, 1)
    cov = inverse(jac.T @ (w[:, None] * jac)) * max(chi2, 1.0)
    c = float(np.clip(c, -1.0, 1.0))
    dip = float(np.degrees(np.arcsin(-c)))
    dip_sigma = float(np.degrees(np.sqrt(max(cov[3, 3], 0.0)) / max(np.sqrt(1.0 - c**2), 1e-12)))
    return MagAlignment(
        rotation=_fitted(r, cov[:3, :3], chi2, np.degrees(np.abs(res))),
        dip_deg=dip,
        dip_sigma_deg=dip_sigma,
        dip_before=dips(g, m),
        dip_after=dips(g, m @ r.T),
        heading_error=heading_change(g, m, m @ r.T),
    )


def dips(g: FloatArray, m: FloatArray) -> FloatArray:
    """Each block's dip (degrees, positive when the field points below the horizontal)."""
    out: FloatArray = np.degrees(np.arcsin(np.clip(-np.einsum("ij,ij->i", unit(g), unit(m)), -1.0, 1.0)))
    return out


def heading_change(g: FloatArray, before: FloatArray, after: FloatArray) -> FloatArray:
    """The signed angle (degrees) about the vertical between the horizontal parts of the field
    ``before`` and ``after`` alignment, per block: how far a tilt-compensated heading moves."""
    up = unit(g)

    def horizontal(m: FloatArray) -> FloatArray:
        return unit(m - np.einsum("ij,ij->i", m, up)[:, None] * up)

    h0, h1 = horizontal(before), horizontal(after)
    sin = np.einsum("ij,ij->i", np.cross(h0, h1), up)
    out: FloatArray = np.degrees(np.arctan2(sin, np.einsum("ij,ij->i", h0, h1)))
    return out


@dataclass(frozen=True)
class Consistency:
    """How far two sensors' corrected readings differ: ``rms``, the RMS over the vectors of
    ``|ref_i - R other_i|`` as read; ``unbiased``, the same with the noise's share taken out
    (what noiseless readings would give); ``sigma``, the 1-sigma of either; ``noise``, the RMS
    the noise alone would give (``sqrt(3 mean(s_i²))``)."""

    rms: float
    unbiased: float
    sigma: float
    noise: float


def consistency(
    ref: FloatArray, other: FloatArray, matrix: FloatArray | None = None, noise: FloatArray | None = None
) -> Consistency:
    """The RMS over vectors of ``|ref_i - R other_i|`` (``R`` the identity when None, else fitted
    to these vectors), and its uncertainty from ``noise`` (k,), each difference's per-component
    1-sigma (both sensors' together; 0 when None). With ``d_i = d0_i + e_i``, the mean square
    ``C² = mean |d_i|²`` is biased up by ``b = (3k - p) mean(s_i²) / k`` (``p`` = 3 when ``R``
    was fitted, which absorbs three of the noise's degrees of freedom) and varies by
    ``Σ (4 s_i² |d0_i|² + 6 s_i⁴) / k²``; ``sqrt(C² - b)`` is the unbiased figure, and its
    1-sigma that variance over ``2 C`` (delta method), or about its fourth root when the figure
    is within the noise."""
    v = other if matrix is None else other @ matrix.T
    d2 = ((ref - v) ** 2).sum(axis=1)
    k = max(len(d2), 1)
    s2 = np.zeros(len(d2)) if noise is None else np.asarray(noise, dtype=np.float64) ** 2
    mean_square = float(np.mean(d2)) if len(d2) else 0.0
    bias = (3.0 * k - (0.0 if matrix is None else 3.0)) * float(np.sum(s2)) / k**2
    unbiased = float(np.sqrt(max(mean_square - bias, 0.0)))
    true2 = np.maximum(d2 - 3.0 * s2, 0.0)
    var = float((4.0 * s2 * true2 + 6.0 * s2**2).sum()) / k**2
    sigma = float(np.sqrt(var)) / (2.0 * max(unbiased, var**0.25 / 2.0)) if var > 0 else 0.0
    floor = float(np.sqrt(3.0 * np.mean(s2))) if len(d2) else 0.0
    return Consistency(float(np.sqrt(mean_square)), unbiased, sigma, floor)


#: A gyroscope's sample counts as turning when its rate exceeds this many times the
#: gyroscope's per-component noise at rest.
TURN_SIGMAS = 10.0
#: Samples per window when looking for a gyroscope at rest.
REST_WINDOW = 32


@dataclass(frozen=True)
class Rest:
    """A gyroscope at rest: its level (the bias, in its readings' units), the per-component
    1-sigma of one sample, and how many samples it was measured from."""

    level: FloatArray  # (3,)
    noise: float
    samples: int


def rest(rates: FloatArray, window: int = REST_WINDOW) -> Rest | None:
    """Where a gyroscope rests, from its rates (n, 3) alone (``window`` samples per window, fewer
    in a log shorter than four windows): the noise of one sample is first
    estimated from adjacent samples' differences (robustly: 1.4826 · median |Δ| / √2, which a
    smooth turn barely moves); windows of ``window`` samples whose spread is within 1.5× that
    are quiet (at rest, or turning at a steady rate); the level is the median of the quiet
    windows' means, and the windows whose mean is within 5 standard errors of it are at rest.
    None when no window is (the gyroscope never rests)."""
    v = np.asarray(rates, dtype=np.float64)
    window = max(min(window, len(v) // 4), 2)  # a short log: four windows at least
    n = len(v) // window * window
    if n == 0:
        return None
    step = 1.4826 * float(np.median(np.abs(np.diff(v, axis=0)))) / np.sqrt(2.0) if len(v) > 1 else 0.0
    parts = v[:n].reshape(-1, window, 3)
    means, spreads = parts.mean(axis=1), np.sqrt(parts.var(axis=1).mean(axis=1))
    quiet = spreads <= 1.5 * max(step, 1e-300)
    if not quiet.any():
        return None
    level = np.median(means[quiet], axis=0)
    near = quiet & (np.abs(means - level).max(axis=1) <= 5.0 * max(step, 1e-300) / np.sqrt(window))
    if not near.any():
        return None
    still = parts[near].reshape(-1, 3)
    level = still.mean(axis=0)
    return Rest(level, float(np.sqrt(np.mean(still.var(axis=0)))), len(still))


def turn_axes(rates: FloatArray, noise: float) -> int:
    """About how many independent axes the turns in ``rates`` (n, 3) went: the directions of
    the rates' second-moment matrix whose RMS rate exceeds TURN_SIGMAS × ``noise``."""
    v = np.asarray(rates, dtype=np.float64)
    if len(v) == 0:
        return 0
    values = np.linalg.eigvalsh(v.T @ v / len(v))
    return int(np.count_nonzero(np.sqrt(np.maximum(values, 0.0)) > TURN_SIGMAS * noise))
