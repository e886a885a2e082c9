"""A stand-in solver, registered in one place: its catalog row (:data:`ROW`) and its function
(:func:`fit`), both in this module. Importing it registers the row; nothing else in the package
names it. tests/test_extension_solver.py runs the command line with it offered::

    python -c "import tests.standin_solver; from tumblecal_cli.cli.app import main_exit; main_exit()" solve ...

which is the console script's own entry point (``tumblecal = tumblecal_cli.cli.app:main_exit``)
with the row registered first: ``--method`` is built from the catalog when the command line is
imported. The test process itself never imports this module, so its catalog holds the real
solvers only.

The solver is the per-axis six-position form (Ferraris et al. 1995): each offset the midpoint of
its axis's two faces, each gain their difference over twice the reference, no cross-axis terms.
It is in the six-pose family, so ``core.methods.pick`` checks its labels (the six faces) and puts
the poses in the order +x -x +y -y +z -z, as for six-pose."""

from __future__ import annotations

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.fits import SolverInput
from tumblecal_cli.core.model import Solution
from tumblecal_cli.core.solvers import Fit


def fit(given: SolverInput) -> Fit:
    """Offsets and gains of the six faces, per axis, with their 1-sigma from the poses' noise."""
    reference = given.settings.reference
    means = np.array([p.mean for p in given.stats])
    se = np.array([p.stderr for p in given.stats])
    plus, minus = np.diag(means[0::2]), np.diag(means[1::2])  # axis i's reading on +i and on -i
    spread = np.sqrt(np.diag(se[0::2]) ** 2 + np.diag(se[1::2]) ** 2)
    gain = (plus - minus) / (2.0 * reference)
    solution = Solution(given.method, 0.5 * (plus + minus), np.diag(1.0 / gain), 0.5 * spread, spread / (2 * reference))
    return Fit(solution=solution)


ROW = catalog.register(
    catalog.Method(
        "standin",
        "six-pose",
        ("accelerometer",),
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(catalog.NO_CROSS_AXIS,),
        source="Ferraris et al. 1995, per axis (a test's stand-in)",
        help="the six faces: offsets, gains, per axis (a test's stand-in)",
        solver="tests.standin_solver:fit",
    )
)
