"""Regenerate sample_data/lot/: a synthetic production lot of 30 three-pose calibrations for the
`tumblecal report` transcript of docs/commands/report.md (run from the repo root: python tests/make_sample_lot.py).

Known truth: offsets ~ N(0, 0.01) g, gains ~ N(1, 0.004), noise 0.002 g, 200 samples per pose;
SN0013's x offset is 0.07 g (an outlier, outside the 0.05 limit); SN0007 is calibrated again a
week later with its y offset moved by 0.015 g (drift). Each file is written by `tumblecal batch`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from tests import synth

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "sample_data" / "lot"
FACES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def unit(folder: Path, rng: np.random.Generator, offset: np.ndarray, gain: np.ndarray) -> None:
    folder.mkdir(parents=True)
    for name, face in FACES.items():
        raw = synth.pose_samples(rng, face, offset=offset, gain=gain, reference=1.0, noise=0.002, n=200)
        lines = ["ax,ay,az", *(",".join(f"{v:.5f}" for v in row) for row in raw)]
        (folder / f"{name}.csv").write_text("\n".join(lines) + "\n")


def batch(units: Path, out: Path, when: int) -> None:
    env = dict(os.environ, SOURCE_DATE_EPOCH=str(when))
    tc = str(Path(sys.executable).parent / "tumblecal")
    subprocess.run([tc, "batch", "units", "--out-dir", str(out), "-q"], cwd=units.parent, env=env, check=False)
    (out / "summary.csv").unlink()


def main() -> None:
    rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
    shutil.rmtree(OUT, ignore_errors=True)
    OUT.mkdir()
    with tempfile.TemporaryDirectory() as tmp:
        units = Path(tmp) / "units"
        offsets, gains = {}, {}
        for k in range(1, 31):
            serial = f"SN{k:04d}"
            offset = rng.normal(0, 0.01, 3)
            if serial == "SN0013":
                offset[0] = 0.07
            offsets[serial], gains[serial] = offset, rng.normal(1, 0.004, 3)
            unit(units / serial, rng, offset, gains[serial])
        batch(units, OUT, 1795251600)  # 2026-11-21 09:00 UTC
        shutil.rmtree(units)
        again = offsets["SN0007"] + np.array([0.0, 0.015, 0.0])
        unit(units / "SN0007", rng, again, gains["SN0007"])
        later = Path(tmp) / "later"
        batch(units, later, 1795251600 + 7 * 86400)
        for path in later.iterdir():
            shutil.copy(path, OUT / path.name)


if __name__ == "__main__":
    main()
