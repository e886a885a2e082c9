"""Where an export or import format plugs in: one registry of each, in the order ``--help`` lists
them (the ``Exporter`` and ``Importer`` contracts a format keeps are io.export.contract's).

A row says what the command line needs to know (the name, its words in ``--help``, which of
export's options it takes) and the module that implements it; the module is imported only when
the format is used, so ``tumblecal --help`` reads the registry without numpy. The module holds
``EXPORTERS`` (or ``IMPORTERS``): the format's name to its implementation, typed by the contract
so that mypy checks it. The rows are NamedTuples, not dataclasses: ``tumblecal --help`` reads them
and imports no dataclasses module for them. A format added anywhere (a test's stand-in among them) is one
``register_export`` or ``register_import`` call before the command line is built
(docs/development.md, "Extension points").
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import TYPE_CHECKING, NamedTuple

from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    from tumblecal_cli.io.export.contract import Exporter, Importer


class ExportFormat(NamedTuple):
    """One export format: its ``name`` (``--format``), its words in ``--help`` (rows in a run with the
    same words are listed together), the ``module`` whose ``EXPORTERS`` holds it, the options of
    ``ExportOptions`` it ``takes``, those it ``needs`` with why, and whether it writes a calibration's
    ``current`` block (a format without: the block is left out, with a warning)."""

    name: str
    help: str
    module: str
    takes: frozenset[str] = frozenset()
    needs: tuple[tuple[str, str], ...] = ()
    current: bool = False

    def exporter(self) -> Exporter:
        """The format's writer, its module imported now."""
        found: Mapping[str, Exporter] = importlib.import_module(self.module).EXPORTERS
        return found[self.name]


class ImportFormat(NamedTuple):
    """One import format: its ``name`` (``--from``), the file as an error names it (``described``),
    and the ``module`` whose ``IMPORTERS`` holds it."""

    name: str
    described: str
    module: str

    def importer(self) -> Importer:
        """The format's reader, its module imported now."""
        found: Mapping[str, Importer] = importlib.import_module(self.module).IMPORTERS
        return found[self.name]


_FORMATS = "tumblecal_cli.io.export.formats"
_PARAMFILE = "tumblecal_cli.io.export.paramfile"
_PEERS = "the peer tools' own files"
_AUTOPILOTS = (
    "the autopilot's parameters (a .parm file of INS_ACC/INS_GYR/COMPASS_, a QGroundControl .params file of "
    "CAL_ACC/CAL_GYRO/CAL_MAG; a thermal block as INS_TCAL or TC_A/TC_G)"
)
_REGISTERS = frozenset({"lsb", "bits", "register_sign", "gain_step", "nominal_gain"})

#: export's formats (docs/commands/export-import.md), in the order --help lists them.
EXPORTS: dict[str, ExportFormat] = {
    row.name: row
    for row in (
        ExportFormat("c-header", "C99/C++ header for firmware", _FORMATS, frozenset({"prefix"})),
        ExportFormat(
            "registers",
            "offset (and gain trim) register counts, CSV",
            _FORMATS,
            _REGISTERS,
            needs=(("lsb", "the raw units of one register count"),),
        ),
        ExportFormat("imucal-json", _PEERS, _FORMATS),
        ExportFormat("ros-yaml", _PEERS, _FORMATS),
        ExportFormat("matlab", _PEERS, _FORMATS),
        ExportFormat("ardupilot", _AUTOPILOTS, _PARAMFILE, frozenset({"instance"}), current=True),
        ExportFormat("px4", _AUTOPILOTS, _PARAMFILE, frozenset({"instance"}), current=True),
    )
}
#: import's formats, in the order a file's keys are tried against them.
IMPORTS: dict[str, ImportFormat] = {
    row.name: row
    for row in (
        ImportFormat("imucal-json", "an imucal JSON (cal_type, K_a …)", _FORMATS),
        ImportFormat("ros-yaml", "a ROS imu_calib YAML (SM, bias)", _FORMATS),
    )
}


def register_export(row: ExportFormat) -> None:
    """Add an export format (after the others in --help); a name taken is an error, not a replacement."""
    if row.name in EXPORTS:
        raise ValueError(f"export format {row.name!r} is registered already")
    EXPORTS[row.name] = row


def register_import(row: ImportFormat) -> None:
    """Add an import format (tried after the others); a name taken is an error, not a replacement."""
    if row.name in IMPORTS:
        raise ValueError(f"import format {row.name!r} is registered already")
    IMPORTS[row.name] = row


def export_format(name: str) -> ExportFormat:
    """The row of ``--format name``; an InputError naming the formats there are."""
    row = EXPORTS.get(name)
    if row is None:
        raise InputError(f"--format: {name!r} is not one of {', '.join(EXPORTS)}")
    return row


def owners(option: str) -> str:
    """The formats that take ``option``, as a message names them ("ardupilot and px4")."""
    return " and ".join(row.name for row in EXPORTS.values() if option in row.takes)


def export_help() -> str:
    """``--format``'s help: each format's words, formats in a run with the same words listed together."""
    runs: list[tuple[list[str], str]] = []
    for row in EXPORTS.values():
        if runs and runs[-1][1] == row.help:
            runs[-1][0].append(row.name)
        else:
            runs.append(([row.name], row.help))
    listed = "; ".join(f"{', '.join(names)}: {words}" for names, words in runs)
    return f"{listed} (docs/commands/export-import.md)."
