"""The solvers beyond 1- and 3-pose: six-pose (with and without cross-axis terms), N-pose least
squares, the orientation-free sphere fit, tilt-compensated 1-pose, magnetometer min/max and
ellipsoid, gyroscope bias. numpy only (the core layer, docs/development.md).

Every solver works in the model of docs/reference/model.md, ``raw = A v + b``, ``corrected =
M (raw - b)``, ``M = inv(A)``, and returns a :class:`~tumblecal_cli.core.model.Solution`. The
solvers fitted to pose means share one propagation (:func:`_propagate`): the parameters
``(b, A)`` are functions of the means, so their covariance is ``J diag(se^2) J^T`` with ``J``
the Jacobian by central differences (exact for the linear solvers), and their worst-case shift
under fixture tilt comes from the same ``J`` (Vitali 2018 notes, Ding and Uchida 2012: a
horizontal reading moves by ``gain·reference·sin θ``, the vertical one by
``gain·reference·(1 - cos θ)``).

Sources cited below (docs/sources.md): Vitali 2018 (ST design tip on tumble calibration,
pointing to ST DT0053 for the 6-point and N-point forms), Sports Sensing 2023 (the
``T·S·(a + o)`` model, judged by the norm of many static poses), Okasho n.d. (magnetometer hard
iron by min/max), Ding and Uchida 2012 (patent CN102313822, bias with an assumed attitude);
Ferraris et al. 1995 (the 6-position form imucal implements); ST AN4508 (the 12-parameter linear
fit); Tedaldi et al. 2014 (orientation-free fit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.gate import beyond, turn_hint
from tumblecal_cli.core.methods import SIX_FACES, face_evidence
from tumblecal_cli.core.model import (
    FACES,
    PoseStats,
    Reach,
    Solution,
)
from tumblecal_cli.core.robust import Outliers
from tumblecal_cli.errors import CaptureRejected, InputError, said

#: A face with no sample within this angle leaves the orientation-free fits undetermined.
FACE_COVERAGE_DEG = 60.0
#: Coverage: the share of these 26 directions (a cube's faces, edges, corners) with a sample
#: within COVERAGE_CAP_DEG.
_CUBE = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)])
CUBE_DIRECTIONS = _CUBE / np.linalg.norm(_CUBE, axis=1)[:, None]
COVERAGE_CAP_DEG = 45.0
#: How coverage names its directions: "+z", "+x+z", "-x+y+z".
CUBE_NAMES = tuple("".join(f"{'+' if c > 0 else '-'}{a}" for c, a in zip(v, "xyz", strict=True) if c) for v in _CUBE)

Params = tuple[FloatArray, FloatArray]  # (b, A)


@dataclass(frozen=True)
class Fit:
    """What every solver reports beyond :class:`Solution`: per-pose residuals, coverage, notes."""

    solution: Solution
    residuals: FloatArray | None = None  # per pose (or sample), |M (raw - b)| - reference, output units
    coverage: float | None = None  # 0-1, the share of directions the samples span
    covariance: FloatArray | None = None  # (12, 12) of (b, A row by row)
    cross_se: FloatArray | None = None  # (3, 3) 1-sigma of A's off-diagonal terms (0 on the diagonal)
    tilt: tuple[FloatArray, FloatArray, FloatArray] | None = None  # offset, gain, cross-axis shifts
    notes: tuple[str, ...] = ()
    reach: Reach | None = None  # a turned capture's (ellipsoid, 3-D min/max): how near it comes to each direction
    outliers: Outliers | None = None  # the samples a robust fit left out (core.robust); None: none


# -- six-pose -------------------------------------------------------------------------------


def _six_pose(means: FloatArray, reference: float) -> Params:
    """Ferraris et al. 1995 (the form imucal implements), 6-point tumble of Vitali 2018 / ST DT0053.

    ``means`` are the +x -x +y -y +z -z poses. Each offset is the mean of the two *vertical*
    readings of its axis (opposite faces: the stimulus cancels, and a vertical reading moves only
    to second order with fixture tilt); each column ``j`` of ``A`` is the difference of the two
    poses of axis ``j`` over twice the reference (the stimulus is ``±reference·e_j``)::

        b_i = (m[+i]_i + m[-i]_i) / 2        A[:, j] = (m[+j] - m[-j]) / (2 reference)
    """
    plus, minus = means[0::2], means[1::2]  # rows: axis x, y, z
    b = 0.5 * (np.diag(plus) + np.diag(minus))
    a = ((plus - minus) / (2.0 * reference)).T  # column j from the pair of axis j
    return b, a


def _six_pose_diagonal(means: FloatArray, reference: float) -> Params:
    """The per-axis part of :func:`_six_pose`: offsets and gains from the vertical readings only
    (no cross-axis terms, so a tilted, hand-placed pose does not leak into them)."""
    b, a = _six_pose(means, reference)
    return b, np.diag(np.diag(a))


def _six_pose_magnitude(means: FloatArray, reference: float) -> Params:
    """Offsets ``b`` and gains ``k`` from each pose's *magnitude*, not its direction:
    ``|(m_p - b) / k| = reference`` for the six poses, six equations in six unknowns, solved by
    Newton's method from :func:`_six_pose_diagonal`. How a pose is tilted about its face changes
    which axes share the stimulus, never its magnitude, so hand placement does not leak into
    these parameters; the price is that no cross-axis term is estimated (the model of Sports
    Sensing 2023 with ``T = I``, fitted on the six poses alone)."""
    b, a = _six_pose_diagonal(means, reference)
    k = np.diag(a).copy()
    if not (np.all(np.isfinite(k)) and np.all(k != 0)):
        return b, np.full((3, 3), np.nan)
    for _ in range(100):
        u = (means - b) / k
        r = np.linalg.norm(u, axis=1)
        if not np.all(r > 0):
            break
        jac = np.hstack([-u / (k * r[:, None]), -(u**2) / (k * r[:, None])])  # d|u| / d(b, k)
        try:
            step = np.linalg.solve(jac, reference - r)
        except np.linalg.LinAlgError:
            return b, np.full((3, 3), np.nan)
        b, k = b + step[:3], k + step[3:]
        if np.abs(step[3:]).max() <= 1e-15 * np.abs(k).max() and np.abs(step[:3]).max() <= 1e-15 * (
            np.abs(b).max() + np.abs(k).max()
        ):
            break
    converged = np.allclose(np.linalg.norm((means - b) / k, axis=1), reference, rtol=1e-9)
    return b, np.diag(k) if converged and np.all(k > 0) else np.full((3, 3), np.nan)


# -- least squares ---------------------------------------------------------------------------


def _least_squares(means: FloatArray, directions: FloatArray, reference: float) -> Params:
    """ST AN4508: the 12-parameter linear fit ``[v 1]·W = raw`` over N >= 4 poses.

    AN4508 writes the fit in the correcting direction (true = W·[raw 1]); here it is written in
    the measuring one, ``raw_k = A v_k + b`` with ``v_k = reference·u_k``, so that the least
    squares runs over the noisy quantity (the raw means) and is the maximum-likelihood fit for
    white noise. Each column of ``W`` (one raw axis) is an ordinary least-squares problem.
    """
    design = np.column_stack([reference * directions, np.ones(len(directions))])
    w = np.asarray(np.linalg.lstsq(design, means, rcond=None)[0], dtype=np.float64)  # (4, 3): A^T, then b
    return w[3].copy(), w[:3].T.copy()


def design_rank(directions: FloatArray) -> int:
    """Rank of ``[u 1]``: 4 when the directions determine an offset and a full matrix."""
    design = np.column_stack([directions, np.ones(len(directions))])
    return int(np.linalg.matrix_rank(design, tol=1e-6))


# -- propagation of noise and tilt -------------------------------------------------------------


def _pack(params: Params) -> FloatArray:
    return np.concatenate([params[0], params[1].ravel()])


def _central_differences(fn: Callable[[FloatArray], FloatArray], x: FloatArray, relative: float) -> FloatArray:
    """d fn / d x, (len(fn(x)), x.size), by central differences with steps ``relative·max(1, |x_k|)``
    (exact for linear functions). ``x`` is flattened; ``fn`` takes it in its own shape."""
    flat = x.ravel()
    columns = []
    for k in range(flat.size):
        h = relative * max(1.0, abs(flat[k]))
        up, down = flat.copy(), flat.copy()
        up[k] += h
        down[k] -= h
        columns.append((fn(up.reshape(x.shape)) - fn(down.reshape(x.shape))) / (2 * h))
    return np.column_stack(columns)


def _jacobian(fn: Callable[[FloatArray], Params], means: FloatArray) -> FloatArray:
    """d(b, A)/d(means), (12, 3N) (exact for linear solvers)."""
    return _central_differences(lambda m: _pack(fn(m)), means, 1e-6)


def _propagate(
    method: str,
    fn: Callable[[FloatArray], Params],
    poses: Sequence[PoseStats],
    directions: FloatArray,
    reference: float,
    tolerance_deg: float,
    stimulus_matrix: FloatArray | None = None,
) -> Fit:
    """Solve, then the 1-sigma noise errors and the worst-case tilt shifts of every parameter.

    ``stimulus_matrix``: the ``A`` through which a tilted stimulus reaches the readings, when
    the solver's own leaves terms out (six-pose-diagonal: the cross-axis terms still leak tilt)."""
    means = np.array([p.mean for p in poses])
    b, a = fn(means)
    jac = _jacobian(fn, means)
    se2 = np.concatenate([p.stderr**2 for p in poses])
    cov = (jac * se2) @ jac.T  # J diag(se^2) J^T
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    a_sd = sd[3:].reshape(3, 3)
    tilt = _tilt(jac, a if stimulus_matrix is None else stimulus_matrix, directions, reference, tolerance_deg)
    solution = Solution(
        method=method,
        offset=b,
        matrix=_inverse(a, poses),
        offset_se=sd[:3],
        gain_se=np.diag(a_sd).copy(),
    )
    return Fit(
        solution=solution,
        residuals=norm_residuals(means, b, solution.matrix, reference),
        covariance=cov,
        cross_se=a_sd - np.diag(np.diag(a_sd)),
        tilt=tilt,
    )


def _tilt(
    jac: FloatArray, a: FloatArray, directions: FloatArray, reference: float, tolerance_deg: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Worst-case shift of each parameter when every pose is off its direction by the tolerance.

    Tilting pose k by θ about a horizontal axis ``w`` moves its mean by
    ``A·reference·(sin θ·w - (1 - cos θ)·u_k)`` (Vitali 2018 notes; Ding and Uchida 2012, the
    vertical term is a cosine). Through ``c = d(param)/d(mean_k)`` that is at worst
    ``|(c·A)_perp|·reference·sin θ + |c·A·u_k|·reference·(1 - cos θ)``; poses tilt independently,
    so the worst cases add. ``A`` is the solved one, itself off by up to the gain's relative
    shift, so the bound is scaled up by ``1 / (1 - shift)`` to stay a bound for the true ``A``.
    """
    theta = math.radians(tolerance_deg)
    s, v = math.sin(theta), 1.0 - math.cos(theta)
    shift = np.zeros(12)
    for k, u in enumerate(directions):
        ca = jac[:, 3 * k : 3 * k + 3] @ a  # (12, 3): each parameter's sensitivity to the stimulus
        along = ca @ u
        perp = np.linalg.norm(ca - np.outer(along, u), axis=1)
        shift += reference * (perp * s + np.abs(along) * v)
    shift /= 1.0 - (s + v)
    cross = shift[3:].reshape(3, 3)
    return shift[:3], np.diag(cross).copy(), cross - np.diag(np.diag(cross))


def _inverse(a: FloatArray, poses: Sequence[PoseStats]) -> FloatArray:
    if not np.all(np.isfinite(a)) or np.linalg.cond(a) > 1e12:
        raise CaptureRejected(
            "the poses do not determine the calibration matrix (it has no inverse)",
            hint="check that the poses are labelled with the faces they were captured on",
            code="poses.undetermined",
        )
    inverse = np.asarray(np.linalg.inv(a), dtype=np.float64)
    return inverse


def norm_residuals(raw: FloatArray, b: FloatArray, matrix: FloatArray, reference: float) -> FloatArray:
    """The test of a model in Sports Sensing 2023: ``|M (raw - b)| - reference`` for each pose (or sample)."""
    result: FloatArray = np.linalg.norm((raw - b) @ matrix.T, axis=1) - reference
    return result


# -- public entry points, one per method --------------------------------------------------------


_SIX = {"six-pose": _six_pose, "six-pose-diagonal": _six_pose_diagonal, "six-pose-magnitude": _six_pose_magnitude}


def six_pose(poses: Sequence[PoseStats], reference: float, tolerance_deg: float, method: str = "six-pose") -> Fit:
    """Six faces in the order +x -x +y -y +z -z; see :func:`_six_pose` and its variants."""
    directions = np.array([FACES[f] for f in SIX_FACES])
    solver = _SIX[method]

    def fn(m: FloatArray) -> Params:
        return solver(m, reference)

    if method == "six-pose":
        return _propagate("six-pose", fn, poses, directions, reference, tolerance_deg)
    means = np.array([p.mean for p in poses])
    if method == "six-pose-magnitude" and not np.all(np.isfinite(fn(means)[1])):
        _inverse(_six_pose_diagonal(means, reference)[1], poses)  # no gain at all: undetermined
        ev = face_evidence(means)
        raise CaptureRejected(
            "the six poses' magnitudes do not determine offsets and gains: "
            + ", ".join(f"{f} {a:.0f}°" for f, a in ev.angles.items())
            + " off their faces",
            hint=said("poses.tilted"),
            code="poses.tilted",
        )
    # a tilted pose reaches the diagonal solver through the cross-axis terms it leaves out; the
    # magnitude fit's own model moves it along the ellipsoid, which leaves its solution alone
    # (from where each pose actually points, not from its face)
    stimulus = None
    if method == "six-pose-diagonal":
        stimulus = _six_pose(means, reference)[1]
    else:
        b, a = fn(means)
        pointing = (means - b) / np.diag(a)
        directions = pointing / np.linalg.norm(pointing, axis=1)[:, None]
    fit = _propagate(method, fn, poses, directions, reference, tolerance_deg, stimulus_matrix=stimulus)
    return replace(fit, cross_se=None)


def least_squares(
    poses: Sequence[PoseStats], directions: FloatArray, reference: float, tolerance_deg: float, names: Sequence[str]
) -> Fit:
    """N >= 4 poses with known directions (unit vectors) not in one plane; see :func:`_least_squares`."""
    if design_rank(directions) < 4:
        raise CaptureRejected(
            f"the {len(directions)} pose directions do not determine an offset and a full matrix "
            "([direction 1] has rank " + f"{design_rank(directions)}, needs 4)",
            hint="add poses so that every axis is seen pointing up and down (the six faces do)",
            code="poses.undetermined",
        )

    def fn(m: FloatArray) -> Params:
        return _least_squares(m, directions, reference)

    fit = _propagate("least-squares", fn, poses, directions, reference, tolerance_deg)
    raw_residuals = np.array([p.mean for p in poses]) - (
        reference * directions @ np.linalg.inv(fit.solution.matrix).T + fit.solution.offset
    )
    if len(directions) == 4:  # 12 readings, 12 parameters: every pose fitted exactly
        note = (
            "4 poses determine the 12 parameters exactly: no residual is left to judge the fit by, "
            "and the cross-axis terms take any tilt of the poses (a fifth pose leaves a residual)"
        )
        return replace(fit, notes=(note,))
    worst = int(np.argmax(np.linalg.norm(raw_residuals, axis=1)))
    size = float(np.linalg.norm(raw_residuals[worst]))
    note = f"largest residual: {names[worst]}, {size:.3g} raw units from its fitted reading"
    return replace(fit, notes=(note,))


# -- orientation-free: the sphere fit (Tedaldi et al. 2014; Sports Sensing 2023's model) -----------


def _ellipsoid_start(points: FloatArray, reference: float) -> Params | None:
    """Linear ellipsoid fit: ``p^T Q p + 2 l^T p = 1`` by least squares, as the start of the
    non-linear fit. Returns (b, M) with ``M`` upper triangular, or None when the points do not
    lie on an ellipsoid (Q not positive definite)."""
    centre0 = points.mean(axis=0)
    scale = float(np.abs(points - centre0).max()) or 1.0
    p = (points - centre0) / scale
    x, y, z = p.T
    design = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z])
    coef, *_ = np.linalg.lstsq(design, np.ones(len(p)), rcond=None)
    qa, qb, qc, qd, qe, qf, lx, ly, lz = coef
    q = np.array([[qa, qd, qe], [qd, qb, qf], [qe, qf, qc]])
    try:
        centre = -np.linalg.solve(q, np.array([lx, ly, lz]))
        q = q / (1.0 + centre @ q @ centre)
        lower = np.linalg.cholesky(q * reference**2)  # M^T M = reference^2 Q, M = L^T
    except np.linalg.LinAlgError:
        return None
    return centre0 + scale * centre, lower.T / scale


def _upper(theta: FloatArray) -> FloatArray:
    m = np.zeros((3, 3))
    m[np.triu_indices(3)] = theta[3:]
    return m


def _sphere_residuals(theta: FloatArray, points: FloatArray, reference: float) -> tuple[FloatArray, FloatArray]:
    """Residuals ``|M (p - b)| - reference`` and their Jacobian over (b, upper M)."""
    b, m = theta[:3], _upper(theta)
    d = points - b
    c = d @ m.T
    norm = np.linalg.norm(c, axis=1)
    u = c / norm[:, None]
    rows, cols = np.triu_indices(3)
    jac = np.column_stack([-(u @ m), u[:, rows] * d[:, cols]])  # d/db = -M^T u; d/dM_ij = u_i d_j
    return norm - reference, jac


def rough_ellipsoid(points: FloatArray, reference: float) -> tuple[FloatArray, FloatArray]:
    """The ellipsoid's offset and M without its checks (core.robust's rounds of trimming, whose
    samples may still hold the outliers that would make a check refuse): the fit, or where it
    finds none, the least-squares sphere's centre and scale."""
    fitted = _fit_sphere(points, reference) if len(points) >= 12 else None
    if fitted is not None:
        return fitted[0][:3], _upper(fitted[0])
    centre = sphere_centre(points)
    radius = float(np.median(np.linalg.norm(points - centre, axis=1)))
    return centre, np.eye(3) * (reference / radius if radius > 0 else 1.0)


def _fit_sphere(points: FloatArray, reference: float) -> tuple[FloatArray, FloatArray] | None:
    """Levenberg-Marquardt on ``sum (|M (p - b)| - reference)^2``, M upper triangular (Tedaldi
    et al. 2014, eq. 10, with the offset-first model of Sports Sensing 2023). Returns (theta,
    Jacobian) or None."""
    start = _ellipsoid_start(points, reference)
    if start is None:
        return None
    theta = np.concatenate([start[0], start[1][np.triu_indices(3)]])
    r, jac = _sphere_residuals(theta, points, reference)
    cost, lam = float(r @ r), 1e-3
    for _ in range(200):
        jtj, grad = jac.T @ jac, jac.T @ r
        step = np.linalg.lstsq(jtj + lam * np.diag(np.diag(jtj)), -grad, rcond=None)[0]
        trial = theta + step
        r_new, jac_new = _sphere_residuals(trial, points, reference)
        new_cost = float(r_new @ r_new)
        if np.isfinite(new_cost) and new_cost <= cost:
            converged = np.linalg.norm(step) <= 1e-12 * (1.0 + np.linalg.norm(theta)) or cost - new_cost <= 1e-15 * (
                1.0 + cost
            )
            theta, r, jac, cost, lam = trial, r_new, jac_new, new_cost, max(lam / 10, 1e-12)
            if converged:
                break
        else:
            lam *= 10
            if lam > 1e12:
                break
    if np.diag(_upper(theta)).min() <= 0:  # a reflected solution: flip the sign of each row
        signs = np.sign(np.diag(_upper(theta)))
        m = _upper(theta) * signs[:, None]
        theta = np.concatenate([theta[:3], m[np.triu_indices(3)]])
        r, jac = _sphere_residuals(theta, points, reference)
    return theta, jac


def missing_faces(directions: FloatArray, within_deg: float = FACE_COVERAGE_DEG) -> list[tuple[str, float]]:
    """Faces with no direction within ``within_deg``: (face, angle to the nearest direction)."""
    out = []
    for face, vec in FACES.items():
        nearest = math.degrees(math.acos(min(1.0, float((directions @ np.asarray(vec)).max()))))
        if nearest > within_deg:
            out.append((face, nearest))
    return out


#: Directions closer than this are one direction to the sphere fit (poses re-placed on a face).
DISTINCT_DEG = 10.0
#: The sphere's 9 parameters need this many distinct directions.
SPHERE_MIN_DIRECTIONS = 9


def distinct_directions(directions: FloatArray) -> int:
    """How many of the unit ``directions`` differ by more than DISTINCT_DEG from each other
    (greedy: each joins the first kept direction within the angle, else is kept)."""
    cos = math.cos(math.radians(DISTINCT_DEG))
    rest = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    kept = 0
    while len(rest):  # the first left is kept, and every later one within the angle of it joins it:
        kept += 1  # one pass a kept direction (unit vectors 10° apart: a few hundred at most)
        first, rest = rest[0], rest[1:]
        rest = rest[rest @ first < cos]
    return kept


def coverage(directions: FloatArray) -> float:
    """The share of 26 cube directions (faces, edges, corners) with a sample within 45°."""
    cos = math.cos(math.radians(COVERAGE_CAP_DEG))
    return float((cos - 1e-12 <= CUBE_DIRECTIONS @ directions.T).any(axis=1).mean())


def reach(directions: FloatArray) -> Reach:
    """How near the unit ``directions`` come to each face and to each direction of :func:`coverage`."""
    nearest = np.degrees(np.arccos(np.clip((CUBE_DIRECTIONS @ directions.T).max(axis=1), -1.0, 1.0)))
    faces = {name: float(a) for name, a in zip(CUBE_NAMES, nearest, strict=True) if len(name) == 2}
    cos = math.cos(math.radians(COVERAGE_CAP_DEG))
    missing = np.cos(np.radians(nearest)) < cos - 1e-12  # as coverage() counts them
    gaps = sorted(((CUBE_NAMES[k], float(nearest[k])) for k in np.flatnonzero(missing)), key=lambda g: -g[1])
    return Reach({f: faces[f] for f in FACES}, tuple(gaps))


def _refuse_poor_coverage(directions: FloatArray, what: str) -> None:
    missing = missing_faces(directions)
    if missing and what == "samples":  # a turned capture: each face it misses, and which way to turn
        faces = dict(missing)
        raise CaptureRejected(
            f"the samples do not cover enough directions to determine the parameters: "
            f"{beyond(faces, FACE_COVERAGE_DEG)}",
            hint=turn_hint(faces, FACE_COVERAGE_DEG),
            code="poses.coverage",
        )
    if missing:
        face, angle = missing[0]
        others = "".join(f", {f} ({a:.0f}°)" for f, a in missing[1:])
        raise CaptureRejected(
            f"the {what} do not cover enough directions to determine the parameters: nothing within "
            f"{FACE_COVERAGE_DEG:.0f}° of {face} (nearest {angle:.0f}°){' or of ' + others[2:] if others else ''}",
            hint=f"add captures with {face} pointing up",
            code="poses.coverage",
        )


def covered(reached: Reach) -> float:
    """:func:`coverage` of the directions ``reached`` was measured on."""
    return (len(CUBE_NAMES) - len(reached.gaps)) / len(CUBE_NAMES)


def sphere_centre(points: FloatArray) -> FloatArray:
    """The centre of the sphere nearest the points: ``|p - c|^2 = r^2`` is linear in ``c`` and
    ``r^2 - |c|^2``, fitted by least squares. A capture that misses a cap of the sphere moves
    min/max's midpoint into the gap (the magcal failure) but not this centre, so the directions
    around it say how far the samples are from the missing face."""
    centre0 = points.mean(axis=0)
    p = points - centre0
    design = np.column_stack([2.0 * p, np.ones(len(p))])
    coef, *_ = np.linalg.lstsq(design, (p * p).sum(axis=1), rcond=None)
    out: FloatArray = centre0 + coef[:3]
    return out


def _directions(points: FloatArray, centre: FloatArray) -> FloatArray:
    around = points - centre
    norms = np.linalg.norm(around, axis=1)
    keep = norms > 0
    out: FloatArray = around[keep] / norms[keep, None]
    return out


def sphere(points: FloatArray, stderr: FloatArray | None, reference: float, *, what: str = "poses") -> Fit:
    """Orientation-free fit of N >= 12 static poses (or, ``ellipsoid``, of every sample of a
    magnetometer rotated through many orientations): minimise ``sum (|M (raw - b)| - reference)^2``.
    ``points`` are the pose means (or samples), ``stderr`` their (N, 3) standard errors (None for
    samples: the ellipsoid fit, whose ``M`` is made symmetric).

    The 1-sigma covariance is the sandwich ``(J^T J)^-1 J^T S J (J^T J)^-1`` with ``S`` the
    variance of each residual from its pose's sample noise (``se`` through ``M^T u``); for a
    magnetometer's samples, whose noise is not known per point, ``S`` is the residual variance.
    """
    ellipsoid = stderr is None
    if reference <= 0:
        raise InputError(said("fit.reference", fit="ellipsoid" if ellipsoid else "sphere"))
    rough = _sphere_precheck(points, what, ellipsoid=ellipsoid)
    fitted = _fit_sphere(points, reference)
    if fitted is None:
        raise _no_ellipsoid(rough, what)
    theta, jac = fitted
    b, m = theta[:3], _upper(theta)
    symmetric = m
    if ellipsoid:  # soft iron is symmetric (it does not rotate the field): M = sqrt(M^T M), |M x| alike
        w, v = np.linalg.eigh(m.T @ m)
        symmetric = (v * np.sqrt(w)) @ v.T
    directions = (points - b) @ (symmetric if ellipsoid else m).T  # in the corrected frame
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    _refuse_poor_coverage(directions, what)
    residuals = norm_residuals(points, b, m, reference)
    dof = len(points) - 9
    if stderr is None or not (stderr > 0).all():  # noise unknown (samples, one-row poses): the fit's own
        noise = np.full(len(points), float(residuals @ residuals) / max(dof, 1))
    else:
        gradient = directions @ m  # d r_k / d mean_k = M^T u_k
        noise = ((gradient**2) * stderr**2).sum(axis=1)
    scale = np.sqrt((jac**2).sum(axis=0))  # columns differ by the raw-to-output unit change (1e9 for counts)
    scale[scale == 0] = 1.0
    js = jac / scale
    jtj_inv = np.linalg.pinv(js.T @ js) / np.outer(scale, scale)
    cov_theta = jtj_inv @ (jac.T * noise) @ jac @ jtj_inv
    if ellipsoid:
        m = symmetric
    cov = _theta_to_params(theta, cov_theta, symmetric=ellipsoid)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    a_sd = sd[3:].reshape(3, 3)
    solution = Solution(
        method="ellipsoid" if ellipsoid else "sphere",
        offset=b,
        matrix=m,
        offset_se=sd[:3],
        gain_se=np.diag(a_sd).copy(),
    )
    rms = float(np.sqrt(np.mean(residuals**2)))
    reached = reach(directions) if ellipsoid else None
    return Fit(
        solution=solution,
        residuals=residuals,
        coverage=coverage(directions) if reached is None else covered(reached),
        covariance=cov,
        cross_se=a_sd - np.diag(np.diag(a_sd)),
        notes=(f"residual RMS {rms:.3g} over {len(points)} {what} ({dof} degrees of freedom)",),
        reach=reached,
    )


def _sphere_precheck(points: FloatArray, what: str, *, ellipsoid: bool) -> FloatArray:
    """Refuse what the sphere (or ellipsoid) fit cannot determine before fitting it: a face with
    nothing near it, too few distinct pose directions. Returns the directions judged, around
    min/max's midpoint for poses and around :func:`sphere_centre` for a turned capture's samples."""
    centre = sphere_centre(points) if ellipsoid else 0.5 * (points.max(axis=0) + points.min(axis=0))
    rough = _directions(points, centre)
    _refuse_poor_coverage(rough, what)
    if not ellipsoid:
        distinct = distinct_directions(rough)
        if distinct < SPHERE_MIN_DIRECTIONS:
            raise CaptureRejected(
                f"{len(points)} {what}, {distinct} distinct directions (more than {DISTINCT_DEG:g}° apart); "
                f"the sphere needs {SPHERE_MIN_DIRECTIONS}+ to determine its 9 parameters",
                hint="capture orientations between the faces (edges, corners), or label the six faces and "
                "use a face solver",
                code="poses.undetermined",
            )
    return rough


def _no_ellipsoid(rough: FloatArray, what: str) -> CaptureRejected:
    """The fit found no ellipsoid. Static poses that do not lie on one moved or mix sensors; a
    turned capture (a magnetometer's: it is meant to move) that leaves a face with no sample
    within COVERAGE_CAP_DEG is named for that face and the way to turn, which is the usual cause."""
    if what != "samples":
        return CaptureRejected(
            f"the {what} do not lie on an ellipsoid: the orientation-free fit has no solution",
            hint="check that every capture is static and of the same sensor",
            code="poses.undetermined",
        )
    faces = reach(rough).faces
    if max(faces.values()) > COVERAGE_CAP_DEG:
        return CaptureRejected(
            f"the samples do not lie on an ellipsoid the fit can find, and they leave a face uncovered: "
            f"{beyond(faces, COVERAGE_CAP_DEG)}",
            hint=turn_hint(faces, COVERAGE_CAP_DEG),
            code="poses.coverage",
        )
    return CaptureRejected(
        "the samples do not lie on an ellipsoid: the orientation-free fit has no solution",
        hint="check that the capture is of one sensor, turned in a steady field away from iron and magnets",
        code="poses.undetermined",
    )


def _theta_to_params(theta: FloatArray, cov_theta: FloatArray, *, symmetric: bool) -> FloatArray:
    """Covariance of (b, A) from that of (b, upper M), through A = inv(M) (or of its symmetric
    square root), by central differences."""

    def params(t: FloatArray) -> FloatArray:
        m = _upper(t)
        if symmetric:
            w, v = np.linalg.eigh(m.T @ m)
            m = (v * np.sqrt(w)) @ v.T
        return np.concatenate([t[:3], np.linalg.inv(m).ravel()])

    g = _central_differences(params, theta, 1e-7)
    result: FloatArray = g @ cov_theta @ g.T
    return result


# -- one pose, tilt-compensated (Ding and Uchida 2012) -----------------------------------------------


def gain_error_bound(reference: float, gain_tolerance: float) -> float:
    """How far a 1-pose up-axis offset is off for an up-axis gain error of up to ``gain_tolerance``.

    With ``raw = A·v + b`` (docs/reference/model.md) and the up axis's gain
    ``1 + ε``, that axis reads ``(1 + ε)·reference + b``; the 1-pose solver fixes the gain at 1
    (Vitali 2018 eqs. 1-3, ``offset = mean - v``), so its up offset is ``b + ε·reference``: a 1 %
    gain error moves it by 0.01 × reference. One pose cannot tell the two apart, so the bound is
    a stated tolerance, not a measurement.

    It belongs with ``tilt_sensitivity``, not ``uncertainty``: ``uncertainty`` is a 1-sigma
    estimated from the samples' noise, while this, like the tilt figures, is a worst case at a
    tolerance the user states (and that no amount of data shrinks). The two worst cases add:
    tilt lowers the up reading, and a gain below 1 lowers it too."""
    return abs(gain_tolerance) * reference


def one_pose_tilt(
    pose: PoseStats, up: str, reference: float, tolerance_deg: float, bias_spread: float, gain_tolerance: float = 0.0
) -> Fit:
    """1-pose offsets with the attitude computed from the readings (Ding and Uchida 2012, patent
    CN102313822).

    Ding and Uchida 2012, eqs. (2)-(3): with the bias assumed zero, the readings give the attitude,
    and the axis pointing up reads ``reference·cos θ`` of it. So its offset is the up reading minus
    ``reference·cos θ``, with ``cos θ = |up reading| / |mean|``: the fixture's tilt, to any order,
    no longer enters it. What remains is the assumed-zero bias of the horizontal axes, whose spread
    σ (``bias_spread``, the error variance of Ding and Uchida 2012) tilts the assumed attitude by up
    to ``δ = √2·σ / reference`` (eqs. (4)-(5)): the up offset is then off by at most
    ``reference·(cos θ - cos(θ + δ))``. The horizontal offsets are the plain 1-pose ones, with their
    first-order tilt bound ``reference·sin(tolerance)``. The up offset also absorbs the up axis's
    unknown gain error, as the 1-pose one does (:func:`gain_error_bound`).
    """
    axis = "xyz".index(up[1])
    sign = 1.0 if up[0] == "+" else -1.0

    def offsets(mean: FloatArray) -> FloatArray:
        magnitude = float(np.linalg.norm(mean))
        cos_t = min(1.0, abs(mean[axis]) / magnitude) if magnitude > 0 else 1.0
        out = mean.copy()
        out[axis] = mean[axis] - sign * reference * cos_t  # Ding and Uchida 2012 eq. (2): f_z = g cos θ + b_z
        return out

    offset = offsets(pose.mean)
    magnitude = float(np.linalg.norm(pose.mean))
    theta = math.acos(min(1.0, abs(pose.mean[axis]) / magnitude)) if magnitude > 0 else 0.0
    delta = math.sqrt(2.0) * bias_spread / reference if reference > 0 else 0.0
    vertical = reference * abs(math.cos(theta) - math.cos(min(math.pi, theta + delta)))
    tilt_offset = np.full(3, reference * math.sin(math.radians(tolerance_deg)))
    tilt_offset[axis] = vertical + gain_error_bound(reference, gain_tolerance)
    grad = _central_differences(offsets, pose.mean, 1e-6)  # d offset / d mean
    offset_se = np.sqrt((grad**2) @ pose.stderr**2)
    solution = Solution("one-pose-tilt", offset, np.eye(3), offset_se, np.zeros(3))
    note = (
        f"attitude from the readings: {math.degrees(theta):.2f}° off {up}; the {up[1]} offset "
        f"is {said('tilt.bounded', spread=bias_spread)} to ±{vertical:.2g}"
    )
    return Fit(solution=solution, tilt=(tilt_offset, np.zeros(3), np.zeros((3, 3))), notes=(note,))


# -- magnetometer: min/max (Okasho n.d.) ----------------------------------------------------------------


#: In 2-D min/max, each in-plane axis spans at least this fraction of the other's range.
PLANE_SPAN = 0.5


def minmax_offset(samples: FloatArray, plane: str | None) -> FloatArray:
    """min/max's hard iron, ``(max + min) / 2`` per axis (Okasho n.d.); in 2-D (``plane``) the
    third axis's 0, not determined."""
    offset: FloatArray = 0.5 * (samples.min(axis=0) + samples.max(axis=0))
    if plane is not None:
        offset[["xyz"[i] not in plane for i in range(3)]] = 0.0
    return offset


def minmax(samples: FloatArray, plane: str | None = None) -> Fit:
    """Hard iron from the extremes (Okasho n.d.): ``offset = (max + min) / 2`` per axis.

    In 2-D mode (``plane`` "xy", "xz" or "yz": the unit turned about the third axis) only the two
    axes in the plane are determined; the third keeps offset 0. The 1-sigma of each offset is
    that of a midpoint of two samples, ``σ/√2``, with ``σ`` the sample noise estimated from
    successive differences (``std(diff)/√2``), which a slow rotation leaves nearly untouched.
    In 3-D its :class:`Reach` says how near the samples come to each face and the bias the faces
    they miss put in the offsets (:func:`minmax_bias`), for the coverage check (core.gate).
    """
    lo, hi = samples.min(axis=0), samples.max(axis=0)
    offset = minmax_offset(samples, None)  # Okasho n.d.: (max + min) / 2
    noise = np.diff(samples, axis=0).std(axis=0) / math.sqrt(2.0) if len(samples) > 2 else np.zeros(3)
    offset_se = noise / math.sqrt(2.0)
    axes = [i for i in range(3) if plane is None or "xyz"[i] in plane]
    reached = None
    if plane is None:
        # judged around the ellipsoid's centre: around the min/max one, a capture that misses a
        # cap of the sphere looks whole (the midpoint moves into the gap: the magcal failure)
        start = _ellipsoid_start(samples, 1.0)
        directions = _directions(samples, start[0] if start is not None else sphere_centre(samples))
        _refuse_poor_coverage(directions, "samples")
        reached = reach(directions)
        cover = covered(reached)
        bias, radius = minmax_bias(lo, hi, reached.faces)
        reached = replace(reached, bias=bias, radius=radius)
    else:
        cover = _plane_coverage(samples - offset, lo, hi, plane)
    for k in range(3):
        if k not in axes:
            offset[k], offset_se[k] = 0.0, 0.0
    solution = Solution("minmax", offset, np.eye(3), offset_se, np.zeros(3))
    notes = (
        ()
        if plane is None
        else (f"2-D min/max in the {plane} plane: the {'xyz'[3 - sum(axes)]} offset is not determined (0)",)
    )
    return Fit(solution=solution, coverage=cover, notes=notes, reach=reached)


def minmax_bias(lo: FloatArray, hi: FloatArray, faces: dict[str, float]) -> tuple[FloatArray, FloatArray]:
    """How far min/max's offsets are moved by faces its samples do not reach, and the field's
    radius along each axis (raw units).

    An axis whose ``+`` face is ``θ+`` from the nearest sample reads at most ``b + R cos θ+``
    (not ``b + R``), and at least ``b - R cos θ-``: its midpoint is off by
    ``R (cos θ+ - cos θ-) / 2``: for a missing cap of half-angle θ around the ``+`` face (the
    ``-`` one reached), ``-R (1 - cos θ) / 2``, the offset too low. ``R`` is the radius these
    extremes imply, ``(max - min) / (cos θ+ + cos θ-)``."""
    plus = np.cos(np.radians([faces[f"+{a}"] for a in "xyz"]))
    minus = np.cos(np.radians([faces[f"-{a}"] for a in "xyz"]))
    radius: FloatArray = (hi - lo) / np.maximum(plus + minus, 1e-12)
    bias: FloatArray = radius * (plus - minus) / 2.0
    return bias, radius


def _plane_coverage(centred: FloatArray, lo: FloatArray, hi: FloatArray, plane: str) -> float:
    """2-D min/max: refuse a capture that did not turn in ``plane`` or did not go round it; its
    coverage is the share of 12 sectors of the plane with a sample."""
    i, j = ("xyz".index(plane[0]), "xyz".index(plane[1]))
    span = hi - lo
    if not span[i] >= PLANE_SPAN * span[j] or not span[j] >= PLANE_SPAN * span[i]:
        # a circle in the plane spans both of its axes alike (soft iron rarely 2:1); an axis
        # that hardly moved was not in the plane, and its noise would pass the gap test
        flat = "xyz"[i] if span[i] < span[j] else "xyz"[j]
        turned = "".join(sorted("xyz"[k] for k in np.argsort(span)[-2:]))
        raise CaptureRejected(
            f"the samples did not turn in the {plane} plane: {flat} spans {min(span[i], span[j]):.3g} "
            f"against {max(span[i], span[j]):.3g} (spans x {span[0]:.3g}, y {span[1]:.3g}, z {span[2]:.3g}); "
            f"it looks like the {turned} plane",
            hint=said("plane.turned", turned=turned, plane=plane),
            code="poses.coverage",
        )
    angles = np.arctan2(centred[:, j], centred[:, i])
    bins = np.unique(np.floor((angles + math.pi) / (2 * math.pi) * 12).astype(int) % 12)
    gap = _largest_gap_deg(angles)
    if gap > 90.0:
        raise CaptureRejected(
            f"the samples do not go round the {plane} plane: a gap of {gap:.0f}° with no sample "
            "(min/max needs each in-plane axis seen pointing both ways)",
            hint=f"turn the unit a full circle in the {plane} plane",
            code="poses.coverage",
        )
    return len(bins) / 12


def _largest_gap_deg(angles: FloatArray) -> float:
    a = np.sort(angles)
    gaps = np.diff(np.concatenate([a, [a[0] + 2 * math.pi]]))
    return math.degrees(float(gaps.max()))


# -- gyroscope --------------------------------------------------------------------------------------


def gyro_bias(poses: Sequence[PoseStats]) -> Fit:
    """Zero-rate bias: the sample-weighted mean of still captures (at rest the true rate is 0,
    so the mean is the bias), 1-sigma ``std / √n`` pooled."""
    n = np.array([p.samples for p in poses], dtype=np.float64)
    means = np.array([p.mean for p in poses])
    offset = (n[:, None] * means).sum(axis=0) / n.sum()
    var = sum((p.samples**2) * p.stderr**2 for p in poses) / n.sum() ** 2
    solution = Solution("gyro-bias", offset, np.eye(3), np.sqrt(var), np.zeros(3))
    return Fit(solution=solution)
