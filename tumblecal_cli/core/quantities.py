"""The units tumblecal knows, one vocabulary for every command: each name and alias a calibration's
``units`` or ``input_units`` may carry, the quantity it measures, and its factor to that quantity's
base unit: m/s^2 for an acceleration, rad/s for an angular rate, gauss for a magnetic field (the
unit autopilot logs and PX4's parameters use; 1 gauss = 1e-4 T, the SI unit). Standard gravity is
defined here once.

noise converts its figures with it, export writes autopilot parameters with it, places puts
local gravity and the Earth's field in a calibration's units with it, and the gate names the
units a reference suggests from it. Plain Python (no numpy): the command line's start-up may read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Standard gravity (m/s^2): what 1 g is, by the third General Conference on Weights and Measures;
#: PX4's CONSTANTS_ONE_G and ROS imu_calib's default reference_acceleration too.
STANDARD_GRAVITY = 9.80665
#: One degree in radians.
DEGREE = math.pi / 180.0

ACCELERATION = "acceleration"
ANGULAR_RATE = "angular rate"
MAGNETIC_FIELD = "magnetic field"
#: Each quantity's base unit, the one its factors lead to.
BASE = {ACCELERATION: "m/s^2", ANGULAR_RATE: "rad/s", MAGNETIC_FIELD: "gauss"}
#: What each sensor measures.
QUANTITY = {"accelerometer": ACCELERATION, "gyroscope": ANGULAR_RATE, "magnetometer": MAGNETIC_FIELD}


@dataclass(frozen=True)
class Measure:
    """A unit name: the ``quantity`` it measures and ``factor``, what one of it is in the quantity's base unit."""

    quantity: str
    factor: float


def _named(quantity: str, factors: dict[str, float]) -> dict[str, Measure]:
    return {name: Measure(quantity, factor) for name, factor in factors.items()}


#: Every unit name tumblecal converts, each quantity's in the order messages list them. Names are
#: matched as written (noise folds case and spaces first: its names are all lower case).
UNITS: dict[str, Measure] = {
    **_named(
        ACCELERATION,
        {"g": STANDARD_GRAVITY, "mg": STANDARD_GRAVITY * 1e-3, "m/s^2": 1.0, "m/s²": 1.0, "m/s2": 1.0, "ms^-2": 1.0},
    ),
    **_named(
        ANGULAR_RATE,
        {
            "rad/s": 1.0,
            "deg/s": DEGREE,
            "°/s": DEGREE,
            "dps": DEGREE,
            "degree/s": DEGREE,
            "degrees/s": DEGREE,
            "mdps": math.pi / 180.0e3,  # a thousandth of a degree per second (STMicroelectronics' datasheets)
        },
    ),
    **_named(
        MAGNETIC_FIELD,
        {
            **dict.fromkeys(("gauss", "Gauss", "G", "Gs"), 1.0),
            **dict.fromkeys(("mG", "mGauss", "mgauss", "milligauss"), 1e-3),
            **dict.fromkeys(("uT", "µT", "μT", "microtesla"), 1e-2),
            "nT": 1e-5,
            "mT": 10.0,
            "T": 1e4,
        },
    ),
}
#: The spellings export's messages name for each quantity (a short list: every name of UNITS is
#: taken all the same).
COMMON = {
    ACCELERATION: ("g", "m/s^2", "m/s2", "m/s²"),
    ANGULAR_RATE: ("rad/s", "deg/s", "dps", "°/s"),
    MAGNETIC_FIELD: tuple(name for name, m in UNITS.items() if m.quantity == MAGNETIC_FIELD),
}
#: The one dip convention tumblecal prints, said beside it: the WMM's inclination (the files'
#: ``dip`` part records the angle from gravity to the field, 90° less this).
DIP_SAID = "inclination: the field's angle below the horizontal, + down"

#: The units a conventional reference (core.model.suggest_reference) is the stimulus of: 1 g,
#: standard gravity in m/s^2, 1000 mg.
REFERENCE_UNITS = {1.0: "g", STANDARD_GRAVITY: "m/s^2", 1000.0: "mg"}


def names(sensor: str) -> tuple[str, ...]:
    """Every unit name of the quantity ``sensor`` measures, in UNITS' order (none for another sensor)."""
    quantity = QUANTITY.get(sensor)
    return tuple(name for name, m in UNITS.items() if m.quantity == quantity)


def factor(sensor: str, name: str) -> float | None:
    """What one ``name`` is in the base unit of the quantity ``sensor`` measures; None: a name
    tumblecal does not know, or one of another quantity."""
    measure = UNITS.get(name)
    if measure is None or measure.quantity != QUANTITY.get(sensor):
        return None
    return measure.factor
