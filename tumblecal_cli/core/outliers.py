"""Outlier flags over a lot that control the lot-wide false-alarm rate (``report --outlier-alpha``).

A lot report judges every unit on every figure (offsets, gains, cross terms): 30 units × 12
figures are 360 judgements, so a per-figure threshold (|robust z| > 4, say) fires on most lots of
good units. The rule here bounds the chance that a lot of good units has ANY flag by ``alpha``:

1. **Screen** (robust centre and spread): the median and the MAD, made consistent for the normal
   at this n (×1.4826 and Croux and Rousseeuw's small-sample factor). A unit whose robust z is
   beyond ``SCREEN_Z`` is set aside, so that one or several gross outliers cannot inflate the
   spread the others are judged by (no masking).
2. **Score** each unit against the units kept, leaving itself out: ``t = (x − mean) / (sd · √(1 +
   1/k))`` with the mean and standard deviation of those k units. For normal units (none set
   aside) this is exactly Student's t with k − 1 degrees of freedom: the externally studentised
   residual, whose reference distribution is right at every lot size, not only asymptotically.
3. **Threshold**: Šidák over every judgement made in the report (N = Σ units over figures), each
   at two-sided ``p = 1 − (1 − alpha)^(1/N)``, the t quantile for its degrees of freedom.
4. Every figure of ``MIN_UNITS`` (8) units or more is judged: the false-alarm rate holds at every
   size, and what a small lot cannot promise is its power, which the report states (the chance a
   unit ``DETECT_SIGMA`` off is flagged at the lot's size, noncentral t: 83 % at 30 units of 12
   figures). Waiting for 95 % power (``smallest_lot``: 46 units of 12 figures) left a 6σ unit in a
   lot of 30 unnamed.

Verified by simulation in tests/test_lot_outliers.py (1,000 lots per size, 8 to 200 units).

Sources: Šidák's per-test level (Sidak 1967); Student's t for the externally studentised residual
(Cook and Weisberg 1982, Residuals and Influence in Regression, §2.2); MAD consistency factors:
Croux and Rousseeuw 1992 ("Time-efficient algorithms for two highly robust estimators of scale",
Computational Statistics vol. 1, the MAD's table); Student's t tail as the regularised incomplete
beta function: Abramowitz and Stegun 1964, 26.7.1 and 26.5.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.errors import InputError, said

#: The lot-wide false-alarm rate of the outlier flags (``--outlier-alpha``): the chance that a lot
#: of good units (every figure normal, no unit off) has any unit flagged on any figure. Half of
#: 1 %, so that "at most 1 % of good lots flagged" holds with room in any sample of 1,000 lots
#: (at a rate of exactly 1 %, one sample in three would count more than 10).
OUTLIER_ALPHA = 0.005
#: The report states its power against a unit this many σ off one figure at the lot's size;
#: ``smallest_lot`` is the size at which that power reaches ``DETECT_POWER`` (36 units for 6
#: figures, 46 for 12, default alpha).
DETECT_SIGMA = 6.0
DETECT_POWER = 0.95
#: A figure of fewer units than this is not judged (its t has under 6 degrees of freedom).
MIN_UNITS = 8
#: A unit whose robust z (median, consistent MAD) is beyond this is set aside from the centre and
#: spread the other units are judged by.
SCREEN_Z = 3.5
#: 1 / Φ⁻¹(3/4): makes the MAD a consistent estimate of σ for normal data.
MAD_NORMAL = 1.482602218505602
#: Croux and Rousseeuw 1992's small-sample factors for the MAD, n = 2..9; n/(n − 0.8) above.
_MAD_SMALL = {2: 1.196, 3: 1.495, 4: 1.363, 5: 1.206, 6: 1.200, 7: 1.140, 8: 1.129, 9: 1.107}
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)


def mad_factor(n: int) -> float:
    """The small-sample consistency factor of the MAD for n values (1 for n < 2)."""
    if n < 2:
        return 1.0
    return _MAD_SMALL.get(n, n / (n - 0.8))


def robust_scores(values: FloatArray) -> FloatArray:
    """(x − median) / (MAD · 1.4826 · small-sample factor) along the last axis; 0 where the MAD
    is 0 and the value is the median, inf where the MAD is 0 and it is not."""
    x = np.asarray(values, dtype=np.float64)
    centre = np.median(x, axis=-1, keepdims=True)
    deviation = x - centre
    scale = np.median(np.abs(deviation), axis=-1, keepdims=True) * MAD_NORMAL * mad_factor(x.shape[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(deviation == 0, 0.0, deviation / scale)
    return np.where(np.isnan(z), np.inf, z)


def studentised(values: FloatArray, keep: BoolArray | None = None) -> tuple[FloatArray, FloatArray]:
    """(t, degrees of freedom) of every value along the last axis: its deviation from the mean of
    the other units in ``keep`` (default: the units the robust screen keeps), over their standard
    deviation × √(1 + 1/k) (module docstring). t is 0 where those units all agree exactly (no
    spread to judge by)."""
    x = np.asarray(values, dtype=np.float64)
    y = x - np.median(x, axis=-1, keepdims=True)  # centred: the sums below lose no digits
    if keep is None:
        keep = np.abs(robust_scores(x)) <= SCREEN_Z
    own = np.where(keep, y, 0.0)
    k = (keep.sum(axis=-1, keepdims=True) - keep).astype(np.float64)  # the others kept: without itself
    total = own.sum(axis=-1, keepdims=True) - own
    squares = (own * own).sum(axis=-1, keepdims=True) - own * own
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = total / k
        variance = np.maximum(squares - k * mean * mean, 0.0) / (k - 1)
        t = (y - mean) / np.sqrt(variance * (1.0 + 1.0 / k))
    spread = (k >= 2) & (variance > 1e-24 * np.maximum(mean * mean, 1e-300))
    return np.where(spread, t, 0.0), np.maximum(k - 1, 0.0)


def t_tail(c: float, df: float) -> float:
    """P(|T| > c) for Student's t with ``df`` degrees of freedom: the regularised incomplete beta
    I_x(df/2, 1/2) at x = df / (df + c²) (Abramowitz and Stegun 26.7.1, 26.5), by 64-point
    Gauss–Legendre after a substitution that makes the integrand smooth."""
    if c <= 0:
        return 1.0
    a, x = df / 2.0, df / (df + c * c)
    log_beta = math.lgamma(a) + math.lgamma(0.5) - math.lgamma(a + 0.5)
    w = 0.5 * (_NODES + 1.0)  # on [0, 1]
    if x < 0.5:  # s = x·w^(1/a): ∫₀ˣ s^(a−1) (1 − s)^(−1/2) ds = (x^a / a) ∫₀¹ (1 − x w^(1/a))^(−1/2) dw
        integral = 0.5 * float(np.sum(_WEIGHTS * (1.0 - x * w ** (1.0 / a)) ** -0.5))
        return math.exp(a * math.log(x) - math.log(a) - log_beta) * integral
    y = 1.0 - x  # I_x(a, ½) = 1 − I_y(½, a); s = y·w²: ∫₀ʸ s^(−1/2) (1 − s)^(a−1) ds = 2√y ∫₀¹ (1 − y w²)^(a−1) dw
    integral = 0.5 * float(np.sum(_WEIGHTS * (1.0 - y * w * w) ** (a - 1.0)))
    return 1.0 - math.exp(math.log(2.0 * math.sqrt(y)) - log_beta) * integral


@functools.lru_cache(maxsize=1024)
def t_quantile(p: float, df: float) -> float:
    """The c with P(|T| > c) = p (two-sided) for Student's t with ``df`` degrees of freedom."""
    if not (0.0 < p < 1.0 and df > 0):
        raise ValueError(f"t_quantile needs 0 < p < 1 and df > 0, got p={p}, df={df}")
    low, high = 0.0, 1.0
    while t_tail(high, df) > p:
        low, high = high, high * 2.0
    for _ in range(80):  # bisection in log space: the tail falls steeply
        middle = math.sqrt(low * high) if low > 0 else high / 2.0
        if t_tail(middle, df) > p:
            low = middle
        else:
            high = middle
        if high - low < 1e-10 * high:
            break
    return high


@functools.lru_cache(maxsize=64)
def smallest_lot(figures: int, alpha: float = OUTLIER_ALPHA) -> int:
    """The fewest units a lot of ``figures`` figures per unit needs to catch a unit DETECT_SIGMA
    off DETECT_POWER of the time (n ≥ ``OutlierRule(alpha, figures·n).detect_units``; more
    figures, more judgements, more units: the condition holds from some n on, found by bisection)."""
    low, high = MIN_UNITS, MIN_UNITS
    while high < OutlierRule(alpha, figures * high).detect_units:
        low, high = high + 1, high * 2
    while low < high:
        middle = (low + high) // 2
        low, high = (middle + 1, high) if middle < OutlierRule(alpha, figures * middle).detect_units else (low, middle)
    return high


def check_alpha(alpha: float) -> float:
    """``alpha`` as a float in (0, 1); InputError naming --outlier-alpha otherwise."""
    if not (isinstance(alpha, int | float) and math.isfinite(alpha) and 0.0 < alpha < 1.0):
        raise InputError(
            said("outliers.alpha", alpha=alpha),
            hint=f"it is the chance a lot of good units gets any flag; {OUTLIER_ALPHA} is usual",
        )
    return float(alpha)


@dataclass(frozen=True)
class OutlierRule:  # (frozen, with a cached_property: min_units is worked out once)
    """The rule a lot's outlier flags follow: lot-wide ``alpha`` over ``tests`` judgements (units
    × figures), none for a figure of fewer than ``min_units`` units."""

    alpha: float = OUTLIER_ALPHA
    tests: int = 1

    @property
    def min_units(self) -> int:
        """The fewest units of a figure that is judged."""
        return MIN_UNITS

    @functools.cached_property
    def detect_units(self) -> int:
        """The smallest figure size (≥ ``MIN_UNITS``) whose power against a unit ``DETECT_SIGMA``
        off is at least ``DETECT_POWER`` (power rises with n)."""
        low, high = MIN_UNITS, MIN_UNITS
        while self.power(high) < DETECT_POWER:
            low, high = high, high * 2
            if high > 1_000_000:
                return high
        while low < high:
            middle = (low + high) // 2
            low, high = (middle + 1, high) if self.power(middle) < DETECT_POWER else (low, middle)
        return high

    def power(self, n: int, shift: float = DETECT_SIGMA) -> float:
        """The probability that a unit whose figure lies ``shift`` σ from the mean of n − 1 normal
        units is flagged: t = (shift − m) / (s·√(1 + 1/k)) with k = n − 1, m ~ N(0, 1/k) and
        s² ~ χ²(k − 1)/(k − 1), so P(t > c) = E_s[Φ̄((c·s·√(1 + 1/k) − shift)·√k)]."""
        if n < 3:
            return 0.0
        k = n - 1.0
        c, df = self.limit(k - 1.0), k - 1.0
        s = np.linspace(1e-6, 1.0 + 12.0 / math.sqrt(df), 801)  # s = sample sd / σ
        log_density = (  # of s: 2 (df/2)^(df/2) / Γ(df/2) · s^(df−1) · exp(−df s²/2)
            math.log(2.0)
            + (df / 2.0) * math.log(df / 2.0)
            - math.lgamma(df / 2.0)
            + (df - 1.0) * np.log(s)
            - df * s * s / 2.0
        )
        z = (c * s * math.sqrt(1.0 + 1.0 / k) - shift) * math.sqrt(k)
        beyond = 0.5 * np.array([math.erfc(v / math.sqrt(2.0)) for v in z])
        return float(np.trapezoid(np.exp(log_density) * beyond, s))

    @property
    def per_test(self) -> float:
        """Šidák's two-sided level of each judgement: 1 − (1 − alpha)^(1/tests)."""
        return -math.expm1(math.log1p(-self.alpha) / max(self.tests, 1))

    def limit(self, df: float) -> float:
        """|t| beyond this is flagged (inf when there are too few degrees of freedom)."""
        return t_quantile(self.per_test, float(df)) if df >= 1 else math.inf

    def flags(self, values: FloatArray) -> tuple[BoolArray, FloatArray]:
        """(flagged, t) of every value along the last axis; nothing flagged below ``min_units``."""
        t, df = studentised(values)
        if np.shape(values)[-1] < self.min_units:
            return np.zeros(np.shape(t), dtype=bool), t
        # a unit the screen set aside but within the limit of the kept units is taken back, so
        # that the screen (noisy in small lots) takes out of the spread only what is flagged
        t, df = studentised(values, np.abs(t) <= self._limits(df))
        return np.abs(t) > self._limits(df), t

    def _limits(self, df: FloatArray) -> FloatArray:
        limits = np.full(np.shape(df), np.inf)
        for d in np.unique(df):
            limits[df == d] = self.limit(float(d))
        return limits

    def figure_limit(self, n: int) -> float | None:
        """The |t| limit of a figure of n units none of which is set aside (None: not judged)."""
        return self.limit(n - 2.0) if n >= self.min_units else None

    def cell(self, n: int, limit: float | None) -> str:
        """The rule a figure of n units was judged by, for a CSV cell (no commas)."""
        if limit is None:
            return f"not judged: {n} units < {MIN_UNITS}"
        return f"|t|>{limit:.3g} (alpha {self.alpha:g} over {self.tests})"

    def describe(self, units: int | None = None) -> str:
        """The rule in one sentence, for people; ``units``: the largest figure's size, to say when
        the lot is too small to be judged, and how likely a unit DETECT_SIGMA off is caught."""
        if units is not None and units < MIN_UNITS:
            return f"outliers: not judged ({units} units; {MIN_UNITS} needed)"
        limit = f" > {self.limit(units - 2.0):.3g}" if units is not None else ""
        per_lot = f"false alarms {self.alpha:g} per lot, {self.tests} unit-figures"
        caught = (
            f"; a unit {DETECT_SIGMA:g}σ off, in a lot this size, caught {_share(self.power(units))} of the time"
            if units
            else ""
        )
        return f"outliers: |t|{limit} vs the other units ({per_lot}{caught})"

    def as_dict(self) -> dict[str, object]:
        return {
            "method": "studentised deviation from the other units, median/MAD screen, Šidák over unit-figures",
            "alpha": self.alpha,
            "tests": self.tests,
            "per_test": self.per_test,
            "screen_z": SCREEN_Z,
            "min_units": MIN_UNITS,
            "detect_sigma": DETECT_SIGMA,
        }


def _share(p: float) -> str:
    """A probability as people read it: 83%, or over 99% (never a rounded 100%)."""
    return "over 99%" if p >= 0.995 else f"{p:.0%}"
