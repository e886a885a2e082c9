"""A table of orientations: one capture whose rows are separate poses, one averaged reading each
(a logger that stores a row per orientation; Hassan & Bao's 49 orientations), recognised by
``core.methods.orientation_table`` or taken so with ``--rows-are-poses``, and split into one
pose per row. solve then fits them as that many poses (sphere for 12 or more, by the rules of
``core.methods``), with the noise per pose unknown: the sphere takes it from its residuals.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import catalog, methods, model
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import readings
from tumblecal_cli.pipeline.frames import read_pose, samples_of

if TYPE_CHECKING:
    from tumblecal_cli.io.csv.readings import Samples
    from tumblecal_cli.pipeline.options import Settings, SolveOptions


def table_methods() -> tuple[str, ...]:
    """The methods a table's rows can be given to: an accelerometer's that take several poses'
    means (core.catalog), and auto."""
    return (
        "auto",
        *(
            m.name
            for m in catalog.rows()
            if m.takes == "means" and "accelerometer" in m.sensors and m.family != "one-pose"
        ),
    )


@dataclass(frozen=True)
class TablePoses:
    """The rows of the table(s) as poses, and the note that says why they were taken so."""

    rows: list[Samples]
    note: str


def take(poses: object, options: SolveOptions, given: Settings) -> tuple[TablePoses | None, Samples | None]:
    """The rows of ``poses`` as poses when they are a table: ``(table, None)``. A single pose file
    read to find out that it is not one comes back as ``(None, samples)`` (stdin is read once);
    ``(None, None)`` when ``poses`` cannot be a table (several, labelled, or --no-rows-are-poses).

    Recognised without --rows-are-poses: one unlabelled capture, no --up, an accelerometer, a
    method that takes several poses, no time column and no --rate (a log's samples are timed),
    and rows that point in different directions from one to the next (orientation_table)."""

    forced = options.rows_are_poses
    items = _unlabelled(poses)
    if forced is False or (forced is None and (items is None or len(items) != 1 or options.up is not None)):
        return None, None
    if items is None or options.up is not None:
        raise InputError(
            "--rows-are-poses takes unlabelled captures: each row is a pose of unknown orientation",
            hint="give the table's file without a label or --up (FILE, not +z=FILE)",
        )
    if forced is None and (options.read.sensor != "accelerometer" or given.method not in table_methods()):
        return None, None
    read = [_read(item, options) for item in items]
    if forced is None:
        centre = np.zeros(3) if given.centre is None else given.centre
        timed = read[0].layout.time is not None or options.read.rate is not None  # a log's samples, or a pose's
        why = None if timed else methods.orientation_table(read[0].values, centre)
        if why is None:
            return None, read[0] if isinstance(items[0], str) else None
        note = (
            f"{os.path.basename(read[0].layout.name)}: {len(read[0].values)} rows taken as {len(read[0].values)} "
            f"poses, one orientation each: {why}, and it has no time column (--no-rows-are-poses takes it as "
            "one pose)"
        )
    else:
        count = sum(len(s.values) for s in read)
        note = f"{count} rows taken as {count} poses, one orientation each (--rows-are-poses)"
    return TablePoses([row for s in read for row in split(s, options)], note), None


def _unlabelled(poses: object) -> list[object] | None:
    """The items of ``poses`` when none has a label: paths (``FILE``, not ``LABEL=FILE``) or
    data in memory given without one; None when any is labelled (a mapping, ``+z=FILE``)."""
    if isinstance(poses, Mapping):
        return None
    items: list[object]
    if isinstance(poses, str | os.PathLike) or hasattr(poses, "shape") or hasattr(poses, "columns"):
        items = [poses]
    elif isinstance(poses, Sequence):
        items = list(poses)
    else:
        return None
    out: list[object] = []
    for item in items:
        if isinstance(item, str | os.PathLike):
            text = os.fspath(item)
            label, sep, _ = text.partition("=")
            if sep and label and _is_label(label):
                return None
            out.append(text)
        else:
            out.append(item)
    return out


def _is_label(text: str) -> bool:
    try:
        model.parse_label(text)
    except ValueError:
        return False
    return True


def _read(item: object, options: SolveOptions) -> Samples:
    if isinstance(item, str):
        return read_pose(item, options)
    return samples_of("data", item, options)


def split(samples: Samples, options: SolveOptions) -> list[Samples]:
    """One pose per row of ``samples``, each named for its data row (``table.csv row 7``)."""
    first, last = samples.rows
    count = len(samples.values)
    if last - first + 1 == count:  # no empty row skipped: the readings are the rows in order
        numbers = list(range(first, last + 1))
    elif samples.layout.name != "<stdin>" and os.path.exists(samples.layout.name):  # read the rows again
        numbers = [int(r) for r in readings.read_log(samples.layout.name, options.read, use_time=False).rows]
    else:
        numbers = list(range(count))
    return [
        replace(
            samples,
            values=samples.values[k : k + 1],
            rows=(n, n),
            duration=None,
            temperature=None,
            row=True,
            summary=None,  # (a long file's running sums are the whole file's, not its row's)
        )
        for k, n in enumerate(numbers)
    ]
