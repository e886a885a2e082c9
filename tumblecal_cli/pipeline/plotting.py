"""The ``--plot`` figures of solve and verify, from their results (io.figures.fitplots and
io.figures.plots draw them, importing matplotlib only then)."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.io.figures import fitplots, plots

if TYPE_CHECKING:
    from tumblecal_cli.core.gate import Limits
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.calfiles.calparts import Pose
    from tumblecal_cli.pipeline.solve.solving import Solved
    from tumblecal_cli.pipeline.verify import Verified

#: "Before" is the raw reading taken as it is (less a nominal offset) unless its norm is off the
#: reference by more than this share of it: unsigned counts, whose zero is far from 0; then it is
#: the reading less the fitted offset, so that what the gains and cross terms do can be seen.
RAW_IS_OFF = 0.5


def solve_plot(path: str, solved: Solved, plane: str | None = None) -> None:
    """``solve --plot``: a rotation capture in its planes (io.figures.plots.rotation_figure), or the
    static poses' residuals before and after (io.figures.fitplots.poses_figure)."""
    cal = solved.calibration
    assert cal is not None
    raw = [s.values for s in solved.samples]
    title = f"{cal.sensor}, {cal.method}" + (f", {cal.serial}" if cal.serial else "")
    limits = solved.limits.for_method(cal.method) if solved.limits is not None else None
    residual = None if limits is None else limits.residual
    if catalog.turned(cal.method):
        fitted = plots.PlottedCorrection(cal.offset, cal.matrix, cal.reference, cal.units)
        plots.rotation_figure(path, np.concatenate(raw), fitted, title=title, plane=plane, limit=residual)
        return
    samples = raw if len(raw) == len(cal.poses) else [None] * len(cal.poses)
    faces = [p.face for p in cal.poses]
    by_face = all(faces) and len(set(faces)) == len(faces)  # six pose files: their faces say which
    poses = [
        fitplots.PoseData(p.face if by_face and p.face else _pose_name(p), p.mean, s, p.face, p.angle_deg)
        for p, s in zip(cal.poses, samples, strict=True)
    ]
    tilt = cal.tilt_sensitivity
    bounds = fitplots.Bounds(residual, tilt.tolerance_deg if tilt is not None else None)
    fitted = plots.PlottedCorrection(cal.offset, cal.matrix, cal.reference, cal.units)
    fitplots.poses_figure(path, poses, fitted, bounds, _before(cal, solved.limits), sensor=cal.sensor, title=title)


def _pose_name(p: Pose) -> str:
    """A log's blocks by number (they share the file), a table's rows by row, pose files by name."""
    if p.block is not None:
        where = f"block {p.block}"
    elif p.rows is not None and p.rows[0] == p.rows[1]:
        where = f"{os.path.basename(str(p.file))} row {p.rows[0]}"
    else:
        where = os.path.basename(str(p.file))
    return f"{p.face} {where}" if p.face else where


def _before(cal: Calibration, limits: Limits | None) -> fitplots.Before:
    """What "before calibration" is: the raw reading less the nominal offset (--nominal-offset,
    the limits file), over the nominal gain (else the mean solved gain: its shape, not its
    units); or, for raw readings far from the reference (RAW_IS_OFF), less the fitted offset."""
    given = limits is not None and limits.nominal_gain_given
    if given:
        assert limits is not None
        gain = float(np.mean(limits.nominal_gain))
    else:
        gain = 1.0 if catalog.fixes_gains(cal.method) else float(np.mean(cal.gain))
    scaled = "" if gain == 1.0 else (" ÷ nominal gain" if given else " ÷ mean gain")
    centre = np.zeros(3) if limits is None else np.asarray(limits.nominal_offset, dtype=np.float64)
    if np.any(centre):
        return fitplots.Before(centre, gain, f"(raw − nominal offset){scaled}")
    means = np.array([p.mean for p in cal.poses], dtype=np.float64)
    norms = np.linalg.norm(means, axis=1) / gain
    ref = cal.reference
    if ref > 0 and float(np.median(np.abs(norms - ref))) > RAW_IS_OFF * ref:
        return fitplots.Before(np.asarray(cal.offset, dtype=np.float64), gain, f"(raw − fitted offset){scaled}")
    return fitplots.Before(centre, gain, f"raw{scaled}" if scaled else "raw")


def verify_plot(path: str, done: Verified) -> None:
    """``verify --plot``: each capture's (or row's) norm error after, with --max-norm-error, and
    before on its own axes."""
    rows = [
        fitplots.VerifiedCapture(
            r["file"], r["error_after"], float(max(r["std"])), r["samples"], r["error_before"], r["file"] in done.failed
        )
        for r in done.rows
    ]
    cal = done.cal
    title = f"verify: {cal.sensor}, {cal.method}" + (f", {cal.serial}" if cal.serial else "")
    fitplots.verify_figure(
        path, rows, done.max_norm_error, fitplots.Scale.of(cal.units, done.reference, cal.sensor), title=title
    )
