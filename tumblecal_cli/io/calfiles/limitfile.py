"""Limits files (docs/production-test.md): the bounds a unit is judged by, read from
YAML or JSON, each key checked; the noise limits `tumblecal noise` judges by; and a bound given
on the command line, one number or X,Y,Z (``triplet``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles.calfile import number_field, vector_field
from tumblecal_cli.io.calfiles.documents import read_object

#: Keys of a limits file (docs/production-test.md); a number, or [x, y, z] where marked per axis.
LIMIT_KEYS = {
    "offset": "per axis",
    "gain_error": "per axis",
    "nominal_gain": "per axis",
    "cross_axis": "one",
    "noise": "one",
    "residual": "one",
    "nominal_offset": "per axis",  # the offset a good unit has (unsigned counts: 32768); any number
    # `tumblecal noise`'s figures, in the units it reports them in (solve and report ignore them)
    "noise_density": "per axis",
    "bias_instability": "per axis",
    "random_walk": "per axis",
    "offset_drift": "per axis",  # a thermal block's largest offset drift over its range, raw units
    "offset_drift_per_degc": "per axis",  # ... and per °C
    # `tumblecal align`'s: the RMS difference of two IMUs' corrected readings, their units
    "imu_consistency": "one",
    "gyro_consistency": "one",  # ... and of two gyroscopes' rates while the unit turns
    # `tumblecal current`'s: the field's change at the largest current, a share of the reference
    "current_interference": "one",
    "dip_angle": "one",  # degrees: a magnetometer's still blocks' dip angle from the model's (docs/real-world.md)
}

#: A bound as the command line or the Python API gives it: text (one number or X,Y,Z), a number, or three.
Triplet = str | float | Sequence[float]


def triplet(value: Triplet, option: str) -> FloatArray:
    """A number or X,Y,Z (text as the command line gives it, a number, or three numbers), as a (3,) array."""

    if isinstance(value, str):
        text = value
        try:
            values = [float(p) for p in value.split(",")]
        except ValueError:
            values = []
    elif isinstance(value, int | float):
        text, values = repr(value), [float(value)]
    else:
        text = ",".join(map(str, value))
        try:
            values = [float(v) for v in value]
        except (TypeError, ValueError):
            values = []
    if len(values) not in (1, 3) or not all(np.isfinite(values)):
        raise InputError(f"{option} takes one number or three (X,Y,Z), got {text!r}")
    return np.array(values * 3 if len(values) == 1 else values)


#: The limits only `tumblecal noise` judges.
NOISE_LIMITS = ("noise_density", "bias_instability", "random_walk")
#: The limits only `tumblecal align` judges.
ALIGN_LIMITS = ("imu_consistency", "gyro_consistency")
#: The limits only `tumblecal current` judges.
CURRENT_LIMITS = ("current_interference",)


def load_limits(path: str) -> dict[str, float | FloatArray]:
    """The bounds in a limits file, validated: ``{key: float or (3,) array}``."""
    doc = read_object(path, "limits file")
    out: dict[str, float | FloatArray] = {}
    for key, value in doc.items():
        if key == "version":
            if isinstance(value, bool) or value != 1:  # True == 1 in Python
                raise InputError(f"unsupported limits version {value!r} (this tumblecal reads version 1)", file=path)
            continue
        if key == "format":
            raise InputError(f"a {value} file, not a limits file", file=path, hint="see docs/production-test.md")
        if key not in LIMIT_KEYS:
            raise InputError(f"unknown limit {key!r} (known: {', '.join(LIMIT_KEYS)})", file=path)
        if key == "nominal_offset":  # not a bound: a centre, which may be 0 or negative
            out[key] = (
                vector_field(value, key, path)
                if isinstance(value, list)
                else np.full(3, number_field(value, key, path))
            )
            continue
        out[key] = limit_value(value, key, path, per_axis=LIMIT_KEYS[key] == "per axis")
    return out


def limit_value(value: object, name: str, path: str | None, *, per_axis: bool) -> float | FloatArray:
    """A positive bound: a number, or for ``per_axis`` also a list [x, y, z] (made (3,))."""
    if per_axis and isinstance(value, list):
        array = vector_field(value, name, path)
    else:
        array = np.full(3, number_field(value, name, path))
    if (array <= 0).any():
        raise InputError(f"{'limit' if path else 'option'} {name!r} must be positive, got {value!r}", file=path)
    return array if per_axis else float(array[0])
