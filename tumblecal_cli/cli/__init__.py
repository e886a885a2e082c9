"""The command line: the Typer app and its error boundary (``app``), one module per command or
small group of commands, the options they share (``options``) and what people read (``render``).

Each command parses its options, makes one call into ``tumblecal_cli.pipeline`` and renders the
result; the pipeline is imported inside the commands, so ``tumblecal --help`` loads no numpy.
"""

from tumblecal_cli.cli import apply, batch, calfiles, report, segment, solve, verify
from tumblecal_cli.cli.app import app, main, main_exit

__all__ = ["app", "apply", "batch", "calfiles", "main", "main_exit", "report", "segment", "solve", "verify"]
