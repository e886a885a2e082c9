"""A synthetic six-pose production lot on disk, with known failing units and outliers, for the
lot figure and the HTML report (tests/test_lot_html.py).

Truth: offsets ~ N(0, 0.01) g, gains ~ N(1, 0.004), cross terms ~ N(0, 2e-4); limits ±0.05,
gain ±2 %, cross ±0.01 (sample_data/limits.yaml). Planted: SN0013 offset.x 0.07 (outside and an
outlier), SN0021 cross.xy 0.003 (an outlier well inside its limit), SN0042 gain.y 1.03 (outside).
Stations bay-1/bay-2, operators ana/ben, alternating."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tumblecal_cli.io.calfiles import calfile

FAILING = {"SN0013", "SN0042"}
OUTLIERS = {"SN0013": "offset.x", "SN0021": "cross.xy"}


def write_lot(folder: Path, n: int = 60, seed: int = 1) -> list[Path]:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(1, n + 1):
        serial = f"SN{k:04d}"
        offset = rng.normal(0.0, 0.01, 3)
        gain = rng.normal(1.0, 0.004, 3)
        cross = rng.normal(0.0, 2e-4, (3, 3))
        np.fill_diagonal(cross, 0.0)
        if serial == "SN0013":
            offset[0] = 0.07
        if serial == "SN0021":
            cross[0, 1] = 0.003 * gain[0]
        if serial == "SN0042":
            gain[1] = 1.03
        a = np.diag(gain) + cross
        doc = {
            "format": calfile.FORMAT,
            "version": calfile.VERSION,
            "sensor": "accelerometer",
            "method": "six-pose",
            "reference": 1.0,
            "units": "g",
            "columns": ["ax", "ay", "az"],
            "offset": [float(v) for v in offset],
            "matrix": [[float(v) for v in row] for row in np.linalg.inv(a)],
            "gain": [float(v) for v in gain],
            "unit": {"serial": serial, "station": f"bay-{1 + k % 2}", "operator": ["ana", "ben"][k % 2], "meta": {}},
            "created": f"2026-11-21T{9 + k // 60:02d}:{k % 60:02d}:00Z",
        }
        path = folder / f"{serial}_20261121.json"
        path.write_text(json.dumps(doc, indent=1))
        paths.append(path)
    return paths
