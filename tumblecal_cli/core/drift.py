"""Temperature drift: fit offset and gain drift against temperature, and correct each row at its
own temperature. numpy only.

Model (docs/commands/thermal.md), per axis j, with d = T - T_ref::

    offset_j(T) = b_j + sum_k beta_jk d^k                      k = 1..order, raw units
    gain_j(T)   = g_j (1 + sum_k gamma_jk d^k)                 relative change of A's row j
    corrected   = M @ ((raw - offset(T)) / (1 + Gamma(T)))     Gamma_j(T) = sum_k gamma_jk d^k

``b``, ``g`` and ``M`` are the base calibration's (made at T_ref), so the drift polynomials have no
constant term: the drift is zero at T_ref. Scaling row j of A by (1 + Gamma_j) is
``inv(diag(1 + Gamma) A) = M diag(1 / (1 + Gamma))``, the last line. The offset-drift form is the one
ArduPilot and PX4 use for their own thermal calibrations (a polynomial of order 3 at most in the
temperature difference from a reference, ``AP_InertialSensor_tempcal.cpp`` ``polynomial_eval``;
PX4 ``TemperatureCompensation.cpp`` ``calc_thermal_offsets_3D``: docs/sources.md), and like both,
a temperature outside the calibrated range is clamped to its nearest end, never extrapolated.

Fit. A still pose with face direction u (|u| = 1) reads on axis j, as the temperature changes,
``raw_j(T) = c_pj + sum_k beta_jk d^k + u_j G_j sum_k gamma_jk d^k`` with ``G_j = g_j reference``
(the gravity term of the linearised model, Vitali 2018 eqs. 1-3 with a gain that drifts) and
``c_pj`` the pose's own constant (its tilt, cross-axis terms: anything that does not change with
temperature). Offset and gain drift separate only where the axis is seen in two orientations
(u_j takes two values: up and down, or up and level); where every pose sees it the same way up,
the gain drift is folded into the offset drift (exact for that orientation only), and where it is
always level its gain drift is not observed (and does not matter there).

Weights: every (pose, temperature interval) counts once, whatever the dwell: the samples of each
pose are averaged per interval and the cells are fitted with equal weights. Uncertainties are the
heteroscedasticity-consistent (sandwich, HC0) standard errors of weighted least squares (White
1980, Econometrica 48(4), eq. 3), so residual hysteresis widens them rather than being ignored.
Order ``auto`` is chosen by cross-validation over temperature: the range is cut into FOLDS bands,
each band is predicted from a fit to the others, and the lowest order whose prediction error is
within AUTO_TOLERANCE of the best is taken (the "one standard error" spirit of Hastie et al.
2009, The Elements of Statistical Learning, 2nd ed., sect. 7.10).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import FloatArray

ORDERS = (1, 2, 3)
#: Cross-validation bands over the temperature range.
FOLDS = 5
#: auto takes the lowest order whose cross-validated error is within this factor of the best.
AUTO_TOLERANCE = 1.10
#: The temperature interval a cell spans: 1 °C, finer when the swing has fewer than 40 of them.
CELL_DEGREES = 1.0
MIN_CELLS = 40
#: Each order needs this much more swing than the one below (on top of --min-swing for order 1).
SWING_PER_ORDER = 5.0
#: Pieces of a sweep (in row order) whose medians give its trend.
TREND_PIECES = 20

#: How the gain drift of an axis is known.
SEPARATE, FOLDED, UNOBSERVED = "separate", "folded", "unobserved"


@dataclass(frozen=True)
class Sweep:
    """One still capture whose temperature changes: its readings (n, 3) raw units, temperature
    (n,) °C, and its face direction (3,) (None: a gyroscope, any pose)."""

    values: FloatArray
    temperature: FloatArray
    up: FloatArray | None


@dataclass(frozen=True)
class Drift:
    """The drift polynomials: ``offset`` (3, order) raw units per °C^k and ``gain`` (3, order)
    relative change per °C^k, for k = 1..order, in d = clip(T, t_min, t_max) - t_ref."""

    t_ref: float
    t_min: float
    t_max: float
    offset: FloatArray
    gain: FloatArray

    @property
    def order(self) -> int:
        return int(self.offset.shape[1])

    def at(self, temperature: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(offset drift (n, 3) raw units, relative gain drift (n, 3)) at each temperature (clamped)."""
        d = (np.clip(temperature, self.t_min, self.t_max) - self.t_ref)[:, None]
        return _horner(self.offset, d), _horner(self.gain, d)


def _horner(coeffs: FloatArray, d: FloatArray) -> FloatArray:
    """sum_k coeffs[:, k-1] d^k for d (n, 1): (n, 3), by Horner's rule in broadcast products (a
    matrix product would go to OpenBLAS, whose threads slow apply down: core.model.apply)."""
    out = np.zeros((d.shape[0], 3))
    for k in range(coeffs.shape[1] - 1, -1, -1):
        out += coeffs[:, k]
        out *= d
    return out


@dataclass(frozen=True)
class ThermalFit:
    """What :func:`fit` found: the drift, each coefficient's 1-sigma, how each axis's gain drift is
    known, the residual RMS per axis (raw units, cells), the cross-validated error per order, and
    the per-pose detrended residual of every sample (for the quality checks)."""

    drift: Drift
    offset_se: FloatArray  # (3, order)
    gain_se: FloatArray  # (3, order)
    gain_drift: tuple[str, str, str]
    residual_rms: FloatArray  # (3,)
    cv_error: dict[int, float]
    order_auto: bool
    cells: int


def correct(
    raw: FloatArray, temperature: FloatArray, offset: FloatArray, matrix: FloatArray, drift: Drift
) -> tuple[FloatArray, int]:
    """Correct (n, 3) raw readings at their own temperatures (n,) (module docstring, last line of
    the model); returns the corrected rows and how many were outside [t_min, t_max] (clamped).
    A row whose temperature is NaN is corrected at T_ref's drift, zero (its own cells are empty)."""
    temp = np.where(np.isfinite(temperature), temperature, drift.t_ref)
    off, gain = drift.at(temp)
    d = raw - offset - off
    if np.any(drift.gain):
        d /= 1.0 + gain
    with np.errstate(invalid="ignore", over="ignore"):
        out: FloatArray = d[:, 0:1] * matrix[:, 0] + d[:, 1:2] * matrix[:, 1] + d[:, 2:3] * matrix[:, 2]
    outside = int(np.count_nonzero((temp < drift.t_min) | (temp > drift.t_max)))
    return out, outside


def at_reference(raw: FloatArray, temperature: FloatArray, offset: FloatArray, drift: Drift) -> FloatArray:
    """Raw readings (n, 3) as they would read at T_ref: ``offset + (raw - offset - offset drift) /
    (1 + gain drift)``, so that ``M (result - offset)`` is :func:`correct` (the model, last line)."""
    off, gain = drift.at(temperature)
    out: FloatArray = offset + (raw - offset - off) / (1.0 + gain)
    return out


def extremes(drift: Drift, points: int = 1001) -> tuple[FloatArray, FloatArray]:
    """Per axis, the largest |offset drift| over [t_min, t_max] (raw units) and the largest
    |d offset / dT| there (raw units per °C), on a grid of ``points`` temperatures."""
    grid = np.linspace(drift.t_min, drift.t_max, points)
    off, _ = drift.at(grid)
    step = (drift.t_max - drift.t_min) / (points - 1) or 1.0
    slope = np.abs(np.diff(off, axis=0)).max(axis=0) / step
    return np.abs(off).max(axis=0), slope


def trend_range(temperature: FloatArray) -> tuple[float, float]:
    """(lowest, highest) of the medians of TREND_PIECES consecutive pieces of one capture: the
    range its temperature trends over, robust to a noisy sensor's single readings."""
    pieces = np.array_split(temperature, min(TREND_PIECES, len(temperature)))
    medians = [float(np.median(p)) for p in pieces if len(p)]
    return min(medians), max(medians)


def required_swing(order: int, min_swing: float) -> float:
    """The swing (°C) an order needs: ``min_swing`` for order 1, SWING_PER_ORDER more per order."""
    return min_swing + SWING_PER_ORDER * (order - 1)


def gain_kinds(ups: Sequence[FloatArray | None]) -> tuple[str, str, str]:
    """How each axis's gain drift can be known from poses with these face directions."""
    out = []
    for j in range(3):
        seen = {round(float(u[j]), 1) for u in ups if u is not None}
        if len(seen) >= 2:
            out.append(SEPARATE)
        elif seen and seen != {0.0}:
            out.append(FOLDED)
        else:
            out.append(UNOBSERVED)
    return out[0], out[1], out[2]


def fit(
    sweeps: Sequence[Sweep],
    *,
    gain_scale: FloatArray,
    t_ref: float,
    order: int | None,
) -> ThermalFit:
    """Fit the drift of every axis (module docstring). ``gain_scale`` (3,) is G = g reference
    (raw units the vertical axis reads from gravity; zeros for a gyroscope); ``order`` None is auto."""
    cells = _cells(sweeps)
    kinds = gain_kinds([s.up for s in sweeps])
    kinds = tuple(k if gain_scale[j] != 0 else UNOBSERVED for j, k in enumerate(kinds))  # type: ignore[assignment]
    t_all = np.concatenate([s.temperature for s in sweeps])
    t_min, t_max = float(t_all.min()), float(t_all.max())
    cv = {k: _cv_error(cells, k, gain_scale, kinds, t_ref, t_min, t_max) for k in ORDERS}
    chosen = order
    if chosen is None:
        best = min(cv.values())
        chosen = next(k for k in ORDERS if cv[k] <= AUTO_TOLERANCE * best)
    offset = np.zeros((3, chosen))
    gain = np.zeros((3, chosen))
    offset_se = np.zeros((3, chosen))
    gain_se = np.zeros((3, chosen))
    rms = np.zeros(3)
    for j in range(3):
        coef, se, resid = _fit_axis(cells, j, chosen, gain_scale[j], kinds[j] == SEPARATE, t_ref)
        offset[j], offset_se[j] = coef[:chosen], se[:chosen]
        if kinds[j] == SEPARATE:
            gain[j], gain_se[j] = coef[chosen : 2 * chosen], se[chosen : 2 * chosen]
        rms[j] = float(np.sqrt(np.mean(resid**2)))
    drift = Drift(t_ref, t_min, t_max, offset, gain)
    return ThermalFit(drift, offset_se, gain_se, kinds, rms, cv, order is None, len(cells.temp))


def detrended(sweep: Sweep, drift: Drift, gain_scale: FloatArray) -> FloatArray:
    """A sweep's readings with the fitted drift removed (as if read at T_ref): what the
    quality checks judge."""
    off, gain = drift.at(sweep.temperature)
    out: FloatArray = sweep.values - off
    if sweep.up is not None:
        out = out - gain * (sweep.up * gain_scale)
    return out


def observed(sweep: Sweep, drift: Drift, gain_scale: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A sweep as its cells (for a figure): (temperature (m,), observed drift (m, 3), fitted drift
    (m, 3)), the sweep's own constant (its reading at T_ref) removed from the observed readings
    as the fit removes it, so that ``observed - fitted`` are the fit's residuals."""
    cells = _cells([sweep])
    off, gain = drift.at(cells.temp)
    fitted = off + gain * (cells.up * gain_scale)
    constant = (cells.value - fitted).mean(axis=0)
    return cells.temp, cells.value - constant, fitted


# -- the fit ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Cells:
    pose: NDArray[np.intp]  # (m,) int
    temp: FloatArray  # (m,) mean temperature of the cell
    value: FloatArray  # (m, 3) mean reading of the cell
    up: FloatArray  # (m, 3) the pose's face direction (zeros for a gyroscope)
    poses: int


def _cells(sweeps: Sequence[Sweep]) -> _Cells:
    t_all = np.concatenate([s.temperature for s in sweeps])
    width = min(CELL_DEGREES, max(float(t_all.max() - t_all.min()), 1e-9) / MIN_CELLS)
    pose, temp, value, up = [], [], [], []
    for p, s in enumerate(sweeps):
        key = np.floor((s.temperature - float(t_all.min())) / width).astype(np.int64)
        uniq, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        sums = np.zeros((len(uniq), 4))
        np.add.at(sums, inverse, np.column_stack([s.temperature, s.values]))
        means = sums / counts[:, None]
        pose.append(np.full(len(uniq), p))
        temp.append(means[:, 0])
        value.append(means[:, 1:])
        up.append(np.tile(np.zeros(3) if s.up is None else s.up, (len(uniq), 1)))
    return _Cells(np.concatenate(pose), np.concatenate(temp), np.vstack(value), np.vstack(up), len(sweeps))


def _powers(d: FloatArray, order: int) -> FloatArray:
    return np.column_stack([d ** (k + 1) for k in range(order)]) if order else np.zeros((len(d), 0))


def _design(
    cells: _Cells, rows: NDArray[np.intp], j: int, order: int, g: float, separate: bool, t_ref: float
) -> FloatArray:
    d = cells.temp[rows] - t_ref
    powers = _powers(d, order)
    parts = [powers]
    if separate:
        parts.append(powers * (cells.up[rows, j] * g)[:, None])
    intercepts = (cells.pose[rows][:, None] == np.arange(cells.poses)[None, :]).astype(np.float64)
    return np.hstack([*parts, intercepts])


def _fit_axis(
    cells: _Cells, j: int, order: int, g: float, separate: bool, t_ref: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(coefficients, their 1-sigma (HC0), residuals) of axis j: drift terms first, then the
    poses' constants."""
    rows = np.arange(len(cells.temp))
    x = _design(cells, rows, j, order, g, separate, t_ref)
    y = cells.value[:, j]
    scale = np.abs(x).max(axis=0)
    scale[scale == 0] = 1.0
    xs = x / scale
    coef_s, *_ = np.linalg.lstsq(xs, y, rcond=None)
    resid = y - xs @ coef_s
    bread = np.linalg.pinv(xs.T @ xs)
    meat = (xs * resid[:, None] ** 2).T @ xs
    cov = bread @ meat @ bread
    n, p = xs.shape
    cov *= n / max(n - p, 1)  # HC1's small-sample factor (module docstring)
    se = np.sqrt(np.clip(np.diag(cov), 0, None)) / scale
    return coef_s / scale, se, resid


def _cv_error(
    cells: _Cells, order: int, gain_scale: FloatArray, kinds: Sequence[str], t_ref: float, t_min: float, t_max: float
) -> float:
    """Mean squared error of predicting each temperature band from the others (all axes, in
    units of each axis's own residual scale so that no axis dominates)."""
    edges = np.linspace(t_min, t_max, FOLDS + 1)
    band = np.clip(np.searchsorted(edges, cells.temp, side="right") - 1, 0, FOLDS - 1)
    total, count = 0.0, 0
    for j in range(3):
        separate = kinds[j] == SEPARATE
        errors = []
        for b in range(FOLDS):
            train, test = np.flatnonzero(band != b), np.flatnonzero(band == b)
            if not len(test):
                continue
            seen = np.unique(cells.pose[train])
            test = test[np.isin(cells.pose[test], seen)]  # a pose with no training cells cannot be predicted
            if not len(test):
                continue
            xt = _design(cells, train, j, order, gain_scale[j], separate, t_ref)
            scale = np.abs(xt).max(axis=0)
            scale[scale == 0] = 1.0
            coef, *_ = np.linalg.lstsq(xt / scale, cells.value[train, j], rcond=None)
            xv = _design(cells, test, j, order, gain_scale[j], separate, t_ref) / scale
            errors.append(cells.value[test, j] - xv @ coef)
        if errors:
            e = np.concatenate(errors)
            spread = float(np.var(cells.value[:, j])) or 1.0
            total += float(np.mean(e**2)) / spread
            count += 1
    return total / max(count, 1)
