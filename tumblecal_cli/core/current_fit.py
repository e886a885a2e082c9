"""Current compensation: a magnetometer's offset per ampere of motor current.

A vehicle held still (or in one attitude) while its motors run up sees its field move with the
current drawn: ``raw(t) = b0 + k I(t) + noise`` per axis, b0 the reading at 0 A (the offset and
the Earth's field in that attitude), k (3,) raw units per ampere. ``fit`` estimates k and b0 by
least squares, with 1-sigma uncertainties from the residuals (the textbook straight line:
se(k) = s / sqrt(Sxx), se(b0) = s sqrt(1/n + mean(I)^2 / Sxx), s^2 = RSS / (n - 2), Sxx the sum
of squares of the current about its mean; residuals that follow one another (a vehicle that
sways, a field that wanders) carry less information than as many independent ones, so each axis's
1-sigma is widened by sqrt((1 + r) / (1 - r)), r the lag-1 autocorrelation of its residuals
within each log, floored at 0: the effective number of readings of an AR(1) series,
n (1 - r) / (1 + r)), and the share of the field's variation the current
explains (R^2 = 1 - RSS / TSS).

``correct`` is what apply does with it: ``corrected = M (raw - offset - k I)`` (README
"Calibration file", DESIGN section 2, with the offset moved by the current).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.core.model import apply as apply_model

#: The fewest readings a fit takes (a straight line per axis and its scatter).
MIN_SAMPLES = 10


@dataclass(frozen=True)
class CurrentFit:
    """A fitted offset per ampere: ``per_amp`` k (3,) raw units per A with its 1-sigma
    ``per_amp_se``; ``at_zero`` (g, 3) each log's reading at 0 A with ``at_zero_se``;
    ``explained`` (3,) the share of each axis's variation (about each log's mean) the current
    explains and ``explained_total`` that of the field's (all axes); ``residual_rms`` (3,) raw
    units; ``autocorrelation`` (3,) r of each axis's residuals (the 1-sigma widened for it);
    ``samples``; ``span`` the lowest and highest current (A)."""

    per_amp: FloatArray
    per_amp_se: FloatArray
    at_zero: FloatArray
    at_zero_se: FloatArray
    explained: FloatArray
    explained_total: float
    residual_rms: FloatArray
    autocorrelation: FloatArray
    samples: int
    span: tuple[float, float]


def fit(values: FloatArray, current: FloatArray, group: IntArray | None = None) -> CurrentFit:
    """Fit ``values`` (n, 3) raw readings against ``current`` (n,) amperes, each axis a straight
    line; ``group`` (n,) numbers each reading's log 0..g-1, each log with its own reading at 0 A
    (another attitude) and one slope for all. The caller makes sure the current varies within a
    log (``spread`` > 0) and n >= MIN_SAMPLES + g."""

    y = np.asarray(values, dtype=np.float64)
    x = np.asarray(current, dtype=np.float64).reshape(-1)
    g = np.zeros(len(x), dtype=np.int64) if group is None else np.asarray(group, dtype=np.int64)
    count = int(g.max()) + 1
    n_g = np.bincount(g, minlength=count).astype(np.float64)
    x_mean = np.bincount(g, weights=x, minlength=count) / n_g  # (g,)
    y_mean = np.stack([np.bincount(g, weights=y[:, j], minlength=count) for j in range(3)], axis=1) / n_g[:, None]
    dx, dy = x - x_mean[g], y - y_mean[g]
    sxx = float(dx @ dx)
    k = (dx @ dy) / sxx  # (3,)
    resid = dy - np.outer(dx, k)
    rss, tss = (resid**2).sum(axis=0), (dy**2).sum(axis=0)
    n = len(x)
    same_log = g[1:] == g[:-1]  # neighbours in one log
    lagged = (resid[1:] * resid[:-1])[same_log].sum(axis=0)
    r = np.clip(np.where(rss > 0, lagged / np.where(rss > 0, rss, 1), 0.0), 0.0, 0.99)
    s2 = rss / (n - count - 1) * (1 + r) / (1 - r)
    explained = np.where(tss > 0, 1 - rss / np.where(tss > 0, tss, 1), 0.0)
    return CurrentFit(
        per_amp=k,
        per_amp_se=np.sqrt(s2 / sxx),
        at_zero=y_mean - np.outer(x_mean, k),
        at_zero_se=np.sqrt(np.outer(1 / n_g + x_mean**2 / sxx, s2)),
        explained=explained,
        explained_total=float(1 - rss.sum() / tss.sum()) if tss.sum() > 0 else 0.0,
        residual_rms=np.sqrt(rss / n),
        autocorrelation=r,
        samples=n,
        span=(float(x.min()), float(x.max())),
    )


def spread(current: FloatArray, group: IntArray | None = None) -> float:
    """The RMS of the current about each log's mean (A): 0 when it never changes within a log,
    which determines no slope."""
    x = np.asarray(current, dtype=np.float64).reshape(-1)
    if x.size == 0:
        return 0.0
    g = np.zeros(len(x), dtype=np.int64) if group is None else np.asarray(group, dtype=np.int64)
    n_g = np.bincount(g).astype(np.float64)
    mean = np.bincount(g, weights=x) / np.where(n_g > 0, n_g, 1)
    return float(np.sqrt(np.mean((x - mean[g]) ** 2)))


def interference(fit: CurrentFit, matrix: FloatArray, reference: float) -> tuple[float, float]:
    """The corrected field's change at the largest current fitted over ``reference`` (ArduPilot's
    compassmot reports it as a percentage), and its 1-sigma to first order: with v = M k and
    g = M^T v / |v| the gradient of |v|, sigma = sqrt(sum_j (g_j se(k_j))^2) * I_max / reference."""

    largest = max(abs(fit.span[0]), abs(fit.span[1]))
    moved = np.asarray(matrix, dtype=np.float64) @ fit.per_amp
    length = float(np.linalg.norm(moved))
    gradient = np.asarray(matrix, dtype=np.float64).T @ moved / length if length > 0 else np.zeros(3)
    sigma = float(np.sqrt(np.sum((gradient * fit.per_amp_se) ** 2)))
    return length * largest / reference, sigma * largest / reference


def correct(
    raw: FloatArray, current: FloatArray, offset: FloatArray, matrix: FloatArray, per_amp: FloatArray
) -> FloatArray:
    """``M (raw - offset - k I)`` for (n, 3) readings at ``current`` (n,) amperes."""

    moved = np.outer(np.asarray(current, dtype=np.float64).reshape(-1), per_amp)
    return apply_model(np.asarray(raw, dtype=np.float64) - moved, offset, matrix)
