"""A synthetic turntable session for tests/test_spin.py and sample_data/turntable: a gyroscope
(raw = A w + b + noise) placed on a platter in turn, each placement 2 s of handling, 1 s of
spin-up and a hold at the rate, the platter's speed off by a random 0.1 % each time.

    python sample_data/make_turntable.py    # writes turntable/45rpm.csv, 33rpm.csv, rest.csv
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from tumblecal_cli.core.arrays import FloatArray

RPM = 2 * math.pi / 60
HZ = 50


def turned(rng: np.random.Generator) -> FloatArray:
    """A random direction: the platter's axis seen from the sensor in one placement."""
    v = rng.normal(size=3)
    out: FloatArray = v / np.linalg.norm(v)
    return out


def readings(
    rng: np.random.Generator, a: FloatArray, b: FloatArray, placements: list[tuple[FloatArray, float]], hold: int = 20
) -> FloatArray:
    """A gyroscope (raw = A w + b + noise) through placements: 2 s of handling, 1 s of spin-up,
    ``hold`` s at the rate (the platter's speed off by a random 0.1 % each time)."""
    rows = []
    for axis, rate in placements:
        rows += [a @ (rng.normal(size=3) * 1.5) + b for _ in range(2 * HZ)]
        rows += [a @ (axis * rate * i / HZ) + b for i in range(HZ)]
        wow = 1 + rng.normal() * 0.001
        rows += [a @ (axis * rate * wow) + b for _ in range(hold * HZ)]
    v = np.array(rows)
    out: FloatArray = v + rng.normal(size=v.shape) * 0.01
    return out


def truth(rng: np.random.Generator, *, symmetric: bool) -> tuple[FloatArray, FloatArray]:
    """A true A (raw per rad/s, cross-axis terms of about 1 %) and bias (rad/s)."""
    s = rng.normal(size=(3, 3)) * 0.01
    m = np.eye(3) + ((s + s.T) / 2 if symmetric else s) + np.diag(rng.normal(size=3) * 0.02)
    a: FloatArray = np.asarray(np.linalg.inv(m), dtype=np.float64)
    return a, rng.normal(size=3) * 0.03


def write(path: Path, values: FloatArray) -> Path:
    """The readings as a CSV log, t,gx,gy,gz at HZ."""
    t = np.arange(len(values)) / HZ
    lines = "".join(f"{ti:.3f},{x:.6f},{y:.6f},{z:.6f}\n" for ti, (x, y, z) in zip(t, values, strict=True))
    path.write_text("t,gx,gy,gz\n" + lines)
    return path


def sample(folder: Path) -> None:
    """sample_data/turntable: 45 and 33⅓ rpm, six placements each, and rest (seed 2024)."""
    rng = np.random.default_rng(2024)
    a, b = truth(rng, symmetric=True)
    folder.mkdir(parents=True, exist_ok=True)
    write(folder / "45rpm.csv", readings(rng, a, b, [(turned(rng), 45 * RPM) for _ in range(6)], hold=10))
    write(folder / "33rpm.csv", readings(rng, a, b, [(turned(rng), 100 / 3 * RPM) for _ in range(6)], hold=10))
    write(folder / "rest.csv", readings(rng, a, b, [(np.array([0.0, 0.0, 1.0]), 0.0)], hold=10))
    print(f"bias {np.round(b, 5)}, gains {np.round(np.diag(a), 5)}")


if __name__ == "__main__":
    sample(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "turntable")
