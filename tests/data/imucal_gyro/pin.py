"""Write ferraris_annotated.json: imucal's own FerrarisCalibration of its annotated session.

Run once, with imucal installed into a scratch environment (it is no dependency of tumblecal):

    pip install imucal==2.6.0
    python tests/data/imucal_gyro/pin.py tests/data/logs/imucal_annotated_session.csv.gz
"""

from __future__ import annotations

import gzip
import hashlib
import importlib.metadata
import io
import json
import sys
from pathlib import Path

import pandas as pd
from imucal import FerrarisCalibration, ferraris_regions_from_df

RATE, GRAV = 204.8, 9.81


def main(source: str) -> None:
    raw = Path(source).read_bytes()
    if source.endswith(".gz"):
        raw = gzip.decompress(raw)
    frame = pd.read_csv(io.BytesIO(raw)).set_index("part")
    out: dict[str, object] = {
        "what": "imucal's FerrarisCalibration of its example_data/annotated_session.csv",
        "produced_by": "tests/data/imucal_gyro/pin.py: ferraris_regions_from_df(frame indexed by 'part'), "
        f"FerrarisCalibration(grav={GRAV}, expected_angle=E).compute(regions, {RATE}, 'a.u.', 'a.u.')",
        "imucal_version": importlib.metadata.version("imucal"),
        "input": {
            "file": "tests/data/logs/imucal_annotated_session.csv.gz (decompressed)",
            "sha256": hashlib.sha256(raw).hexdigest(),
            "sampling_rate_hz": RATE,
            "grav": GRAV,
        },
        "license": "imucal and its example data: MIT, Copyright (c) 2018 MaD-Lab Erlangen (LICENSE in this folder)",
    }
    for angle in (-360.0, 360.0):
        cal = FerrarisCalibration(grav=GRAV, expected_angle=angle).compute(
            ferraris_regions_from_df(frame), RATE, "a.u.", "a.u."
        )
        out[f"expected_angle_{angle:+g}"] = {
            key: getattr(cal, key).tolist() for key in ("b_g", "K_g", "R_g", "K_ga", "b_a", "K_a", "R_a")
        }
    Path(__file__).with_name("ferraris_annotated.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
