"""The command line: the Typer app and its error boundary (``app``), one module per command or
small group of commands, the options they share (``options``) and what people read (``render``).

Each command parses its options, makes one call into ``tumblecal_cli.pipeline`` and renders the
result; the pipeline is imported inside the commands (batch reads the names of SolveOptions,
whose module imports no numpy), so ``tumblecal --help`` loads no numpy.
"""

import importlib

from tumblecal_cli.cli.app import app, main, main_exit

#: The command modules, in the order `tumblecal --help` lists their commands (registration order).
COMMANDS = (
    "solve",
    "apply",
    "thermal",
    "calfiles",
    "report",
    "verify",
    "segment",
    "noise",
    "streams",
    "aligning",
    "batch",
)
for _name in COMMANDS:
    importlib.import_module(f"tumblecal_cli.cli.{_name}")

__all__ = ["COMMANDS", "app", "main", "main_exit"]
