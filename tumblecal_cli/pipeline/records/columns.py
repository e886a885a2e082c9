"""A calibration as one row of the records table: its typed columns and its content key.

The parameters follow the model ``corrected = M·(raw − offset)``, ``A = M⁻¹`` (core.lot's
names, spelt as SQL columns): ``offset_x`` ... in raw units, ``gain_x`` ... ``diag(A)``,
``cross_xy`` ... ``A[i, j] / A[i, i]``, ``residual`` the RMS residual; each offset's and gain's
stated 1σ (the file's ``uncertainty``) in ``offset_x_sd`` ... ``gain_z_sd``.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.pipeline.records.store import AXES, GAINS, OFFSETS, RecordRow
from tumblecal_cli.version import __version__


def content_key(doc: Mapping[str, object], kind: str) -> str:
    """The sha256 of what a record says, its ``created`` time left out: the same calibration
    recorded again (a station script's retry, an import of the file a run recorded) has the same
    key, and adds nothing."""
    kept = {k: v for k, v in doc.items() if k != "created"}
    text = json.dumps({"kind": kind, "document": kept}, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def numbers_of(cal: calfile.Calibration) -> dict[str, float | None]:
    """The typed numbers of one calibration."""
    a = np.linalg.inv(cal.matrix)  # (load and solve have refused a singular M)
    out: dict[str, float | None] = {name: float(v) for name, v in zip(OFFSETS, cal.offset, strict=True)}
    out.update({name: float(v) for name, v in zip(GAINS, np.diag(a), strict=True)})
    for i, row in enumerate(AXES):
        for j, col in enumerate(AXES):
            if i != j:
                out[f"cross_{row}{col}"] = float(a[i, j] / a[i, i]) if a[i, i] else None
    out["residual"] = None if cal.residuals is None else cal.residuals.rms
    for family, names in (("offset", OFFSETS), ("gain", GAINS)):
        sd = cal.uncertainty.get(family)
        flat = None if sd is None else np.asarray(sd, dtype=np.float64).reshape(-1)
        for k, name in enumerate(names):
            out[f"{name}_sd"] = float(flat[k]) if flat is not None and flat.size == 3 else None
    out["reference"] = float(cal.reference)
    out["coverage"] = cal.coverage
    return out


@dataclass(frozen=True)
class Origin:
    """Where a record comes from: its ``kind``, ``lot``, the ``command`` that made it (or
    ``import``), the exit ``status`` and the file it was imported from (``source``)."""

    kind: str = "calibration"
    lot: str | None = None
    command: str = "solve"
    status: int | None = None
    source: str | None = None
    created: str | None = None  # a re-test's own time (a calibration's is its file's ``created``)
    verification: Mapping[str, object] | None = None  # a re-test's figures, kept in its document


def row_of(cal: calfile.Calibration, origin: Origin, recorded: str) -> RecordRow:
    """The record of ``cal`` (a calibration, or a re-test's judged calibration)."""
    doc = cal.to_dict()
    if origin.verification is not None:
        doc["verification"] = dict(origin.verification)
    unit = cal.unit or calfile.Unit()
    verdict = None if cal.verdict is None else ("pass" if cal.verdict.passed else "fail")
    if origin.kind == "verification":
        verdict = "fail" if origin.status else "pass"
    text = {
        "kind": origin.kind,
        "serial": unit.serial,
        "station": unit.station,
        "operator": unit.operator,
        "lot": origin.lot,
        "created": origin.created or cal.created,
        "recorded": recorded,
        "sensor": cal.sensor,
        "method": cal.method,
        "verdict": verdict,
    }
    inputs = tuple((p.file or "", p.sha256) for p in cal.poses if p.sha256)
    return RecordRow(
        key=content_key(doc, origin.kind),
        text=text,
        status=origin.status,
        numbers=numbers_of(cal),
        command=origin.command,
        source=origin.source,
        inputs=inputs,
        document=calfile.dumps(doc, "record.json"),
    )


def tool() -> str:
    """The tool that writes the records."""
    return f"tumblecal {__version__}"
