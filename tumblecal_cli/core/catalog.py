"""The solvers there are, one row each (:class:`Method`): what a method takes, what it fits,
the limits that do not apply to it and why, its source, and the function that solves it; and the
quality checks there are (:data:`CHECKS`, :data:`FIT_CHECKS`), which ``--no-check`` names.

Everything that asks about a method asks here: ``core.fits.fit`` dispatches through the
row, ``core.methods.pick`` checks the labels by its family, the gate reads which limits apply,
solve, segment and the exporters read its flags, and the command line's ``--method`` choices
and help are its names in order. A new solver is one row (:func:`register`) and its function.

No numpy here (and no dataclasses: the rows are NamedTuples), so that ``tumblecal --help`` builds
its ``--method`` choices without importing them: a row names its function as
``"module:function"``, imported when first asked for (:func:`solver`)."""

from __future__ import annotations

import importlib
from typing import Literal, NamedTuple

#: What a solver takes: each pose's mean (and spread), every sample of a capture turned through
#: many orientations, or a gyroscope's turns in a log (fitted by pipeline.solve.turns and
#: pipeline.solve.rotations, which call the row's function themselves).
Takes = Literal["means", "samples", "turns"]
TAKES = ("means", "samples", "turns")
SENSORS = ("accelerometer", "magnetometer", "gyroscope")


class NotApplying(NamedTuple):
    """A limit that does not apply to a method (its ``limit``, as named in a limits file with
    ``_`` for ``-``), and ``why``, said in the note ``the minmax solver <why>, so the residual
    limit does not apply``."""

    limit: str
    why: str


GAINS_FIXED = NotApplying("gain_error", "fixes the gains at 1")
NO_CROSS_AXIS = NotApplying("cross_axis", "estimates no cross-axis terms")
TURNED_NOISE = NotApplying("noise", "fits a capture turned through many orientations (its spread is the turning)")
NO_MODEL = NotApplying("residual", "has no fitted model to measure residuals against")
#: The limits a method may declare not applying, in the order their notes are said.
LIMITS = ("gain_error", "cross_axis", "noise", "residual")

#: The quality checks of each pose (exit 3), in the order the gate judges them (a pose is
#: rejected for the first that fails), each by the last part of its code (``pose.<check>``):
#: core.gate.JUDGES holds the function that judges a pose under each.
CHECKS = ("short", "saturated", "orientation", "moved", "upside_down")
#: The checks of a whole fit, not of each pose (``--no-check`` names them too).
FIT_CHECKS = ("coverage",)


def check_names() -> tuple[str, ...]:
    """The checks as ``--no-check`` names them (``upside-down``): each pose's in alphabetical
    order, then the fit's."""
    return (*sorted(name.replace("_", "-") for name in CHECKS), *FIT_CHECKS)


class Method(NamedTuple):
    """One solver, as everything outside it needs to know it.

    - ``name``: the ``--method`` and the calibration file's ``method``.
    - ``family``: the methods that take the same poses and are checked alike (``one-pose``,
      ``three-pose``, ``six-pose``, ``least-squares``, ``sphere``, ``magnetometer``,
      ``gyroscope``, ``turns``, ``rotations``); ``core.methods.pick`` checks the labels of the
      first five, segment picks a log's blocks by them.
    - ``sensors``: the sensors it is meant for (a table of orientations is tried on the
      accelerometer's methods that take several poses).
    - ``takes``: see :data:`Takes`.
    - ``fits_gains``: False where the gains are fixed at 1 (then no gain is trimmed, judged or
      divided by).
    - ``uses_faces``: whether it reads the poses' labels (faces or directions); an
      orientation-free one is given none.
    - ``turned``: fitted to a capture turned through many orientations, which is meant to move
      (no moved check, no trimming to a still run; the residual limit judges the fit's).
    - ``at_rest``: solves with ``--reference 0`` too (a gyroscope at rest: no stimulus).
    - ``not_applying``: the limits that do not apply to it and why.
    - ``source``: the document it implements (docs/sources.md), and where in it.
    - ``help``: one line: what it takes and what it estimates.
    - ``solver``: ``"module:function"``, the function (:func:`solver`); for the methods that
      take means or samples it takes a ``core.fits.SolverInput`` and returns a
      ``core.solvers.Fit``."""

    name: str
    family: str
    sensors: tuple[str, ...]
    takes: Takes
    fits_gains: bool
    uses_faces: bool
    turned: bool
    at_rest: bool
    not_applying: tuple[NotApplying, ...]
    source: str
    help: str
    solver: str

    @property
    def judges_gains(self) -> bool:
        """Whether its gains are judged for a units mistake (core.gate.check_gains): gains
        fitted to still poses against the reference (a turned capture's or a gyroscope's turns'
        gains are not in the reference's units)."""
        return self.fits_gains and self.takes == "means"


_ROWS: dict[str, Method] = {}
_FUNCTIONS: dict[str, object] = {}


def register(method: Method) -> Method:
    """Add ``method`` to the catalog, after those there (the ``--method`` choices keep this
    order). A name taken, or ``auto``, is a programming error."""
    if method.name in _ROWS or method.name == "auto":
        raise ValueError(f"a solver named {method.name!r} is registered already")
    if method.takes not in TAKES or not set(method.sensors) <= set(SENSORS):
        raise ValueError(f"solver {method.name!r}: takes {method.takes!r}, sensors {method.sensors!r}")
    if any(n.limit not in LIMITS for n in method.not_applying):
        raise ValueError(f"solver {method.name!r}: a limit not applying is one of {', '.join(LIMITS)}")
    _ROWS[method.name] = method
    return method


def rows() -> tuple[Method, ...]:
    """Every registered method, in the order registered."""
    return tuple(_ROWS.values())


def names(*, family: str | None = None, takes: str | None = None) -> tuple[str, ...]:
    """The names of the methods (of one ``family``, or that take ``takes``), in order."""
    return tuple(
        m.name for m in _ROWS.values() if (family is None or m.family == family) and (takes is None or m.takes == takes)
    )


def find(name: str) -> Method | None:
    """The row of ``name``; None for ``auto`` or a name no row has (a file from elsewhere)."""
    return _ROWS.get(name)


def solver(name: str) -> object:
    """The function of ``name``'s row, imported when first asked for (its caller knows its
    signature: :class:`Method`'s ``solver``)."""
    if name not in _FUNCTIONS:
        module, _, function = _ROWS[name].solver.partition(":")
        found = getattr(importlib.import_module(module), function)
        if not callable(found):
            raise TypeError(f"solver {name!r}: {_ROWS[name].solver} is not a function")
        _FUNCTIONS[name] = found
    return _FUNCTIONS[name]


# What the rest asks of one method by name. A name with no row (``auto``, or a file's method
# from elsewhere) is none of these, as it was in none of the tuples they replace.


def fixes_gains(name: str) -> bool:
    """Whether ``name``'s gains are fixed at 1."""
    m = _ROWS.get(name)
    return m is not None and not m.fits_gains


def judges_gains(name: str) -> bool:
    """Whether ``name``'s gains are judged for a units mistake (:attr:`Method.judges_gains`)."""
    m = _ROWS.get(name)
    return m is not None and m.judges_gains


def turned(name: str) -> bool:
    """Whether ``name`` fits a capture turned through many orientations."""
    m = _ROWS.get(name)
    return m is not None and m.turned


def orientation_free(name: str) -> bool:
    """Whether ``name`` ignores the poses' labels."""
    m = _ROWS.get(name)
    return m is not None and not m.uses_faces


def at_rest(name: str) -> bool:
    """Whether ``name`` solves with ``--reference 0``."""
    m = _ROWS.get(name)
    return m is not None and m.at_rest


def family(name: str) -> str | None:
    """``name``'s family (None: no row)."""
    m = _ROWS.get(name)
    return None if m is None else m.family


def not_applying(name: str) -> dict[str, str]:
    """{limit: why} of the limits that do not apply to ``name``, in the order of LIMITS."""
    m = _ROWS.get(name)
    reasons = {} if m is None else {n.limit: n.why for n in m.not_applying}
    return {limit: reasons[limit] for limit in LIMITS if limit in reasons}


_FITS = "tumblecal_cli.core.fits"
_FACES = ("accelerometer",)
_STILL = (GAINS_FIXED, NO_CROSS_AXIS)  # offsets only

register(
    Method(
        "one-pose",
        "one-pose",
        _FACES,
        "means",
        fits_gains=False,
        uses_faces=True,
        turned=False,
        at_rest=True,
        not_applying=_STILL,
        source="Vitali 2018, eqs. 1-3 (offset = mean - v)",
        help="1 face: offsets (gains 1)",
        solver=f"{_FITS}:fit_one_pose",
    )
)
register(
    Method(
        "one-pose-tilt",
        "one-pose",
        _FACES,
        "means",
        fits_gains=False,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=_STILL,
        source="Ding and Uchida 2012 (patent CN102313822), eqs. 2-5",
        help="1 face, the attitude from the readings: offsets (gains 1), the up one immune to tilt",
        solver=f"{_FITS}:fit_one_pose_tilt",
    )
)
register(
    Method(
        "three-pose",
        "three-pose",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(NO_CROSS_AXIS,),
        source="Vitali 2018 (3-point tumble)",
        help="one face per axis, either sign: offsets, gains",
        solver=f"{_FITS}:fit_three_pose",
    )
)
register(
    Method(
        "six-pose",
        "six-pose",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="Ferraris et al. 1995 (imucal's form), ST DT0053",
        help="the six faces: offsets, gains, cross-axis terms (full M)",
        solver=f"{_FITS}:fit_six_pose",
    )
)
register(
    Method(
        "six-pose-diagonal",
        "six-pose",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(NO_CROSS_AXIS,),
        source="Ferraris et al. 1995, ST DT0053, per axis",
        help="the six faces: offsets, gains from the vertical readings only",
        solver=f"{_FITS}:fit_six_pose",
    )
)
register(
    Method(
        "six-pose-magnitude",
        "six-pose",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(NO_CROSS_AXIS,),
        source="Sports Sensing 2023 (its model with T = I, on the six poses)",
        help="the six faces: offsets, gains from each pose's magnitude (immune to hand placement)",
        solver=f"{_FITS}:fit_six_pose",
    )
)
register(
    Method(
        "least-squares",
        "least-squares",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="ST AN4508 (the 12-parameter linear fit)",
        help="4+ faces or directions: offsets, full M (12 parameters)",
        solver=f"{_FITS}:fit_least_squares",
    )
)
register(
    Method(
        "sphere",
        "sphere",
        _FACES,
        "means",
        fits_gains=True,
        uses_faces=False,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="Tedaldi et al. 2014 (orientation-free fit), Sports Sensing 2023 (judged by the norm)",
        help="12+ static poses, any orientation: offsets, upper-triangular M",
        solver=f"{_FITS}:fit_sphere",
    )
)
register(
    Method(
        "minmax",
        "magnetometer",
        ("magnetometer",),
        "samples",
        fits_gains=False,
        uses_faces=False,
        turned=True,
        at_rest=True,
        not_applying=(*_STILL, TURNED_NOISE, NO_MODEL),
        source="Okasho n.d. (offset = (max + min) / 2)",
        help="samples turned through all orientations (or turned in one plane): hard iron",
        solver=f"{_FITS}:fit_minmax",
    )
)
register(
    Method(
        "ellipsoid",
        "magnetometer",
        ("magnetometer",),
        "samples",
        fits_gains=True,
        uses_faces=False,
        turned=True,
        at_rest=False,
        not_applying=(TURNED_NOISE,),
        source="the sphere fit of Tedaldi et al. 2014 on every sample, M symmetric (magcal-style)",
        help="samples turned through many orientations: hard iron, symmetric soft iron M",
        solver=f"{_FITS}:fit_ellipsoid",
    )
)
register(
    Method(
        "gyro-bias",
        "gyroscope",
        ("gyroscope",),
        "means",
        fits_gains=False,
        uses_faces=False,
        turned=False,
        at_rest=True,
        not_applying=_STILL,
        source="no document: at rest the true rate is 0, so the mean of still captures is the bias",
        help="still captures: zero-rate bias",
        solver=f"{_FITS}:fit_gyro_bias",
    )
)
register(
    Method(
        "ferraris-turns",
        "turns",
        ("gyroscope",),
        "turns",
        fits_gains=True,
        uses_faces=True,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="Ferraris et al. 1995 (imucal's form)",
        help="one labelled log, the six faces then known turns about 3 axes: bias, full M, g-sensitivity",
        solver="tumblecal_cli.core.turn_fit:ferraris",
    )
)
register(
    Method(
        "known-rates",
        "rates",
        ("gyroscope",),
        "turns",
        fits_gains=True,
        uses_faces=False,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="IEEE Std 952-1997 and 1431-2004 (the rate transfer test); the magnitude fit as the ellipsoid's",
        help="files spun at known rates (a rate table, a record player): bias, gains, cross-axis terms",
        solver="tumblecal_cli.core.spin:fit_rates",
    )
)
register(
    Method(
        "rotations",
        "rotations",
        ("gyroscope",),
        "turns",
        fits_gains=True,
        uses_faces=False,
        turned=False,
        at_rest=False,
        not_applying=(),
        source="Tedaldi et al. 2014, sect. III-C (imu_tk's gyroscope step)",
        help="one log, still poses joined by hand turns, the accelerometer calibrated: M, bias from the still blocks",
        solver="tumblecal_cli.core.rotation_fit:fit",
    )
)
