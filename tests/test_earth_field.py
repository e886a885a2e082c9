"""The Earth's field as a magnetometer's reference (core.earth's World Magnetic Model WMM2025,
pipeline.places): NOAA's published test values, a peer implementation (pygeomag) to 1 nT, and
``solve --sensor magnetometer --location --date``: the model's total intensity as the reference
in the calibration's units, inclination and declination in the file, a date outside the model's
span exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import assert_untouched, assert_usage_error, precious, run, write
from tests.synth import hand_turned
from tumblecal_cli.core import earth

#: NOAA/BGS, WMM2025 test values (WMM2025_TEST_VALUES.txt of the WMM2025 release, as the WMM2025
#: report prints them): decimal year, height km, latitude, longitude, X, Y, Z (nT), declination (°)
NOAA = [
    (2025.0, 0.0, 80.0, 0.0, 6521.6, 145.9, 54791.5, 1.28),
    (2025.0, 0.0, 0.0, 120.0, 39677.8, -109.6, -10580.2, -0.16),
    (2025.0, 0.0, -80.0, 240.0, 6117.5, 15751.9, -52022.5, 68.78),
    (2025.0, 100.0, 80.0, 0.0, 6216.0, 92.4, 52598.8, 0.85),
    (2025.0, 100.0, 0.0, 120.0, 37688.6, -96.2, -10152.1, -0.15),
    (2025.0, 100.0, -80.0, 240.0, 5907.6, 14780.3, -49540.7, 68.21),
    (2027.5, 0.0, 80.0, 0.0, 6500.8, 294.5, 54869.4, 2.59),
    (2027.5, 0.0, 0.0, 120.0, 39701.6, -167.4, -10381.8, -0.24),
    (2027.5, 0.0, -80.0, 240.0, 6200.7, 15730.3, -51783.7, 68.49),
    (2027.5, 100.0, 80.0, 0.0, 6196.7, 233.8, 52670.5, 2.16),
    (2027.5, 100.0, 0.0, 120.0, 37711.5, -148.7, -9969.8, -0.23),
    (2027.5, 100.0, -80.0, 240.0, 5984.0, 14760.1, -49317.7, 67.93),
]


@pytest.mark.parametrize(("year", "height_km", "lat", "lon", "x", "y", "z", "dec"), NOAA)
def test_wmm_reproduces_noaas_published_test_values(
    year: float, height_km: float, lat: float, lon: float, x: float, y: float, z: float, dec: float
) -> None:
    f = earth.magnetic_field(lat, lon, height_km * 1000.0, year)
    # printed to 0.1 nT and 0.01°: a right answer is within half of that
    assert (f.north, f.east, f.down) == pytest.approx((x, y, z), abs=0.05 + 1e-9)
    assert f.declination == pytest.approx(dec, abs=0.005 + 1e-9)


def test_wmm_at_a_published_example_1000_m_over_natick_on_4_july_2028() -> None:
    """The example of MathWorks' wrldmagm (Aerospace Toolbox), WMM2025: X, Y, Z 2.0139, -0.4905,
    4.6532 x 1e4 nT, H 2.0727e4, D -13.6891°, I 65.9899°, F 5.0940e4."""
    f = earth.magnetic_field(42.283, -71.35, 1000.0, earth.decimal_year(2028, 7, 4))
    assert (f.north, f.east, f.down) == pytest.approx((20139, -4905, 46532), abs=0.5)
    assert (f.declination, f.inclination) == pytest.approx((-13.6891, 65.9899), abs=5e-5)
    assert (f.horizontal, f.total) == pytest.approx((20727, 50940), abs=0.5)


def test_wmm_agrees_with_pygeomag_to_1_nt_everywhere() -> None:
    pygeomag = pytest.importorskip("pygeomag")
    peer = pygeomag.GeoMag(coefficients_file="wmm/WMM_2025.COF")
    rng = np.random.default_rng(7)
    worst = 0.0
    for lat, lon, km, year in zip(
        rng.uniform(-89.5, 89.5, 300),
        rng.uniform(-180, 180, 300),
        rng.uniform(-1, 20, 300),
        rng.uniform(2025, 2030, 300),
        strict=True,
    ):
        theirs = peer.calculate(glat=float(lat), glon=float(lon), alt=float(km), time=float(year))
        ours = earth.magnetic_field(float(lat), float(lon), float(km) * 1000.0, float(year))
        worst = max(worst, abs(ours.north - theirs.x), abs(ours.east - theirs.y), abs(ours.down - theirs.z))
        assert ours.total == pytest.approx(theirs.f, abs=1.0)
        assert ours.inclination == pytest.approx(theirs.i, abs=1e-4)
        assert ours.declination == pytest.approx(theirs.d, abs=1e-3)
    assert worst < 1.0


def test_decimal_year_is_the_share_of_the_year_gone() -> None:
    assert earth.decimal_year(2025, 1, 1) == 2025.0
    assert earth.decimal_year(2028, 7, 2) == pytest.approx(2028.5)  # a leap year: day 183 of 366
    assert earth.decimal_year(2026, 11, 27) == pytest.approx(2026 + 330 / 365)


# -- solve --sensor magnetometer --location --date ---------------------------------------------

PLACE, DAY = "52.2053,0.1218,16", "2026-11-27"


def capture(tmp_path: Path, field: float) -> Path:
    """A magnetometer turned through every orientation in a field of ``field`` (its units)."""
    rng = np.random.default_rng(5)
    directions = hand_turned(rng, 3000, cap_deg=0.0)
    soft = np.array([[1.05, 0.03, -0.02], [0.03, 0.97, 0.04], [-0.02, 0.04, 1.01]])
    raw = (
        (field * directions) @ soft.T
        + np.array([12.0, -25.0, 30.0]) * field / 50
        + rng.normal(0, field / 500, (3000, 3))
    )
    return write(tmp_path / "mag.csv", raw, header="mx,my,mz", fmt="%.5f")


def test_solve_a_magnetometer_against_the_earths_field_in_ut(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    f = earth.magnetic_field(52.2053, 0.1218, 16.0, earth.decimal_year(2026, 11, 27))
    out = tmp_path / "mag.json"
    args = ("solve", "--sensor", "magnetometer", "-p", capture(tmp_path, f.total / 1000), "-o", out)
    r = run(capsys, *args, "--location", PLACE, "--date", DAY, "--json")
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert (doc["reference"], doc["units"]) == (pytest.approx(f.total / 1000, rel=1e-12), "uT")
    part = doc["earth_field"]
    assert (part["model"], part["date"]) == ("WMM2025", DAY)
    assert part["total_nT"] == pytest.approx(f.total, abs=0.05)
    assert (part["inclination_deg"], part["declination_deg"]) == (round(f.inclination, 4), round(f.declination, 4))
    assert json.loads(r.out)["earth_field"] == part
    assert f"reference {f.total / 1000:.5g} uT: the Earth's field {f.total:.1f} nT (WMM2025" in r.err
    corrected = np.linalg.norm(
        np.array(doc["matrix"]) @ (np.loadtxt(tmp_path / "mag.csv", delimiter=",", skiprows=1) - doc["offset"]).T,
        axis=0,
    )
    assert np.median(corrected) == pytest.approx(f.total / 1000, rel=2e-3)


def test_the_field_in_gauss_when_asked(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "mag.json"
    path = capture(tmp_path, 0.49)
    r = run(
        capsys,
        "solve",
        "--sensor",
        "magnetometer",
        "-p",
        path,
        "-o",
        out,
        "--location",
        PLACE,
        "--date",
        DAY,
        "--units",
        "gauss",
    )
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["units"] == "gauss"
    assert doc["reference"] == pytest.approx(doc["earth_field"]["total_nT"] / 1e5, abs=1e-6)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (
            ["--location", PLACE, "--date", "1900-01-01"],
            ["--date 1900-01-01 is outside", "WMM2010", "WMM2025", "2010-01-01 to 2029-12-31"],
        ),
        (["--location", PLACE, "--date", "2030-01-01"], ["--date 2030-01-01 is outside"]),
        (["--location", PLACE, "--date", "2026-02-30"], ["--date takes YYYY-MM-DD", "'2026-02-30'"]),
        (["--location", PLACE, "--date", "27/11/2026"], ["--date takes YYYY-MM-DD"]),
        (["--location", PLACE], ["give --date"]),
        (["--location", "-91,0", "--date", DAY], ["latitude -91"]),
        (["--location", PLACE, "--date", DAY, "--units", "counts"], ["uT, gauss", "'counts'"]),
        (["--gravity", "9.81"], ["an accelerometer's reference", "the Earth's field"]),
    ],
)
def test_bad_fields_are_one_line_exit_2_and_nothing_written(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], words: list[str]
) -> None:
    out = precious(tmp_path / "mag.json")
    r = run(capsys, "solve", "--sensor", "magnetometer", "-p", capture(tmp_path, 50.0), *args, "-o", out)
    assert_usage_error(r, *words)
    assert_untouched(out)


def test_verify_a_magnetometer_against_the_field_of_a_place_and_day(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    f = earth.magnetic_field(52.2053, 0.1218, 16.0, earth.decimal_year(2026, 11, 27))
    cal = tmp_path / "mag.json"
    path = capture(tmp_path, f.total / 1000)
    assert run(capsys, "solve", "--sensor", "magnetometer", "-p", path, "-o", cal, "--reference", "50").code == 0
    doc = json.loads(cal.read_text())
    doc["units"] = "uT"
    cal.write_text(json.dumps(doc))
    raw = np.linalg.inv(np.array(doc["matrix"])) @ np.array([0.3, -0.2, 0.93]) * f.total / 1000 + doc["offset"]
    still = write(tmp_path / "still.csv", raw + np.random.default_rng(1).normal(0, 0.05, (200, 3)), header="mx,my,mz")
    r = run(capsys, "verify", "--cal", cal, still, "--location", PLACE, "--date", DAY, "--json")
    assert json.loads(r.out).get("reference") == pytest.approx(f.total / 1000, rel=1e-12), r.out + r.err


@pytest.mark.parametrize("latitude", [90.0, -90.0, 89.9999999, -89.99999])
def test_wmm_at_the_poles_agrees_with_pygeomag(latitude: float) -> None:
    """At a pole the east component is a 0/0 (m P / cos of the latitude): it stays finite and right."""
    pygeomag = pytest.importorskip("pygeomag")
    theirs = pygeomag.GeoMag(coefficients_file="wmm/WMM_2025.COF").calculate(
        glat=latitude, glon=30.0, alt=0.0, time=2026.5
    )
    ours = earth.magnetic_field(latitude, 30.0, 0.0, 2026.5)
    assert (ours.north, ours.east, ours.down) == pytest.approx((theirs.x, theirs.y, theirs.z), abs=1e-3)
