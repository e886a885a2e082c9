"""A stand-in export format, registered in one place: the ``register_export`` call below (and
its ``EXPORTERS``, the writer the row names). tests/test_extension_export.py shows the installed
command line offering it and running it end to end.

A format registers before the command line is built, so the test runs the command as

    python -c "import tests.standin_export; from tumblecal_cli.cli.app import main_exit; main_exit()" \\
        export --format standin cal.json -o out

(from the repository's root; ``main_exit`` reads its arguments from ``sys.argv``). The test
process itself never imports this module: its command line was built without the stand-in.
"""

from __future__ import annotations

from tumblecal_cli.io.calfiles.calfile import Calibration
from tumblecal_cli.io.export.contract import Exported, Exporter, ExportOptions
from tumblecal_cli.io.export.registry import ExportFormat, register_export


def export_standin(cal: Calibration, options: ExportOptions) -> Exported:
    """One line: the sensor, the method and the offsets, as Python writes floats; a note for people."""
    offset = " ".join(repr(float(v)) for v in cal.offset)
    return Exported(f"standin {cal.sensor} {cal.method} {offset}\n", ("the stand-in wrote one line",))


EXPORTERS: dict[str, Exporter] = {"standin": export_standin}

register_export(ExportFormat("standin", "one line of the sensor, method and offsets (a test's stand-in)", __name__))
