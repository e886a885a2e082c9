"""The Earth's reference fields at a place: WGS-84 normal gravity and the World Magnetic Model.
numpy only (README "Sources": NIMA TR8350.2, the WMM2025 technical report).

Normal gravity (NIMA TR8350.2, 3rd edition, ch. 4): Somigliana's closed formula on the
ellipsoid (Eq. 4-1) ::

    gamma(phi) = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)

with the defining constants of WGS 84 (Table 3.1) and the derived ones (Table 3.3: gamma_e, gamma_p,
k, e^2, m), and above the ellipsoid its second-order height correction (Eq. 4-3) ::

    gamma_h = gamma (1 - 2/a (1 + f + m - 2 f sin^2 phi) h + 3 h^2 / a^2)

The World Magnetic Model (WMM2025 report, sect. 1.2, Eqs. 7-19): the geodetic place becomes
geocentric spherical coordinates (Eqs. 7-8), the Gauss coefficients move linearly with the time
from the epoch (Eq. 9), the field is the gradient of the spherical-harmonic potential to degree
12 with Schmidt semi-normalised associated Legendre functions (Eqs. 10-12), turned into the
ellipsoidal frame (Eq. 17), and its intensity, inclination and declination follow (Eq. 19).
The coefficients are the published WMM.COF of WMM2025 (NOAA NCEI and the British Geological
Survey; a work of the US government, in the public domain), below as published.
"""

from __future__ import annotations

import math
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

#: The geomagnetic reference radius (m), WMM2025 report sect. 1.2.
WMM_RADIUS = 6371200.0
#: The model's span in decimal years: its epoch and the end of its validity.
WMM_SPAN = (2025.0, 2030.0)
#: The model's name as its coefficient file names it.
WMM_NAME = "WMM-2025"
#: The model's own estimate of its error (1 sigma) over its span, WMM2025 report sect. 4 (Table 4):
#: total intensity (nT) and inclination (degrees).
WMM_ERROR = {"total_intensity_nT": 138.0, "inclination_deg": 0.20}


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


def _coefficients() -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """g, h, their secular variation (nT, nT/year), each (13, 13) indexed [n, m], of WMM_COF."""
    g, h, gdot, hdot = (np.zeros((13, 13)) for _ in range(4))
    for line in WMM_COF.splitlines()[1:]:
        parts = line.split()
        if len(parts) != 6:
            break  # the closing line of 9s
        n, m = int(parts[0]), int(parts[1])
        g[n, m], h[n, m], gdot[n, m], hdot[n, m] = (float(p) for p in parts[2:])
    return g, h, gdot, hdot


def _legendre(x: float, s: float) -> tuple[FloatArray, FloatArray]:
    """Schmidt semi-normalised associated Legendre functions P[n, m] of x = cos(theta) to degree
    12 and their derivatives dP/dtheta (s = sin(theta); WMM2025 report Eqs. 12-13, by the standard
    recursions in n and on the diagonal; differentiated term by term so the poles need no division)."""
    p, dp = np.zeros((13, 13)), np.zeros((13, 13))
    p[0, 0] = 1.0
    for n in range(1, 13):
        if n == 1:
            p[1, 1], dp[1, 1] = s, x
        else:
            c = math.sqrt((2 * n - 1) / (2 * n))
            p[n, n] = c * s * p[n - 1, n - 1]
            dp[n, n] = c * (x * p[n - 1, n - 1] + s * dp[n - 1, n - 1])
        for m in range(n):
            k = math.sqrt((n - 1 + m) * (n - 1 - m)) if n > 1 else 0.0
            d = math.sqrt((n + m) * (n - m))
            p[n, m] = ((2 * n - 1) * x * p[n - 1, m] - k * p[n - 2, m]) / d
            dp[n, m] = ((2 * n - 1) * (x * dp[n - 1, m] - s * p[n - 1, m]) - k * dp[n - 2, m]) / d
    return p, dp


def decimal_year(year: int, month: int, day: int) -> float:
    """A date as the WMM software takes it: the year and the share of it gone at 0 h that day."""
    start = _days(year, 1, 1)
    return year + (_days(year, month, day) - start) / (_days(year + 1, 1, 1) - start)


def _days(year: int, month: int, day: int) -> int:
    """Days from a fixed origin (the proleptic Gregorian ordinal, as datetime.date.toordinal)."""
    y, m = (year, month) if month > 2 else (year - 1, month + 12)
    return 365 * y + y // 4 - y // 100 + y // 400 + (153 * (m - 3) + 2) // 5 + day - 307


def magnetic_field(latitude: float, longitude: float, height: float, year: float) -> Field:
    """The WMM2025 main field at geodetic ``latitude``, ``longitude`` (degrees), ``height`` (m
    above the WGS-84 ellipsoid) and ``year`` (decimal). ValueError outside the model's span."""

    if not WMM_SPAN[0] <= year <= WMM_SPAN[1]:
        raise ValueError(f"WMM2025 holds from {WMM_SPAN[0]:g} to {WMM_SPAN[1]:g}, not {year:.3f}")
    phi, lam = math.radians(latitude), math.radians(longitude)
    # Eqs. 7-8: geodetic to geocentric spherical
    n_radius = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    p_axis = (n_radius + height) * math.cos(phi)
    z_axis = (n_radius * (1 - WGS84_E2) + height) * math.sin(phi)
    r = math.hypot(p_axis, z_axis)
    phi_c = math.atan2(z_axis, p_axis)
    sin_c, cos_c = z_axis / r, p_axis / r  # cos(theta), sin(theta) of the colatitude, to full precision
    g0, h0, gdot, hdot = _COEFFICIENTS
    dt = year - WMM_SPAN[0]
    g, h = g0 + dt * gdot, h0 + dt * hdot  # Eq. 9
    p, dp = _legendre(sin_c, cos_c)
    n = np.arange(13)[:, None]
    m = np.arange(13)[None, :]
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


#: WMM.COF of WMM2025 as published by NOAA NCEI (public domain): epoch, model, release date; then
#: n, m, g, h (nT), g-dot, h-dot (nT/year); closed by two lines of 9s.
WMM_COF = """\
    2025.0            WMM-2025     11/13/2024
  1  0  -29351.8       0.0       12.0        0.0
  1  1   -1410.8    4545.4        9.7      -21.5
  2  0   -2556.6       0.0      -11.6        0.0
  2  1    2951.1   -3133.6       -5.2      -27.7
  2  2    1649.3    -815.1       -8.0      -12.1
  3  0    1361.0       0.0       -1.3        0.0
  3  1   -2404.1     -56.6       -4.2        4.0
  3  2    1243.8     237.5        0.4       -0.3
  3  3     453.6    -549.5      -15.6       -4.1
  4  0     895.0       0.0       -1.6        0.0
  4  1     799.5     278.6       -2.4       -1.1
  4  2      55.7    -133.9       -6.0        4.1
  4  3    -281.1     212.0        5.6        1.6
  4  4      12.1    -375.6       -7.0       -4.4
  5  0    -233.2       0.0        0.6        0.0
  5  1     368.9      45.4        1.4       -0.5
  5  2     187.2     220.2        0.0        2.2
  5  3    -138.7    -122.9        0.6        0.4
  5  4    -142.0      43.0        2.2        1.7
  5  5      20.9     106.1        0.9        1.9
  6  0      64.4       0.0       -0.2        0.0
  6  1      63.8     -18.4       -0.4        0.3
  6  2      76.9      16.8        0.9       -1.6
  6  3    -115.7      48.8        1.2       -0.4
  6  4     -40.9     -59.8       -0.9        0.9
  6  5      14.9      10.9        0.3        0.7
  6  6     -60.7      72.7        0.9        0.9
  7  0      79.5       0.0       -0.0        0.0
  7  1     -77.0     -48.9       -0.1        0.6
  7  2      -8.8     -14.4       -0.1        0.5
  7  3      59.3      -1.0        0.5       -0.8
  7  4      15.8      23.4       -0.1        0.0
  7  5       2.5      -7.4       -0.8       -1.0
  7  6     -11.1     -25.1       -0.8        0.6
  7  7      14.2      -2.3        0.8       -0.2
  8  0      23.2       0.0       -0.1        0.0
  8  1      10.8       7.1        0.2       -0.2
  8  2     -17.5     -12.6        0.0        0.5
  8  3       2.0      11.4        0.5       -0.4
  8  4     -21.7      -9.7       -0.1        0.4
  8  5      16.9      12.7        0.3       -0.5
  8  6      15.0       0.7        0.2       -0.6
  8  7     -16.8      -5.2       -0.0        0.3
  8  8       0.9       3.9        0.2        0.2
  9  0       4.6       0.0       -0.0        0.0
  9  1       7.8     -24.8       -0.1       -0.3
  9  2       3.0      12.2        0.1        0.3
  9  3      -0.2       8.3        0.3       -0.3
  9  4      -2.5      -3.3       -0.3        0.3
  9  5     -13.1      -5.2        0.0        0.2
  9  6       2.4       7.2        0.3       -0.1
  9  7       8.6      -0.6       -0.1       -0.2
  9  8      -8.7       0.8        0.1        0.4
  9  9     -12.9      10.0       -0.1        0.1
 10  0      -1.3       0.0        0.1        0.0
 10  1      -6.4       3.3        0.0        0.0
 10  2       0.2       0.0        0.1       -0.0
 10  3       2.0       2.4        0.1       -0.2
 10  4      -1.0       5.3       -0.0        0.1
 10  5      -0.6      -9.1       -0.3       -0.1
 10  6      -0.9       0.4        0.0        0.1
 10  7       1.5      -4.2       -0.1        0.0
 10  8       0.9      -3.8       -0.1       -0.1
 10  9      -2.7       0.9       -0.0        0.2
 10 10      -3.9      -9.1       -0.0       -0.0
 11  0       2.9       0.0        0.0        0.0
 11  1      -1.5       0.0       -0.0       -0.0
 11  2      -2.5       2.9        0.0        0.1
 11  3       2.4      -0.6        0.0       -0.0
 11  4      -0.6       0.2        0.0        0.1
 11  5      -0.1       0.5       -0.1       -0.0
 11  6      -0.6      -0.3        0.0       -0.0
 11  7      -0.1      -1.2       -0.0        0.1
 11  8       1.1      -1.7       -0.1       -0.0
 11  9      -1.0      -2.9       -0.1        0.0
 11 10      -0.2      -1.8       -0.1        0.0
 11 11       2.6      -2.3       -0.1        0.0
 12  0      -2.0       0.0        0.0        0.0
 12  1      -0.2      -1.3        0.0       -0.0
 12  2       0.3       0.7       -0.0        0.0
 12  3       1.2       1.0       -0.0       -0.1
 12  4      -1.3      -1.4       -0.0        0.1
 12  5       0.6      -0.0       -0.0       -0.0
 12  6       0.6       0.6        0.1       -0.0
 12  7       0.5      -0.1       -0.0       -0.0
 12  8      -0.1       0.8        0.0        0.0
 12  9      -0.4       0.1        0.0       -0.0
 12 10      -0.2      -1.0       -0.1       -0.0
 12 11      -1.3       0.1       -0.0        0.0
 12 12      -0.7       0.2       -0.1       -0.1
999999999999999999999999999999999999999999999999
999999999999999999999999999999999999999999999999
"""

_COEFFICIENTS = _coefficients()
