"""A gyroscope's offset, gains and cross-axis terms from known rates: a rate table, or a record
player at 33⅓ and 45 rpm. numpy only.

- **Steady runs** (:func:`steady_runs`). On a platter turning at a constant rate, the unit fixed
  to it, the gyroscope reads one constant vector (the spin axis in its axes, times the rate).
  Its readings are cut into windows; a window is steady when its spread (the RMS of its
  components' standard deviations) is within STEADY_SIGMAS times the quietest windows' spread
  (the noise floor: the 10th percentile) or STEADY_SHARE of its own magnitude (a platter's wow);
  consecutive steady windows whose means agree within the same bound are one run. The platter's
  spin-up and spin-down and the unit's handling between orientations change the reading within
  a window and are left out, named by rows.
- **The fit** (:func:`fit_rates`), over the runs' means ``m_k`` at their stated rates ``r_k``:
  ``corrected = M (raw − b)``. A run at rest (rate 0) says ``M (m − b) = 0``, each component with
  the mean's own standard error; a run whose orientation is unknown says ``|M (m − b)| = |r|``
  (the magnitude fit: ``M`` symmetric, as the ellipsoid's, its rotation not observable); a run
  labelled with the face that pointed up (the platter counter-clockwise seen from above: the
  rate along that face) says ``M (m − b) = r · face``, which fixes the full ``M``. The spinning
  runs' scatter about the fit (a platter's speed error, the unit's wobble) is not known in
  advance: it is the residuals' own, so the covariance holds it (Gauss-Newton, the weights of
  the spinning runs the inverse of their residual variance, iterated).
- **Outliers**: a run off the fit (the unit slipped, the platter at another speed) is left out
  by core.robust's trimmed refit, the same rule as a magnetometer's samples, its floor 1 % of the
  largest rate.
- **Scale factors** (:func:`scale_factors`, IEEE Std 952-1997 and 1431-2004, the rate transfer
  test): for each axis, its scale factor at each rate (the runs whose spin axis lies within
  AXIS_DEG of it), the least-squares scale factor through all of them, the non-linearity (the
  largest departure from that line, ppm of the largest rate) and, where the axis turned both
  ways, the asymmetry (ppm of the mean scale factor).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import robust
from tumblecal_cli.core.alignment import inverse
from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.errors import CaptureRejected

#: A window is steady when its spread is within this many times the noise floor ...
STEADY_SIGMAS = 4.0
#: ... or this share of its mean magnitude (a platter's speed varies by a few tenths of a percent).
STEADY_SHARE = 0.01
#: A run's magnitude this close to its stated rate (as a share, after the rough gain) is at it.
AT_RATE = 0.1
#: The largest rate over this is the reference of core.robust's floor (its 5 % of it: 1 % of the rate).
FLOOR_SHARE = 5.0
#: A run whose spin axis is within this of a sensor axis gives that axis's scale factor.
AXIS_DEG = 10.0


@dataclass(frozen=True)
class Run:
    """A steady stretch of readings: samples ``first``..``last`` (inclusive, 0-based), their
    mean, and the standard error of each component of the mean."""

    first: int
    last: int
    mean: FloatArray  # (3,)
    stderr: float

    @property
    def samples(self) -> int:
        return self.last - self.first + 1


def steady_runs(values: FloatArray, window: int, min_samples: int) -> list[Run]:
    """The steady runs of ``values`` (n, 3) (module docstring), each of ``min_samples`` or more."""
    v = np.asarray(values, dtype=np.float64)
    window = max(int(window), 2)
    count = len(v) // window
    if count == 0:
        return []
    parts = v[: count * window].reshape(count, window, 3)
    means = parts.mean(axis=1)
    spreads = np.sqrt(parts.var(axis=1).mean(axis=1))
    floor = max(float(np.percentile(spreads, 10)), 1e-300)
    allowed = np.maximum(STEADY_SIGMAS * floor, STEADY_SHARE * np.linalg.norm(means, axis=1))
    steady = spreads <= allowed
    runs: list[tuple[int, int]] = []
    for k in np.flatnonzero(steady):
        if runs and runs[-1][1] == k - 1 and np.linalg.norm(means[k] - means[k - 1]) <= allowed[k]:
            runs[-1] = (runs[-1][0], int(k))
        else:
            runs.append((int(k), int(k)))
    out = []
    for a, b in runs:
        first, last = a * window, (b + 1) * window - 1
        if last - first + 1 < min_samples:
            continue
        part = v[first : last + 1]
        out.append(Run(first, last, part.mean(axis=0), float(np.sqrt(part.var(axis=0).mean() / len(part)))))
    return out


@dataclass(frozen=True)
class SpinRun:
    """A run given to the fit: its mean (raw), the standard error of each component, the rate it
    turned at (output units; signed: negative clockwise seen from above; 0 at rest), and the unit
    vector of the face that pointed up (None: the orientation is unknown)."""

    mean: FloatArray
    stderr: float
    rate: float
    face: FloatArray | None = None


@dataclass(frozen=True)
class RateFit:
    """The fitted offset (raw units) and M, the 1-sigma of the offset, of A's diagonal (the gains)
    and of A's off-diagonal terms, the 12x12 covariance of (b, A row-major), each run's residual
    (output units; a labelled or resting run's the length of its vector residual), the spinning
    runs' scatter (output units), the runs the trimmed refit kept, and whether M is full (a
    labelled run fixed its rotation) or symmetric."""

    offset: FloatArray
    matrix: FloatArray
    offset_se: FloatArray
    gain_se: FloatArray
    cross_se: FloatArray
    covariance: FloatArray
    residuals: FloatArray
    scatter: float
    kept: BoolArray
    full: bool


def _params_to_matrix(theta: FloatArray, full: bool) -> tuple[FloatArray, FloatArray]:
    b = theta[:3]
    if full:
        return b, theta[3:12].reshape(3, 3)
    s = theta[3:9]
    return b, np.array([[s[0], s[3], s[4]], [s[3], s[1], s[5]], [s[4], s[5], s[2]]])


def _basis(face: FloatArray) -> FloatArray:
    """Rows: ``face`` and two unit vectors across it (a labelled run's residual along the spin
    axis, where the platter's speed error lies, and across it)."""
    other = np.array([1.0, 0.0, 0.0]) if abs(face[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(face, other)
    u /= np.linalg.norm(u)
    return np.array([face, u, np.cross(face, u)])


#: The kinds of residual, each with a spread of its own: a run at rest (its mean's standard error),
#: along a spin axis (a magnitude, or a labelled run's part along its face: the rate's error), and
#: across it (a labelled run's: the unit's placement on the platter).
REST, ALONG, ACROSS = 0, 1, 2


def _kinds(runs: list[SpinRun]) -> NDArray[np.int8]:
    out: list[int] = []
    for r in runs:
        out += [REST] * 3 if r.rate == 0 else [ALONG, ACROSS, ACROSS] if r.face is not None else [ALONG]
    return np.asarray(out, dtype=np.int8)


def _residuals(theta: FloatArray, runs: list[SpinRun], full: bool) -> FloatArray:
    b, m = _params_to_matrix(theta, full)
    out: list[float] = []
    for r in runs:
        v = m @ (r.mean - b)
        if r.rate == 0:
            out.extend(v)
        elif r.face is not None:
            out.extend(_basis(r.face) @ (v - r.rate * r.face))
        else:
            out.append(float(np.linalg.norm(v)) - abs(r.rate))
    return np.asarray(out, dtype=np.float64)


def _jacobian(theta: FloatArray, runs: list[SpinRun], full: bool, sigma: FloatArray) -> FloatArray:
    jac = np.empty((len(sigma), len(theta)))
    for j in range(len(theta)):
        h = 1e-7 * max(1.0, abs(float(theta[j])))
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        jac[:, j] = (_residuals(up, runs, full) - _residuals(down, runs, full)) / (2 * h) / sigma
    return jac


def _scatters(raw: FloatArray, kinds: NDArray[np.int8], params: int, se: FloatArray) -> FloatArray:
    """Each residual's spread: the rest's own standard error; along and across a spin axis, the
    RMS of that kind's residuals over its share of the degrees of freedom, times the Student
    factor ``dof / (dof - 2)`` in variance (a spread estimated from few runs is itself uncertain)."""
    sigma = se.copy()
    spinning = int((kinds != REST).sum())
    for kind in (ALONG, ACROSS):
        part = kinds == kind
        if not part.any():
            continue
        dof = max(float(part.sum()) - params * float(part.sum()) / max(spinning, 1), 1.0)
        variance = float((raw[part] ** 2).sum()) / dof * (dof / (dof - 2.0) if dof > 4.0 else 3.0)
        sigma[part] = np.maximum(np.sqrt(variance), se[part])
    return sigma


def _solve(runs: list[SpinRun], full: bool, start: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Gauss-Newton (numeric Jacobian) on the weighted residuals; the parameters, the covariance of
    the parameters, and the spinning runs' scatter along their spin axes."""
    kinds = _kinds(runs)
    se = np.concatenate([[max(r.stderr, 1e-300)] * k for r, k in zip(runs, _sizes(runs), strict=True)])
    theta = start.copy()
    params = len(theta) - (3 if (kinds == REST).any() else 0)
    sigma = np.where(kinds == REST, se, max(float(np.median(se)), 1e-300))
    for _ in range(40):
        res = _residuals(theta, runs, full) / sigma
        step = np.linalg.lstsq(_jacobian(theta, runs, full, sigma), -res, rcond=None)[0]
        theta = theta + step
        sigma = _scatters(_residuals(theta, runs, full), kinds, params, se)
        if np.abs(step).max() < 1e-12 * max(1.0, float(np.abs(theta).max())):
            break
    jac = _jacobian(theta, runs, full, sigma)
    along = kinds == ALONG
    scatter = float(np.sqrt(np.mean(_residuals(theta, runs, full)[along] ** 2))) if along.any() else 0.0
    return theta, inverse(jac.T @ jac), scatter


def _sizes(runs: list[SpinRun]) -> list[int]:
    return [3 if (r.rate == 0 or r.face is not None) else 1 for r in runs]


def _start(runs: list[SpinRun], full: bool) -> FloatArray:
    """b from the runs at rest (else 0), M a scale from the spinning runs' magnitudes."""
    rest = [r.mean for r in runs if r.rate == 0]
    b = np.mean(rest, axis=0) if rest else np.zeros(3)
    ratios = [abs(r.rate) / max(float(np.linalg.norm(r.mean - b)), 1e-300) for r in runs if r.rate != 0]
    k = float(np.median(ratios)) if ratios else 1.0
    return np.concatenate([b, (np.eye(3) * k).ravel() if full else [k, k, k, 0.0, 0.0, 0.0]])


def fit_rates(given: list[SpinRun], *, trim: bool = True) -> RateFit:
    """The offset and M of ``runs`` (module docstring), runs off the fit left out by core.robust
    (``trim`` False: every run kept).
    The readings are fitted divided by their rough gain (raw per output unit, from the spinning
    runs' magnitudes), so that the offset's and M's columns of the Jacobian are of one size
    whatever the raw units (counts: thousands a rad/s), and scaled back after."""
    spinning = [abs(r.rate) / max(float(np.linalg.norm(r.mean)), 1e-300) for r in given if r.rate != 0]
    unit = 1.0 / float(np.median(spinning)) if spinning else 1.0  # raw per output unit, roughly
    runs = [SpinRun(r.mean / unit, r.stderr / unit, r.rate, r.face) for r in given]
    full = any(r.face is not None for r in runs)
    largest = max(abs(r.rate) for r in runs)
    index = np.arange(len(runs), dtype=np.float64)[:, None]
    points = np.hstack([np.array([r.mean for r in runs]), index])  # each run's mean and which run it is

    def fit(kept: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        chosen = [runs[int(k)] for k in kept[:, 3]]
        if sum(_sizes(chosen)) < (12 if full else 9) + 1:
            raise CaptureRejected(
                f"{len(chosen)} of {len(runs)} runs agree with one calibration, too few to fit: the others lie off "
                "every fit (a rate or a face that is not the run's?)",
                code="spin.runs",
            )
        return _solve(chosen, full, _start(chosen, full))

    def residuals(found: tuple[FloatArray, FloatArray, float], at: FloatArray) -> FloatArray:
        chosen = [runs[int(k)] for k in at[:, 3]]
        raw, sizes = _residuals(found[0], chosen, full), _sizes(chosen)
        edges = np.cumsum([0, *sizes])
        return np.array([np.linalg.norm(raw[a:b]) for a, b in itertools.pairwise(edges)])

    # the floor a run must be off by to be left out: robust.FLOOR of a fifth of the largest rate, 1 %
    # of it (a platter's speed varies by tenths of a percent; a run 3 % off is at another speed)
    every = np.ones(len(runs), dtype=bool)
    if trim:
        done = robust.trimmed(points, largest / FLOOR_SHARE, fit, residuals, every)
    else:  # every run kept: plain least squares
        done = robust.TrimmedFit(fit(points), every, (), float("inf"), float("nan"))
    theta, cov_theta, scatter = done.fit
    b, m = _params_to_matrix(theta, full)
    cov = _covariance_of_a(theta, cov_theta, full) * unit**2  # b and A scale with the readings
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    a_sd = sd[3:].reshape(3, 3)
    return RateFit(
        offset=b * unit,
        matrix=m / unit,
        offset_se=sd[:3],
        gain_se=np.diag(a_sd).copy(),
        cross_se=a_sd * (1 - np.eye(3)),
        covariance=cov,
        residuals=residuals(done.fit, points),
        scatter=scatter,
        kept=done.kept,
        full=full,
    )


def _covariance_of_a(theta: FloatArray, cov_theta: FloatArray, full: bool) -> FloatArray:
    """The covariance of (b, A = M⁻¹ row-major) from that of the parameters (the Jacobian of the
    map, numerically)."""

    def to_a(t: FloatArray) -> FloatArray:
        b, m = _params_to_matrix(t, full)
        return np.concatenate([b, np.linalg.inv(m).ravel()])

    base = to_a(theta)
    jac = np.empty((12, len(theta)))
    for j in range(len(theta)):
        h = 1e-7 * max(1.0, abs(float(theta[j])))
        up = theta.copy()
        up[j] += h
        jac[:, j] = (to_a(up) - base) / h
    out: FloatArray = jac @ cov_theta @ jac.T
    return out


@dataclass(frozen=True)
class AxisScale:
    """One axis's scale factors (raw per output unit) at each rate (output units, signed), the
    least-squares scale factor, the non-linearity (ppm of the largest rate's output) and the
    asymmetry (ppm of the mean scale factor; None when the axis did not turn both ways)."""

    axis: str
    rates: tuple[float, ...]
    factors: tuple[float, ...]
    least_squares: float
    nonlinearity_ppm: float
    asymmetry_ppm: float | None


def scale_factors(runs: list[SpinRun], fit: RateFit) -> list[AxisScale]:
    """Each axis's scale factors (module docstring) over the kept spinning runs whose corrected
    spin axis is within AXIS_DEG of it; an axis with fewer than two rates is left out."""
    out = []
    for i, name in enumerate("xyz"):
        rates, readings = [], []
        for r, kept in zip(runs, fit.kept, strict=True):
            if not kept or r.rate == 0:
                continue
            v = fit.matrix @ (r.mean - fit.offset)
            u = v / max(float(np.linalg.norm(v)), 1e-300)
            if abs(u[i]) < np.cos(np.radians(AXIS_DEG)):
                continue
            rate = abs(r.rate) * float(np.sign(u[i]))  # the rate about this axis, as the fit says it turned
            rates.append(rate)
            readings.append(float(r.mean[i] - fit.offset[i]))
        if len({round(x, 9) for x in rates}) < 2:
            continue
        x, y = np.array(rates), np.array(readings)
        slope = float((x @ y) / (x @ x))  # through the bias: the output at rest is the offset
        largest = float(np.abs(y).max())
        nonlinear = float(np.abs(y - slope * x).max()) / largest * 1e6 if largest > 0 else 0.0
        plus, minus = x > 0, x < 0
        asym = None
        if plus.any() and minus.any():
            sp = float((x[plus] @ y[plus]) / (x[plus] @ x[plus]))
            sm = float((x[minus] @ y[minus]) / (x[minus] @ x[minus]))
            asym = (sp - sm) / ((sp + sm) / 2) * 1e6
        factors = tuple(float(yy / xx) for xx, yy in zip(x, y, strict=True))
        out.append(AxisScale(name, tuple(float(v) for v in x), factors, slope, nonlinear, asym))
    return out
