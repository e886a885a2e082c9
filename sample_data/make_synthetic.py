"""Write the synthetic tumble-calibration sample data for tumblecal.

Measurement model (per sample, in g):

    raw = A @ v + b + noise,  A = diag(GAIN),  b = OFFSET,  noise ~ N(0, NOISE^2)

with the noise independent per axis. ``v`` is the true stimulus: a unit vector
(|v| = 1 g) along the sensor axis that points up. There are no cross-axis terms.

Outputs, written next to this script whatever the current directory is (header
``t,ax,ay,az``; ``t`` in seconds as "%.3f" from 0.000 at RATE Hz; values as "%.6f"):

* ``x.csv``, ``y.csv``, ``z.csv``    -- SAMPLES rows each, poses +x, +y, +z
* ``xn.csv``, ``yn.csv``, ``zn.csv`` -- SAMPLES rows each, poses -x, -y, -z
* ``capture.csv`` -- a later capture to correct: six static segments of
  CAPTURE_SEGMENT rows, one per orientation in CAPTURE_DIRECTIONS.

The generator is seeded, so running the script again reproduces identical bytes.

Usage: python sample_data/make_synthetic.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# --- truth -------------------------------------------------------------------
OFFSET = np.array([0.021, -0.034, 0.047])  # g
GAIN = np.array([1.012, 0.987, 1.005])  # raw g per true g
NOISE = 0.002  # g, 1 sigma, white gaussian, per axis
RATE = 100.0  # Hz
SAMPLES = 1000  # rows per calibration pose
SEED = 20261121

POSES = {
    "x.csv": [1.0, 0.0, 0.0],
    "y.csv": [0.0, 1.0, 0.0],
    "z.csv": [0.0, 0.0, 1.0],
    "xn.csv": [-1.0, 0.0, 0.0],
    "yn.csv": [0.0, -1.0, 0.0],
    "zn.csv": [0.0, 0.0, -1.0],
}

# capture.csv: six fixed, non-axis-aligned orientations (normalised below)
CAPTURE_DIRECTIONS = [
    [0.30, 0.20, 0.93],
    [-0.50, 0.60, 0.62],
    [0.70, -0.40, -0.59],
    [-0.20, -0.80, 0.56],
    [0.60, 0.60, -0.53],
    [-0.55, 0.30, -0.78],
]
CAPTURE_SEGMENT = 500  # rows per orientation

OUT_DIR = Path(__file__).resolve().parent


def measure(rng: np.random.Generator, v: np.ndarray, n: int) -> np.ndarray:
    """Return n raw samples (n x 3) of a sensor at rest with true stimulus v."""
    return GAIN * v + OFFSET + rng.normal(0.0, NOISE, size=(n, 3))


def write_csv(path: Path, raw: np.ndarray) -> None:
    """Write raw samples with a time column starting at 0 s."""
    lines = ["t,ax,ay,az"]
    for i, (ax, ay, az) in enumerate(raw):
        lines.append(f"{i / RATE:.3f},{ax:.6f},{ay:.6f},{az:.6f}")
    with open(path, "w", encoding="ascii", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")


def main() -> None:
    """Write the six pose files, then capture.csv, from one seeded generator."""
    rng = np.random.default_rng(SEED)
    for name, v in POSES.items():
        write_csv(OUT_DIR / name, measure(rng, np.array(v), SAMPLES))

    segments = []
    for d in CAPTURE_DIRECTIONS:
        v = np.array(d) / np.linalg.norm(d)
        segments.append(measure(rng, v, CAPTURE_SEGMENT))
    write_csv(OUT_DIR / "capture.csv", np.vstack(segments))


if __name__ == "__main__":
    main()
