"""The command line: one module per command (or small group of commands), each named for it.
Its modules:

- ``app``: the Typer application and the one error boundary (every error its exit status).
- ``flags``: the options and choices several commands share, defined once.
- ``render``: what people read on stderr (Rich tables), and the data commands print on stdout.
- ``solve``, ``apply``, ``thermal``, ``current``, ``report``, ``verify``, ``segment``, ``noise``,
  ``logs``, ``align``, ``batch``: the command of that name.
- ``calfiles``: the commands on calibration files: show, check, export and import.
- ``records``: the records database's commands (import, history, trend, migrate), and how
  ``--record`` saves a calibration with its record.

Each command parses its options, makes one call into ``tumblecal_cli.pipeline`` and renders the
result; the pipeline is imported inside the commands (batch takes solve's parameters, all but
``solve.CLI_ONLY``, from the command itself), so ``tumblecal --help`` loads no numpy.
"""

import importlib

from tumblecal_cli.cli.app import app, main, main_exit

#: The command modules, in the order `tumblecal --help` lists their commands (registration order).
COMMANDS = (
    "solve",
    "apply",
    "thermal",
    "current",
    "calfiles",
    "report",
    "verify",
    "segment",
    "noise",
    "logs",
    "align",
    "batch",
    "records",
)
for _name in COMMANDS:
    importlib.import_module(f"tumblecal_cli.cli.{_name}")

__all__ = ["COMMANDS", "app", "main", "main_exit"]
