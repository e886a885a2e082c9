"""What solve says of a fit beyond its parameters: the samples a robust fit left out (as the file
records them, in data rows), an accelerometer's fit that holds the motion's own acceleration, and
a --reference that is not what a unit at rest reads in --units."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import quantities
from tumblecal_cli.core.quantities import STANDARD_GRAVITY
from tumblecal_cli.io.calfiles.calparts import LeftOut, LeftOutStretch

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import IntArray
    from tumblecal_cli.core.solvers import Fit
    from tumblecal_cli.io.csv.readings import Samples


def left_out(fit: Fit, samples: Sequence[Samples], reference: float) -> LeftOut | None:
    """The samples a robust fit left out (core.robust), as the file records them: each stretch in
    its file's data rows (split where it crosses from one file into the next), or in sample
    indices where the rows are not known (empty rows were dropped between)."""
    found = fit.outliers
    if found is None:
        return None
    starts = np.cumsum([0, *(len(s.values) for s in samples)])
    out = []
    for stretch in found.stretches:
        for k, s in enumerate(samples):
            a, b = max(stretch.first, int(starts[k])), min(stretch.last, int(starts[k + 1]) - 1)
            if a > b:
                continue
            i, j = a - int(starts[k]), b - int(starts[k])
            rows = _data_rows(s)
            pair = None if rows is None else (int(rows[i]), int(rows[j]))
            out.append(LeftOutStretch(s.layout.name, pair, None if pair else (i, j), round(stretch.worst, 4)))
    return LeftOut(found.count, found.of, found.bound, tuple(out))


def _data_rows(s: Samples) -> IntArray | None:
    """Each sample's data row in its file, where known: the log's, or a run of consecutive rows."""
    if s.log is not None and len(s.log.rows) == len(s.values):
        return np.asarray(s.log.rows, dtype=np.int64)
    first, last = s.rows
    if last - first + 1 == len(s.values):
        return np.arange(first, last + 1, dtype=np.int64)
    return None


#: Stretches an outlier note names one by one.
SHOWN_STRETCHES = 3


def outlier_notes(found: LeftOut | None, units: str | None) -> list[str]:
    """One note of what a robust fit left out: how many, beyond what, and where."""
    if found is None or not found.stretches:
        return []
    unit = f" {units}" if units else ""
    where = []
    for st in found.stretches[:SHOWN_STRETCHES]:
        span = st.rows if st.rows is not None else st.samples
        word = "row" if st.rows is not None else "sample"
        assert span is not None
        place = f"{word} {span[0]}" if span[0] == span[1] else f"{word}s {span[0]}-{span[1]}"
        if st.worst is None or not np.isfinite(st.worst):
            worst = "not a reading"
        else:
            worst = f"{st.worst:.0%} off" if st.worst < 1 else f"off by {st.worst:.3g} times the reference"
        where.append(f"{os.path.basename(st.file or '')} {place} ({worst})")
    more = len(found.stretches) - SHOWN_STRETCHES
    tail = f" and {more} more stretch{'es' if more > 1 else ''}" if more > 0 else ""
    return [
        f"outliers: {found.count:,} of {found.of:,} samples left out of the fit (|residual| over "
        f"{found.bound:.3g}{unit}): {'; '.join(where)}{tail}; --no-robust keeps them"
    ]


#: An accelerometer's fit over its samples whose residual RMS is over this share of the reference
#: was not still: its readings hold the motion's own acceleration.
MOTION_SHARE = 0.01


def motion_notes(sensor: str, fit: Fit, poses: int, reference: float) -> list[str]:
    """A note when an accelerometer's sphere or ellipsoid over samples (more residuals than poses)
    fits them worse than MOTION_SHARE of the reference: a capture turned while it logs reads the
    motion's acceleration as well as gravity, and no calibration takes that out (a continuous
    tumble forced through --method ellipsoid: residual 0.34 m/s^2, and not a word)."""
    if sensor != "accelerometer" or fit.residuals is None or len(fit.residuals) <= poses or not reference > 0:
        return []
    rms = float(np.sqrt(np.mean(fit.residuals**2)))
    if rms <= MOTION_SHARE * reference:
        return []
    return [
        f"the fit's residual RMS is {rms:.3g} ({rms / reference:.1%} of the reference): an accelerometer turned while "
        "it logs reads the motion's own acceleration beside gravity, which no calibration removes; calibrate from "
        "still orientations (solve --log FILE finds them in one log)"
    ]


#: The Earth's field at its surface, weakest to strongest (WMM: about 22,000 to 67,000 nT), in gauss.
EARTH_FIELD = (0.22, 0.67)


def reference_notes(sensor: str, units: str | None, reference: float) -> list[str]:
    """A note when --units name a unit and --reference is not what a unit at rest reads in it:
    gravity (within 10 %), or a field the Earth has. --units uT with --reference 1 was taken as a
    1 µT field without a word. (A centrifuge or a lab's coils: then the note is to be ignored.)"""
    factor = None if units is None else quantities.factor(sensor, units.strip())
    if factor is None or reference <= 0:
        return []
    value = reference * factor  # in the quantity's base unit: m/s^2, gauss
    if sensor == "accelerometer" and abs(value / STANDARD_GRAVITY - 1) > 0.1:
        return [
            f"--reference {reference:g} {units} is not gravity ({STANDARD_GRAVITY / factor:.4g} {units}): "
            "is --reference in --units?"
        ]
    low, high = EARTH_FIELD
    if sensor == "magnetometer" and not low <= value <= high:
        return [
            f"--reference {reference:g} {units} is not a field the Earth has ({low / factor:.3g}–{high / factor:.3g} "
            f"{units}): is --reference in --units? (a lab's coils may make it; --location gives the local field)"
        ]
    return []
