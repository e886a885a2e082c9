"""Write the synthetic temperature-chamber run for ``tumblecal thermal`` (sample_data/thermal/).

Model (per sample; README "tumblecal thermal"), with d = T - T_REF:

    raw = diag(GAIN * (1 + GAIN_DRIFT1 d)) @ v + OFFSET + OFFSET_DRIFT1 d + OFFSET_DRIFT2 d^2
          + noise                                     noise ~ N(0, NOISE^2), white, per axis

The reading follows the die temperature, which lags the logged temperature by HYSTERESIS °C in
the direction the chamber moves (a little hysteresis: the up and down sweeps differ). Each face is
swept once from -10 to 60 °C (up for +x +y +z, down for -x -y -z) at uneven rates with dwells at
random temperatures, logged at 1 Hz. Also written: six room-temperature poses at T_REF (the base
calibration's captures, ``tumblecal solve``) and ``check.csv``, a capture at random temperatures
in random static orientations to correct with ``apply``.

Usage: python sample_data/make_thermal.py            (seeded: the same bytes every run)
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

T_REF = 25.0
OFFSET = np.array([0.021, -0.034, 0.047])  # g
GAIN = np.array([1.012, 0.987, 1.005])
OFFSET_DRIFT1 = np.array([2.0e-4, -1.5e-4, 3.0e-4])  # g / °C
OFFSET_DRIFT2 = np.array([3.0e-6, -2.0e-6, 4.0e-6])  # g / °C^2
GAIN_DRIFT1 = np.array([1.0e-4, -8.0e-5, 1.5e-4])  # 1 / °C
NOISE = 0.002  # g
HYSTERESIS = 0.3  # °C
T_LOW, T_HIGH = -10.0, 60.0
FACES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
NAMES = {"+x": "xp", "-x": "xn", "+y": "yp", "-y": "yn", "+z": "zp", "-z": "zn"}


def reading(v: np.ndarray, temp: np.ndarray, rng: np.random.Generator, lag: np.ndarray | float = 0.0) -> np.ndarray:
    """Raw readings (n, 3) of stimuli v (n, 3) at logged temperatures temp (n,)."""
    d = (temp - lag) - T_REF
    gain = GAIN * (1 + np.outer(d, GAIN_DRIFT1))
    offset = OFFSET + np.outer(d, OFFSET_DRIFT1) + np.outer(d**2, OFFSET_DRIFT2)
    return gain * v + offset + rng.normal(0.0, NOISE, (len(temp), 3))


def profile(rng: np.random.Generator, up: bool) -> np.ndarray:
    """A chamber sweep from T_LOW to T_HIGH (or back) at 1 Hz: uneven ramps, random dwells."""
    stops = np.sort(rng.uniform(T_LOW, T_HIGH, 5))
    points = [T_LOW, *stops, T_HIGH]
    temps: list[np.ndarray] = []
    for a, b in itertools.pairwise(points):
        rate = rng.uniform(0.05, 0.4)  # °C per sample
        temps.append(np.arange(a, b, rate))
        temps.append(np.full(int(rng.integers(50, 600)), b))  # a dwell of uneven length
    t = np.concatenate(temps)
    t = t + rng.normal(0.0, 0.02, len(t))  # the temperature sensor's own noise
    return t if up else t[::-1]


def chamber(seed: int = 18) -> dict[str, np.ndarray]:
    """{face: (n, 4) rows of temp, ax, ay, az} for the six faces."""
    rng = np.random.default_rng(seed)
    out = {}
    for face, vec in FACES.items():
        up = face[0] == "+"
        temp = profile(rng, up)
        v = np.tile(np.array(vec, dtype=float), (len(temp), 1))
        lag = HYSTERESIS if up else -HYSTERESIS
        out[face] = np.column_stack([temp, reading(v, temp, rng, lag)])
    return out


def check_capture(seed: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """20 still segments of 100 rows at random temperatures and orientations: (directions (20, 3),
    temperatures (20,), rows (2000, 4) of temp, ax, ay, az)."""
    rng = np.random.default_rng(seed)
    directions, temps, rows = [], [], []
    for _ in range(20):
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        t = round(float(rng.uniform(T_LOW, T_HIGH)), 2)
        rows.append(np.column_stack([np.full(100, t), reading(np.tile(v, (100, 1)), np.full(100, t), rng)]))
        directions.append(v)
        temps.append(t)
    return np.array(directions), np.array(temps), np.vstack(rows)


def main() -> None:
    here = Path(__file__).resolve().parent / "thermal"
    here.mkdir(exist_ok=True)
    for face, rows in chamber().items():
        kind = "up" if face[0] == "+" else "down"
        name = here / f"sweep_{kind}_{NAMES[face]}.csv"
        lines = ["t,temp,ax,ay,az"] + [
            f"{k:.0f},{r[0]:.2f},{r[1]:.6f},{r[2]:.6f},{r[3]:.6f}" for k, r in enumerate(rows)
        ]
        name.write_text("\n".join(lines) + "\n")
    rng = np.random.default_rng(25)
    for face, vec in FACES.items():  # the base calibration's poses, at T_REF
        temp = np.full(500, T_REF) + rng.normal(0.0, 0.02, 500)
        rows = reading(np.tile(np.array(vec, dtype=float), (500, 1)), temp, rng)
        lines = ["temp,ax,ay,az"] + [
            f"{t:.2f},{r[0]:.6f},{r[1]:.6f},{r[2]:.6f}" for t, r in zip(temp, rows, strict=True)
        ]
        (here / f"{NAMES[face]}.csv").write_text("\n".join(lines) + "\n")
    _, _, rows = check_capture()
    lines = ["temp,ax,ay,az"] + [f"{r[0]:.2f},{r[1]:.6f},{r[2]:.6f},{r[3]:.6f}" for r in rows]
    (here / "check.csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
