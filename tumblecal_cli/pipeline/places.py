"""The reference of a calibration from where (and when) it was made: an accelerometer's local
gravity (``--location LAT,LON[,HEIGHT_M]`` or ``--gravity VALUE``: WGS-84 normal gravity,
core.earth) and a magnetometer's Earth field (``--location`` and ``--date YYYY-MM-DD``: the World
Magnetic Model release of that date, or with ``--field-model wmmhr`` its high-resolution model).
The magnitude becomes ``reference`` in the calibration's units, and where it came from is written
beside it (``gravity``, ``earth_field``; README "docs/real-world.md").
"""

from __future__ import annotations

import datetime
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from tumblecal_cli.core import earth
from tumblecal_cli.core.quantities import DIP_SAID, factor
from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.pipeline.options import SolveOptions

#: --gravity's range (m/s^2): the Earth's surface gravity, poles to equator, with room for height.
GRAVITY_RANGE = (9.7, 9.9)
#: A magnetometer's units when neither --units nor its log's stream names them.
DEFAULT_FIELD_UNITS = "uT"
_NUMBER = r"\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*"


@dataclass(frozen=True)
class Place:
    """Geodetic ``latitude`` and ``longitude`` (degrees, WGS 84) and ``height`` (m above the ellipsoid)."""

    latitude: float
    longitude: float
    height: float = 0.0


@dataclass(frozen=True)
class ReferenceSource:
    """Where a reference came from: its ``key`` in the calibration file (``gravity`` or
    ``earth_field``) and the part itself."""

    key: str
    part: Mapping[str, object]


def location(text: str) -> Place:
    """``--location LAT,LON[,HEIGHT_M]``: degrees north and east, metres above the ellipsoid."""
    found = re.fullmatch(f"{_NUMBER},{_NUMBER}(?:,{_NUMBER})?", text)
    if found is None:
        raise InputError(
            f"--location takes LAT,LON[,HEIGHT_M] in degrees and metres, got {text!r}",
            hint="e.g. --location 52.21,0.09,20 (north and east positive)",
        )
    lat, lon = float(found.group(1)), float(found.group(2))
    height = float(found.group(3)) if found.group(3) is not None else 0.0
    if not -90 <= lat <= 90:
        raise InputError(f"--location: latitude {lat:g} is not from -90 to 90 degrees", hint="give LAT,LON: LAT first")
    if not -180 <= lon <= 360:
        raise InputError(f"--location: longitude {lon:g} is not from -180 to 360 degrees")
    low, high = earth.HEIGHTS
    if not low <= height <= high:
        raise InputError(
            f"--location: height {height:g} m is not from {low:g} to {high:g} m",
            hint="the third number is the height above the WGS-84 ellipsoid in metres",
        )
    return Place(lat, lon, height)


#: How the messages name each field model of --field-model (core.earth.FIELD_MODELS).
FIELD_MODEL_NAMES = {"wmm": "the World Magnetic Model", "wmmhr": "the high-resolution World Magnetic Model"}


def decimal_date(text: str, family: str = "wmm") -> float:
    """``--date YYYY-MM-DD`` as a decimal year, within the span of the field model ``family``'s
    releases (core.earth.FIELD_MODELS: ``wmm`` from 2010, ``wmmhr`` from 2025)."""
    found = re.fullmatch(r"\s*(\d{4})-(\d{2})-(\d{2})\s*", text)
    try:
        day = datetime.date(*(int(g) for g in found.groups())) if found else None
    except ValueError:
        day = None
    if day is None:
        raise InputError(f"--date takes YYYY-MM-DD, got {text!r}", hint="e.g. --date 2026-11-27")
    year = earth.decimal_year(day.year, day.month, day.day)
    first, last = earth.field_span(family)
    if not first <= year < last:
        names = ", ".join(m.name for m in earth.FIELD_MODELS[family])
        raise InputError(
            f"--date {text.strip()} is outside {FIELD_MODEL_NAMES[family]} ({names}), which holds from "
            f"{first:.0f}-01-01 to {last - 1:.0f}-12-31",
            hint="give the date the log was recorded, within the model's span"
            + ("; before 2025, leave --field-model out (the WMM of the date)" if family != "wmm" else ""),
        )
    return year


@dataclass(frozen=True)
class Asked:
    """What a command was told of its reference: the ``sensor``, the calibration's ``units``
    (None: not said), the ``stream_units`` of a log (m/s^2, gauss), and the options."""

    sensor: str
    units: str | None
    stream_units: str | None = None
    location: str | None = None
    gravity: float | None = None
    date: str | None = None
    reference: float | None = None
    field_model: str | None = None  # --field-model: wmm (None) or wmmhr


def resolve(options: SolveOptions, stream_units: str | None) -> tuple[SolveOptions, ReferenceSource | None]:
    """solve's reference of --location, --gravity and --date (``stream_units``: the units of a
    log's stream, m/s^2 or gauss), in the calibration's units, and where it came from; the
    options unchanged when none is given."""
    o = options
    asked = Asked(o.read.sensor, o.units, stream_units, o.location, o.gravity, o.date, o.reference, o.field_model)
    found = local_reference(asked)
    if found is None:
        return options, None
    reference, units, source = found
    return replace(options, reference=reference, units=units), source


def local_reference(asked: Asked) -> tuple[float, str, ReferenceSource] | None:
    """The reference, its units and its source of --location, --gravity and --date (None: none given)."""
    given = [f for f, v in (("--location", asked.location), ("--gravity", asked.gravity)) if v is not None]
    sensor = asked.sensor
    if not given:
        if asked.date is not None:
            raise InputError("--date dates the Earth's field at a --location: give --location LAT,LON too")
        if asked.field_model is not None:
            raise InputError(
                "--field-model chooses the model of the Earth's field at a --location: give --location LAT,LON too"
            )
        return None
    if asked.reference is not None:
        raise InputError(f"{given[0]} sets the reference: give it or --reference, not both")
    if len(given) == 2:
        raise InputError("give the place (--location) or the value (--gravity) of local gravity, not both")
    if sensor == "accelerometer":
        return _gravity(asked)
    if sensor == "magnetometer" and asked.gravity is None:
        return _field(asked)
    if sensor == "magnetometer":
        raise InputError(
            "--gravity is local gravity, an accelerometer's reference: a magnetometer's is the Earth's field",
            hint="give --location LAT,LON and --date YYYY-MM-DD for the World Magnetic Model's field there",
        )
    raise InputError(
        f"{given[0]} sets a reference for an accelerometer (gravity) or a magnetometer (the Earth's field), "
        f"not a {sensor}"
    )


def _gravity(asked: Asked) -> tuple[float, str, ReferenceSource]:
    if asked.date is not None:
        raise InputError("--date is for a magnetometer's Earth field; gravity does not change with the date")
    if asked.field_model is not None:
        raise InputError("--field-model is for a magnetometer's Earth field; local gravity is WGS-84 normal gravity")
    stream = asked.stream_units or ""
    units = asked.units or ("m/s^2" if factor("accelerometer", stream) == 1.0 else "g")  # a log's stream in m/s^2
    scale = factor("accelerometer", units)  # m/s^2 per one of the units
    if scale is None:
        raise InputError(
            f"local gravity is in g or m/s^2, and the calibration's units are {units!r}",
            hint="give --units g (or m/s^2), or leave --location out and give --reference in your units",
        )
    if asked.gravity is not None:
        value = asked.gravity
        low, high = GRAVITY_RANGE
        if not (math.isfinite(value) and low <= value <= high):
            raise InputError(
                f"--gravity is local gravity in m/s^2, from {low:g} to {high:g}, got {value:g}",
                hint="9.780 at the equator to 9.832 at the poles; in g, give --reference instead",
            )
        part: dict[str, object] = {"value_m_s2": value, "source": "given (--gravity)"}
    else:
        assert asked.location is not None
        place = location(asked.location)
        value = earth.normal_gravity(place.latitude, place.height)
        part = {
            "latitude": place.latitude,
            "longitude": place.longitude,
            "height_m": place.height,
            "value_m_s2": value,
            "source": "WGS-84 normal gravity, NIMA TR8350.2 Eqs. 4-1 and 4-3",
        }
    return value / scale, units, ReferenceSource("gravity", part)


def _field(asked: Asked) -> tuple[float, str, ReferenceSource]:
    if asked.date is None:
        raise InputError(
            "--location gives a magnetometer the Earth's field of the World Magnetic Model on a date: give --date "
            "YYYY-MM-DD too",
            hint="the day the log was recorded",
        )
    assert asked.location is not None
    place = location(asked.location)
    family = asked.field_model or "wmm"
    if family not in earth.FIELD_MODELS:
        raise InputError(f"--field-model is {' or '.join(earth.FIELD_MODELS)}, got {family!r}")
    year = decimal_date(asked.date, family)
    model = earth.field_model(year, family)
    stream = asked.stream_units or ""
    units = asked.units or (stream if factor("magnetometer", stream) is not None else DEFAULT_FIELD_UNITS)
    scale = factor("magnetometer", units)  # gauss per one of the units
    if scale is None:
        raise InputError(
            f"the Earth's field is in uT, gauss, mG or nT, and the calibration's units are {units!r}",
            hint="give --units uT (or gauss), or leave --location out and give --reference in your units",
        )
    f = earth.magnetic_field(place.latitude, place.longitude, place.height, year, model)
    part: dict[str, object] = {
        "latitude": place.latitude,
        "longitude": place.longitude,
        "height_m": place.height,
        "date": asked.date.strip(),
        "model": model.name,
        "total_nT": round(f.total, 1),
        "inclination_deg": round(f.inclination, 4),
        "declination_deg": round(f.declination, 4),
        "north_nT": round(f.north, 1),
        "east_nT": round(f.east, 1),
        "down_nT": round(f.down, 1),
        "source": model.source,
    }
    return f.total * 1e-5 / scale, units, ReferenceSource("earth_field", part)  # nT to gauss, gauss to the units


def stamp(cal: Calibration | None, source: ReferenceSource | None) -> Calibration | None:
    """``cal`` with where its reference came from, after its ``input_units``."""
    if cal is None or source is None:
        return cal
    order = list(cal.order)
    if source.key not in order:
        after = [order.index(k) for k in ("input_units", "gravity", "earth_field") if k in order]
        order.insert(max(after) + 1 if after else len(order), source.key)
    return replace(cal, fields={**cal.fields, source.key: dict(source.part)}, order=tuple(order))


def lines_of(cal: Calibration) -> list[str]:
    """The lines a summary shows of where the reference came from (none: typed by hand) and of
    the dip check."""
    return [*_reference_lines(cal), *_dip_lines(cal.fields.get("dip"))]


def _reference_lines(cal: Calibration) -> list[str]:
    part = cal.fields.get("gravity")
    if isinstance(part, Mapping) and isinstance(part.get("value_m_s2"), float | int):
        at = "" if part.get("latitude") is None else f" at {part.get('latitude')}, {part.get('longitude')}, "
        at += "" if part.get("height_m") is None else f"{part.get('height_m')} m"
        ref = f"reference {cal.reference:.7g} {cal.units or ''}".rstrip()
        return [f"{ref}: local gravity {part['value_m_s2']:.10g} m/s^2{at} ({part.get('source', '')})"]
    part = cal.fields.get("earth_field")
    if isinstance(part, Mapping) and isinstance(part.get("total_nT"), float | int):
        ref = f"reference {cal.reference:.5g} {cal.units or ''}".rstrip()
        return [
            f"{ref}: the Earth's field {part['total_nT']:.1f} nT ({part.get('model')} at {part.get('latitude')}, "
            f"{part.get('longitude')}, {part.get('height_m')} m on {part.get('date')}), "
            f"inclination {part.get('inclination_deg')}°, declination {part.get('declination_deg')}°"
        ]
    return []


def _dip_lines(part: object) -> list[str]:
    """The summary's line of a calibration's ``dip`` part (pipeline.solve.maglog)."""
    if not isinstance(part, Mapping) or not isinstance(part.get("mean_deg"), float | int):
        return []
    line = (  # the file keeps the angle from gravity to the field; people read the inclination
        f"dip {90.0 - part['mean_deg']:.2f}° ± {part.get('uncertainty_deg')}° ({DIP_SAID}) over "
        f"{part.get('blocks')} still blocks, spread {part.get('spread_deg')}°"
    )
    model, difference = part.get("model_deg"), part.get("difference_deg")
    if isinstance(model, float | int) and isinstance(difference, float | int):
        line += f"; the model's {90.0 - model:.2f}° ({-difference:+.2f}°)"
    return [line]
