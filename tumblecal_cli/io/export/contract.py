"""What an export or import format and tumblecal pass each other: the options an exporter is
given (``ExportOptions``) and what it gives back (``Exported``), a peer file's calibration as an
importer reads it (``Peer``, ``Record``), and the two contracts (``Exporter``, ``Importer``) that
each format's ``EXPORTERS`` or ``IMPORTERS`` is typed by, so that mypy checks it. The rows that
name the formats are io.export.registry's; this module is imported only when a format is used.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TypedDict

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.io.calfiles.calfile import Calibration


@dataclass(frozen=True)
class ExportOptions:
    """export's options beyond the calibration, the output and --force, as the command line or
    ``tumblecal.export`` gives them (each checked against the format's row before it is used)."""

    prefix: str | None = None
    lsb: float | None = None
    bits: int = 16
    register_sign: str = "subtract"
    gain_step: float | None = None
    nominal_gain: str | None = None
    instance: int | None = None


@dataclass(frozen=True)
class Exported:
    """An export's text, and its notes for people (a warning starts with ``warning: ``): what an
    autopilot's parameters cannot hold, a value outside the firmware's range."""

    text: str
    notes: tuple[str, ...] = ()


class Exporter(Protocol):
    """A format's writer: the text of a calibration (validated, its verdict passed or --force)
    with the options its row takes, and notes for people; an InputError for what it cannot write."""

    def __call__(self, cal: Calibration, options: ExportOptions, /) -> Exported: ...


class Record(TypedDict, total=False):
    """What a tumblecal export records of its calibration (``record``), as ``recorded`` reads it back."""

    sensor: str
    serial: str
    station: str
    operator: str
    created: str
    method: str
    input_units: str
    units: str
    reference: float
    columns: list[str]


@dataclass(frozen=True)
class Peer:
    """A calibration read from another tool's file, in tumblecal's terms; what a tumblecal export
    recorded in its comment (sensor, serial, units, reference, columns) where there is one."""

    format: str
    sensor: str
    offset: FloatArray
    matrix: FloatArray
    units: str | None
    input_units: str | None
    reference: float | None
    columns: list[str] | None
    serial: str | None
    notes: tuple[str, ...]
    was: Record = field(default_factory=Record)  # what a tumblecal export recorded (see record())


class Importer(Protocol):
    """A peer format's reader: whether a parsed file is in it (by its keys), the calibration in
    it, and what tumblecal takes when the file does not say (the columns, the reference)."""

    def claims(self, doc: Mapping[str, object]) -> bool: ...

    def read(self, doc: Mapping[str, object], path: str, sensor: str | None) -> Peer: ...

    def columns(self, sensor: str) -> list[str]: ...

    def reference(self, peer: Peer) -> float | None: ...
