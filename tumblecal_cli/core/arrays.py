"""The array types the package's signatures name, defined once: float, integer and boolean arrays of
any shape (a name's comment or docstring gives the shape, "(n, 3)")."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


def median(values: FloatArray, axis: int = 0) -> FloatArray:
    """``np.median(values, axis=axis)``, the same digits, by a sort: np.median imports numpy.ma
    (8 ms of a command's start-up) to check for masked arrays. NaN anywhere: np.median's own."""
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0 or not np.isfinite(a).all():
        return np.asarray(np.median(a, axis=axis), dtype=np.float64)
    ordered = np.sort(a, axis=axis)
    n = ordered.shape[axis]
    upper = np.take(ordered, n // 2, axis=axis)
    if n % 2:
        return np.asarray(upper, dtype=np.float64)
    lower = np.take(ordered, n // 2 - 1, axis=axis)
    return np.asarray(np.mean(np.stack([lower, upper]), axis=0), dtype=np.float64)
