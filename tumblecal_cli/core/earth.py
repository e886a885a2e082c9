"""The Earth's reference fields at a place: WGS-84 normal gravity and the World Magnetic Model.
numpy only (README "Sources": NIMA TR8350.2, the WMM2010, WMM2015v2, WMM2020 and WMM2025
reports, WMMHR2025).

Normal gravity (NIMA TR8350.2, 3rd edition, ch. 4): Somigliana's closed formula on the
ellipsoid (Eq. 4-1) ::

    gamma(phi) = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)

with the defining constants of WGS 84 (Table 3.1) and the derived ones (Table 3.3: gamma_e, gamma_p,
k, e^2, m), and above the ellipsoid its second-order height correction (Eq. 4-3) ::

    gamma_h = gamma (1 - 2/a (1 + f + m - 2 f sin^2 phi) h + 3 h^2 / a^2)

The World Magnetic Model (WMM2025 report, sect. 1.2, Eqs. 7-19; every release is evaluated the
same way): the geodetic place becomes geocentric spherical coordinates (Eqs. 7-8), the Gauss
coefficients move linearly with the time from the epoch (Eq. 9), the field is the gradient of the
spherical-harmonic potential to the degree of the coefficient file (12; 133 for WMMHR2025) with
Schmidt semi-normalised associated Legendre functions (Eqs. 10-12), turned into the ellipsoidal
frame (Eq. 17), and its intensity, inclination and declination follow (Eq. 19).

The coefficient files, in ``wmm/`` beside this module, are the published ``WMM.COF`` (and
``WMMHR.COF``) of each release by NOAA (NGDC, since 2015 NCEI) and the British Geological Survey,
works of the US government in the public domain, copied unchanged from the copies that pygeomag
1.1.0 (MIT) ships (``pygeomag/wmm/``; WMM_2025.COF is byte for byte the file this module embedded
before). A date chooses the release (``field_model``; ``--field-model wmm``):

- WMM2010 (file dated 11/20/2009, WMM2010 report) for 2010.0-2015.0;
- WMM2015v2 (09/18/2018, WMM2015v2 report) for 2015.0-2020.0: the out-of-cycle release that
  superseded WMM2015 (12/15/2014) over the whole span, as NOAA advised, so WMM2015 is not kept;
- WMM2020 (12/10/2019, WMM2020 report) for 2020.0-2025.0;
- WMM2025 (11/13/2024, WMM2025 report) for 2025.0-2030.0.

``--field-model wmmhr`` takes WMMHR2025 instead (11/13/2024, degree 133, 2025.0-2030.0), the
high-resolution model released with WMM2025, which adds the larger crustal features.

Each release's own error estimate (1 sigma over its span; ``MagneticModel.error``) is its error
model's total intensity and inclination, as NOAA's software of the release states it (its
``WMM_UNCERTAINTY_F`` and ``_I``): WMM2025 138 nT, 0.20 deg (WMM2025 report, Table 4); WMM2020
145 nT, 0.21 deg; WMMHR2025 134 nT, 0.19 deg; WMM2015v2 152 nT, 0.22 deg, the error model of
WMM2015's software (the WMM2015v2 report reassessed the uncertainties, not read here). For
WMM2010 no error model was found in the sources read, and none is given (None).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import FloatArray

# -- WGS 84 (NIMA TR8350.2, Tables 3.1 and 3.3) ---------------------------------------------------

#: Semi-major axis a (m) and flattening f (Table 3.1).
WGS84_A = 6378137.0
WGS84_F = 1 / 298.257223563
#: First eccentricity squared e^2 (Table 3.3).
WGS84_E2 = 0.00669437999013
#: Normal gravity at the equator and at the poles (m/s^2), Table 3.3.
GAMMA_EQUATOR = 9.7803253359
GAMMA_POLE = 9.8321849378
#: Somigliana's constant k = b gamma_p / (a gamma_e) - 1 (Table 3.3).
SOMIGLIANA_K = 0.00193185265241
#: m = omega^2 a^2 b / GM (Table 3.3).
WGS84_M = 0.00344978650684
#: The heights a place may be given at (m): below the Dead Sea shore to above any station.
HEIGHTS = (-1000.0, 20000.0)


def normal_gravity(latitude: float, height: float = 0.0) -> float:
    """WGS-84 normal gravity (m/s^2) at geodetic ``latitude`` (degrees) and ``height`` (m above
    the ellipsoid): Somigliana's formula (TR8350.2 Eq. 4-1) with the second-order height
    correction (Eq. 4-3)."""

    s2 = math.sin(math.radians(latitude)) ** 2
    gamma = GAMMA_EQUATOR * (1 + SOMIGLIANA_K * s2) / math.sqrt(1 - WGS84_E2 * s2)  # Eq. 4-1
    a, f = WGS84_A, WGS84_F
    return gamma * (1 - 2 / a * (1 + f + WGS84_M - 2 * f * s2) * height + 3 * height**2 / a**2)  # Eq. 4-3


# -- the World Magnetic Model (WMM2025 report) ----------------------------------------------------

#: The geomagnetic reference radius (m), WMM2025 report sect. 1.2 (the same in every release).
WMM_RADIUS = 6371200.0
#: WMM2025's own estimate of its error (1 sigma) over its span, WMM2025 report sect. 4 (Table 4):
#: total intensity (nT) and inclination (degrees).
WMM_ERROR = {"total_intensity_nT": 138.0, "inclination_deg": 0.20}


@dataclass(frozen=True)
class MagneticModel:
    """One release of the World Magnetic Model: its ``name`` (as the calibration file records
    it), its coefficient ``file`` in ``wmm/`` beside this module, its ``span`` in decimal years
    (its epoch and the end of its validity), its own ``error`` estimate (1 sigma over its span:
    total intensity nT, inclination degrees; None where none is known here) and the ``source``
    the calibration file names."""

    name: str
    file: str
    span: tuple[float, float]
    error: Mapping[str, float] | None
    source: str

    @property
    def degree(self) -> int:
        """The degree of its spherical-harmonic expansion (12; WMMHR2025 133), of its file."""
        return int(_coefficients(self.file)[1].shape[0]) - 1


#: The releases (the module docstring says where each comes from and why it holds when).
WMM2010 = MagneticModel(
    "WMM2010", "WMM_2010.COF", (2010.0, 2015.0), None, "World Magnetic Model WMM2010 (NOAA NGDC and BGS)"
)
WMM2015V2 = MagneticModel(
    "WMM2015v2",
    "WMM_2015v2.COF",
    (2015.0, 2020.0),
    {"total_intensity_nT": 152.0, "inclination_deg": 0.22},
    "World Magnetic Model WMM2015v2 (NOAA NCEI and BGS)",
)
WMM2020 = MagneticModel(
    "WMM2020",
    "WMM_2020.COF",
    (2020.0, 2025.0),
    {"total_intensity_nT": 145.0, "inclination_deg": 0.21},
    "World Magnetic Model WMM2020 (NOAA NCEI and BGS)",
)
WMM2025 = MagneticModel(
    "WMM2025", "WMM_2025.COF", (2025.0, 2030.0), WMM_ERROR, "World Magnetic Model WMM2025 (NOAA NCEI and BGS)"
)
WMMHR2025 = MagneticModel(
    "WMMHR2025",
    "WMMHR_2025.COF",
    (2025.0, 2030.0),
    {"total_intensity_nT": 134.0, "inclination_deg": 0.19},
    "World Magnetic Model High Resolution WMMHR2025 (NOAA NCEI and BGS)",
)
#: The field models a date chooses a release of (``--field-model``): the World Magnetic Model,
#: one release after another, and its high-resolution model.
FIELD_MODELS: dict[str, tuple[MagneticModel, ...]] = {
    "wmm": (WMM2010, WMM2015V2, WMM2020, WMM2025),
    "wmmhr": (WMMHR2025,),
}


def release_named(name: object) -> MagneticModel | None:
    """The release a calibration file's ``earth_field.model`` names (None: none of these)."""
    return next((m for family in FIELD_MODELS.values() for m in family if m.name == name), None)


@dataclass(frozen=True)
class Field:
    """The main field at a place and time: ``north``, ``east``, ``down`` (X, Y, Z, nT, in the
    ellipsoidal frame), the ``total`` intensity F (nT), ``inclination`` (I, degrees, positive
    down) and ``declination`` (D, degrees, positive east of true north)."""

    north: float
    east: float
    down: float
    total: float
    inclination: float
    declination: float

    @property
    def horizontal(self) -> float:
        return math.hypot(self.north, self.east)

    @property
    def dip_angle(self) -> float:
        """The angle between gravity (down) and the field (degrees): 90 - inclination."""
        return 90.0 - self.inclination


def field_span(family: str = "wmm") -> tuple[float, float]:
    """The span (decimal years) that the releases of ``family`` (FIELD_MODELS) hold together."""
    models = FIELD_MODELS[family]
    return models[0].span[0], models[-1].span[1]


def field_model(year: float, family: str = "wmm") -> MagneticModel:
    """The release of ``family`` (FIELD_MODELS: ``wmm``, ``wmmhr``) that holds at ``year``
    (decimal): each from its epoch until the next one's, the last to the end of its span.
    ValueError outside them all, naming their span."""
    if family not in FIELD_MODELS:
        raise ValueError(f"the field models are {', '.join(FIELD_MODELS)}, not {family!r}")
    models = FIELD_MODELS[family]
    for model in models:
        if model.span[0] <= year < model.span[1]:
            return model
    first, last = field_span(family)
    if year == last:
        return models[-1]
    names = ", ".join(m.name for m in models)
    raise ValueError(f"the field model {family} ({names}) holds from {first:g} to {last:g}, not {year:.3f}")


@functools.cache
def _coefficients(file: str) -> tuple[float, FloatArray, FloatArray, FloatArray, FloatArray]:
    """The epoch and g, h, their secular variation (nT, nT/year), each (N + 1, N + 1) indexed
    [n, m] to the file's degree N, of a coefficient file (the WMM.COF format: a line of epoch,
    model and release date; then n, m, g, h, g-dot, h-dot; closed by lines of 9s). Read once,
    when a field of the model is first asked for."""
    with open(os.path.join(os.path.dirname(__file__), "wmm", file), encoding="ascii") as f:  # os: no import cost
        text = f.read()
    head, _, body = text.partition("\n")
    rows = np.array(body[: body.index("\n9999")].split(), dtype=float).reshape(-1, 6)
    n, m = rows[:, 0].astype(int), rows[:, 1].astype(int)
    size = int(n.max()) + 1
    g, h, gdot, hdot = (np.zeros((size, size)) for _ in range(4))
    for table, column in zip((g, h, gdot, hdot), range(2, 6), strict=True):
        table[n, m] = rows[:, column]
    return float(head.split()[0]), g, h, gdot, hdot


@functools.cache
def _recursion(degree: int) -> tuple[tuple[FloatArray, FloatArray], ...]:
    """For each n to ``degree``, the factors sqrt((n - 1 + m)(n - 1 - m)) and sqrt((n + m)(n - m))
    of the recursion in n, m = 0 .. n - 1."""
    out = []
    for n in range(degree + 1):
        m = np.arange(n)
        out.append((np.sqrt((n - 1 + m) * (n - 1 - m)) if n > 1 else np.zeros(n), np.sqrt((n + m) * (n - m))))
    return tuple(out)


def _legendre(x: float, s: float, degree: int) -> tuple[FloatArray, FloatArray]:
    """Schmidt semi-normalised associated Legendre functions P[n, m] of x = cos(theta) to
    ``degree`` and their derivatives dP/dtheta (s = sin(theta); WMM2025 report Eqs. 12-13), by
    the standard recursions: on the diagonal, then in n for each m, which stays stable to high
    degree (the functions are bounded by 1); differentiated term by term so the poles need no
    division. Near a pole the high orders underflow to 0, as their terms are below any precision."""
    p, dp = np.zeros((degree + 1, degree + 1)), np.zeros((degree + 1, degree + 1))
    p[0, 0] = 1.0
    factors = _recursion(degree)
    for n in range(1, degree + 1):
        if n == 1:
            p[1, 1], dp[1, 1] = s, x
        else:
            c = math.sqrt((2 * n - 1) / (2 * n))
            p[n, n] = c * s * p[n - 1, n - 1]
            dp[n, n] = c * (x * p[n - 1, n - 1] + s * dp[n - 1, n - 1])
        k, d = factors[n]
        p[n, :n] = ((2 * n - 1) * x * p[n - 1, :n] - k * p[n - 2, :n]) / d
        dp[n, :n] = ((2 * n - 1) * (x * dp[n - 1, :n] - s * p[n - 1, :n]) - k * dp[n - 2, :n]) / d
    return p, dp


def decimal_year(year: int, month: int, day: int) -> float:
    """A date as the WMM software takes it: the year and the share of it gone at 0 h that day."""
    start = _days(year, 1, 1)
    return year + (_days(year, month, day) - start) / (_days(year + 1, 1, 1) - start)


def _days(year: int, month: int, day: int) -> int:
    """Days from a fixed origin (the proleptic Gregorian ordinal, as datetime.date.toordinal)."""
    y, m = (year, month) if month > 2 else (year - 1, month + 12)
    return 365 * y + y // 4 - y // 100 + y // 400 + (153 * (m - 3) + 2) // 5 + day - 307


def magnetic_field(
    latitude: float, longitude: float, height: float, year: float, model: MagneticModel | None = None
) -> Field:
    """The main field of the World Magnetic Model at geodetic ``latitude``, ``longitude``
    (degrees), ``height`` (m above the WGS-84 ellipsoid) and ``year`` (decimal): of ``model``,
    else of the release that holds then (field_model). ValueError outside the model's span."""

    if model is None:
        model = field_model(year)
    elif not model.span[0] <= year <= model.span[1]:
        raise ValueError(f"{model.name} holds from {model.span[0]:g} to {model.span[1]:g}, not {year:.3f}")
    phi, lam = math.radians(latitude), math.radians(longitude)
    # Eqs. 7-8: geodetic to geocentric spherical
    n_radius = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    p_axis = (n_radius + height) * math.cos(phi)
    z_axis = (n_radius * (1 - WGS84_E2) + height) * math.sin(phi)
    r = math.hypot(p_axis, z_axis)
    phi_c = math.atan2(z_axis, p_axis)
    sin_c, cos_c = z_axis / r, p_axis / r  # cos(theta), sin(theta) of the colatitude, to full precision
    epoch, g0, h0, gdot, hdot = _coefficients(model.file)
    dt = year - epoch
    g, h = g0 + dt * gdot, h0 + dt * hdot  # Eq. 9
    degree = g.shape[0] - 1
    p, dp = _legendre(sin_c, cos_c, degree)
    n = np.arange(degree + 1)[:, None]
    m = np.arange(degree + 1)[None, :]
    scale = (WMM_RADIUS / r) ** (n + 2)
    cos_m, sin_m = np.cos(m * lam), np.sin(m * lam)
    along = g * cos_m + h * sin_m
    across = g * sin_m - h * cos_m
    x_c = float(np.sum(scale * along * dp))  # Eq. 10: -dP/dphi' = dP/dtheta
    # Eq. 11: P[n, m] holds cos_c^m, so m P / cos_c stays finite at the poles (cos_c ~ 1e-17 there)
    y_c = float(np.sum(scale * m * across * p)) / cos_c
    z_c = -float(np.sum(scale * (n + 1) * along * p))  # Eq. 12
    turn = phi_c - phi  # Eq. 17: into the ellipsoidal frame
    north = x_c * math.cos(turn) - z_c * math.sin(turn)
    down = x_c * math.sin(turn) + z_c * math.cos(turn)
    east = y_c
    horizontal = math.hypot(north, east)
    return Field(  # Eq. 19
        north,
        east,
        down,
        math.hypot(horizontal, down),
        math.degrees(math.atan2(down, horizontal)),
        math.degrees(math.atan2(east, north)),
    )


# -- the dip angle ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Dip:
    """The angle between gravity and the field in each still block (degrees), their ``mean``,
    ``spread`` (sample standard deviation; 0 for one block) and ``uncertainty`` (1 sigma of the
    mean, spread / sqrt(n): the blocks' scatter, which holds the noise and what the calibration
    leaves in each orientation)."""

    angles: FloatArray
    mean: float
    spread: float
    uncertainty: float


def dip(up: FloatArray, field: FloatArray) -> Dip:
    """The dip angle of each block from the accelerometer's reading at rest (``up`` (n, 3): it
    reads +1 g upwards, so gravity is -up) and the magnetometer's (``field`` (n, 3)), both
    calibrated and in the same axes: the angle between gravity and the field, which is the same
    in every orientation, 90 - inclination (WMM2025 report Eq. 19: I = atan(Z / H))."""

    down = -up / np.linalg.norm(up, axis=1, keepdims=True)
    towards = field / np.linalg.norm(field, axis=1, keepdims=True)
    angles = np.degrees(np.arccos(np.clip(np.sum(down * towards, axis=1), -1.0, 1.0)))
    n = len(angles)
    spread = float(np.std(angles, ddof=1)) if n > 1 else 0.0
    return Dip(angles, float(np.mean(angles)), spread, spread / math.sqrt(n) if n > 1 else math.nan)
