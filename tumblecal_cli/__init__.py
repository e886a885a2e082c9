"""tumblecal: calibrate 3-axis sensors from static tumble poses and correct captures.

The Python API (docs/python.md)::

    import tumblecal_cli as tumblecal

    solved = tumblecal.solve(["x.csv", "y.csv", "z.csv"], reference=1.0, limits="limits.yaml", serial="A17")
    solved.status                      # 0 pass, 1 outside its limits, 3 rejected
    solved.calibration.save("cal.json")
    cal = tumblecal.load("cal.json")
    corrected = cal.apply(df)          # a DataFrame, or (n, 3) readings
    warm = tumblecal.thermal(["+z=up.csv", "-z=down.csv"], "cal.json").calibration
    corrected = warm.apply(df)         # each row at the DataFrame's temperature column

Layers, imports flowing one way: ``cli`` (Typer, Rich) -> ``pipeline`` (what a user does) ->
``io`` (files) -> ``core`` (numpy only). The names below are loaded when first used, so
``import tumblecal_cli`` (and ``tumblecal --help``) imports no numpy. An error's words about the
command line (``--reference``) are the same from the Python API: the core says them by a code,
``err.said``, and ``pipeline.hints`` words each code.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from tumblecal_cli.errors import CaptureRejected, InputError, TumblecalError, use_words
from tumblecal_cli.pipeline.hints import WORDS
from tumblecal_cli.version import __version__

# The words the core says about the command line (a flag it names by a code): installed first,
# so whatever is imported after reads them (pipeline.hints).
use_words(WORDS)

if TYPE_CHECKING:
    from tumblecal_cli.io.calfiles.calfile import Calibration, load
    from tumblecal_cli.io.sources import streams
    from tumblecal_cli.pipeline.apply import correct
    from tumblecal_cli.pipeline.batch.units import run_batch
    from tumblecal_cli.pipeline.current import CurrentResult, current
    from tumblecal_cli.pipeline.exchange import check, export, import_peer
    from tumblecal_cli.pipeline.frames import read_capture
    from tumblecal_cli.pipeline.noise import Noise, noise
    from tumblecal_cli.pipeline.options import SolveOptions
    from tumblecal_cli.pipeline.records.history import history_table
    from tumblecal_cli.pipeline.records.trend import Trended, trend
    from tumblecal_cli.pipeline.report import report
    from tumblecal_cli.pipeline.segment import segment
    from tumblecal_cli.pipeline.solve.solving import Solved, solve, solve_log
    from tumblecal_cli.pipeline.thermal import ThermalResult, thermal
    from tumblecal_cli.pipeline.verify import verify, verify_rotations

#: Each public name and the module that holds it.
_HOMES = {
    "Calibration": "tumblecal_cli.io.calfiles.calfile",
    "load": "tumblecal_cli.io.calfiles.calfile",
    "streams": "tumblecal_cli.io.sources",
    "solve": "tumblecal_cli.pipeline.solve.solving",
    "solve_log": "tumblecal_cli.pipeline.solve.solving",
    "Solved": "tumblecal_cli.pipeline.solve.solving",
    "SolveOptions": "tumblecal_cli.pipeline.options",
    "read_capture": "tumblecal_cli.pipeline.frames",
    "correct": "tumblecal_cli.pipeline.apply",
    "segment": "tumblecal_cli.pipeline.segment",
    "verify": "tumblecal_cli.pipeline.verify",
    "verify_rotations": "tumblecal_cli.pipeline.verify",
    "noise": "tumblecal_cli.pipeline.noise",
    "Noise": "tumblecal_cli.pipeline.noise",
    "report": "tumblecal_cli.pipeline.report",
    "check": "tumblecal_cli.pipeline.exchange",
    "export": "tumblecal_cli.pipeline.exchange",
    "import_peer": "tumblecal_cli.pipeline.exchange",
    "run_batch": "tumblecal_cli.pipeline.batch.units",
    "thermal": "tumblecal_cli.pipeline.thermal",
    "ThermalResult": "tumblecal_cli.pipeline.thermal",
    "current": "tumblecal_cli.pipeline.current",
    "CurrentResult": "tumblecal_cli.pipeline.current",
    "history_table": "tumblecal_cli.pipeline.records.history",
    "trend": "tumblecal_cli.pipeline.records.trend",
    "Trended": "tumblecal_cli.pipeline.records.trend",
}

__all__ = [
    "Calibration",
    "CaptureRejected",
    "CurrentResult",
    "InputError",
    "Noise",
    "SolveOptions",
    "Solved",
    "ThermalResult",
    "Trended",
    "TumblecalError",
    "__version__",
    "check",
    "correct",
    "current",
    "export",
    "history_table",
    "import_peer",
    "load",
    "noise",
    "read_capture",
    "report",
    "run_batch",
    "segment",
    "solve",
    "solve_log",
    "streams",
    "thermal",
    "trend",
    "verify",
    "verify_rotations",
]


def __getattr__(name: str) -> object:
    """The public names, imported on first use (PEP 562)."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'tumblecal_cli' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value
    return value
