"""Monte-Carlo benchmark: each solver's error against its Cramér–Rao bound, both from the same run.

    python tests/montecarlo.py [--trials N] [--seed S]

Not a test (pytest does not collect it; tests/test_montecarlo.py runs it). For each solver a fixed
truth ``(b, A)`` is captured ``--trials`` times with white Gaussian noise, solved with the solver's
public function, and each parameter's RMS error over the trials is divided by its Cramér–Rao
standard deviation, computed here from the Fisher information of the model (docs/reference/model.md)::

    m_k = A · reference · u_k + b + e_k,    e_k ~ N(0, σ²/n · I)        (pose means, k = 1..N)
    CRB = inv(Jᵀ Σ⁻¹ J),                    J = d(all m_k) / d(parameters)

Each pose mean is drawn directly from N(A v_k + b, σ²/n): the same distribution as the mean of n
samples of σ white noise, at a fraction of the cost. The parameters of each model:

- ``rigid``: every pose's direction ``u_k`` is known exactly. one-pose: b (A = I); three-pose
  (+x +y +z, and -x +y -z) and six-pose-diagonal: b and diag(A); six-pose and least-squares: b and all of A.
- ``tilt``: each pose's direction is known only up to a small unknown fixture tilt, two nuisance
  angles per pose (first order: ``d m_k / dδ = A · reference · w`` for the two unit vectors ``w``
  perpendicular to ``u_k``). This is the model the six-pose (Ferraris) solver is built for: it
  takes each offset from the vertical readings of opposite faces only, ``b_i = (m[+i]_i +
  m[-i]_i) / 2``, which costs √3 in offset noise against the rigid model, where the ML offset is
  the mean of all six poses. Under tilt, b and diag(A) are identifiable only with the cross-axis
  terms held at their true values (with them free, a tilt moves a vertical reading by
  ``reference · A_ij · δ``, so the gains are not identifiable either: see the notes printed
  below the table); the cross-axis terms are compared with the rigid model, where the Ferraris
  difference ``(m[+j] - m[-j]) / (2 reference)`` is the ML estimate.
- ``free-dir`` (sphere): every direction is unknown, two nuisance angles per pose, A upper
  triangular; the 9 x 9 (b, upper A) block of the inverse of the full Fisher matrix.

The RMS from T trials has a relative standard deviation of about 1/√(2T) (2.2 % at 1000), so the
tolerances (10 % for the linear solvers, 25 % for the non-linear sphere fit) leave room for
statistics, not for a wrong estimator. Exit status 1 when any group is outside its tolerance.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import methods, solvers
from tumblecal_cli.core import model as core
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import PoseStats, Solution

SIGMA = 0.01  # raw units, 1 sigma per sample
SAMPLES = 200  # samples per pose
REFERENCE = 1.0
SEED = 20240917
TRIALS = 1000
TILT_TOLERANCE_DEG = 1.0  # only feeds the solvers' tilt bounds, which are not benchmarked here

TRUE_OFFSET = np.array([0.05, -0.03, 0.02])
TRUE_GAIN = np.array([1.02, 0.97, 1.01])
TRUE_CROSS = np.array([[0.0, 0.012, -0.02], [0.015, 0.0, 0.006], [-0.01, 0.018, 0.0]])

#: Parameters are indexed in the packed vector (b_x, b_y, b_z, A_xx, A_xy, ..., A_zz).
NAMES = ("b_x", "b_y", "b_z", *(f"A_{r}{c}" for r in "xyz" for c in "xyz"))
OFFSET = (0, 1, 2)
GAIN = (3, 7, 11)
CROSS = (4, 5, 6, 8, 9, 10)
UPPER_CROSS = (4, 5, 8)  # A_xy, A_xz, A_yz
ALL = tuple(range(12))

LINEAR_TOLERANCE = 0.10
SPHERE_TOLERANCE = 0.25


# -- the Fisher information of the pose means -------------------------------------------------


@dataclass(frozen=True)
class Model:
    """What is unknown: ``params`` (indices into the packed (b, A)), and, if ``angles``, two
    nuisance angles per pose (its direction known only to first order, or not at all)."""

    name: str
    params: tuple[int, ...]
    angles: bool = False


def perpendicular(u: FloatArray) -> FloatArray:
    """(2, 3): two orthonormal unit vectors perpendicular to the unit vector ``u``."""
    basis: FloatArray = np.linalg.svd(u[None, :])[2][1:]
    return basis


def jacobian(model: Model, a: FloatArray, directions: FloatArray, reference: float) -> FloatArray:
    """d(pose means, flattened pose by pose) / d(model parameters, then the angles): (3N, P + 2N).

    ``m_k = A · reference · u_k + b``: d m_k / d b_i = e_i, d m_k / d A_ij = reference · u_kj · e_i,
    and turning ``u_k`` by δ towards a perpendicular ``w`` moves it by ``A · reference · w · δ``.
    """
    count = len(directions)
    columns = []
    for p in model.params:
        col = np.zeros((count, 3))
        if p < 3:
            col[:, p] = 1.0
        else:
            i, j = divmod(p - 3, 3)
            col[:, i] = reference * directions[:, j]
        columns.append(col.ravel())
    if model.angles:
        for k, u in enumerate(directions):
            for w in perpendicular(u):
                col = np.zeros((count, 3))
                col[k] = reference * (a @ w)
                columns.append(col.ravel())
    return np.column_stack(columns)


def fisher(
    model: Model, a: FloatArray, directions: FloatArray, reference: float, sigma: float, samples: int
) -> FloatArray:
    """``Jᵀ Σ⁻¹ J`` with ``Σ = σ²/n · I`` (independent white noise on every axis of every pose)."""
    jac = jacobian(model, a, directions, reference)
    info: FloatArray = (jac.T @ jac) * (samples / sigma**2)
    return info


def identifiable(model: Model, a: FloatArray, directions: FloatArray, reference: float = REFERENCE) -> dict[int, bool]:
    """Whether each parameter of ``model`` is identifiable: its unit vector lies in the range of
    the Fisher matrix (a singular Fisher matrix can still bound some parameters)."""
    info = fisher(model, a, directions, reference, 1.0, 1)
    info = info / np.abs(info).max()
    projector = info @ np.linalg.pinv(info, rcond=1e-10)
    eye = np.eye(len(info))
    return {p: bool(np.linalg.norm(projector[:, c] - eye[:, c]) < 1e-6) for c, p in enumerate(model.params)}


def crb(
    model: Model,
    a: FloatArray,
    directions: FloatArray,
    reference: float = REFERENCE,
    sigma: float = SIGMA,
    samples: int = SAMPLES,
) -> dict[int, float]:
    """Cramér–Rao standard deviation of each parameter of ``model``: the square root of the
    diagonal of ``inv(Fisher)``, its (params x params) block when there are nuisance angles.
    ValueError when the Fisher matrix is singular (some parameter is not identifiable)."""
    info = fisher(model, a, directions, reference, sigma, samples)
    if np.linalg.matrix_rank(info / np.abs(info).max(), tol=1e-10) < len(info):
        lost = [NAMES[p] for p, ok in identifiable(model, a, directions, reference).items() if not ok]
        raise ValueError(f"{model.name}: the Fisher matrix is singular; not identifiable: {', '.join(lost)}")
    cov = np.linalg.inv(info)
    return {p: math.sqrt(cov[c, c]) for c, p in enumerate(model.params)}


# -- the cases: a solver, its truth and poses, and what to compare it with ---------------------------


@dataclass(frozen=True)
class Check:
    """Compare the RMS error of ``indices`` (one group) with their CRB under ``model``; the ratio
    should be ``expected`` (1 for an efficient estimator)."""

    group: str  # offset / gain / cross
    indices: tuple[int, ...]
    model: Model
    expected: float = 1.0


@dataclass(frozen=True)
class Case:
    solver: str
    directions: FloatArray  # (N, 3) unit vectors, the poses
    a: FloatArray  # true A
    solve: Callable[[Sequence[PoseStats]], Solution]
    checks: tuple[Check, ...]
    tolerance: float


def fibonacci_directions(count: int) -> FloatArray:
    """``count`` well-spread unit vectors (the Fibonacci lattice on the sphere)."""
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    r = np.sqrt(1.0 - z * z)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    result: FloatArray = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    return result


def label(u: FloatArray) -> str:
    return core.parse_label(",".join(f"{x:.12g}" for x in u))


def cases(reference: float = REFERENCE) -> list[Case]:
    six = np.array([core.FACES[f] for f in methods.SIX_FACES])
    three = np.array([core.FACES[f] for f in ("+x", "+y", "+z")])
    mixed = np.array([core.FACES[f] for f in ("-x", "+y", "-z")])
    tetra = np.array([(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)]) / math.sqrt(3.0)
    ls_directions = np.vstack([six, tetra])
    ls_names = [label(u) for u in ls_directions]
    diagonal = np.diag(TRUE_GAIN)
    full = diagonal + TRUE_CROSS
    upper = diagonal + np.triu(TRUE_CROSS, 1)

    rigid_b = Model("rigid", OFFSET)
    rigid_bg = Model("rigid", OFFSET + GAIN)
    rigid_all = Model("rigid", ALL)
    # tilt: the cross-axis terms (not identifiable under tilt) held at their true values
    tilt_bg = Model("tilt", OFFSET + GAIN, angles=True)
    free = Model("free-dir", OFFSET + GAIN + UPPER_CROSS, angles=True)
    # six-pose takes each offset from 2 of the 6 poses: sqrt(6/2) above the rigid CRB, by design
    ferraris = math.sqrt(3.0)

    return [
        Case(
            "one-pose",
            three[2:],
            np.eye(3),
            lambda p: core.solve_one_pose(p[0], "+z", reference),
            (Check("offset", OFFSET, rigid_b),),
            LINEAR_TOLERANCE,
        ),
        Case(
            "three-pose",
            three,
            diagonal,
            lambda p: core.solve_three_pose(p, reference),
            (Check("offset", OFFSET, rigid_bg), Check("gain", GAIN, rigid_bg)),
            LINEAR_TOLERANCE,
        ),
        Case(
            "six-pose",
            six,
            full,
            lambda p: solvers.six_pose(p, reference, TILT_TOLERANCE_DEG).solution,
            (
                Check("offset", OFFSET, tilt_bg),
                Check("offset", OFFSET, rigid_all, ferraris),
                Check("gain", GAIN, tilt_bg),
                Check("gain", GAIN, rigid_all),
                Check("cross", CROSS, rigid_all),
            ),
            LINEAR_TOLERANCE,
        ),
        Case(
            "six-pose-diagonal",
            six,
            diagonal,
            lambda p: solvers.six_pose(p, reference, TILT_TOLERANCE_DEG, "six-pose-diagonal").solution,
            (
                Check("offset", OFFSET, tilt_bg),
                Check("offset", OFFSET, rigid_bg, ferraris),
                Check("gain", GAIN, tilt_bg),
                Check("gain", GAIN, rigid_bg),
            ),
            LINEAR_TOLERANCE,
        ),
        Case(
            "least-squares",
            ls_directions,
            full,
            lambda p: solvers.least_squares(p, ls_directions, reference, TILT_TOLERANCE_DEG, ls_names).solution,
            (Check("offset", OFFSET, rigid_all), Check("gain", GAIN, rigid_all), Check("cross", CROSS, rigid_all)),
            LINEAR_TOLERANCE,
        ),
        Case(
            "sphere",
            fibonacci_directions(24),
            upper,
            lambda p: (
                solvers.sphere(np.array([q.mean for q in p]), np.array([q.stderr for q in p]), reference).solution
            ),
            (Check("offset", OFFSET, free), Check("gain", GAIN, free), Check("cross", UPPER_CROSS, free)),
            SPHERE_TOLERANCE,
        ),
        Case(
            "three-pose -x +y -z",  # one face per axis, mixed signs (last: the others keep their seeds)
            mixed,
            diagonal,
            lambda p: core.solve_three_pose(p, reference, faces=("-x", "+y", "-z")),
            (Check("offset", OFFSET, rigid_bg), Check("gain", GAIN, rigid_bg)),
            LINEAR_TOLERANCE,
        ),
    ]


# -- the run ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """One solver's parameter group against one model's CRB."""

    solver: str
    check: Check
    rms: FloatArray  # per parameter of the group
    bound: FloatArray  # CRB standard deviation, per parameter
    reported: FloatArray | None  # mean over trials of the solver's own 1-sigma, per parameter
    tolerance: float

    @property
    def ratio(self) -> FloatArray:
        result: FloatArray = self.rms / self.bound
        return result

    @property
    def worst(self) -> float:
        """Largest ``|RMS / CRB / expected - 1|`` over the group."""
        return float(np.abs(self.ratio / self.check.expected - 1.0).max())

    @property
    def passed(self) -> bool:
        return self.worst <= self.tolerance


def packed(solution: Solution) -> FloatArray:
    """(b, A row by row) of a solution, A = inv(M)."""
    return np.concatenate([solution.offset, np.linalg.inv(solution.matrix).ravel()])


def simulate(
    case: Case, trials: int, rng: np.random.Generator, *, offset: FloatArray = TRUE_OFFSET, reference: float = REFERENCE
) -> tuple[FloatArray, FloatArray]:
    """Errors of the packed (b, A) over ``trials`` captures (trials, 12), and the solver's own
    1-sigma of (b, gains) (trials, 6)."""
    ideal = reference * case.directions @ case.a.T + offset  # (N, 3) noise-free pose means
    truth = np.concatenate([offset, case.a.ravel()])
    noise = rng.normal(0.0, SIGMA / math.sqrt(SAMPLES), size=(trials, *ideal.shape))
    std = np.full(3, SIGMA)
    errors = np.empty((trials, 12))
    reported = np.empty((trials, 6))
    for t in range(trials):
        poses = [PoseStats(mean=m, std=std, samples=SAMPLES) for m in ideal + noise[t]]
        solution = case.solve(poses)
        errors[t] = packed(solution) - truth
        reported[t] = np.concatenate([solution.offset_se, solution.gain_se])
    return errors, reported


def benchmark(trials: int = TRIALS, seed: int = SEED) -> list[Row]:
    rows = []
    for index, case in enumerate(cases()):
        errors, reported = simulate(case, trials, np.random.default_rng((seed, index)))
        rms = np.sqrt((errors**2).mean(axis=0))
        se = reported.mean(axis=0)
        for check in case.checks:
            bound = crb(check.model, case.a, case.directions)
            idx = list(check.indices)
            own = {0: se[0], 1: se[1], 2: se[2], 3: se[3], 7: se[4], 11: se[5]}
            rows.append(
                Row(
                    solver=case.solver,
                    check=check,
                    rms=rms[idx],
                    bound=np.array([bound[i] for i in idx]),
                    reported=np.array([own[i] for i in idx]) if all(i in own for i in idx) else None,
                    tolerance=case.tolerance,
                )
            )
    return rows


def identifiability_notes() -> list[str]:
    """What the tilt model can and cannot identify when the cross-axis terms are free as well."""
    six = np.array([core.FACES[f] for f in methods.SIX_FACES])
    notes = []
    for what, a in (("cross-axis terms", np.diag(TRUE_GAIN) + TRUE_CROSS), ("diagonal A", np.diag(TRUE_GAIN))):
        model = Model("tilt", ALL, angles=True)
        ok = identifiable(model, a, six)
        groups = [("offsets", OFFSET), ("gains", GAIN), ("cross", CROSS)]
        yes = [g for g, idx in groups if all(ok[i] for i in idx)]
        no = [g for g, idx in groups if not any(ok[i] for i in idx)]
        some = [g for g, idx in groups if g not in yes + no]
        parts = [f"identifiable: {', '.join(yes) or '-'}", f"not: {', '.join(no) or '-'}"]
        if some:
            parts.append(f"partly: {', '.join(some)}")
        notes.append(f"six faces, tilt model with all 12 of (b, A) free, truth with {what}: " + "; ".join(parts))
    return notes


def table(rows: Sequence[Row]) -> str:
    """The rows as plain aligned text: text columns left, figures right."""
    header = ["solver", "group", "CRB model", "CRB mean", "RMS/CRB mean", "expected", "worst |r/e-1|", "tol"]
    lines = [[*header, "se/RMS", "result"]]
    for r in rows:
        lines.append(
            [
                r.solver,
                f"{r.check.group} ({len(r.check.indices)})",
                r.check.model.name,
                f"{float(np.mean(r.bound)):.4g}",
                f"{float(np.mean(r.ratio)):.3f}",
                f"{r.check.expected:.3f}",
                f"{r.worst:.1%}",
                f"{r.tolerance:.0%}",
                "-" if r.reported is None else f"{float(np.mean(r.reported / r.rms)):.3f}",
                "PASS" if r.passed else "FAIL",
            ]
        )
    widths = [max(len(line[c]) for line in lines) for c in range(len(lines[0]))]
    out = []
    for line in lines:
        cells = [
            cell.ljust(w) if c < 3 else cell.rjust(w) for c, (cell, w) in enumerate(zip(line, widths, strict=True))
        ]
        out.append("  ".join(cells).rstrip())
    out.insert(1, "-" * len(out[0]))
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--trials", type=int, default=TRIALS, help=f"captures per solver (default {TRIALS})")
    parser.add_argument("--seed", type=int, default=SEED, help=f"random seed (default {SEED})")
    args = parser.parse_args(argv)
    if args.trials < 2:
        parser.error("--trials must be at least 2")
    start = time.perf_counter()
    rows = benchmark(args.trials, args.seed)
    elapsed = time.perf_counter() - start
    print(
        f"Monte-Carlo vs Cramér–Rao: {args.trials} trials per solver, seed {args.seed}, "
        f"σ = {SIGMA:g} per sample, n = {SAMPLES} samples per pose, reference {REFERENCE:g}"
    )
    print(table(rows))
    print()
    print(
        f"RMS/CRB: mean over the group (the RMS from {args.trials} trials is good to "
        f"±{1 / math.sqrt(2 * args.trials):.1%}, 1 sigma); expected: 1 for an efficient estimator, "
        f"√3 = {math.sqrt(3):.3f} for the six-pose offsets against the rigid bound (each from 2 of the 6 poses)"
    )
    print("se/RMS: the solver's own reported 1-sigma (mean over trials) over the RMS error")
    for note in identifiability_notes():
        print(note)
    failed = [r for r in rows if not r.passed]
    print(f"{len(rows) - len(failed)}/{len(rows)} groups within tolerance; {elapsed:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
