"""Each catalog row's function (core.catalog) for the methods that take means or samples: one
:class:`SolverInput` in, a :class:`~tumblecal_cli.core.solvers.Fit` out, each a thin call of its
solver in core.solvers (or core.model for 1- and 3-pose); and :func:`fit`, the dispatch through
the row. numpy only."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from tumblecal_cli.core import catalog, robust
from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.core.methods import THREE_FACES
from tumblecal_cli.core.model import FACES, PoseStats, direction, solve_one_pose, solve_three_pose, tilt_sensitivity
from tumblecal_cli.core.solvers import (
    Fit,
    design_rank,
    gain_error_bound,
    gyro_bias,
    least_squares,
    minmax,
    minmax_offset,
    norm_residuals,
    one_pose_tilt,
    rough_ellipsoid,
    six_pose,
    sphere,
)
from tumblecal_cli.errors import CaptureRejected


@dataclass(frozen=True)
class SolverSettings:
    """What a solver is told beside its poses: the ``reference`` magnitude, the fixture's tilt
    tolerance (degrees) the tilt sensitivity is stated for, a 1-pose tilt fit's prior on the
    horizontal offsets (``bias_spread``, raw units), minmax's ``plane``, and the 1-pose methods'
    stated bound on the up axis's unknown gain error (``gain_tolerance``)."""

    reference: float
    tolerance_deg: float
    bias_spread: float
    plane: str | None = None
    gain_tolerance: float = 0.0
    robust: bool = True  # a fit over samples trims its outliers (core.robust); False: plain least squares


@dataclass(frozen=True)
class SolverInput:
    """What every solver of the catalog (core.catalog) is given: the ``method`` run (a function
    may serve several rows), and the poses in the order ``methods.pick`` put them: each pose's
    statistics (``stats``), its readings (``values``, (n, 3) each), its label (a face, a
    direction ``X,Y,Z``, or None for an orientation-free method), its file's name (``names``);
    and the ``settings``."""

    method: str
    stats: Sequence[PoseStats]
    values: Sequence[FloatArray]
    labels: Sequence[str | None]
    names: Sequence[str]
    settings: SolverSettings


#: A catalog row's function for a method that takes means or samples.
Solver = Callable[[SolverInput], Fit]


def fit_one_pose(given: SolverInput) -> Fit:
    """one-pose: core.model.solve_one_pose, its tilt bound widened by the up axis's gain tolerance."""
    s = given.settings
    face = str(given.labels[0])
    one = solve_one_pose(given.stats[0], face, s.reference)
    offset_tilt, gain_tilt = tilt_sensitivity("one-pose", one.gain, s.reference, [face], s.tolerance_deg)
    offset_tilt = offset_tilt + np.abs(np.asarray(FACES[face])) * gain_error_bound(s.reference, s.gain_tolerance)
    return Fit(solution=one, tilt=(offset_tilt, gain_tilt, np.zeros((3, 3))))


def fit_one_pose_tilt(given: SolverInput) -> Fit:
    """one-pose-tilt: :func:`one_pose_tilt`."""
    s = given.settings
    return one_pose_tilt(
        given.stats[0], str(given.labels[0]), s.reference, s.tolerance_deg, s.bias_spread, s.gain_tolerance
    )


def fit_three_pose(given: SolverInput) -> Fit:
    """three-pose: core.model.solve_three_pose, with its tilt bound and norm residuals."""
    s, stats, labels = given.settings, given.stats, given.labels
    faces = [str(x) for x in labels] if all(x in FACES for x in labels) else list(THREE_FACES)
    three = solve_three_pose(stats, s.reference, names=given.names, faces=faces)
    offset_tilt, gain_tilt = tilt_sensitivity("three-pose", three.gain, s.reference, faces, s.tolerance_deg)
    residuals = norm_residuals(np.array([p.mean for p in stats]), three.offset, three.matrix, s.reference)
    return Fit(solution=three, residuals=residuals, tilt=(offset_tilt, gain_tilt, np.zeros((3, 3))))


def fit_six_pose(given: SolverInput) -> Fit:
    """six-pose, six-pose-diagonal and six-pose-magnitude: :func:`six_pose`, the variant run."""
    return six_pose(given.stats, given.settings.reference, given.settings.tolerance_deg, given.method)


#: Fewest poses a least-squares fit judges its poses by leaving one out (12 parameters: five left
#: give a residual to judge by).
ROBUST_POSES = 6
#: A pose left out of a least-squares fit is this many times further off the fit of the others than
#: the worst of them is (and beyond core.robust.FLOOR of the reference).
DELETED_FACTOR = 6.0


def fit_least_squares(given: SolverInput) -> Fit:
    """least-squares: :func:`least_squares` on the labels' directions; with ROBUST_POSES or more
    (unless ``settings.robust`` is False) a pose far off the fit of the others is left out and
    named (:func:`_deleted`)."""
    s = given.settings
    directions = np.array([direction(str(x)) for x in given.labels])

    def solve(chosen: list[int]) -> Fit:
        names = [given.names[i] for i in chosen]
        return least_squares([given.stats[i] for i in chosen], directions[chosen], s.reference, s.tolerance_deg, names)

    def off(fit: Fit, k: int) -> float:
        m, b = fit.solution.matrix, fit.solution.offset
        return float(np.linalg.norm(m @ (given.stats[k].mean - b) - s.reference * directions[k]))

    least = ROBUST_POSES if s.robust and s.reference > 0 else len(given.stats) + 1
    return _deleted(given, solve, off, least, lambda chosen: design_rank(directions[chosen]) >= 4)


def _deleted(
    given: SolverInput,
    solve: Callable[[list[int]], Fit],
    off: Callable[[Fit, int], float],
    least: int,
    enough: Callable[[list[int]], bool],
) -> Fit:
    """A fit over pose means that leaves out the pose worst off the fit of the others (its deleted
    residual, ``off``) while it is beyond core.robust.FLOOR of the reference and DELETED_FACTOR
    times the worst residual of the others' own fit, ``least`` poses or more left (``enough``: the
    poses the fit can do without). A fit over many parameters spreads a pose made in a disturbed
    field over every pose's residual (a bound over the whole fit's residuals, or over every pose's
    deleted residual, missed one 15 % off among eight); the others' fit without it does not. None
    left out: the plain fit, each pose's outliers named in the Fit (stretches of its samples)."""
    kept = list(range(len(given.stats)))
    plain = solve(kept)
    floor = robust.FLOOR * given.settings.reference
    if len(kept) < least or max(off(plain, k) for k in kept) < floor / LEVERAGE:
        return plain  # no pose near the floor: none can be off the others' fit by it (one fit, not one a pose)
    out: list[tuple[int, float, float]] = []  # (pose, its deleted residual, the bound it was beyond)
    while len(kept) >= least:
        fits = {}
        for k in kept:
            others = [i for i in kept if i != k]
            if enough(others):
                try:
                    fits[k] = solve(others)
                except CaptureRejected:  # the others alone too poorly spread: this pose is needed
                    continue
        if not fits:
            break
        worst = max(fits, key=lambda k: off(fits[k], k))
        others_worst = max(off(fits[worst], i) for i in kept if i != worst)
        bound = max(floor, DELETED_FACTOR * others_worst)
        if off(fits[worst], worst) <= bound:
            break
        out.append((worst, off(fits[worst], worst), bound))
        kept.remove(worst)
    if not out:
        return plain
    left = np.zeros(len(given.stats), dtype=bool)
    left[[k for k, _, _ in out]] = True
    runs = tuple(robust.LeftOutRun(k, k, worst / given.settings.reference) for k, worst, _ in out)
    return replace(solve(kept), outliers=_pose_outliers(given, left, runs, min(b for _, _, b in out), 0.0))


def fit_sphere(given: SolverInput) -> Fit:
    """sphere: :func:`sphere` on the pose means; with SPHERE_POSES to LEAVE_ONE_OUT poses (unless
    ``settings.robust`` is False) a pose far off the fit of the others is left out and named, as
    least-squares' are (:func:`_deleted`)."""
    stats, ref = given.stats, given.settings.reference
    means, errors = np.array([p.mean for p in stats]), np.array([p.stderr for p in stats])

    def solve(chosen: list[int]) -> Fit:
        return sphere(means[chosen], errors[chosen], ref)

    def off(fit: Fit, k: int) -> float:
        return float(abs(norm_residuals(means[k : k + 1], fit.solution.offset, fit.solution.matrix, ref)[0]))

    robustly = given.settings.robust and ref > 0 and SPHERE_POSES < len(stats) <= LEAVE_ONE_OUT
    return _deleted(given, solve, off, SPHERE_POSES + 1 if robustly else len(stats) + 1, lambda _: True)


#: A pose's deleted residual is its residual over 1 - its leverage: within this many times it for
#: a leverage up to 0.9, so a fit whose poses all lie within the floor over it leaves none out.
LEVERAGE = 10.0
#: Fewest poses a sphere fit is made from without one left out (its 9 parameters, and 3 to spare),
#: and the most it judges by leaving each out in turn (a log's thousands of blocks: a fit each).
SPHERE_POSES, LEAVE_ONE_OUT = 12, 60


def _pose_outliers(
    given: SolverInput, out: BoolArray, runs: tuple[robust.LeftOutRun, ...], bound: float, scale: float
) -> robust.Outliers:
    """Poses a fit over pose means left out (``out``), as stretches of their samples in turn (as
    the pipeline names a turned capture's: each file and its rows), each with its run's worst."""
    sizes = [len(v) for v in given.values]
    starts = np.cumsum([0, *sizes])
    worst = {k: run.worst for run in runs for k in range(run.first, run.last + 1)}
    stretches = tuple(
        robust.LeftOutRun(int(starts[k]), int(starts[k + 1]) - 1, worst.get(int(k), float("nan")))
        for k in np.flatnonzero(out)
    )
    return robust.Outliers(int(sum(sizes[k] for k in np.flatnonzero(out))), int(starts[-1]), stretches, bound, scale)


def fit_ellipsoid(given: SolverInput) -> Fit:
    """ellipsoid: :func:`sphere` on every sample, outliers trimmed (core.robust) unless
    ``settings.robust`` is False."""
    ref = given.settings.reference
    return _trimmed(
        given,
        lambda points: sphere(points, None, ref, what="samples"),
        lambda points: rough_ellipsoid(points, ref),
    )


def fit_minmax(given: SolverInput) -> Fit:
    """minmax: :func:`minmax` on every sample, outliers trimmed as the ellipsoid's."""
    plane = given.settings.plane

    def midpoint(points: FloatArray) -> tuple[FloatArray, FloatArray]:
        return minmax_offset(points, plane), np.eye(3)

    return _trimmed(given, lambda points: minmax(points, plane), midpoint)


def _trimmed(
    given: SolverInput,
    solve: Callable[[FloatArray], Fit],
    rough: Callable[[FloatArray], tuple[FloatArray, FloatArray]],
) -> Fit:
    """``solve`` on the samples of every pose that core.robust's trimmed refit keeps (its rounds
    fitted by ``rough``, an offset and M without the solver's checks, which outliers still in the
    samples could trip): the Fit with the samples left out said (``outliers``), its residuals
    those of the samples kept, its checks (coverage) judged on them."""
    points = np.concatenate(list(given.values))
    ref = given.settings.reference
    if not given.settings.robust or not ref > 0:
        return solve(points)
    minmax_like = given.method == "minmax"

    def residuals(fitted: tuple[FloatArray, FloatArray], at: FloatArray) -> FloatArray:
        offset, matrix = fitted
        if minmax_like:  # hard iron only, in raw units: against the samples' median radius
            return _radius_residuals(at, offset, given.settings.plane, ref)
        return norm_residuals(at, offset, matrix, ref)

    kept = robust.screen(points)
    if kept.all():  # nothing screened out: the plain fit, kept when it leaves nothing out (one fit)
        try:
            plain = solve(points)
        except CaptureRejected:  # (its checks tripped by outliers still in: the rounds below)
            plain = None
        if plain is not None:
            first = (plain.solution.offset, plain.solution.matrix)
            if robust.bounds(residuals(first, points), kept, ref)[0].all():
                return plain
    done = robust.trimmed(points, ref, rough, residuals, kept)
    if done.left_out == 0:
        return solve(points)
    try:
        fitted = solve(points[done.kept])
    except CaptureRejected as err:  # the good part alone too poorly spread: said so, not blamed on a glitch
        raise CaptureRejected(
            f"{err.message} (judged on the {done.kept.sum():,} samples kept: {done.left_out:,} outliers left out)",
            file=err.file,
            hint=err.hint,
            code=err.code,
        ) from err
    outliers = robust.Outliers(done.left_out, len(points), done.stretches, done.bound, done.scale)
    return replace(fitted, outliers=outliers)


def _radius_residuals(at: FloatArray, offset: FloatArray, plane: str | None, ref: float) -> FloatArray:
    """min/max's residuals: each sample's distance from the centre (in its plane, for a 2-D
    min/max) less their median, scaled so that the median radius reads ``ref`` (min/max has no
    gains: its corrected readings keep the raw units)."""
    axes = [i for i in range(3) if plane is None or "xyz"[i] in plane]
    distance = np.linalg.norm((at - offset)[:, axes], axis=1)
    radius = float(np.nanmedian(distance)) if len(distance) else 0.0
    out: FloatArray = (distance - radius) * (ref / radius) if radius > 0 else distance * 0.0
    return out


def fit_gyro_bias(given: SolverInput) -> Fit:
    """gyro-bias: :func:`gyro_bias`."""
    return gyro_bias(given.stats)


def fit(
    method: str,
    stats: Sequence[PoseStats],
    values: Sequence[FloatArray],
    labels: Sequence[str | None],
    settings: SolverSettings,
    names: Sequence[str],
) -> Fit:
    """Run ``method`` (resolved by :func:`pick`, poses in its order) on the poses: the function
    of its catalog row. The methods that take turns are run by their own readers
    (pipeline.solve.turns, pipeline.solve.rotations)."""
    row = catalog.find(method)
    if row is None or row.takes == "turns":
        raise ValueError(f"unknown method {method!r}")
    fn = cast(Solver, catalog.solver(method))
    return fn(SolverInput(method, stats, values, labels, names, settings))
