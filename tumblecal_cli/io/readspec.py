"""How to read a source: one frozen value from the command line (or the Python API) down to
the reader, whatever the kind of source.

``ReadSpec`` holds what the user says of where the readings are and how the file is written:
the sensor whose triplet is read, its columns, the time column and its unit (or the rate),
the temperature column, the file's dialect, and the columns a calibration recorded. Every
reader takes one (``io.capture.open_capture``, ``io.readings.read_log`` and
``io.logread.scan_log``); a reader of another kind of source (a binary log) takes the same
value and ignores what does not apply to it (``no_header``, ``dialect``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from tumblecal_cli.errors import InputError


@dataclass(frozen=True)
class Dialect:
    """How a station wrote its file, where the sniffer should not guess (README "CSV captures"):
    ``skip_rows`` lines before the header (None: a metadata preamble is found by its field
    count), the ``decimal`` mark (None: a comma when every number of a ``;`` or tab separated
    file has one), and whether an incomplete last line (a logger stopped mid-write) is dropped."""

    skip_rows: int | None = None
    decimal: str | None = None
    drop_incomplete: bool = False

    def __post_init__(self) -> None:
        skip = self.skip_rows
        if skip is not None and (isinstance(skip, bool) or not isinstance(skip, int) or skip < 0):
            raise InputError(f"--skip-rows takes a whole number of 0 or more, got {skip!r}")
        if self.decimal not in (None, ".", ","):
            raise InputError(f"--decimal is '.' or ',', got {self.decimal!r}")


TIME_UNITS = ("auto", "s", "ms", "us", "ns")


@dataclass(frozen=True)
class ReadSpec:
    """How to read a source's readings (README "CSV captures"): ``sensor`` (accelerometer,
    gyroscope, magnetometer) names the triplet found by its column names unless ``columns``
    gives it; ``time_column`` and ``time_unit`` the clock (``rate`` in Hz when the clock is not
    to be used); ``temperature_column`` the temperature (else one of the usual names);
    ``prefer`` a calibration's recorded columns, used when a file has them all; ``stream``
    the stream of a log that holds several (``--stream NAME[:INSTANCE]``, io.sources), and
    ``allow_corrected`` whether a stream the autopilot already corrected may be read (a fit of
    it calibrates the residual, not the sensor: refused without it)."""

    sensor: str = "accelerometer"
    columns: tuple[str, ...] | None = None
    no_header: bool = False
    time_column: str | None = None
    time_unit: str = "auto"
    rate: float | None = None
    dialect: Dialect = field(default_factory=Dialect)
    temperature_column: str | None = None
    prefer: tuple[str, ...] | None = None
    stream: str | None = None
    allow_corrected: bool = False

    def __post_init__(self) -> None:  # a list given in Python is kept as a tuple (a frozen value)
        for name in ("columns", "prefer"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, tuple):
                object.__setattr__(self, name, tuple(value))


def column_list(value: str | Sequence[str] | None) -> tuple[str, ...] | None:
    """``--columns`` as given (``"ax,ay,az"``, or a sequence in Python) as names; empty is none."""
    if value is None or value == "":
        return None
    return tuple(value.split(",")) if isinstance(value, str) else tuple(str(c) for c in value)
