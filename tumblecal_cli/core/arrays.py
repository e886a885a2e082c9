"""The array types the package's signatures name, defined once: float, integer and boolean arrays of
any shape (a name's comment or docstring gives the shape, "(n, 3)")."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
